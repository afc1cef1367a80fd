//! The breast skin the cameras did not see: which part of a breast patch lies on the
//! fill-ins that closed the scan's holes (the underside of a full or hanging breast, the
//! lateral fold), and how much area and volume rest on it.

use glam::DVec3;
use mesh::{CutMesh, Region, SurfaceIndex, Topology, TriMesh};

/// Default of [`super::BreastOptions::max_reconstructed_share`]: a breast whose skin is
/// more than half reconstructed is not a scan of that breast. A standing three-camera
/// scan of a full or hanging breast misses its underside, some 10 to 35% of its skin.
pub const DEFAULT_MAX_RECONSTRUCTED_SHARE: f64 = 0.5;

/// The reconstructed part of one breast patch.
#[derive(Debug, Clone, PartialEq)]
pub struct Reconstructed {
    /// Per triangle of the patch: it lies on a fill-in of the scan's holes.
    pub triangle_flags: Vec<bool>,
    /// Per vertex of the patch: it lies inside reconstructed skin (all its triangles are
    /// reconstructed; the rim of a filled hole is measured skin).
    pub vertex_flags: Vec<bool>,
    /// Area of the reconstructed triangles (mm²).
    pub area_mm2: f64,
    /// Their share of the patch's area (0..1).
    pub area_share: f64,
    /// The volume between the reconstructed skin and flat patches spanning each of its
    /// borders (ml): how much of the breast volume rests on the reconstruction rather
    /// than on the measured skin around it (negative where it lies inside the flat
    /// patches).
    pub volume_ml: f64,
}

impl Reconstructed {
    /// The reconstructed triangles of `patch` (the patch these flags were made for) as a
    /// mesh of their own, on the patch's vertices.
    pub fn skin(&self, patch: &TriMesh) -> TriMesh {
        TriMesh::new(
            patch.positions.clone(),
            patch
                .triangles
                .iter()
                .zip(&self.triangle_flags)
                .filter(|(_, flag)| **flag)
                .map(|(t, _)| *t)
                .collect(),
        )
    }
}

/// Per triangle of the part `region` of `cut` (in the order [`CutMesh::part`] gives):
/// whether it lies on a fill-in of the closed scan the cut was made on, whose first
/// `scan_triangles` of `closed_triangles` triangles are the scan's. A triangle the cut
/// left whole keeps its index; a piece of a split one is placed by its centroid's
/// nearest triangle on the closed scan (`closed_index`; `None`: no hole was closed).
pub fn reconstructed_triangles(
    cut: &CutMesh,
    region: Region,
    scan_triangles: usize,
    closed_triangles: usize,
    closed_index: Option<&SurfaceIndex>,
) -> Vec<bool> {
    (0..cut.mesh.triangle_count())
        .filter(|&t| cut.regions[t] == region)
        .map(|t| match closed_index {
            None => false,
            Some(_) if t < closed_triangles => t >= scan_triangles,
            Some(index) => {
                let centroid = cut.mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
                index.closest_point(centroid).triangle >= scan_triangles
            }
        })
        .collect()
}

/// The reconstructed part of `patch` from its triangles' flags
/// ([`reconstructed_triangles`]); a triangle without a flag counts as measured.
pub fn reconstructed_part(patch: &TriMesh, triangle_flags: Vec<bool>) -> Reconstructed {
    let area_mm2 = (0..patch.triangle_count())
        .filter(|&t| triangle_flags.get(t).copied().unwrap_or(false))
        .map(|t| patch.triangle_area(t))
        .sum::<f64>()
        + 0.0;
    let total_area = patch.area();
    let mut vertex_flags = vec![true; patch.vertex_count()];
    let mut touched = vec![false; patch.vertex_count()];
    for (t, corners) in patch.triangles.iter().enumerate() {
        for &v in corners {
            touched[v as usize] = true;
            vertex_flags[v as usize] &= triangle_flags.get(t).copied().unwrap_or(false);
        }
    }
    for (flag, touched) in vertex_flags.iter_mut().zip(&touched) {
        *flag &= *touched;
    }
    let volume_ml = volume_over_flat_caps(patch, &triangle_flags) / 1000.0 + 0.0;
    Reconstructed {
        vertex_flags,
        triangle_flags,
        area_mm2,
        area_share: if total_area > 0.0 {
            area_mm2 / total_area
        } else {
            0.0
        },
        volume_ml,
    }
}

/// The signed volume (mm³) enclosed by the flagged triangles of `mesh` closed with a fan
/// over each of their border loops (from the loop's centroid), positive where the
/// triangles (oriented outward) bulge outward beyond the fans.
fn volume_over_flat_caps(mesh: &TriMesh, flags: &[bool]) -> f64 {
    let triangles: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .zip(flags)
        .filter(|(_, flag)| **flag)
        .map(|(t, _)| *t)
        .collect();
    if triangles.is_empty() {
        return 0.0;
    }
    let mut part = TriMesh::new(mesh.positions.clone(), triangles);
    let directed: std::collections::HashSet<(u32, u32)> = part
        .triangles
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, c), (c, a)])
        .collect();
    let loops = Topology::new(&part).boundary_loops(&part);
    for boundary in loops {
        if boundary.len() < 3 {
            continue;
        }
        let centre = boundary
            .iter()
            .map(|&v| part.positions[v as usize])
            .sum::<DVec3>()
            / boundary.len() as f64;
        let c = part.positions.len() as u32;
        part.positions.push(centre);
        // The cap runs each border edge against the part's own direction of it.
        let along = directed.contains(&(boundary[0], boundary[1]));
        for k in 0..boundary.len() {
            let (a, b) = (boundary[k], boundary[(k + 1) % boundary.len()]);
            part.triangles
                .push(if along { [c, b, a] } else { [c, a, b] });
        }
    }
    part.signed_volume()
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::icosphere;

    /// A sphere's cap of height `c` closed by its flat disc has the volume
    /// pi c^2 (3 r - c) / 3: an analytic answer for the flat-cap volume. Tolerance 2%:
    /// the faceted sphere (2 mm edges) and the cap's jagged triangle border.
    #[test]
    fn a_spherical_cap_over_its_flat_disc_has_the_analytic_volume() {
        let radius = 50.0;
        let sphere = icosphere(radius, 5);
        let h = 0.4;
        let flags: Vec<bool> = (0..sphere.triangle_count())
            .map(|t| {
                let c = sphere.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
                c.z > h * radius
            })
            .collect();
        let cap_height = radius - h * radius;
        let expected =
            std::f64::consts::PI * cap_height * cap_height * (3.0 * radius - cap_height) / 3.0;
        let got = volume_over_flat_caps(&sphere, &flags);
        assert!(
            ((got - expected) / expected).abs() < 0.02,
            "{got} vs {expected}"
        );
    }

    #[test]
    fn no_closed_holes_means_nothing_reconstructed() {
        let sphere = icosphere(10.0, 2);
        let part = reconstructed_part(&sphere, vec![false; sphere.triangle_count()]);
        assert_eq!(part.area_mm2, 0.0);
        assert_eq!(part.volume_ml, 0.0);
        assert!(part.vertex_flags.iter().all(|f| !f));
    }
}
