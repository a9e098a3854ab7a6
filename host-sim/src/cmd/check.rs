//! `host-sim check DIR`: independent verification of what `plan` or `rollout` wrote.
//!
//! Reads the trajectory **as written** (`trajectory.csv`, the artifact that would be flown)
//! with the task bundle beside it (`task.toml`, `robot.urdf`) and the η of `summary.json`,
//! then verifies:
//! - the file's shape and time grid (`t_s = s·dt`, last = `t_f`, to the bit);
//! - every value equals a fresh rollout of the recorded η, bit for bit;
//! - each row follows from the previous one by the integrator (`q_{s+1} = q_s + dt·q̇_s`);
//! - joint limits; `|q̇| ≤` each joint's velocity limit; `q̇ = 0` at both ends;
//! - the end pose (planner model, from the written `q_S`) within the task's tolerance;
//! - the base disturbance of the written path (truth model, 10 midpoint sub-steps) below
//!   `[check] max_base_disturbance_deg`.
//!
//! A re-timed bundle (`retime`, `plan --retime`; its summary has `original_duration_s`) is
//! verified instead against a fresh re-timing of its η (bit for bit), the time grid and
//! duration, every rate and acceleration against its limit (written q̈ and central
//! differences of the written q̇, 0.5 % tolerance), rest at both ends, the end q against
//! the original plan's (1e-9 rad), the end pose and the base disturbance (truth model).
//!
//! A two-phase plan (`phase1.csv` beside `phase2/`) is verified phase by phase: phase 1's
//! written samples against a fresh phase 1 (bit for bit), its rate, acceleration and joint
//! limits on the written q, its duration, the wheels' momentum and torque recomputed from
//! the written samples against `[preshape]`, phase 2's frame and the standoff; then phase
//! 2's bundle as above.
//!
//! With collision geometry in the URDF or `[[keep_out]]`s in the task, also the clearance
//! of the written path (spec §13, `crate::clearance`): the smallest signed distance of every
//! checked pair over the piecewise-linear path between the samples, with no tunnelling,
//! against `[collision] clearance_m`; `--clearance-json FILE` writes it pair by pair.
//!
//! Prints a table. Exit 0 if everything passes, 1 if anything fails, 2 if the directory
//! cannot be read as a host-sim output.

use crate::args::parse_eta;
use crate::artifacts::{Summary, read_bundle, read_output_file};
use crate::clearance::{PairMin, RESOLUTION_M, Scene, Side, Sweep};
use crate::error::{CliError, Context};
use crate::goal::{Asked, Goal, number};
use crate::output::read_trajectory_csv;
use crate::retiming::{self, RetimeSummary};
use crate::taskfile::LoadedTask;
use crate::with_dims;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::integrator::euler_step;
use reactionless::retime::Setpoint;
use reactionless::{Eta, IDENTITY_WXYZ, Integrator, Sample, Sink, Task, TruthModel};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Verify an output directory of `plan` or `rollout` independently: the trajectory as
/// written against a fresh rollout, the integrator, every limit, the pose error and the
/// base disturbance. Exit code 0 all pass, 1 a check failed, 2 unreadable.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory of `plan` or `rollout`.
    dir: PathBuf,
    /// Also write the path's clearance, pair by pair, to this JSON file (the smallest
    /// signed distance of each pair in m, when, between which primitives, and at the
    /// written samples only).
    #[arg(long, value_name = "FILE")]
    clearance_json: Option<PathBuf>,
}

impl Args {
    /// Runs the subcommand: prints the table, fails with exit code 1 if a check fails.
    pub fn run(self) -> Result<(), CliError> {
        if let Some(file) = &self.clearance_json {
            write_clearance_json(&self.dir, file)?;
        }
        run(&self.dir)
    }
}

/// One line of the report.
#[derive(Debug, Clone, PartialEq)]
pub struct Line {
    /// What was checked.
    pub check: String,
    /// What was found.
    pub value: String,
    /// What is allowed.
    pub limit: String,
    /// Whether it passed.
    pub pass: bool,
}

fn line(check: &str, value: String, limit: String, pass: bool) -> Line {
    Line {
        check: check.to_string(),
        value,
        limit,
        pass,
    }
}

/// Prints the table of `dir`'s checks; fails with exit code 1 if a check fails.
pub fn run(dir: &Path) -> Result<(), CliError> {
    let lines = verify(dir)?;
    println!("{}", table(&lines));
    let failed: Vec<&str> = lines
        .iter()
        .filter(|l| !l.pass)
        .map(|l| l.check.as_str())
        .collect();
    if failed.is_empty() {
        println!(
            "check: PASS, all {} checks of {}",
            lines.len(),
            dir.display()
        );
        Ok(())
    } else {
        Err(CliError::failed(format!(
            "{}: verification failed: {}",
            dir.display(),
            failed.join(", ")
        )))
    }
}

/// All checks of `dir`.
pub fn verify(dir: &Path) -> Result<Vec<Line>, CliError> {
    if crate::preshaping::is_two_phase(dir) {
        return verify_two_phase(dir);
    }
    let lt = read_bundle(dir)?;
    let summary_text = read_output_file(dir, "summary.json")?;
    let csv = read_output_file(dir, "trajectory.csv")?;
    if summary_text.contains("\"original_duration_s\"") {
        let summary: RetimeSummary = serde_json::from_str(&summary_text)
            .or_input(|| format!("{}: summary.json", dir.display()))?;
        return with_dims!(lt.chain.dof(), verify_retimed, &lt, dir, &summary, &csv);
    }
    let summary: Summary = serde_json::from_str(&summary_text)
        .or_input(|| format!("{}: summary.json", dir.display()))?;
    with_dims!(lt.chain.dof(), verify_n, &lt, dir, &summary.eta, &csv)
}

/// A two-phase plan: phase 1 and the join ([`crate::preshaping::verify`]), then phase 2's
/// bundle as any plan, each line prefixed by its phase.
fn verify_two_phase(dir: &Path) -> Result<Vec<Line>, CliError> {
    let lt = read_bundle(dir)?;
    let p2 = crate::preshaping::phase2_dir(dir);
    let lt2 = read_bundle(&p2)?;
    let mut lines: Vec<Line> = crate::preshaping::verify(dir, &lt, &lt2)?
        .into_iter()
        .map(|(c, v, l, ok)| line(&c, v, l, ok))
        .collect();
    for mut l in verify(&p2)? {
        l.check = format!("phase 2: {}", l.check);
        lines.push(l);
    }
    Ok(lines)
}

/// Limits may be exceeded by this factor at a written setpoint (the 0.5 %).
pub const RETIME_TOLERANCE: f64 = 1.005;

/// The worst `|value|/limit` over the setpoints, and where.
fn worst_ratio<const N: usize>(
    written: &[Setpoint<N>],
    limits: &[f64],
    pick: impl Fn(&Setpoint<N>) -> [f64; N],
    name: &str,
) -> (f64, String) {
    let mut worst = (0.0f64, String::from("none"));
    for (row, s) in written.iter().enumerate() {
        for (j, (v, l)) in pick(s).iter().zip(limits).enumerate() {
            let r = v.abs() / l;
            if r > worst.0 || r.is_nan() {
                worst = (r, format!("{name}{} at row {row}", j + 1));
            }
        }
    }
    worst
}

/// The checks of a re-timed bundle (written by `retime` or `plan --retime`), one
/// function each.
fn verify_retimed<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    summary: &RetimeSummary,
    csv: &str,
) -> Result<Vec<Line>, CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(&summary.eta, task.motion().segments())?;
    let written = retiming::read_csv::<N>(dir, csv)?;
    let qdd_deg = lt.qdd_max_deg::<N>(None)?.ok_or_else(|| {
        CliError::input(format!(
            "{}: a re-timed bundle without [limits] qdd_max_deg_s2",
            dir.display()
        ))
    })?;
    let fresh = retiming::compute(
        &task,
        &eta,
        &qdd_deg,
        lt.file.retime.grid,
        lt.file.retime.margin,
    )?;
    let asked = lt.asked(&lt.file.planner, false)?;
    let dt = task.motion().dt();
    let samples: Vec<Sample<N>> = written
        .iter()
        .map(|s| Sample {
            step: s.step,
            t: s.t,
            q: s.q,
            qd: s.qd,
        })
        .collect();
    let mut truth = TruthModel::new(&task, TRUTH_SUBSTEPS);
    for s in &written {
        truth.push(&s.q, s.t);
    }
    let mut lines = vec![
        retimed_grid(&written, dt),
        retimed_duration(&written, summary, &fresh, dt),
        matches_fresh_retiming(&written, &fresh),
        written_rates(&written, &fresh, dt),
        written_accelerations(&written, &fresh, dt),
        retimed_rates(&written, &fresh),
        retimed_accelerations(&written, &fresh),
        accelerations_from_rates(&written, &fresh, dt),
        joint_limits(&task, &samples),
        rest_line(
            "qd = 0 at both ends",
            written.first().map(|s| &s.qd[..]),
            written.last().map(|s| &s.qd[..]),
        ),
        end_q_unchanged(&written, &fresh),
    ];
    lines.extend(pose_lines(&asked, &task, &samples, &truth));
    lines.push(base_disturbance(lt, &truth));
    lines.extend(clearance_lines(lt, &samples)?);
    Ok(lines)
}

/// The re-timed grid `t_k = k·dt`, to the bit.
fn retimed_grid<const N: usize>(written: &[Setpoint<N>], dt: f64) -> Line {
    let bad_t = written
        .iter()
        .enumerate()
        .find(|(k, s)| s.t.to_bits() != (*k as f64 * dt).to_bits());
    line(
        "time grid",
        bad_t.map_or("exact".into(), |(k, s)| format!("row {k}: t = {}", s.t)),
        format!("t_k = k*{dt} s"),
        bad_t.is_none(),
    )
}

/// The written duration: the summary's, at least the minimum time and less than one step
/// above it.
fn retimed_duration<const N: usize>(
    written: &[Setpoint<N>],
    summary: &RetimeSummary,
    fresh: &retiming::Retimed<N>,
    dt: f64,
) -> Line {
    let last_t = written.last().map_or(f64::NAN, |s| s.t);
    line(
        "duration",
        format!("{last_t} s (minimum {:.4} s)", fresh.optimal_duration_s),
        format!(
            "= summary duration_s {} s, < minimum + dt",
            summary.duration_s
        ),
        last_t == summary.duration_s
            && last_t >= fresh.optimal_duration_s
            && last_t < fresh.optimal_duration_s + dt * (1.0 + 1e-9),
    )
}

/// Every written setpoint is a fresh re-timing's, bit for bit.
fn matches_fresh_retiming<const N: usize>(
    written: &[Setpoint<N>],
    fresh: &retiming::Retimed<N>,
) -> Line {
    let bits = |s: &Setpoint<N>| {
        std::iter::once(s.t)
            .chain(s.q)
            .chain(s.qd)
            .chain(s.qdd)
            .map(f64::to_bits)
            .collect::<Vec<_>>()
    };
    let same = written.len() == fresh.setpoints.len()
        && written
            .iter()
            .zip(&fresh.setpoints)
            .all(|(a, b)| bits(a) == bits(b));
    line(
        "matches a fresh re-timing of eta",
        if same {
            "bit for bit".into()
        } else {
            format!(
                "{} rows written, {} computed, or values differ",
                written.len(),
                fresh.setpoints.len()
            )
        },
        "every bit".into(),
        same,
    )
}

/// Spec §11's rate test on the written q: `|q(τ+1) − q(τ)|/dt ≤ q̇max`, exactly.
fn written_rates<const N: usize>(
    written: &[Setpoint<N>],
    fresh: &retiming::Retimed<N>,
    dt: f64,
) -> Line {
    let mut worst = (0.0f64, String::from("none"));
    for (row, w) in written.windows(2).enumerate() {
        for (j, v) in fresh.limits.qd_max().iter().enumerate() {
            let r = (w[1].q[j] - w[0].q[j]).abs() / dt / v;
            if r > worst.0 || r.is_nan() {
                worst = (r, format!("q{} rows {}-{}", j + 1, row, row + 1));
            }
        }
    }
    line(
        "joint rates (differences of the written q)",
        format!("{:.6} of the limit ({})", worst.0, worst.1),
        "<= 1 x rate limit (spec §11)".into(),
        worst.0 <= 1.0,
    )
}

/// Spec §11's acceleration test on the written q: `|q(τ+1) − 2q(τ) + q(τ−1)|/dt² ≤ q̈max`,
/// exactly.
fn written_accelerations<const N: usize>(
    written: &[Setpoint<N>],
    fresh: &retiming::Retimed<N>,
    dt: f64,
) -> Line {
    let mut worst = (0.0f64, String::from("none"));
    for (row, w) in written.windows(3).enumerate() {
        for (j, a) in fresh.limits.qdd_max().iter().enumerate() {
            let r = (w[2].q[j] - 2.0 * w[1].q[j] + w[0].q[j]).abs() / (dt * dt) / a;
            if r > worst.0 || r.is_nan() {
                worst = (r, format!("q{} around row {}", j + 1, row + 1));
            }
        }
    }
    line(
        "joint accelerations (second differences of the written q)",
        format!("{:.6} of the limit ({})", worst.0, worst.1),
        "<= 1 x acceleration limit (spec §11)".into(),
        worst.0 <= 1.0,
    )
}

/// The written rates against the rate limits.
fn retimed_rates<const N: usize>(written: &[Setpoint<N>], fresh: &retiming::Retimed<N>) -> Line {
    let (r, at) = worst_ratio(written, fresh.limits.qd_max(), |s| s.qd, "qd");
    line(
        "joint rates (qd column)",
        format!("{r:.4} of the limit ({at})"),
        format!("<= {RETIME_TOLERANCE} x rate limit"),
        r <= RETIME_TOLERANCE,
    )
}

/// The written accelerations against the acceleration limits.
fn retimed_accelerations<const N: usize>(
    written: &[Setpoint<N>],
    fresh: &retiming::Retimed<N>,
) -> Line {
    let (r, at) = worst_ratio(written, fresh.limits.qdd_max(), |s| s.qdd, "qdd");
    line(
        "joint accelerations (qdd column)",
        format!("{r:.4} of the limit ({at})"),
        format!("<= {RETIME_TOLERANCE} x acceleration limit"),
        r <= RETIME_TOLERANCE,
    )
}

/// Independent of the written q̈: central differences of the written q̇ against the
/// acceleration limits.
fn accelerations_from_rates<const N: usize>(
    written: &[Setpoint<N>],
    fresh: &retiming::Retimed<N>,
    dt: f64,
) -> Line {
    let mut fd = 0.0f64;
    let mut fd_at = String::from("none");
    for (row, w) in written.windows(3).enumerate() {
        for (j, lim) in fresh.limits.qdd_max().iter().enumerate() {
            let a = (w[2].qd[j] - w[0].qd[j]) / (2.0 * dt);
            let ratio = a.abs() / lim;
            if ratio > fd || ratio.is_nan() {
                fd = ratio;
                fd_at = format!("qd{} around row {}", j + 1, row + 1);
            }
        }
    }
    line(
        "joint accelerations (differences of qd)",
        format!("{fd:.4} of the limit ({fd_at})"),
        format!("<= {RETIME_TOLERANCE} x acceleration limit"),
        fd <= RETIME_TOLERANCE,
    )
}

/// The re-timed path ends where the original plan's does.
fn end_q_unchanged<const N: usize>(written: &[Setpoint<N>], fresh: &retiming::Retimed<N>) -> Line {
    let end_diff = written.last().map_or(f64::INFINITY, |s| {
        s.q.iter()
            .zip(&fresh.q_final)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    });
    line(
        "end q vs the original plan's q_S",
        format!("{} rad", number(end_diff)),
        "<= 1e-9 rad".into(),
        end_diff <= 1e-9,
    )
}

fn column_name<const N: usize>(c: usize) -> String {
    match c {
        0 => "t".into(),
        c if c <= N => format!("q{c}"),
        c => format!("qd{}", c - N),
    }
}

fn values<const N: usize>(s: &Sample<N>) -> Vec<f64> {
    std::iter::once(s.t).chain(s.q).chain(s.qd).collect()
}

fn verify_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    eta: &[f64],
    csv: &str,
) -> Result<Vec<Line>, CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(eta, task.motion().segments())?;
    let written = read_trajectory_csv::<N>(dir, csv)?;
    let mut lines = shape(&task, &written);
    lines.push(matches_fresh_rollout(&task, &eta, &written));
    lines.push(follows_integrator(&task, &written));
    lines.push(joint_limits(&task, &written));
    lines.push(joint_rates(lt, &written));
    lines.push(rest_at_both_ends(&written, task.motion().integrator()));
    let mut truth = TruthModel::new(&task, TRUTH_SUBSTEPS);
    for s in &written {
        truth.sample(s);
    }
    let asked = lt.asked(&lt.file.planner, false)?;
    lines.extend(pose_lines(&asked, &task, &written, &truth));
    lines.push(base_disturbance(lt, &truth));
    lines.extend(clearance_lines(lt, &written)?);
    Ok(lines)
}

/// The clearance of the written path, if the robot or the task has collision geometry.
fn sweep_of<const N: usize>(
    lt: &LoadedTask,
    written: &[Sample<N>],
) -> Result<Option<(Scene, Sweep)>, CliError> {
    let q0: Vec<f64> = match written.first() {
        Some(s) => s.q.to_vec(),
        None => return Ok(None),
    };
    let scene = lt.scene(&q0)?;
    if scene.is_empty() {
        return Ok(None);
    }
    let times: Vec<f64> = written.iter().map(|s| s.t).collect();
    let qs: Vec<Vec<f64>> = written.iter().map(|s| s.q.to_vec()).collect();
    let sweep = scene.sweep(&times, &qs);
    Ok(Some((scene, sweep)))
}

/// The smallest clearance over every pair, and a line for every other pair that fails.
fn clearance_lines<const N: usize>(
    lt: &LoadedTask,
    written: &[Sample<N>],
) -> Result<Vec<Line>, CliError> {
    let Some((scene, sweep)) = sweep_of(lt, written)? else {
        return Ok(Vec::new());
    };
    let limit = if sweep.enforced {
        format!(
            ">= {} m + {RESOLUTION_M:e} m between samples ([collision] clearance_m)",
            sweep.required_m
        )
    } else {
        "not required (the task has no [collision] and no [[keep_out]])".to_string()
    };
    let describe = |p: &PairMin| {
        let (a, b) = scene.part_names(p);
        format!(
            "{:.6} m, {} ({a}, {b}) at t = {:.2} s{}",
            p.min_m,
            scene.pair_name(p.pair),
            p.t_s,
            if p.resolved { "" } else { " (unresolved)" }
        )
    };
    let ok = |p: &PairMin| !sweep.enforced || sweep.keeps(p);
    let mut lines = Vec::new();
    if let Some(w) = sweep.worst() {
        lines.push(line(
            &format!("clearance ({} pairs)", sweep.pairs.len()),
            describe(w),
            limit.clone(),
            sweep.pass(),
        ));
        for p in sweep.pairs.iter().filter(|p| !ok(p) && p.pair != w.pair) {
            lines.push(line("clearance", describe(p), limit.clone(), false));
        }
    }
    Ok(lines)
}

/// `--clearance-json`: the written path's clearance, every pair.
fn write_clearance_json(dir: &Path, file: &Path) -> Result<(), CliError> {
    let lt = read_bundle(dir)?;
    let csv = read_output_file(dir, "trajectory.csv")?;
    let report = with_dims!(lt.chain.dof(), clearance_json, &lt, dir, &csv)?;
    crate::output::write_file(file, report.as_bytes(), crate::output::FileKind::Clearance)
}

fn clearance_json<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    csv: &str,
) -> Result<String, CliError> {
    let written = read_trajectory_csv::<N>(dir, csv)?;
    let Some((scene, sweep)) = sweep_of(lt, &written)? else {
        return Err(CliError::input(format!(
            "{}: no collision geometry and no keep-out: there is no clearance to write",
            dir.display()
        )));
    };
    let side = |s: Side| match s {
        Side::Body(i) => scene.body_names[i].clone(),
        Side::KeepOut(k) => scene.keep_outs[k].name.clone(),
    };
    let pairs: Vec<serde_json::Value> = sweep
        .pairs
        .iter()
        .map(|p| {
            let (pa, pb) = scene.part_names(p);
            serde_json::json!({
                "a": side(p.pair.0),
                "b": side(p.pair.1),
                "b_is_keep_out": matches!(p.pair.1, Side::KeepOut(_)),
                "a_part": pa,
                "b_part": pb,
                "min_m": p.min_m,
                "t_s": p.t_s,
                "min_at_samples_m": p.min_at_samples_m,
                "sample": p.sample,
                "resolved": p.resolved,
            })
        })
        .collect();
    let doc = serde_json::json!({
        "format": "reactionless-clearance/1",
        "required_m": sweep.required_m,
        "resolution_m": RESOLUTION_M,
        "required": sweep.enforced,
        "clear": sweep.clear(),
        "pass": sweep.pass(),
        "evaluations_between_samples": sweep.evaluations,
        "pairs": pairs,
    });
    let mut text =
        serde_json::to_string_pretty(&doc).map_err(|e| CliError::internal(e.to_string()))?;
    text.push('\n');
    Ok(text)
}

/// Sample count `t_f/dt + 1` and the time grid `t_s = s·dt`, to the bit.
fn shape<const N: usize, const K: usize>(task: &Task<N, K>, written: &[Sample<N>]) -> Vec<Line> {
    let motion = task.motion();
    let expected = motion.steps() as usize + 1;
    let bad_t = written
        .iter()
        .enumerate()
        .find(|(s, x)| x.t.to_bits() != motion.time(*s as u32).to_bits());
    vec![
        line(
            "samples",
            written.len().to_string(),
            format!("= {expected} (t_f/dt + 1)"),
            written.len() == expected,
        ),
        line(
            "time grid",
            bad_t.map_or("exact".into(), |(s, x)| format!("row {s}: t = {}", x.t)),
            format!("t_s = s*{} s", motion.dt()),
            bad_t.is_none(),
        ),
    ]
}

/// Every written value equals a fresh rollout of the recorded η, bit for bit.
fn matches_fresh_rollout<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &Eta<K>,
    written: &[Sample<N>],
) -> Line {
    let mut fresh = Vec::with_capacity(written.len());
    let rerun = task.rollout_of(eta, &mut |s: &Sample<N>| fresh.push(*s));
    let mismatch = match &rerun {
        Err(e) => Some(format!("rollout of eta failed: {e}")),
        Ok(_) if fresh.len() != written.len() => Some(format!(
            "{} samples written, {} computed",
            written.len(),
            fresh.len()
        )),
        Ok(_) => written
            .iter()
            .zip(&fresh)
            .enumerate()
            .find_map(|(row, (w, f))| {
                let (a, b) = (values(w), values(f));
                a.iter()
                    .zip(&b)
                    .position(|(x, y)| x.to_bits() != y.to_bits())
                    .map(|c| {
                        format!(
                            "row {row}, {}: written {:e}, computed {:e}",
                            column_name::<N>(c),
                            a[c],
                            b[c]
                        )
                    })
            }),
    };
    line(
        "matches a fresh rollout of eta",
        mismatch.clone().unwrap_or_else(|| "bit for bit".into()),
        "every bit".into(),
        mismatch.is_none(),
    )
}

/// Each row follows from the previous one by the integrator, on the written values alone:
/// `q' = q + dt·q̇` to the bit for Euler; for RK4 (whose rows are the dense output, the
/// rate the chord to the next) to [`RK4_ROW_TOLERANCE`] rad.
fn follows_integrator<const N: usize, const K: usize>(
    task: &Task<N, K>,
    written: &[Sample<N>],
) -> Line {
    let dt = task.motion().dt();
    let rk4 = task.motion().integrator() != Integrator::Euler;
    let mut worst = 0.0f64;
    let euler = written.windows(2).enumerate().find_map(|(row, w)| {
        let (a, b) = (&w[0], &w[1]);
        if rk4 {
            let mut next = a.q;
            euler_step(&mut next, &a.qd, b.t - a.t);
            let off = next
                .iter()
                .zip(&b.q)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0, f64::max);
            worst = worst.max(off);
            let within = off <= RK4_ROW_TOLERANCE;
            return (!within).then(|| format!("row {} -> {}: off by {off:e} rad", row, row + 1));
        }
        let mut next = a.q;
        euler_step(&mut next, &a.qd, dt);
        next.iter()
            .zip(&b.q)
            .position(|(x, y)| x.to_bits() != y.to_bits())
            .map(|j| format!("row {} -> {}: q{}", row, row + 1, j + 1))
    });
    let (got, want) = if rk4 {
        (
            format!("every row, within {worst:.1e} rad"),
            format!("<= {RK4_ROW_TOLERANCE:e} rad"),
        )
    } else {
        ("every row".into(), "exact".into())
    };
    line(
        "rows follow q' = q + dt*qd",
        euler.clone().unwrap_or(got),
        want,
        euler.is_none(),
    )
}

/// How far an RK4 row may be from `q + dt·q̇` of the row before (rad): rounding only (the
/// rate is the chord `(q' − q)/dt`).
const RK4_ROW_TOLERANCE: f64 = 1e-12;

/// Every written q within its joint's limits.
fn joint_limits<const N: usize, const K: usize>(task: &Task<N, K>, written: &[Sample<N>]) -> Line {
    let robot = task.robot();
    let mut worst = f64::INFINITY;
    let mut worst_at = String::new();
    for (row, s) in written.iter().enumerate() {
        for (j, ((q, lo), hi)) in s.q.iter().zip(robot.lower()).zip(robot.upper()).enumerate() {
            let margin = (q - lo).min(hi - q);
            if margin < worst {
                worst = margin;
                worst_at = format!("q{} at row {row}", j + 1);
            }
        }
    }
    line(
        "joint limits",
        format!("min margin {:.4} deg ({worst_at})", worst.to_degrees()),
        ">= 0".into(),
        worst >= 0.0,
    )
}

/// Every written |q̇| against its own joint's velocity limit.
fn joint_rates<const N: usize>(lt: &LoadedTask, written: &[Sample<N>]) -> Line {
    let mut worst_ratio = 0.0f64;
    let mut worst_rate = String::new();
    for (row, s) in written.iter().enumerate() {
        for (j, (v, limit)) in
            s.qd.iter()
                .zip(lt.chain.joints.iter().map(|j| j.velocity))
                .enumerate()
        {
            let ratio = v.abs() / limit;
            if ratio > worst_ratio || ratio.is_nan() {
                worst_ratio = ratio;
                worst_rate = format!(
                    "{:.4} deg/s (qd{} at row {row}, limit {:.4})",
                    v.abs().to_degrees(),
                    j + 1,
                    limit.to_degrees()
                );
            }
        }
    }
    line(
        "joint rates",
        worst_rate,
        "<= velocity limit".into(),
        worst_ratio <= 1.0,
    )
}

/// q̇ = 0 exactly at the first and the last sample; for RK4 and AB5, whose first row's rate
/// is the chord over `[0, dt]` of a path that starts at rest, at the last.
fn rest_at_both_ends<const N: usize>(written: &[Sample<N>], integrator: Integrator) -> Line {
    if integrator != Integrator::Euler {
        let last = written.last().map(|s| &s.qd[..]);
        let what = format!(
            "qd = 0 at t_f ({}: row 0 holds the chord)",
            integrator.name()
        );
        return rest_line(&what, last, last);
    }
    rest_line(
        "qd = 0 at t = 0 and t_f",
        written.first().map(|s| &s.qd[..]),
        written.last().map(|s| &s.qd[..]),
    )
}

/// `q̇ = 0` exactly in the first and last rows (`None`: no rows).
fn rest_line(name: &str, first: Option<&[f64]>, last: Option<&[f64]>) -> Line {
    let ends_zero = match (first, last) {
        (Some(a), Some(b)) => a.iter().chain(b).all(|v| *v == 0.0),
        _ => false,
    };
    line(
        name,
        if ends_zero {
            "exactly".into()
        } else {
            "not zero".into()
        },
        "= 0".into(),
        ends_zero,
    )
}

/// The end pose of the written `q_S` against what the bundle's task asked for
/// ([`Asked`]): f within the refinement tolerance (the planner's f, or `truth_f` with the
/// truth model's end pose when it refined against the truth), else within σ_e; and with the
/// pose goal, the position and orientation errors within their tolerances, in the same
/// model.
fn pose_lines<const N: usize, const K: usize>(
    asked: &Asked,
    task: &Task<N, K>,
    written: &[Sample<N>],
    truth: &TruthModel<'_, N, K>,
) -> Vec<Line> {
    let model = asked.model();
    let pose = if asked.against_truth() {
        truth.end_pose()
    } else {
        written
            .last()
            .map(|last| task.end_pose(&last.q, IDENTITY_WXYZ))
    };
    let f_name = if asked.against_truth() {
        "truth_f"
    } else {
        "f"
    };
    let name = format!("pose error {f_name} ({model})");
    let Some(e) = pose.map(|pose| pose.error_to(task.target())) else {
        return vec![line(&name, "no samples".into(), String::new(), false)];
    };
    let (tolerance, key) = match (asked.goal, asked.refine_tolerance) {
        (Goal::Pose, Some(t)) => (t, "the pose goal's f"),
        (Goal::SigmaE, Some(t)) => (t, "[planner] refine_tolerance"),
        (_, None) => (asked.sigma_e, "[planner] tolerance, σ_e"),
    };
    let mut lines = vec![line(
        &name,
        format!(
            "{} ({} m, {} deg)",
            number(e.norm()),
            number(e.position_m()),
            number(e.orientation_deg())
        ),
        format!("<= {tolerance:e} ({key})"),
        e.norm() <= tolerance,
    )];
    if let Some(p) = asked.position_m {
        let v = e.position_m();
        lines.push(line(
            &format!("end-effector position error ({model})"),
            format!("{} m", number(v)),
            format!("<= {p:e} m ([target] position_tolerance_m)"),
            v <= p,
        ));
    }
    if let Some(o) = asked.orientation_deg {
        let v = e.orientation_deg();
        lines.push(line(
            &format!("end-effector orientation error ({model})"),
            format!("{} deg", number(v)),
            format!("<= {o:e} deg ([target] orientation_tolerance_deg)"),
            v <= o,
        ));
    }
    lines
}

/// The written path through the truth model, below `[check] max_base_disturbance_deg`.
fn base_disturbance<const N: usize, const K: usize>(
    lt: &LoadedTask,
    truth: &TruthModel<'_, N, K>,
) -> Line {
    let limit = lt.max_base_disturbance_deg();
    let deg = truth.max_angle().to_degrees();
    line(
        "base disturbance (truth model)",
        match truth.error() {
            Some(e) => format!("failed: {e}"),
            None => format!("{} deg", number(deg)),
        },
        format!("<= {limit} deg ([check] max_base_disturbance_deg)"),
        truth.error().is_none() && deg <= limit,
    )
}

/// The report as an aligned text table.
pub fn table(lines: &[Line]) -> String {
    let w0 = lines
        .iter()
        .map(|l| l.check.len())
        .max()
        .unwrap_or(5)
        .max(5);
    let w1 = lines
        .iter()
        .map(|l| l.value.len())
        .max()
        .unwrap_or(5)
        .max(5);
    let mut out = format!(
        "{:<w0$}  {:<w1$}  {:<6}  limit\n",
        "check", "value", "result"
    );
    for l in lines {
        let _ = writeln!(
            out,
            "{:<w0$}  {:<w1$}  {:<6}  {}",
            l.check,
            l.value,
            if l.pass { "pass" } else { "FAIL" },
            l.limit
        );
    }
    out.trim_end().to_string()
}
