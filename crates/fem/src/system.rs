//! Dirichlet constraints, and the reduced linear system of the free vertices as a
//! block-sparse (3x3) CSR matrix whose pattern is built once and whose values are
//! refilled in parallel at every corotational step.
//!
//! Elimination: the unknowns are the displacements of the free vertices only. The
//! system solved at a step is the Newton-like update `K'_ff Δu_f = r_f` with
//! `r = f_ext - f_int(u)`, where `u` already carries the prescribed displacements at the
//! constrained vertices (so `Δu_c = 0`). With the rotations held fixed `f_int` is linear,
//! `f_int(u) = K' u - Σ R K X + K' X`, so at `u_f = 0` this right-hand side is exactly the
//! classical corrected one, `f_f - K'_fc u_c` (plus the corotational terms).
//!
//! Changeable constraints: the constraints given to [`ReducedSystem::new`] (or
//! [`ReducedSystem::with_permanent`]) are permanent and shape the block pattern. Further
//! constraints, replaced as a whole in O(vertices) by [`ReducedSystem::set_constraints`]
//! (an implant's displacement template that changes whenever the implant moves), keep
//! their vertices as unknowns of the pattern and are eliminated symmetrically at every
//! assembly: their block rows and columns are zeroed, their diagonal blocks set to the
//! identity and their right-hand side to zero (so their correction is `Δu_c = 0`). The
//! coupling `K'_fc u_c` is not lost: `u` carries the prescribed values (see
//! [`ReducedSystem::expand`]), so `f_int(u)` in the right-hand side of the free vertices
//! contains it. The free rows are therefore exactly those of a system built with all the
//! constraints permanent.

#![allow(unsafe_code)] // vector kernels and raw disjoint writes, each block with its SAFETY reason
use crate::blocks::{self, BlockKernels};
use crate::error::FemError;
use crate::membrane::MembraneState;
use crate::model::{FemModel, Formulation, Tangent};
use crate::polar::POLAR_LANES;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::marker::PhantomData;

mod upper;
pub(crate) use upper::UpperTriangle;

/// Marks a vertex that is not an unknown of the reduced system.
pub const NOT_FREE: u32 = u32::MAX;

/// Prescribed displacements (Dirichlet constraints) at chosen vertices.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Constraints {
    /// `(vertex, prescribed displacement in mm)`; a later entry for the same vertex wins.
    pub prescribed: Vec<(u32, DVec3)>,
}

impl Constraints {
    /// No constraints.
    pub fn new() -> Constraints {
        Constraints::default()
    }

    /// Prescribes the displacement (mm) of `vertex`.
    pub fn prescribe(&mut self, vertex: u32, displacement: DVec3) -> &mut Self {
        self.prescribed.push((vertex, displacement));
        self
    }

    /// Fixes `vertex` (zero displacement).
    pub fn fix(&mut self, vertex: u32) -> &mut Self {
        self.prescribe(vertex, DVec3::ZERO)
    }

    /// Per-vertex constraint table: `Some(displacement)` where constrained.
    pub fn table(&self, vertex_count: usize) -> Result<Vec<Option<DVec3>>, FemError> {
        let mut t = vec![None; vertex_count];
        for &(v, d) in &self.prescribed {
            let vertex = v as usize;
            if vertex >= vertex_count {
                return Err(FemError::ConstraintOutOfRange {
                    vertex,
                    vertex_count,
                });
            }
            if !d.is_finite() {
                return Err(FemError::NonFiniteInput {
                    what: "prescribed displacement",
                    vertex,
                    value: d.to_array(),
                });
            }
            t[vertex] = Some(d);
        }
        Ok(t)
    }
}

/// A square block-sparse matrix in CSR form with 3x3 blocks (row-major `[f64; 9]`).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BlockCsr {
    /// Row `i`'s blocks are `row_ptr[i]..row_ptr[i + 1]`.
    pub row_ptr: Vec<usize>,
    /// Block column of each block, ascending within a row.
    pub cols: Vec<u32>,
    /// Block values, row-major 3x3.
    pub values: Vec<[f64; 9]>,
}

impl BlockCsr {
    /// Number of block rows.
    pub fn block_rows(&self) -> usize {
        self.row_ptr.len().saturating_sub(1)
    }

    /// Slot of block `(i, j)`, if present.
    pub fn slot(&self, i: usize, j: usize) -> Option<usize> {
        let r = self.row_ptr[i]..self.row_ptr[i + 1];
        self.cols[r.clone()]
            .binary_search(&(j as u32))
            .ok()
            .map(|k| r.start + k)
    }

    /// `(A x)ᵢ`, row `i` of `A x`.
    #[inline]
    pub fn row_mul(&self, i: usize, x: &[DVec3]) -> DVec3 {
        // SAFETY: `x` is a live slice of `x.len()` entries, borrowed shared (no writer)
        unsafe { self.row_mul_raw(i, x.as_ptr(), x.len()) }
    }

    /// `(A x)ᵢ` with `x` given as `len` entries at `x` (every column index is checked
    /// against `len`). With AVX2 and FMA (detected at run time) four-lane products:
    /// about three times fewer instructions than the scalar loop, the same result to
    /// round-off (the sums are only ordered differently).
    ///
    /// # Safety
    /// `x` must point to `len` initialised entries, and no other thread may write the
    /// entries of this row's columns during the call.
    #[inline]
    pub(crate) unsafe fn row_mul_raw(&self, i: usize, x: *const DVec3, len: usize) -> DVec3 {
        let r = self.row_ptr[i]..self.row_ptr[i + 1];
        let (values, cols) = (&self.values[r.clone()], &self.cols[r]);
        #[cfg(target_arch = "x86_64")]
        if blocks::simd_available() {
            // SAFETY: the processor has AVX2 and FMA (checked just above); the caller
            // vouches for `x` and `len`
            return unsafe { row_mul_avx2(values, cols, x, len) };
        }
        values.iter().zip(cols).fold(DVec3::ZERO, |s, (b, &j)| {
            let j = j as usize;
            assert!(j < len, "column {j} out of {len}");
            // SAFETY: in bounds (asserted); the caller vouches for the rest
            s + block_mul(b, unsafe { x.add(j).read() })
        })
    }

    /// `y = A x` (parallel over rows).
    pub fn mul_vec(&self, x: &[DVec3], y: &mut [DVec3]) {
        y.par_iter_mut()
            .enumerate()
            .for_each(|(i, yi)| *yi = self.row_mul(i, x));
    }

    /// The dense matrix (for tests on small systems), row-major, `3n x 3n`.
    pub fn to_dense(&self) -> Vec<Vec<f64>> {
        let n = 3 * self.block_rows();
        let mut d = vec![vec![0.0; n]; n];
        for i in 0..self.block_rows() {
            for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                let j = self.cols[k] as usize;
                for p in 0..3 {
                    for q in 0..3 {
                        d[3 * i + p][3 * j + q] = self.values[k][3 * p + q];
                    }
                }
            }
        }
        d
    }
}

/// [`BlockCsr::row_mul_raw`]'s four-lane kernel: per block, rows 0 and 1 of `B` are
/// loaded as `(b₀ b₁ b₂ b₃)`, `(b₃ b₄ b₅ b₆)` against `(x y z 0)` and row 2 as
/// `(b₅ b₆ b₇ b₈)` against `(0 x y z)`, so every load stays inside the block; the lanes
/// are summed once per row. Written by hand: no crate offers block-sparse products
/// with 3x3 blocks, and the compiler does not vectorise the scalar form.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn row_mul_avx2(values: &[[f64; 9]], cols: &[u32], x: *const DVec3, len: usize) -> DVec3 {
    use std::arch::x86_64::*;
    let first_three = _mm256_setr_epi64x(-1, -1, -1, 0);
    let (mut row0, mut row1, mut row2) = (
        _mm256_setzero_pd(),
        _mm256_setzero_pd(),
        _mm256_setzero_pd(),
    );
    for (b, &j) in values.iter().zip(cols) {
        let j = j as usize;
        assert!(j < len, "column {j} out of {len}");
        // SAFETY: entry `j` is in bounds (asserted) and its three f64 are read with the
        // fourth lane masked off; the block loads read b[0..4], b[3..7], b[5..9]
        unsafe {
            let xyz0 = _mm256_maskload_pd(x.add(j).cast::<f64>(), first_three);
            let zero_xyz = _mm256_permute4x64_pd::<0b10_01_00_11>(xyz0);
            let p = b.as_ptr();
            row0 = _mm256_fmadd_pd(_mm256_loadu_pd(p), xyz0, row0);
            row1 = _mm256_fmadd_pd(_mm256_loadu_pd(p.add(3)), xyz0, row1);
            row2 = _mm256_fmadd_pd(_mm256_loadu_pd(p.add(5)), zero_xyz, row2);
        }
    }
    let lane_sum = |v: __m256d| {
        let pair = _mm_add_pd(_mm256_castpd256_pd128(v), _mm256_extractf128_pd::<1>(v));
        _mm_cvtsd_f64(_mm_add_sd(pair, _mm_unpackhi_pd(pair, pair)))
    };
    DVec3::new(lane_sum(row0), lane_sum(row1), lane_sum(row2))
}

/// `B x` for a row-major 3x3 block.
#[inline]
pub fn block_mul(b: &[f64; 9], x: DVec3) -> DVec3 {
    DVec3::new(
        b[0] * x.x + b[1] * x.y + b[2] * x.z,
        b[3] * x.x + b[4] * x.y + b[5] * x.z,
        b[6] * x.x + b[7] * x.y + b[8] * x.z,
    )
}

/// Per-element data the block gather reads: rotated gradients, forces, `V λ`, `V μ`,
/// and the inversion barrier's `2κV` (zero where it does not act).
#[derive(Debug, Clone, Copy, Default)]
struct ElementCore {
    rotated_grad: [DVec3; 4],
    force: [DVec3; 4],
    vol_lambda: f64,
    vol_mu: f64,
    barrier_stiffness: f64,
}

/// The reduced system over the free vertices: the fixed block pattern with its
/// element-to-slot maps, and the values and right-hand side of the latest assembly.
#[derive(Debug, Clone)]
pub struct ReducedSystem {
    /// For each vertex, its unknown index, or [`NOT_FREE`] (constrained, or used by no
    /// element).
    pub reduced_of: Vec<u32>,
    /// For each unknown, its vertex.
    pub free: Vec<u32>,
    /// Per-vertex prescribed displacement (zero where free).
    pub prescribed: Vec<DVec3>,
    /// The reduced stiffness `K'_ff`, 3x3 blocks.
    pub matrix: BlockCsr,
    /// The reduced right-hand side `r_f = f_ext - f_int(u)` at the free vertices (mN),
    /// or a dead load where [`ReducedSystem::internal_forces_as_dead_loads`] set one.
    pub rhs: Vec<DVec3>,
    /// For each unknown, the incident elements `element << 2 | a`, sorted by element.
    incident_ptr: Vec<usize>,
    incident: Vec<u32>,
    /// For each vertex that is no unknown (held by a permanent constraint, or used by
    /// no element), in vertex order, its incident elements like `incident`.
    fixed_incident_ptr: Vec<usize>,
    fixed_incident: Vec<u32>,
    /// For each incidence `(element, a)` of row `i`, and each corner `b`, the index of
    /// the block `(i, t[b])` within row `i`'s upper part (diagonal first), or
    /// [`NOT_FREE`] where `t[b]` is no unknown or left of the diagonal.
    incident_slots: Vec<[u32; 4]>,
    /// The upper block triangle of `matrix`, which the assembly computes.
    upper: UpperTriangle,
    /// Rotated gradients and forces of each element, latest assembly.
    cores: Vec<ElementCore>,
    /// Twist terms of each element for [`Tangent::Full`] (empty otherwise).
    twists: Vec<DMat3>,
    /// The model's membranes in their state of the latest assembly (their forces are
    /// in `cores`).
    membranes: Vec<MembraneState>,
    /// For each unknown, whether a changeable constraint holds it (eliminated at
    /// assembly).
    eliminated: Vec<bool>,
    /// Per-vertex prescribed displacement of the permanent constraints (mm).
    permanent: Vec<DVec3>,
    /// Per-vertex: held by a permanent constraint.
    permanent_held: Vec<bool>,
    /// Per-vertex: held by a permanent or a changeable constraint.
    held: Vec<bool>,
    /// `Σ |f|²` of the sliders' forces at the free vertices, latest assembly (mN²).
    slider_force_norm_squared: f64,
    /// Number of vertices held by a permanent or a changeable constraint.
    held_count: usize,
}

impl ReducedSystem {
    /// Builds the pattern for `model` with the given constraints.
    ///
    /// Errors: a constraint out of range or not finite; no constraint at all
    /// ([`FemError::NoConstraints`]: the system would be singular).
    pub fn new(model: &FemModel, constraints: &Constraints) -> Result<ReducedSystem, FemError> {
        if constraints.prescribed.is_empty() {
            return Err(FemError::NoConstraints);
        }
        ReducedSystem::with_permanent(model, constraints)
    }

    /// Builds the pattern for `model` with `permanent` constraints, which may be empty:
    /// the constraints that change are set later with
    /// [`ReducedSystem::set_constraints`] (the system is singular until some vertex is
    /// held; [`ReducedSystem::held_count`] tells).
    ///
    /// Errors: a constraint out of range or not finite.
    pub fn with_permanent(
        model: &FemModel,
        permanent: &Constraints,
    ) -> Result<ReducedSystem, FemError> {
        let n = model.vertex_count();
        let table = permanent.table(n)?;
        if model.element_count() >= (1 << 27) {
            return Err(FemError::LengthMismatch {
                what: "tetrahedra (at most 2^27 supported)",
                expected: (1 << 27) - 1,
                got: model.element_count(),
            });
        }
        let tets = model.tets();
        // vertex -> incident (element, corner), in element order
        let mut count = vec![0usize; n + 1];
        for t in tets {
            for &v in t {
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let vertex_ptr = count.clone();
        let mut fill = count;
        let mut vertex_inc = vec![0u32; vertex_ptr[n]];
        for (e, t) in tets.iter().enumerate() {
            for (a, &v) in t.iter().enumerate() {
                vertex_inc[fill[v as usize]] = ((e as u32) << 2) | a as u32;
                fill[v as usize] += 1;
            }
        }
        let mut reduced_of = vec![NOT_FREE; n];
        let mut free = Vec::new();
        for v in 0..n {
            if table[v].is_none() && vertex_ptr[v + 1] > vertex_ptr[v] {
                reduced_of[v] = free.len() as u32;
                free.push(v as u32);
            }
        }
        let prescribed: Vec<DVec3> = table.iter().map(|d| d.unwrap_or(DVec3::ZERO)).collect();
        // per free row: its sorted columns, and the slots of its incidences
        let rows: Vec<(Vec<u32>, Vec<[u32; 4]>)> = free
            .par_iter()
            .enumerate()
            .map(|(i, &v)| {
                let inc = &vertex_inc[vertex_ptr[v as usize]..vertex_ptr[v as usize + 1]];
                let mut cols: Vec<u32> = inc
                    .iter()
                    .flat_map(|&ea| tets[(ea >> 2) as usize])
                    .map(|w| reduced_of[w as usize])
                    .filter(|&c| c != NOT_FREE)
                    .collect();
                cols.sort_unstable();
                cols.dedup();
                let diag = cols.partition_point(|&c| (c as usize) < i);
                let slots = inc
                    .iter()
                    .map(|&ea| {
                        tets[(ea >> 2) as usize].map(|w| {
                            let c = reduced_of[w as usize];
                            if c == NOT_FREE || (c as usize) < i {
                                NOT_FREE
                            } else {
                                cols[diag..].binary_search(&c).expect("column in row") as u32
                            }
                        })
                    })
                    .collect();
                (cols, slots)
            })
            .collect();
        let mut row_ptr = vec![0usize];
        let mut cols = Vec::new();
        let mut incident_slots = Vec::new();
        for (c, sl) in rows {
            cols.extend_from_slice(&c);
            row_ptr.push(cols.len());
            incident_slots.extend_from_slice(&sl);
        }
        let incidences = |vertices: &mut dyn Iterator<Item = u32>| {
            let mut ptr = vec![0usize];
            let mut list = Vec::new();
            for v in vertices {
                list.extend_from_slice(
                    &vertex_inc[vertex_ptr[v as usize]..vertex_ptr[v as usize + 1]],
                );
                ptr.push(list.len());
            }
            (ptr, list)
        };
        let (incident_ptr, incident) = incidences(&mut free.iter().copied());
        let (fixed_incident_ptr, fixed_incident) =
            incidences(&mut (0..n as u32).filter(|&v| reduced_of[v as usize] == NOT_FREE));
        let slots = cols.len();
        let permanent_held: Vec<bool> = table.iter().map(Option::is_some).collect();
        let held_count = permanent_held.iter().filter(|&&h| h).count();
        let matrix = BlockCsr {
            row_ptr,
            cols,
            values: vec![[0.0; 9]; slots],
        };
        Ok(ReducedSystem {
            upper: UpperTriangle::new(&matrix),
            matrix,
            reduced_of,
            eliminated: vec![false; free.len()],
            permanent: prescribed.clone(),
            held: permanent_held.clone(),
            permanent_held,
            held_count,
            prescribed,
            rhs: vec![DVec3::ZERO; free.len()],
            free,
            incident_ptr,
            incident,
            fixed_incident_ptr,
            fixed_incident,
            incident_slots,
            cores: Vec::new(),
            twists: Vec::new(),
            membranes: Vec::new(),
            slider_force_norm_squared: 0.0,
        })
    }

    /// Number of unknown vertices (including those held by changeable constraints).
    pub fn unknowns(&self) -> usize {
        self.free.len()
    }

    /// Replaces the changeable constraints by `constraints` (the permanent ones stay; a
    /// changeable entry on a permanently held vertex overrides its value until the next
    /// call). O(vertices + constraints); the pattern is kept, the next
    /// [`ReducedSystem::assemble`] eliminates the held unknowns.
    ///
    /// Errors: a constraint out of range or not finite (the system is left unchanged);
    /// [`FemError::NoConstraints`] if no vertex would be held at all (the change is
    /// applied, the system is singular until constraints are added).
    pub fn set_constraints(&mut self, constraints: &Constraints) -> Result<(), FemError> {
        let n = self.reduced_of.len();
        for &(v, d) in &constraints.prescribed {
            let vertex = v as usize;
            if vertex >= n {
                return Err(FemError::ConstraintOutOfRange {
                    vertex,
                    vertex_count: n,
                });
            }
            if !d.is_finite() {
                return Err(FemError::NonFiniteInput {
                    what: "prescribed displacement",
                    vertex,
                    value: d.to_array(),
                });
            }
        }
        self.prescribed.copy_from_slice(&self.permanent);
        self.held.copy_from_slice(&self.permanent_held);
        self.eliminated.iter_mut().for_each(|e| *e = false);
        let mut held = self.permanent_held.iter().filter(|&&h| h).count();
        for &(v, d) in &constraints.prescribed {
            let vertex = v as usize;
            self.prescribed[vertex] = d;
            if !self.held[vertex] {
                self.held[vertex] = true;
                held += 1;
            }
            let r = self.reduced_of[vertex];
            if r != NOT_FREE {
                self.eliminated[r as usize] = true;
            }
        }
        self.held_count = held;
        if held == 0 {
            return Err(FemError::NoConstraints);
        }
        Ok(())
    }

    /// Changes the prescribed displacement (mm) of a vertex that is already held (by a
    /// permanent or a changeable constraint), until the next
    /// [`ReducedSystem::set_constraints`].
    ///
    /// Errors: the vertex is free or out of range, or `d` is not finite.
    pub fn set_prescribed(&mut self, vertex: u32, d: DVec3) -> Result<(), FemError> {
        let v = vertex as usize;
        if !self.is_held(vertex) {
            return Err(FemError::ConstraintOutOfRange {
                vertex: v,
                vertex_count: self.reduced_of.len(),
            });
        }
        if !d.is_finite() {
            return Err(FemError::NonFiniteInput {
                what: "prescribed displacement",
                vertex: v,
                value: d.to_array(),
            });
        }
        self.prescribed[v] = d;
        Ok(())
    }

    /// Whether `vertex` is held by a permanent or a changeable constraint (false for a
    /// vertex out of range).
    pub fn is_held(&self, vertex: u32) -> bool {
        self.held.get(vertex as usize).copied().unwrap_or(false)
    }

    /// For each unknown, whether a changeable constraint holds it: its block row and
    /// column are eliminated (identity diagonal block, zero right-hand side).
    pub fn eliminated(&self) -> &[bool] {
        &self.eliminated
    }

    /// Number of vertices held by a permanent or a changeable constraint.
    pub fn held_count(&self) -> usize {
        self.held_count
    }

    /// The displacement field with the prescribed values at held vertices and `u_free`
    /// (one per unknown) at the other unknowns; vertices used by no element get their
    /// prescribed value or zero.
    pub fn expand(&self, u_free: &[DVec3]) -> Vec<DVec3> {
        let mut u = self.prescribed.clone();
        for (k, &v) in self.free.iter().enumerate() {
            if !self.eliminated[k] {
                u[v as usize] = u_free[k];
            }
        }
        u
    }

    /// Turns the latest assembly's internal force at the marked vertices into a dead load:
    /// at each unknown whose vertex `marked` marks and no changeable constraint holds,
    /// the right-hand side becomes `f_ext` there (mN), as if that vertex's external
    /// force had been its internal force at the assembled displacement plus `f_ext`,
    /// without evaluating that force again. The next [`ReducedSystem::assemble`] undoes
    /// it.
    ///
    /// Errors: `marked` or `f_ext` does not have one entry per vertex, or `f_ext` is not
    /// finite at a marked vertex.
    pub fn internal_forces_as_dead_loads(
        &mut self,
        marked: &[bool],
        f_ext: &[DVec3],
    ) -> Result<(), FemError> {
        let vertices = self.reduced_of.len();
        for (what, got) in [("dead-load mask", marked.len()), ("dead load", f_ext.len())] {
            if got != vertices {
                return Err(FemError::LengthMismatch {
                    what,
                    expected: vertices,
                    got,
                });
            }
        }
        if let Some(vertex) = (0..vertices).find(|&v| marked[v] && !f_ext[v].is_finite()) {
            return Err(FemError::NonFiniteInput {
                what: "dead load",
                vertex,
                value: f_ext[vertex].to_array(),
            });
        }
        for ((r, &v), &held) in self.rhs.iter_mut().zip(&self.free).zip(&self.eliminated) {
            if !held && marked[v as usize] {
                *r = f_ext[v as usize];
            }
        }
        Ok(())
    }

    /// The internal elastic force of the elements and membranes at every vertex of
    /// `model` (the model assembled, mN; not the sliders'), from the latest
    /// [`ReducedSystem::assemble`]: the reactions at held vertices, the internal forces
    /// at free ones.
    pub fn nodal_forces(&self, model: &FemModel) -> Vec<DVec3> {
        model.nodal_sum(|e| self.cores[e].force)
    }

    /// `Σ |f_v|²` over the held vertices `v` (permanent and changeable constraints) of
    /// the internal forces `f` of the latest [`ReducedSystem::assemble`], i.e. the squared
    /// norm of the reactions that hold them (mN²); the same as summing
    /// [`ReducedSystem::nodal_forces`] there, without forming the forces of the free
    /// vertices. Plus the sliders' forces at free vertices, which hold them too.
    pub fn reaction_norm_squared(&self) -> f64 {
        let force_at = |incident: &[u32]| {
            incident.iter().fold(DVec3::ZERO, |f, &k| {
                f + self.cores[(k >> 2) as usize].force[(k & 3) as usize]
            })
        };
        fn ranges(ptr: &[usize]) -> impl Iterator<Item = std::ops::Range<usize>> + '_ {
            ptr.windows(2).map(|w| w[0]..w[1])
        }
        let permanent: f64 = ranges(&self.fixed_incident_ptr)
            .map(|r| force_at(&self.fixed_incident[r]).length_squared())
            .sum();
        let changeable: f64 = ranges(&self.incident_ptr)
            .zip(&self.eliminated)
            .filter(|&(_, &held)| held)
            .map(|(r, _)| force_at(&self.incident[r]).length_squared())
            .sum();
        permanent + changeable + self.slider_force_norm_squared
    }

    /// Assembles `K'_ff` (with the chosen [`Tangent`]) for the rotations of displacement
    /// `u` (mm, all vertices; it should carry the prescribed values, see
    /// [`ReducedSystem::expand`]) and the right-hand side `r_f = f_ext - f_int(u)` at the
    /// free vertices; unknowns held by changeable constraints get an identity diagonal
    /// block, zero off-diagonal blocks in their row and column, and a zero right-hand
    /// side. `f_ext` (mN, one per
    /// vertex) may be empty for no external force. Parallel: one pass over elements
    /// (rotations, rotated gradients, forces); one pass over block rows that reads each
    /// incident element once and adds its blocks on and right of the diagonal (each
    /// block sums its elements in element order: deterministic) and its forces to the
    /// right-hand side; one pass mirroring the lower triangle (exactly symmetric).
    pub fn assemble(
        &mut self,
        model: &FemModel,
        u: &[DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
        tangent: Tangent,
    ) -> Result<(), FemError> {
        model.check_vertex_field("displacement", u)?;
        if !f_ext.is_empty() {
            model.check_vertex_field("external force", f_ext)?;
        }
        let full = formulation == Formulation::Corotated && tangent == Tangent::Full;
        self.element_pass(model, u, formulation, full);
        // out of `self` while its rows are written, so the gathers can borrow the rest
        let mut matrix = std::mem::take(&mut self.matrix);
        let mut rhs = std::mem::take(&mut self.rhs);
        let BlockCsr {
            row_ptr,
            cols,
            values,
        } = &mut matrix;
        let gather = RowGather {
            forces: self.force_gather(model, u, f_ext),
            full,
            membranes: &self.membranes,
            twists: &self.twists,
            row_ptr,
            cols,
            incident_slots: &self.incident_slots,
        };
        let simd = blocks::simd_available();
        // the upper block triangle and the right-hand side, row by row: each block sums
        // its elements' contributions in element order (deterministic)
        self.upper
            .rows_mut(row_ptr, values)
            .into_par_iter()
            .zip(rhs.par_iter_mut())
            .enumerate()
            .for_each(|(i, (vals, r))| {
                #[cfg(target_arch = "x86_64")]
                if simd {
                    // SAFETY: the processor has AVX2 and FMA (`simd_available`)
                    return unsafe { gather.row_avx2(i, vals, r) };
                }
                let _ = simd;
                gather.row::<blocks::Scalar>(i, vals, r);
            });
        self.upper.mirror(&mut matrix);
        (self.matrix, self.rhs) = (matrix, rhs);
        self.update_slider_force_norm(model, u);
        Ok(())
    }

    /// The element pass of an assembly: each element's rotation, rotated gradients and
    /// forces (with the [`Tangent::Full`] twists when `full`), and the membranes' states
    /// and corner forces.
    fn element_pass(
        &mut self,
        model: &FemModel,
        u: &[DVec3],
        formulation: Formulation,
        full: bool,
    ) {
        let ne = model.element_count();
        let elements = model.elements();
        let core = |e: usize, rotated_grad, force, barrier_stiffness| ElementCore {
            rotated_grad,
            force,
            vol_lambda: elements[e].vol_lambda,
            vol_mu: elements[e].vol_mu,
            barrier_stiffness,
        };
        self.cores.resize(ne, ElementCore::default());
        if full {
            self.twists.resize(ne, DMat3::ZERO);
            self.cores
                .par_chunks_mut(POLAR_LANES)
                .zip(self.twists.par_chunks_mut(POLAR_LANES))
                .enumerate()
                .for_each(|(k, (chunk, twists))| {
                    let first = k * POLAR_LANES;
                    model.elements_full(first, u, |l, w, twist| {
                        chunk[l] = core(first + l, w.rotated_grad, w.force, w.barrier_stiffness);
                        twists[l] = twist;
                    });
                });
        } else {
            self.twists.clear();
            self.cores
                .par_chunks_mut(POLAR_LANES)
                .enumerate()
                .for_each(|(k, chunk)| {
                    let first = k * POLAR_LANES;
                    model.elements_warped(first, u, formulation, |l, w| {
                        chunk[l] = core(first + l, w.rotated_grad, w.force, w.barrier_stiffness);
                    });
                });
        }
        self.membranes = model.membrane_states(u, formulation);
        if !self.membranes.is_empty() {
            let states = &self.membranes;
            self.cores.par_iter_mut().enumerate().for_each(|(e, c)| {
                model.membrane_corner_forces(e, states, |k, force| c.force[k] += force);
            });
        }
    }

    /// The right-hand side `r_f = f_ext - f_int(u)` of [`ReducedSystem::assemble`] at the
    /// warped rotations of `u`, leaving the matrix as the latest assembly left it: the
    /// residual of a cycle that reuses the operators (a lagged cycle).
    pub fn assemble_forces(
        &mut self,
        model: &FemModel,
        u: &[DVec3],
        f_ext: &[DVec3],
        formulation: Formulation,
    ) -> Result<(), FemError> {
        model.check_vertex_field("displacement", u)?;
        if !f_ext.is_empty() {
            model.check_vertex_field("external force", f_ext)?;
        }
        self.element_pass(model, u, formulation, false);
        let mut rhs = std::mem::take(&mut self.rhs);
        let gather = self.force_gather(model, u, f_ext);
        rhs.par_iter_mut()
            .enumerate()
            .for_each(|(i, r)| *r = gather.row(i));
        self.rhs = rhs;
        self.update_slider_force_norm(model, u);
        Ok(())
    }

    /// What a row's right-hand side reads, from the latest element pass.
    fn force_gather<'a>(
        &'a self,
        model: &'a FemModel,
        u: &'a [DVec3],
        f_ext: &'a [DVec3],
    ) -> ForceGather<'a> {
        ForceGather {
            model,
            u,
            f_ext,
            cores: &self.cores,
            eliminated: &self.eliminated,
            incident_ptr: &self.incident_ptr,
            incident: &self.incident,
            free: &self.free,
        }
    }

    /// [`ReducedSystem::reaction_norm_squared`]'s sliders' share.
    fn update_slider_force_norm(&mut self, model: &FemModel, u: &[DVec3]) {
        self.slider_force_norm_squared = (model.sliders().iter())
            .filter(|s| {
                let v = s.vertex as usize;
                !self.held[v] && self.reduced_of[v] != NOT_FREE
            })
            .map(|s| s.force(u[s.vertex as usize]).length_squared())
            .sum();
    }
}

/// What a block row's right-hand side `f_ext - f_int(u)` reads: the element pass's
/// forces (membranes included) and the sliders.
struct ForceGather<'a> {
    model: &'a FemModel,
    u: &'a [DVec3],
    f_ext: &'a [DVec3],
    cores: &'a [ElementCore],
    eliminated: &'a [bool],
    incident_ptr: &'a [usize],
    incident: &'a [u32],
    free: &'a [u32],
}

impl ForceGather<'_> {
    /// Block row `i`'s right-hand side (zero for a held unknown): its elements' forces
    /// summed in element order (deterministic).
    #[inline]
    fn row(&self, i: usize) -> DVec3 {
        if self.eliminated[i] {
            return DVec3::ZERO;
        }
        let v = self.free[i] as usize;
        let mut f = if self.f_ext.is_empty() {
            DVec3::ZERO
        } else {
            self.f_ext[v]
        };
        for &k in &self.incident[self.incident_ptr[i]..self.incident_ptr[i + 1]] {
            f -= self.cores[(k >> 2) as usize].force[(k & 3) as usize];
        }
        if let Some(slider) = self.model.sliders.at(v) {
            f -= slider.force(self.u[v]);
        }
        f
    }
}

/// What [`ReducedSystem::assemble`]'s row gather reads: the element pass's results and
/// the pattern's element-to-slot maps.
struct RowGather<'a> {
    /// The elements' forces and the pattern's incidences, shared with the right-hand side.
    forces: ForceGather<'a>,
    full: bool,
    membranes: &'a [MembraneState],
    twists: &'a [DMat3],
    row_ptr: &'a [usize],
    cols: &'a [u32],
    incident_slots: &'a [[u32; 4]],
}

impl RowGather<'_> {
    /// Fills block row `i`'s upper part `vals` (its diagonal block, then the blocks right
    /// of it) and its right-hand side `r`.
    #[inline(always)]
    fn row<K: BlockKernels>(&self, i: usize, vals: &mut [[f64; 9]], r: &mut DVec3) {
        vals.fill([0.0; 9]);
        if self.forces.eliminated[i] {
            // a held unknown: identity diagonal block, zero row and right-hand side
            vals[0] = IDENTITY_BLOCK;
            *r = DVec3::ZERO;
            return;
        }
        let ucols = &self.cols[self.row_ptr[i + 1] - vals.len()..self.row_ptr[i + 1]];
        for k in self.forces.incident_ptr[i]..self.forces.incident_ptr[i + 1] {
            let e = (self.forces.incident[k] >> 2) as usize;
            let a = (self.forces.incident[k] & 3) as usize;
            let c = &self.forces.cores[e];
            let ha = c.rotated_grad[a].to_array();
            let lambda_ha = (c.rotated_grad[a] * c.vol_lambda).to_array();
            let mu_ha = (c.rotated_grad[a] * c.vol_mu).to_array();
            // the inversion barrier acts on few elements: its directions are
            // recomputed here rather than stored for all
            let barrier = (c.barrier_stiffness != 0.0).then(|| {
                self.forces
                    .model
                    .volume_gradients(e, self.forces.u)
                    .map(|g| g.to_array())
            });
            // [hₐ]ₓ C of the twist term, where the element has one
            let twist_a = (self.full && self.twists[e] != DMat3::ZERO)
                .then(|| cross_matrix(c.rotated_grad[a]) * self.twists[e]);
            for (b, &s) in self.incident_slots[k].iter().enumerate() {
                // a held unknown's column stays zero (eliminated)
                if s == NOT_FREE || self.forces.eliminated[ucols[s as usize] as usize] {
                    continue;
                }
                let out = &mut vals[s as usize];
                if a == b {
                    K::add_element_diagonal(out, c.vol_lambda + c.vol_mu, mu_ha, ha);
                } else {
                    K::add_element_block(out, lambda_ha, mu_ha, c.rotated_grad[b].to_array());
                }
                if let Some(twist_a) = twist_a {
                    add_twist_block(out, twist_a, c.rotated_grad[b], a == b);
                }
                if let Some(g) = &barrier {
                    add_rank_one(out, c.barrier_stiffness, g[a], g[b]);
                }
            }
            self.add_membrane_blocks(e, a, k, vals, ucols);
        }
        if let Some(slider) = self.forces.model.sliders.at(self.forces.free[i] as usize) {
            // the diagonal block comes first in the row's upper part
            for (o, x) in vals[0].iter_mut().zip(slider.block()) {
                *o += x;
            }
        }
        *r = self.forces.row(i);
    }

    /// Adds the blocks of element `e`'s membranes for its corner `a` (incidence `k`) to
    /// the row's upper part `vals` (columns `ucols`).
    #[inline]
    fn add_membrane_blocks(
        &self,
        e: usize,
        a: usize,
        k: usize,
        vals: &mut [[f64; 9]],
        ucols: &[u32],
    ) {
        for m in self.forces.model.membranes_of(e) {
            let corners = self.forces.model.membrane_corners(m);
            let Some(i) = corners.iter().position(|&c| c as usize == a) else {
                continue;
            };
            for (j, &b) in corners.iter().enumerate() {
                let s = self.incident_slots[k][b as usize];
                if s == NOT_FREE || self.forces.eliminated[ucols[s as usize] as usize] {
                    continue;
                }
                // row-major: the transpose's columns are the block's rows
                let block = self.membranes[m].block(i, j).transpose().to_cols_array();
                for (o, x) in vals[s as usize].iter_mut().zip(block) {
                    *o += x;
                }
            }
        }
    }

    /// [`RowGather::row`] with the AVX2/FMA block kernels.
    ///
    /// # Safety
    /// The processor must have AVX2 and FMA ([`blocks::simd_available`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn row_avx2(&self, i: usize, vals: &mut [[f64; 9]], r: &mut DVec3) {
        self.row::<blocks::Avx2Fma>(i, vals, r);
    }
}

/// The identity 3x3 block.
pub(crate) const IDENTITY_BLOCK: [f64; 9] = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0];

/// The transpose of a row-major 3x3 block.
#[inline]
pub(crate) fn transposed(b: &[f64; 9]) -> [f64; 9] {
    [b[0], b[3], b[6], b[1], b[4], b[7], b[2], b[5], b[8]]
}

/// A slice that parallel tasks read and write through, each writing only entries that no
/// other task reads or writes at the same time (which the borrow checker cannot see:
/// e.g. the rows of one colour of a Gauss-Seidel sweep, or the lower triangle of a matrix
/// filled from its upper one).
/// It borrows the slice mutably for its lifetime, so the slice cannot be used or freed
/// otherwise while tasks hold it.
#[derive(Clone, Copy)]
pub(crate) struct DisjointWrites<'a, T> {
    ptr: *mut T,
    len: usize,
    slice: PhantomData<&'a mut [T]>,
}

// SAFETY: the users uphold the disjointness contract of `read` and `write`.
unsafe impl<T: Send> Send for DisjointWrites<'_, T> {}
// SAFETY: as for `Send`: no entry is touched by two tasks at once.
unsafe impl<T: Send> Sync for DisjointWrites<'_, T> {}

impl<'a, T: Copy> DisjointWrites<'a, T> {
    pub(crate) fn new(slice: &'a mut [T]) -> DisjointWrites<'a, T> {
        DisjointWrites {
            ptr: slice.as_mut_ptr(),
            len: slice.len(),
            slice: PhantomData,
        }
    }

    /// Entry `i`.
    ///
    /// # Safety
    /// No other task may write entry `i` at the same time.
    #[inline]
    pub(crate) unsafe fn read(self, i: usize) -> T {
        assert!(i < self.len, "index {i} out of {}", self.len);
        // SAFETY: in bounds (asserted); no concurrent write (the caller's contract)
        unsafe { self.ptr.add(i).read() }
    }

    /// The start of the slice and its length, for readers taking raw entries (same
    /// contract as [`DisjointWrites::read`] for every entry they read).
    pub(crate) fn raw_parts(self) -> (*const T, usize) {
        (self.ptr, self.len)
    }

    /// Sets entry `i`.
    ///
    /// # Safety
    /// No other task may read or write entry `i` at the same time.
    #[inline]
    pub(crate) unsafe fn write(self, i: usize, value: T) {
        assert!(i < self.len, "index {i} out of {}", self.len);
        // SAFETY: in bounds (asserted); no concurrent access (the caller's contract)
        unsafe { self.ptr.add(i).write(value) }
    }
}

/// `values` split into the rows of `ptr` (row `i` is `ptr[i]..ptr[i + 1]`).
pub(crate) fn split_rows<'a, T>(mut values: &'a mut [T], ptr: &[usize]) -> Vec<&'a mut [T]> {
    let mut rows = Vec::with_capacity(ptr.len().saturating_sub(1));
    for w in ptr.windows(2) {
        let (head, tail) = values.split_at_mut(w[1] - w[0]);
        rows.push(head);
        values = tail;
    }
    rows
}

/// Adds the twist term `[hₐ]ₓ C [h_b]ₓᵀ` of [`Tangent::Full`] to a block, given
/// `twist_a = [hₐ]ₓ C`; a diagonal block (`a = b`) gets the symmetric part, so that it
/// stays exactly symmetric.
#[inline]
fn add_twist_block(out: &mut [f64; 9], twist_a: DMat3, h_b: DVec3, diagonal: bool) {
    let m = twist_a * cross_matrix(h_b).transpose();
    let m = if diagonal {
        (m + m.transpose()) * 0.5
    } else {
        m
    };
    for p in 0..3 {
        for q in 0..3 {
            out[3 * p + q] += m.col(q)[p];
        }
    }
}

/// The cross-product matrix `[h]ₓ` (`[h]ₓ x = h × x`).
#[inline]
pub(crate) fn cross_matrix(h: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, h.z, -h.y),
        DVec3::new(-h.z, 0.0, h.x),
        DVec3::new(h.y, -h.x, 0.0),
    )
}

/// `out += c · x yᵀ`; the products `x[p] y[q]` round alike for `(x, y)` and `(y, x)`,
/// so a diagonal block (`x = y`) stays exactly symmetric.
#[inline]
fn add_rank_one(out: &mut [f64; 9], c: f64, x: [f64; 3], y: [f64; 3]) {
    for p in 0..3 {
        for q in 0..3 {
            out[3 * p + q] += c * (x[p] * y[q]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 40-row block matrix with rows of 1 to 12 blocks at scattered columns and
    /// entries of mixed sign and size, from a fixed linear congruential sequence.
    fn scattered_matrix() -> BlockCsr {
        let mut state: u64 = 0x2545_f491_4f6c_dd1d;
        let mut next = move || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let n = 40;
        let (mut row_ptr, mut cols, mut values) = (vec![0], Vec::new(), Vec::new());
        for i in 0..n {
            let mut row: Vec<u32> = (0..1 + (i * 7) % 12)
                .map(|_| (next() * n as f64) as u32)
                .collect();
            row.sort_unstable();
            row.dedup();
            for j in row {
                cols.push(j);
                values.push(std::array::from_fn(|_| {
                    (next() - 0.5) * 10f64.powf(4.0 * next())
                }));
            }
            row_ptr.push(cols.len());
        }
        BlockCsr {
            row_ptr,
            cols,
            values,
        }
    }

    /// The row product (vector lanes where the processor has them) against the dense
    /// matrix times the vector, summed in a different order: relative 1e-13 of the
    /// row's absolute sum (a few dozen terms, each rounded at 1.1e-16).
    #[test]
    fn row_products_match_the_dense_product() {
        let a = scattered_matrix();
        let n = a.block_rows();
        let x: Vec<DVec3> = (0..n)
            .map(|i| DVec3::new(i as f64 - 20.0, 1.0 / (i as f64 + 1.0), (i as f64).sin()))
            .collect();
        let dense = a.to_dense();
        let flat: Vec<f64> = x.iter().flat_map(|v| v.to_array()).collect();
        for i in 0..n {
            let got = a.row_mul(i, &x).to_array();
            for (c, value) in got.iter().enumerate() {
                let row = &dense[3 * i + c];
                let expected: f64 = row.iter().zip(&flat).map(|(m, v)| m * v).sum();
                let scale: f64 = row.iter().zip(&flat).map(|(m, v)| (m * v).abs()).sum();
                assert!(
                    (value - expected).abs() <= 1e-13 * scale.max(f64::MIN_POSITIVE),
                    "row {i} component {c}: {value} against {expected}"
                );
            }
        }
    }

    /// A column index beyond the vector is refused, not read.
    #[test]
    #[should_panic(expected = "out of")]
    fn a_column_beyond_the_vector_panics() {
        let a = scattered_matrix();
        let short = vec![DVec3::ONE; 3];
        for i in 0..a.block_rows() {
            a.row_mul(i, &short);
        }
    }
}
