//! The planning half of the window: the breast model (settings, "Build model" with its
//! progress, volumes, cut curves), the simulation's indicator and
//! display modes, the measurements and their export, and planning cases.

use super::ControlPointTool;
use super::{ERROR_COLOR, GuiApp, PLACED_COLOR, Status};
use crate::carried::{SurfaceAnchor, anchors};
use crate::display_mode::DisplayMode;
use crate::document::Document;
use crate::implant_plan::ImplantPlan;
use crate::live_simulation::{
    ExportPaths, ImplantSet, LiveSimulation, MeasurementState, ReportState, SolverStatus,
};
use crate::model_build::{BuildOutcome, ModelBuild};
use crate::render::SceneMesh;
use anatomy::ControlPoints;
use anatomy::breast::{QuadrantVolumes, Side};
use eframe::egui::{self, Color32};
use glam::DVec3;
use plan::Place;
use plan::case::PlanningCase;
use plan::model::{DEFAULT_ELEMENTS, PerSide};
use plan::report::PostoperativeScan;
use plan::simulate::{Material, Session, SimulatedMeasurements, SolveState, Stage};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

/// The stages of a model build, in order (the progress bar's thirds).
const BUILD_STAGES: [&str; 3] = ["model", "tetrahedra", "simulation"];
/// The element counts the slider offers.
const ELEMENTS_RANGE: std::ops::RangeInclusive<usize> = 2_000..=200_000;
const RUNNING_COLOR: Color32 = Color32::from_rgb(240, 190, 60);

/// How the model is built and the tissue simulated (saved in planning cases).
#[derive(Debug, Clone, PartialEq)]
pub struct ModelSettings {
    /// About how many tetrahedra the finest level has.
    pub elements: usize,
    pub tissue: Material,
    /// The cut curves' control points of the built model (or of a reopened case); `None`:
    /// the defaults from the landmarks.
    pub control_points: Option<ControlPoints>,
}

impl Default for ModelSettings {
    fn default() -> ModelSettings {
        ModelSettings {
            elements: DEFAULT_ELEMENTS,
            tissue: Material::default(),
            control_points: None,
        }
    }
}

/// The figures of a built model the window shows.
#[derive(Debug, Clone)]
pub struct ModelFigures {
    pub breast_volume_ml: PerSide<f64>,
    pub quadrant_volume_ml: PerSide<QuadrantVolumes>,
    /// Each breast's cut curve (closed, mm, file frame).
    pub cut_curves: PerSide<Vec<DVec3>>,
    /// The cut curves' points on the scan, to carry them onto simulated frames.
    pub cut_curve_anchors: PerSide<Vec<SurfaceAnchor>>,
    /// Tetrahedra of the finest level and number of levels.
    pub elements: usize,
    pub levels: usize,
    pub build_time: Duration,
    /// The landmarks changed since it was built.
    pub stale: bool,
}

impl ModelFigures {
    fn of(session: &Session, build_time: Duration) -> ModelFigures {
        let breasts = &session.model.breasts;
        let cut_curves: PerSide<Vec<DVec3>> = PerSide::from_fn(|side| {
            breasts
                .breast(side)
                .curve
                .points
                .iter()
                .map(|p| p.position)
                .collect()
        });
        ModelFigures {
            breast_volume_ml: PerSide::from_fn(|side| breasts.breast(side).volume_ml),
            quadrant_volume_ml: PerSide::from_fn(|side| breasts.breast(side).quadrant_volume_ml),
            cut_curve_anchors: PerSide::from_fn(|side| {
                anchors(&session.marked.scan.index, cut_curves.get(side))
            }),
            cut_curves,
            elements: session.model.levels.first().map_or(0, |l| l.elements),
            levels: session.model.levels.len(),
            build_time,
            stale: false,
        }
    }
}

impl GuiApp {
    /// The built model's figures.
    pub fn model(&self) -> Option<&ModelFigures> {
        self.model.as_ref()
    }

    /// Where the last build failed, if its error names a place and nothing has changed
    /// since (a new build, scan or landmarks take it away).
    pub fn failure_place(&self) -> Option<Place> {
        self.failure_place
    }

    /// Whether a model build is under way.
    pub fn is_building(&self) -> bool {
        self.build.is_some()
    }

    /// The live simulation, once a model is built.
    pub fn live(&self) -> Option<&LiveSimulation> {
        self.live.as_ref()
    }

    /// The implants as edited.
    pub fn implants(&self) -> &ImplantPlan {
        &self.implants
    }

    /// The model settings.
    pub fn settings(&self) -> &ModelSettings {
        &self.settings
    }

    /// What the viewport shows.
    pub fn display(&self) -> DisplayMode {
        self.display
    }

    /// Starts building the model of the open scan on a worker thread.
    pub(super) fn start_build(&mut self) {
        self.failure_place = None;
        let Some(document) = &self.document else {
            return;
        };
        let (marked, case) = match document.marked() {
            Ok(marked) => (marked, self.case_of(document)),
            Err(error) => return self.error_status(&error),
        };
        self.cancel_build();
        // The build cuts along the control points as they are now.
        self.control_points_edited = false;
        self.control_point_tool = None;
        let wake = self.waker();
        self.build = Some(ModelBuild::start(
            marked,
            case.model_options(),
            case.simulation_options(),
            wake,
        ));
        self.info("building the model…");
    }

    /// Stops a build under way (its worker finishes its stage and is forgotten).
    pub(super) fn cancel_build(&mut self) {
        if let Some(build) = self.build.take() {
            build.cancel();
        }
    }

    /// A callback that asks the window for a repaint (a no-op before the first frame).
    pub(super) fn waker(&self) -> impl Fn() + Send + Sync + 'static {
        let ctx = self.ctx.clone();
        move || {
            if let Some(ctx) = &ctx {
                ctx.request_repaint();
            }
        }
    }

    /// Takes a finished build: its figures shown, its session handed to a live
    /// simulation.
    pub(super) fn poll_build(&mut self, ctx: &egui::Context) {
        self.ctx = Some(ctx.clone());
        let Some(build) = &self.build else {
            return;
        };
        let warnings = build.take_warnings();
        let outcome = build.poll();
        for warning in warnings {
            self.info(format!("warning: {warning}"));
        }
        let Some(outcome) = outcome else {
            // Keep the progress bar moving while the worker has nothing to report.
            ctx.request_repaint_after(Duration::from_millis(250));
            return;
        };
        self.build = None;
        match outcome {
            BuildOutcome::Built(session, build_time) => {
                let figures = ModelFigures::of(&session, build_time);
                // The control points the model was built with: those given (a case's,
                // kept as they are) or else the defaults it derived from the landmarks.
                if self.settings.control_points.is_none() {
                    self.settings.control_points = Some(session.model.control_points());
                }
                self.info(format!(
                    "model built in {:.1} s: {} tetrahedra in {} levels",
                    build_time.as_secs_f64(),
                    figures.elements,
                    figures.levels
                ));
                self.model = Some(figures);
                self.muscle = muscle_scene(&session);
                if let Some(scene) = &self.scene {
                    self.live = Some(LiveSimulation::start(
                        *session,
                        Arc::clone(scene),
                        self.software_renderer,
                        self.waker(),
                    ));
                    self.display = DisplayMode::Simulated;
                }
            }
            BuildOutcome::Cancelled => self.info("model building cancelled"),
            BuildOutcome::Failed(error) => {
                self.failure_place = plan::failure_place(&error);
                if self.failure_place.is_some() {
                    // The ring is drawn on the scan the failed build was given.
                    self.display = DisplayMode::PreOperative;
                }
                self.error_status(&error.context("building the model"));
            }
        }
    }

    /// Takes the simulation's updates and sends it the implants if they changed.
    pub(super) fn update_simulation(&mut self) {
        let Some(live) = &mut self.live else {
            return;
        };
        live.poll();
        match self.implants.requests(&self.catalog) {
            Ok(implants) => {
                self.implant_error = None;
                live.set_implants(&ImplantSet {
                    implants,
                    gravity: self.implants.gravity,
                });
            }
            Err(error) => self.implant_error = Some(error),
        }
    }

    /// The planning case of the window's state.
    fn case_of(&self, document: &Document) -> PlanningCase {
        let mut case = PlanningCase::new(document.source.clone(), document.landmarks.clone());
        case.up = document.up;
        let unit = document.scan.file_unit;
        case.scan_units = (unit != plan::LengthUnit::Millimetre).then_some(unit);
        case.control_points = self.settings.control_points.clone();
        case.elements = self.settings.elements;
        case.tissue = self.settings.tissue;
        case.gravity = self.implants.gravity;
        case.linked = self.implants.linked();
        case
    }

    /// The planning case of the window, implants included; errors when an implant's
    /// design makes no implant.
    pub fn case(&self) -> anyhow::Result<PlanningCase> {
        let Some(document) = &self.document else {
            anyhow::bail!("no scan open");
        };
        let mut case = self.case_of(document);
        case.implants = self
            .implants
            .requests(&self.catalog)
            .map_err(anyhow::Error::msg)?;
        Ok(case)
    }

    /// Writes the planning case to the `.json` path typed in the path field.
    pub(super) fn save_case(&mut self) {
        let path = PathBuf::from(self.path_text.trim());
        if !Document::is_landmark_file(&path) {
            self.status = Status::Error(
                "type where to save the case (a path ending in .json) in the path field".into(),
            );
            return;
        }
        match self.case().and_then(|case| case.write(&path)) {
            Ok(()) => self.info(format!("saved the case {}", path.display())),
            Err(error) => self.error_status(&error),
        }
    }

    /// Opens a planning case: its scan and landmarks, settings and implants; builds its
    /// model when all landmarks are placed (the implants follow once it is built).
    pub(super) fn open_case(&mut self, path: &Path) {
        let opened = PlanningCase::read(path).and_then(|case| {
            let (document, warnings) = Document::from_case(&case, path)?;
            let implants = ImplantPlan::from_requests(
                &case.implants,
                case.linked,
                case.gravity,
                &self.catalog,
            )
            .map_err(anyhow::Error::msg)?;
            Ok((case, document, warnings, implants))
        });
        let (case, document, warnings, implants) = match opened {
            Ok(opened) => opened,
            Err(error) => return self.error_status(&error),
        };
        self.set_document(document);
        self.settings = ModelSettings {
            elements: case.elements,
            tissue: case.tissue,
            control_points: case.control_points,
        };
        self.implants = implants;
        let mut message = format!("opened the case {}", path.display());
        for warning in warnings {
            message.push_str("; ");
            message.push_str(&warning);
        }
        self.info(message);
        if self
            .document
            .as_ref()
            .is_some_and(|d| d.landmarks.missing().next().is_none())
        {
            self.start_build();
        }
    }

    pub(super) fn model_panel(&mut self, ui: &mut egui::Ui) {
        let Some(document) = &self.document else {
            ui.label("No scan open.");
            return;
        };
        let missing = document.landmarks.missing().count();
        let idle = self.build.is_none();
        ui.add_enabled(
            idle,
            egui::Slider::new(&mut self.settings.elements, ELEMENTS_RANGE)
                .logarithmic(true)
                .text("Elements"),
        )
        .on_hover_text("tetrahedra of the finest level: more is finer and slower");
        ui.add_enabled(
            idle,
            egui::Slider::new(&mut self.settings.tissue.young_kpa, 0.5..=20.0)
                .logarithmic(true)
                .text("Young's modulus (kPa)"),
        );
        ui.add_enabled(
            idle,
            egui::Slider::new(&mut self.settings.tissue.poisson_ratio, 0.3..=0.49)
                .text("Poisson ratio"),
        );
        if let Some(build) = &self.build {
            let progress = build.progress();
            let stage = BUILD_STAGES
                .iter()
                .position(|s| *s == progress.stage)
                .unwrap_or(0);
            let within = progress.step as f32 / progress.steps.max(1) as f32;
            let fraction = (stage as f32 + within.min(1.0)) / BUILD_STAGES.len() as f32;
            ui.add(egui::ProgressBar::new(fraction).text(format!(
                "{} {:.0} s",
                progress.stage,
                progress.elapsed.as_secs_f64()
            )));
            let label = if progress.cancelling {
                "Cancelling…"
            } else {
                "Cancel"
            };
            if ui
                .add_enabled(!progress.cancelling, egui::Button::new(label))
                .clicked()
            {
                build.cancel();
            }
        } else {
            let label = if self.model.is_some() {
                "Rebuild model"
            } else {
                "Build model"
            };
            if ui
                .add_enabled(missing == 0, egui::Button::new(label))
                .on_hover_text("cut curves, breast volumes, tetrahedra and the simulation set-up")
                .clicked()
            {
                self.start_build();
            }
            if missing > 0 {
                ui.weak(format!(
                    "Place the {missing} missing landmarks to build the model."
                ));
            }
        }
        let Some(model) = &self.model else {
            return;
        };
        if model.stale {
            ui.colored_label(
                RUNNING_COLOR,
                "The landmarks changed since the model was built: rebuild it.",
            );
        }
        volume_table(ui, model);
        ui.checkbox(&mut self.show_curves, "Show cut curves");
        if let Some(points) = &self.settings.control_points {
            ui.label(format!(
                "Control points: {} left, {} right (squares on the cut curves: drag them along \
                 the surface)",
                points.left.len(),
                points.right.len()
            ));
        }
        ui.horizontal(|ui| {
            for (tool, label, hint) in [
                (
                    ControlPointTool::Insert,
                    "Insert point",
                    "then click on the surface near a cut curve",
                ),
                (
                    ControlPointTool::Remove,
                    "Remove point",
                    "then click on a control point (three stay at least)",
                ),
            ] {
                let active = self.control_point_tool == Some(tool);
                if ui
                    .add_enabled(
                        self.settings.control_points.is_some(),
                        egui::Button::selectable(active, label),
                    )
                    .on_hover_text(hint)
                    .clicked()
                {
                    self.control_point_tool = (!active).then_some(tool);
                }
            }
            if ui
                .button("Default points")
                .on_hover_text("the control points derived from the landmarks, at the next build")
                .clicked()
            {
                self.settings.control_points = None;
                self.control_points_edited = true;
                self.control_point_tool = None;
            }
        });
        if self.control_points_edited {
            ui.colored_label(
                RUNNING_COLOR,
                "The control points changed since the model was built: rebuild it to cut along \
                 them.",
            );
        }
        ui.weak(format!(
            "{} tetrahedra in {} levels, built in {:.1} s",
            model.elements,
            model.levels,
            model.build_time.as_secs_f64()
        ));
    }

    pub(super) fn simulation_panel(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            for mode in DisplayMode::ALL {
                ui.radio_value(&mut self.display, mode, mode.label());
            }
        });
        let Some(live) = &self.live else {
            ui.weak("No model built yet.");
            return;
        };
        if self.display == DisplayMode::Deviation {
            deviation_summary(ui, live);
        }
        if let Some(failure) = &live.failure {
            ui.colored_label(ERROR_COLOR, failure);
        }
        match &live.solver {
            None => {
                ui.weak("Waiting for the first cycle…");
            }
            Some(solver) => {
                let (color, state) = solver_summary(solver);
                ui.colored_label(color, state);
                ui.weak(format!(
                    "{} cycles since the last change ({} in the {} stage), relative residual \
                     {:.1e}, last cycle {:.0} ms + {:.0} ms to the scan",
                    solver.cycles,
                    solver.advance.stage_cycles,
                    stage_name(solver.stage()),
                    solver.advance.cycle.relative_residual,
                    solver.advance.cycle.time_ms,
                    solver.frame_ms
                ));
            }
        }
    }

    pub(super) fn measurement_panel(&mut self, ui: &mut egui::Ui) {
        let postoperative =
            self.postoperative
                .registered
                .as_ref()
                .map(|registered| PostoperativeScan {
                    scan: registered.scan_path.clone(),
                    landmarks: registered.landmarks_path.clone(),
                    up: None,
                    units: None,
                });
        let Some(live) = &mut self.live else {
            ui.weak("Build the model and choose implants to measure the prediction.");
            return;
        };
        let frame = live.frame.as_ref().map_or(0, |f| f.number);
        ui.horizontal(|ui| {
            let measuring = live.measurements == MeasurementState::Measuring;
            if ui
                .add_enabled(
                    !measuring && frame > 0,
                    egui::Button::new("Measure prediction"),
                )
                .on_hover_text(
                    "distances on the simulated scan and breast volumes (a second or two)",
                )
                .clicked()
            {
                live.measure();
            }
            if measuring {
                ui.spinner();
            }
        });
        match &live.measurements {
            MeasurementState::NotYet | MeasurementState::Measuring => {}
            MeasurementState::Failed(message) => {
                ui.colored_label(ERROR_COLOR, message);
            }
            MeasurementState::Measured(measured, at) => {
                if *at != frame {
                    ui.weak("measured before the latest change");
                }
                measurement_table(ui, measured);
            }
        }
        ui.horizontal(|ui| {
            let label = ui.label("Folder");
            ui.add(
                egui::TextEdit::singleline(&mut self.export_folder)
                    .hint_text("where to export and write the report")
                    .desired_width(220.0),
            )
            .labelled_by(label.id);
            if ui
                .add_enabled(frame > 0, egui::Button::new("Export"))
                .on_hover_text(
                    "simulated_scan.ply, measurements.csv and measurements.json into the folder",
                )
                .clicked()
            {
                let folder = PathBuf::from(self.export_folder.trim());
                match std::fs::create_dir_all(&folder) {
                    Ok(()) => live.export(ExportPaths::in_folder(&folder)),
                    Err(error) => {
                        live.exported =
                            Some(Err(format!("creating {}: {error}", folder.display())));
                    }
                }
            }
        });
        match &live.exported {
            Some(Ok(paths)) => {
                ui.colored_label(
                    PLACED_COLOR,
                    format!(
                        "exported to {}",
                        paths.scan.parent().unwrap_or(Path::new("")).display()
                    ),
                );
            }
            Some(Err(message)) => {
                ui.colored_label(ERROR_COLOR, message);
            }
            None => {}
        }
        ui.horizontal(|ui| {
            let writing = live.is_writing_report();
            if ui
                .add_enabled(frame > 0 && !writing, egui::Button::new("Write report"))
                .on_hover_text(
                    "report.html into the folder (as mammaplan report), with the scan, model and \
                     simulation folders it is made from; compared with the post-operative scan \
                     when one is registered",
                )
                .clicked()
            {
                live.write_report(PathBuf::from(self.export_folder.trim()), postoperative);
            }
            if writing {
                ui.spinner();
                ui.weak(match &live.report {
                    ReportState::WritingFolders(_) => "writing the model and simulation…",
                    _ => "writing the report (views, measurements)…",
                });
            }
        });
        match &live.report {
            ReportState::Written(Ok(summary)) => {
                ui.colored_label(
                    PLACED_COLOR,
                    format!(
                        "Report written: {} ({} views)",
                        summary.out.display(),
                        summary.views
                    ),
                );
            }
            ReportState::Written(Err(message)) => {
                ui.colored_label(ERROR_COLOR, format!("The report failed: {message}"));
            }
            _ => {}
        }
    }
}

/// What the deviation view shows: the figures of the settled prediction's deviation from
/// the scan as loaded, or why there are none yet.
fn deviation_summary(ui: &mut egui::Ui, live: &LiveSimulation) {
    let latest = live.frame.as_ref().map(|f| f.number);
    match &live.settled {
        Some(settled) => match &settled.deviation {
            Ok(map) => {
                ui.label(format!(
                    "Deviation from the pre-operative surface: RMS {:.2} mm, mean {:.2} mm, \
                     largest {:.1} mm over {:.0}% of the vertices",
                    map.statistics.rms_mm,
                    map.statistics.mean_mm,
                    map.statistics.max_test_to_reference_mm,
                    100.0 * map.overlap_fraction
                ));
            }
            Err(message) => {
                ui.colored_label(ERROR_COLOR, message);
            }
        },
        None => {
            ui.weak("The deviation map follows once the simulation has settled.");
        }
    }
    if live.is_preparing_settled() {
        ui.horizontal(|ui| {
            ui.spinner();
            ui.weak("computing the deviation map…");
        });
    } else if live.settled.as_ref().map(|s| s.frame) != latest && latest.is_some() {
        ui.weak("updated once the simulation has settled");
    }
}

/// The indicator's colour and words for the solver's state.
fn solver_summary(solver: &SolverStatus) -> (Color32, String) {
    match solver.advance.state {
        SolveState::Running => (
            RUNNING_COLOR,
            format!("Solving ({} stage)…", stage_name(solver.stage())),
        ),
        SolveState::Converged => (PLACED_COLOR, "Converged".to_string()),
        SolveState::Stopped => (
            ERROR_COLOR,
            "Stopped at the cycle limit: the prediction is approximate".to_string(),
        ),
    }
}

/// The model's breast and quadrant volumes.
fn volume_table(ui: &mut egui::Ui, model: &ModelFigures) {
    egui::Grid::new("breast volumes")
        .striped(true)
        .show(ui, |ui| {
            ui.strong("Volume (ml)");
            ui.strong("left");
            ui.strong("right");
            ui.end_row();
            ui.label("breast");
            for side in Side::BOTH {
                ui.label(format!("{:.1}", model.breast_volume_ml.get(side)));
            }
            ui.end_row();
            type Quadrant = fn(&QuadrantVolumes) -> f64;
            let quadrants: [(&str, Quadrant); 4] = [
                ("upper outer", |q| q.upper_outer),
                ("upper inner", |q| q.upper_inner),
                ("lower inner", |q| q.lower_inner),
                ("lower outer", |q| q.lower_outer),
            ];
            for (name, value) in quadrants {
                ui.label(name);
                for side in Side::BOTH {
                    ui.label(format!("{:.1}", value(model.quadrant_volume_ml.get(side))));
                }
                ui.end_row();
            }
        });
}

/// The clinical distances, breast, half and implant volumes before and as simulated.
fn measurement_table(ui: &mut egui::Ui, measured: &SimulatedMeasurements) {
    egui::Grid::new("measurements")
        .striped(true)
        .show(ui, |ui| {
            ui.strong("surface (mm)");
            ui.strong("before");
            ui.strong("simulated");
            ui.strong("change");
            ui.end_row();
            for change in &measured.distances {
                let before = change.before.surface_mm;
                let after = change.simulated.surface_mm;
                ui.label(change.name.as_str());
                ui.label(super::format_optional(before));
                ui.label(super::format_optional(after));
                ui.label(super::format_optional(
                    before.zip(after).map(|(b, a)| a - b),
                ));
                ui.end_row();
            }
            for side in Side::BOTH {
                let before = *measured.breast_volume_before_ml.get(side);
                let after = *measured.breast_volume_ml.get(side);
                ui.label(format!("{side} breast (ml)"));
                ui.label(format!("{before:.1}"));
                ui.label(format!("{after:.1}"));
                ui.label(format!("{:+.1}", after - before));
                ui.end_row();
            }
            // The breast's halves above and below the lines from the
            // nipple to the fold's ends: the upper pole's fullness.
            type Half = fn(&QuadrantVolumes) -> f64;
            let halves: [(&str, Half); 2] = [
                ("upper half", |q| q.upper_outer + q.upper_inner),
                ("lower half", |q| q.lower_outer + q.lower_inner),
            ];
            for side in Side::BOTH {
                for (name, half) in halves {
                    let before = half(measured.quadrant_volume_before_ml.get(side));
                    let after = measured.quadrant_volume_ml.get(side).as_ref().map(half);
                    ui.label(format!("{side} {name} (ml)"));
                    ui.label(format!("{before:.1}"));
                    ui.label(super::format_optional(after));
                    ui.label(after.map_or("–".into(), |a| format!("{:+.1}", a - before)));
                    ui.end_row();
                }
            }
            for side in Side::BOTH {
                ui.label(format!("{side} implant (ml)"));
                ui.label("");
                ui.label(format!("{:.1}", measured.implant_volume_ml.get(side)));
                ui.end_row();
            }
        });
}

fn stage_name(stage: Stage) -> &'static str {
    match stage {
        Stage::Implant => "implant",
        Stage::Gravity => "gravity",
    }
}

/// The built model's pectoralis major (both sides, at rest) as the viewport draws it, in
/// the report's muscle tone; `None` where the model has none.
fn muscle_scene(session: &plan::simulate::Session) -> Option<Arc<SceneMesh>> {
    let simulation = &session.simulation;
    let mut surface = simulation.muscle().surface(simulation.finest_mesh())?;
    surface.vertex_colors = Some(vec![plan::views::MUSCLE_TONE; surface.positions.len()]);
    Some(Arc::new(SceneMesh::new(&surface)))
}
