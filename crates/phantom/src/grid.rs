//! The sampling grid of the scan: columns of constant azimuth and rows of constant
//! height, denser where the surface is steep (shoulders) or detailed (breasts), with
//! grid lines pinned through every landmark so that landmarks are mesh vertices.

use crate::breast::Breast;
use crate::shape::{Warp, smoothstep};
use crate::surface::{SurfaceSample, THETA_MAX, TorsoSurface};
use crate::torso::{BOTTOM_HEIGHT_MM, TOP_HEIGHT_MM, base_point};
use glam::DVec3;
use mesh::TriMesh;

/// Grid columns on each side of the midline (the midline column is shared).
const HALF_COLUMNS: usize = 210;
/// Grid rows.
const ROWS: usize = 345;
/// Extra sampling density over the breasts (1 = twice as dense).
const BREAST_REFINEMENT: f64 = 0.9;
/// Further sampling density over the lower pole and the fold crease.
const LOWER_POLE_REFINEMENT: f64 = 1.5;
/// Margin around a breast footprint that is sampled densely (mm).
const REFINEMENT_MARGIN_MM: f64 = 15.0;
/// Samples of the density tables.
const DENSITY_SAMPLES: usize = 2048;

/// Grid line values: azimuths (rad) of the columns and heights (mm) of the rows, both
/// increasing.
pub struct Grid {
    pub thetas: Vec<f64>,
    pub heights: Vec<f64>,
}

impl Grid {
    /// A grid over the scan whose lines pass exactly through `pins`, a list of
    /// `(theta, h)` parameter points.
    pub fn new(surface: &TorsoSurface, pins: &[(f64, f64)]) -> Grid {
        let [left, right] = &surface.breasts;
        let left_half = half_columns(surface, left, pins, 1.0);
        let right_half = half_columns(surface, right, pins, -1.0);
        let thetas: Vec<f64> = right_half
            .iter()
            .rev()
            .map(|&theta| -theta)
            .chain(left_half.into_iter().skip(1))
            .collect();

        // The band below the fold takes in the lower pole hanging over it with ptosis.
        let fold = |b: &Breast| b.center_height_mm - b.shape.lower_mm - 2.0 * REFINEMENT_MARGIN_MM;
        let breasts = &surface.breasts;
        let warp = Warp::new(BOTTOM_HEIGHT_MM, TOP_HEIGHT_MM, DENSITY_SAMPLES, |h| {
            let breast = band(breasts, h, |b| {
                (fold(b), b.center_height_mm + b.shape.upper_mm)
            });
            let lower_pole = band(breasts, h, |b| (fold(b), b.center_height_mm));
            vertical_stretch(h)
                * (1.0 + BREAST_REFINEMENT * breast + LOWER_POLE_REFINEMENT * lower_pole)
        });
        let mut heights: Vec<f64> = (0..ROWS)
            .map(|j| warp.at(j as f64 / (ROWS - 1) as f64))
            .collect();
        let row_pins: Vec<f64> = pins.iter().map(|&(_, h)| h).collect();
        pin_lines(&mut heights, &row_pins);
        Grid { thetas, heights }
    }

    /// Index of the vertex on the grid lines nearest to `theta` and `h` (exactly at
    /// `(theta, h)` for a pinned point).
    pub fn nearest_vertex(&self, theta: f64, h: f64) -> usize {
        nearest_line(&self.heights, h) * self.thetas.len() + nearest_line(&self.thetas, theta)
    }

    /// The texture coordinates of every grid vertex (in the order of [`Grid::mesh`]'s).
    pub fn uv(&self) -> Vec<glam::DVec2> {
        self.heights
            .iter()
            .flat_map(|&h| {
                self.thetas
                    .iter()
                    .map(move |&theta| crate::texture::uv_of(theta, h))
            })
            .collect()
    }

    /// A mesh of one layer of the surface (`layer` picks the skin or the chest wall of
    /// each sample) at every grid point, shifted by `-origin`, two triangles per cell
    /// split along the shorter diagonal, oriented outwards.
    pub fn mesh(
        &self,
        surface: &TorsoSurface,
        origin: DVec3,
        layer: fn(&SurfaceSample) -> DVec3,
    ) -> TriMesh {
        let columns = self.thetas.len();
        let positions: Vec<DVec3> = self
            .heights
            .iter()
            .flat_map(|&h| self.thetas.iter().map(move |&theta| (theta, h)))
            .map(|(theta, h)| layer(&surface.sample(theta, h)) - origin)
            .collect();
        let mut triangles = Vec::with_capacity(2 * (columns - 1) * (self.heights.len() - 1));
        for j in 0..self.heights.len() - 1 {
            for i in 0..columns - 1 {
                // Corners counter-clockwise seen from outside: +theta is +x, +h is +y.
                let a = (j * columns + i) as u32;
                let b = a + 1;
                let c = b + columns as u32;
                let d = a + columns as u32;
                let p = |v: u32| positions[v as usize];
                if p(a).distance_squared(p(c)) <= p(b).distance_squared(p(d)) {
                    triangles.push([a, b, c]);
                    triangles.push([a, c, d]);
                } else {
                    triangles.push([a, b, d]);
                    triangles.push([b, c, d]);
                }
            }
        }
        TriMesh::new(positions, triangles)
    }
}

/// Column azimuths `0 ..= THETA_MAX` on one side (`side` = +1 left, -1 right), denser over
/// the breast of that side, pinned through the pins of that side.
fn half_columns(
    surface: &TorsoSurface,
    breast: &Breast,
    pins: &[(f64, f64)],
    side: f64,
) -> Vec<f64> {
    let breast_columns = |theta: f64| -> f64 {
        let s = surface.arc.arc(theta) - breast.center_arc_mm;
        let medial = -breast.shape.medial_mm - REFINEMENT_MARGIN_MM;
        let lateral = breast.shape.lateral_mm + REFINEMENT_MARGIN_MM;
        smoothstep(medial - REFINEMENT_MARGIN_MM, medial, s)
            * (1.0 - smoothstep(lateral, lateral + REFINEMENT_MARGIN_MM, s))
    };
    let step = THETA_MAX / DENSITY_SAMPLES as f64;
    let warp = Warp::new(0.0, THETA_MAX, DENSITY_SAMPLES, |theta| {
        let arc_rate =
            (surface.arc.arc(theta + step) - surface.arc.arc(theta - step)).abs() / (2.0 * step);
        arc_rate * (1.0 + BREAST_REFINEMENT * breast_columns(theta))
    });
    let mut thetas: Vec<f64> = (0..=HALF_COLUMNS)
        .map(|k| warp.at(k as f64 / HALF_COLUMNS as f64))
        .collect();
    let side_pins: Vec<f64> = pins
        .iter()
        .filter(|&&(theta, _)| theta * side > 0.0)
        .map(|&(theta, _)| theta.abs())
        .collect();
    pin_lines(&mut thetas, &side_pins);
    thetas
}

/// 1 where height `h` is inside the range `(bottom, top)` (mm) of either breast, fading
/// to 0 over the refinement margin above and below.
fn band(breasts: &[Breast; 2], h: f64, range: impl Fn(&Breast) -> (f64, f64)) -> f64 {
    breasts
        .iter()
        .map(|breast| {
            let (bottom, top) = range(breast);
            smoothstep(bottom - REFINEMENT_MARGIN_MM, bottom, h)
                * (1.0 - smoothstep(top, top + REFINEMENT_MARGIN_MM, h))
        })
        .fold(0.0, f64::max)
}

/// Mean rate of change of surface position with height across the scanned azimuths:
/// large where the shoulders slope into the neck.
fn vertical_stretch(h: f64) -> f64 {
    const AZIMUTHS: [f64; 6] = [0.0, 0.4, 0.8, 1.2, 1.55, 1.9];
    const D_H: f64 = 0.5;
    AZIMUTHS
        .iter()
        .map(|&theta| base_point(theta, h + D_H).distance(base_point(theta, h - D_H)) / (2.0 * D_H))
        .sum::<f64>()
        / AZIMUTHS.len() as f64
}

/// Moves, for each distinct value in `pins`, the nearest free interior line of the sorted
/// `lines` onto it, then re-sorts. The first and last lines stay.
fn pin_lines(lines: &mut [f64], pins: &[f64]) {
    let mut pins = pins.to_vec();
    pins.sort_by(f64::total_cmp);
    pins.dedup();
    let last = lines.len() - 1;
    let mut pinned = vec![false; lines.len()];
    pinned[0] = true;
    pinned[last] = true;
    for &value in &pins {
        if let Some(k) = lines.iter().position(|&line| line == value) {
            pinned[k] = true;
            continue;
        }
        let nearest = (1..last).filter(|&k| !pinned[k]).min_by(|&a, &b| {
            (lines[a] - value)
                .abs()
                .total_cmp(&(lines[b] - value).abs())
        });
        if let Some(k) = nearest {
            lines[k] = value;
            pinned[k] = true;
        }
    }
    lines.sort_by(f64::total_cmp);
}

/// Index of the value in the sorted `lines` nearest to `value`.
fn nearest_line(lines: &[f64], value: f64) -> usize {
    let above = lines
        .partition_point(|&line| line < value)
        .min(lines.len() - 1);
    if above > 0 && value - lines[above - 1] < lines[above] - value {
        above - 1
    } else {
        above
    }
}
