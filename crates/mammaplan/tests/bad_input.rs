//! Bad input, a hostile environment and failures half way (issue 26): a clear error
//! that names the problem and what to do, a non-zero exit, no panic, and no output
//! left behind.

#![allow(unsafe_code)] // setrlimit through libc, to make a write fail half way
mod common;

use common::*;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

/// Standard output that cannot be written (a full disk, here `/dev/full`) is a clean
/// error that says so, not a panic.
#[cfg(target_os = "linux")]
#[test]
fn a_full_disk_on_standard_output_is_a_clean_error() {
    let full = std::fs::File::create("/dev/full").expect("/dev/full exists on Linux");
    let output = Command::new(env!("CARGO_BIN_EXE_mammaplan"))
        .args(["catalog", "list"])
        .stdout(full)
        .output()
        .expect("the binary runs");
    assert_clean_failure(&output, "cannot write to standard output");
}

/// A negative number given to an option is read as its value and refused by the
/// option's own check, which names the option, rather than read as an unknown flag.
#[test]
fn a_negative_number_is_refused_by_its_option() {
    let output = mammaplan(&[
        "model",
        "--scan",
        "scan.ply",
        "--landmarks",
        "landmarks.json",
        "--out",
        "model",
        "--elements",
        "-5",
    ]);
    assert_clean_failure(&output, "invalid value '-5' for '--elements <N>'");
}

/// `phantom` refuses to write its scan and its landmarks to one file (the landmarks
/// would overwrite the scan), however the two paths are spelled, and writes nothing.
#[test]
fn phantom_refuses_one_file_for_scan_and_landmarks() {
    let dir = tempfile::tempdir().unwrap();
    let scan = dir.path().join("x.ply");
    let same = dir.path().join(".").join("x.ply");
    let output = mammaplan(&[
        "phantom",
        "--out",
        scan.to_str().unwrap(),
        "--landmarks",
        same.to_str().unwrap(),
    ]);
    assert_clean_failure(&output, "give them different names");
    assert!(!scan.exists());
}

/// Standard output whose reader has gone (`| head`) ends the command quietly, as Unix
/// tools do: a failure status, nothing on standard error, no panic.
#[test]
fn a_closed_pipe_on_standard_output_ends_quietly() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = (dir.path().join("p.ply"), dir.path().join("p.json"));
    let phantom = mammaplan(&[
        "phantom",
        "--out",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
    ]);
    assert!(phantom.status.success(), "{}", stderr(&phantom));
    let mut child = Command::new(env!("CARGO_BIN_EXE_mammaplan"))
        .args(["measure", "--json", "--scan", scan.to_str().unwrap()])
        .args(["--landmarks", landmarks.to_str().unwrap(), "--quiet"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("the binary runs");
    // the reader leaves before the measurement (a few hundred ms) is printed
    drop(child.stdout.take());
    let output = child.wait_with_output().unwrap();
    assert!(!output.status.success());
    assert_eq!(stderr(&output), "");
}

/// The distances of `mammaplan measure --json` and its warnings (not `--quiet`).
fn measured_distances(scan: &Path, landmarks: &Path) -> (serde_json::Value, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_mammaplan"))
        .args(["measure", "--json", "--scan", scan.to_str().unwrap()])
        .args(["--landmarks", landmarks.to_str().unwrap()])
        .output()
        .expect("the binary runs");
    assert!(output.status.success(), "{}", stderr(&output));
    let json: serde_json::Value = serde_json::from_slice(&output.stdout).expect("stdout is JSON");
    (json["distances"].clone(), stderr(&output))
}

/// A scan written with every face twice, or with a fin (a strip of two triangles
/// standing on an interior edge), is repaired on load with a warning that counts what
/// was dropped, and measures exactly as the clean scan: the repair removes what was
/// added and nothing else.
#[test]
fn a_doubled_or_finned_scan_is_repaired_and_measures_as_the_clean_one() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom_as(dir.path(), "clean.obj");
    let clean_text = std::fs::read_to_string(&scan).unwrap();
    let (clean, warnings) = measured_distances(&scan, &landmarks);
    assert!(!warnings.contains("dropped"), "{warnings}");

    let faces: Vec<&str> = clean_text.lines().filter(|l| l.starts_with("f ")).collect();
    let doubled = dir.path().join("doubled.obj");
    std::fs::write(&doubled, format!("{clean_text}{}\n", faces.join("\n"))).unwrap();
    let (distances, warnings) = measured_distances(&doubled, &landmarks);
    assert!(
        warnings.contains(&format!("dropped {} triangle(s) that repeat", faces.len())),
        "{warnings}"
    );
    assert_eq!(distances, clean);

    // A fin on an edge that two faces share (an interior edge).
    let corners = |face: &str| -> Vec<usize> {
        face.split_whitespace()
            .skip(1)
            .map(|c| c.split('/').next().unwrap().parse().unwrap())
            .collect()
    };
    let mut edge_faces = std::collections::HashMap::new();
    for face in &faces {
        let c = corners(face);
        for k in 0..3 {
            let edge = (c[k].min(c[(k + 1) % 3]), c[k].max(c[(k + 1) % 3]));
            *edge_faces.entry(edge).or_insert(0) += 1;
        }
    }
    let middle = corners(faces[faces.len() / 2]);
    let (a, b) = (middle[0], middle[1]);
    assert_eq!(edge_faces[&(a.min(b), a.max(b))], 2, "an interior edge");
    let vertex_count = clean_text.lines().filter(|l| l.starts_with("v ")).count();
    let position = |v: usize| -> Vec<f64> {
        let line = clean_text
            .lines()
            .filter(|l| l.starts_with("v "))
            .nth(v - 1)
            .unwrap();
        line.split_whitespace()
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect()
    };
    let (pa, pb) = (position(a), position(b));
    let lifted = |p: &[f64]| format!("v {} {} {}", p[0], p[1] + 15.0, p[2] - 20.0);
    let (top_a, top_b) = (vertex_count + 1, vertex_count + 2);
    let finned = dir.path().join("finned.obj");
    std::fs::write(
        &finned,
        format!(
            "{clean_text}{}\n{}\nf {a} {b} {top_b}\nf {a} {top_b} {top_a}\n",
            lifted(&pa),
            lifted(&pb)
        ),
    )
    .unwrap();
    let (distances, warnings) = measured_distances(&finned, &landmarks);
    assert!(
        warnings.contains("1 edge(s) were shared by more than two triangles")
            && warnings.contains("dropped 2 triangle(s) so that one surface runs through each"),
        "{warnings}"
    );
    assert_eq!(distances, clean);
}

/// `mammaplan` (quiet) with every file it writes limited to `max_file_bytes`
/// (RLIMIT_FSIZE, SIGXFSZ ignored): a write past the limit fails with EFBIG, as on a
/// full disk, half way through the file.
fn mammaplan_with_file_limit(args: &[&str], max_file_bytes: u64) -> Output {
    use std::os::unix::process::CommandExt;
    let mut command = Command::new(env!("CARGO_BIN_EXE_mammaplan"));
    command.args(args).arg("--quiet");
    // SAFETY: between fork and exec the closure makes only async-signal-safe calls.
    unsafe {
        command.pre_exec(move || {
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let limit = libc::rlimit {
                rlim_cur: max_file_bytes,
                rlim_max: max_file_bytes,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    command.output().expect("the binary runs")
}

/// Every file under `folder` with its content.
fn folder_content(folder: &Path) -> std::collections::BTreeMap<PathBuf, Vec<u8>> {
    let mut content = std::collections::BTreeMap::new();
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            content.extend(folder_content(&path));
        } else {
            content.insert(path.clone(), std::fs::read(&path).unwrap());
        }
    }
    content
}

/// A write that fails half way (a file-size limit the run reaches in the sixth of the
/// model's files, or inside the simulation's first) leaves the previous model and
/// simulation folders byte for byte; `phantom` whose landmark file cannot be written
/// leaves no scan.
#[test]
fn a_write_that_fails_half_way_leaves_what_was_there() {
    let dir = tempfile::tempdir().unwrap();
    let (scan, landmarks) = phantom(dir.path());
    let model_dir = dir.path().join("model");
    let output = model(&scan, &landmarks, &model_dir, &["--elements", "8000"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let simulation_dir = dir.path().join("simulation");
    let simulate = |limit: Option<u64>| {
        let args = [
            "simulate",
            "--model",
            model_dir.to_str().unwrap(),
            "--left",
            "catalog:R-MOD-100",
            "--out",
            simulation_dir.to_str().unwrap(),
        ];
        match limit {
            Some(limit) => mammaplan_with_file_limit(&args, limit),
            None => mammaplan(&args),
        }
    };
    let output = simulate(None);
    assert!(output.status.success(), "{}", stderr(&output));
    let (model_before, simulation_before) =
        (folder_content(&model_dir), folder_content(&simulation_dir));

    // The small phantom's model files in writing order: closed_surface.ply (5.8 MB), the
    // two breast patches and fill-ins (under 1 MB), filled_base.ply (6.2 MB), ...
    let args = [
        "model",
        "--scan",
        scan.to_str().unwrap(),
        "--landmarks",
        landmarks.to_str().unwrap(),
        "--out",
        model_dir.to_str().unwrap(),
        "--elements",
        "9000",
    ];
    let output = mammaplan_with_file_limit(&args, 6_000_000);
    assert_clean_failure(&output, "filled_base.ply");
    assert_eq!(folder_content(&model_dir), model_before);

    // simulated_scan.ply (7.2 MB) is written first.
    assert_clean_failure(&simulate(Some(1_000_000)), "simulated_scan.ply");
    assert_eq!(folder_content(&simulation_dir), simulation_before);

    let new_scan = dir.path().join("new.ply");
    let output = mammaplan(&[
        "phantom",
        "--out",
        new_scan.to_str().unwrap(),
        "--landmarks",
        dir.path().join("missing/landmarks.json").to_str().unwrap(),
    ]);
    assert_clean_failure(&output, "landmarks.json");
    assert!(!new_scan.exists());
    assert_no_temporary_files(dir.path());
}

/// The corpus of plausible mistakes, each refused with what was found and what
/// to do, with no output left: left and right swapped, only the nipples swapped, a
/// mirrored export, control points for the wrong side, coordinates far beyond a body (a
/// landmark at 1e308, a vertex at 3e38), a file too large to be a scan.
#[test]
fn a_corpus_of_plausible_mistakes_is_refused_with_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let (scan, landmarks) = phantom_as(dir.path(), "scan.obj");
    let landmarks_with = |name: &str, edit: &dyn Fn(&mut serde_json::Value)| {
        let edited = path(name);
        std::fs::copy(&landmarks, &edited).unwrap();
        edit_landmarks(&edited, edit);
        edited
    };
    let pairs = [
        ("Pcl", "Pcr"),
        ("Pnl", "Pnr"),
        ("PSMFl", "PSMFr"),
        ("PSMFml", "PSMFmr"),
        ("PSMFll", "PSMFlr"),
    ];
    let swap = |json: &mut serde_json::Value, pairs: &[(&str, &str)]| {
        let landmarks = &mut json["landmarks"];
        for (left, right) in pairs {
            let point = landmarks[left].take();
            landmarks[left] = landmarks[right].take();
            landmarks[right] = point;
        }
    };
    let swapped = landmarks_with("swapped.json", &|json| swap(json, &pairs));
    let nipples = landmarks_with("nipples.json", &|json| swap(json, &pairs[1..2]));
    let far = landmarks_with("far.json", &|json| {
        json["landmarks"]["Pj"][0] = 1e308.into();
    });
    let mirrored_landmarks = landmarks_with("mirrored.json", &|json| {
        for point in json["landmarks"].as_object_mut().unwrap().values_mut() {
            point[0] = (-point[0].as_f64().unwrap()).into();
        }
    });
    // The scan mirrored in x as a flipped export writes it (triangles as they were), and
    // one with a vertex at 3e38 mm.
    let text = std::fs::read_to_string(&scan).unwrap();
    let mut vertex = 0;
    let mut huge_line = 0;
    let (mut mirrored, mut huge) = (String::new(), String::new());
    for (number, line) in (1..).zip(text.lines()) {
        if let Some(rest) = line.strip_prefix("v ") {
            let mut coordinates = rest.split_whitespace();
            let x: f64 = coordinates.next().unwrap().parse().unwrap();
            let rest: Vec<&str> = coordinates.collect();
            mirrored += &format!("v {} {}\n", -x, rest.join(" "));
            huge += &if vertex == 100 {
                huge_line = number;
                "v 3e38 0 0\n".to_string()
            } else {
                format!("{line}\n")
            };
            vertex += 1;
        } else {
            mirrored += &format!("{line}\n");
            huge += &format!("{line}\n");
        }
    }
    std::fs::write(path("mirrored.obj"), mirrored).unwrap();
    std::fs::write(path("huge.obj"), huge).unwrap();
    // 2 GiB, sparse: nothing is read.
    std::fs::File::create(path("sparse.ply"))
        .unwrap()
        .set_len(2 << 30)
        .unwrap();

    let huge_expected = format!(
        "line {huge_line}: vertex 101: a coordinate of 3.000e38 mm lies more than a kilometre"
    );
    let cases: [(&Path, &Path, &str); 6] = [
        (
            &scan,
            &swapped,
            "left and right landmarks are swapped, or the scan is mirrored",
        ),
        (
            &scan,
            &nipples,
            "landmark Pnl lies 100 mm on the patient's right",
        ),
        (
            &path("mirrored.obj"),
            &mirrored_landmarks,
            "left and right landmarks are swapped, or the scan is mirrored",
        ),
        (
            &scan,
            &far,
            "landmark Pj: a coordinate of 1.000e308 mm lies more than a kilometre",
        ),
        (&path("huge.obj"), &landmarks, &huge_expected),
        (&path("sparse.ply"), &landmarks, "more than 1 GiB"),
    ];
    for (scan, landmarks, expected) in cases {
        let out = path("model");
        assert_clean_failure(&model(scan, landmarks, &out, &[]), expected);
        assert!(!out.exists());
    }

    // Control points made for the other side.
    let out = path("model");
    let output = model(&scan, &landmarks, &out, &["--elements", "8000"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let control_points = path("control_points.json");
    std::fs::copy(out.join("control_points.json"), &control_points).unwrap();
    edit_landmarks(&control_points, |json| {
        let left = json["left"].take();
        json["left"] = json["right"].take();
        json["right"] = left;
    });
    let other = path("other_model");
    let output = model(
        &scan,
        &landmarks,
        &other,
        &["--control-points", control_points.to_str().unwrap()],
    );
    assert_clean_failure(&output, "the \"left\" points lie on the patient's right");
    assert!(!other.exists());
}
