//! The closed C2 cubic spline through a breast's control points (paper IV-B): a periodic
//! interpolating cubic with centripetal parametrisation (knot spacing = square root of
//! the chord length), which neither overshoots nor forms cusps or loops between control
//! points the way a uniform parametrisation can on uneven spacing.

use glam::DVec3;

/// Two consecutive control points closer than this (mm) leave the spline segment
/// between them undefined.
pub const MIN_CONTROL_POINT_SPACING_MM: f64 = 0.1;

/// A closed interpolating cubic spline, C2 everywhere including the closing point.
#[derive(Debug, Clone, PartialEq)]
pub struct ClosedSpline {
    /// The control points, in order (the first is not repeated at the end).
    points: Vec<DVec3>,
    /// Second derivatives with respect to the knot parameter at each control point.
    second_derivatives: Vec<DVec3>,
    /// Parameter length of the segment from point `i` to point `i + 1` (cyclically).
    knot_spacing: Vec<f64>,
}

/// Why no spline passes through the control points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SplineError {
    /// Fewer than three control points.
    TooFewPoints(usize),
    /// Control point `index` and the next one (cyclically) coincide.
    CoincidentPoints { index: usize },
}

impl ClosedSpline {
    /// The periodic cubic through `points` (mm), at least three, consecutive ones (and the
    /// last and first) at least [`MIN_CONTROL_POINT_SPACING_MM`] apart.
    pub fn through(points: &[DVec3]) -> Result<ClosedSpline, SplineError> {
        let n = points.len();
        if n < 3 {
            return Err(SplineError::TooFewPoints(n));
        }
        let knot_spacing: Vec<f64> = (0..n)
            .map(|i| points[i].distance(points[(i + 1) % n]))
            .collect();
        if let Some(index) = knot_spacing
            .iter()
            .position(|&d| d.is_nan() || d < MIN_CONTROL_POINT_SPACING_MM)
        {
            return Err(SplineError::CoincidentPoints { index });
        }
        let knot_spacing: Vec<f64> = knot_spacing.into_iter().map(f64::sqrt).collect();
        // Continuity of the first derivative at point i, with h = knot spacing:
        // h[i-1] M[i-1] + 2 (h[i-1] + h[i]) M[i] + h[i] M[i+1]
        //   = 6 ((P[i+1] - P[i]) / h[i] - (P[i] - P[i-1]) / h[i-1]).
        let previous = |i: usize| (i + n - 1) % n;
        let slope = |i: usize| (points[(i + 1) % n] - points[i]) / knot_spacing[i];
        let lower: Vec<f64> = (0..n).map(|i| knot_spacing[previous(i)]).collect();
        let diagonal: Vec<f64> = (0..n)
            .map(|i| 2.0 * (knot_spacing[previous(i)] + knot_spacing[i]))
            .collect();
        let rhs: Vec<DVec3> = (0..n)
            .map(|i| 6.0 * (slope(i) - slope(previous(i))))
            .collect();
        let second_derivatives = solve_cyclic_tridiagonal(&lower, &diagonal, &knot_spacing, &rhs);
        Ok(ClosedSpline {
            points: points.to_vec(),
            second_derivatives,
            knot_spacing,
        })
    }

    /// The point at fraction `s` (0..=1) along segment `segment`, from control point
    /// `segment` to the next.
    pub fn evaluate(&self, segment: usize, s: f64) -> DVec3 {
        let n = self.points.len();
        let next = (segment + 1) % n;
        let h = self.knot_spacing[segment];
        let (m0, m1) = (
            self.second_derivatives[segment],
            self.second_derivatives[next],
        );
        let (a, b) = (1.0 - s, s);
        // Cubic with second derivatives m0, m1 at the ends, through both control points.
        a * self.points[segment]
            + b * self.points[next]
            + (h * h / 6.0) * ((a * a * a - a) * m0 + (b * b * b - b) * m1)
    }

    /// Points along the closed curve, starting at the first control point (not repeated
    /// at the end), about `spacing_mm` apart: each segment is split into equal parameter
    /// steps, as many as its chord length needs. Every control point is a sample.
    pub fn sample(&self, spacing_mm: f64) -> Vec<DVec3> {
        let n = self.points.len();
        let mut samples = Vec::new();
        for segment in 0..n {
            let chord = self.points[segment].distance(self.points[(segment + 1) % n]);
            let steps = (chord / spacing_mm).ceil().max(1.0) as usize;
            samples.extend((0..steps).map(|k| self.evaluate(segment, k as f64 / steps as f64)));
        }
        samples
    }
}

/// Solves the cyclic tridiagonal system `lower[i] x[i-1] + diagonal[i] x[i] + upper[i]
/// x[i+1] = rhs[i]` (indices mod n, n >= 3) by the Sherman-Morrison formula around the
/// Thomas algorithm. The spline's system is strictly diagonally dominant, so no pivoting
/// is needed.
fn solve_cyclic_tridiagonal(
    lower: &[f64],
    diagonal: &[f64],
    upper: &[f64],
    rhs: &[DVec3],
) -> Vec<DVec3> {
    let n = diagonal.len();
    // A = B + u v^T with u = (gamma, 0, .., 0, upper[n-1]), v = (1, 0, .., 0, lower[0] / gamma).
    let gamma = -diagonal[0];
    let mut modified = diagonal.to_vec();
    modified[0] -= gamma;
    modified[n - 1] -= upper[n - 1] * lower[0] / gamma;
    let y = solve_tridiagonal(lower, &modified, upper, rhs);
    let mut u = vec![DVec3::ZERO; n];
    u[0] = DVec3::splat(gamma);
    u[n - 1] = DVec3::splat(upper[n - 1]);
    let z = solve_tridiagonal(lower, &modified, upper, &u);
    let v_dot = |x: &[DVec3]| x[0] + x[n - 1] * (lower[0] / gamma);
    let factor = v_dot(&y) / (DVec3::ONE + v_dot(&z));
    y.iter()
        .zip(&z)
        .map(|(&yi, &zi)| yi - factor * zi)
        .collect()
}

/// The Thomas algorithm for a tridiagonal system (`lower[0]` and `upper[n-1]` ignored).
fn solve_tridiagonal(lower: &[f64], diagonal: &[f64], upper: &[f64], rhs: &[DVec3]) -> Vec<DVec3> {
    let n = diagonal.len();
    let mut upper_scaled = vec![0.0; n];
    let mut x = vec![DVec3::ZERO; n];
    let mut pivot = diagonal[0];
    upper_scaled[0] = upper[0] / pivot;
    x[0] = rhs[0] / pivot;
    for i in 1..n {
        pivot = diagonal[i] - lower[i] * upper_scaled[i - 1];
        upper_scaled[i] = upper[i] / pivot;
        x[i] = (rhs[i] - lower[i] * x[i - 1]) / pivot;
    }
    for i in (0..n - 1).rev() {
        x[i] = x[i] - upper_scaled[i] * x[i + 1];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    fn circle(count: usize, radius: f64) -> Vec<DVec3> {
        (0..count)
            .map(|k| {
                let angle = TAU * k as f64 / count as f64;
                DVec3::new(radius * angle.cos(), radius * angle.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn interpolates_its_points_and_is_c2_at_them() {
        let points = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(40.0, -10.0, 5.0),
            DVec3::new(90.0, 20.0, 0.0),
            DVec3::new(60.0, 80.0, -8.0),
            DVec3::new(10.0, 60.0, 3.0),
        ];
        let spline = ClosedSpline::through(&points).unwrap();
        let n = points.len();
        let step = 1e-4;
        for i in 0..n {
            assert!(spline.evaluate(i, 0.0).distance(points[i]) < 1e-12);
            assert!(spline.evaluate(i, 1.0).distance(points[(i + 1) % n]) < 1e-12);
            // One-sided derivatives in the knot parameter agree on both sides of point i.
            let before = (i + n - 1) % n;
            let (h0, h1) = (spline.knot_spacing[before], spline.knot_spacing[i]);
            let left = |s: f64| spline.evaluate(before, 1.0 - s / h0);
            let right = |s: f64| spline.evaluate(i, s / h1);
            let left_slope = (points[i] - left(step)) / step;
            let right_slope = (right(step) - points[i]) / step;
            assert!(left_slope.distance(right_slope) < 1e-3, "{i}");
            let left_curvature = (left(2.0 * step) - 2.0 * left(step) + points[i]) / step.powi(2);
            let right_curvature =
                (right(2.0 * step) - 2.0 * right(step) + points[i]) / step.powi(2);
            assert!(left_curvature.distance(right_curvature) < 1e-2, "{i}");
        }
    }

    #[test]
    fn twelve_points_on_a_circle_give_a_near_circle() {
        let radius = 70.0;
        let spline = ClosedSpline::through(&circle(12, radius)).unwrap();
        let samples = spline.sample(1.0);
        assert!(samples.len() >= 440);
        let worst = samples
            .iter()
            .map(|p| (p.length() - radius).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.05, "{worst}");
    }

    #[test]
    fn too_few_or_coincident_points_are_refused() {
        let points = circle(3, 10.0);
        assert_eq!(
            ClosedSpline::through(&points[..2]),
            Err(SplineError::TooFewPoints(2))
        );
        let repeated = [points[0], points[1], points[1], points[2]];
        assert_eq!(
            ClosedSpline::through(&repeated),
            Err(SplineError::CoincidentPoints { index: 1 })
        );
        assert!(ClosedSpline::through(&[points[0], points[1], DVec3::NAN]).is_err());
    }
}
