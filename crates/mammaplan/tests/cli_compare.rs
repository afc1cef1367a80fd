//! `mammaplan compare` as users and scripts see it: the JSON report, the deviation map,
//! and clean failures.

mod common;

use common::*;
use std::path::Path;
use std::process::Output;

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
