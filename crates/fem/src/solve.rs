//! The static solve: corotational fixed-point (Newton-like) iteration with the direct
//! solver. Each iteration re-estimates the element rotations from the current
//! displacement, reassembles `K'_ff` and `r_f = f_ext - f_int(u)`, and solves
//! `K'_ff Δu_f = r_f`. `K'` is the exact tangent with the rotations held fixed (the
//! derivative of the rotations is neglected, as in the corotational literature), so the
//! linear formulation converges in one iteration and the corotated one linearly, fast for
//! moderate rotations.

use crate::direct::DirectSolver;
use crate::error::FemError;
use crate::model::{FemModel, Formulation, Tangent};
use crate::system::{Constraints, ReducedSystem};
use glam::DVec3;

/// Options of [`StaticSolver::solve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveOptions {
    /// Linear or corotated strain.
    pub formulation: Formulation,
    /// Tangent of the corotated iteration: [`Tangent::Full`] (Newton, robust) or
    /// [`Tangent::Warped`] (the paper's fixed-point iteration).
    pub tangent: Tangent,
    /// Most corotational iterations (each one assembly and one factorisation).
    pub max_iterations: usize,
    /// Stop when `‖r_f‖₂ ≤ relative_tolerance · max(‖f_ext‖₂, ‖f_int‖₂)`, where `f_int`
    /// is the internal force at all vertices (so reaction forces set the scale of a
    /// purely displacement-driven problem).
    pub relative_tolerance: f64,
}

impl Default for SolveOptions {
    /// Corotated, full tangent, 100 iterations, relative tolerance 1e-9 (rounding
    /// floors the relative residual near 1e-11 at strains of 1e-3).
    fn default() -> Self {
        SolveOptions {
            formulation: Formulation::Corotated,
            tangent: Tangent::Full,
            max_iterations: 100,
            relative_tolerance: 1e-9,
        }
    }
}

/// Result of [`StaticSolver::solve`].
#[derive(Debug, Clone, PartialEq)]
pub struct StaticSolution {
    /// Displacement of every vertex (mm); prescribed values at constrained vertices.
    pub displacement: Vec<DVec3>,
    /// Linear solves performed.
    pub iterations: usize,
    /// Final `‖r_f‖₂ / max(‖f_ext‖₂, ‖f_int‖₂)` (0 when both are 0).
    pub relative_residual: f64,
    /// Whether the tolerance was met within the iteration limit.
    pub converged: bool,
}

/// A static solver for one model and one set of constrained vertices; keeps the block
/// pattern and the symbolic Cholesky factorisation across solves (the prescribed values
/// may change between solves through [`StaticSolver::set_prescribed`]).
#[derive(Debug, Clone)]
pub struct StaticSolver {
    system: ReducedSystem,
    direct: Option<DirectSolver>,
}

impl StaticSolver {
    /// Builds the reduced pattern and its symbolic factorisation.
    ///
    /// Errors: see [`ReducedSystem::new`] (no constraints, bad constraint).
    pub fn new(model: &FemModel, constraints: &Constraints) -> Result<StaticSolver, FemError> {
        let system = ReducedSystem::new(model, constraints)?;
        let direct = if system.unknowns() > 0 {
            Some(DirectSolver::new(&system.matrix)?)
        } else {
            None
        };
        Ok(StaticSolver { system, direct })
    }

    /// The reduced system of the latest assembly.
    pub fn system(&self) -> &ReducedSystem {
        &self.system
    }

    /// Changes the prescribed displacement of an already constrained vertex.
    ///
    /// Errors: the vertex is free (that would change the pattern), or `d` is not finite.
    pub fn set_prescribed(&mut self, vertex: u32, d: DVec3) -> Result<(), FemError> {
        let v = vertex as usize;
        if v >= self.system.reduced_of.len() || self.system.reduced_of[v] != crate::system::NOT_FREE
        {
            return Err(FemError::ConstraintOutOfRange {
                vertex: v,
                vertex_count: self.system.reduced_of.len(),
            });
        }
        if !d.is_finite() {
            return Err(FemError::NonFiniteInput {
                what: "prescribed displacement",
                vertex: v,
                value: d.to_array(),
            });
        }
        self.system.prescribed[v] = d;
        Ok(())
    }

    /// Solves the static problem `f_int(u) = f_ext` at the free vertices with the
    /// prescribed displacements, from `initial` (warm start; prescribed values are
    /// imposed on it) or from zero. `f_ext` (mN per vertex) may be empty.
    pub fn solve(
        &mut self,
        model: &FemModel,
        f_ext: &[DVec3],
        initial: Option<&[DVec3]>,
        options: &SolveOptions,
    ) -> Result<StaticSolution, FemError> {
        let mut u_free: Vec<DVec3> = match initial {
            Some(u0) => {
                model.check_vertex_field("initial displacement", u0)?;
                self.system.free.iter().map(|&v| u0[v as usize]).collect()
            }
            None => vec![DVec3::ZERO; self.system.unknowns()],
        };
        let f_ext_norm = f_ext.iter().map(|f| f.length_squared()).sum::<f64>().sqrt();
        let mut iterations = 0;
        loop {
            let u = self.system.expand(&u_free);
            self.system
                .assemble(model, &u, f_ext, options.formulation, options.tangent)?;
            let r_norm = self
                .system
                .rhs
                .iter()
                .map(|r| r.length_squared())
                .sum::<f64>()
                .sqrt();
            let scale = f_ext_norm.max(internal_force_norm(model, &self.system, &u));
            let relative_residual = if r_norm == 0.0 { 0.0 } else { r_norm / scale };
            let converged = relative_residual <= options.relative_tolerance;
            if converged || iterations >= options.max_iterations || self.direct.is_none() {
                return Ok(StaticSolution {
                    displacement: u,
                    iterations,
                    relative_residual,
                    converged: converged || self.direct.is_none(),
                });
            }
            let direct = self.direct.as_mut().expect("unknowns exist");
            let du = direct.solve(&self.system.matrix, &self.system.rhs)?;
            iterations += 1;
            if du.iter().any(|d| !d.is_finite()) {
                return Err(FemError::NonFiniteSolution {
                    iteration: iterations,
                });
            }
            let alpha = if options.formulation == Formulation::Linear {
                1.0
            } else {
                self.line_search(model, f_ext, &u, &u_free, &du)
            };
            for (u, d) in u_free.iter_mut().zip(&du) {
                *u += *d * alpha;
            }
        }
    }
}

impl StaticSolver {
    /// Backtracking (Armijo) line search on the potential energy along `du`, which is a
    /// descent direction because `K'` is positive definite: returns the step length.
    /// Near convergence the energy differences drown in rounding, so the full step is
    /// taken when the decrease predicted by the slope is below rounding of the energy.
    fn line_search(
        &self,
        model: &FemModel,
        f_ext: &[DVec3],
        u: &[DVec3],
        u_free: &[DVec3],
        du: &[DVec3],
    ) -> f64 {
        let slope: f64 = -self
            .system
            .rhs
            .iter()
            .zip(du)
            .map(|(r, d)| r.dot(*d))
            .sum::<f64>();
        let e0 = model.potential_energy(u, f_ext, Formulation::Corotated);
        if slope >= 0.0 || -slope <= 1e-12 * e0.abs().max(f64::MIN_POSITIVE) {
            return 1.0;
        }
        let mut alpha = 1.0;
        for _ in 0..30 {
            let trial: Vec<DVec3> = u_free
                .iter()
                .zip(du)
                .map(|(u, d)| *u + *d * alpha)
                .collect();
            let e =
                model.potential_energy(&self.system.expand(&trial), f_ext, Formulation::Corotated);
            if e <= e0 + 1e-4 * alpha * slope {
                return alpha;
            }
            alpha *= 0.5;
        }
        alpha
    }
}

/// `‖f_int‖₂` over all vertices from the element forces of the latest assembly at
/// displacement `u`, the sliders' included.
fn internal_force_norm(model: &FemModel, system: &ReducedSystem, u: &[DVec3]) -> f64 {
    let mut f = system.nodal_forces(model);
    model.add_slider_forces(u, &mut f);
    f.iter().map(|x| x.length_squared()).sum::<f64>().sqrt()
}

/// Convenience: builds a [`StaticSolver`] and solves once from zero.
pub fn solve_static(
    model: &FemModel,
    constraints: &Constraints,
    f_ext: &[DVec3],
    options: &SolveOptions,
) -> Result<StaticSolution, FemError> {
    StaticSolver::new(model, constraints)?.solve(model, f_ext, None, options)
}
