//! The tetrahedral mesh type: positions and positively oriented tetrahedra, with volume,
//! boundary extraction and validation.

use crate::error::TetMeshError;
use crate::quality::{QualityReport, quality, signed_volume};
use glam::DVec3;
use mesh::TriMesh;
use rayon::prelude::*;

/// A tetrahedral mesh. Every tetrahedron `[a, b, c, d]` is positively oriented:
/// `(b - a) · ((c - a) × (d - a)) > 0`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TetMesh {
    /// Vertex positions (mm).
    pub positions: Vec<DVec3>,
    /// Vertex indices of each tetrahedron.
    pub tets: Vec<[u32; 4]>,
}

/// The faces of a tetrahedral mesh used by one tetrahedron only, as an outward-oriented
/// triangle surface.
#[derive(Debug, Clone)]
pub struct BoundarySurface {
    /// The boundary triangles over the boundary vertices only.
    pub mesh: TriMesh,
    /// For each vertex of `mesh`, its index in the tetrahedral mesh.
    pub tet_vertex: Vec<u32>,
}

/// The faces of a positively oriented tetrahedron `[0, 1, 2, 3]`, each with its normal
/// pointing out of the tetrahedron.
const OUTWARD_FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];

impl TetMesh {
    /// A mesh from tetrahedra over point keys `0..key_count`: the used keys are
    /// numbered in key order and placed at `position(key)` (mm); unused keys are dropped.
    pub fn compacted(
        mut tets: Vec<[u32; 4]>,
        key_count: usize,
        position: impl Fn(u32) -> DVec3 + Sync,
    ) -> TetMesh {
        let mut new_index = vec![u32::MAX; key_count];
        for tet in &tets {
            for &key in tet {
                new_index[key as usize] = 0;
            }
        }
        let mut used_keys = Vec::new();
        for (key, slot) in new_index.iter_mut().enumerate() {
            if *slot == 0 {
                *slot = used_keys.len() as u32;
                used_keys.push(key as u32);
            }
        }
        let positions = used_keys.par_iter().map(|&key| position(key)).collect();
        tets.par_iter_mut()
            .for_each(|tet| *tet = tet.map(|key| new_index[key as usize]));
        TetMesh { positions, tets }
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// Number of tetrahedra.
    pub fn tet_count(&self) -> usize {
        self.tets.len()
    }

    /// The corner positions of tetrahedron `t` (mm).
    #[inline]
    pub fn tet_positions(&self, t: usize) -> [DVec3; 4] {
        self.tets[t].map(|v| self.positions[v as usize])
    }

    /// Total volume (mm³): the sum of the signed element volumes.
    pub fn volume_mm3(&self) -> f64 {
        (0..self.tets.len())
            .into_par_iter()
            .map(|t| signed_volume(self.tet_positions(t)))
            .sum()
    }

    /// Smallest and largest dihedral angle and smallest volume.
    pub fn quality(&self) -> QualityReport {
        quality(self)
    }

    /// Axis-aligned bounding box `(lo, hi)` of the vertices (mm).
    pub fn bounding_box(&self) -> (DVec3, DVec3) {
        self.positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// The faces used by exactly one tetrahedron, oriented outward.
    pub fn boundary(&self) -> BoundarySurface {
        let mut faces: Vec<([u32; 3], [u32; 3])> = self
            .tets
            .par_iter()
            .flat_map_iter(|tet| {
                OUTWARD_FACES.iter().map(move |f| {
                    let face = f.map(|k| tet[k]);
                    let mut key = face;
                    key.sort_unstable();
                    (key, face)
                })
            })
            .collect();
        faces.par_sort_unstable_by_key(|&(key, _)| key);
        let once: Vec<[u32; 3]> = faces
            .chunk_by(|a, b| a.0 == b.0)
            .filter(|group| group.len() == 1)
            .map(|group| group[0].1)
            .collect();
        let (triangles, tet_vertex) = mesh::compact(once.into_iter(), self.positions.len());
        let positions = tet_vertex
            .iter()
            .map(|&v| self.positions[v as usize])
            .collect();
        BoundarySurface {
            mesh: TriMesh::new(positions, triangles),
            tet_vertex,
        }
    }

    /// Checks finite coordinates, indices in range, four distinct vertices and a
    /// positive volume for every tetrahedron; the first problem is returned.
    pub fn validate(&self) -> Result<(), TetMeshError> {
        self.validate_indices()?;
        let problem = |t: usize| {
            let volume = signed_volume(self.tet_positions(t));
            (volume.is_nan() || volume <= 0.0)
                .then(|| format!("volume {volume:e} mm³ is not positive"))
        };
        first_problem(self.tets.len(), problem)
    }

    /// Checks finite coordinates, indices in range and four distinct vertices per
    /// tetrahedron (not the orientation); the first problem is returned.
    pub fn validate_indices(&self) -> Result<(), TetMeshError> {
        if let Some((vertex, p)) = self
            .positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return Err(TetMeshError::NonFiniteVertex {
                vertex,
                position: p.to_array(),
            });
        }
        let n = self.positions.len();
        let problem = |t: usize| -> Option<String> {
            let tet = self.tets[t];
            if let Some(&v) = tet.iter().find(|&&v| v as usize >= n) {
                return Some(format!(
                    "vertex index {v} out of range (the mesh has {n} vertices)"
                ));
            }
            (0..4)
                .any(|i| (i + 1..4).any(|j| tet[i] == tet[j]))
                .then(|| format!("repeats a vertex: {tet:?}"))
        };
        first_problem(self.tets.len(), problem)
    }
}

/// The first of `count` tetrahedra for which `problem` says something, as an error.
fn first_problem(
    count: usize,
    problem: impl Fn(usize) -> Option<String> + Sync,
) -> Result<(), TetMeshError> {
    match (0..count)
        .into_par_iter()
        .find_first(|&t| problem(t).is_some())
    {
        Some(tet) => Err(TetMeshError::InvalidTetrahedron {
            tet,
            problem: problem(tet).unwrap_or_default(),
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_tets() -> TetMesh {
        TetMesh {
            positions: vec![
                DVec3::ZERO,
                DVec3::X,
                DVec3::Y,
                DVec3::Z,
                DVec3::new(1.0, 1.0, 1.0),
            ],
            tets: vec![[0, 1, 2, 3], [1, 2, 3, 4]],
        }
    }

    #[test]
    fn two_tetrahedra_share_one_face() {
        let mut mesh = two_tets();
        // Orient the second one positively.
        if signed_volume(mesh.tet_positions(1)) < 0.0 {
            mesh.tets[1].swap(2, 3);
        }
        mesh.validate().unwrap();
        assert!((mesh.volume_mm3() - (1.0 / 6.0 + 1.0 / 3.0)).abs() < 1e-12);
        let boundary = mesh.boundary();
        assert_eq!(boundary.mesh.triangle_count(), 6);
        assert_eq!(boundary.tet_vertex.len(), 5);
        assert!((boundary.mesh.signed_volume() - mesh.volume_mm3()).abs() < 1e-12);
    }

    #[test]
    fn inverted_and_out_of_range_tetrahedra_are_named() {
        let mut mesh = two_tets();
        mesh.tets[0].swap(0, 1);
        let message = mesh.validate().unwrap_err().to_string();
        assert!(message.starts_with("tetrahedron 0: volume"), "{message}");
        let mut mesh = two_tets();
        mesh.tets[1][3] = 9;
        let message = mesh.validate().unwrap_err().to_string();
        assert!(
            message.contains("tetrahedron 1: vertex index 9"),
            "{message}"
        );
    }
}
