//! Closing a curve whose walk stopped short of its first point: the shortest path along
//! the mesh's edges between the two.

use super::CurveLocation;
use crate::ordered::OrderedMm;
use crate::topology::Topology;
use crate::trimesh::TriMesh;
use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

/// Longest gap (mm) bridged along edges: a few triangles of a scan, the size of the
/// noise ridges a walk stops at. A wider gap is a curve that does not close.
const MAX_GAP_MM: f64 = 10.0;

/// The vertices of the shortest path along edges from a corner of `from`'s triangles to
/// a corner of `to`'s (the distances from `from` and to `to` counted straight), so that
/// `from`, the path and `to` follow each other on common triangles; `None` if it is
/// longer than [`MAX_GAP_MM`].
pub(super) fn edge_path(
    mesh: &TriMesh,
    topology: &Topology,
    from: &CurveLocation,
    to: &CurveLocation,
) -> Option<Vec<u32>> {
    let corners = |location: &CurveLocation| -> Vec<u32> {
        let mut corners: Vec<u32> = location
            .triangles(topology)
            .into_iter()
            .flat_map(|t| mesh.triangles[t])
            .collect();
        corners.sort_unstable();
        corners.dedup();
        corners
    };
    let (start, end) = (from.position(mesh), to.position(mesh));
    let position = |v: u32| mesh.positions[v as usize];
    let ends: HashMap<u32, f64> = corners(to)
        .into_iter()
        .map(|v| (v, position(v).distance(end)))
        .collect();
    let mut distance: HashMap<u32, f64> = HashMap::new();
    let mut previous: HashMap<u32, u32> = HashMap::new();
    let mut queue = BinaryHeap::new();
    for v in corners(from) {
        let d = position(v).distance(start);
        distance.insert(v, d);
        queue.push(Reverse((OrderedMm(d), v)));
    }
    // Dijkstra, finished when the cheapest path to `to` (through one of its corners) is
    // known.
    let mut best: Option<(f64, u32)> = None;
    while let Some(Reverse((OrderedMm(d), v))) = queue.pop() {
        if d > MAX_GAP_MM || best.is_some_and(|(b, _)| d >= b) {
            break;
        }
        if distance.get(&v).is_some_and(|&known| d > known) {
            continue;
        }
        if let Some(&rest) = ends.get(&v)
            && best.is_none_or(|(b, _)| d + rest < b)
        {
            best = Some((d + rest, v));
        }
        for w in topology.vertex_neighbors(mesh, v as usize) {
            let through = d + position(v).distance(position(w));
            if distance.get(&w).is_none_or(|&known| through < known) {
                distance.insert(w, through);
                previous.insert(w, v);
                queue.push(Reverse((OrderedMm(through), w)));
            }
        }
    }
    let (length, last) = best?;
    if length > MAX_GAP_MM {
        return None;
    }
    let mut path = vec![last];
    while let Some(&v) = previous.get(path.last()?) {
        path.push(v);
    }
    path.reverse();
    Some(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::grid;

    #[test]
    fn a_short_gap_is_bridged_along_edges_and_a_long_one_is_not() {
        // A 1 mm grid: vertex (i, j) is i + 21 j.
        let mesh = grid(20, 20, 1.0);
        let topology = Topology::new(&mesh);
        let vertex = |i: u32, j: u32| i + 21 * j;
        let from = CurveLocation::OnVertex(vertex(5, 5));
        let to = CurveLocation::OnVertex(vertex(9, 5));
        let path = edge_path(&mesh, &topology, &from, &to).unwrap();
        // Consecutive vertices are neighbours, and the whole way from `from` through the
        // path to `to` is the 4 mm along the grid line (no shorter one exists).
        for pair in path.windows(2) {
            assert!(
                topology
                    .vertex_neighbors(&mesh, pair[0] as usize)
                    .contains(&pair[1])
            );
        }
        let points: Vec<_> = std::iter::once(from.position(&mesh))
            .chain(path.iter().map(|&v| mesh.positions[v as usize]))
            .chain(std::iter::once(to.position(&mesh)))
            .collect();
        let length: f64 = points.windows(2).map(|w| w[0].distance(w[1])).sum();
        assert!((length - 4.0).abs() < 1e-12, "{length}");
        // 15 mm is beyond the bridge's reach.
        let far = CurveLocation::OnVertex(vertex(20, 5));
        assert_eq!(edge_path(&mesh, &topology, &from, &far), None);
    }
}
