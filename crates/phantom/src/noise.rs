//! Measurement noise along the normals, kept from folding the scan through itself.

use mesh::TriMesh;
use rand::Rng;
use rand_distr::Normal;

/// Passes of [`damp_where_crossing`] that halve the noise at crossing triangles; after
/// them (2^-12 of the noise, far below any scanner's resolution) a vertex still on a
/// crossing triangle loses its noise.
const MAX_DAMPING_PASSES: usize = 12;

/// Adds Gaussian noise of standard deviation `noise_mm` along each vertex normal of
/// `scan` (which has `full_skin`'s vertices and triangles, without noise), then damps it
/// where it makes the scan cross itself ([`damp_where_crossing`]).
pub(crate) fn add_noise(
    scan: &mut TriMesh,
    full_skin: &TriMesh,
    noise_mm: f64,
    rng: &mut impl Rng,
) {
    let Ok(distribution) = Normal::new(0.0, noise_mm) else {
        return;
    };
    let normals = scan.vertex_normals();
    for (position, normal) in scan.positions.iter_mut().zip(normals) {
        *position += normal * rng.sample(distribution);
    }
    damp_where_crossing(scan, full_skin);
}

/// Where independent noise on either side of a tight crease (the fold under a large,
/// hanging breast, its two sheets a fraction of a millimetre apart) makes the scan
/// cross itself, halves the noise of the crossing triangles' corners until it no
/// longer does: a scanner's surface reconstruction gives a surface that does not cross
/// itself, and the model rightly refuses one that does. `full_skin` (the same vertices
/// and triangles, without noise) must not cross itself; elsewhere the noise is kept.
fn damp_where_crossing(scan: &mut TriMesh, full_skin: &TriMesh) {
    for pass in 0..=MAX_DAMPING_PASSES {
        let crossing = mesh::self_intersections(scan);
        if crossing.is_empty() {
            return;
        }
        let keep = if pass == MAX_DAMPING_PASSES { 0.0 } else { 0.5 };
        let mut damped = vec![false; scan.positions.len()];
        for (a, b) in crossing {
            for v in scan.triangles[a].into_iter().chain(scan.triangles[b]) {
                damped[v as usize] = true;
            }
        }
        for (v, _) in damped.iter().enumerate().filter(|(_, d)| **d) {
            let truth = full_skin.positions[v];
            scan.positions[v] = truth + (scan.positions[v] - truth) * keep;
        }
    }
}
