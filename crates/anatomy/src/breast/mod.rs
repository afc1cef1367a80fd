//! The breast model (paper IV-B, IV-C, VI-C): a cut curve around each breast, the scan
//! cut along both into left breast, right breast and base, the holes in the base filled
//! (the rear wall), and each breast's volume and quadrant volumes.
//!
//! # Steps of [`build_breast_model`]
//! 1. Scanner holes are closed with the fill-in ([`close_scan_holes`]), so a cut curve can
//!    run across a hole where the scanner missed the lateral fold, and the skin no camera
//!    saw (the underside of a full or hanging breast) is reconstructed as a smooth
//!    surface continuing the seen skin's positions and tangents. The holes lying
//!    entirely inside a breast are listed in [`BreastModel::holes_in_breasts`]; each
//!    breast's reconstructed part ([`Reconstructed`]: vertices, area, volume over flat
//!    patches) is kept apart, and a breast more than
//!    [`BreastOptions::max_reconstructed_share`] reconstructed is an error.
//! 2. Cut curves ([`cut_curve`]): the control points (the defaults of
//!    [`ControlPoints::from_landmarks`] or the user's) are snapped to the surface, a
//!    periodic C2 cubic spline ([`ClosedSpline`]) is sampled through them about every
//!    millimetre and projected onto the surface by triangle walking
//!    ([`SurfaceCurve::project`]); the curve runs counter-clockwise seen from the front,
//!    so its inside is the breast.
//! 3. Both curves cut the scan in one call ([`cut_along_curves`]): region `Inside(0)` is
//!    the left breast, `Inside(1)` the right one, `Outside` the base.
//! 4. Each hole of the base is filled ([`fill_hole`]); the filled base is the base with
//!    both fill-ins stitched in.
//! 5. Each breast patch is closed by its fill-in (reversed, so the closed surface points
//!    outward; they share the loop vertices exactly), and its volume follows from the
//!    divergence theorem; the quadrant volumes from [`quadrant_volumes_ml`].

mod control_points;
mod quadrants;
mod reconstructed;
mod spline;

pub use control_points::{ControlPoints, DEFAULT_CONTROL_POINT_ROLES, DEFAULT_PC_RATIO};
pub use quadrants::{QuadrantError, QuadrantLines, QuadrantVolumes, quadrant_volumes_ml};
pub use reconstructed::{
    DEFAULT_MAX_RECONSTRUCTED_SHARE, Reconstructed, reconstructed_part, reconstructed_triangles,
};
pub use spline::{ClosedSpline, MIN_CONTROL_POINT_SPACING_MM, SplineError};

use crate::fill_in::{FillIn, FillInError, FillInParams, fill_hole, stitch};
use crate::frame::AnatomicalFrame;
use crate::landmarks::{LandmarkName, Landmarks, MAX_SNAP_DISTANCE_MM, ON_SURFACE_MM};
use crate::measure::{MeasuredSurface, mean_normal_near};
use crate::place::Place;
use crate::scan_holes::{ClosedHole, ClosedScan, OpenHole, close_scan_holes, loop_length};
use glam::DVec3;
use mesh::{
    CurveError, CutError, CutMesh, MeshPart, PathError, Region, SurfaceCurve, SurfaceIndex,
    Topology, TriMesh, cut_along_curves,
};
use std::collections::HashMap;
use std::path::PathBuf;

/// Default distance (mm) between the spline samples projected onto the surface: finer
/// than the scan's 1.5-3 mm triangles, so the cut follows the spline closely.
pub const DEFAULT_SAMPLE_SPACING_MM: f64 = 1.0;

/// Marks a vertex that a part does not contain.
const NOT_IN_PART: u32 = u32::MAX;

/// Cut-curve points within this fraction of an edge of a mesh vertex move onto it (and
/// points inside a triangle this close to an edge are dropped) before cutting, so the cut
/// leaves no sliver triangles: their normals are noise, and they would make the angle
/// across the stitch meaningless. A point moves by at most 0.15 of an edge (about 0.3 mm
/// on a scan), well below the scanner's noise.
const CUT_SNAP_FRACTION: f64 = 0.15;

/// The patient's left or right breast.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Side {
    Left,
    Right,
}

/// The landmarks of one side.
struct SideLandmarks {
    nipple: LandmarkName,
    fold_lowest: LandmarkName,
    fold_medial: LandmarkName,
    fold_lateral: LandmarkName,
    clavicle: LandmarkName,
}

impl Side {
    /// Both sides, in the order of the cut curves: left (curve 0), right (curve 1).
    pub const BOTH: [Side; 2] = [Side::Left, Side::Right];

    /// `"left"` or `"right"`.
    pub fn name(self) -> &'static str {
        match self {
            Side::Left => "left",
            Side::Right => "right",
        }
    }

    /// The other side.
    pub fn opposite(self) -> Side {
        match self {
            Side::Left => Side::Right,
            Side::Right => Side::Left,
        }
    }

    fn landmark_names(self) -> SideLandmarks {
        use LandmarkName::*;
        match self {
            Side::Left => SideLandmarks {
                nipple: Pnl,
                fold_lowest: PSMFl,
                fold_medial: PSMFml,
                fold_lateral: PSMFll,
                clavicle: Pcl,
            },
            Side::Right => SideLandmarks {
                nipple: Pnr,
                fold_lowest: PSMFr,
                fold_medial: PSMFmr,
                fold_lateral: PSMFlr,
                clavicle: Pcr,
            },
        }
    }
}

impl QuadrantLines {
    /// The lines of one breast from its landmarks (nipple, clavicle point, the fold's
    /// lateral end, lowest point and medial end).
    pub fn of_breast(side: Side, landmarks: &Landmarks) -> QuadrantLines {
        let names = side.landmark_names();
        QuadrantLines {
            nipple: landmarks.get(names.nipple),
            upper: landmarks.get(names.clavicle),
            lateral: landmarks.get(names.fold_lateral),
            lower: landmarks.get(names.fold_lowest),
            medial: landmarks.get(names.fold_medial),
        }
    }
}

impl std::fmt::Display for Side {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Settings of [`build_breast_model`].
#[derive(Debug, Clone, PartialEq)]
pub struct BreastOptions {
    /// Where the upper control point lies on the on-surface line from Pc to Pn (0..1).
    pub pc_ratio: f64,
    /// Distance between spline samples (mm).
    pub sample_spacing_mm: f64,
    /// Parameters of the fill-ins behind the breasts. Unless `cylinder_axis` is set, the
    /// fill-ins are built over a cylinder about the chest's own axis near the anatomical
    /// frame's `y` axis (the sternum's direction).
    pub fill_in: FillInParams,
    /// The user's control points; `None`: the defaults from the landmarks.
    pub control_points: Option<ControlPoints>,
    /// A breast whose skin is more than this share (0..1) reconstructed (scanner holes
    /// closed by the fill-in) is an error: the scan lacks that breast.
    pub max_reconstructed_share: f64,
}

impl Default for BreastOptions {
    fn default() -> BreastOptions {
        BreastOptions {
            pc_ratio: DEFAULT_PC_RATIO,
            sample_spacing_mm: DEFAULT_SAMPLE_SPACING_MM,
            fill_in: FillInParams::default(),
            control_points: None,
            max_reconstructed_share: DEFAULT_MAX_RECONSTRUCTED_SHARE,
        }
    }
}

/// One breast of a [`BreastModel`].
#[derive(Debug, Clone)]
pub struct Breast {
    pub side: Side,
    /// The control points, snapped to the surface (mm).
    pub control_points: Vec<DVec3>,
    /// The cut curve on [`BreastModel::surface`], counter-clockwise seen from the front.
    pub curve: SurfaceCurve,
    /// The breast's skin: the part of the cut mesh inside the curve.
    pub patch: MeshPart,
    /// The fill-in closing the base behind the breast; its boundary indices refer to
    /// [`BreastModel::base`].
    pub fill: FillIn,
    /// The patch closed by the reversed fill-in: watertight, outward oriented.
    pub closed: TriMesh,
    /// Volume enclosed by `closed` (ml).
    pub volume_ml: f64,
    /// The volumes of its quadrants (ml); they add up to `volume_ml`.
    pub quadrant_volume_ml: QuadrantVolumes,
    /// The part of `patch` the scanner did not see, filled in.
    pub reconstructed: Reconstructed,
}

/// Both breasts cut out of a scan, and the rear wall.
#[derive(Debug, Clone)]
pub struct BreastModel {
    /// The scan with its holes closed: the surface the curves lie on. Its first vertices
    /// and triangles are the scan's.
    pub surface: TriMesh,
    /// The scanner holes closed before cutting.
    pub holes_closed: Vec<ClosedHole>,
    /// Holes that could not be closed (away from the cut curves and breasts).
    pub holes_left_open: Vec<OpenHole>,
    /// The closed holes that lie inside a breast region (small dropouts).
    pub holes_in_breasts: Vec<BreastHole>,
    /// `surface` cut along both curves: region `Inside(0)` is the left breast,
    /// `Inside(1)` the right one.
    pub cut_mesh: CutMesh,
    pub left: Breast,
    pub right: Breast,
    /// The scan without the breasts.
    pub base: MeshPart,
    /// The base with both fill-ins stitched in (base vertices and triangles first).
    pub filled_base: TriMesh,
}

impl BreastModel {
    /// The breast of one side.
    pub fn breast(&self, side: Side) -> &Breast {
        match side {
            Side::Left => &self.left,
            Side::Right => &self.right,
        }
    }

    /// For each of the first `scan_vertex_count` vertices (the scan's, which
    /// [`BreastModel::surface`] and the cut mesh start with), the breast whose region
    /// (inside its cut curve) it lies in, or `None` on the base. A vertex on a cut curve
    /// belongs to the breast.
    pub fn scan_vertex_sides(&self, scan_vertex_count: usize) -> Vec<Option<Side>> {
        let mut sides = vec![None; scan_vertex_count];
        let cut = &self.cut_mesh;
        for (corners, region) in cut.mesh.triangles.iter().zip(&cut.regions) {
            if let Region::Inside(curve) = *region {
                for &v in corners {
                    if let Some(side) = sides.get_mut(v as usize) {
                        *side = Some(Side::BOTH[curve.min(1)]);
                    }
                }
            }
        }
        sides
    }

    /// How smoothly the rear wall meets the base across each cut curve, left then right
    /// (the order of [`Side::BOTH`]); see [`max_stitch_angle_deg`].
    pub fn stitch_angles(&self) -> [StitchAngles; 2] {
        let base = &self.base.mesh;
        let base_topology = Topology::new(base);
        Side::BOTH.map(|side| {
            let fill = &self.breast(side).fill;
            let fill_topology = Topology::new(&fill.mesh);
            let angle = |radius_mm| {
                max_stitch_angle_deg(base, &base_topology, fill, &fill_topology, radius_mm)
            };
            StitchAngles {
                averaged_deg: angle(STITCH_NORMAL_RADIUS_MM),
                single_triangles_deg: angle(0.0),
            }
        })
    }
}

/// How smoothly the rear wall meets the base across one cut curve: the largest angle
/// between the base's and the fill-in's normals (degrees).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StitchAngles {
    /// With each side's normals averaged over [`STITCH_NORMAL_RADIUS_MM`].
    pub averaged_deg: f64,
    /// Between the two single triangles on either side of each edge of the curve.
    pub single_triangles_deg: f64,
}

/// A scanner hole inside a breast region.
#[derive(Debug, Clone, PartialEq)]
pub struct BreastHole {
    pub side: Side,
    /// Length of its boundary (mm).
    pub perimeter_mm: f64,
    /// Centre of its boundary vertices (mm).
    pub centre: [f64; 3],
}

/// Why the breast model could not be built. Errors about one breast start with its name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BreastError {
    #[error("the upper control point ratio {0} is out of range: expected a number between 0 and 1")]
    InvalidPcRatio(f64),
    #[error("the spline sample spacing {0} mm is out of range: expected a positive length")]
    InvalidSampleSpacing(f64),
    #[error(
        "the largest reconstructed share of a breast {0} is out of range: expected a number between 0 and 1"
    )]
    InvalidReconstructedShare(f64),
    #[error("control point file {}: {message}", path.display())]
    ControlPointFile { path: PathBuf, message: String },
    #[error("{side} breast: the on-surface line from {from} to {to} failed: {source}")]
    Section {
        side: Side,
        from: String,
        to: String,
        #[source]
        source: PathError,
    },
    #[error("{side} breast: {count} control points; a closed cut curve needs at least 3")]
    TooFewControlPoints { side: Side, count: usize },
    #[error(
        "{side} breast: control point {index} at ({:.1}, {:.1}, {:.1}) mm is {distance_mm:.1} mm off the scan (at most {MAX_SNAP_DISTANCE_MM} mm)",
        position[0], position[1], position[2]
    )]
    ControlPointOffSurface {
        side: Side,
        index: usize,
        position: [f64; 3],
        distance_mm: f64,
    },
    #[error(
        "{side} breast: control point {index} and the next one are closer than {MIN_CONTROL_POINT_SPACING_MM} mm"
    )]
    CoincidentControlPoints { side: Side, index: usize },
    #[error("{side} breast: the cut curve cannot be laid on the scan: {source}{hint}")]
    Curve {
        side: Side,
        #[source]
        source: CurveError,
        /// What to do, where the failure has a place: the nearest control point to
        /// move (empty otherwise).
        hint: String,
    },
    #[error(
        "{side} breast: the cut curve runs along the scan's border near ({:.1}, {:.1}, {:.1}) mm, so the breast is not surrounded by scanned chest: move its control points inwards",
        position[0], position[1], position[2]
    )]
    CurveOnBorder { side: Side, position: [f64; 3] },
    #[error(
        "the left and right cut curves touch or cross near ({:.1}, {:.1}, {:.1}) mm: move their medial control points apart",
        position[0], position[1], position[2]
    )]
    CurvesTouch { position: [f64; 3] },
    #[error("cutting the scan failed (cut curve 0 is the left breast's, 1 the right's): {0}")]
    Cut(CutError),
    #[error(
        "{side} breast: {:.0}% of its skin ({:.0} of {:.0} cm²) was not seen by the scanner, more than the {:.0}% the model reconstructs: too little of this breast was scanned to measure it; rescan with the breast facing the cameras",
        100.0 * reconstructed_area_mm2 / area_mm2, reconstructed_area_mm2 / 100.0, area_mm2 / 100.0, 100.0 * max_share
    )]
    MostlyUnscanned {
        side: Side,
        reconstructed_area_mm2: f64,
        area_mm2: f64,
        max_share: f64,
        /// Around the unseen skin.
        place: Option<Place>,
    },
    #[error("{side} breast: the fill-in behind the breast failed: {source}")]
    FillIn {
        side: Side,
        #[source]
        source: FillInError,
        /// Around the cut curve.
        place: Option<Place>,
    },
    #[error(
        "{side} breast: the breast surface is not closed ({open_edges} open edges): a scanner hole inside the breast could not be filled; rescan or move the cut curve"
    )]
    BreastOpen {
        side: Side,
        open_edges: usize,
        /// Around the open edges.
        place: Option<Place>,
    },
    #[error(
        "{side} breast: the closed breast surface encloses {volume_ml:.1} ml; the cut curve does not enclose the breast"
    )]
    NotEnclosed {
        side: Side,
        volume_ml: f64,
        /// Around the cut curve.
        place: Option<Place>,
    },
    #[error("{side} breast: quadrants: {source}")]
    Quadrants {
        side: Side,
        #[source]
        source: QuadrantError,
        /// The nipple the quadrant lines run from.
        place: Place,
    },
}

impl BreastError {
    /// Where on the body the problem lies (mm, the scan's file coordinates), for the
    /// errors that have a place: `None` for invalid options and files.
    pub fn place(&self) -> Option<Place> {
        match self {
            BreastError::ControlPointOffSurface { position, .. }
            | BreastError::CurveOnBorder { position, .. }
            | BreastError::CurvesTouch { position } => Some(Place::at(*position)),
            BreastError::Curve { source, .. } => source.position().map(Place::at),
            BreastError::Cut(
                CutError::Triangulation { position, .. }
                | CutError::LabelConflict { position }
                | CutError::CurvesTouch { position, .. },
            ) => Some(Place::at(*position)),
            BreastError::Cut(
                CutError::Curve { source, .. } | CutError::TopologyMismatch(source),
            ) => source.position().map(Place::at),
            BreastError::MostlyUnscanned { place, .. }
            | BreastError::FillIn { place, .. }
            | BreastError::BreastOpen { place, .. }
            | BreastError::NotEnclosed { place, .. } => *place,
            BreastError::Quadrants { place, .. } => Some(*place),
            // Settings, files, a line between two named landmarks, a curve with too few
            // points or a cut with nothing to cut: no one place on the body.
            BreastError::InvalidPcRatio(_)
            | BreastError::InvalidSampleSpacing(_)
            | BreastError::InvalidReconstructedShare(_)
            | BreastError::ControlPointFile { .. }
            | BreastError::Section { .. }
            | BreastError::TooFewControlPoints { .. }
            | BreastError::CoincidentControlPoints { .. }
            | BreastError::Cut(CutError::NoCurves | CutError::CurveInsideTriangle { .. }) => None,
        }
    }
}

/// Builds both breasts and the rear wall from a scan (mm) with its topology and spatial
/// index, the standing frame and the landmarks (on the surface). See the module
/// documentation for the steps. The model is built in the frame's body axes
/// ([`AnatomicalFrame::sternal`]): it follows the thorax, not the way she stood.
pub fn build_breast_model(
    scan: &TriMesh,
    topology: &Topology,
    index: &SurfaceIndex,
    frame: &AnatomicalFrame,
    landmarks: &Landmarks,
    options: &BreastOptions,
) -> Result<BreastModel, BreastError> {
    let standing = frame;
    let frame = &frame.sternal();
    check_options(options)?;
    let hole_params = FillInParams {
        cylinder_axis: Some(frame.up()),
        ..FillInParams::default()
    };
    let closed_scan = close_scan_holes(scan, topology, &hole_params);
    let closed_topology =
        (!closed_scan.closed.is_empty()).then(|| Topology::new(&closed_scan.mesh));
    // Control points are put on the surface as nearest points and on-surface lines:
    // over a hole the scan's own index would put them on the hole's rim or the back of
    // the torso, so the closed scan gets its own. It starts with the scan's triangles, so
    // points located on the scan stay valid on it.
    let closed_index = closed_topology
        .is_some()
        .then(|| SurfaceIndex::new(&closed_scan.mesh))
        .flatten();
    let surface = MeasuredSurface {
        mesh: &closed_scan.mesh,
        topology: closed_topology.as_ref().unwrap_or(topology),
        index: closed_index.as_ref().unwrap_or(index),
    };
    let control_points = match &options.control_points {
        Some(points) => points.clone(),
        None => ControlPoints::from_landmarks(&surface, standing, landmarks, options.pc_ratio)?,
    };
    let roles = options
        .control_points
        .is_none()
        .then_some(&DEFAULT_CONTROL_POINT_ROLES[..]);
    let [left_curve, right_curve] = Side::BOTH.map(|side| {
        cut_curve(
            &surface,
            frame,
            side,
            control_points.side(side),
            roles,
            options.sample_spacing_mm,
        )
    });
    let (left_points, left_curve) = left_curve?;
    let (right_points, right_curve) = right_curve?;

    let cut_mesh = cut_along_curves(
        surface.mesh,
        surface.topology,
        &[left_curve.clone(), right_curve.clone()],
    )
    .map_err(cut_error)?;
    let holes_in_breasts = holes_in_breasts(scan, topology, &cut_mesh);

    let base = cut_mesh.part(Region::Outside);
    let to_base = inverse_map(&base.vertex_map, cut_mesh.mesh.vertex_count());
    // The chest wall behind a breast wraps around an axis near the body's long axis.
    let fill_params = FillInParams {
        cylinder_axis: options.fill_in.cylinder_axis.or(Some(frame.up())),
        ..options.fill_in
    };
    let inputs = BreastInputs {
        scan,
        closed_scan: &closed_scan,
        closed_index: closed_index.as_ref(),
        cut_mesh: &cut_mesh,
        base: &base,
        to_base: &to_base,
        fill_params: &fill_params,
        frame,
        landmarks,
        options,
    };
    let left = inputs.breast(Side::Left, left_points, left_curve)?;
    let right = inputs.breast(Side::Right, right_points, right_curve)?;
    let filled_base = stitch(&stitch(&base.mesh, &left.fill), &right.fill);
    Ok(BreastModel {
        surface: closed_scan.mesh,
        holes_closed: closed_scan.closed,
        holes_left_open: closed_scan.left_open,
        holes_in_breasts,
        cut_mesh,
        left,
        right,
        base,
        filled_base,
    })
}

/// What [`build_breast_model`] has ready, shared by both breasts, when it makes each
/// breast from its cut curve.
struct BreastInputs<'a> {
    scan: &'a TriMesh,
    closed_scan: &'a ClosedScan,
    closed_index: Option<&'a SurfaceIndex>,
    cut_mesh: &'a CutMesh,
    base: &'a MeshPart,
    /// Cut-mesh vertex to base vertex ([`NOT_IN_PART`] off the base).
    to_base: &'a [u32],
    fill_params: &'a FillInParams,
    frame: &'a AnatomicalFrame,
    landmarks: &'a Landmarks,
    options: &'a BreastOptions,
}

impl BreastInputs<'_> {
    /// The breast of `side` inside its cut curve: its patch, the fill-in behind it, the
    /// closed breast, its volumes and its reconstructed share.
    fn breast(
        &self,
        side: Side,
        control_points: Vec<DVec3>,
        curve: SurfaceCurve,
    ) -> Result<Breast, BreastError> {
        let Self {
            scan,
            closed_scan,
            closed_index,
            cut_mesh,
            base,
            to_base,
            fill_params,
            frame,
            landmarks,
            options,
        } = *self;
        let curve_index = side as usize;
        let cut_loop = &cut_mesh.loops[curve_index];
        let base_loop: Vec<u32> = cut_loop.iter().map(|&v| to_base[v as usize]).collect();
        if let Some(k) = base_loop.iter().position(|&v| v == NOT_IN_PART) {
            let position = cut_mesh.mesh.positions[cut_loop[k] as usize].to_array();
            return Err(BreastError::CurveOnBorder { side, position });
        }
        // Around the cut curve: where the errors of a breast as a whole are shown.
        let curve_place = || {
            let points: Vec<DVec3> = (cut_loop.iter())
                .map(|&v| cut_mesh.mesh.positions[v as usize])
                .collect();
            Place::around(&points)
        };
        let fill = fill_hole(&base.mesh, &base_loop, fill_params).map_err(|source| {
            BreastError::FillIn {
                side,
                source,
                place: curve_place(),
            }
        })?;
        let patch = cut_mesh.part(Region::Inside(curve_index));
        let to_patch = inverse_map(&patch.vertex_map, cut_mesh.mesh.vertex_count());
        if let Some(&v) = cut_loop
            .iter()
            .find(|&&v| to_patch[v as usize] == NOT_IN_PART)
        {
            let position = cut_mesh.mesh.positions[v as usize].to_array();
            return Err(BreastError::CurveOnBorder { side, position });
        }
        let reconstructed = reconstructed_part(
            &patch.mesh,
            reconstructed_triangles(
                cut_mesh,
                Region::Inside(curve_index),
                scan.triangle_count(),
                closed_scan.mesh.triangle_count(),
                closed_index,
            ),
        );
        if reconstructed.area_share > options.max_reconstructed_share {
            return Err(BreastError::MostlyUnscanned {
                side,
                reconstructed_area_mm2: reconstructed.area_mm2,
                area_mm2: patch.mesh.area(),
                max_share: options.max_reconstructed_share,
                place: Place::around(&flagged_centres(&patch.mesh, &reconstructed.triangle_flags)),
            });
        }
        let closed = close_patch(&patch.mesh, &fill, cut_loop, &to_patch);
        let closed_topology = Topology::new(&closed);
        let open_edges = closed_topology.boundary_edge_count;
        if open_edges > 0 {
            let open: Vec<DVec3> = (closed_topology.boundary_loops(&closed).iter().flatten())
                .map(|&v| closed.positions[v as usize])
                .collect();
            return Err(BreastError::BreastOpen {
                side,
                open_edges,
                place: Place::around(&open),
            });
        }
        let volume_ml = closed.signed_volume() / 1000.0;
        let encloses = volume_ml > 0.0;
        if !encloses {
            return Err(BreastError::NotEnclosed {
                side,
                volume_ml,
                place: curve_place(),
            });
        }
        let lines = QuadrantLines::of_breast(side, landmarks);
        let quadrant_volume_ml =
            quadrant_volumes_ml(&closed, &lines, frame.anterior()).map_err(|source| {
                BreastError::Quadrants {
                    side,
                    source,
                    place: Place::at(lines.nipple.to_array()),
                }
            })?;
        Ok(Breast {
            side,
            control_points,
            curve,
            patch,
            fill,
            closed,
            volume_ml,
            quadrant_volume_ml,
            reconstructed,
        })
    }
}

/// The centres of the triangles of `mesh` whose flag is set.
fn flagged_centres(mesh: &TriMesh, flags: &[bool]) -> Vec<DVec3> {
    (0..mesh.triangle_count())
        .filter(|&t| flags.get(t).copied().unwrap_or(false))
        .map(|t| mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0)
        .collect()
}

/// Fails on a sample spacing or a reconstructed share no model can be built with.
fn check_options(options: &BreastOptions) -> Result<(), BreastError> {
    if !(options.sample_spacing_mm > 0.0 && options.sample_spacing_mm.is_finite()) {
        return Err(BreastError::InvalidSampleSpacing(options.sample_spacing_mm));
    }
    if !(0.0..=1.0).contains(&options.max_reconstructed_share) {
        return Err(BreastError::InvalidReconstructedShare(
            options.max_reconstructed_share,
        ));
    }
    Ok(())
}

/// Closest-point steps a control point takes at most until it finds itself on the
/// surface (one almost always).
const MAX_SNAP_STEPS: usize = 3;

/// The cut curve of one breast through `control_points` (mm, at most
/// [`MAX_SNAP_DISTANCE_MM`] off the surface), sampled every `sample_spacing_mm`:
/// returns the control points snapped to the surface (a point already on it, within
/// [`ON_SURFACE_MM`], kept as given, so that the snapped points snap to themselves) and
/// the curve on `surface.mesh`, counter-clockwise seen from the front.
pub fn cut_curve(
    surface: &MeasuredSurface<'_>,
    frame: &AnatomicalFrame,
    side: Side,
    control_points: &[DVec3],
    roles: Option<&[&str]>,
    sample_spacing_mm: f64,
) -> Result<(Vec<DVec3>, SurfaceCurve), BreastError> {
    let mut start_triangle = 0;
    let mut snapped = Vec::with_capacity(control_points.len());
    for (index, &point) in control_points.iter().enumerate() {
        let closest = surface.index.closest_point(point);
        if closest.distance.is_nan() || closest.distance > MAX_SNAP_DISTANCE_MM {
            return Err(BreastError::ControlPointOffSurface {
                side,
                index,
                position: point.to_array(),
                distance_mm: closest.distance,
            });
        }
        // snapped until the point finds itself on the surface: the model folder's
        // control_points.json then rebuilds the same curve
        let (mut kept, mut found) = (point, closest);
        for _ in 0..MAX_SNAP_STEPS {
            if found.distance <= ON_SURFACE_MM {
                break;
            }
            kept = found.point;
            found = surface.index.closest_point(kept);
        }
        if index == 0 {
            start_triangle = found.triangle;
        }
        snapped.push(kept);
    }
    let spline = ClosedSpline::through(&snapped).map_err(|error| match error {
        SplineError::TooFewPoints(count) => BreastError::TooFewControlPoints { side, count },
        SplineError::CoincidentPoints { index } => {
            BreastError::CoincidentControlPoints { side, index }
        }
    })?;
    // Each sample is moved to its nearest surface point before the walk: the spline's
    // chords leave the skin by centimetres where it turns sharply (a breast's lateral
    // side), and walking towards points that far off a steep surface doubles back on
    // itself. The first sample is exactly the first snapped control point, on
    // `start_triangle`.
    let samples: Vec<DVec3> = spline
        .sample(sample_spacing_mm)
        .into_iter()
        .map(|sample| surface.index.closest_point(sample).point)
        .collect();
    let curve = SurfaceCurve::project(surface.mesh, surface.topology, start_triangle, &samples)
        .map_err(|source| {
            let hint = curve_error_hint(&source, &snapped, roles);
            BreastError::Curve { side, source, hint }
        })?
        .snapped_to_vertices(surface.mesh, surface.topology, CUT_SNAP_FRACTION)
        .oriented_counter_clockwise_about(frame.anterior());
    Ok((snapped, curve))
}

/// "; the nearest control point is ... move it" for a curve error that has a place, naming
/// the point by `roles` (one per control point) where given, else by its number.
fn curve_error_hint(
    error: &CurveError,
    control_points: &[DVec3],
    roles: Option<&[&str]>,
) -> String {
    let advice = match error {
        CurveError::LeavesMesh { .. } | CurveError::NotClosed { .. } => {
            "onto skin the scanner saw, away from the scan's edge"
        }
        CurveError::DegenerateTriangle { .. }
        | CurveError::NoProgress { .. }
        | CurveError::SelfCrossing { .. } => {
            "so that the curve runs once round the breast without doubling back"
        }
        _ => return String::new(),
    };
    let Some(place) = error.position() else {
        return String::new();
    };
    let place = DVec3::from_array(place);
    let Some((index, distance_mm)) = control_points
        .iter()
        .map(|p| p.distance(place))
        .enumerate()
        .min_by(|a, b| a.1.total_cmp(&b.1))
    else {
        return String::new();
    };
    let name = match roles.and_then(|roles| roles.get(index)) {
        Some(role) => format!("{role} (control point {index})"),
        None => format!("control point {index}"),
    };
    format!(
        "; the nearest control point is {name}, {distance_mm:.0} mm away: move it (or the \
         landmark it comes from) {advice}"
    )
}

/// Radius (mm) over which the triangle normals on each side of the stitch are averaged
/// (area-weighted) before their angle is taken. Scan triangles along a cut are split into
/// pieces far smaller than the scanner's noise, whose single normals say nothing about the
/// surface (on the shared scans, neighbouring scan triangles far from any cut already
/// differ by 58° at the 95th percentile); 3 mm is about two scan triangles.
pub const STITCH_NORMAL_RADIUS_MM: f64 = 3.0;

/// The largest angle (degrees) across the stitch of `fill` into `base`: for each boundary
/// edge of the fill-in, between the area-weighted mean normal of the base triangles and of
/// the fill-in triangles within `radius_mm` of the edge's midpoint (always at least the
/// triangle on the edge; `radius_mm = 0` compares just the two triangles on the edge).
/// 0 if no edge has a triangle on both sides. The topologies are those of `base` and of
/// `fill.mesh`.
fn max_stitch_angle_deg(
    base: &TriMesh,
    base_topology: &Topology,
    fill: &FillIn,
    fill_topology: &Topology,
    radius_mm: f64,
) -> f64 {
    let boundary = &fill.boundary_to_base;
    let n = boundary.len();
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    // Per boundary edge, the base triangle and the fill-in triangle on it.
    let mut sides: HashMap<(u32, u32), [Option<usize>; 2]> = (0..n)
        .map(|k| (key(boundary[k], boundary[(k + 1) % n]), [None, None]))
        .collect();
    for (t, corners) in base.triangles.iter().enumerate() {
        for k in 0..3 {
            if let Some(entry) = sides.get_mut(&key(corners[k], corners[(k + 1) % 3])) {
                entry[0] = Some(t);
            }
        }
    }
    for (t, corners) in fill.mesh.triangles.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (corners[k] as usize, corners[(k + 1) % 3] as usize);
            if a < n
                && b < n
                && let Some(entry) = sides.get_mut(&key(boundary[a], boundary[b]))
            {
                entry[1] = Some(t);
            }
        }
    }
    sides
        .iter()
        .filter_map(|(&(a, b), &[base_triangle, fill_triangle])| {
            let midpoint = 0.5 * (base.positions[a as usize] + base.positions[b as usize]);
            let base_normal =
                mean_normal_near(base, base_topology, base_triangle?, midpoint, radius_mm);
            let fill_normal = mean_normal_near(
                &fill.mesh,
                fill_topology,
                fill_triangle?,
                midpoint,
                radius_mm,
            );
            Some(base_normal.angle_between(fill_normal).to_degrees())
        })
        .filter(|angle| angle.is_finite())
        .fold(0.0, f64::max)
}

/// A breast patch closed by its fill-in: the fill-in's triangles reversed (it was made
/// for the base, which runs the other way along the loop) and its boundary vertices
/// merged into the patch's. `cut_loop` is the curve's loop in the cut mesh, `to_patch`
/// maps cut-mesh vertices to the patch's.
fn close_patch(patch: &TriMesh, fill: &FillIn, cut_loop: &[u32], to_patch: &[u32]) -> TriMesh {
    let reversed = FillIn {
        mesh: TriMesh::new(
            fill.mesh.positions.clone(),
            fill.mesh
                .triangles
                .iter()
                .map(|&[a, b, c]| [a, c, b])
                .collect(),
        ),
        boundary_to_base: cut_loop.iter().map(|&v| to_patch[v as usize]).collect(),
    };
    stitch(patch, &reversed)
}

/// For each vertex of the whole (`count` vertices), its index in a part with
/// `vertex_map`, or [`NOT_IN_PART`].
fn inverse_map(vertex_map: &[u32], count: usize) -> Vec<u32> {
    let mut inverse = vec![NOT_IN_PART; count];
    for (part_vertex, &whole_vertex) in vertex_map.iter().enumerate() {
        inverse[whole_vertex as usize] = part_vertex as u32;
    }
    inverse
}

/// The holes of the scan (its boundary loops but the outer border, the longest) that
/// lie inside a breast region: all triangles around their rims belong to that breast.
/// The cut mesh's first vertices are the scan's.
fn holes_in_breasts(scan: &TriMesh, topology: &Topology, cut: &CutMesh) -> Vec<BreastHole> {
    let mut loops: Vec<(f64, Vec<u32>)> = topology
        .boundary_loops(scan)
        .into_iter()
        .map(|l| (loop_length(scan, &l), l))
        .collect();
    if loops.len() < 2 {
        return Vec::new();
    }
    loops.sort_by(|a, b| b.0.total_cmp(&a.0));
    // Bit 0: next to the base; bit 1 + k: next to breast k.
    let region_bit = |region: Region| match region {
        Region::Outside => 1u8,
        Region::Inside(k) => 2 << k,
    };
    let mut touching = vec![0u8; scan.vertex_count()];
    for (corners, &region) in cut.mesh.triangles.iter().zip(&cut.regions) {
        for &v in corners {
            if let Some(bits) = touching.get_mut(v as usize) {
                *bits |= region_bit(region);
            }
        }
    }
    let mut holes = Vec::new();
    for (perimeter_mm, hole) in &loops[1..] {
        for side in Side::BOTH {
            let bit = region_bit(Region::Inside(side as usize));
            if hole.iter().all(|&v| touching[v as usize] == bit) {
                let centre = hole
                    .iter()
                    .map(|&v| scan.positions[v as usize])
                    .sum::<DVec3>()
                    / hole.len() as f64;
                holes.push(BreastHole {
                    side,
                    perimeter_mm: *perimeter_mm,
                    centre: centre.to_array(),
                });
            }
        }
    }
    holes
}

/// The breast error of a failed cut.
fn cut_error(error: CutError) -> BreastError {
    match error {
        CutError::Curve { curve, source } => BreastError::Curve {
            side: Side::BOTH[curve.min(1)],
            source,
            hint: String::new(),
        },
        CutError::CurvesTouch { position, .. } => BreastError::CurvesTouch { position },
        other => BreastError::Cut(other),
    }
}
