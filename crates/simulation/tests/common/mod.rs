//! Shared test fixtures: the phantom's patient model, built once per test binary.

#![allow(dead_code)]

use anatomy::breast::Side;
use anatomy::{AnatomicalFrame, Landmarks};
use phantom::PhantomParams;
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
    PATIENT.get_or_init(|| {
        let phantom = phantom::generate(&PhantomParams::default());
        let marked = MarkedScan::new(
            Scan::from_mesh(phantom.scan.clone(), Path::new("phantom.ply")).unwrap(),
            phantom.landmarks.clone(),
            Path::new("phantom.json"),
            &Silent,
        )
        .unwrap();
        let options = ModelOptions {
            elements: ELEMENTS,
            ..Default::default()
        };
        let model = build_model(&marked, &options, &Silent).unwrap();
        Patient { marked, model }
    })
}

/// A shared scan's model (`/work/shared/scans` or `$MAMMAPLAN_SCANS`), if present.
pub fn shared_scan(name: &str) -> Option<Patient> {
    let dir = std::env::var("MAMMAPLAN_SCANS").unwrap_or_else(|_| "/work/shared/scans".into());
    let dir = Path::new(&dir);
    let scan = dir.join(format!("{name}.ply"));
    let landmarks = dir.join(format!("{name}_landmarks.json"));
    if !scan.exists() || !landmarks.exists() {
        return None;
    }
    let marked = MarkedScan::load(&scan, &landmarks, &Silent).unwrap();
    let options = ModelOptions {
        elements: ELEMENTS,
        ..Default::default()
    };
    let model = build_model(&marked, &options, &Silent).unwrap();
    Some(Patient { marked, model })
}

/// The nipple of a side.
pub fn nipple(landmarks: &Landmarks, side: Side) -> glam::DVec3 {
    landmarks.get(match side {
        Side::Left => anatomy::LandmarkName::Pnl,
        Side::Right => anatomy::LandmarkName::Pnr,
    })
}
