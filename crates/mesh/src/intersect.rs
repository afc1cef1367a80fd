//! Checks a closed surface must pass before it is tetrahedralised: self-intersecting
//! triangles ([`self_intersections`]) and watertightness ([`manifold_report`]).
//!
//! # Self-intersections
//! Broad phase: every triangle's bounding box is entered into the cells of a uniform
//! grid (cell size three times the mean box extent); pairs in a cell whose boxes overlap are
//! tested once, in the cell that holds the lower corner of their boxes' overlap. Cells
//! are processed in parallel. A triangle spanning very many cells (a huge triangle in
//! an otherwise fine mesh) is kept out of the grid and tested against the triangles in
//! the cells under its box, and against the other huge ones.
//!
//! Narrow phase, with `tol` = [`RELATIVE_TOLERANCE`] × the mesh's bounding-box diagonal:
//! - no shared vertex: two triangles meet iff an edge of one meets the other (their
//!   intersection is a segment whose ends lie on edges; coplanar triangles included);
//! - one shared vertex `s`: they meet beyond `s` iff the edge opposite `s` of one meets
//!   the other (both intersections with the line of the planes start at `s`; the
//!   shorter one ends on an opposite edge inside the other triangle);
//! - a shared edge: only a fold-over counts, the third corners (nearly) coplanar and
//!   on the same side of the edge;
//! - three shared vertices: a duplicate triangle, always reported.
//!
//! Contact counts as intersection: a point within `tol` of the other triangle, e.g. two
//! triangles touching along an edge without sharing its vertices, is reported. Triangles
//! with a height below `tol` (degenerate) or with an out-of-range index are skipped.

use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::TriMesh;
use glam::DVec3;
use rayon::prelude::*;

/// Narrow-phase tolerance relative to the bounding-box diagonal: far above the round-off
/// of the plane distances (about 1e-15 relative), far below any real feature
/// (5e-7 mm on a 500 mm scan).
pub const RELATIVE_TOLERANCE: f64 = 1e-9;
/// Broad-phase cell size as a multiple of the mean triangle bounding-box extent: a
/// triangle of mean size falls into one to eight cells (the choice is measured in
/// docs/dev/model-on-every-body.md).
const CELL_SIZE_FACTOR: f64 = 3.0;
/// Grid cells per axis at most: a key packs three 21-bit cell coordinates into a `u64`.
const MAX_CELLS_PER_AXIS: u64 = (1 << 21) - 1;
/// A triangle covering more cells than this is kept out of the grid and tested against
/// the triangles in the cells under its box.
const MAX_CELLS_PER_TRIANGLE: u64 = 512;

/// A triangle prepared for the tests.
struct Prepared {
    corners: [DVec3; 3],
    vertices: [u32; 3],
    /// Unit normal.
    normal: DVec3,
    /// `normal · corner` for any corner.
    offset: f64,
    /// In-plane unit normals of the edges (edge `k` from corner `k` to `k + 1`),
    /// pointing into the triangle.
    edge_normals: [DVec3; 3],
    lo: DVec3,
    hi: DVec3,
}

impl Prepared {
    /// `None` for a triangle with an index out of range or a height below `tol`.
    fn new(mesh: &TriMesh, vertices: [u32; 3], tol: f64) -> Option<Prepared> {
        let corner = |v: u32| mesh.positions.get(v as usize).copied();
        let corners = [
            corner(vertices[0])?,
            corner(vertices[1])?,
            corner(vertices[2])?,
        ];
        let [a, b, c] = corners;
        let cross = (b - a).cross(c - a);
        let longest_edge = (b - a).length().max((c - b).length()).max((a - c).length());
        // Twice the area over the longest edge is the smallest height.
        let height_ok = cross.length() > tol * longest_edge;
        if !height_ok {
            return None;
        }
        let normal = cross.normalize();
        let edge_normals =
            [0, 1, 2].map(|k| normal.cross(corners[(k + 1) % 3] - corners[k]).normalize());
        Some(Prepared {
            corners,
            vertices,
            normal,
            offset: normal.dot(a),
            edge_normals,
            lo: a.min(b).min(c),
            hi: a.max(b).max(c),
        })
    }

    fn plane_distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    /// Signed in-plane distance of `p` from edge `k`'s line, positive inside.
    fn edge_distance(&self, k: usize, p: DVec3) -> f64 {
        self.edge_normals[k].dot(p - self.corners[k])
    }

    fn boxes_overlap(&self, other: &Prepared, tol: f64) -> bool {
        self.lo.cmple(other.hi + tol).all() && other.lo.cmple(self.hi + tol).all()
    }

    /// Whether the segment `p`-`q` meets the (closed) triangle.
    fn meets_segment(&self, p: DVec3, q: DVec3, tol: f64) -> bool {
        let (dp, dq) = (self.plane_distance(p), self.plane_distance(q));
        if (dp > tol && dq > tol) || (dp < -tol && dq < -tol) {
            return false;
        }
        if dp.abs() <= tol && dq.abs() <= tol {
            return self.meets_coplanar_segment(p, q, tol);
        }
        let crossing = if dp.abs() <= tol {
            p
        } else if dq.abs() <= tol {
            q
        } else {
            p + (q - p) * (dp / (dp - dq))
        };
        (0..3).all(|k| self.edge_distance(k, crossing) >= -tol)
    }

    /// Whether a segment lying in the triangle's plane meets it: the segment clipped to
    /// the three edge half-planes (Cyrus-Beck) is not empty.
    fn meets_coplanar_segment(&self, p: DVec3, q: DVec3, tol: f64) -> bool {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for k in 0..3 {
            let (sp, sq) = (self.edge_distance(k, p), self.edge_distance(k, q));
            if sp == sq {
                if sp < -tol {
                    return false;
                }
                continue;
            }
            // s(t) = sp + t (sq - sp) >= -tol
            let bound = (-tol - sp) / (sq - sp);
            if sq > sp {
                t0 = t0.max(bound);
            } else {
                t1 = t1.min(bound);
            }
        }
        t0 <= t1
    }

    /// Whether all three corners of `other` lie strictly on one side of this plane.
    fn separates(&self, other: &Prepared, tol: f64) -> bool {
        let d = other.corners.map(|p| self.plane_distance(p));
        d.iter().all(|&x| x > tol) || d.iter().all(|&x| x < -tol)
    }
}

/// Whether two triangles intersect other than along what they share (see module docs).
fn triangles_intersect(a: &Prepared, b: &Prepared, tol: f64) -> bool {
    // Corners of `a` whose vertex `b` also has, in increasing order.
    let mut shared = [0usize; 3];
    let mut shared_count = 0;
    for k in 0..3 {
        if b.vertices.contains(&a.vertices[k]) {
            shared[shared_count] = k;
            shared_count += 1;
        }
    }
    match shared_count {
        0 => {
            if a.separates(b, tol) || b.separates(a, tol) {
                return false;
            }
            let meets_edge_of = |edges: &Prepared, other: &Prepared| {
                (0..3)
                    .any(|k| other.meets_segment(edges.corners[k], edges.corners[(k + 1) % 3], tol))
            };
            meets_edge_of(a, b) || meets_edge_of(b, a)
        }
        1 => {
            let k = shared[0];
            let Some(m) = (0..3).find(|&m| b.vertices[m] == a.vertices[k]) else {
                return false;
            };
            let opposite =
                |t: &Prepared, k: usize| (t.corners[(k + 1) % 3], t.corners[(k + 2) % 3]);
            let (p, q) = opposite(a, k);
            let (r, s) = opposite(b, m);
            b.meets_segment(p, q, tol) || a.meets_segment(r, s, tol)
        }
        2 => {
            // The shared edge is edge `k` of `a`, from corner `k` to `k + 1`.
            let (k0, k1) = (shared[0], shared[1]);
            let k = if (k0 + 1) % 3 == k1 { k0 } else { k1 };
            (0..3)
                .find(|&m| !a.vertices.contains(&b.vertices[m]))
                .map(|m| b.corners[m])
                .is_some_and(|third| {
                    a.plane_distance(third).abs() <= tol && a.edge_distance(k, third) > tol
                })
        }
        _ => true,
    }
}

/// Pairs `(i, j)`, `i < j`, of triangles that intersect, sorted (see module docs for what
/// counts). Empty for a mesh without triangles.
pub fn self_intersections(mesh: &TriMesh) -> Vec<(usize, usize)> {
    let (lo, hi) = mesh.bounding_box();
    let diagonal = (hi - lo).length();
    if !diagonal.is_finite() || diagonal == 0.0 {
        return Vec::new();
    }
    let tol = RELATIVE_TOLERANCE * diagonal;
    let prepared: Vec<Option<Prepared>> = mesh
        .triangles
        .par_iter()
        .map(|&tri| Prepared::new(mesh, tri, tol))
        .collect();
    let valid: Vec<u32> = (0..prepared.len() as u32)
        .filter(|&t| prepared[t as usize].is_some())
        .collect();
    if valid.is_empty() {
        return Vec::new();
    }
    let get = |t: u32| prepared[t as usize].as_ref();
    let mean_extent = valid
        .iter()
        .filter_map(|&t| get(t))
        .map(|p| (p.hi - p.lo).max_element())
        .sum::<f64>()
        / valid.len() as f64;
    let cell = (CELL_SIZE_FACTOR * mean_extent)
        .max(diagonal / MAX_CELLS_PER_AXIS as f64)
        .max(tol);
    let cell_of = |p: DVec3| {
        ((p - lo) / cell)
            .floor()
            .max(DVec3::ZERO)
            .min(DVec3::splat(MAX_CELLS_PER_AXIS as f64))
            .as_u64vec3()
    };
    let key = |c: glam::U64Vec3| (c.x << 42) | (c.y << 21) | c.z;

    let mut entries: Vec<(u64, u32)> = Vec::new();
    let mut large: Vec<(u32, &Prepared)> = Vec::new();
    for &t in &valid {
        let Some(p) = get(t) else { continue };
        let (c0, c1) = (cell_of(p.lo - tol), cell_of(p.hi + tol));
        let span = c1 - c0 + 1;
        if span.x * span.y * span.z > MAX_CELLS_PER_TRIANGLE {
            large.push((t, p));
            continue;
        }
        for x in c0.x..=c1.x {
            for y in c0.y..=c1.y {
                for z in c0.z..=c1.z {
                    entries.push((key(glam::U64Vec3::new(x, y, z)), t));
                }
            }
        }
    }
    entries.par_sort_unstable();

    let test = |i: u32, j: u32| -> Option<(usize, usize)> {
        let (a, b) = (get(i)?, get(j)?);
        (a.boxes_overlap(b, tol) && triangles_intersect(a, b, tol))
            .then_some((i.min(j) as usize, i.max(j) as usize))
    };
    let groups: Vec<&[(u64, u32)]> = entries.chunk_by(|x, y| x.0 == y.0).collect();
    let mut pairs: Vec<(usize, usize)> = groups
        .par_iter()
        .flat_map_iter(|group| {
            let cell_key = group[0].0;
            // The group's triangles side by side: the pair loop reads them k² times.
            let members: Vec<(u32, &Prepared)> = group
                .iter()
                .filter_map(|&(_, t)| Some((t, get(t)?)))
                .collect();
            let mut found = Vec::new();
            for (n, &(i, a)) in members.iter().enumerate() {
                for &(j, b) in &members[n + 1..] {
                    // Test each pair once: in the cell of its boxes' overlap's lower corner.
                    if a.boxes_overlap(b, tol)
                        && key(cell_of(a.lo.max(b.lo) - tol)) == cell_key
                        && triangles_intersect(a, b, tol)
                    {
                        found.push((i.min(j) as usize, i.max(j) as usize));
                    }
                }
            }
            found
        })
        .collect();
    // A large triangle meets the gridded ones through the grid's cells under its box
    // (one run of sorted keys per column of cells), and the other large ones directly.
    let large = &large;
    let entries = &entries;
    pairs.extend(
        large
            .par_iter()
            .enumerate()
            .flat_map_iter(|(n, &(i, p))| {
                let (c0, c1) = (cell_of(p.lo - tol), cell_of(p.hi + tol));
                let mut candidates = gridded_under(entries, c0, c1, key, valid.len())
                    .unwrap_or_else(|| {
                        valid
                            .iter()
                            .copied()
                            .filter(|&j| large.binary_search_by_key(&j, |&(t, _)| t).is_err())
                            .collect()
                    });
                candidates.sort_unstable();
                candidates.dedup();
                candidates.extend(large[n + 1..].iter().map(|&(j, _)| j));
                candidates.into_iter().filter_map(move |j| test(i, j))
            })
            .collect::<Vec<_>>(),
    );
    pairs.sort_unstable();
    pairs
}

/// The triangles entered in the cells from `c0` to `c1` (with repeats), read from
/// `entries` sorted by `key`: one binary search per column of cells along z. `None` when
/// those searches would take more steps than `scan_steps` (a scan of every triangle is
/// then cheaper).
fn gridded_under(
    entries: &[(u64, u32)],
    c0: glam::U64Vec3,
    c1: glam::U64Vec3,
    key: impl Fn(glam::U64Vec3) -> u64,
    scan_steps: usize,
) -> Option<Vec<u32>> {
    let columns = (c1.x - c0.x + 1).saturating_mul(c1.y - c0.y + 1);
    let steps_per_search = u64::from(usize::BITS - entries.len().leading_zeros());
    if columns.saturating_mul(steps_per_search) > scan_steps as u64 {
        return None;
    }
    let mut found = Vec::new();
    for x in c0.x..=c1.x {
        for y in c0.y..=c1.y {
            let (first, last) = (
                key(glam::U64Vec3::new(x, y, c0.z)),
                key(glam::U64Vec3::new(x, y, c1.z)),
            );
            let start = entries.partition_point(|e| e.0 < first);
            found.extend(
                entries[start..]
                    .iter()
                    .take_while(|e| e.0 <= last)
                    .map(|e| e.1),
            );
        }
    }
    Some(found)
}

/// How far a mesh is from a watertight, 2-manifold, consistently oriented surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ManifoldReport {
    /// Edges with one triangle.
    pub boundary_edges: usize,
    /// Edges with more than two triangles.
    pub non_manifold_edges: usize,
    /// Edges whose two triangles run along them in the same direction.
    pub inconsistent_edges: usize,
    /// Vertices whose triangles form more than one fan (bow ties).
    pub non_manifold_vertices: usize,
}

impl ManifoldReport {
    /// Every count is zero.
    pub fn is_watertight_manifold(&self) -> bool {
        *self == ManifoldReport::default()
    }
}

impl std::fmt::Display for ManifoldReport {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{} boundary edges, {} non-manifold edges, {} inconsistently oriented edges, {} non-manifold vertices",
            self.boundary_edges,
            self.non_manifold_edges,
            self.inconsistent_edges,
            self.non_manifold_vertices
        )
    }
}

/// The closedness counts of `mesh`; `topology` must be built from it.
pub fn manifold_report(mesh: &TriMesh, topology: &Topology) -> ManifoldReport {
    let non_manifold_vertices = (0..mesh.positions.len())
        .into_par_iter()
        .filter(|&v| !is_single_fan(mesh, topology, v))
        .count();
    ManifoldReport {
        boundary_edges: topology.boundary_edge_count,
        non_manifold_edges: topology.non_manifold_edge_count,
        inconsistent_edges: topology.inconsistent_edge_count,
        non_manifold_vertices,
    }
}

/// Whether the triangles around `v` are connected through edges at `v` (true for a
/// vertex without triangles).
fn is_single_fan(mesh: &TriMesh, topology: &Topology, v: usize) -> bool {
    let around = topology.vertex_triangles(v);
    let Some(&first) = around.first() else {
        return true;
    };
    let mut reached = vec![first];
    let mut stack = vec![first];
    while let Some(t) = stack.pop() {
        let tri = mesh.triangles[t as usize];
        let Some(k) = tri.iter().position(|&w| w as usize == v) else {
            continue;
        };
        // The two edges at v: k (v -> next) and k + 2 (previous -> v).
        for edge in [k, (k + 2) % 3] {
            let neighbor = topology.triangle_neighbors[t as usize][edge];
            if neighbor != NO_TRIANGLE && !reached.contains(&neighbor) {
                reached.push(neighbor);
                stack.push(neighbor);
            }
        }
    }
    reached.len() == around.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{cube, grid, icosphere};

    fn mesh(positions: &[[f64; 3]], triangles: Vec<[u32; 3]>) -> TriMesh {
        TriMesh::new(
            positions.iter().map(|&p| DVec3::from(p)).collect(),
            triangles,
        )
    }

    #[test]
    fn crossing_triangles_intersect() {
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.5, 0.5, -1.0],
                [0.5, 0.5, 1.0],
                [3.0, 3.0, 0.5],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
    }

    #[test]
    fn coplanar_overlapping_triangles_intersect() {
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.2, 0.2, 0.0],
                [0.6, 0.2, 0.0],
                [0.2, 0.6, 0.0],
            ],
            vec![[0, 1, 2], [3, 4, 5]],
        );
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
    }

    #[test]
    fn edge_neighbors_do_not_intersect_unless_folded_over() {
        let mut m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [1.0, 1.0, 0.3],
            ],
            vec![[0, 1, 2], [1, 3, 2]],
        );
        assert!(self_intersections(&m).is_empty());
        // The fourth corner folded flat onto the first triangle.
        m.positions[3] = DVec3::new(0.2, 0.2, 0.0);
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
    }

    #[test]
    fn touching_by_an_edge_without_shared_vertices_is_contact() {
        // Same geometric edge, separate vertices: a seam the closed surface must not have.
        let m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.5, -1.0, 0.5],
            ],
            vec![[0, 1, 2], [4, 3, 5]],
        );
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
    }

    #[test]
    fn triangles_sharing_a_vertex_intersect_only_when_crossing() {
        let mut m = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.2],
                [0.0, -1.0, 0.4],
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        );
        assert!(self_intersections(&m).is_empty());
        // Now the second triangle's far edge pierces the first away from the shared vertex.
        m.positions[3] = DVec3::new(0.3, 0.3, -1.0);
        m.positions[4] = DVec3::new(0.3, 0.3, 1.0);
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
        // Coplanar, one wedge inside the other.
        m.positions[3] = DVec3::new(0.5, 0.1, 0.0);
        m.positions[4] = DVec3::new(0.1, 0.5, 0.0);
        assert_eq!(self_intersections(&m), vec![(0, 1)]);
    }

    #[test]
    fn icosphere_has_none_until_a_vertex_is_pushed_through() {
        let mut sphere = icosphere(50.0, 3);
        assert!(self_intersections(&sphere).is_empty());
        sphere.positions[0] *= -1.3;
        let pairs = self_intersections(&sphere);
        assert!(!pairs.is_empty());
        // Every reported pair involves a triangle of the moved vertex's fan.
        let in_fan = |t: usize| sphere.triangles[t].contains(&0);
        assert!(pairs.iter().all(|&(i, j)| in_fan(i) || in_fan(j)));
    }

    #[test]
    fn a_huge_triangle_is_found_by_the_fallback_path() {
        let mut m = grid(40, 40, 1.0);
        let base = m.positions.len() as u32;
        m.positions.extend([
            // Tilted so that it crosses the grid's plane along x = 20.
            DVec3::new(-100.0, -100.0, -12.0),
            DVec3::new(300.0, -100.0, 28.0),
            DVec3::new(-100.0, 300.0, -12.0),
        ]);
        m.triangles.push([base, base + 1, base + 2]);
        let pairs = self_intersections(&m);
        assert!(!pairs.is_empty());
        assert!(pairs.iter().all(|&(_, j)| j == m.triangles.len() - 1));
        assert_eq!(pairs, every_pair(&m));
    }

    /// Every pair tested by the narrow phase alone: the reference for the broad phase.
    fn every_pair(mesh: &TriMesh) -> Vec<(usize, usize)> {
        let (lo, hi) = mesh.bounding_box();
        let tol = RELATIVE_TOLERANCE * (hi - lo).length();
        let prepared: Vec<_> = mesh
            .triangles
            .iter()
            .map(|&t| Prepared::new(mesh, t, tol))
            .collect();
        let mut pairs = Vec::new();
        for (i, a) in prepared.iter().enumerate() {
            for (j, b) in prepared.iter().enumerate().skip(i + 1) {
                if let (Some(a), Some(b)) = (a, b)
                    && triangles_intersect(a, b, tol)
                {
                    pairs.push((i, j));
                }
            }
        }
        pairs
    }

    /// The grid finds exactly the pairs that testing every pair finds: two crumpled
    /// sheets through each other (1 mm triangles: cells of about 3.4 mm), first alone,
    /// then with triangles kept out of the grid through both, crossing each other too:
    /// four of about 33 mm (over 512 cells, under 81 columns: found through the grid) and
    /// three of 120 mm and more (841 columns: found by a scan of every triangle).
    #[test]
    fn the_grid_finds_what_testing_every_pair_finds() {
        // A fixed pseudo-random height in [-1, 1] per vertex.
        let height = |k: usize| ((k as f64 * 12.9898).sin() * 43_758.545).fract() * 2.0 - 1.0;
        let mut sheets = grid(30, 30, 1.0);
        let count = sheets.positions.len();
        for (k, p) in sheets.positions.iter_mut().enumerate() {
            p.z = 0.6 * height(k);
        }
        let second: Vec<DVec3> = (0..count)
            .map(|k| sheets.positions[k] + DVec3::new(0.37, 0.21, 0.6 * height(k + count)))
            .collect();
        sheets.positions.extend(second);
        let first_sheet = sheets.triangles.clone();
        sheets
            .triangles
            .extend(first_sheet.iter().map(|t| t.map(|v| v + count as u32)));
        let crossings = self_intersections(&sheets);
        assert!(crossings.len() > 100, "{} crossings", crossings.len());
        assert_eq!(crossings, every_pair(&sheets));

        let base = sheets.positions.len() as u32;
        for (n, tilt) in [-0.2, 0.05, 0.3].into_iter().enumerate() {
            sheets.positions.extend([
                DVec3::new(-40.0, -40.0, -40.0 * tilt),
                DVec3::new(80.0, -40.0, 80.0 * tilt),
                DVec3::new(-40.0, 80.0 + n as f64, -40.0 * tilt),
            ]);
            let v = base + 3 * n as u32;
            sheets.triangles.push([v, v + 1, v + 2]);
        }
        let huge = sheets.triangles.len() - 3;
        for n in 0..4 {
            let (x, y) = (-3.3 + 4.1 * n as f64, -2.7 + 3.9 * n as f64);
            let v = sheets.positions.len() as u32;
            sheets.positions.extend([
                DVec3::new(x, y, -12.0),
                DVec3::new(x + 33.0, y + 5.0, 0.5),
                DVec3::new(x + 5.0, y + 33.0, 12.0),
            ]);
            sheets.triangles.push([v, v + 1, v + 2]);
        }
        let pins = huge + 3;
        let kept_out = self_intersections(&sheets);
        let count = |range: std::ops::Range<usize>| {
            kept_out
                .iter()
                .filter(|&&(i, j)| i < huge && range.contains(&j))
                .count()
        };
        assert!(count(huge..pins) > 10, "{kept_out:?}");
        assert!(count(pins..pins + 4) >= 8, "{kept_out:?}");
        assert_eq!(kept_out, every_pair(&sheets));
    }

    #[test]
    fn degenerate_and_invalid_triangles_are_skipped() {
        let m = mesh(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
            vec![[0, 1, 2], [0, 1, 7]],
        );
        assert!(self_intersections(&m).is_empty());
        assert!(self_intersections(&TriMesh::new(Vec::new(), Vec::new())).is_empty());
    }

    #[test]
    fn manifold_report_of_closed_open_and_bow_tie_meshes() {
        let closed = cube(1.0);
        assert!(manifold_report(&closed, &Topology::new(&closed)).is_watertight_manifold());

        let open = grid(2, 2, 1.0);
        let report = manifold_report(&open, &Topology::new(&open));
        assert_eq!(report.boundary_edges, 8);
        assert!(!report.is_watertight_manifold());

        // Two triangles touching at one vertex.
        let bow_tie = mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [-1.0, 0.0, 0.0],
                [0.0, -1.0, 0.0],
            ],
            vec![[0, 1, 2], [0, 3, 4]],
        );
        let report = manifold_report(&bow_tie, &Topology::new(&bow_tie));
        assert_eq!(report.non_manifold_vertices, 1);
    }

    /// Run with `cargo test --release -p mesh intersect -- --ignored --nocapture`.
    #[test]
    #[ignore = "timing; run in release"]
    fn timing_300k_triangles() {
        let sphere = icosphere(100.0, 6);
        let mut many = sphere.clone();
        // Four spheres side by side: 327,680 triangles.
        for shift in 1..4 {
            let offset = many.positions.len() as u32;
            many.positions.extend(
                sphere
                    .positions
                    .iter()
                    .map(|p| *p + DVec3::X * (250.0 * shift as f64)),
            );
            many.triangles
                .extend(sphere.triangles.iter().map(|t| t.map(|v| v + offset)));
        }
        let start = std::time::Instant::now();
        let pairs = self_intersections(&many);
        println!(
            "self_intersections: {} triangles in {:.0} ms",
            many.triangles.len(),
            start.elapsed().as_secs_f64() * 1e3
        );
        assert!(pairs.is_empty());
    }
}
