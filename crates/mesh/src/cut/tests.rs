use super::*;
use crate::shapes::{cylinder, grid, icosphere};
use crate::surface_curve::tests::{circle, project};
use std::f64::consts::{PI, TAU};

/// Signed volume (mm³) of the cones from the origin over the triangles: additive over
/// parts, and the enclosed volume for a closed mesh.
fn cone_volume(mesh: &TriMesh) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| {
            let [a, b, c] = mesh.triangle_positions(t);
            a.dot(b.cross(c)) / 6.0
        })
        .sum()
}

/// Whether `a` is `b` rotated.
fn same_cycle(a: &[u32], b: &[u32]) -> bool {
    a.len() == b.len()
        && (0..b.len()).any(|shift| (0..a.len()).all(|i| a[i] == b[(i + shift) % b.len()]))
}

/// Cuts and checks what every cut must give: the parts are manifold, consistently
/// oriented and free of degenerate triangles, together they have the input's area,
/// and each inside part is bounded by its curve's loop, in the curve's direction,
/// whose vertices the outside part shares. Returns the cut and the parts, inside ones first.
fn checked_cut(
    mesh: &TriMesh,
    topology: &Topology,
    curves: &[SurfaceCurve],
) -> Result<(CutMesh, Vec<MeshPart>), CutError> {
    let cut = cut_along_curves(mesh, topology, curves)?;
    let regions = (0..curves.len())
        .map(Region::Inside)
        .chain([Region::Outside]);
    let parts: Vec<MeshPart> = regions.map(|r| cut.part(r)).collect();
    for (index, part) in parts.iter().enumerate() {
        let part_mesh = &part.mesh;
        part_mesh.validate().unwrap();
        let part_topology = Topology::new(part_mesh);
        assert_eq!(part_topology.non_manifold_edge_count, 0);
        assert_eq!(part_topology.inconsistent_edge_count, 0);
        // No triangle below 1e-14 of a unit triangle's area (COLLINEAR_TOLERANCE).
        assert!(part_mesh.degenerate_triangles(1e-14).is_empty());
        if let Some(boundary) = cut.loops.get(index) {
            let loops = part_topology.boundary_loops(part_mesh);
            let in_cut = |l: &Vec<u32>| -> Vec<u32> {
                l.iter().map(|&v| part.vertex_map[v as usize]).collect()
            };
            assert!(loops.iter().any(|l| same_cycle(&in_cut(l), boundary)));
            assert!(
                boundary
                    .iter()
                    .all(|v| parts[curves.len()].vertex_map.contains(v))
            );
        }
    }
    let area: f64 = parts.iter().map(|p| p.mesh.area()).sum();
    assert!((area - mesh.area()).abs() <= 1e-9 * mesh.area());
    Ok((cut, parts))
}

/// Shoelace area (mm²) of a loop of vertices in the xy plane.
fn polygon_area(mesh: &TriMesh, vertices: &[u32]) -> f64 {
    let n = vertices.len();
    (0..n)
        .map(|i| {
            let p = mesh.positions[vertices[i] as usize];
            let q = mesh.positions[vertices[(i + 1) % n] as usize];
            0.5 * (p.x * q.y - q.x * p.y)
        })
        .sum()
}

/// A 20 mm grid with colours and texture coordinates that are linear in position.
fn textured_grid() -> TriMesh {
    let mut mesh = grid(20, 20, 1.0);
    mesh.vertex_colors = Some(
        mesh.positions
            .iter()
            .map(|p| [(10.0 * p.x) as u8, (10.0 * p.y) as u8, 7])
            .collect(),
    );
    mesh.uv = Some(UvLayer {
        coords: mesh.positions.iter().map(|p| p.truncate() / 20.0).collect(),
        triangles: mesh.triangles.clone(),
    });
    mesh
}

/// A small deterministic random number generator (xorshift64), uniform in [lo, hi).
struct Random(u64);

impl Random {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        lo + (hi - lo) * (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn cutting_a_grid_along_a_circle() {
    let mesh = textured_grid();
    let topology = Topology::new(&mesh);
    let samples = circle(DVec3::new(10.3, 9.7, 0.0), 6.0, [DVec3::X, DVec3::Y], 200);
    let curve = project(&mesh, &topology, &samples).unwrap();
    let (cut, parts) = checked_cut(&mesh, &topology, std::slice::from_ref(&curve)).unwrap();
    let boundary = &cut.loops[0];
    assert_eq!(boundary.len(), curve.points.len());
    for (&v, point) in boundary.iter().zip(&curve.points) {
        assert!(cut.mesh.positions[v as usize].distance(point.position) < 1e-12);
    }
    // The cut polygon is the curve polyline, so the inside area is exact.
    let polygon = polygon_area(&cut.mesh, boundary);
    assert!((parts[0].mesh.area() - polygon).abs() < 1e-9);
    assert!((parts[1].mesh.area() - (400.0 - polygon)).abs() < 1e-9);
    assert!((polygon - PI * 36.0).abs() < 0.02);
    let outside = &parts[1].mesh;
    assert_eq!(Topology::new(outside).boundary_loops(outside).len(), 2);

    // Attributes follow the geometry: both are linear in position on this grid.
    for part in [&parts[0].mesh, outside] {
        let uv = part.uv.as_ref().unwrap();
        for (tri, uv_tri) in part.triangles.iter().zip(&uv.triangles) {
            for k in 0..3 {
                let expected = part.positions[tri[k] as usize].truncate() / 20.0;
                assert!(uv.coords[uv_tri[k] as usize].distance(expected) < 1e-12);
            }
        }
        let colors = part.vertex_colors.as_ref().unwrap();
        for (p, c) in part.positions.iter().zip(colors) {
            assert!((f64::from(c[0]) - 10.0 * p.x).abs() <= 1.0, "{p} {c:?}");
            assert!((f64::from(c[1]) - 10.0 * p.y).abs() <= 1.0, "{p} {c:?}");
        }
    }
}

#[test]
fn cut_along_grid_edges_keeps_the_triangles() {
    let mesh = grid(10, 10, 1.0);
    let topology = Topology::new(&mesh);
    // Counter-clockwise square (2,2)-(7,7) along grid lines, through vertices only.
    let corners = [[2.0, 2.0], [7.0, 2.0], [7.0, 7.0], [2.0, 7.0]];
    let samples: Vec<DVec3> = (0..4)
        .flat_map(|i| {
            let [a, b] = [corners[i], corners[(i + 1) % 4]].map(|[x, y]| DVec3::new(x, y, 0.0));
            (0..5).map(move |k| a.lerp(b, k as f64 / 5.0))
        })
        .collect();
    let curve = project(&mesh, &topology, &samples).unwrap();
    let (cut, parts) = checked_cut(&mesh, &topology, &[curve]).unwrap();
    assert_eq!(cut.mesh, mesh);
    assert_eq!(parts[0].mesh.triangle_count(), 50);
    assert!((parts[0].mesh.area() - 25.0).abs() < 1e-12);
}

#[test]
fn cut_through_vertices_and_across_edges() {
    let mesh = grid(10, 10, 1.0);
    let topology = Topology::new(&mesh);
    // Sides through the vertices (4,3), (5,6) and (3,5), crossing edges in between.
    let corners = [[2.0, 2.0], [6.0, 4.0], [4.0, 8.0]].map(|[x, y]| DVec3::new(x, y, 0.0));
    let samples: Vec<DVec3> = (0..3)
        .flat_map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % 3]);
            (0..13).map(move |k| a.lerp(b, k as f64 / 13.0))
        })
        .collect();
    let curve = project(&mesh, &topology, &samples).unwrap();
    let (_, parts) = checked_cut(&mesh, &topology, &[curve]).unwrap();
    assert!((parts[0].mesh.area() - 10.0).abs() < 1e-9);
}

#[test]
fn clockwise_curve_encloses_the_outside() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let samples = circle(DVec3::new(10.0, 10.0, 0.0), 5.0, [DVec3::Y, DVec3::X], 150);
    let clockwise = project(&mesh, &topology, &samples).unwrap();
    let (cut, parts) = checked_cut(&mesh, &topology, std::slice::from_ref(&clockwise)).unwrap();
    let polygon = -polygon_area(&cut.mesh, &cut.loops[0]);
    assert!((parts[0].mesh.area() - (400.0 - polygon)).abs() < 1e-9);

    let oriented = clockwise.oriented_counter_clockwise_about(DVec3::Z);
    let (_, parts) = checked_cut(&mesh, &topology, &[oriented]).unwrap();
    assert!((parts[0].mesh.area() - polygon).abs() < 1e-9);
}

#[test]
fn ring_around_a_cylinder_cuts_off_the_top() {
    let (radius, height, segments) = (10.0, 30.0, 48);
    let mesh = cylinder(radius, height, segments, 6);
    let topology = Topology::new(&mesh);
    // Counter-clockwise about +z with outward normals: the inside is above the ring.
    let level = 12.3;
    let samples = circle(
        DVec3::new(0.0, 0.0, level),
        radius,
        [DVec3::X, DVec3::Y],
        500,
    );
    let curve = project(&mesh, &topology, &samples).unwrap();
    assert!(
        curve
            .points
            .iter()
            .all(|p| (p.position.z - level).abs() < 1e-9)
    );
    let (_, parts) = checked_cut(&mesh, &topology, &[curve]).unwrap();
    // The side faces are rectangles: the area above is the polygon's perimeter times
    // the height above the ring.
    let perimeter = segments as f64 * 2.0 * radius * (PI / segments as f64).sin();
    assert!((parts[0].mesh.area() - perimeter * (height - level)).abs() < 1e-9);
    assert!(parts[0].mesh.positions.iter().all(|p| p.z >= level - 1e-9));
}

#[test]
fn two_circles_cut_a_sphere_into_three_parts() {
    let radius = 50.0;
    let mesh = icosphere(radius, 4);
    let topology = Topology::new(&mesh);
    // Circles 40° about the +x and -x axes, each counter-clockwise seen from outside.
    let angle = 40f64.to_radians();
    let curves: Vec<SurfaceCurve> = [DVec3::X, -DVec3::X]
        .into_iter()
        .map(|axis| {
            let center = axis * radius * angle.cos();
            let samples = circle(center, radius * angle.sin(), [DVec3::Y, DVec3::Z], 300);
            project(&mesh, &topology, &samples)
                .unwrap()
                .oriented_counter_clockwise_about(axis)
        })
        .collect();
    let (cut, parts) = checked_cut(&mesh, &topology, &curves).unwrap();
    let volume = mesh.signed_volume();
    assert!((cone_volume(&cut.mesh) - volume).abs() < 1e-9 * volume);
    let part_volumes: f64 = parts.iter().map(|p| cone_volume(&p.mesh)).sum();
    assert!((part_volumes - volume).abs() < 1e-9 * volume);
    // The caps are about the size of a spherical cap and lie beyond their circles.
    let cap = TAU * radius * radius * (1.0 - angle.cos());
    for part in &parts[..2] {
        assert!((part.mesh.area() - cap).abs() < 0.01 * cap);
        let beyond = radius * angle.cos() - 1.0;
        assert!(part.mesh.positions.iter().all(|p| p.x.abs() >= beyond));
    }
    let base = &parts[2].mesh;
    assert_eq!(Topology::new(base).boundary_loops(base).len(), 2);
}

#[test]
fn random_circles_on_a_noisy_sphere_cut_cleanly() {
    let mut random = Random(0x9e37_79b9_7f4a_7c15);
    let radius = 60.0;
    let mut mesh = icosphere(radius, 4);
    for p in &mut mesh.positions {
        *p *= 1.0 + random.uniform(-0.004, 0.004); // ±0.24 mm of scanner noise
    }
    let topology = Topology::new(&mesh);
    for _ in 0..40 {
        let axis = DVec3::new(
            random.uniform(-1.0, 1.0),
            random.uniform(-1.0, 1.0),
            random.uniform(-1.0, 1.0),
        )
        .normalize();
        let u = axis.any_orthonormal_vector();
        let angle = random.uniform(0.1, 1.2);
        let count = random.uniform(8.0, 1500.0) as usize;
        let center = axis * radius * angle.cos();
        let samples = circle(center, radius * angle.sin(), [u, axis.cross(u)], count);
        let curve = project(&mesh, &topology, &samples).unwrap();
        checked_cut(&mesh, &topology, &[curve]).unwrap();
    }
}

#[test]
fn circles_through_and_near_vertices_cut_cleanly() {
    let mesh = grid(30, 30, 1.0);
    let topology = Topology::new(&mesh);
    // Offsets from below to above the snap tolerance; 4..24-gons hit vertices exactly.
    for offset in [0.0, 1e-12, 1e-9, 1e-7, 1e-6, 2e-6, 1e-5] {
        for radius in [3.0, 5.0, 5.0 + offset] {
            for count in [4, 8, 12, 16, 24, 100] {
                let center = DVec3::new(15.0 + offset, 15.0, 0.0);
                let samples = circle(center, radius, [DVec3::X, DVec3::Y], count);
                let curve = project(&mesh, &topology, &samples).unwrap();
                checked_cut(&mesh, &topology, &[curve]).unwrap();
            }
        }
    }
}

#[test]
fn open_curve_is_an_error() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let samples = circle(DVec3::new(10.0, 10.0, 0.0), 5.0, [DVec3::X, DVec3::Y], 100);
    let mut curve = project(&mesh, &topology, &samples).unwrap();
    curve.points.truncate(curve.points.len() / 2);
    let error = cut_along_curves(&mesh, &topology, &[curve]).unwrap_err();
    assert!(
        matches!(
            error,
            CutError::Curve {
                curve: 0,
                source: CurveError::NotClosed { .. }
            }
        ),
        "{error}"
    );
    assert!(error.to_string().contains("not closed"));
    let no_curves = cut_along_curves(&mesh, &topology, &[]);
    assert_eq!(no_curves.unwrap_err(), CutError::NoCurves);
}

#[test]
fn nested_or_touching_curves_are_errors() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let ring = |radius: f64, x: f64, y: f64| {
        let samples = circle(DVec3::new(x, y, 0.0), radius, [DVec3::X, DVec3::Y], 120);
        project(&mesh, &topology, &samples).unwrap()
    };
    let nested = cut_along_curves(
        &mesh,
        &topology,
        &[ring(6.0, 10.0, 10.0), ring(3.0, 10.0, 10.0)],
    );
    assert!(matches!(nested, Err(CutError::LabelConflict { .. })));
    let crossing = cut_along_curves(
        &mesh,
        &topology,
        &[ring(4.0, 7.0, 10.0), ring(4.0, 12.0, 10.0)],
    );
    assert!(matches!(
        crossing,
        Err(CutError::CurvesTouch {
            first: 0,
            second: 1,
            ..
        })
    ));
    let tiny = cut_along_curves(&mesh, &topology, &[ring(0.1, 10.3, 10.5)]);
    assert!(matches!(tiny, Err(CutError::CurveInsideTriangle { .. })));
}

/// Run with `cargo test -p mesh --release -- --ignored --nocapture timing`.
#[test]
#[ignore = "timing; run in release"]
fn timing_of_a_cut_of_a_160k_vertex_mesh() {
    let radius = 100.0;
    let mesh = icosphere(radius, 7);
    let topology = Topology::new(&mesh);
    let curves: Vec<SurfaceCurve> = [DVec3::X, -DVec3::X]
        .into_iter()
        .map(|axis| {
            let center = axis * 0.7 * radius;
            let circle_radius = 0.7 * radius;
            let samples = circle(center, circle_radius, [DVec3::Y, DVec3::Z], 2000);
            project(&mesh, &topology, &samples)
                .unwrap()
                .oriented_counter_clockwise_about(axis)
        })
        .collect();
    let start = std::time::Instant::now();
    let cut = cut_along_curves(&mesh, &topology, &curves).unwrap();
    let cut_time = start.elapsed();
    let start = std::time::Instant::now();
    let base = cut.part(Region::Outside);
    println!(
        "{} vertices, curves of {} and {} points: cut {cut_time:?}, base part {:?} ({} triangles)",
        mesh.vertex_count(),
        curves[0].points.len(),
        curves[1].points.len(),
        start.elapsed(),
        base.mesh.triangle_count()
    );
}
