//! Sliders: vertices held on a plane they may slide along (beyond the paper).
//!
//! A slider keeps vertex `v`'s displacement `u` on the plane through a target
//! displacement `d` with unit normal `n`, by a penalty spring across the plane: the
//! energy `½ k (n · (u - d))²`, the internal force `k (n · (u - d)) n` and the constant
//! stiffness block `k n nᵀ` (stiffness `k` in mN/mm). Along the plane the vertex is free.
//! It holds tissue at its distance from a surface it slides over (the skin over an
//! implant) where a full Dirichlet constraint would forbid the slide.
//!
//! The terms are per vertex, so they enter the diagonal block of the vertex's row only,
//! which a block smoother inverts exactly; Galerkin coarse levels inherit them.

use crate::error::FemError;
use crate::model::FemModel;
use glam::DVec3;

/// A vertex held on a plane (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slider {
    /// The vertex.
    pub vertex: u32,
    /// A displacement on the plane (mm).
    pub displacement: DVec3,
    /// The plane's normal (normalised when set; not zero).
    pub normal: DVec3,
    /// The spring's stiffness across the plane (mN/mm), positive.
    pub stiffness_mn_per_mm: f64,
}

impl Slider {
    /// How far displacement `u` lies off the plane, along the normal (mm).
    #[inline]
    pub fn gap_mm(&self, u: DVec3) -> f64 {
        self.normal.dot(u - self.displacement)
    }

    /// The spring's energy at displacement `u` (mN·mm).
    #[inline]
    pub fn energy(&self, u: DVec3) -> f64 {
        0.5 * self.stiffness_mn_per_mm * self.gap_mm(u).powi(2)
    }

    /// The internal force at displacement `u` (mN), the energy's gradient.
    #[inline]
    pub fn force(&self, u: DVec3) -> DVec3 {
        self.normal * (self.stiffness_mn_per_mm * self.gap_mm(u))
    }

    /// The stiffness block `k n nᵀ` (row-major).
    #[inline]
    pub fn block(&self) -> [f64; 9] {
        let n = self.normal.to_array();
        let k = self.stiffness_mn_per_mm;
        std::array::from_fn(|i| k * n[i / 3] * n[i % 3])
    }
}

/// A model's sliders, with each vertex's slider found in constant time.
#[derive(Debug, Clone, Default)]
pub(crate) struct Sliders {
    sliders: Vec<Slider>,
    /// Per vertex: the index of its slider, or `u32::MAX` (empty when there are none).
    of_vertex: Vec<u32>,
}

impl Sliders {
    /// Vertex `v`'s slider, if it has one.
    #[inline]
    pub(crate) fn at(&self, v: usize) -> Option<&Slider> {
        let k = *self.of_vertex.get(v)?;
        self.sliders.get(k as usize)
    }

    /// The sliders.
    pub(crate) fn all(&self) -> &[Slider] {
        &self.sliders
    }
}

impl FemModel {
    /// Replaces the model's [`Slider`]s (none by default); a vertex has at most one.
    ///
    /// Errors: a vertex out of range or given twice, a non-finite displacement, a zero or
    /// non-finite normal, a stiffness that is not positive and finite (the model is left
    /// unchanged).
    pub fn set_sliders(&mut self, sliders: &[Slider]) -> Result<(), FemError> {
        let n = self.vertex_count();
        let mut of_vertex = if sliders.is_empty() {
            Vec::new()
        } else {
            vec![u32::MAX; n]
        };
        let mut kept = Vec::with_capacity(sliders.len());
        for (k, s) in sliders.iter().enumerate() {
            let v = s.vertex as usize;
            let bad = |what: &'static str| FemError::BadSlider { slider: k, what };
            if v >= n {
                return Err(bad("vertex index out of range"));
            }
            if of_vertex[v] != u32::MAX {
                return Err(bad("a second slider on the same vertex"));
            }
            let length = s.normal.length();
            if !(length.is_finite() && length > 0.0) {
                return Err(bad("normal zero or not finite"));
            }
            if !s.displacement.is_finite() {
                return Err(bad("displacement not finite"));
            }
            if !(s.stiffness_mn_per_mm.is_finite() && s.stiffness_mn_per_mm > 0.0) {
                return Err(bad("stiffness not positive and finite"));
            }
            of_vertex[v] = kept.len() as u32;
            kept.push(Slider {
                normal: s.normal / length,
                ..*s
            });
        }
        self.sliders = Sliders {
            sliders: kept,
            of_vertex,
        };
        Ok(())
    }

    /// The model's sliders.
    pub fn sliders(&self) -> &[Slider] {
        self.sliders.all()
    }

    /// The sliders' energy at displacement `u` (mN·mm; `u` one per vertex).
    pub(crate) fn slider_energy(&self, u: &[DVec3]) -> f64 {
        let all = self.sliders.all();
        all.iter().map(|s| s.energy(u[s.vertex as usize])).sum()
    }

    /// Adds the sliders' internal forces at displacement `u` to `forces` (one per vertex).
    pub(crate) fn add_slider_forces(&self, u: &[DVec3], forces: &mut [DVec3]) {
        for s in self.sliders.all() {
            let v = s.vertex as usize;
            forces[v] += s.force(u[v]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn slider() -> Slider {
        Slider {
            vertex: 0,
            displacement: DVec3::new(1.0, 2.0, 3.0),
            normal: DVec3::new(0.0, 3.0, 4.0) / 5.0,
            stiffness_mn_per_mm: 7.0,
        }
    }

    /// The force is the energy's gradient (central differences, step 1e-5 mm: error
    /// of order 1e-10 relative for a quadratic) and the block its derivative (exact: the
    /// force is linear); a move along the plane costs nothing.
    #[test]
    fn force_and_block_derive_from_the_energy() {
        let s = slider();
        let u = DVec3::new(0.3, -1.2, 2.5);
        let h = 1e-5;
        let f = s.force(u);
        let b = s.block();
        for i in 0..3 {
            let mut e = DVec3::ZERO;
            e[i] = h;
            let numeric = (s.energy(u + e) - s.energy(u - e)) / (2.0 * h);
            assert!((numeric - f[i]).abs() < 1e-8 * f.length().max(1.0), "{i}");
            let df = (s.force(u + e) - s.force(u)) / h;
            for j in 0..3 {
                assert!((df[j] - b[3 * j + i]).abs() < 1e-9, "{i} {j}");
            }
        }
        let along = DVec3::new(1.0, 0.0, 0.0) * 4.0 + DVec3::new(0.0, 4.0, -3.0);
        assert!(s.energy(s.displacement + along).abs() < 1e-12);
        assert!(s.energy(s.displacement + s.normal) > 3.4);
    }
}
