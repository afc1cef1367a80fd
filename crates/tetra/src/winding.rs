//! Inside/outside classification against a closed, outward-oriented triangle surface by
//! winding numbers along lines parallel to the x axis.
//!
//! The line through `(y, z)` meets a triangle iff `(y, z)` lies in the triangle's
//! projection onto the y-z plane. Each edge's side test is the exact predicate
//! `robust::orient2d`, always evaluated with the edge's endpoints in vertex-index order,
//! and an exact zero is broken by simulation of simplicity (the query moved by
//! `(ε, ε²)` in `(y, z)`). Two triangles sharing an edge therefore see the same answer for
//! it, and a line through an edge or a vertex of a watertight surface crosses it exactly
//! as often as a line in general position: never twice, never zero times.
//!
//! Walking along +x, a crossing adds +1 where the surface is entered (normal x < 0) and
//! −1 where it is left; a point's winding number is the sum over the crossings before it
//! (1 inside, 0 outside for a valid surface).
//!
//! Triangles are binned by their bounding rectangles in the y-z plane, so a line is
//! tested only against the triangles of its bin.

use glam::{DVec2, DVec3};
use mesh::TriMesh;
use robust::{Coord, orient2d};

/// Bins per axis at most.
const MAX_BINS_PER_AXIS: f64 = 4096.0;

/// A crossing of an x-parallel line with the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Crossing {
    /// Where the line meets the surface (mm).
    pub x: f64,
    /// +1 entering, −1 leaving, walking along +x.
    pub step: i32,
}

/// Triangles binned over the y-z plane for exact line crossings.
pub(crate) struct WindingIndex {
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Lower corner of the bin grid in (y, z) (mm).
    lo: DVec2,
    /// Bin side (mm).
    bin_size: f64,
    bins: [usize; 2],
    /// `bin_triangles[bin_start[b]..bin_start[b + 1]]` are the triangles of bin `b`.
    bin_start: Vec<u32>,
    bin_triangles: Vec<u32>,
}

fn yz(p: DVec3) -> DVec2 {
    DVec2::new(p.y, p.z)
}

impl WindingIndex {
    /// Bins the triangles of `mesh` (which must have valid indices and at least one
    /// triangle).
    pub fn new(mesh: &TriMesh) -> WindingIndex {
        let positions = mesh.positions.clone();
        let triangles = mesh.triangles.clone();
        let rect = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| yz(mesh.positions[v as usize]));
            (a.min(b).min(c), a.max(b).max(c))
        };
        let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
        let mut extent_sum = 0.0;
        for t in &triangles {
            let (a, b) = rect(t);
            lo = lo.min(a);
            hi = hi.max(b);
            extent_sum += (b - a).max_element();
        }
        let span = (hi - lo).max_element().max(f64::MIN_POSITIVE);
        let bin_size = (extent_sum / triangles.len() as f64)
            .max(span / MAX_BINS_PER_AXIS)
            .max(f64::MIN_POSITIVE);
        let bins = [
            ((hi.x - lo.x) / bin_size) as usize + 1,
            ((hi.y - lo.y) / bin_size) as usize + 1,
        ];
        let mut index = WindingIndex {
            positions,
            triangles,
            lo,
            bin_size,
            bins,
            bin_start: Vec::new(),
            bin_triangles: Vec::new(),
        };
        let ranges: Vec<([usize; 2], [usize; 2])> = index
            .triangles
            .iter()
            .map(|t| {
                let (a, b) = rect(t);
                (index.bin_of(a), index.bin_of(b))
            })
            .collect();
        let mut counts = vec![0u32; bins[0] * bins[1] + 1];
        for (a, b) in &ranges {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    counts[i + bins[0] * j + 1] += 1;
                }
            }
        }
        for b in 1..counts.len() {
            counts[b] += counts[b - 1];
        }
        let mut fill = counts.clone();
        let mut bin_triangles = vec![0u32; counts[counts.len() - 1] as usize];
        for (t, (a, b)) in ranges.iter().enumerate() {
            for j in a[1]..=b[1] {
                for i in a[0]..=b[0] {
                    let slot = &mut fill[i + bins[0] * j];
                    bin_triangles[*slot as usize] = t as u32;
                    *slot += 1;
                }
            }
        }
        index.bin_start = counts;
        index.bin_triangles = bin_triangles;
        index
    }

    /// The bin holding `q` (clamped to the grid). Monotone in `q`, so a triangle's
    /// rectangle covers the bin of every point it contains.
    fn bin_of(&self, q: DVec2) -> [usize; 2] {
        let cell = ((q - self.lo) / self.bin_size).max(DVec2::ZERO);
        [
            (cell.x as usize).min(self.bins[0] - 1),
            (cell.y as usize).min(self.bins[1] - 1),
        ]
    }

    /// The triangles whose rectangles may contain `q`; empty outside the grid.
    fn candidates(&self, q: DVec2) -> &[u32] {
        let relative = (q - self.lo) / self.bin_size;
        let outside = relative.x < 0.0
            || relative.y < 0.0
            || relative.x >= self.bins[0] as f64
            || relative.y >= self.bins[1] as f64;
        if outside || !relative.is_finite() {
            return &[];
        }
        let [i, j] = self.bin_of(q);
        let b = i + self.bins[0] * j;
        &self.bin_triangles[self.bin_start[b] as usize..self.bin_start[b + 1] as usize]
    }

    /// Which side of the directed edge `a -> b` the (perturbed) query `q` lies on, +1
    /// left, −1 right, 0 only for an edge that projects to a point; with the
    /// `orient2d` value (unperturbed).
    fn edge_side(&self, a: u32, b: u32, q: DVec2) -> (i32, f64) {
        if a > b {
            let (side, value) = self.edge_side(b, a, q);
            return (-side, -value);
        }
        let (pa, pb) = (
            yz(self.positions[a as usize]),
            yz(self.positions[b as usize]),
        );
        let value = orient2d(
            Coord { x: pa.x, y: pa.y },
            Coord { x: pb.x, y: pb.y },
            Coord { x: q.x, y: q.y },
        );
        let side = if value > 0.0 {
            1
        } else if value < 0.0 {
            -1
        } else {
            // q + (ε, ε²): the orientation gains d.x ε² − d.y ε.
            let d = pb - pa;
            if d.y != 0.0 {
                -(d.y.signum() as i32)
            } else if d.x != 0.0 {
                d.x.signum() as i32
            } else {
                0
            }
        };
        (side, value)
    }

    /// Where the line through `q = (y, z)` crosses triangle `t`, if it does.
    fn crossing(&self, t: u32, q: DVec2) -> Option<Crossing> {
        let tri = self.triangles[t as usize];
        let mut sides = [0i32; 3];
        let mut weights = [0.0f64; 3];
        for k in 0..3 {
            let (side, value) = self.edge_side(tri[k], tri[(k + 1) % 3], q);
            sides[k] = side;
            // The edge k -> k+1 weighs the opposite corner k+2.
            weights[(k + 2) % 3] = value;
        }
        if sides[0] == 0 || sides[0] != sides[1] || sides[1] != sides[2] {
            return None;
        }
        let total: f64 = weights.iter().sum();
        let xs = tri.map(|v| self.positions[v as usize].x);
        let x = if total != 0.0 {
            (0..3).map(|k| weights[k] * xs[k]).sum::<f64>() / total
        } else {
            (xs[0] + xs[1] + xs[2]) / 3.0
        };
        // Counter-clockwise in (y, z) means normal x > 0: the line leaves the solid.
        Some(Crossing { x, step: -sides[0] })
    }

    /// The crossings of the line `{(x, y, z)}` with the surface, sorted by `x`, into
    /// `out` (cleared first).
    pub fn line_crossings(&self, y: f64, z: f64, out: &mut Vec<Crossing>) {
        out.clear();
        let q = DVec2::new(y, z);
        out.extend(
            self.candidates(q)
                .iter()
                .filter_map(|&t| self.crossing(t, q)),
        );
        out.sort_unstable_by(|a, b| a.x.total_cmp(&b.x));
    }

    /// The winding number of the surface around `p`: 1 inside, 0 outside.
    pub fn winding_number(&self, p: DVec3) -> i32 {
        let q = yz(p);
        self.candidates(q)
            .iter()
            .filter_map(|&t| self.crossing(t, q))
            .filter(|c| c.x < p.x)
            .map(|c| c.step)
            .sum()
    }
}

/// Marks `inside[i]` for the points `x0 + i·dx`-style abscissas `xs(i)` of one line,
/// given the line's sorted crossings: a point is inside where the winding number of
/// the crossings before it is not zero.
pub(crate) fn classify_line(
    crossings: &[Crossing],
    xs: impl Fn(usize) -> f64,
    inside: &mut [bool],
) {
    let mut winding = 0;
    let mut next = 0;
    for (i, flag) in inside.iter_mut().enumerate() {
        let x = xs(i);
        while next < crossings.len() && crossings[next].x < x {
            winding += crossings[next].step;
            next += 1;
        }
        *flag = winding != 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::{cube, icosphere};

    #[test]
    fn lines_through_vertices_and_edges_cross_a_cube_twice() {
        // The cube's vertices and edges sit on the lines y, z in {0, 5, 10}.
        let index = WindingIndex::new(&cube(10.0));
        let mut crossings = Vec::new();
        for y in [0.0, 2.5, 5.0, 10.0] {
            for z in [0.0, 5.0, 7.5, 10.0] {
                index.line_crossings(y, z, &mut crossings);
                let steps: Vec<i32> = crossings.iter().map(|c| c.step).collect();
                let xs: Vec<f64> = crossings.iter().map(|c| c.x).collect();
                // Lines along the boundary count as inside or outside, but never cross
                // only once or twice in the same direction.
                if steps.is_empty() {
                    continue;
                }
                assert_eq!(steps, vec![1, -1], "y {y} z {z}");
                assert_eq!(xs, vec![0.0, 10.0], "y {y} z {z}");
            }
        }
        index.line_crossings(5.0, 5.0, &mut crossings);
        assert_eq!(crossings.len(), 2);
    }

    #[test]
    fn winding_number_of_sphere_points() {
        let index = WindingIndex::new(&icosphere(10.0, 3));
        assert_eq!(index.winding_number(DVec3::ZERO), 1);
        assert_eq!(index.winding_number(DVec3::new(0.0, 0.0, 9.0)), 1);
        assert_eq!(index.winding_number(DVec3::new(0.0, 0.0, 10.5)), 0);
        assert_eq!(index.winding_number(DVec3::new(50.0, 0.0, 0.0)), 0);
        assert_eq!(index.winding_number(DVec3::new(-11.0, 0.0, 0.0)), 0);
        // Lines through icosphere vertices (the poles of its construction) still cross twice.
        let mut crossings = Vec::new();
        for p in icosphere(10.0, 3).positions.iter().take(40) {
            index.line_crossings(p.y, p.z, &mut crossings);
            let total: i32 = crossings.iter().map(|c| c.step).sum();
            assert_eq!(total, 0);
            assert!(
                crossings.len() % 2 == 0 && crossings.len() <= 2,
                "{crossings:?}"
            );
        }
    }
}
