//! The transfers between levels: the reduced prolongation `P`, its transpose, and the
//! smoothed prolongation `P_s`.

use super::{block_of, concat_rows};
use crate::system::{BlockCsr, split_rows};
use crate::transfer::Prolongation;
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Reduced prolongation from level `l + 1` (coarse) to level `l` (fine), CSR both ways,
/// and the sampling of the fine displacement at the coarse vertices.
#[derive(Debug, Clone)]
pub(super) struct Transfer {
    pub(super) p_ptr: Vec<usize>,
    pub(super) p_cols: Vec<u32>,
    /// Weights of `P` with the rows of inactive fine unknowns and the columns of inactive
    /// coarse unknowns zeroed (see [`Multigrid::set_constraints`]).
    ///
    /// [`Multigrid::set_constraints`]: super::Multigrid::set_constraints
    pub(super) p_w: Vec<f64>,
    /// Weights of `P` over the pattern's unknowns (before masking).
    pub(super) p_w_full: Vec<f64>,
    /// `Pᵀ`: rows are coarse unknowns.
    pub(super) pt_ptr: Vec<usize>,
    pub(super) pt_cols: Vec<u32>,
    pub(super) pt_w: Vec<f64>,
    /// For each entry of `Pᵀ`, its entry in `P`.
    pub(super) pt_src: Vec<usize>,
    /// Coarse vertices located in the fine mesh (rows: coarse vertices).
    pub(super) sample: Prolongation,
    /// The smoothed prolongation replacing `P` in the cycle and the Galerkin product
    /// (finest transfer with [`MultigridOptions::prolongation_smoothing`] > 0).
    ///
    /// [`MultigridOptions::prolongation_smoothing`]: super::MultigridOptions::prolongation_smoothing
    pub(super) smoothed: Option<SmoothedProlongation>,
}

/// `P_s = (I - ω D⁻¹ A) P` with 3x3 blocks (rows: fine unknowns, columns: coarse
/// unknowns), its transpose's pattern, and `Q = A P_s` for the Galerkin product. The
/// patterns are built once; the values follow every assembly of `A` (and the masked `P`).
#[derive(Debug, Clone)]
pub(super) struct SmoothedProlongation {
    pub(super) omega: f64,
    pub(super) ptr: Vec<usize>,
    pub(super) cols: Vec<u32>,
    pub(super) w: Vec<DMat3>,
    /// `P_sᵀ`: rows are coarse unknowns; `t_src` gives the entry of `P_s`.
    pub(super) t_ptr: Vec<usize>,
    pub(super) t_cols: Vec<u32>,
    pub(super) t_src: Vec<usize>,
    /// `Q = A P_s` (rows: fine unknowns).
    pub(super) q_ptr: Vec<usize>,
    pub(super) q_cols: Vec<u32>,
    pub(super) q: Vec<DMat3>,
}

impl Transfer {
    /// The reduced transfer from `p` (coarse to fine, all vertices) restricted to the
    /// unknowns of both levels, with its transpose.
    pub(super) fn new(
        p: Prolongation,
        sample: Prolongation,
        fine_reduced_of: &[u32],
        coarse_reduced_of: &[u32],
        coarse_unknowns: usize,
    ) -> Transfer {
        let (p_ptr, mut p_cols, mut p_w) = p.reduced(fine_reduced_of, coarse_reduced_of);
        // columns ascending within each row (the Galerkin product skips a row's low end)
        for f in 0..p_ptr.len() - 1 {
            let mut row: Vec<(u32, f64)> = (p_ptr[f]..p_ptr[f + 1])
                .map(|k| (p_cols[k], p_w[k]))
                .collect();
            row.sort_unstable_by_key(|&(c, _)| c);
            for (k, (c, w)) in (p_ptr[f]..).zip(row) {
                p_cols[k] = c;
                p_w[k] = w;
            }
        }
        let nc = coarse_unknowns;
        let mut count = vec![0usize; nc + 1];
        for &c in &p_cols {
            count[c as usize + 1] += 1;
        }
        for i in 0..nc {
            count[i + 1] += count[i];
        }
        let pt_ptr = count.clone();
        let mut fill = count;
        let mut pt_cols = vec![0u32; p_cols.len()];
        let mut pt_w = vec![0.0; p_cols.len()];
        let mut pt_src = vec![0usize; p_cols.len()];
        for f in 0..p_ptr.len() - 1 {
            for k in p_ptr[f]..p_ptr[f + 1] {
                let c = p_cols[k] as usize;
                pt_cols[fill[c]] = f as u32;
                pt_w[fill[c]] = p_w[k];
                pt_src[fill[c]] = k;
                fill[c] += 1;
            }
        }
        Transfer {
            p_ptr,
            p_cols,
            p_w_full: p_w.clone(),
            p_w,
            pt_ptr,
            pt_cols,
            pt_w,
            pt_src,
            sample,
            smoothed: None,
        }
    }

    /// Zeroes the rows of inactive fine unknowns and the columns of inactive coarse
    /// unknowns of `P` and `Pᵀ`.
    pub(super) fn mask(&mut self, fine_active: &[bool], coarse_active: &[bool]) {
        for (f, &fa) in fine_active.iter().enumerate() {
            for k in self.p_ptr[f]..self.p_ptr[f + 1] {
                let c = self.p_cols[k] as usize;
                self.p_w[k] = if fa && coarse_active[c] {
                    self.p_w_full[k]
                } else {
                    0.0
                };
            }
        }
        for (w, &k) in self.pt_w.iter_mut().zip(&self.pt_src) {
            *w = self.p_w[k];
        }
    }
}

/// CSR rows `i` of `a` (block pattern) times the rows of `(b_ptr, b_cols)`: for each
/// row the sorted union of the `b` columns over the columns of `a`'s row.
fn product_pattern(a: &BlockCsr, b_ptr: &[usize], b_cols: &[u32]) -> (Vec<usize>, Vec<u32>) {
    let rows: Vec<Vec<u32>> = (0..a.block_rows())
        .into_par_iter()
        .map(|i| {
            let mut cols = Vec::new();
            for s in a.row_ptr[i]..a.row_ptr[i + 1] {
                let g = a.cols[s] as usize;
                cols.extend_from_slice(&b_cols[b_ptr[g]..b_ptr[g + 1]]);
            }
            cols.sort_unstable();
            cols.dedup();
            cols
        })
        .collect();
    concat_rows(rows)
}

impl SmoothedProlongation {
    /// The patterns for the fine operator pattern `a` and the transfer `t`.
    pub(super) fn new(a: &BlockCsr, t: &Transfer, omega: f64) -> SmoothedProlongation {
        let (ptr, cols) = product_pattern(a, &t.p_ptr, &t.p_cols);
        let nc = t.pt_ptr.len() - 1;
        let mut t_ptr = vec![0usize; nc + 1];
        for &c in &cols {
            t_ptr[c as usize + 1] += 1;
        }
        for i in 0..nc {
            t_ptr[i + 1] += t_ptr[i];
        }
        let mut fill = t_ptr.clone();
        let mut t_cols = vec![0u32; cols.len()];
        let mut t_src = vec![0usize; cols.len()];
        for f in 0..ptr.len() - 1 {
            for (k, &c) in cols.iter().enumerate().take(ptr[f + 1]).skip(ptr[f]) {
                let c = c as usize;
                t_cols[fill[c]] = f as u32;
                t_src[fill[c]] = k;
                fill[c] += 1;
            }
        }
        let (q_ptr, q_cols) = product_pattern(a, &ptr, &cols);
        SmoothedProlongation {
            omega,
            w: vec![DMat3::ZERO; cols.len()],
            ptr,
            cols,
            t_ptr,
            t_cols,
            t_src,
            q: vec![DMat3::ZERO; q_cols.len()],
            q_ptr,
            q_cols,
        }
    }

    /// Recomputes `P_s` from the masked `P` of `t`, the fine operator `a` and its inverse
    /// diagonal blocks, then `Q = A P_s` (parallel over fine rows).
    pub(super) fn update(&mut self, a: &BlockCsr, inv_diag: &[DMat3], t: &Transfer) {
        let nc = t.pt_ptr.len() - 1;
        let omega = self.omega;
        let (ptr, cols) = (&self.ptr, &self.cols);
        split_rows(&mut self.w, ptr)
            .into_par_iter()
            .enumerate()
            .for_each_init(
                || vec![u32::MAX; nc],
                |pos, (f, out)| {
                    let rc = &cols[ptr[f]..ptr[f + 1]];
                    for (k, &c) in rc.iter().enumerate() {
                        pos[c as usize] = k as u32;
                    }
                    out.fill(DMat3::ZERO);
                    for k in t.p_ptr[f]..t.p_ptr[f + 1] {
                        out[pos[t.p_cols[k] as usize] as usize] +=
                            DMat3::from_diagonal(DVec3::splat(t.p_w[k]));
                    }
                    for s in a.row_ptr[f]..a.row_ptr[f + 1] {
                        let g = a.cols[s] as usize;
                        let m = inv_diag[f] * block_of(&a.values[s]) * omega;
                        for k in t.p_ptr[g]..t.p_ptr[g + 1] {
                            if t.p_w[k] != 0.0 {
                                out[pos[t.p_cols[k] as usize] as usize] -= m * t.p_w[k];
                            }
                        }
                    }
                    for &c in rc {
                        pos[c as usize] = u32::MAX;
                    }
                },
            );
        let (w, q_ptr, q_cols) = (&self.w, &self.q_ptr, &self.q_cols);
        split_rows(&mut self.q, q_ptr)
            .into_par_iter()
            .enumerate()
            .for_each_init(
                || vec![u32::MAX; nc],
                |pos, (f, out)| {
                    let rc = &q_cols[q_ptr[f]..q_ptr[f + 1]];
                    for (k, &c) in rc.iter().enumerate() {
                        pos[c as usize] = k as u32;
                    }
                    out.fill(DMat3::ZERO);
                    for s in a.row_ptr[f]..a.row_ptr[f + 1] {
                        let g = a.cols[s] as usize;
                        let blk = block_of(&a.values[s]);
                        for k in ptr[g]..ptr[g + 1] {
                            out[pos[cols[k] as usize] as usize] += blk * w[k];
                        }
                    }
                    for &c in rc {
                        pos[c as usize] = u32::MAX;
                    }
                },
            );
    }
}
