//! Gauss-Legendre quadrature, used for implant volumes.

use std::f64::consts::PI;

/// Nodes and weights of the `n`-point Gauss-Legendre rule on [-1, 1], nodes ascending.
///
/// Exact for polynomials of degree up to `2n - 1`. Nodes are the roots of the Legendre
/// polynomial `P_n`, found by Newton's method from Tricomi's initial guesses, to about
/// 1e-15; the weights sum to 2 within a few ulps. `n = 0` gives an empty rule.
pub fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    let mut rule = vec![(0.0, 0.0); n];
    let nf = n as f64;
    for i in 0..n.div_ceil(2) {
        let mut x = (PI * (i as f64 + 0.75) / (nf + 0.5)).cos();
        for _ in 0..100 {
            let (p, dp) = legendre_with_derivative(n, x);
            let step = p / dp;
            x -= step;
            if step.abs() <= 1e-16 {
                break;
            }
        }
        let (_, derivative) = legendre_with_derivative(n, x);
        let weight = 2.0 / ((1.0 - x * x) * derivative * derivative);
        // Tricomi's guesses run from the largest root down.
        rule[n - 1 - i] = (x, weight);
        rule[i] = (-x, weight);
    }
    if n % 2 == 1 {
        // The middle node is exactly zero for odd n.
        rule[n / 2].0 = 0.0;
    }
    rule
}

/// `P_n(x)` and `P_n'(x)` by the three-term recurrence (|x| < 1).
fn legendre_with_derivative(n: usize, x: f64) -> (f64, f64) {
    let mut p_prev = 1.0;
    let mut p = x;
    if n == 0 {
        return (1.0, 0.0);
    }
    for k in 2..=n {
        let kf = k as f64;
        let p_next = ((2.0 * kf - 1.0) * x * p - (kf - 1.0) * p_prev) / kf;
        p_prev = p;
        p = p_next;
    }
    let dp = n as f64 * (x * p - p_prev) / (x * x - 1.0);
    (p, dp)
}
