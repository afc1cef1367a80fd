//! The skin: a thin stiff membrane over the soft breast tissue, on the finest mesh's
//! boundary faces.
//!
//! Breast skin is about 1.5 mm thick and some 150 times stiffer than the fat and gland
//! under it (in vivo suction and ultrasound on 23 women: 344 ± 88 kPa, 1.55 ± 0.25 mm;
//! Sutradhar A, Miller MJ, "In vivo measurement of breast skin elasticity and breast skin
//! thickness", Skin Res Technol 2013;19:e191-e199). The finest elements are 4-7 mm
//! across, far thicker than the skin, so the skin is not meshed: each boundary face on
//! the skin carries a plane-stress membrane ([`fem::Membrane`]) of the skin's thickness
//! with the modulus `E_skin - E_tissue` (the tissue under it already fills the skin's
//! volume), so that stretch along the skin stores the membrane's energy
//! `½ E_skin t_skin A ε²` exactly. A membrane resists neither bending nor shear through
//! the skin, and its stiffness does not depend on the element size (stiffening the
//! elements under the face, as before, made the skin's bending grow with the square of
//! the element size; docs/dev/discretisation.md).
use fem::{Material, Membrane};
use std::collections::HashMap;
use tetra::TetMesh;

/// Default Young's modulus of breast skin (kPa), Sutradhar and Miller's mean.
pub const DEFAULT_SKIN_YOUNG_KPA: f64 = 344.0;

/// Default thickness of breast skin (mm), Sutradhar and Miller's mean.
pub const DEFAULT_SKIN_THICKNESS_MM: f64 = 1.55;

/// The skin's membrane: Young's modulus and thickness.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkinLayer {
    /// Young's modulus of the skin (kPa), above the tissue's.
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
        if !(self.young_kpa.is_finite() && self.young_kpa > tissue.young_kpa) {
            return Err(format!(
                "skin Young's modulus {} kPa: expected a finite value above the \
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

    /// The skin's membranes on `mesh` over `tissue`: one per skin face, a boundary
    /// face none of whose vertices `not_skin` marks (the posterior wall and the clip
    /// planes' band), on the tetrahedron it bounds.
    pub fn membranes(&self, mesh: &TetMesh, tissue: Material, not_skin: &[bool]) -> Vec<Membrane> {
        let material = Material {
            young_kpa: self.young_kpa - tissue.young_kpa,
            ..tissue
        };
        skin_faces(mesh, not_skin)
            .into_iter()
            .map(|(element, face)| Membrane {
                element,
                face,
                material,
                thickness_mm: self.thickness_mm,
            })
            .collect()
    }
}

/// The boundary faces of `mesh` none of whose vertices `not_skin` marks, each with the
/// tetrahedron it bounds, in element order.
fn skin_faces(mesh: &TetMesh, not_skin: &[bool]) -> Vec<(u32, [u32; 3])> {
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
    let mut faces: Vec<(u32, [u32; 3])> = owners
        .into_iter()
        .filter(|(key, (e, _))| *e != u32::MAX && key.iter().all(|&v| !not_skin[v as usize]))
        .map(|(_, (e, k))| (e, FACES[k].map(|i| mesh.tets[e as usize][i])))
        .collect();
    faces.sort_unstable();
    faces
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use tetra::quality::signed_volume;

    /// One tetrahedron with the right-angled corner at the origin and legs of 10 mm.
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
    fn a_stretched_slab_stores_the_tissue_and_the_skin_membrane_energy() {
        // A 40 x 20 x 10 mm slab with skin on its top face (z = 10), stretched along x by
        // ε with the Poisson contraction: every element is in uniaxial stress and the
        // skin in plane stress, both σ = E ε, so the energy is
        // ½ ε² (E_tissue V + (E_skin - E_tissue) t A_top) to round-off: the membranes add
        // exactly the skin's energy over the tissue's.
        let mesh = fem::box_mesh(DVec3::ZERO, DVec3::new(40.0, 20.0, 10.0), [8, 4, 1]);
        let tissue = Material::new(2.4, 0.45);
        let skin = SkinLayer {
            young_kpa: 344.0,
            thickness_mm: 1.0,
        };
        let below_top: Vec<bool> = mesh.positions.iter().map(|p| p.z < 10.0).collect();
        let membranes = skin.membranes(&mesh, tissue, &below_top);
        assert_eq!(membranes.len(), 8 * 4 * 2);
        let mut model = fem::FemModel::homogeneous(&mesh, tissue).unwrap();
        model.set_membranes(&membranes).unwrap();
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
    fn a_face_touching_the_wall_is_no_skin() {
        // two vertices on the wall: every face touches it
        let skin = SkinLayer::default();
        let mesh = corner_tet();
        let none = skin.membranes(&mesh, Material::default(), &[true, true, false, false]);
        assert!(none.is_empty());
        // one vertex on the wall: the face opposite it is skin
        let one = skin.membranes(&mesh, Material::default(), &[false, false, false, true]);
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].face, [0, 2, 1]);
    }

    #[test]
    fn an_inner_face_is_not_skin() {
        // Two tetrahedra sharing the face (1, 2, 3): each has three boundary faces and
        // their shared face is not among the skin faces. With the apex vertices 0 and 4
        // on the wall, no boundary face is skin.
        let mut mesh = corner_tet();
        mesh.positions.push(DVec3::splat(10.0));
        mesh.tets.push([4, 3, 2, 1]);
        assert!(signed_volume(mesh.tets[1].map(|v| mesh.positions[v as usize])) > 0.0);
        assert_eq!(skin_faces(&mesh, &[false; 5]).len(), 6);
        assert!(skin_faces(&mesh, &[true, false, false, false, true]).is_empty());
    }
}
