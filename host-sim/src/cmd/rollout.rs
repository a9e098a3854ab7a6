//! `host-sim rollout`: one η through the reference discretization, with the truth model.
//!
//! Writes `trajectory.csv` (every sample, s / rad / rad/s), `summary.json` and the task
//! bundle into the output directory, atomically; with `--plots` the figures and the 3-D
//! replay page `view.html` too.

use crate::args::{GoalArgs, List, eta_error, parse_eta, parse_list};
use crate::artifacts::{summary, write_bundle, write_figures, write_rollout};
use crate::drive::HOST_CAPACITY;
use crate::error::CliError;
use crate::goal::number;
use crate::output::OutDir;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::view;
use crate::with_dims;
use reactionless::Rollout;
use std::path::{Path, PathBuf};

/// Roll out one η of a task: writes DIR/trajectory.csv and DIR/summary.json.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML).
    task: PathBuf,
    /// η = a1,b1,...,aK,bK (K = N − 3), comma-separated.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_list)]
    eta: List,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Also write figures (PNG and SVG) and the 3-D replay page view.html.
    #[arg(long)]
    plots: bool,
    /// What `check` holds the rollout to (written into the bundle's task.toml).
    #[command(flatten)]
    goal: GoalArgs,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let lt = taskfile::load(&self.task)?;
        with_dims!(
            lt.chain.dof(),
            run_n,
            &lt,
            &self.eta.0,
            &self.out,
            self.plots,
            &self.goal.overrides()
        )
    }
}

fn run_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
    out: &Path,
    plots: bool,
    overrides: &Overrides,
) -> Result<(), CliError> {
    let (config, asked) = lt.plan_settings(HOST_CAPACITY, overrides)?;
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(eta, task.motion().segments())?;
    // Validate η before anything is created on disk.
    Rollout::of(&task, &eta).map_err(eta_error)?;
    let dir = OutDir::create(out)?;
    let run = write_rollout(&task, &eta, Some(&dir), plots)?;
    dir.write_json(
        "summary.json",
        &summary(&task, &eta, &run.outcome, &run.truth),
    )?;
    let _ = write_bundle(lt, &dir, Some((&config, &asked)))?;
    if let Some(trace) = run.trace {
        write_figures(lt, &task, trace, None, &dir)?;
        dir.write(
            "view.html",
            view::render_dir(&dir.path(""), out)?.as_bytes(),
        )?;
    }
    let path = dir.commit()?;
    eprintln!(
        "rollout: f = {}, phi = {}, base disturbance = {} deg -> {}",
        number(run.outcome.f),
        number(run.outcome.phi),
        number(run.truth.base_disturbance_deg),
        path.display()
    );
    Ok(())
}
