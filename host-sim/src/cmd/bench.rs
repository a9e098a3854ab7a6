//! `host-sim bench`: in-process timings of the core on a task, after a warm-up.
//!
//! `step_ns`: median over single-rollout slices of 100 integration steps, divided by 100.
//! `rollout_us`: median of 21 full rollouts. `plan_s_median`, `plan_iterations_median`,
//! `plan_rollouts_median`: over seeds 1..=10 with the task's planner settings (host-sim's
//! planner: candidates in lanes). The η timed for steps and rollouts is the seed-1 plan's.
//!
//! `lanes`: rollouts integrated side by side ([`reactionless::batch`]) in the build of the
//! kernel this CPU runs (`isa`), for 2 and 4 lanes on one thread and 8 lanes as two chunks
//! of 4 on two threads (host-sim's planner): the η of the plans of seeds 1..L, one per
//! lane; per rollout-equivalent (the time of L rollouts divided by L), the median of 21
//! runs, and the throughput against the scalar rollout (`speedup`).

use crate::args::{GoalArgs, parse_strategy};
use crate::drive::{self, HOST_CAPACITY};
use crate::error::{CliError, Context};
use crate::stats::median;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use reactionless::batch::{Batch, Engine};
use reactionless::{Progress, Rollout, Strategy};
use reactionless_simd::{Isa, Native, Threaded};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The report.
#[derive(Serialize, schemars::JsonSchema)]
pub struct BenchJson {
    /// Joint count.
    pub n: usize,
    /// Integration steps per rollout.
    pub steps_per_rollout: u32,
    /// Median time of one integration step (ns).
    pub step_ns: f64,
    /// Median time of one full rollout (µs).
    pub rollout_us: f64,
    /// Median planning time over seeds 1..=10 (s).
    pub plan_s_median: f64,
    /// Median C-PSO iterations over seeds 1..=10.
    pub plan_iterations_median: f64,
    /// Median rollouts over seeds 1..=10.
    pub plan_rollouts_median: f64,
    /// Seeds (of 10) that converged.
    pub plan_converged: u32,
    /// One entry per seed.
    pub plans: Vec<PlanRun>,
    /// The build of the lane kernel that ran (`sse2`, `avx2`).
    pub isa: String,
    /// Rollouts in lanes, per rollout-equivalent (none for an RK4 task: lanes integrate
    /// with Euler only).
    pub lanes: Vec<LanesRun>,
    /// How the task's rollouts integrate: `"euler"`, `"rk4"` or `"ab5"`.
    pub integrator: String,
    /// RK4 tasks: median time of the same η's rollout by the reference Euler
    /// discretization in the same run (µs); `rollout_us` over it is the cost ratio.
    pub euler_rollout_us: Option<f64>,
}

/// Rollouts integrated side by side.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct LanesRun {
    /// Lanes (rollouts in lockstep).
    pub lanes: usize,
    /// Threads they ran on (8 lanes: two chunks of 4, on up to two threads).
    pub threads: usize,
    /// Median time of L full rollouts, divided by L (µs).
    pub rollout_us: f64,
    /// The same per integration step (ns).
    pub step_ns: f64,
    /// `rollout_us` of the scalar rollout divided by this one.
    pub speedup: f64,
}

/// One timed plan.
#[derive(Debug, Clone, Serialize, schemars::JsonSchema)]
pub struct PlanRun {
    /// Seed.
    pub seed: u64,
    /// Wall time (s).
    pub wall_time_s: f64,
    /// C-PSO iterations.
    pub iterations: u32,
    /// Rollouts.
    pub rollouts: u32,
    /// Whether it converged.
    pub converged: bool,
}

/// Time the core on a task: one step, one rollout, and planning over seeds 1..10.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML).
    task: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
    /// Search strategy: multistart or cpso (overrides `[planner] strategy`).
    #[arg(long, value_parser = parse_strategy)]
    strategy: Option<Strategy>,
    /// What the timed plans must reach (the task's goal by default).
    #[command(flatten)]
    goal: GoalArgs,
    /// How rollouts integrate the path: euler, rk4 or ab5 (overrides `[motion] integrator`); an
    /// RK4 task also times the same η by Euler, for the ratio.
    #[arg(long, value_parser = crate::args::parse_integrator)]
    integrator: Option<reactionless::Integrator>,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let overrides = Overrides {
            strategy: self.strategy,
            integrator: self.integrator,
            ..self.goal.overrides()
        };
        run(&self.task, self.json, &overrides)
    }
}

fn run(task_path: &Path, json: bool, overrides: &Overrides) -> Result<(), CliError> {
    let mut lt = taskfile::load(task_path)?;
    lt.set_integrator(overrides.integrator)?;
    let report = with_dims!(lt.chain.dof(), bench_n, &lt, overrides)?;
    if json {
        let s = serde_json::to_string(&report).or_internal(|| "report JSON")?;
        println!("{s}");
    } else {
        println!("step            {:10.1} ns (median)", report.step_ns);
        println!(
            "rollout         {:10.1} µs (median, {} steps)",
            report.rollout_us, report.steps_per_rollout
        );
        println!(
            "plan            {:10.3} s  (median over seeds 1..10)",
            report.plan_s_median
        );
        println!(
            "plan iterations {:10.1}    (median)",
            report.plan_iterations_median
        );
        println!(
            "plan rollouts   {:10.1}    (median)",
            report.plan_rollouts_median
        );
        println!("converged       {:10}    of 10", report.plan_converged);
        if let Some(e) = report.euler_rollout_us {
            println!(
                "euler rollout   {e:10.1} µs (median, the same η): {} is {:.1}x cheaper",
                report.integrator,
                e / report.rollout_us
            );
        }
        for l in &report.lanes {
            println!(
                "{} lanes ({}, {} thread{}) {:8.1} µs per rollout ({:.1} ns per step), {:.2}x the scalar rollout",
                l.lanes,
                report.isa,
                l.threads,
                if l.threads == 1 { "" } else { "s" },
                l.rollout_us,
                l.step_ns,
                l.speedup
            );
        }
    }
    Ok(())
}

/// Median time of `L` rollouts of `etas` (the first `L`, repeated if there are fewer) side
/// by side in engine `E`, divided by `L` (µs).
fn time_lanes<E: Engine, const N: usize, const K: usize, const L: usize>(
    task: &reactionless::Task<N, K>,
    etas: &[[[f64; 2]; K]],
) -> Result<f64, CliError> {
    let mut per = Vec::new();
    for _ in 0..21 {
        let mut b: Batch<N, K, L> = Batch::new(task);
        for (i, eta) in etas.iter().cycle().take(L).enumerate() {
            b.load(i, task, eta, f64::INFINITY)
                .or_failed(|| "rollout")?;
        }
        let start = Instant::now();
        while b.running() > 0 {
            E::run(&mut b, task, u32::MAX, [false; L]);
        }
        per.push(start.elapsed().as_secs_f64() * 1e6 / L as f64);
        std::hint::black_box(b.take(0));
    }
    Ok(median(&per))
}

fn bench_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
) -> Result<BenchJson, CliError> {
    let task = lt.task::<N, K>()?;
    let mut plans = Vec::new();
    let mut eta = None;
    let mut etas = Vec::new();
    // Seed 1 twice: the first run is the warm-up and provides the η timed below.
    for seed in std::iter::once(1).chain(1..=10) {
        let config = lt.planner(
            HOST_CAPACITY,
            &Overrides {
                seed: Some(seed),
                ..*overrides
            },
        )?;
        let done = drive::plan::<N, K>(lt, config, false)?;
        let p = done.plan;
        if eta.is_none() {
            eta = Some(p.eta);
            continue;
        }
        let [first, ..] = p.eta;
        etas.push(first);
        plans.push(PlanRun {
            seed,
            wall_time_s: done.seconds,
            iterations: p.iterations,
            rollouts: p.rollouts,
            converged: p.converged(),
        });
    }
    let eta = eta.ok_or_else(|| CliError::internal("no plan"))?;
    let steps = task.motion().steps();
    let mut per_step = Vec::new();
    let mut per_rollout = Vec::new();
    for _ in 0..21 {
        let start = Instant::now();
        let o = task.rollout_of(&eta, &mut ()).or_failed(|| "rollout")?;
        per_rollout.push(start.elapsed().as_secs_f64() * 1e6);
        std::hint::black_box(o);
        let mut r = Rollout::of(&task, &eta).or_failed(|| "rollout")?;
        loop {
            let t = Instant::now();
            let p = r.advance(&task, 100, &mut ()).or_failed(|| "rollout")?;
            let dt = t.elapsed().as_secs_f64();
            match p {
                Progress::Running { .. } => per_step.push(dt * 1e9 / 100.0),
                Progress::Done(_) | Progress::Abandoned { .. } => break,
            }
        }
    }
    let rollout_us = median(&per_rollout);
    let rk4 = task.motion().integrator() != reactionless::Integrator::Euler;
    let euler_rollout_us = if rk4 {
        let motion = task
            .motion()
            .with_integrator(reactionless::Integrator::Euler)
            .or_failed(|| "the Euler twin")?;
        let euler = reactionless::Task::<N, K>::new(
            task.robot().clone(),
            *task.start(),
            *task.target(),
            motion,
        )
        .or_failed(|| "the Euler twin")?;
        let mut per = Vec::new();
        for _ in 0..21 {
            let start = Instant::now();
            let o = euler.rollout_of(&eta, &mut ()).or_failed(|| "rollout")?;
            per.push(start.elapsed().as_secs_f64() * 1e6);
            std::hint::black_box(o);
        }
        Some(median(&per))
    } else {
        None
    };
    let lane = |lanes: usize, threads: usize, us: f64| LanesRun {
        lanes,
        threads,
        rollout_us: us,
        step_ns: us * 1e3 / f64::from(steps),
        speedup: rollout_us / us,
    };
    let lanes = if rk4 {
        Vec::new()
    } else {
        vec![
            lane(2, 1, time_lanes::<Native, N, K, 2>(&task, &etas)?),
            lane(4, 1, time_lanes::<Native, N, K, 4>(&task, &etas)?),
            lane(
                8,
                rayon::current_num_threads().min(8 / reactionless_simd::CHUNK),
                time_lanes::<Threaded, N, K, 8>(&task, &etas)?,
            ),
        ]
    };
    Ok(BenchJson {
        n: N,
        steps_per_rollout: steps,
        step_ns: median(&per_step),
        rollout_us,
        plan_s_median: median(&plans.iter().map(|p| p.wall_time_s).collect::<Vec<_>>()),
        plan_iterations_median: median(
            &plans
                .iter()
                .map(|p| f64::from(p.iterations))
                .collect::<Vec<_>>(),
        ),
        plan_rollouts_median: median(
            &plans
                .iter()
                .map(|p| f64::from(p.rollouts))
                .collect::<Vec<_>>(),
        ),
        plan_converged: plans.iter().filter(|p| p.converged).count() as u32,
        plans,
        isa: Isa::native().name().to_string(),
        lanes,
        integrator: task.motion().integrator().name().to_string(),
        euler_rollout_us,
    })
}
