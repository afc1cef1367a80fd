//! Direct reference solver: faer's sparse Cholesky (LLᵀ) of the reduced system, with
//! the symbolic factorisation (fill-reducing ordering, elimination tree) computed once
//! per pattern and reused for every numeric refactorisation.

use crate::error::FemError;
use crate::system::BlockCsr;
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::solvers::{Llt, SymbolicLlt};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMat};
use faer::{Mat, Side};
use glam::DVec3;

/// Sparse Cholesky solver of a block-CSR system with a fixed pattern.
#[derive(Debug, Clone)]
pub struct DirectSolver {
    /// Upper triangle of the scalar matrix, column-compressed.
    symbolic_matrix: SymbolicSparseColMat<usize>,
    /// For each scalar entry, its index in the flattened block values (`slot * 9 + k`).
    gather: Vec<usize>,
    values: Vec<f64>,
    symbolic: SymbolicLlt<usize>,
    pattern_slots: usize,
    /// The numeric factor of the last [`DirectSolver::factorise`].
    factor: Option<Llt<usize, f64>>,
}

impl DirectSolver {
    /// Builds the scalar pattern (upper triangle) and its symbolic factorisation for the
    /// pattern of `a`, which must be structurally and numerically symmetric.
    pub fn new(a: &BlockCsr) -> Result<DirectSolver, FemError> {
        let nb = a.block_rows();
        let n = 3 * nb;
        let mut col_ptr = Vec::with_capacity(n + 1);
        col_ptr.push(0usize);
        let mut row_idx = Vec::new();
        let mut gather = Vec::new();
        // column c = 3I + q holds rows r = 3J + p <= c; by symmetry
        // A[3J+p][3I+q] = block(I, J)[q][p], read from block row I
        for i in 0..nb {
            for q in 0..3 {
                let c = 3 * i + q;
                for s in a.row_ptr[i]..a.row_ptr[i + 1] {
                    let j = a.cols[s] as usize;
                    if j > i {
                        break;
                    }
                    for p in 0..3 {
                        let r = 3 * j + p;
                        if r <= c {
                            row_idx.push(r);
                            gather.push(s * 9 + 3 * q + p);
                        }
                    }
                }
                col_ptr.push(row_idx.len());
            }
        }
        let symbolic_matrix = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let symbolic =
            SymbolicLlt::try_new(symbolic_matrix.as_ref(), Side::Upper).map_err(|e| {
                FemError::Singular {
                    detail: format!("symbolic factorisation failed: {e:?}"),
                }
            })?;
        let values = vec![0.0; gather.len()];
        Ok(DirectSolver {
            symbolic_matrix,
            gather,
            values,
            symbolic,
            pattern_slots: a.values.len(),
            factor: None,
        })
    }

    /// Factorises the current values of `a` (same pattern as at construction) and solves
    /// `a x = b`.
    pub fn solve(&mut self, a: &BlockCsr, b: &[DVec3]) -> Result<Vec<DVec3>, FemError> {
        self.factorise(a)?;
        let mut x = vec![DVec3::ZERO; b.len()];
        self.solve_factorised(b, &mut x);
        Ok(x)
    }

    /// Factorises the current values of `a` (same pattern as at construction) and keeps
    /// the factor for [`DirectSolver::solve_factorised`].
    pub fn factorise(&mut self, a: &BlockCsr) -> Result<(), FemError> {
        assert_eq!(
            a.values.len(),
            self.pattern_slots,
            "DirectSolver: the block pattern changed"
        );
        let flat = a.values.as_flattened();
        for (v, &g) in self.values.iter_mut().zip(&self.gather) {
            *v = flat[g];
        }
        let mat = SparseColMatRef::new(self.symbolic_matrix.as_ref(), &self.values);
        let llt =
            Llt::try_new_with_symbolic(self.symbolic.clone(), mat, Side::Upper).map_err(|e| {
                FemError::Singular {
                    detail: format!("{e}"),
                }
            })?;
        self.factor = Some(llt);
        Ok(())
    }

    /// Solves `a x = b` with the factor of the last [`DirectSolver::factorise`]. Panics
    /// if nothing was factorised yet.
    pub fn solve_factorised(&self, b: &[DVec3], x: &mut [DVec3]) {
        let llt = self
            .factor
            .as_ref()
            .expect("DirectSolver::factorise before solve_factorised");
        let mut rhs = Mat::<f64>::from_fn(3 * b.len(), 1, |r, _| b[r / 3][r % 3]);
        llt.solve_in_place(rhs.as_mut());
        for (k, xk) in x.iter_mut().enumerate() {
            *xk = DVec3::new(rhs[(3 * k, 0)], rhs[(3 * k + 1, 0)], rhs[(3 * k + 2, 0)]);
        }
    }
}
