//! Closing a scan's small holes (missing data where no camera saw the skin, e.g. under the
//! lateral breast) for measurements along the surface: a tape measure lies across such a
//! gap, a path on the raw mesh would have to go around it.
//!
//! Every boundary loop except the scan's outer border (the longest loop) is closed with
//! a surface continuing the skin around it: the paper's fill-in over a cylinder about the
//! chest's axis near the body's, or a plane ([`crate::fill_in`]; its tangents come from quadrics fitted to the rim, so
//! it is the steadier on a noisy rim), or where that one refuses the loop or crosses the
//! scan near the hole (a jagged rim), the 3D fill ([`mesh::hole_patch`]), which needs no
//! projection and so also closes the crescent a standing scan leaves round a hanging
//! breast's lower and lateral pole. Where both cross the scan, the 3D fill is kept (the
//! closed surface's untangling, or its error, deals with the crossings).

use crate::fill_in::{FillIn, FillInParams, fill_hole, stitch};
use mesh::{DVec3, HolePatch, Topology, TriMesh, patch_hole, self_intersections};

/// One closed hole.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedHole {
    /// Length of the hole's boundary (mm).
    pub perimeter_mm: f64,
    /// Centre of its boundary vertices (mm).
    pub centre: [f64; 3],
}

/// A hole that could not be closed, and why.
#[derive(Debug, Clone, PartialEq)]
pub struct OpenHole {
    pub perimeter_mm: f64,
    pub centre: [f64; 3],
    pub reason: String,
}

impl std::fmt::Display for OpenHole {
    /// `a hole of 40 mm perimeter near [x, y, z] stays open (reason)`.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "a hole of {:.0} mm perimeter near {:.0?} stays open ({})",
            self.perimeter_mm, self.centre, self.reason
        )
    }
}

/// A scan with its holes closed. Its first vertices and triangles are the input's, in
/// the same order, so points located on the input are valid on it.
#[derive(Debug, Clone)]
pub struct ClosedScan {
    pub mesh: TriMesh,
    pub closed: Vec<ClosedHole>,
    pub left_open: Vec<OpenHole>,
}

/// Closes every hole of `scan` but its outer border (the longest boundary loop) with the
/// fill-in of `params`. Give the body's long axis as `params.cylinder_axis` where it is
/// known: the hole a standing scan leaves under a full breast is a crescent wrapped round
/// the lower pole, whose two rims overlap seen from its own best-fit plane but not seen
/// from an axis near the body's (the surface's own where the skin around the hole
/// determines one, else the body's: round a breast's dome it does not).
pub fn close_scan_holes(scan: &TriMesh, topology: &Topology, params: &FillInParams) -> ClosedScan {
    let mut loops: Vec<(f64, Vec<u32>)> = topology
        .boundary_loops(scan)
        .into_iter()
        .map(|l| (loop_length(scan, &l), l))
        .collect();
    loops.sort_by(|a, b| b.0.total_cmp(&a.0));
    let mut mesh = scan.clone();
    let mut closed = Vec::new();
    let mut left_open = Vec::new();
    for (perimeter_mm, boundary) in loops.into_iter().skip(1) {
        let centre = (boundary
            .iter()
            .map(|&v| scan.positions[v as usize])
            .sum::<mesh::DVec3>()
            / boundary.len() as f64)
            .to_array();
        // Holes are filled one at a time into the growing mesh; earlier vertices keep
        // their indices, so the loop stays valid.
        let filled = fill_one(&mesh, topology, &boundary, params);
        match filled {
            Ok(fill) => {
                mesh = stitch(&mesh, &fill);
                closed.push(ClosedHole {
                    perimeter_mm,
                    centre,
                });
            }
            Err(error) => left_open.push(OpenHole {
                perimeter_mm,
                centre,
                reason: error,
            }),
        }
    }
    ClosedScan {
        mesh,
        closed,
        left_open,
    }
}

/// Closes one hole: the first of the projected fill-in and the 3D fill that crosses no
/// triangle of `mesh` near the hole, else the 3D fill if it was built (the closed
/// surface's untangling smooths a rim's noise folds out of it more often than out of the
/// projected one); the reasons of both where neither could be built.
fn fill_one(
    mesh: &TriMesh,
    topology: &Topology,
    boundary: &[u32],
    params: &FillInParams,
) -> Result<FillIn, String> {
    let in_3d = || {
        patch_hole(mesh, topology, boundary)
            .map(|patch| patch_as_fill_in(mesh, boundary, patch))
            .map_err(|error| format!("in 3D: {error}"))
    };
    let projected = || fill_hole(mesh, boundary, params).map_err(|error| error.to_string());
    let mut reasons = Vec::new();
    let mut crossing: Option<FillIn> = None;
    for attempt in [&projected as &dyn Fn() -> Result<FillIn, String>, &in_3d] {
        match attempt() {
            Ok(fill) if crosses_near(mesh, &fill) => crossing = Some(fill),
            Ok(fill) => return Ok(fill),
            Err(reason) => reasons.push(reason),
        }
    }
    crossing.ok_or(reasons.join("; "))
}

/// Margin (mm) round a fill's bounding box within which the surface's triangles are
/// checked against it.
const CROSSING_MARGIN_MM: f64 = 5.0;

/// Whether the fill crosses itself or a triangle of `mesh` near it.
fn crosses_near(mesh: &TriMesh, fill: &FillIn) -> bool {
    let stitched = stitch(mesh, fill);
    let fill_triangles = mesh.triangle_count()..stitched.triangle_count();
    let (low, high) = fill.mesh.positions.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(low, high), &p| (low.min(p), high.max(p)),
    );
    let (low, high) = (
        low - DVec3::splat(CROSSING_MARGIN_MM),
        high + DVec3::splat(CROSSING_MARGIN_MM),
    );
    let near = |t: &[u32; 3]| {
        t.iter().any(|&v| {
            let p = stitched.positions[v as usize];
            p.cmpge(low).all() && p.cmple(high).all()
        })
    };
    // The fill's triangles first, so a pair involving one has its first index below
    // their count.
    let selected: Vec<[u32; 3]> = stitched.triangles[fill_triangles.clone()]
        .iter()
        .chain(
            stitched.triangles[..fill_triangles.start]
                .iter()
                .filter(|t| near(t)),
        )
        .copied()
        .collect();
    let local = TriMesh::from_used_vertices(&stitched.positions, &selected);
    self_intersections(&local)
        .into_iter()
        .any(|(a, _)| a < fill_triangles.len())
}

/// A 3D patch in the fill-in's form: the loop's vertices first, then its interior.
fn patch_as_fill_in(mesh: &TriMesh, boundary: &[u32], patch: HolePatch) -> FillIn {
    let positions = boundary
        .iter()
        .map(|&v| mesh.positions[v as usize])
        .chain(patch.interior)
        .collect();
    FillIn {
        mesh: TriMesh::new(positions, patch.triangles),
        boundary_to_base: boundary.to_vec(),
    }
}

pub(crate) fn loop_length(mesh: &TriMesh, boundary: &[u32]) -> f64 {
    (0..boundary.len())
        .map(|i| {
            let next = boundary[(i + 1) % boundary.len()];
            mesh.positions[boundary[i] as usize].distance(mesh.positions[next as usize])
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::grid;

    #[test]
    fn inner_holes_are_closed_and_the_border_is_kept() {
        // A 40 x 40 mm grid with two square holes of 4 x 4 cells.
        let mut scan = grid(40, 40, 1.0);
        let holes = [(10.0, 10.0), (25.0, 28.0)];
        let in_hole = |c: mesh::DVec3| {
            holes
                .iter()
                .any(|&(x, y)| (c.x - x).abs() < 2.0 && (c.y - y).abs() < 2.0)
        };
        let remove: Vec<usize> = (0..scan.triangle_count())
            .filter(|&t| in_hole(scan.triangle_positions(t).iter().sum::<mesh::DVec3>() / 3.0))
            .collect();
        let area_before = scan.area();
        scan.remove_triangles(&remove);
        let topology = Topology::new(&scan);
        assert_eq!(topology.boundary_loops(&scan).len(), 3);

        let result = close_scan_holes(&scan, &topology, &FillInParams::default());
        assert_eq!(result.closed.len(), 2);
        assert!(result.left_open.is_empty());
        for hole in &result.closed {
            assert!((hole.perimeter_mm - 16.0).abs() < 1e-12);
        }
        let closed_topology = Topology::new(&result.mesh);
        assert_eq!(closed_topology.boundary_loops(&result.mesh).len(), 1);
        assert_eq!(closed_topology.inconsistent_edge_count, 0);
        // Flat holes are filled flat: the area is the full grid's again.
        assert!((result.mesh.area() - area_before).abs() < 1e-9);
        assert_eq!(
            &result.mesh.positions[..scan.vertex_count()],
            &scan.positions[..]
        );
        assert_eq!(
            &result.mesh.triangles[..scan.triangle_count()],
            &scan.triangles[..]
        );
    }
}
