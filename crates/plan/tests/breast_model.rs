//! The breast model (cut curves, cutting, fill-ins, breast and quadrant volumes) on the
//! phantom, whose true breast volumes are known, and on the realistic shared scans.
//! Here rather than in `anatomy` because the phantom depends on `anatomy`.
//!
//! Run with `cargo test --release -p plan --test breast_model -- --nocapture` to see the
//! figures. Set `BREAST_MODEL_EXPORT_DIR` to also write the curves, fill-ins and filled
//! base of every model as PLY files there.

use anatomy::breast::{BreastError, BreastModel, BreastOptions, ControlPoints, Side};
use anatomy::{AnatomicalFrame, LandmarkName, Landmarks, Up, build_breast_model};
use mesh::{CurveError, DVec3, SurfaceIndex, Topology, TriMesh};
use phantom::{Cup, PhantomParams};
use plan::{MarkedScan, Silent};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The issue's bound on the angle between face normals across the stitch (degrees).
const MAX_STITCH_ANGLE_DEG: f64 = 25.0;

/// The frame the breast model is built in ([`AnatomicalFrame::sternal`]) for landmarks
/// in an upright file.
fn sternal_frame(landmarks: &Landmarks) -> AnatomicalFrame {
    AnatomicalFrame::from_landmarks(landmarks, Up::FILE_VERTICAL)
        .unwrap()
        .sternal()
}

/// Builds the model of a mesh with its landmarks.
fn build(
    mesh: &TriMesh,
    landmarks: &Landmarks,
    options: &BreastOptions,
) -> Result<BreastModel, BreastError> {
    let topology = Topology::new(mesh);
    let index = SurfaceIndex::new(mesh).unwrap();
    let frame = sternal_frame(landmarks);
    build_breast_model(mesh, &topology, &index, &frame, landmarks, options)
}

/// Checks what every model must satisfy and prints its figures; returns the largest
/// angle across the stitch of either fill-in (degrees).
fn check_model(name: &str, model: &BreastModel) -> f64 {
    let mut max_stitch_angle_deg: f64 = 0.0;
    for (side, angles) in Side::BOTH.into_iter().zip(model.stitch_angles()) {
        let breast = model.breast(side);
        let quadrants = breast.quadrant_volume_ml;
        let sum = quadrants.total();
        let stitch = angles.averaged_deg;
        let stitch_raw = angles.single_triangles_deg;
        println!(
            "{name} {side}: {:.1} ml; quadrants UO {:.1} UI {:.1} LI {:.1} LO {:.1} (sum off by {:.2e}); \
             curve {} points, {:.0} mm; max stitch angle {stitch:.1}° (single triangles {stitch_raw:.1}°)",
            breast.volume_ml,
            quadrants.upper_outer,
            quadrants.upper_inner,
            quadrants.lower_inner,
            quadrants.lower_outer,
            (sum - breast.volume_ml).abs() / breast.volume_ml,
            breast.curve.points.len(),
            breast.curve.length_mm(),
        );
        assert!((sum - breast.volume_ml).abs() < 0.005 * breast.volume_ml);
        for volume in [
            quadrants.upper_outer,
            quadrants.upper_inner,
            quadrants.lower_inner,
            quadrants.lower_outer,
        ] {
            assert!(volume > 0.0, "{name} {side}: {quadrants:?}");
        }
        let closed = Topology::new(&breast.closed);
        assert_eq!(closed.boundary_edge_count, 0, "{name} {side}");
        assert_eq!(closed.inconsistent_edge_count, 0, "{name} {side}");
        max_stitch_angle_deg = max_stitch_angle_deg.max(stitch);
    }
    let filled = Topology::new(&model.filled_base);
    assert_eq!(filled.inconsistent_edge_count, 0, "{name}");
    assert_eq!(filled.non_manifold_edge_count, 0, "{name}");
    assert_eq!(
        filled.boundary_loops(&model.filled_base).len(),
        1 + model.holes_left_open.len(),
        "{name}: the filled base keeps only the scan's border"
    );
    max_stitch_angle_deg
}

#[test]
fn phantom_breast_volumes_match_the_truth() {
    let mut failures = Vec::new();
    let symmetric = |cup| PhantomParams {
        cup,
        ..PhantomParams::default()
    };
    // A harder case: scanner noise and one breast larger than the other.
    let noisy_asymmetric = PhantomParams {
        noise_mm: 0.3,
        asymmetry: 0.8,
        ..PhantomParams::default()
    };
    for params in [
        symmetric(Cup::Small),
        symmetric(Cup::Medium),
        symmetric(Cup::Large),
        noisy_asymmetric,
    ] {
        let cup = params.cup;
        let phantom = phantom::generate(&params);
        let start = Instant::now();
        let model = build(&phantom.scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
        let elapsed = start.elapsed();
        let name = format!(
            "phantom {params} ({} vertices)",
            phantom.scan.vertex_count()
        );
        if let Some(out) = std::env::var_os("BREAST_MODEL_EXPORT_DIR") {
            export(Path::new(&out), &format!("phantom_{cup}"), &model);
            mesh::io::write_mesh(
                &Path::new(&out).join(format!("phantom_{cup}_chest_wall.ply")),
                &phantom.chest_wall,
            )
            .unwrap();
        }
        let truth = phantom.breast_volume_ml;
        let (left, right) = (model.left.volume_ml, model.right.volume_ml);
        println!(
            "{name}: left {left:.1} ml (truth {:.1}, {:+.2}%), right {right:.1} ml (truth {:.1}, {:+.2}%), \
             left/right differ by {:.3}%; built in {elapsed:.2?}",
            truth.left,
            100.0 * (left / truth.left - 1.0),
            truth.right,
            100.0 * (right / truth.right - 1.0),
            100.0 * (left / right - 1.0).abs(),
        );
        let wall = SurfaceIndex::new(&phantom.chest_wall).unwrap();
        for side in Side::BOTH {
            let fill = &model.breast(side).fill.mesh;
            let (mut max_mm, mut sum_mm) = (0.0f64, 0.0);
            for &p in &fill.positions {
                let closest = wall.closest_point(p);
                let normal = phantom.chest_wall.triangle_normal(closest.triangle);
                let signed = (p - closest.point).dot(normal).signum() * closest.distance;
                max_mm = max_mm.max(signed.abs());
                sum_mm += signed;
            }
            println!(
                "{name} {side}: fill-in off the true chest wall by at most {max_mm:.2} mm, mean {:+.2} mm",
                sum_mm / fill.positions.len() as f64
            );
        }
        let stitch = check_model(&name, &model);
        if stitch >= MAX_STITCH_ANGLE_DEG {
            failures.push(format!("{name}: stitch angle {stitch:.1}°"));
        }
        for (side, volume, truth) in [("left", left, truth.left), ("right", right, truth.right)] {
            if (volume / truth - 1.0).abs() >= 0.05 {
                failures.push(format!(
                    "{name} {side}: {volume:.1} ml, truth {truth:.1} ml"
                ));
            }
        }
        if params.asymmetry == 0.0 && (left / right - 1.0).abs() >= 0.01 {
            failures.push(format!("{name}: left {left:.1} ml, right {right:.1} ml"));
        }
        // The fill-in alone, whatever the curve encloses: the volume between the skin and
        // the true chest wall inside the same cut curve.
        for side in Side::BOTH {
            let volume = model.breast(side).volume_ml;
            let inside = true_volume_inside_curve_ml(&phantom, &model, side);
            println!(
                "{name} {side}: true volume inside the cut curve {inside:.1} ml, model {volume:.1} ml ({:+.2}%)",
                100.0 * (volume / inside - 1.0)
            );
            if (volume / inside - 1.0).abs() >= FILL_IN_VOLUME_TOLERANCE {
                failures.push(format!(
                    "{name} {side}: {volume:.1} ml, {inside:.1} ml inside the curve"
                ));
            }
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// How far the model's breast volume may be from the true volume inside its own cut
/// curve: this isolates the fill-in (the rear wall), 3% as on the analytic ellipsoid cap
/// the fill-in's error is 0.5% of the cap and a breast-sized chest bends more.
const FILL_IN_VOLUME_TOLERANCE: f64 = 0.03;

/// The volume (ml) between the phantom's skin and its true chest wall under the breast
/// patch of `side`, as the phantom computes its truth: the signed volume of the cones from
/// a common apex over the patch's skin triangles minus those over the same triangles on
/// the chest wall. Only triangles whose corners are all scan vertices count; the strip of
/// split triangles along the curve, where skin and wall meet, is left out, and the cones
/// over its two rims (skin and wall, nearly equal there) cancel.
fn true_volume_inside_curve_ml(phantom: &phantom::Phantom, model: &BreastModel, side: Side) -> f64 {
    let scan_vertices = phantom.scan.vertex_count();
    let patch = &model.breast(side).patch;
    let apex = patch.mesh.centroid();
    let six_cone = |[a, b, c]: [DVec3; 3]| (a - apex).dot((b - apex).cross(c - apex));
    let mut total = 0.0;
    for triangle in &patch.mesh.triangles {
        let corners = triangle.map(|v| patch.vertex_map[v as usize] as usize);
        if corners.iter().any(|&v| v >= scan_vertices) {
            continue;
        }
        total += six_cone(corners.map(|v| phantom.scan.positions[v]))
            - six_cone(corners.map(|v| phantom.chest_wall.positions[v]));
    }
    total / 6.0 / 1000.0
}

fn shared_scans() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../../shared/scans"
    ));
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!("skipped: {} not found", dir.display());
        None
    }
}

fn load(dir: &Path, name: &str) -> MarkedScan {
    MarkedScan::load(
        &dir.join(format!("{name}.ply")),
        &dir.join(format!("{name}_landmarks.json")),
        None,
        &Silent,
    )
    .unwrap()
}

/// The breast model of a marked scan with the default options; panics naming the scan.
fn default_model(name: &str, marked: &MarkedScan) -> BreastModel {
    let scan = &marked.scan;
    build_breast_model(
        &scan.mesh,
        &scan.topology,
        &scan.index,
        &marked.frame,
        &marked.landmarks,
        &BreastOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The generator's volumes of pair1's breasts before and after (ml per side, from
/// pair1_transform.json `volume_ml`). It grows the breast by a morph (`cupsize` 0.56 ->
/// 0.72) out to its own border, wider than our cut curve (ours measure about 0.75 of its
/// volumes), so the added volume inside our curve is smaller than its 184 ml by that
/// share. The ratio after over before is compared instead: it holds where that share is
/// the same before and after, which is assumed (the generator's border is not known
/// here); 10% on a ratio of 2.1 is about 19% on the added volume.
const PAIR1_GENERATOR_VOLUMES_ML: (f64, f64) = (165.454927, 349.866119);

/// How far the measured ratio may be from the generator's: the two scans' cut curves are
/// drawn through each scan's own landmarks (PSMFll moves 11 mm between them), and the
/// right breast of the post scan has two scanner holes closed inside it.
const VOLUME_RATIO_TOLERANCE: f64 = 0.10;

#[test]
fn shared_scans_give_plausible_volumes_and_the_larger_cup_the_larger_breasts() {
    let Some(dir) = shared_scans() else { return };
    let mut volumes = Vec::new();
    let mut failures = Vec::new();
    for name in ["v02_average", "pair1_pre", "pair1_post"] {
        let marked = load(&dir, name);
        let scan = &marked.scan;
        let start = Instant::now();
        let model = default_model(name, &marked);
        let elapsed = start.elapsed();
        let holes: Vec<String> = model
            .holes_closed
            .iter()
            .map(|h| format!("{:.0} mm at {:.0?}", h.perimeter_mm, h.centre))
            .collect();
        let in_breasts: Vec<String> = model
            .holes_in_breasts
            .iter()
            .map(|h| format!("{} {:.0} mm", h.side, h.perimeter_mm))
            .collect();
        println!(
            "{name}: {} vertices, built in {elapsed:.2?}; holes closed: {}; of them inside a breast: {}",
            scan.mesh.vertex_count(),
            holes.join(", "),
            in_breasts.join(", ")
        );
        if let Some(out) = std::env::var_os("BREAST_MODEL_EXPORT_DIR") {
            export(Path::new(&out), name, &model);
        }
        // The stitch angle is reported, not asserted: see the phantom test.
        check_model(name, &model);
        for side in Side::BOTH {
            let volume = model.breast(side).volume_ml;
            // pair1_pre is a small breast (about 60 ml by the cut curve).
            if !(40.0..=1200.0).contains(&volume) {
                failures.push(format!("{name} {side}: {volume:.1} ml"));
            }
        }
        volumes.push([model.left.volume_ml, model.right.volume_ml]);
    }
    let (pre, post) = (volumes[1], volumes[2]);
    let (generator_pre, generator_post) = PAIR1_GENERATOR_VOLUMES_ML;
    let generator_ratio = generator_post / generator_pre;
    println!(
        "pair1 pre {pre:.1?} ml, post {post:.1?} ml (generator: {generator_pre:.1} and \
         {generator_post:.1} ml)"
    );
    for (side, ratio) in ["left", "right"]
        .into_iter()
        .zip([post[0] / pre[0], post[1] / pre[1]])
    {
        let deviation = ratio / generator_ratio - 1.0;
        println!(
            "pair1 {side}: post / pre {ratio:.3}, generator {generator_ratio:.3} ({:+.1}%)",
            100.0 * deviation
        );
        if deviation.abs() > VOLUME_RATIO_TOLERANCE {
            failures.push(format!("pair1 {side}: post / pre {ratio:.3}"));
        }
    }
    assert!(failures.is_empty(), "{failures:#?}");
}

/// The body model's breast volumes of a zoo body (ml, left and right; `_meta.json`
/// `volume_ml`).
fn body_model_volumes_ml(dir: &Path, name: &str) -> [f64; 2] {
    let path = dir.join(format!("{name}_meta.json"));
    let text = std::fs::read_to_string(&path).unwrap();
    let meta: serde_json::Value = serde_json::from_str(&text).unwrap();
    ["l", "r"].map(|key| {
        meta["volume_ml"][key]
            .as_f64()
            .unwrap_or_else(|| panic!("{}: no volume_ml.{key}", path.display()))
    })
}

/// Ranks from 1 (ties do not occur in measured volumes).
fn ranks(values: &[f64]) -> Vec<f64> {
    let mut order: Vec<usize> = (0..values.len()).collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]));
    let mut rank = vec![0.0; values.len()];
    for (r, &i) in order.iter().enumerate() {
        rank[i] = (r + 1) as f64;
    }
    rank
}

/// Spearman's rank correlation of two samples without ties.
fn spearman(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let d2: f64 = (ranks(a).iter().zip(ranks(b)))
        .map(|(x, y)| (x - y).powi(2))
        .sum();
    1.0 - 6.0 * d2 / (n * (n * n - 1.0))
}

/// The zoo's twelve bodies (drawn from the independent body model) with the default
/// model: the 24 breast volumes rank as the body model's do (Spearman at least 0.9, the
/// issue's bound: its volume is taken out to its own border, wider than our cut curve,
/// so only the order is compared), and where its two sides differ, the left-minus-right
/// difference has its sign (its symmetric bodies have exactly equal sides and no sign).
#[test]
fn the_zoo_breasts_rank_and_differ_as_the_body_models_do() {
    let Some(dir) = shared_scans().map(|d| d.join("zoo")) else {
        return;
    };
    let (mut ours, mut theirs, mut wrong_signs) = (Vec::new(), Vec::new(), Vec::new());
    for body in 1..=12 {
        let name = format!("s{body:02}");
        let model = default_model(&name, &load(&dir, &name));
        let measured = [model.left.volume_ml, model.right.volume_ml];
        let truth = body_model_volumes_ml(&dir, &name);
        println!(
            "{name}: {:.1} / {:.1} ml (body model {:.1} / {:.1})",
            measured[0], measured[1], truth[0], truth[1]
        );
        let truth_difference = truth[0] - truth[1];
        if truth_difference != 0.0
            && (measured[0] - measured[1]).signum() != truth_difference.signum()
        {
            wrong_signs.push(name);
        }
        ours.extend(measured);
        theirs.extend(truth);
    }
    let rho = spearman(&ours, &theirs);
    println!("Spearman {rho:.3} over {} breasts", ours.len());
    assert!(rho >= 0.9, "Spearman {rho:.3}");
    assert!(
        wrong_signs.is_empty(),
        "left/right order against the body model's: {wrong_signs:?}"
    );
}

/// Writes each curve as text (`x y z` per line), and the fill-ins, breast patches, closed
/// breasts and filled base as PLY.
fn export(dir: &Path, prefix: &str, model: &BreastModel) {
    std::fs::create_dir_all(dir).unwrap();
    let write = |file: String, mesh: &TriMesh| {
        mesh::io::write_mesh(&dir.join(format!("{prefix}_{file}.ply")), mesh).unwrap();
    };
    for side in Side::BOTH {
        let breast = model.breast(side);
        let curve: String = breast
            .curve
            .points
            .iter()
            .map(|p| format!("{} {} {}\n", p.position.x, p.position.y, p.position.z))
            .collect();
        std::fs::write(dir.join(format!("{prefix}_curve_{side}.xyz")), curve).unwrap();
        write(format!("fill_{side}"), &breast.fill.mesh);
        write(format!("patch_{side}"), &breast.patch.mesh);
        write(format!("closed_breast_{side}"), &breast.closed);
    }
    write("filled_base".to_string(), &model.filled_base);
}

fn medium_phantom() -> phantom::Phantom {
    phantom::generate(&PhantomParams::default())
}

/// The default control points of the phantom.
fn default_points(mesh: &TriMesh, landmarks: &Landmarks) -> ControlPoints {
    let topology = Topology::new(mesh);
    let index = SurfaceIndex::new(mesh).unwrap();
    let frame = sternal_frame(landmarks);
    let surface = anatomy::measure::MeasuredSurface {
        mesh,
        topology: &topology,
        index: &index,
    };
    ControlPoints::from_landmarks(
        &surface,
        &frame,
        landmarks,
        anatomy::breast::DEFAULT_PC_RATIO,
    )
    .unwrap()
}

fn with_points(control_points: ControlPoints) -> BreastOptions {
    BreastOptions {
        control_points: Some(control_points),
        ..BreastOptions::default()
    }
}

#[test]
fn user_control_points_move_the_curve() {
    let phantom = medium_phantom();
    let defaults = default_points(&phantom.scan, &phantom.landmarks);
    let default_model = build(
        &phantom.scan,
        &phantom.landmarks,
        &with_points(defaults.clone()),
    );
    let default_model = default_model.unwrap();
    // An extra control point on the surface 30 mm below the middle of the fold, between
    // PSMF and PSMFl.
    let mut moved = defaults.clone();
    let index = SurfaceIndex::new(&phantom.scan).unwrap();
    let between = 0.5 * (moved.left[1] + moved.left[2]) - 30.0 * DVec3::Y;
    moved.left.insert(2, index.closest_point(between).point);
    let model = build(&phantom.scan, &phantom.landmarks, &with_points(moved)).unwrap();
    assert_eq!(model.left.control_points.len(), defaults.left.len() + 1);
    // The curve bulges out there: the breast patch grows.
    assert!(model.left.patch.mesh.area() > default_model.left.patch.mesh.area() + 100.0);
    // The right breast barely notices: its fill-in's chest cylinder is fitted to the base
    // within 40 mm around its hole, which reaches the left curve's medial end.
    assert!((model.right.volume_ml / default_model.right.volume_ml - 1.0).abs() < 1e-3);
    // The defaults are what `build_breast_model` uses without control points.
    let plain = build(&phantom.scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
    assert_eq!(plain.left.volume_ml, default_model.left.volume_ml);
}

#[test]
fn a_self_crossing_curve_is_an_error_naming_the_breast() {
    let phantom = medium_phantom();
    let mut points = default_points(&phantom.scan, &phantom.landmarks);
    // PSMFm, PSMF, upper, middle, PSMFl: the way back from PSMFl to PSMFm crosses the
    // way up from PSMF.
    points.left.swap(2, 4);
    let error = build(&phantom.scan, &phantom.landmarks, &with_points(points)).unwrap_err();
    println!("{error}");
    assert!(
        matches!(
            error,
            BreastError::Curve {
                side: Side::Left,
                source: CurveError::SelfCrossing { .. },
                ..
            }
        ),
        "{error:?}"
    );
    assert!(error.to_string().starts_with("left breast: "));
    // The message names a control point to move (user points: by number).
    assert!(
        error
            .to_string()
            .contains("the nearest control point is control point"),
        "{error}"
    );
}

/// The phantom's scan with a hole (seen from the front) of `radius_mm` 35 mm above the
/// right nipple.
fn with_hole_above_right_nipple(phantom: &phantom::Phantom, radius_mm: f64) -> TriMesh {
    let mut scan = phantom.scan.clone();
    let centre = phantom.landmarks.get(LandmarkName::Pnr) + 35.0 * DVec3::Y;
    let remove: Vec<usize> = (0..scan.triangle_count())
        .filter(|&t| {
            let c = scan.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
            c.truncate().distance(centre.truncate()) < radius_mm
        })
        .collect();
    assert!(!remove.is_empty());
    scan.remove_triangles(&remove);
    scan
}

/// A scanner dropout inside a breast is closed by the fill-in and reported. Known answer:
/// the intact breast's volume. Even a flat patch over a hole 25 mm across on a 60 mm
/// radius breast misses a cap of 0.35 ml; the fill-in follows the skin's curvature:
/// bound 0.35 ml.
#[test]
fn a_dropout_in_the_breast_is_closed_with_the_breast_volume_kept() {
    let phantom = medium_phantom();
    let intact = build(&phantom.scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
    let scan = with_hole_above_right_nipple(&phantom, 7.0);
    let model = build(&scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
    let [hole] = &model.holes_in_breasts[..] else {
        panic!("{:?}", model.holes_in_breasts)
    };
    println!("a dropout of {:.1} mm around", hole.perimeter_mm);
    assert_eq!(hole.side, Side::Right);
    assert!(
        hole.perimeter_mm > 60.0 && hole.perimeter_mm <= 80.0,
        "{hole:?}"
    );
    let error_ml = model.right.volume_ml - intact.right.volume_ml;
    assert!(error_ml.abs() < 0.35, "{error_ml} ml");
}

/// A hole some 40 mm across (130 mm around) in a breast, as the scanner leaves under a
/// full breast, is reconstructed: the breast keeps its intact volume within 2 ml (the
/// fill-in continues the skin's curvature; a flat patch would miss a cap of about 2.8 ml
/// on the phantom's 60 mm radius breast), the reconstructed area is the hole's within
/// 15% (the hole's ragged triangle border), and its vertices are flagged.
#[test]
fn a_large_hole_in_the_breast_is_reconstructed_with_the_volume_kept() {
    let phantom = medium_phantom();
    let intact = build(&phantom.scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
    let radius_mm = 20.0;
    let scan = with_hole_above_right_nipple(&phantom, radius_mm);
    let model = build(&scan, &phantom.landmarks, &BreastOptions::default()).unwrap();
    let part = &model.right.reconstructed;
    let hole_area = scan_area_difference(&phantom.scan, &scan);
    println!(
        "reconstructed {:.0} mm² (hole {hole_area:.0} mm²), {:.2} ml over flat; volume {:.2} vs intact {:.2} ml",
        part.area_mm2, part.volume_ml, model.right.volume_ml, intact.right.volume_ml
    );
    assert!(
        (part.area_mm2 - hole_area).abs() < 0.15 * hole_area,
        "{} vs {hole_area}",
        part.area_mm2
    );
    assert!(part.vertex_flags.iter().any(|&f| f));
    assert_eq!(model.left.reconstructed.area_mm2, 0.0);
    let error_ml = model.right.volume_ml - intact.right.volume_ml;
    assert!(error_ml.abs() < 2.0, "{error_ml} ml");
}

/// A breast reconstructed beyond the allowed share is refused, naming the share: here the
/// 40 mm hole of the test above (a few per cent of the breast) against a limit of 1%.
#[test]
fn a_breast_reconstructed_beyond_the_limit_is_an_error() {
    let phantom = medium_phantom();
    let scan = with_hole_above_right_nipple(&phantom, 20.0);
    let options = BreastOptions {
        max_reconstructed_share: 0.01,
        ..BreastOptions::default()
    };
    let error = build(&scan, &phantom.landmarks, &options).unwrap_err();
    println!("{error}");
    let BreastError::MostlyUnscanned {
        side,
        reconstructed_area_mm2,
        area_mm2,
        ..
    } = error
    else {
        panic!("{error:?}")
    };
    assert_eq!(side, Side::Right);
    let hole_area = scan_area_difference(&phantom.scan, &scan);
    assert!((reconstructed_area_mm2 - hole_area).abs() < 0.15 * hole_area);
    assert!(area_mm2 > 10.0 * hole_area);
    assert!(error.to_string().contains("was not seen by the scanner"));
    // The place shown is the hole: seen from the front, its centre lies at the hole's
    // (within 4 mm: the fill-in spreads its triangles evenly over the skin, and a hole
    // round seen from the front is tilted on the breast, so their mean leans towards the
    // steeper side; 1.9 mm here) and its radius is the hole's 20 mm, lengthened by the
    // breast's slope there (within 20-35 mm, a slope of up to 55 degrees; 28 mm here).
    let place = error.place().expect("the unseen skin has a place");
    let hole_centre = phantom.landmarks.get(LandmarkName::Pnr) + 35.0 * DVec3::Y;
    let off_mm = place.centre().truncate().distance(hole_centre.truncate());
    println!(
        "ringed {off_mm:.2} mm from the hole's centre, radius {:.1} mm",
        place.radius_mm
    );
    assert!(off_mm < 4.0, "{off_mm} mm");
    assert!((20.0..35.0).contains(&place.radius_mm), "{place:?}");
}

/// The distance (mm) from `point` to the closed polyline through `mesh`'s vertices `ring`.
fn distance_to_loop(mesh: &TriMesh, ring: &[u32], point: DVec3) -> f64 {
    (0..ring.len())
        .map(|k| {
            let a = mesh.positions[ring[k] as usize];
            let b = mesh.positions[ring[(k + 1) % ring.len()] as usize];
            let t = ((point - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            point.distance(a + t * (b - a))
        })
        .fold(f64::INFINITY, f64::min)
}

/// The area (mm²) `holed` lacks against `full`.
fn scan_area_difference(full: &TriMesh, holed: &TriMesh) -> f64 {
    full.area() - holed.area()
}

#[test]
fn a_curve_across_the_scan_border_is_an_error() {
    let phantom = medium_phantom();
    let scan = &phantom.scan;
    let mut points = default_points(scan, &phantom.landmarks);
    // PSMF, the fold's lowest point, pulled straight down onto the scan's lower border:
    // the spline beyond it runs off the scan.
    let topology = Topology::new(scan);
    let border = topology
        .boundary_loops(scan)
        .into_iter()
        .max_by_key(|l| l.len())
        .unwrap();
    let fold = points.left[1];
    let below = border
        .iter()
        .map(|&v| scan.positions[v as usize])
        .filter(|p| p.y < fold.y - 50.0)
        .min_by(|a, b| (a.x - fold.x).abs().total_cmp(&(b.x - fold.x).abs()))
        .unwrap();
    points.left[1] = below;
    let Err(error) = build(scan, &phantom.landmarks, &with_points(points.clone())) else {
        panic!("a curve across the border gave a model");
    };
    println!("{error}");
    assert!(
        matches!(
            error,
            BreastError::Curve {
                side: Side::Left,
                source: CurveError::LeavesMesh { .. },
                ..
            } | BreastError::CurveOnBorder {
                side: Side::Left,
                ..
            }
        ),
        "{error:?}"
    );
    // The place shown lies on the scan's border, where the curve meets it (1 µm: it is
    // a point of a border edge, up to rounding).
    let place = error.place().expect("a curve on the border has a place");
    let to_border_mm = distance_to_loop(scan, &border, place.centre());
    println!("ringed {to_border_mm:.2e} mm from the border");
    assert!(to_border_mm < 1e-3, "{to_border_mm} mm");
    // Farther out, the control point itself is off the scan.
    points.left[1] = below - 40.0 * DVec3::Y;
    let error = build(scan, &phantom.landmarks, &with_points(points)).unwrap_err();
    println!("{error}");
    assert!(
        matches!(
            error,
            BreastError::ControlPointOffSurface {
                side: Side::Left,
                index: 1,
                ..
            }
        ),
        "{error:?}"
    );
}

/// A model rebuilt from the control points it wrote (`control_points.json`, through its
/// JSON text) is the same model, bit for bit: the snapped points snap to themselves, so
/// a model folder reopened by `simulate` rebuilds the model it holds. Before, a point
/// snapped twice moved by a rounding step, and on one body in seventy that changed the
/// tetrahedral mesh and the folder was refused. On the phantom with its landmarks moved
/// along the skin (a few millimetres off their vertices, as a hand places them).
#[test]
fn a_model_rebuilt_from_its_control_points_is_the_same() {
    let phantom = medium_phantom();
    let mesh = &phantom.scan;
    let mut landmarks = phantom.landmarks.clone();
    let index = SurfaceIndex::new(mesh).unwrap();
    for (k, name) in LandmarkName::ALL.into_iter().enumerate() {
        let angle = k as f64 * 2.4;
        let step = DVec3::new(angle.cos(), angle.sin(), 0.3 * angle.cos()) * 2.5;
        landmarks.set(name, index.closest_point(landmarks.get(name) + step).point);
    }
    let first = build(mesh, &landmarks, &BreastOptions::default()).unwrap();
    let written = ControlPoints {
        left: first.left.control_points.clone(),
        right: first.right.control_points.clone(),
    };
    let read =
        ControlPoints::from_json(&written.to_json().to_string(), Path::new("cp.json")).unwrap();
    assert_eq!(read, written, "the JSON text keeps every bit");
    let options = BreastOptions {
        control_points: Some(read),
        ..BreastOptions::default()
    };
    let second = build(mesh, &landmarks, &options).unwrap();
    for side in Side::BOTH {
        let (a, b) = (first.breast(side), second.breast(side));
        assert_eq!(a.control_points, b.control_points, "{side}: snapped again");
        let along = |m: &BreastModel| -> Vec<DVec3> {
            m.breast(side)
                .curve
                .points
                .iter()
                .map(|p| p.position)
                .collect()
        };
        assert_eq!(along(&first), along(&second), "{side}: the cut curve");
        assert_eq!(
            a.volume_ml.to_bits(),
            b.volume_ml.to_bits(),
            "{side}: volume"
        );
    }
    assert_eq!(first.filled_base.positions, second.filled_base.positions);
}
