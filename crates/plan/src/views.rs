//! The standard views of a scan for a report: front, obliques and sides in the
//! anatomical frame from its landmarks, with an optional colour map, the landmarks as
//! markers and curves (e.g. the cut curves) on the surface, as PNG files in memory.

use anatomy::{AnatomicalFrame, Landmarks, Up};
use anyhow::{Context, Result};
use glam::DVec3;
use mesh::TriMesh;
use render::{
    Camera, Colouring, Marker, MarkerPlacement, MeshLayer, Polyline, RenderOptions, SKIN_TONE,
    Scene, StandardView, encode_png, render,
};

/// Marker colours (sRGB): the patient's left side, her right side, the midline; none of
/// them green, yellow or red, the colours of a deviation map.
const LEFT_MARKER: [u8; 3] = [0, 90, 200];
const RIGHT_MARKER: [u8; 3] = [210, 0, 140];
const MIDLINE_MARKER: [u8; 3] = [35, 35, 35];
/// Tone (sRGB) of skin the scanner did not see and the model reconstructed: a cool grey,
/// apart from every skin tone and from the deviation map's colours.
pub const RECONSTRUCTED_TONE: [u8; 3] = [150, 165, 190];
/// Tone (sRGB) of the pectoralis major seen through the skin: a muscle red, apart from
/// the skin tones, the reconstructed skin's grey and the deviation map's colours.
pub const MUSCLE_TONE: [u8; 3] = [165, 55, 50];
/// Opacity of the skin over the muscles where they are shown: a veil that lets them
/// show through while the breasts' outline stays readable.
const SKIN_VEIL_OPACITY: f64 = 0.4;
/// Curve colour (sRGB) and stroke width (pixels).
const CURVE_COLOUR: [u8; 3] = [100, 40, 150];
const CURVE_WIDTH_PX: f64 = 2.5;

/// What the views show besides the scan and its landmarks.
#[derive(Debug, Clone, Copy)]
pub struct ViewContent<'a> {
    /// One colour per scan vertex (e.g. a deviation map); without it the scan's
    /// photograph (`texture`, through its texture coordinates), its own vertex colours,
    /// or a skin tone.
    pub colours: Option<&'a [[u8; 3]]>,
    /// The scan's photograph ([`crate::texture`]).
    pub texture: Option<&'a render::Texture>,
    /// Closed curves on the surface (mm, scan frame), e.g. the breasts' cut curves.
    pub curves: &'a [Vec<DVec3>],
    /// Skin the scanner did not see, reconstructed by the model (mm, scan frame): drawn
    /// over the scan's holes in [`RECONSTRUCTED_TONE`].
    pub reconstructed: &'a [TriMesh],
    /// Surfaces under the skin drawn through it (mm, scan frame), e.g. the pectoralis
    /// major ([`MUSCLE_TONE`]); with any, the skin is a translucent veil.
    pub muscles: &'a [TriMesh],
    /// Picture size (pixels).
    pub width: u32,
    pub height: u32,
}

impl Default for ViewContent<'_> {
    fn default() -> Self {
        ViewContent {
            colours: None,
            texture: None,
            curves: &[],
            reconstructed: &[],
            muscles: &[],
            width: 800,
            height: 1000,
        }
    }
}

/// One rendered view.
#[derive(Debug, Clone)]
pub struct RenderedView {
    pub view: StandardView,
    /// For people: "Front", "Left oblique", ...
    pub name: &'static str,
    pub png: Vec<u8>,
    pub width: u32,
    pub height: u32,
    /// Each landmark (required ones first, then extras) in the picture, for its label.
    pub markers: Vec<MarkerPlacement>,
}

/// Renders `scan` in every [`StandardView`], all at the same scale, looking from the
/// standing frame of `landmarks` with `up`.
pub fn standard_views(
    scan: &TriMesh,
    landmarks: &Landmarks,
    up: Up,
    content: &ViewContent,
) -> Result<Vec<RenderedView>> {
    let frame = AnatomicalFrame::from_landmarks(landmarks, up)
        .context("the views look from the landmarks' standing frame")?;
    let colouring = match (content.colours, content.texture, &scan.vertex_colors) {
        (Some(colours), _, _) => Colouring::PerVertex(colours),
        (None, Some(texture), _) if scan.uv.is_some() => Colouring::Texture(texture),
        (None, _, Some(_)) => Colouring::MeshColours,
        (None, _, None) => Colouring::Uniform(SKIN_TONE),
    };
    let skin_opacity = if content.muscles.is_empty() {
        1.0
    } else {
        SKIN_VEIL_OPACITY
    };
    let mut layers = vec![MeshLayer::new(scan, colouring).with_opacity(skin_opacity)];
    layers.extend(
        content
            .reconstructed
            .iter()
            .filter(|skin| skin.triangle_count() > 0)
            .map(|skin| {
                MeshLayer::new(skin, Colouring::Uniform(RECONSTRUCTED_TONE))
                    .with_opacity(skin_opacity)
            }),
    );
    layers.extend(
        (content.muscles.iter())
            .filter(|muscle| muscle.triangle_count() > 0)
            .map(|muscle| MeshLayer::new(muscle, Colouring::Uniform(MUSCLE_TONE))),
    );
    let scene = Scene {
        layers,
        markers: landmarks
            .iter()
            .map(|(name, position)| Marker {
                position,
                colour: marker_colour(name),
                label: name.to_owned(),
            })
            .collect(),
        polylines: content
            .curves
            .iter()
            .map(|curve| Polyline {
                points: curve.clone(),
                colour: CURVE_COLOUR,
                closed: true,
                width_px: CURVE_WIDTH_PX,
            })
            .collect(),
    };
    let aspect = f64::from(content.width) / f64::from(content.height);
    let cameras =
        Camera::standard_views(frame.axes, &scan.positions, aspect).context("framing the scan")?;
    let options = RenderOptions::default();
    cameras
        .into_iter()
        .map(|(view, camera)| {
            let rendering = render(&scene, &camera, content.width, content.height, &options)
                .with_context(|| format!("rendering the {} view", view.label()))?;
            Ok(RenderedView {
                view,
                name: view.label(),
                png: encode_png(&rendering.image)?,
                width: content.width,
                height: content.height,
                markers: rendering.markers,
            })
        })
        .collect()
}

/// Landmarks of the patient's left side end in `l`, of her right side in `r`
/// (`Pcl`, `PSMFlr`, ...); the rest (`Pj`, `Px`, extras) are drawn as midline points.
fn marker_colour(name: &str) -> [u8; 3] {
    let suffix = anatomy::LandmarkName::parse(name).and_then(|n| n.as_str().chars().last());
    match suffix {
        Some('l') => LEFT_MARKER,
        Some('r') => RIGHT_MARKER,
        _ => MIDLINE_MARKER,
    }
}
