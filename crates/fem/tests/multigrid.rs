//! Geometric multigrid on non-nested box levels against the direct solver.
//!
//! Body: the box `[0, 100] x [0, 60] x [0, 60]` mm, Poisson ratio 0.45, 3 kPa, gravity;
//! the bottom face (`z = 0`, the chest wall) fixed, an implant-like patch of the top face
//! (radius 20 mm around its centre) pushed down by 8 mm (a smooth bump). The finest level
//! is jittered (irregular); the coarse levels are coarser boxes over the same domain with
//! cell counts that do not divide the finer ones (non-nested levels). The coarse levels'
//! constraints (the same geometric predicate) are only used by the rediscretised
//! variant; the default Galerkin levels derive their unknowns from the finer level.

mod common;

use common::*;
use fem::multigrid::{Multigrid, MultigridOptions};
use fem::{Constraints, DirectSolver, FemError, FemModel, Formulation, Material, box_mesh};
use glam::DVec3;
use tetra::TetMesh;

const SIZE: DVec3 = DVec3::new(100.0, 60.0, 60.0);

fn constraints_for(mesh: &TetMesh, depth_mm: f64) -> Constraints {
    let mut c = Constraints::new();
    let centre = DVec3::new(50.0, 30.0, 60.0);
    for (v, x) in mesh.positions.iter().enumerate() {
        if x.z <= 1e-9 {
            c.fix(v as u32);
        } else if x.z >= 60.0 - 1e-9 {
            let r = ((x.x - centre.x).powi(2) + (x.y - centre.y).powi(2)).sqrt();
            if r <= 20.0 {
                let s = (std::f64::consts::PI * r / 40.0).cos().powi(2);
                c.prescribe(v as u32, DVec3::new(0.0, 0.0, -depth_mm * s));
            }
        }
    }
    c
}

/// The hierarchy (finest first) for the given cell counts.
fn hierarchy(
    cells: &[[usize; 3]],
    depth_mm: f64,
    options: MultigridOptions,
) -> (Multigrid, Vec<DVec3>) {
    box_hierarchy(SIZE, cells, |mesh| constraints_for(mesh, depth_mm), options)
}

const TWO_LEVELS: &[[usize; 3]] = &[[20, 12, 12], [7, 4, 4]];
const THREE_LEVELS: &[[usize; 3]] = &[[20, 12, 12], [11, 7, 7], [5, 3, 3]];

/// Assembles at the prescribed values (rest state elsewhere) and returns `(b, x_direct)`.
fn linear_problem(mg: &mut Multigrid, gravity: &[DVec3]) -> (Vec<DVec3>, Vec<DVec3>) {
    let u0 = mg
        .system()
        .expand(&vec![DVec3::ZERO; mg.system().unknowns()]);
    mg.assemble(&u0, gravity, Formulation::Linear).unwrap();
    let b = mg.system().rhs.clone();
    let x = DirectSolver::new(&mg.system().matrix)
        .unwrap()
        .solve(&mg.system().matrix, &b)
        .unwrap();
    (b, x)
}

/// (1) PCG with the symmetric V(2,2) preconditioner agrees with the direct solver to 1e-6
/// relative (2-norm over the unknowns), linear and corotated (warped `R K Rᵀ` at a
/// deformed state, every level with its own rotations), for 2 and 3 levels.
#[test]
fn pcg_agrees_with_direct_solver() {
    for cells in [TWO_LEVELS, THREE_LEVELS] {
        let (mut mg, gravity) = hierarchy(cells, 8.0, MultigridOptions::default());
        println!(
            "levels {:?}: unknowns {:?}, colours {:?}, elements {}",
            cells,
            mg.unknowns_per_level(),
            mg.colours_per_level(),
            mg.model().element_count()
        );
        let (b, x_direct) = linear_problem(&mut mg, &gravity);
        let mut x = vec![DVec3::ZERO; b.len()];
        let res = mg.pcg(&b, &mut x, 1e-10, 100);
        let err = rel_diff(&x, &x_direct);
        println!("  linear: PCG {res:?}, error vs direct {err:e}");
        assert!(res.converged);
        assert!(err < 1e-6);

        // a deformed state: the linear solution scaled to a large deformation
        let u_free: Vec<DVec3> = x_direct.iter().map(|d| *d * 3.0).collect();
        let u = mg.system().expand(&u_free);
        mg.assemble(&u, &gravity, Formulation::Corotated).unwrap();
        let b = mg.system().rhs.clone();
        let x_direct = DirectSolver::new(&mg.system().matrix)
            .unwrap()
            .solve(&mg.system().matrix, &b)
            .unwrap();
        let mut x = vec![DVec3::ZERO; b.len()];
        let res = mg.pcg(&b, &mut x, 1e-10, 100);
        let err = rel_diff(&x, &x_direct);
        println!("  corotated: PCG {res:?}, error vs direct {err:e}");
        assert!(res.converged);
        assert!(err < 1e-6);
    }
}

/// With sliders on the finest level (the top face around the pushed patch held on its
/// plane, free to slide along it, 100 times the modulus times the spacing, as the
/// skin's), the Galerkin hierarchy still preconditions the system: PCG agrees with the
/// direct solver to 1e-6 relative, linear, for 2 and 3 levels.
#[test]
fn pcg_with_sliders_agrees_with_direct_solver() {
    for cells in [TWO_LEVELS, THREE_LEVELS] {
        let (mut mg, gravity) = hierarchy(cells, 8.0, MultigridOptions::default());
        let spacing_mm = SIZE.x / cells[0][0] as f64;
        let held = constraints_for(&jittered_box(DVec3::ZERO, SIZE, cells[0], 0.15), 8.0)
            .table(mg.model().vertex_count())
            .unwrap();
        let sliders: Vec<fem::Slider> = (mg.model().rest_positions().iter().enumerate())
            .filter(|&(v, p)| p.z >= SIZE.z - 1e-9 && held[v].is_none())
            .map(|(v, _)| fem::Slider {
                vertex: v as u32,
                displacement: DVec3::ZERO,
                normal: DVec3::Z,
                stiffness_mn_per_mm: 100.0 * 3.0 * spacing_mm,
            })
            .collect();
        assert!(sliders.len() > 100, "{}", sliders.len());
        mg.set_sliders(&sliders).unwrap();
        let (b, x_direct) = linear_problem(&mut mg, &gravity);
        let mut x = vec![DVec3::ZERO; b.len()];
        let res = mg.pcg(&b, &mut x, 1e-10, 200);
        let err = rel_diff(&x, &x_direct);
        println!(
            "levels {cells:?}, {} sliders: PCG {res:?}, error vs direct {err:e}",
            sliders.len()
        );
        assert!(res.converged);
        assert!(err < 1e-6);
    }
}

/// `‖e‖_A² = eᵀ A e` on the assembled finest system.
fn energy(mg: &Multigrid, e: &[DVec3]) -> f64 {
    let mut ae = vec![DVec3::ZERO; e.len()];
    mg.system().matrix.mul_vec(e, &mut ae);
    e.iter().zip(&ae).map(|(a, b)| a.dot(*b)).sum()
}

/// A warm start from a guess (`PcgIteration::from_guess`) takes the energy-optimal
/// multiple of it: twice the direct solution becomes the solution (to 1e-12 relative,
/// rounding of one matrix-vector product), the solution of the bump pushed half as deep
/// (a related problem, as after an implant moved) starts far closer to the answer than
/// zero in the energy norm, and an unrelated guess is never worse than zero; PCG from
/// each agrees with the direct solver.
#[test]
fn a_guess_starts_at_its_best_multiple() {
    use fem::multigrid::PcgIteration;
    let (mut mg, gravity) = hierarchy(THREE_LEVELS, 4.0, MultigridOptions::default());
    let (_, half_deep) = linear_problem(&mut mg, &gravity);
    let (mut mg, gravity) = hierarchy(THREE_LEVELS, 8.0, MultigridOptions::default());
    let (b, x_direct) = linear_problem(&mut mg, &gravity);
    let from_zero = energy(&mg, &x_direct);

    let doubled: Vec<DVec3> = x_direct.iter().map(|x| *x * 2.0).collect();
    let start = PcgIteration::from_guess(&mut mg, &b, doubled);
    let err = rel_diff(start.solution(), &x_direct);
    println!("twice the solution: starts {err:e} from it");
    assert!(err < 1e-12);

    let unrelated: Vec<DVec3> = (0..b.len())
        .map(|i| {
            DVec3::new(
                (i % 7) as f64 - 3.0,
                (i % 5) as f64 - 2.0,
                (i % 3) as f64 - 1.0,
            )
        })
        .collect();
    let iterations_from = |mg: &mut Multigrid, mut cg: PcgIteration| {
        let bnorm = b.iter().map(|d| d.length_squared()).sum::<f64>().sqrt();
        while cg.residual_norm() > 1e-10 * bnorm && cg.iterations() < 100 {
            cg.step(mg);
        }
        let err = rel_diff(cg.solution(), &x_direct);
        assert!(err < 1e-6, "{err}");
        cg.iterations()
    };
    let zero = PcgIteration::new(&mut mg, &b, vec![DVec3::ZERO; b.len()]);
    let cold = iterations_from(&mut mg, zero);
    for (what, guess) in [("half as deep", half_deep), ("unrelated", unrelated)] {
        let start = PcgIteration::from_guess(&mut mg, &b, guess);
        let e: Vec<DVec3> = start
            .solution()
            .iter()
            .zip(&x_direct)
            .map(|(x, d)| *x - *d)
            .collect();
        let ratio = (energy(&mg, &e) / from_zero).sqrt();
        let iterations = iterations_from(&mut mg, start);
        println!(
            "{what}: energy error {ratio:.3} of zero's, PCG {iterations} iterations (from zero {cold})"
        );
        assert!(ratio <= 1.0 + 1e-12, "{what}: {ratio}");
        if what == "half as deep" {
            // the gravity load does not scale with the depth
            assert!(ratio < 0.5, "{what}: {ratio}");
        }
    }
}

/// The preconditioner of conjugate gradients is a symmetric operator `S` (CG's theory
/// needs it): `w·S(v) = v·S(w)` for two unrelated right-hand sides, to 1e-12 relative
/// (rounding of sums over about 4,000 unknowns), while the interactive V(2,1) cycle is
/// not symmetric (its asymmetry is checked to be far larger, so the check can fail).
/// Three levels, so the coarse corrections of two levels and the coarsest Cholesky
/// take part.
#[test]
fn the_preconditioner_is_symmetric() {
    let (mut mg, gravity) = hierarchy(THREE_LEVELS, 8.0, MultigridOptions::default());
    let (b, _) = linear_problem(&mut mg, &gravity);
    let v: Vec<DVec3> = b.clone();
    let w: Vec<DVec3> = (0..b.len())
        .map(|i| {
            let t = i as f64;
            DVec3::new((0.37 * t).sin(), (0.11 * t).cos(), (0.53 * t).sin()) * b[i].length()
        })
        .collect();
    let dot = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum::<f64>();
    let asymmetry = |mg: &mut Multigrid, symmetric: bool| {
        let apply = |mg: &mut Multigrid, rhs: &[DVec3]| {
            let mut x = vec![DVec3::ZERO; rhs.len()];
            if symmetric {
                mg.symmetric_vcycle(&mut x, rhs);
            } else {
                mg.vcycle(&mut x, rhs);
            }
            x
        };
        let (sv, sw) = (apply(mg, &v), apply(mg, &w));
        let (a, b) = (dot(&w, &sv), dot(&v, &sw));
        (a - b).abs() / a.abs().max(b.abs())
    };
    let symmetric = asymmetry(&mut mg, true);
    let interactive = asymmetry(&mut mg, false);
    println!("relative asymmetry: symmetric cycle {symmetric:e}, V(2,1) {interactive:e}");
    assert!(symmetric < 1e-12, "{symmetric}");
    assert!(interactive > 1e3 * symmetric.max(1e-15), "{interactive}");
}

/// Runs `cycles` stand-alone V(2,1) cycles from zero on `A x = b`; returns the residual
/// reduction factor of every cycle and the relative error (2-norm over the unknowns)
/// against `x_direct` after each cycle.
fn cycles_from_zero(
    mg: &mut Multigrid,
    b: &[DVec3],
    x_direct: &[DVec3],
    cycles: usize,
) -> (Vec<f64>, Vec<f64>) {
    let mut x = vec![DVec3::ZERO; b.len()];
    let mut r_prev = mg.residual_norm(&x, b);
    let mut factors = Vec::new();
    let mut errors = Vec::new();
    for _ in 0..cycles {
        mg.vcycle(&mut x, b);
        let r = mg.residual_norm(&x, b);
        factors.push(r_prev / r);
        errors.push(rel_diff(&x, x_direct));
        r_prev = r;
    }
    (factors, errors)
}

/// Options with the smoothed finest prolongation, `ω_P = 0.5`.
fn smoothed_options() -> MultigridOptions {
    MultigridOptions {
        prolongation_smoothing: 0.5,
        ..MultigridOptions::default()
    }
}

/// Prints the factors and errors of `cycles_from_zero`.
fn print_cycles(label: &str, factors: &[f64], errors: &[f64]) {
    println!("  {label}: reduction factor per cycle: {factors:.2?}");
    println!(
        "  {label}: relative error per cycle: {:?}",
        errors
            .iter()
            .map(|e| format!("{e:.2e}"))
            .collect::<Vec<_>>()
    );
}

/// Smallest reduction factor of the first five cycles.
fn min5(factors: &[f64]) -> f64 {
    factors[..5].iter().copied().fold(f64::INFINITY, f64::min)
}

/// Geometric mean of the first five factors.
fn mean5(factors: &[f64]) -> f64 {
    factors[..5].iter().product::<f64>().powf(0.2)
}

/// (2) and (3) on a box of 62,208 tetrahedra (32x18x18 cells, jittered; coarse boxes
/// 16x9x9 and 8x5x5, Galerkin): ν = 0.45, bottom fixed, a 20 mm patch of the top
/// pushed in by 8 mm, gravity. Stand-alone V(2,1) cycles from zero on the linear
/// system. Measured (release), default options: factors 10.3, 4.8, 3.3, 2.8, 2.6
/// (geometric mean 4.14, asymptotically 2.3), relative error 2.2e-3 after five cycles
/// (9.1e-4 after six): this misses the targets (5 per cycle, 1e-3 after five
/// cycles). With the smoothed finest prolongation (`prolongation_smoothing` 0.5):
/// 12.1, 7.7, 6.3, 5.8, 5.07 (then 4.7, 4.6, ...), error 3.0e-5 after five cycles;
/// asserted: every one of the first five cycles at least 5 (1.4% under the smallest
/// measured, 5.07: a thin margin) and the error at most 4e-5. The other asserted bounds sit just
/// below the measured figures so that a regression shows. Runs in about 3 s in
/// release.
#[test]
fn vcycle_convergence_box_60k() {
    let cells: &[[usize; 3]] = &[[32, 18, 18], [16, 9, 9], [8, 5, 5]];
    let (mut mg, gravity) = hierarchy(cells, 8.0, MultigridOptions::default());
    assert!(mg.model().element_count() > 60_000);
    let (b, x_direct) = linear_problem(&mut mg, &gravity);
    let (factors, errors) = cycles_from_zero(&mut mg, &b, &x_direct, 12);
    println!(
        "box {cells:?}: unknowns {:?}, colours {:?}",
        mg.unknowns_per_level(),
        mg.colours_per_level()
    );
    println!("  reduction factor per cycle: {factors:.2?}");
    println!(
        "  relative error per cycle: {:?}",
        errors
            .iter()
            .map(|e| format!("{e:.2e}"))
            .collect::<Vec<_>>()
    );
    println!(
        "  mean factor over the first 5 cycles: {:.2}",
        mean5(&factors)
    );
    assert!(mean5(&factors) >= 4.0, "mean reduction {}", mean5(&factors));
    assert!(errors[4] <= 3e-3, "error after five cycles {}", errors[4]);
    assert!(
        factors.iter().all(|&f| f >= 2.0),
        "a cycle reduced less than 2x"
    );

    // the smoothed finest prolongation meets the figure in every cycle
    let (mut mg, gravity) = hierarchy(cells, 8.0, smoothed_options());
    let (b, x_direct) = linear_problem(&mut mg, &gravity);
    let (factors, errors) = cycles_from_zero(&mut mg, &b, &x_direct, 12);
    print_cycles("smoothed P (ω_P = 0.5)", &factors, &errors);
    assert!(min5(&factors) >= 5.0, "a cycle reduced less than 5x");
    assert!(errors[4] <= 4e-5, "error after five cycles {}", errors[4]);
}

/// (2) and (3) on a real hierarchy of our pipeline: the finest two levels written by
/// `mammaplan model --scan S --landmarks L --out DIR` (`tets_level0.vtu`,
/// `tets_level1.vtu`), read from the folder in the environment variable
/// `FEM_TEST_MODEL_DIR` (skipped with a message if unset or missing; the coarsest
/// level of such a hierarchy keeps only a third of the volume of a 15 mm slab and
/// slows the cycle down, so it is not used). Constraints: the rear wall (boundary
/// faces with outward normal z < -0.7) fixed, the boundary vertices within 25 mm of the
/// most anterior point pushed back by up to 8 mm. ν = 0.45. Measured on `v02_average`
/// (59,506 tetrahedra): factors 23.8, 7.9, 5.2, 4.3, 3.9 (geometric mean 6.94),
/// relative error 2.8e-4 after five cycles; PCG agrees with the direct solver to
/// 1e-10. With the smoothed finest prolongation (`prolongation_smoothing` 0.5): 26.0,
/// 10.6, 8.9, 6.8, 5.6, error 3.5e-5 after five cycles; asserted: every one of the
/// first five cycles at least 5 (11% under the smallest measured) and the error at
/// most 1e-4.
#[test]
fn vcycle_convergence_real_hierarchy() {
    let Some(dir) = std::env::var_os("FEM_TEST_MODEL_DIR") else {
        println!("skipped: set FEM_TEST_MODEL_DIR to a `mammaplan model` output folder");
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    let mut meshes = Vec::new();
    for l in 0..2 {
        let path = dir.join(format!("tets_level{l}.vtu"));
        match tetra::vtu::read_vtu(&path) {
            Ok(v) => meshes.push(v.mesh),
            Err(e) => {
                println!("skipped: {}: {e}", path.display());
                return;
            }
        }
    }
    let top = *meshes[0]
        .positions
        .iter()
        .max_by(|a, b| a.z.total_cmp(&b.z))
        .unwrap();
    let material = Material::new(3.0, 0.45);
    let levels = meshes
        .iter()
        .map(|mesh| {
            let boundary = mesh.boundary();
            let mut rear = vec![false; boundary.tet_vertex.len()];
            for t in &boundary.mesh.triangles {
                let p = t.map(|k| boundary.mesh.positions[k as usize]);
                if (p[1] - p[0]).cross(p[2] - p[0]).normalize().z < -0.7 {
                    t.iter().for_each(|&k| rear[k as usize] = true);
                }
            }
            let mut c = Constraints::new();
            for (k, &v) in boundary.tet_vertex.iter().enumerate() {
                let r = (mesh.positions[v as usize] - top).length();
                if rear[k] {
                    c.fix(v);
                } else if r <= 25.0 {
                    c.prescribe(v, DVec3::new(0.0, 0.0, -8.0 * (1.0 - r / 25.0)));
                }
            }
            (FemModel::homogeneous(mesh, material).unwrap(), c)
        })
        .collect();
    let levels: Vec<(FemModel, Constraints)> = levels;
    let levels_smoothed = levels.clone();
    let mut mg = Multigrid::new(levels, MultigridOptions::default()).unwrap();
    let (b, x_direct) = linear_problem(&mut mg, &[]);
    let (factors, errors) = cycles_from_zero(&mut mg, &b, &x_direct, 8);
    println!(
        "real hierarchy: {} elements, unknowns {:?}",
        mg.model().element_count(),
        mg.unknowns_per_level()
    );
    println!("  reduction factor per cycle: {factors:.2?}");
    println!(
        "  relative error per cycle: {:?}",
        errors
            .iter()
            .map(|e| format!("{e:.2e}"))
            .collect::<Vec<_>>()
    );
    assert!(mean5(&factors) >= 5.0, "mean reduction {}", mean5(&factors));
    assert!(errors[4] <= 1e-3, "error after five cycles {}", errors[4]);
    let mut x = vec![DVec3::ZERO; b.len()];
    let res = mg.pcg(&b, &mut x, 1e-10, 100);
    println!("  PCG {res:?}");
    assert!(res.converged);
    assert!(rel_diff(&x, &x_direct) < 1e-6);

    // the smoothed finest prolongation: at least 5 in every one of the first five cycles
    let mut mg = Multigrid::new(levels_smoothed, smoothed_options()).unwrap();
    let (b, x_direct) = linear_problem(&mut mg, &[]);
    let (factors, errors) = cycles_from_zero(&mut mg, &b, &x_direct, 8);
    print_cycles("smoothed P (ω_P = 0.5)", &factors, &errors);
    assert!(min5(&factors) >= 5.0, "a cycle reduced less than 5x");
    assert!(errors[4] <= 1e-4, "error after five cycles {}", errors[4]);
}

/// Interactive use: `cycle` (reassemble every level at the current displacement, one
/// V-cycle) on the linear problem is one warm-started V-cycle; five of them from zero
/// reach the direct solution to the same accuracy as five `vcycle`s. With the optimal
/// step (the default) five cycles come closer than five plain V-cycles.
#[test]
fn interactive_cycles_match_vcycles_linear() {
    let plain = MultigridOptions {
        optimal_step: false,
        ..MultigridOptions::default()
    };
    let (mut mg, gravity) = hierarchy(THREE_LEVELS, 8.0, plain);
    let (b, x_direct) = linear_problem(&mut mg, &gravity);
    let mut y = vec![DVec3::ZERO; b.len()];
    for _ in 0..5 {
        mg.vcycle(&mut y, &b);
    }
    let mut u = vec![DVec3::ZERO; mg.model().vertex_count()];
    for k in 0..5 {
        let rep = mg.cycle(&mut u, &gravity, Formulation::Linear).unwrap();
        println!("cycle {k}: {rep:?}");
    }
    let u_free: Vec<DVec3> = mg.system().free.iter().map(|&v| u[v as usize]).collect();
    let e_cycle = rel_diff(&u_free, &x_direct);
    let e_v = rel_diff(&y, &x_direct);
    println!("five interactive cycles: {e_cycle:e}, five vcycles: {e_v:e}");
    assert!((e_cycle - e_v).abs() <= 1e-6 * e_v.max(1e-12) + 1e-12);

    let (mut mg, gravity) = hierarchy(THREE_LEVELS, 8.0, MultigridOptions::default());
    let mut u = vec![DVec3::ZERO; mg.model().vertex_count()];
    for k in 0..5 {
        let rep = mg.cycle(&mut u, &gravity, Formulation::Linear).unwrap();
        println!("optimal step, cycle {k}: {rep:?}");
        assert!((0.5..=2.0).contains(&rep.step_scale));
    }
    let u_free: Vec<DVec3> = mg.system().free.iter().map(|&v| u[v as usize]).collect();
    let e_step = rel_diff(&u_free, &x_direct);
    println!("five interactive cycles with the optimal step: {e_step:e}");
    assert!(e_step < 0.5 * e_v, "{e_step} against {e_v}");
}

/// Out-of-range options are an error, not a panic.
#[test]
fn invalid_options_are_errors() {
    let mesh = box_mesh(DVec3::ZERO, SIZE, [4, 3, 3]);
    let model = FemModel::homogeneous(&mesh, Material::new(3.0, 0.45)).unwrap();
    let c = constraints_for(&mesh, 8.0);
    for options in [
        MultigridOptions {
            sweeps_per_step: 0,
            ..MultigridOptions::default()
        },
        MultigridOptions {
            relaxation: 2.0,
            ..MultigridOptions::default()
        },
        MultigridOptions {
            relaxation: f64::NAN,
            ..MultigridOptions::default()
        },
        MultigridOptions {
            prolongation_smoothing: 1.5,
            ..MultigridOptions::default()
        },
        MultigridOptions {
            prolongation_smoothing: 0.5,
            coarse_operator: fem::multigrid::CoarseOperator::Rediscretised,
            ..MultigridOptions::default()
        },
    ] {
        let err = Multigrid::new(vec![(model.clone(), c.clone())], options).unwrap_err();
        assert!(matches!(err, FemError::InvalidOptions { .. }), "{err}");
    }
}
