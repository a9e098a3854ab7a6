//! A campaign's table and its summary: one [`Run`] per (task, strategy, seed), the rows
//! of `runs.csv`, and [`summary`] (`summary.md`), a function of the rows alone (so the
//! shards of a campaign merged give what one machine writes, wall times aside).

use crate::stats::{max, median, percentile};
use serde::{Deserialize, Serialize};
use std::fmt::Write as _;

/// One run's result: one row of `runs.csv` (columns in field order).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Run {
    /// Task file as given.
    pub task: String,
    /// The robot's name (URDF).
    pub robot: String,
    /// The search strategy.
    pub strategy: String,
    /// Seed.
    pub seed: u64,
    /// `converged` (what was asked is met, see `asked`) or `not_converged`.
    pub status: String,
    /// Why planning stopped: `converged`, `exhausted` (a budget was spent first) or
    /// `stalled` (no step got closer: for a 6-joint arm, the target's floor).
    pub stop: String,
    /// What was asked, in words (`crate::goal::Asked::describe`).
    pub asked: String,
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
    /// Whether a feasible rollout had f ≤ σ_e (the paper's test) at some point.
    pub sigma_e_met: bool,
    /// Wall time of planning (s).
    pub wall_time_s: f64,
}

impl Run {
    /// Whether the run converged.
    pub fn converged(&self) -> bool {
        self.status == "converged"
    }
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
    let sigma_e = runs.iter().filter(|r| r.sigma_e_met).count();
    let sigma_e = format!(
        "{sigma_e} ({:.1}%)",
        100.0 * sigma_e as f64 / runs.len().max(1) as f64
    );
    let _ = writeln!(
        out,
        "| {label} | {} | {} ({:.1}%) | {sigma_e} | {:.0} | {:.0} | {:.0} | {:.0} | {:.3} | {:.3} |",
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
    let mut asked: Vec<&str> = runs.iter().map(|r| r.asked.as_str()).collect();
    asked.sort_unstable();
    asked.dedup();
    let _ = writeln!(
        out,
        "\n## Overview\n\nConverged: the plan meets what was asked ({}). σ_e met: a feasible rollout had f ≤ σ_e (the paper's test) at some point. Rollouts to success over the converged runs (median, p95, max); the most rollouts any run spent; wall time of planning over all runs.\n\n| strategy · robot | runs | converged | σ_e met | rollouts median | p95 | max | most spent | wall median (s) | wall max (s) |\n|---|---|---|---|---|---|---|---|---|---|",
        asked.join("; ")
    );
    let mut strategies: Vec<&str> = runs.iter().map(|r| r.strategy.as_str()).collect();
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
