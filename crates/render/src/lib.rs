//! Pictures of meshes without a window or a GPU: the standard clinical views of a scan
//! (front, obliques, laterals) with its colours, a colour map or a texture, a translucent
//! second surface, landmarks and curves, rendered on the CPU so tests and CI can run it.
//!
//! # How a picture is made
//! 1. [`Camera`]: an orthographic (or mildly perspective) view from a [`StandardView`] in
//!    the body's axes (patient-left, up, anterior), framing given points with a margin.
//! 2. Rasterisation (`raster`): every triangle of every [`MeshLayer`] into a depth and
//!    triangle-id buffer at `supersampling`² samples per pixel, in bands of rows on all
//!    cores. No back-face culling: scans are open, so their inside shows where the
//!    outside does not (tinted, so it reads as the inside).
//! 3. Shading (`shade`): per sample, Lambert key and fill light and a soft Blinn-Phong
//!    highlight on the interpolated vertex normal, in linear light; translucent layers
//!    blended over the opaque ones; samples averaged into pixels and encoded as sRGB.
//! 4. Overlay (`overlay`): curves and markers, tested against the depth buffer (curves
//!    with a small depth offset so they show on the surface they lie on), drawn as
//!    anti-aliased strokes and discs; each marker's pixel and visibility is returned so
//!    a report can place its text label over the image.
//! 5. [`encode_png`].
//!
//! # Why our own triangle rasteriser, and which crates
//! Candidates for the 3D part, checked in 2026: `euc` (the one software 3D rasteriser on
//! crates.io with a shader-like API) has had no release since 0.5.3 (2021; its reworked
//! master branch is unreleased), works in f32 on one thread, has no anti-aliasing and
//! asserts (panics) on mismatched buffers. Headless `wgpu` on Mesa's software drivers
//! would reuse the GUI's shaders, but needs system drivers at run time, is heavy to build
//! for a library this low in the stack and gives driver-dependent pixels in tests. A
//! depth-buffered triangle rasteriser is about a hundred lines, so it is written here
//! (with shared edges evaluated identically from both sides, so no cracks); the 2D parts
//! use crates made for them:
//! - `tiny-skia` (BSD-3-Clause, kept by the linebender group): anti-aliased strokes with
//!   round joins and dashes, filled circles, for curves and markers;
//! - `png` (MIT OR Apache-2.0, image-rs): encoding, as the project guide recommends.
//!
//! Texture images: `mesh` keeps texture coordinates and material names but loads no
//! images, so a [`Texture`] (RGB pixels) is passed in by the caller.

mod camera;
mod colour;
mod image;
mod overlay;
mod raster;
mod render;
mod scene;
mod shade;

pub use camera::{Camera, ProjectedPoint, Projection, StandardView};
pub use image::{Image, encode_png};
pub use overlay::{MarkerPlacement, Visibility};
pub use render::{RenderOptions, Rendering, render};
pub use scene::{Colouring, Marker, MeshLayer, Polyline, SKIN_TONE, Scene, Texture};
pub use shade::Shading;

use mesh::MeshError;

/// Why a picture cannot be made.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("the image size {width}x{height} is empty: both sides must be at least one pixel")]
    EmptyImage { width: u32, height: u32 },
    #[error(
        "the image size {width}x{height} with {supersampling}x{supersampling} supersampling exceeds {max_samples} samples"
    )]
    ImageTooLarge {
        width: u32,
        height: u32,
        supersampling: u32,
        max_samples: u64,
    },
    #[error("supersampling must be 1 to {max} samples per pixel side, not {found}")]
    Supersampling { found: u32, max: u32 },
    #[error("mesh layer {layer}: {source}")]
    Mesh { layer: usize, source: MeshError },
    #[error("mesh layer {layer}: the mesh has no vertex colours to show")]
    NoVertexColours { layer: usize },
    #[error("mesh layer {layer}: {found} colours given for {expected} vertices")]
    ColourCount {
        layer: usize,
        found: usize,
        expected: usize,
    },
    #[error("mesh layer {layer}: a texture needs the mesh's texture coordinates, it has none")]
    NoTextureCoordinates { layer: usize },
    #[error("mesh layer {layer}: opacity {opacity} is not between 0 and 1")]
    Opacity { layer: usize, opacity: f64 },
    #[error("texture of {width}x{height} pixels has {found} pixels")]
    TextureSize {
        width: u32,
        height: u32,
        found: usize,
    },
    #[error("marker {label:?}: its position {position:?} is not finite")]
    NonFiniteMarker { label: String, position: [f64; 3] },
    #[error("polyline {polyline}: point {point} ({position:?}) is not finite")]
    NonFinitePolyline {
        polyline: usize,
        point: usize,
        position: [f64; 3],
    },
    #[error("polyline {polyline}: needs at least two points, has {count}")]
    ShortPolyline { polyline: usize, count: usize },
    #[error("polyline {polyline}: width {width_px} px is not a positive number")]
    PolylineWidth { polyline: usize, width_px: f64 },
    #[error("{count} triangles in the scene: at most {} can be drawn at once", u32::MAX - 1)]
    TooManyTriangles { count: usize },
    #[error("camera: {0}")]
    Camera(&'static str),
    #[error("nothing to frame: {0}")]
    Framing(&'static str),
    #[error("PNG encoding failed: {0}")]
    Png(String),
}
