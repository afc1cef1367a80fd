//! The finite element model: linear tetrahedra with per-element isotropic Hooke
//! material, rest-state shape function gradients, consistent loads, and the corotated
//! element kinematics (rotation, stress, elastic force).
//!
//! Units: positions and displacements in mm, Young's modulus in kPa = mN/mm², so stresses
//! are in kPa and forces in mN; density in kg/m³ and gravity in m/s², converted with
//! 1 kg/m³ · 1 m/s² = 1e-6 mN/mm³.

use crate::eigen3::symmetric_eigen_closed_form;
use crate::error::FemError;
use crate::material::Material;
use crate::membrane::{Membrane, MembraneRest, MembraneState};
use crate::polar::{POLAR_LANES, polar_rotation, polar_rotations};
use crate::slider::Sliders;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use tetmesh::TetMesh;

/// Conversion of density (kg/m³) times acceleration (m/s²) to a force density (mN/mm³).
pub const KG_M3_TIMES_M_S2_TO_MN_MM3: f64 = 1e-6;

/// Strain formulation.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Formulation {
    /// Small-strain (Cauchy) linear elasticity: `R = I` in every element.
    Linear,
    /// Corotated linear elasticity: the element rotation `R` of the polar decomposition
    /// of the deformation gradient is removed before the linear strain is measured.
    #[default]
    Corotated,
}

/// Which tangent stiffness the corotated formulation assembles.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Tangent {
    /// `R K Rᵀ` only ("stiffness warping", the paper's and the multigrid's matrix; with
    /// membranes, their tension across the sheet too, see [`crate::membrane`]): the
    /// derivative of the rotation is neglected. The fixed-point iteration built on it
    /// converges linearly, and diverges in the bending modes of slender parts under a
    /// large tension (the missing geometric stiffness).
    Warped,
    /// `R K Rᵀ` plus the rotation-derivative (geometric) term of the corotated energy,
    /// clamped to stay positive semi-definite: in the principal frame of `S = RᵀF`, the
    /// twist mode of the axes `i, j` gets the stiffness `2 max(σᵢ + σⱼ, 0) / max(sᵢ + sⱼ,
    /// 0.1)` (σ principal stresses, s signed singular values). Exact Newton tangent in
    /// tension for the tetrahedra (membranes lack the term of their in-plane turn), so
    /// Newton converges quadratically there; in compression the negative
    /// part is dropped (a positive definite approximation, as in Teran et al. 2005).
    #[default]
    Full,
}

/// A safeguard against inverted elements added to the corotated energy (beyond the
/// paper): below the volume ratio `J_min`, an element gains the energy
/// `κ V (J_min - J)²` (`J = det F`, `V` its rest volume). Corotated linear elasticity
/// alone resists a collapse to zero volume only with a bounded force (its strain of an
/// inverted element is measured from the reflected rest shape), so tissue squeezed hard
/// over an implant can pass through `J = 0`; the barrier's force `2κV (J_min - J) ∂J/∂x`
/// grows until it stops that. Elements above `J_min` are untouched, and so is the
/// [`Formulation::Linear`]. The assembled stiffness gains the positive Gauss-Newton term
/// `2κV (∂J/∂xₐ)(∂J/∂x_b)ᵀ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InversionBarrier {
    /// Volume ratio `J_min` below which the barrier acts, in (0, 1).
    pub min_volume_ratio: f64,
    /// Its modulus `κ` (kPa), positive: the least of every element's.
    pub modulus_kpa: f64,
    /// An element's `κ` is at least this multiple of its own Young's modulus
    /// (non-negative), so that stiff elements are held as firmly relative to what pushes
    /// them.
    pub young_multiple: f64,
}

/// Resistance to large volume loss added to the corotated energy (beyond the paper):
/// below the volume ratio `J₀` an element gains the energy `m λ V (J₀ - J)²` (`λ` its
/// first Lamé parameter, `V` its rest volume). The corotated energy measures volume
/// change by `tr(RᵀF) - 3`, which is first-order exact but blind to large anisotropic
/// compression: an element squeezed to principal stretches 0.42, 1.15 and 1.34 has lost
/// 35% of its volume while `tr(S) - 3 = -0.09`, so soft tissue pressed over an implant
/// loses volume no real tissue loses. With `m = ½` and `J₀ = 1` the term would be the
/// volumetric energy of the fixed-corotated model (Stomakhin et al. 2012); an onset
/// below one keeps small strains exactly linear-elastic. Like the
/// [`InversionBarrier`], it acts on the [`Formulation::Corotated`] only, and the
/// stiffness gains its Gauss-Newton term `2 m λ V (∂J/∂xₐ)(∂J/∂x_b)ᵀ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompressionPenalty {
    /// Volume ratio `J₀` below which the penalty acts, in (0, 1].
    pub onset_volume_ratio: f64,
    /// Its modulus as a multiple `m` of the element's first Lamé parameter, positive.
    pub lambda_multiple: f64,
}

/// The volume terms (barrier and compression penalty) of one element where they act:
/// energy `Ψ`, its derivative `-dΨ/dJ` and second derivative `d²Ψ/dJ²` in the volume
/// ratio (mN·mm).
struct VolumeTerms {
    energy: f64,
    force_coef: f64,
    stiffness: f64,
}

impl VolumeTerms {
    /// Adds `k V (onset - J)²`, `k V` given as `modulus_volume`, where `J < onset`.
    fn add(&mut self, onset: f64, volume_ratio: f64, modulus_volume: f64) {
        let gap = onset - volume_ratio;
        if gap > 0.0 {
            self.energy += modulus_volume * gap * gap;
            self.force_coef += 2.0 * modulus_volume * gap;
            self.stiffness += 2.0 * modulus_volume;
        }
    }
}

/// Rest-state data of one linear tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementRest {
    /// Gradients of the four barycentric shape functions (1/mm); they sum to zero.
    pub grad: [DVec3; 4],
    /// Rest volume (mm³), positive.
    pub volume_mm3: f64,
    /// Volume times the first Lamé parameter (mN·mm).
    pub vol_lambda: f64,
    /// Volume times the shear modulus (mN·mm).
    pub vol_mu: f64,
}

/// What the assembly reads of one element in its current state.
pub(crate) struct WarpedElement {
    /// `R gᵢ`: the rest gradients rotated into the current frame. The rotated element
    /// stiffness block is `K'ᵢⱼ = V (λ hᵢ hⱼᵀ + μ hⱼ hᵢᵀ + μ (hᵢ·hⱼ) I)`.
    pub(crate) rotated_grad: [DVec3; 4],
    /// Internal elastic force `R K (Rᵀ x - X)` at the four vertices (mN), with the
    /// volume terms' ([`InversionBarrier`], [`CompressionPenalty`]); the force the
    /// element exerts on a vertex is its negative.
    pub(crate) force: [DVec3; 4],
    /// `d²Ψ/dJ²` of the volume terms where they act on the element (mN·mm; `2κV` for
    /// the barrier), else zero: the block `(a, b)` gains `barrier_stiffness · bₐ b_bᵀ`
    /// with `b = FemModel::volume_gradients`.
    pub(crate) barrier_stiffness: f64,
}

/// A tetrahedral finite element model in its rest state.
#[derive(Debug, Clone)]
pub struct FemModel {
    rest: Vec<DVec3>,
    tets: Vec<[u32; 4]>,
    materials: Vec<Material>,
    elements: Vec<ElementRest>,
    barrier: Option<InversionBarrier>,
    compression: Option<CompressionPenalty>,
    /// Membranes ([`crate::membrane`]) sorted by element, and for each element the start
    /// of its own in that list (`ne + 1` entries; empty when there are none).
    membranes: Vec<MembraneRest>,
    membrane_ptr: Vec<u32>,
    pub(crate) sliders: Sliders,
    /// Per element, `Σᵢ (Xᵢ - X₀) ⊗ gᵢ - I` of an element given a rest shape of its own
    /// ([`FemModel::set_rest_shape`]; `X` the mesh's rest positions, `gᵢ` the rest
    /// shape's gradients): added to every displacement gradient, so `I + ∇u` is the
    /// deformation from the element's own rest shape. Empty while no element has one.
    rest_offset: Vec<DMat3>,
}

/// Rest data of one tetrahedron; `Err` with its signed volume if it is not positive.
fn element_rest(p: [DVec3; 4], material: &Material) -> Result<ElementRest, f64> {
    let dm = DMat3::from_cols(p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = dm.determinant();
    let volume = det / 6.0;
    // relative test: a sliver far below rounding is as bad as an inverted element
    let scale = (p[1] - p[0])
        .length()
        .max((p[2] - p[0]).length())
        .max((p[3] - p[0]).length());
    if !(volume.is_finite() && det > 1e-14 * scale * scale * scale) {
        return Err(volume);
    }
    let inv = dm.inverse();
    let g1 = inv.row(0);
    let g2 = inv.row(1);
    let g3 = inv.row(2);
    let g0 = -(g1 + g2 + g3);
    let (lambda, mu) = material.lame();
    Ok(ElementRest {
        grad: [g0, g1, g2, g3],
        volume_mm3: volume,
        vol_lambda: volume * lambda,
        vol_mu: volume * mu,
    })
}

impl FemModel {
    /// A model over `mesh` with one material per tetrahedron.
    ///
    /// Errors: non-finite vertices, bad indices, a material out of range, an inverted or
    /// flat rest element (each naming the first bad vertex or element).
    pub fn new(mesh: &TetMesh, materials: Vec<Material>) -> Result<FemModel, FemError> {
        if materials.len() != mesh.tets.len() {
            return Err(FemError::LengthMismatch {
                what: "materials (one per tetrahedron)",
                expected: mesh.tets.len(),
                got: materials.len(),
            });
        }
        if let Some((vertex, p)) = mesh
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(FemError::NonFiniteVertex {
                vertex,
                position: p.to_array(),
            });
        }
        let n = mesh.positions.len();
        for (element, t) in mesh.tets.iter().enumerate() {
            if t.iter().any(|&v| v as usize >= n) {
                return Err(FemError::BadElement {
                    element,
                    vertices: *t,
                    reason: "vertex index out of range",
                });
            }
            if (0..4).any(|a| (a + 1..4).any(|b| t[a] == t[b])) {
                return Err(FemError::BadElement {
                    element,
                    vertices: *t,
                    reason: "repeated vertex",
                });
            }
        }
        for (element, m) in materials.iter().enumerate() {
            m.check()
                .map_err(|what| FemError::BadMaterial { element, what })?;
        }
        let elements: Vec<Result<ElementRest, f64>> = mesh
            .tets
            .par_iter()
            .zip(materials.par_iter())
            .map(|(t, m)| element_rest(t.map(|v| mesh.positions[v as usize]), m))
            .collect();
        let mut rest_elements = Vec::with_capacity(elements.len());
        for (element, e) in elements.into_iter().enumerate() {
            match e {
                Ok(e) => rest_elements.push(e),
                Err(volume_mm3) => {
                    return Err(FemError::InvertedElement {
                        element,
                        volume_mm3,
                    });
                }
            }
        }
        Ok(FemModel {
            rest: mesh.positions.clone(),
            tets: mesh.tets.clone(),
            materials,
            elements: rest_elements,
            barrier: None,
            compression: None,
            membranes: Vec::new(),
            membrane_ptr: Vec::new(),
            sliders: Sliders::default(),
            rest_offset: Vec::new(),
        })
    }

    /// A model with the same material in every tetrahedron.
    pub fn homogeneous(mesh: &TetMesh, material: Material) -> Result<FemModel, FemError> {
        FemModel::new(mesh, vec![material; mesh.tets.len()])
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.rest.len()
    }

    /// Number of tetrahedra.
    pub fn element_count(&self) -> usize {
        self.tets.len()
    }

    /// Rest positions (mm).
    pub fn rest_positions(&self) -> &[DVec3] {
        &self.rest
    }

    /// Tetrahedra.
    pub fn tets(&self) -> &[[u32; 4]] {
        &self.tets
    }

    /// Materials, one per tetrahedron.
    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    /// Rest data, one per tetrahedron.
    pub fn elements(&self) -> &[ElementRest] {
        &self.elements
    }

    /// Replaces the material of one element (e.g. softening implant elements); the rest
    /// geometry is kept.
    pub fn set_material(&mut self, element: usize, material: Material) -> Result<(), FemError> {
        material
            .check()
            .map_err(|what| FemError::BadMaterial { element, what })?;
        let (lambda, mu) = material.lame();
        let e = &mut self.elements[element];
        e.vol_lambda = e.volume_mm3 * lambda;
        e.vol_mu = e.volume_mm3 * mu;
        self.materials[element] = material;
        Ok(())
    }

    /// Gives element `e` a rest shape of its own, the tetrahedron `corners` (mm; e.g. an
    /// inflated implant, stress-free only once its vertices reach those corners), with
    /// its material kept. Its rest volume, mass and stiffness become the shape's; a
    /// membrane on one of its faces keeps the mesh's rest shape.
    ///
    /// Errors: an element out of range, an inverted or flat shape (the model is left
    /// unchanged).
    pub fn set_rest_shape(&mut self, e: usize, corners: [DVec3; 4]) -> Result<(), FemError> {
        let t = self.element_vertices(e)?;
        let rest = element_rest(corners, &self.materials[e]).map_err(|volume_mm3| {
            FemError::InvertedElement {
                element: e,
                volume_mm3,
            }
        })?;
        let x = t.map(|v| self.rest[v as usize]);
        let offset = outer(x[1] - x[0], rest.grad[1])
            + outer(x[2] - x[0], rest.grad[2])
            + outer(x[3] - x[0], rest.grad[3])
            - DMat3::IDENTITY;
        if self.rest_offset.is_empty() {
            self.rest_offset = vec![DMat3::ZERO; self.tets.len()];
        }
        self.rest_offset[e] = offset;
        self.elements[e] = rest;
        Ok(())
    }

    /// The vertices of element `e`; an error where there is no such element.
    fn element_vertices(&self, e: usize) -> Result<[u32; 4], FemError> {
        self.tets.get(e).copied().ok_or(FemError::BadElement {
            element: e,
            vertices: [0; 4],
            reason: "element index out of range",
        })
    }

    /// Gives element `e` back the mesh's rest shape (see [`FemModel::set_rest_shape`]).
    ///
    /// Errors: an element out of range.
    pub fn reset_rest_shape(&mut self, e: usize) -> Result<(), FemError> {
        let t = self.element_vertices(e)?;
        if let Some(offset) = self.rest_offset.get_mut(e) {
            *offset = DMat3::ZERO;
        }
        let corners = t.map(|v| self.rest[v as usize]);
        self.elements[e] = element_rest(corners, &self.materials[e]).map_err(|volume_mm3| {
            FemError::InvertedElement {
                element: e,
                volume_mm3,
            }
        })?;
        Ok(())
    }

    /// Replaces the model's membranes ([`crate::membrane`]; none by default), each on a
    /// face of its tetrahedron.
    ///
    /// Errors: an element out of range, a face that is not one of its element's, a
    /// degenerate face, a material or thickness out of range (the model is left
    /// unchanged).
    pub fn set_membranes(&mut self, membranes: &[Membrane]) -> Result<(), FemError> {
        let mut sorted = membranes.to_vec();
        sorted.sort_by_key(|m| m.element);
        let ne = self.tets.len();
        let mut rest = Vec::with_capacity(sorted.len());
        let mut ptr = vec![0u32; ne + 1];
        for m in &sorted {
            let tet = *self
                .tets
                .get(m.element as usize)
                .ok_or(FemError::LengthMismatch {
                    what: "membrane's element (an index into the tetrahedra)",
                    expected: ne,
                    got: m.element as usize,
                })?;
            rest.push(MembraneRest::new(m, tet, &self.rest)?);
            ptr[m.element as usize + 1] += 1;
        }
        for e in 0..ne {
            ptr[e + 1] += ptr[e];
        }
        self.membrane_ptr = if rest.is_empty() { Vec::new() } else { ptr };
        self.membranes = rest;
        Ok(())
    }

    /// Number of membranes.
    pub fn membrane_count(&self) -> usize {
        self.membranes.len()
    }

    /// The indices of element `e`'s membranes in [`FemModel::membrane_states`].
    #[inline]
    pub(crate) fn membranes_of(&self, e: usize) -> std::ops::Range<usize> {
        if self.membrane_ptr.is_empty() {
            return 0..0;
        }
        self.membrane_ptr[e] as usize..self.membrane_ptr[e + 1] as usize
    }

    /// The tetrahedron corner of each face corner of membrane `m`.
    #[inline]
    pub(crate) fn membrane_corners(&self, m: usize) -> [u8; 3] {
        self.membranes[m].corners
    }

    /// Every membrane's state for displacement `u`, in the order of
    /// [`FemModel::membranes_of`].
    pub(crate) fn membrane_states(
        &self,
        u: &[DVec3],
        formulation: Formulation,
    ) -> Vec<MembraneState> {
        if self.membranes.is_empty() {
            return Vec::new();
        }
        (0..self.tets.len())
            .into_par_iter()
            .flat_map_iter(|e| {
                let tet = self.tets[e];
                self.membranes_of(e).map(move |m| {
                    let rest = &self.membranes[m];
                    let x = rest.corners.map(|c| {
                        let v = tet[c as usize] as usize;
                        self.rest[v] + u[v]
                    });
                    rest.state(x, formulation)
                })
            })
            .collect()
    }

    /// Calls `add(corner, force)` for each face corner of element `e`'s membranes with
    /// its force in `states` (from [`FemModel::membrane_states`]).
    #[inline]
    pub(crate) fn membrane_corner_forces(
        &self,
        e: usize,
        states: &[MembraneState],
        mut add: impl FnMut(usize, DVec3),
    ) {
        for m in self.membranes_of(e) {
            for (i, &c) in self.membranes[m].corners.iter().enumerate() {
                add(c as usize, states[m].force[i]);
            }
        }
    }

    /// Sets (or, with `None`, removes) the [`InversionBarrier`] of every element; none by
    /// default (the paper's corotated energy).
    ///
    /// Errors: a volume ratio outside (0, 1) or a modulus that is not positive and finite.
    pub fn set_inversion_barrier(
        &mut self,
        barrier: Option<InversionBarrier>,
    ) -> Result<(), FemError> {
        if let Some(b) = barrier
            && !(b.min_volume_ratio > 0.0
                && b.min_volume_ratio < 1.0
                && b.modulus_kpa > 0.0
                && b.modulus_kpa.is_finite()
                && b.young_multiple >= 0.0
                && b.young_multiple.is_finite())
        {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "inversion barrier: volume ratio {} must lie in (0, 1), modulus {} kPa \
                     be positive and the multiple {} of Young's modulus not negative",
                    b.min_volume_ratio, b.modulus_kpa, b.young_multiple
                ),
            });
        }
        self.barrier = barrier;
        Ok(())
    }

    /// The model's [`InversionBarrier`], if any.
    pub fn inversion_barrier(&self) -> Option<InversionBarrier> {
        self.barrier
    }

    /// Sets (or, with `None`, removes) the [`CompressionPenalty`] of every element; none by
    /// default (the paper's corotated energy).
    ///
    /// Errors: an onset outside (0, 1] or a multiple that is not positive and finite.
    pub fn set_compression_penalty(
        &mut self,
        penalty: Option<CompressionPenalty>,
    ) -> Result<(), FemError> {
        if let Some(p) = penalty
            && !(p.onset_volume_ratio > 0.0
                && p.onset_volume_ratio <= 1.0
                && p.lambda_multiple > 0.0
                && p.lambda_multiple.is_finite())
        {
            return Err(FemError::InvalidOptions {
                what: format!(
                    "compression penalty: onset volume ratio {} must lie in (0, 1] and the \
                     multiple {} of the first Lamé parameter be positive",
                    p.onset_volume_ratio, p.lambda_multiple
                ),
            });
        }
        self.compression = penalty;
        Ok(())
    }

    /// The model's [`CompressionPenalty`], if any.
    pub fn compression_penalty(&self) -> Option<CompressionPenalty> {
        self.compression
    }

    /// `∂J/∂xᵢ = cof(F) gᵢ` for the four vertices of element `e` at displacement `u`
    /// (mm²; `J = det F` its volume ratio): the directions of the [`InversionBarrier`].
    pub fn volume_gradients(&self, e: usize, u: &[DVec3]) -> [DVec3; 4] {
        let cof = cofactor_matrix(DMat3::IDENTITY + self.displacement_gradient(e, u));
        self.elements[e].grad.map(|g| cof * g)
    }

    /// The volume terms ([`InversionBarrier`], [`CompressionPenalty`]) of element `e`
    /// with displacement gradient `du`, when one acts (the corotated formulation only:
    /// the small-strain one knows nothing of large volume changes).
    #[inline]
    fn volume_terms(&self, e: usize, formulation: Formulation, du: DMat3) -> Option<VolumeTerms> {
        if formulation == Formulation::Linear
            || (self.barrier.is_none() && self.compression.is_none())
        {
            return None;
        }
        let volume_ratio = (DMat3::IDENTITY + du).determinant();
        let element = &self.elements[e];
        let mut terms = VolumeTerms {
            energy: 0.0,
            force_coef: 0.0,
            stiffness: 0.0,
        };
        if let Some(b) = self.barrier {
            let modulus = b
                .modulus_kpa
                .max(b.young_multiple * self.materials[e].young_kpa);
            terms.add(
                b.min_volume_ratio,
                volume_ratio,
                modulus * element.volume_mm3,
            );
        }
        if let Some(c) = self.compression {
            terms.add(
                c.onset_volume_ratio,
                volume_ratio,
                c.lambda_multiple * element.vol_lambda,
            );
        }
        (terms.stiffness > 0.0).then_some(terms)
    }

    /// Consistent nodal gravity forces (mN) for the acceleration `gravity_m_s2` (m/s²,
    /// e.g. `(0, -9.80665, 0)`): each element adds `ρ g V / 4` to each of its vertices
    /// (exact for a constant body force on linear elements), over the rest volume.
    pub fn gravity_forces(&self, gravity_m_s2: DVec3) -> Result<Vec<DVec3>, FemError> {
        if !gravity_m_s2.is_finite() {
            return Err(FemError::NonFiniteInput {
                what: "gravity",
                vertex: 0,
                value: gravity_m_s2.to_array(),
            });
        }
        let mut f = vec![DVec3::ZERO; self.rest.len()];
        for ((t, e), m) in self.tets.iter().zip(&self.elements).zip(&self.materials) {
            let fe =
                gravity_m_s2 * (m.density_kg_m3 * e.volume_mm3 * 0.25 * KG_M3_TIMES_M_S2_TO_MN_MM3);
            for &v in t {
                f[v as usize] += fe;
            }
        }
        Ok(f)
    }

    /// Checks that `u` has one finite entry per vertex.
    pub(crate) fn check_vertex_field(
        &self,
        what: &'static str,
        u: &[DVec3],
    ) -> Result<(), FemError> {
        if u.len() != self.rest.len() {
            return Err(FemError::LengthMismatch {
                what,
                expected: self.rest.len(),
                got: u.len(),
            });
        }
        if let Some((vertex, p)) = u.iter().enumerate().find(|(_, p)| !p.is_finite()) {
            return Err(FemError::NonFiniteInput {
                what,
                vertex,
                value: p.to_array(),
            });
        }
        Ok(())
    }

    /// The displacement gradient `∇u = Σᵢ (uᵢ - u₀) ⊗ gᵢ` of element `e`.
    #[inline]
    fn displacement_gradient(&self, e: usize, u: &[DVec3]) -> DMat3 {
        let t = self.tets[e];
        let g = &self.elements[e].grad;
        let u0 = u[t[0] as usize];
        let d1 = u[t[1] as usize] - u0;
        let d2 = u[t[2] as usize] - u0;
        let d3 = u[t[3] as usize] - u0;
        let du = outer(d1, g[1]) + outer(d2, g[2]) + outer(d3, g[3]);
        match self.rest_offset.get(e) {
            Some(offset) => du + *offset,
            None => du,
        }
    }

    /// The rotation of element `e` for displacement `u`.
    #[inline]
    pub fn element_rotation(&self, e: usize, u: &[DVec3], formulation: Formulation) -> DMat3 {
        match formulation {
            Formulation::Linear => DMat3::IDENTITY,
            Formulation::Corotated => {
                polar_rotation(DMat3::IDENTITY + self.displacement_gradient(e, u))
            }
        }
    }

    /// The unrotated (corotated-frame) stress of element `e` (kPa):
    /// `σ = λ tr(ε) I + 2μ ε` with `ε = sym(Rᵀ F - I)`; in the current frame the stress is
    /// `R σ Rᵀ`. Also returns `R`.
    pub fn element_stress(
        &self,
        e: usize,
        u: &[DVec3],
        formulation: Formulation,
    ) -> (DMat3, DMat3) {
        let du = self.displacement_gradient(e, u);
        let (r, g) = match formulation {
            Formulation::Linear => (DMat3::IDENTITY, du),
            Formulation::Corotated => {
                let r = polar_rotation(DMat3::IDENTITY + du);
                // Rᵀ(I + ∇u) - I = (Rᵀ - I) + Rᵀ ∇u, accurate for small ∇u
                (r, (r.transpose() - DMat3::IDENTITY) + r.transpose() * du)
            }
        };
        let el = &self.elements[e];
        let v = el.volume_mm3;
        let eps = (g + g.transpose()) * 0.5;
        let tr = eps.x_axis.x + eps.y_axis.y + eps.z_axis.z;
        let sigma = DMat3::from_diagonal(DVec3::splat(el.vol_lambda / v * tr))
            + eps * (2.0 * el.vol_mu / v);
        (sigma, r)
    }

    /// Displacement gradients and rotations of the elements `first..` (at most
    /// [`POLAR_LANES`], fewer at the end of the mesh; the rest of the arrays is unused),
    /// the rotations computed together by [`polar_rotations`].
    #[inline]
    fn chunk_rotations(
        &self,
        first: usize,
        u: &[DVec3],
        formulation: Formulation,
    ) -> (usize, [DMat3; POLAR_LANES], [DMat3; POLAR_LANES]) {
        let count = POLAR_LANES.min(self.tets.len() - first);
        let du: [DMat3; POLAR_LANES] = std::array::from_fn(|l| {
            if l < count {
                self.displacement_gradient(first + l, u)
            } else {
                DMat3::ZERO
            }
        });
        let r = match formulation {
            Formulation::Linear => [DMat3::IDENTITY; POLAR_LANES],
            Formulation::Corotated => polar_rotations(&du.map(|d| DMat3::IDENTITY + d)),
        };
        (count, du, r)
    }

    /// The rotated gradients `R gᵢ` and internal forces `V R σ gᵢ` (mN) of the elements
    /// `first..` (at most [`POLAR_LANES`]) for the [`Tangent::Warped`] rotations of
    /// displacement `u`, handed to `emit(lane, element)`.
    #[inline]
    pub(crate) fn elements_warped(
        &self,
        first: usize,
        u: &[DVec3],
        formulation: Formulation,
        mut emit: impl FnMut(usize, WarpedElement),
    ) {
        let (count, du, r) = self.chunk_rotations(first, u, formulation);
        for l in 0..count {
            emit(l, self.rotated_forces(first + l, formulation, r[l], du[l]));
        }
    }

    /// [`FemModel::elements_warped`] with each element's twist stiffness of
    /// [`Tangent::Full`] ([`FemModel::twist_stiffness`]); corotated.
    pub(crate) fn elements_full(
        &self,
        first: usize,
        u: &[DVec3],
        mut emit: impl FnMut(usize, WarpedElement, DMat3),
    ) {
        let (count, du, r) = self.chunk_rotations(first, u, Formulation::Corotated);
        for l in 0..count {
            let e = first + l;
            let warped = self.rotated_forces(e, Formulation::Corotated, r[l], du[l]);
            emit(l, warped, self.twist_stiffness(e, r[l], du[l]));
        }
    }

    /// The geometric (twist) term of [`Tangent::Full`] for element `e` at rotation `r`
    /// and displacement gradient `du`, as the symmetric `C` (mN·mm) with which the block
    /// `(a, b)` gains `[hₐ]ₓ C [h_b]ₓᵀ` (`h = R g` the rotated gradients, `[h]ₓ` the
    /// cross-product matrix).
    ///
    /// With the principal stretches `sₖ` and axes `vₖ` of `S = Rᵀ(I + ∇u)` (symmetric for
    /// the polar `R`) and `uₖ = R vₖ`, the positive part of the geometric stiffness is
    /// `Σ cᵢⱼ tᵢⱼ,ₐ tᵢⱼ,_bᵀ` over the axis pairs with `cᵢⱼ = 2 max(σ̂ᵢ + σ̂ⱼ, 0) / (sᵢ + sⱼ)`
    /// (`σ̂` the principal stresses times the volume) and
    /// `tᵢⱼ,ₐ = ½ (uᵢ (gₐ·vⱼ) - uⱼ (gₐ·vᵢ)) = ±½ hₐ × uₖ` (`k` the third axis), so
    /// `C = ¼ Σₖ cᵢⱼ uₖ uₖᵀ`: one symmetric 3x3 per element instead of twelve vectors. Zero
    /// without the eigendecomposition where an upper bound of every pair's stress sum
    /// (Gershgorin's on the largest principal strain) is not positive: compressed
    /// elements cost no more than in the warped assembly. Where no clamp acts, without
    /// it too ([`unclamped_twist`]).
    #[inline]
    fn twist_stiffness(&self, e: usize, r: DMat3, du: DMat3) -> DMat3 {
        let el = &self.elements[e];
        let strain = corotated_strain(r, du);
        let a = strain.to_cols_array_2d();
        let trace = a[0][0] + a[1][1] + a[2][2];
        let largest_strain_bound = (0..3)
            .map(|i| {
                a[i][i]
                    + (0..3)
                        .filter(|&j| j != i)
                        .map(|j| a[i][j].abs())
                        .sum::<f64>()
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if 4.0 * el.vol_mu * largest_strain_bound + 2.0 * el.vol_lambda * trace <= 0.0 {
            return DMat3::ZERO;
        }
        if let Some(c) = unclamped_twist(el.vol_lambda, el.vol_mu, r, strain, trace) {
            return c;
        }
        let (principal_strains, v) = symmetric_eigen_closed_form(strain);
        let s = principal_strains.map(|e| 1.0 + e);
        let trs = s[0] + s[1] + s[2] - 3.0;
        let vsig = s.map(|si| 2.0 * el.vol_mu * (si - 1.0) + el.vol_lambda * trs);
        let axes = r * v;
        let mut c = DMat3::ZERO;
        for (i, j, k) in [(0usize, 1usize, 2usize), (0, 2, 1), (1, 2, 0)] {
            let coef = 2.0 * (vsig[i] + vsig[j]).max(0.0) / (s[i] + s[j]).max(MIN_PAIR_STRETCH);
            if coef > 0.0 {
                let uk = axes.col(k);
                c += outer(uk, uk) * (0.25 * coef);
            }
        }
        c
    }

    /// Rotated gradients and forces of element `e` for rotation `r` and displacement
    /// gradient `du` (with the [`InversionBarrier`]'s force where it acts); the corner 0
    /// terms are minus the sum of the others (the gradients sum to zero).
    #[inline]
    fn rotated_forces(
        &self,
        e: usize,
        formulation: Formulation,
        r: DMat3,
        du: DMat3,
    ) -> WarpedElement {
        let el = &self.elements[e];
        let g = match formulation {
            Formulation::Linear => du,
            // Rᵀ(I + ∇u) - I = (Rᵀ - I) + Rᵀ ∇u, accurate for small ∇u
            Formulation::Corotated => (r.transpose() - DMat3::IDENTITY) + r.transpose() * du,
        };
        let eps = (g + g.transpose()) * 0.5;
        let tr = eps.x_axis.x + eps.y_axis.y + eps.z_axis.z;
        // volume times stress
        let vsigma =
            DMat3::from_diagonal(DVec3::splat(el.vol_lambda * tr)) + eps * (2.0 * el.vol_mu);
        let mut rs = r * vsigma;
        let mut barrier_stiffness = 0.0;
        if let Some(terms) = self.volume_terms(e, formulation, du) {
            // f += (dΨ/dJ) cof(F) g
            rs -= cofactor_matrix(DMat3::IDENTITY + du) * terms.force_coef;
            barrier_stiffness = terms.stiffness;
        }
        let [_, g1, g2, g3] = el.grad;
        let (h1, h2, h3) = (r * g1, r * g2, r * g3);
        let (f1, f2, f3) = (rs * g1, rs * g2, rs * g3);
        WarpedElement {
            rotated_grad: [-(h1 + h2 + h3), h1, h2, h3],
            force: [-(f1 + f2 + f3), f1, f2, f3],
            barrier_stiffness,
        }
    }

    /// Elastic energy of element `e` (mN·mm = µJ): `V (μ ‖ε‖² + λ/2 tr(ε)²)` with the
    /// strain of [`FemModel::element_stress`], plus the [`InversionBarrier`]'s and those of
    /// the element's membranes ([`crate::membrane`]). For the corotated formulation this is
    /// `V (μ ‖F - R‖² + λ/2 tr(RᵀF - I)²)`, whose gradient is exactly the element force
    /// (the derivative of the polar rotation drops out), so the forces are conservative.
    pub fn element_energy(&self, e: usize, u: &[DVec3], formulation: Formulation) -> f64 {
        let du = self.displacement_gradient(e, u);
        let r = match formulation {
            Formulation::Linear => DMat3::IDENTITY,
            Formulation::Corotated => polar_rotation(DMat3::IDENTITY + du),
        };
        let tet = self.tets[e];
        let membranes: f64 = self
            .membranes_of(e)
            .map(|m| {
                let rest = &self.membranes[m];
                let x = rest.corners.map(|c| {
                    let v = tet[c as usize] as usize;
                    self.rest[v] + u[v]
                });
                rest.state(x, formulation).energy
            })
            .sum();
        self.energy_of(e, formulation, r, du) + membranes
    }

    /// [`FemModel::element_energy`] for rotation `r` and displacement gradient `du`.
    #[inline]
    fn energy_of(&self, e: usize, formulation: Formulation, r: DMat3, du: DMat3) -> f64 {
        let g = match formulation {
            Formulation::Linear => du,
            Formulation::Corotated => (r.transpose() - DMat3::IDENTITY) + r.transpose() * du,
        };
        let el = &self.elements[e];
        let eps = (g + g.transpose()) * 0.5;
        let tr = eps.x_axis.x + eps.y_axis.y + eps.z_axis.z;
        let norm2 =
            eps.x_axis.length_squared() + eps.y_axis.length_squared() + eps.z_axis.length_squared();
        let barrier = self
            .volume_terms(e, formulation, du)
            .map_or(0.0, |terms| terms.energy);
        el.vol_mu * norm2 + 0.5 * el.vol_lambda * tr * tr + barrier
    }

    /// Total potential energy `Σₑ Ψₑ(u) - f_ext · u` (mN·mm), the membranes' and
    /// sliders' included;
    /// `f_ext` may be empty.
    pub fn potential_energy(&self, u: &[DVec3], f_ext: &[DVec3], formulation: Formulation) -> f64 {
        let elastic: f64 = (0..self.tets.len().div_ceil(POLAR_LANES))
            .into_par_iter()
            .map(|k| {
                let first = k * POLAR_LANES;
                let (count, du, r) = self.chunk_rotations(first, u, formulation);
                (0..count)
                    .map(|l| self.energy_of(first + l, formulation, r[l], du[l]))
                    .sum::<f64>()
            })
            .sum();
        let membranes: f64 = self
            .membrane_states(u, formulation)
            .iter()
            .map(|m| m.energy)
            .sum();
        let work: f64 = f_ext.iter().zip(u).map(|(f, u)| f.dot(*u)).sum();
        elastic + membranes + self.slider_energy(u) - work
    }

    /// Unrotated stresses of all elements (kPa), see [`FemModel::element_stress`].
    pub fn stresses(&self, u: &[DVec3], formulation: Formulation) -> Result<Vec<DMat3>, FemError> {
        self.check_vertex_field("displacement", u)?;
        Ok((0..self.tets.len())
            .into_par_iter()
            .map(|e| self.element_stress(e, u, formulation).0)
            .collect())
    }

    /// The internal elastic force `Σₑ R K (Rᵀ x - X)` (and the membranes' and sliders') at every vertex (mN) for
    /// displacement `u` (mm). At equilibrium it equals the external force at free
    /// vertices.
    pub fn internal_forces(
        &self,
        u: &[DVec3],
        formulation: Formulation,
    ) -> Result<Vec<DVec3>, FemError> {
        self.check_vertex_field("displacement", u)?;
        let mut forces = vec![[DVec3::ZERO; 4]; self.tets.len()];
        forces
            .par_chunks_mut(POLAR_LANES)
            .enumerate()
            .for_each(|(k, chunk)| {
                self.elements_warped(k * POLAR_LANES, u, formulation, |l, w| {
                    chunk[l] = w.force;
                });
            });
        let states = self.membrane_states(u, formulation);
        if !states.is_empty() {
            forces.par_iter_mut().enumerate().for_each(|(e, f)| {
                self.membrane_corner_forces(e, &states, |c, force| f[c] += force);
            });
        }
        let mut f = self.nodal_sum(|e| forces[e]);
        self.add_slider_forces(u, &mut f);
        Ok(f)
    }
}

impl FemModel {
    /// `Σₑ` of per-element corner values (e.g. forces, mN) at every vertex,
    /// `corners(e)` giving element `e`'s. Parallel over [`NODAL_SUM_BLOCKS`] fixed blocks
    /// of elements whose partial sums are added in order, so the result does not depend
    /// on the threads.
    pub(crate) fn nodal_sum(&self, corners: impl Fn(usize) -> [DVec3; 4] + Sync) -> Vec<DVec3> {
        let n = self.rest.len();
        let block = self.tets.len().div_ceil(NODAL_SUM_BLOCKS).max(1);
        let partial: Vec<Vec<DVec3>> = self
            .tets
            .par_chunks(block)
            .enumerate()
            .map(|(k, tets)| {
                let mut f = vec![DVec3::ZERO; n];
                for (i, t) in tets.iter().enumerate() {
                    let c = corners(k * block + i);
                    for a in 0..4 {
                        f[t[a] as usize] += c[a];
                    }
                }
                f
            })
            .collect();
        let mut sum = vec![DVec3::ZERO; n];
        for p in &partial {
            sum.par_iter_mut().zip(p).for_each(|(s, x)| *s += *x);
        }
        sum
    }
}

/// Blocks of elements summed separately by [`FemModel::nodal_sum`].
const NODAL_SUM_BLOCKS: usize = 8;

/// The cofactor matrix `cof(F) = det F · F⁻ᵀ`, whose column `q` is `∂ det F / ∂(column q
/// of F)`.
#[inline]
fn cofactor_matrix(f: DMat3) -> DMat3 {
    DMat3::from_cols(
        f.y_axis.cross(f.z_axis),
        f.z_axis.cross(f.x_axis),
        f.x_axis.cross(f.y_axis),
    )
}

/// The symmetric strain `sym(Rᵀ(I + ∇u)) - I` of rotation `r` and displacement gradient
/// `du` (exactly symmetric: the sum of a matrix and its transpose).
#[inline]
fn corotated_strain(r: DMat3, du: DMat3) -> DMat3 {
    let f = r.transpose() * (DMat3::IDENTITY + du);
    (f + f.transpose()) * 0.5 - DMat3::IDENTITY
}

/// [`FemModel::twist_stiffness`]'s `C` where none of its clamps acts, without the
/// eigendecomposition, else `None`. With `S = I + ε` (`strain` = ε, `trace` = tr(ε))
/// and the volume times stress `Σ̂ = 2Vμ ε + Vλ tr(ε) I` (`vol_mu` = Vμ, `vol_lambda` =
/// Vλ), the pair sums `σ̂ᵢ + σ̂ⱼ` and `sᵢ + sⱼ` are the eigenvalues, on the third axis
/// `vₖ`, of `A = tr(Σ̂) I - Σ̂` and `B = tr(S) I - S`. Where `A` is positive definite and
/// `B - 0.1 I` too (Sylvester's criterion), every pair has `cᵢⱼ = 2 (σ̂ᵢ + σ̂ⱼ) / (sᵢ +
/// sⱼ)`, so `C = ½ R A B⁻¹ Rᵀ` (`A` and `B` commute; the product is symmetrised against
/// rounding).
#[inline]
fn unclamped_twist(
    vol_lambda: f64,
    vol_mu: f64,
    r: DMat3,
    strain: DMat3,
    trace: f64,
) -> Option<DMat3> {
    let a = DMat3::from_diagonal(DVec3::splat(2.0 * (vol_mu + vol_lambda) * trace))
        - strain * (2.0 * vol_mu);
    let b = DMat3::from_diagonal(DVec3::splat(2.0 + trace)) - strain;
    let b_above_clamp = b - DMat3::from_diagonal(DVec3::splat(MIN_PAIR_STRETCH));
    if !(positive_definite(a) && positive_definite(b_above_clamp)) {
        return None;
    }
    let ratio = a * b.inverse();
    let symmetric = (ratio + ratio.transpose()) * 0.5;
    Some(r * symmetric * r.transpose() * 0.5)
}

/// The least pair sum of principal stretches `sᵢ + sⱼ` that divides a twist mode's
/// stress in [`FemModel::twist_stiffness`] (a nearly flattened element would otherwise
/// get an unbounded stiffness).
const MIN_PAIR_STRETCH: f64 = 0.1;

/// Whether the symmetric `m` is positive definite: its leading principal minors are
/// positive (Sylvester's criterion).
#[inline]
fn positive_definite(m: DMat3) -> bool {
    let (m00, m01, m11) = (m.x_axis.x, m.y_axis.x, m.y_axis.y);
    m00 > 0.0 && m00 * m11 - m01 * m01 > 0.0 && m.determinant() > 0.0
}

/// `a bᵀ`.
#[inline]
pub(crate) fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::polar::rotation_variant_svd;
    use crate::system::cross_matrix;

    /// Sylvester's criterion against matrices built from their eigenvalues: `Q diag(d) Qᵀ`
    /// is positive definite exactly when every `d` is, for rotations `Q` that mix all
    /// axes (eigenvalues at least 0.05 from zero, far beyond rounding).
    #[test]
    fn positive_definite_is_the_sign_of_the_least_eigenvalue() {
        let levels = [-2.0, -0.05, 0.05, 0.7, 3.0];
        let rotations = [
            DMat3::IDENTITY,
            DMat3::from_axis_angle(DVec3::new(0.3, -1.0, 0.5).normalize(), 0.7),
            DMat3::from_axis_angle(DVec3::new(1.0, 1.0, 1.0).normalize(), 2.1),
        ];
        let mut checked = 0;
        for q in rotations {
            for a in levels {
                for b in levels {
                    for c in levels {
                        let m = q * DMat3::from_diagonal(DVec3::new(a, b, c)) * q.transpose();
                        let expected = a > 0.0 && b > 0.0 && c > 0.0;
                        assert_eq!(positive_definite(m), expected, "{a} {b} {c} {q}");
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 3 * 125);
    }

    /// The compact twist stiffness `C` gives, block by block, the sum it replaces:
    /// `Σ cᵢⱼ tᵢⱼ,ₐ tᵢⱼ,_bᵀ` with `tᵢⱼ,ₐ = ½ (uᵢ (gₐ·vⱼ) - uⱼ (gₐ·vᵢ))` from the rotation-
    /// variant SVD (an independent decomposition), to 1e-9 of the largest block entry
    /// (both are rounding-exact formulas; the closed-form eigenvectors carry about 1e-12
    /// here, the spectra being well separated). Over stretched (no clamp acts: `C` in
    /// closed form without the eigendecomposition), compressed (where the Gershgorin
    /// bound skips the element: both are zero), mixed (some pairs clamped to zero),
    /// sheared and rotated deformations, an inverted element, and a flattened one (a
    /// stretch sum clamped, every stress sum positive).
    #[test]
    fn compact_twist_equals_the_pairwise_sum() {
        let mesh = TetMesh {
            positions: vec![
                DVec3::ZERO,
                DVec3::new(6.0, 0.5, 0.0),
                DVec3::new(1.0, 5.0, 0.3),
                DVec3::new(0.4, 1.0, 4.0),
            ],
            tets: vec![[0, 1, 2, 3]],
        };
        let model = FemModel::homogeneous(&mesh, Material::new(2.4, 0.45)).unwrap();
        let el = &model.elements[0];
        let q = DMat3::from_axis_angle(DVec3::new(0.3, -1.0, 0.5).normalize(), 0.7);
        let stretch = |d: [f64; 3]| DMat3::from_diagonal(DVec3::from_array(d));
        let shear = DMat3::from_cols(
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.25, 1.0, 0.0),
            DVec3::new(0.1, -0.15, 1.0),
        );
        let cases = [
            ("stretched", q * stretch([1.2, 1.1, 1.05])),
            ("compressed", q * stretch([0.8, 0.9, 0.95])),
            ("mixed", q * stretch([1.2, 1.0, 0.78])),
            ("sheared", q * shear),
            ("inverted", q * stretch([1.7, 1.5, -0.05])),
            // every pair's stress sum positive, but s₂ + s₃ = 0.09 under the 0.1 clamp
            ("flattened", q * stretch([3.5, 0.06, 0.03])),
        ];
        let mut skipped = 0;
        let mut unclamped = Vec::new();
        for (name, f) in cases {
            let u: Vec<DVec3> = mesh
                .positions
                .iter()
                .map(|&x| (f - DMat3::IDENTITY) * x)
                .collect();
            let du = model.displacement_gradient(0, &u);
            let r = polar_rotation(DMat3::IDENTITY + du);
            let c = model.twist_stiffness(0, r, du);
            skipped += usize::from(c == DMat3::ZERO);
            let strain = corotated_strain(r, du);
            let trace = strain.x_axis.x + strain.y_axis.y + strain.z_axis.z;
            if unclamped_twist(el.vol_lambda, el.vol_mu, r, strain, trace).is_some() {
                unclamped.push(name);
            }
            let (r_svd, v, s) = rotation_variant_svd(DMat3::IDENTITY + du);
            assert!(
                (r - r_svd).abs().to_cols_array().iter().all(|x| *x < 1e-12),
                "{name}"
            );
            let trs = s[0] + s[1] + s[2] - 3.0;
            let vsig = s.map(|si| 2.0 * el.vol_mu * (si - 1.0) + el.vol_lambda * trs);
            let uu = r_svd * v;
            let mut largest: f64 = 0.0;
            let mut worst: f64 = 0.0;
            for a in 0..4 {
                for b in 0..4 {
                    let mut explicit = DMat3::ZERO;
                    for (i, j) in [(0usize, 1usize), (0, 2), (1, 2)] {
                        let coef = 2.0 * (vsig[i] + vsig[j]).max(0.0) / (s[i] + s[j]).max(0.1);
                        let t = |g: DVec3| {
                            (uu.col(i) * g.dot(v.col(j)) - uu.col(j) * g.dot(v.col(i))) * 0.5
                        };
                        explicit += outer(t(el.grad[a]), t(el.grad[b])) * coef;
                    }
                    let (ha, hb) = (r * el.grad[a], r * el.grad[b]);
                    let compact = cross_matrix(ha) * c * cross_matrix(hb).transpose();
                    for (x, y) in explicit.to_cols_array().iter().zip(compact.to_cols_array()) {
                        largest = largest.max(x.abs());
                        worst = worst.max((x - y).abs());
                    }
                }
            }
            println!("{name}: largest entry {largest:.3e}, largest difference {worst:.3e}");
            assert!(
                worst <= 1e-9 * largest.max(1e-30),
                "{name}: {worst} of {largest}"
            );
        }
        // the compressed case is skipped without the eigendecomposition; where every
        // pair's stress sum is positive (the inverted element's too: principal strains
        // 0.7, 0.5, -1.05 under ν = 0.45) and no stretch sum under 0.1 (unlike the
        // flattened element's), the closed form serves
        assert!(skipped >= 1, "{skipped}");
        println!("without the eigendecomposition: {unclamped:?}");
        assert_eq!(unclamped, ["stretched", "sheared", "inverted"]);
    }
}
