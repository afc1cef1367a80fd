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

use crate::spatial::{ClosestPoint, barycentric};
use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::TriMesh;
use glam::{DVec2, DVec3};
use parry3d_f64::query::PointQuery;
use parry3d_f64::shape::Triangle;
use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::{PI, TAU};
use std::sync::{Mutex, PoisonError};

/// Relative distance (of the triangle size) within which a given point counts as lying on
/// its triangle: generous for round-off, far below any scan's noise.
const ON_TRIANGLE_TOLERANCE: f64 = 1e-6;
/// Relative distance (of the triangle size) within which a path end counts as lying on a
/// vertex or edge, and so on every triangle sharing it.
const ON_EDGE_TOLERANCE: f64 = 1e-9;
/// Vertices whose angles sum to more than 2π plus this (radians) count as saddles, where
/// shortest paths may bend; also the slack (radians) on the directions they may leave in.
const FLAT_ANGLE_SLACK: f64 = 1e-9;
/// A window is cut back only where another reaches its points shorter by more than this
/// fraction, so round-off never cuts away a shortest path.
const TRIM_TOLERANCE: f64 = 1e-12;

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

/// One shortest-path query: the window propagation from the start to the end point.
struct Search<'q, 'a> {
    solver: &'q GeodesicSolver<'a>,
    scratch: &'q mut Scratch,
    start: &'q Location,
    end: &'q Location,
    /// Length of the best path to the end point found so far and where it comes from.
    best: (f64, Parent),
}

impl Search<'_, '_> {
    /// Propagates until no window can improve the best path; the path, if the end was reached.
    fn run(&mut self) -> Option<Vec<DVec3>> {
        self.scratch.begin();
        self.seed();
        while let Some(Event { key, item }) = self.scratch.queue.pop() {
            if key >= self.best.0 {
                break;
            }
            match item {
                Item::Vertex { vertex, distance } => {
                    if distance <= self.scratch.distance(vertex) {
                        self.emit_from_vertex(vertex, distance);
                    }
                }
                Item::Window(index) => {
                    let window = self.scratch.windows[index as usize];
                    if window.is_alive() && !self.dominated(&window) {
                        self.scratch.windows[index as usize].carried = true;
                        self.propagate(index, &window);
                    }
                }
            }
        }
        self.best.0.is_finite().then(|| self.backtrack())
    }

    /// Windows from the start point: from its vertex, or across the edges of its triangles.
    fn seed(&mut self) {
        let start = self.start;
        if let Some(vertex) = start.vertex {
            // A source in every direction, whatever the vertex.
            self.reach_vertex(vertex, 0.0, Parent::Start);
            if !self.solver.may_bend[vertex as usize] {
                self.push_vertex(vertex, 0.0);
            }
            return;
        }
        for &t in &start.triangles {
            let frame = self.solver.frame(t, 0);
            let source = frame.flatten(start.point);
            for i in 0..3 {
                self.reach_vertex(
                    frame.corners[i],
                    start.point.distance(frame.positions[i]),
                    Parent::Start,
                );
            }
            for k in 0..3 {
                let ends = [frame.flat[k], frame.flat[(k + 1) % 3]];
                let from_start = Source {
                    flat: source,
                    sigma: 0.0,
                    parent: Parent::Start,
                };
                if let Some(window) = self.window_across(&frame, (t, k), ends, from_start) {
                    self.push_window(window);
                }
            }
        }
    }

    /// Windows from a vertex source across the far edges of its triangles, within the
    /// directions a shortest path can leave it in: at least π from the direction it
    /// arrived from on either side (all directions from the start point).
    fn emit_from_vertex(&mut self, vertex: u32, distance: f64) {
        let solver = self.solver;
        let Some(fan) = solver.fan(vertex) else {
            return self.emit_all_around(vertex, distance);
        };
        let arrival = match self.scratch.parent(vertex) {
            Parent::Start if self.start.vertex == Some(vertex) => None,
            Parent::Start => self
                .start
                .triangles
                .iter()
                .find(|&&t| solver.mesh.triangles[t as usize].contains(&vertex))
                .map(|&t| (t, self.start.point)),
            Parent::Vertex(from) => fan
                .triangles
                .iter()
                .find(|f| solver.mesh.triangles[f.triangle as usize].contains(&from))
                .map(|f| (f.triangle, solver.mesh.positions[from as usize])),
            Parent::Window(index) => {
                let window = self.scratch.windows[index as usize];
                let frame = solver.frame(window.triangle, window.edge);
                // Where the path through the window crossed its edge.
                let cut = edge_crossing(window.source, frame.flat[2]);
                let x = cut.max(window.start).min(window.end) / frame.flat[1].x;
                Some((
                    window.triangle,
                    frame.positions[0].lerp(frame.positions[1], x),
                ))
            }
        };
        let allowed = match arrival {
            None => vec![(0.0, fan.total)],
            Some((t, from)) => match fan.angle_of(solver.mesh, vertex, t, from) {
                Some(back) => fan.continuations(back),
                None => vec![(0.0, fan.total)],
            },
        };
        let from_vertex = Source {
            flat: DVec2::ZERO,
            sigma: distance,
            parent: Parent::Vertex(vertex),
        };
        let within = |angle: f64| {
            allowed
                .iter()
                .any(|&(low, high)| (low..=high).contains(&angle))
        };
        for part in &fan.triangles {
            // Straight along the triangle's edges, if those are directions to leave in.
            let frame = solver.frame(part.triangle, part.corner);
            let (first, second) = if part.reversed { (2, 1) } else { (1, 2) };
            for (j, angle) in [(first, part.start), (second, part.start + part.angle)] {
                if within(angle) {
                    self.reach_vertex(
                        frame.corners[j],
                        distance + frame.flat[j].length(),
                        Parent::Vertex(vertex),
                    );
                }
            }
            for &(low, high) in &allowed {
                let (a, b) = (low.max(part.start), high.min(part.start + part.angle));
                if a > b {
                    continue;
                }
                let (a, b) = (a - part.start, b - part.start);
                let (a, b) = if part.reversed {
                    (part.angle - b, part.angle - a)
                } else {
                    (a, b)
                };
                let far = |angle: f64| {
                    let direction = DVec2::from_angle(angle);
                    line_intersection(DVec2::ZERO, direction, frame.flat[1], frame.flat[2])
                };
                let far_edge = (part.corner + 1) % 3;
                let ends = [far(a), far(b)];
                if let Some(window) =
                    self.window_across(&frame, (part.triangle, far_edge), ends, from_vertex)
                {
                    self.push_window(window);
                }
            }
        }
    }

    /// Windows from a vertex source across the far edge of each of its triangles (for a
    /// vertex whose triangles do not form one fan).
    fn emit_all_around(&mut self, vertex: u32, distance: f64) {
        let solver = self.solver;
        for &t in solver.topology.vertex_triangles(vertex as usize) {
            let corners = solver.mesh.triangles[t as usize];
            let Some(i) = corners.iter().position(|&c| c == vertex) else {
                continue;
            };
            let frame = solver.frame(t, i);
            for j in 1..3 {
                self.reach_vertex(
                    frame.corners[j],
                    distance + frame.flat[j].length(),
                    Parent::Vertex(vertex),
                );
            }
            let ends = [frame.flat[1], frame.flat[2]];
            let from_vertex = Source {
                flat: DVec2::ZERO,
                sigma: distance,
                parent: Parent::Vertex(vertex),
            };
            if let Some(window) = self.window_across(&frame, (t, (i + 1) % 3), ends, from_vertex) {
                self.push_window(window);
            }
        }
    }

    /// Carries window `index` across its triangle: the far corner if it sees it, the end
    /// point if there, and the child windows on the two far edges.
    fn propagate(&mut self, index: u32, window: &Window) {
        let frame = self.solver.frame(window.triangle, window.edge);
        let (source, sigma) = (window.source, window.sigma);
        let apex = frame.flat[2];
        // Where the line from the source through the far corner crosses the window's edge.
        let apex_cut = edge_crossing(source, apex);
        if let Some(length) = window.length_to(apex, apex_cut, frame.flat[1].x) {
            self.reach_vertex(frame.corners[2], length, Parent::Window(index));
        }
        if self.end.triangles.contains(&window.triangle) {
            let end = frame.flatten(self.end.point);
            let length = window.length_to(end, edge_crossing(source, end), frame.flat[1].x);
            if let Some(length) = length.filter(|&length| length < self.best.0) {
                self.best = (length, Parent::Window(index));
            }
        }
        // Where the lines through the window's ends meet the far edges.
        let through = |x: f64, from: DVec2, to: DVec2| {
            line_intersection(source, DVec2::new(x, 0.0), from, to)
        };
        let [origin, corner, _] = frame.flat;
        let seen = Source {
            flat: source,
            sigma,
            parent: Parent::Window(index),
        };
        if window.start < apex_cut {
            // Edge k + 2, from the far corner back to the window edge's start.
            let near = through(window.start, apex, origin);
            let far = if window.end < apex_cut {
                through(window.end, apex, origin)
            } else {
                apex
            };
            let k = (window.edge + 2) % 3;
            if let Some(child) = self.window_across(&frame, (window.triangle, k), [near, far], seen)
            {
                self.push_window(child);
            }
        }
        if window.end > apex_cut {
            // Edge k + 1, from the window edge's end to the far corner.
            let near = if window.start > apex_cut {
                through(window.start, corner, apex)
            } else {
                apex
            };
            let far = through(window.end, corner, apex);
            let k = (window.edge + 1) % 3;
            if let Some(child) = self.window_across(&frame, (window.triangle, k), [near, far], seen)
            {
                self.push_window(child);
            }
        }
    }

    /// The window on edge `k` of triangle `t` (laid flat in `frame`) between the points
    /// `ends`, seen from `source`, as it enters the triangle across that edge; `None` at the
    /// border or if empty.
    fn window_across(
        &self,
        frame: &Frame,
        (t, k): (u32, usize),
        ends: [DVec2; 2],
        source: Source,
    ) -> Option<Window> {
        let mesh = self.solver.mesh;
        let tri = mesh.triangles[t as usize];
        let next = self.solver.topology.triangle_neighbors[t as usize][k];
        if next == NO_TRIANGLE {
            return None;
        }
        let next_corners = mesh.triangles[next as usize];
        let edge = edge_index(next_corners, tri[k], tri[(k + 1) % 3])?;
        let flat = |v: u32| Some(frame.flat[frame.corners.iter().position(|&c| c == v)?]);
        let origin = flat(next_corners[edge])?;
        let toward = flat(next_corners[(edge + 1) % 3])?;
        let off_edge = flat(tri[(k + 2) % 3])?;
        let length = origin.distance(toward);
        let x_axis = (toward - origin) / length;
        let mut y_axis = x_axis.perp();
        if y_axis.dot(off_edge - origin) > 0.0 {
            y_axis = -y_axis;
        }
        let local = |p: DVec2| DVec2::new((p - origin).dot(x_axis), (p - origin).dot(y_axis));
        let (a, b) = (local(ends[0]).x, local(ends[1]).x);
        let window = Window {
            triangle: next,
            edge,
            start: a.min(b).max(0.0),
            end: a.max(b).min(length),
            source: local(source.flat),
            sigma: source.sigma,
            parent: source.parent,
            next_on_edge: None,
            carried: false,
        };
        // The source must lie strictly behind the edge; one on its line only grazes it.
        let proper = window.end > window.start && window.source.y < -ON_EDGE_TOLERANCE * length;
        proper.then_some(window)
    }

    /// Queues a window, first cut back to the part not reached sooner through the windows
    /// already on its edge, and cuts those not yet carried on back in turn.
    fn push_window(&mut self, mut window: Window) {
        let slot = 3 * window.triangle as usize + window.edge;
        let mut other = self.scratch.first_on_edge(slot);
        while let Some(index) = other {
            let existing = &self.scratch.windows[index as usize];
            if existing.is_alive() {
                let Some((start, end)) = trimmed(&window, existing) else {
                    return;
                };
                (window.start, window.end) = (start, end);
            }
            other = existing.next_on_edge;
        }
        let mesh = self.solver.mesh;
        let tri = mesh.triangles[window.triangle as usize];
        let (a, b) = (
            mesh.positions[tri[window.edge] as usize],
            mesh.positions[tri[(window.edge + 1) % 3] as usize],
        );
        let length = a.distance(b);
        let nearest = DVec2::new(window.source.x.clamp(window.start, window.end), 0.0);
        let key = window.sigma
            + window.source.distance(nearest)
            + distance_to_segment(
                self.end.point,
                a.lerp(b, window.start / length),
                a.lerp(b, window.end / length),
            );
        let useful = key < self.best.0 && !self.dominated(&window);
        if !useful {
            return;
        }
        let mut other = self.scratch.first_on_edge(slot);
        while let Some(index) = other {
            let existing = &mut self.scratch.windows[index as usize];
            if existing.is_alive() && !existing.carried {
                match trimmed(existing, &window) {
                    Some((start, end)) => (existing.start, existing.end) = (start, end),
                    None => existing.end = existing.start,
                }
            }
            other = existing.next_on_edge;
        }
        window.next_on_edge = self.scratch.first_on_edge(slot);
        let index = self.scratch.windows.len() as u32;
        self.scratch.windows.push(window);
        self.scratch.set_first_on_edge(slot, index);
        self.scratch.queue.push(Event {
            key,
            item: Item::Window(index),
        });
    }

    /// Whether an end vertex of the window's edge reaches every point of the window
    /// sooner than the window does (then no shortest path needs it).
    fn dominated(&self, window: &Window) -> bool {
        let tri = self.solver.mesh.triangles[window.triangle as usize];
        let (first, second) = (tri[window.edge], tri[(window.edge + 1) % 3]);
        let length = self.solver.mesh.positions[first as usize]
            .distance(self.solver.mesh.positions[second as usize]);
        // Along the edge from its first vertex to the window's far end, and from the
        // second vertex to the near end: the triangle inequality covers the points between.
        self.scratch.distance(first) + window.end < window.distance_at(window.end)
            || self.scratch.distance(second) + (length - window.start)
                < window.distance_at(window.start)
    }

    /// Records a path of length `distance` to `vertex`; a shorter one makes the vertex a
    /// source (if paths may pass it) and may give a shorter path to the end point.
    fn reach_vertex(&mut self, vertex: u32, distance: f64, parent: Parent) {
        let shorter = distance < self.scratch.distance(vertex);
        if !shorter {
            return;
        }
        self.scratch.set_distance(vertex, distance, parent);
        if self.solver.may_bend[vertex as usize] {
            self.push_vertex(vertex, distance);
        }
        let end = self.end;
        let on_end_triangle = end
            .triangles
            .iter()
            .any(|&t| self.solver.mesh.triangles[t as usize].contains(&vertex));
        if on_end_triangle {
            let length = distance + self.solver.mesh.positions[vertex as usize].distance(end.point);
            if length < self.best.0 {
                self.best = (length, Parent::Vertex(vertex));
            }
        }
    }

    fn push_vertex(&mut self, vertex: u32, distance: f64) {
        let key = distance + self.solver.mesh.positions[vertex as usize].distance(self.end.point);
        self.scratch.queue.push(Event {
            key,
            item: Item::Vertex { vertex, distance },
        });
    }

    /// The best path, followed back from the end point through windows and vertex sources.
    fn backtrack(&self) -> Vec<DVec3> {
        let mesh = self.solver.mesh;
        let mut points = vec![self.end.point];
        let mut current = self.end.point;
        let mut via = self.best.1;
        // Every step goes to an earlier window or a nearer vertex; the bound only guards
        // against round-off cycles.
        for _ in 0..=self.scratch.windows.len() + mesh.positions.len() {
            match via {
                Parent::Start => break,
                Parent::Vertex(vertex) => {
                    current = mesh.positions[vertex as usize];
                    via = self.scratch.parent(vertex);
                }
                Parent::Window(index) => {
                    let window = self.scratch.windows[index as usize];
                    let frame = self.solver.frame(window.triangle, window.edge);
                    let x = edge_crossing(window.source, frame.flatten(current))
                        .clamp(window.start, window.end);
                    current = frame.positions[0].lerp(frame.positions[1], x / frame.flat[1].x);
                    via = window.parent;
                }
            }
            push_distinct(&mut points, current);
        }
        push_distinct(&mut points, self.start.point);
        points.reverse();
        points
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
    if topology.triangle_neighbors.len() == mesh.triangles.len() {
        Ok(())
    } else {
        Err(PathError::TopologyMismatch {
            topology_triangles: topology.triangle_neighbors.len(),
            mesh_triangles: mesh.triangles.len(),
        })
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

/// Where the line from `source` (behind the x axis) through `point` crosses the x axis;
/// a point on the axis is its own crossing.
fn edge_crossing(source: DVec2, point: DVec2) -> f64 {
    if point.y <= 0.0 {
        return point.x;
    }
    source.x + (point.x - source.x) * (-source.y) / (point.y - source.y)
}

/// Where the line through `a` and `b` meets the segment from `from` to `to` (clamped).
fn line_intersection(a: DVec2, b: DVec2, from: DVec2, to: DVec2) -> DVec2 {
    let (direction, segment) = (b - a, to - from);
    let t = (a - from).perp_dot(direction) / segment.perp_dot(direction);
    from + segment
        * if t.is_finite() {
            t.clamp(0.0, 1.0)
        } else {
            0.0
        }
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

/// A window's source: where it lies in the flat frame the window is made in, its distance
/// from the start point (mm), and how that was reached.
#[derive(Debug, Clone, Copy)]
struct Source {
    flat: DVec2,
    sigma: f64,
    parent: Parent,
}

/// Where a distance comes from.
#[derive(Debug, Clone, Copy)]
enum Parent {
    /// Straight from the start point.
    Start,
    /// Through a window (index into the query's windows).
    Window(u32),
    /// Straight from a vertex.
    Vertex(u32),
}

/// An interval of an edge seen from a source: every point `x` of it is reached by the
/// straight line from the source, at distance `sigma + |source - x|` from the start.
#[derive(Debug, Clone, Copy)]
struct Window {
    /// The triangle the window looks into and the index of its edge the window lies on.
    triangle: u32,
    edge: usize,
    /// The interval, as distances along the edge from its first corner (mm).
    start: f64,
    end: f64,
    /// The source, unfolded into the plane of the triangle with the edge along the x
    /// axis from the origin and the triangle above (so the source has y < 0).
    source: DVec2,
    /// Distance from the start point to the source (mm).
    sigma: f64,
    /// How the source was reached.
    parent: Parent,
    /// The window queued before it on the same edge (towards the same triangle).
    next_on_edge: Option<u32>,
    /// Whether it has been carried across its triangle (its interval is then fixed: its
    /// children and paths refer to it).
    carried: bool,
}

impl Window {
    /// Distance from the start point to the point `x` of the window's edge through it.
    fn distance_at(&self, x: f64) -> f64 {
        self.sigma + self.source.distance(DVec2::new(x, 0.0))
    }

    /// Length of the path from the start point through the window to `point`, a point of
    /// its triangle (flat coordinates) whose line from the source crosses the window's
    /// edge (of length `length`) at `cut`; `None` unless the window sees the point.
    ///
    /// A straight path through a vertex bounds the windows on either side of it, so
    /// where it goes on (past more vertices, along a chain of edges, say) the crossing
    /// lands on a window's end only up to round-off in the unfolded source. A crossing
    /// that far beyond an end (`ON_EDGE_TOLERANCE` of the frame's size) still counts, the
    /// path then running through that end: a surface path, so never too short, and longer
    /// only by the square of the round-off.
    fn length_to(&self, point: DVec2, cut: f64, length: f64) -> Option<f64> {
        if (self.start..=self.end).contains(&cut) {
            return Some(self.sigma + self.source.distance(point));
        }
        let slack = ON_EDGE_TOLERANCE * (length + self.source.length());
        let via = DVec2::new(cut.max(self.start).min(self.end), 0.0);
        (via.x - slack <= cut && cut <= via.x + slack)
            .then(|| self.sigma + self.source.distance(via) + via.distance(point))
    }

    /// Whether anything is left of it after trimming.
    fn is_alive(&self) -> bool {
        self.end > self.start
    }
}

/// The part of `keep`'s interval not reached sooner through `by`, two windows on the same
/// edge towards the same triangle: the hull of what is left, `None` if nothing is.
fn trimmed(keep: &Window, by: &Window) -> Option<(f64, f64)> {
    let (low, high) = (keep.start.max(by.start), keep.end.min(by.end));
    if low >= high {
        return Some((keep.start, keep.end));
    }
    // Where the two distance functions are equal: sigma_b + |s_b - x| = sigma_k + |s_k - x|
    // squared twice gives a quadratic in x (possibly with spurious roots, harmless here).
    let (sk, sb) = (keep.source, by.source);
    let d = keep.sigma - by.sigma;
    let p = 2.0 * (sk.x - sb.x);
    let q = sb.length_squared() - sk.length_squared() - d * d;
    let (a, b, c) = (
        p * p - 4.0 * d * d,
        2.0 * p * q + 8.0 * d * d * sk.x,
        q * q - 4.0 * d * d * sk.length_squared(),
    );
    let mut cuts = [low, high, high, high];
    if a.abs() > 1e-12 * (p * p + 4.0 * d * d) {
        let discriminant = b * b - 4.0 * a * c;
        if discriminant >= 0.0 {
            let root = discriminant.sqrt();
            cuts[2] = (-b - root) / (2.0 * a);
            cuts[3] = (-b + root) / (2.0 * a);
        }
    } else if b != 0.0 {
        cuts[2] = -c / b;
    }
    for cut in &mut cuts[2..] {
        if !(low < *cut && *cut < high) {
            *cut = high;
        }
    }
    cuts.sort_by(f64::total_cmp);
    // Keep what lies outside `by`'s interval and the pieces where `by` is not shorter
    // throughout (checked at both ends too, in case round-off hid a crossing).
    let by_shorter = |x: f64, margin: f64| {
        let kept = keep.distance_at(x);
        by.distance_at(x) < kept + margin * kept
    };
    let mut kept: Option<(f64, f64)> = None;
    let mut keep_piece = |from: f64, to: f64| {
        kept = Some(kept.map_or((from, to), |(a, b)| (a.min(from), b.max(to))));
    };
    if keep.start < low {
        keep_piece(keep.start, low);
    }
    if high < keep.end {
        keep_piece(high, keep.end);
    }
    for piece in cuts.windows(2) {
        let cut = by_shorter(0.5 * (piece[0] + piece[1]), -TRIM_TOLERANCE)
            && by_shorter(piece[0], TRIM_TOLERANCE)
            && by_shorter(piece[1], TRIM_TOLERANCE);
        if piece[0] < piece[1] && !cut {
            keep_piece(piece[0], piece[1]);
        }
    }
    kept
}

/// What the queue holds: a window to carry on, or a vertex to emit windows from.
#[derive(Debug, Clone, Copy)]
enum Item {
    Window(u32),
    Vertex { vertex: u32, distance: f64 },
}

/// A queue entry, smallest key (lower bound of the path length through it) first.
#[derive(Debug, Clone, Copy)]
struct Event {
    key: f64,
    item: Item,
}

impl PartialEq for Event {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Event {}

impl PartialOrd for Event {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Event {
    fn cmp(&self, other: &Self) -> Ordering {
        other.key.total_cmp(&self.key)
    }
}

/// Per-query state. Entries per vertex and per triangle edge are valid when stamped with
/// the current generation, so a query touches only what it reaches; each entry keeps its
/// fields together (one cache line per look-up).
struct Scratch {
    generation: u32,
    vertices: Vec<VertexState>,
    /// Per edge of each triangle (`3 t + k`): generation stamp and the last window queued
    /// on it.
    last_on_edge: Vec<(u32, u32)>,
    windows: Vec<Window>,
    queue: BinaryHeap<Event>,
}

/// The shortest distance found to a vertex (mm) and where it comes from.
#[derive(Debug, Clone, Copy)]
struct VertexState {
    stamp: u32,
    parent: Parent,
    distance: f64,
}

impl Scratch {
    fn new(vertex_count: usize, triangle_count: usize) -> Scratch {
        let unreached = VertexState {
            stamp: 0,
            parent: Parent::Start,
            distance: f64::INFINITY,
        };
        Scratch {
            generation: 0,
            vertices: vec![unreached; vertex_count],
            last_on_edge: vec![(0, 0); 3 * triangle_count],
            windows: Vec::new(),
            queue: BinaryHeap::new(),
        }
    }

    fn begin(&mut self) {
        self.windows.clear();
        self.queue.clear();
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.vertices.iter_mut().for_each(|v| v.stamp = 0);
            self.last_on_edge.fill((0, 0));
            self.generation = 1;
        }
    }

    fn first_on_edge(&self, slot: usize) -> Option<u32> {
        let (stamp, window) = self.last_on_edge[slot];
        (stamp == self.generation).then_some(window)
    }

    fn set_first_on_edge(&mut self, slot: usize, window: u32) {
        self.last_on_edge[slot] = (self.generation, window);
    }

    /// Shortest distance (mm) found so far to `vertex`.
    fn distance(&self, vertex: u32) -> f64 {
        let state = &self.vertices[vertex as usize];
        if state.stamp == self.generation {
            state.distance
        } else {
            f64::INFINITY
        }
    }

    fn parent(&self, vertex: u32) -> Parent {
        self.vertices[vertex as usize].parent
    }

    fn set_distance(&mut self, vertex: u32, distance: f64, parent: Parent) {
        self.vertices[vertex as usize] = VertexState {
            stamp: self.generation,
            parent,
            distance,
        };
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::section::plane_section_path;
    use crate::shapes::{cube, cylinder, grid, icosphere};
    use crate::spatial::SurfaceIndex;
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
    fn graph_distance(
        mesh: &TriMesh,
        from: SurfacePoint,
        to: SurfacePoint,
        per_edge: usize,
    ) -> f64 {
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
                            nodes.push(
                                mesh.positions[a as usize].lerp(mesh.positions[b as usize], f),
                            );
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
                    let vertex = |i: i64, j: i64| {
                        at_vertex(mesh, &topology, (j * columns as i64 + i) as usize)
                    };
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
                .chain(
                    (0..3).map(|_| DVec3::new(random.next(), random.next(), random.next()) - 0.5),
                )
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
}
