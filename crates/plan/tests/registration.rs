//! Registration against known transforms on the phantom.

mod common;

use anatomy::register::RigidTransform;
use glam::{DMat3, DQuat, DVec3};
use plan::PhantomParams;

fn known_motion() -> RigidTransform {
    RigidTransform {
        rotation: DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(-0.3, 0.8, 0.5).normalize(),
            9f64.to_radians(),
        )),
        translation: DVec3::new(-40.0, 12.0, 25.0),
    }
}

#[test]
fn a_known_transform_is_recovered_on_noise_free_data() {
    let params = PhantomParams::default();
    let fixed = common::marked_phantom(&params, None);
    let motion = known_motion();
    let moving = common::marked_phantom(&params, Some(&motion));
    for icp in [false, true] {
        let (found, report) = plan::register::register(&fixed, &moving, icp).unwrap();
        let (degrees, worst_mm) = common::registration_errors(&found, &motion.inverse(), &fixed);
        // The issue asks for 0.05 degrees and 0.05 mm; noise-free input is recovered to
        // round-off (the ICP tolerance is 1e-4 mm per step).
        assert!(
            degrees < 0.05 && worst_mm < 0.05,
            "icp {icp}: {degrees} deg, {worst_mm} mm"
        );
        assert!(report.landmark_rms_mm < 1e-3);
    }
}

#[test]
fn icp_lowers_the_surface_rms_on_noisy_data_with_imprecise_landmarks() {
    let fixed = common::marked_phantom(
        &PhantomParams {
            noise_mm: 0.3,
            seed: 11,
            ..PhantomParams::default()
        },
        None,
    );
    let motion = known_motion();
    let mut moving = common::marked_phantom(
        &PhantomParams {
            noise_mm: 0.3,
            seed: 12,
            ..PhantomParams::default()
        },
        Some(&motion),
    );
    // Landmarks clicked a few millimetres off, as a user would.
    let offsets = [
        DVec3::new(2.0, -1.5, 0.5),
        DVec3::new(-1.0, 2.5, 0.0),
        DVec3::new(1.5, 1.0, -0.5),
        DVec3::new(-2.0, -2.0, 1.0),
    ];
    for (name, offset) in anatomy::register::BONY_LANDMARKS.iter().zip(offsets) {
        let moved = moving.landmarks.get(*name) + offset;
        moving.landmarks.set(*name, moved);
    }
    let (by_landmarks, before) = plan::register::register(&fixed, &moving, false).unwrap();
    let (by_icp, after) = plan::register::register(&fixed, &moving, true).unwrap();
    let truth = motion.inverse();
    let (_, worst_before) = common::registration_errors(&by_landmarks, &truth, &fixed);
    let (degrees, worst_after) = common::registration_errors(&by_icp, &truth, &fixed);
    eprintln!(
        "surface rms {:.3} -> {:.3} mm, worst error {worst_before:.2} -> {worst_after:.3} mm",
        before.surface_rms_mm, after.surface_rms_mm
    );
    assert!(after.surface_rms_mm < before.surface_rms_mm);
    // Two independent noise draws of 0.3 mm: the RMS distance cannot go below the noise
    // but stays near it (sqrt(2) x 0.3 mm is the point-to-point bound, point-to-surface
    // is lower).
    assert!(after.surface_rms_mm < 0.45, "{}", after.surface_rms_mm);
    assert!(
        degrees < 0.1 && worst_after < 0.3,
        "{degrees} deg, {worst_after} mm"
    );
}
