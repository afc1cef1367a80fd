//! The comparison of a test surface with a reference surface (paper VI-D: the real
//! post-operative scan is the reference, the simulation the test): per-vertex
//! deviations in both directions and their statistics over the whole overlap and over
//! the breast regions.
//!
//! The statistics are over vertices, as the paper's "node to surface root mean square":
//! `rms_mm`, `mean_mm` (unsigned), `signed_mean_mm` and the 95th percentile are over the
//! test vertices in the overlap (and the zone), each vertex's distance to the reference
//! surface. `hausdorff_mm` is symmetric: the larger of the farthest test vertex from the
//! reference surface and the farthest reference vertex (in the overlap and the zone of
//! the reference) from the test surface. Taking vertices rather than every surface point
//! underestimates the Hausdorff distance by at most the deviation's change across half a
//! triangle (well under 0.1 mm on a scan with 2 mm triangles).

use crate::AssessError;
use crate::deviation::{DistanceSurface, PointDeviation};
use anatomy::Side;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

/// Which vertices a statistic covers. Breast regions are the regions inside each
/// breast's cut curve on each scan ([`anatomy::BreastModel::scan_vertex_sides`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Zone {
    /// The whole overlap.
    Whole,
    /// One breast region.
    Breast(Side),
    /// Both breast regions.
    Breasts,
}

impl Zone {
    /// Whether a vertex in breast region `side` (`None`: not in a breast) is in the zone.
    pub fn contains(self, side: Option<Side>) -> bool {
        match self {
            Zone::Whole => true,
            Zone::Breast(zone_side) => side == Some(zone_side),
            Zone::Breasts => side.is_some(),
        }
    }
}

/// The breast regions of `points` taken from another surface: each point gets the region
/// of the vertex of `from` nearest to its closest point on `from` (`None` farther than
/// `max_distance_mm`). For a scan whose own breast model is missing, its regions from
/// the other scan's cut curves.
pub fn transfer_sides(
    from: &DistanceSurface<'_>,
    from_sides: &[Option<Side>],
    points: &[DVec3],
    max_distance_mm: f64,
) -> Vec<Option<Side>> {
    points
        .par_iter()
        .map(|&p| {
            from.nearest_vertex(p, max_distance_mm)
                .and_then(|v| from_sides[v])
        })
        .collect()
}

/// The statistics of the deviation over one zone (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct DeviationStatistics {
    /// Test vertices in the zone and the overlap: what the figures below are over.
    pub vertices: usize,
    /// Root mean square of the test vertices' distances to the reference surface.
    pub rms_mm: f64,
    /// Mean of those distances (unsigned).
    pub mean_mm: f64,
    /// Mean of the signed distances: positive where the test surface lies in front of
    /// the reference (outside the body), negative behind it.
    pub signed_mean_mm: f64,
    /// 95th percentile of the distances (nearest rank).
    pub percentile_95_mm: f64,
    /// The farthest test vertex from the reference surface.
    pub max_test_to_reference_mm: f64,
    /// The farthest reference vertex (of the zone, in the overlap) from the test
    /// surface; `None` if no reference vertex of the zone overlaps the test surface.
    pub max_reference_to_test_mm: Option<f64>,
    /// The symmetric Hausdorff distance: the larger of the two maxima.
    pub hausdorff_mm: f64,
}

/// The statistics over the whole overlap and the breast regions; a breast zone with no
/// test vertex in the overlap has none.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ZoneStatistics {
    pub whole: DeviationStatistics,
    pub left_breast: Option<DeviationStatistics>,
    pub right_breast: Option<DeviationStatistics>,
    pub both_breasts: Option<DeviationStatistics>,
}

/// A test surface compared with a reference surface, vertex by vertex in both
/// directions.
#[derive(Debug, Clone)]
pub struct SurfaceComparison {
    /// Per test vertex, its deviation from the reference surface (`None` outside the
    /// overlap).
    pub test_to_reference: Vec<Option<PointDeviation>>,
    /// Per reference vertex, its deviation from the test surface (`None` outside).
    pub reference_to_test: Vec<Option<PointDeviation>>,
    /// Per test vertex, the breast region it lies in.
    pub test_sides: Vec<Option<Side>>,
    /// Per reference vertex, the breast region it lies in.
    pub reference_sides: Vec<Option<Side>>,
    /// Points farther than this from the other surface are outside the overlap (mm).
    pub max_distance_mm: f64,
}

impl SurfaceComparison {
    /// Compares `test` with `reference` (both in the same frame), given the breast
    /// region of every vertex of each (all `None` to compare without breast regions).
    /// Fails on non-finite coordinates, a non-positive `max_distance_mm`, region lists
    /// of the wrong size, and when no test vertex overlaps the reference surface.
    pub fn new(
        reference: &DistanceSurface<'_>,
        reference_sides: Vec<Option<Side>>,
        test: &DistanceSurface<'_>,
        test_sides: Vec<Option<Side>>,
        max_distance_mm: f64,
    ) -> Result<SurfaceComparison, AssessError> {
        if max_distance_mm.is_nan() || max_distance_mm <= 0.0 {
            return Err(AssessError::InvalidMaxDistance(max_distance_mm));
        }
        for (role, surface, sides) in [
            ("reference", reference, &reference_sides),
            ("test", test, &test_sides),
        ] {
            surface
                .mesh()
                .validate()
                .map_err(|source| AssessError::Mesh { role, source })?;
            if sides.len() != surface.mesh().vertex_count() {
                return Err(AssessError::SizeMismatch {
                    what: "the breast region list",
                    role,
                    found: sides.len(),
                    expected: surface.mesh().vertex_count(),
                });
            }
        }
        let test_to_reference = reference.deviations(&test.mesh().positions, max_distance_mm);
        if test_to_reference.iter().all(Option::is_none) {
            return Err(AssessError::NoOverlap { max_distance_mm });
        }
        let reference_to_test = test.deviations(&reference.mesh().positions, max_distance_mm);
        Ok(SurfaceComparison {
            test_to_reference,
            reference_to_test,
            test_sides,
            reference_sides,
            max_distance_mm,
        })
    }

    /// The statistics over `zone`, or `None` if no test vertex of the zone is in the
    /// overlap.
    pub fn statistics(&self, zone: Zone) -> Option<DeviationStatistics> {
        let in_zone = |deviations: &[Option<PointDeviation>], sides: &[Option<Side>]| {
            deviations
                .iter()
                .zip(sides)
                .filter(|(_, side)| zone.contains(**side))
                .filter_map(|(deviation, _)| *deviation)
                .collect::<Vec<PointDeviation>>()
        };
        let test = in_zone(&self.test_to_reference, &self.test_sides);
        if test.is_empty() {
            return None;
        }
        let count = test.len() as f64;
        let mut distances: Vec<f64> = test.iter().map(|d| d.distance_mm).collect();
        distances.sort_by(f64::total_cmp);
        let rank_95 = (0.95 * count).ceil() as usize;
        let max_test_to_reference_mm = distances[distances.len() - 1];
        let max_reference_to_test_mm = in_zone(&self.reference_to_test, &self.reference_sides)
            .iter()
            .map(|d| d.distance_mm)
            .reduce(f64::max);
        Some(DeviationStatistics {
            vertices: test.len(),
            rms_mm: (distances.iter().map(|d| d * d).sum::<f64>() / count).sqrt(),
            mean_mm: distances.iter().sum::<f64>() / count,
            signed_mean_mm: test.iter().map(|d| d.signed_distance_mm).sum::<f64>() / count,
            percentile_95_mm: distances[rank_95.clamp(1, distances.len()) - 1],
            max_test_to_reference_mm,
            max_reference_to_test_mm,
            hausdorff_mm: max_reference_to_test_mm.map_or(max_test_to_reference_mm, |m| {
                m.max(max_test_to_reference_mm)
            }),
        })
    }

    /// The statistics over the whole overlap and each breast zone.
    pub fn zone_statistics(&self) -> ZoneStatistics {
        ZoneStatistics {
            whole: self
                .statistics(Zone::Whole)
                .expect("a comparison has at least one test vertex in the overlap"),
            left_breast: self.statistics(Zone::Breast(Side::Left)),
            right_breast: self.statistics(Zone::Breast(Side::Right)),
            both_breasts: self.statistics(Zone::Breasts),
        }
    }

    /// The fraction of test vertices in the overlap.
    pub fn test_overlap_fraction(&self) -> f64 {
        overlap_fraction(&self.test_to_reference)
    }

    /// The fraction of reference vertices in the overlap.
    pub fn reference_overlap_fraction(&self) -> f64 {
        overlap_fraction(&self.reference_to_test)
    }

    /// Per test vertex, its distance to the reference surface (mm; NaN outside the
    /// overlap).
    pub fn test_distances_mm(&self) -> Vec<f64> {
        self.test_to_reference
            .iter()
            .map(|d| d.map_or(f64::NAN, |d| d.distance_mm))
            .collect()
    }

    /// Per test vertex, its signed distance to the reference surface (mm; NaN outside
    /// the overlap).
    pub fn test_signed_distances_mm(&self) -> Vec<f64> {
        self.test_to_reference
            .iter()
            .map(|d| d.map_or(f64::NAN, |d| d.signed_distance_mm))
            .collect()
    }
}

fn overlap_fraction(deviations: &[Option<PointDeviation>]) -> f64 {
    let inside = deviations.iter().filter(|d| d.is_some()).count();
    inside as f64 / deviations.len().max(1) as f64
}
