//! `plan::report` on real folders: a small phantom model, a simulation with one implant,
//! and an asymmetric phantom standing in for the post-operative scan. The report must
//! show what `result.json` and `model.json` hold, and the post-operative scan's volumes
//! and symmetry against the phantom's truth.

use phantom::PhantomParams;
use plan::model::{ModelOptions, build_model, write_model};
use plan::report::{PostoperativeScan, ReportInputs, report_content, write_report};
use plan::simulate::{ImplantRequest, SimulateOptions, simulate};
use plan::{MarkedScan, Silent};
use report::ReportContent;
use serde_json::Value;
use std::path::Path;
use std::time::{Duration, UNIX_EPOCH};

/// Tetrahedra of the small model: enough for a stable simulation, fast to build.
const ELEMENTS: usize = 8_000;

fn read_json(path: &std::path::Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// The folders a report reads, in `dir`: the phantom's model, a simulation with one
/// implant, and an asymmetric phantom standing in for the post-operative scan (whose
/// truth is returned).
fn write_case(dir: &Path) -> (ReportInputs, phantom::Phantom) {
    let path = |name: &str| dir.join(name);
    plan::demo::write_phantom(
        &PhantomParams::default(),
        &path("scan.ply"),
        &path("landmarks.json"),
    )
    .unwrap();
    let marked =
        MarkedScan::load(&path("scan.ply"), &path("landmarks.json"), None, &Silent).unwrap();
    let options = ModelOptions {
        elements: ELEMENTS,
        ..Default::default()
    };
    let model = build_model(&marked, &options, &Silent).unwrap();
    write_model(&path("model"), &model, &Silent).unwrap();
    let left = ImplantRequest {
        move_mm: [2.0, -3.0, 0.0].into(),
        ..ImplantRequest::new("anatomic:width=115,height=110,projection=38")
    };
    simulate(
        &path("model"),
        &path("simulation"),
        &SimulateOptions {
            left: Some(left),
            // centred on the native breast's base at the native fold: the carried cut
            // curve then still bounds the breast, so the simulated scan cut again along
            // it measures the simulation's volume (check_volumes); an implant reaching
            // below the fold would be cut through
            anchor: plan::simulate::AnchorRule::FootprintCentre,
            fold_lowering_mm: plan::model::PerSide {
                left: Some(0.0),
                right: Some(0.0),
            },
            ..Default::default()
        },
        &Silent,
    )
    .unwrap();
    // The post-operative stand-in: a phantom with one breast about 9% larger and its
    // nipple about 6 mm lower (phantom::PhantomParams::asymmetry).
    let postop_params = PhantomParams {
        asymmetry: 1.0,
        ..Default::default()
    };
    let postop = plan::demo::write_phantom(
        &postop_params,
        &path("postop.ply"),
        &path("postop_landmarks.json"),
    )
    .unwrap();

    let inputs = ReportInputs {
        model_dir: path("model"),
        simulation_dir: path("simulation"),
        postoperative: Some(PostoperativeScan {
            scan: path("postop.ply"),
            landmarks: path("postop_landmarks.json"),
            up: None,
            units: None,
        }),
        created: UNIX_EPOCH + Duration::from_secs(1_795_339_260),
        show_muscle: false,
    };
    (inputs, postop)
}

#[test]
fn a_report_shows_the_model_the_simulation_and_the_postoperative_scan() {
    let dir = tempfile::tempdir().unwrap();
    let path = |name: &str| dir.path().join(name);
    let (inputs, postop) = write_case(dir.path());
    let content = report_content(&inputs, &Silent).unwrap();
    let result = read_json(&path("simulation/result.json"));
    let model_json = read_json(&path("model/model.json"));
    check_case(&content, &result, &model_json);
    check_implants(&content, &result);
    check_template_lengths(&result, &model_json);
    check_distances(&content, &result);
    check_volumes(&content, &result, &model_json, &postop, dir.path());
    check_symmetry(&content, &postop);
    check_views_and_comparison(&content);
    check_page(&inputs, &result, dir.path());
}

/// The case: file names only, the finest level of model.json, the materials of result.json.
fn check_case(content: &ReportContent, result: &Value, model_json: &Value) {
    assert_eq!(content.case.created, "2026-11-22 09:21 UTC");
    let names: Vec<&str> = content.case.files.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(
        names,
        [
            "scan.ply",
            "landmarks.json",
            "simulated_scan.ply",
            "postop.ply",
            "postop_landmarks.json"
        ]
    );
    let finest = &model_json["levels"][0];
    assert_eq!(
        content.case.model.finest_elements as u64,
        finest["elements"].as_u64().unwrap()
    );
    assert_eq!(
        content.case.model.tissue.young_kpa,
        result["materials"]["tissue"]["young_kpa"].as_f64().unwrap()
    );
}

/// The implants as result.json has them: the left one, none on the right.
fn check_implants(content: &ReportContent, result: &Value) {
    let implant = content.implants.left.as_ref().unwrap();
    let left = &result["implants"]["left"];
    assert_eq!(implant.spec, "anatomic:width=115,height=110,projection=38");
    assert_eq!(implant.volume_ml, left["volume_ml"].as_f64().unwrap());
    assert_eq!(
        implant.volume_ml,
        result["implant_volume_ml"]["left"].as_f64().unwrap()
    );
    assert_eq!(
        (implant.width_mm, implant.height_mm, implant.projection_mm),
        (115.0, 110.0, 38.0)
    );
    assert_eq!(implant.offset_mm, [2.0, -3.0, 0.0]);
    // result.json's anchor rule, as asked.
    assert_eq!(result["anchor"], "footprint-centre");
    assert_eq!(implant.default_position, "centred on the breast's base");
    assert!(implant.catalog.is_none());
    assert!(implant.shape.starts_with("anatomic, "), "{}", implant.shape);
    assert!(content.implants.right.is_none());
}

/// The template's lengths as resolved on this model: 14 and 7 mm, or two and one finest
/// spacings where those are longer (the coarse test model's case).
fn check_template_lengths(result: &Value, model_json: &Value) {
    let spacing_mm = model_json["levels"][0]["spacing_mm"].as_f64().unwrap();
    let left = &result["implants"]["left"];
    assert_eq!(
        left["rim_smoothing_mm"].as_f64().unwrap(),
        f64::max(14.0, 2.0 * spacing_mm)
    );
    assert_eq!(
        left["template_layer_mm"].as_f64().unwrap(),
        f64::max(7.0, spacing_mm)
    );
}

/// The distance table: simulated values are result.json's, row for row.
fn check_distances(content: &ReportContent, result: &Value) {
    let distances = result["distances"].as_array().unwrap();
    assert_eq!(content.measurements.len(), distances.len());
    for (row, distance) in content.measurements.iter().zip(distances) {
        assert_eq!(row.name, distance["name"].as_str().unwrap());
        assert_eq!(row.simulated_mm, distance["surface_mm"].as_f64());
        assert!(row.preoperative_mm.is_some() && row.postoperative_mm.is_some());
    }
}

/// Volumes: model.json before, result.json as simulated, the phantom's truth after.
fn check_volumes(
    content: &ReportContent,
    result: &Value,
    model_json: &Value,
    postop: &phantom::Phantom,
    dir: &Path,
) {
    let path = |name: &str| dir.join(name);
    let volumes = &content.volumes;
    assert_eq!(
        volumes.preoperative.left.breast_ml,
        model_json["breast_volume_ml"]["left"].as_f64().unwrap()
    );
    let quadrants = volumes.preoperative.left.quadrants_ml.unwrap();
    assert_eq!(
        quadrants.upper_outer_ml,
        model_json["quadrant_volume_ml"]["left"]["upper_outer"]
            .as_f64()
            .unwrap()
    );
    let simulated = volumes.simulated.unwrap();
    assert_eq!(
        simulated.left.breast_ml,
        result["breast_volume_ml"]["left"].as_f64().unwrap()
    );
    // The simulated quadrants are result.json's and partition the breast (round-off).
    let simulated_quadrants = simulated.left.quadrants_ml.unwrap();
    assert_eq!(
        simulated_quadrants.upper_outer_ml,
        result["quadrant_volume_ml"]["left"]["upper_outer"]
            .as_f64()
            .unwrap()
    );
    let sum: f64 = simulated_quadrants.values_ml().iter().sum();
    assert!((sum - simulated.left.breast_ml).abs() < 1e-6 * sum, "{sum}");
    // The right breast has no implant and barely moves: the simulation's quadrants
    // (moved patch over the chest wall) match the model's own (the scan as loaded) to
    // 2%, the right breast's change here.
    let (model_right, simulated_right) = (
        volumes.preoperative.right.quadrants_ml.unwrap(),
        simulated.right.quadrants_ml.unwrap(),
    );
    for (before, after) in model_right
        .values_ml()
        .into_iter()
        .zip(simulated_right.values_ml())
    {
        assert!((after / before - 1.0).abs() < 0.02, "{before} -> {after}");
    }
    // The model's control points carried onto the simulated scan cut the same breast:
    // a breast model of the simulated scan along them measures what the simulation
    // measures over a fill-in rebuilt on the moved cut curve, up to the smoothing of the
    // displacement over the scan and the spline re-projected through the carried points
    // (-2% to -3.5% on the shared scans' tests): bound 5%.
    let simulated_scan = MarkedScan::load(
        &path("simulation/simulated_scan.ply"),
        &path("simulation/simulated_landmarks.json"),
        None,
        &Silent,
    )
    .unwrap();
    let (simulated_breasts, _) = plan::model::build_breasts(
        &simulated_scan,
        &Default::default(),
        Some(&path("simulation/simulated_control_points.json")),
        &Silent,
    )
    .unwrap();
    let remeasured = simulated_breasts.left.volume_ml;
    let rebuilt = result["breast_volume_rebuilt_fill_ml"]["left"]
        .as_f64()
        .unwrap();
    assert!(
        (remeasured / rebuilt - 1.0).abs() < 0.05,
        "{remeasured} ml against {rebuilt} ml"
    );
    let post = volumes.postoperative.unwrap();
    for (measured, truth) in [
        (post.left.breast_ml, postop.breast_volume_ml.left),
        (post.right.breast_ml, postop.breast_volume_ml.right),
    ] {
        // The breast model's bound on the phantom (docs/user/model.md: within 2.3%), with margin.
        assert!(
            (measured / truth - 1.0).abs() < 0.05,
            "{measured} ml against {truth} ml"
        );
        let quadrants = post.left.quadrants_ml.unwrap();
        let sum: f64 = quadrants.values_ml().iter().sum();
        assert!((sum - post.left.breast_ml).abs() < 1e-6 * post.left.breast_ml);
    }
}

/// Symmetry: the symmetric phantom before; the asymmetric one after, against its truth.
fn check_symmetry(content: &ReportContent, postop: &phantom::Phantom) {
    assert_eq!(content.symmetry.len(), 3);
    let before = &content.symmetry[0];
    assert!((before.volume_ratio_left_to_right - 1.0).abs() < 1e-6);
    // Exact landmarks of a mirror-symmetric phantom: only round-off.
    assert!(before.nipple_height_difference_mm.abs() < 1e-6);
    assert!(before.nipple_mirror_distance_mm < 1e-6);
    let after = &content.symmetry[2];
    let true_ratio = postop.breast_volume_ml.left / postop.breast_volume_ml.right;
    assert!(
        (after.volume_ratio_left_to_right / true_ratio - 1.0).abs() < 0.05,
        "{} against {true_ratio}",
        after.volume_ratio_left_to_right
    );
    // The larger breast's nipple is the lower one (by about 6 mm).
    let larger_is_left = true_ratio > 1.0;
    let lower_is_left = after.nipple_height_difference_mm < 0.0;
    assert_eq!(larger_is_left, lower_is_left);
    assert!(
        (3.0..9.0).contains(&after.nipple_height_difference_mm.abs()),
        "{}",
        after.nipple_height_difference_mm
    );
}

/// The views: five of each scan (pre-operative, simulated, post-operative) and the change
/// from the pre-operative surface from the front and the obliques; the comparison with the
/// post-operative scan, which differs from the simulation.
fn check_views_and_comparison(content: &ReportContent) {
    assert_eq!(content.views.len(), 18);
    assert!(content.views.iter().all(|v| !v.labels.is_empty()));
    assert_eq!(
        content
            .views
            .iter()
            .filter(|v| v.colour_scale.is_some())
            .count(),
        3
    );
    // The comparison with the post-operative scan, which differs from the simulation.
    let comparison = content.comparison.as_ref().expect("a comparison");
    let whole = &comparison.regions[0];
    assert_eq!(whole.region, "Whole overlap");
    assert!(whole.rms_mm > 0.0 && whole.rms_mm.is_finite(), "{whole:?}");
    assert!(whole.mean_mm <= whole.rms_mm && whole.rms_mm <= whole.hausdorff_mm);
    assert!(content.notes.is_empty(), "{:?}", content.notes);
}

/// The page as written: the implant volume and the simulated distances as printed.
fn check_page(inputs: &ReportInputs, result: &Value, dir: &Path) {
    let path = |name: &str| dir.join(name);
    let left = &result["implants"]["left"];
    let distances = result["distances"].as_array().unwrap();
    let summary = write_report(inputs, &path("report.html"), &Silent).unwrap();
    let page = std::fs::read_to_string(path("report.html")).unwrap();
    assert_eq!(summary.bytes, page.len());
    assert!(page.contains(&format!(
        "<strong>{:.0}</strong>",
        left["volume_ml"].as_f64().unwrap()
    )));
    for distance in distances {
        let name = distance["name"].as_str().unwrap();
        let value = format!("{:.1}", distance["surface_mm"].as_f64().unwrap());
        let row = page
            .split("<tr>")
            .find(|row| row.contains(&format!(">{name}</th>")))
            .unwrap_or_else(|| panic!("no row {name}"));
        assert!(row.contains(&format!(">{value}</td>")), "{name}: {value}");
    }
}

#[test]
fn missing_and_malformed_folders_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let inputs = |model: &str, simulation: &str| ReportInputs {
        model_dir: dir.path().join(model),
        simulation_dir: dir.path().join(simulation),
        postoperative: None,
        created: UNIX_EPOCH,
        show_muscle: false,
    };
    let error = |inputs: ReportInputs| {
        format!(
            "{:#}",
            report_content(&inputs, &Silent).expect_err("the report must fail")
        )
    };
    let message = error(inputs("nowhere", "simulation"));
    assert!(message.contains("model.json"), "{message}");
    assert!(message.contains("a model folder"), "{message}");

    std::fs::create_dir_all(dir.path().join("model")).unwrap();
    std::fs::write(dir.path().join("model/model.json"), "{\"scan\": 3}").unwrap();
    let message = error(inputs("model", "simulation"));
    assert!(message.contains("not a model report"), "{message}");

    // A well-formed model.json, then a missing and a malformed result.json.
    let record = serde_json::json!({
        "scan": "scan.ply", "landmarks": "landmarks.json", "elements_requested": 8000,
        "rear_wall_offset_mm": 15.0, "refinement": null,
        "levels": [{"elements": 8000, "nodes": 2000}],
        "breast_volume_ml": {"left": 300.0, "right": 300.0},
        "quadrant_volume_ml": {
            "left": {"upper_outer": 75.0, "upper_inner": 75.0, "lower_inner": 75.0, "lower_outer": 75.0},
            "right": {"upper_outer": 75.0, "upper_inner": 75.0, "lower_inner": 75.0, "lower_outer": 75.0}
        }
    });
    std::fs::write(dir.path().join("model/model.json"), record.to_string()).unwrap();
    let message = error(inputs("model", "simulation"));
    assert!(message.contains("result.json"), "{message}");
    assert!(message.contains("a simulation folder"), "{message}");
    std::fs::create_dir_all(dir.path().join("simulation")).unwrap();
    std::fs::write(dir.path().join("simulation/result.json"), "{}").unwrap();
    let message = error(inputs("model", "simulation"));
    assert!(message.contains("not a simulation report"), "{message}");
}

/// On request the report adds the pectoralis major through the pre-operative skin,
/// front and obliques, after the other views; a model folder without the muscle's
/// files is named with what to do. The simulation's `fe_result.vtu` marks the muscle's
/// elements the model measured.
#[test]
fn the_report_shows_the_pectoralis_major_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let (inputs, _) = write_case(dir.path());
    let inputs = ReportInputs {
        postoperative: None,
        ..inputs
    };
    let plain = report_content(&inputs, &Silent).unwrap();
    let with_muscle = ReportInputs {
        show_muscle: true,
        ..inputs.clone()
    };
    let content = report_content(&with_muscle, &Silent).unwrap();
    assert_eq!(content.views.len(), plain.views.len() + 3);
    let added: Vec<&str> = content.views[plain.views.len()..]
        .iter()
        .map(|v| v.title.as_str())
        .collect();
    for (title, view) in added.iter().zip(["Front", "Left oblique", "Right oblique"]) {
        assert!(title.starts_with("Pectoralis major"), "{title}");
        assert!(title.ends_with(view), "{title}");
    }
    // the simulation writes the muscle's elements into fe_result.vtu (the session places
    // them as the model did): their volumes, summed from the file's geometry, are the
    // ones model.json reports (to rounding)
    let fe = tetra::vtu::read_vtu(&dir.path().join("simulation/fe_result.vtu")).unwrap();
    let Some(tetra::vtu::FieldValues::Scalars(codes)) =
        fe.cell_field("pectoralis_major").map(|f| &f.values)
    else {
        panic!("fe_result.vtu has no pectoralis_major scalars");
    };
    let model_json = read_json(&dir.path().join("model/model.json"));
    for (code, side) in [(1.0, "left"), (2.0, "right")] {
        let volume_mm3: f64 = (fe.mesh.tets.iter().zip(codes))
            .filter(|(_, c)| **c == code)
            .map(|(t, _)| tetra::quality::signed_volume(t.map(|v| fe.mesh.positions[v as usize])))
            .sum();
        let reported = model_json["pectoralis_major"][side]["volume_ml"]
            .as_f64()
            .unwrap();
        assert!(
            (volume_mm3 / 1000.0 / reported - 1.0).abs() < 1e-9,
            "{side}: {volume_mm3} mm³ vs {reported} ml"
        );
    }
    for side in ["left", "right"] {
        std::fs::remove_file(dir.path().join(format!("model/muscle_{side}.ply"))).unwrap();
    }
    let message = format!("{:#}", report_content(&with_muscle, &Silent).unwrap_err());
    assert!(message.contains("muscle_left.ply"), "{message}");
    assert!(message.contains("mammaplan model"), "{message}");
}
