//! The foundation's acceptance checks on the realistic scans in `../shared/scans/`
//! (made from an independent body model, not our phantom).

use anatomy::register::RigidTransform;
use glam::{DQuat, DVec3};
use plan::{MarkedScan, Progress, Scan, Silent, Up, UpSource};
use std::path::{Path, PathBuf};

mod warnings;
use warnings::Warnings;

fn shared_scans() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scans"
    ));
    if dir.is_dir() {
        Some(dir)
    } else if std::env::var_os("CI").is_some() {
        panic!(
            "{} is missing: CI must run with ../shared beside the repository",
            dir.display()
        );
    } else {
        eprintln!("skipped: {} not found", dir.display());
        None
    }
}

fn load(dir: &std::path::Path, name: &str) -> MarkedScan {
    MarkedScan::load(
        &dir.join(format!("{name}.ply")),
        &dir.join(format!("{name}_landmarks.json")),
        None,
        &Silent,
    )
    .unwrap()
}

#[test]
fn clinical_distances_on_every_shared_scan_are_plausible_and_ordered() {
    let Some(dir) = shared_scans() else { return };
    for name in ["v02_average", "pair1_pre", "pair1_post"] {
        let report = plan::measure::measure(&load(&dir, name), &[], &Silent).unwrap();
        assert_eq!(report.distances.len(), 11);
        for d in &report.distances {
            let surface = d
                .surface_mm
                .unwrap_or_else(|| panic!("{name} {}: {:?}", d.name, d.note));
            let geodesic = d
                .geodesic_mm
                .unwrap_or_else(|| panic!("{name} {}: {:?}", d.name, d.note));
            // The section curve and the geodesic are both paths on the surface; the
            // geodesic is the shortest, and no path is shorter than the straight line.
            assert!(
                surface >= geodesic && geodesic >= d.euclidean_mm,
                "{name} {}: surface {surface} geodesic {geodesic} euclidean {}",
                d.name,
                d.euclidean_mm
            );
            if d.name.starts_with("Pj-") {
                assert!(
                    (170.0..=260.0).contains(&surface),
                    "{name} {}: {surface}",
                    d.name
                );
            }
            if d.name.ends_with("-PSMFl") || d.name.ends_with("-PSMFr") {
                assert!(
                    (40.0..=110.0).contains(&surface),
                    "{name} {}: {surface}",
                    d.name
                );
            }
        }
    }
}

/// The true transform (`inverse_4x4` of `pair1_transform.json`, post -> pre).
fn true_post_to_pre(dir: &std::path::Path) -> RigidTransform {
    let text = std::fs::read_to_string(dir.join("pair1_transform.json")).unwrap();
    let json: serde_json::Value = serde_json::from_str(&text).unwrap();
    let matrix: [[f64; 4]; 4] = serde_json::from_value(json["inverse_4x4"].clone()).unwrap();
    RigidTransform::from_row_major(&matrix)
}

/// How far a registration error moves every 97th vertex of `scan` (mm).
fn displacement_errors_mm(error: &RigidTransform, scan: &MarkedScan) -> Vec<f64> {
    scan.scan
        .mesh
        .positions
        .iter()
        .step_by(97)
        .map(|&p| error.apply(p).distance(p))
        .collect()
}

#[test]
fn registration_recovers_the_known_transform_of_pair1() {
    let Some(dir) = shared_scans() else { return };
    let pre = load(&dir, "pair1_pre");
    let post = load(&dir, "pair1_post");
    let truth = true_post_to_pre(&dir);
    for icp in [false, true] {
        let (found, report) = plan::register::register(&pre, &post, icp).unwrap();
        let error = found.after(&truth.inverse());
        // Worst displacement error over the scan's extent: rotation about the file origin
        // is not meaningful (y ~ 1200 mm), so compare where the body is.
        let errors = displacement_errors_mm(&error, &pre);
        let worst_mm = errors.iter().copied().fold(0.0, f64::max);
        let rms_mm = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
        let centre = pre.scan.mesh.centroid();
        let centre_mm = error.apply(centre).distance(centre);
        eprintln!(
            "icp {icp}: rotation error {:.4} deg, error at the scan centroid {centre_mm:.3} mm, over the scan rms {rms_mm:.3} mm worst {worst_mm:.3} mm, landmark rms {:.3}, surface rms {:.3} mm",
            error.rotation_angle_deg(),
            report.landmark_rms_mm,
            report.surface_rms_mm
        );
        // The acceptance: within 0.5 degrees and 1 mm (translation measured where
        // the body is, at the scan's centroid, since the file origin is on the floor).
        assert!(error.rotation_angle_deg() < 0.5);
        assert!(centre_mm < 1.0);
        if icp {
            // ICP on the unchanged surface away from the breasts is far tighter.
            assert!(worst_mm < 0.5, "{worst_mm}");
            assert!(report.surface_rms_mm <= report.surface_rms_landmarks_only_mm);
        }
    }
}

#[test]
fn compare_of_pair1_recovers_the_registration_and_sees_the_larger_cup() {
    let Some(dir) = shared_scans() else { return };
    let pre = load(&dir, "pair1_pre");
    let post = load(&dir, "pair1_post");
    let options = plan::compare::CompareOptions {
        register: true,
        ..Default::default()
    };
    let report = plan::compare::compare(&pre, &post, &options, &Silent).unwrap();
    let found = RigidTransform::from_row_major(&report.registration.as_ref().unwrap().matrix);
    let error = found.after(&true_post_to_pre(&dir).inverse());
    let worst_mm = displacement_errors_mm(&error, &pre)
        .into_iter()
        .fold(0.0, f64::max);
    let both = report.breast_regions.both.unwrap();
    eprintln!(
        "pair1: registration error {worst_mm:.3} mm; rms {:.2} mm, breasts {:.2} mm (signed {:+.2}), hausdorff {:.2} mm, overlap {:.3}",
        report.rms_mm,
        both.rms_mm,
        both.signed_mean_mm,
        report.hausdorff_mm,
        report.overlap_fraction
    );
    assert!(worst_mm < 0.5, "{worst_mm}");
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    assert!(report.overlap_fraction > 0.9);
    // The larger cup lies in front of the smaller one, and the change is in the breasts.
    assert!(both.signed_mean_mm > 3.0 && both.rms_mm > report.rms_mm);
    let (pre_volumes, post_volumes) = (
        report.breast_volume_ml.reference.unwrap(),
        report.breast_volume_ml.test.unwrap(),
    );
    assert!(post_volumes.left > pre_volumes.left + 50.0);
    // The body is symmetric (MakeHuman's average model).
    for symmetry in [&report.symmetry.reference, &report.symmetry.test] {
        let symmetry = symmetry.as_ref().unwrap();
        assert!((symmetry.volume_ratio_left_to_right - 1.0).abs() < 0.05);
        assert!(symmetry.asymmetry.both_breasts.unwrap().rms_mm < 1.0);
    }
}

/// Issue 6's measurement gap: pair1_pre with R-MOD-90 on both sides (as `mammaplan
/// simulate` runs it, gravity included). On the simulated scan the nipple ends up at the
/// fold's height: the paper's plane through Pn and PSMF, orthogonal to the coronal
/// plane, is nearly horizontal and cuts the breast in a closed loop that misses the
/// fold (it measured nothing), so Pn-PSMF is measured in the plane containing the mean
/// surface normal, which the JSON says. Every surface distance is measured, and no
/// shorter than the geodesic; the fallback's section follows the geodesic closely
/// (measured 1.04 times it; the paper's plane gives 1.09-1.14 for Pn-PSMF on the shared
/// scans before surgery): bound 1.2.
#[test]
fn the_simulated_pair1_pre_has_every_surface_distance() {
    let Some(dir) = shared_scans() else { return };
    let mut session = simulated(&dir, "pair1_pre", "catalog:R-MOD-90");
    let measurements = session.measurements(&Silent).unwrap();
    assert_eq!(measurements.distances.len(), 11);
    the_simulated_breasts_can_be_cut_again(&mut session, &measurements);
    for change in &measurements.distances {
        let d = &change.simulated;
        let surface = d
            .surface_mm
            .unwrap_or_else(|| panic!("{}: {:?}", d.name, d.note));
        let geodesic = d.geodesic_mm.unwrap();
        println!(
            "{}: surface {:?} -> {surface:.1} mm in the {:?} plane, geodesic {geodesic:.1} mm",
            d.name,
            change.before.surface_mm,
            d.surface_plane.unwrap()
        );
        assert!(surface >= geodesic && geodesic >= d.euclidean_mm, "{d:?}");
        if d.surface_plane == Some(anatomy::measure::SectionPlane::MeanNormal) {
            assert!(
                d.note
                    .as_deref()
                    .is_some_and(|n| n.contains("mean surface normal")),
                "{d:?}"
            );
            assert!(surface <= 1.2 * geodesic, "{d:?}");
        }
    }
}

/// The session of the shared scan `name` with the implant `spec` on both sides, run to
/// convergence as `mammaplan simulate` runs it (gravity included), at the native fold:
/// the carried cut curve then still bounds the breast, so the simulated scan cut again
/// along it measures the simulation's volume over a fill-in rebuilt on the moved curve
/// (below a lowered fold it would cut through the implant).
fn simulated(dir: &std::path::Path, name: &str, spec: &str) -> plan::simulate::Session {
    let native_fold = plan::simulate::PocketLimits {
        fold_lowering: plan::simulate::FoldLowering::Mm(0.0),
        ..Default::default()
    };
    let mut session = plan::simulate::Session::build(
        load(dir, name),
        &plan::model::ModelOptions::default(),
        plan::catalog::Catalog::builtin(),
        plan::simulate::SimulationOptions {
            pocket: Some([native_fold; 2]),
            ..Default::default()
        },
        &Silent,
    )
    .unwrap();
    for side in anatomy::breast::Side::BOTH {
        session.set_implant(side, spec, Default::default()).unwrap();
    }
    let run = session.simulation.run(false).unwrap();
    assert!(run.implant.converged, "{name}, {spec}: {run:?}");
    session
}

/// `v02_average` has a 47 mm scanner dropout under its right breast; R-MOD-110 on both
/// sides stretches it to 63 mm with the skin, and the simulated scan is still cut into
/// breasts along the carried curves (measured -2.7% and -2.4% against the simulation's
/// volume over a rebuilt fill-in, 2026-11-29).
#[test]
fn the_simulated_v02_average_is_cut_again_over_its_stretched_dropout() {
    let Some(dir) = shared_scans() else { return };
    let mut session = simulated(&dir, "v02_average", "catalog:R-MOD-110");
    let measurements = session.measurements(&Silent).unwrap();
    the_simulated_breasts_can_be_cut_again(&mut session, &measurements);
}

/// The simulated scan of `session` cut into breasts as a real scan is, along the model's
/// control points carried with the tissue: on `pair1_pre` the default control points
/// from the simulated landmarks fail there (the fold landmarks ride forward on the
/// implant, and the curve 8 mm below them folds over the lower pole), the carried ones
/// do not. Its volumes match the simulation's over a fill-in rebuilt on the moved cut
/// curve (`volume_rebuilt_fill_ml`, not its breast volume over the chest wall) up to the
/// smoothing of the displacement over the scan, which rounds the simulated skin a
/// little, the spline re-projected through the carried points, and scanner holes closed
/// afresh on the simulated scan: measured -3.5% and -3.0% on `pair1_pre`, -2.7% and
/// -2.4% on `v02_average` (2026-11-29). Bound 7%.
/// The simulation's quadrant volumes partition its breast volume.
fn the_simulated_breasts_can_be_cut_again(
    session: &mut plan::simulate::Session,
    measurements: &plan::simulate::SimulatedMeasurements,
) {
    let dir = tempfile::tempdir().unwrap();
    let control_points = dir.path().join("simulated_control_points.json");
    session
        .simulated_control_points()
        .write(&control_points)
        .unwrap();
    let simulated = session
        .simulated_scan(&dir.path().join("simulated_scan.ply"))
        .unwrap();
    let (breasts, _) = plan::model::build_breasts(
        &simulated,
        &Default::default(),
        Some(&control_points),
        &Silent,
    )
    .unwrap();
    let rebuilt_ml = session.breast_volumes().volume_rebuilt_fill_ml;
    for side in anatomy::breast::Side::BOTH {
        let simulated_ml = *measurements.breast_volume_ml.get(side);
        let rebuilt_ml = rebuilt_ml.get(side).unwrap();
        let remeasured_ml = breasts.breast(side).volume_ml;
        println!(
            "{side}: {simulated_ml:.1} ml simulated, {rebuilt_ml:.1} ml over a rebuilt fill-in, \
             {remeasured_ml:.1} ml cut again"
        );
        assert!(
            (remeasured_ml / rebuilt_ml - 1.0).abs() < 0.07,
            "{side}: {remeasured_ml} ml against {rebuilt_ml} ml"
        );
        let quadrants = measurements.quadrant_volume_ml.get(side).unwrap();
        assert!((quadrants.total() - simulated_ml).abs() < 1e-6 * simulated_ml);
    }
}

// The standing frame: up is the file's vertical on these upright files, a known turn
// of the file is undone exactly by giving up, and a scan lying on its back gets an
// estimate and a warning.

/// v02_average turned by `rotation` about the origin, with `up` given or not.
fn turned_v02(dir: &Path, rotation: DQuat, up: Option<Up>, progress: &dyn Progress) -> MarkedScan {
    let upright = MarkedScan::load(
        &dir.join("v02_average.ply"),
        &dir.join("v02_average_landmarks.json"),
        None,
        &Silent,
    )
    .unwrap();
    let mut mesh = upright.scan.mesh.clone();
    mesh.map_positions(|p| rotation * p);
    let mut landmarks = upright.landmarks.clone();
    landmarks.map_positions(|p| rotation * p);
    let scan = Scan::from_mesh(mesh, Path::new("v02_average turned")).unwrap();
    MarkedScan::new(scan, landmarks, Path::new("turned landmarks"), up, progress).unwrap()
}

#[test]
fn upright_files_keep_their_vertical_and_report_the_sternum_lean() {
    let Some(dir) = shared_scans() else { return };
    for name in ["v02_average", "pair1_pre", "pair1_post"] {
        let warnings = Warnings::default();
        let marked = MarkedScan::load(
            &dir.join(format!("{name}.ply")),
            &dir.join(format!("{name}_landmarks.json")),
            None,
            &warnings,
        )
        .unwrap();
        // Gravity is -up: exactly the file's -y (asked: within 1 degree).
        assert_eq!(marked.frame.up(), DVec3::Y, "{name}");
        assert_eq!(marked.frame.up_source, UpSource::FileVertical);
        assert!(warnings.0.lock().unwrap().is_empty());
        // The sternum leans back 25.7-27.0° on every body-model scan (measured with an
        // independent script from the landmark files: the angle of Pj - Px from +y).
        let lean = marked.frame.sternum_lean_deg();
        assert!((20.0..=30.0).contains(&lean), "{name}: sternum lean {lean}");
    }
}

#[test]
fn a_turned_file_with_its_up_given_measures_as_the_upright_one() {
    let Some(dir) = shared_scans() else { return };
    let upright = turned_v02(&dir, DQuat::IDENTITY, None, &Silent);
    let rotation = DQuat::from_rotation_x(10f64.to_radians());
    let given = Up::parse(&Up::FILE_VERTICAL.rotated(rotation).to_arg()).unwrap();
    let turned = turned_v02(&dir, rotation, Some(given), &Silent);
    // The frame turns with the file (round-off of a rotation of ~1 m coordinates).
    let expected = glam::DMat3::from_quat(rotation) * upright.frame.axes;
    assert!(turned.frame.axes.abs_diff_eq(expected, 1e-12));
    let before = plan::measure::measure(&upright, &[], &Silent).unwrap();
    let after = plan::measure::measure(&turned, &[], &Silent).unwrap();
    for (a, b) in before.distances.iter().zip(&after.distances) {
        assert!((a.euclidean_mm - b.euclidean_mm).abs() < 1e-6, "{}", a.name);
        // The plane sections meet the same triangles in turned coordinates: equal to
        // well under a micrometre.
        let (sa, sb) = (a.surface_mm.unwrap(), b.surface_mm.unwrap());
        assert!((sa - sb).abs() < 1e-6, "{}: {sa} vs {sb}", a.name);
    }
    // Without --up a 10° turn is within a standing sternum's range, so the file is taken
    // as upright: only the user can say it (the flag above).
    let unsaid = turned_v02(&dir, rotation, None, &Silent);
    assert_eq!(unsaid.frame.up(), DVec3::Y);
}

#[test]
fn a_lying_scan_gets_an_estimated_up_and_a_warning() {
    let Some(dir) = shared_scans() else { return };
    // Lying on her back: the body's up now along the file's -z.
    let rotation = DQuat::from_rotation_x(-90f64.to_radians());
    let warnings = Warnings::default();
    let lying = turned_v02(&dir, rotation, None, &warnings);
    assert_eq!(lying.frame.up_source, UpSource::Estimated);
    let truth = rotation * DVec3::Y;
    let error_deg = lying.frame.up().angle_between(truth).to_degrees();
    // v02_average's sternum leans 26.8°, the estimate assumes 26°.
    assert!(error_deg < 3.0, "estimate {error_deg:.2}° off");
    let warnings = warnings.0.lock().unwrap();
    assert!(
        warnings
            .iter()
            .any(|w| w.contains("--up") && w.contains("estimated")),
        "{warnings:?}"
    );
}
