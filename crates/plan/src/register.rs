//! `mammaplan register`: rigid registration of a moving scan onto a fixed one.

use crate::MarkedScan;
use anatomy::register::{
    FixedSurface, IcpOptions, RigidTransform, icp_point_to_plane, landmark_rms_mm,
    matching_samples, register_landmarks, surface_rms_mm,
};
use anyhow::{Context, Result};
use serde::Serialize;
use std::path::Path;

/// Moving-scan vertices used for ICP and for the surface RMS.
const SURFACE_SAMPLES: usize = 30_000;
/// Surface points farther than this from the other scan are outside the overlap (mm).
const OVERLAP_DISTANCE_MM: f64 = 10.0;

/// The JSON of `register` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct RegisterReport {
    /// Homogeneous 4x4, row-major, moving -> fixed.
    pub matrix: [[f64; 4]; 4],
    /// RMS of the bony landmarks Pcl, Pcr, Pj, Px after registration.
    pub landmark_rms_mm: f64,
    /// RMS distance from the registered moving surface to the fixed surface, away from
    /// the breasts, over the overlap (points within 10 mm).
    pub surface_rms_mm: f64,
    /// The same before ICP (after the landmark fit).
    pub surface_rms_landmarks_only_mm: f64,
    /// Moving-scan points that entered the surface RMS.
    pub surface_points: usize,
    pub icp: bool,
    pub icp_iterations: usize,
    pub rotation_deg: f64,
    pub translation_mm: [f64; 3],
}

/// Registers `moving` onto `fixed`: bony landmarks first, then ICP if asked.
pub fn register(
    fixed: &MarkedScan,
    moving: &MarkedScan,
    icp: bool,
) -> Result<(RigidTransform, RegisterReport)> {
    let context = || {
        format!(
            "registering {} onto {}",
            moving.scan.path.display(),
            fixed.scan.path.display()
        )
    };
    let by_landmarks =
        register_landmarks(&moving.landmarks, &fixed.landmarks).with_context(context)?;
    let surface = FixedSurface::new(
        &fixed.scan.mesh,
        &fixed.scan.index,
        &fixed.scan.topology,
        &fixed.landmarks,
    );
    let samples = matching_samples(&moving.scan.mesh, &moving.landmarks, SURFACE_SAMPLES);
    let (rms_landmarks_only, _) =
        surface_rms_mm(&surface, &samples, &by_landmarks, OVERLAP_DISTANCE_MM);
    let (transform, iterations) = if icp {
        let result = icp_point_to_plane(&surface, &samples, by_landmarks, &IcpOptions::default())
            .with_context(context)?;
        (result.transform, result.iterations)
    } else {
        (by_landmarks, 0)
    };
    let (surface_rms, surface_points) =
        surface_rms_mm(&surface, &samples, &transform, OVERLAP_DISTANCE_MM);
    let report = RegisterReport {
        matrix: transform.to_row_major(),
        landmark_rms_mm: landmark_rms_mm(&moving.landmarks, &fixed.landmarks, &transform),
        surface_rms_mm: surface_rms,
        surface_rms_landmarks_only_mm: rms_landmarks_only,
        surface_points,
        icp,
        icp_iterations: iterations,
        rotation_deg: transform.rotation_angle_deg(),
        translation_mm: transform.translation.to_array(),
    };
    Ok((transform, report))
}

/// Writes the moving scan moved onto the fixed scan (texture and colours kept).
pub fn write_registered_mesh(
    path: &Path,
    moving: &MarkedScan,
    transform: &RigidTransform,
) -> Result<()> {
    let mut mesh = moving.scan.mesh.clone();
    mesh.map_positions(|p| transform.apply(p));
    mesh::io::write_mesh(path, &mesh).with_context(|| format!("writing {}", path.display()))
}
