//! Issue 5: the multigrid (as the preconditioner of CG) and the direct sparse Cholesky
//! solver agree to 1e-6 relative on the finest system of the shared scans' models, with
//! the real implant template (round 196 ml, the largest moderate-profile implant that
//! fits both scans' fill-ins) after one corotated cycle of the session.
//!
//! `pair1_pre` is left out: no implant fits its fill-ins at the default anchor yet (see
//! the simulation crate's shared-scan test).

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
    for name in ["v02_average", "pair1_post"] {
        let marked = MarkedScan::load(
            &dir.join(format!("{name}.ply")),
            &dir.join(format!("{name}_landmarks.json")),
            &Silent,
        )
        .unwrap();
        let model = build_model(&marked, &ModelOptions::default(), &Silent).unwrap();
        let mut session = Session::new(
            marked,
            model,
            implant::Catalog::builtin(),
            simulation::SimulationOptions::default(),
        )
        .unwrap();
        for side in anatomy::breast::Side::BOTH {
            session
                .set_implant(side, "catalog:R-MOD-110", DVec3::ZERO)
                .unwrap();
        }
        session.cycle().unwrap();
        let mg = session.simulation.multigrid_mut().expect("assembled");
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
            "{name}: {} unknowns, PCG {} iterations (residual {:.1e}), |x_mg - x_direct| / \
             |x_direct| = {relative:.1e}",
            b.len(),
            result.iterations,
            result.relative_residual
        );
        assert!(result.converged, "{name}: {result:?}");
        // PCG stops at 1e-10 relative residual; the system's condition number (soft
        // implant elements at 1% of the tissue) leaves the error well under 1e-6.
        assert!(relative < 1e-6, "{name}: {relative}");
    }
}
