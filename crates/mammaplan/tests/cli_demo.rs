//! `mammaplan demo` and `mammaplan report` as users see them: the whole pipeline end to
//! end, and clean failures that write nothing.

mod common;

use common::*;
use std::path::{Path, PathBuf};

#[test]
fn a_textured_demo_runs_from_the_phantoms_obj_and_its_views_wear_the_photograph() {
    let dir = tempfile::tempdir().unwrap();
    let output = mammaplan(&["demo", "--textured", "--out", dir.path().to_str().unwrap()]);
    assert!(output.status.success(), "{}", stderr(&output));
    for name in ["scan.obj", "scan.mtl", "scan.png"] {
        assert!(dir.path().join(name).is_file(), "{name}");
    }
    assert!(!dir.path().join("scan.ply").exists());
    for name in [
        "simulated_scan.obj",
        "simulated_scan.mtl",
        "simulated_scan_texture.png",
    ] {
        assert!(dir.path().join("simulation").join(name).is_file(), "{name}");
    }
    // the report's first picture (the pre-operative front view) shows the phantom's
    // dark blue marks (30, 60, 120 shaded), which neither skin tone, shading, the
    // landmarks' markers (0, 90, 200 and 210, 0, 140) nor the cut curves (100, 40, 150)
    // give: the untextured demo's picture has none
    let html = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    let start = html.find("data:image/png;base64,").unwrap() + "data:image/png;base64,".len();
    let end = start + html[start..].find('"').unwrap();
    use base64::Engine;
    let png = base64::engine::general_purpose::STANDARD
        .decode(&html[start..end])
        .unwrap();
    let image = image::load_from_memory(&png).unwrap().to_rgb8();
    let marked = image
        .pixels()
        .filter(|p| {
            let [r, g, b] = p.0.map(i32::from);
            b > r + 20 && r < 100 && g < 110 && b < 170 && g > r
        })
        .count();
    assert!(marked > 500, "{marked} mark pixels");
}

#[test]
fn demo_builds_the_model_and_compares_it_with_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let output = mammaplan(&["demo", "--out", dir.path().to_str().unwrap(), "--json"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    check_demo_folder(dir.path(), &json);
    check_bad_implants(dir.path());
    check_behind_nipple(dir.path());
    check_reports(dir.path());
    check_edited_results(dir.path());
    // last: it corrupts the model
    check_corrupted_level(dir.path());
}

/// Where the failing simulations of the demo's model would write (never created).
const BAD_SIMULATION: &str = "bad_simulation";

/// `simulate` on `model_dir` with the left implant `spec`, further arguments, into `out`.
fn simulate_into(model_dir: &Path, spec: &str, extra: &[&str], out: &Path) -> std::process::Output {
    let mut args = vec!["simulate", "--model", model_dir.to_str().unwrap()];
    args.extend(["--left", spec, "--out", out.to_str().unwrap()]);
    args.extend(extra);
    mammaplan(&args)
}

/// The demo's folder: exactly its entries, the phantom's volumes against the truth, the
/// implants' volume gained, symmetric.
fn check_demo_folder(dir: &Path, json: &serde_json::Value) {
    // Exactly the entries the demo replaces all or nothing (plan::demo::DEMO_ENTRIES): a
    // file written beside them would survive a failed demo.
    let mut written: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    written.sort();
    assert_eq!(
        written,
        [
            "followup_landmarks.json",
            "followup_registered.ply",
            "followup_scan.ply",
            "landmarks.json",
            "measurements.json",
            "model",
            "registration.json",
            "report.html",
            "scan.ply",
            "simulation"
        ]
    );
    for side in ["left", "right"] {
        let error = json["breast_volume_error_percent"][side].as_f64().unwrap();
        // The bound on the phantom's breast volumes.
        assert!(error.abs() < 5.0, "{side}: {error}%");
    }
    for file in MODEL_FILES {
        assert!(dir.join("model").join(file).is_file(), "{file}");
    }
    for file in [
        "simulated_scan.ply",
        "simulated_landmarks.json",
        "simulated_control_points.json",
        "fe_result.vtu",
        "result.json",
    ] {
        assert!(dir.join("simulation").join(file).is_file(), "{file}");
    }
    let simulation = &json["simulation"];
    let after = &simulation["breast_volume_ml"];
    let before = &simulation["breast_volume_before_ml"];
    for side in ["left", "right"] {
        let implant = simulation["implant_volume_ml"][side].as_f64().unwrap();
        let gain = after[side].as_f64().unwrap() - before[side].as_f64().unwrap();
        // Issue 6 asked for the implant's volume within 15%. With gravity vertical (the
        // standing frame) the phantom gains 0.85 of it: 0.90 before gravity, the
        // displacement template's own shortfall (issue 23), and the implant's weight
        // pulling the lower pole down takes 5% more (docs/dev/standing-frame.md). Within
        // 20% until issue 23 removes the template's shortfall.
        assert!(
            (gain - implant).abs() <= 0.20 * implant,
            "{side}: +{gain} ml for a {implant} ml implant"
        );
    }
    let (left, right) = (
        after["left"].as_f64().unwrap(),
        after["right"].as_f64().unwrap(),
    );
    // Symmetric phantom, same implants: within 1% (issue 6).
    assert!((left - right).abs() <= 0.01 * left, "{left} / {right}");
}

/// Bad implants on the demo's model: clear errors, no simulation folder.
fn check_bad_implants(dir: &Path) {
    let model = dir.join("model");
    let out = dir.join(BAD_SIMULATION);
    let simulate = |spec: &str| simulate_into(&model, spec, &[], &out);
    assert_clean_failure(&simulate("catalog:NO-SUCH-ID"), "NO-SUCH-ID");
    assert_clean_failure(&simulate("round:diameter=0,projection=30"), "diameter");
    assert_clean_failure(
        &simulate("round:diameter=240,projection=60"),
        "left implant",
    );
    assert_clean_failure(&simulate("oval:width=100"), "oval");
    assert_clean_failure(
        &simulate_into(&model, "catalog:R-MOD-120", &["--rotate-left", "400"], &out),
        "angle",
    );
    assert_clean_failure(
        &simulate_into(&model, "catalog:R-MOD-120", &["--anchor", "armpit"], &out),
        "unknown anchor \"armpit\"",
    );
    assert!(!out.exists());
    assert_clean_failure(
        &simulate_into(&dir.join("nowhere"), "catalog:R-MOD-120", &[], &out),
        "model.json",
    );
}

/// The other default position, recorded in result.json with the demo's.
fn check_behind_nipple(dir: &Path) {
    let model = dir.join("model");
    let behind_nipple = dir.join("behind_nipple");
    let output = mammaplan(&[
        "simulate",
        "--model",
        model.to_str().unwrap(),
        "--right",
        "catalog:R-MOD-90",
        "--anchor",
        "behind-nipple",
        "--no-gravity",
        "--out",
        behind_nipple.to_str().unwrap(),
        "--json",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    assert_eq!(json["anchor"], "behind-nipple");
    let demo_result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("simulation/result.json")).unwrap())
            .unwrap();
    assert_eq!(demo_result["anchor"], "on-fold");
}

/// The demo's report, and one with the follow-up scan as the post-operative scan.
fn check_reports(dir: &Path) {
    let model = dir.join("model");
    let demo_report = std::fs::read_to_string(dir.join("report.html")).unwrap();
    assert!(demo_report.contains("catalog:R-MOD-120"));
    assert!(!demo_report.contains("Post-op"));
    let report_path = dir.join("with_postop.html");
    let report = mammaplan(&[
        "report",
        "--model",
        model.to_str().unwrap(),
        "--simulation",
        dir.join("simulation").to_str().unwrap(),
        "--postop",
        dir.join("followup_scan.ply").to_str().unwrap(),
        "--postop-landmarks",
        dir.join("followup_landmarks.json").to_str().unwrap(),
        "--out",
        report_path.to_str().unwrap(),
    ]);
    assert!(report.status.success(), "{}", stderr(&report));
    assert!(String::from_utf8_lossy(&report.stdout).contains("with_postop.html"));
    let page = std::fs::read_to_string(&report_path).unwrap();
    assert!(page.contains("Post-op − simulated"));
    assert!(page.contains("followup_scan.ply"));
}

/// Edited result files: refused, naming the file and the field.
fn check_edited_results(dir: &Path) {
    let model = dir.join("model");
    let out = dir.join(BAD_SIMULATION);
    let edited = |folder: &str, copy: &str, file: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let copy = dir.join(copy);
        std::fs::create_dir_all(&copy).unwrap();
        for entry in std::fs::read_dir(dir.join(folder)).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), copy.join(entry.file_name())).unwrap();
        }
        edit_landmarks(&copy.join(file), edit);
        copy
    };
    let edited_simulation = edited("simulation", "edited_simulation", "result.json", &|json| {
        json["implants"]["left"]["width_mm"] = (-120.0).into();
    });
    let edited_model = edited("model", "edited_model", "model.json", &|json| {
        json["breast_volume_ml"]["right"] = 1e9.into();
    });
    for (model_dir, simulation_dir, expected) in [
        (
            &model,
            &edited_simulation,
            "result.json: implants.left.width_mm is -120 mm",
        ),
        (
            &edited_model,
            &dir.join("simulation"),
            "model.json: breast_volume_ml.right is 1000000000 ml",
        ),
    ] {
        let output = mammaplan(&[
            "report",
            "--model",
            model_dir.to_str().unwrap(),
            "--simulation",
            simulation_dir.to_str().unwrap(),
            "--out",
            dir.join("edited.html").to_str().unwrap(),
        ]);
        assert_clean_failure(&output, expected);
        assert!(!dir.join("edited.html").exists());
    }
    assert_clean_failure(
        &simulate_into(&edited_model, "catalog:R-MOD-120", &[], &out),
        "model.json: breast_volume_ml.right is 1000000000 ml",
    );
    assert!(!out.exists());

    // A folder from another version whose model came out differently, and landmarks
    // moved by half a millimetre since the model was built.
    let older = edited("model", "older_model", "model.json", &|json| {
        json["software"] = "mammaplan 0.0.9 (commit 0123456789ab)".into();
        let elements = json["levels"][0]["elements"].as_u64().unwrap();
        json["levels"][0]["elements"] = (elements + 1).into();
    });
    let moved_landmarks = dir.join("moved_landmarks.json");
    let moved = edited("model", "moved_model", "model.json", &|json| {
        let recorded = PathBuf::from(json["landmarks"].as_str().unwrap());
        std::fs::copy(recorded, &moved_landmarks).unwrap();
        edit_landmarks(&moved_landmarks, |landmarks| {
            let x = landmarks["landmarks"]["Pj"][0].as_f64().unwrap();
            landmarks["landmarks"]["Pj"][0] = (x + 0.5).into();
        });
        json["landmarks"] = moved_landmarks.to_str().unwrap().into();
    });
    for (model_dir, expected) in [
        (
            &older,
            "the folder was written by mammaplan 0.0.9 (commit 0123456789ab), and this \
             mammaplan",
        ),
        (
            &moved,
            "moved_landmarks.json is not the landmark file the model in",
        ),
    ] {
        assert_clean_failure(
            &simulate_into(model_dir, "catalog:R-MOD-120", &[], &out),
            expected,
        );
        assert!(!out.exists());
    }
}

/// One bit of a tetrahedral level changed: refused before any work, naming the file.
fn check_corrupted_level(dir: &Path) {
    let model = dir.join("model");
    let out = dir.join(BAD_SIMULATION);
    let level = model.join("tets_level1.vtu");
    let mut bytes = std::fs::read(&level).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(&level, bytes).unwrap();
    assert_clean_failure(
        &simulate_into(&model, "catalog:R-MOD-120", &[], &out),
        "tets_level1.vtu does not match the checksum model.json recorded",
    );
    assert!(!out.exists());
}

#[test]
fn bad_report_input_fails_cleanly_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("report.html");
    let path = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let report = |extra: &[&str]| {
        let mut args = vec!["report", "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        mammaplan(&args)
    };
    let (model, simulation) = (path("model"), path("simulation"));
    assert_clean_failure(
        &report(&["--model", &model, "--simulation", &simulation]),
        "model.json",
    );
    std::fs::create_dir_all(dir.path().join("model")).unwrap();
    std::fs::write(dir.path().join("model/model.json"), "not json").unwrap();
    assert_clean_failure(
        &report(&["--model", &model, "--simulation", &simulation]),
        "not a model report",
    );
    assert_clean_failure(
        &report(&[
            "--model",
            &model,
            "--simulation",
            &simulation,
            "--postop",
            &path("postop.ply"),
        ]),
        "--postop-landmarks",
    );
    assert_clean_failure(
        &report(&[
            "--model",
            &model,
            "--simulation",
            &simulation,
            "--postop-landmarks",
            &path("postop.json"),
        ]),
        "--postop",
    );
    assert_clean_failure(&report(&["--model", &model]), "--simulation");
    assert!(!out.exists());
}
