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
