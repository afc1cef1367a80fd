//! Keeping the rear wall clear of the scan (paper IV-C's shifted base).
//!
//! The wall is the filled base translated posteriorly. Where the scan runs almost parallel
//! to that direction, a translation does not move the wall away from it: under a hanging
//! breast the fill-in leaves the fold nearly level with the breast's underside, and the
//! translated copy stays within a millimetre of it (or crosses it where scanner noise
//! raises the skin). [`keep_wall_clear`] pushes such wall vertices further inside, along
//! the scan's inward normal at their nearest scan point, towards the clearance behind the
//! scan, for a bounded number of rounds (what is still too close is reported); the push
//! is smoothed over some ten rings of the wall so it bends rather than dents, and cut back
//! (or, at the clip planes, evened) where it would turn a wall triangle over or fold the
//! wall's border back on a clip plane. A wall with
//! no vertex too close stays exactly the translated copy.

use glam::DVec3;
use mesh::topology::NO_TRIANGLE;
use mesh::{SurfaceIndex, Topology, TriMesh};

/// Rounds of push and check.
const ROUNDS: usize = 8;
/// Smoothing passes over the push per round (each averages a vertex's push with its
/// neighbours'), spreading a local push over some ten rings of the wall.
const SMOOTHING_PASSES: usize = 10;

/// Times a push that would turn a wall triangle over or fold a border edge is halved
/// before it is dropped ([`without_turning_over`]).
const MAX_HALVINGS: u32 = 6;

/// Which coordinates of a wall vertex must not change: a vertex on a lateral clip plane
/// keeps its x, one on the top or bottom plane its y (so the wall's border stays on the
/// planes and meets the scan's at the same corners).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct FixedAxes {
    pub x: bool,
    pub y: bool,
}

impl FixedAxes {
    /// Whether the vertex lies on a clip plane.
    fn on_a_plane(self) -> bool {
        self.x || self.y
    }

    /// Whether this vertex and `other` lie on one clip plane.
    fn share_a_plane(self, other: FixedAxes) -> bool {
        (self.x && other.x) || (self.y && other.y)
    }

    /// `push` less the coordinates the vertex keeps.
    fn mask(self, push: DVec3) -> DVec3 {
        DVec3::new(
            if self.x { 0.0 } else { push.x },
            if self.y { 0.0 } else { push.y },
            push.z,
        )
    }
}

/// What [`keep_wall_clear`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct WallClearance {
    /// Wall vertices found closer to the scan than the clearance at first.
    pub too_close: usize,
    /// The largest push of a wall vertex (mm).
    pub max_push_mm: f64,
    /// Wall vertices still closer than the clearance after the last round.
    pub still_too_close: usize,
}

/// Pushes the vertices of `wall` (positions changed in place; its triangles are read) that
/// lie less than `clearance_mm` behind `scan` (oriented outward) further inside, keeping
/// the coordinates `fixed` names per wall vertex.
pub(crate) fn keep_wall_clear(
    scan: &TriMesh,
    wall: &mut TriMesh,
    fixed: &[FixedAxes],
    clearance_mm: f64,
) -> WallClearance {
    let nothing = WallClearance {
        too_close: 0,
        max_push_mm: 0.0,
        still_too_close: 0,
    };
    let Some(index) = SurfaceIndex::new(scan) else {
        return nothing;
    };
    let scan_normals = scan.vertex_normals();
    // How far a point must move along the scan's inward normal to lie the clearance
    // behind it, and that normal.
    let deficit = |p: DVec3| -> Option<(f64, DVec3)> {
        // A vertex that crossed to the scan's outside by less than the clearance is found
        // too (its depth is negative); one farther out is left to the closed surface's
        // self-intersection check, since the sign from the normal at the nearest point
        // is unreliable farther off (at the scan's border on the clip planes).
        let closest = index.closest_point_within(p, clearance_mm)?;
        let corners = scan.triangles[closest.triangle];
        let normal = (0..3)
            .map(|k| scan_normals[corners[k] as usize] * closest.barycentric[k])
            .sum::<DVec3>()
            .try_normalize()?;
        let depth = (closest.point - p).dot(normal);
        (depth < clearance_mm).then_some((clearance_mm - depth, -normal))
    };
    let masked = |v: usize, push: DVec3| fixed[v].mask(push);
    let start = wall.positions.clone();
    let mut candidates: Vec<usize> = (0..wall.vertex_count()).collect();
    let mut too_close = None;
    let mut still = 0;
    let topology = Topology::new(wall);
    let neighbours: Vec<Vec<u32>> = (0..wall.vertex_count())
        .map(|v| topology.vertex_neighbors(wall, v))
        .collect();
    let border = PlaneBorder::new(wall, &topology, fixed);
    for _ in 0..ROUNDS {
        let mut push = vec![DVec3::ZERO; wall.vertex_count()];
        let mut close = Vec::new();
        for &v in &candidates {
            if let Some((amount, direction)) = deficit(wall.positions[v]) {
                push[v] = masked(v, direction * amount);
                close.push(v);
            }
        }
        too_close.get_or_insert(close.len());
        still = close.len();
        if close.is_empty() {
            break;
        }
        // Spread the push; a vertex never gets less than its own need along its own
        // direction, so the smoothing only widens the region that moves.
        let own = push.clone();
        for _ in 0..SMOOTHING_PASSES {
            let previous = push.clone();
            for v in 0..push.len() {
                let around = &neighbours[v];
                if around.is_empty() {
                    continue;
                }
                let mean = around.iter().map(|&n| previous[n as usize]).sum::<DVec3>()
                    / around.len() as f64;
                let smoothed = masked(v, 0.5 * (previous[v] + mean));
                push[v] = if smoothed.length_squared() < own[v].length_squared() {
                    own[v]
                } else {
                    smoothed
                };
            }
        }
        without_turning_over(wall, &border, fixed, &mut push);
        candidates.clear();
        for (v, p) in push.iter().enumerate() {
            if *p != DVec3::ZERO {
                wall.positions[v] += *p;
                candidates.push(v);
            }
        }
    }
    let max_push_mm = wall
        .positions
        .iter()
        .zip(&start)
        .map(|(p, q)| p.distance(*q))
        .fold(0.0, f64::max);
    WallClearance {
        too_close: too_close.unwrap_or(0),
        max_push_mm,
        still_too_close: still,
    }
}

/// `push` (per vertex of `wall`) changed where it would turn a wall triangle over (its
/// normal reversed) or fold the wall's border back on a clip plane, until neither
/// happens. The scan's inward normals differ across a crease (the fold under a breast,
/// the side of the torso), so neighbouring vertices can be pushed across each other; a
/// wall folded through itself cannot close the surface, while one left short of the
/// clearance is only reported.
/// - A triangle with pushed corners off the clip planes: their push is halved, up to
///   [`MAX_HALVINGS`] times, then dropped.
/// - A triangle turned by its corners on a clip plane (any of `fixed`) alone: those
///   corners first move as one, by the longest of their pushes (a short border edge
///   across a crease then only translates); where they already do, the whole triangle
///   does, its inner corner included (a sliver against the plane). A corner the shared
///   push would move against its own keeps its own. The longest push is chosen before
///   each corner drops the coordinates it keeps, so a corner of two planes may get less
///   depth than its own push. Each corner is evened so once in a call; only then are
///   a triangle's border corners halved: the wall's border must stay behind the scan's,
///   or the band between them on the plane crosses itself.
/// - A border edge on a clip plane that the pushes turn by a right angle or more from
///   its direction before any push ([`PlaneBorder`]; an edge of no length there counts
///   as turned): the wall's section on the plane folds back there, and the band
///   stitched to it crosses itself. Its ends move as one, by the longer of their
///   pushes, if neither has been evened yet in this call; else its pushed ends are
///   halved, though the other end was never evened. Triangles are judged against the
///   round's positions, edges against the wall before any round: rounds each turning a
///   short edge by less than a right angle add up to a fold. (Evened once per call, so
///   a longest push can still spread one edge along the border per round.)
///
/// Terminates: a pass that evens marks at least one vertex evened for the first time
/// (at most one such pass per vertex; it may push again a vertex evened or dropped
/// before), and between those passes every pass halves or drops a push, each push at
/// most `MAX_HALVINGS + 1` times, since the count of halvings never falls.
fn without_turning_over(
    wall: &TriMesh,
    border: &PlaneBorder,
    fixed: &[FixedAxes],
    push: &mut [DVec3],
) {
    let mut halvings = vec![0; push.len()];
    let mut evened = vec![false; push.len()];
    loop {
        let mut culprits = Culprits::default();
        for triangle in &wall.triangles {
            culprits.judge_triangle(triangle.map(|v| v as usize), wall, fixed, push, &evened);
        }
        for &(ends, start_direction) in &border.edges {
            let [a, b] = ends;
            if push[a] == DVec3::ZERO && push[b] == DVec3::ZERO {
                continue;
            }
            let direction = wall.positions[b] + push[b] - wall.positions[a] - push[a];
            if start_direction.dot(direction) <= 0.0 {
                // Evened once: evening again would carry the longest push along the
                // border edge by edge and shear the wall beside it.
                if ends.iter().any(|&v| evened[v]) {
                    culprits.halve_pushed(&ends, push);
                } else {
                    culprits.border_group(&ends, &ends, push, &evened);
                }
            }
        }
        let Culprits { turned, to_even } = culprits;
        if turned.is_empty() && to_even.is_empty() {
            return;
        }
        // Border corners turning a triangle, or the ends of a folded border edge, move
        // as one, by the longest of their pushes (less the coordinates a corner keeps),
        // except a corner the shared push would move against its own push (across a
        // crease sharper than a right angle): it keeps its own, and is halved if the
        // triangle or edge is still turned.
        let mut evened_now = Vec::new();
        for corners in to_even {
            let longest = (corners.iter())
                .map(|&v| push[v])
                .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
                .unwrap_or(DVec3::ZERO);
            for v in corners {
                let shared = fixed[v].mask(longest);
                if shared.dot(push[v]) >= 0.0 {
                    push[v] = shared;
                }
                evened[v] = true;
                evened_now.push(v);
            }
        }
        let mut turned = turned;
        turned.sort_unstable();
        turned.dedup();
        for v in turned {
            if evened_now.contains(&v) {
                continue;
            }
            if halvings[v] < MAX_HALVINGS {
                push[v] *= 0.5;
                halvings[v] += 1;
            } else {
                push[v] = DVec3::ZERO;
            }
        }
    }
}

/// What one pass of [`without_turning_over`] found: vertices whose push is to be halved,
/// and groups of border corners to move as one.
#[derive(Default)]
struct Culprits {
    turned: Vec<usize>,
    to_even: Vec<Vec<usize>>,
}

impl Culprits {
    /// Records `corners` (a triangle of the wall) if `push` turns it over.
    fn judge_triangle(
        &mut self,
        corners: [usize; 3],
        wall: &TriMesh,
        fixed: &[FixedAxes],
        push: &[DVec3],
        evened: &[bool],
    ) {
        if corners.iter().all(|&v| push[v] == DVec3::ZERO) {
            return;
        }
        let normal = |p: [DVec3; 3]| (p[1] - p[0]).cross(p[2] - p[0]);
        let before = normal(corners.map(|v| wall.positions[v]));
        let after = normal(corners.map(|v| wall.positions[v] + push[v]));
        if before.dot(after) >= 0.0 {
            return;
        }
        let inner: Vec<usize> = (corners.into_iter())
            .filter(|&v| push[v] != DVec3::ZERO && !fixed[v].on_a_plane())
            .collect();
        if inner.is_empty() {
            self.border_group(&corners, &corners, push, evened);
        } else {
            self.turned.extend(inner);
        }
    }

    /// A turn caused by the pushes of border corners alone (the pushed ones of
    /// `group`): they move as one if not yet evened, else the whole of `wider` does
    /// (a triangle's inner corner with them), else their pushes are halved.
    fn border_group(&mut self, group: &[usize], wider: &[usize], push: &[DVec3], evened: &[bool]) {
        let pushed: Vec<usize> = (group.iter().copied())
            .filter(|&v| push[v] != DVec3::ZERO)
            .collect();
        let due =
            |vertices: &[usize]| vertices.iter().any(|&v| !evened[v]) && !all_equal(vertices, push);
        if due(&pushed) {
            self.to_even.push(pushed);
        } else if due(wider) {
            self.to_even.push(wider.to_vec());
        } else {
            self.halve_pushed(group, push);
        }
    }

    /// Records the pushed vertices of `group` for halving.
    fn halve_pushed(&mut self, group: &[usize], push: &[DVec3]) {
        (self.turned).extend(group.iter().copied().filter(|&v| push[v] != DVec3::ZERO));
    }
}

/// The wall's border edges on the clip planes (both ends on one plane), each with its
/// direction before any push.
struct PlaneBorder {
    /// `[a, b]` with `a < b`, sorted (the evening depends on the order it meets them),
    /// and the vector from `a` to `b`.
    edges: Vec<([usize; 2], DVec3)>,
}

impl PlaneBorder {
    fn new(wall: &TriMesh, topology: &Topology, fixed: &[FixedAxes]) -> PlaneBorder {
        let mut edges = Vec::new();
        for (t, triangle) in wall.triangles.iter().enumerate() {
            for k in 0..3 {
                if topology.triangle_neighbors[t][k] != NO_TRIANGLE {
                    continue;
                }
                let (p, q) = (triangle[k] as usize, triangle[(k + 1) % 3] as usize);
                let (a, b) = (p.min(q), p.max(q));
                if fixed[a].share_a_plane(fixed[b]) {
                    edges.push(([a, b], wall.positions[b] - wall.positions[a]));
                }
            }
        }
        edges.sort_unstable_by_key(|&(ends, _)| ends);
        edges.dedup_by_key(|&mut (ends, _)| ends);
        PlaneBorder { edges }
    }
}

/// Whether the pushes of `vertices` are all the same.
fn all_equal(vertices: &[usize], push: &[DVec3]) -> bool {
    vertices
        .windows(2)
        .all(|pair| push[pair[0]] == push[pair[1]])
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::grid;

    /// A flat 60 x 60 mm wall 10 mm behind a flat scan at z = 0 (facing +z), with a
    /// Gaussian bump of `height_mm` towards the scan in its middle.
    fn wall_with_bump(height_mm: f64) -> TriMesh {
        let mut wall = grid(60, 60, 1.0);
        for p in &mut wall.positions {
            let r = (p.x - 30.0).hypot(p.y - 30.0);
            p.z = -10.0 + height_mm * (-(r * r) / 50.0).exp();
        }
        wall
    }

    /// A wall whose middle has crossed 2 mm in front of the scan ends at least the
    /// clearance (3 mm) behind it: a crossing is found and undone, not taken for
    /// clearance.
    #[test]
    fn a_wall_crossing_the_scan_is_pushed_back_behind_it() {
        let scan = grid(60, 60, 1.0);
        let mut wall = wall_with_bump(12.0);
        let fixed = vec![FixedAxes::default(); wall.vertex_count()];
        let done = keep_wall_clear(&scan, &mut wall, &fixed, 3.0);
        assert_eq!(done.still_too_close, 0);
        assert!(wall.positions.iter().all(|p| p.z <= -3.0 + 1e-9));
    }

    /// A dent rising to 2 mm behind the scan: with a 5 mm clearance every wall vertex
    /// ends at least 5 mm behind (to round-off), the vertices far from the dent keep
    /// their place, and the fixed coordinates do not change.
    #[test]
    fn a_dent_towards_the_scan_is_pushed_back_to_the_clearance() {
        let scan = grid(60, 60, 1.0);
        let mut wall = wall_with_bump(8.0);
        let fixed: Vec<FixedAxes> = wall
            .positions
            .iter()
            .map(|p| FixedAxes {
                x: p.x == 0.0 || p.x == 60.0,
                y: p.y == 0.0 || p.y == 60.0,
            })
            .collect();
        let before = wall.positions.clone();
        let done = keep_wall_clear(&scan, &mut wall, &fixed, 5.0);
        assert!(done.too_close > 0);
        assert_eq!(done.still_too_close, 0);
        for (p, q) in wall.positions.iter().zip(&before) {
            assert!(p.z <= -5.0 + 1e-9, "{p}");
            // The push is along the scan's normal: x and y stay.
            assert!((p.x - q.x).abs() < 1e-9 && (p.y - q.y).abs() < 1e-9);
            let r = (q.x - 30.0).hypot(q.y - 30.0);
            if r > 25.0 {
                assert_eq!(p, q);
            }
        }
    }

    /// Triangles of `wall` whose normal `moved` positions reverse.
    fn turned_over(wall: &TriMesh, moved: &[DVec3]) -> usize {
        let normal = |p: &[DVec3], t: [u32; 3]| {
            let [a, b, c] = t.map(|v| p[v as usize]);
            (b - a).cross(c - a)
        };
        wall.triangles
            .iter()
            .filter(|&&t| normal(&wall.positions, t).dot(normal(moved, t)) < 0.0)
            .count()
    }

    /// A wall 3 mm behind a scan with a ridge along y (its flanks sloping back at 0.8
    /// mm/mm, the way skin runs into a crease): the inward normals on the two flanks
    /// point towards each other, so the pushes of neighbouring wall vertices cross. No
    /// wall triangle turns over (with the cut-back switched off by hand, 120 did).
    #[test]
    fn pushes_from_a_crease_never_turn_the_wall_over() {
        let mut scan = grid(60, 60, 1.0);
        for p in &mut scan.positions {
            p.z = -0.8 * (p.x - 30.0).abs();
        }
        let mut wall = grid(60, 60, 1.0);
        for p in &mut wall.positions {
            p.z = -3.0 - 0.8 * (p.x - 30.0).abs();
        }
        let start = wall.clone();
        let fixed = vec![FixedAxes::default(); wall.vertex_count()];
        let done = keep_wall_clear(&scan, &mut wall, &fixed, 5.0);
        println!("{done:?}");
        assert!(done.too_close > 0 && done.max_push_mm > 1.0, "{done:?}");
        assert_eq!(turned_over(&start, &wall.positions), 0);
    }

    /// One vertex pushed 2.5 mm across its neighbours 1 mm away: halved twice, to 0.625
    /// mm, the first push that turns none of its triangles over; the other pushes (zero)
    /// stay.
    #[test]
    fn a_push_across_the_neighbours_is_halved_until_nothing_turns_over() {
        let wall = grid(10, 10, 1.0);
        let centre = 5 * 11 + 5;
        let mut push = vec![DVec3::ZERO; wall.vertex_count()];
        push[centre] = DVec3::new(2.5, 0.0, 0.0);
        let fixed = vec![FixedAxes::default(); wall.vertex_count()];
        guard(&wall, &fixed, &mut push);
        assert_eq!(push[centre], DVec3::new(0.625, 0.0, 0.0));
        assert!(
            push.iter()
                .enumerate()
                .all(|(v, p)| v == centre || *p == DVec3::ZERO)
        );
        let moved: Vec<DVec3> = wall
            .positions
            .iter()
            .zip(&push)
            .map(|(p, d)| *p + *d)
            .collect();
        assert_eq!(turned_over(&wall, &moved), 0);
    }

    /// A border edge on a lateral clip plane (x fixed) shortened to 0.2 mm, its corners
    /// pushed 0.5 and 0.1 mm along it (as across a crease): they pass each other and turn
    /// the border triangle over. They move as one instead, by the longer push (exactly),
    /// so the border keeps its full push away from the scan rather than halving it
    /// towards the scan's border; nothing else moves and nothing turns over.
    #[test]
    fn border_corners_pushed_past_each_other_move_as_one() {
        let mut wall = grid(10, 10, 1.0);
        let (low, high) = (5 * 11, 6 * 11);
        wall.positions[high].y = 5.2;
        let fixed: Vec<FixedAxes> = (wall.positions.iter())
            .map(|p| FixedAxes {
                x: p.x == 0.0,
                y: false,
            })
            .collect();
        let longer = DVec3::new(0.0, 0.5, -0.5);
        let mut push = vec![DVec3::ZERO; wall.vertex_count()];
        push[low] = longer;
        push[high] = DVec3::new(0.0, 0.1, -0.3);
        assert!(turned_over(&wall, &moved(&wall, &push)) > 0);
        guard(&wall, &fixed, &mut push);
        assert_eq!(push[low], longer);
        assert_eq!(push[high], longer);
        assert!(
            (0..push.len()).all(|v| v == low || v == high || push[v] == DVec3::ZERO),
            "{push:?}"
        );
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 0);
    }

    /// A sliver against a lateral clip plane: its border corners pushed alike 0.8 mm
    /// past its inner corner (0.5 mm from their edge) would turn it over. The inner
    /// corner moves with them, by the same push (exactly), rather than the border being
    /// halved back towards the scan.
    #[test]
    fn a_sliver_against_the_plane_moves_with_its_border_corners() {
        let wall = edge_on_lateral_plane(DVec3::new(0.1, 0.5, 0.5));
        let fixed = [LATERAL, LATERAL, FixedAxes::default()];
        let border_push = DVec3::new(0.0, 0.0, 0.8);
        let mut push = vec![border_push, border_push, DVec3::ZERO];
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 1);
        guard(&wall, &fixed, &mut push);
        assert_eq!(push, vec![border_push; 3]);
    }

    /// The box's corner: a wall vertex on a lateral and the bottom plane (x and y fixed)
    /// pushed 0.9 mm away from the scan (-z), beside one on the lateral plane alone
    /// pushed 1.0 mm along it and 0.5 mm away; together they turn their triangle over.
    /// They move as one by the longest push, chosen before each drops what it keeps: the
    /// corner keeps its x and y and takes that push's 0.5 mm in z (less than its own
    /// 0.9, the documented cost; choosing after dropping would keep 0.9), the other
    /// keeps its own push, and the triangle no longer turns over.
    #[test]
    fn a_corner_of_two_planes_takes_only_the_depth_of_the_longest_push() {
        let wall = edge_on_lateral_plane(DVec3::new(0.1, 0.5, -0.5));
        let corner = FixedAxes { x: true, y: true };
        let fixed = [corner, LATERAL, FixedAxes::default()];
        let along = DVec3::new(0.0, 1.0, -0.5);
        let mut push = vec![DVec3::new(0.0, 0.0, -0.9), along, DVec3::ZERO];
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 1);
        guard(&wall, &fixed, &mut push);
        assert_eq!(push, vec![DVec3::new(0.0, 0.0, -0.5), along, DVec3::ZERO]);
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 0);
    }

    /// A border edge on a lateral clip plane (x fixed), 1 mm long, whose first corner is
    /// pushed 1.5 mm along it past the second: the wall's section on the plane folds
    /// back, while the inner corner's push across the edge's line keeps the triangle
    /// from turning over, so only the edge shows it. Its corners move as one, by the
    /// longer push (exactly), and the edge keeps its direction; the triangle, which that
    /// turns over, is then set right by halving the inner corner's push once, to 0.6 mm
    /// (with its border corners moved as one it turns over for inner pushes above 1.04
    /// mm).
    #[test]
    fn a_border_edge_folded_back_by_the_push_moves_as_one() {
        let wall = edge_on_lateral_plane(DVec3::new(0.2, 0.5, -1.0));
        let fixed = [LATERAL, LATERAL, FixedAxes::default()];
        let longer = DVec3::new(0.0, 1.5, 0.0);
        let mut push = vec![longer, DVec3::ZERO, DVec3::new(0.0, 0.0, 1.2)];
        let edge = |p: &[DVec3]| p[1] - p[0];
        let raw = moved(&wall, &push);
        assert_eq!(turned_over(&wall, &raw), 0);
        assert!(edge(&raw).dot(edge(&wall.positions)) < 0.0);
        guard(&wall, &fixed, &mut push);
        assert_eq!(push, vec![longer, longer, DVec3::new(0.0, 0.0, 0.6)]);
        let after = moved(&wall, &push);
        assert_eq!(edge(&after), edge(&wall.positions));
        assert_eq!(turned_over(&wall, &after), 0);
    }

    /// Rounds add up: a border edge that earlier rounds turned 80 degrees in the plane
    /// is turned 20 more by this round's push (its second corner pushed along the
    /// plane; each round alone turns it less than a right angle). Against its direction
    /// before any push that is a fold, so its corners move as one.
    #[test]
    fn a_border_edge_turned_over_several_rounds_moves_as_one() {
        let start = edge_on_lateral_plane(DVec3::new(1.0, 0.5, -0.5));
        let fixed = [LATERAL, LATERAL, FixedAxes::default()];
        let turned_by = |degrees: f64| {
            let r = degrees.to_radians();
            DVec3::new(0.0, r.cos(), r.sin())
        };
        let mut wall = start.clone();
        wall.positions[1] = turned_by(80.0);
        let border = PlaneBorder::new(&start, &Topology::new(&start), &fixed);
        let second = turned_by(100.0) - turned_by(80.0);
        let mut push = vec![DVec3::ZERO, second, DVec3::ZERO];
        let raw = moved(&wall, &push);
        assert!((raw[1] - raw[0]).dot(wall.positions[1] - wall.positions[0]) > 0.0);
        assert_eq!(turned_over(&wall, &raw), 0);
        without_turning_over(&wall, &border, &fixed, &mut push);
        assert_eq!(push[0], second);
        assert_eq!(push[1], second);
        let after = moved(&wall, &push);
        assert!((after[1] - after[0]).dot(start.positions[1] - start.positions[0]) > 0.0);
    }

    /// Two border edges in a row on a lateral plane, each in a triangle like the one of
    /// `a_border_edge_folded_back_by_the_push_moves_as_one` (inner corners pushed so
    /// the triangles alone do not turn). Evening the first edge gives the middle corner
    /// the 1.5 mm push, which folds the second; its middle corner, evened already, is
    /// halved instead, so the push does not run on along the border: the third corner
    /// stays put, and nothing is folded or turned over.
    #[test]
    fn a_folded_edge_beside_an_evened_one_is_halved_not_evened() {
        let wall = TriMesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.0, 2.0, 0.0),
                DVec3::new(0.2, 0.5, -1.0),
                DVec3::new(0.2, 1.5, -1.0),
            ],
            vec![[0, 1, 3], [1, 2, 4]],
        );
        let inner = FixedAxes::default();
        let fixed = [LATERAL, LATERAL, LATERAL, inner, inner];
        let mut push = vec![
            DVec3::new(0.0, 1.5, 0.0),
            DVec3::ZERO,
            DVec3::ZERO,
            DVec3::new(0.0, 0.0, 1.2),
            DVec3::new(0.0, 0.0, 0.9),
        ];
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 0);
        guard(&wall, &fixed, &mut push);
        assert_eq!(push[2], DVec3::ZERO);
        assert!(push[1].y > 0.0 && push[1].y < 1.5, "{push:?}");
        let after = moved(&wall, &push);
        for [a, b] in [[0, 1], [1, 2]] {
            let start = wall.positions[b] - wall.positions[a];
            assert!((after[b] - after[a]).dot(start) > 0.0, "{push:?}");
        }
        assert_eq!(turned_over(&wall, &after), 0);
    }

    /// On a lateral clip plane: x fixed.
    const LATERAL: FixedAxes = FixedAxes { x: true, y: false };

    /// One wall triangle: the border edge from the origin to (0, 1, 0), on the lateral
    /// plane x = 0, and `inner`.
    fn edge_on_lateral_plane(inner: DVec3) -> TriMesh {
        TriMesh::new(vec![DVec3::ZERO, DVec3::Y, inner], vec![[0, 1, 2]])
    }

    /// [`without_turning_over`] on a wall no earlier round has pushed.
    fn guard(wall: &TriMesh, fixed: &[FixedAxes], push: &mut [DVec3]) {
        let border = PlaneBorder::new(wall, &Topology::new(wall), fixed);
        without_turning_over(wall, &border, fixed, push);
    }

    /// The wall's positions moved by `push`.
    fn moved(wall: &TriMesh, push: &[DVec3]) -> Vec<DVec3> {
        (wall.positions.iter().zip(push))
            .map(|(p, d)| *p + *d)
            .collect()
    }
}
