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
//! says, or a few conjugate gradient iterations as [`MultigridOptions::krylov_iterations`]
//! says: with the full tangent, an inexact Newton-Krylov step); [`Multigrid::lagged_cycle`]
//! is such a step on the operators of the last assembly, only the forces renewed;
//! [`Multigrid::vcycle`] is one V-cycle on the assembled finest system;
//! [`Multigrid::pcg`] is conjugate gradients preconditioned by one symmetric V(ν₁, ν₁)
//! cycle ([`PcgIteration`]).
//!
//! # Files
//! This file holds the options, the levels and the cycle (assembly, V-cycle, interactive
//! step); the rest is in:
//! - `build.rs`: building the hierarchy ([`Multigrid::new`]).
//! - `transfer.rs`: the prolongations between levels, barycentric and smoothed.
//! - `galerkin.rs`: the coarse unknowns and the Galerkin products `Pᵀ A P`.
//! - `smoother.rs`: the colouring and the multicolour block SOR sweeps.
//! - `coarse.rs`: the coarsest level's shifted Cholesky factorisation.
//! - `pcg.rs`: conjugate gradients preconditioned by the V-cycle ([`PcgIteration`]).
//!
//! [`Prolongation`]: crate::transfer::Prolongation
//! [`Prolongation::reduced`]: crate::transfer::Prolongation::reduced

mod build;
mod coarse;
mod galerkin;
mod pcg;
mod smoother;
mod transfer;

pub use pcg::{PcgIteration, PcgResult};

use crate::direct::DirectSolver;
use crate::error::FemError;
use crate::model::{FemModel, Formulation, Tangent};
use crate::system::{BlockCsr, Constraints, ReducedSystem};
use galerkin::{Galerkin, MIN_COARSE_WEIGHT};
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use smoother::sor_sweep;
use std::time::{Duration, Instant};
use transfer::Transfer;

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
    /// The corotated tangent of every assembly: the paper's warped stiffness
    /// `R K Rᵀ` (default), or [`Tangent::Full`] with the positive part of the geometric
    /// term (a Newton-like step where tissue is stretched and turned hard).
    pub tangent: Tangent,
    /// Whether [`Multigrid::cycle`] with the linear formulation scales the V-cycle's
    /// correction `z` to the minimum of the quadratic energy along it,
    /// `α = (b·z) / (zᵀ A z)` (one step of steepest descent preconditioned by the
    /// V-cycle; one more finest matrix-vector product). Default on: see the module
    /// documentation for the measured gain, and why corotated cycles are not scaled.
    pub optimal_step: bool,
    /// Conjugate gradient iterations per [`Multigrid::cycle`], each preconditioned by
    /// one symmetric V-cycle ([`PcgIteration`]), for the correction on the assembled
    /// tangent system; 0 runs the single V(ν₁, ν₂) cycle (with
    /// [`MultigridOptions::optimal_step`] for the linear formulation).
    pub krylov_iterations: usize,
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
            krylov_iterations: 0,
        }
    }
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
    /// Whether the cycle kept the latest assembly's operators ([`Multigrid::lagged_cycle`]).
    pub operators_lagged: bool,
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
    /// For each vertex its unknown, or [`NOT_FREE`](crate::system::NOT_FREE).
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
    /// The formulation of the latest assembly, if its operators still hold (`None`
    /// before any, and after a change of constraints, tangent, material or sliders).
    assembled: Option<Formulation>,
    times: PhaseTimes,
}

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

fn ms(d: Duration) -> f64 {
    d.as_secs_f64() * 1e3
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

impl Multigrid {
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

    /// The finest level's reduced system: the matrix of the latest
    /// [`Multigrid::assemble`], the right-hand side and element forces of the latest
    /// cycle (a [`Multigrid::lagged_cycle`] renews only these).
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

    /// [`ReducedSystem::internal_forces_as_dead_loads`] on the finest level's system of
    /// the latest [`Multigrid::assemble`] (the coarse levels have no right-hand side).
    pub fn internal_forces_as_dead_loads(
        &mut self,
        marked: &[bool],
        f_ext: &[DVec3],
    ) -> Result<(), FemError> {
        self.finest_mut()
            .internal_forces_as_dead_loads(marked, f_ext)
    }

    /// Changes the prescribed displacement (mm) of an already constrained vertex of the
    /// finest level (permanent or changeable), until the next
    /// [`Multigrid::set_constraints`].
    ///
    /// Errors: the vertex is free or out of range, or `d` is not finite.
    pub fn set_prescribed(&mut self, vertex: u32, d: DVec3) -> Result<(), FemError> {
        self.assembled = None;
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
            self.assembled = None;
        }
    }

    /// Changes how [`Multigrid::cycle`] computes its correction
    /// ([`MultigridOptions::krylov_iterations`]).
    pub fn set_krylov_iterations(&mut self, iterations: usize) {
        self.options.krylov_iterations = iterations;
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
        self.assembled = None;
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
        self.assembled = None;
        self.levels[0].model.set_material(element, material)
    }

    /// Gives a finest element a rest shape of its own ([`FemModel::set_rest_shape`]), or
    /// with `None` the mesh's back; the next [`Multigrid::assemble`] uses it.
    ///
    /// Errors: see [`FemModel::set_rest_shape`].
    pub fn set_rest_shape(
        &mut self,
        element: usize,
        corners: Option<[DVec3; 4]>,
    ) -> Result<(), FemError> {
        self.assembled = None;
        let model = &mut self.levels[0].model;
        match corners {
            Some(corners) => model.set_rest_shape(element, corners),
            None => model.reset_rest_shape(element),
        }
    }

    /// Replaces the finest model's sliders ([`FemModel::set_sliders`]); the next
    /// [`Multigrid::assemble`] uses them. Rediscretised coarse levels have none.
    ///
    /// Errors: see [`FemModel::set_sliders`].
    pub fn set_sliders(&mut self, sliders: &[crate::slider::Slider]) -> Result<(), FemError> {
        self.assembled = None;
        self.levels[0].model.set_sliders(sliders)
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
        // until this assembly completes, no operators hold (an error part-way leaves
        // some levels renewed and others not)
        self.assembled = None;
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
        self.factorise_coarsest()?;
        times.coarsest_factorisation_ms = ms(t2.elapsed());
        times.vcycle_ms = self.times.vcycle_ms;
        self.times = times;
        self.assembled = Some(formulation);
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
        assert!(
            self.assembled.is_some(),
            "Multigrid::vcycle before assemble"
        );
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
    /// V-cycle (or [`MultigridOptions::krylov_iterations`] preconditioned conjugate
    /// gradient iterations) on `K'_ff Δu_f = f_ext - f_int(u)` from `Δu_f = 0` and adds
    /// `Δu_f`. For the linear formulation one V-cycle is exactly one V-cycle
    /// warm-started from `u`.
    pub fn cycle(
        &mut self,
        u: &mut [DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
    ) -> Result<CycleReport, FemError> {
        self.step(u, f_ext, formulation, None)
    }

    /// [`Multigrid::cycle`] on the operators of the latest assembly (every level's matrix,
    /// smoother data and coarsest factor kept, i.e. lagged): only the right-hand side
    /// `f_ext - f_int(u)` is formed, at `u`'s own rotations, so the iteration still
    /// converges to the equilibrium, at a rate that depends on how far the rotations
    /// moved since the operators were assembled. About half a cycle's cost (the element
    /// pass and the V-cycle). A fresh cycle instead if the operators do not hold (no
    /// assembly yet, or one of another formulation, or a change of constraints,
    /// tangent, material or sliders since), or if the residual at `u` is not below
    /// `residual_limit_mn` (mN; the iteration is not contracting, so the operators are
    /// renewed; the element pass is then done twice). [`CycleReport::operators_lagged`]
    /// says which.
    pub fn lagged_cycle(
        &mut self,
        u: &mut [DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
        residual_limit_mn: f64,
    ) -> Result<CycleReport, FemError> {
        let limit = (self.assembled == Some(formulation)).then_some(residual_limit_mn);
        self.step(u, f_ext, formulation, limit)
    }

    /// A cycle; with `lag_below_mn`, the operators are kept if the residual is below it
    /// (the caller checked that they hold for `formulation`).
    fn step(
        &mut self,
        u: &mut [DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
        lag_below_mn: Option<f64>,
    ) -> Result<CycleReport, FemError> {
        self.levels[0].model.check_vertex_field("displacement", u)?;
        let sys = self.system();
        let u_free: Vec<DVec3> = sys.free.iter().map(|&v| u[v as usize]).collect();
        let imposed = sys.expand(&u_free);
        u.copy_from_slice(&imposed);
        let mut reuse_operators = false;
        if let Some(limit) = lag_below_mn {
            let level = &mut self.levels[0];
            let system = (level.system.as_mut()).expect("the finest level has its system");
            system.assemble_forces(&level.model, u, f_ext, formulation)?;
            reuse_operators = norm(&system.rhs) < limit;
        }
        if !reuse_operators {
            self.assemble(u, f_ext, formulation)?;
        }
        let b = self.system().rhs.clone();
        let residual_before = norm(&b);
        let mut du = vec![DVec3::ZERO; b.len()];
        let step_scale = if self.options.krylov_iterations > 0 {
            self.pcg(&b, &mut du, 0.0, self.options.krylov_iterations);
            1.0
        } else if self.options.optimal_step && formulation == Formulation::Linear {
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
            operators_lagged: reuse_operators,
        })
    }
}
