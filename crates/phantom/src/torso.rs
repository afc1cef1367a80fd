//! The torso without breasts: a stack of superelliptic cross-sections (chest, waist,
//! shoulders) joined to a neck stub, plus the local relief of the bony landmarks
//! (sternal notch, clavicles, sternum, xiphoid, costal margins) and the navel.
//!
//! Parameters: the azimuth `theta` (rad, 0 = front midline, positive towards the
//! patient's left, +x) and the height `h` (mm, 0 = sternal notch, up positive). The
//! surface point at `(theta, h)` has `y = h` before relief is added.

use crate::shape::{gaussian, profile, smooth_max, smoothstep};
use glam::DVec3;

/// Height of the top edge of the scan, on the neck (mm above the sternal notch).
pub const TOP_HEIGHT_MM: f64 = 45.0;
/// Height of the bottom edge of the scan, below the navel (mm).
pub const BOTTOM_HEIGHT_MM: f64 = -425.0;
/// Height of the navel centre (mm): the sternal notch to navel distance.
pub const NAVEL_HEIGHT_MM: f64 = -385.0;
/// Height of the xiphoid tip, the lower end of the sternum (mm).
pub const XIPHOID_HEIGHT_MM: f64 = -185.0;
/// Lateral distance of the mid-clavicular landmark from the midline (mm).
pub const MID_CLAVICLE_X_MM: f64 = 85.0;

/// Half-width of the trunk at the sides (theta = ±90°) without breasts, by height
/// `(h, half-width)` in mm.
const TRUNK_HALF_WIDTH: [(f64, f64); 8] = [
    (-440.0, 150.0), // upper hips below the navel
    (-385.0, 136.0), // navel level
    (-310.0, 126.0), // natural waist
    (-240.0, 139.0), // lower ribs, under the bust
    (-165.0, 151.0), // chest wall at nipple level
    (-100.0, 157.0), // armpits (arms cut away)
    (-30.0, 163.0),  // shoulders
    (45.0, 166.0),
];

/// Skin of the front midline before local relief, `(h, z)` in mm: the upper chest leans
/// forward from the notch, the abdomen is nearly vertical with a slight lower belly.
const TRUNK_FRONT_Z: [(f64, f64); 10] = [
    (-440.0, 63.0),
    (-412.0, 67.0), // lower belly
    (-385.0, 65.0), // navel
    (-330.0, 62.0), // upper abdomen
    (-260.0, 60.0), // epigastrium
    (-185.0, 64.0), // xiphoid
    (-120.0, 56.0), // mid sternum
    (-60.0, 34.0),  // manubrium
    (0.0, 0.0),     // top of the manubrium, the sternal notch level
    (45.0, -22.0),
];

/// Distance from the trunk's axis to the front skin at the midline, `(h, depth)` in mm.
const TRUNK_FRONT_DEPTH: [(f64, f64); 6] = [
    (-440.0, 96.0),
    (-310.0, 88.0),  // waist
    (-165.0, 100.0), // chest
    (-60.0, 96.0),
    (0.0, 88.0),
    (45.0, 88.0),
];

/// Distance from the trunk's axis to the back skin (only its front part is scanned), mm.
const TRUNK_BACK_DEPTH_MM: f64 = 95.0;

/// Superellipse exponent of the cross-section, `(h, exponent)`: 2 is an ellipse, larger
/// is boxier (a flatter front and fuller flanks).
const TRUNK_SQUARENESS: [(f64, f64); 5] = [
    (-440.0, 2.4),
    (-310.0, 2.25), // round waist
    (-165.0, 2.7),  // flat, broad chest
    (-60.0, 2.45),
    (45.0, 2.2), // the clavicles curve back towards the shoulders
];

/// Scale of the trunk section by height, `(h, scale)`: above the clavicles it shrinks
/// towards the neck, first gently (the shoulder tops), then steeply (the trapezius).
const SHOULDER_SCALE: [(f64, f64); 6] = [
    (-25.0, 1.0),
    (-8.0, 0.975),
    (5.0, 0.87),
    (20.0, 0.64),
    (35.0, 0.47),
    (50.0, 0.38),
];
/// Neck radius (mm).
const NECK_RADIUS_MM: f64 = 50.0;
/// Depth of the front of the neck behind the manubrium top (mm).
const NECK_FRONT_SETBACK_MM: f64 = 14.0;
/// Heights over which the neck emerges from the trunk (mm).
const NECK_EMERGE_START_MM: f64 = -40.0;
const NECK_EMERGE_END_MM: f64 = -5.0;
/// How far inside the trunk the neck starts below its emergence (mm).
const NECK_SUBMERSION_MM: f64 = 80.0;
/// Size of the rounded blend between neck and shoulders (mm).
const NECK_BLEND_MM: f64 = 18.0;

/// Depth of the sternal notch between the clavicle heads (mm).
const NOTCH_DEPTH_MM: f64 = 9.0;
/// Half-width of the notch (mm).
const NOTCH_HALF_WIDTH_MM: f64 = 13.0;
/// Height of the notch's deepest part above the manubrium top (mm).
const NOTCH_CENTER_MM: f64 = 2.0;
/// Vertical half-widths of the notch: short below (the manubrium's edge), long above
/// (the soft throat), mm.
const NOTCH_HALF_HEIGHTS_MM: (f64, f64) = (5.0, 14.0);

/// Height of the clavicle ridge above the surrounding skin (mm).
const CLAVICLE_RIDGE_MM: f64 = 3.5;
/// Extra height of the clavicle heads beside the notch (mm).
const CLAVICLE_HEAD_MM: f64 = 4.0;
/// Distance of the clavicle heads from the midline and their half-width (mm).
const CLAVICLE_HEAD_X_MM: f64 = 24.0;
const CLAVICLE_HEAD_HALF_WIDTH_MM: f64 = 9.0;
/// Medial end of the clavicle, beside the notch (mm from the midline).
const CLAVICLE_MEDIAL_END_MM: f64 = 22.0;
/// Lateral extent of the clavicle from the midline (mm).
const CLAVICLE_LENGTH_MM: f64 = 172.0;
/// Vertical half-width of the clavicle ridge (mm).
const CLAVICLE_HALF_WIDTH_MM: f64 = 7.0;
/// Height of the clavicle heads relative to the notch (mm).
const CLAVICLE_HEAD_HEIGHT_MM: f64 = -4.0;
/// Sag of the clavicle's mid part below its ends (mm).
const CLAVICLE_SAG_MM: f64 = 16.0;
/// Depth of the hollow above the clavicle, its height above the crest and its vertical
/// half-width (mm).
const SUPRACLAVICULAR_DEPTH_MM: f64 = 4.0;
const SUPRACLAVICULAR_RISE_MM: f64 = 14.0;
const SUPRACLAVICULAR_HALF_HEIGHT_MM: f64 = 7.0;

/// Height of the sternocleidomastoid tendons framing the notch (mm).
const NECK_TENDON_MM: f64 = 1.5;
/// Distance of the tendons from the midline at the notch level, and how much it grows
/// per mm of height (they diverge upwards), mm and mm/mm.
const NECK_TENDON_X_MM: f64 = 20.0;
const NECK_TENDON_SPREAD: f64 = 0.45;
/// Half-width of each tendon (mm).
const NECK_TENDON_HALF_WIDTH_MM: f64 = 7.0;

/// Depth and half-width of the groove along the sternum between the pectorals (mm).
const STERNAL_GROOVE_MM: f64 = 1.8;
const STERNAL_GROOVE_HALF_WIDTH_MM: f64 = 14.0;
/// Upper end of the groove, below the manubrium (mm).
const STERNAL_GROOVE_TOP_MM: f64 = -60.0;

/// Depth, drop below the xiphoid and radius of the epigastric hollow (mm).
const EPIGASTRIC_DEPTH_MM: f64 = 4.0;
const EPIGASTRIC_DROP_MM: f64 = 22.0;
const EPIGASTRIC_RADIUS_MM: f64 = 24.0;
/// Height and half-width of the costal margin ridges running down-laterally from the
/// xiphoid (mm).
const COSTAL_MARGIN_MM: f64 = 1.0;
const COSTAL_MARGIN_HALF_WIDTH_MM: f64 = 14.0;
/// Drop of the costal margin per mm of lateral distance near the midline (mm/mm).
const COSTAL_MARGIN_SLOPE: f64 = 0.9;
/// Depth and half-width of the midline groove of the abdomen (linea alba, mm).
const LINEA_ALBA_MM: f64 = 0.7;
const LINEA_ALBA_HALF_WIDTH_MM: f64 = 9.0;

/// Depth and half-widths of the navel (mm).
const NAVEL_DEPTH_MM: f64 = 9.0;
const NAVEL_HALF_WIDTH_MM: f64 = 5.5;
const NAVEL_HALF_HEIGHT_MM: f64 = 7.5;
/// Height and radius of the soft rim around the navel (mm).
const NAVEL_RIM_MM: f64 = 1.2;
const NAVEL_RIM_RADIUS_MM: f64 = 15.0;

/// The trunk without local relief at `(theta, h)` (mm).
pub fn base_point(theta: f64, h: f64) -> DVec3 {
    let (sin, cos) = theta.sin_cos();
    let front_z = profile(&TRUNK_FRONT_Z, h);
    let front_depth = profile(&TRUNK_FRONT_DEPTH, h);
    let axis_z = front_z - front_depth;
    let depth = if cos >= 0.0 {
        front_depth
    } else {
        TRUNK_BACK_DEPTH_MM
    };
    let half_width = profile(&TRUNK_HALF_WIDTH, h);
    let n = profile(&TRUNK_SQUARENESS, h);
    let trunk = ((cos / depth).abs().powf(n) + (sin / half_width).abs().powf(n)).powf(-1.0 / n);
    let shrink = profile(&SHOULDER_SCALE, h);

    // The neck: a vertical cylinder, its polar radius seen from the trunk axis.
    let neck_center_z = -NECK_FRONT_SETBACK_MM - NECK_RADIUS_MM;
    let offset = axis_z - neck_center_z; // trunk axis relative to the neck centre, along z
    let along = offset * cos;
    let neck = -along
        + (along * along - offset * offset + NECK_RADIUS_MM * NECK_RADIUS_MM)
            .max(0.0)
            .sqrt();
    let emerged = smoothstep(NECK_EMERGE_START_MM, NECK_EMERGE_END_MM, h);
    let neck = neck - NECK_SUBMERSION_MM * (1.0 - emerged);

    let radius = smooth_max(trunk * shrink, neck, NECK_BLEND_MM);
    DVec3::new(radius * sin, h, axis_z + radius * cos)
}

/// Unit outward normal of [`base_point`] at `(theta, h)`, by central differences.
pub fn base_normal(theta: f64, h: f64) -> DVec3 {
    const D_THETA: f64 = 1e-5;
    const D_H: f64 = 1e-3;
    let along_theta = base_point(theta + D_THETA, h) - base_point(theta - D_THETA, h);
    let along_h = base_point(theta, h + D_H) - base_point(theta, h - D_H);
    along_theta.cross(along_h).normalize()
}

/// Height of the clavicle crest at lateral distance `s` (mm) from the midline.
pub fn clavicle_height(s: f64) -> f64 {
    let along = ((s - CLAVICLE_MEDIAL_END_MM) / (CLAVICLE_LENGTH_MM - CLAVICLE_MEDIAL_END_MM))
        .clamp(0.0, 1.0);
    CLAVICLE_HEAD_HEIGHT_MM - CLAVICLE_SAG_MM * (std::f64::consts::PI * along).sin()
}

/// Outward relief (mm) of bones, muscles and the navel at base-surface position `x`
/// (mm, lateral) and height `h`.
pub fn relief(x: f64, h: f64) -> f64 {
    sternal_notch(x, h)
        + clavicles(x.abs(), h)
        + neck_tendons(x.abs(), h)
        + sternum(x, h)
        + abdomen(x, h)
        + navel(x, h)
}

/// The notch between the clavicle heads at the top of the sternum (negative, mm).
fn sternal_notch(x: f64, h: f64) -> f64 {
    let (below, above) = NOTCH_HALF_HEIGHTS_MM;
    let dh = h - NOTCH_CENTER_MM;
    -NOTCH_DEPTH_MM
        * gaussian(x, NOTCH_HALF_WIDTH_MM)
        * gaussian(dh, if dh > 0.0 { above } else { below })
}

/// The clavicle ridges with their prominent heads beside the notch, fading into the
/// shoulders, and the hollow above them (mm), at lateral distance `s`.
fn clavicles(s: f64, h: f64) -> f64 {
    let crest = clavicle_height(s);
    // Fade in beside the notch and out into the shoulder.
    let extent = smoothstep(CLAVICLE_MEDIAL_END_MM - 10.0, CLAVICLE_MEDIAL_END_MM, s)
        * (1.0 - smoothstep(CLAVICLE_LENGTH_MM - 30.0, CLAVICLE_LENGTH_MM + 10.0, s));
    let ridge = (CLAVICLE_RIDGE_MM
        + CLAVICLE_HEAD_MM * gaussian(s - CLAVICLE_HEAD_X_MM, CLAVICLE_HEAD_HALF_WIDTH_MM))
        * extent
        * gaussian(h - crest, CLAVICLE_HALF_WIDTH_MM);
    // The supraclavicular fossa, between the neck and the shoulder.
    let fossa_extent = smoothstep(40.0, 60.0, s) * (1.0 - smoothstep(120.0, 150.0, s));
    let fossa = -SUPRACLAVICULAR_DEPTH_MM
        * fossa_extent
        * gaussian(
            h - crest - SUPRACLAVICULAR_RISE_MM,
            SUPRACLAVICULAR_HALF_HEIGHT_MM,
        );
    ridge + fossa
}

/// The sternal heads of the sternocleidomastoid muscles, rising from beside the notch
/// and diverging up the neck (mm), at lateral distance `s`.
fn neck_tendons(s: f64, h: f64) -> f64 {
    let center = NECK_TENDON_X_MM + NECK_TENDON_SPREAD * h;
    NECK_TENDON_MM * smoothstep(-4.0, 6.0, h) * gaussian(s - center, NECK_TENDON_HALF_WIDTH_MM)
}

/// The groove along the sternum between the breasts, from below the manubrium to the
/// xiphoid (negative, mm).
fn sternum(x: f64, h: f64) -> f64 {
    -STERNAL_GROOVE_MM
        * gaussian(x, STERNAL_GROOVE_HALF_WIDTH_MM)
        * smoothstep(
            STERNAL_GROOVE_TOP_MM + 20.0,
            STERNAL_GROOVE_TOP_MM - 20.0,
            h,
        )
        * smoothstep(XIPHOID_HEIGHT_MM - 15.0, XIPHOID_HEIGHT_MM + 20.0, h)
}

/// The epigastric hollow below the xiphoid, the costal margins running down-laterally
/// from it, and the linea alba down to the navel (mm).
fn abdomen(x: f64, h: f64) -> f64 {
    let s = x.abs();
    let epigastric = -EPIGASTRIC_DEPTH_MM
        * gaussian(x, EPIGASTRIC_RADIUS_MM)
        * gaussian(
            h - (XIPHOID_HEIGHT_MM - EPIGASTRIC_DROP_MM),
            EPIGASTRIC_RADIUS_MM,
        );
    // The margin curves: steep beside the xiphoid, flatter towards the flanks.
    let margin_height = XIPHOID_HEIGHT_MM - 10.0 - COSTAL_MARGIN_SLOPE * s + 0.003 * s * s;
    let costal = COSTAL_MARGIN_MM
        * smoothstep(15.0, 35.0, s)
        * (1.0 - smoothstep(100.0, 130.0, s))
        * gaussian(h - margin_height, COSTAL_MARGIN_HALF_WIDTH_MM);
    let linea_alba = -LINEA_ALBA_MM
        * gaussian(x, LINEA_ALBA_HALF_WIDTH_MM)
        * smoothstep(XIPHOID_HEIGHT_MM - 30.0, XIPHOID_HEIGHT_MM - 60.0, h)
        * smoothstep(NAVEL_HEIGHT_MM - 10.0, NAVEL_HEIGHT_MM + 20.0, h);
    epigastric + costal + linea_alba
}

/// The navel: a deep, slightly tall dimple in a soft rim (mm).
fn navel(x: f64, h: f64) -> f64 {
    let dh = h - NAVEL_HEIGHT_MM;
    -NAVEL_DEPTH_MM * gaussian(x, NAVEL_HALF_WIDTH_MM) * gaussian(dh, NAVEL_HALF_HEIGHT_MM)
        + NAVEL_RIM_MM * gaussian((x * x + dh * dh).sqrt(), NAVEL_RIM_RADIUS_MM)
}
