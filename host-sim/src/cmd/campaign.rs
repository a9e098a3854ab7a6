//! `host-sim campaign`: Monte Carlo over tasks and seeds, in parallel.
//!
//! Every (task, seed) pair is planned with the task's settings and checked with the truth
//! model. Runs are spread over `--jobs` threads (rayon); each run is independent and
//! deterministic, so the table is the same for any number of jobs (wall times aside). Writes
//! `runs.csv` (one row per run, sorted by task then seed) and `summary.md` (per task and
//! overall: success rate, and median / p90 / max of iterations, rollouts, f, base
//! disturbance and wall time) atomically.

use crate::cmd::plan::{HOST_CAPACITY, plan};
use crate::cmd::rollout::write_rollout;
use crate::error::CliError;
use crate::output::OutDir;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;
use reactionless::Status;
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};

/// One run's result.
#[derive(Debug, Clone)]
pub struct Run {
    /// Task file as given.
    pub task: String,
    /// Seed.
    pub seed: u64,
    /// Converged (f ≤ σ_e with Φ = 0)?
    pub converged: bool,
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
    /// Wall time of planning (s).
    pub wall_s: f64,
}

/// Parses `A..B` (inclusive) into seeds.
pub fn parse_seeds(s: &str) -> Result<Vec<u64>, String> {
    let (a, b) = s
        .split_once("..")
        .ok_or_else(|| format!("'{s}' is not a range A..B (inclusive)"))?;
    let a: u64 = a
        .trim()
        .parse()
        .map_err(|_| format!("'{a}' is not a seed"))?;
    let b: u64 = b
        .trim()
        .trim_start_matches('=')
        .parse()
        .map_err(|_| format!("'{b}' is not a seed"))?;
    if b < a {
        return Err(format!("empty range {a}..{b}"));
    }
    if b - a >= 1_000_000 {
        return Err(format!("{a}..{b} has more than a million seeds"));
    }
    Ok((a..=b).collect())
}

fn one<const N: usize, const K: usize>(lt: &LoadedTask, seed: u64) -> Result<Run, CliError> {
    let config = lt.planner(
        HOST_CAPACITY,
        &Overrides {
            seed: Some(seed),
            ..Overrides::default()
        },
    )?;
    let task = lt.task::<N, K>()?;
    let done = plan::<N, K>(lt, config, false)?;
    let (converged, p) = match done.status {
        Status::Finished(p) => (p.converged(), p),
        Status::Running(_) => return Err(CliError::internal("planner still running")),
    };
    let truth = write_rollout(&task, &p.eta, None, false)?.truth;
    Ok(Run {
        task: lt.path.display().to_string(),
        seed,
        converged,
        iterations: p.iterations,
        rollouts: p.rollouts,
        f: p.outcome.f,
        phi: p.outcome.phi,
        position_error_m: p.outcome.error.position_m(),
        orientation_error_deg: p.outcome.error.orientation_deg(),
        base_disturbance_deg: truth.base_disturbance_deg,
        wall_s: done.seconds,
    })
}

/// Nearest-rank percentile `p` (0..=100) of `v`.
pub fn percentile(v: &[f64], p: f64) -> f64 {
    let mut s: Vec<f64> = v.to_vec();
    s.sort_by(f64::total_cmp);
    if s.is_empty() {
        return f64::NAN;
    }
    let rank = ((p / 100.0) * s.len() as f64).ceil().max(1.0) as usize;
    s[rank.min(s.len()) - 1]
}

/// Median (mean of the middle two for an even count).
pub fn median(v: &[f64]) -> f64 {
    let mut s: Vec<f64> = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    match n {
        0 => f64::NAN,
        _ if n % 2 == 1 => s[n / 2],
        _ => 0.5 * (s[n / 2 - 1] + s[n / 2]),
    }
}

/// A summary column: name, the value of a run, scientific notation.
type Column = (&'static str, fn(&Run) -> f64, bool);

fn stats_rows(out: &mut String, label: &str, runs: &[&Run]) {
    let ok = runs.iter().filter(|r| r.converged).count();
    let _ = writeln!(
        out,
        "\n### {label}\n\n{} runs, {} converged ({:.1}%)\n",
        runs.len(),
        ok,
        100.0 * ok as f64 / runs.len().max(1) as f64
    );
    let _ = writeln!(out, "| quantity | median | p90 | max |\n|---|---|---|---|");
    let cols: [Column; 5] = [
        ("iterations", |r| f64::from(r.iterations), false),
        ("rollouts", |r| f64::from(r.rollouts), false),
        ("f", |r| r.f, true),
        ("base disturbance (deg)", |r| r.base_disturbance_deg, true),
        ("wall time (s)", |r| r.wall_s, false),
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
            fmt(v.iter().copied().fold(f64::NEG_INFINITY, f64::max))
        );
    }
}

/// The Markdown summary.
pub fn summary(runs: &[Run], seeds: &[u64]) -> String {
    let mut out = format!(
        "# Campaign summary\n\nSeeds {}..{} ({} per task), {} runs. Wall times depend on the machine and the number of jobs; everything else is deterministic.\n",
        seeds.first().copied().unwrap_or(0),
        seeds.last().copied().unwrap_or(0),
        seeds.len(),
        runs.len()
    );
    let mut tasks: Vec<&str> = runs.iter().map(|r| r.task.as_str()).collect();
    tasks.dedup();
    for t in &tasks {
        let rs: Vec<&Run> = runs.iter().filter(|r| r.task == *t).collect();
        stats_rows(&mut out, &format!("`{t}`"), &rs);
    }
    if tasks.len() > 1 {
        let all: Vec<&Run> = runs.iter().collect();
        stats_rows(&mut out, "all tasks", &all);
    }
    out
}

/// Runs the subcommand.
pub fn run(
    tasks: &[PathBuf],
    seeds: &[u64],
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
        lt.planner(HOST_CAPACITY, &Overrides::default())?;
        with_dims!(lt.chain.dof(), validate, lt)?;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.unwrap_or(0))
        .build()
        .map_err(|e| CliError::input(format!("--jobs: {e}")))?;
    let pairs: Vec<(&LoadedTask, u64)> = loaded
        .iter()
        .flat_map(|lt| seeds.iter().map(move |s| (lt, *s)))
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
            .map(|(lt, seed)| {
                let r = with_dims!(lt.chain.dof(), one, lt, *seed);
                bar.inc(1);
                r
            })
            .collect()
    });
    bar.finish_and_clear();
    let runs: Vec<Run> = results.into_iter().collect::<Result<_, _>>()?;
    let dir = OutDir::create(out)?;
    let mut csv = String::from(
        "task,seed,status,iterations,rollouts,f,phi,position_error_m,orientation_error_deg,base_disturbance_deg,wall_s\n",
    );
    for r in &runs {
        let b = |v: f64| ryu::Buffer::new().format(v).to_string();
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{},{}",
            r.task,
            r.seed,
            if r.converged {
                "converged"
            } else {
                "not_converged"
            },
            r.iterations,
            r.rollouts,
            b(r.f),
            b(r.phi),
            b(r.position_error_m),
            b(r.orientation_error_deg),
            b(r.base_disturbance_deg),
            b(r.wall_s)
        );
    }
    dir.write("runs.csv", csv.as_bytes())?;
    let md = summary(&runs, seeds);
    dir.write("summary.md", md.as_bytes())?;
    let path = dir.commit()?;
    let ok = runs.iter().filter(|r| r.converged).count();
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
