//! Closest-point and ray queries on a triangle mesh through a bounding volume hierarchy.
//!
//! Built on parry3d-f64's BVH (well kept, f64, glam types); we only translate its
//! answers into triangle indices and barycentric coordinates the pipeline can use.

use crate::trimesh::TriMesh;
use glam::DVec3;
use parry3d_f64::query::{PointQuery, Ray};
use parry3d_f64::shape::{CompositeShapeRef, TriMesh as ParryMesh, TriMeshFlags};

/// The point of a mesh nearest to a query point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClosestPoint {
    /// The nearest point on the surface (mm).
    pub point: DVec3,
    /// The triangle it lies on.
    pub triangle: usize,
    /// Barycentric coordinates of `point` in that triangle (sum to one).
    pub barycentric: [f64; 3],
    /// Distance from the query point (mm).
    pub distance: f64,
}

/// Where a ray first meets a mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Ray parameter of the hit: `origin + t * direction`.
    pub t: f64,
    /// The hit point (mm).
    pub point: DVec3,
    /// The triangle hit.
    pub triangle: usize,
}

/// A BVH over a mesh's triangles for nearest-point and ray queries.
/// The index holds its own copy of the geometry: rebuild it when the mesh moves.
pub struct SurfaceIndex {
    bvh: ParryMesh,
}

impl SurfaceIndex {
    /// Builds the index. Returns `None` for a mesh without triangles.
    pub fn new(mesh: &TriMesh) -> Option<SurfaceIndex> {
        if mesh.triangles.is_empty() {
            return None;
        }
        ParryMesh::with_flags(
            mesh.positions.clone(),
            mesh.triangles.clone(),
            TriMeshFlags::empty(),
        )
        .ok()
        .map(|bvh| SurfaceIndex { bvh })
    }

    /// The nearest surface point to `query`.
    pub fn closest_point(&self, query: DVec3) -> ClosestPoint {
        self.closest_point_within(query, f64::MAX)
            .expect("a non-empty mesh always has a nearest point")
    }

    /// The nearest surface point to `query` if it is within `max_distance` (mm).
    pub fn closest_point_within(&self, query: DVec3, max_distance: f64) -> Option<ClosestPoint> {
        let (triangle, projection, _) = CompositeShapeRef(&self.bvh)
            .project_local_point_and_get_feature(query, max_distance)?;
        let triangle = triangle as usize;
        let corners = self.bvh.triangle(triangle as u32);
        let barycentric = barycentric(projection.point, [corners.a, corners.b, corners.c]);
        Some(ClosestPoint {
            point: projection.point,
            triangle,
            barycentric,
            distance: projection.point.distance(query),
        })
    }

    /// The first hit of the ray `origin + t * direction`, `0 <= t <= max_t`, from either
    /// side of the surface.
    pub fn cast_ray(&self, origin: DVec3, direction: DVec3, max_t: f64) -> Option<RayHit> {
        let ray = Ray::new(origin, direction);
        let (triangle, hit) =
            CompositeShapeRef(&self.bvh).cast_local_ray_and_get_normal(&ray, max_t, false)?;
        Some(RayHit {
            t: hit.time_of_impact,
            point: ray.point_at(hit.time_of_impact),
            triangle: triangle as usize,
        })
    }

    /// Whether `query` lies within `distance` (mm) of the surface.
    pub fn is_within(&self, query: DVec3, distance: f64) -> bool {
        self.bvh.distance_to_local_point(query, true) <= distance
    }
}

/// Barycentric coordinates of `p` (assumed in the triangle's plane) with respect to the
/// corners; a degenerate triangle gives the nearest corner weight one.
pub fn barycentric(p: DVec3, [a, b, c]: [DVec3; 3]) -> [f64; 3] {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d00, d01, d11) = (ab.dot(ab), ab.dot(ac), ac.dot(ac));
    let (d20, d21) = (ap.dot(ab), ap.dot(ac));
    let denominator = d00 * d11 - d01 * d01;
    if denominator.abs() <= f64::EPSILON * d00 * d11 {
        let distances = [
            p.distance_squared(a),
            p.distance_squared(b),
            p.distance_squared(c),
        ];
        let nearest = (0..3)
            .min_by(|&i, &j| distances[i].total_cmp(&distances[j]))
            .unwrap_or(0);
        let mut weights = [0.0; 3];
        weights[nearest] = 1.0;
        return weights;
    }
    let v = (d11 * d20 - d01 * d21) / denominator;
    let w = (d00 * d21 - d01 * d20) / denominator;
    [1.0 - v - w, v, w]
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::{grid, icosphere};

    #[test]
    fn closest_point_on_a_plane_grid_is_the_orthogonal_foot() {
        let mesh = grid(10, 10, 1.0);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let query = DVec3::new(3.3, 4.6, 2.5);
        let hit = index.closest_point(query);
        assert!(hit.point.distance(DVec3::new(3.3, 4.6, 0.0)) < 1e-12);
        assert!((hit.distance - 2.5).abs() < 1e-12);
        // The reported triangle and barycentrics reproduce the point.
        let corners = mesh.triangle_positions(hit.triangle);
        let rebuilt: DVec3 = (0..3).map(|k| corners[k] * hit.barycentric[k]).sum();
        assert!(rebuilt.distance(hit.point) < 1e-12);
        assert!(index.closest_point_within(query, 2.0).is_none());
        assert!(index.is_within(query, 2.6));
    }

    #[test]
    fn closest_point_agrees_with_brute_force_on_a_sphere() {
        let mesh = icosphere(50.0, 3);
        let index = SurfaceIndex::new(&mesh).unwrap();
        for k in 0..50 {
            let angle = k as f64 * 0.7;
            let query = DVec3::new(
                angle.cos() * 80.0,
                angle.sin() * 30.0,
                (k as f64 - 25.0) * 3.0,
            );
            let fast = index.closest_point(query).distance;
            let brute = (0..mesh.triangle_count())
                .map(|t| {
                    let [a, b, c] = mesh.triangle_positions(t);
                    parry3d_f64::shape::Triangle::new(a, b, c).distance_to_local_point(query, true)
                })
                .fold(f64::INFINITY, f64::min);
            assert!((fast - brute).abs() < 1e-9, "{fast} vs {brute}");
        }
    }

    #[test]
    fn ray_hits_the_sphere_at_its_radius() {
        let mesh = icosphere(50.0, 4);
        let index = SurfaceIndex::new(&mesh).unwrap();
        let hit = index
            .cast_ray(DVec3::new(0.0, 0.0, -200.0), DVec3::Z, 1000.0)
            .unwrap();
        // The polyhedron is inscribed: the hit lies between the inradius and 50 mm.
        assert!(
            hit.point.z > -50.0 - 1e-9 && hit.point.z < -49.5,
            "{:?}",
            hit.point
        );
        assert!(
            index
                .cast_ray(DVec3::new(0.0, 0.0, -200.0), DVec3::X, 1000.0)
                .is_none()
        );
    }
}
