//! Laplace-Beltrami smoothing of the fill-in's heights.

use glam::DVec2;

/// Fraction of the way each smoothing step moves a height to its weighted neighbour mean.
/// At most one keeps every step a convex combination of old heights, hence stable.
const SMOOTHING_STEP: f64 = 0.5;

/// Bounds on an edge's cotangent weight `cot α + cot β`. It is negative only where two
/// opposite angles are obtuse together (a non-Delaunay edge); clamping it to a small
/// positive value there keeps every step a convex combination, and the cap keeps a
/// near-degenerate triangle from dominating. Clamping the sum rather than each angle's
/// cotangent keeps the weights exact, and so a tilted plane unchanged, elsewhere.
const MIN_EDGE_WEIGHT: f64 = 1e-3;
const MAX_EDGE_WEIGHT: f64 = 1e3;

/// Explicit Laplace-Beltrami smoothing of the heights over the triangulated plane
/// points, the first `fixed_count` vertices (the boundary) held fixed. Each step moves a
/// height part of the way to the cotangent-weighted mean of its neighbours, the weights
/// `cot α + cot β` taken from the current 3D triangles.
pub(super) fn smooth_heights(
    points: &[DVec2],
    heights: &mut [f64],
    triangles: &[[u32; 3]],
    fixed_count: usize,
    steps: usize,
) {
    let (edges, opposite_edges) = edge_table(triangles);
    let mut edge_weights = vec![0.0; edges.len()];
    let mut weight_sums = vec![0.0; heights.len()];
    let mut weighted_heights = vec![0.0; heights.len()];
    for _ in 0..steps {
        edge_weights.fill(0.0);
        for (triangle, opposite) in triangles.iter().zip(&opposite_edges) {
            let position = triangle.map(|v| points[v as usize].extend(heights[v as usize]));
            for k in 0..3 {
                let to_next = position[(k + 1) % 3] - position[k];
                let to_previous = position[(k + 2) % 3] - position[k];
                let twice_area = to_next.cross(to_previous).length().max(f64::MIN_POSITIVE);
                // The cotangent of the angle at corner k, for the opposite edge.
                edge_weights[opposite[k]] += to_next.dot(to_previous) / twice_area;
            }
        }
        weight_sums.fill(0.0);
        weighted_heights.fill(0.0);
        for (&[a, b], &cotangents) in edges.iter().zip(&edge_weights) {
            let weight = cotangents.clamp(MIN_EDGE_WEIGHT, MAX_EDGE_WEIGHT);
            weight_sums[a] += weight;
            weighted_heights[a] += weight * heights[b];
            weight_sums[b] += weight;
            weighted_heights[b] += weight * heights[a];
        }
        for v in fixed_count..heights.len() {
            if weight_sums[v] > 0.0 {
                heights[v] += SMOOTHING_STEP * (weighted_heights[v] / weight_sums[v] - heights[v]);
            }
        }
    }
}

/// The undirected edges `[a, b]` (`a < b`) of `triangles`, and per triangle the index of
/// the edge opposite each corner.
fn edge_table(triangles: &[[u32; 3]]) -> (Vec<[usize; 2]>, Vec<[usize; 3]>) {
    let mut corners: Vec<([usize; 2], usize)> = triangles
        .iter()
        .enumerate()
        .flat_map(|(t, triangle)| {
            (0..3).map(move |k| {
                let (a, b) = (
                    triangle[(k + 1) % 3] as usize,
                    triangle[(k + 2) % 3] as usize,
                );
                ([a.min(b), a.max(b)], 3 * t + k)
            })
        })
        .collect();
    corners.sort_unstable();
    let mut edges = Vec::new();
    let mut opposite_edges = vec![[0; 3]; triangles.len()];
    for group in corners.chunk_by(|x, y| x.0 == y.0) {
        for &(_, corner) in group {
            opposite_edges[corner / 3][corner % 3] = edges.len();
        }
        edges.push(group[0].0);
    }
    (edges, opposite_edges)
}
