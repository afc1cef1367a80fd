//! Small smooth building blocks for the procedural surface: blends, bumps and profiles
//! given as knot tables.

/// Hermite smoothstep: 0 at `edge0`, 1 at `edge1`, C1 (also for `edge0 > edge1`).
pub fn smoothstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Quintic smootherstep: 0 at `edge0`, 1 at `edge1`, C2 (also for `edge0 > edge1`).
pub fn smootherstep(edge0: f64, edge1: f64, x: f64) -> f64 {
    let t = ((x - edge0) / (edge1 - edge0)).clamp(0.0, 1.0);
    t * t * t * (t * (6.0 * t - 15.0) + 10.0)
}

/// Gaussian bump `exp(-(x/width)²)`, 1 at 0.
pub fn gaussian(x: f64, width: f64) -> f64 {
    let q = x / width;
    (-q * q).exp()
}

/// Smooth maximum of `a` and `b` with a rounded blend of size `k` (same unit): exceeds
/// the true maximum by `k / 2` where `a == b` and by about `k² / (4 |a - b|)` elsewhere.
pub fn smooth_max(a: f64, b: f64, k: f64) -> f64 {
    0.5 * (a + b + ((a - b) * (a - b) + k * k).sqrt())
}

/// A function of one variable through knots `(x, value)` sorted by `x`: a cubic Hermite
/// spline with finite-difference (Catmull-Rom) tangents, flat outside the knots (C1).
pub fn profile(knots: &[(f64, f64)], x: f64) -> f64 {
    let n = knots.len();
    if x <= knots[0].0 {
        return knots[0].1;
    }
    if x >= knots[n - 1].0 {
        return knots[n - 1].1;
    }
    let k = knots.partition_point(|&(kx, _)| kx <= x) - 1;
    let tangent = |i: usize| -> f64 {
        if i == 0 || i == n - 1 {
            0.0
        } else {
            (knots[i + 1].1 - knots[i - 1].1) / (knots[i + 1].0 - knots[i - 1].0)
        }
    };
    let (x0, y0) = knots[k];
    let (x1, y1) = knots[k + 1];
    let width = x1 - x0;
    let t = (x - x0) / width;
    let (t2, t3) = (t * t, t * t * t);
    (2.0 * t3 - 3.0 * t2 + 1.0) * y0
        + (t3 - 2.0 * t2 + t) * width * tangent(k)
        + (-2.0 * t3 + 3.0 * t2) * y1
        + (t3 - t2) * width * tangent(k + 1)
}

/// A monotone map from `[0, 1]` onto `[start, end]` whose local step is inversely
/// proportional to a positive density: equal density-weighted length per step.
/// Piecewise linear through a fine table.
pub struct Warp {
    /// Domain values at equal steps of cumulative density.
    domain: Vec<f64>,
    /// Cumulative density at each `domain` value, normalised to `[0, 1]`.
    cumulative: Vec<f64>,
}

impl Warp {
    /// Tabulates `density` (positive) at `samples + 1` points of `[start, end]`.
    pub fn new(start: f64, end: f64, samples: usize, density: impl Fn(f64) -> f64) -> Warp {
        let step = (end - start) / samples as f64;
        let domain: Vec<f64> = (0..=samples).map(|i| start + step * i as f64).collect();
        let mut cumulative = Vec::with_capacity(samples + 1);
        let mut total = 0.0;
        let mut previous = density(start);
        cumulative.push(0.0);
        for &x in &domain[1..] {
            let current = density(x);
            total += 0.5 * (previous + current) * step;
            cumulative.push(total);
            previous = current;
        }
        for c in &mut cumulative {
            *c /= total;
        }
        Warp { domain, cumulative }
    }

    /// The domain value at fraction `u` of the cumulative density.
    pub fn at(&self, u: f64) -> f64 {
        interpolate(&self.cumulative, &self.domain, u)
    }
}

/// Piecewise-linear interpolation of `ys` over increasing `xs`, clamped at the ends.
pub fn interpolate(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    let n = xs.len();
    if x <= xs[0] {
        return ys[0];
    }
    if x >= xs[n - 1] {
        return ys[n - 1];
    }
    let k = xs.partition_point(|&v| v <= x) - 1;
    let t = (x - xs[k]) / (xs[k + 1] - xs[k]);
    ys[k] + t * (ys[k + 1] - ys[k])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_passes_through_knots_and_is_flat_outside() {
        let knots = [(0.0, 1.0), (1.0, 3.0), (3.0, 2.0)];
        for &(x, y) in &knots {
            assert!((profile(&knots, x) - y).abs() < 1e-12);
        }
        assert_eq!(profile(&knots, -5.0), 1.0);
        assert_eq!(profile(&knots, 9.0), 2.0);
    }

    #[test]
    fn warp_of_constant_density_is_linear() {
        let warp = Warp::new(2.0, 6.0, 100, |_| 3.0);
        assert!((warp.at(0.25) - 3.0).abs() < 1e-12);
        assert_eq!(warp.at(0.0), 2.0);
        assert_eq!(warp.at(1.0), 6.0);
    }

    #[test]
    fn smooth_max_is_close_to_max_away_from_equality() {
        assert!((smooth_max(10.0, 0.0, 1.0) - 10.0).abs() < 0.03);
        assert!((smooth_max(5.0, 5.0, 2.0) - 6.0).abs() < 1e-12);
    }
}
