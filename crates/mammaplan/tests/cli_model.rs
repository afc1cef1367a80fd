//! `mammaplan model` as users and scripts see it: the files it writes, its volumes,
//! units and quality, and clean failures that write nothing.

mod common;

use common::*;
use std::path::Path;
use std::process::Output;

#[test]
fn model_writes_every_file_and_the_volumes() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let out = dir.path().join("model");
    let output = model(&scan, &landmarks, &out, &[]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("stdout is JSON");
    let written: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("model.json")).unwrap()).unwrap();
    assert_eq!(json, written, "model.json holds what --json prints");
    for side in ["left", "right"] {
        let volume = json["breast_volume_ml"][side].as_f64().unwrap();
        assert!(volume > 50.0, "{side}: {volume} ml");
        let quadrants = &json["quadrant_volume_ml"][side];
        let sum: f64 = ["upper_outer", "upper_inner", "lower_inner", "lower_outer"]
            .iter()
            .map(|q| quadrants[q].as_f64().unwrap())
            .sum();
        assert!(
            (sum - volume).abs() < 0.005 * volume,
            "{side}: {sum} vs {volume}"
        );
        assert!(json["max_stitch_angle_deg"][side].as_f64().is_some());
    }
    let closed = json["closed_surface_volume_ml"].as_f64().unwrap();
    assert!(closed > json["breast_volume_ml"]["left"].as_f64().unwrap());
    for key in [
        "clip_box",
        "rear_wall_offset_mm",
        "holes_closed",
        "counts",
        "timings",
        "min_dihedral_deg",
        "pectoralis_major",
    ] {
        assert!(json.get(key).is_some(), "{key} missing");
    }
    for file in MODEL_FILES {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let levels = json["levels"].as_array().unwrap();
    assert_eq!(levels.len(), 3);
    for level in levels {
        for key in [
            "elements",
            "nodes",
            "spacing_mm",
            "min_dihedral_deg",
            "max_dihedral_deg",
            "volume_ml",
        ] {
            assert!(level.get(key).is_some(), "levels: {key} missing");
        }
    }
    let files: Vec<&str> = json["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| f.as_str().unwrap())
        .collect();
    assert_eq!(files, MODEL_FILES);
    assert_no_temporary_files(&out);
    // A cut curve: one vertex per point and one closed line through them.
    let curve = std::fs::read_to_string(out.join("cut_curve_left.obj")).unwrap();
    let points = curve.lines().filter(|l| l.starts_with("v ")).count();
    let line: Vec<&str> = curve.lines().filter(|l| l.starts_with("l ")).collect();
    assert_eq!(
        points,
        json["counts"]["cut_curve_points"]["left"].as_u64().unwrap() as usize
    );
    assert_eq!(line.len(), 1);
    assert_eq!(line[0].split_whitespace().count(), points + 2);

    // The control points written back give the same model.
    let again = dir.path().join("again");
    let control_points = out.join("control_points.json");
    let output = model(
        &scan,
        &landmarks,
        &again,
        &["--control-points", control_points.to_str().unwrap()],
    );
    assert!(output.status.success(), "{}", stderr(&output));
    let json_again: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    for side in ["left", "right"] {
        let (a, b) = (
            json["breast_volume_ml"][side].as_f64().unwrap(),
            json_again["breast_volume_ml"][side].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 1e-3 * a, "{side}: {a} vs {b} ml");
    }
}

#[test]
fn bad_model_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let out = dir.path().join("model");

    let control_points = dir.path().join("cp.json");
    std::fs::write(&control_points, "{\"units\":\"mm\",\"left\":[[0,0,0]]").unwrap();
    let output = model(
        &scan,
        &landmarks,
        &out,
        &["--control-points", control_points.to_str().unwrap()],
    );
    assert_clean_failure(&output, "control point file");
    assert!(stderr(&output).contains("cp.json: not valid JSON"));
    assert!(output.stdout.is_empty());
    assert!(!out.exists());

    // PSMFml and PSMFll swapped: the left cut curve runs back across itself.
    let swapped = dir.path().join("swapped.json");
    std::fs::copy(&landmarks, &swapped).unwrap();
    edit_landmarks(&swapped, |json| {
        let landmarks = &mut json["landmarks"];
        let medial = landmarks["PSMFml"].take();
        landmarks["PSMFml"] = landmarks["PSMFll"].take();
        landmarks["PSMFll"] = medial;
    });
    let output = model(&scan, &swapped, &out, &[]);
    assert_clean_failure(
        &output,
        "left breast: the cut curve cannot be laid on the scan: the curve crosses or touches itself",
    );
    assert!(!out.exists());

    edit_landmarks(&landmarks, |json| {
        json["landmarks"].as_object_mut().unwrap().remove("PSMFll");
    });
    let output = model(&scan, &landmarks, &out, &[]);
    assert_clean_failure(&output, "missing required landmark PSMFll");
    assert!(!out.exists());

    assert_clean_failure(
        &model(&scan, &landmarks, &out, &["--pc-ratio", "1.5"]),
        "expected a number between 0 and 1",
    );
    assert_clean_failure(
        &model(&scan, &landmarks, &out, &["--rear-wall-offset-mm", "0"]),
        "expected a number > 0",
    );
    assert_clean_failure(
        &model(&scan, &landmarks, &out, &["--rear-wall-offset-mm", "1e6"]),
        "at most 60 mm",
    );
    assert_clean_failure(
        &model(&scan, &landmarks, &out, &["--elements", "0"]),
        "expected a whole number > 0",
    );
    assert!(!out.exists());
}

/// The zoo's s03 (`../shared`) with its scan and landmark file in metres (`"units":
/// "m"`): refused without `--units`, naming `--units m`; with it, the breast volumes of
/// the millimetre files within 0.1% (the scan's single-precision coordinates, divided
/// by 1000, round differently).
#[test]
fn a_scan_in_metres_needs_units_and_then_models_as_in_millimetres() {
    let shared = Path::new(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scans/zoo"
    ));
    if !shared.is_dir() {
        assert!(
            std::env::var_os("CI").is_none(),
            "{} is missing",
            shared.display()
        );
        eprintln!("skipped: {} not found", shared.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let (scan_mm, landmarks_mm) = (shared.join("s03.ply"), shared.join("s03_landmarks.json"));
    let (scan_m, landmarks_m) = (dir.path().join("s03_m.ply"), dir.path().join("s03_m.json"));
    let mut mesh = mesh::io::read_mesh(&scan_mm).unwrap();
    mesh.map_positions(|p| p / 1000.0);
    mesh::io::write_mesh(&scan_m, &mesh).unwrap();
    std::fs::copy(&landmarks_mm, &landmarks_m).unwrap();
    edit_landmarks(&landmarks_m, |json| {
        json["units"] = "m".into();
        for point in json["landmarks"].as_object_mut().unwrap().values_mut() {
            for c in point.as_array_mut().unwrap() {
                *c = (c.as_f64().unwrap() / 1000.0).into();
            }
        }
    });
    let out = dir.path().join("model");
    assert_clean_failure(
        &model(&scan_m, &landmarks_m, &out, &[]),
        "in m it would be 414 mm: give --units m",
    );
    assert!(!out.exists());
    let volumes = |output: Output| -> [f64; 2] {
        assert!(output.status.success(), "{}", stderr(&output));
        let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        ["left", "right"].map(|side| json["breast_volume_ml"][side].as_f64().unwrap())
    };
    let in_metres = volumes(model(&scan_m, &landmarks_m, &out, &["--units", "m"]));
    let model_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("model.json")).unwrap()).unwrap();
    assert_eq!(model_json["scan_units"], "m");
    let in_mm = volumes(model(&scan_mm, &landmarks_mm, &dir.path().join("mm"), &[]));
    for (m, mm) in in_metres.iter().zip(&in_mm) {
        assert!(
            (m - mm).abs() <= 1e-3 * mm,
            "{m} ml in metres, {mm} ml in millimetres"
        );
    }
}

/// `--quality` chooses the element count by purpose and excludes `--elements`.
#[test]
fn model_quality_sets_the_element_count() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let out = dir.path().join("model");
    let output = model(&scan, &landmarks, &out, &["--quality", "draft"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["elements_requested"], 15_000);
    assert_clean_failure(
        &model(
            &scan,
            &landmarks,
            &out,
            &["--quality", "draft", "--elements", "8000"],
        ),
        "cannot be used with",
    );
    assert_clean_failure(
        &model(&scan, &landmarks, &out, &["--quality", "best"]),
        "expected draft, standard or accurate",
    );
}
