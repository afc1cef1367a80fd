//! The implant panel: the side edited, the implant from the catalog or of a custom size,
//! its position, rotation and fold, and what the simulation placed.

use super::{ERROR_COLOR, GuiApp, Status, WARNING_COLOR};
use crate::implant_plan::{Editing, ImplantDesign, MoveDirection, Source};
use anatomy::breast::Side;
use eframe::egui;
use glam::DVec3;
use plan::catalog::{Catalog, ShapeKind};

impl GuiApp {
    /// The implant panel: which side is edited, the implant (catalog entry or custom
    /// size), its position, rotation and fold, and what the simulation placed.
    pub(super) fn implant_panel(&mut self, ui: &mut egui::Ui) {
        if self.live.is_none() {
            ui.weak("Build the model to simulate implants; you can choose them already.");
        }
        let mut editing = self.implants.editing;
        ui.horizontal(|ui| {
            ui.selectable_value(&mut editing, Editing::Side(Side::Right), "Right breast");
            ui.selectable_value(&mut editing, Editing::Linked, "Both, mirrored");
            ui.selectable_value(&mut editing, Editing::Side(Side::Left), "Left breast");
        });
        if editing != self.implants.editing {
            self.implants.edit(editing);
        }
        let catalog = &self.catalog;
        let linked = self.implants.linked();
        let design = self.implants.edited();
        ui.checkbox(
            &mut design.enabled,
            if linked {
                "Implants on both sides"
            } else {
                "Implant on this side"
            },
        );
        ui.horizontal(|ui| {
            ui.radio_value(&mut design.source, Source::Catalog, "Catalog");
            let custom = ui.radio_value(&mut design.source, Source::Custom, "Custom size");
            // Custom sizes start from the catalog entry chosen.
            if custom.changed()
                && let Some(entry) = catalog.get(&design.catalog_id)
            {
                design.set_dimensions(entry.shape());
            }
        });
        let suggested = match design.source {
            Source::Catalog => {
                catalog_choice(ui, design, catalog);
                None
            }
            Source::Custom => custom_size(ui, design, catalog),
        };
        match design.shape(catalog) {
            Ok(shape) => {
                ui.label(format!(
                    "Volume {:.1} ml ({:.0} × {:.0} × {:.1} mm)",
                    shape.volume_ml(),
                    shape.width_mm(),
                    shape.height_mm(),
                    shape.projection_mm()
                ));
            }
            Err(error) => {
                ui.colored_label(ERROR_COLOR, error);
            }
        }
        ui.separator();
        self.position_controls(ui);
        if let Some(error) = &self.implant_error {
            ui.colored_label(ERROR_COLOR, error);
        }
        self.placed_implants(ui);
        match suggested {
            Some(Ok(id)) => {
                self.implants.edited().choose(&id, &self.catalog);
                self.info(format!("suggested {id} for these dimensions"));
            }
            Some(Err(error)) => self.status = Status::Error(error),
            None => {}
        }
    }

    /// The edited implant's position: the move buttons, rotation, fold, step, gravity
    /// and the outlines' switch.
    fn position_controls(&mut self, ui: &mut egui::Ui) {
        ui.strong("Position");
        let pressed = move_buttons(ui);
        let design = self.implants.edited();
        ui.add(egui::Slider::new(&mut design.rotation_deg, -45.0..=45.0).text("Rotation (°)"))
            .on_hover_text(
                "about the chest wall's normal, counter-clockwise seen from the front \
                 (anatomic implants; a round one looks the same turned)",
            );
        fold_lowering_control(ui, design);
        let moved = design.move_mm;
        ui.horizontal(|ui| {
            ui.label(format!(
                "Moved {:+.1} left, {:+.1} up, {:+.1} front (mm)",
                moved.x, moved.y, moved.z
            ));
            if ui.small_button("Reset").clicked() {
                design.move_mm = DVec3::ZERO;
                design.rotation_deg = 0.0;
            }
        });
        ui.add(egui::Slider::new(&mut self.implants.step_mm, 1.0..=20.0).text("Step (mm)"));
        if let Some(direction) = pressed {
            self.implants.step(direction);
        }
        ui.checkbox(&mut self.implants.gravity, "Gravity correction")
            .on_hover_text("the implant's weight lets the breast sag (paper V-B)");
        ui.checkbox(&mut self.show_outlines, "Show implant and pocket outlines")
            .on_hover_text(
                "the footprint of each implant (cyan) and, where it lies beyond the native \
                 breast, its pocket within the planned limits (pink), seen through the skin",
            );
        ui.add_enabled(
            self.muscle.is_some(),
            egui::Checkbox::new(&mut self.show_muscle, "Show the pectoralis major"),
        )
        .on_hover_text(
            "the muscle under the skin as the model placed it from the landmarks (at rest), \
             the shown surface drawn as a veil over it",
        );
    }

    /// What the simulation placed on each side (volume, fold lowering, the fit's move),
    /// its warnings and errors.
    fn placed_implants(&self, ui: &mut egui::Ui) {
        let Some(live) = &self.live else {
            return;
        };
        for side in [Side::Right, Side::Left] {
            let state = live.sides.get(side);
            if let Some(placed) = &state.placed {
                let fit_mm = glam::DVec2::from_array(placed.fit_shift_mm).length();
                let fit_note = if fit_mm > 0.05 {
                    format!(", moved {fit_mm:.1} mm further to fit")
                } else {
                    String::new()
                };
                let fold_note = if placed.fold_lowering_mm > 0.05 {
                    format!(", fold lowered {:.0} mm", placed.fold_lowering_mm)
                } else {
                    String::new()
                };
                ui.label(format!(
                    "{side}: {}, {:.0} ml{fold_note}{fit_note}",
                    placed.spec, placed.volume_ml
                ));
                if let Some(warning) = placed.left_out() {
                    ui.colored_label(WARNING_COLOR, format!("{side}: {warning}"));
                }
            }
            if let Some(error) = &state.error {
                ui.colored_label(ERROR_COLOR, format!("{side}: {error}"));
            }
        }
    }
}

/// The catalog's family and entry chosen for `design`.
fn catalog_choice(ui: &mut egui::Ui, design: &mut ImplantDesign, catalog: &Catalog) {
    let current = catalog.get(&design.catalog_id);
    let family = current.map_or("", |e| e.family());
    let mut families: Vec<&str> = Vec::new();
    for entry in catalog.entries() {
        if !families.contains(&entry.family()) {
            families.push(entry.family());
        }
    }
    let mut chosen = None;
    egui::ComboBox::from_label("Family")
        .selected_text(family)
        .show_ui(ui, |ui| {
            for name in &families {
                if ui.selectable_label(*name == family, *name).clicked() {
                    // The family's entry closest in width to the current one.
                    chosen = catalog
                        .entries()
                        .iter()
                        .filter(|e| e.family() == *name)
                        .min_by(|a, b| {
                            let d = |e: &&plan::catalog::CatalogEntry| {
                                (e.shape().width_mm() - design.width_mm).abs()
                            };
                            d(a).total_cmp(&d(b))
                        })
                        .map(|e| e.id().to_string());
                }
            }
        });
    egui::ComboBox::from_label("Implant")
        .selected_text(design.catalog_id.as_str())
        .height(400.0)
        .show_ui(ui, |ui| {
            for entry in catalog.entries().iter().filter(|e| e.family() == family) {
                let shape = entry.shape();
                let text = format!(
                    "{}: {:.0} × {:.0} × {:.1} mm, {:.0} ml",
                    entry.id(),
                    shape.width_mm(),
                    shape.height_mm(),
                    shape.projection_mm(),
                    entry.volume_ml()
                );
                if ui
                    .selectable_label(entry.id() == design.catalog_id, text)
                    .clicked()
                {
                    chosen = Some(entry.id().to_string());
                }
            }
        });
    if let Some(id) = chosen {
        design.choose(&id, catalog);
    }
}

/// A custom size for `design`; the catalog entry suggested for it when asked.
fn custom_size(
    ui: &mut egui::Ui,
    design: &mut ImplantDesign,
    catalog: &Catalog,
) -> Option<Result<String, String>> {
    ui.horizontal(|ui| {
        ui.radio_value(&mut design.kind, ShapeKind::Round, "Round");
        ui.radio_value(&mut design.kind, ShapeKind::Anatomic, "Anatomic");
    });
    ui.add(egui::Slider::new(&mut design.width_mm, 80.0..=180.0).text("Width (mm)"));
    if design.kind == ShapeKind::Anatomic {
        ui.add(egui::Slider::new(&mut design.height_mm, 80.0..=180.0).text("Height (mm)"));
    }
    ui.add(egui::Slider::new(&mut design.projection_mm, 10.0..=80.0).text("Projection (mm)"));
    if ui
        .button("Suggest catalog implant")
        .on_hover_text("the catalog entry closest to these dimensions")
        .clicked()
    {
        return Some(design.suggest(catalog));
    }
    None
}

/// The move buttons (paper Fig. 10); the one pressed.
fn move_buttons(ui: &mut egui::Ui) -> Option<MoveDirection> {
    let mut pressed = None;
    egui::Grid::new("move buttons").show(ui, |ui| {
        let mut button = |ui: &mut egui::Ui, direction: MoveDirection, hint: &str| {
            if ui.button(direction.label()).on_hover_text(hint).clicked() {
                pressed = Some(direction);
            }
        };
        ui.label("");
        button(ui, MoveDirection::Up, "key ↑");
        button(
            ui,
            MoveDirection::Front,
            "shallower (anterior), key Page Up",
        );
        ui.end_row();
        button(
            ui,
            MoveDirection::Right,
            "towards the patient's right (screen left from the front), key ←",
        );
        ui.label("");
        button(
            ui,
            MoveDirection::Left,
            "towards the patient's left (screen right from the front), key →",
        );
        ui.end_row();
        ui.label("");
        button(ui, MoveDirection::Down, "key ↓");
        button(ui, MoveDirection::Back, "deeper (posterior), key Page Down");
        ui.end_row();
    });
    pressed
}

/// The fold lowering of the edited implant: as planned for it (the ICE principle), or a
/// given depth below the native fold.
fn fold_lowering_control(ui: &mut egui::Ui, design: &mut ImplantDesign) {
    let mut for_implant = design.fold_lowering_mm.is_none();
    ui.checkbox(&mut for_implant, "Fold lowered as planned for the implant")
        .on_hover_text(
            "the ICE principle: half the implant's height plus its projection, less the \
             nipple-to-fold distance (0 to 30 mm)",
        );
    if for_implant {
        design.fold_lowering_mm = None;
    } else {
        let mut mm = design.fold_lowering_mm.unwrap_or(0.0);
        ui.add(
            egui::Slider::new(&mut mm, 0.0..=plan::simulate::MAX_ICE_FOLD_LOWERING_MM)
                .text("Fold lowering (mm)"),
        )
        .on_hover_text("how far the pocket and the new fold reach below the native fold");
        design.fold_lowering_mm = Some(mm);
    }
}
