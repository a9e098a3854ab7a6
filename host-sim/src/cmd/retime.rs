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
//! phase 1 stays as planned (it already is the shortest quintic within `[preshape]`'s
//! acceleration limit and the wheels' bounds, which a faster phase 1 would break), phase 2
//! is re-timed as any plan into `OUT/phase2/`, and OUT holds the rest of DIR's files, so
//! `check OUT` verifies phase 1, the join and the re-timed phase 2. Refused when phase 1's
//! acceleration limit is above the re-timing's for some joint (phase 1 would exceed it).

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
        if crate::artifacts::is_two_phase(&self.dir) {
            return self.two_phase();
        }
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
        let (s, path) = with_dims!(
            lt.chain.dof(),
            run_n,
            &lt,
            &eta,
            self.accel_deg_s2,
            self.grid,
            &self.out,
            self.plots
        )?;
        eprintln!(
            "retime: {:.2} s (was {:.2} s), base disturbance = {} deg -> {}",
            s.duration_s,
            s.original_duration_s,
            number(s.base_disturbance_deg),
            path.display()
        );
        Ok(())
    }
}

impl Args {
    /// A two-phase DIR: phase 1 as planned, phase 2 re-timed into `OUT/phase2/`.
    fn two_phase(&self) -> Result<(), CliError> {
        use crate::artifacts::{PHASE1_CSV, PHASE2_DIR, phase2_dir};
        let read = |dir: &Path, name: &str| {
            std::fs::read_to_string(dir.join(name))
                .or_input(|| format!("{}: cannot read {name}", dir.display()))
        };
        let lt = taskfile::from_texts(
            &self.dir.join(BUNDLE_TASK),
            &read(&self.dir, BUNDLE_TASK)?,
            &read(&self.dir, BUNDLE_URDF)?,
        )?;
        let section = lt.file.preshape.ok_or_else(|| {
            CliError::input(format!(
                "{}: {BUNDLE_TASK} has no [preshape]",
                self.dir.display()
            ))
        })?;
        let p2 = phase2_dir(&self.dir);
        let lt2 = taskfile::from_texts(
            &p2.join(BUNDLE_TASK),
            &read(&p2, BUNDLE_TASK)?,
            &read(&p2, BUNDLE_URDF)?,
        )?;
        let summary: serde_json::Value = serde_json::from_str(&read(&p2, "summary.json")?)
            .or_input(|| format!("{}: summary.json", p2.display()))?;
        let eta: Vec<f64> = summary
            .get("eta")
            .and_then(|v| serde_json::from_value(v.clone()).ok())
            .ok_or_else(|| CliError::input(format!("{}: summary.json has no eta", p2.display())))?;
        // Phase 1 moves at up to [preshape]'s acceleration limit: the re-timing's must not be
        // lower, or the whole plan would break it in phase 1.
        if let Some(qdd) = lt2.qdd_values(self.accel_deg_s2, lt2.chain.dof())? {
            if let Some((j, a)) = qdd
                .iter()
                .enumerate()
                .find(|(_, a)| **a < section.qdd_max_deg_s2)
            {
                return Err(CliError::input(format!(
                    "{}: phase 1 was planned at [preshape] qdd_max_deg_s2 = {}, above the re-timing's acceleration limit {a} deg/s² of joint {}: plan again with [preshape] qdd_max_deg_s2 ≤ {a}",
                    self.dir.display(),
                    section.qdd_max_deg_s2,
                    j + 1
                )));
            }
        }
        let dir = OutDir::create(&self.out)?;
        for name in [BUNDLE_TASK, BUNDLE_URDF, PHASE1_CSV, "plan.json"] {
            let bytes = std::fs::read(self.dir.join(name))
                .or_input(|| format!("{}: cannot read {name}", self.dir.display()))?;
            dir.write(name, &bytes)?;
        }
        let plan: serde_json::Value = serde_json::from_str(&read(&self.dir, "plan.json")?)
            .or_input(|| format!("{}: plan.json", self.dir.display()))?;
        let phase1_s = plan
            .pointer("/phase1/duration_s")
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(f64::NAN);
        let (s, _) = with_dims!(
            lt2.chain.dof(),
            run_n,
            &lt2,
            &eta,
            self.accel_deg_s2,
            self.grid,
            &dir.path(PHASE2_DIR),
            self.plots
        )?;
        let path = dir.commit()?;
        eprintln!(
            "retime: two phases, {:.2} s: phase 1 {phase1_s:.2} s as planned (attitude controlled), phase 2 re-timed to {:.2} s (was {:.2} s), base disturbance = {} deg -> {}",
            phase1_s + s.duration_s,
            s.duration_s,
            s.original_duration_s,
            number(s.base_disturbance_deg),
            path.display()
        );
        Ok(())
    }
}

/// Re-times `eta` of `lt` into `out` through [`retiming::write`], which `plan --retime`
/// calls too; its summary and where it went.
pub fn run_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
    out: &Path,
    plots: bool,
) -> Result<(retiming::RetimeSummary, std::path::PathBuf), CliError> {
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
    Ok((s, path))
}
