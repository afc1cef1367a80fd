//! The live simulation with a software renderer (`keep_to_window`): while the solve runs
//! its frames are previews drawn on the interaction mesh, with the pre-operative scan on
//! the same mesh for overlays; the frame it settles on, and the deviation map prepared
//! from it, are drawn on the full scan.

use gui::live_simulation::{INTERACTION_TRIANGLE_SHARE, ImplantSet, LiveSimulation};
use gui::render::SceneMesh;
use plan::catalog::Catalog;
use plan::model::ModelOptions;
use plan::simulate::{ImplantRequest, Session, SimulationOptions};
use plan::{MarkedScan, PhantomParams, Silent};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Longest the test waits for the solve (s): a few seconds are needed at 8,000 elements.
const PATIENCE_S: f64 = 300.0;

#[test]
fn previews_while_running_and_the_full_scan_once_settled() {
    let marked = MarkedScan::phantom(&PhantomParams::default()).unwrap();
    let scan_triangles = marked.scan.mesh.triangles.len();
    let scan_vertices = marked.scan.mesh.vertex_count();
    let scene = Arc::new(SceneMesh::new(&marked.scan.mesh));
    let options = ModelOptions {
        elements: 8000,
        ..ModelOptions::default()
    };
    let session = Session::build(
        marked,
        &options,
        Catalog::builtin(),
        SimulationOptions::default(),
        &Silent,
    )
    .unwrap();
    let mut live = LiveSimulation::start(session, scene, true, || {});
    let set = |projection_mm: f64| {
        let spec = format!("round:diameter=120,projection={projection_mm}");
        ImplantSet::both_sides(&ImplantRequest::new(spec), false)
    };
    let start = Instant::now();
    let mut previews = 0;
    let mut last = 0;
    // a short drag, then the solve settles
    for (k, projection_mm) in [30.0, 34.0, 38.0, 42.0].into_iter().enumerate() {
        live.set_implants(&set(projection_mm));
        let until = Instant::now() + Duration::from_millis(150 * (k as u64 + 1));
        while Instant::now() < until || (k == 3 && !live.is_settled()) {
            assert!(
                start.elapsed().as_secs_f64() < PATIENCE_S,
                "no settled frame"
            );
            live.poll();
            if let Some(frame) = &live.frame
                && frame.number != last
            {
                last = frame.number;
                assert_eq!(frame.positions.len(), scan_vertices);
                if let Some(pre_operative) = &frame.pre_operative {
                    previews += 1;
                    let triangles = frame.scene.triangle_count();
                    // the phantom's share decides (tests/interaction_mesh.rs)
                    let share = triangles as f64 / scan_triangles as f64;
                    assert!(
                        share <= INTERACTION_TRIANGLE_SHARE
                            && share > 0.9 * INTERACTION_TRIANGLE_SHARE,
                        "a preview of {triangles} triangles"
                    );
                    assert_eq!(pre_operative.triangle_count(), triangles);
                } else {
                    assert_eq!(frame.scene.triangle_count(), scan_triangles);
                }
            }
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    assert!(previews > 0, "no preview while the solve ran");
    let frame = live.frame.clone().expect("frames were received");
    assert!(
        frame.pre_operative.is_none(),
        "the settled frame is a preview"
    );
    assert_eq!(frame.scene.triangle_count(), scan_triangles);
    // the deviation map of the settled frame is drawn on the full scan too
    while live
        .settled
        .as_ref()
        .is_none_or(|s| s.frame != frame.number)
    {
        assert!(start.elapsed().as_secs_f64() < PATIENCE_S, "not prepared");
        live.poll();
        std::thread::sleep(Duration::from_millis(5));
    }
    let settled = live.settled.as_ref().unwrap();
    let map = settled.deviation.as_ref().expect("a deviation map");
    assert_eq!(map.scene.triangle_count(), scan_triangles);
}
