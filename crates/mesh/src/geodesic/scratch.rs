//! Per-query state: the queue of windows and vertices, and the per-vertex and per-edge
//! buffers reused from query to query.

use super::window::{Parent, Window};
use std::cmp::Ordering;
use std::collections::BinaryHeap;

/// What the queue holds: a window to carry on, or a vertex to emit windows from.
#[derive(Debug, Clone, Copy)]
pub(super) enum Item {
    Window(u32),
    Vertex { vertex: u32, distance: f64 },
}

/// A queue entry, smallest key (lower bound of the path length through it) first.
#[derive(Debug, Clone, Copy)]
pub(super) struct Event {
    pub(super) key: f64,
    pub(super) item: Item,
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
pub(super) struct Scratch {
    generation: u32,
    vertices: Vec<VertexState>,
    /// Per edge of each triangle (`3 t + k`): generation stamp and the last window queued
    /// on it.
    last_on_edge: Vec<(u32, u32)>,
    pub(super) windows: Vec<Window>,
    pub(super) queue: BinaryHeap<Event>,
}

/// The shortest distance found to a vertex (mm) and where it comes from.
#[derive(Debug, Clone, Copy)]
struct VertexState {
    stamp: u32,
    parent: Parent,
    distance: f64,
}

impl Scratch {
    pub(super) fn new(vertex_count: usize, triangle_count: usize) -> Scratch {
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

    pub(super) fn begin(&mut self) {
        self.windows.clear();
        self.queue.clear();
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.vertices.iter_mut().for_each(|v| v.stamp = 0);
            self.last_on_edge.fill((0, 0));
            self.generation = 1;
        }
    }

    pub(super) fn first_on_edge(&self, slot: usize) -> Option<u32> {
        let (stamp, window) = self.last_on_edge[slot];
        (stamp == self.generation).then_some(window)
    }

    pub(super) fn set_first_on_edge(&mut self, slot: usize, window: u32) {
        self.last_on_edge[slot] = (self.generation, window);
    }

    /// Shortest distance (mm) found so far to `vertex`.
    pub(super) fn distance(&self, vertex: u32) -> f64 {
        let state = &self.vertices[vertex as usize];
        if state.stamp == self.generation {
            state.distance
        } else {
            f64::INFINITY
        }
    }

    pub(super) fn parent(&self, vertex: u32) -> Parent {
        self.vertices[vertex as usize].parent
    }

    pub(super) fn set_distance(&mut self, vertex: u32, distance: f64, parent: Parent) {
        self.vertices[vertex as usize] = VertexState {
            stamp: self.generation,
            parent,
            distance,
        };
    }
}
