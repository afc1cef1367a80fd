//! `mammaplan catalog`: the built-in catalog of generic implant shapes or a user's CSV
//! catalog (e.g. a manufacturer's table), listed or searched for the entries closest to
//! given dimensions or a target volume (paper VI-B: "suggest an implant which matches
//! best").

use anyhow::{Context, Result};
pub use implant::{
    AnatomicImplant, Catalog, CatalogEntry, ImplantShape, ImplantSpec, PROJECTION_RANGE_MM,
    RoundImplant, ShapeKind, SuggestTarget, Suggestion, WIDTH_RANGE_MM,
};
use serde::Serialize;
use std::path::Path;

/// The user's CSV catalog if given, else the built-in one.
pub fn load(csv: Option<&Path>) -> Result<Catalog> {
    match csv {
        Some(path) => Catalog::load_csv(path).with_context(|| "reading the implant catalog"),
        None => Ok(Catalog::builtin()),
    }
}

/// What `catalog list --json` prints.
#[derive(Debug, Serialize)]
pub struct CatalogListing<'a> {
    /// `builtin` or the CSV file's path.
    pub source: String,
    pub entries: &'a [CatalogEntry],
}

/// What `catalog suggest --json` prints: the best entries first.
#[derive(Debug, Serialize)]
pub struct SuggestReport<'a> {
    pub source: String,
    pub suggestions: Vec<Suggestion<'a>>,
}

/// The `count` entries of `catalog` closest to `target`, of one shape kind if given.
pub fn suggest<'a>(
    catalog: &'a Catalog,
    source: String,
    target: &SuggestTarget,
    kind: Option<ShapeKind>,
    count: usize,
) -> Result<SuggestReport<'a>> {
    let suggestions = catalog
        .suggest(target, kind, count)
        .context("suggesting implants")?;
    Ok(SuggestReport {
        source,
        suggestions,
    })
}
