//! The mesher's input: a closed triangle surface, checked once and indexed for the two
//! queries stuffing needs (inside/outside of a point, crossing of a segment).

use crate::error::TetraError;
use crate::winding::{Crossing, WindingIndex};
use glam::DVec3;
use mesh::{SurfaceIndex, Topology, TriMesh, manifold_report, self_intersections};

/// Relative overshoot of segment ray casts at both ends, so a crossing exactly at an end
/// point is found.
const SEGMENT_PAD: f64 = 1e-9;
/// Bisection steps when a ray cast misses (2⁻⁵⁰ of the segment length).
const BISECTION_STEPS: usize = 50;

/// A watertight, 2-manifold, outward-oriented surface without self-intersections.
pub struct ClosedSurface {
    winding: WindingIndex,
    rays: SurfaceIndex,
    volume_mm3: f64,
    bounds: (DVec3, DVec3),
}

impl ClosedSurface {
    /// Checks `mesh` and indexes it. Errors, in the order checked: invalid mesh (empty,
    /// non-finite, bad index), not watertight or not consistently oriented, oriented
    /// inward, self-intersecting.
    pub fn new(mesh: &TriMesh) -> Result<ClosedSurface, TetraError> {
        mesh.validate().map_err(TetraError::InvalidSurface)?;
        let report = manifold_report(mesh, &Topology::new(mesh));
        if !report.is_watertight_manifold() {
            return Err(TetraError::NotWatertight(report));
        }
        let volume_mm3 = mesh.signed_volume();
        if volume_mm3 <= 0.0 {
            return Err(TetraError::InwardOriented { volume_mm3 });
        }
        let pairs = self_intersections(mesh);
        if let Some(&first) = pairs.first() {
            return Err(TetraError::SelfIntersecting {
                pairs: pairs.len(),
                first,
            });
        }
        let rays =
            SurfaceIndex::new(mesh).ok_or(TetraError::InvalidSurface(mesh::MeshError::Empty))?;
        Ok(ClosedSurface {
            winding: WindingIndex::new(mesh),
            rays,
            volume_mm3,
            bounds: mesh.bounding_box(),
        })
    }

    /// Enclosed volume (mm³).
    pub fn volume_mm3(&self) -> f64 {
        self.volume_mm3
    }

    /// Axis-aligned bounding box `(lo, hi)` (mm).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        self.bounds
    }

    /// Whether `p` is inside (winding number not zero; points on the surface fall on
    /// either side, consistently).
    pub fn contains(&self, p: DVec3) -> bool {
        self.winding.winding_number(p) != 0
    }

    /// The crossings of the line through `(y, z)` parallel to x, sorted by x.
    pub(crate) fn line_crossings(&self, y: f64, z: f64, out: &mut Vec<Crossing>) {
        self.winding.line_crossings(y, z, out);
    }

    /// Where the segment from `inside` to `outside` (classified so by [`Self::contains`])
    /// first crosses the surface, as a fraction of the way from `inside` (0 to 1).
    pub(crate) fn segment_crossing(&self, inside: DVec3, outside: DVec3) -> f64 {
        let d = outside - inside;
        let start = inside - d * SEGMENT_PAD;
        if let Some(hit) = self.rays.cast_ray(start, d, 1.0 + 2.0 * SEGMENT_PAD) {
            return (hit.t - SEGMENT_PAD).clamp(0.0, 1.0);
        }
        // A ray through an edge or vertex may slip between triangles: fall back to
        // bisection on the same inside test that classified the ends.
        let (mut lo, mut hi) = (0.0, 1.0);
        for _ in 0..BISECTION_STEPS {
            let mid = 0.5 * (lo + hi);
            if self.contains(inside + d * mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        0.5 * (lo + hi)
    }
}
