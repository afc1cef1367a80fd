//! The orchestration layer: loading scans and landmarks, measuring, registering, the
//! breast model, simulation, comparing scans and the demo pipeline. Both front ends (CLI, GUI) call only this crate;
//! it holds the glue, the algorithms live in the stage crates below it.

pub mod bench;
pub mod catalog;
pub mod compare;
pub mod demo;
pub mod fem_solve;
pub mod measure;
pub mod model;
pub mod register;
pub mod report;
pub mod scan;
pub mod simulate;
pub mod views;

pub use anatomy::measure::Distance;
pub use phantom::{Cup, PhantomParams};
pub use scan::{MarkedScan, Scan};

/// The error and its causes on one line, outermost first. A cause whose message the
/// previous one already ends with (errors that print their source) is not repeated.
pub fn one_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    for cause in error.chain() {
        let message = cause.to_string();
        if line.ends_with(&message) {
            continue;
        }
        if !line.is_empty() {
            line += ": ";
        }
        line += &message;
    }
    line
}

/// Receives progress of long operations (a terminal bar, a GUI, or nothing).
pub trait Progress: Sync {
    /// A new stage starts, with the number of steps it has.
    fn stage(&self, name: &str, steps: u64);
    /// One step of the current stage is done.
    fn step(&self);
    /// A warning for the user (e.g. a landmark snapped onto the surface).
    fn warn(&self, message: &str);
}

/// Progress that goes nowhere.
pub struct Silent;

impl Progress for Silent {
    fn stage(&self, _: &str, _: u64) {}
    fn step(&self) {}
    fn warn(&self, _: &str) {}
}
