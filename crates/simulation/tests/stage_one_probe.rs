//! Stage 1's cycles with and without the switch to Newton-Krylov steps, cycle by cycle
//! (docs/dev/converged.md). A measurement, not a check:
//!
//! `PROBE_BODIES=phantom,v02_average [PROBE_UPRIGHT=1] [PROBE_SLIDES=1] cargo test
//! --release -p simulation --test stage_one_probe -- --ignored --nocapture`
//!
//! `PROBE_UPRIGHT` builds the model with the upright lateral clip planes (the default
//! before session 26) instead of those fitted to the footprints. Per body, switch off and
//! on: R-MOD-115 on both sides at the default placement from rest (solve 0), then both
//! moved up 10 mm (solve 1), each stage 1 to the session's tolerance and the gravity
//! correction after it; the relative residual of every stage-1 cycle (`@0.5`: the line
//! search halved the step). `PROBE_SLIDES` puts the skin over a thin pocket on sliders
//! (`SimulationOptions::skin_slides`).

mod common;

use anatomy::breast::Side;
use implant::Catalog;
use simulation::{Placement, SimulationOptions};

#[test]
#[ignore]
fn stage_one_cycles() {
    let bodies = std::env::var("PROBE_BODIES").unwrap_or_else(|_| "phantom".into());
    let fit = std::env::var("PROBE_UPRIGHT").is_err();
    let skin_slides = std::env::var("PROBE_SLIDES").is_ok();
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    for name in bodies.split(',') {
        let mut model_options = common::default_model_options();
        model_options.closed_surface.fit_lateral_planes = fit;
        let Some(patient) = common::patient(name, &model_options) else {
            println!("{name}: not found");
            continue;
        };
        for newton_krylov_iterations in [0, 2] {
            let options = SimulationOptions {
                newton_krylov_iterations,
                skin_slides,
                ..SimulationOptions::default()
            };
            let tolerance = options.relative_tolerance;
            let mut sim = patient.session(options);
            let placements = [Placement::default(), Placement::moved(0.0, 10.0, 0.0)];
            for (solve, placement) in placements.into_iter().enumerate() {
                for side in [Side::Left, Side::Right] {
                    sim.set_implant(side, shape, placement).unwrap();
                }
                let mut history = Vec::new();
                let mut stage_one_ms = 0.0;
                for _ in 0..60 {
                    let info = sim.cycle().unwrap();
                    stage_one_ms += info.time_ms;
                    let halved = if info.step < 1.0 {
                        format!("@{}", info.step)
                    } else {
                        String::new()
                    };
                    history.push(format!("{:.1e}{halved}", info.relative_residual));
                    if info.relative_residual < tolerance && !info.linear {
                        break;
                    }
                }
                sim.start_gravity_correction().unwrap();
                let gravity = sim.solve(60, tolerance).unwrap();
                println!(
                    "{name} fitted {fit} slides {skin_slides} switch {newton_krylov_iterations} solve {solve}: stage 1 {} cycles {stage_one_ms:.0} ms, gravity {} cycles {:.0} ms\n  {}",
                    history.len(),
                    gravity.cycles,
                    gravity.time_ms,
                    history.join(" ")
                );
            }
        }
    }
}
