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
use mesh::{SurfaceIndex, Topology, TriMesh};
use std::collections::HashMap;

/// Rounds of push and check.
const ROUNDS: usize = 8;
/// Smoothing passes over the push per round (each averages a vertex's push with its
/// neighbours'), spreading a local push over some ten rings of the wall.
const SMOOTHING_PASSES: usize = 10;

/// Times a push that would turn a wall triangle over is halved before it is dropped
/// ([`without_turning_over`]).
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
    let masked = |v: usize, push: DVec3| {
        DVec3::new(
            if fixed[v].x { 0.0 } else { push.x },
            if fixed[v].y { 0.0 } else { push.y },
            push.z,
        )
    };
    let start = wall.positions.clone();
    let mut candidates: Vec<usize> = (0..wall.vertex_count()).collect();
    let mut too_close = None;
    let mut still = 0;
    let topology = Topology::new(wall);
    let neighbours: Vec<Vec<u32>> = (0..wall.vertex_count())
        .map(|v| topology.vertex_neighbors(wall, v))
        .collect();
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
        without_turning_over(wall, &start, fixed, &mut push);
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
/// normal reversed), until none turns over. The scan's inward normals differ across a
/// crease (the fold under a breast, the side of the torso), so neighbouring vertices can
/// be pushed across each other; a wall folded through itself cannot close the surface,
/// while one left short of the clearance is only reported.
/// - A triangle with pushed corners off the clip planes: their push is halved, up to
///   [`MAX_HALVINGS`] times, then dropped.
/// - A triangle turned by its corners on a clip plane (any of `fixed`) alone: those
///   corners first move as one, by the longest of their pushes (a short border edge
///   across a crease then only translates); where they already do, the whole triangle
///   does, its inner corner included (a sliver against the plane). A corner the shared
///   push would move against its own keeps its own. Each vertex is evened so once;
///   only then are border corners halved: the wall's border must stay behind the
///   scan's, or the band between them on the plane crosses itself.
/// - A border edge on a clip plane that the pushes, with those of the rounds before,
///   reverse against its direction in `start` (the wall before any push): the wall's
///   section on the plane folds back there, where it runs front to back and neighbouring
///   pushes differ. Its ends are treated as the border corners of a turned triangle.
///   Judged against `start`, not the round's positions, since rounds each turning a
///   short edge by less than a right angle add up to a fold.
///
/// Terminates: a pass that evens marks at least one vertex evened for the first time
/// (at most one such pass per vertex), and between those passes every pass halves or
/// drops a push, each push at most `MAX_HALVINGS + 1` times.
fn without_turning_over(wall: &TriMesh, start: &[DVec3], fixed: &[FixedAxes], push: &mut [DVec3]) {
    let on_plane = |v: usize| fixed[v].on_a_plane();
    let normal = |corners: [DVec3; 3]| (corners[1] - corners[0]).cross(corners[2] - corners[0]);
    let border_edges = border_edges_on_planes(wall, fixed);
    let mut halvings = vec![0; push.len()];
    let mut evened = vec![false; push.len()];
    loop {
        let mut turned = Vec::new();
        let mut to_even = Vec::new();
        for triangle in &wall.triangles {
            let corners = triangle.map(|v| v as usize);
            if corners.iter().all(|&v| push[v] == DVec3::ZERO) {
                continue;
            }
            let before = normal(corners.map(|v| wall.positions[v]));
            let after = normal(corners.map(|v| wall.positions[v] + push[v]));
            if before.dot(after) < 0.0 {
                let pushed: Vec<usize> = (corners.into_iter())
                    .filter(|&v| push[v] != DVec3::ZERO)
                    .collect();
                let inner: Vec<usize> = pushed.iter().copied().filter(|&v| !on_plane(v)).collect();
                if !inner.is_empty() {
                    turned.extend(inner);
                } else if pushed.iter().any(|&v| !evened[v]) && !all_equal(&pushed, push) {
                    to_even.push(pushed);
                } else if corners.iter().any(|&v| !evened[v]) && !all_equal(&corners, push) {
                    to_even.push(corners.to_vec());
                } else {
                    turned.extend(pushed);
                }
            }
        }
        // A border edge on a clip plane that the pushes reverse folds the wall's section
        // on that plane (its neighbours' pushes differ across a section running front
        // to back, under a hanging breast), and the band stitched to it crosses itself:
        // treated as a triangle turned by its border corners alone.
        for &[a, b] in &border_edges {
            if push[a] == DVec3::ZERO && push[b] == DVec3::ZERO {
                continue;
            }
            let before = start[b] - start[a];
            let after = wall.positions[b] + push[b] - wall.positions[a] - push[a];
            if before.dot(after) < 0.0 {
                let ends = [a, b];
                if ends.iter().any(|&v| !evened[v]) && !all_equal(&ends, push) {
                    to_even.push(ends.to_vec());
                } else {
                    turned.extend(ends.into_iter().filter(|&v| push[v] != DVec3::ZERO));
                }
            }
        }
        if turned.is_empty() && to_even.is_empty() {
            return;
        }
        // Corners turning a triangle by their border pushes alone move as one, by the
        // longest of those pushes (less the coordinates a corner keeps), except a corner
        // the shared push would move against its own push (across a crease sharper than
        // a right angle): it keeps its own, and is halved if the triangle still turns.
        let mut evened_now = Vec::new();
        for corners in to_even {
            let longest = (corners.iter())
                .map(|&v| push[v])
                .max_by(|a, b| a.length_squared().total_cmp(&b.length_squared()))
                .unwrap_or(DVec3::ZERO);
            for v in corners {
                let shared = DVec3::new(
                    if fixed[v].x { 0.0 } else { longest.x },
                    if fixed[v].y { 0.0 } else { longest.y },
                    longest.z,
                );
                if shared.dot(push[v]) >= 0.0 {
                    push[v] = shared;
                }
                evened[v] = true;
                evened_now.push(v);
            }
        }
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

/// The edges of `wall` on its border (in one triangle only) whose ends both lie on a
/// clip plane (any of `fixed`).
fn border_edges_on_planes(wall: &TriMesh, fixed: &[FixedAxes]) -> Vec<[usize; 2]> {
    let on_plane = |v: usize| fixed[v].on_a_plane();
    let mut uses: HashMap<[usize; 2], u32> = HashMap::new();
    for triangle in &wall.triangles {
        for k in 0..3 {
            let (a, b) = (triangle[k] as usize, triangle[(k + 1) % 3] as usize);
            *uses.entry([a.min(b), a.max(b)]).or_default() += 1;
        }
    }
    let mut edges: Vec<[usize; 2]> = uses
        .into_iter()
        .filter(|&([a, b], count)| count == 1 && on_plane(a) && on_plane(b))
        .map(|(edge, _)| edge)
        .collect();
    // The map's order is arbitrary; the evening below depends on the order it meets edges.
    edges.sort_unstable();
    edges
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
        without_turning_over(&wall, &wall.positions, &fixed, &mut push);
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
        without_turning_over(&wall, &wall.positions, &fixed, &mut push);
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
        let wall = TriMesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.1, 0.5, 0.5),
            ],
            vec![[0, 1, 2]],
        );
        let on_plane = FixedAxes { x: true, y: false };
        let fixed = [on_plane, on_plane, FixedAxes::default()];
        let border_push = DVec3::new(0.0, 0.0, 0.8);
        let mut push = vec![border_push, border_push, DVec3::ZERO];
        assert_eq!(turned_over(&wall, &moved(&wall, &push)), 1);
        without_turning_over(&wall, &wall.positions, &fixed, &mut push);
        assert_eq!(push, vec![border_push; 3]);
    }

    /// A border edge on a lateral clip plane (x fixed), 1 mm long, whose first corner is
    /// pushed 1.5 mm along it past the second: the wall's section on the plane folds
    /// back (on s04 with jittered landmarks the band stitched to it then crossed itself)
    /// while the inner corner's own push keeps the triangle from turning over, so only
    /// the edge shows it. Its corners move as one, by the longer push (exactly), and the
    /// edge keeps its direction.
    #[test]
    fn a_border_edge_folded_back_by_the_push_moves_as_one() {
        let wall = TriMesh::new(
            vec![
                DVec3::ZERO,
                DVec3::new(0.0, 1.0, 0.0),
                DVec3::new(0.2, 0.5, -1.0),
            ],
            vec![[0, 1, 2]],
        );
        let on_plane = FixedAxes { x: true, y: false };
        let fixed = [on_plane, on_plane, FixedAxes::default()];
        let longer = DVec3::new(0.0, 1.5, 0.0);
        let mut push = vec![longer, DVec3::ZERO, DVec3::new(0.0, 0.0, 1.2)];
        let edge = |p: &[DVec3]| p[1] - p[0];
        let raw = moved(&wall, &push);
        assert_eq!(turned_over(&wall, &raw), 0);
        assert!(edge(&raw).dot(edge(&wall.positions)) < 0.0);
        without_turning_over(&wall, &wall.positions, &fixed, &mut push);
        assert_eq!(push[0], longer);
        assert_eq!(push[1], longer);
        let after = moved(&wall, &push);
        assert_eq!(edge(&after), edge(&wall.positions));
        assert_eq!(turned_over(&wall, &after), 0);
    }

    /// The wall's positions moved by `push`.
    fn moved(wall: &TriMesh, push: &[DVec3]) -> Vec<DVec3> {
        (wall.positions.iter().zip(push))
            .map(|(p, d)| *p + *d)
            .collect()
    }
}
