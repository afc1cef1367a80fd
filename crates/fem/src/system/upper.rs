//! The upper block triangle of a symmetric block pattern, and its mirroring.

use super::{BlockCsr, DisjointWrites, split_rows, transposed};
use rayon::prelude::*;

/// The upper block triangle (diagonal and right of it) of a symmetric [`BlockCsr`]
/// pattern: callers fill the upper part of every row in place ([`UpperTriangle::rows_mut`])
/// and [`UpperTriangle::mirror`] writes the lower blocks as the transposes of the upper
/// ones, so the matrix is exactly symmetric.
#[derive(Debug, Clone, Default)]
pub(crate) struct UpperTriangle {
    /// Row `i` has `ptr[i + 1] - ptr[i]` blocks on and right of its diagonal.
    ptr: Vec<usize>,
    /// For each block left of the diagonal, in row order, the slot of its transpose in
    /// the full matrix.
    lower_src: Vec<u32>,
}

impl UpperTriangle {
    /// The upper triangle of the pattern of `a` (structurally symmetric, every diagonal
    /// block present).
    pub(crate) fn new(a: &BlockCsr) -> UpperTriangle {
        let n = a.block_rows();
        let mut ptr = vec![0usize];
        for i in 0..n {
            let row = &a.cols[a.row_ptr[i]..a.row_ptr[i + 1]];
            ptr.push(ptr[i] + row.len() - row.partition_point(|&j| (j as usize) < i));
        }
        // rows i ascending meet the blocks (j, i), j < i, of row j in column order; the
        // next unmatched block right of row j's diagonal is its slot `next[j]`
        let mut next: Vec<usize> = (0..n)
            .map(|j| a.row_ptr[j + 1] - (ptr[j + 1] - ptr[j]))
            .collect();
        let mut lower_src = Vec::with_capacity(a.cols.len() - ptr[n]);
        for i in 0..n {
            for &j in &a.cols[a.row_ptr[i]..a.row_ptr[i + 1]] {
                let j = j as usize;
                if j < i {
                    next[j] += 1;
                    lower_src.push(next[j] as u32);
                }
            }
        }
        UpperTriangle { ptr, lower_src }
    }

    /// The upper part of every row of the values of a matrix with the pattern given to
    /// [`UpperTriangle::new`] (`row_ptr` its row pointers): row `i`'s diagonal block,
    /// then the blocks right of it.
    pub(crate) fn rows_mut<'a>(
        &self,
        row_ptr: &[usize],
        values: &'a mut [[f64; 9]],
    ) -> Vec<&'a mut [[f64; 9]]> {
        split_rows(values, row_ptr)
            .into_iter()
            .enumerate()
            .map(|(i, row)| {
                let lower = row.len() - (self.ptr[i + 1] - self.ptr[i]);
                &mut row[lower..]
            })
            .collect()
    }

    /// Writes the blocks left of the diagonal of `a` (the pattern given to
    /// [`UpperTriangle::new`]) as the transposes of the upper blocks (parallel over rows).
    pub(crate) fn mirror(&self, a: &mut BlockCsr) {
        let (ptr, lower_src) = (&self.ptr, &self.lower_src);
        let row_ptr = &a.row_ptr;
        let values = DisjointWrites::new(&mut a.values);
        (0..row_ptr.len() - 1).into_par_iter().for_each(|i| {
            let lower = row_ptr[i + 1] - row_ptr[i] - (ptr[i + 1] - ptr[i]);
            let src = &lower_src[row_ptr[i] - ptr[i]..][..lower];
            for (k, &s) in src.iter().enumerate() {
                // SAFETY: every slot is within `a.values`; the slots written are the
                // lower blocks of row `i`, written by this task alone, and the slots read
                // are upper blocks, which no task writes.
                unsafe {
                    values.write(row_ptr[i] + k, transposed(&values.read(s as usize)));
                }
            }
        });
    }
}
