//! Step 1: the minimum-weight triangulation of the loop (Liepa 2003, after Barequet and
//! Sharir): weight = (largest dihedral angle, area), compared in that order.

use glam::DVec3;
use rayon::prelude::*;

/// The weight of a sub-triangulation: the cosine of its largest dihedral angle (larger is
/// better) and its area (smaller is better).
#[derive(Debug, Clone, Copy)]
struct Weight {
    min_cosine: f64,
    area: f64,
}

impl Weight {
    /// Cosines closer than this count as equal, so that area decides between
    /// triangulations whose worst angle is the same up to rounding.
    const COSINE_TIE: f64 = 1e-9;
    /// A sub-triangulation not yet known (never read: spans grow one at a time).
    const UNKNOWN: Weight = Weight {
        min_cosine: -1.0,
        area: f64::INFINITY,
    };
    /// A loop edge: nothing to triangulate.
    const EDGE: Weight = Weight {
        min_cosine: 1.0,
        area: 0.0,
    };

    fn better_than(self, other: Weight) -> bool {
        if (self.min_cosine - other.min_cosine).abs() > Self::COSINE_TIE {
            self.min_cosine > other.min_cosine
        } else {
            self.area < other.area
        }
    }
}

/// The best sub-triangulation of the loop vertices `i..=k`: its weight, its triangle on
/// the edge `(i, k)` (the middle vertex) and that triangle's unit normal.
#[derive(Debug, Clone, Copy)]
struct Best {
    weight: Weight,
    middle: u32,
    normal: DVec3,
}

/// The table of best sub-triangulations, stored twice so that the inner loop of the
/// programme reads both its operands contiguously: `rows[i * n + m]` for the spans
/// `(i, m)` of a row, `columns[k * n + m]` for the spans `(m, k)` of a column.
struct Table {
    n: usize,
    rows: Vec<Best>,
    columns: Vec<Best>,
}

impl Table {
    /// The table with the loop's edges filled in: span `(a, a + 1)` has no triangle and
    /// borders the surface with normal `edge_normals[a]`.
    fn new(edge_normals: &[DVec3]) -> Table {
        let n = edge_normals.len();
        let unknown = Best {
            weight: Weight::UNKNOWN,
            middle: 0,
            normal: DVec3::ZERO,
        };
        let mut table = Table {
            n,
            rows: vec![unknown; n * n],
            columns: vec![unknown; n * n],
        };
        for (a, &normal) in edge_normals.iter().enumerate().take(n - 1) {
            table.set(
                a,
                a + 1,
                Best {
                    weight: Weight::EDGE,
                    middle: 0,
                    normal,
                },
            );
        }
        table
    }

    fn set(&mut self, i: usize, k: usize, best: Best) {
        self.rows[i * self.n + k] = best;
        self.columns[k * self.n + i] = best;
    }
}

/// Triangles `(i, m, k)` in loop order covering the loop `positions`, whose edge `i -> i+1`
/// borders the surface with unit normal `edge_normals[i]` (turned to the orientation of a
/// patch triangle in loop order).
pub(super) fn minimum_weight(positions: &[DVec3], edge_normals: &[DVec3]) -> Vec<[u32; 3]> {
    let n = positions.len();
    let mut table = Table::new(edge_normals);
    for span in 2..n {
        let found: Vec<Best> = (0..n - span)
            .into_par_iter()
            .map(|i| {
                let k = i + span;
                // The loop's closing edge (n-1 -> 0) borders the surface too.
                let outer = (i == 0 && k == n - 1).then(|| edge_normals[n - 1]);
                best_over(positions, &table, i, k, outer)
            })
            .collect();
        for (i, best) in found.into_iter().enumerate() {
            table.set(i, i + span, best);
        }
    }
    let mut triangles = Vec::with_capacity(n - 2);
    let mut stack = vec![(0usize, n - 1)];
    while let Some((i, k)) = stack.pop() {
        if k - i < 2 {
            continue;
        }
        let m = table.rows[i * n + k].middle as usize;
        triangles.push([i as u32, m as u32, k as u32]);
        stack.push((i, m));
        stack.push((m, k));
    }
    triangles
}

/// The best triangle `(i, m, k)` on the edge `(i, k)` with the sub-triangulations on
/// either side; `outer` is the normal across `(i, k)` where that edge borders the surface.
fn best_over(positions: &[DVec3], table: &Table, i: usize, k: usize, outer: Option<DVec3>) -> Best {
    let n = table.n;
    let row = &table.rows[i * n..i * n + k];
    let column = &table.columns[k * n..k * n + k];
    let (p_i, p_k) = (positions[i], positions[k]);
    let mut chosen = Best {
        weight: Weight::UNKNOWN,
        middle: (i + 1) as u32,
        normal: DVec3::ZERO,
    };
    let mut first = true;
    for m in i + 1..k {
        let (left, right) = (row[m], column[m]);
        let doubled = (positions[m] - p_i).cross(p_k - p_i);
        let normal = doubled.normalize_or_zero();
        let mut min_cosine = if normal == DVec3::ZERO {
            // A degenerate triangle: as bad as a fold.
            -1.0
        } else {
            left.weight
                .min_cosine
                .min(right.weight.min_cosine)
                .min(normal.dot(left.normal))
                .min(normal.dot(right.normal))
        };
        if let Some(outer) = outer {
            min_cosine = min_cosine.min(normal.dot(outer));
        }
        let weight = Weight {
            min_cosine,
            area: left.weight.area + right.weight.area + 0.5 * doubled.length(),
        };
        if first || weight.better_than(chosen.weight) {
            chosen = Best {
                weight,
                middle: m as u32,
                normal,
            };
            first = false;
        }
    }
    chosen
}
