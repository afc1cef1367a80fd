//! Surface comparison on pairs with a known answer: a sphere against a moved and a bumped
//! sphere (the distance of a point to a sphere is `| |p - c| - R |`), and an open plane
//! patch against a larger bumped one (the distance to a plane is the height). Every
//! per-vertex distance is also checked against an independent brute-force
//! point-to-triangle implementation.

mod common;

use assess::{AssessError, DistanceSurface, SurfaceComparison, Zone};
use glam::{DQuat, DVec3};
use mesh::shapes::{grid, icosphere};
use mesh::{SurfaceIndex, Topology, TriMesh};
use tetra::locate::closest_point_on_triangle;

const RADIUS_MM: f64 = 50.0;

/// The acceptance bound on RMS and Hausdorff against the true values.
const ACCEPTANCE: f64 = 0.02;

/// Compares `test` with `reference` without breast regions.
fn compare(reference: &TriMesh, test: &TriMesh, max_distance_mm: f64) -> SurfaceComparison {
    let (reference_index, reference_topology) = (
        SurfaceIndex::new(reference).unwrap(),
        Topology::new(reference),
    );
    let (test_index, test_topology) = (SurfaceIndex::new(test).unwrap(), Topology::new(test));
    SurfaceComparison::new(
        &DistanceSurface::new(reference, &reference_index, &reference_topology),
        vec![None; reference.vertex_count()],
        &DistanceSurface::new(test, &test_index, &test_topology),
        vec![None; test.vertex_count()],
        max_distance_mm,
    )
    .unwrap()
}

/// The largest gap (mm) between the sphere of radius `RADIUS_MM` and the inscribed
/// polyhedron `sphere`: how far any distance to the polyhedron can differ from the
/// distance to the sphere.
fn polyhedron_gap_mm(sphere: &TriMesh) -> f64 {
    (0..sphere.triangle_count())
        .map(|t| {
            let [a, _, _] = sphere.triangle_positions(t);
            RADIUS_MM - a.dot(sphere.triangle_normal(t))
        })
        .fold(0.0, f64::max)
}

/// A sphere of another tessellation than the reference's, turned so that no vertex
/// lies over a reference vertex.
fn test_sphere() -> TriMesh {
    let mut sphere = icosphere(RADIUS_MM, 4);
    let turn = DQuat::from_axis_angle(DVec3::new(0.3, -0.8, 0.5).normalize(), 0.37);
    sphere.map_positions(|p| turn * p);
    sphere
}

fn rms(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, count) = values.fold((0.0, 0usize), |(s, n), v| (s + v * v, n + 1));
    (sum / count as f64).sqrt()
}

/// The distance from `p` to `mesh` by trying every triangle, each by the Voronoi regions
/// of its corners, edges and face (`tetra`'s point location primitive): independent of
/// the BVH and of parry's projection that the comparison uses.
fn brute_force_distance(mesh: &TriMesh, p: DVec3) -> f64 {
    (0..mesh.triangle_count())
        .map(|t| closest_point_on_triangle(p, mesh.triangle_positions(t)).distance(p))
        .fold(f64::INFINITY, f64::min)
}

/// Every test vertex's distance equals the brute-force one (round-off only: both
/// compute the same geometric quantity in f64, 1e-9 mm is far above their round-off
/// and far below anything that matters); returns the brute-force RMS.
fn check_against_brute_force(
    reference: &TriMesh,
    test: &TriMesh,
    comparison: &SurfaceComparison,
) -> f64 {
    let brute: Vec<f64> = test
        .positions
        .iter()
        .map(|&p| brute_force_distance(reference, p))
        .collect();
    for (v, (deviation, brute)) in comparison.test_to_reference.iter().zip(&brute).enumerate() {
        let found = deviation.unwrap().distance_mm;
        assert!(
            (found - brute).abs() < 1e-9,
            "vertex {v}: {found} vs {brute}"
        );
    }
    rms(brute.into_iter())
}

#[test]
fn a_translated_sphere_deviates_by_its_distance_to_the_sphere() {
    let reference = icosphere(RADIUS_MM, 5);
    let gap = polyhedron_gap_mm(&reference);
    let shift = DVec3::new(3.0, -2.0, 4.0);
    let mut test = test_sphere();
    test.map_positions(|p| p + shift);
    let comparison = compare(&reference, &test, 100.0);
    assert_eq!(comparison.test_overlap_fraction(), 1.0);

    // Exact per vertex to within the polyhedron's gap to the true sphere (0.01 mm).
    let truth: Vec<f64> = test
        .positions
        .iter()
        .map(|p| p.length() - RADIUS_MM)
        .collect();
    for (deviation, true_signed) in comparison.test_to_reference.iter().zip(&truth) {
        let deviation = deviation.unwrap();
        assert!(
            (deviation.distance_mm - true_signed.abs()).abs() <= gap + 1e-12,
            "{} vs {true_signed}",
            deviation.distance_mm
        );
        if true_signed.abs() > gap {
            assert_eq!(deviation.signed_distance_mm.signum(), true_signed.signum());
        }
    }
    let statistics = comparison.statistics(Zone::Whole).unwrap();
    let true_rms = rms(truth.iter().copied());
    // Two equal spheres a distance |shift| apart are |shift| apart in Hausdorff distance.
    let true_hausdorff = shift.length();
    eprintln!(
        "translated sphere: rms {:.4} (true {true_rms:.4}), hausdorff {:.4} (true {true_hausdorff:.4}), gap {gap:.4} mm",
        statistics.rms_mm, statistics.hausdorff_mm
    );
    assert!((statistics.rms_mm / true_rms - 1.0).abs() < ACCEPTANCE);
    assert!((statistics.hausdorff_mm / true_hausdorff - 1.0).abs() < ACCEPTANCE);
    let brute_rms = check_against_brute_force(&reference, &test, &comparison);
    assert!((statistics.rms_mm - brute_rms).abs() < 1e-9);
}

#[test]
fn a_bumped_sphere_deviates_by_the_bump() {
    let reference = icosphere(RADIUS_MM, 5);
    let gap = polyhedron_gap_mm(&reference);
    // A smooth radial bump: the true distance of a displaced vertex to the sphere is the
    // bump's height. One outward, one inward (a dent).
    let (amplitude_mm, width_rad) = (8.0, 0.4);
    let axis = DVec3::new(1.0, 1.0, 0.2).normalize();
    for direction in [1.0, -1.0] {
        let bump = |p: DVec3| {
            let angle = p.angle_between(axis);
            direction * amplitude_mm * (-angle * angle / (2.0 * width_rad * width_rad)).exp()
        };
        let mut test = test_sphere();
        test.map_positions(|p| p + p.normalize() * bump(p));
        let heights: Vec<f64> = test_sphere().positions.iter().map(|&p| bump(p)).collect();
        let comparison = compare(&reference, &test, 100.0);
        for (deviation, height) in comparison.test_to_reference.iter().zip(&heights) {
            assert!((deviation.unwrap().distance_mm - height.abs()).abs() <= gap + 1e-12);
        }
        let statistics = comparison.statistics(Zone::Whole).unwrap();
        let true_rms = rms(heights.iter().copied());
        let true_signed_mean = heights.iter().sum::<f64>() / heights.len() as f64;
        eprintln!(
            "bump {direction:+}: rms {:.4} (true {true_rms:.4}), hausdorff {:.4} (true {amplitude_mm}), signed mean {:.4} (true {true_signed_mean:.4}) mm",
            statistics.rms_mm, statistics.hausdorff_mm, statistics.signed_mean_mm
        );
        assert!((statistics.rms_mm / true_rms - 1.0).abs() < ACCEPTANCE);
        // The bump's top is the farthest point of either surface from the other.
        assert!((statistics.hausdorff_mm / amplitude_mm - 1.0).abs() < ACCEPTANCE);
        // Every signed distance is within the gap of its true value, so is their mean.
        assert!((statistics.signed_mean_mm - true_signed_mean).abs() <= gap);
        let brute_rms = check_against_brute_force(&reference, &test, &comparison);
        assert!((statistics.rms_mm - brute_rms).abs() < 1e-9);
    }
}

#[test]
fn an_open_patch_overlaps_only_where_it_lies_over_the_reference() {
    // Reference: a 100 mm square at z = 0. Test: a 140 mm square around it with a bump.
    let reference = grid(50, 50, 2.0);
    let mut test = grid(70, 70, 2.0);
    let height = |p: DVec3| {
        let r2 = (p - DVec3::new(50.0, 50.0, 0.0)).length_squared();
        6.0 * (-r2 / (2.0 * 25.0 * 25.0)).exp()
    };
    test.map_positions(|p| {
        let p = p - DVec3::new(20.0, 20.0, 0.0);
        p + DVec3::Z * height(p)
    });
    let over_reference =
        |p: &DVec3| p.x > 1e-9 && p.x < 100.0 - 1e-9 && p.y > 1e-9 && p.y < 100.0 - 1e-9;
    let inside: Vec<f64> = test
        .positions
        .iter()
        .filter(|p| over_reference(p))
        .map(|p| p.z)
        .collect();

    let comparison = compare(&reference, &test, 50.0);
    // Exactly the vertices strictly over the reference square are in the overlap, each
    // at its height above the plane.
    for (deviation, p) in comparison.test_to_reference.iter().zip(&test.positions) {
        assert_eq!(deviation.is_some(), over_reference(p), "{p}");
        if let Some(deviation) = deviation {
            assert!((deviation.signed_distance_mm - p.z).abs() < 1e-9);
        }
    }
    let statistics = comparison.statistics(Zone::Whole).unwrap();
    assert_eq!(statistics.vertices, inside.len());
    assert!((statistics.rms_mm - rms(inside.iter().copied())).abs() < 1e-9);
    assert!(
        (comparison.test_overlap_fraction() - inside.len() as f64 / test.vertex_count() as f64)
            .abs()
            < 1e-12
    );

    // A smaller maximum distance drops the bump's top.
    let near = compare(&reference, &test, 3.0);
    let kept = near.statistics(Zone::Whole).unwrap();
    assert_eq!(kept.vertices, inside.iter().filter(|&&z| z <= 3.0).count());
    assert!(kept.max_test_to_reference_mm <= 3.0);
}

#[test]
fn bad_input_gives_clear_errors() {
    let reference = icosphere(RADIUS_MM, 3);
    let (index, topology) = (
        SurfaceIndex::new(&reference).unwrap(),
        Topology::new(&reference),
    );
    let surface = DistanceSurface::new(&reference, &index, &topology);
    let mut far = reference.clone();
    far.map_positions(|p| p + DVec3::new(500.0, 0.0, 0.0));
    let (far_index, far_topology) = (SurfaceIndex::new(&far).unwrap(), Topology::new(&far));
    let far_surface = DistanceSurface::new(&far, &far_index, &far_topology);
    let sides = || vec![None; reference.vertex_count()];

    let error = SurfaceComparison::new(&surface, sides(), &far_surface, sides(), 50.0).unwrap_err();
    assert!(matches!(error, AssessError::NoOverlap { .. }));
    assert!(error.to_string().contains("do not overlap"), "{error}");

    for bad in [0.0, -1.0, f64::NAN] {
        let error = SurfaceComparison::new(&surface, sides(), &surface, sides(), bad).unwrap_err();
        assert!(
            matches!(error, AssessError::InvalidMaxDistance(_)),
            "{error}"
        );
    }
    let error =
        SurfaceComparison::new(&surface, vec![None; 3], &surface, sides(), 50.0).unwrap_err();
    assert!(error.to_string().contains("breast region list"), "{error}");
}

#[test]
fn a_scan_against_a_copy_with_a_bump_on_the_left_breast() {
    use anatomy::LandmarkName;
    let marked = common::marked_phantom(&phantom::PhantomParams::default());
    let (phantom, index, topology) = (&marked.phantom, &marked.index, &marked.topology);
    let reference = &phantom.scan;
    let sides = marked.breasts.scan_vertex_sides(reference.vertex_count());

    // A smooth bump along the normals on the left breast's upper pole (between the
    // nipple and the clavicle, away from the nipple's sharp curvature): 5 mm high,
    // 30 mm wide, so its slope stays below 0.1 and the distance of a displaced vertex
    // to the original skin, convex there with radii of curvature far above 5 mm, is its
    // height to well under 1%.
    let (amplitude_mm, width_mm) = (5.0, 30.0);
    let nipple = phantom.landmarks.get(LandmarkName::Pnl);
    let clavicle = phantom.landmarks.get(LandmarkName::Pcl);
    let centre = index.closest_point(nipple.lerp(clavicle, 0.35)).point;
    let height =
        |p: DVec3| amplitude_mm * (-p.distance_squared(centre) / (2.0 * width_mm * width_mm)).exp();
    let heights: Vec<f64> = reference.positions.iter().map(|&p| height(p)).collect();
    let mut test = reference.clone();
    for ((p, normal), h) in test
        .positions
        .iter_mut()
        .zip(reference.vertex_normals())
        .zip(&heights)
    {
        *p += normal * *h;
    }
    let (test_index, test_topology) = (SurfaceIndex::new(&test).unwrap(), Topology::new(&test));
    let comparison = SurfaceComparison::new(
        &DistanceSurface::new(reference, index, topology),
        sides.clone(),
        &DistanceSurface::new(&test, &test_index, &test_topology),
        sides.clone(),
        50.0,
    )
    .unwrap();

    for zone in [Zone::Whole, Zone::Breast(anatomy::Side::Left)] {
        let statistics = comparison.statistics(zone).unwrap();
        let true_rms = rms(comparison
            .test_to_reference
            .iter()
            .zip(&heights)
            .zip(&sides)
            .filter(|((deviation, _), side)| deviation.is_some() && zone.contains(**side))
            .map(|((_, h), _)| *h));
        eprintln!(
            "phantom bump, {zone:?}: rms {:.4} (true {true_rms:.4}), hausdorff {:.4} (true {amplitude_mm}), signed mean {:.4} mm, {} vertices",
            statistics.rms_mm,
            statistics.hausdorff_mm,
            statistics.signed_mean_mm,
            statistics.vertices
        );
        assert!((statistics.rms_mm / true_rms - 1.0).abs() < ACCEPTANCE);
        assert!((statistics.hausdorff_mm / amplitude_mm - 1.0).abs() < ACCEPTANCE);
        // The bump is outward everywhere.
        assert!((statistics.signed_mean_mm - statistics.mean_mm).abs() < 1e-3);
    }
    // The right breast, 20 cm away, is untouched.
    let right = comparison
        .statistics(Zone::Breast(anatomy::Side::Right))
        .unwrap();
    assert!(right.hausdorff_mm < 1e-3, "{right:?}");

    // Every 101st vertex against the brute-force search over all triangles.
    for (v, deviation) in comparison.test_to_reference.iter().enumerate().step_by(101) {
        if let Some(deviation) = deviation {
            let brute = brute_force_distance(reference, test.positions[v]);
            assert!((deviation.distance_mm - brute).abs() < 1e-9, "vertex {v}");
        }
    }
}

#[test]
fn breast_regions_carry_over_to_a_copy_and_stay_on_their_side() {
    use anatomy::Side;
    // A sphere with its x > 0 cap as the "left" region and x < 0 as the "right" one.
    let reference = icosphere(RADIUS_MM, 4);
    let (index, topology) = (
        SurfaceIndex::new(&reference).unwrap(),
        Topology::new(&reference),
    );
    let surface = DistanceSurface::new(&reference, &index, &topology);
    let side_of = |p: &DVec3| match p.x {
        x if x > 20.0 => Some(Side::Left),
        x if x < -20.0 => Some(Side::Right),
        _ => None,
    };
    let sides: Vec<_> = reference.positions.iter().map(side_of).collect();
    // Onto itself: every vertex keeps its region.
    let carried = assess::transfer_sides(&surface, &sides, &reference.positions, 10.0);
    assert_eq!(carried, sides);
    // Onto a turned sphere: a point gets its nearest reference vertex's region,
    // which agrees with the analytic region but within an edge of its border.
    let turned = test_sphere();
    let carried = assess::transfer_sides(&surface, &sides, &turned.positions, 10.0);
    for (p, side) in turned.positions.iter().zip(&carried) {
        if (p.x.abs() - 20.0).abs() > 4.0 {
            assert_eq!(*side, side_of(p), "{p}");
        }
    }
    // Beyond the maximum distance nothing is carried.
    let far: Vec<DVec3> = turned.positions.iter().map(|p| *p * 2.0).collect();
    assert!(
        assess::transfer_sides(&surface, &sides, &far, 10.0)
            .iter()
            .all(Option::is_none)
    );
}
