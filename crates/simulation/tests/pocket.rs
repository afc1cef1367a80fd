//! The pocket on the smallest phantom cup: an implant wider than the native breast's
//! base is laid in the pocket rather than refused, one moved across the midline gets the
//! error naming that limit, a lowered fold takes the default position down with it, the
//! default rule sets the implant's lower edge on the planned fold, and the ICE rule plans
//! the lowering.
//! Without a pocket (the paper's bed, the fill-in alone) the same implant is refused,
//! so the first check can fail.

mod common;

use anatomy::LandmarkName;
use anatomy::breast::Side;
use common::Patient;
use glam::DVec3;
use implant::{ImplantShape, RoundImplant};
use phantom::{Cup, PhantomParams};
use plan::model::{ModelOptions, build_model};
use plan::{MarkedScan, Silent};
use simulation::pocket::{FoldLowering, PocketLimits};
use simulation::{AnchorRule, Placement, SimulationError, SimulationOptions};
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
    // On the pocket's bed, wider than the fill-in's, and hardly moved sideways to fit.
    // The ICE rule asks for the 30 mm cap on this cup; the pocket ends above that (the
    // model's clip box), so the implant moves up and the fold follows its lower edge.
    let shift = placed.fit_shift_mm;
    println!(
        "fit shift {shift:?} mm, fold lowered {:.1} mm",
        placed.fold_lowering_mm
    );
    assert!(shift.x.abs() < 10.0, "moved {shift:?} mm to fit");
    assert!((0.0..30.0).contains(&placed.fold_lowering_mm));
    assert!(session.bed(Side::Left).area_mm2() > 1.2 * fill_area);
}

#[test]
fn an_implant_moved_across_the_midline_names_the_limit() {
    let mut session = small_cup().session(SimulationOptions::default());
    // 45 mm towards the patient's right from below the nipple: the 135 mm implant's
    // medial edge then lies 30-60 mm past the 15 mm band either side of the midline (the
    // error names the outline point furthest off the pocket, placed on the chest's
    // cylinder, not the most medial one).
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
            assert!((30.0..60.0).contains(&beyond_mm), "{beyond_mm}");
        }
        other => panic!("{other}"),
    }
}

/// The anchor and the lowest point of the footprint (standing frame, mm) of a
/// R-MOD-100 on the left with the fold lowered by `lowering_mm` under `rule`.
fn placed_with_lowering(rule: AnchorRule, lowering_mm: f64) -> (DVec3, f64) {
    let patient = small_cup();
    let limits = PocketLimits {
        fold_lowering: FoldLowering::Mm(lowering_mm),
        ..PocketLimits::default()
    };
    let mut session = patient.session(SimulationOptions {
        anchor_rule: rule,
        pocket: Some([limits; 2]),
        ..SimulationOptions::default()
    });
    let implant = *implant::Catalog::builtin()
        .get("R-MOD-100")
        .unwrap()
        .shape();
    let placed = session
        .set_implant(Side::Left, implant, Placement::default())
        .unwrap()
        .clone();
    assert_eq!(placed.fold_lowering_mm, lowering_mm);
    let lowest_mm = lowest_edge_mm(&session, &placed);
    (patient.frame().to_local(placed.anchor.position), lowest_mm)
}

/// The lowest point of a left implant's footprint on its bed (standing frame, mm), from
/// 90 outline points.
fn lowest_edge_mm(session: &simulation::Simulation, placed: &simulation::PlacedImplant) -> f64 {
    let bed = session.bed(Side::Left);
    (placed.shape.footprint_outline_mm(90).into_iter())
        .filter_map(|local| bed.at(placed.anchor.uv_of(local)))
        .map(|at| small_cup().frame().to_local(at.position).y)
        .fold(f64::INFINITY, f64::min)
}

#[test]
fn a_lowered_fold_takes_the_default_position_down() {
    let (native, _) = placed_with_lowering(AnchorRule::FootprintCentre, 0.0);
    let (lowered, _) = placed_with_lowering(AnchorRule::FootprintCentre, 10.0);
    // Walked 10 mm down the bed, which leans back a little under the breast: 7-10 mm
    // lower in the standing frame (asked of the simulated fold: 7-13 mm).
    let down_mm = native.y - lowered.y;
    assert!((7.0..=10.5).contains(&down_mm), "{down_mm}");
}

/// The default rule puts the implant's lower edge on the planned fold: the native
/// fold's lowest point (the landmark) less the lowering, within the footprint's
/// tolerance on the bed's edge (2 mm) plus the outline's sampling (0.1 mm).
#[test]
fn on_the_fold_the_lower_edge_lies_on_the_planned_fold() {
    let patient = small_cup();
    let fold_y = patient
        .frame()
        .to_local(patient.marked.landmarks.get(LandmarkName::PSMFl))
        .y;
    for lowering_mm in [0.0, 10.0] {
        let (_, lowest_mm) = placed_with_lowering(AnchorRule::OnFold, lowering_mm);
        let planned_mm = fold_y - lowering_mm;
        assert!(
            (lowest_mm - planned_mm).abs() <= 2.1,
            "lowered {lowering_mm}: lower edge at {lowest_mm:.1}, planned fold {planned_mm:.1}"
        );
    }
}

/// Without a given lowering the fold is lowered by the ICE rule (half the height plus
/// the projection, less the nipple-to-fold distance), computed here from the landmarks.
#[test]
fn the_ice_rule_plans_the_lowering_for_the_implant() {
    let patient = small_cup();
    let landmarks = &patient.marked.landmarks;
    let capacity_mm = landmarks
        .get(LandmarkName::Pnl)
        .distance(landmarks.get(LandmarkName::PSMFl));
    let implant = *implant::Catalog::builtin()
        .get("R-MOD-115")
        .unwrap()
        .shape();
    let expected_mm = (57.5 + implant.projection_mm() - capacity_mm).clamp(0.0, 30.0);
    let session = patient.session(SimulationOptions::default());
    let planned_mm = session.fold_lowering_mm(Side::Left, &implant);
    assert!(
        (planned_mm - expected_mm).abs() < 1e-9,
        "{planned_mm} vs {expected_mm}"
    );
    assert!(
        planned_mm > 0.0,
        "the smallest cup has no room for a 115 mm implant"
    );
}

/// An implant's own fold lowering overrides the side's rule (the GUI's and a planning
/// case's per-implant choice): the lower edge lies on the fold it asks for, within the
/// footprint's tolerance (2 mm) plus the outline's sampling; deeper than the pocket was
/// built (30 mm for the ICE rule) is refused with the error naming the value.
#[test]
fn an_implant_carries_its_own_fold_lowering() {
    let patient = small_cup();
    let fold_y = patient
        .frame()
        .to_local(patient.marked.landmarks.get(LandmarkName::PSMFl))
        .y;
    let mut session = patient.session(SimulationOptions::default());
    let implant = *implant::Catalog::builtin()
        .get("R-MOD-100")
        .unwrap()
        .shape();
    let own = |mm: f64| Placement {
        fold_lowering_mm: Some(mm),
        ..Placement::default()
    };
    let placed = session
        .set_implant(Side::Left, implant, own(12.0))
        .unwrap()
        .clone();
    assert_eq!(placed.fold_lowering_mm, 12.0);
    let lowest_mm = lowest_edge_mm(&session, &placed);
    assert!(
        (lowest_mm - (fold_y - 12.0)).abs() <= 2.1,
        "lower edge {lowest_mm:.1}, planned fold {:.1}",
        fold_y - 12.0
    );
    match session.set_implant(Side::Left, implant, own(31.0)) {
        Err(SimulationError::BadPlacement { what, value, .. }) => {
            assert_eq!((what, value), ("fold lowering (mm)", 31.0));
        }
        other => panic!("{other:?}"),
    }
}
