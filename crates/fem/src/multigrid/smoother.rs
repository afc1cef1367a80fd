//! The smoother: a balanced multicolouring of the block graph and block SOR sweeps in
//! colour order.

#![allow(unsafe_code)] // vector kernels and raw disjoint writes, each block with its SAFETY reason
use super::Level;
use crate::system::{BlockCsr, DisjointWrites};
use glam::{DMat3, DVec3};
use rayon::prelude::*;

/// Colouring of the block graph of `a` (no two rows of one colour share a block), with
/// classes of about equal size: a greedy pass fixes the number of colours, then
/// [`BALANCING_PASSES`] passes move every row to the smallest class its neighbours
/// allow. Equal classes let every colour of a large level run in parallel (the greedy
/// classes alone shrink geometrically: on the phantom's 60k-element level 2503, 2495,
/// 2237, 2247, 751, 354, 64 and 5 rows, the last four relaxed serially).
pub(super) fn colour_rows(a: &BlockCsr) -> Vec<Vec<u32>> {
    let n = a.block_rows();
    let mut colour = vec![u32::MAX; n];
    let mut used: Vec<bool> = Vec::new();
    let mut sizes: Vec<usize> = Vec::new();
    let neighbours = |i: usize| {
        a.cols[a.row_ptr[i]..a.row_ptr[i + 1]]
            .iter()
            .map(|&j| j as usize)
    };
    for i in 0..n {
        used.iter_mut().for_each(|u| *u = false);
        for j in neighbours(i) {
            if colour[j] != u32::MAX {
                used[colour[j] as usize] = true;
            }
        }
        let c = used.iter().position(|u| !u).unwrap_or(used.len());
        if c == used.len() {
            used.push(false);
            sizes.push(0);
        }
        colour[i] = c as u32;
        sizes[c] += 1;
    }
    for _ in 0..BALANCING_PASSES {
        for i in 0..n {
            used.iter_mut().for_each(|u| *u = false);
            for j in neighbours(i).filter(|&j| j != i) {
                used[colour[j] as usize] = true;
            }
            let own = colour[i] as usize;
            let best = (0..sizes.len())
                .filter(|&c| !used[c])
                .min_by_key(|&c| (sizes[c], c != own))
                .unwrap_or(own);
            if sizes[best] + 1 < sizes[own] {
                sizes[own] -= 1;
                sizes[best] += 1;
                colour[i] = best as u32;
            }
        }
    }
    // The parallel relaxation (`sor_colour`) writes the rows of a colour while reading
    // their columns: it is sound only if no row's column is another row of its colour.
    // The greedy passes look at each row's own columns, which suffices for the
    // structurally symmetric patterns built here; checked, as it is cheap.
    assert!(
        (0..n).all(|i| neighbours(i).all(|j| j == i || colour[j] != colour[i])),
        "a colour class holds two coupled rows (pattern not symmetric)"
    );
    let mut classes: Vec<Vec<u32>> = sizes.iter().map(|&s| Vec::with_capacity(s)).collect();
    for (i, &c) in colour.iter().enumerate() {
        classes[c as usize].push(i as u32);
    }
    classes
}

/// Passes of [`colour_rows`] that even out the colour classes.
const BALANCING_PASSES: usize = 2;

/// Colours with fewer blocks than this (rows times the level's mean blocks per row) are
/// relaxed serially: below it the fork-join of a parallel loop costs more than the work.
/// The first coarse level's colours have about 90 rows of 37 blocks on the phantom's
/// 60k hierarchy; relaxing them in parallel made the V-cycle a third faster (7.8-9.4 to
/// 5.1-5.5 ms, `solve_ms` 104-121 to 85-92 ms; `mammaplan bench`, four runs of each
/// binary in turn at a load of about 1.5; the former limit of 1024 rows kept them
/// serial). Limits of 600 to 3000 blocks measured alike.
const SERIAL_COLOUR_BLOCKS: usize = 2000;
/// Blocks per task of a colour relaxed in parallel (350 to 700 measured alike).
const TASK_BLOCKS: usize = 500;

/// One block SOR pass over the rows of one colour, in place: `xᵢ += ω Dᵢ⁻¹ (b - A x)ᵢ`.
/// Rows of one colour share no block, so the order does not matter and large colours
/// run in parallel.
fn sor_colour(
    a: &BlockCsr,
    inv_diag: &[DMat3],
    omega: f64,
    rows: &[u32],
    x: &mut [DVec3],
    b: &[DVec3],
) {
    assert_eq!(x.len(), a.block_rows(), "iterate length");
    let relax = |i: usize, xi: DVec3, ax: DVec3| xi + inv_diag[i] * ((b[i] - ax) * omega);
    let mean_row_blocks = (a.cols.len() / a.block_rows().max(1)).max(1);
    if rows.len() * mean_row_blocks < SERIAL_COLOUR_BLOCKS {
        for &i in rows {
            let i = i as usize;
            x[i] = relax(i, x[i], a.row_mul(i, x));
        }
        return;
    }
    let x = DisjointWrites::new(x);
    rows.par_iter()
        .with_min_len(TASK_BLOCKS.div_ceil(mean_row_blocks))
        .for_each(|&i| {
            let i = i as usize;
            // SAFETY: row `i` is written by this task alone, and the rows it reads (its
            // block columns) are `i` itself or rows of other colours, which no task writes
            // while this colour is relaxed; the parallel loop ends before the next colour.
            unsafe {
                let (x_ptr, len) = x.raw_parts();
                let ax = a.row_mul_raw(i, x_ptr, len);
                x.write(i, relax(i, x.read(i), ax));
            }
        });
}

/// One multicolour block SOR sweep, colours in order (`forward`) or reversed.
pub(super) fn sor_sweep(level: &Level, omega: f64, forward: bool, x: &mut [DVec3], b: &[DVec3]) {
    let a = level.op();
    if forward {
        for rows in &level.colours {
            sor_colour(a, &level.inv_diag, omega, rows, x, b);
        }
    } else {
        for rows in level.colours.iter().rev() {
            sor_colour(a, &level.inv_diag, omega, rows, x, b);
        }
    }
}
