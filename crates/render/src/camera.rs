//! The camera: where a standard view looks from, in the body's axes, and how a point maps
//! to a pixel.
//!
//! Body axes are a matrix whose columns are the patient's left, up and anterior
//! directions in file coordinates (the anatomical frame's axes; any orthonormal,
//! right-handed frame works). Pixels are measured from the image's top-left corner, x to
//! the right and y down; pixel `(i, j)` covers `[i, i+1) × [j, j+1)`, so its centre is at
//! `(i + 0.5, j + 0.5)`.

use crate::RenderError;
use glam::{DMat3, DVec2, DVec3};

/// Empty border on each side of framed points, as a fraction of the image's height.
const MARGIN_FRACTION: f64 = 0.05;
/// How far body axes may be from orthonormal (dot products, lengths) and still count.
const AXES_TOLERANCE: f64 = 1e-6;
/// Points closer to a perspective eye than this fraction of the eye distance are not
/// drawn (the near plane).
const NEAR_FRACTION: f64 = 0.05;

/// A standard clinical view, named for the side of the patient the viewer looks at (the
/// GUI's view buttons too).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum StandardView {
    Front,
    /// Between front and the patient's left side, 45°.
    LeftOblique,
    /// The patient's left side.
    Left,
    /// Between front and the patient's right side, 45°.
    RightOblique,
    /// The patient's right side.
    Right,
}

impl StandardView {
    /// Every view: the front, then the patient's left side, then her right (the order
    /// of the GUI's toolbar and of a report's pictures).
    pub const ALL: [StandardView; 5] = [
        StandardView::Front,
        StandardView::LeftOblique,
        StandardView::Left,
        StandardView::RightOblique,
        StandardView::Right,
    ];

    /// A label for people.
    pub fn label(self) -> &'static str {
        match self {
            StandardView::Front => "Front",
            StandardView::LeftOblique => "Left oblique",
            StandardView::Left => "Left",
            StandardView::RightOblique => "Right oblique",
            StandardView::Right => "Right",
        }
    }

    /// A name for files and ids (`front`, `left_oblique`, ...).
    pub fn id(self) -> &'static str {
        match self {
            StandardView::Front => "front",
            StandardView::LeftOblique => "left_oblique",
            StandardView::Left => "left",
            StandardView::RightOblique => "right_oblique",
            StandardView::Right => "right",
        }
    }

    /// Azimuth of the viewer about the body's up axis, from anterior towards the
    /// patient's left (radians).
    pub fn azimuth(self) -> f64 {
        let degrees: f64 = match self {
            StandardView::Front => 0.0,
            StandardView::LeftOblique => 45.0,
            StandardView::Left => 90.0,
            StandardView::RightOblique => -45.0,
            StandardView::Right => -90.0,
        };
        degrees.to_radians()
    }
}

/// How depth shows.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Projection {
    /// Parallel rays: sizes do not change with depth (measurable pictures).
    Orthographic,
    /// A pinhole `eye_distance_mm` in front of the target: nearer parts look larger.
    Perspective { eye_distance_mm: f64 },
}

/// A point as the camera sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProjectedPoint {
    /// Position in the image (pixels from the top-left corner, y down).
    pub pixel: DVec2,
    /// Distance along the viewing direction (mm), larger is farther: from the target's
    /// plane for an orthographic camera (negative in front of it), from the eye for a
    /// perspective one.
    pub depth_mm: f64,
}

/// A camera looking at `target` along `-backward`, with `up` up and `right` to the right
/// on the screen (unit vectors, file frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    pub right: DVec3,
    pub up: DVec3,
    /// From the scene towards the viewer.
    pub backward: DVec3,
    /// The point at the image's centre (mm, file frame).
    pub target: DVec3,
    /// Height of the scene the image shows at the target's depth (mm).
    pub view_height_mm: f64,
    pub projection: Projection,
}

impl Camera {
    /// An orthographic camera looking from `view` in `body_axes` at `target`, showing
    /// `view_height_mm` from the image's top to its bottom.
    pub fn looking_from(
        view: StandardView,
        body_axes: DMat3,
        target: DVec3,
        view_height_mm: f64,
    ) -> Result<Camera, RenderError> {
        check_body_axes(body_axes)?;
        let (sin_a, cos_a) = view.azimuth().sin_cos();
        let backward = body_axes * DVec3::new(sin_a, 0.0, cos_a);
        let up = body_axes.y_axis;
        let camera = Camera {
            right: up.cross(backward),
            up,
            backward,
            target,
            view_height_mm,
            projection: Projection::Orthographic,
        };
        camera.validate()?;
        Ok(camera)
    }

    /// An orthographic camera looking from `view` in `body_axes` that shows all `points`
    /// (mm, file frame; e.g. a mesh's vertices or a box's corners) centred, with a margin,
    /// in an image of `aspect` = width / height.
    pub fn framing(
        view: StandardView,
        body_axes: DMat3,
        points: &[DVec3],
        aspect: f64,
    ) -> Result<Camera, RenderError> {
        let mut camera = Camera::looking_from(view, body_axes, DVec3::ZERO, 1.0)?;
        let extent = ScreenExtent::of(&camera, points)?;
        camera.target = extent.centre(&camera);
        camera.view_height_mm = extent.view_height_mm(aspect)?;
        Ok(camera)
    }

    /// Cameras for all [`StandardView::ALL`], each framing `points` as
    /// [`Camera::framing`] does, all at the same scale (the largest any view needs), so
    /// the views can be compared side by side.
    pub fn standard_views(
        body_axes: DMat3,
        points: &[DVec3],
        aspect: f64,
    ) -> Result<Vec<(StandardView, Camera)>, RenderError> {
        let mut cameras = StandardView::ALL
            .iter()
            .map(|&view| Ok((view, Camera::framing(view, body_axes, points, aspect)?)))
            .collect::<Result<Vec<_>, RenderError>>()?;
        let common_height_mm = cameras
            .iter()
            .map(|(_, camera)| camera.view_height_mm)
            .fold(0.0, f64::max);
        for (_, camera) in &mut cameras {
            camera.view_height_mm = common_height_mm;
        }
        Ok(cameras)
    }

    /// The same view through a pinhole with a vertical field of view of `fov_y`
    /// (radians, 0 to π): the scene at the target's depth keeps its size in the image,
    /// nearer parts grow. A mild 15-20° keeps the framing margin enough.
    pub fn with_perspective(self, fov_y: f64) -> Result<Camera, RenderError> {
        if !(fov_y > 0.0 && fov_y < std::f64::consts::PI) {
            return Err(RenderError::Camera(
                "the field of view must be between 0 and 180 degrees",
            ));
        }
        Ok(Camera {
            projection: Projection::Perspective {
                eye_distance_mm: 0.5 * self.view_height_mm / (0.5 * fov_y).tan(),
            },
            ..self
        })
    }

    /// Checks the camera's numbers: finite, an orthonormal screen basis, a positive view
    /// height and eye distance.
    pub fn validate(&self) -> Result<(), RenderError> {
        if !(self.right.is_finite() && self.up.is_finite() && self.backward.is_finite()) {
            return Err(RenderError::Camera("its axes are not finite"));
        }
        check_body_axes(DMat3::from_cols(self.right, self.up, self.backward))?;
        if !self.target.is_finite() {
            return Err(RenderError::Camera("its target is not finite"));
        }
        if !(self.view_height_mm > 0.0 && self.view_height_mm.is_finite()) {
            return Err(RenderError::Camera(
                "its view height must be a positive number of millimetres",
            ));
        }
        if let Projection::Perspective { eye_distance_mm } = self.projection
            && !(eye_distance_mm > 0.0 && eye_distance_mm.is_finite())
        {
            return Err(RenderError::Camera(
                "its eye distance must be a positive number of millimetres",
            ));
        }
        Ok(())
    }

    /// Image pixels per millimetre at the target's depth, for an image `height` pixels
    /// high.
    pub fn pixels_per_mm(&self, height: f64) -> f64 {
        height / self.view_height_mm
    }

    /// Where `point` (mm, file frame) appears in an image of `width` × `height` pixels;
    /// `None` for a perspective camera when the point is not in front of the near plane.
    pub fn project(&self, point: DVec3, width: f64, height: f64) -> Option<ProjectedPoint> {
        let offset = point - self.target;
        let (x, y, towards_viewer) = (
            offset.dot(self.right),
            offset.dot(self.up),
            offset.dot(self.backward),
        );
        let scale = self.pixels_per_mm(height);
        let (magnification, depth_mm) = match self.projection {
            Projection::Orthographic => (1.0, -towards_viewer),
            Projection::Perspective { eye_distance_mm } => {
                let distance = eye_distance_mm - towards_viewer;
                if distance <= NEAR_FRACTION * eye_distance_mm {
                    return None;
                }
                (eye_distance_mm / distance, distance)
            }
        };
        Some(ProjectedPoint {
            pixel: DVec2::new(
                0.5 * width + x * scale * magnification,
                0.5 * height - y * scale * magnification,
            ),
            depth_mm,
        })
    }

    /// A direction (file frame) in screen coordinates: x right, y up, z towards the
    /// viewer.
    pub(crate) fn to_screen_axes(self, direction: DVec3) -> DVec3 {
        DVec3::new(
            direction.dot(self.right),
            direction.dot(self.up),
            direction.dot(self.backward),
        )
    }
}

/// The extent of points in the screen plane of a camera (mm along its right and up axes,
/// and along its backward axis).
struct ScreenExtent {
    min: DVec3,
    max: DVec3,
}

impl ScreenExtent {
    fn of(camera: &Camera, points: &[DVec3]) -> Result<ScreenExtent, RenderError> {
        if points.is_empty() {
            return Err(RenderError::Framing("no points given"));
        }
        let mut extent = ScreenExtent {
            min: DVec3::INFINITY,
            max: DVec3::NEG_INFINITY,
        };
        for &point in points {
            if !point.is_finite() {
                return Err(RenderError::Framing("a point is not finite"));
            }
            let screen = camera.to_screen_axes(point);
            extent.min = extent.min.min(screen);
            extent.max = extent.max.max(screen);
        }
        Ok(extent)
    }

    fn centre(&self, camera: &Camera) -> DVec3 {
        let mid = 0.5 * (self.min + self.max);
        camera.right * mid.x + camera.up * mid.y + camera.backward * mid.z
    }

    /// The view height that fits the extent into an image of `aspect` with the margin.
    fn view_height_mm(&self, aspect: f64) -> Result<f64, RenderError> {
        if !(aspect > 0.0 && aspect.is_finite()) {
            return Err(RenderError::Framing(
                "the image's aspect ratio is not a positive number",
            ));
        }
        let size = self.max - self.min;
        let needed = size.y.max(size.x / aspect);
        if !(needed > 0.0 && needed.is_finite()) {
            return Err(RenderError::Framing(
                "the points all project onto one pixel",
            ));
        }
        Ok(needed / (1.0 - 2.0 * MARGIN_FRACTION))
    }
}

fn check_body_axes(axes: DMat3) -> Result<(), RenderError> {
    let gram = axes.transpose() * axes;
    if !axes.is_finite() || !gram.abs_diff_eq(DMat3::IDENTITY, AXES_TOLERANCE) {
        return Err(RenderError::Camera("the axes are not orthonormal"));
    }
    if axes.determinant() < 0.0 {
        return Err(RenderError::Camera("the axes are not right-handed"));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    /// A body frame turned about an oblique axis: the file frame is not the body frame.
    fn tilted_body() -> DMat3 {
        DMat3::from_quat(DQuat::from_axis_angle(
            DVec3::new(0.3, 1.0, -0.4).normalize(),
            0.7,
        ))
    }

    #[test]
    fn views_look_from_the_named_side_with_the_body_upright() {
        let body = tilted_body();
        let [left, up, anterior] = [body.x_axis, body.y_axis, body.z_axis];
        let camera = |view| Camera::looking_from(view, body, DVec3::ZERO, 100.0).unwrap();
        let close = |a: DVec3, b: DVec3| a.distance(b) < 1e-12;
        // Facing the patient, her left is on the viewer's right.
        let front = camera(StandardView::Front);
        assert!(close(front.backward, anterior) && close(front.right, left));
        // From her left side, anterior is on the viewer's left.
        let side = camera(StandardView::Left);
        assert!(close(side.backward, left) && close(side.right, -anterior));
        let side = camera(StandardView::Right);
        assert!(close(side.backward, -left) && close(side.right, anterior));
        let oblique = camera(StandardView::LeftOblique);
        assert!(close(oblique.backward, (left + anterior) / 2f64.sqrt()));
        for view in StandardView::ALL {
            assert!(close(camera(view).up, up));
        }
    }

    #[test]
    fn framing_centres_the_points_inside_the_margin() {
        let body = tilted_body();
        // A box 300 mm wide, 400 mm high, 200 mm deep in body coordinates.
        let corners: Vec<DVec3> = (0..8)
            .map(|i| {
                let local = DVec3::new(
                    if i & 1 == 0 { -150.0 } else { 150.0 },
                    if i & 2 == 0 { -250.0 } else { 150.0 },
                    if i & 4 == 0 { 0.0 } else { 200.0 },
                );
                DVec3::new(5.0, 1200.0, -30.0) + body * local
            })
            .collect();
        let (width, height) = (800.0, 1000.0);
        let camera = Camera::framing(StandardView::Front, body, &corners, width / height).unwrap();
        // Height limits: 400 mm fill the image less the two margins.
        assert!((camera.view_height_mm - 400.0 / 0.9).abs() < 1e-9);
        let pixels: Vec<DVec2> = corners
            .iter()
            .map(|&p| camera.project(p, width, height).unwrap().pixel)
            .collect();
        let (min, max) = pixels
            .iter()
            .fold((DVec2::INFINITY, DVec2::NEG_INFINITY), |(lo, hi), &p| {
                (lo.min(p), hi.max(p))
            });
        assert!((min.y - 50.0).abs() < 1e-6 && (max.y - 950.0).abs() < 1e-6);
        assert!((min.x + max.x - width).abs() < 1e-6, "centred horizontally");
    }

    #[test]
    fn bad_cameras_are_errors() {
        let skewed = DMat3::from_cols(DVec3::X, DVec3::new(0.1, 1.0, 0.0), DVec3::Z);
        assert!(Camera::looking_from(StandardView::Front, skewed, DVec3::ZERO, 1.0).is_err());
        let mirrored = DMat3::from_cols(-DVec3::X, DVec3::Y, DVec3::Z);
        assert!(Camera::looking_from(StandardView::Front, mirrored, DVec3::ZERO, 1.0).is_err());
        let identity = DMat3::IDENTITY;
        assert!(Camera::looking_from(StandardView::Front, identity, DVec3::ZERO, 0.0).is_err());
        assert!(Camera::framing(StandardView::Front, identity, &[], 1.0).is_err());
        assert!(
            Camera::framing(
                StandardView::Front,
                identity,
                &[DVec3::ONE, DVec3::ONE],
                1.0
            )
            .is_err()
        );
        assert!(
            Camera::framing(
                StandardView::Front,
                identity,
                &[DVec3::NAN, DVec3::ONE],
                1.0
            )
            .is_err()
        );
    }
}
