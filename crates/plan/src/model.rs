//! `mammaplan model`: the breast model of a scan (cut curves, breast patches, fill-ins,
//! breast and quadrant volumes), the closed surface around the breasts, its tetrahedral
//! meshes (a hierarchy of up to [`MAX_TET_LEVELS`] levels for the multigrid solver, plus on request
//! a finest level refined around the fill-ins, where the implant sits), and the model
//! folder a researcher opens ([`write_model`], [`load_model`]).

use crate::measure::HoleSummary;
pub use crate::per_side::PerSide;
use crate::{MarkedScan, Progress, check_cancelled};
use anatomy::breast::{BreastModel, QuadrantVolumes, Side};
use anatomy::closed_surface::{ClosedSurface, ClosedSurfaceOptions, build_closed_surface};
use anatomy::{BreastOptions, ControlPoints, build_breast_model};
use anyhow::{Context, Result};
use serde::{Deserialize, Serialize};
use simulation::{MuscleFigures, MuscleLayer};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub mod folder;
pub(crate) use folder::{ModelRecord, read_folder_json, read_model_record};
pub use folder::{load_model, write_closed_polyline, write_model};

/// The file name of the carried control points in a simulation folder.
pub const SIMULATED_CONTROL_POINTS: &str = "simulated_control_points.json";

pub use anatomy::breast::DEFAULT_PC_RATIO;
pub use anatomy::closed_surface::{DEFAULT_REAR_WALL_OFFSET_MM, MAX_REAR_WALL_OFFSET_MM};

/// Default number of tetrahedra of the finest level (`--elements`).
pub const DEFAULT_ELEMENTS: usize = 60_000;

/// A resolution chosen by what it is for (`model --quality`); the discretisation error
/// each leaves is measured in `docs/dev/discretisation.md`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quality {
    /// Quick looks while planning: 15,000 elements.
    Draft,
    /// The default: [`DEFAULT_ELEMENTS`], fast enough for the live view.
    Standard,
    /// For the report: 240,000 elements, about seven seconds more per simulation.
    Accurate,
}

impl Quality {
    /// About how many tetrahedra the finest level has.
    pub fn elements(self) -> usize {
        match self {
            Quality::Draft => 15_000,
            Quality::Standard => DEFAULT_ELEMENTS,
            Quality::Accurate => 240_000,
        }
    }
}

impl std::str::FromStr for Quality {
    type Err = String;

    fn from_str(name: &str) -> Result<Quality, String> {
        match name {
            "draft" => Ok(Quality::Draft),
            "standard" => Ok(Quality::Standard),
            "accurate" => Ok(Quality::Accurate),
            _ => Err(format!(
                "unknown quality \"{name}\": expected draft, standard or accurate"
            )),
        }
    }
}
/// Most levels of the uniform tetrahedral hierarchy; each coarser level has twice the
/// lattice spacing and about 1/8 the elements, down to the last with at least
/// [`MIN_COARSEST_NODES`] nodes. A refined level, when asked for, comes on top.
pub const MAX_TET_LEVELS: usize = 4;

/// Nodes the coarsest uniform level keeps at least (unless it is the second level). The
/// multigrid factorises the coarsest level's nearly dense Galerkin operator at every
/// cycle: the phantom's 60k-element model has 208 coarsest unknowns with three levels
/// (a 1.5-2 ms Cholesky per cycle) and a few dozen with four (0.1 ms), at the same
/// convergence (residual reduction 4.51 and 4.49 per cycle in `mammaplan bench`).
pub const MIN_COARSEST_NODES: usize = 24;

/// Local refinement of the finest tetrahedral level in a band around both fill-ins, the
/// surfaces the implant sits on (paper V-A: "the region which may be covered by an
/// implant"). Off by default: with 4 mm edges a band round two fill-ins of about
/// 160 cm² each costs several hundred thousand elements (see docs/user/model.md), six times
/// the default budget of the interactive solver.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    /// Half-width of the band around each fill-in (mm).
    pub band_mm: f64,
    /// Upper bound on element edges in the band (mm).
    pub max_edge_mm: f64,
}

/// Default half-width of the refinement band (mm): the elements the implant template
/// displaces lie within a few millimetres of the fill-in.
pub const DEFAULT_REFINE_BAND_MM: f64 = 5.0;

/// Default upper bound on element edges in the refinement band (mm).
pub const DEFAULT_REFINE_EDGE_MM: f64 = tetra::refine::DEFAULT_MAX_EDGE_MM;

impl Default for Refinement {
    fn default() -> Refinement {
        Refinement {
            band_mm: DEFAULT_REFINE_BAND_MM,
            max_edge_mm: DEFAULT_REFINE_EDGE_MM,
        }
    }
}

/// Settings of [`build_model`].
#[derive(Debug, Clone)]
pub struct ModelOptions {
    /// Cut curves, fill-ins, volumes. Its `control_points` are replaced by the file's
    /// when `control_points_file` is set.
    pub breast: BreastOptions,
    /// Clip planes and rear-wall offset of the closed surface.
    pub closed_surface: ClosedSurfaceOptions,
    /// A control-point file (`{"units":"mm","left":[[x,y,z],...],"right":[...]}`, the
    /// format of `control_points.json` in a model folder).
    pub control_points_file: Option<PathBuf>,
    /// About how many tetrahedra the finest uniform level has (within about 20%).
    pub elements: usize,
    /// A refined finest level on top of the uniform ones, if set.
    pub refinement: Option<Refinement>,
}

/// How many tetrahedra a model's finest uniform level may be asked for: fewer than a
/// thousand leave lattice cells wider than a breast, more than two million take more
/// memory and time than an interactive tool has (the largest measured, 240,000, took
/// seconds per cycle).
pub const ELEMENTS_RANGE: std::ops::RangeInclusive<usize> = 1_000..=2_000_000;

impl ModelOptions {
    /// Checks the numbers a user (or an edited `model.json`) can set, naming the field
    /// and its range.
    pub fn check(&self) -> Result<()> {
        anyhow::ensure!(
            ELEMENTS_RANGE.contains(&self.elements),
            "elements = {} is out of range: a model holds {} to {} tetrahedra",
            self.elements,
            ELEMENTS_RANGE.start(),
            ELEMENTS_RANGE.end()
        );
        let offset = self.closed_surface.rear_wall_offset_mm;
        anyhow::ensure!(
            offset > 0.0 && offset <= MAX_REAR_WALL_OFFSET_MM,
            "rear_wall_offset_mm = {offset} is out of range: more than 0 and at most \
             {MAX_REAR_WALL_OFFSET_MM} mm"
        );
        if let Some(refinement) = self.refinement {
            for (name, value) in [
                ("refinement band_mm", refinement.band_mm),
                ("refinement max_edge_mm", refinement.max_edge_mm),
            ] {
                anyhow::ensure!(
                    value > 0.0 && value <= MAX_REFINEMENT_MM,
                    "{name} = {value} is out of range: more than 0 and at most \
                     {MAX_REFINEMENT_MM} mm"
                );
            }
        }
        Ok(())
    }
}

/// The largest refinement band or edge (mm): wider than any breast's tissue.
const MAX_REFINEMENT_MM: f64 = 100.0;

impl Default for ModelOptions {
    fn default() -> ModelOptions {
        ModelOptions {
            breast: BreastOptions::default(),
            closed_surface: ClosedSurfaceOptions::default(),
            control_points_file: None,
            elements: DEFAULT_ELEMENTS,
            refinement: None,
        }
    }
}

/// A patient's model: both breasts with the rear wall, and the closed surface.
pub struct PatientModel {
    pub scan_path: PathBuf,
    /// The unit of the scan file's coordinates.
    pub scan_unit: mesh::LengthUnit,
    pub landmarks_path: PathBuf,
    pub control_points_file: Option<PathBuf>,
    /// Which way was up in the scan's file.
    pub up: crate::UpRecord,
    /// The upper control point ratio used (unless the control points came from a file).
    pub pc_ratio: f64,
    pub breasts: BreastModel,
    pub closed_surface: ClosedSurface,
    /// Tetrahedral meshes of the closed surface, `levels[0]` the finest.
    pub tets: tetra::Hierarchy,
    /// The `--elements` asked for.
    pub elements_requested: usize,
    /// The figures of each level of `tets`.
    pub levels: Vec<LevelReport>,
    /// The refined level's figures, when `tets.levels[0]` is one.
    pub refinement: Option<RefinementReport>,
    /// The pectoralis major on the finest level ([`simulation::muscle`]): what its
    /// elements measure, and their surface (`muscle_left.ply`, `muscle_right.ply`);
    /// `None` on a side where it takes no element.
    pub pectoralis_major: PerSide<Option<MuscleFigures>>,
    pub muscle_surfaces: PerSide<Option<mesh::TriMesh>>,
    pub scan_vertices: usize,
    pub scan_triangles: usize,
    pub timings: ModelTimings,
}

/// Wall-clock time of the steps (ms).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ModelTimings {
    /// Cut curves, cutting, fill-ins, volumes.
    pub breast_model_ms: f64,
    /// Clipping, shifting, stitching and the watertightness checks.
    pub closed_surface_ms: f64,
    /// The tetrahedral hierarchy with its quality figures.
    pub tetrahedra_ms: f64,
    pub total_ms: f64,
}

/// One level of the tetrahedral hierarchy.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct LevelReport {
    /// Tetrahedra.
    pub elements: usize,
    pub nodes: usize,
    /// Lattice spacing (mm).
    pub spacing_mm: f64,
    pub min_dihedral_deg: f64,
    pub max_dihedral_deg: f64,
    pub volume_ml: f64,
}

/// The refined finest level.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct RefinementReport {
    /// Half-width of the band around each fill-in (mm).
    pub band_mm: f64,
    /// The requested upper bound on edges in the band (mm).
    pub max_edge_mm: f64,
    /// Lattice spacing in the band (mm); tetrahedra next to the surface whose warped
    /// edges exceed the bound are refined to half of it.
    pub band_spacing_mm: f64,
    /// Tetrahedra with their centroid in the band.
    pub elements_in_band: usize,
    /// The longest edge of those (mm).
    pub longest_edge_in_band_mm: f64,
}

/// The clip planes of the closed surface in the body's sternal frame (mm; origin Pj,
/// `x` towards the patient's left, `y` along the sternum towards Pj): top and bottom
/// `y = y_max_mm`, `y = y_min_mm`; the patient's right plane
/// `x = x_min_mm + x_min_slope * (y - y_ref_mm)`, the left one likewise with `x_max`
/// (slopes 0: upright).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ClipBoxReport {
    pub x_min_mm: f64,
    pub x_max_mm: f64,
    pub y_min_mm: f64,
    pub y_max_mm: f64,
    pub x_min_slope: f64,
    pub x_max_slope: f64,
    pub y_ref_mm: f64,
}

/// A scanner hole inside a breast region, closed by the fill-in.
#[derive(Debug, Clone, Serialize)]
pub struct BreastHoleSummary {
    pub side: &'static str,
    pub perimeter_mm: f64,
    pub centre_mm: [f64; 3],
}

/// Sizes of the meshes.
#[derive(Debug, Clone, Serialize)]
pub struct ModelCounts {
    pub scan_vertices: usize,
    pub scan_triangles: usize,
    pub control_points: PerSide<usize>,
    pub cut_curve_points: PerSide<usize>,
    pub breast_triangles: PerSide<usize>,
    pub fill_triangles: PerSide<usize>,
    pub filled_base_triangles: usize,
    pub closed_surface_vertices: usize,
    pub closed_surface_triangles: usize,
    /// Of the closed surface's triangles: the clipped scan, the shifted wall, the band.
    pub closed_surface_front_triangles: usize,
    pub closed_surface_back_wall_triangles: usize,
    pub closed_surface_band_triangles: usize,
}

/// The JSON of `model` and the content of `model.json` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct ModelReport {
    /// The program that wrote the folder ([`crate::software`]).
    pub software: String,
    pub scan: String,
    /// The unit of the scan file's coordinates (`mm`, `cm`, `m` or `in`); everything
    /// else here is in millimetres.
    pub scan_units: String,
    pub landmarks: String,
    /// The control-point file given, if any.
    pub control_points_file: Option<String>,
    /// Which way was up in the scan's file (the standing frame's y), with the sternum's
    /// lean from it.
    pub up: crate::UpRecord,
    pub breast_volume_ml: PerSide<f64>,
    pub quadrant_volume_ml: PerSide<QuadrantVolumes>,
    pub closed_surface_volume_ml: f64,
    /// The `--elements` asked for (the uniform finest level's target).
    pub elements_requested: usize,
    /// The tetrahedral meshes, level 0 the finest (`tets_level{l}.vtu`).
    pub levels: Vec<LevelReport>,
    /// The refinement of level 0 around the fill-ins (`None`: all levels uniform).
    pub refinement: Option<RefinementReport>,
    /// What the pectoralis major's elements on level 0 measure ([`MuscleFigures`];
    /// `None` on a side where it takes none).
    pub pectoralis_major: PerSide<Option<MuscleFigures>>,
    /// The smallest dihedral angle over all levels (degrees).
    pub min_dihedral_deg: f64,
    /// The largest angle across each fill-in's stitch to the base between the base's and
    /// the fill-in's normals, each averaged over 3 mm (degrees): how smoothly the rear
    /// wall continues the chest.
    pub max_stitch_angle_deg: PerSide<f64>,
    /// The same between the two single triangles at each stitch edge (degrees); on a
    /// noisy scan this is the scan's own roughness.
    pub max_stitch_angle_single_triangles_deg: PerSide<f64>,
    pub cut_curve_length_mm: PerSide<f64>,
    /// How much of each breast the scanner did not see and the model reconstructed
    /// (the vertices are flagged in `breast_*.ply`'s `reconstructed` property).
    pub reconstructed: PerSide<ReconstructedReport>,
    /// The upper control point's ratio along Pc-Pn; `None` when the control points
    /// came from a file.
    pub pc_ratio: Option<f64>,
    pub rear_wall_offset_mm: f64,
    pub clip_box: ClipBoxReport,
    /// Scanner holes closed before cutting.
    pub holes_closed: Vec<HoleSummary>,
    /// Of those, the ones inside a breast region (small dropouts, closed by the fill-in).
    pub holes_in_breasts: Vec<BreastHoleSummary>,
    /// Holes away from the breasts that stay open.
    pub holes_left_open: Vec<HoleSummary>,
    pub counts: ModelCounts,
    pub timings: ModelTimings,
    /// The model folder and the files written into it (names).
    pub out_dir: PathBuf,
    pub files: Vec<String>,
    /// SHA-256 of every file but `model.json`, checked when the folder is reopened
    /// ([`load_model`]).
    pub sha256: crate::checksum::Checksums,
    /// SHA-256 of the scan and landmark files the model was built from, checked before
    /// [`load_model`] rebuilds the model from them; `None` when they are not files (a
    /// phantom made in memory), which no command can reopen anyway.
    pub inputs_sha256: Option<InputChecksums>,
}

/// SHA-256 (lower-case hexadecimal) of the files a model folder is built from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct InputChecksums {
    pub scan: String,
    pub landmarks: String,
}

impl InputChecksums {
    /// The checksums of the files at `scan` and `landmarks`; `None` if either does not
    /// exist (a phantom made in memory). Errors name the file that cannot be read.
    pub fn of(scan: &Path, landmarks: &Path) -> Result<Option<InputChecksums>> {
        if !scan.exists() || !landmarks.exists() {
            return Ok(None);
        }
        let sha256 = |path: &Path| {
            crate::checksum::file_sha256(path)
                .with_context(|| format!("reading {} for its checksum", path.display()))
        };
        Ok(Some(InputChecksums {
            scan: sha256(scan)?,
            landmarks: sha256(landmarks)?,
        }))
    }
}

/// The skin of one breast the scanner did not see, reconstructed by the fill-in.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct ReconstructedReport {
    pub area_mm2: f64,
    /// Of the breast's skin (0..1).
    pub area_share: f64,
    /// The breast volume between the reconstructed skin and flat patches over its
    /// borders (ml): the part of the breast volume that rests on reconstruction.
    pub volume_ml: f64,
}

/// One sentence for the user when Px does not lie below Pj within the strip the
/// simulation holds over the sternum ([`simulation::STERNUM_HALF_WIDTH_MM`] either side
/// of the vertical through Pj): the skin at Px is then not held, and the pockets'
/// midline clearance is measured from a line the sternum does not follow.
fn sternum_doubt(marked: &MarkedScan) -> Option<String> {
    use anatomy::LandmarkName;
    let px = marked
        .frame
        .to_local(marked.landmarks.get(LandmarkName::Px));
    let (aside_mm, below_mm) = (px.x.abs(), -px.y);
    (aside_mm > simulation::STERNUM_HALF_WIDTH_MM || below_mm <= 0.0).then(|| {
        let (vertical_mm, way) = (
            below_mm.abs(),
            if below_mm > 0.0 { "below" } else { "above" },
        );
        format!(
            "Px lies {aside_mm:.0} mm to the side of the vertical through Pj and \
             {vertical_mm:.0} mm {way} it: check where Px and Pj are marked, or the scan's up \
             axis (--up); the skin over the sternum at Px is not held in the simulation"
        )
    })
}

/// Builds the breast model and the closed surface of a scan with its landmarks.
/// Errors about one breast start with its name ("left breast: ..."). Stops with
/// [`crate::Cancelled`] between stages once `progress` asks to.
pub fn build_model(
    marked: &MarkedScan,
    options: &ModelOptions,
    progress: &dyn Progress,
) -> Result<PatientModel> {
    options.check()?;
    check_cancelled(progress)?;
    let start = Instant::now();
    let scan = &marked.scan;
    if let Some(doubt) = sternum_doubt(marked) {
        progress.warn(&format!("{}: {doubt}", marked.landmarks_path.display()));
    }
    progress.stage("model", 2);
    let (breasts, pc_ratio) = build_breasts(
        marked,
        &options.breast,
        options.control_points_file.as_deref(),
        progress,
    )?;
    let breast_model_ms = elapsed_ms(start);
    progress.step();
    check_cancelled(progress)?;

    let closed_start = Instant::now();
    let closed_surface = build_closed_surface(
        &breasts.surface,
        &breasts.filled_base,
        &marked.frame,
        &marked.landmarks,
        &options.closed_surface,
    )
    .with_context(|| scan.path.display().to_string())?;
    for warning in &closed_surface.warnings {
        progress.warn(&format!(
            "{}: closed surface: {warning}",
            scan.path.display()
        ));
    }
    let closed_surface_ms = elapsed_ms(closed_start);
    progress.step();
    check_cancelled(progress)?;

    progress.stage("tetrahedra", 1);
    let tets_start = Instant::now();
    let (tets, levels, refinement) = tetrahedra(
        &closed_surface,
        options.elements,
        options.refinement.map(|r| (r, &breasts)),
    )
    .context("tetrahedral meshing")?;
    let tetrahedra_ms = elapsed_ms(tets_start);
    progress.step();
    check_cancelled(progress)?;
    let finest = &tets.levels[0];
    let muscle = MuscleLayer::new(
        &finest.mesh,
        &closed_surface,
        &marked.frame,
        &marked.landmarks,
    )
    .context("placing the pectoralis major")?;
    for warning in &muscle.warnings {
        progress.warn(&format!("{}: {warning}", scan.path.display()));
    }
    let wall_tolerance_mm = finest.spacing_mm * simulation::WALL_TOLERANCE_FACTOR;
    let pectoralis_major = PerSide::from_fn(|side| {
        muscle.figures(
            &finest.mesh,
            &closed_surface,
            &marked.frame,
            side,
            wall_tolerance_mm,
        )
    });
    let muscle_surfaces = PerSide::from_fn(|side| muscle.side_surface(&finest.mesh, side));

    Ok(PatientModel {
        scan_path: scan.path.clone(),
        scan_unit: scan.file_unit,
        landmarks_path: marked.landmarks_path.clone(),
        control_points_file: options.control_points_file.clone(),
        up: crate::UpRecord::of(&marked.frame),
        pc_ratio,
        breasts,
        closed_surface,
        tets,
        elements_requested: options.elements,
        levels,
        refinement,
        pectoralis_major,
        muscle_surfaces,
        scan_vertices: scan.mesh.vertex_count(),
        scan_triangles: scan.mesh.triangle_count(),
        timings: ModelTimings {
            breast_model_ms,
            closed_surface_ms,
            tetrahedra_ms,
            total_ms: elapsed_ms(start),
        },
    })
}

/// The breast model of a scan alone (cut curves, breast patches, fill-ins, breast and
/// quadrant volumes), with the control points of `control_points_file` instead of those
/// of `options` when given, warning about scanner holes it closed or left open. Returns
/// it with the upper control point ratio used.
pub fn build_breasts(
    marked: &MarkedScan,
    options: &BreastOptions,
    control_points_file: Option<&Path>,
    progress: &dyn Progress,
) -> Result<(BreastModel, f64)> {
    let scan = &marked.scan;
    let mut options = options.clone();
    if let Some(path) = control_points_file {
        let points = ControlPoints::read(path)?;
        points.check_sides(&marked.frame, path)?;
        options.control_points = Some(points);
    }
    if options.control_points.is_none() {
        for doubt in ControlPoints::landmark_doubts(&marked.frame, &marked.landmarks) {
            progress.warn(&format!("{}: {doubt}", marked.landmarks_path.display()));
        }
    }
    let breasts = build_breast_model(
        &scan.mesh,
        &scan.topology,
        &scan.index,
        &marked.frame,
        &marked.landmarks,
        &options,
    )
    .with_context(|| {
        // A simulated scan's fold landmarks ride forward on the implant, so the default
        // curves below them can fold; its folder holds the model's curves carried along.
        let carried = (scan.path.parent())
            .map(|dir| dir.join(SIMULATED_CONTROL_POINTS))
            .filter(|path| options.control_points.is_none() && path.is_file());
        let hint = carried.map_or(String::new(), |path| {
            format!(
                " (a simulated scan? {} holds the model's cut curves carried along: cut it \
                 along them, with model --control-points or compare's \
                 --test-control-points/--reference-control-points)",
                path.display()
            )
        });
        format!(
            "{} with {}{hint}",
            scan.path.display(),
            marked.landmarks_path.display()
        )
    })?;
    for hole in &breasts.holes_left_open {
        progress.warn(&format!("{}: {hole}", scan.path.display()));
    }
    for side in Side::BOTH {
        let part = &breasts.breast(side).reconstructed;
        if part.area_mm2 > 0.0 {
            progress.warn(&format!(
                "{}: {side} breast: {:.0}% of its skin ({:.1} cm²) was not seen by the scanner and is reconstructed; {:.1} ml of its volume rests on the reconstruction",
                scan.path.display(),
                100.0 * part.area_share,
                part.area_mm2 / 100.0,
                part.volume_ml
            ));
        }
    }
    Ok((breasts, options.pc_ratio))
}

/// The (up to [`MAX_TET_LEVELS`]) tetrahedral meshes of the closed surface, the finest with about
/// `elements` tetrahedra, and their figures; with a refinement, a level refined around
/// the breasts' fill-ins comes first, at the uniform finest level's spacing elsewhere.
/// Fails on an element of non-positive volume.
fn tetrahedra(
    closed: &ClosedSurface,
    elements: usize,
    refinement: Option<(Refinement, &BreastModel)>,
) -> Result<(tetra::Hierarchy, Vec<LevelReport>, Option<RefinementReport>)> {
    let surface = tetra::ClosedSurface::new(&closed.mesh)?;
    let mut hierarchy =
        tetra::build_hierarchy_down_to(&surface, elements, MAX_TET_LEVELS, MIN_COARSEST_NODES)?;
    let refinement = match refinement {
        None => None,
        Some((refinement, breasts)) => {
            anyhow::ensure!(
                refinement.band_mm.is_finite() && refinement.band_mm > 0.0,
                "the refinement band must be a positive width in mm, not {}",
                refinement.band_mm
            );
            anyhow::ensure!(
                refinement.max_edge_mm.is_finite() && refinement.max_edge_mm >= MIN_REFINE_EDGE_MM,
                "the refinement's maximum edge must be at least {MIN_REFINE_EDGE_MM} mm, not {}",
                refinement.max_edge_mm
            );
            let region = Side::BOTH
                .into_iter()
                .fold(tetra::RefinementRegion::new(), |region, side| {
                    region.with_band(breasts.breast(side).fill.mesh.clone(), refinement.band_mm)
                })
                .with_max_edge(refinement.max_edge_mm);
            let spacing_mm = hierarchy.levels[0].spacing_mm;
            let mesh = tetra::stuff_refined(&surface, spacing_mm, &region)?;
            let (longest_edge_in_band_mm, elements_in_band) =
                tetra::refine::longest_edge_in_region(&mesh, &region);
            hierarchy
                .levels
                .insert(0, tetra::Level { spacing_mm, mesh });
            Some(RefinementReport {
                band_mm: refinement.band_mm,
                max_edge_mm: refinement.max_edge_mm,
                band_spacing_mm: region.fine_spacing(spacing_mm),
                elements_in_band,
                longest_edge_in_band_mm,
            })
        }
    };
    let mut levels = Vec::with_capacity(hierarchy.levels.len());
    for (l, level) in hierarchy.levels.iter().enumerate() {
        let quality = tetra::quality::quality(&level.mesh);
        anyhow::ensure!(
            quality.min_volume_mm3 > 0.0,
            "level {l} has a tetrahedron of volume {} mm³",
            quality.min_volume_mm3
        );
        levels.push(LevelReport {
            elements: level.mesh.tet_count(),
            nodes: level.mesh.vertex_count(),
            spacing_mm: level.spacing_mm,
            min_dihedral_deg: quality.min_dihedral_deg,
            max_dihedral_deg: quality.max_dihedral_deg,
            volume_ml: level.mesh.volume_mm3() / 1000.0,
        });
    }
    Ok((hierarchy, levels, refinement))
}

/// The smallest maximum edge a refinement may ask for (mm): below it the band alone
/// would need tens of millions of elements.
pub const MIN_REFINE_EDGE_MM: f64 = 1.0;

fn elapsed_ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

impl PatientModel {
    /// The control points used (snapped to the surface), as a control-point file holds
    /// them.
    pub fn control_points(&self) -> ControlPoints {
        ControlPoints {
            left: self.breasts.left.control_points.clone(),
            right: self.breasts.right.control_points.clone(),
        }
    }

    /// The figures of the model; `out_dir` and `files` say where it is written.
    pub fn report(
        &self,
        out_dir: &Path,
        files: Vec<String>,
        sha256: crate::checksum::Checksums,
        inputs_sha256: Option<InputChecksums>,
    ) -> ModelReport {
        let model = &self.breasts;
        let closed = &self.closed_surface;
        let clip = closed.clip_box;
        let hole = |perimeter_mm: f64, centre_mm: [f64; 3]| HoleSummary {
            perimeter_mm,
            centre_mm,
        };
        // Absolute paths, so that the folder can be reopened from anywhere (`load_model`).
        let absolute = |p: &Path| std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf());
        let [stitch_left, stitch_right] = model.stitch_angles();
        ModelReport {
            software: crate::software(),
            scan: absolute(&self.scan_path).display().to_string(),
            scan_units: self.scan_unit.symbol().to_string(),
            landmarks: absolute(&self.landmarks_path).display().to_string(),
            control_points_file: self
                .control_points_file
                .as_ref()
                .map(|p| p.display().to_string()),
            up: self.up,
            breast_volume_ml: PerSide::from_fn(|side| model.breast(side).volume_ml),
            quadrant_volume_ml: PerSide::from_fn(|side| model.breast(side).quadrant_volume_ml),
            closed_surface_volume_ml: closed.volume_ml,
            elements_requested: self.elements_requested,
            levels: self.levels.clone(),
            refinement: self.refinement,
            pectoralis_major: self.pectoralis_major,
            min_dihedral_deg: self
                .levels
                .iter()
                .map(|l| l.min_dihedral_deg)
                .fold(f64::INFINITY, f64::min),
            max_stitch_angle_deg: PerSide {
                left: stitch_left.averaged_deg,
                right: stitch_right.averaged_deg,
            },
            max_stitch_angle_single_triangles_deg: PerSide {
                left: stitch_left.single_triangles_deg,
                right: stitch_right.single_triangles_deg,
            },
            cut_curve_length_mm: PerSide::from_fn(|side| model.breast(side).curve.length_mm()),
            reconstructed: PerSide::from_fn(|side| {
                let part = &model.breast(side).reconstructed;
                ReconstructedReport {
                    area_mm2: part.area_mm2,
                    area_share: part.area_share,
                    volume_ml: part.volume_ml,
                }
            }),
            pc_ratio: self.control_points_file.is_none().then_some(self.pc_ratio),
            rear_wall_offset_mm: closed.rear_wall_offset_mm,
            clip_box: ClipBoxReport {
                x_min_mm: clip.x_min_mm,
                x_max_mm: clip.x_max_mm,
                y_min_mm: clip.y_min_mm,
                y_max_mm: clip.y_max_mm,
                x_min_slope: clip.x_min_slope,
                x_max_slope: clip.x_max_slope,
                y_ref_mm: clip.y_ref_mm,
            },
            holes_closed: model.holes_closed.iter().map(HoleSummary::from).collect(),
            holes_in_breasts: model
                .holes_in_breasts
                .iter()
                .map(|h| BreastHoleSummary {
                    side: h.side.name(),
                    perimeter_mm: h.perimeter_mm,
                    centre_mm: h.centre,
                })
                .collect(),
            holes_left_open: model
                .holes_left_open
                .iter()
                .map(|h| hole(h.perimeter_mm, h.centre))
                .collect(),
            counts: ModelCounts {
                scan_vertices: self.scan_vertices,
                scan_triangles: self.scan_triangles,
                control_points: PerSide::from_fn(|side| model.breast(side).control_points.len()),
                cut_curve_points: PerSide::from_fn(|side| model.breast(side).curve.points.len()),
                breast_triangles: PerSide::from_fn(|side| {
                    model.breast(side).patch.mesh.triangle_count()
                }),
                fill_triangles: PerSide::from_fn(|side| {
                    model.breast(side).fill.mesh.triangle_count()
                }),
                filled_base_triangles: model.filled_base.triangle_count(),
                closed_surface_vertices: closed.mesh.vertex_count(),
                closed_surface_triangles: closed.mesh.triangle_count(),
                closed_surface_front_triangles: closed.front.len(),
                closed_surface_back_wall_triangles: closed.back_wall.len(),
                closed_surface_band_triangles: closed.band.len(),
            },
            timings: self.timings,
            out_dir: out_dir.to_path_buf(),
            files,
            sha256,
            inputs_sha256,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Px marked 12 mm to the side of the vertical through Pj is doubted, with the
    /// distance; the phantom's own is not.
    #[test]
    fn a_px_off_the_midline_is_doubted() {
        use crate::{MarkedScan, PhantomParams, Silent};
        use anatomy::LandmarkName;
        let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
        assert_eq!(sternum_doubt(&marked), None);
        let mut landmarks = marked.landmarks.clone();
        let px = landmarks.get(LandmarkName::Px);
        landmarks.set(LandmarkName::Px, px + marked.frame.left() * 12.0);
        let moved = MarkedScan::new(
            marked.scan.clone(),
            landmarks,
            Path::new("moved.json"),
            Some(marked.up()),
            &Silent,
        )
        .unwrap();
        let doubt = sternum_doubt(&moved).expect("a doubt");
        assert!(doubt.starts_with("Px lies 12 mm to the side"), "{doubt}");
    }

    /// The defaults pass; each number out of its range is refused with its field named.
    #[test]
    fn options_out_of_range_are_named() {
        assert!(ModelOptions::default().check().is_ok());
        let message = |options: ModelOptions| options.check().unwrap_err().to_string();
        let few = ModelOptions {
            elements: 10,
            ..ModelOptions::default()
        };
        assert!(message(few).starts_with("elements = 10 is out of range"));
        let mut far = ModelOptions::default();
        far.closed_surface.rear_wall_offset_mm = 1e6;
        assert!(message(far).starts_with("rear_wall_offset_mm = 1000000 is out of range"));
        let wide = ModelOptions {
            refinement: Some(Refinement {
                band_mm: 5.0,
                max_edge_mm: f64::NAN,
            }),
            ..ModelOptions::default()
        };
        assert!(message(wide).starts_with("refinement max_edge_mm = NaN"));
    }
}
