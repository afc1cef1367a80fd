//! What the base says along the loop: its normals there, fitted to the base around each
//! loop vertex and smoothed along the loop.

use super::polygon::is_counter_clockwise;
use super::{arc_length_weights, edge_lengths};
use faer::linalg::solvers::Solve;
use faer::{Mat, Side};
use glam::{DVec2, DVec3};
use mesh::TriMesh;

/// The Gaussian filter along the loop ignores vertices beyond this many sigmas.
const GAUSSIAN_CUTOFF_SIGMAS: f64 = 3.0;

/// Largest radius (mm) of the base patch whose fitted quadric gives the base's normal at a
/// loop vertex: the chest's scale over a breast-sized hole, so the normal follows the
/// chest's curvature (which the quadric fits) and not the tilt of the last few
/// millimetres of skin next to the loop, which an implant under the curve lifts.
const MAX_JET_RADIUS_MM: f64 = 20.0;

/// Smallest patch radius (mm): some 20 scan vertices on the base side of 2 mm triangles,
/// enough for a scanner's noise (8° on a single normal) to average out.
const MIN_JET_RADIUS_MM: f64 = 6.0;

/// A quadric fit needs at least this many points (it has six unknowns).
const MIN_JET_POINTS: usize = 10;

/// The patch radius for a hole whose loop is `perimeter_mm` long: the radius of a circle
/// of that perimeter, the hole's own scale, within [`MIN_JET_RADIUS_MM`] and
/// [`MAX_JET_RADIUS_MM`]; a small scanner hole in a crease or by the areola is not fitted
/// over the crease's far wall or the nipple.
pub(super) fn jet_radius_mm(perimeter_mm: f64) -> f64 {
    (perimeter_mm / std::f64::consts::TAU).clamp(MIN_JET_RADIUS_MM, MAX_JET_RADIUS_MM)
}

/// The base's normal at each loop vertex (`boundary_loop[k]`) from a least-squares quadric
/// `w = a + b·u + c·v + d·u² + e·u·v + f·v²` fitted to the base vertices within
/// `radius_mm` that base edges join to the loop vertex inside that ball (not another
/// sheet of the scan the ball reaches: an arm, a fold's far side), in the tangent frame of
/// its one-ring normal `normals[k]`: the normal of the quadric at the vertex, `(-b, -c, 1)`.
/// Where too few points or a singular fit, the one-ring normal stays.
pub(super) fn jet_normals(
    base: &TriMesh,
    boundary_loop: &[u32],
    normals: &[DVec3],
    radius_mm: f64,
) -> Vec<DVec3> {
    let mut balls = ConnectedBalls::new(base);
    let mut patch = Vec::new();
    boundary_loop
        .iter()
        .zip(normals)
        .map(|(&vertex, &normal)| {
            let Some(normal) = normal.try_normalize() else {
                return normal;
            };
            let Some(centre) = balls.gather(vertex, radius_mm, &mut patch) else {
                return normal;
            };
            quadric_normal(centre, normal, &patch, radius_mm).unwrap_or(normal)
        })
        .collect()
}

/// The unit normal at `centre` of the quadric fitted to `patch` in the tangent frame of
/// `normal` (unit), if the fit is determined.
fn quadric_normal(centre: DVec3, normal: DVec3, patch: &[DVec3], radius_mm: f64) -> Option<DVec3> {
    if patch.len() < MIN_JET_POINTS {
        return None;
    }
    let (u_axis, v_axis) = normal.any_orthonormal_pair();
    let mut normal_matrix = Mat::<f64>::zeros(6, 6);
    let mut rhs = Mat::<f64>::zeros(6, 1);
    for &p in patch {
        let d = p - centre;
        // Coordinates in units of the radius keep the system well scaled.
        let (u, v, w) = (
            d.dot(u_axis) / radius_mm,
            d.dot(v_axis) / radius_mm,
            d.dot(normal) / radius_mm,
        );
        let row = [1.0, u, v, u * u, u * v, v * v];
        for i in 0..6 {
            rhs[(i, 0)] += row[i] * w;
            for j in 0..6 {
                normal_matrix[(i, j)] += row[i] * row[j];
            }
        }
    }
    let x = normal_matrix.llt(Side::Lower).ok()?.solve(&rhs);
    let (slope_u, slope_v) = (x[(1, 0)], x[(2, 0)]);
    let fitted = (normal - slope_u * u_axis - slope_v * v_axis).normalize_or_zero();
    (fitted.is_finite() && fitted != DVec3::ZERO).then_some(fitted)
}

/// A mesh's vertex adjacency, for gathering the vertices that edges join to a vertex
/// within a ball about it; triangles with out-of-range indices are left out.
pub(super) struct ConnectedBalls<'a> {
    mesh: &'a TriMesh,
    /// `neighbours[offsets[v]..offsets[v + 1]]` are the vertices sharing an edge with `v`.
    offsets: Vec<usize>,
    neighbours: Vec<u32>,
    /// The gather that last reached each vertex, so no per-gather clearing is needed.
    reached_by: Vec<usize>,
    gathers: usize,
    /// Vertices reached and not yet expanded (reused between gathers).
    pending: Vec<u32>,
}

impl<'a> ConnectedBalls<'a> {
    pub(super) fn new(mesh: &'a TriMesh) -> ConnectedBalls<'a> {
        let n = mesh.positions.len();
        let valid = |t: &&[u32; 3]| t.iter().all(|&v| (v as usize) < n);
        let mut offsets = vec![0usize; n + 1];
        for triangle in mesh.triangles.iter().filter(valid) {
            for &v in triangle {
                offsets[v as usize + 1] += 2;
            }
        }
        for v in 0..n {
            offsets[v + 1] += offsets[v];
        }
        let mut filled = offsets.clone();
        let mut neighbours = vec![0u32; offsets[n]];
        for triangle in mesh.triangles.iter().filter(valid) {
            for corner in 0..3 {
                let v = triangle[corner] as usize;
                for other in [triangle[(corner + 1) % 3], triangle[(corner + 2) % 3]] {
                    neighbours[filled[v]] = other;
                    filled[v] += 1;
                }
            }
        }
        ConnectedBalls {
            mesh,
            offsets,
            neighbours,
            reached_by: vec![0; n],
            gathers: 0,
            pending: Vec::new(),
        }
    }

    /// Writes into `patch` the positions of the vertices within `radius_mm` of vertex
    /// `centre` that a path of edges inside that ball joins to it, `centre` included, and
    /// returns `centre`'s position; `None` (and `patch` empty) if there is no such vertex.
    pub(super) fn gather(
        &mut self,
        centre: u32,
        radius_mm: f64,
        patch: &mut Vec<DVec3>,
    ) -> Option<DVec3> {
        patch.clear();
        let origin = *self.mesh.positions.get(centre as usize)?;
        self.gathers += 1;
        self.pending.clear();
        self.pending.push(centre);
        self.reached_by[centre as usize] = self.gathers;
        while let Some(vertex) = self.pending.pop() {
            let vertex = vertex as usize;
            patch.push(self.mesh.positions[vertex]);
            for &next in &self.neighbours[self.offsets[vertex]..self.offsets[vertex + 1]] {
                let reached = &mut self.reached_by[next as usize];
                let position = self.mesh.positions[next as usize];
                if *reached != self.gathers
                    && position.distance_squared(origin) <= radius_mm * radius_mm
                {
                    *reached = self.gathers;
                    self.pending.push(next);
                }
            }
        }
        Some(origin)
    }
}

/// What the base says along the loop.
pub(super) struct BaseAlongLoop {
    /// Per loop vertex, the unit area-weighted normal of its base triangles (zero if none).
    pub(super) normals: Vec<DVec3>,
    /// Loop edges that a base triangle traverses in loop direction, minus those it
    /// traverses against it.
    forward_edge_votes: i64,
}

impl BaseAlongLoop {
    /// One pass over the base's triangles; needs no topology and tolerates invalid ones.
    pub(super) fn gather(base: &TriMesh, boundary_loop: &[u32]) -> BaseAlongLoop {
        const NOT_ON_LOOP: usize = usize::MAX;
        let n = boundary_loop.len();
        let mut loop_index = vec![NOT_ON_LOOP; base.positions.len()];
        for (k, &vertex) in boundary_loop.iter().enumerate() {
            if let Some(slot) = loop_index.get_mut(vertex as usize) {
                *slot = k;
            }
        }
        let mut normals = vec![DVec3::ZERO; n];
        let mut forward_edge_votes = 0;
        for triangle in &base.triangles {
            let on_loop =
                triangle.map(|v| loop_index.get(v as usize).copied().unwrap_or(NOT_ON_LOOP));
            if on_loop.iter().all(|&k| k == NOT_ON_LOOP) {
                continue;
            }
            let corner = |k: usize| base.positions.get(triangle[k] as usize);
            let (Some(&a), Some(&b), Some(&c)) = (corner(0), corner(1), corner(2)) else {
                continue;
            };
            // Twice the area along the normal: area weighting for free.
            let weighted_normal = (b - a).cross(c - a);
            if !weighted_normal.is_finite() {
                continue;
            }
            for corner in 0..3 {
                let (from, to) = (on_loop[corner], on_loop[(corner + 1) % 3]);
                if from == NOT_ON_LOOP {
                    continue;
                }
                normals[from] += weighted_normal;
                if to == (from + 1) % n {
                    forward_edge_votes += 1;
                } else if to != NOT_ON_LOOP && from == (to + 1) % n {
                    forward_edge_votes -= 1;
                }
            }
        }
        BaseAlongLoop {
            normals: normals.iter().map(|n| n.normalize_or_zero()).collect(),
            forward_edge_votes,
        }
    }

    /// Whether the counter-clockwise (in `(u, v)`) triangles of the triangulation must be
    /// reversed so that the fill-in runs against the base along the loop. Without base
    /// triangles on the loop they are kept, their normals along the fitted plane's.
    pub(super) fn fill_must_flip(&self, polygon: &[DVec2]) -> bool {
        // A counter-clockwise triangle inside a counter-clockwise polygon runs along it.
        let triangles_run_along_loop = is_counter_clockwise(polygon);
        match self.forward_edge_votes.signum() {
            1 => triangles_run_along_loop,
            -1 => !triangles_run_along_loop,
            _ => false,
        }
    }
}

/// Gaussian filter (standard deviation `sigma_mm` of arc length) of per-vertex vectors
/// along the closed loop, each vertex weighted by its arc-length share; unit results.
pub(super) fn gaussian_along_loop(
    values: &[DVec3],
    loop_positions: &[DVec3],
    sigma_mm: f64,
) -> Vec<DVec3> {
    if sigma_mm <= 0.0 {
        return values.to_vec();
    }
    let n = values.len();
    let lengths = edge_lengths(loop_positions);
    let shares = arc_length_weights(loop_positions);
    let cutoff = GAUSSIAN_CUTOFF_SIGMAS * sigma_mm;
    let weighted = |j: usize, distance: f64| {
        values[j] * shares[j] * (-0.5 * (distance / sigma_mm).powi(2)).exp()
    };
    (0..n)
        .map(|i| {
            let mut sum = weighted(i, 0.0);
            // Forward and backward, visiting every other vertex at most once.
            let mut distance = 0.0;
            for step in 1..=n / 2 {
                distance += lengths[(i + step - 1) % n];
                if distance > cutoff {
                    break;
                }
                sum += weighted((i + step) % n, distance);
            }
            distance = 0.0;
            for step in 1..=(n - 1) / 2 {
                let j = (i + n - step) % n;
                distance += lengths[j];
                if distance > cutoff {
                    break;
                }
                sum += weighted(j, distance);
            }
            sum.normalize_or_zero()
        })
        .collect()
}
