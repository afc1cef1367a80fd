//! Helpers shared by the window's tests: where a point of the scan is on screen, and
//! pointer presses and clicks there.

use eframe::egui::{self, Event, Modifiers, PointerButton, Pos2};
use egui_kittest::Harness;
use glam::{DVec2, DVec3};
use gui::GuiApp;

/// A few frames so panels settle and the worker's answers arrive.
pub fn settle(harness: &mut Harness<'_, GuiApp>) {
    for _ in 0..4 {
        harness.step();
    }
}

/// Where `point` is on screen (egui points), through the app's camera and viewport.
pub fn screen_position(app: &GuiApp, point: DVec3) -> (Pos2, DVec2, DVec2) {
    let rect = app.viewport_rect().unwrap();
    let size = DVec2::new(f64::from(rect.width()), f64::from(rect.height()));
    let pixel = app.camera().project(point, size).unwrap();
    let pos = rect.min + egui::vec2(pixel.x as f32, pixel.y as f32);
    // The pixel the event really carries (f32), relative to the viewport.
    let local = DVec2::new(f64::from(pos.x - rect.min.x), f64::from(pos.y - rect.min.y));
    (pos, local, size)
}

/// Moves the pointer to `pos` and presses or releases the primary button there.
fn button(harness: &mut Harness<'_, GuiApp>, pos: Pos2, pressed: bool) {
    harness.event(Event::PointerMoved(pos));
    harness.event(Event::PointerButton {
        pos,
        button: PointerButton::Primary,
        pressed,
        modifiers: Modifiers::default(),
    });
    harness.step();
}

pub fn click_at(harness: &mut Harness<'_, GuiApp>, pos: Pos2) {
    harness.event(Event::PointerMoved(pos));
    harness.step();
    button(harness, pos, true);
    button(harness, pos, false);
    settle(harness);
}

/// Drags with the primary button from `from` to `to` in ten steps.
pub fn drag(harness: &mut Harness<'_, GuiApp>, from: Pos2, to: Pos2) {
    button(harness, from, true);
    for k in 1..=10 {
        let pos = from + (to - from) * (k as f32 / 10.0);
        harness.event(Event::PointerMoved(pos));
        harness.step();
    }
    button(harness, to, false);
    settle(harness);
}
