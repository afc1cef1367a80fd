//! The session's settings and their defaults, and the check of their ranges.

use super::*;

/// A finest vertex belongs to the posterior wall or band when its closest point on the
/// closed surface lies on such a triangle within this many finest spacings.
pub const WALL_TOLERANCE_FACTOR: f64 = 0.25;

/// Half-width of the strip over the sternum held with
/// [`SimulationOptions::hold_sternum`] (mm): the sternal body is 2-3 cm wide, and the
/// pocket keeps 15 mm from the midline ([`crate::pocket::DEFAULT_MIDLINE_CLEARANCE_MM`]).
pub const STERNUM_HALF_WIDTH_MM: f64 = 10.0;

// the strip held over the sternum must lie inside every pocket's midline clearance
const _: () = assert!(STERNUM_HALF_WIDTH_MM < crate::pocket::DEFAULT_MIDLINE_CLEARANCE_MM);
// the option check's message ([`SimulationOptions::check`]) says "10 mm" in a static text
const _: () = assert!(STERNUM_HALF_WIDTH_MM == 10.0);

/// Default Young's modulus of implant elements as a fraction of the tissue's: "very soft"
/// (paper V-A). Only stage 2 sees it (in stage 1 every implant element has all its corners
/// prescribed).
pub const DEFAULT_IMPLANT_YOUNG_RATIO: f64 = 0.01;

/// Default Poisson ratio of implant elements. The paper asks only for a very soft
/// modulus; an implant's gel or saline fill is nearly incompressible (finite-element
/// studies of implants take 0.45-0.49), so the implant keeps its volume while it sags.
/// At 0.3 the gravity stage's linear answer squeezed elements along the implant's edge
/// until they turned over on two landmark-jittered bodies (docs/dev/model-on-every-body.md,
/// session 52).
pub const DEFAULT_IMPLANT_POISSON_RATIO: f64 = 0.49;

/// Default inversion barrier of the finest level: elements squeezed below half their
/// volume resist with a modulus of 100 kPa (about forty times the tissue's Young's
/// modulus), the soft implant elements too, and any stiffer element with forty times its
/// own modulus (docs/dev/skin.md): the least that left no element inverted on the shared
/// scans (docs/dev/session-choices.md).
pub const DEFAULT_INVERSION_BARRIER: InversionBarrier = InversionBarrier {
    min_volume_ratio: 0.5,
    modulus_kpa: 100.0,
    young_multiple: 40.0,
};

/// Stiffness of the sliders that keep the skin over a thin pocket at the template's
/// distance from the implant, as a multiple of the tissue's Young's modulus times the
/// finest spacing (mN/mm; 100 x 2.4 kPa x 6.4 mm = 1,540 mN/mm at the default mesh):
/// stiff against the skin's press on a vertex, soft enough for the multigrid (figures:
/// docs/dev/model-on-every-body.md, session 40).
pub const SKIN_SLIDER_STIFFNESS_MULTIPLE: f64 = 100.0;

/// Default compression penalty of the finest level: every element that loses volume
/// resists with twice its own first Lamé parameter, `2 λ V (1 - J)²`. To first order
/// that is the resistance to compression of tissue with a Poisson ratio of 0.489 (five
/// times the paper's `λ` at 0.45) while shear stays the paper's; breast tissue is nearly
/// incompressible (0.49-0.5 in breast models). Without it the tissue squeezed between
/// implant and skin lost 6-8% of the implant's volume; one `λ` was enough while the skin
/// stiffened the outer elements in every direction, not once it became a membrane
/// (docs/dev/volume-loss.md, docs/dev/discretisation.md).
pub const DEFAULT_COMPRESSION_PENALTY: CompressionPenalty = CompressionPenalty {
    onset_volume_ratio: 1.0,
    lambda_multiple: 2.0,
};

/// Default radius of the implant rim's mollifier. Linear tetrahedra cannot follow a rim
/// that rises by 10 mm within 3 mm (the square-root edge of eqs. 3 and 10); two
/// spacings inverted the fewest elements over the rim, and 14 mm (two spacings of the
/// default mesh on the largest of our bodies) is about a real round implant's rounded
/// edge (docs/dev/session-choices.md).
pub const DEFAULT_RIM_SMOOTHING: ResolvedLength = ResolvedLength {
    mm: 14.0,
    min_spacings: 2.0,
};

/// Least height over the planned fold from which the implant's full thickness is laid
/// off ([`crate::template::FoldPlane`], which widens it to
/// [`crate::template::TAPER_PER_THICKNESS`] times a greater thickness). The smooth
/// step's steepest slope is 1.5 over its width, so 1.5 spacings make it no steeper than
/// a linear ramp over one element; 10.5 mm is 1.5 spacings of the default mesh on the
/// largest of our bodies. Steeper steps left the skin under the held fold converging
/// slowly or turned elements over, a wider one left the simulated fold 2 mm above the
/// plan (docs/dev/standing-frame.md).
pub const FOLD_TAPER: ResolvedLength = ResolvedLength {
    mm: 10.5,
    min_spacings: 1.5,
};

/// Default thickness of the tissue layer that moves with the implant. The paper's
/// template displaces only the front vertices of the elements crossing the bed, a
/// ragged set: free vertices at the same height between displaced ones lagged and
/// folded their elements over, so the layer is at least one spacing; 7 mm is one
/// spacing of the default mesh on the largest of our bodies
/// (docs/dev/session-choices.md).
pub const DEFAULT_TEMPLATE_LAYER: ResolvedLength = ResolvedLength {
    mm: 7.0,
    min_spacings: 1.0,
};

/// Default radius of the smoothing of the displacement over the scan
/// ([`SimulationOptions::scan_smoothing_mm`]), which takes out the elements' facets:
/// half of 7 mm, one spacing of the default mesh on the largest of our bodies; fixed in
/// mm so that a finer mesh is smoothed alike (docs/dev/discretisation.md).
pub const DEFAULT_SCAN_SMOOTHING: ResolvedLength = ResolvedLength {
    mm: 3.5,
    min_spacings: 0.5,
};

/// Radius of the blend beyond the finest mesh: past about this distance, a point
/// outside takes a weighted average of the boundary's displacements rather than its
/// closest point's ([`crate::field`]); 7 mm, one spacing of the default mesh on the
/// largest of our bodies, fixed in mm for the same reason.
pub const OUTSIDE_BLEND_RADIUS: ResolvedLength = ResolvedLength {
    mm: 7.0,
    min_spacings: 1.0,
};

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

/// Stage 1 counts as stalled when its relative residual fell, per corotated cycle and
/// on average over the last [`STALL_WINDOW`] of them (the first cycle after a change
/// not counted), by a factor worse than [`STALL_CONTRACTION`] (see
/// [`SimulationOptions::newton_krylov_iterations`]).
pub const STALL_WINDOW: usize = 2;

/// The ratio of the residual after a warped cycle to the one before, above which a
/// Newton-Krylov step (dearer per cycle, faster per millisecond there) takes over if it
/// pays ([`NEWTON_KRYLOV_COST`]; docs/dev/converged.md).
pub const STALL_CONTRACTION: f64 = 0.5;

/// What a Newton-Krylov step costs, in warped cycles, with the default two conjugate
/// gradient iterations (its full-tangent assembly and two symmetric V-cycles): measured
/// at 1.5-2.8 times a warped cycle in session 27 and 1.6-2.1 in session 43
/// (docs/dev/converged.md).
pub const NEWTON_KRYLOV_COST: f64 = 2.0;

/// The residual's ratio after a Newton-Krylov step to the one before: reductions of 4.6-7
/// fold measured where stage 1 stalls (session 27, docs/dev/converged.md), rounded to 5.
pub const NEWTON_KRYLOV_CONTRACTION: f64 = 0.2;

/// The relative residual below which stage 1's warped cycles keep their operators
/// ([`SimulationOptions::lagged_operators`]): past the first cycles after a change, where
/// the rotations still move by much (lagged from 0.2, the cycles stalled into
/// Newton-Krylov steps; docs/dev/converged.md).
pub const LAGGED_OPERATORS_BELOW: f64 = 0.05;

/// What a cycle on kept operators costs, in warped cycles: its element pass and V-cycle
/// without the assemblies (9-10 ms against 19-21 ms at 60,000 elements, session 44,
/// docs/dev/converged.md).
pub const LAGGED_CYCLE_COST: f64 = 0.5;

/// How many earlier steps the lagged cycles mix ([`crate::session`]'s Anderson mixing):
/// 2 took one lagged cycle off the bench's change, 3 no more (docs/dev/converged.md).
pub const ANDERSON_DEPTH: usize = 2;

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
    /// invert and the corotated iteration stall (docs/dev/session-choices.md).
    pub hold_bed: bool,
    /// Let the skin the template would push where the tissue over the bed is thinner
    /// than its layer (the pocket beyond the native breast, a lowered fold) slide over
    /// the implant on [`fem::Slider`]s, at the template's distance, instead of holding
    /// it. Held skin next to free skin can shear the surface elements between them
    /// over; sliding, far fewer do, but stage 1 converges more slowly. Off by default
    /// (docs/dev/model-on-every-body.md, session 40).
    pub skin_slides: bool,
    /// Hold the tissue over the sternum ([`STERNUM_HALF_WIDTH_MM`] either side of the
    /// standing frame's midline, the one the pockets' clearance is measured from,
    /// between the heights of Pj and Px) to the bone at every stage. The presternal skin is
    /// bound to the sternum; it lifts off only where the pockets join over it
    /// (symmastia), which the pocket's midline clearance rules out. Left free, the
    /// 15 mm slab in front of the rear wall let the breasts drag the skin at Px 2-3 mm
    /// forwards on most bodies (docs/dev/session-choices.md).
    pub hold_sternum: bool,
    /// Radius of the kernel that mollifies the implant's thickness in the template
    /// (mm); `None`: [`DEFAULT_RIM_SMOOTHING`]. `Some(0.0)`: no smoothing.
    pub rim_smoothing_mm: Option<f64>,
    /// Thickness of the tissue layer over the footprint that moves with the implant
    /// (mm), besides the front vertices of the elements crossing the bed (the paper's
    /// template); `None`: [`DEFAULT_TEMPLATE_LAYER`].
    pub template_layer_mm: Option<f64>,
    /// Breast tissue.
    pub tissue: Material,
    /// The pectoralis major's elements ([`crate::muscle`]); `None`: breast tissue there
    /// too (the paper's homogeneous model).
    pub muscle: Option<Material>,
    /// The skin over it ([`crate::skin`]); `None`: tissue up to the surface (the
    /// paper's homogeneous model).
    pub skin: Option<SkinLayer>,
    /// Once stage 1 has converged with the template's prescribed implant, release the
    /// implant's front and let it be a deformable gel of this material, stress-free in
    /// the template's shape: where the tissue over it resists more (a muscle), it yields,
    /// and being nearly incompressible it bulges elsewhere. Only [`Simulation::run`]
    /// takes this step (experimental, issue 24). `None`: the paper's template.
    pub implant_gel: Option<Material>,
    /// Implant elements' Young's modulus over the tissue's.
    pub implant_young_ratio: f64,
    /// Implant elements' Poisson ratio.
    pub implant_poisson_ratio: f64,
    /// Implant density (kg/m³) for the gravity correction.
    pub implant_density_kg_m3: f64,
    /// Gravity (m/s²), acting along the anatomical frame's `-y`.
    pub gravity_m_s2: f64,
    /// The corotated tangent `K` of the gravity stage's linear system (stage 1 uses the
    /// multigrid's, the paper's warped stiffness, until it stalls). [`Tangent::Full`] adds the positive
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
    /// iteration can overshoot into an oscillation (docs/dev/session-choices.md). It
    /// starts only then: an energy costs a fair part of a cycle, and most placements
    /// never need it. (The gravity stage is linear and needs none.)
    pub line_search: bool,
    /// Linear (small-strain) cycles before the corotated ones when stage 1 starts cold
    /// (zero displacement): at most this many, stopping once the relative residual is
    /// below [`WARMUP_TOLERANCE`]. From zero, the first corotated cycles push the implant
    /// vertices through their neighbours and take many cycles to untangle
    /// (docs/dev/session-choices.md).
    pub linear_warmup_cycles: usize,
    /// Once stage 1 stalls ([`STALL_WINDOW`]), each of its further cycles is a
    /// Newton-Krylov step: the full tangent ([`Tangent::Full`], with the geometric term
    /// the warped stiffness lacks) solved by this many conjugate gradient iterations
    /// preconditioned by the multigrid, instead of one V-cycle on the warped stiffness.
    /// Dearer per cycle, so only once the cheap cycles converge more slowly than these
    /// steps would in the same time ([`STALL_CONTRACTION`]): near the answer, and
    /// against the free lateral faces of a model, where tissue is stretched and turned,
    /// they settle into an oscillation (docs/dev/converged.md). Not while the warped
    /// cycles, at their last rate, would reach the tolerance aimed at
    /// ([`Simulation::solve`]'s while it runs, else [`SimulationOptions::relative_tolerance`])
    /// at less cost ([`NEWTON_KRYLOV_COST`], [`NEWTON_KRYLOV_CONTRACTION`]). 0: never.
    pub newton_krylov_iterations: usize,
    /// Once stage 1's relative residual is below [`LAGGED_OPERATORS_BELOW`] and falling,
    /// its warped cycles keep the operators of the last assembly (only the forces are
    /// evaluated at the new rotations, so the answer is the same equilibrium), their
    /// steps mixed with the last [`ANDERSON_DEPTH`] (Anderson mixing); a cycle whose
    /// starting residual is not below the last one's is itself a fresh one. Off: every
    /// cycle reassembles, as the paper's interactive cycle does.
    pub lagged_operators: bool,
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
    /// [`SurfaceSmoother`]); `None`: [`DEFAULT_SCAN_SMOOTHING`]; `Some(0.0)`: none.
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
            skin_slides: false,
            hold_sternum: true,
            rim_smoothing_mm: None,
            template_layer_mm: None,
            tissue: Material::default(),
            muscle: Some(DEFAULT_MUSCLE),
            skin: Some(SkinLayer::default()),
            implant_gel: None,
            implant_young_ratio: DEFAULT_IMPLANT_YOUNG_RATIO,
            implant_poisson_ratio: DEFAULT_IMPLANT_POISSON_RATIO,
            implant_density_kg_m3: DEFAULT_IMPLANT_DENSITY_KG_M3,
            gravity_m_s2: fem::STANDARD_GRAVITY_M_S2,
            multigrid: MultigridOptions::default(),
            inversion_barrier: Some(DEFAULT_INVERSION_BARRIER),
            compression_penalty: Some(DEFAULT_COMPRESSION_PENALTY),
            max_levels: None,
            line_search: true,
            linear_warmup_cycles: 6,
            newton_krylov_iterations: 2,
            lagged_operators: true,
            max_cycles: DEFAULT_MAX_CYCLES,
            relative_tolerance: DEFAULT_RELATIVE_TOLERANCE,
            falloff_mm: DEFAULT_FALLOFF_MM,
            scan_smoothing_mm: None,
            gravity_tangent: Tangent::Full,
            fill_in: FillInParams::default(),
        }
    }
}

impl SimulationOptions {
    /// The radius of the smoothing over the scan on a mesh of finest spacing
    /// `spacing_mm` (mm).
    pub fn scan_smoothing_on_mesh(&self, spacing_mm: f64) -> f64 {
        (self.scan_smoothing_mm).unwrap_or(DEFAULT_SCAN_SMOOTHING.on_mesh(spacing_mm))
    }

    /// The radius the implant's rim is mollified over on a mesh of finest spacing
    /// `spacing_mm` (mm).
    pub fn rim_smoothing_on_mesh(&self, spacing_mm: f64) -> f64 {
        (self.rim_smoothing_mm).unwrap_or(DEFAULT_RIM_SMOOTHING.on_mesh(spacing_mm))
    }

    /// The implant elements' material while the template prescribes their corners:
    /// [`SimulationOptions::implant_young_ratio`] of the tissue's modulus.
    pub fn soft_implant(&self) -> Material {
        Material {
            young_kpa: self.tissue.young_kpa * self.implant_young_ratio,
            poisson_ratio: self.implant_poisson_ratio,
            density_kg_m3: self.implant_density_kg_m3,
        }
    }

    /// The template's tissue layer over the footprint on a mesh of finest spacing
    /// `spacing_mm` (mm).
    pub fn template_layer_on_mesh(&self, spacing_mm: f64) -> f64 {
        (self.template_layer_mm).unwrap_or(DEFAULT_TEMPLATE_LAYER.on_mesh(spacing_mm))
    }

    /// Checks every setting's range; the error names the first bad one.
    pub(super) fn check(&self) -> Result<(), SimulationError> {
        check_option("shift_mm", self.shift_mm, true, "a finite number of mm")?;
        for (name, material) in [("muscle", self.muscle), ("implant_gel", self.implant_gel)] {
            if let Some(material) = material {
                check_option(
                    name,
                    material.young_kpa,
                    material.check().is_ok(),
                    "a positive Young's modulus (kPa), a Poisson ratio in (-1, 0.5) and a \
                     non-negative density",
                )?;
            }
        }
        check_option(
            "implant_young_ratio",
            self.implant_young_ratio,
            self.implant_young_ratio > 0.0,
            "a positive fraction",
        )?;
        check_option(
            "implant_density_kg_m3",
            self.implant_density_kg_m3,
            self.implant_density_kg_m3 >= 0.0,
            "a non-negative density",
        )?;
        check_option(
            "gravity_m_s2",
            self.gravity_m_s2,
            true,
            "a finite acceleration",
        )?;
        check_option(
            "relative_tolerance",
            self.relative_tolerance,
            self.relative_tolerance > 0.0,
            "a positive number",
        )?;
        check_option(
            "falloff_mm",
            self.falloff_mm,
            self.falloff_mm > 0.0,
            "a positive length",
        )?;
        for (what, value, max, expected) in [
            (
                "rim_smoothing_mm",
                self.rim_smoothing_mm,
                f64::INFINITY,
                "a length of at least 0 mm",
            ),
            (
                "template_layer_mm",
                self.template_layer_mm,
                f64::INFINITY,
                "a length of at least 0 mm",
            ),
            (
                "scan_smoothing_mm",
                self.scan_smoothing_mm,
                MAX_SCAN_SMOOTHING_MM,
                "a length from 0 to 20 mm",
            ),
        ] {
            if let Some(v) = value {
                check_option(what, v, (0.0..=max).contains(&v), expected)?;
            }
        }
        if self.hold_sternum {
            for limits in self.pocket.iter().flatten() {
                check_option(
                    "pocket midline_clearance_mm",
                    limits.midline_clearance_mm,
                    limits.midline_clearance_mm > STERNUM_HALF_WIDTH_MM,
                    "more than the 10 mm either side of the midline held over the sternum \
                     (or hold_sternum off)",
                )?;
            }
        }
        self.tissue
            .check()
            .map_err(|what| SimulationError::BadModel(format!("tissue material: {what}")))?;
        if let Some(skin) = &self.skin {
            skin.check(&self.tissue)
                .map_err(|what| SimulationError::BadModel(format!("skin: {what}")))?;
        }
        Ok(())
    }
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
