//! `mammaplan fem` and `mammaplan bench` as users and scripts see them: a solve on a
//! generated mesh, its rows and exports, and clean failures that write nothing.

mod common;

use common::*;

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
    // held skin unless `--skin-slides` is given
    assert_eq!(report["skin_slides"], false, "{report}");
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
    // the guide's contract: `converged_ms` is the row's own, not nested
    let fields = row.as_object().unwrap();
    assert!(fields.contains_key("converged_ms"), "{row}");
    assert!(!fields.contains_key("converged"), "{row}");
    // the medians are those of the five runs listed
    let runs = row["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 5, "{row}");
    let median_stop = runs
        .iter()
        .find(|run| run["default_stop_ms"] == row["default_stop_ms"])
        .unwrap_or_else(|| panic!("the median stop is no run's: {row}"));
    assert_eq!(
        median_stop["default_stop_cycles"],
        row["default_stop_cycles"]
    );
    assert!(row["default_stop_ms"].as_f64().unwrap() > 0.0, "{row}");
    if !row["converged_ms"].is_null() {
        assert!(
            runs.iter()
                .any(|run| run["converged_ms"] == row["converged_ms"]
                    && run["converged_cycles"] == row["converged_cycles"]),
            "the median answer is no run's: {row}"
        );
    }
    for distance in ["default_stop_skin", "start_dependence"] {
        assert!(row[distance]["max_mm"].as_f64().unwrap() >= 0.0, "{row}");
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
