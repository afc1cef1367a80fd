//! The constrained Delaunay triangulation of the loop and the lattice points inside it.

use super::FillInError;
use super::boundary::Boundary;
use super::polygon::is_counter_clockwise;
use glam::DVec2;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Constrained Delaunay triangles of the loop (vertices `0..n`, edges as constraints) and
/// the interior points (vertices `n..`), those inside the loop only, counter-clockwise in
/// `(u, v)`.
pub(super) fn triangulate(
    boundary: &Boundary,
    interior: &[DVec2],
) -> Result<Vec<[u32; 3]>, FillInError> {
    let boundary_count = boundary.points.len();
    // Spade refuses nonzero coordinates below its minimum; they are zero to any purpose.
    let flush = |x: f64| {
        if x.abs() < spade::MIN_ALLOWED_VALUE {
            0.0
        } else {
            x
        }
    };
    let vertices: Vec<Point2<f64>> = boundary
        .points
        .iter()
        .chain(interior)
        .map(|p| Point2::new(flush(p.x), flush(p.y)))
        .collect();
    let vertex_count = vertices.len();
    let loop_is_counter_clockwise = is_counter_clockwise(&boundary.points);
    let edges = (0..boundary_count)
        .map(|k| [k, (k + 1) % boundary_count])
        .collect();
    let mut conflict = None;
    let cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(
        vertices,
        edges,
        |edge| conflict = Some(edge),
    )
    .map_err(|error| FillInError::Triangulation(format!("invalid coordinate ({error})")))?;
    // Spade's own check of the constraints, behind `straighten_small_folds`'s.
    if let Some([from, to]) = conflict {
        let edge = if (from + 1) % boundary_count == to {
            from
        } else {
            to
        };
        return Err(FillInError::NotSimple { edge });
    }
    if cdt.num_vertices() != vertex_count {
        return Err(FillInError::Triangulation(
            "two points coincide seen from the best-fit plane".to_string(),
        ));
    }
    Ok(cdt
        .inner_faces()
        .filter_map(|face| {
            let corners = face.vertices().map(|v| v.fix().index());
            // A triangle with a lattice corner is inside: constraints are never crossed.
            let inside = corners.iter().any(|&c| c >= boundary_count)
                || inside_polygon(corners, loop_is_counter_clockwise);
            inside.then(|| corners.map(|c| c as u32))
        })
        .collect())
}

/// Whether a counter-clockwise triangle of a constrained Delaunay triangulation whose
/// three corners are polygon vertices (indices in polygon order) lies inside the polygon:
/// exactly if it lists them in the polygon's cyclic order and sense. This needs no
/// geometry, so slivers along straight runs of the polygon are classified as reliably as
/// the triangulation's exact predicates.
pub(crate) fn inside_polygon(corners: [usize; 3], polygon_counter_clockwise: bool) -> bool {
    let ascents = (0..3)
        .filter(|&k| corners[k] < corners[(k + 1) % 3])
        .count();
    (ascents == 2) == polygon_counter_clockwise
}
