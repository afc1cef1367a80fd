//! Closed curves on a triangle mesh: a 3D curve projected onto the surface by walking
//! across triangles (the cut curve of paper section IV-B), and the checks every closed
//! surface curve must pass before the mesh can be cut along it ([`crate::cut`]).
//!
//! # Algorithm
//! [`SurfaceCurve::project`] starts at the first sample, in the triangle the caller names.
//! For every further sample it takes the segment from the current point to the sample,
//! projects it into the current triangle's plane along the triangle normal, and clips it
//! where it leaves the triangle; the crossing point is recorded and the rest of the
//! segment is projected into the neighbour's plane, until the projected sample falls inside
//! a triangle. After the last sample it walks back to the first point, closing the loop.
//!
//! Points within [`SNAP_TOLERANCE`] of an edge or vertex are moved onto it, so a curve
//! running along an edge or through a vertex is followed exactly:
//! - on an edge, the walk enters whichever of the two triangles the projected segment
//!   points into; if it points out of both (the sample lies beyond a ridge) it follows the
//!   edge to the sample's foot on it;
//! - at a vertex, it enters the triangle whose corner wedge contains the projected
//!   direction; where no wedge does (a sharp cone vertex) it follows the nearest wedge side.
//!
//! Following a ridge can double back along the edge (the foot lies behind the point where
//! the walk reached the edge); such back-tracking points are dropped. The result is
//! checked: the curve must be closed and must not cross or touch itself.

mod checks;
mod close;
mod loops;

pub(crate) use checks::{
    CurvesDefect, SegmentPlace, Touching, check_curves, check_topology, segment_place,
};

use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::TriMesh;
use glam::{DVec2, DVec3};

/// Barycentric distance (a fraction of the triangle's height) within which a point is moved
/// onto an edge or vertex. On a 2 mm triangle it is 2 nm: far below scan noise, far above
/// the 1e-16 round-off of the walk, so a curve along an edge or through a vertex is
/// recognised as such, and a cut never puts a vertex nearer than this to an edge it is not
/// on.
pub const SNAP_TOLERANCE: f64 = 1e-6;
/// A triangle whose height is below this fraction of its longest edge counts as degenerate
/// (zero area): its plane and barycentric coordinates are meaningless, so the walk refuses
/// to enter it. Well below [`SNAP_TOLERANCE`], so slivers of real scans still count as
/// triangles.
const DEGENERATE_RATIO: f64 = 1e-8;
/// Relative barycentric tolerance for a projected direction running along an edge
/// (round-off of a direction computed in two triangle planes).
const ALONG_EDGE_TOLERANCE: f64 = 1e-9;
/// Barycentric distance below which two non-consecutive segments count as touching.
const TOUCH_TOLERANCE: f64 = 1e-9;
/// Walking steps allowed per mesh triangle (plus a constant) for one segment of the curve:
/// a walk that takes longer is going round in circles.
const STEPS_PER_TRIANGLE: usize = 4;

/// Where a curve point lies on the mesh. Edge `k` of a triangle runs from corner `k` to
/// corner `(k + 1) % 3`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CurveLocation {
    /// On a mesh vertex.
    OnVertex(u32),
    /// Inside edge `edge` of `triangle`, at the fraction `t` of the way from its start
    /// corner to its end corner (0 < t < 1).
    OnEdge {
        triangle: usize,
        edge: usize,
        t: f64,
    },
    /// Inside `triangle`, at these barycentric coordinates (positive, summing to one).
    InTriangle {
        triangle: usize,
        barycentric: [f64; 3],
    },
}

/// One point of a [`SurfaceCurve`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CurvePoint {
    /// Position on the surface (mm).
    pub position: DVec3,
    /// Where it lies on the mesh.
    pub location: CurveLocation,
}

/// A closed polyline on a mesh: consecutive points, and the last and the first, share a
/// triangle, so every segment runs on the surface. The first point is not repeated at the
/// end.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceCurve {
    /// The points in curve order.
    pub points: Vec<CurvePoint>,
}

/// Why a curve could not be put on, or is not a valid closed curve on, the surface.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CurveError {
    #[error(
        "the topology was built for a mesh with {topology_triangles} triangles, but this mesh has {mesh_triangles}"
    )]
    TopologyMismatch {
        topology_triangles: usize,
        mesh_triangles: usize,
    },
    #[error("a closed curve needs at least 3 points, got {count}")]
    TooFewPoints { count: usize },
    #[error("sample {index} has a non-finite coordinate {position:?}")]
    NonFiniteSample { index: usize, position: [f64; 3] },
    #[error(
        "the start triangle {triangle} does not exist (the mesh has {triangle_count} triangles)"
    )]
    StartOutOfRange {
        triangle: usize,
        triangle_count: usize,
    },
    #[error("the first sample {position:?} does not lie on its start triangle {triangle}")]
    StartOffTriangle { triangle: usize, position: [f64; 3] },
    #[error(
        "the curve leaves the scan at its border or a hole near ({:.1}, {:.1}, {:.1}) mm",
        position[0], position[1], position[2]
    )]
    LeavesMesh { position: [f64; 3] },
    #[error(
        "the curve runs into the degenerate (zero-area) triangle {triangle} near ({:.1}, {:.1}, {:.1}) mm; remove degenerate triangles first",
        position[0], position[1], position[2]
    )]
    DegenerateTriangle { triangle: usize, position: [f64; 3] },
    #[error(
        "the walk towards sample {sample} makes no progress near ({:.1}, {:.1}, {:.1}) mm",
        position[0], position[1], position[2]
    )]
    NoProgress { sample: usize, position: [f64; 3] },
    #[error(
        "curve point {index} is not a valid location: a triangle, edge or vertex the mesh lacks, or coordinates off it"
    )]
    InvalidLocation { index: usize },
    #[error(
        "curve points {index} and {} share no triangle: the curve is not connected on the surface",
        index + 1
    )]
    NotConnected { index: usize },
    #[error(
        "the curve is not closed: its last point ({:.1}, {:.1}, {:.1}) mm shares no triangle with its first, {gap_mm:.3} mm away",
        last[0], last[1], last[2]
    )]
    NotClosed { last: [f64; 3], gap_mm: f64 },
    #[error(
        "the curve crosses or touches itself near ({:.1}, {:.1}, {:.1}) mm",
        position[0], position[1], position[2]
    )]
    SelfCrossing { position: [f64; 3] },
}

impl CurveError {
    /// Where on the surface the curve failed (mm, the mesh's coordinates), for the errors
    /// that have a place.
    pub fn position(&self) -> Option<[f64; 3]> {
        match self {
            CurveError::LeavesMesh { position }
            | CurveError::DegenerateTriangle { position, .. }
            | CurveError::NoProgress { position, .. }
            | CurveError::SelfCrossing { position }
            | CurveError::StartOffTriangle { position, .. } => Some(*position),
            CurveError::NotClosed { last, .. } => Some(*last),
            // Not finite, or not a place on the mesh.
            CurveError::NonFiniteSample { .. }
            | CurveError::TopologyMismatch { .. }
            | CurveError::TooFewPoints { .. }
            | CurveError::StartOutOfRange { .. }
            | CurveError::InvalidLocation { .. }
            | CurveError::NotConnected { .. } => None,
        }
    }
}

impl CurveLocation {
    /// The location of the point with barycentric coordinates `barycentric` in `triangle`,
    /// moved onto the edge or vertex it lies within [`SNAP_TOLERANCE`] of. Coordinates
    /// slightly outside the triangle are clamped onto it.
    fn from_barycentric(mesh: &TriMesh, triangle: usize, barycentric: [f64; 3]) -> Self {
        // NaN fails the comparison and becomes zero too.
        let snapped = barycentric.map(|x| if x >= SNAP_TOLERANCE { x } else { 0.0 });
        let sum: f64 = snapped.iter().sum();
        let corners = mesh.triangles[triangle];
        if sum <= 0.0 || !sum.is_finite() {
            return CurveLocation::OnVertex(corners[0]);
        }
        let weights = snapped.map(|x| x / sum);
        match weights.map(|x| x == 0.0) {
            [false, false, false] => CurveLocation::InTriangle {
                triangle,
                barycentric: weights,
            },
            [true, true, _] => CurveLocation::OnVertex(corners[2]),
            [true, _, true] => CurveLocation::OnVertex(corners[1]),
            [_, true, true] => CurveLocation::OnVertex(corners[0]),
            zero => {
                // Coordinate `i` vanishes on edge `i + 1`, whose end corner is `i + 2`.
                let i = zero.iter().position(|&z| z).unwrap_or(0);
                let edge = (i + 1) % 3;
                CurveLocation::OnEdge {
                    triangle,
                    edge,
                    t: weights[(edge + 1) % 3],
                }
            }
        }
    }

    /// The mesh vertices the location interpolates and their weights.
    pub(crate) fn vertex_weights(&self, mesh: &TriMesh) -> ([u32; 3], [f64; 3]) {
        match *self {
            CurveLocation::OnVertex(v) => ([v; 3], [1.0, 0.0, 0.0]),
            CurveLocation::OnEdge { triangle, edge, t } => {
                let corners = mesh.triangles[triangle];
                let (a, b) = (corners[edge], corners[(edge + 1) % 3]);
                ([a, b, b], [1.0 - t, t, 0.0])
            }
            CurveLocation::InTriangle {
                triangle,
                barycentric,
            } => (mesh.triangles[triangle], barycentric),
        }
    }

    /// Position on the surface (mm). Panics if `mesh` lacks the location's triangle or
    /// vertex ([`SurfaceCurve::check`] tells).
    pub fn position(&self, mesh: &TriMesh) -> DVec3 {
        let (vertices, weights) = self.vertex_weights(mesh);
        (0..3)
            .map(|k| mesh.positions[vertices[k] as usize] * weights[k])
            .sum()
    }

    /// Barycentric coordinates in `triangle`, if the location lies on it; coordinates of
    /// the corners off the location's edge or vertex are exactly zero.
    pub(crate) fn barycentric_in(&self, mesh: &TriMesh, triangle: usize) -> Option<[f64; 3]> {
        if let CurveLocation::InTriangle {
            triangle: own,
            barycentric,
        } = *self
        {
            return (own == triangle).then_some(barycentric);
        }
        let corners = mesh.triangles[triangle];
        let (vertices, weights) = self.vertex_weights(mesh);
        let mut result = [0.0; 3];
        for (&v, &w) in vertices.iter().zip(&weights).filter(|(_, w)| **w != 0.0) {
            result[corners.iter().position(|&c| c == v)?] = w;
        }
        Some(result)
    }

    /// The triangles the location lies on.
    pub(crate) fn triangles(&self, topology: &Topology) -> Vec<usize> {
        match *self {
            CurveLocation::OnVertex(v) => topology
                .vertex_triangles(v as usize)
                .iter()
                .map(|&t| t as usize)
                .collect(),
            CurveLocation::OnEdge { triangle, edge, .. } => {
                let neighbor = topology.triangle_neighbors[triangle][edge];
                std::iter::once(triangle)
                    .chain((neighbor != NO_TRIANGLE).then_some(neighbor as usize))
                    .collect()
            }
            CurveLocation::InTriangle { triangle, .. } => vec![triangle],
        }
    }

    /// Whether the location exists on `mesh` and is in the form
    /// `CurveLocation::from_barycentric` gives: a point within the snap tolerance of an
    /// edge or vertex is on it (half the tolerance allows for round-off).
    fn is_valid(&self, mesh: &TriMesh) -> bool {
        let inner = 0.5 * SNAP_TOLERANCE..=1.0 - 0.5 * SNAP_TOLERANCE;
        match *self {
            CurveLocation::OnVertex(v) => (v as usize) < mesh.positions.len(),
            CurveLocation::OnEdge { triangle, edge, t } => {
                triangle < mesh.triangles.len() && edge < 3 && inner.contains(&t)
            }
            CurveLocation::InTriangle {
                triangle,
                barycentric,
            } => {
                triangle < mesh.triangles.len()
                    && barycentric.iter().all(|x| inner.contains(x))
                    && (barycentric.iter().sum::<f64>() - 1.0).abs() <= SNAP_TOLERANCE
            }
        }
    }
}

impl SurfaceCurve {
    /// Projects the closed curve through `samples` (mm) onto the surface by walking across
    /// triangles (see the module documentation). `samples[0]` must lie on triangle
    /// `start_triangle` (e.g. from [`crate::SurfaceIndex::closest_point`]); the others may
    /// lie off the surface. Do not repeat the first sample at the end. The mesh must pass
    /// [`TriMesh::validate`].
    ///
    /// A loop of the walk shorter than a tenth of the curve (where it doubles back past a
    /// sample on a steep flank) is cut out where it touches the rest. Errors if the curve
    /// leaves the mesh at its border or a hole, runs into a degenerate triangle, or still
    /// crosses or touches itself.
    pub fn project(
        mesh: &TriMesh,
        topology: &Topology,
        start_triangle: usize,
        samples: &[DVec3],
    ) -> Result<SurfaceCurve, CurveError> {
        check_topology(mesh, topology)?;
        if samples.len() < 3 {
            return Err(CurveError::TooFewPoints {
                count: samples.len(),
            });
        }
        if let Some(index) = samples.iter().position(|s| !s.is_finite()) {
            return Err(CurveError::NonFiniteSample {
                index,
                position: samples[index].to_array(),
            });
        }
        if start_triangle >= mesh.triangles.len() {
            return Err(CurveError::StartOutOfRange {
                triangle: start_triangle,
                triangle_count: mesh.triangles.len(),
            });
        }
        if is_degenerate(mesh, start_triangle) {
            return Err(CurveError::DegenerateTriangle {
                triangle: start_triangle,
                position: samples[0].to_array(),
            });
        }
        let start = projected_barycentric(mesh, start_triangle, samples[0]);
        if start.iter().any(|&x| x < -SNAP_TOLERANCE) {
            return Err(CurveError::StartOffTriangle {
                triangle: start_triangle,
                position: samples[0].to_array(),
            });
        }
        let first = CurveLocation::from_barycentric(mesh, start_triangle, start);
        let mut walker = Walker {
            mesh,
            topology,
            location: first,
            points: Vec::new(),
            step_limit: STEPS_PER_TRIANGLE * mesh.triangles.len() + 16,
        };
        walker.push(first);
        for (index, &sample) in samples.iter().enumerate().skip(1) {
            walker.walk_to(sample, index)?;
        }
        let first_position = walker.points[0].position;
        walker.walk_to(first_position, 0)?;
        // The walk may stop short of the first point behind a ridge of scanner noise
        // (where it stops, the nearest surface point seen from its triangle).
        let stopped = walker.location;
        if segment_place(mesh, topology, &stopped, &first).is_none()
            && let Some(vertices) = close::edge_path(mesh, topology, &stopped, &first)
        {
            for v in vertices {
                walker.push(CurveLocation::OnVertex(v));
            }
        }
        let points = without_edge_spikes(mesh, topology, walker.points);
        let curve = SurfaceCurve {
            points: loops::without_small_loops(mesh, topology, points),
        };
        curve.check(mesh, topology)?;
        Ok(curve)
    }

    /// The curve with the points that would leave sliver triangles in a cut moved onto
    /// mesh vertices or dropped: an edge crossing within `fraction` (of the edge's length)
    /// of a corner moves onto that corner, a point inside a triangle within `fraction`
    /// (barycentric) of an edge is dropped (its neighbours share its triangle, so the
    /// curve stays on the surface); repeated vertices are merged. Each point moves by at
    /// most `fraction` of an edge. If the result is not a valid simple curve (points so
    /// merged that it touches itself), the curve is returned unchanged.
    pub fn snapped_to_vertices(
        self,
        mesh: &TriMesh,
        topology: &Topology,
        fraction: f64,
    ) -> SurfaceCurve {
        let mut points: Vec<CurvePoint> = Vec::with_capacity(self.points.len());
        for point in &self.points {
            let location = match point.location {
                CurveLocation::OnEdge { triangle, edge, t } if t < fraction => {
                    CurveLocation::OnVertex(mesh.triangles[triangle][edge])
                }
                CurveLocation::OnEdge { triangle, edge, t } if t > 1.0 - fraction => {
                    CurveLocation::OnVertex(mesh.triangles[triangle][(edge + 1) % 3])
                }
                CurveLocation::InTriangle { barycentric, .. }
                    if barycentric.iter().any(|&x| x < fraction) =>
                {
                    continue;
                }
                location => location,
            };
            let position = match location {
                CurveLocation::OnVertex(vertex) => mesh.positions[vertex as usize],
                _ => point.position,
            };
            if points.last().is_none_or(|last| last.location != location) {
                points.push(CurvePoint { position, location });
            }
        }
        while points.len() > 1
            && points.first().map(|p| p.location) == points.last().map(|p| p.location)
        {
            points.pop();
        }
        let snapped = SurfaceCurve { points };
        if snapped.check(mesh, topology).is_ok() {
            snapped
        } else {
            self
        }
    }

    /// Total length of the closed polyline (mm).
    pub fn length_mm(&self) -> f64 {
        let n = self.points.len();
        (0..n)
            .map(|i| {
                self.points[i]
                    .position
                    .distance(self.points[(i + 1) % n].position)
            })
            .sum()
    }

    /// The same curve run the other way.
    pub fn reversed(&self) -> SurfaceCurve {
        SurfaceCurve {
            points: self.points.iter().rev().copied().collect(),
        }
    }

    /// Area (mm²) enclosed by the polyline projected onto the plane orthogonal to `axis`:
    /// positive if the curve runs counter-clockwise seen from the tip of `axis`.
    pub fn signed_area_about(&self, axis: DVec3) -> f64 {
        let axis = axis.normalize_or_zero();
        let Some(origin) = self.points.first().map(|p| p.position) else {
            return 0.0;
        };
        let n = self.points.len();
        (0..n)
            .map(|i| {
                let p = self.points[i].position - origin;
                let q = self.points[(i + 1) % n].position - origin;
                0.5 * p.cross(q).dot(axis)
            })
            .sum()
    }

    /// The curve, reversed if needed so that it runs counter-clockwise seen from outside
    /// along `outward` (e.g. the mean normal of the enclosed region). Then the region the
    /// curve encloses is its inside for [`crate::cut`].
    pub fn oriented_counter_clockwise_about(self, outward: DVec3) -> SurfaceCurve {
        if self.signed_area_about(outward) < 0.0 {
            self.reversed()
        } else {
            self
        }
    }

    /// Checks that the curve is a closed simple curve on `mesh`: at least three points,
    /// valid locations, consecutive points (and the last and first) sharing a triangle,
    /// and no two segments crossing or touching except consecutive ones at their common
    /// point.
    pub fn check(&self, mesh: &TriMesh, topology: &Topology) -> Result<(), CurveError> {
        check_topology(mesh, topology)?;
        check_curves(mesh, topology, std::slice::from_ref(self)).map_err(|defect| match defect {
            CurvesDefect::Curve { error, .. } => error,
            CurvesDefect::Touch { position, .. } => CurveError::SelfCrossing { position },
        })
    }
}

/// The closed curve `points` without back-tracking along edges. Where the walk follows a
/// ridge edge to the foot of a sample, that foot can lie behind the point where the walk
/// reached the edge, and the curve would double back over itself. So a point whose two
/// neighbours lie on the same edge on one side of it is dropped, and so is a point that
/// then coincides with the one before (the first point included: the curve is closed).
fn without_edge_spikes(
    mesh: &TriMesh,
    topology: &Topology,
    points: Vec<CurvePoint>,
) -> Vec<CurvePoint> {
    let is_spike = |a: &CurvePoint, b: &CurvePoint, c: &CurvePoint| {
        b.location.triangles(topology).into_iter().any(|t| {
            let on_t = |p: &CurvePoint| p.location.barycentric_in(mesh, t);
            let (Some(a), Some(b), Some(c)) = (on_t(a), on_t(b), on_t(c)) else {
                return false;
            };
            // On the edge opposite corner k, the weight of corner k + 1 orders the points.
            (0..3).any(|k| {
                let j = (k + 1) % 3;
                a[k] == 0.0
                    && b[k] == 0.0
                    && c[k] == 0.0
                    && (b[j] <= a[j].min(c[j]) || b[j] >= a[j].max(c[j]))
            })
        })
    };
    let mut kept: Vec<CurvePoint> = Vec::with_capacity(points.len());
    for point in points {
        kept.push(point);
        loop {
            let n = kept.len();
            if n >= 2 && coincide(mesh, topology, &kept[n - 2], &kept[n - 1]) {
                kept.pop();
            } else if n >= 3 && is_spike(&kept[n - 3], &kept[n - 2], &kept[n - 1]) {
                kept.remove(n - 2);
            } else {
                break;
            }
        }
    }
    // The same around the seam between the last and the first point.
    loop {
        let n = kept.len();
        if n < 4 {
            break;
        }
        if coincide(mesh, topology, &kept[n - 1], &kept[0]) {
            kept.pop();
        } else if is_spike(&kept[n - 2], &kept[n - 1], &kept[0]) {
            kept.remove(n - 1);
        } else if is_spike(&kept[n - 1], &kept[0], &kept[1]) {
            kept.remove(0);
        } else {
            break;
        }
    }
    kept
}

/// Whether two curve points are the same point: on a common triangle, with barycentric
/// coordinates within [`SNAP_TOLERANCE`].
fn coincide(mesh: &TriMesh, topology: &Topology, a: &CurvePoint, b: &CurvePoint) -> bool {
    a.location.triangles(topology).into_iter().any(|t| {
        match (
            a.location.barycentric_in(mesh, t),
            b.location.barycentric_in(mesh, t),
        ) {
            (Some(p), Some(q)) => (0..3).all(|k| (p[k] - q[k]).abs() < SNAP_TOLERANCE),
            _ => false,
        }
    })
}

/// Whether triangle `t` has (numerically) no area; see [`DEGENERATE_RATIO`].
fn is_degenerate(mesh: &TriMesh, t: usize) -> bool {
    let [a, b, c] = mesh.triangle_positions(t);
    let double_area = (b - a).cross(c - a).length();
    let longest_squared = a
        .distance_squared(b)
        .max(b.distance_squared(c))
        .max(c.distance_squared(a));
    double_area.is_nan() || double_area <= DEGENERATE_RATIO * longest_squared
}

/// Barycentric coordinates in triangle `t` of `point` projected onto the triangle's plane
/// along its normal. Linear in `point`, so a segment maps to a segment.
fn projected_barycentric(mesh: &TriMesh, t: usize, point: DVec3) -> [f64; 3] {
    let [a, b, c] = mesh.triangle_positions(t);
    let (ab, ac, ap) = (b - a, c - a, point - a);
    let normal = ab.cross(ac);
    // Dotting with the normal drops the off-plane part of `ap`: the orthogonal projection.
    let scale = 1.0 / normal.length_squared();
    let v = ap.cross(ac).dot(normal) * scale;
    let w = ab.cross(ap).dot(normal) * scale;
    [1.0 - v - w, v, w]
}

/// Barycentric coordinates in `t` of `point` projected onto the line of edge `edge`.
fn edge_line_barycentric(mesh: &TriMesh, t: usize, edge: usize, point: DVec3) -> [f64; 3] {
    let corners = mesh.triangle_positions(t);
    let (a, b) = (corners[edge], corners[(edge + 1) % 3]);
    let s = (point - a).dot(b - a) / a.distance_squared(b);
    let mut result = [0.0; 3];
    result[edge] = 1.0 - s;
    result[(edge + 1) % 3] = s;
    result
}

/// The state of the walk of [`SurfaceCurve::project`].
struct Walker<'a> {
    mesh: &'a TriMesh,
    topology: &'a Topology,
    location: CurveLocation,
    points: Vec<CurvePoint>,
    step_limit: usize,
}

/// One straight move inside a triangle, in its barycentric coordinates.
struct Move {
    triangle: usize,
    from: [f64; 3],
    to: [f64; 3],
}

impl Walker<'_> {
    /// Records `location` unless it coincides with the last point, and moves to the last
    /// point.
    fn push(&mut self, location: CurveLocation) {
        let point = CurvePoint {
            position: location.position(self.mesh),
            location,
        };
        match self.points.last() {
            Some(last) if coincide(self.mesh, self.topology, last, &point) => {
                self.location = last.location;
            }
            _ => {
                self.location = location;
                self.points.push(point);
            }
        }
    }

    fn position(&self) -> [f64; 3] {
        self.location.position(self.mesh).to_array()
    }

    /// Walks from the current point towards `target`, triangle by triangle, recording
    /// every edge crossing and the end point.
    fn walk_to(&mut self, target: DVec3, sample: usize) -> Result<(), CurveError> {
        for _ in 0..self.step_limit {
            let Some(Move { triangle, from, to }) = self.next_move(target)? else {
                return Ok(()); // the target projects onto the current point
            };
            // The first coordinate to turn negative names the edge the segment leaves by.
            let exit = (0..3)
                .filter(|&i| to[i] < -SNAP_TOLERANCE)
                .map(|i| (from[i] / (from[i] - to[i]), i))
                .min_by(|x, y| x.0.total_cmp(&y.0));
            let Some((s, i)) = exit else {
                self.push(CurveLocation::from_barycentric(self.mesh, triangle, to));
                return Ok(());
            };
            let mut crossing = [0, 1, 2].map(|k| from[k] + s * (to[k] - from[k]));
            crossing[i] = 0.0;
            self.push(CurveLocation::from_barycentric(
                self.mesh, triangle, crossing,
            ));
        }
        Err(CurveError::NoProgress {
            sample,
            position: self.position(),
        })
    }

    /// The triangle to move in from the current point towards `target`, with the
    /// projected segment; `None` if the target projects onto the current point.
    fn next_move(&self, target: DVec3) -> Result<Option<Move>, CurveError> {
        match self.location {
            CurveLocation::InTriangle {
                triangle,
                barycentric,
            } => Ok(Some(Move {
                triangle,
                from: barycentric,
                to: projected_barycentric(self.mesh, triangle, target),
            })),
            CurveLocation::OnEdge { triangle, edge, .. } => {
                self.leave_edge(triangle, edge, target).map(Some)
            }
            CurveLocation::OnVertex(v) => self.leave_vertex(v as usize, target),
        }
    }

    /// From a point on edge `edge` of `triangle`: into the triangle on the side the segment
    /// points to, or along the edge if it points out of both.
    fn leave_edge(&self, triangle: usize, edge: usize, target: DVec3) -> Result<Move, CurveError> {
        let mesh = self.mesh;
        let here = |t: usize| self.location.barycentric_in(mesh, t).unwrap_or_default();
        let from = here(triangle);
        let to = projected_barycentric(mesh, triangle, target);
        let off_edge = (edge + 2) % 3;
        let displacement = (0..3).map(|k| (to[k] - from[k]).abs()).fold(0.0, f64::max);
        let along_edge = Move {
            triangle,
            from,
            to: edge_line_barycentric(mesh, triangle, edge, target),
        };
        if to[off_edge] >= 0.0 {
            return Ok(Move { triangle, from, to });
        }
        if to[off_edge] >= -ALONG_EDGE_TOLERANCE * displacement {
            return Ok(along_edge);
        }
        let neighbor = self.topology.triangle_neighbors[triangle][edge];
        if neighbor == NO_TRIANGLE {
            return Err(CurveError::LeavesMesh {
                position: self.position(),
            });
        }
        let neighbor = neighbor as usize;
        if is_degenerate(mesh, neighbor) {
            return Err(CurveError::DegenerateTriangle {
                triangle: neighbor,
                position: self.position(),
            });
        }
        let (from, to) = (
            here(neighbor),
            projected_barycentric(mesh, neighbor, target),
        );
        if let Some(k) = (0..3).find(|&k| from[k] == 0.0)
            && to[k] >= 0.0
        {
            return Ok(Move {
                triangle: neighbor,
                from,
                to,
            });
        }
        // Both triangles send the segment back across the edge: the target lies beyond a
        // ridge, and its foot on the edge is the nearest surface point.
        Ok(along_edge)
    }

    /// From vertex `v`: into the incident triangle whose corner wedge contains the
    /// projected segment, or along the nearest wedge side if none does.
    fn leave_vertex(&self, v: usize, target: DVec3) -> Result<Option<Move>, CurveError> {
        let mesh = self.mesh;
        // (score, triangle, corner of v, projected target); the score is positive inside
        // the wedge, scale-free, and largest for the wedge's bisector.
        let mut best: Option<(f64, usize, usize, [f64; 3])> = None;
        for &t in self.topology.vertex_triangles(v) {
            let t = t as usize;
            if is_degenerate(mesh, t) {
                continue;
            }
            let corner = (0..3)
                .find(|&k| mesh.triangles[t][k] as usize == v)
                .unwrap_or(0);
            let to = projected_barycentric(mesh, t, target);
            let (alpha, beta) = (to[(corner + 1) % 3], to[(corner + 2) % 3]);
            let size = alpha.abs() + beta.abs();
            if size < SNAP_TOLERANCE {
                return Ok(None);
            }
            let score = alpha.min(beta) / size;
            if best.is_none_or(|b| score > b.0) {
                best = Some((score, t, corner, to));
            }
        }
        let Some((score, triangle, corner, to)) = best else {
            return Err(CurveError::DegenerateTriangle {
                triangle: self
                    .topology
                    .vertex_triangles(v)
                    .first()
                    .map_or(0, |&t| t as usize),
                position: self.position(),
            });
        };
        let mut from = [0.0; 3];
        from[corner] = 1.0;
        if score >= 0.0 {
            return Ok(Some(Move { triangle, from, to }));
        }
        if score < -ALONG_EDGE_TOLERANCE && self.is_boundary_vertex(v) {
            return Err(CurveError::LeavesMesh {
                position: self.position(),
            });
        }
        // Follow the wedge side nearer the direction: edge `corner` runs to the next
        // corner, edge `corner + 2` arrives from the previous one.
        let (next, previous) = ((corner + 1) % 3, (corner + 2) % 3);
        let (edge, other) = if to[next] >= to[previous] {
            (corner, next)
        } else {
            (previous, previous)
        };
        let to = edge_line_barycentric(mesh, triangle, edge, target);
        Ok((to[other] > 0.0).then_some(Move { triangle, from, to }))
    }

    /// Whether vertex `v` lies on the mesh border or a hole.
    fn is_boundary_vertex(&self, v: usize) -> bool {
        self.topology.vertex_triangles(v).iter().any(|&t| {
            let t = t as usize;
            (0..3).any(|k| {
                let corners = self.mesh.triangles[t];
                let touches_v = corners[k] as usize == v || corners[(k + 1) % 3] as usize == v;
                touches_v && self.topology.triangle_neighbors[t][k] == NO_TRIANGLE
            })
        })
    }
}

#[cfg(test)]
pub(crate) mod tests;
