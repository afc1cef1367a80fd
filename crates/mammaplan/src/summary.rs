//! Human-readable summaries printed when `--json` is not given.

use plan::Distance;
use plan::compare::SymmetryReport;
use plan::demo::DemoReport;
use plan::model::ModelReport;
use plan::register::RegisterReport;
use std::fmt::Write;

fn millimetres(value: Option<f64>) -> String {
    value.map_or_else(|| "-".to_string(), |v| format!("{v:.1}"))
}

/// Which way was up, and the sternum's lean from it.
pub fn up(up: &plan::UpRecord) -> String {
    format!("up: {}\n", up.in_words())
}

/// The distance table.
pub fn distances(distances: &[Distance]) -> String {
    let mut out = format!(
        "{:<14} {:>14} {:>12} {:>12}\n",
        "distance", "euclidean mm", "surface mm", "geodesic mm"
    );
    for d in distances {
        let _ = writeln!(
            out,
            "{:<14} {:>14.1} {:>12} {:>12}{}",
            d.name,
            d.euclidean_mm,
            millimetres(d.surface_mm),
            millimetres(d.geodesic_mm),
            d.note
                .as_ref()
                .map(|n| format!("  ({n})"))
                .unwrap_or_default()
        );
    }
    out
}

/// The registration figures.
pub fn registration(report: &RegisterReport) -> String {
    let mut out = String::from("moving -> fixed (row-major 4x4):\n");
    for row in &report.matrix {
        let _ = writeln!(
            out,
            "  {:>10.6} {:>10.6} {:>10.6} {:>10.3}",
            row[0], row[1], row[2], row[3]
        );
    }
    let _ = writeln!(
        out,
        "rotation {:.3} deg, translation {:.2} mm\nbony landmark RMS {:.2} mm\nsurface RMS away from the breasts {:.3} mm ({} points; landmarks only: {:.3} mm){}",
        report.rotation_deg,
        glam_length(report.translation_mm),
        report.landmark_rms_mm,
        report.surface_rms_mm,
        report.surface_points,
        report.surface_rms_landmarks_only_mm,
        if report.icp {
            format!(", ICP {} iterations", report.icp_iterations)
        } else {
            String::new()
        }
    );
    out
}

fn glam_length(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// What the demo did and where the files are.
pub fn demo(report: &DemoReport) -> String {
    let mut out = format!(
        "mammaplan demo -> {}\n\nphantom: {} vertices, {} triangles; true breast volumes left {:.1} ml, right {:.1} ml\n\n",
        report.out_dir.display(),
        report.vertices,
        report.triangles,
        report.true_breast_volume_ml[0],
        report.true_breast_volume_ml[1]
    );
    out += &distances(&report.measurements.distances);
    out += "\nregistration of a noisy follow-up scan in a moved frame:\n";
    out += &registration(&report.registration);
    let _ = writeln!(
        out,
        "error against the known motion: {:.4} deg, {:.3} mm\n",
        report.registration_error_deg, report.registration_error_mm
    );
    out += "breast model:\n";
    out += &model_figures(&report.model);
    let _ = writeln!(
        out,
        "breast volume against the phantom's truth: left {:+.1}%, right {:+.1}%\n",
        report.breast_volume_error_percent.left, report.breast_volume_error_percent.right
    );
    out += "simulation:\n";
    out += &simulation_figures(&report.simulation);
    out += "\n";
    out += &self::report(&report.report);
    out += "\nfiles:\n";
    for file in &report.files {
        let _ = writeln!(out, "  {}", file.display());
    }
    out
}

/// The breast and closed-surface figures of a model.
fn model_figures(report: &ModelReport) -> String {
    let mut out = format!(
        "{:<6} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}\n",
        "breast", "volume ml", "UO ml", "UI ml", "LI ml", "LO ml", "stitch deg"
    );
    for (side, volume, quadrants, stitch) in [
        (
            "left",
            report.breast_volume_ml.left,
            &report.quadrant_volume_ml.left,
            report.max_stitch_angle_deg.left,
        ),
        (
            "right",
            report.breast_volume_ml.right,
            &report.quadrant_volume_ml.right,
            report.max_stitch_angle_deg.right,
        ),
    ] {
        let _ = writeln!(
            out,
            "{side:<6} {volume:>10.1} {:>10.1} {:>10.1} {:>10.1} {:>10.1} {stitch:>10.1}",
            quadrants.upper_outer,
            quadrants.upper_inner,
            quadrants.lower_inner,
            quadrants.lower_outer,
        );
    }
    let counts = &report.counts;
    let _ = writeln!(
        out,
        "closed surface: {:.1} ml, {} triangles, rear wall = filled base smoothed and shifted {:.1} mm back\n\
         scan holes closed: {}; built in {:.0} ms (breast model {:.0} ms, closed surface {:.0} ms, \
         tetrahedra {:.0} ms)",
        report.closed_surface_volume_ml,
        counts.closed_surface_triangles,
        report.rear_wall_offset_mm,
        report.holes_closed.len(),
        report.timings.total_ms,
        report.timings.breast_model_ms,
        report.timings.closed_surface_ms,
        report.timings.tetrahedra_ms,
    );
    let _ = writeln!(
        out,
        "{:<10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "tet level", "elements", "nodes", "spacing mm", "volume ml", "min deg", "max deg"
    );
    for (l, level) in report.levels.iter().enumerate() {
        let _ = writeln!(
            out,
            "{l:<10} {:>10} {:>10} {:>10.2} {:>10.1} {:>10.1} {:>10.1}",
            level.elements,
            level.nodes,
            level.spacing_mm,
            level.volume_ml,
            level.min_dihedral_deg,
            level.max_dihedral_deg,
        );
    }
    if let Some(refinement) = &report.refinement {
        let _ = writeln!(
            out,
            "level 0 is refined within {} mm of the fill-ins: lattice spacing {:.2} mm, \
             {} elements in the band, longest edge {:.2} mm (bound {} mm)",
            refinement.band_mm,
            refinement.band_spacing_mm,
            refinement.elements_in_band,
            refinement.longest_edge_in_band_mm,
            refinement.max_edge_mm,
        );
    }
    for (side, muscle) in [
        ("left", &report.pectoralis_major.left),
        ("right", &report.pectoralis_major.right),
    ] {
        let _ = match muscle {
            Some(m) => writeln!(
                out,
                "{side} pectoralis major: {:.0} cm² of chest wall, {:.1} mm thick on average, \
                 {:.1} ml; {:.1} mm from the midline",
                m.area_cm2, m.mean_thickness_mm, m.volume_ml, m.medial_border_from_midline_mm,
            ),
            None => writeln!(out, "{side} pectoralis major: no element of the model"),
        };
    }
    out
}

/// What `model` built and where the files are.
pub fn model(report: &ModelReport) -> String {
    let mut out = model_figures(report);
    out.push_str(&up(&report.up));
    let _ = writeln!(out, "\nfiles in {}:", report.out_dir.display());
    for file in &report.files {
        let _ = writeln!(out, "  {file}");
    }
    out
}

/// A table of catalog entries; `scores` adds a column (the suggestion's distance).
pub fn catalog_entries<'a>(
    source: &str,
    entries: impl Iterator<Item = &'a plan::catalog::CatalogEntry>,
    scores: Option<(&str, Vec<f64>)>,
) -> String {
    let mut out = format!("catalog: {source}\n");
    let _ = write!(
        out,
        "{:<16} {:<9} {:<34} {:>9} {:>9} {:>13} {:>10}",
        "id", "shape", "family", "width mm", "height mm", "projection mm", "volume ml"
    );
    if let Some((name, _)) = &scores {
        let _ = write!(out, " {name:>14}");
    }
    out.push('\n');
    for (k, entry) in entries.enumerate() {
        let shape = entry.shape();
        let _ = write!(
            out,
            "{:<16} {:<9} {:<34} {:>9.1} {:>9.1} {:>13.1} {:>10.1}",
            entry.id(),
            shape.kind().as_str(),
            entry.family(),
            shape.width_mm(),
            shape.height_mm(),
            shape.projection_mm(),
            entry.volume_ml(),
        );
        if let Some((_, values)) = &scores {
            let _ = write!(out, " {:>14.1}", values[k]);
        }
        out.push('\n');
    }
    out
}

/// The suggested entries, best first, with how far each is from the target.
pub fn suggestions(report: &plan::catalog::SuggestReport) -> String {
    let by_dimensions = report.suggestions.iter().any(|s| s.distance_mm.is_some());
    let scores = report
        .suggestions
        .iter()
        .map(|s| s.distance_mm.or(s.volume_difference_ml).unwrap_or(f64::NAN))
        .collect();
    let name = if by_dimensions {
        "distance mm"
    } else {
        "difference ml"
    };
    catalog_entries(
        &report.source,
        report.suggestions.iter().map(|s| s.entry),
        Some((name, scores)),
    )
}

/// What `fem solve` computed.
pub fn fem_solve(report: &plan::fem_solve::FemSolveReport) -> String {
    format!(
        "{}: {} elements, {} nodes ({} constrained), {} elasticity\n\
         solved in {} iterations ({:.0} ms), relative residual {:.1e}\n\
         largest displacement {:.3} mm, largest von Mises stress {:.4} kPa\n\
         written to {}\n",
        report.mesh.display(),
        report.elements,
        report.nodes,
        report.constrained_nodes,
        report.formulation,
        report.iterations,
        report.solve_ms,
        report.relative_residual,
        report.max_displacement_mm,
        report.max_von_mises_kpa,
        report.out.display(),
    )
}

/// What `simulate` predicted and where it is written.
pub fn simulation(report: &plan::simulate::SimulateReport) -> String {
    let mut out = simulation_figures(report);
    let _ = writeln!(out, "written to {}:", report.out_dir.display());
    for file in &report.files {
        let _ = writeln!(out, "  {file}");
    }
    out
}

/// Implants, breast volumes, the solver and the distances of a simulation.
fn simulation_figures(report: &plan::simulate::SimulateReport) -> String {
    let mut out = String::new();
    for (side, implant, before, after) in [
        (
            "left",
            &report.implants.left,
            report.breast_volume_before_ml.left,
            report.breast_volume_ml.left,
        ),
        (
            "right",
            &report.implants.right,
            report.breast_volume_before_ml.right,
            report.breast_volume_ml.right,
        ),
    ] {
        let implant = implant.as_ref().map_or_else(
            || "no implant".to_string(),
            |i| {
                let [x, y] = i.fit_shift_mm;
                let fitted = if x != 0.0 || y != 0.0 {
                    format!(", moved {x:+.1} mm left, {y:+.1} mm up to fit its pocket")
                } else {
                    String::new()
                };
                let lowered = if i.fold_lowering_mm > 0.05 {
                    format!(", fold lowered {:.1} mm", i.fold_lowering_mm)
                } else {
                    String::new()
                };
                format!("{} ({:.0} ml{lowered}{fitted})", i.spec, i.volume_ml)
            },
        );
        let _ = writeln!(
            out,
            "{side:<6} {implant}: breast {before:.1} ml -> {after:.1} ml ({:+.1} ml)",
            after - before
        );
    }
    for (side, implant, fold) in [
        (
            "left",
            &report.implants.left,
            &report.nipple_to_fold_mm.left,
        ),
        (
            "right",
            &report.implants.right,
            &report.nipple_to_fold_mm.right,
        ),
    ] {
        if implant.is_none() {
            continue;
        }
        let below = fold
            .simulated_fold_lowering_mm
            .map_or_else(String::new, |mm| {
                format!(" (the fold {mm:.1} mm below the native one)")
            });
        let _ = writeln!(
            out,
            "{side:<6} nipple to fold: {:.1} mm before, {:.1} mm planned, {:.1} mm simulated{below}",
            fold.before_mm, fold.planned_mm, fold.simulated_mm
        );
    }
    let s = &report.solver;
    let _ = writeln!(
        out,
        "solver: {} V-cycles in {:.0} ms, relative residual {:.1e}{}, {} inverted elements",
        s.vcycles,
        s.time_ms,
        s.relative_residual,
        if s.converged { "" } else { " (not converged)" },
        s.inverted_elements
    );
    out.push_str(&distances(&report.distances));
    out
}

/// The benchmark table.
pub fn bench(report: &plan::bench::BenchReport) -> String {
    let mut out = format!(
        "implant {} on both sides of the phantom, prolongation smoothing {}{}\n{:>9} {:>6} {:>9} {:>9} {:>9} {:>9} {:>9} {:>9} {:>10} {:>9}\n",
        report.implant,
        report.prolongation_smoothing,
        if report.skin_slides {
            ", skin on sliders"
        } else {
            ""
        },
        "elements",
        "levels",
        "setup ms",
        "build ms",
        "change ms",
        "solve ms",
        "vcycle ms",
        "update Hz",
        "reduction",
        "direct ms"
    );
    for row in &report.rows {
        let _ = writeln!(
            out,
            "{:>9} {:>6} {:>9.2} {:>9.0} {:>9.1} {:>9.1} {:>9.2} {:>9.1} {:>10.2} {:>9.0}",
            row.elements,
            row.levels,
            row.implant_setup_ms,
            row.multigrid_build_ms,
            row.implant_change_cycle_ms,
            row.solve_ms,
            row.vcycle_ms,
            row.update_hz,
            row.residual_reduction_per_cycle,
            row.direct_solve_ms
        );
    }
    out.push_str("where a cycle's time goes (medians, ms):\n");
    for row in &report.rows {
        let p = &row.phases_ms;
        let _ = writeln!(
            out,
            "{:>9}  finest assembly {:.1}, coarse operators {:.1}, smoother set-up {:.2}, coarsest Cholesky {:.1}, V-cycle {:.1}; then to the scan {:.1} ({:.1} in two steps; composing the map {:.0}, {} terms)",
            row.elements,
            p.finest_assembly,
            p.coarse_operators,
            p.smoother_setup,
            p.coarsest_factorisation,
            p.vcycle,
            row.scan_update_ms,
            row.scan_update_two_steps_ms,
            row.scan_carry_compose_ms,
            row.scan_carry_terms
        );
    }
    let _ = writeln!(
        out,
        "time to an answer after moving both implants up 5 mm (both stages, gravity on):"
    );
    for row in &report.rows {
        let c = &row.converged;
        let range = |times: Vec<f64>| {
            let (low, high) = times
                .iter()
                .fold((f64::INFINITY, 0.0_f64), |(l, h), &t| (l.min(t), h.max(t)));
            format!("{low:.0}-{high:.0} ms over {} runs", times.len())
        };
        let converged = match (c.converged_ms, c.converged_cycles) {
            (Some(ms), Some(cycles)) => format!(
                "{ms:.0} ms ({cycles} cycles; median, {})",
                range(c.runs.iter().filter_map(|r| r.converged_ms).collect())
            ),
            _ => "not within the cycle limit".to_string(),
        };
        let _ = writeln!(
            out,
            "{:>9}  skin within {} mm of the tight answer after {converged}; the session's own stop after {:.0} ms ({} cycles; {}), RMS {:.3}, 95th percentile {:.3}, largest {:.2} mm from it; the tight answer from rest: RMS {:.3}, 95th percentile {:.3}, largest {:.2} mm from the one from the warm start",
            row.elements,
            plan::bench::SKIN_TOLERANCE_MM,
            c.default_stop_ms,
            c.default_stop_cycles,
            range(c.runs.iter().map(|r| r.default_stop_ms).collect()),
            c.default_stop_skin.rms_mm,
            c.default_stop_skin.p95_mm,
            c.default_stop_skin.max_mm,
            c.start_dependence.rms_mm,
            c.start_dependence.p95_mm,
            c.start_dependence.max_mm
        );
    }
    if let Some(dir) = &report.exported_system {
        let _ = writeln!(
            out,
            "finest system written to {}",
            dir.join("A.mtx").display()
        );
    }
    out
}

/// One figure of a symmetry report.
type SymmetryFigure = fn(&SymmetryReport) -> f64;

/// The figures of `compare`.
pub fn comparison(report: &plan::compare::CompareReport) -> String {
    let mut out = format!(
        "test {}\nreference {}\n",
        report.test.scan, report.reference.scan
    );
    if let Some(transform) = &report.registration {
        out += "\nregistration of the test onto the reference:\n";
        out += &registration(transform);
    }
    let _ = writeln!(
        out,
        "\nsurface deviation, test vertices to the reference surface (overlap: {:.0}% of the test, {:.0}% of the reference; at most {} mm apart):",
        100.0 * report.overlap_fraction,
        100.0 * report.reference_overlap_fraction,
        report.max_distance_mm
    );
    let _ = writeln!(
        out,
        "{:<14} {:>9} {:>8} {:>8} {:>10} {:>8} {:>13}",
        "region", "vertices", "rms mm", "mean mm", "signed mm", "p95 mm", "hausdorff mm"
    );
    let regions = &report.breast_regions;
    for (name, statistics) in [
        ("overall", Some(report.overall)),
        ("left breast", regions.left),
        ("right breast", regions.right),
        ("both breasts", regions.both),
    ] {
        let _ = match statistics {
            Some(s) => writeln!(
                out,
                "{name:<14} {:>9} {:>8.2} {:>8.2} {:>+10.2} {:>8.2} {:>13.2}",
                s.vertices,
                s.rms_mm,
                s.mean_mm,
                s.signed_mean_mm,
                s.percentile_95_mm,
                s.hausdorff_mm
            ),
            None => writeln!(out, "{name:<14} {:>9}", "no overlap"),
        };
    }
    let _ = writeln!(
        out,
        "\n{:<14} {:>13} {:>10} {:>14}",
        "distance", "reference mm", "test mm", "difference mm"
    );
    for d in &report.distances {
        let _ = writeln!(
            out,
            "{:<14} {:>13} {:>10} {:>14}",
            d.name,
            millimetres(d.reference_mm),
            millimetres(d.test_mm),
            d.difference_mm
                .map_or_else(|| "-".to_string(), |v| format!("{v:+.1}"))
        );
    }
    let _ = writeln!(
        out,
        "\n{:<16} {:>9} {:>7} {:>7} {:>7} {:>7}",
        "breast volume", "total ml", "UO ml", "UI ml", "LI ml", "LO ml"
    );
    for (scan, volumes, quadrants) in [
        (
            "reference",
            &report.breast_volume_ml.reference,
            &report.quadrant_volume_ml.reference,
        ),
        (
            "test",
            &report.breast_volume_ml.test,
            &report.quadrant_volume_ml.test,
        ),
    ] {
        let (Some(volumes), Some(quadrants)) = (volumes, quadrants) else {
            let _ = writeln!(out, "{scan:<16} {:>9}", "no breast model");
            continue;
        };
        for (side, volume, q) in [
            ("left", volumes.left, &quadrants.left),
            ("right", volumes.right, &quadrants.right),
        ] {
            let _ = writeln!(
                out,
                "{:<16} {volume:>9.1} {:>7.1} {:>7.1} {:>7.1} {:>7.1}",
                format!("{scan} {side}"),
                q.upper_outer,
                q.upper_inner,
                q.lower_inner,
                q.lower_outer
            );
        }
    }
    let symmetry = &report.symmetry;
    let _ = writeln!(
        out,
        "\n{:<38} {:>10} {:>10}",
        "symmetry (left against mirrored right)", "reference", "test"
    );
    let rows: [(&str, SymmetryFigure); 6] = [
        ("volume ratio left/right", |s| s.volume_ratio_left_to_right),
        ("nipple height difference mm", |s| {
            s.nipple_height_difference_mm
        }),
        ("nipple position difference mm", |s| s.nipple_distance_mm),
        ("asymmetry rms, breasts mm", |s| {
            s.asymmetry.both_breasts.map_or(f64::NAN, |b| b.rms_mm)
        }),
        ("asymmetry rms, overall mm", |s| s.asymmetry.whole.rms_mm),
        ("mirror plane correction deg", |s| s.mirror_correction_deg),
    ];
    let cell = |symmetry: &Option<plan::compare::SymmetryReport>,
                value: fn(&plan::compare::SymmetryReport) -> f64| {
        symmetry
            .as_ref()
            .map_or_else(|| "-".to_string(), |s| format!("{:.2}", value(s)))
    };
    for (name, value) in rows {
        let _ = writeln!(
            out,
            "{name:<38} {:>10} {:>10}",
            cell(&symmetry.reference, value),
            cell(&symmetry.test, value)
        );
    }
    for warning in &report.warnings {
        let _ = writeln!(out, "\nnote: {warning}");
    }
    if let Some(path) = &report.out {
        let _ = writeln!(
            out,
            "\ndeviation map (test scan, green 0 mm to red 20 mm) -> {}",
            path.display()
        );
    }
    out
}

/// What `report` wrote.
pub fn report(report: &plan::report::ReportSummary) -> String {
    let mut parts = vec![format!("{} views", report.views)];
    if report.postoperative {
        parts.push("post-operative scan".into());
    }
    if report.comparison {
        parts.push("comparison".into());
    }
    format!(
        "report -> {} ({} kB; {})\n",
        report.out.display(),
        report.bytes.div_ceil(1000),
        parts.join(", ")
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The table's header says which skin was benchmarked.
    #[test]
    fn the_bench_table_names_sliding_skin() {
        let report = |skin_slides| plan::bench::BenchReport {
            implant: "catalog:R-MOD-120",
            prolongation_smoothing: 0.0,
            skin_slides,
            rows: Vec::new(),
            exported_system: None,
        };
        assert!(bench(&report(true)).contains("prolongation smoothing 0, skin on sliders\n"));
        assert!(bench(&report(false)).contains("prolongation smoothing 0\n"));
    }
}
