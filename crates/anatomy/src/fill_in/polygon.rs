//! Predicates on the projected loop, a polygon in the plane: its orientation and whether
//! it is simple, the latter with exact orientation signs (`robust::orient2d`).

use super::FillInError;
use glam::DVec2;
use robust::{Coord, orient2d};

/// Whether a simple polygon runs counter-clockwise (its signed area is positive).
pub(super) fn is_counter_clockwise(polygon: &[DVec2]) -> bool {
    let n = polygon.len();
    let twice_area: f64 = (0..n)
        .map(|k| polygon[k].perp_dot(polygon[(k + 1) % n]))
        .sum();
    twice_area > 0.0
}

/// Errors unless the closed polygon is simple: no edge of zero length, no two edges
/// touching except consecutive ones at their shared corner. Edges are swept in order of
/// their smallest `u`, so only edges overlapping in `u` are compared.
pub(super) fn check_simple(polygon: &[DVec2]) -> Result<(), FillInError> {
    let n = polygon.len();
    let edge = |k: usize| (polygon[k], polygon[(k + 1) % n]);
    for k in 0..n {
        let ((a, b), c) = (edge(k), polygon[(k + 2) % n]);
        let folds_back = orientation(a, b, c) == 0.0 && (a - b).dot(c - b) > 0.0;
        if a == b || folds_back {
            return Err(FillInError::NotSimple { edge: k });
        }
    }
    let min_u: Vec<f64> = (0..n).map(|k| edge(k).0.x.min(edge(k).1.x)).collect();
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by(|&k, &l| min_u[k].total_cmp(&min_u[l]));
    for (rank, &k) in order.iter().enumerate() {
        let (a, b) = edge(k);
        for &l in &order[rank + 1..] {
            if min_u[l] > a.x.max(b.x) {
                break;
            }
            let (c, d) = edge(l);
            let consecutive = (k + 1) % n == l || (l + 1) % n == k;
            if !consecutive && segments_touch(a, b, c, d) {
                return Err(FillInError::NotSimple { edge: k.min(l) });
            }
        }
    }
    Ok(())
}

/// Twice the signed area of triangle `abc` (positive counter-clockwise), with the exact
/// sign (`robust::orient2d`, adaptive precision): zero exactly when the three points are
/// collinear. The plain `(b - a) × (c - a)` in floating point gets the sign wrong, or
/// gives zero, for points nearly collinear, and so could pass a loop that touches itself
/// or refuse one that does not.
pub(super) fn orientation(a: DVec2, b: DVec2, c: DVec2) -> f64 {
    let coord = |p: DVec2| Coord { x: p.x, y: p.y };
    orient2d(coord(a), coord(b), coord(c))
}

/// Whether segments `ab` and `cd` share at least one point.
fn segments_touch(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let (c_side, d_side) = (orientation(a, b, c), orientation(a, b, d));
    let (a_side, b_side) = (orientation(c, d, a), orientation(c, d, b));
    let opposite = |x: f64, y: f64| (x > 0.0 && y < 0.0) || (x < 0.0 && y > 0.0);
    let on = |p: DVec2, from: DVec2, to: DVec2| {
        p.cmpge(from.min(to)).all() && p.cmple(from.max(to)).all()
    };
    (opposite(c_side, d_side) && opposite(a_side, b_side))
        || (c_side == 0.0 && on(c, a, b))
        || (d_side == 0.0 && on(d, a, b))
        || (a_side == 0.0 && on(a, c, d))
        || (b_side == 0.0 && on(b, c, d))
}

/// Distance (mm) from `p` to segment `ab`.
pub(super) fn distance_to_segment(p: DVec2, a: DVec2, b: DVec2) -> f64 {
    let ab = b - a;
    let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
    if t.is_nan() {
        return p.distance(a);
    }
    p.distance(a + t * ab)
}
