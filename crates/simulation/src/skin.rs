//! The skin: a thin stiff membrane over the soft breast tissue, carried by the finest
//! elements that hold a face of the skin.
//!
//! Breast skin is about 1.5 mm thick and some 150 times stiffer than the fat and gland
//! under it (in vivo suction and ultrasound on 23 women: 344 ± 88 kPa, 1.55 ± 0.25 mm;
//! Sutradhar A, Miller MJ, "In vivo measurement of breast skin elasticity and breast skin
//! thickness", Skin Res Technol 2013;19:e191-e199). The finest elements are some 7 mm
//! across, far thicker than the skin, so the skin is not meshed: each element with a
//! face on the skin gets the Young's modulus that gives it, for stretch along that face,
//! the tissue's energy plus the skin membrane's over the face,
//! `E = E_tissue + (E_skin - E_tissue) * t_skin * A_skin / V` (capped at `E_skin`),
//! the membrane energy `½ E_skin t_skin A ε²` spread over the element's volume `V`.
//! The element is stiffened in every direction, not only along the skin: its resistance
//! to shear and to compression through the skin is overestimated by the same factor.

use fem::Material;
use std::collections::HashMap;
use tetra::TetMesh;
use tetra::quality::signed_volume;

/// Default Young's modulus of breast skin (kPa), Sutradhar and Miller's mean.
pub const DEFAULT_SKIN_YOUNG_KPA: f64 = 344.0;

/// Default thickness of breast skin (mm), Sutradhar and Miller's mean.
pub const DEFAULT_SKIN_THICKNESS_MM: f64 = 1.55;

/// The skin's membrane: Young's modulus and thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinLayer {
    /// Young's modulus of the skin (kPa), at least the tissue's.
    pub young_kpa: f64,
    /// Thickness of the skin (mm), positive.
    pub thickness_mm: f64,
}

impl Default for SkinLayer {
    /// [`DEFAULT_SKIN_YOUNG_KPA`], [`DEFAULT_SKIN_THICKNESS_MM`].
    fn default() -> Self {
        SkinLayer {
            young_kpa: DEFAULT_SKIN_YOUNG_KPA,
            thickness_mm: DEFAULT_SKIN_THICKNESS_MM,
        }
    }
}

impl SkinLayer {
    /// Checks the ranges against the tissue under the skin; the message names the bad
    /// value.
    pub fn check(&self, tissue: &Material) -> Result<(), String> {
        if !(self.young_kpa.is_finite() && self.young_kpa >= tissue.young_kpa) {
            return Err(format!(
                "skin Young's modulus {} kPa: expected a finite value of at least the \
                 tissue's {} kPa",
                self.young_kpa, tissue.young_kpa
            ));
        }
        if !(self.thickness_mm.is_finite() && self.thickness_mm > 0.0) {
            return Err(format!(
                "skin thickness {} mm: expected a finite positive value",
                self.thickness_mm
            ));
        }
        Ok(())
    }

    /// Per element of `mesh`: `tissue`, stiffened where the element holds skin faces.
    /// A skin face is a boundary face none of whose vertices `not_skin` marks (the
    /// posterior wall and the clip planes' band).
    pub fn materials(&self, mesh: &TetMesh, tissue: Material, not_skin: &[bool]) -> Vec<Material> {
        let areas = skin_area_per_element(mesh, not_skin);
        mesh.tets
            .iter()
            .zip(areas)
            .map(|(tet, area_mm2)| {
                if area_mm2 == 0.0 {
                    return tissue;
                }
                let volume_mm3 = signed_volume(tet.map(|v| mesh.positions[v as usize]));
                let share = (self.thickness_mm * area_mm2 / volume_mm3).min(1.0);
                Material {
                    young_kpa: tissue.young_kpa + (self.young_kpa - tissue.young_kpa) * share,
                    ..tissue
                }
            })
            .collect()
    }
}

/// Per element: the area (mm²) of its faces on the boundary whose vertices are all
/// unmarked in `not_skin`.
fn skin_area_per_element(mesh: &TetMesh, not_skin: &[bool]) -> Vec<f64> {
    const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
    let mut owners: HashMap<[u32; 3], (u32, usize)> = HashMap::with_capacity(mesh.tets.len() * 2);
    for (e, tet) in mesh.tets.iter().enumerate() {
        for (k, face) in FACES.iter().enumerate() {
            let mut key = face.map(|i| tet[i]);
            key.sort_unstable();
            owners
                .entry(key)
                .and_modify(|owner| owner.0 = u32::MAX)
                .or_insert((e as u32, k));
        }
    }
    let mut areas = vec![0.0; mesh.tets.len()];
    for (key, (e, k)) in owners {
        if e == u32::MAX || key.iter().any(|&v| not_skin[v as usize]) {
            continue;
        }
        let tet = mesh.tets[e as usize];
        let [a, b, c] = FACES[k].map(|i| mesh.positions[tet[i] as usize]);
        areas[e as usize] += 0.5 * (b - a).cross(c - a).length();
    }
    areas
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// One tetrahedron with the right-angled corner at the origin and legs of 10 mm:
    /// volume 1000/6 mm³, the three leg faces 50 mm² each.
    fn corner_tet() -> TetMesh {
        TetMesh {
            positions: vec![
                DVec3::ZERO,
                DVec3::new(10.0, 0.0, 0.0),
                DVec3::new(0.0, 10.0, 0.0),
                DVec3::new(0.0, 0.0, 10.0),
            ],
            tets: vec![[0, 1, 2, 3]],
        }
    }

    #[test]
    fn one_skin_face_adds_the_membrane_energy_over_the_element_volume() {
        // Only the face z = 0 (vertices 0, 1, 2) is skin: vertex 3 is on the wall.
        // E = 2 + (300 - 2) * 1.5 mm * 50 mm² / (1000/6 mm³) = 2 + 298 * 0.45.
        let skin = SkinLayer {
            young_kpa: 300.0,
            thickness_mm: 1.5,
        };
        let tissue = Material::new(2.0, 0.45);
        let m = skin.materials(&corner_tet(), tissue, &[false, false, false, true]);
        assert!((m[0].young_kpa - (2.0 + 298.0 * 0.45)).abs() < 1e-9);
        assert_eq!(m[0].poisson_ratio, 0.45);
    }

    #[test]
    fn no_skin_face_keeps_the_tissue_and_a_thin_element_is_capped() {
        let skin = SkinLayer::default();
        let tissue = Material::default();
        let mesh = corner_tet();
        // two vertices on the wall: every face touches it
        let none = skin.materials(&mesh, tissue, &[true, true, false, false]);
        assert_eq!(none[0], tissue);
        // all four faces skin (446.6 mm² over 166.7 mm³, times 1.55 mm > 1): capped
        let all = skin.materials(&mesh, tissue, &[false; 4]);
        assert_eq!(all[0].young_kpa, skin.young_kpa);
    }

    #[test]
    fn a_stretched_slab_stores_the_tissue_and_the_skin_membrane_energy() {
        // A 40 x 20 x 10 mm slab with skin on its top face (z = 10), stretched along x by
        // ε with the Poisson contraction: with one Poisson ratio every element is in
        // uniaxial stress σ = E ε, and linear tetrahedra hold the linear field exactly,
        // so the energy is ½ ε² Σ E V = ½ ε² (E_tissue V + (E_skin - E_tissue) t A_top)
        // to round-off: the stiffening adds exactly the membrane's energy.
        let mesh = fem::box_mesh(DVec3::ZERO, DVec3::new(40.0, 20.0, 10.0), [8, 4, 1]);
        let tissue = Material::new(2.4, 0.45);
        let skin = SkinLayer {
            young_kpa: 344.0,
            thickness_mm: 1.0,
        };
        let below_top: Vec<bool> = mesh.positions.iter().map(|p| p.z < 10.0).collect();
        let materials = skin.materials(&mesh, tissue, &below_top);
        assert!(materials.iter().all(|m| m.young_kpa < skin.young_kpa));
        let model = fem::FemModel::new(&mesh, materials).unwrap();
        let strain = 0.1;
        let nu = tissue.poisson_ratio;
        let u: Vec<DVec3> = mesh
            .positions
            .iter()
            .map(|p| DVec3::new(p.x, -nu * p.y, -nu * p.z) * strain)
            .collect();
        let energy = model.potential_energy(&u, &[], fem::Formulation::Linear);
        let expected = 0.5
            * strain
            * strain
            * (tissue.young_kpa * 8000.0 + (skin.young_kpa - tissue.young_kpa) * 1.0 * 800.0);
        assert!(
            (energy - expected).abs() < 1e-9 * expected,
            "{energy} {expected}"
        );
    }

    #[test]
    fn an_inner_face_is_not_skin() {
        // Two tetrahedra sharing the face (1, 2, 3): each has three boundary faces and
        // its shared face is not counted. With the apex vertices 0 and 4 on the wall,
        // no boundary face is skin.
        let mut mesh = corner_tet();
        mesh.positions.push(DVec3::splat(10.0));
        mesh.tets.push([4, 3, 2, 1]);
        assert!(signed_volume(mesh.tets[1].map(|v| mesh.positions[v as usize])) > 0.0);
        let areas = skin_area_per_element(&mesh, &[true, false, false, false, true]);
        assert_eq!(areas, vec![0.0, 0.0]);
    }
}
