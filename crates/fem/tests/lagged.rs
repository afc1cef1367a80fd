//! Cycles on kept operators (`Multigrid::lagged_cycle`): the right-hand side they form
//! is the full assembly's, and they converge to the same equilibrium as fresh cycles.

mod common;

use common::*;
use fem::multigrid::{Multigrid, MultigridOptions};
use fem::{Constraints, FemModel, Formulation, Material, Membrane, ReducedSystem, Slider, Tangent};
use glam::DVec3;
use tetra::TetMesh;

const SIZE: DVec3 = DVec3::new(100.0, 60.0, 60.0);
const CELLS: [[usize; 3]; 2] = [[20, 12, 12], [7, 4, 4]];

/// Fixed bottom, a dimple pressed 12 mm into the top (large rotations around it).
fn constraints_for(mesh: &TetMesh) -> Constraints {
    let mut c = Constraints::new();
    for (v, x) in mesh.positions.iter().enumerate() {
        let r = ((x.x - 50.0).powi(2) + (x.y - 30.0).powi(2)).sqrt();
        if x.z <= 1e-9 {
            c.fix(v as u32);
        } else if x.z >= SIZE.z - 1e-9 && r <= 20.0 {
            let s = (std::f64::consts::PI * r / 40.0).cos().powi(2);
            c.prescribe(v as u32, DVec3::new(0.0, 0.0, -12.0 * s));
        }
    }
    c
}

/// A two-level hierarchy over the box under gravity, and the gravity forces.
fn hierarchy() -> (Multigrid, Vec<DVec3>) {
    box_hierarchy(SIZE, &CELLS, constraints_for, MultigridOptions::default())
}

/// The right-hand side of the forces-only pass equals the full assembly's to the bit
/// (the same sums in the same order) at a deformed state with large rotations, with
/// membranes on the top face, a slider and an external force, in both formulations;
/// and the reaction norm the relative residual is measured against equals too.
#[test]
fn the_forces_only_right_hand_side_is_the_full_assemblys() {
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(40.0, 20.0, 10.0), [8, 4, 2], 0.15);
    let mut model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let mut membranes = Vec::new();
    for (e, tet) in mesh.tets.iter().enumerate() {
        for face in [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]] {
            let face = face.map(|i| tet[i]);
            if face.iter().all(|&v| mesh.positions[v as usize].z == 10.0) {
                membranes.push(Membrane {
                    element: e as u32,
                    face,
                    material: Material::new(340.0, 0.45),
                    thickness_mm: 1.5,
                });
            }
        }
    }
    assert!(!membranes.is_empty());
    model.set_membranes(&membranes).unwrap();
    let top = (mesh.positions.iter()).position(|p| p.z == 10.0).unwrap() as u32;
    model
        .set_sliders(&[Slider {
            vertex: top,
            displacement: DVec3::new(0.0, 0.0, 1.0),
            normal: DVec3::Z,
            stiffness_mn_per_mm: 50.0,
        }])
        .unwrap();
    let mut constraints = Constraints::new();
    for (v, p) in mesh.positions.iter().enumerate() {
        if p.x == 0.0 {
            constraints.fix(v as u32);
        }
    }
    // bent up by a quarter turn about y over the length, with a twist
    let u: Vec<DVec3> = (mesh.positions.iter())
        .map(|p| {
            let angle = std::f64::consts::FRAC_PI_2 * p.x / 40.0;
            let (s, c) = angle.sin_cos();
            let turned = DVec3::new(p.x * c - p.z * s, p.y + 0.1 * p.x * p.z, p.x * s + p.z * c);
            turned - *p
        })
        .collect();
    let f_ext: Vec<DVec3> = (0..u.len())
        .map(|v| DVec3::new(0.0, 0.01 * v as f64, -0.2))
        .collect();
    for formulation in [Formulation::Linear, Formulation::Corotated] {
        let mut full = ReducedSystem::new(&model, &constraints).unwrap();
        let u = full.expand(
            &(full.free.iter())
                .map(|&v| u[v as usize])
                .collect::<Vec<_>>(),
        );
        full.assemble(&model, &u, &f_ext, formulation, Tangent::Warped)
            .unwrap();
        let mut forces = ReducedSystem::new(&model, &constraints).unwrap();
        forces
            .assemble_forces(&model, &u, &f_ext, formulation)
            .unwrap();
        assert!(
            full.rhs.iter().any(|r| r.length() > 1e-3),
            "{formulation:?}"
        );
        assert_eq!(full.rhs, forces.rhs, "{formulation:?}");
        assert_eq!(
            full.reaction_norm_squared(),
            forces.reaction_norm_squared(),
            "{formulation:?}"
        );
    }
}

/// The linear formulation's operators do not depend on the displacement, so cycles on
/// kept operators are the fresh cycles themselves: five of each from zero agree to
/// round-off (1e-12 relative; the parallel sums' order may differ from run to run), and
/// every one after the first kept the operators.
#[test]
fn lagged_linear_cycles_are_fresh_ones() {
    let (mut fresh, gravity) = hierarchy();
    let (mut lagged, _) = hierarchy();
    let n = fresh.model().vertex_count();
    let (mut u_fresh, mut u_lagged) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
    for k in 0..5 {
        let a = fresh
            .cycle(&mut u_fresh, &gravity, Formulation::Linear)
            .unwrap();
        let b = lagged
            .lagged_cycle(&mut u_lagged, &gravity, Formulation::Linear, f64::INFINITY)
            .unwrap();
        assert!(!a.operators_lagged);
        assert_eq!(b.operators_lagged, k > 0, "cycle {k}");
        let residuals = (a.residual_before - b.residual_before).abs();
        assert!(
            residuals <= 1e-12 * a.residual_before,
            "cycle {k}: {a:?} {b:?}"
        );
    }
    // the parallel sums' order may differ between runs: to round-off
    let difference = rel_diff(&u_lagged, &u_fresh);
    assert!(difference < 1e-12, "{difference}");
}

/// Corotated, with a dimple that turns the elements around it: after linear warm-up
/// cycles, cycles on operators kept from the third corotated cycle on converge to the
/// fresh cycles' equilibrium. Both run until the residual is 1e-9 of the first; they
/// then agree to 1e-9 relative (measured 2e-12: both end within round-off of the same
/// equilibrium, which the bound leaves room for however the box's condition scales
/// the residual).
#[test]
fn lagged_corotated_cycles_reach_the_fresh_equilibrium() {
    let solve = |lag_from: usize| {
        let (mut mg, gravity) = hierarchy();
        let mut u = vec![DVec3::ZERO; mg.model().vertex_count()];
        let mut first = None;
        // linear cycles first, as the session warms up: from zero, corotated cycles
        // push the dimple's vertices through their neighbours
        for _ in 0..3 {
            mg.cycle(&mut u, &gravity, Formulation::Linear).unwrap();
        }
        for k in 0..200 {
            let report = if k >= lag_from {
                mg.lagged_cycle(&mut u, &gravity, Formulation::Corotated, f64::INFINITY)
            } else {
                mg.cycle(&mut u, &gravity, Formulation::Corotated)
            }
            .unwrap();
            assert_eq!(report.operators_lagged, k >= lag_from, "cycle {k}");
            let first = *first.get_or_insert(report.residual_before);
            if report.residual_before < 1e-9 * first {
                return (u, k);
            }
        }
        panic!("no convergence with operators kept from cycle {lag_from}");
    };
    let (u_fresh, fresh_cycles) = solve(usize::MAX);
    let (u_lagged, lagged_cycles) = solve(2);
    let difference = rel_diff(&u_lagged, &u_fresh);
    println!("fresh {fresh_cycles} cycles, lagged {lagged_cycles}; difference {difference:e}");
    assert!(difference < 1e-9, "{difference}");
}

/// A change of constraints, tangent, formulation or material drops the kept operators:
/// the next lagged cycle assembles afresh; so does a residual not below the limit.
#[test]
fn a_change_drops_the_kept_operators() {
    let (mut mg, gravity) = hierarchy();
    let mut u = vec![DVec3::ZERO; mg.model().vertex_count()];
    let mut lagged = |mg: &mut Multigrid, formulation| {
        mg.lagged_cycle(&mut u, &gravity, formulation, f64::INFINITY)
            .unwrap()
            .operators_lagged
    };
    assert!(!lagged(&mut mg, Formulation::Corotated));
    assert!(lagged(&mut mg, Formulation::Corotated));
    assert!(!lagged(&mut mg, Formulation::Linear));
    assert!(lagged(&mut mg, Formulation::Linear));
    mg.set_tangent(Tangent::Full);
    assert!(!lagged(&mut mg, Formulation::Corotated));
    let mesh = jittered_box(DVec3::ZERO, SIZE, CELLS[0], 0.15);
    mg.set_constraints(&constraints_for(&mesh)).unwrap();
    assert!(!lagged(&mut mg, Formulation::Corotated));
    mg.set_material(0, Material::new(6.0, 0.45)).unwrap();
    assert!(!lagged(&mut mg, Formulation::Corotated));
    assert!(lagged(&mut mg, Formulation::Corotated));
    mg.set_sliders(&[]).unwrap();
    assert!(!lagged(&mut mg, Formulation::Corotated));
    assert!(lagged(&mut mg, Formulation::Corotated));
    // a residual not below the limit renews them too, and the cycle is the fresh one
    let (mut fresh, _) = hierarchy();
    fresh.set_material(0, Material::new(6.0, 0.45)).unwrap();
    fresh.set_tangent(Tangent::Full);
    let mut u_fresh = u.clone();
    let a = fresh
        .cycle(&mut u_fresh, &gravity, Formulation::Corotated)
        .unwrap();
    let limit_mn = 0.5 * a.residual_before;
    let b = mg
        .lagged_cycle(&mut u, &gravity, Formulation::Corotated, limit_mn)
        .unwrap();
    assert!(!b.operators_lagged);
    // to round-off: the parallel sums' order may differ from run to run
    let residuals = (a.residual_before - b.residual_before).abs();
    assert!(residuals <= 1e-12 * a.residual_before, "{a:?} {b:?}");
    assert!(rel_diff(&u, &u_fresh) < 1e-12);
}
