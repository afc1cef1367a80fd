//! One shortest-path query: windows propagated from the start point, best first, until
//! none can beat the best path to the end point.

use super::scratch::{Event, Item, Scratch};
use super::window::{Parent, Source, Window, trimmed};
use super::{
    Frame, GeodesicSolver, Location, ON_EDGE_TOLERANCE, distance_to_segment, edge_index,
    push_distinct,
};
use crate::topology::NO_TRIANGLE;
use glam::{DVec2, DVec3};

/// One shortest-path query: the window propagation from the start to the end point.
pub(super) struct Search<'q, 'a> {
    pub(super) solver: &'q GeodesicSolver<'a>,
    pub(super) scratch: &'q mut Scratch,
    pub(super) start: &'q Location,
    pub(super) end: &'q Location,
    /// Length of the best path to the end point found so far and where it comes from.
    pub(super) best: (f64, Parent),
}

impl Search<'_, '_> {
    /// Propagates until no window can improve the best path; the path, if the end was reached.
    pub(super) fn run(&mut self) -> Option<Vec<DVec3>> {
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
