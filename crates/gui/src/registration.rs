//! A second scan of the same patient (the post-operative one) registered onto the scan
//! being planned: `plan`'s registration (bony landmarks, then point-to-plane ICP away from
//! the breasts, as `mammaplan register --icp` and `mammaplan compare --register`), the
//! scan moved into the planned scan's frame with its landmarks, ready to be drawn and
//! compared. Slow (seconds): the window runs it on a [`crate::job::Job`].

use crate::render::SceneMesh;
use anatomy::Landmarks;
use anyhow::{Context, Result};
use plan::register::{RegisterReport, register};
use plan::{MarkedScan, Scan, Silent};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A scan registered onto the planned one.
pub struct RegisteredScan {
    /// The scan file and its landmark file, as given.
    pub scan_path: PathBuf,
    pub landmarks_path: PathBuf,
    /// The registration: matrix (moving to fixed), landmark and surface RMS.
    pub report: RegisterReport,
    /// The scan moved onto the planned one, with its spatial index.
    pub scan: Arc<Scan>,
    /// Its landmarks, moved the same way.
    pub landmarks: Landmarks,
    /// The moved scan as drawn (its own colours).
    pub scene: Arc<SceneMesh>,
}

impl RegisteredScan {
    /// Loads the scan at `scan_path` with the landmarks at `landmarks_path` and registers
    /// it onto `fixed` (with ICP).
    pub fn register(
        fixed: &MarkedScan,
        scan_path: &Path,
        landmarks_path: &Path,
    ) -> Result<RegisteredScan> {
        let moving = MarkedScan::load(scan_path, landmarks_path, None, &Silent)?;
        let (transform, report) = register(fixed, &moving, true)?;
        let positions = (moving.scan.mesh.positions.iter())
            .map(|&p| transform.apply(p))
            .collect();
        let scan = moving
            .scan
            .moved_to(positions, scan_path)
            .context("the registered scan")?;
        let mut landmarks = moving.landmarks.clone();
        landmarks.map_positions(|p| transform.apply(p));
        Ok(RegisteredScan {
            scan_path: scan_path.to_path_buf(),
            landmarks_path: landmarks_path.to_path_buf(),
            report,
            scene: Arc::new(SceneMesh::of_scan(&scan)),
            scan: Arc::new(scan),
            landmarks,
        })
    }
}
