//! Parsing the command line.

use crate::Cli;
use clap::{CommandFactory, FromArgMatches};

/// The command line, with negative numbers read as values wherever an option takes one
/// (`--elements -5` is then refused by the option's own check, which names it, rather
/// than read as an unknown flag).
pub fn parse_command_line() -> Cli {
    let matches = command().get_matches();
    Cli::from_arg_matches(&matches).unwrap_or_else(|error| error.exit())
}

/// The command-line definition: [`Cli`] with negative numbers allowed as values.
fn command() -> clap::Command {
    fn negative_numbers(command: clap::Command) -> clap::Command {
        command
            .mut_args(|arg| {
                // only where a value follows: clap refuses the setting on a flag
                let takes_values = arg.get_action().takes_values();
                arg.allow_negative_numbers(takes_values)
            })
            .mut_subcommands(negative_numbers)
    }
    negative_numbers(Cli::command())
}

#[cfg(test)]
mod tests {
    /// Clap's own consistency checks, which release builds skip: a setting clap refuses
    /// (negative numbers on a flag) made every command of a debug build panic.
    #[test]
    fn the_command_line_passes_clap_s_checks() {
        super::command().debug_assert();
    }
}
