//! Shared test fixtures: the phantom's patient model, built once per test binary.

#![allow(dead_code)]

use anatomy::breast::Side;
use anatomy::{AnatomicalFrame, Landmarks};
use phantom::{Cup, PhantomParams};
use plan::model::{ModelOptions, PatientModel, build_model};
use plan::{MarkedScan, Scan, Silent};
use simulation::{PatientInput, Simulation, SimulationOptions};
use std::path::Path;
use std::sync::OnceLock;

/// A patient model with its scan.
pub struct Patient {
    pub marked: MarkedScan,
    pub model: PatientModel,
}

impl Patient {
    pub fn input(&self) -> PatientInput<'_> {
        PatientInput {
            scan: &self.marked.scan.mesh,
            landmarks: &self.marked.landmarks,
            frame: &self.marked.frame,
            breasts: &self.model.breasts,
            closed_surface: &self.model.closed_surface,
            tets: &self.model.tets,
        }
    }

    pub fn frame(&self) -> &AnatomicalFrame {
        &self.marked.frame
    }

    pub fn landmarks(&self) -> &Landmarks {
        &self.marked.landmarks
    }

    pub fn session(&self, options: SimulationOptions) -> Simulation {
        Simulation::new(self.input(), options).expect("session")
    }
}

/// Elements of the phantom's finest level in the tests (the default of `model`).
pub const ELEMENTS: usize = 60_000;

/// The symmetric default phantom's model.
pub fn phantom() -> &'static Patient {
    static PATIENT: OnceLock<Patient> = OnceLock::new();
    PATIENT.get_or_init(|| patient("phantom", &default_model_options()).unwrap())
}

/// The symmetric phantom with large cups (about 560 ml): a 115 mm implant lies on its
/// native fill-in, with no pocket beyond it and no fold lowering.
pub fn large_phantom() -> &'static Patient {
    static PATIENT: OnceLock<Patient> = OnceLock::new();
    PATIENT.get_or_init(|| patient("phantom-large", &default_model_options()).unwrap())
}

/// The symmetric phantom with small hanging cups (ptosis 0.8, nipple 55-60 mm above the
/// fold): a 115 mm implant needs the fold lowered by the ICE rule's 25-30 mm.
pub fn small_hanging_phantom() -> &'static Patient {
    static PATIENT: OnceLock<Patient> = OnceLock::new();
    PATIENT.get_or_init(|| patient("phantom-small-hanging", &default_model_options()).unwrap())
}

/// `model`'s options with the tests' element count.
pub fn default_model_options() -> ModelOptions {
    ModelOptions {
        elements: ELEMENTS,
        ..Default::default()
    }
}

/// The model of a body with `options`: `phantom` (the symmetric default phantom),
/// `phantom-large` (the same with large cups), `phantom-small-hanging` (small hanging
/// cups), a shared scan, or a zoo body (`s01`..),
/// if present (see [`shared_scan`]).
pub fn patient(name: &str, options: &ModelOptions) -> Option<Patient> {
    let phantom_params = match name {
        "phantom" => Some(PhantomParams::default()),
        "phantom-large" => Some(PhantomParams {
            cup: Cup::Large,
            ..PhantomParams::default()
        }),
        "phantom-small-hanging" => Some(PhantomParams {
            cup: Cup::Small,
            ptosis: 0.8,
            ..PhantomParams::default()
        }),
        _ => None,
    };
    let marked = if let Some(params) = phantom_params {
        let phantom = phantom::generate(&params);
        MarkedScan::new(
            Scan::from_mesh(phantom.scan.clone(), Path::new("phantom.ply")).unwrap(),
            phantom.landmarks.clone(),
            Path::new("phantom.json"),
            None,
            &Silent,
        )
        .unwrap()
    } else {
        let dir = std::env::var_os("MAMMAPLAN_SCANS")
            .map(std::path::PathBuf::from)
            .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scans"));
        let zoo = name.len() == 3 && name.starts_with('s');
        let dir = if zoo { dir.join("zoo") } else { dir };
        let scan = dir.join(format!("{name}.ply"));
        let landmarks = dir.join(format!("{name}_landmarks.json"));
        if !scan.exists() || !landmarks.exists() {
            return None;
        }
        MarkedScan::load(&scan, &landmarks, None, &Silent).unwrap()
    };
    let model = build_model(&marked, options, &Silent).unwrap();
    Some(Patient { marked, model })
}

/// A shared scan's model (`shared/scans` beside the checkout, as the other crates' tests
/// find it, or `$MAMMAPLAN_SCANS`), if present.
pub fn shared_scan(name: &str) -> Option<Patient> {
    patient(name, &default_model_options())
}

/// The nipple of a side.
pub fn nipple(landmarks: &Landmarks, side: Side) -> glam::DVec3 {
    landmarks.get(match side {
        Side::Left => anatomy::LandmarkName::Pnl,
        Side::Right => anatomy::LandmarkName::Pnr,
    })
}

/// The largest stretch factor of a scan edge, `|moved edge| / |rest edge|`, and its two
/// vertices; prints where it is (anatomical frame) and how far its ends moved.
pub fn largest_edge_stretch(patient: &Patient, moved: &[glam::DVec3]) -> f64 {
    let mesh = &patient.marked.scan.mesh;
    let mut worst: f64 = 0.0;
    let mut at = (0, 0);
    for t in &mesh.triangles {
        for k in 0..3 {
            let (a, c) = (t[k] as usize, t[(k + 1) % 3] as usize);
            let before = mesh.positions[a].distance(mesh.positions[c]);
            let after = moved[a].distance(moved[c]);
            if before > 1e-9 && after / before > worst {
                worst = after / before;
                at = (a, c);
            }
        }
    }
    let f = patient.frame();
    println!(
        "largest edge stretch on the scan: {worst:.2}x, edge {:.2} mm -> {:.2} mm at {:.1?} (moved {:.1?}) and {:.1?} (moved {:.1?})",
        mesh.positions[at.0].distance(mesh.positions[at.1]),
        moved[at.0].distance(moved[at.1]),
        f.to_local(mesh.positions[at.0]).to_array(),
        (moved[at.0] - mesh.positions[at.0]).to_array(),
        f.to_local(mesh.positions[at.1]).to_array(),
        (moved[at.1] - mesh.positions[at.1]).to_array(),
    );
    worst
}
