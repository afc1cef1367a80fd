//! Point-to-surface deviation: the distance from a point to the closest point of a
//! triangle surface (through the surface's BVH), unsigned and signed along the surface's
//! outward normal, and the overlap of two open scans.
//!
//! # Sign
//! The sign is that of `(p - q) · n`, where `q` is the closest surface point and `n` the
//! pseudo-normal of the feature `q` lies on (Bærentzen and Aanæs 2005): the triangle's
//! normal inside a triangle, the sum of both triangles' normals on an edge, the
//! angle-weighted vertex normal at a vertex. Unlike an interpolated normal this is
//! exact: a point in front of the surface (on the side the normals point to, outside the
//! body) is positive, a point behind it negative, whichever feature is nearest.
//!
//! # Overlap
//! Scans are open surfaces (the back and areas hidden from the cameras are missing,
//! scanner holes). A point whose closest surface point lies on the surface's boundary
//! (an edge with one triangle, or a vertex on such an edge: the scan's outer border or
//! a hole's rim) lies beyond the surface rather than over it, and its distance measures
//! the gap to the border, not a deviation: such points are outside the overlap. So are
//! points farther than a maximum distance from the surface ([`DEFAULT_MAX_DISTANCE_MM`]),
//! which are not the same skin. A point is in the overlap when its closest point lies
//! inside the surface (in a triangle or on an interior edge or vertex) within that
//! distance.

use glam::DVec3;
use mesh::topology::NO_TRIANGLE;
use mesh::{SurfaceIndex, Topology, TriMesh};
use rayon::prelude::*;

/// Default largest distance (mm) at which a point still counts as over the other
/// surface. Beyond it two scans of a torso are not the same skin; 50 mm keeps every
/// clinically plausible change (an implant adds at most about 60 mm of projection at
/// the nipple, a cup size about 15-25 mm) and both scans' landmarks must already agree
/// for registration.
pub const DEFAULT_MAX_DISTANCE_MM: f64 = 50.0;

/// Barycentric coordinates at or below this count as zero: the closest point lies on
/// the triangle's edge or corner. Closest points on an edge or corner come back from the
/// BVH with round-off of about 1e-16 there; points inside a triangle this close to an
/// edge are 1e-9 of an edge length (a nanometre) from it.
const ON_FEATURE_TOLERANCE: f64 = 1e-9;

/// How far a point lies from a surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PointDeviation {
    /// Distance to the closest surface point (mm).
    pub distance_mm: f64,
    /// The distance, positive in front of the surface (the side its normals point to),
    /// negative behind it (mm).
    pub signed_distance_mm: f64,
    /// The closest surface point (mm).
    pub closest_point: DVec3,
}

/// A surface prepared for point-to-surface deviations: its BVH, topology, normals and
/// boundary.
pub struct DistanceSurface<'a> {
    mesh: &'a TriMesh,
    index: &'a SurfaceIndex,
    topology: &'a Topology,
    triangle_normals: Vec<DVec3>,
    vertex_normals: Vec<DVec3>,
    boundary_vertex: Vec<bool>,
}

impl<'a> DistanceSurface<'a> {
    /// Prepares `mesh` with its BVH and topology (built from this mesh).
    pub fn new(
        mesh: &'a TriMesh,
        index: &'a SurfaceIndex,
        topology: &'a Topology,
    ) -> DistanceSurface<'a> {
        let mut boundary_vertex = vec![false; mesh.vertex_count()];
        for (corners, neighbors) in mesh.triangles.iter().zip(&topology.triangle_neighbors) {
            for k in 0..3 {
                if neighbors[k] == NO_TRIANGLE {
                    boundary_vertex[corners[k] as usize] = true;
                    boundary_vertex[corners[(k + 1) % 3] as usize] = true;
                }
            }
        }
        DistanceSurface {
            mesh,
            index,
            topology,
            triangle_normals: mesh.triangle_normals(),
            vertex_normals: mesh.angle_weighted_vertex_normals(),
            boundary_vertex,
        }
    }

    /// The surface mesh.
    pub fn mesh(&self) -> &TriMesh {
        self.mesh
    }

    /// The deviation of `point` from the surface, or `None` if it is outside the overlap
    /// (its closest point is on the boundary, or farther than `max_distance_mm`).
    pub fn deviation(&self, point: DVec3, max_distance_mm: f64) -> Option<PointDeviation> {
        let closest = self.index.closest_point_within(point, max_distance_mm)?;
        let normal = self.pseudo_normal(closest.triangle, closest.barycentric)?;
        let side = (point - closest.point).dot(normal);
        Some(PointDeviation {
            distance_mm: closest.distance,
            signed_distance_mm: if side < 0.0 {
                -closest.distance
            } else {
                closest.distance
            },
            closest_point: closest.point,
        })
    }

    /// The deviations of many points (in parallel), `None` outside the overlap.
    pub fn deviations(
        &self,
        points: &[DVec3],
        max_distance_mm: f64,
    ) -> Vec<Option<PointDeviation>> {
        points
            .par_iter()
            .map(|&p| self.deviation(p, max_distance_mm))
            .collect()
    }

    /// The vertex nearest to `point`'s closest surface point (the corner of its triangle
    /// with the largest barycentric weight), if that point is within `max_distance_mm`.
    pub fn nearest_vertex(&self, point: DVec3, max_distance_mm: f64) -> Option<usize> {
        let closest = self.index.closest_point_within(point, max_distance_mm)?;
        let corner =
            (0..3).max_by(|&a, &b| closest.barycentric[a].total_cmp(&closest.barycentric[b]))?;
        Some(self.mesh.triangles[closest.triangle][corner] as usize)
    }

    /// The pseudo-normal of the feature of `triangle` at `barycentric` (see the module
    /// documentation), or `None` on the boundary.
    fn pseudo_normal(&self, triangle: usize, barycentric: [f64; 3]) -> Option<DVec3> {
        let on_opposite_edge = barycentric.map(|b| b <= ON_FEATURE_TOLERANCE);
        match on_opposite_edge.iter().filter(|&&zero| zero).count() {
            0 => Some(self.triangle_normals[triangle]),
            1 => {
                // The edge opposite corner j runs from corner j + 1 to j + 2: edge j + 1.
                let j = on_opposite_edge.iter().position(|&zero| zero)?;
                let neighbor = self.topology.triangle_neighbors[triangle][(j + 1) % 3];
                (neighbor != NO_TRIANGLE).then(|| {
                    self.triangle_normals[triangle] + self.triangle_normals[neighbor as usize]
                })
            }
            _ => {
                let corner = (0..3).max_by(|&a, &b| barycentric[a].total_cmp(&barycentric[b]))?;
                let vertex = self.mesh.triangles[triangle][corner] as usize;
                (!self.boundary_vertex[vertex]).then_some(self.vertex_normals[vertex])
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::{grid, icosphere};

    fn prepared(mesh: &TriMesh) -> (SurfaceIndex, Topology) {
        (SurfaceIndex::new(mesh).unwrap(), Topology::new(mesh))
    }

    #[test]
    fn sign_follows_the_outward_normal_at_faces_edges_and_vertices() {
        let sphere = icosphere(50.0, 2);
        let (index, topology) = prepared(&sphere);
        let surface = DistanceSurface::new(&sphere, &index, &topology);
        // Points along the rays through vertices, edge midpoints and triangle centres,
        // inside and outside: the sign must say which.
        let mut directions: Vec<DVec3> = sphere.positions.clone();
        for t in 0..sphere.triangle_count() {
            let [a, b, c] = sphere.triangle_positions(t);
            directions.push(a + b);
            directions.push(a + b + c);
        }
        for direction in directions {
            let direction = direction.normalize();
            for radius in [20.0, 49.0, 51.0, 80.0] {
                let deviation = surface.deviation(direction * radius, 100.0).unwrap();
                assert_eq!(
                    deviation.signed_distance_mm > 0.0,
                    radius > 50.0,
                    "{direction} at {radius}"
                );
                assert_eq!(
                    deviation.signed_distance_mm.abs(),
                    deviation.distance_mm,
                    "{direction}"
                );
            }
        }
    }

    #[test]
    fn points_beyond_the_boundary_or_too_far_are_outside_the_overlap() {
        // A 10 x 10 mm plane patch at z = 0, normals +z.
        let patch = grid(10, 10, 1.0);
        let (index, topology) = prepared(&patch);
        let surface = DistanceSurface::new(&patch, &index, &topology);
        let over = surface.deviation(DVec3::new(4.3, 6.1, -2.0), 10.0).unwrap();
        assert!((over.signed_distance_mm + 2.0).abs() < 1e-12);
        // Beyond an edge, beyond a corner, right above a border edge.
        for beyond in [
            DVec3::new(12.0, 5.0, 1.0),
            DVec3::new(-1.0, -1.0, 0.5),
            DVec3::new(5.0, 0.0, 1.0),
        ] {
            assert_eq!(surface.deviation(beyond, 10.0), None, "{beyond}");
        }
        assert_eq!(surface.deviation(DVec3::new(5.0, 5.0, 11.0), 10.0), None);
    }
}
