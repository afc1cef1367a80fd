//! The Galerkin coarse operators against a straightforward dense triple product.
//!
//! Body: the jittered box `[0, 100] x [0, 60] x [0, 60]` mm, 3 kPa, ν = 0.45, three
//! non-nested levels; the bottom face fixed (permanent), and an implant-like changeable
//! template (the top face inside a radius pushed down, the slab `20 <= z <= 40` inside it held)
//! so that some finest unknowns are eliminated and some coarse unknowns switched off.
//! Every coarse operator of a corotated assembly must equal the dense `Pᵀ A P` built from
//! the next finer operator and the prolongation (identity blocks for the inactive coarse
//! unknowns, the coarsest diagonal scaled by `1 + 1e-8`) to 1e-12 relative, and be
//! exactly symmetric; with the barycentric and with the smoothed finest prolongation.

mod common;

use common::*;
use fem::multigrid::{Multigrid, MultigridOptions};
use fem::{Constraints, FemModel, Formulation, Material, box_mesh};
use glam::DVec3;

const SIZE: DVec3 = DVec3::new(100.0, 60.0, 60.0);

/// The relative shift of the coarsest diagonal before its factorisation.
const COARSEST_SHIFT: f64 = 1e-8;

fn hierarchy(options: MultigridOptions) -> Multigrid {
    let material = Material::new(3.0, 0.45);
    let cells: [[usize; 3]; 3] = [[8, 6, 6], [5, 4, 4], [3, 2, 2]];
    let levels = cells
        .iter()
        .enumerate()
        .map(|(l, &n)| {
            let mesh = if l == 0 {
                jittered_box(DVec3::ZERO, SIZE, n, 0.15)
            } else {
                box_mesh(DVec3::ZERO, SIZE, n)
            };
            let mut wall = Constraints::new();
            for (v, x) in mesh.positions.iter().enumerate() {
                if x.z <= 1e-9 {
                    wall.fix(v as u32);
                }
            }
            (FemModel::homogeneous(&mesh, material).unwrap(), wall)
        })
        .collect();
    let mut mg = Multigrid::with_permanent_constraints(levels, options).unwrap();
    let mesh = mg.model().rest_positions().to_vec();
    let mut template = Constraints::new();
    for (v, x) in mesh.iter().enumerate() {
        let r = ((x.x - 50.0).powi(2) + (x.y - 30.0).powi(2)).sqrt();
        if r > 30.0 {
            continue;
        }
        if x.z >= 60.0 - 1e-9 {
            let s = (std::f64::consts::PI * r / 60.0).cos().powi(2);
            template.prescribe(v as u32, DVec3::new(1.6 * s, 0.0, -8.0 * s));
        } else if (x.z - 30.0).abs() < 12.0 {
            template.fix(v as u32);
        }
    }
    mg.set_constraints(&template).unwrap();
    mg
}

/// `Pᵀ A P` by dense loops (row-major), skipping zero entries of `A` and `P`.
fn triple_product(a: &[Vec<f64>], p: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let (nf, nc) = (p.len(), p[0].len());
    let mut ap = vec![vec![0.0; nc]; nf];
    for (r, ar) in a.iter().enumerate() {
        for (k, &x) in ar.iter().enumerate() {
            if x != 0.0 {
                for (out, &y) in ap[r].iter_mut().zip(&p[k]) {
                    *out += x * y;
                }
            }
        }
    }
    let mut c = vec![vec![0.0; nc]; nc];
    for (pr, apr) in p.iter().zip(&ap) {
        for (i, &x) in pr.iter().enumerate() {
            if x != 0.0 {
                for (out, &y) in c[i].iter_mut().zip(apr) {
                    *out += x * y;
                }
            }
        }
    }
    c
}

fn check_coarse_operators(mg: &mut Multigrid) {
    let free = mg.system().unknowns();
    let mut u = mg.system().expand(&vec![DVec3::ZERO; free]);
    for _ in 0..2 {
        mg.cycle(&mut u, &[], Formulation::Corotated).unwrap();
    }
    mg.assemble(&u, &[], Formulation::Corotated).unwrap();
    let unknowns = mg.unknowns_per_level();
    let active = mg.active_unknowns_per_level();
    println!("unknowns {unknowns:?}, active {active:?}");
    assert!(active[0] < unknowns[0], "some finest unknowns are held");
    assert!(
        (1..unknowns.len()).any(|l| active[l] < unknowns[l]),
        "some coarse unknowns are switched off"
    );
    for (l, &n) in unknowns.iter().enumerate().skip(1) {
        let a = mg.operator(l - 1).to_dense();
        let p = mg.prolongation_dense(l - 1);
        let mut reference = triple_product(&a, &p);
        for i in 0..n {
            let switched_off = (0..3).all(|r| p.iter().all(|row| row[3 * i + r] == 0.0));
            if switched_off {
                for r in 0..3 {
                    reference[3 * i + r][3 * i + r] = 1.0;
                }
            }
        }
        if l + 1 == mg.level_count() {
            for (d, row) in reference.iter_mut().enumerate() {
                row[d] *= 1.0 + COARSEST_SHIFT;
            }
        }
        let c = mg.operator(l).to_dense();
        let scale = reference
            .iter()
            .flatten()
            .fold(0.0f64, |m, x| m.max(x.abs()));
        let mut diff = 0.0f64;
        let mut asymmetric = 0;
        for r in 0..3 * n {
            for q in 0..3 * n {
                diff = diff.max((c[r][q] - reference[r][q]).abs());
                if c[r][q].to_bits() != c[q][r].to_bits() {
                    asymmetric += 1;
                }
            }
        }
        let rel = diff / scale;
        println!("level {l}: max |C - Pᵀ A P| / max |Pᵀ A P| = {rel:.2e}, {asymmetric} asymmetric");
        assert!(rel <= 1e-12, "level {l}: {rel:.2e}");
        assert_eq!(asymmetric, 0, "level {l}: not exactly symmetric");
    }
}

#[test]
fn galerkin_operators_equal_dense_triple_product() {
    check_coarse_operators(&mut hierarchy(MultigridOptions::default()));
}

#[test]
fn smoothed_galerkin_operator_equals_dense_triple_product() {
    check_coarse_operators(&mut hierarchy(MultigridOptions {
        prolongation_smoothing: 0.5,
        ..MultigridOptions::default()
    }));
}
