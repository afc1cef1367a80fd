//! Galerkin coarse operators: the coarse unknowns, and `Pᵀ A P` on fixed patterns (fused
//! per fine row for the barycentric `P`, by slots for the smoothed one).

#![allow(unsafe_code)] // vector kernels and raw disjoint writes, each block with its SAFETY reason
use super::concat_rows;
use super::transfer::{SmoothedProlongation, Transfer};
use crate::blocks::{self, BlockKernels};
use crate::model::FemModel;
use crate::system::{BlockCsr, IDENTITY_BLOCK, NOT_FREE, UpperTriangle, split_rows, transposed};
use crate::transfer::Prolongation;
use glam::DMat3;
use rayon::prelude::*;

/// A coarse vertex is a Galerkin unknown when the absolute interpolation weights it
/// gives the finer level's unknowns sum to at least this (vertices the finer unknowns
/// hardly see would make the coarse operator nearly singular).
pub(super) const MIN_COARSE_WEIGHT: f64 = 0.1;

/// The Galerkin unknowns of a coarse level: its vertices used by a tetrahedron whose
/// weights in `p` (coarse to fine) towards fine unknowns sum to [`MIN_COARSE_WEIGHT`].
pub(super) fn galerkin_unknowns(
    p: &Prolongation,
    fine_reduced_of: &[u32],
    coarse: &FemModel,
) -> Vec<u32> {
    let mut weight = vec![0.0; coarse.vertex_count()];
    for (row, &r) in p.rows.iter().zip(fine_reduced_of) {
        if r != NOT_FREE {
            for &(c, w) in row {
                weight[c as usize] += w.abs();
            }
        }
    }
    let mut used = vec![false; coarse.vertex_count()];
    for t in coarse.tets() {
        for &v in t {
            used[v as usize] = true;
        }
    }
    let mut next = 0u32;
    weight
        .iter()
        .zip(&used)
        .map(|(&w, &u)| {
            if u && w >= MIN_COARSE_WEIGHT {
                next += 1;
                next - 1
            } else {
                NOT_FREE
            }
        })
        .collect()
}

/// Contiguous ranges of fine rows of the barycentric Galerkin product, each accumulated
/// serially into a buffer of its own (fixed, so that the rounding does not depend on the
/// number of threads).
const GALERKIN_PARTS: usize = 8;

/// The barycentric Galerkin product `C = Pᵀ A P` fused per fine row on fixed patterns,
/// with every index precomputed: for each fine row `f`, the row `Q_f` of `Q = A P` is
/// formed in a scratch row (it stays in the L1 cache) and scattered at once into the
/// upper blocks `(i, j)`, `j >= i`, of the coarse rows `i` of `P`'s row `f`; then every
/// block of `C` is gathered from the buffers (the sum of its parts' contributions, the
/// transposed upper block left of the diagonal, so that `C` is exactly symmetric). Neither
/// `Q` nor a column map is stored, and `A` is read once.
#[derive(Debug, Clone)]
struct FusedProduct {
    /// Row `f` of `Q` has `q_ptr[f + 1] - q_ptr[f]` blocks: the union of the columns of
    /// `P` over the columns of `A`'s row `f`, ascending, from the smallest column of
    /// `P`'s row `f` on (the columns of `P`'s rows are ascending).
    q_ptr: Vec<usize>,
    /// Row `f`'s terms are `term_ptr[f]..term_ptr[f + 1]` of `term_slot`.
    term_ptr: Vec<usize>,
    /// For each block `(f, g)` of `A`, the entries of `P`'s row `g` it skips: those with
    /// a column below the smallest column of `P`'s row `f` (the upper triangle of `C`
    /// never needs them).
    term_skip: Vec<u8>,
    /// For each block `(f, g)` of `A` in storage order and each entry of `P`'s row `g`
    /// after the skipped ones, the position of its column in row `f` of `Q`.
    term_slot: Vec<u32>,
    /// For each entry `(f, i)` of `P`, the first position in row `f` of `Q` whose column
    /// is at least `i`.
    q_from: Vec<u32>,
    /// Row `f`'s destinations are `dest_ptr[f]..dest_ptr[f + 1]` of `dest`.
    dest_ptr: Vec<usize>,
    /// For each entry `(f, i)` of `P` in storage order and each block `j` of row `f` of
    /// `Q` from `q_from`, the index in `buf` of the block `(i, j)` of the part of `f`.
    dest: Vec<u32>,
    /// Part `p` holds the fine rows `part_rows[p]..part_rows[p + 1]` and the buffer
    /// blocks `buf_ptr[p]..buf_ptr[p + 1]`.
    part_rows: Vec<usize>,
    buf_ptr: Vec<usize>,
    /// The parts' sums of upper blocks of `C` (row-major 3x3, mN/mm), each part's blocks
    /// ordered by row and column.
    buf: Vec<[f64; 9]>,
    /// Block `b` of `C` (storage order) sums the blocks `src[src_ptr[b]..src_ptr[b + 1]]`
    /// of `buf`: the parts' sums of its upper block.
    src_ptr: Vec<usize>,
    src: Vec<u32>,
}

/// A parts' scatter pattern: its sorted upper blocks `(i, j)` (as `i << 32 | j`), then
/// for its fine rows the `q_from` and `dest` entries and the number of `dest` entries per
/// row.
type PartPattern = (Vec<u64>, Vec<u32>, Vec<u32>, Vec<usize>);

impl FusedProduct {
    /// The product for the finer operator pattern `a` and the barycentric `P` of `t`,
    /// and the pattern of `C` (values zero).
    fn new(a: &BlockCsr, t: &Transfer) -> (FusedProduct, BlockCsr) {
        let nf = a.block_rows();
        let p_row = |g: usize| &t.p_cols[t.p_ptr[g]..t.p_ptr[g + 1]];
        let lowest = |f: usize| p_row(f).first().copied().unwrap_or(u32::MAX);
        let (q_ptr, q_cols) = concat_rows(
            (0..nf)
                .into_par_iter()
                .map(|f| {
                    let lo = lowest(f);
                    let mut cols = Vec::new();
                    for &g in &a.cols[a.row_ptr[f]..a.row_ptr[f + 1]] {
                        cols.extend(p_row(g as usize).iter().filter(|&&j| j >= lo));
                    }
                    cols.sort_unstable();
                    cols.dedup();
                    cols
                })
                .collect(),
        );
        let terms: Vec<(Vec<u8>, Vec<u32>)> = (0..nf)
            .into_par_iter()
            .map(|f| {
                let (lo, row) = (lowest(f), &q_cols[q_ptr[f]..q_ptr[f + 1]]);
                let mut skips = Vec::new();
                let mut slots = Vec::new();
                for &g in &a.cols[a.row_ptr[f]..a.row_ptr[f + 1]] {
                    let g_cols = p_row(g as usize);
                    let skip = g_cols.partition_point(|&j| j < lo);
                    skips.push(skip as u8);
                    slots.extend(g_cols[skip..].iter().map(|j| {
                        row.binary_search(j).expect("column in the product pattern") as u32
                    }));
                }
                (skips, slots)
            })
            .collect();
        let (skips, slots): (Vec<_>, Vec<_>) = terms.into_iter().unzip();
        let term_skip = skips.concat();
        let (term_ptr, term_slot) = concat_rows(slots);
        let parts = GALERKIN_PARTS.min(nf.max(1));
        let part_rows: Vec<usize> = (0..=parts).map(|p| p * nf / parts).collect();
        let patterns: Vec<PartPattern> = (0..parts)
            .into_par_iter()
            .map(|p| {
                let rows = part_rows[p]..part_rows[p + 1];
                let key = |i: u32, j: u32| (i as u64) << 32 | j as u64;
                let mut keys = Vec::new();
                for f in rows.clone() {
                    let q_row = &q_cols[q_ptr[f]..q_ptr[f + 1]];
                    for &i in &t.p_cols[t.p_ptr[f]..t.p_ptr[f + 1]] {
                        keys.extend(q_row.iter().filter(|&&j| j >= i).map(|&j| key(i, j)));
                    }
                }
                keys.sort_unstable();
                keys.dedup();
                let (mut from, mut dest, mut counts) = (Vec::new(), Vec::new(), Vec::new());
                for f in rows {
                    let q_row = &q_cols[q_ptr[f]..q_ptr[f + 1]];
                    let before = dest.len();
                    for &i in &t.p_cols[t.p_ptr[f]..t.p_ptr[f + 1]] {
                        let start = q_row.partition_point(|&j| j < i);
                        from.push(start as u32);
                        dest.extend(q_row[start..].iter().map(|&j| {
                            keys.binary_search(&key(i, j)).expect("key of the part") as u32
                        }));
                    }
                    counts.push(dest.len() - before);
                }
                (keys, from, dest, counts)
            })
            .collect();
        // the pattern of C: the parts' upper blocks, mirrored, and the diagonal
        let nc = t.pt_ptr.len() - 1;
        let mut rows: Vec<Vec<u32>> = (0..nc as u32).map(|i| vec![i]).collect();
        for (keys, ..) in &patterns {
            for &key in keys {
                let (i, j) = ((key >> 32) as u32, key as u32);
                rows[i as usize].push(j);
                rows[j as usize].push(i);
            }
        }
        rows.par_iter_mut().for_each(|r| {
            r.sort_unstable();
            r.dedup();
        });
        let (row_ptr, cols) = concat_rows(rows);
        let c = BlockCsr {
            values: vec![[0.0; 9]; cols.len()],
            row_ptr,
            cols,
        };
        let mut buf_ptr = vec![0usize];
        let (mut q_from, mut dest, mut dest_ptr) = (Vec::new(), Vec::new(), vec![0usize]);
        for (keys, from, part_dest, counts) in &patterns {
            let base = *buf_ptr.last().expect("starts at zero");
            q_from.extend_from_slice(from);
            dest.extend(part_dest.iter().map(|&d| (base + d as usize) as u32));
            for &n in counts {
                dest_ptr.push(dest_ptr.last().expect("starts at zero") + n);
            }
            buf_ptr.push(base + keys.len());
        }
        let (src_ptr, src) = concat_rows(
            (0..c.block_rows())
                .into_par_iter()
                .flat_map_iter(|r| {
                    let patterns = &patterns;
                    let buf_ptr = &buf_ptr;
                    c.cols[c.row_ptr[r]..c.row_ptr[r + 1]]
                        .iter()
                        .map(move |&j| {
                            let (lo, hi) = (j.min(r as u32) as u64, j.max(r as u32) as u64);
                            patterns
                                .iter()
                                .zip(buf_ptr)
                                .filter_map(|((keys, ..), &base)| {
                                    let k = keys.binary_search(&(lo << 32 | hi)).ok()?;
                                    Some((base + k) as u32)
                                })
                                .collect::<Vec<u32>>()
                        })
                })
                .collect(),
        );
        let product = FusedProduct {
            buf: vec![[0.0; 9]; *buf_ptr.last().expect("starts at zero")],
            q_ptr,
            term_ptr,
            term_skip,
            term_slot,
            q_from,
            dest_ptr,
            dest,
            part_rows,
            buf_ptr,
            src_ptr,
            src,
        };
        (product, c)
    }

    /// Fills `c = Pᵀ A P` (the pattern returned by [`FusedProduct::new`]) for the finer
    /// operator `a` and the masked `P` of `t`, with an identity diagonal block in the
    /// (otherwise zero) rows of inactive coarse unknowns: the parts in parallel, each
    /// fine row of a part in turn (rows whose entries of `P` are all zero are skipped),
    /// then the blocks of `c` in parallel over rows.
    fn values(&mut self, a: &BlockCsr, t: &Transfer, active: &[bool], c: &mut BlockCsr) {
        let mut buf = std::mem::take(&mut self.buf);
        let this = &*self;
        let simd = blocks::simd_available();
        split_rows(&mut buf, &self.buf_ptr)
            .into_par_iter()
            .enumerate()
            .for_each_init(Vec::new, |q_row, (p, part)| {
                #[cfg(target_arch = "x86_64")]
                if simd {
                    // SAFETY: the processor has AVX2 and FMA (`simd_available`)
                    return unsafe { this.fill_part_avx2(a, t, p, q_row, part) };
                }
                let _ = simd;
                this.fill_part::<blocks::Scalar>(a, t, p, q_row, part);
            });
        let (src_ptr, src) = (&self.src_ptr, &self.src);
        let BlockCsr {
            row_ptr,
            cols,
            values,
        } = c;
        split_rows(values, row_ptr)
            .into_par_iter()
            .enumerate()
            .for_each(|(r, row)| {
                let start = row_ptr[r];
                for (b, (out, &j)) in row.iter_mut().zip(&cols[start..]).enumerate() {
                    let j = j as usize;
                    if j == r && !active[r] {
                        *out = IDENTITY_BLOCK;
                        continue;
                    }
                    let sum = match &src[src_ptr[start + b]..src_ptr[start + b + 1]] {
                        [k] => buf[*k as usize],
                        parts => parts.iter().fold([0.0; 9], |mut sum, &k| {
                            blocks::Scalar::add_scaled(&mut sum, 1.0, &buf[k as usize]);
                            sum
                        }),
                    };
                    *out = match j.cmp(&r) {
                        std::cmp::Ordering::Less => transposed(&sum),
                        std::cmp::Ordering::Equal => symmetrised(sum),
                        std::cmp::Ordering::Greater => sum,
                    };
                }
            });
        self.buf = buf;
    }

    /// Part `p`'s contributions to the upper blocks of `C` (its buffer blocks `part`):
    /// each fine row of the part in turn (rows whose entries of `P` are all zero are
    /// skipped), `q_row` a scratch row.
    #[inline(always)]
    fn fill_part<K: BlockKernels>(
        &self,
        a: &BlockCsr,
        t: &Transfer,
        p: usize,
        q_row: &mut Vec<[f64; 9]>,
        part: &mut [[f64; 9]],
    ) {
        part.fill([0.0; 9]);
        let base = self.buf_ptr[p];
        for f in self.part_rows[p]..self.part_rows[p + 1] {
            let weights = &t.p_w[t.p_ptr[f]..t.p_ptr[f + 1]];
            if weights.iter().all(|&w| w == 0.0) {
                continue;
            }
            q_row.clear();
            q_row.resize(self.q_ptr[f + 1] - self.q_ptr[f], [0.0; 9]);
            let mut slots = self.term_slot[self.term_ptr[f]..self.term_ptr[f + 1]].iter();
            let row = a.row_ptr[f]..a.row_ptr[f + 1];
            for ((blk, &g), &skip) in a.values[row.clone()]
                .iter()
                .zip(&a.cols[row.clone()])
                .zip(&self.term_skip[row])
            {
                // a copy, kept in registers over the row of `P`
                let blk = *blk;
                let g = g as usize;
                let ws = &t.p_w[t.p_ptr[g] + skip as usize..t.p_ptr[g + 1]];
                for (&w, &slot) in ws.iter().zip(&mut slots) {
                    K::add_scaled(&mut q_row[slot as usize], w, &blk);
                }
            }
            let mut dests = &self.dest[self.dest_ptr[f]..self.dest_ptr[f + 1]];
            for (k, &w) in (t.p_ptr[f]..).zip(weights) {
                let q_part = &q_row[self.q_from[k] as usize..];
                let (here, rest) = dests.split_at(q_part.len());
                dests = rest;
                if w != 0.0 {
                    for (qb, &d) in q_part.iter().zip(here) {
                        K::add_scaled(&mut part[d as usize - base], w, qb);
                    }
                }
            }
        }
    }

    /// [`FusedProduct::fill_part`] with the AVX2/FMA block kernels.
    ///
    /// # Safety
    /// The processor must have AVX2 and FMA ([`blocks::simd_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn fill_part_avx2(
        &self,
        a: &BlockCsr,
        t: &Transfer,
        p: usize,
        q_row: &mut Vec<[f64; 9]>,
        part: &mut [[f64; 9]],
    ) {
        self.fill_part::<blocks::Avx2Fma>(a, t, p, q_row, part);
    }
}

/// A diagonal block made exactly symmetric: each off-diagonal pair replaced by its mean.
fn symmetrised(mut d: [f64; 9]) -> [f64; 9] {
    for (a, b) in [(1, 3), (2, 6), (5, 7)] {
        let m = 0.5 * (d[a] + d[b]);
        d[a] = m;
        d[b] = m;
    }
    d
}

/// Slots of the product `C = Bᵀ Q` restricted to the upper block triangle of `C`, where
/// `Bᵀ` (rows: coarse unknowns `i`, columns: fine unknowns `f`) is given by its CSR
/// pattern and `Q` by its row pattern: row `i` of the upper triangle sums `b_fi Q_fj`
/// over the entries of row `i` of `Bᵀ` and the blocks `j >= i` of row `f` of `Q`, a
/// suffix of the row.
#[derive(Debug, Clone)]
struct UpperSlots {
    /// For each entry `(i, f)` of `Bᵀ`, the first block of row `f` of `Q` with column at
    /// least `i` (an index into the values of `Q`).
    q_from: Vec<usize>,
    /// Row `i`'s slots are `ptr[i]..ptr[i + 1]` of `slot`.
    ptr: Vec<usize>,
    /// For each entry `(i, f)` of `Bᵀ` in storage order and each block of row `f` of `Q`
    /// from `q_from`, the position of its column in row `i` of the upper triangle (0 =
    /// the diagonal block).
    slot: Vec<u32>,
}

impl UpperSlots {
    /// The slots for `Bᵀ` (`t_ptr`, `t_cols`), `Q` (`q_ptr`, `q_cols`) and the full
    /// pattern `c` of `C` (which holds every product block).
    fn new(
        t_ptr: &[usize],
        t_cols: &[u32],
        q_ptr: &[usize],
        q_cols: &[u32],
        c: &BlockCsr,
    ) -> UpperSlots {
        let rows: Vec<(Vec<usize>, Vec<u32>)> = (0..c.block_rows())
            .into_par_iter()
            .map(|i| {
                let row = &c.cols[c.row_ptr[i]..c.row_ptr[i + 1]];
                let upper = &row[row.partition_point(|&j| (j as usize) < i)..];
                let mut from = Vec::with_capacity(t_ptr[i + 1] - t_ptr[i]);
                let mut slots = Vec::new();
                for &f in &t_cols[t_ptr[i]..t_ptr[i + 1]] {
                    let f = f as usize;
                    let q_row = &q_cols[q_ptr[f]..q_ptr[f + 1]];
                    let start = q_row.partition_point(|&j| (j as usize) < i);
                    from.push(q_ptr[f] + start);
                    slots.extend(q_row[start..].iter().map(|j| {
                        upper
                            .binary_search(j)
                            .expect("block in the Galerkin pattern") as u32
                    }));
                }
                (from, slots)
            })
            .collect();
        let (froms, slots): (Vec<_>, Vec<_>) = rows.into_iter().unzip();
        let q_from = froms.concat();
        let (ptr, slot) = concat_rows(slots);
        UpperSlots { q_from, ptr, slot }
    }

    /// Fills the upper triangle of `C = P_sᵀ Q` (parallel over rows) for the smoothed
    /// prolongation `p` (the patterns given to [`UpperSlots::new`] are its `P_sᵀ` and
    /// `Q = A P_s`), with an identity diagonal block in the rows of inactive coarse
    /// unknowns and every diagonal block made exactly symmetric.
    fn fill(
        &self,
        p: &SmoothedProlongation,
        active: &[bool],
        upper: &UpperTriangle,
        c: &mut BlockCsr,
    ) {
        upper
            .rows_mut(&c.row_ptr, &mut c.values)
            .into_par_iter()
            .enumerate()
            .for_each(|(i, vals)| {
                vals.fill([0.0; 9]);
                if !active[i] {
                    vals[0] = IDENTITY_BLOCK;
                    return;
                }
                let mut slots = &self.slot[self.ptr[i]..self.ptr[i + 1]];
                for k in p.t_ptr[i]..p.t_ptr[i + 1] {
                    let q_row = &p.q[self.q_from[k]..p.q_ptr[p.t_cols[k] as usize + 1]];
                    let (here, rest) = slots.split_at(q_row.len());
                    slots = rest;
                    let wt = p.w[p.t_src[k]].transpose();
                    if wt == DMat3::ZERO {
                        continue;
                    }
                    for (qm, &slot) in q_row.iter().zip(here) {
                        let m = wt * *qm;
                        // row-major, as `block_of` reads it
                        for (r, row) in vals[slot as usize].chunks_exact_mut(3).enumerate() {
                            for (c, o) in row.iter_mut().enumerate() {
                                *o += m.col(c)[r];
                            }
                        }
                    }
                }
                vals[0] = symmetrised(vals[0]);
            });
    }
}

/// Pattern of the Galerkin operator `Bᵀ Q` (rows: coarse unknowns), values zero: row `i`
/// is the union of the rows of `Q` (`q_ptr`, `q_cols`) over the entries of row `i` of
/// `Bᵀ` (`t_ptr`, `t_cols`), and the diagonal.
fn galerkin_pattern(t_ptr: &[usize], t_cols: &[u32], q_ptr: &[usize], q_cols: &[u32]) -> BlockCsr {
    let rows: Vec<Vec<u32>> = (0..t_ptr.len() - 1)
        .into_par_iter()
        .map(|i| {
            let mut cols = vec![i as u32];
            for &f in &t_cols[t_ptr[i]..t_ptr[i + 1]] {
                let f = f as usize;
                cols.extend_from_slice(&q_cols[q_ptr[f]..q_ptr[f + 1]]);
            }
            cols.sort_unstable();
            cols.dedup();
            cols
        })
        .collect();
    let (row_ptr, cols) = concat_rows(rows);
    BlockCsr {
        values: vec![[0.0; 9]; cols.len()],
        row_ptr,
        cols,
    }
}

/// A Galerkin operator on its fixed pattern and the tables of its product.
#[derive(Debug, Clone)]
pub(super) struct Galerkin {
    pub(super) op: BlockCsr,
    product: GalerkinProduct,
}

/// How a Galerkin operator is computed.
#[derive(Debug, Clone)]
enum GalerkinProduct {
    /// `Pᵀ A P` for the barycentric `P`, fused per fine row.
    Barycentric(FusedProduct),
    /// `P_sᵀ Q` for the smoothed prolongation (which keeps `Q = A P_s`): its upper
    /// triangle (the part computed; the rest is mirrored) and the slots of the product.
    Smoothed {
        upper: UpperTriangle,
        slots: UpperSlots,
    },
}

impl Galerkin {
    /// The pattern and product tables for the barycentric `P` of `t` and the finer
    /// operator pattern `a`.
    pub(super) fn new(a: &BlockCsr, t: &Transfer) -> Galerkin {
        let (product, op) = FusedProduct::new(a, t);
        Galerkin {
            op,
            product: GalerkinProduct::Barycentric(product),
        }
    }

    /// The pattern and product tables for the smoothed prolongation `p`.
    pub(super) fn smoothed(p: &SmoothedProlongation) -> Galerkin {
        let op = galerkin_pattern(&p.t_ptr, &p.t_cols, &p.q_ptr, &p.q_cols);
        let slots = UpperSlots::new(&p.t_ptr, &p.t_cols, &p.q_ptr, &p.q_cols, &op);
        Galerkin {
            product: GalerkinProduct::Smoothed {
                upper: UpperTriangle::new(&op),
                slots,
            },
            op,
        }
    }

    /// Fills `Pᵀ A P` for the finer operator `a` and the (masked) barycentric `P` of `t`,
    /// with an identity diagonal block in the (otherwise zero) rows of inactive coarse
    /// unknowns (see [`FusedProduct`]).
    pub(super) fn barycentric_values(&mut self, a: &BlockCsr, t: &Transfer, active: &[bool]) {
        match &mut self.product {
            GalerkinProduct::Barycentric(product) => product.values(a, t, active, &mut self.op),
            GalerkinProduct::Smoothed { .. } => unreachable!("a barycentric Galerkin level"),
        }
    }

    /// Fills `P_sᵀ A P_s` from the updated smoothed prolongation `p` (its `Q = A P_s`),
    /// with identity blocks for inactive coarse unknowns; upper triangle, then mirrored.
    pub(super) fn smoothed_values(&mut self, p: &SmoothedProlongation, active: &[bool]) {
        match &mut self.product {
            GalerkinProduct::Smoothed { upper, slots } => {
                slots.fill(p, active, upper, &mut self.op);
                upper.mirror(&mut self.op);
            }
            GalerkinProduct::Barycentric(_) => unreachable!("a smoothed Galerkin level"),
        }
    }
}
