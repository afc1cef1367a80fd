//! The desktop planning application (`mammaplan gui`): a window with a lit 3D view of a
//! scan, landmark placement by clicking on the surface, the clinical distances updated
//! live, the breast model built on a worker thread, implants chosen and moved with the
//! simulation running live on another, measurements, exports and planning cases. A
//! thin layer over `plan`, `anatomy` and `mesh`: geometry queries, simulation and file
//! formats live there; this crate holds presentation, input, the camera and the
//! workers that keep the window responsive.
//!
//! Built on eframe/egui with the wgpu backend; the scan is drawn through an
//! `egui_wgpu` paint callback ([`render`]), picking is a CPU ray cast on the scan's BVH.

pub mod app;
pub mod camera;
pub mod carried;
pub mod control_points;
pub mod deviation;
mod display_mode;
pub mod document;
mod hints;
pub mod implant_plan;
pub mod job;
pub mod live_distances;
pub mod live_simulation;
pub mod model_build;
pub mod registration;
pub mod render;
pub mod script;

pub use app::GuiApp;
pub use document::Document;

use eframe::egui;

/// What the window shows first.
pub enum Start {
    Empty,
    Document(Box<Document>),
    /// A planning case file.
    Case(std::path::PathBuf),
}

/// Opens the window and runs until it is closed; `script`, if given, is run in it.
pub fn run(start: Start, script: Option<script::Script>) -> anyhow::Result<()> {
    let options = eframe::NativeOptions {
        renderer: eframe::Renderer::Wgpu,
        viewport: egui::ViewportBuilder::default()
            .with_title("mammaplan")
            .with_inner_size([1400.0, 860.0])
            .with_drag_and_drop(true),
        // The viewport keeps its own depth buffer and multisampling (see `render`), so
        // egui's pass stays without depth and single-sampled, as `render` expects.
        depth_buffer: 0,
        multisampling: 0,
        ..eframe::NativeOptions::default()
    };
    eframe::run_native(
        "mammaplan",
        options,
        Box::new(move |cc| {
            let render_state = cc.wgpu_render_state.as_ref();
            let mut app = match start {
                Start::Empty => GuiApp::new(render_state, None),
                Start::Document(document) => GuiApp::new(render_state, Some(*document)),
                Start::Case(path) => {
                    let mut app = GuiApp::new(render_state, None);
                    app.open(&path);
                    app
                }
            };
            if let Some(script) = script {
                app.run_script(script);
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|error| anyhow::anyhow!("cannot open the window: {error}"))
}
