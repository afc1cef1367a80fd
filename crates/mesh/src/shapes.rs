//! Meshes of shapes with known answers (areas, volumes, geodesics), for tests and
//! benchmarks across the workspace.

use crate::trimesh::TriMesh;
use glam::DVec3;
use std::collections::HashMap;

/// A planar grid of `nx` x `ny` squares of side `spacing_mm` in z = 0, two triangles per
/// square, normals +z. Vertex `(i, j)` has index `j * (nx + 1) + i`.
pub fn grid(nx: usize, ny: usize, spacing_mm: f64) -> TriMesh {
    let mut positions = Vec::with_capacity((nx + 1) * (ny + 1));
    for j in 0..=ny {
        for i in 0..=nx {
            positions.push(DVec3::new(i as f64, j as f64, 0.0) * spacing_mm);
        }
    }
    let id = |i: usize, j: usize| (j * (nx + 1) + i) as u32;
    let mut triangles = Vec::with_capacity(2 * nx * ny);
    for j in 0..ny {
        for i in 0..nx {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(positions, triangles)
}

/// An axis-aligned cube `[0, size]³` as 12 outward triangles.
pub fn cube(size_mm: f64) -> TriMesh {
    let positions = (0..8)
        .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64) * size_mm)
        .collect();
    let triangles = vec![
        [0, 2, 1],
        [1, 2, 3],
        [4, 5, 6],
        [5, 7, 6],
        [0, 1, 4],
        [1, 5, 4],
        [2, 6, 3],
        [3, 6, 7],
        [0, 4, 2],
        [2, 4, 6],
        [1, 3, 5],
        [3, 7, 5],
    ];
    TriMesh::new(positions, triangles)
}

/// A sphere of `radius_mm` about the origin: an icosahedron subdivided `subdivisions`
/// times (20·4^s triangles), vertices projected onto the sphere, outward oriented.
pub fn icosphere(radius_mm: f64, subdivisions: u32) -> TriMesh {
    let phi = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<DVec3> = [
        [-1.0, phi, 0.0],
        [1.0, phi, 0.0],
        [-1.0, -phi, 0.0],
        [1.0, -phi, 0.0],
        [0.0, -1.0, phi],
        [0.0, 1.0, phi],
        [0.0, -1.0, -phi],
        [0.0, 1.0, -phi],
        [phi, 0.0, -1.0],
        [phi, 0.0, 1.0],
        [-phi, 0.0, -1.0],
        [-phi, 0.0, 1.0],
    ]
    .iter()
    .map(|p| DVec3::from_array(*p).normalize())
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<DVec3>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                positions.push((positions[a as usize] + positions[b as usize]).normalize());
                (positions.len() - 1) as u32
            })
        };
        let mut finer = Vec::with_capacity(4 * triangles.len());
        for &[a, b, c] in &triangles {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    for p in &mut positions {
        *p *= radius_mm;
    }
    TriMesh::new(positions, triangles)
}

/// An open cylinder of `radius_mm` around the z axis from z = 0 to `height_mm`, with
/// `segments` around and `rings` along, normals pointing outward.
/// Vertex `(i, j)` (angle index `i`, ring `j`) has index `j * segments + i`.
pub fn cylinder(radius_mm: f64, height_mm: f64, segments: usize, rings: usize) -> TriMesh {
    let mut positions = Vec::with_capacity(segments * (rings + 1));
    for j in 0..=rings {
        let z = height_mm * j as f64 / rings as f64;
        for i in 0..segments {
            let angle = std::f64::consts::TAU * i as f64 / segments as f64;
            positions.push(DVec3::new(
                radius_mm * angle.cos(),
                radius_mm * angle.sin(),
                z,
            ));
        }
    }
    let id = |i: usize, j: usize| (j * segments + i % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * segments * rings);
    for j in 0..rings {
        for i in 0..segments {
            triangles.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            triangles.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    TriMesh::new(positions, triangles)
}

/// A torus about the `z` axis: tube centre radius `major_mm`, tube radius `minor_mm`,
/// `around` x `tube` quads split in two, outward oriented; vertex `(i, j)` (index
/// `i * tube + j`) lies `i` steps around the axis from `+x` and `j` steps around the
/// tube from its outer equator. Area `4π² R r`, volume `2π² R r²` (up to the facets).
pub fn torus(major_mm: f64, minor_mm: f64, around: usize, tube: usize) -> TriMesh {
    let index = |i: usize, j: usize| ((i % around) * tube + j % tube) as u32;
    let mut positions = Vec::with_capacity(around * tube);
    for i in 0..around {
        let phi = std::f64::consts::TAU * i as f64 / around as f64;
        for j in 0..tube {
            let theta = std::f64::consts::TAU * j as f64 / tube as f64;
            let radius = major_mm + minor_mm * theta.cos();
            positions.push(DVec3::new(
                radius * phi.cos(),
                radius * phi.sin(),
                minor_mm * theta.sin(),
            ));
        }
    }
    let mut triangles = Vec::with_capacity(2 * around * tube);
    for i in 0..around {
        for j in 0..tube {
            let [a, b, c, d] = [
                index(i, j),
                index(i + 1, j),
                index(i + 1, j + 1),
                index(i, j + 1),
            ];
            triangles.push([a, b, c]);
            triangles.push([a, c, d]);
        }
    }
    TriMesh::new(positions, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::topology::Topology;
    use std::f64::consts::PI;

    #[test]
    fn icosphere_is_closed_outward_and_converges_to_the_sphere_volume() {
        let mesh = icosphere(10.0, 5);
        let topology = Topology::new(&mesh);
        assert_eq!(topology.boundary_edge_count, 0);
        assert_eq!(topology.inconsistent_edge_count, 0);
        // An inscribed polyhedron: volume slightly below 4/3 pi r^3; at 20480 faces the
        // relative deficit is about 3e-4, bounded here by 1e-3.
        let exact = 4.0 / 3.0 * PI * 1000.0;
        let volume = mesh.signed_volume();
        assert!(
            volume < exact && volume > exact * (1.0 - 1e-3),
            "{volume} vs {exact}"
        );
    }

    #[test]
    fn cylinder_area_converges() {
        let mesh = cylinder(5.0, 20.0, 256, 8);
        let exact = 2.0 * PI * 5.0 * 20.0;
        // Chord deficit of a 256-gon: 1 - sin(2pi/256)/(2pi/256) ~ 1e-4.
        assert!((mesh.area() - exact).abs() / exact < 2e-4);
    }
}
