//! The window: menu and path bar, landmark list and breast model on the left, 3D
//! viewport, implants, simulation and measurements on the right, status line.
//! Everything here is presentation and input; the work is done by [`Document`],
//! [`Camera`], [`LiveDistances`], [`ModelBuild`], [`LiveSimulation`] and the
//! `plan`/`mesh`/`anatomy` functions behind them.

mod dialogs;
mod implant_panel;
mod planning;
mod postoperative;
mod scripted;
mod standing_frame;
mod viewport;

use crate::camera::{Camera, StandardView};
use crate::document::{Document, Placing};
use crate::hints::hint;
use crate::implant_plan::{ImplantPlan, MoveDirection};
use crate::live_distances::{LiveDistances, Table};
use crate::live_simulation::LiveSimulation;
use crate::model_build::ModelBuild;
use crate::render::{self, SceneMesh};
use anatomy::LandmarkName;
use anatomy::measure::clinical_distances;
use eframe::egui::{self, Color32, Key, Rect};
use eframe::egui_wgpu;
use glam::{DMat3, DVec3};
use plan::Place;
use plan::case::PlanningCase;
use plan::catalog::Catalog;
use std::path::{Path, PathBuf};
use std::sync::Arc;

pub use crate::display_mode::DisplayMode;
pub use dialogs::FileChoice;
pub use planning::{ModelFigures, ModelSettings};
pub use postoperative::{DeviationReference, PostOperative};
use viewport::Drag;
pub use viewport::{ControlPointTool, Overlay};

/// Markers closer than this to the pointer are grabbed by a drag (points).
const GRAB_RADIUS: f32 = 10.0;
/// Marker radius (points).
const MARKER_RADIUS: f32 = 5.0;
/// Zoom per point of scroll.
const ZOOM_PER_SCROLL: f64 = 0.002;
/// A landmark counts as visible if nothing is in front of it by more than this (mm).
const OCCLUSION_TOLERANCE_MM: f64 = 0.5;
const ERROR_COLOR: Color32 = Color32::from_rgb(235, 90, 80);
/// A result that stands, with a caveat.
const WARNING_COLOR: Color32 = Color32::from_rgb(240, 170, 60);
const PLACED_COLOR: Color32 = Color32::from_rgb(60, 200, 120);
const SELECTED_COLOR: Color32 = Color32::from_rgb(255, 200, 40);
const EXTRA_COLOR: Color32 = Color32::from_rgb(90, 170, 255);
const CURVE_COLOR: Color32 = Color32::from_rgb(255, 120, 200);
/// Width of the cut curves on screen (points).
const CURVE_WIDTH: f32 = 2.0;

/// A message in the status line.
enum Status {
    Info(String),
    Error(String),
}

/// The planning application.
pub struct GuiApp {
    document: Option<Document>,
    scene: Option<Arc<SceneMesh>>,
    distances: Option<LiveDistances>,
    camera: Camera,
    /// Whether the wgpu pipelines are installed (false in tests without a GPU: everything
    /// but the shaded surface still works).
    gpu: bool,
    /// Whether the scene is drawn on the processor (a software renderer): the solver
    /// then keeps to the window's pace (see [`LiveSimulation::start`]).
    software_renderer: bool,
    path_text: String,
    extra_name: String,
    status: Status,
    drag: Option<Drag>,
    viewport_rect: Option<Rect>,
    /// Model building and simulation settings (saved in planning cases).
    settings: ModelSettings,
    catalog: Catalog,
    build: Option<ModelBuild>,
    model: Option<ModelFigures>,
    /// Where the last build's failure lies on the scan, if its error names a place.
    failure_place: Option<Place>,
    live: Option<LiveSimulation>,
    implants: ImplantPlan,
    /// Why the implants cannot be simulated as edited (bad custom dimensions).
    implant_error: Option<String>,
    display: DisplayMode,
    show_curves: bool,
    /// Whether the implants' footprint outlines are drawn on the scan.
    show_outlines: bool,
    /// The pectoralis major of the built model (both sides, at rest), and whether it is
    /// drawn under the shown surface, which then becomes a veil.
    muscle: Option<Arc<SceneMesh>>,
    show_muscle: bool,
    export_folder: String,
    /// The window's context once it has drawn a frame (workers wake the window with it).
    ctx: Option<egui::Context>,
    script: Option<scripted::ScriptRun>,
    /// A post-operative scan registered onto this one.
    postoperative: PostOperative,
    /// The control points changed since the model was built from them.
    control_points_edited: bool,
    /// What a click does to the control points, if anything.
    control_point_tool: Option<ControlPointTool>,
    /// The desktop's file dialog, while it is open.
    dialog: Option<dialogs::OpenDialog>,
}

impl GuiApp {
    /// The application, optionally with a document to show. With `render_state` (eframe's
    /// wgpu state) the viewport draws the scan; without, it draws markers only.
    pub fn new(
        render_state: Option<&egui_wgpu::RenderState>,
        document: Option<Document>,
    ) -> GuiApp {
        let software_renderer = render_state.is_some_and(render::install);
        let mut app = GuiApp {
            document: None,
            scene: None,
            distances: None,
            camera: Camera::framing(DMat3::IDENTITY, DVec3::ZERO, 100.0),
            gpu: render_state.is_some(),
            software_renderer,
            path_text: String::new(),
            extra_name: String::new(),
            status: Status::Info(
                "Open a scan (path above, or drop a file on the window) or the phantom (File menu)."
                    .into(),
            ),
            drag: None,
            viewport_rect: None,
            settings: ModelSettings::default(),
            catalog: Catalog::builtin(),
            build: None,
            model: None,
            failure_place: None,
            live: None,
            implants: ImplantPlan::default(),
            implant_error: None,
            display: DisplayMode::PreOperative,
            show_curves: true,
            show_outlines: false,
            muscle: None,
            show_muscle: false,
            export_folder: String::new(),
            ctx: None,
            script: None,
            postoperative: PostOperative::default(),
            control_points_edited: false,
            control_point_tool: None,
            dialog: None,
        };
        if let Some(document) = document {
            app.set_document(document);
        }
        app
    }

    /// The viewport's camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// The open scan and its landmarks.
    pub fn document(&self) -> Option<&Document> {
        self.document.as_ref()
    }

    /// Where the viewport was drawn last frame (egui points).
    pub fn viewport_rect(&self) -> Option<Rect> {
        self.viewport_rect
    }

    /// The error in the status line, if the last action failed.
    pub fn error(&self) -> Option<&str> {
        match &self.status {
            Status::Error(message) => Some(message),
            Status::Info(_) => None,
        }
    }

    /// Draws the whole window into `ui` and handles its input. The panels have no fill
    /// of their own: the window is expected to be cleared to the style's `panel_fill`
    /// (as [`eframe::App::clear_color`] does here).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        self.take_dropped_files(ui);
        self.view_keys(ui);
        self.move_keys(ui);
        self.poll_build(ui.ctx());
        self.advance_script(ui.ctx());
        self.update_simulation();
        self.update_postoperative();
        self.poll_dialog();
        if let (Some(document), None) = (&self.document, &self.distances) {
            let ctx = ui.ctx().clone();
            let mut distances =
                LiveDistances::start(Arc::clone(&document.scan), document.up, move || {
                    ctx.request_repaint()
                });
            distances.update(&document.landmarks);
            self.distances = Some(distances);
        }
        let panel_frame = panel_frame(ui.style());
        egui::Panel::top("toolbar")
            .frame(panel_frame)
            .show(ui, |ui| self.toolbar(ui));
        egui::Panel::bottom("status")
            .frame(panel_frame)
            .show(ui, |ui| match &self.status {
                Status::Info(message) => {
                    ui.label(message.as_str());
                }
                Status::Error(message) => {
                    ui.colored_label(ERROR_COLOR, message.as_str());
                }
            });
        egui::Panel::left("landmarks")
            .frame(panel_frame)
            .default_size(300.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    section(ui, "Landmarks", |ui| self.landmark_panel(ui));
                    section(ui, "Standing frame", |ui| self.up_panel(ui));
                    section(ui, "Breast model", |ui| self.model_panel(ui));
                    section(ui, "Post-operative scan", |ui| self.postoperative_panel(ui));
                });
            });
        egui::Panel::right("planning")
            .frame(panel_frame)
            .default_size(400.0)
            .show(ui, |ui| {
                egui::ScrollArea::vertical().show(ui, |ui| {
                    section(ui, "Implants", |ui| self.implant_panel(ui));
                    section(ui, "Simulation", |ui| self.simulation_panel(ui));
                    section(ui, "Distances (mm)", |ui| self.distance_panel(ui));
                    section(ui, "Measurements", |ui| self.measurement_panel(ui));
                });
            });
        egui::CentralPanel::no_frame().show(ui, |ui| self.viewport(ui));
        // While a running solve's previews are drawn, the panels' shapes go without
        // egui's anti-aliasing feather, whose thin triangles a software renderer pays
        // for (docs/user/gui.md). Read when the frame is tessellated, after this.
        let feathering = !self.draws_preview();
        if ui.ctx().tessellation_options(|o| o.feathering) != feathering {
            ui.ctx()
                .tessellation_options_mut(|o| o.feathering = feathering);
        }
    }

    fn info(&mut self, message: impl Into<String>) {
        self.status = Status::Info(message.into());
    }

    fn error_status(&mut self, error: &anyhow::Error) {
        self.status = Status::Error(plan::one_line(error));
    }

    /// Shows a new scan: frames it from the front, restarts the distance worker and
    /// drops the model and simulation of the previous one.
    fn set_document(&mut self, document: Document) {
        self.cancel_build();
        self.model = None;
        self.muscle = None;
        self.failure_place = None;
        self.live = None;
        self.settings.control_points = None;
        self.control_points_edited = false;
        self.control_point_tool = None;
        self.display = DisplayMode::PreOperative;
        self.postoperative.reset();
        self.scene = Some(Arc::new(SceneMesh::of_scan(&document.scan)));
        self.info(format!(
            "{}: {} vertices, {} triangles",
            document.scan.path.display(),
            document.scan.mesh.vertex_count(),
            document.scan.mesh.triangle_count()
        ));
        self.document = Some(document);
        self.distances = None;
        self.drag = None;
        self.set_view(StandardView::Front);
    }

    /// Frames the scan and looks from a standard direction of the anatomical frame (the
    /// file's axes until Pj, Px, Pcl and Pcr are placed).
    fn set_view(&mut self, view: StandardView) {
        let Some(document) = &self.document else {
            return;
        };
        let body = match document.landmarks.frame(document.up) {
            Some(Ok(frame)) => frame.axes,
            _ => DMat3::IDENTITY,
        };
        let (low, high) = document.scan.mesh.bounding_box();
        self.camera = Camera::framing(body, 0.5 * (low + high), 0.5 * low.distance(high));
        self.camera.set_view(view, body);
    }

    /// Tells the distance worker that the landmarks changed; a model built before no
    /// longer matches them (nor do its control points).
    fn landmarks_changed(&mut self) {
        // The ring marked where the old landmarks failed.
        self.failure_place = None;
        if let (Some(document), Some(distances)) = (&self.document, &mut self.distances) {
            distances.update(&document.landmarks);
        }
        self.settings.control_points = None;
        self.control_points_edited = false;
        self.control_point_tool = None;
        if let Some(model) = &mut self.model {
            model.stale = true;
        }
    }

    /// Opens a planning case, a scan, or a landmark file (`.json`) for the open scan, as
    /// the path field's Open button does.
    pub fn open(&mut self, path: &Path) {
        if PlanningCase::is_case_file(path) {
            self.open_case(path);
        } else if Document::is_landmark_file(path) {
            let Some(document) = &mut self.document else {
                self.status = Status::Error(format!(
                    "{}: open a scan before its landmarks",
                    path.display()
                ));
                return;
            };
            match document.open_landmarks(path) {
                Ok(warnings) => {
                    let placed = document.landmarks.iter().count();
                    let mut message = format!("{}: {placed} points", path.display());
                    for warning in warnings {
                        message.push_str("; ");
                        message.push_str(&warning);
                    }
                    self.info(message);
                    self.landmarks_changed();
                }
                Err(error) => self.error_status(&error),
            }
        } else {
            match Document::open_scan(path, None) {
                Ok(document) => self.set_document(document),
                Err(error) => self.error_status(&error),
            }
        }
    }

    fn open_phantom(&mut self, with_landmarks: bool) {
        match Document::phantom(with_landmarks) {
            Ok(document) => self.set_document(document),
            Err(error) => self.error_status(&error),
        }
    }

    fn save_landmarks(&mut self) {
        let Some(document) = &mut self.document else {
            return;
        };
        let typed = PathBuf::from(self.path_text.trim());
        let path = if Document::is_landmark_file(&typed) {
            typed
        } else if let Some(path) = &document.landmarks_path {
            path.clone()
        } else {
            self.status = Status::Error(
                "type where to save the landmarks (a path ending in .json) in the path field"
                    .into(),
            );
            return;
        };
        match document.save_landmarks(&path) {
            Ok(()) => {
                let missing = document.landmarks.missing().count();
                let note = if missing > 0 {
                    format!(" ({missing} required landmarks not placed yet)")
                } else {
                    String::new()
                };
                self.info(format!("saved {}{note}", path.display()));
            }
            Err(error) => self.error_status(&error),
        }
    }

    /// Files dropped on the window: scans first, then landmark files.
    fn take_dropped_files(&mut self, ui: &egui::Ui) {
        let mut paths: Vec<PathBuf> = ui.input(|i| {
            i.raw
                .dropped_files
                .iter()
                .map(|f| f.path().to_path_buf())
                .collect()
        });
        paths.sort_by_key(|p| Document::is_landmark_file(p));
        for path in paths {
            self.open(&path);
        }
    }

    /// Keys 1 to 5 choose the standard views (in the toolbar's order) when no text field
    /// has the keyboard.
    fn view_keys(&mut self, ui: &egui::Ui) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        for view in StandardView::ALL {
            if ui.input(|i| i.key_pressed(view_key(view))) {
                self.set_view(view);
            }
        }
    }

    /// The arrow keys move the edited implant as the move buttons do, in the directions
    /// they point on the screen in the front view (the patient's left is screen right);
    /// Page Up and Page Down move it to the front and back.
    fn move_keys(&mut self, ui: &egui::Ui) {
        if ui.ctx().egui_wants_keyboard_input() || self.live.is_none() {
            return;
        }
        for direction in MoveDirection::ALL {
            if ui.input(|i| i.key_pressed(move_key(direction))) {
                self.implants.step(direction);
            }
        }
    }

    fn toolbar(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Phantom (place the landmarks)").clicked() {
                    self.open_phantom(false);
                }
                if ui.button("Phantom with its landmarks").clicked() {
                    self.open_phantom(true);
                }
            });
        });
        ui.horizontal(|ui| {
            ui.label("Path:");
            ui.add(
                egui::TextEdit::singleline(&mut self.path_text)
                    .hint_text("scan.ply / .obj / .stl, or landmarks.json")
                    .desired_width(360.0),
            );
            if ui.button("Open").clicked() {
                let path = PathBuf::from(self.path_text.trim());
                self.open(&path);
            }
            let asking = self.dialog.is_some();
            if ui
                .add_enabled(!asking, egui::Button::new("Browse…"))
                .on_hover_text("choose the file to open in the desktop's file dialog")
                .clicked()
            {
                self.ask_for_file(FileChoice::Open);
            }
            let has_document = self.document.is_some();
            if ui
                .add_enabled(has_document, egui::Button::new("Save landmarks"))
                .clicked()
            {
                self.save_landmarks();
            }
            if ui
                .add_enabled(has_document, egui::Button::new("Save case"))
                .on_hover_text("the scan, landmarks, model settings and implants, as JSON")
                .clicked()
            {
                self.save_case();
            }
            if ui
                .add_enabled(has_document && !asking, egui::Button::new("Save case as…"))
                .on_hover_text("choose where in the desktop's file dialog")
                .clicked()
            {
                self.ask_for_file(FileChoice::SaveCase);
            }
            ui.separator();
            for view in StandardView::ALL {
                let button = ui
                    .add_enabled(has_document, egui::Button::new(view.label()))
                    .on_hover_text(format!("key {}", view_key(view).name()));
                if button.clicked() {
                    self.set_view(view);
                }
            }
        });
    }

    fn landmark_panel(&mut self, ui: &mut egui::Ui) {
        let Some(document) = &mut self.document else {
            ui.label("No scan open.");
            return;
        };
        let mut changed = false;
        egui::Frame::group(ui.style()).show(ui, |ui| match document.placing() {
            Some(Placing::Next(name)) => {
                ui.strong(format!("Click on the surface to place {}", name.as_str()));
                ui.label(hint(name));
            }
            Some(Placing::Selected(name)) => {
                let verb = if document.landmarks.lookup(&name).is_some() {
                    "move"
                } else {
                    "place"
                };
                ui.strong(format!("Click on the surface to {verb} {name}"));
                if let Some(required) = LandmarkName::parse(&name) {
                    ui.label(hint(required));
                }
                if ui.button("Cancel").clicked() {
                    document.toggle_selection(&name);
                }
            }
            Some(Placing::Extra(name)) => {
                ui.strong(format!(
                    "Click on the surface to place the extra point {name}"
                ));
                if ui.button("Cancel").clicked() {
                    document.pending_extra = None;
                }
            }
            None => {
                ui.label(
                    "All required landmarks are placed. Select one to move it, or drag its marker.",
                );
            }
        });
        ui.add_space(4.0);
        egui::Grid::new("landmark list")
            .striped(true)
            .show(ui, |ui| {
                for name in LandmarkName::ALL {
                    let selected = document.selected.as_deref() == Some(name.as_str());
                    let placed = document.landmarks.get(name);
                    let clicked = ui
                        .selectable_label(selected, name.as_str())
                        .on_hover_text(hint(name))
                        .clicked();
                    if clicked {
                        document.toggle_selection(name.as_str());
                    }
                    match placed {
                        Some(p) => ui.colored_label(PLACED_COLOR, format_point(p)),
                        None => ui.weak("not placed"),
                    };
                    ui.end_row();
                }
            });
        ui.add_space(8.0);
        ui.strong("Extra points");
        let mut remove = None;
        let extras: Vec<(String, DVec3)> = document
            .landmarks
            .extra
            .iter()
            .map(|(k, v)| (k.clone(), *v))
            .collect();
        egui::Grid::new("extra list").striped(true).show(ui, |ui| {
            for (name, p) in &extras {
                let selected = document.selected.as_deref() == Some(name.as_str());
                if ui.selectable_label(selected, name.as_str()).clicked() {
                    document.toggle_selection(name);
                }
                ui.colored_label(EXTRA_COLOR, format_point(*p));
                if ui.small_button("Remove").clicked() {
                    remove = Some(name.clone());
                }
                ui.end_row();
            }
        });
        if let Some(name) = remove {
            document.remove_extra(&name);
            changed = true;
        }
        let mut add_error = None;
        ui.horizontal(|ui| {
            ui.add(
                egui::TextEdit::singleline(&mut self.extra_name)
                    .hint_text("name")
                    .desired_width(120.0),
            );
            if ui.button("Add extra point").clicked() {
                match document.add_extra(&self.extra_name) {
                    Ok(()) => self.extra_name.clear(),
                    Err(error) => add_error = Some(error),
                }
            }
        });
        if document.unsaved {
            ui.weak("Unsaved changes: Save landmarks writes them (GUIDE format).");
        }
        if let Some(error) = add_error {
            self.error_status(&error);
        }
        if changed {
            self.landmarks_changed();
        }
    }

    fn distance_panel(&mut self, ui: &mut egui::Ui) {
        let Some(distances) = &mut self.distances else {
            ui.label("No scan open.");
            return;
        };
        let stale = distances.is_stale();
        let measured = match distances.poll() {
            Table::Preparing => {
                ui.label("Preparing the surface (closing scanner holes)…");
                return;
            }
            Table::NeedFrame => {
                ui.label("Place Pj, Px, Pcl and Pcr: they define the coronal plane the surface distances need.");
                return;
            }
            Table::Failed(message) => {
                ui.colored_label(ERROR_COLOR, message.as_str());
                return;
            }
            Table::Measured(measured) => measured,
        };
        ui.weak(if stale { "updating…" } else { "up to date" });
        egui::Grid::new("distance table")
            .striped(true)
            .show(ui, |ui| {
                ui.strong("");
                ui.strong("straight");
                ui.strong("surface");
                ui.strong("geodesic");
                ui.end_row();
                for spec in clinical_distances() {
                    ui.label(spec.name.as_str());
                    match measured.iter().find(|d| d.name == spec.name) {
                        Some(distance) => {
                            ui.label(format!("{:.1}", distance.euclidean_mm));
                            ui.label(format_optional(distance.surface_mm));
                            ui.label(format_optional(distance.geodesic_mm));
                        }
                        None => {
                            for _ in 0..3 {
                                ui.weak("–");
                            }
                        }
                    }
                    ui.end_row();
                }
            });
    }
}

impl eframe::App for GuiApp {
    /// The panels' colour: the panels leave their background to the clear (see
    /// [`panel_frame`]).
    fn clear_color(&self, visuals: &egui::Visuals) -> [f32; 4] {
        visuals.panel_fill.to_normalized_gamma_f32()
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

/// The side and top panels' frame: egui's, without its fill. The window is cleared to
/// the panels' colour instead ([`eframe::App::clear_color`]), so the renderer does not
/// shade the panels' area once more with egui's shader: with Mesa's software renderer
/// that fill cost about a third of a window frame (40 of 125 ms of rasteriser time at
/// 1400 x 860).
fn panel_frame(style: &egui::Style) -> egui::Frame {
    egui::Frame::side_top_panel(style).fill(Color32::TRANSPARENT)
}

/// A panel section under a header that folds it away (open at first).
fn section(ui: &mut egui::Ui, title: &str, add: impl FnOnce(&mut egui::Ui)) {
    egui::CollapsingHeader::new(title)
        .default_open(true)
        .show(ui, add);
}

/// The key of a standard view: 1 to 5 in the toolbar's order.
fn view_key(view: StandardView) -> Key {
    match view {
        StandardView::Front => Key::Num1,
        StandardView::LeftOblique => Key::Num2,
        StandardView::Left => Key::Num3,
        StandardView::RightOblique => Key::Num4,
        StandardView::Right => Key::Num5,
    }
}

/// The key of a move button (see [`GuiApp::move_keys`]).
fn move_key(direction: MoveDirection) -> Key {
    match direction {
        MoveDirection::Left => Key::ArrowRight,
        MoveDirection::Right => Key::ArrowLeft,
        MoveDirection::Up => Key::ArrowUp,
        MoveDirection::Down => Key::ArrowDown,
        MoveDirection::Front => Key::PageUp,
        MoveDirection::Back => Key::PageDown,
    }
}

fn format_point(p: DVec3) -> String {
    format!("{:.1}, {:.1}, {:.1}", p.x, p.y, p.z)
}

fn format_optional(value: Option<f64>) -> String {
    value.map_or("–".into(), |v| format!("{v:.1}"))
}
