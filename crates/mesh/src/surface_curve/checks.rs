//! The checks a closed surface curve passes before the mesh is cut along it: the
//! topology belongs to the mesh, every curve is closed and no curve crosses or touches
//! itself or another.

use super::*;

/// Whether `topology` was built for `mesh` (as far as a cheap check tells).
pub(crate) fn check_topology(mesh: &TriMesh, topology: &Topology) -> Result<(), CurveError> {
    match topology.mismatch(mesh) {
        None => Ok(()),
        Some((topology_triangles, mesh_triangles)) => Err(CurveError::TopologyMismatch {
            topology_triangles,
            mesh_triangles,
        }),
    }
}

/// What is wrong with a set of curves: one curve on its own, or two that touch.
pub(crate) enum CurvesDefect {
    Curve {
        curve: usize,
        error: CurveError,
    },
    /// Curves `first` and `second` (the same for a curve touching itself) meet at `at`:
    /// segment or point `first_index` of the first and `second_index` of the second
    /// ([`Touching`]).
    Touch {
        first: usize,
        second: usize,
        position: [f64; 3],
        touching: Touching,
    },
}

/// Where two curves (or one curve twice) meet.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Touching {
    /// Point `first_index` and point `second_index` are the same vertex.
    Vertex {
        first_index: usize,
        second_index: usize,
    },
    /// Segment `first_index` (from that point to the next) and segment `second_index`
    /// cross or touch at `at`.
    Segments {
        first_index: usize,
        second_index: usize,
        at: CurveLocation,
    },
}

/// Where a curve segment runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum SegmentPlace {
    /// Through the inside of a triangle (it must be split along the segment).
    InTriangle(usize),
    /// Along an edge of these one or two triangles (already a mesh edge).
    AlongEdge([Option<usize>; 2]),
}

/// Where the segment between two curve locations runs, or `None` if they share no
/// triangle.
pub(crate) fn segment_place(
    mesh: &TriMesh,
    topology: &Topology,
    a: &CurveLocation,
    b: &CurveLocation,
) -> Option<SegmentPlace> {
    a.triangles(topology).into_iter().find_map(|t| {
        let (from, to) = (a.barycentric_in(mesh, t)?, b.barycentric_in(mesh, t)?);
        Some(match (0..3).find(|&i| from[i] == 0.0 && to[i] == 0.0) {
            Some(i) => {
                let neighbor = topology.triangle_neighbors[t][(i + 1) % 3];
                SegmentPlace::AlongEdge([
                    Some(t),
                    (neighbor != NO_TRIANGLE).then_some(neighbor as usize),
                ])
            }
            None => SegmentPlace::InTriangle(t),
        })
    })
}

/// One segment in one triangle, in that triangle's barycentric plane `(b1, b2)`.
struct PlacedSegment {
    triangle: usize,
    curve: usize,
    index: usize,
    from: DVec2,
    to: DVec2,
}

/// Checks curves on their own (see [`SurfaceCurve::check`]) and against each other.
pub(crate) fn check_curves(
    mesh: &TriMesh,
    topology: &Topology,
    curves: &[SurfaceCurve],
) -> Result<(), CurvesDefect> {
    let mut placed: Vec<PlacedSegment> = Vec::new();
    let mut vertices: Vec<(u32, usize, usize)> = Vec::new();
    for (curve, points) in curves.iter().map(|c| &c.points).enumerate() {
        let defect = |error| CurvesDefect::Curve { curve, error };
        let n = points.len();
        if n < 3 {
            return Err(defect(CurveError::TooFewPoints { count: n }));
        }
        if let Some(index) = points.iter().position(|p| !p.location.is_valid(mesh)) {
            return Err(defect(CurveError::InvalidLocation { index }));
        }
        for (index, point) in points.iter().enumerate() {
            let next = &points[(index + 1) % n];
            let triangles = match segment_place(mesh, topology, &point.location, &next.location) {
                Some(SegmentPlace::InTriangle(t)) => [Some(t), None],
                Some(SegmentPlace::AlongEdge(triangles)) => triangles,
                None if index + 1 == n => {
                    return Err(defect(CurveError::NotClosed {
                        last: point.position.to_array(),
                        gap_mm: point.position.distance(next.position),
                    }));
                }
                None => return Err(defect(CurveError::NotConnected { index })),
            };
            for t in triangles.into_iter().flatten() {
                let plane = |p: &CurvePoint| {
                    let b = p.location.barycentric_in(mesh, t).unwrap_or_default();
                    DVec2::new(b[1], b[2])
                };
                placed.push(PlacedSegment {
                    triangle: t,
                    curve,
                    index,
                    from: plane(point),
                    to: plane(next),
                });
            }
            if let CurveLocation::OnVertex(v) = point.location {
                vertices.push((v, curve, index));
            }
        }
    }
    // A vertex visited twice: the segments around it may lie in different triangles.
    vertices.sort_unstable();
    if let Some(pair) = vertices.windows(2).find(|w| w[0].0 == w[1].0) {
        let ((v, first, first_index), (_, second, second_index)) = (pair[0], pair[1]);
        return Err(CurvesDefect::Touch {
            first,
            second,
            position: mesh.positions[v as usize].to_array(),
            touching: Touching::Vertex {
                first_index,
                second_index,
            },
        });
    }
    placed.sort_by_key(|s| s.triangle);
    for segments in placed.chunk_by(|s, r| s.triangle == r.triangle) {
        for (i, s) in segments.iter().enumerate() {
            for r in &segments[i + 1..] {
                let n = curves[s.curve].points.len();
                let consecutive = s.curve == r.curve
                    && (s.index.abs_diff(r.index) == 1 || s.index.abs_diff(r.index) == n - 1);
                if !consecutive && let Some(at) = segments_touch(s, r) {
                    let at = CurveLocation::from_barycentric(
                        mesh,
                        s.triangle,
                        [1.0 - at.x - at.y, at.x, at.y],
                    );
                    return Err(CurvesDefect::Touch {
                        first: s.curve,
                        second: r.curve,
                        position: at.position(mesh).to_array(),
                        touching: Touching::Segments {
                            first_index: s.index,
                            second_index: r.index,
                            at,
                        },
                    });
                }
            }
        }
    }
    Ok(())
}

/// Where two segments cross, or come within [`TOUCH_TOLERANCE`] of each other (in their
/// triangle's barycentric plane); `None` if they do neither.
fn segments_touch(s: &PlacedSegment, r: &PlacedSegment) -> Option<DVec2> {
    let orient = |a: DVec2, b: DVec2, c: DVec2| (b - a).perp_dot(c - a);
    let (r_from_s, r_to_s) = (orient(r.from, r.to, s.from), orient(r.from, r.to, s.to));
    let crosses =
        r_from_s * r_to_s < 0.0 && orient(s.from, s.to, r.from) * orient(s.from, s.to, r.to) < 0.0;
    if crosses {
        let along_s = r_from_s / (r_from_s - r_to_s);
        return Some(s.from + along_s * (s.to - s.from));
    }
    [
        (s.from, closest_on_segment(s.from, r.from, r.to)),
        (s.to, closest_on_segment(s.to, r.from, r.to)),
        (r.from, closest_on_segment(r.from, s.from, s.to)),
        (r.to, closest_on_segment(r.to, s.from, s.to)),
    ]
    .into_iter()
    .find(|(p, q)| p.distance(*q) <= TOUCH_TOLERANCE)
    .map(|(p, _)| p)
}

fn closest_on_segment(p: DVec2, a: DVec2, b: DVec2) -> DVec2 {
    let ab = b - a;
    let length_squared = ab.length_squared();
    let s = if length_squared > 0.0 {
        ((p - a).dot(ab) / length_squared).clamp(0.0, 1.0)
    } else {
        0.0
    };
    a + s * ab
}
