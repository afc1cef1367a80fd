//! Isotropic Hooke material per element, and the default breast tissue parameters.
//!
//! Units: Young's modulus in kPa (= mN/mm²), density in kg/m³, lengths in mm, so forces
//! come out in mN.

/// Default Young's modulus of breast tissue (kPa).
///
/// Magnetic resonance elastography of normal breast parenchyma at 3 T reports
/// 1.85 ± 0.32 kPa for fatty and 2.95 ± 0.43 kPa for fibroglandular tissue (Karakaş L,
/// Poçan S, "Correlation Between Breast Parenchymal Stiffness Measured by 3T Magnetic
/// Resonance Elastography and CT-Derived Hounsfield Units", Med Sci Monit 2026;
/// 32:e952112, doi:10.12659/MSM.952112). We take 2.4 kPa, the middle of the two, for a
/// mixed breast. Caveat: MRE measures a dynamic (shear-wave) stiffness, not a static
/// Young's modulus; with displacement constraints only, a homogeneous modulus does not
/// change the displacement at all, it matters only against gravity and forces.
pub const DEFAULT_YOUNG_KPA: f64 = 2.4;

/// Default Poisson ratio of breast tissue: nearly incompressible soft tissue, 0.45 as in
/// issue 5 (linear tetrahedra lock as the ratio approaches 0.5).
pub const DEFAULT_POISSON_RATIO: f64 = 0.45;

/// Default density of breast tissue (kg/m³): between fat (about 920) and glandular
/// tissue (about 1040); close to water.
pub const DEFAULT_DENSITY_KG_M3: f64 = 1000.0;

/// Standard gravity (m/s²).
pub const STANDARD_GRAVITY_M_S2: f64 = 9.80665;

/// An isotropic linear elastic (Hooke) material.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Material {
    /// Young's modulus (kPa = mN/mm²), positive.
    pub young_kpa: f64,
    /// Poisson ratio, in (-1, 0.5).
    pub poisson_ratio: f64,
    /// Mass density (kg/m³), non-negative.
    pub density_kg_m3: f64,
}

impl Default for Material {
    /// Breast tissue: [`DEFAULT_YOUNG_KPA`], [`DEFAULT_POISSON_RATIO`],
    /// [`DEFAULT_DENSITY_KG_M3`].
    fn default() -> Self {
        Material {
            young_kpa: DEFAULT_YOUNG_KPA,
            poisson_ratio: DEFAULT_POISSON_RATIO,
            density_kg_m3: DEFAULT_DENSITY_KG_M3,
        }
    }
}

impl Material {
    /// A material with the given Young's modulus (kPa) and Poisson ratio, default density.
    pub fn new(young_kpa: f64, poisson_ratio: f64) -> Material {
        Material {
            young_kpa,
            poisson_ratio,
            density_kg_m3: DEFAULT_DENSITY_KG_M3,
        }
    }

    /// Lamé parameters `(λ, μ)` in kPa.
    pub fn lame(&self) -> (f64, f64) {
        let e = self.young_kpa;
        let nu = self.poisson_ratio;
        let lambda = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
        let mu = e / (2.0 * (1.0 + nu));
        (lambda, mu)
    }

    /// Checks the ranges; the message names the bad value.
    pub fn check(&self) -> Result<(), String> {
        if !(self.young_kpa.is_finite() && self.young_kpa > 0.0) {
            return Err(format!(
                "Young's modulus {} kPa: expected a finite positive value",
                self.young_kpa
            ));
        }
        if !(self.poisson_ratio.is_finite()
            && self.poisson_ratio > -1.0
            && self.poisson_ratio < 0.5)
        {
            return Err(format!(
                "Poisson ratio {}: expected a value in (-1, 0.5)",
                self.poisson_ratio
            ));
        }
        if !(self.density_kg_m3.is_finite() && self.density_kg_m3 >= 0.0) {
            return Err(format!(
                "density {} kg/m³: expected a finite non-negative value",
                self.density_kg_m3
            ));
        }
        Ok(())
    }
}
