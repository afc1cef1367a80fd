//! Errors of the tetrahedral mesher and its file I/O. Every variant says what is wrong and
//! where (file, line, element), so the message can go straight to the user.

use mesh::{ManifoldReport, MeshError};
use std::path::PathBuf;

/// An error from meshing, validation or VTU I/O.
#[derive(Debug, thiserror::Error)]
pub enum TetraError {
    /// The input surface fails the basic mesh checks (empty, NaN, bad index).
    #[error("input surface: {0}")]
    InvalidSurface(#[source] MeshError),
    /// The input surface has holes, non-manifold edges or vertices, or mixed orientation.
    #[error("input surface is not a closed, consistently oriented manifold: {0}")]
    NotWatertight(ManifoldReport),
    /// The input surface's triangles are oriented inward (negative enclosed volume).
    #[error(
        "input surface is oriented inward (enclosed volume {volume_mm3:.3} mm³): flip its triangles"
    )]
    InwardOriented { volume_mm3: f64 },
    /// Triangles of the input surface intersect each other.
    #[error(
        "input surface intersects itself: {pairs} pairs of triangles meet, the first is ({}, {})",
        first.0,
        first.1
    )]
    SelfIntersecting { pairs: usize, first: (usize, usize) },
    /// The lattice spacing is not a positive finite length.
    #[error("lattice spacing must be a positive length in mm, got {spacing_mm}")]
    InvalidSpacing { spacing_mm: f64 },
    /// The lattice over the surface's bounding box would be too large to hold.
    #[error(
        "a lattice of spacing {spacing_mm} mm over this surface needs {points} points (at most {limit}): choose a coarser spacing"
    )]
    LatticeTooLarge {
        spacing_mm: f64,
        points: u64,
        limit: u64,
    },
    /// The spacing is so coarse that no tetrahedron is left inside the surface.
    #[error("a lattice spacing of {spacing_mm} mm leaves no tetrahedron inside the surface")]
    NoTetrahedra { spacing_mm: f64 },
    /// A hierarchy was asked for zero levels or zero elements.
    #[error("{what} must be at least 1")]
    ZeroCount { what: &'static str },
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
