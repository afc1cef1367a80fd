//! Anatomical landmarks (paper Fig. 2) and the landmark file format of the GUIDE:
//! `{"units":"mm","landmarks":{"Pj":[x,y,z],...},"extra":{"name":[x,y,z]}}`.

use glam::DVec3;
use mesh::LengthUnit;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};

/// The twelve required landmarks. Suffix `l`/`r` is the patient's left/right.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum LandmarkName {
    /// Sternal notch (jugulum).
    Pj,
    /// Mid-clavicular point, left.
    Pcl,
    /// Mid-clavicular point, right.
    Pcr,
    /// Nipple, left.
    Pnl,
    /// Nipple, right.
    Pnr,
    /// Lowest point of the inframammary fold, left.
    PSMFl,
    /// Lowest point of the inframammary fold, right.
    PSMFr,
    /// Medial end of the fold, left.
    PSMFml,
    /// Medial end of the fold, right.
    PSMFmr,
    /// Lateral end of the fold, left.
    PSMFll,
    /// Lateral end of the fold, right.
    PSMFlr,
    /// Xiphoid.
    Px,
}

impl LandmarkName {
    /// All required landmarks in file order.
    pub const ALL: [LandmarkName; 12] = [
        LandmarkName::Pj,
        LandmarkName::Pcl,
        LandmarkName::Pcr,
        LandmarkName::Pnl,
        LandmarkName::Pnr,
        LandmarkName::PSMFl,
        LandmarkName::PSMFr,
        LandmarkName::PSMFml,
        LandmarkName::PSMFmr,
        LandmarkName::PSMFll,
        LandmarkName::PSMFlr,
        LandmarkName::Px,
    ];

    /// The name as written in files and reports (`"Pj"`, `"PSMFl"`, ...).
    pub fn as_str(self) -> &'static str {
        match self {
            LandmarkName::Pj => "Pj",
            LandmarkName::Pcl => "Pcl",
            LandmarkName::Pcr => "Pcr",
            LandmarkName::Pnl => "Pnl",
            LandmarkName::Pnr => "Pnr",
            LandmarkName::PSMFl => "PSMFl",
            LandmarkName::PSMFr => "PSMFr",
            LandmarkName::PSMFml => "PSMFml",
            LandmarkName::PSMFmr => "PSMFmr",
            LandmarkName::PSMFll => "PSMFll",
            LandmarkName::PSMFlr => "PSMFlr",
            LandmarkName::Px => "Px",
        }
    }

    /// The same landmark on the patient's other side (`Pnl` <-> `Pnr`, ...); the midline
    /// landmarks `Pj` and `Px` are their own.
    pub fn opposite(self) -> LandmarkName {
        use LandmarkName::*;
        match self {
            Pj => Pj,
            Px => Px,
            Pcl => Pcr,
            Pcr => Pcl,
            Pnl => Pnr,
            Pnr => Pnl,
            PSMFl => PSMFr,
            PSMFr => PSMFl,
            PSMFml => PSMFmr,
            PSMFmr => PSMFml,
            PSMFll => PSMFlr,
            PSMFlr => PSMFll,
        }
    }

    /// Parses a file name of a landmark (exact spelling).
    pub fn parse(name: &str) -> Option<LandmarkName> {
        LandmarkName::ALL.into_iter().find(|n| n.as_str() == name)
    }
}

/// A complete set of landmarks in one scan's file frame (mm): the twelve required ones
/// and any number of named extra points.
#[derive(Debug, Clone, PartialEq)]
pub struct Landmarks {
    required: [DVec3; 12],
    /// User-defined points by name.
    pub extra: BTreeMap<String, DVec3>,
}

impl Landmarks {
    /// Builds a set from a position for every required landmark.
    pub fn new(position: impl Fn(LandmarkName) -> DVec3) -> Landmarks {
        Landmarks {
            required: LandmarkName::ALL.map(position),
            extra: BTreeMap::new(),
        }
    }

    /// Position of a required landmark (mm).
    pub fn get(&self, name: LandmarkName) -> DVec3 {
        self.required[name as usize]
    }

    /// Moves a required landmark.
    pub fn set(&mut self, name: LandmarkName, position: DVec3) {
        self.required[name as usize] = position;
    }

    /// Looks a point up by its file name, required or extra.
    pub fn lookup(&self, name: &str) -> Option<DVec3> {
        LandmarkName::parse(name)
            .map(|n| self.get(n))
            .or_else(|| self.extra.get(name).copied())
    }

    /// Every point with its name: required ones first, then extras.
    pub fn iter(&self) -> impl Iterator<Item = (&str, DVec3)> + '_ {
        LandmarkName::ALL
            .into_iter()
            .map(|n| (n.as_str(), self.get(n)))
            .chain(self.extra.iter().map(|(k, v)| (k.as_str(), *v)))
    }

    /// Applies `f` to every point (required and extra), e.g. a rigid transform.
    pub fn map_positions(&mut self, f: impl Fn(DVec3) -> DVec3) {
        for p in &mut self.required {
            *p = f(*p);
        }
        for p in self.extra.values_mut() {
            *p = f(*p);
        }
    }
}

/// A problem with a landmark file or with landmarks on a scan.
#[derive(Debug, thiserror::Error)]
pub enum LandmarkError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a valid landmark file: {message}")]
    Format { path: PathBuf, message: String },
    #[error("{path}: missing required landmark{} {}", if names.len() > 1 { "s" } else { "" }, names.join(", "))]
    Missing { path: PathBuf, names: Vec<String> },
    #[error("{path}: landmark {name}: {message}")]
    BadValue {
        path: PathBuf,
        name: String,
        message: String,
    },
    #[error(
        "landmark {name} is {distance_mm:.1} mm from the scan surface (at most {limit_mm} mm allowed): is it placed on this scan, in this scan's frame?"
    )]
    OffSurface {
        name: String,
        distance_mm: f64,
        limit_mm: f64,
    },
    #[error("{0}")]
    Write(#[from] mesh::MeshError),
}

/// A landmark that was moved onto the surface.
#[derive(Debug, Clone, PartialEq)]
pub struct SnapWarning {
    pub name: String,
    /// How far it was moved (mm).
    pub distance_mm: f64,
}

impl std::fmt::Display for SnapWarning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "landmark {} was {:.2} mm off the surface and has been snapped onto it",
            self.name, self.distance_mm
        )
    }
}

/// Landmarks farther than this from the surface are rejected (mm).
pub const MAX_SNAP_DISTANCE_MM: f64 = 5.0;
/// Landmarks closer than this are snapped without a warning (mm).
const ON_SURFACE_TOLERANCE_MM: f64 = 1e-3;
/// A point this close to the surface (mm) lies on it: what is left is rounding, not a
/// distance to snap, so points the tool wrote keep their coordinates when read back.
pub const ON_SURFACE_MM: f64 = 1e-6;

impl Landmarks {
    /// Reads a landmark file. Unknown keys are ignored; `units`, if given, must be `"mm"`.
    pub fn read(path: &Path) -> Result<Landmarks, LandmarkError> {
        PartialLandmarks::read(path)?.complete(path)
    }

    /// Parses landmark JSON; `path` is only used in error messages.
    pub fn from_json(text: &str, path: &Path) -> Result<Landmarks, LandmarkError> {
        PartialLandmarks::from_json(text, path)?.complete(path)
    }

    /// The landmark file as JSON, with `additional` top-level fields (e.g. a phantom's
    /// true volumes) after `units`, `landmarks` and `extra`.
    pub fn to_json(&self, additional: serde_json::Map<String, Value>) -> Value {
        PartialLandmarks::from(self).to_json(additional)
    }

    /// Writes the landmark file atomically.
    pub fn write(
        &self,
        path: &Path,
        additional: serde_json::Map<String, Value>,
    ) -> Result<(), LandmarkError> {
        write_json(path, &self.to_json(additional))
    }

    /// Moves every point onto the nearest surface point. Points more than
    /// [`MAX_SNAP_DISTANCE_MM`] away are an error naming the landmark; points that moved
    /// noticeably are returned as warnings.
    pub fn snap_to_surface(
        &mut self,
        surface: &mesh::SurfaceIndex,
    ) -> Result<Vec<SnapWarning>, LandmarkError> {
        let required = LandmarkName::ALL.iter().map(|n| n.as_str());
        let extra = self.extra.iter_mut().map(|(k, v)| (k.as_str(), v));
        snap_points(required.zip(self.required.iter_mut()).chain(extra), surface)
    }
}

/// Moves named points onto the nearest surface points (see
/// [`Landmarks::snap_to_surface`]); returns a warning for each that moved noticeably.
fn snap_points<'a>(
    points: impl Iterator<Item = (&'a str, &'a mut DVec3)>,
    surface: &mesh::SurfaceIndex,
) -> Result<Vec<SnapWarning>, LandmarkError> {
    let mut warnings = Vec::new();
    for (name, position) in points {
        let nearest = surface.closest_point(*position);
        if nearest.distance > MAX_SNAP_DISTANCE_MM {
            return Err(LandmarkError::OffSurface {
                name: name.to_string(),
                distance_mm: nearest.distance,
                limit_mm: MAX_SNAP_DISTANCE_MM,
            });
        }
        *position = nearest.point;
        if nearest.distance > ON_SURFACE_TOLERANCE_MM {
            warnings.push(SnapWarning {
                name: name.to_string(),
                distance_mm: nearest.distance,
            });
        }
    }
    Ok(warnings)
}

/// Writes landmark JSON atomically.
fn write_json(path: &Path, json: &Value) -> Result<(), LandmarkError> {
    mesh::io::write_atomically(path, |w| {
        serde_json::to_writer_pretty(&mut *w, json)?;
        writeln!(w)
    })?;
    Ok(())
}

/// Landmarks being placed (e.g. clicked one by one in the GUI): any subset of the
/// required ones and any named extra points, in a scan's file frame (mm). The same file
/// format as [`Landmarks`]; a file written before every required landmark is placed
/// reads back here, and [`PartialLandmarks::complete`] turns a full set into
/// [`Landmarks`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PartialLandmarks {
    required: [Option<DVec3>; 12],
    /// User-defined points by name.
    pub extra: BTreeMap<String, DVec3>,
}

impl From<&Landmarks> for PartialLandmarks {
    fn from(landmarks: &Landmarks) -> PartialLandmarks {
        PartialLandmarks {
            required: landmarks.required.map(Some),
            extra: landmarks.extra.clone(),
        }
    }
}

impl PartialLandmarks {
    /// Position of a required landmark if it is placed (mm).
    pub fn get(&self, name: LandmarkName) -> Option<DVec3> {
        self.required[name as usize]
    }

    /// Places or moves a required landmark.
    pub fn set(&mut self, name: LandmarkName, position: DVec3) {
        self.required[name as usize] = Some(position);
    }

    /// Looks a placed point up by its file name, required or extra.
    pub fn lookup(&self, name: &str) -> Option<DVec3> {
        match LandmarkName::parse(name) {
            Some(required) => self.get(required),
            None => self.extra.get(name).copied(),
        }
    }

    /// Moves a placed point (required or extra) by its file name; `false` if there is no
    /// such point.
    pub fn move_point(&mut self, name: &str, position: DVec3) -> bool {
        match LandmarkName::parse(name) {
            Some(required) => self.set(required, position),
            None => match self.extra.get_mut(name) {
                Some(point) => *point = position,
                None => return false,
            },
        }
        true
    }

    /// The required landmarks not yet placed, in file order.
    pub fn missing(&self) -> impl Iterator<Item = LandmarkName> + '_ {
        LandmarkName::ALL
            .into_iter()
            .filter(|n| self.get(*n).is_none())
    }

    /// Every placed point with its name: required ones first (file order), then extras.
    pub fn iter(&self) -> impl Iterator<Item = (&str, DVec3)> + '_ {
        LandmarkName::ALL
            .into_iter()
            .filter_map(|n| self.get(n).map(|p| (n.as_str(), p)))
            .chain(self.extra.iter().map(|(k, v)| (k.as_str(), *v)))
    }

    /// The full set, or an error naming the landmarks still missing (`path` names the
    /// file in the message).
    pub fn complete(&self, path: &Path) -> Result<Landmarks, LandmarkError> {
        let missing: Vec<String> = self.missing().map(|n| n.as_str().to_string()).collect();
        if !missing.is_empty() {
            return Err(LandmarkError::Missing {
                path: path.to_path_buf(),
                names: missing,
            });
        }
        let mut landmarks = Landmarks::new(|n| self.get(n).unwrap_or_default());
        landmarks.extra = self.extra.clone();
        Ok(landmarks)
    }

    /// Reads a landmark file that may lack some required landmarks.
    pub fn read(path: &Path) -> Result<PartialLandmarks, LandmarkError> {
        let text = std::fs::read_to_string(path).map_err(|source| LandmarkError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        PartialLandmarks::from_json(&text, path)
    }

    /// Parses landmark JSON in which required landmarks may be missing; `path` is only
    /// used in error messages. Unknown keys are ignored; `units` (`"mm"` when absent,
    /// `"cm"`, `"m"` or `"in"`) is converted to millimetres, and refused where the points'
    /// size contradicts it ([`mesh::units::check_declared_unit`]); unknown names under
    /// `"landmarks"` are kept as extras.
    pub fn from_json(text: &str, path: &Path) -> Result<PartialLandmarks, LandmarkError> {
        let format_error = |message: String| LandmarkError::Format {
            path: path.to_path_buf(),
            message,
        };
        let root: Value = serde_json::from_str(text).map_err(|e| format_error(e.to_string()))?;
        let root = root
            .as_object()
            .ok_or_else(|| format_error("expected a JSON object at the top".into()))?;
        let unit = match root.get("units") {
            None => LengthUnit::Millimetre,
            Some(units) => units.as_str().and_then(LengthUnit::parse).ok_or_else(|| {
                format_error(format!(
                    "units are {units}, expected \"mm\", \"cm\", \"m\" or \"in\""
                ))
            })?,
        };
        let points = |key: &str| -> Result<BTreeMap<String, DVec3>, LandmarkError> {
            let Some(value) = root.get(key) else {
                return Ok(BTreeMap::new());
            };
            let object = value.as_object().ok_or_else(|| {
                format_error(format!("\"{key}\" must be an object of name: [x, y, z]"))
            })?;
            object
                .iter()
                .map(|(name, value)| {
                    parse_point(value, unit)
                        .map(|p| (name.clone(), p))
                        .map_err(|message| LandmarkError::BadValue {
                            path: path.to_path_buf(),
                            name: name.clone(),
                            message,
                        })
                })
                .collect()
        };
        let mut landmarks = PartialLandmarks {
            required: [None; 12],
            extra: points("extra")?,
        };
        for (name, position) in points("landmarks")? {
            match LandmarkName::parse(&name) {
                Some(required) => landmarks.set(required, position),
                None => {
                    landmarks.extra.entry(name).or_insert(position);
                }
            }
        }
        let placed: Vec<DVec3> = (landmarks.required.iter().flatten())
            .chain(landmarks.extra.values())
            .copied()
            .collect();
        mesh::units::check_declared_unit(
            unit,
            mesh::units::span(&placed) / unit.mm(),
            placed.len(),
        )
        .map_err(format_error)?;
        Ok(landmarks)
    }

    /// The landmark file as JSON (placed points only), with `additional` top-level fields
    /// after `units`, `landmarks` and `extra`.
    pub fn to_json(&self, additional: serde_json::Map<String, Value>) -> Value {
        let point = |p: DVec3| json!([p.x, p.y, p.z]);
        let required: serde_json::Map<String, Value> = LandmarkName::ALL
            .iter()
            .filter_map(|n| self.get(*n).map(|p| (n.as_str().to_string(), point(p))))
            .collect();
        let extra: serde_json::Map<String, Value> = self
            .extra
            .iter()
            .map(|(k, v)| (k.clone(), point(*v)))
            .collect();
        let mut root = serde_json::Map::new();
        root.insert("units".into(), json!("mm"));
        root.insert("landmarks".into(), Value::Object(required));
        root.insert("extra".into(), Value::Object(extra));
        root.extend(additional);
        Value::Object(root)
    }

    /// Writes the landmark file atomically (placed points only).
    pub fn write(&self, path: &Path) -> Result<(), LandmarkError> {
        write_json(path, &self.to_json(serde_json::Map::new()))
    }

    /// Moves every placed point onto the nearest surface point, as
    /// [`Landmarks::snap_to_surface`] does.
    pub fn snap_to_surface(
        &mut self,
        surface: &mesh::SurfaceIndex,
    ) -> Result<Vec<SnapWarning>, LandmarkError> {
        let required = LandmarkName::ALL.iter().map(|n| n.as_str());
        let placed = required
            .zip(self.required.iter_mut())
            .filter_map(|(n, p)| p.as_mut().map(|p| (n, p)));
        let extra = self.extra.iter_mut().map(|(k, v)| (k.as_str(), v));
        snap_points(placed.chain(extra), surface)
    }
}

/// Points a measurement can look up by file name: a complete [`Landmarks`] set or a
/// [`PartialLandmarks`] set being placed.
pub trait NamedPoints: Sync {
    /// The point named `name` (mm), if there is one.
    fn point(&self, name: &str) -> Option<DVec3>;
}

impl NamedPoints for Landmarks {
    fn point(&self, name: &str) -> Option<DVec3> {
        self.lookup(name)
    }
}

impl NamedPoints for PartialLandmarks {
    fn point(&self, name: &str) -> Option<DVec3> {
        self.lookup(name)
    }
}

/// A point `[x, y, z]` in `unit`, converted to millimetres and checked
/// ([`mesh::geometry::check_position`]).
pub(crate) fn parse_point(value: &Value, unit: LengthUnit) -> Result<DVec3, String> {
    let array = value
        .as_array()
        .filter(|a| a.len() == 3)
        .ok_or_else(|| format!("expected [x, y, z], found {value}"))?;
    let mut coordinates = [0.0; 3];
    for (c, v) in coordinates.iter_mut().zip(array) {
        *c = v
            .as_f64()
            .filter(|x| x.is_finite())
            .ok_or_else(|| format!("coordinate {v} is not a finite number"))?;
    }
    let point = DVec3::from_array(coordinates) * unit.mm();
    mesh::geometry::check_position(point)?;
    Ok(point)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::grid;

    fn sample_json() -> String {
        let entries: Vec<String> = LandmarkName::ALL
            .iter()
            .enumerate()
            .map(|(i, n)| format!("\"{}\": [{}, 2.0, 0.5]", n.as_str(), i as f64))
            .collect();
        format!(
            "{{\"units\":\"mm\",\"frame\":\"ignored\",\"landmarks\":{{{}}},\"extra\":{{\"scar\":[1,2,3]}}}}",
            entries.join(",")
        )
    }

    #[test]
    fn reads_required_and_extra_points_and_ignores_unknown_keys() {
        let landmarks = Landmarks::from_json(&sample_json(), Path::new("lm.json")).unwrap();
        assert_eq!(landmarks.get(LandmarkName::Px), DVec3::new(11.0, 2.0, 0.5));
        assert_eq!(landmarks.lookup("scar"), Some(DVec3::new(1.0, 2.0, 3.0)));
        let again = Landmarks::from_json(
            &landmarks.to_json(serde_json::Map::new()).to_string(),
            Path::new("lm.json"),
        )
        .unwrap();
        assert_eq!(again, landmarks);
    }

    #[test]
    fn a_missing_landmark_is_named() {
        let text = sample_json().replace("\"Pj\"", "\"Pjx\"");
        let error = Landmarks::from_json(&text, Path::new("lm.json")).unwrap_err();
        assert_eq!(error.to_string(), "lm.json: missing required landmark Pj");
    }

    #[test]
    fn bad_values_are_named() {
        let text = sample_json().replace("[4, 2.0, 0.5]", "[4, \"a\", 0.5]");
        let error = Landmarks::from_json(&text, Path::new("lm.json")).unwrap_err();
        assert!(
            error.to_string().contains("landmark Pnr: coordinate \"a\""),
            "{error}"
        );
        // finite, but past any scan: its squared distances would overflow
        let text = sample_json().replace("[4, 2.0, 0.5]", "[4, -1e308, 0.5]");
        let error = Landmarks::from_json(&text, Path::new("lm.json")).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("landmark Pnr: a coordinate of 1.000e308 mm"),
            "{error}"
        );
        let error =
            Landmarks::from_json("{\"units\":\"furlong\"}", Path::new("lm.json")).unwrap_err();
        assert!(
            error
                .to_string()
                .contains("expected \"mm\", \"cm\", \"m\" or \"in\""),
            "{error}"
        );
        assert!(Landmarks::from_json("[1,2", Path::new("lm.json")).is_err());
    }

    /// A file in centimetres is read as ten times its numbers in millimetres (the same
    /// product, so exactly); one declared in metres whose points span a body in
    /// millimetres is refused, naming the declared unit.
    #[test]
    fn a_file_unit_is_converted_or_contradicted() {
        let in_mm = Landmarks::from_json(&sample_json(), Path::new("lm.json")).unwrap();
        let text = sample_json().replace("\"units\":\"mm\"", "\"units\":\"cm\"");
        let in_cm = Landmarks::from_json(&text, Path::new("lm.json")).unwrap();
        for name in LandmarkName::ALL {
            assert_eq!(in_cm.get(name), in_mm.get(name) * 10.0, "{name:?}");
        }
        let scaled = Landmarks::from_json(
            &sample_json().replace("\"units\":\"mm\"", "\"units\":\"m\""),
            Path::new("lm.json"),
        );
        // the sample's points span some ten units: 10 m is no torso
        let error = scaled.unwrap_err().to_string();
        assert!(
            error.contains("\"units\" is \"m\", but then the points span"),
            "{error}"
        );
    }

    #[test]
    fn snapping_moves_near_points_and_rejects_far_ones() {
        // Landmarks 0.5 mm above the plane z = 0 of a 20 x 20 mm grid.
        let surface = mesh::SurfaceIndex::new(&grid(20, 20, 1.0)).unwrap();
        let mut landmarks = Landmarks::from_json(&sample_json(), Path::new("lm.json")).unwrap();
        landmarks.extra.clear();
        let warnings = landmarks.snap_to_surface(&surface).unwrap();
        assert_eq!(warnings.len(), 12);
        assert!((warnings[0].distance_mm - 0.5).abs() < 1e-12);
        assert!(landmarks.get(LandmarkName::Pj).z.abs() < 1e-12);

        landmarks.set(LandmarkName::Pnl, DVec3::new(5.0, 5.0, 20.0));
        let error = landmarks.snap_to_surface(&surface).unwrap_err();
        assert!(
            error.to_string().starts_with("landmark Pnl is 20.0 mm"),
            "{error}"
        );
    }

    #[test]
    fn a_partial_set_reads_writes_and_completes() {
        let full = Landmarks::from_json(&sample_json(), Path::new("lm.json")).unwrap();
        let mut partial = PartialLandmarks::default();
        assert_eq!(partial.missing().next(), Some(LandmarkName::Pj));
        assert!(partial.frame(None).is_none());
        for name in [LandmarkName::Pj, LandmarkName::Px, LandmarkName::Pnl] {
            partial.set(name, full.get(name));
        }
        partial
            .extra
            .insert("scar".into(), DVec3::new(1.0, 2.0, 3.0));
        assert!(partial.move_point("scar", DVec3::new(4.0, 5.0, 6.0)));
        assert!(!partial.move_point("mole", DVec3::ZERO));
        assert_eq!(partial.missing().count(), 9);
        assert_eq!(partial.iter().count(), 4);
        assert_eq!(partial.lookup("Pnl"), Some(full.get(LandmarkName::Pnl)));
        assert_eq!(partial.lookup("Pcl"), None);

        let text = partial.to_json(serde_json::Map::new()).to_string();
        assert!(!text.contains("Pcl"), "{text}");
        let again = PartialLandmarks::from_json(&text, Path::new("lm.json")).unwrap();
        assert_eq!(again, partial);
        let error = again.complete(Path::new("lm.json")).unwrap_err();
        assert!(
            error.to_string().starts_with(
                "lm.json: missing required landmarks Pcl, Pcr, Pnr, PSMFl, PSMFr, PSMFml"
            ),
            "{error}"
        );

        let mut whole = PartialLandmarks::from(&full);
        assert!(whole.frame(None).is_some());
        whole.extra.clear();
        whole.extra.insert("scar".into(), DVec3::new(1.0, 2.0, 3.0));
        assert_eq!(whole.complete(Path::new("lm.json")).unwrap(), full);
    }

    #[test]
    fn a_partial_set_snaps_its_placed_points() {
        let surface = mesh::SurfaceIndex::new(&grid(20, 20, 1.0)).unwrap();
        let mut partial = PartialLandmarks::default();
        partial.set(LandmarkName::Pnr, DVec3::new(5.0, 5.0, 0.5));
        partial
            .extra
            .insert("scar".into(), DVec3::new(2.0, 3.0, -1.0));
        let warnings = partial.snap_to_surface(&surface).unwrap();
        assert_eq!(warnings.len(), 2);
        assert_eq!(
            partial.get(LandmarkName::Pnr),
            Some(DVec3::new(5.0, 5.0, 0.0))
        );
        assert_eq!(partial.lookup("scar"), Some(DVec3::new(2.0, 3.0, 0.0)));
        partial.set(LandmarkName::Pj, DVec3::new(5.0, 5.0, 9.0));
        assert!(partial.snap_to_surface(&surface).is_err());
    }
}
