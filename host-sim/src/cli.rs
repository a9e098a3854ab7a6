//! The command line: the top-level parser and the list of subcommands, one leaf each in
//! [`crate::cmd`]. A new subcommand is its file plus two lines here (the variant and its
//! `run` arm).

use crate::cmd;
use crate::error::CliError;
use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

/// Host simulator for the reactionless planner.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, long_about = None)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands; each variant's arguments and doc live in its `cmd/` file.
#[derive(Debug, Subcommand)]
enum Command {
    Model(cmd::model::Args),
    Rollout(cmd::rollout::Args),
    Plan(cmd::plan::Args),
    Check(cmd::check::Args),
    Retime(cmd::retime::Args),
    Record(cmd::record::Args),
    Replay(cmd::replay::Args),
    Generate(cmd::generate::Args),
    Frames(cmd::frames::Args),
    Campaign(cmd::campaign::Args),
    Disperse(cmd::disperse::Args),
    Merge(cmd::merge::Args),
    Target(cmd::target::Args),
    Block(cmd::block::Args),
    Bench(cmd::bench::Args),
    Completions(cmd::completions::Args),
    Manpage(cmd::manpage::Args),
    View(cmd::view::Args),
}

/// The command line as parsed: every option that takes a value accepts a negative number
/// after a space (`--seed -1`, `--refine-tolerance -1e-6` reach the value's own check, which
/// names the flag, instead of being taken for an unknown flag `-1`). clap's own test of a
/// negative number does not take an exponent with a sign (`-1e-6`), so an option whose
/// value is an `f64` takes any value that starts with `-`.
pub fn command() -> clap::Command {
    let f64_id = std::any::TypeId::of::<f64>();
    Cli::command().mut_subcommands(|sc| {
        sc.mut_args(|a| {
            if !a.get_action().takes_values() || a.is_positional() {
                a
            } else if a.get_value_parser().type_id() == f64_id {
                a.allow_hyphen_values(true)
            } else {
                a.allow_negative_numbers(true)
            }
        })
    })
}

/// Parses the command line, runs the subcommand, maps the result to the exit code (0
/// success, 1 a result that does not pass, 2 bad input).
pub fn main() -> ExitCode {
    let cli = match Cli::from_arg_matches(&command().get_matches()) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    match dispatch(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.code)
        }
    }
}

/// Runs one command line given as words (`["host-sim", "disperse", DIR, ...]`) in this
/// process, as the binary would: the library entry of callers that wrap the CLI (the
/// Python package's `disperse` and `retime`). A command line clap refuses is bad input,
/// with clap's message.
///
/// # Errors
/// The subcommand's, or bad input for a command line that does not parse.
pub fn run_args<I, T>(args: I) -> Result<(), CliError>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let matches = command()
        .try_get_matches_from(args)
        .map_err(|e| CliError::input(e.render().to_string().trim_end().to_string()))?;
    let cli = Cli::from_arg_matches(&matches).map_err(|e| CliError::input(e.to_string()))?;
    dispatch(cli)
}

fn dispatch(cli: Cli) -> Result<(), CliError> {
    // A bad REACTIONLESS_ISA is bad input, whatever the subcommand.
    reactionless_simd::Isa::from_env().map_err(|e| CliError::input(e.to_string()))?;
    match cli.command {
        Command::Model(a) => a.run(),
        Command::Rollout(a) => a.run(),
        Command::Plan(a) => a.run(),
        Command::Check(a) => a.run(),
        Command::Retime(a) => a.run(),
        Command::Record(a) => a.run(),
        Command::Replay(a) => a.run(),
        Command::Generate(a) => a.run(),
        Command::Frames(a) => a.run(),
        Command::Campaign(a) => a.run(),
        Command::Disperse(a) => a.run(),
        Command::Merge(a) => a.run(),
        Command::Target(a) => a.run(),
        Command::Block(a) => a.run(),
        Command::Bench(a) => a.run(),
        Command::Completions(a) => a.run(),
        Command::Manpage(a) => a.run(),
        Command::View(a) => a.run(),
    }
}

#[cfg(test)]
mod tests {
    /// Clap's own consistency checks of every subcommand's arguments (a type mismatch
    /// between a value parser and its field panics only when the flag is used).
    #[test]
    fn the_command_line_is_consistent() {
        super::command().debug_assert();
    }
}
