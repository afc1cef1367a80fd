//! `mammaplan measure`: the clinical distance table of one scan.

use crate::{MarkedScan, Scan};
use anatomy::measure::{
    Distance, DistanceSpec, MeasuredSurface, UnknownLandmark, clinical_distances, measure_distances,
};
use anatomy::scan_holes::{ClosedHole, close_scan_holes};
use anatomy::{AnatomicalFrame, NamedPoints};
use anyhow::{Context, Result};
use mesh::{SurfaceIndex, Topology};
use serde::Serialize;

/// The JSON of `measure` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct MeasureReport {
    pub scan: String,
    pub landmarks: String,
    /// Which way was up in the scan's file (the coronal plane of the plane-section
    /// distances is vertical), with the sternum's lean from it.
    pub up: crate::UpRecord,
    pub distances: Vec<Distance>,
    /// Scanner holes closed (fill-in) before the on-surface measurements.
    pub holes_closed: Vec<HoleSummary>,
}

/// A closed scanner hole.
#[derive(Debug, Clone, Serialize)]
pub struct HoleSummary {
    pub perimeter_mm: f64,
    pub centre_mm: [f64; 3],
}

impl From<&ClosedHole> for HoleSummary {
    fn from(hole: &ClosedHole) -> HoleSummary {
        HoleSummary {
            perimeter_mm: hole.perimeter_mm,
            centre_mm: hole.centre,
        }
    }
}

/// A scan prepared for measuring: its holes closed with the smooth fill-in (as a tape
/// measure would lie across them), with connectivity and spatial index. Built once per
/// scan; [`MeasuringSurface::distances`] can then be called for every landmark change.
pub struct MeasuringSurface {
    mesh: mesh::TriMesh,
    topology: Topology,
    index: SurfaceIndex,
    /// Scanner holes closed before measuring.
    pub holes_closed: Vec<HoleSummary>,
}

impl MeasuringSurface {
    /// Closes the scan's holes; a hole that cannot be closed is a warning (paths go
    /// around it).
    pub fn new(scan: &Scan, progress: &dyn crate::Progress) -> Result<MeasuringSurface> {
        let closed = close_scan_holes(
            &scan.mesh,
            &scan.topology,
            &anatomy::FillInParams::default(),
        );
        for hole in &closed.left_open {
            progress.warn(&format!(
                "{}: {hole}; paths go around it",
                scan.path.display()
            ));
        }
        let topology = Topology::new(&closed.mesh);
        let index = SurfaceIndex::new(&closed.mesh)
            .with_context(|| format!("{}: the mesh has no triangles", scan.path.display()))?;
        Ok(MeasuringSurface {
            holes_closed: closed.closed.iter().map(HoleSummary::from).collect(),
            mesh: closed.mesh,
            topology,
            index,
        })
    }

    /// Measures `specs` between named points on the surface (mm): Euclidean, along the
    /// plane section orthogonal to the coronal plane of `frame`, and geodesic.
    pub fn distances(
        &self,
        frame: &AnatomicalFrame,
        points: &impl NamedPoints,
        specs: &[DistanceSpec],
    ) -> Result<Vec<Distance>, UnknownLandmark> {
        let surface = MeasuredSurface {
            mesh: &self.mesh,
            topology: &self.topology,
            index: &self.index,
        };
        measure_distances(&surface, frame, points, specs)
    }
}

/// Measures the eleven clinical distances plus `extra_pairs` (landmark or extra-point
/// names) on the scan with its holes closed, as a tape measure would lie across them.
pub fn measure(
    marked: &MarkedScan,
    extra_pairs: &[(String, String)],
    progress: &dyn crate::Progress,
) -> Result<MeasureReport> {
    let mut specs = clinical_distances();
    specs.extend(extra_pairs.iter().map(|(a, b)| DistanceSpec::between(a, b)));
    let surface = MeasuringSurface::new(&marked.scan, progress)?;
    let distances = surface
        .distances(&marked.frame, &marked.landmarks, &specs)
        .with_context(|| marked.landmarks_path.display().to_string())?;
    Ok(MeasureReport {
        scan: marked.scan.path.display().to_string(),
        landmarks: marked.landmarks_path.display().to_string(),
        up: crate::UpRecord::of(&marked.frame),
        distances,
        holes_closed: surface.holes_closed,
    })
}
