//! The depth-buffered triangle rasteriser: which triangle is nearest at each sample.
//!
//! Samples sit at the centres of a grid of unit cells (`(i + 0.5, j + 0.5)`). A sample
//! belongs to a triangle when it is inside or on its edges. An edge two triangles share is
//! evaluated from the same vertex order for both (the lower vertex index first), so the
//! two values are exact negatives and no sample between them falls through a crack.
//! Rows are split into bands; each band takes the triangles reaching into it and runs on
//! its own core. [`screen_vertex`] projects a point onto the sample grid.

use crate::camera::{Camera, Projection};
use glam::DVec3;
use rayon::prelude::*;

/// The id of a sample no triangle covers.
pub(crate) const NO_TRIANGLE: u32 = u32::MAX;
/// Sample rows per band of work.
const BAND_ROWS: usize = 16;

/// A vertex on the sample grid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ScreenVertex {
    /// Sample coordinates (x right, y down); NaN for a vertex that cannot be drawn.
    pub x: f32,
    pub y: f32,
    /// Depth key, linear across the screen: larger is farther.
    pub key: f32,
    /// Weight of the vertex's attributes in perspective-correct interpolation (1 for an
    /// orthographic camera).
    pub attribute_weight: f32,
}

/// Per sample, the nearest depth key and the triangle id drawn there.
pub(crate) struct SampleBuffer {
    pub width: usize,
    pub height: usize,
    pub key: Vec<f32>,
    pub id: Vec<u32>,
}

impl SampleBuffer {
    /// An empty buffer: infinitely far, no triangle.
    pub fn new(width: usize, height: usize) -> SampleBuffer {
        SampleBuffer {
            width,
            height,
            key: vec![f32::INFINITY; width * height],
            id: vec![NO_TRIANGLE; width * height],
        }
    }

    /// A buffer for what lies in front of `opaque`, or behind it by less than the
    /// depth keys `behind` gives: those depths, no triangles.
    pub fn in_front_of(opaque: &SampleBuffer, behind: impl Fn(f32) -> f32 + Sync) -> SampleBuffer {
        SampleBuffer {
            width: opaque.width,
            height: opaque.height,
            key: opaque.key.par_iter().map(|&key| behind(key)).collect(),
            id: vec![NO_TRIANGLE; opaque.id.len()],
        }
    }

    /// Draws `triangles` (indices into `vertices`) with ids `first_id + t`, keeping the
    /// nearest at each sample.
    pub fn rasterise(&mut self, vertices: &[ScreenVertex], triangles: &[[u32; 3]], first_id: u32) {
        let width = self.width;
        let bands = Bands::bin(vertices, triangles, width, self.height);
        self.key
            .par_chunks_mut(BAND_ROWS * width)
            .zip(self.id.par_chunks_mut(BAND_ROWS * width))
            .enumerate()
            .for_each(|(band, (keys, ids))| {
                let first_row = band * BAND_ROWS;
                let end_row = first_row + keys.len() / width;
                let mut target = BandTarget {
                    keys,
                    ids,
                    width,
                    first_row,
                    end_row,
                };
                for &t in bands.triangles(band) {
                    let corners = triangles[t as usize];
                    target.draw(vertices, corners, first_id + t);
                }
            });
    }

    /// The sample index at column `x`, row `y`.
    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }
}

/// Triangles listed by the bands of rows they reach into (a counting sort).
struct Bands {
    /// `offsets[b]..offsets[b + 1]` indexes `triangles` for band `b`.
    offsets: Vec<usize>,
    triangles: Vec<u32>,
}

impl Bands {
    fn bin(
        vertices: &[ScreenVertex],
        triangles: &[[u32; 3]],
        width: usize,
        height: usize,
    ) -> Bands {
        let band_count = height.div_ceil(BAND_ROWS);
        let ranges: Vec<Option<(usize, usize)>> = triangles
            .par_iter()
            .map(|corners| {
                let [a, b, c] = corners.map(|v| vertices[v as usize]);
                let rows =
                    SampleRange::covering(a.y.min(b.y).min(c.y), a.y.max(b.y).max(c.y), height)?;
                // Also skip triangles left or right of the image.
                SampleRange::covering(a.x.min(b.x).min(c.x), a.x.max(b.x).max(c.x), width)?;
                Some((rows.first / BAND_ROWS, rows.last / BAND_ROWS))
            })
            .collect();
        let mut offsets = vec![0usize; band_count + 1];
        for &(first, last) in ranges.iter().flatten() {
            for band in first..=last {
                offsets[band + 1] += 1;
            }
        }
        for band in 0..band_count {
            offsets[band + 1] += offsets[band];
        }
        let mut fill = offsets.clone();
        let mut binned = vec![0u32; offsets[band_count]];
        for (t, range) in ranges.iter().enumerate() {
            if let Some((first, last)) = *range {
                for band in first..=last {
                    binned[fill[band]] = t as u32;
                    fill[band] += 1;
                }
            }
        }
        Bands {
            offsets,
            triangles: binned,
        }
    }

    fn triangles(&self, band: usize) -> &[u32] {
        &self.triangles[self.offsets[band]..self.offsets[band + 1]]
    }
}

/// The samples whose centres lie in `[min, max]` along one axis, within `0..count`.
struct SampleRange {
    first: usize,
    last: usize,
}

impl SampleRange {
    fn covering(min: f32, max: f32, count: usize) -> Option<SampleRange> {
        // NaN fails both comparisons and so is skipped.
        if !(max >= 0.5 && min <= count as f32 - 0.5) {
            return None;
        }
        let first = (min - 0.5).ceil().max(0.0) as usize;
        let last = ((max - 0.5).floor() as usize).min(count - 1);
        (first <= last).then_some(SampleRange { first, last })
    }
}

/// One edge function `e(p) = sign · ((x1 - x0)(p.y - y0) - (y1 - y0)(p.x - x0))`, with
/// `(x0, y0)` the end with the lower vertex index.
#[derive(Clone, Copy)]
struct Edge {
    x0: f32,
    y0: f32,
    dx: f32,
    dy: f32,
    sign: f32,
}

impl Edge {
    fn new(from: (u32, ScreenVertex), to: (u32, ScreenVertex)) -> Edge {
        let (start, end, sign) = if from.0 < to.0 {
            (from.1, to.1, 1.0)
        } else {
            (to.1, from.1, -1.0)
        };
        Edge {
            x0: start.x,
            y0: start.y,
            dx: end.x - start.x,
            dy: end.y - start.y,
            sign,
        }
    }

    /// The same edge with its sign times `orientation` (±1: exact).
    fn oriented(self, orientation: f32) -> Edge {
        Edge {
            sign: self.sign * orientation,
            ..self
        }
    }

    #[inline]
    fn at(&self, x: f32, y: f32) -> f32 {
        self.at_row(self.row_term(y), x)
    }

    /// The part of the edge function that depends on the row only.
    #[inline]
    fn row_term(&self, y: f32) -> f32 {
        self.dx * (y - self.y0)
    }

    /// The edge function at column `x` of the row with `row_term` (the same operations as
    /// [`Edge::at`], so the same value).
    #[inline]
    fn at_row(&self, row_term: f32, x: f32) -> f32 {
        self.sign * (row_term - self.dy * (x - self.x0))
    }
}

/// The rows of one band of a sample buffer.
struct BandTarget<'a> {
    keys: &'a mut [f32],
    ids: &'a mut [u32],
    width: usize,
    first_row: usize,
    end_row: usize,
}

impl BandTarget<'_> {
    fn draw(&mut self, vertices: &[ScreenVertex], corners: [u32; 3], id: u32) {
        let [a, b, c] = corners.map(|v| (v, vertices[v as usize]));
        // Each edge is named by the corner opposite it: its value over twice the area is
        // that corner's barycentric coordinate.
        let edges = [Edge::new(b, c), Edge::new(c, a), Edge::new(a, b)];
        let twice_area = edges[0].at(a.1.x, a.1.y);
        // Skips degenerate triangles and NaN (a vertex that cannot be drawn).
        if !(twice_area.abs() > 0.0 && twice_area.is_finite()) {
            return;
        }
        // Oriented so that inside all three are non-negative.
        let edges = edges.map(|edge| edge.oriented(twice_area.signum()));
        let keys = [a.1.key, b.1.key, c.1.key].map(|k| k / twice_area.abs());
        let (xs, ys) = ([a.1.x, b.1.x, c.1.x], [a.1.y, b.1.y, c.1.y]);
        let (Some(columns), Some(rows)) = (
            SampleRange::covering(min3(xs), max3(xs), self.width),
            SampleRange::covering(min3(ys), max3(ys), self.end_row),
        ) else {
            return;
        };
        for row in rows.first.max(self.first_row)..=rows.last {
            let y = row as f32 + 0.5;
            let row_terms = edges.map(|edge| edge.row_term(y));
            let line = (row - self.first_row) * self.width;
            for column in columns.first..=columns.last {
                let x = column as f32 + 0.5;
                let e = [0, 1, 2].map(|k| edges[k].at_row(row_terms[k], x));
                if e[0] >= 0.0 && e[1] >= 0.0 && e[2] >= 0.0 {
                    let key = e[0] * keys[0] + e[1] * keys[1] + e[2] * keys[2];
                    let sample = line + column;
                    if key < self.keys[sample] {
                        self.keys[sample] = key;
                        self.ids[sample] = id;
                    }
                }
            }
        }
    }
}

fn min3(v: [f32; 3]) -> f32 {
    v[0].min(v[1]).min(v[2])
}

fn max3(v: [f32; 3]) -> f32 {
    v[0].max(v[1]).max(v[2])
}

/// A point on a sample grid of `width` × `height` for the rasteriser: x and y in samples,
/// its [`depth_key`], NaN where it cannot be drawn.
pub(crate) fn screen_vertex(
    camera: &Camera,
    point: DVec3,
    width: f64,
    height: f64,
) -> ScreenVertex {
    match camera.project(point, width, height) {
        Some(projected) => {
            let attribute_weight = match camera.projection {
                Projection::Orthographic => 1.0,
                Projection::Perspective { .. } => 1.0 / projected.depth_mm,
            };
            ScreenVertex {
                x: projected.pixel.x as f32,
                y: projected.pixel.y as f32,
                key: depth_key(camera.projection, projected.depth_mm),
                attribute_weight: attribute_weight as f32,
            }
        }
        None => ScreenVertex {
            x: f32::NAN,
            y: f32::NAN,
            key: f32::NAN,
            attribute_weight: 0.0,
        },
    }
}

/// The depth key of a depth (mm, as [`crate::ProjectedPoint::depth_mm`]): the depth for
/// an orthographic camera, minus its reciprocal for a perspective one (linear across the
/// screen, larger farther).
pub(crate) fn depth_key(projection: Projection, depth_mm: f64) -> f32 {
    match projection {
        Projection::Orthographic => depth_mm as f32,
        Projection::Perspective { .. } => (-1.0 / depth_mm) as f32,
    }
}

/// The depth (mm, as [`crate::ProjectedPoint::depth_mm`]) of a depth key of
/// [`screen_vertex`].
pub(crate) fn key_depth_mm(projection: Projection, key: f32) -> f64 {
    match projection {
        Projection::Orthographic => f64::from(key),
        Projection::Perspective { .. } => -1.0 / f64::from(key),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vertex(x: f32, y: f32, key: f32) -> ScreenVertex {
        ScreenVertex {
            x,
            y,
            key,
            attribute_weight: 1.0,
        }
    }

    #[test]
    fn a_fan_of_triangles_covers_every_sample_of_its_square_once_without_cracks() {
        // A 40x40 square split into a fan of 64 thin triangles around an off-grid
        // centre: every sample inside must get a triangle, none outside.
        let size = 48;
        let centre = vertex(21.37, 19.61, 0.0);
        let mut vertices = vec![centre];
        let border: Vec<(f32, f32)> = (0..16)
            .map(|i| (4.0 + 2.5 * i as f32, 4.0))
            .chain((0..16).map(|i| (44.0, 4.0 + 2.5 * i as f32)))
            .chain((0..16).map(|i| (44.0 - 2.5 * i as f32, 44.0)))
            .chain((0..16).map(|i| (4.0, 44.0 - 2.5 * i as f32)))
            .collect();
        vertices.extend(border.iter().map(|&(x, y)| vertex(x, y, 1.0)));
        let ring = border.len() as u32;
        let triangles: Vec<[u32; 3]> = (0..ring).map(|i| [0, 1 + i, 1 + (i + 1) % ring]).collect();
        let mut buffer = SampleBuffer::new(size, size);
        buffer.rasterise(&vertices, &triangles, 0);
        for y in 0..size {
            for x in 0..size {
                let inside = (4..44).contains(&x) && (4..44).contains(&y);
                let id = buffer.id[buffer.index(x, y)];
                assert_eq!(id != NO_TRIANGLE, inside, "sample ({x}, {y})");
            }
        }
    }

    #[test]
    fn the_nearer_triangle_wins_whatever_the_order() {
        let vertices = [
            vertex(0.0, 0.0, 5.0),
            vertex(8.0, 0.0, 5.0),
            vertex(0.0, 8.0, 5.0),
            vertex(0.0, 0.0, 2.0),
            vertex(8.0, 0.0, 2.0),
            vertex(0.0, 8.0, 2.0),
        ];
        for triangles in [[[0, 1, 2], [3, 4, 5]], [[3, 5, 4], [0, 1, 2]]] {
            let mut buffer = SampleBuffer::new(8, 8);
            buffer.rasterise(&vertices, &triangles, 10);
            let near = 10 + triangles.iter().position(|t| t[0] == 3).unwrap() as u32;
            assert_eq!(buffer.id[buffer.index(1, 1)], near);
            assert!((buffer.key[buffer.index(1, 1)] - 2.0).abs() < 1e-6);
        }
    }
}
