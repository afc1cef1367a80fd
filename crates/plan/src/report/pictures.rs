//! The report's pictures: the scans' standard views with their cut curves, landmarks
//! and reconstructed skin, and the change from the pre-operative surface as a colour map.

use super::*;

/// The rendered views of the report: the pre-operative, the simulated and (when given)
/// the post-operative scan from the front, the obliques and the sides, with landmarks
/// (labelled) and cut curves, then the simulated scan coloured by its distance from the
/// pre-operative surface (where the implants changed the shape), front and obliques;
/// with `muscles` (the model's `muscle_*.ply`), the pectoralis major through the
/// pre-operative skin, front and obliques, last.
pub fn report_views(scans: &ReportScans, muscles: &[mesh::TriMesh]) -> Result<Vec<report::View>> {
    let mut views = Vec::new();
    let mut shown = vec![
        ("Pre-operative", &scans.preoperative),
        ("Simulated", &scans.simulated),
    ];
    if let Some(postoperative) = &scans.postoperative {
        shown.push(("Post-operative", postoperative));
    }
    for (title, scan) in shown {
        let curves = scan.breasts.as_ref().map(cut_curves).unwrap_or_default();
        let reconstructed = scan
            .breasts
            .as_ref()
            .map(reconstructed_skin)
            .unwrap_or_default();
        let content = ViewContent {
            curves: &curves,
            reconstructed: &reconstructed,
            texture: scan.marked.scan.texture.as_ref().map(|t| &t.image),
            ..Default::default()
        };
        for view in standard_views(
            &scan.marked.scan.mesh,
            &scan.marked.landmarks,
            scan.marked.up(),
            &content,
        )? {
            views.push(report_view(format!("{title}, {}", view.name), view, None)?);
        }
    }
    let pre = &scans.preoperative.marked.scan;
    let reference = DistanceSurface::new(&pre.mesh, &pre.index, &pre.topology);
    let colours: Vec<[u8; 3]> = reference
        .deviations(
            &scans.simulated.marked.scan.mesh.positions,
            DEFAULT_MAX_DISTANCE_MM,
        )
        .iter()
        .map(|d| deviation_color(d.map_or(f64::NAN, |d| d.distance_mm)))
        .collect();
    let content = ViewContent {
        colours: Some(&colours),
        ..Default::default()
    };
    let simulated = &scans.simulated.marked;
    for view in standard_views(
        &simulated.scan.mesh,
        &simulated.landmarks,
        simulated.up(),
        &content,
    )? {
        if is_front_or_oblique(view.view) {
            let title = format!("Change from the pre-operative surface, {}", view.name);
            views.push(report_view(
                title,
                view,
                Some(deviation_scale(
                    "Distance from the pre-operative surface (mm)",
                )),
            )?);
        }
    }
    if !muscles.is_empty() {
        let pre = &scans.preoperative.marked;
        let content = ViewContent {
            muscles,
            ..Default::default()
        };
        for view in standard_views(&pre.scan.mesh, &pre.landmarks, pre.up(), &content)? {
            if is_front_or_oblique(view.view) {
                let title = format!(
                    "Pectoralis major under the pre-operative skin, {}",
                    view.name
                );
                views.push(report_view(title, view, None)?);
            }
        }
    }
    Ok(views)
}

fn is_front_or_oblique(view: StandardView) -> bool {
    matches!(
        view,
        StandardView::Front | StandardView::LeftOblique | StandardView::RightOblique
    )
}

/// The cut curves of both breasts as points on the surface (mm).
/// What the views' grey-blue patches are, where the pre-operative breasts have any.
pub(super) fn reconstruction_note(scans: &ReportScans) -> Option<String> {
    let breasts = scans.preoperative.breasts.as_ref()?;
    let shares = Side::BOTH.map(|side| breasts.breast(side).reconstructed.area_share);
    (shares.iter().any(|&share| share > 0.0)).then(|| {
        format!(
            "Skin drawn in grey-blue was not seen by the scanner and is reconstructed by the \
             model ({:.0}% of the left breast's skin, {:.0}% of the right's): its shape is \
             an estimate, not a measurement.",
            100.0 * shares[0],
            100.0 * shares[1]
        )
    })
}

/// Each breast's reconstructed skin, as a mesh of its own.
pub(super) fn reconstructed_skin(breasts: &BreastModel) -> Vec<mesh::TriMesh> {
    Side::BOTH
        .map(|side| {
            let breast = breasts.breast(side);
            breast.reconstructed.skin(&breast.patch.mesh)
        })
        .into()
}

pub(super) fn cut_curves(breasts: &BreastModel) -> Vec<Vec<DVec3>> {
    [&breasts.left, &breasts.right]
        .map(|breast| breast.curve.points.iter().map(|p| p.position).collect())
        .to_vec()
}

/// A rendered view for the report, its visible landmarks labelled.
pub(super) fn report_view(
    title: String,
    view: RenderedView,
    colour_scale: Option<report::ColourScale>,
) -> Result<report::View> {
    let mut shown = report::View::new(title, view.png).context("a rendered view")?;
    shown.labels = view
        .markers
        .into_iter()
        .filter(|m| m.visibility == Visibility::Visible)
        .map(|m| report::ImageLabel {
            text: m.label,
            x_px: m.pixel.x,
            y_px: m.pixel.y,
        })
        .collect();
    shown.colour_scale = colour_scale;
    Ok(shown)
}

/// The legend of [`assess::deviation_color`], sampled at its ramp's corners.
pub(super) fn deviation_scale(label: &str) -> report::ColourScale {
    report::ColourScale {
        label: label.into(),
        min: 0.0,
        max: DEVIATION_COLOR_MAX_MM,
        saturates_above_max: true,
        stops: [0.0, 0.5, 1.0]
            .map(|fraction| report::ColourStop {
                fraction,
                rgb: deviation_color(fraction * DEVIATION_COLOR_MAX_MM),
            })
            .to_vec(),
    }
}
