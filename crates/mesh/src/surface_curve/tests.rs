use super::*;
use crate::shapes::{grid, icosphere};
use crate::spatial::SurfaceIndex;
use std::f64::consts::{PI, TAU};

/// `count` points of the circle of `radius` about `center` in the plane spanned by the
/// unit vectors `u` and `v`, counter-clockwise seen from the tip of `u × v`.
pub(crate) fn circle(center: DVec3, radius: f64, [u, v]: [DVec3; 2], count: usize) -> Vec<DVec3> {
    (0..count)
        .map(|i| {
            let angle = TAU * i as f64 / count as f64;
            center + radius * (angle.cos() * u + angle.sin() * v)
        })
        .collect()
}

/// Projects `samples` as a caller would: the first sample moved onto the surface.
pub(crate) fn project(
    mesh: &TriMesh,
    topology: &Topology,
    samples: &[DVec3],
) -> Result<SurfaceCurve, CurveError> {
    let start = SurfaceIndex::new(mesh).unwrap().closest_point(samples[0]);
    let mut samples = samples.to_vec();
    samples[0] = start.point;
    SurfaceCurve::project(mesh, topology, start.triangle, &samples)
}

fn distance_to_polygon(p: DVec3, polygon: &[DVec3]) -> f64 {
    (0..polygon.len())
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % polygon.len()]);
            let s = ((p - a).dot(b - a) / a.distance_squared(b)).clamp(0.0, 1.0);
            p.distance(a + s * (b - a))
        })
        .fold(f64::INFINITY, f64::min)
}

/// Checks the invariants of a projected curve: positions match locations, and the
/// curve passes every check.
fn assert_consistent(mesh: &TriMesh, topology: &Topology, curve: &SurfaceCurve) {
    for point in &curve.points {
        assert!(point.position.distance(point.location.position(mesh)) < 1e-12);
    }
    curve.check(mesh, topology).unwrap();
}

#[test]
fn circle_on_a_grid_is_the_sample_polygon() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let (radius, count) = (6.0, 720);
    let samples = circle(
        DVec3::new(10.3, 9.7, 0.0),
        radius,
        [DVec3::X, DVec3::Y],
        count,
    );
    let curve = project(&mesh, &topology, &samples).unwrap();
    assert_consistent(&mesh, &topology, &curve);

    // Every sample is a curve point, in order, and every edge crossing is on a chord.
    let mut next_sample = 0;
    for point in &curve.points {
        if next_sample < count && point.position.distance(samples[next_sample]) < 1e-12 {
            next_sample += 1;
        }
        assert!(distance_to_polygon(point.position, &samples) < 1e-12);
    }
    assert_eq!(next_sample, count);
    assert!(curve.points.len() > count + 40, "{}", curve.points.len());

    // So the length is the polygon's perimeter, which is below 2 pi r by the chord
    // error 2 pi r (1 - sin(pi/N) / (pi/N)) <= 2 pi r pi^2 / (6 N^2) (3.2e-6 relative).
    let perimeter: f64 = (0..count)
        .map(|i| samples[i].distance(samples[(i + 1) % count]))
        .sum();
    assert!((curve.length_mm() - perimeter).abs() < 1e-9);
    let exact = TAU * radius;
    let chord_error = exact * PI * PI / (6.0 * (count * count) as f64);
    assert!(exact - curve.length_mm() >= 0.0);
    assert!(exact - curve.length_mm() <= chord_error);
    assert!((curve.signed_area_about(DVec3::Z) - PI * radius * radius).abs() < 2e-3);
}

#[test]
fn latitude_circle_on_a_sphere_stays_within_the_discretisation_error() {
    let radius = 50.0;
    let mesh = icosphere(radius, 4);
    let topology = Topology::new(&mesh);
    // The inscribed polyhedron lies between the smallest face-plane distance and R.
    let depth = (0..mesh.triangle_count())
        .map(|t| {
            let [a, ..] = mesh.triangle_positions(t);
            radius - a.dot(mesh.triangle_normal(t))
        })
        .fold(0.0, f64::max);
    let polar = 60f64.to_radians();
    let (height, circle_radius) = (radius * polar.cos(), radius * polar.sin());
    let samples = circle(
        DVec3::new(0.0, 0.0, height),
        circle_radius,
        [DVec3::X, DVec3::Y],
        1000,
    );
    let curve = project(&mesh, &topology, &samples).unwrap();
    assert_consistent(&mesh, &topology, &curve);
    let worst = curve
        .points
        .iter()
        .map(|p| {
            let q = p.position;
            DVec2::new(q.x.hypot(q.y) - circle_radius, q.z - height).length()
        })
        .fold(0.0, f64::max);
    assert!(
        worst <= depth,
        "{worst} mm off the circle, depth {depth} mm"
    );
    let exact = TAU * circle_radius;
    // The polyline runs slightly inside the sphere (0.07 % short here).
    assert!((curve.length_mm() - exact).abs() < 2e-3 * exact);
}

#[test]
fn curves_along_grid_edges_and_through_vertices_are_followed_exactly() {
    let mesh = grid(10, 10, 1.0);
    let topology = Topology::new(&mesh);
    let polyline = |corners: &[[f64; 2]], step: f64| -> Vec<DVec3> {
        let mut samples = Vec::new();
        for (i, a) in corners.iter().enumerate() {
            let b = corners[(i + 1) % corners.len()];
            let (a, b) = (DVec3::new(a[0], a[1], 0.0), DVec3::new(b[0], b[1], 0.0));
            let steps = (a.distance(b) / step).round() as usize;
            samples.extend((0..steps).map(|k| a.lerp(b, k as f64 / steps as f64)));
        }
        samples
    };

    // A square along grid lines: only vertices and edge midpoints.
    let corners = [[2.0, 2.0], [7.0, 2.0], [7.0, 7.0], [2.0, 7.0]];
    let square = project(&mesh, &topology, &polyline(&corners, 0.5)).unwrap();
    assert_consistent(&mesh, &topology, &square);
    assert_eq!(square.points.len(), 40);
    assert!(square.points.iter().all(|p| match p.location {
        CurveLocation::OnVertex(_) => true,
        CurveLocation::OnEdge { t, .. } => (t - 0.5).abs() < 1e-12,
        CurveLocation::InTriangle { .. } => false,
    }));
    assert!((square.length_mm() - 20.0).abs() < 1e-12);

    // Along the diagonal edges, then back along grid lines.
    let corners = [[2.0, 2.0], [8.0, 8.0], [2.0, 8.0]];
    let wedge = project(&mesh, &topology, &polyline(&corners, 0.7)).unwrap();
    assert_consistent(&mesh, &topology, &wedge);
    let vertices = wedge
        .points
        .iter()
        .filter(|p| matches!(p.location, CurveLocation::OnVertex(_)))
        .count();
    assert_eq!(vertices, 18);
    assert!(
        wedge
            .points
            .iter()
            .all(|p| !matches!(p.location, CurveLocation::InTriangle { .. }))
    );
    assert!((wedge.length_mm() - (12.0 + 6.0 * 2f64.sqrt())).abs() < 1e-12);

    // Oblique sides through vertices (4,3), (5,6) and (3,5), crossing edges between.
    let corners = [[2.0, 2.0], [6.0, 4.0], [4.0, 8.0]];
    let samples = polyline(&corners, 0.3);
    let oblique = project(&mesh, &topology, &samples).unwrap();
    assert_consistent(&mesh, &topology, &oblique);
    let on_vertex = |x: f64, y: f64| {
        let v = (y as u32) * 11 + x as u32;
        oblique
            .points
            .iter()
            .any(|p| p.location == CurveLocation::OnVertex(v))
    };
    assert!(on_vertex(4.0, 3.0) && on_vertex(5.0, 6.0) && on_vertex(3.0, 5.0));
    let triangle: Vec<DVec3> = corners
        .iter()
        .map(|c| DVec3::new(c[0], c[1], 0.0))
        .collect();
    assert!(
        oblique
            .points
            .iter()
            .all(|p| distance_to_polygon(p.position, &triangle) < 1e-12)
    );
    let perimeter = 20f64.sqrt() + 20f64.sqrt() + 40f64.sqrt();
    assert!((oblique.length_mm() - perimeter).abs() < 1e-9);
}

#[test]
fn curve_leaving_the_grid_is_an_error() {
    let mesh = grid(10, 10, 1.0);
    let topology = Topology::new(&mesh);
    let samples = circle(DVec3::new(3.0, 5.0, 0.0), 4.0, [DVec3::X, DVec3::Y], 200);
    let error = project(&mesh, &topology, &samples).unwrap_err();
    let CurveError::LeavesMesh { position } = error else {
        panic!("{error}");
    };
    assert!(position[0].abs() < 1e-9, "{position:?}");
    assert!(error.to_string().contains("leaves the scan at its border"));

    // A hole: the two triangles of the square (5, 5)-(6, 6) are missing.
    let mut holed = grid(10, 10, 1.0);
    holed.remove_triangles(&[110, 111]);
    let topology = Topology::new(&holed);
    let samples = circle(DVec3::new(5.5, 3.0, 0.0), 2.5, [DVec3::X, DVec3::Y], 200);
    let error = project(&holed, &topology, &samples).unwrap_err();
    let CurveError::LeavesMesh { position } = error else {
        panic!("{error}");
    };
    // On the hole's rim, where the circle (up to y = 5.5) first reaches it.
    let on_rim = |x: f64| (5.0..=6.0).contains(&x);
    assert!(on_rim(position[0]) && on_rim(position[1]), "{position:?}");
}

#[test]
fn degenerate_triangle_on_the_way_is_an_error() {
    let mut mesh = grid(10, 10, 1.0);
    // Vertex (5, 4) onto the diagonal (4, 4)-(5, 5): triangle [(4,4), (5,4), (5,5)] has
    // no area.
    mesh.positions[4 * 11 + 5] = DVec3::new(4.5, 4.5, 0.0);
    let degenerate = 2 * (4 * 10 + 4);
    assert_eq!(mesh.degenerate_triangles(1e-12), vec![degenerate]);
    let topology = Topology::new(&mesh);
    let samples = circle(DVec3::new(4.3, 6.0, 0.0), 1.8, [DVec3::X, DVec3::Y], 100);
    let error = project(&mesh, &topology, &samples).unwrap_err();
    assert!(
        matches!(error, CurveError::DegenerateTriangle { triangle, .. } if triangle == degenerate),
        "{error}"
    );
}

#[test]
fn self_crossing_curve_is_an_error() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    // A figure eight (lemniscate of Gerono) about (10, 10).
    let samples: Vec<DVec3> = (0..400)
        .map(|i| {
            let angle = TAU * i as f64 / 400.0;
            DVec3::new(
                10.0 + 6.0 * angle.cos(),
                10.0 + 6.0 * angle.sin() * angle.cos(),
                0.0,
            )
        })
        .collect();
    let error = project(&mesh, &topology, &samples).unwrap_err();
    let CurveError::SelfCrossing { position } = error else {
        panic!("{error}");
    };
    assert!(DVec3::from_array(position).distance(DVec3::new(10.0, 10.0, 0.0)) < 1.5);
}

#[test]
fn orientation_follows_the_outward_direction() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let mut samples = circle(DVec3::new(10.0, 10.0, 0.0), 5.0, [DVec3::X, DVec3::Y], 100);
    samples.reverse();
    let clockwise = project(&mesh, &topology, &samples).unwrap();
    assert!(clockwise.signed_area_about(DVec3::Z) < 0.0);
    let oriented = clockwise.clone().oriented_counter_clockwise_about(DVec3::Z);
    assert!(oriented.signed_area_about(DVec3::Z) > 0.0);
    assert_eq!(oriented, clockwise.reversed());
    assert_eq!(
        oriented.clone().oriented_counter_clockwise_about(DVec3::Z),
        oriented
    );
}

#[test]
fn bad_input_is_an_error() {
    let mesh = grid(4, 4, 1.0);
    let topology = Topology::new(&mesh);
    let samples = [
        DVec3::new(1.2, 1.1, 0.0),
        DVec3::new(2.0, 1.5, 0.0),
        DVec3::new(1.5, 2.5, 0.0),
    ];
    assert!(SurfaceCurve::project(&mesh, &topology, 10, &samples).is_ok());
    assert!(matches!(
        SurfaceCurve::project(&mesh, &topology, 10, &samples[..2]),
        Err(CurveError::TooFewPoints { count: 2 })
    ));
    assert!(matches!(
        SurfaceCurve::project(&mesh, &topology, 99, &samples),
        Err(CurveError::StartOutOfRange { .. })
    ));
    assert!(matches!(
        SurfaceCurve::project(&mesh, &topology, 0, &samples),
        Err(CurveError::StartOffTriangle { .. })
    ));
    let mut nan = samples;
    nan[1].y = f64::NAN;
    assert!(matches!(
        SurfaceCurve::project(&mesh, &topology, 10, &nan),
        Err(CurveError::NonFiniteSample { index: 1, .. })
    ));
    let other = Topology::new(&grid(2, 2, 1.0));
    assert!(matches!(
        SurfaceCurve::project(&mesh, &other, 2, &samples),
        Err(CurveError::TopologyMismatch { .. })
    ));
}

#[test]
fn a_small_curl_is_cut_out_where_it_crosses_the_curve() {
    let mesh = grid(60, 60, 1.0);
    let topology = Topology::new(&mesh);
    // A 50 mm square whose top side curls round a 3 x 3 mm loop before going on: the
    // side (17.3, 58.4) -> (17.3, 52.4) crosses the top at (17.3, 55.4). The loop is 12 mm
    // of the 212 mm, under a tenth: it is cut out at the crossing.
    let corners = [
        [55.4, 5.4],
        [55.4, 55.4],
        [14.3, 55.4],
        [14.3, 58.4],
        [17.3, 58.4],
        [17.3, 52.4],
        [5.4, 52.4],
        [5.4, 5.4],
    ];
    let samples: Vec<DVec3> = (0..corners.len())
        .flat_map(|i| {
            let (a, b) = (corners[i], corners[(i + 1) % corners.len()]);
            let (a, b) = (DVec3::new(a[0], a[1], 0.0), DVec3::new(b[0], b[1], 0.0));
            let steps = (a.distance(b) / 0.5).round() as usize;
            (0..steps).map(move |k| a.lerp(b, k as f64 / steps as f64))
        })
        .collect();
    let curve = project(&mesh, &topology, &samples).unwrap();
    assert_consistent(&mesh, &topology, &curve);
    // The square's 200 mm once round, the loop gone (a flat grid: exact to rounding).
    assert!(
        (curve.length_mm() - 200.0).abs() < 1e-9,
        "{}",
        curve.length_mm()
    );
    assert!(curve.points.iter().all(|p| p.position.y < 55.4 + 1e-9));
}
