//! The scan's displacement as one sparse linear map of the finest level's vertex
//! displacements: the point map ([`PointMap`]) followed by the surface smoothing
//! ([`SurfaceSmoother`]), composed once per model. Applying it is one pass over its
//! terms whatever the smoothing's reach (its damped steps grow as the square of the
//! radius over the scan's edge length: 13-30 on the phantom from the finest to the
//! coarsest models). Terms the smoothing spreads to with less than [`PRUNED_SHARE`]
//! of their row's weight are dropped and their weight given back to the row's others
//! in proportion, so that a translation is still carried exactly; then the terms of
//! vertices whose displacement is always zero, which carry nothing (a translation of the
//! other vertices is still carried exactly where those stay at zero).

use crate::field::{PointMap, SurfaceSmoother};
use glam::{DVec3, Vec3A};
use rayon::prelude::*;

/// A term with less than this share of its row's total weight is dropped. The
/// smoothing's kernel then ends about three of its radii out; the terms beyond weigh
/// 1e-5 and less each.
pub const PRUNED_SHARE: f64 = 1e-5;

/// Terms smaller than this are dropped between the smoothing's steps (the far tails of
/// the kernel, which the final pruning would drop anyway).
const STEP_PRUNED_WEIGHT: f64 = 1e-7;

/// Rows per parallel task of a carry.
const ROW_CHUNK: usize = 1024;

/// One sparse row: (finest-level vertex, weight), each vertex once. Single precision
/// halves the memory the composition streams through at each step.
type Row = Vec<(u32, f32)>;

/// Scan vertex `v` moves by `Σ u[nodes[k]] weights[k]` over `k in starts[v]..starts[v + 1]`.
#[derive(Debug, Clone, Default)]
pub struct ScanCarry {
    starts: Vec<u32>,
    nodes: Vec<u32>,
    /// Single precision: a relative error of 6e-8 per weight.
    weights: Vec<f32>,
    /// Vertices of the finest level it reads.
    node_count: usize,
    /// What it was composed from, as its composer identified it (see
    /// [`ScanCarry::source`]).
    source: u64,
}

/// A dense accumulator over the finest level's vertices with the list of those touched,
/// in the order first touched (rows need no order).
struct Accumulator {
    sums: Vec<f64>,
    /// `row_stamp[node] == stamp`: `node` is in `touched` for the row under way.
    row_stamp: Vec<u32>,
    stamp: u32,
    touched: Vec<u32>,
}

impl Accumulator {
    fn new(node_count: usize) -> Accumulator {
        Accumulator {
            sums: vec![0.0; node_count],
            row_stamp: vec![0; node_count],
            stamp: 1,
            touched: Vec::new(),
        }
    }

    fn add(&mut self, row: &[(u32, f32)], scale: f64) {
        for &(node, weight) in row {
            let n = node as usize;
            if self.row_stamp[n] != self.stamp {
                self.row_stamp[n] = self.stamp;
                self.sums[n] = 0.0;
                self.touched.push(node);
            }
            self.sums[n] += scale * f64::from(weight);
        }
    }

    /// The accumulated row without terms below `pruned` in magnitude; starts a new one.
    fn take(&mut self, pruned: f64) -> Row {
        let row = (self.touched.iter())
            .map(|&node| (node, self.sums[node as usize]))
            .filter(|term| term.1.abs() >= pruned)
            .map(|(node, weight)| (node, weight as f32))
            .collect();
        self.touched.clear();
        self.stamp = self.stamp.wrapping_add(1);
        if self.stamp == 0 {
            self.row_stamp.fill(0);
            self.stamp = 1;
        }
        row
    }
}

impl ScanCarry {
    /// Composes `map` (one point per scan vertex) and `smoother` (over the scan) for a
    /// finest level of `node_count` vertices, without the terms of the vertices in
    /// `held_at_zero`: vertices whose displacement is zero in every field it will carry
    /// (the caller's invariant; a carry that breaks it is wrong, not slow). `source`
    /// identifies what it was composed from, for the caller to check before use.
    pub(crate) fn new(
        map: &PointMap,
        smoother: &SurfaceSmoother,
        node_count: usize,
        held_at_zero: &[u32],
        source: u64,
    ) -> ScanCarry {
        let mut rows: Vec<Row> = (0..map.len())
            .into_par_iter()
            .map_init(
                || Accumulator::new(node_count),
                |accumulator, point| {
                    for (node, weight) in map.terms(point) {
                        accumulator.add(&[(node, 1.0)], weight);
                    }
                    accumulator.take(0.0)
                },
            )
            .collect();
        if rows.len() == smoother.vertex_count() {
            for _ in 0..smoother.iterations() {
                let next: Vec<Row> = (0..smoother.active_count())
                    .into_par_iter()
                    .map_init(
                        || Accumulator::new(node_count),
                        |accumulator, k| {
                            let (vertex, around) = smoother.vertex_and_neighbours(k);
                            accumulator.add(&rows[vertex as usize], 0.5);
                            let scale = 0.5 / around.len() as f64;
                            for neighbour in
                                around.iter().filter_map(|&w| smoother.active_vertex(w))
                            {
                                accumulator.add(&rows[neighbour as usize], scale);
                            }
                            accumulator.take(STEP_PRUNED_WEIGHT)
                        },
                    )
                    .collect();
                for (k, row) in next.into_iter().enumerate() {
                    rows[smoother.vertex_and_neighbours(k).0 as usize] = row;
                }
            }
        }
        let mut zero = vec![false; node_count];
        for &node in held_at_zero {
            zero[node as usize] = true;
        }
        let rows: Vec<Row> = (rows.into_par_iter())
            .map(|row| {
                let mut row = pruned_row(row);
                row.retain(|term| !zero[term.0 as usize]);
                row
            })
            .collect();
        let mut carry = ScanCarry {
            starts: Vec::with_capacity(rows.len() + 1),
            nodes: Vec::new(),
            weights: Vec::new(),
            node_count,
            source,
        };
        carry.starts.push(0);
        for row in rows {
            for (node, weight) in row {
                carry.nodes.push(node);
                carry.weights.push(weight);
            }
            carry.starts.push(carry.nodes.len() as u32);
        }
        carry
    }

    /// What it was composed from, as its composer identified it.
    pub fn source(&self) -> u64 {
        self.source
    }

    /// Number of scan vertices.
    pub fn len(&self) -> usize {
        self.starts.len().saturating_sub(1)
    }

    /// Whether it carries to no vertex.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Number of vertices of the finest level it reads.
    pub fn node_count(&self) -> usize {
        self.node_count
    }

    /// Number of terms over all rows.
    pub fn term_count(&self) -> usize {
        self.nodes.len()
    }

    /// The displacement of every scan vertex for the finest level's `u` (mm), summed in
    /// single precision: with weights of one sign summing to at most 1, a row of `n`
    /// terms is off by at most about `n` times 6e-8 of the largest displacement
    /// (1e-3 mm for 400 terms of 40 mm).
    pub fn displacements(&self, u: &[DVec3]) -> Vec<DVec3> {
        self.carried_onto(u, |_| DVec3::ZERO)
    }

    /// Every scan vertex of rest position `rest` moved by its displacement for `u` (mm):
    /// [`ScanCarry::displacements`] added in the same pass.
    pub fn positions(&self, rest: &[DVec3], u: &[DVec3]) -> Vec<DVec3> {
        self.carried_onto(u, |v| rest[v])
    }

    /// `base(v)` plus scan vertex `v`'s displacement for `u`, for every scan vertex.
    fn carried_onto(&self, u: &[DVec3], base: impl Fn(usize) -> DVec3 + Sync) -> Vec<DVec3> {
        let u: Vec<Vec3A> = u.iter().map(|d| d.as_vec3a()).collect();
        let mut out = vec![DVec3::ZERO; self.len()];
        out.par_chunks_mut(ROW_CHUNK)
            .enumerate()
            .for_each(|(chunk, out)| {
                let first = chunk * ROW_CHUNK;
                for (v, d) in (first..).zip(out) {
                    *d = base(v) + self.row_sum(v, &u).as_dvec3();
                }
            });
        out
    }

    /// Row `v`'s sum over `u`.
    #[inline]
    fn row_sum(&self, v: usize, u: &[Vec3A]) -> Vec3A {
        let terms = self.starts[v] as usize..self.starts[v + 1] as usize;
        let nodes = &self.nodes[terms.clone()];
        let weights = &self.weights[terms];
        // Four running sums: one would wait on its own addition at every term.
        let mut sums = [Vec3A::ZERO; 4];
        for (n4, w4) in nodes.chunks_exact(4).zip(weights.chunks_exact(4)) {
            for ((sum, &node), &weight) in sums.iter_mut().zip(n4).zip(w4) {
                *sum += u[node as usize] * weight;
            }
        }
        let tail = nodes.len() / 4 * 4;
        for ((sum, &node), &weight) in sums.iter_mut().zip(&nodes[tail..]).zip(&weights[tail..]) {
            *sum += u[node as usize] * weight;
        }
        (sums[0] + sums[1]) + (sums[2] + sums[3])
    }
}

/// `row` without the terms under [`PRUNED_SHARE`] of its total, the others scaled to keep
/// the total.
fn pruned_row(row: Row) -> Row {
    let total: f64 = row.iter().map(|t| f64::from(t.1)).sum();
    let magnitude: f64 = row.iter().map(|t| f64::from(t.1).abs()).sum();
    let kept: Row = row
        .into_iter()
        .filter(|t| f64::from(t.1).abs() >= PRUNED_SHARE * magnitude)
        .collect();
    let kept_total: f64 = kept.iter().map(|t| f64::from(t.1)).sum();
    let scale = if kept_total != 0.0 {
        total / kept_total
    } else {
        0.0
    };
    kept.into_iter()
        .map(|(node, weight)| (node, (f64::from(weight) * scale) as f32))
        .collect()
}
