//! Tetrahedral mesh data, apart from how it was made: the mesh (positive tetrahedra,
//! volume, boundary, validation), element quality, point location, and VTK XML (`.vtu`)
//! input and output. The finite elements (`fem`) and the mesher (`tetra`) both build on
//! it; it knows nothing about meshing, anatomy or the solver.
//!
//! Lengths are in millimetres, volumes in mm³.

pub mod error;
pub mod locate;
pub mod quality;
pub mod tetmesh;
pub mod vtu;

pub use error::TetMeshError;
pub use locate::{Location, TetLocator};
pub use quality::QualityReport;
pub use tetmesh::{BoundarySurface, TetMesh};
