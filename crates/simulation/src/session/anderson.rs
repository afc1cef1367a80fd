//! Anderson mixing (Walker and Ni, "Anderson Acceleration for Fixed-Point Iterations",
//! SIAM J. Numer. Anal. 49, 2011) of stage 1's lagged cycles: with the operators kept,
//! a cycle is a fixed map `u ↦ u + M⁻¹ r(u)`, and mixing its last steps recovers the
//! directions in which that map converges slowly (the rotations that moved since `M`
//! was assembled). A handful of vectors per session; no crate offers it over `DVec3`
//! fields.

use glam::DVec3;
use std::collections::VecDeque;

/// The history of one run of cycles of the same map: the iterates each cycle started
/// from and the steps it took.
#[derive(Debug, Clone, Default)]
pub(crate) struct AndersonMixing {
    depth: usize,
    history: VecDeque<Cycle>,
}

/// One cycle of the map: where it started and the step it took (one entry per vertex).
#[derive(Debug, Clone)]
struct Cycle {
    start: Vec<DVec3>,
    step: Vec<DVec3>,
}

/// `a - b`, entry by entry.
fn difference(a: &[DVec3], b: &[DVec3]) -> Vec<DVec3> {
    a.iter().zip(b).map(|(x, y)| *x - *y).collect()
}

impl AndersonMixing {
    /// Mixing of up to `depth` earlier steps with the last (0: none).
    pub(crate) fn new(depth: usize) -> AndersonMixing {
        AndersonMixing {
            depth,
            history: VecDeque::with_capacity(depth + 1),
        }
    }

    /// Forgets the history (the map changed).
    pub(crate) fn clear(&mut self) {
        self.history.clear();
    }

    /// Records the cycle from `start` to `u` (one entry per vertex) and replaces `u` by
    /// the mix: `u = x + f - Σ γⱼ (Δxⱼ + Δfⱼ)` with `x` the start, `f = u - x` the step,
    /// `Δ` the differences of consecutive starts and steps, and `γ` minimising
    /// `|f - Σ γⱼ Δfⱼ|`. Entries the map does not move (held vertices) stay. Without
    /// history, or if the least-squares problem is singular, `u` is left as it is.
    pub(crate) fn mix(&mut self, start: &[DVec3], u: &mut [DVec3]) {
        if self.depth == 0 {
            return;
        }
        if self.history.len() > self.depth {
            self.history.pop_front();
        }
        self.history.push_back(Cycle {
            start: start.to_vec(),
            step: difference(u, start),
        });
        let m = self.history.len() - 1;
        if m == 0 {
            return;
        }
        let h = &self.history;
        let d_step: Vec<Vec<DVec3>> = (0..m)
            .map(|j| difference(&h[j + 1].step, &h[j].step))
            .collect();
        let d_start: Vec<Vec<DVec3>> = (0..m)
            .map(|j| difference(&h[j + 1].start, &h[j].start))
            .collect();
        let f = &h[m].step;
        let dot = |a: &[DVec3], b: &[DVec3]| a.iter().zip(b).map(|(x, y)| x.dot(*y)).sum();
        let gram: Vec<Vec<f64>> = (0..m)
            .map(|i| (0..m).map(|j| dot(&d_step[i], &d_step[j])).collect())
            .collect();
        let rhs: Vec<f64> = (0..m).map(|i| dot(&d_step[i], f)).collect();
        let Some(gamma) = solve_normal_equations(gram, rhs) else {
            return;
        };
        for (k, out) in u.iter_mut().enumerate() {
            let mut x = start[k] + f[k];
            for j in 0..m {
                x -= (d_start[j][k] + d_step[j][k]) * gamma[j];
            }
            *out = x;
        }
    }
}

/// Relative regularisation of the normal equations (times their trace): only guards
/// against exactly parallel steps; larger values (1e-10) already cost the mixing its
/// exactness on a slowly contracting linear map (the unit test below).
const REGULARISATION: f64 = 1e-14;

/// `γ` with `(G + εI) γ = b` for the small symmetric positive semidefinite Gram matrix
/// `G` (Cholesky; `None` if it is not positive definite even so, or not finite).
fn solve_normal_equations(mut gram: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let m = b.len();
    let trace: f64 = (0..m).map(|i| gram[i][i]).sum();
    for (i, row) in gram.iter_mut().enumerate() {
        row[i] += REGULARISATION * trace;
    }
    // in-place Cholesky factor L (lower triangle) with L Lᵀ = G
    for j in 0..m {
        let d = gram[j][j] - (0..j).map(|k| gram[j][k] * gram[j][k]).sum::<f64>();
        if d.is_nan() || d <= 0.0 {
            return None;
        }
        gram[j][j] = d.sqrt();
        for i in j + 1..m {
            let s = gram[i][j] - (0..j).map(|k| gram[i][k] * gram[j][k]).sum::<f64>();
            gram[i][j] = s / gram[j][j];
        }
    }
    for i in 0..m {
        b[i] = (b[i] - (0..i).map(|k| gram[i][k] * b[k]).sum::<f64>()) / gram[i][i];
    }
    for i in (0..m).rev() {
        b[i] = (b[i] - (i + 1..m).map(|k| gram[k][i] * b[k]).sum::<f64>()) / gram[i][i];
    }
    b.iter().all(|x| x.is_finite()).then_some(b)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// On a linear fixed-point map `x ↦ G x + c` of dimension n, Anderson mixing with
    /// depth n is GMRES in disguise (Walker and Ni 2011, Theorem 2.2): it reaches the
    /// fixed point after n + 1 steps, where the plain iteration is still far off. The
    /// map here contracts slowly (spectral radius 0.9), so the plain iteration's error
    /// after 4 steps is still about 0.9⁴ of the start's; the mixed one is exact to
    /// round-off (bound 1e-9 against a solution of order 1).
    #[test]
    fn mixing_a_linear_map_reaches_its_fixed_point_in_dimension_plus_one_steps() {
        let g = DMat3::from_cols_array(&[0.9, 0.05, 0.0, -0.1, 0.5, 0.2, 0.0, 0.1, -0.3]);
        let c = DVec3::new(1.0, -2.0, 0.5);
        let fixed = (DMat3::IDENTITY - g).inverse() * c;
        let map = |x: DVec3| g * x + c;
        let mut mixing = AndersonMixing::new(3);
        let (mut mixed, mut plain) = (vec![DVec3::ZERO], DVec3::ZERO);
        for _ in 0..4 {
            let start = mixed.clone();
            mixed[0] = map(start[0]);
            mixing.mix(&start, &mut mixed);
            plain = map(plain);
        }
        let error = mixed[0].distance(fixed);
        assert!(error < 1e-9, "mixed {error}");
        assert!(
            plain.distance(fixed) > 0.1,
            "plain {}",
            plain.distance(fixed)
        );
    }

    /// Without depth, or on the first step, the iterate is the map's own; after a clear
    /// the history starts again.
    #[test]
    fn the_first_step_after_a_clear_is_the_maps_own() {
        let mut mixing = AndersonMixing::new(2);
        let mut u = vec![DVec3::X];
        mixing.mix(&[DVec3::ZERO], &mut u);
        assert_eq!(u, vec![DVec3::X]);
        let mut v = vec![DVec3::new(1.5, 0.0, 0.0)];
        mixing.clear();
        mixing.mix(&[DVec3::X], &mut v);
        assert_eq!(v, vec![DVec3::new(1.5, 0.0, 0.0)]);
        let mut none = AndersonMixing::new(0);
        let mut w = vec![DVec3::Y];
        none.mix(&[DVec3::ZERO], &mut w);
        none.mix(&[DVec3::Y], &mut w);
        assert_eq!(w, vec![DVec3::Y]);
    }
}
