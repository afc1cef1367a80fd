//! The finest level's displacement carried to arbitrary points (scan vertices, landmarks,
//! breast patches, fill-ins).
//!
//! A point inside the finest mesh takes the barycentric interpolation of its element's
//! corner displacements. A point outside at distance `d` takes the displacement at its
//! closest point on the mesh, which lies on a boundary face of the nearest element
//! (barycentric coordinates of that closest point, all in `[0, 1]`, so nothing is
//! extrapolated linearly and nothing grows with distance); beyond about one blend
//! radius `b` (the finest spacing) that gives way, smoothly, to a weighted average of the
//! boundary vertices within `d + 2b` (weights `(1 - (r/(d + 2b))²)²`), because closest
//! points jump across the medial axis of concave parts of the boundary (measured on
//! the phantom beyond a lateral clip plane: a 1.4 mm scan edge stretched to 5.8 mm).
//! All of it times a falloff
//! `(1 - (d/D)²)²` of its distance `d` to the mesh that is 1 with zero slope at the
//! mesh and reaches 0 with zero slope at `D` ([`DEFAULT_FALLOFF_MM`]). The map is
//! continuous in the point (closest points move continuously), so the moved scan has no
//! seams or spikes. The map depends only on the rest geometry: it is computed once and
//! applied to every new displacement.

use glam::DVec3;
use mesh::SurfaceIndex;
use rayon::prelude::*;
use tetra::{TetLocator, TetMesh};

/// Default distance beyond the finest mesh over which the displacement fades to zero
/// (mm). Scan vertices on the modelled skin lie within about a millimetre of the mesh
/// (the tetrahedral boundary is a linear approximation of the closed surface); the
/// scan beyond the clip box is held at the clip faces, so its displacement is already
/// near zero there, except beyond a lateral clip plane that cuts through a breast (every
/// model so far): there the lateral 20-30 mm of the breast lie outside the model and
/// follow the free clip face. At 20 mm the phantom's breasts grew 5 ml less.
pub const DEFAULT_FALLOFF_MM: f64 = 40.0;

/// Where one point takes its displacement from.
#[derive(Debug, Clone, PartialEq)]
pub struct PointWeights {
    /// Corner vertices of the element (or boundary face).
    pub vertices: [u32; 4],
    /// Weights of the corners (the falloff included).
    pub weights: [f64; 4],
    /// Further `(vertex, weight)` pairs: the smooth average of the boundary vertices
    /// around a point well outside the mesh.
    pub blend: Vec<(u32, f64)>,
}

/// A fixed linear map from the finest level's vertex displacements to the displacements of
/// a set of points.
#[derive(Debug, Clone, Default)]
pub struct PointMap {
    pub points: Vec<PointWeights>,
}

/// Point location for [`PointMap`]: the finest level's tetrahedra and its boundary
/// surface (for points outside).
pub struct FieldLocator<'a> {
    mesh: &'a TetMesh,
    tets: TetLocator<'a>,
    boundary: SurfaceIndex,
    /// Boundary surface vertex to tetrahedral vertex.
    tet_vertex: Vec<u32>,
    boundary_triangles: Vec<[u32; 3]>,
    /// Grid of the boundary vertices (for the outside blend).
    grid: PointGrid,
    /// Radius added to the distance for the outside blend (mm).
    blend_mm: f64,
}

/// A uniform grid over points.
struct PointGrid {
    lo: DVec3,
    cell: f64,
    dims: [usize; 3],
    start: Vec<u32>,
    items: Vec<u32>,
    points: Vec<DVec3>,
}

impl PointGrid {
    fn new(points: Vec<DVec3>, cell: f64) -> PointGrid {
        let (lo, hi) = points.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(a, b), &p| (a.min(p), b.max(p)),
        );
        let dims = ((hi - lo) / cell)
            .floor()
            .to_array()
            .map(|x| x.max(0.0) as usize + 1);
        let index = |p: DVec3| {
            let q = ((p - lo) / cell).floor();
            let c = [q.x, q.y, q.z];
            let mut i = 0;
            for k in (0..3).rev() {
                i = i * dims[k] + (c[k].max(0.0) as usize).min(dims[k] - 1);
            }
            i
        };
        let n = dims[0] * dims[1] * dims[2];
        let mut start = vec![0u32; n + 1];
        for &p in &points {
            start[index(p) + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        let mut fill = start.clone();
        let mut items = vec![0u32; points.len()];
        for (k, &p) in points.iter().enumerate() {
            let c = index(p);
            items[fill[c] as usize] = k as u32;
            fill[c] += 1;
        }
        PointGrid {
            lo,
            cell,
            dims,
            start,
            items,
            points,
        }
    }

    /// Calls `f(k, distance)` for every point within `r` of `p`.
    fn within(&self, p: DVec3, r: f64, mut f: impl FnMut(usize, f64)) {
        let a = ((p - r - self.lo) / self.cell).floor();
        let b = ((p + r - self.lo) / self.cell).floor();
        let clamp = |x: f64, k: usize| (x.max(0.0) as usize).min(self.dims[k] - 1);
        if b.x < 0.0 || b.y < 0.0 || b.z < 0.0 {
            return;
        }
        let (a, b) = (
            [clamp(a.x, 0), clamp(a.y, 1), clamp(a.z, 2)],
            [clamp(b.x, 0), clamp(b.y, 1), clamp(b.z, 2)],
        );
        for z in a[2]..=b[2] {
            for y in a[1]..=b[1] {
                for x in a[0]..=b[0] {
                    let c = x + self.dims[0] * (y + self.dims[1] * z);
                    for &k in &self.items[self.start[c] as usize..self.start[c + 1] as usize] {
                        let d = self.points[k as usize].distance(p);
                        if d < r {
                            f(k as usize, d);
                        }
                    }
                }
            }
        }
    }
}

impl<'a> FieldLocator<'a> {
    /// Indexes `mesh` (its tetrahedra and its boundary faces). `None` for a mesh without
    /// tetrahedra.
    pub fn new(mesh: &'a TetMesh, blend_mm: f64) -> Option<FieldLocator<'a>> {
        let boundary = mesh.boundary();
        let index = SurfaceIndex::new(&boundary.mesh)?;
        let blend_mm = blend_mm.max(1e-3);
        Some(FieldLocator {
            mesh,
            tets: TetLocator::new(mesh),
            boundary: index,
            grid: PointGrid::new(boundary.mesh.positions.clone(), blend_mm),
            tet_vertex: boundary.tet_vertex,
            boundary_triangles: boundary.mesh.triangles,
            blend_mm,
        })
    }

    /// The weights of point `p` for the fade length `falloff_mm`: inside, its element's
    /// barycentric coordinates; outside, those of its closest point on the boundary
    /// (on a boundary face) times the falloff; beyond the falloff, zero.
    pub fn weights(&self, p: DVec3, falloff_mm: f64) -> PointWeights {
        if let Some(loc) = self.tets.locate(p) {
            return PointWeights {
                vertices: self.mesh.tets[loc.tet],
                weights: loc.barycentric,
                blend: Vec::new(),
            };
        }
        match self.boundary.closest_point_within(p, falloff_mm) {
            None => PointWeights {
                vertices: [0; 4],
                weights: [0.0; 4],
                blend: Vec::new(),
            },
            Some(cp) => {
                let w = falloff_weight(cp.distance, falloff_mm);
                let t = self.boundary_triangles[cp.triangle].map(|v| self.tet_vertex[v as usize]);
                let b = cp.barycentric.map(|x| x.max(0.0));
                let s: f64 = b.iter().sum::<f64>().max(1e-300);
                let mut out = PointWeights {
                    vertices: [t[0], t[1], t[2], t[0]],
                    weights: [b[0] / s, b[1] / s, b[2] / s, 0.0],
                    blend: Vec::new(),
                };
                // beyond about one blend radius, the closest point gives way to a smooth
                // average of the boundary vertices around (closest points jump across the
                // medial axis of concave parts of the boundary)
                let near = falloff_weight(cp.distance, self.blend_mm);
                if near < 1.0 {
                    let r = cp.distance + 2.0 * self.blend_mm;
                    let mut blend = Vec::new();
                    self.grid.within(p, r, |k, d| {
                        let s = d / r;
                        blend.push((self.tet_vertex[k], (1.0 - s * s).powi(2)));
                    });
                    let total: f64 = blend.iter().map(|b| b.1).sum();
                    if total > 0.0 {
                        for b in &mut blend {
                            b.1 *= (1.0 - near) * w / total;
                        }
                        out.weights = out.weights.map(|x| x * near * w);
                        out.blend = blend;
                        return out;
                    }
                }
                out.weights = out.weights.map(|x| x * w);
                out
            }
        }
    }
}

/// The falloff weight at distance `d` beyond the mesh for the fade length `falloff`.
pub fn falloff_weight(d: f64, falloff: f64) -> f64 {
    if d <= 0.0 {
        1.0
    } else if d >= falloff {
        0.0
    } else {
        let s = d / falloff;
        (1.0 - s * s).powi(2)
    }
}

impl PointMap {
    /// Locates `points` in `mesh` (parallel) with the fade length `falloff_mm`.
    pub fn new(locator: &FieldLocator, points: &[DVec3], falloff_mm: f64) -> Self {
        let points = points
            .par_iter()
            .with_min_len(256)
            .map(|&p| locator.weights(p, falloff_mm))
            .collect();
        PointMap { points }
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points.len()
    }

    /// Whether it maps no point.
    pub fn is_empty(&self) -> bool {
        self.points.is_empty()
    }

    /// The displacement of every point for the vertex displacement `u` (mm).
    pub fn displacements(&self, u: &[DVec3]) -> Vec<DVec3> {
        self.points
            .par_iter()
            .with_min_len(1024)
            .map(|pw| {
                let mut d = DVec3::ZERO;
                for k in 0..4 {
                    d += u[pw.vertices[k] as usize] * pw.weights[k];
                }
                for &(v, w) in &pw.blend {
                    d += u[v as usize] * w;
                }
                d
            })
            .collect()
    }

    /// `rest + displacement` of every point.
    pub fn moved(&self, rest: &[DVec3], u: &[DVec3]) -> Vec<DVec3> {
        assert_eq!(rest.len(), self.points.len());
        self.displacements(u)
            .into_iter()
            .zip(rest)
            .map(|(d, p)| *p + d)
            .collect()
    }
}

/// Smoothing of a displacement field over a triangle mesh's vertices (the scan): damped
/// Jacobi averaging over edge neighbours, `d ← ½ d + ½ mean(d_neighbours)`, a number of
/// times chosen so that the averaging reaches about `radius_mm`.
///
/// Why: the finite-element displacement is piecewise linear on tetrahedra of 6-7 mm,
/// with kinks at every element face; where it changes fast (over the implant's rim,
/// and where displaced and free vertices of the template alternate) the kinks show on
/// the finely meshed scan as a saw-tooth of element size. The field is only resolved
/// at the element scale anyway, so the scan takes it low-passed at half that scale.
/// A translation is kept exactly; an affine field moves by its gradient times each
/// vertex's umbrella vector (hundredths of a millimetre on a scan).
#[derive(Debug, Clone, Default)]
pub struct SurfaceSmoother {
    /// Neighbours of vertex `v`: `neighbours[ptr[v]..ptr[v + 1]]`.
    ptr: Vec<usize>,
    neighbours: Vec<u32>,
    iterations: usize,
}

impl SurfaceSmoother {
    /// The smoother of `mesh` reaching about `radius_mm` (0: none). One damped step
    /// spreads by about half an edge length squared in variance, so
    /// `4 (radius / mean edge)²` steps reach the radius.
    pub fn new(mesh: &mesh::TriMesh, radius_mm: f64) -> SurfaceSmoother {
        let topology = mesh::Topology::new(mesh);
        let lists: Vec<Vec<u32>> = (0..mesh.positions.len())
            .into_par_iter()
            .map(|v| topology.vertex_neighbors(mesh, v))
            .collect();
        let mut ptr = vec![0usize];
        let mut neighbours = Vec::new();
        let mut edge_sum = 0.0;
        for (v, list) in lists.iter().enumerate() {
            for &w in list {
                edge_sum += mesh.positions[v].distance(mesh.positions[w as usize]);
            }
            neighbours.extend_from_slice(list);
            ptr.push(neighbours.len());
        }
        let mean_edge = edge_sum / neighbours.len().max(1) as f64;
        let iterations = if radius_mm > 0.0 && mean_edge > 0.0 {
            (4.0 * (radius_mm / mean_edge).powi(2)).ceil() as usize
        } else {
            0
        };
        SurfaceSmoother {
            ptr,
            neighbours,
            iterations,
        }
    }

    /// Number of damped Jacobi steps of [`SurfaceSmoother::apply`].
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Smooths `field` (one value per mesh vertex) in place.
    pub fn apply(&self, field: &mut Vec<DVec3>) {
        if self.iterations == 0 || field.len() + 1 != self.ptr.len() {
            return;
        }
        let mut next = field.clone();
        for _ in 0..self.iterations {
            next.par_iter_mut()
                .with_min_len(1024)
                .enumerate()
                .for_each(|(v, out)| {
                    let around = &self.neighbours[self.ptr[v]..self.ptr[v + 1]];
                    *out = if around.is_empty() {
                        field[v]
                    } else {
                        let sum: DVec3 = around.iter().map(|&w| field[w as usize]).sum();
                        0.5 * field[v] + 0.5 * sum / around.len() as f64
                    };
                });
            std::mem::swap(field, &mut next);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An 80 x 80 grid of 1 mm squares and its smoother reaching 2 mm.
    fn grid() -> (mesh::TriMesh, SurfaceSmoother) {
        let grid = mesh::shapes::grid(80, 80, 1.0);
        let smoother = SurfaceSmoother::new(&grid, 2.0);
        (grid, smoother)
    }

    #[test]
    fn translations_are_kept_and_affine_fields_inside_too() {
        let (grid, smoother) = grid();
        assert!(smoother.iterations() >= 10, "{}", smoother.iterations());
        let t = DVec3::new(1.5, -2.0, 30.0);
        let mut field = vec![t; grid.positions.len()];
        smoother.apply(&mut field);
        // a translation is an average of itself: kept to round-off
        assert!(field.iter().all(|d| (*d - t).length() < 1e-12));
        // an affine field on a regular grid: every umbrella vector is zero inside, so
        // vertices further than the reach from the border keep it to round-off
        let affine = |p: DVec3| DVec3::new(0.3 * p.x - 0.1 * p.y, 0.2 * p.y, 0.5 * p.x + 1.0);
        let mut field: Vec<DVec3> = grid.positions.iter().map(|&p| affine(p)).collect();
        smoother.apply(&mut field);
        // each step reaches one ring further (diagonal neighbours: √2 mm)
        let reach = 1.5 * smoother.iterations() as f64 + 1.0;
        let mut checked = 0;
        for (p, d) in grid.positions.iter().zip(&field) {
            let inside = p.x.min(p.y).min(80.0 - p.x).min(80.0 - p.y) > reach;
            if inside {
                assert!((*d - affine(*p)).length() < 1e-12, "{p:?}");
                checked += 1;
            }
        }
        assert!(checked > 100, "{checked}");
    }

    #[test]
    fn a_saw_tooth_of_element_size_is_damped() {
        let (grid, smoother) = grid();
        // +-1 mm alternating every 3 mm along x (a kinked field of period 6 mm)
        let tooth = |p: DVec3| {
            let phase = (p.x / 3.0).rem_euclid(2.0);
            DVec3::Z * if phase < 1.0 { phase } else { 2.0 - phase }
        };
        let mut field: Vec<DVec3> = grid.positions.iter().map(|&p| tooth(p)).collect();
        let swing = |f: &[DVec3]| {
            let z: Vec<f64> = f.iter().map(|d| d.z).collect();
            z.iter().cloned().fold(f64::MIN, f64::max) - z.iter().cloned().fold(f64::MAX, f64::min)
        };
        let before = swing(&field);
        smoother.apply(&mut field);
        // a smooth field of the same scale: a 2 mm kernel damps a 6 mm period by more
        // than half; slow variations (the implant's shape) pass almost unchanged
        assert!(
            swing(&field) < 0.5 * before,
            "{} -> {}",
            before,
            swing(&field)
        );
    }

    #[test]
    fn no_radius_means_no_smoothing() {
        let (grid, _) = grid();
        let smoother = SurfaceSmoother::new(&grid, 0.0);
        let mut field: Vec<DVec3> = grid.positions.iter().map(|p| *p * 0.1).collect();
        let before = field.clone();
        smoother.apply(&mut field);
        assert_eq!(field, before);
    }
}
