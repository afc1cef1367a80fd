//! The warping rule of isosurface stuffing (Labelle and Shewchuk 2007), shared by the
//! uniform and the graded mesher: which lattice points move onto which cut points.

use rayon::prelude::*;

/// A cut point (where a lattice edge crosses the surface) as the warping rule sees it.
pub(crate) trait WarpCut: Sync {
    /// The edge's end inside the surface.
    fn inside(&self) -> u32;
    /// The edge's end outside the surface.
    fn outside(&self) -> u32;
    /// How close the cut lies to its end `point`, if close enough to violate it (smaller
    /// is closer; the unit is the mesher's own).
    fn violation(&self, point: u32) -> Option<f64>;
}

/// The lattice points to warp and the cut point each moves to: `(point, cut index)`,
/// sorted by point. The paper's order:
/// 1. while an outside point is violated by a cut point on an edge whose inside end is
///    not violated, it moves to the nearest such cut point (in rounds: all such points
///    at once, then the violations are updated);
/// 2. every inside point still violated moves to its nearest violating cut point.
///
/// A warped point drops the cut points on its edges, which may clear violations of its
/// neighbours. No edge ends up with both ends warped towards each other, and no cut
/// point is left violating an end.
pub(crate) fn warp_targets<C: WarpCut>(cuts: &[C]) -> Vec<(u32, u32)> {
    // Every point at the end of a cut, with its cuts: (point, cut) grouped by point.
    let mut incidence: Vec<(u32, u32)> = cuts
        .iter()
        .enumerate()
        .flat_map(|(c, cut)| [(cut.inside(), c as u32), (cut.outside(), c as u32)])
        .collect();
    incidence.sort_unstable();
    let points: Vec<&[(u32, u32)]> = incidence.chunk_by(|a, b| a.0 == b.0).collect();
    let cuts_of = |point: u32| points[points.partition_point(|g| g[0].0 < point)];
    let is_outside = |group: &[(u32, u32)]| cuts[group[0].1 as usize].outside() == group[0].0;
    let mut live = vec![true; cuts.len()];
    let violated = |point: u32, live: &[bool]| {
        cuts_of(point)
            .iter()
            .any(|&(_, c)| live[c as usize] && cuts[c as usize].violation(point).is_some())
    };
    // The nearest live cut violating the group's point among those `eligible`.
    let nearest = |group: &[(u32, u32)], live: &[bool], eligible: &dyn Fn(&C) -> bool| {
        group
            .iter()
            .filter(|&&(_, c)| live[c as usize] && eligible(&cuts[c as usize]))
            .filter_map(|&(point, c)| cuts[c as usize].violation(point).map(|d| (d, c)))
            .min_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)))
            .map(|(_, c)| (group[0].0, c))
    };
    let mut warps: Vec<(u32, u32)> = Vec::new();
    loop {
        let round: Vec<(u32, u32)> = points
            .par_iter()
            .filter(|g| is_outside(g))
            .filter_map(|g| nearest(g, &live, &|cut: &C| !violated(cut.inside(), &live)))
            .collect();
        if round.is_empty() {
            break;
        }
        for &(point, _) in &round {
            for &(_, c) in cuts_of(point) {
                live[c as usize] = false;
            }
        }
        warps.extend(round);
    }
    // Inside points share no cut edge, so their warps are independent.
    warps.par_extend(
        points
            .par_iter()
            .filter(|g| !is_outside(g))
            .filter_map(|g| nearest(g, &live, &|_| true)),
    );
    warps.par_sort_unstable();
    warps
}
