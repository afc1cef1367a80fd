//! Clipping a surface to the box: triangles split exactly at the planes, the largest
//! piece kept, and its border loop split into the four sides.

use super::clip_box::{ClipBox, ClipPlane, PLANE_NAMES, planes_through};
use super::stitch::triangulate_in_plane;
use super::{ClosedSurfaceError, MIN_CLIPPED_TRIANGLES, SurfaceRole};
use crate::frame::AnatomicalFrame;
use crate::wall_clearance::{FixedAxes, keep_wall_clear};
use glam::DVec3;
use mesh::{Topology, TriMesh};
use std::collections::HashMap;

/// A vertex whose edge crosses a clip plane within this fraction of the mean edge length
/// of it (2% of an edge, about 0.05 mm on a scan) is moved along that edge onto the
/// crossing, so clipping leaves no sliver triangles.
const SNAP_FRACTION: f64 = 0.02;

/// One side of a clipped border: the plane index into [`ClipBox::planes`] and the
/// border vertices on it from corner to corner, in the scan's border direction.
pub(super) struct Side {
    pub(super) plane: usize,
    pub(super) chain: Vec<u32>,
}

/// A surface clipped to the box, in frame coordinates, with its single border loop.
pub(super) struct ClippedPart {
    role: SurfaceRole,
    planes: [ClipPlane; 4],
    frame: AnatomicalFrame,
    clip_box: ClipBox,
    /// In the box's coordinates ([`ClipBox::to_box`]).
    pub(super) positions: Vec<DVec3>,
    pub(super) triangles: Vec<[u32; 3]>,
    /// Border vertices in the direction of the triangles' edges.
    pub(super) border: Vec<u32>,
}

impl ClippedPart {
    pub(super) fn new(
        surface: &TriMesh,
        role: SurfaceRole,
        frame: &AnatomicalFrame,
        clip_box: &ClipBox,
    ) -> Result<ClippedPart, ClosedSurfaceError> {
        surface
            .validate()
            .map_err(|source| ClosedSurfaceError::InvalidMesh { role, source })?;
        let mut positions: Vec<DVec3> = surface
            .positions
            .iter()
            .map(|&p| clip_box.to_box(frame.to_local(p)))
            .collect();
        let mut triangles = surface.triangles.clone();
        let snap = SNAP_FRACTION * surface.mean_edge_length();
        let planes = clip_box.planes();
        for (k, plane) in planes.iter().enumerate() {
            snap_onto_crossings(&mut positions, &triangles, plane, &planes[..k], snap);
            triangles = clip_by_plane(&mut positions, &triangles, plane);
        }
        let (positions, triangles) = largest_piece(&positions, &triangles);
        if triangles.len() < MIN_CLIPPED_TRIANGLES {
            return Err(ClosedSurfaceError::TooFewTriangles {
                role,
                count: triangles.len(),
            });
        }
        let mut part = ClippedPart {
            role,
            planes,
            frame: *frame,
            clip_box: *clip_box,
            positions,
            triangles,
            border: Vec::new(),
        };
        part.cap_islands()?;
        part.border = part.single_border_loop()?;
        Ok(part)
    }

    fn to_file(&self, local: DVec3) -> [f64; 3] {
        self.frame
            .to_file(self.clip_box.box_to_local(local))
            .to_array()
    }

    /// Pushes this part's vertices (a wall) that lie less than `clearance_mm` behind
    /// `scan` (or in front of it) further in ([`keep_wall_clear`]); border vertices stay
    /// on their planes. Returns how many are still too close.
    pub(super) fn keep_clear_of(&mut self, scan: &ClippedPart, clearance_mm: f64) -> usize {
        let scan_mesh = TriMesh::new(scan.positions.clone(), scan.triangles.clone());
        let mut wall = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let fixed: Vec<FixedAxes> = (0..self.positions.len() as u32)
            .map(|v| {
                let mask = self.plane_mask(v);
                let on_axis = |axis: usize| {
                    self.planes
                        .iter()
                        .enumerate()
                        .any(|(i, plane)| plane.axis == axis && mask & (1 << i) != 0)
                };
                FixedAxes {
                    x: on_axis(0),
                    y: on_axis(1),
                }
            })
            .collect();
        let done = keep_wall_clear(&scan_mesh, &mut wall, &fixed, clearance_mm);
        self.positions = wall.positions;
        done.still_too_close
    }

    /// Bit `i` set if vertex `v` lies on plane `i`.
    fn plane_mask(&self, v: u32) -> u8 {
        planes_through(self.positions[v as usize], &self.planes)
    }

    /// Closes the holes a plane leaves where it grazes the surface: where a bump (a
    /// breast's lateral side, say) pokes through a plane by a little, clipping cuts its
    /// tip off and leaves a small border cycle lying entirely on that plane, apart from
    /// the main border or touching it at a vertex. The tip is replaced by its section, a
    /// flat cap on the plane (a constrained Delaunay triangulation of the cycle), as
    /// clipping a solid does. The cycle must enclose material (the skin's inside, behind
    /// the scan or in front of the filled base), so the cap faces out of the box; a
    /// cycle around air (a pocket) is an error.
    fn cap_islands(&mut self) -> Result<(), ClosedSurfaceError> {
        let mesh = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let loops = Topology::new(&mesh).boundary_loops(&mesh);
        // +1 if the triangles face away from the material: an anterior-facing scan, or
        // a posterior-facing base.
        let faces_anteriorly = self.anterior_area() > 0.0;
        let away_from_material = match (self.role, faces_anteriorly) {
            (SurfaceRole::Scan, true) | (SurfaceRole::FilledBase, false) => 1.0,
            _ => -1.0,
        };
        let mut caps = Vec::new();
        for island in loops.iter().flat_map(|walk| simple_cycles(walk)) {
            let on_all = island
                .iter()
                .fold(0b1111u8, |mask, &v| mask & self.plane_mask(v));
            if on_all == 0 || island.len() < 3 {
                continue;
            }
            let plane = on_all.trailing_zeros() as usize;
            let name = PLANE_NAMES[plane];
            let cap = triangulate_in_plane(&self.positions, plane, &island).map_err(|defect| {
                ClosedSurfaceError::Stitch {
                    what: format!(
                        "where the {} grazes the {name} plane, its section {}",
                        self.role,
                        defect.describe("crosses itself", "touches itself")
                    ),
                    near_mm: defect.at().map(|at| self.to_file(at)),
                }
            })?;
            let clip = self.planes[plane];
            let normal: f64 = cap
                .iter()
                .map(|tri| {
                    let [a, b, c] = tri.map(|v| self.positions[v as usize]);
                    (b - a).cross(c - a)[clip.axis]
                })
                .sum();
            // Towards the clipped-away side, as the triangles face.
            let out_of_box = if clip.keep_above { -normal } else { normal };
            if out_of_box * away_from_material <= 0.0 {
                let center = island
                    .iter()
                    .map(|&v| self.positions[v as usize])
                    .sum::<DVec3>()
                    / island.len() as f64;
                return Err(ClosedSurfaceError::Stitch {
                    what: format!(
                        "the {} passes through the {name} plane around a pocket of air; \
                         move the plane",
                        self.role
                    ),
                    near_mm: Some(self.to_file(center)),
                });
            }
            caps.extend(cap);
        }
        self.triangles.extend(caps);
        Ok(())
    }

    /// The border loop, which must be the only one and lie on the planes.
    fn single_border_loop(&self) -> Result<Vec<u32>, ClosedSurfaceError> {
        let mesh = TriMesh::new(self.positions.clone(), self.triangles.clone());
        let loops = Topology::new(&mesh).boundary_loops(&mesh);
        let role = self.role;
        if let Some(hole) = loops
            .iter()
            .find(|l| l.iter().all(|&v| self.plane_mask(v) == 0))
        {
            let center = hole
                .iter()
                .map(|&v| self.positions[v as usize])
                .sum::<DVec3>()
                / hole.len() as f64;
            return Err(ClosedSurfaceError::HoleInsideBox {
                role,
                vertices: hole.len(),
                center_mm: self.to_file(center),
            });
        }
        // Every border edge must lie on one plane.
        for border in &loops {
            for (k, &a) in border.iter().enumerate() {
                let b = border[(k + 1) % border.len()];
                if self.plane_mask(a) & self.plane_mask(b) == 0 {
                    let middle = 0.5 * (self.positions[a as usize] + self.positions[b as usize]);
                    return Err(ClosedSurfaceError::RunsOffBorder {
                        role,
                        near_mm: self.to_file(middle),
                    });
                }
            }
        }
        match <[Vec<u32>; 1]>::try_from(loops) {
            Ok([border]) => Ok(border),
            Err(loops) => {
                // The stray loop is the shortest one (none: the part has no border).
                let stray = loops
                    .iter()
                    .filter(|l| !l.is_empty())
                    .min_by_key(|l| l.len());
                let centre = |border: &Vec<u32>| {
                    let sum: DVec3 = border.iter().map(|&v| self.positions[v as usize]).sum();
                    self.to_file(sum / border.len() as f64)
                };
                Err(ClosedSurfaceError::Stitch {
                    what: format!(
                        "the clipped {role} has {} border loops on the planes instead of one",
                        loops.len()
                    ),
                    near_mm: stray.map(centre),
                })
            }
        }
    }

    /// Reverses the orientation of the triangles and of the border.
    pub(super) fn reverse(&mut self) {
        for tri in &mut self.triangles {
            tri.swap(1, 2);
        }
        self.border.reverse();
    }

    /// Twice the area of the surface projected on the coronal plane, signed positive
    /// where the triangles face anteriorly (mm²).
    pub(super) fn anterior_area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|tri| {
                let [a, b, c] = tri.map(|v| self.positions[v as usize]);
                (b - a).cross(c - a).z
            })
            .sum()
    }

    /// Twice the signed area of the border projected on the coronal plane.
    pub(super) fn winding(&self) -> f64 {
        let n = self.border.len();
        (0..n)
            .map(|k| {
                let a = self.positions[self.border[k] as usize];
                let b = self.positions[self.border[(k + 1) % n] as usize];
                a.x * b.y - b.x * a.y
            })
            .sum()
    }

    /// The error for a border without one corner on each edge of the box: the first
    /// edge met other than once, and where (the corners there, or the border's point
    /// nearest the edge).
    fn corner_error(&self) -> ClosedSurfaceError {
        // The box's edges as pairs of planes, and their names.
        const EDGES: [(u8, &str, &str); 4] = [
            (0b0101, "right", "bottom"),
            (0b0110, "left", "bottom"),
            (0b1010, "left", "top"),
            (0b1001, "right", "top"),
        ];
        let on_edge = |mask: u8| -> Vec<DVec3> {
            (self.border.iter())
                .filter(|&&v| self.plane_mask(v) == mask)
                .map(|&v| self.positions[v as usize])
                .collect()
        };
        let (mask, side, end, corners) = EDGES
            .iter()
            .map(|&(mask, side, end)| (mask, side, end, on_edge(mask)))
            .find(|edge| edge.3.len() != 1)
            .unwrap_or_else(|| (EDGES[0].0, EDGES[0].1, EDGES[0].2, on_edge(EDGES[0].0)));
        let near = if corners.is_empty() {
            let off_edge = |p: DVec3| -> f64 {
                (self.planes.iter().enumerate())
                    .filter(|(i, _)| mask & (1 << i) != 0)
                    .map(|(_, plane)| plane.distance(p).abs())
                    .sum()
            };
            (self.border.iter())
                .map(|&v| self.positions[v as usize])
                .min_by(|a, b| off_edge(*a).total_cmp(&off_edge(*b)))
                .unwrap_or_default()
        } else {
            corners.iter().sum::<DVec3>() / corners.len() as f64
        };
        ClosedSurfaceError::MissingCorners {
            role: self.role,
            side,
            end,
            count: corners.len(),
            near_mm: self.to_file(near),
        }
    }

    /// The border split at its four corners, in [`ClipBox::planes`] order.
    pub(super) fn sides(&self) -> Result<[Side; 4], ClosedSurfaceError> {
        let is_corner = |v: u32| self.plane_mask(v).count_ones() == 2;
        let corners = self.border.iter().filter(|&&v| is_corner(v)).count();
        let missing = self.corner_error();
        let Some(start) = self.border.iter().position(|&v| is_corner(v)) else {
            return Err(missing);
        };
        if corners != 4 {
            return Err(missing);
        }
        let n = self.border.len();
        let mut sides: [Option<Side>; 4] = Default::default();
        let mut chain = vec![self.border[start]];
        for k in 1..=n {
            let v = self.border[(start + k) % n];
            chain.push(v);
            if is_corner(v) {
                let common = self.plane_mask(chain[0]) & self.plane_mask(chain[1]);
                let plane = common.trailing_zeros() as usize;
                if chain
                    .windows(2)
                    .any(|w| self.plane_mask(w[0]) & self.plane_mask(w[1]) & common == 0)
                    || plane >= 4
                    || sides[plane].is_some()
                {
                    return Err(missing);
                }
                sides[plane] = Some(Side {
                    plane,
                    chain: std::mem::replace(&mut chain, vec![v]),
                });
            }
        }
        let [Some(a), Some(b), Some(c), Some(d)] = sides else {
            return Err(missing);
        };
        Ok([a, b, c, d])
    }
}

/// A closed walk (the last vertex followed by the first) split at its repeated
/// vertices into simple cycles, each in walk order: `[a, b, c, d, b, e]` gives
/// `[b, c, d]` and `[a, b, e]`.
pub(super) fn simple_cycles(walk: &[u32]) -> Vec<Vec<u32>> {
    let mut cycles = Vec::new();
    let mut stack: Vec<u32> = Vec::with_capacity(walk.len());
    let mut position: HashMap<u32, usize> = HashMap::new();
    for &v in walk {
        if let Some(&at) = position.get(&v) {
            let cycle: Vec<u32> = stack.drain(at..).collect();
            for u in &cycle {
                position.remove(u);
            }
            cycles.push(cycle);
        }
        position.insert(v, stack.len());
        stack.push(v);
    }
    if !stack.is_empty() {
        cycles.push(stack);
    }
    cycles
}

/// Moves each vertex of `triangles` that has an edge crossing `plane` within `snap_mm`
/// of it to that crossing, the nearest first, so no clipped piece of an edge is shorter
/// than `snap_mm` where it can be helped. Every point of the clipped border is then a
/// crossing of one of the surface's edges, in order along its section by the plane:
/// moving a vertex straight onto the plane instead would put it off the section by
/// `snap_mm` over the tangent of the angle between surface and plane, and where they
/// meet at a grazing angle the border would zigzag and could cross itself. A vertex on
/// one of `earlier` planes moves only along an edge lying on that plane too, so the
/// borders clipped so far stay on their planes; a move that would turn one of the
/// vertex's triangles over is not made (the edge is then split a little way from it).
fn snap_onto_crossings(
    positions: &mut [DVec3],
    triangles: &[[u32; 3]],
    plane: &ClipPlane,
    earlier: &[ClipPlane],
    snap_mm: f64,
) {
    // The distance along edge (v, w) from v to where it crosses the plane, if it does
    // within the snap and v may move along it.
    let crossing = |positions: &[DVec3], v: u32, w: u32| {
        let (p, q) = (positions[v as usize], positions[w as usize]);
        let (dp, dq) = (plane.distance(p), plane.distance(q));
        let crosses = (dp > 0.0 && dq < 0.0) || (dp < 0.0 && dq > 0.0);
        let along_mm = dp / (dp - dq) * p.distance(q);
        let stays_on_planes = planes_through(p, earlier) & !planes_through(q, earlier) == 0;
        (crosses && along_mm <= snap_mm && stays_on_planes).then_some(along_mm)
    };
    let mut candidates: Vec<(f64, u32, u32)> = triangles
        .iter()
        .flat_map(|&[a, b, c]| [(a, b), (b, a), (b, c), (c, b), (c, a), (a, c)])
        .filter(|&(v, _)| plane.distance(positions[v as usize]).abs() <= snap_mm)
        .filter_map(|(v, w)| crossing(positions, v, w).map(|along| (along, v, w)))
        .collect();
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0).then((x.1, x.2).cmp(&(y.1, y.2))));
    candidates.dedup_by(|x, y| (x.1, x.2) == (y.1, y.2));
    let mut star: HashMap<u32, Vec<usize>> = HashMap::new();
    for &(_, v, _) in &candidates {
        star.entry(v).or_default();
    }
    for (t, tri) in triangles.iter().enumerate() {
        for v in tri {
            if let Some(around) = star.get_mut(v) {
                around.push(t);
            }
        }
    }
    // A vertex moved onto the plane crosses it no longer, so each moves at most once and
    // never onto the crossing a neighbour has taken.
    for (_, v, w) in candidates {
        if crossing(positions, v, w).is_none() {
            continue;
        }
        let moved = plane.crossing(positions[v as usize], positions[w as usize]);
        let normal_with = |positions: &[DVec3], t: usize, at: DVec3| {
            let [a, b, c] = triangles[t].map(|u| if u == v { at } else { positions[u as usize] });
            (b - a).cross(c - a)
        };
        let keeps_facing = star[&v].iter().all(|&t| {
            let before = normal_with(positions, t, positions[v as usize]);
            normal_with(positions, t, moved).dot(before) > 0.0
        });
        if keeps_facing {
            positions[v as usize] = moved;
        }
    }
}

/// Triangles of `triangles` clipped to the kept side of `plane`. Crossed edges are split
/// at the plane, each edge once (new vertices are appended to `positions`), so the
/// result stays connected.
fn clip_by_plane(
    positions: &mut Vec<DVec3>,
    triangles: &[[u32; 3]],
    plane: &ClipPlane,
) -> Vec<[u32; 3]> {
    let mut split_vertices: HashMap<(u32, u32), u32> = HashMap::new();
    let mut clipped = Vec::with_capacity(triangles.len());
    for tri in triangles {
        let d = tri.map(|v| plane.distance(positions[v as usize]));
        if d.iter().all(|&x| x >= 0.0) {
            if d.iter().any(|&x| x > 0.0) {
                clipped.push(*tri);
            }
            continue;
        }
        if d.iter().all(|&x| x <= 0.0) {
            continue;
        }
        // Sutherland-Hodgman on one triangle: three or four corners, orientation kept.
        let mut polygon: Vec<u32> = Vec::with_capacity(4);
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            let (da, db) = (d[k], d[(k + 1) % 3]);
            if da >= 0.0 {
                polygon.push(a);
            }
            if (da > 0.0 && db < 0.0) || (da < 0.0 && db > 0.0) {
                let key = (a.min(b), a.max(b));
                let v = *split_vertices.entry(key).or_insert_with(|| {
                    let (p, q) = (positions[key.0 as usize], positions[key.1 as usize]);
                    positions.push(plane.crossing(p, q));
                    (positions.len() - 1) as u32
                });
                polygon.push(v);
            }
        }
        match polygon[..] {
            [a, b, c] => clipped.push([a, b, c]),
            [a, b, c, e] => {
                let at = |v: u32| positions[v as usize];
                // The shorter diagonal gives the better pair of triangles.
                if at(a).distance_squared(at(c)) <= at(b).distance_squared(at(e)) {
                    clipped.extend([[a, b, c], [a, c, e]]);
                } else {
                    clipped.extend([[a, b, e], [b, c, e]]);
                }
            }
            _ => {}
        }
    }
    clipped
}

/// The component with the most triangles, of `count` components numbered per triangle
/// in `component` (as [`Topology::triangle_components_among`] gives them, `u32::MAX`
/// for a triangle in none); 0 if none.
pub(super) fn largest_component(component: &[u32], count: usize) -> u32 {
    let mut sizes = vec![0usize; count];
    for &c in component {
        if let Some(size) = sizes.get_mut(c as usize) {
            *size += 1;
        }
    }
    (0..count).max_by_key(|&c| sizes[c]).unwrap_or(0) as u32
}

/// The connected piece (through edges) with the most triangles, its vertices renumbered
/// without unused ones.
fn largest_piece(positions: &[DVec3], triangles: &[[u32; 3]]) -> (Vec<DVec3>, Vec<[u32; 3]>) {
    let mesh = TriMesh::new(positions.to_vec(), triangles.to_vec());
    let (component, count) = Topology::new(&mesh).triangle_components();
    let largest = largest_component(&component, count);
    let kept: Vec<[u32; 3]> = (triangles.iter().zip(&component))
        .filter(|&(_, &c)| c == largest)
        .map(|(tri, _)| *tri)
        .collect();
    let piece = TriMesh::from_used_vertices(positions, &kept);
    (piece.positions, piece.triangles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::grid;

    /// A flat 40 x 40 mm sheet on a 2 mm grid, tilted 5 degrees off the plane x = 0
    /// about the y axis (u along the grid's x): (u sin 5°, y, u cos 5°).
    fn grazing_sheet() -> TriMesh {
        let tilt = 5f64.to_radians();
        let mut sheet = grid(20, 20, 2.0);
        sheet.map_positions(|p| DVec3::new(p.x * tilt.sin(), p.y, p.x * tilt.cos()));
        sheet
    }

    /// Clips `sheet` by `planes` in turn and returns the kept triangles.
    fn clip_all(sheet: &TriMesh, planes: &[ClipPlane]) -> TriMesh {
        let mut positions = sheet.positions.clone();
        let mut triangles = sheet.triangles.clone();
        let snap = SNAP_FRACTION * sheet.mean_edge_length();
        for (k, plane) in planes.iter().enumerate() {
            snap_onto_crossings(&mut positions, &triangles, plane, &planes[..k], snap);
            triangles = clip_by_plane(&mut positions, &triangles, plane);
        }
        TriMesh::from_used_vertices(&positions, &triangles)
    }

    /// Clips the sheet at u = `section_u` (a plane of constant x, keeping larger u) and
    /// returns the kept triangles' area and the vertices on the plane.
    fn clip_sheet_at(section_u: f64) -> (f64, Vec<DVec3>) {
        let tilt = 5f64.to_radians();
        let sheet = grazing_sheet();
        let plane = ClipPlane {
            axis: 0,
            value: section_u * tilt.sin(),
            keep_above: true,
        };
        let clipped = clip_all(&sheet, &[plane]);
        let area: f64 = (0..clipped.triangle_count())
            .map(|t| {
                let [a, b, c] = clipped.triangle_positions(t);
                0.5 * (b - a).cross(c - a).length()
            })
            .sum();
        let on_plane = clipped
            .positions
            .iter()
            .filter(|p| p.x == plane.value)
            .copied()
            .collect();
        (area, on_plane)
    }

    /// Where a plane meets the surface at a grazing angle, the clipped border must lie on
    /// the surface's section. A column of vertices 0.3 mm (in u) short of the section is
    /// within the snap distance of the plane in x (0.026 mm) but 0.3 mm from it along the
    /// sheet: moving it straight onto the plane would leave it 0.3 mm off the section.
    /// A column 0.03 mm short of it is moved onto the section along its nearest crossing
    /// edges, the grid's rows (keeping its rows' heights), not the diagonals. The kept
    /// area is that of the sheet beyond the section, 40 mm x (40 mm - u); vertices moved
    /// within a flat sheet change no area, so the checks hold to rounding (1e-9).
    #[test]
    fn a_grazing_plane_leaves_the_border_on_the_exact_section() {
        let tilt = 5f64.to_radians();
        // The 0.3 mm case splits the 21 rows' edges and the 20 diagonals; in the 0.03 mm
        // case the moved column is the border.
        for (section_u, border_vertices) in [(20.3, 41), (20.03, 21)] {
            let rows_kept = clip_sheet_at(section_u).1.iter().all(|p| p.y % 2.0 == 0.0);
            assert_eq!(rows_kept, section_u == 20.03, "u {section_u}");
            let (area, on_plane) = clip_sheet_at(section_u);
            let expected = 40.0 * (40.0 - section_u);
            assert!(
                (area - expected).abs() < 1e-9 * expected,
                "u {section_u}: area {area} mm², expected {expected}"
            );
            assert_eq!(on_plane.len(), border_vertices, "u {section_u}");
            let section_z = section_u * tilt.cos();
            for p in on_plane {
                assert!(
                    (p.z - section_z).abs() < 1e-9,
                    "u {section_u}: border vertex at depth {} mm, the section is at {section_z}",
                    p.z
                );
            }
        }
    }

    /// A vertex on an earlier plane's border moves along that border only. On the sheet
    /// z = 2 (y - x), clipped at x = 10.3 and then at y = 4.02, the border vertex at
    /// y = 4 is 0.045 mm from the second plane along the border but 0.027 mm along an
    /// inner edge; moved along the inner edge it would leave the first plane and the
    /// corner would be lost. The one corner must lie where both planes cut the sheet.
    #[test]
    fn a_vertex_on_a_clipped_border_stays_on_it() {
        let mut sheet = grid(20, 20, 2.0);
        sheet.map_positions(|p| DVec3::new(p.x, p.y, 2.0 * (p.y - p.x)));
        let planes = [
            ClipPlane {
                axis: 0,
                value: 10.3,
                keep_above: true,
            },
            ClipPlane {
                axis: 1,
                value: 4.02,
                keep_above: true,
            },
        ];
        let clipped = clip_all(&sheet, &planes);
        let corners: Vec<DVec3> = clipped
            .positions
            .iter()
            .filter(|p| planes_through(**p, &planes) == 0b11)
            .copied()
            .collect();
        assert_eq!(corners.len(), 1, "corners {corners:?}");
        let expected_z = 2.0 * (4.02 - 10.3);
        assert!((corners[0].z - expected_z).abs() < 1e-9, "{}", corners[0]);
    }

    /// A border that meets the box's left-bottom edge three times (running level with
    /// the bottom there, as a torso's side can) is an error naming that edge, placed at
    /// the mean of its three corners. Box 0-10 mm in x and y; the border's vertices in
    /// order, the wiggle at x = 10, y = 0 set apart in depth.
    #[test]
    fn extra_corners_are_an_error_placed_at_their_edge() {
        let clip_box = ClipBox {
            x_min_mm: 0.0,
            x_max_mm: 10.0,
            y_min_mm: 0.0,
            y_max_mm: 10.0,
            ..ClipBox::default()
        };
        let positions = [
            [0.0, 0.0, 0.0],
            [5.0, 0.0, 0.0],
            [10.0, 0.0, 0.0],
            [10.0, 0.5, 1.0],
            [10.0, 0.0, 2.0],
            [9.0, 0.0, 3.0],
            [10.0, 0.0, 4.0],
            [10.0, 5.0, 4.0],
            [10.0, 10.0, 4.0],
            [0.0, 10.0, 4.0],
            [0.0, 5.0, 2.0],
        ]
        .map(DVec3::from_array)
        .to_vec();
        let part = ClippedPart {
            role: SurfaceRole::Scan,
            planes: clip_box.planes(),
            frame: crate::closed_surface::tests::identity_frame(),
            clip_box,
            border: (0..positions.len() as u32).collect(),
            positions,
            triangles: Vec::new(),
        };
        let Err(error) = part.sides() else {
            panic!("three corners on one edge were accepted");
        };
        let ClosedSurfaceError::MissingCorners {
            side,
            end,
            count,
            near_mm,
            ..
        } = error
        else {
            panic!("{error}");
        };
        assert_eq!((side, end, count), ("left", "bottom", 3));
        assert_eq!(near_mm, [10.0, 0.0, 2.0]);
    }
}
