//! On-surface paths: the point, path and error types they share, and exact shortest paths
//! on the triangulated surface (polyhedral geodesics).
//!
//! # Algorithm
//! [`GeodesicSolver::shortest_path`] is exact: it propagates "windows" from the start point
//! (Chen & Han 1990; Mitchell, Mount & Papadimitriou 1987). A window is an interval of an
//! edge together with the source it is seen from, unfolded into the plane: the start point,
//! or a vertex where shortest paths may bend (a saddle, whose angles sum to more than 2π,
//! or a border vertex). The straight lines from the source through the interval continue
//! into the next triangle and cover intervals of its two other edges, the window's
//! children. The search is kept small by three sound prunings, each dropping only points
//! that another path reaches strictly sooner:
//!
//! - a window is dropped when a vertex at an end of its edge, going along the edge,
//!   reaches all its points sooner (Xin & Wang 2009, "ICH");
//! - windows on the same edge are cut back to where each is the shorter (as in Surazhsky
//!   et al. 2005);
//! - a vertex sends windows only in the directions a shortest path can continue in, at
//!   least π from its arriving direction on both sides: a wedge of the angle excess.
//!
//! Windows are processed best first by a lower bound of the whole path through them
//! (distance so far plus Euclidean distance to the end point, as in A*), and the search
//! stops when no window can beat the best path found: it explores roughly the ellipse of
//! points whose distances to the two ends add up to at most the answer.
//!
//! A straight path through a vertex that is not a source (a flat one) bounds windows on
//! both sides of it and is carried on only by their ends: along a chain of edges, say, or
//! through a row of vertices of a regular grid, every later vertex and the end point lie
//! exactly on a window's end line, and round-off in the unfolded source decides whether
//! the window still sees them. So a window sees a vertex or the end point also within a
//! relative 1e-9 beyond its ends (the path then passes through that end: a surface path,
//! longer only by the square of the round-off); the exact comparison lost such paths and
//! with them every point only they reach, returning detours up to several percent longer.
//!
//! The result is the shortest path on the polyhedral surface up to round-off, a polyline
//! through source vertices and across edges with every segment inside one triangle. So
//! its length is at least the Euclidean distance and at most that of any other surface
//! path, a plane section in particular.
//!
//! Alternatives tried: a shortest path in a graph of vertices and edge points, straightened
//! by unfolding plus the funnel algorithm and re-routed around vertices (FlipOut, Sharp &
//! Crane 2020), is only locally shortest. On a noisy scan, where most vertices are saddles
//! that can pin a path, such local minima came out up to 0.9 % longer than the exact path
//! and longer than plane sections. The heat method's smoothed distances can fall below the
//! Euclidean distance or exceed a plane section.
//!
//! # Files
//! - `search.rs`: one query's window propagation ([`GeodesicSolver::shortest_path`]'s work).
//! - `window.rs`: windows, and how two on one edge trim each other.
//! - `scratch.rs`: the queue and the per-vertex and per-edge buffers a query reuses.

mod scratch;
mod search;
mod window;

use crate::spatial::{ClosestPoint, barycentric};
use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::TriMesh;
use glam::{DVec2, DVec3};
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::Triangle;
use scratch::Scratch;
use search::Search;
use std::f64::consts::{PI, TAU};
use std::sync::{Mutex, PoisonError};
use window::Parent;

/// Relative distance (of the triangle size) within which a given point counts as lying on
/// its triangle: generous for round-off, far below any scan's noise.
const ON_TRIANGLE_TOLERANCE: f64 = 1e-6;
/// Relative distance (of the triangle size) within which a path end counts as lying on a
/// vertex or edge, and so on every triangle sharing it.
const ON_EDGE_TOLERANCE: f64 = 1e-9;
/// Vertices whose angles sum to more than 2π plus this (radians) count as saddles, where
/// shortest paths may bend; also the slack (radians) on the directions they may leave in.
const FLAT_ANGLE_SLACK: f64 = 1e-9;

/// A point on a mesh triangle (mm), e.g. from [`crate::SurfaceIndex::closest_point`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Index of the triangle the point lies on.
    pub triangle: usize,
    /// The point (mm).
    pub point: DVec3,
}

impl From<ClosestPoint> for SurfacePoint {
    fn from(closest: ClosestPoint) -> SurfacePoint {
        SurfacePoint {
            triangle: closest.triangle,
            point: closest.point,
        }
    }
}

/// A polyline on the surface from a start to an end point: consecutive points lie on a
/// common triangle, so every segment runs on the surface.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfacePath {
    /// The polyline, from the start point to the end point (mm).
    pub points: Vec<DVec3>,
    /// Sum of the segment lengths (mm).
    pub length_mm: f64,
}

impl SurfacePath {
    pub(crate) fn from_points(points: Vec<DVec3>) -> SurfacePath {
        let length_mm = polyline_length(&points);
        SurfacePath { points, length_mm }
    }
}

/// Why no on-surface path could be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PathError {
    #[error(
        "the topology was built for a mesh with {topology_triangles} triangles, but this mesh has {mesh_triangles}"
    )]
    TopologyMismatch {
        topology_triangles: usize,
        mesh_triangles: usize,
    },
    #[error(
        "the {endpoint} point is on triangle {triangle}, but the mesh has only {triangle_count} triangles"
    )]
    TriangleOutOfRange {
        endpoint: &'static str,
        triangle: usize,
        triangle_count: usize,
    },
    #[error(
        "the {endpoint} point {point:?} does not lie on its triangle {triangle} ({distance_mm:.3} mm away)"
    )]
    NotOnTriangle {
        endpoint: &'static str,
        point: [f64; 3],
        triangle: usize,
        distance_mm: f64,
    },
    #[error("the section plane normal {normal:?} is zero or not finite")]
    InvalidPlaneNormal { normal: [f64; 3] },
    #[error("the end point lies {distance_mm:.3} mm off the section plane through the start point")]
    EndOffPlane { distance_mm: f64 },
    #[error(
        "the section plane only touches the surface at the start point; no intersection curve leaves it"
    )]
    NoSectionAtStart,
    #[error(
        "the section plane's intersection curve from the start point does not reach the end point (it leaves the scan at its border)"
    )]
    SectionLeavesMesh,
    #[error(
        "the section plane's intersection curve from the start point closes on itself without passing the end point"
    )]
    SectionMissesEnd,
    #[error("the section walk exceeded {steps} steps: the mesh connectivity is inconsistent")]
    WalkTooLong { steps: usize },
    #[error("the two points lie on different connected parts of the mesh")]
    DifferentComponents,
}

/// Exact shortest paths on one mesh. Built once per mesh in O(n); queries are independent
/// and may run in parallel (`Sync`). Per-mesh search buffers (about 24 bytes per vertex and
/// 8 per triangle edge) are pooled and reused, so a query allocates only what it explores.
pub struct GeodesicSolver<'a> {
    mesh: &'a TriMesh,
    topology: &'a Topology,
    /// Per vertex: whether shortest paths may bend at it (saddle or border vertex).
    may_bend: Vec<bool>,
    /// Connected part of each vertex (triangles sharing a vertex are connected).
    vertex_component: Vec<u32>,
    /// Search buffers of past queries, reused so a query allocates only what it visits.
    scratch_pool: Mutex<Vec<Scratch>>,
}

impl<'a> GeodesicSolver<'a> {
    /// Prepares the mesh. The mesh must be valid ([`TriMesh::validate`]) and `topology`
    /// built from it.
    pub fn new(mesh: &'a TriMesh, topology: &'a Topology) -> Result<GeodesicSolver<'a>, PathError> {
        check_topology(mesh, topology)?;
        let mut angle_sum = vec![0.0; mesh.positions.len()];
        let mut may_bend = vec![false; mesh.positions.len()];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let corners = mesh.triangle_positions(t);
            for i in 0..3 {
                let (here, next, previous) =
                    (corners[i], corners[(i + 1) % 3], corners[(i + 2) % 3]);
                angle_sum[tri[i] as usize] += angle(next - here, previous - here);
                if topology.triangle_neighbors[t][i] == NO_TRIANGLE {
                    may_bend[tri[i] as usize] = true;
                    may_bend[tri[(i + 1) % 3] as usize] = true;
                }
            }
        }
        for (may_bend, sum) in may_bend.iter_mut().zip(angle_sum) {
            *may_bend |= sum > TAU + FLAT_ANGLE_SLACK;
        }
        Ok(GeodesicSolver {
            mesh,
            topology,
            may_bend,
            vertex_component: vertex_components(mesh),
            scratch_pool: Mutex::new(Vec::new()),
        })
    }

    /// The shortest path on the surface from `from` to `to` (see the module doc).
    pub fn shortest_path(
        &self,
        from: SurfacePoint,
        to: SurfacePoint,
    ) -> Result<SurfacePath, PathError> {
        check_endpoint(self.mesh, from, "start")?;
        check_endpoint(self.mesh, to, "end")?;
        let component =
            |p: SurfacePoint| self.vertex_component[self.mesh.triangles[p.triangle][0] as usize];
        if component(from) != component(to) {
            return Err(PathError::DifferentComponents);
        }
        let start = locate(self.mesh, self.topology, from);
        let end = locate(self.mesh, self.topology, to);
        if start.shares_triangle(&end) {
            // On a common triangle the straight segment is the shortest path.
            return Ok(SurfacePath::from_points(vec![from.point, to.point]));
        }
        let points = self.with_scratch(|scratch| {
            let mut search = Search {
                solver: self,
                scratch,
                start: &start,
                end: &end,
                best: (f64::INFINITY, Parent::Start),
            };
            search.run()
        });
        points
            .map(SurfacePath::from_points)
            .ok_or(PathError::DifferentComponents)
    }

    fn with_scratch<R>(&self, search: impl FnOnce(&mut Scratch) -> R) -> R {
        let pooled = self
            .scratch_pool
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .pop();
        let mut scratch = pooled
            .unwrap_or_else(|| Scratch::new(self.mesh.positions.len(), self.mesh.triangles.len()));
        let result = search(&mut scratch);
        self.scratch_pool
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .push(scratch);
        result
    }

    /// The triangles around vertex `v` in rotational order, `None` unless they form one
    /// fan (a disk, or a half-disk at the border).
    fn fan(&self, v: u32) -> Option<Fan> {
        let incident = self.topology.vertex_triangles(v as usize);
        let first = *incident.first()?;
        // The next triangle round, entered across the edge to the current one's second spoke.
        let step = |(t, reversed): (u32, bool)| -> Option<(u32, bool)> {
            let tri = self.mesh.triangles[t as usize];
            let i = tri.iter().position(|&c| c == v)?;
            let (k, spoke) = if reversed {
                (i, tri[(i + 1) % 3])
            } else {
                ((i + 2) % 3, tri[(i + 2) % 3])
            };
            let next = self.topology.triangle_neighbors[t as usize][k];
            if next == NO_TRIANGLE {
                return None;
            }
            let next_tri = self.mesh.triangles[next as usize];
            let j = next_tri.iter().position(|&c| c == v)?;
            if next_tri[(j + 1) % 3] == spoke {
                Some((next, false))
            } else {
                (next_tri[(j + 2) % 3] == spoke).then_some((next, true))
            }
        };
        let walk = |from: (u32, bool)| {
            let mut order = vec![from];
            let mut current = from;
            while let Some(next) = step(current) {
                if next.0 == first || order.len() > incident.len() {
                    return (order, next.0 == first);
                }
                order.push(next);
                current = next;
            }
            (order, false)
        };
        let (forward, closed) = walk((first, false));
        let order: Vec<(u32, bool)> = if closed {
            forward
        } else {
            let (backward, _) = walk((first, true));
            backward
                .iter()
                .skip(1)
                .rev()
                .map(|&(t, reversed)| (t, !reversed))
                .chain(forward)
                .collect()
        };
        if order.len() != incident.len() {
            return None;
        }
        let mut triangles = Vec::with_capacity(order.len());
        let mut total = 0.0;
        for (triangle, reversed) in order {
            let tri = self.mesh.triangles[triangle as usize];
            let corner = tri.iter().position(|&c| c == v)?;
            let [here, next, previous] =
                [0, 1, 2].map(|j| self.mesh.positions[tri[(corner + j) % 3] as usize]);
            let angle = angle(next - here, previous - here);
            triangles.push(FanTriangle {
                triangle,
                corner,
                reversed,
                start: total,
                angle,
            });
            total += angle;
        }
        Some(Fan {
            triangles,
            total,
            closed,
        })
    }

    /// Triangle `t` laid flat with its edge `k` on the x axis.
    fn frame(&self, t: u32, k: usize) -> Frame {
        let tri = self.mesh.triangles[t as usize];
        let corners = [tri[k], tri[(k + 1) % 3], tri[(k + 2) % 3]];
        let [a, b, c] = corners.map(|v| self.mesh.positions[v as usize]);
        let length = a.distance(b);
        let along = (c - a).dot(b - a) / length;
        let height = (c - a).cross(b - a).length() / length;
        Frame {
            corners,
            positions: [a, b, c],
            flat: [
                DVec2::ZERO,
                DVec2::new(length, 0.0),
                DVec2::new(along, height),
            ],
        }
    }
}

/// Where a path end lies: on a vertex (then on all its triangles), on an edge (then on
/// both its triangles) or inside its triangle.
pub(crate) fn locate(mesh: &TriMesh, topology: &Topology, end: SurfacePoint) -> Location {
    let corners = mesh.triangles[end.triangle];
    let positions = mesh.triangle_positions(end.triangle);
    let size = (0..3)
        .map(|i| positions[i].distance(positions[(i + 1) % 3]))
        .fold(0.0, f64::max);
    let tolerance = ON_EDGE_TOLERANCE * size;
    let vertex = (0..3)
        .find(|&i| positions[i].distance(end.point) <= tolerance)
        .map(|i| corners[i]);
    let triangles = match vertex {
        Some(v) => topology.vertex_triangles(v as usize).to_vec(),
        None => std::iter::once(end.triangle as u32)
            .chain((0..3).filter_map(|k| {
                let neighbor = topology.triangle_neighbors[end.triangle][k];
                let on_edge = distance_to_segment(end.point, positions[k], positions[(k + 1) % 3])
                    <= tolerance;
                (on_edge && neighbor != NO_TRIANGLE).then_some(neighbor)
            }))
            .collect(),
    };
    Location {
        point: end.point,
        vertex,
        triangles,
    }
}

/// Checks that `topology` has one entry per triangle of `mesh`.
pub(crate) fn check_topology(mesh: &TriMesh, topology: &Topology) -> Result<(), PathError> {
    match topology.mismatch(mesh) {
        None => Ok(()),
        Some((topology_triangles, mesh_triangles)) => Err(PathError::TopologyMismatch {
            topology_triangles,
            mesh_triangles,
        }),
    }
}

/// Checks that a path end names an existing triangle and lies on it.
pub(crate) fn check_endpoint(
    mesh: &TriMesh,
    end: SurfacePoint,
    endpoint: &'static str,
) -> Result<(), PathError> {
    if end.triangle >= mesh.triangles.len() {
        return Err(PathError::TriangleOutOfRange {
            endpoint,
            triangle: end.triangle,
            triangle_count: mesh.triangles.len(),
        });
    }
    let [a, b, c] = mesh.triangle_positions(end.triangle);
    let distance_mm = if end.point.is_finite() {
        Triangle::new(a, b, c).distance_to_local_point(end.point, true)
    } else {
        f64::INFINITY
    };
    let size = a.distance(b).max(b.distance(c)).max(c.distance(a));
    if distance_mm <= ON_TRIANGLE_TOLERANCE * size {
        Ok(())
    } else {
        Err(PathError::NotOnTriangle {
            endpoint,
            point: end.point.to_array(),
            triangle: end.triangle,
            distance_mm,
        })
    }
}

/// Index `k` of the edge of `triangle` joining vertices `a` and `b` (either direction).
pub(crate) fn edge_index(triangle: [u32; 3], a: u32, b: u32) -> Option<usize> {
    (0..3).find(|&k| {
        let (u, v) = (triangle[k], triangle[(k + 1) % 3]);
        (u == a && v == b) || (u == b && v == a)
    })
}

/// Distance from `point` to the segment from `a` to `b` (mm).
pub(crate) fn distance_to_segment(point: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let t = ab.dot(point - a) / ab.length_squared();
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    point.distance(a + ab * t)
}

/// Appends `point` unless it repeats the last one.
pub(crate) fn push_distinct(points: &mut Vec<DVec3>, point: DVec3) {
    if points.last() != Some(&point) {
        points.push(point);
    }
}

fn polyline_length(points: &[DVec3]) -> f64 {
    points.windows(2).map(|w| w[0].distance(w[1])).sum()
}

/// Unsigned angle between two vectors (radians), zero if either is zero.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// Connected part of every vertex through shared triangles (union-find), as the root
/// vertex index.
fn vertex_components(mesh: &TriMesh) -> Vec<u32> {
    fn root(parent: &mut [u32], mut v: u32) -> u32 {
        while parent[v as usize] != v {
            let grandparent = parent[parent[v as usize] as usize];
            parent[v as usize] = grandparent;
            v = grandparent;
        }
        v
    }
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    for &[a, b, c] in &mesh.triangles {
        let ra = root(&mut parent, a);
        for v in [b, c] {
            let rv = root(&mut parent, v);
            parent[rv as usize] = ra;
        }
    }
    (0..parent.len() as u32)
        .map(|v| root(&mut parent, v))
        .collect()
}

/// The triangles around a vertex in rotational order, with their angles at the vertex:
/// a direction from the vertex has a coordinate from 0 to `total` (radians) round it.
struct Fan {
    triangles: Vec<FanTriangle>,
    /// Sum of the angles (2π for a flat interior vertex, more for a saddle).
    total: f64,
    /// Whether the fan closes round the vertex (no border).
    closed: bool,
}

/// A triangle of a [`Fan`].
struct FanTriangle {
    triangle: u32,
    /// Index of the fan's vertex among the triangle's corners.
    corner: usize,
    /// Whether the fan passes the triangle from its corner `corner + 2` to `corner + 1`
    /// (against the triangle's own orientation).
    reversed: bool,
    /// Direction coordinate where the triangle begins, and its angle at the vertex.
    start: f64,
    angle: f64,
}

impl Fan {
    /// Direction coordinate of the point `toward` on triangle `t` seen from vertex `v`.
    fn angle_of(&self, mesh: &TriMesh, v: u32, t: u32, toward: DVec3) -> Option<f64> {
        let part = self.triangles.iter().find(|p| p.triangle == t)?;
        let tri = mesh.triangles[t as usize];
        let first_spoke = tri[(part.corner + if part.reversed { 2 } else { 1 }) % 3];
        let here = mesh.positions[v as usize];
        let within = angle(mesh.positions[first_spoke as usize] - here, toward - here);
        Some(part.start + within.min(part.angle))
    }

    /// Direction intervals in which a shortest path arriving from direction `back` may
    /// continue: at least π away on each side (with a little slack for round-off).
    fn continuations(&self, back: f64) -> Vec<(f64, f64)> {
        let slack = FLAT_ANGLE_SLACK;
        if !self.closed {
            return [(0.0, back - PI + slack), (back + PI - slack, self.total)]
                .into_iter()
                .filter(|(low, high)| low <= high)
                .collect();
        }
        let width = self.total - 2.0 * PI + 2.0 * slack;
        if width < 0.0 {
            return Vec::new();
        }
        let low = (back + PI - slack).rem_euclid(self.total);
        let high = low + width;
        if high <= self.total {
            vec![(low, high)]
        } else {
            vec![(low, self.total), (0.0, high - self.total)]
        }
    }
}

/// A path end and the triangles it lies on.
pub(crate) struct Location {
    point: DVec3,
    /// The vertex it lies on, if any.
    vertex: Option<u32>,
    triangles: Vec<u32>,
}

impl Location {
    /// Whether the two points lie on a common triangle (then the straight segment between
    /// them runs on the surface).
    pub(crate) fn shares_triangle(&self, other: &Location) -> bool {
        self.triangles.iter().any(|t| other.triangles.contains(t))
    }
}

/// A triangle laid flat: its corners (from the chosen edge on), their positions, and
/// their flat coordinates with the edge along the x axis from the origin and the third
/// corner above it.
struct Frame {
    corners: [u32; 3],
    positions: [DVec3; 3],
    flat: [DVec2; 3],
}

impl Frame {
    /// Flat coordinates of a point on the triangle.
    fn flatten(&self, point: DVec3) -> DVec2 {
        let weights = barycentric(point, self.positions);
        (0..3).map(|i| self.flat[i] * weights[i]).sum()
    }
}

#[cfg(test)]
pub(crate) mod tests;
