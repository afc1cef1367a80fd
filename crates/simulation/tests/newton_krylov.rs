//! Stage 1 where its cheap cycles stall: the phantom's model with the lateral clip planes
//! fitted to the breasts' footprints (`ClosedSurfaceOptions::fit_lateral_planes`, the
//! default, set here explicitly), whose free lateral faces lie close to the implants.

mod common;

use anatomy::breast::Side;
use implant::Catalog;
use simulation::{Placement, SimulationOptions};

fn fitted_phantom() -> common::Patient {
    let mut options = common::default_model_options();
    options.closed_surface.fit_lateral_planes = true;
    common::patient("phantom", &options).unwrap()
}

/// Both implants placed; stage 1 run with at most `max_cycles` to the session's
/// tolerance. Returns the session, its cycle count, whether it converged and whether it
/// switched to Newton-Krylov steps.
fn implant_stage(
    patient: &common::Patient,
    options: SimulationOptions,
    max_cycles: usize,
) -> (simulation::Simulation, usize, bool, bool) {
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    let mut sim = patient.session(options);
    for side in [Side::Left, Side::Right] {
        sim.set_implant(side, shape, Placement::default()).unwrap();
    }
    let tolerance = sim.options().relative_tolerance;
    let mut switched = false;
    for cycle in 1..=max_cycles {
        let info = sim.cycle().unwrap();
        switched |= info.newton_krylov;
        if info.relative_residual < tolerance && !info.linear {
            return (sim, cycle, true, switched);
        }
    }
    (sim, max_cycles, false, switched)
}

/// Where the warped cycles settle into an oscillation (relative residual about 3e-3
/// for ten cycles; 28 cycles to the tolerance of 1e-3 without the switch, measured by
/// `tests/stage_one_probe.rs`), the session switches to
/// Newton-Krylov steps and reaches the tolerance in at most 22 cycles. Its answer is
/// the equilibrium: the skin lies within 0.1 mm (the `converged_ms` criterion of
/// `mammaplan bench`) of the same session solved on to a relative residual of 1e-7.
/// With the switch turned off afterwards, the next cycle is a warped one.
#[test]
fn a_stalled_implant_stage_converges_by_newton_krylov_steps() {
    let patient = fitted_phantom();
    let (mut sim, cycles, converged, switched) =
        implant_stage(&patient, SimulationOptions::default(), 22);
    println!("with the switch: {cycles} cycles, converged {converged}, switched {switched}");
    assert!(converged && switched);
    let answer = sim.scan_positions();
    let tight = sim.solve(40, 1e-7).unwrap();
    assert!(tight.converged, "{tight:?}");
    let equilibrium = sim.scan_positions();
    let largest = answer
        .iter()
        .zip(&equilibrium)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    println!("largest distance of the skin from the equilibrium: {largest:.3} mm");
    assert!(largest < 0.1, "{largest}");
    // switched off (as `mammaplan bench` does for the paper's cycles), the stage's
    // further cycles are warped ones
    sim.set_newton_krylov_iterations(0);
    assert!(!sim.cycle().unwrap().newton_krylov);
}
