//! The finest level's displacement carried to arbitrary points (scan vertices, landmarks,
//! breast patches, fill-ins).
//!
//! A point inside the finest mesh takes the barycentric interpolation of its element's
//! corner displacements. A point outside at distance `d` takes the displacement at its
//! closest point on the mesh, which lies on a boundary face of the nearest element
//! (barycentric coordinates of that closest point, all in `[0, 1]`, so nothing is
//! extrapolated linearly and nothing grows with distance); beyond about one blend
//! radius `b` (in a session, `OUTSIDE_BLEND_RADIUS`) that gives way, smoothly, to a
//! weighted average of the boundary vertices within `d + 2b` (weights
//! `(1 - (r/(d + 2b))²)²`), because closest points jump across the medial axis of
//! concave parts of the boundary (measured on the phantom beyond a lateral clip plane: a
//! 1.4 mm scan edge stretched to 5.8 mm). All of it times a falloff `(1 - (d/D)²)²` of its distance `d` to the mesh
//! that is 1 with zero slope at the mesh and reaches 0 with zero slope at `D`
//! ([`DEFAULT_FALLOFF_MM`]). The map is
//! continuous in the point (closest points move continuously), so the moved scan has no
//! seams or spikes. The map depends only on the rest geometry: it is computed once and
//! applied to every new displacement.

use glam::DVec3;
use mesh::SurfaceIndex;
use rayon::prelude::*;
use tetra::{TetLocator, TetMesh};

/// Points per parallel task of [`PointMap::displacements`].
const MAP_CHUNK: usize = 1024;

/// Points whose sums [`PointMap::displacements`] runs side by side (measured on the
/// phantom's scan at 60,000 elements, one thread: 7 ms for 2, 12 ms for 1, 8-9 ms
/// for 4 or 8).
const INTERLEAVED_POINTS: usize = 2;

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
/// a set of points: point `p` moves by `Σ u[vertices[k]] weights[k]` over
/// `k in starts[p]..starts[p + 1]`, the terms of its [`PointWeights`] in order (corners,
/// then blend) without those of zero weight, which add exact zeros to the sum for any
/// finite displacement (a sum started at `+0` never becomes `-0`).
#[derive(Debug, Clone, Default)]
pub struct PointMap {
    starts: Vec<usize>,
    vertices: Vec<u32>,
    weights: Vec<f64>,
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
        let located: Vec<PointWeights> = points
            .par_iter()
            .with_min_len(256)
            .map(|&p| locator.weights(p, falloff_mm))
            .collect();
        let mut map = PointMap {
            starts: Vec::with_capacity(points.len() + 1),
            vertices: Vec::new(),
            weights: Vec::new(),
        };
        map.starts.push(0);
        for pw in &located {
            let corners = pw.vertices.into_iter().zip(pw.weights);
            for (v, w) in corners.chain(pw.blend.iter().copied()) {
                if w != 0.0 {
                    map.vertices.push(v);
                    map.weights.push(w);
                }
            }
            map.starts.push(map.vertices.len());
        }
        map
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// Whether it maps no point.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The `(vertex, weight)` terms of `point`'s sum, in order.
    pub fn terms(&self, point: usize) -> impl Iterator<Item = (u32, f64)> + '_ {
        let range = self.starts[point]..self.starts[point + 1];
        self.vertices[range.clone()]
            .iter()
            .copied()
            .zip(self.weights[range].iter().copied())
    }

    /// Per point: whether its displacement can be non-zero (it has a non-zero weight);
    /// the others lie beyond the falloff and do not move.
    pub fn support(&self) -> Vec<bool> {
        self.starts.windows(2).map(|s| s[1] > s[0]).collect()
    }

    /// The displacement of every point for the vertex displacement `u` (mm).
    pub fn displacements(&self, u: &[DVec3]) -> Vec<DVec3> {
        let mut out = vec![DVec3::ZERO; self.len()];
        out.par_chunks_mut(MAP_CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                for (group, out) in out.chunks_mut(INTERLEAVED_POINTS).enumerate() {
                    let first = chunk * MAP_CHUNK + group * INTERLEAVED_POINTS;
                    self.add_terms(u, &self.starts[first..=first + out.len()], out);
                }
            });
        out
    }

    /// Adds the terms of the points whose term ranges `starts` delimits (one more entry
    /// than points) to `out`, each point's in order. A point's sum is a chain of
    /// dependent additions; a full group runs its chains side by side as far as the
    /// shortest goes, so that they overlap, then finishes each alone.
    fn add_terms(&self, u: &[DVec3], starts: &[usize], out: &mut [DVec3]) {
        let term = |k: usize| u[self.vertices[k] as usize] * self.weights[k];
        let common = if out.len() == INTERLEAVED_POINTS {
            starts.windows(2).map(|s| s[1] - s[0]).min().unwrap_or(0)
        } else {
            0
        };
        let mut sums = [DVec3::ZERO; INTERLEAVED_POINTS];
        for i in 0..common {
            for (lane, sum) in sums.iter_mut().enumerate() {
                *sum += term(starts[lane] + i);
            }
        }
        for (lane, d) in out.iter_mut().enumerate() {
            let mut sum = sums[lane];
            for k in starts[lane] + common..starts[lane + 1] {
                sum += term(k);
            }
            *d = sum;
        }
    }

    /// `rest + displacement` of every point.
    pub fn moved(&self, rest: &[DVec3], u: &[DVec3]) -> Vec<DVec3> {
        assert_eq!(rest.len(), self.len());
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
///
/// A field that is zero outside a known set of vertices (the scan beyond the model's
/// falloff, see [`PointMap::support`]) stays exactly zero more than `iterations` edge
/// rings away from that set: [`SurfaceSmoother::with_support`] updates only the vertices
/// within that reach, in the same order and with the same operations, so it gives
/// bit for bit the numbers of the smoother over the whole mesh.
#[derive(Debug, Clone, Default)]
pub struct SurfaceSmoother {
    /// Mesh vertices the smoothing updates (ascending; vertices without neighbours are
    /// left out: a step keeps their value).
    active: Vec<u32>,
    /// Neighbours of `active[k]` as positions in `active`, or `active.len()` for a
    /// neighbour outside it (whose value stays zero): `neighbours[ptr[k]..ptr[k + 1]]`.
    ptr: Vec<u32>,
    neighbours: Vec<u32>,
    /// Vertices of the mesh.
    vertex_count: usize,
    iterations: usize,
}

/// Vertices per parallel task of [`SurfaceSmoother::apply`].
const SMOOTHING_CHUNK: usize = 512;

impl SurfaceSmoother {
    /// The smoother of `mesh` reaching about `radius_mm` (0: none), over all vertices.
    /// One damped step spreads by about half an edge length squared in variance, so
    /// `4 (radius / mean edge)²` steps reach the radius.
    pub fn new(mesh: &mesh::TriMesh, radius_mm: f64) -> SurfaceSmoother {
        SurfaceSmoother::with_support(mesh, radius_mm, &vec![true; mesh.positions.len()])
    }

    /// The smoother of [`SurfaceSmoother::new`] for fields that are zero at every vertex
    /// `v` with `support[v] == false`: it updates only the vertices within
    /// [`SurfaceSmoother::iterations`] edge rings of the support, the only ones whose
    /// smoothed value can be non-zero. `support` has one entry per mesh vertex (missing
    /// entries count as outside).
    pub fn with_support(mesh: &mesh::TriMesh, radius_mm: f64, support: &[bool]) -> SurfaceSmoother {
        let vertex_count = mesh.positions.len();
        let topology = mesh::Topology::new(mesh);
        let lists: Vec<Vec<u32>> = (0..vertex_count)
            .into_par_iter()
            .map(|v| topology.vertex_neighbors(mesh, v))
            .collect();
        let mut edge_sum = 0.0;
        let mut edge_count = 0usize;
        for (v, list) in lists.iter().enumerate() {
            for &w in list {
                edge_sum += mesh.positions[v].distance(mesh.positions[w as usize]);
            }
            edge_count += list.len();
        }
        let mean_edge = edge_sum / edge_count.max(1) as f64;
        let iterations = if radius_mm > 0.0 && mean_edge > 0.0 {
            (4.0 * (radius_mm / mean_edge).powi(2)).ceil() as usize
        } else {
            0
        };
        // the vertices within `iterations` rings of the support, breadth first
        let mut reached: Vec<bool> = (0..vertex_count)
            .map(|v| support.get(v).copied().unwrap_or(false))
            .collect();
        let mut ring: Vec<u32> = (0..vertex_count as u32)
            .filter(|&v| reached[v as usize])
            .collect();
        for _ in 0..iterations {
            let mut next = Vec::new();
            for &v in &ring {
                for &w in &lists[v as usize] {
                    if !reached[w as usize] {
                        reached[w as usize] = true;
                        next.push(w);
                    }
                }
            }
            if next.is_empty() {
                break;
            }
            ring = next;
        }
        let active: Vec<u32> = (0..vertex_count as u32)
            .filter(|&v| reached[v as usize] && !lists[v as usize].is_empty())
            .collect();
        let outside = active.len() as u32;
        let mut position = vec![outside; vertex_count];
        for (k, &v) in active.iter().enumerate() {
            position[v as usize] = k as u32;
        }
        let mut ptr = Vec::with_capacity(active.len() + 1);
        ptr.push(0);
        let mut neighbours = Vec::new();
        for &v in &active {
            neighbours.extend(lists[v as usize].iter().map(|&w| position[w as usize]));
            ptr.push(neighbours.len() as u32);
        }
        SurfaceSmoother {
            active,
            ptr,
            neighbours,
            vertex_count,
            iterations,
        }
    }

    /// Number of damped Jacobi steps of [`SurfaceSmoother::apply`].
    pub fn iterations(&self) -> usize {
        self.iterations
    }

    /// Number of vertices each step updates.
    pub fn active_count(&self) -> usize {
        self.active.len()
    }

    /// Number of vertices of the mesh it smooths over.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// The mesh vertex the step updates `k`-th and its neighbours' positions among those
    /// ([`SurfaceSmoother::active_vertex`] turns one into a mesh vertex).
    pub fn vertex_and_neighbours(&self, k: usize) -> (u32, &[u32]) {
        let around = &self.neighbours[self.ptr[k] as usize..self.ptr[k + 1] as usize];
        (self.active[k], around)
    }

    /// The mesh vertex at `position` among the updated ones; `None` for a neighbour
    /// outside them (whose value is zero).
    pub fn active_vertex(&self, position: u32) -> Option<u32> {
        self.active.get(position as usize).copied()
    }

    /// Smooths `field` (one value per mesh vertex, zero outside the support the
    /// smoother was built for) in place. A field of another length is left as it is.
    pub fn apply(&self, field: &mut [DVec3]) {
        if self.iterations == 0 || field.len() != self.vertex_count {
            return;
        }
        let active_count = self.active.len();
        // x, y, z of every active vertex, then the zero of every neighbour outside them
        let mut current: Vec<f64> = Vec::with_capacity(3 * active_count + 3);
        for &v in &self.active {
            current.extend_from_slice(&field[v as usize].to_array());
        }
        current.extend_from_slice(&[0.0; 3]);
        let mut next = current.clone();
        for _ in 0..self.iterations {
            next[..3 * active_count]
                .par_chunks_mut(3 * SMOOTHING_CHUNK)
                .enumerate()
                .for_each(|(chunk, out)| self.step(&current, chunk, out));
            std::mem::swap(&mut current, &mut next);
        }
        for (&v, value) in self.active.iter().zip(current.chunks_exact(3)) {
            field[v as usize] = DVec3::new(value[0], value[1], value[2]);
        }
    }

    /// One damped Jacobi step `out = ½ current + ½ Σ neighbours / count` (component
    /// by component, each vertex's neighbours summed in order from zero, as
    /// [`DVec3`]'s sum does) of the active vertices of `chunk` (x, y, z each in `out`).
    fn step(&self, current: &[f64], chunk: usize, out: &mut [f64]) {
        let first = chunk * SMOOTHING_CHUNK;
        for (k, out) in (first..).zip(out.chunks_exact_mut(3)) {
            let around = &self.neighbours[self.ptr[k] as usize..self.ptr[k + 1] as usize];
            let mut sum = [0.0; 3];
            for &w in around {
                let value = &current[3 * w as usize..3 * w as usize + 3];
                for c in 0..3 {
                    sum[c] += value[c];
                }
            }
            let count = around.len() as f64;
            for c in 0..3 {
                out[c] = 0.5 * current[3 * k + c] + 0.5 * sum[c] / count;
            }
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

    /// Bit patterns of a field, for comparisons to the last bit.
    fn bits(field: &[DVec3]) -> Vec<[u64; 3]> {
        field
            .iter()
            .map(|d| d.to_array().map(f64::to_bits))
            .collect()
    }

    #[test]
    fn the_smoother_over_the_support_gives_the_full_smoothers_numbers() {
        let (grid, full) = grid();
        // a bump of compact support: non-zero within 12 mm of (30, 40) only, kinked
        // (a saw-tooth inside) so that the smoothing changes every value
        let centre = DVec3::new(30.0, 40.0, 0.0);
        let bump = |p: DVec3| {
            let r = p.distance(centre);
            if r < 12.0 {
                DVec3::new(1.0, -0.5, 2.0) * (12.0 - r) * (1.0 + 0.3 * (p.x % 3.0))
            } else {
                DVec3::ZERO
            }
        };
        let field: Vec<DVec3> = grid.positions.iter().map(|&p| bump(p)).collect();
        let support: Vec<bool> = field.iter().map(|d| *d != DVec3::ZERO).collect();
        let restricted = SurfaceSmoother::with_support(&grid, 2.0, &support);
        assert_eq!(restricted.iterations(), full.iterations());
        // the reach of the support: every vertex within `iterations` rings of the
        // bump (diagonal neighbours: √2 mm per ring), far fewer than the grid's
        assert!(
            restricted.active_count() < grid.positions.len() / 2,
            "{} of {}",
            restricted.active_count(),
            grid.positions.len()
        );
        let mut expected = field.clone();
        full.apply(&mut expected);
        let mut smoothed = field.clone();
        restricted.apply(&mut smoothed);
        // tolerance 0: the same additions and divisions in the same order on every
        // vertex the field can reach; the rest stays an exact zero in both
        assert_eq!(bits(&smoothed), bits(&expected));
        let spread = expected
            .iter()
            .zip(&support)
            .filter(|(d, inside)| !**inside && **d != DVec3::ZERO)
            .count();
        assert!(
            spread > 100,
            "the smoothing spread beyond the support: {spread}"
        );
    }

    #[test]
    fn the_point_map_sums_the_locators_weights_in_order() {
        // a 60 x 40 x 30 mm box of 12 x 8 x 6 cells, points inside and up to 60 mm
        // outside (beyond the 40 mm falloff too)
        let mesh = fem::boxmesh::box_mesh(DVec3::ZERO, DVec3::new(60.0, 40.0, 30.0), [12, 8, 6]);
        let locator = FieldLocator::new(&mesh, 5.0).unwrap();
        // quasi-random points over [lo, lo + size]
        let scatter = |count: usize, lo: DVec3, size: DVec3| {
            (0..count).map(move |k| {
                let t = k as f64;
                let f = DVec3::new(
                    t * 0.618_034 % 1.0,
                    t * 0.414_214 % 1.0,
                    t * 0.732_051 % 1.0,
                );
                lo + f * size
            })
        };
        let points: Vec<DVec3> = scatter(600, DVec3::splat(-60.0), DVec3::new(180.0, 160.0, 150.0))
            .chain(scatter(
                100,
                DVec3::splat(-2.0),
                DVec3::new(64.0, 44.0, 34.0),
            ))
            .collect();
        let map = PointMap::new(&locator, &points, DEFAULT_FALLOFF_MM);
        let u: Vec<DVec3> = mesh
            .positions
            .iter()
            .map(|p| DVec3::new((0.1 * p.x).sin(), p.y * p.z * 1e-3, -0.02 * p.x + 0.7))
            .collect();
        let moved = map.displacements(&u);
        let support = map.support();
        let mut counts = [0; 3];
        for (k, &p) in points.iter().enumerate() {
            // the reference: every term of the point's weights, in order
            let pw = locator.weights(p, DEFAULT_FALLOFF_MM);
            let mut expected = DVec3::ZERO;
            for c in 0..4 {
                expected += u[pw.vertices[c] as usize] * pw.weights[c];
            }
            for &(v, w) in &pw.blend {
                expected += u[v as usize] * w;
            }
            // tolerance 0: the terms left out have zero weight and add exact zeros
            assert_eq!(bits(&[moved[k]]), bits(&[expected]), "point {k} at {p:?}");
            assert_eq!(support[k], expected != DVec3::ZERO, "point {k} at {p:?}");
            counts[if pw.blend.is_empty() {
                usize::from(support[k])
            } else {
                2
            }] += 1;
        }
        // the points cover the three cases: beyond the falloff, inside or near, blended
        assert!(counts.iter().all(|&c| c > 20), "{counts:?}");
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
