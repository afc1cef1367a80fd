//! Windows: intervals of an edge seen from a source, and how two on one edge trim each
//! other.

use super::ON_EDGE_TOLERANCE;
use glam::DVec2;

/// A window is cut back only where another reaches its points shorter by more than this
/// fraction, so round-off never cuts away a shortest path.
const TRIM_TOLERANCE: f64 = 1e-12;

/// A window's source: where it lies in the flat frame the window is made in, its distance
/// from the start point (mm), and how that was reached.
#[derive(Debug, Clone, Copy)]
pub(super) struct Source {
    pub(super) flat: DVec2,
    pub(super) sigma: f64,
    pub(super) parent: Parent,
}

/// Where a distance comes from.
#[derive(Debug, Clone, Copy)]
pub(super) enum Parent {
    /// Straight from the start point.
    Start,
    /// Through a window (index into the query's windows).
    Window(u32),
    /// Straight from a vertex.
    Vertex(u32),
}

/// An interval of an edge seen from a source: every point `x` of it is reached by the
/// straight line from the source, at distance `sigma + |source - x|` from the start.
#[derive(Debug, Clone, Copy)]
pub(super) struct Window {
    /// The triangle the window looks into and the index of its edge the window lies on.
    pub(super) triangle: u32,
    pub(super) edge: usize,
    /// The interval, as distances along the edge from its first corner (mm).
    pub(super) start: f64,
    pub(super) end: f64,
    /// The source, unfolded into the plane of the triangle with the edge along the x
    /// axis from the origin and the triangle above (so the source has y < 0).
    pub(super) source: DVec2,
    /// Distance from the start point to the source (mm).
    pub(super) sigma: f64,
    /// How the source was reached.
    pub(super) parent: Parent,
    /// The window queued before it on the same edge (towards the same triangle).
    pub(super) next_on_edge: Option<u32>,
    /// Whether it has been carried across its triangle (its interval is then fixed: its
    /// children and paths refer to it).
    pub(super) carried: bool,
}

impl Window {
    /// Distance from the start point to the point `x` of the window's edge through it.
    pub(super) fn distance_at(&self, x: f64) -> f64 {
        self.sigma + self.source.distance(DVec2::new(x, 0.0))
    }

    /// Length of the path from the start point through the window to `point`, a point of
    /// its triangle (flat coordinates) whose line from the source crosses the window's
    /// edge (of length `length`) at `cut`; `None` unless the window sees the point.
    ///
    /// A straight path through a vertex bounds the windows on either side of it, so
    /// where it goes on (past more vertices, along a chain of edges, say) the crossing
    /// lands on a window's end only up to round-off in the unfolded source. A crossing
    /// that far beyond an end (`ON_EDGE_TOLERANCE` of the frame's size) still counts, the
    /// path then running through that end: a surface path, so never too short, and longer
    /// only by the square of the round-off.
    pub(super) fn length_to(&self, point: DVec2, cut: f64, length: f64) -> Option<f64> {
        if (self.start..=self.end).contains(&cut) {
            return Some(self.sigma + self.source.distance(point));
        }
        let slack = ON_EDGE_TOLERANCE * (length + self.source.length());
        let via = DVec2::new(cut.max(self.start).min(self.end), 0.0);
        (via.x - slack <= cut && cut <= via.x + slack)
            .then(|| self.sigma + self.source.distance(via) + via.distance(point))
    }

    /// Whether anything is left of it after trimming.
    pub(super) fn is_alive(&self) -> bool {
        self.end > self.start
    }
}

/// The part of `keep`'s interval not reached sooner through `by`, two windows on the same
/// edge towards the same triangle: the hull of what is left, `None` if nothing is.
pub(super) fn trimmed(keep: &Window, by: &Window) -> Option<(f64, f64)> {
    let (low, high) = (keep.start.max(by.start), keep.end.min(by.end));
    if low >= high {
        return Some((keep.start, keep.end));
    }
    // Where the two distance functions are equal: sigma_b + |s_b - x| = sigma_k + |s_k - x|
    // squared twice gives a quadratic in x (possibly with spurious roots, harmless here).
    let (sk, sb) = (keep.source, by.source);
    let d = keep.sigma - by.sigma;
    let p = 2.0 * (sk.x - sb.x);
    let q = sb.length_squared() - sk.length_squared() - d * d;
    let (a, b, c) = (
        p * p - 4.0 * d * d,
        2.0 * p * q + 8.0 * d * d * sk.x,
        q * q - 4.0 * d * d * sk.length_squared(),
    );
    let mut cuts = [low, high, high, high];
    if a.abs() > 1e-12 * (p * p + 4.0 * d * d) {
        let discriminant = b * b - 4.0 * a * c;
        if discriminant >= 0.0 {
            let root = discriminant.sqrt();
            cuts[2] = (-b - root) / (2.0 * a);
            cuts[3] = (-b + root) / (2.0 * a);
        }
    } else if b != 0.0 {
        cuts[2] = -c / b;
    }
    for cut in &mut cuts[2..] {
        if !(low < *cut && *cut < high) {
            *cut = high;
        }
    }
    cuts.sort_by(f64::total_cmp);
    // Keep what lies outside `by`'s interval and the pieces where `by` is not shorter
    // throughout (checked at both ends too, in case round-off hid a crossing).
    let by_shorter = |x: f64, margin: f64| {
        let kept = keep.distance_at(x);
        by.distance_at(x) < kept + margin * kept
    };
    let mut kept: Option<(f64, f64)> = None;
    let mut keep_piece = |from: f64, to: f64| {
        kept = Some(kept.map_or((from, to), |(a, b)| (a.min(from), b.max(to))));
    };
    if keep.start < low {
        keep_piece(keep.start, low);
    }
    if high < keep.end {
        keep_piece(high, keep.end);
    }
    for piece in cuts.windows(2) {
        let cut = by_shorter(0.5 * (piece[0] + piece[1]), -TRIM_TOLERANCE)
            && by_shorter(piece[0], TRIM_TOLERANCE)
            && by_shorter(piece[1], TRIM_TOLERANCE);
        if piece[0] < piece[1] && !cut {
            keep_piece(piece[0], piece[1]);
        }
    }
    kept
}
