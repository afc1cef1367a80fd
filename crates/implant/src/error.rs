//! Errors of the implant crate: impossible shapes, bad catalog files, bad implant specs.

use thiserror::Error;

/// An implant shape that cannot be built: a dimension that is not finite, outside the
/// accepted range, or a projection too large for the footprint.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ImplantError {
    /// A dimension is NaN or infinite.
    #[error("implant {what} is not a finite number ({value_mm} mm)")]
    NonFinite {
        /// Which dimension (`diameter`, `width`, `height`, `projection`).
        what: &'static str,
        /// The offending value (mm).
        value_mm: f64,
    },
    /// A dimension is outside the accepted range (zero and negative values land here).
    #[error("implant {what} {value_mm} mm is outside the accepted range {min_mm}-{max_mm} mm")]
    OutOfRange {
        /// Which dimension.
        what: &'static str,
        /// The offending value (mm).
        value_mm: f64,
        /// Smallest accepted value (mm).
        min_mm: f64,
        /// Largest accepted value (mm).
        max_mm: f64,
    },
    /// The projection exceeds half of the footprint's smaller extent: the shape would be
    /// taller than a hemisphere on its base.
    #[error(
        "implant projection {projection_mm} mm is larger than half the {limited_by} \
         ({limit_mm} mm)"
    )]
    ProjectionTooLarge {
        /// The projection (mm).
        projection_mm: f64,
        /// Half of the limiting dimension (mm).
        limit_mm: f64,
        /// The limiting dimension (`diameter`, `width` or `height`).
        limited_by: &'static str,
    },
    /// A catalog suggestion target outside the sizes an implant can have.
    #[error("suggestion target {what} must be from {min} to {max}, got {value}")]
    BadTarget {
        /// Which target value (`width_mm`, `height_mm`, `projection_mm`, `volume_ml`).
        what: &'static str,
        /// The offending value.
        value: f64,
        /// The accepted range.
        min: f64,
        max: f64,
    },
    /// A surface mesh resolution that cannot make a closed shell.
    #[error(
        "implant surface mesh needs at least {min_rings} rings and {min_segments} segments, \
         got {rings} rings and {segments} segments"
    )]
    MeshResolution {
        /// Requested rings.
        rings: usize,
        /// Requested segments per ring.
        segments: usize,
        /// Minimum rings.
        min_rings: usize,
        /// Minimum segments.
        min_segments: usize,
    },
}

/// A catalog that cannot be read: file errors, a bad header, a bad cell, duplicate ids.
/// `line` numbers are 1-based lines of the file (the header is line 1 when it is the first
/// line); `column` is the header name of the offending column.
#[derive(Debug, Error)]
pub enum CatalogError {
    /// The file cannot be opened or read.
    #[error("{source_name}: cannot read the catalog: {message}")]
    Io {
        /// File name (or a description of the source).
        source_name: String,
        /// The system's message.
        message: String,
    },
    /// The header row lacks a required column or repeats one.
    #[error("{source_name}: line {line}: bad header: {message}")]
    Header {
        /// File name.
        source_name: String,
        /// Line of the header.
        line: u64,
        /// What is wrong, with the expected columns.
        message: String,
    },
    /// A row that is not well-formed CSV (e.g. invalid UTF-8 or a broken quote).
    #[error("{source_name}: line {line}: {message}")]
    Row {
        /// File name.
        source_name: String,
        /// Line of the row.
        line: u64,
        /// What is wrong.
        message: String,
    },
    /// A cell with a bad value, or an implant that cannot be built from the row.
    #[error("{source_name}: line {line}, column {column_index} ({column}): {message}")]
    Field {
        /// File name.
        source_name: String,
        /// Line of the row.
        line: u64,
        /// Header name of the column.
        column: String,
        /// 1-based column number.
        column_index: usize,
        /// What is wrong and what was expected.
        message: String,
    },
    /// Two rows have the same id.
    #[error("{source_name}: line {line}: id `{id}` already used on line {first_line}")]
    DuplicateId {
        /// File name.
        source_name: String,
        /// Line of the second use.
        line: u64,
        /// The id.
        id: String,
        /// Line of the first use.
        first_line: u64,
    },
    /// The file has a header but no implant rows.
    #[error("{source_name}: the catalog has no implant rows")]
    Empty {
        /// File name.
        source_name: String,
    },
}

/// An implant spec (`round:diameter=115,projection=33`, `anatomic:width=..,height=..,
/// projection=..`, `catalog:ID`) that cannot be parsed or resolved.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum SpecError {
    /// No `kind:` prefix, or an unknown kind.
    #[error(
        "implant spec `{spec}`: expected `round:diameter=D,projection=P`, \
         `anatomic:width=W,height=H,projection=P` or `catalog:ID` (mm){detail}"
    )]
    Syntax {
        /// The whole spec.
        spec: String,
        /// Extra detail, starting with "; " when present.
        detail: String,
    },
    /// A `key=value` item with an unknown key.
    #[error("implant spec `{spec}`: unknown key `{key}` for a {kind} implant (allowed: {allowed})")]
    UnknownKey {
        /// The whole spec.
        spec: String,
        /// Implant kind.
        kind: &'static str,
        /// The unknown key.
        key: String,
        /// The allowed keys.
        allowed: &'static str,
    },
    /// A required key is missing.
    #[error("implant spec `{spec}`: missing `{key}=` for a {kind} implant")]
    MissingKey {
        /// The whole spec.
        spec: String,
        /// Implant kind.
        kind: &'static str,
        /// The missing key.
        key: &'static str,
    },
    /// A key given twice.
    #[error("implant spec `{spec}`: key `{key}` given twice")]
    DuplicateKey {
        /// The whole spec.
        spec: String,
        /// The key.
        key: String,
    },
    /// A value that is not a number (or not one of the allowed words).
    #[error("implant spec `{spec}`: `{key}={value}`: expected {expected}")]
    BadValue {
        /// The whole spec.
        spec: String,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
        /// What was expected.
        expected: &'static str,
    },
    /// The numbers parse but do not make an implant.
    #[error("implant spec `{spec}`: {source}")]
    Invalid {
        /// The whole spec.
        spec: String,
        /// Why the shape is impossible.
        source: ImplantError,
    },
    /// `catalog:ID` names an id the catalog does not have.
    #[error(
        "implant spec `{spec}`: unknown catalog id `{id}` (the catalog has {count} entries{hint})"
    )]
    UnknownCatalogId {
        /// The whole spec.
        spec: String,
        /// The id.
        id: String,
        /// Number of catalog entries.
        count: usize,
        /// Close ids, starting with "; did you mean " when present.
        hint: String,
    },
}
