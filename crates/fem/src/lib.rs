//! Corotated linear tetrahedral finite elements for the breast simulation (paper V).
//!
//! - [`FemModel`]: linear tetrahedra, isotropic Hooke material per element
//!   ([`Material`], defaults for breast tissue), per-element density, consistent gravity;
//!   optional plane-stress [`Membrane`]s on faces (the skin).
//! - [`Formulation`]: small-strain linear or corotated elasticity; element rotations from
//!   a robust polar decomposition ([`polar_rotation`]) that handles inverted elements.
//! - [`Constraints`] and [`ReducedSystem`]: prescribed displacements eliminated from the
//!   system; the reduced stiffness is a 3x3 block CSR matrix ([`BlockCsr`]) whose pattern
//!   and element-to-slot maps are built once and whose values are refilled in parallel.
//!   Constraints that change (an implant's template) are replaced in O(vertices) by
//!   [`ReducedSystem::set_constraints`] and [`multigrid::Multigrid::set_constraints`]
//!   and eliminated symmetrically at assembly, without rebuilding the pattern.
//! - [`DirectSolver`]: faer sparse Cholesky, symbolic factorisation reused.
//! - [`StaticSolver`]: the corotational static solve (re-estimate rotations, reassemble,
//!   solve) to convergence.
//! - [`box_mesh`]: structured box tetrahedralisations for tests and benchmarks.
//! - [`Prolongation`]: barycentric transfer between non-nested levels.
//! - [`multigrid`]: geometric multigrid on non-nested levels (Galerkin or rediscretised
//!   coarse operators, multicolour block Gauss-Seidel, Cholesky on the coarsest level),
//!   one V(2,1) cycle per call, or a symmetric V(2,2) cycle as the preconditioner of CG. Measured: PCG
//!   matches the direct solver to 1e-10; a bare cycle reduces the residual only about
//!   1.7x at ν = 0.45, short of the target of 5.
//!
//! # The static solve
//! Each iteration re-estimates the element rotations, reassembles and solves
//! `K_ff Δu_f = f_ext - f_int(u)` with a backtracking line search on the potential
//! energy (the corotated forces are conservative). With [`Tangent::Full`] (default) `K`
//! includes the clamped rotation-derivative term and the iteration is a Newton method:
//! measured 6 iterations for a 20% affine stretch-and-rotation patch test and 9 for a
//! clamped bar pulled 10%, against 37 and 30 with [`Tangent::Warped`] (`R K Rᵀ` only, the
//! paper's and the multigrid's matrix). The warped fixed-point iteration can diverge in
//! the bending modes of slender parts under large tension (it lacks the geometric
//! stiffness): a 100x10x10 mm bar pulled by 10% under a dead load did not converge in
//! 200 iterations. Rounding floors the relative residual near 1e-11 at small strains.
//!
//! Vertices used by no tetrahedron are not unknowns; their displacement is zero.
//!
//! # Units
//! Lengths and displacements in mm; Young's modulus and stresses in kPa (= mN/mm²);
//! forces in mN; density in kg/m³; gravity in m/s² (converted with
//! [`model::KG_M3_TIMES_M_S2_TO_MN_MM3`]).

mod blocks;
pub mod boxmesh;
pub mod direct;
mod eigen3;
pub mod error;
pub mod material;
pub mod membrane;
pub mod model;
pub mod multigrid;
pub mod polar;
pub mod slider;
pub mod solve;
pub mod system;
pub mod transfer;

pub use boxmesh::{box_is_boundary, box_mesh, box_vertex_index};
pub use direct::DirectSolver;
pub use error::FemError;
pub use material::{
    DEFAULT_DENSITY_KG_M3, DEFAULT_POISSON_RATIO, DEFAULT_YOUNG_KPA, Material,
    STANDARD_GRAVITY_M_S2,
};
pub use membrane::Membrane;
pub use model::{
    CompressionPenalty, ElementRest, FemModel, Formulation, InversionBarrier, Tangent,
};
pub use polar::{polar_rotation, rotation_variant_svd};
pub use slider::Slider;
pub use solve::{SolveOptions, StaticSolution, StaticSolver, solve_static};
pub use system::{BlockCsr, Constraints, NOT_FREE, ReducedSystem, block_mul};
pub use transfer::Prolongation;
