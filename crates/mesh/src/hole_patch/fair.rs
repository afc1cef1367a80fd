//! Step 3: fairing. The interior vertices minimise `sum_v |L x_v|^2` over every patch
//! vertex `v`, `L` the uniform umbrella Laplacian (the mean of the neighbours minus the
//! vertex); the loop's vertices and their neighbours on the surface are held. The normal
//! equations are symmetric positive definite (the Laplacian of the interior with the loop
//! held is invertible on a connected patch) and solved by sparse Cholesky.

use super::HolePatchError;
use faer::linalg::solvers::Solve;
use faer::sparse::{SparseColMat, Triplet};
use faer::{Mat, Side};
use glam::DVec3;

/// Moves `positions[loop_len..]` to the faired surface of `triangles`. `ring[k]` holds
/// the positions of loop vertex `k`'s neighbours on the surface that are not loop
/// vertices themselves.
pub(super) fn fair(
    positions: &mut [DVec3],
    triangles: &[[u32; 3]],
    loop_len: usize,
    ring: &[Vec<DVec3>],
) -> Result<(), HolePatchError> {
    let free = positions.len() - loop_len;
    if free == 0 {
        return Ok(());
    }
    let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); positions.len()];
    for t in triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            for (from, to) in [(a, b), (b, a)] {
                if !neighbours[from as usize].contains(&to) {
                    neighbours[from as usize].push(to);
                }
            }
        }
    }
    let mut triplets = Vec::new();
    let mut rhs = Mat::<f64>::zeros(free, 3);
    let mut row: Vec<(usize, f64)> = Vec::new();
    for (v, around) in neighbours.iter().enumerate() {
        let fixed_ring = ring.get(v).map_or(&[][..], Vec::as_slice);
        let degree = (around.len() + fixed_ring.len()) as f64;
        if degree == 0.0 {
            continue;
        }
        // Row v: sum_j c_j x_j (free) + constant.
        row.clear();
        let mut constant: DVec3 = fixed_ring.iter().sum::<DVec3>() / degree;
        let mut add = |vertex: usize, coefficient: f64, row: &mut Vec<(usize, f64)>| {
            if vertex >= loop_len {
                row.push((vertex - loop_len, coefficient));
            } else {
                constant += coefficient * positions[vertex];
            }
        };
        add(v, -1.0, &mut row);
        for &w in around {
            add(w as usize, 1.0 / degree, &mut row);
        }
        for &(p, cp) in &row {
            for &(q, cq) in &row {
                triplets.push(Triplet::new(p, q, cp * cq));
            }
            for axis in 0..3 {
                rhs[(p, axis)] -= cp * constant[axis];
            }
        }
    }
    let matrix = SparseColMat::<usize, f64>::try_new_from_triplets(free, free, &triplets)
        .map_err(|e| HolePatchError::Fairing(format!("{e:?}")))?;
    let factor = matrix
        .sp_cholesky(Side::Lower)
        .map_err(|e| HolePatchError::Fairing(format!("{e:?}")))?;
    let solution = factor.solve(&rhs);
    for j in 0..free {
        let p = DVec3::new(solution[(j, 0)], solution[(j, 1)], solution[(j, 2)]);
        if !p.is_finite() {
            return Err(HolePatchError::Fairing(
                "the solution is not finite".to_string(),
            ));
        }
        positions[loop_len + j] = p;
    }
    Ok(())
}
