//! Planning in the window, driven like a user would with egui_kittest (widgets found by
//! their labels): building the model, an implant slider changing the simulated scan, the
//! move buttons, and a planning case saved and reopened. The phantom with a small model
//! (6,000 elements) keeps each build to seconds; the workers run for real, so the tests
//! step frames until the window shows their answers.

use anatomy::breast::Side;
use eframe::egui::{self, accesskit::Role};
use egui_kittest::Harness;
use egui_kittest::kittest::Queryable;
use glam::DVec3;
use gui::GuiApp;
use plan::simulate::SolveState;
use plan::{MarkedScan, PhantomParams};
use std::time::{Duration, Instant};

mod common;
use common::{click_at, drag, screen_position};

const ELEMENTS: f64 = 6_000.0;
/// Longest a build or a solve may take here (2 cores shared with other work).
const PATIENCE: Duration = Duration::from_secs(600);

fn harness() -> Harness<'static, GuiApp> {
    // Tall enough that both side panels show all their widgets without scrolling.
    Harness::builder()
        .with_size(egui::vec2(1500.0, 1500.0))
        .build_ui_state(|ui, app: &mut GuiApp| app.show(ui), GuiApp::new(None, None))
}

/// Steps frames until `done` holds.
fn wait_until(harness: &mut Harness<'_, GuiApp>, what: &str, done: impl Fn(&GuiApp) -> bool) {
    let start = Instant::now();
    loop {
        harness.step();
        if done(harness.state()) {
            break;
        }
        if let Some(error) = harness.state().error() {
            panic!("waiting for {what}: {error}");
        }
        assert!(
            start.elapsed() < PATIENCE,
            "no {what} after {PATIENCE:?}; the simulation: {:?}",
            harness.state().live().map(|live| (
                live.is_settled(),
                live.solver,
                live.failure.clone(),
                live.frames_received
            ))
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    for _ in 0..3 {
        harness.step();
    }
}

fn click(harness: &mut Harness<'_, GuiApp>, label: &str) {
    harness.get_by_label(label).click();
    harness.step();
    harness.step();
}

fn set_slider(harness: &mut Harness<'_, GuiApp>, label: &str, value: f64) {
    harness
        .get_by_role_and_label(Role::Slider, label)
        .set_value_accesskit(value);
    harness.step();
    harness.step();
}

/// Whether the simulation has applied the implants asked for and converged.
fn settled(app: &GuiApp) -> bool {
    app.live().is_some_and(|live| {
        live.is_settled()
            && live
                .solver
                .is_some_and(|s| s.advance.state == SolveState::Converged)
    })
}

/// The phantom opened from the File menu, its model built with the Elements slider at
/// [`ELEMENTS`].
fn with_model() -> Harness<'static, GuiApp> {
    let mut harness = harness();
    harness.step();
    click(&mut harness, "File");
    click(&mut harness, "Phantom with its landmarks");
    set_slider(&mut harness, "Elements", ELEMENTS);
    click(&mut harness, "Build model");
    assert!(harness.state().is_building());
    wait_until(&mut harness, "a model", |app| app.model().is_some());
    harness
}

/// The phantom with its model and the default implant on both sides, converged.
fn with_implants() -> Harness<'static, GuiApp> {
    let mut harness = with_model();
    click(&mut harness, "Implants on both sides");
    wait_until(&mut harness, "a converged simulation", settled);
    harness
}

fn positions(app: &GuiApp) -> Vec<DVec3> {
    app.live()
        .and_then(|live| live.frame.as_ref())
        .map(|frame| frame.positions.to_vec())
        .expect("a simulated frame")
}

/// Whether the settled prediction's deviation map is there for the latest frame.
fn deviation_ready(app: &GuiApp) -> bool {
    app.live().is_some_and(|live| {
        live.is_settled()
            && live.frame.is_some()
            && live.settled.as_ref().map(|s| s.frame) == live.frame.as_ref().map(|f| f.number)
    })
}

fn deviation(app: &GuiApp) -> &gui::deviation::DeviationMap {
    let settled = app.live().unwrap().settled.as_ref().unwrap();
    settled.deviation.as_ref().expect("a deviation map")
}

fn anchor(app: &GuiApp, side: Side) -> DVec3 {
    let placed = app.live().unwrap().sides.get(side).placed.as_ref().unwrap();
    DVec3::from_array(placed.anchor_mm)
}

#[test]
fn building_the_model_shows_its_volumes_and_can_be_cancelled() {
    let mut harness = with_model();
    let app = harness.state();
    assert!(!app.is_building());
    let model = app.model().unwrap();
    // About the requested size (isosurface stuffing: within about 20%).
    assert!(
        (model.elements as f64 - ELEMENTS).abs() < 0.25 * ELEMENTS,
        "{} elements",
        model.elements
    );
    // Independent answer: the phantom's true breast volumes (integrated from its
    // analytic shape); the model's cut curves enclose them within 10%.
    let truth = phantom::generate(&PhantomParams::default()).breast_volume_ml;
    for (side, expected) in [(Side::Left, truth.left), (Side::Right, truth.right)] {
        let built = *model.breast_volume_ml.get(side);
        assert!(
            (built - expected).abs() < 0.1 * expected,
            "{side}: {built} ml vs {expected} ml"
        );
        let quadrants = model.quadrant_volume_ml.get(side);
        assert!((quadrants.total() - built).abs() < 1e-6 * built);
        assert!(model.cut_curves.get(side).len() > 20);
    }
    harness.get_by_label("Rebuild model");
    harness.get_by_label_contains("levels, built in");
    assert_eq!(app.display(), gui::app::DisplayMode::Simulated);

    // A rebuild cancelled at once stops after its first stage; the old model stays.
    click(&mut harness, "Rebuild model");
    click(&mut harness, "Cancel");
    wait_until(&mut harness, "the end of the build", |app| {
        !app.is_building()
    });
    harness.get_by_label("model building cancelled");
    assert!(harness.state().model().is_some());
}

#[test]
fn an_implant_slider_changes_the_simulated_scan() {
    let mut harness = with_implants();
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let frame = marked.frame;
    let notch = marked.landmarks.get(anatomy::LandmarkName::Pj);
    let nearest = |p: DVec3| {
        (0..marked.scan.mesh.vertex_count())
            .min_by(|&a, &b| {
                let d = |v: usize| marked.scan.mesh.positions[v].distance(p);
                d(a).total_cmp(&d(b))
            })
            .unwrap()
    };
    let notch = nearest(notch);
    let before = positions(harness.state());

    // The same implant as custom dimensions, then a larger projection.
    click(&mut harness, "Custom size");
    set_slider(&mut harness, "Projection (mm)", 45.0);
    // Eq. 2's half ellipsoid: π 120² 45 / 6 mm³.
    harness.get_by_label_contains("Volume 339.3 ml");
    wait_until(&mut harness, "a converged simulation", settled);
    let placed = harness
        .state()
        .live()
        .unwrap()
        .sides
        .left
        .placed
        .clone()
        .unwrap();
    assert_eq!(placed.spec, "round:diameter=120,projection=45");
    let after = positions(harness.state());

    // 11.5 mm more projection (33.5 -> 45): the implant's apex pushes the tissue in front
    // of it forward by about half of that (the nipple rode forward 0.51 x projection at
    // 60,000 elements); at least 3 mm here, well beyond the solver's tolerance (a
    // relative residual of 1e-3 leaves differences of a few hundredths of a mm). Not
    // necessarily at the nipple: the ICE rule lowers the fold, and the implant with it,
    // by the added projection.
    let forward = (after.iter().zip(&before))
        .map(|(a, b)| (*a - *b).dot(frame.anterior()))
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(forward > 3.0, "the skin moved at most {forward} mm forward");
    // Far from the breasts, nothing moves (the sternal notch is outside the model).
    let notch_moved = after[notch].distance(before[notch]);
    assert!(notch_moved < 0.05, "the notch moved {notch_moved} mm");

    // The measurements of the prediction: the breasts grew, by less than the implants.
    click(&mut harness, "Measure prediction");
    wait_until(&mut harness, "the measurements", |app| {
        matches!(
            app.live().unwrap().measurements,
            gui::live_simulation::MeasurementState::Measured(..)
        )
    });
    let live = harness.state().live().unwrap();
    let gui::live_simulation::MeasurementState::Measured(measured, _) = &live.measurements else {
        unreachable!()
    };
    assert_eq!(measured.distances.len(), 11);
    for side in Side::BOTH {
        let added =
            measured.breast_volume_ml.get(side) - measured.breast_volume_before_ml.get(side);
        let implant = *measured.implant_volume_ml.get(side);
        assert!(
            added > 0.3 * implant && added < implant,
            "{side}: +{added} ml, implant {implant} ml"
        );
        // The simulated quadrants partition the simulated breast (round-off).
        let quadrants = measured.quadrant_volume_ml.get(side).unwrap();
        let after = *measured.breast_volume_ml.get(side);
        assert!((quadrants.total() - after).abs() < 1e-6 * after);
    }
    // The upper and lower halves, before and simulated, are in the panel.
    harness.run();
    harness.get_by_label("left upper half (ml)");
    harness.get_by_label("right lower half (ml)");
}

#[test]
fn the_move_buttons_move_the_implants_by_the_step_in_the_anatomical_frame() {
    let mut harness = with_implants();
    let frame = MarkedScan::phantom(&PhantomParams::default())
        .unwrap()
        .frame;
    let start = [
        anchor(harness.state(), Side::Left),
        anchor(harness.state(), Side::Right),
    ];

    click(&mut harness, "Move up");
    wait_until(&mut harness, "the moved implants", settled);
    let app = harness.state();
    let live = app.live().unwrap();
    for (k, side) in Side::BOTH.into_iter().enumerate() {
        let placed = live.sides.get(side).placed.as_ref().unwrap();
        // Known answer: one step of 5 mm up, on both sides (linked).
        assert_eq!(placed.move_mm, [0.0, 5.0, 0.0]);
        assert_eq!(placed.fit_shift_mm, [0.0, 0.0]);
        // The anchor walks 5 mm along the curved bed (a chord of at most 5 mm) in the
        // direction of "up" projected onto the bed, which leans back with the chest
        // wall: within 30% of the step of a straight 5 mm step up (a lean of up to 17°),
        // and at least 4.5 mm of it upwards.
        let moved = DVec3::from_array(placed.anchor_mm) - start[k];
        assert!(moved.length() <= 5.0 + 1e-6, "{side}: {moved}");
        assert!(
            (moved - 5.0 * frame.up()).length() < 0.3 * 5.0,
            "{side}: moved {moved}, up is {}",
            frame.up()
        );
        assert!(moved.dot(frame.up()) > 4.5, "{side}: {moved}");
    }

    // The patient's left: the left implant goes laterally, the right one (mirrored)
    // too, to the patient's right; the arrow key towards screen right does the same.
    let start = [anchor(app, Side::Left), anchor(app, Side::Right)];
    click(&mut harness, "Move left");
    harness.key_press(egui::Key::ArrowRight);
    wait_until(&mut harness, "the moved implants", settled);
    let app = harness.state();
    let left = anchor(app, Side::Left) - start[0];
    let right = anchor(app, Side::Right) - start[1];
    let live = app.live().unwrap();
    assert_eq!(
        live.sides.left.placed.as_ref().unwrap().move_mm,
        [10.0, 5.0, 0.0]
    );
    assert_eq!(
        live.sides.right.placed.as_ref().unwrap().move_mm,
        [-10.0, 5.0, 0.0]
    );
    // The placement keeps each implant inside the breast's footprint, which may hold
    // part of a 10 mm move back: 7.6 mm laterally on this phantom (since 2026-11-26, when
    // the fold's control points became the nearest surface points).
    assert!(left.dot(frame.left()) > 6.0, "{left}");
    assert!(right.dot(frame.left()) < -6.0, "{right}");
}

#[test]
fn a_saved_case_reopens_with_the_same_state() {
    let mut harness = with_implants();
    click(&mut harness, "Left breast");
    click(&mut harness, "Move down");
    set_slider(&mut harness, "Rotation (°)", 10.0);
    wait_until(&mut harness, "a converged simulation", settled);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plan.json");
    type_path(&mut harness, &path.display().to_string());
    click(&mut harness, "Save case");
    assert!(harness.state().error().is_none());
    let saved = harness.state().case().unwrap();
    assert!(!saved.linked);
    assert_eq!(
        saved.implants.left.as_ref().unwrap().move_mm,
        DVec3::new(0.0, -5.0, 0.0)
    );
    assert!(saved.control_points.is_some());
    let before = positions(harness.state());

    let mut reopened = harness_with_case(&path);
    wait_until(&mut reopened, "a converged simulation", settled);
    let app = reopened.state();
    // The same case: scan, landmarks, control points, settings and implants, bit for bit.
    assert_eq!(app.case().unwrap(), saved);
    assert_eq!(app.implants(), harness.state().implants());
    let after = positions(app);
    // Rebuilt from the same control points and settings, solved from scratch instead of
    // from the previous positions: both within the solver's tolerance (relative residual
    // 1e-3) of the same equilibrium, a few hundredths of a millimetre apart.
    let largest_mm = before
        .iter()
        .zip(&after)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    assert!(largest_mm < 0.3, "{largest_mm} mm");
}

#[test]
fn the_deviation_view_colours_the_prediction_by_its_distance_from_the_scan() {
    let mut harness = with_model();
    // No implant yet: the prediction is the scan itself, at distance zero wherever it
    // lies over itself (all but the border, whose closest points are on the border).
    click(&mut harness, "Deviation");
    wait_until(&mut harness, "the deviation map", deviation_ready);
    let map = deviation(harness.state());
    assert!(map.distances_mm.iter().all(|d| d.is_nan() || *d < 1e-6));
    assert!(map.overlap_fraction > 0.95, "{}", map.overlap_fraction);
    harness.get_by_label_contains("Deviation from the pre-operative surface: RMS 0.00 mm");

    click(&mut harness, "Implants on both sides");
    wait_until(&mut harness, "the deviation map", deviation_ready);
    let app = harness.state();
    let map = deviation(app);
    let scan = &app.document().unwrap().scan.mesh;
    let positions = positions(app);
    // Independent check: the distance of every 500th simulated vertex to the
    // pre-operative scan by testing every triangle (Ericson's closest point); the BVH
    // answers the same to rounding.
    let mut compared = 0;
    for v in (0..scan.vertex_count()).step_by(500) {
        let mapped = map.distances_mm[v];
        if mapped.is_nan() {
            continue;
        }
        let brute = (0..scan.triangle_count())
            .map(|t| {
                let corners = scan.triangle_positions(t);
                tetra::locate::closest_point_on_triangle(positions[v], corners)
                    .distance(positions[v])
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            (mapped - brute).abs() < 1e-6,
            "vertex {v}: {mapped} vs {brute}"
        );
        compared += 1;
    }
    assert!(compared > 200, "{compared}");
    // The implants pushed the breasts forward: centimetres at the nipples, nothing at
    // the sternal notch (outside the model).
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let nearest = |p: DVec3| {
        (0..scan.vertex_count())
            .min_by(|&a, &b| {
                scan.positions[a]
                    .distance(p)
                    .total_cmp(&scan.positions[b].distance(p))
            })
            .unwrap()
    };
    let nipple = map.distances_mm[nearest(marked.landmarks.get(anatomy::LandmarkName::Pnl))];
    let notch = map.distances_mm[nearest(marked.landmarks.get(anatomy::LandmarkName::Pj))];
    assert!(nipple > 10.0, "{nipple} mm at the nipple");
    assert!(notch < 0.05, "{notch} mm at the notch");
    assert!(map.statistics.rms_mm > 1.0);
}

#[test]
fn the_report_is_written_from_the_window() {
    let mut harness = with_implants();
    let dir = tempfile::tempdir().unwrap();
    let folder = dir.path().join("plan");
    harness
        .get_by_role_and_label(Role::TextInput, "Folder")
        .focus();
    harness.step();
    harness
        .get_by_role_and_label(Role::TextInput, "Folder")
        .type_text(&folder.display().to_string());
    harness.step();
    click(&mut harness, "Write report");
    assert!(harness.state().live().unwrap().is_writing_report());
    wait_until(&mut harness, "the report", |app| {
        !app.live().unwrap().is_writing_report()
    });
    let live = harness.state().live().unwrap();
    let gui::live_simulation::ReportState::Written(written) = &live.report else {
        panic!("no report");
    };
    let summary = written.as_ref().expect("the report");
    assert_eq!(summary.out, folder.join("report.html"));
    // Without a post-operative scan: the pre-operative and the simulated scan from five
    // sides each, and the change from the front and the obliques.
    assert_eq!(summary.views, 13);
    harness.get_by_label_contains("Report written:");
    let page = std::fs::read_to_string(folder.join("report.html")).unwrap();
    assert!(page.contains("Breast augmentation plan"));
    // The folders it was made from: the phantom's scan (it has no file), the landmarks,
    // the model and the simulation with the implants as placed in the window.
    for file in [
        "scan.ply",
        "landmarks.json",
        "model/model.json",
        "simulation/result.json",
    ] {
        assert!(folder.join(file).is_file(), "{file}");
    }
    let result: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(folder.join("simulation/result.json")).unwrap(),
    )
    .unwrap();
    for side in Side::BOTH {
        let placed = live.sides.get(side).placed.as_ref().unwrap();
        let recorded = &result["implants"][side.name()];
        assert_eq!(recorded["spec"], placed.spec.as_str());
        assert_eq!(recorded["volume_ml"], placed.volume_ml);
        assert!(page.contains(&placed.spec), "{}", placed.spec);
    }
    assert_eq!(result["solver"]["converged"], true);

    // A folder that cannot be made: the panel says why, the window goes on.
    harness
        .get_by_role_and_label(Role::TextInput, "Folder")
        .focus();
    harness.step();
    harness.key_press_modifiers(egui::Modifiers::COMMAND, egui::Key::A);
    harness
        .get_by_role_and_label(Role::TextInput, "Folder")
        .type_text("/proc/mammaplan-report");
    harness.step();
    click(&mut harness, "Write report");
    wait_until(&mut harness, "the failed report", |app| {
        !app.live().unwrap().is_writing_report()
    });
    harness.get_by_label_contains("The report failed: writing the report's files into /proc");
}

#[test]
fn control_points_are_dragged_and_inserted_on_the_surface_and_the_rebuild_cuts_along_them() {
    let mut harness = with_model();
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let scan = &marked.scan;
    let volume_before = harness.state().model().unwrap().breast_volume_ml;
    let points = harness.state().settings().control_points.clone().unwrap();
    // The defaults: PSMFm, PSMF, PSMFl, a lateral, the upper and a medial point.
    assert_eq!((points.left.len(), points.right.len()), (6, 6));
    harness.get_by_label_contains("Control points: 6 left, 6 right");
    // They are edited on the scan as loaded (the build showed the simulated one).
    click(&mut harness, "Pre-operative");

    // Drag the left upper point up the screen by what 15 mm up would be.
    let upper = points.left[4];
    let (from, _, _) = screen_position(harness.state(), upper);
    let (to, _, _) = screen_position(harness.state(), upper + 15.0 * marked.frame.up());
    drag(&mut harness, from, to);
    let moved = harness
        .state()
        .settings()
        .control_points
        .as_ref()
        .unwrap()
        .left[4];
    assert!(
        scan.index.closest_point(moved).distance < 1e-6,
        "{moved} off the surface"
    );
    // The surface there leans back towards the clavicle, so the point lands within a few
    // mm of 15 mm from where it was, and higher.
    let distance = moved.distance(upper);
    assert!((distance - 15.0).abs() < 4.0, "moved {distance} mm");
    assert!((moved - upper).dot(marked.frame.up()) > 10.0, "{moved}");
    harness.get_by_label_contains("The control points changed since the model was built");

    // Insert a point halfway between the (moved) upper and the medial point.
    click(&mut harness, "Insert point");
    let edited = harness.state().settings().control_points.clone().unwrap();
    let spline = anatomy::breast::ClosedSpline::through(&edited.left).unwrap();
    let between = scan.index.closest_point(spline.evaluate(4, 0.5)).point;
    let (at, _, _) = screen_position(harness.state(), between);
    click_at(&mut harness, at);
    let edited = harness.state().settings().control_points.clone().unwrap();
    assert_eq!((edited.left.len(), edited.right.len()), (7, 6));
    let inserted = edited.left[5];
    assert!(inserted.distance(between) < 1.0, "{inserted} vs {between}");
    assert_eq!(edited.left[4], moved);

    // The rebuild cuts along them: its left curve passes through both points (to the
    // snapping of the cut onto scan vertices, a fraction of a triangle), and the left
    // breast holds more with its upper border moved up.
    click(&mut harness, "Rebuild model");
    assert!(harness.state().is_building());
    wait_until(&mut harness, "the rebuilt model", |app| !app.is_building());
    let app = harness.state();
    let model = app.model().unwrap();
    for point in [moved, inserted] {
        let nearest = (model.cut_curves.left.iter())
            .map(|p| p.distance(point))
            .fold(f64::INFINITY, f64::min);
        assert!(nearest < 1.5, "the curve passes {nearest} mm from {point}");
    }
    // (Little more: the chest above the breast is a thin layer over the fill-in.) The
    // right side, its points unchanged, is cut as before (the first build's points as
    // derived, the rebuild's as snapped onto the scan: a tenth of a millilitre apart).
    assert!(
        model.breast_volume_ml.left > volume_before.left + 0.5,
        "{} ml, before {} ml",
        model.breast_volume_ml.left,
        volume_before.left
    );
    assert!((model.breast_volume_ml.right - volume_before.right).abs() < 0.5);
    // The planning case holds the edited points.
    assert_eq!(app.case().unwrap().control_points.unwrap().left.len(), 7);

    // Remove point, then a click on the inserted point: it goes, the others stay.
    click(&mut harness, "Pre-operative");
    click(&mut harness, "Remove point");
    let (at, _, _) = screen_position(harness.state(), inserted);
    click_at(&mut harness, at);
    let edited = harness.state().settings().control_points.clone().unwrap();
    assert_eq!(edited.left.len(), 6);
    assert!(!edited.left.contains(&inserted));
    assert_eq!(edited.left[4], moved);
    harness.get_by_label_contains("The control points changed since the model was built");
}

#[test]
fn landmarks_cut_curves_and_implant_outlines_are_drawn_on_the_shown_surface() {
    let mut harness = with_implants();
    click(&mut harness, "Show implant and pocket outlines");
    wait_until(&mut harness, "the prepared simulated scan", deviation_ready);
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let frame = marked.frame;
    let app = harness.state();
    assert_eq!(app.display(), gui::app::DisplayMode::Simulated);
    let live = app.live().unwrap();
    let simulated = &live.settled.as_ref().unwrap().scan;
    let on_simulated = |p: DVec3| simulated.index.closest_point(p).distance;

    // On the simulated scan: the landmarks moved with the tissue (the nipples forward),
    // the cut curves and the outlines carried with it, all on its surface.
    let overlay = app.overlay();
    assert!(!overlay.editable);
    assert_eq!(overlay.landmarks.len(), 12);
    for (name, point) in &overlay.landmarks {
        assert!(on_simulated(*point) < 1e-6, "{name} {point}");
    }
    let nipple = |overlay: &gui::app::Overlay| {
        overlay
            .landmarks
            .iter()
            .find(|(name, _)| name == "Pnl")
            .unwrap()
            .1
    };
    let forward =
        (nipple(&overlay) - marked.landmarks.get(anatomy::LandmarkName::Pnl)).dot(frame.anterior());
    assert!(forward > 5.0, "the nipple moved {forward} mm forward");
    assert_eq!(overlay.curves.len(), 2);
    assert_eq!(overlay.outlines.len(), 2);
    // the phantom's fold is lowered for the implant, so both lie in their pockets
    assert_eq!(overlay.pockets.len(), 2);
    for point in (overlay.curves.iter())
        .chain(&overlay.outlines)
        .chain(&overlay.pockets)
        .flatten()
    {
        assert!(on_simulated(*point) < 1e-6, "{point}");
    }

    // On the scan as loaded: the outlines on its skin, each around its breast's nipple
    // and about as wide as the implant (the skin lies in front of the bed, so a little
    // wider), seen from the front.
    let diameter = live.sides.left.placed.as_ref().unwrap().width_mm;
    click(&mut harness, "Pre-operative");
    let overlay = harness.state().overlay();
    assert!(overlay.editable);
    for (outline, nipple) in overlay.outlines.iter().zip([
        marked.landmarks.get(anatomy::LandmarkName::Pnl),
        marked.landmarks.get(anatomy::LandmarkName::Pnr),
    ]) {
        assert_eq!(outline.len(), 64);
        for point in outline {
            assert!(
                marked.scan.index.closest_point(*point).distance < 1e-6,
                "{point}"
            );
        }
        let across = |axis: DVec3| {
            let values = outline.iter().map(|p| (*p - nipple).dot(axis));
            let (low, high) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                (l.min(v), h.max(v))
            });
            (low, high)
        };
        for axis in [frame.left(), frame.up()] {
            let (low, high) = across(axis);
            assert!(
                low < 0.0 && high > 0.0,
                "the nipple is not inside: {low} {high}"
            );
            let width = high - low;
            assert!(
                width > 0.85 * diameter && width < 1.4 * diameter,
                "{width} mm across for a {diameter} mm implant"
            );
        }
    }
    // The pocket holds its implant: seen on the skin, its outline reaches at least as
    // far across and down as the implant's, within the fit's 2 mm tolerance.
    for (pocket, outline) in overlay.pockets.iter().zip(&overlay.outlines) {
        for point in pocket {
            assert!(marked.scan.index.closest_point(*point).distance < 1e-6);
        }
        let range = |points: &[DVec3], axis: DVec3| {
            (points.iter().map(|p| p.dot(axis)))
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
                    (l.min(v), h.max(v))
                })
        };
        let (pocket_x, implant_x) = (range(pocket, frame.left()), range(outline, frame.left()));
        assert!(pocket_x.0 <= implant_x.0 + 2.0 && pocket_x.1 >= implant_x.1 - 2.0);
        let (pocket_y, implant_y) = (range(pocket, frame.up()), range(outline, frame.up()));
        assert!(
            pocket_y.0 <= implant_y.0 + 2.0,
            "{pocket_y:?} {implant_y:?}"
        );
    }
}

/// Types `text` into the toolbar's path field.
fn type_path(harness: &mut Harness<'_, GuiApp>, text: &str) {
    // The path field is the first text field (the toolbar is drawn first).
    harness
        .get_all_by_role(Role::TextInput)
        .next()
        .unwrap()
        .focus();
    harness.step();
    harness
        .get_all_by_role(Role::TextInput)
        .next()
        .unwrap()
        .type_text(text);
    harness.step();
}

/// A new window in which the case at `path` was opened with the path field.
fn harness_with_case(path: &std::path::Path) -> Harness<'static, GuiApp> {
    let mut harness = harness();
    harness.step();
    type_path(&mut harness, &path.display().to_string());
    click(&mut harness, "Open");
    assert!(
        harness.state().error().is_none(),
        "{:?}",
        harness.state().error()
    );
    assert!(harness.state().is_building());
    harness
}

/// A build that fails at a place rings it on the scan, and the next build that succeeds
/// takes the ring away. The failure is provoked: the left fold's lowest landmark (PSMFl)
/// moved onto the scan's lower border, so the cut curve leaves the scan there. Independent
/// check: the ring's centre lies on the scan's border (1 µm: a point of a border edge).
#[test]
fn a_failed_build_rings_the_place_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let phantom = phantom::generate(&PhantomParams::default());
    let scan = &phantom.scan;
    let border = mesh::Topology::new(scan)
        .boundary_loops(scan)
        .into_iter()
        .max_by_key(|ring| ring.len())
        .unwrap();
    let fold = phantom.landmarks.get(anatomy::LandmarkName::PSMFl);
    let below = (border.iter())
        .map(|&v| scan.positions[v as usize])
        .filter(|p| p.y < fold.y - 50.0)
        .min_by(|a, b| (a.x - fold.x).abs().total_cmp(&(b.x - fold.x).abs()))
        .unwrap();
    let mut moved = phantom.landmarks.clone();
    moved.set(anatomy::LandmarkName::PSMFl, below);
    let (moved_path, original_path) = (
        dir.path().join("moved.json"),
        dir.path().join("phantom.json"),
    );
    moved.write(&moved_path, Default::default()).unwrap();
    (phantom.landmarks)
        .write(&original_path, Default::default())
        .unwrap();

    let mut harness = harness();
    harness.step();
    click(&mut harness, "File");
    click(&mut harness, "Phantom with its landmarks");
    set_slider(&mut harness, "Elements", ELEMENTS);
    harness.state_mut().open(&moved_path);
    click(&mut harness, "Build model");
    let start = Instant::now();
    while harness.state().is_building() {
        assert!(start.elapsed() < PATIENCE, "the build did not end");
        harness.step();
        std::thread::sleep(Duration::from_millis(20));
    }
    harness.step();
    let error = harness
        .state()
        .error()
        .expect("the build failed")
        .to_string();
    assert!(
        error.contains("the curve leaves the scan at its border"),
        "{error}"
    );
    // said once (the breast's message carries the curve's, then its advice)
    assert_eq!(error.matches("leaves the scan").count(), 1, "{error}");
    // drawn on the scan the build was given
    assert_eq!(
        harness.state().display(),
        gui::app::DisplayMode::PreOperative
    );
    let place = harness.state().overlay().failure.expect("a ringed place");
    let to_border_mm = (0..border.len())
        .map(|k| {
            let a = scan.positions[border[k] as usize];
            let b = scan.positions[border[(k + 1) % border.len()] as usize];
            let t = ((place.centre() - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            place.centre().distance(a + t * (b - a))
        })
        .fold(f64::INFINITY, f64::min);
    assert!(
        to_border_mm < 1e-3,
        "ringed {to_border_mm} mm from the border"
    );

    // new landmarks take the ring away; a good build leaves none
    harness.state_mut().open(&original_path);
    assert_eq!(harness.state().failure_place(), None);
    click(&mut harness, "Build model");
    wait_until(&mut harness, "a model", |app| app.model().is_some());
    assert_eq!(harness.state().failure_place(), None);
}
