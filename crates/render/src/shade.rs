//! Surface colour and light at a sample: the layer's colour (vertex colours, a colour
//! map, a uniform tone or a texture) interpolated across the triangle, lit by a key and a
//! fill light with a soft highlight, in linear light.

use crate::camera::Camera;
use crate::colour::srgb_colour_to_linear;
use crate::raster::{ScreenVertex, screen_vertex};
use crate::scene::{Colouring, MeshLayer, Texture};
use glam::{DVec3, Vec3};
use mesh::{TriMesh, UvLayer};
use rayon::prelude::*;
use std::sync::LazyLock;

/// Light that reaches every surface, whatever its direction.
const AMBIENT: f32 = 0.26;
/// The key light, from above and to the viewer's left, and its strength.
const KEY_DIRECTION: Vec3 = Vec3::new(-0.45, 0.55, 1.0);
const KEY: f32 = 0.68;
/// The fill light, from the viewer's right and a little below, and its strength.
const FILL_DIRECTION: Vec3 = Vec3::new(0.8, -0.2, 0.6);
const FILL: f32 = 0.2;
/// The soft Blinn-Phong highlight of the key light: strength and exponent (skin is not
/// glossy: a broad, weak highlight).
const SPECULAR: f32 = 0.1;
const SHININESS: i32 = 20;
/// The inside of an open surface is shown in this grey (linear), mixed half and half with
/// the surface's colour, so it reads as the inside.
const BACK_FACE_GREY: [f32; 3] = [0.32, 0.34, 0.38];
const BACK_FACE_MIX: f32 = 0.5;
/// Where a prepared layer's colour comes from, in linear light.
enum Albedo<'a> {
    PerVertex(Vec<[f32; 3]>),
    Uniform([f32; 3]),
    Texture {
        uv: &'a UvLayer,
        texture: &'a Texture,
    },
}

/// A mesh layer on the sample grid of one camera, ready to rasterise and shade.
pub(crate) struct PreparedLayer<'a> {
    mesh: &'a TriMesh,
    pub vertices: Vec<ScreenVertex>,
    pub triangles: &'a [[u32; 3]],
    /// Vertex normals in screen axes (x right, y up, z towards the viewer).
    normals: Vec<Vec3>,
    albedo: Albedo<'a>,
    pub opacity: f32,
    /// Id of the layer's first triangle in the sample buffers.
    pub first_id: u32,
}

impl<'a> PreparedLayer<'a> {
    /// `layer` (validated) on a sample grid of `width` × `height` seen by `camera`.
    pub fn new(
        layer: &MeshLayer<'a>,
        camera: &Camera,
        width: f64,
        height: f64,
        first_id: u32,
    ) -> PreparedLayer<'a> {
        let mesh = layer.mesh;
        let vertices = mesh
            .positions
            .par_iter()
            .map(|&p| screen_vertex(camera, p, width, height))
            .collect();
        let normals = mesh
            .vertex_normals()
            .iter()
            .map(|&n| camera.to_screen_axes(n).as_vec3())
            .collect();
        let per_vertex = |colours: &[[u8; 3]]| {
            Albedo::PerVertex(colours.iter().map(|&c| srgb_colour_to_linear(c)).collect())
        };
        let albedo = match layer.colouring {
            Colouring::MeshColours => per_vertex(mesh.vertex_colors.as_deref().unwrap_or(&[])),
            Colouring::PerVertex(colours) => per_vertex(colours),
            Colouring::Uniform(colour) => Albedo::Uniform(srgb_colour_to_linear(colour)),
            Colouring::Texture(texture) => match &mesh.uv {
                Some(uv) => Albedo::Texture { uv, texture },
                // Validation rejects a texture without texture coordinates.
                None => Albedo::Uniform(srgb_colour_to_linear(crate::SKIN_TONE)),
            },
        };
        PreparedLayer {
            mesh,
            vertices,
            triangles: &mesh.triangles,
            normals,
            albedo,
            opacity: layer.opacity as f32,
            first_id,
        }
    }

    /// Whether triangle `t` passes within `tolerance_mm` of `point` (mm, file frame): near
    /// its plane and its corners.
    pub fn passes_near(&self, t: usize, point: DVec3, tolerance_mm: f64) -> bool {
        let corners = self.mesh.triangle_positions(t);
        let centroid = (corners[0] + corners[1] + corners[2]) / 3.0;
        let radius = corners
            .iter()
            .map(|c| c.distance(centroid))
            .fold(0.0, f64::max);
        let off_plane = (point - centroid).dot(self.mesh.triangle_normal(t)).abs();
        off_plane <= tolerance_mm && point.distance(centroid) <= radius + tolerance_mm
    }

    /// The colour (linear RGB) of triangle `t` at sample position `(x, y)`.
    pub fn shade(&self, t: usize, x: f32, y: f32, shading: Shading) -> [f32; 3] {
        let corners = self.triangles[t];
        let [a, b, c] = corners.map(|v| self.vertices[v as usize]);
        let (ab, ac) = ((b.x - a.x, b.y - a.y), (c.x - a.x, c.y - a.y));
        let ap = (x - a.x, y - a.y);
        let twice_area = ab.0 * ac.1 - ac.0 * ab.1;
        let wb = (ap.0 * ac.1 - ac.0 * ap.1) / twice_area;
        let wc = (ab.0 * ap.1 - ap.0 * ab.1) / twice_area;
        // Samples on an edge can fall a rounding error outside: clamp, then weigh each
        // corner for perspective-correct interpolation.
        let screen_weights = [1.0 - wb - wc, wb, wc].map(|w| w.max(0.0));
        let weighted = [
            screen_weights[0] * a.attribute_weight,
            screen_weights[1] * b.attribute_weight,
            screen_weights[2] * c.attribute_weight,
        ];
        let total = weighted[0] + weighted[1] + weighted[2];
        let weights = if total > 0.0 {
            weighted.map(|w| w / total)
        } else {
            [1.0 / 3.0; 3]
        };
        let albedo = self.albedo(t, corners, weights);
        // Triangles run counter-clockwise seen from outside; on a y-down grid that is a
        // negative signed area.
        let front_facing = twice_area < 0.0;
        let albedo = if front_facing {
            albedo
        } else {
            std::array::from_fn(|k| albedo[k] + BACK_FACE_MIX * (BACK_FACE_GREY[k] - albedo[k]))
        };
        match shading {
            Shading::Unlit => albedo,
            Shading::Lit => {
                let normal = corners
                    .iter()
                    .zip(weights)
                    .map(|(&v, w)| w * self.normals[v as usize])
                    .sum::<Vec3>();
                let normal = if front_facing { normal } else { -normal };
                light(albedo, normal.try_normalize().unwrap_or(Vec3::Z))
            }
        }
    }

    fn albedo(&self, t: usize, corners: [u32; 3], weights: [f32; 3]) -> [f32; 3] {
        match &self.albedo {
            Albedo::Uniform(colour) => *colour,
            Albedo::PerVertex(colours) => {
                let [a, b, c] = corners.map(|v| colours[v as usize]);
                std::array::from_fn(|k| weights[0] * a[k] + weights[1] * b[k] + weights[2] * c[k])
            }
            Albedo::Texture { uv, texture } => {
                let [a, b, c] = uv.triangles[t].map(|i| uv.coords[i as usize].as_vec2());
                let coords = weights[0] * a + weights[1] * b + weights[2] * c;
                texture.sample_linear(coords.x, coords.y)
            }
        }
    }
}

/// The layer drawn with triangle id `id` and the triangle's index in its mesh; `layers`
/// are in the order of their first ids.
pub(crate) fn locate<'l, 'a>(
    layers: &'l [PreparedLayer<'a>],
    id: u32,
) -> (&'l PreparedLayer<'a>, usize) {
    let layer = &layers[layers.partition_point(|layer| layer.first_id <= id) - 1];
    (layer, (id - layer.first_id) as usize)
}

/// Unit light directions in screen axes.
struct Lights {
    key: Vec3,
    fill: Vec3,
    /// Halfway between the key light and the viewer (+z), for the highlight.
    half_way: Vec3,
}

static LIGHTS: LazyLock<Lights> = LazyLock::new(|| Lights {
    key: KEY_DIRECTION.normalize(),
    fill: FILL_DIRECTION.normalize(),
    half_way: (KEY_DIRECTION.normalize() + Vec3::Z).normalize(),
});

/// Lambert key and fill light plus a soft highlight, for a unit `normal` in screen axes
/// seen along -z.
fn light(albedo: [f32; 3], normal: Vec3) -> [f32; 3] {
    let lights = &*LIGHTS;
    let key = normal.dot(lights.key).max(0.0);
    let fill = normal.dot(lights.fill).max(0.0);
    let diffuse = AMBIENT + KEY * key + FILL * fill;
    let highlight = if key > 0.0 {
        SPECULAR * normal.dot(lights.half_way).max(0.0).powi(SHININESS)
    } else {
        0.0
    };
    albedo.map(|c| c * diffuse + highlight)
}

/// How a surface's colour is shown.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shading {
    /// Lit by a key and a fill light with a soft highlight: shows the shape.
    Lit,
    /// The colour as it is: exact colour-map values, no shape.
    Unlit,
}
