//! The phantom's photograph (issue 25): a procedural skin texture with darker areolas and
//! a grid of small dark marks at known places on the skin, so that a test can find a
//! mark in a picture where its 3D point projects.
//!
//! Texture coordinates are the grid's parameters: `u` the azimuth from `-THETA_MAX` to
//! `THETA_MAX`, `v` the height from the bottom of the scan to its top (OBJ's convention:
//! `v = 0` is the image's bottom row). A texel is painted by where its parameter point
//! lies on the noise-free skin, so marks and areolas are round on the skin, not in the
//! image.

use crate::surface::{THETA_MAX, TorsoSurface};
use crate::torso::{BOTTOM_HEIGHT_MM, TOP_HEIGHT_MM};
use glam::{DVec2, DVec3};

/// Side of the square texture image (pixels): about half a millimetre of skin per pixel.
pub const TEXTURE_SIZE: u32 = 1024;
/// Radius of a mark on the skin (mm).
pub const MARK_RADIUS_MM: f64 = 3.0;
/// Spacing of the marks along the chest and in height (mm).
const MARK_SPACING_MM: f64 = 40.0;
/// Marks lie within this arc length of the midline (mm) and this band of heights below
/// the sternal notch (mm).
const MARK_ARC_REACH_MM: f64 = 160.0;
const MARK_HEIGHTS_MM: (f64, f64) = (-360.0, -40.0);
/// No mark within this distance of a nipple (mm): the areola is there.
const MARK_NIPPLE_CLEARANCE_MM: f64 = 30.0;
/// Radius of an areola (mm).
pub const AREOLA_RADIUS_MM: f64 = 18.0;

const SKIN_RGB: [u8; 3] = [226, 182, 160];
const AREOLA_RGB: [u8; 3] = [150, 96, 84];
const MARK_RGB: [u8; 3] = [30, 60, 120];

/// The phantom's skin texture.
#[derive(Debug, Clone, PartialEq)]
pub struct SkinTexture {
    pub width: u32,
    pub height: u32,
    /// sRGB pixels, row by row from the top.
    pub rgb: Vec<[u8; 3]>,
    /// Texture coordinates of every vertex of [`crate::Phantom::scan`].
    pub uv: Vec<DVec2>,
    /// Where each mark's centre lies on the noise-free skin (scan coordinates, mm).
    pub marks: Vec<DVec3>,
}

/// The texture coordinates of the grid point `(theta, h)`.
pub(crate) fn uv_of(theta: f64, h: f64) -> DVec2 {
    DVec2::new(
        0.5 + 0.5 * theta / THETA_MAX,
        (h - BOTTOM_HEIGHT_MM) / (TOP_HEIGHT_MM - BOTTOM_HEIGHT_MM),
    )
}

/// A disc painted on the skin: its parameter point, its centre on the skin (mm), its
/// radius (mm) and colour.
struct Spot {
    at: (f64, f64),
    centre: DVec3,
    radius: f64,
    colour: [u8; 3],
}

/// Paints the texture of `surface` (whose skin is shifted by `-origin` in the scan) with
/// the areolas around `nipples` (parameter points).
pub(crate) fn paint(
    surface: &TorsoSurface,
    origin: DVec3,
    nipples: [(f64, f64); 2],
    uv: Vec<DVec2>,
) -> SkinTexture {
    let skin = |(theta, h): (f64, f64)| surface.sample(theta, h).skin - origin;
    let nipple_points = nipples.map(skin);
    let mut spots: Vec<Spot> = nipples
        .iter()
        .zip(nipple_points)
        .map(|(&at, centre)| Spot {
            at,
            centre,
            radius: AREOLA_RADIUS_MM,
            colour: AREOLA_RGB,
        })
        .collect();
    let mut marks = Vec::new();
    let steps = |from: f64, to: f64| {
        let n = ((to - from) / MARK_SPACING_MM).round() as i32;
        (0..=n).map(move |k| from + k as f64 * MARK_SPACING_MM)
    };
    for h in steps(MARK_HEIGHTS_MM.0, MARK_HEIGHTS_MM.1) {
        for arc in steps(-MARK_ARC_REACH_MM, MARK_ARC_REACH_MM) {
            let at = (surface.arc.theta(arc), h);
            let centre = skin(at);
            if nipple_points
                .iter()
                .all(|n| n.distance(centre) > MARK_NIPPLE_CLEARANCE_MM)
            {
                marks.push(centre);
                spots.push(Spot {
                    at,
                    centre,
                    radius: MARK_RADIUS_MM,
                    colour: MARK_RGB,
                });
            }
        }
    }
    let (width, height) = (TEXTURE_SIZE, TEXTURE_SIZE);
    let mut rgb = vec![SKIN_RGB; (width * height) as usize];
    // each spot paints the texels of a parameter window around it that lie within its
    // radius on the skin; the window is generous (twice the radius in height, against
    // the ptotic breast's shear, and the chest's radius exceeds 60 mm)
    for Spot {
        at: (theta_c, h_c),
        centre,
        radius,
        colour,
    } in spots
    {
        let half_theta = 2.0 * radius / 60.0;
        let texel = |uv: DVec2| {
            (
                (uv.x * width as f64).floor() as i64,
                ((1.0 - uv.y) * height as f64).floor() as i64,
            )
        };
        let (i0, j1) = texel(uv_of(theta_c - half_theta, h_c - 2.0 * radius));
        let (i1, j0) = texel(uv_of(theta_c + half_theta, h_c + 2.0 * radius));
        for j in j0.max(0)..=j1.min(height as i64 - 1) {
            for i in i0.max(0)..=i1.min(width as i64 - 1) {
                let u = (i as f64 + 0.5) / width as f64;
                let v = 1.0 - (j as f64 + 0.5) / height as f64;
                let theta = (2.0 * u - 1.0) * THETA_MAX;
                let h = BOTTOM_HEIGHT_MM + v * (TOP_HEIGHT_MM - BOTTOM_HEIGHT_MM);
                if skin((theta, h)).distance(centre) <= radius {
                    rgb[(j * width as i64 + i) as usize] = colour;
                }
            }
        }
    }
    SkinTexture {
        width,
        height,
        rgb,
        uv,
        marks,
    }
}
