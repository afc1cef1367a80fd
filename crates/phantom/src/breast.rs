//! One breast: a compact-support mound on the chest wall with a teardrop profile (long,
//! gently sloping upper pole; full, steep lower pole ending in the fold crease), an
//! areola and a nipple, sheared downwards by ptosis.
//!
//! The breast is described in footprint coordinates on the chest wall: `s` (mm) runs
//! along the chest surface at the reference height, positive laterally; `t` (mm) is the
//! height above the nipple. The mound is a horizontal profile through the nipple times
//! a vertical profile stretched to reach the footprint's upper edge or the fold.

use crate::shape::{smootherstep, smoothstep};

/// Fullness of the horizontal profile through the nipple, `(1 - x²)³ (1 + c x²)`:
/// larger is rounder at the nipple (below 3 it still falls monotonically); the cubic
/// onset lets the breast rise gently from the chest medially and laterally.
const ROW_FULLNESS: f64 = 2.0;
/// Fullness of the upper pole's vertical profile, same form: a small value gives the
/// straight, slightly concave slope from the chest down to the nipple.
const UPPER_POLE_FULLNESS: f64 = 1.0;
/// How much the upper pole's reach shrinks towards the medial and lateral ends,
/// `reach ∝ (1 - x²)^e` (0.5 would be an ellipse): 2 gives a rounded-diamond upper
/// edge, the outline a surgeon's cut curve through the upper and the lateral landmarks
/// traces (paper IV-B), so the breast and the region the landmarks delimit agree.
const UPPER_EDGE_ROUNDNESS: f64 = 2.0;
/// Exponent of the lower pole's vertical profile `(1 - v² + ε)^p - ε^p`: below 1 the
/// lower pole is round and full and meets the chest wall steeply, forming the fold
/// crease.
const LOWER_POLE_EXPONENT: f64 = 0.55;
/// The `ε` of the lower pole's profile: keeps the crease's slope finite (about 75° to
/// the chest wall for a medium cup) so that the crease is sampled well.
const CREASE_SOFTENING: f64 = 0.06;
/// Width of the smooth change between the medial and lateral half-axes across the
/// nipple (mm).
const AXIS_BLEND_MM: f64 = 20.0;
/// Radius of the nipple (mm).
const NIPPLE_RADIUS_MM: f64 = 5.0;
/// Height of the areola above the breast mound (mm).
const AREOLA_HEIGHT_MM: f64 = 1.0;

/// Size and shape of one breast (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BreastShape {
    /// Projection of the mound at the nipple, along the chest normal.
    pub projection_mm: f64,
    /// Footprint extent from the nipple towards the sternum.
    pub medial_mm: f64,
    /// Footprint extent from the nipple towards the side.
    pub lateral_mm: f64,
    /// Footprint extent from the nipple up (upper pole).
    pub upper_mm: f64,
    /// Footprint extent from the nipple down to the fold (lower pole).
    pub lower_mm: f64,
    /// Areola radius.
    pub areola_radius_mm: f64,
    /// Nipple height above the areola.
    pub nipple_height_mm: f64,
}

impl BreastShape {
    /// The same breast scaled in footprint by `footprint` and in projection by
    /// `projection` (volume scales by about `footprint² · projection`).
    pub fn scaled(self, footprint: f64, projection: f64) -> BreastShape {
        BreastShape {
            projection_mm: self.projection_mm * projection,
            medial_mm: self.medial_mm * footprint,
            lateral_mm: self.lateral_mm * footprint,
            upper_mm: self.upper_mm * footprint,
            lower_mm: self.lower_mm * footprint,
            ..self
        }
    }

    /// Footprint coordinates `(s, t)` (mm) of the point of the inframammary fold at
    /// `fraction` of the way from below the nipple (0) to the fold's medial (-1) or
    /// lateral (+1) end, where the fold meets the nipple's row.
    pub fn fold_point(&self, fraction: f64) -> (f64, f64) {
        let x = fraction.clamp(-1.0, 1.0);
        // Solve s / half_width(s) = x; s / half_width(s) is increasing.
        let (mut low, mut high) = (-2.0 * self.medial_mm, 2.0 * self.lateral_mm);
        for _ in 0..80 {
            let middle = 0.5 * (low + high);
            if middle / self.half_width(middle) < x {
                low = middle;
            } else {
                high = middle;
            }
        }
        let s = 0.5 * (low + high);
        (s, -self.lower_mm * (1.0 - x * x).sqrt())
    }

    /// Footprint half-width (mm) at lateral offset `s`: medial to lateral extent.
    fn half_width(&self, s: f64) -> f64 {
        let w = smootherstep(-AXIS_BLEND_MM, AXIS_BLEND_MM, s);
        self.medial_mm + (self.lateral_mm - self.medial_mm) * w
    }

    /// Height of the skin above the chest wall (mm) at footprint coordinates `(s, t)`:
    /// zero outside the footprint, an ellipse of half-axes `medial_mm`/`lateral_mm` and
    /// `upper_mm`/`lower_mm` whose lower half is the fold.
    pub fn height(&self, s: f64, t: f64) -> f64 {
        let x = s / self.half_width(s);
        let row = 1.0 - x * x;
        if row <= 0.0 {
            return 0.0;
        }
        let across = row * row * row * (1.0 + ROW_FULLNESS * x * x);
        // The fold follows the footprint ellipse; the upper pole's edge narrows towards
        // the sides, and the pole fades into the chest without an outline.
        let reach = if t >= 0.0 {
            self.upper_mm * row.powf(UPPER_EDGE_ROUNDNESS)
        } else {
            self.lower_mm * row.sqrt()
        };
        let v = t / reach;
        let column = 1.0 - v * v;
        if column <= 0.0 {
            return 0.0;
        }
        let along = if t >= 0.0 {
            column * column * column * (1.0 + UPPER_POLE_FULLNESS * v * v)
        } else {
            let soft = CREASE_SOFTENING.powf(LOWER_POLE_EXPONENT);
            ((column + CREASE_SOFTENING).powf(LOWER_POLE_EXPONENT) - soft)
                / ((1.0 + CREASE_SOFTENING).powf(LOWER_POLE_EXPONENT) - soft)
        };
        let mound = self.projection_mm * across * along;

        let r = (s * s + t * t).sqrt();
        let areola = AREOLA_HEIGHT_MM
            * (1.0 - smoothstep(self.areola_radius_mm - 3.0, self.areola_radius_mm + 1.5, r));
        let q = r / NIPPLE_RADIUS_MM;
        let nipple = self.nipple_height_mm
            * (1.0 - smoothstep(NIPPLE_RADIUS_MM - 2.0, NIPPLE_RADIUS_MM + 0.8, r))
            * (1.0 - 0.25 * q * q);
        mound + areola + nipple
    }
}

/// A breast placed on the torso.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Breast {
    /// +1 for the patient's left breast (+x), -1 for the right.
    pub side: f64,
    pub shape: BreastShape,
    /// Arc length (mm) from the midline to the footprint centre along the chest at the
    /// reference height.
    pub center_arc_mm: f64,
    /// Height of the footprint centre (mm).
    pub center_height_mm: f64,
    /// Downward shift of the skin per mm of mound height (ptosis shear, dimensionless).
    pub sag: f64,
}
