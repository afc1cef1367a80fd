//! The pocket (issue 22): the region of the chest wall under a breast where the surgeon
//! may lay the implant. It is the fill-in behind the native breast widened over the
//! chest around it by [`PocketLimits::margin_mm`] (measured along the skin from the cut
//! curve), inside anatomical limits: not within [`PocketLimits::midline_clearance_mm`]
//! of the sternal midline, not past the anterior axillary line, and not below the
//! planned fold. The implant bed ([`crate::ImplantBed`]) is laid over the pocket, so an
//! implant wider than the native breast's base, or reaching below its fold, is
//! simulated rather than refused; the tissue over the widened part is the model's own
//! (the pocket keeps to the scan inside the model's clip box).
//!
//! Limits are in the standing frame (`x` to the patient's left from the midsagittal
//! plane through Pj, `y` up). Outside the native breast the bed lies [`crate::bed`]'s
//! shift under the skin, as inside it under the fill-in.

use crate::bed::{ChestCylinder, folded_triangles, shifted_surface};
use anatomy::breast::Side;
use anatomy::closed_surface::ClipBox;
use anatomy::fill_in::{FillIn, stitch};
use anatomy::{AnatomicalFrame, LandmarkName, Landmarks};
use glam::DVec3;
use implant::ImplantShape;
use mesh::OrderedMm;
use mesh::{Topology, TriMesh};
use std::cmp::Reverse;
use std::collections::BinaryHeap;

/// How far the pocket reaches over the chest beyond the native breast's cut curve
/// (mm, along the skin): room for a 125 mm implant on a breast whose base is 90 mm wide.
pub const DEFAULT_POCKET_MARGIN_MM: f64 = 40.0;

/// The band either side of the sternal midline no pocket enters (mm): medial dissection
/// stops 1-2 cm from the midline, or the pockets join over the sternum (symmastia).
pub const DEFAULT_MIDLINE_CLEARANCE_MM: f64 = 15.0;

/// How far beyond the lateral end of the native fold (PSMFll/PSMFlr) the pocket may
/// reach (mm): the lateral end of the fold lies on or just inside the anterior axillary
/// line, the lateral limit of a breast pocket.
pub const DEFAULT_LATERAL_BEYOND_FOLD_MM: f64 = 10.0;

/// Where a pocket may reach, per side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PocketLimits {
    /// Reach beyond the cut curve (mm, along the skin).
    pub margin_mm: f64,
    /// Distance kept from the midsagittal plane (mm).
    pub midline_clearance_mm: f64,
    /// Reach beyond the lateral end of the fold (mm, horizontally).
    pub lateral_beyond_fold_mm: f64,
    /// How far below the native fold's lowest point the pocket reaches: the planned
    /// fold lowering.
    pub fold_lowering: FoldLowering,
}

/// The planned fold lowering of one side.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum FoldLowering {
    /// As the ICE principle plans it for the implant ([`ice_fold_lowering_mm`]).
    #[default]
    ForImplant,
    /// This many millimetres below the native fold's lowest point (PSMF), whatever the
    /// implant.
    Mm(f64),
}

impl FoldLowering {
    /// The lowering (mm) for an implant of `shape` in a breast whose nipple lies
    /// `nipple_to_fold_mm` from the native fold's lowest point.
    pub fn mm(&self, shape: &ImplantShape, nipple_to_fold_mm: f64) -> f64 {
        match *self {
            FoldLowering::ForImplant => ice_fold_lowering_mm(shape, nipple_to_fold_mm),
            FoldLowering::Mm(mm) => mm,
        }
    }

    /// The deepest lowering any implant can get (mm): how far below the native fold a
    /// pocket is built.
    pub fn deepest_mm(&self) -> f64 {
        match *self {
            FoldLowering::ForImplant => MAX_ICE_FOLD_LOWERING_MM,
            FoldLowering::Mm(mm) => mm,
        }
    }
}

/// The ICE principle's planned lowering is capped here (mm): primary augmentations lower
/// the fold by up to about 3 cm; a larger excess asks for a smaller implant, not a
/// lower fold.
pub const MAX_ICE_FOLD_LOWERING_MM: f64 = 30.0;

/// The fold lowering (mm) the ICE principle plans (Mallucci and Branford 2016, Plast.
/// Reconstr. Surg. 137:1728): implant dimension `I` (half the implant's height plus its
/// projection) minus the breast's capacity `C` (nipple to fold) is the excess `E` by
/// which the new fold lies below the native one; none when the breast already has the
/// room, at most [`MAX_ICE_FOLD_LOWERING_MM`]. `C` is measured on the scan, straight and
/// at rest, where the surgeon measures it along the skin under maximal stretch: it is
/// shorter, so the lowering errs on the generous side.
pub fn ice_fold_lowering_mm(shape: &ImplantShape, nipple_to_fold_mm: f64) -> f64 {
    let implant_dimension_mm = shape.height_mm() / 2.0 + shape.projection_mm();
    (implant_dimension_mm - nipple_to_fold_mm).clamp(0.0, MAX_ICE_FOLD_LOWERING_MM)
}

impl Default for PocketLimits {
    fn default() -> PocketLimits {
        PocketLimits {
            margin_mm: DEFAULT_POCKET_MARGIN_MM,
            midline_clearance_mm: DEFAULT_MIDLINE_CLEARANCE_MM,
            lateral_beyond_fold_mm: DEFAULT_LATERAL_BEYOND_FOLD_MM,
            fold_lowering: FoldLowering::default(),
        }
    }
}

/// The lines a pocket may not cross, in the standing frame's coordinates (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PocketBounds {
    /// `x` towards this side: 1 on the left, -1 on the right.
    pub side_sign: f64,
    /// The side's medial limit: `x` towards the side at least this.
    pub medial_x_mm: f64,
    /// The side's lateral limit: `x` towards the side at most this.
    pub lateral_x_mm: f64,
    /// The planned fold: `y` at least this.
    pub floor_y_mm: f64,
}

impl PocketBounds {
    /// The bounds of one side's pocket from the landmarks, with the fold lowered by
    /// `fold_lowering_mm`.
    pub fn new(
        side: Side,
        frame: &AnatomicalFrame,
        landmarks: &Landmarks,
        limits: &PocketLimits,
        fold_lowering_mm: f64,
    ) -> PocketBounds {
        let lateral = match side {
            Side::Left => LandmarkName::PSMFll,
            Side::Right => LandmarkName::PSMFlr,
        };
        PocketBounds {
            side_sign: match side {
                Side::Left => 1.0,
                Side::Right => -1.0,
            },
            medial_x_mm: limits.midline_clearance_mm,
            lateral_x_mm: frame.to_local(landmarks.get(lateral)).x.abs()
                + limits.lateral_beyond_fold_mm,
            floor_y_mm: planned_fold_y_mm(side, frame, landmarks, fold_lowering_mm),
        }
    }

    /// Which limit `local` (standing frame, mm) lies beyond, and by how much (mm), if any.
    pub fn violation(&self, local: DVec3) -> Option<(&'static str, f64)> {
        let x = local.x * self.side_sign;
        [
            ("the sternal midline region", self.medial_x_mm - x),
            ("the anterior axillary line", x - self.lateral_x_mm),
            ("the planned fold", self.floor_y_mm - local.y),
        ]
        .into_iter()
        .filter(|&(_, beyond)| beyond > 0.0)
        .max_by(|a, b| a.1.total_cmp(&b.1))
    }
}

/// The native fold's lowest point (PSMF): its height in the standing frame (mm).
pub fn native_fold_y_mm(side: Side, frame: &AnatomicalFrame, landmarks: &Landmarks) -> f64 {
    frame.to_local(landmarks.get(fold_lowest(side))).y
}

/// The planned fold's height in the standing frame (mm): `fold_lowering_mm` below the
/// native fold's lowest point.
pub fn planned_fold_y_mm(
    side: Side,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    fold_lowering_mm: f64,
) -> f64 {
    native_fold_y_mm(side, frame, landmarks) - fold_lowering_mm
}

/// The straight distance from the nipple to the native fold's lowest point (mm).
pub fn nipple_to_fold_mm(side: Side, landmarks: &Landmarks) -> f64 {
    landmarks
        .get(nipple_of(side))
        .distance(landmarks.get(fold_lowest(side)))
}

/// The nipple landmark of `side`.
pub(crate) fn nipple_of(side: Side) -> LandmarkName {
    match side {
        Side::Left => LandmarkName::Pnl,
        Side::Right => LandmarkName::Pnr,
    }
}

/// The native fold's lowest point of `side` (PSMF).
pub(crate) fn fold_lowest(side: Side) -> LandmarkName {
    match side {
        Side::Left => LandmarkName::PSMFl,
        Side::Right => LandmarkName::PSMFr,
    }
}

/// A pocket's surface: the fill-in and the chest around it inside the bounds, its
/// outer boundary loop's vertices first (in loop order), as [`crate::ImplantBed::new`]
/// takes it.
#[derive(Debug, Clone)]
pub struct PocketSurface {
    pub mesh: TriMesh,
    pub boundary_count: usize,
    /// Per triangle: part of the fill-in (else of the chest around it).
    pub from_fill: Vec<bool>,
}

impl PocketSurface {
    /// The pocket without the chest triangles that fold over seen from `cylinder`'s
    /// axis once shifted `shift_mm` back (the crease of a fold, noise folds, the chest
    /// turning away at the side): a bed must be a graph over the cylinder. Repeated
    /// (the normals change as triangles go) up to [`FOLD_PASSES`] times; the fill-in's
    /// own triangles are kept (the bed tolerates a few of its folds, as without a
    /// pocket).
    pub fn without_folds(self, cylinder: &ChestCylinder, shift_mm: f64) -> Option<PocketSurface> {
        let mut surface = self;
        for _ in 0..FOLD_PASSES {
            let (_, positions) = shifted_surface(&surface.mesh, cylinder, shift_mm);
            let uv: Vec<_> = (positions.iter())
                .map(|&p| cylinder.to_cylindrical(p).truncate())
                .collect();
            let folded = folded_triangles(&uv, &surface.mesh.triangles);
            if !(folded.iter().zip(&surface.from_fill)).any(|(&f, &fill)| f && !fill) {
                break;
            }
            let (triangles, from_fill): (Vec<[u32; 3]>, Vec<bool>) = (surface
                .mesh
                .triangles
                .iter()
                .zip(&surface.from_fill)
                .zip(&folded))
            .filter(|&((_, &fill), &f)| fill || !f)
            .map(|((t, &fill), _)| (*t, fill))
            .unzip();
            surface = connected_with_fill(&surface.mesh.positions, &triangles, &from_fill)?;
        }
        Some(surface)
    }
}

/// Passes of [`PocketSurface::without_folds`].
const FOLD_PASSES: usize = 3;

/// The pocket of one breast: `fill` stitched into `base` (the scan without the breasts)
/// and widened over the base by `limits.margin_mm` (Dijkstra along the base's edges from
/// the cut curve), keeping base triangles whose corners all lie inside `bounds` and, in
/// the sternal frame, inside `clip_box` (the model's simulated region). `None` when the
/// result has no boundary loop (never for a fill-in with a cut curve).
pub fn pocket_surface(
    base: &TriMesh,
    fill: &FillIn,
    frame: &AnatomicalFrame,
    bounds: &PocketBounds,
    clip_box: Option<&ClipBox>,
    margin_mm: f64,
) -> Option<PocketSurface> {
    let stitched = stitch(base, fill);
    let base_triangles = base.triangles.len();
    let reach = distances_from(&stitched, base_triangles, &fill.boundary_to_base, margin_mm);
    let sternal = frame.sternal();
    let inside = |v: u32| {
        let p = stitched.positions[v as usize];
        reach[v as usize] <= margin_mm
            && bounds.violation(frame.to_local(p)).is_none()
            && clip_box.is_none_or(|b| b.contains(sternal.to_local(p)))
    };
    let (keep, from_fill): (Vec<[u32; 3]>, Vec<bool>) = stitched
        .triangles
        .iter()
        .enumerate()
        .filter(|&(t, tri)| t >= base_triangles || tri.iter().all(|&v| inside(v)))
        .map(|(t, tri)| (*tri, t >= base_triangles))
        .unzip();
    connected_with_fill(&stitched.positions, &keep, &from_fill)
}

/// The connected piece of `triangles` (over `positions`) that holds the fill-in's
/// first triangle, compacted, its longest boundary loop's vertices first.
fn connected_with_fill(
    positions: &[DVec3],
    triangles: &[[u32; 3]],
    from_fill: &[bool],
) -> Option<PocketSurface> {
    let candidate = TriMesh::from_used_vertices(positions, triangles);
    let (component, _) = Topology::new(&candidate).triangle_components();
    let fill_component = component[from_fill.iter().position(|&f| f)?];
    let (kept, kept_from_fill): (Vec<[u32; 3]>, Vec<bool>) = (candidate.triangles.iter())
        .zip(&component)
        .zip(from_fill)
        .filter(|&((_, &c), _)| c == fill_component)
        .map(|((t, _), &f)| (*t, f))
        .unzip();
    let piece = TriMesh::from_used_vertices(&candidate.positions, &kept);
    let loops = Topology::new(&piece).boundary_loops(&piece);
    let outer = loops
        .into_iter()
        .max_by(|a, b| perimeter(&piece.positions, a).total_cmp(&perimeter(&piece.positions, b)))?;
    let (mesh, boundary_count) = boundary_first(&piece, &outer);
    Some(PocketSurface {
        mesh,
        boundary_count,
        from_fill: kept_from_fill,
    })
}

/// Shortest distances along the edges of the first `base_triangles` triangles from
/// `sources` (0 there), explored up to `limit`; `f64::INFINITY` beyond.
fn distances_from(mesh: &TriMesh, base_triangles: usize, sources: &[u32], limit: f64) -> Vec<f64> {
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); mesh.positions.len()];
    for tri in &mesh.triangles[..base_triangles] {
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            neighbours[a as usize].push(b);
            neighbours[b as usize].push(a);
        }
    }
    let mut distance = vec![f64::INFINITY; mesh.positions.len()];
    let mut queue = BinaryHeap::new();
    for &s in sources {
        distance[s as usize] = 0.0;
        queue.push(Reverse((OrderedMm(0.0), s)));
    }
    while let Some(Reverse((OrderedMm(d), v))) = queue.pop() {
        if d > distance[v as usize] || d > limit {
            continue;
        }
        for &n in &neighbours[v as usize] {
            let next = d + mesh.positions[v as usize].distance(mesh.positions[n as usize]);
            if next < distance[n as usize] {
                distance[n as usize] = next;
                queue.push(Reverse((OrderedMm(next), n)));
            }
        }
    }
    distance
}

fn perimeter(positions: &[DVec3], boundary: &[u32]) -> f64 {
    (0..boundary.len())
        .map(|i| {
            let (a, b) = (boundary[i], boundary[(i + 1) % boundary.len()]);
            positions[a as usize].distance(positions[b as usize])
        })
        .sum()
}

/// `mesh` renumbered with `boundary`'s vertices first, in its order, and their count.
pub(crate) fn boundary_first(mesh: &TriMesh, boundary: &[u32]) -> (TriMesh, usize) {
    let mut order: Vec<u32> = boundary.to_vec();
    let mut placed = vec![false; mesh.positions.len()];
    for &v in boundary {
        placed[v as usize] = true;
    }
    order.extend((0..mesh.positions.len() as u32).filter(|&v| !placed[v as usize]));
    let mut new_index = vec![0u32; mesh.positions.len()];
    for (new, &old) in order.iter().enumerate() {
        new_index[old as usize] = new as u32;
    }
    let renumbered = TriMesh::new(
        order.iter().map(|&v| mesh.positions[v as usize]).collect(),
        mesh.triangles
            .iter()
            .map(|t| t.map(|v| new_index[v as usize]))
            .collect(),
    );
    (renumbered, boundary.len())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_name_the_limit_crossed_and_by_how_much() {
        let bounds = PocketBounds {
            side_sign: 1.0,
            medial_x_mm: 15.0,
            lateral_x_mm: 140.0,
            floor_y_mm: -220.0,
        };
        assert_eq!(bounds.violation(DVec3::new(60.0, -150.0, 0.0)), None);
        assert_eq!(
            bounds.violation(DVec3::new(10.0, -150.0, 0.0)),
            Some(("the sternal midline region", 5.0))
        );
        // past the midline: measured from the side's own limit
        assert_eq!(
            bounds.violation(DVec3::new(-20.0, -150.0, 0.0)),
            Some(("the sternal midline region", 35.0))
        );
        assert_eq!(
            bounds.violation(DVec3::new(150.0, -150.0, 0.0)),
            Some(("the anterior axillary line", 10.0))
        );
        assert_eq!(
            bounds.violation(DVec3::new(60.0, -232.0, 0.0)),
            Some(("the planned fold", 12.0))
        );
    }

    #[test]
    fn a_grid_widened_around_a_square_keeps_its_outer_loop_first() {
        // A 10 x 10 grid of 10 mm cells on z = 0 centred on the origin; the "fill" is the
        // middle 2 x 2 cells stitched back in. Widened by 10 mm along the edges it takes
        // the eight cells beside them, and of the corner cells (their far corner 20 mm
        // away) the two triangles whose diagonal avoids that corner: a plus sign with
        // two corners cut off diagonally.
        let mut grid = mesh::shapes::grid(10, 10, 10.0);
        grid.map_positions(|p| p - DVec3::new(50.0, 50.0, 0.0));
        let inner = |p: DVec3| p.x.abs() <= 10.0 + 1e-9 && p.y.abs() <= 10.0 + 1e-9;
        let centre =
            |t: &[u32; 3]| t.iter().map(|&v| grid.positions[v as usize]).sum::<DVec3>() / 3.0;
        let fill_triangles: Vec<[u32; 3]> = grid
            .triangles
            .iter()
            .copied()
            .filter(|t| inner(centre(t)))
            .collect();
        let base_triangles: Vec<[u32; 3]> = grid
            .triangles
            .iter()
            .copied()
            .filter(|t| !inner(centre(t)))
            .collect();
        let base = TriMesh::new(grid.positions.clone(), base_triangles);
        // the fill-in with its boundary first: the 8 vertices round the middle square
        let fill_piece = TriMesh::from_used_vertices(&grid.positions, &fill_triangles);
        let loops = Topology::new(&fill_piece).boundary_loops(&fill_piece);
        let (ordered, boundary_count) = boundary_first(&fill_piece, &loops[0]);
        let boundary_to_base = ordered.positions[..boundary_count]
            .iter()
            .map(|p| {
                grid.positions
                    .iter()
                    .position(|q| q.distance(*p) < 1e-9)
                    .unwrap() as u32
            })
            .collect();
        let fill = FillIn {
            mesh: ordered,
            boundary_to_base,
        };
        let frame = AnatomicalFrame::from_landmarks(
            &Landmarks::new(|name| match name {
                LandmarkName::Pj => DVec3::new(-100.0, 100.0, 0.0),
                LandmarkName::Px => DVec3::new(-100.0, 0.0, 0.0),
                LandmarkName::Pcl => DVec3::new(0.0, 100.0, 0.0),
                LandmarkName::Pcr => DVec3::new(-200.0, 100.0, 0.0),
                _ => DVec3::ZERO,
            }),
            anatomy::Up::FILE_VERTICAL,
        )
        .unwrap();
        let open = PocketBounds {
            side_sign: 1.0,
            medial_x_mm: -1e3,
            lateral_x_mm: 1e3,
            floor_y_mm: -1e3,
        };
        let pocket = pocket_surface(&base, &fill, &frame, &open, None, 10.0).unwrap();
        // 12 cells of 2 triangles and 2 corner triangles; the outline of 14 vertices
        // comes first
        assert_eq!(pocket.mesh.triangles.len(), 26);
        assert_eq!(pocket.boundary_count, 14);
        for p in &pocket.mesh.positions[..14] {
            let reach = p.x.abs().max(p.y.abs());
            assert!(
                (reach - 20.0).abs() < 1e-9 || (p.x.abs() - 10.0).abs() < 1e-9,
                "{p}"
            );
        }
        assert!(
            pocket.mesh.positions[14..]
                .iter()
                .all(|p| p.x.abs().max(p.y.abs()) < 20.0)
        );
        // A floor at y = -10 mm (the frame's origin is Pj at y = 100) drops the lower arm
        // and the corner triangle beside it.
        let floored = PocketBounds {
            floor_y_mm: -110.0,
            ..open
        };
        let pocket = pocket_surface(&base, &fill, &frame, &floored, None, 10.0).unwrap();
        assert!(pocket.mesh.positions.iter().all(|p| p.y >= -10.0 - 1e-9));
        assert_eq!(pocket.mesh.triangles.len(), 21);
    }

    /// `E = I - C` with `I` half the height plus the projection (Mallucci and Branford
    /// 2016), clamped to 0..=30 mm: by hand for a 115 x 32 mm round implant.
    #[test]
    fn the_ice_lowering_is_the_implant_dimension_less_the_capacity() {
        let round = ImplantShape::Round(implant::RoundImplant::new(115.0, 32.0).unwrap());
        for (capacity_mm, expected_mm) in [(77.5, 12.0), (89.5, 0.0), (100.0, 0.0), (40.0, 30.0)] {
            let lowering_mm = ice_fold_lowering_mm(&round, capacity_mm);
            assert!(
                (lowering_mm - expected_mm).abs() < 1e-9,
                "{capacity_mm}: {lowering_mm}"
            );
        }
        assert_eq!(FoldLowering::Mm(7.0).mm(&round, 50.0), 7.0);
        assert_eq!(
            FoldLowering::ForImplant.deepest_mm(),
            MAX_ICE_FOLD_LOWERING_MM
        );
    }
}
