//! Linear elastic membranes on faces of the tetrahedra: a thin stiff sheet (the skin)
//! whose energy depends on the face's own stretch only.
//!
//! A membrane is a plane-stress triangle of thickness `t` over one face of a tetrahedron,
//! corotated by the polar decomposition of its own deformation gradient
//! `F = Σₐ xₐ ⊗ gₐ` (3x2: `gₐ` are the rest gradients of the face's barycentric functions
//! in an orthonormal rest frame of the face). With `F = Q S` (`Q` 3x2 with orthonormal
//! columns, `S` 2x2 symmetric positive definite) the strain is `ε = S - I` and the energy
//! `t A (μ ‖ε‖² + λ/2 tr(ε)²)` with plane-stress `λ = E ν / (1 - ν²)`, `μ = E / (2 (1 + ν))`.
//! The corner forces `t A Q σ gₐ` are its exact gradient (`σ` commutes with `S`, so the
//! derivative of `Q` drops out, as for the tetrahedra), and the warped stiffness
//! `t A (λ ĥₐ ĥ_bᵀ + μ ĥ_b ĥₐᵀ + μ (ĥₐ·ĥ_b) Q Qᵀ)` with `ĥₐ = Q gₐ` is the tetrahedra's
//! form with the identity replaced by the projector on the face. Unlike stiffening the
//! tetrahedron under the face, a membrane resists neither bending nor shear through the
//! sheet, so its stiffness does not grow with the element size.
//!
//! A sheet has no stiffness across itself but what its tension gives (a drumhead), so
//! both corotated tangents add the tension's part of the geometric term (the linear
//! formulation's tangent stays its exact, constant Jacobian), the derivative of the
//! forces through the turn of the face's normal: `t A (gₐᵀ T g_b) n nᵀ` with
//! `T = (σ S⁻¹)⁺` (the positive part keeps the matrix positive semidefinite; a sheet in
//! compression would buckle). Without it the corotated iteration crawled (27 stage-1
//! cycles instead of 16 on v02_average; docs/dev/discretisation.md). The in-plane turn's
//! part is left out.

use crate::Formulation;
use crate::error::FemError;
use crate::material::Material;
use glam::{DMat3, DVec2, DVec3};

/// A membrane on one face of a tetrahedron.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Membrane {
    /// The tetrahedron whose face it lies on.
    pub element: u32,
    /// The face's three vertices (three of the tetrahedron's).
    pub face: [u32; 3],
    /// The sheet's Young's modulus and Poisson ratio (its density is not used).
    pub material: Material,
    /// The sheet's thickness (mm), positive.
    pub thickness_mm: f64,
}

/// Rest data of one membrane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct MembraneRest {
    /// The tetrahedron's corner index of each face vertex.
    pub(crate) corners: [u8; 3],
    /// Rest gradients of the face's barycentric functions in its rest frame (1/mm).
    grad: [DVec2; 3],
    /// Orthonormal rest frame of the face (its first two axes).
    frame: [DVec3; 2],
    /// `t A λ` and `t A μ` (plane stress; mN·mm).
    ta_lambda: f64,
    ta_mu: f64,
}

/// A membrane in its current state: what the assembly reads.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct MembraneState {
    /// `ĥₐ = Q gₐ` per face corner.
    pub(crate) rotated_grad: [DVec3; 3],
    /// The projector `Q Qᵀ` on the current face.
    pub(crate) projector: DMat3,
    /// The face's unit normal `q₁ × q₂`.
    normal: DVec3,
    /// `t A Q (σ S⁻¹)⁺ Qᵀ`: the tension that stiffens the sheet across itself (mN·mm).
    tension: DMat3,
    /// Internal elastic force at the face corners (mN).
    pub(crate) force: [DVec3; 3],
    /// Elastic energy (mN·mm).
    pub(crate) energy: f64,
    /// `t A λ` and `t A μ`.
    pub(crate) ta_lambda: f64,
    pub(crate) ta_mu: f64,
}

impl MembraneRest {
    /// The rest data of `m` on the tetrahedron `tet` with rest positions `rest`; the
    /// error names what is wrong.
    pub(crate) fn new(m: &Membrane, tet: [u32; 4], rest: &[DVec3]) -> Result<Self, FemError> {
        let bad = |reason: &'static str| FemError::BadElement {
            element: m.element as usize,
            vertices: tet,
            reason,
        };
        let mut corners = [0u8; 3];
        for (c, v) in corners.iter_mut().zip(m.face) {
            *c = tet.iter().position(|&w| w == v).ok_or(bad(
                "a membrane's face vertex is not a vertex of its tetrahedron",
            ))? as u8;
        }
        if corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2] {
            return Err(bad("a membrane's face repeats a vertex"));
        }
        m.material.check().map_err(|what| FemError::BadMaterial {
            element: m.element as usize,
            what: format!("membrane: {what}"),
        })?;
        if !(m.thickness_mm.is_finite() && m.thickness_mm > 0.0) {
            return Err(FemError::BadMaterial {
                element: m.element as usize,
                what: format!(
                    "membrane thickness {} mm: expected a finite positive value",
                    m.thickness_mm
                ),
            });
        }
        let [x0, x1, x2] = m.face.map(|v| rest[v as usize]);
        let normal = (x1 - x0).cross(x2 - x0);
        let edge = (x1 - x0).length().max((x2 - x0).length());
        let twice_area = normal.length();
        if twice_area.is_nan() || twice_area <= 1e-10 * edge * edge {
            return Err(bad("a membrane's rest face is degenerate"));
        }
        let e1 = (x1 - x0).normalize();
        let e2 = normal.normalize().cross(e1);
        let local = |x: DVec3| DVec2::new((x - x0).dot(e1), (x - x0).dot(e2));
        let (d1, d2) = (local(x1), local(x2));
        let det = d1.x * d2.y - d1.y * d2.x;
        // rows of the inverse of [d1 d2]
        let g1 = DVec2::new(d2.y, -d2.x) / det;
        let g2 = DVec2::new(-d1.y, d1.x) / det;
        let area = 0.5 * det.abs();
        let (young, nu) = (m.material.young_kpa, m.material.poisson_ratio);
        let ta = m.thickness_mm * area;
        Ok(MembraneRest {
            corners,
            grad: [-(g1 + g2), g1, g2],
            frame: [e1, e2],
            ta_lambda: ta * young * nu / (1.0 - nu * nu),
            ta_mu: ta * young / (2.0 * (1.0 + nu)),
        })
    }

    /// The state for the current positions `x` of the face's corners.
    pub(crate) fn state(&self, x: [DVec3; 3], formulation: Formulation) -> MembraneState {
        let f1 = x[0] * self.grad[0].x + x[1] * self.grad[1].x + x[2] * self.grad[2].x;
        let f2 = x[0] * self.grad[0].y + x[1] * self.grad[1].y + x[2] * self.grad[2].y;
        let [q1, q2] = match formulation {
            Formulation::Linear => self.frame,
            Formulation::Corotated => polar_frame(f1, f2).unwrap_or(self.frame),
        };
        // S = Qᵀ F, symmetrised (exactly symmetric for the polar factor)
        let s12 = 0.5 * (q1.dot(f2) + q2.dot(f1));
        let (e11, e22, e12) = (q1.dot(f1) - 1.0, q2.dot(f2) - 1.0, s12);
        let tr = e11 + e22;
        let sigma = |g: DVec2| {
            DVec2::new(
                self.ta_lambda * tr * g.x + 2.0 * self.ta_mu * (e11 * g.x + e12 * g.y),
                self.ta_lambda * tr * g.y + 2.0 * self.ta_mu * (e12 * g.x + e22 * g.y),
            )
        };
        let to_3d = |v: DVec2| q1 * v.x + q2 * v.y;
        let outer = |a: DVec3, b: DVec3| DMat3::from_cols(a * b.x, a * b.y, a * b.z);
        // σ S⁻¹ (t A included), symmetric as σ commutes with S; its positive part
        let (s11, s22) = (e11 + 1.0, e22 + 1.0);
        let det_s = s11 * s22 - s12 * s12;
        let (p11, p12, p22) = if formulation == Formulation::Corotated && det_s > 0.0 {
            let (a, b, c) = (
                self.ta_lambda * tr + 2.0 * self.ta_mu * e11,
                2.0 * self.ta_mu * e12,
                self.ta_lambda * tr + 2.0 * self.ta_mu * e22,
            );
            // [a b; b c] [s22 -s12; -s12 s11] / det S, symmetrised
            let m11 = (a * s22 - b * s12) / det_s;
            let m22 = (c * s11 - b * s12) / det_s;
            let m12 = 0.5 * ((b * s11 - a * s12) + (b * s22 - c * s12)) / det_s;
            positive_part(m11, m12, m22)
        } else {
            (0.0, 0.0, 0.0)
        };
        let tension =
            (outer(q1, q1) * p11 + outer(q2, q2) * p22) + (outer(q1, q2) + outer(q2, q1)) * p12;
        MembraneState {
            rotated_grad: self.grad.map(to_3d),
            projector: outer(q1, q1) + outer(q2, q2),
            normal: q1.cross(q2),
            tension,
            force: self.grad.map(|g| to_3d(sigma(g))),
            energy: self.ta_mu * (e11 * e11 + e22 * e22 + 2.0 * e12 * e12)
                + 0.5 * self.ta_lambda * tr * tr,
            ta_lambda: self.ta_lambda,
            ta_mu: self.ta_mu,
        }
    }
}

impl MembraneState {
    /// The stiffness block `(a, b)` of the face corners `a`, `b`, row-major.
    #[inline]
    pub(crate) fn block(&self, a: usize, b: usize) -> DMat3 {
        let (ha, hb) = (self.rotated_grad[a], self.rotated_grad[b]);
        let outer = |x: DVec3, y: DVec3| DMat3::from_cols(x * y.x, x * y.y, x * y.z);
        outer(ha, hb) * self.ta_lambda
            + outer(hb, ha) * self.ta_mu
            + self.projector * (self.ta_mu * ha.dot(hb))
            + outer(self.normal, self.normal) * ha.dot(self.tension * hb)
    }
}

/// The positive part `(p₁₁, p₁₂, p₂₂)` of the symmetric 2x2 matrix `[m₁₁ m₁₂; m₁₂ m₂₂]`.
fn positive_part(m11: f64, m12: f64, m22: f64) -> (f64, f64, f64) {
    let mean = 0.5 * (m11 + m22);
    let radius = (0.25 * (m11 - m22) * (m11 - m22) + m12 * m12).sqrt();
    let (high, low) = (mean + radius, mean - radius);
    if low >= 0.0 {
        return (m11, m12, m22);
    }
    if high <= 0.0 {
        return (0.0, 0.0, 0.0);
    }
    // high · v vᵀ with v the eigenvector of `high`
    let v = if (m11 - low).abs() >= (m22 - low).abs() {
        DVec2::new(m11 - low, m12)
    } else {
        DVec2::new(m12, m22 - low)
    }
    .normalize();
    (high * v.x * v.x, high * v.x * v.y, high * v.y * v.y)
}

/// The orthonormal factor `Q = F S⁻¹` of the polar decomposition of the 3x2 matrix with
/// columns `f1`, `f2`, in closed form (`S = (C + s I) / √(tr C + 2s)` with `C = FᵀF`,
/// `s = √det C`); `None` for a face collapsed to a line or a point.
fn polar_frame(f1: DVec3, f2: DVec3) -> Option<[DVec3; 2]> {
    let (c11, c22, c12) = (f1.dot(f1), f2.dot(f2), f1.dot(f2));
    let s = f1.cross(f2).length();
    if s.is_nan() || s <= 1e-12 * (c11 + c22) {
        return None;
    }
    let t = (c11 + c22 + 2.0 * s).sqrt();
    // S⁻¹ = adj(C + s I) / (s t)
    let k = 1.0 / (s * t);
    Some([
        (f1 * (c22 + s) - f2 * c12) * k,
        (f2 * (c11 + s) - f1 * c12) * k,
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A triangle in a tilted plane with a right angle at its first corner.
    fn rest_face() -> ([DVec3; 3], MembraneRest) {
        let tilt = DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 0.6);
        let x = [
            DVec3::new(1.0, 2.0, 3.0),
            DVec3::new(1.0, 2.0, 3.0) + tilt * DVec3::new(8.0, 0.0, 0.0),
            DVec3::new(1.0, 2.0, 3.0) + tilt * DVec3::new(0.0, 5.0, 0.0),
        ];
        let mut rest = x.to_vec();
        rest.push(x[0] + tilt * DVec3::new(0.0, 0.0, -4.0));
        let m = Membrane {
            element: 0,
            face: [0, 1, 2],
            material: Material::new(300.0, 0.4),
            thickness_mm: 1.5,
        };
        (x, MembraneRest::new(&m, [0, 1, 2, 3], &rest).unwrap())
    }

    #[test]
    fn a_uniaxial_stretch_stores_the_plane_stress_energy() {
        // Stretched by ε along the first leg with the plane-stress contraction -ν ε
        // along the second, the sheet is in uniaxial stress σ = E ε: the energy is
        // ½ E ε² t A with A = 20 mm², to round-off, after any rotation of the whole.
        let (x, rest) = rest_face();
        let (e1, e2) = ((x[1] - x[0]).normalize(), (x[2] - x[0]).normalize());
        let eps = 0.05;
        let turn = DMat3::from_axis_angle(DVec3::new(-0.3, 0.2, 1.0).normalize(), 1.1);
        let moved = x.map(|p| {
            let d = p - x[0];
            turn * (d + e1 * (eps * d.dot(e1)) - e2 * (0.4 * eps * d.dot(e2))) + DVec3::X
        });
        let state = rest.state(moved, Formulation::Corotated);
        let expected = 0.5 * 300.0 * eps * eps * 1.5 * 20.0;
        assert!(
            (state.energy - expected).abs() < 1e-9 * expected,
            "{}",
            state.energy
        );
        // the forces balance
        let sum: DVec3 = state.force.iter().copied().sum();
        assert!(sum.length() < 1e-9);
    }

    #[test]
    fn a_rigid_motion_costs_nothing() {
        let (x, rest) = rest_face();
        let turn = DMat3::from_axis_angle(DVec3::new(0.5, -1.0, 0.2).normalize(), 2.5);
        let state = rest.state(
            x.map(|p| turn * p + DVec3::new(3.0, -2.0, 7.0)),
            Formulation::Corotated,
        );
        assert!(state.energy.abs() < 1e-20);
        assert!(state.force.iter().all(|f| f.length() < 1e-9));
    }

    #[test]
    fn the_forces_are_the_energy_gradient() {
        // Central differences of the energy (step 1e-6 mm) against the forces, in a
        // stretched, sheared and turned state: the corotated membrane is conservative.
        // Truncation is O(h²) of the third derivative and rounding O(ε E / h): 1e-6 of
        // the largest force is far above both.
        let (x, rest) = rest_face();
        let turn = DMat3::from_axis_angle(DVec3::new(0.1, 0.7, 0.4).normalize(), 0.9);
        let moved = [
            turn * x[0],
            turn * (x[1] + DVec3::new(0.9, -0.3, 0.5)),
            turn * (x[2] + DVec3::new(-0.4, 0.8, -0.6)),
        ];
        let state = rest.state(moved, Formulation::Corotated);
        let largest = state.force.iter().map(|f| f.length()).fold(0.0, f64::max);
        let h = 1e-6;
        for a in 0..3 {
            for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
                let energy = |d: f64| {
                    let mut p = moved;
                    p[a] += axis * d;
                    rest.state(p, Formulation::Corotated).energy
                };
                let numeric = (energy(h) - energy(-h)) / (2.0 * h);
                let analytic = state.force[a].dot(axis);
                assert!(
                    (numeric - analytic).abs() < 1e-6 * largest,
                    "corner {a}: {numeric} against {analytic}"
                );
            }
        }
    }

    #[test]
    fn the_stiffness_is_the_force_derivative_at_rest() {
        // At rest the warped stiffness is the exact derivative of the forces (no
        // geometric term), so K δu equals the central difference of the forces.
        let (x, rest) = rest_face();
        let state = rest.state(x, Formulation::Corotated);
        let du = [
            DVec3::new(0.3, -0.2, 0.1),
            DVec3::new(-0.1, 0.4, 0.2),
            DVec3::new(0.2, 0.1, -0.3),
        ];
        let h = 1e-6;
        let forces = |s: f64| {
            let p = [x[0] + du[0] * s, x[1] + du[1] * s, x[2] + du[2] * s];
            rest.state(p, Formulation::Corotated).force
        };
        let (plus, minus) = (forces(h), forces(-h));
        for a in 0..3 {
            let numeric = (plus[a] - minus[a]) / (2.0 * h);
            let analytic: DVec3 = (0..3).map(|b| state.block(a, b) * du[b]).sum();
            assert!(
                (numeric - analytic).length() < 1e-6 * analytic.length().max(1.0),
                "corner {a}: {numeric} against {analytic}"
            );
        }
    }

    #[test]
    fn a_stretched_sheet_resists_a_push_across_it_by_its_tension() {
        // Stretched 5% in its plane one way and 2% the other (all tension), a push of the
        // corners across the face changes the forces, to first order, by the tension's
        // term alone (the strain does not change to first order): the block against the
        // central difference (step 1e-6 mm) to 1e-6 relative. Compressed instead, the
        // clamped tension is zero and so is the block across the face.
        let (x, rest) = rest_face();
        let (e1, e2) = ((x[1] - x[0]).normalize(), (x[2] - x[0]).normalize());
        let normal = e1.cross(e2);
        let stretched = |a: f64, b: f64| {
            x.map(|p| {
                let d = p - x[0];
                x[0] + d + e1 * (a * d.dot(e1)) + e2 * (b * d.dot(e2))
            })
        };
        let push = [0.2, -0.5, 0.3].map(|k| normal * k);
        for (a, b, tension) in [(0.05, 0.02, true), (-0.05, -0.02, false)] {
            let moved = stretched(a, b);
            let state = rest.state(moved, Formulation::Corotated);
            let h = 1e-6;
            let forces = |s: f64| {
                let p = [0, 1, 2].map(|k| moved[k] + push[k] * s);
                rest.state(p, Formulation::Corotated).force
            };
            let (plus, minus) = (forces(h), forces(-h));
            for c in 0..3 {
                let across: DVec3 = (0..3).map(|d| state.block(c, d) * push[d]).sum();
                let along = (plus[c] - minus[c]) / (2.0 * h);
                if tension {
                    assert!(
                        (along - across).length() < 1e-6 * along.length(),
                        "corner {c}: {along} against {across}"
                    );
                } else {
                    assert!(across.length() < 1e-12, "corner {c}: {across}");
                }
            }
        }
    }

    #[test]
    fn the_positive_part_keeps_the_positive_eigenvalue_only() {
        // [[1, 2], [2, 1]] has eigenvalues 3 (along (1, 1)) and -1: its positive part is
        // 3/2 [[1, 1], [1, 1]]; a positive definite matrix is its own, a negative one 0.
        let (a, b, c) = positive_part(1.0, 2.0, 1.0);
        assert!((a - 1.5).abs() < 1e-14 && (b - 1.5).abs() < 1e-14 && (c - 1.5).abs() < 1e-14);
        // tilted: eigenvalues 4 and -2 along (cos, sin) of 30 and 120 degrees
        let (cs, sn) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
        let m11 = 4.0 * cs * cs - 2.0 * sn * sn;
        let m12 = 4.0 * cs * sn + 2.0 * sn * cs;
        let m22 = 4.0 * sn * sn - 2.0 * cs * cs;
        let (a, b, c) = positive_part(m11, m12, m22);
        for (got, want) in [(a, 4.0 * cs * cs), (b, 4.0 * cs * sn), (c, 4.0 * sn * sn)] {
            assert!((got - want).abs() < 1e-12, "{got} {want}");
        }
        assert_eq!(positive_part(2.0, 0.5, 1.0), (2.0, 0.5, 1.0));
        assert_eq!(positive_part(-2.0, 0.5, -1.0), (0.0, 0.0, 0.0));
    }

    #[test]
    fn a_face_not_on_its_element_or_a_bad_sheet_is_refused() {
        let rest = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z, DVec3::ONE];
        let mut m = Membrane {
            element: 0,
            face: [0, 1, 4],
            material: Material::new(300.0, 0.4),
            thickness_mm: 1.0,
        };
        assert!(MembraneRest::new(&m, [0, 1, 2, 3], &rest).is_err());
        m.face = [0, 1, 2];
        m.thickness_mm = 0.0;
        assert!(MembraneRest::new(&m, [0, 1, 2, 3], &rest).is_err());
        m.thickness_mm = 1.0;
        assert!(MembraneRest::new(&m, [0, 1, 2, 3], &rest).is_ok());
    }
}
