//! Transfer between non-nested tetrahedral levels (for the geometric multigrid of
//! issue 5, item 4): prolongation by barycentric interpolation of each fine vertex in
//! the coarse level, with linear extrapolation from the nearest coarse element for fine
//! vertices outside it; restriction is its transpose.

use crate::system::NOT_FREE;
use glam::DVec3;
use rayon::prelude::*;
use tetmesh::{TetLocator, TetMesh};

/// One row of the prolongation: four `(coarse vertex, weight)` pairs.
pub type ProlongationRow = [(u32, f64); 4];

/// Prolongation from a coarse to a fine level: each fine vertex is the barycentric
/// combination of the four corners of its coarse element (weights sum to one; some are
/// negative when extrapolating outside the coarse mesh). Acts on every displacement
/// component alike. Affine fields are reproduced exactly.
#[derive(Debug, Clone, PartialEq)]
pub struct Prolongation {
    /// Number of coarse vertices (columns).
    pub coarse_count: usize,
    /// For each fine vertex (row): four `(coarse vertex, weight)` pairs.
    pub rows: Vec<ProlongationRow>,
    /// For each fine vertex, its distance to the coarse mesh (mm; zero inside).
    pub distance_mm: Vec<f64>,
}

impl Prolongation {
    /// Locates every vertex of `fine` in `coarse` (parallel). Returns `None` if `coarse`
    /// has no tetrahedra.
    pub fn new(coarse: &TetMesh, fine: &TetMesh) -> Option<Prolongation> {
        let locator = TetLocator::new(coarse);
        let located: Option<Vec<(ProlongationRow, f64)>> = fine
            .positions
            .par_iter()
            .map(|&p| {
                let loc = locator.locate_or_nearest(p)?;
                let t = coarse.tets[loc.tet];
                Some((
                    [0, 1, 2, 3].map(|k| (t[k], loc.barycentric[k])),
                    loc.distance_mm,
                ))
            })
            .collect();
        let (rows, distance_mm) = located?.into_iter().unzip();
        Some(Prolongation {
            coarse_count: coarse.positions.len(),
            rows,
            distance_mm,
        })
    }

    /// Number of fine vertices (rows).
    pub fn fine_count(&self) -> usize {
        self.rows.len()
    }

    /// `fine = P coarse`.
    pub fn prolong(&self, coarse: &[DVec3], fine: &mut [DVec3]) {
        assert_eq!(coarse.len(), self.coarse_count);
        assert_eq!(fine.len(), self.rows.len());
        fine.par_iter_mut().zip(&self.rows).for_each(|(f, row)| {
            *f = row.iter().map(|&(c, w)| coarse[c as usize] * w).sum();
        });
    }

    /// `coarse = Pᵀ fine` (serial scatter; deterministic).
    pub fn restrict(&self, fine: &[DVec3], coarse: &mut [DVec3]) {
        assert_eq!(coarse.len(), self.coarse_count);
        assert_eq!(fine.len(), self.rows.len());
        coarse.fill(DVec3::ZERO);
        for (f, row) in fine.iter().zip(&self.rows) {
            for &(c, w) in row {
                coarse[c as usize] += *f * w;
            }
        }
    }

    /// The operator between reduced (eliminated) systems: rows are the fine unknowns,
    /// columns the coarse unknowns (`reduced_of` maps of the two levels' systems, with
    /// [`NOT_FREE`] for constrained vertices). Coarse constrained vertices carry no
    /// correction and are dropped; fine constrained vertices have no row. Returned as
    /// CSR: `(row_ptr, cols, weights)`.
    pub fn reduced(
        &self,
        fine_reduced_of: &[u32],
        coarse_reduced_of: &[u32],
    ) -> (Vec<usize>, Vec<u32>, Vec<f64>) {
        assert_eq!(fine_reduced_of.len(), self.rows.len());
        assert_eq!(coarse_reduced_of.len(), self.coarse_count);
        let mut order: Vec<(u32, usize)> = fine_reduced_of
            .iter()
            .enumerate()
            .filter(|&(_, &r)| r != NOT_FREE)
            .map(|(v, &r)| (r, v))
            .collect();
        order.sort_unstable();
        let mut row_ptr = vec![0];
        let mut cols = Vec::new();
        let mut weights = Vec::new();
        for (_, v) in order {
            for &(c, w) in &self.rows[v] {
                let rc = coarse_reduced_of[c as usize];
                if rc != NOT_FREE && w != 0.0 {
                    cols.push(rc);
                    weights.push(w);
                }
            }
            row_ptr.push(cols.len());
        }
        (row_ptr, cols, weights)
    }
}
