//! Membranes on the faces of a tetrahedral model: their energy, forces and assembled
//! stiffness against independent expectations.

mod common;

use common::*;
use fem::{
    Constraints, FemModel, Formulation, Material, Membrane, ReducedSystem, Tangent, box_mesh,
};
use glam::DVec3;
use tetra::TetMesh;

const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

/// Membranes of `thickness_mm` and `material` on every face of `mesh` whose three
/// vertices satisfy `on`.
fn membranes_on(
    mesh: &TetMesh,
    on: impl Fn(DVec3) -> bool,
    material: Material,
    thickness_mm: f64,
) -> Vec<Membrane> {
    let mut out = Vec::new();
    for (e, tet) in mesh.tets.iter().enumerate() {
        for face in FACES {
            let face = face.map(|i| tet[i]);
            if face.iter().all(|&v| on(mesh.positions[v as usize])) {
                out.push(Membrane {
                    element: e as u32,
                    face,
                    material,
                    thickness_mm,
                });
            }
        }
    }
    out
}

/// A 40 x 20 x 10 mm slab with a membrane on its top face (z = 10).
fn slab_with_top_membrane(tissue: Material, sheet: Material, thickness_mm: f64) -> FemModel {
    let mesh = box_mesh(DVec3::ZERO, DVec3::new(40.0, 20.0, 10.0), [8, 4, 2]);
    let mut model = FemModel::homogeneous(&mesh, tissue).unwrap();
    let top = membranes_on(&mesh, |p| p.z == 10.0, sheet, thickness_mm);
    assert_eq!(top.len(), 8 * 4 * 2, "two triangles per top cell");
    model.set_membranes(&top).unwrap();
    model
}

#[test]
fn a_stretched_slab_stores_the_tissue_and_the_membrane_energy() {
    // Stretched along x by ε with the Poisson contraction (the same ratio in the tissue
    // and the sheet), every tetrahedron is in uniaxial stress E ε and the sheet in plane
    // stress E_m ε: the energy is ½ ε² (E V + E_m t A_top), to round-off, in both
    // formulations (the corotated rotation is the identity for a pure stretch).
    let tissue = Material::new(2.4, 0.45);
    let sheet = Material::new(340.0, 0.45);
    let model = slab_with_top_membrane(tissue, sheet, 1.5);
    let strain = 0.04;
    let nu = 0.45;
    let u: Vec<DVec3> = model
        .rest_positions()
        .iter()
        .map(|p| DVec3::new(p.x, -nu * p.y, -nu * p.z) * strain)
        .collect();
    let expected = 0.5 * strain * strain * (2.4 * 8000.0 + 340.0 * 1.5 * 800.0);
    for formulation in [Formulation::Linear, Formulation::Corotated] {
        let energy = model.potential_energy(&u, &[], formulation);
        assert!(
            (energy - expected).abs() < 1e-9 * expected,
            "{formulation:?}: {energy} against {expected}"
        );
    }
}

#[test]
fn the_forces_with_membranes_are_the_energy_gradient() {
    // Turned, stretched and uneven: central differences of the potential energy (step
    // 1e-6 mm) against the internal forces, and the assembled system's nodal forces
    // against the model's, to 1e-6 of the largest force (differencing error far below).
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(20.0, 10.0, 10.0), [2, 2, 2], 0.1);
    let mut model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let sheet = Material::new(340.0, 0.45);
    model
        .set_membranes(&membranes_on(
            &mesh,
            |p| p.z == 10.0 || p.x == 0.0,
            sheet,
            1.5,
        ))
        .unwrap();
    let q = generic_rotation();
    let u: Vec<DVec3> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(k, &x)| {
            q * (x * 1.05 + DVec3::new(0.02 * x.z, 0.0, 0.0)) - x
                + DVec3::new((k % 3) as f64, (k % 2) as f64, (k % 5) as f64) * 0.1
        })
        .collect();
    let forces = model.internal_forces(&u, Formulation::Corotated).unwrap();
    let gradient = energy_gradient(&model, &u, Formulation::Corotated, 1e-6);
    let largest = max_norm(&forces);
    assert!(max_diff(&forces, &gradient) < 1e-6 * largest);
    let mut c = Constraints::new();
    c.fix(0);
    let mut system = ReducedSystem::new(&model, &c).unwrap();
    system
        .assemble(&model, &u, &[], Formulation::Corotated, Tangent::Warped)
        .unwrap();
    assert!(max_diff(&system.nodal_forces(&model), &forces) < 1e-12 * largest);
}

#[test]
fn the_assembled_matrix_is_the_force_derivative_at_rest() {
    // At rest no element or membrane is stressed, so the warped matrix is the exact
    // derivative of the residual in both formulations: K δ against the central
    // difference of the right-hand side (step 1e-6 mm) to 1e-6 relative. Without the
    // membranes' blocks it would be off by their stiffness, 140 times the tissue's.
    let tissue = Material::new(2.4, 0.45);
    let model = slab_with_top_membrane(tissue, Material::new(340.0, 0.45), 1.5);
    let mut c = Constraints::new();
    for (v, p) in model.rest_positions().iter().enumerate() {
        if p.z == 0.0 {
            c.fix(v as u32);
        }
    }
    let mut system = ReducedSystem::new(&model, &c).unwrap();
    let delta: Vec<DVec3> = (0..system.unknowns())
        .map(|k| DVec3::new(((k * 7) % 11) as f64 - 5.0, ((k * 3) % 5) as f64 - 2.0, 1.0) / 5.0)
        .collect();
    let h = 1e-6;
    for formulation in [Formulation::Linear, Formulation::Corotated] {
        let mut residual = |s: f64| {
            let uf: Vec<DVec3> = delta.iter().map(|d| *d * s).collect();
            let u = system.expand(&uf);
            system
                .assemble(&model, &u, &[], formulation, Tangent::Warped)
                .unwrap();
            system.rhs.clone()
        };
        let (rp, rm) = (residual(h), residual(-h));
        let fd: Vec<DVec3> = rp
            .iter()
            .zip(&rm)
            .map(|(a, b)| (*b - *a) / (2.0 * h))
            .collect();
        residual(0.0);
        let mut kd = vec![DVec3::ZERO; delta.len()];
        system.matrix.mul_vec(&delta, &mut kd);
        let rel = max_diff(&kd, &fd) / max_norm(&fd);
        assert!(rel < 1e-6, "{formulation:?}: {rel}");
    }
}

#[test]
fn a_membrane_off_its_element_is_refused_and_leaves_the_model() {
    let mesh = box_mesh(DVec3::ZERO, DVec3::splat(10.0), [1, 1, 1]);
    let mut model = FemModel::homogeneous(&mesh, Material::default()).unwrap();
    let good = membranes_on(&mesh, |p| p.z == 10.0, Material::new(340.0, 0.45), 1.5);
    model.set_membranes(&good).unwrap();
    let mut bad = good.clone();
    bad[0].element = 10_000;
    assert!(model.set_membranes(&bad).is_err());
    assert_eq!(model.membrane_count(), good.len());
}
