//! `plan::model`: the model folder of the phantom and of every shared scan, with the
//! closed surface read back from `closed_surface.ply` and checked to be watertight,
//! 2-manifold, outward and free of self-intersections, and the tetrahedral meshes read
//! back from `tets_level*.vtu` and checked against the request and the closed surface.
//!
//! Run with `cargo test --release -p plan --test model -- --nocapture` for the figures.

use anatomy::breast::Side;
use mesh::{Topology, manifold_report, self_intersections};
use phantom::PhantomParams;
use plan::model::{ModelOptions, ModelReport, build_model, load_model, write_model};
use plan::{MarkedScan, Scan, Silent};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Tetrahedra asked for on the finest level: the default. At 20,000 (about 9 mm spacing)
/// the closed surface, only a few centimetres thick at its edges, loses 2.5-3.5% of its
/// volume on level 0; at 60,000 (about 6 mm) about 1.3%. Meshing takes about 0.3 s.
const ELEMENTS: usize = plan::model::DEFAULT_ELEMENTS;

/// Builds and writes the model, checks the closed surface and the tetrahedral meshes as
/// written, prints the figures.
fn build_write_check(name: &str, marked: &MarkedScan, out: &Path) -> ModelReport {
    let options = ModelOptions {
        elements: ELEMENTS,
        ..Default::default()
    };
    let model = build_model(marked, &options, &Silent).unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let report = write_model(out, &model, &Silent).unwrap();
    let closed = mesh::io::read_mesh(&out.join("closed_surface.ply")).unwrap();
    let start = Instant::now();
    let manifold = manifold_report(&closed, &Topology::new(&closed));
    let crossings = self_intersections(&closed);
    let check_ms = start.elapsed().as_secs_f64() * 1e3;
    let volume_ml = closed.signed_volume() / 1000.0;
    println!(
        "{name}: breasts left {:.1} ml, right {:.1} ml; closed surface {:.1} ml \
         ({} triangles, box x {:.1}..{:.1} y {:.1}..{:.1} mm); {manifold}; \
         {} self-intersecting pairs; stitch angles {:.1}° / {:.1}°; \
         built in {:.0} ms (breasts {:.0}, closed surface {:.0}); checked in {check_ms:.0} ms",
        report.breast_volume_ml.left,
        report.breast_volume_ml.right,
        report.closed_surface_volume_ml,
        closed.triangle_count(),
        report.clip_box.x_min_mm,
        report.clip_box.x_max_mm,
        report.clip_box.y_min_mm,
        report.clip_box.y_max_mm,
        crossings.len(),
        report.max_stitch_angle_deg.left,
        report.max_stitch_angle_deg.right,
        report.timings.total_ms,
        report.timings.breast_model_ms,
        report.timings.closed_surface_ms,
    );
    assert!(manifold.is_watertight_manifold(), "{name}: {manifold}");
    assert!(crossings.is_empty(), "{name}: {crossings:?}");
    assert!(volume_ml > 0.0, "{name}: {volume_ml} ml");
    assert!(
        (volume_ml - report.closed_surface_volume_ml).abs() < 1e-6 * volume_ml,
        "{name}: the file's volume {volume_ml} ml"
    );
    check_tetrahedra(name, &report, out);
    report
}

/// The `tets_level*.vtu` files match the report; level 0 has about [`ELEMENTS`]
/// tetrahedra and the closed surface's volume; every level's dihedral angles are >= 8°.
fn check_tetrahedra(name: &str, report: &ModelReport, out: &Path) {
    let levels = report.levels.len();
    assert!(
        (1..=plan::model::MAX_TET_LEVELS).contains(&levels),
        "{name}: {levels} levels"
    );
    for level in &report.levels[1..] {
        assert!(
            level.nodes >= plan::model::MIN_COARSEST_NODES,
            "{name}: {level:?}"
        );
    }
    for (l, level) in report.levels.iter().enumerate() {
        println!(
            "{name}: level {l}: {} tets, {} nodes, spacing {:.2} mm, {:.1} ml, \
             dihedral {:.1}°..{:.1}°",
            level.elements,
            level.nodes,
            level.spacing_mm,
            level.volume_ml,
            level.min_dihedral_deg,
            level.max_dihedral_deg
        );
        let file = format!("tets_level{l}.vtu");
        assert!(report.files.contains(&file), "{name}: {file} not listed");
        let data = tetra::vtu::read_vtu(&out.join(&file)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(data.mesh.tet_count(), level.elements, "{name}: {file}");
        assert_eq!(data.mesh.vertex_count(), level.nodes, "{name}: {file}");
        assert!(
            level.min_dihedral_deg >= 8.0,
            "{name}: level {l} min dihedral {}°",
            level.min_dihedral_deg
        );
    }
    // Distances between level 0's boundary and the closed surface, sampled at the
    // vertices and triangle centroids of each.
    let closed_mesh = mesh::io::read_mesh(&out.join("closed_surface.ply")).unwrap();
    let level0 = tetra::vtu::read_vtu(&out.join("tets_level0.vtu"))
        .unwrap()
        .mesh;
    let boundary = level0.boundary().mesh;
    let distances = |from: &mesh::TriMesh, to: &mesh::TriMesh| {
        let index = mesh::SurfaceIndex::new(to).unwrap();
        let centroids = from.triangles.iter().map(|t| {
            t.iter()
                .map(|&v| from.positions[v as usize])
                .sum::<mesh::DVec3>()
                / 3.0
        });
        let mut d: Vec<f64> = from
            .positions
            .iter()
            .copied()
            .chain(centroids)
            .map(|p| index.closest_point(p).distance)
            .collect();
        d.sort_by(f64::total_cmp);
        d
    };
    let outward = distances(&boundary, &closed_mesh);
    let inward = distances(&closed_mesh, &boundary);
    let spacing = report.levels[0].spacing_mm;
    let quantile = |d: &[f64], q: f64| d[((d.len() - 1) as f64 * q) as usize];
    println!(
        "{name}: level 0 ({spacing:.2} mm spacing) boundary to closed surface: max {:.3} mm; \
         closed surface to boundary: median {:.3}, 99% {:.3}, 99.9% {:.3}, max {:.3} mm",
        outward.last().unwrap(),
        quantile(&inward, 0.5),
        quantile(&inward, 0.99),
        quantile(&inward, 0.999),
        inward.last().unwrap(),
    );
    // Stuffing's bound: the boundary lies within half a lattice spacing of the surface.
    // The other way round it does not hold: where the slab is thinner than the lattice
    // (its rim at the clip planes) the mesh does not reach the surface.
    assert!(*outward.last().unwrap() <= 0.5 * spacing, "{name}");
    let finest = &report.levels[0];
    let miss = (finest.elements as f64 - ELEMENTS as f64).abs() / ELEMENTS as f64;
    assert!(
        miss <= 0.2,
        "{name}: {} tets for {ELEMENTS}",
        finest.elements
    );
    let closed = report.closed_surface_volume_ml;
    assert!(
        (finest.volume_ml - closed).abs() <= 0.02 * closed,
        "{name}: level 0 {} ml, closed surface {closed} ml",
        finest.volume_ml
    );
    let min = report
        .levels
        .iter()
        .map(|l| l.min_dihedral_deg)
        .fold(f64::INFINITY, f64::min);
    assert_eq!(report.min_dihedral_deg, min, "{name}");
}

#[test]
fn phantom_model_folder() {
    let phantom = phantom::generate(&PhantomParams::default());
    let dir = tempfile::tempdir().unwrap();
    let marked = MarkedScan::new(
        Scan::from_mesh(phantom.scan.clone(), Path::new("phantom.ply")).unwrap(),
        phantom.landmarks.clone(),
        Path::new("phantom.json"),
        None,
        &Silent,
    )
    .unwrap();
    let report = build_write_check("phantom", &marked, dir.path());
    for file in &report.files {
        assert!(dir.path().join(file).is_file(), "{file}");
    }
    // The control points come back from their file unchanged.
    let points = anatomy::ControlPoints::read(&dir.path().join("control_points.json")).unwrap();
    assert_eq!(points.left.len(), report.counts.control_points.left);
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

#[test]
fn every_shared_scan_gives_a_watertight_closed_surface() {
    let Some(dir) = shared_scans() else { return };
    let out = tempfile::tempdir().unwrap();
    for name in ["v02_average", "pair1_pre", "pair1_post"] {
        let marked = MarkedScan::load(
            &dir.join(format!("{name}.ply")),
            &dir.join(format!("{name}_landmarks.json")),
            None,
            &Silent,
        )
        .unwrap();
        build_write_check(name, &marked, &out.path().join(name));
    }
}

/// A refined finest level on a shared scan: every level keeps its dihedral angles >= 8°,
/// level 0 keeps the closed surface's volume within 2%, and every tetrahedron with its
/// centroid within the band of a fill-in (recomputed here from `fill_*.ply` and
/// `tets_level0.vtu`) has edges of at most the bound; the uniform levels follow it.
#[test]
fn refined_level_around_the_fill_ins() {
    let Some(dir) = shared_scans() else { return };
    let name = "pair1_post";
    let marked = MarkedScan::load(
        &dir.join(format!("{name}.ply")),
        &dir.join(format!("{name}_landmarks.json")),
        None,
        &Silent,
    )
    .unwrap();
    let refinement = plan::model::Refinement::default();
    let options = ModelOptions {
        refinement: Some(refinement),
        ..Default::default()
    };
    let model = build_model(&marked, &options, &Silent).unwrap();
    let out = tempfile::tempdir().unwrap();
    let report = write_model(out.path(), &model, &Silent).unwrap();
    let refined = report.refinement.expect("refinement report");
    assert!(report.levels.len() >= 2 && report.levels.len() <= plan::model::MAX_TET_LEVELS + 1);
    for (l, level) in report.levels.iter().enumerate() {
        println!(
            "{name} refined: level {l}: {} tets, spacing {:.2} mm, {:.1} ml, dihedral \
             {:.1}°..{:.1}°",
            level.elements,
            level.spacing_mm,
            level.volume_ml,
            level.min_dihedral_deg,
            level.max_dihedral_deg
        );
        assert!(level.min_dihedral_deg >= 8.0, "level {l}");
    }
    let closed = report.closed_surface_volume_ml;
    assert!((report.levels[0].volume_ml - closed).abs() <= 0.02 * closed);
    let uniform = report.levels[1].elements as f64;
    assert!((uniform - ELEMENTS as f64).abs() <= 0.2 * ELEMENTS as f64);
    assert_eq!(report.levels[1].spacing_mm, report.levels[0].spacing_mm);

    let fills: Vec<mesh::SurfaceIndex> = ["fill_left.ply", "fill_right.ply"]
        .iter()
        .map(|f| {
            mesh::SurfaceIndex::new(&mesh::io::read_mesh(&out.path().join(f)).unwrap()).unwrap()
        })
        .collect();
    let level0 = tetra::vtu::read_vtu(&out.path().join("tets_level0.vtu"))
        .unwrap()
        .mesh;
    let (mut longest, mut in_band) = (0.0f64, 0usize);
    for t in 0..level0.tet_count() {
        let p = level0.tet_positions(t);
        let centroid = (p[0] + p[1] + p[2] + p[3]) / 4.0;
        if fills.iter().any(|f| {
            f.closest_point_within(centroid, refinement.band_mm)
                .is_some()
        }) {
            in_band += 1;
            for i in 0..4 {
                for j in i + 1..4 {
                    longest = longest.max(p[i].distance(p[j]));
                }
            }
        }
    }
    println!(
        "{name} refined: {in_band} tets in the {} mm band (report {}), longest edge {longest:.3} mm \
         (report {:.3}), band spacing {:.2} mm",
        refinement.band_mm,
        refined.elements_in_band,
        refined.longest_edge_in_band_mm,
        refined.band_spacing_mm
    );
    assert_eq!(in_band, refined.elements_in_band);
    // The VTU holds positions in shortest round-trip form, so the lengths agree exactly.
    assert_eq!(longest, refined.longest_edge_in_band_mm);
    assert!(longest <= refinement.max_edge_mm, "{longest}");
}

/// A model folder of a scan with holes reopens as the model it holds. The default
/// phantom scanned with occlusion lacks the underside of each breast, which the model
/// reconstructs; `mammaplan simulate` rebuilds the model from the scan and landmark
/// files and the folder's control points (`load_model`), and must get the same
/// reconstruction, breast volumes, closed surface and tetrahedra to the bit (meshing is
/// deterministic; a difference would move the prediction between `model` and
/// `simulate`).
#[test]
fn a_model_folder_of_a_scan_with_holes_reopens_as_the_same_model() {
    let dir = tempfile::tempdir().unwrap();
    let phantom = phantom::generate(&PhantomParams {
        occlusion: true,
        ..PhantomParams::default()
    });
    let scan_path = dir.path().join("scan.ply");
    let landmarks_path = dir.path().join("landmarks.json");
    mesh::io::write_mesh(&scan_path, &phantom.scan).unwrap();
    phantom
        .landmarks
        .write(&landmarks_path, serde_json::Map::new())
        .unwrap();
    let marked = MarkedScan::load_in(&scan_path, None, &landmarks_path, None, &Silent).unwrap();
    let model = build_model(&marked, &ModelOptions::default(), &Silent).unwrap();
    let folder = dir.path().join("model");
    write_model(&folder, &model, &Silent).unwrap();
    let (_, reopened) = load_model(&folder, &Silent).unwrap();

    assert!(!model.breasts.holes_closed.is_empty(), "the scan has holes");
    assert_eq!(
        model.breasts.holes_closed.len(),
        reopened.breasts.holes_closed.len()
    );
    for side in Side::BOTH {
        let (built, again) = (model.breasts.breast(side), reopened.breasts.breast(side));
        assert!(
            built.reconstructed.area_share > 0.01,
            "{side}: nothing reconstructed"
        );
        assert_eq!(built.control_points, again.control_points, "{side}");
        assert_eq!(
            built.reconstructed.vertex_flags, again.reconstructed.vertex_flags,
            "{side}"
        );
        // the breast's skin, reconstructed underside included, and the fill-in behind it
        assert_eq!(
            built.patch.mesh.positions, again.patch.mesh.positions,
            "{side}"
        );
        assert_eq!(
            built.fill.mesh.positions, again.fill.mesh.positions,
            "{side}"
        );
        assert_eq!(
            built.volume_ml.to_bits(),
            again.volume_ml.to_bits(),
            "{side}"
        );
    }
    assert_eq!(
        model.closed_surface.mesh.positions,
        reopened.closed_surface.mesh.positions
    );
    assert_eq!(
        model.closed_surface.mesh.triangles,
        reopened.closed_surface.mesh.triangles
    );
    assert_eq!(model.tets.levels.len(), reopened.tets.levels.len());
    for (built, again) in model.tets.levels.iter().zip(&reopened.tets.levels) {
        assert_eq!(built.mesh.positions, again.mesh.positions);
        assert_eq!(built.mesh.tets, again.mesh.tets);
    }
}
