//! The implant simulation (paper V-A, V-B): placing an implant on the slightly shifted
//! fill-in behind a breast, turning it into a displacement template on the finest
//! tetrahedral level, solving the corotated elasticity problem with the multigrid,
//! correcting for the implant's weight, and carrying the result to the scan.
//!
//! - [`bed`]: the implant bed (the fill-in shifted back) and its cylindrical
//!   (Mercator-like) parameterisation about the body's axis.
//! - [`placement`]: the anchor (default: lower edge on the planned fold), moves along
//!   the bed, rotation, the implant's local frame.
//! - [`pocket`]: where the implant may lie beyond the fill-in, and the planned fold.
//! - [`over_implant`]: the chest skin over an implant that reaches beyond the native
//!   breast, measured with the breast after surgery.
//! - [`template`]: fill-in elements, implant vertices, fixed vertices, implant elements.
//! - [`skin`]: the skin as a stiff membrane on the finest mesh's surface faces.
//! - [`session`]: [`Simulation`], the session: set or move implants, one V-cycle or
//!   solve to convergence, the gravity correction, the moved scan, landmarks and breast
//!   volumes.
//! - [`field`]: the finest displacement at arbitrary points (inside: barycentric;
//!   outside: nearest element, faded out).
//!
//! This crate knows nothing about files or command lines; `plan` builds the patient
//! model and calls it.
//!
//! # Measured (60,000-element models, 2 cores)
//! Phantom, round 120 x 33.6 mm (252.6 ml) on both sides, no gravity (`tests/phantom.rs`):
//! breasts +241.3 / +241.6 ml (-4.5%; the template inserts 249.9 ml, the implant over
//! the part of the bed the mesh covers), nipples 12.3 mm forward (0.37 x projection), no
//! inverted element, largest scan edge stretch 1.6x, mirror asymmetry at most 0.06 mm;
//! gravity correction (22 cycles): nipple 0.7 mm lower. Shared scans with a
//! moderate-profile implant sized to the breast base (`tests/shared_scans.rs`): volume
//! within 2.2% of the implant's, no inverted element.
//!
//! # Known shortfalls
//! - The implant's coordinates are a linear map of the bed's cylinder coordinates, so
//!   its thickness is laid off stretched where the bed slopes against the cylinder (the
//!   lower pole); the template is scaled as a whole to the implant's volume over the
//!   part of the bed the mesh covers.
//! - The tissue resists volume loss through a penalty on `J = det F` beside the
//!   corotated energy, which sees volume change only to first order; volume gain
//!   (tension) is left to the corotated energy, so the tangent stiffness jumps at
//!   `J = 1`, and the penalty is on the finest level only (a Galerkin hierarchy carries
//!   it down; rediscretised coarse levels, the fallback, do not).
//! - Galerkin coarse operators of `fem` can turn singular for some constraint sets
//!   (two levels on the phantom; three levels with both implants before the bed was
//!   held); the session then falls back to rediscretised coarse operators.
//!
//! # Units
//! Millimetres, ml, kPa, kg/m³, mN (see `fem`).

pub mod bed;
pub mod carry;
pub mod error;
pub mod field;
pub mod muscle;
pub mod over_implant;
pub mod placement;
pub mod pocket;
pub mod resolved_length;
pub mod session;
pub mod skin;
pub mod template;
pub mod template_volume;

pub use bed::{ChestCylinder, DEFAULT_SHIFT_MM, ImplantBed};
pub use error::SimulationError;
pub use field::{DEFAULT_FALLOFF_MM, PointMap};
pub use muscle::{DEFAULT_MUSCLE, MuscleFigures, MuscleLayer, Pectoralis};
pub use placement::{Anchor, AnchorRule, ParseAnchorRuleError, Placement};
pub use resolved_length::ResolvedLength;
pub use session::{
    BreastVolume, CARRIED_CONTROL_POINT_SPACING_MM, CycleInfo, PatientInput, PlacedImplant,
    RunReport, STERNUM_HALF_WIDTH_MM, Simulation, SimulationOptions, SolveReport, SolvedState,
    Stage, WALL_TOLERANCE_FACTOR,
};
pub use skin::SkinLayer;
pub use template::ImplantTemplate;
