//! Rigid registration of two scans of the same patient (paper IV-A, Fig. 3): first on the
//! bony landmarks Pcl, Pcr, Pj, Px (optimal least-squares rotation, Kabsch/Umeyama without
//! scale, in place of the paper's PCA), then optionally refined by point-to-plane ICP on
//! the surface away from the breasts, which change between scans.

use crate::landmarks::{LandmarkName, Landmarks};
use faer::Mat;
use faer::linalg::solvers::Solve;
use glam::{DMat3, DQuat, DVec3};
use mesh::{SurfaceIndex, Topology, TriMesh};
use rayon::prelude::*;

/// The landmarks close to bone, which surgery does not move.
pub const BONY_LANDMARKS: [LandmarkName; 4] = [
    LandmarkName::Pcl,
    LandmarkName::Pcr,
    LandmarkName::Pj,
    LandmarkName::Px,
];

/// A rotation followed by a translation: `p -> rotation * p + translation` (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RigidTransform {
    pub rotation: DMat3,
    pub translation: DVec3,
}

impl RigidTransform {
    pub const IDENTITY: RigidTransform = RigidTransform {
        rotation: DMat3::IDENTITY,
        translation: DVec3::ZERO,
    };

    /// Applies the transform to a point.
    #[inline]
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.rotation * p + self.translation
    }

    /// `self` after `first`: `p -> self(first(p))`.
    pub fn after(&self, first: &RigidTransform) -> RigidTransform {
        RigidTransform {
            rotation: self.rotation * first.rotation,
            translation: self.rotation * first.translation + self.translation,
        }
    }

    /// The inverse transform.
    pub fn inverse(&self) -> RigidTransform {
        let rotation = self.rotation.transpose();
        RigidTransform {
            rotation,
            translation: -(rotation * self.translation),
        }
    }

    /// The homogeneous 4x4 matrix, row-major.
    pub fn to_row_major(&self) -> [[f64; 4]; 4] {
        let r = self.rotation;
        let t = self.translation;
        [
            [r.x_axis.x, r.y_axis.x, r.z_axis.x, t.x],
            [r.x_axis.y, r.y_axis.y, r.z_axis.y, t.y],
            [r.x_axis.z, r.y_axis.z, r.z_axis.z, t.z],
            [0.0, 0.0, 0.0, 1.0],
        ]
    }

    /// Reads a homogeneous row-major 4x4 matrix (the last row is ignored).
    pub fn from_row_major(m: &[[f64; 4]; 4]) -> RigidTransform {
        RigidTransform {
            rotation: DMat3::from_cols(
                DVec3::new(m[0][0], m[1][0], m[2][0]),
                DVec3::new(m[0][1], m[1][1], m[2][1]),
                DVec3::new(m[0][2], m[1][2], m[2][2]),
            ),
            translation: DVec3::new(m[0][3], m[1][3], m[2][3]),
        }
    }

    /// The rotation angle (degrees).
    pub fn rotation_angle_deg(&self) -> f64 {
        let cos = ((self.rotation.x_axis.x + self.rotation.y_axis.y + self.rotation.z_axis.z
            - 1.0)
            / 2.0)
            .clamp(-1.0, 1.0);
        cos.acos().to_degrees()
    }
}

/// Why a registration could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RegistrationError {
    #[error("need at least 3 point pairs for a rigid fit, got {0}")]
    TooFewPoints(usize),
    #[error("the landmarks are (nearly) collinear: the rotation about their line is undetermined")]
    Collinear,
    #[error(
        "ICP found only {found} surface pairs away from the breasts (need {needed}): do the scans overlap, and are the landmarks on the right scans?"
    )]
    TooFewPairs { found: usize, needed: usize },
}

/// The rigid transform minimising the sum of squared distances between `transform(moving[i])`
/// and `fixed[i]` (Kabsch; reflections excluded).
pub fn fit_rigid(moving: &[DVec3], fixed: &[DVec3]) -> Result<RigidTransform, RegistrationError> {
    let n = moving.len().min(fixed.len());
    if n < 3 {
        return Err(RegistrationError::TooFewPoints(n));
    }
    let moving_centroid = moving[..n].iter().copied().sum::<DVec3>() / n as f64;
    let fixed_centroid = fixed[..n].iter().copied().sum::<DVec3>() / n as f64;
    let covariance = Mat::<f64>::from_fn(3, 3, |i, j| {
        (0..n)
            .map(|k| (moving[k] - moving_centroid)[i] * (fixed[k] - fixed_centroid)[j])
            .sum()
    });
    let svd = covariance.svd().map_err(|_| RegistrationError::Collinear)?;
    let singular = svd.S().column_vector();
    if singular[1] <= 1e-9 * singular[0].max(f64::MIN_POSITIVE) {
        return Err(RegistrationError::Collinear);
    }
    let to_glam = |m: faer::MatRef<'_, f64>| {
        DMat3::from_cols_array_2d(&[0, 1, 2].map(|j| [0, 1, 2].map(|i| m[(i, j)])))
    };
    let (u, v) = (to_glam(svd.U()), to_glam(svd.V()));
    let mut correction = DMat3::IDENTITY;
    if (v * u.transpose()).determinant() < 0.0 {
        correction.z_axis.z = -1.0;
    }
    let rotation = v * correction * u.transpose();
    Ok(RigidTransform {
        rotation,
        translation: fixed_centroid - rotation * moving_centroid,
    })
}

/// Registers on the bony landmarks: the transform taking `moving` landmarks onto `fixed`.
pub fn register_landmarks(
    moving: &Landmarks,
    fixed: &Landmarks,
) -> Result<RigidTransform, RegistrationError> {
    let points = |l: &Landmarks| BONY_LANDMARKS.map(|n| l.get(n));
    fit_rigid(&points(moving), &points(fixed))
}

/// Root mean square distance (mm) of the bony landmarks after the transform.
pub fn landmark_rms_mm(moving: &Landmarks, fixed: &Landmarks, transform: &RigidTransform) -> f64 {
    let sum: f64 = BONY_LANDMARKS
        .iter()
        .map(|&n| {
            transform
                .apply(moving.get(n))
                .distance_squared(fixed.get(n))
        })
        .sum();
    (sum / BONY_LANDMARKS.len() as f64).sqrt()
}

/// A ball around one breast that surface matching must ignore.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExcludedBall {
    pub centre: DVec3,
    pub radius_mm: f64,
}

/// Margin added around the breast landmarks when excluding the breasts (mm).
const BREAST_EXCLUSION_MARGIN_MM: f64 = 30.0;

/// Generous balls around both breasts, from their landmarks: centred at the nipple, with a
/// radius 1.2 times the farthest fold landmark plus a margin. Until cut curves exist this
/// is how "away from the breasts" is defined.
pub fn breast_exclusion(landmarks: &Landmarks) -> [ExcludedBall; 2] {
    use LandmarkName::*;
    let ball = |nipple: LandmarkName, fold: [LandmarkName; 3]| {
        let centre = landmarks.get(nipple);
        let reach = fold
            .iter()
            .map(|&n| landmarks.get(n).distance(centre))
            .fold(0.0, f64::max);
        ExcludedBall {
            centre,
            radius_mm: 1.2 * reach + BREAST_EXCLUSION_MARGIN_MM,
        }
    };
    [
        ball(Pnl, [PSMFl, PSMFml, PSMFll]),
        ball(Pnr, [PSMFr, PSMFmr, PSMFlr]),
    ]
}

fn is_excluded(p: DVec3, balls: &[ExcludedBall]) -> bool {
    balls
        .iter()
        .any(|b| p.distance_squared(b.centre) < b.radius_mm * b.radius_mm)
}

/// A scan prepared as the fixed side of surface matching.
pub struct FixedSurface<'a> {
    mesh: &'a TriMesh,
    index: &'a SurfaceIndex,
    normals: Vec<DVec3>,
    /// Triangles touching the scan border: closest points there are not correspondences.
    near_border: Vec<bool>,
    excluded: [ExcludedBall; 2],
}

impl<'a> FixedSurface<'a> {
    /// Prepares `mesh` (with its index, topology and landmarks) for matching.
    pub fn new(
        mesh: &'a TriMesh,
        index: &'a SurfaceIndex,
        topology: &Topology,
        landmarks: &Landmarks,
    ) -> FixedSurface<'a> {
        let mut border_vertex = vec![false; mesh.vertex_count()];
        for boundary in topology.boundary_loops(mesh) {
            for v in boundary {
                border_vertex[v as usize] = true;
            }
        }
        let near_border = mesh
            .triangles
            .iter()
            .map(|t| t.iter().any(|&v| border_vertex[v as usize]))
            .collect();
        FixedSurface {
            mesh,
            index,
            normals: mesh.vertex_normals(),
            near_border,
            excluded: breast_exclusion(landmarks),
        }
    }

    /// The matching surface point for `p`: position and interpolated unit normal, or
    /// `None` if it is farther than `max_distance_mm`, on the border or on a breast.
    fn correspondence(&self, p: DVec3, max_distance_mm: f64) -> Option<(DVec3, DVec3)> {
        let nearest = self.index.closest_point_within(p, max_distance_mm)?;
        if self.near_border[nearest.triangle] || is_excluded(nearest.point, &self.excluded) {
            return None;
        }
        let tri = self.mesh.triangles[nearest.triangle];
        let normal: DVec3 = (0..3)
            .map(|k| self.normals[tri[k] as usize] * nearest.barycentric[k])
            .sum();
        Some((nearest.point, normal.normalize_or_zero()))
    }
}

/// Points of the moving scan used for surface matching: vertices away from its breasts,
/// thinned to at most `max_count` by a regular stride.
pub fn matching_samples(moving: &TriMesh, landmarks: &Landmarks, max_count: usize) -> Vec<DVec3> {
    let excluded = breast_exclusion(landmarks);
    let stride = moving.vertex_count().div_ceil(max_count.max(1)).max(1);
    moving
        .positions
        .iter()
        .step_by(stride)
        .copied()
        .filter(|&p| !is_excluded(p, &excluded))
        .collect()
}

/// Settings of the ICP refinement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpOptions {
    pub max_iterations: usize,
    /// Pairs farther apart than this are ignored in the first iteration (mm).
    pub initial_max_distance_mm: f64,
    /// Lower bound of the adaptive pair distance cut-off (mm).
    pub min_max_distance_mm: f64,
    /// Stop when an iteration moves no sample by more than this (mm).
    pub tolerance_mm: f64,
}

impl Default for IcpOptions {
    fn default() -> IcpOptions {
        IcpOptions {
            max_iterations: 60,
            initial_max_distance_mm: 15.0,
            min_max_distance_mm: 2.0,
            tolerance_mm: 1e-4,
        }
    }
}

/// Outcome of ICP.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IcpResult {
    pub transform: RigidTransform,
    pub iterations: usize,
    /// Surface RMS (mm) of the pairs found in the last iteration.
    pub rms_mm: f64,
    pub pairs: usize,
}

/// Fewest pairs for a trustworthy fit.
const MIN_ICP_PAIRS: usize = 100;

/// Point-to-plane ICP: refines `initial` so the `samples` (moving scan, file frame) lie on
/// the fixed surface. Each step linearises the rotation, solves the 6x6 normal equations,
/// and tightens the pair cut-off to three times the current RMS.
pub fn icp_point_to_plane(
    fixed: &FixedSurface<'_>,
    samples: &[DVec3],
    initial: RigidTransform,
    options: &IcpOptions,
) -> Result<IcpResult, RegistrationError> {
    let mut transform = initial;
    let mut max_distance = options.initial_max_distance_mm;
    let mut result = None;
    for iteration in 1..=options.max_iterations {
        let pairs: Vec<(DVec3, DVec3, DVec3)> = samples
            .par_iter()
            .filter_map(|&s| {
                let p = transform.apply(s);
                fixed
                    .correspondence(p, max_distance)
                    .map(|(q, n)| (p, q, n))
            })
            .collect();
        if pairs.len() < MIN_ICP_PAIRS {
            return Err(RegistrationError::TooFewPairs {
                found: pairs.len(),
                needed: MIN_ICP_PAIRS,
            });
        }
        let rms = (pairs
            .iter()
            .map(|(p, q, _)| p.distance_squared(*q))
            .sum::<f64>()
            / pairs.len() as f64)
            .sqrt();
        let step = solve_point_to_plane_step(&pairs);
        let largest_move = pairs
            .iter()
            .map(|(p, _, _)| step.apply(*p).distance(*p))
            .fold(0.0, f64::max);
        transform = step.after(&transform);
        result = Some(IcpResult {
            transform,
            iterations: iteration,
            rms_mm: rms,
            pairs: pairs.len(),
        });
        max_distance =
            (3.0 * rms).clamp(options.min_max_distance_mm, options.initial_max_distance_mm);
        if largest_move < options.tolerance_mm {
            break;
        }
    }
    result.ok_or(RegistrationError::TooFewPairs {
        found: 0,
        needed: MIN_ICP_PAIRS,
    })
}

/// One Gauss-Newton step of point-to-plane alignment, about the pairs' centroid for good
/// conditioning: minimises Σ ((ω × (p - c) + t + p - q) · n)².
fn solve_point_to_plane_step(pairs: &[(DVec3, DVec3, DVec3)]) -> RigidTransform {
    let centre = pairs.iter().map(|(p, _, _)| *p).sum::<DVec3>() / pairs.len() as f64;
    let mut normal_matrix = Mat::<f64>::zeros(6, 6);
    let mut rhs = Mat::<f64>::zeros(6, 1);
    for (p, q, n) in pairs {
        let arm = (*p - centre).cross(*n);
        let jacobian = [arm.x, arm.y, arm.z, n.x, n.y, n.z];
        let residual = (*p - *q).dot(*n);
        for i in 0..6 {
            rhs[(i, 0)] -= jacobian[i] * residual;
            for j in 0..6 {
                normal_matrix[(i, j)] += jacobian[i] * jacobian[j];
            }
        }
    }
    let Ok(cholesky) = normal_matrix.llt(faer::Side::Lower) else {
        return RigidTransform::IDENTITY; // degenerate geometry (e.g. a plane): stay put
    };
    let x = cholesky.solve(&rhs);
    let rotation = DMat3::from_quat(DQuat::from_scaled_axis(DVec3::new(
        x[(0, 0)],
        x[(1, 0)],
        x[(2, 0)],
    )));
    let shift = DVec3::new(x[(3, 0)], x[(4, 0)], x[(5, 0)]);
    // Rotate about the centre, then shift.
    RigidTransform {
        rotation,
        translation: centre - rotation * centre + shift,
    }
}

/// RMS distance (mm) from the transformed samples to the fixed surface, over the samples
/// that have a correspondence within `max_distance_mm` away from border and breasts, and
/// how many they are.
pub fn surface_rms_mm(
    fixed: &FixedSurface<'_>,
    samples: &[DVec3],
    transform: &RigidTransform,
    max_distance_mm: f64,
) -> (f64, usize) {
    let squared: Vec<f64> = samples
        .par_iter()
        .filter_map(|&s| {
            let p = transform.apply(s);
            fixed
                .correspondence(p, max_distance_mm)
                .map(|(q, _)| p.distance_squared(q))
        })
        .collect();
    if squared.is_empty() {
        return (f64::NAN, 0);
    }
    (
        (squared.iter().sum::<f64>() / squared.len() as f64).sqrt(),
        squared.len(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use mesh::shapes::icosphere;

    fn known_transform() -> RigidTransform {
        RigidTransform {
            rotation: DMat3::from_quat(DQuat::from_axis_angle(
                DVec3::new(0.2, 1.0, 0.4).normalize(),
                7f64.to_radians(),
            )),
            translation: DVec3::new(25.0, -8.0, 4.0),
        }
    }

    #[test]
    fn kabsch_recovers_a_known_transform_exactly() {
        let truth = known_transform();
        let fixed = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(88.0, -30.0, -2.0),
            DVec3::new(-88.0, -30.0, -2.0),
            DVec3::new(0.0, -150.0, 75.0),
        ];
        let moving = fixed.map(|p| truth.inverse().apply(p));
        let fit = fit_rigid(&moving, &fixed).unwrap();
        // Noise-free: exact up to round-off.
        assert!((fit.rotation - truth.rotation).abs_diff_eq(DMat3::ZERO, 1e-12));
        assert!(fit.translation.distance(truth.translation) < 1e-10);
        assert!(
            (fit.inverse().after(&fit).rotation - DMat3::IDENTITY).abs_diff_eq(DMat3::ZERO, 1e-12)
        );
        let m = RigidTransform::from_row_major(&fit.to_row_major());
        assert!(m.translation.distance(fit.translation) < 1e-15);
        assert!((truth.rotation_angle_deg() - 7.0).abs() < 1e-9);
    }

    #[test]
    fn kabsch_rejects_degenerate_input() {
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        assert_eq!(fit_rigid(&line, &line), Err(RegistrationError::Collinear));
        assert_eq!(
            fit_rigid(&line[..2], &line[..2]),
            Err(RegistrationError::TooFewPoints(2))
        );
    }

    #[test]
    fn icp_converges_on_an_ellipsoid_from_a_perturbed_start() {
        // An ellipsoid has no rotational symmetry, so the pose is unique.
        let mut fixed = icosphere(1.0, 5);
        fixed.map_positions(|p| DVec3::new(120.0 * p.x, 90.0 * p.y, 60.0 * p.z));
        let index = SurfaceIndex::new(&fixed).unwrap();
        let topology = Topology::new(&fixed);
        // Landmarks far away: nothing is excluded.
        let landmarks = Landmarks::new(|_| DVec3::splat(1e6));
        let surface = FixedSurface::new(&fixed, &index, &topology, &landmarks);

        let truth = known_transform();
        let mut moving = fixed.clone();
        let to_moving = truth.inverse();
        moving.map_positions(|p| to_moving.apply(p));
        let samples = matching_samples(&moving, &landmarks, 5000);
        // Start 2 degrees and 3 mm away from the truth.
        let start = RigidTransform {
            rotation: DMat3::from_quat(DQuat::from_axis_angle(DVec3::Z, 2f64.to_radians())),
            translation: DVec3::new(3.0, 0.0, 0.0),
        }
        .after(&truth);
        let result = icp_point_to_plane(&surface, &samples, start, &IcpOptions::default()).unwrap();
        let error = result.transform.after(&truth.inverse());
        // Noise-free, same sampling: converges to round-off; 1e-3 degrees / 1e-3 mm is
        // far below the 0.05 degrees and 0.05 mm the issue asks for.
        assert!(
            error.rotation_angle_deg() < 1e-3,
            "{}",
            error.rotation_angle_deg()
        );
        assert!(error.translation.length() < 1e-3, "{}", error.translation);
        assert!(result.rms_mm < 1e-3);
    }
}
