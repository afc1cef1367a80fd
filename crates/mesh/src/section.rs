//! Plane sections: the paper's on-surface distance (section IV-A). A plane through both
//! points (for landmarks: also orthogonal to the coronal plane) is intersected with the
//! surface, and the intersection curve is traced from the start point triangle by
//! triangle across the edges the plane crosses (the triangle walking of section IV-B),
//! both ways, until it reaches the end point.
//!
//! A vertex exactly on the plane counts as lying on its positive side (a symbolic
//! perturbation). Every triangle is then crossed at exactly zero or two edges, both
//! triangles of an edge agree on whether and where it is crossed, and a curve through a
//! vertex or along an edge stays one walk that cannot get stuck.

use crate::geodesic::{
    PathError, SurfacePath, SurfacePoint, check_endpoint, check_topology, distance_to_segment,
    edge_index, locate, push_distinct,
};
use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::TriMesh;
use glam::DVec3;

/// Relative tolerance, of the distance between the points plus the end triangle's size,
/// for the end point's distance from the plane and for a curve passing through a point:
/// far above round-off at scan coordinates (~1e-13 mm), far below any scan's noise.
const PLANE_TOLERANCE: f64 = 1e-6;

/// How far (in sizes of the point's triangle) a section curve may pass beside a path end
/// and still count as reaching it; see [`End::approach`].
const APPROACH_IN_TRIANGLE_SIZES: f64 = 3.0;

/// The path along the intersection curve of the surface with the plane through `from`
/// with normal `plane_normal` (any length), from `from` to `to`; `to` must lie on the
/// plane. Of the two ways along the curve, the shorter one reaching `to` is returned.
///
/// Errors if the curve leaves the surface at its border both ways before reaching `to`,
/// or closes on itself without passing it.
pub fn plane_section_path(
    mesh: &TriMesh,
    topology: &Topology,
    from: SurfacePoint,
    to: SurfacePoint,
    plane_normal: DVec3,
) -> Result<SurfacePath, PathError> {
    check_topology(mesh, topology)?;
    check_endpoint(mesh, from, "start")?;
    check_endpoint(mesh, to, "end")?;
    if locate(mesh, topology, from).shares_triangle(&locate(mesh, topology, to)) {
        // On a common triangle the segment is the whole curve between them, whatever the
        // plane (the caller's normal degenerates when the points coincide).
        return Ok(SurfacePath::from_points(vec![from.point, to.point]));
    }
    let normal = plane_normal
        .try_normalize()
        .ok_or(PathError::InvalidPlaneNormal {
            normal: plane_normal.to_array(),
        })?;
    let section = Section {
        mesh,
        topology,
        normal,
        origin: from.point,
    };
    let [a, b, c] = mesh.triangle_positions(to.triangle);
    let end_size = a.distance(b).max(b.distance(c)).max(c.distance(a));
    let tolerance = PLANE_TOLERANCE * (from.point.distance(to.point) + end_size);
    let off_plane = section.signed_distance(to.point).abs();
    let on_plane = off_plane <= tolerance; // false for NaN too
    if !on_plane {
        return Err(PathError::EndOffPlane {
            distance_mm: off_plane,
        });
    }
    // A curve point within this distance of a path end passes through it.
    let reach = 2.0 * tolerance;
    let end = End {
        point: to.point,
        triangles: triangles_around(mesh, topology, to.triangle),
        reach,
        approach: APPROACH_IN_TRIANGLE_SIZES * end_size,
    };

    // The curve piece nearest to the start point among the triangles touching its
    // triangle (the start may lie on an edge or vertex the curve passes on a neighbour).
    let (start_triangle, crossed, _) = triangles_around(mesh, topology, from.triangle)
        .into_iter()
        .filter_map(|t| {
            let crossed = section.crossed_edges(t as usize)?;
            let [p, q] = crossed.map(|k| section.crossing(t as usize, k));
            Some((t as usize, crossed, distance_to_segment(from.point, p, q)))
        })
        .min_by(|x, y| x.2.total_cmp(&y.2))
        .filter(|&(_, _, distance)| distance <= APPROACH_IN_TRIANGLE_SIZES * start_size(mesh, from))
        .ok_or(PathError::NoSectionAtStart)?;
    let [p, q] = crossed.map(|k| section.crossing(start_triangle, k));
    if end.lies_on(start_triangle, p, q) {
        return Ok(SurfacePath::from_points(vec![from.point, to.point]));
    }

    let budget = mesh.triangles.len() + 1;
    let mut shortest: Option<SurfacePath> = None;
    let mut closed = false;
    for exit in crossed {
        match section.walk(start_triangle, exit, from.point, &end, budget)? {
            Walk::Reached(points) => {
                let path = SurfacePath::from_points(points);
                if shortest
                    .as_ref()
                    .is_none_or(|s| path.length_mm < s.length_mm)
                {
                    shortest = Some(path);
                }
            }
            Walk::Closed => closed = true,
            Walk::LeftMesh => {}
        }
    }
    shortest.ok_or(if closed {
        PathError::SectionMissesEnd
    } else {
        PathError::SectionLeavesMesh
    })
}

/// A plane cutting a mesh.
struct Section<'a> {
    mesh: &'a TriMesh,
    topology: &'a Topology,
    /// Unit normal.
    normal: DVec3,
    /// A point of the plane.
    origin: DVec3,
}

/// The end point of a walk and where the curve counts as passing it.
struct End {
    point: DVec3,
    /// The triangles touching the end point's triangle.
    triangles: Vec<u32>,
    /// Distance (mm) within which a curve piece passes the end point.
    reach: f64,
    /// Distance (mm) within which a curve that never passes the end point exactly counts
    /// as reaching it: three times the size of the end point's triangle. At a landmark on a bump tip
    /// (a nipple) the plane may only touch the surface at the point itself, the curve
    /// then passing a fraction of a millimetre beside it.
    approach: f64,
}

impl End {
    /// Whether the curve piece from `p` to `q` on triangle `t` passes the end point.
    fn lies_on(&self, t: usize, p: DVec3, q: DVec3) -> bool {
        self.triangles.contains(&(t as u32)) && distance_to_segment(self.point, p, q) <= self.reach
    }
}

/// Longest edge (mm) of the start point's triangle; three times it is the farthest a
/// curve piece may pass beside the start point (see [`End::approach`]).
fn start_size(mesh: &TriMesh, from: SurfacePoint) -> f64 {
    let [a, b, c] = mesh.triangle_positions(from.triangle);
    a.distance(b).max(b.distance(c)).max(c.distance(a))
}

/// The point of segment `a`-`b` nearest to `point`.
fn closest_on_segment(point: DVec3, a: DVec3, b: DVec3) -> DVec3 {
    let ab = b - a;
    let t = ab.dot(point - a) / ab.length_squared();
    a + ab
        * if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.0
        }
}

/// The closest approach of a walk to its end point so far.
struct Approach {
    distance: f64,
    /// How many walk points precede the closest point.
    points_before: usize,
    closest: DVec3,
}

/// How a walk along the curve ended.
enum Walk {
    /// At the end point, with the polyline from the start point.
    Reached(Vec<DVec3>),
    /// Back at the start triangle: the curve is closed and misses the end point.
    Closed,
    /// At the mesh border.
    LeftMesh,
}

impl Section<'_> {
    fn signed_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p - self.origin)
    }

    /// Whether vertex `v` lies on the positive side (on the plane counts as positive).
    fn is_above(&self, v: u32) -> bool {
        self.signed_distance(self.mesh.positions[v as usize]) >= 0.0
    }

    /// The two edges of triangle `t` whose ends lie on opposite sides, if any.
    fn crossed_edges(&self, t: usize) -> Option<[usize; 2]> {
        let above = self.mesh.triangles[t].map(|v| self.is_above(v));
        let mut crossed = (0..3).filter(|&k| above[k] != above[(k + 1) % 3]);
        Some([crossed.next()?, crossed.next()?])
    }

    /// Where the plane crosses edge `k` of triangle `t` (a crossed edge). Computed from
    /// the lower vertex index, so both triangles of the edge get the identical point.
    fn crossing(&self, t: usize, k: usize) -> DVec3 {
        let triangle = self.mesh.triangles[t];
        let (u, w) = (triangle[k], triangle[(k + 1) % 3]);
        let (a, b) = (
            self.mesh.positions[u.min(w) as usize],
            self.mesh.positions[u.max(w) as usize],
        );
        let (da, db) = (self.signed_distance(a), self.signed_distance(b));
        // The ends lie on opposite sides, so `da - db` is not zero.
        a + (b - a) * (da / (da - db))
    }

    /// Follows the curve from `start` on triangle `start_triangle` out across its edge
    /// `exit`, triangle by triangle, until it passes the end point, returns to the start
    /// triangle or leaves the mesh.
    fn walk(
        &self,
        start_triangle: usize,
        exit: usize,
        start: DVec3,
        end: &End,
        budget: usize,
    ) -> Result<Walk, PathError> {
        let mut points = vec![start];
        let mut nearest: Option<Approach> = None;
        // A walk that never passes the end point exactly ends at its closest approach
        // within `end.approach`, if it had one.
        let end_at_approach =
            |mut points: Vec<DVec3>, nearest: Option<Approach>, otherwise| match nearest {
                Some(a) if a.distance <= end.approach => {
                    points.truncate(a.points_before);
                    push_distinct(&mut points, a.closest);
                    push_distinct(&mut points, end.point);
                    Walk::Reached(points)
                }
                _ => otherwise,
            };
        let (mut triangle, mut exit) = (start_triangle, exit);
        for _ in 0..budget {
            let crossing = self.crossing(triangle, exit);
            let previous = *points.last().unwrap_or(&start);
            let closest = closest_on_segment(end.point, previous, crossing);
            let distance = closest.distance(end.point);
            if nearest.as_ref().is_none_or(|a| distance < a.distance) {
                nearest = Some(Approach {
                    distance,
                    points_before: points.len(),
                    closest,
                });
            }
            push_distinct(&mut points, crossing);
            let next = self.topology.triangle_neighbors[triangle][exit];
            if next == NO_TRIANGLE {
                return Ok(end_at_approach(points, nearest, Walk::LeftMesh));
            }
            let next = next as usize;
            if next == start_triangle {
                return Ok(end_at_approach(points, nearest, Walk::Closed));
            }
            let corners = self.mesh.triangles[triangle];
            // The neighbour's copy of the shared edge is crossed too (same end vertices);
            // the curve leaves through its other crossed edge.
            let entry = edge_index(
                self.mesh.triangles[next],
                corners[exit],
                corners[(exit + 1) % 3],
            );
            let leave = entry
                .zip(self.crossed_edges(next))
                .and_then(|(entry, [k1, k2])| {
                    (entry == k1).then_some(k2).or((entry == k2).then_some(k1))
                });
            let Some(leave) = leave else {
                return Ok(Walk::LeftMesh); // inconsistent neighbour tables: treat as border
            };
            if end.lies_on(next, crossing, self.crossing(next, leave)) {
                push_distinct(&mut points, end.point);
                return Ok(Walk::Reached(points));
            }
            (triangle, exit) = (next, leave);
        }
        Err(PathError::WalkTooLong { steps: budget })
    }
}

/// Triangle `t` followed by the other triangles sharing a vertex with it.
fn triangles_around(mesh: &TriMesh, topology: &Topology, t: usize) -> Vec<u32> {
    let mut around = vec![t as u32];
    for &v in &mesh.triangles[t] {
        for &u in topology.vertex_triangles(v as usize) {
            if !around.contains(&u) {
                around.push(u);
            }
        }
    }
    around
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesic::GeodesicSolver;
    use crate::geodesic::tests::{
        assert_on_surface, at_vertex, grid_with_hole, inradius, on_surface,
    };
    use crate::shapes::{grid, icosphere};
    use crate::spatial::SurfaceIndex;

    /// The section path between two points of the z = 0 grid, plane containing +z.
    fn flat_section(
        mesh: &TriMesh,
        from: SurfacePoint,
        to: SurfacePoint,
    ) -> Result<SurfacePath, PathError> {
        let topology = Topology::new(mesh);
        plane_section_path(
            mesh,
            &topology,
            from,
            to,
            (to.point - from.point).cross(DVec3::Z),
        )
    }

    #[test]
    fn flat_grid_section_is_the_straight_segment() {
        let mesh = grid(20, 20, 1.0);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let point = |x: f64, y: f64| on_surface(&index, DVec3::new(x, y, 0.0));
        for (from, to) in [
            (point(1.3, 2.7), point(17.9, 15.2)), // triangle interiors
            (point(1.0, 5.0), point(8.0, 5.0)),   // along a grid line, vertex to vertex
            (point(2.0, 2.0), point(17.0, 17.0)), // along the triangles' diagonals
            (point(2.0, 3.0), point(6.0, 5.0)),   // through the vertex (4, 4)
            (point(2.5, 3.0), point(14.0, 11.5)), // from and to points on edges
            (point(7.0, 0.0), point(7.0, 20.0)),  // border to border along a grid line
            (point(3.3, 19.7), point(16.2, 0.4)), // against the diagonals
        ] {
            let path = flat_section(&mesh, from, to).unwrap();
            let straight = from.point.distance(to.point);
            // Exact up to round-off: the curve is the segment itself.
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
    fn sphere_section_follows_the_great_circle_and_bounds_the_geodesic() {
        let radius = 100.0;
        let mesh = icosphere(radius, 5);
        let topology = Topology::new(&mesh);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let solver = GeodesicSolver::new(&mesh, &topology).unwrap();
        let inner = inradius(&mesh);
        // Between vertices, the section through the centre is a convex polygon arc
        // between the circles of the inradius and the radius: within 2.9e-4 of the arc
        // (measured: 0.5e-4 to 1.6e-4 below it).
        for (a, b) in [(0, 5), (3, 4000), (17, 9000), (42, 7777)] {
            let (pa, pb) = (mesh.positions[a], mesh.positions[b]);
            let theta = pa.angle_between(pb);
            let path = plane_section_path(
                &mesh,
                &topology,
                at_vertex(&mesh, &topology, a),
                at_vertex(&mesh, &topology, b),
                pa.cross(pb),
            )
            .unwrap();
            assert!(
                path.length_mm >= inner * theta && path.length_mm <= radius * theta + 1e-9,
                "angle {theta}: {}",
                path.length_mm
            );
            assert_on_surface(&index, &path, 1e-9);
        }
        // Any pair, any plane containing both: section >= geodesic >= chord, the section
        // being one surface path among those the geodesic minimises over.
        let direction = |k: usize| {
            let (z, phi) = (
                1.0 - 2.0 * ((k as f64 * 0.618_034) % 1.0),
                k as f64 * 2.399_963,
            );
            let r = (1.0 - z * z).sqrt();
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        };
        for k in 0..24 {
            let (da, db) = (direction(3 * k + 1), direction(7 * k + 2));
            if da.angle_between(db) > 0.95 * std::f64::consts::PI {
                continue; // near-antipodal: many nearly equal geodesics
            }
            let (from, to) = (
                on_surface(&index, da * radius),
                on_surface(&index, db * radius),
            );
            // Planes through the centre, and tilted ones cutting smaller circles.
            for tilt in [DVec3::ZERO, 0.3 * da.cross(db).cross(da + db)] {
                let normal = (to.point - from.point).cross(from.point + to.point + tilt);
                let section = plane_section_path(&mesh, &topology, from, to, normal).unwrap();
                let geodesic = solver.shortest_path(from, to).unwrap();
                let chord = from.point.distance(to.point);
                assert!(
                    section.length_mm >= geodesic.length_mm - 1e-9 && geodesic.length_mm >= chord,
                    "section {} geodesic {} chord {chord}",
                    section.length_mm,
                    geodesic.length_mm
                );
            }
        }
    }

    #[test]
    fn equal_points_give_an_empty_path() {
        let mesh = grid(4, 4, 1.0);
        let topology = Topology::new(&mesh);
        let p = SurfacePoint {
            triangle: 2,
            point: DVec3::new(1.6, 0.5, 0.0),
        };
        // The caller's normal (B - A) x coronal is zero here: no plane is needed.
        assert_eq!(flat_section(&mesh, p, p).unwrap().length_mm, 0.0);
        let triangles = topology.vertex_triangles(12);
        let (from, to) = (
            at_vertex(&mesh, &topology, 12),
            SurfacePoint {
                triangle: triangles[3] as usize,
                point: mesh.positions[12],
            },
        );
        assert_ne!(from.triangle, to.triangle);
        assert_eq!(flat_section(&mesh, from, to).unwrap().length_mm, 0.0);
    }

    #[test]
    fn a_curve_leaving_the_scan_is_an_error() {
        let mesh = grid_with_hole();
        let index = SurfaceIndex::new(&mesh).unwrap();
        let from = on_surface(&index, DVec3::new(10.0, 2.0, 0.0));
        let to = on_surface(&index, DVec3::new(10.0, 18.0, 0.0));
        // Towards the end the line runs into the hole; the other way, into the outer border.
        assert_eq!(
            flat_section(&mesh, from, to),
            Err(PathError::SectionLeavesMesh)
        );
        // Beside the hole it gets through.
        let (from, to) = (
            on_surface(&index, DVec3::new(4.0, 2.0, 0.0)),
            on_surface(&index, DVec3::new(4.5, 18.0, 0.0)),
        );
        assert!(flat_section(&mesh, from, to).is_ok());
    }

    #[test]
    fn a_closed_curve_missing_the_end_is_an_error() {
        // Two separate spheres: the plane cuts each in a circle, and the one from the
        // start never meets the end.
        let mut mesh = icosphere(10.0, 2);
        let other = icosphere(10.0, 2);
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(
            other
                .positions
                .iter()
                .map(|p| *p + DVec3::new(50.0, 0.0, 0.0)),
        );
        mesh.triangles
            .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
        let topology = Topology::new(&mesh);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let from = on_surface(&index, DVec3::new(-6.0, 8.0, 0.0));
        let to = on_surface(&index, DVec3::new(56.0, 8.0, 0.0));
        let normal = (to.point - from.point).cross(DVec3::Z);
        assert_eq!(
            plane_section_path(&mesh, &topology, from, to, normal),
            Err(PathError::SectionMissesEnd)
        );
    }

    #[test]
    fn bad_planes_are_errors() {
        let mesh = grid(10, 10, 1.0);
        let topology = Topology::new(&mesh);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let from = on_surface(&index, DVec3::new(1.2, 1.7, 0.0));
        let to = on_surface(&index, DVec3::new(8.1, 6.3, 0.0));
        assert!(matches!(
            plane_section_path(&mesh, &topology, from, to, DVec3::ZERO),
            Err(PathError::InvalidPlaneNormal { .. })
        ));
        assert!(matches!(
            plane_section_path(&mesh, &topology, from, to, DVec3::new(f64::NAN, 0.0, 1.0)),
            Err(PathError::InvalidPlaneNormal { .. })
        ));
        // A plane through the start that misses the end by 1 mm.
        let normal = DVec3::new(0.0, 1.0, 0.0);
        assert!(matches!(
            plane_section_path(&mesh, &topology, from, to, normal),
            Err(PathError::EndOffPlane { distance_mm }) if (distance_mm - 4.6).abs() < 1e-9
        ));
        // The grid's own plane touches everything and crosses nothing.
        let (from, to) = (
            on_surface(&index, DVec3::new(1.2, 1.7, 0.0)),
            on_surface(&index, DVec3::new(1.2, 6.3, 0.0)),
        );
        assert_eq!(
            plane_section_path(&mesh, &topology, from, to, DVec3::Z),
            Err(PathError::NoSectionAtStart)
        );
        let other = grid(2, 2, 1.0);
        assert!(matches!(
            plane_section_path(&other, &topology, from, to, DVec3::X),
            Err(PathError::TopologyMismatch { .. })
        ));
    }
}
