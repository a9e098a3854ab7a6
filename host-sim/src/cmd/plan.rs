//! `host-sim plan`: C-PSO (and refinement, if asked) on a task; writes `plan.json`,
//! `trajectory.csv` and `summary.json` atomically.
//!
//! The trajectory is the plan's η rolled out again by the same code; it must reproduce the
//! outcome the planner evaluated bit for bit (checked here, so a mismatch is never written).
//! Exit code 0 converged, 1 not converged (outputs still written), 2 bad input.

use crate::cmd::rollout::{self, PoseJson};
use crate::error::CliError;
use crate::output::OutDir;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use indicatif::{ProgressBar, ProgressStyle};
use reactionless::{Event, Planner, PlannerConfig, RefineStop, Status};
use serde::Serialize;
use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

/// Swarm capacity of the host planner. It does not change results (only the task's count
/// of particles is ever used); the flight image uses 64.
pub const HOST_CAPACITY: usize = 256;

/// Integration steps per `step` call when host-sim drives the planner.
const SLICE: u32 = 3000;

/// `plan.json`.
#[derive(Serialize)]
pub struct PlanJson {
    /// `"converged"` or `"not_converged"`.
    pub status: &'static str,
    /// η as `a1,b1,…,aK,bK`.
    pub eta: Vec<f64>,
    /// f of the plan.
    pub f: f64,
    /// Φ of the plan (rad).
    pub phi: f64,
    /// ‖p_des − p‖ (m).
    pub position_error_m: f64,
    /// Angle of R_des Rᵀ (deg).
    pub orientation_error_deg: f64,
    /// C-PSO generations after the initial one.
    pub iterations: u32,
    /// All rollouts (C-PSO and refinement).
    pub rollouts: u32,
    /// Rollouts of C-PSO.
    pub swarm_rollouts: u32,
    /// Rollouts stopped early because their joint-limit violation already ruled them out.
    pub abandoned_rollouts: u32,
    /// Integration steps spent (the planner's budget unit); not part of any record.
    pub integration_steps: u64,
    /// Stagnation alarms.
    pub stagnation_events: u32,
    /// Seed used.
    pub seed: u64,
    /// gbest's f after each completed generation (0 = initial), then the successful f.
    pub best_f_history: Vec<f64>,
    /// f when C-PSO stopped.
    pub swarm_f: f64,
    /// Refinement, if it ran.
    pub refine: Option<RefineJson>,
    /// End pose of the plan (planner model).
    pub end_pose: PoseJson,
    /// Wall time of planning (s); not part of any record.
    pub wall_time_s: f64,
}

/// Refinement in `plan.json`.
#[derive(Serialize)]
pub struct RefineJson {
    /// Target on f.
    pub tolerance: f64,
    /// `"reached"`, `"budget"` or `"stalled"`.
    pub stop: &'static str,
    /// Accepted steps.
    pub iterations: u32,
    /// Rollouts spent.
    pub rollouts: u32,
    /// f before refinement.
    pub f_start: f64,
    /// f after each trial (best so far).
    pub f_history: Vec<f64>,
}

/// What `plan` was asked to do.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlanOptions {
    /// Seed override.
    pub seed: Option<u64>,
    /// Refinement tolerance override.
    pub refine: Option<f64>,
    /// Write figures.
    pub plots: bool,
}

/// Runs the subcommand.
pub fn run(task_path: &Path, out: &Path, options: PlanOptions) -> Result<(), CliError> {
    let lt = taskfile::load(task_path)?;
    with_dims!(lt.chain.dof(), run_n, &lt, out, options)
}

/// A finished planning run.
pub struct Finished<const N: usize, const K: usize> {
    /// The planner's final status.
    pub status: Status<N, K>,
    /// gbest f per generation, then the successful f.
    pub history: Vec<f64>,
    /// Refinement f per trial.
    pub refine_history: Vec<f64>,
    /// Wall time (s).
    pub seconds: f64,
    /// Integration steps spent ([`Planner::spent`]).
    pub steps: u64,
}

/// Plans `lt` with `config`, with a progress bar on a terminal.
pub fn plan<const N: usize, const K: usize>(
    lt: &LoadedTask,
    config: PlannerConfig,
    progress: bool,
) -> Result<Finished<N, K>, CliError> {
    let task = lt.task::<N, K>()?;
    let mut planner: Box<Planner<N, K, HOST_CAPACITY>> =
        Box::new(Planner::new(task, config).map_err(|e| CliError::input(format!("planner: {e}")))?);
    let bar = if progress && std::io::stderr().is_terminal() {
        let b = ProgressBar::new(u64::from(config.max_iterations));
        b.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} [{bar:30}] gen {pos}/{len} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    let mut history = Vec::new();
    let mut refine_history = Vec::new();
    let mut observer = |e: &Event| match e {
        Event::Generation {
            iteration,
            best,
            rollouts,
        } => {
            history.push(best.f);
            bar.set_position(u64::from(*iteration));
            bar.set_message(format!("best f {:.3e}, {rollouts} rollouts", best.f));
        }
        Event::SwarmConverged { f, .. } => {
            history.push(*f);
            bar.set_message(format!("C-PSO converged, f {f:.3e}; refining"));
        }
        Event::RefineTrial { f, .. } => refine_history.push(*f),
        Event::Stagnation { .. } => {}
    };
    let start = Instant::now();
    let status = loop {
        match planner.step(SLICE, &mut observer) {
            Ok(Status::Running(_)) => {}
            Ok(s) => break s,
            Err(e) => return Err(CliError::failed(format!("planning failed: {e}"))),
        }
    };
    bar.finish_and_clear();
    Ok(Finished {
        status,
        history,
        refine_history,
        seconds: start.elapsed().as_secs_f64(),
        steps: planner.spent(),
    })
}

fn stop_name(s: RefineStop) -> &'static str {
    match s {
        RefineStop::Reached => "reached",
        RefineStop::Budget => "budget",
        RefineStop::Stalled => "stalled",
    }
}

fn run_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    out: &Path,
    options: PlanOptions,
) -> Result<(), CliError> {
    let PlanOptions {
        seed,
        refine,
        plots,
    } = options;
    let config = lt.planner(
        HOST_CAPACITY,
        &Overrides {
            seed,
            refine_tolerance: refine,
        },
    )?;
    let task = lt.task::<N, K>()?;
    let done = plan::<N, K>(lt, config, true)?;
    let (converged, p) = match done.status {
        Status::Finished(p) => (p.converged(), p),
        Status::Running(_) => return Err(CliError::internal("planner still running")),
    };
    let dir = OutDir::create(out)?;
    let run = rollout::write_rollout(&task, &p.eta, Some(&dir), plots)?;
    if run.outcome != p.outcome {
        return Err(CliError::internal(
            "the re-run rollout differs from the one the planner evaluated",
        ));
    }
    let truth = &run.truth;
    dir.write_json(
        "summary.json",
        &rollout::summary(&task, &p.eta, &run.outcome, truth),
    )?;
    rollout::write_bundle(
        lt,
        &dir,
        Some(config.seed),
        config.refine().map(|r| r.tolerance),
    )?;
    if let Some(trace) = run.trace {
        rollout::write_figures(lt, &task, trace, Some(done.history.clone()), &dir)?;
    }
    let json = PlanJson {
        status: if converged {
            "converged"
        } else {
            "not_converged"
        },
        eta: p.eta.iter().flatten().copied().collect(),
        f: p.outcome.f,
        phi: p.outcome.phi,
        position_error_m: p.outcome.error.position_m(),
        orientation_error_deg: p.outcome.error.orientation_deg(),
        iterations: p.iterations,
        rollouts: p.rollouts,
        swarm_rollouts: p.swarm_rollouts,
        abandoned_rollouts: p.abandoned,
        integration_steps: done.steps,
        stagnation_events: p.stagnation_events,
        seed: config.seed,
        best_f_history: done.history,
        swarm_f: p.swarm_f,
        refine: p.refine.map(|r| RefineJson {
            tolerance: config.refine().map_or(f64::NAN, |c| c.tolerance),
            stop: stop_name(r.stop),
            iterations: r.iterations,
            rollouts: r.rollouts,
            f_start: r.f_start,
            f_history: done.refine_history,
        }),
        end_pose: (&p.outcome.end_pose).into(),
        wall_time_s: done.seconds,
    };
    dir.write_json("plan.json", &json)?;
    let path = dir.commit()?;
    eprintln!(
        "plan: {} after {} iterations, {} rollouts, f = {:.3e} ({:.3e} m, {:.3e} deg), base disturbance {:.3e} deg, {:.2} s -> {}",
        json.status,
        p.iterations,
        p.rollouts,
        p.outcome.f,
        json.position_error_m,
        json.orientation_error_deg,
        truth.base_disturbance_deg,
        done.seconds,
        path.display()
    );
    if converged {
        Ok(())
    } else {
        Err(CliError::failed(format!(
            "not converged after {} iterations (best f = {:.3e})",
            p.iterations, p.outcome.f
        )))
    }
}
