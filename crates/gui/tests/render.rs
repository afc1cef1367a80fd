//! The viewport drawn for real with wgpu (Mesa's software renderer in CI): the lit scan
//! fills the middle of the viewport and the background shows around it.
//!
//! Without any wgpu adapter (no GPU driver and no Mesa) the test says so and passes,
//! unless `MAMMAPLAN_REQUIRE_GPU` is set, as `.ci/run` does.

use eframe::egui;
use egui_kittest::Harness;
use egui_kittest::wgpu::{WgpuTestRenderer, create_render_state, default_wgpu_setup};
use gui::{Document, GuiApp};

#[test]
fn the_viewport_draws_the_lit_scan() {
    let Ok(render_state) = std::panic::catch_unwind(|| {
        create_render_state(
            default_wgpu_setup(),
            eframe::egui_wgpu::RendererOptions::PREDICTABLE,
        )
    }) else {
        assert!(
            std::env::var_os("MAMMAPLAN_REQUIRE_GPU").is_none(),
            "no wgpu adapter, and MAMMAPLAN_REQUIRE_GPU is set"
        );
        eprintln!("skipped: no wgpu adapter (install Mesa's EGL/OpenGL or Vulkan drivers)");
        return;
    };
    let app = GuiApp::new(Some(&render_state), Some(Document::phantom(true).unwrap()));
    let mut harness = Harness::builder()
        .with_size(egui::vec2(1200.0, 800.0))
        .renderer(WgpuTestRenderer::from_render_state(render_state))
        .build_ui_state(|ui, app: &mut GuiApp| app.show(ui), app);
    for _ in 0..4 {
        harness.step();
    }
    let image = harness.render().unwrap();
    let rect = harness.state().viewport_rect().unwrap();
    let scale = image.width() as f32 / 1200.0;
    let pixel = |x: f32, y: f32| {
        let p = image.get_pixel((x * scale) as u32, (y * scale) as u32);
        [p[0], p[1], p[2]]
    };
    let background = gui::render::background();
    let background = [background.r(), background.g(), background.b()];
    // A corner of the viewport is background; the upper abdomen, a little below the
    // middle and clear of the landmark markers and labels around the xiphoid, is lit
    // skin: reddish, brighter than the background.
    let corner = pixel(rect.min.x + 3.0, rect.min.y + 3.0);
    assert_eq!(corner, background);
    let centre = pixel(rect.center().x, rect.center().y + 0.1 * rect.height());
    assert!(
        centre[0] > 120 && centre[0] > centre[2] && centre != background,
        "centre pixel {centre:?}"
    );
    // Save the frame for people to look at (not compared: software renderers differ).
    let out = std::env::temp_dir().join("mammaplan-gui-render-test.png");
    image.save(&out).unwrap();
}
