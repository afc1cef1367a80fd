//! Closed test surfaces with known volumes, shared by the tests and the benchmark; in
//! `vtu`, what the VTU tests share.
// Each test crate uses some of these shapes only.
#![allow(dead_code)]

pub mod vtu;

use glam::DVec3;
use mesh::TriMesh;

/// An ellipsoid with semi-axes `radii` (mm) as a latitude-longitude mesh with `slices`
/// around the z axis and `stacks` from pole to pole: `2 slices (stacks - 1)` triangles,
/// outward oriented. Volume `4/3 π a b c`.
pub fn ellipsoid(radii: DVec3, slices: usize, stacks: usize) -> TriMesh {
    let mut positions = vec![DVec3::new(0.0, 0.0, -radii.z)];
    for s in 1..stacks {
        let polar = std::f64::consts::PI * s as f64 / stacks as f64;
        for k in 0..slices {
            let azimuth = std::f64::consts::TAU * k as f64 / slices as f64;
            let unit = DVec3::new(
                polar.sin() * azimuth.cos(),
                polar.sin() * azimuth.sin(),
                -polar.cos(),
            );
            positions.push(unit * radii);
        }
    }
    positions.push(DVec3::new(0.0, 0.0, radii.z));
    let top = (positions.len() - 1) as u32;
    let ring = |s: usize, k: usize| (1 + (s - 1) * slices + k % slices) as u32;
    let mut triangles = Vec::new();
    for k in 0..slices {
        triangles.push([0, ring(1, k + 1), ring(1, k)]);
        triangles.push([top, ring(stacks - 1, k), ring(stacks - 1, k + 1)]);
    }
    for s in 1..stacks - 1 {
        for k in 0..slices {
            triangles.push([ring(s, k), ring(s, k + 1), ring(s + 1, k + 1)]);
            triangles.push([ring(s, k), ring(s + 1, k + 1), ring(s + 1, k)]);
        }
    }
    TriMesh::new(positions, triangles)
}
