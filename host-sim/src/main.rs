//! The `host-sim` command line: one leaf per subcommand (see `host_sim::cmd`).

use clap::{Parser, Subcommand};
use host_sim::cmd;
use std::process::ExitCode;

/// Host simulator for the reactionless planner.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, long_about = None)]
struct Cli {
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
    Record(cmd::record::Args),
    Replay(cmd::replay::Args),
    Generate(cmd::generate::Args),
    Frames(cmd::frames::Args),
    Campaign(cmd::campaign::Args),
    Target(cmd::target::Args),
    Bench(cmd::bench::Args),
}

fn main() -> ExitCode {
    let result = match Cli::parse().command {
        Command::Model(a) => a.run(),
        Command::Rollout(a) => a.run(),
        Command::Plan(a) => a.run(),
        Command::Check(a) => a.run(),
        Command::Record(a) => a.run(),
        Command::Replay(a) => a.run(),
        Command::Generate(a) => a.run(),
        Command::Frames(a) => a.run(),
        Command::Campaign(a) => a.run(),
        Command::Target(a) => a.run(),
        Command::Bench(a) => a.run(),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.code)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::Cli;
    use clap::CommandFactory;

    /// Clap's own consistency checks of every subcommand's arguments (a type mismatch
    /// between a value parser and its field panics only when the flag is used).
    #[test]
    fn the_command_line_is_consistent() {
        Cli::command().debug_assert();
    }
}
