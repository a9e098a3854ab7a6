//! `host-sim retime DIR --out OUT`: the plan or rollout in DIR re-timed to minimum time
//! under the joint rate limits (URDF) and acceleration limits (`[limits] qdd_max_deg_s2`
//! or `--accel-deg-s2`), rest to rest, along the same geometric path (spec §10).
//!
//! Reads DIR's self-contained bundle (`task.toml`, `robot.urdf`) and the η of its
//! `summary.json`; writes OUT atomically: `trajectory.csv` (`t,q1..qN,qd1..qdN,qdd1..qddN`,
//! every `dt` from 0 to the new duration, rounded up to a whole step), `summary.json`
//! (durations, per-joint largest rates and accelerations with the limits used, base
//! disturbance from the truth model, end pose and f, setpoint digest) and the bundle with
//! the limits and grid used, which `host-sim check OUT` verifies.
//!
//! A two-phase plan (`phase1.csv` beside `phase2/`, docs/twophase.md) is re-timed whole:
//! phase 1 stays as planned (it already is the fastest path within `[preshape]`'s
//! acceleration limit and the wheels' bounds, which a faster phase 1 would break), phase 2
//! is re-timed as any plan into `OUT/phase2/`, and OUT holds the rest of DIR's files, so
//! `check OUT` verifies phase 1, the join and the re-timed phase 2. Refused when phase 1's
//! acceleration limit is above the re-timing's for some joint (phase 1 would exceed it).

use crate::error::CliError;
use crate::retiming;
use std::path::PathBuf;

/// Re-time the plan or rollout in DIR to minimum time under rate and acceleration limits.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory of `plan` or `rollout`.
    dir: PathBuf,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Acceleration limit of every joint (deg/s²); default: the task's
    /// `[limits] qdd_max_deg_s2`.
    #[arg(long)]
    accel_deg_s2: Option<f64>,
    /// Arc-length grid points; default: the task's `[retime] grid` (2000).
    #[arg(long, value_parser = crate::args::parse_u32)]
    grid: Option<u32>,
    /// Also write figures of the rates and accelerations against their limits.
    #[arg(long)]
    plots: bool,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        if crate::artifacts::is_two_phase(&self.dir) {
            let (phase1_s, s, path) = retiming::retime_two_phase(
                &self.dir,
                self.accel_deg_s2,
                self.grid,
                &self.out,
                self.plots,
            )?;
            eprintln!("{}", retiming::describe_two_phase(phase1_s, &s, &path));
            return Ok(());
        }
        let (s, path) = retiming::retime_bundle(
            &self.dir,
            self.accel_deg_s2,
            self.grid,
            &self.out,
            self.plots,
        )?;
        eprintln!("{}", retiming::describe(&s, &path));
        Ok(())
    }
}
