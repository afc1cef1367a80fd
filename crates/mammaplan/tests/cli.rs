//! The command line as users and scripts see it: exit codes, one-line errors naming the
//! problem, no panics, JSON on stdout.

mod common;

use common::*;
use std::path::Path;
use std::process::Output;

#[test]
fn measure_prints_json_with_eleven_distances() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let output = mammaplan(&[
        "measure",
        "--scan",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
        "--pair",
        "Pj,Px",
        "--json",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("stdout is JSON");
    let distances = json["distances"].as_array().unwrap();
    assert_eq!(distances.len(), 12);
    for d in distances {
        for key in [
            "name",
            "from",
            "to",
            "euclidean_mm",
            "surface_mm",
            "geodesic_mm",
        ] {
            assert!(d.get(key).is_some(), "{key} missing in {d}");
        }
    }
}

#[test]
fn truncated_ply_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let bytes = std::fs::read(&scan).unwrap();
    std::fs::write(&scan, &bytes[..bytes.len() / 2]).unwrap();
    let output = measure(&scan, &landmarks);
    assert_clean_failure(&output, "scan.ply");
    assert!(stderr(&output).contains("truncated"), "{}", stderr(&output));
}

#[test]
fn obj_face_index_out_of_range_names_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let (_, landmarks) = phantom(dir.path());
    let obj = dir.path().join("bad.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 9\n").unwrap();
    let output = measure(&obj, &landmarks);
    assert_clean_failure(&output, "line 5");
}

#[test]
fn landmark_file_without_pj_names_it() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    edit_landmarks(&landmarks, |json| {
        json["landmarks"].as_object_mut().unwrap().remove("Pj");
    });
    let output = measure(&scan, &landmarks);
    assert_clean_failure(&output, "missing required landmark Pj");
}

#[test]
fn landmark_20_mm_off_the_surface_is_rejected() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    // The nipple points anteriorly (+z in the phantom's frame): 20 mm in front of it.
    edit_landmarks(&landmarks, |json| {
        let z = json["landmarks"]["Pnl"][2].as_f64().unwrap();
        json["landmarks"]["Pnl"][2] = serde_json::json!(z + 20.0);
    });
    let output = measure(&scan, &landmarks);
    // The nearest surface point is a little less than 20 mm away (the nipple's normal is
    // not exactly +z).
    assert_clean_failure(&output, "landmark Pnl is 19.");
    assert!(stderr(&output).contains("mm from the scan surface (at most 5 mm allowed)"));
}

#[test]
fn bad_arguments_and_missing_files_fail_cleanly() {
    assert_clean_failure(&mammaplan(&["measure", "--bogus"]), "--bogus");
    assert_clean_failure(
        &mammaplan(&[
            "measure",
            "--scan",
            "/nonexistent/scan.ply",
            "--landmarks",
            "x.json",
        ]),
        "/nonexistent/scan.ply",
    );
    assert_clean_failure(
        &mammaplan(&[
            "phantom",
            "--out",
            "a.ply",
            "--landmarks",
            "a.json",
            "--cup",
            "huge",
        ]),
        "huge",
    );
    assert_clean_failure(
        &mammaplan(&["phantom", "--out", "a.xyz", "--landmarks", "a.json"]),
        "unsupported mesh format",
    );
}

#[test]
fn register_writes_the_registered_scan_and_reports_json() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let out = dir.path().join("registered.ply");
    let output = mammaplan(&[
        "register",
        "--fixed",
        scan.to_str().unwrap(),
        "--fixed-landmarks",
        landmarks.to_str().unwrap(),
        "--moving",
        scan.to_str().unwrap(),
        "--moving-landmarks",
        landmarks.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--icp",
        "--json",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    // A scan registered onto itself: identity to round-off.
    assert!(json["landmark_rms_mm"].as_f64().unwrap() < 1e-6);
    assert!(json["surface_rms_mm"].as_f64().unwrap() < 1e-6);
    assert!((json["matrix"][0][0].as_f64().unwrap() - 1.0).abs() < 1e-9);
    assert!(out.is_file());
    assert_no_temporary_files(dir.path());
}

/// `mammaplan compare` of a test scan with a reference scan (scan, landmarks), with
/// extra arguments.
fn compare(reference: (&Path, &Path), test: (&Path, &Path), extra: &[&str]) -> Output {
    let mut args = vec![
        "compare",
        "--reference",
        reference.0.to_str().unwrap(),
        "--reference-landmarks",
        reference.1.to_str().unwrap(),
        "--test",
        test.0.to_str().unwrap(),
        "--test-landmarks",
        test.1.to_str().unwrap(),
    ];
    args.extend(extra);
    mammaplan(&args)
}

#[test]
fn compare_reports_json_and_writes_the_deviation_map() {
    let dir = tempfile::tempdir().unwrap();
    let (small, small_landmarks) = phantom(dir.path());
    let (medium, medium_landmarks) = (
        dir.path().join("medium.ply"),
        dir.path().join("medium.json"),
    );
    let output = mammaplan(&[
        "phantom",
        "--out",
        medium.to_str().unwrap(),
        "--landmarks",
        medium_landmarks.to_str().unwrap(),
        "--cup",
        "medium",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let out = dir.path().join("deviation.ply");
    let output = compare(
        (&small, &small_landmarks),
        (&medium, &medium_landmarks),
        &["--register", "--out", out.to_str().unwrap(), "--json"],
    );
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("stdout is JSON");
    let number = |value: &serde_json::Value| value.as_f64().unwrap_or_else(|| panic!("{value}"));
    for key in [
        "rms_mm",
        "mean_mm",
        "signed_mean_mm",
        "hausdorff_mm",
        "overlap_fraction",
        "reference_overlap_fraction",
        "max_distance_mm",
    ] {
        number(&json[key]);
    }
    let distances = json["distances"].as_array().unwrap();
    assert_eq!(distances.len(), 11);
    for d in distances {
        for key in ["name", "from", "to"] {
            assert!(d[key].is_string(), "{key} in {d}");
        }
        for key in ["reference_mm", "test_mm", "difference_mm"] {
            number(&d[key]);
        }
    }
    for scan in ["reference", "test"] {
        for side in ["left", "right"] {
            number(&json["breast_volume_ml"][scan][side]);
            number(&json["quadrant_volume_ml"][scan][side]["upper_outer"]);
        }
        let symmetry = &json["symmetry"][scan];
        for key in [
            "volume_ratio_left_to_right",
            "nipple_height_difference_mm",
            "nipple_distance_mm",
            "mirror_correction_deg",
        ] {
            number(&symmetry[key]);
        }
        number(&symmetry["asymmetry"]["both_breasts"]["rms_mm"]);
    }
    for region in ["left", "right", "both"] {
        for key in [
            "rms_mm",
            "mean_mm",
            "signed_mean_mm",
            "hausdorff_mm",
            "vertices",
        ] {
            number(&json["breast_regions"][region][key]);
        }
    }
    assert_eq!(json["registration"]["matrix"].as_array().unwrap().len(), 4);
    number(&json["registration"]["surface_rms_mm"]);
    // A larger cup: larger breasts, lying in front of the smaller ones.
    let volumes = &json["breast_volume_ml"];
    assert!(number(&volumes["test"]["left"]) > number(&volumes["reference"]["left"]) + 50.0);
    let both = &json["breast_regions"]["both"];
    assert!(number(&both["signed_mean_mm"]) > 1.0);
    assert!(number(&both["rms_mm"]) > number(&json["rms_mm"]));
    assert_eq!(json["out"].as_str(), out.to_str());
    assert!(out.is_file());
    assert_no_temporary_files(dir.path());

    // Without --json: the summary.
    let output = compare((&small, &small_landmarks), (&small, &small_landmarks), &[]);
    assert!(output.status.success(), "{}", stderr(&output));
    let summary = String::from_utf8_lossy(&output.stdout);
    for expected in ["both breasts", "Pj-Pnl", "volume ratio left/right"] {
        assert!(summary.contains(expected), "{expected} in {summary}");
    }
}

#[test]
fn bad_compare_input_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());

    let without_nipple = dir.path().join("without_nipple.json");
    std::fs::copy(&landmarks, &without_nipple).unwrap();
    edit_landmarks(&without_nipple, |json| {
        json["landmarks"].as_object_mut().unwrap().remove("Pnl");
    });
    let output = compare((&scan, &landmarks), (&scan, &without_nipple), &[]);
    assert_clean_failure(&output, "missing required landmark Pnl");

    let nan = dir.path().join("nan.ply");
    std::fs::write(
        &nan,
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n\
         0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n",
    )
    .unwrap();
    let output = compare((&scan, &landmarks), (&nan, &landmarks), &[]);
    assert_clean_failure(&output, "non-finite coordinate");

    // The same scan 1 m in front: no vertex lies over the other scan.
    let obj = dir.path().join("scan.obj");
    let output = mammaplan(&[
        "phantom",
        "--out",
        obj.to_str().unwrap(),
        "--landmarks",
        dir.path().join("obj.json").to_str().unwrap(),
        "--cup",
        "small",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let moved: String = std::fs::read_to_string(&obj)
        .unwrap()
        .lines()
        .map(
            |line| match line.split_whitespace().collect::<Vec<_>>()[..] {
                ["v", x, y, z, ..] => format!("v {x} {y} {}\n", z.parse::<f64>().unwrap() + 1000.0),
                _ => format!("{line}\n"),
            },
        )
        .collect();
    std::fs::write(&obj, moved).unwrap();
    let moved_landmarks = dir.path().join("moved.json");
    std::fs::copy(&landmarks, &moved_landmarks).unwrap();
    edit_landmarks(&moved_landmarks, |json| {
        for point in json["landmarks"].as_object_mut().unwrap().values_mut() {
            point[2] = (point[2].as_f64().unwrap() + 1000.0).into();
        }
    });
    let output = compare((&scan, &landmarks), (&obj, &moved_landmarks), &[]);
    assert_clean_failure(&output, "do not overlap");

    let output = compare(
        (&scan, &landmarks),
        (&scan, &landmarks),
        &["--out", dir.path().join("deviation.obj").to_str().unwrap()],
    );
    assert_clean_failure(&output, "give a .ply file");
    let output = compare(
        (&scan, &landmarks),
        (&scan, &landmarks),
        &["--max-distance-mm", "0"],
    );
    assert_clean_failure(&output, "expected a number > 0");

    let missing = dir.path().join("missing_control_points.json");
    let output = compare(
        (&scan, &landmarks),
        (&scan, &landmarks),
        &["--test-control-points", missing.to_str().unwrap()],
    );
    assert_clean_failure(&output, "missing_control_points.json");
    let two_points = dir.path().join("two_points.json");
    std::fs::write(
        &two_points,
        r#"{"units":"mm","left":[[0,0,0],[1,0,0]],"right":[[0,0,0],[1,0,0],[0,1,0]]}"#,
    )
    .unwrap();
    let output = compare(
        (&scan, &landmarks),
        (&scan, &landmarks),
        &["--reference-control-points", two_points.to_str().unwrap()],
    );
    assert_clean_failure(&output, "two_points.json");
}

/// The files `model` writes into its folder.
const MODEL_FILES: [&str; 13] = [
    "closed_surface.ply",
    "breast_left.ply",
    "breast_right.ply",
    "fill_left.ply",
    "fill_right.ply",
    "filled_base.ply",
    "tets_level0.vtu",
    "tets_level1.vtu",
    "tets_level2.vtu",
    "cut_curve_left.obj",
    "cut_curve_right.obj",
    "control_points.json",
    "model.json",
];

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
    // Exactly the entries the demo replaces all or nothing (plan::demo::DEMO_ENTRIES): a
    // file written beside them would survive a failed demo.
    let mut written: Vec<String> = std::fs::read_dir(dir.path())
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
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    for side in ["left", "right"] {
        let error = json["breast_volume_error_percent"][side].as_f64().unwrap();
        // The issue's bound on the phantom's breast volumes.
        assert!(error.abs() < 5.0, "{side}: {error}%");
    }
    for file in MODEL_FILES {
        assert!(dir.path().join("model").join(file).is_file(), "{file}");
    }
    for file in [
        "simulated_scan.ply",
        "simulated_landmarks.json",
        "simulated_control_points.json",
        "fe_result.vtu",
        "result.json",
    ] {
        assert!(dir.path().join("simulation").join(file).is_file(), "{file}");
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

    // Bad implants on the demo's model: clear errors, no simulation folder.
    let model = dir.path().join("model");
    let out = dir.path().join("bad_simulation");
    // `simulate` on `model_dir` with the left implant `spec` and further arguments.
    let simulate_with = |model_dir: &Path, spec: &str, extra: &[&str]| {
        let mut args = vec!["simulate", "--model", model_dir.to_str().unwrap()];
        args.extend(["--left", spec, "--out", out.to_str().unwrap()]);
        args.extend(extra);
        mammaplan(&args)
    };
    let simulate = |spec: &str| simulate_with(&model, spec, &[]);
    assert_clean_failure(&simulate("catalog:NO-SUCH-ID"), "NO-SUCH-ID");
    assert_clean_failure(&simulate("round:diameter=0,projection=30"), "diameter");
    assert_clean_failure(
        &simulate("round:diameter=240,projection=60"),
        "left implant",
    );
    assert_clean_failure(&simulate("oval:width=100"), "oval");
    assert_clean_failure(
        &simulate_with(&model, "catalog:R-MOD-120", &["--rotate-left", "400"]),
        "angle",
    );
    assert_clean_failure(
        &simulate_with(&model, "catalog:R-MOD-120", &["--anchor", "armpit"]),
        "unknown anchor \"armpit\"",
    );
    assert!(!out.exists());
    assert_clean_failure(
        &simulate_with(&dir.path().join("nowhere"), "catalog:R-MOD-120", &[]),
        "model.json",
    );
    // The other default position, recorded in result.json with the demo's.
    let behind_nipple = dir.path().join("behind_nipple");
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
    let demo_result: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("simulation/result.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(demo_result["anchor"], "on-fold");

    // The demo's report, and one with the follow-up scan as the post-operative scan.
    let demo_report = std::fs::read_to_string(dir.path().join("report.html")).unwrap();
    assert!(demo_report.contains("catalog:R-MOD-120"));
    assert!(!demo_report.contains("Post-op"));
    let report_path = dir.path().join("with_postop.html");
    let report = mammaplan(&[
        "report",
        "--model",
        model.to_str().unwrap(),
        "--simulation",
        dir.path().join("simulation").to_str().unwrap(),
        "--postop",
        dir.path().join("followup_scan.ply").to_str().unwrap(),
        "--postop-landmarks",
        dir.path().join("followup_landmarks.json").to_str().unwrap(),
        "--out",
        report_path.to_str().unwrap(),
    ]);
    assert!(report.status.success(), "{}", stderr(&report));
    assert!(String::from_utf8_lossy(&report.stdout).contains("with_postop.html"));
    let page = std::fs::read_to_string(&report_path).unwrap();
    assert!(page.contains("Post-op − simulated"));
    assert!(page.contains("followup_scan.ply"));

    // Edited result files: refused, naming the file and the field.
    let edited = |folder: &str, file: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let copy = dir.path().join(format!("edited_{folder}"));
        std::fs::create_dir_all(&copy).unwrap();
        for entry in std::fs::read_dir(dir.path().join(folder)).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), copy.join(entry.file_name())).unwrap();
        }
        edit_landmarks(&copy.join(file), edit);
        copy
    };
    let edited_simulation = edited("simulation", "result.json", &|json| {
        json["implants"]["left"]["width_mm"] = (-120.0).into();
    });
    let edited_model = edited("model", "model.json", &|json| {
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
            &dir.path().join("simulation"),
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
            dir.path().join("edited.html").to_str().unwrap(),
        ]);
        assert_clean_failure(&output, expected);
        assert!(!dir.path().join("edited.html").exists());
    }
    assert_clean_failure(
        &simulate_with(&edited_model, "catalog:R-MOD-120", &[]),
        "model.json: breast_volume_ml.right is 1000000000 ml",
    );
    assert!(!out.exists());

    // One bit of a tetrahedral level changed: refused before any work, naming the file.
    let level = model.join("tets_level1.vtu");
    let mut bytes = std::fs::read(&level).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(&level, bytes).unwrap();
    assert_clean_failure(
        &simulate("catalog:R-MOD-120"),
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

#[test]
fn catalog_lists_and_suggests() {
    let list = mammaplan(&["catalog", "list", "--json"]);
    assert!(list.status.success(), "{}", stderr(&list));
    let listing: serde_json::Value = serde_json::from_slice(&list.stdout).unwrap();
    let entries = listing["entries"].as_array().unwrap();
    assert!(entries.len() >= 50, "{} entries", entries.len());
    for entry in entries {
        let volume = entry["volume_ml"].as_f64().unwrap();
        assert!((100.0..=800.0).contains(&volume), "{entry}");
    }

    // A round 120 x 33.5 mm implant is in the moderate family: it is its own best match.
    let suggest = mammaplan(&[
        "catalog",
        "suggest",
        "--width",
        "120",
        "--projection",
        "33.5",
        "--shape",
        "round",
        "--json",
    ]);
    assert!(suggest.status.success(), "{}", stderr(&suggest));
    let report: serde_json::Value = serde_json::from_slice(&suggest.stdout).unwrap();
    let best = &report["suggestions"][0];
    assert_eq!(best["id"], "R-MOD-120", "{report}");
    assert_eq!(best["distance_mm"].as_f64(), Some(0.0));

    // By volume: signed differences (entry minus target), closest first.
    let by_volume = mammaplan(&["catalog", "suggest", "--volume-ml", "300", "--json"]);
    assert!(by_volume.status.success(), "{}", stderr(&by_volume));
    let report: serde_json::Value = serde_json::from_slice(&by_volume.stdout).unwrap();
    let differences: Vec<f64> = report["suggestions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["volume_difference_ml"].as_f64().unwrap().abs())
        .collect();
    assert_eq!(differences.len(), 5);
    assert!(
        differences.windows(2).all(|w| w[0] <= w[1]),
        "{differences:?}"
    );
}

#[test]
fn bad_catalog_input_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("catalog.csv");
    std::fs::write(
        &csv,
        "id,shape,family,width_mm,height_mm,projection_mm\nX1,round,test,120,,abc\n",
    )
    .unwrap();
    let csv = csv.to_str().unwrap();
    assert_clean_failure(&mammaplan(&["catalog", "list", "--catalog", csv]), "line 2");
    assert_clean_failure(
        &mammaplan(&[
            "catalog",
            "suggest",
            "--width",
            "1000",
            "--projection",
            "30",
        ]),
        "width_mm must be from 50 to 250",
    );
    assert_clean_failure(
        &mammaplan(&["catalog", "suggest", "--width", "120"]),
        "--projection",
    );
}

/// An `nx x ny x nz` grid of unit-`h` cubes, six tetrahedra each, as an ASCII `.vtu` with
/// the given point data arrays (`(name, components, values)`).
fn box_vtu(n: [usize; 3], h: f64, point_data: &[(&str, usize, Vec<f64>)]) -> String {
    let index = |i: usize, j: usize, k: usize| (k * (n[1] + 1) + j) * (n[0] + 1) + i;
    let mut points = Vec::new();
    for k in 0..=n[2] {
        for j in 0..=n[1] {
            for i in 0..=n[0] {
                points.push([i as f64 * h, j as f64 * h, k as f64 * h]);
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..n[2] {
        for j in 0..n[1] {
            for i in 0..n[0] {
                let c = |b: usize| index(i + (b & 1), j + ((b >> 1) & 1), k + ((b >> 2) & 1));
                for t in [
                    [0, 1, 3, 7],
                    [0, 3, 2, 7],
                    [0, 2, 6, 7],
                    [0, 6, 4, 7],
                    [0, 4, 5, 7],
                    [0, 5, 1, 7],
                ] {
                    let mut v = t.map(c);
                    let p = v.map(|q| points[q]);
                    let d = |a: usize| [0, 1, 2].map(|x| p[a][x] - p[0][x]);
                    let (a, b, cc) = (d(1), d(2), d(3));
                    let volume = a[0] * (b[1] * cc[2] - b[2] * cc[1])
                        - a[1] * (b[0] * cc[2] - b[2] * cc[0])
                        + a[2] * (b[0] * cc[1] - b[1] * cc[0]);
                    if volume < 0.0 {
                        v.swap(2, 3);
                    }
                    tets.push(v);
                }
            }
        }
    }
    let join = |values: Vec<String>| values.join(" ");
    let mut xml = format!(
        "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"LittleEndian\">\n\
         <UnstructuredGrid><Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\n<PointData>\n",
        points.len(),
        tets.len()
    );
    for (name, components, values) in point_data {
        xml += &format!(
            "<DataArray type=\"Float64\" Name=\"{name}\" NumberOfComponents=\"{components}\" format=\"ascii\">{}</DataArray>\n",
            join(values.iter().map(|v| v.to_string()).collect())
        );
    }
    xml += &format!(
        "</PointData>\n<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">{}</DataArray></Points>\n",
        join(points.iter().flatten().map(|v| v.to_string()).collect())
    );
    xml += &format!(
        "<Cells><DataArray type=\"Int64\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"Int64\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\n\
         <DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n\
         </Piece></UnstructuredGrid></VTKFile>\n",
        join(tets.iter().flatten().map(|v| v.to_string()).collect()),
        join((1..=tets.len()).map(|t| (4 * t).to_string()).collect()),
        join(vec!["10".to_string(); tets.len()])
    );
    xml
}

/// A bar stretched by its end faces with Poisson ratio 0: the exact solution is the
/// linear field `u_z = δ z / L`, which linear tetrahedra reproduce exactly (patch test),
/// in both formulations (a pure stretch has no rotation).
#[test]
fn fem_solve_reproduces_a_stretched_bar() {
    let n = [2, 2, 6];
    let (h, stretch_mm) = (5.0, 3.0);
    let length = n[2] as f64 * h;
    let count = (n[0] + 1) * (n[1] + 1) * (n[2] + 1);
    let layer = (n[0] + 1) * (n[1] + 1);
    let mut constrained = vec![0.0; count];
    let mut displacement = vec![0.0; 3 * count];
    for v in 0..count {
        let k = v / layer;
        if k == 0 || k == n[2] {
            constrained[v] = 1.0;
            displacement[3 * v + 2] = if k == 0 { 0.0 } else { stretch_mm };
        }
    }
    let dir = tempfile::tempdir().unwrap();
    let input = dir.path().join("bar.vtu");
    std::fs::write(
        &input,
        box_vtu(
            n,
            h,
            &[
                ("constrained", 1, constrained),
                ("displacement", 3, displacement),
            ],
        ),
    )
    .unwrap();
    for linear in [true, false] {
        let out = dir.path().join(format!("solved_{linear}.vtu"));
        let mut args = vec![
            "fem",
            "solve",
            "--mesh",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--poisson",
            "0",
            "--young-kpa",
            "3",
            "--json",
        ];
        if linear {
            args.push("--linear");
        }
        let output = mammaplan(&args);
        assert!(output.status.success(), "{}", stderr(&output));
        let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
        assert_eq!(report["young_modulus_from"], "command_line");
        // σ_zz = E δ / L everywhere; von Mises equals it for uniaxial stress.
        let stress = 3.0 * stretch_mm / length;
        let max_von_mises = report["max_von_mises_kpa"].as_f64().unwrap();
        assert!((max_von_mises - stress).abs() < 1e-9 * stress, "{report}");
        // the written file's arrays are compressed binary: read through the reader that
        // tetra's tests hold against hand-encoded files of every encoding
        let solved = tetra::vtu::read_vtu(&out).unwrap();
        let field = solved.point_data.iter().find(|f| f.name == "displacement");
        let Some(tetra::vtu::FieldValues::Vectors(displacement)) = field.map(|f| &f.values) else {
            panic!("no displacement vectors in {}", out.display());
        };
        let values: Vec<f64> = displacement.iter().flat_map(|d| d.to_array()).collect();
        for v in 0..count {
            let z = (v / layer) as f64 * h;
            let expected = [0.0, 0.0, stretch_mm * z / length];
            for c in 0..3 {
                // Round-off of a direct solve on a few hundred unknowns.
                assert!(
                    (values[3 * v + c] - expected[c]).abs() < 1e-9,
                    "vertex {v}: {:?}",
                    &values[3 * v..3 * v + 3]
                );
            }
        }
    }
}

#[test]
fn bad_fem_input_fails_cleanly_and_writes_nothing() {
    let n = [1, 1, 2];
    let count = 2 * 2 * 3;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.vtu");
    let solve = |name: &str, xml: String| {
        let input = dir.path().join(name);
        std::fs::write(&input, xml).unwrap();
        mammaplan(&[
            "fem",
            "solve",
            "--mesh",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
    };
    let fixed_bottom: Vec<f64> = (0..count).map(|v| f64::from(u8::from(v < 4))).collect();
    assert_clean_failure(
        &solve("no_constrained.vtu", box_vtu(n, 5.0, &[])),
        "constrained",
    );
    assert_clean_failure(
        &solve(
            "unconstrained.vtu",
            box_vtu(n, 5.0, &[("constrained", 1, vec![0.0; count])]),
        ),
        "no vertex is constrained",
    );
    let inverted = box_vtu(n, 5.0, &[("constrained", 1, fixed_bottom)]).replacen(
        "format=\"ascii\">0 1 3 7",
        "format=\"ascii\">0 1 7 3",
        1,
    );
    assert!(inverted.contains("0 1 7 3"));
    assert_clean_failure(&solve("inverted.vtu", inverted), "not positive");
    assert!(!out.exists());
}

/// `bench` on a small model: every field of the contract, and the exported system is a
/// square Matrix Market matrix matching its right-hand side, symmetric as the
/// eliminated stiffness must be.
#[test]
fn bench_reports_its_rows_and_exports_the_system() {
    let dir = tempfile::tempdir().unwrap();
    let output = mammaplan(&[
        "bench",
        "--elements",
        "15000",
        "--export-system",
        dir.path().to_str().unwrap(),
        "--json",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let row = &report["rows"][0];
    for field in [
        "elements",
        "levels",
        "implant_setup_ms",
        "solve_ms",
        "vcycle_ms",
        "update_hz",
        "residual_reduction_per_cycle",
        "direct_solve_ms",
        "scan_update_ms",
        "scan_update_two_steps_ms",
        "scan_carry_compose_ms",
    ] {
        assert!(row[field].as_f64().unwrap() > 0.0, "{field}: {row}");
    }
    let converged = &row["converged"];
    assert!(
        converged["default_stop_ms"].as_f64().unwrap() > 0.0,
        "{converged}"
    );
    for distance in ["default_stop_skin", "start_dependence"] {
        assert!(
            converged[distance]["max_mm"].as_f64().unwrap() >= 0.0,
            "{converged}"
        );
    }
    let a = std::fs::read_to_string(dir.path().join("A.mtx")).unwrap();
    let b = std::fs::read_to_string(dir.path().join("b.mtx")).unwrap();
    let size_line = |text: &str| -> Vec<usize> {
        text.lines()
            .find(|l| !l.starts_with('%'))
            .unwrap()
            .split_whitespace()
            .map(|x| x.parse().unwrap())
            .collect()
    };
    let (a_size, b_size) = (size_line(&a), size_line(&b));
    assert_eq!(a_size[0], a_size[1]);
    assert_eq!(b_size, vec![a_size[0], 1]);
    let mut entries = std::collections::HashMap::new();
    for line in a.lines().filter(|l| !l.starts_with('%')).skip(1) {
        let mut parts = line.split_whitespace();
        let i: usize = parts.next().unwrap().parse().unwrap();
        let j: usize = parts.next().unwrap().parse().unwrap();
        let v: f64 = parts.next().unwrap().parse().unwrap();
        entries.insert((i, j), v);
    }
    assert_eq!(entries.len(), a_size[2]);
    let scale = entries.values().fold(0.0f64, |m, v| m.max(v.abs()));
    for (&(i, j), &v) in &entries {
        // The assembly mirrors its blocks; printing is exact (shortest round trip).
        let w = entries.get(&(j, i)).copied().unwrap_or(0.0);
        assert!(
            (v - w).abs() <= 1e-12 * scale,
            "A[{i},{j}] = {v}, A[{j},{i}] = {w}"
        );
    }
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
