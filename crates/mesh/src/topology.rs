//! Connectivity of a triangle mesh: triangle neighbours across edges, triangles and
//! neighbours around a vertex, boundary loops and connected components.
//!
//! Built once per mesh in O(n log n); every query is then a slice lookup.

use crate::trimesh::TriMesh;

/// Marker for "no triangle" in neighbour tables.
pub const NO_TRIANGLE: u32 = u32::MAX;

/// Connectivity tables of a mesh. Edge `k` of triangle `t` runs from corner `k` to
/// corner `(k + 1) % 3`.
#[derive(Debug, Clone)]
pub struct Topology {
    /// `triangle_neighbors[t][k]` is the triangle across edge `k` of `t`, or
    /// [`NO_TRIANGLE`] on the boundary (and on non-manifold edges, which are treated as
    /// boundary so walks never branch).
    pub triangle_neighbors: Vec<[u32; 3]>,
    vertex_triangle_offsets: Vec<u32>,
    vertex_triangles: Vec<u32>,
    /// Number of edges with exactly one triangle.
    pub boundary_edge_count: usize,
    /// Number of edges shared by more than two triangles.
    pub non_manifold_edge_count: usize,
    /// Number of interior edges whose two triangles traverse it in the same direction
    /// (inconsistent orientation).
    pub inconsistent_edge_count: usize,
}

impl Topology {
    /// `(this topology's triangles, the mesh's)` when it was not built for `mesh`, as far
    /// as a cheap check tells (one entry per triangle); `None` when it may have been.
    pub(crate) fn mismatch(&self, mesh: &TriMesh) -> Option<(usize, usize)> {
        let (ours, theirs) = (self.triangle_neighbors.len(), mesh.triangles.len());
        (ours != theirs).then_some((ours, theirs))
    }

    /// Builds the tables. The mesh must have valid indices ([`TriMesh::validate`]).
    pub fn new(mesh: &TriMesh) -> Topology {
        let triangle_count = mesh.triangles.len();
        // Every half-edge keyed by its undirected vertex pair; sorting groups the twins.
        let mut half_edges: Vec<(u64, u32)> = Vec::with_capacity(3 * triangle_count);
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
                half_edges.push((key, (3 * t + k) as u32));
            }
        }
        half_edges.sort_unstable();

        let mut triangle_neighbors = vec![[NO_TRIANGLE; 3]; triangle_count];
        let mut boundary_edge_count = 0;
        let mut non_manifold_edge_count = 0;
        let mut inconsistent_edge_count = 0;
        for group in half_edges.chunk_by(|x, y| x.0 == y.0) {
            match group {
                [(_, h0), (_, h1)] => {
                    let (t0, k0) = ((h0 / 3) as usize, (h0 % 3) as usize);
                    let (t1, k1) = ((h1 / 3) as usize, (h1 % 3) as usize);
                    if mesh.triangles[t0][k0] == mesh.triangles[t1][k1] {
                        inconsistent_edge_count += 1;
                    }
                    triangle_neighbors[t0][k0] = t1 as u32;
                    triangle_neighbors[t1][k1] = t0 as u32;
                }
                [_] => boundary_edge_count += 1,
                _ => non_manifold_edge_count += 1,
            }
        }

        // Compressed rows of vertex -> incident triangles.
        let mut vertex_triangle_offsets = vec![0u32; mesh.positions.len() + 1];
        for tri in &mesh.triangles {
            for &v in tri {
                vertex_triangle_offsets[v as usize + 1] += 1;
            }
        }
        for v in 0..mesh.positions.len() {
            vertex_triangle_offsets[v + 1] += vertex_triangle_offsets[v];
        }
        let mut fill = vertex_triangle_offsets.clone();
        let mut vertex_triangles = vec![0u32; 3 * triangle_count];
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for &v in tri {
                vertex_triangles[fill[v as usize] as usize] = t as u32;
                fill[v as usize] += 1;
            }
        }

        Topology {
            triangle_neighbors,
            vertex_triangle_offsets,
            vertex_triangles,
            boundary_edge_count,
            non_manifold_edge_count,
            inconsistent_edge_count,
        }
    }

    /// Triangles incident to vertex `v`.
    #[inline]
    pub fn vertex_triangles(&self, v: usize) -> &[u32] {
        let start = self.vertex_triangle_offsets[v] as usize;
        let end = self.vertex_triangle_offsets[v + 1] as usize;
        &self.vertex_triangles[start..end]
    }

    /// Vertices sharing an edge with vertex `v`, sorted and without repeats.
    pub fn vertex_neighbors(&self, mesh: &TriMesh, v: usize) -> Vec<u32> {
        let mut neighbors: Vec<u32> = self
            .vertex_triangles(v)
            .iter()
            .flat_map(|&t| mesh.triangles[t as usize])
            .filter(|&w| w as usize != v)
            .collect();
        neighbors.sort_unstable();
        neighbors.dedup();
        neighbors
    }

    /// Closed loops of boundary vertices, each in the direction of its triangles' edges
    /// (so a hole in an outward-oriented surface runs clockwise seen from outside).
    /// Non-manifold edges are left out.
    pub fn boundary_loops(&self, mesh: &TriMesh) -> Vec<Vec<u32>> {
        let non_manifold = self.non_manifold_edges(mesh);
        // Boundary half-edges as (from, to), indexed by their start vertex.
        let mut outgoing: Vec<Vec<u32>> = vec![Vec::new(); mesh.positions.len()];
        let mut count = 0usize;
        for (t, tri) in mesh.triangles.iter().enumerate() {
            for k in 0..3 {
                if self.triangle_neighbors[t][k] != NO_TRIANGLE {
                    continue;
                }
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if non_manifold.binary_search(&edge_key(a, b)).is_ok() {
                    continue;
                }
                outgoing[a as usize].push(b);
                count += 1;
            }
        }
        let mut loops = Vec::new();
        let mut used = 0usize;
        for start in 0..outgoing.len() {
            while let Some(next) = outgoing[start].pop() {
                let mut boundary = vec![start as u32];
                let mut current = next;
                used += 1;
                while current as usize != start {
                    boundary.push(current);
                    match outgoing[current as usize].pop() {
                        Some(n) => {
                            current = n;
                            used += 1;
                        }
                        None => break, // open chain at a bow-tie vertex; keep what we have
                    }
                }
                loops.push(boundary);
            }
        }
        debug_assert!(used <= count);
        loops
    }

    /// Connected components (through shared edges) as a component index per triangle,
    /// and the number of components.
    pub fn triangle_components(&self) -> (Vec<u32>, usize) {
        self.triangle_components_among(|_| true)
    }

    /// Connected components (through shared edges) of the triangles `included` accepts
    /// (by index), as a component index per triangle (`u32::MAX` for the others), and
    /// the number of components.
    pub fn triangle_components_among(&self, included: impl Fn(usize) -> bool) -> (Vec<u32>, usize) {
        let n = self.triangle_neighbors.len();
        let mut component = vec![u32::MAX; n];
        let mut count = 0u32;
        let mut stack = Vec::new();
        for seed in 0..n {
            if component[seed] != u32::MAX || !included(seed) {
                continue;
            }
            component[seed] = count;
            stack.push(seed as u32);
            while let Some(t) = stack.pop() {
                for &neighbor in &self.triangle_neighbors[t as usize] {
                    if neighbor != NO_TRIANGLE
                        && component[neighbor as usize] == u32::MAX
                        && included(neighbor as usize)
                    {
                        component[neighbor as usize] = count;
                        stack.push(neighbor);
                    }
                }
            }
            count += 1;
        }
        (component, count as usize)
    }

    /// Sorted undirected keys of the edges shared by more than two triangles.
    fn non_manifold_edges(&self, mesh: &TriMesh) -> Vec<u64> {
        if self.non_manifold_edge_count == 0 {
            return Vec::new();
        }
        let mut keys: Vec<u64> = mesh
            .triangles
            .iter()
            .flat_map(|tri| (0..3).map(move |k| edge_key(tri[k], tri[(k + 1) % 3])))
            .collect();
        keys.sort_unstable();
        let mut repeated: Vec<u64> = keys
            .chunk_by(|a, b| a == b)
            .filter(|g| g.len() > 2)
            .map(|g| g[0])
            .collect();
        repeated.dedup();
        repeated
    }
}

#[inline]
pub(crate) fn edge_key(a: u32, b: u32) -> u64 {
    ((a.min(b) as u64) << 32) | a.max(b) as u64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::grid;
    use glam::DVec3;

    #[test]
    fn grid_has_one_boundary_loop_of_perimeter_length() {
        let mesh = grid(4, 4, 1.0);
        let topology = Topology::new(&mesh);
        let loops = topology.boundary_loops(&mesh);
        assert_eq!(loops.len(), 1);
        assert_eq!(loops[0].len(), 16);
        assert_eq!(topology.boundary_edge_count, 16);
        assert_eq!(topology.inconsistent_edge_count, 0);
        assert_eq!(topology.triangle_components().1, 1);
        // Interior vertex (2,2) has six neighbours in this triangulation.
        assert_eq!(topology.vertex_neighbors(&mesh, 12).len(), 6);
        assert_eq!(topology.vertex_triangles(12).len(), 6);
    }

    #[test]
    fn two_separate_grids_are_two_components() {
        let mut mesh = grid(2, 2, 1.0);
        let other = grid(2, 2, 1.0);
        let offset = mesh.positions.len() as u32;
        mesh.positions.extend(
            other
                .positions
                .iter()
                .map(|p| *p + DVec3::new(10.0, 0.0, 0.0)),
        );
        mesh.triangles
            .extend(other.triangles.iter().map(|t| t.map(|v| v + offset)));
        let topology = Topology::new(&mesh);
        let (component, count) = topology.triangle_components();
        assert_eq!(count, 2);
        assert_ne!(component[0], component[component.len() - 1]);
        assert_eq!(topology.boundary_loops(&mesh).len(), 2);
    }

    /// A strip of four triangles (1-0-3-2 through shared edges) without its second:
    /// the first apart from the last two, the left-out one in none.
    #[test]
    fn components_among_some_triangles_split_where_one_is_left_out() {
        let mesh = grid(2, 1, 1.0);
        let topology = Topology::new(&mesh);
        assert_eq!(topology.triangle_components().1, 1);
        let (component, count) = topology.triangle_components_among(|t| t != 0);
        assert_eq!(count, 2);
        assert_eq!(component[0], u32::MAX);
        assert_eq!(component[2], component[3]);
        assert_ne!(component[1], component[2]);
    }

    #[test]
    fn flipped_triangle_is_counted_as_inconsistent() {
        let mut mesh = grid(1, 1, 1.0);
        mesh.triangles[1].swap(1, 2);
        assert_eq!(Topology::new(&mesh).inconsistent_edge_count, 1);
    }
}
