//! Point location against brute force over all tetrahedra.

mod common;

use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use tetra::locate::{barycentric, distance_to_tet};
use tetra::{ClosedSurface, TetLocator, stuff};

/// Barycentric tolerance for "contains" in the brute force.
const TOLERANCE: f64 = 1e-9;

#[test]
fn located_tetrahedra_match_brute_force() {
    let surface = ClosedSurface::new(&mesh::shapes::torus(40.0, 15.0, 96, 32)).unwrap();
    let mesh = stuff(&surface, 5.0).unwrap();
    let locator = TetLocator::new(&mesh);
    let (lo, hi) = mesh.bounding_box();
    let margin = DVec3::splat(6.0);
    let mut rng = Pcg64::seed_from_u64(7);
    let (mut inside, mut outside) = (0, 0);
    for _ in 0..2000 {
        let p = (lo - margin)
            + DVec3::new(rng.random(), rng.random(), rng.random()) * (hi - lo + 2.0 * margin);
        let containing: Vec<usize> = (0..mesh.tet_count())
            .filter(|&t| {
                barycentric(mesh.tet_positions(t), p)
                    .iter()
                    .all(|&b| b >= -TOLERANCE)
            })
            .collect();
        let nearest = (0..mesh.tet_count())
            .map(|t| distance_to_tet(mesh.tet_positions(t), p))
            .fold(f64::INFINITY, f64::min);
        let found = locator.locate_or_nearest(p).unwrap();
        let rebuilt: DVec3 = (0..4)
            .map(|k| mesh.positions[mesh.tets[found.tet][k] as usize] * found.barycentric[k])
            .sum();
        assert!(
            rebuilt.distance(p) < 1e-9,
            "barycentric coordinates reproduce the point"
        );
        if containing.is_empty() {
            outside += 1;
            assert!(locator.locate(p).is_none());
            assert!(
                (found.distance_mm - nearest).abs() < 1e-9,
                "{} vs {nearest}",
                found.distance_mm
            );
        } else {
            inside += 1;
            let located = locator
                .locate(p)
                .expect("a point inside the mesh is located");
            assert!(containing.contains(&located.tet));
            assert_eq!(located.distance_mm, 0.0);
            assert!(located.barycentric.iter().all(|&b| b >= -TOLERANCE));
        }
    }
    eprintln!("{inside} points inside, {outside} outside");
    assert!(inside > 200 && outside > 200);
}

#[test]
fn lattice_vertices_and_far_points_are_handled() {
    let surface = ClosedSurface::new(&mesh::shapes::icosphere(20.0, 3)).unwrap();
    let mesh = stuff(&surface, 5.0).unwrap();
    let locator = TetLocator::new(&mesh);
    // Every vertex lies in (on the boundary of) some tetrahedron.
    for &p in &mesh.positions {
        let found = locator.locate(p).expect("a mesh vertex is located");
        assert!(found.barycentric.iter().any(|&b| (b - 1.0).abs() < 1e-9));
    }
    // A point far away gets the nearest element.
    let far = DVec3::new(500.0, 3.0, -2.0);
    let found = locator.locate_or_nearest(far).unwrap();
    let nearest = (0..mesh.tet_count())
        .map(|t| distance_to_tet(mesh.tet_positions(t), far))
        .fold(f64::INFINITY, f64::min);
    assert!((found.distance_mm - nearest).abs() < 1e-9);
}
