//! Where on the body a failed model's problem lies, so that a user can be shown it (the
//! GUI rings it on the scan; issue 21, item 6). Errors that know a place say it through
//! their `place` method; a place is in the scan's file coordinates (mm).

use glam::DVec3;

/// Radius of the ring around a failure known only as a point (mm): about the reach of a
/// cut curve's control point, the thing the messages ask to move.
pub const POINT_RADIUS_MM: f64 = 15.0;

/// A ball on the body around a failure (mm, the scan's file coordinates).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Place {
    pub centre_mm: [f64; 3],
    pub radius_mm: f64,
}

impl Place {
    /// A failure at one point, ringed at [`POINT_RADIUS_MM`].
    pub fn at(position: [f64; 3]) -> Place {
        Place {
            centre_mm: position,
            radius_mm: POINT_RADIUS_MM,
        }
    }

    /// The ball about the mean of `points` that holds them all (at least
    /// [`POINT_RADIUS_MM`]); `None` without points or with a non-finite one.
    pub fn around(points: &[DVec3]) -> Option<Place> {
        if points.is_empty() || points.iter().any(|p| !p.is_finite()) {
            return None;
        }
        let centre = points.iter().sum::<DVec3>() / points.len() as f64;
        let reach = points
            .iter()
            .map(|p| p.distance(centre))
            .fold(0.0, f64::max);
        Some(Place {
            centre_mm: centre.to_array(),
            radius_mm: reach.max(POINT_RADIUS_MM),
        })
    }

    /// The centre as a vector.
    pub fn centre(&self) -> DVec3 {
        DVec3::from_array(self.centre_mm)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ball_around_points_holds_them_all() {
        // The corners of a 100 mm square: centre at its middle, radius half its diagonal.
        let corners = [
            DVec3::new(0.0, 0.0, 5.0),
            DVec3::new(100.0, 0.0, 5.0),
            DVec3::new(100.0, 100.0, 5.0),
            DVec3::new(0.0, 100.0, 5.0),
        ];
        let place = Place::around(&corners).unwrap();
        assert_eq!(place.centre_mm, [50.0, 50.0, 5.0]);
        assert!((place.radius_mm - 50.0 * 2f64.sqrt()).abs() < 1e-12);
        // One point: the point's ring.
        assert_eq!(
            Place::around(&[DVec3::ONE]),
            Some(Place::at([1.0, 1.0, 1.0]))
        );
        assert_eq!(Place::around(&[]), None);
        assert_eq!(Place::around(&[DVec3::new(f64::NAN, 0.0, 0.0)]), None);
    }
}
