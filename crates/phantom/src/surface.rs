//! The whole parametric scan surface: torso, relief and both breasts, evaluated at
//! `(theta, h)`, together with the chest wall beneath the breasts.

use crate::breast::Breast;
use crate::shape::interpolate;
use crate::torso::{base_normal, base_point, relief};
use glam::DVec3;

/// Azimuth of the scan's side edges (rad): 110° either side of the front, as seen by
/// cameras at -30°, 0° and +30°.
pub const THETA_MAX: f64 = 110.0 * std::f64::consts::PI / 180.0;
/// Height at which footprint arc lengths are measured (mm, at the nipples).
const REFERENCE_HEIGHT_MM: f64 = -165.0;
/// Number of intervals of the arc length table.
const ARC_SAMPLES: usize = 4096;

/// Arc length along the trunk's cross-section at the reference height, from the front
/// midline, as a function of the azimuth (odd in `theta`).
pub struct ArcTable {
    theta: Vec<f64>,
    arc_mm: Vec<f64>,
}

impl ArcTable {
    fn new() -> ArcTable {
        let theta: Vec<f64> = (0..=ARC_SAMPLES)
            .map(|i| THETA_MAX * i as f64 / ARC_SAMPLES as f64)
            .collect();
        let mut arc_mm = Vec::with_capacity(theta.len());
        let mut length = 0.0;
        let mut previous = base_point(0.0, REFERENCE_HEIGHT_MM);
        for &angle in &theta {
            let point = base_point(angle, REFERENCE_HEIGHT_MM);
            length += point.distance(previous);
            arc_mm.push(length);
            previous = point;
        }
        ArcTable { theta, arc_mm }
    }

    /// Arc length (mm) from the midline at azimuth `theta` (rad), negative on the right.
    pub fn arc(&self, theta: f64) -> f64 {
        theta.signum() * interpolate(&self.theta, &self.arc_mm, theta.abs())
    }

    /// Azimuth (rad) at arc length `arc_mm` from the midline.
    pub fn theta(&self, arc_mm: f64) -> f64 {
        arc_mm.signum() * interpolate(&self.arc_mm, &self.theta, arc_mm.abs())
    }
}

/// The scan surface and the chest wall beneath it at one parameter point (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceSample {
    /// The skin as scanned.
    pub skin: DVec3,
    /// The chest wall without breasts (equal to `skin` away from the breasts).
    pub wall: DVec3,
}

/// The torso with its two breasts.
pub struct TorsoSurface {
    pub arc: ArcTable,
    /// Left (+x) and right breast.
    pub breasts: [Breast; 2],
}

impl TorsoSurface {
    pub fn new(breasts: [Breast; 2]) -> TorsoSurface {
        TorsoSurface {
            arc: ArcTable::new(),
            breasts,
        }
    }

    /// Footprint coordinates `(s, t)` (mm) of `(theta, h)` relative to `breast`.
    pub fn footprint_coordinates(&self, breast: &Breast, theta: f64, h: f64) -> (f64, f64) {
        (
            self.arc.arc(breast.side * theta) - breast.center_arc_mm,
            h - breast.center_height_mm,
        )
    }

    /// Parameters `(theta, h)` of footprint coordinates `(s, t)` of `breast`.
    pub fn footprint_parameters(&self, breast: &Breast, s: f64, t: f64) -> (f64, f64) {
        (
            breast.side * self.arc.theta(breast.center_arc_mm + s),
            breast.center_height_mm + t,
        )
    }

    /// Skin and chest wall at `(theta, h)`.
    pub fn sample(&self, theta: f64, h: f64) -> SurfaceSample {
        let base = base_point(theta, h);
        let normal = base_normal(theta, h);
        let wall = base + relief(base.x, h) * normal;
        let mut skin = wall;
        for breast in &self.breasts {
            let (s, t) = self.footprint_coordinates(breast, theta, h);
            let height = breast.shape.height(s, t);
            if height > 0.0 {
                skin += height * normal - DVec3::Y * (breast.sag * height);
            }
        }
        SurfaceSample { skin, wall }
    }
}
