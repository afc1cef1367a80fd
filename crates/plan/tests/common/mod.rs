//! The phantom as a marked scan, shared by the tests.

use anatomy::register::RigidTransform;
use plan::{MarkedScan, PhantomParams, Scan, Silent, Up, UpSource};
use std::path::Path;

/// A phantom scan and its landmarks, optionally moved (its up, the file's +y, moved
/// along: the patient stands as before).
pub fn marked_phantom(params: &PhantomParams, motion: Option<&RigidTransform>) -> MarkedScan {
    let mut phantom = phantom::generate(params);
    if let Some(motion) = motion {
        phantom.scan.map_positions(|p| motion.apply(p));
        phantom.landmarks.map_positions(|p| motion.apply(p));
    }
    let scan = Scan::from_mesh(phantom.scan, Path::new("phantom.ply")).unwrap();
    MarkedScan::new(
        scan,
        phantom.landmarks,
        Path::new("phantom.json"),
        motion.map(|motion| Up {
            direction: motion.rotation * Up::FILE_VERTICAL.direction,
            source: UpSource::Given,
        }),
        &Silent,
    )
    .unwrap()
}

/// Rotation error (degrees) and worst displacement error over the fixed scan (mm).
pub fn registration_errors(
    found: &RigidTransform,
    truth: &RigidTransform,
    fixed: &MarkedScan,
) -> (f64, f64) {
    let error = found.after(&truth.inverse());
    let worst = fixed
        .scan
        .mesh
        .positions
        .iter()
        .map(|&p| error.apply(p).distance(p))
        .fold(0.0, f64::max);
    (error.rotation_angle_deg(), worst)
}
