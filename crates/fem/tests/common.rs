//! Shared helpers of the integration tests.
#![allow(dead_code)]

use fem::multigrid::{Multigrid, MultigridOptions};
use fem::{
    Constraints, FemModel, Formulation, Material, STANDARD_GRAVITY_M_S2, box_is_boundary, box_mesh,
};
use glam::{DMat3, DVec3};
use tetra::TetMesh;

/// A box mesh whose interior vertices are moved by a deterministic pseudo-random offset
/// of up to `jitter` cell sizes per axis, so that the mesh is irregular (a stronger
/// patch test). All elements stay positively oriented for `jitter <= 0.15`.
pub fn jittered_box(min: DVec3, max: DVec3, n: [usize; 3], jitter: f64) -> TetMesh {
    let mut m = box_mesh(min, max, n);
    let h = (max - min) / DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64);
    for (v, p) in m.positions.iter_mut().enumerate() {
        if !box_is_boundary(n, v as u32) {
            let r = |k: u64| {
                let mut x = (v as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
                    ^ k.wrapping_mul(0xD1B5_4A32_D192_ED03);
                x ^= x >> 31;
                x = x.wrapping_mul(0xBF58_476D_1CE4_E5B9);
                x ^= x >> 29;
                (x >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
            };
            *p += DVec3::new(r(1), r(2), r(3)) * h * jitter;
        }
    }
    m.validate().expect("jittered mesh stays valid");
    m
}

/// Largest |a - b| over two fields.
pub fn max_diff(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length())
        .fold(0.0, f64::max)
}

/// Largest |a|.
pub fn max_norm(a: &[DVec3]) -> f64 {
    a.iter().map(|x| x.length()).fold(0.0, f64::max)
}

/// Frobenius norm of a 3x3 matrix.
pub fn frob(m: DMat3) -> f64 {
    m.to_cols_array().iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// A generic rotation (axis (1, 2, 3), 70 degrees).
pub fn generic_rotation() -> DMat3 {
    DMat3::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 70f64.to_radians())
}

/// The gradient of `model`'s potential energy at `u` by central differences of step
/// `h` (mm), for checking that internal forces are conservative.
pub fn energy_gradient(
    model: &FemModel,
    u: &[DVec3],
    formulation: Formulation,
    h: f64,
) -> Vec<DVec3> {
    let mut gradient = vec![DVec3::ZERO; u.len()];
    for v in 0..u.len() {
        for axis in 0..3 {
            let mut plus = u.to_vec();
            let mut minus = u.to_vec();
            plus[v][axis] += h;
            minus[v][axis] -= h;
            gradient[v][axis] = (model.potential_energy(&plus, &[], formulation)
                - model.potential_energy(&minus, &[], formulation))
                / (2.0 * h);
        }
    }
    gradient
}

/// A jittered 20 mm box of 2.4 kPa tissue (Poisson ratio 0.45) and a displacement that
/// squeezes it to 40% of its height with a shear: about half its elements below half
/// their volume.
pub fn squeezed_box() -> (FemModel, Vec<DVec3>) {
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(20.0, 20.0, 20.0), [2, 2, 2], 0.15);
    let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let u = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(k, x)| DVec3::new(0.2 * x.z, 0.05 * (k % 3) as f64, -0.6 * x.z))
        .collect();
    (model, u)
}

/// Relative 2-norm of `a - b` over `b`.
pub fn rel_diff(a: &[DVec3], b: &[DVec3]) -> f64 {
    let d: f64 = a
        .iter()
        .zip(b)
        .map(|(x, y)| (*x - *y).length_squared())
        .sum();
    let n: f64 = b.iter().map(|x| x.length_squared()).sum();
    (d / n).sqrt()
}

/// A multigrid hierarchy over boxes of `size` (mm) of 3 kPa tissue (Poisson ratio
/// 0.45) with the given cell counts, finest first (the finest jittered by 0.15 cells,
/// the coarser regular), each level held by `constraints_for` its mesh; and the finest
/// level's gravity forces (along -z).
pub fn box_hierarchy(
    size: DVec3,
    cells: &[[usize; 3]],
    constraints_for: impl Fn(&TetMesh) -> Constraints,
    options: MultigridOptions,
) -> (Multigrid, Vec<DVec3>) {
    let material = Material::new(3.0, 0.45);
    let mut levels = Vec::new();
    let mut gravity = Vec::new();
    for (l, &n) in cells.iter().enumerate() {
        let mesh = if l == 0 {
            jittered_box(DVec3::ZERO, size, n, 0.15)
        } else {
            box_mesh(DVec3::ZERO, size, n)
        };
        let model = FemModel::homogeneous(&mesh, material).unwrap();
        if l == 0 {
            gravity = model
                .gravity_forces(DVec3::new(0.0, 0.0, -STANDARD_GRAVITY_M_S2))
                .unwrap();
        }
        levels.push((model, constraints_for(&mesh)));
    }
    let mg = Multigrid::new(levels, options).unwrap();
    (mg, gravity)
}
