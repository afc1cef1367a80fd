//! The viewport's orbit camera as plain math: view and projection matrices, a pixel's
//! ray, a point's pixel, orbit, pan, zoom and the standard views. No GPU and no egui
//! here, so every function is unit-tested against known transforms.
//!
//! Lengths are millimetres in the scan's file frame; angles are radians; pixel positions
//! are measured from the viewport's top-left corner, x to the right and y down, in any
//! unit as long as the viewport size is given in the same one (the GUI uses egui points).
//! The orbit is expressed in a body frame whose columns are the patient's left (x), up
//! (y) and anterior (z) directions: the anatomical frame once Pj, Px, Pcl and Pcr are
//! placed, the file's axes before.

use glam::{DMat3, DMat4, DVec2, DVec3};
/// The standard views are the reports' (`render`): same names, same directions.
pub use render::StandardView;

/// Elevation is kept inside ±this so the view never flips over the pole (radians).
const MAX_ELEVATION: f64 = 89.0 * std::f64::consts::PI / 180.0;
/// Orbit angle per pixel of mouse drag (radians).
const ORBIT_PER_PIXEL: f64 = 0.008;
/// The camera never comes closer to its target than this (mm).
const MIN_DISTANCE_MM: f64 = 1.0;
/// Near and far clip planes as fractions / multiples of the eye distance.
const NEAR_FRACTION: f64 = 0.02;
const FAR_MULTIPLE: f64 = 20.0;

/// A ray from the eye through a pixel: `origin + t * direction`, `direction` unit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ray {
    /// On the near clip plane (mm, file frame).
    pub origin: DVec3,
    pub direction: DVec3,
}

/// An orbit camera looking at `target` from `distance` away.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Columns: the patient's left, up and anterior directions in file coordinates
    /// (orthonormal, right-handed).
    pub body: DMat3,
    /// The point orbited around and looked at (mm, file frame).
    pub target: DVec3,
    /// From the eye to the target (mm).
    pub distance: f64,
    /// Eye direction about the body's up axis, from anterior towards the patient's left
    /// (radians).
    pub azimuth: f64,
    /// Eye direction above the body's horizontal plane (radians).
    pub elevation: f64,
    /// Vertical field of view (radians).
    pub fov_y: f64,
}

impl Camera {
    /// The front view of a sphere (centre and radius in mm): the whole sphere fits the
    /// vertical field of view with a small margin.
    pub fn framing(body: DMat3, centre: DVec3, radius: f64) -> Camera {
        let fov_y = 30f64.to_radians();
        Camera {
            body,
            target: centre,
            distance: (1.1 * radius / (0.5 * fov_y).sin()).max(MIN_DISTANCE_MM),
            azimuth: 0.0,
            elevation: 0.0,
            fov_y,
        }
    }

    /// Unit vector from the target to the eye (file frame).
    pub fn backward(&self) -> DVec3 {
        let (sin_a, cos_a) = self.azimuth.sin_cos();
        let (sin_e, cos_e) = self.elevation.sin_cos();
        self.body * DVec3::new(sin_a * cos_e, sin_e, cos_a * cos_e)
    }

    /// The screen's up direction (file frame), orthogonal to the view direction.
    pub fn up(&self) -> DVec3 {
        let (sin_a, cos_a) = self.azimuth.sin_cos();
        let (sin_e, cos_e) = self.elevation.sin_cos();
        self.body * DVec3::new(-sin_a * sin_e, cos_e, -cos_a * sin_e)
    }

    /// The screen's right direction (file frame).
    pub fn right(&self) -> DVec3 {
        self.up().cross(self.backward())
    }

    /// The eye position (mm, file frame).
    pub fn eye(&self) -> DVec3 {
        self.target + self.distance * self.backward()
    }

    /// World (file frame) to view coordinates: the eye at the origin looking down -z,
    /// the screen's up along +y.
    pub fn view(&self) -> DMat4 {
        glam::dcamera::rh::view::look_at_mat4(self.eye(), self.target, self.up())
    }

    /// View to clip coordinates for a viewport of `aspect` = width / height, depth 0 at
    /// the near plane and 1 at the far plane, y up (wgpu's convention, as Direct3D's).
    pub fn projection(&self, aspect: f64) -> DMat4 {
        glam::dcamera::rh::proj::directx::perspective(
            self.fov_y,
            aspect.max(1e-6),
            NEAR_FRACTION * self.distance,
            FAR_MULTIPLE * self.distance,
        )
    }

    /// World to clip coordinates for a viewport of `size` (width, height).
    pub fn view_projection(&self, size: DVec2) -> DMat4 {
        self.projection(size.x / size.y.max(1e-6)) * self.view()
    }

    /// The ray from the eye through `pixel` of a viewport of `size`.
    pub fn ray(&self, pixel: DVec2, size: DVec2) -> Ray {
        let ndc = DVec2::new(2.0 * pixel.x / size.x - 1.0, 1.0 - 2.0 * pixel.y / size.y);
        let inverse = self.view_projection(size).inverse();
        let near = inverse.project_point3(ndc.extend(0.0));
        let far = inverse.project_point3(ndc.extend(1.0));
        Ray {
            origin: near,
            direction: (far - near).normalize(),
        }
    }

    /// Where `point` appears in a viewport of `size`; `None` behind the eye.
    pub fn project(&self, point: DVec3, size: DVec2) -> Option<DVec2> {
        let clip = self.view_projection(size) * point.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(DVec2::new(
            0.5 * (ndc.x + 1.0) * size.x,
            0.5 * (1.0 - ndc.y) * size.y,
        ))
    }

    /// Turns the eye about the target by a mouse drag of `delta` pixels: right drags turn
    /// the body to the right, downward drags tilt it towards the viewer's feet.
    pub fn orbit(&mut self, delta: DVec2) {
        self.azimuth -= delta.x * ORBIT_PER_PIXEL;
        self.elevation =
            (self.elevation + delta.y * ORBIT_PER_PIXEL).clamp(-MAX_ELEVATION, MAX_ELEVATION);
    }

    /// Moves the target in the screen plane so the point at the target's depth follows a
    /// mouse drag of `delta` pixels in a viewport `height` pixels high.
    pub fn pan(&mut self, delta: DVec2, height: f64) {
        let mm_per_pixel = 2.0 * self.distance * (0.5 * self.fov_y).tan() / height.max(1.0);
        self.target += mm_per_pixel * (-delta.x * self.right() + delta.y * self.up());
    }

    /// Multiplies the eye distance by `factor` (below one comes closer).
    pub fn zoom(&mut self, factor: f64) {
        if factor.is_finite() && factor > 0.0 {
            self.distance = (self.distance * factor).max(MIN_DISTANCE_MM);
        }
    }

    /// Looks from a standard direction (level, same target and distance) in the body frame
    /// `body`.
    pub fn set_view(&mut self, view: StandardView, body: DMat3) {
        self.body = body;
        self.azimuth = view.azimuth();
        self.elevation = 0.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    const SIZE: DVec2 = DVec2::new(800.0, 600.0);

    fn assert_close(a: DVec3, b: DVec3, tolerance: f64) {
        assert!(a.distance(b) < tolerance, "{a} vs {b}");
    }

    fn camera() -> Camera {
        Camera::framing(DMat3::IDENTITY, DVec3::new(10.0, -150.0, 40.0), 200.0)
    }

    /// A body frame turned 30° about the file's z axis and 20° about x.
    fn tilted_body() -> DMat3 {
        DMat3::from_quat(DQuat::from_rotation_z(30f64.to_radians()) * DQuat::from_rotation_x(0.35))
    }

    #[test]
    fn the_front_view_looks_at_the_chest_with_the_patient_left_on_screen_right() {
        let camera = camera();
        assert_close(
            camera.eye(),
            camera.target + DVec3::Z * camera.distance,
            1e-9,
        );
        let view = camera.view();
        assert_close(
            view.transform_point3(camera.target),
            DVec3::new(0.0, 0.0, -camera.distance),
            1e-9,
        );
        assert_close(view.transform_vector3(DVec3::X), DVec3::X, 1e-12);
        assert_close(view.transform_vector3(DVec3::Y), DVec3::Y, 1e-12);
        // The target is in the middle; the patient's left (+x) appears right of it and
        // up (+y) above it.
        let centre = camera.project(camera.target, SIZE).unwrap();
        assert_close(centre.extend(0.0), (SIZE / 2.0).extend(0.0), 1e-9);
        let left = camera
            .project(camera.target + 50.0 * DVec3::X, SIZE)
            .unwrap();
        let up = camera
            .project(camera.target + 50.0 * DVec3::Y, SIZE)
            .unwrap();
        assert!(left.x > centre.x + 10.0 && (left.y - centre.y).abs() < 1e-9);
        assert!(up.y < centre.y - 10.0 && (up.x - centre.x).abs() < 1e-9);
        // A 200 mm sphere fits the height.
        let top = camera
            .project(camera.target + 200.0 * DVec3::Y, SIZE)
            .unwrap();
        assert!(top.y > 0.0 && top.y < 0.1 * SIZE.y, "{top}");
    }

    #[test]
    fn side_views_look_from_the_patients_sides() {
        let mut camera = camera();
        camera.set_view(StandardView::Left, DMat3::IDENTITY);
        assert_close(
            camera.eye(),
            camera.target + DVec3::X * camera.distance,
            1e-9,
        );
        // Seen from the patient's left, the front of the body is on the screen's left.
        let anterior = camera
            .project(camera.target + 50.0 * DVec3::Z, SIZE)
            .unwrap();
        assert!(anterior.x < SIZE.x / 2.0 - 10.0, "{anterior}");
        camera.set_view(StandardView::Right, DMat3::IDENTITY);
        assert_close(
            camera.eye(),
            camera.target - DVec3::X * camera.distance,
            1e-9,
        );
        camera.set_view(StandardView::LeftOblique, DMat3::IDENTITY);
        let expected = DVec3::new(1.0, 0.0, 1.0).normalize() * camera.distance;
        assert_close(camera.eye(), camera.target + expected, 1e-9);
        camera.set_view(StandardView::RightOblique, DMat3::IDENTITY);
        let expected = DVec3::new(-1.0, 0.0, 1.0).normalize() * camera.distance;
        assert_close(camera.eye(), camera.target + expected, 1e-9);
    }

    #[test]
    fn views_follow_the_body_frame() {
        let body = tilted_body();
        let mut camera = camera();
        for view in StandardView::ALL {
            camera.set_view(view, body);
            let (sin_a, cos_a) = view.azimuth().sin_cos();
            let expected = body * DVec3::new(sin_a, 0.0, cos_a);
            assert_close(camera.backward(), expected, 1e-12);
            assert_close(camera.up(), body.y_axis, 1e-12);
            // The basis stays orthonormal and right-handed.
            assert!(camera.right().dot(camera.up()).abs() < 1e-12);
            assert_close(camera.right().cross(camera.up()), camera.backward(), 1e-12);
        }
    }

    #[test]
    fn a_pixel_ray_passes_through_the_point_seen_there() {
        let mut camera = camera();
        camera.body = tilted_body();
        camera.azimuth = 0.4;
        camera.elevation = -0.3;
        let centre_ray = camera.ray(SIZE / 2.0, SIZE);
        let forward = -camera.backward();
        assert_close(centre_ray.direction, forward, 1e-9);
        assert_close(
            centre_ray.origin,
            camera.eye() + NEAR_FRACTION * camera.distance * forward,
            1e-6,
        );
        for point in [
            DVec3::new(60.0, -100.0, 20.0),
            DVec3::new(-80.0, -230.0, 90.0),
            camera.target,
        ] {
            let pixel = camera.project(point, SIZE).unwrap();
            let ray = camera.ray(pixel, SIZE);
            let along = (point - ray.origin).dot(ray.direction);
            assert!(along > 0.0);
            assert_close(ray.origin + along * ray.direction, point, 1e-6);
            // The ray's line passes through the eye.
            let back = (camera.eye() - ray.origin).normalize();
            assert_close(back, -ray.direction, 1e-9);
        }
        assert!(
            camera
                .project(camera.eye() + 10.0 * camera.backward(), SIZE)
                .is_none()
        );
    }

    #[test]
    fn orbiting_a_quarter_turn_is_the_side_view() {
        let mut camera = camera();
        camera.orbit(DVec2::new(
            -std::f64::consts::FRAC_PI_2 / ORBIT_PER_PIXEL,
            0.0,
        ));
        let mut left = camera;
        left.set_view(StandardView::Left, DMat3::IDENTITY);
        assert_close(camera.eye(), left.eye(), 1e-9);
        // Dragging down lifts the eye; the elevation stops short of the pole.
        camera.orbit(DVec2::new(0.0, 10.0));
        assert!(camera.eye().y > camera.target.y);
        camera.orbit(DVec2::new(0.0, 1e6));
        assert_eq!(camera.elevation, MAX_ELEVATION);
        assert!(camera.up().y > 0.0);
    }

    #[test]
    fn panning_moves_the_target_depth_with_the_mouse_and_zoom_scales_the_distance() {
        let mut camera = camera();
        camera.body = tilted_body();
        camera.azimuth = -0.7;
        let point = camera.target + 5.0 * camera.right();
        let before = camera.project(point, SIZE).unwrap();
        let delta = DVec2::new(37.0, -12.0);
        camera.pan(delta, SIZE.y);
        let after = camera.project(point, SIZE).unwrap();
        assert_close((after - before).extend(0.0), delta.extend(0.0), 1e-6);

        let distance = camera.distance;
        camera.zoom(0.5);
        assert!((camera.distance - 0.5 * distance).abs() < 1e-9);
        camera.zoom(f64::NAN);
        camera.zoom(-2.0);
        assert!((camera.distance - 0.5 * distance).abs() < 1e-9);
        camera.zoom(1e-9);
        assert_eq!(camera.distance, MIN_DISTANCE_MM);
    }
}
