//! Editing the cut curves' control points (paper IV-B) in the window: the curve a set of
//! control points gives, previewed on the scan while they are edited, and inserting and
//! removing points. The curve itself is `anatomy`'s closed C2 spline; the model build
//! then lays it on the surface exactly (`plan`'s model options take the control points).

use anatomy::breast::{ClosedSpline, SplineError};
use anatomy::{ControlPoints, Side};
use glam::DVec3;
use plan::Scan;

/// Spacing of the preview's samples along the spline (mm): finer than the scan's
/// triangles where the curve bends, coarse enough to draw every frame.
const PREVIEW_SPACING_MM: f64 = 2.0;

/// Parameter steps per spline segment when looking for the segment nearest a point.
const SEGMENT_STEPS: usize = 32;

/// The fewest control points a closed curve needs.
pub const MIN_CONTROL_POINTS: usize = 3;

/// The control points of one side, to edit.
pub fn side_mut(points: &mut ControlPoints, side: Side) -> &mut Vec<DVec3> {
    match side {
        Side::Left => &mut points.left,
        Side::Right => &mut points.right,
    }
}

/// The cut curve through `points` as a preview: the closed spline sampled about every
/// [`PREVIEW_SPACING_MM`], each sample moved to the closest point of `scan` (the model
/// build projects it onto the surface more carefully). Errors say why no spline passes
/// through the points.
pub fn preview_curve(points: &[DVec3], scan: &Scan) -> Result<Vec<DVec3>, String> {
    let spline = ClosedSpline::through(points).map_err(|error| match error {
        SplineError::TooFewPoints(count) => {
            format!("a cut curve needs at least {MIN_CONTROL_POINTS} control points, not {count}")
        }
        SplineError::CoincidentPoints { index } => format!(
            "control points {} and {} coincide",
            index + 1,
            (index + 1) % points.len() + 1
        ),
    })?;
    Ok(spline
        .sample(PREVIEW_SPACING_MM)
        .into_iter()
        .map(|p| scan.index.closest_point(p).point)
        .collect())
}

/// Inserts `point` into the curve that passes nearest to it, between the two control
/// points whose spline segment comes nearest, if that curve passes within
/// `max_distance_mm`; returns the side and the new point's index.
pub fn insert_nearest(
    points: &mut ControlPoints,
    point: DVec3,
    max_distance_mm: f64,
) -> Option<(Side, usize)> {
    let (side, segment, distance) = Side::BOTH
        .into_iter()
        .filter_map(|side| {
            let spline = ClosedSpline::through(points.side(side)).ok()?;
            let n = points.side(side).len();
            (0..n)
                .map(|segment| {
                    let distance = (0..=SEGMENT_STEPS)
                        .map(|k| {
                            let s = k as f64 / SEGMENT_STEPS as f64;
                            spline.evaluate(segment, s).distance(point)
                        })
                        .fold(f64::INFINITY, f64::min);
                    (side, segment, distance)
                })
                .min_by(|a, b| a.2.total_cmp(&b.2))
        })
        .min_by(|a, b| a.2.total_cmp(&b.2))?;
    if distance > max_distance_mm {
        return None;
    }
    side_mut(points, side).insert(segment + 1, point);
    Some((side, segment + 1))
}

/// Removes control point `index` of `side`, unless the curve would keep fewer than
/// [`MIN_CONTROL_POINTS`].
pub fn remove(points: &mut ControlPoints, side: Side, index: usize) -> Result<(), String> {
    let list = side_mut(points, side);
    if list.len() <= MIN_CONTROL_POINTS {
        return Err(format!(
            "the {side} cut curve keeps at least {MIN_CONTROL_POINTS} control points"
        ));
    }
    if index < list.len() {
        list.remove(index);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;
    use std::path::Path;

    /// Points on a circle of radius 10 mm about `centre` in the plane z = 0.
    fn circle(centre: DVec3, count: usize) -> Vec<DVec3> {
        (0..count)
            .map(|k| {
                let a = TAU * k as f64 / count as f64;
                centre + 10.0 * DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect()
    }

    #[test]
    fn a_point_goes_into_the_nearest_segment_of_the_nearest_curve() {
        let mut points = ControlPoints {
            left: circle(DVec3::new(60.0, 0.0, 0.0), 4),
            right: circle(DVec3::new(-60.0, 0.0, 0.0), 4),
        };
        // Between the right circle's first two points (angles 0 and 90°), on the circle.
        let between = DVec3::new(-60.0, 0.0, 0.0) + 10.0 * DVec3::new(0.6, 0.8, 0.0);
        assert_eq!(
            insert_nearest(&mut points, between, 5.0),
            Some((Side::Right, 1))
        );
        assert_eq!(points.right[1], between);
        assert_eq!(points.right.len(), 5);
        assert_eq!(points.left.len(), 4);
        // Far from both curves: nothing changes.
        assert_eq!(
            insert_nearest(&mut points, DVec3::new(0.0, 50.0, 0.0), 5.0),
            None
        );
        assert_eq!(points.right.len(), 5);

        remove(&mut points, Side::Right, 1).unwrap();
        assert_eq!(points.right, circle(DVec3::new(-60.0, 0.0, 0.0), 4));
        remove(&mut points, Side::Left, 0).unwrap();
        assert!(remove(&mut points, Side::Left, 0).is_err());
        assert_eq!(points.left.len(), 3);
    }

    #[test]
    fn the_preview_runs_through_the_control_points_on_the_surface() {
        // A flat sheet: the spline through points on it stays on it, and passes through
        // every control point (each is a sample).
        let scan = Scan::from_mesh(mesh::shapes::grid(40, 40, 1.0), Path::new("sheet")).unwrap();
        let points = circle(DVec3::new(20.0, 20.0, 0.0), 6);
        let curve = preview_curve(&points, &scan).unwrap();
        for p in &points {
            let nearest = curve
                .iter()
                .map(|c| c.distance(*p))
                .fold(f64::INFINITY, f64::min);
            assert!(nearest < 1e-9, "{p}: {nearest}");
        }
        assert!(curve.iter().all(|c| c.z.abs() < 1e-12));
        let error = preview_curve(&points[..2], &scan).unwrap_err();
        assert!(error.contains("at least 3"), "{error}");
    }
}
