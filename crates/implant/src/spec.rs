//! Implant specs of the command-line contract:
//! `round:diameter=115,projection=33`, `anatomic:width=120,height=113,projection=42`
//! (millimetres), `catalog:ID`.
//!
//! Optional keys: `profile=ellipsoid|smoothed` for round implants (default `ellipsoid`),
//! `taper=tall|short` for anatomic implants (default: chosen by height, see
//! [`AnatomicTaper::for_dimensions`]). Kinds and keys are case-insensitive; values may end
//! in `mm`; spaces around items are ignored.

use crate::catalog::{Catalog, CatalogEntry};
use crate::error::SpecError;
use crate::shape::{AnatomicImplant, AnatomicTaper, ImplantShape, RoundImplant, RoundProfile};
use std::fmt;
use std::str::FromStr;

/// A parsed implant spec: a shape given by its dimensions, or a catalog id still to be
/// resolved against a catalog.
#[derive(Debug, Clone, PartialEq)]
pub enum ImplantSpec {
    /// `round:...` or `anatomic:...`.
    Shape(ImplantShape),
    /// `catalog:ID`.
    Catalog(String),
}

const ROUND_KEYS: &str = "diameter, projection, profile";
const ANATOMIC_KEYS: &str = "width, height, projection, taper";

impl ImplantSpec {
    /// Parses a spec. Errors: no or unknown `kind:`, an item that is not `key=value`, an
    /// unknown, repeated or missing key, a value that is not a number (or not an allowed
    /// word), dimensions that make no implant, an empty catalog id.
    pub fn parse(spec: &str) -> Result<ImplantSpec, SpecError> {
        let syntax = |detail: String| SpecError::Syntax {
            spec: spec.to_string(),
            detail,
        };
        let Some((kind, rest)) = spec.split_once(':') else {
            return Err(syntax("; no `kind:` prefix".into()));
        };
        let kind = kind.trim().to_ascii_lowercase();
        match kind.as_str() {
            "catalog" => {
                let id = rest.trim();
                if id.is_empty() {
                    return Err(syntax("; empty catalog id".into()));
                }
                Ok(ImplantSpec::Catalog(id.to_string()))
            }
            "round" => {
                let items = Items::parse(
                    spec,
                    rest,
                    "round",
                    &["diameter", "projection", "profile"],
                    ROUND_KEYS,
                )?;
                let diameter = items.number("diameter")?;
                let projection = items.number("projection")?;
                let profile = match items.word("profile", &["ellipsoid", "smoothed"])? {
                    Some("smoothed") => RoundProfile::Smoothed,
                    _ => RoundProfile::Ellipsoid,
                };
                let round = RoundImplant::new(diameter, projection).map_err(|source| {
                    SpecError::Invalid {
                        spec: spec.to_string(),
                        source,
                    }
                })?;
                Ok(ImplantSpec::Shape(round.with_profile(profile).into()))
            }
            "anatomic" => {
                let items = Items::parse(
                    spec,
                    rest,
                    "anatomic",
                    &["width", "height", "projection", "taper"],
                    ANATOMIC_KEYS,
                )?;
                let width = items.number("width")?;
                let height = items.number("height")?;
                let projection = items.number("projection")?;
                let taper = items.word("taper", &["tall", "short"])?;
                let mut anatomic =
                    AnatomicImplant::new(width, height, projection).map_err(|source| {
                        SpecError::Invalid {
                            spec: spec.to_string(),
                            source,
                        }
                    })?;
                match taper {
                    Some("tall") => anatomic = anatomic.with_taper(AnatomicTaper::Tall),
                    Some("short") => anatomic = anatomic.with_taper(AnatomicTaper::Short),
                    _ => {}
                }
                Ok(ImplantSpec::Shape(anatomic.into()))
            }
            other => Err(syntax(format!("; unknown kind `{other}`"))),
        }
    }

    /// The entry this spec stands for. A shape becomes an entry with its canonical spec as
    /// id (e.g. `round:diameter=115,projection=33`) and family `custom`; a catalog id is
    /// looked up ([`Catalog::get`]). Errors: an unknown id, with close ids as a hint.
    pub fn resolve(&self, catalog: &Catalog) -> Result<CatalogEntry, SpecError> {
        match self {
            ImplantSpec::Shape(shape) => Ok(CatalogEntry::new(shape.to_string(), "custom", *shape)),
            ImplantSpec::Catalog(id) => catalog.get(id).cloned().ok_or_else(|| {
                let close = close_ids(catalog, id);
                let hint = if close.is_empty() {
                    String::new()
                } else {
                    format!("; did you mean {}?", close.join(", "))
                };
                SpecError::UnknownCatalogId {
                    spec: self.to_string(),
                    id: id.clone(),
                    count: catalog.len(),
                    hint,
                }
            }),
        }
    }
}

impl FromStr for ImplantSpec {
    type Err = SpecError;

    fn from_str(spec: &str) -> Result<ImplantSpec, SpecError> {
        ImplantSpec::parse(spec)
    }
}

impl fmt::Display for ImplantSpec {
    /// The canonical spec text; parsing it gives the same spec back.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ImplantSpec::Shape(shape) => shape.fmt(f),
            ImplantSpec::Catalog(id) => write!(f, "catalog:{id}"),
        }
    }
}

/// The `key=value` items of a spec, keys lower-cased.
struct Items<'a> {
    spec: &'a str,
    kind: &'static str,
    pairs: Vec<(String, &'a str)>,
}

impl<'a> Items<'a> {
    fn parse(
        spec: &'a str,
        rest: &'a str,
        kind: &'static str,
        keys: &[&str],
        allowed: &'static str,
    ) -> Result<Items<'a>, SpecError> {
        let mut pairs: Vec<(String, &'a str)> = Vec::new();
        for item in rest.split(',').map(str::trim).filter(|i| !i.is_empty()) {
            let Some((key, value)) = item.split_once('=') else {
                return Err(SpecError::Syntax {
                    spec: spec.to_string(),
                    detail: format!("; `{item}` is not `key=value`"),
                });
            };
            let key = key.trim().to_ascii_lowercase();
            if !keys.contains(&key.as_str()) {
                return Err(SpecError::UnknownKey {
                    spec: spec.to_string(),
                    kind,
                    key,
                    allowed,
                });
            }
            if pairs.iter().any(|(k, _)| *k == key) {
                return Err(SpecError::DuplicateKey {
                    spec: spec.to_string(),
                    key,
                });
            }
            pairs.push((key, value.trim()));
        }
        Ok(Items { spec, kind, pairs })
    }

    fn get(&self, key: &str) -> Option<&'a str> {
        self.pairs.iter().find(|(k, _)| k == key).map(|(_, v)| *v)
    }

    fn bad_value(&self, key: &str, value: &str, expected: &'static str) -> SpecError {
        SpecError::BadValue {
            spec: self.spec.to_string(),
            key: key.to_string(),
            value: value.to_string(),
            expected,
        }
    }

    /// A required number of millimetres (an `mm` suffix is allowed).
    fn number(&self, key: &'static str) -> Result<f64, SpecError> {
        let value = self.get(key).ok_or_else(|| SpecError::MissingKey {
            spec: self.spec.to_string(),
            kind: self.kind,
            key,
        })?;
        let digits = value.strip_suffix("mm").unwrap_or(value).trim();
        digits
            .parse::<f64>()
            .map_err(|_| self.bad_value(key, value, "a number of millimetres"))
    }

    /// An optional word out of `words` (case-insensitive).
    fn word(&self, key: &str, words: &[&'static str]) -> Result<Option<&'static str>, SpecError> {
        let Some(value) = self.get(key) else {
            return Ok(None);
        };
        let expected = match key {
            "profile" => "`ellipsoid` or `smoothed`",
            _ => "`tall` or `short`",
        };
        words
            .iter()
            .find(|w| w.eq_ignore_ascii_case(value))
            .map(|w| Some(*w))
            .ok_or_else(|| self.bad_value(key, value, expected))
    }
}

/// Up to three catalog ids close to `id`: containing it, or within edit distance 2
/// (case-insensitive), closest first.
fn close_ids(catalog: &Catalog, id: &str) -> Vec<String> {
    let wanted = id.to_ascii_lowercase();
    let mut scored: Vec<(usize, &str)> = catalog
        .entries()
        .iter()
        .filter_map(|e| {
            let candidate = e.id().to_ascii_lowercase();
            let d = edit_distance(&wanted, &candidate);
            (d <= 2 || candidate.contains(&wanted)).then_some((d, e.id()))
        })
        .collect();
    scored.sort();
    scored
        .into_iter()
        .take(3)
        .map(|(_, id)| id.to_string())
        .collect()
}

/// Levenshtein distance between two strings, by characters.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut diagonal = row[0];
        row[0] = i + 1;
        for (j, &cb) in b.iter().enumerate() {
            let substitution = diagonal + usize::from(ca != cb);
            diagonal = row[j + 1];
            row[j + 1] = substitution.min(row[j] + 1).min(row[j + 1] + 1);
        }
    }
    row[b.len()]
}
