//! A progress that keeps the warnings, for tests that check what the user is told.

use plan::Progress;
use std::sync::Mutex;

/// Collects warnings.
#[derive(Default)]
pub struct Warnings(pub Mutex<Vec<String>>);

impl Progress for Warnings {
    fn stage(&self, _: &str, _: u64) {}
    fn step(&self) {}
    fn warn(&self, message: &str) {
        self.0.lock().unwrap().push(message.to_string());
    }
}
