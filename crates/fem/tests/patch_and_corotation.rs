//! Patch tests (linear and corotated) and the corotation invariance tests.

mod common;

use common::*;
use fem::{
    Constraints, FemModel, Formulation, Material, SolveOptions, StaticSolver, Tangent,
    box_is_boundary, box_mesh,
};
use glam::{DMat3, DVec3};

fn patch_test(formulation: Formulation, tangent: Tangent, a: DMat3, c: DVec3) -> (f64, usize) {
    let n = [4, 3, 3];
    let mesh = jittered_box(
        DVec3::new(-10.0, 5.0, 0.0),
        DVec3::new(30.0, 35.0, 24.0),
        n,
        0.15,
    );
    let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let exact: Vec<DVec3> = mesh.positions.iter().map(|&x| a * x + c).collect();
    let mut constraints = Constraints::new();
    for v in 0..mesh.positions.len() as u32 {
        if box_is_boundary(n, v) {
            constraints.prescribe(v, exact[v as usize]);
        }
    }
    let options = SolveOptions {
        formulation,
        tangent,
        max_iterations: 100,
        relative_tolerance: 1e-13,
    };
    let mut solver = StaticSolver::new(&model, &constraints).unwrap();
    assert_eq!(solver.system().unknowns(), 2 * 3 * 2);
    let sol = solver.solve(&model, &[], None, &options).unwrap();
    assert!(sol.converged, "{sol:?}");
    (
        max_diff(&sol.displacement, &exact) / max_norm(&exact),
        sol.iterations,
    )
}

/// Tolerance 1e-10 relative to the largest displacement.
#[test]
fn patch_test_linear() {
    let a = DMat3::from_cols(
        DVec3::new(0.02, -0.01, 0.005),
        DVec3::new(0.01, -0.015, 0.0),
        DVec3::new(-0.004, 0.008, 0.01),
    );
    let (err, iterations) = patch_test(
        Formulation::Linear,
        Tangent::Warped,
        a,
        DVec3::new(0.3, -0.2, 0.1),
    );
    println!("linear patch test: relative error {err:e}, {iterations} iteration(s)");
    assert!(err < 1e-10, "relative error {err:e}");
    assert_eq!(iterations, 1);
}

/// A large affine motion (rotation by 70 degrees times a 20% stretch with shear):
/// tolerance 1e-10 relative to the largest displacement.
#[test]
fn patch_test_corotated() {
    let s = DMat3::from_cols(
        DVec3::new(1.2, 0.05, 0.0),
        DVec3::new(0.05, 0.9, 0.02),
        DVec3::new(0.0, 0.02, 1.05),
    );
    let a = generic_rotation() * s - DMat3::IDENTITY;
    for tangent in [Tangent::Full, Tangent::Warped] {
        let (err, iterations) = patch_test(
            Formulation::Corotated,
            tangent,
            a,
            DVec3::new(3.0, -2.0, 1.0),
        );
        println!(
            "corotated patch test ({tangent:?} tangent): relative error {err:e}, {iterations} iterations"
        );
        assert!(err < 1e-10, "relative error {err:e}");
    }
}

/// A rigid rotation by 90 degrees (plus a translation) gives zero corotated elastic
/// forces: at most 1e-10 times the (spurious) linear elastic forces of the same motion,
/// and at most 1e-10 times the force scale E·h² of the mesh.
#[test]
fn rigid_rotation_gives_zero_elastic_forces() {
    let mesh = jittered_box(DVec3::ZERO, DVec3::new(40.0, 20.0, 20.0), [6, 3, 3], 0.15);
    let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    for axis in [DVec3::Z, DVec3::X, DVec3::new(1.0, -2.0, 0.5).normalize()] {
        let q = DMat3::from_axis_angle(axis, std::f64::consts::FRAC_PI_2);
        let t = DVec3::new(5.0, -3.0, 7.0);
        let u: Vec<DVec3> = mesh.positions.iter().map(|&x| q * x + t - x).collect();
        let f_corot = model.internal_forces(&u, Formulation::Corotated).unwrap();
        let f_lin = model.internal_forces(&u, Formulation::Linear).unwrap();
        let rel = max_norm(&f_corot) / max_norm(&f_lin);
        let force_scale = 2.4 * (40.0f64 / 6.0).powi(2);
        println!(
            "rigid 90° rotation about {axis}: max corotated force {:e} mN, linear {:e} mN, ratio {rel:e}",
            max_norm(&f_corot),
            max_norm(&f_lin)
        );
        assert!(rel < 1e-10, "ratio {rel:e}");
        assert!(max_norm(&f_corot) < 1e-10 * force_scale);
        // and the stresses vanish
        let s = model.stresses(&u, Formulation::Corotated).unwrap();
        assert!(s.iter().all(|m| frob(*m) < 1e-10 * 2.4));
    }
}

/// A bar stretched by 10% and then rotated has the same (unrotated) stress as the bar
/// stretched only, to 1e-10 relative; its current-frame stress is `Q σ Qᵀ`.
#[test]
fn stretched_and_rotated_bar_has_the_same_stress_affine() {
    let mesh = box_mesh(DVec3::ZERO, DVec3::new(100.0, 10.0, 10.0), [10, 2, 2]);
    let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let s = DMat3::from_diagonal(DVec3::new(1.1, 1.0, 1.0));
    let q = generic_rotation();
    let u_s: Vec<DVec3> = mesh.positions.iter().map(|&x| s * x - x).collect();
    let u_r: Vec<DVec3> = mesh.positions.iter().map(|&x| q * s * x - x).collect();
    let scale = frob(model.element_stress(0, &u_s, Formulation::Corotated).0);
    let mut worst: f64 = 0.0;
    for e in 0..model.element_count() {
        let (sig_s, r_s) = model.element_stress(e, &u_s, Formulation::Corotated);
        let (sig_r, r_r) = model.element_stress(e, &u_r, Formulation::Corotated);
        worst = worst.max(frob(sig_s - sig_r) / scale);
        worst = worst.max(
            frob(r_r * sig_r * r_r.transpose() - q * r_s * sig_s * r_s.transpose() * q.transpose())
                / scale,
        );
        assert!(frob(r_r - q) < 1e-12);
    }
    println!(
        "stretched-and-rotated bar (affine): stress difference {worst:e} relative (stress {scale:.4} kPa)"
    );
    assert!(worst < 1e-10);
    // the linear formulation fails this test: the rotation shows up as strain
    let (sig_lin, _) = model.element_stress(0, &u_r, Formulation::Linear);
    let (sig_s, _) = model.element_stress(0, &u_s, Formulation::Corotated);
    assert!(frob(sig_lin - sig_s) > 0.1 * scale);
}

/// The static solution of a bar clamped at one end and pulled by 10% at the other,
/// and of the same bar rotated by 70 degrees: unrotated stresses agree to 1e-8 relative
/// (the solver tolerance is 1e-12), deformed positions are rotated copies to 1e-8
/// relative to the stretch.
#[test]
fn stretched_and_rotated_bar_has_the_same_stress_solved() {
    let n = [10, 2, 2];
    let mesh = box_mesh(DVec3::ZERO, DVec3::new(100.0, 10.0, 10.0), n);
    let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
    let q = generic_rotation();
    let stretch = DVec3::new(10.0, 0.0, 0.0);
    let mut c_s = Constraints::new();
    let mut c_r = Constraints::new();
    for (v, &x) in mesh.positions.iter().enumerate() {
        let target = if x.x == 0.0 {
            Some(x)
        } else if x.x == 100.0 {
            Some(x + stretch)
        } else {
            None
        };
        if let Some(t) = target {
            c_s.prescribe(v as u32, t - x);
            c_r.prescribe(v as u32, q * t - x);
        }
    }
    let options = SolveOptions {
        relative_tolerance: 1e-12,
        max_iterations: 1000,
        ..SolveOptions::default()
    };
    let sol_s = StaticSolver::new(&model, &c_s)
        .unwrap()
        .solve(&model, &[], None, &options)
        .unwrap();
    // cold start from the rest state: the first iterate inverts the end elements
    let sol_r = StaticSolver::new(&model, &c_r)
        .unwrap()
        .solve(&model, &[], None, &options)
        .unwrap();
    assert!(
        sol_s.converged && sol_r.converged,
        "{} {:e} {} {:e}",
        sol_s.iterations,
        sol_s.relative_residual,
        sol_r.iterations,
        sol_r.relative_residual
    );
    let sig_s = model
        .stresses(&sol_s.displacement, Formulation::Corotated)
        .unwrap();
    let sig_r = model
        .stresses(&sol_r.displacement, Formulation::Corotated)
        .unwrap();
    let scale = sig_s.iter().map(|m| frob(*m)).fold(0.0, f64::max);
    let worst = sig_s
        .iter()
        .zip(&sig_r)
        .map(|(a, b)| frob(*a - *b))
        .fold(0.0, f64::max)
        / scale;
    let x_s: Vec<DVec3> = mesh
        .positions
        .iter()
        .zip(&sol_s.displacement)
        .map(|(x, u)| q * (*x + *u))
        .collect();
    let x_r: Vec<DVec3> = mesh
        .positions
        .iter()
        .zip(&sol_r.displacement)
        .map(|(x, u)| *x + *u)
        .collect();
    let pos = max_diff(&x_s, &x_r) / 10.0;
    println!(
        "stretched-and-rotated bar (solved): stress difference {worst:e} relative, position difference {pos:e} \
         relative to the stretch; iterations {} / {}",
        sol_s.iterations, sol_r.iterations
    );
    assert!(worst < 1e-8, "{worst:e}");
    assert!(pos < 1e-8, "{pos:e}");
}
