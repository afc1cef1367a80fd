//! The closed surface (paper IV-C, Fig. 4 d-e): the scan and the filled base clipped by
//! four planes around the breasts, the base shifted posteriorly to the chest wall, and
//! the two clipped borders stitched by a band of triangles. The result bounds the volume
//! the finite elements fill.
//!
//! # Algorithm
//! 1. The clip box ([`ClipBox::around_breasts_and_footprints`]): top and bottom planes
//!    orthogonal to the frame's y axis, from the clavicles and the folds; two lateral
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
//!    exactly, a vertex within a small snap distance is moved onto it, so no slivers),
//!    keeping the inside. Only the largest connected piece is kept (drops specks).
//!    Where a plane grazes a bump (a breast's lateral side), the bump's cut-off tip
//!    leaves a small border cycle entirely on that plane; it is closed by a flat cap.
//!    The border must then be a single loop lying on the planes, with one corner vertex on
//!    each of the four plane intersections; a loop off the planes means the box reaches
//!    beyond the surface's border, a further loop a hole inside the box.
//! 3. The clipped base is translated by the rear-wall offset along the posterior axis
//!    (`-z` of the frame), the paper's "shifted towards the back"; a translation keeps
//!    its border on the same four planes. Where the scan runs almost parallel to that
//!    axis (the underside of a hanging breast), the translated wall stays too close to
//!    it; there its vertices are pushed further in along the scan's inward normal until
//!    they lie a fifth of the offset behind it (`wall_clearance.rs`). Its
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
//!    ([`mesh::self_intersections`]; sub-millimetre folds of the scan's own noise are
//!    smoothed out first, [`mesh::untangle`], with a warning), and a positive volume
//!    (else the wall lies in front of the scan).
//! 6. If clipping or stitching fails, [`build_closed_surface`] retries with the lateral
//!    planes further in, a few times, then with the upright box of earlier versions
//!    (see there).
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
//!   the scan at every height of the box. On the phantom and the shared scans the
//!   breasts reach to within a few millimetres of the torso's silhouette, so the planes
//!   still cut 8 to 17 mm off the lateral edge of each footprint (it was 20 to 30 mm with
//!   upright planes); see the warnings. A curved lateral boundary following the outline
//!   would gain a few millimetres more.

use crate::fill_in::inside_polygon;
use crate::frame::AnatomicalFrame;
use crate::landmarks::{LandmarkName, Landmarks};
use crate::wall_clearance::{FixedAxes, keep_wall_clear};
use glam::{DVec2, DVec3};
use mesh::{ManifoldReport, MeshError, Topology, TriMesh, manifold_report, untangle};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};
use std::collections::HashMap;
use std::ops::Range;

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
/// The landmarks the clip box must contain. The lateral fold ends PSMFll and PSMFlr are
/// not among them: on a torso scanned round to the side they may lie beyond the scan's
/// silhouette at the waist, so no lateral plane inside the scan can keep them.
const BREAST_LANDMARKS: [LandmarkName; 6] = [
    LandmarkName::Pnl,
    LandmarkName::Pnr,
    LandmarkName::PSMFl,
    LandmarkName::PSMFr,
    LandmarkName::PSMFml,
    LandmarkName::PSMFmr,
];
/// Further attempts of [`build_closed_surface`] after a failed clip or stitch, each with
/// the lateral planes [`RETRY_STEP_MM`] further in.
const LATERAL_RETRIES: usize = 4;
/// See [`LATERAL_RETRIES`] (mm).
const RETRY_STEP_MM: f64 = 1.0;
/// Attempts with the box fitted to the footprints, each [`FITTED_RETRY_STEP_MM`] further
/// in, before [`build_closed_surface`] falls back to the upright box.
const FITTED_RETRIES: usize = 5;
/// See [`FITTED_RETRIES`] (mm).
const FITTED_RETRY_STEP_MM: f64 = 2.0;
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
const WALL_CLEARANCE_FRACTION: f64 = 0.2;
/// Vertices closer to a clip plane than this fraction of the mean edge length are moved
/// onto it (at most 2% of an edge, about 0.05 mm on a scan), so clipping leaves no
/// sliver triangles.
const SNAP_FRACTION: f64 = 0.02;

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
    /// inside the waist. Default `false` for now: it keeps 8 to 14 mm more of each
    /// breast's lateral side, but the simulation's phantom tests then see 2 inverted
    /// elements and a slower solve near the lateral clip faces (to be resolved there).
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
            fit_lateral_planes: false,
        }
    }
}

/// The four clip planes in the anatomical frame (mm). Top and bottom are `y = y_max_mm`
/// and `y = y_min_mm`. The lateral planes are parallel to the frame's z axis and may
/// lean in the coronal plane (to follow a torso narrower at the waist than across the
/// breasts): the patient's right plane is `x = x_min_mm + x_min_slope * (y - y_ref_mm)`,
/// the left one `x = x_max_mm + x_max_slope * (y - y_ref_mm)`; so `x_min_mm` and
/// `x_max_mm` are the planes' positions at the height `y_ref_mm` (the nipples' height
/// for [`ClipBox::around_breasts`]). Slopes 0 give the upright box. The part kept lies
/// between the four.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ClipBox {
    pub x_min_mm: f64,
    pub x_max_mm: f64,
    pub y_min_mm: f64,
    pub y_max_mm: f64,
    /// dx/dy of the right (`x_min`) plane.
    pub x_min_slope: f64,
    /// dx/dy of the left (`x_max`) plane.
    pub x_max_slope: f64,
    /// The height at which the lateral planes lie at `x_min_mm` and `x_max_mm` (mm).
    pub y_ref_mm: f64,
}

/// A clip box with how well it holds the breasts ([`ClipBox::around_breasts_and_footprints`]).
#[derive(Debug, Clone, PartialEq)]
pub struct ClipBoxFit {
    pub clip_box: ClipBox,
    /// How far the right and the left plane lie beyond the footprints (mm), negative
    /// where they cut them.
    pub lateral_room_mm: [f64; 2],
    /// Footprints the scan leaves too little room for.
    pub warnings: Vec<String>,
}

/// A lateral plane `x <= offset + slope (y - y_ref)` (mirrored for the right one) and its
/// least distance beyond the points it keeps.
#[derive(Debug, Clone, Copy)]
struct LateralFit {
    offset: f64,
    slope: f64,
    room: f64,
}

/// Steepest lean of a lateral plane (dx/dy): a torso's side narrows by some 20 to 30 mm
/// from the breasts to the waist, about 0.2.
const MAX_LATERAL_SLOPE: f64 = 0.6;
/// Step of the search over the lean.
const LATERAL_SLOPE_STEP: f64 = 0.002;

/// The lateral plane that lies `clearance` inside the scan's outline (`limits`: heights
/// and the outline's largest x there) and as far beyond the least-kept of `points`
/// (height, x) as it can: a two-variable linear programme, solved by a search over the
/// slope (the best offset of a slope is a minimum over the limits, the room a concave
/// function of the slope). Ties go to the more upright plane.
fn fit_lateral_plane(
    limits: &[(f64, f64)],
    points: &[(f64, f64)],
    y_ref: f64,
    clearance: f64,
) -> LateralFit {
    let steps = (MAX_LATERAL_SLOPE / LATERAL_SLOPE_STEP).round() as i64;
    let mut best: Option<LateralFit> = None;
    for k in 0..=2 * steps {
        // 0, +1, -1, +2, -2, ...: the upright plane first.
        let j = if k % 2 == 1 { (k + 1) / 2 } else { -(k / 2) };
        let slope = j as f64 * LATERAL_SLOPE_STEP;
        let offset = limits
            .iter()
            .map(|&(y, hi)| hi - clearance - slope * (y - y_ref))
            .fold(f64::INFINITY, f64::min);
        if !offset.is_finite() {
            continue;
        }
        let room = points
            .iter()
            .map(|&(y, x)| offset + slope * (y - y_ref) - x)
            .fold(f64::INFINITY, f64::min);
        if best.is_none_or(|b| room > b.room + 1e-9) {
            best = Some(LateralFit {
                offset,
                slope,
                room,
            });
        }
    }
    best.unwrap_or(LateralFit {
        offset: f64::INFINITY,
        slope: 0.0,
        room: f64::INFINITY,
    })
}

/// The x-extent of `points` (frame coordinates) in bins of [`EXTENT_BIN_MM`] of height
/// over `[lo, hi]`: for each non-empty bin, both its edges' heights with the bin's
/// smallest and largest x.
fn outline_by_height(points: &[DVec3], lo: f64, hi: f64) -> Vec<(f64, f64, f64)> {
    let bins = ((hi - lo) / EXTENT_BIN_MM).ceil().clamp(1.0, 1e6) as usize;
    let mut ranges = vec![(f64::INFINITY, f64::NEG_INFINITY); bins];
    for p in points.iter().filter(|p| (lo..=hi).contains(&p.y)) {
        let bin = (((p.y - lo) / EXTENT_BIN_MM) as usize).min(bins - 1);
        let range = &mut ranges[bin];
        *range = (range.0.min(p.x), range.1.max(p.x));
    }
    ranges
        .iter()
        .enumerate()
        .filter(|(_, r)| r.0 <= r.1)
        .flat_map(|(bin, r)| {
            let y0 = lo + bin as f64 * EXTENT_BIN_MM;
            let y1 = (y0 + EXTENT_BIN_MM).min(hi);
            [(y0, r.0, r.1), (y1, r.0, r.1)]
        })
        .collect()
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
        "closed surface: the clipped {role}'s border meets the plane intersections in \
         {corners} corners instead of one on each of the four"
    )]
    MissingCorners { role: SurfaceRole, corners: usize },
    #[error("closed surface: the scan's and the filled base's borders cannot be stitched: {0}")]
    Stitch(String),
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
    /// Triangles of the clipped, shifted filled base (facing posteriorly): the wall the
    /// implant sits on.
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

impl ClipBox {
    /// [`ClipBox::around_breasts_and_footprints`] without fill-ins: the lateral fold ends
    /// stand for the breasts' lateral extent.
    pub fn around_breasts(
        scan: &TriMesh,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
        options: &ClosedSurfaceOptions,
    ) -> Result<ClipBox, ClosedSurfaceError> {
        Self::around_breasts_and_footprints(scan, frame, landmarks, &[], options)
            .map(|fit| fit.clip_box)
    }

    /// The planes from the landmarks, the breast footprints and the margins of
    /// `options`, kept the clearance inside the scan's extent:
    /// 1. top and bottom from the clavicles and the folds' lowest points;
    /// 2. each lateral plane, leaning as the torso's side does, as far beyond the
    ///    footprints (`footprints`, file coordinates: the fill-ins' points; the lateral
    ///    fold ends and the breast landmarks always count) as the scan allows: it stays
    ///    `border_clearance_mm` inside the scan's outline at every height of the box, down
    ///    to `min_border_clearance_mm` if the footprint would otherwise come closer than
    ///    [`LANDMARK_MARGIN_MM`] to it, and at most `lateral_margin_mm` beyond the
    ///    footprint. Where even then the scan ends too close beyond a breast, a warning
    ///    says by how much the footprint is cut;
    /// 3. top and bottom moved inside the scan's highest and lowest point at every x
    ///    of the box.
    ///
    /// An error if a nipple or a fold's lowest point or medial end ends up outside.
    pub fn around_breasts_and_footprints(
        scan: &TriMesh,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
        footprints: &[DVec3],
        options: &ClosedSurfaceOptions,
    ) -> Result<ClipBoxFit, ClosedSurfaceError> {
        let margins = [
            ("top_margin_mm", options.top_margin_mm),
            ("bottom_margin_mm", options.bottom_margin_mm),
            ("lateral_margin_mm", options.lateral_margin_mm),
            ("border_clearance_mm", options.border_clearance_mm),
            ("min_border_clearance_mm", options.min_border_clearance_mm),
        ];
        if let Some((name, value)) = margins.iter().find(|(_, v)| !v.is_finite()) {
            return Err(ClosedSurfaceError::InvalidInput(format!(
                "{name} must be a finite number, got {value}"
            )));
        }
        let local = |name: LandmarkName| frame.to_local(landmarks.get(name));
        let mut clip_box = ClipBox {
            y_ref_mm: 0.5 * (local(LandmarkName::Pnl).y + local(LandmarkName::Pnr).y),
            ..landmark_box(frame, landmarks, options)
        };
        clip_box.check()?;

        let clearance = options.border_clearance_mm.max(0.0);
        let min_clearance = options.min_border_clearance_mm.clamp(0.0, clearance);
        let local_scan: Vec<DVec3> = scan.positions.iter().map(|&p| frame.to_local(p)).collect();
        // The scan's outline at every height of the box.
        let outline = outline_by_height(&local_scan, clip_box.y_min_mm, clip_box.y_max_mm);
        // The points each lateral plane should keep inside: the footprints, the lateral
        // fold ends and the breast landmarks.
        let mut keep: Vec<DVec3> = footprints.iter().map(|&p| frame.to_local(p)).collect();
        keep.extend(
            BREAST_LANDMARKS
                .iter()
                .chain(&[LandmarkName::PSMFll, LandmarkName::PSMFlr])
                .map(|&name| local(name)),
        );
        let keep: Vec<DVec3> = keep
            .into_iter()
            .filter(|p| (clip_box.y_min_mm..=clip_box.y_max_mm).contains(&p.y))
            .collect();
        let mut room = [0.0; 2];
        let mut warnings = Vec::new();
        for (k, sign) in [(0usize, -1.0), (1, 1.0)] {
            // Mirrored for the right plane, so both are "x <= a + s (y - y_ref)".
            let limits: Vec<(f64, f64)> = outline
                .iter()
                .map(|&(y, lo, hi)| (y, if sign > 0.0 { hi } else { -lo }))
                .collect();
            let points: Vec<(f64, f64)> = keep.iter().map(|p| (p.y, sign * p.x)).collect();
            let mut fit = fit_lateral_plane(&limits, &points, clip_box.y_ref_mm, clearance);
            if fit.room < LANDMARK_MARGIN_MM && min_clearance < clearance {
                let closer = fit_lateral_plane(&limits, &points, clip_box.y_ref_mm, min_clearance);
                let needed = LANDMARK_MARGIN_MM - fit.room;
                // Only as much closer to the scan's border as the footprint needs.
                let shift = needed.min(closer.room - fit.room).max(0.0);
                fit = if closer.room > fit.room {
                    let t = shift / (closer.room - fit.room);
                    LateralFit {
                        offset: fit.offset + t * (closer.offset - fit.offset),
                        slope: fit.slope + t * (closer.slope - fit.slope),
                        room: fit.room + shift,
                    }
                } else {
                    fit
                };
            }
            if fit.room > options.lateral_margin_mm {
                fit.offset -= fit.room - options.lateral_margin_mm;
                fit.room = options.lateral_margin_mm;
            }
            room[k] = fit.room;
            if fit.room < LANDMARK_MARGIN_MM {
                warnings.push(format!(
                    "the scan ends close beyond the {} breast: kept {min_clearance} mm inside \
                     the scan's outline, the {} clip plane lies {:.1} mm beyond the breast's \
                     footprint (wanted {LANDMARK_MARGIN_MM} mm){}",
                    ["right", "left"][k],
                    ["right", "left"][k],
                    fit.room,
                    if fit.room < 0.0 {
                        ", so it cuts off part of it"
                    } else {
                        ""
                    }
                ));
            }
            if sign > 0.0 {
                clip_box.x_max_mm = fit.offset;
                clip_box.x_max_slope = fit.slope;
            } else {
                clip_box.x_min_mm = -fit.offset;
                clip_box.x_min_slope = -fit.slope;
            }
        }
        clip_box.check()?;
        // Top and bottom inside the scan's height at every x of the box (in the box's
        // coordinates, where the lateral planes are upright).
        let boxed: Vec<DVec3> = local_scan.iter().map(|&p| clip_box.to_box(p)).collect();
        let (y_min, y_max) = extent_limits(&boxed, 0, clip_box.x_min_mm, clip_box.x_max_mm, 1);
        clip_box.y_min_mm = clip_box.y_min_mm.max(y_min + clearance);
        clip_box.y_max_mm = clip_box.y_max_mm.min(y_max - clearance);
        clip_box.check()?;

        if let Some(name) = clip_box.left_out(frame, landmarks) {
            return Err(ClosedSurfaceError::InvalidInput(format!(
                "the scan does not extend {min_clearance} mm beyond the breasts: kept clear of \
                 its border, the clip box (x {:.1} to {:.1} mm at y {:.1}, y {:.1} to {:.1} mm \
                 in the anatomical frame) leaves out landmark {}",
                clip_box.x_min_mm,
                clip_box.x_max_mm,
                clip_box.y_ref_mm,
                clip_box.y_min_mm,
                clip_box.y_max_mm,
                name.as_str()
            )));
        }
        Ok(ClipBoxFit {
            clip_box,
            lateral_room_mm: room,
            warnings,
        })
    }

    /// The right plane's x at height `y` (mm).
    pub fn x_min_at(&self, y: f64) -> f64 {
        self.x_min_mm + self.x_min_slope * (y - self.y_ref_mm)
    }

    /// The left plane's x at height `y` (mm).
    pub fn x_max_at(&self, y: f64) -> f64 {
        self.x_max_mm + self.x_max_slope * (y - self.y_ref_mm)
    }

    /// Frame coordinates to the box's: `x` mapped affinely at each height so that the
    /// lateral planes become `x = x_min_mm` and `x = x_max_mm` (heights outside the box
    /// use its top or bottom row, so the map stays one-to-one and continuous); `y` and
    /// `z` unchanged. The identity for an upright box.
    fn to_box(self, p: DVec3) -> DVec3 {
        if self.x_min_slope == 0.0 && self.x_max_slope == 0.0 {
            return p;
        }
        let y = p.y.clamp(self.y_min_mm, self.y_max_mm);
        let (lo, hi) = (self.x_min_at(y), self.x_max_at(y));
        let x = self.x_min_mm + (p.x - lo) * (self.x_max_mm - self.x_min_mm) / (hi - lo);
        DVec3::new(x, p.y, p.z)
    }

    /// The inverse of [`ClipBox::to_box`].
    fn box_to_local(self, p: DVec3) -> DVec3 {
        if self.x_min_slope == 0.0 && self.x_max_slope == 0.0 {
            return p;
        }
        let y = p.y.clamp(self.y_min_mm, self.y_max_mm);
        let (lo, hi) = (self.x_min_at(y), self.x_max_at(y));
        let x = lo + (p.x - self.x_min_mm) * (hi - lo) / (self.x_max_mm - self.x_min_mm);
        DVec3::new(x, p.y, p.z)
    }

    /// The first of [`BREAST_LANDMARKS`] outside the box, if any.
    fn left_out(&self, frame: &AnatomicalFrame, landmarks: &Landmarks) -> Option<LandmarkName> {
        BREAST_LANDMARKS
            .into_iter()
            .find(|&name| !self.contains(frame.to_local(landmarks.get(name))))
    }

    fn check(&self) -> Result<(), ClosedSurfaceError> {
        let ordered = self.y_min_mm < self.y_max_mm
            && self.x_min_at(self.y_min_mm) < self.x_max_at(self.y_min_mm)
            && self.x_min_at(self.y_max_mm) < self.x_max_at(self.y_max_mm)
            && self.x_min_mm < self.x_max_mm;
        let finite = [
            self.x_min_mm,
            self.x_max_mm,
            self.y_min_mm,
            self.y_max_mm,
            self.x_min_slope,
            self.x_max_slope,
            self.y_ref_mm,
        ]
        .iter()
        .all(|v| v.is_finite());
        if ordered && finite {
            Ok(())
        } else {
            Err(ClosedSurfaceError::InvalidInput(format!(
                "empty clip box: x {} to {} mm, y {} to {} mm in the anatomical frame",
                self.x_min_mm, self.x_max_mm, self.y_min_mm, self.y_max_mm
            )))
        }
    }

    /// Whether a point (frame coordinates) lies inside the box.
    pub fn contains(&self, local: DVec3) -> bool {
        (self.y_min_mm..=self.y_max_mm).contains(&local.y)
            && (self.x_min_at(local.y)..=self.x_max_at(local.y)).contains(&local.x)
    }

    /// The four planes as (axis, coordinate, keep-the-side-above).
    fn planes(&self) -> [ClipPlane; 4] {
        [
            ClipPlane {
                axis: 0,
                value: self.x_min_mm,
                keep_above: true,
            },
            ClipPlane {
                axis: 0,
                value: self.x_max_mm,
                keep_above: false,
            },
            ClipPlane {
                axis: 1,
                value: self.y_min_mm,
                keep_above: true,
            },
            ClipPlane {
                axis: 1,
                value: self.y_max_mm,
                keep_above: false,
            },
        ]
    }
}

/// The clip box from the landmarks ([`ClipBox::around_breasts`]), then
/// [`build_closed_surface_in_box`].
///
/// A lateral plane that meets the side of the chest almost tangentially (below a large
/// breast, where the surface runs nearly along the plane) can leave the shifted wall
/// touching the band or the scan's cut curve crossing the wall's; a millimetre further
/// in, the same surface usually closes. So if the clip or the stitch fails, the build is
/// tried again with both lateral planes [`RETRY_STEP_MM`] further in, up to
/// [`LATERAL_RETRIES`] times while the box keeps the breast landmarks; the error is the
/// first attempt's.
pub fn build_closed_surface(
    scan: &TriMesh,
    filled_base: &TriMesh,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &ClosedSurfaceOptions,
) -> Result<ClosedSurface, ClosedSurfaceError> {
    // The box follows the thorax (the body's axes), not the way she stood.
    let frame = &frame.sternal();
    let footprints = footprint_points(scan, filled_base);
    let mut first_error = None;
    // The fitted box if asked for, then (should it not close) the upright one.
    let mut boxes = Vec::new();
    if options.fit_lateral_planes {
        match ClipBox::around_breasts_and_footprints(scan, frame, landmarks, &footprints, options) {
            Ok(fit) => boxes.push((fit.clip_box, true)),
            Err(error) => first_error = Some(error),
        }
    }
    match upright_box(scan, frame, landmarks, options) {
        Ok(upright) => boxes.push((upright, false)),
        Err(error) => {
            if boxes.is_empty() {
                return Err(first_error.unwrap_or(error));
            }
        }
    }
    for (start, fitted) in boxes {
        let mut clip_box = start;
        // The fitted box may cut a footprint where the fill-in bows out of the body;
        // it gets more and larger steps inwards before the upright box is tried.
        let (retries, step) = if fitted {
            (FITTED_RETRIES, FITTED_RETRY_STEP_MM)
        } else {
            (LATERAL_RETRIES, RETRY_STEP_MM)
        };
        for _ in 0..=retries {
            let error =
                match build_closed_surface_in_box(
                    scan,
                    filled_base,
                    frame,
                    &clip_box,
                    options.rear_wall_offset_mm,
                ) {
                    Ok(mut surface) => {
                        let keep: Vec<DVec3> =
                            footprints.iter().map(|&p| frame.to_local(p)).collect();
                        let room = lateral_room(&clip_box, &keep, frame, landmarks);
                        surface.lateral_room_mm = Some(room);
                        for (k, side) in ["right", "left"].into_iter().enumerate() {
                            if room[k] < LANDMARK_MARGIN_MM {
                                surface.warnings.push(format!(
                                "the {side} clip plane lies {:.1} mm beyond the {side} breast's \
                                 footprint (wanted {LANDMARK_MARGIN_MM} mm){}: the scan ends \
                                 close beyond the breast",
                                room[k],
                                if room[k] < 0.0 { ", so it cuts off part of it" } else { "" }
                            ));
                            }
                        }
                        let moved = clip_box.x_min_mm - start.x_min_mm;
                        if fitted && moved > 0.0 {
                            surface.warnings.push(format!(
                                "the lateral clip planes were moved {moved:.0} mm inwards for the \
                             surface to close; they now lie {:.1} and {:.1} mm beyond the \
                             right and left footprints",
                                room[0], room[1]
                            ));
                        }
                        if !fitted && options.fit_lateral_planes {
                            surface.warnings.push(format!(
                                "the clip box fitted to the breasts could not be closed ({}); \
                             used the upright box, which lies {:.1} and {:.1} mm beyond the \
                             right and left footprints",
                                first_error
                                    .as_ref()
                                    .map_or(String::new(), |e| format!("{e}")),
                                room[0],
                                room[1]
                            ));
                        }
                        return Ok(surface);
                    }
                    Err(error) => error,
                };
            let retry = matches!(
                error,
                ClosedSurfaceError::RunsOffBorder { .. }
                    | ClosedSurfaceError::MissingCorners { .. }
                    | ClosedSurfaceError::Stitch(_)
                    | ClosedSurfaceError::NotWatertight(_)
                    | ClosedSurfaceError::SelfIntersecting { .. }
            );
            if first_error.is_none() {
                first_error = Some(error);
            }
            if !retry {
                break;
            }
            clip_box.x_min_mm += step;
            clip_box.x_max_mm -= step;
            if clip_box.left_out(frame, landmarks).is_some() || clip_box.check().is_err() {
                break;
            }
        }
    }
    Err(first_error.expect("at least one attempt"))
}

/// How far the right and left planes of `clip_box` lie beyond `footprint` (frame
/// coordinates) and the lateral fold ends, at the points' heights inside the box (mm).
fn lateral_room(
    clip_box: &ClipBox,
    footprint: &[DVec3],
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
) -> [f64; 2] {
    let ends =
        [LandmarkName::PSMFll, LandmarkName::PSMFlr].map(|n| frame.to_local(landmarks.get(n)));
    let inside = footprint
        .iter()
        .chain(&ends)
        .filter(|p| (clip_box.y_min_mm..=clip_box.y_max_mm).contains(&p.y));
    inside.fold([f64::INFINITY; 2], |[right, left], p| {
        [
            right.min(p.x - clip_box.x_min_at(p.y)),
            left.min(clip_box.x_max_at(p.y) - p.x),
        ]
    })
}

/// The upright box from the landmarks and margins alone (before any plane is moved to
/// stay inside the scan): lateral planes beyond the fold ends, bottom below the lower
/// fold point, top at the clavicles.
fn landmark_box(
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &ClosedSurfaceOptions,
) -> ClipBox {
    let local = |name: LandmarkName| frame.to_local(landmarks.get(name));
    ClipBox {
        x_min_mm: local(LandmarkName::PSMFlr).x - options.lateral_margin_mm,
        x_max_mm: local(LandmarkName::PSMFll).x + options.lateral_margin_mm,
        y_min_mm: local(LandmarkName::PSMFl)
            .y
            .min(local(LandmarkName::PSMFr).y)
            - options.bottom_margin_mm,
        y_max_mm: local(LandmarkName::Pcl).y.max(local(LandmarkName::Pcr).y)
            + options.top_margin_mm,
        ..ClipBox::default()
    }
}
/// The upright box of earlier versions, the fallback of [`build_closed_surface`] where the
/// fitted one cannot be closed: the lateral planes `lateral_margin_mm` beyond the lateral
/// fold ends, moved inwards to stay the clearance inside the scan's narrowest width over
/// the box's heights (less where the breast landmarks need it).
fn upright_box(
    scan: &TriMesh,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &ClosedSurfaceOptions,
) -> Result<ClipBox, ClosedSurfaceError> {
    let mut clip_box = landmark_box(frame, landmarks, options);
    clip_box.check()?;
    let clearance = options.border_clearance_mm.max(0.0);
    let min_clearance = options.min_border_clearance_mm.clamp(0.0, clearance);
    let landmark_x = BREAST_LANDMARKS.map(|name| frame.to_local(landmarks.get(name)).x);
    let needed_x_min = landmark_x.iter().fold(f64::INFINITY, |a, &b| a.min(b)) - LANDMARK_MARGIN_MM;
    let needed_x_max =
        landmark_x.iter().fold(f64::NEG_INFINITY, |a, &b| a.max(b)) + LANDMARK_MARGIN_MM;
    let local_scan: Vec<DVec3> = scan.positions.iter().map(|&p| frame.to_local(p)).collect();
    // Lateral planes inside the scan's width at every height of the box (by the
    // clearance, less where the landmarks need it), then top and bottom inside its
    // height at every x of the narrowed box.
    let (x_min, x_max) = extent_limits(&local_scan, 1, clip_box.y_min_mm, clip_box.y_max_mm, 0);
    clip_box.x_min_mm = clip_box
        .x_min_mm
        .max((x_min + clearance).min(needed_x_min))
        .max(x_min + min_clearance);
    clip_box.x_max_mm = clip_box
        .x_max_mm
        .min((x_max - clearance).max(needed_x_max))
        .min(x_max - min_clearance);
    let (y_min, y_max) = extent_limits(&local_scan, 0, clip_box.x_min_mm, clip_box.x_max_mm, 1);
    clip_box.y_min_mm = clip_box.y_min_mm.max(y_min + clearance);
    clip_box.y_max_mm = clip_box.y_max_mm.min(y_max - clearance);
    clip_box.check()?;
    if let Some(name) = clip_box.left_out(frame, landmarks) {
        return Err(ClosedSurfaceError::InvalidInput(format!(
            "the scan does not extend {min_clearance} mm beyond the breasts: kept clear of \
             its border, the clip box (x {:.1} to {:.1} mm, y {:.1} to {:.1} mm in the \
             anatomical frame) leaves out landmark {}",
            clip_box.x_min_mm,
            clip_box.x_max_mm,
            clip_box.y_min_mm,
            clip_box.y_max_mm,
            name.as_str()
        )));
    }
    Ok(clip_box)
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
    if !(rear_wall_offset_mm > 0.0 && rear_wall_offset_mm <= MAX_REAR_WALL_OFFSET_MM) {
        return Err(ClosedSurfaceError::InvalidInput(format!(
            "the rear-wall offset must lie between 0 and {MAX_REAR_WALL_OFFSET_MM} mm (the \
             chest wall lies some 10 to 30 mm behind the breast's base), got \
             {rear_wall_offset_mm}"
        )));
    }
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
    for (front_side, back_side) in front_sides.iter().zip(&back_sides) {
        let back_chain: Vec<u32> = back_side.chain.iter().map(|&v| v + offset).collect();
        let same_corner = |f: Option<&u32>, b: Option<&u32>| match (f, b) {
            (Some(&f), Some(&b)) => {
                let (p, q) = (positions[f as usize], positions[b as usize]);
                p.x == q.x && p.y == q.y
            }
            _ => false,
        };
        if !same_corner(front_side.chain.first(), back_chain.first())
            || !same_corner(front_side.chain.last(), back_chain.last())
        {
            return Err(ClosedSurfaceError::Stitch(format!(
                "the corners of the scan's and the wall's border differ on the {} plane",
                PLANE_NAMES[front_side.plane]
            )));
        }
        triangles.extend(band_on_side(
            &positions,
            front_side.plane,
            &front_side.chain,
            &back_chain,
        )?);
    }
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
    // Scanner noise may fold a few tiny triangles of the scan through each other; only
    // the scan's inner vertices move, by at most [`MAX_UNTANGLE_MM`], so the band and
    // the wall stay as built and a real crossing of wall and scan stays an error.
    let mut scan_border = vec![false; offset as usize];
    for side in &front_sides {
        for &v in &side.chain {
            scan_border[v as usize] = true;
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
    let crossings = match untangle(
        &mut mesh,
        |v| v < offset && !scan_border[v as usize],
        MAX_UNTANGLE_MM,
    ) {
        Ok(None) => Vec::new(),
        Ok(Some(done)) => {
            warnings.push(format!(
                "the scan folds through itself in {} places near ({:.0}, {:.0}, {:.0}) mm \
                 (scanner noise); smoothed there, moving {} vertices by at most {:.2} mm \
                 (at most {MAX_UNTANGLE_MM} mm allowed)",
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

/// A plane of the clip box: `axis` 0 (x) or 1 (y) of the frame; the kept side is
/// `coordinate >= value` if `keep_above`, else `<=`.
#[derive(Debug, Clone, Copy)]
struct ClipPlane {
    axis: usize,
    value: f64,
    keep_above: bool,
}

impl ClipPlane {
    /// Signed distance, positive on the kept side.
    fn distance(&self, p: DVec3) -> f64 {
        let d = p[self.axis] - self.value;
        if self.keep_above { d } else { -d }
    }
}

/// One side of a clipped border: the plane index into [`ClipBox::planes`] and the
/// border vertices on it from corner to corner, in the scan's border direction.
struct Side {
    plane: usize,
    chain: Vec<u32>,
}

/// A surface clipped to the box, in frame coordinates, with its single border loop.
struct ClippedPart {
    role: SurfaceRole,
    planes: [ClipPlane; 4],
    frame: AnatomicalFrame,
    clip_box: ClipBox,
    /// In the box's coordinates ([`ClipBox::to_box`]).
    positions: Vec<DVec3>,
    triangles: Vec<[u32; 3]>,
    /// Border vertices in the direction of the triangles' edges.
    border: Vec<u32>,
}

impl ClippedPart {
    fn new(
        surface: &TriMesh,
        role: SurfaceRole,
        frame: &AnatomicalFrame,
        clip_box: &ClipBox,
    ) -> Result<ClippedPart, ClosedSurfaceError> {
        surface
            .validate()
            .map_err(|source| ClosedSurfaceError::InvalidMesh { role, source })?;
        let mut positions: Vec<DVec3> = surface
            .positions
            .iter()
            .map(|&p| clip_box.to_box(frame.to_local(p)))
            .collect();
        let mut triangles = surface.triangles.clone();
        let snap = SNAP_FRACTION * surface.mean_edge_length();
        let planes = clip_box.planes();
        for plane in &planes {
            triangles = clip_by_plane(&mut positions, &triangles, plane, snap);
        }
        let (positions, triangles) = largest_piece(&positions, &triangles);
        if triangles.len() < MIN_CLIPPED_TRIANGLES {
            return Err(ClosedSurfaceError::TooFewTriangles {
                role,
                count: triangles.len(),
            });
        }
        let mut part = ClippedPart {
            role,
            planes,
            frame: *frame,
            clip_box: *clip_box,
            positions,
            triangles,
            border: Vec::new(),
        };
        part.cap_islands()?;
        part.border = part.single_border_loop()?;
        Ok(part)
    }

    fn to_file(&self, local: DVec3) -> [f64; 3] {
        self.frame
            .to_file(self.clip_box.box_to_local(local))
            .to_array()
    }

    /// Pushes this part's vertices (a wall) that lie less than `clearance_mm` behind
    /// `scan` (or in front of it) further in ([`keep_wall_clear`]); border vertices stay
    /// on their planes. Returns how many are still too close.
    fn keep_clear_of(&mut self, scan: &ClippedPart, clearance_mm: f64) -> usize {
        let scan_mesh = TriMesh::new(scan.positions.clone(), scan.triangles.clone());
        let mut wall = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let fixed: Vec<FixedAxes> = (0..self.positions.len() as u32)
            .map(|v| {
                let mask = self.plane_mask(v);
                let on_axis = |axis: usize| {
                    self.planes
                        .iter()
                        .enumerate()
                        .any(|(i, plane)| plane.axis == axis && mask & (1 << i) != 0)
                };
                FixedAxes {
                    x: on_axis(0),
                    y: on_axis(1),
                }
            })
            .collect();
        let done = keep_wall_clear(&scan_mesh, &mut wall, &fixed, clearance_mm);
        self.positions = wall.positions;
        done.still_too_close
    }

    /// Bit `i` set if vertex `v` lies on plane `i`.
    fn plane_mask(&self, v: u32) -> u8 {
        let p = self.positions[v as usize];
        self.planes
            .iter()
            .enumerate()
            .filter(|(_, plane)| p[plane.axis] == plane.value)
            .fold(0, |mask, (i, _)| mask | (1 << i))
    }

    /// Closes the holes a plane leaves where it grazes the surface: where a bump (a
    /// breast's lateral side, say) pokes through a plane by a little, clipping cuts its
    /// tip off and leaves a small border cycle lying entirely on that plane, apart from
    /// the main border or touching it at a vertex. The tip is replaced by its section, a
    /// flat cap on the plane (a constrained Delaunay triangulation of the cycle), as
    /// clipping a solid does. The cycle must enclose material (the skin's inside, behind
    /// the scan or in front of the filled base), so the cap faces out of the box; a
    /// cycle around air (a pocket) is an error.
    fn cap_islands(&mut self) -> Result<(), ClosedSurfaceError> {
        let mesh = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let loops = Topology::new(&mesh).boundary_loops(&mesh);
        // +1 if the triangles face away from the material: an anterior-facing scan, or
        // a posterior-facing base.
        let faces_anteriorly = self.anterior_area() > 0.0;
        let away_from_material = match (self.role, faces_anteriorly) {
            (SurfaceRole::Scan, true) | (SurfaceRole::FilledBase, false) => 1.0,
            _ => -1.0,
        };
        let mut caps = Vec::new();
        for island in loops.iter().flat_map(|walk| simple_cycles(walk)) {
            let on_all = island
                .iter()
                .fold(0b1111u8, |mask, &v| mask & self.plane_mask(v));
            if on_all == 0 || island.len() < 3 {
                continue;
            }
            let plane = on_all.trailing_zeros() as usize;
            let name = PLANE_NAMES[plane];
            let cap = triangulate_in_plane(&self.positions, plane, &island).map_err(|defect| {
                ClosedSurfaceError::Stitch(format!(
                    "where the {} grazes the {name} plane, its section {}",
                    self.role,
                    defect.describe("crosses itself", "touches itself")
                ))
            })?;
            let clip = self.planes[plane];
            let normal: f64 = cap
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|v| self.positions[v as usize]);
                    (b - a).cross(c - a)[clip.axis]
                })
                .sum();
            // Towards the clipped-away side, as the triangles face.
            let out_of_box = if clip.keep_above { -normal } else { normal };
            if out_of_box * away_from_material <= 0.0 {
                let center = island
                    .iter()
                    .map(|&v| self.positions[v as usize])
                    .sum::<DVec3>()
                    / island.len() as f64;
                let [x, y, z] = self.to_file(center);
                return Err(ClosedSurfaceError::Stitch(format!(
                    "the {} passes through the {name} plane around a pocket of air near \
                     ({x:.1}, {y:.1}, {z:.1}) mm; move the plane",
                    self.role
                )));
            }
            caps.extend(cap);
        }
        self.triangles.extend(caps);
        Ok(())
    }

    /// The border loop, which must be the only one and lie on the planes.
    fn single_border_loop(&self) -> Result<Vec<u32>, ClosedSurfaceError> {
        let mesh = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let loops = Topology::new(&mesh).boundary_loops(&mesh);
        let role = self.role;
        if let Some(hole) = loops
            .iter()
            .find(|l| l.iter().all(|&v| self.plane_mask(v) == 0))
        {
            let center = hole
                .iter()
                .map(|&v| self.positions[v as usize])
                .sum::<DVec3>()
                / hole.len() as f64;
            return Err(ClosedSurfaceError::HoleInsideBox {
                role,
                vertices: hole.len(),
                center_mm: self.to_file(center),
            });
        }
        // Every border edge must lie on one plane.
        for border in &loops {
            for (k, &a) in border.iter().enumerate() {
                let b = border[(k + 1) % border.len()];
                if self.plane_mask(a) & self.plane_mask(b) == 0 {
                    let middle = 0.5 * (self.positions[a as usize] + self.positions[b as usize]);
                    return Err(ClosedSurfaceError::RunsOffBorder {
                        role,
                        near_mm: self.to_file(middle),
                    });
                }
            }
        }
        match <[Vec<u32>; 1]>::try_from(loops) {
            Ok([border]) => Ok(border),
            Err(loops) => Err(ClosedSurfaceError::Stitch(format!(
                "the clipped {role} has {} border loops on the planes instead of one",
                loops.len()
            ))),
        }
    }

    /// Reverses the orientation of the triangles and of the border.
    fn reverse(&mut self) {
        for tri in &mut self.triangles {
            tri.swap(1, 2);
        }
        self.border.reverse();
    }

    /// Twice the area of the surface projected on the coronal plane, signed positive
    /// where the triangles face anteriorly (mm²).
    fn anterior_area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|v| self.positions[v as usize]);
                (b - a).cross(c - a).z
            })
            .sum()
    }

    /// Twice the signed area of the border projected on the coronal plane.
    fn winding(&self) -> f64 {
        let n = self.border.len();
        (0..n)
            .map(|k| {
                let a = self.positions[self.border[k] as usize];
                let b = self.positions[self.border[(k + 1) % n] as usize];
                a.x * b.y - b.x * a.y
            })
            .sum()
    }

    /// The border split at its four corners, in [`ClipBox::planes`] order.
    fn sides(&self) -> Result<[Side; 4], ClosedSurfaceError> {
        let is_corner = |v: u32| self.plane_mask(v).count_ones() == 2;
        let corners = self.border.iter().filter(|&&v| is_corner(v)).count();
        let missing = ClosedSurfaceError::MissingCorners {
            role: self.role,
            corners,
        };
        let Some(start) = self.border.iter().position(|&v| is_corner(v)) else {
            return Err(missing);
        };
        if corners != 4 {
            return Err(missing);
        }
        let n = self.border.len();
        let mut sides: [Option<Side>; 4] = Default::default();
        let mut chain = vec![self.border[start]];
        for k in 1..=n {
            let v = self.border[(start + k) % n];
            chain.push(v);
            if is_corner(v) {
                let common = self.plane_mask(chain[0]) & self.plane_mask(chain[1]);
                let plane = common.trailing_zeros() as usize;
                if chain
                    .windows(2)
                    .any(|w| self.plane_mask(w[0]) & self.plane_mask(w[1]) & common == 0)
                    || plane >= 4
                    || sides[plane].is_some()
                {
                    return Err(missing);
                }
                sides[plane] = Some(Side {
                    plane,
                    chain: std::mem::replace(&mut chain, vec![v]),
                });
            }
        }
        let [Some(a), Some(b), Some(c), Some(d)] = sides else {
            return Err(missing);
        };
        Ok([a, b, c, d])
    }
}

/// A closed walk (the last vertex followed by the first) split at its repeated
/// vertices into simple cycles, each in walk order: `[a, b, c, d, b, e]` gives
/// `[b, c, d]` and `[a, b, e]`.
fn simple_cycles(walk: &[u32]) -> Vec<Vec<u32>> {
    let mut cycles = Vec::new();
    let mut stack: Vec<u32> = Vec::with_capacity(walk.len());
    let mut position: HashMap<u32, usize> = HashMap::new();
    for &v in walk {
        if let Some(&at) = position.get(&v) {
            let cycle: Vec<u32> = stack.drain(at..).collect();
            for u in &cycle {
                position.remove(u);
            }
            cycles.push(cycle);
        }
        position.insert(v, stack.len());
        stack.push(v);
    }
    if !stack.is_empty() {
        cycles.push(stack);
    }
    cycles
}

/// Triangles of `triangles` clipped to the kept side of `plane`. Vertices within `snap`
/// of the plane are moved onto it; crossed edges are split at the plane, each edge once
/// (new vertices are appended to `positions`), so the result stays connected.
fn clip_by_plane(
    positions: &mut Vec<DVec3>,
    triangles: &[[u32; 3]],
    plane: &ClipPlane,
    snap: f64,
) -> Vec<[u32; 3]> {
    for p in positions.iter_mut() {
        if plane.distance(*p).abs() <= snap {
            p[plane.axis] = plane.value;
        }
    }
    let mut split_vertices: HashMap<(u32, u32), u32> = HashMap::new();
    let mut clipped = Vec::with_capacity(triangles.len());
    for tri in triangles {
        let d = tri.map(|v| plane.distance(positions[v as usize]));
        if d.iter().all(|&x| x >= 0.0) {
            if d.iter().any(|&x| x > 0.0) {
                clipped.push(*tri);
            }
            continue;
        }
        if d.iter().all(|&x| x <= 0.0) {
            continue;
        }
        // Sutherland-Hodgman on one triangle: three or four corners, orientation kept.
        let mut polygon: Vec<u32> = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (da, db) = (d[k], d[(k + 1) % 3]);
            if da >= 0.0 {
                polygon.push(a);
            }
            if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                let key = (a.min(b), a.max(b));
                let v = *split_vertices.entry(key).or_insert_with(|| {
                    let (p, q) = (positions[key.0 as usize], positions[key.1 as usize]);
                    let (dp, dq) = (plane.distance(p), plane.distance(q));
                    let mut split = p + (q - p) * (dp / (dp - dq));
                    split[plane.axis] = plane.value;
                    positions.push(split);
                    (positions.len() - 1) as u32
                });
                polygon.push(v);
            }
        }
        match polygon[..] {
            [a, b, c] => clipped.push([a, b, c]),
            [a, b, c, e] => {
                let at = |v: u32| positions[v as usize];
                // The shorter diagonal gives the better pair of triangles.
                if at(a).distance_squared(at(c)) <= at(b).distance_squared(at(e)) {
                    clipped.extend([[a, b, c], [a, c, e]]);
                } else {
                    clipped.extend([[a, b, e], [b, c, e]]);
                }
            }
            _ => {}
        }
    }
    clipped
}

/// The connected piece (through edges) with the most triangles, its vertices renumbered
/// without unused ones.
fn largest_piece(positions: &[DVec3], triangles: &[[u32; 3]]) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mesh = TriMesh::new(positions.to_vec(), triangles.to_vec());
    let (component, count) = Topology::new(&mesh).triangle_components();
    let mut sizes = vec![0usize; count];
    for &c in &component {
        sizes[c as usize] += 1;
    }
    let largest = (0..count).max_by_key(|&c| sizes[c]).unwrap_or(0) as u32;
    let kept: Vec<[u32; 3]> = (triangles.iter().zip(&component))
        .filter(|&(_, &c)| c == largest)
        .map(|(tri, _)| *tri)
        .collect();
    let piece = TriMesh::from_used_vertices(positions, &kept);
    (piece.positions, piece.triangles)
}

/// Names of the planes in [`ClipBox::planes`] order, for messages.
const PLANE_NAMES: [&str; 4] = ["right", "left", "bottom", "top"];

/// The band on `plane` (an index into [`ClipBox::planes`]) between one side of the scan
/// (`front`, in the scan's border direction) and the same side of the wall (`back`, same
/// direction, same first and last corner in the plane): a constrained Delaunay
/// triangulation of the planar polygon the two chains bound, oriented against the
/// polygon so the triangles run against the scan's border edges and the wall's.
fn band_on_side(
    positions: &[DVec3],
    plane: usize,
    front: &[u32],
    back: &[u32],
) -> Result<Vec<[u32; 3]>, ClosedSurfaceError> {
    let polygon: Vec<u32> = front.iter().chain(back.iter().rev()).copied().collect();
    triangulate_in_plane(positions, plane, &polygon).map_err(|defect| {
        ClosedSurfaceError::Stitch(format!(
            "on the {} plane {}",
            PLANE_NAMES[plane],
            defect.describe(
                "the scan's cut curve and the shifted wall's cross",
                "a point of the scan's cut curve coincides with one of the wall's"
            )
        ))
    })
}

/// Why a polygon on a clip plane could not be triangulated.
enum PolygonDefect {
    /// A coordinate spade refuses.
    Invalid(String),
    /// Two edges cross.
    Crossing,
    /// Two corners coincide.
    Coincident,
}

impl PolygonDefect {
    fn describe(&self, crossing: &str, coincident: &str) -> String {
        match self {
            PolygonDefect::Invalid(error) => format!("has an invalid coordinate ({error})"),
            PolygonDefect::Crossing => crossing.to_string(),
            PolygonDefect::Coincident => coincident.to_string(),
        }
    }
}

/// The triangles of the simple polygon `polygon` (vertex indices into `positions`, all
/// on `plane`, an index into [`ClipBox::planes`]): a constrained Delaunay triangulation
/// of its corners without new vertices, oriented against the polygon's sense, so the
/// triangles run against the polygon's edges.
fn triangulate_in_plane(
    positions: &[DVec3],
    plane: usize,
    polygon: &[u32],
) -> Result<Vec<[u32; 3]>, PolygonDefect> {
    // In-plane coordinates: along the plane's side of the box, and anterior.
    let along = 1 - [0, 0, 1, 1][plane];
    let flat: Vec<DVec2> = polygon
        .iter()
        .map(|&v| {
            let p = positions[v as usize];
            DVec2::new(p[along], p.z)
        })
        .collect();
    let n = flat.len();
    let twice_area: f64 = (0..n).map(|k| flat[k].perp_dot(flat[(k + 1) % n])).sum();
    let counter_clockwise = twice_area > 0.0;
    // Spade refuses nonzero coordinates below its minimum; they are zero to any purpose.
    let flush = |x: f64| {
        if x.abs() < spade::MIN_ALLOWED_VALUE {
            0.0
        } else {
            x
        }
    };
    let vertices: Vec<Point2<f64>> = flat
        .iter()
        .map(|p| Point2::new(flush(p.x), flush(p.y)))
        .collect();
    let edges = (0..n).map(|k| [k, (k + 1) % n]).collect();
    let mut conflict = false;
    let cdt =
        ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(vertices, edges, |_| {
            conflict = true
        })
        .map_err(|error| PolygonDefect::Invalid(error.to_string()))?;
    if conflict {
        return Err(PolygonDefect::Crossing);
    }
    if cdt.num_vertices() != n {
        return Err(PolygonDefect::Coincident);
    }
    Ok(cdt
        .inner_faces()
        .filter_map(|face| {
            // Spade lists corners counter-clockwise.
            let corners = face.vertices().map(|v| v.fix().index());
            let inside = inside_polygon(corners, counter_clockwise);
            // Against the polygon's sense: clockwise if the polygon runs counter-clockwise.
            let [a, b, c] = corners.map(|k| polygon[k]);
            inside.then_some(if counter_clockwise {
                [a, c, b]
            } else {
                [a, b, c]
            })
        })
        .collect())
}

/// Height of the bins [`extent_limits`] scans the surface in (mm): a few vertex
/// spacings, so no bin of a scan is empty, fine enough to follow the body's outline.
const EXTENT_BIN_MM: f64 = 5.0;

/// Over the points whose coordinate `across` lies in `[lo, hi]`, binned by it: the
/// largest per-bin minimum and the smallest per-bin maximum of coordinate `along`,
/// i.e. the range of `along` that the surface spans in every bin (mm). Empty bins
/// (a gap across the whole surface) are skipped; no points give an unbounded range.
fn extent_limits(points: &[DVec3], across: usize, lo: f64, hi: f64, along: usize) -> (f64, f64) {
    let bins = ((hi - lo) / EXTENT_BIN_MM).ceil().clamp(1.0, 1e6) as usize;
    let mut ranges = vec![(f64::INFINITY, f64::NEG_INFINITY); bins];
    for p in points.iter().filter(|p| (lo..=hi).contains(&p[across])) {
        let bin = (((p[across] - lo) / EXTENT_BIN_MM) as usize).min(bins - 1);
        let range = &mut ranges[bin];
        *range = (range.0.min(p[along]), range.1.max(p[along]));
    }
    ranges
        .iter()
        .filter(|r| r.0 <= r.1)
        .fold((f64::NEG_INFINITY, f64::INFINITY), |(low, high), r| {
            (low.max(r.0), high.min(r.1))
        })
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;
    use mesh::self_intersections;
    use mesh::shapes::grid;

    /// Radius of the synthetic chest (mm).
    const RADIUS_MM: f64 = 150.0;

    /// The frame equal to the file frame.
    fn identity_frame() -> AnatomicalFrame {
        AnatomicalFrame {
            origin: DVec3::ZERO,
            axes: DMat3::IDENTITY,
            sternal_axes: DMat3::IDENTITY,
            up_source: crate::UpSource::FileVertical,
        }
    }

    /// Part of a cylinder of radius 150 mm about the y axis, facing +z (anterior):
    /// x from -120 to 120 mm, y from -150 to 50 mm, 2 mm grid.
    fn cylinder_patch() -> TriMesh {
        let mut patch = grid(120, 100, 2.0);
        patch.map_positions(|p| {
            let x = p.x - 120.0;
            DVec3::new(
                x,
                p.y - 150.0,
                (RADIUS_MM * RADIUS_MM - x * x).sqrt() - RADIUS_MM,
            )
        });
        patch
    }

    /// Planes off the grid lines, so clipping splits triangles.
    fn clip_box() -> ClipBox {
        ClipBox {
            x_min_mm: -80.3,
            x_max_mm: 79.1,
            y_min_mm: -120.7,
            y_max_mm: 10.2,
            ..ClipBox::default()
        }
    }

    fn assert_closed(surface: &ClosedSurface) {
        let topology = Topology::new(&surface.mesh);
        assert!(manifold_report(&surface.mesh, &topology).is_watertight_manifold());
        assert!(self_intersections(&surface.mesh).is_empty());
        assert!(surface.volume_ml > 0.0);
        assert_eq!(surface.band.end, surface.mesh.triangles.len());
        assert!(!surface.front.is_empty() && !surface.back_wall.is_empty());
    }

    #[test]
    fn a_translated_cylinder_patch_closes_to_the_analytic_slab_volume() {
        let patch = cylinder_patch();
        let offset_mm = 15.0;
        let clip = clip_box();
        let surface =
            build_closed_surface_in_box(&patch, &patch, &identity_frame(), &clip, offset_mm)
                .unwrap();
        assert_closed(&surface);
        // Front and wall are the same clipped surface, one translated by the offset
        // along z, and the band lies in the planes: the solid is a slab of constant
        // height over the box, whatever the surface's shape, so its volume is the box
        // area times the offset up to round-off.
        let area_mm2 = (clip.x_max_mm - clip.x_min_mm) * (clip.y_max_mm - clip.y_min_mm);
        let expected_ml = area_mm2 * offset_mm / 1000.0;
        assert!(
            (surface.volume_ml - expected_ml).abs() < 1e-9 * expected_ml,
            "{} vs {expected_ml} ml",
            surface.volume_ml
        );
        // The band lies in the planes; the front faces anteriorly.
        let on_plane = |p: DVec3| {
            [clip.x_min_mm, clip.x_max_mm].contains(&p.x)
                || [clip.y_min_mm, clip.y_max_mm].contains(&p.y)
        };
        for t in surface.band.clone() {
            let [a, b, c] = surface.mesh.triangle_positions(t);
            let centroid = (a + b + c) / 3.0;
            assert!(on_plane(a) && on_plane(b) && on_plane(c), "{a} {b} {c}");
            assert!((clip.x_min_mm..=clip.x_max_mm).contains(&centroid.x));
        }
        let front_normal_z: f64 = surface
            .front
            .clone()
            .map(|t| surface.mesh.triangle_normal(t).z)
            .sum();
        assert!(front_normal_z > 0.0);
    }

    #[test]
    fn an_inward_base_or_scan_gives_the_same_outward_surface() {
        let patch = cylinder_patch();
        let mut flipped = patch.clone();
        for tri in &mut flipped.triangles {
            tri.swap(1, 2);
        }
        let frame = identity_frame();
        let reference = build_closed_surface_in_box(&patch, &patch, &frame, &clip_box(), 15.0)
            .unwrap()
            .volume_ml;
        for (scan, base) in [(&patch, &flipped), (&flipped, &patch), (&flipped, &flipped)] {
            let surface =
                build_closed_surface_in_box(scan, base, &frame, &clip_box(), 15.0).unwrap();
            assert_closed(&surface);
            assert!((surface.volume_ml - reference).abs() < 1e-9 * reference);
        }
    }

    #[test]
    fn a_hole_inside_the_box_is_an_error() {
        let mut patch = cylinder_patch();
        // Remove the triangles around the vertex at x = 0, y = -50.
        let centre = (50 * 121 + 60) as u32;
        patch.triangles.retain(|tri| !tri.contains(&centre));
        let error = build_closed_surface_in_box(
            &patch,
            &cylinder_patch(),
            &identity_frame(),
            &clip_box(),
            15.0,
        )
        .unwrap_err();
        assert!(
            matches!(
                error,
                ClosedSurfaceError::HoleInsideBox {
                    role: SurfaceRole::Scan,
                    vertices: 6,
                    ..
                }
            ),
            "{error}"
        );
        assert!(error.to_string().contains("hole"), "{error}");
    }

    #[test]
    fn walks_split_into_simple_cycles() {
        assert_eq!(simple_cycles(&[1, 2, 3]), vec![vec![1, 2, 3]]);
        assert_eq!(
            simple_cycles(&[1, 2, 3, 4, 2, 5]),
            vec![vec![2, 3, 4], vec![1, 2, 5]]
        );
        // Pinched at the first vertex, and nested.
        assert_eq!(
            simple_cycles(&[1, 2, 3, 1, 4, 5, 6, 5, 7]),
            vec![vec![1, 2, 3], vec![5, 6], vec![1, 4, 5, 7]]
        );
    }

    #[test]
    fn a_bump_grazing_a_plane_is_capped_flat() {
        // One vertex of the scan (at x = 76 mm, 3.1 mm inside the left plane) pushed
        // 3.5 mm out, past the plane: its tip is cut off, leaving a small hole on the
        // plane, apart from the border, that the cap closes.
        let mut scan = cylinder_patch();
        let bump = (50 * 121 + 98) as usize;
        assert_eq!(scan.positions[bump].x, 76.0);
        scan.positions[bump].x += 3.5;
        let clip = clip_box();
        let frame = identity_frame();
        let surface =
            build_closed_surface_in_box(&scan, &cylinder_patch(), &frame, &clip, 15.0).unwrap();
        assert_closed(&surface);
        // Triangles lying in the left plane off the band: the cap.
        let cap: Vec<usize> = surface
            .front
            .clone()
            .filter(|&t| {
                surface
                    .mesh
                    .triangle_positions(t)
                    .iter()
                    .all(|p| p.x == clip.x_max_mm)
            })
            .collect();
        assert!(!cap.is_empty());
        for &t in &cap {
            assert!(
                surface.mesh.triangle_normal(t).x > 0.99,
                "the cap faces out"
            );
        }
        // The bump adds a sliver of volume to the slab.
        let reference =
            build_closed_surface_in_box(&cylinder_patch(), &cylinder_patch(), &frame, &clip, 15.0)
                .unwrap();
        let added = surface.volume_ml - reference.volume_ml;
        assert!(added > 0.0 && added < 0.01, "{added} ml");
    }

    #[test]
    fn a_plane_beyond_the_border_is_an_error() {
        let patch = cylinder_patch();
        let beyond = ClipBox {
            x_max_mm: 130.0,
            ..clip_box()
        };
        let error = build_closed_surface_in_box(&patch, &patch, &identity_frame(), &beyond, 15.0)
            .unwrap_err();
        assert!(
            matches!(
                error,
                ClosedSurfaceError::RunsOffBorder {
                    role: SurfaceRole::Scan,
                    ..
                }
            ),
            "{error}"
        );
    }

    #[test]
    fn a_base_in_front_of_the_scan_and_bad_options_are_errors() {
        let patch = cylinder_patch();
        let mut in_front = patch.clone();
        in_front.map_positions(|p| p + DVec3::Z * 30.0);
        let frame = identity_frame();
        let error =
            build_closed_surface_in_box(&patch, &in_front, &frame, &clip_box(), 15.0).unwrap_err();
        assert!(
            matches!(error, ClosedSurfaceError::WallInFront { .. }),
            "{error}"
        );

        for offset in [0.0, -5.0, f64::NAN] {
            assert!(matches!(
                build_closed_surface_in_box(&patch, &patch, &frame, &clip_box(), offset),
                Err(ClosedSurfaceError::InvalidInput(_))
            ));
        }
        let empty = ClipBox {
            x_min_mm: 10.0,
            x_max_mm: -10.0,
            ..clip_box()
        };
        assert!(matches!(
            build_closed_surface_in_box(&patch, &patch, &frame, &empty, 15.0),
            Err(ClosedSurfaceError::InvalidInput(_))
        ));
        let missing = ClipBox {
            x_min_mm: 500.0,
            x_max_mm: 600.0,
            ..clip_box()
        };
        assert!(matches!(
            build_closed_surface_in_box(&patch, &patch, &frame, &missing, 15.0),
            Err(ClosedSurfaceError::TooFewTriangles { .. })
        ));
    }
}
