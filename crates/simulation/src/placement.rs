//! Placing an implant on its bed (paper V-A): the anchor point (the centre of the
//! implant's back wall) on the bed, moved along it, and the implant's local frame there.
//!
//! # Default anchor
//! [`AnchorRule::OnFold`] (default): the implant's lower edge on the planned fold (the
//! native fold's lowest point, PSMF, lowered as planned, see
//! [`crate::pocket::ice_fold_lowering_mm`]), its centre line straight down the bed from
//! the point behind the nipple (the nipple's parameters on the chest's cylinder, as
//! [`AnchorRule::BehindNipple`]): the anchor keeps that point's place across and is
//! walked until the footprint's lowest point lies at the planned fold's height
//! ([`anchor_on_floor`]). This is how the inframammary-fold approach places an implant:
//! its lower pole in the fold, the fold set for the implant's size (Mallucci and
//! Branford 2016, Plast. Reconstr. Surg. 137:1728, the ICE principle; Tebbetts and
//! Adams 2005, Plast. Reconstr. Surg. 116:2005, the High Five process), so the nipple
//! lies over the implant's upper-lower divide instead of on its lower slope. The point
//! behind the nipple lies medial of the nipple's own `x` on a curved chest, which keeps
//! the implant inside the model where the scans' sides (and the model's lateral clip
//! planes) end close beside the nipple (see `docs/dev/standing-frame.md`).
//!
//! [`AnchorRule::FootprintCentre`]: the area centroid of the bed's domain in the
//! cylinder parameters `(u, v)`, i.e. the implant centred on the breast's footprint (the
//! region inside the cut curve, seen from the body's axis). On the shared scans, whose
//! breasts hang a little, it lies 25-30 mm above and 6-12 mm lateral of the nipple's
//! radial projection (the cut curve reaches far up the chest), so the nipple rides on
//! the lower half of the implant and moves down and forward even without gravity.
//! [`AnchorRule::BehindNipple`] puts it straight behind the nipple instead (the
//! nipple's `(u, v)`); there a 120 mm implant overhangs the fold and is moved up by
//! about 37 mm to fit.
//!
//! When the footprint overhangs the bed at the requested anchor, the session moves the
//! anchor to the nearest place where it fits (see [`crate::template::fit_footprint`]) and
//! reports the move.
//!
//! # Moves
//! [`Placement::move_mm`] is in the anatomical frame: `x` towards the patient's left and
//! `y` up are arc lengths walked along the bed (in steps of at most
//! [`WALK_STEP_MM`], following the frame's left and up directions projected onto the bed's
//! tangent plane), `z` anterior shifts the bed forwards (the implant lies deeper for
//! negative values: the bed's backward shift is `shift_mm - z`).
//!
//! # Local frame and warping
//! At the anchor, `x'` is the frame's `x` (patient's left) projected onto the bed's
//! tangent plane, `y' = n × x'` (up), `z' = n` the bed's normal, then turned by
//! [`Placement::rotation_deg`] about `n` (counter-clockwise seen from the front). The
//! shapes are symmetric in `x'`, so `x'` pointing left on both sides is harmless. A point
//! with bed parameters `(u, v)` gets `(x', y') = T (u - u_a, v - v_a)` where `T` is the
//! bed's tangent map at the anchor expressed in `(x', y')` (isometric at the anchor).
//! The implant is warped to the bed: its thickness `z'(x', y')` is laid off along the bed's
//! local normal at `(u, v)`, not along the anchor's.

use crate::bed::ImplantBed;
use crate::error::SimulationError;
use anatomy::AnatomicalFrame;
use glam::{DMat2, DVec2, DVec3};
use serde::{Deserialize, Serialize};

/// Longest step of the walk along the bed (mm).
pub const WALK_STEP_MM: f64 = 2.0;

/// Step of the finite differences of the bed's tangent map (mm in parameters).
const TANGENT_STEP_MM: f64 = 1.5;

/// Where an implant goes, relative to the default anchor.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize)]
pub struct Placement {
    /// Move in the anatomical frame (mm): `x` towards the patient's left and `y` up
    /// along the bed, `z` anterior (the bed shifted forwards; negative = deeper).
    pub move_mm: DVec3,
    /// Turn about the bed's normal, counter-clockwise seen from the front (degrees).
    pub rotation_deg: f64,
    /// How far below the native fold the pocket reaches for this implant (mm, from 0 to
    /// the depth the pockets were built for); `None`: the side's
    /// [`crate::pocket::FoldLowering`] rule.
    pub fold_lowering_mm: Option<f64>,
}

impl Placement {
    /// A move (mm, anatomical frame) without rotation.
    pub fn moved(x_mm: f64, y_mm: f64, z_mm: f64) -> Placement {
        Placement {
            move_mm: DVec3::new(x_mm, y_mm, z_mm),
            ..Placement::default()
        }
    }
}

/// Where the default anchor lies.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AnchorRule {
    /// The implant's lower edge on the planned fold, its centre line straight down from
    /// the point behind the nipple (see the module documentation).
    #[default]
    OnFold,
    /// The area centroid of the bed's domain in `(u, v)` (see the module documentation).
    FootprintCentre,
    /// Straight behind the nipple: the nipple's `(u, v)`.
    BehindNipple,
}

/// A name that is not `on-fold`, `footprint-centre` or `behind-nipple`.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown anchor \"{0}\": expected on-fold, footprint-centre or behind-nipple")]
pub struct ParseAnchorRuleError(String);

impl std::fmt::Display for AnchorRule {
    /// The name `simulate --anchor` takes.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            AnchorRule::OnFold => "on-fold",
            AnchorRule::FootprintCentre => "footprint-centre",
            AnchorRule::BehindNipple => "behind-nipple",
        })
    }
}

impl std::str::FromStr for AnchorRule {
    type Err = ParseAnchorRuleError;

    fn from_str(name: &str) -> Result<AnchorRule, ParseAnchorRuleError> {
        match name.trim().to_ascii_lowercase().as_str() {
            "on-fold" => Ok(AnchorRule::OnFold),
            "footprint-centre" => Ok(AnchorRule::FootprintCentre),
            "behind-nipple" => Ok(AnchorRule::BehindNipple),
            _ => Err(ParseAnchorRuleError(name.to_string())),
        }
    }
}

/// The implant's anchor on its bed and its local frame there.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Anchor {
    /// Bed parameters `(u, v)` (mm).
    pub uv: DVec2,
    /// Position (file frame, mm).
    pub position: DVec3,
    /// Bed normal (anterior, unit).
    pub normal: DVec3,
    /// `x'` and `y'` axes (unit, tangent to the bed, after the rotation).
    pub x_axis: DVec3,
    pub y_axis: DVec3,
    /// `(u - u_a, v - v_a)` to `(x', y')`.
    pub to_local: DMat2,
    /// `(x', y')` to `(u - u_a, v - v_a)`.
    pub to_uv: DMat2,
    /// The bed's backward shift behind the fill-in (mm).
    pub shift_mm: f64,
}

impl Anchor {
    /// Implant coordinates `(x', y')` (mm) of bed parameters `uv`.
    #[inline]
    pub fn local(&self, uv: DVec2) -> DVec2 {
        self.to_local * (uv - self.uv)
    }

    /// Bed parameters of implant coordinates `(x', y')`.
    #[inline]
    pub fn uv_of(&self, local: DVec2) -> DVec2 {
        self.uv + self.to_uv * local
    }

    /// The anchor of a flat bed `z = 0` with `(u, v) = (x, y)`, at the origin, the
    /// implant's axes along x and y (tests' fixture).
    #[cfg(test)]
    pub(crate) fn flat() -> Anchor {
        Anchor {
            uv: DVec2::ZERO,
            position: DVec3::ZERO,
            normal: DVec3::Z,
            x_axis: DVec3::X,
            y_axis: DVec3::Y,
            to_local: DMat2::IDENTITY,
            to_uv: DMat2::IDENTITY,
            shift_mm: 0.0,
        }
    }
}

/// Tangent vectors `(S_u, S_v)` of the bed at `uv` by central differences (one-sided
/// at the domain's edge), and the bed point there.
fn tangents(bed: &ImplantBed, uv: DVec2) -> Option<(DVec3, DVec3, crate::bed::BedPoint)> {
    let at = bed.at(uv)?;
    let h = TANGENT_STEP_MM;
    let diff = |d: DVec2| -> Option<DVec3> {
        match (bed.at(uv + d), bed.at(uv - d)) {
            (Some(a), Some(b)) => Some((a.position - b.position) / (2.0 * h)),
            (Some(a), None) => Some((a.position - at.position) / h),
            (None, Some(b)) => Some((at.position - b.position) / h),
            (None, None) => None,
        }
    };
    Some((diff(DVec2::X * h)?, diff(DVec2::Y * h)?, at))
}

/// The frame's left and up projected onto the tangent plane of `normal`.
fn tangent_frame(frame: &AnatomicalFrame, normal: DVec3) -> (DVec3, DVec3) {
    let left = frame.left();
    let x = (left - normal * left.dot(normal))
        .try_normalize()
        .unwrap_or_else(|| normal.any_orthonormal_vector());
    (x, normal.cross(x))
}

/// `(du, dv)` to tangent-plane coordinates along `(x, y)`.
fn tangent_map(su: DVec3, sv: DVec3, x: DVec3, y: DVec3) -> DMat2 {
    DMat2::from_cols(
        DVec2::new(su.dot(x), su.dot(y)),
        DVec2::new(sv.dot(x), sv.dot(y)),
    )
}

/// Resolves a placement on `bed`: the default anchor `start` (bed parameters) walked
/// by the move, and the local frame there.
///
/// Errors: the walk leaves the bed; a non-finite move or rotation.
pub fn resolve_anchor(
    bed: &ImplantBed,
    frame: &AnatomicalFrame,
    start: DVec2,
    placement: &Placement,
) -> Result<Anchor, SimulationError> {
    let side = bed.side;
    for (what, value) in [
        ("move x (mm)", placement.move_mm.x),
        ("move y (mm)", placement.move_mm.y),
        ("move z (mm)", placement.move_mm.z),
        ("rotation (degrees)", placement.rotation_deg),
    ] {
        if !value.is_finite() {
            return Err(SimulationError::BadPlacement {
                side,
                what,
                value,
                expected: "a finite number".into(),
            });
        }
    }
    let step = DVec2::new(placement.move_mm.x, placement.move_mm.y);
    let moved_mm = step.length();
    let steps = (moved_mm / WALK_STEP_MM).ceil().max(0.0) as usize;
    let off = || SimulationError::AnchorOffFillIn { side, moved_mm };
    let mut uv = start;
    for _ in 0..steps {
        let (su, sv, at) = tangents(bed, uv).ok_or_else(off)?;
        let (x, y) = tangent_frame(frame, at.normal);
        let j = tangent_map(su, sv, x, y);
        if j.determinant().abs() < 1e-9 {
            return Err(off());
        }
        uv += j.inverse() * (step / steps as f64);
    }
    let (su, sv, at) = tangents(bed, uv).ok_or_else(off)?;
    let (x, y) = tangent_frame(frame, at.normal);
    let (s, c) = placement.rotation_deg.to_radians().sin_cos();
    let x_axis = x * c + y * s;
    let y_axis = -x * s + y * c;
    let to_local = tangent_map(su, sv, x_axis, y_axis);
    if to_local.determinant().abs() < 1e-9 {
        return Err(off());
    }
    Ok(Anchor {
        uv,
        position: at.position,
        normal: at.normal,
        x_axis,
        y_axis,
        to_local,
        to_uv: to_local.inverse(),
        shift_mm: bed.shift_mm,
    })
}

/// Most steps of [`anchor_on_floor`]'s walk.
const FLOOR_SEARCH_STEPS: usize = 24;

/// [`anchor_on_floor`] stops within this of its targets (mm).
const FLOOR_TOLERANCE_MM: f64 = 0.25;

/// The anchor on `bed` (bed parameters), walked from `start`, that lies at height
/// `centre_x_mm` across (standing frame) and at which the footprint's lowest point,
/// `half_height_mm` below the anchor along the bed's up, lies at height `floor_y_mm`
/// (standing frame, on the bed's tangent plane). Each step walks the bed by the
/// remaining differences (a walk of `d` along the bed moves a coordinate by `d` times
/// the cosine of the bed's slope, so the steps close in from one side).
///
/// Errors: the walk leaves the bed.
pub fn anchor_on_floor(
    bed: &ImplantBed,
    frame: &AnatomicalFrame,
    start: DVec2,
    centre_x_mm: f64,
    half_height_mm: f64,
    floor_y_mm: f64,
) -> Result<DVec2, SimulationError> {
    let mut uv = start;
    for _ in 0..FLOOR_SEARCH_STEPS {
        let anchor = resolve_anchor(bed, frame, uv, &Placement::default())?;
        let lowest = anchor.position - anchor.y_axis * half_height_mm;
        let across_mm = centre_x_mm - frame.to_local(anchor.position).x;
        let up_mm = floor_y_mm - frame.to_local(lowest).y;
        if across_mm.abs() <= FLOOR_TOLERANCE_MM && up_mm.abs() <= FLOOR_TOLERANCE_MM {
            break;
        }
        uv = resolve_anchor(bed, frame, uv, &Placement::moved(across_mm, up_mm, 0.0))?.uv;
    }
    Ok(uv)
}
