//! Per-element geometry: normals, areas, enclosed volume, bounding box, and which
//! positions a body scan can hold.

use crate::trimesh::TriMesh;
use glam::DVec3;

/// How far from its origin (mm) a position of a body scan, a landmark or a control point
/// may lie: a kilometre. Beyond it a coordinate is a damaged or mis-scaled file, and
/// squared distances would overflow.
pub const MAX_COORDINATE_MM: f64 = 1e6;

/// `Err` with what is wrong when `p` is not a position a scan can hold: a coordinate
/// that is not finite, or lies more than [`MAX_COORDINATE_MM`] from the origin.
pub fn check_position(p: DVec3) -> Result<(), String> {
    if !p.is_finite() {
        return Err(format!("non-finite coordinate {p}"));
    }
    let largest = p.abs().max_element();
    if largest > MAX_COORDINATE_MM {
        return Err(format!(
            "a coordinate of {largest:.3e} mm lies more than a kilometre from the origin (a \
             damaged file, or not in millimetres)"
        ));
    }
    Ok(())
}

impl TriMesh {
    /// Unit normal of triangle `t` (zero for a degenerate triangle).
    #[inline]
    pub fn triangle_normal(&self, t: usize) -> DVec3 {
        let [a, b, c] = self.triangle_positions(t);
        (b - a).cross(c - a).normalize_or_zero()
    }

    /// Area of triangle `t` (mm²).
    #[inline]
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangle_positions(t);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Unit normals of all triangles.
    pub fn triangle_normals(&self) -> Vec<DVec3> {
        (0..self.triangles.len())
            .map(|t| self.triangle_normal(t))
            .collect()
    }

    /// Area-weighted unit vertex normals (zero for a vertex without triangles).
    pub fn vertex_normals(&self) -> Vec<DVec3> {
        let mut normals = vec![DVec3::ZERO; self.positions.len()];
        for t in 0..self.triangles.len() {
            let [a, b, c] = self.triangle_positions(t);
            // The cross product's length is twice the area: area weighting for free.
            let weighted = (b - a).cross(c - a);
            for &v in &self.triangles[t] {
                normals[v as usize] += weighted;
            }
        }
        normals.iter().map(|n| n.normalize_or_zero()).collect()
    }

    /// Angle-weighted unit vertex normals (Thürmer and Wüthrich): each triangle's unit
    /// normal weighted by its angle at the vertex. Unlike area weighting they do not
    /// depend on how the fan around a vertex is triangulated, and they are the vertex
    /// pseudo-normals that decide the inside of a closed surface robustly (Bærentzen
    /// and Aanæs 2005). Zero for a vertex without (non-degenerate) triangles.
    pub fn angle_weighted_vertex_normals(&self) -> Vec<DVec3> {
        let mut normals = vec![DVec3::ZERO; self.positions.len()];
        for t in 0..self.triangles.len() {
            let corners = self.triangle_positions(t);
            let normal = self.triangle_normal(t);
            for k in 0..3 {
                let (here, next, previous) =
                    (corners[k], corners[(k + 1) % 3], corners[(k + 2) % 3]);
                let angle = (next - here).angle_between(previous - here);
                if angle.is_finite() {
                    normals[self.triangles[t][k] as usize] += normal * angle;
                }
            }
        }
        normals.iter().map(|n| n.normalize_or_zero()).collect()
    }

    /// Total surface area (mm²).
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|t| self.triangle_area(t))
            .sum()
    }

    /// Signed enclosed volume by the divergence theorem (mm³): positive for a closed mesh
    /// with outward-facing triangles. For an open mesh the value depends on the origin;
    /// the centroid of the vertices is used as origin to keep round-off small.
    pub fn signed_volume(&self) -> f64 {
        let origin = self.centroid();
        let six_volume: f64 = (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle_positions(t);
                (a - origin).dot((b - origin).cross(c - origin))
            })
            .sum();
        six_volume / 6.0
    }

    /// Mean of the vertex positions.
    pub fn centroid(&self) -> DVec3 {
        if self.positions.is_empty() {
            return DVec3::ZERO;
        }
        self.positions.iter().copied().sum::<DVec3>() / self.positions.len() as f64
    }

    /// Axis-aligned bounding box `(min, max)`.
    pub fn bounding_box(&self) -> (DVec3, DVec3) {
        self.positions.iter().fold(
            (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
            |(lo, hi), &p| (lo.min(p), hi.max(p)),
        )
    }

    /// Mean edge length (mm), counting each triangle's three edges.
    pub fn mean_edge_length(&self) -> f64 {
        if self.triangles.is_empty() {
            return 0.0;
        }
        let total: f64 = (0..self.triangles.len())
            .map(|t| {
                let [a, b, c] = self.triangle_positions(t);
                a.distance(b) + b.distance(c) + c.distance(a)
            })
            .sum();
        total / (3 * self.triangles.len()) as f64
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::cube;

    #[test]
    fn cube_volume_area_and_normals() {
        let mesh = cube(2.0);
        // Exact in floating point for an axis-aligned cube.
        assert!((mesh.signed_volume() - 8.0).abs() < 1e-12);
        assert!((mesh.area() - 24.0).abs() < 1e-12);
        let normals = mesh.vertex_normals();
        let expected = DVec3::splat(-1.0).normalize();
        assert!(normals[0].distance(expected) < 1e-12);
    }

    #[test]
    fn angle_weighted_normals_ignore_how_the_corner_is_triangulated() {
        // Each cube corner meets three faces at 90° each, however they are split into
        // triangles: the normal is the corner's diagonal.
        let mesh = cube(2.0);
        let centre = DVec3::splat(1.0);
        for (p, normal) in mesh
            .positions
            .iter()
            .zip(mesh.angle_weighted_vertex_normals())
        {
            assert!(normal.distance((*p - centre).normalize()) < 1e-12, "{p}");
        }
    }

    #[test]
    fn flipped_cube_has_negative_volume() {
        let mut mesh = cube(1.0);
        for tri in &mut mesh.triangles {
            tri.swap(1, 2);
        }
        assert!((mesh.signed_volume() + 1.0).abs() < 1e-12);
    }
}
