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
//!   breast itself (on every scan so far the lateral planes cut 20-30 mm off the lateral
//!   breast), and holding those faces glues the breast to the plane next to the implant
//!   (measured on the phantom: about a thousand inverted elements along the lateral
//!   plane); they are left free (traction-free). Vertices are assigned to the wall or
//!   band when their closest point on the closed surface lies on one of those triangles
//!   and within [`WALL_TOLERANCE_FACTOR`] times the finest spacing of it.
//! - Per implant ([`crate::template`]): implant vertices displaced along the bed normal by
//!   the implant's thickness, back vertices inside the footprint fixed. A vertex that is
//!   both wall and implant takes the implant's value.
//!
//! # Stages
//! 1. [`Stage::Implant`]: the Dirichlet problem of the template, solved by
//!    [`Multigrid::cycle`] (rotation update, reassembly, one V(2,1)-cycle) on the
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
//!    cycle ([`fem::multigrid::PcgIteration`]), from the stage-1 displacement. The breast
//!    sags: the nipple moves down. Why linear: under the dead loads the soft implant
//!    region has no stiffness of its own against moving as a whole, and the corotated
//!    iteration with a line search on the energy wandered off (on `v02_average` the
//!    residual grew from 5e-3 to 0.5 in 40 cycles, inverting 18 elements, and neither
//!    pair1 scan converged); the added weight moves the nipple by 5-9 mm, where the
//!    linear response of the deformed state is accurate, and the tangent system is
//!    symmetric positive definite. Bare V-cycles converge slowly on it (the soft implant
//!    region is a coefficient jump of 100 that the coarse levels do not see); conjugate
//!    gradients with a symmetric V(2,2) preconditioner reach a relative residual of 1e-3
//!    in 6-21 cycles at 60k elements (phantom 6, `pair1_pre` 10, `v02_average` 21; with
//!    the interactive V(2,1) cycle `v02_average` stalled at 2.4e-3 after 40).
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
//! displacement is kept as the warm start.

mod carried;

pub use carried::CARRIED_CONTROL_POINT_SPACING_MM;
use carried::{ScanFeet, closed_volume, points_along_loop};

use crate::bed::{ChestCylinder, DEFAULT_SHIFT_MM, ImplantBed};
use crate::carry::ScanCarry;
use crate::error::SimulationError;
use crate::field::{DEFAULT_FALLOFF_MM, FieldLocator, PointMap, SurfaceSmoother};
use crate::placement::{Anchor, AnchorRule, Placement, anchor_on_floor, resolve_anchor};
use crate::pocket::{
    FoldLowering, PocketBounds, PocketLimits, fold_lowest, native_fold_y_mm, nipple_of,
    nipple_to_fold_mm, pocket_surface,
};
use crate::skin::SkinLayer;
use crate::template::{
    BedFeet, FOOTPRINT_TOLERANCE_MM, ImplantTemplate, SideCandidates, SmoothedThickness,
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
    CompressionPenalty, Constraints, FemModel, Formulation, InversionBarrier, Material, Tangent,
};
use glam::{DVec2, DVec3};
use implant::ImplantShape;
use mesh::TriMesh;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;
use tetra::TetMesh;

/// A finest vertex belongs to the posterior wall or band when its closest point on the
/// closed surface lies on such a triangle within this many finest spacings.
pub const WALL_TOLERANCE_FACTOR: f64 = 0.25;

/// Default Young's modulus of implant elements as a fraction of the tissue's: "very soft"
/// (paper V-A). Only stage 2 sees it (in stage 1 every implant element has all its corners
/// prescribed).
pub const DEFAULT_IMPLANT_YOUNG_RATIO: f64 = 0.01;

/// Default inversion barrier of the finest level: elements squeezed below half their
/// volume resist with a modulus of 100 kPa (about forty times the tissue's Young's
/// modulus), the soft implant elements too, and stiffer elements (the skin's) with forty
/// times their own modulus (docs/dev/skin.md). Measured on the
/// shared scans with base-sized round implants (no gravity): inverted elements 3, 7 and
/// 10 (v02_average, pair1_post, pair1_pre) without it; with 50 kPa 1, 0, 0; with
/// 100 kPa none (stage 1 in 14 cycles on v02_average instead of 10); 200 kPa took 34
/// cycles there, and a threshold of 0.3 left one element inverted at 100 kPa.
pub const DEFAULT_INVERSION_BARRIER: InversionBarrier = InversionBarrier {
    min_volume_ratio: 0.5,
    modulus_kpa: 100.0,
    young_multiple: 40.0,
};

/// Default compression penalty of the finest level: beyond 10% volume loss an element
/// resists with its own first Lamé parameter, `λ V (0.9 - J)²`, so small strains stay
/// linear-elastic and tissue squeezed over an implant keeps its volume
/// (docs/dev/volume-loss.md).
pub const DEFAULT_COMPRESSION_PENALTY: CompressionPenalty = CompressionPenalty {
    onset_volume_ratio: 0.9,
    lambda_multiple: 1.0,
};

/// Default radius of the implant rim's mollifier in finest lattice spacings. Linear
/// tetrahedra cannot follow a rim that rises by 10 mm within 3 mm (the square-root edge
/// of eqs. 3 and 10): measured on v02_average with R-MOD-110 at 60,000 elements, the
/// elements over the rim inverted: 32 with one spacing, 5 with two or two and a half.
/// Two spacings (12-14 mm) is also about the rounded edge of a real round implant.
pub const RIM_SMOOTHING_SPACINGS: f64 = 2.0;

/// Default thickness of the tissue layer that moves with the implant in finest lattice
/// spacings. The paper's template displaces only the front vertices of the elements
/// crossing the bed, a ragged set: free vertices at the same height between displaced
/// ones lagged and folded their elements over (v02_average, R-MOD-110: 11 inverted
/// with the paper's set, 5 with one spacing, 3 with one and a half).
pub const TEMPLATE_LAYER_SPACINGS: f64 = 1.0;

/// Largest [`SimulationOptions::scan_smoothing_mm`] (mm): the smoothing is meant for
/// the element scale, and its cost grows with the radius squared.
pub const MAX_SCAN_SMOOTHING_MM: f64 = 20.0;

/// Default implant density (kg/m³): silicone gel, 0.97 g/cm³.
pub const DEFAULT_IMPLANT_DENSITY_KG_M3: f64 = 970.0;

/// Half the width of the vertical section [`Simulation::simulated_fold`] looks on (mm).
pub const FOLD_SECTION_HALF_WIDTH_MM: f64 = 3.0;

/// How far forward the skin must have moved to count as breast in
/// [`Simulation::simulated_fold`] (mm): above the scan's noise and the gravity
/// correction's small shifts of the chest.
pub const FOLD_MOVED_FORWARD_MM: f64 = 2.0;

/// Default relative residual at which [`Simulation::solve`] stops.
pub const DEFAULT_RELATIVE_TOLERANCE: f64 = 1e-3;

/// Default cycle limit of [`Simulation::solve`].
pub const DEFAULT_MAX_CYCLES: usize = 40;

/// Relative residual at which the linear warm-up stops.
pub const WARMUP_TOLERANCE: f64 = 0.05;

/// Most halvings of a cycle's step by the line search.
pub const MAX_HALVINGS: usize = 5;

/// Furthest the bed may be moved in front of the fill-in (mm).
pub const MAX_FORWARD_SHIFT_MM: f64 = 10.0;

/// Least tissue kept between the bed and the posterior wall (mm).
pub const MIN_WALL_CLEARANCE_MM: f64 = 3.0;

/// Settings of a [`Simulation`].
#[derive(Debug, Clone, PartialEq)]
pub struct SimulationOptions {
    /// Backward shift of the implant bed behind the fill-in (mm).
    pub shift_mm: f64,
    /// Where the default anchor lies.
    pub anchor_rule: AnchorRule,
    /// The pocket the implant may lie in ([`crate::pocket`]): the fill-in widened over
    /// the chest within anatomical limits, per side `[left, right]` (the fold lowering
    /// may differ). `None`: the paper's bed, the fill-in alone.
    pub pocket: Option<[PocketLimits; 2]>,
    /// Move an implant whose footprint overhangs the bed at the requested anchor to the
    /// nearest anchor where it fits ([`crate::template::fit_footprint`]; the move is
    /// reported as [`PlacedImplant::fit_shift_mm`]) instead of refusing it.
    pub fit_footprint: bool,
    /// Hold the whole bed, not only its part under the implant: every back vertex of a
    /// fill-in element is fixed (the paper fixes the back vertices inside the footprint
    /// only). The tissue behind the bed is the pectoral muscle on the ribs; leaving it
    /// free next to the implant's rim let the rim elements, pushed out by the steep
    /// edge of the implant on one side and dragged along the free slab on the other,
    /// invert (measured on the phantom at 60,000 elements: 40-80 inverted elements
    /// and a corotated iteration that stalled at a relative residual of 0.2-0.3).
    pub hold_bed: bool,
    /// Radius of the kernel that mollifies the implant's thickness in the template
    /// (mm); `None`: [`RIM_SMOOTHING_SPACINGS`] finest lattice spacings. `Some(0.0)`: no
    /// smoothing.
    pub rim_smoothing_mm: Option<f64>,
    /// Thickness of the tissue layer over the footprint that moves with the implant
    /// (mm), besides the front vertices of the elements crossing the bed (the paper's
    /// template); `None`: [`TEMPLATE_LAYER_SPACINGS`] finest lattice spacings.
    pub template_layer_mm: Option<f64>,
    /// Breast tissue.
    pub tissue: Material,
    /// The skin over it ([`crate::skin`]); `None`: tissue up to the surface (the
    /// paper's homogeneous model).
    pub skin: Option<SkinLayer>,
    /// Implant elements' Young's modulus over the tissue's.
    pub implant_young_ratio: f64,
    /// Implant elements' Poisson ratio.
    pub implant_poisson_ratio: f64,
    /// Implant density (kg/m³) for the gravity correction.
    pub implant_density_kg_m3: f64,
    /// Gravity (m/s²), acting along the anatomical frame's `-y`.
    pub gravity_m_s2: f64,
    /// The corotated tangent `K` of the gravity stage's linear system (stage 1 uses the
    /// multigrid's, the paper's warped stiffness). [`Tangent::Full`] adds the positive
    /// part of the geometric stiffness, the better linearisation where tissue is
    /// stretched and turned.
    pub gravity_tangent: Tangent,
    /// The multigrid's settings. With Galerkin coarse operators (the default) a
    /// singular coarse operator (see [`Simulation::coarse_fallbacks`]) makes the session
    /// switch to rediscretised ones, whose coarse levels hold their own wall and band
    /// vertices.
    pub multigrid: MultigridOptions,
    /// In stage 1, once the residual grows from one corotated cycle to the next,
    /// backtrack each cycle's step on the potential energy (halving up to
    /// [`MAX_HALVINGS`] times until it does not grow): the multigrid's matrix is the
    /// warped stiffness `R K Rᵀ` without the geometric term, so the plain fixed-point
    /// iteration can overshoot. It starts only then (an energy costs a fair part of a
    /// cycle, and most placements never need it): a 252 ml implant in v02_average's
    /// 182 ml breast otherwise settled into a three-cycle oscillation at a relative
    /// residual of 0.19-0.21. (The gravity stage is linear and needs none.)
    pub line_search: bool,
    /// Linear (small-strain) cycles before the corotated ones when stage 1 starts cold
    /// (zero displacement): at most this many, stopping once the relative residual is
    /// below [`WARMUP_TOLERANCE`]. From zero, the first corotated cycles push the implant
    /// vertices through their neighbours (3,600 inverted elements on the phantom after
    /// one cycle) and took 20 cycles to untangle; from the linear solution the corotated
    /// cycles converged in 8 with no inverted element on the way.
    pub linear_warmup_cycles: usize,
    /// The finest level's safeguard against inverted elements (see
    /// [`fem::InversionBarrier`]; `None`: the paper's plain corotated energy). Default
    /// [`DEFAULT_INVERSION_BARRIER`].
    pub inversion_barrier: Option<InversionBarrier>,
    /// The finest level's resistance to large volume loss (see
    /// [`fem::CompressionPenalty`]; `None`: the paper's corotated energy). Default
    /// [`DEFAULT_COMPRESSION_PENALTY`].
    pub compression_penalty: Option<CompressionPenalty>,
    /// Use at most this many levels of the hierarchy, finest first (`None`: all).
    pub max_levels: Option<usize>,
    /// Cycle limit and relative residual of [`Simulation::solve`].
    pub max_cycles: usize,
    pub relative_tolerance: f64,
    /// Fade length of the displacement beyond the finest mesh (mm), see [`crate::field`].
    pub falloff_mm: f64,
    /// Radius over which the displacement is smoothed on the scan (mm, see
    /// [`SurfaceSmoother`]); `None`: half the finest lattice spacing; `Some(0.0)`: none.
    pub scan_smoothing_mm: Option<f64>,
    /// Fill-in parameters for re-measuring the simulated breasts (the cylinder axis
    /// defaults to the frame's `y`, as when the model was built).
    pub fill_in: FillInParams,
}

impl Default for SimulationOptions {
    fn default() -> Self {
        SimulationOptions {
            shift_mm: DEFAULT_SHIFT_MM,
            anchor_rule: AnchorRule::default(),
            pocket: Some([PocketLimits::default(); 2]),
            fit_footprint: true,
            hold_bed: true,
            rim_smoothing_mm: None,
            template_layer_mm: None,
            tissue: Material::default(),
            skin: Some(SkinLayer::default()),
            implant_young_ratio: DEFAULT_IMPLANT_YOUNG_RATIO,
            implant_poisson_ratio: 0.3,
            implant_density_kg_m3: DEFAULT_IMPLANT_DENSITY_KG_M3,
            gravity_m_s2: fem::STANDARD_GRAVITY_M_S2,
            multigrid: MultigridOptions::default(),
            inversion_barrier: Some(DEFAULT_INVERSION_BARRIER),
            compression_penalty: Some(DEFAULT_COMPRESSION_PENALTY),
            max_levels: None,
            line_search: true,
            linear_warmup_cycles: 6,
            max_cycles: DEFAULT_MAX_CYCLES,
            relative_tolerance: DEFAULT_RELATIVE_TOLERANCE,
            falloff_mm: DEFAULT_FALLOFF_MM,
            scan_smoothing_mm: None,
            gravity_tangent: Tangent::Full,
            fill_in: FillInParams::default(),
        }
    }
}

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
    /// After: the moved breast patch closed by a fill-in rebuilt on the moved base with
    /// the model's fill-in method (ml): the same measurement as on a real post-operative
    /// scan.
    pub volume_ml: f64,
    /// Whether `volume_ml` stands on a rebuilt fill-in; `false`: on the pre-operative
    /// fill-in joined to the moved cut curve by a strip (the curve folded seen from
    /// every projection the fill-in method tries).
    pub rebuilt_fill: bool,
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

/// What [`Simulation::fit_on`] found: bed, feet, pocket bounds, requested and fitted
/// anchor, fold lowering (mm).
type FittedOn = (
    ImplantBed,
    BedFeet,
    Option<PocketBounds>,
    Anchor,
    Anchor,
    f64,
);

/// An implant that does not fit its pocket because it reaches past one of the pocket's
/// anatomical limits gets the error naming that limit; other errors pass.
fn pocket_limit_error(
    side: Side,
    bounds: Option<&PocketBounds>,
    error: SimulationError,
) -> SimulationError {
    let (SimulationError::ImplantLargerThanFootprint { near_mm, .. }, Some(bounds)) =
        (&error, bounds)
    else {
        return error;
    };
    match bounds.violation(DVec3::from_array(*near_mm)) {
        Some((limit, beyond_mm)) => SimulationError::PocketLimit {
            side,
            limit,
            beyond_mm,
        },
        None => error,
    }
}

/// A move may take the implant this much further past a pocket's limit than its
/// default position lies before it is refused (mm): the pushes of the fit undo that much.
const MOVE_PAST_LIMIT_TOLERANCE_MM: f64 = 2.0;

/// The footprint's lowest point may lie this far below a fold lowered by a given amount
/// (mm): the footprint's own tolerance on the bed's edge.
const FLOOR_TOLERANCE_MM: f64 = FOOTPRINT_TOLERANCE_MM;

/// Outline points of the footprint checked against the planned fold.
const FLOOR_CHECK_POINTS: usize = 72;

/// The height (standing frame, mm) of the lowest point of the footprint of `shape`
/// anchored at `anchor` on `bed`.
fn lowest_footprint_y_mm(
    bed: &ImplantBed,
    anchor: &Anchor,
    shape: &ImplantShape,
    frame: &AnatomicalFrame,
) -> f64 {
    (shape.footprint_outline_mm(FLOOR_CHECK_POINTS).into_iter())
        .filter_map(|local| bed.at(anchor.uv_of(local)))
        .map(|at| frame.to_local(at.position).y)
        .fold(f64::INFINITY, f64::min)
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

/// The session's multigrid hierarchy, the elements its finest model currently treats as
/// implant (soft), and the stage whose constraints and tangent it holds.
struct StageMultigrid {
    multigrid: Multigrid,
    soft_elements: Vec<u32>,
    stage: Stage,
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
    /// Posterior wall and band vertices of the finest level.
    wall: Vec<u32>,
    /// Per finest vertex: on the wall (held at every stage).
    on_wall: Vec<bool>,
    /// Per finest vertex: on the clip planes' band (held or not).
    on_band: Vec<bool>,
    /// Per finest vertex: on the skin (a boundary vertex off the wall and the band).
    on_skin: Vec<bool>,
    /// Held wall and band vertices of each coarser level (for rediscretised operators).
    coarse_walls: Vec<Vec<u32>>,
    /// The coarse operator in use, and how often Galerkin failed.
    coarse_operator: CoarseOperator,
    coarse_fallbacks: usize,
    /// Vertex neighbours of the finest level (CSR).
    neighbour_ptr: Vec<usize>,
    neighbours: Vec<u32>,
    implants: [Option<PlacedImplant>; 2],
    stage: Stage,
    /// The hierarchy of both stages, once the first cycle built it.
    multigrid: Option<StageMultigrid>,
    /// Hierarchies built so far.
    multigrid_builds: usize,
    /// The constraints changed since stage 1's multigrid last received them.
    dirty: bool,
    u: Vec<DVec3>,
    f_ext: Vec<DVec3>,
    u_before_gravity: Option<Vec<DVec3>>,
    /// Stage 2's linear system `K Δu = r` at the stage-1 displacement (its right-hand
    /// side the added implant weight and what is left of stage 1's residual) and its
    /// conjugate gradient iteration, once the stage's first cycle assembled it, with the
    /// norm of that right-hand side (mN), which the stage's residual is relative to.
    gravity: Option<(PcgIteration, f64)>,
    last_relative_residual: f64,
    stage_cycles: usize,
    /// The constraints or loads changed since the last cycle (no line search then).
    fresh: bool,
    /// Linear warm-up cycles still to run.
    warmup_left: usize,
    /// Stage 1's residual grew from one corotated cycle to the next: line search on
    /// for the rest of the stage.
    stage_one_search: bool,
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

fn check_option(
    what: &'static str,
    value: f64,
    ok: bool,
    expected: &'static str,
) -> Result<(), SimulationError> {
    if ok && value.is_finite() {
        Ok(())
    } else {
        Err(SimulationError::BadOption {
            what,
            value,
            expected,
        })
    }
}

impl Simulation {
    /// Prepares a session: the tissue model of every level, the implant beds at the
    /// default shift with their default anchors, the template index, the held wall and
    /// band vertices, and the maps of the scan and landmarks onto the finest level.
    ///
    /// Errors: bad options, a hierarchy without levels or with inverted elements, a
    /// fill-in that cannot carry an implant.
    pub fn new(
        input: PatientInput,
        options: SimulationOptions,
    ) -> Result<Simulation, SimulationError> {
        check_option("shift_mm", options.shift_mm, true, "a finite number of mm")?;
        check_option(
            "implant_young_ratio",
            options.implant_young_ratio,
            options.implant_young_ratio > 0.0,
            "a positive fraction",
        )?;
        check_option(
            "implant_density_kg_m3",
            options.implant_density_kg_m3,
            options.implant_density_kg_m3 >= 0.0,
            "a non-negative density",
        )?;
        check_option(
            "gravity_m_s2",
            options.gravity_m_s2,
            true,
            "a finite acceleration",
        )?;
        check_option(
            "relative_tolerance",
            options.relative_tolerance,
            options.relative_tolerance > 0.0,
            "a positive number",
        )?;
        check_option(
            "falloff_mm",
            options.falloff_mm,
            options.falloff_mm > 0.0,
            "a positive length",
        )?;
        for (what, value, max, expected) in [
            (
                "rim_smoothing_mm",
                options.rim_smoothing_mm,
                f64::INFINITY,
                "a length of at least 0 mm",
            ),
            (
                "template_layer_mm",
                options.template_layer_mm,
                f64::INFINITY,
                "a length of at least 0 mm",
            ),
            (
                "scan_smoothing_mm",
                options.scan_smoothing_mm,
                MAX_SCAN_SMOOTHING_MM,
                "a length from 0 to 20 mm",
            ),
        ] {
            if let Some(v) = value {
                check_option(what, v, (0.0..=max).contains(&v), expected)?;
            }
        }
        options
            .tissue
            .check()
            .map_err(|what| SimulationError::BadModel(format!("tissue material: {what}")))?;
        if let Some(skin) = &options.skin {
            skin.check(&options.tissue)
                .map_err(|what| SimulationError::BadModel(format!("skin: {what}")))?;
        }
        let frame = *input.frame;
        let Some(level0) = input.tets.levels.first() else {
            return Err(SimulationError::BadModel(
                "the hierarchy has no level".into(),
            ));
        };
        let finest = level0.mesh.clone();
        let spacing_mm = level0.spacing_mm;
        let level_count = options.max_levels.unwrap_or(usize::MAX).max(1);
        let mut levels = input
            .tets
            .levels
            .iter()
            .take(level_count)
            .map(|l| FemModel::homogeneous(&l.mesh, options.tissue))
            .collect::<Result<Vec<_>, _>>()?;
        levels[0].set_inversion_barrier(options.inversion_barrier)?;
        levels[0].set_compression_penalty(options.compression_penalty)?;
        let closed = input.closed_surface;

        // one cylinder about the body's axis through both fill-ins
        let fill_points: Vec<DVec3> = Side::BOTH
            .iter()
            .flat_map(|&s| input.breasts.breast(s).fill.mesh.positions.iter().copied())
            .collect();
        let cylinder = ChestCylinder::fit(&fill_points, &frame.sternal());
        let sides = Side::BOTH.map(|side| {
            let b = input.breasts.breast(side);
            let (volume_before_ml, centre_before_mm) = closed_volume(&b.patch.mesh, &b.fill.mesh);
            SideData {
                fill: b.fill.mesh.clone(),
                boundary_count: b.fill.boundary_to_base.len(),
                base_loop: b.fill.boundary_to_base.clone(),
                patch: b.patch.mesh.clone(),
                volume_before_ml,
                centre_before_mm,
                default_uv: DVec2::ZERO,
            }
        });
        // the chest-wide cylinder, or where the fill-in folds over seen from its axis
        // (a steep lateral fill-in), one fitted to that fill-in alone
        let bed_over = |side: Side, surface: &TriMesh, boundary_count: usize| {
            let data = &sides[side as usize];
            ImplantBed::new(side, surface, boundary_count, &cylinder, options.shift_mm).or_else(
                |error| {
                    let own = ChestCylinder::fit(&data.fill.positions, &frame.sternal());
                    ImplantBed::new(side, surface, boundary_count, &own, options.shift_mm)
                        .map_err(|_| error)
                },
            )
        };
        let pockets = Side::BOTH.map(|side| {
            let limits = options.pocket?[side as usize];
            // as deep as any implant's planned fold; each implant's own bounds are
            // checked when it is placed
            let deepest = limits.fold_lowering.deepest_mm();
            let bounds = PocketBounds::new(side, &frame, input.landmarks, &limits, deepest);
            let surface = pocket_surface(
                &input.breasts.base.mesh,
                &input.breasts.breast(side).fill,
                &frame,
                &bounds,
                Some(&closed.clip_box),
                limits.margin_mm,
            )?;
            Some((bounds, surface))
        });
        // the fill-in's bed, and the pocket's where it can carry an implant (a graph
        // over the same cylinder once its folding chest triangles are dropped)
        let fill_bed_of = |side: Side| {
            let data = &sides[side as usize];
            bed_over(side, &data.fill, data.boundary_count)
        };
        let beds = [fill_bed_of(Side::Left)?, fill_bed_of(Side::Right)?];
        let pocket_beds = Side::BOTH.map(|side| {
            let (bounds, pocket) = pockets[side as usize].as_ref()?;
            let fill_bed = &beds[side as usize];
            let pocket = pocket
                .clone()
                .without_folds(&fill_bed.cylinder, options.shift_mm)?;
            let bed = ImplantBed::new(
                side,
                &pocket.mesh,
                pocket.boundary_count,
                &fill_bed.cylinder,
                options.shift_mm,
            )
            .ok()?;
            Some((bed, *bounds))
        });
        let mut sides = sides;
        for side in Side::BOTH {
            let bed = &beds[side as usize];
            let uv = match options.anchor_rule {
                AnchorRule::FootprintCentre => bed.centroid_uv(),
                // on-fold walks down from behind the nipple for each implant
                AnchorRule::BehindNipple | AnchorRule::OnFold => {
                    let nipple = input.landmarks.get(nipple_of(side));
                    let c = bed.cylinder.to_cylindrical(nipple);
                    DVec2::new(c.x, c.y)
                }
            };
            if bed.at(uv).is_none() {
                return Err(SimulationError::BadFillIn {
                    side,
                    reason: format!(
                        "the default anchor ({}) does not lie on it",
                        options.anchor_rule
                    ),
                });
            }
            sides[side as usize].default_uv = uv;
        }

        let max_edge = finest
            .tets
            .iter()
            .flat_map(|t| {
                [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)].map(|(a, b)| {
                    finest.positions[t[a] as usize].distance(finest.positions[t[b] as usize])
                })
            })
            .fold(0.0, f64::max);
        let (back_mm, front_mm) = (
            closed.rear_wall_offset_mm + 2.0 * max_edge,
            MAX_FORWARD_SHIFT_MM + options.shift_mm.max(0.0) + 2.0 * max_edge,
        );
        // candidates over the fill-in's bed (the paper's), and over each pocket
        let [fill_left, fill_right] =
            TemplateIndex::new(&finest, [&beds[0], &beds[1]], back_mm, front_mm).sides;

        let pocket_candidates = pocket_beds.each_ref().map(|pocket| {
            let (bed, _) = pocket.as_ref()?;
            let [left, right] = TemplateIndex::new(&finest, [bed, bed], back_mm, front_mm).sides;
            Some(match bed.side {
                Side::Left => left,
                Side::Right => right,
            })
        });
        // the band is held except where a clip plane cuts through breast tissue in front
        // of an implant bed
        let held = |mesh: &TetMesh, wall_and_band: &[(u32, bool)]| -> Vec<u32> {
            wall_and_band
                .iter()
                .filter(|&&(v, band)| {
                    !band
                        || !beds.iter().any(|bed| {
                            let c = bed.cylinder.to_cylindrical(mesh.positions[v as usize]);
                            bed.at(DVec2::new(c.x, c.y)).is_some_and(|b| c.z > b.w)
                        })
                })
                .map(|&(v, _)| v)
                .collect()
        };
        let finest_wall_and_band =
            wall_vertices(&finest, closed, spacing_mm * WALL_TOLERANCE_FACTOR)?;
        if let Some(skin) = options.skin {
            let mut not_skin = vec![false; finest.positions.len()];
            for &(v, _) in &finest_wall_and_band {
                not_skin[v as usize] = true;
            }
            let materials = skin.materials(&finest, options.tissue, &not_skin);
            for (e, material) in materials.into_iter().enumerate() {
                if material != options.tissue {
                    levels[0].set_material(e, material)?;
                }
            }
        }
        let wall = held(&finest, &finest_wall_and_band);
        let mut on_band = vec![false; finest.positions.len()];
        let mut on_skin = vec![false; finest.positions.len()];
        for &v in &finest.boundary().tet_vertex {
            on_skin[v as usize] = true;
        }
        for &(v, band) in &finest_wall_and_band {
            on_band[v as usize] = band;
            on_skin[v as usize] = false;
        }
        let mut on_wall = vec![false; finest.positions.len()];
        for &v in &wall {
            on_wall[v as usize] = true;
        }
        let coarse_walls = input.tets.levels[1..levels.len()]
            .iter()
            .map(|l| {
                let wall_and_band =
                    wall_vertices(&l.mesh, closed, l.spacing_mm * WALL_TOLERANCE_FACTOR)?;
                Ok(held(&l.mesh, &wall_and_band))
            })
            .collect::<Result<Vec<_>, SimulationError>>()?;

        let locator = FieldLocator::new(&finest, spacing_mm).ok_or_else(|| {
            SimulationError::BadModel("the finest level has no tetrahedra".into())
        })?;
        let scan_rest = input.scan.positions.clone();
        let scan_map = PointMap::new(&locator, &scan_rest, options.falloff_mm);
        let scan_smoother = SurfaceSmoother::with_support(
            input.scan,
            options.scan_smoothing_mm.unwrap_or(0.5 * spacing_mm),
            &scan_map.support(),
        );
        let scan_index = mesh::SurfaceIndex::new(input.scan)
            .ok_or_else(|| SimulationError::BadModel("the scan has no triangles".into()))?;
        let landmark_feet = ScanFeet::locate(
            input.scan,
            &scan_index,
            input.landmarks.iter().map(|(_, p)| p),
        );
        let control_points = Side::BOTH.map(|side| {
            let curve = &input.breasts.breast(side).curve;
            let positions: Vec<DVec3> = curve.points.iter().map(|p| p.position).collect();
            points_along_loop(&positions, CARRIED_CONTROL_POINT_SPACING_MM)
        });
        let control_point_feet = control_points
            .each_ref()
            .map(|points| ScanFeet::locate(input.scan, &scan_index, points.iter().copied()));
        let n = finest.positions.len();
        let (neighbour_ptr, neighbours) = vertex_neighbours(&finest);
        let [pocket_left, pocket_right] = pocket_candidates;
        let sides_candidates = [
            (Side::Left, fill_left, pocket_left),
            (Side::Right, fill_right, pocket_right),
        ];
        let bed_choices = sides_candidates.map(|(side, candidates, pocket_candidates)| {
            let s = side as usize;
            let fill = BedChoice {
                feet: candidates.feet(&beds[s]),
                candidates,
                bed: beds[s].clone(),
                bounds: None,
            };
            let pocket = (pocket_beds[s].as_ref()).zip(pocket_candidates).map(
                |((bed, bounds), candidates)| BedChoice {
                    feet: candidates.feet(bed),
                    candidates,
                    bed: bed.clone(),
                    bounds: Some(*bounds),
                },
            );
            match pocket {
                Some(pocket) => vec![fill, pocket],
                None => vec![fill],
            }
        });
        Ok(Simulation {
            pocket_bounds: bed_choices.each_ref().map(|choices| choices[0].bounds),
            feet: bed_choices
                .each_ref()
                .map(|choices| choices[0].feet.clone()),
            beds: bed_choices.each_ref().map(|choices| choices[0].bed.clone()),
            bed_choices,
            coarse_walls,
            coarse_operator: options.multigrid.coarse_operator,
            coarse_fallbacks: 0,
            neighbour_ptr,
            neighbours,
            frame,
            levels,
            spacing_mm,
            rear_wall_offset_mm: closed.rear_wall_offset_mm,
            cylinder,
            sides,
            wall,
            on_wall,
            on_band,
            on_skin,
            implants: [None, None],
            stage: Stage::Implant,
            multigrid: None,
            multigrid_builds: 0,
            dirty: true,
            u: vec![DVec3::ZERO; n],
            f_ext: Vec::new(),
            u_before_gravity: None,
            gravity: None,
            last_relative_residual: 0.0,
            stage_cycles: 0,
            fresh: true,
            stage_one_search: false,
            warmup_left: 0,
            last_energy: None,
            last_step: 1.0,
            scan_rest,
            scan_map,
            scan_smoother,
            scan_carry: None,
            landmarks: input.landmarks.clone(),
            landmark_feet,
            control_points,
            control_point_feet,
            base: input.breasts.base.mesh.clone(),
            mesh_maps: None,
            finest,
            options,
        })
    }

    /// The options.
    pub fn options(&self) -> &SimulationOptions {
        &self.options
    }

    /// The finest level (rest state).
    pub fn finest_mesh(&self) -> &TetMesh {
        &self.finest
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

    /// The finest vertices held at the posterior wall and the clip faces.
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
        self.stage
    }

    /// The default anchor of one side (bed parameters `(u, v)`, mm).
    pub fn default_anchor_uv(&self, side: Side) -> DVec2 {
        self.sides[side as usize].default_uv
    }

    /// The fold lowering (mm) the pocket of `side` is planned with for an implant of
    /// `shape` by the side's rule (0 without pockets).
    pub fn fold_lowering_mm(&self, side: Side, shape: &ImplantShape) -> f64 {
        self.fold_rule(side, &Placement::default())
            .map_or(0.0, |rule| {
                rule.mm(shape, nipple_to_fold_mm(side, &self.landmarks))
            })
    }

    /// The fold lowering rule for an implant placed with `placement`: its own lowering
    /// if it gives one, else the side's; `None` without pockets.
    fn fold_rule(&self, side: Side, placement: &Placement) -> Option<FoldLowering> {
        let side_rule = self.options.pocket?[side as usize].fold_lowering;
        Some(
            placement
                .fold_lowering_mm
                .map_or(side_rule, FoldLowering::Mm),
        )
    }

    /// Checks an implant's own fold lowering: finite, and from 0 to the depth the side's
    /// pocket was built for.
    fn check_fold_lowering(
        &self,
        side: Side,
        placement: &Placement,
    ) -> Result<(), SimulationError> {
        let Some(mm) = placement.fold_lowering_mm else {
            return Ok(());
        };
        let deepest_mm = self.options.pocket.map_or(0.0, |limits| {
            limits[side as usize].fold_lowering.deepest_mm()
        });
        if mm.is_finite() && (0.0..=deepest_mm).contains(&mm) {
            return Ok(());
        }
        Err(SimulationError::BadPlacement {
            side,
            what: "fold lowering (mm)",
            value: mm,
            expected: format!(
                "from 0 to {deepest_mm:.0} mm, as deep as the side's pocket was built"
            ),
        })
    }

    /// Places (or replaces) the implant of one side and rebuilds its template; the
    /// session drops back to stage 1 and keeps its displacement as the warm start. On
    /// error nothing changes.
    ///
    /// Errors: a move or rotation that is not finite, a bed moved further forward than
    /// [`MAX_FORWARD_SHIFT_MM`] or closer than [`MIN_WALL_CLEARANCE_MM`] to the posterior
    /// wall, an anchor walked off the bed, an implant whose footprint does not fit on
    /// the bed, a template without implant vertices.
    pub fn set_implant(
        &mut self,
        side: Side,
        shape: ImplantShape,
        placement: Placement,
    ) -> Result<&PlacedImplant, SimulationError> {
        let start = Instant::now();
        let s = side as usize;
        let shift = self.options.shift_mm - placement.move_mm.z;
        let max_shift = self.rear_wall_offset_mm - MIN_WALL_CLEARANCE_MM;
        if !(shift.is_finite() && shift >= -MAX_FORWARD_SHIFT_MM && shift <= max_shift) {
            return Err(SimulationError::BadPlacement {
                side,
                what: "move z (mm)",
                value: placement.move_mm.z,
                expected: format!(
                    "the bed lies {:.1} mm behind the fill-in by default; it may move from \
                     {MAX_FORWARD_SHIFT_MM} mm in front of the fill-in to {MIN_WALL_CLEARANCE_MM} mm \
                     before the posterior wall, so z in {:.1}..={:.1}",
                    self.options.shift_mm,
                    self.options.shift_mm - max_shift,
                    self.options.shift_mm + MAX_FORWARD_SHIFT_MM
                ),
            });
        }
        // the fill-in's bed first, then the pocket's (or the other way round where the
        // fold is lowered): the first on which the implant fits
        self.check_fold_lowering(side, &placement)?;
        let fold_lowering_mm = self.fold_rule(side, &placement).map_or(0.0, |rule| {
            rule.mm(&shape, nipple_to_fold_mm(side, &self.landmarks))
        });
        let mut order: Vec<usize> = (0..self.bed_choices[s].len()).collect();
        if fold_lowering_mm > 0.0 {
            order.sort_by_key(|&k| self.bed_choices[s][k].bounds.is_none());
        }
        // a move the user asked for past a pocket's limit ends the search; where no bed
        // takes the implant, a pocket's limit it reached is the clearest error
        let moved = placement.move_mm.truncate() != DVec2::ZERO;
        let mut outcome = Err(SimulationError::BadModel("no bed".into()));
        let mut limit_reached = None;
        let mut chosen = 0;
        for k in order {
            let choice = &self.bed_choices[s][k];
            outcome = self.fit_on(side, choice, shift, &shape, &placement, fold_lowering_mm);
            chosen = k;
            match &outcome {
                Ok(_) => break,
                Err(limit @ SimulationError::PocketLimit { .. }) => {
                    if moved {
                        break;
                    }
                    limit_reached.get_or_insert_with(|| limit.clone());
                }
                Err(_) => {}
            }
        }
        if let (Err(_), Some(limit)) = (&outcome, limit_reached) {
            outcome = Err(limit);
        }
        let (bed, feet, bounds, requested, anchor, fold_lowering_mm) = outcome?;
        let radius = self
            .options
            .rim_smoothing_mm
            .unwrap_or(RIM_SMOOTHING_SPACINGS * self.spacing_mm);
        let layer_mm = self
            .options
            .template_layer_mm
            .unwrap_or(TEMPLATE_LAYER_SPACINGS * self.spacing_mm);
        let thickness = SmoothedThickness::new(shape, radius);
        let template = build_template(
            &self.finest,
            &self.bed_choices[s][chosen].candidates,
            &feet,
            &anchor,
            &thickness,
            &TemplateRules {
                hold_bed: self.options.hold_bed,
                layer_mm,
                on_wall: &self.on_wall,
            },
        )?;
        let fold_vertices = self.fold_line(side, fold_lowering_mm, &template);
        self.beds[s] = bed;
        self.feet[s] = feet;
        self.pocket_bounds[s] = bounds;
        self.implants[s] = Some(PlacedImplant {
            shape,
            placement,
            anchor,
            fit_shift_mm: requested.local(anchor.uv),
            fold_lowering_mm,
            template,
            fold_vertices,
            setup_ms: elapsed_ms(start),
        });
        self.constraints_changed();
        Ok(self.implants[s].as_ref().expect("just set"))
    }

    /// The skin vertices along the planned fold of `side` ([`PlacedImplant::fold_vertices`]):
    /// on the skin, up to one finest spacing below the planned fold's height (standing
    /// frame), across the width of the template's vertices below the implant's middle,
    /// and neither template vertices nor their neighbours (a held vertex next to one
    /// pushed by the implant folds the element between them over).
    fn fold_line(&self, side: Side, fold_lowering_mm: f64, template: &ImplantTemplate) -> Vec<u32> {
        let local = |v: u32| self.frame.to_local(self.finest.positions[v as usize]);
        let fold_y_mm = native_fold_y_mm(side, &self.frame, &self.landmarks) - fold_lowering_mm;
        let pushed: Vec<DVec3> = template
            .implant_vertices
            .iter()
            .map(|&(v, _)| local(v))
            .collect();
        let Some(middle_y_mm) = pushed
            .iter()
            .map(|p| p.y)
            .reduce(f64::max)
            .zip(pushed.iter().map(|p| p.y).reduce(f64::min))
            .map(|(top, bottom)| 0.5 * (top + bottom))
        else {
            return Vec::new();
        };
        let (x_lo, x_hi) = pushed
            .iter()
            .filter(|p| p.y < middle_y_mm)
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p.x), hi.max(p.x))
            });
        let in_template: std::collections::HashSet<u32> =
            template.implant_vertices.iter().map(|&(v, _)| v).collect();
        let pushed_near = |v: u32| {
            let v = v as usize;
            in_template.contains(&(v as u32))
                || self.neighbours[self.neighbour_ptr[v]..self.neighbour_ptr[v + 1]]
                    .iter()
                    .any(|w| in_template.contains(w))
        };
        (0..self.finest.positions.len() as u32)
            .filter(|&v| self.on_skin[v as usize] && !pushed_near(v))
            .filter(|&v| {
                let p = local(v);
                p.y <= fold_y_mm && p.y > fold_y_mm - self.spacing_mm && p.x >= x_lo && p.x <= x_hi
            })
            .collect()
    }

    /// Starts stage 1 afresh from the displacement `u` (mm, one per finest vertex, as
    /// [`Simulation::displacement`] gives it), as after a change of the implants: a saved
    /// state restored, or two solves compared from one start. On error nothing changes.
    pub fn restart_from(&mut self, u: &[DVec3]) -> Result<(), SimulationError> {
        if u.len() != self.u.len() || !u.iter().all(|d| d.is_finite()) {
            return Err(SimulationError::BadModel(format!(
                "a restart needs {} finite displacements, got {}",
                self.u.len(),
                u.len()
            )));
        }
        self.u.copy_from_slice(u);
        self.constraints_changed();
        Ok(())
    }

    /// Removes the implant of one side (back to stage 1).
    pub fn remove_implant(&mut self, side: Side) {
        if self.implants[side as usize].take().is_some() {
            self.constraints_changed();
        }
    }

    fn constraints_changed(&mut self) {
        self.stage = Stage::Implant;
        self.f_ext.clear();
        self.u_before_gravity = None;
        self.gravity = None;
        self.stage_cycles = 0;
        self.dirty = true;
        self.fresh = true;
        self.stage_one_search = false;
        self.warmup_left = 0;
    }

    /// The constraints of stage 1 (or of stage 2 without the implant vertices).
    ///
    /// Besides the wall and the templates, a free vertex all of whose neighbours are held
    /// at zero is held at zero too (repeatedly): in stage 1 its equilibrium displacement
    /// is zero anyway (no load acts on it), and such islands, found between the fixed
    /// back vertices and the posterior wall, leave coarse multigrid functions that only
    /// see one free fine vertex, which made the Galerkin coarse operator singular.
    fn constraints(&self, with_implant_vertices: bool) -> Constraints {
        let n = self.finest.positions.len();
        let mut zero = vec![false; n];
        let mut held = vec![false; n];
        for &v in &self.wall {
            zero[v as usize] = true;
        }
        for implant in self.implants.iter().flatten() {
            for &v in implant
                .template
                .fixed_vertices
                .iter()
                .chain(&implant.fold_vertices)
            {
                zero[v as usize] = true;
            }
        }
        if with_implant_vertices {
            for implant in self.implants.iter().flatten() {
                for &(v, _) in &implant.template.implant_vertices {
                    held[v as usize] = true;
                    zero[v as usize] = false;
                }
            }
        }
        let mut islands = Vec::new();
        loop {
            let before = islands.len();
            for v in 0..n {
                if zero[v] || held[v] {
                    continue;
                }
                let nb = &self.neighbours[self.neighbour_ptr[v]..self.neighbour_ptr[v + 1]];
                if !nb.is_empty() && nb.iter().all(|&w| zero[w as usize]) {
                    zero[v] = true;
                    islands.push(v as u32);
                }
            }
            if islands.len() == before {
                break;
            }
        }
        let mut c = Constraints::new();
        for &v in &self.wall {
            c.fix(v);
        }
        for &v in &islands {
            c.fix(v);
        }
        for implant in self.implants.iter().flatten() {
            for &v in implant
                .template
                .fixed_vertices
                .iter()
                .chain(&implant.fold_vertices)
            {
                c.fix(v);
            }
            for &(v, d) in &implant.template.implant_vertices {
                if with_implant_vertices {
                    c.prescribe(v, d);
                } else if self.on_band[v as usize] {
                    // where the model is cut through the body, the holding force includes
                    // the unmodelled tissue's: released, the vertex would hang on the soft
                    // implant elements alone, so it keeps its stage-1 place
                    c.fix(v);
                }
            }
        }
        c
    }

    /// The finest model with the implant elements' soft material.
    fn finest_model(&self) -> Result<FemModel, SimulationError> {
        let mut model = self.levels[0].clone();
        let t = self.options.tissue;
        let soft = Material {
            young_kpa: t.young_kpa * self.options.implant_young_ratio,
            poisson_ratio: self.options.implant_poisson_ratio,
            density_kg_m3: self.options.implant_density_kg_m3,
        };
        for implant in self.implants.iter().flatten() {
            for &e in &implant.template.implant_elements {
                model.set_material(e as usize, soft)?;
            }
        }
        Ok(model)
    }

    /// A multigrid over the hierarchy with the posterior wall as its permanent
    /// constraints and `finest` set as the changeable ones.
    fn build_multigrid(
        &self,
        finest: Constraints,
        tangent: Tangent,
    ) -> Result<Multigrid, SimulationError> {
        let mut levels = Vec::with_capacity(self.levels.len());
        let mut wall = Constraints::new();
        for &v in &self.wall {
            wall.fix(v);
        }
        levels.push((self.finest_model()?, wall));
        let galerkin = self.coarse_operator == CoarseOperator::Galerkin;
        for (m, wall) in self.levels[1..].iter().zip(&self.coarse_walls) {
            let mut c = Constraints::new();
            if !galerkin {
                for &v in wall {
                    c.fix(v);
                }
            }
            levels.push((m.clone(), c));
        }
        let options = MultigridOptions {
            coarse_operator: self.coarse_operator,
            tangent,
            ..self.options.multigrid
        };
        let mut mg = Multigrid::with_permanent_constraints(levels, options)?;
        mg.set_constraints(&finest)?;
        Ok(mg)
    }

    /// Gives a stage's finest model the current implants' soft elements (and the
    /// tissue back to the elements of earlier implants).
    fn update_implant_materials(&self, stage: &mut StageMultigrid) -> Result<(), SimulationError> {
        let t = self.options.tissue;
        let soft = Material {
            young_kpa: t.young_kpa * self.options.implant_young_ratio,
            poisson_ratio: self.options.implant_poisson_ratio,
            density_kg_m3: self.options.implant_density_kg_m3,
        };
        let current: Vec<u32> = self
            .implants
            .iter()
            .flatten()
            .flat_map(|i| i.template.implant_elements.iter().copied())
            .collect();
        for &e in &stage.soft_elements {
            let own = self.levels[0].materials()[e as usize];
            stage.multigrid.set_material(e as usize, own)?;
        }
        for &e in &current {
            stage.multigrid.set_material(e as usize, soft)?;
        }
        stage.soft_elements = current;
        Ok(())
    }

    /// How many multigrid hierarchies the session has built: one at its first cycle (or
    /// at the first start of the gravity correction, if that comes first), and again
    /// after a switch of coarse operator ([`Simulation::coarse_fallbacks`]).
    pub fn multigrid_builds(&self) -> usize {
        self.multigrid_builds
    }

    /// How often a Galerkin coarse operator turned out singular and the session switched
    /// to rediscretised coarse operators (at most once per session), and the operator in
    /// use.
    pub fn coarse_fallbacks(&self) -> (usize, CoarseOperator) {
        (self.coarse_fallbacks, self.coarse_operator)
    }

    /// Brings the stage-1 multigrid up to date with the current constraints. Returns
    /// whether it had to be built.
    fn ensure_multigrid(&mut self) -> Result<bool, SimulationError> {
        if !self.dirty
            && self
                .multigrid
                .as_ref()
                .is_some_and(|m| m.stage == Stage::Implant)
        {
            return Ok(false);
        }
        let built = self.prepare_multigrid(Stage::Implant)?;
        self.dirty = false;
        Ok(built)
    }

    /// Gives the session's hierarchy the constraints, tangent and implant materials of
    /// `stage`, building it if there is none yet; returns whether it was built. A new
    /// implant or position changes the constrained set: the kept hierarchy keeps its
    /// patterns and only swaps the changeable constraints (fem's symmetric elimination
    /// over a fixed pattern) and the tangent it assembles.
    fn prepare_multigrid(&mut self, stage: Stage) -> Result<bool, SimulationError> {
        let (constraints, tangent) = match stage {
            Stage::Implant => (self.constraints(true), self.options.multigrid.tangent),
            Stage::Gravity => (self.constraints(false), self.options.gravity_tangent),
        };
        let (mut kept, built) = match self.multigrid.take() {
            Some(mut kept) => {
                kept.multigrid.set_constraints(&constraints)?;
                kept.multigrid.set_tangent(tangent);
                kept.stage = stage;
                (kept, false)
            }
            None => {
                let kept = StageMultigrid {
                    multigrid: self.build_multigrid(constraints, tangent)?,
                    soft_elements: Vec::new(),
                    stage,
                };
                self.multigrid_builds += 1;
                (kept, true)
            }
        };
        self.update_implant_materials(&mut kept)?;
        self.multigrid = Some(kept);
        Ok(built)
    }

    /// The session's multigrid, once built.
    fn stage_multigrid(&self) -> Option<&Multigrid> {
        self.multigrid.as_ref().map(|stage| &stage.multigrid)
    }

    /// The load scale of the relative residual: the reaction forces at the held
    /// vertices (from the latest assembly) plus the external loads (mN).
    fn load_scale(&self) -> f64 {
        let mg = self.stage_multigrid().expect("assembled");
        let reaction = mg.system().reaction_norm_squared();
        let external: f64 = self.f_ext.iter().map(|x| x.length_squared()).sum();
        (reaction + external).sqrt().max(1e-12)
    }

    /// One interactive step: rotation update, reassembly and one V(2,1)-cycle of the
    /// current stage, warm-started from the current displacement (giving stage 1's
    /// multigrid the new constraints first if they changed, building it at the session's
    /// first cycle).
    pub fn cycle(&mut self) -> Result<CycleInfo, SimulationError> {
        if self.stage == Stage::Implant && self.fresh && self.u.iter().all(|d| *d == DVec3::ZERO) {
            self.warmup_left = self.options.linear_warmup_cycles;
        }
        if self.warmup_left > 0 {
            self.warmup_left -= 1;
            let info = self.cycle_with(Formulation::Linear)?;
            if info.relative_residual < WARMUP_TOLERANCE {
                self.warmup_left = 0;
            }
            // the first corotated cycle starts afresh (no line search, energy unknown)
            self.fresh = self.warmup_left == 0 || self.fresh;
            return Ok(info);
        }
        self.cycle_with(Formulation::Corotated)
    }

    /// [`Simulation::cycle`] with a chosen formulation (the linear one as a warm-up).
    pub fn cycle_with(&mut self, formulation: Formulation) -> Result<CycleInfo, SimulationError> {
        let u_before = self.u.clone();
        match self.cycle_once(formulation) {
            Err(SimulationError::Fem(fem::FemError::Singular { .. }))
                if self.coarse_operator == CoarseOperator::Galerkin && self.levels.len() > 1 =>
            {
                // a singular Galerkin coarse operator: rediscretised levels from now on
                self.coarse_operator = CoarseOperator::Rediscretised;
                self.coarse_fallbacks += 1;
                self.u = u_before;
                self.rebuild_current_stage()?;
                self.cycle_once(formulation)
            }
            other => other,
        }
    }

    /// Rebuilds the multigrid for the current stage after a change of coarse operator.
    fn rebuild_current_stage(&mut self) -> Result<(), SimulationError> {
        self.multigrid = None;
        match self.stage {
            Stage::Implant => self.dirty = true,
            Stage::Gravity => {
                self.prepare_multigrid(Stage::Gravity)?;
                self.gravity = None;
            }
        }
        Ok(())
    }

    fn cycle_once(&mut self, formulation: Formulation) -> Result<CycleInfo, SimulationError> {
        let start = Instant::now();
        if self.stage == Stage::Gravity {
            return self.gravity_cycle(start);
        }
        let rebuilt = self.ensure_multigrid()?;
        let fresh = std::mem::take(&mut self.fresh) || rebuilt;
        let search = self.options.line_search
            && self.stage_one_search
            && !fresh
            && formulation == Formulation::Corotated;
        let u_old = search.then(|| self.u.clone());
        let mg = &mut self.multigrid.as_mut().expect("ensured").multigrid;
        let report = mg.cycle(&mut self.u, &self.f_ext, formulation)?;
        if let Some(u_old) = u_old {
            // backtracking on the potential energy (the corotated forces are conservative)
            let model = mg.model();
            let energy = |u: &[DVec3]| model.potential_energy(u, &self.f_ext, formulation);
            let e0 = match self.last_energy {
                Some(e) => e,
                None => energy(&u_old),
            };
            let step: Vec<DVec3> = self.u.iter().zip(&u_old).map(|(a, b)| *a - *b).collect();
            let mut alpha = 1.0;
            let mut e = energy(&self.u);
            let mut halvings = 0;
            while (e > e0 || e.is_nan()) && halvings < MAX_HALVINGS {
                alpha *= 0.5;
                halvings += 1;
                for ((u, o), d) in self.u.iter_mut().zip(&u_old).zip(&step) {
                    *u = *o + *d * alpha;
                }
                e = energy(&self.u);
            }
            self.last_energy = Some(e);
            self.last_step = alpha;
        } else {
            self.last_energy = None;
            self.last_step = 1.0;
        }

        let relative = report.residual_before / self.load_scale();
        if self.stage == Stage::Implant
            && !fresh
            && formulation == Formulation::Corotated
            && relative > self.last_relative_residual
        {
            self.stage_one_search = true;
        }
        self.last_relative_residual = relative;
        self.stage_cycles += 1;
        Ok(CycleInfo {
            stage: self.stage,
            residual_mn: report.residual_before,
            relative_residual: relative,
            rebuilt,
            step: self.last_step,
            linear: formulation == Formulation::Linear,
            time_ms: elapsed_ms(start),
        })
    }

    /// One cycle of stage 2: one iteration of conjugate gradients preconditioned by a
    /// symmetric V-cycle on the tangent system of the stage-1 state (assembled at the stage's first
    /// cycle); the displacement is stage 1's plus the correction so far.
    fn gravity_cycle(&mut self, start: Instant) -> Result<CycleInfo, SimulationError> {
        let u1 = self
            .u_before_gravity
            .as_deref()
            .expect("stage 2 starts from stage 1's displacement");
        let mg = &mut self
            .multigrid
            .as_mut()
            .expect("prepared when the stage started")
            .multigrid;
        if self.gravity.is_none() {
            mg.assemble(u1, &self.f_ext, Formulation::Corotated)?;
            let rhs = mg.system().rhs.clone();
            let rhs_norm = rhs.iter().map(|d| d.length_squared()).sum::<f64>().sqrt();
            let zero = vec![DVec3::ZERO; rhs.len()];
            self.gravity = Some((PcgIteration::new(mg, &rhs, zero), rhs_norm));
        }
        let (cg, rhs_norm) = self.gravity.as_mut().expect("assembled above");
        let rhs_norm = *rhs_norm;
        let residual = cg.residual_norm();
        cg.step(mg);
        self.u.copy_from_slice(u1);
        let sys = mg.system();
        for ((&v, d), &held) in sys.free.iter().zip(cg.solution()).zip(sys.eliminated()) {
            if !held {
                self.u[v as usize] += *d;
            }
        }
        self.last_energy = None;
        self.last_step = 1.0;
        self.fresh = false;
        // relative to the stage's own load: against stage 1's reaction forces (the
        // wall's, the fold's) the added weight's residual started below the tolerance
        // and the correction stopped after one conjugate gradient step
        let relative = residual / rhs_norm.max(f64::MIN_POSITIVE);
        self.last_relative_residual = relative;
        self.stage_cycles += 1;
        Ok(CycleInfo {
            stage: self.stage,
            residual_mn: residual,
            relative_residual: relative,
            rebuilt: false,
            step: 1.0,
            linear: false,
            time_ms: elapsed_ms(start),
        })
    }

    /// Cycles the current stage until the relative residual before a cycle is below
    /// `relative_tolerance` (that cycle is still run) or `max_cycles` were run.
    pub fn solve(
        &mut self,
        max_cycles: usize,
        relative_tolerance: f64,
    ) -> Result<SolveReport, SimulationError> {
        let start = Instant::now();
        let mut cycles = 0;
        let mut relative = f64::INFINITY;
        while cycles < max_cycles {
            let info = self.cycle()?;
            cycles += 1;
            relative = info.relative_residual;
            if relative < relative_tolerance && !info.linear {
                break;
            }
        }
        Ok(SolveReport {
            stage: self.stage,
            cycles,
            relative_residual: relative,
            converged: relative < relative_tolerance,
            time_ms: elapsed_ms(start),
        })
    }

    /// Switches to stage 2 (paper V-B) from the current (stage-1) displacement: the
    /// implant vertices' holding forces and the added implant weight become loads, the
    /// implant vertices are released. Does nothing without implants or when already
    /// there. The session's multigrid only swaps its constraints and tangent (see the
    /// module documentation). Run
    /// [`Simulation::cycle`] or [`Simulation::solve`] afterwards.
    pub fn start_gravity_correction(&mut self) -> Result<(), SimulationError> {
        if self.stage == Stage::Gravity || self.implants.iter().all(Option::is_none) {
            return Ok(());
        }
        self.ensure_multigrid()?;
        let model = self.multigrid.as_ref().expect("ensured").multigrid.model();
        let f_int = model.internal_forces(&self.u, Formulation::Corotated)?;
        let mut f_ext = vec![DVec3::ZERO; self.u.len()];
        let g = -self.frame.up()
            * (self.options.gravity_m_s2
                * self.options.implant_density_kg_m3
                * fem::model::KG_M3_TIMES_M_S2_TO_MN_MM3);
        let wall: std::collections::HashSet<u32> = self.wall.iter().copied().collect();
        for implant in self.implants.iter().flatten() {
            for &(v, _) in &implant.template.implant_vertices {
                if !wall.contains(&v) {
                    f_ext[v as usize] = f_int[v as usize];
                }
            }
        }
        for implant in self.implants.iter().flatten() {
            for &e in &implant.template.implant_elements {
                let t = self.finest.tets[e as usize];
                let p = t.map(|v| self.finest.positions[v as usize]);
                let q = [0, 1, 2, 3].map(|k| p[k] + self.u[t[k] as usize]);
                let added = tetra::quality::signed_volume(q) - tetra::quality::signed_volume(p);
                for &v in &t {
                    f_ext[v as usize] += g * (added * 0.25);
                }
            }
        }
        self.prepare_multigrid(Stage::Gravity)?;
        self.u_before_gravity = Some(self.u.clone());
        self.gravity = None;
        self.f_ext = f_ext;
        self.stage = Stage::Gravity;
        self.stage_cycles = 0;
        self.fresh = true;
        Ok(())
    }

    /// Solves stage 1 to convergence and, unless `no_gravity`, the gravity correction,
    /// with the options' cycle limit and tolerance.
    pub fn run(&mut self, no_gravity: bool) -> Result<RunReport, SimulationError> {
        if self.stage == Stage::Gravity {
            // start from the Dirichlet problem again
            self.constraints_changed();
        }
        let (max, tol) = (self.options.max_cycles, self.options.relative_tolerance);
        let implant = self.solve(max, tol)?;
        let gravity = if no_gravity || self.implants.iter().all(Option::is_none) {
            None
        } else {
            self.start_gravity_correction()?;
            Some(self.solve(max, tol)?)
        };
        Ok(RunReport { implant, gravity })
    }

    /// The finest level's displacement (mm, one per vertex).
    pub fn displacement(&self) -> &[DVec3] {
        &self.u
    }

    /// The finest displacement at the end of stage 1, once the gravity correction began.
    pub fn displacement_before_gravity(&self) -> Option<&[DVec3]> {
        self.u_before_gravity.as_deref()
    }

    /// Cycles run in the current stage, and the relative residual before the last one.
    pub fn stage_progress(&self) -> (usize, f64) {
        (self.stage_cycles, self.last_relative_residual)
    }

    /// The current external loads of stage 2 (mN; empty in stage 1).
    pub fn external_forces(&self) -> &[DVec3] {
        &self.f_ext
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
        self.multigrid.as_mut().map(|stage| &mut stage.multigrid)
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

    /// The implant placed on `choice`'s bed shifted `shift` mm back: the bed and feet
    /// used, the pocket's bounds, the requested and the fitted anchor.
    ///
    /// Errors: as [`Simulation::set_implant`]; a move the user asked for that takes the
    /// implant past an anatomical limit of the pocket is [`SimulationError::PocketLimit`]
    /// (not undone by the fit).
    fn fit_on(
        &self,
        side: Side,
        choice: &BedChoice,
        shift: f64,
        shape: &ImplantShape,
        placement: &Placement,
        fold_lowering_mm: f64,
    ) -> Result<FittedOn, SimulationError> {
        let (bed, feet) = if choice.bed.shift_mm == shift {
            (choice.bed.clone(), choice.feet.clone())
        } else {
            let bed = choice.bed.shifted(shift)?;
            let feet = choice.candidates.feet(&bed);
            (bed, feet)
        };
        // the pocket as planned for this implant (it was built for the deepest fold)
        let bounds = choice.bounds.and_then(|_| {
            let limits = self.options.pocket?[side as usize];
            Some(PocketBounds::new(
                side,
                &self.frame,
                &self.landmarks,
                &limits,
                fold_lowering_mm,
            ))
        });
        let limit_error = |error| pocket_limit_error(side, bounds.as_ref(), error);
        let default_uv = self.default_uv_on(side, &bed, shape, bounds.as_ref())?;
        let requested = resolve_anchor(&bed, &self.frame, default_uv, placement)?;
        // a move that takes the implant further past a limit than its default position
        // lies (the fit would undo it) is refused, naming the limit
        let beyond_limit_mm =
            |anchor: &Anchor| match check_footprint(&bed, anchor, shape, &self.frame)
                .map_err(limit_error)
            {
                Err(limit @ SimulationError::PocketLimit { beyond_mm, .. }) => {
                    Some((beyond_mm, limit))
                }
                _ => None,
            };
        let moved = placement.move_mm.truncate() != glam::DVec2::ZERO;
        if moved && let Some((beyond_mm, limit)) = beyond_limit_mm(&requested) {
            let unmoved = Placement {
                move_mm: DVec3::new(0.0, 0.0, placement.move_mm.z),
                ..*placement
            };
            let default_beyond_mm = resolve_anchor(&bed, &self.frame, default_uv, &unmoved)
                .ok()
                .and_then(|anchor| beyond_limit_mm(&anchor))
                .map_or(0.0, |(mm, _)| mm);
            if beyond_mm > default_beyond_mm + MOVE_PAST_LIMIT_TOLERANCE_MM {
                return Err(limit);
            }
        }
        let anchor = if self.options.fit_footprint {
            fit_footprint(&bed, &self.frame, requested, placement.rotation_deg, shape)
        } else {
            check_footprint(&bed, &requested, shape, &self.frame).map(|()| requested)
        }
        .map_err(limit_error)?;
        // a lowering planned for the implant follows it where the fit moved it (the new
        // fold lies at its lower edge); a given one holds
        let below_mm = bounds.map_or(0.0, |b| {
            b.floor_y_mm - lowest_footprint_y_mm(&bed, &anchor, shape, &self.frame)
        });
        let fold_lowering_mm = match self.fold_rule(side, placement) {
            Some(FoldLowering::ForImplant) if bounds.is_some() => {
                (fold_lowering_mm + below_mm).max(0.0)
            }
            Some(FoldLowering::Mm(_)) if below_mm > FLOOR_TOLERANCE_MM => {
                return Err(SimulationError::PocketLimit {
                    side,
                    limit: "the planned fold",
                    beyond_mm: below_mm,
                });
            }
            _ if bounds.is_some() => fold_lowering_mm,
            _ => 0.0,
        };
        Ok((bed, feet, bounds, requested, anchor, fold_lowering_mm))
    }

    /// The default anchor of `side` for an implant of `shape` on `bed` (bed parameters):
    /// the rule's, on a pocket with a lowered fold taken down with it (see
    /// [`AnchorRule`]).
    fn default_uv_on(
        &self,
        side: Side,
        bed: &ImplantBed,
        shape: &ImplantShape,
        bounds: Option<&PocketBounds>,
    ) -> Result<DVec2, SimulationError> {
        let start = self.sides[side as usize].default_uv;
        let floor_y_mm = bounds.map_or_else(
            || native_fold_y_mm(side, &self.frame, &self.landmarks),
            |b| b.floor_y_mm,
        );
        let lowering_mm = native_fold_y_mm(side, &self.frame, &self.landmarks) - floor_y_mm;
        match self.options.anchor_rule {
            AnchorRule::OnFold => {
                let half_height_mm = shape.footprint().height_mm() / 2.0;
                // straight down from behind the nipple (on the chest's radius through it)
                let behind = resolve_anchor(bed, &self.frame, start, &Placement::default())?;
                let across_mm = self.frame.to_local(behind.position).x;
                anchor_on_floor(
                    bed,
                    &self.frame,
                    start,
                    across_mm,
                    half_height_mm,
                    floor_y_mm,
                )
            }
            _ if lowering_mm > 0.0 => {
                let down = Placement::moved(0.0, -lowering_mm, 0.0);
                Ok(resolve_anchor(bed, &self.frame, start, &down)?.uv)
            }
            _ => Ok(start),
        }
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
