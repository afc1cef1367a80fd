//! The report page parsed back with a browser-grade HTML5 parser (html5ever): well
//! formed, each section present exactly when its data is, nothing fetched from outside,
//! images byte for byte as given, user text escaped.

use base64::Engine;
use html5ever::tendril::TendrilSink;
use markup5ever_rcdom::{Handle, NodeData, RcDom};
use report::*;

/// A small RGB PNG with a colour gradient, encoded by the `png` crate.
fn png_image(width: u32, height: u32) -> Vec<u8> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    let pixels: Vec<u8> = (0..height)
        .flat_map(|y| {
            (0..width).flat_map(move |x| [(x * 255 / width) as u8, (y * 255 / height) as u8, 128])
        })
        .collect();
    writer.write_image_data(&pixels).unwrap();
    writer.finish().unwrap();
    bytes
}

fn material() -> MaterialParameters {
    MaterialParameters {
        young_kpa: 2.4,
        poisson_ratio: 0.45,
        density_kg_m3: 1000.0,
    }
}

fn volumes(breast_ml: f64) -> PerSide<BreastVolumes> {
    let side = BreastVolumes {
        breast_ml,
        quadrants_ml: Some(QuadrantVolumes {
            upper_outer_ml: 0.25 * breast_ml,
            upper_inner_ml: 0.35 * breast_ml,
            lower_inner_ml: 0.1 * breast_ml,
            lower_outer_ml: 0.3 * breast_ml,
        }),
    };
    PerSide {
        left: side,
        right: side,
    }
}

/// Content with only what every report has: case, implants, measurements and volumes
/// before and as simulated.
fn minimal_content() -> ReportContent {
    let implant = ImplantChoice {
        spec: "catalog:R-MOD-120".into(),
        catalog: Some(CatalogReference {
            id: "R-MOD-120".into(),
            family: "moderate profile".into(),
        }),
        shape: "round, ellipsoid profile".into(),
        width_mm: 120.0,
        height_mm: 120.0,
        projection_mm: 33.5,
        volume_ml: 252.58,
        default_position: "centred on the breast's base".into(),
        offset_mm: [0.0, 5.0, 0.0],
        rotation_deg: 0.0,
        fit_shift_mm: [0.0, 0.0],
    };
    ReportContent {
        title: "Breast augmentation plan".into(),
        case: CaseInfo {
            created: "2026-11-22 09:41 UTC".into(),
            software: "mammaplan 0.1.0".into(),
            files: vec![CaseFile {
                role: "Pre-operative scan".into(),
                name: "scan.ply".into(),
            }],
            model: ModelParameters {
                finest_elements: 60_491,
                finest_nodes: 13_943,
                mesh_levels: 4,
                rear_wall_offset_mm: 15.0,
                tissue: material(),
                implant_material: MaterialParameters {
                    young_kpa: 0.024,
                    poisson_ratio: 0.3,
                    density_kg_m3: 970.0,
                },
                skin: Some("344 kPa, 1.55 mm thick, a membrane on the surface".into()),
                compression_penalty: Some(
                    "every loss resisted with 1 times the first Lamé parameter".into(),
                ),
                gravity_correction: true,
                up: "the file's +y; the sternum leans 26.8° back from it".into(),
                pocket: Some("the fill-in widened up to 40 mm over the chest".into()),
                solver: SolverSummary {
                    vcycles: 23,
                    relative_residual: 3.1e-5,
                    converged: true,
                },
            },
        },
        implants: PerSide {
            left: Some(implant),
            right: None,
        },
        views: Vec::new(),
        measurements: vec![MeasurementRow {
            name: "Pj-Pnl".into(),
            preoperative_mm: Some(230.04),
            simulated_mm: Some(247.45),
            postoperative_mm: None,
        }],
        volumes: VolumeTable {
            preoperative: volumes(338.9),
            simulated: Some(volumes(574.4)),
            postoperative: None,
        },
        comparison: None,
        symmetry: Vec::new(),
        notes: Vec::new(),
    }
}

/// Content with every section filled.
fn full_content() -> ReportContent {
    let mut content = minimal_content();
    let mut frontal = View::new("Simulated, frontal", png_image(64, 48)).unwrap();
    frontal.caption = Some("landmarks as placed".into());
    frontal.labels = vec![
        ImageLabel {
            text: "Pnl".into(),
            x_px: 40.0,
            y_px: 30.0,
        },
        ImageLabel {
            text: "Pj".into(),
            x_px: 32.0,
            y_px: 5.5,
        },
    ];
    let mut deviation = View::new("Deviation, frontal", png_image(32, 40)).unwrap();
    deviation.colour_scale = Some(ColourScale::deviation_mm());
    let mut second_deviation = View::new("Deviation, left", png_image(20, 20)).unwrap();
    second_deviation.colour_scale = Some(ColourScale::deviation_mm());
    content.views = vec![frontal, deviation, second_deviation];
    content.measurements[0].postoperative_mm = Some(245.0);
    content.volumes.postoperative = Some(volumes(560.0));
    content.comparison = Some(Comparison {
        reference: "post-operative scan".into(),
        test: "simulated scan".into(),
        regions: vec![DeviationFigures {
            region: "Whole overlap".into(),
            rms_mm: 3.3,
            mean_mm: 2.1,
            hausdorff_mm: 14.2,
        }],
    });
    content.symmetry = vec![SymmetryRow {
        scan: "Pre-operative".into(),
        volume_ratio_left_to_right: 1.02,
        nipple_height_difference_mm: -4.0,
        nipple_midline_difference_mm: 1.5,
        nipple_mirror_distance_mm: 4.3,
    }];
    content.notes = vec!["The simulation did not converge.".into()];
    content
}

/// Parses a page; fails on any HTML5 parse error.
fn parse(page: &str) -> RcDom {
    let dom = html5ever::parse_document(RcDom::default(), Default::default())
        .from_utf8()
        .read_from(&mut page.as_bytes())
        .unwrap();
    let errors = dom.errors.borrow().clone();
    assert!(errors.is_empty(), "parse errors: {errors:?}");
    dom
}

/// Every element of the tree under `node` (depth first) with its local name.
fn elements(node: &Handle, out: &mut Vec<Handle>) {
    if let NodeData::Element { .. } = node.data {
        out.push(node.clone());
    }
    for child in node.children.borrow().iter() {
        elements(child, out);
    }
}

fn all_elements(dom: &RcDom) -> Vec<Handle> {
    let mut out = Vec::new();
    elements(&dom.document, &mut out);
    out
}

fn name(node: &Handle) -> String {
    match &node.data {
        NodeData::Element { name, .. } => name.local.to_string(),
        _ => String::new(),
    }
}

fn attribute(node: &Handle, key: &str) -> Option<String> {
    match &node.data {
        NodeData::Element { attrs, .. } => attrs
            .borrow()
            .iter()
            .find(|a| &*a.name.local == key)
            .map(|a| a.value.to_string()),
        _ => None,
    }
}

/// The text under `node`, concatenated.
fn text(node: &Handle) -> String {
    let mut out = String::new();
    if let NodeData::Text { contents } = &node.data {
        out.push_str(&contents.borrow());
    }
    for child in node.children.borrow().iter() {
        out.push_str(&text(child));
    }
    out
}

fn section_ids(dom: &RcDom) -> Vec<String> {
    all_elements(dom)
        .iter()
        .filter(|e| name(e) == "section")
        .filter_map(|e| attribute(e, "id"))
        .collect()
}

fn column_headers(dom: &RcDom, section: &str) -> Vec<String> {
    let elements = all_elements(dom);
    let section = elements
        .iter()
        .find(|e| attribute(e, "id").as_deref() == Some(section))
        .unwrap();
    let mut inside = Vec::new();
    crate::elements(section, &mut inside);
    inside
        .iter()
        .filter(|e| name(e) == "th" && attribute(e, "scope").as_deref() == Some("col"))
        .map(text)
        .collect()
}

#[test]
fn the_parser_reports_broken_markup() {
    // The check below means something: html5ever flags mismatched and stray tags.
    let dom = html5ever::parse_document(RcDom::default(), Default::default())
        .from_utf8()
        .read_from(&mut "<!DOCTYPE html><html><body><p>a</div></body></html>".as_bytes())
        .unwrap();
    assert!(!dom.errors.borrow().is_empty());
}

#[test]
fn a_full_report_is_well_formed_with_every_section() {
    let page = render_html(&full_content());
    let dom = parse(&page);
    assert_eq!(
        section_ids(&dom),
        [
            "notes",
            "case",
            "implants",
            "views",
            "measurements",
            "volumes",
            "comparison",
            "symmetry"
        ]
    );
    assert_eq!(
        column_headers(&dom, "measurements"),
        [
            "Distance",
            "Pre-op",
            "Simulated",
            "Change",
            "Post-op",
            "Post-op − simulated"
        ]
    );
    assert_eq!(
        column_headers(&dom, "volumes"),
        [
            "Region",
            "Pre-op",
            "Simulated",
            "Change",
            "Post-op",
            "Post-op − simulated"
        ]
    );
    // Differences: 247.45 - 230.04 = 17.41 and 245.0 - 247.45 = -2.45, to one decimal.
    assert!(page.contains("+17.4"), "simulated change");
    assert!(page.contains("the sternum leans 26.8° back") && page.contains("widened up to 40 mm"));
    assert!(
        page.contains("\u{2212}2.5") || page.contains("\u{2212}2.4"),
        "post-op difference"
    );
    // One legend per colour-mapped view, each with its own gradient.
    let gradients: Vec<String> = all_elements(&dom)
        .iter()
        .filter(|e| name(e) == "linearGradient")
        .filter_map(|e| attribute(e, "id"))
        .collect();
    assert_eq!(gradients, ["colour-scale-1", "colour-scale-2"]);
    assert!(
        page.contains("≥ 20"),
        "the saturated end of the deviation scale"
    );
}

#[test]
fn a_minimal_report_leaves_out_the_sections_it_has_no_data_for() {
    let page = render_html(&minimal_content());
    let dom = parse(&page);
    assert_eq!(
        section_ids(&dom),
        ["case", "implants", "measurements", "volumes"]
    );
    assert_eq!(
        column_headers(&dom, "measurements"),
        ["Distance", "Pre-op", "Simulated", "Change"]
    );
    let elements = all_elements(&dom);
    for absent in ["svg", "image", "figure"] {
        assert!(!elements.iter().any(|e| name(e) == absent), "{absent}");
    }
    // The right side has no implant.
    assert!(column_headers(&dom, "implants").contains(&"Right (none)".to_string()));

    // Without quadrant volumes there are no quadrant rows.
    let mut content = minimal_content();
    content.volumes.preoperative.left.quadrants_ml = None;
    content.volumes.preoperative.right.quadrants_ml = None;
    content.volumes.simulated = None;
    let dom = parse(&render_html(&content));
    assert_eq!(column_headers(&dom, "volumes"), ["Region", "Pre-op"]);
    assert!(
        !all_elements(&dom)
            .iter()
            .any(|e| attribute(e, "class").as_deref() == Some("quadrant"))
    );
}

#[test]
fn the_page_references_nothing_outside_itself() {
    let page = render_html(&full_content());
    let dom = parse(&page);
    for element in all_elements(&dom) {
        for key in ["src", "href", "xlink:href", "action", "poster", "srcset"] {
            if let Some(value) = attribute(&element, key) {
                assert!(
                    value.starts_with("data:image/png;base64,"),
                    "<{} {key}={value:.60}>",
                    name(&element)
                );
            }
        }
        assert!(
            !["script", "link", "iframe", "object", "embed", "img"]
                .contains(&name(&element).as_str())
        );
    }
    // Outside the data URIs (whose base64 may contain `//`) no address of any kind.
    let mut rest = page.clone();
    while let Some(start) = rest.find("data:image/png;base64,") {
        let end = rest[start..].find('"').map_or(rest.len(), |e| start + e);
        rest.replace_range(start..end, "");
    }
    for forbidden in ["http:", "https:", "//", "@import", "src=", "file:", "ftp:"] {
        assert!(!rest.contains(forbidden), "{forbidden} in the page");
    }
    for (at, _) in rest.match_indices("url(") {
        assert!(rest[at..].starts_with("url(#"), "{:.30}", &rest[at..]);
    }
}

#[test]
fn embedded_images_decode_to_the_given_png_bytes() {
    let content = full_content();
    let dom = parse(&render_html(&content));
    let images: Vec<Handle> = all_elements(&dom)
        .into_iter()
        .filter(|e| name(e) == "image")
        .collect();
    assert_eq!(images.len(), content.views.len());
    for (image, view) in images.iter().zip(&content.views) {
        let href = attribute(image, "href").unwrap();
        let encoded = href.strip_prefix("data:image/png;base64,").unwrap();
        let decoded = base64::engine::general_purpose::STANDARD
            .decode(encoded)
            .unwrap();
        assert_eq!(decoded, view.png());
        let (width, height) = view.size_px();
        assert_eq!(attribute(image, "width"), Some(width.to_string()));
        assert_eq!(attribute(image, "height"), Some(height.to_string()));
    }
    // The labels sit at their pixels in the image's own coordinates (the SVG's view box
    // is the image), just above and to the right.
    let svg = all_elements(&dom)
        .into_iter()
        .find(|e| name(e) == "svg")
        .unwrap();
    assert_eq!(
        attribute(&svg, "viewbox").or(attribute(&svg, "viewBox")),
        Some("0 0 64 48".into())
    );
    let labels: Vec<(String, f64, f64)> = all_elements(&dom)
        .iter()
        .filter(|e| name(e) == "text")
        .take(2)
        .map(|e| {
            let coordinate = |key| attribute(e, key).unwrap().parse::<f64>().unwrap();
            (text(e), coordinate("x"), coordinate("y"))
        })
        .collect();
    assert_eq!(labels[0].0, "Pnl");
    assert_eq!(labels[1].0, "Pj");
    for ((_, x, y), (x_px, y_px)) in labels.iter().zip([(40.0, 30.0), (32.0, 5.5)]) {
        assert!(*x > x_px && *x < x_px + 5.0, "x {x}");
        assert!(*y < y_px && *y > y_px - 5.0, "y {y}");
    }
}

#[test]
fn user_text_is_escaped() {
    let hostile = r#"<script>alert("x")</script> & 'quoted' "double" </td></table>"#;
    let mut content = full_content();
    content.title = hostile.into();
    content.case.files[0].name = hostile.into();
    content.views[0].labels[0].text = hostile.into();
    content.views[0].title = hostile.into();
    content.measurements[0].name = hostile.into();
    content.notes = vec![hostile.into()];
    let page = render_html(&content);
    assert!(!page.contains("<script"), "raw markup in the page");
    assert!(page.contains("&lt;script&gt;alert(&quot;x&quot;)&lt;/script&gt; &amp; 'quoted'"));
    let dom = parse(&page);
    let elements = all_elements(&dom);
    assert!(!elements.iter().any(|e| name(e) == "script"));
    // The text reads back as given wherever it is shown.
    let title = elements.iter().find(|e| name(e) == "title").unwrap();
    assert_eq!(text(title), hostile);
    let shown = elements
        .iter()
        .filter(|e| ["h1", "td", "text", "li", "th", "strong"].contains(&name(e).as_str()))
        .filter(|e| text(e) == hostile)
        .count();
    // h1, file name cell, label, note, measurement row header, view title.
    assert_eq!(shown, 6);
    // In attributes too (the view's accessible name).
    let svg = elements.iter().find(|e| name(e) == "svg").unwrap();
    assert_eq!(attribute(svg, "aria-label").as_deref(), Some(hostile));
}

#[test]
fn a_view_needs_a_png_image() {
    assert_eq!(
        View::new("not an image", b"GIF89a and more bytes here".to_vec()),
        Err(PngError::NotPng)
    );
    let view = View::new("image", png_image(7, 3)).unwrap();
    assert_eq!(view.size_px(), (7, 3));
}
