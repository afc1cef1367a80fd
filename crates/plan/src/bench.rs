//! `mammaplan bench`: the paper's Table I on this machine. For each element count, the
//! phantom's model is built by our own pipeline, the demo's implant is set on both
//! sides (the real displacement template), and the interactive loop is timed: implant
//! set-up, multigrid cycles with rotation update and reassembly on every level, and the
//! direct solver on the same system for comparison.

mod converged;

pub use converged::{ConvergedTiming, SKIN_TOLERANCE_MM, TimedRun};

use crate::demo::DEMO_IMPLANT;
use crate::model::{ModelOptions, build_model};
use crate::simulate::{Placement, Session};
use crate::{MarkedScan, Progress, Scan};
use anatomy::breast::Side;
use anyhow::{Context, Result};
use fem::{BlockCsr, DirectSolver};
use glam::DVec3;
use serde::Serialize;
use simulation::SimulationOptions;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Element counts of the default rows (about those of the paper's Table I).
pub const DEFAULT_ELEMENTS: [usize; 3] = [15_000, 40_000, 60_000];

/// Cycles timed per row (the paper's five V(2,1) cycles).
pub const TIMED_CYCLES: usize = 5;

/// Cycles of the gravity correction run before the implants move again.
const GRAVITY_CYCLES: usize = 3;

/// Placements timed for the implant set-up (the median is reported).
const SETUP_REPEATS: usize = 7;

/// One row of the table.
#[derive(Debug, Clone, Serialize)]
pub struct BenchRow {
    /// Tetrahedra of the finest level.
    pub elements: usize,
    /// Levels of the hierarchy used.
    pub levels: usize,
    /// Placing both implants and building their displacement templates (median, ms).
    pub implant_setup_ms: f64,
    /// The first cycle of a session: building the multigrid (patterns, transfers,
    /// colours, symbolic Cholesky) and one cycle (ms).
    pub multigrid_build_ms: f64,
    /// The first cycle after moving both implants on a built session: new templates
    /// swapped into the existing hierarchy, and one cycle (ms).
    pub implant_change_cycle_ms: f64,
    /// Five cycles, each with rotation update, reassembly on every level and one
    /// V(2,1)-cycle (ms): the paper's recipe, with the session's switch to Newton-Krylov
    /// steps off for them.
    pub solve_ms: f64,
    /// One V(2,1)-cycle alone on the assembled system (median, ms).
    pub vcycle_ms: f64,
    /// Cycles per second of the interactive loop (1000 / median cycle time), of the
    /// paper's cycles as in `solve_ms` (a session's Newton-Krylov steps, once stage 1
    /// stalls, are dearer).
    pub update_hz: f64,
    /// Geometric mean over the timed cycles of the residual's reduction per cycle.
    pub residual_reduction_per_cycle: f64,
    /// Sparse Cholesky factorisation and solve of the finest system (ms).
    pub direct_solve_ms: f64,
    /// Carrying the displacement to the scan, as the live view does after every cycle
    /// (`Session::scan_positions`: the finest field at every scan vertex, smoothed) with
    /// the map and the smoothing composed into one sparse map (median, ms).
    pub scan_update_ms: f64,
    /// The same in two steps, the map then each smoothing step, as a session carries
    /// before composing (median, ms).
    pub scan_update_two_steps_ms: f64,
    /// Composing the map and the smoothing, once per model, on one thread as the live
    /// view does beside the solver (ms).
    pub scan_carry_compose_ms: f64,
    /// Terms of the composed map.
    pub scan_carry_terms: usize,
    /// Switching to the gravity correction: its forces, and the session's hierarchy
    /// given the stage's constraints and tangent (ms; nothing is built).
    pub gravity_start_ms: f64,
    /// The first cycle after moving both implants during the gravity correction: back to
    /// the implant stage on the same hierarchy, and one cycle (ms).
    pub change_after_gravity_cycle_ms: f64,
    /// Where a timed cycle's time goes: the median of each phase over the timed cycles
    /// (ms; the medians need not add up to the median cycle).
    pub phases_ms: BenchPhases,
    /// From moving both implants up 5 mm in a warm session to a skin within 0.1 mm of
    /// the tightly converged one, both stages, gravity on. Its fields are the row's own
    /// in the JSON (`converged_ms` beside `solve_ms`, as the guide's contract has it).
    #[serde(flatten)]
    pub converged: ConvergedTiming,
}

/// Medians of the multigrid's phase times over the timed cycles (ms), see
/// `fem::multigrid::PhaseTimes`.
#[derive(Debug, Clone, Serialize)]
pub struct BenchPhases {
    /// Finest level: element rotations, `R K Rᵀ` blocks, internal forces.
    pub finest_assembly: f64,
    /// Galerkin products (or rediscretised assemblies) of the coarse levels.
    pub coarse_operators: f64,
    /// Inverse diagonal blocks of every level.
    pub smoother_setup: f64,
    /// Numeric Cholesky factorisation of the coarsest level.
    pub coarsest_factorisation: f64,
    /// The V(2,1)-cycle.
    pub vcycle: f64,
}

/// The JSON of `bench`.
#[derive(Debug, Clone, Serialize)]
pub struct BenchReport {
    pub implant: &'static str,
    /// The multigrid's prolongation smoothing ω_P (0: the barycentric prolongation).
    pub prolongation_smoothing: f64,
    /// The skin over thin pockets on sliders (`simulate --skin-slides`).
    pub skin_slides: bool,
    pub rows: Vec<BenchRow>,
    /// Where `--export-system` wrote the finest system of the first row, if asked.
    pub exported_system: Option<PathBuf>,
}

/// Runs the benchmark rows with the multigrid's prolongation smoothing
/// `prolongation_smoothing` (see `fem::multigrid::MultigridOptions`) and the skin over
/// thin pockets on sliders if `skin_slides` (`simulation::SimulationOptions::skin_slides`);
/// with `export_dir`,
/// the first row's finest eliminated system (after the first cycle's assembly) is
/// written there as Matrix Market `A.mtx`, `b.mtx`.
pub fn bench(
    elements: &[usize],
    prolongation_smoothing: f64,
    skin_slides: bool,
    export_dir: Option<&Path>,
    progress: &dyn Progress,
) -> Result<BenchReport> {
    let phantom = phantom::generate(&phantom::PhantomParams::default());
    let mut rows = Vec::with_capacity(elements.len());
    for (row, &count) in elements.iter().enumerate() {
        progress.stage(&format!("bench {count} elements"), 1);
        let marked = MarkedScan::new(
            Scan::from_mesh(phantom.scan.clone(), Path::new("phantom.ply"))?,
            phantom.landmarks.clone(),
            Path::new("phantom.json"),
            None,
            &crate::Silent,
        )?;
        let model = build_model(
            &marked,
            &ModelOptions {
                elements: count,
                ..Default::default()
            },
            &crate::Silent,
        )?;
        let mut options = SimulationOptions::default();
        options.multigrid.prolongation_smoothing = prolongation_smoothing;
        options.skin_slides = skin_slides;
        let newton_krylov_iterations = options.newton_krylov_iterations;
        let lagged_operators = options.lagged_operators;
        let mut session = Session::new(marked, model, implant::Catalog::builtin(), options)?;
        // the paper's cycles for Table I; the session's own for the converged answer
        session.simulation.set_newton_krylov_iterations(0);
        session.simulation.set_lagged_operators(false);
        let mut setups = Vec::with_capacity(SETUP_REPEATS);
        for k in 0..SETUP_REPEATS {
            // Small moves, so every repetition builds a fresh template.
            let offset = 0.5 * k as f64;
            let start = Instant::now();
            for side in Side::BOTH {
                session.set_implant(side, DEMO_IMPLANT, Placement::moved(0.0, offset, 0.0))?;
            }
            setups.push(start.elapsed().as_secs_f64() * 1e3);
        }
        let built = session.cycle()?;
        for side in Side::BOTH {
            session.set_implant(side, DEMO_IMPLANT, Placement::moved(2.0, 3.0, 0.0))?;
        }
        let first = session.cycle()?;
        if row == 0
            && let Some(dir) = export_dir
        {
            let system = session
                .simulation
                .multigrid()
                .context("no multigrid after a cycle")?
                .system();
            write_matrix_market(dir, &system.matrix, &system.rhs)?;
        }
        let TableOneCycles {
            mut cycle_ms,
            phases_ms,
            reduction,
        } = table_one_cycles(&mut session, first.residual_mn)?;
        let time_scan_updates = |session: &Session| -> Vec<f64> {
            (0..TIMED_CYCLES)
                .map(|_| {
                    let start = Instant::now();
                    std::hint::black_box(session.scan_positions());
                    start.elapsed().as_secs_f64() * 1e3
                })
                .collect()
        };
        let mut scan_update_two_steps_ms = time_scan_updates(&session);
        let start = Instant::now();
        let carry = session.simulation.scan_carry_job()();
        let scan_carry_compose_ms = start.elapsed().as_secs_f64() * 1e3;
        let scan_carry_terms = carry.term_count();
        anyhow::ensure!(
            session.simulation.use_scan_carry(carry),
            "the composed scan carry does not fit its own simulation"
        );
        let mut scan_update_ms = time_scan_updates(&session);
        let mg = session
            .simulation
            .multigrid()
            .context("no multigrid after a cycle")?;
        let system = mg.system();
        let direct_start = Instant::now();
        DirectSolver::new(&system.matrix)?.solve(&system.matrix, &system.rhs)?;
        let direct_solve_ms = direct_start.elapsed().as_secs_f64() * 1e3;
        let levels = mg.level_count();
        session
            .simulation
            .set_newton_krylov_iterations(newton_krylov_iterations);
        session.simulation.set_lagged_operators(lagged_operators);
        let start = Instant::now();
        session.simulation.start_gravity_correction()?;
        let gravity_start_ms = start.elapsed().as_secs_f64() * 1e3;
        for _ in 0..GRAVITY_CYCLES {
            session.cycle()?;
        }
        for side in Side::BOTH {
            session.set_implant(side, DEMO_IMPLANT, Placement::moved(0.0, 2.0, 0.0))?;
        }
        let change_after_gravity = session.cycle()?;
        let converged = converged::converged_timing(&mut session, DEMO_IMPLANT)?;
        rows.push(BenchRow {
            elements: session.model.levels[0].elements,
            levels,
            implant_setup_ms: median(&mut setups),
            multigrid_build_ms: built.time_ms,
            implant_change_cycle_ms: first.time_ms,
            solve_ms: cycle_ms.iter().sum(),
            vcycle_ms: phases_ms.vcycle,
            update_hz: 1000.0 / median(&mut cycle_ms),
            residual_reduction_per_cycle: reduction,
            direct_solve_ms,
            scan_update_ms: median(&mut scan_update_ms),
            scan_update_two_steps_ms: median(&mut scan_update_two_steps_ms),
            scan_carry_compose_ms,
            scan_carry_terms,
            gravity_start_ms,
            change_after_gravity_cycle_ms: change_after_gravity.time_ms,
            phases_ms,
            converged,
        });
        progress.step();
    }
    Ok(BenchReport {
        implant: DEMO_IMPLANT,
        prolongation_smoothing,
        skin_slides,
        rows,
        exported_system: export_dir.map(Path::to_path_buf),
    })
}

/// The paper's Table I cycles of a row, timed.
struct TableOneCycles {
    /// Each cycle's time (ms).
    cycle_ms: Vec<f64>,
    /// The medians of the phases over them.
    phases_ms: BenchPhases,
    /// The geometric mean of the residual's reduction per cycle, after the first.
    reduction: f64,
}

/// Runs and times [`TIMED_CYCLES`] cycles of `session`, whose last cycle left the
/// residual `first_residual_mn`.
fn table_one_cycles(session: &mut Session, first_residual_mn: f64) -> Result<TableOneCycles> {
    let mut cycle_ms = Vec::with_capacity(TIMED_CYCLES);
    let mut phases = Vec::with_capacity(TIMED_CYCLES);
    let mut residuals = vec![first_residual_mn];
    for _ in 0..TIMED_CYCLES {
        let info = session.cycle()?;
        cycle_ms.push(info.time_ms);
        residuals.push(info.residual_mn);
        if let Some(mg) = session.simulation.multigrid() {
            phases.push(mg.phase_times());
        }
    }
    let phase_median = |of: fn(&fem::multigrid::PhaseTimes) -> f64| {
        median(&mut phases.iter().map(of).collect::<Vec<_>>())
    };
    let phases_ms = BenchPhases {
        finest_assembly: phase_median(|p| p.finest_assembly_ms),
        coarse_operators: phase_median(|p| p.coarse_operators_ms),
        smoother_setup: phase_median(|p| p.smoother_setup_ms),
        coarsest_factorisation: phase_median(|p| p.coarsest_factorisation_ms),
        vcycle: phase_median(|p| p.vcycle_ms),
    };
    let reductions = residuals.len() - 2;
    let reduction = (residuals[1] / residuals[residuals.len() - 1]).powf(1.0 / reductions as f64);
    Ok(TableOneCycles {
        cycle_ms,
        phases_ms,
        reduction,
    })
}

fn median(values: &mut [f64]) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Writes `A` (symmetric, all entries, 1-based coordinates) and `b` (one column) as
/// Matrix Market files, with unknown `3 i + c` for block row `i`, component `c`.
pub fn write_matrix_market(dir: &Path, a: &BlockCsr, b: &[DVec3]) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let n = 3 * a.block_rows();
    let entries: usize = a.values.len() * 9;
    mesh::io::write_atomically(&dir.join("A.mtx"), |w| {
        writeln!(w, "%%MatrixMarket matrix coordinate real general")?;
        writeln!(
            w,
            "% mammaplan: eliminated stiffness K'_ff (mN/mm), 3x3 blocks"
        )?;
        writeln!(w, "{n} {n} {entries}")?;
        for i in 0..a.block_rows() {
            for k in a.row_ptr[i]..a.row_ptr[i + 1] {
                let j = a.cols[k] as usize;
                for r in 0..3 {
                    for c in 0..3 {
                        writeln!(
                            w,
                            "{} {} {:e}",
                            3 * i + r + 1,
                            3 * j + c + 1,
                            a.values[k][3 * r + c]
                        )?;
                    }
                }
            }
        }
        Ok(())
    })?;
    mesh::io::write_atomically(&dir.join("b.mtx"), |w| {
        writeln!(w, "%%MatrixMarket matrix array real general")?;
        writeln!(
            w,
            "% mammaplan: right-hand side f_ext - f_int(u) at the free vertices (mN)"
        )?;
        writeln!(w, "{n} 1")?;
        for v in b {
            writeln!(w, "{:e}\n{:e}\n{:e}", v.x, v.y, v.z)?;
        }
        Ok(())
    })?;
    Ok(())
}
