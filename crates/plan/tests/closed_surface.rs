//! The closed surface (issue 3 item 5) on the phantom. Here rather than in `anatomy`
//! because the phantom depends on `anatomy`.
//!
//! The filled base is stood in for by the phantom with the smallest cup: it has the
//! same chest and border, and its breasts lie inside the larger cups' skin, so the
//! shifted wall stays behind the scan as a real fill-in does.
//!
//! Run with `cargo test --release -p plan --test closed_surface -- --nocapture` for the
//! figures.

use anatomy::closed_surface::{
    ClosedSurface, ClosedSurfaceError, ClosedSurfaceOptions, build_closed_surface,
};
use anatomy::{AnatomicalFrame, LandmarkName, Up};
use mesh::{Topology, TriMesh, manifold_report, self_intersections};
use phantom::{Cup, Phantom, PhantomParams};
use std::time::Instant;

fn phantom(cup: Cup, noise_mm: f64) -> Phantom {
    phantom::generate(&PhantomParams {
        cup,
        noise_mm,
        ..PhantomParams::default()
    })
}

/// The closed surface of `front` over the small-cup stand-in base, with its build time.
fn close(front: &Phantom, options: &ClosedSurfaceOptions) -> (ClosedSurface, f64) {
    let base = phantom(Cup::Small, 0.0);
    let frame = sternal_frame(front);
    let start = Instant::now();
    let surface =
        build_closed_surface(&front.scan, &base.scan, &frame, &front.landmarks, options).unwrap();
    (surface, start.elapsed().as_secs_f64() * 1e3)
}

fn check_closed(name: &str, surface: &ClosedSurface, build_ms: f64) {
    let mesh: &TriMesh = &surface.mesh;
    let start = Instant::now();
    let report = manifold_report(mesh, &Topology::new(mesh));
    let crossings = self_intersections(mesh);
    let check_ms = start.elapsed().as_secs_f64() * 1e3;
    assert!(report.is_watertight_manifold(), "{name}: {report}");
    assert!(crossings.is_empty(), "{name}: {crossings:?}");
    let clip = surface.clip_box;
    println!(
        "{name}: {:.0} ml, {} triangles (front {}, wall {}, band {}), box x {:.1}..{:.1} \
         y {:.1}..{:.1} mm; build {build_ms:.0} ms, of which checks about {check_ms:.0} ms",
        surface.volume_ml,
        mesh.triangles.len(),
        surface.front.len(),
        surface.back_wall.len(),
        surface.band.len(),
        clip.x_min_mm,
        clip.x_max_mm,
        clip.y_min_mm,
        clip.y_max_mm,
    );
}

#[test]
fn phantom_closes_watertight_outward_and_plausible() {
    let options = ClosedSurfaceOptions::default();
    let mut volumes = Vec::new();
    for cup in [Cup::Medium, Cup::Large] {
        let front = phantom(cup, 0.0);
        let (surface, build_ms) = close(&front, &options);
        check_closed(&format!("{cup} cup"), &surface, build_ms);
        let clip = surface.clip_box;
        // At least the slab between the scan and the wall over the box; the breasts
        // (each at most about 800 ml) add to it.
        let slab_ml = (clip.x_max_mm - clip.x_min_mm)
            * (clip.y_max_mm - clip.y_min_mm)
            * options.rear_wall_offset_mm
            / 1000.0;
        assert!(
            surface.volume_ml > slab_ml && surface.volume_ml < slab_ml + 2000.0,
            "{} ml for a {slab_ml:.0} ml slab",
            surface.volume_ml
        );
        // The box holds the nipples and the folds' lowest points and medial ends (not
        // the lateral fold ends, which lie beyond the torso's silhouette at the waist).
        let local = |name| frame_local(&front, name);
        for name in [
            LandmarkName::Pnl,
            LandmarkName::Pnr,
            LandmarkName::PSMFl,
            LandmarkName::PSMFr,
            LandmarkName::PSMFml,
            LandmarkName::PSMFmr,
        ] {
            let p = local(name);
            assert!(
                p.x > clip.x_min_mm
                    && p.x < clip.x_max_mm
                    && p.y > clip.y_min_mm
                    && p.y < clip.y_max_mm,
                "{} at {p:.1} outside {clip:?}",
                name.as_str()
            );
        }
        volumes.push(surface.volume_ml);
    }
    assert!(volumes[1] > volumes[0], "{volumes:?}");
}

#[test]
fn noisy_phantom_closes() {
    // With 0.5 mm of noise the phantom's scan intersects itself in the fold's crease
    // (3 pairs for the medium cup), which the closed surface rightly refuses; 0.4 mm is
    // twice the shared scans' noise.
    let front = phantom(Cup::Medium, 0.4);
    assert!(self_intersections(&front.scan).is_empty());
    let (surface, build_ms) = close(&front, &ClosedSurfaceOptions::default());
    check_closed("medium cup, 0.4 mm noise", &surface, build_ms);
}

#[test]
fn too_large_an_offset_or_a_box_outside_the_scan_is_an_error() {
    let front = phantom(Cup::Medium, 0.0);
    let base = phantom(Cup::Small, 0.0);
    let frame = sternal_frame(&front);
    // A clearance larger than the scan's reach around the breasts leaves them out.
    let options = ClosedSurfaceOptions {
        border_clearance_mm: 400.0,
        ..ClosedSurfaceOptions::default()
    };
    let error = build_closed_surface(&front.scan, &base.scan, &frame, &front.landmarks, &options)
        .unwrap_err();
    assert!(
        matches!(error, ClosedSurfaceError::InvalidInput(_)),
        "{error}"
    );
    println!("{error}");
}

fn frame_local(phantom: &Phantom, name: LandmarkName) -> glam::DVec3 {
    sternal_frame(phantom).to_local(phantom.landmarks.get(name))
}

/// The frame the closed surface is built in ([`AnatomicalFrame::sternal`]).
fn sternal_frame(phantom: &Phantom) -> AnatomicalFrame {
    AnatomicalFrame::from_landmarks(&phantom.landmarks, Up::FILE_VERTICAL)
        .unwrap()
        .sternal()
}
