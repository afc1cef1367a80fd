//! What a picture shows: mesh layers with their colours, markers and curves.

use crate::RenderError;
use crate::colour::srgb_colour_to_linear;
use glam::DVec3;
use mesh::TriMesh;

/// A light skin tone (sRGB) for scans without colours.
pub const SKIN_TONE: [u8; 3] = [226, 190, 166];

/// An RGB image to paint onto a mesh through its texture coordinates (row 0 at the top;
/// texture coordinate v = 0 is the image's bottom row, as in OBJ).
#[derive(Debug, Clone, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    rgb: Vec<[u8; 3]>,
}

impl Texture {
    /// A texture from `width` × `height` sRGB pixels, row by row from the top.
    pub fn new(width: u32, height: u32, rgb: Vec<[u8; 3]>) -> Result<Texture, RenderError> {
        if width == 0 || height == 0 || rgb.len() as u64 != u64::from(width) * u64::from(height) {
            return Err(RenderError::TextureSize {
                width,
                height,
                found: rgb.len(),
            });
        }
        Ok(Texture { width, height, rgb })
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The colour (sRGB) at texture coordinates `uv`, bilinear between pixel centres in
    /// linear light, clamped at the borders: what a picture paints there.
    pub fn colour_at(&self, uv: glam::DVec2) -> [u8; 3] {
        self.sample_linear(uv.x as f32, uv.y as f32)
            .map(crate::colour::linear_to_srgb)
    }

    /// The colour (linear) at texture coordinates `(u, v)`, bilinear between pixel
    /// centres, clamped at the borders.
    pub(crate) fn sample_linear(&self, u: f32, v: f32) -> [f32; 3] {
        let (width, height) = (self.width(), self.height());
        let x = (u * width as f32 - 0.5).clamp(0.0, (width - 1) as f32);
        let y = ((1.0 - v) * height as f32 - 0.5).clamp(0.0, (height - 1) as f32);
        let (x0, y0) = (x.floor() as u32, y.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(width - 1), (y0 + 1).min(height - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let texel = |x, y| srgb_colour_to_linear(self.pixel(x, y));
        let [p00, p10, p01, p11] = [texel(x0, y0), texel(x1, y0), texel(x0, y1), texel(x1, y1)];
        std::array::from_fn(|k| {
            let top = p00[k] + fx * (p10[k] - p00[k]);
            let bottom = p01[k] + fx * (p11[k] - p01[k]);
            top + fy * (bottom - top)
        })
    }

    /// The pixel in column `x`, row `y` (from the top).
    pub(crate) fn pixel(&self, x: u32, y: u32) -> [u8; 3] {
        self.rgb[(y * self.width + x) as usize]
    }
}

/// Where a layer's surface colour comes from (all sRGB).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Colouring<'a> {
    /// The mesh's own vertex colours.
    MeshColours,
    /// One colour per vertex, e.g. a deviation colour map.
    PerVertex(&'a [[u8; 3]]),
    /// One colour for the whole surface.
    Uniform([u8; 3]),
    /// An image through the mesh's texture coordinates.
    Texture(&'a Texture),
}

/// A mesh drawn with one colouring and opacity.
#[derive(Debug, Clone, Copy)]
pub struct MeshLayer<'a> {
    pub mesh: &'a TriMesh,
    pub colouring: Colouring<'a>,
    /// 1 opaque, below 1 translucent (the nearest surface of the layer is blended over
    /// what lies behind it, also where it lies up to 1 mm behind an opaque surface, as a
    /// second scan of the same body does), 0 not drawn.
    pub opacity: f64,
}

impl<'a> MeshLayer<'a> {
    /// An opaque layer.
    pub fn new(mesh: &'a TriMesh, colouring: Colouring<'a>) -> MeshLayer<'a> {
        MeshLayer {
            mesh,
            colouring,
            opacity: 1.0,
        }
    }

    /// The same layer with `opacity` (0 to 1).
    pub fn with_opacity(self, opacity: f64) -> MeshLayer<'a> {
        MeshLayer { opacity, ..self }
    }

    /// Checks the mesh and that the colouring fits it; `layer` names it in errors.
    pub(crate) fn validate(&self, layer: usize) -> Result<(), RenderError> {
        self.mesh
            .validate()
            .map_err(|source| RenderError::Mesh { layer, source })?;
        if !(0.0..=1.0).contains(&self.opacity) {
            return Err(RenderError::Opacity {
                layer,
                opacity: self.opacity,
            });
        }
        let expected = self.mesh.vertex_count();
        match self.colouring {
            Colouring::MeshColours => match &self.mesh.vertex_colors {
                None => Err(RenderError::NoVertexColours { layer }),
                // The mesh's validation checked the layer's size.
                Some(_) => Ok(()),
            },
            Colouring::PerVertex(colours) if colours.len() != expected => {
                Err(RenderError::ColourCount {
                    layer,
                    found: colours.len(),
                    expected,
                })
            }
            Colouring::Texture(_) if self.mesh.uv.is_none() => {
                Err(RenderError::NoTextureCoordinates { layer })
            }
            _ => Ok(()),
        }
    }
}

/// A labelled point, e.g. a landmark.
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// mm, file frame.
    pub position: DVec3,
    /// sRGB.
    pub colour: [u8; 3],
    /// Returned with the marker's pixel, for a text label next to it.
    pub label: String,
}

/// A curve in space, e.g. a breast's cut curve, drawn where it is not hidden by a
/// surface (points on a surface count as visible).
#[derive(Debug, Clone, PartialEq)]
pub struct Polyline {
    /// mm, file frame.
    pub points: Vec<DVec3>,
    /// sRGB.
    pub colour: [u8; 3],
    /// Joins the last point back to the first.
    pub closed: bool,
    /// Stroke width in image pixels.
    pub width_px: f64,
}

/// Everything a picture shows.
#[derive(Debug, Clone, Default)]
pub struct Scene<'a> {
    pub layers: Vec<MeshLayer<'a>>,
    pub markers: Vec<Marker>,
    pub polylines: Vec<Polyline>,
}

impl Scene<'_> {
    /// Checks every layer, marker and polyline, naming the first bad one.
    pub(crate) fn validate(&self) -> Result<(), RenderError> {
        for (layer, mesh_layer) in self.layers.iter().enumerate() {
            mesh_layer.validate(layer)?;
        }
        for marker in &self.markers {
            if !marker.position.is_finite() {
                return Err(RenderError::NonFiniteMarker {
                    label: marker.label.clone(),
                    position: marker.position.to_array(),
                });
            }
        }
        for (index, polyline) in self.polylines.iter().enumerate() {
            if polyline.points.len() < 2 {
                return Err(RenderError::ShortPolyline {
                    polyline: index,
                    count: polyline.points.len(),
                });
            }
            if let Some(point) = polyline.points.iter().position(|p| !p.is_finite()) {
                return Err(RenderError::NonFinitePolyline {
                    polyline: index,
                    point,
                    position: polyline.points[point].to_array(),
                });
            }
            if !(polyline.width_px > 0.0 && polyline.width_px.is_finite()) {
                return Err(RenderError::PolylineWidth {
                    polyline: index,
                    width_px: polyline.width_px,
                });
            }
        }
        Ok(())
    }
}
