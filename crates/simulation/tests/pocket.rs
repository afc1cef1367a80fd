//! The pocket on the smallest phantom cup: an implant wider than the native breast's
//! base is laid in the pocket rather than refused, one moved across the midline gets the
//! error naming that limit, and a lowered fold takes the default position down with it.
//! Without a pocket (the paper's bed, the fill-in alone) the same implant is refused,
//! so the first check can fail.

mod common;

use anatomy::breast::Side;
use common::Patient;
use implant::{ImplantShape, RoundImplant};
use phantom::{Cup, PhantomParams};
use plan::model::{ModelOptions, build_model};
use plan::{MarkedScan, Silent};
use simulation::pocket::PocketLimits;
use simulation::{Placement, SimulationError, SimulationOptions};
use std::sync::OnceLock;

/// Coarse enough to stay quick: the placement does not depend on the elements.
const ELEMENTS: usize = 8_000;

fn small_cup() -> &'static Patient {
    static PATIENT: OnceLock<Patient> = OnceLock::new();
    PATIENT.get_or_init(|| {
        let marked = MarkedScan::phantom(&PhantomParams {
            cup: Cup::Small,
            ..PhantomParams::default()
        })
        .unwrap();
        let options = ModelOptions {
            elements: ELEMENTS,
            ..Default::default()
        };
        let model = build_model(&marked, &options, &Silent).unwrap();
        Patient { marked, model }
    })
}

/// A 135 mm round implant, 40 mm projection (about 380 ml).
fn wide_implant() -> ImplantShape {
    ImplantShape::Round(RoundImplant::new(135.0, 40.0).unwrap())
}

#[test]
fn a_135_mm_implant_on_the_smallest_cup_lies_in_the_pocket() {
    let patient = small_cup();
    let without_pocket = SimulationOptions {
        pocket: None,
        ..SimulationOptions::default()
    };
    let mut paper = patient.session(without_pocket);
    let refused = paper.set_implant(Side::Left, wide_implant(), Placement::default());
    assert!(
        matches!(
            refused,
            Err(SimulationError::ImplantLargerThanFootprint { .. })
        ),
        "{:?}",
        refused.map(|placed| placed.fit_shift_mm)
    );
    let mut session = patient.session(SimulationOptions::default());
    let fill_area = session.bed(Side::Left).area_mm2();
    let placed = session
        .set_implant(Side::Left, wide_implant(), Placement::default())
        .unwrap();
    // On the pocket's bed, wider than the fill-in's, and hardly moved to fit.
    let shift_mm = placed.fit_shift_mm.length();
    assert!(shift_mm < 10.0, "moved {shift_mm:.1} mm to fit");
    assert!(session.bed(Side::Left).area_mm2() > 1.2 * fill_area);
}

#[test]
fn an_implant_moved_across_the_midline_names_the_limit() {
    let mut session = small_cup().session(SimulationOptions::default());
    // 45 mm towards the patient's right: the 135 mm implant's medial edge then lies
    // about 35 mm past the 15 mm band either side of the midline.
    let error = session
        .set_implant(
            Side::Left,
            wide_implant(),
            Placement::moved(-45.0, 0.0, 0.0),
        )
        .unwrap_err();
    match error {
        SimulationError::PocketLimit {
            side,
            limit,
            beyond_mm,
        } => {
            assert_eq!(side, Side::Left);
            assert_eq!(limit, "the sternal midline region");
            assert!((20.0..50.0).contains(&beyond_mm), "{beyond_mm}");
        }
        other => panic!("{other}"),
    }
}

#[test]
fn a_lowered_fold_takes_the_default_position_down() {
    let patient = small_cup();
    let lowered = |lowering_mm: f64| {
        let limits = PocketLimits {
            fold_lowering_mm: lowering_mm,
            ..PocketLimits::default()
        };
        let mut session = patient.session(SimulationOptions {
            pocket: Some([limits; 2]),
            ..SimulationOptions::default()
        });
        let implant = *implant::Catalog::builtin()
            .get("R-MOD-100")
            .unwrap()
            .shape();
        let placed = session
            .set_implant(Side::Left, implant, Placement::default())
            .unwrap();
        patient.frame().to_local(placed.anchor.position)
    };
    let (native, lowered) = (lowered(0.0), lowered(10.0));
    // Walked 10 mm down the bed, which leans back a little under the breast: 7-10 mm
    // lower in the standing frame (asked of the simulated fold: 7-13 mm).
    let down_mm = native.y - lowered.y;
    assert!((7.0..=10.5).contains(&down_mm), "{down_mm}");
}
