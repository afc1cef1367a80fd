//! The stencils of isosurface stuffing: how one BCC lattice tetrahedron, its vertices
//! labelled inside / on the surface / outside after warping, is filled with output
//! tetrahedra.
//!
//! With `i` inside and `o` outside vertices (the rest on the surface):
//! - no inside vertex: nothing (four surface vertices would make a flat sliver along
//!   the surface);
//! - no outside vertex: the lattice tetrahedron itself;
//! - one inside vertex: one tetrahedron, each outside vertex replaced by the cut point
//!   on its edge to the inside one;
//! - two inside, one surface, one outside: a pyramid, two tetrahedra;
//! - two inside, two outside, or three inside, one outside: a triangular prism, three
//!   tetrahedra.
//!
//! A quadrilateral on a lattice face (two inside vertices `p`, `q`, one outside `m`) is
//! split by a diagonal that both tetrahedra sharing the face choose alike, from the face
//! alone:
//! - `pq` a long edge: the parity rule, the diagonal starts at the even end;
//! - `pq` a short edge: of `p`, `q` let `x` be the one in `m`'s grid (`xm` is the face's
//!   long edge) and `y` the other; the diagonal joins `x` to the cut point on `ym`.
//!   (The other choice, `y` to the cut on `xm`, measured a few degrees worse.)
//!
//! With these rules the three quadrilaterals of a 3-1 prism never form a cycle (the two
//! short-edge faces share one vertex, a source or a sink of the diagonals), so every
//! prism splits into three tetrahedra. In a 2-2 prism the third quadrilateral lies on the
//! surface, free of neighbours: its diagonal is forced when the lattice faces chain, and
//! otherwise chosen for the larger smallest dihedral angle.
//!
//! Output tetrahedra are oriented on a reference copy of the lattice tetrahedron (cut
//! points at edge midpoints, exact integer arithmetic), where every stencil is a proper
//! subdivision; warping then keeps orientations by the method's angle guarantee.

use crate::lattice::LatticePoint;
use crate::quality::{dihedral_angles, signed_volume};
use glam::{DVec3, I64Vec3, IVec3};

/// The label of a lattice vertex after warping.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Sign {
    Outside,
    Surface,
    Inside,
}

/// A vertex of a lattice tetrahedron as the stencils see it.
#[derive(Debug, Clone, Copy)]
pub(crate) struct StencilVertex {
    pub point: LatticePoint,
    pub sign: Sign,
}

/// What the stencils need from the mesher: output vertex keys and positions.
pub(crate) trait StencilContext {
    /// The output key of the cut point on the edge from `inside` to `outside`.
    fn cut_key(&self, inside: LatticePoint, outside: LatticePoint) -> u32;
    /// The final position of an output vertex (mm); lattice points have their index as
    /// key.
    fn position(&self, key: u32) -> DVec3;
    /// Which of the inside vertices `p`, `q` of the lattice face `(p, q, m)` (`m`
    /// outside) is the lattice end of the diagonal of its quadrilateral. It must depend
    /// on the face alone, and the three faces at the outside vertex of a 3-1 prism must
    /// not form a cycle. The default is the uniform BCC lattice's rule.
    fn diagonal_end(&self, p: LatticePoint, q: LatticePoint, m: LatticePoint) -> LatticePoint {
        diagonal_lattice_end(p, q, m)
    }
}

/// An output vertex with its position on the reference lattice, in units of a quarter
/// spacing.
#[derive(Debug, Clone, Copy)]
struct Corner {
    key: u32,
    reference: IVec3,
}

fn lattice_corner(p: LatticePoint) -> Corner {
    Corner {
        key: p.index,
        reference: p.doubled * 2,
    }
}

fn cut_corner(
    context: &impl StencilContext,
    inside: LatticePoint,
    outside: LatticePoint,
) -> Corner {
    Corner {
        key: context.cut_key(inside, outside),
        reference: inside.doubled + outside.doubled,
    }
}

/// `corners` reordered to positive orientation on the reference lattice.
fn oriented(mut corners: [Corner; 4]) -> [Corner; 4] {
    let r = corners.map(|c| c.reference.as_i64vec3());
    let det = (r[1] - r[0]).dot(cross(r[2] - r[0], r[3] - r[0]));
    debug_assert!(det != 0, "degenerate stencil tetrahedron");
    if det < 0 {
        corners.swap(2, 3);
    }
    corners
}

fn cross(a: I64Vec3, b: I64Vec3) -> I64Vec3 {
    I64Vec3::new(
        a.y * b.z - a.z * b.y,
        a.z * b.x - a.x * b.z,
        a.x * b.y - a.y * b.x,
    )
}

fn emit(out: &mut Vec<[u32; 4]>, corners: [Corner; 4]) {
    out.push(oriented(corners).map(|c| c.key));
}

/// Which of the inside vertices `p`, `q` of the lattice face `(p, q, m)` (`m` outside)
/// is the lattice end of the diagonal of its quadrilateral `p, q, cut(q, m), cut(p, m)`.
fn diagonal_lattice_end(p: LatticePoint, q: LatticePoint, m: LatticePoint) -> LatticePoint {
    if p.same_grid(q) {
        if p.is_odd() { q } else { p }
    } else if p.same_grid(m) {
        p
    } else {
        q
    }
}

/// The three tetrahedra of the prism with columns `top[i]`-`bottom[i]`, given for each
/// side quadrilateral `(i, j)` the diagonal as an arrow `i -> j` meaning
/// `top[i]`-`bottom[j]`. The arrows must not form a cycle.
fn prism(
    out: &mut Vec<[u32; 4]>,
    top: [Corner; 3],
    bottom: [Corner; 3],
    arrows: [(usize, usize); 3],
) {
    for tet in prism_tetrahedra(top, bottom, arrows) {
        emit(out, tet);
    }
}

fn prism_tetrahedra(
    top: [Corner; 3],
    bottom: [Corner; 3],
    arrows: [(usize, usize); 3],
) -> [[Corner; 4]; 3] {
    let mut out_degree = [0; 3];
    for &(from, _) in &arrows {
        out_degree[from] += 1;
    }
    debug_assert!(out_degree.contains(&2), "cyclic prism diagonals {arrows:?}");
    let mut order = [0, 1, 2];
    order.sort_by_key(|&c| std::cmp::Reverse(out_degree[c]));
    let [s, m, k] = order;
    [
        [top[s], top[m], top[k], bottom[k]],
        [top[s], top[m], bottom[m], bottom[k]],
        [top[s], bottom[s], bottom[m], bottom[k]],
    ]
    .map(oriented)
}

/// The diagonal arrow of the quadrilateral between prism columns `i` and `j` that lies on
/// the lattice face `(p, q, m)`, where `p` is column `i`'s end and `q` column `j`'s end.
fn face_arrow(
    context: &impl StencilContext,
    i: usize,
    j: usize,
    p: LatticePoint,
    q: LatticePoint,
    m: LatticePoint,
) -> (usize, usize) {
    if context.diagonal_end(p, q, m) == p {
        (i, j)
    } else {
        (j, i)
    }
}

/// Fills the lattice tetrahedron `vertices` by its stencil, appending output
/// tetrahedra (vertex keys, positively oriented) to `out`.
pub(crate) fn fill(
    vertices: &[StencilVertex; 4],
    context: &impl StencilContext,
    out: &mut Vec<[u32; 4]>,
) {
    let with = |sign: Sign| {
        let mut points = [vertices[0].point; 4];
        let mut count = 0;
        for v in vertices.iter().filter(|v| v.sign == sign) {
            points[count] = v.point;
            count += 1;
        }
        (points, count)
    };
    let (inside, inside_count) = with(Sign::Inside);
    let (outside, outside_count) = with(Sign::Outside);
    let (surface, _) = with(Sign::Surface);
    let whole = || vertices.map(|v| lattice_corner(v.point));
    match (inside_count, outside_count) {
        (0, _) => {}
        (_, 0) => emit(out, whole()),
        (1, _) => {
            let p = inside[0];
            let corners = vertices.map(|v| match v.sign {
                Sign::Outside => cut_corner(context, p, v.point),
                _ => lattice_corner(v.point),
            });
            emit(out, corners);
        }
        (2, 1) => {
            let (m, z) = (outside[0], surface[0]);
            let end = context.diagonal_end(inside[0], inside[1], m);
            let other = if end == inside[0] {
                inside[1]
            } else {
                inside[0]
            };
            let (end_cut, other_cut) = (cut_corner(context, end, m), cut_corner(context, other, m));
            let (end, other, z) = (
                lattice_corner(end),
                lattice_corner(other),
                lattice_corner(z),
            );
            emit(out, [end, other, other_cut, z]);
            emit(out, [end, other_cut, end_cut, z]);
        }
        (2, _) => two_two_prism(inside[0], inside[1], outside[0], outside[1], context, out),
        _ => {
            let m = outside[0];
            let p = [inside[0], inside[1], inside[2]];
            let top = p.map(lattice_corner);
            let bottom = p.map(|v| cut_corner(context, v, m));
            let arrows =
                [(0, 1), (1, 2), (0, 2)].map(|(i, j)| face_arrow(context, i, j, p[i], p[j], m));
            prism(out, top, bottom, arrows);
        }
    }
}

/// The prism of a lattice tetrahedron with inside vertices `p`, `q` and outside ones
/// `m1`, `m2`: columns `p`-`q`, `cut(p, m1)`-`cut(q, m1)`, `cut(p, m2)`-`cut(q, m2)`.
fn two_two_prism(
    p: LatticePoint,
    q: LatticePoint,
    m1: LatticePoint,
    m2: LatticePoint,
    context: &impl StencilContext,
    out: &mut Vec<[u32; 4]>,
) {
    let top = [
        lattice_corner(p),
        cut_corner(context, p, m1),
        cut_corner(context, p, m2),
    ];
    let bottom = [
        lattice_corner(q),
        cut_corner(context, q, m1),
        cut_corner(context, q, m2),
    ];
    let first = face_arrow(context, 0, 1, p, q, m1);
    let second = face_arrow(context, 0, 2, p, q, m2);
    let surface_options: &[(usize, usize)] = match (first, second) {
        ((1, 0), (0, 2)) => &[(1, 2)],
        ((0, 1), (2, 0)) => &[(2, 1)],
        _ => &[(1, 2), (2, 1)],
    };
    let score = |tets: &[[Corner; 4]; 3]| {
        tets.iter()
            .map(|tet| {
                let positions = tet.map(|c| context.position(c.key));
                if signed_volume(positions) > 0.0 {
                    dihedral_angles(positions)
                        .into_iter()
                        .fold(f64::INFINITY, f64::min)
                } else {
                    f64::NEG_INFINITY
                }
            })
            .fold(f64::INFINITY, f64::min)
    };
    let best = surface_options
        .iter()
        .map(|&surface| prism_tetrahedra(top, bottom, [first, second, surface]))
        .map(|tets| (score(&tets), tets))
        .reduce(|a, b| if b.0 > a.0 { b } else { a });
    if let Some((_, tets)) = best {
        for tet in tets {
            out.push(tet.map(|c| c.key));
        }
    }
}
