//! Symmetry analysis on the phantom, whose mid-sagittal plane is exactly `x = 0` and
//! whose asymmetry is known: a symmetric torso must read as symmetric, and a torso with
//! one larger, lower breast must give its true volume ratio and nipple offset.

mod common;

use anatomy::{AnatomicalFrame, LandmarkName, Side};
use assess::{DEFAULT_MAX_DISTANCE_MM, Symmetry, SymmetryInput, Zone, analyse_symmetry};
use glam::DVec3;
use phantom::{Phantom, PhantomParams};

fn analyse(params: &PhantomParams) -> (Phantom, AnatomicalFrame, Symmetry) {
    let marked = common::marked_phantom(params);
    let symmetry = analyse_symmetry(
        &SymmetryInput {
            mesh: &marked.phantom.scan,
            index: &marked.index,
            topology: &marked.topology,
            landmarks: &marked.phantom.landmarks,
            frame: &marked.frame,
            breasts: &marked.breasts,
        },
        DEFAULT_MAX_DISTANCE_MM,
    )
    .unwrap();
    (marked.phantom, marked.frame, symmetry)
}

#[test]
fn a_symmetric_torso_is_its_own_mirror_image() {
    let (_, _, symmetry) = analyse(&PhantomParams::default());
    // The mirror is the reflection x -> -x (the phantom's midline is x = 0).
    let matrix = symmetry.mirror.to_row_major();
    let expected: [[f64; 4]; 3] = [
        [-1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
    ];
    for (row, expected_row) in matrix.iter().zip(expected) {
        for (value, expected) in row.iter().zip(expected_row) {
            // Rotation entries to 1e-3, translation to 0.05 mm: ICP stops within its
            // tolerance of the exact answer.
            assert!((value - expected).abs() < 0.05, "{matrix:?}");
        }
    }
    assert!(
        symmetry.matching_rms_mm < 0.1,
        "{}",
        symmetry.matching_rms_mm
    );
    // The breast model cuts the two sides' triangles differently, within 1% in volume.
    assert!((symmetry.volume_ratio_left_to_right() - 1.0).abs() < 0.01);
    assert!(symmetry.nipple_position_difference_mm.length() < 0.1);
    let breasts = symmetry.statistics.both_breasts.unwrap();
    let whole = symmetry.statistics.whole;
    eprintln!(
        "symmetric: rms {:.3} mm (breasts {:.3} mm), ratio {:.4}",
        whole.rms_mm,
        breasts.rms_mm,
        symmetry.volume_ratio_left_to_right()
    );
    // Only the triangulation differs between a side and the mirrored other side.
    assert!(whole.rms_mm < 0.1 && breasts.rms_mm < 0.1);
    assert!(symmetry.comparison.test_overlap_fraction() > 0.9);
}

#[test]
fn an_asymmetric_torso_gives_its_true_volume_ratio_and_nipple_offset() {
    let params = PhantomParams {
        asymmetry: 1.0,
        ..PhantomParams::default()
    };
    let (phantom, frame, symmetry) = analyse(&params);
    let truth = phantom.breast_volume_ml;
    let true_ratio = truth.left / truth.right;
    let ratio = symmetry.volume_ratio_left_to_right();
    // The nipple offset from the landmarks and the exact mirror x -> -x.
    let local = |name| frame.to_local(phantom.landmarks.get(name));
    let (left, right) = (local(LandmarkName::Pnl), local(LandmarkName::Pnr));
    let true_offset = left - DVec3::new(-right.x, right.y, right.z);
    eprintln!(
        "asymmetric: ratio {ratio:.4} (true {true_ratio:.4}), nipple offset {:.2} (true {true_offset:.2}) mm",
        symmetry.nipple_position_difference_mm
    );
    assert!((true_ratio - 1.0).abs() > 0.05, "the phantom is asymmetric");
    // Each breast volume is within about 2% of the truth (docs/user/model.md), with errors of the
    // same sign on both sides.
    assert!((ratio / true_ratio - 1.0).abs() < 0.02);
    // ICP away from the breasts finds the exact plane to a fraction of a millimetre.
    assert!(symmetry.nipple_position_difference_mm.distance(true_offset) < 0.5);
    assert!(symmetry.nipple_height_difference_mm().abs() > 3.0);

    // The larger breast lies in front of the mirrored smaller one, and vice versa.
    let (larger, smaller) = if truth.left > truth.right {
        (Side::Left, Side::Right)
    } else {
        (Side::Right, Side::Left)
    };
    let larger_statistics = symmetry
        .comparison
        .statistics(Zone::Breast(larger))
        .unwrap();
    let smaller_statistics = symmetry
        .comparison
        .statistics(Zone::Breast(smaller))
        .unwrap();
    eprintln!(
        "asymmetry map: larger breast signed mean {:.2} mm rms {:.2} mm, smaller {:.2} mm",
        larger_statistics.signed_mean_mm,
        larger_statistics.rms_mm,
        smaller_statistics.signed_mean_mm
    );
    assert!(larger_statistics.signed_mean_mm > 0.5);
    assert!(smaller_statistics.signed_mean_mm < -0.5);
    assert!(symmetry.statistics.both_breasts.unwrap().rms_mm > 1.0);
}
