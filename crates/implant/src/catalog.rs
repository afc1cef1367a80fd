//! Implant catalogs: the built-in generic catalog, user CSV catalogs, and suggestions
//! (paper VI-B: "suggest an implant from a given database which matches best").
//!
//! The built-in entries are generic shapes of the paper's formulas with typical
//! manufacturer proportions, not any manufacturer's products.

use crate::error::{CatalogError, ImplantError};
use crate::shape::{
    AnatomicImplant, ImplantShape, PROJECTION_RANGE_MM, RoundImplant, ShapeKind, WIDTH_RANGE_MM,
};
use serde::Serialize;
use std::collections::HashMap;
use std::io::Read;
use std::path::Path;

/// Nominal widths of the built-in catalog (mm): 90 to 160 in steps of 5.
pub const BUILTIN_WIDTHS_MM: [f64; 15] = [
    90.0, 95.0, 100.0, 105.0, 110.0, 115.0, 120.0, 125.0, 130.0, 135.0, 140.0, 145.0, 150.0, 155.0,
    160.0,
];

/// Built-in entries whose computed volume falls outside this range (ml) are left out.
pub const BUILTIN_VOLUME_RANGE_ML: (f64, f64) = (100.0, 800.0);

/// Target volumes [`Catalog::suggest`] accepts (ml): well beyond any breast implant sold.
pub const TARGET_VOLUME_RANGE_ML: (f64, f64) = (10.0, 2000.0);

/// Built-in round families: (id code, family name, projection / diameter).
///
/// The ratios follow the usual spacing of manufacturers' profiles (about 0.2-0.25 low,
/// 0.27-0.3 moderate, 0.33-0.36 high, 0.38-0.43 extra-high); the paper's round implant
/// (115 x 33 mm, ratio 0.287) sits in the moderate family.
pub const ROUND_FAMILIES: [(&str, &str, f64); 4] = [
    ("LOW", "low profile", 0.22),
    ("MOD", "moderate profile", 0.28),
    ("HIGH", "high profile", 0.34),
    ("XHIGH", "extra-high profile", 0.40),
];

/// Built-in anatomic families: (id code, family name, height / width, projection / width).
///
/// Low height 0.86 (the short taper of eq. 5 applies, below
/// [`crate::AnatomicTaper::TALL_HEIGHT_RATIO`]), full height 0.95 (tall taper); moderate
/// projection 0.28, full projection 0.35. The paper's anatomic implant (120 x 113 x 42 mm:
/// 0.94, 0.35) is a full-height, full-projection implant.
pub const ANATOMIC_FAMILIES: [(&str, &str, f64, f64); 4] = [
    ("LM", "low height moderate projection", 0.86, 0.28),
    ("LF", "low height full projection", 0.86, 0.35),
    ("FM", "full height moderate projection", 0.95, 0.28),
    ("FF", "full height full projection", 0.95, 0.35),
];

/// Weight of the projection difference in [`SuggestTarget::Dimensions`] distances. Width
/// and height weigh 1. A millimetre of projection changes the volume about twice as much
/// (relatively) as a millimetre of width (`V ∝ w² p`: at 120 x 34 mm, 1.7 % per mm of
/// width, 2.9 % per mm of projection) and is as visible in profile.
pub const PROJECTION_WEIGHT: f64 = 2.0;

/// One implant of a catalog: an id, a family, the shape and its computed volume.
///
/// Serialises (for `--json`) as `{id, shape, family, width_mm, height_mm, projection_mm,
/// volume_ml, max_thickness_mm, variant}`; `height_mm` equals `width_mm` for round
/// implants, `variant` is the round profile (`ellipsoid`, `smoothed`) or anatomic taper
/// (`tall`, `short`).
#[derive(Debug, Clone, PartialEq)]
pub struct CatalogEntry {
    id: String,
    family: String,
    shape: ImplantShape,
    volume_ml: f64,
}

impl CatalogEntry {
    /// An entry; the volume is computed ([`ImplantShape::volume_ml`]).
    pub fn new(id: impl Into<String>, family: impl Into<String>, shape: ImplantShape) -> Self {
        CatalogEntry {
            id: id.into(),
            family: family.into(),
            volume_ml: shape.volume_ml(),
            shape,
        }
    }

    /// The id (e.g. `R-MOD-120`).
    pub fn id(&self) -> &str {
        &self.id
    }

    /// The family name (e.g. `moderate profile`).
    pub fn family(&self) -> &str {
        &self.family
    }

    /// The shape.
    pub fn shape(&self) -> &ImplantShape {
        &self.shape
    }

    /// The computed volume (ml).
    pub fn volume_ml(&self) -> f64 {
        self.volume_ml
    }
}

#[derive(Serialize)]
struct EntryRecord<'a> {
    id: &'a str,
    shape: ShapeKind,
    family: &'a str,
    width_mm: f64,
    height_mm: f64,
    projection_mm: f64,
    volume_ml: f64,
    max_thickness_mm: f64,
    variant: &'static str,
}

impl Serialize for CatalogEntry {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        let variant = match &self.shape {
            ImplantShape::Round(r) => match r.profile() {
                crate::RoundProfile::Ellipsoid => "ellipsoid",
                crate::RoundProfile::Smoothed => "smoothed",
            },
            ImplantShape::Anatomic(a) => a.taper().as_str(),
        };
        EntryRecord {
            id: &self.id,
            shape: self.shape.kind(),
            family: &self.family,
            width_mm: self.shape.width_mm(),
            height_mm: self.shape.height_mm(),
            projection_mm: self.shape.projection_mm(),
            volume_ml: self.volume_ml,
            max_thickness_mm: self.shape.max_thickness_mm(),
            variant,
        }
        .serialize(serializer)
    }
}

/// What a suggestion should match.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SuggestTarget {
    /// Dimensions (mm). Entries are ranked by
    /// `sqrt(Δw² + Δh² + (PROJECTION_WEIGHT Δp)²)` (mm), `Δ` = entry minus target, a round
    /// entry's height being its diameter; without a height the `Δh` term is left out.
    Dimensions {
        /// Target width (mm).
        width_mm: f64,
        /// Target height (mm), if any.
        height_mm: Option<f64>,
        /// Target projection (mm).
        projection_mm: f64,
    },
    /// A volume (ml). Entries are ranked by `|volume - target|`.
    Volume {
        /// Target volume (ml).
        volume_ml: f64,
    },
}

impl SuggestTarget {
    fn validate(&self) -> Result<(), ImplantError> {
        let check = |what: &'static str, value: f64, (min, max): (f64, f64)| {
            if (min..=max).contains(&value) {
                Ok(())
            } else {
                Err(ImplantError::BadTarget {
                    what,
                    value,
                    min,
                    max,
                })
            }
        };
        match *self {
            SuggestTarget::Dimensions {
                width_mm,
                height_mm,
                projection_mm,
            } => {
                check("width_mm", width_mm, WIDTH_RANGE_MM)?;
                if let Some(h) = height_mm {
                    check("height_mm", h, WIDTH_RANGE_MM)?;
                }
                check("projection_mm", projection_mm, PROJECTION_RANGE_MM)
            }
            SuggestTarget::Volume { volume_ml } => {
                check("volume_ml", volume_ml, TARGET_VOLUME_RANGE_ML)
            }
        }
    }
}

/// One suggested entry.
///
/// Serialises as the entry's fields plus `distance_mm` (dimension targets only) and
/// `volume_difference_ml`.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Suggestion<'a> {
    /// The entry.
    #[serde(flatten)]
    pub entry: &'a CatalogEntry,
    /// Weighted dimension distance (mm) for a [`SuggestTarget::Dimensions`] target.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance_mm: Option<f64>,
    /// Entry volume minus the target volume (ml); for a dimensions target, minus the
    /// volume of the same-kind shape with the target dimensions when those make a valid
    /// shape, otherwise absent.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub volume_difference_ml: Option<f64>,
}

/// An implant catalog: entries with unique ids, in their original order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Catalog {
    entries: Vec<CatalogEntry>,
}

impl Catalog {
    /// The built-in generic catalog: every family of [`ROUND_FAMILIES`] and
    /// [`ANATOMIC_FAMILIES`] at every width of [`BUILTIN_WIDTHS_MM`], dimensions rounded to
    /// 0.5 mm, keeping the entries whose volume is within [`BUILTIN_VOLUME_RANGE_ML`]. Ids
    /// are `R-<family>-<diameter>` and `A-<family>-<width>`, e.g. `R-MOD-120`, `A-FF-120`.
    /// Round entries come first, by family then width. Generic shapes, not a
    /// manufacturer's products.
    pub fn builtin() -> Catalog {
        let mut entries = Vec::new();
        let (v_min, v_max) = BUILTIN_VOLUME_RANGE_ML;
        let mut push = |id: String, family: &str, shape: Result<ImplantShape, ImplantError>| {
            // Every built-in dimension is inside the accepted ranges (tested).
            if let Ok(shape) = shape {
                let entry = CatalogEntry::new(id, family, shape);
                if (v_min..=v_max).contains(&entry.volume_ml) {
                    entries.push(entry);
                }
            }
        };
        for (code, family, ratio) in ROUND_FAMILIES {
            for w in BUILTIN_WIDTHS_MM {
                let shape = RoundImplant::new(w, half_mm(w * ratio)).map(ImplantShape::from);
                push(format!("R-{code}-{w}"), family, shape);
            }
        }
        for (code, family, h_ratio, p_ratio) in ANATOMIC_FAMILIES {
            for w in BUILTIN_WIDTHS_MM {
                let shape = AnatomicImplant::new(w, half_mm(w * h_ratio), half_mm(w * p_ratio))
                    .map(ImplantShape::from);
                push(format!("A-{code}-{w}"), family, shape);
            }
        }
        Catalog { entries }
    }

    /// A catalog of the given entries. Errors name the first repeated id (`line` is the
    /// 1-based entry index).
    pub fn from_entries(entries: Vec<CatalogEntry>) -> Result<Catalog, CatalogError> {
        let mut first: HashMap<&str, usize> = HashMap::new();
        for (i, e) in entries.iter().enumerate() {
            if let Some(&j) = first.get(e.id.as_str()) {
                return Err(CatalogError::DuplicateId {
                    source_name: "catalog entries".into(),
                    line: i as u64 + 1,
                    id: e.id.clone(),
                    first_line: j as u64 + 1,
                });
            }
            first.insert(&e.id, i);
        }
        Ok(Catalog { entries })
    }

    /// Reads a CSV catalog file; see [`Catalog::from_csv_reader`].
    pub fn load_csv(path: &Path) -> Result<Catalog, CatalogError> {
        let source_name = path.display().to_string();
        let file = std::fs::File::open(path).map_err(|e| CatalogError::Io {
            source_name: source_name.clone(),
            message: e.to_string(),
        })?;
        Catalog::from_csv_reader(std::io::BufReader::new(file), &source_name)
    }

    /// Reads a CSV catalog (e.g. a manufacturer's table). `source_name` names the source
    /// in errors.
    ///
    /// Format: a header row, then one implant per row. Columns, matched by name (case and
    /// surrounding spaces ignored, any order): `id`, `shape` (`round` or `anatomic`),
    /// `family` (free text, may be empty), `width_mm` (the diameter for round implants),
    /// `height_mm` (anatomic; for round implants empty or equal to `width_mm`; the column
    /// may be absent when there is no anatomic row), `projection_mm`. Other columns (a
    /// manufacturer's nominal volume, say) are ignored. Lines starting with `#` and blank
    /// lines are skipped; fields may be quoted; a UTF-8 byte-order mark is accepted. Round
    /// implants get the default profile, anatomic ones the taper chosen by height.
    /// Volumes are computed. Errors name the line and the column.
    pub fn from_csv_reader<R: Read>(
        mut reader: R,
        source_name: &str,
    ) -> Result<Catalog, CatalogError> {
        // Read it whole: catalogs are small, and the line numbers come from byte offsets
        // (the csv crate's own line count skips blank and comment lines).
        let mut bytes = Vec::new();
        reader
            .read_to_end(&mut bytes)
            .map_err(|e| CatalogError::Io {
                source_name: source_name.to_string(),
                message: e.to_string(),
            })?;
        let line_at = |position: Option<&csv::Position>| -> u64 {
            position.map_or(0, |p| line_of_record(&bytes, p.byte() as usize))
        };
        let mut csv_reader = csv::ReaderBuilder::new()
            .has_headers(false)
            .flexible(true)
            .trim(csv::Trim::All)
            .comment(Some(b'#'))
            .from_reader(bytes.as_slice());
        let row_error = |e: csv::Error| CatalogError::Row {
            source_name: source_name.to_string(),
            line: line_at(e.position()),
            message: e.to_string(),
        };
        // Lines of spaces come through as one empty field: skip them like blank lines.
        let mut records = csv_reader
            .records()
            .filter(|r| r.as_ref().map_or(true, |r| r.iter().any(|f| !f.is_empty())));
        let header = match records.next() {
            Some(r) => r.map_err(row_error)?,
            None => {
                return Err(CatalogError::Empty {
                    source_name: source_name.to_string(),
                });
            }
        };
        let columns = Columns::from_header(&header, line_at(header.position()), source_name)?;
        let mut entries = Vec::new();
        let mut first_line: HashMap<String, u64> = HashMap::new();
        for record in records {
            let record = record.map_err(row_error)?;
            let line = line_at(record.position());
            let row = Row {
                record: &record,
                columns: &columns,
                source_name,
                line,
            };
            let entry = row.entry()?;
            if let Some(&first) = first_line.get(entry.id()) {
                return Err(CatalogError::DuplicateId {
                    source_name: source_name.to_string(),
                    line,
                    id: entry.id.clone(),
                    first_line: first,
                });
            }
            first_line.insert(entry.id.clone(), line);
            entries.push(entry);
        }
        if entries.is_empty() {
            return Err(CatalogError::Empty {
                source_name: source_name.to_string(),
            });
        }
        Ok(Catalog { entries })
    }

    /// All entries, in order.
    pub fn entries(&self) -> &[CatalogEntry] {
        &self.entries
    }

    /// Number of entries.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// True when the catalog has no entries.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// The entry with this id: an exact match, else the only case-insensitive match.
    pub fn get(&self, id: &str) -> Option<&CatalogEntry> {
        let id = id.trim();
        if let Some(e) = self.entries.iter().find(|e| e.id == id) {
            return Some(e);
        }
        let mut matches = self
            .entries
            .iter()
            .filter(|e| e.id.eq_ignore_ascii_case(id));
        match (matches.next(), matches.next()) {
            (Some(e), None) => Some(e),
            _ => None,
        }
    }

    /// The `count` entries closest to `target`, best first (ties by id), optionally only
    /// of one kind. See [`SuggestTarget`] for the distances.
    ///
    /// Errors: a target value that is not a positive finite number.
    pub fn suggest(
        &self,
        target: &SuggestTarget,
        kind: Option<ShapeKind>,
        count: usize,
    ) -> Result<Vec<Suggestion<'_>>, ImplantError> {
        target.validate()?;
        let target_volume_ml = |entry: &CatalogEntry| -> Option<f64> {
            match *target {
                SuggestTarget::Volume { volume_ml } => Some(volume_ml),
                SuggestTarget::Dimensions {
                    width_mm,
                    height_mm,
                    projection_mm,
                } => match entry.shape.kind() {
                    ShapeKind::Round => RoundImplant::new(width_mm, projection_mm)
                        .ok()
                        .map(|r| ImplantShape::from(r).volume_ml()),
                    ShapeKind::Anatomic => {
                        AnatomicImplant::new(width_mm, height_mm?, projection_mm)
                            .ok()
                            .map(|a| ImplantShape::from(a).volume_ml())
                    }
                },
            }
        };
        let mut kind_volume: HashMap<ShapeKind, Option<f64>> = HashMap::new();
        let mut ranked: Vec<(f64, Suggestion<'_>)> = self
            .entries
            .iter()
            .filter(|e| kind.is_none_or(|k| e.shape.kind() == k))
            .map(|entry| {
                let reference = *kind_volume
                    .entry(entry.shape.kind())
                    .or_insert_with(|| target_volume_ml(entry));
                let volume_difference_ml = reference.map(|v| entry.volume_ml - v);
                let (key, distance_mm) = match *target {
                    SuggestTarget::Volume { volume_ml } => {
                        ((entry.volume_ml - volume_ml).abs(), None)
                    }
                    SuggestTarget::Dimensions {
                        width_mm,
                        height_mm,
                        projection_mm,
                    } => {
                        let dw = entry.shape.width_mm() - width_mm;
                        let dh = height_mm.map_or(0.0, |h| entry.shape.height_mm() - h);
                        let dp = PROJECTION_WEIGHT * (entry.shape.projection_mm() - projection_mm);
                        let d = (dw * dw + dh * dh + dp * dp).sqrt();
                        (d, Some(d))
                    }
                };
                (
                    key,
                    Suggestion {
                        entry,
                        distance_mm,
                        volume_difference_ml,
                    },
                )
            })
            .collect();
        ranked
            .sort_by(|(ka, a), (kb, b)| ka.total_cmp(kb).then_with(|| a.entry.id.cmp(&b.entry.id)));
        Ok(ranked.into_iter().take(count).map(|(_, s)| s).collect())
    }
}

/// The 1-based line on which the record starting at byte `start` begins: the csv reader's
/// byte offset points before the blank and comment lines it skipped, so skip them too.
fn line_of_record(bytes: &[u8], start: usize) -> u64 {
    let start = start.min(bytes.len());
    let mut line = 1 + bytes[..start].iter().filter(|&&b| b == b'\n').count() as u64;
    let mut rest = &bytes[start..];
    loop {
        let end = rest.iter().position(|&b| b == b'\n');
        let text = &rest[..end.unwrap_or(rest.len())];
        let skipped = text.iter().all(|b| b.is_ascii_whitespace()) || text.first() == Some(&b'#');
        match end {
            Some(end) if skipped => {
                line += 1;
                rest = &rest[end + 1..];
            }
            _ => return line,
        }
    }
}

/// Rounds to the nearest 0.5 mm.
fn half_mm(value_mm: f64) -> f64 {
    (value_mm * 2.0).round() / 2.0
}

/// Column positions of a CSV catalog header.
struct Columns {
    names: Vec<String>,
    id: usize,
    shape: usize,
    family: usize,
    width: usize,
    height: Option<usize>,
    projection: usize,
}

impl Columns {
    const REQUIRED: [&'static str; 5] = ["id", "shape", "family", "width_mm", "projection_mm"];

    fn from_header(
        header: &csv::StringRecord,
        line: u64,
        source_name: &str,
    ) -> Result<Columns, CatalogError> {
        let header_error = |message: String| CatalogError::Header {
            source_name: source_name.to_string(),
            line,
            message,
        };
        let names: Vec<String> = header
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let name = if i == 0 {
                    name.trim_start_matches('\u{feff}')
                } else {
                    name
                };
                name.trim().to_ascii_lowercase()
            })
            .collect();
        let find = |wanted: &str| -> Result<Option<usize>, CatalogError> {
            let mut hits = names
                .iter()
                .enumerate()
                .filter(|(_, n)| n.as_str() == wanted);
            match (hits.next(), hits.next()) {
                (None, _) => Ok(None),
                (Some((i, _)), None) => Ok(Some(i)),
                (Some((i, _)), Some((j, _))) => Err(header_error(format!(
                    "column `{wanted}` appears twice (columns {} and {})",
                    i + 1,
                    j + 1
                ))),
            }
        };
        let required = |wanted: &'static str| -> Result<usize, CatalogError> {
            find(wanted)?.ok_or_else(|| {
                header_error(format!(
                    "missing column `{wanted}`; expected columns {} and, for anatomic \
                     implants, height_mm (found: {})",
                    Self::REQUIRED.join(", "),
                    names.join(", ")
                ))
            })
        };
        Ok(Columns {
            id: required("id")?,
            shape: required("shape")?,
            family: required("family")?,
            width: required("width_mm")?,
            height: find("height_mm")?,
            projection: required("projection_mm")?,
            names,
        })
    }
}

/// One CSV row being turned into an entry.
struct Row<'a> {
    record: &'a csv::StringRecord,
    columns: &'a Columns,
    source_name: &'a str,
    line: u64,
}

impl Row<'_> {
    fn cell(&self, column: usize) -> &str {
        self.record.get(column).unwrap_or("")
    }

    fn field_error(&self, column: usize, message: String) -> CatalogError {
        CatalogError::Field {
            source_name: self.source_name.to_string(),
            line: self.line,
            column: self.columns.names[column].clone(),
            column_index: column + 1,
            message,
        }
    }

    fn number(&self, column: usize) -> Result<Option<f64>, CatalogError> {
        let text = self.cell(column);
        if text.is_empty() {
            return Ok(None);
        }
        match text.parse::<f64>() {
            Ok(v) => Ok(Some(v)),
            Err(_) => Err(self.field_error(
                column,
                format!("expected a number of millimetres, got `{text}`"),
            )),
        }
    }

    fn required_number(&self, column: usize) -> Result<f64, CatalogError> {
        self.number(column)?.ok_or_else(|| {
            self.field_error(column, "empty; expected a number of millimetres".into())
        })
    }

    fn entry(&self) -> Result<CatalogEntry, CatalogError> {
        let c = self.columns;
        let id = self.cell(c.id);
        if id.is_empty() {
            return Err(self.field_error(c.id, "empty; every implant needs an id".into()));
        }
        let kind = match self.cell(c.shape).to_ascii_lowercase().as_str() {
            "round" => ShapeKind::Round,
            "anatomic" => ShapeKind::Anatomic,
            other => {
                return Err(self.field_error(
                    c.shape,
                    format!("expected `round` or `anatomic`, got `{other}`"),
                ));
            }
        };
        let family = self.cell(c.family);
        let width = self.required_number(c.width)?;
        let projection = self.required_number(c.projection)?;
        let height = match c.height {
            Some(column) => self.number(column)?,
            None => None,
        };
        let shape = match kind {
            ShapeKind::Round => {
                if let (Some(h), Some(column)) = (height, c.height)
                    && h != width
                {
                    return Err(self.field_error(
                        column,
                        format!(
                            "a round implant's height must be empty or equal to its width \
                             (diameter) {width} mm, got {h} mm"
                        ),
                    ));
                }
                RoundImplant::new(width, projection).map(ImplantShape::from)
            }
            ShapeKind::Anatomic => {
                let Some(column) = c.height else {
                    return Err(CatalogError::Row {
                        source_name: self.source_name.to_string(),
                        line: self.line,
                        message: format!(
                            "anatomic implant `{id}` needs a height, but the header has no \
                             `height_mm` column"
                        ),
                    });
                };
                let height = height.ok_or_else(|| {
                    self.field_error(
                        column,
                        "empty; an anatomic implant needs a height in mm".into(),
                    )
                })?;
                AnatomicImplant::new(width, height, projection).map(ImplantShape::from)
            }
        };
        let shape = shape.map_err(|e| {
            let column = match &e {
                ImplantError::NonFinite { what, .. } | ImplantError::OutOfRange { what, .. } => {
                    match *what {
                        "height" => c.height.unwrap_or(c.width),
                        "projection" => c.projection,
                        _ => c.width,
                    }
                }
                _ => c.projection,
            };
            self.field_error(column, e.to_string())
        })?;
        Ok(CatalogEntry::new(id, family, shape))
    }
}
