//! Where a lateral clip plane meets the side of the torso once at every height.
//!
//! The closed surface clips the scan and the filled base by the lateral planes and
//! stitches the two sections on each plane. That needs the plane to cross the surface
//! cleanly: one chain from the box's bottom to its top, met once at every height. Where
//! a plane grazes the torso's side instead (near the scan's outline, where the side turns
//! to face the plane), it cuts off the tip of a bump or the rim of a dent, leaving a
//! closed loop on the plane (which the wall's copy turns into a pocket of air), and its
//! section runs front to back along an overhang, so the wall (the base's section moved
//! back) crosses the scan's or touches the plane along edges. [`LateralSection`]
//! measures both on a candidate plane; [`clear_of_grazing`] moves each plane inwards
//! until they are gone. Loops and spread are measured on the filled base only: the scan
//! differs from it inside the cut curves, where a breast's lateral side crossing the
//! plane is a bump of material that clipping caps. The corners, where each section
//! crosses the box's top and bottom heights, are counted on both.

use super::clip_box::ClipBox;
use crate::frame::AnatomicalFrame;
use crate::landmarks::Landmarks;
use glam::DVec3;
use mesh::TriMesh;
use std::collections::HashMap;

/// Step of the search inwards for a clean lateral plane (mm).
const STEP_MM: f64 = 0.5;
/// The farthest a lateral plane moves in from where the box put it (mm): a few scan
/// vertex spacings past a grazed bump; beyond, the torso's side itself is to blame.
pub(super) const MAX_INWARD_MM: f64 = 10.0;
/// The largest depth spread of a clean section, as a fraction of the rear-wall offset.
/// A spread near the offset lets the wall (the base moved back by it) cross the skin;
/// well below it, a spread of more than 6 mm within a millimetre of height is the plane
/// running along an overhang (a hanging breast's lateral underside beyond its cut curve),
/// where it touches the base along edges and the stitch is not 2-manifold (s09 at 9.8
/// mm; docs/dev/model-on-every-body.md).
const MAX_FOLD_FRACTION: f64 = 0.4;

/// Where [`clear_of_grazing`] left one lateral plane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct PlaneMove {
    /// How far the plane moved inwards (mm).
    pub(super) moved_mm: f64,
    /// Closed loops and extra or missing corners left in the sections there; 0 on a
    /// clean plane.
    pub(super) defects: usize,
    /// How far the depth spread there exceeds the bound (mm); 0 on a clean plane.
    pub(super) excess_fold_mm: f64,
}

impl PlaneMove {
    pub(super) fn is_clean(&self) -> bool {
        self.defects == 0 && self.excess_fold_mm == 0.0
    }
}

/// Moves each lateral plane of `clip_box` inwards by [`STEP_MM`] steps to the first
/// position where it crosses the surfaces cleanly. On the plane and on the planes a
/// step either side of it: the filled base's section (`filled_base`, file coordinates,
/// already smoothed) has no closed loop and a depth spread of at most
/// [`MAX_FOLD_FRACTION`] of `rear_wall_offset_mm`; and near the base's frontmost
/// crossing of the top and of the bottom plane's height, the base and `scan` each
/// cross that height once, so each clipped border has one corner at each plane
/// intersection. A plane moves at most [`MAX_INWARD_MM`] and never past a breast
/// landmark; with no clean position in reach it goes where the sections are least bad
/// and [`PlaneMove`] says what is left. Returns the box and `[right, left]`.
pub(super) fn clear_of_grazing(
    clip_box: ClipBox,
    scan: &TriMesh,
    filled_base: &TriMesh,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    rear_wall_offset_mm: f64,
) -> (ClipBox, [PlaneMove; 2]) {
    let to_local = |mesh: &TriMesh| -> Vec<DVec3> {
        mesh.positions.iter().map(|&p| frame.to_local(p)).collect()
    };
    let surfaces = Surfaces {
        scan_local: to_local(scan),
        scan_triangles: &scan.triangles,
        base_local: to_local(filled_base),
        base_triangles: &filled_base.triangles,
        max_fold_mm: MAX_FOLD_FRACTION * rear_wall_offset_mm,
    };
    let moves = [0, 1].map(|k| {
        let shifted = |shift: f64| {
            let mut candidate = clip_box;
            if k == 0 {
                candidate.x_min_mm += shift;
            } else {
                candidate.x_max_mm -= shift;
            }
            candidate
        };
        surfaces.search(&clip_box, k, |shift| {
            shifted(shift).left_out(frame, landmarks).is_none()
        })
    });
    let mut adjusted = clip_box;
    adjusted.x_min_mm += moves[0].moved_mm;
    adjusted.x_max_mm -= moves[1].moved_mm;
    (adjusted, moves)
}

/// The two surfaces in frame coordinates, and the depth-spread bound.
struct Surfaces<'a> {
    scan_local: Vec<DVec3>,
    scan_triangles: &'a [[u32; 3]],
    base_local: Vec<DVec3>,
    base_triangles: &'a [[u32; 3]],
    max_fold_mm: f64,
}

impl Surfaces<'_> {
    /// The search of [`clear_of_grazing`] for plane `k` (0 right, 1 left) of
    /// `clip_box`; `keeps_landmarks(shift)` says whether the box with that plane `shift`
    /// mm in still holds the breast landmarks.
    fn search(
        &self,
        clip_box: &ClipBox,
        k: usize,
        keeps_landmarks: impl Fn(f64) -> bool,
    ) -> PlaneMove {
        // The plane `shift` mm in from where the box put it.
        let plane_at = |shift: f64| {
            let (slope, at_ref) = if k == 0 {
                (clip_box.x_min_slope, clip_box.x_min_mm + shift)
            } else {
                (clip_box.x_max_slope, clip_box.x_max_mm - shift)
            };
            LateralPlane {
                slope,
                offset: at_ref - slope * clip_box.y_ref_mm,
            }
        };
        let heights = (clip_box.y_min_mm, clip_box.y_max_mm);
        // Only the triangles the search's planes can cross.
        let reach = [plane_at(-STEP_MM), plane_at(MAX_INWARD_MM + STEP_MM)];
        let base_near = crossing_any(&self.base_local, self.base_triangles, reach);
        let scan_near = crossing_any(&self.scan_local, self.scan_triangles, reach);
        let base_at = |shift: f64| {
            LateralSection::measure(&self.base_local, &base_near, plane_at(shift), heights)
        };
        let scan_at = |shift: f64| {
            LateralSection::measure(&self.scan_local, &scan_near, plane_at(shift), heights)
        };
        let mut best: Option<PlaneMove> = None;
        let mut base_window = vec![base_at(-STEP_MM), base_at(0.0)];
        let mut scan_window = vec![scan_at(-STEP_MM), scan_at(0.0)];
        let steps = (MAX_INWARD_MM / STEP_MM).round() as usize;
        for step in 0..=steps {
            let shift = step as f64 * STEP_MM;
            if step > 0 && !keeps_landmarks(shift) {
                break;
            }
            base_window.push(base_at(shift + STEP_MM));
            scan_window.push(scan_at(shift + STEP_MM));
            // The slab one step either side of the plane: a bump whose tip just touches
            // the plane is a loop a step further in.
            let slab = &base_window[base_window.len() - 3..];
            let here = PlaneMove {
                moved_mm: shift,
                defects: slab.iter().map(|s| s.loops).sum::<usize>()
                    + extra_corners(slab, &scan_window[scan_window.len() - 3..]),
                excess_fold_mm: slab
                    .iter()
                    .map(|s| (s.fold_depth_mm - self.max_fold_mm).max(0.0))
                    .fold(0.0, f64::max),
            };
            // Fewer defects first, then less excess spread.
            let better =
                |b: &PlaneMove| (here.defects, here.excess_fold_mm) < (b.defects, b.excess_fold_mm);
            if best.as_ref().is_none_or(better) {
                best = Some(here);
            }
            if here.is_clean() {
                break;
            }
        }
        best.unwrap_or(PlaneMove {
            moved_mm: 0.0,
            defects: 0,
            excess_fold_mm: 0.0,
        })
    }
}

/// Crossings of the top and of the bottom height other than exactly one, near the
/// base's frontmost crossing of it (within [`CORNER_RADIUS_MM`] in depth; where the
/// surfaces wrap round the side and cross again further back, that part is clipped
/// off), at the worst of the heights and planes a step either side: the base's and the
/// scan's. A height the base does not cross at all counts one.
fn extra_corners(base: &[LateralSection], scans: &[LateralSection]) -> usize {
    let mut extra = 0;
    for end in 0..2 {
        let Some(front) = base[1].corner_depths_mm[end][1]
            .iter()
            .copied()
            .reduce(f64::max)
        else {
            extra += 1;
            continue;
        };
        let worst = |sections: &[LateralSection]| {
            sections
                .iter()
                .flat_map(|s| &s.corner_depths_mm[end])
                .map(|depths| {
                    depths
                        .iter()
                        .filter(|&&z| (z - front).abs() < CORNER_RADIUS_MM)
                        .count()
                        .abs_diff(1)
                })
                .max()
                .unwrap_or(0)
        };
        extra += worst(base) + worst(scans);
    }
    extra
}

/// How far in depth from the base's frontmost crossing of a height another crossing
/// counts as the same corner (mm): the scan lies on the base there, give or take the
/// smoothing of noise, and a wrap round the side lies tens of millimetres further back.
const CORNER_RADIUS_MM: f64 = 5.0;

/// The triangles of `triangles` that some plane between the two crosses.
fn crossing_any(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    planes: [LateralPlane; 2],
) -> Vec<[u32; 3]> {
    let slope = planes[0].slope;
    let lo = planes[0].offset.min(planes[1].offset);
    let hi = planes[0].offset.max(planes[1].offset);
    triangles
        .iter()
        .filter(|tri| {
            let u = tri.map(|v| {
                let p = positions[v as usize];
                p.x - slope * p.y
            });
            let (min, max) = (u[0].min(u[1]).min(u[2]), u[0].max(u[1]).max(u[2]));
            max >= lo && min <= hi
        })
        .copied()
        .collect()
}

/// A slanted lateral plane in frame coordinates: the points with
/// `x - slope * y == offset`.
#[derive(Debug, Clone, Copy)]
struct LateralPlane {
    slope: f64,
    offset: f64,
}

/// How a lateral plane meets a surface between two heights.
#[derive(Debug, Clone, PartialEq)]
struct LateralSection {
    /// Closed loops of the section lying wholly between the heights: the plane cuts off
    /// a bump's tip or a dent's rim inside the box.
    loops: usize,
    /// The largest spread in depth (z) of the section at one height (mm): 0 where the
    /// section is met once at every height, the depth of the fold where it doubles back.
    fold_depth_mm: f64,
    /// The depths (z, mm) at which the section crosses the lower and the upper height
    /// (where the clipped border will have its corners), each at that height minus
    /// [`STEP_MM`], at it, and plus [`STEP_MM`].
    corner_depths_mm: [[Vec<f64>; 3]; 2],
}

impl LateralSection {
    /// The section of the surface (`positions` in frame coordinates) with `plane`,
    /// between heights `y_range`: its components (joined by the mesh edges they cross)
    /// and each one's spread in depth per [`HEIGHT_BIN_MM`] of height.
    fn measure(
        positions: &[DVec3],
        triangles: &[[u32; 3]],
        plane: LateralPlane,
        y_range: (f64, f64),
    ) -> LateralSection {
        let side = |v: u32| {
            let p = positions[v as usize];
            p.x - plane.slope * p.y - plane.offset
        };
        let point_on = |a: u32, b: u32| {
            let (sa, sb) = (side(a), side(b));
            let t = sa / (sa - sb);
            positions[a as usize].lerp(positions[b as usize], t)
        };
        // Each crossed triangle gives a segment between two crossed edges; a vertex on the
        // plane counts as beyond it, so every crossed triangle has exactly two.
        let mut edge_ids: HashMap<(u32, u32), usize> = HashMap::new();
        let mut edge_points: Vec<DVec3> = Vec::new();
        let mut segments: Vec<[usize; 2]> = Vec::new();
        for tri in triangles {
            let beyond = tri.map(|v| side(v) >= 0.0);
            if beyond.iter().all(|&b| b) || beyond.iter().all(|&b| !b) {
                continue;
            }
            let mut ends = Vec::with_capacity(2);
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                if beyond[k] != beyond[(k + 1) % 3] {
                    let key = (a.min(b), a.max(b));
                    let id = *edge_ids.entry(key).or_insert_with(|| {
                        edge_points.push(point_on(key.0, key.1));
                        edge_points.len() - 1
                    });
                    ends.push(id);
                }
            }
            if let [a, b] = ends[..] {
                segments.push([a, b]);
            }
        }
        // Components of the section inside the band, by union-find over the crossed
        // edges; a component with an edge crossed once is an open chain.
        let (y_lo, y_hi) = y_range;
        let in_band = |id: usize| (y_lo..=y_hi).contains(&edge_points[id].y);
        // Crossings of each end's height and of the heights a step either side (a chain
        // that runs level near a height and crosses it once may cross it three times a
        // step away; clipped, it would cross it so after a vertex moves by a snap).
        let corner_depths_mm = [y_lo, y_hi].map(|height| {
            [-STEP_MM, 0.0, STEP_MM].map(|delta| {
                let level = height + delta;
                segments
                    .iter()
                    .filter_map(|&[a, b]| {
                        let (p, q) = (edge_points[a], edge_points[b]);
                        ((p.y >= level) != (q.y >= level))
                            .then(|| p.lerp(q, (level - p.y) / (q.y - p.y)).z)
                    })
                    .collect::<Vec<f64>>()
            })
        });
        segments.retain(|&[a, b]| in_band(a) && in_band(b));
        let mut parent: Vec<usize> = (0..edge_points.len()).collect();
        fn root(parent: &mut [usize], mut i: usize) -> usize {
            while parent[i] != i {
                parent[i] = parent[parent[i]];
                i = parent[i];
            }
            i
        }
        let mut uses = vec![0u8; edge_points.len()];
        for &[a, b] in &segments {
            uses[a] = uses[a].saturating_add(1);
            uses[b] = uses[b].saturating_add(1);
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            parent[ra] = rb;
        }
        let mut open: HashMap<usize, bool> = HashMap::new();
        for id in (0..edge_points.len()).filter(|&id| uses[id] > 0) {
            *open.entry(root(&mut parent, id)).or_default() |= uses[id] < 2;
        }
        let loops = open.values().filter(|&&is_open| !is_open).count();
        // Depth spread of each chain per height bin, over its points inside the band
        // (another chain, the back of a scan wrapping round the side, is not a fold).
        let mut depth: HashMap<(usize, i64), (f64, f64)> = HashMap::new();
        for &[a, b] in &segments {
            let (p, q) = (edge_points[a], edge_points[b]);
            let chain = root(&mut parent, a);
            // Sampled finely enough that a segment steeper than a bin lands in each.
            let steps = ((p.y - q.y).abs() / HEIGHT_BIN_MM).ceil().max(1.0) as usize;
            for s in 0..=steps {
                let r = p.lerp(q, s as f64 / steps as f64);
                let bin = ((r.y - y_lo) / HEIGHT_BIN_MM).floor() as i64;
                let range = depth
                    .entry((chain, bin))
                    .or_insert((f64::INFINITY, f64::NEG_INFINITY));
                *range = (range.0.min(r.z), range.1.max(r.z));
            }
        }
        let fold_depth_mm = depth.values().map(|d| d.1 - d.0).fold(0.0, f64::max);
        LateralSection {
            loops,
            fold_depth_mm,
            corner_depths_mm,
        }
    }
}

/// Height of the bins the depth spread is taken over (mm): about a scan's vertex
/// spacing, so a steep but single section (the side of the torso leaning in the
/// sagittal plane) spreads by no more than its slope times this.
const HEIGHT_BIN_MM: f64 = 1.0;

#[cfg(test)]
mod tests {
    use super::super::tests::identity_frame;
    use super::*;
    use crate::landmarks::Landmarks;
    use mesh::shapes::grid;

    /// A side wall facing -x: `x = -90 + slope_z * z - bump_mm * exp(-r² / 2σ²)`
    /// with `r` the distance from `(y, z) = (0, 10)` and σ = 4 mm, over y and z in
    /// [-40, 40] mm on a 0.5 mm grid.
    fn side_wall(slope_z: f64, bump_mm: f64) -> TriMesh {
        let mut wall = grid(160, 160, 0.5);
        wall.map_positions(|p| {
            let (y, z) = (p.x - 40.0, p.y - 40.0);
            let r2 = y * y + (z - 10.0) * (z - 10.0);
            let x = -90.0 + slope_z * z - bump_mm * (-r2 / 32.0).exp();
            DVec3::new(x, y, z)
        });
        wall
    }

    fn upright_at(x: f64) -> LateralPlane {
        LateralPlane {
            slope: 0.0,
            offset: x,
        }
    }

    #[test]
    fn a_surface_extruded_from_a_folded_curve_has_the_folds_depth() {
        // The curve in (y, z): up the line z = 0 to y = 0, 20 mm forward along y = 0,
        // then up again at z = 20; extruded along x. Its section by any plane x = c is
        // the curve itself, which at height 0 spans exactly 20 mm in depth.
        let mut surface = grid(120, 10, 1.0);
        surface.map_positions(|p| {
            let s = p.x;
            let (y, z) = if s <= 50.0 {
                (s - 50.0, 0.0)
            } else if s <= 70.0 {
                (0.0, s - 50.0)
            } else {
                (s - 70.0, 20.0)
            };
            DVec3::new(p.y * 2.0 - 10.0, y, z)
        });
        let section = LateralSection::measure(
            &surface.positions,
            &surface.triangles,
            upright_at(0.3),
            (-40.0, 40.0),
        );
        assert_eq!(section.loops, 0);
        assert!((section.fold_depth_mm - 20.0).abs() < 1e-9, "{section:?}");
    }

    #[test]
    fn a_plane_through_a_bumps_tip_cuts_a_loop_of_the_analytic_size() {
        // Flat wall at x = -90 with a 5 mm bump towards -x: the plane x = -92 meets it
        // on the circle exp(-r²/32) = 2/5, r = 4 sqrt(2 ln 2.5) = 5.42 mm, a loop whose
        // depth spread at the bump's height is its diameter (to the 0.5 mm grid's
        // chord error, under 0.1 mm). Beyond the tip (-95 mm) the plane meets nothing.
        let wall = side_wall(0.0, 5.0);
        let through = LateralSection::measure(
            &wall.positions,
            &wall.triangles,
            upright_at(-92.0),
            (-30.0, 30.0),
        );
        let diameter = 2.0 * 4.0 * (2.0 * 2.5f64.ln()).sqrt();
        assert_eq!(through.loops, 1);
        assert!(
            (through.fold_depth_mm - diameter).abs() < 0.1,
            "{through:?} vs {diameter}"
        );
        let beyond = LateralSection::measure(
            &wall.positions,
            &wall.triangles,
            upright_at(-95.5),
            (-30.0, 30.0),
        );
        assert_eq!(beyond.loops, 0);
        assert_eq!(beyond.fold_depth_mm, 0.0);
    }

    /// Whether the upright plane at `x` is clean by [`clear_of_grazing`]'s rule for
    /// loops and spread (the wall's sections cross each height once, so its corners are).
    fn clean_at(wall: &TriMesh, x: f64) -> bool {
        [-STEP_MM, 0.0, STEP_MM].iter().all(|&d| {
            let section = LateralSection::measure(
                &wall.positions,
                &wall.triangles,
                upright_at(x + d),
                (-30.0, 30.0),
            );
            section.loops == 0 && section.fold_depth_mm <= MAX_FOLD_FRACTION * 15.0
        })
    }

    #[test]
    fn a_plane_is_moved_only_off_a_graze() {
        // A wall leaning 2:1 (x = -90 + z / 2) crosses every upright plane along a
        // straight line at one depth: left where it is. With a 5 mm bump it is moved in
        // to the first position (in 0.5 mm steps) where the slab around it crosses
        // neither a loop nor a deep fold, checked here one step either side.
        let landmarks = Landmarks::new(|_| DVec3::new(0.0, 0.0, 0.0));
        let clip_box = ClipBox {
            x_min_mm: -90.2,
            x_max_mm: 50.0,
            y_min_mm: -30.0,
            y_max_mm: 30.0,
            ..ClipBox::default()
        };
        let frame = identity_frame();
        let flat = side_wall(0.5, 0.0);
        let (_, moves) = clear_of_grazing(clip_box, &flat, &flat, &frame, &landmarks, 15.0);
        assert_eq!(moves[0].moved_mm, 0.0);
        assert!(moves[0].is_clean());
        let bumped = side_wall(0.5, 5.0);
        assert!(!clean_at(&bumped, clip_box.x_min_mm));
        let (cleared, moves) =
            clear_of_grazing(clip_box, &bumped, &bumped, &frame, &landmarks, 15.0);
        assert!(moves[0].is_clean() && moves[0].moved_mm > 0.0, "{moves:?}");
        assert!(clean_at(&bumped, cleared.x_min_mm));
        assert!(!clean_at(&bumped, cleared.x_min_mm - STEP_MM));
        // The left plane meets no surface: it crosses neither height, and nothing
        // clears that.
        assert!(!moves[1].is_clean());
        // A breast landmark 1 mm in from the right plane stops it there, still grazing.
        let near_plane = Landmarks::new(|_| DVec3::new(-89.2, 0.0, 0.0));
        let (stopped, moves) =
            clear_of_grazing(clip_box, &bumped, &bumped, &frame, &near_plane, 15.0);
        assert!(
            moves[0].moved_mm <= 2.0 && !moves[0].is_clean(),
            "{moves:?}"
        );
        assert!(stopped.x_min_mm <= -88.0);
    }

    #[test]
    fn corners_count_crossings_near_the_base_s_front_one() {
        // Corner depths as `measure` gives them, at the height and a step either side.
        let section = |bottom: Vec<f64>, top: Vec<f64>| LateralSection {
            loops: 0,
            fold_depth_mm: 0.0,
            corner_depths_mm: [
                [bottom.clone(), bottom.clone(), bottom],
                [top.clone(), top.clone(), top],
            ],
        };
        let base = vec![section(vec![-80.0], vec![-40.0]); 3];
        let once = vec![section(vec![-79.0], vec![-41.0]); 3];
        assert_eq!(extra_corners(&base, &once), 0);
        // The scan crossing the top height three times within a millimetre: two extra.
        let wiggle = vec![section(vec![-79.0], vec![-41.0, -40.5, -40.2]); 3];
        assert_eq!(extra_corners(&base, &wiggle), 2);
        // A second layer 30 mm further back (a wrap round the side) is not a corner;
        // the base's frontmost crossing is the one the scan is held against.
        let wrapped = vec![section(vec![-79.0, -110.0], vec![-41.0, -70.0]); 3];
        let wrapped_base = vec![section(vec![-110.0, -80.0], vec![-70.0, -40.0]); 3];
        assert_eq!(extra_corners(&wrapped_base, &wrapped), 0);
        // A base that never reaches the bottom height: one missing corner.
        let short = vec![section(vec![], vec![-40.0]); 3];
        assert_eq!(extra_corners(&short, &once), 1);
    }
}
