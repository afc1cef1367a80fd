//! `mammaplan measure`: the clinical distance table of one scan.

use crate::MarkedScan;
use anatomy::measure::{
    Distance, DistanceSpec, MeasuredSurface, clinical_distances, measure_distances,
};
use anatomy::scan_holes::{ClosedHole, close_scan_holes};
use anyhow::{Context, Result};
use mesh::{SurfaceIndex, Topology};
use serde::Serialize;

/// The JSON of `measure` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct MeasureReport {
    pub scan: String,
    pub landmarks: String,
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

/// Measures the eleven clinical distances plus `extra_pairs` (landmark or extra-point
/// names) on the scan with its holes closed, as a tape measure would lie across them.
pub fn measure(
    marked: &MarkedScan,
    extra_pairs: &[(String, String)],
    progress: &dyn crate::Progress,
) -> Result<MeasureReport> {
    let mut specs = clinical_distances();
    specs.extend(extra_pairs.iter().map(|(a, b)| DistanceSpec::between(a, b)));
    let scan = &marked.scan;
    let closed = close_scan_holes(&scan.mesh, &scan.topology);
    for hole in &closed.left_open {
        progress.warn(&format!(
            "{}: a hole of {:.0} mm perimeter near {:.0?} stays open ({}); paths go around it",
            scan.path.display(),
            hole.perimeter_mm,
            hole.centre,
            hole.reason
        ));
    }
    let topology = Topology::new(&closed.mesh);
    let index = SurfaceIndex::new(&closed.mesh)
        .with_context(|| format!("{}: the mesh has no triangles", scan.path.display()))?;
    let surface = MeasuredSurface {
        mesh: &closed.mesh,
        topology: &topology,
        index: &index,
    };
    let distances = measure_distances(&surface, &marked.frame, &marked.landmarks, &specs)
        .with_context(|| marked.landmarks_path.display().to_string())?;
    Ok(MeasureReport {
        scan: scan.path.display().to_string(),
        landmarks: marked.landmarks_path.display().to_string(),
        distances,
        holes_closed: closed.closed.iter().map(HoleSummary::from).collect(),
    })
}
