//! Curves and markers over the rendered surfaces: each point is tested against the depth
//! buffer of the opaque layers, then drawn anti-aliased with `tiny-skia`.
//!
//! A point counts as hidden when the opaque surface drawn at its sample lies in front of
//! it by more than a small tolerance and that surface's triangle does not pass through
//! the point itself: points on the surface (landmarks snapped to vertices, cut curves
//! projected onto it) stay visible also where the surface is steep or at its silhouette,
//! while a point behind another part of the body, even one just behind its edge, is
//! hidden.

use crate::camera::Camera;
use crate::image::Image;
use crate::raster::key_depth_mm;
use crate::raster::{NO_TRIANGLE, SampleBuffer};
use crate::scene::{Polyline, Scene};
use crate::shade::{PreparedLayer, locate};
use glam::{DVec2, DVec3};
use tiny_skia::{
    ColorSpace, FillRule, LineCap, LineJoin, Paint, PathBuilder, PixmapMut, Stroke, StrokeDash,
    Transform,
};

/// Whether a marker can be seen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Visibility {
    /// In the image and in front of every opaque surface (or on it): drawn as a disc.
    Visible,
    /// In the image but behind an opaque surface: drawn as a dashed ring.
    Hidden,
    /// Outside the image (or behind a perspective camera): not drawn.
    OutsideImage,
}

/// Where a marker landed in the image.
#[derive(Debug, Clone, PartialEq)]
pub struct MarkerPlacement {
    pub label: String,
    /// Pixels from the image's top-left corner, y down (pixel `(i, j)` has its centre at
    /// `(i + 0.5, j + 0.5)`); NaN for a point behind a perspective camera.
    pub pixel: DVec2,
    pub visibility: Visibility,
}

/// A point may lie this far behind the surface in front of it, or off the plane of the
/// triangle drawn there, and still count as on it (mm): the chord between two curve
/// points on a breast of 60 mm radius 3 mm apart dips 0.02 mm below the skin, the depth
/// buffer is exact to about 0.01 mm.
const OCCLUSION_TOLERANCE_MM: f64 = 1.0;
/// Added to the tolerance per sample width (mm per mm): the surface's depth varies across
/// a sample where it is steep.
const OCCLUSION_TOLERANCE_PER_SAMPLE: f64 = 2.0;
/// Curves are tested every this many samples along their length.
const CURVE_STEP_SAMPLES: f64 = 0.5;
/// A white band this much wider than a curve (pixels) lies under it, for contrast.
const HALO_WIDTH_PX: f32 = 2.0;
const HALO: [u8; 4] = [255, 255, 255, 210];
/// A visible marker's white outline and a hidden marker's ring (pixels).
const MARKER_OUTLINE_PX: f32 = 1.5;
/// Dash and gap of a hidden marker's ring (pixels).
const HIDDEN_DASH_PX: [f32; 2] = [3.0, 2.5];
/// Opacity of a hidden marker's ring.
const HIDDEN_ALPHA: u8 = 220;

/// Whether points are hidden behind the opaque surfaces of a rendering.
struct Occlusion<'a> {
    depth: &'a SampleBuffer,
    layers: &'a [PreparedLayer<'a>],
    camera: &'a Camera,
    supersampling: f64,
    tolerance_mm: f64,
}

impl Occlusion<'_> {
    /// The point's position in image pixels and whether it is hidden; `None` outside the
    /// image or behind a perspective eye.
    fn place(&self, point: DVec3) -> Option<(DVec2, bool)> {
        let (width, height) = (self.depth.width as f64, self.depth.height as f64);
        let projected = self.camera.project(point, width, height)?;
        let sample = projected.pixel;
        if !(sample.x >= 0.0 && sample.x < width && sample.y >= 0.0 && sample.y < height) {
            return None;
        }
        let index = self.depth.index(sample.x as usize, sample.y as usize);
        let id = self.depth.id[index];
        let hidden = id != NO_TRIANGLE
            && key_depth_mm(self.camera.projection, self.depth.key[index])
                < projected.depth_mm - self.tolerance_mm
            && {
                let (layer, t) = locate(self.layers, id);
                !layer.passes_near(t, point, self.tolerance_mm)
            };
        Some((sample / self.supersampling, hidden))
    }
}

/// Draws the scene's polylines and markers onto `image` (rendered from `depth` at
/// `supersampling` samples per pixel side) and returns where each marker landed.
pub(crate) fn draw(
    image: &mut Image,
    scene: &Scene,
    camera: &Camera,
    depth: &SampleBuffer,
    layers: &[PreparedLayer],
    supersampling: usize,
    marker_radius_px: f64,
) -> Vec<MarkerPlacement> {
    let mm_per_sample = camera.view_height_mm / depth.height as f64;
    let occlusion = Occlusion {
        depth,
        layers,
        camera,
        supersampling: supersampling as f64,
        tolerance_mm: OCCLUSION_TOLERANCE_MM + OCCLUSION_TOLERANCE_PER_SAMPLE * mm_per_sample,
    };
    let placements: Vec<MarkerPlacement> = scene
        .markers
        .iter()
        .map(|marker| {
            let (pixel, visibility) = match occlusion.place(marker.position) {
                Some((pixel, false)) => (pixel, Visibility::Visible),
                Some((pixel, true)) => (pixel, Visibility::Hidden),
                None => {
                    let (width, height) = (f64::from(image.width()), f64::from(image.height()));
                    let pixel = camera
                        .project(marker.position, width, height)
                        .map_or(DVec2::NAN, |p| p.pixel);
                    (pixel, Visibility::OutsideImage)
                }
            };
            MarkerPlacement {
                label: marker.label.clone(),
                pixel,
                visibility,
            }
        })
        .collect();

    let (width, height) = (image.width(), image.height());
    premultiply(image.rgba_mut());
    if let Some(mut canvas) = PixmapMut::from_bytes(image.rgba_mut(), width, height) {
        let runs: Vec<(Vec<DVec2>, &Polyline)> = scene
            .polylines
            .iter()
            .flat_map(|polyline| {
                visible_runs(polyline, &occlusion)
                    .into_iter()
                    .map(move |run| (run, polyline))
            })
            .collect();
        for (run, polyline) in &runs {
            stroke_run(
                &mut canvas,
                run,
                polyline.width_px as f32 + HALO_WIDTH_PX,
                HALO,
            );
        }
        for (run, polyline) in &runs {
            let [r, g, b] = polyline.colour;
            stroke_run(&mut canvas, run, polyline.width_px as f32, [r, g, b, 255]);
        }
        // Hidden markers first: a visible one at the same place covers them.
        for visibility in [Visibility::Hidden, Visibility::Visible] {
            for (marker, placement) in scene.markers.iter().zip(&placements) {
                if placement.visibility == visibility {
                    draw_marker(
                        &mut canvas,
                        placement,
                        marker.colour,
                        marker_radius_px as f32,
                    );
                }
            }
        }
    }
    demultiply(image.rgba_mut());
    placements
}

/// The stretches of a polyline that are not hidden, as image pixels.
fn visible_runs(polyline: &Polyline, occlusion: &Occlusion) -> Vec<Vec<DVec2>> {
    let points = &polyline.points;
    let segment_count = if polyline.closed {
        points.len()
    } else {
        points.len() - 1
    };
    let (width, height) = (occlusion.depth.width as f64, occlusion.depth.height as f64);
    let mut runs = Vec::new();
    let mut run: Vec<DVec2> = Vec::new();
    let mut starts_visible = false;
    for segment in 0..segment_count {
        let (start, end) = (points[segment], points[(segment + 1) % points.len()]);
        let length_samples = match (
            occlusion.camera.project(start, width, height),
            occlusion.camera.project(end, width, height),
        ) {
            (Some(a), Some(b)) => a.pixel.distance(b.pixel),
            _ => 0.0,
        };
        // A segment longer than the image is wide and high together (far outside it)
        // is tested more coarsely, so no curve takes long.
        let steps = (length_samples / CURVE_STEP_SAMPLES)
            .ceil()
            .clamp(1.0, (width + height) / CURVE_STEP_SAMPLES) as usize;
        // The segment's end is the next segment's start: each point is tested once, the
        // polyline's last point only when it is open.
        let last_step = if segment + 1 == segment_count && !polyline.closed {
            steps
        } else {
            steps - 1
        };
        for step in 0..=last_step {
            let point = start.lerp(end, step as f64 / steps as f64);
            match occlusion.place(point) {
                Some((pixel, false)) => {
                    starts_visible |= segment == 0 && step == 0;
                    run.push(pixel);
                }
                _ => end_run(&mut runs, &mut run),
            }
        }
    }
    if polyline.closed && !run.is_empty() && starts_visible {
        // Visible where the curve closes: the last run continues into the first.
        match runs.first_mut() {
            Some(first_run) => {
                run.append(first_run);
                *first_run = std::mem::take(&mut run);
            }
            None => run.push(run[0]),
        }
    }
    end_run(&mut runs, &mut run);
    runs
}

/// Keeps `run` if it is a line (two points or more) and starts a new one.
fn end_run(runs: &mut Vec<Vec<DVec2>>, run: &mut Vec<DVec2>) {
    if run.len() >= 2 {
        runs.push(std::mem::take(run));
    }
    run.clear();
}

fn stroke_run(canvas: &mut PixmapMut, run: &[DVec2], width_px: f32, rgba: [u8; 4]) {
    let mut builder = PathBuilder::new();
    builder.move_to(run[0].x as f32, run[0].y as f32);
    for point in &run[1..] {
        builder.line_to(point.x as f32, point.y as f32);
    }
    let Some(path) = builder.finish() else {
        return;
    };
    let stroke = Stroke {
        width: width_px,
        line_cap: LineCap::Round,
        line_join: LineJoin::Round,
        ..Stroke::default()
    };
    canvas.stroke_path(&path, &paint(rgba), &stroke, Transform::identity(), None);
}

/// A visible marker: a disc in its colour with a white outline. A hidden one: a dashed
/// ring in its colour over a faint white one.
fn draw_marker(canvas: &mut PixmapMut, placement: &MarkerPlacement, colour: [u8; 3], radius: f32) {
    let centre = placement.pixel.as_vec2();
    let Some(circle) = PathBuilder::from_circle(centre.x, centre.y, radius) else {
        return;
    };
    let [r, g, b] = colour;
    let outline = |width| Stroke {
        width,
        ..Stroke::default()
    };
    match placement.visibility {
        Visibility::Visible => {
            canvas.fill_path(
                &circle,
                &paint([r, g, b, 255]),
                FillRule::Winding,
                Transform::identity(),
                None,
            );
            canvas.stroke_path(
                &circle,
                &paint([255, 255, 255, 255]),
                &outline(MARKER_OUTLINE_PX),
                Transform::identity(),
                None,
            );
        }
        Visibility::Hidden => {
            canvas.stroke_path(
                &circle,
                &paint(HALO),
                &outline(MARKER_OUTLINE_PX + HALO_WIDTH_PX),
                Transform::identity(),
                None,
            );
            let dashed = Stroke {
                dash: StrokeDash::new(HIDDEN_DASH_PX.to_vec(), 0.0),
                ..outline(MARKER_OUTLINE_PX)
            };
            canvas.stroke_path(
                &circle,
                &paint([r, g, b, HIDDEN_ALPHA]),
                &dashed,
                Transform::identity(),
                None,
            );
        }
        Visibility::OutsideImage => {}
    }
}

fn paint(rgba: [u8; 4]) -> Paint<'static> {
    let mut paint = Paint {
        anti_alias: true,
        colorspace: ColorSpace::FullSRGBGamma,
        ..Paint::default()
    };
    let [r, g, b, a] = rgba;
    paint.set_color_rgba8(r, g, b, a);
    paint
}

fn premultiply(rgba: &mut [u8]) {
    for pixel in rgba.chunks_exact_mut(4) {
        let alpha = u16::from(pixel[3]);
        for channel in &mut pixel[..3] {
            *channel = ((u16::from(*channel) * alpha + 127) / 255) as u8;
        }
    }
}

fn demultiply(rgba: &mut [u8]) {
    for pixel in rgba.chunks_exact_mut(4) {
        let alpha = u16::from(pixel[3]);
        if alpha != 0 && alpha != 255 {
            for channel in &mut pixel[..3] {
                *channel = ((u16::from(*channel) * 255 + alpha / 2) / alpha).min(255) as u8;
            }
        }
    }
}
