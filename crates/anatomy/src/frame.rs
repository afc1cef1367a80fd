//! The standing frame (GUIDE section 4): `y` up against gravity, `x` to the patient's
//! left (Pcr towards Pcl, made horizontal), `z` anterior and horizontal = x × y, origin
//! at Pj. Up comes from the scan ([`Up`]); the sternum (Px towards Pj), which leans back
//! 20-30° in a standing woman, is kept as an anatomical direction, never as up.

use crate::landmarks::{LandmarkName, Landmarks, PartialLandmarks};
use glam::{DMat3, DQuat, DVec3};

/// The sternum's usual lean back from the vertical in a standing woman (degrees), used
/// to estimate up when the file's vertical is not: 25.7-27.0° on all fifteen
/// body-model scans in `../shared/scans` (the GUIDE gives 20-30°).
pub const TYPICAL_STERNUM_LEAN_DEG: f64 = 26.0;

/// The largest lean of the sternum from the file's +y (degrees) for which the file is
/// taken to be upright; beyond it up is estimated from the sternum.
pub const MAX_UPRIGHT_STERNUM_LEAN_DEG: f64 = 45.0;

/// The largest tilt of the line between the clavicle points from the file's horizontal
/// plane (degrees) for which the file is taken to be upright: a standing patient's
/// shoulders are near level, a scan lying on its side has them vertical.
pub const MAX_UPRIGHT_SHOULDER_TILT_DEG: f64 = 30.0;

/// Which way is up, against gravity, in a scan's file coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Up {
    /// Unit vector, file frame.
    pub direction: DVec3,
    pub source: UpSource,
}

/// Where [`Up`] came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UpSource {
    /// The file's +y: the file is upright, as clinical 3D cameras export scans.
    FileVertical,
    /// The user said it (`--up`, a planning case).
    Given,
    /// The file's +y is implausible for a standing patient; up is estimated from the
    /// sternum and the clavicles.
    Estimated,
}

impl Up {
    /// The file's +y.
    pub const FILE_VERTICAL: Up = Up {
        direction: DVec3::Y,
        source: UpSource::FileVertical,
    };

    /// Up as the user gives it: an axis (`+y`, `-z`, `x`) or a vector `x,y,z` (any
    /// length but zero).
    pub fn parse(text: &str) -> Result<Up, FrameError> {
        let bad = || FrameError::BadUp(text.to_string());
        let trimmed = text.trim();
        let direction = match trimmed.split(',').collect::<Vec<_>>().as_slice() {
            [axis] => {
                let (sign, name) = match axis.strip_prefix('-') {
                    Some(rest) => (-1.0, rest),
                    None => (1.0, axis.strip_prefix('+').unwrap_or(axis)),
                };
                sign * match name.to_ascii_lowercase().as_str() {
                    "x" => DVec3::X,
                    "y" => DVec3::Y,
                    "z" => DVec3::Z,
                    _ => return Err(bad()),
                }
            }
            [x, y, z] => {
                let number = |s: &str| s.trim().parse::<f64>().map_err(|_| bad());
                DVec3::new(number(x)?, number(y)?, number(z)?)
            }
            _ => return Err(bad()),
        };
        let direction = direction
            .is_finite()
            .then(|| direction.try_normalize())
            .flatten()
            .ok_or_else(bad)?;
        Ok(Up {
            direction,
            source: UpSource::Given,
        })
    }

    /// Up for a scan with these landmarks: `given` if there is one, else the file's +y
    /// if the patient stands upright in it (the sternum leans at most
    /// [`MAX_UPRIGHT_STERNUM_LEAN_DEG`] from it and the shoulders are within
    /// [`MAX_UPRIGHT_SHOULDER_TILT_DEG`] of level), else an estimate: the sternum turned
    /// forward by [`TYPICAL_STERNUM_LEAN_DEG`] about the left axis.
    pub fn resolve(given: Option<Up>, landmarks: &Landmarks) -> Result<Up, FrameError> {
        if let Some(given) = given {
            return Ok(given);
        }
        let anatomy = SternalAxes::from_landmarks(landmarks)?;
        let lean = anatomy.sternum.angle_between(DVec3::Y).to_degrees();
        let shoulder_tilt = anatomy.left.dot(DVec3::Y).abs().asin().to_degrees();
        if lean <= MAX_UPRIGHT_STERNUM_LEAN_DEG && shoulder_tilt <= MAX_UPRIGHT_SHOULDER_TILT_DEG {
            return Ok(Up::FILE_VERTICAL);
        }
        let forward = anatomy.left.cross(anatomy.sternum);
        let typical = TYPICAL_STERNUM_LEAN_DEG.to_radians();
        Ok(Up {
            direction: anatomy.sternum * typical.cos() + forward * typical.sin(),
            source: UpSource::Estimated,
        })
    }

    /// The angle between this up and the file's +y (degrees).
    pub fn tilt_from_file_vertical_deg(&self) -> f64 {
        self.direction.angle_between(DVec3::Y).to_degrees()
    }

    /// What the user should know about an estimated up, or `None`.
    pub fn warning(&self) -> Option<String> {
        (self.source == UpSource::Estimated).then(|| {
            format!(
                "the scan's +y axis is not the patient's vertical (she does not stand upright in the file); up is estimated from the sternum as ({:.3}, {:.3}, {:.3}), {:.0}° from +y: give --up (an axis such as +z, or x,y,z) if you know it",
                self.direction.x,
                self.direction.y,
                self.direction.z,
                self.tilt_from_file_vertical_deg()
            )
        })
    }

    /// The same up after the scan is moved by `rotation` (a registration, a test's turn);
    /// an estimate stays an estimate.
    pub fn rotated(&self, rotation: DQuat) -> Up {
        Up {
            direction: rotation * self.direction,
            source: self.source,
        }
    }

    /// The direction as a string [`Up::parse`] reads back.
    pub fn to_arg(&self) -> String {
        let d = self.direction;
        format!("{},{},{}", d.x, d.y, d.z)
    }
}

/// The sternum and the line between the clavicle points, as unit vectors.
struct SternalAxes {
    /// Px towards Pj.
    sternum: DVec3,
    /// Pcr towards Pcl, orthogonal to the sternum.
    left: DVec3,
}

impl SternalAxes {
    fn from_landmarks(landmarks: &Landmarks) -> Result<SternalAxes, FrameError> {
        let sternum = landmarks.get(LandmarkName::Pj) - landmarks.get(LandmarkName::Px);
        // NaN (coordinates overflowing) fails too.
        if sternum.length().is_nan() || sternum.length() < 1.0 {
            return Err(FrameError::NoVerticalAxis(sternum.length()));
        }
        let sternum = sternum.normalize();
        let left = horizontal_left(landmarks, sternum)?;
        Ok(SternalAxes { sternum, left })
    }
}

/// Pcr towards Pcl, made orthogonal to `up` (unit).
fn horizontal_left(landmarks: &Landmarks, up: DVec3) -> Result<DVec3, FrameError> {
    let across = landmarks.get(LandmarkName::Pcl) - landmarks.get(LandmarkName::Pcr);
    let lateral = across - up * across.dot(up);
    let enough = 0.1 * across.length().max(1.0);
    if lateral.length().is_nan() || lateral.length() < enough {
        return Err(FrameError::NoLateralAxis);
    }
    Ok(lateral.normalize())
}

/// An orthonormal, right-handed standing frame at the sternal notch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnatomicalFrame {
    /// The sternal notch Pj (mm, file frame).
    pub origin: DVec3,
    /// Columns: the x (left), y (up) and z (anterior) axes in file coordinates.
    pub axes: DMat3,
    /// The body's own axes (columns: left, the sternum Px towards Pj, and their cross
    /// product), unit, file frame: anatomical directions, not up.
    pub sternal_axes: DMat3,
    /// Where up came from.
    pub up_source: UpSource,
}

/// The landmarks do not span a frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameError {
    #[error("Pj and Px coincide ({0:.2} mm apart): cannot tell where the sternum runs")]
    NoVerticalAxis(f64),
    #[error(
        "the line from Pcr to Pcl is (nearly) parallel to the vertical: cannot tell left from right"
    )]
    NoLateralAxis,
    #[error(
        "up \"{0}\" is not an axis (+x, -y, z, ...) or a non-zero vector x,y,z: say which way is up in the scan's file"
    )]
    BadUp(String),
}

/// Landmarks whose side disagrees with the frame: a mistake that would otherwise measure
/// distances across the chest or swap the breasts' volumes.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SideError {
    #[error(
        "the nipples lie {behind_mm:.0} mm behind the sternal notch as seen from the left \
         direction Pcr -> Pcl: left and right landmarks are swapped, or the scan is mirrored \
         (check that Pcl, Pnl and the PSMF..l points are on the patient's left, and that the \
         scan was not flipped on export)"
    )]
    SwappedOrMirrored { behind_mm: f64 },
    #[error(
        "landmark {name} lies {across_mm:.0} mm on the patient's {wrong} of the sternal notch, \
         but its name says {named}: its side is swapped (or Pcl and Pcr are); move it or fix \
         its name"
    )]
    WrongSide {
        name: &'static str,
        across_mm: f64,
        wrong: &'static str,
        named: &'static str,
    },
}

/// The landmarks named for the patient's left and right.
const LEFT_LANDMARKS: [LandmarkName; 5] = [
    LandmarkName::Pcl,
    LandmarkName::Pnl,
    LandmarkName::PSMFl,
    LandmarkName::PSMFml,
    LandmarkName::PSMFll,
];
const RIGHT_LANDMARKS: [LandmarkName; 5] = [
    LandmarkName::Pcr,
    LandmarkName::Pnr,
    LandmarkName::PSMFr,
    LandmarkName::PSMFmr,
    LandmarkName::PSMFlr,
];

impl AnatomicalFrame {
    /// Checks that `landmarks` (those this frame was built from) agree with it: both
    /// nipples in front of the sternal notch, and every landmark named for a side on that
    /// side of it. A full left/right swap or a mirrored scan turns the frame round (its
    /// left comes from Pcr -> Pcl, its anterior from left x up), so the nipples appear
    /// behind; a single swapped landmark lies on the other side.
    pub fn check_sides(&self, landmarks: &Landmarks) -> Result<(), SideError> {
        let local = |name: LandmarkName| self.to_local(landmarks.get(name));
        let front_mm = local(LandmarkName::Pnl).z.max(local(LandmarkName::Pnr).z);
        if front_mm <= 0.0 {
            return Err(SideError::SwappedOrMirrored {
                behind_mm: -front_mm,
            });
        }
        for (names, sign, named, wrong) in [
            (LEFT_LANDMARKS, 1.0, "left", "right"),
            (RIGHT_LANDMARKS, -1.0, "right", "left"),
        ] {
            for name in names {
                let across_mm = local(name).x * sign;
                if across_mm < 0.0 {
                    return Err(SideError::WrongSide {
                        name: name.as_str(),
                        across_mm: -across_mm,
                        wrong,
                        named,
                    });
                }
            }
        }
        Ok(())
    }

    /// The standing frame from Pj, Px, Pcl and Pcr and which way is up.
    pub fn from_landmarks(landmarks: &Landmarks, up: Up) -> Result<AnatomicalFrame, FrameError> {
        let sternal = SternalAxes::from_landmarks(landmarks)?;
        let y = up.direction;
        let x = horizontal_left(landmarks, y)?;
        Ok(AnatomicalFrame {
            origin: landmarks.get(LandmarkName::Pj),
            axes: DMat3::from_cols(x, y, x.cross(y)),
            sternal_axes: DMat3::from_cols(
                sternal.left,
                sternal.sternum,
                sternal.left.cross(sternal.sternum),
            ),
            up_source: up.source,
        })
    }

    /// The frame of the body's own axes ([`AnatomicalFrame::sternal_axes`]: `y` along
    /// the sternum) at the same origin: what the breast model and the chest's shape are
    /// built in, so that they follow the thorax whichever way the patient stood.
    pub fn sternal(&self) -> AnatomicalFrame {
        AnatomicalFrame {
            axes: self.sternal_axes,
            ..*self
        }
    }

    /// Px towards Pj (unit, file frame).
    pub fn sternum(&self) -> DVec3 {
        self.sternal_axes.y_axis
    }

    /// The patient's left direction (file frame).
    pub fn left(&self) -> DVec3 {
        self.axes.x_axis
    }

    /// The up direction, against gravity (file frame).
    pub fn up(&self) -> DVec3 {
        self.axes.y_axis
    }

    /// The anterior direction, horizontal, the normal of the coronal plane (file frame).
    pub fn anterior(&self) -> DVec3 {
        self.axes.z_axis
    }

    /// How far the sternum leans back from the vertical (degrees; negative if forward).
    pub fn sternum_lean_deg(&self) -> f64 {
        let sternum = self.sternum();
        let in_sagittal = sternum - self.left() * sternum.dot(self.left());
        (-in_sagittal.dot(self.anterior()))
            .atan2(in_sagittal.dot(self.up()))
            .to_degrees()
    }

    /// File coordinates to frame coordinates (mm, relative to Pj).
    pub fn to_local(&self, p: DVec3) -> DVec3 {
        self.axes.transpose() * (p - self.origin)
    }

    /// Frame coordinates to file coordinates.
    pub fn to_file(&self, local: DVec3) -> DVec3 {
        self.origin + self.axes * local
    }
}

impl PartialLandmarks {
    /// The standing frame once Pj, Px, Pcl and Pcr are placed, with up `given` or
    /// resolved as [`Up::resolve`] does.
    pub fn frame(&self, given: Option<Up>) -> Option<Result<AnatomicalFrame, FrameError>> {
        use LandmarkName::{Pcl, Pcr, Pj, Px};
        let bony = [Pj, Px, Pcl, Pcr];
        if bony.iter().any(|&n| self.get(n).is_none()) {
            return None;
        }
        let landmarks = Landmarks::new(|n| self.get(n).unwrap_or_default());
        Some(
            Up::resolve(given, &landmarks)
                .and_then(|up| AnatomicalFrame::from_landmarks(&landmarks, up)),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A standing patient in an upright file, the sternum leaning back atan(60/150).
    fn upright_landmarks() -> Landmarks {
        Landmarks::new(|name| match name {
            LandmarkName::Pj => DVec3::new(0.0, 0.0, 0.0),
            LandmarkName::Px => DVec3::new(0.0, -150.0, 60.0),
            LandmarkName::Pcl => DVec3::new(85.0, -20.0, 0.0),
            LandmarkName::Pcr => DVec3::new(-85.0, -20.0, 2.0),
            _ => DVec3::new(0.0, -100.0, 100.0),
        })
    }

    fn turned(landmarks: &Landmarks, rotation: DQuat) -> Landmarks {
        let mut moved = landmarks.clone();
        moved.map_positions(|p| rotation * p);
        moved
    }

    #[test]
    fn frame_is_orthonormal_right_handed_and_follows_a_rigid_motion() {
        let landmarks = upright_landmarks();
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let axes = frame.axes;
        assert!((axes.transpose() * axes - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!((axes.determinant() - 1.0).abs() < 1e-12);
        assert_eq!(frame.up(), DVec3::Y);
        // Left made horizontal, anterior horizontal.
        assert!(frame.left().y.abs() < 1e-15 && frame.anterior().y.abs() < 1e-15);
        assert!(frame.left().x > 0.99 && frame.anterior().z > 0.99);
        // With the clavicle points level front to back, the sternum lies in the
        // sagittal plane and leans atan(60/150) back.
        let mut level = landmarks.clone();
        level.set(LandmarkName::Pcr, DVec3::new(-85.0, -20.0, 0.0));
        let lean = (60.0f64 / 150.0).atan().to_degrees();
        let level_frame = AnatomicalFrame::from_landmarks(&level, Up::FILE_VERTICAL).unwrap();
        assert!((level_frame.sternum_lean_deg() - lean).abs() < 1e-9);
        // The sternal frame: y along Px to Pj, x from Pcr to Pcl orthogonal to it.
        let sternal = frame.sternal().axes;
        assert!(
            sternal
                .y_axis
                .distance(DVec3::new(0.0, 150.0, -60.0).normalize())
                < 1e-12
        );
        assert!(sternal.x_axis.dot(sternal.y_axis).abs() < 1e-12 && sternal.x_axis.x > 0.99);
        assert!((sternal.determinant() - 1.0).abs() < 1e-12);

        // Move the scan and its up rigidly: local coordinates do not change.
        let rotation = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 1.1);
        let shift = DVec3::new(10.0, -4.0, 7.0);
        let mut moved = landmarks.clone();
        moved.map_positions(|p| rotation * p + shift);
        let moved_up = Up::FILE_VERTICAL.rotated(rotation);
        let moved_frame = AnatomicalFrame::from_landmarks(&moved, moved_up).unwrap();
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

    /// A torso's landmarks with each on its own side (mm; x to the patient's left).
    fn sided_landmarks() -> Landmarks {
        Landmarks::new(|name| {
            let (x, y, z) = match name {
                LandmarkName::Pj => (0.0, 0.0, 0.0),
                LandmarkName::Px => (0.0, -150.0, 60.0),
                LandmarkName::Pcl => (85.0, -20.0, 0.0),
                LandmarkName::Pnl => (100.0, -180.0, 110.0),
                LandmarkName::PSMFl => (90.0, -240.0, 80.0),
                LandmarkName::PSMFml => (40.0, -220.0, 90.0),
                LandmarkName::PSMFll => (130.0, -210.0, 40.0),
                LandmarkName::Pcr => (-85.0, -20.0, 0.0),
                LandmarkName::Pnr => (-100.0, -180.0, 110.0),
                LandmarkName::PSMFr => (-90.0, -240.0, 80.0),
                LandmarkName::PSMFmr => (-40.0, -220.0, 90.0),
                LandmarkName::PSMFlr => (-130.0, -210.0, 40.0),
            };
            DVec3::new(x, y, z)
        })
    }

    fn sides_of(landmarks: &Landmarks) -> Result<(), SideError> {
        AnatomicalFrame::from_landmarks(landmarks, Up::FILE_VERTICAL)
            .unwrap()
            .check_sides(landmarks)
    }

    /// Right as marked; the nipples' names swapped: Pnl named on the right, 100 mm from
    /// the notch; every name swapped, or the scan and its marks mirrored: the frame turns
    /// round and the nipples lie 110 mm behind.
    #[test]
    fn swapped_sides_and_mirrored_scans_are_caught() {
        let landmarks = sided_landmarks();
        assert_eq!(sides_of(&landmarks), Ok(()));

        let mut nipples = landmarks.clone();
        nipples.set(LandmarkName::Pnl, landmarks.get(LandmarkName::Pnr));
        nipples.set(LandmarkName::Pnr, landmarks.get(LandmarkName::Pnl));
        match sides_of(&nipples) {
            Err(SideError::WrongSide {
                name, across_mm, ..
            }) => assert!(name == "Pnl" && (across_mm - 100.0).abs() < 1e-9),
            other => panic!("{other:?}"),
        }

        let mut swapped = landmarks.clone();
        for (left, right) in LEFT_LANDMARKS.iter().zip(&RIGHT_LANDMARKS) {
            swapped.set(*left, landmarks.get(*right));
            swapped.set(*right, landmarks.get(*left));
        }
        let mut mirrored = landmarks.clone();
        mirrored.map_positions(|p| DVec3::new(-p.x, p.y, p.z));
        for wrong in [swapped, mirrored] {
            match sides_of(&wrong) {
                Err(SideError::SwappedOrMirrored { behind_mm }) => {
                    assert!((behind_mm - 110.0).abs() < 1e-9, "{behind_mm}")
                }
                other => panic!("{other:?}"),
            }
        }
    }

    #[test]
    fn an_upright_file_keeps_its_vertical_exactly() {
        let up = Up::resolve(None, &upright_landmarks()).unwrap();
        assert_eq!(up, Up::FILE_VERTICAL);
        assert!(up.warning().is_none());
    }

    #[test]
    fn a_given_up_restores_a_turned_scan_exactly() {
        // Turned by 10° about the left axis: still plausible as upright (the sternum
        // leans 32° from +y), so only --up can tell; given, the frame is the turned one.
        let landmarks = upright_landmarks();
        let frame = AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL).unwrap();
        let rotation = DQuat::from_rotation_x(10f64.to_radians());
        let given = Up::parse(&Up::FILE_VERTICAL.rotated(rotation).to_arg()).unwrap();
        assert_eq!(given.source, UpSource::Given);
        let up = Up::resolve(Some(given), &turned(&landmarks, rotation)).unwrap();
        let turned_frame =
            AnatomicalFrame::from_landmarks(&turned(&landmarks, rotation), up).unwrap();
        let expected = DMat3::from_quat(rotation) * frame.axes;
        assert!(turned_frame.axes.abs_diff_eq(expected, 1e-12));
    }

    #[test]
    fn a_lying_scan_gets_an_estimate_and_a_warning() {
        // The sternum leaning the typical amount, the file turned 90° (lying on her
        // back) and 70° about the other axes: the estimate is exact up to the lean's
        // deviation from the typical one.
        let lean = TYPICAL_STERNUM_LEAN_DEG.to_radians();
        let standing = Landmarks::new(|name| match name {
            LandmarkName::Pj => DVec3::ZERO,
            LandmarkName::Px => DVec3::new(0.0, -lean.cos(), lean.sin()) * 160.0,
            LandmarkName::Pcl => DVec3::new(85.0, -10.0, -5.0),
            LandmarkName::Pcr => DVec3::new(-85.0, -10.0, -5.0),
            _ => DVec3::new(0.0, -100.0, 100.0),
        });
        for rotation in [
            DQuat::from_rotation_x(-90f64.to_radians()),
            DQuat::from_rotation_z(70f64.to_radians()),
            DQuat::from_axis_angle(DVec3::new(1.0, 1.0, 0.0).normalize(), 2.0),
        ] {
            let up = Up::resolve(None, &turned(&standing, rotation)).unwrap();
            assert_eq!(up.source, UpSource::Estimated);
            assert!(up.direction.angle_between(rotation * DVec3::Y) < 1e-9);
            let warning = up.warning().unwrap();
            assert!(warning.contains("--up"), "{warning}");
        }
    }

    #[test]
    fn up_is_parsed_from_axes_and_vectors() {
        assert_eq!(Up::parse("+y").unwrap().direction, DVec3::Y);
        assert_eq!(Up::parse("-Z").unwrap().direction, DVec3::NEG_Z);
        assert_eq!(Up::parse("x").unwrap().direction, DVec3::X);
        let vector = Up::parse("0, 3, 4").unwrap().direction;
        assert!(vector.distance(DVec3::new(0.0, 0.6, 0.8)) < 1e-15);
        for bad in ["up", "", "0,0,0", "nan,1,0", "1,2", "+w", "1,2,3,4"] {
            assert_eq!(Up::parse(bad), Err(FrameError::BadUp(bad.to_string())));
        }
    }

    #[test]
    fn degenerate_landmarks_are_rejected() {
        let mut landmarks = upright_landmarks();
        landmarks.set(LandmarkName::Px, DVec3::ZERO);
        assert!(matches!(
            AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL),
            Err(FrameError::NoVerticalAxis(_))
        ));
        let mut landmarks = upright_landmarks();
        landmarks.set(LandmarkName::Pcl, DVec3::new(0.0, 100.0, 0.0));
        landmarks.set(LandmarkName::Pcr, DVec3::new(0.0, -100.0, 0.0));
        assert_eq!(
            AnatomicalFrame::from_landmarks(&landmarks, Up::FILE_VERTICAL),
            Err(FrameError::NoLateralAxis)
        );
    }
}
