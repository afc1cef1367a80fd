//! Predicates on the projected loop, a polygon in the plane: its orientation and whether
//! it is simple, the latter with exact orientation signs (`robust::orient2d`); and the
//! straightening of its small folds.

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

/// Where a closed polygon first fails to be simple.
struct Defect {
    /// The first of the edges at fault, as [`FillInError::NotSimple`] names it.
    edge: usize,
    /// The shorter stretch of the loop holding the fault: the positions strictly after
    /// `from` and before `from + inner + 1` (modulo the length), the ends kept. `inner`
    /// zero: a zero-length edge, which laying points on a chord cannot mend.
    from: usize,
    inner: usize,
}

/// The first zero-length edge, fold-back or touching pair of edges; `None` for a simple
/// polygon. Edges are swept in order of their smallest `u`, so only edges overlapping in
/// `u` are compared.
fn first_defect(polygon: &[DVec2]) -> Option<Defect> {
    let n = polygon.len();
    let edge = |k: usize| (polygon[k], polygon[(k + 1) % n]);
    for k in 0..n {
        let ((a, b), c) = (edge(k), polygon[(k + 2) % n]);
        if a == b {
            return Some(Defect {
                edge: k,
                from: k,
                inner: 0,
            });
        }
        if orientation(a, b, c) == 0.0 && (a - b).dot(c - b) > 0.0 {
            return Some(Defect {
                edge: k,
                from: k,
                inner: 1,
            });
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
                let (first, last) = (k.min(l), k.max(l));
                // Edges `first` and `last` touch: between them lie either the positions
                // first + 1 ..= last, or last + 1 ..= first going round.
                let forward = last - first;
                let (from, inner) = if forward <= n - forward {
                    (first, forward)
                } else {
                    (last, n - forward)
                };
                return Some(Defect {
                    edge: first,
                    from,
                    inner,
                });
            }
        }
    }
    None
}

/// Makes a polygon simple by straightening its small folds: where it first fails to be
/// simple, the points of the shorter stretch of loop between the edges at fault are laid
/// on the chord between the stretch's ends, in the order and at the spacing of their
/// path, and so on until it is simple. Refused (the polygon unchanged, the error that of
/// the first fault) when that would move a point more than `max_move` from where it
/// started, or takes more than `MAX_STRAIGHTENED` rounds.
///
/// For the fill-in these points only parameterise the triangulation, the 3D loop keeps
/// its positions: a scan's cut curve seen from a plane it grazes can turn back on itself
/// by a fraction of a millimetre, far below the lattice spacing, where no plane sees it
/// simple.
pub(super) fn straighten_small_folds(
    polygon: &mut [DVec2],
    max_move: f64,
) -> Result<(), FillInError> {
    const MAX_STRAIGHTENED: usize = 64;
    let original = polygon.to_vec();
    let n = polygon.len();
    let refuse = |polygon: &mut [DVec2], error: FillInError| {
        polygon.copy_from_slice(&original);
        Err(error)
    };
    let Some(first) = first_defect(polygon) else {
        return Ok(());
    };
    let error = FillInError::NotSimple { edge: first.edge };
    let mut defect = first;
    for _ in 0..MAX_STRAIGHTENED {
        if defect.inner == 0 {
            return refuse(polygon, error);
        }
        let stretch: Vec<usize> = (0..defect.inner + 2)
            .map(|k| (defect.from + k) % n)
            .collect();
        let along: Vec<f64> = std::iter::once(0.0)
            .chain(stretch.windows(2).scan(0.0, |length, pair| {
                *length += polygon[pair[0]].distance(polygon[pair[1]]);
                Some(*length)
            }))
            .collect();
        let total = along[along.len() - 1];
        let (start, end) = (polygon[stretch[0]], polygon[stretch[stretch.len() - 1]]);
        if total <= 0.0 || start == end {
            return refuse(polygon, error);
        }
        for (k, &position) in stretch.iter().enumerate().skip(1).take(defect.inner) {
            polygon[position] = start.lerp(end, along[k] / total);
            if polygon[position].distance(original[position]) > max_move {
                return refuse(polygon, error);
            }
        }
        match first_defect(polygon) {
            None => return Ok(()),
            Some(next) => defect = next,
        }
    }
    refuse(polygon, error)
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
