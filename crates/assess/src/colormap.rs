//! The deviation colour map of the paper's Fig. 3: green at 0 mm, red at 20 mm and
//! beyond.
//!
//! The exact ramp, with `t = min(|d| / 20 mm, 1)`: red `= 255 · min(2t, 1)`, green
//! `= 255 · min(2 (1 - t), 1)`, blue `= 0`, rounded to the nearest integer. So 0 mm is
//! pure green (0, 255, 0), 10 mm pure yellow (255, 255, 0) and 20 mm or more pure red
//! (255, 0, 0): the hue falls linearly from 120° to 0° at full saturation and value,
//! never through the muddy brown of a straight green-red blend. A signed distance is
//! coloured by its magnitude; a vertex without a distance (NaN: outside the overlap)
//! is mid grey.

/// The distance (mm) at and beyond which the map is pure red.
pub const DEVIATION_COLOR_MAX_MM: f64 = 20.0;

/// The colour of a vertex that has no deviation (outside the overlap).
pub const OUTSIDE_OVERLAP_COLOR: [u8; 3] = [128, 128, 128];

/// The colour (RGB, 0-255) of a deviation of `distance_mm` (see the module
/// documentation for the ramp). NaN or infinite distances give
/// [`OUTSIDE_OVERLAP_COLOR`].
pub fn deviation_color(distance_mm: f64) -> [u8; 3] {
    if !distance_mm.is_finite() {
        return OUTSIDE_OVERLAP_COLOR;
    }
    let t = (distance_mm.abs() / DEVIATION_COLOR_MAX_MM).min(1.0);
    let channel = |value: f64| (255.0 * value.min(1.0)).round() as u8;
    [channel(2.0 * t), channel(2.0 * (1.0 - t)), 0]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_runs_green_yellow_red_and_saturates() {
        assert_eq!(deviation_color(0.0), [0, 255, 0]);
        assert_eq!(deviation_color(5.0), [128, 255, 0]);
        assert_eq!(deviation_color(10.0), [255, 255, 0]);
        assert_eq!(deviation_color(15.0), [255, 128, 0]);
        assert_eq!(deviation_color(20.0), [255, 0, 0]);
        assert_eq!(deviation_color(75.0), [255, 0, 0]);
        assert_eq!(deviation_color(-10.0), deviation_color(10.0));
        assert_eq!(deviation_color(f64::NAN), OUTSIDE_OVERLAP_COLOR);
    }

    #[test]
    fn ramp_is_monotone() {
        // Red never decreases and green never increases along the distance.
        let colors: Vec<[u8; 3]> = (0..=250).map(|k| deviation_color(k as f64 * 0.1)).collect();
        for pair in colors.windows(2) {
            assert!(pair[1][0] >= pair[0][0] && pair[1][1] <= pair[0][1]);
        }
    }
}
