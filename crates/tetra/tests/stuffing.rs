//! Isosurface stuffing against analytic shapes: volume convergence, element quality,
//! boundary accuracy, interior regularity, and refusal of bad input surfaces.

mod common;

use glam::{DMat3, DVec3, EulerRot};
use mesh::{SurfaceIndex, TriMesh};
use std::f64::consts::PI;
use tetra::{ClosedSurface, TetMesh, TetraError, stuff};

/// The paper's lower bound on dihedral angles for these warping parameters (degrees).
const PAPER_MIN_DIHEDRAL_DEG: f64 = 10.7;
/// The paper's upper bound (degrees).
const PAPER_MAX_DIHEDRAL_DEG: f64 = 164.8;

fn surface(mesh: &TriMesh) -> ClosedSurface {
    ClosedSurface::new(mesh).expect("a valid closed surface")
}

/// Relative volume errors of the meshes at `spacings` against the input polyhedron's
/// volume (what the mesher sees), printed with the error against the analytic `exact`.
fn volume_errors(shape: &str, surface: &ClosedSurface, exact: f64, spacings: &[f64]) -> Vec<f64> {
    eprintln!(
        "{shape}: input polyhedron {:+.4} % from the analytic volume",
        100.0 * (surface.volume_mm3() - exact) / exact
    );
    spacings
        .iter()
        .map(|&h| {
            let mesh = stuff(surface, h).unwrap();
            let volume = mesh.volume_mm3();
            eprintln!(
                "{shape}: spacing {h:5.2} mm, {:7} tets, volume error {:+.4} % (analytic), {:+.4} % (input)",
                mesh.tet_count(),
                100.0 * (volume - exact) / exact,
                100.0 * (volume - surface.volume_mm3()) / surface.volume_mm3(),
            );
            (volume - surface.volume_mm3()) / surface.volume_mm3()
        })
        .collect()
}

/// Boundary facets are chords of the surface: second-order convergence, each halving of
/// the spacing cutting the error by about 4 (at least 3 asserted).
fn assert_second_order(errors: &[f64]) {
    for pair in errors.windows(2) {
        assert!(pair[1].abs() * 3.0 < pair[0].abs(), "{errors:?}");
    }
}

#[test]
fn sphere_volume_converges_to_the_analytic_volume() {
    // 81,920 triangles: the polyhedron's own volume deficit is about 1.4e-4.
    let radius = 50.0;
    let sphere = surface(&mesh::shapes::icosphere(radius, 6));
    let exact = 4.0 / 3.0 * PI * radius.powi(3);
    let errors = volume_errors("sphere", &sphere, exact, &[16.0, 8.0, 4.0, 2.0]);
    assert_second_order(&errors);
    assert!(errors[3].abs() < 1e-3, "{errors:?}");
    assert!((sphere.volume_mm3() - exact).abs() < 2e-4 * exact);
}

#[test]
fn torus_volume_converges_to_the_analytic_volume() {
    let (major, minor) = (40.0, 15.0);
    let torus = surface(&mesh::shapes::torus(major, minor, 384, 144));
    let exact = 2.0 * PI * PI * major * minor * minor;
    let errors = volume_errors("torus", &torus, exact, &[8.0, 4.0, 2.0, 1.0]);
    assert_second_order(&errors);
    assert!(errors[3].abs() < 1e-3, "{errors:?}");
    assert!((torus.volume_mm3() - exact).abs() < 5e-4 * exact);
}

fn rotated(mesh: &TriMesh, k: usize) -> TriMesh {
    let a = k as f64 * 0.7;
    let rotation = DMat3::from_euler(EulerRot::XYZ, a, 1.3 * a, 0.4 * a);
    let mut out = mesh.clone();
    out.map_positions(|p| rotation * p);
    out
}

#[test]
fn dihedral_angles_stay_within_the_paper_bounds_on_rotated_shapes() {
    let shapes = [
        ("sphere", mesh::shapes::icosphere(50.0, 3)),
        ("torus", mesh::shapes::torus(40.0, 15.0, 96, 32)),
        ("cube", mesh::shapes::cube(37.0)),
        (
            "flat ellipsoid",
            common::ellipsoid(DVec3::new(30.0, 20.0, 6.0), 48, 24),
        ),
        ("thin torus", mesh::shapes::torus(30.0, 4.0, 96, 16)),
    ];
    let (mut lowest, mut highest) = (180.0f64, 0.0f64);
    for (name, shape) in &shapes {
        for k in 0..30 {
            let surface = surface(&rotated(shape, k));
            for h in [13.0 + 0.1 * k as f64, 6.1 + 0.03 * k as f64, 3.3] {
                let Ok(mesh) = stuff(&surface, h) else {
                    continue;
                };
                mesh.validate()
                    .unwrap_or_else(|e| panic!("{name} k {k} h {h}: {e}"));
                let quality = mesh.quality();
                lowest = lowest.min(quality.min_dihedral_deg);
                highest = highest.max(quality.max_dihedral_deg);
            }
        }
    }
    eprintln!("dihedral angles over all meshes: {lowest:.2}° to {highest:.2}°");
    assert!(lowest >= PAPER_MIN_DIHEDRAL_DEG, "{lowest}");
    assert!(highest <= PAPER_MAX_DIHEDRAL_DEG, "{highest}");
}

/// Points spread over every triangle of `mesh`: corners, edge midpoints, centroid.
fn samples(mesh: &TriMesh) -> Vec<DVec3> {
    (0..mesh.triangle_count())
        .flat_map(|t| {
            let [a, b, c] = mesh.triangle_positions(t);
            [
                a,
                (a + b) / 2.0,
                (b + c) / 2.0,
                (c + a) / 2.0,
                (a + b + c) / 3.0,
            ]
        })
        .collect()
}

fn one_sided_distance(from: &TriMesh, to: &TriMesh) -> f64 {
    let index = SurfaceIndex::new(to).unwrap();
    samples(from)
        .iter()
        .map(|&p| index.closest_point(p).distance)
        .fold(0.0, f64::max)
}

#[test]
fn boundary_is_a_closed_surface_within_half_a_spacing_of_the_input() {
    let input = common::ellipsoid(DVec3::new(125.0, 100.0, 50.0), 200, 100);
    let surface = surface(&input);
    for h in [8.0, 4.0] {
        let mesh = stuff(&surface, h).unwrap();
        let boundary = mesh.boundary().mesh;
        let report = mesh::manifold_report(&boundary, &mesh::Topology::new(&boundary));
        assert!(report.is_watertight_manifold(), "{report}");
        let outward = one_sided_distance(&boundary, &input);
        let inward = one_sided_distance(&input, &boundary);
        eprintln!(
            "ellipsoid spacing {h} mm: boundary to input {outward:.3} mm, input to boundary {inward:.3} mm (Hausdorff {:.3} mm, {:.3} of the spacing)",
            outward.max(inward),
            outward.max(inward) / h
        );
        assert!(outward.max(inward) <= 0.5 * h);
    }
}

/// Whether every dihedral angle of tetrahedron `t` is 60° or 90°, as in the BCC lattice.
fn is_lattice_tet(mesh: &TetMesh, t: usize) -> bool {
    tetra::quality::dihedral_angles(mesh.tet_positions(t))
        .iter()
        .all(|a| (a.to_degrees() - 60.0).abs() < 1e-9 || (a.to_degrees() - 90.0).abs() < 1e-9)
}

#[test]
fn interior_is_the_regular_lattice() {
    let input = mesh::shapes::icosphere(50.0, 4);
    let index = SurfaceIndex::new(&input).unwrap();
    let h = 5.0;
    let mesh = stuff(&surface(&input), h).unwrap();
    let mut interior = 0;
    for t in 0..mesh.tet_count() {
        let deep = mesh
            .tet_positions(t)
            .iter()
            .all(|&p| index.closest_point(p).distance > h);
        if deep {
            interior += 1;
            assert!(is_lattice_tet(&mesh, t), "tet {t}");
        }
    }
    assert!(interior > mesh.tet_count() / 3, "{interior}");
}

#[test]
fn stuffing_is_deterministic() {
    let surface = surface(&mesh::shapes::torus(40.0, 15.0, 96, 32));
    let first = stuff(&surface, 3.0).unwrap();
    for _ in 0..3 {
        assert_eq!(stuff(&surface, 3.0).unwrap(), first);
    }
}

#[test]
fn bad_input_surfaces_are_refused_with_a_reason() {
    let open = mesh::shapes::cylinder(10.0, 20.0, 32, 4);
    let message = ClosedSurface::new(&open).err().unwrap().to_string();
    assert!(
        message.contains("not a closed") && message.contains("64 boundary edges"),
        "{message}"
    );

    let mut two = mesh::shapes::icosphere(10.0, 2);
    let mut other = mesh::shapes::icosphere(10.0, 2);
    other.map_positions(|p| p + DVec3::new(5.0, 0.0, 0.0));
    let offset = two.positions.len() as u32;
    two.positions.extend(other.positions);
    two.triangles
        .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
    match ClosedSurface::new(&two) {
        Err(TetraError::SelfIntersecting { pairs, .. }) => assert!(pairs > 0),
        other => panic!("expected a self-intersection error, got {:?}", other.err()),
    }

    let mut inward = mesh::shapes::icosphere(10.0, 2);
    for t in &mut inward.triangles {
        t.swap(1, 2);
    }
    let message = ClosedSurface::new(&inward).err().unwrap().to_string();
    assert!(message.contains("oriented inward"), "{message}");

    let empty = TriMesh::default();
    assert!(matches!(
        ClosedSurface::new(&empty),
        Err(TetraError::InvalidSurface(_))
    ));

    let sphere = surface(&mesh::shapes::icosphere(10.0, 2));
    for spacing in [0.0, -1.0, f64::NAN] {
        assert!(matches!(
            stuff(&sphere, spacing),
            Err(TetraError::InvalidSpacing { .. })
        ));
    }
    assert!(matches!(
        stuff(&sphere, 1e-3),
        Err(TetraError::LatticeTooLarge { .. })
    ));
    assert!(matches!(
        stuff(&sphere, 100.0),
        Err(TetraError::NoTetrahedra { .. })
    ));
}
