//! How much of the implant's volume the finest mesh can carry: the implant's thickness
//! integrated over the part of the bed that the mesh's elements cross.
//!
//! Each fill-in element (one crossing the bed) meets the bed in a cross section, where
//! the linear interpolation of its corners' heights above the bed vanishes (a triangle or
//! a quadrilateral); these sections tile the bed as far as the mesh reaches. The implant
//! volume over a section is its area in implant coordinates times the mean thickness at
//! its corners. Summed, it is the implant's volume where the whole footprint lies within
//! the mesh, and less where the footprint reaches past a clip plane, where the scan ends
//! (docs/dev/volume-loss.md).

use crate::bed::Foot;
use crate::placement::Anchor;
use crate::template::SmoothedThickness;
use glam::DVec2;

/// The implant volume over the cross section of one element with the bed (mm³), from
/// the feet of its four corners; zero for an element that does not cross the bed.
pub fn bed_section_volume_mm3(
    feet: &[Foot; 4],
    anchor: &Anchor,
    thickness: &SmoothedThickness,
) -> f64 {
    let section = bed_section(feet, anchor);
    let n = section.len();
    if n < 3 {
        return 0.0;
    }
    let area = 0.5
        * (0..n)
            .map(|k| section[k].perp_dot(section[(k + 1) % n]))
            .sum::<f64>()
            .abs();
    let mean_thickness = section.iter().map(|&p| thickness.at(p)).sum::<f64>() / n as f64;
    area * mean_thickness
}

/// The corners of an element's cross section with the bed in implant coordinates, in
/// order round it (empty if the element does not cross the bed).
fn bed_section(feet: &[Foot; 4], anchor: &Anchor) -> Vec<DVec2> {
    let front: Vec<usize> = (0..4).filter(|&k| feet[k].height_mm > 0.0).collect();
    let back: Vec<usize> = (0..4).filter(|&k| feet[k].height_mm <= 0.0).collect();
    let crossing = |a: usize, b: usize| {
        let (ha, hb) = (feet[a].height_mm, feet[b].height_mm);
        anchor.local(feet[a].uv.lerp(feet[b].uv, ha / (ha - hb)))
    };
    match (front.as_slice(), back.as_slice()) {
        ([a], others) | (others, [a]) if others.len() == 3 => {
            others.iter().map(|&b| crossing(*a, b)).collect()
        }
        ([a, b], [c, d]) => vec![
            crossing(*a, *c),
            crossing(*a, *d),
            crossing(*b, *d),
            crossing(*b, *c),
        ],
        _ => Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DMat2, DVec3};

    /// A prism of three tetrahedra across the flat bed z = 0 over the triangle (0,0),
    /// (6,0), (0,6), from z = -2 to z = 4, at the centre of a 120 mm round implant: the
    /// sections tile the triangle, so together they carry the thickness integrated over
    /// it, here by a fine midpoint rule (20,000 cells). Within 1e-3 relative: the
    /// sections take the mean thickness at their corners, and the dome's thickness
    /// changes by a fraction of a millimetre over 6 mm.
    #[test]
    fn the_sections_of_a_prism_tile_its_base() {
        let anchor = Anchor {
            uv: DVec2::ZERO,
            position: DVec3::ZERO,
            normal: DVec3::Z,
            x_axis: DVec3::X,
            y_axis: DVec3::Y,
            to_local: DMat2::IDENTITY,
            to_uv: DMat2::IDENTITY,
            shift_mm: 0.0,
        };
        let shape = implant::ImplantShape::from(implant::RoundImplant::new(120.0, 10.0).unwrap());
        let thickness = SmoothedThickness::new(shape, 0.0);
        let base = [
            DVec2::new(0.0, 0.0),
            DVec2::new(6.0, 0.0),
            DVec2::new(0.0, 6.0),
        ];
        let bottom = base.map(|p| p.extend(-2.0));
        let top = base.map(|p| p.extend(4.0));
        let tets = [
            [bottom[0], bottom[1], bottom[2], top[0]],
            [bottom[1], bottom[2], top[0], top[1]],
            [bottom[2], top[0], top[1], top[2]],
        ];
        let volume: f64 = tets
            .iter()
            .map(|t| {
                let feet = t.map(|p| Foot {
                    uv: p.truncate(),
                    height_mm: p.z,
                    normal: DVec3::Z,
                });
                bed_section_volume_mm3(&feet, &anchor, &thickness)
            })
            .sum();
        let cells = 200;
        let h = 6.0 / cells as f64;
        let mut exact = 0.0;
        for i in 0..cells {
            for j in 0..cells - i {
                // the lower-left triangle of each square cell, and the upper-right one
                // where it lies inside
                let corner = DVec2::new(i as f64 * h, j as f64 * h);
                exact += 0.5 * h * h * thickness.at(corner + DVec2::splat(h / 3.0));
                if i + j + 1 < cells {
                    exact += 0.5 * h * h * thickness.at(corner + DVec2::splat(2.0 * h / 3.0));
                }
            }
        }
        assert!((volume - exact).abs() < 1e-3 * exact, "{volume} {exact}");
        // an element wholly in front of the bed carries nothing
        let above = top.map(|p| Foot {
            uv: p.truncate(),
            height_mm: 1.0,
            normal: DVec3::Z,
        });
        let above = [above[0], above[1], above[2], above[0]];
        assert_eq!(bed_section_volume_mm3(&above, &anchor, &thickness), 0.0);
    }
}
