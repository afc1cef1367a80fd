//! Filling a hole of a surface in 3D, without projecting it (Liepa 2003, "Filling holes
//! in meshes", Eurographics SGP): for holes no plane or cylinder sees as a simple
//! polygon, such as the crescent a standing scan leaves round a hanging breast's lower
//! and lateral pole.
//!
//! # Algorithm
//! 1. Triangulate the boundary loop alone by dynamic programming over its vertices: of all
//!    triangulations whose triangles use loop vertices only, the one whose largest
//!    dihedral angle (between its own triangles and with the surface along the loop) is
//!    smallest, ties broken by the smallest area (`triangulate.rs`).
//! 2. Refine it to the loop's edge length: split interior edges longer than 4/3 of the
//!    target at their midpoint, then flip edges whose opposite angles sum to more than π
//!    (`refine.rs`).
//! 3. Fair it: the interior vertices minimise the squared uniform (umbrella) Laplacian
//!    summed over every patch vertex, the loop and its ring on the surface held, a
//!    discrete thin plate that meets the surface with a continuous tangent plane
//!    (`fair.rs`).
//!
//! # Deviations from the paper, and why
//! - Refinement by edge splits and flips rather than Liepa's centroid insertion with a
//!   per-vertex scale: both give a patch of the loop's density; the edge form needs no
//!   circumsphere tests.
//! - One fairing solve (sparse Cholesky of the normal equations) instead of Liepa's
//!   scale-dependent umbrella iterations: the refined patch is near uniform, so the
//!   uniform umbrella's bias is small, and a direct solve has no iteration count to tune.

mod fair;
mod refine;
mod triangulate;

use crate::topology::Topology;
use crate::trimesh::TriMesh;
use glam::DVec3;
use std::collections::HashSet;

/// Largest loop taken: the triangulation's time grows with the cube of the loop's
/// vertices (about 0.5 s for 554 on these two cores, `cargo bench -p mesh --bench
/// hole_patch`) and its tables with the square; a breast's crescent has 150-480 at
/// scanner spacing. A triangulation in two levels (every other vertex first) was tried
/// for longer loops and left fills crossing the scan (`docs/dev/model-on-every-body.md`).
pub const MAX_LOOP_VERTICES: usize = 800;

/// Bounds (mm) on the patch's target edge length, the loop's mean edge length: finer
/// adds vertices and time for nothing a surface measurement sees, coarser loses the
/// curvature.
const MIN_EDGE_MM: f64 = 2.0;
const MAX_EDGE_MM: f64 = 8.0;

/// A patch closing one hole. Vertex `k < loop_len` of its triangles is the loop's `k`-th
/// vertex; vertex `loop_len + j` is `interior[j]`. Triangles are oriented like the
/// surface around the hole.
#[derive(Debug, Clone, PartialEq)]
pub struct HolePatch {
    pub interior: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Why a hole could not be patched.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HolePatchError {
    #[error("the hole's boundary has {0} vertices; a loop needs at least 3")]
    TooFewVertices(usize),
    #[error(
        "the hole's boundary has {0} vertices, more than the {MAX_LOOP_VERTICES} the 3D fill takes"
    )]
    TooManyVertices(usize),
    #[error("hole boundary vertex {0} does not exist or has a non-finite position")]
    InvalidVertex(u32),
    #[error(
        "the hole's boundary edge from vertex {0} to {1} is not the edge of exactly one triangle"
    )]
    NotABoundaryEdge(u32, u32),
    #[error("the patch could not be faired: {0}")]
    Fairing(String),
}

/// Patches the hole of `surface` bounded by `boundary_loop` (vertex indices in order round
/// the hole, either direction, as [`Topology::boundary_loops`] gives them). `topology`
/// may be that of an earlier state of `surface` that already had this hole and the
/// triangles along it.
pub fn patch_hole(
    surface: &TriMesh,
    topology: &Topology,
    boundary_loop: &[u32],
) -> Result<HolePatch, HolePatchError> {
    let n = boundary_loop.len();
    if n < 3 {
        return Err(HolePatchError::TooFewVertices(n));
    }
    if n > MAX_LOOP_VERTICES {
        return Err(HolePatchError::TooManyVertices(n));
    }
    let positions = boundary_loop
        .iter()
        .map(|&v| {
            surface
                .positions
                .get(v as usize)
                .copied()
                .filter(|p| p.is_finite())
                .ok_or(HolePatchError::InvalidVertex(v))
        })
        .collect::<Result<Vec<DVec3>, _>>()?;
    let along = SurfaceAlongLoop::gather(surface, topology, boundary_loop)?;
    let mut triangles = triangulate::minimum_weight(&positions, &along.edge_normals);
    let target_edge_mm = (0..n)
        .map(|i| positions[i].distance(positions[(i + 1) % n]))
        .sum::<f64>()
        / n as f64;
    let target_edge_mm = target_edge_mm.clamp(MIN_EDGE_MM, MAX_EDGE_MM);
    let mut all_positions = positions.clone();
    refine::refine(&mut all_positions, &mut triangles, target_edge_mm);
    let on_loop: HashSet<u32> = boundary_loop.iter().copied().collect();
    let ring: Vec<Vec<DVec3>> = boundary_loop
        .iter()
        .map(|&v| {
            topology
                .vertex_neighbors(surface, v as usize)
                .into_iter()
                .filter(|w| !on_loop.contains(w))
                .map(|w| surface.positions[w as usize])
                .collect()
        })
        .collect();
    fair::fair(&mut all_positions, &triangles, n, &ring)?;
    if along.loop_runs_with_surface {
        for triangle in &mut triangles {
            triangle.swap(1, 2);
        }
    }
    Ok(HolePatch {
        interior: all_positions.split_off(n),
        triangles,
    })
}

/// The surface's triangles along the loop.
struct SurfaceAlongLoop {
    /// For loop edge `i -> i+1`, the unit normal of the surface's triangle on it, turned
    /// to the orientation the patch's triangles have in loop order `(i, m, k)`.
    edge_normals: Vec<DVec3>,
    /// Whether the surface's triangles run along the loop's direction (so the patch,
    /// built in loop order, must be turned over to match them).
    loop_runs_with_surface: bool,
}

impl SurfaceAlongLoop {
    fn gather(
        surface: &TriMesh,
        topology: &Topology,
        boundary_loop: &[u32],
    ) -> Result<SurfaceAlongLoop, HolePatchError> {
        let n = boundary_loop.len();
        let mut edge_normals = Vec::with_capacity(n);
        let mut runs_with = 0usize;
        for i in 0..n {
            let (a, b) = (boundary_loop[i], boundary_loop[(i + 1) % n]);
            let mut on_edge = topology
                .vertex_triangles(a as usize)
                .iter()
                .filter(|&&t| surface.triangles[t as usize].contains(&b));
            let (Some(&t), None) = (on_edge.next(), on_edge.next()) else {
                return Err(HolePatchError::NotABoundaryEdge(a, b));
            };
            let corners = surface.triangles[t as usize];
            let same_direction = (0..3).any(|k| corners[k] == a && corners[(k + 1) % 3] == b);
            let [p, q, r] = corners.map(|v| surface.positions[v as usize]);
            let normal = (q - p).cross(r - p).normalize_or_zero();
            // A patch triangle (i, m, k) runs i -> m; it matches the surface if the
            // surface runs b -> a, so a surface running a -> b faces the other way.
            if same_direction {
                runs_with += 1;
                edge_normals.push(-normal);
            } else {
                edge_normals.push(normal);
            }
        }
        Ok(SurfaceAlongLoop {
            edge_normals,
            loop_runs_with_surface: 2 * runs_with > n,
        })
    }
}

#[cfg(test)]
mod tests;
