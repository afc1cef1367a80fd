//! The desktop planning application (`mammaplan gui`): a window with a lit 3D view of a
//! scan, landmark placement by clicking on the surface, and the clinical distances
//! updated live. A thin layer over `plan`, `anatomy` and `mesh`: geometry queries and
//! file formats live there; this crate holds presentation, input and the camera.
//!
//! Built on eframe/egui with the wgpu backend; the scan is drawn through an
//! `egui_wgpu` paint callback ([`render`]), picking is a CPU ray cast on the scan's BVH.

pub mod app;
pub mod camera;
pub mod document;
mod hints;
pub mod live_distances;
pub mod render;

pub use app::GuiApp;
pub use document::Document;

use eframe::egui;

/// Opens the window and runs until it is closed; `document` is shown first if given.
pub fn run(document: Option<Document>) -> anyhow::Result<()> {
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
            Ok(Box::new(GuiApp::new(
                cc.wgpu_render_state.as_ref(),
                document,
            )))
        }),
    )
    .map_err(|error| anyhow::anyhow!("cannot open the window: {error}"))
}
