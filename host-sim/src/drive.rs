//! Driving the core's planner on the host: to the end, with a progress bar on a terminal.
//!
//! Owns [`plan`] and what a finished run hands back ([`Planned`]): the plan, the histories
//! the observer collected for plots and `plan.json`, the wall time and the integration
//! steps spent. Every subcommand that plans (`plan`, `record`, `replay`, `campaign`,
//! `bench`, `target`) goes through here, so the planner is driven one way everywhere.

use crate::error::{CliError, Context};
use crate::taskfile::LoadedTask;
use indicatif::{ProgressBar, ProgressStyle};
use reactionless::{Event, Plan, Planner, PlannerConfig, Status};
use reactionless_simd::Threaded;
use std::io::IsTerminal;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Instant;

/// Swarm capacity of the host planner. It does not change results (only the task's count
/// of particles is ever used); the flight image uses 64.
pub const HOST_CAPACITY: usize = 256;

/// Candidates the host planner integrates side by side ([`reactionless::batch`]): eight
/// lanes, as two chunks of four in the AVX2 build where the CPU has AVX2, each chunk on
/// its own thread ([`Threaded`]: a single plan uses both cores of the build machine). It
/// does not change results: every lane has the bits of the scalar rollout, and the plan
/// those of the one-at-a-time planner of the flight target.
pub const HOST_LANES: usize = 8;

/// The planner host-sim drives.
pub type HostPlanner<const N: usize, const K: usize> =
    Planner<N, K, HOST_CAPACITY, HOST_LANES, Threaded>;

/// Integration steps per `step` call when host-sim drives the planner: a rollout's worth
/// per lane, so that the lanes' threads get long runs of work between calls (results do
/// not depend on it: the planner is bit-identical under any slicing).
const SLICE: u32 = 3000 * HOST_LANES as u32;

/// A finished planning run.
#[derive(Debug, Clone)]
pub struct Planned<const N: usize, const K: usize> {
    /// The plan (why it stopped: [`Plan::stop`]).
    pub plan: Plan<N, K>,
    /// C-PSO: gbest's f after each completed generation, then the successful f (empty for
    /// the multistart).
    pub history: Vec<f64>,
    /// Refinement: the best f after each trial.
    pub refine_history: Vec<f64>,
    /// The best f after each rollout (search, then refinement).
    pub best_per_rollout: Vec<f64>,
    /// Wall time of planning (s).
    pub seconds: f64,
    /// Integration steps spent ([`Planner::spent`]; with lanes, also those of candidates
    /// evaluated ahead that the search did not use).
    pub steps: u64,
}

/// A spinner with the elapsed time and `msg` on a terminal (stderr); elsewhere one line
/// `msg…` on stderr, so logs show what long work is under way. Finish it with
/// [`ProgressBar::finish_and_clear`].
pub fn spinner(msg: &str) -> ProgressBar {
    if std::io::stderr().is_terminal() {
        let b = ProgressBar::new_spinner();
        b.set_style(
            ProgressStyle::with_template("{spinner} {elapsed} {msg}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner()),
        );
        b.set_message(msg.to_string());
        b.enable_steady_tick(std::time::Duration::from_millis(200));
        b
    } else {
        eprintln!("{msg}…");
        ProgressBar::hidden()
    }
}

/// A bar of `len` items with the elapsed time, `{pos}/{len}` and `tail` (an indicatif
/// template fragment, e.g. `samples, eta {eta}`) on a terminal (stderr); hidden elsewhere.
pub fn bar(len: u64, tail: &str) -> ProgressBar {
    if !std::io::stderr().is_terminal() {
        return ProgressBar::hidden();
    }
    let b = ProgressBar::new(len);
    b.set_style(
        ProgressStyle::with_template(&format!(
            "{{spinner}} {{elapsed}} [{{bar:30}}] {{pos}}/{{len}} {tail}"
        ))
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    b
}

/// Progress of `len` items done on several threads (`campaign`, `disperse`): a bar on a
/// terminal; elsewhere (a batch log, e.g. a Slurm job's) one line on stderr at every tenth
/// of a run of at least [`Progress::LOGGED`] items, `what: 300/1000 samples (30%), 2.1 s`.
#[derive(Debug)]
pub struct Progress {
    bar: ProgressBar,
    logged: Option<(String, &'static str)>,
    len: u64,
    done: AtomicU64,
    start: Instant,
}

impl Progress {
    /// The smallest run that logs its progress when stderr is not a terminal.
    pub const LOGGED: u64 = 100;

    /// `len` items called `unit` (e.g. `samples`) of the work `what` (e.g. `disperse`).
    pub fn new(what: &str, len: u64, unit: &'static str) -> Self {
        let tty = std::io::stderr().is_terminal();
        Self {
            bar: bar(len, &format!("{unit}, eta {{eta}}")),
            logged: (!tty && len >= Self::LOGGED).then(|| (what.to_string(), unit)),
            len,
            done: AtomicU64::new(0),
            start: Instant::now(),
        }
    }

    /// One more item done (any thread).
    pub fn inc(&self) {
        self.bar.inc(1);
        if let Some((what, unit)) = &self.logged {
            let k = self.done.fetch_add(1, Ordering::Relaxed) + 1;
            if k * 10 / self.len != (k - 1) * 10 / self.len {
                eprintln!(
                    "{what}: {k}/{} {unit} ({}%), {:.1} s",
                    self.len,
                    k * 100 / self.len,
                    self.start.elapsed().as_secs_f64()
                );
            }
        }
    }

    /// Clears the bar.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

/// Set by [`cancel`]: long runs over many items (`disperse`'s samples) stop at the next
/// item with an "interrupted" failure. Never set by the CLI (Ctrl-C ends its process); the
/// Python package sets it on KeyboardInterrupt.
static CANCELLED: AtomicBool = AtomicBool::new(false);

/// Asks the runs in progress to stop at their next item ([`cancelled`]).
pub fn cancel() {
    CANCELLED.store(true, Ordering::SeqCst);
}

/// Clears [`cancel`] (before a new run).
pub fn reset_cancel() {
    CANCELLED.store(false, Ordering::SeqCst);
}

/// Whether [`cancel`] was called since the last [`reset_cancel`].
pub fn cancelled() -> bool {
    CANCELLED.load(Ordering::SeqCst)
}

/// Plans `lt` with `config` to the end; shows a progress bar on a terminal if `progress`.
///
/// # Errors
/// Bad input for an invalid task or settings; "failed" if no rollout could be evaluated.
pub fn plan<const N: usize, const K: usize>(
    lt: &LoadedTask,
    config: PlannerConfig,
    progress: bool,
) -> Result<Planned<N, K>, CliError> {
    plan_with(lt, config, progress, &mut || Ok(()))
}

/// [`plan`], calling `between` after every slice of integration steps: an error
/// from it stops planning and is returned (the Python binding's Ctrl-C). The plan does not
/// depend on `between` (slices of any size give the same bits).
///
/// # Errors
/// As [`plan`], and `between`'s.
pub fn plan_with<const N: usize, const K: usize>(
    lt: &LoadedTask,
    config: PlannerConfig,
    progress: bool,
    between: &mut dyn FnMut() -> Result<(), CliError>,
) -> Result<Planned<N, K>, CliError> {
    let task = lt.task::<N, K>()?;
    let mut planner: Box<HostPlanner<N, K>> =
        Box::new(Planner::new(task, config).or_input(|| "planner")?);
    let bar = if progress {
        bar(u64::from(config.max_rollouts), "rollouts {msg}")
    } else {
        ProgressBar::hidden()
    };
    let mut history = Vec::new();
    let mut refine_history = Vec::new();
    let mut best_per_rollout = Vec::new();
    let mut observer = |e: &Event| match e {
        Event::Evaluated { best, .. } => best_per_rollout.push(best.f),
        Event::Generation { best, .. } => history.push(best.f),
        Event::SwarmConverged { f, .. } => history.push(*f),
        Event::RefineTrial { f, .. } => refine_history.push(*f),
        Event::Stagnation { .. } => {}
    };
    let start = Instant::now();
    let plan = loop {
        match planner
            .step(SLICE, &mut observer)
            .or_failed(|| "planning failed")?
        {
            Status::Running(r) => {
                bar.set_position(u64::from(r.rollouts));
                bar.set_message(format!("best f {:.3e} ({:?})", r.best.f, r.stage));
                if let Err(e) = between() {
                    bar.finish_and_clear();
                    return Err(e);
                }
            }
            Status::Finished(plan) => break plan,
        }
    };
    bar.finish_and_clear();
    Ok(Planned {
        plan,
        history,
        refine_history,
        best_per_rollout,
        seconds: start.elapsed().as_secs_f64(),
        steps: planner.spent(),
    })
}
