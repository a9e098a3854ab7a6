//! `host-sim view DIR --out FILE.html`: the 3-D replay page of a `plan` or `rollout`
//! output directory (see [`crate::view`] and docs/view.md).

use crate::error::CliError;
use crate::view;
use std::path::PathBuf;

/// Write a self-contained 3-D replay page (one HTML file, nothing loaded from the network)
/// of a plan or rollout directory; FILE.html?t=T shows time T.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory of `plan` or `rollout`.
    dir: PathBuf,
    /// The page to write (HTML).
    #[arg(long)]
    out: PathBuf,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        view::write_dir(&self.dir, &self.out)?;
        eprintln!(
            "view: {} -> {} (open it in a browser; ?t=T shows time T)",
            self.dir.display(),
            self.out.display()
        );
        Ok(())
    }
}
