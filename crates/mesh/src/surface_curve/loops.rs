//! Cutting small loops out of a closed curve: where a walk doubles back past a sample on
//! the steep side of a bump (a fold's lateral end at the scan's edge), the curve touches
//! itself and encloses a sliver; the sliver is dropped and the curve runs once round.

use super::{
    CurveLocation, CurvePoint, CurvesDefect, SurfaceCurve, Touching, check_curves,
    without_edge_spikes,
};
use crate::topology::Topology;
use crate::trimesh::TriMesh;

/// Largest share of the curve's length a dropped loop may have: a sliver at a control
/// point, not a part of the breast's border.
const MAX_LOOP_SHARE: f64 = 0.1;
/// Loops dropped at most (each check of the curve is `O(n log n)`).
const MAX_LOOPS: usize = 8;

/// `points` (a closed curve) with every loop shorter than [`MAX_LOOP_SHARE`] of its
/// length cut out at the point where it touches the rest of the curve.
pub(super) fn without_small_loops(
    mesh: &TriMesh,
    topology: &Topology,
    mut points: Vec<CurvePoint>,
) -> Vec<CurvePoint> {
    for _ in 0..MAX_LOOPS {
        let curve = [SurfaceCurve { points }];
        let checked = check_curves(mesh, topology, &curve);
        let [SurfaceCurve { points: unchanged }] = curve;
        points = unchanged;
        let Err(CurvesDefect::Touch { touching, .. }) = checked else {
            break;
        };
        let Some(shorter) = cut_loop(mesh, &points, touching) else {
            break;
        };
        points = without_edge_spikes(mesh, topology, shorter);
    }
    points
}

/// The curve with the shorter of the two arcs between the touching places replaced by
/// the touching point; `None` if that arc is longer than [`MAX_LOOP_SHARE`].
fn cut_loop(mesh: &TriMesh, points: &[CurvePoint], touching: Touching) -> Option<Vec<CurvePoint>> {
    let n = points.len();
    let point = |location: CurveLocation| CurvePoint {
        position: location.position(mesh),
        location,
    };
    // The inner arc runs over points `first + 1 ..= second`; the touching point takes
    // its place (for a vertex visited twice, that vertex: the point `first`).
    let (first, second, at) = match touching {
        Touching::Vertex {
            first_index,
            second_index,
        } => (first_index, second_index, None),
        Touching::Segments {
            first_index,
            second_index,
            at,
        } => (first_index, second_index, Some(point(at))),
    };
    let (first, second) = (first.min(second), first.max(second));
    if second >= n || first == second {
        return None;
    }
    let arc = |from: usize, to: usize| -> f64 {
        (from..to)
            .map(|k| {
                points[k % n]
                    .position
                    .distance(points[(k + 1) % n].position)
            })
            .sum()
    };
    let total = arc(0, n);
    let inner = arc(first, second + 1);
    let outer = total - inner;
    let kept: Vec<CurvePoint> = if inner <= outer {
        if inner > MAX_LOOP_SHARE * total {
            return None;
        }
        points[..=first]
            .iter()
            .cloned()
            .chain(at)
            .chain(points[second + 1..].iter().cloned())
            .collect()
    } else {
        if outer > MAX_LOOP_SHARE * total {
            return None;
        }
        match at {
            // The loop from the vertex round to itself, without its second visit.
            None => points[first..second].to_vec(),
            Some(at) => std::iter::once(at)
                .chain(points[first + 1..=second].iter().cloned())
                .collect(),
        }
    };
    (kept.len() >= 3).then_some(kept)
}
