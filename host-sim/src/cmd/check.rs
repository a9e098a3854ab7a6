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
//! Prints a table. Exit 0 if everything passes, 1 if anything fails, 2 if the directory
//! cannot be read as a host-sim output.

use crate::args::parse_eta;
use crate::artifacts::{Summary, TRUTH_SUBSTEPS, read_bundle, read_output_file};
use crate::error::{CliError, Context};
use crate::output::read_trajectory_csv;
use crate::retiming::{self, RetimeSummary};
use crate::taskfile::LoadedTask;
use crate::with_dims;
use reactionless::integrator::euler_step;
use reactionless::retime::Setpoint;
use reactionless::{IDENTITY_WXYZ, RefineAgainst, Sample, Sink, Task, TruthModel};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Verify an output directory of `plan` or `rollout` independently: the trajectory as
/// written against a fresh rollout, the integrator, every limit, the pose error and the
/// base disturbance. Exit code 0 all pass, 1 a check failed, 2 unreadable.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory of `plan` or `rollout`.
    dir: PathBuf,
}

impl Args {
    /// Runs the subcommand: prints the table, fails with exit code 1 if a check fails.
    pub fn run(self) -> Result<(), CliError> {
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

/// The checks of a re-timed bundle (written by `retime` or `plan --retime`).
fn verify_retimed<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    summary: &RetimeSummary,
    csv: &str,
) -> Result<Vec<Line>, CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(&summary.eta)?;
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
    let dt = task.motion().dt();
    let mut lines = Vec::new();
    let bad_t = written
        .iter()
        .enumerate()
        .find(|(k, s)| s.t.to_bits() != (*k as f64 * dt).to_bits());
    lines.push(line(
        "time grid",
        bad_t.map_or("exact".into(), |(k, s)| format!("row {k}: t = {}", s.t)),
        format!("t_k = k*{dt} s"),
        bad_t.is_none(),
    ));
    let last_t = written.last().map_or(f64::NAN, |s| s.t);
    lines.push(line(
        "duration",
        format!("{last_t} s (minimum {:.4} s)", fresh.optimal_duration_s),
        format!(
            "= summary duration_s {} s, < minimum + dt",
            summary.duration_s
        ),
        last_t == summary.duration_s
            && last_t >= fresh.optimal_duration_s
            && last_t < fresh.optimal_duration_s + dt * (1.0 + 1e-9),
    ));
    let same = written.len() == fresh.setpoints.len()
        && written.iter().zip(&fresh.setpoints).all(|(a, b)| {
            let bits = |s: &Setpoint<N>| {
                std::iter::once(s.t)
                    .chain(s.q)
                    .chain(s.qd)
                    .chain(s.qdd)
                    .map(f64::to_bits)
                    .collect::<Vec<_>>()
            };
            bits(a) == bits(b)
        });
    lines.push(line(
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
    ));
    let qd_lim = fresh.limits.qd_max().to_vec();
    let qdd_lim = fresh.limits.qdd_max().to_vec();
    let (r, at) = worst_ratio(&written, &qd_lim, |s| s.qd, "qd");
    lines.push(line(
        "joint rates",
        format!("{:.4} of the limit ({at})", r),
        format!("<= {RETIME_TOLERANCE} x rate limit"),
        r <= RETIME_TOLERANCE,
    ));
    let (r, at) = worst_ratio(&written, &qdd_lim, |s| s.qdd, "qdd");
    lines.push(line(
        "joint accelerations (written)",
        format!("{:.4} of the limit ({at})", r),
        format!("<= {RETIME_TOLERANCE} x acceleration limit"),
        r <= RETIME_TOLERANCE,
    ));
    // Independent of the written q̈: central differences of the written q̇.
    let mut fd = 0.0f64;
    let mut fd_at = String::from("none");
    for (row, w) in written.windows(3).enumerate() {
        for (j, lim) in qdd_lim.iter().enumerate() {
            let a = (w[2].qd[j] - w[0].qd[j]) / (2.0 * dt);
            let ratio = a.abs() / lim;
            if ratio > fd || ratio.is_nan() {
                fd = ratio;
                fd_at = format!("qd{} around row {}", j + 1, row + 1);
            }
        }
    }
    lines.push(line(
        "joint accelerations (differences of qd)",
        format!("{fd:.4} of the limit ({fd_at})"),
        format!("<= {RETIME_TOLERANCE} x acceleration limit"),
        fd <= RETIME_TOLERANCE,
    ));
    lines.push(joint_limits(
        &task,
        &written
            .iter()
            .map(|s| Sample {
                step: s.step,
                t: s.t,
                q: s.q,
                qd: s.qd,
            })
            .collect::<Vec<_>>(),
    ));
    lines.push(rest_line(
        "qd = 0 at both ends",
        written.first().map(|s| &s.qd[..]),
        written.last().map(|s| &s.qd[..]),
    ));
    let end_diff = written.last().map_or(f64::INFINITY, |s| {
        s.q.iter()
            .zip(&fresh.q_final)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max)
    });
    lines.push(line(
        "end q vs the original plan's q_S",
        format!("{end_diff:.3e} rad"),
        "<= 1e-9 rad".into(),
        end_diff <= 1e-9,
    ));
    let tolerance = lt.file.planner.tolerance;
    let e = written
        .last()
        .map(|s| {
            task.end_pose(&s.q, IDENTITY_WXYZ)
                .error_to(task.target())
                .norm()
        })
        .unwrap_or(f64::INFINITY);
    lines.push(line(
        "pose error f (planner model)",
        format!("{e:.3e}"),
        format!("<= {tolerance:e} ([planner] tolerance)"),
        e <= tolerance.max(lt.file.planner.refine_tolerance.unwrap_or(0.0)),
    ));
    let mut truth = TruthModel::new(&task, TRUTH_SUBSTEPS);
    for s in &written {
        truth.push(&s.q, s.t);
    }
    lines.push(base_disturbance(lt, &truth));
    Ok(lines)
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
    let eta = parse_eta::<K>(eta)?;
    let written = read_trajectory_csv::<N>(dir, csv)?;
    let mut lines = shape(&task, &written);
    lines.push(matches_fresh_rollout(&task, &eta, &written));
    lines.push(follows_integrator(&task, &written));
    lines.push(joint_limits(&task, &written));
    lines.push(joint_rates(lt, &written));
    lines.push(rest_at_both_ends(&written));
    let mut truth = TruthModel::new(&task, TRUTH_SUBSTEPS);
    for s in &written {
        truth.sample(s);
    }
    lines.push(pose_error(lt, &task, &written, &truth));
    lines.extend(pose_tolerances(lt, &task, &written, &truth)?);
    lines.push(base_disturbance(lt, &truth));
    Ok(lines)
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
    eta: &[[f64; 2]; K],
    written: &[Sample<N>],
) -> Line {
    let mut fresh = Vec::with_capacity(written.len());
    let rerun = task.rollout(eta, &mut |s: &Sample<N>| fresh.push(*s));
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

/// Each row follows from the previous one by the integrator, on the written values alone.
fn follows_integrator<const N: usize, const K: usize>(
    task: &Task<N, K>,
    written: &[Sample<N>],
) -> Line {
    let dt = task.motion().dt();
    let euler = written.windows(2).enumerate().find_map(|(row, w)| {
        let (a, b) = (&w[0], &w[1]);
        let mut next = a.q;
        euler_step(&mut next, &a.qd, dt);
        next.iter()
            .zip(&b.q)
            .position(|(x, y)| x.to_bits() != y.to_bits())
            .map(|j| format!("row {} -> {}: q{}", row, row + 1, j + 1))
    });
    line(
        "rows follow q' = q + dt*qd",
        euler.clone().unwrap_or_else(|| "every row".into()),
        "exact".into(),
        euler.is_none(),
    )
}

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

/// q̇ = 0 exactly at the first and the last sample.
fn rest_at_both_ends<const N: usize>(written: &[Sample<N>]) -> Line {
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

/// The end pose of the written `q_S` within the tolerance that was asked for: the
/// refinement's if the task refines (against the truth model: the truth-model end pose),
/// else σ_e (planner model).
fn pose_error<const N: usize, const K: usize>(
    lt: &LoadedTask,
    task: &Task<N, K>,
    written: &[Sample<N>],
    truth: &TruthModel<'_, N, K>,
) -> Line {
    let planner = &lt.file.planner;
    // A bad [target] tolerance has its own line (pose_tolerances); here it is left out.
    let refine = lt
        .refine_with_pose_tolerances(planner.refine_tolerance)
        .unwrap_or(planner.refine_tolerance);
    let (tolerance, key) = match (refine, planner.refine_tolerance) {
        (Some(t), Some(r)) if t == r => (t, "[planner] refine_tolerance"),
        (Some(t), _) => (t, "[target] pose tolerances"),
        (None, _) => (planner.tolerance, "[planner] tolerance"),
    };
    let against_truth = refine.is_some() && planner.refine_against == RefineAgainst::Truth;
    let name = if against_truth {
        "pose error truth_f (truth model)"
    } else {
        "pose error f (planner model)"
    };
    let pose = if against_truth {
        truth.end_pose()
    } else {
        written
            .last()
            .map(|last| task.end_pose(&last.q, IDENTITY_WXYZ))
    };
    let Some(pose) = pose else {
        return line(name, "no samples".into(), String::new(), false);
    };
    let e = pose.error_to(task.target());
    line(
        name,
        format!(
            "{:.3e} ({:.3e} m, {:.3e} deg)",
            e.norm(),
            e.position_m(),
            e.orientation_deg()
        ),
        format!("<= {tolerance:e} ({key})"),
        e.norm() <= tolerance,
    )
}

/// The end pose's position and orientation errors, each within `[target]
/// position_tolerance_m` and `orientation_tolerance_deg` when the task sets them (the model
/// that the pose-error line uses).
fn pose_tolerances<const N: usize, const K: usize>(
    lt: &LoadedTask,
    task: &Task<N, K>,
    written: &[Sample<N>],
    truth: &TruthModel<'_, N, K>,
) -> Result<Vec<Line>, CliError> {
    let (p, o) = lt.pose_tolerances()?;
    let planner = &lt.file.planner;
    let against_truth = lt
        .refine_with_pose_tolerances(planner.refine_tolerance)?
        .is_some()
        && planner.refine_against == RefineAgainst::Truth;
    let (model, pose) = if against_truth {
        ("truth model", truth.end_pose())
    } else {
        (
            "planner model",
            written
                .last()
                .map(|last| task.end_pose(&last.q, IDENTITY_WXYZ)),
        )
    };
    let e = pose.map(|pose| pose.error_to(task.target()));
    let mut lines = Vec::new();
    if let Some(p) = p {
        let value = e.map(|e| e.position_m());
        lines.push(line(
            &format!("end-effector position error ({model})"),
            value.map_or("no samples".into(), |v| format!("{v:.3e} m")),
            format!("<= {p:e} m ([target] position_tolerance_m)"),
            value.is_some_and(|v| v <= p),
        ));
    }
    if let Some(o) = o {
        let value = e.map(|e| e.orientation_deg());
        lines.push(line(
            &format!("end-effector orientation error ({model})"),
            value.map_or("no samples".into(), |v| format!("{v:.3e} deg")),
            format!("<= {o:e} deg ([target] orientation_tolerance_deg)"),
            value.is_some_and(|v| v <= o),
        ));
    }
    Ok(lines)
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
            None => format!("{deg:.3e} deg"),
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
