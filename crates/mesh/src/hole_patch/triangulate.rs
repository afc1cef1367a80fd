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

/// Triangles `(i, m, k)` in loop order covering the loop `positions`, whose edge `i -> i+1`
/// borders the surface with unit normal `edge_normals[i]` (turned to the orientation of a
/// patch triangle in loop order).
pub(super) fn minimum_weight(positions: &[DVec3], edge_normals: &[DVec3]) -> Vec<[u32; 3]> {
    let n = positions.len();
    // Row-major upper triangle: best[i * n + k] for i < k.
    let mut best: Vec<Option<Best>> = vec![None; n * n];
    for span in 2..n {
        let row: Vec<(usize, Best)> = (0..n - span)
            .into_par_iter()
            .map(|i| {
                let k = i + span;
                // The loop's closing edge (n-1 -> 0) borders the surface too.
                let outer = (i == 0 && k == n - 1).then(|| edge_normals[n - 1]);
                (k, best_over(positions, edge_normals, &best, i, k, outer))
            })
            .collect();
        for (k, found) in row {
            best[(k - span) * n + k] = Some(found);
        }
    }
    let mut triangles = Vec::with_capacity(n - 2);
    let mut stack = vec![(0usize, n - 1)];
    while let Some((i, k)) = stack.pop() {
        if k - i < 2 {
            continue;
        }
        let Some(found) = best[i * n + k] else {
            continue;
        };
        let m = found.middle as usize;
        triangles.push([i as u32, m as u32, k as u32]);
        stack.push((i, m));
        stack.push((m, k));
    }
    triangles
}

/// The best triangle `(i, m, k)` on the edge `(i, k)` with the sub-triangulations on
/// either side; `outer` is the normal across `(i, k)` where that edge borders the surface.
fn best_over(
    positions: &[DVec3],
    edge_normals: &[DVec3],
    best: &[Option<Best>],
    i: usize,
    k: usize,
    outer: Option<DVec3>,
) -> Best {
    let n = positions.len();
    // The sub-triangulation on edge (a, b): its weight and the normal across that edge.
    let side = |a: usize, b: usize| -> (Weight, DVec3) {
        if b == a + 1 {
            (
                Weight {
                    min_cosine: 1.0,
                    area: 0.0,
                },
                edge_normals[a],
            )
        } else {
            let sub = best[a * n + b].unwrap_or(Best {
                weight: Weight {
                    min_cosine: -1.0,
                    area: f64::INFINITY,
                },
                middle: 0,
                normal: DVec3::ZERO,
            });
            (sub.weight, sub.normal)
        }
    };
    let mut chosen: Option<Best> = None;
    for m in i + 1..k {
        let doubled = (positions[m] - positions[i]).cross(positions[k] - positions[i]);
        let normal = doubled.normalize_or_zero();
        let (left, left_normal) = side(i, m);
        let (right, right_normal) = side(m, k);
        let mut min_cosine = left
            .min_cosine
            .min(right.min_cosine)
            .min(normal.dot(left_normal))
            .min(normal.dot(right_normal));
        if let Some(outer) = outer {
            min_cosine = min_cosine.min(normal.dot(outer));
        }
        if normal == DVec3::ZERO {
            // A degenerate triangle: as bad as a fold.
            min_cosine = -1.0;
        }
        let candidate = Best {
            weight: Weight {
                min_cosine,
                area: left.area + right.area + 0.5 * doubled.length(),
            },
            middle: m as u32,
            normal,
        };
        if chosen.is_none_or(|c| candidate.weight.better_than(c.weight)) {
            chosen = Some(candidate);
        }
    }
    // `k - i >= 2`, so the loop above ran at least once.
    chosen.unwrap_or(Best {
        weight: Weight {
            min_cosine: -1.0,
            area: f64::INFINITY,
        },
        middle: (i + 1) as u32,
        normal: DVec3::ZERO,
    })
}
