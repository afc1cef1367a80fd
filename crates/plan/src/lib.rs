//! The orchestration layer: loading scans and landmarks, measuring, registering, the
//! breast model, the simulation session, planning cases, comparing scans, the report and the
//! demo pipeline. Both front ends (CLI, GUI) call only this crate; it holds the glue, the
//! algorithms live in the stage crates below it.

pub mod bench;
pub mod case;
pub mod catalog;
mod checksum;
pub mod compare;
pub mod demo;
mod failure_place;
pub mod fem_solve;
pub mod measure;
pub mod model;
mod per_side;
mod record_check;
pub mod register;
pub mod report;
pub mod scan;
pub mod simulate;
mod staged;
pub mod texture;
pub mod views;

pub use anatomy::measure::Distance;
pub use anatomy::{Up, UpSource};
pub use failure_place::{Place, failure_place};
pub use mesh::LengthUnit;
pub use phantom::{Cup, PhantomParams};
pub use scan::{MarkedScan, Scan, UpRecord, UpSourceName};

/// Writes pretty JSON atomically (a temporary file renamed into place).
pub fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    mesh::io::write_atomically(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value)?;
        std::io::Write::write_all(w, b"\n")
    })?;
    Ok(())
}

/// The error and its causes on one line, outermost first. A cause whose message the line
/// already holds (errors that print their source, some followed by advice) is not
/// repeated.
pub fn one_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let message = cause.to_string();
        if line.contains(&message) {
            continue;
        }
        if !line.is_empty() {
            line += ": ";
        }
        line += &message;
    }
    line
}

/// Receives progress of long operations (a terminal bar, a GUI, or nothing) and may ask
/// them to stop.
pub trait Progress: Sync {
    /// A new stage starts, with the number of steps it has.
    fn stage(&self, name: &str, steps: u64);
    /// One step of the current stage is done.
    fn step(&self);
    /// A warning for the user (e.g. a landmark snapped onto the surface).
    fn warn(&self, message: &str);
    /// Whether the user asked to stop. Long operations ask between their stages and then
    /// return the error [`Cancelled`] (cooperative: a stage under way runs to its end).
    fn cancelled(&self) -> bool {
        false
    }
}

/// The error of an operation stopped because [`Progress::cancelled`] said so; find it
/// in an `anyhow` chain with `error.chain().any(|cause| cause.is::<Cancelled>())`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Cancelled;

impl std::fmt::Display for Cancelled {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("cancelled")
    }
}

impl std::error::Error for Cancelled {}

/// `Err(Cancelled)` once `progress` asks to stop.
pub fn check_cancelled(progress: &dyn Progress) -> Result<(), Cancelled> {
    if progress.cancelled() {
        Err(Cancelled)
    } else {
        Ok(())
    }
}

/// Progress that goes nowhere.
pub struct Silent;

impl Progress for Silent {
    fn stage(&self, _: &str, _: u64) {}
    fn step(&self) {}
    fn warn(&self, _: &str) {}
}
