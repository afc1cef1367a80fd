//! The 3D viewport: the shaded scans of the display mode (GPU), and over them the cut
//! curves with their control points, the landmarks, the implant outlines and the colour
//! legend, on whichever surface is shown (the pre-operative scan, the simulated one, the
//! registered post-operative one); and the mouse: orbit, pan, zoom, placing and dragging
//! landmarks, dragging, inserting and removing control points.

use super::{
    CURVE_COLOR, CURVE_WIDTH, DisplayMode, ERROR_COLOR, EXTRA_COLOR, GRAB_RADIUS, GuiApp,
    MARKER_RADIUS, OCCLUSION_TOLERANCE_MM, PLACED_COLOR, SELECTED_COLOR, Status, ZOOM_PER_SCROLL,
};
use crate::camera::Camera;
use crate::carried::carried;
use crate::control_points::{insert_nearest, preview_curve, remove, side_mut};
use crate::deviation::DeviationMap;
use crate::live_simulation::SimulatedFrame;
use crate::registration::RegisteredScan;
use crate::render::{self, Layer, LayerStyle, SceneMesh, ViewportCallback};
use anatomy::{LandmarkName, Side};
use assess::{DEVIATION_COLOR_MAX_MM, deviation_color};
use eframe::egui::{self, Color32, PointerButton, Pos2, Rect, Sense, Stroke};
use eframe::egui_wgpu;
use glam::{DVec2, DVec3};
use plan::Place;
use std::sync::Arc;

use super::postoperative::DeviationReference;

/// Colour of the cut curves' control points.
const CONTROL_POINT_COLOR: Color32 = Color32::from_rgb(255, 150, 40);
/// Width of the ring around the place a build failed (pixels).
const FAILURE_RING_WIDTH: f32 = 2.5;
/// Colour of the implant outlines.
const OUTLINE_COLOR: Color32 = Color32::from_rgb(80, 220, 235);
/// Colour of the pocket outlines.
const POCKET_COLOR: Color32 = Color32::from_rgb(235, 120, 200);
/// A click inserts a control point into a cut curve passing at most this far from the
/// clicked surface point (mm).
const INSERT_DISTANCE_MM: f64 = 25.0;

/// What a drag in the viewport does.
#[derive(Debug, Clone, PartialEq)]
pub(super) enum Drag {
    /// Moves a placed point along the surface.
    Point(String),
    /// Moves a cut curve's control point along the surface.
    ControlPoint(Side, usize),
    Orbit,
    Pan,
}

/// What a click on the pre-operative surface does to the cut curves' control points
/// (instead of placing a landmark).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlPointTool {
    /// Inserts a control point into the nearest curve, where clicked.
    Insert,
    /// Removes the control point clicked.
    Remove,
}

/// A marker under the pointer.
enum Grab {
    Landmark(String),
    ControlPoint(Side, usize),
}

/// The surface the viewport shows opaque.
pub(super) enum Shown<'a> {
    PreOperative,
    Simulated(&'a SimulatedFrame),
    PostOperative(&'a RegisteredScan),
}

/// What the viewport draws over the shown surface (mm, on it).
#[derive(Debug, Clone, Default)]
pub struct Overlay {
    /// The cut curves (closed).
    pub curves: Vec<Vec<DVec3>>,
    /// The cut curves' control points: side, index and position.
    pub control_points: Vec<(Side, usize, DVec3)>,
    /// The landmarks and extra points by name.
    pub landmarks: Vec<(String, DVec3)>,
    /// The implants' footprint outlines (closed).
    pub outlines: Vec<Vec<DVec3>>,
    /// The outlines of the pockets the implants lie in (closed).
    pub pockets: Vec<Vec<DVec3>>,
    /// Where the last build failed, ringed (the pre-operative scan).
    pub failure: Option<Place>,
    /// Landmarks and control points can be placed and moved (the pre-operative scan).
    pub editable: bool,
}

impl GuiApp {
    pub(super) fn viewport(&mut self, ui: &mut egui::Ui) {
        let (rect, response) = ui.allocate_exact_size(ui.available_size(), Sense::click_and_drag());
        self.viewport_rect = Some(rect);
        let size = DVec2::new(f64::from(rect.width()), f64::from(rect.height()));
        let painter = ui.painter_at(rect);
        if self.document.is_none() {
            painter.rect_filled(rect, 0.0, render::background());
            painter.text(
                rect.center(),
                egui::Align2::CENTER_CENTER,
                "Open a scan or the phantom (File menu), or drop a scan and its landmarks here",
                egui::FontId::proportional(16.0),
                Color32::GRAY,
            );
            return;
        }
        let layers = self.layers();
        let legend = self.legend_title();
        let overlay = self.overlay();
        let occluder = self.occluder();
        let camera = self.camera;
        let eye = camera.eye();
        let visible = |point: DVec3| {
            crate::document::visible_on(&occluder.index, eye, point, OCCLUSION_TOLERANCE_MM)
        };

        let landmarks_changed =
            self.viewport_input(ui, &response, rect, &overlay, &camera, &visible);

        // Drawing: the shaded scans (GPU), then the curves, outlines and markers on top.
        if self.gpu {
            let pixel_scale = if self.draws_preview() {
                render::INTERACTION_PIXEL_SCALE
            } else {
                1.0
            };
            painter.add(egui_wgpu::Callback::new_paint_callback(
                rect,
                ViewportCallback {
                    camera: self.camera,
                    layers,
                    size_points: size,
                    pixel_scale,
                },
            ));
        } else {
            painter.rect_filled(rect, 0.0, render::background());
        }
        let selected = self.document.as_ref().and_then(|d| d.selected.clone());
        draw_overlay(
            &painter,
            rect,
            &overlay,
            &camera,
            selected.as_deref(),
            &visible,
        );
        if let Some(title) = legend {
            deviation_legend(&painter, rect, title);
        }
        if !self.gpu {
            painter.text(
                rect.center_top() + egui::vec2(0.0, 12.0),
                egui::Align2::CENTER_TOP,
                "no GPU renderer: markers only",
                egui::FontId::proportional(13.0),
                Color32::GRAY,
            );
        }
        if landmarks_changed {
            self.landmarks_changed();
        }
    }

    /// The mouse over the viewport `rect`: drags orbit, pan (right or middle button, or
    /// Shift) or move a marker; a click places a point (or inserts or removes a control
    /// point); the wheel zooms. Returns whether the landmarks changed.
    fn viewport_input(
        &mut self,
        ui: &egui::Ui,
        response: &egui::Response,
        rect: Rect,
        overlay: &Overlay,
        camera: &Camera,
        visible: &impl Fn(DVec3) -> bool,
    ) -> bool {
        let size = DVec2::new(f64::from(rect.width()), f64::from(rect.height()));
        let local =
            |pos: Pos2| DVec2::new(f64::from(pos.x - rect.min.x), f64::from(pos.y - rect.min.y));
        let mut landmarks_changed = false;
        if response.drag_started() {
            let shift = ui.input(|i| i.modifiers.shift);
            let origin = ui.input(|i| i.pointer.press_origin());
            self.drag = if response.dragged_by(PointerButton::Primary) && !shift {
                let grabbed = origin
                    .filter(|_| overlay.editable)
                    .and_then(|origin| grab_at(overlay, camera, local(origin), size, visible));
                Some(match grabbed {
                    Some(Grab::Landmark(name)) => Drag::Point(name),
                    Some(Grab::ControlPoint(side, index)) => Drag::ControlPoint(side, index),
                    None => Drag::Orbit,
                })
            } else {
                Some(Drag::Pan)
            };
        }
        let pick = |document: &crate::Document, pointer: Pos2| {
            let ray = camera.ray(local(pointer), size);
            document.pick(ray.origin, ray.direction)
        };
        if response.dragged() {
            let delta = response.drag_delta();
            let delta = DVec2::new(f64::from(delta.x), f64::from(delta.y));
            let pointer = response.interact_pointer_pos();
            match (&self.drag, &mut self.document) {
                (Some(Drag::Point(name)), Some(document)) => {
                    if let Some(point) = pointer.and_then(|p| pick(document, p)) {
                        document.drag_to(name, point);
                        landmarks_changed = true;
                    }
                }
                (Some(Drag::ControlPoint(side, index)), Some(document)) => {
                    let point = pointer.and_then(|p| pick(document, p));
                    if let (Some(point), Some(points)) = (point, &mut self.settings.control_points)
                        && let Some(moved) = side_mut(points, *side).get_mut(*index)
                    {
                        *moved = point;
                        self.control_points_edited = true;
                    }
                }
                (Some(Drag::Orbit), _) => self.camera.orbit(delta),
                (Some(Drag::Pan), _) => self.camera.pan(delta, size.y),
                _ => {}
            }
        }
        if response.drag_stopped() {
            self.drag = None;
        }
        if response.clicked()
            && overlay.editable
            && let Some(pointer) = response.interact_pointer_pos()
        {
            landmarks_changed |= self.click(overlay, local(pointer), size, visible);
        }
        if response.hovered() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                self.camera
                    .zoom((-f64::from(scroll) * ZOOM_PER_SCROLL).exp());
            }
        }
        landmarks_changed
    }

    /// A click on the editable surface at `pixel` (in the viewport): inserts or
    /// removes a control point when a tool is chosen, else places a landmark. Returns
    /// whether the landmarks changed.
    fn click(
        &mut self,
        overlay: &Overlay,
        pixel: DVec2,
        size: DVec2,
        visible: &impl Fn(DVec3) -> bool,
    ) -> bool {
        let Some(document) = &mut self.document else {
            return false;
        };
        let ray = self.camera.ray(pixel, size);
        let picked = document.pick(ray.origin, ray.direction);
        match (self.control_point_tool, &mut self.settings.control_points) {
            (Some(ControlPointTool::Insert), Some(points)) => {
                let Some(point) = picked else {
                    self.status = Status::Info("No surface under the pointer.".into());
                    return false;
                };
                self.status = match insert_nearest(points, point, INSERT_DISTANCE_MM) {
                    Some((side, index)) => {
                        self.control_points_edited = true;
                        self.control_point_tool = None;
                        Status::Info(format!(
                            "inserted control point {} of the {side} cut curve",
                            index + 1
                        ))
                    }
                    None => Status::Info(format!(
                        "Click within {INSERT_DISTANCE_MM:.0} mm of a cut curve to insert a \
                         control point into it."
                    )),
                };
                false
            }
            (Some(ControlPointTool::Remove), Some(points)) => {
                let grabbed = grab_at(overlay, &self.camera, pixel, size, visible);
                self.status = match grabbed {
                    Some(Grab::ControlPoint(side, index)) => match remove(points, side, index) {
                        Ok(()) => {
                            self.control_points_edited = true;
                            self.control_point_tool = None;
                            Status::Info(format!(
                                "removed control point {} of the {side} cut curve",
                                index + 1
                            ))
                        }
                        Err(message) => Status::Error(message),
                    },
                    _ => Status::Info("Click on a control point to remove it.".into()),
                };
                false
            }
            _ => match picked {
                Some(point) => {
                    let placed = document.place(point);
                    if let Some(name) = &placed {
                        let next = document
                            .placing()
                            .map_or(String::new(), |p| format!("; next: {}", p.name()));
                        self.status = Status::Info(format!("placed {name}{next}"));
                    }
                    placed.is_some()
                }
                None => {
                    self.status = Status::Info("No surface under the pointer.".into());
                    false
                }
            },
        }
    }

    /// The surface the viewport shows opaque in the current display mode (the
    /// pre-operative scan until the one asked for exists).
    pub(super) fn shown(&self) -> Shown<'_> {
        let frame = self.live.as_ref().and_then(|live| live.frame.as_ref());
        match (self.display, frame, &self.postoperative.registered) {
            (DisplayMode::Simulated | DisplayMode::Deviation, Some(frame), _) => {
                Shown::Simulated(frame)
            }
            (DisplayMode::PostOperative, _, Some(registered)) => Shown::PostOperative(registered),
            _ => Shown::PreOperative,
        }
    }

    /// What the viewport draws over the shown surface.
    pub fn overlay(&self) -> Overlay {
        let Some(document) = &self.document else {
            return Overlay::default();
        };
        let model = self.model.as_ref().filter(|_| self.show_curves);
        let triangles = &document.scan.mesh.triangles;
        // The implant (or, with `pockets`, the pocket) outlines on a scan whose vertices
        // are at `positions`.
        let outlines = |positions: &[DVec3], pockets: bool| -> Vec<Vec<DVec3>> {
            let Some(live) = self.live.as_ref().filter(|_| self.show_outlines) else {
                return Vec::new();
            };
            Side::BOTH
                .iter()
                .map(|&side| {
                    let state = live.sides.get(side);
                    if pockets {
                        &state.pocket_outline
                    } else {
                        &state.outline
                    }
                })
                .filter(|outline| !outline.is_empty())
                .map(|outline| carried(outline, triangles, positions))
                .collect()
        };
        match self.shown() {
            Shown::PreOperative => {
                let control_points = match (&self.settings.control_points, model) {
                    (Some(points), Some(_)) => Side::BOTH
                        .into_iter()
                        .flat_map(|side| {
                            (points.side(side).iter().enumerate())
                                .map(move |(index, &p)| (side, index, p))
                        })
                        .collect(),
                    _ => Vec::new(),
                };
                let curves = match (&self.settings.control_points, model) {
                    // Edited since the build: the curves the rebuild will cut along.
                    (Some(points), Some(_)) if self.control_points_edited => Side::BOTH
                        .iter()
                        .filter_map(|&side| preview_curve(points.side(side), &document.scan).ok())
                        .collect(),
                    (_, Some(model)) => vec![
                        model.cut_curves.left.clone(),
                        model.cut_curves.right.clone(),
                    ],
                    _ => Vec::new(),
                };
                Overlay {
                    curves,
                    control_points,
                    landmarks: owned(document.landmarks.iter()),
                    outlines: outlines(&document.scan.mesh.positions, false),
                    pockets: outlines(&document.scan.mesh.positions, true),
                    failure: self.failure_place,
                    editable: true,
                }
            }
            Shown::Simulated(frame) => {
                let curves = model.map_or_else(Vec::new, |model| {
                    Side::BOTH
                        .iter()
                        .map(|&side| {
                            carried(
                                model.cut_curve_anchors.get(side),
                                triangles,
                                &frame.positions,
                            )
                        })
                        .collect()
                });
                Overlay {
                    curves,
                    landmarks: owned(frame.landmarks.iter()),
                    outlines: outlines(&frame.positions, false),
                    pockets: outlines(&frame.positions, true),
                    ..Overlay::default()
                }
            }
            Shown::PostOperative(registered) => Overlay {
                landmarks: owned(registered.landmarks.iter()),
                ..Overlay::default()
            },
        }
    }

    /// The surface that hides what lies behind it in the view: the shown one (the
    /// simulated scan of the settled frame; while the simulation runs, the last settled
    /// one, or the pre-operative scan, which the prediction lies in front of).
    fn occluder(&self) -> Arc<plan::Scan> {
        let pre_operative = || {
            Arc::clone(
                &self
                    .document
                    .as_ref()
                    .expect("the viewport draws a document")
                    .scan,
            )
        };
        match self.shown() {
            Shown::PreOperative => pre_operative(),
            Shown::Simulated(_) => self
                .live
                .as_ref()
                .and_then(|live| live.settled.as_ref())
                .map_or_else(pre_operative, |settled| Arc::clone(&settled.scan)),
            Shown::PostOperative(registered) => Arc::clone(&registered.scan),
        }
    }

    /// The meshes the viewport draws in the current display mode: with the pectoralis
    /// major shown, the muscle and the front surface over it as a veil.
    fn layers(&self) -> Vec<Layer> {
        let layers = self.surface_layers();
        match (&self.muscle, layers.last()) {
            (Some(muscle), Some(front)) if self.show_muscle => vec![
                Layer {
                    scene: Arc::clone(muscle),
                    style: LayerStyle::Opaque,
                },
                Layer {
                    scene: Arc::clone(&front.scene),
                    style: LayerStyle::Translucent,
                },
            ],
            _ => layers,
        }
    }

    /// The surfaces the viewport draws in the current display mode.
    fn surface_layers(&self) -> Vec<Layer> {
        let Some(scene) = &self.scene else {
            return Vec::new();
        };
        let opaque = |scene: &Arc<SceneMesh>| Layer {
            scene: Arc::clone(scene),
            style: LayerStyle::Opaque,
        };
        match self.shown() {
            Shown::PreOperative => {
                let frame = self.live.as_ref().and_then(|live| live.frame.as_ref());
                match (self.display, frame) {
                    (DisplayMode::Overlay, Some(frame)) => vec![
                        // a preview's veil lies on the pre-operative scan's same triangles
                        opaque(frame.pre_operative.as_ref().unwrap_or(scene)),
                        Layer {
                            scene: Arc::clone(&frame.scene),
                            style: LayerStyle::Translucent,
                        },
                    ],
                    _ => vec![opaque(scene)],
                }
            }
            // The map of the settled prediction; the prediction itself until there is one.
            Shown::Simulated(frame) => match self.simulated_deviation() {
                Some(map) if self.display == DisplayMode::Deviation => vec![opaque(&map.scene)],
                _ => vec![opaque(&frame.scene)],
            },
            Shown::PostOperative(registered) => match self.postoperative.deviation() {
                Some((_, map)) => vec![opaque(&map.scene)],
                None => vec![opaque(&registered.scene)],
            },
        }
    }

    /// Whether the viewport draws a running solve's preview frame (on the interaction
    /// mesh, with a software renderer): the window then trades detail for rate (see
    /// [`render`]).
    pub(super) fn draws_preview(&self) -> bool {
        let frame = self.live.as_ref().and_then(|live| live.frame.as_ref());
        frame.is_some_and(|frame| frame.pre_operative.is_some())
            && self.shown_frame_number().is_some()
    }

    /// The number of the live simulation's latest frame if the viewport draws it.
    pub(super) fn shown_frame_number(&self) -> Option<u64> {
        let frame = self.live.as_ref()?.frame.as_ref()?;
        (self.layers().iter())
            .any(|layer| Arc::ptr_eq(&layer.scene, &frame.scene))
            .then_some(frame.number)
    }

    /// The deviation map of the settled prediction, if there is one.
    fn simulated_deviation(&self) -> Option<&DeviationMap> {
        let settled = self.live.as_ref()?.settled.as_ref()?;
        settled.deviation.as_ref().ok()
    }

    /// The title of the colour legend the viewport shows, if it shows a colour map.
    fn legend_title(&self) -> Option<&'static str> {
        match self.shown() {
            Shown::Simulated(_) if self.display == DisplayMode::Deviation => self
                .simulated_deviation()
                .map(|_| DeviationReference::PreOperative.legend_title()),
            Shown::PostOperative(_) => self
                .postoperative
                .deviation()
                .map(|(reference, _)| reference.legend_title()),
            _ => None,
        }
    }
}

/// Named points as owned pairs.
fn owned<'a>(points: impl Iterator<Item = (&'a str, DVec3)>) -> Vec<(String, DVec3)> {
    points.map(|(name, p)| (name.to_string(), p)).collect()
}

/// Draws the cut curves, implant and pocket outlines, control points and landmarks of
/// `overlay` over the viewport `rect`: in sight bright, hidden dimmed; `selected` names the
/// selected landmark.
fn draw_overlay(
    painter: &egui::Painter,
    rect: Rect,
    overlay: &Overlay,
    camera: &Camera,
    selected: Option<&str>,
    visible: &impl Fn(DVec3) -> bool,
) {
    let size = DVec2::new(f64::from(rect.width()), f64::from(rect.height()));
    let on_screen = |point: DVec3| {
        let pixel = camera.project(point, size)?;
        Some(rect.min + egui::vec2(pixel.x as f32, pixel.y as f32))
    };
    let closed_line = |points: &[DVec3], stroke: Stroke| {
        // Segments whose ends are both in sight are drawn.
        let shown: Vec<Option<Pos2>> = points
            .iter()
            .map(|&p| visible(p).then(|| on_screen(p)).flatten())
            .collect();
        for k in 0..shown.len() {
            if let (Some(a), Some(b)) = (shown[k], shown[(k + 1) % shown.len()]) {
                painter.line_segment([a, b], stroke);
            }
        }
    };
    for curve in &overlay.curves {
        closed_line(curve, Stroke::new(CURVE_WIDTH, CURVE_COLOR));
    }
    for outline in &overlay.outlines {
        closed_line(outline, Stroke::new(CURVE_WIDTH, OUTLINE_COLOR));
    }
    for pocket in &overlay.pockets {
        closed_line(pocket, Stroke::new(CURVE_WIDTH, POCKET_COLOR));
    }
    if let Some(place) = &overlay.failure {
        draw_failure(painter, rect, place, camera, size);
    }
    for &(_, _, point) in &overlay.control_points {
        let Some(at) = on_screen(point) else {
            continue;
        };
        let square = Rect::from_center_size(at, egui::Vec2::splat(2.0 * MARKER_RADIUS - 1.0));
        if visible(point) {
            painter.rect_filled(square, 0.0, CONTROL_POINT_COLOR);
            painter.rect_stroke(
                square,
                0.0,
                Stroke::new(1.0, Color32::BLACK),
                egui::StrokeKind::Outside,
            );
        } else {
            painter.rect_stroke(
                square,
                0.0,
                Stroke::new(1.0, CONTROL_POINT_COLOR.gamma_multiply(0.6)),
                egui::StrokeKind::Outside,
            );
        }
    }
    for (name, point) in &overlay.landmarks {
        let Some(at) = on_screen(*point) else {
            continue;
        };
        let in_sight = visible(*point);
        let color = if overlay.editable && selected == Some(name.as_str()) {
            SELECTED_COLOR
        } else if LandmarkName::parse(name).is_some() {
            PLACED_COLOR
        } else {
            EXTRA_COLOR
        };
        if in_sight {
            painter.circle_filled(at, MARKER_RADIUS, color);
            painter.circle_stroke(at, MARKER_RADIUS, Stroke::new(1.0, Color32::BLACK));
        } else {
            painter.circle_stroke(
                at,
                MARKER_RADIUS,
                Stroke::new(1.0, color.gamma_multiply(0.6)),
            );
        }
        painter.text(
            at + egui::vec2(MARKER_RADIUS + 2.0, -MARKER_RADIUS - 2.0),
            egui::Align2::LEFT_BOTTOM,
            name,
            egui::FontId::proportional(13.0),
            if in_sight {
                Color32::WHITE
            } else {
                Color32::GRAY
            },
        );
    }
}

/// Rings `place`, where a build failed, at its radius on the body (at least a marker's
/// size), labelled below (landmark names stand above their markers). Never dimmed: a
/// region's centre lies inside the body, behind the skin it rings.
fn draw_failure(painter: &egui::Painter, rect: Rect, place: &Place, camera: &Camera, size: DVec2) {
    let centre = place.centre();
    let Some(pixel) = camera.project(centre, size) else {
        return;
    };
    let at = rect.min + egui::vec2(pixel.x as f32, pixel.y as f32);
    let radius_px = camera
        .project(centre + camera.right() * place.radius_mm, size)
        .map_or(0.0, |edge| edge.distance(pixel) as f32)
        .max(2.0 * MARKER_RADIUS);
    painter.circle_stroke(at, radius_px, Stroke::new(FAILURE_RING_WIDTH, ERROR_COLOR));
    painter.text(
        at + egui::vec2(0.0, radius_px + 2.0),
        egui::Align2::CENTER_TOP,
        "the model failed here",
        egui::FontId::proportional(13.0),
        ERROR_COLOR,
    );
}

/// The visible marker (landmark or control point) within [`GRAB_RADIUS`] of `pixel`,
/// the nearest one.
fn grab_at(
    overlay: &Overlay,
    camera: &Camera,
    pixel: DVec2,
    size: DVec2,
    visible: &impl Fn(DVec3) -> bool,
) -> Option<Grab> {
    let landmarks = (overlay.landmarks.iter()).map(|(name, p)| (*p, Grab::Landmark(name.clone())));
    let control_points = (overlay.control_points.iter())
        .map(|&(side, index, p)| (p, Grab::ControlPoint(side, index)));
    landmarks
        .chain(control_points)
        .filter_map(|(point, grab)| {
            let distance = camera.project(point, size)?.distance(pixel);
            (distance <= f64::from(GRAB_RADIUS) && visible(point)).then_some((distance, grab))
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, grab)| grab)
}

/// The colour legend of the deviation map (paper Fig. 3) in the viewport's lower left
/// corner: the ramp of [`deviation_color`] sampled finely enough to be drawn exactly
/// (it is linear in each channel between 0, 10 and 20 mm), its ticks, and the colour of
/// vertices outside the overlap.
fn deviation_legend(painter: &egui::Painter, viewport: Rect, title: &str) {
    const WIDTH: f32 = 240.0;
    const HEIGHT: f32 = 14.0;
    const SAMPLES: usize = 40;
    let font = egui::FontId::proportional(13.0);
    let text_color = Color32::from_gray(230);
    let color = |distance_mm: f64| {
        let [r, g, b] = deviation_color(distance_mm);
        Color32::from_rgb(r, g, b)
    };
    let origin = viewport.left_bottom() + egui::vec2(16.0, -64.0);
    let backdrop = Rect::from_min_size(
        origin - egui::vec2(8.0, 22.0),
        egui::vec2(WIDTH + 130.0, 74.0),
    );
    painter.rect_filled(backdrop, 4.0, Color32::from_black_alpha(150));
    painter.text(
        origin - egui::vec2(0.0, 4.0),
        egui::Align2::LEFT_BOTTOM,
        title,
        font.clone(),
        text_color,
    );
    let mut ramp = egui::epaint::Mesh::default();
    for k in 0..=SAMPLES {
        let fraction = k as f32 / SAMPLES as f32;
        let x = origin.x + fraction * WIDTH;
        let c = color(f64::from(fraction) * DEVIATION_COLOR_MAX_MM);
        ramp.colored_vertex(Pos2::new(x, origin.y), c);
        ramp.colored_vertex(Pos2::new(x, origin.y + HEIGHT), c);
        if k > 0 {
            let i = 2 * k as u32;
            ramp.add_triangle(i - 2, i - 1, i);
            ramp.add_triangle(i - 1, i + 1, i);
        }
    }
    painter.add(ramp);
    for (fraction, label) in [(0.0, "0"), (0.5, "10"), (1.0, "≥ 20")] {
        let x = origin.x + fraction * WIDTH;
        painter.line_segment(
            [
                Pos2::new(x, origin.y + HEIGHT),
                Pos2::new(x, origin.y + HEIGHT + 4.0),
            ],
            Stroke::new(1.0, text_color),
        );
        painter.text(
            Pos2::new(x, origin.y + HEIGHT + 5.0),
            egui::Align2::CENTER_TOP,
            label,
            font.clone(),
            text_color,
        );
    }
    let outside = Rect::from_min_size(
        Pos2::new(origin.x + WIDTH + 22.0, origin.y),
        egui::vec2(HEIGHT, HEIGHT),
    );
    painter.rect_filled(outside, 0.0, color(f64::NAN));
    painter.text(
        outside.right_center() + egui::vec2(6.0, 0.0),
        egui::Align2::LEFT_CENTER,
        "outside\noverlap",
        font,
        text_color,
    );
}
