//! How many simulated frames per second the live simulation delivers while an implant
//! slider is dragged, without a window: the phantom's model is built, the built-in
//! `R-MOD-120` placed on both sides and solved, then the projection is dragged from 33.5
//! to 45 mm for a while, a new value 60 times a second (as a window sends them), and the
//! frames coming back are counted. The window's own frame rate comes from
//! `mammaplan gui --script` with its `stats` action (see docs/user/gui.md).
//!
//! `cargo run --release -p gui --example live_rate -- [ELEMENTS] [SECONDS]`
//! (defaults: 60000 elements, 20 s).

use anyhow::Context;
use gui::live_simulation::{ImplantSet, LiveSimulation};
use gui::render::SceneMesh;
use plan::catalog::Catalog;
use plan::model::ModelOptions;
use plan::simulate::{ImplantRequest, Session, SimulationOptions, SolveState};
use plan::{MarkedScan, PhantomParams, Silent};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// How often the "window" sends a new slider value.
const SEND_PERIOD: Duration = Duration::from_micros(16_667);

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let elements: usize = args.next().map_or(Ok(60_000), |a| a.parse())?;
    let seconds: f64 = args.next().map_or(Ok(20.0), |a| a.parse())?;

    let start = Instant::now();
    let marked = MarkedScan::phantom(&PhantomParams::default())?;
    let scene = Arc::new(SceneMesh::new(&marked.scan.mesh));
    let vertices = marked.scan.mesh.vertex_count();
    let options = ModelOptions {
        elements,
        ..ModelOptions::default()
    };
    let session = Session::build(
        marked,
        &options,
        Catalog::builtin(),
        SimulationOptions::default(),
        &Silent,
    )?;
    let finest = session.model.levels.first().context("no levels")?.elements;
    println!(
        "model: {finest} tetrahedra (asked {elements}), scan {vertices} vertices, built in {:.1} s",
        start.elapsed().as_secs_f64()
    );

    let mut live = LiveSimulation::start(session, scene, false, || {});
    let set = |projection_mm: f64| {
        let spec = format!("round:diameter=120,projection={projection_mm:.2}");
        ImplantSet::both_sides(&ImplantRequest::new(spec), true)
    };
    let start = Instant::now();
    live.set_implants(&set(33.5));
    while !live.is_settled() {
        std::thread::sleep(Duration::from_millis(5));
        live.poll();
    }
    println!(
        "first solve: {} cycles in {:.1} s ({:?})",
        live.solver.map_or(0, |s| s.cycles),
        start.elapsed().as_secs_f64(),
        live.solver.map(|s| s.advance.state)
    );

    let received_before = live.frames_received;
    let mut cycle_ms = Vec::new();
    let mut frame_ms = Vec::new();
    let mut last_frame = live.frame.as_ref().map_or(0, |f| f.number);
    let start = Instant::now();
    let mut sent = 0;
    while start.elapsed().as_secs_f64() < seconds {
        let t = start.elapsed().as_secs_f64() / seconds;
        live.set_implants(&set(33.5 + 11.5 * t));
        sent += 1;
        live.poll();
        if let (Some(frame), Some(solver)) = (&live.frame, live.solver)
            && frame.number != last_frame
        {
            last_frame = frame.number;
            cycle_ms.push(solver.advance.cycle.time_ms);
            frame_ms.push(solver.frame_ms);
        }
        std::thread::sleep(SEND_PERIOD);
    }
    let elapsed = start.elapsed().as_secs_f64();
    let received = live.frames_received - received_before;
    let median = |values: &mut Vec<f64>| {
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "drag: {sent} slider values in {elapsed:.1} s, {received} simulated frames received: \
         {:.1} per second; median cycle {:.0} ms + {:.0} ms to the scan",
        received as f64 / elapsed,
        median(&mut cycle_ms),
        median(&mut frame_ms)
    );
    while !live.is_settled() {
        std::thread::sleep(Duration::from_millis(5));
        live.poll();
    }
    println!(
        "after the drag: {:?} in {} cycles",
        live.solver.map(|s| s.advance.state),
        live.solver.map_or(0, |s| s.cycles)
    );
    anyhow::ensure!(
        live.solver
            .is_some_and(|s| s.advance.state == SolveState::Converged),
        "the simulation did not converge"
    );
    Ok(())
}
