//! Tetrahedral meshing of closed surfaces for the finite-element simulation: isosurface
//! stuffing on a BCC lattice (regular interior, conforming boundary, dihedral angles
//! bounded by the method), a hierarchy of ever coarser levels, point location, and VTK
//! XML (`.vtu`) input and output.
//!
//! Lengths are in millimetres, volumes in mm³. This crate knows nothing about anatomy,
//! implants or the solver.
//!
//! # Local refinement (planned, not built yet)
//! The paper's graded variant replaces the uniform lattice by a BCC octree: cubes are
//! split in eight inside the refinement region (boxes, a surface, or a distance band
//! around the fill-ins), the octree is balanced so face and edge neighbours differ by at
//! most one level, and the cells between levels are filled with the paper's bisected
//! BCC tetrahedra (a long edge shared by a coarse and a fine cube is split at its
//! midpoint). Everything downstream is per lattice edge or tetrahedron and stays:
//! classification, cut points, warping (with the paper's α values for the graded
//! lattice, whose angle bound is lower) and the stencils. The change is confined to
//! `lattice.rs`, which becomes an octree lattice that enumerates points, edges (with ids)
//! and tetrahedra, and to `classify`, which then sweeps each leaf row of the octree
//! instead of whole lattice lines. The coarser hierarchy levels stay uniform; the finest
//! level's spacing outside the region then follows `--elements`, inside it the requested
//! edge length (4 mm by default).

pub mod error;
pub mod hierarchy;
mod lattice;
pub mod locate;
pub mod quality;
mod stencils;
pub mod stuffing;
pub mod surface;
pub mod tetmesh;
pub mod vtu;
mod winding;

pub use error::TetraError;
pub use hierarchy::{
    Hierarchy, Level, build_hierarchy, build_hierarchy_with_elements, level_with_elements,
};
pub use locate::{Location, TetLocator};
pub use quality::QualityReport;
pub use stuffing::stuff;
pub use surface::ClosedSurface;
pub use tetmesh::{BoundarySurface, TetMesh};
