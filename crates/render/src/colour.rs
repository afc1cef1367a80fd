//! sRGB levels and linear light: the tables every colour goes through.

use std::sync::LazyLock;

/// Entries of the linear-to-sRGB table: steps of 1/4095 in linear light are under one
/// sRGB level everywhere (the curve is steepest at black, 12.92).
const LINEAR_TO_SRGB_STEPS: usize = 4096;

static SRGB_TO_LINEAR: LazyLock<[f32; 256]> = LazyLock::new(|| {
    std::array::from_fn(|level| {
        let c = level as f64 / 255.0;
        let linear = if c <= 0.04045 {
            c / 12.92
        } else {
            ((c + 0.055) / 1.055).powf(2.4)
        };
        linear as f32
    })
});

static LINEAR_TO_SRGB: LazyLock<Vec<u8>> = LazyLock::new(|| {
    (0..LINEAR_TO_SRGB_STEPS)
        .map(|step| {
            let linear = step as f64 / (LINEAR_TO_SRGB_STEPS - 1) as f64;
            let c = if linear <= 0.0031308 {
                12.92 * linear
            } else {
                1.055 * linear.powf(1.0 / 2.4) - 0.055
            };
            (255.0 * c).round().clamp(0.0, 255.0) as u8
        })
        .collect()
});

/// An sRGB level (0-255) in linear light (0-1).
#[inline]
pub(crate) fn srgb_to_linear(level: u8) -> f32 {
    SRGB_TO_LINEAR[level as usize]
}

/// An sRGB colour in linear light.
pub(crate) fn srgb_colour_to_linear(colour: [u8; 3]) -> [f32; 3] {
    colour.map(srgb_to_linear)
}

/// Linear light (clamped to 0-1) as an sRGB level.
#[inline]
pub(crate) fn linear_to_srgb(linear: f32) -> u8 {
    // Non-negative, so adding one half and truncating rounds.
    let step = linear.clamp(0.0, 1.0) * (LINEAR_TO_SRGB_STEPS - 1) as f32 + 0.5;
    LINEAR_TO_SRGB[step as usize]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_round_trips_every_level() {
        for level in 0..=255u8 {
            assert_eq!(linear_to_srgb(srgb_to_linear(level)), level);
        }
    }
}
