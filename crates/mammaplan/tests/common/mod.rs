//! What the command-line tests share: running the binary, checking a clean failure,
//! a phantom to work on.

// Each test binary uses a part of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn mammaplan(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_mammaplan"))
        .args(args)
        .arg("--quiet")
        .output()
        .expect("the binary runs")
}

pub fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Fails unless the command failed cleanly with a message containing `expected`.
pub fn assert_clean_failure(output: &Output, expected: &str) {
    let message = stderr(output);
    assert!(
        !output.status.success(),
        "expected failure, stderr: {message}"
    );
    assert!(!message.contains("panicked"), "panic: {message}");
    assert!(
        !message.contains("RUST_BACKTRACE"),
        "backtrace hint: {message}"
    );
    assert!(
        message.contains(expected),
        "expected {expected:?} in: {message}"
    );
}

/// Fails if an atomic write left a temporary file in `dir`.
pub fn assert_no_temporary_files(dir: &Path) {
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".partial"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

/// `mammaplan measure` on a scan and landmark file.
pub fn measure(scan: &Path, landmarks: &Path) -> Output {
    mammaplan(&[
        "measure",
        "--scan",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
    ])
}

/// A small-cup phantom `scan.ply` and its landmark file `lm.json` in `dir`.
pub fn phantom(dir: &Path) -> (PathBuf, PathBuf) {
    phantom_as(dir, "scan.ply")
}

/// A small-cup phantom scan `scan_name` (its format from the extension) and its
/// landmark file `lm.json` in `dir`.
pub fn phantom_as(dir: &Path, scan_name: &str) -> (PathBuf, PathBuf) {
    let (scan, landmarks) = (dir.join(scan_name), dir.join("lm.json"));
    let output = mammaplan(&[
        "phantom",
        "--out",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
        "--cup",
        "small",
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    (scan, landmarks)
}

pub fn edit_landmarks(path: &Path, edit: impl FnOnce(&mut serde_json::Value)) {
    let mut json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
    edit(&mut json);
    std::fs::write(path, json.to_string()).unwrap();
}

/// `mammaplan model --json` with extra arguments.
pub fn model(scan: &Path, landmarks: &Path, out: &Path, extra: &[&str]) -> Output {
    let mut args = vec![
        "model",
        "--scan",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    args.extend(extra);
    mammaplan(&args)
}

/// The files `model` writes into its folder.
pub const MODEL_FILES: [&str; 15] = [
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
    "muscle_left.ply",
    "muscle_right.ply",
    "control_points.json",
    "model.json",
];
