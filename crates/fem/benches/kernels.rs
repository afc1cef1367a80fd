//! Kernels of the static solve and of the multigrid on structured boxes of about 15,000
//! and 60,000 tetrahedra, Poisson ratio 0.45, bottom face fixed and top face pushed
//! sideways: corotated assembly (warped and full tangent, and the full tangent on a
//! stretched state, where its twist term acts in every element), one sparse Cholesky
//! refactorisation and solve (symbolic factorisation reused), and for the multigrid
//! (three Galerkin levels, default options): assembly of every level, the coarse
//! operators alone (the Galerkin products of an assembly, as timed by
//! `Multigrid::phase_times`), one V(2,1) cycle, one prolongation and restriction, one
//! interactive cycle (`Multigrid::cycle`: rotation update, reassembly of every level, one
//! V-cycle; `1000 / update_hz` of the issue), `solve_ms` of the issue, five
//! interactive cycles from the rest state, and a change of the changeable constraints
//! (`Multigrid::set_constraints`, an implant moving: the pushed part of the top face
//! alternates between two sizes). After the
//! five-cycle bench the median and minimum phase times of `Multigrid::phase_times` over
//! 50 cycles are printed (where the time of a cycle goes).
//!
//! `cargo bench -p fem --bench kernels` (`-- mg_` for the multigrid only)

use criterion::{Criterion, criterion_group, criterion_main};
use fem::multigrid::{Multigrid, MultigridOptions, PhaseTimes};
use fem::{
    Constraints, DirectSolver, FemModel, Formulation, Material, Prolongation, ReducedSystem,
    Tangent, box_mesh,
};
use glam::DVec3;
use std::hint::black_box;
use std::time::Duration;
use tetra::TetMesh;

fn box_of(n: [usize; 3]) -> (TetMesh, DVec3) {
    let size = DVec3::new(n[0] as f64, n[1] as f64, n[2] as f64) * 5.0;
    (box_mesh(DVec3::ZERO, size, n), size)
}

fn constraints(mesh: &TetMesh, size: DVec3) -> Constraints {
    pushed_part(mesh, size, 1.0)
}

/// The bottom face fixed and the part `x < fraction · size.x` of the top face pushed.
fn pushed_part(mesh: &TetMesh, size: DVec3, fraction: f64) -> Constraints {
    let mut c = Constraints::new();
    for (v, x) in mesh.positions.iter().enumerate() {
        if x.z == 0.0 {
            c.fix(v as u32);
        } else if x.z == size.z && x.x <= fraction * size.x {
            c.prescribe(v as u32, DVec3::new(0.3 * size.z, 0.0, -0.1 * size.z));
        }
    }
    c
}

fn setup(n: [usize; 3]) -> (FemModel, ReducedSystem, Vec<DVec3>) {
    let (mesh, size) = box_of(n);
    let model = FemModel::homogeneous(&mesh, Material::default()).unwrap();
    let system = ReducedSystem::new(&model, &constraints(&mesh, size)).unwrap();
    // a sheared state: the linear interpolation of the top displacement
    let u: Vec<DVec3> = mesh
        .positions
        .iter()
        .map(|x| DVec3::new(0.3 * x.z, 0.0, -0.1 * x.z))
        .collect();
    (model, system, u)
}

/// A displacement that stretches by 10, 6 and 3 % along the axes and turns by 0.5 rad
/// (every element alike; each still goes through its own polar decomposition).
fn stretched_and_turned(rest: &[DVec3]) -> Vec<DVec3> {
    let turn = glam::DMat3::from_axis_angle(DVec3::new(0.3, -1.0, 0.5).normalize(), 0.5);
    let f = turn * glam::DMat3::from_diagonal(DVec3::new(1.1, 1.06, 1.03));
    rest.iter().map(|&x| f * x - x).collect()
}

/// The multigrid over the box with `n` cells and two coarser boxes (about half and a
/// quarter of the cells per axis, not nested).
fn multigrid(n: [usize; 3]) -> Multigrid {
    let levels = [1usize, 2, 4]
        .iter()
        .map(|&d| {
            let (_, size) = box_of(n);
            let m = n.map(|c| (c / d).max(1));
            let mesh = box_mesh(DVec3::ZERO, size, m);
            let model = FemModel::homogeneous(&mesh, Material::default()).unwrap();
            let c = constraints(&mesh, size);
            (model, c)
        })
        .collect();
    Multigrid::new(levels, MultigridOptions::default()).unwrap()
}

fn kernels(c: &mut Criterion) {
    for n in [[14, 14, 13], [22, 22, 21]] {
        let (model, mut system, u) = setup(n);
        let ne = model.element_count();
        c.bench_function(&format!("assemble_warped_{ne}"), |b| {
            b.iter(|| {
                system
                    .assemble(
                        &model,
                        black_box(&u),
                        &[],
                        Formulation::Corotated,
                        Tangent::Warped,
                    )
                    .unwrap()
            })
        });
        c.bench_function(&format!("assemble_full_{ne}"), |b| {
            b.iter(|| {
                system
                    .assemble(
                        &model,
                        black_box(&u),
                        &[],
                        Formulation::Corotated,
                        Tangent::Full,
                    )
                    .unwrap()
            })
        });
        // every element stretched along all axes and turned: the full tangent's twist
        // term without any clamp (the sheared state above is compressed throughout, which
        // the twist term skips)
        let stretched = stretched_and_turned(model.rest_positions());
        c.bench_function(&format!("assemble_full_stretched_{ne}"), |b| {
            b.iter(|| {
                system
                    .assemble(
                        &model,
                        black_box(&stretched),
                        &[],
                        Formulation::Corotated,
                        Tangent::Full,
                    )
                    .unwrap()
            })
        });
        let mut direct = DirectSolver::new(&system.matrix).unwrap();
        let rhs = system.rhs.clone();
        c.bench_function(&format!("cholesky_refactor_solve_{ne}"), |b| {
            b.iter(|| direct.solve(&system.matrix, black_box(&rhs)).unwrap())
        });

        let mut mg = multigrid(n);
        let u0 = mg
            .system()
            .expand(&vec![DVec3::ZERO; mg.system().unknowns()]);
        c.bench_function(&format!("mg_assemble_all_levels_{ne}"), |b| {
            b.iter(|| {
                mg.assemble(black_box(&u), &[], Formulation::Corotated)
                    .unwrap()
            })
        });
        c.bench_function(&format!("mg_coarse_operators_{ne}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    mg.assemble(black_box(&u), &[], Formulation::Corotated)
                        .unwrap();
                    let ms = mg.phase_times().coarse_operators_ms;
                    total += Duration::from_secs_f64(ms * 1e-3);
                }
                total
            })
        });
        // assembled here too, so that a filtered run (only this bench) has a system
        mg.assemble(&u, &[], Formulation::Corotated).unwrap();
        let rhs = mg.system().rhs.clone();
        c.bench_function(&format!("mg_vcycle_{ne}"), |b| {
            b.iter(|| {
                let mut x = vec![DVec3::ZERO; rhs.len()];
                mg.vcycle(&mut x, black_box(&rhs));
                x
            })
        });
        c.bench_function(&format!("mg_solve_five_cycles_{ne}"), |b| {
            b.iter(|| {
                let mut x = u0.clone();
                for _ in 0..5 {
                    mg.cycle(&mut x, &[], Formulation::Corotated).unwrap();
                }
                x
            })
        });
        let mut x = u0.clone();
        for _ in 0..5 {
            mg.cycle(&mut x, &[], Formulation::Corotated).unwrap();
        }
        c.bench_function(&format!("mg_one_cycle_{ne}"), |b| {
            b.iter(|| {
                mg.cycle(black_box(&mut x), &[], Formulation::Corotated)
                    .unwrap()
            })
        });
        print_phases(&mut mg, &u0, ne);
        let (fine, size) = box_of(n);
        let coarse = box_mesh(DVec3::ZERO, size, n.map(|c| c / 2));
        let p = Prolongation::new(&coarse, &fine).unwrap();
        let xc = vec![DVec3::ONE; coarse.positions.len()];
        let mut xf = vec![DVec3::ZERO; fine.positions.len()];
        c.bench_function(&format!("transfer_prolong_restrict_{ne}"), |b| {
            b.iter(|| {
                p.prolong(black_box(&xc), &mut xf);
                let mut back = vec![DVec3::ZERO; coarse.positions.len()];
                p.restrict(&xf, &mut back);
                back
            })
        });
        let sets = [0.4, 0.6].map(|fraction| pushed_part(&fine, size, fraction));
        let mut k = 0;
        c.bench_function(&format!("mg_set_constraints_{ne}"), |b| {
            b.iter(|| {
                k ^= 1;
                mg.set_constraints(black_box(&sets[k])).unwrap()
            })
        });
    }
}

/// Prints the median and the minimum phase times of 50 interactive cycles from the rest
/// state (ten runs of five cycles; the minimum is the figure least disturbed by other
/// work on a busy machine).
fn print_phases(mg: &mut Multigrid, u0: &[DVec3], ne: usize) {
    let mut phases: Vec<PhaseTimes> = Vec::new();
    for _ in 0..10 {
        let mut x = u0.to_vec();
        for _ in 0..5 {
            mg.cycle(&mut x, &[], Formulation::Corotated).unwrap();
            phases.push(mg.phase_times());
        }
    }
    for (what, pick) in [("median", 1usize), ("minimum", 0)] {
        let stat = |f: fn(&PhaseTimes) -> f64| {
            let mut v: Vec<f64> = phases.iter().map(f).collect();
            v.sort_by(f64::total_cmp);
            v[pick * v.len() / 2]
        };
        println!(
            "phases {ne} ({what} ms): finest assembly {:.2}, coarse operators {:.2}, smoother \
             set-up {:.2}, coarsest factorisation {:.2}, V-cycle {:.2}",
            stat(|p| p.finest_assembly_ms),
            stat(|p| p.coarse_operators_ms),
            stat(|p| p.smoother_setup_ms),
            stat(|p| p.coarsest_factorisation_ms),
            stat(|p| p.vcycle_ms),
        );
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = kernels
}
criterion_main!(benches);
