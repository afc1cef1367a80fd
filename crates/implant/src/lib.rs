//! Breast implants: the shapes of paper V-C, their volumes and surfaces, and catalogs.
//!
//! - [`ImplantShape`]: a round ([`RoundImplant`], eqs. 2-4) or anatomic
//!   ([`AnatomicImplant`], eqs. 5-10) implant as a thickness function `z'(x', y') >= 0`
//!   (mm) over its local base plane (frame and anchor in [`shape`]), with its footprint,
//!   volume by Gauss-Legendre quadrature on a sine-mapped footprint, and a closed surface
//!   mesh for display and export.
//! - [`Catalog`]: the built-in generic catalog ([`Catalog::builtin`]: round low, moderate,
//!   high, extra-high profile; anatomic low/full height x moderate/full projection), user
//!   CSV catalogs ([`Catalog::load_csv`]), and [`Catalog::suggest`] (closest entries to
//!   given dimensions or a volume).
//! - [`ImplantSpec`]: the command line's implant specs (`round:diameter=115,projection=33`,
//!   `anatomic:width=120,height=113,projection=42`, `catalog:ID`).
//!
//! This crate knows nothing about patients, fill-ins or finite elements: placing an
//! implant on the chest wall and turning its thickness into displacement constraints is
//! done above it.
//!
//! # Units
//! Lengths in mm, volumes in ml (= cm³; quadrature results in mm³ say so).

pub mod catalog;
pub mod error;
pub mod quadrature;
pub mod shape;
pub mod spec;

pub use catalog::{Catalog, CatalogEntry, SuggestTarget, Suggestion};
pub use error::{CatalogError, ImplantError, SpecError};
pub use shape::{
    ANATOMIC_PEAK_HEIGHT_RATIO, ANATOMIC_PEAK_RATIO, AnatomicImplant, AnatomicTaper, Footprint,
    ImplantShape, PROJECTION_RANGE_MM, RoundImplant, RoundProfile, ShapeKind, WIDTH_RANGE_MM,
};
pub use spec::ImplantSpec;
