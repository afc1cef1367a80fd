use super::clip::Side;
use super::clip::simple_cycles;
use super::stitch::{PolygonDefect, bands, triangulate_in_plane};
use super::*;
use glam::DMat3;
use mesh::self_intersections;
use mesh::shapes::grid;

/// Radius of the synthetic chest (mm).
const RADIUS_MM: f64 = 150.0;

/// The frame equal to the file frame.
pub(super) fn identity_frame() -> AnatomicalFrame {
    AnatomicalFrame {
        origin: DVec3::ZERO,
        axes: DMat3::IDENTITY,
        sternal_axes: DMat3::IDENTITY,
        up_source: crate::UpSource::FileVertical,
    }
}

/// Part of a cylinder of radius 150 mm about the y axis, facing +z (anterior):
/// x from -120 to 120 mm, y from -150 to 50 mm, 2 mm grid.
fn cylinder_patch() -> TriMesh {
    let mut patch = grid(120, 100, 2.0);
    patch.map_positions(|p| {
        let x = p.x - 120.0;
        DVec3::new(
            x,
            p.y - 150.0,
            (RADIUS_MM * RADIUS_MM - x * x).sqrt() - RADIUS_MM,
        )
    });
    patch
}

/// Planes off the grid lines, so clipping splits triangles.
fn clip_box() -> ClipBox {
    ClipBox {
        x_min_mm: -80.3,
        x_max_mm: 79.1,
        y_min_mm: -120.7,
        y_max_mm: 10.2,
        ..ClipBox::default()
    }
}

fn assert_closed(surface: &ClosedSurface) {
    let topology = Topology::new(&surface.mesh);
    assert!(manifold_report(&surface.mesh, &topology).is_watertight_manifold());
    assert!(self_intersections(&surface.mesh).is_empty());
    assert!(surface.volume_ml > 0.0);
    assert_eq!(surface.band.end, surface.mesh.triangles.len());
    assert!(!surface.front.is_empty() && !surface.back_wall.is_empty());
}

#[test]
fn a_translated_cylinder_patch_closes_to_the_analytic_slab_volume() {
    let patch = cylinder_patch();
    let offset_mm = 15.0;
    let clip = clip_box();
    let surface =
        build_closed_surface_in_box(&patch, &patch, &identity_frame(), &clip, offset_mm).unwrap();
    assert_closed(&surface);
    // Front and wall are the same clipped surface, one translated by the offset
    // along z, and the band lies in the planes: the solid is a slab of constant
    // height over the box, whatever the surface's shape, so its volume is the box
    // area times the offset up to round-off.
    let area_mm2 = (clip.x_max_mm - clip.x_min_mm) * (clip.y_max_mm - clip.y_min_mm);
    let expected_ml = area_mm2 * offset_mm / 1000.0;
    assert!(
        (surface.volume_ml - expected_ml).abs() < 1e-9 * expected_ml,
        "{} vs {expected_ml} ml",
        surface.volume_ml
    );
    // The band lies in the planes; the front faces anteriorly.
    let on_plane = |p: DVec3| {
        [clip.x_min_mm, clip.x_max_mm].contains(&p.x)
            || [clip.y_min_mm, clip.y_max_mm].contains(&p.y)
    };
    for t in surface.band.clone() {
        let [a, b, c] = surface.mesh.triangle_positions(t);
        let centroid = (a + b + c) / 3.0;
        assert!(on_plane(a) && on_plane(b) && on_plane(c), "{a} {b} {c}");
        assert!((clip.x_min_mm..=clip.x_max_mm).contains(&centroid.x));
    }
    let front_normal_z: f64 = surface
        .front
        .clone()
        .map(|t| surface.mesh.triangle_normal(t).z)
        .sum();
    assert!(front_normal_z > 0.0);
}

#[test]
fn an_inward_base_or_scan_gives_the_same_outward_surface() {
    let patch = cylinder_patch();
    let mut flipped = patch.clone();
    for tri in &mut flipped.triangles {
        tri.swap(1, 2);
    }
    let frame = identity_frame();
    let reference = build_closed_surface_in_box(&patch, &patch, &frame, &clip_box(), 15.0)
        .unwrap()
        .volume_ml;
    for (scan, base) in [(&patch, &flipped), (&flipped, &patch), (&flipped, &flipped)] {
        let surface = build_closed_surface_in_box(scan, base, &frame, &clip_box(), 15.0).unwrap();
        assert_closed(&surface);
        assert!((surface.volume_ml - reference).abs() < 1e-9 * reference);
    }
}

#[test]
fn a_hole_inside_the_box_is_an_error() {
    let mut patch = cylinder_patch();
    // Remove the triangles around the vertex at x = 0, y = -50.
    let centre = (50 * 121 + 60) as u32;
    patch.triangles.retain(|tri| !tri.contains(&centre));
    let error = build_closed_surface_in_box(
        &patch,
        &cylinder_patch(),
        &identity_frame(),
        &clip_box(),
        15.0,
    )
    .unwrap_err();
    assert!(
        matches!(
            error,
            ClosedSurfaceError::HoleInsideBox {
                role: SurfaceRole::Scan,
                vertices: 6,
                ..
            }
        ),
        "{error}"
    );
    assert!(error.to_string().contains("hole"), "{error}");
}

#[test]
fn walks_split_into_simple_cycles() {
    assert_eq!(simple_cycles(&[1, 2, 3]), vec![vec![1, 2, 3]]);
    assert_eq!(
        simple_cycles(&[1, 2, 3, 4, 2, 5]),
        vec![vec![2, 3, 4], vec![1, 2, 5]]
    );
    // Pinched at the first vertex, and nested.
    assert_eq!(
        simple_cycles(&[1, 2, 3, 1, 4, 5, 6, 5, 7]),
        vec![vec![1, 2, 3], vec![5, 6], vec![1, 4, 5, 7]]
    );
}

#[test]
fn a_bump_grazing_a_plane_is_capped_flat() {
    // One vertex of the scan (at x = 76 mm, 3.1 mm inside the left plane) pushed
    // 3.5 mm out, past the plane: its tip is cut off, leaving a small hole on the
    // plane, apart from the border, that the cap closes.
    let mut scan = cylinder_patch();
    let bump = (50 * 121 + 98) as usize;
    assert_eq!(scan.positions[bump].x, 76.0);
    scan.positions[bump].x += 3.5;
    let clip = clip_box();
    let frame = identity_frame();
    let surface =
        build_closed_surface_in_box(&scan, &cylinder_patch(), &frame, &clip, 15.0).unwrap();
    assert_closed(&surface);
    // Triangles lying in the left plane off the band: the cap.
    let cap: Vec<usize> = surface
        .front
        .clone()
        .filter(|&t| {
            surface
                .mesh
                .triangle_positions(t)
                .iter()
                .all(|p| p.x == clip.x_max_mm)
        })
        .collect();
    assert!(!cap.is_empty());
    for &t in &cap {
        assert!(
            surface.mesh.triangle_normal(t).x > 0.99,
            "the cap faces out"
        );
    }
    // The bump adds a sliver of volume to the slab.
    let reference =
        build_closed_surface_in_box(&cylinder_patch(), &cylinder_patch(), &frame, &clip, 15.0)
            .unwrap();
    let added = surface.volume_ml - reference.volume_ml;
    assert!(added > 0.0 && added < 0.01, "{added} ml");
}

#[test]
fn a_plane_beyond_the_border_is_an_error() {
    let patch = cylinder_patch();
    let beyond = ClipBox {
        x_max_mm: 130.0,
        ..clip_box()
    };
    let error =
        build_closed_surface_in_box(&patch, &patch, &identity_frame(), &beyond, 15.0).unwrap_err();
    assert!(
        matches!(
            error,
            ClosedSurfaceError::RunsOffBorder {
                role: SurfaceRole::Scan,
                ..
            }
        ),
        "{error}"
    );
}

#[test]
fn a_base_in_front_of_the_scan_and_bad_options_are_errors() {
    let patch = cylinder_patch();
    let mut in_front = patch.clone();
    in_front.map_positions(|p| p + DVec3::Z * 30.0);
    let frame = identity_frame();
    let error =
        build_closed_surface_in_box(&patch, &in_front, &frame, &clip_box(), 15.0).unwrap_err();
    assert!(
        matches!(error, ClosedSurfaceError::WallInFront { .. }),
        "{error}"
    );

    for offset in [0.0, -5.0, f64::NAN] {
        assert!(matches!(
            build_closed_surface_in_box(&patch, &patch, &frame, &clip_box(), offset),
            Err(ClosedSurfaceError::InvalidInput(_))
        ));
    }
    let empty = ClipBox {
        x_min_mm: 10.0,
        x_max_mm: -10.0,
        ..clip_box()
    };
    assert!(matches!(
        build_closed_surface_in_box(&patch, &patch, &frame, &empty, 15.0),
        Err(ClosedSurfaceError::InvalidInput(_))
    ));
    let missing = ClipBox {
        x_min_mm: 500.0,
        x_max_mm: 600.0,
        ..clip_box()
    };
    assert!(matches!(
        build_closed_surface_in_box(&patch, &patch, &frame, &missing, 15.0),
        Err(ClosedSurfaceError::TooFewTriangles { .. })
    ));
}

/// A polygon on a clip plane that crosses itself, or visits a point twice, is refused
/// with the place: the middle of an edge at the crossing (a bow tie whose edges cross at
/// its centre), the repeated point. The stitch error carries it, in file coordinates,
/// for the GUI's ring.
#[test]
fn a_section_that_crosses_itself_is_refused_where_it_does() {
    // On plane 0 (x = const) the in-plane coordinates are y and z.
    let on_plane = |y: f64, z: f64| DVec3::new(-100.0, y, z);
    let bow_tie = [(0.0, 0.0), (40.0, 20.0), (40.0, 0.0), (0.0, 20.0)].map(|(y, z)| on_plane(y, z));
    let crossing = triangulate_in_plane(&bow_tie, 0, &[0, 1, 2, 3]).unwrap_err();
    let Some(at) = crossing.at() else {
        panic!("a crossing has a place");
    };
    // Edges 0-1 and 2-3 cross, and both have their middle at the crossing.
    assert!(at.distance(on_plane(20.0, 10.0)) < 1e-12, "{at}");
    assert!(matches!(crossing, PolygonDefect::Crossing(_)));

    let square = [
        (0.0, 0.0),
        (40.0, 0.0),
        (40.0, 20.0),
        (0.0, 20.0),
        (40.0, 0.0),
    ]
    .map(|(y, z)| on_plane(y, z));
    let twice = triangulate_in_plane(&square, 0, &[0, 1, 2, 3, 4]).unwrap_err();
    assert!(matches!(twice, PolygonDefect::Coincident(_)));
    assert_eq!(twice.at(), Some(on_plane(40.0, 0.0)));

    let error = ClosedSurfaceError::Stitch {
        what: "test".into(),
        near_mm: Some([1.0, 2.0, 3.0]),
    };
    assert_eq!(error.place().map(|p| p.centre_mm), Some([1.0, 2.0, 3.0]));
    assert!(
        error.to_string().ends_with("(near (1, 2, 3) mm)"),
        "{error}"
    );
}

/// The scan's and the wall's border, side by side on the four clip planes: on each a
/// scan chain from in-plane (0, 0) over (20, `dips[k]`) to (40, 0) (along the plane,
/// anterior), and a wall chain straight from (0, -10) to (40, -10), the same corners.
/// Returns the positions (scan's chains first, the wall's from the offset) and the
/// sides of each.
fn borders_on_planes(dips: [f64; 4]) -> (Vec<DVec3>, [Side; 4], [Side; 4], u32) {
    let on_plane = |plane: usize, along: f64, z: f64| match plane {
        0 => DVec3::new(-20.0, along, z),
        1 => DVec3::new(20.0, along, z),
        2 => DVec3::new(along, -20.0, z),
        _ => DVec3::new(along, 20.0, z),
    };
    let mut positions = Vec::new();
    for (plane, dip) in dips.iter().enumerate() {
        for (along, z) in [(0.0, 0.0), (20.0, *dip), (40.0, 0.0)] {
            positions.push(on_plane(plane, along, z));
        }
    }
    let offset = positions.len() as u32;
    for plane in 0..4 {
        for along in [0.0, 40.0] {
            positions.push(on_plane(plane, along, -10.0));
        }
    }
    let front = std::array::from_fn(|plane| Side {
        plane,
        chain: (0..3).map(|k| 3 * plane as u32 + k).collect(),
    });
    let back = std::array::from_fn(|plane| Side {
        plane,
        chain: vec![2 * plane as u32, 2 * plane as u32 + 1],
    });
    (positions, front, back, offset)
}

/// Where the scan's section dips behind the wall's on the left plane (to 15 mm, the
/// wall lying 10 mm behind), the bands are refused: the error names the left plane and
/// the crossing, at the middle of one of the three edges that cross (the two of the
/// scan's dip and the wall's). With the dip between the scan's ends and the wall on
/// every plane, each band is its five-cornered polygon's three triangles (n - 2): the
/// polygon is not convex, so the triangulation of its corners has a fourth triangle,
/// outside it, which must be dropped.
#[test]
fn scan_and_wall_sections_that_cross_are_refused_on_their_plane() {
    let to_file = |p: DVec3| p.to_array();
    let (positions, front, back, offset) = borders_on_planes([5.0, -15.0, 5.0, 5.0]);
    let error = bands(&positions, &front, &back, offset, to_file).unwrap_err();
    let ClosedSurfaceError::Stitch { what, near_mm } = &error else {
        panic!("{error}");
    };
    assert!(
        what.starts_with("on the left plane") && what.contains("cross"),
        "{what}"
    );
    let middles = [[20.0, 10.0, -7.5], [20.0, 30.0, -7.5], [20.0, 20.0, -10.0]];
    assert!(
        near_mm.is_some_and(|at| middles.contains(&at)),
        "{near_mm:?}"
    );

    let (positions, front, back, offset) = borders_on_planes([-5.0; 4]);
    let triangles = bands(&positions, &front, &back, offset, to_file).unwrap();
    assert_eq!(triangles.len(), 4 * 3);
}

/// A box error with no place, both lateral planes left grazing: both are named, each
/// with its own figures, and the box's error is said once.
#[test]
fn an_error_with_no_place_names_both_grazing_planes() {
    let plane = |side, moved_mm| GrazingPlane {
        side,
        moved_mm,
        defects: 2,
        excess_fold_mm: 1.5,
    };
    let error = ClosedSurfaceError::OnGrazingPlane {
        grazing: vec![plane("right", 10.0), plane("left", 4.5)],
        error: Box::new(ClosedSurfaceError::WallInFront { volume_ml: -3.0 }),
    };
    let text = error.to_string();
    assert!(
        text.contains("the right and left clip planes still graze the side of the torso"),
        "{text}"
    );
    assert!(text.contains("right: moved 10.0 mm inwards"), "{text}");
    assert!(text.contains("left: moved 4.5 mm inwards"), "{text}");
    let inner = ClosedSurfaceError::WallInFront { volume_ml: -3.0 }.to_string();
    assert_eq!(text.matches(inner.as_str()).count(), 1, "{text}");
    assert_eq!(error.place(), None);
}

/// Landmarks on [`cylinder_patch`]: clavicles at y = 40 mm, nipples at y = -60 mm, fold
/// points at -90 to -100 mm (left at +x).
fn cylinder_landmarks() -> Landmarks {
    use crate::landmarks::LandmarkName::*;
    Landmarks::new(|name| {
        let (x, y) = match name {
            Pj => (0.0, 40.0),
            Pcl => (70.0, 40.0),
            Pcr => (-70.0, 40.0),
            Pnl => (60.0, -60.0),
            Pnr => (-60.0, -60.0),
            PSMFl => (60.0, -100.0),
            PSMFr => (-60.0, -100.0),
            PSMFml => (20.0, -90.0),
            PSMFmr => (-20.0, -90.0),
            PSMFll => (90.0, -80.0),
            PSMFlr => (-90.0, -80.0),
            Px => (0.0, -80.0),
        };
        DVec3::new(x, y, (RADIUS_MM * RADIUS_MM - x * x).sqrt() - RADIUS_MM)
    })
}

/// The triangles of `mesh` whose three corners satisfy `cut`, removed.
fn without(mut mesh: TriMesh, cut: impl Fn(DVec3) -> bool) -> TriMesh {
    let positions = mesh.positions.clone();
    mesh.triangles
        .retain(|tri| !tri.iter().all(|&v| cut(positions[v as usize])));
    mesh
}

/// Bands of unseen skin cut into the scan from its edge, like the upward-facing skin over
/// a clavicle that a standing scan misses: across the upper chest (y -20 to -14 mm, from
/// x = 30 mm out to the scan's left edge) and below the folds (y -130 to -126 mm, from
/// x = -30 mm to the right edge). The scan goes on beyond each band, so its height at
/// every x does not show them. The box at the clavicles would end the clipped scan's
/// border inside the box; the top moves to the clearance (10 mm) below the upper band,
/// y = -30 mm, the bottom to 10 mm above the lower one, y = -116 mm, and the surface
/// closes.
#[test]
fn the_top_and_bottom_planes_stay_clear_of_notches_in_the_scan_edge() {
    let notched = without(cylinder_patch(), |p| {
        (p.x >= 30.0 && (-20.0..=-14.0).contains(&p.y))
            || (p.x <= -30.0 && (-130.0..=-126.0).contains(&p.y))
    });
    let frame = identity_frame();
    let landmarks = cylinder_landmarks();
    let options = ClosedSurfaceOptions::default();
    let clip = ClipBox::around_breasts(&notched, &frame, &landmarks, &options).unwrap();
    assert_eq!((clip.y_min_mm, clip.y_max_mm), (-116.0, -30.0), "{clip:?}");
    let surface =
        build_closed_surface_in_box(&notched, &cylinder_patch(), &frame, &clip, 15.0).unwrap();
    assert_closed(&surface);
    // The box at the clavicles fails as the occluded phantom did.
    let at_clavicles = ClipBox {
        y_max_mm: 40.0,
        ..clip
    };
    let error =
        build_closed_surface_in_box(&notched, &cylinder_patch(), &frame, &at_clavicles, 15.0)
            .unwrap_err();
    assert!(
        matches!(error, ClosedSurfaceError::RunsOffBorder { .. }),
        "{error}"
    );

    // The moves are said, with where.
    let fit = ClipBox::around_breasts_and_footprints(&notched, &frame, &landmarks, &[], &options)
        .unwrap();
    assert_eq!(fit.clip_box, clip);
    let [top, bottom] = &fit.notch_warnings[..] else {
        panic!("{:?}", fit.notch_warnings);
    };
    assert!(top.contains("top was moved 70.0 mm down"), "{top}");
    assert!(bottom.contains("bottom was moved 24.0 mm up"), "{bottom}");

    // A hole wholly inside the box (y -40 mm) does not move it: that is a hole for the
    // breast model to close. Nor does a hole above the box (y -22 mm, its border clear
    // of the triangles the top cuts), nor a speck apart from the scan across the new top
    // (the clipping drops both).
    let with_hole = without(notched.clone(), |p| {
        p.distance(DVec3::new(-40.0, -40.0, p.z)) < 3.0
    });
    let hole_above = without(notched.clone(), |p| {
        p.distance(DVec3::new(-40.0, -22.0, p.z)) < 3.0
    });
    let mut speck = grid(3, 5, 2.0);
    speck.map_positions(|p| DVec3::new(p.x - 60.0, p.y - 35.0, 20.0));
    let mut with_speck = notched.clone();
    let first = with_speck.positions.len() as u32;
    with_speck.positions.extend(&speck.positions);
    with_speck
        .triangles
        .extend(speck.triangles.iter().map(|tri| tri.map(|v| v + first)));
    for scan in [&with_hole, &hole_above, &with_speck] {
        assert_eq!(
            ClipBox::around_breasts(scan, &frame, &landmarks, &options).unwrap(),
            clip
        );
    }
    // A hole the new top would pass through is a notch of that box: the top moves on,
    // below it, and the surface closes.
    let hole_at_top = without(notched, |p| p.distance(DVec3::new(-40.0, -30.0, p.z)) < 3.0);
    let lower = ClipBox::around_breasts(&hole_at_top, &frame, &landmarks, &options).unwrap();
    assert!(lower.y_max_mm <= -40.0, "{lower:?}");
    let surface =
        build_closed_surface_in_box(&hole_at_top, &cylinder_patch(), &frame, &lower, 15.0).unwrap();
    assert_closed(&surface);
}

/// The side of a torso that curves back behind its widest point, as on the front half of
/// a torso (the default phantom): the scan goes on from its right edge (x = -120 mm)
/// back and inwards to x = -100 mm, inside the box's right plane (x = -110 mm, the
/// clearance inside the widest point), its free edge at every height of the box. The
/// clipping drops that strip as a piece apart from the rest, so its edge is no notch:
/// the box is the one without it, and the surface closes.
#[test]
fn a_strip_behind_a_lateral_plane_moves_neither_top_nor_bottom() {
    let mut with_strip = grid(130, 100, 2.0);
    with_strip.map_positions(|p| {
        let x = p.x - 140.0;
        let y = p.y - 150.0;
        let edge_z = (RADIUS_MM * RADIUS_MM - 120.0 * 120.0).sqrt() - RADIUS_MM;
        if x >= -120.0 {
            DVec3::new(x, y, (RADIUS_MM * RADIUS_MM - x * x).sqrt() - RADIUS_MM)
        } else {
            let back = -120.0 - x;
            DVec3::new(-120.0 + back, y, edge_z - 3.0 * back)
        }
    });
    let frame = identity_frame();
    let landmarks = cylinder_landmarks();
    let options = ClosedSurfaceOptions::default();
    let plain = ClipBox::around_breasts(&cylinder_patch(), &frame, &landmarks, &options).unwrap();
    let clip = ClipBox::around_breasts(&with_strip, &frame, &landmarks, &options).unwrap();
    assert_eq!(clip, plain);
    assert_eq!(clip.x_min_mm, -110.0, "{clip:?}");
    let surface =
        build_closed_surface_in_box(&with_strip, &cylinder_patch(), &frame, &clip, 15.0).unwrap();
    assert_closed(&surface);
}
