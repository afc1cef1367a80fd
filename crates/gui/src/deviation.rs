//! The deviation colour map of the paper's Fig. 3 in the window: a scan coloured by each
//! vertex's distance from a reference surface, with its statistics over the overlap.
//! The distances, the overlap of two open scans, the statistics and the colour ramp are
//! `assess`'s (as `mammaplan compare` computes them); this module only puts them on a
//! scene the viewport draws. Computing a map takes a second on a large scan: the window
//! runs it on a [`crate::job::Job`].

use crate::render::SceneMesh;
use anyhow::{Context, Result};
use assess::{
    DEFAULT_MAX_DISTANCE_MM, DeviationStatistics, DistanceSurface, SurfaceComparison, Zone,
    deviation_color,
};
use plan::Scan;
use std::sync::Arc;

/// A scan coloured by its distance from a reference surface.
pub struct DeviationMap {
    /// Per vertex of the coloured scan, its distance from the reference surface (mm;
    /// NaN outside the overlap).
    pub distances_mm: Vec<f64>,
    /// Over the overlap (the test vertices over the reference surface within
    /// [`DEFAULT_MAX_DISTANCE_MM`]).
    pub statistics: DeviationStatistics,
    /// The fraction of the scan's vertices in the overlap.
    pub overlap_fraction: f64,
    /// The scan drawn in the map's colours.
    pub scene: Arc<SceneMesh>,
}

impl DeviationMap {
    /// The deviation of `test` from the surface of `reference` (both in the same frame),
    /// drawn on `test_scene` (the scene of `test`: same vertices) in the colours of
    /// [`deviation_color`]. Fails when the scans do not overlap.
    pub fn compute(reference: &Scan, test: &Scan, test_scene: &SceneMesh) -> Result<DeviationMap> {
        let reference_surface =
            DistanceSurface::new(&reference.mesh, &reference.index, &reference.topology);
        let test_surface = DistanceSurface::new(&test.mesh, &test.index, &test.topology);
        let comparison = SurfaceComparison::new(
            &reference_surface,
            vec![None; reference.mesh.vertex_count()],
            &test_surface,
            vec![None; test.mesh.vertex_count()],
            DEFAULT_MAX_DISTANCE_MM,
        )
        .with_context(|| {
            format!(
                "the deviation of {} from {}",
                test.path.display(),
                reference.path.display()
            )
        })?;
        let statistics = comparison
            .statistics(Zone::Whole)
            .context("no vertex in the overlap")?;
        let distances_mm = comparison.test_distances_mm();
        let colors: Vec<[u8; 3]> = distances_mm.iter().map(|&d| deviation_color(d)).collect();
        Ok(DeviationMap {
            statistics,
            overlap_fraction: comparison.test_overlap_fraction(),
            scene: Arc::new(test_scene.recoloured(&colors)),
            distances_mm,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use std::path::Path;

    #[test]
    fn a_sheet_moved_along_its_normal_deviates_by_the_move_inside_the_overlap() {
        // A 20 x 20 mm sheet and the same sheet 3 mm in front of it, shifted 5 mm
        // sideways: over the overlap every vertex is exactly 3 mm away; the vertices
        // beyond the reference's border (x > 20) are outside the overlap.
        let reference = Scan::from_mesh(mesh::shapes::grid(20, 20, 1.0), Path::new("a")).unwrap();
        let moved = (reference.mesh.positions.iter())
            .map(|p| *p + DVec3::new(5.0, 0.0, 3.0))
            .collect();
        let test = reference.moved_to(moved, Path::new("b")).unwrap();
        let scene = SceneMesh::new(&test.mesh);
        let map = DeviationMap::compute(&reference, &test, &scene).unwrap();
        for (p, d) in test.mesh.positions.iter().zip(&map.distances_mm) {
            // Strictly inside the reference (x < 20, 0 < y < 20): over it.
            if p.x < 19.5 && p.y > 0.5 && p.y < 19.5 {
                assert!((d - 3.0).abs() < 1e-9, "{p}: {d}");
            }
            if p.x > 20.5 {
                assert!(d.is_nan(), "{p}: {d}");
            }
        }
        assert!((map.statistics.rms_mm - 3.0).abs() < 1e-9);
        assert!(map.overlap_fraction > 0.6 && map.overlap_fraction < 0.9);

        // A scan against itself: zero wherever it overlaps itself (all but the border).
        let itself = DeviationMap::compute(&reference, &reference, &scene).unwrap();
        // (The closest point of a vertex is itself, to rounding.)
        assert!(itself.distances_mm.iter().all(|d| d.is_nan() || *d < 1e-9));
        assert!(itself.statistics.rms_mm < 1e-9);
    }
}
