//! `host-sim completions SHELL`: shell completions from the clap definitions, on stdout.

use crate::error::CliError;
use clap_complete::Shell;

/// Print shell completions (bash, zsh, fish, elvish, powershell) to stdout, e.g.
/// `host-sim completions bash > ~/.local/share/bash-completion/completions/host-sim`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The shell.
    shell: Shell,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let mut cmd = crate::cli::command();
        clap_complete::generate(self.shell, &mut cmd, "host-sim", &mut std::io::stdout());
        Ok(())
    }
}
