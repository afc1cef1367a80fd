//! Structured tetrahedral meshes of an axis-aligned box, for tests and benchmarks.

use glam::DVec3;
use tetmesh::TetMesh;

/// The six tetrahedra of the Kuhn (Freudenthal) subdivision of a cube, as corner indices
/// `i + 2j + 4k` of the corner at offset `(i, j, k)`. Every tetrahedron contains the main
/// diagonal from corner 0 to corner 7; each follows one monotone lattice path
/// 0 → 7 along the three axes in one of the 3! orders. The subdivision is the same in
/// every cube, so neighbouring cubes share their face diagonals and the mesh conforms.
/// Orientation is fixed to positive by [`box_mesh`].
const KUHN: [[usize; 4]; 6] = [
    [0, 1, 3, 7], // x, y, z
    [0, 1, 5, 7], // x, z, y
    [0, 2, 3, 7], // y, x, z
    [0, 2, 6, 7], // y, z, x
    [0, 4, 5, 7], // z, x, y
    [0, 4, 6, 7], // z, y, x
];

/// Index of the lattice vertex `(i, j, k)` in a [`box_mesh`] with `n` cells per axis:
/// `i + (n[0] + 1) * (j + (n[1] + 1) * k)`.
pub fn box_vertex_index(n: [usize; 3], i: usize, j: usize, k: usize) -> u32 {
    (i + (n[0] + 1) * (j + (n[1] + 1) * k)) as u32
}

/// A structured tetrahedral mesh of the box `[min, max]` with `n = [nx, ny, nz]` cubes
/// (cells) per axis, six tetrahedra per cell (Kuhn subdivision, conforming), every
/// tetrahedron positively oriented: `(b - a) · ((c - a) × (d - a)) > 0`.
///
/// Vertices are the `(nx+1)(ny+1)(nz+1)` lattice points in the order of
/// [`box_vertex_index`] (x fastest); tetrahedra are listed cell by cell, x fastest.
///
/// # Panics
/// If a cell count is zero or `max` is not greater than `min` on every axis.
pub fn box_mesh(min: DVec3, max: DVec3, n: [usize; 3]) -> TetMesh {
    assert!(n.iter().all(|&c| c > 0), "box_mesh: zero cells on an axis");
    assert!(max.cmpgt(min).all(), "box_mesh: empty box {min} .. {max}");
    let h = (max - min) / DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    let mut positions = Vec::with_capacity((n[0] + 1) * (n[1] + 1) * (n[2] + 1));
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                let p = min + h * DVec3::new(i as f64, j as f64, k as f64);
                // exact end points, no rounding drift at the far faces
                positions.push(DVec3::new(
                    if i == n[0] { max.x } else { p.x },
                    if j == n[1] { max.y } else { p.y },
                    if k == n[2] { max.z } else { p.z },
                ));
            }
        }
    }
    // orientation of each Kuhn tetrahedron on the unit cube (independent of h > 0)
    let corner = |c: usize| DVec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, (c >> 2) as f64);
    let kuhn: Vec<[usize; 4]> = KUHN
        .iter()
        .map(|&[a, b, c, d]| {
            let (pa, pb, pc, pd) = (corner(a), corner(b), corner(c), corner(d));
            if (pb - pa).dot((pc - pa).cross(pd - pa)) > 0.0 {
                [a, b, c, d]
            } else {
                [a, c, b, d]
            }
        })
        .collect();
    let mut tets = Vec::with_capacity(6 * n[0] * n[1] * n[2]);
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let v =
                    |c: usize| box_vertex_index(n, i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2));
                for t in &kuhn {
                    tets.push(t.map(v));
                }
            }
        }
    }
    TetMesh { positions, tets }
}

/// Whether vertex `v` of a [`box_mesh`] with `n` cells per axis lies on the boundary.
pub fn box_is_boundary(n: [usize; 3], v: u32) -> bool {
    let v = v as usize;
    let i = v % (n[0] + 1);
    let j = (v / (n[0] + 1)) % (n[1] + 1);
    let k = v / ((n[0] + 1) * (n[1] + 1));
    i == 0 || j == 0 || k == 0 || i == n[0] || j == n[1] || k == n[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_mesh_is_valid_and_fills_the_box() {
        let n = [3, 2, 4];
        let m = box_mesh(DVec3::new(-1.0, 0.0, 2.0), DVec3::new(2.0, 1.0, 6.0), n);
        assert_eq!(m.tets.len(), 6 * 24);
        assert_eq!(m.positions.len(), 4 * 3 * 5);
        m.validate().unwrap();
        assert!((m.volume_mm3() - 12.0).abs() < 1e-12);
        // conforming: the boundary is exactly the box surface, 2 triangles per cell face
        let b = m.boundary();
        assert_eq!(b.mesh.triangles.len(), 2 * 2 * (3 * 2 + 2 * 4 + 3 * 4));
        let boundary_count = (0..m.positions.len() as u32)
            .filter(|&v| box_is_boundary(n, v))
            .count();
        assert_eq!(boundary_count, 60 - 6);
    }
}
