//! Removing a surface's small self-intersections by smoothing them out locally.
//!
//! Scanner noise on a sharply curved spot (a nipple, an areola's rim) can fold a few
//! sub-millimetre triangles through their neighbours. Such a fold is not anatomy, yet a
//! closed surface containing it cannot be meshed into tetrahedra. [`untangle`] finds the
//! intersecting triangles ([`self_intersections`]), moves the vertices around them towards
//! the mean of their neighbours (uniform Laplacian steps, the region growing by one ring
//! each round) and checks again, until none is left or the rounds run out.

use crate::intersect::self_intersections;
use crate::smooth::laplacian_smooth;
use crate::topology::Topology;
use crate::trimesh::TriMesh;
use glam::DVec3;

/// Rounds of [`untangle`]: each smooths the region around every remaining intersection,
/// one ring wider than the round before.
const UNTANGLE_ROUNDS: usize = 8;
/// Laplacian steps per round ([`laplacian_smooth`]).
const STEPS_PER_ROUND: usize = 3;

/// What [`untangle`] did.
#[derive(Debug, Clone, PartialEq)]
pub struct Untangled {
    /// Intersecting triangle pairs found at first.
    pub pairs_found: usize,
    /// Vertices moved.
    pub vertices_moved: usize,
    /// The largest distance a vertex moved (mm).
    pub max_displacement_mm: f64,
    /// The centre of the intersecting triangles found first (mm), for messages.
    pub near: DVec3,
}

/// Smooths out the self-intersections of `mesh` by moving only vertices for which
/// `movable` is true (e.g. not on a border that must stay where it is), and only if
/// every intersecting triangle has a movable corner and no vertex moves farther than
/// `max_displacement_mm`: a fold of noise, not a crossing of two surfaces. Returns
/// `None` if the mesh had none; `Some` with what moved if all were removed; otherwise,
/// with `mesh` unchanged, the intersecting pairs (as [`self_intersections`]) that are
/// the reason: those with a triangle it may not move, else those left after the rounds
/// (found on the smoothed mesh: they say where, and may not cross in the mesh returned),
/// else (all removed, but moving a vertex too far) all it found.
pub fn untangle(
    mesh: &mut TriMesh,
    movable: impl Fn(u32) -> bool,
    max_displacement_mm: f64,
) -> Result<Option<Untangled>, Vec<(usize, usize)>> {
    let first_pairs = self_intersections(mesh);
    let Some(&(a, b)) = first_pairs.first() else {
        return Ok(None);
    };
    let held: Vec<(usize, usize)> = first_pairs
        .iter()
        .copied()
        .filter(|&(a, b)| {
            [a, b]
                .iter()
                .any(|&t| !mesh.triangles[t].iter().any(|&v| movable(v)))
        })
        .collect();
    if !held.is_empty() {
        return Err(held);
    }
    let mut pairs = first_pairs.clone();
    let centre = |mesh: &TriMesh, t: usize| mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0;
    let near = 0.5 * (centre(mesh, a) + centre(mesh, b));
    let pairs_found = pairs.len();
    let original = mesh.positions.clone();
    let topology = Topology::new(mesh);
    let mut moved = vec![false; mesh.vertex_count()];
    for round in 0..UNTANGLE_ROUNDS {
        if pairs.is_empty() {
            break;
        }
        let mut region = vec![false; mesh.vertex_count()];
        for &(a, b) in &pairs {
            for t in [a, b] {
                for &v in &mesh.triangles[t] {
                    region[v as usize] = true;
                }
            }
        }
        // Grow by `round + 1` rings, so a fold that resists widens the smoothing.
        for _ in 0..=round {
            let seeds: Vec<usize> = (0..region.len()).filter(|&v| region[v]).collect();
            for v in seeds {
                for n in topology.vertex_neighbors(mesh, v) {
                    region[n as usize] = true;
                }
            }
        }
        let vertices: Vec<usize> = (0..region.len())
            .filter(|&v| region[v] && movable(v as u32))
            .collect();
        if vertices.is_empty() {
            break;
        }
        laplacian_smooth(mesh, &topology, &vertices, STEPS_PER_ROUND);
        for &v in &vertices {
            moved[v] = true;
        }
        pairs = self_intersections(mesh);
    }
    let moved_by = (0..moved.len())
        .filter(|&v| moved[v])
        .map(|v| mesh.positions[v].distance(original[v]))
        .fold(0.0, f64::max);
    if !pairs.is_empty() || moved_by > max_displacement_mm {
        mesh.positions = original;
        return Err(if pairs.is_empty() { first_pairs } else { pairs });
    }
    Ok(Some(Untangled {
        pairs_found,
        vertices_moved: moved.iter().filter(|&&m| m).count(),
        max_displacement_mm: moved_by,
        near,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{grid, icosphere};

    #[test]
    fn a_vertex_pushed_through_the_far_side_is_smoothed_back() {
        // A 10 mm sphere with one vertex pushed through the centre out beyond the far
        // side: its triangles pierce the far side. Smoothing pulls it back towards its
        // neighbours until nothing crosses: back on its own side, within half the radius
        // of where it was (untangled, not restored: each step halves the distance).
        let sphere = icosphere(10.0, 3);
        let mut mesh = sphere.clone();
        let v = 0;
        mesh.positions[v] = -1.3 * sphere.positions[v];
        assert!(!self_intersections(&mesh).is_empty());
        let result = untangle(&mut mesh, |_| true, 30.0).unwrap().unwrap();
        assert!(self_intersections(&mesh).is_empty());
        assert!(result.pairs_found > 0);
        let back = mesh.positions[v].distance(sphere.positions[v]);
        assert!(back < 5.0, "{back} mm from where it was");
        // Far from the fold nothing moved.
        let far = (0..sphere.vertex_count())
            .filter(|&k| sphere.positions[k].distance(sphere.positions[v]) > 8.0)
            .filter(|&k| sphere.positions[k].distance(-sphere.positions[v]) > 8.0);
        for k in far {
            assert_eq!(mesh.positions[k], sphere.positions[k]);
        }
    }

    /// The same fold with the displacement capped at 1 mm (undoing it takes some 20), or
    /// with every vertex held: refused, the pairs returned, the mesh exactly as it was.
    #[test]
    fn a_fold_beyond_the_cap_or_on_held_vertices_is_refused_unchanged() {
        let sphere = icosphere(10.0, 3);
        let mut folded = sphere.clone();
        folded.positions[0] = -1.3 * sphere.positions[0];
        let pairs = self_intersections(&folded);
        let mut capped = folded.clone();
        assert_eq!(untangle(&mut capped, |_| true, 1.0), Err(pairs.clone()));
        assert_eq!(capped.positions, folded.positions);
        let mut held = folded.clone();
        assert_eq!(untangle(&mut held, |_| false, 30.0), Err(pairs));
        assert_eq!(held.positions, folded.positions);
    }

    /// Two folds of the sphere, one where vertices may move and one where none may: the
    /// error names only the pairs of the held fold, the one that blocks.
    #[test]
    fn the_error_names_the_fold_that_cannot_be_smoothed() {
        let sphere = icosphere(10.0, 3);
        let first = 0;
        // A vertex about a quarter turn round from the first: its fold and the far side
        // it pierces lie some 14 mm from the first fold's.
        let second = (0..sphere.vertex_count())
            .min_by(|&a, &b| {
                let off = |v: usize| sphere.positions[v].dot(sphere.positions[first]).abs();
                off(a).total_cmp(&off(b))
            })
            .unwrap();
        let mut folded = sphere.clone();
        for v in [first, second] {
            folded.positions[v] = -1.3 * sphere.positions[v];
        }
        let near = |v: u32, centre: DVec3| sphere.positions[v as usize].distance(centre) < 8.0;
        let at_first =
            |v: u32| near(v, sphere.positions[first]) || near(v, -sphere.positions[first]);
        let at_second = |t: usize| folded.triangles[t].iter().all(|&v| !at_first(v));
        let expected: Vec<(usize, usize)> = self_intersections(&folded)
            .into_iter()
            .filter(|&(a, b)| at_second(a) || at_second(b))
            .collect();
        assert!(!expected.is_empty());
        assert!(expected.len() < self_intersections(&folded).len());
        let mut mesh = folded.clone();
        assert_eq!(untangle(&mut mesh, at_first, 30.0), Err(expected));
        assert_eq!(mesh.positions, folded.positions);
    }

    #[test]
    fn a_clean_mesh_is_left_alone() {
        let mut mesh = grid(5, 5, 1.0);
        assert_eq!(untangle(&mut mesh, |_| true, 1.0), Ok(None));
        assert_eq!(mesh.positions, grid(5, 5, 1.0).positions);
    }
}
