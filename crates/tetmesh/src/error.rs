//! Errors of tetrahedral mesh data and its file I/O. Every variant says what is wrong and
//! where (file, line, element), so the message can go straight to the user.

use std::path::PathBuf;

/// An error from validating a tetrahedral mesh or reading and writing it.
#[derive(Debug, thiserror::Error)]
pub enum TetMeshError {
    /// A tetrahedral mesh breaks an invariant (index range, finite coordinates, volume).
    #[error("tetrahedron {tet}: {problem}")]
    InvalidTetrahedron { tet: usize, problem: String },
    /// A vertex coordinate of a tetrahedral mesh is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate {position:?}")]
    NonFiniteVertex { vertex: usize, position: [f64; 3] },
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A VTU file does not follow the format or lacks what is needed.
    #[error("{path}{}: {message}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Vtu {
        path: PathBuf,
        /// 1-based line number, when known.
        line: Option<usize>,
        message: String,
    },
    /// A data array to be written holds NaN or infinity.
    #[error("data array `{name}` entry {entry} is not finite")]
    NonFiniteValue { name: String, entry: usize },
    /// A data array to be written does not match the mesh.
    #[error("{location} data array `{name}` has {found} values, expected {expected}")]
    DataSize {
        location: &'static str,
        name: String,
        found: usize,
        expected: usize,
    },
}
