//! The anatomical frame (GUIDE section 4): `y` up (Px towards Pj), `x` to the patient's
//! left (Pcr towards Pcl, orthogonalised), `z` anterior = x × y, origin at Pj.

use crate::landmarks::{LandmarkName, Landmarks};
use glam::{DMat3, DVec3};

/// An orthonormal, right-handed frame derived from the bony landmarks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnatomicalFrame {
    /// The sternal notch Pj (mm, file frame).
    pub origin: DVec3,
    /// Columns: the x (left), y (up) and z (anterior) axes in file coordinates.
    pub axes: DMat3,
}

/// The landmarks do not span a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    #[error("Pj and Px coincide ({0:.2} mm apart): cannot tell which way is up")]
    NoVerticalAxis(f64),
    #[error(
        "the line from Pcr to Pcl is (nearly) parallel to the line from Px to Pj: cannot tell left from right"
    )]
    NoLateralAxis,
}

impl AnatomicalFrame {
    /// The frame from Pj, Px, Pcl and Pcr.
    pub fn from_landmarks(landmarks: &Landmarks) -> Result<AnatomicalFrame, FrameError> {
        AnatomicalFrame::from_points(
            landmarks.get(LandmarkName::Pj),
            landmarks.get(LandmarkName::Px),
            landmarks.get(LandmarkName::Pcl),
            landmarks.get(LandmarkName::Pcr),
        )
    }

    /// The frame from the sternal notch, the xiphoid and the left and right clavicle
    /// points (mm, file frame).
    pub fn from_points(
        pj: DVec3,
        px: DVec3,
        pcl: DVec3,
        pcr: DVec3,
    ) -> Result<AnatomicalFrame, FrameError> {
        let up = pj - px;
        if up.length() < 1.0 {
            return Err(FrameError::NoVerticalAxis(up.length()));
        }
        let y = up.normalize();
        let across = pcl - pcr;
        let lateral = across - y * across.dot(y);
        if lateral.length() < 0.1 * across.length().max(1.0) {
            return Err(FrameError::NoLateralAxis);
        }
        let x = lateral.normalize();
        let z = x.cross(y);
        Ok(AnatomicalFrame {
            origin: pj,
            axes: DMat3::from_cols(x, y, z),
        })
    }

    /// The patient's left direction (file frame).
    pub fn left(&self) -> DVec3 {
        self.axes.x_axis
    }

    /// The up direction (file frame).
    pub fn up(&self) -> DVec3 {
        self.axes.y_axis
    }

    /// The anterior direction, the normal of the coronal plane (file frame).
    pub fn anterior(&self) -> DVec3 {
        self.axes.z_axis
    }

    /// File coordinates to frame coordinates (mm, relative to Pj).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.axes.transpose() * (p - self.origin)
    }

    /// Frame coordinates to file coordinates.
    pub fn to_file(&self, local: DVec3) -> DVec3 {
        self.origin + self.axes * local
    }

    /// Axes for pictures: the frame's axes turned about its left axis until up follows
    /// the long axis of `points` (mm, file frame; a torso scan's vertices), so the torso
    /// stands upright. The frame's own up, Px towards Pj, leans back with the sternum
    /// (about 20-25° on the shared scans), which tilts side views. Columns: left, up,
    /// anterior. The long axis is the direction of largest spread of the points in the
    /// sagittal plane; the frame's axes are kept when the points spread more from front
    /// to back than from top to bottom.
    pub fn upright_axes(&self, points: &[DVec3]) -> DMat3 {
        let local: Vec<(f64, f64)> = points
            .iter()
            .map(|&p| {
                let l = self.to_local(p);
                (l.y, l.z)
            })
            .filter(|(y, z)| y.is_finite() && z.is_finite())
            .collect();
        if local.len() < 2 {
            return self.axes;
        }
        let (sum_y, sum_z) = local
            .iter()
            .fold((0.0, 0.0), |(a, b), &(y, z)| (a + y, b + z));
        let count = local.len() as f64;
        let (mean_y, mean_z) = (sum_y / count, sum_z / count);
        let (mut yy, mut yz, mut zz) = (0.0, 0.0, 0.0);
        for &(y, z) in &local {
            let (dy, dz) = (y - mean_y, z - mean_z);
            yy += dy * dy;
            yz += dy * dz;
            zz += dz * dz;
        }
        if yy <= zz {
            // No spread, or deeper than tall: not a standing torso, keep the frame.
            return self.axes;
        }
        // The principal direction of the 2x2 covariance, at angle `tilt` from up towards
        // anterior; with more spread along up than along anterior, under 45°.
        let tilt = 0.5 * (2.0 * yz).atan2(yy - zz);
        let up = self.up() * tilt.cos() + self.anterior() * tilt.sin();
        DMat3::from_cols(self.left(), up, self.left().cross(up))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DQuat;

    fn upright_landmarks() -> Landmarks {
        Landmarks::new(|name| match name {
            LandmarkName::Pj => DVec3::new(0.0, 0.0, 0.0),
            LandmarkName::Px => DVec3::new(0.0, -150.0, 60.0),
            LandmarkName::Pcl => DVec3::new(85.0, -20.0, 0.0),
            LandmarkName::Pcr => DVec3::new(-85.0, -20.0, 2.0),
            _ => DVec3::new(0.0, -100.0, 100.0),
        })
    }

    #[test]
    fn frame_is_orthonormal_right_handed_and_follows_a_rigid_motion() {
        let landmarks = upright_landmarks();
        let frame = AnatomicalFrame::from_landmarks(&landmarks).unwrap();
        let axes = frame.axes;
        assert!((axes.transpose() * axes - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!((axes.determinant() - 1.0).abs() < 1e-12);
        assert!(frame.left().x > 0.9 && frame.up().y > 0.9 && frame.anterior().z > 0.9);

        // Move the scan rigidly: the frame moves with it, local coordinates do not change.
        let rotation = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.1);
        let shift = DVec3::new(10.0, -4.0, 7.0);
        let mut moved = landmarks.clone();
        moved.map_positions(|p| rotation * p + shift);
        let moved_frame = AnatomicalFrame::from_landmarks(&moved).unwrap();
        let nipple = landmarks.get(LandmarkName::Pnl);
        let local = frame.to_local(nipple);
        assert!(
            moved_frame
                .to_local(rotation * nipple + shift)
                .distance(local)
                < 1e-9
        );
        assert!(frame.to_file(local).distance(nipple) < 1e-12);
    }

    #[test]
    fn upright_axes_follow_the_long_axis_of_a_leaning_body() {
        // Points along a line 400 mm long leaning 20° forward from the frame's up, spread
        // 50 mm across it (left-right spread does not matter).
        let frame = AnatomicalFrame::from_landmarks(&upright_landmarks()).unwrap();
        let lean = 20f64.to_radians();
        let long = frame.up() * lean.cos() + frame.anterior() * lean.sin();
        let across = frame.left().cross(long);
        let points: Vec<DVec3> = (0..=40)
            .flat_map(|i| {
                let along = frame.origin + long * (10.0 * i as f64 - 300.0);
                [-25.0, 25.0].map(|d| along + across * d + frame.left() * (i % 7) as f64 * 30.0)
            })
            .collect();
        let axes = frame.upright_axes(&points);
        assert!(axes.y_axis.distance(long) < 1e-9, "{}", axes.y_axis);
        assert!(axes.x_axis.distance(frame.left()) < 1e-12);
        assert!((axes.transpose() * axes - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!((axes.determinant() - 1.0).abs() < 1e-12);
        // Without points the frame's own axes.
        assert_eq!(frame.upright_axes(&[]), frame.axes);
    }

    #[test]
    fn degenerate_landmarks_are_rejected() {
        let mut landmarks = upright_landmarks();
        landmarks.set(LandmarkName::Px, DVec3::ZERO);
        assert!(matches!(
            AnatomicalFrame::from_landmarks(&landmarks),
            Err(FrameError::NoVerticalAxis(_))
        ));
        let mut landmarks = upright_landmarks();
        landmarks.set(LandmarkName::Px, DVec3::new(0.0, -150.0, 0.0));
        landmarks.set(LandmarkName::Pcl, DVec3::new(0.0, 100.0, 0.0));
        landmarks.set(LandmarkName::Pcr, DVec3::new(0.0, -100.0, 0.0));
        assert_eq!(
            AnatomicalFrame::from_landmarks(&landmarks),
            Err(FrameError::NoLateralAxis)
        );
    }
}
