//! `compare` on the phantom against itself in a moved frame: after registration the
//! deviation, the distance differences and the volume differences vanish, and the
//! deviation mesh holds the map. Bad input gives errors naming the problem.

mod common;

use anatomy::register::RigidTransform;
use glam::{DMat3, DQuat, DVec3};
use plan::compare::{CompareOptions, compare};
use plan::{MarkedScan, PhantomParams, Silent};

/// The phantom (small cup: the smallest scan) moved by `motion`.
fn moved_phantom(motion: &RigidTransform) -> MarkedScan {
    let params = PhantomParams {
        cup: plan::Cup::Small,
        ..PhantomParams::default()
    };
    common::marked_phantom(&params, Some(motion))
}

fn motion() -> RigidTransform {
    RigidTransform {
        rotation: DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(0.2, 0.9, -0.4).normalize(),
            8f64.to_radians(),
        )),
        translation: DVec3::new(35.0, -20.0, 10.0),
    }
}

#[test]
fn a_scan_against_itself_moved_reads_zero_after_registration() {
    let reference = moved_phantom(&RigidTransform::IDENTITY);
    let test = moved_phantom(&motion());
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("deviation.ply");
    let options = CompareOptions {
        register: true,
        out: Some(out.clone()),
        ..CompareOptions::default()
    };
    let report = compare(&reference, &test, &options, &Silent).unwrap();

    // The registration finds the inverse motion: the landmarks fit exactly, ICP keeps it.
    let registration = report.registration.as_ref().unwrap();
    let found = RigidTransform::from_row_major(&registration.matrix);
    let (_, worst_mm) = common::registration_errors(&found, &motion().inverse(), &reference);
    assert!(worst_mm < 1e-6, "{worst_mm}");
    // The same surface on itself: nothing but round-off.
    assert!(
        report.rms_mm < 1e-6 && report.hausdorff_mm < 1e-6,
        "{report:?}"
    );
    let both = report.breast_regions.both.unwrap();
    assert!(both.rms_mm < 1e-6 && both.vertices > 1000);
    // Only the border vertices (closest point on the border) are outside the overlap.
    assert!(
        report.overlap_fraction > 0.97,
        "{}",
        report.overlap_fraction
    );
    for distance in &report.distances {
        let difference = distance.difference_mm.unwrap();
        assert!(difference.abs() < 1e-6, "{}: {difference}", distance.name);
    }
    let (reference_volumes, test_volumes) = (
        report.breast_volume_ml.reference.unwrap(),
        report.breast_volume_ml.test.unwrap(),
    );
    for (reference, test) in [
        (reference_volumes.left, test_volumes.left),
        (reference_volumes.right, test_volumes.right),
    ] {
        // Every step of the breast model works in the anatomical frame.
        assert!(
            (reference - test).abs() < 1e-6 * reference,
            "{reference} {test}"
        );
    }
    // The phantom is symmetric.
    let symmetry = report.symmetry.test.as_ref().unwrap();
    assert!((symmetry.volume_ratio_left_to_right - 1.0).abs() < 0.01);
    assert!(symmetry.nipple_distance_mm < 0.1);

    // The deviation mesh: the registered test scan, all green, distances zero or NaN
    // outside the overlap.
    let (mesh, scalars) = mesh::io::read_ply_with_scalars(
        &out,
        &["distance_mm", "signed_distance_mm", "asymmetry_mm"],
    )
    .unwrap();
    assert_eq!(mesh.vertex_count(), test.scan.mesh.vertex_count());
    for (p, q) in mesh.positions.iter().zip(&reference.scan.mesh.positions) {
        assert!(p.distance(*q) < 1e-6);
    }
    let inside = scalars[0].iter().filter(|d| !d.is_nan()).count();
    let expected = report.overlap_fraction * mesh.vertex_count() as f64;
    assert_eq!(inside, expected.round() as usize);
    let colors = mesh.vertex_colors.unwrap();
    for (distance, color) in scalars[0].iter().zip(&colors) {
        if distance.is_nan() {
            assert_eq!(*color, assess::OUTSIDE_OVERLAP_COLOR);
        } else {
            assert!(distance.abs() < 1e-6);
            assert_eq!(*color, [0, 255, 0]);
        }
    }
}

#[test]
fn scans_that_do_not_overlap_or_a_mesh_file_that_is_not_ply_are_errors() {
    let reference = moved_phantom(&RigidTransform::IDENTITY);
    let far = moved_phantom(&RigidTransform {
        rotation: DMat3::IDENTITY,
        translation: DVec3::new(0.0, 0.0, 1000.0),
    });
    let error = compare(&reference, &far, &CompareOptions::default(), &Silent).unwrap_err();
    let message = format!("{error:#}");
    assert!(message.contains("do not overlap"), "{message}");

    let options = CompareOptions {
        out: Some("deviation.obj".into()),
        ..CompareOptions::default()
    };
    let error = compare(&reference, &reference, &options, &Silent).unwrap_err();
    assert!(error.to_string().contains("give a .ply file"), "{error}");
}

#[test]
fn a_scan_whose_breast_model_fails_takes_the_other_scans_breast_regions() {
    let reference = moved_phantom(&RigidTransform::IDENTITY);
    let mut test = moved_phantom(&RigidTransform::IDENTITY);
    // The left fold's medial end on its lowest point: two control points coincide.
    let lowest = test.landmarks.get(anatomy::LandmarkName::PSMFl);
    test.landmarks.set(anatomy::LandmarkName::PSMFml, lowest);
    let report = compare(&reference, &test, &CompareOptions::default(), &Silent).unwrap();

    assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
    assert!(report.warnings[0].contains("the test scan has no breast model"));
    assert!(
        report.warnings[0].contains("left breast"),
        "{}",
        report.warnings[0]
    );
    assert!(report.breast_volume_ml.test.is_none() && report.symmetry.test.is_none());
    assert!(report.breast_volume_ml.reference.is_some() && report.symmetry.reference.is_some());
    let regions = report.breast_regions;
    assert_eq!(regions.source.test, plan::compare::RegionSource::OtherScan);
    // The same surface: the carried-over regions are the reference's, vertex for vertex.
    let both = regions.both.unwrap();
    let left = regions.left.unwrap();
    let right = regions.right.unwrap();
    assert_eq!(both.vertices, left.vertices + right.vertices);
    assert!(both.rms_mm < 1e-9 && report.rms_mm < 1e-9);
}
