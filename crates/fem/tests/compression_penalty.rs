//! The compression penalty (`fem::CompressionPenalty`): exactly `m λ V (J₀ - J)²` below
//! its onset and nothing above it, conservative forces, and less volume lost by a
//! squeezed body.

mod common;

use common::*;
use fem::{
    CompressionPenalty, Constraints, FemModel, Formulation, InversionBarrier, Material,
    SolveOptions, StaticSolver,
};
use glam::DVec3;

const PENALTY: CompressionPenalty = CompressionPenalty {
    onset_volume_ratio: 0.9,
    lambda_multiple: 1.0,
};

const BARRIER: InversionBarrier = InversionBarrier {
    min_volume_ratio: 0.5,
    modulus_kpa: 50.0,
    young_multiple: 0.0,
};

/// A 10 mm cube of 2.4 kPa tissue (Poisson ratio 0.45) shrunk uniformly to the volume
/// ratio `j`: its energy with and without the penalty (mN·mm).
fn shrunk_cube_energies(j: f64) -> (f64, f64) {
    let mesh = fem::box_mesh(DVec3::ZERO, DVec3::splat(10.0), [2, 2, 2]);
    let mut model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let u: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|x| *x * (j.cbrt() - 1.0))
        .collect();
    let without = model.potential_energy(&u, &[], Formulation::Corotated);
    model.set_compression_penalty(Some(PENALTY)).unwrap();
    (
        without,
        model.potential_energy(&u, &[], Formulation::Corotated),
    )
}

/// Shrunk to half its volume, the cube gains exactly `λ V (0.9 - 0.5)²` (λ from the
/// Lamé formula, V = 1000 mm³), to round-off (1e-9 relative); shrunk by 5%, above the
/// onset, nothing at all.
#[test]
fn the_penalty_is_its_formula_below_the_onset_and_nothing_above() {
    let (lambda, _) = Material::new(2.4, 0.45).lame();
    let (without, with) = shrunk_cube_energies(0.5);
    let expected = lambda * 1000.0 * (0.9f64 - 0.5).powi(2);
    assert!(
        ((with - without) - expected).abs() < 1e-9 * expected,
        "{} {expected}",
        with - without
    );
    let (without, with) = shrunk_cube_energies(0.95);
    assert_eq!(with, without);
}

/// A box squeezed to 40% of its height with a shear, penalty and barrier together: the
/// internal forces agree with the central difference of the potential energy (step
/// 1e-5 mm) to 1e-6 relative, so line searches on the energy stay valid.
#[test]
fn penalty_forces_are_the_gradient_of_its_energy() {
    let (mut model, u) = squeezed_box();
    let without = model.internal_forces(&u, Formulation::Corotated).unwrap();
    model.set_compression_penalty(Some(PENALTY)).unwrap();
    model.set_inversion_barrier(Some(BARRIER)).unwrap();
    let f = model.internal_forces(&u, Formulation::Corotated).unwrap();
    let fd = energy_gradient(&model, &u, Formulation::Corotated, 1e-5);
    let rel = max_diff(&f, &fd) / max_norm(&fd);
    println!("|f - dE/du| / |dE/du| = {rel:.1e}");
    assert!(rel < 1e-6, "{rel}");
    assert!(max_diff(&f, &without) > 1e-3 * max_norm(&f));
}

/// A bar 10 mm thick squeezed by 5 mm between a fixed floor and a top plate that also
/// slides 4 mm sideways, solved to equilibrium (corotated, Newton, with the inversion
/// barrier, to a relative residual of 1e-6): with the penalty it converges and keeps more of its volume than without.
#[test]
fn a_squeezed_bar_loses_less_volume_with_the_penalty() {
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(40.0, 10.0, 10.0), [8, 2, 2], 0.1);
    let solve = |penalty: Option<CompressionPenalty>| {
        let mut model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
        model.set_compression_penalty(penalty).unwrap();
        model.set_inversion_barrier(Some(BARRIER)).unwrap();
        let mut c = Constraints::new();
        for (v, x) in mesh.positions.iter().enumerate() {
            if x.z == 0.0 {
                c.fix(v as u32);
            } else if x.z == 10.0 {
                c.prescribe(v as u32, DVec3::new(4.0, 0.0, -5.0));
            }
        }
        let mut solver = StaticSolver::new(&model, &c).unwrap();
        let s = solver
            .solve(
                &model,
                &[],
                None,
                &SolveOptions {
                    relative_tolerance: 1e-6,
                    ..SolveOptions::default()
                },
            )
            .unwrap();
        assert!(
            s.converged,
            "{penalty:?}: {} iterations, residual {}",
            s.iterations, s.relative_residual
        );
        let rest = model.rest_positions();
        let volume = |p: &dyn Fn(usize) -> DVec3| -> f64 {
            model
                .tets()
                .iter()
                .map(|t| {
                    let [a, b, c, d] = t.map(|v| p(v as usize));
                    (b - a).cross(c - a).dot(d - a) / 6.0
                })
                .sum()
        };
        let before = volume(&|v| rest[v]);
        let after = volume(&|v| rest[v] + s.displacement[v]);
        after / before
    };
    let plain = solve(None);
    let penalised = solve(Some(PENALTY));
    println!("volume kept: {plain:.3} without the penalty, {penalised:.3} with it");
    assert!(penalised > plain + 0.01, "{plain} {penalised}");
}
