//! `host-sim block TASK --out FILE`: the task block that the flight image and C clients
//! load, written to a file.
//!
//! The bytes are exactly those `host-sim target` gives QEMU ([`crate::flight::task_block`]):
//! the task, robot and planner settings for the flight robot (7 joints), little-endian,
//! CRC-32 last (layout in `reactionless::block`). A C client loads them with
//! `rl_planner_load_block` (`ffi/include/reactionless.h`). Written atomically.

use crate::args::PlanArgs;
use crate::error::CliError;
use crate::flight::task_block;
use crate::output::{FileKind, write_file};
use crate::taskfile;
use std::path::PathBuf;

/// Write the task block of a task file (for the flight robot, 7 joints): the bytes the
/// flight image and C clients (`rl_planner_load_block`) load.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML) for the flight robot (7 joints).
    task: PathBuf,
    /// Block file to write (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    planning: PlanArgs,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let mut lt = taskfile::load(&self.task)?;
        lt.set_integrator(self.planning.integrator)?;
        let block = task_block(&lt, &self.planning.overrides())?;
        write_file(&self.out, &block, FileKind::Block)?;
        eprintln!(
            "block: {} bytes ({}) -> {}",
            block.len(),
            self.task.display(),
            self.out.display()
        );
        Ok(())
    }
}
