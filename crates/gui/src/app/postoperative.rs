//! The post-operative scan in the window (issue 8, item 3): its scan and landmark files,
//! its registration onto the planned scan and its deviation map from the pre-operative or
//! the simulated surface, each on a background job, and the panel that drives them.

use super::{ERROR_COLOR, FileChoice, GuiApp, PLACED_COLOR};
use crate::deviation::DeviationMap;
use crate::job::Job;
use crate::registration::RegisteredScan;
use eframe::egui;
use plan::Scan;
use std::path::PathBuf;
use std::sync::Arc;

/// The surface the post-operative scan is compared with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum DeviationReference {
    /// The scan as loaded.
    #[default]
    PreOperative,
    /// The settled prediction.
    Simulated,
}

impl DeviationReference {
    /// The colour legend's title.
    pub fn legend_title(self) -> &'static str {
        match self {
            DeviationReference::PreOperative => "Distance from the pre-operative surface (mm)",
            DeviationReference::Simulated => "Distance from the simulated surface (mm)",
        }
    }
}

/// Which surface a map was computed against: the reference and, for the simulated one,
/// the number of the frame it was settled on.
type ReferenceKey = (DeviationReference, u64);

/// The post-operative scan's state.
#[derive(Default)]
pub struct PostOperative {
    /// The scan and landmark paths typed in the panel.
    pub scan_text: String,
    pub landmarks_text: String,
    registering: Option<Job<anyhow::Result<RegisteredScan>>>,
    /// The scan registered onto the planned one.
    pub registered: Option<Arc<RegisteredScan>>,
    /// What it is compared with.
    pub reference: DeviationReference,
    comparing: Option<(ReferenceKey, Job<anyhow::Result<DeviationMap>>)>,
    /// The latest deviation map, and what it was computed against.
    deviation: Option<(ReferenceKey, Result<DeviationMap, String>)>,
}

impl PostOperative {
    /// Forgets the registered scan and its maps (the planned scan changed); keeps the
    /// paths typed.
    pub fn reset(&mut self) {
        *self = PostOperative {
            scan_text: std::mem::take(&mut self.scan_text),
            landmarks_text: std::mem::take(&mut self.landmarks_text),
            reference: self.reference,
            ..PostOperative::default()
        };
    }

    /// Whether a registration is under way.
    pub fn is_registering(&self) -> bool {
        self.registering.is_some()
    }

    /// Whether a deviation map is being computed.
    pub fn is_comparing(&self) -> bool {
        self.comparing.is_some()
    }

    /// Why the latest deviation map could not be computed, if it could not.
    pub fn deviation_failure(&self) -> Option<&str> {
        self.deviation
            .as_ref()?
            .1
            .as_ref()
            .err()
            .map(String::as_str)
    }

    /// The latest deviation map (perhaps of an earlier reference while the current one
    /// is computed), with the reference it was computed against.
    pub fn deviation(&self) -> Option<(DeviationReference, &DeviationMap)> {
        let ((reference, _), map) = self.deviation.as_ref()?;
        Some((*reference, map.as_ref().ok()?))
    }
}

impl GuiApp {
    /// The post-operative scan's state.
    pub fn postoperative(&self) -> &PostOperative {
        &self.postoperative
    }

    /// Starts registering the post-operative scan typed in the panel onto the open scan.
    pub(super) fn start_registration(&mut self) {
        let Some(document) = &self.document else {
            return;
        };
        let fixed = match document.marked() {
            Ok(fixed) => fixed,
            Err(error) => {
                return self.error_status(&error.context("registering the post-operative scan"));
            }
        };
        let scan = PathBuf::from(self.postoperative.scan_text.trim());
        let landmarks = PathBuf::from(self.postoperative.landmarks_text.trim());
        self.postoperative.reset();
        self.postoperative.registering = Some(Job::spawn(self.waker(), move || {
            RegisteredScan::register(&fixed, &scan, &landmarks)
        }));
        self.info("registering the post-operative scan…");
    }

    /// Takes the registration and deviation maps once computed, and starts the map
    /// against the chosen surface when it is missing.
    pub(super) fn update_postoperative(&mut self) {
        let postoperative = &mut self.postoperative;
        if let Some(job) = &postoperative.registering
            && let Some(answer) = job.poll()
        {
            postoperative.registering = None;
            match answer.and_then(|result| result.map_err(|error| format!("{error:#}"))) {
                Ok(registered) => {
                    let report = &registered.report;
                    let message = format!(
                        "registered {}: landmark RMS {:.2} mm, surface RMS {:.2} mm away from \
                         the breasts",
                        registered.scan_path.display(),
                        report.landmark_rms_mm,
                        report.surface_rms_mm
                    );
                    postoperative.registered = Some(Arc::new(registered));
                    self.display = super::DisplayMode::PostOperative;
                    self.info(message);
                }
                Err(message) => {
                    self.status = super::Status::Error(format!(
                        "registering the post-operative scan: {message}"
                    ));
                }
            }
        }
        let postoperative = &mut self.postoperative;
        if let Some((key, job)) = &postoperative.comparing
            && let Some(answer) = job.poll()
        {
            let key = *key;
            postoperative.comparing = None;
            let map = answer.and_then(|result| result.map_err(|error| format!("{error:#}")));
            postoperative.deviation = Some((key, map));
        }
        let Some((key, reference)) = self.deviation_reference() else {
            return;
        };
        let postoperative = &self.postoperative;
        let (Some(registered), None) = (&postoperative.registered, &postoperative.comparing) else {
            return;
        };
        if postoperative.deviation.as_ref().map(|(k, _)| *k) == Some(key) {
            return;
        }
        let registered = Arc::clone(registered);
        let job = Job::spawn(self.waker(), move || {
            DeviationMap::compute(&reference, &registered.scan, &registered.scene)
        });
        self.postoperative.comparing = Some((key, job));
    }

    /// The surface the post-operative scan is to be compared with, if it is there (the
    /// simulated one once the simulation has settled and its scan is prepared).
    fn deviation_reference(&self) -> Option<(ReferenceKey, Arc<Scan>)> {
        match self.postoperative.reference {
            DeviationReference::PreOperative => {
                let document = self.document.as_ref()?;
                Some((
                    (DeviationReference::PreOperative, 0),
                    Arc::clone(&document.scan),
                ))
            }
            DeviationReference::Simulated => {
                let settled = self.live.as_ref()?.settled.as_ref()?;
                Some((
                    (DeviationReference::Simulated, settled.frame),
                    Arc::clone(&settled.scan),
                ))
            }
        }
    }

    pub(super) fn postoperative_panel(&mut self, ui: &mut egui::Ui) {
        if self.document.is_none() {
            ui.label("No scan open.");
            return;
        }
        let postoperative = &mut self.postoperative;
        let asking = self.dialog.is_some();
        let mut browse = None;
        for (label, text, hint, choice) in [
            (
                "Scan file",
                &mut postoperative.scan_text,
                "post-operative scan .ply / .obj / .stl",
                FileChoice::PostoperativeScan,
            ),
            (
                "Landmark file",
                &mut postoperative.landmarks_text,
                "its landmarks .json",
                FileChoice::PostoperativeLandmarks,
            ),
        ] {
            let label = ui.label(label);
            ui.horizontal(|ui| {
                ui.add(
                    egui::TextEdit::singleline(text)
                        .hint_text(hint)
                        .desired_width(230.0),
                )
                .labelled_by(label.id);
                if ui
                    .add_enabled(!asking, egui::Button::new("…"))
                    .on_hover_text("choose in the desktop's file dialog")
                    .clicked()
                {
                    browse = Some(choice);
                }
            });
        }
        if let Some(choice) = browse {
            self.ask_for_file(choice);
        }
        let postoperative = &mut self.postoperative;
        let busy = postoperative.registering.is_some();
        let mut register = false;
        ui.horizontal(|ui| {
            register = ui
                .add_enabled(!busy, egui::Button::new("Register"))
                .on_hover_text(
                    "onto the open scan: bony landmarks, then ICP away from the breasts \
                     (as mammaplan register --icp)",
                )
                .clicked();
            if busy {
                ui.spinner();
                ui.weak("registering…");
            }
        });
        if register {
            self.start_registration();
        }
        let postoperative = &mut self.postoperative;
        let Some(registered) = &postoperative.registered else {
            return;
        };
        let report = &registered.report;
        ui.colored_label(
            PLACED_COLOR,
            format!(
                "Registered: landmark RMS {:.2} mm, surface RMS {:.2} mm away from the breasts \
                 ({} ICP iterations, turned {:.1}°, moved {:.1} mm)",
                report.landmark_rms_mm,
                report.surface_rms_mm,
                report.icp_iterations,
                report.rotation_deg,
                glam::DVec3::from_array(report.translation_mm).length()
            ),
        );
        ui.horizontal(|ui| {
            ui.label("Compare with");
            ui.radio_value(
                &mut postoperative.reference,
                DeviationReference::PreOperative,
                "pre-operative",
            );
            ui.radio_value(
                &mut postoperative.reference,
                DeviationReference::Simulated,
                "simulated",
            );
        });
        let wanted = postoperative.reference;
        match &postoperative.deviation {
            Some(((reference, _), Ok(map))) if *reference == wanted => {
                ui.label(format!(
                    "Post-operative deviation: RMS {:.2} mm, mean {:.2} mm, Hausdorff {:.1} mm \
                     over {:.0}% of its vertices",
                    map.statistics.rms_mm,
                    map.statistics.mean_mm,
                    map.statistics.hausdorff_mm,
                    100.0 * map.overlap_fraction
                ));
            }
            Some(((reference, _), Err(message))) if *reference == wanted => {
                ui.colored_label(ERROR_COLOR, message);
            }
            _ if wanted == DeviationReference::Simulated && self.live.is_none() => {
                ui.weak("Build the model to compare with the simulation.");
            }
            _ => {}
        }
        if postoperative.comparing.is_some() {
            ui.horizontal(|ui| {
                ui.spinner();
                ui.weak("computing the deviation map…");
            });
        }
        if ui.button("Show the post-operative scan").clicked() {
            self.display = super::DisplayMode::PostOperative;
        }
    }
}
