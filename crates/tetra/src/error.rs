//! Errors of the tetrahedral mesher and its file I/O. Every variant says what is wrong and
//! where (file, line, element), so the message can go straight to the user.

use mesh::{ManifoldReport, MeshError};

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
    /// The tetrahedral mesh data or its file ([`tetmesh::TetMeshError`]).
    #[error(transparent)]
    Mesh(#[from] tetmesh::TetMeshError),
}
