//! `host-sim campaign`: Monte Carlo over tasks and seeds, in parallel.
//!
//! Every (task, seed) pair is planned with the task's settings and checked with the truth
//! model. Runs are spread over `--jobs` threads (rayon); each run is independent and
//! deterministic, so the table is the same for any number of jobs (wall times aside). Writes
//! `runs.csv` (one row per run, sorted by task then seed) and `summary.md` (per task and
//! overall: success rate, and median / p90 / max of iterations, rollouts, f, base
//! disturbance and wall time) atomically.

use crate::args::{Strategies, parse_refine_against, parse_seeds, parse_strategies};
use crate::artifacts::write_rollout;
use crate::drive::{self, HOST_CAPACITY};
use crate::error::{CliError, Context};
use crate::output::OutDir;
use crate::stats::{max, median, percentile};
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use reactionless::{RefineAgainst, Strategy};
use serde::Serialize;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// One run's result: one row of `runs.csv` (columns in field order).
#[derive(Debug, Clone, Serialize)]
pub struct Run {
    /// Task file as given.
    pub task: String,
    /// The robot's name (URDF).
    pub robot: String,
    /// The search strategy.
    pub strategy: &'static str,
    /// Seed.
    pub seed: u64,
    /// `converged` (f ≤ σ_e with Φ = 0) or `not_converged`.
    pub status: &'static str,
    /// C-PSO iterations.
    pub iterations: u32,
    /// Rollouts.
    pub rollouts: u32,
    /// f of the plan.
    pub f: f64,
    /// Φ of the plan (rad).
    pub phi: f64,
    /// Position error (m).
    pub position_error_m: f64,
    /// Orientation error (deg).
    pub orientation_error_deg: f64,
    /// Base disturbance, truth model (deg).
    pub base_disturbance_deg: f64,
    /// f of the truth-model end pose (the base drift included) against the target.
    pub truth_f: f64,
    /// With a refinement tolerance: whether it was met (f, or truth_f when refining
    /// against the truth model); empty without one.
    pub refined: Option<bool>,
    /// Wall time of planning (s).
    pub wall_time_s: f64,
}

fn one<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
) -> Result<Run, CliError> {
    let config = lt.planner(HOST_CAPACITY, overrides)?;
    let seed = config.seed;
    let task = lt.task::<N, K>()?;
    let done = drive::plan::<N, K>(lt, config, false)?;
    let p = done.plan;
    let truth = write_rollout(&task, &p.eta, None, false)?.truth;
    Ok(Run {
        task: lt.path.display().to_string(),
        robot: lt.chain.name.clone(),
        strategy: config.strategy.name(),
        seed,
        status: if p.converged() {
            "converged"
        } else {
            "not_converged"
        },
        iterations: p.iterations,
        rollouts: p.rollouts,
        f: p.outcome.f,
        phi: p.outcome.phi,
        position_error_m: p.outcome.error.position_m(),
        orientation_error_deg: p.outcome.error.orientation_deg(),
        base_disturbance_deg: truth.base_disturbance_deg,
        truth_f: truth.f,
        refined: config.refine_tolerance.map(|tol| {
            p.converged()
                && match config.refine_against {
                    RefineAgainst::Planner => p.outcome.f <= tol,
                    RefineAgainst::Truth => truth.f <= tol,
                }
        }),
        wall_time_s: done.seconds,
    })
}

/// A summary column: name, the value of a run, scientific notation.
type Column = (&'static str, fn(&Run) -> f64, bool);

fn stats_rows(out: &mut String, label: &str, runs: &[&Run]) {
    let ok = runs.iter().filter(|r| r.converged()).count();
    let _ = writeln!(
        out,
        "\n### {label}\n\n{} runs, {} converged ({:.1}%)\n",
        runs.len(),
        ok,
        100.0 * ok as f64 / runs.len().max(1) as f64
    );
    let _ = writeln!(out, "| quantity | median | p90 | max |\n|---|---|---|---|");
    let cols: [Column; 6] = [
        ("iterations", |r| f64::from(r.iterations), false),
        ("rollouts", |r| f64::from(r.rollouts), false),
        ("f", |r| r.f, true),
        ("base disturbance (deg)", |r| r.base_disturbance_deg, true),
        ("truth f", |r| r.truth_f, true),
        ("wall time (s)", |r| r.wall_time_s, false),
    ];
    for (name, get, sci) in cols {
        let v: Vec<f64> = runs.iter().map(|r| get(r)).collect();
        let fmt = |x: f64| {
            if sci {
                format!("{x:.3e}")
            } else {
                format!("{x:.3}")
            }
        };
        let _ = writeln!(
            out,
            "| {name} | {} | {} | {} |",
            fmt(median(&v)),
            fmt(percentile(&v, 90.0)),
            fmt(max(&v))
        );
    }
}

/// One row of the overview: success and the cost of success for a group of runs.
fn overview_row(out: &mut String, label: &str, runs: &[&Run]) {
    let ok: Vec<&&Run> = runs.iter().filter(|r| r.converged()).collect();
    let rollouts: Vec<f64> = ok.iter().map(|r| f64::from(r.rollouts)).collect();
    let all_rollouts: Vec<f64> = runs.iter().map(|r| f64::from(r.rollouts)).collect();
    let wall: Vec<f64> = runs.iter().map(|r| r.wall_time_s).collect();
    let refined = runs.iter().filter(|r| r.refined == Some(true)).count();
    let refined = if runs.iter().any(|r| r.refined.is_some()) {
        format!(
            "{refined} ({:.1}%)",
            100.0 * refined as f64 / runs.len().max(1) as f64
        )
    } else {
        "–".into()
    };
    let _ = writeln!(
        out,
        "| {label} | {} | {} ({:.1}%) | {refined} | {:.0} | {:.0} | {:.0} | {:.0} | {:.3} | {:.3} |",
        runs.len(),
        ok.len(),
        100.0 * ok.len() as f64 / runs.len().max(1) as f64,
        median(&rollouts),
        percentile(&rollouts, 95.0),
        max(&rollouts),
        max(&all_rollouts),
        median(&wall),
        max(&wall),
    );
}

/// The Markdown summary: an overview per robot (and all), then each task's statistics.
pub fn summary(runs: &[Run], seeds: &[u64]) -> String {
    let mut out = format!(
        "# Campaign summary\n\nSeeds {} ({} per task), {} runs. Wall times depend on the machine and the number of jobs; everything else is deterministic.\n",
        seed_text(seeds),
        seeds.len(),
        runs.len()
    );
    let _ = writeln!(
        out,
        "\n## Overview\n\nConverged: f ≤ σ_e with Φ = 0. Refined: the refinement tolerance met (f, or truth_f against the truth model). Rollouts to success over the converged runs (median, p95, max); the most rollouts any run spent; wall time of planning over all runs.\n\n| strategy · robot | runs | converged | refined | rollouts median | p95 | max | most spent | wall median (s) | wall max (s) |\n|---|---|---|---|---|---|---|---|---|---|"
    );
    let mut strategies: Vec<&str> = runs.iter().map(|r| r.strategy).collect();
    strategies.dedup();
    strategies.sort_unstable();
    strategies.dedup();
    let mut robots: Vec<&str> = runs.iter().map(|r| r.robot.as_str()).collect();
    robots.sort_unstable();
    robots.dedup();
    for strategy in &strategies {
        for robot in &robots {
            let rs: Vec<&Run> = runs
                .iter()
                .filter(|r| r.robot == *robot && r.strategy == *strategy)
                .collect();
            overview_row(&mut out, &format!("{strategy} · {robot}"), &rs);
        }
        if robots.len() > 1 {
            let all: Vec<&Run> = runs.iter().filter(|r| r.strategy == *strategy).collect();
            overview_row(&mut out, &format!("{strategy} · all robots"), &all);
        }
    }
    let _ = writeln!(out, "\n## Per task");
    let mut tasks: Vec<&str> = runs.iter().map(|r| r.task.as_str()).collect();
    tasks.dedup();
    for t in &tasks {
        for strategy in &strategies {
            let rs: Vec<&Run> = runs
                .iter()
                .filter(|r| r.task == *t && r.strategy == *strategy)
                .collect();
            if !rs.is_empty() {
                stats_rows(&mut out, &format!("`{t}` ({strategy})"), &rs);
            }
        }
    }
    if tasks.len() > 1 {
        let all: Vec<&Run> = runs.iter().collect();
        stats_rows(&mut out, "all tasks", &all);
    }
    out
}

/// `1..5` for a contiguous ascending list, else the list.
fn seed_text(seeds: &[u64]) -> String {
    match (seeds.first(), seeds.last()) {
        (Some(a), Some(b)) if seeds.windows(2).all(|w| w[1] == w[0] + 1) => format!("{a}..{b}"),
        _ => seeds
            .iter()
            .map(u64::to_string)
            .collect::<Vec<_>>()
            .join(","),
    }
}

/// Monte Carlo over tasks and seeds in parallel: DIR/runs.csv and DIR/summary.md.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task files (TOML).
    #[arg(required = true)]
    tasks: Vec<PathBuf>,
    /// Seeds: `3`, `1,2,5` or `1..10` (inclusive).
    #[arg(long, value_parser = parse_seeds)]
    seeds: Seeds,
    /// Strategies to compare, comma-separated (default: each task's `[planner] strategy`).
    #[arg(long, value_parser = parse_strategies)]
    strategy: Option<Strategies>,
    /// Refine until f ≤ this (overrides `[planner] refine_tolerance`).
    #[arg(long)]
    refine_tolerance: Option<f64>,
    /// What refinement drives: planner or truth (overrides `[planner] refine_against`).
    #[arg(long, value_parser = parse_refine_against)]
    refine_against: Option<RefineAgainst>,
    /// Worker threads (default: one per core).
    #[arg(long)]
    jobs: Option<usize>,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
}

/// A list of seeds.
type Seeds = Vec<u64>;

impl Run {
    /// Whether the run converged.
    pub fn converged(&self) -> bool {
        self.status == "converged"
    }
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let strategies: Vec<Option<Strategy>> = match &self.strategy {
            Some(list) => list.0.iter().copied().map(Some).collect(),
            None => vec![None],
        };
        let base = Overrides {
            refine_tolerance: self.refine_tolerance,
            refine_against: self.refine_against,
            ..Overrides::default()
        };
        run(
            &self.tasks,
            &self.seeds,
            &strategies,
            &base,
            self.jobs,
            &self.out,
        )
    }
}

fn run(
    tasks: &[PathBuf],
    seeds: &[u64],
    strategies: &[Option<Strategy>],
    base: &Overrides,
    jobs: Option<usize>,
    out: &Path,
) -> Result<(), CliError> {
    if tasks.is_empty() {
        return Err(CliError::input("campaign needs at least one task file"));
    }
    let loaded: Vec<LoadedTask> = tasks
        .iter()
        .map(|t| taskfile::load(t))
        .collect::<Result<_, _>>()?;
    // Validate every task and its planner settings before anything runs.
    for lt in &loaded {
        for st in strategies {
            lt.planner(
                HOST_CAPACITY,
                &Overrides {
                    strategy: *st,
                    ..*base
                },
            )?;
        }
        with_dims!(lt.chain.dof(), validate, lt)?;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.unwrap_or(0))
        .build()
        .or_input(|| "--jobs")?;
    let pairs: Vec<(&LoadedTask, Overrides)> = loaded
        .iter()
        .flat_map(|lt| {
            strategies.iter().flat_map(move |st| {
                seeds.iter().map(move |s| {
                    (
                        lt,
                        Overrides {
                            seed: Some(*s),
                            strategy: *st,
                            ..*base
                        },
                    )
                })
            })
        })
        .collect();
    let bar = if std::io::stderr().is_terminal() {
        let b = ProgressBar::new(pairs.len() as u64);
        b.set_style(
            ProgressStyle::with_template(
                "{spinner} {elapsed} [{bar:30}] {pos}/{len} runs, eta {eta}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    } else {
        ProgressBar::hidden()
    };
    let results: Vec<Result<Run, CliError>> = pool.install(|| {
        pairs
            .par_iter()
            .map(|(lt, overrides)| {
                let r = with_dims!(lt.chain.dof(), one, lt, overrides);
                bar.inc(1);
                r
            })
            .collect()
    });
    bar.finish_and_clear();
    let runs: Vec<Run> = results.into_iter().collect::<Result<_, _>>()?;
    let dir = OutDir::create(out)?;
    let mut csv = csv::Writer::from_path(dir.path("runs.csv")).or_input(|| "runs.csv")?;
    for r in &runs {
        csv.serialize(r).or_input(|| "runs.csv")?;
    }
    csv.flush().or_input(|| "runs.csv")?;

    let md = summary(&runs, seeds);
    dir.write("summary.md", md.as_bytes())?;
    let path = dir.commit()?;
    let ok = runs.iter().filter(|r| r.converged()).count();
    eprintln!(
        "campaign: {ok} of {} runs converged -> {}",
        runs.len(),
        path.display()
    );
    Ok(())
}

fn validate<const N: usize, const K: usize>(lt: &LoadedTask) -> Result<(), CliError> {
    lt.task::<N, K>().map(|_| ())
}
