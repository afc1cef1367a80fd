//! Tetrahedral meshing of closed surfaces for the finite-element simulation: isosurface
//! stuffing on a BCC lattice (regular interior, conforming boundary, dihedral angles
//! bounded by the method), a hierarchy of ever coarser levels, point location, and VTK
//! XML (`.vtu`) input and output.
//!
//! Lengths are in millimetres, volumes in mm³. This crate knows nothing about anatomy,
//! implants or the solver.
//!
//! # Local refinement
//! [`stuff_refined`] (module [`refine`]) replaces the uniform lattice by a balanced
//! octree of BCC cubes: cubes are split in eight near the refinement region (boxes
//! and distance bands around surfaces such as the fill-ins) down to a fine spacing that
//! keeps element edges there within the requested bound (4 mm by default), leaves
//! sharing a face or an edge differ by at most one level, and the cells between levels
//! are filled with half pyramids, fans and bisected BCC tetrahedra (a long edge with a
//! finer neighbour's corner at its midpoint is split there). Classification, cut points,
//! warping and the stencils are shared with the uniform mesher. Unlike the paper's
//! graded variant, which keeps the whole boundary at the finest spacing, the level
//! transitions here meet the surface, where no angle bound is proved: the mesh is
//! checked and refined around any tetrahedron below 8° (falling back to the uniform
//! fine mesh if that fails). The coarser hierarchy levels stay uniform.

pub mod error;
pub mod hierarchy;
mod lattice;
pub mod refine;
mod stencils;
pub mod stuffing;
pub mod surface;
mod warp;
mod winding;

pub use error::TetraError;
pub use hierarchy::{
    Hierarchy, Level, build_hierarchy, build_hierarchy_down_to, build_hierarchy_with_elements,
    level_with_elements,
};
pub use refine::{RefinementRegion, stuff_refined};
pub use stuffing::stuff;
pub use surface::ClosedSurface;
// the mesh data lives in its own crate; these paths stay for the mesher's users
pub use ::tetmesh::{
    BoundarySurface, Location, QualityReport, TetLocator, TetMesh, TetMeshError, locate, quality,
    tetmesh, vtu,
};
