//! A campaign's table and its summary: one [`Run`] per (task, strategy, seed), the rows
//! of `runs.csv`, and [`summary`] (`summary.md`), a function of the rows alone (so the
//! shards of a campaign merged give what one machine writes, wall times aside).

use crate::goal::number;
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
    /// `converged` (what was asked is met, see `asked`, and the path keeps any required
    /// clearance), `collides` (converged, but closer than `[collision] clearance_m`) or
    /// `not_converged`.
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
    /// Smallest clearance of the written path (m, `crate::clearance`); empty where the task
    /// requires none (and in runs.csv files written before it).
    #[serde(default)]
    pub clearance_m: Option<f64>,
    /// Wall time of planning (s), the last column.
    pub wall_time_s: f64,
}

impl Run {
    /// Whether the run converged.
    pub fn converged(&self) -> bool {
        self.status == "converged"
    }
}

/// A summary column: name, the value of a run, whether it is a count.
type Column = (&'static str, fn(&Run) -> f64, bool);

/// A count as an integer (`3`, not `3.000`); a median of an even number of counts can be
/// a half (`12.5`); a statistic of no runs (NaN, −∞: no run converged) is `–`.
fn count(v: f64) -> String {
    if !v.is_finite() {
        "–".into()
    } else if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        number(v)
    }
}

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
        ("iterations", |r| f64::from(r.iterations), true),
        ("rollouts", |r| f64::from(r.rollouts), true),
        ("f", |r| r.f, false),
        ("base disturbance (deg)", |r| r.base_disturbance_deg, false),
        ("truth f", |r| r.truth_f, false),
        ("wall time (s)", |r| r.wall_time_s, false),
    ];
    for (name, get, is_count) in cols {
        let v: Vec<f64> = runs.iter().map(|r| get(r)).collect();
        let fmt = |x: f64| if is_count { count(x) } else { number(x) };
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
        "| {label} | {} | {} ({:.1}%) | {sigma_e} | {} | {} | {} | {} | {} | {} |",
        runs.len(),
        ok.len(),
        100.0 * ok.len() as f64 / runs.len().max(1) as f64,
        count(median(&rollouts)),
        count(percentile(&rollouts, 95.0)),
        count(max(&rollouts)),
        count(max(&all_rollouts)),
        number(median(&wall)),
        number(max(&wall)),
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

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn run(seed: u64, iterations: u32, rollouts: u32, f: f64, wall: f64) -> Run {
        Run {
            task: "t.toml".into(),
            robot: "arm6".into(),
            strategy: "multistart".into(),
            seed,
            status: "converged".into(),
            stop: "converged".into(),
            asked: "f ≤ σ_e = 0.05 (the paper's test)".into(),
            iterations,
            rollouts,
            f,
            phi: 0.0,
            position_error_m: f,
            orientation_error_deg: 1.44,
            base_disturbance_deg: 1.44,
            truth_f: 97.57,
            sigma_e_met: true,
            clearance_m: None,
            wall_time_s: wall,
        }
    }

    /// Counts are integers (`3`, not `3.000`; the median of an even number of them can be
    /// a half); other numbers read plainly where that is short (`1.44`, `97.57`) and
    /// scientifically where not (`3.254e-5`).
    /// Verifies RL-SIM-CAMP-004.
    #[test]
    fn counts_are_integers_and_numbers_read_plainly() {
        let runs = [run(1, 3, 97, 3.254e-5, 0.25), run(2, 4, 120, 3.254e-5, 0.5)];
        let md = summary(&runs, &[1, 2]);
        assert!(md.contains("| iterations | 3.5 | 4 | 4 |"), "{md}");
        assert!(md.contains("| rollouts | 108.5 | 120 | 120 |"), "{md}");
        assert!(
            md.contains("| f | 3.254e-5 | 3.254e-5 | 3.254e-5 |"),
            "{md}"
        );
        assert!(
            md.contains("| base disturbance (deg) | 1.44 | 1.44 | 1.44 |"),
            "{md}"
        );
        assert!(md.contains("| truth f | 97.57 | 97.57 | 97.57 |"), "{md}");
        assert!(md.contains("| wall time (s) | 0.375 | 0.5 | 0.5 |"), "{md}");
        // Overview: rollouts to success median, p95, max, most spent; wall median, max.
        assert!(
            md.contains("| 108.5 | 120 | 120 | 120 | 0.375 | 0.5 |"),
            "{md}"
        );
        assert!(!md.contains(".000") && !md.contains("e0 "), "{md}");
        // No run converged: no rollouts to success, not NaN and -inf.
        let failed: Vec<Run> = runs
            .iter()
            .map(|r| Run {
                status: "not_converged".into(),
                ..r.clone()
            })
            .collect();
        let md = summary(&failed, &[1, 2]);
        assert!(
            md.contains("| 0 (0.0%) | 2 (100.0%) | – | – | – | 120 |"),
            "{md}"
        );
    }
}
