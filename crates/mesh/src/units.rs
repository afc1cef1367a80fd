//! Units of length a file's coordinates may come in. Everything inside mammaplan is in
//! millimetres; a file in another unit is converted where it is read.

use std::ops::RangeInclusive;

/// A unit of length.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LengthUnit {
    Millimetre,
    Centimetre,
    Metre,
    Inch,
}

/// How far apart points on a torso lie (mm): a file whose points span less (with at
/// least three of them) or more in its declared unit is in another unit.
pub const TORSO_SPAN_MM: RangeInclusive<f64> = 20.0..=2_000.0;

impl LengthUnit {
    pub const ALL: [LengthUnit; 4] = [
        LengthUnit::Millimetre,
        LengthUnit::Centimetre,
        LengthUnit::Metre,
        LengthUnit::Inch,
    ];

    /// Millimetres in one unit.
    pub fn mm(self) -> f64 {
        match self {
            LengthUnit::Millimetre => 1.0,
            LengthUnit::Centimetre => 10.0,
            LengthUnit::Metre => 1000.0,
            LengthUnit::Inch => 25.4,
        }
    }

    /// The unit's symbol as files and the command line write it.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::Millimetre => "mm",
            LengthUnit::Centimetre => "cm",
            LengthUnit::Metre => "m",
            LengthUnit::Inch => "in",
        }
    }

    /// The unit of `symbol` (`mm`, `cm`, `m` or `in`).
    pub fn parse(symbol: &str) -> Option<LengthUnit> {
        LengthUnit::ALL.into_iter().find(|u| u.symbol() == symbol)
    }

    /// The first unit in which a size of `size` file units is `plausible_mm`, if any
    /// (millimetres first).
    pub fn plausible(size: f64, plausible_mm: &RangeInclusive<f64>) -> Option<LengthUnit> {
        LengthUnit::ALL
            .into_iter()
            .find(|u| plausible_mm.contains(&(size * u.mm())))
    }
}

impl std::fmt::Display for LengthUnit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.symbol())
    }
}

impl std::str::FromStr for LengthUnit {
    type Err = String;

    fn from_str(symbol: &str) -> Result<LengthUnit, String> {
        LengthUnit::parse(symbol).ok_or_else(|| {
            format!("unknown unit \"{symbol}\": expected \"mm\", \"cm\", \"m\" or \"in\"")
        })
    }
}

/// `Err` naming the declared unit and a plausible one when points declared in `unit`
/// that lie `span` file units apart (the largest distance between two of `count`
/// points) cannot be points on a torso ([`TORSO_SPAN_MM`]). Fewer than three points,
/// and millimetres (the default, whose mistakes show as points off the scan), are not
/// judged.
pub fn check_declared_unit(unit: LengthUnit, span: f64, count: usize) -> Result<(), String> {
    let span_mm = span * unit.mm();
    if count < 3 || unit == LengthUnit::Millimetre || TORSO_SPAN_MM.contains(&span_mm) {
        return Ok(());
    }
    let instead = LengthUnit::plausible(span, &TORSO_SPAN_MM)
        .map(|other| {
            format!(
                "; in \"{other}\" they would span {:.0} mm, a body's size: correct the \"units\" field",
                span * other.mm()
            )
        })
        .unwrap_or_default();
    Err(format!(
        "\"units\" is \"{unit}\", but then the points span {span_mm:.3e} mm, which no torso does{instead}"
    ))
}

/// The largest distance between two of `points` (in their unit).
pub fn span(points: &[glam::DVec3]) -> f64 {
    let mut largest: f64 = 0.0;
    for (k, a) in points.iter().enumerate() {
        for b in &points[k + 1..] {
            largest = largest.max(a.distance(*b));
        }
    }
    largest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn symbols_and_factors_round_trip() {
        for unit in LengthUnit::ALL {
            assert_eq!(unit.symbol().parse::<LengthUnit>(), Ok(unit));
        }
        assert!("furlong".parse::<LengthUnit>().is_err());
        assert_eq!(LengthUnit::Inch.mm(), 25.4);
    }

    /// Landmarks 0.3 apart declared in cm are in metres; 300 apart declared in m are in
    /// millimetres; a torso in its own unit passes.
    #[test]
    fn a_declared_unit_that_contradicts_the_size_is_named() {
        let error = check_declared_unit(LengthUnit::Centimetre, 0.3, 12).unwrap_err();
        assert!(error.contains("in \"m\" they would span 300 mm"), "{error}");
        let error = check_declared_unit(LengthUnit::Metre, 300.0, 12).unwrap_err();
        assert!(
            error.contains("in \"mm\" they would span 300 mm"),
            "{error}"
        );
        assert!(check_declared_unit(LengthUnit::Metre, 0.3, 12).is_ok());
        assert!(check_declared_unit(LengthUnit::Metre, 300.0, 2).is_ok());
    }
}
