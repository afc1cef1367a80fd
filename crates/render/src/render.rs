//! [`render`]: a scene through a camera into an image.

use crate::RenderError;
use crate::camera::Camera;
use crate::colour::{linear_to_srgb, srgb_colour_to_linear};
use crate::image::Image;
use crate::overlay;
use crate::overlay::MarkerPlacement;
use crate::raster::{NO_TRIANGLE, SampleBuffer, depth_key, key_depth_mm};
use crate::scene::Scene;
use crate::shade::{PreparedLayer, Shading, locate};
use glam::{Vec3, Vec4};
use rayon::prelude::*;

/// A translucent layer shows also where it lies up to this far behind the opaque
/// surfaces (mm): two scans of one body differ by their noise (0.2 mm on the shared
/// scans) and would otherwise show through each other in specks.
const TRANSLUCENT_DEPTH_OFFSET_MM: f64 = 1.0;
/// Largest supersampling factor (samples per pixel side).
const MAX_SUPERSAMPLING: u32 = 4;
/// Largest number of samples (width × height × supersampling²): about 0.5 GB per depth
/// buffer.
const MAX_SAMPLES: u64 = 1 << 26;

/// Picture settings.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Samples per pixel side (1 to 4): 2 gives 4 samples per pixel, smooth edges.
    pub supersampling: u32,
    /// sRGB and alpha where no surface is.
    pub background: [u8; 4],
    pub shading: Shading,
    /// Radius of a marker's disc (pixels).
    pub marker_radius_px: f64,
}

impl Default for RenderOptions {
    fn default() -> RenderOptions {
        RenderOptions {
            supersampling: 2,
            background: [255, 255, 255, 255],
            shading: Shading::Lit,
            marker_radius_px: 5.0,
        }
    }
}

/// A rendered picture and where its markers are.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendering {
    pub image: Image,
    /// One per marker of the scene, in order.
    pub markers: Vec<MarkerPlacement>,
}

/// Renders `scene` through `camera` into a `width` × `height` picture: opaque layers
/// depth-tested, translucent layers blended over them (each layer's nearest surface),
/// then polylines and markers on top where they are not hidden.
pub fn render(
    scene: &Scene,
    camera: &Camera,
    width: u32,
    height: u32,
    options: &RenderOptions,
) -> Result<Rendering, RenderError> {
    check_size(width, height, options.supersampling)?;
    camera.validate()?;
    scene.validate()?;
    let drawn = || scene.layers.iter().filter(|layer| layer.opacity > 0.0);
    let count: usize = drawn().map(|layer| layer.mesh.triangle_count()).sum();
    if count >= NO_TRIANGLE as usize {
        return Err(RenderError::TooManyTriangles { count });
    }
    let supersampling = options.supersampling as usize;
    let (sample_width, sample_height) = (
        width as usize * supersampling,
        height as usize * supersampling,
    );

    let mut first_id = 0;
    let layers: Vec<PreparedLayer> = drawn()
        .map(|layer| {
            let prepared = PreparedLayer::new(
                layer,
                camera,
                sample_width as f64,
                sample_height as f64,
                first_id,
            );
            first_id += layer.mesh.triangle_count() as u32;
            prepared
        })
        .collect();
    let mut opaque = SampleBuffer::new(sample_width, sample_height);
    for layer in layers.iter().filter(|l| l.opacity >= 1.0) {
        opaque.rasterise(&layer.vertices, layer.triangles, layer.first_id);
    }
    let translucent: Vec<SampleBuffer> = layers
        .iter()
        .filter(|l| l.opacity < 1.0)
        .map(|layer| {
            let mut buffer = SampleBuffer::in_front_of(&opaque, |key| {
                if key == f32::INFINITY {
                    return key; // no opaque surface
                }
                let depth_mm = key_depth_mm(camera.projection, key);
                depth_key(camera.projection, depth_mm + TRANSLUCENT_DEPTH_OFFSET_MM)
            });
            buffer.rasterise(&layer.vertices, layer.triangles, layer.first_id);
            buffer
        })
        .collect();

    let mut image = Image::filled(width, height, options.background);
    Resolve {
        layers: &layers,
        opaque: &opaque,
        translucent: &translucent,
        supersampling,
        shading: options.shading,
        background: options.background,
    }
    .shade_into(&mut image);
    let markers = overlay::draw(
        &mut image,
        scene,
        camera,
        &opaque,
        &layers,
        supersampling,
        options.marker_radius_px,
    );
    Ok(Rendering { image, markers })
}

fn check_size(width: u32, height: u32, supersampling: u32) -> Result<(), RenderError> {
    if width == 0 || height == 0 {
        return Err(RenderError::EmptyImage { width, height });
    }
    if !(1..=MAX_SUPERSAMPLING).contains(&supersampling) {
        return Err(RenderError::Supersampling {
            found: supersampling,
            max: MAX_SUPERSAMPLING,
        });
    }
    let samples = u64::from(width) * u64::from(height) * u64::from(supersampling).pow(2);
    if samples > MAX_SAMPLES {
        return Err(RenderError::ImageTooLarge {
            width,
            height,
            supersampling,
            max_samples: MAX_SAMPLES,
        });
    }
    Ok(())
}

/// Shades every pixel's samples and averages them. Each triangle seen in a pixel is
/// shaded once, at the centroid of its samples there (as multisampling does on a GPU):
/// the colour varies little across a pixel, the shading is the costly part.
struct Resolve<'a> {
    layers: &'a [PreparedLayer<'a>],
    opaque: &'a SampleBuffer,
    translucent: &'a [SampleBuffer],
    supersampling: usize,
    shading: Shading,
    background: [u8; 4],
}

/// A triangle seen in a pixel: where its samples are (summed) and its colour there.
struct PixelHit {
    id: u32,
    position_sum: [f32; 2],
    samples: f32,
    /// Linear RGB.
    colour: Vec3,
}

impl Resolve<'_> {
    fn shade_into(&self, image: &mut Image) {
        let width = image.width() as usize;
        let s = self.supersampling;
        let [r, g, b, a] = self.background;
        let background_alpha = f32::from(a) / 255.0;
        let background =
            Vec3::from_array(srgb_colour_to_linear([r, g, b])).extend(1.0) * background_alpha;
        let samples_per_pixel = (s * s) as f32;
        image
            .rgba_mut()
            .par_chunks_mut(4 * width)
            .enumerate()
            .for_each(|(row, pixels)| {
                let mut hits: Vec<PixelHit> = Vec::new();
                let mut in_front = Vec::with_capacity(self.translucent.len());
                for (column, pixel) in pixels.chunks_exact_mut(4).enumerate() {
                    let samples = (row * s..(row + 1) * s)
                        .flat_map(|y| (column * s..(column + 1) * s).map(move |x| (x, y)));
                    hits.clear();
                    let mut empty_samples = 0.0;
                    for (x, y) in samples.clone() {
                        let index = self.opaque.index(x, y);
                        let opaque_id = self.opaque.id[index];
                        empty_samples += f32::from(u8::from(opaque_id == NO_TRIANGLE));
                        let layer_ids = self.translucent.iter().map(|buffer| buffer.id[index]);
                        for id in std::iter::once(opaque_id).chain(layer_ids) {
                            if id != NO_TRIANGLE {
                                record_hit(&mut hits, id, x, y);
                            }
                        }
                    }
                    if hits.is_empty() {
                        // The image is filled with the background already.
                        continue;
                    }
                    for hit in &mut hits {
                        let [x, y] = hit.position_sum.map(|p| p / hit.samples + 0.5);
                        let (layer, t) = locate(self.layers, hit.id);
                        hit.colour = Vec3::from_array(layer.shade(t, x, y, self.shading));
                    }
                    let sum: Vec4 = if self.translucent.is_empty() {
                        // Opaque surfaces only: each triangle's colour counts once per
                        // sample it covers.
                        hits.iter().fold(background * empty_samples, |sum, hit| {
                            sum + hit.colour.extend(1.0) * hit.samples
                        })
                    } else {
                        samples
                            .map(|(x, y)| {
                                let index = self.opaque.index(x, y);
                                self.composite(index, &hits, background, &mut in_front)
                            })
                            .sum()
                    };
                    let alpha = sum.w / samples_per_pixel;
                    if alpha > 0.0 {
                        let colour = sum.truncate() / sum.w;
                        pixel[..3].copy_from_slice(&colour.to_array().map(linear_to_srgb));
                    }
                    pixel[3] = (255.0 * alpha + 0.5) as u8;
                }
            });
    }

    /// Premultiplied linear RGBA of sample `index`: the opaque surface (or the background)
    /// with the translucent layers in front of it blended over, farthest first. `hits`
    /// hold the colours of the pixel's triangles; `in_front` is scratch space.
    fn composite(
        &self,
        index: usize,
        hits: &[PixelHit],
        background: Vec4,
        in_front: &mut Vec<(f32, u32)>,
    ) -> Vec4 {
        let colour_of = |id| {
            hits.iter()
                .find(|hit| hit.id == id)
                .map_or(Vec3::ZERO, |hit| hit.colour)
        };
        let mut premultiplied = match self.opaque.id[index] {
            NO_TRIANGLE => background,
            id => colour_of(id).extend(1.0),
        };
        in_front.clear();
        in_front.extend(
            self.translucent
                .iter()
                .filter(|buffer| buffer.id[index] != NO_TRIANGLE)
                .map(|buffer| (buffer.key[index], buffer.id[index])),
        );
        in_front.sort_by(|a, b| b.0.total_cmp(&a.0));
        for &(_, id) in in_front.iter() {
            let opacity = locate(self.layers, id).0.opacity;
            premultiplied = premultiplied.lerp(colour_of(id).extend(1.0), opacity);
        }
        premultiplied
    }
}

/// Counts sample `(x, y)` for triangle `id` among the pixel's hits.
fn record_hit(hits: &mut Vec<PixelHit>, id: u32, x: usize, y: usize) {
    let position = [x as f32, y as f32];
    match hits.iter_mut().find(|hit| hit.id == id) {
        Some(hit) => {
            hit.position_sum[0] += position[0];
            hit.position_sum[1] += position[1];
            hit.samples += 1.0;
        }
        None => hits.push(PixelHit {
            id,
            position_sum: position,
            samples: 1.0,
            colour: Vec3::ZERO,
        }),
    }
}
