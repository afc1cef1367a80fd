//! The skin beyond the native breast that lies over the implant, and the volume it
//! sweeps.
//!
//! A pocket lets the implant reach beyond the native breast's cut curve: below the
//! native fold where the fold is lowered, and medially or laterally where the implant is
//! wider than the breast's base. After the operation the breast lies over the implant
//! there too (its new fold is the planned one), so the breast after surgery is measured
//! over the native breast and the chest skin over the implant (as the template lays it,
//! its rim mollified, above the planned fold). That skin lay on the chest before (it encloses no breast volume); the volume it adds is the
//! volume its triangles sweep from rest to their moved positions.

use crate::bed::ImplantBed;
use crate::placement::Anchor;
use crate::template::{FoldPlane, SmoothedThickness, laid_thickness_mm};
use glam::DVec3;
use mesh::TriMesh;
use rayon::prelude::*;

/// The triangles of `surface` (indices) whose corners all lie over the implant as its
/// template lays it: their feet on `bed` ([`ImplantBed::foot`]) lie where the template
/// lays off a positive thickness ([`laid_thickness_mm`]: the mollified `thickness`
/// anchored at `anchor`, above the planned `fold`).
pub fn triangles_over_implant(
    surface: &TriMesh,
    bed: &ImplantBed,
    anchor: &Anchor,
    thickness: &SmoothedThickness,
    fold: &FoldPlane,
) -> Vec<usize> {
    // A point over the implant lies within its reach along the bed (the bed's
    // parameters are lengths along it) and its height in front of the bed; the bound
    // only skips the feet of points that cannot be over it.
    let bound_mm = thickness.reach_mm() + anchor.shift_mm + REACH_MARGIN_MM;
    let over: Vec<bool> = (surface.positions.par_iter())
        .map(|&p| {
            p.distance(anchor.position) <= bound_mm
                && bed
                    .foot(p)
                    .is_some_and(|foot| laid_thickness_mm(thickness, fold, anchor, &foot) > 0.0)
        })
        .collect();
    (surface.triangles.iter().enumerate())
        .filter(|(_, t)| t.iter().all(|&v| over[v as usize]))
        .map(|(k, _)| k)
        .collect()
}

/// Added to the reach in [`triangles_over_implant`] (mm): the skin's height over the
/// bed beyond the shift, and the bed's curvature.
const REACH_MARGIN_MM: f64 = 60.0;

/// The closed prisms that `triangles` sweep from `rest` to `moved` (positions of the
/// same vertices, mm) as one outward triangle soup: each triangle moved, the triangle at
/// rest reversed, and the three quadrilaterals between its edges at rest and moved. A
/// quadrilateral is split along its diagonal from the edge's lower-numbered vertex at
/// rest to the other one moved ([`swept_quad`]), so the two triangles sharing an edge
/// cut it alike and their quadrilaterals cancel exactly: the soup's signed volume is
/// the volume the surface sweeps forwards (along its normals), whatever the origin, and
/// its boundary's quadrilaterals close it.
pub fn swept_prisms(rest: &[DVec3], moved: &[DVec3], triangles: &[[u32; 3]]) -> TriMesh {
    let (compact, used) = mesh::compact(triangles.iter().copied(), rest.len());
    let n = used.len() as u32;
    let positions: Vec<DVec3> = (used.iter().map(|&v| rest[v as usize]))
        .chain(used.iter().map(|&v| moved[v as usize]))
        .collect();
    let mut soup = Vec::with_capacity(compact.len() * 8);
    for &[a, b, c] in &compact {
        soup.push([a + n, b + n, c + n]);
        soup.push([a, c, b]);
        for (p, q) in [(a, b), (b, c), (c, a)] {
            // `used` keeps the first-use order; the split follows the original numbers
            let p_first = used[p as usize] < used[q as usize];
            soup.extend(swept_quad([p, q], [p + n, q + n], p_first));
        }
    }
    TriMesh::new(positions, soup)
}

/// The quadrilateral swept by the edge `rest[0] -> rest[1]` to `moved` (vertex indices),
/// as two triangles facing the way a surface walking the edge that way faces once
/// swept forwards: split along the diagonal from the first rest vertex to the second
/// moved one where `first_is_lower`, else from the second rest vertex to the first moved
/// one. Both walks of an edge (`p -> q` and `q -> p`) thus cut it along the same
/// diagonal.
pub fn swept_quad(rest: [u32; 2], moved: [u32; 2], first_is_lower: bool) -> [[u32; 3]; 2] {
    let ([p, q], [pm, qm]) = (rest, moved);
    if first_is_lower {
        [[p, q, qm], [p, qm, pm]]
    } else {
        [[p, q, pm], [q, qm, pm]]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Signed volume of a triangle soup (mm³), by the divergence theorem about the origin.
    fn soup_volume_mm3(soup: &TriMesh) -> f64 {
        (soup.triangles.iter())
            .map(|t| {
                let [a, b, c] = t.map(|v| soup.positions[v as usize]);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// A 10 x 6 mm rectangle in z = 0 facing +z, as two triangles.
    fn rectangle() -> (Vec<DVec3>, Vec<[u32; 3]>) {
        let positions = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::new(10.0, 6.0, 0.0),
            DVec3::new(0.0, 6.0, 0.0),
        ];
        (positions, vec![[0, 1, 2], [0, 2, 3]])
    }

    /// Lifted 3 mm along its normal and slid sideways, the rectangle sweeps a prism of
    /// its area times 3 mm (Cavalieri); exact up to round-off.
    #[test]
    fn a_lifted_rectangle_sweeps_its_area_times_the_lift() {
        let (rest, triangles) = rectangle();
        let moved: Vec<DVec3> = rest
            .iter()
            .map(|&p| p + DVec3::new(2.0, -1.0, 3.0))
            .collect();
        let volume = soup_volume_mm3(&swept_prisms(&rest, &moved, &triangles));
        assert!((volume - 180.0).abs() < 1e-9, "{volume}");
        // moved back behind the plane: negative
        let behind: Vec<DVec3> = rest.iter().map(|&p| p - DVec3::Z * 3.0).collect();
        let volume = soup_volume_mm3(&swept_prisms(&rest, &behind, &triangles));
        assert!((volume + 180.0).abs() < 1e-9, "{volume}");
    }

    /// Lifted by `z = x / 2` (a wedge up to 5 mm at `x = 10`), the rectangle sweeps the
    /// wedge's volume, 6 * 10 * 5 / 2 = 150 mm³, whatever the origin: exact, since the
    /// moved triangles are flat.
    #[test]
    fn a_tilted_lift_sweeps_the_wedge_under_it_wherever_the_origin() {
        let (rest, triangles) = rectangle();
        for offset in [DVec3::ZERO, DVec3::new(-300.0, 120.0, 55.0)] {
            let rest: Vec<DVec3> = rest.iter().map(|&p| p + offset).collect();
            let moved: Vec<DVec3> = (rest.iter())
                .map(|&p| p + DVec3::Z * ((p.x - offset.x) / 2.0))
                .collect();
            let volume = soup_volume_mm3(&swept_prisms(&rest, &moved, &triangles));
            assert!((volume - 150.0).abs() < 1e-9, "{volume} at {offset}");
        }
    }

    /// In a twisted sweep (each corner moved a different way, also within the plane) the
    /// quadrilaterals of the edge inside the rectangle cancel exactly, whichever way the
    /// rectangle is cut into triangles: the soup's volume equals that of the moved
    /// triangles, the reversed rest ones and the four boundary quadrilaterals alone,
    /// built here by hand.
    #[test]
    fn a_twisted_sweep_does_not_depend_on_the_triangulation() {
        let (rest, _) = rectangle();
        let moved: Vec<DVec3> = (rest.iter().enumerate())
            .map(|(k, &p)| {
                p + DVec3::new(0.7 * k as f64, -0.4 * (k * k) as f64, 2.0 + 0.5 * k as f64)
            })
            .collect();
        let cuts = [vec![[0, 1, 2], [0, 2, 3]], vec![[0, 1, 3], [1, 2, 3]]];
        let volumes: Vec<f64> = cuts
            .iter()
            .map(|triangles| soup_volume_mm3(&swept_prisms(&rest, &moved, triangles)))
            .collect();
        let boundary_only = |triangles: &[[u32; 3]]| {
            let mut soup = Vec::new();
            for &[a, b, c] in triangles {
                soup.push([a + 4, b + 4, c + 4]);
                soup.push([a, c, b]);
            }
            for (p, q) in [(0u32, 1u32), (1, 2), (2, 3), (3, 0)] {
                soup.extend(swept_quad([p, q], [p + 4, q + 4], p < q));
            }
            let positions = rest.iter().chain(&moved).copied().collect();
            soup_volume_mm3(&TriMesh::new(positions, soup))
        };
        for (triangles, volume) in cuts.iter().zip(&volumes) {
            let expected = boundary_only(triangles);
            assert!(
                (volume - expected).abs() < 1e-9,
                "{volume} against {expected}"
            );
        }
    }

    /// The soup is closed: every directed edge is matched by its reverse, so its volume
    /// is independent of the origin.
    #[test]
    fn the_swept_soup_is_closed() {
        let (rest, triangles) = rectangle();
        let moved: Vec<DVec3> = (rest.iter().enumerate())
            .map(|(k, &p)| p + DVec3::new(0.3 * k as f64, 0.1, 1.0 + k as f64))
            .collect();
        let soup = swept_prisms(&rest, &moved, &triangles);
        let mut edges = std::collections::HashMap::new();
        for t in &soup.triangles {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0i32) += 1;
                *edges.entry((t[(k + 1) % 3], t[k])).or_insert(0i32) -= 1;
            }
        }
        assert!(edges.values().all(|&c| c == 0));
    }

    /// A grid of `spacing_mm` squares over `[-half_mm, half_mm]²` at height `z_mm`,
    /// shifted by `offset_mm` in x and y.
    fn grid(half_mm: f64, spacing_mm: f64, offset_mm: f64, z_mm: f64) -> TriMesh {
        let n = (2.0 * half_mm / spacing_mm).round() as u32;
        let positions = (0..=n)
            .flat_map(|j| (0..=n).map(move |i| (i, j)))
            .map(|(i, j)| {
                let at = |k: u32| -half_mm + offset_mm + spacing_mm * k as f64;
                DVec3::new(at(i), at(j), z_mm)
            })
            .collect();
        let index = |i: u32, j: u32| j * (n + 1) + i;
        let triangles = (0..n)
            .flat_map(|j| (0..n).map(move |i| (i, j)))
            .flat_map(|(i, j)| {
                let (a, b) = (index(i, j), index(i + 1, j));
                let (c, d) = (index(i + 1, j + 1), index(i, j + 1));
                [[a, b, c], [a, c, d]]
            })
            .collect();
        TriMesh::new(positions, triangles)
    }

    /// A flat bed in z = 0 over x, y in [-100, 100] mm, its parameters (u, v) = (x, y) to
    /// within 1e-8 mm (a cylinder of radius 10⁵ mm about the y axis behind it).
    fn flat_bed() -> ImplantBed {
        let surface = grid(100.0, 5.0, 0.0, 0.0);
        let topology = mesh::Topology::new(&surface);
        let outer = topology.boundary_loops(&surface).remove(0);
        let (surface, boundary_count) = crate::pocket::boundary_first(&surface, &outer);
        let radius_mm = 1e5;
        let cylinder = crate::bed::ChestCylinder {
            centre: DVec3::new(0.0, 0.0, -radius_mm),
            axes: glam::DMat3::from_cols(DVec3::Z, DVec3::X, DVec3::Y),
            radius_mm,
        };
        ImplantBed::new(
            anatomy::breast::Side::Left,
            &surface,
            boundary_count,
            &cylinder,
            0.0,
        )
        .unwrap()
    }

    /// Skin 10 mm over a flat bed, under a round 120 mm implant anchored at the origin
    /// (rim not mollified) with the planned fold at y = -20 mm: exactly the triangles
    /// whose three corners lie inside the 60 mm circle and above the fold are over the
    /// implant, by the corners' own coordinates (no corner lies on either line: the
    /// grid's coordinates are odd multiples of 2.5 mm). With the fold far below, the
    /// circle alone decides.
    #[test]
    fn skin_under_the_planned_fold_is_not_over_the_implant() {
        let bed = flat_bed();
        let skin = grid(97.5, 5.0, 0.0, 10.0);
        let shape = implant::ImplantShape::from(implant::RoundImplant::new(120.0, 30.0).unwrap());
        let thickness = SmoothedThickness::new(shape, 0.0);
        let fold_at = |y_mm: f64| FoldPlane {
            point: DVec3::new(0.0, y_mm, 0.0),
            up: DVec3::Y,
            taper_mm: 5.0,
        };
        let expected = |fold_y_mm: f64| -> Vec<usize> {
            let inside = |v: u32| {
                let p = skin.positions[v as usize];
                p.x * p.x + p.y * p.y < 60.0 * 60.0 && p.y > fold_y_mm
            };
            (skin.triangles.iter().enumerate())
                .filter(|(_, t)| t.iter().all(|&v| inside(v)))
                .map(|(k, _)| k)
                .collect()
        };
        for fold_y_mm in [-20.0, -200.0] {
            let over = triangles_over_implant(
                &skin,
                &bed,
                &Anchor::flat(),
                &thickness,
                &fold_at(fold_y_mm),
            );
            assert_eq!(over, expected(fold_y_mm), "fold at {fold_y_mm} mm");
        }
        assert!(expected(-20.0).len() < expected(-200.0).len());
    }
}
