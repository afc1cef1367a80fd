//! The pectoralis major on the phantom's finest level (60,000 elements). Run with
//! `cargo test --release -p simulation --test muscle -- --nocapture` for the figures.

mod common;

use anatomy::breast::Side;
use simulation::{MuscleLayer, WALL_TOLERANCE_FACTOR};

/// The muscle's elements hold the volume its thickness integrates to over the rear wall,
/// summed independently over the wall's triangles (area times the thickness at the
/// centroid, or the room to the bed's depth under the skin where that is less). The elements are taken whole by their centroids, so the layer's front
/// and its tapering borders are resolved to about half an element: at a 6-7 mm spacing
/// over a 10 mm layer that is up to a third of its thickness locally, and it averages
/// out over the layer to within 15%. The surface written for it encloses the same volume.
#[test]
fn the_muscle_elements_hold_the_volume_of_its_thickness_over_the_wall() {
    let patient = common::phantom();
    let closed = &patient.model.closed_surface;
    let finest = &patient.model.tets.levels[0].mesh;
    let layer = MuscleLayer::new(finest, closed, patient.frame(), patient.landmarks()).unwrap();
    let skin = mesh::SurfaceIndex::new(&mesh::TriMesh::new(
        closed.mesh.positions.clone(),
        closed.mesh.triangles[closed.front.clone()].to_vec(),
    ))
    .unwrap();
    for side in Side::BOTH {
        let muscle = layer.muscles[side as usize].as_ref().unwrap();
        let sign = if side == Side::Left { 1.0 } else { -1.0 };
        let integral_mm3: f64 = closed.mesh.triangles[closed.back_wall.clone()]
            .iter()
            .map(|t| t.map(|v| closed.mesh.positions[v as usize]))
            .map(|[a, b, c]| {
                let centroid = (a + b + c) / 3.0;
                let local = patient.frame().to_local(centroid);
                let area = 0.5 * (b - a).cross(c - a).length();
                // the muscle keeps the bed's depth under the skin
                let room = skin.closest_point(centroid).distance - simulation::DEFAULT_SHIFT_MM;
                if local.x * sign >= 0.0 {
                    area * muscle.thickness_at(local).min(room.max(0.0))
                } else {
                    0.0
                }
            })
            .sum();
        let elements_mm3: f64 = layer.elements[side as usize]
            .iter()
            .map(|&e| {
                let p = finest.tets[e as usize].map(|v| finest.positions[v as usize]);
                tetra::quality::signed_volume(p)
            })
            .sum();
        // the surface written as muscle_*.ply encloses exactly the elements (divergence
        // theorem on a closed, outward surface: equal to rounding)
        let surface = layer.side_surface(finest, side).unwrap();
        let enclosed_mm3 = surface.signed_volume();
        assert!(
            (enclosed_mm3 / elements_mm3 - 1.0).abs() < 1e-9,
            "{side}: surface {enclosed_mm3:.1} vs elements {elements_mm3:.1} mm³"
        );
        let ratio = elements_mm3 / integral_mm3;
        println!(
            "{side}: elements {:.1} ml, thickness over the wall {:.1} ml, ratio {ratio:.3}",
            elements_mm3 / 1000.0,
            integral_mm3 / 1000.0
        );
        assert!((ratio - 1.0).abs() < 0.15, "{side}: ratio {ratio:.3}");
    }
}

/// The figures the model reports put the muscle where the landmarks place it: its
/// sternal origin 5 mm from the midline and ending at Px's height, each within one
/// element spacing (elements are taken by their centroids); a mean thickness under the
/// full 10 mm (it tapers) but over half of it; the two sides of the symmetric phantom
/// within 5% of each other in area.
#[test]
fn the_muscle_figures_match_its_placement() {
    let patient = common::phantom();
    let level = &patient.model.tets.levels[0];
    let layer = MuscleLayer::new(
        &level.mesh,
        &patient.model.closed_surface,
        patient.frame(),
        patient.landmarks(),
    )
    .unwrap();
    let spacing = level.spacing_mm;
    let figures = Side::BOTH.map(|side| {
        layer
            .figures(
                &level.mesh,
                &patient.model.closed_surface,
                patient.frame(),
                side,
                spacing * WALL_TOLERANCE_FACTOR,
            )
            .unwrap()
    });
    for (side, f) in Side::BOTH.iter().zip(&figures) {
        println!("{side}: {f:?} (spacing {spacing:.1} mm)");
        let medial = f.medial_border_from_midline_mm;
        assert!(
            (simulation::muscle::MEDIAL_ORIGIN_MM..=simulation::muscle::MEDIAL_ORIGIN_MM + spacing)
                .contains(&medial),
            "{side}: medial border {medial:.1} mm"
        );
        let origin = f.lower_sternal_origin_above_px_mm.unwrap();
        assert!(
            origin.abs() <= spacing,
            "{side}: origin {origin:.1} mm above Px"
        );
        assert!(
            (5.0..10.0).contains(&f.mean_thickness_mm),
            "{side}: {:.1} mm",
            f.mean_thickness_mm
        );
    }
    let [left, right] = figures.map(|f| f.area_cm2);
    assert!(
        (left / right - 1.0).abs() < 0.05,
        "{left:.0} / {right:.0} cm²"
    );
}
