//! The simulation session: a patient's finite element hierarchy prepared once, implants
//! set and moved cheaply, corotated multigrid V-cycles warm-started from the current
//! displacement, the gravity correction of paper V-B, and the result on the scan.
//!
//! # Boundary conditions
//! - Held (zero displacement) at all times: the finest vertices on the closed surface's
//!   posterior wall (the shifted filled base: the chest wall, assumed rigid) and on its
//!   band (the faces cut by the four clip planes, where the modelled region continues
//!   into the rest of the body), except band vertices over an implant bed's domain and
//!   in front of the bed (at the default shift): there a clip plane cuts through the
//!   breast itself, and holding those faces glues the breast to the plane next to the
//!   implant (docs/dev/session-choices.md); they are left free (traction-free). Vertices are assigned to the wall or
//!   band when their closest point on the closed surface lies on one of those triangles
//!   and within [`WALL_TOLERANCE_FACTOR`] times the finest spacing of it.
//! - Held at all times with [`SimulationOptions::hold_sternum`]: the tissue over the
//!   sternum, within [`STERNUM_HALF_WIDTH_MM`] of the standing frame's midline between
//!   the heights of Pj and Px, at any depth, except in front of any bed an implant may lie on (the fill-ins' and the
//!   pockets').
//! - Per implant ([`crate::template`]): implant vertices displaced along the bed normal by
//!   the implant's thickness, back vertices inside the footprint fixed. A vertex that is
//!   both wall and implant takes the implant's value.
//!
//! # Stages
//! 1. [`Stage::Implant`]: the Dirichlet problem of the template, solved by
//!    [`Multigrid::cycle`] (rotation update, reassembly, one V(2,1)-cycle; near the
//!    answer the forces alone on kept operators, [`Multigrid::lagged_cycle`]; Newton-Krylov
//!    steps once these stall and the steps pay, see
//!    [`SimulationOptions::newton_krylov_iterations`]) on the
//!    corotated formulation. The scan as captured is the rest state: the tissue's own
//!    weight is already in it, so no body force acts.
//! 2. [`Stage::Gravity`] (paper V-B): the implant vertices are released; the force that
//!    held them, `f1 = K11 u1 + K12 u2` (for the corotated model: the internal elastic
//!    force `f_int(u)` at those vertices, implant elements already soft), becomes a dead
//!    load there, plus the weight of the volume the implant added: each implant element's
//!    gravity at the implant density over its deformed minus its rest volume, a quarter
//!    to each corner. Only the added mass pulls; the dead load keeps stage 1's
//!    equilibrium otherwise. The correction is the linear response of the stage-1 state:
//!    `K Δu = r` with `K` the corotated tangent at the stage-1 displacement (implant
//!    vertices free) and `r` the added weight (and what is left of stage 1's residual),
//!    solved by conjugate gradients preconditioned with the multigrid, one iteration per
//!    cycle ([`fem::multigrid::PcgIteration`]), from the stage-1 displacement plus the
//!    best multiple of the session's last correction (none after a restart). The breast
//!    sags: the nipple moves down. Why linear: under the dead loads the soft implant
//!    region has no stiffness of its own against moving as a whole, and the corotated
//!    iteration wandered off; the added weight moves the nipple by a few millimetres,
//!    where the linear response of the deformed state is accurate, and the tangent
//!    system is symmetric positive definite. Bare V-cycles converge slowly on it (the
//!    soft implant region is a coefficient jump of 100 that the coarse levels do not
//!    see); conjugate gradients with a symmetric V(2,2) preconditioner do
//!    (docs/dev/session-choices.md).
//!
//! # Changing the implant
//! [`Simulation::set_implant`] rebuilds that side's template from scratch (milliseconds)
//! and drops back to stage 1. The next cycle swaps the new constraints into the existing
//! multigrid ([`Multigrid::set_constraints`]: a fixed pattern over all vertices,
//! symmetric elimination, about 0.2 ms at 60,000 elements) and softens the new implant
//! elements in place. One hierarchy serves the whole session: it is built at the
//! session's first cycle (0.3-0.5 s at 60,000 elements), and every later change of
//! implant and every switch between the stages only swaps its constraints, materials
//! and assembled tangent ([`Multigrid::set_tangent`]; the stages assemble different
//! tangents, see [`SimulationOptions::gravity_tangent`]), so neither the start of the
//! gravity correction nor a change after it costs more than an ordinary cycle. The
//! displacement is kept as the warm start, and so is the last gravity correction, for the
//! next one.

mod anderson;
mod build;
mod carried;
mod options;
mod placing;
mod solve;

pub use options::*;

use anderson::AndersonMixing;
use build::field_locator;
pub use carried::CARRIED_CONTROL_POINT_SPACING_MM;
use carried::{ScanFeet, closed_volume, points_along_loop};

use crate::bed::{ChestCylinder, DEFAULT_SHIFT_MM, ImplantBed};
use crate::carry::ScanCarry;
use crate::error::SimulationError;
use crate::field::{DEFAULT_FALLOFF_MM, FieldLocator, PointMap, SurfaceSmoother};
use crate::muscle::{DEFAULT_MUSCLE, MuscleLayer};
use crate::over_implant::{swept_prisms, swept_quad, triangles_over_implant};
use crate::placement::{Anchor, AnchorRule, Placement, anchor_on_floor, resolve_anchor};
use crate::pocket::{
    FoldLowering, PocketBounds, PocketLimits, fold_lowest, native_fold_y_mm, nipple_of,
    nipple_to_fold_mm, planned_fold_y_mm, pocket_surface,
};
use crate::resolved_length::ResolvedLength;
use crate::skin::SkinLayer;
use crate::template::{
    BedFeet, FOOTPRINT_TOLERANCE_MM, FoldPlane, ImplantTemplate, SideCandidates, SmoothedThickness,
    TemplateIndex, TemplateRules, build_template, check_footprint, fit_footprint,
};
use anatomy::breast::{
    BreastModel, ControlPoints, QuadrantLines, QuadrantVolumes, Side, quadrant_volumes_ml,
};
use anatomy::closed_surface::ClosedSurface;
use anatomy::fill_in::{FillInParams, fill_hole};
use anatomy::{AnatomicalFrame, LandmarkName, Landmarks};
use fem::multigrid::{CoarseOperator, Multigrid, MultigridOptions, PcgIteration};
use fem::{
    CompressionPenalty, Constraints, FemModel, Formulation, InversionBarrier, Material, Slider,
    Tangent,
};
use glam::{DVec2, DVec3};
use implant::ImplantShape;
use mesh::TriMesh;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;
use tetra::TetMesh;

/// What a [`Simulation`] is built from (all borrowed; the session keeps its own copies).
#[derive(Clone, Copy)]
pub struct PatientInput<'a> {
    /// The scan as loaded (file frame, mm).
    pub scan: &'a TriMesh,
    pub landmarks: &'a Landmarks,
    pub frame: &'a AnatomicalFrame,
    pub breasts: &'a BreastModel,
    pub closed_surface: &'a ClosedSurface,
    /// The tetrahedral hierarchy, finest level first.
    pub tets: &'a tetra::Hierarchy,
}

/// Which problem the session solves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stage {
    /// Implant vertices prescribed (Dirichlet).
    Implant,
    /// Implant vertices released under their holding force plus the added weight.
    Gravity,
}

/// The stage being solved, with what only stage 2 has.
enum StageState {
    Implant,
    Gravity(Box<GravityStage>),
}

impl StageState {
    fn stage(&self) -> Stage {
        match self {
            StageState::Implant => Stage::Implant,
            StageState::Gravity(_) => Stage::Gravity,
        }
    }
}

/// A session's state to start again from ([`Simulation::solved_state`],
/// [`Simulation::restore`]).
#[derive(Debug, Clone)]
pub struct SolvedState {
    /// The displacement (mm, per finest vertex).
    u: Vec<DVec3>,
    /// The gravity correction in it, if known (mm, per finest vertex).
    gravity_correction: Option<Vec<DVec3>>,
}

/// Stage 2: the linear correction of stage 1's displacement.
struct GravityStage {
    /// The session's hierarchy, with stage 2's constraints and tangent.
    multigrid: StageMultigrid,
    /// Stage 1's displacement (mm, per finest vertex), which stage 2 corrects.
    u_implant: Vec<DVec3>,
    /// The conjugate gradient iteration on the linear system `K Δu = r` at `u_implant`
    /// (its right-hand side the added implant weight and what is left of stage 1's
    /// residual), preconditioned by the stage's multigrid.
    iteration: PcgIteration,
    /// The norm of that right-hand side (mN), which the stage's residual is relative to.
    rhs_norm_mn: f64,
}

/// An implant placed on one side.
#[derive(Debug, Clone)]
pub struct PlacedImplant {
    pub shape: ImplantShape,
    pub placement: Placement,
    pub anchor: Anchor,
    /// How far the anchor was moved from the requested one so that the footprint fits
    /// on the bed (mm, in the requested anchor's `x'` (patient's left) and `y'` (up);
    /// zero when it fitted where asked, see [`SimulationOptions::fit_footprint`]).
    pub fit_shift_mm: DVec2,
    /// How far below the native fold's lowest point the pocket reaches for this implant
    /// (mm; 0 on the fill-in's bed, which ends at the native fold).
    pub fold_lowering_mm: f64,
    pub template: ImplantTemplate,
    /// The implant's thickness as the template lays it (its rim mollified).
    pub thickness: SmoothedThickness,
    /// The planned fold, `fold_lowering_mm` below the native one: the template lays
    /// nothing off below it.
    pub fold: FoldPlane,
    /// Skin vertices of the finest level along the planned fold, under the implant's
    /// lower half: held to the chest at every stage, as the inframammary fold's
    /// attachment (re-formed at the planned fold) holds the skin there.
    pub fold_vertices: Vec<u32>,
    /// Time to place the implant and build its template (ms).
    pub setup_ms: f64,
}

/// The outcome of one [`Simulation::cycle`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CycleInfo {
    pub stage: Stage,
    /// `‖f_ext - f_int(u)‖` at the free vertices before the cycle (mN).
    pub residual_mn: f64,
    /// That over the load scale: in stage 1 the reaction forces at the held vertices
    /// plus the external loads, in stage 2 the norm of the stage's right-hand side.
    pub relative_residual: f64,
    /// Whether stage 1's multigrid hierarchy was built for this cycle (the session's
    /// first cycle, or after a switch of coarse operator); a new constraint set alone
    /// does not rebuild it.
    pub rebuilt: bool,
    /// The fraction of the cycle's step taken (1 unless the line search cut it).
    pub step: f64,
    /// A linear warm-up cycle (see [`SimulationOptions::linear_warmup_cycles`]).
    pub linear: bool,
    /// A Newton-Krylov step of a stalled stage 1 (see
    /// [`SimulationOptions::newton_krylov_iterations`]).
    pub newton_krylov: bool,
    /// A stage-1 cycle on the last assembly's operators (see
    /// [`SimulationOptions::lagged_operators`]).
    pub lagged: bool,
    /// Wall-clock time of the cycle, a rebuild included (ms).
    pub time_ms: f64,
}

/// The outcome of [`Simulation::solve`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct SolveReport {
    pub stage: Stage,
    pub cycles: usize,
    /// The relative residual before the last cycle.
    pub relative_residual: f64,
    pub converged: bool,
    pub time_ms: f64,
}

/// Both stages of [`Simulation::run`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct RunReport {
    pub implant: SolveReport,
    pub gravity: Option<SolveReport>,
}

/// One breast after the simulation.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct BreastVolume {
    /// Before (the breast model's figure, ml).
    pub volume_before_ml: f64,
    /// After: the moved breast patch over the chest wall (ml), that is the
    /// pre-operative fill-in, which the implant does not move, joined to the moved cut
    /// curve by a strip. An implant lies in front of that wall whatever the curve does,
    /// so the breast gains the implant's volume less what it pushes beyond the curve.
    /// Where the implant lies beyond the native breast (in a pocket below a lowered
    /// fold, beside a narrow breast), the chest skin over it is part of the breast after
    /// surgery: the volume that skin sweeps is added ([`crate::over_implant`]).
    pub volume_ml: f64,
    /// After, closed by a fill-in rebuilt on the moved cut curve with the model's
    /// method (ml): what a post-operative scan gives when modelled along the cut curve
    /// carried with the tissue. Where the implant pushes the curve itself forwards, the
    /// rebuilt fill-in rises with it and takes the implant's volume out of the breast.
    /// `None` where no fill-in can be rebuilt on the moved curve.
    pub volume_rebuilt_fill_ml: Option<f64>,
    /// After, closed by the fill-in moved with the tissue instead (ml). The fill-in lies
    /// in front of the bed, so the implant pushes it forwards with the breast: this
    /// volume barely grows (a diagnostic, not the clinical figure).
    pub volume_moved_fill_ml: f64,
    /// Centre of volume before and after (file frame, mm), of the closed surfaces of
    /// `volume_before_ml` and `volume_ml`.
    pub centre_before_mm: DVec3,
    pub centre_mm: DVec3,
    /// The quadrants of the closed surface of `volume_ml` (ml; they add up to it),
    /// bounded by the lines from the moved nipple to the moved clavicle and fold
    /// landmarks as on a real scan; `None` where those lines no longer run around the
    /// nipple in order.
    pub quadrant_volume_ml: Option<QuadrantVolumes>,
}

/// A bed an implant may lie on, with the template candidates' feet on it.
#[derive(Debug, Clone)]
struct BedChoice {
    bed: ImplantBed,
    /// The template's candidate vertices over this bed.
    candidates: SideCandidates,
    feet: BedFeet,
    /// The pocket's limits (`None`: the fill-in's bed).
    bounds: Option<PocketBounds>,
}

/// Per-side data of the session.
#[derive(Debug, Clone)]
struct SideData {
    fill: TriMesh,
    boundary_count: usize,
    /// The fill-in's boundary loop as base vertex indices.
    base_loop: Vec<u32>,
    patch: TriMesh,
    volume_before_ml: f64,
    centre_before_mm: DVec3,
    default_uv: DVec2,
}

/// The session's multigrid hierarchy and the elements its finest model currently treats
/// as implant (soft).
struct StageMultigrid {
    multigrid: Multigrid,
    soft_elements: Vec<u32>,
}

/// Maps of the breast meshes, computed on first use.
#[derive(Debug, Clone)]
struct MeshMaps {
    base: PointMap,
    patches: [PointMap; 2],
    fills: [PointMap; 2],
}

/// A simulation session over one patient model.
pub struct Simulation {
    options: SimulationOptions,
    frame: AnatomicalFrame,
    /// Tissue models of every level, finest first.
    levels: Vec<FemModel>,
    finest: TetMesh,
    /// The pectoralis major on the finest level (its elements have the muscle's
    /// material where [`SimulationOptions::muscle`] gives one).
    muscle: MuscleLayer,
    spacing_mm: f64,
    rear_wall_offset_mm: f64,
    cylinder: ChestCylinder,
    sides: [SideData; 2],
    beds: [ImplantBed; 2],
    /// Each side's beds to try, in order: the fill-in's and the pocket's (the pocket's
    /// first where the fold is lowered); `beds` holds the one the implant lies on.
    bed_choices: [Vec<BedChoice>; 2],
    /// The limits of the pocket the current implant lies in, if it lies in one.
    pocket_bounds: [Option<PocketBounds>; 2],
    /// The template candidates' feet on each side's current bed.
    feet: [BedFeet; 2],
    /// The finest vertices held at every stage (the wall, the band as held, the strip
    /// over the sternum).
    wall: Vec<u32>,
    /// Per finest vertex: on the wall (held at every stage).
    on_wall: Vec<bool>,
    /// The finest vertices whose displacement is zero whatever the implants (the wall
    /// where no template reaches): `u` is zero there at all times, which the composed
    /// carry to the scan relies on.
    never_moved: Vec<u32>,
    /// Per finest vertex: on the clip planes' band (held or not).
    on_band: Vec<bool>,
    /// Per finest vertex: on the skin (a boundary vertex off the wall and the band).
    on_skin: Vec<bool>,
    /// The held vertices of each coarser level, chosen alike (for rediscretised
    /// operators).
    coarse_walls: Vec<Vec<u32>>,
    /// The coarse operator in use, and how often Galerkin failed.
    coarse_operator: CoarseOperator,
    coarse_fallbacks: usize,
    /// Vertex neighbours of the finest level (CSR).
    neighbour_ptr: Vec<usize>,
    neighbours: Vec<u32>,
    implants: [Option<PlacedImplant>; 2],
    stage: StageState,
    /// Stage 1's hierarchy, once the first cycle built it (stage 2 holds it while it runs;
    /// its constraints are stale while `dirty`).
    multigrid: Option<StageMultigrid>,
    /// Hierarchies built so far.
    multigrid_builds: usize,
    /// The constraints changed since stage 1's multigrid last received them.
    dirty: bool,
    u: Vec<DVec3>,
    /// Stage 2's added implant weight (mN per finest vertex; empty in stage 1). The
    /// implant vertices' dead load goes into stage 2's right-hand side directly.
    f_ext: Vec<DVec3>,
    last_relative_residual: f64,
    /// Stage 1's residual before its last cycle (mN).
    last_residual_mn: f64,
    stage_cycles: usize,
    /// The constraints or loads changed since the last cycle (no line search then).
    fresh: bool,
    /// Stage 1's implants released as a gel ([`SimulationOptions::implant_gel`]).
    released: bool,
    /// Linear warm-up cycles still to run.
    warmup_left: usize,
    /// Stage 1's residual grew from one corotated cycle to the next: line search on
    /// for the rest of the stage.
    stage_one_search: bool,
    /// Stage 1's relative residuals before its last corotated cycles, at most
    /// [`STALL_WINDOW`] + 1 (the stall test's).
    stage_one_residuals: Vec<f64>,
    /// Stage 1's lagged cycles since its operators were last assembled.
    anderson: AndersonMixing,
    /// The last gravity correction (mm, per finest vertex): stage 2's displacement minus
    /// stage 1's when the session last left stage 2. The next correction starts from
    /// its best multiple ([`PcgIteration::from_guess`]): after a small change of the
    /// implants it is close to the new one.
    gravity_guess: Option<Vec<DVec3>>,
    /// Stage 1 stalled where the steps pay: Newton-Krylov steps for the rest of the stage
    /// ([`SimulationOptions::newton_krylov_iterations`]).
    newton_krylov: bool,
    /// The relative residual the cycles aim for: [`Simulation::solve`]'s tolerance while
    /// it runs, the options' otherwise (when Newton-Krylov steps pay depends on it).
    aimed_tolerance: f64,
    /// Potential energy at the current displacement, when known, and the last step.
    last_energy: Option<f64>,
    last_step: f64,
    scan_rest: Vec<DVec3>,
    scan_map: PointMap,
    scan_smoother: SurfaceSmoother,
    /// The two composed, once given ([`Simulation::scan_carry_job`]).
    scan_carry: Option<ScanCarry>,
    landmarks: Landmarks,
    /// Where each landmark (required, then extra) sits on the scan.
    landmark_feet: ScanFeet,
    /// Points along the breast model's cut curves per side (mm, every
    /// [`CARRIED_CONTROL_POINT_SPACING_MM`]) and where they sit on the scan.
    control_points: [Vec<DVec3>; 2],
    control_point_feet: [ScanFeet; 2],
    base: TriMesh,
    mesh_maps: Option<MeshMaps>,
}

fn elapsed_ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl Simulation {
    /// The options.
    pub fn options(&self) -> &SimulationOptions {
        &self.options
    }

    /// Sets [`SimulationOptions::newton_krylov_iterations`]; 0 also ends the Newton-Krylov
    /// steps of a stage 1 that has stalled (its further cycles are warped ones), for
    /// timing the paper's cycles alone.
    pub fn set_newton_krylov_iterations(&mut self, iterations: usize) {
        self.options.newton_krylov_iterations = iterations;
        if iterations == 0 {
            self.newton_krylov = false;
        }
    }

    /// Sets [`SimulationOptions::lagged_operators`]; off, every further cycle reassembles
    /// (for timing the paper's cycles alone).
    pub fn set_lagged_operators(&mut self, lagged: bool) {
        self.options.lagged_operators = lagged;
    }

    /// The finest level (rest state).
    pub fn finest_mesh(&self) -> &TetMesh {
        &self.finest
    }

    /// Whether stage 1's implants were released as a gel
    /// ([`SimulationOptions::implant_gel`]): their vertices are then free.
    pub fn implants_released(&self) -> bool {
        self.released
    }

    /// The pectoralis major on the finest level ([`crate::muscle`]).
    pub fn muscle(&self) -> &MuscleLayer {
        &self.muscle
    }

    /// The finest level's lattice spacing (mm).
    pub fn spacing_mm(&self) -> f64 {
        self.spacing_mm
    }

    /// The cylinder fitted to both fill-ins (each bed keeps the one it is
    /// parameterised over: this one, or its own where this one let it fold over).
    pub fn cylinder(&self) -> &ChestCylinder {
        &self.cylinder
    }

    /// The current implant bed of one side.
    pub fn bed(&self, side: Side) -> &ImplantBed {
        &self.beds[side as usize]
    }

    /// The limits of the pocket the implant of `side` lies in (with its own fold
    /// lowering); `None` where it lies on the fill-in's bed.
    pub fn pocket_bounds(&self, side: Side) -> Option<&PocketBounds> {
        self.pocket_bounds[side as usize].as_ref()
    }

    /// The finest vertices whose displacement is zero whatever the implants: the wall
    /// ([`Simulation::wall_vertices`]) but where a template may displace it.
    pub fn never_moved(&self) -> &[u32] {
        &self.never_moved
    }

    /// The finest vertices held at every stage: the posterior wall, the clip faces but
    /// where they cut a breast, and the strip over the sternum.
    pub fn wall_vertices(&self) -> &[u32] {
        &self.wall
    }

    /// The implant of one side, if any.
    pub fn implant(&self, side: Side) -> Option<&PlacedImplant> {
        self.implants[side as usize].as_ref()
    }

    /// The patient's anatomical frame (its `to_local` is the standing frame).
    pub fn frame(&self) -> &AnatomicalFrame {
        &self.frame
    }

    /// The current stage.
    pub fn stage(&self) -> Stage {
        self.stage.stage()
    }

    /// Starts stage 1 afresh from the displacement `u` (mm, one per finest vertex, as
    /// [`Simulation::displacement`] gives it), as after a change of the implants: two
    /// solves compared from one start. No gravity correction is known for it (see
    /// [`Simulation::restore`]). On error nothing changes.
    pub fn restart_from(&mut self, u: &[DVec3]) -> Result<(), SimulationError> {
        self.restore(&SolvedState {
            u: u.to_vec(),
            gravity_correction: None,
        })
    }

    /// The current state to start again from: the displacement and the gravity
    /// correction in it (or the last one the session made).
    pub fn solved_state(&self) -> SolvedState {
        SolvedState {
            u: self.u.clone(),
            gravity_correction: self.gravity_correction(),
        }
    }

    /// Starts stage 1 afresh from a state [`Simulation::solved_state`] gave, as after a
    /// change of the implants; the next gravity correction starts from the state's. The
    /// vertices no implant moves ([`Simulation::never_moved`]) start at zero whatever
    /// the state says. On error nothing changes.
    pub fn restore(&mut self, state: &SolvedState) -> Result<(), SimulationError> {
        let count = self.u.len();
        let fits = |v: &[DVec3]| v.len() == count && v.iter().all(|d| d.is_finite());
        for (what, values) in [
            ("displacements", Some(&state.u)),
            ("gravity corrections", state.gravity_correction.as_ref()),
        ] {
            if let Some(values) = values.filter(|v| !fits(v)) {
                return Err(SimulationError::BadModel(format!(
                    "a restart needs {count} finite {what}, got {}",
                    values.len()
                )));
            }
        }
        self.u.copy_from_slice(&state.u);
        for &v in &self.never_moved {
            self.u[v as usize] = DVec3::ZERO;
        }
        self.constraints_changed();
        self.gravity_guess = state.gravity_correction.clone();
        Ok(())
    }

    /// The gravity correction in the current state (stage 2, once it has iterated),
    /// else the last one made.
    fn gravity_correction(&self) -> Option<Vec<DVec3>> {
        match &self.stage {
            StageState::Gravity(gravity) if gravity.iteration.iterations() > 0 => Some(
                self.u
                    .iter()
                    .zip(&gravity.u_implant)
                    .map(|(u, u_implant)| *u - *u_implant)
                    .collect(),
            ),
            _ => self.gravity_guess.clone(),
        }
    }

    /// Removes the implant of one side (back to stage 1).
    pub fn remove_implant(&mut self, side: Side) {
        if self.implants[side as usize].take().is_some() {
            self.constraints_changed();
        }
    }

    /// The finest level's displacement (mm, one per vertex).
    pub fn displacement(&self) -> &[DVec3] {
        &self.u
    }

    /// The finest displacement at the end of stage 1, once the gravity correction began.
    pub fn displacement_before_gravity(&self) -> Option<&[DVec3]> {
        match &self.stage {
            StageState::Implant => None,
            StageState::Gravity(gravity) => Some(&gravity.u_implant),
        }
    }

    /// Cycles run in the current stage, and the relative residual before the last one.
    pub fn stage_progress(&self) -> (usize, f64) {
        (self.stage_cycles, self.last_relative_residual)
    }

    /// The current stage's multigrid (its system, phase timings), once built: stage 1's
    /// by its first cycle, stage 2's by [`Simulation::start_gravity_correction`].
    pub fn multigrid(&self) -> Option<&Multigrid> {
        self.stage_multigrid()
    }

    /// The current multigrid, mutably: for solving its assembled system another way
    /// (e.g. [`Multigrid::pcg`] in checks and benchmarks). Changing its constraints or
    /// materials through it would desynchronise the session.
    pub fn multigrid_mut(&mut self) -> Option<&mut Multigrid> {
        match &mut self.stage {
            StageState::Implant => self.multigrid.as_mut().map(|kept| &mut kept.multigrid),
            StageState::Gravity(gravity) => Some(&mut gravity.multigrid.multigrid),
        }
    }

    /// Finest elements whose deformed volume is not positive.
    pub fn inverted_elements(&self) -> Vec<usize> {
        self.finest
            .tets
            .par_iter()
            .enumerate()
            .filter_map(|(e, t)| {
                let q = t.map(|v| self.finest.positions[v as usize] + self.u[v as usize]);
                (tetra::quality::signed_volume(q) <= 0.0).then_some(e)
            })
            .collect()
    }
}

/// Vertex neighbours of a tetrahedral mesh (CSR: `neighbours[ptr[v]..ptr[v + 1]]`).
fn vertex_neighbours(mesh: &TetMesh) -> (Vec<usize>, Vec<u32>) {
    let n = mesh.positions.len();
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.tets.len() * 12);
    for t in &mesh.tets {
        for a in 0..4 {
            for b in 0..4 {
                if a != b {
                    pairs.push((t[a], t[b]));
                }
            }
        }
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    let mut ptr = vec![0usize; n + 1];
    for &(a, _) in &pairs {
        ptr[a as usize + 1] += 1;
    }
    for i in 0..n {
        ptr[i + 1] += ptr[i];
    }
    (ptr, pairs.into_iter().map(|(_, b)| b).collect())
}

/// The finest vertices on the closed surface's posterior wall or band: boundary vertices
/// of the tetrahedral mesh whose closest point on the closed surface lies on a
/// `back_wall` or `band` triangle within `tolerance_mm`; `true` marks band vertices.
fn wall_vertices(
    mesh: &TetMesh,
    closed: &ClosedSurface,
    tolerance_mm: f64,
) -> Result<Vec<(u32, bool)>, SimulationError> {
    let Some(index) = mesh::SurfaceIndex::new(&closed.mesh) else {
        return Err(SimulationError::BadModel(
            "the closed surface has no triangles".into(),
        ));
    };
    let boundary = mesh.boundary();
    let mut wall: Vec<(u32, bool)> = boundary
        .tet_vertex
        .par_iter()
        .filter_map(|&v| {
            let cp = index.closest_point_within(mesh.positions[v as usize], tolerance_mm)?;
            if closed.back_wall.contains(&cp.triangle) {
                Some((v, false))
            } else if closed.band.contains(&cp.triangle) {
                Some((v, true))
            } else {
                None
            }
        })
        .collect();
    wall.sort_unstable();
    if wall.is_empty() {
        return Err(SimulationError::BadModel(
            "no finest vertex lies on the closed surface's posterior wall or band".into(),
        ));
    }
    Ok(wall)
}
