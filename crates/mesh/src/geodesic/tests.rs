use super::window::{Window, trimmed};
use super::*;
use crate::section::plane_section_path;
use crate::shapes::{cube, cylinder, grid, icosphere};
use crate::spatial::SurfaceIndex;
use std::collections::BinaryHeap;
use std::f64::consts::{PI, TAU};

/// The surface point nearest to `query`.
pub(crate) fn on_surface(index: &SurfaceIndex, query: DVec3) -> SurfacePoint {
    index.closest_point(query).into()
}

/// Vertex `v` as a point on one of its triangles.
pub(crate) fn at_vertex(mesh: &TriMesh, topology: &Topology, v: usize) -> SurfacePoint {
    SurfacePoint {
        triangle: topology.vertex_triangles(v)[0] as usize,
        point: mesh.positions[v],
    }
}

/// Every segment of the path runs on the surface: its midpoint is on the mesh.
pub(crate) fn assert_on_surface(index: &SurfaceIndex, path: &SurfacePath, tolerance: f64) {
    for w in path.points.windows(2) {
        let mid = (w[0] + w[1]) * 0.5;
        assert!(
            index.is_within(mid, tolerance),
            "segment {w:?} leaves the surface"
        );
    }
}

/// Smallest distance of a face plane from the origin: the polyhedron lies outside the
/// ball of this radius, so its geodesics are at least this radius times the angle.
pub(crate) fn inradius(mesh: &TriMesh) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| {
            mesh.triangle_normal(t)
                .dot(mesh.triangle_positions(t)[0])
                .abs()
        })
        .fold(f64::INFINITY, f64::min)
}

fn two_grids_apart() -> TriMesh {
    let mut mesh = grid(4, 4, 1.0);
    let other = grid(4, 4, 1.0);
    let offset = mesh.positions.len() as u32;
    let shift = DVec3::new(10.0, 0.0, 0.0);
    mesh.positions
        .extend(other.positions.iter().map(|p| *p + shift));
    mesh.triangles
        .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
    mesh
}

/// A 20 x 20 grid (1 mm) without the squares of 8 <= x < 12, 5 <= y < 15.
pub(crate) fn grid_with_hole() -> TriMesh {
    let mut mesh = grid(20, 20, 1.0);
    let hole: Vec<usize> = (0..mesh.triangle_count())
        .filter(|&t| {
            let [a, b, c] = mesh.triangle_positions(t);
            let center = (a + b + c) / 3.0;
            (8.0..12.0).contains(&center.x) && (5.0..15.0).contains(&center.y)
        })
        .collect();
    mesh.remove_triangles(&hole);
    mesh
}

#[test]
fn flat_grid_geodesic_is_the_straight_segment() {
    let mesh = grid(20, 20, 1.0);
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let point = |x: f64, y: f64| on_surface(&index, DVec3::new(x, y, 0.0));
    let pairs = [
        (point(1.3, 2.7), point(17.9, 15.2)), // triangle interiors
        (point(0.0, 0.0), point(20.0, 20.0)), // corners, along the diagonal edges
        (point(1.0, 5.0), point(19.0, 5.0)),  // vertices, along a grid line
        (point(2.5, 3.0), point(14.0, 11.5)), // points on edges
        (point(3.0, 19.7), point(16.2, 0.4)), // against the diagonals
        (point(0.0, 7.3), point(20.0, 7.9)),  // border to border
    ];
    for (from, to) in pairs {
        let path = solver.shortest_path(from, to).unwrap();
        // Exact: only round-off (measured below 1e-14 mm) remains.
        let straight = from.point.distance(to.point);
        assert!(
            (path.length_mm - straight).abs() < 1e-9,
            "{} vs {straight}",
            path.length_mm
        );
        assert_eq!(path.points.first(), Some(&from.point));
        assert_eq!(path.points.last(), Some(&to.point));
        assert_on_surface(&index, &path, 1e-9);
    }
}

#[test]
fn path_around_a_hole_wraps_its_corners() {
    let mesh = grid_with_hole();
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let from = on_surface(&index, DVec3::new(10.0, 2.0, 0.0));
    let to = on_surface(&index, DVec3::new(10.0, 18.0, 0.0));
    let path = solver.shortest_path(from, to).unwrap();
    // Taut string around the corners (8, 5) and (8, 15), or their mirror images.
    let expected = 2.0 * 13f64.sqrt() + 10.0;
    assert!(
        (path.length_mm - expected).abs() < 1e-9,
        "{}",
        path.length_mm
    );
    assert_on_surface(&index, &path, 1e-9);
}

#[test]
fn cube_corner_to_corner_unfolds_two_faces() {
    let mesh = cube(10.0);
    let topology = Topology::new(&mesh);
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let path = solver
        .shortest_path(
            at_vertex(&mesh, &topology, 0),
            at_vertex(&mesh, &topology, 7),
        )
        .unwrap();
    // Two faces unfolded into a 10 x 20 rectangle; the path avoids the convex corners.
    assert!(
        (path.length_mm - 500f64.sqrt()).abs() < 1e-9,
        "{}",
        path.length_mm
    );
}

#[test]
fn sphere_geodesic_matches_the_great_circle_arc() {
    let radius = 100.0;
    let mesh = icosphere(radius, 5);
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    // The polyhedron lies between the balls of its inradius (99.97 mm) and its
    // circumradius (100 mm), so between two vertices (on both spheres) its geodesic is
    // at least inradius * angle (radial projection onto the inner ball shortens paths)
    // and, the polyhedron being convex, at most radius * angle (nearest-point
    // projection of the great-circle arc onto it shortens it): within 2.9e-4 of the
    // arc. Measured: 0.6e-4 to 1.6e-4 below the arc.
    let inner = inradius(&mesh);
    assert!(radius - inner < 0.03);
    let mut worst = 0f64;
    for (a, b) in [
        (0, 5),
        (0, 997),
        (3, 4000),
        (17, 9000),
        (100, 10_000),
        (42, 7777),
    ] {
        let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
        let theta = angle(pa, pb);
        let path = solver
            .shortest_path(
                at_vertex(&mesh, &topology, a),
                at_vertex(&mesh, &topology, b),
            )
            .unwrap();
        assert!(
            path.length_mm >= inner * theta && path.length_mm <= radius * theta + 1e-9,
            "angle {theta}: {} outside [{}, {}]",
            path.length_mm,
            inner * theta,
            radius * theta
        );
        assert_on_surface(&index, &path, 1e-9);
        worst = worst.max((1.0 - path.length_mm / (radius * theta)).abs());
    }
    assert!(worst < 2e-4, "{worst}");
}

#[test]
fn cylinder_geodesic_is_the_unrolled_helix() {
    let (radius, height, segments, rings) = (50.0, 200.0, 256, 64);
    let mesh = cylinder(radius, height, segments, rings);
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let step = TAU / segments as f64;
    let chord = 2.0 * radius * (step / 2.0).sin();
    // Position of a point on the prism unrolled: perimeter coordinate and height.
    let unroll = |p: DVec3| {
        let i = (p.y.atan2(p.x).rem_euclid(TAU) / step).floor();
        let corner = DVec3::new(radius * (i * step).cos(), radius * (i * step).sin(), p.z);
        (i * chord + corner.distance(p), p.z)
    };
    let point = |angle: f64, z: f64| {
        on_surface(
            &index,
            DVec3::new(radius * angle.cos(), radius * angle.sin(), z),
        )
    };
    let perimeter = segments as f64 * chord;
    for (from, to) in [
        (point(0.0, 20.0), point(1.0, 170.0)),
        (point(0.3, 190.0), point(2.9, 3.0)),
        (point(5.9, 50.0), point(0.4, 60.0)), // across the seam at angle 0
        (point(1.0, 100.0), point(1.0 + PI - 0.05, 110.0)),
    ] {
        let path = solver.shortest_path(from, to).unwrap();
        let ((s0, z0), (s1, z1)) = (unroll(from.point), unroll(to.point));
        let ds = (s1 - s0).abs().min(perimeter - (s1 - s0).abs());
        // The prism is developable: unrolled, the geodesic is a straight line, found
        // exactly up to round-off.
        let exact = ds.hypot(z1 - z0);
        assert!(
            (path.length_mm - exact).abs() < 1e-9,
            "{} vs {exact}",
            path.length_mm
        );
        // Against the smooth helix the prism's perimeter is short by the chord deficit
        // 1 - sin(x)/x, x = pi/256: 2.5e-5 relative.
        let (angle_from, angle_to) = (
            from.point.y.atan2(from.point.x),
            to.point.y.atan2(to.point.x),
        );
        let turn = (angle_to - angle_from).rem_euclid(TAU);
        let helix = (radius * turn.min(TAU - turn)).hypot(to.point.z - from.point.z);
        assert!(
            (path.length_mm / helix - 1.0).abs() < 3e-5,
            "{} vs {helix}",
            path.length_mm
        );
        assert_on_surface(&index, &path, 1e-9);
    }
}

/// A sphere of radius 50 mm with its vertices moved radially by up to 1 mm
/// (deterministic), so that about half the vertices are saddles.
fn bumpy_sphere() -> TriMesh {
    let mut mesh = icosphere(50.0, 3);
    for (i, p) in mesh.positions.iter_mut().enumerate() {
        let bump = ((i as f64 * 12.9898).sin() * 43_758.545).fract();
        *p *= 1.0 + bump / 50.0;
    }
    mesh
}

/// Length of the shortest path in the graph of the vertices and `per_edge` points on
/// every edge, all points of a triangle joined: a surface path, so an upper bound.
fn graph_distance(mesh: &TriMesh, from: SurfacePoint, to: SurfacePoint, per_edge: usize) -> f64 {
    let mut index_of = std::collections::HashMap::new();
    let mut nodes: Vec<DVec3> = mesh.positions.clone();
    let triangle_nodes: Vec<Vec<usize>> = (0..mesh.triangle_count())
        .map(|t| {
            let tri = mesh.triangles[t];
            let mut list: Vec<usize> = tri.iter().map(|&v| v as usize).collect();
            for k in 0..3 {
                let (a, b) = (tri[k].min(tri[(k + 1) % 3]), tri[k].max(tri[(k + 1) % 3]));
                for j in 1..=per_edge {
                    let id = *index_of.entry((a, b, j)).or_insert_with(|| {
                        let f = j as f64 / (per_edge + 1) as f64;
                        nodes.push(mesh.positions[a as usize].lerp(mesh.positions[b as usize], f));
                        nodes.len() - 1
                    });
                    list.push(id);
                }
            }
            list
        })
        .collect();
    let mut node_triangles = vec![Vec::new(); nodes.len()];
    for (t, list) in triangle_nodes.iter().enumerate() {
        for &n in list {
            node_triangles[n].push(t);
        }
    }
    // Dijkstra; non-negative floats order like their bit patterns.
    let mut distance = vec![f64::INFINITY; nodes.len()];
    let mut queue = BinaryHeap::new();
    for &n in &triangle_nodes[from.triangle] {
        distance[n] = from.point.distance(nodes[n]);
        queue.push((std::cmp::Reverse(distance[n].to_bits()), n));
    }
    let mut best = f64::INFINITY;
    while let Some((std::cmp::Reverse(bits), n)) = queue.pop() {
        if f64::from_bits(bits) > distance[n] {
            continue;
        }
        if triangle_nodes[to.triangle].contains(&n) {
            best = best.min(distance[n] + nodes[n].distance(to.point));
        }
        for &t in &node_triangles[n] {
            for &m in &triangle_nodes[t] {
                let through = distance[n] + nodes[n].distance(nodes[m]);
                if through < distance[m] {
                    distance[m] = through;
                    queue.push((std::cmp::Reverse(through.to_bits()), m));
                }
            }
        }
    }
    best
}

#[test]
fn no_graph_path_is_shorter_on_a_bumpy_surface() {
    let mesh = bumpy_sphere();
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let saddles = solver.may_bend.iter().filter(|&&b| b).count();
    assert!(saddles > mesh.vertex_count() / 4, "{saddles}");
    let direction = |k: f64| {
        DVec3::new(
            k.cos() * (2.0 * k).cos(),
            k.sin() * (2.0 * k).cos(),
            (2.0 * k).sin(),
        )
    };
    for k in 0..6 {
        let from = on_surface(&index, direction(k as f64) * 60.0);
        let to = on_surface(&index, direction(k as f64 + 1.3) * 60.0);
        let exact = solver.shortest_path(from, to).unwrap().length_mm;
        // Every graph path is a surface path, so never shorter; with 6 points per edge
        // it comes close (measured: 0.10 % to 0.37 % longer).
        let graph = graph_distance(&mesh, from, to, 6);
        assert!(
            exact <= graph + 1e-9 && graph < 1.01 * exact,
            "{exact} vs {graph}"
        );
    }
}

#[test]
fn a_path_bends_at_a_saddle_vertex() {
    // Eight triangles round a centre vertex, the rim zig-zagging up and down: the
    // angles at the centre sum to 8 x 68.5 = 548 degrees.
    let (radius, lift) = (10.0, 5.0);
    let mut positions = vec![DVec3::ZERO];
    positions.extend((0..8).map(|k| {
        let phi = k as f64 * TAU / 8.0;
        let z = if k % 2 == 0 { lift } else { -lift };
        DVec3::new(radius * phi.cos(), radius * phi.sin(), z)
    }));
    let triangles = (0..8).map(|k| [0, k + 1, (k + 1) % 8 + 1]).collect();
    let mesh = TriMesh::new(positions, triangles);
    let topology = Topology::new(&mesh);
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let rim = |k: usize| at_vertex(&mesh, &topology, k + 1);
    let spoke = radius.hypot(lift);
    let wedge = angle(mesh.positions[1], mesh.positions[2]);
    // Opposite rim points are 4 x 68.5 = 274 degrees apart either way round, more than
    // 180: the shortest path runs through the centre.
    let through = solver.shortest_path(rim(0), rim(4)).unwrap();
    assert!((through.length_mm - 2.0 * spoke).abs() < 1e-12);
    assert!(through.points.contains(&DVec3::ZERO));
    // Two apart (137 degrees) the two triangles between unfold flat: a straight line.
    let across = solver.shortest_path(rim(0), rim(2)).unwrap();
    assert!((across.length_mm - 2.0 * spoke * wedge.sin()).abs() < 1e-12);
    assert!(!across.points.contains(&DVec3::ZERO));
}

#[test]
fn trimming_keeps_every_point_a_window_reaches_first() {
    // Pairs of random windows on one edge, checked at 201 points of the kept one.
    let mut state = 0x2545_f491_4f6c_dd1d_u64;
    let mut random = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut window = || {
        let start = 10.0 * random();
        Window {
            triangle: 0,
            edge: 0,
            start,
            end: start + 5.0 * random(),
            source: DVec2::new(20.0 * random() - 5.0, -10.0 * random() - 0.1),
            sigma: 5.0 * random(),
            parent: Parent::Start,
            next_on_edge: None,
            carried: false,
        }
    };
    let mut dominated = 0;
    for _ in 0..20_000 {
        let (keep, by) = (window(), window());
        let kept = trimmed(&keep, &by);
        let mut everywhere_shorter = true;
        for i in 0..=200 {
            let x = keep.start + (keep.end - keep.start) * i as f64 / 200.0;
            let covered = (by.start..=by.end).contains(&x);
            if !covered || keep.distance_at(x) < by.distance_at(x) - 1e-9 {
                assert!(
                    kept.is_some_and(|(a, b)| a - 1e-9 <= x && x <= b + 1e-9),
                    "{keep:?} trimmed by {by:?} to {kept:?} loses {x}"
                );
            }
            everywhere_shorter &= covered && by.distance_at(x) < keep.distance_at(x) - 1e-6;
        }
        // And a window reached sooner everywhere through the other goes.
        if everywhere_shorter {
            assert_eq!(kept, None, "{keep:?} survives {by:?}");
            dominated += 1;
        }
    }
    assert!(dominated > 100, "{dominated}");
}

#[test]
fn equal_points_give_an_empty_path() {
    let mesh = grid(4, 4, 1.0);
    let topology = Topology::new(&mesh);
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let p = SurfacePoint {
        triangle: 2,
        point: DVec3::new(1.6, 0.5, 0.0),
    };
    assert_eq!(solver.shortest_path(p, p).unwrap().length_mm, 0.0);
    // The same vertex named through two different triangles.
    let v = 12;
    let triangles = topology.vertex_triangles(v);
    let (from, to) = (
        SurfacePoint {
            triangle: triangles[0] as usize,
            point: mesh.positions[v],
        },
        SurfacePoint {
            triangle: triangles[3] as usize,
            point: mesh.positions[v],
        },
    );
    assert_eq!(solver.shortest_path(from, to).unwrap().length_mm, 0.0);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let mesh = two_grids_apart();
    let topology = Topology::new(&mesh);
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let from = SurfacePoint {
        triangle: 0,
        point: DVec3::new(0.7, 0.2, 0.0),
    };
    let far = SurfacePoint {
        triangle: mesh.triangle_count() - 1,
        point: DVec3::new(13.8, 3.9, 0.0),
    };
    assert_eq!(
        solver.shortest_path(from, far),
        Err(PathError::DifferentComponents)
    );
    let missing = SurfacePoint {
        triangle: 999,
        ..from
    };
    assert!(matches!(
        solver.shortest_path(from, missing),
        Err(PathError::TriangleOutOfRange {
            endpoint: "end",
            ..
        })
    ));
    let off = SurfacePoint {
        point: DVec3::new(0.7, 0.2, 1.0),
        ..from
    };
    assert!(matches!(
        solver.shortest_path(off, from),
        Err(PathError::NotOnTriangle {
            endpoint: "start",
            ..
        })
    ));
    let nan = SurfacePoint {
        point: DVec3::NAN,
        ..from
    };
    assert!(solver.shortest_path(nan, from).is_err());
    let other = grid(2, 2, 1.0);
    assert!(matches!(
        GeodesicSolver::new(&other, &topology),
        Err(PathError::TopologyMismatch { .. })
    ));
}

#[test]
fn collapsed_triangles_do_not_break_paths() {
    // Vertex (2, 1) moved onto (3, 1): two triangles collapse to segments and the
    // edge between the two vertices has length zero.
    let mut mesh = grid(4, 4, 1.0);
    mesh.positions[7] = mesh.positions[8];
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let (from, to) = (
        on_surface(&index, DVec3::new(0.5, 0.2, 0.0)),
        on_surface(&index, DVec3::new(3.6, 3.9, 0.0)),
    );
    let path = solver.shortest_path(from, to).unwrap();
    assert!(path.length_mm.is_finite() && path.length_mm >= from.point.distance(to.point));
    let normal = (to.point - from.point).cross(DVec3::Z);
    let section = plane_section_path(&mesh, &topology, from, to, normal).unwrap();
    assert!(section.length_mm >= path.length_mm - 1e-9);
}

#[test]
fn queries_run_in_parallel() {
    use rayon::prelude::*;
    fn assert_sync<T: Sync>(_: &T) {}
    let mesh = icosphere(50.0, 3);
    let topology = Topology::new(&mesh);
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    assert_sync(&solver);
    let lengths: Vec<f64> = (1..40)
        .into_par_iter()
        .map(|v| {
            let path = solver.shortest_path(
                at_vertex(&mesh, &topology, 0),
                at_vertex(&mesh, &topology, v * 16),
            );
            path.map_or(f64::NAN, |p| p.length_mm)
        })
        .collect();
    for (v, length) in (1..40).zip(lengths) {
        let alone = solver
            .shortest_path(
                at_vertex(&mesh, &topology, 0),
                at_vertex(&mesh, &topology, v * 16),
            )
            .unwrap();
        assert_eq!(alone.length_mm, length);
    }
}

/// Deterministic numbers uniform in [0, 1) (xorshift).
struct Random(u64);

impl Random {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn below(&mut self, n: usize) -> usize {
        ((self.next() * n as f64) as usize).min(n - 1)
    }
}

/// The point at `fraction` of the way from vertex `a` to vertex `b` (an edge), on the
/// `side`-th (0 or 1) of the edge's triangles.
fn on_edge(
    mesh: &TriMesh,
    topology: &Topology,
    (a, b): (usize, usize),
    fraction: f64,
    side: usize,
) -> SurfacePoint {
    let triangles: Vec<u32> = topology
        .vertex_triangles(a)
        .iter()
        .copied()
        .filter(|&t| mesh.triangles[t as usize].contains(&(b as u32)))
        .collect();
    SurfacePoint {
        triangle: triangles[side.min(triangles.len() - 1)] as usize,
        point: mesh.positions[a].lerp(mesh.positions[b], fraction),
    }
}

/// Length of the shortest path along mesh edges, joined to the end points across their
/// triangles: a surface path, so never shorter than the geodesic.
fn edge_path_length(
    mesh: &TriMesh,
    topology: &Topology,
    from: SurfacePoint,
    to: SurfacePoint,
) -> f64 {
    // Dijkstra; non-negative floats order like their bit patterns.
    let mut distance = vec![f64::INFINITY; mesh.vertex_count()];
    let mut queue = BinaryHeap::new();
    for &v in &mesh.triangles[from.triangle] {
        distance[v as usize] = from.point.distance(mesh.positions[v as usize]);
        queue.push((std::cmp::Reverse(distance[v as usize].to_bits()), v));
    }
    while let Some((std::cmp::Reverse(bits), v)) = queue.pop() {
        if f64::from_bits(bits) > distance[v as usize] {
            continue;
        }
        let here = mesh.positions[v as usize];
        for w in topology.vertex_neighbors(mesh, v as usize) {
            let d = distance[v as usize] + here.distance(mesh.positions[w as usize]);
            if d < distance[w as usize] {
                distance[w as usize] = d;
                queue.push((std::cmp::Reverse(d.to_bits()), w));
            }
        }
    }
    mesh.triangles[to.triangle]
        .iter()
        .map(|&v| distance[v as usize] + mesh.positions[v as usize].distance(to.point))
        .fold(f64::INFINITY, f64::min)
}

/// Whether every segment of the path lies on the surface (sampled at seven points).
fn lies_on_the_surface(index: &SurfaceIndex, path: &SurfacePath) -> bool {
    path.points.windows(2).all(|w| {
        let tolerance = 1e-9 * (1.0 + w[0].distance(w[1]));
        (1..8).all(|k| index.is_within(w[0].lerp(w[1], k as f64 / 8.0), tolerance))
    })
}

/// The reported case and its kin: on a cylinder every vertex is flat and the ring edges
/// unroll to straight lines, so between two vertices of a ring the geodesic is the
/// polygon arc along the ring, a straight line through vertices that only round-off
/// separates from the windows' ends.
#[test]
fn geodesic_along_a_cylinder_ring_is_the_polygon_arc() {
    let mut mesh = cylinder(100.0, 200.0, 512, 128);
    // Axis along y, as in the anatomy crate's test (a proper rotation).
    mesh.map_positions(|p| DVec3::new(p.x, p.z, -p.y));
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let step = TAU / 512.0;
    let chord = 200.0 * (step / 2.0).sin();
    let on_cylinder = |angle: f64, y: f64| {
        let azimuth = angle - PI / 2.0;
        DVec3::new(100.0 * azimuth.cos(), y, -100.0 * azimuth.sin())
    };
    for (first, segments, ring) in [
        (-40, 80, 64),
        (0, 1, 64),
        (3, 2, 64),
        (-7, 13, 10),
        (250, 31, 100),
        (-60, 120, 127),
    ] {
        let y = 200.0 * ring as f64 / 128.0;
        // Located by the closest point, as the measurements do: on a vertex up to
        // round-off, on whichever triangle of its fan the search found first.
        let from = on_surface(&index, on_cylinder(first as f64 * step, y));
        let to = on_surface(&index, on_cylinder((first + segments) as f64 * step, y));
        let path = solver.shortest_path(from, to).unwrap();
        let arc = segments as f64 * chord;
        // Measured: within 1.1e-14 relative (was 0.8 % over for the first pair).
        assert!(
            (path.length_mm / arc - 1.0).abs() < 1e-12,
            "{segments} segments: {} vs {arc}",
            path.length_mm
        );
        assert_on_surface(&index, &path, 1e-9);
        // The horizontal section through both runs along the ring too.
        let section = plane_section_path(&mesh, &topology, from, to, DVec3::Y).unwrap();
        assert!(
            path.length_mm <= section.length_mm * (1.0 + 1e-12),
            "{} vs section {}",
            path.length_mm,
            section.length_mm
        );
    }
}

/// A grid of 2.5 mm squares turned and moved away from the origin, so the unfolding
/// rounds (axis-aligned small integers would not).
fn turned_grid() -> (TriMesh, impl Fn(i64, i64) -> usize) {
    let mut mesh = grid(60, 60, 2.5);
    let (x, y) = (DVec3::new(0.6, 0.48, 0.64), DVec3::new(-0.8, 0.36, 0.48));
    mesh.map_positions(|p| DVec3::new(412.7, -1033.1, 871.3) + x * p.x + y * p.y);
    (mesh, |i: i64, j: i64| (j * 61 + i) as usize)
}

#[test]
fn geodesics_through_vertices_of_a_flat_grid_are_straight() {
    let (mesh, vertex) = turned_grid();
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    // Along a row, a column and the diagonal edges; against the diagonals and at a
    // knight's move, through vertices between edges.
    let cases = [
        ((2, 5), (1, 0), 50),
        ((7, 1), (0, 1), 57),
        ((3, 4), (1, 1), 45),
        ((55, 2), (-1, 1), 40),
        ((1, 9), (2, 1), 25),
        ((30, 30), (1, 0), 1),
        ((30, 30), (1, 1), 2),
    ];
    for ((i, j), (di, dj), steps) in cases {
        let (a, b) = (vertex(i, j), vertex(i + steps * di, j + steps * dj));
        let path = solver
            .shortest_path(
                at_vertex(&mesh, &topology, a),
                at_vertex(&mesh, &topology, b),
            )
            .unwrap();
        let straight = mesh.positions[a].distance(mesh.positions[b]);
        // Measured: within 7e-15 relative.
        assert!(
            (path.length_mm / straight - 1.0).abs() < 1e-12,
            "({di}, {dj}) x {steps}: {} vs {straight}",
            path.length_mm
        );
        assert_on_surface(&index, &path, 1e-9);
    }
}

#[test]
fn geodesics_between_points_on_edges_run_along_the_edges() {
    let (mesh, vertex) = turned_grid();
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let side = 2.5;
    // (start edge, fraction along it), (end edge, fraction): on one line of edges.
    let row = |i: i64| (vertex(i, 20), vertex(i + 1, 20));
    let diagonal = |i: i64| (vertex(i, i), vertex(i + 1, i + 1));
    let cases = [
        ((row(3), 0.3), (row(40), 0.6), (37.0 + 0.3) * side),
        ((row(3), 0.0), (row(40), 0.25), (37.0 + 0.25) * side),
        ((row(3), 0.75), (row(40), 1.0), (37.0 + 0.25) * side),
        ((row(10), 0.5), (row(11), 0.5), side),
        (
            (diagonal(2), 0.1),
            (diagonal(50), 0.9),
            48.8 * side * 2f64.sqrt(),
        ),
    ];
    for ((from_edge, f), (to_edge, g), expected) in cases {
        for (from_side, to_side) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            let from = on_edge(&mesh, &topology, from_edge, f, from_side);
            let to = on_edge(&mesh, &topology, to_edge, g, to_side);
            let path = solver.shortest_path(from, to).unwrap();
            assert!(
                (path.length_mm / expected - 1.0).abs() < 1e-12,
                "{} vs {expected}",
                path.length_mm
            );
            assert_on_surface(&index, &path, 1e-9);
        }
    }
    // The same on the cylinder, along a ring.
    let (segments, rings) = (256, 32);
    let mesh = cylinder(50.0, 100.0, segments, rings);
    let topology = Topology::new(&mesh);
    let index = SurfaceIndex::new(&mesh).unwrap();
    let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
    let chord = 100.0 * (PI / segments as f64).sin();
    let ring = |i: usize| {
        (
            12 * segments + i % segments,
            12 * segments + (i + 1) % segments,
        )
    };
    for (first, f, last, g) in [(250, 0.4, 290, 0.7), (5, 0.0, 40, 0.5), (9, 0.5, 10, 0.0)] {
        for sides in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let from = on_edge(&mesh, &topology, ring(first), f, sides.0);
            let to = on_edge(&mesh, &topology, ring(last), g, sides.1);
            let path = solver.shortest_path(from, to).unwrap();
            let expected = ((last - first) as f64 + g - f) * chord;
            assert!(
                (path.length_mm / expected - 1.0).abs() < 1e-12,
                "{} vs {expected}",
                path.length_mm
            );
            assert_on_surface(&index, &path, 1e-9);
        }
    }
}

/// Random pairs of vertices, of points inside triangles and of points on edges, and
/// of vertices on a common row, column or diagonal of a grid of vertices (`columns`
/// per row, `wraps` round as on a cylinder): the geodesic is never longer than the
/// path along mesh edges or a plane section through both points. Returns how many
/// sections were compared.
fn assert_never_beaten(
    mesh: &TriMesh,
    seed: u64,
    pairs: usize,
    columns: Option<(usize, bool)>,
) -> usize {
    let topology = Topology::new(mesh);
    let index = SurfaceIndex::new(mesh).unwrap();
    let solver = GeodesicSolver::new(mesh, &topology).unwrap();
    let mut random = Random(seed);
    let mut sections = 0;
    for pair in 0..pairs {
        let point = |random: &mut Random, kind: usize| {
            let t = random.below(mesh.triangle_count());
            let [a, b, c] = mesh.triangle_positions(t);
            let (u, v) = (random.next(), random.next());
            let point = match kind {
                0 => return at_vertex(mesh, &topology, random.below(mesh.vertex_count())),
                1 if u + v > 1.0 => a + (b - a) * (1.0 - u) + (c - a) * (1.0 - v),
                1 => a + (b - a) * u + (c - a) * v,
                _ => {
                    let k = random.below(3);
                    [a, b, c][k].lerp([b, c, a][k], u)
                }
            };
            SurfacePoint { triangle: t, point }
        };
        let (from, to) = match (pair % 4, columns) {
            (3, Some((columns, wraps))) => {
                let rows = mesh.vertex_count() / columns;
                let (i, j) = (random.below(columns) as i64, random.below(rows) as i64);
                let (di, dj) = [(1, 0), (0, 1), (1, 1), (-1, 1), (2, 1)][random.below(5)];
                let steps = 1 + random.below(rows) as i64;
                let (mut i1, j1) = (i + steps * di, j + steps * dj);
                if wraps {
                    i1 = i1.rem_euclid(columns as i64);
                }
                if j1 >= rows as i64 || !(0..columns as i64).contains(&i1) {
                    continue;
                }
                let vertex =
                    |i: i64, j: i64| at_vertex(mesh, &topology, (j * columns as i64 + i) as usize);
                (vertex(i, j), vertex(i1, j1))
            }
            (kind, _) => {
                let kind = kind.min(2);
                (point(&mut random, kind), point(&mut random, kind))
            }
        };
        let geodesic = solver.shortest_path(from, to).unwrap().length_mm;
        let along_edges = edge_path_length(mesh, &topology, from, to);
        assert!(
            geodesic <= along_edges * (1.0 + 1e-9),
            "pair {pair}: {geodesic} vs {along_edges} along edges, {from:?} to {to:?}"
        );
        let normals = [mesh.triangle_normal(from.triangle) + mesh.triangle_normal(to.triangle)]
            .into_iter()
            .chain((0..3).map(|_| DVec3::new(random.next(), random.next(), random.next()) - 0.5))
            .map(|direction| (to.point - from.point).cross(direction));
        for normal in normals {
            // A section curve that misses the end point is finished straight to it
            // within three triangle sizes (see `plane_section_path`): then it leaves
            // the surface and bounds nothing.
            let Ok(section) = plane_section_path(mesh, &topology, from, to, normal) else {
                continue;
            };
            if lies_on_the_surface(&index, &section) {
                sections += 1;
                assert!(
                    geodesic <= section.length_mm * (1.0 + 1e-9),
                    "pair {pair}: {geodesic} vs section {}, {from:?} to {to:?}",
                    section.length_mm
                );
            }
        }
    }
    sections
}

#[test]
fn geodesics_are_never_beaten_by_edge_paths_or_plane_sections() {
    let mut random = Random(0x9e37_79b9_7f4a_7c15);
    let mut noisy_grid = grid(40, 40, 1.0);
    for p in &mut noisy_grid.positions {
        p.z = 0.3 * (2.0 * random.next() - 1.0);
    }
    let mut noisy_sphere = icosphere(50.0, 4);
    for p in &mut noisy_sphere.positions {
        *p *= 1.0 + 0.005 * (2.0 * random.next() - 1.0);
    }
    let (turned, _) = turned_grid();
    let meshes = [
        (noisy_grid, Some((41, false))),
        (cylinder(50.0, 100.0, 128, 32), Some((128, true))),
        (noisy_sphere, None),
        (turned, Some((61, false))),
    ];
    for (seed, (mesh, columns)) in (1..).zip(meshes) {
        let sections = assert_never_beaten(&mesh, seed, 200, columns);
        assert!(sections > 400, "{sections}");
    }
}
