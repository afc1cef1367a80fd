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

/// This program's version and the git commit it was built from, `0.1.0 (commit
/// 0123456789ab)` (the version alone when built outside a git checkout).
pub const VERSION: &str = env!("MAMMAPLAN_VERSION");

/// The program that writes a folder, as its records name it: `mammaplan ` and
/// [`VERSION`].
pub fn software() -> String {
    format!("mammaplan {VERSION}")
}

/// Writes pretty JSON atomically (a temporary file renamed into place).
pub fn write_json(path: &std::path::Path, value: &impl serde::Serialize) -> anyhow::Result<()> {
    mesh::io::write_atomically(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value)?;
        std::io::Write::write_all(w, b"\n")
    })?;
    Ok(())
}

/// The error and its causes on one line, outermost first. A cause its parent already
/// prints (at the parent's end, or after a colon and followed by advice) is not repeated.
pub fn one_line(error: &anyhow::Error) -> String {
    let mut line = String::new();
    let mut parent = String::new();
    for cause in error.chain() {
        let message = cause.to_string();
        let printed = parent.ends_with(&message) || parent.contains(&format!(": {message}"));
        if !printed {
            if !line.is_empty() {
                line += ": ";
            }
            line += &message;
        }
        parent = message;
    }
    line
}

#[cfg(test)]
mod tests {
    use super::one_line;

    use std::fmt;

    #[derive(Debug)]
    struct Message(&'static str);

    impl fmt::Display for Message {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str(self.0)
        }
    }

    impl std::error::Error for Message {}

    /// An error that prints its source, then advice.
    #[derive(Debug)]
    struct PrintsItsSource {
        source: Message,
    }

    impl fmt::Display for PrintsItsSource {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "the curve failed: {}; move the point", self.source)
        }
    }

    impl std::error::Error for PrintsItsSource {
        fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
            Some(&self.source)
        }
    }

    #[test]
    fn a_cause_is_said_once_and_only_a_printed_one_is_left_out() {
        // The parent prints its source before its advice: said once.
        let error = anyhow::Error::new(PrintsItsSource {
            source: Message("it leaves the scan"),
        })
        .context("building the model");
        assert_eq!(
            one_line(&error),
            "building the model: the curve failed: it leaves the scan; move the point"
        );
        // A cause whose words merely occur earlier in the line (here in a path) is kept.
        let error = anyhow::Error::new(Message("cancelled"))
            .context("/data/cancelled/scan.ply: reading the scan");
        assert_eq!(
            one_line(&error),
            "/data/cancelled/scan.ply: reading the scan: cancelled"
        );
    }
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
