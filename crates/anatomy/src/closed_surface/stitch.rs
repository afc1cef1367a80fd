//! Stitching: the band of triangles that closes the gap between the scan's and the
//! wall's borders on each clip plane.

use super::ClosedSurfaceError;
use super::clip::Side;
use super::clip_box::PLANE_NAMES;
use crate::fill_in::inside_polygon;
use glam::{DVec2, DVec3};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// The bands between the sides of the scan's border (`front_sides`) and those of the
/// wall's (`back_sides`, on the same planes in the same order, their vertex indices
/// shifted by `offset` in `positions`), side by side ([`band_on_side`]); an error where
/// the corners of a side differ, placed by `to_file` (box to file coordinates).
pub(super) fn bands(
    positions: &[DVec3],
    front_sides: &[Side; 4],
    back_sides: &[Side; 4],
    offset: u32,
    to_file: impl Fn(DVec3) -> [f64; 3],
) -> Result<Vec<[u32; 3]>, ClosedSurfaceError> {
    let mut triangles = Vec::new();
    for (front_side, back_side) in front_sides.iter().zip(back_sides) {
        let back_chain: Vec<u32> = back_side.chain.iter().map(|&v| v + offset).collect();
        let same_corner = |f: Option<&u32>, b: Option<&u32>| match (f, b) {
            (Some(&f), Some(&b)) => {
                let (p, q) = (positions[f as usize], positions[b as usize]);
                p.x == q.x && p.y == q.y
            }
            _ => false,
        };
        let differing = if !same_corner(front_side.chain.first(), back_chain.first()) {
            Some(front_side.chain.first())
        } else if !same_corner(front_side.chain.last(), back_chain.last()) {
            Some(front_side.chain.last())
        } else {
            None
        };
        if let Some(corner) = differing {
            return Err(ClosedSurfaceError::Stitch {
                what: format!(
                    "the corners of the scan's and the wall's border differ on the {} plane",
                    PLANE_NAMES[front_side.plane]
                ),
                near_mm: corner.map(|&v| to_file(positions[v as usize])),
            });
        }
        triangles.extend(band_on_side(
            positions,
            front_side.plane,
            &front_side.chain,
            &back_chain,
            &to_file,
        )?);
    }
    Ok(triangles)
}

/// The band on `plane` (an index into [`ClipBox::planes`]) between one side of the scan
/// (`front`, in the scan's border direction) and the same side of the wall (`back`, same
/// direction, same first and last corner in the plane): a constrained Delaunay
/// triangulation of the planar polygon the two chains bound, oriented against the
/// polygon so the triangles run against the scan's border edges and the wall's.
///
/// [`ClipBox::planes`]: super::ClipBox::planes
fn band_on_side(
    positions: &[DVec3],
    plane: usize,
    front: &[u32],
    back: &[u32],
    to_file: impl Fn(DVec3) -> [f64; 3],
) -> Result<Vec<[u32; 3]>, ClosedSurfaceError> {
    let polygon: Vec<u32> = front.iter().chain(back.iter().rev()).copied().collect();
    triangulate_in_plane(positions, plane, &polygon).map_err(|defect| ClosedSurfaceError::Stitch {
        what: format!(
            "on the {} plane {}",
            PLANE_NAMES[plane],
            defect.describe(
                "the skin's section and the section of the chest wall rebuilt behind it \
                 cross (the skin there runs almost front to back, as under a hanging \
                 breast or along the side of the torso)",
                "a point of the skin's section coincides with one of the rebuilt chest wall's"
            )
        ),
        near_mm: defect.at().map(to_file),
    })
}

/// Why a polygon on a clip plane could not be triangulated.
pub(super) enum PolygonDefect {
    /// A coordinate spade refuses.
    Invalid(String),
    /// Two edges cross: the middle of one of them (the coordinates of `positions`).
    Crossing(DVec3),
    /// Two corners coincide, there.
    Coincident(DVec3),
}

impl PolygonDefect {
    /// Where the defect lies, if it has one place.
    pub(super) fn at(&self) -> Option<DVec3> {
        match self {
            PolygonDefect::Invalid(_) => None,
            PolygonDefect::Crossing(at) | PolygonDefect::Coincident(at) => Some(*at),
        }
    }

    pub(super) fn describe(&self, crossing: &str, coincident: &str) -> String {
        match self {
            PolygonDefect::Invalid(error) => format!("has an invalid coordinate ({error})"),
            PolygonDefect::Crossing(_) => crossing.to_string(),
            PolygonDefect::Coincident(_) => coincident.to_string(),
        }
    }
}

/// The triangles of the simple polygon `polygon` (vertex indices into `positions`, all
/// on `plane`, an index into [`ClipBox::planes`]): a constrained Delaunay triangulation
/// of its corners without new vertices, oriented against the polygon's sense, so the
/// triangles run against the polygon's edges.
///
/// [`ClipBox::planes`]: super::ClipBox::planes
pub(super) fn triangulate_in_plane(
    positions: &[DVec3],
    plane: usize,
    polygon: &[u32],
) -> Result<Vec<[u32; 3]>, PolygonDefect> {
    // In-plane coordinates: along the plane's side of the box, and anterior.
    let along = 1 - [0, 0, 1, 1][plane];
    let flat: Vec<DVec2> = polygon
        .iter()
        .map(|&v| {
            let p = positions[v as usize];
            DVec2::new(p[along], p.z)
        })
        .collect();
    let n = flat.len();
    let twice_area: f64 = (0..n).map(|k| flat[k].perp_dot(flat[(k + 1) % n])).sum();
    let counter_clockwise = twice_area > 0.0;
    // Spade refuses nonzero coordinates below its minimum; they are zero to any purpose.
    let flush = |x: f64| {
        if x.abs() < spade::MIN_ALLOWED_VALUE {
            0.0
        } else {
            x
        }
    };
    let vertices: Vec<Point2<f64>> = flat
        .iter()
        .map(|p| Point2::new(flush(p.x), flush(p.y)))
        .collect();
    let edges = (0..n).map(|k| [k, (k + 1) % n]).collect();
    let mut conflict = None;
    let cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(
        vertices.clone(),
        edges,
        |edge| conflict = conflict.or(Some(edge)),
    )
    .map_err(|error| PolygonDefect::Invalid(error.to_string()))?;
    let position = |k: usize| positions[polygon[k] as usize];
    if let Some([from, to]) = conflict {
        return Err(PolygonDefect::Crossing(
            0.5 * (position(from) + position(to)),
        ));
    }
    if cdt.num_vertices() != n {
        let mut order: Vec<usize> = (0..n).collect();
        let key = |k: usize| (vertices[k].x, vertices[k].y);
        order.sort_by(|&a, &b| {
            let ((ax, ay), (bx, by)) = (key(a), key(b));
            ax.total_cmp(&bx).then(ay.total_cmp(&by))
        });
        let twin = order.windows(2).find(|pair| key(pair[0]) == key(pair[1]));
        return Err(match twin {
            Some(pair) => PolygonDefect::Coincident(position(pair[0])),
            None => PolygonDefect::Invalid("a corner was dropped".into()),
        });
    }
    Ok(cdt
        .inner_faces()
        .filter_map(|face| {
            // Spade lists corners counter-clockwise.
            let corners = face.vertices().map(|v| v.fix().index());
            let inside = inside_polygon(corners, counter_clockwise);
            // Against the polygon's sense: clockwise if the polygon runs counter-clockwise.
            let [a, b, c] = corners.map(|k| polygon[k]);
            inside.then_some(if counter_clockwise {
                [a, c, b]
            } else {
                [a, b, c]
            })
        })
        .collect())
}
