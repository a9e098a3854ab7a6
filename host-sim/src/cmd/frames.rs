//! `host-sim frames`: the planner under a cyclic executive, on the host.
//!
//! Every frame gives the planner at most `--frame-budget` integration steps
//! ([`reactionless::Planner::step`]); this reports how many frames planning takes, the
//! budget actually used per frame (max and mean; never above the budget) and the wall time
//! per frame on this machine (max and mean).

use crate::args::PlanArgs;
use crate::drive::HOST_CAPACITY;
use crate::error::{CliError, Context};
use crate::goal::number;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use reactionless::{Planner, Status};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The report.
#[derive(Debug, Serialize, schemars::JsonSchema)]
pub struct FramesJson {
    /// Budget per frame (integration steps).
    pub frame_budget: u32,
    /// Frames until the planner finished.
    pub frames: u64,
    /// Largest budget used in one frame.
    pub max_steps_per_frame: u64,
    /// Mean budget used per frame.
    pub mean_steps_per_frame: f64,
    /// Longest frame (ms, this machine).
    pub max_frame_ms: f64,
    /// Mean frame (ms, this machine).
    pub mean_frame_ms: f64,
    /// Whether the plan converged.
    pub converged: bool,
    /// C-PSO iterations.
    pub iterations: u32,
    /// Rollouts.
    pub rollouts: u32,
    /// f of the plan.
    pub f: f64,
}

/// Plan under a cyclic executive: at most FRAME_BUDGET integration steps per frame;
/// report frames, steps per frame and wall time per frame.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML).
    task: PathBuf,
    /// Integration steps per frame (default: the task's `[planner] frame_budget`).
    #[arg(long, value_parser = crate::args::parse_u32)]
    frame_budget: Option<u32>,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    planning: PlanArgs,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        run(
            &self.task,
            self.frame_budget,
            self.json,
            &self.planning.overrides(),
        )
    }
}

fn run(
    task_path: &Path,
    frame_budget: Option<u32>,
    json: bool,
    overrides: &Overrides,
) -> Result<(), CliError> {
    if frame_budget == Some(0) {
        return Err(CliError::input(
            "--frame-budget 0: must be at least 1 integration step",
        ));
    }
    let mut lt = taskfile::load(task_path)?;
    lt.set_integrator(overrides.integrator)?;
    let frame_budget = frame_budget.unwrap_or(lt.file.planner.frame_budget);
    let report = with_dims!(lt.chain.dof(), frames_n, &lt, frame_budget, overrides)?;
    if json {
        println!(
            "{}",
            serde_json::to_string(&report).or_internal(|| "report JSON")?
        );
    } else {
        println!("frame budget       {:>10} steps", report.frame_budget);
        println!("frames             {:>10}", report.frames);
        println!(
            "steps per frame    {:>10} max, {:.1} mean",
            report.max_steps_per_frame, report.mean_steps_per_frame
        );
        println!(
            "frame wall time    {:>10.3} ms max, {:.3} ms mean",
            report.max_frame_ms, report.mean_frame_ms
        );
        println!(
            "result             {:>10} after {} iterations, {} rollouts, f = {}",
            if report.converged {
                "converged"
            } else {
                "not converged"
            },
            report.iterations,
            report.rollouts,
            number(report.f)
        );
    }
    if report.converged {
        Ok(())
    } else {
        Err(CliError::failed("not converged"))
    }
}

fn frames_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    budget: u32,
    overrides: &Overrides,
) -> Result<FramesJson, CliError> {
    let config = lt.planner(HOST_CAPACITY, overrides)?;
    let mut planner: Box<Planner<N, K, HOST_CAPACITY>> =
        Box::new(Planner::new(lt.task::<N, K>()?, config).or_input(|| "planner")?);
    let (mut frames, mut max_steps, mut max_ms, mut total_ms) = (0u64, 0u64, 0.0f64, 0.0f64);
    let plan = loop {
        let before = planner.spent();
        let start = Instant::now();
        let s = planner
            .step(budget, &mut ())
            .or_failed(|| "planning failed")?;
        let ms = start.elapsed().as_secs_f64() * 1e3;
        frames += 1;
        max_steps = max_steps.max(planner.spent() - before);
        max_ms = max_ms.max(ms);
        total_ms += ms;
        if let Status::Finished(plan) = s {
            break plan;
        }
    };
    let converged = plan.converged();
    Ok(FramesJson {
        frame_budget: budget,
        frames,
        max_steps_per_frame: max_steps,
        mean_steps_per_frame: planner.spent() as f64 / frames as f64,
        max_frame_ms: max_ms,
        mean_frame_ms: total_ms / frames as f64,
        converged,
        iterations: plan.iterations,
        rollouts: plan.rollouts,
        f: plan.outcome.f,
    })
}
