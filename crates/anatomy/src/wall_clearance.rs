//! Keeping the rear wall clear of the scan (paper IV-C's shifted base).
//!
//! The wall is the filled base translated posteriorly. Where the scan runs almost parallel
//! to that direction, a translation does not move the wall away from it: under a hanging
//! breast the fill-in leaves the fold nearly level with the breast's underside, and the
//! translated copy stays within a millimetre of it (or crosses it where scanner noise
//! raises the skin). [`keep_wall_clear`] pushes such wall vertices further inside, along
//! the scan's inward normal at their nearest scan point, towards the clearance behind the
//! scan, for a bounded number of rounds (what is still too close is reported); the push
//! is smoothed over some ten rings of the wall so it bends rather than dents. A wall with
//! no vertex too close stays exactly the translated copy.

use glam::DVec3;
use mesh::{SurfaceIndex, Topology, TriMesh};

/// Rounds of push and check.
const ROUNDS: usize = 8;
/// Smoothing passes over the push per round (each averages a vertex's push with its
/// neighbours'), spreading a local push over some ten rings of the wall.
const SMOOTHING_PASSES: usize = 10;

/// Which coordinates of a wall vertex must not change: a vertex on a lateral clip plane
/// keeps its x, one on the top or bottom plane its y (so the wall's border stays on the
/// planes and meets the scan's at the same corners).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(crate) struct FixedAxes {
    pub x: bool,
    pub y: bool,
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
}
