//! The body-centred cubic (BCC) lattice: the corners of a cubic grid of spacing `h` and
//! the centres of its cubes.
//!
//! Points are addressed by "doubled" integer coordinates, in units of `h / 2` from the
//! origin: corners have all-even coordinates, centres all-odd ones.
//! - Long ("black") edges, length `h`, join neighbouring points of the same grid along
//!   an axis.
//! - Short ("red") edges, length `h √3 / 2`, join a centre to the eight corners of its
//!   cube.
//! - Tetrahedra: two neighbouring centres and two consecutive corners of the square face
//!   between them. Every tetrahedron has two long edges (opposite each other) and four
//!   short ones; all are congruent, twelve per cube.

use crate::error::TetraError;
use glam::{DVec3, IVec3, UVec3};

/// Lattice points at most: indices are `u32` and edge ids `16 × index + slot`.
pub(crate) const MAX_LATTICE_POINTS: u64 = 1 << 28;

/// A point of the lattice.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct LatticePoint {
    /// Index into per-point arrays: corners first, then centres.
    pub index: u32,
    /// Coordinates in units of half a spacing from the lattice origin.
    pub doubled: IVec3,
}

impl LatticePoint {
    /// Whether the point is a cube centre (else a grid corner).
    pub fn is_centre(self) -> bool {
        self.doubled.x & 1 == 1
    }

    /// Whether the point is odd in a checkerboard colouring of its own grid: the two
    /// ends of a long edge always differ.
    pub fn is_odd(self) -> bool {
        (self.doubled.element_sum() >> 1) & 1 == 1
    }

    /// Whether `self` and `other` are joined by a long edge (same grid).
    pub fn same_grid(self, other: LatticePoint) -> bool {
        self.is_centre() == other.is_centre()
    }
}

/// A BCC lattice covering a box.
#[derive(Debug, Clone)]
pub(crate) struct Lattice {
    /// Position of corner (0, 0, 0) (mm).
    origin: DVec3,
    /// Cube side `h` (mm).
    spacing: f64,
    /// Cubes per axis: `cubes + 1` corners and `cubes` centres per axis.
    cubes: UVec3,
    corner_count: u32,
}

impl Lattice {
    /// A lattice of spacing `spacing_mm` whose outer layer of points lies at least half a
    /// spacing outside the box `lo..hi`: every point of the box is inside a lattice
    /// tetrahedron, and the outermost points are outside the box. The lattice is
    /// centred on the box, so a box symmetric about a coordinate plane gets a lattice
    /// mirror symmetric about it (a symmetric body gets a symmetric mesh).
    pub fn around(lo: DVec3, hi: DVec3, spacing_mm: f64) -> Result<Lattice, TetraError> {
        if !(spacing_mm.is_finite() && spacing_mm > 0.0) {
            return Err(TetraError::InvalidSpacing { spacing_mm });
        }
        let (origin, cubes_f) = centred_cubes(lo, hi, spacing_mm, 1.0);
        let corners = (cubes_f + 1.0).element_product();
        let points = corners + cubes_f.element_product();
        if points.is_nan() || points > MAX_LATTICE_POINTS as f64 {
            return Err(TetraError::LatticeTooLarge {
                spacing_mm,
                points: points.min(u64::MAX as f64) as u64,
                limit: MAX_LATTICE_POINTS,
            });
        }
        Ok(Lattice {
            origin,
            spacing: spacing_mm,
            cubes: cubes_f.as_uvec3(),
            corner_count: corners as u32,
        })
    }

    /// Number of points (corners and centres).
    pub fn point_count(&self) -> usize {
        self.corner_count as usize + self.cubes.element_product() as usize
    }

    /// Corners per axis.
    pub fn corners_per_axis(&self) -> UVec3 {
        self.cubes + 1
    }

    /// Centres (cubes) per axis.
    pub fn cubes(&self) -> UVec3 {
        self.cubes
    }

    /// Number of corners: corner indices are `0..corner_count`, centres follow.
    pub fn corner_count(&self) -> usize {
        self.corner_count as usize
    }

    /// The point at doubled coordinates `d` (which must lie in the lattice).
    pub fn point(&self, d: IVec3) -> LatticePoint {
        let index = if d.x & 1 == 0 {
            let n = self.cubes + 1;
            let c = (d / 2).as_uvec3();
            c.x + n.x * (c.y + n.y * c.z)
        } else {
            let n = self.cubes;
            let c = (d / 2).as_uvec3();
            self.corner_count + c.x + n.x * (c.y + n.y * c.z)
        };
        LatticePoint { index, doubled: d }
    }

    /// The point with index `index`.
    pub fn point_at(&self, index: u32) -> LatticePoint {
        let (local, n, offset) = if index < self.corner_count {
            (index, self.cubes + 1, 0)
        } else {
            (index - self.corner_count, self.cubes, 1)
        };
        let c = UVec3::new(local % n.x, (local / n.x) % n.y, local / (n.x * n.y));
        LatticePoint {
            index,
            doubled: c.as_ivec3() * 2 + offset,
        }
    }

    /// Whether doubled coordinates `d` name a point of this lattice.
    fn contains(&self, d: IVec3) -> bool {
        let limit = if d.x & 1 == 0 {
            self.cubes.as_ivec3() * 2
        } else {
            self.cubes.as_ivec3() * 2 - 1
        };
        d.cmpge(IVec3::ZERO).all() && d.cmple(limit).all()
    }

    /// Position of the point with doubled coordinates `d` (mm).
    pub fn position_of(&self, d: IVec3) -> DVec3 {
        self.origin + d.as_dvec3() * (0.5 * self.spacing)
    }

    /// Position of `p` (mm).
    pub fn position(&self, p: LatticePoint) -> DVec3 {
        self.position_of(p.doubled)
    }

    /// The lattice points that `p` shares an edge with and that come after it in the
    /// edge numbering: its +x, +y, +z neighbours in its own grid and, for a centre, the
    /// eight corners of its cube. Every edge is listed once, from one end.
    pub fn forward_neighbours(&self, p: LatticePoint) -> impl Iterator<Item = LatticePoint> + '_ {
        let along_axes = (0..3).map(move |axis| p.doubled + IVec3::AXES[axis] * 2);
        let corners = (0..8)
            .filter(move |_| p.is_centre())
            .map(move |k| p.doubled + corner_offset(k));
        along_axes
            .chain(corners)
            .filter(move |&d| self.contains(d))
            .map(move |d| self.point(d))
    }

    /// A unique id for the edge `a`-`b` (in either order), which must be a lattice edge.
    pub fn edge_id(a: LatticePoint, b: LatticePoint) -> u64 {
        let slot = |from: LatticePoint, to: LatticePoint| -> u64 {
            let d = to.doubled - from.doubled;
            if from.same_grid(to) {
                if d.x != 0 {
                    0
                } else if d.y != 0 {
                    1
                } else {
                    2
                }
            } else {
                3 + ((d.x > 0) as u64 | ((d.y > 0) as u64) << 1 | ((d.z > 0) as u64) << 2)
            }
        };
        let (from, to) = if a.same_grid(b) {
            if (b.doubled - a.doubled).element_sum() > 0 {
                (a, b)
            } else {
                (b, a)
            }
        } else if a.is_centre() {
            (a, b)
        } else {
            (b, a)
        };
        16 * from.index as u64 + slot(from, to)
    }

    /// The lattice tetrahedra with the long edge from centre `centre` to the next centre
    /// along each axis (up to 12): `out` is cleared and filled.
    pub fn tetrahedra_from_centre(&self, centre: LatticePoint, out: &mut Vec<[LatticePoint; 4]>) {
        out.clear();
        for axis in 0..3 {
            let (ea, eu, ev) = (
                IVec3::AXES[axis],
                IVec3::AXES[(axis + 1) % 3],
                IVec3::AXES[(axis + 2) % 3],
            );
            let next = centre.doubled + ea * 2;
            if !self.contains(next) {
                continue;
            }
            let face = centre.doubled + ea;
            let square = [-eu - ev, eu - ev, eu + ev, -eu + ev].map(|o| self.point(face + o));
            let next = self.point(next);
            for s in 0..4 {
                out.push([centre, next, square[s], square[(s + 1) % 4]]);
            }
        }
    }
}

/// Origin and number of cubes per axis of a grid of cubes of side `spacing_mm` centred
/// on the box `lo..hi`, with at least `margin` cubes beyond it on each side. Centred, so
/// that a box symmetric about a coordinate plane gets a grid mirror symmetric about it;
/// the same box gives the same grid points for every margin.
pub(crate) fn centred_cubes(lo: DVec3, hi: DVec3, spacing_mm: f64, margin: f64) -> (DVec3, DVec3) {
    let cubes = ((hi - lo) / spacing_mm).ceil() + 2.0 * margin;
    ((lo + hi) * 0.5 - cubes * (0.5 * spacing_mm), cubes)
}

/// Offset from a centre to corner `k` (bit 0: +x, bit 1: +y, bit 2: +z) of its cube, in
/// doubled coordinates.
fn corner_offset(k: usize) -> IVec3 {
    IVec3::new(
        if k & 1 != 0 { 1 } else { -1 },
        if k & 2 != 0 { 1 } else { -1 },
        if k & 4 != 0 { 1 } else { -1 },
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    fn small() -> Lattice {
        Lattice::around(DVec3::ZERO, DVec3::new(3.0, 2.0, 1.0), 1.0).unwrap()
    }

    #[test]
    fn indices_and_coordinates_round_trip() {
        let lattice = small();
        for index in 0..lattice.point_count() as u32 {
            let p = lattice.point_at(index);
            assert_eq!(lattice.point(p.doubled), p);
            assert!(lattice.contains(p.doubled));
        }
    }

    #[test]
    fn edges_are_listed_once_with_unique_ids_and_right_lengths() {
        let lattice = small();
        let mut ids = HashSet::new();
        for index in 0..lattice.point_count() as u32 {
            let p = lattice.point_at(index);
            for q in lattice.forward_neighbours(p) {
                assert!(ids.insert(Lattice::edge_id(p, q)));
                assert_eq!(Lattice::edge_id(p, q), Lattice::edge_id(q, p));
                let length = lattice.position(p).distance(lattice.position(q));
                let expected = if p.same_grid(q) {
                    1.0
                } else {
                    3f64.sqrt() / 2.0
                };
                assert!((length - expected).abs() < 1e-12);
                if p.same_grid(q) {
                    assert_ne!(p.is_odd(), q.is_odd());
                }
            }
        }
    }

    #[test]
    fn tetrahedra_fill_the_centre_box_and_use_lattice_edges() {
        let lattice = small();
        let mut tets = Vec::new();
        let mut volume = 0.0;
        let mut count = 0;
        for index in lattice.corner_count() as u32..lattice.point_count() as u32 {
            lattice.tetrahedra_from_centre(lattice.point_at(index), &mut tets);
            for t in &tets {
                let p = t.map(|v| lattice.position(v));
                let v = (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0;
                assert!((v.abs() - 1.0 / 12.0).abs() < 1e-12);
                volume += v.abs();
                count += 1;
                let long = (0..4)
                    .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
                    .filter(|&(i, j)| t[i].same_grid(t[j]))
                    .count();
                assert_eq!(long, 2);
            }
        }
        // The centres span a box of (cubes - 1) per axis; tetrahedra tile it and reach
        // half a cube beyond along one axis at a time, 12 per interior cube.
        let c = lattice.cubes();
        assert!(count >= 12 * ((c - 1).element_product()) as usize);
        assert!(volume >= (c - 1).as_dvec3().element_product());
    }
}
