//! `mammaplan report`: one self-contained HTML page (crate `report`) about a plan, from
//! a model folder (`model.json`, `control_points.json`), a simulation folder
//! (`result.json`, `simulated_scan.ply`, `simulated_landmarks.json`, and
//! `simulated_control_points.json` where present) and optionally the post-operative scan
//! with its landmarks.
//!
//! Every scan shown is loaded with its landmarks ([`ShownScan`]). The pre-operative one
//! is cut into breasts with the model's own control points (the model's cut curves, for
//! the views; its volumes are `model.json`'s), the post-operative one with the default
//! control points from its landmarks (its breast and quadrant volumes). The simulated
//! breast and quadrant volumes are the simulation's (`result.json`: the pre-operative
//! breast patch moved with the tissue, over the chest wall, with the chest skin over an
//! implant that lies beyond the native breast; the post-operative scan's
//! own model closes its breast by a fill-in over its own cut curve, which measures less
//! where the implant pushes the breast's border forwards);
//! the simulated scan is cut along the model's curves carried with the tissue
//! (`simulated_control_points.json`) for its views and the comparison: a breast model
//! built afresh from the simulated landmarks would not measure the same breast, because
//! the fold landmarks move with the tissue in front of the implant. The clinical
//! distances are measured on the pre- and post-operative scans and read from
//! `result.json` for the simulation.

use crate::compare::{CompareOptions, compare};
use crate::measure::measure;
use crate::model::{
    PerSide, SIMULATED_CONTROL_POINTS, build_breasts, read_folder_json, read_model_record,
    write_model,
};
use crate::record_check::{FieldCheck, LENGTH_MM, SHIFT_MM, VOLUME_ML};
use crate::simulate::{AnchorRule, MaterialsReport, Session, SimulationState, write_simulation};
use crate::views::{RenderedView, ViewContent, standard_views};
use crate::{Distance, MarkedScan, Progress};
use anatomy::breast::{BreastModel, QuadrantVolumes, Side};
use anatomy::{AnatomicalFrame, BreastOptions, LandmarkName, Landmarks, Up};
use anyhow::{Context, Result};
use assess::{
    DEFAULT_MAX_DISTANCE_MM, DEVIATION_COLOR_MAX_MM, DeviationStatistics, DistanceSurface,
    deviation_color,
};
use glam::DVec3;
use render::{StandardView, Visibility};
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::{SystemTime, UNIX_EPOCH};

mod pictures;
mod record;
use pictures::reconstruction_note;
pub use pictures::report_views;
use record::{ImplantRecord, SimulationRecord, read_simulation_record};

/// What a report is made from.
#[derive(Debug, Clone)]
pub struct ReportInputs {
    /// A model folder written by `mammaplan model`.
    pub model_dir: PathBuf,
    /// A simulation folder written by `mammaplan simulate` from that model.
    pub simulation_dir: PathBuf,
    /// The post-operative scan, when there is one.
    pub postoperative: Option<PostoperativeScan>,
    /// When the report is made (shown as UTC date and time).
    pub created: SystemTime,
    /// Show the pectoralis major (the model folder's `muscle_*.ply`) through the
    /// pre-operative skin.
    pub show_muscle: bool,
}

/// A post-operative scan and its landmark file.
#[derive(Debug, Clone)]
pub struct PostoperativeScan {
    pub scan: PathBuf,
    pub landmarks: PathBuf,
    /// Which way is up in its file (`None`: resolved from the file and landmarks).
    pub up: Option<Up>,
    /// The unit of its coordinates (`None`: millimetres, checked).
    pub units: Option<mesh::LengthUnit>,
}

/// What was written.
#[derive(Debug, Clone, Serialize)]
pub struct ReportSummary {
    pub out: PathBuf,
    pub bytes: usize,
    pub views: usize,
    pub postoperative: bool,
    pub comparison: bool,
}

/// A scan the report shows: with its landmarks and frame, and cut into breasts where
/// the report measures its volumes.
pub struct ShownScan {
    pub marked: MarkedScan,
    /// Cut curves, breast patches, volumes.
    pub breasts: Option<BreastModel>,
}

impl ShownScan {
    /// Loads a scan with its landmarks.
    pub fn load(
        scan: &Path,
        landmarks: &Path,
        up: Option<Up>,
        progress: &dyn Progress,
    ) -> Result<ShownScan> {
        Ok(ShownScan {
            marked: MarkedScan::load(scan, landmarks, up, progress)?,
            breasts: None,
        })
    }

    /// Loads a scan (its coordinates in `unit`, see [`crate::Scan::load_in`]) with its
    /// landmarks and builds its breast model, with the control points of
    /// `control_points_file` when given (else the defaults from the landmarks).
    pub fn load_with_breasts(
        scan: &Path,
        unit: Option<mesh::LengthUnit>,
        landmarks: &Path,
        up: Option<Up>,
        control_points_file: Option<&Path>,
        progress: &dyn Progress,
    ) -> Result<ShownScan> {
        let marked = MarkedScan::load_in(scan, unit, landmarks, up, progress)?;
        let (breasts, _) = build_breasts(
            &marked,
            &BreastOptions::default(),
            control_points_file,
            progress,
        )?;
        Ok(ShownScan {
            marked,
            breasts: Some(breasts),
        })
    }
}

/// Breast and quadrant volumes of a breast model (ml).
fn model_volumes(breasts: &BreastModel) -> report::PerSide<report::BreastVolumes> {
    let side = |breast: &anatomy::breast::Breast| {
        breast_volumes(breast.volume_ml, Some(breast.quadrant_volume_ml))
    };
    report::PerSide {
        left: side(&breasts.left),
        right: side(&breasts.right),
    }
}

/// The scans of a report.
pub struct ReportScans {
    pub preoperative: ShownScan,
    pub simulated: ShownScan,
    pub postoperative: Option<ShownScan>,
}

/// The surface deviation of the simulated scan from the post-operative scan (RMS, mean
/// and symmetric Hausdorff distance over the whole overlap and over the breasts), the
/// post-operative scan registered onto the simulated one first ([`crate::compare`]).
/// The simulated breasts are cut along `simulated_control_points` (a file of control
/// points carried with the tissue) when given, else along the defaults from the
/// simulated landmarks.
pub fn compare_with_postoperative(
    simulated: &ShownScan,
    simulated_control_points: Option<&Path>,
    postoperative: &ShownScan,
    progress: &dyn Progress,
) -> Result<Option<report::Comparison>> {
    let options = CompareOptions {
        register: true,
        test_control_points: simulated_control_points.map(Path::to_path_buf),
        ..Default::default()
    };
    let compared = compare(&postoperative.marked, &simulated.marked, &options, progress)
        .context("comparing the simulated with the post-operative scan")?;
    let figures = |region: &str, stats: &DeviationStatistics| report::DeviationFigures {
        region: region.into(),
        rms_mm: stats.rms_mm,
        mean_mm: stats.mean_mm,
        hausdorff_mm: stats.hausdorff_mm,
    };
    let breasts = &compared.breast_regions;
    let mut regions = vec![figures("Whole overlap", &compared.overall)];
    for (region, stats) in [
        ("Left breast", &breasts.left),
        ("Right breast", &breasts.right),
        ("Both breasts", &breasts.both),
    ] {
        if let Some(stats) = stats {
            regions.push(figures(region, stats));
        }
    }
    Ok(Some(report::Comparison {
        reference: "Post-operative scan (registered)".into(),
        test: "Simulated scan".into(),
        regions,
    }))
}

/// A report's folders written by [`write_session_folders`], its page not yet. Dropped
/// without [`PendingReport::write`] succeeding, it leaves the folder as it was before.
pub struct PendingReport {
    pub inputs: ReportInputs,
    update: crate::staged::FolderUpdate,
}

impl PendingReport {
    /// Where the page goes: `report.html` beside the model and simulation folders.
    pub fn out(&self) -> PathBuf {
        self.inputs.model_dir.with_file_name("report.html")
    }

    /// Writes the page ([`write_report`]) and keeps the whole folder.
    pub fn write(self, progress: &dyn Progress) -> Result<ReportSummary> {
        let summary = write_report(&self.inputs, &self.out(), progress)?;
        self.update.commit()?;
        Ok(summary)
    }
}

/// Writes the files a report of an open session is made from into `folder` and returns
/// the report to write (created now): the scan as `scan.ply` when it was not read from a
/// file (the phantom), the landmarks the model was built from as `landmarks.json`, the
/// model folder `model/` ([`write_model`]) and the simulation folder `simulation/` of the
/// session's current prediction ([`write_simulation`], `state` saying how the session
/// got there). The session's model then names those scan and landmark files. The
/// report itself ([`PendingReport::write`]) reads only files, so a front end can write
/// it on another thread while the session goes on. The folder's entries are replaced
/// all or nothing ([`crate::staged::FolderUpdate`]).
pub fn write_session_folders(
    session: &mut Session,
    state: &SimulationState,
    folder: &Path,
    postoperative: Option<PostoperativeScan>,
    progress: &dyn Progress,
) -> Result<PendingReport> {
    let scan = &session.marked.scan;
    let writes_scan = !scan.path.is_file();
    let mut entries = vec!["landmarks.json", "model", "simulation", "report.html"];
    if writes_scan {
        entries.push("scan.ply");
    }
    let update = crate::staged::FolderUpdate::begin(folder, &entries)?;
    if writes_scan {
        let path = folder.join("scan.ply");
        mesh::io::write_mesh(&path, &scan.mesh)?;
        session.model.scan_path = path;
    }
    let landmarks = folder.join("landmarks.json");
    session
        .marked
        .landmarks
        .write(&landmarks, Default::default())?;
    session.model.landmarks_path = landmarks;
    let model_dir = folder.join("model");
    let simulation_dir = folder.join("simulation");
    write_model(&model_dir, &session.model, progress)?;
    write_simulation(session, state, &model_dir, &simulation_dir, progress)?;
    Ok(PendingReport {
        inputs: ReportInputs {
            model_dir,
            simulation_dir,
            postoperative,
            created: SystemTime::now(),
            show_muscle: false,
        },
        update,
    })
}

/// The pectoralis major from a model folder (`muscle_left.ply`, `muscle_right.ply`, each
/// written where the side has one); an error says what to do when neither is there.
fn read_muscles(model_dir: &Path) -> Result<Vec<mesh::TriMesh>> {
    let paths: Vec<PathBuf> = Side::BOTH
        .iter()
        .map(|side| model_dir.join(format!("muscle_{side}.ply")))
        .filter(|path| path.is_file())
        .collect();
    if paths.is_empty() {
        anyhow::bail!(
            "{} has no muscle_left.ply or muscle_right.ply: the model was built before the \
             pectoralis major was modelled; build it again with `mammaplan model` to show it",
            model_dir.display()
        );
    }
    paths
        .iter()
        .map(|path| mesh::io::read_mesh(path).with_context(|| path.display().to_string()))
        .collect()
}

/// Builds the report of `inputs` and writes it to `out` (atomically).
pub fn write_report(
    inputs: &ReportInputs,
    out: &Path,
    progress: &dyn Progress,
) -> Result<ReportSummary> {
    let content = report_content(inputs, progress)?;
    let page = report::render_html(&content);
    mesh::io::write_atomically(out, |w| w.write_all(page.as_bytes()))
        .with_context(|| format!("writing {}", out.display()))?;
    Ok(ReportSummary {
        out: out.to_path_buf(),
        bytes: page.len(),
        views: content.views.len(),
        postoperative: inputs.postoperative.is_some(),
        comparison: content.comparison.is_some(),
    })
}

/// What the report shows about `inputs`.
pub fn report_content(
    inputs: &ReportInputs,
    progress: &dyn Progress,
) -> Result<report::ReportContent> {
    let model_dir = &inputs.model_dir;
    let simulation_dir = &inputs.simulation_dir;
    let model = read_model_record(model_dir)?;
    let simulation = read_simulation_record(simulation_dir)?;

    progress.stage("report", 3 + 2 * inputs.postoperative.is_some() as u64);
    let model_up = model
        .up
        .map(|up| up.up())
        .transpose()
        .with_context(|| model_dir.join("model.json").display().to_string())?;
    let preoperative = ShownScan::load_with_breasts(
        &model.scan,
        Some(model.scan_unit(&model_dir.join("model.json"))?),
        &model.landmarks,
        model_up,
        Some(&model_dir.join("control_points.json")),
        progress,
    )
    .with_context(|| {
        format!(
            "the pre-operative scan named in {}",
            model_dir.join("model.json").display()
        )
    })?;
    let preoperative_distances = measure(&preoperative.marked, &[], progress)?.distances;
    progress.step();
    let (simulated, carried) =
        load_simulated(simulation_dir, &preoperative, &model, model_dir, progress)?;
    progress.step();
    let (postoperative, postoperative_distances) = match &inputs.postoperative {
        None => (None, None),
        Some(files) => {
            let scan = ShownScan::load_with_breasts(
                &files.scan,
                files.units,
                &files.landmarks,
                files.up,
                None,
                progress,
            )
            .context("the post-operative scan")?;
            progress.step();
            let distances = measure(&scan.marked, &[], progress)?.distances;
            progress.step();
            (Some(scan), Some(distances))
        }
    };
    let scans = ReportScans {
        preoperative,
        simulated,
        postoperative,
    };
    let comparison = match &scans.postoperative {
        Some(postoperative) => compare_with_postoperative(
            &scans.simulated,
            carried.as_deref(),
            postoperative,
            progress,
        )?,
        None => None,
    };
    let muscles = if inputs.show_muscle {
        read_muscles(model_dir)?
    } else {
        Vec::new()
    };
    let views = report_views(&scans, &muscles)?;
    progress.step();

    let volumes = volume_table(&model, &simulation, &scans);
    let symmetry = symmetry_rows(&scans, &volumes);

    let case = case_info(inputs, &model, &simulation)?;

    Ok(report::ReportContent {
        title: "Breast augmentation plan".into(),
        notes: notes(&simulation, model_dir)
            .into_iter()
            .chain(reconstruction_note(&scans))
            .collect(),
        case,
        implants: report::PerSide {
            left: (simulation.implants.left).map(|i| implant_choice(i, simulation.anchor)),
            right: (simulation.implants.right).map(|i| implant_choice(i, simulation.anchor)),
        },
        views,
        measurements: measurement_rows(
            &preoperative_distances,
            &simulation.distances,
            postoperative_distances.as_deref(),
        ),
        volumes,
        comparison,
        symmetry,
    })
}

/// The simulated scan of `simulation_dir` (wearing the pre-operative photograph), cut
/// along the model's curves carried with the tissue where the folder has them (their
/// file then comes back too: the comparison cuts along them); it must be the model's
/// scan moved (the same vertex count).
fn load_simulated(
    simulation_dir: &Path,
    preoperative: &ShownScan,
    model: &crate::model::ModelRecord,
    model_dir: &Path,
    progress: &dyn Progress,
) -> Result<(ShownScan, Option<PathBuf>)> {
    let mut simulated = ShownScan::load(
        &simulation_dir.join("simulated_scan.ply"),
        &simulation_dir.join("simulated_landmarks.json"),
        Some(preoperative.marked.up()),
        progress,
    )
    .with_context(|| format!("the simulated scan in {}", simulation_dir.display()))?;
    if let Some(scan) = std::sync::Arc::get_mut(&mut simulated.marked.scan) {
        scan.wear_texture_of(&preoperative.marked.scan);
    }
    // The simulated scan cut along the model's curves carried with the tissue (folders
    // written before those existed have none): its views show where it was measured.
    // The comparison cuts it along them too, if they served here (else it warns and
    // takes the post-operative scan's breast regions).
    let mut carried = Some(simulation_dir.join(SIMULATED_CONTROL_POINTS)).filter(|p| p.is_file());
    if let Some(path) = &carried {
        match build_breasts(
            &simulated.marked,
            &BreastOptions::default(),
            Some(path),
            progress,
        ) {
            Ok((breasts, _)) => simulated.breasts = Some(breasts),
            Err(error) => {
                progress.warn(&format!(
                    "the simulated scan's cut curves are not drawn: {}",
                    crate::one_line(&error)
                ));
                carried = None;
            }
        }
    }
    let (scan_vertices, simulated_vertices) = (
        preoperative.marked.scan.mesh.vertex_count(),
        simulated.marked.scan.mesh.vertex_count(),
    );
    anyhow::ensure!(
        scan_vertices == simulated_vertices,
        "{}: {simulated_vertices} vertices, but the model's scan {} has {scan_vertices}: the \
         simulation was not made from the model in {}",
        simulation_dir.join("simulated_scan.ply").display(),
        model.scan.display(),
        model_dir.display()
    );
    Ok((simulated, carried))
}

/// The breast and quadrant volumes before (the model's), as simulated (`result.json`'s)
/// and after (the post-operative scan's breast model, when given).
fn volume_table(
    model: &crate::model::ModelRecord,
    simulation: &SimulationRecord,
    scans: &ReportScans,
) -> report::VolumeTable {
    report::VolumeTable {
        preoperative: report::PerSide {
            left: breast_volumes(
                model.breast_volume_ml.left,
                Some(model.quadrant_volume_ml.left),
            ),
            right: breast_volumes(
                model.breast_volume_ml.right,
                Some(model.quadrant_volume_ml.right),
            ),
        },
        simulated: Some(report::PerSide {
            left: breast_volumes(
                simulation.breast_volume_ml.left,
                simulation.quadrant_volume_ml.left,
            ),
            right: breast_volumes(
                simulation.breast_volume_ml.right,
                simulation.quadrant_volume_ml.right,
            ),
        }),
        postoperative: scans
            .postoperative
            .as_ref()
            .and_then(|scan| scan.breasts.as_ref())
            .map(model_volumes),
    }
}

/// The symmetry rows of every scan with volumes.
fn symmetry_rows(scans: &ReportScans, volumes: &report::VolumeTable) -> Vec<report::SymmetryRow> {
    let mut symmetry = vec![symmetry_row(
        "Pre-operative",
        &scans.preoperative.marked,
        &volumes.preoperative,
    )];
    if let Some(simulated_volumes) = &volumes.simulated {
        symmetry.push(symmetry_row(
            "Simulated",
            &scans.simulated.marked,
            simulated_volumes,
        ));
    }
    if let (Some(scan), Some(post_volumes)) = (&scans.postoperative, &volumes.postoperative) {
        symmetry.push(symmetry_row("Post-operative", &scan.marked, post_volumes));
    }
    symmetry
}

/// The case: its files, the model's parameters and the solver's figures.
fn case_info(
    inputs: &ReportInputs,
    model: &crate::model::ModelRecord,
    simulation: &SimulationRecord,
) -> Result<report::CaseInfo> {
    let simulation_dir = &inputs.simulation_dir;
    let mut files = vec![
        case_file("Pre-operative scan", &model.scan),
        case_file("Pre-operative landmarks", &model.landmarks),
        case_file("Simulated scan", &simulation_dir.join("simulated_scan.ply")),
    ];
    if let Some(post) = &inputs.postoperative {
        files.push(case_file("Post-operative scan", &post.scan));
        files.push(case_file("Post-operative landmarks", &post.landmarks));
    }
    let finest = model
        .levels
        .first()
        .context("model.json lists no tetrahedral level")?;
    Ok(report::CaseInfo {
        created: utc_date_time(inputs.created),
        software: crate::software(),
        files,
        model: report::ModelParameters {
            finest_elements: finest.elements,
            finest_nodes: finest.nodes,
            mesh_levels: model.levels.len(),
            rear_wall_offset_mm: model.rear_wall_offset_mm,
            tissue: material(&simulation.materials.tissue),
            implant_material: material(&simulation.materials.implant),
            skin: simulation.materials.skin.map(|skin| {
                format!(
                    "{:.0} kPa, {:.2} mm thick, a membrane on the surface",
                    skin.young_kpa, skin.thickness_mm
                )
            }),
            compression_penalty: simulation.materials.compression_penalty.map(|penalty| {
                let onset = if penalty.onset_volume_ratio >= 1.0 {
                    "every loss".to_string()
                } else {
                    format!("beyond {:.0}%", 100.0 * (1.0 - penalty.onset_volume_ratio))
                };
                format!(
                    "{onset} resisted with {} times the first Lamé parameter",
                    penalty.lambda_multiple
                )
            }),
            gravity_correction: !simulation.no_gravity,
            up: model.up.as_ref().map_or_else(
                || "the file's +y (a model folder from before the standing frame)".to_string(),
                crate::UpRecord::in_words,
            ),
            pocket: simulation.pocket.as_ref().map(pocket_in_words),
            solver: report::SolverSummary {
                vcycles: simulation.solver.vcycles,
                relative_residual: simulation.solver.relative_residual,
                converged: simulation.solver.converged,
            },
        },
    })
}

/// The anchor rule of folders written before [`AnchorRule`] was recorded.
fn footprint_centre() -> AnchorRule {
    AnchorRule::FootprintCentre
}

/// A pocket's limits, in words.
fn pocket_in_words(pocket: &PerSide<crate::simulate::PocketReport>) -> String {
    let left = &pocket.left;
    let rule = |p: &crate::simulate::PocketReport| match p.fold_lowering_rule {
        crate::simulate::FoldLoweringRule::Ice => "ICE principle",
        crate::simulate::FoldLoweringRule::Given => "as planned",
    };
    format!(
        "the fill-in widened up to {:.0} mm over the chest where the implant needs it, {:.0} mm \
         from the midline, {:.0} mm beyond the fold's lateral end; fold lowered {:.0} mm left \
         ({}), {:.0} mm right ({})",
        left.margin_mm,
        left.midline_clearance_mm,
        left.lateral_beyond_fold_mm,
        left.fold_lowering_mm,
        rule(left),
        pocket.right.fold_lowering_mm,
        rule(&pocket.right),
    )
}

fn breast_volumes(breast_ml: f64, quadrants: Option<QuadrantVolumes>) -> report::BreastVolumes {
    report::BreastVolumes {
        breast_ml,
        quadrants_ml: quadrants.map(|q| report::QuadrantVolumes {
            upper_outer_ml: q.upper_outer,
            upper_inner_ml: q.upper_inner,
            lower_inner_ml: q.lower_inner,
            lower_outer_ml: q.lower_outer,
        }),
    }
}

fn material(material: &crate::simulate::MaterialReport) -> report::MaterialParameters {
    report::MaterialParameters {
        young_kpa: material.young_kpa,
        poisson_ratio: material.poisson_ratio,
        density_kg_m3: material.density_kg_m3,
    }
}

fn implant_choice(implant: ImplantRecord, anchor: AnchorRule) -> report::ImplantChoice {
    let variant = match (&implant.shape.profile, &implant.shape.taper) {
        (Some(profile), _) => format!(", {profile} profile"),
        (None, Some(taper)) => format!(", {taper} taper"),
        (None, None) => String::new(),
    };
    report::ImplantChoice {
        catalog: implant.catalog_id.map(|id| report::CatalogReference {
            id,
            family: implant.family.unwrap_or_default(),
        }),
        shape: format!("{}{variant}", implant.shape.shape),
        spec: implant.spec,
        width_mm: implant.width_mm,
        height_mm: implant.height_mm,
        projection_mm: implant.projection_mm,
        volume_ml: implant.volume_ml,
        default_position: match anchor {
            AnchorRule::OnFold => {
                "lower edge on the planned fold, below the point behind the nipple"
            }
            AnchorRule::FootprintCentre => "centred on the breast's base",
            AnchorRule::BehindNipple => "behind the nipple",
        }
        .into(),
        offset_mm: implant.move_mm,
        rotation_deg: implant.rotation_deg,
        fit_shift_mm: implant.fit_shift_mm,
    }
}

/// The clinical distances along the skin, one row per distance of the pre-operative
/// table, the other scans' values matched by name.
fn measurement_rows(
    preoperative: &[Distance],
    simulated: &[Distance],
    postoperative: Option<&[Distance]>,
) -> Vec<report::MeasurementRow> {
    let along_skin = |distances: &[Distance], name: &str| {
        distances
            .iter()
            .find(|d| d.name == name)
            .and_then(|d| d.surface_mm)
    };
    preoperative
        .iter()
        .map(|distance| report::MeasurementRow {
            name: distance.name.clone(),
            preoperative_mm: distance.surface_mm,
            simulated_mm: along_skin(simulated, &distance.name),
            postoperative_mm: postoperative.and_then(|d| along_skin(d, &distance.name)),
        })
        .collect()
}

/// Left against right on one scan: the breast volume ratio and the nipples compared
/// across the mid-sagittal plane.
fn symmetry_row(
    scan: &str,
    marked: &MarkedScan,
    volumes: &report::PerSide<report::BreastVolumes>,
) -> report::SymmetryRow {
    let nipples = NippleSymmetry::new(&marked.frame, &marked.landmarks);
    report::SymmetryRow {
        scan: scan.to_string(),
        volume_ratio_left_to_right: volumes.left.breast_ml / volumes.right.breast_ml,
        nipple_height_difference_mm: nipples.height_difference_mm,
        nipple_midline_difference_mm: nipples.midline_difference_mm,
        nipple_mirror_distance_mm: nipples.mirror_distance_mm,
    }
}

/// The nipples compared across the mid-sagittal plane, the anatomical frame's `x = 0`
/// (through Pj and Px, orthogonal to the line Pcr-Pcl). Differences are left minus right.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NippleSymmetry {
    /// Height along the frame's `y` (mm).
    pub height_difference_mm: f64,
    /// Distance to the mid-sagittal plane (mm).
    pub midline_difference_mm: f64,
    /// Distance from the left nipple to the right one mirrored across the plane (mm).
    pub mirror_distance_mm: f64,
}

impl NippleSymmetry {
    pub fn new(frame: &AnatomicalFrame, landmarks: &Landmarks) -> NippleSymmetry {
        let left = frame.to_local(landmarks.get(LandmarkName::Pnl));
        let right = frame.to_local(landmarks.get(LandmarkName::Pnr));
        let mirrored_right = DVec3::new(-right.x, right.y, right.z);
        NippleSymmetry {
            height_difference_mm: left.y - right.y,
            midline_difference_mm: left.x.abs() - right.x.abs(),
            mirror_distance_mm: left.distance(mirrored_right),
        }
    }
}

/// Remarks the reader must see: a solve that did not converge, inverted elements, a
/// simulation that names another model folder.
fn notes(simulation: &SimulationRecord, model_dir: &Path) -> Vec<String> {
    let mut notes = Vec::new();
    let solver = &simulation.solver;
    if !solver.converged {
        notes.push(format!(
            "The simulation stopped after {} multigrid cycles at relative residual {:.1e} \
             without reaching its tolerance: the prediction is approximate.",
            solver.vcycles, solver.relative_residual
        ));
    }
    if solver.inverted_elements > 0 {
        notes.push(format!(
            "{} finite elements of the simulation are inverted: the prediction is unreliable \
             near the implants.",
            solver.inverted_elements
        ));
    }
    let same_folder = match (
        std::fs::canonicalize(&simulation.model),
        std::fs::canonicalize(model_dir),
    ) {
        (Ok(recorded), Ok(given)) => recorded == given,
        _ => simulation.model == model_dir,
    };
    if !same_folder {
        notes.push(format!(
            "The simulation was made from the model folder {}, not from {}, the one given \
             for this report.",
            simulation.model.display(),
            model_dir.display()
        ));
    }
    notes
}

/// An input file by its role, file name only (folders may name the patient).
fn case_file(role: &str, path: &Path) -> report::CaseFile {
    report::CaseFile {
        role: role.to_string(),
        name: path.file_name().map_or_else(
            || path.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        ),
    }
}

/// `YYYY-MM-DD hh:mm UTC`.
pub fn utc_date_time(time: SystemTime) -> String {
    let seconds = time.duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let (year, month, day) = civil_date(seconds / 86_400);
    let minutes = seconds % 86_400 / 60;
    format!(
        "{year:04}-{month:02}-{day:02} {:02}:{:02} UTC",
        minutes / 60,
        minutes % 60
    )
}

/// The proleptic Gregorian date of a day counted from 1970-01-01 (H. Hinnant's
/// `civil_from_days`: 400-year eras of 146,097 days, years starting in March).
fn civil_date(days_since_epoch: u64) -> (u64, u64, u64) {
    let days = days_since_epoch + 719_468; // from 0000-03-01
    let era = days / 146_097;
    let day_of_era = days % 146_097;
    let year_of_era =
        (day_of_era - day_of_era / 1460 + day_of_era / 36_524 - day_of_era / 146_096) / 365;
    let day_of_year = day_of_era - (365 * year_of_era + year_of_era / 4 - year_of_era / 100);
    let month_from_march = (5 * day_of_year + 2) / 153;
    let day = day_of_year - (153 * month_from_march + 2) / 5 + 1;
    let month = if month_from_march < 10 {
        month_from_march + 3
    } else {
        month_from_march - 9
    };
    let year = year_of_era + era * 400 + u64::from(month <= 2);
    (year, month, day)
}

#[cfg(test)]
mod tests;
