//! Cutting a mesh along closed surface curves (paper section IV-C): the triangles a curve
//! runs through are split so that every curve segment becomes a mesh edge, and every
//! triangle is labelled as inside or outside of each curve, so the mesh falls apart
//! exactly along the curves (e.g. left breast, right breast and the rest of the body).
//!
//! # Algorithm
//! 1. Every curve point becomes a vertex: a point on a vertex reuses it, a point on an
//!    edge becomes one new vertex shared by both triangles of the edge, a point inside a
//!    triangle a new vertex of that triangle. Colours are interpolated.
//! 2. Every triangle with a curve segment through its inside or a new vertex on its edges
//!    is re-triangulated: its outline (corners and edge points, counter-clockwise) is split
//!    into faces by the chains of curve segments crossing it, and each face is
//!    ear-clipped, choosing the best-shaped ear first. A triangle crossed once becomes two
//!    or three triangles; one crossed several times or by several curves is handled the
//!    same way. Segments along existing edges need no split, and the triangles beside them
//!    are kept unchanged.
//! 3. Labels: the triangle to the left of each directed curve edge (seen from the side the
//!    normals point to) is inside that curve, the one to the right outside. The inside
//!    labels are flood-filled across all other edges; meeting a different label is an
//!    error, and what no inside reaches is outside.
//!
//! So a curve must run counter-clockwise around its inside seen from outside
//! ([`SurfaceCurve::oriented_counter_clockwise_about`] orients it about a given outward
//! direction), and the mesh must be consistently oriented. Several curves are cut in one
//! call; they must be disjoint and not nested (each has its own inside, the rest is
//! outside). Triangles no label reaches (pieces of the mesh no curve touches) are outside.
//!
//! Curve points within [`crate::surface_curve::SNAP_TOLERANCE`] (relative) of an edge or
//! vertex lie on it, so no new vertex comes closer than that to an edge it is not on, and
//! no new triangle has less than [`COLLINEAR_TOLERANCE`] of its parent's area (thin ones
//! arise only where consecutive curve points are nearly collinear). Besides copying the
//! mesh, the work is linear in the curves' length and the insides' size; extracting a
//! part is linear in the mesh.

use crate::surface_curve::{
    CurveError, CurveLocation, CurvesDefect, SegmentPlace, SurfaceCurve, check_curves,
    check_topology, segment_place,
};
use crate::topology::{NO_TRIANGLE, Topology};
use crate::trimesh::{MaterialLayer, TriMesh, UvLayer};
use glam::{DVec2, DVec3};
use std::collections::{HashMap, HashSet};

/// Twice the area of three points of a re-triangulated triangle, as a fraction of the
/// parent triangle's, at or below which they count as collinear. Barycentric round-off is
/// about 1e-16, while snapped points span at least about 1e-12.
const COLLINEAR_TOLERANCE: f64 = 1e-14;

/// Which side of the curves a triangle of a [`CutMesh`] is on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Region {
    /// Outside every curve.
    Outside,
    /// Inside the curve with this index.
    Inside(usize),
}

/// A mesh cut along closed curves: every curve segment is an edge, and every triangle
/// knows its region.
#[derive(Debug, Clone)]
pub struct CutMesh {
    /// The input mesh with the crossed triangles split; attribute layers carried along.
    /// Unsplit triangles keep their index; extra pieces follow the original triangles.
    pub mesh: TriMesh,
    /// The region of each triangle of `mesh`.
    pub regions: Vec<Region>,
    /// Per curve, its vertices in `mesh` in curve order: the closed boundary between its
    /// inside and the outside.
    pub loops: Vec<Vec<u32>>,
}

/// One region of a [`CutMesh`] as a mesh of its own.
#[derive(Debug, Clone)]
pub struct MeshPart {
    /// The part's triangles, vertices and attributes.
    pub mesh: TriMesh,
    /// For each vertex of `mesh`, its index in the cut mesh. Parts sharing a boundary have
    /// exactly the same positions there, so they stitch back watertight.
    pub vertex_map: Vec<u32>,
}

/// Why a mesh could not be cut.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CutError {
    #[error("no curve to cut along")]
    NoCurves,
    #[error(transparent)]
    TopologyMismatch(CurveError),
    #[error("cut curve {curve}: {source}")]
    Curve {
        curve: usize,
        #[source]
        source: CurveError,
    },
    #[error(
        "cut curves {first} and {second} touch or cross near ({:.1}, {:.1}, {:.1}) mm",
        position[0], position[1], position[2]
    )]
    CurvesTouch {
        first: usize,
        second: usize,
        position: [f64; 3],
    },
    #[error("cut curve {curve} lies inside triangle {triangle}: it is too small to cut along")]
    CurveInsideTriangle { curve: usize, triangle: usize },
    #[error(
        "could not re-triangulate triangle {triangle} near ({:.1}, {:.1}, {:.1}) mm",
        position[0], position[1], position[2]
    )]
    Triangulation { triangle: usize, position: [f64; 3] },
    #[error(
        "the inside and outside of a cut curve meet near ({:.1}, {:.1}, {:.1}) mm: the curves do not separate the surface into one inside each and an outside (a curve runs around a handle, or curves are nested)",
        position[0], position[1], position[2]
    )]
    LabelConflict { position: [f64; 3] },
}

/// Cuts `mesh` along disjoint, non-nested closed `curves` (e.g. the left and right breast
/// curves: three regions in one call). See the module documentation. The mesh must pass
/// [`TriMesh::validate`] and be consistently oriented.
pub fn cut_along_curves(
    mesh: &TriMesh,
    topology: &Topology,
    curves: &[SurfaceCurve],
) -> Result<CutMesh, CutError> {
    if curves.is_empty() {
        return Err(CutError::NoCurves);
    }
    check_topology(mesh, topology).map_err(CutError::TopologyMismatch)?;
    check_curves(mesh, topology, curves).map_err(|defect| match defect {
        CurvesDefect::Curve { curve, error } => CutError::Curve {
            curve,
            source: error,
        },
        CurvesDefect::Touch {
            first,
            second,
            position,
            ..
        } => CutError::CurvesTouch {
            first,
            second,
            position,
        },
    })?;

    let mut vertices = CutVertices {
        positions: mesh.positions.clone(),
        colors: mesh.vertex_colors.clone(),
        edge_points: HashMap::new(),
    };
    let loops: Vec<Vec<u32>> = curves
        .iter()
        .map(|curve| {
            curve
                .points
                .iter()
                .map(|p| vertices.insert(mesh, p.location))
                .collect()
        })
        .collect();

    // Curve segments through the inside of each triangle, and the triangles to split.
    let mut segments: HashMap<usize, Vec<(usize, usize)>> = HashMap::new();
    let mut affected = Vec::new();
    for (c, curve) in curves.iter().enumerate() {
        let n = curve.points.len();
        for (i, point) in curve.points.iter().enumerate() {
            let next = &curve.points[(i + 1) % n];
            if let Some(SegmentPlace::InTriangle(t)) =
                segment_place(mesh, topology, &point.location, &next.location)
            {
                segments.entry(t).or_default().push((c, i));
                affected.push(t);
            }
            if let CurveLocation::OnEdge { .. } = point.location {
                affected.extend(point.location.triangles(topology));
            }
        }
    }
    affected.sort_unstable();
    affected.dedup();

    let splitter = Splitter {
        mesh,
        curves,
        loops: &loops,
        vertices: &vertices,
    };
    let pieces: Vec<Vec<Piece>> = affected
        .iter()
        .map(|&t| splitter.split(t, segments.get(&t).map_or(&[], Vec::as_slice)))
        .collect::<Result<_, _>>()?;

    let assembled = assemble(mesh, vertices, &affected, pieces);
    let regions = label(mesh, topology, &assembled, &loops)?;
    Ok(CutMesh {
        mesh: assembled.mesh,
        regions,
        loops,
    })
}

impl CutMesh {
    /// The triangles of `region` as a mesh of their own, with all attribute layers.
    pub fn part(&self, region: Region) -> MeshPart {
        let mesh = &self.mesh;
        let selected: Vec<usize> = (0..mesh.triangles.len())
            .filter(|&t| self.regions[t] == region)
            .collect();
        let (triangles, vertex_map) = compact(
            selected.iter().map(|&t| mesh.triangles[t]),
            mesh.positions.len(),
        );
        let uv = mesh.uv.as_ref().map(|uv| {
            let (triangles, coord_map) =
                compact(selected.iter().map(|&t| uv.triangles[t]), uv.coords.len());
            UvLayer {
                coords: coord_map.iter().map(|&i| uv.coords[i as usize]).collect(),
                triangles,
            }
        });
        let part = TriMesh {
            positions: vertex_map
                .iter()
                .map(|&v| mesh.positions[v as usize])
                .collect(),
            triangles,
            vertex_colors: mesh
                .vertex_colors
                .as_ref()
                .map(|colors| vertex_map.iter().map(|&v| colors[v as usize]).collect()),
            uv,
            materials: mesh.materials.as_ref().map(|m| MaterialLayer {
                libraries: m.libraries.clone(),
                names: m.names.clone(),
                triangle_material: selected.iter().map(|&t| m.triangle_material[t]).collect(),
            }),
        };
        MeshPart {
            mesh: part,
            vertex_map,
        }
    }
}

/// Renumbers the indices (below `count`) that `triangles` use densely, in order of first
/// use: the renumbered triangles and, for each new index, the old one.
pub fn compact(
    triangles: impl Iterator<Item = [u32; 3]>,
    count: usize,
) -> (Vec<[u32; 3]>, Vec<u32>) {
    let mut new_index = vec![u32::MAX; count];
    let mut old_index = Vec::new();
    let renumbered = triangles
        .map(|tri| {
            tri.map(|i| {
                if new_index[i as usize] == u32::MAX {
                    new_index[i as usize] = old_index.len() as u32;
                    old_index.push(i);
                }
                new_index[i as usize]
            })
        })
        .collect();
    (renumbered, old_index)
}

/// The vertices of the cut mesh: the input's plus one per curve point off the vertices.
struct CutVertices {
    positions: Vec<DVec3>,
    colors: Option<Vec<[u8; 3]>>,
    /// New vertices inside each edge, keyed by the edge's (lower, higher) vertex index,
    /// with the fraction of the way from the lower one.
    edge_points: HashMap<(u32, u32), Vec<(f64, u32)>>,
}

impl CutVertices {
    /// The vertex for a curve point, created unless the point is on a vertex.
    fn insert(&mut self, mesh: &TriMesh, location: CurveLocation) -> u32 {
        if let CurveLocation::OnVertex(v) = location {
            return v;
        }
        let index = self.positions.len() as u32;
        let (corners, weights) = location.vertex_weights(mesh);
        self.positions.push(location.position(mesh));
        if let Some(colors) = &mut self.colors {
            let blend = (0..3).fold([0.0; 3], |sum, k| {
                let c = colors[corners[k] as usize];
                [0, 1, 2].map(|channel| sum[channel] + weights[k] * f64::from(c[channel]))
            });
            colors.push(blend.map(|x| x.round().clamp(0.0, 255.0) as u8));
        }
        if let CurveLocation::OnEdge { t, .. } = location {
            let (a, b) = (corners[0], corners[1]);
            let (key, fraction) = if a < b {
                ((a, b), t)
            } else {
                ((b, a), 1.0 - t)
            };
            self.edge_points
                .entry(key)
                .or_default()
                .push((fraction, index));
        }
        index
    }
}

/// A point of a triangle being re-triangulated: its cut-mesh vertex and barycentric
/// coordinates in the triangle.
struct Node {
    vertex: u32,
    barycentric: [f64; 3],
}

impl Node {
    /// Position in the triangle's barycentric plane, where the triangle is the unit right
    /// triangle: orientation and containment are the triangle's, and edge points have
    /// exact coordinates.
    fn plane(&self) -> DVec2 {
        DVec2::new(self.barycentric[1], self.barycentric[2])
    }
}

/// One triangle replacing part of a split triangle.
struct Piece {
    vertices: [u32; 3],
    barycentric: [[f64; 3]; 3],
}

/// Re-triangulates the triangles the curves run through.
struct Splitter<'a> {
    mesh: &'a TriMesh,
    curves: &'a [SurfaceCurve],
    loops: &'a [Vec<u32>],
    vertices: &'a CutVertices,
}

impl Splitter<'_> {
    /// Triangle `t` split along the curve segments through its inside, `(curve, index)`,
    /// and at the new vertices on its edges.
    fn split(&self, t: usize, segments: &[(usize, usize)]) -> Result<Vec<Piece>, CutError> {
        let failure = || CutError::Triangulation {
            triangle: t,
            position: (self.mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0).to_array(),
        };
        // The outline, counter-clockwise: each corner followed by the points on its edge.
        let corners = self.mesh.triangles[t];
        let mut nodes = Vec::new();
        for k in 0..3 {
            let (a, b) = (corners[k], corners[(k + 1) % 3]);
            nodes.push(Node {
                vertex: a,
                barycentric: unit(k),
            });
            let Some(points) = self.vertices.edge_points.get(&(a.min(b), a.max(b))) else {
                continue;
            };
            let mut along: Vec<(f64, u32)> = points
                .iter()
                .map(|&(s, v)| (if a < b { s } else { 1.0 - s }, v))
                .collect();
            along.sort_by(|x, y| x.0.total_cmp(&y.0));
            for (s, vertex) in along {
                let mut barycentric = [0.0; 3];
                barycentric[k] = 1.0 - s;
                barycentric[(k + 1) % 3] = s;
                nodes.push(Node {
                    vertex,
                    barycentric,
                });
            }
        }
        let mut faces = vec![(0..nodes.len()).collect::<Vec<usize>>()];
        for chain in self.chains(t, segments, &mut nodes)? {
            split_face(&mut faces, &chain, &nodes).ok_or_else(failure)?;
        }
        let mut pieces = Vec::new();
        for face in &faces {
            let triangles =
                triangulate(face, &nodes, &self.vertices.positions).ok_or_else(failure)?;
            pieces.extend(triangles.into_iter().map(|tri| Piece {
                vertices: tri.map(|i| nodes[i].vertex),
                barycentric: tri.map(|i| nodes[i].barycentric),
            }));
        }
        Ok(pieces)
    }

    /// The curve pieces crossing triangle `t`: runs of segments from an outline node
    /// through points inside the triangle (appended to `nodes`) to an outline node.
    fn chains(
        &self,
        t: usize,
        segments: &[(usize, usize)],
        nodes: &mut Vec<Node>,
    ) -> Result<Vec<Vec<usize>>, CutError> {
        let outline = nodes.len();
        let outline_node = |nodes: &[Node], vertex: u32| {
            nodes[..outline]
                .iter()
                .position(|node| node.vertex == vertex)
                .ok_or(CutError::Triangulation {
                    triangle: t,
                    position: self.vertices.positions[vertex as usize].to_array(),
                })
        };
        let mut chains = Vec::new();
        for &(curve, start) in segments {
            let points = &self.curves[curve].points;
            let inside = |i: usize| match points[i].location {
                CurveLocation::InTriangle { triangle, .. } => triangle == t,
                _ => false,
            };
            if inside(start) {
                continue;
            }
            let mut chain = vec![outline_node(nodes, self.loops[curve][start])?];
            let mut i = (start + 1) % points.len();
            // Ends at the latest back at `start`, which is not inside.
            while let CurveLocation::InTriangle { barycentric, .. } = points[i].location
                && inside(i)
            {
                nodes.push(Node {
                    vertex: self.loops[curve][i],
                    barycentric,
                });
                chain.push(nodes.len() - 1);
                i = (i + 1) % points.len();
            }
            chain.push(outline_node(nodes, self.loops[curve][i])?);
            if chain[0] == chain[chain.len() - 1] {
                return Err(CutError::CurveInsideTriangle { curve, triangle: t });
            }
            chains.push(chain);
        }
        match segments.first() {
            Some(&(curve, _)) if chains.is_empty() => {
                Err(CutError::CurveInsideTriangle { curve, triangle: t })
            }
            _ => Ok(chains),
        }
    }
}

fn unit(k: usize) -> [f64; 3] {
    let mut result = [0.0; 3];
    result[k] = 1.0;
    result
}

/// Splits the face that `chain` (outline node, inner nodes, outline node) crosses into
/// the faces on its two sides, both counter-clockwise. `None` if no face holds the chain.
fn split_face(faces: &mut Vec<Vec<usize>>, chain: &[usize], nodes: &[Node]) -> Option<()> {
    let (start, end) = (chain[0], chain[chain.len() - 1]);
    let holds_ends = |face: &Vec<usize>| face.contains(&start) && face.contains(&end);
    let candidates: Vec<usize> = (0..faces.len())
        .filter(|&f| holds_ends(&faces[f]))
        .collect();
    let index = match candidates[..] {
        [only] => only,
        // The ends bound several faces: take the one the chain's first segment runs into.
        _ => {
            let probe = 0.5 * (nodes[chain[0]].plane() + nodes[chain[1]].plane());
            *candidates
                .iter()
                .find(|&&f| contains(&faces[f], nodes, probe))?
        }
    };
    let face = faces.swap_remove(index);
    let m = face.len();
    let (at_start, at_end) = (
        face.iter().position(|&n| n == start)?,
        face.iter().position(|&n| n == end)?,
    );
    // Outline nodes strictly between two positions, going forward.
    let face = &face;
    let between =
        |from: usize, to: usize| (1..(to + m - from) % m).map(move |k| face[(from + k) % m]);
    let left: Vec<usize> = chain
        .iter()
        .copied()
        .chain(between(at_end, at_start))
        .collect();
    let right: Vec<usize> = chain
        .iter()
        .rev()
        .copied()
        .chain(between(at_start, at_end))
        .collect();
    if left.len() < 3 || right.len() < 3 {
        return None;
    }
    faces.push(left);
    faces.push(right);
    Some(())
}

/// Whether `point` lies inside the polygon `face` (crossing number, barycentric plane).
fn contains(face: &[usize], nodes: &[Node], point: DVec2) -> bool {
    let m = face.len();
    let mut inside = false;
    for i in 0..m {
        let (a, b) = (nodes[face[i]].plane(), nodes[face[(i + 1) % m]].plane());
        if (a.y > point.y) != (b.y > point.y) {
            let x = a.x + (point.y - a.y) * (b.x - a.x) / (b.y - a.y);
            if point.x < x {
                inside = !inside;
            }
        }
    }
    inside
}

/// Ear-clips the counter-clockwise polygon `face`, always cutting off the best-shaped
/// known ear (in 3D). `None` if no valid ear is left (a self-overlapping polygon).
///
/// Clipping a vertex changes only its two neighbours' ears, except that ears the clipped
/// vertex blocked become valid; those are found by a full rescan once no known ear is
/// left. So a polygon of k vertices takes O(k²) rather than O(k³).
fn triangulate(face: &[usize], nodes: &[Node], positions: &[DVec3]) -> Option<Vec<[usize; 3]>> {
    let orient = |a: usize, b: usize, c: usize| {
        let (a, b, c) = (nodes[a].plane(), nodes[b].plane(), nodes[c].plane());
        (b - a).perp_dot(c - a)
    };
    let covers = |a, b, c, p| {
        orient(a, b, p) >= -COLLINEAR_TOLERANCE
            && orient(b, c, p) >= -COLLINEAR_TOLERANCE
            && orient(c, a, p) >= -COLLINEAR_TOLERANCE
    };
    let corners = |polygon: &[usize], i: usize| {
        let m = polygon.len();
        [polygon[(i + m - 1) % m], polygon[i], polygon[(i + 1) % m]]
    };
    // The shape quality of the ear at vertex `i`, if it is one.
    let ear = |polygon: &[usize], i: usize| {
        let [a, b, c] = corners(polygon, i);
        let is_ear = orient(a, b, c) > COLLINEAR_TOLERANCE
            && polygon
                .iter()
                .all(|&p| p == a || p == b || p == c || !covers(a, b, c, p));
        let [a, b, c] = [a, b, c].map(|n| positions[nodes[n].vertex as usize]);
        is_ear.then(|| shape_quality(a, b, c))
    };
    let all_ears = |polygon: &[usize]| -> Vec<Option<f64>> {
        (0..polygon.len()).map(|i| ear(polygon, i)).collect()
    };
    let best = |ears: &[Option<f64>]| {
        (0..ears.len())
            .filter(|&i| ears[i].is_some())
            .max_by(|&i, &j| ears[i].unwrap_or(0.0).total_cmp(&ears[j].unwrap_or(0.0)))
    };
    let mut polygon = face.to_vec();
    let mut ears = all_ears(&polygon);
    let mut triangles = Vec::with_capacity(face.len().saturating_sub(2));
    while polygon.len() > 3 {
        let i = match best(&ears) {
            Some(i) => i,
            None => {
                ears = all_ears(&polygon);
                best(&ears)?
            }
        };
        triangles.push(corners(&polygon, i));
        polygon.remove(i);
        ears.remove(i);
        let m = polygon.len();
        for j in [(i + m - 1) % m, i % m] {
            ears[j] = ear(&polygon, j);
        }
    }
    let [a, b, c] = polygon[..] else {
        return None;
    };
    (orient(a, b, c) > COLLINEAR_TOLERANCE).then(|| {
        triangles.push([a, b, c]);
        triangles
    })
}

/// 1 for an equilateral triangle, 0 for a degenerate one.
fn shape_quality(a: DVec3, b: DVec3, c: DVec3) -> f64 {
    let squares = a.distance_squared(b) + b.distance_squared(c) + c.distance_squared(a);
    if squares > 0.0 {
        2.0 * 3f64.sqrt() * (b - a).cross(c - a).length() / squares
    } else {
        0.0
    }
}

/// The cut mesh before labelling, with what labelling needs to know about the split.
struct Assembled {
    mesh: TriMesh,
    /// Whether each input triangle was split.
    is_split: Vec<bool>,
    /// The input triangle of each piece appended after the input triangles.
    extra_parents: Vec<usize>,
    /// Each directed edge of the pieces of split triangles, and its piece.
    piece_edges: HashMap<(u32, u32), usize>,
}

/// Puts the pieces in place of their triangles (the first in its slot, the rest at the
/// end) and carries the attribute layers along.
fn assemble(
    mesh: &TriMesh,
    vertices: CutVertices,
    affected: &[usize],
    pieces: Vec<Vec<Piece>>,
) -> Assembled {
    let original_count = mesh.triangles.len();
    let mut triangles = mesh.triangles.clone();
    let mut is_split = vec![false; original_count];
    let mut extra_parents = Vec::new();
    let mut placed = Vec::new(); // (index in the cut mesh, parent, piece)
    for (&parent, parent_pieces) in affected.iter().zip(pieces) {
        is_split[parent] = true;
        for (k, piece) in parent_pieces.into_iter().enumerate() {
            let index = if k == 0 {
                triangles[parent] = piece.vertices;
                parent
            } else {
                triangles.push(piece.vertices);
                extra_parents.push(parent);
                triangles.len() - 1
            };
            placed.push((index, parent, piece));
        }
    }
    let piece_edges = placed
        .iter()
        .flat_map(|(index, _, piece)| {
            let v = piece.vertices;
            (0..3).map(move |k| ((v[k], v[(k + 1) % 3]), *index))
        })
        .collect();

    let uv = mesh.uv.as_ref().map(|uv| {
        let mut coords = uv.coords.clone();
        let mut uv_triangles = uv.triangles.clone();
        uv_triangles.extend(extra_parents.iter().map(|&p| uv.triangles[p]));
        for (index, parent, piece) in &placed {
            let (corners, corner_uv) = (mesh.triangles[*parent], uv.triangles[*parent]);
            uv_triangles[*index] =
                [0, 1, 2].map(
                    |j| match corners.iter().position(|&c| c == piece.vertices[j]) {
                        Some(k) => corner_uv[k],
                        None => {
                            let weights = piece.barycentric[j];
                            coords.push(
                                (0..3)
                                    .map(|k| uv.coords[corner_uv[k] as usize] * weights[k])
                                    .sum(),
                            );
                            (coords.len() - 1) as u32
                        }
                    },
                );
        }
        UvLayer {
            coords,
            triangles: uv_triangles,
        }
    });
    let materials = mesh.materials.as_ref().map(|m| {
        let mut layer = m.clone();
        let extra = extra_parents.iter().map(|&p| m.triangle_material[p]);
        layer.triangle_material.extend(extra);
        layer
    });
    Assembled {
        mesh: TriMesh {
            positions: vertices.positions,
            triangles,
            vertex_colors: vertices.colors,
            uv,
            materials,
        },
        is_split,
        extra_parents,
        piece_edges,
    }
}

impl Assembled {
    /// The triangle of the cut mesh with the directed edge `a -> b`.
    fn triangle_with_edge(
        &self,
        original: &TriMesh,
        topology: &Topology,
        a: u32,
        b: u32,
    ) -> Option<usize> {
        if let Some(&t) = self.piece_edges.get(&(a, b)) {
            return Some(t);
        }
        // Otherwise an unsplit input triangle has it, if `a` is an input vertex.
        if a as usize >= original.positions.len() {
            return None;
        }
        let around = topology.vertex_triangles(a as usize);
        around.iter().map(|&t| t as usize).find(|&t| {
            let tri = original.triangles[t];
            !self.is_split[t] && (0..3).any(|k| tri[k] == a && tri[(k + 1) % 3] == b)
        })
    }

    /// The triangle across edge `k` of triangle `t` of the cut mesh.
    fn neighbor(
        &self,
        original: &TriMesh,
        topology: &Topology,
        t: usize,
        k: usize,
    ) -> Option<usize> {
        let count = original.triangles.len();
        let tri = self.mesh.triangles[t];
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        let across = |parent: usize, k: usize| {
            let u = topology.triangle_neighbors[parent][k];
            (u != NO_TRIANGLE).then_some(u as usize)
        };
        if t < count && !self.is_split[t] {
            // An input triangle: its neighbour or, if that was split, the piece across.
            let u = across(t, k)?;
            return if self.is_split[u] {
                self.piece_edges.get(&(b, a)).copied()
            } else {
                Some(u)
            };
        }
        // A piece: the piece across, or else the unsplit triangle across a whole edge of
        // its parent.
        if let Some(&u) = self.piece_edges.get(&(b, a)) {
            return Some(u);
        }
        let parent = if t < count {
            t
        } else {
            self.extra_parents[t - count]
        };
        let corners = original.triangles[parent];
        let k = (0..3).find(|&k| corners[k] == a && corners[(k + 1) % 3] == b)?;
        across(parent, k).filter(|&u| !self.is_split[u])
    }
}

/// The region of every triangle of the cut mesh; see the module documentation. Takes time
/// in proportion to the curves and the insides, not the whole mesh.
fn label(
    original: &TriMesh,
    topology: &Topology,
    cut: &Assembled,
    loops: &[Vec<u32>],
) -> Result<Vec<Region>, CutError> {
    let mesh = &cut.mesh;
    let mut regions: Vec<Option<Region>> = vec![None; mesh.triangles.len()];
    let mut stack = Vec::new();
    let assign = |t: usize, region: Region, regions: &mut [Option<Region>], stack: &mut Vec<_>| {
        match regions[t] {
            None => {
                regions[t] = Some(region);
                stack.push((t, region));
                Ok(())
            }
            Some(existing) if existing == region => Ok(()),
            Some(_) => Err(CutError::LabelConflict {
                position: (mesh.triangle_positions(t).iter().sum::<DVec3>() / 3.0).to_array(),
            }),
        }
    };
    // Hash lookups only for edges between two curve vertices: the flood fill is O(n).
    let mut on_curve = vec![false; mesh.positions.len()];
    let mut curve_edges = HashSet::new();
    for (curve, vertices) in loops.iter().enumerate() {
        let n = vertices.len();
        for i in 0..n {
            let (a, b) = (vertices[i], vertices[(i + 1) % n]);
            on_curve[a as usize] = true;
            curve_edges.insert((a, b));
            if let Some(t) = cut.triangle_with_edge(original, topology, a, b) {
                assign(t, Region::Inside(curve), &mut regions, &mut stack)?;
            }
            if let Some(t) = cut.triangle_with_edge(original, topology, b, a) {
                assign(t, Region::Outside, &mut regions, &mut stack)?;
            }
        }
    }
    let is_curve_edge = |a: u32, b: u32| {
        on_curve[a as usize]
            && on_curve[b as usize]
            && (curve_edges.contains(&(a, b)) || curve_edges.contains(&(b, a)))
    };
    // Only the insides need filling: an inside meeting any other label reaches a seed of
    // it, and whatever no inside reaches is outside.
    stack.retain(|&(_, region)| region != Region::Outside);
    while let Some((t, region)) = stack.pop() {
        let tri = mesh.triangles[t];
        for k in 0..3 {
            let (a, b) = (tri[k], tri[(k + 1) % 3]);
            if is_curve_edge(a, b) {
                continue;
            }
            if let Some(u) = cut.neighbor(original, topology, t, k) {
                assign(u, region, &mut regions, &mut stack)?;
            }
        }
    }
    Ok(regions
        .into_iter()
        .map(|r| r.unwrap_or(Region::Outside))
        .collect())
}

#[cfg(test)]
mod tests;
