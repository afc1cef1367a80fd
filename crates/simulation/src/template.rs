//! The displacement template (paper V-A, Fig. 6): which vertices of the finest
//! tetrahedral level the implant displaces, which it holds, and which elements become
//! implant.
//!
//! For one breast with its bed ([`ImplantBed`]) and anchor ([`Anchor`]):
//! 1. *Fill-in elements*: tetrahedra of the finest level with vertices on both sides of
//!    the bed (all four vertices over the bed's `(u, v)` domain). The spatial index is
//!    the bed's `(u, v)` grid: every finest vertex near the fill-in has its cylinder
//!    coordinates computed once per model ([`TemplateIndex`]), so a template costs one
//!    2D point location per candidate vertex.
//! 2. Each candidate vertex gets its *foot* on the bed (the start of the bed normal
//!    through it, [`ImplantBed::foot`]), its height above the bed, implant
//!    coordinates `(x', y')` of the foot and the thickness `z'(x', y')` there,
//!    mollified over 14 mm by default ([`SmoothedThickness`]: linear tetrahedra of
//!    4-7 mm cannot follow the square-root rim of eqs. 3 and 10, which rises by 10 mm
//!    within the outer 5% of the radius). A *front* vertex (in front of the bed) of a
//!    fill-in element with `z' > 0` is an *implant vertex*, displaced by `z'` along the
//!    bed's normal at its foot; so is every front vertex over the footprint within a
//!    thin layer above the bed (7 mm by default), which smooths the ragged top
//!    of the paper's set (with [`crate::SimulationOptions::skin_slides`], a vertex
//!    on the skin is not held but slides over the implant). A *back* vertex with
//!    `z' > 0` (inside the footprint) is fixed, and by default
//!    ([`crate::SimulationOptions::hold_bed`]) every other back vertex of a fill-in
//!    element too. Laying the thickness off along normals from the foot makes
//!    the prescribed map `b(s) + h n(s) -> b(s) + (h + z'(s)) n(s)`, which does not
//!    fold elements over where the bed is inclined.
//! 3. *Implant elements*: fill-in elements whose four vertices are implant or fixed
//!    vertices; they get the implant's soft material and density (see
//!    [`crate::SimulationOptions`]).
//!
//! The template is rebuilt from scratch on every change of implant or position. The
//! posterior wall and the clip faces are held by [`TemplateIndex::wall_vertices`]
//! (see [`crate::session`]).

use crate::bed::{Foot, ImplantBed};
use crate::error::SimulationError;
use crate::placement::{Anchor, Placement, resolve_anchor};
use crate::template_volume::{covered_volume_ml, in_front};
use anatomy::breast::Side;
use glam::{DVec2, DVec3};
use implant::ImplantShape;
use rayon::prelude::*;
use tetra::TetMesh;

/// Points of the implant's outline checked against the bed's domain.
pub const OUTLINE_POINTS: usize = 72;

/// Margin around the fill-in's domain within which vertices are candidates (mm): the
/// shifted bed's domain moves a little against the fill-in's.
const DOMAIN_MARGIN_MM: f64 = 15.0;

/// Per-model data of the template search for one breast: the finest vertices near its
/// fill-in, with their cylinder coordinates, and the tetrahedra among them.
#[derive(Debug, Clone)]
pub struct SideCandidates {
    /// Candidate vertices (finest level).
    pub vertices: Vec<u32>,
    /// Their positions (file frame, mm).
    pub positions: Vec<DVec3>,
    /// Tetrahedra whose four vertices are candidates, with their corners as candidate
    /// indices.
    pub tets: Vec<(u32, [u32; 4])>,
}

/// Per-model data of the template search.
#[derive(Debug, Clone)]
pub struct TemplateIndex {
    pub sides: [SideCandidates; 2],
}

impl TemplateIndex {
    /// Candidates of each side: finest vertices whose `(u, v)` lies on the side's
    /// unshifted bed (or within [`DOMAIN_MARGIN_MM`] of its edge) and whose radial offset
    /// lies within `[-back_mm, front_mm]` of it (or of the bed's range near the edge).
    pub fn new(mesh: &TetMesh, beds: [&ImplantBed; 2], back_mm: f64, front_mm: f64) -> Self {
        let sides = beds.map(|bed| {
            let cyl: Vec<DVec3> = mesh
                .positions
                .iter()
                .map(|p| bed.cylinder.to_cylindrical(*p))
                .collect();
            let (w_lo, w_hi) = bed
                .w
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &w| {
                    (a.min(w), b.max(w))
                });
            let mut local = vec![u32::MAX; mesh.positions.len()];
            let mut vertices = Vec::new();
            let mut positions = Vec::new();
            for (i, c) in cyl.iter().enumerate() {
                let p = DVec2::new(c.x, c.y);
                let keep = match bed.at(p) {
                    Some(b) => c.z >= b.w - back_mm && c.z <= b.w + front_mm,
                    None => {
                        c.z >= w_lo - back_mm
                            && c.z <= w_hi + front_mm
                            && bed.distance_to_boundary(p) <= DOMAIN_MARGIN_MM
                    }
                };
                if keep {
                    local[i] = vertices.len() as u32;
                    vertices.push(i as u32);
                    positions.push(mesh.positions[i]);
                }
            }
            let tets = mesh
                .tets
                .iter()
                .enumerate()
                .filter_map(|(t, tet)| {
                    let l = tet.map(|v| local[v as usize]);
                    l.iter().all(|&x| x != u32::MAX).then_some((t as u32, l))
                })
                .collect();
            SideCandidates {
                vertices,
                positions,
                tets,
            }
        });
        TemplateIndex { sides }
    }

    /// The candidates of one side.
    pub fn side(&self, side: Side) -> &SideCandidates {
        &self.sides[side as usize]
    }
}

/// The feet of one side's candidates on its current bed.
#[derive(Debug, Clone)]
pub struct BedFeet {
    pub side: Side,
    /// Per candidate: its foot ([`ImplantBed::foot`]), `None` off the bed.
    pub feet: Vec<Option<Foot>>,
}

impl SideCandidates {
    /// The feet of the candidates on `bed`. They depend on the bed's shift only, so
    /// they are computed once per bed, not per implant.
    pub fn feet(&self, bed: &ImplantBed) -> BedFeet {
        BedFeet {
            side: bed.side,
            feet: self.positions.par_iter().map(|&p| bed.foot(p)).collect(),
        }
    }
}

/// The displacement template of one implant.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImplantTemplate {
    /// Implant (front) vertices with their displacement (mm): `z'` along the bed normal,
    /// all scaled by one factor so that the fill-in elements gain the covered volume.
    pub implant_vertices: Vec<(u32, DVec3)>,
    /// Skin vertices the template would displace, with that displacement (mm, scaled
    /// like [`ImplantTemplate::implant_vertices`]), with
    /// [`crate::SimulationOptions::skin_slides`] (else none): not held but on sliders in
    /// stage 1, and counted with their displacement when the template is scaled to the
    /// covered volume.
    pub skin_vertices: Vec<(u32, DVec3)>,
    /// Back vertices inside the footprint, fixed.
    pub fixed_vertices: Vec<u32>,
    /// Implant elements (finest level).
    pub implant_elements: Vec<u32>,
    /// Elements that would be implant elements but have a sliding skin corner
    /// ([`ImplantTemplate::skin_vertices`]): the tissue's material, the implant's weight.
    pub sliding_elements: Vec<u32>,
    /// Number of fill-in elements (crossing the bed).
    pub fill_in_elements: usize,
    /// The volume the template alone adds to the fill-in elements (ml): the sum over the
    /// elements crossing the bed of deformed minus rest volume, with only the template's
    /// displacements applied. [`ImplantTemplate::covered_volume_ml`] (within 1e-6 of it)
    /// once scaled; less where the unscaled template already adds less.
    pub template_volume_ml: f64,
    /// The implant's volume over the part of its footprint the finest mesh reaches
    /// (ml; [`crate::template_volume`]): less than the implant's volume where the
    /// footprint lies beyond a clip plane, where the scan ends.
    pub covered_volume_ml: f64,
    /// The factor in (0, 1] the thicknesses along the bed's normals were scaled by to
    /// insert the covered volume (1 where the unscaled template inserts no more).
    pub scale: f64,
    /// Thickness of the tissue layer over the footprint that moved with the implant (mm;
    /// [`TemplateRules::layer_mm`]).
    pub layer_mm: f64,
}

impl ImplantTemplate {
    /// The vertices the implant pushes: held ones, then the skin carried over them.
    pub fn pushed_vertices(&self) -> impl Iterator<Item = &(u32, DVec3)> {
        self.implant_vertices.iter().chain(&self.skin_vertices)
    }
}

/// The implant's thickness mollified over a disc of radius `radius_mm` (mm): the
/// average of `z'` under the biweight kernel `(1 - (r/ρ)²)²`, by a polar rule of
/// [`SMOOTHING_RINGS`] rings (1, 6, 12, ... points). Zero radius: the thickness itself.
/// The convolution keeps the implant's volume and spreads its steep rim (the square
/// root edge of eqs. 3 and 10) over the disc's width.
#[derive(Debug, Clone)]
pub struct SmoothedThickness {
    shape: ImplantShape,
    radius_mm: f64,
    /// Offsets (unit disc) and normalised weights.
    samples: Vec<(DVec2, f64)>,
}

/// Rings of [`SmoothedThickness`] beyond the centre.
pub const SMOOTHING_RINGS: usize = 4;

impl SmoothedThickness {
    /// The radius of the disc the rim is mollified over (mm).
    pub fn radius_mm(&self) -> f64 {
        self.radius_mm
    }

    pub fn new(shape: ImplantShape, radius_mm: f64) -> SmoothedThickness {
        let mut samples = vec![(DVec2::ZERO, 1.0)];
        if radius_mm > 0.0 {
            let dr = 1.0 / (SMOOTHING_RINGS as f64 + 0.5);
            // the centre carries the kernel's mass over r in [0, dr/2]
            let kernel = |r: f64| (1.0 - r * r).powi(2);
            samples[0].1 = kernel(0.0) * (dr * 0.5).powi(2) * std::f64::consts::PI;
            for ring in 1..=SMOOTHING_RINGS {
                let r = ring as f64 * dr;
                let count = 6 * ring;
                let ring_weight = kernel(r) * 2.0 * std::f64::consts::PI * r * dr;
                for k in 0..count {
                    let a =
                        (k as f64 + 0.5 * (ring % 2) as f64) / count as f64 * std::f64::consts::TAU;
                    samples.push((DVec2::new(a.cos(), a.sin()) * r, ring_weight / count as f64));
                }
            }
            let total: f64 = samples.iter().map(|s| s.1).sum();
            samples.iter_mut().for_each(|s| s.1 /= total);
        }
        SmoothedThickness {
            shape,
            radius_mm: radius_mm.max(0.0),
            samples,
        }
    }

    /// How far from the implant's centre `(x', y') = 0` the mollified thickness can be
    /// positive (mm): the footprint's half-diagonal plus the mollifying radius.
    pub fn reach_mm(&self) -> f64 {
        let f = self.shape.footprint();
        f.width_mm().hypot(f.height_mm()) / 2.0 + self.radius_mm
    }

    /// The mollified thickness at `(x', y')` (mm).
    #[inline]
    pub fn at(&self, p: DVec2) -> f64 {
        if self.radius_mm == 0.0 {
            return self.shape.thickness_mm(p.x, p.y);
        }
        let f = self.shape.footprint();
        let r = self.radius_mm;
        if p.x < f.x_min_mm - r
            || p.x > f.x_max_mm + r
            || p.y < f.y_min_mm - r
            || p.y > f.y_max_mm + r
        {
            return 0.0;
        }
        self.samples
            .iter()
            .map(|&(o, w)| {
                let q = p + o * r;
                w * self.shape.thickness_mm(q.x, q.y)
            })
            .sum()
    }
}

/// Scratch state of one candidate vertex.
#[derive(Clone, Copy)]
enum Class {
    /// Not over the bed.
    Off,
    /// In front of the bed; thickness and normal there, height above it (mm).
    Front(f64, DVec3, f64),
    /// Behind the bed; thickness there.
    Back(f64),
}

/// How far the implant's outline may reach beyond the cut curve (mm): its rim has zero
/// thickness, and the cut curve itself is only as precise as its control points.
pub const FOOTPRINT_TOLERANCE_MM: f64 = 2.0;

/// Passes of releasing corners of fully held elements that the template folds.
const UNFOLD_PASSES: usize = 3;

/// A fully held element counts as folded when the template leaves it less than this
/// fraction of its volume.
const UNFOLD_VOLUME_RATIO: f64 = 0.1;

/// Most pushes of [`fit_footprint`].
const FIT_ITERATIONS: usize = 60;

/// Extra push beyond the tolerance per step of [`fit_footprint`] (mm), so that the
/// pushes converge in a few steps instead of creeping.
const FIT_OVERSHOOT_MM: f64 = 0.25;

/// An outline point off the bed's domain.
#[derive(Clone, Copy)]
struct Overhang {
    /// How far outside (mm in bed parameters).
    outside_mm: f64,
    /// Its bed parameters.
    uv: DVec2,
    /// The nearest point of the domain's boundary.
    nearest: DVec2,
}

/// The points of the implant's outline at `anchor` that lie further than
/// [`FOOTPRINT_TOLERANCE_MM`] outside the bed's domain.
fn overhangs(bed: &ImplantBed, anchor: &Anchor, shape: &ImplantShape) -> Vec<Overhang> {
    shape
        .footprint_outline_mm(OUTLINE_POINTS)
        .into_iter()
        .filter_map(|local| {
            let uv = anchor.uv_of(local);
            if bed.contains(uv) {
                return None;
            }
            let nearest = bed.nearest_on_boundary(uv);
            let outside_mm = uv.distance(nearest);
            (outside_mm > FOOTPRINT_TOLERANCE_MM).then_some(Overhang {
                outside_mm,
                uv,
                nearest,
            })
        })
        .collect()
}

/// The deepest of `over`, if any.
fn deepest(over: &[Overhang]) -> Option<&Overhang> {
    over.iter()
        .max_by(|a, b| a.outside_mm.total_cmp(&b.outside_mm))
}

/// The error for an implant whose outline reaches `worst` beyond the bed.
fn larger_than_footprint(
    bed: &ImplantBed,
    shape: &ImplantShape,
    frame: &anatomy::AnatomicalFrame,
    worst: &Overhang,
) -> SimulationError {
    // where: on the cylinder at the bed's mean offset
    let radius = bed.cylinder.radius_mm + bed.w.iter().sum::<f64>() / bed.w.len() as f64;
    let p = bed.cylinder.centre
        + bed.cylinder.radial(worst.uv.x) * radius
        + bed.cylinder.axes.z_axis * worst.uv.y;
    let footprint = shape.footprint();
    SimulationError::ImplantLargerThanFootprint {
        side: bed.side,
        width_mm: footprint.width_mm(),
        height_mm: footprint.height_mm(),
        outside_mm: worst.outside_mm,
        near_mm: frame.to_local(p).to_array(),
    }
}

/// Checks that the implant's footprint outline lies on the bed's domain (within
/// [`FOOTPRINT_TOLERANCE_MM`]).
///
/// Errors: [`SimulationError::ImplantLargerThanFootprint`] naming how far the worst
/// outline point is outside and where.
pub fn check_footprint(
    bed: &ImplantBed,
    anchor: &Anchor,
    shape: &ImplantShape,
    frame: &anatomy::AnatomicalFrame,
) -> Result<(), SimulationError> {
    match deepest(&overhangs(bed, anchor, shape)) {
        None => Ok(()),
        Some(worst) => Err(larger_than_footprint(bed, shape, frame, worst)),
    }
}

/// The anchor nearest to `requested` at which the implant's footprint lies on the bed
/// (within [`FOOTPRINT_TOLERANCE_MM`]): `requested` itself when it fits, else the anchor
/// pushed along the bed away from the cut curve where the outline overhangs it. Each
/// push moves the anchor, in bed parameters, along the mean inward direction of the
/// overhanging outline points by the deepest overhang less the tolerance (plus
/// [`FIT_OVERSHOOT_MM`]); the implant's frame is re-resolved at every new anchor with
/// the requested rotation. A breast footprint is not convex (a small breast's cut curve
/// can be kidney-shaped), so the centroid or the point behind the nipple may leave too
/// little room on one side although the implant fits a little further in. Where the
/// outline overhangs on opposite sides (the bed too narrow at that height), the pushes
/// start again from anchors walked up and down the bed in steps of
/// [`HEIGHT_SEARCH_STEP_MM`], nearest first (the chest is wider where it curves more).
///
/// Errors: [`SimulationError::ImplantLargerThanFootprint`] for the anchor with the
/// smallest overhang found when the outline overhangs on opposite sides (the implant is
/// wider than the footprint there) or the pushes do not settle.
pub fn fit_footprint(
    bed: &ImplantBed,
    frame: &anatomy::AnatomicalFrame,
    requested: Anchor,
    rotation_deg: f64,
    shape: &ImplantShape,
) -> Result<Anchor, SimulationError> {
    let pushed = push_to_fit(bed, frame, requested, rotation_deg, shape);
    if pushed.is_ok() {
        return pushed;
    }
    // too wide at this height: the nearest height at which it fits, higher first
    for k in 1..=HEIGHT_SEARCH_STEPS {
        for sign in [1.0, -1.0] {
            let walk = Placement {
                move_mm: glam::DVec3::new(0.0, sign * k as f64 * HEIGHT_SEARCH_STEP_MM, 0.0),
                rotation_deg,
                fold_lowering_mm: None,
            };
            let Ok(start) = resolve_anchor(bed, frame, requested.uv, &walk) else {
                continue;
            };
            if let Ok(anchor) = push_to_fit(bed, frame, start, rotation_deg, shape) {
                return Ok(anchor);
            }
        }
    }
    pushed
}

/// Step of [`fit_footprint`]'s search over heights (mm along the bed).
const HEIGHT_SEARCH_STEP_MM: f64 = 5.0;

/// Steps of [`fit_footprint`]'s search over heights, each way.
const HEIGHT_SEARCH_STEPS: usize = 12;

/// [`fit_footprint`]'s pushes from `requested`.
fn push_to_fit(
    bed: &ImplantBed,
    frame: &anatomy::AnatomicalFrame,
    requested: Anchor,
    rotation_deg: f64,
    shape: &ImplantShape,
) -> Result<Anchor, SimulationError> {
    let mut anchor = requested;
    let mut over = overhangs(bed, &anchor, shape);
    let Some(mut best) = deepest(&over).copied() else {
        return Ok(anchor);
    };
    let placement = Placement {
        rotation_deg,
        ..Placement::default()
    };
    for _ in 0..FIT_ITERATIONS {
        let Some(worst) = deepest(&over).copied() else {
            return Ok(anchor);
        };
        if worst.outside_mm < best.outside_mm {
            best = worst;
        }
        let inward = over
            .iter()
            .map(|o| (o.nearest - o.uv) / o.outside_mm)
            .sum::<DVec2>()
            / over.len() as f64;
        // overhanging on opposite sides: no push helps
        if inward.length() < 0.3 {
            break;
        }
        let step_mm = worst.outside_mm - FOOTPRINT_TOLERANCE_MM + FIT_OVERSHOOT_MM;
        match resolve_anchor(
            bed,
            frame,
            anchor.uv + inward.normalize() * step_mm,
            &placement,
        ) {
            Ok(next) => anchor = next,
            Err(_) => break,
        }
        over = overhangs(bed, &anchor, shape);
    }
    if over.is_empty() {
        return Ok(anchor);
    }
    Err(larger_than_footprint(bed, shape, frame, &best))
}

/// The session's choices a template follows (see [`build_template`]).
#[derive(Debug, Clone, Copy)]
pub struct TemplateRules<'a> {
    /// Fix every back vertex of a fill-in element, not only those in the footprint.
    pub hold_bed: bool,
    /// Thickness of the tissue layer over the footprint that moves with the implant (mm).
    pub layer_mm: f64,
    /// Per finest vertex: held on the wall in every stage.
    pub on_wall: &'a [bool],
    /// Per finest vertex: on the skin, which the template does not hold but lets slide
    /// ([`ImplantTemplate::skin_vertices`]); `None`: the skin is held like any vertex.
    pub slides: Option<&'a [bool]>,
    /// Where the pocket ends below: nothing over bed points under the planned fold is
    /// pushed.
    pub fold: FoldPlane,
}

/// The least width of the fold's taper as a multiple of the thickness it lays off: the
/// smooth step's steepest slope is 1.5 over its width, so the push rises by at most 1.5
/// mm per mm of height. Over `taper_mm` alone (1.5 spacings) an implant 11-16 mm thick
/// at the plane rose by up to 2.3 per mm, and an element across the rise turned over on
/// landmark-jittered bodies; 0.8 was the least that turned none there, and 1.2 already
/// left a lowered fold more than 1 mm above its plan (docs/dev/standing-frame.md and
/// model-on-every-body.md, session 52).
pub const TAPER_PER_THICKNESS: f64 = 1.0;

/// The planned fold as a horizontal plane of the standing frame. The pocket ends there
/// and the fold's attachment holds the skin, so no part of the implant, its mollified rim
/// included (which reaches up to its radius beyond the outline), pushes tissue over bed
/// points below it; over the plane the push rises smoothly to the implant's thickness
/// within `taper_mm` or [`TAPER_PER_THICKNESS`] times that thickness, whichever is
/// wider. (Where the bed normal leans down, a pushed vertex in front of the bed can lie
/// a little below the plane while its foot lies above it.)
#[derive(Debug, Clone, Copy)]
pub struct FoldPlane {
    /// A point at the planned fold's height (file frame, mm).
    pub point: DVec3,
    /// Up, against gravity (file frame, unit).
    pub up: DVec3,
    /// Least height over the plane from which the full thickness is laid off (mm,
    /// positive; the session's is `FOLD_TAPER`).
    pub taper_mm: f64,
}

impl FoldPlane {
    /// How far `p` (file frame) lies above the planned fold (mm; negative below).
    pub fn height_mm(&self, p: DVec3) -> f64 {
        (p - self.point).dot(self.up)
    }

    /// The thickness laid off over the bed point `p` (file frame) where the implant is
    /// `thickness_mm` thick (mm): none below the plane, all from the taper's width `w`
    /// over it, `3t² - 2t³` of it between (`t` the height over `w`; `w` the wider of
    /// `taper_mm` and [`TAPER_PER_THICKNESS`] times `thickness_mm`). Taken at the foot
    /// on the bed, so that it is the same all along the bed normal: the prescribed map
    /// stays a function of the bed point alone, as the paper's is, which as a continuous
    /// map folds nothing over.
    pub fn laid_off_mm(&self, p: DVec3, thickness_mm: f64) -> f64 {
        let width_mm = self.taper_mm.max(TAPER_PER_THICKNESS * thickness_mm);
        let t = (self.height_mm(p) / width_mm).clamp(0.0, 1.0);
        t * t * (3.0 - 2.0 * t) * thickness_mm
    }
}

/// Builds the template of the implant whose mollified thickness is `thickness`,
/// anchored at `anchor`, over the finest level `mesh` with its `candidates` (of one
/// side) and their `feet` on that side's bed, following `rules`. With `hold_bed`, every back vertex of a
/// fill-in element is fixed, inside the footprint or not (see
/// [`crate::SimulationOptions::hold_bed`]); else only those inside (the paper's rule).
/// Besides the front vertices of fill-in elements, every front vertex over the
/// footprint up to `layer_mm` above the bed is displaced (see
/// [`crate::SimulationOptions::template_layer_mm`]). An element all of whose corners end
/// up held (by the template, or on the wall: `on_wall`, per finest vertex) and which the
/// template would fold (leave under a tenth of its volume) gets one of its template
/// corners off the wall released: its highest displaced one if any, else a fixed one.
/// With `slides`, a vertex on the skin (and off the wall) that the template would
/// displace is not held: where the tissue over the bed is thinner than the layer, the
/// skin slides over the implant, and no element with a sliding corner is an implant
/// element (it keeps the tissue's material but is weighed with the implant,
/// [`ImplantTemplate::sliding_elements`]).
///
/// Errors: [`SimulationError::EmptyTemplate`] when no vertex is displaced.
pub fn build_template(
    mesh: &TetMesh,
    candidates: &SideCandidates,
    feet: &BedFeet,
    anchor: &Anchor,
    thickness: &SmoothedThickness,
    rules: &TemplateRules,
) -> Result<ImplantTemplate, SimulationError> {
    let TemplateRules {
        hold_bed,
        layer_mm,
        on_wall,
        slides,
        fold,
    } = *rules;
    let classes = classify(feet, anchor, thickness, &fold);
    let mut state = vec![0u8; classes.len()];
    let mut template = ImplantTemplate {
        layer_mm,
        ..ImplantTemplate::default()
    };
    let fill_in = mark_fill_in(candidates, &classes, hold_bed, &mut state, &mut template);
    // the rest of the tissue layer up to `layer_mm` over the footprint moves with it
    for (k, class) in classes.iter().enumerate() {
        if let Class::Front(z, _, h) = *class
            && z > 0.0
            && h <= layer_mm
            && state[k] == 0
        {
            state[k] = DISPLACED;
        }
    }
    if let Some(on_skin) = slides {
        // skin held next to free skin shears the surface elements between them over
        let mut sliding = vec![false; mesh.positions.len()];
        for (k, st) in state.iter_mut().enumerate() {
            let v = candidates.vertices[k] as usize;
            if *st == DISPLACED && on_skin[v] && !on_wall[v] {
                *st = FOLLOWS;
                sliding[v] = true;
            }
        }
        // the soft implant material under a sliding corner has nothing to hold its shape
        let (tissue, implant): (Vec<u32>, Vec<u32>) = (template.implant_elements.iter())
            .partition(|&&t| mesh.tets[t as usize].iter().any(|&v| sliding[v as usize]));
        template.implant_elements = implant;
        template.sliding_elements = tissue;
    }
    release_folded(mesh, candidates, &classes, on_wall, &mut state);
    for (k, &st) in state.iter().enumerate() {
        let v = candidates.vertices[k];
        match (st, classes[k]) {
            (DISPLACED, Class::Front(z, n, _)) => template.implant_vertices.push((v, n * z)),
            (FOLLOWS, Class::Front(z, n, _)) => template.skin_vertices.push((v, n * z)),
            (FIXED, _) => template.fixed_vertices.push(v),
            _ => {}
        }
    }
    if template.implant_vertices.is_empty() {
        return Err(SimulationError::EmptyTemplate { side: feet.side });
    }
    template.covered_volume_ml = covered_volume_ml(&fill_in, feet, anchor, thickness);
    let fill_in_elements: Vec<u32> = fill_in.iter().map(|&(t, _)| t).collect();
    template.template_volume_ml =
        scale_to_covered_volume(mesh, &fill_in_elements, &mut template) / 1000.0;
    Ok(template)
}

/// Scales the template's displacements by the factor in (0, 1] at which the fill-in
/// elements (`fill_in_elements`, those crossing the bed, over whose sections
/// [`ImplantTemplate::covered_volume_ml`] integrates the implant) gain exactly the
/// covered volume, records the factor in [`ImplantTemplate::scale`], and returns their
/// gain (mm³).
///
/// Why: the thickness is laid off along the normals of a bed curved like a chest, and
/// the implant's coordinates are a linear map of the bed's cylinder coordinates, so
/// unscaled the template inserts 1.1-1.2 times the implant's volume (docs/dev/
/// volume-loss.md). The gain is a cubic in the factor (each element's volume is a
/// determinant of its displaced edges), zero at zero; the root in (0, 1] is bracketed
/// and found by regula falsi with the Illinois modification. Where the unscaled
/// template gains no more than the covered volume it is left as it is: the template
/// never lays off more than the implant's thickness, which the unfolding checked.
fn scale_to_covered_volume(
    mesh: &TetMesh,
    fill_in_elements: &[u32],
    template: &mut ImplantTemplate,
) -> f64 {
    let mut displacement = vec![DVec3::ZERO; mesh.positions.len()];
    for &(v, d) in template.pushed_vertices() {
        displacement[v as usize] = d;
    }
    let gain_mm3 = |factor: f64| -> f64 {
        (fill_in_elements.iter())
            .map(|&t| {
                let d = mesh.tets[t as usize].map(|v| displacement[v as usize] * factor);
                let (rest, moved) = displaced_volumes(mesh, t, d);
                moved - rest
            })
            .sum()
    };
    let target_mm3 = template.covered_volume_ml * 1000.0;
    let unscaled_mm3 = gain_mm3(1.0);
    template.scale = 1.0;
    if unscaled_mm3 <= target_mm3 || target_mm3 <= 0.0 {
        return unscaled_mm3;
    }
    // residuals gain - target: negative at 0, positive at 1
    let (mut lo, mut lo_residual) = (0.0, -target_mm3);
    let (mut hi, mut hi_residual) = (1.0, unscaled_mm3 - target_mm3);
    let mut factor = 1.0;
    let mut residual = hi_residual;
    let mut last_side = 0i8;
    for _ in 0..SCALE_ITERATIONS {
        factor = (lo * hi_residual - hi * lo_residual) / (hi_residual - lo_residual);
        residual = gain_mm3(factor) - target_mm3;
        if residual.abs() <= SCALE_TOLERANCE * target_mm3 {
            break;
        }
        if residual < 0.0 {
            (lo, lo_residual) = (factor, residual);
            if last_side == -1 {
                hi_residual *= 0.5;
            }
            last_side = -1;
        } else {
            (hi, hi_residual) = (factor, residual);
            if last_side == 1 {
                lo_residual *= 0.5;
            }
            last_side = 1;
        }
    }
    for (_, d) in (template.implant_vertices.iter_mut()).chain(&mut template.skin_vertices) {
        *d *= factor;
    }
    template.scale = factor;
    target_mm3 + residual
}

/// Most steps of [`scale_to_covered_volume`].
const SCALE_ITERATIONS: usize = 60;

/// Relative tolerance of [`scale_to_covered_volume`]'s gain.
const SCALE_TOLERANCE: f64 = 1e-6;

/// A template state of a candidate vertex: displaced with the implant.
const DISPLACED: u8 = 1;
/// A template state of a candidate vertex: fixed (0: free).
const FIXED: u8 = 2;
/// A template state of a candidate vertex: on the skin where the template would
/// displace it, on a slider in the solve.
const FOLLOWS: u8 = 3;

/// Where each candidate vertex lies: over the bed or not, in front of it or behind, with
/// the thickness the template lays off there ([`laid_thickness_mm`]).
fn classify(
    feet: &BedFeet,
    anchor: &Anchor,
    thickness: &SmoothedThickness,
    fold: &FoldPlane,
) -> Vec<Class> {
    (feet.feet.par_iter())
        .map(|foot| match foot {
            None => Class::Off,
            Some(f) => {
                let z = laid_thickness_mm(thickness, fold, anchor, f);
                if in_front(f.height_mm) {
                    Class::Front(z, f.normal, f.height_mm)
                } else {
                    Class::Back(z)
                }
            }
        })
        .collect()
}

/// The thickness the template lays off along the bed's normal at `foot` (mm): the
/// implant's mollified `thickness` anchored at `anchor`, as much of it as the `fold`
/// lets off at the foot itself ([`FoldPlane::laid_off_mm`]), so that it is the same all
/// along the normal.
pub fn laid_thickness_mm(
    thickness: &SmoothedThickness,
    fold: &FoldPlane,
    anchor: &Anchor,
    foot: &Foot,
) -> f64 {
    if fold.height_mm(foot.position) > 0.0 {
        fold.laid_off_mm(foot.position, thickness.at(anchor.local(foot.uv)))
    } else {
        0.0
    }
}

/// Marks the corners of the fill-in elements (crossing the bed) in `state`, displaced in
/// front of the bed over the footprint, fixed behind it (with `hold_bed` outside the
/// footprint too), and counts them and the implant elements into `template`. Returns the
/// fill-in elements with their corners.
fn mark_fill_in(
    candidates: &SideCandidates,
    classes: &[Class],
    hold_bed: bool,
    state: &mut [u8],
    template: &mut ImplantTemplate,
) -> Vec<(u32, [u32; 4])> {
    let mut fill_in = Vec::new();
    for &(t, corners) in &candidates.tets {
        let c = corners.map(|k| classes[k as usize]);
        if c.iter().any(|x| matches!(x, Class::Off)) {
            continue;
        }
        let front = c.iter().filter(|x| matches!(x, Class::Front(..))).count();
        if front == 0 || front == 4 {
            continue;
        }
        template.fill_in_elements += 1;
        fill_in.push((t, corners));
        let mut interior = 0;
        for (k, class) in corners.iter().zip(&c) {
            let s = &mut state[*k as usize];
            match *class {
                Class::Front(z, _, _) if z > 0.0 => {
                    interior += 1;
                    if *s == 0 {
                        *s = DISPLACED;
                    }
                }
                Class::Back(z) if z > 0.0 || hold_bed => {
                    if z > 0.0 {
                        interior += 1;
                    }
                    if *s == 0 {
                        *s = FIXED;
                    }
                }
                _ => {}
            }
        }
        if interior == 4 {
            template.implant_elements.push(t);
        }
    }
    fill_in
}

/// Releases, in up to [`UNFOLD_PASSES`] passes, a template corner of each fully held
/// element that the template folds (see [`build_template`]).
fn release_folded(
    mesh: &TetMesh,
    candidates: &SideCandidates,
    classes: &[Class],
    on_wall: &[bool],
    state: &mut [u8],
) {
    // An element whose four corners are all held (by the template or on the wall)
    // cannot change what the template does to it; where that folds it over (a tilted
    // face pushed past its fourth corner), release one of its template corners: the
    // highest displaced one if any (the tissue above the bed may lag, pushed on by its
    // neighbours), else a fixed one (the muscle under the implant may follow). Releasing
    // a fixed corner first (as before) left most such elements folded, since nothing
    // pushes a free corner behind the bed through the soft implant elements: on
    // `pair1_pre` with R-MOD-95 on both sides 5 elements ended inverted against none now,
    // with R-MOD-100 30 against 5 (21 of the 30 were implant elements with a released
    // fixed corner); `v02_average` with R-MOD-120 is unchanged (one in stage 1). Tried
    // and not kept: moving a folded element's corners fixed inside the footprint with
    // the implant (R-MOD-100 on `pair1_pre`: 7 inverted, but the tissue behind the bed,
    // stretched by the implant's thickness, kept `v02_average` with R-MOD-120 from
    // converging: relative residual 1.9e-2 after 40 cycles).
    // sliding skin counts as held at its template position (its slider keeps it near),
    // but is never the corner released
    let walled = |k: u32| on_wall[candidates.vertices[k as usize] as usize];
    let held = |st: u8| st != 0;
    let displacement = |state: &[u8], k: usize| match classes[k] {
        Class::Front(z, n, _) if state[k] == DISPLACED || state[k] == FOLLOWS => n * z,
        _ => DVec3::ZERO,
    };
    let mut release = Vec::new();
    for _ in 0..UNFOLD_PASSES {
        release.clear();
        for &(t, corners) in &candidates.tets {
            if !corners
                .iter()
                .all(|&k| held(state[k as usize]) || walled(k))
                || !corners.iter().any(|&k| held(state[k as usize]))
            {
                continue;
            }
            let d = corners.map(|k| displacement(state, k as usize));
            let (rest, moved) = displaced_volumes(mesh, t, d);
            if moved > UNFOLD_VOLUME_RATIO * rest {
                continue;
            }
            let height = |k: u32| match classes[k as usize] {
                Class::Front(_, _, h) => h,
                _ => f64::NEG_INFINITY,
            };
            // a corner on the wall stays held whatever the template says
            let releasable = corners.iter().copied().filter(|&k| !walled(k));
            let corner = releasable
                .clone()
                .filter(|&k| state[k as usize] == DISPLACED)
                .max_by(|&a, &b| height(a).total_cmp(&height(b)))
                .or_else(|| releasable.clone().find(|&k| state[k as usize] == FIXED));
            release.extend(corner);
        }
        if release.is_empty() {
            break;
        }
        for &k in &release {
            state[k as usize] = 0;
        }
    }
}

/// The rest and displaced signed volumes of finest element `t` with corner displacements
/// `d` (mm³).
fn displaced_volumes(mesh: &TetMesh, t: u32, d: [DVec3; 4]) -> (f64, f64) {
    let p = mesh.tets[t as usize].map(|v| mesh.positions[v as usize]);
    let rest = tetra::quality::signed_volume(p);
    let moved = tetra::quality::signed_volume([p[0] + d[0], p[1] + d[1], p[2] + d[2], p[3] + d[3]]);
    (rest, moved)
}

#[cfg(test)]
mod tests;
