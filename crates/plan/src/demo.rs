//! `mammaplan phantom` and `mammaplan demo`: the built-in phantom written to disk, and
//! the pipeline run end to end on it.

use crate::measure::{MeasureReport, measure};
use crate::model::{ModelOptions, ModelReport, PerSide, build_model, write_model};
use crate::register::{RegisterReport, register, write_registered_mesh};
use crate::report::{ReportInputs, ReportSummary, write_report};
use crate::simulate::{ImplantRequest, Session, SimulateOptions, SimulateReport, run_session};
use crate::{MarkedScan, Progress, Scan};
use anatomy::register::RigidTransform;
use anyhow::Result;
use glam::{DMat3, DQuat, DVec3};
use phantom::{Phantom, PhantomParams};
use serde::Serialize;
use serde_json::json;
use std::path::{Path, PathBuf};
use std::time::SystemTime;

/// Generates a phantom and writes its scan and landmark file; the landmark file also
/// carries the phantom's true breast volumes (`true_breast_volume_ml`).
pub fn write_phantom(
    params: &PhantomParams,
    scan_path: &Path,
    landmarks_path: &Path,
) -> Result<Phantom> {
    // the folder resolved (links, `..`), the name as given
    let resolved = |path: &Path| {
        let folder = path
            .parent()
            .filter(|folder| !folder.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        match (folder.canonicalize(), path.file_name()) {
            (Ok(folder), Some(name)) => folder.join(name),
            _ => path.to_path_buf(),
        }
    };
    if resolved(scan_path) == resolved(landmarks_path) {
        anyhow::bail!(
            "the scan and the landmark file would both be {}: give them different names",
            scan_path.display()
        );
    }
    let phantom = phantom::generate(params);
    write_phantom_files(&phantom, params, scan_path, landmarks_path)?;
    Ok(phantom)
}

fn write_phantom_files(
    phantom: &Phantom,
    params: &PhantomParams,
    scan_path: &Path,
    landmarks_path: &Path,
) -> Result<()> {
    let mut staged = crate::staged::Staged::new();
    let textured = scan_path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("obj"));
    if textured {
        stage_textured_phantom(&mut staged, phantom, scan_path)?;
    } else {
        staged.write(scan_path, |path| mesh::io::write_mesh(path, &phantom.scan))?;
    }
    let mut additional = serde_json::Map::new();
    additional.insert(
        "true_breast_volume_ml".into(),
        json!({"left": phantom.breast_volume_ml.left, "right": phantom.breast_volume_ml.right}),
    );
    additional.insert("phantom".into(), json!(params.to_string()));
    staged.write(landmarks_path, |path| {
        phantom.landmarks.write(path, additional)
    })?;
    staged.commit()
}

/// Stages the phantom's scan as the OBJ `scan_path` wearing its photograph
/// ([`phantom::SkinTexture`]): `<stem>.mtl` and `<stem>.png` beside it.
fn stage_textured_phantom(
    staged: &mut crate::staged::Staged,
    phantom: &Phantom,
    scan_path: &Path,
) -> Result<()> {
    let folder = scan_path.parent().unwrap_or(Path::new(""));
    let stem = scan_path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scan".into());
    let image_path = folder.join(format!("{stem}.png"));
    let texture = &phantom.texture;
    let bytes: Vec<u8> = texture.rgb.iter().flatten().copied().collect();
    staged.write(&image_path, |path| {
        image::save_buffer(
            path,
            &bytes,
            texture.width,
            texture.height,
            image::ColorType::Rgb8,
        )
    })?;
    let mut scan = phantom.scan.clone();
    scan.uv = Some(mesh::UvLayer {
        coords: texture.uv.clone(),
        triangles: scan.triangles.clone(),
    });
    crate::texture::stage_obj_wearing(staged, folder, &stem, &format!("{stem}.png"), &scan)?;
    Ok(())
}

/// The demo's implant on both sides: the built-in catalog's moderate-profile round
/// implant of 120 mm diameter and 33.5 mm projection, 253 ml.
pub const DEMO_IMPLANT: &str = "catalog:R-MOD-120";

/// What the demo did, for the summary and `--json`.
#[derive(Debug, Clone, Serialize)]
pub struct DemoReport {
    pub out_dir: PathBuf,
    pub vertices: usize,
    pub triangles: usize,
    pub true_breast_volume_ml: [f64; 2],
    pub measurements: MeasureReport,
    pub registration: RegisterReport,
    /// Error of the recovered transform against the known one.
    pub registration_error_deg: f64,
    pub registration_error_mm: f64,
    /// The breast model of the phantom, written to `model/`.
    pub model: ModelReport,
    /// Its breast volumes against the phantom's truth (per cent, signed).
    pub breast_volume_error_percent: PerSide<f64>,
    /// A round 250 ml implant ([`DEMO_IMPLANT`]) on both sides, written to `simulation/`.
    pub simulation: SimulateReport,
    /// The report of the model and the simulation, `report.html`.
    pub report: ReportSummary,
    pub files: Vec<PathBuf>,
}

/// What a demo writes into its folder, replaced all or nothing
/// ([`crate::staged::FolderUpdate`]): a failure half way leaves the folder as it was.
pub const DEMO_ENTRIES: [&str; 10] = [
    "scan.ply",
    "landmarks.json",
    "followup_scan.ply",
    "followup_landmarks.json",
    "measurements.json",
    "followup_registered.ply",
    "registration.json",
    "model",
    "simulation",
    "report.html",
];

/// What a textured demo (`demo --textured`) writes instead of `scan.ply`: the phantom's
/// scan as an OBJ wearing its photograph.
pub const TEXTURED_SCAN_ENTRIES: [&str; 3] = ["scan.obj", "scan.mtl", "scan.png"];

/// The entries a demo replaces in its folder.
fn demo_entries(textured: bool) -> Vec<&'static str> {
    DEMO_ENTRIES
        .iter()
        .flat_map(|&entry| match (entry, textured) {
            ("scan.ply", true) => TEXTURED_SCAN_ENTRIES.to_vec(),
            _ => vec![entry],
        })
        .collect()
}

/// The known motion between the demo's two scans: 6 degrees about an oblique axis and a
/// 30 mm shift, like a patient standing differently at the follow-up.
fn follow_up_motion() -> RigidTransform {
    RigidTransform {
        rotation: DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(0.1, 0.9, 0.4).normalize(),
            6f64.to_radians(),
        )),
        translation: DVec3::new(28.0, 6.0, -12.0),
    }
}

/// Runs the pipeline on the phantom into `out_dir`: phantom scan, measurements, a second
/// noisy scan in a moved frame and its registration back onto the first, the breast
/// model of the first (in `out_dir/model`), the simulation of [`DEMO_IMPLANT`] on both
/// sides (in `out_dir/simulation`) and the report of both (`out_dir/report.html`).
/// `textured`: the phantom's scan is written as `scan.obj` wearing its photograph and
/// read back from there, so the model, the simulation and the report's views carry it.
pub fn demo(out_dir: &Path, textured: bool, progress: &dyn Progress) -> Result<DemoReport> {
    let update = crate::staged::FolderUpdate::begin(out_dir, &demo_entries(textured))?;
    let path = |name: &str| out_dir.join(name);
    let mut files = Vec::new();

    progress.stage("phantom", 2);
    let params = PhantomParams::default();
    let scan_name = if textured { "scan.obj" } else { "scan.ply" };
    let phantom = write_phantom(&params, &path(scan_name), &path("landmarks.json"))?;
    if textured {
        files.extend(TEXTURED_SCAN_ENTRIES.map(path));
    } else {
        files.push(path(scan_name));
    }
    files.push(path("landmarks.json"));
    progress.step();

    // The follow-up scan: the same body with fresh scanner noise, in a moved frame.
    let follow_up_params = PhantomParams {
        noise_mm: 0.2,
        seed: params.seed + 1,
        ..params
    };
    let mut follow_up = phantom::generate(&follow_up_params);
    let motion = follow_up_motion();
    follow_up.scan.map_positions(|p| motion.apply(p));
    follow_up.landmarks.map_positions(|p| motion.apply(p));
    write_phantom_files(
        &follow_up,
        &follow_up_params,
        &path("followup_scan.ply"),
        &path("followup_landmarks.json"),
    )?;
    files.extend([path("followup_scan.ply"), path("followup_landmarks.json")]);
    progress.step();

    progress.stage("measure", 1);
    let fixed_scan = if textured {
        Scan::load(&path(scan_name), progress)?
    } else {
        Scan::from_mesh(phantom.scan.clone(), &path(scan_name))?
    };
    let fixed = MarkedScan::new(
        fixed_scan,
        phantom.landmarks.clone(),
        &path("landmarks.json"),
        None,
        progress,
    )?;
    let measurements = measure(&fixed, &[], progress)?;
    crate::write_json(&path("measurements.json"), &measurements)?;
    files.push(path("measurements.json"));
    progress.step();

    progress.stage("register", 1);
    let moving = MarkedScan::new(
        Scan::from_mesh(follow_up.scan, &path("followup_scan.ply"))?,
        follow_up.landmarks,
        &path("followup_landmarks.json"),
        None,
        progress,
    )?;
    let (transform, registration) = register(&fixed, &moving, true)?;
    write_registered_mesh(&path("followup_registered.ply"), &moving, &transform)?;
    crate::write_json(&path("registration.json"), &registration)?;
    files.extend([path("followup_registered.ply"), path("registration.json")]);
    progress.step();

    let patient = build_model(&fixed, &ModelOptions::default(), progress)?;
    let model = write_model(&path("model"), &patient, progress)?;
    files.extend(model.files.iter().map(|name| path("model").join(name)));

    let session = Session::new(
        fixed,
        patient,
        implant::Catalog::builtin(),
        simulation::SimulationOptions::default(),
    )?;
    let request = Some(ImplantRequest::new(DEMO_IMPLANT));
    let simulation = run_session(
        session,
        &path("model"),
        &path("simulation"),
        &SimulateOptions {
            left: request.clone(),
            right: request,
            ..Default::default()
        },
        progress,
    )?;
    files.extend(
        simulation
            .files
            .iter()
            .map(|name| path("simulation").join(name)),
    );
    let report = write_report(
        &ReportInputs {
            model_dir: path("model"),
            simulation_dir: path("simulation"),
            postoperative: None,
            created: SystemTime::now(),
            show_muscle: false,
        },
        &path("report.html"),
        progress,
    )?;
    files.push(path("report.html"));
    let truth = phantom.breast_volume_ml;
    let breast_volume_error_percent = PerSide {
        left: 100.0 * (model.breast_volume_ml.left / truth.left - 1.0),
        right: 100.0 * (model.breast_volume_ml.right / truth.right - 1.0),
    };

    update.commit()?;
    let error = transform.after(&motion);
    Ok(DemoReport {
        out_dir: out_dir.to_path_buf(),
        vertices: phantom.scan.vertex_count(),
        triangles: phantom.scan.triangle_count(),
        true_breast_volume_ml: [
            phantom.breast_volume_ml.left,
            phantom.breast_volume_ml.right,
        ],
        measurements,
        registration,
        registration_error_deg: error.rotation_angle_deg(),
        registration_error_mm: error.translation.length(),
        model,
        breast_volume_error_percent,
        simulation,
        report,
        files,
    })
}
