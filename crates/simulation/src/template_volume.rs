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
use crate::template::{BedFeet, SmoothedThickness};
use glam::DVec2;
use rayon::prelude::*;

/// Whether a point at `height_mm` above the bed counts as in front of it; every other
/// point (a NaN height included) counts as behind.
pub(crate) fn in_front(height_mm: f64) -> bool {
    height_mm > 0.0
}

/// Where the edge from a corner in front of the bed (`front`) to one behind it (`back`)
/// meets the bed, in implant coordinates: where the linear interpolation of their
/// heights vanishes. Always taken from the front corner, so every element sharing the
/// edge gets the same point.
fn bed_crossing(front: &Foot, back: &Foot, anchor: &Anchor) -> DVec2 {
    let (h_front, h_back) = (front.height_mm, back.height_mm);
    anchor.local(front.uv.lerp(back.uv, h_front / (h_front - h_back)))
}

/// The implant volume over the cross section of one element with the bed (mm³), from
/// the heights of its four corners above the bed and `crossing(front, back)`: the bed
/// crossing ([`bed_crossing`]) on the edge from corner `front` (in front of the bed) to
/// corner `back` (behind it), with the implant's mollified thickness there. Zero for an
/// element that does not cross the bed.
fn bed_section_volume_mm3(
    heights_mm: [f64; 4],
    mut crossing: impl FnMut(usize, usize) -> (DVec2, f64),
) -> f64 {
    let mut front = [0; 4];
    let mut back = [0; 4];
    let (mut fronts, mut backs) = (0, 0);
    for (k, &h) in heights_mm.iter().enumerate() {
        if in_front(h) {
            front[fronts] = k;
            fronts += 1;
        } else {
            back[backs] = k;
            backs += 1;
        }
    }
    // the section's corners in order round it: a triangle or a quadrilateral
    let mut section = [(DVec2::ZERO, 0.0); 4];
    let n = match (fronts, backs) {
        (1, 3) => {
            for (corner, &b) in section.iter_mut().zip(&back[..3]) {
                *corner = crossing(front[0], b);
            }
            3
        }
        (3, 1) => {
            for (corner, &f) in section.iter_mut().zip(&front[..3]) {
                *corner = crossing(f, back[0]);
            }
            3
        }
        (2, 2) => {
            section = [
                crossing(front[0], back[0]),
                crossing(front[0], back[1]),
                crossing(front[1], back[1]),
                crossing(front[1], back[0]),
            ];
            4
        }
        _ => return 0.0,
    };
    let section = &section[..n];
    let area = 0.5
        * (0..n)
            .map(|k| section[k].0.perp_dot(section[(k + 1) % n].0))
            .sum::<f64>()
            .abs();
    let mean_thickness = section.iter().map(|&(_, z)| z).sum::<f64>() / n as f64;
    area * mean_thickness
}

/// The implant's volume over the bed sections of the fill-in elements `fill_in`
/// (element, corners as candidate indices into `feet`), in ml. A bed
/// crossing lies on an edge that several fill-in elements share: its point and mollified
/// thickness (the costly part) are computed once per edge, in parallel. The whole
/// implant, without the fold's share: the template is scaled to insert it all
/// (docs/dev/standing-frame.md).
pub fn covered_volume_ml(
    fill_in: &[(u32, [u32; 4])],
    feet: &BedFeet,
    anchor: &Anchor,
    thickness: &SmoothedThickness,
) -> f64 {
    let foot = |k: u32| feet.feet[k as usize];
    let front = |k: u32| foot(k).is_some_and(|f| in_front(f.height_mm));
    let behind = |k: u32| foot(k).is_some_and(|f| !in_front(f.height_mm));
    // every crossed edge of every element, keyed `front << 32 | back` (candidate
    // indices), with its slot `16 e + 4 front + back` (element `e`, local corners);
    // the same predicate as the section's, so every pair a section asks for is here
    let mut uses: Vec<(u64, usize)> = (fill_in.iter().enumerate())
        .flat_map(|(e, (_, corners))| {
            (0..16).filter_map(move |pair| {
                let (a, b) = (corners[pair / 4], corners[pair % 4]);
                let key = (u64::from(a) << 32) | u64::from(b);
                (front(a) && behind(b)).then_some((key, 16 * e + pair))
            })
        })
        .collect();
    uses.sort_unstable_by_key(|&(key, _)| key);
    let mut edges: Vec<(u32, u32)> = Vec::new();
    let mut edge_of_slot = vec![u32::MAX; 16 * fill_in.len()];
    let mut last_key = None;
    for &(key, slot) in &uses {
        if last_key != Some(key) {
            edges.push(((key >> 32) as u32, key as u32));
            last_key = Some(key);
        }
        edge_of_slot[slot] = (edges.len() - 1) as u32;
    }
    let crossings: Vec<(DVec2, f64)> = edges
        .par_iter()
        .map(|&(a, b)| match (foot(a), foot(b)) {
            (Some(front), Some(back)) => {
                let p = bed_crossing(&front, &back, anchor);
                (p, thickness.at(p))
            }
            _ => (DVec2::ZERO, 0.0),
        })
        .collect();
    (fill_in.iter().enumerate())
        .filter_map(|(e, (_, corners))| {
            let feet = corners.map(foot);
            let heights_mm = [feet[0]?, feet[1]?, feet[2]?, feet[3]?].map(|f| f.height_mm);
            // the section's crossings are the element's crossed edges, all in `uses`
            Some(bed_section_volume_mm3(heights_mm, |front, back| {
                crossings[edge_of_slot[16 * e + 4 * front + back] as usize]
            }))
        })
        .sum::<f64>()
        / 1000.0
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    /// A prism of three tetrahedra across the flat bed z = 0 over the triangle (0,0),
    /// (6,0), (0,6), from z = -2 to z = 4, at the centre of a 120 mm round implant: the
    /// sections tile the triangle, so together they carry the thickness integrated over
    /// it, here by a fine midpoint rule (20,000 cells). Within 1e-3 relative: the
    /// sections take the mean thickness at their corners, and the dome's thickness
    /// changes by a fraction of a millimetre over 6 mm.
    #[test]
    fn the_sections_of_a_prism_tile_its_base() {
        let anchor = Anchor::flat();
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
                    position: p.truncate().extend(0.0),
                });
                section_volume(&feet, &anchor, &thickness)
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
            position: p.truncate().extend(0.0),
        });
        let above = [above[0], above[1], above[2], above[0]];
        assert_eq!(section_volume(&above, &anchor, &thickness), 0.0);
    }

    /// A 4 x 4 grid of 6 mm squares, each split into two triangles and each triangle's
    /// prism from z = -2 to 4 into three tetrahedra as above, over the flat bed z = 0
    /// with one corner at the dome's centre: `covered_volume_ml`, which computes each crossing once
    /// per shared edge, equals the sum of the elements' own sections (to rounding: each
    /// crossing is the same point from either element) and the thickness integrated
    /// over the grid's 24 x 24 mm by a fine midpoint rule (1e-3, as above).
    #[test]
    fn the_covered_volume_shares_crossings_and_tiles_the_bed() {
        let anchor = Anchor::flat();
        let shape = implant::ImplantShape::from(implant::RoundImplant::new(120.0, 10.0).unwrap());
        let thickness = SmoothedThickness::new(shape, 0.0);
        let n = 4;
        let index = |i: usize, j: usize, top: bool| ((i * (n + 1) + j) * 2 + top as usize) as u32;
        let mut feet = vec![None; (n + 1) * (n + 1) * 2];
        for i in 0..=n {
            for j in 0..=n {
                for top in [false, true] {
                    let uv = DVec2::new(6.0 * i as f64, 6.0 * j as f64);
                    feet[index(i, j, top) as usize] = Some(Foot {
                        uv,
                        height_mm: if top { 4.0 } else { -2.0 },
                        normal: DVec3::Z,
                        position: uv.extend(0.0),
                    });
                }
            }
        }
        let mut fill_in = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for triangle in [
                    [(i, j), (i + 1, j), (i, j + 1)],
                    [(i + 1, j), (i + 1, j + 1), (i, j + 1)],
                ] {
                    let b = triangle.map(|(a, c)| index(a, c, false));
                    let t = triangle.map(|(a, c)| index(a, c, true));
                    for tet in [
                        [b[0], b[1], b[2], t[0]],
                        [b[1], b[2], t[0], t[1]],
                        [b[2], t[0], t[1], t[2]],
                    ] {
                        fill_in.push((fill_in.len() as u32, tet));
                    }
                }
            }
        }
        let feet = BedFeet {
            side: anatomy::breast::Side::Left,
            feet,
        };
        let covered = covered_volume_ml(&fill_in, &feet, &anchor, &thickness);
        let own: f64 = (fill_in.iter())
            .map(|(_, tet)| {
                let corners = tet.map(|k| feet.feet[k as usize].unwrap());
                section_volume(&corners, &anchor, &thickness)
            })
            .sum::<f64>()
            / 1000.0;
        assert!((covered - own).abs() < 1e-12 * own, "{covered} {own}");
        let cells = 480;
        let h = 24.0 / cells as f64;
        let exact_ml: f64 = (0..cells * cells)
            .map(|c| {
                let p = DVec2::new((c / cells) as f64 + 0.5, (c % cells) as f64 + 0.5) * h;
                h * h * thickness.at(p)
            })
            .sum::<f64>()
            / 1000.0;
        assert!(
            (covered - exact_ml).abs() < 1e-3 * exact_ml,
            "{covered} {exact_ml}"
        );
    }

    /// The implant's volume over the bed section of the element with `feet` (mm³), as
    /// `covered_volume_ml` takes it for each element.
    fn section_volume(feet: &[Foot; 4], anchor: &Anchor, thickness: &SmoothedThickness) -> f64 {
        bed_section_volume_mm3(feet.map(|f| f.height_mm), |front, back| {
            let p = bed_crossing(&feet[front], &feet[back], anchor);
            (p, thickness.at(p))
        })
    }
}
