//! The model folder: written all or nothing, read back and checked against its inputs.
//!
//! The model folder holds:
//! - `closed_surface.ply`: the watertight surface the finite elements will fill;
//! - `breast_left.ply`, `breast_right.ply`: the breast patches (skin inside each curve),
//!   with a vertex property `reconstructed` (1 where the scanner saw no skin and the
//!   model filled it in, 0 where it was measured);
//! - `fill_left.ply`, `fill_right.ply`: the fill-ins behind the breasts (rear wall);
//! - `filled_base.ply`: the scan without the breasts, with both fill-ins stitched in;
//! - `cut_curve_left.obj`, `cut_curve_right.obj`: each cut curve as a closed polyline
//!   (OBJ `v` and `l` records; ParaView, MeshLab and Blender open them as lines);
//! - `tets_level0.vtu`, `tets_level1.vtu`, ...: the tetrahedral meshes of the closed
//!   surface, level 0 the finest (VTK XML unstructured grids; ParaView opens them);
//! - `muscle_left.ply`, `muscle_right.ply`: the surface of each side's pectoralis major,
//!   the finest level's elements the simulation gives the muscle's material
//!   ([`simulation::muscle`]);
//! - `control_points.json`: the control points used, snapped to the surface, in the
//!   control-point file format, so a user can move some and pass the file back with
//!   `--control-points`;
//! - `model.json`: the figures ([`ModelReport`]), written last.
//!
//! Every file is written to a temporary name and renamed; the folder is only created
//! once the model is built, so a failed build writes nothing.

use super::*;

/// Writes the model folder (its files: [`crate::model::folder`]), creating it if
/// needed, and returns the report that `model.json` holds. The files are written all or
/// nothing ([`crate::staged`]); `model.json` comes last.
pub fn write_model(
    out_dir: &Path,
    model: &PatientModel,
    progress: &dyn Progress,
) -> Result<ModelReport> {
    std::fs::create_dir_all(out_dir).with_context(|| format!("creating {}", out_dir.display()))?;
    let report_path = out_dir.join("model.json");
    let mut staged = crate::staged::Staged::new();
    let breasts = &model.breasts;
    let meshes = [
        ("fill_left.ply", &breasts.left.fill.mesh),
        ("fill_right.ply", &breasts.right.fill.mesh),
        ("filled_base.ply", &breasts.filled_base),
    ];
    let levels = &model.tets.levels;
    progress.stage("write", (meshes.len() + levels.len()) as u64 + 7);
    let mut files = vec!["closed_surface.ply".to_string()];
    staged.write(&out_dir.join(&files[0]), |path| {
        mesh::io::write_mesh(path, &model.closed_surface.mesh)
    })?;
    progress.step();
    // The breast patches carry which vertices are reconstructed skin (1) and which
    // were measured (0).
    for side in Side::BOTH {
        let breast = breasts.breast(side);
        let name = format!("breast_{side}.ply");
        let flags: Vec<f64> = breast
            .reconstructed
            .vertex_flags
            .iter()
            .map(|&f| f64::from(u8::from(f)))
            .collect();
        staged.write(&out_dir.join(&name), |path| {
            mesh::io::write_ply_with_scalars(
                path,
                &breast.patch.mesh,
                mesh::io::PlyEncoding::BinaryLittleEndian,
                &[mesh::io::VertexScalar {
                    name: "reconstructed",
                    values: &flags,
                }],
            )
        })?;
        files.push(name);
        progress.step();
    }
    for (name, mesh) in meshes {
        staged.write(&out_dir.join(name), |path| mesh::io::write_mesh(path, mesh))?;
        files.push(name.to_string());
        progress.step();
    }
    for (l, level) in levels.iter().enumerate() {
        let name = format!("tets_level{l}.vtu");
        staged.write(&out_dir.join(&name), |path| {
            tetra::vtu::write_vtu(path, &level.mesh, &[], &[])
        })?;
        files.push(name);
        progress.step();
    }
    for side in Side::BOTH {
        let name = format!("cut_curve_{side}.obj");
        let points: Vec<_> = breasts
            .breast(side)
            .curve
            .points
            .iter()
            .map(|p| p.position)
            .collect();
        staged.write(&out_dir.join(&name), |path| {
            write_closed_polyline(path, &points)
        })?;
        files.push(name);
        progress.step();
    }
    for side in Side::BOTH {
        if let Some(surface) = model.muscle_surfaces.get(side) {
            let name = format!("muscle_{side}.ply");
            staged.write(&out_dir.join(&name), |path| {
                mesh::io::write_mesh(path, surface)
            })?;
            files.push(name);
        }
    }
    staged.write(&out_dir.join("control_points.json"), |path| {
        model.control_points().write(path)
    })?;
    files.push("control_points.json".into());
    progress.step();
    let sha256 = staged.checksums()?;
    let inputs_sha256 = InputChecksums::of(&model.scan_path, &model.landmarks_path)?;
    files.push("model.json".into());
    let report = model.report(out_dir, files, sha256, inputs_sha256);
    staged.write(&report_path, |path| crate::write_json(path, &report))?;
    staged.commit()?;
    progress.step();
    Ok(report)
}

/// Writes a closed polyline as an OBJ file: one `v` per point and one `l` record
/// through all of them back to the first.
pub fn write_closed_polyline(path: &Path, points: &[mesh::DVec3]) -> Result<()> {
    mesh::io::write_atomically(path, |w| {
        writeln!(w, "# mammaplan cut curve, {} points (mm)", points.len())?;
        for p in points {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        if !points.is_empty() {
            write!(w, "l")?;
            for k in (1..=points.len()).chain([1]) {
                write!(w, " {k}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    })?;
    Ok(())
}

/// What [`load_model`] and the report read back from `model.json`.
#[derive(Debug, Deserialize)]
pub(crate) struct ModelRecord {
    /// Absent in folders from before the program was recorded.
    #[serde(default)]
    pub software: Option<String>,
    pub scan: PathBuf,
    /// Absent in folders from before units: millimetres.
    #[serde(default)]
    pub scan_units: Option<String>,
    pub landmarks: PathBuf,
    /// Absent in folders from before the standing frame: the file's vertical.
    pub up: Option<crate::UpRecord>,
    pub elements_requested: usize,
    pub rear_wall_offset_mm: f64,
    pub refinement: Option<Refinement>,
    pub levels: Vec<LevelRecord>,
    pub breast_volume_ml: PerSide<f64>,
    pub quadrant_volume_ml: PerSide<QuadrantVolumes>,
    /// Absent in folders from before checksums were recorded.
    #[serde(default)]
    pub sha256: crate::checksum::Checksums,
    /// Absent in folders from before the inputs' checksums were recorded.
    #[serde(default)]
    pub inputs_sha256: Option<InputChecksums>,
}

#[derive(Debug, Deserialize)]
pub(crate) struct LevelRecord {
    pub elements: usize,
    pub nodes: usize,
}

impl ModelRecord {
    /// The unit of the scan file's coordinates (millimetres in folders from before
    /// units); `report` names the file in an error.
    pub fn scan_unit(&self, report: &Path) -> Result<mesh::LengthUnit> {
        match &self.scan_units {
            None => Ok(mesh::LengthUnit::Millimetre),
            Some(symbol) => symbol.parse().map_err(|message: String| {
                anyhow::anyhow!("{}: scan_units: {message}", report.display())
            }),
        }
    }
}

/// Reads the `model.json` of a model folder; its volumes must be ones a model can have.
pub(crate) fn read_model_record(model_dir: &Path) -> Result<ModelRecord> {
    let record: ModelRecord = read_folder_json(model_dir, "model.json", "model", "model")?;
    crate::record_check::FieldCheck::default()
        .breast_volumes(&record.breast_volume_ml, |side| {
            Some(record.quadrant_volume_ml.get(side))
        })
        .finish(&model_dir.join("model.json"), "mammaplan model")?;
    Ok(record)
}

/// Reads `file` of a folder that `mammaplan {command}` writes (a `{kind}` folder) as `T`.
/// Errors name the file and the folder expected.
pub(crate) fn read_folder_json<T: serde::de::DeserializeOwned>(
    folder: &Path,
    file: &str,
    kind: &str,
    command: &str,
) -> Result<T> {
    let path = folder.join(file);
    let text = std::fs::read_to_string(&path).with_context(|| {
        format!(
            "reading {} (is {} a {kind} folder written by `mammaplan {command}`?)",
            path.display(),
            folder.display()
        )
    })?;
    serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not a {kind} report of this mammaplan version (run `mammaplan {command}` again)",
            path.display()
        )
    })
}

/// Reopens a model folder written by [`write_model`]: reads the scan and landmarks named
/// in its `model.json` and rebuilds the model with the folder's `control_points.json` and
/// the recorded settings (meshing is deterministic, so the result is the folder's; the
/// level sizes are checked against `model.json`, which catches a program that builds
/// models differently). The folder's files, and the scan and landmark files where
/// recorded, must match the checksums `model.json` recorded.
/// Returns the marked scan with the model.
pub fn load_model(model_dir: &Path, progress: &dyn Progress) -> Result<(MarkedScan, PatientModel)> {
    let report_path = model_dir.join("model.json");
    let record = read_model_record(model_dir)?;
    let up = record
        .up
        .map(|up| up.up())
        .transpose()
        .with_context(|| report_path.display().to_string())?;
    let mut options = ModelOptions {
        control_points_file: Some(model_dir.join("control_points.json")),
        elements: record.elements_requested,
        refinement: record.refinement,
        ..Default::default()
    };
    options.closed_surface.rear_wall_offset_mm = record.rear_wall_offset_mm;
    options.check().with_context(|| {
        format!(
            "{}: a field holds a value no `mammaplan model` writes (was the file edited?); \
             run `mammaplan model` again",
            report_path.display()
        )
    })?;
    crate::checksum::verify(model_dir, &record.sha256, "model.json", "mammaplan model")?;
    verify_inputs(&record, &report_path)?;
    let marked = MarkedScan::load_in(
        &record.scan,
        Some(record.scan_unit(&report_path)?),
        &record.landmarks,
        up,
        progress,
    )
    .with_context(|| format!("the scan named in {}", report_path.display()))?;
    let model = build_model(&marked, &options, progress)?;
    let rebuilt: Vec<(usize, usize)> = model.levels.iter().map(|l| (l.elements, l.nodes)).collect();
    let recorded: Vec<(usize, usize)> = record
        .levels
        .iter()
        .map(|l| (l.elements, l.nodes))
        .collect();
    if rebuilt != recorded {
        anyhow::bail!(
            "{}: rebuilding the model from {} gives tetrahedral levels (elements, nodes) \
             {rebuilt:?}, but the folder has {recorded:?}: {}; run `mammaplan model` again",
            model_dir.display(),
            record.scan.display(),
            why_the_rebuild_differs(&record, &crate::software())
        );
    }
    Ok((marked, model))
}

/// Refuses a scan or landmark file that is not the one the folder's model was built
/// from (when `model.json` recorded their checksums), before any rebuilding.
fn verify_inputs(record: &ModelRecord, report_path: &Path) -> Result<()> {
    let Some(expected) = &record.inputs_sha256 else {
        return Ok(());
    };
    for (what, path, expected) in [
        ("scan", &record.scan, &expected.scan),
        ("landmark file", &record.landmarks, &expected.landmarks),
    ] {
        let found = crate::checksum::file_sha256(path).with_context(|| {
            format!(
                "reading {}, the {what} named in {}",
                path.display(),
                report_path.display()
            )
        })?;
        anyhow::ensure!(
            &found == expected,
            "{} is not the {what} the model in {} was built from (its checksum differs from \
             the one recorded): it was changed since; run `mammaplan model` again",
            path.display(),
            report_path.display()
        );
    }
    Ok(())
}

/// Why a model rebuilt from a folder's recorded inputs (checked unchanged where
/// recorded) can differ from the folder's, for a program named `this`.
fn why_the_rebuild_differs(record: &ModelRecord, this: &str) -> String {
    match (&record.inputs_sha256, &record.software) {
        (Some(_), Some(writer)) if writer == this => {
            "the scan and landmarks are those the model was built from and the program has \
             the same version and commit, so model.json or control_points.json was edited, \
             this build has changes not committed, another platform's arithmetic differs, or \
             the build is not exactly repeatable here (a fault: please report it with the \
             scan and landmark files)"
                .to_string()
        }
        (Some(_), Some(writer)) => format!(
            "the folder was written by {writer}, and this {this} builds a different model \
             from the same scan, landmarks and control points"
        ),
        _ => format!(
            "the scan or landmarks changed since, or the folder was written by a mammaplan \
             older than this {this}, which builds a different model"
        ),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each way a rebuilt model can differ is named: the same program (an edit), another
    /// version, and a folder from before programs and inputs were recorded.
    #[test]
    fn a_differing_rebuild_is_explained() {
        let record = |software: Option<&str>, inputs: bool| ModelRecord {
            software: software.map(str::to_string),
            scan: "scan.ply".into(),
            scan_units: None,
            landmarks: "landmarks.json".into(),
            up: None,
            elements_requested: DEFAULT_ELEMENTS,
            rear_wall_offset_mm: 15.0,
            refinement: None,
            levels: Vec::new(),
            breast_volume_ml: PerSide::from_fn(|_| 300.0),
            quadrant_volume_ml: PerSide::from_fn(|_| QuadrantVolumes::default()),
            sha256: Default::default(),
            inputs_sha256: inputs.then(|| InputChecksums {
                scan: "0".repeat(64),
                landmarks: "1".repeat(64),
            }),
        };
        let this = "mammaplan 0.2.0 (commit 0123456789ab)";
        assert!(
            why_the_rebuild_differs(&record(Some(this), true), this)
                .starts_with("the scan and landmarks are those the model was built from")
        );
        assert!(
            why_the_rebuild_differs(&record(Some("mammaplan 0.1.0"), true), this).starts_with(
                "the folder was written by mammaplan 0.1.0, and this mammaplan 0.2.0 (commit"
            )
        );
        assert!(
            why_the_rebuild_differs(&record(None, false), this)
                .starts_with("the scan or landmarks changed since, or the folder was written by")
        );
    }
}
