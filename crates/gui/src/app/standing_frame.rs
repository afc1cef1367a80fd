//! Which way is up (issue 25): the standing frame the window believes in, where that
//! came from, and the user's choice of the scan's vertical for a file that lies in
//! another orientation (a handheld scanner's, say).

use super::{ERROR_COLOR, GuiApp};
use crate::camera::StandardView;
use anatomy::{AnatomicalFrame, Up, UpSource};
use eframe::egui;
use glam::DVec3;

/// The file axes offered as the scan's vertical.
const AXES: [(&str, DVec3); 6] = [
    ("+y", DVec3::Y),
    ("-y", DVec3::NEG_Y),
    ("+z", DVec3::Z),
    ("-z", DVec3::NEG_Z),
    ("+x", DVec3::X),
    ("-x", DVec3::NEG_X),
];

/// The choice's label: an axis, a vector, or the automatic rule.
fn label(up: Option<Up>) -> String {
    match up {
        None => "automatic".into(),
        Some(up) => AXES
            .iter()
            .find(|(_, axis)| up.direction.abs_diff_eq(*axis, 1e-9))
            .map_or_else(
                || {
                    let d = up.direction;
                    format!("{:.2}, {:.2}, {:.2}", d.x, d.y, d.z)
                },
                |(name, _)| (*name).to_string(),
            ),
    }
}

/// What the window believes about up, in words.
fn describe(frame: &AnatomicalFrame) -> String {
    let tilt = frame.up().angle_between(DVec3::Y).to_degrees();
    match frame.up_source {
        UpSource::FileVertical => "Up is the file's +y: the scan stands upright.".into(),
        UpSource::Given => format!("Up as chosen, {tilt:.0}° from the file's +y."),
        UpSource::Estimated => format!(
            "Up estimated from the sternum and clavicles, {tilt:.0}° from the file's +y: \
             the file does not stand upright. Choose its vertical if you know it."
        ),
    }
}

impl GuiApp {
    /// The standing frame's up and the choice of the scan's vertical.
    pub(super) fn up_panel(&mut self, ui: &mut egui::Ui) {
        let Some(document) = &self.document else {
            return;
        };
        match document.landmarks.frame(document.up) {
            None => {
                ui.weak("Up: the file's +y until Pj, Px, Pcl and Pcr are placed.");
            }
            Some(Err(error)) => {
                ui.colored_label(ERROR_COLOR, error.to_string());
            }
            Some(Ok(frame)) => {
                ui.label(describe(&frame));
            }
        }
        let current = document.up;
        let mut chosen = label(current);
        egui::ComboBox::from_label("Scan's vertical")
            .selected_text(chosen.clone())
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut chosen, "automatic".to_string(), "automatic");
                for (name, _) in AXES {
                    ui.selectable_value(&mut chosen, name.to_string(), name);
                }
            })
            .response
            .on_hover_text(
                "the file axis that points up in the standing patient; automatic: the \
                 file's +y when the patient stands upright in it, else an estimate from \
                 the sternum and clavicles",
            );
        if chosen != label(current) {
            let up = AXES
                .iter()
                .find(|(name, _)| *name == chosen)
                .map(|&(_, direction)| Up {
                    direction,
                    source: UpSource::Given,
                });
            self.set_up(up);
        }
    }

    /// Takes `up` as the scan's vertical (`None`: the automatic rule): the distances are
    /// measured again, a model built before no longer fits, and the view looks from the
    /// front of the new frame.
    pub(super) fn set_up(&mut self, up: Option<Up>) {
        let Some(document) = &mut self.document else {
            return;
        };
        document.up = up;
        self.distances = None;
        self.landmarks_changed();
        self.set_view(StandardView::Front);
        self.info(format!("the scan's vertical: {}", label(up)));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn axes_and_the_automatic_rule_have_labels_that_round_trip() {
        assert_eq!(label(None), "automatic");
        for (name, direction) in AXES {
            let up = Up {
                direction,
                source: UpSource::Given,
            };
            assert_eq!(label(Some(up)), name);
            assert_eq!(Up::parse(name).unwrap().direction, direction);
        }
        let tilted = Up {
            direction: DVec3::new(0.0, 0.6, 0.8),
            source: UpSource::Given,
        };
        assert_eq!(label(Some(tilted)), "0.00, 0.60, 0.80");
    }
}
