//! Conjugate gradients preconditioned by the symmetric V-cycle.

use super::{Multigrid, dot, norm, residual};
use glam::DVec3;
use rayon::prelude::*;

/// Conjugate gradients on the assembled finest system of a [`Multigrid`], preconditioned
/// by one symmetric V(ν₁, ν₁) cycle from zero per iteration
/// ([`Multigrid::symmetric_vcycle`]), one iteration per [`PcgIteration::step`]: for
/// interactive use, where the caller may stop after any iteration. [`Multigrid::pcg`]
/// runs it to a tolerance. `β` has the Polak-Ribière form (equal to the usual one with a
/// symmetric preconditioner, and forgiving of rounding). The interactive V(2,1) cycle is
/// not symmetric, and as a preconditioner it made conjugate gradients stall where the
/// system is badly conditioned: the gravity correction on the shared scan
/// `v02_average` (60k elements, R-MOD-120 on both sides, implant elements at 1% of the
/// tissue's stiffness) went from a relative residual of 1.5e-2 only to 2.4e-3 in 40
/// iterations; with V(2,2) it reached 8.1e-4 in 21 (V(1,1): 28). On the phantom 6
/// iterations instead of 7, on `pair1_pre` (100 x 30 mm round implants) 10 instead of
/// 12, each about a third dearer.
#[derive(Debug, Clone)]
pub struct PcgIteration {
    x: Vec<DVec3>,
    r: Vec<DVec3>,
    z: Vec<DVec3>,
    z_old: Vec<DVec3>,
    p: Vec<DVec3>,
    ap: Vec<DVec3>,
    rz_old: f64,
    iterations: usize,
}

impl PcgIteration {
    /// Starts from `x` on `A x = b` (`A` the finest system `mg` has assembled).
    ///
    /// # Panics
    /// Before the first [`Multigrid::assemble`], or on length mismatches.
    pub fn new(mg: &mut Multigrid, b: &[DVec3], x: Vec<DVec3>) -> PcgIteration {
        let n = b.len();
        assert_eq!(x.len(), n, "PcgIteration: x and b differ in length");
        let mut r = vec![DVec3::ZERO; n];
        if x.iter().all(|xi| *xi == DVec3::ZERO) {
            r.copy_from_slice(b);
        } else {
            residual(mg.levels[0].op(), &x, b, &mut r);
        }
        PcgIteration::starting(x, r)
    }

    /// Starts from the multiple `α g` of a guess `g` (a related system's solution: the
    /// same problem before a small change) closest to the solution in the energy norm,
    /// `α = gᵀb / gᵀAg` (zero when `gᵀAg` is not positive): never further from the
    /// solution in that norm than a start from zero. The guess is zero at eliminated
    /// unknowns (their rows are the identity with a zero right-hand side).
    ///
    /// # Panics
    /// Before the first [`Multigrid::assemble`], or on length mismatches.
    pub fn from_guess(mg: &mut Multigrid, b: &[DVec3], guess: Vec<DVec3>) -> PcgIteration {
        let n = b.len();
        assert_eq!(guess.len(), n, "PcgIteration: guess and b differ in length");
        let mut a_guess = vec![DVec3::ZERO; n];
        mg.levels[0].op().mul_vec(&guess, &mut a_guess);
        let energy = dot(&guess, &a_guess);
        let alpha = if energy > 0.0 {
            dot(&guess, b) / energy
        } else {
            0.0
        };
        let x: Vec<DVec3> = guess.iter().map(|g| *g * alpha).collect();
        let r: Vec<DVec3> = b
            .iter()
            .zip(&a_guess)
            .map(|(bi, agi)| *bi - *agi * alpha)
            .collect();
        PcgIteration::starting(x, r)
    }

    fn starting(x: Vec<DVec3>, r: Vec<DVec3>) -> PcgIteration {
        let n = x.len();
        PcgIteration {
            x,
            r,
            z: vec![DVec3::ZERO; n],
            z_old: vec![DVec3::ZERO; n],
            p: vec![DVec3::ZERO; n],
            ap: vec![DVec3::ZERO; n],
            rz_old: 0.0,
            iterations: 0,
        }
    }

    /// One iteration (one symmetric V-cycle and one matrix-vector product).
    pub fn step(&mut self, mg: &mut Multigrid) {
        self.z.fill(DVec3::ZERO);
        mg.symmetric_vcycle(&mut self.z, &self.r);
        let rz = dot(&self.r, &self.z);
        if self.iterations == 0 {
            self.p.copy_from_slice(&self.z);
        } else {
            let beta = (rz - dot(&self.r, &self.z_old)) / self.rz_old;
            self.p
                .par_iter_mut()
                .zip(&self.z)
                .for_each(|(pi, zi)| *pi = *zi + *pi * beta);
        }
        mg.levels[0].op().mul_vec(&self.p, &mut self.ap);
        let alpha = rz / dot(&self.p, &self.ap);
        self.x
            .par_iter_mut()
            .zip(&self.p)
            .for_each(|(xi, pi)| *xi += *pi * alpha);
        self.r
            .par_iter_mut()
            .zip(&self.ap)
            .for_each(|(ri, api)| *ri -= *api * alpha);
        std::mem::swap(&mut self.z, &mut self.z_old);
        self.rz_old = rz;
        self.iterations += 1;
    }

    /// `‖b - A x‖₂` (the recurrence's residual).
    pub fn residual_norm(&self) -> f64 {
        norm(&self.r)
    }

    /// The current iterate `x`.
    pub fn solution(&self) -> &[DVec3] {
        &self.x
    }

    /// The iterations taken so far.
    pub fn iterations(&self) -> usize {
        self.iterations
    }
}

/// Outcome of [`Multigrid::pcg`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PcgResult {
    /// CG iterations (one V-cycle each).
    pub iterations: usize,
    /// `‖b - A x‖₂ / ‖b‖₂` at the end.
    pub relative_residual: f64,
    /// Whether the tolerance was reached.
    pub converged: bool,
}

impl Multigrid {
    /// Conjugate gradients on the assembled finest system, preconditioned by one
    /// symmetric V-cycle from zero per iteration ([`PcgIteration`]). Starts from `x`;
    /// stops when
    /// `‖b - A x‖₂ ≤ relative_tolerance · ‖b‖₂` or after `max_iterations`.
    pub fn pcg(
        &mut self,
        b: &[DVec3],
        x: &mut [DVec3],
        relative_tolerance: f64,
        max_iterations: usize,
    ) -> PcgResult {
        let bnorm = norm(b);
        if bnorm == 0.0 {
            x.fill(DVec3::ZERO);
            return PcgResult {
                iterations: 0,
                relative_residual: 0.0,
                converged: true,
            };
        }
        let mut cg = PcgIteration::new(self, b, x.to_vec());
        let mut rel = cg.residual_norm() / bnorm;
        while rel > relative_tolerance && cg.iterations < max_iterations {
            cg.step(self);
            rel = cg.residual_norm() / bnorm;
        }
        x.copy_from_slice(&cg.x);
        PcgResult {
            iterations: cg.iterations,
            relative_residual: rel,
            converged: rel <= relative_tolerance,
        }
    }
}
