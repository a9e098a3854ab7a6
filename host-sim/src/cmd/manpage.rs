//! `host-sim manpage --out DIR`: man pages from the clap definitions (`host-sim.1` and one
//! `host-sim-SUBCOMMAND.1` per subcommand), written atomically.

use crate::error::{CliError, Context};
use crate::output::OutDir;
use std::path::PathBuf;

/// Write man pages (roff) for host-sim and every subcommand into DIR.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (replaced atomically); read with `man -l DIR/host-sim.1`.
    #[arg(long)]
    out: PathBuf,
}

fn render(cmd: clap::Command) -> Result<Vec<u8>, CliError> {
    let mut buf = Vec::new();
    clap_mangen::Man::new(cmd)
        .render(&mut buf)
        .or_internal(|| "man page")?;
    Ok(buf)
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let dir = OutDir::create(&self.out)?;
        let top = crate::cli::command();
        dir.write("host-sim.1", &render(top.clone())?)?;
        let mut written = 1;
        for sub in top.get_subcommands() {
            let name = format!("host-sim-{}", sub.get_name());
            dir.write(
                &format!("{name}.1"),
                &render(sub.clone().name(name.clone()))?,
            )?;
            written += 1;
        }
        let path = dir.commit()?;
        eprintln!("manpage: {written} pages -> {}", path.display());
        Ok(())
    }
}
