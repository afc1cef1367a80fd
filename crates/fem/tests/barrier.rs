//! The inversion barrier (`fem::InversionBarrier`): its forces are the gradient of its
//! energy, it leaves uncompressed elements alone, and it keeps squeezed elements from
//! passing through zero volume.

mod common;

use common::*;
use fem::{
    Constraints, FemModel, Formulation, InversionBarrier, Material, SolveOptions, StaticSolver,
};
use glam::DVec3;

const BARRIER: InversionBarrier = InversionBarrier {
    min_volume_ratio: 0.5,
    modulus_kpa: 50.0,
    young_multiple: 0.0,
};

/// Volume ratio `det F` of every element.
fn volume_ratios(model: &FemModel, u: &[DVec3]) -> Vec<f64> {
    model
        .tets()
        .iter()
        .map(|t| {
            let x = t.map(|v| model.rest_positions()[v as usize]);
            let y = t.map(|v| model.rest_positions()[v as usize] + u[v as usize]);
            let vol = |p: [DVec3; 4]| (p[1] - p[0]).cross(p[2] - p[0]).dot(p[3] - p[0]);
            vol(y) / vol(x)
        })
        .collect()
}

/// A box squeezed to 40% of its height with a shear: about half its elements below the
/// barrier's volume ratio. The internal forces (elastic and barrier) agree with the
/// central difference of the potential energy (step 1e-5 mm) to 1e-6 relative: the
/// barrier is conservative, so line searches on the energy stay valid. Without the
/// barrier the corotated forces differ (it acts); the linear ones do not (it does not
/// act on the small-strain formulation).
#[test]
fn barrier_forces_are_the_gradient_of_its_energy() {
    let (mut model, u) = squeezed_box();
    let without = model.internal_forces(&u, Formulation::Corotated).unwrap();
    let linear_without = model.internal_forces(&u, Formulation::Linear).unwrap();
    model.set_inversion_barrier(Some(BARRIER)).unwrap();
    let ratios = volume_ratios(&model, &u);
    let acting = ratios
        .iter()
        .filter(|&&j| j < BARRIER.min_volume_ratio)
        .count();
    assert!(acting > 0, "{ratios:?}");
    for formulation in [Formulation::Linear, Formulation::Corotated] {
        let f = model.internal_forces(&u, formulation).unwrap();
        let fd = energy_gradient(&model, &u, formulation, 1e-5);
        let rel = max_diff(&f, &fd) / max_norm(&fd);
        println!(
            "{formulation:?}: {acting} elements under the barrier, |f - dE/du| / |dE/du| = {rel:.1e}"
        );
        assert!(rel < 1e-6, "{formulation:?}: {rel}");
    }
    let f = model.internal_forces(&u, Formulation::Corotated).unwrap();
    assert!(max_diff(&f, &without) > 1e-3 * max_norm(&f));
    let linear = model.internal_forces(&u, Formulation::Linear).unwrap();
    assert_eq!(linear, linear_without);
}

/// A bar 4 mm thick squeezed by 3 mm between a fixed floor and a sheared top plate,
/// solved to equilibrium (corotated, Newton): without the barrier the iteration does
/// not settle in 100 iterations and elements pass through zero volume (smallest volume
/// ratio -0.44); with it (volume ratio 0.5, 50 kPa) it converges (77 iterations) and
/// every element keeps a positive volume (smallest 0.24). A bar stretched by 10% is the
/// same with and without the barrier, bit for bit.
#[test]
fn barrier_keeps_squeezed_elements_positive_and_leaves_others_alone() {
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(40.0, 10.0, 4.0), [8, 2, 2], 0.1);
    let solve = |barrier: Option<InversionBarrier>, squeeze: bool| {
        let mut model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
        model.set_inversion_barrier(barrier).unwrap();
        let mut c = Constraints::new();
        for (v, x) in mesh.positions.iter().enumerate() {
            if squeeze {
                if x.z == 0.0 {
                    c.fix(v as u32);
                } else if x.z == 4.0 {
                    c.prescribe(v as u32, DVec3::new(3.0 * (x.x / 40.0), 0.0, -3.0));
                }
            } else if x.x == 0.0 {
                c.fix(v as u32);
            } else if x.x == 40.0 {
                c.prescribe(v as u32, DVec3::new(4.0, 0.0, 0.0));
            }
        }
        let mut solver = StaticSolver::new(&model, &c).unwrap();
        let s = solver
            .solve(&model, &[], None, &SolveOptions::default())
            .unwrap();
        let ratios = volume_ratios(&model, &s.displacement);
        let min = ratios.iter().copied().fold(f64::INFINITY, f64::min);
        (s, min)
    };
    let (plain, min_plain) = solve(None, true);
    let (guarded, min_guarded) = solve(Some(BARRIER), true);
    println!(
        "squeezed: smallest volume ratio {min_plain:.3} without the barrier ({} iterations), \
         {min_guarded:.3} with it ({} iterations, converged {})",
        plain.iterations, guarded.iterations, guarded.converged
    );
    assert!(guarded.converged);
    assert!(min_plain < 0.0, "{min_plain}");
    assert!(min_guarded > 0.2, "{min_guarded}");
    let (a, _) = solve(None, false);
    let (b, _) = solve(Some(BARRIER), false);
    assert_eq!(a.displacement, b.displacement);
}

/// One tetrahedron of a stiff material (1000 kPa) shrunk uniformly to a volume ratio of
/// 0.3: the barrier adds exactly `κ V (J_min - J)²`, with `κ` the larger of the barrier's
/// modulus (100 kPa) and 40 times the element's Young's modulus (40,000 kPa).
#[test]
fn a_stiff_element_gets_a_barrier_in_proportion_to_its_modulus() {
    let mesh = fem::box_mesh(DVec3::ZERO, DVec3::splat(10.0), [1, 1, 1]);
    let mut model = FemModel::homogeneous(&mesh, Material::new(1000.0, 0.45)).unwrap();
    let scale = 0.3f64.cbrt();
    let u: Vec<DVec3> = mesh.positions.iter().map(|x| *x * (scale - 1.0)).collect();
    let without = model.potential_energy(&u, &[], Formulation::Corotated);
    model
        .set_inversion_barrier(Some(InversionBarrier {
            min_volume_ratio: 0.5,
            modulus_kpa: 100.0,
            young_multiple: 40.0,
        }))
        .unwrap();
    let with = model.potential_energy(&u, &[], Formulation::Corotated);
    let expected = 40_000.0 * 1000.0 * (0.5f64 - 0.3).powi(2);
    assert!(
        ((with - without) - expected).abs() < 1e-9 * expected,
        "{} {expected}",
        with - without
    );
}
