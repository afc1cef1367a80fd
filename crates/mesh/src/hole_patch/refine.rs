//! Step 2: refining the loop's triangulation to the target edge length by edge splits
//! and Delaunay flips. The loop's vertices and edges are never touched.

use glam::DVec3;
use std::collections::HashMap;
use std::f64::consts::PI;

/// Rounds of splitting (each halves the longest edges); far more than a hole at the
/// default bounds needs (a 300 mm chord at 2 mm needs eight).
const MAX_SPLIT_ROUNDS: usize = 40;
/// Sweeps of flipping after each round of splits.
const MAX_FLIP_SWEEPS: usize = 20;
/// An edge is split when longer than this many target lengths (Botsch and Kobbelt's
/// 4/3, which leaves the halves no shorter than 2/3).
const SPLIT_RATIO: f64 = 4.0 / 3.0;

/// Directed edge -> the triangle holding it.
struct Edges(HashMap<(u32, u32), usize>);

impl Edges {
    fn new(triangles: &[[u32; 3]]) -> Edges {
        let mut map = HashMap::with_capacity(3 * triangles.len());
        for (t, corners) in triangles.iter().enumerate() {
            for (a, b) in directed(*corners) {
                map.insert((a, b), t);
            }
        }
        Edges(map)
    }

    fn set(&mut self, triangles: &[[u32; 3]], t: usize) {
        for (a, b) in directed(triangles[t]) {
            self.0.insert((a, b), t);
        }
    }

    /// The two triangles on the undirected edge `(a, b)`: the one running `a -> b` and
    /// the one running `b -> a`, with their third corners.
    fn pair(&self, triangles: &[[u32; 3]], a: u32, b: u32) -> Option<(usize, u32, usize, u32)> {
        let &t1 = self.0.get(&(a, b))?;
        let &t2 = self.0.get(&(b, a))?;
        Some((
            t1,
            third(triangles[t1], a, b),
            t2,
            third(triangles[t2], a, b),
        ))
    }

    fn interior_edges(&self) -> Vec<(u32, u32)> {
        self.0
            .keys()
            .filter(|&&(a, b)| a < b && self.0.contains_key(&(b, a)))
            .copied()
            .collect()
    }
}

fn directed(t: [u32; 3]) -> [(u32, u32); 3] {
    [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])]
}

fn third(t: [u32; 3], a: u32, b: u32) -> u32 {
    t.into_iter().find(|&v| v != a && v != b).unwrap_or(a)
}

/// Refines `triangles` over `positions` (new vertices appended) until no interior edge is
/// longer than [`SPLIT_RATIO`] target lengths.
pub(super) fn refine(
    positions: &mut Vec<DVec3>,
    triangles: &mut Vec<[u32; 3]>,
    target_edge_mm: f64,
) {
    let longest = SPLIT_RATIO * target_edge_mm;
    let mut edges = Edges::new(triangles);
    for _ in 0..MAX_SPLIT_ROUNDS {
        let mut long: Vec<(f64, u32, u32)> = edges
            .interior_edges()
            .into_iter()
            .map(|(a, b)| (positions[a as usize].distance(positions[b as usize]), a, b))
            .filter(|&(length, _, _)| length > longest)
            .collect();
        if long.is_empty() {
            break;
        }
        long.sort_by(|x, y| y.0.total_cmp(&x.0).then((x.1, x.2).cmp(&(y.1, y.2))));
        for (_, a, b) in long {
            let Some((t1, c, t2, d)) = edges.pair(triangles, a, b) else {
                continue;
            };
            let m = positions.len() as u32;
            positions.push(0.5 * (positions[a as usize] + positions[b as usize]));
            edges.0.remove(&(a, b));
            edges.0.remove(&(b, a));
            triangles[t1] = [a, m, c];
            triangles[t2] = [b, m, d];
            triangles.push([m, b, c]);
            triangles.push([m, a, d]);
            let last = triangles.len();
            for t in [t1, t2, last - 2, last - 1] {
                edges.set(triangles, t);
            }
        }
        flip_to_delaunay(positions, triangles, &mut edges);
    }
}

/// The angle at `apex` of the triangle `(apex, a, b)`.
fn angle(apex: DVec3, a: DVec3, b: DVec3) -> f64 {
    (a - apex).angle_between(b - apex)
}

/// Flips interior edges whose opposite angles sum to more than π, where the two new
/// triangles face the same way as the old pair (no fold).
fn flip_to_delaunay(positions: &[DVec3], triangles: &mut [[u32; 3]], edges: &mut Edges) {
    for _ in 0..MAX_FLIP_SWEEPS {
        let mut flipped = false;
        let mut candidates = edges.interior_edges();
        candidates.sort_unstable();
        for (a, b) in candidates {
            let Some((t1, c, t2, d)) = edges.pair(triangles, a, b) else {
                continue;
            };
            if c == d || edges.0.contains_key(&(c, d)) || edges.0.contains_key(&(d, c)) {
                continue;
            }
            let p = |v: u32| positions[v as usize];
            if angle(p(c), p(a), p(b)) + angle(p(d), p(a), p(b)) <= PI + 1e-9 {
                continue;
            }
            let normal = |t: [u32; 3]| (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
            let before = normal([a, b, c]) + normal([b, a, d]);
            let (new1, new2) = ([a, d, c], [d, b, c]);
            if normal(new1).dot(before) <= 0.0
                || normal(new2).dot(before) <= 0.0
                || normal(new1).dot(normal(new2)) <= 0.0
            {
                continue;
            }
            edges.0.remove(&(a, b));
            edges.0.remove(&(b, a));
            triangles[t1] = new1;
            triangles[t2] = new2;
            edges.set(triangles, t1);
            edges.set(triangles, t2);
            flipped = true;
        }
        if !flipped {
            break;
        }
    }
}
