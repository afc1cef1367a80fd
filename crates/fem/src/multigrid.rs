//! Geometric multigrid on non-nested tetrahedral levels for the warped system
//! `K'_ff = (R K Rᵀ)_ff` (issue 5, item 4). Units as in the rest of the crate:
//! displacements in mm, forces and residuals in mN, stiffness blocks in mN/mm. The
//! measurements behind each choice, and what was tried and not kept, are in
//! `docs/dev/multigrid.md`.
//!
//! - Levels: independent tetrahedral meshes of the same body, finest first, each with its
//!   own [`FemModel`]; coarse levels need not cover the fine domain (fine vertices
//!   outside are extrapolated from the nearest coarse element).
//! - Coarse operators ([`CoarseOperator`]): Galerkin `Pᵀ A P` on a pattern built once
//!   (default: variational, every two-grid step an A-norm contraction, and it converged
//!   better in every measurement), or rediscretised on every level.
//! - Coarse unknowns (Galerkin): every coarse vertex whose interpolation weights towards
//!   the finer level's unknowns sum to at least 0.1; the coarse levels' own constraints
//!   are not used. A fine constrained vertex has no row in `P`, so every coarse function
//!   vanishes there and the fine constraints hold on every level.
//! - Prolongation `P`: [`Prolongation`] (coarse to fine, barycentric, nearest-element
//!   extrapolation outside) restricted to the unknowns of both levels
//!   ([`Prolongation::reduced`]); restriction is `Pᵀ`. Optionally smoothed on the finest
//!   transfer ([`MultigridOptions::prolongation_smoothing`]: `P_s = (I - ω_P D⁻¹ A) P`,
//!   recomputed at every assembly; off by default, as it costs about twice a cycle).
//! - Smoother: block (3x3) SOR in multicolour order (a greedy colouring of the block
//!   graph with its classes evened out; the rows of one colour are independent and
//!   updated in place), ω = 1.5. A smoothing step is two sweeps, colours forward before
//!   the coarse correction and backward after it.
//! - Changeable constraints ([`Multigrid::set_constraints`]): the hierarchy is built once
//!   with the permanent constraints ([`Multigrid::with_permanent_constraints`]); a change
//!   eliminates the held finest unknowns symmetrically at assembly, zeroes their
//!   prolongation rows and switches off every coarse unknown whose weights towards the
//!   active finer unknowns drop below the Galerkin threshold. Invariant: the coarse
//!   spaces and Galerkin operators on the active unknowns are those of a hierarchy built
//!   from scratch with all the constraints (only the smoother's colour order differs).
//! - Coarsest level: faer sparse Cholesky of `A + 1e-8 diag(A)`, refactorised at every
//!   [`Multigrid::assemble`]; the shift keeps it away from zero pivots when dependent
//!   columns of `P` make the Galerkin operator singular (see `tests/coarse_singular.rs`).
//! - Parallelism: [`Multigrid::assemble`] and [`Multigrid::vcycle`] run on a worker of
//!   rayon's pool; colours of fewer than `SERIAL_COLOUR_BLOCKS` blocks are relaxed
//!   serially. Invariant: the iterates are those of every colour in parallel.
//! - Products: the block row product ([`BlockCsr::row_mul`]) and the assembly's element
//!   blocks use four-lane AVX2/FMA where the processor has them (chosen at run time);
//!   the barycentric Galerkin products are fused per fine row (`FusedProduct`), reading
//!   `A` once and filling the upper triangle.
//! - Cycle: V(ν₁, ν₂), default V(2, 1).
//! - Step: linear cycles add the V-cycle's correction `z` scaled to the minimum of the
//!   assembled quadratic energy along it, `α = (b·z) / (zᵀ A z)` (the correction is
//!   consistently too short); corotated cycles take it unscaled (the warped `R K Rᵀ` is
//!   not the energy's Hessian).
//!
//! Use: [`Multigrid::cycle`] does one interactive step (reassemble every level at the
//! current displacement, one V-cycle on the correction from zero, i.e. warm-started from
//! the current displacement, the correction scaled as [`MultigridOptions::optimal_step`]
//! says); [`Multigrid::vcycle`] is one V-cycle on the assembled finest system;
//! [`Multigrid::pcg`] is conjugate gradients preconditioned by one symmetric V(ν₁, ν₁)
//! cycle ([`PcgIteration`]).

use crate::blocks::{self, BlockKernels};
use crate::direct::DirectSolver;
use crate::error::FemError;
use crate::model::{FemModel, Formulation, Tangent};
use crate::system::{
    BlockCsr, Constraints, DisjointWrites, IDENTITY_BLOCK, NOT_FREE, ReducedSystem, UpperTriangle,
    split_rows, transposed,
};
use crate::transfer::Prolongation;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::time::{Duration, Instant};
use tetra::TetMesh;

/// Options of the [`Multigrid`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MultigridOptions {
    /// Smoothing steps before the coarse correction (ν₁); each step is
    /// [`MultigridOptions::sweeps_per_step`] forward multicolour block SOR sweeps.
    pub pre_smooth: usize,
    /// Smoothing steps after the coarse correction (ν₂); each step is
    /// [`MultigridOptions::sweeps_per_step`] backward sweeps (colours in reverse order),
    /// so that V(ν, ν) is a symmetric operator.
    pub post_smooth: usize,
    /// Block SOR sweeps per smoothing step (at least 1).
    pub sweeps_per_step: usize,
    /// SOR relaxation factor ω (1 is Gauss-Seidel; 0 < ω < 2 converges).
    pub relaxation: f64,
    /// How the coarse operators are built.
    pub coarse_operator: CoarseOperator,
    /// Damping ω_P of the smoothed finest prolongation `P_s = (I - ω_P D⁻¹ A) P`
    /// (dimensionless, `D` the 3x3 diagonal blocks of the finest operator); 0 (the
    /// default) keeps the barycentric `P`. Galerkin only; 0.5 measured best (see the
    /// module documentation), at a much higher coarse-operator cost.
    pub prolongation_smoothing: f64,
    /// The corotated tangent assembled every cycle: the paper's warped stiffness
    /// `R K Rᵀ` (default), or [`Tangent::Full`] with the positive part of the geometric
    /// term (a Newton-like step where tissue is stretched and turned hard).
    pub tangent: Tangent,
    /// Whether [`Multigrid::cycle`] with the linear formulation scales the V-cycle's
    /// correction `z` to the minimum of the quadratic energy along it,
    /// `α = (b·z) / (zᵀ A z)` (one step of steepest descent preconditioned by the
    /// V-cycle; one more finest matrix-vector product). Default on: see the module
    /// documentation for the measured gain, and why corotated cycles are not scaled.
    pub optimal_step: bool,
}

/// How the coarse levels' operators are built.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CoarseOperator {
    /// Galerkin `Pᵀ A P` from the next finer level's operator, on a pattern built once.
    /// The coarse unknowns are derived from the finer level (every coarse vertex that
    /// carries interpolation weight to a finer unknown); the coarse levels' own
    /// constraints are not used.
    #[default]
    Galerkin,
    /// Each level assembles its own `R K Rᵀ` with rotations from the fine displacement
    /// sampled at its vertices; each level's own constraints say which of its vertices
    /// are eliminated.
    Rediscretised,
}

impl Default for MultigridOptions {
    /// V(2, 1) with two sweeps of block SOR (ω = 1.5) per smoothing step, Galerkin
    /// coarse operators (measured choices, see the module documentation).
    fn default() -> Self {
        MultigridOptions {
            pre_smooth: 2,
            post_smooth: 1,
            sweeps_per_step: 2,
            relaxation: 1.5,
            coarse_operator: CoarseOperator::Galerkin,
            prolongation_smoothing: 0.0,
            tangent: Tangent::Warped,
            optimal_step: true,
        }
    }
}

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
        residual(mg.levels[0].op(), &x, b, &mut r);
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

/// Outcome of one interactive [`Multigrid::cycle`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleReport {
    /// `‖f_ext - f_int(u)‖₂` at the free vertices before the cycle (mN). (The linear
    /// residual after the V-cycle is not computed: it would cost a finest
    /// matrix-vector product per cycle; the next cycle's `residual_before` tells.)
    pub residual_before: f64,
    /// The factor `α` the V-cycle's correction was scaled by (1 without
    /// [`MultigridOptions::optimal_step`] or with the corotated formulation).
    pub step_scale: f64,
}

/// Bounds of the energy-optimal scale of an interactive cycle's correction: outside
/// them the quadratic model is not trusted (measured values lie in 1.0-1.3).
const STEP_SCALE_RANGE: (f64, f64) = (0.5, 2.0);

/// Wall-clock times (ms) of the phases of the latest [`Multigrid::assemble`] and
/// [`Multigrid::vcycle`], for benchmarks that report where the time goes.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PhaseTimes {
    /// Finest level: element rotations, `R K Rᵀ` blocks and `f_int`, right-hand side.
    pub finest_assembly_ms: f64,
    /// Coarse operators (Galerkin products, or rediscretised assemblies).
    pub coarse_operators_ms: f64,
    /// Smoother set-up on every level (inverse diagonal blocks).
    pub smoother_setup_ms: f64,
    /// Numeric Cholesky factorisation of the coarsest level.
    pub coarsest_factorisation_ms: f64,
    /// The latest V-cycle.
    pub vcycle_ms: f64,
}

/// One level: its model, its unknowns, its operator, the smoother's data.
#[derive(Debug, Clone)]
struct Level {
    model: FemModel,
    /// The level's own reduced system: the finest level, and every level with
    /// [`CoarseOperator::Rediscretised`].
    system: Option<ReducedSystem>,
    /// For each vertex its unknown, or [`NOT_FREE`].
    reduced_of: Vec<u32>,
    /// Number of unknowns.
    unknowns: usize,
    /// The Galerkin operator (coarse levels with [`CoarseOperator::Galerkin`]).
    galerkin: Option<Galerkin>,
    /// Unknowns grouped by colour (no two of one colour share a matrix block).
    colours: Vec<Vec<u32>>,
    /// Slot of the diagonal block of each row.
    diag_slot: Vec<usize>,
    /// Inverse diagonal blocks, refreshed at every assembly.
    inv_diag: Vec<DMat3>,
    /// For each unknown, whether it takes part in the current problem: false for a
    /// finest unknown held by a changeable constraint and for a coarse unknown that the
    /// active finer unknowns hardly see (its Galerkin row is replaced by an identity
    /// block, its prolongation column is zero).
    active: Vec<bool>,
}

/// Reduced prolongation from level `l + 1` (coarse) to level `l` (fine), CSR both ways,
/// and the sampling of the fine displacement at the coarse vertices.
#[derive(Debug, Clone)]
struct Transfer {
    p_ptr: Vec<usize>,
    p_cols: Vec<u32>,
    /// Weights of `P` with the rows of inactive fine unknowns and the columns of inactive
    /// coarse unknowns zeroed (see [`Multigrid::set_constraints`]).
    p_w: Vec<f64>,
    /// Weights of `P` over the pattern's unknowns (before masking).
    p_w_full: Vec<f64>,
    /// `Pᵀ`: rows are coarse unknowns.
    pt_ptr: Vec<usize>,
    pt_cols: Vec<u32>,
    pt_w: Vec<f64>,
    /// For each entry of `Pᵀ`, its entry in `P`.
    pt_src: Vec<usize>,
    /// Coarse vertices located in the fine mesh (rows: coarse vertices).
    sample: Prolongation,
    /// The smoothed prolongation replacing `P` in the cycle and the Galerkin product
    /// (finest transfer with [`MultigridOptions::prolongation_smoothing`] > 0).
    smoothed: Option<SmoothedProlongation>,
}

/// `P_s = (I - ω D⁻¹ A) P` with 3x3 blocks (rows: fine unknowns, columns: coarse
/// unknowns), its transpose's pattern, and `Q = A P_s` for the Galerkin product. The
/// patterns are built once; the values follow every assembly of `A` (and the masked `P`).
#[derive(Debug, Clone)]
struct SmoothedProlongation {
    omega: f64,
    ptr: Vec<usize>,
    cols: Vec<u32>,
    w: Vec<DMat3>,
    /// `P_sᵀ`: rows are coarse unknowns; `t_src` gives the entry of `P_s`.
    t_ptr: Vec<usize>,
    t_cols: Vec<u32>,
    t_src: Vec<usize>,
    /// `Q = A P_s` (rows: fine unknowns).
    q_ptr: Vec<usize>,
    q_cols: Vec<u32>,
    q: Vec<DMat3>,
}

/// Geometric multigrid over non-nested tetrahedral levels, see the module documentation.
#[derive(Debug)]
pub struct Multigrid {
    levels: Vec<Level>,
    /// `transfers[l]` connects level `l` (fine) and `l + 1` (coarse).
    transfers: Vec<Transfer>,
    coarse: Option<DirectSolver>,
    options: MultigridOptions,
    /// Per-level work vectors: iterate, right-hand side, residual.
    xs: Vec<Vec<DVec3>>,
    bs: Vec<Vec<DVec3>>,
    rs: Vec<Vec<DVec3>>,
    /// Per-level displacement used for the rotations (all vertices).
    us: Vec<Vec<DVec3>>,
    assembled: bool,
    times: PhaseTimes,
}

impl Transfer {
    /// The reduced transfer from `p` (coarse to fine, all vertices) restricted to the
    /// unknowns of both levels, with its transpose.
    fn new(
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
    fn mask(&mut self, fine_active: &[bool], coarse_active: &[bool]) {
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

fn mesh_of(model: &FemModel) -> TetMesh {
    TetMesh {
        positions: model.rest_positions().to_vec(),
        tets: model.tets().to_vec(),
    }
}

/// Colouring of the block graph of `a` (no two rows of one colour share a block), with
/// classes of about equal size: a greedy pass fixes the number of colours, then
/// [`BALANCING_PASSES`] passes move every row to the smallest class its neighbours
/// allow. Equal classes let every colour of a large level run in parallel (the greedy
/// classes alone shrink geometrically: on the phantom's 60k-element level 2503, 2495,
/// 2237, 2247, 751, 354, 64 and 5 rows, the last four relaxed serially).
fn colour_rows(a: &BlockCsr) -> Vec<Vec<u32>> {
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

impl Level {
    /// The operator smoothed and solved on this level.
    fn op(&self) -> &BlockCsr {
        match (&self.galerkin, &self.system) {
            (Some(g), _) => &g.op,
            (None, Some(s)) => &s.matrix,
            (None, None) => unreachable!("a level has a Galerkin operator or a system"),
        }
    }
}

/// A coarse vertex is a Galerkin unknown when the absolute interpolation weights it
/// gives the finer level's unknowns sum to at least this (vertices the finer unknowns
/// hardly see would make the coarse operator nearly singular).
const MIN_COARSE_WEIGHT: f64 = 0.1;

/// Relative shift of the diagonal of the coarsest Galerkin operator before its Cholesky
/// factorisation: `A + ε diag(A)`. `Pᵀ A P` is singular whenever the columns of `P`
/// restricted to the active finer unknowns are linearly dependent (e.g. two coarse
/// vertices that both see only one free fine vertex next to a large held patch); the
/// system `Pᵀ A P x = Pᵀ r` is then consistent and its null space is that of `P`, so the
/// shift changes the prolonged correction only by `O(ε)`, while the factorisation no
/// longer meets zero or negative pivots.
const COARSEST_SHIFT: f64 = 1e-8;

/// The Galerkin unknowns of a coarse level: its vertices used by a tetrahedron whose
/// weights in `p` (coarse to fine) towards fine unknowns sum to [`MIN_COARSE_WEIGHT`].
fn galerkin_unknowns(p: &Prolongation, fine_reduced_of: &[u32], coarse: &FemModel) -> Vec<u32> {
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
    fn new(a: &BlockCsr, t: &Transfer, omega: f64) -> SmoothedProlongation {
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
    fn update(&mut self, a: &BlockCsr, inv_diag: &[DMat3], t: &Transfer) {
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

/// Concatenates per-row lists into CSR form: `(ptr, items)`.
fn concat_rows<T>(rows: Vec<Vec<T>>) -> (Vec<usize>, Vec<T>) {
    let mut ptr = Vec::with_capacity(rows.len() + 1);
    ptr.push(0);
    let mut items = Vec::with_capacity(rows.iter().map(Vec::len).sum());
    for r in rows {
        items.extend(r);
        ptr.push(items.len());
    }
    (ptr, items)
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
struct Galerkin {
    op: BlockCsr,
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
    fn new(a: &BlockCsr, t: &Transfer) -> Galerkin {
        let (product, op) = FusedProduct::new(a, t);
        Galerkin {
            op,
            product: GalerkinProduct::Barycentric(product),
        }
    }

    /// The pattern and product tables for the smoothed prolongation `p`.
    fn smoothed(p: &SmoothedProlongation) -> Galerkin {
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
    fn barycentric_values(&mut self, a: &BlockCsr, t: &Transfer, active: &[bool]) {
        match &mut self.product {
            GalerkinProduct::Barycentric(product) => product.values(a, t, active, &mut self.op),
            GalerkinProduct::Smoothed { .. } => unreachable!("a barycentric Galerkin level"),
        }
    }

    /// Fills `P_sᵀ A P_s` from the updated smoothed prolongation `p` (its `Q = A P_s`),
    /// with identity blocks for inactive coarse unknowns; upper triangle, then mirrored.
    fn smoothed_values(&mut self, p: &SmoothedProlongation, active: &[bool]) {
        match &mut self.product {
            GalerkinProduct::Smoothed { upper, slots } => {
                slots.fill(p, active, upper, &mut self.op);
                upper.mirror(&mut self.op);
            }
            GalerkinProduct::Barycentric(_) => unreachable!("a smoothed Galerkin level"),
        }
    }
}

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
}

fn block_of(b: &[f64; 9]) -> DMat3 {
    DMat3::from_cols_array(b).transpose()
}

fn dot(a: &[DVec3], b: &[DVec3]) -> f64 {
    a.par_iter().zip(b).map(|(x, y)| x.dot(*y)).sum()
}

fn norm(a: &[DVec3]) -> f64 {
    dot(a, a).sqrt()
}

/// `r = b - A x`.
fn residual(a: &BlockCsr, x: &[DVec3], b: &[DVec3], r: &mut [DVec3]) {
    r.par_iter_mut()
        .enumerate()
        .for_each(|(i, ri)| *ri = b[i] - a.row_mul(i, x));
}

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
fn sor_sweep(level: &Level, omega: f64, forward: bool, x: &mut [DVec3], b: &[DVec3]) {
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

impl Multigrid {
    /// Builds the hierarchy: `levels` are `(model, constraints)` pairs, finest first,
    /// at least one. The finest level must have at least one constraint (else its system
    /// is singular). With [`CoarseOperator::Galerkin`] the coarse levels' constraints are
    /// ignored (their unknowns follow from the finer level, see [`CoarseOperator`]);
    /// with [`CoarseOperator::Rediscretised`] every level needs its own.
    ///
    /// Errors: see [`ReducedSystem::new`]; a level without tetrahedra;
    /// [`FemError::InvalidOptions`] if `options.sweeps_per_step` is zero,
    /// `options.relaxation` is outside (0, 2), or `options.prolongation_smoothing` is
    /// outside [0, 1] or positive with rediscretised coarse operators.
    pub fn new(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
    ) -> Result<Multigrid, FemError> {
        Multigrid::build(levels, options, false)
    }

    /// Like [`Multigrid::new`], but the finest level's constraints are only the
    /// permanent ones (e.g. the chest wall; may be empty): the constraints that change
    /// (an implant's displacement template) are set with [`Multigrid::set_constraints`]
    /// before the first assembly, and changed with it in O(vertices) without rebuilding
    /// the hierarchy. [`Multigrid::new`] allows the same, with a non-empty permanent set.
    ///
    /// Errors: as [`Multigrid::new`], except that an empty finest constraint set is
    /// allowed.
    pub fn with_permanent_constraints(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
    ) -> Result<Multigrid, FemError> {
        Multigrid::build(levels, options, true)
    }

    fn build(
        levels: Vec<(FemModel, Constraints)>,
        options: MultigridOptions,
        changeable: bool,
    ) -> Result<Multigrid, FemError> {
        if levels.is_empty() {
            return Err(FemError::LengthMismatch {
                what: "multigrid levels",
                expected: 1,
                got: 0,
            });
        }
        if options.sweeps_per_step == 0 {
            return Err(FemError::InvalidOptions {
                what: "multigrid sweeps_per_step is 0, need at least 1".into(),
            });
        }
        if !(options.relaxation > 0.0 && options.relaxation < 2.0) {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "multigrid relaxation {}, need 0 < ω < 2",
                    options.relaxation
                ),
            });
        }
        let galerkin = options.coarse_operator == CoarseOperator::Galerkin;
        let ps = options.prolongation_smoothing;
        if !(0.0..=1.0).contains(&ps) || (ps > 0.0 && !galerkin) {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "multigrid prolongation_smoothing {ps}, need 0 <= ω_P <= 1 and Galerkin \
                     coarse operators when positive"
                ),
            });
        }
        let empty = || FemError::LengthMismatch {
            what: "tetrahedra of a multigrid level",
            expected: 1,
            got: 0,
        };
        let mut built: Vec<Level> = Vec::with_capacity(levels.len());
        let mut transfers = Vec::with_capacity(levels.len() - 1);
        for (model, constraints) in levels {
            let prolongations = match built.last() {
                Some(fine) => {
                    let fine_mesh = mesh_of(&fine.model);
                    let coarse_mesh = mesh_of(&model);
                    let p = Prolongation::new(&coarse_mesh, &fine_mesh).ok_or_else(empty)?;
                    let sample = Prolongation::new(&fine_mesh, &coarse_mesh).ok_or_else(empty)?;
                    Some((p, sample))
                }
                None => None,
            };
            let (system, reduced_of) = match (&prolongations, built.last()) {
                (Some((p, _)), Some(fine)) if galerkin => {
                    (None, galerkin_unknowns(p, &fine.reduced_of, &model))
                }
                _ => {
                    let system = if changeable && built.is_empty() {
                        ReducedSystem::with_permanent(&model, &constraints)?
                    } else {
                        ReducedSystem::new(&model, &constraints)?
                    };
                    let reduced_of = system.reduced_of.clone();
                    (Some(system), reduced_of)
                }
            };
            let unknowns = reduced_of.iter().filter(|&&r| r != NOT_FREE).count();
            if let (Some((p, sample)), Some(fine)) = (prolongations, built.last()) {
                transfers.push(Transfer::new(
                    p,
                    sample,
                    &fine.reduced_of,
                    &reduced_of,
                    unknowns,
                ));
            }
            built.push(Level {
                model,
                system,
                reduced_of,
                unknowns,
                galerkin: None,
                colours: Vec::new(),
                diag_slot: Vec::new(),
                inv_diag: vec![DMat3::IDENTITY; unknowns],
                active: vec![true; unknowns],
            });
        }
        for l in 0..built.len() {
            if l > 0 && galerkin {
                let fine = built[l - 1].op();
                let t = &mut transfers[l - 1];
                built[l].galerkin = Some(if l == 1 && ps > 0.0 {
                    let smoothed = SmoothedProlongation::new(fine, t, ps);
                    let g = Galerkin::smoothed(&smoothed);
                    t.smoothed = Some(smoothed);
                    g
                } else {
                    Galerkin::new(fine, t)
                });
            }
            let a = built[l].op();
            let colours = colour_rows(a);
            let diag_slot = (0..a.block_rows())
                .map(|i| a.slot(i, i).expect("diagonal block present"))
                .collect();
            built[l].colours = colours;
            built[l].diag_slot = diag_slot;
        }
        let last = built.last().expect("at least one level");
        let coarse = if last.unknowns > 0 {
            Some(DirectSolver::new(last.op())?)
        } else {
            None
        };
        let sizes: Vec<usize> = built.iter().map(|l| l.unknowns).collect();
        let xs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let bs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let rs = sizes.iter().map(|&n| vec![DVec3::ZERO; n]).collect();
        let us = built
            .iter()
            .map(|l| vec![DVec3::ZERO; l.model.vertex_count()])
            .collect();
        Ok(Multigrid {
            levels: built,
            transfers,
            coarse,
            options,
            xs,
            bs,
            rs,
            us,
            assembled: false,
            times: PhaseTimes::default(),
        })
    }

    /// Number of levels.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Unknown vertices per level, finest first.
    pub fn unknowns_per_level(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.unknowns).collect()
    }

    /// Colours of the Gauss-Seidel smoother per level, finest first.
    pub fn colours_per_level(&self) -> Vec<usize> {
        self.levels.iter().map(|l| l.colours.len()).collect()
    }

    /// The operator of level `level` (finest first) of the latest [`Multigrid::assemble`],
    /// 3x3 blocks in mN/mm over the level's unknowns: the finest reduced stiffness, a
    /// coarse Galerkin operator (the coarsest with the diagonal of its diagonal blocks
    /// scaled by `1 + 1e-8` for the Cholesky factorisation) or a rediscretised one.
    ///
    /// # Panics
    /// If `level` is not below [`Multigrid::level_count`].
    pub fn operator(&self, level: usize) -> &BlockCsr {
        self.levels[level].op()
    }

    /// The prolongation from level `level + 1` to level `level` as the cycle and the
    /// Galerkin product use it, dense and row-major (`3 n_fine x 3 n_coarse`,
    /// dimensionless; for tests on small hierarchies): the barycentric `P` with the rows
    /// of held fine unknowns and the columns of inactive coarse unknowns zeroed, or the
    /// smoothed `P_s` of the latest assembly.
    ///
    /// # Panics
    /// If `level + 1` is not below [`Multigrid::level_count`].
    pub fn prolongation_dense(&self, level: usize) -> Vec<Vec<f64>> {
        let t = &self.transfers[level];
        let nc = self.levels[level + 1].unknowns;
        let mut d = vec![vec![0.0; 3 * nc]; 3 * self.levels[level].unknowns];
        match &t.smoothed {
            Some(p) => {
                for (f, rows) in d.chunks_mut(3).enumerate() {
                    for k in p.ptr[f]..p.ptr[f + 1] {
                        let c = 3 * p.cols[k] as usize;
                        for (r, row) in rows.iter_mut().enumerate() {
                            for q in 0..3 {
                                row[c + q] += p.w[k].col(q)[r];
                            }
                        }
                    }
                }
            }
            None => {
                for (f, rows) in d.chunks_mut(3).enumerate() {
                    for k in t.p_ptr[f]..t.p_ptr[f + 1] {
                        let c = 3 * t.p_cols[k] as usize;
                        for (r, row) in rows.iter_mut().enumerate() {
                            row[c + r] += t.p_w[k];
                        }
                    }
                }
            }
        }
        d
    }

    /// The finest level's model.
    pub fn model(&self) -> &FemModel {
        &self.levels[0].model
    }

    /// The finest level's reduced system of the latest [`Multigrid::assemble`].
    pub fn system(&self) -> &ReducedSystem {
        self.levels[0]
            .system
            .as_ref()
            .expect("the finest level has its system")
    }

    /// The finest level's system, mutably.
    fn finest_mut(&mut self) -> &mut ReducedSystem {
        self.levels[0]
            .system
            .as_mut()
            .expect("the finest level has its system")
    }

    /// Changes the prescribed displacement (mm) of an already constrained vertex of the
    /// finest level (permanent or changeable), until the next
    /// [`Multigrid::set_constraints`].
    ///
    /// Errors: the vertex is free or out of range, or `d` is not finite.
    pub fn set_prescribed(&mut self, vertex: u32, d: DVec3) -> Result<(), FemError> {
        self.finest_mut().set_prescribed(vertex, d)
    }

    /// Changes the corotated tangent the assemblies compute ([`MultigridOptions::tangent`]),
    /// e.g. from the warped stiffness of the interactive cycles to the full tangent of a
    /// linearised correction. The hierarchy is kept: the patterns hold either tangent
    /// (the twist terms lie within each element's blocks). Call [`Multigrid::assemble`]
    /// (or [`Multigrid::cycle`]) afterwards.
    pub fn set_tangent(&mut self, tangent: Tangent) {
        if self.options.tangent != tangent {
            self.options.tangent = tangent;
            self.assembled = false;
        }
    }

    /// The corotated tangent the assemblies compute.
    pub fn tangent(&self) -> Tangent {
        self.options.tangent
    }

    /// Replaces the changeable constraints of the finest level (prescribed displacements
    /// in mm; the permanent ones given at construction stay) without rebuilding the
    /// hierarchy: O(vertices + prolongation entries), about a millisecond at 60,000
    /// elements. The held finest unknowns are eliminated symmetrically at the next
    /// [`Multigrid::assemble`] (identity diagonal block, zero row, column and right-hand
    /// side; see [`ReducedSystem::set_constraints`]), their prolongation rows are zeroed,
    /// and every coarse unknown whose weights towards the active finer unknowns sum to
    /// less than the Galerkin threshold gets a zero prolongation column and an identity
    /// block. The block patterns, colourings and the coarsest symbolic factorisation are
    /// kept, and the free part of the result is the one a hierarchy built with all the
    /// constraints permanent gives (same coarse spaces, same Galerkin operators on the
    /// active unknowns; only the smoother's colour order differs). Call
    /// [`Multigrid::assemble`] (or [`Multigrid::cycle`]) afterwards.
    ///
    /// Errors: a constraint out of range or not finite (nothing changed);
    /// [`FemError::NoConstraints`] if no finest vertex is held at all.
    pub fn set_constraints(&mut self, constraints: &Constraints) -> Result<(), FemError> {
        let result = self.finest_mut().set_constraints(constraints);
        if matches!(
            result,
            Err(FemError::ConstraintOutOfRange { .. } | FemError::NonFiniteInput { .. })
        ) {
            return result;
        }
        self.update_active();
        self.assembled = false;
        result
    }

    /// Recomputes the active unknowns of every level and masks the transfers.
    fn update_active(&mut self) {
        let finest = self.levels[0]
            .system
            .as_ref()
            .expect("the finest level has its system");
        let active: Vec<bool> = finest.eliminated().iter().map(|&e| !e).collect();
        self.levels[0].active = active;
        let galerkin = self.options.coarse_operator == CoarseOperator::Galerkin;
        for l in 0..self.transfers.len() {
            let (fine, coarse) = self.levels.split_at_mut(l + 1);
            let fine_active = &fine[l].active;
            let t = &mut self.transfers[l];
            let coarse_active = &mut coarse[0].active;
            if galerkin {
                for (c, a) in coarse_active.iter_mut().enumerate() {
                    let weight: f64 = (t.pt_ptr[c]..t.pt_ptr[c + 1])
                        .filter(|&k| fine_active[t.pt_cols[k] as usize])
                        .map(|k| t.p_w_full[t.pt_src[k]].abs())
                        .sum();
                    *a = weight >= MIN_COARSE_WEIGHT;
                }
            }
            t.mask(fine_active, coarse_active);
        }
    }

    /// Replaces the material of one finest element (e.g. the implant elements of a
    /// displacement template); the patterns are kept, the next [`Multigrid::assemble`]
    /// uses it. Rediscretised coarse levels keep their own materials.
    ///
    /// Errors: see [`FemModel::set_material`].
    pub fn set_material(
        &mut self,
        element: usize,
        material: crate::material::Material,
    ) -> Result<(), FemError> {
        self.levels[0].model.set_material(element, material)
    }

    /// Active unknowns per level, finest first: the unknowns not held by a changeable
    /// constraint (finest) or not switched off as too weakly seen (coarse).
    pub fn active_unknowns_per_level(&self) -> Vec<usize> {
        self.levels
            .iter()
            .map(|l| l.active.iter().filter(|&&a| a).count())
            .collect()
    }

    /// Assembles every level at the finest displacement `u` (mm, all finest vertices;
    /// use [`ReducedSystem::expand`] to impose the prescribed values): the finest
    /// `K'_ff` and `r_f = f_ext - f_int(u)` (`f_ext` may be empty), each coarse level's
    /// `K'_ff` with rotations from `u` sampled at its vertices, the smoother's inverse
    /// diagonal blocks, and the coarsest Cholesky factor. Parallel within each level.
    pub fn assemble(
        &mut self,
        u: &[DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
    ) -> Result<(), FemError> {
        rayon::scope(|_| self.assemble_in_pool(u, f_ext, formulation))
    }

    fn assemble_in_pool(
        &mut self,
        u: &[DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
    ) -> Result<(), FemError> {
        self.levels[0].model.check_vertex_field("displacement", u)?;
        if self.system().held_count() == 0 {
            return Err(FemError::NoConstraints);
        }
        self.us[0].copy_from_slice(u);
        let mut times = PhaseTimes::default();
        for l in 0..self.levels.len() {
            let t0 = Instant::now();
            if l > 0 && self.options.coarse_operator == CoarseOperator::Rediscretised {
                let (fine, coarse) = self.us.split_at_mut(l);
                if formulation == Formulation::Corotated {
                    self.transfers[l - 1]
                        .sample
                        .prolong(&fine[l - 1], &mut coarse[0]);
                } else {
                    coarse[0].fill(DVec3::ZERO);
                }
            }
            if l > 0 && self.options.coarse_operator == CoarseOperator::Galerkin {
                let (fine, coarse) = self.levels.split_at_mut(l);
                let level = &mut coarse[0];
                let c = level.galerkin.as_mut().expect("Galerkin pattern");
                let t = &mut self.transfers[l - 1];
                match t.smoothed.take() {
                    Some(mut smoothed) => {
                        smoothed.update(fine[l - 1].op(), &fine[l - 1].inv_diag, t);
                        c.smoothed_values(&smoothed, &level.active);
                        t.smoothed = Some(smoothed);
                    }
                    None => c.barycentric_values(fine[l - 1].op(), t, &level.active),
                }
            } else {
                let level = &mut self.levels[l];
                let f = if l == 0 { f_ext } else { &[] };
                level
                    .system
                    .as_mut()
                    .expect("a level without a Galerkin operator has its system")
                    .assemble(
                        &level.model,
                        &self.us[l],
                        f,
                        formulation,
                        self.options.tangent,
                    )?;
            }
            let t1 = Instant::now();
            if l == 0 {
                times.finest_assembly_ms += ms(t1 - t0);
            } else {
                times.coarse_operators_ms += ms(t1 - t0);
            }
            let level = &mut self.levels[l];
            let a = match (&level.galerkin, &level.system) {
                (Some(g), _) => &g.op,
                (None, Some(s)) => &s.matrix,
                (None, None) => unreachable!("a level has a Galerkin operator or a system"),
            };
            let diag_slot = &level.diag_slot;
            level
                .inv_diag
                .par_iter_mut()
                .enumerate()
                .for_each(|(i, d)| {
                    let m = block_of(&a.values[diag_slot[i]]);
                    *d = m.inverse();
                });
            if let Some(i) = level.inv_diag.iter().position(|d| !d.is_finite()) {
                return Err(FemError::Singular {
                    detail: format!("level {l}: diagonal block of unknown {i} is singular"),
                });
            }
            times.smoother_setup_ms += ms(t1.elapsed());
        }
        let t2 = Instant::now();
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
        times.coarsest_factorisation_ms = ms(t2.elapsed());
        times.vcycle_ms = self.times.vcycle_ms;
        self.times = times;
        self.assembled = true;
        Ok(())
    }

    /// `‖b - A x‖₂` on the assembled finest system.
    pub fn residual_norm(&mut self, x: &[DVec3], b: &[DVec3]) -> f64 {
        let r = &mut self.rs[0];
        residual(self.levels[0].op(), x, b, r);
        norm(r)
    }

    /// One V(ν₁, ν₂) cycle on the assembled finest system `A x = b` (one entry per finest
    /// unknown), improving `x` in place (warm start).
    ///
    /// # Panics
    /// Before the first [`Multigrid::assemble`], or on length mismatches.
    pub fn vcycle(&mut self, x: &mut [DVec3], b: &[DVec3]) {
        // run on a worker of the thread pool: the parallel loops inside then fork
        // without the cross-thread hand-over of a call from outside the pool
        let post_smooth = self.options.post_smooth;
        rayon::scope(|_| self.vcycle_in_pool(x, b, post_smooth));
    }

    /// One V(ν₁, ν₁) cycle, [`Multigrid::vcycle`] with as many smoothing steps after the
    /// coarse correction as before it: a symmetric positive definite operator (for a
    /// symmetric positive definite `A`), as conjugate gradients needs of a preconditioner.
    ///
    /// # Panics
    /// Before the first [`Multigrid::assemble`], or on length mismatches.
    pub fn symmetric_vcycle(&mut self, x: &mut [DVec3], b: &[DVec3]) {
        let post_smooth = self.options.pre_smooth;
        rayon::scope(|_| self.vcycle_in_pool(x, b, post_smooth));
    }

    /// The V-cycle with `post_smooth` steps after the coarse correction.
    fn vcycle_in_pool(&mut self, x: &mut [DVec3], b: &[DVec3], post_smooth: usize) {
        assert!(self.assembled, "Multigrid::vcycle before assemble");
        let n0 = self.levels[0].unknowns;
        assert_eq!(x.len(), n0);
        assert_eq!(b.len(), n0);
        if n0 == 0 {
            return;
        }
        let t0 = Instant::now();
        self.xs[0].copy_from_slice(x);
        self.bs[0].copy_from_slice(b);
        let nl = self.levels.len();
        let o = self.options;
        // down
        for l in 0..nl - 1 {
            let level = &self.levels[l];
            for _ in 0..o.pre_smooth * o.sweeps_per_step {
                sor_sweep(level, o.relaxation, true, &mut self.xs[l], &self.bs[l]);
            }
            residual(level.op(), &self.xs[l], &self.bs[l], &mut self.rs[l]);
            let t = &self.transfers[l];
            let r = &self.rs[l];
            let restrict = |(c, bc): (usize, &mut DVec3)| {
                let mut s = DVec3::ZERO;
                match &t.smoothed {
                    Some(p) => {
                        for k in p.t_ptr[c]..p.t_ptr[c + 1] {
                            s += p.w[p.t_src[k]].transpose() * r[p.t_cols[k] as usize];
                        }
                    }
                    None => {
                        for k in t.pt_ptr[c]..t.pt_ptr[c + 1] {
                            s += r[t.pt_cols[k] as usize] * t.pt_w[k];
                        }
                    }
                }
                *bc = s;
            };
            self.bs[l + 1]
                .par_iter_mut()
                .enumerate()
                .with_min_len(256)
                .for_each(restrict);
            self.xs[l + 1].fill(DVec3::ZERO);
        }
        // coarsest
        if let Some(c) = &self.coarse {
            c.solve_factorised(&self.bs[nl - 1], &mut self.xs[nl - 1]);
        }
        // up
        for l in (0..nl - 1).rev() {
            let t = &self.transfers[l];
            let (fine, coarse) = self.xs.split_at_mut(l + 1);
            let xc = &coarse[0];
            fine[l]
                .par_iter_mut()
                .enumerate()
                .with_min_len(256)
                .for_each(|(f, xf)| match &t.smoothed {
                    Some(p) => {
                        for k in p.ptr[f]..p.ptr[f + 1] {
                            *xf += p.w[k] * xc[p.cols[k] as usize];
                        }
                    }
                    None => {
                        for k in t.p_ptr[f]..t.p_ptr[f + 1] {
                            *xf += xc[t.p_cols[k] as usize] * t.p_w[k];
                        }
                    }
                });
            let level = &self.levels[l];
            for _ in 0..post_smooth * o.sweeps_per_step {
                sor_sweep(level, o.relaxation, false, &mut self.xs[l], &self.bs[l]);
            }
        }
        x.copy_from_slice(&self.xs[0]);
        self.times.vcycle_ms = ms(t0.elapsed());
    }

    /// Phase times of the latest [`Multigrid::assemble`] and [`Multigrid::vcycle`].
    pub fn phase_times(&self) -> PhaseTimes {
        self.times
    }

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

    /// The correction `α z` for the residual `r` of the assembled finest system: `z` one
    /// V-cycle from zero on `A z = r`, `α = (r·z) / (zᵀ A z)` the minimum of the
    /// quadratic energy along it (see [`MultigridOptions::optimal_step`]), kept within
    /// [`STEP_SCALE_RANGE`] (1 if the energy does not decrease along `z`). Writes it to
    /// `z` and returns `α`.
    ///
    /// # Panics
    /// Before the first [`Multigrid::assemble`], or on length mismatches.
    pub fn optimal_correction(&mut self, r: &[DVec3], z: &mut [DVec3]) -> f64 {
        z.fill(DVec3::ZERO);
        self.vcycle(z, r);
        let az = &mut self.rs[0];
        self.levels[0].op().mul_vec(z, az);
        let (rz, zaz) = (dot(r, z), dot(z, az));
        let alpha = if rz > 0.0 && zaz > 0.0 {
            (rz / zaz).clamp(STEP_SCALE_RANGE.0, STEP_SCALE_RANGE.1)
        } else {
            1.0
        };
        z.par_iter_mut().for_each(|zi| *zi *= alpha);
        alpha
    }

    /// One interactive step on the finest displacement `u` (mm, all vertices; the
    /// prescribed values are imposed on it): reassembles every level at `u`, runs one
    /// V-cycle on `K'_ff Δu_f = f_ext - f_int(u)` from `Δu_f = 0` and adds `Δu_f`. For
    /// the linear formulation this is exactly one V-cycle warm-started from `u`.
    pub fn cycle(
        &mut self,
        u: &mut [DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
    ) -> Result<CycleReport, FemError> {
        self.levels[0].model.check_vertex_field("displacement", u)?;
        let sys = self.system();
        let u_free: Vec<DVec3> = sys.free.iter().map(|&v| u[v as usize]).collect();
        let imposed = sys.expand(&u_free);
        u.copy_from_slice(&imposed);
        self.assemble(u, f_ext, formulation)?;
        let b = self.system().rhs.clone();
        let residual_before = norm(&b);
        let mut du = vec![DVec3::ZERO; b.len()];
        let step_scale = if self.options.optimal_step && formulation == Formulation::Linear {
            self.optimal_correction(&b, &mut du)
        } else {
            self.vcycle(&mut du, &b);
            1.0
        };
        for (&v, d) in self.system().free.iter().zip(&du) {
            u[v as usize] += *d;
        }
        Ok(CycleReport {
            residual_before,
            step_scale,
        })
    }
}
