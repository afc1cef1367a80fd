//! Left/right symmetry of one scan (beyond the paper): the scan mirrored across its
//! mid-sagittal plane and compared with itself.
//!
//! # Mirror
//! The mid-sagittal plane comes from the landmarks: it holds the sternal notch Pj and the
//! xiphoid Px and is orthogonal to the anatomical frame's left axis (Pcr towards Pcl),
//! i.e. the frame's `x = 0` plane. Clavicle points placed a few millimetres off tilt it
//! by a degree or two, which at the breasts (10-15 cm from the plane) would read as
//! several millimetres of asymmetry, so the reflection is refined: the mirrored scan
//! (with its landmarks' sides swapped) is registered onto the scan by point-to-plane
//! ICP away from both breasts ([`anatomy::register`]). The mirror is the reflection
//! followed by that rigid correction; where the chest is symmetric it maps the scan
//! onto itself.
//!
//! # Figures
//! - breast volumes (from the breast model) and their ratio left / right;
//! - the nipple position difference: the left nipple minus the mirrored right nipple, in
//!   the anatomical frame (x: how much farther from the midline the left nipple is, y:
//!   how much higher, z: how much more anterior), and its y component as the nipple
//!   height difference;
//! - the asymmetry map: every vertex's deviation from the mirrored surface (positive in
//!   front of it: this side is fuller there than the other), with its statistics over
//!   the whole overlap and the breast regions, as for two scans
//!   ([`SurfaceComparison`]: the scan is the test, its mirror image the reference).

use crate::AssessError;
use crate::deviation::DistanceSurface;
use crate::statistics::{SurfaceComparison, ZoneStatistics};
use anatomy::register::{
    FixedSurface, IcpOptions, RigidTransform, icp_point_to_plane, matching_samples,
};
use anatomy::{AnatomicalFrame, BreastModel, LandmarkName, Landmarks, Side};
use glam::{DMat3, DVec3};
use mesh::{SurfaceIndex, Topology, TriMesh};

/// Scan vertices used to match the mirrored scan to the scan.
const MATCHING_SAMPLES: usize = 30_000;

/// A scan with what its symmetry analysis needs.
pub struct SymmetryInput<'a> {
    pub mesh: &'a TriMesh,
    pub index: &'a SurfaceIndex,
    pub topology: &'a Topology,
    /// The landmarks on the scan (mm).
    pub landmarks: &'a Landmarks,
    pub frame: &'a AnatomicalFrame,
    /// The breast model of the scan: volumes and breast regions.
    pub breasts: &'a BreastModel,
}

/// The improper isometry taking a scan onto its mirror image: the reflection across the
/// landmarks' mid-sagittal plane, then a rigid correction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mirror {
    /// A point of the landmarks' mid-sagittal plane (Pj, mm).
    pub plane_point: DVec3,
    /// Its unit normal (the frame's left axis).
    pub plane_normal: DVec3,
    /// The correction found by matching the reflected scan to the scan.
    pub correction: RigidTransform,
}

impl Mirror {
    /// The reflection across the landmarks' mid-sagittal plane, without correction.
    pub fn from_frame(frame: &AnatomicalFrame) -> Mirror {
        Mirror {
            plane_point: frame.origin,
            plane_normal: frame.left(),
            correction: RigidTransform::IDENTITY,
        }
    }

    /// The mirror image of `p` (mm).
    pub fn apply(&self, p: DVec3) -> DVec3 {
        self.correction.apply(self.reflect(p))
    }

    fn reflect(&self, p: DVec3) -> DVec3 {
        p - 2.0 * (p - self.plane_point).dot(self.plane_normal) * self.plane_normal
    }

    /// The homogeneous 4x4 matrix of [`Mirror::apply`], row-major (determinant -1).
    pub fn to_row_major(&self) -> [[f64; 4]; 4] {
        let n = self.plane_normal;
        let reflection = DMat3::IDENTITY - 2.0 * DMat3::from_cols(n * n.x, n * n.y, n * n.z);
        RigidTransform {
            rotation: self.correction.rotation * reflection,
            translation: self.apply(DVec3::ZERO),
        }
        .to_row_major()
    }

    /// The mirror image of a mesh: positions mirrored, triangles reversed so that the
    /// normals still point out of the body; colours and texture coordinates kept.
    pub fn mirrored_mesh(&self, mesh: &TriMesh) -> TriMesh {
        let mut mirrored = mesh.clone();
        mirrored.map_positions(|p| self.apply(p));
        for triangle in &mut mirrored.triangles {
            triangle.swap(1, 2);
        }
        if let Some(uv) = &mut mirrored.uv {
            for triangle in &mut uv.triangles {
                triangle.swap(1, 2);
            }
        }
        mirrored
    }

    /// The landmarks of the mirror image: each mirrored, with the sides' names swapped
    /// (the mirrored left nipple is the mirror image's right nipple).
    pub fn mirrored_landmarks(&self, landmarks: &Landmarks) -> Landmarks {
        let mut mirrored = Landmarks::new(|name| self.apply(landmarks.get(name.opposite())));
        mirrored.extra = landmarks
            .extra
            .iter()
            .map(|(name, &p)| (name.clone(), self.apply(p)))
            .collect();
        mirrored
    }
}

/// The symmetry of a scan (see the module documentation).
#[derive(Debug, Clone)]
pub struct Symmetry {
    pub mirror: Mirror,
    /// RMS distance (mm) between the mirrored scan and the scan away from the breasts
    /// after the correction, and the ICP iterations it took.
    pub matching_rms_mm: f64,
    pub matching_iterations: usize,
    /// Breast volumes (ml).
    pub left_volume_ml: f64,
    pub right_volume_ml: f64,
    /// The left nipple minus the mirrored right nipple, in the anatomical frame (mm).
    pub nipple_position_difference_mm: DVec3,
    /// The scan (test) against its mirror image (reference): per-vertex asymmetry.
    pub comparison: SurfaceComparison,
    /// The asymmetry's statistics over the whole overlap and the breast regions.
    pub statistics: ZoneStatistics,
}

impl Symmetry {
    /// Left breast volume over right breast volume.
    pub fn volume_ratio_left_to_right(&self) -> f64 {
        self.left_volume_ml / self.right_volume_ml
    }

    /// How much higher the left nipple is than the mirrored right one (mm, frame `y`).
    pub fn nipple_height_difference_mm(&self) -> f64 {
        self.nipple_position_difference_mm.y
    }
}

/// Mirrors a scan across its mid-sagittal plane, refines the mirror by matching away
/// from the breasts, and compares the scan with its mirror image (see the module
/// documentation). `max_distance_mm` bounds the overlap as in [`SurfaceComparison`].
pub fn analyse_symmetry(
    scan: &SymmetryInput<'_>,
    max_distance_mm: f64,
) -> Result<Symmetry, AssessError> {
    let reflection = Mirror::from_frame(scan.frame);
    let reflected = reflection.mirrored_mesh(scan.mesh);
    let fixed = FixedSurface::new(scan.mesh, scan.index, scan.topology, scan.landmarks);
    let samples = matching_samples(
        &reflected,
        &reflection.mirrored_landmarks(scan.landmarks),
        MATCHING_SAMPLES,
    );
    let matched = icp_point_to_plane(
        &fixed,
        &samples,
        RigidTransform::IDENTITY,
        &IcpOptions::default(),
    )
    .map_err(AssessError::MirrorMatching)?;
    let mirror = Mirror {
        correction: matched.transform,
        ..reflection
    };

    let mirrored = mirror.mirrored_mesh(scan.mesh);
    let mirrored_index = SurfaceIndex::new(&mirrored).ok_or(AssessError::Mesh {
        role: "mirrored",
        source: mesh::MeshError::Empty,
    })?;
    let mirrored_topology = Topology::new(&mirrored);
    let sides = scan.breasts.scan_vertex_sides(scan.mesh.vertex_count());
    // Mirroring turns the left breast region into the right one.
    let mirrored_sides = sides.iter().map(|side| side.map(Side::opposite)).collect();
    let comparison = SurfaceComparison::new(
        &DistanceSurface::new(&mirrored, &mirrored_index, &mirrored_topology),
        mirrored_sides,
        &DistanceSurface::new(scan.mesh, scan.index, scan.topology),
        sides,
        max_distance_mm,
    )?;
    let nipple_difference =
        scan.landmarks.get(LandmarkName::Pnl) - mirror.apply(scan.landmarks.get(LandmarkName::Pnr));
    Ok(Symmetry {
        mirror,
        matching_rms_mm: matched.rms_mm,
        matching_iterations: matched.iterations,
        left_volume_ml: scan.breasts.left.volume_ml,
        right_volume_ml: scan.breasts.right.volume_ml,
        nipple_position_difference_mm: scan.frame.axes.transpose() * nipple_difference,
        statistics: comparison.zone_statistics(),
        comparison,
    })
}
