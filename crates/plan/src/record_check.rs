//! Values read back from a result file (`model.json`, `result.json`), checked against the
//! ranges any real result lies in, so that an edited or damaged file is refused with the
//! field's name instead of shown as a plan.

use crate::per_side::PerSide;
use anatomy::breast::{QuadrantVolumes, Side};
use std::ops::RangeInclusive;

/// Volumes of breasts, quadrants and implants (ml).
pub(crate) const VOLUME_ML: RangeInclusive<f64> = 0.0..=20_000.0;
/// Distances on the body and implant dimensions (mm).
pub(crate) const LENGTH_MM: RangeInclusive<f64> = 0.0..=10_000.0;
/// A quadrant's volume: signed, where the skin of a flat quadrant can lie behind the
/// fill-in (ml).
pub(crate) const QUADRANT_ML: RangeInclusive<f64> = -20_000.0..=20_000.0;
/// Moves of an implant from its default position (mm).
pub(crate) const SHIFT_MM: RangeInclusive<f64> = -1_000.0..=1_000.0;

/// Collects the first field out of range, by its path in the file (`implants.left.width_mm`).
#[derive(Default)]
#[must_use = "`finish` reports the field out of range"]
pub(crate) struct FieldCheck {
    problem: Option<String>,
}

impl FieldCheck {
    /// Checks `value` of `field` against `range` (`unit` for the message).
    pub(crate) fn value(
        &mut self,
        field: impl FnOnce() -> String,
        value: f64,
        range: &RangeInclusive<f64>,
        unit: &str,
    ) -> &mut Self {
        if self.problem.is_none() && !range.contains(&value) {
            self.problem = Some(format!(
                "{} is {value} {unit}; a result holds {} to {} {unit}",
                field(),
                range.start(),
                range.end()
            ));
        }
        self
    }

    /// Every value of `values` under `field`'s name with its own suffix.
    pub(crate) fn values<'a>(
        &mut self,
        field: &str,
        values: impl IntoIterator<Item = (&'a str, f64)>,
        range: &RangeInclusive<f64>,
        unit: &str,
    ) -> &mut Self {
        for (name, value) in values {
            self.value(|| format!("{field}.{name}"), value, range, unit);
        }
        self
    }

    /// Both breasts' volumes and, where recorded, their quadrants'.
    pub(crate) fn breast_volumes<'a>(
        &mut self,
        breast_ml: &PerSide<f64>,
        quadrants_ml: impl Fn(Side) -> Option<&'a QuadrantVolumes>,
    ) -> &mut Self {
        for side in Side::BOTH {
            self.value(
                || format!("breast_volume_ml.{side}"),
                *breast_ml.get(side),
                &VOLUME_ML,
                "ml",
            );
            if let Some(q) = quadrants_ml(side) {
                self.values(
                    &format!("quadrant_volume_ml.{side}"),
                    [
                        ("upper_outer", q.upper_outer),
                        ("upper_inner", q.upper_inner),
                        ("lower_inner", q.lower_inner),
                        ("lower_outer", q.lower_outer),
                    ],
                    &QUADRANT_ML,
                    "ml",
                );
            }
        }
        self
    }

    /// `Err` naming `file`, the field and `rerun`, if a value was out of range.
    pub(crate) fn finish(&self, file: &std::path::Path, rerun: &str) -> anyhow::Result<()> {
        match &self.problem {
            None => Ok(()),
            Some(problem) => anyhow::bail!(
                "{}: {problem} (was the file edited?); run `{rerun}` again",
                file.display()
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_value_out_of_range_is_named() {
        let mut check = FieldCheck::default();
        check
            .value(|| "breast_volume_ml.left".into(), 310.0, &VOLUME_ML, "ml")
            .values(
                "implants.left",
                [
                    ("width_mm", 115.0),
                    ("height_mm", -4.0),
                    ("projection_mm", -1.0),
                ],
                &LENGTH_MM,
                "mm",
            );
        let error = check
            .finish(
                std::path::Path::new("sim/result.json"),
                "mammaplan simulate",
            )
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            "sim/result.json: implants.left.height_mm is -4 mm; a result holds 0 to 10000 mm \
             (was the file edited?); run `mammaplan simulate` again"
        );
        assert!(
            FieldCheck::default()
                .finish(std::path::Path::new("x"), "y")
                .is_ok()
        );
    }
}
