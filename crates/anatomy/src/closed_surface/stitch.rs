//! Stitching: the band of triangles that closes the gap between the scan's and the
//! wall's borders on each clip plane.

use super::ClosedSurfaceError;
use super::clip::Side;
use super::clip_box::PLANE_NAMES;
use crate::fill_in::inside_polygon;
use glam::{DVec2, DVec3};
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

/// Largest move (mm) of a wall border vertex when a fold of its chain is straightened:
/// the wall is built, not measured, and a fold of its section this small carries no shape.
const MAX_FOLD_STRAIGHTENING_MM: f64 = 1.0;
/// How many chain edges apart the two crossing edges of a fold may lie.
const MAX_FOLD_EDGES: usize = 6;

/// A point on clip plane `plane` (an index into [`ClipBox::planes`]) in the plane's own
/// coordinates: along the plane's side of the box, and anterior.
///
/// [`ClipBox::planes`]: super::ClipBox::planes
fn in_plane(p: DVec3, plane: usize) -> DVec2 {
    let along = 1 - [0, 0, 1, 1][plane];
    DVec2::new(p[along], p.z)
}

/// Whether segments `a`-`b` and `c`-`d` cross at a point inside both.
fn segments_cross(a: DVec2, b: DVec2, c: DVec2, d: DVec2) -> bool {
    let turn = |p: DVec2, q: DVec2, r: DVec2| (q - p).perp_dot(r - p);
    turn(a, b, c) * turn(a, b, d) < 0.0 && turn(c, d, a) * turn(c, d, b) < 0.0
}

/// Straightens the small folds of the wall's border chains (`sides`, vertex indices
/// shifted by `offset` in `positions`) on the clip planes: where two edges of a chain at
/// most [`MAX_FOLD_EDGES`] apart cross in the plane, the vertices between them are put
/// evenly on the straight line joining the fold's outer ends (on the plane, so they stay
/// on it), unless one would move more than [`MAX_FOLD_STRAIGHTENING_MM`]. A chain's ends
/// (the box's corners) never move. Returns the number of folds straightened.
pub(super) fn straighten_small_folds(
    positions: &mut [DVec3],
    sides: &[Side; 4],
    offset: u32,
) -> usize {
    let mut straightened = 0;
    for side in sides {
        let chain: Vec<usize> = side.chain.iter().map(|&v| (v + offset) as usize).collect();
        let flat = |positions: &[DVec3], k: usize| in_plane(positions[chain[k]], side.plane);
        let mut i = 0;
        while i + 2 < chain.len() {
            let last = (i + MAX_FOLD_EDGES).min(chain.len() - 2);
            let fold = (i + 2..=last).find(|&j| {
                segments_cross(
                    flat(positions, i),
                    flat(positions, i + 1),
                    flat(positions, j),
                    flat(positions, j + 1),
                )
            });
            let Some(j) = fold else {
                i += 1;
                continue;
            };
            let (start, end) = (positions[chain[i]], positions[chain[j + 1]]);
            let steps = (j + 1 - i) as f64;
            let line: Vec<DVec3> = (i + 1..=j)
                .map(|k| start.lerp(end, (k - i) as f64 / steps))
                .collect();
            let small = (i + 1..=j)
                .zip(&line)
                .all(|(k, p)| positions[chain[k]].distance(*p) <= MAX_FOLD_STRAIGHTENING_MM);
            if small {
                for (k, p) in (i + 1..=j).zip(line) {
                    positions[chain[k]] = p;
                }
                straightened += 1;
            }
            i = j + 1;
        }
    }
    straightened
}

/// The bands between the sides of the scan's border (`front_sides`) and those of the
/// wall's (`back_sides`, on the same planes in the same order, their vertex indices
/// shifted by `offset` in `positions`), side by side ([`band_on_side`]); an error where
/// the corners of a side differ.
pub(super) fn bands(
    positions: &[DVec3],
    front_sides: &[Side; 4],
    back_sides: &[Side; 4],
    offset: u32,
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
        if !same_corner(front_side.chain.first(), back_chain.first())
            || !same_corner(front_side.chain.last(), back_chain.last())
        {
            return Err(ClosedSurfaceError::Stitch(format!(
                "the corners of the scan's and the wall's border differ on the {} plane",
                PLANE_NAMES[front_side.plane]
            )));
        }
        triangles.extend(band_on_side(
            positions,
            front_side.plane,
            &front_side.chain,
            &back_chain,
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
) -> Result<Vec<[u32; 3]>, ClosedSurfaceError> {
    let polygon: Vec<u32> = front.iter().chain(back.iter().rev()).copied().collect();
    triangulate_in_plane(positions, plane, &polygon).map_err(|defect| {
        ClosedSurfaceError::Stitch(format!(
            "on the {} plane {}",
            PLANE_NAMES[plane],
            defect.describe(
                "the scan's cut curve and the shifted wall's cross",
                "a point of the scan's cut curve coincides with one of the wall's"
            )
        ))
    })
}

/// Why a polygon on a clip plane could not be triangulated.
pub(super) enum PolygonDefect {
    /// A coordinate spade refuses.
    Invalid(String),
    /// Two edges cross.
    Crossing,
    /// Two corners coincide.
    Coincident,
}

impl PolygonDefect {
    pub(super) fn describe(&self, crossing: &str, coincident: &str) -> String {
        match self {
            PolygonDefect::Invalid(error) => format!("has an invalid coordinate ({error})"),
            PolygonDefect::Crossing => crossing.to_string(),
            PolygonDefect::Coincident => coincident.to_string(),
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
    let flat: Vec<DVec2> = polygon
        .iter()
        .map(|&v| in_plane(positions[v as usize], plane))
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
    let mut conflict = false;
    let cdt =
        ConstrainedDelaunayTriangulation::<Point2<f64>>::try_bulk_load_cdt(vertices, edges, |_| {
            conflict = true
        })
        .map_err(|error| PolygonDefect::Invalid(error.to_string()))?;
    if conflict {
        return Err(PolygonDefect::Crossing);
    }
    if cdt.num_vertices() != n {
        return Err(PolygonDefect::Coincident);
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain on plane 0 (coordinates y along, z depth) at x = -90 mm through `points`.
    fn chain_on_plane(points: &[(f64, f64)]) -> (Vec<DVec3>, [Side; 4]) {
        let positions = points
            .iter()
            .map(|&(y, z)| DVec3::new(-90.0, y, z))
            .collect();
        let side = |plane: usize, chain: Vec<u32>| Side { plane, chain };
        let chain = (0..points.len() as u32).collect();
        let sides = [
            side(0, chain),
            side(1, vec![]),
            side(2, vec![]),
            side(3, vec![]),
        ];
        (positions, sides)
    }

    fn crossings(positions: &[DVec3]) -> usize {
        let flat: Vec<DVec2> = positions.iter().map(|&p| in_plane(p, 0)).collect();
        let edges = flat.len() - 1;
        (0..edges)
            .flat_map(|i| (i + 2..edges).map(move |j| (i, j)))
            .filter(|&(i, j)| segments_cross(flat[i], flat[i + 1], flat[j], flat[j + 1]))
            .count()
    }

    /// A fold of a few tenths of a millimetre (the second edge turns back and the fourth
    /// crosses it) is straightened onto the line between its ends: no crossing is left,
    /// the ends and the plane stay; the same fold five times larger is left alone.
    #[test]
    fn a_sub_millimetre_fold_is_straightened_and_a_large_one_kept() {
        let fold = [
            (0.0, 0.0),
            (0.6, 0.0),
            (0.45, 0.03),
            (0.48, -0.03),
            (1.2, 0.0),
            (2.0, 0.0),
        ];
        let (mut positions, sides) = chain_on_plane(&fold);
        assert_eq!(crossings(&positions), 1);
        let before = positions.clone();
        assert_eq!(straighten_small_folds(&mut positions, &sides, 0), 1);
        assert_eq!(crossings(&positions), 0);
        // The two vertices inside the fold lie a third and two thirds of the way from
        // the first point to the fourth; the others did not move.
        let expected = |t: f64| before[0].lerp(before[3], t);
        assert!(positions[1].distance(expected(1.0 / 3.0)) < 1e-12);
        assert!(positions[2].distance(expected(2.0 / 3.0)) < 1e-12);
        for k in [0, 3, 4, 5] {
            assert_eq!(positions[k], before[k]);
        }
        assert!(positions.iter().all(|p| p.x == -90.0));

        let large: Vec<(f64, f64)> = fold.iter().map(|&(y, z)| (5.0 * y, 5.0 * z)).collect();
        let (mut positions, sides) = chain_on_plane(&large);
        let before = positions.clone();
        assert_eq!(straighten_small_folds(&mut positions, &sides, 0), 0);
        assert_eq!(positions, before);
    }
}
