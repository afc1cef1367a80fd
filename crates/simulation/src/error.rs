//! Errors of the simulation crate.

use anatomy::breast::Side;
use thiserror::Error;

/// Everything that can go wrong when placing an implant, building its template, solving
/// or measuring the result.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SimulationError {
    /// The implant's footprint does not fit on its bed (the pocket, or the fill-in).
    #[error(
        "{side} breast: the implant's footprint ({width_mm:.0} x {height_mm:.0} mm) does not fit \
         in the pocket behind the breast: its outline reaches {outside_mm:.1} mm beyond it \
         near {near_mm:.0?} (standing frame, mm); choose a smaller implant or move it"
    )]
    ImplantLargerThanFootprint {
        side: Side,
        /// Footprint width of the implant (mm).
        width_mm: f64,
        /// Footprint height of the implant (mm).
        height_mm: f64,
        /// How far the outline's worst point lies outside the fill-in (mm, along the
        /// surface).
        outside_mm: f64,
        /// That point in the anatomical frame (mm, relative to Pj).
        near_mm: [f64; 3],
    },
    /// The implant reaches past one of its pocket's anatomical limits.
    #[error(
        "{side} breast: the implant reaches {beyond_mm:.0} mm past {limit}, which limits the \
         pocket; choose a narrower implant or move it away from there"
    )]
    PocketLimit {
        side: Side,
        /// "the sternal midline region", "the anterior axillary line" or "the planned fold".
        limit: &'static str,
        beyond_mm: f64,
    },
    /// The anchor (after the moves) left the fill-in.
    #[error(
        "{side} breast: the implant anchor moved off the fill-in behind the breast \
         (after moving {moved_mm:.0} mm along it); move it less far"
    )]
    AnchorOffFillIn { side: Side, moved_mm: f64 },
    /// A placement parameter is out of range.
    #[error("{side} breast: placement {what} = {value} is out of range: {expected}")]
    BadPlacement {
        side: Side,
        what: &'static str,
        value: f64,
        expected: String,
    },
    /// The fill-in behind a breast cannot serve as the implant bed.
    #[error("{side} breast: the fill-in cannot carry an implant: {reason}")]
    BadFillIn { side: Side, reason: String },
    /// The tetrahedral hierarchy does not fit the breast model.
    #[error("the tetrahedral model: {0}")]
    BadModel(String),
    /// A setting is out of range.
    #[error("simulation option {what} = {value} is out of range: {expected}")]
    BadOption {
        what: &'static str,
        value: f64,
        expected: &'static str,
    },
    /// The finite element solver failed.
    #[error("finite elements: {0}")]
    Fem(#[from] fem::FemError),
    /// The template holds no implant vertex: the implant thickness reached no element
    /// of the finest level (a mesh far too coarse for the implant).
    #[error(
        "{side} breast: no element of the finest level lies in front of the implant bed inside \
         the implant's footprint; the tetrahedral mesh is too coarse for this implant"
    )]
    EmptyTemplate { side: Side },
}
