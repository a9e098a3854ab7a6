//! `host-sim plan`: plans a task (the task's strategy, the multistart by default) to what
//! it asks for (the pose tolerances by default, see [`crate::goal`]); writes `plan.json`,
//! `trajectory.csv`, `summary.json` and the task bundle atomically (with `--plots` also the
//! figures and the 3-D replay page `view.html`).
//!
//! The trajectory is the plan's η rolled out again by the same code; it must reproduce the
//! outcome the planner evaluated bit for bit (checked here, so a mismatch is never written).
//!
//! A task with a `[preshape]` table is planned in two phases instead
//! ([`crate::preshaping`]: `plan.json`, `phase1.csv` and phase 2's bundle in `phase2/`).
//! Exit code 0 converged (what was asked is met), 1 not converged (outputs still written),
//! 2 bad input.

use crate::args::PlanArgs;
use crate::artifacts::{
    PlanFigures, PoseJson, RolloutRun, summary, write_bundle, write_figures, write_rollout,
};
use crate::drive::{self, HOST_CAPACITY};
use crate::error::CliError;
use crate::goal::{Asked, number, status_name};
use crate::output::OutDir;
use crate::retiming;
use crate::taskfile::{self, LoadedTask};
use crate::view;
use crate::with_dims;
use reactionless::{Plan, Stop, eta_flat};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// `plan.json`.
#[derive(Serialize, schemars::JsonSchema)]
pub struct PlanJson {
    /// `"converged"` (what was asked is met) or `"not_converged"`.
    pub status: &'static str,
    /// Why planning stopped: `"converged"`, `"exhausted"` (a budget was spent first) or
    /// `"stalled"` (the refinement could get no closer).
    pub stop: &'static str,
    /// What was asked, in words (see `[target] goal`).
    pub asked: String,
    /// The search strategy (`"multistart"` or `"cpso"`).
    pub strategy: &'static str,
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
    /// Rollouts of the search.
    pub search_rollouts: u32,
    /// Rollouts spent when a feasible rollout first had f ≤ σ_e (null if none did).
    pub first_hit_rollouts: Option<u32>,
    /// Multistart: LM starts after the first (0 for C-PSO).
    pub restarts: u32,
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
    /// f when the search stopped.
    pub search_f: f64,
    /// Refinement, if it ran.
    pub refine: Option<RefineJson>,
    /// End pose of the plan (planner model).
    pub end_pose: PoseJson,
    /// f of the truth-model end pose (the base drift included) against the target.
    pub truth_f: f64,
    /// Wall time of planning (s); not part of any record.
    pub wall_time_s: f64,
}

/// Refinement in `plan.json`.
#[derive(Serialize, schemars::JsonSchema)]
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

/// Plan a task to the pose it asks for (multistart by default, or the paper's C-PSO):
/// writes DIR/plan.json, DIR/trajectory.csv, DIR/summary.json and the task bundle. Exit code
/// 0 converged (what was asked is met), 1 not converged, 2 bad input.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML).
    task: PathBuf,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    planning: PlanArgs,
    /// Also write figures (PNG and SVG), convergence included, and the 3-D replay page
    /// view.html.
    #[arg(long)]
    plots: bool,
    /// Also re-time the plan to minimum time into OUT/retimed/ (as `host-sim retime`),
    /// under `[limits] qdd_max_deg_s2` or `--accel-deg-s2`; a two-phase plan whole (phase 1
    /// as planned, phase 2 re-timed), once converged.
    #[arg(long)]
    retime: bool,
    /// Acceleration limit of every joint for `--retime` (deg/s²).
    #[arg(long, requires = "retime")]
    accel_deg_s2: Option<f64>,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let mut lt = taskfile::load(&self.task)?;
        lt.set_integrator(self.planning.integrator)?;
        with_dims!(lt.chain.dof(), run_n, &lt, &self)
    }
}

fn run_n<const N: usize, const K: usize>(lt: &LoadedTask, args: &Args) -> Result<(), CliError> {
    let (config, asked) = lt.plan_settings(HOST_CAPACITY, &args.planning.overrides())?;
    if let Some(section) = &lt.file.preshape {
        crate::preshaping::plan::<N, K>(lt, section, &config, &asked, &args.out, args.plots)?;
        if args.retime {
            // The whole plan, as `host-sim retime OUT` does it: phase 1 as planned, phase 2
            // re-timed (only a converged plan gets here).
            let (phase1_s, s, path) = crate::retiming::retime_two_phase(
                &args.out,
                args.accel_deg_s2,
                None,
                &args.out.join("retimed"),
                args.plots,
            )?;
            eprintln!(
                "{}",
                crate::retiming::describe_two_phase(phase1_s, &s, &path)
            );
        }
        return Ok(());
    }
    let task = lt.task::<N, K>()?;
    let done = drive::plan::<N, K>(lt, config, true)?;
    let p = done.plan;
    let converged = p.converged();
    let dir = OutDir::create(&args.out)?;
    let mut run = write_rollout(&task, &p.eta, Some(&dir), args.plots)?;
    if run.outcome != p.outcome {
        return Err(CliError::internal(
            "the re-run rollout differs from the one the planner evaluated",
        ));
    }
    let truth = &run.truth;
    dir.write_json("summary.json", &summary(&task, &p.eta, &run.outcome, truth))?;
    let bundled = write_bundle(lt, &dir, Some((&config, &asked)))?;
    if let Some(trace) = run.trace.take() {
        let plan = PlanFigures {
            history: done.best_per_rollout.clone(),
            seed: config.seed,
            strategy: config.strategy,
            first_hit: p.first_hit,
        };
        write_figures(lt, &task, trace, Some(plan), &dir)?;
    }
    if args.plots {
        // From the files just written, exactly as `host-sim view DIR` reads them.
        dir.write(
            "view.html",
            view::render_dir(&dir.path(""), &args.out)?.as_bytes(),
        )?;
    }
    let json = PlanJson {
        status: status_name(converged),
        stop: p.stop.name(),
        asked: asked.describe(),
        strategy: p.strategy.name(),
        eta: eta_flat(&p.eta, task.motion().segments()).collect(),
        f: p.outcome.f,
        phi: p.outcome.phi,
        position_error_m: p.outcome.error.position_m(),
        orientation_error_deg: p.outcome.error.orientation_deg(),
        iterations: p.iterations,
        rollouts: p.rollouts,
        search_rollouts: p.search_rollouts,
        first_hit_rollouts: p.first_hit,
        restarts: p.restarts,
        abandoned_rollouts: p.abandoned,
        integration_steps: done.steps,
        stagnation_events: p.stagnation_events,
        seed: config.seed,
        best_f_history: done.history,
        search_f: p.search_f,
        refine: p.refine.map(|r| RefineJson {
            tolerance: config.refine_tolerance.unwrap_or(f64::NAN),
            stop: r.stop.name(),
            iterations: r.iterations,
            rollouts: r.rollouts,
            f_start: r.f_start,
            f_history: done.refine_history,
        }),
        end_pose: (&p.outcome.end_pose).into(),
        truth_f: truth.f,
        wall_time_s: done.seconds,
    };
    dir.write_json("plan.json", &json)?;
    let retimed = if args.retime {
        let qdd = lt.qdd_max_deg::<N>(args.accel_deg_s2)?.ok_or_else(|| {
            CliError::input(format!(
                "{}: --retime needs acceleration limits: give --accel-deg-s2 or set [limits] qdd_max_deg_s2",
                lt.path.display()
            ))
        })?;
        let sub = OutDir::create(&dir.path("retimed"))?;
        // From the plan's bundle, as `host-sim retime DIR` reads it: the re-timed bundle
        // carries the settings the plan used.
        let s = retiming::write(
            &bundled,
            &task,
            &p.eta,
            &qdd,
            lt.file.retime.grid,
            lt.file.retime.margin,
            &sub,
            args.plots,
        )?;
        sub.commit()?;
        Some(s)
    } else {
        None
    };
    let path = dir.commit()?;
    if let Some(s) = retimed {
        eprintln!("{}", retiming::describe(&s, &path.join("retimed")));
    }
    let clearance = clearance_of::<N>(lt, &path);
    eprintln!(
        "{}",
        human_summary(lt, &asked, &p, &json, &run, &path, clearance.as_ref())
    );
    if let Some((text, true)) = &clearance {
        return Err(CliError::failed(format!(
            "the plan reaches the target but violates the required clearance: {text}; clearance is not yet a constraint of the planner (docs/collision.md)"
        )));
    }
    if converged {
        Ok(())
    } else {
        Err(CliError::failed(format!(
            "not converged: {} ({} rollouts)",
            missed(&asked, &p, N),
            p.rollouts
        )))
    }
}

/// The written plan's clearance line ([`crate::clearance::summary_line`]), read back from
/// its `trajectory.csv`; `None` without collision geometry.
fn clearance_of<const N: usize>(lt: &LoadedTask, dir: &Path) -> Option<(String, bool)> {
    let line = || -> Result<Option<(String, bool)>, CliError> {
        let csv = std::fs::read_to_string(dir.join("trajectory.csv"))
            .map_err(|e| CliError::input(format!("{}: {e}", dir.display())))?;
        let written = crate::output::read_trajectory_csv::<N>(dir, &csv)?;
        let Some(first) = written.first() else {
            return Ok(None);
        };
        let scene = lt.scene(&first.q)?;
        let times: Vec<f64> = written.iter().map(|s| s.t).collect();
        let qs: Vec<Vec<f64>> = written.iter().map(|s| s.q.to_vec()).collect();
        Ok(crate::clearance::summary_line(&scene, &times, &qs))
    };
    line().unwrap_or_else(|e| Some((format!("not measured: {e}"), false)))
}

/// Why a plan that is not converged misses what was asked, in one sentence: how it
/// stopped, where it ended, and for a 6-joint arm that stops at the planner model's floor
/// on a pose goal, that floor.
fn missed<const N: usize, const K: usize>(asked: &Asked, p: &Plan<N, K>, n: usize) -> String {
    let how = match p.stop {
        Stop::Converged => "converged",
        Stop::Exhausted => "the budget was spent first",
        Stop::Stalled => "it stalled: no step got closer",
    };
    let mut s = format!(
        "{how}; reached f = {} ({} m, {} deg), asked {}",
        number(p.outcome.f),
        number(p.outcome.error.position_m()),
        number(p.outcome.error.orientation_deg()),
        asked.describe()
    );
    if p.first_hit.is_some() {
        s.push_str(&format!("; σ_e = {} was met", number(asked.sigma_e)));
    }
    // 6 joints: 2K − 1 = 5 unknowns (η's direction) for the 6 pose equations, so a target
    // made by the truth model can lie off the planner model's reachable set.
    if n == 6 && p.first_hit.is_some() && !asked.against_truth() && asked.refine_tolerance.is_some()
    {
        s.push_str(&format!(
            ". A 6-joint arm has 5 unknowns for 6 pose equations: f = {} is this target's floor on the planner model; refine against the truth model (--refine-against truth) or loosen the pose tolerances",
            number(p.outcome.f)
        ));
    }
    s
}

/// The plan as an engineer reads it: reached against asked, the errors in their units, the
/// base disturbance and the largest rate against their limits, the cost, and where the
/// files are.
fn human_summary<const N: usize, const K: usize>(
    lt: &LoadedTask,
    asked: &Asked,
    p: &Plan<N, K>,
    json: &PlanJson,
    run: &RolloutRun<N>,
    dir: &Path,
    clearance: Option<&(String, bool)>,
) -> String {
    let limit_deg = lt.max_base_disturbance_deg();
    let disturbance = run.truth.base_disturbance_deg;
    let (rate_joint, ratio) = run
        .max_abs_qd
        .iter()
        .zip(lt.chain.joints.iter().map(|j| j.velocity))
        .enumerate()
        .map(|(j, (v, lim))| (j, v / lim))
        .fold((0, 0.0f64), |best, x| if x.1 > best.1 { x } else { best });
    let rate = run.max_abs_qd.get(rate_joint).copied().unwrap_or(0.0);
    let rate_limit = lt
        .chain
        .joints
        .get(rate_joint)
        .map_or(f64::NAN, |j| j.velocity);
    let verdict = if p.converged() {
        format!("converged; asked {}", asked.describe())
    } else {
        format!("NOT converged: {}", missed(asked, p, N))
    };
    let pass = |ok: bool| if ok { "ok" } else { "EXCEEDED" };
    format!(
        "plan: {verdict}\n\
         \x20 strategy             {} (seed {})\n\
         \x20 pose error f         {} (planner model), truth_f {} (base drift included)\n\
         \x20 position error       {} m\n\
         \x20 orientation error    {} deg\n\
         \x20 base disturbance     {} deg (requirement ≤ {limit_deg} deg: {})\n\
         \x20 largest joint rate   {} deg/s on {} (its limit {} deg/s: {:.0}%)\n\
         \x20 rollouts             {}{} in {:.2} s\n\
         {}\
         \x20 files                {}/ (plan.json, summary.json, trajectory.csv, task.toml, robot.urdf)",
        json.strategy,
        json.seed,
        number(json.f),
        number(json.truth_f),
        number(json.position_error_m),
        number(json.orientation_error_deg),
        number(disturbance),
        pass(disturbance <= limit_deg),
        number(rate.to_degrees()),
        lt.chain
            .joint_names
            .get(rate_joint)
            .map_or("?", String::as_str),
        number(rate_limit.to_degrees()),
        100.0 * ratio,
        json.rollouts,
        integrated_by(lt),
        json.wall_time_s,
        clearance.as_ref().map_or(String::new(), |c| format!(
            "  smallest clearance   {}\n",
            c.0
        )),
        dir.display(),
    )
}

/// ` (rk4, step H s)` for a task integrated by RK4; nothing for the reference Euler.
fn integrated_by(lt: &LoadedTask) -> String {
    match lt.motion() {
        Ok(m) if m.integrator() != reactionless::Integrator::Euler => format!(
            " ({}, step {} s)",
            m.integrator().name(),
            f64::from(m.stride()) * m.dt()
        ),
        _ => String::new(),
    }
}
