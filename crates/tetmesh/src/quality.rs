//! Shape measures of tetrahedra: signed volume and dihedral angles, per element and
//! over a mesh.

use crate::tetmesh::TetMesh;
use glam::DVec3;
use rayon::prelude::*;

/// Signed volume of the tetrahedron `p` (mm³): positive when `p[3]` lies on the side of
/// triangle `p[0], p[1], p[2]` its right-hand normal points to.
pub fn signed_volume(p: [DVec3; 4]) -> f64 {
    (p[1] - p[0]).dot((p[2] - p[0]).cross(p[3] - p[0])) / 6.0
}

/// The six dihedral angles of a tetrahedron (radians), at edges 01, 02, 03, 12, 13, 23.
/// A degenerate face gives NaN.
pub fn dihedral_angles(p: [DVec3; 4]) -> [f64; 6] {
    // Unit normal of the face opposite each vertex, pointing away from that vertex.
    let normal = |k: usize| {
        let [a, b, c] = [(k + 1) % 4, (k + 2) % 4, (k + 3) % 4].map(|i| p[i]);
        let n = (b - a).cross(c - a).normalize();
        if n.dot(p[k] - a) > 0.0 { -n } else { n }
    };
    let n = [normal(0), normal(1), normal(2), normal(3)];
    // The edge ij lies on the faces opposite the two other vertices k, l.
    let edges = [(2, 3), (1, 3), (1, 2), (0, 3), (0, 2), (0, 1)];
    edges.map(|(k, l)| (-n[k].dot(n[l])).clamp(-1.0, 1.0).acos())
}

/// Extreme shape measures of a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QualityReport {
    /// Smallest dihedral angle (degrees).
    pub min_dihedral_deg: f64,
    /// Largest dihedral angle (degrees).
    pub max_dihedral_deg: f64,
    /// Smallest signed volume (mm³); positive for a valid mesh.
    pub min_volume_mm3: f64,
}

/// The extreme dihedral angles and volume over all tetrahedra of `mesh` (NaN angles of
/// degenerate elements are ignored; `min_volume_mm3` shows them).
pub fn quality(mesh: &TetMesh) -> QualityReport {
    let identity = || (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY);
    let (lo, hi, volume) = (0..mesh.tets.len())
        .into_par_iter()
        .map(|t| {
            let p = mesh.tet_positions(t);
            let angles = dihedral_angles(p);
            (
                angles.iter().copied().fold(f64::INFINITY, f64::min),
                angles.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                signed_volume(p),
            )
        })
        .reduce(identity, |a, b| (a.0.min(b.0), a.1.max(b.1), a.2.min(b.2)));
    QualityReport {
        min_dihedral_deg: lo.to_degrees(),
        max_dihedral_deg: hi.to_degrees(),
        min_volume_mm3: volume,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn regular_and_corner_tetrahedra() {
        let regular = [
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(1.0, -1.0, -1.0),
            DVec3::new(-1.0, 1.0, -1.0),
            DVec3::new(-1.0, -1.0, 1.0),
        ];
        let expected = (1.0f64 / 3.0).acos();
        for angle in dihedral_angles(regular) {
            assert!((angle - expected).abs() < 1e-12);
        }
        assert!((signed_volume(regular).abs() - 8.0 / 3.0).abs() < 1e-12);
        let corner = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::Z];
        assert!((signed_volume(corner) - 1.0 / 6.0).abs() < 1e-15);
        let angles = dihedral_angles(corner).map(f64::to_degrees);
        // Edges 01, 02, 03 meet at right angles; the others at acos(1/√3)... 54.7356°.
        for a in &angles[..3] {
            assert!((a - 90.0).abs() < 1e-9, "{angles:?}");
        }
        for a in &angles[3..] {
            assert!((a - 54.735_610_317).abs() < 1e-6, "{angles:?}");
        }
    }
}
