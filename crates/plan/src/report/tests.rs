//! Tests of the report's own helpers.

use super::*;
use glam::{DMat3, DQuat};
use std::time::Duration;

#[test]
fn dates_match_the_calendar() {
    // Seconds since 1970 of known UTC times (computed with Python's datetime).
    let at = |seconds| utc_date_time(UNIX_EPOCH + Duration::from_secs(seconds));
    assert_eq!(at(0), "1970-01-01 00:00 UTC");
    assert_eq!(at(951_782_400), "2000-02-29 00:00 UTC");
    assert_eq!(at(951_868_799), "2000-02-29 23:59 UTC");
    assert_eq!(at(1_767_225_599), "2025-12-31 23:59 UTC");
    assert_eq!(at(4_107_542_400), "2100-03-01 00:00 UTC");
    assert_eq!(at(1_795_339_260), "2026-11-22 09:21 UTC");
}

#[test]
fn nipple_symmetry_follows_the_frame_not_the_file() {
    // Landmarks built in the anatomical frame (x left, y up, z forwards, Pj at the
    // origin), then moved rigidly: the figures come from the local positions.
    let local = |name| match name {
        LandmarkName::Pj => DVec3::ZERO,
        LandmarkName::Px => DVec3::new(0.0, -180.0, 0.0),
        LandmarkName::Pcl => DVec3::new(80.0, -10.0, -5.0),
        LandmarkName::Pcr => DVec3::new(-80.0, -10.0, -5.0),
        LandmarkName::Pnl => DVec3::new(95.0, -180.0, 80.0),
        LandmarkName::Pnr => DVec3::new(-90.0, -185.0, 78.0),
        _ => DVec3::new(0.0, -200.0, 50.0),
    };
    let turn = DQuat::from_axis_angle(DVec3::new(0.3, 1.0, -0.2).normalize(), 0.7);
    let rotation = DMat3::from_quat(turn);
    let shift = DVec3::new(12.0, 900.0, -40.0);
    let landmarks = Landmarks::new(|name| rotation * local(name) + shift);
    let up = Up::FILE_VERTICAL.rotated(turn);
    let frame = AnatomicalFrame::from_landmarks(&landmarks, up).unwrap();
    let nipples = NippleSymmetry::new(&frame, &landmarks);
    // Left 5 mm higher, 5 mm further from the midline, 2 mm further forward.
    let tolerance_mm = 1e-9; // round-off of a rigid motion of ~1 m coordinates
    assert!((nipples.height_difference_mm - 5.0).abs() < tolerance_mm);
    assert!((nipples.midline_difference_mm - 5.0).abs() < tolerance_mm);
    let expected = (5f64 * 5.0 + 5.0 * 5.0 + 2.0 * 2.0).sqrt();
    assert!((nipples.mirror_distance_mm - expected).abs() < tolerance_mm);
}
