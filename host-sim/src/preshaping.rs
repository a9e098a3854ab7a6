//! Two-phase plans on the host (spec §15, docs/twophase.md): what `plan` writes for a task
//! with a `[preshape]` table, and what `check` verifies of it.
//!
//! Owns the two-phase output directory:
//! - `plan.json` ([`TwoPhaseJson`]): how the plan ended, phase 1 (duration, `q_s`, the
//!   wheels' demand against the task's bounds, the base shift) and phase 2;
//! - `task.toml` + `robot.urdf`: the task as given (with its `[preshape]`);
//! - `phase1.csv`: phase 1's written samples (`t, q…, q̇…`, s / rad / rad/s, as
//!   `trajectory.csv`), from the task's start to `q_s`, the attitude control holding the
//!   base;
//! - `phase2/`: phase 2 as an ordinary single-phase bundle (`task.toml`, `robot.urdf`,
//!   `trajectory.csv`, `summary.json`), in the inertial frame of phase 2's start: the base
//!   has translated by the base shift (the CoM stays put) and not rotated, so its target is
//!   the task's target moved by minus that shift. `check`, `view`, `retime` and `disperse`
//!   read it like any plan.
//!
//! `q_s` is written in degrees; the plan is re-evaluated from the `q_s` that the written
//! degrees give back, so every file agrees to the bit with what a reader re-computes.

use crate::artifacts::{PoseJson, TruthReport, summary, write_bundle, write_rollout};
use crate::error::{CliError, Context};
use crate::goal::{Asked, number, status_name};
use crate::output::{CsvSink, OutDir, read_trajectory_csv};
use crate::taskfile::{self, LoadedTask, PreshapeSection};
use reactionless::twophase::{
    TwoPhasePlan, TwoPhaseSearch, TwoPhaseStage, TwoPhaseStatus, TwoPhaseStop, fit_preshape,
    plan as plan_two_phase,
};
use reactionless::{Frames, Momentum, PlannerConfig, Sample, one_segment};
use serde::Serialize;
use std::path::Path;

pub use crate::artifacts::{PHASE1_CSV, PHASE2_DIR, is_two_phase, phase2_dir};

/// `plan.json` of a two-phase plan.
#[derive(Serialize, schemars::JsonSchema)]
pub struct TwoPhaseJson {
    /// `"converged"` or `"not_converged"`.
    pub status: &'static str,
    /// `"converged"`, `"exhausted"`, `"beyond_reach"` or `"preshape_bounds"`.
    pub stop: &'static str,
    /// What was asked, in words.
    pub asked: String,
    /// f of the best kinematic inverse (how well the target lies within reach).
    pub reach_f: f64,
    /// Rollouts spent.
    pub rollouts: u32,
    /// LM starts.
    pub starts: u32,
    /// Seed.
    pub seed: u64,
    /// Phase 1.
    pub phase1: Phase1Json,
    /// Phase 2 (null when no plan was evaluated: a target beyond reach).
    pub phase2: Option<Phase2Json>,
    /// Wall time of planning (s); not part of any record.
    pub wall_time_s: f64,
}

/// Phase 1 in `plan.json`.
#[derive(Serialize, schemars::JsonSchema)]
pub struct Phase1Json {
    /// Duration (s).
    pub duration_s: f64,
    /// Integration steps (`dt` of `[motion]`).
    pub steps: u32,
    /// `q_s`, phase 2's start (deg).
    pub q_s_deg: Vec<f64>,
    /// Largest joint move of phase 1 (deg).
    pub largest_move_deg: f64,
    /// Largest `|h_w|` on the written samples (N m s) and the bound.
    pub momentum_nms: f64,
    /// `[preshape] max_momentum_nms`.
    pub max_momentum_nms: f64,
    /// Largest `|Δh_w|/dt` (N m).
    pub torque_nm: f64,
    /// `[preshape] max_torque_nm`.
    pub max_torque_nm: f64,
    /// Base translation at `q_s` (m).
    pub base_shift_m: [f64; 3],
}

/// Phase 2 in `plan.json`.
#[derive(Serialize, schemars::JsonSchema)]
pub struct Phase2Json {
    /// η as `a1,b1,…,aK,bK`.
    pub eta: Vec<f64>,
    /// f (planner model).
    pub f: f64,
    /// ‖p_des − p‖ (m).
    pub position_error_m: f64,
    /// Angle of R_des Rᵀ (deg).
    pub orientation_error_deg: f64,
    /// Φ (rad).
    pub phi: f64,
    /// Largest base rotation, truth model (deg).
    pub base_disturbance_deg: f64,
    /// f of the truth-model end pose.
    pub truth_f: f64,
    /// End pose, planner model, in phase 2's frame.
    pub end_pose: PoseJson,
    /// Sub-directory holding phase 2's bundle.
    pub dir: &'static str,
}

/// The task text of phase 2: `[start]` at `q_s_deg`, `[target]` moved by `-shift`, no
/// `[preshape]`.
fn phase2_text(lt: &LoadedTask, q_s_deg: &[f64], shift: &[f64; 3]) -> Result<String, CliError> {
    let mut table: toml::Table = toml::from_str(&lt.text).or_internal(|| "re-reading the task")?;
    table.remove("preshape");
    let floats = |v: &[f64]| toml::Value::Array(v.iter().map(|x| toml::Value::Float(*x)).collect());
    if let Some(toml::Value::Table(start)) = table.get_mut("start") {
        start.insert("q_deg".into(), floats(q_s_deg));
    }
    let target = lt.target()?;
    let moved: Vec<f64> = (0..3).map(|i| target.position[i] - shift[i]).collect();
    if let Some(toml::Value::Table(t)) = table.get_mut("target") {
        t.insert("position_m".into(), floats(&moved));
    }
    toml::to_string(&table).or_internal(|| "writing phase 2's task")
}

/// The core's two-phase settings of `lt`: `[preshape]`'s bounds, phase 2's success test
/// (the refinement tolerance asked for, else σ_e, on the model `[planner] refine_against`
/// names), the planner's rollout budget and
/// `[check]`'s base-disturbance limit. What `plan`, `campaign` and the flight block use.
pub fn two_phase_config(
    lt: &LoadedTask,
    section: &PreshapeSection,
    config: &PlannerConfig,
    asked: &Asked,
) -> reactionless::TwoPhaseConfig {
    reactionless::TwoPhaseConfig {
        against_truth: asked.against_truth(),
        ..section.config(
            asked.refine_tolerance.unwrap_or(asked.sigma_e),
            config.max_rollouts,
            lt.max_base_disturbance_deg(),
        )
    }
}

/// The core's two-phase plan of `lt` with the settings the task and flags ask for: the
/// task, those settings, the plan and the wall time of planning (s). With `show`, a
/// spinner on stderr says where the search is (stage, rollouts, starts).
pub fn solve<const N: usize, const K: usize>(
    lt: &LoadedTask,
    section: &PreshapeSection,
    config: &PlannerConfig,
    asked: &Asked,
    show: bool,
) -> Result<
    (
        reactionless::Task<N, K>,
        reactionless::TwoPhaseConfig,
        TwoPhasePlan<N, K>,
        f64,
    ),
    CliError,
> {
    let task = lt.task::<N, K>()?;
    let tp = two_phase_config(lt, section, config, asked);
    let clock = std::time::Instant::now();
    let p = if show {
        search_with_progress(&task, &tp, config.seed)
    } else {
        plan_two_phase(&task, &tp, config.seed)
    }
    .map_err(|e| lt.err(format!("two-phase plan: {e}")))?;
    Ok((task, tp, p, clock.elapsed().as_secs_f64()))
}

/// Units per call between progress updates (a few milliseconds of work at most, one
/// truth-model rollout aside).
const PROGRESS_UNITS: u32 = 64;

/// The two-phase search stepped in slices, its stage and counts on a spinner; the same
/// bits as one call (RL-TWO-006).
fn search_with_progress<const N: usize, const K: usize>(
    task: &reactionless::Task<N, K>,
    tp: &reactionless::TwoPhaseConfig,
    seed: u64,
) -> Result<TwoPhasePlan<N, K>, reactionless::Error> {
    let mut search = Box::new(TwoPhaseSearch::<N, K>::IDLE);
    search.reset(task, tp, seed)?;
    let spinner = crate::drive::spinner("plan: two phases, reach check");
    let result = loop {
        match search.step(PROGRESS_UNITS) {
            Ok(TwoPhaseStatus::Running) => spinner.set_message(format!(
                "plan: two phases, {}, {}/{} rollouts, {} starts",
                match search.stage() {
                    TwoPhaseStage::Reach => "reach check",
                    TwoPhaseStage::Screen => "screening starts",
                    _ => "searching",
                },
                search.rollouts(),
                tp.max_rollouts,
                search.starts()
            )),
            Ok(TwoPhaseStatus::Finished(p)) => break Ok(p),
            Err(e) => break Err(e),
        }
    };
    spinner.finish_and_clear();
    result
}

/// `plan` of a task with `[preshape]`: plans both phases and writes the directory described
/// in the module documentation; exit code 1 when not converged (files still written).
pub fn plan<const N: usize, const K: usize>(
    lt: &LoadedTask,
    section: &PreshapeSection,
    config: &PlannerConfig,
    asked: &Asked,
    out: &Path,
    plots: bool,
) -> Result<(), CliError> {
    eprintln!(
        "plan: two phases ([preshape]): reach check, then up to {} rollouts …",
        config.max_rollouts
    );
    let (task, tp, p, wall) = solve::<N, K>(lt, section, config, asked, true)?;
    let tolerance = tp.tolerance;
    let dir = OutDir::create(out)?;
    write_bundle(lt, &dir, None)?;
    // q_s as the files hold it: degrees, and back.
    let q_s_deg: Vec<f64> = p.q_s.iter().map(|q| q.to_degrees()).collect();
    let mut q_s = [0.0; N];
    for (q, d) in q_s.iter_mut().zip(&q_s_deg) {
        *q = d.to_radians();
    }
    let (preshape, demand, fits) =
        fit_preshape(&task, &tp, &q_s).map_err(|e| CliError::internal(format!("phase 1: {e}")))?;
    let largest_move_deg = q_s
        .iter()
        .zip(task.start())
        .map(|(a, b)| (a - b).abs().to_degrees())
        .fold(0.0, f64::max);
    let phase1 = Phase1Json {
        duration_s: preshape.duration(),
        steps: preshape.steps(),
        q_s_deg: q_s_deg.clone(),
        largest_move_deg,
        momentum_nms: demand.momentum_nms,
        max_momentum_nms: section.max_momentum_nms,
        torque_nm: demand.torque_nm,
        max_torque_nm: section.max_torque_nm,
        base_shift_m: demand.base_shift_m,
    };
    let mut phase2 = None;
    let mut converged = false;
    if p.outcome.is_some() {
        let mut csv = CsvSink::create(&dir.path(PHASE1_CSV), N)?;
        preshape.write(&mut |s: &Sample<N>| csv.push(s));
        csv.finish()?;
        let text = phase2_text(lt, &q_s_deg, &demand.base_shift_m)?;
        let lt2 = taskfile::from_texts(&lt.path, &text, &lt.urdf_text)?;
        let task2 = lt2.task::<N, K>()?;
        let sub = OutDir::create(&dir.path(PHASE2_DIR))?;
        let run = write_rollout(&task2, &one_segment(p.eta), Some(&sub), false)?;
        sub.write_json(
            "summary.json",
            &summary(&task2, &one_segment(p.eta), &run.outcome, &run.truth),
        )?;
        write_bundle(&lt2, &sub, Some((config, asked)))?;
        sub.commit()?;
        let o = run.outcome;
        // On the model the goal was asked on (the truth model's end pose, or the planner's).
        let f = if asked.against_truth() {
            run.truth.f
        } else {
            o.f
        };
        converged = p.converged() && fits && f <= tolerance && o.phi == 0.0;
        phase2 = Some(Phase2Json {
            eta: p.eta.iter().flatten().copied().collect(),
            f: o.f,
            position_error_m: o.error.position_m(),
            orientation_error_deg: o.error.orientation_deg(),
            phi: o.phi,
            base_disturbance_deg: run.truth.base_disturbance_deg,
            truth_f: run.truth.f,
            end_pose: (&o.end_pose).into(),
            dir: PHASE2_DIR,
        });
    }
    let json = TwoPhaseJson {
        status: status_name(converged),
        stop: p.stop.name(),
        asked: asked.describe(),
        reach_f: p.reach_f,
        rollouts: p.rollouts,
        starts: p.starts,
        seed: config.seed,
        phase1,
        phase2,
        wall_time_s: wall,
    };
    dir.write_json("plan.json", &json)?;
    if plots && json.phase2.is_some() {
        // Both phases on one page, from the files just written (as `host-sim view DIR`).
        dir.write(
            "view.html",
            crate::view::render_dir(&dir.path(""), out)?.as_bytes(),
        )?;
    }
    let path = dir.commit()?;
    eprintln!("{}", human_summary(lt, &json, &path));
    if converged {
        Ok(())
    } else {
        Err(CliError::failed(match p.stop {
            TwoPhaseStop::BeyondReach => format!(
                "not converged: the target is beyond the arm's reach within its limits (the closest configuration leaves f = {}); nothing was rolled out",
                number(p.reach_f)
            ),
            TwoPhaseStop::PreshapeBounds => format!(
                "not converged: plans reached the target, but none whose phase 1 the attitude control can serve within [preshape] max_duration_s = {} s ({} rollouts)",
                number(section.max_duration_s),
                p.rollouts
            ),
            _ => format!(
                "not converged: the budget was spent first; closest f = {} ({} rollouts), asked {}",
                number(json.phase2.as_ref().map_or(f64::NAN, |p2| p2.f)),
                p.rollouts,
                asked.describe()
            ),
        }))
    }
}

fn human_summary(lt: &LoadedTask, j: &TwoPhaseJson, dir: &Path) -> String {
    let p1 = &j.phase1;
    let limit = lt.max_base_disturbance_deg();
    let mut s = format!(
        "plan: {} in two phases ({}); asked {}\n\
         \x20 phase 1 (attitude controlled)  {} s, largest joint move {} deg\n\
         \x20   wheels' momentum               {} N m s (bound {})\n\
         \x20   wheels' torque                 {} N m (bound {})\n",
        if j.status == "converged" {
            "converged"
        } else {
            "NOT converged"
        },
        j.stop,
        j.asked,
        number(p1.duration_s),
        number(p1.largest_move_deg),
        number(p1.momentum_nms),
        number(p1.max_momentum_nms),
        number(p1.torque_nm),
        number(p1.max_torque_nm),
    );
    if let Some(p2) = &j.phase2 {
        s.push_str(&format!(
            "\x20 phase 2 (free floating)        f = {} ({} m, {} deg)\n\
             \x20   truth model                    truth_f = {}\n\
             \x20   base disturbance               {} deg (requirement ≤ {limit} deg)\n",
            number(p2.f),
            number(p2.position_error_m),
            number(p2.orientation_error_deg),
            number(p2.truth_f),
            number(p2.base_disturbance_deg),
        ));
    }
    s.push_str(&format!(
        "\x20 rollouts                       {} in {:.2} s\n\
         \x20 files                          {}/ (plan.json, phase1.csv, phase2/, task.toml, robot.urdf)",
        j.rollouts,
        j.wall_time_s,
        dir.display()
    ));
    s
}

/// A two-phase plan of `lt` in memory (for `campaign`): the plan, phase 2 flown on the
/// truth model (from `q_s` as planned), whether it met what was asked, and the wall time
/// of planning (s).
pub fn plan_in_memory<const N: usize, const K: usize>(
    lt: &LoadedTask,
    section: &PreshapeSection,
    config: &PlannerConfig,
    asked: &Asked,
) -> Result<(TwoPhasePlan<N, K>, Option<TruthReport>, bool, f64), CliError> {
    let (task, _, p, wall) = solve::<N, K>(lt, section, config, asked, false)?;
    let truth = match p.outcome {
        Some(_) => {
            let mut task2 = task.clone();
            task2
                .move_start(&p.q_s)
                .map_err(|e| CliError::internal(format!("phase 2's start: {e}")))?;
            Some(write_rollout(&task2, &one_segment(p.eta), None, false)?.truth)
        }
        None => None,
    };
    let converged = p.converged();
    Ok((p, truth, converged, wall))
}

/// One verified item of a two-phase directory: what, found, allowed, passed.
pub type Item = (String, String, String, bool);

/// The checks of phase 1 and of how phase 2 joins it (`check` adds phase 2's own). `dir`
/// holds the task bundle, `phase1.csv` and `phase2/`.
pub fn verify(dir: &Path, lt: &LoadedTask, lt2: &LoadedTask) -> Result<Vec<Item>, CliError> {
    crate::with_dims!(lt.chain.dof(), verify_n, dir, lt, lt2)
}

fn verify_n<const N: usize, const K: usize>(
    dir: &Path,
    lt: &LoadedTask,
    lt2: &LoadedTask,
) -> Result<Vec<Item>, CliError> {
    let section = lt.file.preshape.ok_or_else(|| {
        CliError::input(format!("{}: task.toml has no [preshape]", dir.display()))
    })?;
    let task = lt.task::<N, K>()?;
    let task2 = lt2.task::<N, K>()?;
    let tp = section.config(1e-6, 1, lt.max_base_disturbance_deg());
    let csv = std::fs::read_to_string(dir.join(PHASE1_CSV))
        .or_input(|| format!("{}: {PHASE1_CSV}", dir.display()))?;
    let written = read_trajectory_csv::<N>(&dir.join(PHASE1_CSV), &csv)?;
    let robot = task.robot();
    let dt = task.motion().dt();
    let mut items: Vec<Item> = Vec::new();
    let mut add = |c: &str, v: String, l: String, ok: bool| items.push((c.into(), v, l, ok));
    let q_s = *task2.start();
    let (fresh, demand, _) =
        fit_preshape(&task, &tp, &q_s).map_err(|e| CliError::input(format!("phase 1: {e}")))?;
    let same = written.len() == fresh.steps() as usize + 1
        && written.iter().enumerate().all(|(j, s)| {
            let (q, qd) = fresh.sample(j as u32);
            s.q == q && s.qd == qd && s.t == j as f64 * dt
        });
    add(
        "phase 1 matches a fresh phase 1 to phase 2's start",
        if same {
            "bit for bit".into()
        } else {
            "differs".into()
        },
        "every bit".into(),
        same,
    );
    let (first, last) = (written.first(), written.last());
    let ends = first.is_some_and(|s| s.q == *task.start() && s.qd == [0.0; N])
        && last.is_some_and(|s| s.q == q_s && s.qd == [0.0; N]);
    add(
        "phase 1 from [start] to phase 2's start, at rest at both",
        if ends { "exactly".into() } else { "no".into() },
        "= [start], = phase2/ [start], q̇ = 0".into(),
        ends,
    );
    let (mut rate, mut accel, mut margin) = (0.0f64, 0.0f64, f64::INFINITY);
    for (j, s) in written.iter().enumerate() {
        for r in 0..N {
            margin = margin
                .min(s.q[r] - robot.lower()[r])
                .min(robot.upper()[r] - s.q[r]);
            if let Some(n) = written.get(j + 1) {
                rate = rate.max((n.q[r] - s.q[r]).abs() / dt / robot.qd_max());
                if let Some(p) = j.checked_sub(1).and_then(|i| written.get(i)) {
                    let a = (n.q[r] - 2.0 * s.q[r] + p.q[r]).abs() / (dt * dt);
                    accel = accel.max(a / tp.qdd_max);
                }
            }
        }
    }
    add(
        "phase 1 joint rates (differences of the written q)",
        format!("{rate:.6} of the limit"),
        "<= 1 x the robot's rate limit (spec §11)".into(),
        rate <= 1.0,
    );
    add(
        "phase 1 joint accelerations (second differences)",
        format!("{accel:.6} of the limit"),
        format!(
            "<= {} deg/s² ([preshape] qdd_max_deg_s2)",
            number(section.qdd_max_deg_s2)
        ),
        accel <= 1.0 + 1e-9,
    );
    add(
        "phase 1 joint limits",
        format!("min margin {} deg", number(margin.to_degrees())),
        ">= 0".into(),
        margin >= 0.0,
    );
    let duration = fresh.duration();
    add(
        "phase 1 duration",
        format!("{} s", number(duration)),
        format!(
            "<= {} s ([preshape] max_duration_s)",
            number(section.max_duration_s)
        ),
        duration <= section.max_duration_s,
    );
    // The wheels' demand from the written samples: h_w = −H~bm(q) q̇.
    let (mut h, mut tau, mut last_h) = (0.0f64, 0.0f64, None::<[f64; 3]>);
    for s in &written {
        let m = Momentum::new(robot, &Frames::new(robot, &s.q)).coupling_momentum(&s.qd);
        let hw = [-m.x, -m.y, -m.z];
        h = h.max(norm(&hw));
        if let Some(l) = last_h {
            tau = tau.max(norm(&[hw[0] - l[0], hw[1] - l[1], hw[2] - l[2]]) / dt);
        }
        last_h = Some(hw);
    }
    add(
        "phase 1 wheels' momentum |h_w|, h_w = -H~bm q̇",
        format!("{} N m s", number(h)),
        format!(
            "<= {} N m s ([preshape] max_momentum_nms)",
            number(section.max_momentum_nms)
        ),
        h <= section.max_momentum_nms,
    );
    add(
        "phase 1 wheels' torque |Δh_w|/dt",
        format!("{} N m", number(tau)),
        format!(
            "<= {} N m ([preshape] max_torque_nm)",
            number(section.max_torque_nm)
        ),
        tau <= section.max_torque_nm,
    );
    // Phase 2's frame: the base moved by the shift, the target by minus it.
    let target = task.target();
    let moved = task2.target();
    let shift = demand.base_shift_m;
    let gap = (0..3)
        .map(|i| (target.position[i] - shift[i] - moved.position[i]).abs())
        .fold(0.0, f64::max);
    let frame_ok = gap <= 1e-12
        && moved.quat_wxyz == target.quat_wxyz
        && lt2.urdf_text == lt.urdf_text
        && task2.motion() == task.motion();
    add(
        "phase 2's target = the task's, moved by minus the base shift",
        format!("{} m apart", number(gap)),
        "<= 1e-12 m, same attitude, robot and motion".into(),
        frame_ok,
    );
    let start = task2.start_pose().error_to(moved);
    let d = norm(&start.position);
    let a = norm(&start.rotation);
    add(
        "standoff at phase 2's start",
        format!(
            "{} m, {} deg from the target",
            number(d),
            number(a.to_degrees())
        ),
        format!(
            ">= {} m or >= {} deg ([preshape] standoff_m, standoff_deg)",
            number(section.standoff_m),
            number(section.standoff_deg)
        ),
        d >= section.standoff_m || a >= section.standoff_deg.to_radians(),
    );
    Ok(items)
}

fn norm(v: &[f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}
