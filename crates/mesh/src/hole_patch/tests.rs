use super::*;
use crate::intersect::self_intersections;
use crate::shapes::{grid, icosphere};

/// `surface` with `remove` taken out, its one hole (the second-longest boundary loop, or
/// the only loop of a closed surface) patched and stitched in.
fn patched(mut surface: TriMesh, remove: impl Fn(DVec3) -> bool) -> (TriMesh, usize) {
    let removed: Vec<usize> = (0..surface.triangle_count())
        .filter(|&t| remove(surface.triangle_positions(t).iter().sum::<DVec3>() / 3.0))
        .collect();
    surface.remove_triangles(&removed);
    let topology = Topology::new(&surface);
    let mut loops = topology.boundary_loops(&surface);
    loops.sort_by_key(|l| std::cmp::Reverse(l.len()));
    let hole = if loops.len() == 1 {
        loops.remove(0)
    } else {
        loops.remove(1)
    };
    let patch = patch_hole(&surface, &topology, &hole).unwrap();
    let first_interior = surface.vertex_count() as u32;
    let n = hole.len() as u32;
    let mut positions = surface.positions.clone();
    positions.extend(&patch.interior);
    let mut triangles = surface.triangles.clone();
    triangles.extend(patch.triangles.iter().map(|t| {
        t.map(|v| {
            if v < n {
                hole[v as usize]
            } else {
                first_interior + v - n
            }
        })
    }));
    (TriMesh::new(positions, triangles), patch.interior.len())
}

#[test]
fn a_hole_in_a_plane_is_patched_flat_and_exactly_covered() {
    // 40 x 40 mm at 1 mm, an L-shaped hole (not convex, so a fan would not do).
    let surface = grid(40, 40, 1.0);
    let area = surface.area();
    let in_hole = |c: DVec3| {
        (10.0..30.0).contains(&c.x) && (10.0..16.0).contains(&c.y)
            || (10.0..16.0).contains(&c.x) && (10.0..30.0).contains(&c.y)
    };
    let (mesh, interior) = patched(surface, in_hole);
    // The loop's edges are 1 mm, so the target is the 2 mm floor: interior vertices exist.
    assert!(interior > 0);
    // The thin plate through a flat boundary is the plane (rounding only).
    for p in &mesh.positions {
        assert!(p.z.abs() < 1e-9, "{p}");
    }
    // Flat and without folds: the area is the full grid's again.
    assert!((mesh.area() - area).abs() < 1e-9);
    let topology = Topology::new(&mesh);
    assert_eq!(topology.boundary_loops(&mesh).len(), 1);
    assert_eq!(topology.inconsistent_edge_count, 0);
}

#[test]
fn a_band_round_a_sphere_is_patched_close_to_the_sphere() {
    // A rim of 276 vertices.
    band_round_a_sphere(100.0, 5, 0.15);
}

/// A band 8° of latitude wide wrapping 250° round a sphere of `radius`, patched within
/// `tolerance_mm` of the sphere, closed, consistently oriented, without self-crossing.
fn band_round_a_sphere(radius: f64, subdivisions: u32, tolerance_mm: f64) {
    // A crescent wrapping 250 degrees: no plane sees its loop as a simple polygon, as
    // with the hole a standing scan leaves round a hanging breast's lower and lateral
    // pole.
    let sphere = icosphere(radius, subdivisions);
    let in_band = |c: DVec3| {
        let latitude = (c.z / c.length()).asin().to_degrees();
        let longitude = c.y.atan2(c.x).to_degrees().rem_euclid(360.0);
        latitude.abs() < 4.0 && longitude < 250.0
    };
    let (mesh, interior) = patched(sphere, in_band);
    assert!(interior > 50, "{interior}");
    // The sphere's sag over the band's width w is w^2 / 8r (0.25 mm on the 100 mm
    // sphere), which a patch of straight chords across the band would miss by; one that
    // continues the tangent planes on both rims stays within 60% of it (0.09 mm measured
    // there).
    let worst = mesh
        .positions
        .iter()
        .map(|p| (p.length() - radius).abs())
        .fold(0.0, f64::max);
    assert!(worst < tolerance_mm, "{worst}");
    let topology = Topology::new(&mesh);
    assert!(topology.boundary_loops(&mesh).is_empty());
    assert_eq!(topology.inconsistent_edge_count, 0);
    assert!(self_intersections(&mesh).is_empty());
}

#[test]
fn bad_loops_are_refused_with_their_reason() {
    let surface = grid(4, 4, 1.0);
    let topology = Topology::new(&surface);
    assert_eq!(
        patch_hole(&surface, &topology, &[0, 1]),
        Err(HolePatchError::TooFewVertices(2))
    );
    assert_eq!(
        patch_hole(&surface, &topology, &[0, 1, 99]),
        Err(HolePatchError::InvalidVertex(99))
    );
    let long: Vec<u32> = (0..=MAX_LOOP_VERTICES as u32).collect();
    assert_eq!(
        patch_hole(&surface, &topology, &long),
        Err(HolePatchError::TooManyVertices(MAX_LOOP_VERTICES + 1))
    );
    // An interior edge of the grid is not a hole's edge.
    let centre = 2 * 5 + 2;
    assert!(matches!(
        patch_hole(&surface, &topology, &[centre, centre + 1, centre + 6]),
        Err(HolePatchError::NotABoundaryEdge(..))
    ));
}
