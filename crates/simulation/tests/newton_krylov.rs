//! Stage 1 where its cheap cycles stall: the phantom with small hanging cups, whose
//! warped cycles from rest settle at a relative residual of about 2.7e-3 for four
//! cycles before the line search breaks out (`PROBE_BODIES=phantom-small-hanging
//! cargo test --release -p simulation --test stage_one_probe -- --ignored --nocapture`).

mod common;

use anatomy::breast::Side;
use implant::Catalog;
use simulation::{Placement, SimulationOptions};

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

/// Where the warped cycles settle at a plateau, the session switches to Newton-Krylov
/// steps and reaches the tolerance in at most 15 cycles (measured 15, four of them on
/// kept operators at about 0.4 of a fresh cycle's time; 14 with every cycle fresh, and
/// 16 without the switch, the last after a halved step; measured by the probe above). Its answer is the
/// equilibrium: the skin lies within 0.1 mm (the `converged_ms` criterion of
/// `mammaplan bench`) of the same session solved on to a relative residual of 1e-7.
/// With the switch turned off afterwards, the next cycle is a warped one.
#[test]
fn a_stalled_implant_stage_converges_by_newton_krylov_steps() {
    let patient = common::small_hanging_phantom();
    let (mut sim, cycles, converged, switched) =
        implant_stage(patient, SimulationOptions::default(), 15);
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
