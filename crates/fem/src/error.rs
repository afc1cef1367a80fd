//! Errors of the finite element crate.

use thiserror::Error;

/// Everything that can go wrong when building or solving a finite element model.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum FemError {
    /// A vertex position is NaN or infinite.
    #[error("vertex {vertex}: position {position:?} is not finite")]
    NonFiniteVertex {
        /// Vertex index.
        vertex: usize,
        /// The offending position (mm).
        position: [f64; 3],
    },
    /// A tetrahedron refers to a vertex that does not exist or repeats a vertex.
    #[error("tetrahedron {element}: vertex indices {vertices:?} are invalid ({reason})")]
    BadElement {
        /// Element index.
        element: usize,
        /// Its vertex indices.
        vertices: [u32; 4],
        /// What is wrong.
        reason: &'static str,
    },
    /// A tetrahedron of the rest mesh is inverted or flat.
    #[error(
        "tetrahedron {element}: rest volume {volume_mm3:e} mm³ is not positive \
         (inverted or degenerate element; expected (b-a)·((c-a)×(d-a)) > 0)"
    )]
    InvertedElement {
        /// Element index.
        element: usize,
        /// Its signed rest volume (mm³).
        volume_mm3: f64,
    },
    /// A material parameter is out of range or not finite.
    #[error("tetrahedron {element}: {what}")]
    BadMaterial {
        /// Element index.
        element: usize,
        /// What is wrong, with the value.
        what: String,
    },
    /// A slider ([`crate::slider::Slider`]) is out of range or not finite.
    #[error("slider {slider}: {what}")]
    BadSlider {
        /// Index in the list given.
        slider: usize,
        /// What is wrong.
        what: &'static str,
    },
    /// A per-vertex or per-element input array has the wrong length.
    #[error("{what}: expected {expected} entries, got {got}")]
    LengthMismatch {
        /// Which input.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// A load, prescribed displacement or state value is NaN or infinite.
    #[error("{what} at vertex {vertex} is not finite: {value:?}")]
    NonFiniteInput {
        /// Which input.
        what: &'static str,
        /// Vertex index (or 0 for global values such as gravity).
        vertex: usize,
        /// The offending value.
        value: [f64; 3],
    },
    /// No vertex is constrained: the static system is singular (rigid motions are free).
    #[error(
        "no vertex is constrained: the static system is singular (rigid body motions are \
         free); prescribe the displacement of at least three non-collinear vertices"
    )]
    NoConstraints,
    /// A constraint names a vertex that does not exist.
    #[error("constraint on vertex {vertex}, but the mesh has {vertex_count} vertices")]
    ConstraintOutOfRange {
        /// The vertex.
        vertex: usize,
        /// Number of vertices of the mesh.
        vertex_count: usize,
    },
    /// The sparse Cholesky factorisation failed: some part of the mesh is not held by
    /// enough constraints, or the system is otherwise not positive definite.
    #[error(
        "the reduced stiffness matrix is not positive definite ({detail}): a part of the \
         mesh may not be held by any constraint"
    )]
    Singular {
        /// The solver's message.
        detail: String,
    },
    /// A solver option is out of range.
    #[error("invalid solver options: {what}")]
    InvalidOptions {
        /// Which option and its value.
        what: String,
    },
    /// The solution contains NaN or infinite values.
    #[error("the solver produced a non-finite displacement (iteration {iteration})")]
    NonFiniteSolution {
        /// Iteration of the corotational loop.
        iteration: usize,
    },
}
