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

use crate::args::parse_eta;
use crate::error::{CliError, Context};
use crate::goal::number;
use crate::output::OutDir;
use crate::retiming;
use crate::taskfile::{self, BUNDLE_TASK, BUNDLE_URDF, LoadedTask};
use crate::with_dims;
use std::path::{Path, PathBuf};

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
        let read = |name: &str| {
            std::fs::read_to_string(self.dir.join(name)).map_err(|e| {
                CliError::input(format!(
                    "{}: cannot read {name}: {e} (give the --out directory of plan or rollout)",
                    self.dir.display()
                ))
            })
        };
        let lt = taskfile::from_texts(
            &self.dir.join(BUNDLE_TASK),
            &read(BUNDLE_TASK)?,
            &read(BUNDLE_URDF)?,
        )?;
        let summary: serde_json::Value = serde_json::from_str(&read("summary.json")?)
            .or_input(|| format!("{}: summary.json", self.dir.display()))?;
        let eta: Vec<f64> = summary
            .get("eta")
            .and_then(|v| serde_json::from_value(v.clone()).ok())
            .ok_or_else(|| {
                CliError::input(format!("{}: summary.json has no eta", self.dir.display()))
            })?;
        with_dims!(
            lt.chain.dof(),
            run_n,
            &lt,
            &eta,
            self.accel_deg_s2,
            self.grid,
            &self.out,
            self.plots
        )
    }
}

/// Re-times `eta` of `lt` into `out` through [`retiming::write`], which `plan --retime`
/// calls too.
pub fn run_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
    out: &Path,
    plots: bool,
) -> Result<(), CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(eta)?;
    let qdd = lt.qdd_max_deg::<N>(accel_deg_s2)?.ok_or_else(|| {
        CliError::input(format!(
            "{}: no acceleration limits: give --accel-deg-s2 or set [limits] qdd_max_deg_s2",
            lt.path.display()
        ))
    })?;
    let grid = grid.unwrap_or(lt.file.retime.grid);
    let dir = OutDir::create(out)?;
    let s = retiming::write(
        lt,
        &task,
        &eta,
        &qdd,
        grid,
        lt.file.retime.margin,
        &dir,
        plots,
    )?;
    let path = dir.commit()?;
    eprintln!(
        "retime: {:.2} s (was {:.2} s), base disturbance = {} deg -> {}",
        s.duration_s,
        s.original_duration_s,
        number(s.base_disturbance_deg),
        path.display()
    );
    Ok(())
}
