//! Points on the scan carried with the simulation: a point is remembered by the scan
//! triangle it lies on and its barycentric coordinates there, so that on a simulated
//! frame (the same triangles, the vertices moved) it is where the tissue under it went.
//! The session carries the landmarks the same way; the window carries the cut curves and
//! the implant outlines.

use glam::DVec3;
use mesh::SurfaceIndex;

/// A point on a scan by its triangle and barycentric coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceAnchor {
    triangle: usize,
    weights: [f64; 3],
}

impl SurfaceAnchor {
    /// The closest point of the scan (its spatial index) to `point`.
    pub fn nearest(index: &SurfaceIndex, point: DVec3) -> SurfaceAnchor {
        let closest = index.closest_point(point);
        SurfaceAnchor {
            triangle: closest.triangle,
            weights: closest.barycentric,
        }
    }

    /// Where the point is when the scan's vertices are at `positions` (its triangles
    /// `triangles`).
    pub fn on(&self, triangles: &[[u32; 3]], positions: &[DVec3]) -> DVec3 {
        let corners = triangles[self.triangle];
        (0..3)
            .map(|k| positions[corners[k] as usize] * self.weights[k])
            .sum()
    }
}

/// The anchors of `points` on the scan of `index`.
pub fn anchors(index: &SurfaceIndex, points: &[DVec3]) -> Vec<SurfaceAnchor> {
    points
        .iter()
        .map(|&p| SurfaceAnchor::nearest(index, p))
        .collect()
}

/// Where `anchors` are when the scan's vertices are at `positions`.
pub fn carried(
    anchors: &[SurfaceAnchor],
    triangles: &[[u32; 3]],
    positions: &[DVec3],
) -> Vec<DVec3> {
    anchors.iter().map(|a| a.on(triangles, positions)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_follows_an_affine_motion_of_the_scan_exactly() {
        // Barycentric coordinates are invariant under affine maps: a sheet sheared and
        // moved carries its points to their images.
        let sheet = mesh::shapes::grid(10, 10, 1.0);
        let index = SurfaceIndex::new(&sheet).unwrap();
        let motion = |p: DVec3| DVec3::new(p.x + 0.3 * p.y, 2.0 * p.y, p.z + 0.5 * p.x + 4.0);
        let points = [DVec3::new(2.25, 7.5, 0.0), DVec3::new(9.9, 0.1, 0.0)];
        let moved: Vec<DVec3> = sheet.positions.iter().map(|&p| motion(p)).collect();
        for (point, carried) in
            points
                .iter()
                .zip(carried(&anchors(&index, &points), &sheet.triangles, &moved))
        {
            assert!(carried.distance(motion(*point)) < 1e-12, "{carried}");
        }
    }
}
