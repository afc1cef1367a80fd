//! The closed surface (paper IV-C, Fig. 4 d-e): the scan and the filled base clipped by
//! four planes around the breasts, the base shifted posteriorly to the chest wall, and
//! the two clipped borders stitched by a band of triangles. The result bounds the volume
//! the finite elements fill.
//!
//! # Algorithm
//! 1. The clip box ([`ClipBox::around_breasts_and_footprints`]): top and bottom planes
//!    orthogonal to the frame's y axis, from the clavicles and the folds, kept a
//!    clearance inside the scan's height and off notches cut into its edge; two lateral
//!    planes parallel to its z axis that may lean in the coronal plane, each fitted (a
//!    small linear programme over offset and lean) to lie as far beyond the breast
//!    footprints as the scan allows while staying a clearance inside the scan's outline
//!    at every height of the box: a torso narrows from the breasts to the waist, and an
//!    upright plane, held inside the waist, cut 20 to 30 mm off each breast. The
//!    footprints are the filled base's points that are not the scan's (fill-ins and cut
//!    curves). Where even so a plane cuts a footprint (the scan ends just beyond the
//!    breast, as on the phantom and the shared scans), the surface carries a warning and
//!    the room left ([`ClosedSurface::lateral_room_mm`]).
//! 2. Clipping, in the box's coordinates (the frame's, with x mapped affinely at each
//!    height so that the leaning planes become upright, [`ClipBox::to_box`]; exact
//!    for the planes, and the mapped-back split points lie within micrometres of the
//!    split edges): each plane in turn splits the triangles it
//!    crosses exactly at the plane (the split vertex gets the plane's coordinate
//!    exactly; a vertex whose edge crosses within a small snap distance is moved along
//!    that edge onto the crossing, so no slivers and the border stays on the exact
//!    section), keeping the inside. Only the largest connected piece is kept (drops specks).
//!    Where a plane grazes a bump (a breast's lateral side), the bump's cut-off tip
//!    leaves a small border cycle entirely on that plane; it is closed by a flat cap.
//!    The border must then be a single loop lying on the planes, with one corner vertex on
//!    each of the four plane intersections; a loop off the planes means the box reaches
//!    beyond the surface's border, a further loop a hole inside the box.
//! 3. The clipped base (in [`build_closed_surface`], smoothed first by ten Laplacian
//!    steps inside its border: the scanner's noise means nothing on a stand-in for the
//!    chest wall; [`build_closed_surface_in_box`] takes it as given) is translated by
//!    the rear-wall offset along the posterior axis
//!    (`-z` of the frame), the paper's "shifted towards the back"; a translation keeps
//!    its border on the same four planes. Where the scan runs almost parallel to that
//!    axis (the underside of a hanging breast), the translated wall stays too close to
//!    it; there its vertices are pushed further in along the scan's inward normal until
//!    they lie a fifth of the offset behind it (`wall_clearance.rs`; a push is cut
//!    back where it would turn a wall triangle over or fold the wall's border back on
//!    a clip plane). Its
//!    orientation is reversed (if needed, judged by the winding of its border against
//!    the scan's) so it faces posteriorly.
//! 4. Stitching: both borders are split at their corners into four sides; each side of
//!    the scan and the same side of the wall lie in one plane and, with the two corner
//!    edges, bound a planar polygon, triangulated by a constrained Delaunay
//!    triangulation (spade) of its vertices. Unlike a two-chain zipper this stays
//!    correct where a cut curve is not monotone along the side (over a ptotic breast's
//!    lower pole, cut by a lateral plane). The band adds no vertices.
//!    The scan is turned to face anteriorly first if it faces the other way.
//! 5. Checks: watertight and 2-manifold ([`mesh::manifold_report`]), no self-intersections
//!    ([`mesh::self_intersections`]; sub-millimetre folds of the scan's own noise, and
//!    of the wall where a breast's fill-in meets a filled scan hole, are smoothed out
//!    first, [`mesh::untangle`], with a warning), and a positive volume
//!    (else the wall lies in front of the scan).
//! 6. Before all this, [`build_closed_surface`] moves each lateral plane inwards, by at
//!    most 10 mm and never past a breast landmark, off any graze of the torso's side: to
//!    where, on the plane and a step either side, the smoothed base's section has no
//!    closed loop and does not run front to back along an overhang, and the base's and
//!    the scan's sections cross the top and bottom heights once
//!    (`lateral_section.rs`). The surface is then built once; an error is that box's
//!    (with the remaining defects of each plane that could not be cleared). The box is the
//!    fitted one or, without `fit_lateral_planes`, the upright one; if the fit itself
//!    fails (a breast landmark outside what the scan allows), that is the error.
//!
//! The result is in the scan's (file) coordinates.
//!
//! # Limitations
//! - On each plane the scan's cut curve must lie anterior to the shifted wall's; where
//!   they cross, the build fails rather than repairs.
//! - The wall is a translated copy pushed in only where it comes within a fifth of the
//!   offset of the scan, so where the chest is steep (the lateral planes) its distance
//!   from the scan along the normal is less than the offset.
//! - The lateral planes are planes (straight lines in the coronal plane) and stay inside
//!   the scan at every height of the box. The upright box (without
//!   `fit_lateral_planes`), held inside the waist, cuts 19 to 25 mm off the lateral
//!   edge of each footprint on every shared scan; the fitted, leaning planes (the
//!   default), moved in off grazes, about 8 to 18 mm on the zoo
//!   (`docs/dev/model-on-every-body.md`). A curved lateral boundary following the
//!   outline, meeting the side at a steeper angle, would keep more.
//!
//! # Files
//! - `clip_box.rs`: the clip box ([`ClipBox`]): its planes, fitted or upright.
//! - `lateral_section.rs`: where a lateral plane crosses the torso's side cleanly.
//! - `clip.rs`: a surface clipped to the box, with its border split into four sides.
//! - `stitch.rs`: the band that stitches the two borders on each plane.

mod clip;
mod clip_box;
mod lateral_section;
mod stitch;

pub use clip_box::{ClipBox, ClipBoxFit};

use crate::frame::AnatomicalFrame;
use crate::landmarks::Landmarks;
use crate::place::Place;
use clip::ClippedPart;
use clip_box::{lateral_room, upright_box};
use glam::DVec3;
use lateral_section::{MAX_INWARD_MM, clear_of_grazing};
use mesh::{
    ManifoldReport, MeshError, Topology, TriMesh, manifold_report, smooth_inside_borders, untangle,
};
use std::ops::Range;
use stitch::bands;

/// Default rear-wall offset (mm): skin (about 2 mm) plus pectoralis major (about 10 to
/// 13 mm in adult women by ultrasound), the layers the paper shifts the base back by so
/// the wall lies at the chest wall (ribs); the implant sits on this wall.
pub const DEFAULT_REAR_WALL_OFFSET_MM: f64 = 15.0;

/// The largest rear-wall offset (mm): further back the wall passes through the ribs,
/// and a wall kilometres away made the self-intersection test's grid, which spans the
/// bounding box, take minutes.
pub const MAX_REAR_WALL_OFFSET_MM: f64 = 60.0;

/// A clip box needs at least this many triangles of each surface inside it; fewer means
/// the box misses the surface.
const MIN_CLIPPED_TRIANGLES: usize = 16;
/// How far inside a lateral plane the breast landmarks should lie (mm); see
/// [`ClosedSurfaceOptions::min_border_clearance_mm`].
pub const LANDMARK_MARGIN_MM: f64 = 5.0;
/// The farthest a scan vertex may move to smooth out a fold of noise through the scan
/// (mm): a few times the scanner's noise (0.1-0.4 mm on the shared scans); a larger
/// crossing is anatomy or a wrong wall, and an error.
const MAX_UNTANGLE_MM: f64 = 1.5;
/// The rear wall keeps at least this fraction of the offset behind the scan
/// ([`keep_wall_clear`]): where the chest runs almost parallel to the shift, the
/// translated wall alone would come closer.
///
/// [`keep_wall_clear`]: crate::wall_clearance::keep_wall_clear
const WALL_CLEARANCE_FRACTION: f64 = 0.2;

/// Laplacian steps ([`mesh::laplacian_smooth`]) on the filled base before it becomes
/// the wall: ten take a one-vertex spike of noise down to about 6% and independent
/// per-vertex noise to about a sixth, and move the smooth chest by about 0.1 mm.
const WALL_SMOOTHING_STEPS: usize = 10;

/// Where the clip planes go relative to the landmarks (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosedSurfaceOptions {
    /// Top plane this far above the higher clavicle point Pc. Default 0: the clavicle
    /// level, above the upper pole of both breasts (which starts some 20 to 40 mm below
    /// it) and below the neck, where scans end.
    pub top_margin_mm: f64,
    /// Bottom plane this far below the lower fold point PSMF. Default 40: room below the
    /// fold for the tissue an implant pushes down.
    pub bottom_margin_mm: f64,
    /// Left and right planes this far beyond the lateral fold ends PSMFll and PSMFlr.
    /// Default 40: the breast reaches some 25 to 30 mm beyond the fold's lateral end.
    pub lateral_margin_mm: f64,
    /// The planes keep at least this distance from the scan's outer border (measured in
    /// the coronal plane); planes closer are moved inwards. Default 10: clear of the
    /// ragged, noisy triangles at a scan's edge, and (for the lateral planes) where the
    /// surface still faces forward enough for the shifted wall to stay behind it.
    pub border_clearance_mm: f64,
    /// Where the border clearance would leave a nipple or a fold's lowest point or
    /// medial end less than [`LANDMARK_MARGIN_MM`] inside a lateral plane, that plane
    /// moves outwards as far as the landmark needs, but keeps at least this clearance.
    /// Default 5: on a torso narrower at the waist than across the breasts (the shared
    /// `pair1_post`), the bottom of the box would otherwise pull the lateral planes in
    /// through the nipples. Closer to the scan's widest point, a lateral plane meets the
    /// side of the chest almost tangentially and the shifted wall runs into the scan.
    pub min_border_clearance_mm: f64,
    /// How far the filled base is shifted posteriorly (mm); default
    /// [`DEFAULT_REAR_WALL_OFFSET_MM`].
    pub rear_wall_offset_mm: f64,
    /// Fit leaning lateral planes to the breast footprints
    /// ([`ClipBox::around_breasts_and_footprints`]) instead of the upright box held
    /// inside the waist. Default `true`: the upright planes cut 19 to 25 mm off the
    /// lateral side of every shared scan's breast footprints, the fitted ones 7 to 16
    /// (docs/dev/model-on-every-body.md).
    pub fit_lateral_planes: bool,
}

impl Default for ClosedSurfaceOptions {
    fn default() -> ClosedSurfaceOptions {
        ClosedSurfaceOptions {
            top_margin_mm: 0.0,
            bottom_margin_mm: 40.0,
            lateral_margin_mm: 40.0,
            border_clearance_mm: 10.0,
            min_border_clearance_mm: 5.0,
            rear_wall_offset_mm: DEFAULT_REAR_WALL_OFFSET_MM,
            fit_lateral_planes: true,
        }
    }
}

/// Which input surface an error is about.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SurfaceRole {
    Scan,
    FilledBase,
}

impl std::fmt::Display for SurfaceRole {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            SurfaceRole::Scan => "scan",
            SurfaceRole::FilledBase => "filled base",
        })
    }
}

/// Why no closed surface could be built.
#[derive(Debug, thiserror::Error)]
pub enum ClosedSurfaceError {
    #[error("closed surface: {0}")]
    InvalidInput(String),
    #[error("closed surface: the {role} is not a valid mesh: {source}")]
    InvalidMesh {
        role: SurfaceRole,
        source: MeshError,
    },
    #[error(
        "closed surface: only {count} triangles of the {role} lie inside the clip box \
         (at least {MIN_CLIPPED_TRIANGLES} needed): the box misses the surface"
    )]
    TooFewTriangles { role: SurfaceRole, count: usize },
    #[error(
        "closed surface: the {role} has a hole inside the clip box (a border loop of \
         {vertices} vertices around ({:.1}, {:.1}, {:.1}) mm); close it first",
        center_mm[0], center_mm[1], center_mm[2]
    )]
    HoleInsideBox {
        role: SurfaceRole,
        vertices: usize,
        center_mm: [f64; 3],
    },
    #[error(
        "closed surface: the clip box reaches beyond the {role}'s border near \
         ({:.1}, {:.1}, {:.1}) mm, so the clipped border is not a closed loop on the \
         four planes; move the planes inwards",
        near_mm[0], near_mm[1], near_mm[2]
    )]
    RunsOffBorder {
        role: SurfaceRole,
        near_mm: [f64; 3],
    },
    #[error(
        "closed surface: the clipped {role}'s border meets the box's edge where its {side} \
         and {end} planes meet {count} times instead of once, near ({:.0}, {:.0}, {:.0}) \
         mm: the side of the torso runs along the box's {end} there; check the scan there, \
         and the landmarks that set the {end} (the clavicles the top, the folds the bottom)",
        near_mm[0], near_mm[1], near_mm[2]
    )]
    MissingCorners {
        role: SurfaceRole,
        side: &'static str,
        end: &'static str,
        count: usize,
        near_mm: [f64; 3],
    },
    #[error(
        "closed surface: the scan's and the filled base's borders cannot be stitched: {what}{}",
        near_mm.map_or(String::new(), |[x, y, z]| format!(" (near ({x:.0}, {y:.0}, {z:.0}) mm)"))
    )]
    Stitch {
        /// What is wrong, in words.
        what: String,
        /// Where (mm, the scan's file coordinates), where there is one place.
        near_mm: Option<[f64; 3]>,
    },
    #[error("closed surface: the result is not watertight and 2-manifold: {0}")]
    NotWatertight(ManifoldReport),
    #[error(
        "closed surface: the shifted filled base lies in front of the scan (signed volume \
         {volume_ml:.1} ml); check that the base is the scan with the breasts filled in"
    )]
    WallInFront { volume_ml: f64 },
    #[error(
        "closed surface: {what} near ({:.0}, {:.0}, {:.0}) mm ({count} pairs of triangles \
         cross): check the scan there, and the landmarks and control points near that \
         point", near_mm[0], near_mm[1], near_mm[2]
    )]
    SelfIntersecting {
        count: usize,
        /// Which surfaces cross, in words.
        what: &'static str,
        near_mm: [f64; 3],
    },
    #[error("{error} ({})", describe_grazing(grazing))]
    OnGrazingPlane {
        /// The planes that could not be cleared and may cause `error`: the one on its
        /// side of the box, or each grazing one where it has no place.
        grazing: Vec<GrazingPlane>,
        /// The error of the box with that plane (its text is part of this one's, so it
        /// is not a `source` a caller would print again).
        error: Box<ClosedSurfaceError>,
    },
}

/// A lateral clip plane that [`build_closed_surface`] could not move off a graze of the
/// torso's side.
#[derive(Debug, Clone, PartialEq)]
pub struct GrazingPlane {
    /// "right" or "left".
    pub side: &'static str,
    /// How far it was moved inwards (mm).
    pub moved_mm: f64,
    /// Loops and stray corners left in its sections.
    pub defects: usize,
    /// How far its section's depth spread exceeds the bound (mm).
    pub excess_fold_mm: f64,
}

/// The planes of [`ClosedSurfaceError::OnGrazingPlane`] in words: what they share once,
/// then each one's figures.
fn describe_grazing(grazing: &[GrazingPlane]) -> String {
    let sides: Vec<&str> = grazing.iter().map(|plane| plane.side).collect();
    let figures: Vec<String> = grazing
        .iter()
        .map(|plane| {
            format!(
                "{}moved {:.1} mm inwards, {} loop(s) or stray corner(s) left in its section, \
                 which runs {:.1} mm further front to back than it should",
                if grazing.len() > 1 {
                    format!("{}: ", plane.side)
                } else {
                    String::new()
                },
                plane.moved_mm,
                plane.defects,
                plane.excess_fold_mm
            )
        })
        .collect();
    format!(
        "the {} clip plane{} still graze{} the side of the torso at the least bad position \
         within {MAX_INWARD_MM} mm and short of the breast landmarks ({}); check the scan's \
         side there",
        sides.join(" and "),
        if grazing.len() > 1 { "s" } else { "" },
        if grazing.len() > 1 { "" } else { "s" },
        figures.join("; ")
    )
}

impl ClosedSurfaceError {
    /// Where on the body the problem lies (mm, the scan's file coordinates), for the
    /// errors that have a place.
    pub fn place(&self) -> Option<Place> {
        match self {
            ClosedSurfaceError::HoleInsideBox { center_mm, .. } => Some(Place::at(*center_mm)),
            ClosedSurfaceError::RunsOffBorder { near_mm, .. }
            | ClosedSurfaceError::MissingCorners { near_mm, .. }
            | ClosedSurfaceError::SelfIntersecting { near_mm, .. } => Some(Place::at(*near_mm)),
            ClosedSurfaceError::Stitch { near_mm, .. } => near_mm.map(Place::at),
            ClosedSurfaceError::InvalidInput(_)
            | ClosedSurfaceError::InvalidMesh { .. }
            | ClosedSurfaceError::TooFewTriangles { .. }
            | ClosedSurfaceError::NotWatertight(_)
            | ClosedSurfaceError::WallInFront { .. } => None,
            ClosedSurfaceError::OnGrazingPlane { error, .. } => error.place(),
        }
    }
}

/// A closed, outward-oriented surface around the breast region.
#[derive(Debug, Clone)]
pub struct ClosedSurface {
    /// Watertight, 2-manifold, outward, without self-intersections (mm, file frame).
    pub mesh: TriMesh,
    /// Enclosed volume (ml).
    pub volume_ml: f64,
    /// Triangles of the clipped scan.
    pub front: Range<usize>,
    /// Triangles of the clipped, shifted filled base (facing posteriorly; smoothed by
    /// [`build_closed_surface`]): the wall the implant sits on.
    pub back_wall: Range<usize>,
    /// Triangles of the band joining the two.
    pub band: Range<usize>,
    /// The planes used.
    pub clip_box: ClipBox,
    /// The shift of the base (mm).
    pub rear_wall_offset_mm: f64,
    /// How far each lateral plane lies beyond the breast footprints (the fill-ins, where
    /// known, and the lateral fold ends), `[right plane, left plane]`, measured along x
    /// at the footprint's heights (mm); negative where a plane cuts a footprint. `None`
    /// when built with [`build_closed_surface_in_box`].
    pub lateral_room_mm: Option<[f64; 2]>,
    /// What the caller should tell the user: e.g. a scan that ends too close beyond a
    /// breast for the clip box to keep its whole footprint with a margin.
    pub warnings: Vec<String>,
}

/// The clip box from the landmarks and the footprints
/// ([`ClipBox::around_breasts_and_footprints`], or the upright box without
/// `fit_lateral_planes`), its lateral planes moved in off any graze of the torso's side
/// ([`clear_of_grazing`]), then [`build_closed_surface_in_box`].
///
/// A lateral plane that meets the side of the chest almost tangentially cuts off the
/// tip of a bump (a closed loop on the plane, which the wall's copy turns into a pocket
/// of air) or follows the side in depth so that the wall moved back crosses the skin;
/// a few millimetres further in, the plane crosses the side cleanly. The surface is
/// built once: an error is the one of that box.
pub fn build_closed_surface(
    scan: &TriMesh,
    filled_base: &TriMesh,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &ClosedSurfaceOptions,
) -> Result<ClosedSurface, ClosedSurfaceError> {
    // The box follows the thorax (the body's axes), not the way she stood.
    let frame = &frame.sternal();
    check_rear_wall_offset(options.rear_wall_offset_mm)?;
    let footprints = footprint_points(scan, filled_base);
    // The wall is a stand-in for the chest wall 15 mm behind the skin: the scanner's
    // noise means nothing there, and at a lateral plane's grazing angle it pokes
    // through the plane in loops that the wall would cap around air.
    let mut filled_base = filled_base.clone();
    smooth_inside_borders(&mut filled_base, WALL_SMOOTHING_STEPS);
    let filled_base = &filled_base;
    let (fitted, notch_warnings) = if options.fit_lateral_planes {
        let fit =
            ClipBox::around_breasts_and_footprints(scan, frame, landmarks, &footprints, options)?;
        (fit.clip_box, fit.notch_warnings)
    } else {
        upright_box(scan, frame, landmarks, options)?
    };
    let (clip_box, moves) = clear_of_grazing(
        fitted,
        scan,
        filled_base,
        frame,
        landmarks,
        options.rear_wall_offset_mm,
    );
    const SIDES: [&str; 2] = ["right", "left"];
    let mut surface = build_closed_surface_in_box(
        scan,
        filled_base,
        frame,
        &clip_box,
        options.rear_wall_offset_mm,
    )
    .map_err(|error| {
        // A grazing plane is named only where it can be the cause: the plane on the
        // error's side of the box, or each grazing one where the error has no place.
        let on_side = |k: usize| match error.place() {
            Some(place) => {
                let local = frame.to_local(DVec3::from_array(place.centre_mm));
                let middle = 0.5 * (clip_box.x_min_at(local.y) + clip_box.x_max_at(local.y));
                (local.x < middle) == (k == 0)
            }
            None => true,
        };
        let grazing: Vec<GrazingPlane> = (0..2)
            .filter(|&k| !moves[k].is_clean() && on_side(k))
            .map(|k| GrazingPlane {
                side: SIDES[k],
                moved_mm: moves[k].moved_mm,
                defects: moves[k].defects,
                excess_fold_mm: moves[k].excess_fold_mm,
            })
            .collect();
        if grazing.is_empty() {
            error
        } else {
            ClosedSurfaceError::OnGrazingPlane {
                grazing,
                error: Box::new(error),
            }
        }
    })?;
    let keep: Vec<DVec3> = footprints.iter().map(|&p| frame.to_local(p)).collect();
    let room = lateral_room(&clip_box, &keep, frame, landmarks);
    surface.lateral_room_mm = Some(room);
    surface.warnings.extend(notch_warnings);
    for (k, side) in SIDES.into_iter().enumerate() {
        let plane = moves[k];
        if !plane.is_clean() {
            surface.warnings.push(format!(
                "the {side} clip plane still grazes the side of the torso {:.1} mm in from \
                 where it was fitted ({} loops or stray corners in its section, which runs \
                 {:.1} mm further front to back than it should); the surface closed anyway",
                plane.moved_mm, plane.defects, plane.excess_fold_mm
            ));
        } else if plane.moved_mm > 0.0 {
            surface.warnings.push(format!(
                "the {side} clip plane was moved {:.1} mm inwards, off a graze of the side of \
                 the torso (a bump, an overhang or a corner of the section there would have \
                 kept the scan and the chest wall rebuilt behind it from being joined)",
                plane.moved_mm
            ));
        }
        if room[k] < LANDMARK_MARGIN_MM {
            surface.warnings.push(format!(
                "the {side} clip plane lies {:.1} mm beyond the {side} breast's footprint \
                 (wanted {LANDMARK_MARGIN_MM} mm){}: the scan ends close beyond the breast",
                room[k],
                if room[k] < 0.0 {
                    ", so it cuts off part of it"
                } else {
                    ""
                }
            ));
        }
    }
    Ok(surface)
}

/// An error unless the offset lies in (0, [`MAX_REAR_WALL_OFFSET_MM`]] (NaN included).
fn check_rear_wall_offset(rear_wall_offset_mm: f64) -> Result<(), ClosedSurfaceError> {
    if rear_wall_offset_mm > 0.0 && rear_wall_offset_mm <= MAX_REAR_WALL_OFFSET_MM {
        Ok(())
    } else {
        Err(ClosedSurfaceError::InvalidInput(format!(
            "the rear-wall offset must lie between 0 and {MAX_REAR_WALL_OFFSET_MM} mm (the \
             chest wall lies some 10 to 30 mm behind the breast's base), got \
             {rear_wall_offset_mm}"
        )))
    }
}

/// The points of `filled_base` that are not points of `scan`: where the base was cut and
/// filled, the breasts' footprints (the fill-ins and the cut curves). Empty if more than
/// half of the base differs (then it is not the scan with the breasts filled in).
fn footprint_points(scan: &TriMesh, filled_base: &TriMesh) -> Vec<DVec3> {
    let key = |p: &DVec3| p.to_array().map(f64::to_bits);
    let on_scan: std::collections::HashSet<[u64; 3]> = scan.positions.iter().map(key).collect();
    let differing: Vec<DVec3> = filled_base
        .positions
        .iter()
        .filter(|p| !on_scan.contains(&key(p)))
        .copied()
        .collect();
    if 2 * differing.len() > filled_base.positions.len() {
        Vec::new()
    } else {
        differing
    }
}

/// Clips `scan` and `filled_base` (both open, with the same outer border region) by
/// `clip_box`, shifts the base back by `rear_wall_offset_mm` along the frame's posterior
/// axis and stitches the two into a closed surface (see the module docs).
pub fn build_closed_surface_in_box(
    scan: &TriMesh,
    filled_base: &TriMesh,
    frame: &AnatomicalFrame,
    clip_box: &ClipBox,
    rear_wall_offset_mm: f64,
) -> Result<ClosedSurface, ClosedSurfaceError> {
    clip_box.check()?;
    check_rear_wall_offset(rear_wall_offset_mm)?;
    let mut front = ClippedPart::new(scan, SurfaceRole::Scan, frame, clip_box)?;
    let mut back = ClippedPart::new(filled_base, SurfaceRole::FilledBase, frame, clip_box)?;
    for p in &mut back.positions {
        p.z -= rear_wall_offset_mm;
    }
    if front.anterior_area() < 0.0 {
        front.reverse();
    }
    let clearance_mm = WALL_CLEARANCE_FRACTION * rear_wall_offset_mm;
    let too_close = back.keep_clear_of(&front, clearance_mm);
    // The wall's border must run against the scan's around the box; then walk the
    // wall's border in the scan's direction.
    if (front.winding() > 0.0) == (back.winding() > 0.0) {
        back.reverse();
    }
    back.border.reverse();
    let front_sides = front.sides()?;
    let back_sides = back.sides()?;

    let offset = front.positions.len() as u32;
    let mut positions = front.positions;
    positions.extend(&back.positions);
    let mut triangles = front.triangles;
    let front_range = 0..triangles.len();
    triangles.extend(back.triangles.iter().map(|t| t.map(|v| v + offset)));
    let back_range = front_range.end..triangles.len();
    let to_file = |p: DVec3| frame.to_file(clip_box.box_to_local(p)).to_array();
    triangles.extend(bands(
        &positions,
        &front_sides,
        &back_sides,
        offset,
        to_file,
    )?);
    let band_range = back_range.end..triangles.len();

    let mut mesh = TriMesh::new(
        positions
            .iter()
            .map(|&p| frame.to_file(clip_box.box_to_local(p)))
            .collect(),
        triangles,
    );
    let topology = Topology::new(&mesh);
    let report = manifold_report(&mesh, &topology);
    if !report.is_watertight_manifold() {
        return Err(ClosedSurfaceError::NotWatertight(report));
    }
    // Scanner noise may fold a few tiny triangles of the scan through each other, and
    // the wall (the filled base moved back) carries any small fold of the base, where a
    // breast's fill-in meets a filled scan hole beside the cut curve. The inner vertices
    // of the scan and of the wall move, by at most [`MAX_UNTANGLE_MM`]; the borders on
    // the clip planes and the band stay as built, and a real crossing of wall and scan
    // stays an error.
    let mut on_border = vec![false; positions.len()];
    for side in &front_sides {
        for &v in &side.chain {
            on_border[v as usize] = true;
        }
    }
    for side in &back_sides {
        for &v in &side.chain {
            on_border[(v + offset) as usize] = true;
        }
    }
    let mut warnings = Vec::new();
    if too_close > 0 {
        warnings.push(format!(
            "{too_close} vertices of the rear wall stay less than {clearance_mm:.1} mm behind \
             the scan"
        ));
    }
    let scan_only = |t: usize| front_range.contains(&t);
    let crossings = match untangle(&mut mesh, |v| !on_border[v as usize], MAX_UNTANGLE_MM) {
        Ok(None) => Vec::new(),
        Ok(Some(done)) => {
            warnings.push(format!(
                "the scan or the wall behind it folds through itself in {} places near \
                 ({:.0}, {:.0}, {:.0}) mm (scanner noise, or a fill-in meeting a filled hole); \
                 smoothed there, moving {} vertices by at most {:.2} mm (at most \
                 {MAX_UNTANGLE_MM} mm allowed)",
                done.pairs_found,
                done.near.x,
                done.near.y,
                done.near.z,
                done.vertices_moved,
                done.max_displacement_mm
            ));
            Vec::new()
        }
        Err(pairs) => pairs,
    };
    // Name the worst kind of crossing: the wall through the skin before a fold of either.
    let first = crossings
        .iter()
        .find(|&&(a, b)| scan_only(a) != scan_only(b))
        .or(crossings.first());
    if let Some(&(a, b)) = first {
        let centre = |t: usize| mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
        let what = match (scan_only(a), scan_only(b)) {
            (true, true) => "the skin folds through itself",
            (false, false) => "the rebuilt chest wall folds through itself",
            _ => "the chest wall rebuilt behind the breasts crosses the skin",
        };
        return Err(ClosedSurfaceError::SelfIntersecting {
            count: crossings.len(),
            what,
            near_mm: (0.5 * (centre(a) + centre(b))).to_array(),
        });
    }
    let volume_ml = mesh.signed_volume() / 1000.0;
    let wall_behind_scan = volume_ml > 0.0;
    if !wall_behind_scan {
        return Err(ClosedSurfaceError::WallInFront { volume_ml });
    }
    Ok(ClosedSurface {
        mesh,
        volume_ml,
        front: front_range,
        back_wall: back_range,
        band: band_range,
        clip_box: *clip_box,
        rear_wall_offset_mm,
        lateral_room_mm: None,
        warnings,
    })
}

#[cfg(test)]
mod tests;
