//! The simulation on the symmetric phantom (60,000 elements): volumes, symmetry,
//! directions, gravity, mesh quality, errors. Run with
//! `cargo test --release -p simulation --test phantom -- --nocapture` for the figures.

mod common;

use anatomy::breast::Side;
use anatomy::{AnatomicalFrame, LandmarkName};
use glam::DVec3;
use implant::{Catalog, ImplantShape, ImplantSpec, RoundImplant};
use simulation::{AnchorRule, Placement, Simulation, SimulationError, SimulationOptions};
use std::sync::OnceLock;

/// The default implant of the tests: the catalog's moderate-profile 120 mm round
/// implant (about 250 ml).
fn implant() -> ImplantShape {
    *Catalog::builtin().get("R-MOD-120").unwrap().shape()
}

/// The same side's point mirrored across the midsagittal plane (frame `x -> -x`).
fn mirror(frame: &AnatomicalFrame, p: DVec3) -> DVec3 {
    let mut q = frame.to_local(p);
    q.x = -q.x;
    frame.to_file(q)
}

/// The baseline: both breasts with [`implant`], stage 1 only (no gravity), solved.
struct Baseline {
    sim: Simulation,
    volumes: [simulation::BreastVolume; 2],
    scan: Vec<DVec3>,
}

fn baseline() -> &'static Baseline {
    static BASELINE: OnceLock<Baseline> = OnceLock::new();
    BASELINE.get_or_init(|| {
        let p = common::phantom();
        let mut sim = p.session(SimulationOptions::default());
        for side in Side::BOTH {
            sim.set_implant(side, implant(), Placement::default())
                .unwrap();
        }
        let report = sim.run(true).unwrap();
        println!("baseline: {report:?}");
        assert!(report.implant.converged, "{report:?}");
        let volumes = sim.breast_volumes();
        let scan = sim.scan_positions();
        Baseline { sim, volumes, scan }
    })
}

#[test]
fn volume_grows_by_the_implant_volume() {
    let b = baseline();
    let v = implant().volume_ml();
    for (side, vol) in Side::BOTH.iter().zip(&b.volumes) {
        let t = &b.sim.implant(*side).unwrap().template;
        let added = vol.volume_ml - vol.volume_before_ml;
        println!(
            "{side}: breast {:.1} -> {:.1} ml (+{added:.1} ml; moved fill-in {:.1} ml); implant {v:.1} ml, \
             template {:.1} ml; {} implant vertices, {} fixed, {} implant elements",
            vol.volume_before_ml,
            vol.volume_ml,
            vol.volume_moved_fill_ml,
            t.template_volume_ml,
            t.implant_vertices.len(),
            t.fixed_vertices.len(),
            t.implant_elements.len()
        );
        assert!(
            (added - v).abs() <= 0.10 * v,
            "{side}: added {added:.1} ml for a {v:.1} ml implant"
        );
    }
}

/// A 115 mm implant (222 ml) under a large cup (555 ml) lies on the native fill-in and
/// pushes the breast's medial border forwards by up to 8 mm. The breast over the chest
/// wall, which the implant does not move, gains the implant's volume less what the
/// tissue carries beyond the border: within 10%, the bound issue 22 holds every body to
/// (measured 0.954). A fill-in rebuilt on the
/// moved border rises with it and takes volume out (measured 0.45 of the implant): it is
/// reported apart, and must come out lower.
#[test]
fn a_large_breast_gains_the_implants_volume_over_the_chest_wall() {
    let patient = common::large_phantom();
    let mut sim = patient.session(SimulationOptions::default());
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    for side in Side::BOTH {
        sim.set_implant(side, shape, Placement::default()).unwrap();
        assert!(sim.pocket_bounds(side).is_none(), "{side}: in a pocket");
    }
    let report = sim.run(false).unwrap();
    assert!(report.implant.converged, "{report:?}");
    let implant_ml = shape.volume_ml();
    for (side, vol) in Side::BOTH.iter().zip(sim.breast_volumes()) {
        let gain = (vol.volume_ml - vol.volume_before_ml) / implant_ml;
        println!(
            "{side}: {:.1} -> {:.1} ml, gain {gain:.3} of {implant_ml:.1} ml; rebuilt fill-in {:?} ml",
            vol.volume_before_ml, vol.volume_ml, vol.volume_rebuilt_fill_ml
        );
        assert!((gain - 1.0).abs() <= 0.10, "{side}: gain {gain:.3}");
        let rebuilt = vol.volume_rebuilt_fill_ml.unwrap();
        assert!(rebuilt < vol.volume_ml, "{side}: {rebuilt} ml");
    }
}

/// A 115 mm implant (222 ml) under a small hanging cup lies in the pocket with the fold
/// lowered 25-30 mm (the ICE rule), so a fifth of it lies below the native fold. The
/// pocket's floor lies at the fold the implant got, which the fit moves from the rule's
/// lowering (1.9 mm up here), to rounding. The breast after surgery, measured over the
/// native breast and the skin over the implant, gains the implant's volume within 10%
/// (the envelope's band; Tepper et al. 2008 measured 1.9% on real augmentations;
/// measured 0.965). Measured over the native breast
/// alone it gained 0.78 of the implant, so the check can fail. The template is scaled to
/// insert the implant's volume over the part of the bed the mesh reaches, which lies
/// within 2% of the implant's volume from its closed form (the whole footprint lies inside
/// the mesh; the 2% are the bed sections' linear thickness over the 7 mm elements).
#[test]
fn a_lowered_fold_gains_the_implants_volume_over_the_skin_it_lies_under() {
    let patient = common::small_hanging_phantom();
    let mut sim = patient.session(SimulationOptions::default());
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    let implant_ml = shape.volume_ml();
    for side in Side::BOTH {
        let placed = sim
            .set_implant(side, shape, Placement::default())
            .unwrap()
            .clone();
        assert!(
            placed.fold_lowering_mm > 20.0,
            "{side}: fold lowered {:.1} mm",
            placed.fold_lowering_mm
        );
        // the pocket's bounds end at the fold the implant got, which the fit moved from
        // the rule's lowering (else the check below could not tell stale bounds)
        let rule_mm = sim.fold_lowering_mm(side, &shape);
        let floor_y = sim.pocket_bounds(side).unwrap().floor_y_mm;
        let planned_y = simulation::pocket::planned_fold_y_mm(
            side,
            sim.frame(),
            &patient.marked.landmarks,
            placed.fold_lowering_mm,
        );
        println!(
            "{side}: rule's lowering {rule_mm:.1} mm, after the fit {:.1} mm; pocket floor \
             {:.1} mm below the planned fold",
            placed.fold_lowering_mm,
            planned_y - floor_y
        );
        assert!(
            (rule_mm - placed.fold_lowering_mm).abs() > 0.5,
            "{side}: the fit kept the rule's {rule_mm} mm"
        );
        assert!(
            (planned_y - floor_y).abs() < 1e-9,
            "{side}: floor {floor_y} vs planned {planned_y}"
        );
        let t = &placed.template;
        println!(
            "{side}: fold lowered {:.1} mm; implant {implant_ml:.1} ml, covered {:.1} ml, \
             template {:.1} ml, scaled by {:.3}",
            placed.fold_lowering_mm, t.covered_volume_ml, t.template_volume_ml, t.scale
        );
        // Over a bed curved like this chest the unscaled template overshoots, so the
        // factor lies strictly inside (0, 1).
        assert!(
            (t.template_volume_ml - t.covered_volume_ml).abs() < 1e-3
                && t.scale > 0.0
                && t.scale < 1.0,
            "{side}: not scaled ({})",
            t.scale
        );
        assert!(
            (t.covered_volume_ml / implant_ml - 1.0).abs() < 0.02,
            "{side}"
        );
    }
    let report = sim.run(false).unwrap();
    assert!(report.implant.converged, "{report:?}");
    for (side, vol) in Side::BOTH.iter().zip(sim.breast_volumes()) {
        let gain = (vol.volume_ml - vol.volume_before_ml) / implant_ml;
        println!(
            "{side}: {:.1} -> {:.1} ml, gain {gain:.3} of {implant_ml:.1} ml",
            vol.volume_before_ml, vol.volume_ml
        );
        assert!((gain - 1.0).abs() <= 0.10, "{side}: gain {gain:.3}");
    }
}

#[test]
fn symmetric_implants_give_symmetric_breasts() {
    let b = baseline();
    let p = common::phantom();
    let [l, r] = b.volumes;
    let rel = (l.volume_ml - r.volume_ml).abs() / (0.5 * (l.volume_ml + r.volume_ml));
    println!(
        "left {:.2} ml, right {:.2} ml ({:.2}%)",
        l.volume_ml,
        r.volume_ml,
        rel * 100.0
    );
    assert!(rel < 0.01);
    // mirror symmetry of the scan's displacement: each left vertex against its mirror
    // vertex (the phantom's scan is mirror symmetric vertex by vertex)
    let frame = p.frame();
    let scan = &p.marked.scan.mesh;
    let rest = &scan.positions;
    let d: Vec<DVec3> = b.scan.iter().zip(rest).map(|(a, r)| *a - *r).collect();
    let scan_index = mesh::SurfaceIndex::new(scan).unwrap();
    let mirror_vertex = |i: usize| {
        let q = mirror(frame, rest[i]);
        let hit = scan_index.closest_point(q);
        let v = scan.triangles[hit.triangle]
            .into_iter()
            .min_by(|&a, &c| {
                q.distance(rest[a as usize])
                    .total_cmp(&q.distance(rest[c as usize]))
            })
            .unwrap() as usize;
        assert!(q.distance(rest[v]) < 1e-6, "no mirror vertex of {i}");
        v
    };
    // the left breast's skin: scan vertices inside the left closed breast surface's
    // bounding box, in front of its fill-in (the patch's own vertices are the cut mesh's)
    let patch = &p.model.breasts.left.patch.mesh;
    let index = mesh::SurfaceIndex::new(patch).unwrap();
    let left: Vec<usize> = (0..rest.len())
        .filter(|&i| {
            frame.to_local(rest[i]).x > 1.0 && index.closest_point(rest[i]).distance < 1e-6
        })
        .collect();
    let all: Vec<usize> = (0..rest.len())
        .filter(|&i| frame.to_local(rest[i]).x > 1.0 && d[i].length() > 0.1)
        .collect();
    {
        let dm: Vec<DVec3> = all.iter().map(|&i| d[mirror_vertex(i)]).collect();
        let axes = frame.axes;
        let worst = all
            .iter()
            .zip(&dm)
            .map(|(&i, m)| {
                let mut q = axes.transpose() * *m;
                q.x = -q.x;
                (d[i] - axes * q).length()
            })
            .fold(0.0, f64::max);
        println!("whole scan (displaced by > 0.1 mm): max mirror asymmetry {worst:.2} mm");
    }
    let dm: Vec<DVec3> = left.iter().map(|&i| d[mirror_vertex(i)]).collect();
    let axes = frame.axes;
    let flip = |v: DVec3| {
        let mut q = axes.transpose() * v;
        q.x = -q.x;
        axes * q
    };
    let mut worst: f64 = 0.0;
    let mut sum2 = 0.0;
    let mut at = 0;
    let mut over = 0;
    let mut errors = Vec::with_capacity(left.len());
    for (k, &i) in left.iter().enumerate() {
        let e = (d[i] - flip(dm[k])).length();
        errors.push(e);
        if e > worst {
            worst = e;
            at = i;
        }
        if e > 0.5 {
            over += 1;
        }
        sum2 += e * e;
    }
    println!(
        "worst at {:.1?}: displacement {:.2?}; {over} vertices over 0.5 mm",
        frame.to_local(rest[at]).to_array(),
        (axes.transpose() * d[at]).to_array()
    );
    let rms = (sum2 / left.len() as f64).sqrt();
    let max_d = d.iter().map(|x| x.length()).fold(0.0, f64::max);
    println!(
        "mirror asymmetry over the {} vertices of the left breast's skin: max {worst:.3} mm, rms {rms:.3} mm \
         (largest displacement {max_d:.1} mm)",
        left.len()
    );
    errors.sort_by(f64::total_cmp);
    let p99 = errors[errors.len() * 99 / 100];
    let p95 = errors[errors.len() * 95 / 100];
    println!("95th percentile {p95:.3} mm, 99th percentile {p99:.3} mm");
    // The bound: 0.5 mm everywhere. The lattice is centred on the (symmetric)
    // closed surface, so the mesh is mirror symmetric and what remains is round-off in
    // the surface, the template and the solve: measured max 0.16 mm, rms 0.005 mm.
    assert!(worst < 0.5, "max asymmetry {worst} mm");
    assert!(rms < 0.05, "rms asymmetry {rms} mm");
}

#[test]
fn nipple_moves_forward_by_a_fraction_of_the_projection() {
    let b = baseline();
    let p = common::phantom();
    let moved = b.sim.landmarks();
    let projection = implant().projection_mm();
    for side in Side::BOTH {
        let d = common::nipple(&moved, side) - common::nipple(p.landmarks(), side);
        let local = p.frame().axes.transpose() * d;
        println!(
            "{side} nipple moved {:.1?} mm (frame), anterior {:.2} x projection",
            local.to_array(),
            local.z / projection
        );
        assert!(local.z >= 0.3 * projection && local.z <= 1.2 * projection);
    }
}

#[test]
fn no_inverted_elements_and_no_spikes() {
    let b = baseline();
    let p = common::phantom();
    let inverted = b.sim.inverted_elements();
    assert!(inverted.is_empty(), "{} inverted elements", inverted.len());
    let worst = common::largest_edge_stretch(p, &b.scan);
    assert!(worst <= 3.0);
}

/// Left implant only, solved, from a fresh session; then `placement` (warm start).
fn left_centres(
    placements: &[Placement],
    shapes: &[ImplantShape],
) -> Vec<simulation::BreastVolume> {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions::default());
    let mut out = Vec::new();
    for (placement, shape) in placements.iter().zip(shapes) {
        sim.set_implant(Side::Left, *shape, *placement).unwrap();
        let report = sim.run(true).unwrap();
        assert!(report.implant.converged, "{report:?}");
        out.push(sim.breast_volumes()[0]);
    }
    out
}

#[test]
fn moving_the_implant_up_moves_the_breast_up() {
    let v = left_centres(
        &[Placement::default(), Placement::moved(0.0, 10.0, 0.0)],
        &[implant(), implant()],
    );
    let p = common::phantom();
    let y = |c: DVec3| p.frame().to_local(c).y;
    println!(
        "centre of volume y: before {:.2}, default {:.2}, moved up 10 mm {:.2} (mm, frame)",
        y(v[0].centre_before_mm),
        y(v[0].centre_mm),
        y(v[1].centre_mm)
    );
    assert!(y(v[1].centre_mm) > y(v[0].centre_mm));
}

#[test]
fn a_larger_implant_gives_a_larger_breast() {
    let catalog = Catalog::builtin();
    let small = *catalog.get("R-MOD-110").unwrap().shape();
    let large = *catalog.get("R-MOD-120").unwrap().shape();
    let v = left_centres(
        &[Placement::default(), Placement::default()],
        &[small, large],
    );
    println!(
        "R-MOD-110 ({:.0} ml): {:.1} ml; R-MOD-120 ({:.0} ml): {:.1} ml",
        small.volume_ml(),
        v[0].volume_ml,
        large.volume_ml(),
        v[1].volume_ml
    );
    assert!(v[1].volume_ml > v[0].volume_ml);
}

/// The implant's added weight moves the nipple down by more than 0.25 mm, about eight
/// times the skin's distance from its equilibrium at the default tolerance (0.03 mm,
/// docs/dev/standing-frame.md; figures in docs/dev/model-on-every-body.md, session 52).
#[test]
fn gravity_correction_moves_the_nipple_down() {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions::default());
    sim.set_implant(Side::Left, implant(), Placement::default())
        .unwrap();
    let report = sim.run(false).unwrap();
    println!("{report:?}");
    let gravity = report.gravity.unwrap();
    let before_gravity = sim.displacement_before_gravity().unwrap().to_vec();
    let at = sim.displacements_at(&[common::nipple(p.landmarks(), Side::Left)]);
    let frame = p.frame();
    let nipple = common::nipple(p.landmarks(), Side::Left);
    // the nipple after the correction by the finite-element field (the landmarks follow
    // the scan's smoothed displacement, tested in `landmarks_stay_on_the_simulated_scan`)
    let after = nipple + at[0];
    // the nipple before the correction, from the stage-1 displacement
    let map = simulation::PointMap::new(&sim.field_locator(), &[nipple], sim.options().falloff_mm);
    let stage1 = nipple + map.displacements(&before_gravity)[0];
    let drop = frame.to_local(after).y - frame.to_local(stage1).y;
    println!(
        "nipple: stage 1 {:.1?}, gravity-corrected {:.1?} (frame mm): {drop:.2} mm vertically; \
         {} cycles, relative residual {:.1e}; {} inverted elements",
        frame.to_local(stage1).to_array(),
        frame.to_local(after).to_array(),
        gravity.cycles,
        gravity.relative_residual,
        sim.inverted_elements().len()
    );
    assert!(drop < -0.25, "the nipple moved {drop} mm vertically");
}

#[test]
fn bad_implants_are_refused_clearly() {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions::default());
    // larger than the fill-in
    let huge: ImplantShape = RoundImplant::new(200.0, 60.0).unwrap().into();
    let e = sim
        .set_implant(Side::Left, huge, Placement::default())
        .unwrap_err();
    println!("{e}");
    // wider than the fill-in, and than the pocket between the midline and the anterior
    // axillary line (the pocket is tried first: the ICE rule lowers the fold for it)
    assert!(matches!(
        e,
        SimulationError::ImplantLargerThanFootprint {
            side: Side::Left,
            ..
        } | SimulationError::PocketLimit {
            side: Side::Left,
            ..
        }
    ));
    assert!(sim.implant(Side::Left).is_none());
    // moved off the bed
    let e = sim
        .set_implant(Side::Left, implant(), Placement::moved(0.0, 200.0, 0.0))
        .unwrap_err();
    println!("{e}");
    assert!(matches!(e, SimulationError::AnchorOffFillIn { .. }));
    // too deep
    let e = sim
        .set_implant(Side::Left, implant(), Placement::moved(0.0, 0.0, -30.0))
        .unwrap_err();
    println!("{e}");
    assert!(matches!(e, SimulationError::BadPlacement { .. }));
    // bad dimensions and unknown ids come from the implant crate
    let e = ImplantSpec::parse("round:diameter=0,projection=30").unwrap_err();
    println!("{e}");
    let e = ImplantSpec::parse("catalog:R-NONE-999")
        .unwrap()
        .resolve(&Catalog::builtin())
        .unwrap_err();
    println!("{e}");
    // nothing was placed
    assert!(sim.implant(Side::Left).is_none());
}

/// The bony landmarks that register a post-operative scan onto the prediction
/// (`anatomy::register::BONY_LANDMARKS`: Pcl, Pcr, Pj, Px) stay where they were: their
/// RMS movement is under 1 mm, a third of the paper's clinical accuracy (2.1-3.3 mm RMS),
/// so that registering on them cannot shift a comparison by a clinically visible amount.
/// The clavicle points and the sternal notch, over 100 mm from both cut curves, each move
/// less than 0.2 mm (measured 0.13 mm at Pcl with the skin as a membrane and twice the
/// compression penalty; 0.09 with the skin as stiffened outer elements and once). Px, on the midline below both curves,
/// moves most: the skin over the sternum is continuous with the breasts', and the model
/// does not tie it to the bone (docs/dev/model-on-every-body.md).
#[test]
fn landmarks_off_the_breasts_stay() {
    use anatomy::register::{BONY_LANDMARKS, RigidTransform, landmark_rms_mm};
    let b = baseline();
    let p = common::phantom();
    let moved = b.sim.landmarks();
    for name in BONY_LANDMARKS {
        let d = moved.get(name).distance(p.landmarks().get(name));
        println!("{name:?} moved {d:.3} mm");
        if name != LandmarkName::Px {
            assert!(d < 0.2, "{name:?} moved {d} mm");
        }
    }
    let rms_mm = landmark_rms_mm(&moved, p.landmarks(), &RigidTransform::IDENTITY);
    println!("bony landmarks moved {rms_mm:.3} mm RMS");
    assert!(rms_mm < 1.0, "{rms_mm}");
}

#[test]
fn an_anatomic_implant_turned_upside_down_fills_the_upper_pole() {
    // An anatomic implant is fuller below its centre (paper eqs. 5-10); turned by 180°
    // about the bed's normal its fuller part lies above, so the breast's centre of
    // volume ends higher. A round implant turned by 90° is the same implant.
    let catalog = Catalog::builtin();
    let anatomic = *catalog.get("A-FM-115").unwrap().shape();
    let turned = |deg: f64| Placement {
        rotation_deg: deg,
        ..Placement::default()
    };
    let v = left_centres(&[turned(0.0), turned(180.0)], &[anatomic, anatomic]);
    let p = common::phantom();
    let y = |c: DVec3| p.frame().to_local(c).y;
    println!(
        "anatomic centre of volume y: upright {:.2}, upside down {:.2} (mm, frame); {:.1} / {:.1} ml",
        y(v[0].centre_mm),
        y(v[1].centre_mm),
        v[0].volume_ml,
        v[1].volume_ml
    );
    assert!(y(v[1].centre_mm) > y(v[0].centre_mm) + 0.1);
    let round = left_centres(&[turned(0.0), turned(90.0)], &[implant(), implant()]);
    println!(
        "round turned by 90°: {:.3} / {:.3} ml",
        round[0].volume_ml, round[1].volume_ml
    );
    // the same implant: the templates sample the same rotationally symmetric thickness
    // at the same points (up to round-off in the local frame), so the volumes agree
    // far inside the solver's 1e-3 tolerance
    assert!((round[0].volume_ml - round[1].volume_ml).abs() < 0.5);
}

/// The landmarks move with the simulated scan: each stays as far from the simulated
/// surface as it was from the scan (the phantom's landmarks lie on it), to round-off
/// (1e-9 mm: a barycentric combination of the moved vertices).
#[test]
fn landmarks_stay_on_the_simulated_scan() {
    let b = baseline();
    let p = common::phantom();
    let rest = &p.marked.scan.mesh;
    let mut simulated = rest.clone();
    simulated.positions = b.scan.clone();
    let rest_index = mesh::SurfaceIndex::new(rest).unwrap();
    let simulated_index = mesh::SurfaceIndex::new(&simulated).unwrap();
    let moved = b.sim.landmarks();
    for ((name, before), (_, after)) in p.landmarks().iter().zip(moved.iter()) {
        let off_before = rest_index.closest_point(before).distance;
        let off_after = simulated_index.closest_point(after).distance;
        assert!(
            off_after <= off_before + 1e-9,
            "{name}: {off_before} -> {off_after} mm"
        );
    }
}

/// The scan's displacement (the finite-element field carried to the scan, smoothed only
/// where it can be non-zero) has, to the last bit, the numbers of the smoother over the
/// whole scan: tolerance 0, the same operations in the same order (see
/// `simulation::field::SurfaceSmoother::with_support`). The two composed into one sparse
/// map (`simulation::carry::ScanCarry`, as the session composes it) give it within
/// 5e-3 mm: its pruned terms and single-precision weights and sums change the sums by
/// far less than a scanner's noise (0.2 mm)
/// or the discretisation's error (millimetres), while a wrong composition is off by
/// millimetres. A session in the same state answers `scan_positions` with the two steps'
/// numbers before it has the composed map and with the map's after, each to the bit.
#[test]
fn the_scan_displacement_equals_the_smoothing_over_the_whole_scan() {
    let b = baseline();
    let p = common::phantom();
    let scan = &p.marked.scan.mesh;
    let sim = &b.sim;
    let map = simulation::PointMap::new(
        &sim.field_locator(),
        &scan.positions,
        sim.options().falloff_mm,
    );
    let mut expected = map.displacements(sim.displacement());
    let full = simulation::field::SurfaceSmoother::new(scan, sim.scan_smoothing_mm());
    full.apply(&mut expected);
    let bits = |field: &[DVec3]| -> Vec<[u64; 3]> {
        field
            .iter()
            .map(|d| d.to_array().map(f64::to_bits))
            .collect()
    };
    let moved = sim.scan_displacements();
    let still = moved.iter().filter(|d| **d == DVec3::ZERO).count();
    println!(
        "scan: {} vertices, {still} not moved, {} smoothing steps",
        moved.len(),
        full.iterations()
    );
    assert!(still > 0 && still < moved.len());
    assert!(bits(&moved) == bits(&expected));

    let t = std::time::Instant::now();
    let carry = sim.scan_carry_job()();
    println!("TIMING compose {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
    let mut hist = [0usize; 6];
    let mut terms = [0usize; 6];
    for pnt in 0..map.len() {
        let n = map.terms(pnt).count();
        let b = match n {
            0 => 0,
            1..=4 => 1,
            5..=20 => 2,
            21..=100 => 3,
            101..=400 => 4,
            _ => 5,
        };
        hist[b] += 1;
        terms[b] += n;
    }
    println!("TIMING P rows by size (0,1-4,5-20,21-100,101-400,>400): {hist:?} terms {terms:?}");
    let composed = carry.displacements(sim.displacement());
    // the positions in one pass, against the rest positions moved by the two steps
    let positions = carry.positions(&scan.positions, sim.displacement());
    let position_error = (positions.iter().zip(&expected).zip(&scan.positions))
        .map(|((p, d), r)| p.distance(*r + *d))
        .fold(0.0, f64::max);
    assert!(position_error <= 5e-3, "{position_error} mm");
    let error = (composed.iter().zip(&expected))
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f64::max);
    let largest = expected.iter().map(|d| d.length()).fold(0.0, f64::max);
    println!(
        "composed: {} terms, {:.1} per moved vertex; off by at most {error:.1e} mm of {largest:.1} mm",
        carry.term_count(),
        carry.term_count() as f64 / (moved.len() - still) as f64
    );
    assert!(error <= 5e-3, "{error} mm");

    // A session in the same state answers through the composed map once it has it: the
    // same numbers as the map's own positions, to the bit.
    let mut own = p.session(SimulationOptions::default());
    own.restore(&sim.solved_state()).unwrap();
    let two_steps = own.scan_positions();
    assert!(
        own.use_scan_carry(carry),
        "the composed map fits its session"
    );
    let carried = own.scan_positions();
    assert!(bits(&carried) == bits(&positions));
    let rest_plus_expected: Vec<DVec3> = (scan.positions.iter().zip(&expected))
        .map(|(p, d)| *p + *d)
        .collect();
    assert!(bits(&two_steps) == bits(&rest_plus_expected));
}

/// `AnchorRule::BehindNipple` (`simulate --anchor behind-nipple`): the default anchor is
/// the nipple's own bed parameters `(u, v)` (a known answer, exact), where
/// `AnchorRule::FootprintCentre` centres the implant on the footprint, which on the
/// phantom lies 34 mm above the nipple. The phantom's nipple sits so low that even a 90 mm implant overhangs the fold
/// there, so the session moves it up until it fits: the placed anchor lies about the
/// reported fit shift (mm along the bed) away from the nipple's parameters (arc lengths
/// on the chest's cylinder, which the bed's tilt against the cylinder stretches by up to
/// about 1/cos 35°: bound 20%), and much nearer the nipple than the footprint's centre.
#[test]
fn the_behind_nipple_rule_starts_from_behind_the_nipple() {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions {
        anchor_rule: AnchorRule::BehindNipple,
        ..Default::default()
    });
    let centred = p.session(SimulationOptions {
        anchor_rule: AnchorRule::FootprintCentre,
        ..Default::default()
    });
    let small = *Catalog::builtin().get("R-MOD-90").unwrap().shape();
    for side in Side::BOTH {
        let nipple = common::nipple(p.landmarks(), side);
        let at_nipple = sim.bed(side).cylinder.to_cylindrical(nipple).truncate();
        assert_eq!(sim.default_anchor_uv(side), at_nipple);
        let footprint_centre = centred.default_anchor_uv(side);
        assert!(footprint_centre.y > at_nipple.y + 5.0);

        sim.set_implant(side, small, Placement::default()).unwrap();
        let placed = sim.implant(side).unwrap();
        let from_nipple_mm = placed.anchor.uv.distance(at_nipple);
        let shift_mm = placed.fit_shift_mm.length();
        println!(
            "{side}: footprint centre {:.1} mm from the nipple, anchor behind it {from_nipple_mm:.1} mm (fit shift {:.1?})",
            footprint_centre.distance(at_nipple),
            placed.fit_shift_mm
        );
        assert!(
            (from_nipple_mm / shift_mm - 1.0).abs() < 0.2,
            "{side}: {from_nipple_mm} mm for a shift of {shift_mm} mm"
        );
        assert!(
            from_nipple_mm < 0.5 * footprint_centre.distance(at_nipple),
            "{side}"
        );
    }
}

/// The skin follows the planned fold (issue 22): with the fold lowered by 0 and by 10
/// mm, the simulated fold (`Simulation::simulated_fold`, the lowest skin pushed forward
/// on the section through PSMF) lies below the planned fold by at most one finest
/// spacing and the 2 mm threshold of the junction (the skin is held from the planned
/// fold to one spacing below it, and the push ends at the planned fold), never above it
/// by more than 1 mm, and the 10 mm lowering takes it 7-13 mm lower (the issue's
/// range; measured 1.0 and 10.1 mm below the native fold). Without the held skin the
/// fold sagged 16 mm below PSMF at a 10 mm lowering; with the mollified rim reaching
/// under the planned fold it lay 7.0 mm below the native one with no lowering, and the
/// lowering moved it 5.5 mm.
#[test]
fn a_lowered_fold_takes_the_simulated_fold_down() {
    use simulation::pocket::{FoldLowering, PocketLimits};
    let p = common::phantom();
    let spacing_mm = p.model.tets.levels[0].spacing_mm;
    let native_y = p
        .frame()
        .to_local(p.marked.landmarks.get(LandmarkName::PSMFl))
        .y;
    let below_native_mm = |lowering_mm: f64| {
        let limits = PocketLimits {
            fold_lowering: FoldLowering::Mm(lowering_mm),
            ..PocketLimits::default()
        };
        let mut sim = p.session(SimulationOptions {
            pocket: Some([limits; 2]),
            ..SimulationOptions::default()
        });
        sim.set_implant(Side::Left, implant(), Placement::default())
            .unwrap();
        assert!(sim.run(true).unwrap().implant.converged);
        let fold = sim.simulated_fold(Side::Left).expect("the breast moved");
        native_y - p.frame().to_local(fold).y
    };
    let (at_native, lowered) = (below_native_mm(0.0), below_native_mm(10.0));
    println!(
        "simulated fold below the native one: {at_native:.1} mm (planned 0), {lowered:.1} mm \
         (planned 10); spacing {spacing_mm:.1} mm"
    );
    for (below, planned) in [(at_native, 0.0), (lowered, 10.0)] {
        assert!(
            below >= planned - 1.0 && below <= planned + spacing_mm + 2.0,
            "{below} vs {planned}"
        );
    }
    assert!(
        (7.0..=13.0).contains(&(lowered - at_native)),
        "{at_native} {lowered}"
    );
}

/// A restart from a solved displacement starts at its equilibrium: the residual before
/// the first cycle is the one the solve stopped at (below 1e-6; bound 1e-5 for the
/// reassembly's round-off), not that of a fresh start. A displacement of the wrong size
/// is refused and changes nothing.
#[test]
fn a_restart_from_a_solved_state_starts_at_its_equilibrium() {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions::default());
    for side in Side::BOTH {
        sim.set_implant(side, implant(), Placement::default())
            .unwrap();
    }
    let solved = sim.solve(300, 1e-6).unwrap();
    assert!(solved.converged, "{solved:?}");
    let u = sim.displacement().to_vec();
    assert!(sim.restart_from(&u[1..]).is_err());
    assert_eq!(sim.displacement(), &u[..]);
    sim.restart_from(&u).unwrap();
    let first = sim.cycle().unwrap();
    assert!(first.relative_residual < 1e-5, "{first:?}");
}

/// After the implants move, the gravity correction starts from the best multiple of the
/// last one (`PcgIteration::from_guess`) and needs fewer conjugate gradient cycles than
/// from zero (`restart_from` forgets it), for the same answer: every finest vertex of
/// both within 0.1 mm (the bench's `converged_ms` criterion) of the answer solved on to
/// 1e-7.
#[test]
fn a_moved_implant_corrects_gravity_from_the_last_correction() {
    let p = common::phantom();
    let mut sim = p.session(SimulationOptions::default());
    let place = |sim: &mut simulation::Simulation, up_mm: f64| {
        for side in Side::BOTH {
            sim.set_implant(side, implant(), Placement::moved(0.0, up_mm, 0.0))
                .unwrap();
        }
    };
    place(&mut sim, 0.0);
    sim.run(false).unwrap();
    let warm = sim.solved_state();
    let u_warm = sim.displacement().to_vec();
    let solve_moved = |sim: &mut simulation::Simulation, tolerance: f64| {
        place(sim, 5.0);
        let implant_stage = sim.solve(300, tolerance).unwrap();
        assert!(implant_stage.converged, "{implant_stage:?}");
        sim.start_gravity_correction().unwrap();
        let gravity = sim.solve(300, tolerance).unwrap();
        assert!(gravity.converged, "{gravity:?}");
        (gravity.cycles, sim.displacement().to_vec())
    };
    sim.restore(&warm).unwrap();
    let (warm_cycles, u_from_guess) = solve_moved(&mut sim, 1e-3);
    sim.restart_from(&u_warm).unwrap();
    let (cold_cycles, u_from_zero) = solve_moved(&mut sim, 1e-3);
    sim.restore(&warm).unwrap();
    let (_, tight) = solve_moved(&mut sim, 1e-7);
    let largest = |u: &[glam::DVec3]| {
        u.iter()
            .zip(&tight)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f64::max)
    };
    println!(
        "gravity cycles from the last correction {warm_cycles}, from zero {cold_cycles}; \
         largest distance to the tight answer {:.3} / {:.3} mm",
        largest(&u_from_guess),
        largest(&u_from_zero)
    );
    assert!(warm_cycles < cold_cycles, "{warm_cycles} vs {cold_cycles}");
    assert!(largest(&u_from_guess) < 0.1 && largest(&u_from_zero) < 0.1);
}

/// Where the tissue over the pocket is thinner than the layer that moves with the
/// implant (below a lowered fold the bed lies 5 mm under the skin), the template holds
/// no skin vertex: held skin next to free skin sheared the surface elements between
/// them over (jittered landmark layouts of six zoo bodies,
/// docs/dev/model-on-every-body.md, session 40). The skin the template would push
/// rides on sliders: after stage 1 it lies on average within 0.4 mm, and everywhere
/// within 2 mm, of the plane through its template position across the bed's normal
/// (the slider's gap is its force over its stiffness, some 1,500 mN/mm; measured 0.30
/// and 1.74 mm, the largest just over the fold, where the push rises steeply within
/// the fold's taper; 0.17 and 0.52 before the push ended at the fold), it has slid
/// along that plane by more than a millimetre somewhere (held, it would not move along
/// it at all), and no element is inverted.
#[test]
fn the_skin_over_a_thin_pocket_slides_over_the_implant() {
    let patient = common::small_hanging_phantom();
    let mut sim = patient.session(SimulationOptions {
        skin_slides: true,
        ..SimulationOptions::default()
    });
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    for side in Side::BOTH {
        sim.set_implant(side, shape, Placement::default()).unwrap();
    }
    let mut on_boundary = vec![false; sim.finest_mesh().positions.len()];
    for v in sim.finest_mesh().boundary().tet_vertex {
        on_boundary[v as usize] = true;
    }
    let report = sim.run(true).unwrap();
    assert!(report.implant.converged, "{report:?}");
    let u = sim.displacement();
    for side in Side::BOTH {
        let t = &sim.implant(side).unwrap().template;
        let (mut gap_sum_mm, mut gap_max_mm, mut slide_max_mm) = (0.0, 0.0f64, 0.0f64);
        for &(v, d) in &t.skin_vertices {
            let n = d.normalize();
            let off = u[v as usize] - d;
            gap_sum_mm += off.dot(n).abs();
            gap_max_mm = gap_max_mm.max(off.dot(n).abs());
            slide_max_mm = slide_max_mm.max((off - n * off.dot(n)).length());
        }
        let gap_mean_mm = gap_sum_mm / t.skin_vertices.len().max(1) as f64;
        println!(
            "{side}: {} vertices held, {} skin vertices on sliders; off their planes by \
             {gap_mean_mm:.2} mm on average, at most {gap_max_mm:.2} mm; slid along them \
             by up to {slide_max_mm:.1} mm",
            t.implant_vertices.len(),
            t.skin_vertices.len(),
        );
        assert!(
            t.skin_vertices.len() > 20,
            "{side}: the thin pocket has no skin"
        );
        assert!(
            t.skin_vertices
                .iter()
                .all(|&(v, _)| on_boundary[v as usize])
        );
        assert!(gap_mean_mm < 0.4 && gap_max_mm < 2.0, "{side}");
        assert!(slide_max_mm > 1.0, "{side}");
    }
    let inverted = sim.inverted_elements();
    assert!(inverted.is_empty(), "{} inverted elements", inverted.len());
}

/// Stage 2 turns the forces that held the implant's vertices (and the skin on sliders)
/// in stage 1 into dead loads and releases those vertices (paper V-B); the implant's
/// weight is the only new load. With a weightless implant the loads are the reactions
/// of stage 1's equilibrium, so nothing moves: stage 2 leaves stage 1's answer where it
/// is, to the solvers' tolerance (relative residual 1e-3 on displacements of up to 29
/// mm; 0.1 mm allows for both stages' residuals, measured 0.030 mm held and 0.065
/// sliding), with held skin and with sliding skin. A wrong reaction (a vertex left out of the dead loads, a force of the
/// wrong level or sign) moves the released tissue by millimetres.
#[test]
fn a_weightless_implant_leaves_stage_one_where_it_is() {
    let patient = common::small_hanging_phantom();
    let shape = *Catalog::builtin().get("R-MOD-115").unwrap().shape();
    for skin_slides in [false, true] {
        let mut sim = patient.session(SimulationOptions {
            skin_slides,
            implant_density_kg_m3: 0.0,
            ..SimulationOptions::default()
        });
        for side in Side::BOTH {
            sim.set_implant(side, shape, Placement::default()).unwrap();
        }
        let stage_one = sim.run(true).unwrap();
        assert!(stage_one.implant.converged, "{stage_one:?}");
        let u_one = sim.displacement().to_vec();
        let report = sim.run(false).unwrap();
        let gravity = report.gravity.expect("a gravity stage");
        assert!(gravity.converged, "{report:?}");
        let moved_mm = (sim.displacement().iter().zip(&u_one))
            .map(|(u, u1)| u.distance(*u1))
            .fold(0.0, f64::max);
        let largest_mm = u_one.iter().map(|u| u.length()).fold(0.0, f64::max);
        println!(
            "skin slides {skin_slides}: stage 2 with a weightless implant moved the tissue \
             by at most {moved_mm:.4} mm (stage 1 moved it up to {largest_mm:.1} mm), in {} \
             cycles",
            gravity.cycles
        );
        assert!(largest_mm > 10.0);
        assert!(moved_mm < 0.1, "skin slides {skin_slides}: {moved_mm} mm");
    }
}
