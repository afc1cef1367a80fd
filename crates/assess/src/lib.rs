//! Assessment of surface scans (paper VI-C, VI-D, Fig. 3, Fig. 13): how far one scan
//! lies from another (per-vertex point-to-surface deviation, unsigned and signed, over
//! the overlap of two open scans), its statistics over the whole overlap and over the
//! breast regions (RMS, mean, signed mean, symmetric Hausdorff), the deviation colour
//! map, and the left/right symmetry of one scan (beyond the paper).
//!
//! Works on [`mesh::TriMesh`] with the breast model and landmarks of [`anatomy`]; knows
//! nothing about implants, simulation, files or front ends. Lengths are millimetres.

pub mod colormap;
pub mod deviation;
pub mod statistics;
pub mod symmetry;

pub use colormap::{DEVIATION_COLOR_MAX_MM, OUTSIDE_OVERLAP_COLOR, deviation_color};
pub use deviation::{DEFAULT_MAX_DISTANCE_MM, DistanceSurface, PointDeviation};
pub use statistics::{
    DeviationStatistics, SurfaceComparison, Zone, ZoneStatistics, transfer_sides,
};
pub use symmetry::{Mirror, Symmetry, SymmetryInput, analyse_symmetry};

use anatomy::register::RegistrationError;
use mesh::MeshError;

/// Why an assessment could not be made.
#[derive(Debug, thiserror::Error)]
pub enum AssessError {
    #[error("the {role} surface: {source}")]
    Mesh {
        /// Which surface ("reference", "test", ...).
        role: &'static str,
        #[source]
        source: MeshError,
    },
    #[error("the maximum distance must be a positive number of mm, not {0}")]
    InvalidMaxDistance(f64),
    #[error(
        "no vertex of the test surface lies over the reference surface within {max_distance_mm} mm: the scans do not overlap (are they in the same frame? register them first)"
    )]
    NoOverlap { max_distance_mm: f64 },
    #[error("{what} has {found} entries, but the {role} surface has {expected} vertices")]
    SizeMismatch {
        what: &'static str,
        role: &'static str,
        found: usize,
        expected: usize,
    },
    #[error("symmetry: matching the mirrored scan to the scan away from the breasts failed: {0}")]
    MirrorMatching(#[source] RegistrationError),
}
