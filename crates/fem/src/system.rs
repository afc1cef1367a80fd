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

use crate::error::FemError;
use crate::model::{FemModel, Formulation, Tangent};
use glam::DVec3;
use rayon::prelude::*;

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

    /// `y = A x` (parallel over rows).
    pub fn mul_vec(&self, x: &[DVec3], y: &mut [DVec3]) {
        y.par_iter_mut().enumerate().for_each(|(i, yi)| {
            let mut s = DVec3::ZERO;
            for k in self.row_ptr[i]..self.row_ptr[i + 1] {
                s += block_mul(&self.values[k], x[self.cols[k] as usize]);
            }
            *yi = s;
        });
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

/// `B x` for a row-major 3x3 block.
#[inline]
pub fn block_mul(b: &[f64; 9], x: DVec3) -> DVec3 {
    DVec3::new(
        b[0] * x.x + b[1] * x.y + b[2] * x.z,
        b[3] * x.x + b[4] * x.y + b[5] * x.z,
        b[6] * x.x + b[7] * x.y + b[8] * x.z,
    )
}

/// Per-element data the block gather reads: rotated gradients and forces.
#[derive(Debug, Clone, Copy, Default)]
struct ElementCore {
    rotated_grad: [DVec3; 4],
    force: [DVec3; 4],
}

/// Per-element twist (geometric stiffness) term of [`Tangent::Full`].
#[derive(Debug, Clone, Copy, Default)]
struct ElementTwist {
    twist: [[DVec3; 4]; 3],
    coef: [f64; 3],
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
    /// The reduced right-hand side `r_f = f_ext - f_int(u)` at the free vertices (mN).
    pub rhs: Vec<DVec3>,
    /// For each block slot, its contributions `contrib_ptr[s]..contrib_ptr[s + 1]` in
    /// `contrib`, each `element << 4 | a << 2 | b` (local corners), sorted by element.
    contrib_ptr: Vec<usize>,
    contrib: Vec<u32>,
    /// For each unknown, the incident elements `element << 2 | a`, sorted by element.
    incident_ptr: Vec<usize>,
    incident: Vec<u32>,
    /// Rotated gradients and forces of each element, latest assembly.
    cores: Vec<ElementCore>,
    /// Twist terms of each element for [`Tangent::Full`] (empty otherwise).
    twists: Vec<ElementTwist>,
    /// For each unknown, whether a changeable constraint holds it (eliminated at
    /// assembly).
    eliminated: Vec<bool>,
    /// Per-vertex prescribed displacement of the permanent constraints (mm).
    permanent: Vec<DVec3>,
    /// Per-vertex: held by a permanent constraint.
    permanent_held: Vec<bool>,
    /// Per-vertex: held by a permanent or a changeable constraint.
    held: Vec<bool>,
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
        // per free row: (column, contribution) sorted by column then element
        let rows: Vec<(Vec<u32>, Vec<usize>, Vec<u32>)> = free
            .par_iter()
            .map(|&v| {
                let mut entries: Vec<(u32, u32)> = Vec::new();
                for &ea in &vertex_inc[vertex_ptr[v as usize]..vertex_ptr[v as usize + 1]] {
                    let e = (ea >> 2) as usize;
                    let a = ea & 3;
                    for (b, &w) in tets[e].iter().enumerate() {
                        let col = reduced_of[w as usize];
                        if col != NOT_FREE {
                            entries.push((col, ((e as u32) << 4) | (a << 2) | b as u32));
                        }
                    }
                }
                entries.sort_unstable();
                let mut cols = Vec::new();
                let mut ptr = vec![0usize];
                let mut contrib = Vec::with_capacity(entries.len());
                for (k, &(c, x)) in entries.iter().enumerate() {
                    if k > 0 && entries[k - 1].0 != c {
                        ptr.push(contrib.len());
                    }
                    if k == 0 || entries[k - 1].0 != c {
                        cols.push(c);
                    }
                    contrib.push(x);
                }
                ptr.push(contrib.len());
                (cols, ptr, contrib)
            })
            .collect();
        let mut row_ptr = vec![0usize];
        let mut cols = Vec::new();
        let mut contrib_ptr = vec![0usize];
        let mut contrib = Vec::new();
        for (c, p, x) in rows {
            cols.extend_from_slice(&c);
            row_ptr.push(cols.len());
            let base = contrib.len();
            contrib_ptr.extend(p[1..].iter().map(|k| base + k));
            contrib.extend_from_slice(&x);
        }
        let mut incident_ptr = vec![0usize];
        let mut incident = Vec::new();
        for &v in &free {
            incident
                .extend_from_slice(&vertex_inc[vertex_ptr[v as usize]..vertex_ptr[v as usize + 1]]);
            incident_ptr.push(incident.len());
        }
        let slots = cols.len();
        let permanent_held: Vec<bool> = table.iter().map(Option::is_some).collect();
        let held_count = permanent_held.iter().filter(|&&h| h).count();
        Ok(ReducedSystem {
            reduced_of,
            eliminated: vec![false; free.len()],
            permanent: prescribed.clone(),
            held: permanent_held.clone(),
            permanent_held,
            held_count,
            prescribed,
            rhs: vec![DVec3::ZERO; free.len()],
            free,
            matrix: BlockCsr {
                row_ptr,
                cols,
                values: vec![[0.0; 9]; slots],
            },
            contrib_ptr,
            contrib,
            incident_ptr,
            incident,
            cores: Vec::new(),
            twists: Vec::new(),
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

    /// Internal elastic forces of each element at its four vertices (mN), from the
    /// latest [`ReducedSystem::assemble`].
    pub fn element_forces(&self) -> impl Iterator<Item = &[DVec3; 4]> {
        self.cores.iter().map(|c| &c.force)
    }

    /// Assembles `K'_ff` (with the chosen [`Tangent`]) for the rotations of displacement
    /// `u` (mm, all vertices; it should carry the prescribed values, see
    /// [`ReducedSystem::expand`]) and the right-hand side `r_f = f_ext - f_int(u)` at the
    /// free vertices; unknowns held by changeable constraints get an identity diagonal
    /// block, zero off-diagonal blocks in their row and column, and a zero right-hand
    /// side. `f_ext` (mN, one per
    /// vertex) may be empty for no external force. Parallel: one pass over elements
    /// (rotations, rotated gradients, forces), one pass over block rows gathering each
    /// slot's contributions in a fixed order (so the matrix is exactly symmetric and the
    /// result is deterministic).
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
        let ne = model.element_count();
        let full = formulation == Formulation::Corotated && tangent == Tangent::Full;
        self.cores.resize(ne, ElementCore::default());
        if full {
            self.twists.resize(ne, ElementTwist::default());
            self.cores
                .par_iter_mut()
                .zip(self.twists.par_iter_mut())
                .enumerate()
                .for_each(|(e, (c, t))| {
                    let s = model.element_state(e, u, formulation, tangent);
                    *c = ElementCore {
                        rotated_grad: s.rotated_grad,
                        force: s.force,
                    };
                    *t = ElementTwist {
                        twist: s.twist,
                        coef: s.twist_coef,
                    };
                });
        } else {
            self.twists.clear();
            self.cores.par_iter_mut().enumerate().for_each(|(e, c)| {
                let s = model.element_state(e, u, formulation, tangent);
                *c = ElementCore {
                    rotated_grad: s.rotated_grad,
                    force: s.force,
                };
            });
        }
        let states = &self.cores;
        let twists = &self.twists;
        let elements = model.elements();
        let m = &mut self.matrix;
        let contrib_ptr = &self.contrib_ptr;
        let contrib = &self.contrib;
        // rows are independent: split the value array by rows
        let mut row_values: Vec<&mut [[f64; 9]]> = Vec::with_capacity(m.block_rows());
        let mut rest: &mut [[f64; 9]] = &mut m.values;
        for i in 0..m.row_ptr.len() - 1 {
            let (head, tail) = rest.split_at_mut(m.row_ptr[i + 1] - m.row_ptr[i]);
            row_values.push(head);
            rest = tail;
        }
        let row_ptr = &m.row_ptr;
        let cols = &m.cols;
        let eliminated = &self.eliminated;
        row_values
            .into_par_iter()
            .enumerate()
            .for_each(|(i, vals)| {
                if eliminated[i] {
                    // a held unknown: identity diagonal block, zero row
                    for (k, out) in vals.iter_mut().enumerate() {
                        *out = if cols[row_ptr[i] + k] as usize == i {
                            [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
                        } else {
                            [0.0; 9]
                        };
                    }
                    return;
                }
                for (k, out) in vals.iter_mut().enumerate() {
                    let s = row_ptr[i] + k;
                    let mut b = [0.0; 9];
                    if eliminated[cols[s] as usize] {
                        // a held unknown's column: eliminated
                        *out = b;
                        continue;
                    }
                    for &c in &contrib[contrib_ptr[s]..contrib_ptr[s + 1]] {
                        let e = (c >> 4) as usize;
                        let a = ((c >> 2) & 3) as usize;
                        let bb = (c & 3) as usize;
                        let h = &states[e].rotated_grad;
                        let (ha, hb) = (h[a], h[bb]);
                        let vm = elements[e].vol_mu;
                        let d = vm * ha.dot(hb);
                        // V λ hₐ h_bᵀ + V μ h_b hₐᵀ from the nine products hₐ[p] h_b[q],
                        // rounded alike for the blocks (a, b) and (b, a): the matrix
                        // stays exactly symmetric
                        let vl = elements[e].vol_lambda;
                        let ha = ha.to_array();
                        let hb = hb.to_array();
                        let mut prod = [0.0; 9];
                        for p in 0..3 {
                            for q in 0..3 {
                                prod[3 * p + q] = ha[p] * hb[q];
                            }
                        }
                        for p in 0..3 {
                            for q in 0..3 {
                                b[3 * p + q] += vl * prod[3 * p + q] + vm * prod[3 * q + p];
                            }
                        }
                        b[0] += d;
                        b[4] += d;
                        b[8] += d;
                        if !full {
                            continue;
                        }
                        let st = &twists[e];
                        for m in 0..3 {
                            let c = st.coef[m];
                            if c != 0.0 {
                                let ta = st.twist[m][a].to_array();
                                let tb = st.twist[m][bb].to_array();
                                for p in 0..3 {
                                    for q in 0..3 {
                                        b[3 * p + q] += c * (ta[p] * tb[q]);
                                    }
                                }
                            }
                        }
                    }
                    *out = b;
                }
            });
        let incident_ptr = &self.incident_ptr;
        let incident = &self.incident;
        let free = &self.free;
        let eliminated = &self.eliminated;
        self.rhs.par_iter_mut().enumerate().for_each(|(k, r)| {
            if eliminated[k] {
                *r = DVec3::ZERO;
                return;
            }
            let mut f = if f_ext.is_empty() {
                DVec3::ZERO
            } else {
                f_ext[free[k] as usize]
            };
            for &ea in &incident[incident_ptr[k]..incident_ptr[k + 1]] {
                f -= states[(ea >> 2) as usize].force[(ea & 3) as usize];
            }
            *r = f;
        });
        Ok(())
    }
}
