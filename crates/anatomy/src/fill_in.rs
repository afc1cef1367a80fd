//! The fill-in (paper IV-C, Fig. 5): a triangle mesh closing the hole a breast leaves in
//! the base mesh, continuing the curvature of the surrounding chest. Base and fill-in
//! stitched together ([`stitch`]) form the rear wall.
//!
//! # Algorithm
//! 1. Fit the least-squares plane of the hole's boundary loop: centroid and smallest
//!    eigenvector of the covariance, the normal turned towards the base's normals along
//!    the loop; the in-plane `u` axis is the loop's principal direction. For a hole in a
//!    torso (the caller gives the body's long axis) fit instead a cylinder to the chest
//!    around the hole, about the chest's own axis near the body's (the direction its
//!    normals vary least along), and use it as the "plane": `u` runs round it, `v` along
//!    it, `w` outwards.
//! 2. Project the loop onto the plane (cylinder), giving 2D coordinates `(u, v)` and a
//!    height `w` per boundary vertex. Where the loop turns back on itself there,
//!    straighten those `(u, v)` along the chord, moving no point by more than 0.45
//!    lattice spacings (within the lattice points' clearance; the 3D loop keeps its
//!    positions); refuse a loop that is still not a simple polygon (on the cylinder:
//!    fall back to the plane).
//! 3. Put a regular square lattice of the given spacing into the polygon, dropping points
//!    closer than half a spacing to the boundary (no slivers), and triangulate loop and
//!    lattice points with a 2D constrained Delaunay triangulation (spade), the loop edges
//!    as constraints; keep the triangles inside the polygon.
//! 4. Give every lattice point a height: along each lattice row and column, where it
//!    enters and leaves the polygon, take the boundary's height and the slope of the base
//!    surface in the line's direction, and span a cubic Hermite spline between the two
//!    ends; a lattice point takes a blend of its row and column spline. The base normals
//!    the slopes come from are those of a quadric fitted to the base around each loop
//!    vertex (the vertices joined to it inside a ball of the hole's scale, 6 to 20 mm),
//!    Gaussian-filtered along the loop.
//! 5. Smooth the heights by Laplace-Beltrami steps (cotangent weights), boundary fixed.
//!
//! # Deviations from the paper, and why
//! - The plane fit weights each loop vertex by its share of the loop's arc length, so an
//!   unevenly sampled cut curve does not tilt the plane towards its dense parts.
//! - The cylinder: a chest wraps round the body, and the breast's cut curve runs from the
//!   sternum round to the side of the chest, where the base stands at some 80° to the
//!   loop's plane. Over the plane, rows ending there need near-vertical end tangents and
//!   the fill-in bulged forward (on the phantom up to 13 mm in front of the true chest
//!   wall, the breast volume 26% low); over the fitted cylinder the same rows are gentle
//!   (phantom: within 0.7 to 3.4 mm of the true wall, volumes within 2.3%).
//! - The cylinder's axis is the chest's own, not the body's: about the sternum's
//!   direction (leaning back some 25°) the axis came out through the chest below the
//!   breast, within 0.1 to 0.4 radii of the cut curve on every realistic scan, and a
//!   fill-in reaching it folded (docs/dev/fill-in-axis.md).
//! - Each spline is the paper's 3D Hermite curve (in the lattice line's vertical plane,
//!   unit base tangents scaled by the chord), but a lattice point takes the curve's height
//!   where the curve passes over it rather than at its parameter value. Lattice points
//!   therefore keep their `(u, v)`: the fill-in is a graph over the plane, so its
//!   triangles are the 2D Delaunay triangles lifted, and none can fold or flip.
//! - Row and column heights are blended with weights `1 / (d_entry · d_exit)`, the
//!   distances along each line to its two ends, rather than averaged: near a boundary
//!   the line that meets it steeply knows the base there, while the other, grazing that
//!   boundary and spanning the whole hole, does not. On the phantom both give a fill-in
//!   within 2 mm of the true chest wall; on the shared scan pair1_pre the plain mean
//!   left a 42° kink across the stitch (3 mm scale), the blend 25°.
//! - The base's tangent at a crossing is where its tangent plane meets the vertical plane
//!   of the lattice line, a slope `dw/du = -n_u / n_w` (capped at 5.7, about 80°). The
//!   normal `n` is the area-weighted normal of the base triangles at the loop vertices,
//!   interpolated along the crossed boundary edge.
//! - The base normal at a loop vertex is that of a local quadric fit (a "jet") rather
//!   than of its one ring of triangles: scanner noise tilts single normals by some 8°,
//!   and on the phantom with 0.3 mm noise the one-ring normals left the two identical
//!   breasts 3.7% apart in volume, the fitted ones (over 6 mm) 1%. Behind a breast the
//!   fit spans 20 mm, the chest's scale, not the rim's: an implant under the curve tilts
//!   the skin next to it, and a fill-in rebuilt after a simulation rose with that tilt
//!   (docs/dev/model-on-every-body.md). A small scanner hole is fitted at its own scale,
//!   the radius of a circle of its length (at least 6 mm).
//! - The Gaussian filter acts on those normals along the loop (by arc length) rather than
//!   on each family of row and column tangents: both tangents come from the same smoothed
//!   normal, and the filter width does not depend on the lattice spacing.
//! - The Laplace-Beltrami filter smooths the height function rather than all three
//!   coordinates, for the same reason as above: no tangential drift, no flipped triangles.
//!   Each explicit step moves a height halfway to the mean of its neighbours, weighted by
//!   the cotangent weights `cot α + cot β` of the current 3D triangles; only a negative
//!   edge weight is clamped (to a small positive one), so a tilted plane stays exact.
//! - Triangle orientation is read from the base: the fill-in runs against the base along
//!   every boundary edge, whichever direction the loop was given in, so base plus fill-in
//!   is consistently oriented (for a hole in an outward surface, the fill-in's normals
//!   point outward too).
//!
//! # Limitations
//! - The fill-in is a height field over the fitted plane: a cut curve that folds over
//!   seen from that plane is refused where straightening it would move a point by more
//!   than 0.45 lattice spacings (a smaller fold is straightened, and the triangles on it
//!   face backwards; lattice points may then lie as close as 0.05 spacings to the
//!   projected loop), and where the base stands steeper than the slope cap the fill-in
//!   is flatter than the base.
//! - A cubic per lattice line cannot follow curvature that changes within the hole: on a
//!   chest-like cylinder (150 mm radius, 120 mm hole) the fill-in stays within 0.2 mm of
//!   it, on a 150 x 120 x 90 mm ellipsoid within 0.8 mm.
//! - Triangles whose three corners are boundary vertices (where the boundary turns
//!   sharply) take their normal from the base's boundary alone, so on a noisy scan the
//!   angle across the stitch is as large as the scan's own roughness there.
//!
//! # Files
//! - `base.rs`: the base's normals along the loop (step 1's reference, step 4's slopes).
//! - `frame.rs`: the fitted plane or cylinder and its coordinates (step 1).
//! - `polygon.rs`: exact predicates on the projected loop: orientation, simplicity (step 2).
//! - `lattice.rs`: the lattice of interior points (step 3).
//! - `triangulate.rs`: the constrained Delaunay triangulation (step 3).
//! - `boundary.rs`: the projected loop and the Hermite heights of the lattice (step 4).
//! - `smooth.rs`: the Laplace-Beltrami smoothing (step 5).

mod base;
mod boundary;
mod frame;
mod lattice;
mod polygon;
mod smooth;
mod triangulate;

pub(crate) use triangulate::inside_polygon;

use base::{BaseAlongLoop, jet_normals, jet_radius_mm};
use boundary::Boundary;
use frame::Frame;
use glam::{DVec2, DVec3};
use lattice::Lattice;
use mesh::TriMesh;
use polygon::straighten_small_folds;
use smooth::smooth_heights;
use triangulate::triangulate;

/// Default number of Laplace-Beltrami smoothing steps (the paper uses 10 to 20).
pub const DEFAULT_SMOOTHING_STEPS: usize = 15;

/// Default standard deviation (mm of arc length along the loop) of the Gaussian that
/// smooths the base normals before the spline tangents are taken from them.
pub const DEFAULT_TANGENT_SIGMA_MM: f64 = 10.0;

/// Bounds (mm) on the default lattice spacing, the mean boundary edge length: finer
/// adds nothing to a rear wall but time, coarser loses its curvature.
const MIN_DEFAULT_SPACING_MM: f64 = 2.0;
const MAX_DEFAULT_SPACING_MM: f64 = 8.0;

/// Largest move of a loop point's plane coordinates, as a fraction of the lattice
/// spacing, when a loop that turns back on itself seen from the frame is straightened
/// there. Below the lattice points' clearance from the straightened loop
/// ([`lattice::MIN_BOUNDARY_CLEARANCE`]), moving the loop back to its projection sweeps
/// over no lattice point, so every lattice point lies inside the 3D loop's projection as
/// well (winding number one); a tenth of the clearance is kept in hand. Triangles on the
/// loop's backward edges themselves face backwards in the frame, as any height field
/// must there.
const MAX_STRAIGHTENING: f64 = 0.9 * lattice::MIN_BOUNDARY_CLEARANCE;

/// Upper bound on the lattice points over the loop's bounding box, guarding time and
/// memory against a spacing far too fine for the hole.
const MAX_LATTICE_POINTS: usize = 1 << 20;

/// Parameters of [`fill_hole`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FillInParams {
    /// Lattice spacing (mm). `None`: the mean boundary edge length, clamped to 2-8 mm.
    pub spacing_mm: Option<f64>,
    /// Laplace-Beltrami smoothing steps.
    pub smoothing_steps: usize,
    /// Standard deviation (mm of arc length) of the Gaussian filter on the base normals
    /// along the loop; zero disables it.
    pub tangent_sigma_mm: f64,
    /// The body's long axis (any length), for holes in a torso. When set, the hole is
    /// projected onto the cylinder that best fits the chest around it, about the chest's
    /// own axis within 45° of this one (else about this one), rather than onto the
    /// loop's plane; where that fit fails (a flat loop, a centre in front of the
    /// surface) the plane is used.
    pub cylinder_axis: Option<DVec3>,
}

impl Default for FillInParams {
    fn default() -> FillInParams {
        FillInParams {
            spacing_mm: None,
            smoothing_steps: DEFAULT_SMOOTHING_STEPS,
            tangent_sigma_mm: DEFAULT_TANGENT_SIGMA_MM,
            cylinder_axis: None,
        }
    }
}

/// A mesh covering one hole of a base mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct FillIn {
    /// The fill-in. Vertices `0..boundary_to_base.len()` are the hole's boundary vertices
    /// in loop order, with positions bit-identical to the base's; the lattice points
    /// follow.
    pub mesh: TriMesh,
    /// For each boundary vertex of `mesh`, its index in the base mesh.
    pub boundary_to_base: Vec<u32>,
}

/// Why a hole could not be filled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FillInError {
    #[error("the hole boundary has {0} vertices; a loop needs at least 3")]
    TooFewVertices(usize),
    #[error("hole boundary vertex {vertex} does not exist: the base has {vertex_count} vertices")]
    VertexOutOfRange { vertex: u32, vertex_count: usize },
    #[error("hole boundary vertex {0} has a non-finite position")]
    NonFiniteVertex(u32),
    #[error("the hole boundary is degenerate: its vertices are (nearly) collinear")]
    Collinear,
    #[error(
        "the cut curve is not a simple loop seen from its best-fit plane (its edge from loop position {edge} to the next touches or crosses another)"
    )]
    NotSimple { edge: usize },
    #[error("{name} = {value} is out of range: {requirement}")]
    InvalidParameter {
        name: &'static str,
        value: f64,
        requirement: &'static str,
    },
    #[error(
        "a lattice spacing of {spacing_mm} mm needs about {points:.0} lattice points for this hole, more than {MAX_LATTICE_POINTS}"
    )]
    LatticeTooLarge { spacing_mm: f64, points: f64 },
    #[error("the hole could not be triangulated: {0}")]
    Triangulation(String),
}

/// Fills the hole of `base` bounded by `boundary_loop` (vertex indices in order around the
/// hole, as [`mesh::Topology::boundary_loops`] returns them; either direction works).
/// The result shares the loop's vertices exactly; see [`stitch`] to merge it into `base`.
pub fn fill_hole(
    base: &TriMesh,
    boundary_loop: &[u32],
    params: &FillInParams,
) -> Result<FillIn, FillInError> {
    let loop_positions = loop_positions(base, boundary_loop)?;
    params.check()?;
    let spacing = params.lattice_spacing(&loop_positions);
    let mut base_side = BaseAlongLoop::gather(base, boundary_loop);
    let perimeter_mm: f64 = edge_lengths(&loop_positions).iter().sum();
    base_side.normals = jet_normals(
        base,
        boundary_loop,
        &base_side.normals,
        jet_radius_mm(perimeter_mm),
    );
    let project = |frame: &Frame| -> Result<Boundary, FillInError> {
        let mut boundary = Boundary::project(
            frame,
            &loop_positions,
            &base_side.normals,
            params.tangent_sigma_mm,
        );
        straighten_small_folds(&mut boundary.points, MAX_STRAIGHTENING * spacing)?;
        Ok(boundary)
    };
    // The cylinder where it fits and the loop stays simple on it, else the plane.
    let on_cylinder = params
        .cylinder_axis
        .and_then(|axis| Frame::fit_cylinder(base, &loop_positions, &base_side.normals, axis))
        .and_then(|cylinder| Some((project(&cylinder).ok()?, cylinder)));
    // Then the best-fit plane, and where the loop folds over seen from it (the crescent
    // a standing scan leaves round a full breast's lower pole, whose two rims overlap
    // seen from the front), the plane from which the loop encloses the most area.
    let (boundary, frame) = match on_cylinder {
        Some(found) => found,
        None => {
            let reference_normal: DVec3 = base_side.normals.iter().sum();
            let plane = Frame::fit(&loop_positions, reference_normal)?;
            match project(&plane) {
                Ok(boundary) => (boundary, plane),
                Err(error) => {
                    let facing = Frame::facing(&loop_positions, reference_normal, &plane)
                        .ok_or(error.clone())?;
                    (project(&facing).map_err(|_| error)?, facing)
                }
            }
        }
    };
    let lattice = Lattice::covering(&boundary.points, spacing)?;
    let (interior, interior_heights) = boundary.interior_points(&lattice);

    let mut triangles = triangulate(&boundary, &interior)?;
    if base_side.fill_must_flip(&boundary.points) {
        for triangle in &mut triangles {
            triangle.swap(1, 2);
        }
    }
    let points: Vec<DVec2> = boundary.points.iter().chain(&interior).copied().collect();
    let mut heights: Vec<f64> = boundary
        .heights
        .iter()
        .chain(&interior_heights)
        .copied()
        .collect();
    smooth_heights(
        &points,
        &mut heights,
        &triangles,
        boundary.points.len(),
        params.smoothing_steps,
    );

    let boundary_count = boundary.points.len();
    let positions = loop_positions
        .into_iter()
        .chain(
            (boundary_count..points.len())
                .map(|k| frame.to_world(DVec3::new(points[k].x, points[k].y, heights[k]))),
        )
        .collect();
    Ok(FillIn {
        mesh: TriMesh::new(positions, triangles),
        boundary_to_base: boundary_loop.to_vec(),
    })
}

/// Base and fill-in as one mesh, the fill-in's boundary vertices merged into the base's.
/// Base vertices and triangles keep their indices (the fill-in's interior vertices and
/// triangles follow), so callers can re-attach the base's attribute layers; the result
/// has positions and triangles only.
pub fn stitch(base: &TriMesh, fill: &FillIn) -> TriMesh {
    let boundary_count = fill.boundary_to_base.len();
    let first_interior = base.positions.len();
    let to_stitched = |v: u32| match fill.boundary_to_base.get(v as usize) {
        Some(&base_vertex) => base_vertex,
        None => (first_interior + v as usize - boundary_count) as u32,
    };
    let positions = base
        .positions
        .iter()
        .chain(fill.mesh.positions.iter().skip(boundary_count))
        .copied()
        .collect();
    let triangles = base
        .triangles
        .iter()
        .copied()
        .chain(fill.mesh.triangles.iter().map(|t| t.map(to_stitched)))
        .collect();
    TriMesh::new(positions, triangles)
}

impl FillInParams {
    /// Errors on a parameter out of range.
    fn check(&self) -> Result<(), FillInError> {
        if let Some(spacing) = self.spacing_mm
            && !(spacing.is_finite() && spacing > 0.0)
        {
            return Err(FillInError::InvalidParameter {
                name: "spacing_mm",
                value: spacing,
                requirement: "a finite length above 0 mm",
            });
        }
        let sigma = self.tangent_sigma_mm;
        if !(sigma.is_finite() && sigma >= 0.0) {
            return Err(FillInError::InvalidParameter {
                name: "tangent_sigma_mm",
                value: sigma,
                requirement: "a finite length of at least 0 mm",
            });
        }
        Ok(())
    }

    /// The lattice spacing (mm) for a loop.
    fn lattice_spacing(&self, loop_positions: &[DVec3]) -> f64 {
        self.spacing_mm.unwrap_or_else(|| {
            let perimeter: f64 = edge_lengths(loop_positions).iter().sum();
            let mean_edge = perimeter / loop_positions.len() as f64;
            mean_edge.clamp(MIN_DEFAULT_SPACING_MM, MAX_DEFAULT_SPACING_MM)
        })
    }
}

/// The loop's vertex positions, after checking the loop.
fn loop_positions(base: &TriMesh, boundary_loop: &[u32]) -> Result<Vec<DVec3>, FillInError> {
    if boundary_loop.len() < 3 {
        return Err(FillInError::TooFewVertices(boundary_loop.len()));
    }
    boundary_loop
        .iter()
        .map(|&vertex| match base.positions.get(vertex as usize) {
            Some(p) if p.is_finite() => Ok(*p),
            Some(_) => Err(FillInError::NonFiniteVertex(vertex)),
            None => Err(FillInError::VertexOutOfRange {
                vertex,
                vertex_count: base.positions.len(),
            }),
        })
        .collect()
}

/// Length (mm) of each loop edge `k -> k + 1`.
fn edge_lengths(loop_positions: &[DVec3]) -> Vec<f64> {
    let n = loop_positions.len();
    (0..n)
        .map(|k| loop_positions[k].distance(loop_positions[(k + 1) % n]))
        .collect()
}

/// The `weights`-weighted mean of `points`; `None` if the weights sum to zero or less.
fn weighted_centroid(points: &[DVec3], weights: &[f64]) -> Option<DVec3> {
    let total: f64 = weights.iter().sum();
    (total > 0.0).then(|| {
        points
            .iter()
            .zip(weights)
            .map(|(p, w)| *p * *w)
            .sum::<DVec3>()
            / total
    })
}

/// Each loop vertex's share of the loop's arc length (mm): half its two edges.
fn arc_length_weights(loop_positions: &[DVec3]) -> Vec<f64> {
    let lengths = edge_lengths(loop_positions);
    let n = lengths.len();
    (0..n)
        .map(|k| 0.5 * (lengths[(k + n - 1) % n] + lengths[k]))
        .collect()
}

#[cfg(test)]
mod tests;
