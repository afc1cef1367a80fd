//! `mammaplan compare`: a test scan against a reference scan (paper VI-C, VI-D, Figs. 3
//! and 13). In the paper's validation the real post-operative scan is the reference and
//! the simulated one the test; comparing a post-operative with a pre-operative scan
//! works the same way.
//!
//! Steps: optionally register the test scan onto the reference (bony landmarks, then
//! ICP away from the breasts: [`crate::register`]); the per-vertex deviation of the test
//! surface from the reference over their overlap and its statistics over the whole
//! overlap and the breast regions ([`assess`]); the clinical distances of both
//! ([`crate::measure`]); the breast model of each for breast and quadrant volumes and
//! breast regions ([`crate::model::build_breasts`]); the symmetry of each
//! ([`assess::symmetry`]). With `out`, the test mesh (registered) is written as PLY with
//! the deviation colour map as vertex colours and the scalar vertex properties
//! `distance_mm`, `signed_distance_mm` (to the reference; NaN outside the overlap) and
//! `asymmetry_mm` (the test scan's signed distance to its own mirror image).

use crate::measure::measure;
use crate::model::{PerSide, build_breasts};
use crate::register::{RegisterReport, register};
use crate::{MarkedScan, Progress};
use anatomy::BreastOptions;
use anatomy::Side;
use anatomy::breast::{BreastModel, ControlPoints, QuadrantVolumes};
use anatomy::measure::Distance;
use anyhow::{Context, Result, bail};
use assess::{
    DeviationStatistics, DistanceSurface, SurfaceComparison, Symmetry, SymmetryInput,
    ZoneStatistics, analyse_symmetry, deviation_color, transfer_sides,
};
use mesh::io::{PlyEncoding, VertexScalar, write_ply_with_scalars};
use mesh::{SurfaceIndex, TriMesh};
use serde::Serialize;
use std::path::{Path, PathBuf};

pub use assess::DEFAULT_MAX_DISTANCE_MM;

/// Settings of [`compare`].
#[derive(Debug, Clone, PartialEq)]
pub struct CompareOptions {
    /// Register the test scan onto the reference first.
    pub register: bool,
    /// Points farther than this from the other surface are outside the overlap (mm).
    pub max_distance_mm: f64,
    /// Where to write the test mesh with the deviation map (a `.ply` file).
    pub out: Option<PathBuf>,
    /// Control-point files (`mammaplan model --control-points`) for the reference's and
    /// the test's breast models, instead of the defaults from their landmarks; e.g. a
    /// simulation folder's `simulated_control_points.json` for a simulated scan.
    pub reference_control_points: Option<PathBuf>,
    pub test_control_points: Option<PathBuf>,
}

impl Default for CompareOptions {
    fn default() -> CompareOptions {
        CompareOptions {
            register: false,
            max_distance_mm: DEFAULT_MAX_DISTANCE_MM,
            out: None,
            reference_control_points: None,
            test_control_points: None,
        }
    }
}

/// The JSON of `compare` (GUIDE section 5).
#[derive(Debug, Clone, Serialize)]
pub struct CompareReport {
    /// Scan and landmark files of the reference and the test.
    pub reference: ScanFiles,
    pub test: ScanFiles,
    /// The registration of the test onto the reference, if asked for.
    pub registration: Option<RegisterReport>,
    pub max_distance_mm: f64,
    /// Over the whole overlap, test vertices to the reference surface: root mean square,
    /// unsigned mean and signed mean of the distances (mm).
    pub rms_mm: f64,
    pub mean_mm: f64,
    pub signed_mean_mm: f64,
    /// The symmetric Hausdorff distance over the overlap (mm).
    pub hausdorff_mm: f64,
    /// The fraction of test vertices over the reference surface, and of reference
    /// vertices over the test surface.
    pub overlap_fraction: f64,
    pub reference_overlap_fraction: f64,
    /// The full statistics over the whole overlap.
    pub overall: DeviationStatistics,
    /// The same over each scan's breast regions (inside the cut curves); `null` for a
    /// region without a test vertex in the overlap.
    pub breast_regions: BreastRegionStatistics,
    /// The clinical distances of both scans.
    pub distances: Vec<DistanceComparison>,
    /// Breast and quadrant volumes (ml); `null` for a scan whose breast model failed.
    pub breast_volume_ml: Paired<Option<PerSide<f64>>>,
    pub quadrant_volume_ml: Paired<Option<PerSide<QuadrantVolumes>>>,
    /// The left/right symmetry of each scan; `null` where it could not be analysed.
    pub symmetry: Paired<Option<SymmetryReport>>,
    /// What could not be computed and why (a breast model or a symmetry analysis that
    /// failed); everything else in the report stands.
    pub warnings: Vec<String>,
    /// The deviation mesh written, if any.
    pub out: Option<PathBuf>,
}

/// The files a scan came from.
#[derive(Debug, Clone, Serialize)]
pub struct ScanFiles {
    pub scan: String,
    pub landmarks: String,
    /// The control-point file its breasts were cut along (`null`: the defaults from its
    /// landmarks).
    pub control_points: Option<String>,
}

impl ScanFiles {
    fn of(marked: &MarkedScan, control_points: Option<&Path>) -> ScanFiles {
        ScanFiles {
            scan: marked.scan.path.display().to_string(),
            landmarks: marked.landmarks_path.display().to_string(),
            control_points: control_points.map(|path| path.display().to_string()),
        }
    }
}

/// A value for the reference and for the test scan.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Paired<T> {
    pub reference: T,
    pub test: T,
}

/// Deviation statistics over the breast regions.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct BreastRegionStatistics {
    pub left: Option<DeviationStatistics>,
    pub right: Option<DeviationStatistics>,
    pub both: Option<DeviationStatistics>,
    /// Where each scan's breast regions come from.
    pub source: Paired<RegionSource>,
}

/// Where a scan's breast regions come from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum RegionSource {
    /// Its own cut curves.
    CutCurves,
    /// Its breast model failed: the other scan's regions, carried over by closest points.
    OtherScan,
    /// Neither scan has a breast model.
    None,
}

/// One clinical distance on both scans: `reference_mm`, `test_mm` are the on-surface
/// lengths (the paper's plane sections, `surface_mm` of `measure`), `difference_mm` is
/// test minus reference; `null` where a section could not be measured (see the notes).
#[derive(Debug, Clone, Serialize)]
pub struct DistanceComparison {
    pub name: String,
    pub from: String,
    pub to: String,
    pub reference_mm: Option<f64>,
    pub test_mm: Option<f64>,
    pub difference_mm: Option<f64>,
    /// The straight-line and geodesic lengths on each scan (mm).
    pub reference_euclidean_mm: f64,
    pub test_euclidean_mm: f64,
    pub reference_geodesic_mm: Option<f64>,
    pub test_geodesic_mm: Option<f64>,
    /// Why a length is missing, per scan.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reference_note: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub test_note: Option<String>,
}

impl DistanceComparison {
    fn new(reference: &Distance, test: &Distance) -> DistanceComparison {
        DistanceComparison {
            name: reference.name.clone(),
            from: reference.from.clone(),
            to: reference.to.clone(),
            reference_mm: reference.surface_mm,
            test_mm: test.surface_mm,
            difference_mm: test
                .surface_mm
                .zip(reference.surface_mm)
                .map(|(t, r)| t - r),
            reference_euclidean_mm: reference.euclidean_mm,
            test_euclidean_mm: test.euclidean_mm,
            reference_geodesic_mm: reference.geodesic_mm,
            test_geodesic_mm: test.geodesic_mm,
            reference_note: reference.note.clone(),
            test_note: test.note.clone(),
        }
    }
}

/// The left/right symmetry of one scan ([`assess::symmetry`]).
#[derive(Debug, Clone, Serialize)]
pub struct SymmetryReport {
    /// Left breast volume over right breast volume.
    pub volume_ratio_left_to_right: f64,
    /// How much higher the left nipple is than the mirrored right one (mm).
    pub nipple_height_difference_mm: f64,
    /// The left nipple minus the mirrored right nipple in the anatomical frame (mm):
    /// x farther from the midline, y higher, z more anterior.
    pub nipple_position_difference_mm: [f64; 3],
    /// The length of that difference (mm).
    pub nipple_distance_mm: f64,
    /// The scan against its mirror image: statistics of the asymmetry map over the whole
    /// overlap and the breast regions (signed: positive where a side is fuller than the
    /// other side's mirror image).
    pub asymmetry: ZoneStatistics,
    /// The mirror (file frame, row-major 4x4, determinant -1): the reflection across the
    /// landmarks' mid-sagittal plane followed by the correction from matching the
    /// mirrored scan to the scan away from the breasts.
    pub mirror_matrix: [[f64; 4]; 4],
    /// How far that correction turns (degrees) and moves the sternal notch (mm): how far
    /// the landmarks' plane was from the best symmetry plane.
    pub mirror_correction_deg: f64,
    pub mirror_correction_mm: f64,
    /// RMS distance of the mirrored scan to the scan away from the breasts (mm).
    pub mirror_matching_rms_mm: f64,
}

impl SymmetryReport {
    fn new(symmetry: &Symmetry) -> SymmetryReport {
        let mirror = &symmetry.mirror;
        let notch = mirror.plane_point;
        SymmetryReport {
            volume_ratio_left_to_right: symmetry.volume_ratio_left_to_right(),
            nipple_height_difference_mm: symmetry.nipple_height_difference_mm(),
            nipple_position_difference_mm: symmetry.nipple_position_difference_mm.to_array(),
            nipple_distance_mm: symmetry.nipple_position_difference_mm.length(),
            asymmetry: symmetry.statistics,
            mirror_matrix: mirror.to_row_major(),
            mirror_correction_deg: mirror.correction.rotation_angle_deg(),
            mirror_correction_mm: mirror.correction.apply(notch).distance(notch),
            mirror_matching_rms_mm: symmetry.matching_rms_mm,
        }
    }
}

/// Compares `test` with `reference` (see the module documentation) and writes the
/// deviation mesh if `options.out` is set.
pub fn compare(
    reference: &MarkedScan,
    test: &MarkedScan,
    options: &CompareOptions,
    progress: &dyn Progress,
) -> Result<CompareReport> {
    check_files(options)?;
    progress.stage("compare", 8);
    let (transform, registration) = if options.register {
        let (transform, report) = register(reference, test, true)?;
        (transform, Some(report))
    } else {
        (anatomy::register::RigidTransform::IDENTITY, None)
    };
    progress.step();

    let mut registered = test.scan.mesh.clone();
    registered.map_positions(|p| transform.apply(p));
    let registered_index = SurfaceIndex::new(&registered)
        .with_context(|| format!("{}: the mesh has no triangles", test.scan.path.display()))?;
    let mut warnings = Vec::new();
    let mut warn = |message: String| {
        progress.warn(&message);
        warnings.push(message);
    };
    let breasts = Paired {
        reference: breast_model(
            reference,
            options.reference_control_points.as_deref(),
            "reference",
            &mut warn,
            progress,
        ),
        test: breast_model(
            test,
            options.test_control_points.as_deref(),
            "test",
            &mut warn,
            progress,
        ),
    };
    progress.step();

    let (comparison, source) = compare_surfaces(
        reference,
        test,
        (&registered, &registered_index),
        &breasts,
        options.max_distance_mm,
    )?;
    let statistics = comparison.zone_statistics();
    progress.step();

    let reference_distances = measure(reference, &[], progress)?.distances;
    progress.step();
    let test_distances = measure(test, &[], progress)?.distances;
    progress.step();
    let distances = reference_distances
        .iter()
        .zip(&test_distances)
        .map(|(r, t)| DistanceComparison::new(r, t))
        .collect();

    let symmetries = Paired {
        reference: symmetry_analysis(
            reference,
            breasts.reference.as_ref(),
            "reference",
            options.max_distance_mm,
            &mut warn,
            progress,
        ),
        test: symmetry_analysis(
            test,
            breasts.test.as_ref(),
            "test",
            options.max_distance_mm,
            &mut warn,
            progress,
        ),
    };

    if let Some(out) = &options.out {
        let asymmetry = symmetries.test.as_ref().map(|s| &s.comparison);
        write_deviation_mesh(out, registered, &comparison, asymmetry)?;
    }
    progress.step();

    let volumes = |model: &Option<BreastModel>| {
        model
            .as_ref()
            .map(|m| PerSide::from_fn(|side| m.breast(side).volume_ml))
    };
    let quadrants = |model: &Option<BreastModel>| {
        model
            .as_ref()
            .map(|m| PerSide::from_fn(|side| m.breast(side).quadrant_volume_ml))
    };
    let overall = statistics.whole;
    Ok(CompareReport {
        reference: ScanFiles::of(reference, options.reference_control_points.as_deref()),
        test: ScanFiles::of(test, options.test_control_points.as_deref()),
        registration,
        max_distance_mm: options.max_distance_mm,
        rms_mm: overall.rms_mm,
        mean_mm: overall.mean_mm,
        signed_mean_mm: overall.signed_mean_mm,
        hausdorff_mm: overall.hausdorff_mm,
        overlap_fraction: comparison.test_overlap_fraction(),
        reference_overlap_fraction: comparison.reference_overlap_fraction(),
        overall,
        breast_regions: BreastRegionStatistics {
            left: statistics.left_breast,
            right: statistics.right_breast,
            both: statistics.both_breasts,
            source,
        },
        distances,
        breast_volume_ml: Paired {
            reference: volumes(&breasts.reference),
            test: volumes(&breasts.test),
        },
        quadrant_volume_ml: Paired {
            reference: quadrants(&breasts.reference),
            test: quadrants(&breasts.test),
        },
        symmetry: Paired {
            reference: symmetries.reference.as_ref().map(SymmetryReport::new),
            test: symmetries.test.as_ref().map(SymmetryReport::new),
        },
        warnings,
        out: options.out.clone(),
    })
}

/// The test scan, `registered` onto the reference, against the reference scan, within
/// `max_distance_mm`, over the breast regions of their `breasts` models; and where each
/// scan's breast regions come from.
fn compare_surfaces(
    reference: &MarkedScan,
    test: &MarkedScan,
    (registered, registered_index): (&TriMesh, &SurfaceIndex),
    breasts: &Paired<Option<BreastModel>>,
    max_distance_mm: f64,
) -> Result<(SurfaceComparison, Paired<RegionSource>)> {
    let reference_surface = DistanceSurface::new(
        &reference.scan.mesh,
        &reference.scan.index,
        &reference.scan.topology,
    );
    let test_surface = DistanceSurface::new(registered, registered_index, &test.scan.topology);
    let (sides, source) = breast_regions(
        (&reference_surface, breasts.reference.as_ref()),
        (&test_surface, breasts.test.as_ref()),
        max_distance_mm,
    );
    let comparison = SurfaceComparison::new(
        &reference_surface,
        sides.reference,
        &test_surface,
        sides.test,
        max_distance_mm,
    )
    .with_context(|| {
        format!(
            "comparing {} with {}",
            test.scan.path.display(),
            reference.scan.path.display()
        )
    })?;
    Ok((comparison, source))
}

/// Fails unless the deviation mesh is to be a PLY file and each control-point file the
/// user named is readable: checked before the work.
fn check_files(options: &CompareOptions) -> Result<()> {
    if let Some(out) = &options.out {
        let is_ply = out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
        if !is_ply {
            bail!(
                "{}: the deviation mesh is written as PLY (its distances are vertex properties): give a .ply file",
                out.display()
            );
        }
    }
    for path in [
        &options.reference_control_points,
        &options.test_control_points,
    ]
    .into_iter()
    .flatten()
    {
        ControlPoints::read(path)?;
    }
    Ok(())
}

/// The symmetry analysis of a scan with its breast `model`, or `None` with a warning
/// saying why it failed (or without one when the scan has no model).
fn symmetry_analysis(
    marked: &MarkedScan,
    model: Option<&BreastModel>,
    role: &str,
    max_distance_mm: f64,
    warn: &mut impl FnMut(String),
    progress: &dyn Progress,
) -> Option<Symmetry> {
    let model = model?;
    let analysis = analyse_symmetry(
        &SymmetryInput {
            mesh: &marked.scan.mesh,
            index: &marked.scan.index,
            topology: &marked.scan.topology,
            landmarks: &marked.landmarks,
            frame: &marked.frame,
            breasts: model,
        },
        max_distance_mm,
    );
    progress.step();
    analysis
        .map_err(|error| {
            warn(format!(
                "the {role} scan {}: no symmetry analysis: {error}",
                marked.scan.path.display()
            ))
        })
        .ok()
}

/// The breast model of a scan, or `None` with a warning saying why it failed: the
/// comparison goes on without that scan's volumes and symmetry.
fn breast_model(
    marked: &MarkedScan,
    control_points_file: Option<&Path>,
    role: &str,
    warn: &mut impl FnMut(String),
    progress: &dyn Progress,
) -> Option<BreastModel> {
    build_breasts(
        marked,
        &BreastOptions::default(),
        control_points_file,
        progress,
    )
        .map(|(breasts, _)| breasts)
        .map_err(|error| {
            warn(format!(
                "the {role} scan has no breast model, so no breast volumes or symmetry (its breast regions come from the other scan): {}",
                crate::one_line(&error)
            ))
        })
        .ok()
}

/// The breast region of every vertex of both scans: each scan's own cut curves, or the
/// other scan's regions carried over where its breast model is missing.
fn breast_regions(
    reference: (&DistanceSurface<'_>, Option<&BreastModel>),
    test: (&DistanceSurface<'_>, Option<&BreastModel>),
    max_distance_mm: f64,
) -> (Paired<Vec<Option<Side>>>, Paired<RegionSource>) {
    let own = |(surface, model): (&DistanceSurface<'_>, Option<&BreastModel>)| {
        model.map(|m| m.scan_vertex_sides(surface.mesh().vertex_count()))
    };
    let carried = |from: &DistanceSurface<'_>, sides: &[Option<Side>], to: &DistanceSurface<'_>| {
        transfer_sides(from, sides, &to.mesh().positions, max_distance_mm)
    };
    match (own(reference), own(test)) {
        (Some(reference_sides), Some(test_sides)) => (
            Paired {
                reference: reference_sides,
                test: test_sides,
            },
            Paired {
                reference: RegionSource::CutCurves,
                test: RegionSource::CutCurves,
            },
        ),
        (Some(reference_sides), None) => (
            Paired {
                test: carried(reference.0, &reference_sides, test.0),
                reference: reference_sides,
            },
            Paired {
                reference: RegionSource::CutCurves,
                test: RegionSource::OtherScan,
            },
        ),
        (None, Some(test_sides)) => (
            Paired {
                reference: carried(test.0, &test_sides, reference.0),
                test: test_sides,
            },
            Paired {
                reference: RegionSource::OtherScan,
                test: RegionSource::CutCurves,
            },
        ),
        (None, None) => (
            Paired {
                reference: vec![None; reference.0.mesh().vertex_count()],
                test: vec![None; test.0.mesh().vertex_count()],
            },
            Paired {
                reference: RegionSource::None,
                test: RegionSource::None,
            },
        ),
    }
}

/// Writes the (registered) test mesh with the deviation colour map and the distance
/// scalars (see the module documentation), atomically.
fn write_deviation_mesh(
    path: &Path,
    mut mesh: TriMesh,
    comparison: &SurfaceComparison,
    symmetry: Option<&SurfaceComparison>,
) -> Result<()> {
    let distances = comparison.test_distances_mm();
    let signed = comparison.test_signed_distances_mm();
    let asymmetry = symmetry.map_or_else(
        || vec![f64::NAN; mesh.vertex_count()],
        SurfaceComparison::test_signed_distances_mm,
    );
    mesh.vertex_colors = Some(distances.iter().map(|&d| deviation_color(d)).collect());
    let scalars = [
        VertexScalar {
            name: "distance_mm",
            values: &distances,
        },
        VertexScalar {
            name: "signed_distance_mm",
            values: &signed,
        },
        VertexScalar {
            name: "asymmetry_mm",
            values: &asymmetry,
        },
    ];
    write_ply_with_scalars(path, &mesh, PlyEncoding::BinaryLittleEndian, &scalars)
        .with_context(|| format!("writing {}", path.display()))
}
