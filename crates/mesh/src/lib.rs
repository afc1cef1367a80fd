//! Triangle surface meshes: the data type every stage shares, file I/O (PLY, OBJ, STL),
//! validation, topology (adjacency, boundary loops, components), geometry (normals, areas,
//! enclosed volume), spatial queries (closest point, ray casts) and on-surface paths
//! (plane sections and geodesics).
//!
//! Lengths are in millimetres wherever a unit matters; the crate itself is unit-agnostic.
//! This crate knows nothing about anatomy, landmarks or simulation.

pub mod cut;
pub mod error;
pub mod geodesic;
pub mod geometry;
pub mod hole_patch;
pub mod intersect;
pub mod io;
pub mod ordered;
pub mod repair;
pub mod section;
pub mod shapes;
pub mod smooth;
pub mod spatial;
pub mod surface_curve;
pub mod topology;
pub mod trimesh;
pub mod units;
pub mod untangle;

pub use cut::{CutError, CutMesh, MeshPart, Region, compact, cut_along_curves};
pub use error::MeshError;
pub use geodesic::{GeodesicSolver, PathError, SurfacePath, SurfacePoint};
pub use glam::{DVec2, DVec3};
pub use hole_patch::{HolePatch, HolePatchError, patch_hole};
pub use intersect::{ManifoldReport, manifold_report, self_intersections};
pub use ordered::OrderedMm;
pub use repair::{FinRepair, fin_triangles};
pub use section::plane_section_path;
pub use smooth::{laplacian_smooth, smooth_inside_borders};
pub use spatial::{ClosestPoint, RayHit, SurfaceIndex};
pub use surface_curve::{CurveError, CurveLocation, CurvePoint, SurfaceCurve};
pub use topology::Topology;
pub use trimesh::{MaterialLayer, TriMesh, UvLayer};
pub use units::LengthUnit;
pub use untangle::{Untangled, untangle};
