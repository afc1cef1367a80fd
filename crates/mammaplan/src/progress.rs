//! Progress bars on a terminal (indicatif); no bar with `--quiet` or when stderr is not a
//! terminal. Warnings are printed unless `--quiet`.

use indicatif::{ProgressBar, ProgressStyle};
use std::io::IsTerminal;
use std::time::Duration;

pub struct TerminalProgress {
    quiet: bool,
    /// The one bar, reused stage after stage; `None` when bars are off.
    bar: Option<ProgressBar>,
}

impl TerminalProgress {
    pub fn new(quiet: bool) -> TerminalProgress {
        let bar = (!quiet && std::io::stderr().is_terminal()).then(|| {
            let bar = ProgressBar::hidden();
            if let Ok(style) =
                ProgressStyle::with_template("{spinner} {msg:12} [{bar:30}] {pos}/{len} {elapsed}")
            {
                bar.set_style(style.progress_chars("=> "));
            }
            bar
        });
        TerminalProgress { quiet, bar }
    }

    /// Clears the bar before normal output.
    pub fn finish(&self) {
        if let Some(bar) = &self.bar {
            bar.finish_and_clear();
        }
    }
}

impl plan::Progress for TerminalProgress {
    fn stage(&self, name: &str, steps: u64) {
        if let Some(bar) = &self.bar {
            bar.set_draw_target(indicatif::ProgressDrawTarget::stderr());
            bar.set_length(steps);
            bar.set_position(0);
            bar.set_message(name.to_string());
            bar.enable_steady_tick(Duration::from_millis(120));
        }
    }

    fn step(&self) {
        if let Some(bar) = &self.bar {
            bar.inc(1);
        }
    }

    fn warn(&self, message: &str) {
        match &self.bar {
            _ if self.quiet => {}
            Some(bar) if !bar.is_hidden() => bar.println(format!("warning: {message}")),
            _ => eprintln!("warning: {message}"),
        }
    }
}
