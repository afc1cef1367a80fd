//! Point location in a tetrahedral mesh: the containing tetrahedron and barycentric
//! coordinates of a point, or for a point outside the mesh the nearest tetrahedron and
//! the (extrapolating) barycentric coordinates with respect to it.
//!
//! Tetrahedra are entered into the cells of a uniform grid by their bounding boxes (cell
//! side about one element edge). A containing tetrahedron is searched in the point's cell
//! only; the nearest one in growing shells of cells around it, until the shells are
//! farther away than the best tetrahedron found.

use crate::quality::signed_volume;
use crate::tetmesh::TetMesh;
use glam::{DVec3, IVec3};

/// Barycentric coordinates down to this (relative) negative value still count as
/// inside, so points on shared faces and round-off never fall between elements.
const INSIDE_TOLERANCE: f64 = 1e-10;

/// Where a point lies with respect to a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Location {
    /// The containing (or nearest) tetrahedron.
    pub tet: usize,
    /// Barycentric coordinates of the point in that tetrahedron (sum to one; some are
    /// negative for a point outside it).
    pub barycentric: [f64; 4],
    /// Distance from the point to the tetrahedron (mm); zero inside.
    pub distance_mm: f64,
}

/// A uniform-grid index over a mesh's tetrahedra.
pub struct TetLocator<'a> {
    mesh: &'a TetMesh,
    lo: DVec3,
    hi: DVec3,
    /// Cell side (mm).
    cell: f64,
    cells: IVec3,
    /// `cell_tets[cell_start[c]..cell_start[c + 1]]` are the tetrahedra overlapping cell `c`.
    cell_start: Vec<u32>,
    cell_tets: Vec<u32>,
}

impl<'a> TetLocator<'a> {
    /// Indexes `mesh`.
    pub fn new(mesh: &'a TetMesh) -> TetLocator<'a> {
        let (lo, hi) = mesh.bounding_box();
        let volume: f64 = (0..mesh.tet_count())
            .map(|t| signed_volume(mesh.tet_positions(t)).abs())
            .sum();
        // Edge of a regular tetrahedron of the mean volume.
        let mean_edge = (6.0 * 2f64.sqrt() * volume / mesh.tet_count().max(1) as f64).cbrt();
        let extent = (hi - lo).max(DVec3::ZERO);
        let cell = mean_edge
            .max(extent.max_element() / 1024.0)
            .max(f64::MIN_POSITIVE);
        let cells = ((extent / cell).floor() + 1.0).as_ivec3().max(IVec3::ONE);
        let mut locator = TetLocator {
            mesh,
            lo,
            hi,
            cell,
            cells,
            cell_start: Vec::new(),
            cell_tets: Vec::new(),
        };
        let ranges: Vec<(IVec3, IVec3)> = (0..mesh.tet_count())
            .map(|t| {
                let p = mesh.tet_positions(t);
                let (a, b) = p
                    .iter()
                    .fold((p[0], p[0]), |(a, b), &q| (a.min(q), b.max(q)));
                (locator.cell_of(a), locator.cell_of(b))
            })
            .collect();
        let mut counts = vec![0u32; cells.element_product() as usize + 1];
        let each_cell = |(a, b): (IVec3, IVec3), f: &mut dyn FnMut(usize)| {
            for z in a.z..=b.z {
                for y in a.y..=b.y {
                    for x in a.x..=b.x {
                        f((x + cells.x * (y + cells.y * z)) as usize);
                    }
                }
            }
        };
        for &range in &ranges {
            each_cell(range, &mut |c| counts[c + 1] += 1);
        }
        for c in 1..counts.len() {
            counts[c] += counts[c - 1];
        }
        let mut fill = counts.clone();
        let mut cell_tets = vec![0u32; counts[counts.len() - 1] as usize];
        for (t, &range) in ranges.iter().enumerate() {
            each_cell(range, &mut |c| {
                cell_tets[fill[c] as usize] = t as u32;
                fill[c] += 1;
            });
        }
        locator.cell_start = counts;
        locator.cell_tets = cell_tets;
        locator
    }

    /// The cell holding `p`, clamped to the grid.
    fn cell_of(&self, p: DVec3) -> IVec3 {
        ((p - self.lo) / self.cell)
            .floor()
            .max(DVec3::ZERO)
            .min((self.cells - 1).as_dvec3())
            .as_ivec3()
    }

    fn tets_in(&self, c: IVec3) -> &[u32] {
        let i = (c.x + self.cells.x * (c.y + self.cells.y * c.z)) as usize;
        &self.cell_tets[self.cell_start[i] as usize..self.cell_start[i + 1] as usize]
    }

    /// The tetrahedron containing `p` and its barycentric coordinates, or `None` if `p`
    /// is outside the mesh. On a shared face the element where `p` lies deepest wins.
    pub fn locate(&self, p: DVec3) -> Option<Location> {
        let inside_box = p.cmpge(self.lo).all() && p.cmple(self.hi).all();
        if !inside_box {
            return None;
        }
        self.tets_in(self.cell_of(p))
            .iter()
            .map(|&t| {
                (
                    t as usize,
                    barycentric(self.mesh.tet_positions(t as usize), p),
                )
            })
            .filter(|(_, b)| b.iter().all(|&x| x >= -INSIDE_TOLERANCE))
            .max_by(|a, b| min4(&a.1).total_cmp(&min4(&b.1)))
            .map(|(tet, barycentric)| Location {
                tet,
                barycentric,
                distance_mm: 0.0,
            })
    }

    /// The containing tetrahedron of `p`, or if there is none the nearest one, with the
    /// barycentric coordinates of `p` in it (linear extrapolation for a point outside).
    /// `None` only for a mesh without tetrahedra.
    pub fn locate_or_nearest(&self, p: DVec3) -> Option<Location> {
        if let Some(found) = self.locate(p) {
            return Some(found);
        }
        let centre = self.cell_of(p);
        let to_box = (self.lo - p).max(p - self.hi).max(DVec3::ZERO).length();
        let max_ring = self.cells.max_element();
        let mut best: Option<(f64, usize)> = None;
        for ring in 0..=max_ring {
            let bound = to_box.max((ring - 1).max(0) as f64 * self.cell);
            if best.is_some_and(|(d, _)| d <= bound) {
                break;
            }
            self.for_each_cell_in_ring(centre, ring, |c| {
                for &t in self.tets_in(c) {
                    let d = distance_to_tet(self.mesh.tet_positions(t as usize), p);
                    if best.is_none_or(|(b, bt)| d < b || (d == b && (t as usize) < bt)) {
                        best = Some((d, t as usize));
                    }
                }
            });
        }
        best.map(|(distance_mm, tet)| Location {
            tet,
            barycentric: barycentric(self.mesh.tet_positions(tet), p),
            distance_mm,
        })
    }

    /// Calls `f` on every grid cell at Chebyshev distance `ring` from `centre`.
    fn for_each_cell_in_ring(&self, centre: IVec3, ring: i32, mut f: impl FnMut(IVec3)) {
        let lo = (centre - ring).max(IVec3::ZERO);
        let hi = (centre + ring).min(self.cells - 1);
        for x in lo.x..=hi.x {
            for y in lo.y..=hi.y {
                let on_shell = (x - centre.x).abs().max((y - centre.y).abs()) == ring;
                if on_shell {
                    for z in lo.z..=hi.z {
                        f(IVec3::new(x, y, z));
                    }
                } else {
                    // ring > 0 here: only the top and bottom layers are on the shell.
                    for z in [centre.z - ring, centre.z + ring] {
                        if (lo.z..=hi.z).contains(&z) {
                            f(IVec3::new(x, y, z));
                        }
                    }
                }
            }
        }
    }
}

fn min4(b: &[f64; 4]) -> f64 {
    b[0].min(b[1]).min(b[2]).min(b[3])
}

/// Barycentric coordinates of `p` in the tetrahedron `t` (sub-volume ratios).
pub fn barycentric(t: [DVec3; 4], p: DVec3) -> [f64; 4] {
    let volume = signed_volume(t);
    let mut weights = [0.0; 4];
    for (k, w) in weights.iter_mut().enumerate() {
        let mut sub = t;
        sub[k] = p;
        *w = signed_volume(sub) / volume;
    }
    weights
}

/// Distance from `p` to the solid tetrahedron `t` (mm).
pub fn distance_to_tet(t: [DVec3; 4], p: DVec3) -> f64 {
    let b = barycentric(t, p);
    if b.iter().all(|&x| x >= 0.0) {
        return 0.0;
    }
    [[1, 2, 3], [0, 2, 3], [0, 1, 3], [0, 1, 2]]
        .iter()
        .map(|f| closest_point_on_triangle(p, f.map(|k| t[k])).distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// The point of triangle `[a, b, c]` nearest to `p` (Ericson, "Real-Time Collision
/// Detection", 5.1.5: Voronoi regions of vertices, edges and face).
pub fn closest_point_on_triangle(p: DVec3, [a, b, c]: [DVec3; 3]) -> DVec3 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return c;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        return b + (c - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denominator = 1.0 / (va + vb + vc);
    a + ab * (vb * denominator) + ac * (vc * denominator)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closest_point_regions() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let cases = [
            (DVec3::new(0.2, 0.2, 1.0), DVec3::new(0.2, 0.2, 0.0)),
            (DVec3::new(-1.0, -1.0, 0.0), DVec3::ZERO),
            (DVec3::new(2.0, -0.5, 0.3), DVec3::X),
            (DVec3::new(0.5, -1.0, 0.0), DVec3::new(0.5, 0.0, 0.0)),
            (DVec3::new(1.0, 1.0, 0.0), DVec3::new(0.5, 0.5, 0.0)),
            (DVec3::new(-1.0, 0.5, 2.0), DVec3::new(0.0, 0.5, 0.0)),
        ];
        for (p, expected) in cases {
            assert!(
                closest_point_on_triangle(p, tri).distance(expected) < 1e-12,
                "{p}"
            );
        }
        let unit = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        assert_eq!(distance_to_tet(unit, DVec3::splat(0.1)), 0.0);
        assert!((distance_to_tet(unit, DVec3::new(0.2, 0.2, -3.0)) - 3.0).abs() < 1e-12);
    }
}
