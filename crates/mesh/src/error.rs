//! Errors for reading, writing and validating meshes. Every variant names what is wrong
//! and where (file, line, element), so the message can go straight to the user.

use std::path::PathBuf;

/// An error from mesh I/O or validation.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened, read or written.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The file's content does not follow its format.
    #[error("{path}{}: {message}", line.map(|l| format!(", line {l}")).unwrap_or_default())]
    Parse {
        path: PathBuf,
        /// 1-based line number for text formats, when known.
        line: Option<usize>,
        message: String,
    },
    /// The file holds more than any scan: a damaged file, or a device that never ends.
    #[error(
        "{path}: more than {limit_gib} GiB, larger than any body scan (a damaged file, or not a file at all)"
    )]
    TooLarge { path: PathBuf, limit_gib: u64 },
    /// The file extension names no format we read or write.
    #[error("{path}: unsupported mesh format (expected .ply, .obj or .stl)")]
    UnsupportedFormat { path: PathBuf },
    /// A vertex coordinate is NaN or infinite.
    #[error("vertex {vertex} has a non-finite coordinate {position:?}")]
    NonFiniteVertex { vertex: usize, position: [f64; 3] },
    /// A triangle refers to a vertex that does not exist.
    #[error(
        "triangle {triangle} refers to vertex {index}, but the mesh has only {vertex_count} vertices"
    )]
    IndexOutOfRange {
        triangle: usize,
        index: u32,
        vertex_count: usize,
    },
    /// A triangle uses the same vertex twice.
    #[error("triangle {triangle} repeats a vertex: {indices:?}")]
    RepeatedVertex { triangle: usize, indices: [u32; 3] },
    /// The mesh has no triangles at all.
    #[error("the mesh has no triangles")]
    Empty,
    /// An extra vertex property cannot be written.
    #[error("vertex property {name:?}: {message}")]
    VertexProperty { name: String, message: &'static str },
    /// An attribute layer's size does not match the mesh.
    #[error("{layer} has {found} entries, expected {expected}")]
    AttributeSize {
        layer: &'static str,
        found: usize,
        expected: usize,
    },
}

impl MeshError {
    /// Adds the file path to an error raised while checking a mesh that came from `path`.
    pub fn in_file(self, path: &std::path::Path) -> MeshError {
        match self {
            MeshError::Io { .. }
            | MeshError::Parse { .. }
            | MeshError::UnsupportedFormat { .. } => self,
            other => MeshError::Parse {
                path: path.to_path_buf(),
                line: None,
                message: other.to_string(),
            },
        }
    }
}
