//! The planning report (issue 7): what it shows as plain data ([`ReportContent`]) and
//! one self-contained, printable HTML page of it ([`render_html`]).
//!
//! Pure presentation: this crate computes nothing about scans or simulations and knows
//! no other crate of the workspace; `plan` fills the content. The page fetches nothing
//! (style sheet inline, images as `data:` URIs, labels and legends as inline SVG), so it
//! can be filed, mailed and printed as one file.

mod content;
mod html;
mod png;

pub use content::{
    BreastVolumes, CaseFile, CaseInfo, CatalogReference, ColourScale, ColourStop, Comparison,
    DEVIATION_SCALE_MAX_MM, DeviationFigures, ImageLabel, ImplantChoice, MaterialParameters,
    MeasurementRow, ModelParameters, PerSide, QuadrantVolumes, ReportContent, SolverSummary,
    SymmetryRow, View, VolumeTable,
};
pub use html::render_html;
pub use png::PngError;
