//! The square lattice of interior points laid over the projected loop.

use super::boundary::Axis;
use super::polygon::distance_to_segment;
use super::{FillInError, MAX_LATTICE_POINTS};
use glam::DVec2;
use std::ops::Range;

/// Lattice points closer to the boundary than this fraction of the spacing are dropped,
/// so that no sliver triangles form between them and the boundary.
pub(super) const MIN_BOUNDARY_CLEARANCE: f64 = 0.5;

/// A square lattice of points `origin + spacing * (i, j)`, `i < size[0]`, `j < size[1]`,
/// at integer multiples of the spacing in the plane frame.
pub(super) struct Lattice {
    origin: DVec2,
    spacing: f64,
    pub(super) size: [usize; 2],
}

impl Lattice {
    /// The lattice points within the polygon's bounding box.
    pub(super) fn covering(polygon: &[DVec2], spacing: f64) -> Result<Lattice, FillInError> {
        let (min, max) = polygon
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        let first = (min / spacing).ceil();
        let counts = ((max / spacing).floor() - first + 1.0).max(DVec2::ZERO);
        if counts.x * counts.y > MAX_LATTICE_POINTS as f64 {
            return Err(FillInError::LatticeTooLarge {
                spacing_mm: spacing,
                points: counts.x * counts.y,
            });
        }
        Ok(Lattice {
            origin: first * spacing,
            spacing,
            size: [counts.x as usize, counts.y as usize],
        })
    }

    pub(super) fn len(&self) -> usize {
        self.size[0] * self.size[1]
    }

    /// Coordinate `dimension` (0: u, 1: v) of lattice index `k` in that dimension (mm).
    pub(super) fn coordinate(&self, dimension: usize, k: usize) -> f64 {
        self.origin[dimension] + k as f64 * self.spacing
    }

    /// Indices in `dimension` whose coordinate lies in `[from, to]` (mm).
    pub(super) fn indices_between(&self, dimension: usize, from: f64, to: f64) -> Range<usize> {
        let origin = self.origin[dimension];
        let first = ((from - origin) / self.spacing).ceil().max(0.0) as usize;
        let end = (((to - origin) / self.spacing).floor() + 1.0).max(0.0) as usize;
        first..end.min(self.size[dimension])
    }

    /// Point index of the `k`-th point on line `line` of `axis`.
    pub(super) fn index(&self, axis: Axis, line: usize, k: usize) -> usize {
        match axis {
            Axis::U => line * self.size[0] + k,
            Axis::V => k * self.size[0] + line,
        }
    }

    /// The position of point `index` (mm).
    pub(super) fn point(&self, index: usize) -> DVec2 {
        let (i, j) = (index % self.size[0], index / self.size[0]);
        self.origin + self.spacing * DVec2::new(i as f64, j as f64)
    }

    /// Per point, whether it lies within the minimum clearance of a polygon edge. Only the
    /// points in each edge's widened bounding box are tested.
    pub(super) fn near_polygon(&self, polygon: &[DVec2]) -> Vec<bool> {
        let clearance = MIN_BOUNDARY_CLEARANCE * self.spacing;
        let mut near = vec![false; self.len()];
        let n = polygon.len();
        for k in 0..n {
            let (a, b) = (polygon[k], polygon[(k + 1) % n]);
            let (lo, hi) = (a.min(b) - clearance, a.max(b) + clearance);
            for j in self.indices_between(1, lo.y, hi.y) {
                for i in self.indices_between(0, lo.x, hi.x) {
                    let index = self.index(Axis::U, j, i);
                    if distance_to_segment(self.point(index), a, b) < clearance {
                        near[index] = true;
                    }
                }
            }
        }
        near
    }
}
