//! Repair of a scanner export's topology: fins and overlapping sheets, where an edge
//! is shared by more than two triangles. Paths across the surface branch there and
//! plane sections stop, so a scan keeps one surface through every edge.

use crate::topology::{Topology, edge_key};
use crate::trimesh::TriMesh;

/// A detached piece left by the repair is dropped when it has fewer than this share of
/// the largest piece's triangles (a fin's remains, not a second body part).
const DETACHED_PIECE_SHARE: f64 = 0.05;

/// What [`fin_triangles`] found.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct FinRepair {
    /// Edges shared by more than two triangles.
    pub non_manifold_edges: usize,
    /// Triangles to remove (ascending): every triangle on such an edge except the two
    /// that continue the surface across it most smoothly, and the small pieces those
    /// removals detach.
    pub triangles: Vec<usize>,
}

/// Finds the triangles to remove so that no edge is shared by more than two. On each
/// such edge the pair kept is the one that traverses it in opposite directions (a
/// consistently oriented surface) with the most nearly parallel normals; a fin standing
/// on the surface or a sheet crossing it loses its triangle there, and what remains of
/// it, now held by a vertex at most, is dropped as a small detached piece.
pub fn fin_triangles(mesh: &TriMesh) -> FinRepair {
    let mut half_edges: Vec<(u64, u32)> = mesh
        .triangles
        .iter()
        .enumerate()
        .flat_map(|(t, tri)| {
            (0..3).map(move |k| (edge_key(tri[k], tri[(k + 1) % 3]), (3 * t + k) as u32))
        })
        .collect();
    half_edges.sort_unstable();
    let mut remove = vec![false; mesh.triangles.len()];
    let mut non_manifold_edges = 0;
    for group in half_edges.chunk_by(|x, y| x.0 == y.0) {
        if group.len() <= 2 {
            continue;
        }
        non_manifold_edges += 1;
        let (keep_a, keep_b) = smoothest_pair(mesh, group);
        for (i, &(_, half_edge)) in group.iter().enumerate() {
            if i != keep_a && i != keep_b {
                remove[half_edge as usize / 3] = true;
            }
        }
    }
    if non_manifold_edges == 0 {
        return FinRepair::default();
    }
    drop_detached_pieces(mesh, &mut remove);
    FinRepair {
        non_manifold_edges,
        triangles: (0..remove.len()).filter(|&t| remove[t]).collect(),
    }
}

/// Indices into `group` (half-edges of one edge) of the two triangles to keep.
fn smoothest_pair(mesh: &TriMesh, group: &[(u64, u32)]) -> (usize, usize) {
    let start = |half_edge: u32| mesh.triangles[half_edge as usize / 3][half_edge as usize % 3];
    let normal = |half_edge: u32| mesh.triangle_normal(half_edge as usize / 3);
    let mut best = (0, 1);
    let mut best_score = (false, f64::NEG_INFINITY);
    for i in 0..group.len() {
        for j in i + 1..group.len() {
            let (a, b) = (group[i].1, group[j].1);
            let score = (start(a) != start(b), normal(a).dot(normal(b)));
            if score > best_score {
                best = (i, j);
                best_score = score;
            }
        }
    }
    best
}

/// Marks for removal the pieces (edge-connected, over the triangles kept) that share a
/// vertex with a removed triangle and are small against the largest piece.
fn drop_detached_pieces(mesh: &TriMesh, remove: &mut [bool]) {
    let kept_index: Vec<usize> = (0..mesh.triangles.len()).filter(|&t| !remove[t]).collect();
    let kept = TriMesh::new(
        mesh.positions.clone(),
        kept_index.iter().map(|&t| mesh.triangles[t]).collect(),
    );
    let (component, count) = Topology::new(&kept).triangle_components();
    let mut size = vec![0usize; count];
    for &c in &component {
        size[c as usize] += 1;
    }
    let largest = size.iter().copied().max().unwrap_or(0);
    let mut touches_removed_vertex = vec![false; mesh.positions.len()];
    for t in (0..remove.len()).filter(|&t| remove[t]) {
        for v in mesh.triangles[t] {
            touches_removed_vertex[v as usize] = true;
        }
    }
    let mut near_fin = vec![false; count];
    for (k, tri) in kept.triangles.iter().enumerate() {
        if tri.iter().any(|&v| touches_removed_vertex[v as usize]) {
            near_fin[component[k] as usize] = true;
        }
    }
    for (k, &c) in component.iter().enumerate() {
        let c = c as usize;
        if near_fin[c] && (size[c] as f64) < DETACHED_PIECE_SHARE * largest as f64 {
            remove[kept_index[k]] = true;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A flat grid with a vertical strip of `strip_quads` quads standing on one of
    /// its interior edges.
    fn grid_with_fin(strip_quads: usize) -> (TriMesh, usize) {
        let mut mesh = crate::shapes::grid(20, 20, 10.0);
        let grid_triangles = mesh.triangles.len();
        // An interior edge of the grid, from its first triangle's corners.
        let (a, b) = {
            let interior = mesh.triangles.len() / 2;
            let tri = mesh.triangles[interior];
            (tri[0], tri[1])
        };
        let (pa, pb) = (mesh.positions[a as usize], mesh.positions[b as usize]);
        let mut bottom = (a, b);
        for level in 1..=strip_quads {
            let up = DVec3::Z * 10.0 * level as f64;
            let top_a = mesh.positions.len() as u32;
            mesh.positions.extend([pa + up, pb + up]);
            let top = (top_a, top_a + 1);
            mesh.triangles.push([bottom.0, bottom.1, top.1]);
            mesh.triangles.push([bottom.0, top.1, top.0]);
            bottom = top;
        }
        (mesh, grid_triangles)
    }

    /// A fin of one or several quads is removed whole and the grid is kept whole; the
    /// repaired mesh has no edge on more than two triangles.
    #[test]
    fn a_fin_is_removed_and_the_surface_kept() {
        for strip_quads in [1, 3] {
            let (mesh, grid_triangles) = grid_with_fin(strip_quads);
            let repair = fin_triangles(&mesh);
            assert_eq!(repair.non_manifold_edges, 1);
            let fin: Vec<usize> = (grid_triangles..mesh.triangles.len()).collect();
            assert_eq!(repair.triangles, fin, "{strip_quads} quads");
            let mut repaired = mesh.clone();
            repaired.remove_triangles(&repair.triangles);
            assert_eq!(Topology::new(&repaired).non_manifold_edge_count, 0);
        }
    }

    /// A clean closed surface needs nothing.
    #[test]
    fn a_manifold_surface_is_left_alone() {
        let sphere = crate::shapes::icosphere(50.0, 3);
        assert_eq!(fin_triangles(&sphere), FinRepair::default());
    }
}
