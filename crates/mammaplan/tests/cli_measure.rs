//! The command line as users and scripts see it, for `measure`, `register` and argument
//! handling: exit codes, one-line errors naming the problem, no panics, JSON on stdout.

mod common;

use common::*;

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
