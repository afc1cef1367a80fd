//! The coarsest level's solve: a sparse Cholesky factorisation of its shifted operator.

use super::{CoarseOperator, Multigrid};
use crate::error::FemError;

/// Relative shift of the diagonal of the coarsest Galerkin operator before its Cholesky
/// factorisation: `A + ε diag(A)`. `Pᵀ A P` is singular whenever the columns of `P`
/// restricted to the active finer unknowns are linearly dependent (e.g. two coarse
/// vertices that both see only one free fine vertex next to a large held patch); the
/// system `Pᵀ A P x = Pᵀ r` is then consistent and its null space is that of `P`, so the
/// shift changes the prolonged correction only by `O(ε)`, while the factorisation no
/// longer meets zero or negative pivots.
const COARSEST_SHIFT: f64 = 1e-8;

impl Multigrid {
    /// Shifts the diagonal of the coarsest Galerkin operator by [`COARSEST_SHIFT`] and
    /// refactorises the coarsest level's Cholesky factor.
    pub(super) fn factorise_coarsest(&mut self) -> Result<(), FemError> {
        let nl = self.levels.len();
        if nl > 1 && self.options.coarse_operator == CoarseOperator::Galerkin {
            let level = &mut self.levels[nl - 1];
            let g = level.galerkin.as_mut().expect("Galerkin operator");
            for &s in &level.diag_slot {
                for q in [0, 4, 8] {
                    g.op.values[s][q] *= 1.0 + COARSEST_SHIFT;
                }
            }
        }
        if let Some(c) = self.coarse.as_mut() {
            c.factorise(self.levels.last().expect("levels").op())
                .map_err(|error| match error {
                    FemError::Singular { detail } => FemError::Singular {
                        detail: format!("coarsest level: {detail}"),
                    },
                    other => other,
                })?;
        }
        Ok(())
    }
}
