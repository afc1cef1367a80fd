//! The clip box: its four planes, fitted around the breasts and kept inside the scan.

use super::{ClosedSurfaceError, ClosedSurfaceOptions, LANDMARK_MARGIN_MM};
use crate::frame::AnatomicalFrame;
use crate::landmarks::{LandmarkName, Landmarks};
use glam::DVec3;
use mesh::{Topology, TriMesh};

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
    /// The top or bottom moved off a notch of the scan's border, with where.
    pub notch_warnings: Vec<String>,
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

/// The x-extent of `points` (frame coordinates) in bins of height over `[lo, hi]`
/// ([`extent_bins`]): for each non-empty bin, both its edges' heights with the bin's
/// smallest and largest x.
fn outline_by_height(points: &[DVec3], lo: f64, hi: f64) -> Vec<(f64, f64, f64)> {
    extent_bins(points, 1, lo, hi, 0)
        .into_iter()
        .flat_map(|bin| {
            [
                (bin.from_mm, bin.min_mm, bin.max_mm),
                (bin.to_mm, bin.min_mm, bin.max_mm),
            ]
        })
        .collect()
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
    ///    of the box, and off notches of the scan's border that reach into it, short of
    ///    the footprints and breast landmarks.
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
        let notch_warnings =
            fit_top_and_bottom(&mut clip_box, scan, &local_scan, &keep, clearance)?;

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
            notch_warnings,
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
    /// lateral planes become `x = x_min_mm` and `x = x_max_mm` (heights more than
    /// [`MAPPED_BEYOND_MM`] beyond the top or bottom use the map at that distance, so the
    /// map stays one-to-one and continuous); `y` and `z` unchanged. The identity for an
    /// upright box.
    pub(super) fn to_box(self, p: DVec3) -> DVec3 {
        if self.x_min_slope == 0.0 && self.x_max_slope == 0.0 {
            return p;
        }
        let y = self.mapped_height(p.y);
        let (lo, hi) = (self.x_min_at(y), self.x_max_at(y));
        let x = self.x_min_mm + (p.x - lo) * (self.x_max_mm - self.x_min_mm) / (hi - lo);
        DVec3::new(x, p.y, p.z)
    }

    /// The inverse of [`ClipBox::to_box`].
    pub(super) fn box_to_local(self, p: DVec3) -> DVec3 {
        if self.x_min_slope == 0.0 && self.x_max_slope == 0.0 {
            return p;
        }
        let y = self.mapped_height(p.y);
        let (lo, hi) = (self.x_min_at(y), self.x_max_at(y));
        let x = lo + (p.x - self.x_min_mm) * (hi - lo) / (self.x_max_mm - self.x_min_mm);
        DVec3::new(x, p.y, p.z)
    }

    /// The first of [`BREAST_LANDMARKS`] outside the box, if any.
    pub(super) fn left_out(
        &self,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
    ) -> Option<LandmarkName> {
        BREAST_LANDMARKS
            .into_iter()
            .find(|&name| !self.contains(frame.to_local(landmarks.get(name))))
    }

    /// The height whose row of the box maps a point at height `y`: `y` itself up to
    /// [`MAPPED_BEYOND_MM`] beyond the top and bottom.
    fn mapped_height(self, y: f64) -> f64 {
        y.clamp(
            self.y_min_mm - MAPPED_BEYOND_MM,
            self.y_max_mm + MAPPED_BEYOND_MM,
        )
    }

    pub(super) fn check(&self) -> Result<(), ClosedSurfaceError> {
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
        let ordered_at = |y: f64| self.x_min_at(y) < self.x_max_at(y);
        if !finite
            || self.y_min_mm >= self.y_max_mm
            || !ordered_at(self.y_min_mm)
            || !ordered_at(self.y_max_mm)
        {
            return Err(ClosedSurfaceError::InvalidInput(format!(
                "empty clip box: x {} to {} mm, y {} to {} mm in the anatomical frame",
                self.x_min_mm, self.x_max_mm, self.y_min_mm, self.y_max_mm
            )));
        }
        // The map to the box's coordinates must stay one-to-one where it follows the
        // planes.
        if !ordered_at(self.y_min_mm - MAPPED_BEYOND_MM)
            || !ordered_at(self.y_max_mm + MAPPED_BEYOND_MM)
        {
            return Err(ClosedSurfaceError::InvalidInput(format!(
                "the clip box's lateral planes (leaning {} and {}) meet within \
                 {MAPPED_BEYOND_MM} mm of its top or bottom; lean them less",
                self.x_min_slope, self.x_max_slope
            )));
        }
        Ok(())
    }

    /// Whether a point (frame coordinates) lies inside the box.
    pub fn contains(&self, local: DVec3) -> bool {
        (self.y_min_mm..=self.y_max_mm).contains(&local.y)
            && (self.x_min_at(local.y)..=self.x_max_at(local.y)).contains(&local.x)
    }

    /// The four planes as (axis, coordinate, keep-the-side-above).
    pub(super) fn planes(&self) -> [ClipPlane; 4] {
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

/// How far the right and left planes of `clip_box` lie beyond `footprint` (frame
/// coordinates) and the lateral fold ends, at the points' heights inside the box (mm).
pub(super) fn lateral_room(
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
/// The upright box of earlier versions, which [`build_closed_surface`] uses without
/// `fit_lateral_planes`: the lateral planes `lateral_margin_mm` beyond the lateral
/// fold ends, moved inwards to stay the clearance inside the scan's narrowest width over
/// the box's heights (less where the breast landmarks need it); top and bottom as in
/// the fitted box, short of the breast landmarks (it has no footprints). With the
/// warnings of planes moved off notches of the scan's border.
///
/// [`build_closed_surface`]: super::build_closed_surface
pub(super) fn upright_box(
    scan: &TriMesh,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &ClosedSurfaceOptions,
) -> Result<(ClipBox, Vec<String>), ClosedSurfaceError> {
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
    // height at every x of the narrowed box and off notches of its border.
    let (x_min, x_max) = extent_limits(&local_scan, 1, clip_box.y_min_mm, clip_box.y_max_mm, 0);
    clip_box.x_min_mm = clip_box
        .x_min_mm
        .max((x_min + clearance).min(needed_x_min))
        .max(x_min + min_clearance);
    clip_box.x_max_mm = clip_box
        .x_max_mm
        .min((x_max - clearance).max(needed_x_max))
        .min(x_max - min_clearance);
    let kept = BREAST_LANDMARKS.map(|name| frame.to_local(landmarks.get(name)));
    let notch_warnings = fit_top_and_bottom(&mut clip_box, scan, &local_scan, &kept, clearance)?;
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
    Ok((clip_box, notch_warnings))
}

/// Top and bottom moved `clearance` inside the scan (`local_scan`: its positions in the
/// frame), in the box's coordinates where the lateral planes are upright:
/// 1. inside the scan's height at every x of the box;
/// 2. off the scan's border where it reaches into the box from outside it: a notch of
///    skin the cameras did not see cut into the scan's edge (the upward-facing skin over
///    a clavicle), which step 1 does not see because the skin behind the notch reaches
///    higher. The border would otherwise end inside the box and the clipped scan would
///    have no closed border on the planes. Neither plane passes the points to keep
///    (`kept`, frame coordinates) with [`LANDMARK_MARGIN_MM`].
///
/// Only the border the clipping keeps counts: that of the largest piece of the scan
/// inside the box ([`clipped_piece`]). A strip of the scan behind a lateral plane (the
/// side of a torso that curves back behind its widest point) and specks apart from the
/// scan are dropped by the clipping, and their borders do not count. A border loop
/// wholly inside the box is a hole, not a notch, left for the clipping to report. A
/// plane moved through a hole makes it a notch, so the loops are looked at again
/// until the planes stay.
///
/// Returns a warning per plane moved off a notch, naming where (file coordinates).
fn fit_top_and_bottom(
    clip_box: &mut ClipBox,
    scan: &TriMesh,
    local_scan: &[DVec3],
    kept: &[DVec3],
    clearance: f64,
) -> Result<Vec<String>, ClosedSurfaceError> {
    let boxed: Vec<DVec3> = local_scan.iter().map(|&p| clip_box.to_box(p)).collect();
    let (y_min, y_max) = extent_limits(&boxed, 0, clip_box.x_min_mm, clip_box.x_max_mm, 1);
    clip_box.y_min_mm = clip_box.y_min_mm.max(y_min + clearance);
    clip_box.y_max_mm = clip_box.y_max_mm.min(y_max - clearance);
    clip_box.check()?;

    let kept_heights = kept.iter().map(|p| p.y);
    let lowest_kept = kept_heights.clone().fold(f64::INFINITY, f64::min) - LANDMARK_MARGIN_MM;
    let highest_kept = kept_heights.fold(f64::NEG_INFINITY, f64::max) + LANDMARK_MARGIN_MM;
    let (first_top, first_bottom) = (clip_box.y_max_mm, clip_box.y_min_mm);
    // The scan vertex that set each plane last: top, bottom.
    let mut set_by: [Option<u32>; 2] = [None, None];
    let topology = Topology::new(scan);
    let borders = topology.boundary_loops(scan);
    // A plane moves only inwards and never past the points to keep; the passes are
    // capped (a moved plane can bring in a hole or, splitting the piece, another
    // border), and a box the cap leaves unsettled is the clipping's to report.
    for _ in 0..MAX_NOTCH_PASSES {
        let (top, bottom) = (clip_box.y_max_mm, clip_box.y_min_mm);
        let across_box = |p: &DVec3| (clip_box.x_min_mm..=clip_box.x_max_mm).contains(&p.x);
        let inside = |p: &DVec3| across_box(p) && (bottom..=top).contains(&p.y);
        let in_piece = clipped_piece(&topology, scan, &boxed, clip_box);
        let (mut new_top, mut new_bottom) = ((top, None), (bottom, None));
        for border in &borders {
            if border.iter().all(|&v| inside(&boxed[v as usize])) {
                continue;
            }
            let counted = (border.iter().copied())
                .filter(|&v| in_piece[v as usize] && across_box(&boxed[v as usize]));
            for v in counted {
                let y = boxed[v as usize].y;
                if (highest_kept..top + clearance).contains(&y) && y - clearance < new_top.0 {
                    new_top = (y - clearance, Some(v));
                } else if (bottom - clearance..lowest_kept).contains(&y)
                    && y + clearance > new_bottom.0
                {
                    new_bottom = (y + clearance, Some(v));
                }
            }
        }
        clip_box.y_max_mm = new_top.0.max(highest_kept.min(top));
        clip_box.y_min_mm = new_bottom.0.min(lowest_kept.max(bottom));
        set_by[0] = new_top.1.or(set_by[0]);
        set_by[1] = new_bottom.1.or(set_by[1]);
        if (clip_box.y_max_mm, clip_box.y_min_mm) == (top, bottom) {
            break;
        }
    }
    clip_box.check()?;
    let moved = [
        ("top", "down", first_top - clip_box.y_max_mm),
        ("bottom", "up", clip_box.y_min_mm - first_bottom),
    ];
    Ok((moved.iter().zip(set_by))
        .filter(|((_, _, moved_mm), _)| *moved_mm > 0.0)
        .filter_map(|(&(plane, way, moved_mm), v)| {
            let near = scan.positions[v? as usize];
            Some(format!(
                "the scan's border reaches into the clip box near ({:.1}, {:.1}, \
                 {:.1}) mm (skin the cameras did not see?): its {plane} was moved \
                 {moved_mm:.1} mm {way} to stay {clearance} mm clear of it",
                near.x, near.y, near.z
            ))
        })
        .collect())
}

/// Most passes [`fit_top_and_bottom`] makes over the scan's border loops: one, and one
/// more per hole a moved plane may bring in, a few on any scan.
const MAX_NOTCH_PASSES: usize = 8;

/// Per vertex of `scan`: whether it is a corner of the piece the clipping keeps, near
/// enough for [`fit_top_and_bottom`]: the largest connected piece of the triangles with
/// a corner inside the box (`boxed`: the scan's positions in the box's coordinates).
fn clipped_piece(
    topology: &Topology,
    scan: &TriMesh,
    boxed: &[DVec3],
    clip_box: &ClipBox,
) -> Vec<bool> {
    let inside = |p: DVec3| {
        (clip_box.x_min_mm..=clip_box.x_max_mm).contains(&p.x)
            && (clip_box.y_min_mm..=clip_box.y_max_mm).contains(&p.y)
    };
    let (component, count) = topology.triangle_components_among(|t| {
        scan.triangles[t].iter().any(|&v| inside(boxed[v as usize]))
    });
    let largest = super::clip::largest_component(&component, count);
    let mut in_piece = vec![false; scan.positions.len()];
    for (triangle, &c) in scan.triangles.iter().zip(&component) {
        if c == largest {
            for &v in triangle {
                in_piece[v as usize] = true;
            }
        }
    }
    in_piece
}

/// A plane of the clip box: `axis` 0 (x) or 1 (y) of the frame; the kept side is
/// `coordinate >= value` if `keep_above`, else `<=`.
#[derive(Debug, Clone, Copy)]
pub(super) struct ClipPlane {
    pub(super) axis: usize,
    pub(super) value: f64,
    pub(super) keep_above: bool,
}

impl ClipPlane {
    /// Signed distance, positive on the kept side.
    pub(super) fn distance(&self, p: DVec3) -> f64 {
        let d = p[self.axis] - self.value;
        if self.keep_above { d } else { -d }
    }

    /// Where the segment from `p` to `q` (on opposite sides) crosses the plane, its
    /// coordinate set to the plane's exactly so the point counts as on it.
    pub(super) fn crossing(&self, p: DVec3, q: DVec3) -> DVec3 {
        let (dp, dq) = (self.distance(p), self.distance(q));
        let mut point = p + (q - p) * (dp / (dp - dq));
        point[self.axis] = self.value;
        point
    }
}

/// Bit `i` set if `p` lies exactly on `planes[i]`.
pub(super) fn planes_through(p: DVec3, planes: &[ClipPlane]) -> u8 {
    planes
        .iter()
        .enumerate()
        .filter(|(_, plane)| p[plane.axis] == plane.value)
        .fold(0, |mask, (i, _)| mask | (1 << i))
}

/// How far beyond its top and bottom the box's map ([`ClipBox::to_box`]) still follows
/// the leaning planes (mm): past the triangles the top and bottom planes cut, assuming
/// edges of a few mm as on a scan, so each such triangle is mapped by one rule and its
/// section by a lateral plane is the one measured in the frame
/// ([`super::lateral_section`]). A map bent at the top or bottom moves that section by
/// up to the lean times an edge, enough to add corners where it runs level there.
const MAPPED_BEYOND_MM: f64 = 20.0;

/// Names of the planes in [`ClipBox::planes`] order, for messages.
pub(super) const PLANE_NAMES: [&str; 4] = ["right", "left", "bottom", "top"];

/// Largest height of the bins [`extent_bins`] scans a surface in (mm): a few vertex
/// spacings, so no bin of a scan is empty, fine enough to follow the body's outline.
const EXTENT_BIN_MM: f64 = 5.0;

/// One bin of [`extent_bins`]: its range of the binned coordinate and the range of the
/// measured one over its points.
struct ExtentBin {
    from_mm: f64,
    to_mm: f64,
    min_mm: f64,
    max_mm: f64,
}

/// The points whose coordinate `across` lies in `[lo, hi]`, in bins of equal height of
/// at most [`EXTENT_BIN_MM`] (none thinner than half that unless the range is): each
/// non-empty bin with the range of coordinate `along` over its points. Equal heights,
/// because a sliver of a bin at the range's end holds a few vertices of the scan's
/// triangles and understates its extent there.
fn extent_bins(points: &[DVec3], across: usize, lo: f64, hi: f64, along: usize) -> Vec<ExtentBin> {
    let bins = ((hi - lo) / EXTENT_BIN_MM).ceil().clamp(1.0, 1e6) as usize;
    let height = (hi - lo) / bins as f64;
    let mut ranges = vec![(f64::INFINITY, f64::NEG_INFINITY); bins];
    for p in points.iter().filter(|p| (lo..=hi).contains(&p[across])) {
        let bin = (((p[across] - lo) / height) as usize).min(bins - 1);
        let range = &mut ranges[bin];
        *range = (range.0.min(p[along]), range.1.max(p[along]));
    }
    ranges
        .into_iter()
        .enumerate()
        .filter(|(_, r)| r.0 <= r.1)
        .map(|(bin, (min_mm, max_mm))| ExtentBin {
            from_mm: lo + bin as f64 * height,
            to_mm: (lo + (bin + 1) as f64 * height).min(hi),
            min_mm,
            max_mm,
        })
        .collect()
}

/// Over the points whose coordinate `across` lies in `[lo, hi]`, binned by it
/// ([`extent_bins`]): the largest per-bin minimum and the smallest per-bin maximum of
/// coordinate `along`, i.e. the range of `along` that the surface spans in every bin
/// (mm). Empty bins (a gap across the whole surface) are skipped; no points give an
/// unbounded range.
fn extent_limits(points: &[DVec3], across: usize, lo: f64, hi: f64, along: usize) -> (f64, f64) {
    extent_bins(points, across, lo, hi, along)
        .iter()
        .fold((f64::NEG_INFINITY, f64::INFINITY), |(low, high), bin| {
            (low.max(bin.min_mm), high.min(bin.max_mm))
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Points spread evenly over a cylinder of `radius_mm` about the y axis, for y in
    /// 0 to 100 mm, one per 6 mm² as on a scan (a Weyl sequence: no two on a grid line).
    fn cylinder_points(radius_mm: f64) -> Vec<DVec3> {
        let area = 2.0 * std::f64::consts::PI * radius_mm * 100.0;
        let count = (area / 6.0) as usize;
        let golden = 0.5 * (5f64.sqrt() - 1.0);
        (0..count)
            .map(|k| {
                let angle = 2.0 * std::f64::consts::PI * (k as f64 * golden).fract();
                let y = 100.0 * (k as f64 * std::f64::consts::SQRT_2).fract();
                DVec3::new(radius_mm * angle.cos(), y, radius_mm * angle.sin())
            })
            .collect()
    }

    /// The width of a cylinder over a height range whose length is not a whole number of
    /// bins: the 0.1 mm sliver a 50.1 mm range left at its end with bins of exactly 5 mm
    /// held 15 points and reported the cylinder 7 mm narrower. Bins of 4.5 mm hold some
    /// 700 points, whose widest gap near the side (about 10 mm of arc) falls 0.3 mm short
    /// of the radius; 1 mm is allowed.
    #[test]
    fn a_height_range_of_no_whole_bins_still_sees_the_full_width() {
        let radius_mm = 150.0;
        let points = cylinder_points(radius_mm);
        for hi in [50.1, 52.4, 99.9] {
            let (low, high) = extent_limits(&points, 1, 0.0, hi, 0);
            assert!(
                low < -radius_mm + 1.0 && high > radius_mm - 1.0,
                "y 0 to {hi} mm: x from {low:.2} to {high:.2} mm, the cylinder spans ±{radius_mm}"
            );
        }
        let outline = outline_by_height(&points, 0.0, 50.1);
        assert!(
            outline
                .iter()
                .all(|&(_, low, high)| low < -radius_mm + 1.0 && high > radius_mm - 1.0)
        );
    }

    /// A point on a leaning lateral plane maps onto the box's upright plane also a
    /// little beyond the box's top and bottom, where the triangles the top and bottom
    /// planes cut have their other corners, and the map inverts there (to rounding).
    #[test]
    fn the_box_map_follows_the_leaning_planes_just_beyond_the_box() {
        let clip_box = ClipBox {
            x_min_mm: -110.0,
            x_max_mm: 115.0,
            x_min_slope: -0.12,
            x_max_slope: 0.2,
            y_min_mm: -260.0,
            y_max_mm: -30.0,
            y_ref_mm: -200.0,
        };
        for y in [-275.0, -261.0, -200.0, -29.0, -15.0] {
            for (x, expected) in [
                (clip_box.x_min_at(y), clip_box.x_min_mm),
                (clip_box.x_max_at(y), clip_box.x_max_mm),
            ] {
                let p = DVec3::new(x, y, -80.0);
                let mapped = clip_box.to_box(p);
                assert!(
                    (mapped.x - expected).abs() < 1e-9,
                    "y {y}: {mapped} for {expected}"
                );
                assert!(clip_box.box_to_local(mapped).distance(p) < 1e-9);
            }
        }
    }
}
