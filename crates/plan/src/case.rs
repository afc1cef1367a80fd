//! Planning cases: what the desktop application saves and reopens (`mammaplan gui --case
//! FILE`): the scan (a file or the built-in phantom), the landmarks, the cut curves'
//! control points once a model was built, the model and material settings, and the
//! implant of each side with its position. One JSON file, written atomically:
//!
//! ```json
//! {
//!   "format": "mammaplan case", "version": 1, "units": "mm",
//!   "scan": {"path": "/data/scan.ply"},
//!   "landmarks": {"units": "mm", "landmarks": {"Pj": [0, 0, 0], "...": []}, "extra": {}},
//!   "control_points": {"units": "mm", "left": [[0, 0, 0], "..."], "right": ["..."]},
//!   "model": {"elements": 60000},
//!   "material": {"young_kpa": 2.4, "poisson_ratio": 0.45},
//!   "simulation": {"gravity": true},
//!   "implants": {
//!     "linked": false,
//!     "left": {"spec": "catalog:R-MOD-120", "move_mm": [0, 5, 0], "rotation_deg": 0,
//!              "fold_lowering_mm": 10},
//!     "right": null
//!   }
//! }
//! ```
//!
//! `scan` is `{"phantom": {"cup": "medium", "ptosis": 0.3, "noise_mm": 0, "asymmetry": 0,
//! "seed": 1}}` for the built-in phantom. `landmarks` and `control_points` are the
//! landmark and control-point file formats (GUIDE section 4; some required landmarks may
//! be missing while they are being placed); `control_points` is `null` until a model was
//! built. A relative scan path is read relative to the case file's folder; saving writes
//! the absolute path. Implant specs are the command line's (`round:...`, `anatomic:...`,
//! `catalog:ID`), moves in the anatomical frame (mm) from the default position; an
//! implant's `fold_lowering_mm` is optional (absent: as planned for the implant).

use crate::model::{DEFAULT_ELEMENTS, ModelOptions, PerSide};
use crate::simulate::{ImplantRequest, Material, SimulationOptions};
use crate::{LengthUnit, PhantomParams, Progress, Scan};
use anatomy::{ControlPoints, PartialLandmarks, Up};
use anyhow::{Context, Result, bail, ensure};
use glam::DVec3;
use implant::ImplantSpec;
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The `format` field of a case file.
pub const CASE_FORMAT: &str = "mammaplan case";
/// The version this build writes and reads.
pub const CASE_VERSION: u32 = 1;
/// The element counts a case may ask for: below, the breasts get only a few elements
/// across; above, model building takes minutes and the live view stalls.
pub const CASE_ELEMENTS_RANGE: (usize, usize) = (1_000, 2_000_000);

/// Where a case's scan comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum ScanSource {
    /// A scan file (PLY, OBJ or STL).
    File(PathBuf),
    /// The built-in phantom with these parameters.
    Phantom(PhantomParams),
}

impl ScanSource {
    /// Reads the file (its coordinates in `unit`, see [`Scan::load_in`]) or generates
    /// the phantom.
    pub fn load(&self, unit: Option<LengthUnit>, progress: &dyn Progress) -> Result<Scan> {
        match self {
            ScanSource::File(path) => Scan::load_in(path, unit, progress),
            ScanSource::Phantom(params) => Scan::phantom(params),
        }
    }
}

/// A planning case: everything needed to rebuild a planning session.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanningCase {
    pub scan: ScanSource,
    /// Which way is up in the scan's file, when the user said it (`--up`); `None`: the
    /// file's vertical or an estimate ([`anatomy::Up::resolve`]).
    pub up: Option<Up>,
    /// The unit of the scan file's coordinates, when the user said it (`--units`);
    /// `None`: millimetres.
    pub scan_units: Option<LengthUnit>,
    pub landmarks: PartialLandmarks,
    /// The cut curves' control points (from a built model); `None`: the defaults from
    /// the landmarks.
    pub control_points: Option<ControlPoints>,
    /// About how many tetrahedra the finest level has (`--elements`).
    pub elements: usize,
    /// Breast tissue (Young's modulus and Poisson ratio; the density is the default).
    pub tissue: Material,
    /// Whether the gravity correction (paper V-B) follows the implant stage.
    pub gravity: bool,
    /// The right implant mirrors the left one (an editing mode of the front end).
    pub linked: bool,
    pub implants: PerSide<Option<ImplantRequest>>,
}

impl PlanningCase {
    /// A case of a scan with its landmarks and the default settings: no implants.
    pub fn new(scan: ScanSource, landmarks: PartialLandmarks) -> PlanningCase {
        PlanningCase {
            scan,
            up: None,
            scan_units: None,
            landmarks,
            control_points: None,
            elements: DEFAULT_ELEMENTS,
            tissue: Material::default(),
            gravity: true,
            linked: false,
            implants: PerSide::default(),
        }
    }

    /// The model settings of the case (its element count and control points).
    pub fn model_options(&self) -> ModelOptions {
        let mut options = ModelOptions {
            elements: self.elements,
            ..ModelOptions::default()
        };
        options.breast.control_points = self.control_points.clone();
        options
    }

    /// The simulation settings of the case (its tissue).
    pub fn simulation_options(&self) -> SimulationOptions {
        SimulationOptions {
            tissue: self.tissue,
            ..SimulationOptions::default()
        }
    }

    /// Whether `path` is a planning case: a `.json` file whose `format` is
    /// [`CASE_FORMAT`] (a landmark file, also `.json`, is not).
    pub fn is_case_file(path: &Path) -> bool {
        path.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
            && std::fs::read_to_string(path)
                .ok()
                .and_then(|text| serde_json::from_str::<Value>(&text).ok())
                .is_some_and(|v| v.get("format").and_then(Value::as_str) == Some(CASE_FORMAT))
    }

    /// Reads a case file; errors name the file and the field.
    pub fn read(path: &Path) -> Result<PlanningCase> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("reading the case {}", path.display()))?;
        PlanningCase::from_json(&text, path).with_context(|| format!("the case {}", path.display()))
    }

    /// Parses a case; `path` is where it came from (relative scan paths are taken from
    /// its folder).
    fn from_json(text: &str, path: &Path) -> Result<PlanningCase> {
        let record: CaseRecord = serde_json::from_str(text).context("not a planning case")?;
        ensure!(
            record.format == CASE_FORMAT,
            "format is \"{}\", expected \"{CASE_FORMAT}\"",
            record.format
        );
        ensure!(
            record.version == CASE_VERSION,
            "version {} is not the version {CASE_VERSION} this build reads",
            record.version
        );
        ensure!(
            record.units == "mm",
            "units are \"{}\", expected \"mm\"",
            record.units
        );
        let scan = match record.scan {
            ScanRecord::Path(scan) if scan.is_relative() => {
                let folder = path.parent().unwrap_or(Path::new(""));
                ScanSource::File(folder.join(scan))
            }
            ScanRecord::Path(scan) => ScanSource::File(scan),
            ScanRecord::Phantom(phantom) => ScanSource::Phantom(phantom.params()?),
        };
        let landmarks = PartialLandmarks::from_json(&record.landmarks.to_string(), path)
            .context("landmarks")?;
        let control_points = match &record.control_points {
            None | Some(Value::Null) => None,
            Some(value) => {
                Some(ControlPoints::from_json(&value.to_string(), path).context("control_points")?)
            }
        };
        let (low, high) = CASE_ELEMENTS_RANGE;
        let elements = record.model.elements;
        ensure!(
            (low..=high).contains(&elements),
            "model.elements is {elements}, expected {low} to {high}"
        );
        let tissue = Material::new(record.material.young_kpa, record.material.poisson_ratio);
        tissue
            .check()
            .map_err(|message| anyhow::anyhow!("material: {message}"))?;
        let implants = PerSide {
            left: record
                .implants
                .left
                .map(|r| r.request("left"))
                .transpose()?,
            right: record
                .implants
                .right
                .map(|r| r.request("right"))
                .transpose()?,
        };
        let up = record
            .up
            .map(|[x, y, z]| Up::parse(&format!("{x},{y},{z}")).context("up"))
            .transpose()?;
        let scan_units = record
            .scan_units
            .map(|symbol| {
                symbol
                    .parse::<LengthUnit>()
                    .map_err(|e| anyhow::anyhow!("scan_units: {e}"))
            })
            .transpose()?;
        Ok(PlanningCase {
            scan,
            up,
            scan_units,
            landmarks,
            control_points,
            elements,
            tissue,
            gravity: record.simulation.gravity,
            linked: record.implants.linked,
            implants,
        })
    }

    /// Writes the case atomically (pretty JSON; the scan path made absolute).
    pub fn write(&self, path: &Path) -> Result<()> {
        let scan = match &self.scan {
            ScanSource::File(scan) => {
                ScanRecord::Path(std::path::absolute(scan).unwrap_or_else(|_| scan.to_path_buf()))
            }
            ScanSource::Phantom(params) => ScanRecord::Phantom(PhantomRecord::from(params)),
        };
        let implant = |request: &Option<ImplantRequest>| {
            request.as_ref().map(|r| ImplantRecord {
                spec: r.spec.clone(),
                move_mm: r.move_mm.to_array(),
                rotation_deg: r.rotation_deg,
                fold_lowering_mm: r.fold_lowering_mm,
            })
        };
        let record = CaseRecord {
            format: CASE_FORMAT.into(),
            version: CASE_VERSION,
            units: "mm".into(),
            scan,
            up: self.up.map(|up| up.direction.to_array()),
            scan_units: self.scan_units.map(|unit| unit.symbol().to_string()),
            landmarks: self.landmarks.to_json(Default::default()),
            control_points: self.control_points.as_ref().map(ControlPoints::to_json),
            model: ModelRecord {
                elements: self.elements,
            },
            material: MaterialRecord {
                young_kpa: self.tissue.young_kpa,
                poisson_ratio: self.tissue.poisson_ratio,
            },
            simulation: SimulationRecord {
                gravity: self.gravity,
            },
            implants: ImplantsRecord {
                linked: self.linked,
                left: implant(&self.implants.left),
                right: implant(&self.implants.right),
            },
        };
        crate::write_json(path, &record)
            .with_context(|| format!("writing the case {}", path.display()))
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct CaseRecord {
    format: String,
    version: u32,
    units: String,
    scan: ScanRecord,
    /// The given up (file frame); absent when the file's vertical or an estimate serves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    up: Option<[f64; 3]>,
    /// The unit of the scan file's coordinates; absent: millimetres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    scan_units: Option<String>,
    landmarks: Value,
    #[serde(default)]
    control_points: Option<Value>,
    model: ModelRecord,
    material: MaterialRecord,
    simulation: SimulationRecord,
    implants: ImplantsRecord,
}

#[derive(Serialize, Deserialize)]
#[serde(rename_all = "lowercase", deny_unknown_fields)]
enum ScanRecord {
    Path(PathBuf),
    Phantom(PhantomRecord),
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PhantomRecord {
    cup: String,
    ptosis: f64,
    noise_mm: f64,
    asymmetry: f64,
    seed: u64,
    /// Cases written before occlusion existed read as without it.
    #[serde(default)]
    occlusion: bool,
}

impl From<&PhantomParams> for PhantomRecord {
    fn from(params: &PhantomParams) -> PhantomRecord {
        PhantomRecord {
            cup: params.cup.to_string(),
            ptosis: params.ptosis,
            noise_mm: params.noise_mm,
            asymmetry: params.asymmetry,
            seed: params.seed,
            occlusion: params.occlusion,
        }
    }
}

impl PhantomRecord {
    fn params(&self) -> Result<PhantomParams> {
        Ok(PhantomParams {
            cup: self.cup.parse().context("scan.phantom.cup")?,
            ptosis: self.ptosis,
            noise_mm: self.noise_mm,
            asymmetry: self.asymmetry,
            seed: self.seed,
            occlusion: self.occlusion,
        })
    }
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ModelRecord {
    elements: usize,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialRecord {
    young_kpa: f64,
    poisson_ratio: f64,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimulationRecord {
    gravity: bool,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ImplantsRecord {
    linked: bool,
    left: Option<ImplantRecord>,
    right: Option<ImplantRecord>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct ImplantRecord {
    spec: String,
    move_mm: [f64; 3],
    rotation_deg: f64,
    /// Absent or `null`: the fold lowered as planned for the implant.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fold_lowering_mm: Option<f64>,
}

impl ImplantRecord {
    /// The request, its spec checked (a catalog id is looked up when it is placed).
    fn request(self, side: &str) -> Result<ImplantRequest> {
        if let Err(error) = ImplantSpec::parse(&self.spec) {
            bail!("implants.{side}.spec: {error}");
        }
        if let Some(mm) = self.fold_lowering_mm
            && !(mm.is_finite() && mm >= 0.0)
        {
            bail!("implants.{side}.fold_lowering_mm: {mm} mm; expected a length of at least 0");
        }
        Ok(ImplantRequest {
            spec: self.spec,
            move_mm: DVec3::from_array(self.move_mm),
            rotation_deg: self.rotation_deg,
            fold_lowering_mm: self.fold_lowering_mm,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::MarkedScan;
    use anatomy::LandmarkName;

    fn phantom_case() -> PlanningCase {
        let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
        let mut case = PlanningCase::new(
            ScanSource::Phantom(PhantomParams::default()),
            PartialLandmarks::from(&marked.landmarks),
        );
        case.landmarks
            .extra
            .insert("scar".into(), DVec3::new(1.5, -2.25, 80.125));
        case.control_points = Some(ControlPoints {
            left: vec![DVec3::new(1.0, 2.0, 3.0); 4],
            right: vec![DVec3::new(-1.0, 2.0, 3.0); 5],
        });
        case.up = Some(Up::parse("-z").unwrap());
        case.elements = 8_000;
        case.tissue = Material::new(3.5, 0.4);
        case.gravity = false;
        case.linked = true;
        case.implants.left = Some(ImplantRequest {
            spec: "catalog:R-MOD-120".into(),
            move_mm: DVec3::new(-5.0, 10.0, 2.5),
            rotation_deg: 15.0,
            fold_lowering_mm: Some(12.5),
        });
        case.implants.right = Some(ImplantRequest::new(
            "anatomic:width=120,height=113,projection=42",
        ));
        case
    }

    #[test]
    fn a_case_reads_back_as_written() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("case.json");
        let case = phantom_case();
        case.write(&path).unwrap();
        assert!(PlanningCase::is_case_file(&path));
        let read = PlanningCase::read(&path).unwrap();
        // Every coordinate goes through JSON's shortest round-trip representation: equal.
        assert_eq!(read, case);
        let options = read.model_options();
        assert_eq!(options.elements, 8_000);
        assert_eq!(options.breast.control_points, case.control_points);
        assert_eq!(read.simulation_options().tissue, Material::new(3.5, 0.4));

        // A scan file: written absolute; a relative one is read from the case's folder.
        // Its unit is kept.
        let mut on_file = PlanningCase::new(
            ScanSource::File(dir.path().join("scan.ply")),
            PartialLandmarks::default(),
        );
        on_file.scan_units = Some(LengthUnit::Metre);
        on_file.write(&path).unwrap();
        assert!(
            std::fs::read_to_string(&path)
                .unwrap()
                .contains("\"scan_units\": \"m\"")
        );
        assert_eq!(PlanningCase::read(&path).unwrap(), on_file);
        let text = std::fs::read_to_string(&path).unwrap().replace(
            &dir.path().join("scan.ply").display().to_string(),
            "scan.ply",
        );
        std::fs::write(&path, text).unwrap();
        on_file.scan = ScanSource::File(dir.path().join("scan.ply"));
        assert_eq!(PlanningCase::read(&path).unwrap(), on_file);
        assert!(on_file.landmarks.get(LandmarkName::Pj).is_none());
        // A landmark file is not a case.
        let landmarks = dir.path().join("landmarks.json");
        case.landmarks.write(&landmarks).unwrap();
        assert!(!PlanningCase::is_case_file(&landmarks));
    }

    #[test]
    fn bad_cases_name_the_problem() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("case.json");
        phantom_case().write(&path).unwrap();
        let good = std::fs::read_to_string(&path).unwrap();
        let check = |from: &str, to: &str, expected: &str| {
            assert!(good.contains(from), "{from}");
            std::fs::write(&path, good.replacen(from, to, 1)).unwrap();
            let error = format!("{:#}", PlanningCase::read(&path).unwrap_err());
            assert!(error.contains(expected), "{error}");
            assert!(error.contains("case.json"), "{error}");
        };
        check(
            "\"elements\": 8000",
            "\"elements\": 10",
            "model.elements is 10",
        );
        check(
            "\"young_kpa\": 3.5",
            "\"young_kpa\": -1.0",
            "Young's modulus -1",
        );
        check(
            "\"catalog:R-MOD-120\"",
            "\"round:diameter=12\"",
            "implants.left.spec",
        );
        check(
            "\"cup\": \"medium\"",
            "\"cup\": \"huge\"",
            "unknown cup size",
        );
        check("\"version\": 1", "\"version\": 7", "version 7");
        check(
            "\"format\": \"mammaplan case\",",
            "\"format\": \"mammaplan case\", \"scan_units\": \"furlong\",",
            "scan_units: unknown unit \"furlong\"",
        );
        check(
            "\"gravity\": false",
            "\"gravity\": \"no\"",
            "not a planning case",
        );
        assert!(
            format!(
                "{:#}",
                PlanningCase::read(&dir.path().join("missing.json")).unwrap_err()
            )
            .contains("missing.json")
        );
    }
}
