//! The report as one self-contained HTML page: inline style sheet, images as `data:`
//! URIs, labels and legends as inline SVG; nothing is fetched from anywhere. Text is
//! escaped by maud. The style prints on A4 with tables and figures kept whole.

use crate::content::{
    BreastVolumes, CaseInfo, ColourScale, Comparison, ImageLabel, ImplantChoice,
    MaterialParameters, MeasurementRow, PerSide, QuadrantVolumes, ReportContent, SymmetryRow, View,
    VolumeTable,
};
use base64::Engine;
use maud::{DOCTYPE, Markup, PreEscaped, html};

/// The page's style sheet: sober, readable on screen, A4 in print.
const STYLE: &str = include_str!("report.css");

/// The report as a complete HTML5 document.
pub fn render_html(content: &ReportContent) -> String {
    let page = html! {
        (DOCTYPE)
        html lang="en" {
            head {
                meta charset="utf-8";
                meta name="viewport" content="width=device-width, initial-scale=1";
                meta name="generator" content=(content.case.software);
                title { (content.title) }
                style { (PreEscaped(STYLE)) }
            }
            body {
                header {
                    h1 { (content.title) }
                    p.subtitle { "Created " (content.case.created) " · " (content.case.software) }
                }
                @if !content.notes.is_empty() {
                    section #notes .notes {
                        h2 { "Notes" }
                        ul { @for note in &content.notes { li { (note) } } }
                    }
                }
                (case_section(&content.case))
                (implant_section(&content.implants))
                @if !content.views.is_empty() {
                    section #views {
                        h2 { "Views" }
                        div.views { @for (index, view) in content.views.iter().enumerate() { (view_figure(index, view)) } }
                    }
                }
                @if !content.measurements.is_empty() {
                    (measurement_section(&content.measurements))
                }
                (volume_section(&content.volumes))
                @if let Some(comparison) = &content.comparison {
                    (comparison_section(comparison))
                }
                @if !content.symmetry.is_empty() {
                    (symmetry_section(&content.symmetry))
                }
                footer {
                    p {
                        "The simulated shape is the prediction of a biomechanical (finite-element) model "
                        "built from the pre-operative scan; it is not a guarantee of the surgical outcome. "
                        "Lengths in millimetres, volumes in millilitres (cm³); left and right are the patient's; "
                        "a dash marks a value that is not available."
                    }
                    p { (content.case.software) " · " (content.case.created) }
                }
            }
        }
    };
    page.into_string()
}

fn case_section(case: &CaseInfo) -> Markup {
    let model = &case.model;
    let solver = &model.solver;
    html! {
        section #case {
            h2 { "Case" }
            table.facts {
                tbody {
                    @for file in &case.files {
                        tr { th scope="row" { (file.role) } td { (file.name) } }
                    }
                    tr {
                        th scope="row" { "Finite-element mesh" }
                        td {
                            (grouped(model.finest_elements)) " tetrahedra, " (grouped(model.finest_nodes))
                            " nodes (finest of " (model.mesh_levels) " levels)"
                        }
                    }
                    tr { th scope="row" { "Rear wall behind the breast" } td { (number(model.rear_wall_offset_mm, 1)) " mm" } }
                    tr { th scope="row" { "Breast tissue" } td { (material(&model.tissue)) } }
                    tr { th scope="row" { "Implant material" } td { (material(&model.implant_material)) } }
                    tr {
                        th scope="row" { "Skin" }
                        td { (model.skin.as_deref().unwrap_or("not modelled (homogeneous tissue up to the surface)")) }
                    }
                    tr {
                        th scope="row" { "Volume loss" }
                        td { (model.compression_penalty.as_deref().unwrap_or("as the corotated energy measures it (the paper's model)")) }
                    }
                    tr {
                        th scope="row" { "Weight of the implant (gravity)" }
                        td { @if model.gravity_correction { "simulated" } @else { "not simulated" } }
                    }
                    tr { th scope="row" { "Up (against gravity)" } td { (model.up) } }
                    @if let Some(pocket) = &model.pocket {
                        tr { th scope="row" { "Pocket" } td { (pocket) } }
                    }
                    tr {
                        th scope="row" { "Solver" }
                        td {
                            (solver.vcycles) " multigrid cycles, relative residual "
                            (format!("{:.1e}", solver.relative_residual)) ", "
                            @if solver.converged { "converged" } @else { "not converged" }
                        }
                    }
                }
            }
        }
    }
}

fn material(material: &MaterialParameters) -> String {
    format!(
        "Young's modulus {} kPa, Poisson ratio {}, density {} kg/m³",
        trimmed(material.young_kpa, 3),
        trimmed(material.poisson_ratio, 3),
        trimmed(material.density_kg_m3, 1)
    )
}

fn implant_section(implants: &PerSide<Option<ImplantChoice>>) -> Markup {
    let sides = implants.labelled();
    let row = |label: &str, cell: &dyn Fn(&ImplantChoice) -> Markup| {
        html! {
            tr {
                th scope="row" { (label) }
                @for (_, implant) in sides {
                    @match implant {
                        Some(implant) => td { (cell(implant)) },
                        None => td { "—" },
                    }
                }
            }
        }
    };
    html! {
        section #implants {
            h2 { "Implants" }
            table.implants {
                thead { tr { th {} @for (side, implant) in sides { th scope="col" { (side) @if implant.is_none() { " (none)" } } } } }
                tbody {
                    (row("Implant", &|i| html! { code { (i.spec) } }))
                    (row("Catalog entry", &|i| match &i.catalog {
                        Some(entry) => html! { (entry.id) " (" (entry.family) ")" },
                        None => html! { "custom dimensions" },
                    }))
                    (row("Shape", &|i| html! { (i.shape) }))
                    (row("Width (mm)", &|i| html! { (number(i.width_mm, 1)) }))
                    (row("Height (mm)", &|i| html! { (number(i.height_mm, 1)) }))
                    (row("Projection (mm)", &|i| html! { (number(i.projection_mm, 1)) }))
                    (row("Volume (ml)", &|i| html! { strong { (number(i.volume_ml, 0)) } }))
                    (row("Default position", &|i| html! { (i.default_position) }))
                    (row("Offset x / y / z (mm)", &|i| html! { (i.offset_mm.map(|v| number(v, 1)).join(" / ")) }))
                    (row("Rotation (°)", &|i| html! { (number(i.rotation_deg, 0)) }))
                    (row("Shifted to fit (mm)", &|i| html! { (i.fit_shift_mm.map(|v| number(v, 1)).join(" / ")) }))
                }
            }
            p.remark {
                "Offset: the move from the default position on the chest wall "
                "(x towards the patient's left, y up, z forwards). Shifted to fit: the further move along "
                "the chest wall (towards the patient's left, up) that placed the implant within the breast's base."
            }
        }
    }
}

fn view_figure(index: usize, view: &View) -> Markup {
    let (width, height) = view.size_px();
    let font_px = (f64::from(width.max(height)) / 36.0).max(8.0);
    let data_uri = format!(
        "data:image/png;base64,{}",
        base64::engine::general_purpose::STANDARD.encode(view.png())
    );
    html! {
        figure.view {
            svg.image viewBox=(format!("0 0 {width} {height}")) role="img" aria-label=(view.title) {
                image href=(data_uri) x="0" y="0" width=(width) height=(height) {}
                @if !view.labels.is_empty() {
                    g.labels font-size=(svg_number(font_px)) {
                        @for label in &view.labels { (image_label(label, font_px)) }
                    }
                }
            }
            figcaption {
                strong { (view.title) }
                @if let Some(caption) = &view.caption { br; (caption) }
            }
            @if let Some(scale) = &view.colour_scale { (legend(index, scale)) }
        }
    }
}

fn image_label(label: &ImageLabel, font_px: f64) -> Markup {
    let offset = 0.35 * font_px;
    html! {
        text x=(svg_number(label.x_px + offset)) y=(svg_number(label.y_px - offset)) { (label.text) }
    }
}

/// Width and height of a legend in SVG units (CSS pixels at natural size).
const LEGEND_SIZE: (f64, f64) = (360.0, 58.0);
/// Ticks along a legend, ends included.
const LEGEND_TICKS: usize = 5;

/// A horizontal gradient bar from `scale.min` to `scale.max` with ticks; `index` makes
/// the gradient's id unique on the page.
fn legend(index: usize, scale: &ColourScale) -> Markup {
    let (width, height) = LEGEND_SIZE;
    let (left, right, bar_top, bar_height) = (14.0, width - 24.0, 20.0, 14.0);
    let id = format!("colour-scale-{index}");
    let span = scale.max - scale.min;
    html! {
        svg.legend viewBox=(format!("0 0 {width} {height}")) width=(width) height=(height) role="img" aria-label=(scale.label) {
            defs {
                linearGradient id=(id) x1="0" y1="0" x2="1" y2="0" {
                    @for stop in &scale.stops {
                        stop offset=(svg_number(stop.fraction)) stop-color=(format!("rgb({},{},{})", stop.rgb[0], stop.rgb[1], stop.rgb[2])) {}
                    }
                }
            }
            text x=(svg_number(left)) y="13" font-size="12" { (scale.label) }
            rect x=(svg_number(left)) y=(svg_number(bar_top)) width=(svg_number(right - left)) height=(svg_number(bar_height))
                fill=(format!("url(#{id})")) stroke="#555" stroke-width="0.6" {}
            @for k in 0..LEGEND_TICKS {
                @let fraction = k as f64 / (LEGEND_TICKS - 1) as f64;
                @let x = left + fraction * (right - left);
                @let value = trimmed(scale.min + fraction * span, 1);
                line x1=(svg_number(x)) x2=(svg_number(x)) y1=(svg_number(bar_top + bar_height)) y2=(svg_number(bar_top + bar_height + 5.0)) stroke="#333" stroke-width="0.8" {}
                text x=(svg_number(x)) y=(svg_number(height - 6.0)) font-size="11" text-anchor="middle" {
                    @if k + 1 == LEGEND_TICKS && scale.saturates_above_max { "≥ " } (value)
                }
            }
        }
    }
}

/// Which of the three scans a table has columns for.
#[derive(Clone, Copy)]
struct ScanColumns {
    simulated: bool,
    postoperative: bool,
}

impl ScanColumns {
    fn header(self) -> Markup {
        html! {
            th.num scope="col" { "Pre-op" }
            @if self.simulated {
                th.num scope="col" { "Simulated" }
                th.num scope="col" { "Change" }
            }
            @if self.postoperative {
                th.num scope="col" { "Post-op" }
                @if self.simulated { th.num scope="col" { "Post-op − simulated" } }
                @else { th.num scope="col" { "Change" } }
            }
        }
    }

    /// The values, the simulated change from before and the post-operative difference
    /// from the simulation (or from before, without a simulation).
    fn cells(
        self,
        pre: Option<f64>,
        simulated: Option<f64>,
        post: Option<f64>,
        decimals: usize,
    ) -> Markup {
        let difference = |a: Option<f64>, b: Option<f64>| a.zip(b).map(|(a, b)| a - b);
        html! {
            td.num { (optional(pre, decimals)) }
            @if self.simulated {
                td.num { (optional(simulated, decimals)) }
                td.num.change { (optional_signed(difference(simulated, pre), decimals)) }
            }
            @if self.postoperative {
                td.num { (optional(post, decimals)) }
                td.num.change { (optional_signed(difference(post, if self.simulated { simulated } else { pre }), decimals)) }
            }
        }
    }
}

fn measurement_section(rows: &[MeasurementRow]) -> Markup {
    let columns = ScanColumns {
        simulated: rows.iter().any(|r| r.simulated_mm.is_some()),
        postoperative: rows.iter().any(|r| r.postoperative_mm.is_some()),
    };
    html! {
        section #measurements {
            h2 { "Measurements" }
            table.figures {
                caption { "Clinical distances along the skin (mm), measured like a tape measure along the section through both points." }
                thead { tr { th scope="col" { "Distance" } (columns.header()) } }
                tbody {
                    @for row in rows {
                        tr { th scope="row" { (row.name) } (columns.cells(row.preoperative_mm, row.simulated_mm, row.postoperative_mm, 1)) }
                    }
                }
            }
        }
    }
}

fn volume_section(volumes: &VolumeTable) -> Markup {
    let columns = ScanColumns {
        simulated: volumes.simulated.is_some(),
        postoperative: volumes.postoperative.is_some(),
    };
    // Side `k` (0 left, 1 right) of an optional pair.
    let side = |sides: &Option<PerSide<BreastVolumes>>, k: usize| {
        sides.as_ref().map(|s| *s.labelled()[k].1)
    };
    html! {
        section #volumes {
            h2 { "Volumes" }
            table.figures {
                caption { "Breast and quadrant volumes (ml). Inner quadrants are medial, outer lateral." }
                thead { tr { th scope="col" { "Region" } (columns.header()) } }
                tbody {
                    @for (k, (label, pre)) in volumes.preoperative.labelled().into_iter().enumerate() {
                        @let pre = Some(*pre);
                        @let simulated = side(&volumes.simulated, k);
                        @let post = side(&volumes.postoperative, k);
                        tr.breast {
                            th scope="row" { (label) " breast" }
                            (columns.cells(pre.map(|v| v.breast_ml), simulated.map(|v| v.breast_ml), post.map(|v| v.breast_ml), 1))
                        }
                        @if [pre, simulated, post].iter().flatten().any(|v| v.quadrants_ml.is_some()) {
                            @for (quadrant, name) in QuadrantVolumes::NAMES.iter().enumerate() {
                                @let value = |v: Option<BreastVolumes>| v.and_then(|v| v.quadrants_ml).map(|q| q.values_ml()[quadrant]);
                                tr.quadrant {
                                    th scope="row" { (name) }
                                    (columns.cells(value(pre), value(simulated), value(post), 1))
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

fn comparison_section(comparison: &Comparison) -> Markup {
    html! {
        section #comparison {
            h2 { "Prediction against outcome" }
            table.figures {
                caption { "Distances from the " (comparison.test) " to the " (comparison.reference) " (mm)." }
                thead { tr { th scope="col" { "Region" } th.num scope="col" { "RMS" } th.num scope="col" { "Mean" } th.num scope="col" { "Hausdorff" } } }
                tbody {
                    @for region in &comparison.regions {
                        tr {
                            th scope="row" { (region.region) }
                            td.num { (number(region.rms_mm, 1)) }
                            td.num { (number(region.mean_mm, 1)) }
                            td.num { (number(region.hausdorff_mm, 1)) }
                        }
                    }
                }
            }
        }
    }
}

fn symmetry_section(rows: &[SymmetryRow]) -> Markup {
    html! {
        section #symmetry {
            h2 { "Symmetry" }
            table.figures {
                caption {
                    "Left against right across the mid-sagittal plane (through the sternal notch and the "
                    "xiphoid, orthogonal to the line between the clavicle points). Differences are left minus right (mm)."
                }
                thead {
                    tr {
                        th scope="col" { "Scan" }
                        th.num scope="col" { "Volume left / right" }
                        th.num scope="col" { "Nipple height" }
                        th.num scope="col" { "Nipple to midline" }
                        th.num scope="col" { "Nipple to mirrored nipple" }
                    }
                }
                tbody {
                    @for row in rows {
                        tr {
                            th scope="row" { (row.scan) }
                            td.num { (number(row.volume_ratio_left_to_right, 3)) }
                            td.num { (signed(row.nipple_height_difference_mm, 1)) }
                            td.num { (signed(row.nipple_midline_difference_mm, 1)) }
                            td.num { (number(row.nipple_mirror_distance_mm, 1)) }
                        }
                    }
                }
            }
        }
    }
}

/// The minus sign used for negative numbers (U+2212, as in print).
const MINUS: &str = "\u{2212}";
/// Shown for a missing or non-finite value.
const MISSING: &str = "—";

/// `value` with `decimals` decimals and a typographic minus; a dash if not finite.
fn number(value: f64, decimals: usize) -> String {
    if !value.is_finite() {
        return MISSING.to_string();
    }
    let text = format!("{:.*}", decimals, value);
    match text.strip_prefix('-') {
        // A value that rounds to zero has no sign.
        Some(digits) if digits.bytes().any(|b| (b'1'..=b'9').contains(&b)) => {
            format!("{MINUS}{digits}")
        }
        Some(digits) => digits.to_string(),
        None => text,
    }
}

/// As [`number`], with a `+` on positive values.
fn signed(value: f64, decimals: usize) -> String {
    let text = number(value, decimals);
    let nonzero = text.bytes().any(|b| (b'1'..=b'9').contains(&b));
    if value > 0.0 && nonzero {
        format!("+{text}")
    } else {
        text
    }
}

fn optional(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| MISSING.to_string(), |v| number(v, decimals))
}

fn optional_signed(value: Option<f64>, decimals: usize) -> String {
    value.map_or_else(|| MISSING.to_string(), |v| signed(v, decimals))
}

/// At most `decimals` decimals, trailing zeros dropped (`2.4`, `1000`, `0.45`).
fn trimmed(value: f64, decimals: usize) -> String {
    let text = number(value, decimals);
    if text.contains('.') {
        text.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        text
    }
}

/// A coordinate for an SVG attribute (plain ASCII, two decimals at most).
fn svg_number(value: f64) -> String {
    let text = format!("{value:.2}");
    text.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A count with thousands separators (`60,491`).
fn grouped(count: usize) -> String {
    let digits = count.to_string();
    let mut out = String::with_capacity(digits.len() + digits.len() / 3);
    for (i, digit) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(digit);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_formatted_for_print() {
        assert_eq!(number(-3.25, 1), "\u{2212}3.2");
        assert_eq!(number(-0.04, 1), "0.0");
        assert_eq!(number(f64::NAN, 1), "—");
        assert_eq!(signed(2.0, 1), "+2.0");
        assert_eq!(signed(0.01, 1), "0.0");
        assert_eq!(signed(-2.0, 0), "\u{2212}2");
        assert_eq!(trimmed(2.4, 3), "2.4");
        assert_eq!(trimmed(1000.0, 1), "1000");
        assert_eq!(svg_number(12.5), "12.5");
        assert_eq!(svg_number(3.0), "3");
        assert_eq!(grouped(60_491), "60,491");
        assert_eq!(grouped(999), "999");
        assert_eq!(grouped(1_234_567), "1,234,567");
    }
}
