//! What `retime` and `plan --retime` write, and what `check` recomputes: a planned η
//! re-timed to minimum time under the joint rate limits (URDF) and acceleration limits
//! (`[limits] qdd_max_deg_s2` or `--accel-deg-s2`) with the core's [`reactionless::retime`].
//!
//! Owns [`RetimeSummary`] (`summary.json` of a re-timed bundle), [`compute`] (the core's
//! re-timing of one η: grid, solve, every setpoint) and [`write`] (the bundle:
//! `trajectory.csv` with header `t,q1..qN,qd1..qdN,qdd1..qddN`, `summary.json`, `task.toml`
//! with the limits and grid used, `robot.urdf`, and with `--plots` the rate and
//! acceleration figures, whose data and stamp are filled here and drawn by `plots`);
//! [`retime_bundle`] (a plan's or rollout's directory) and [`retime_two_phase`] (a
//! two-phase plan's directory whole: phase 1 as planned, phase 2 re-timed).

use crate::artifacts::PoseJson;
use crate::error::{CliError, Context};
use crate::output::OutDir;
use crate::plots::{self, RetimePlotData};
use crate::taskfile::{self, BUNDLE_TASK, BUNDLE_URDF, LoadedTask};
use crate::version::Build;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::retime::{self, GridPoint, Limits, Setpoint, Stream};
use reactionless::{Eta, IDENTITY_WXYZ, Task, TrajectoryDigest, TruthModel, eta_flat};
use serde::{Deserialize, Serialize};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// `summary.json` of a re-timed bundle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct RetimeSummary {
    /// η as given (the path is its rollout).
    pub eta: Vec<f64>,
    /// Written duration `K·dt` (s): the minimum time rounded up to a whole step.
    pub duration_s: f64,
    /// Minimum time on the grid before rounding (s).
    pub optimal_duration_s: f64,
    /// Duration of the plan as planned, `t_f` (s).
    pub original_duration_s: f64,
    /// Step of the setpoints (s).
    pub dt_s: f64,
    /// Steps `K` (the file has `K + 1` rows).
    pub steps: u32,
    /// Arc-length grid points.
    pub grid: u32,
    /// Limit margin factor applied.
    pub margin: f64,
    /// Joint-space arc length of the path (rad).
    pub path_length_rad: f64,
    /// Rate limits used, per joint, margin applied (rad/s).
    pub qd_max: Vec<f64>,
    /// Acceleration limits used, per joint, margin applied (rad/s²).
    pub qdd_max: Vec<f64>,
    /// Largest |q̇| per joint over the written setpoints (rad/s).
    pub max_abs_qdot: Vec<f64>,
    /// Largest |q̈| per joint over the written setpoints (rad/s²).
    pub max_abs_qddot: Vec<f64>,
    /// Largest `|q(τ+1) − q(τ)|/dt` over the rate limit, of the written q (spec §11; ≤ 1).
    pub written_rate_ratio: f64,
    /// Largest `|q(τ+1) − 2q(τ) + q(τ−1)|/dt²` over the acceleration limit, of the written q
    /// (spec §11; ≤ 1).
    pub written_accel_ratio: f64,
    /// Largest base rotation of the written path, truth model (deg).
    pub base_disturbance_deg: f64,
    /// End pose of the last written q (planner model).
    pub end_pose: PoseJson,
    /// f of that pose against the task target.
    pub f: f64,
    /// Largest |q_K − q_S| between the re-timed and the original end (rad).
    pub end_q_difference_rad: f64,
    /// FNV-1a-64 of every setpoint's bits (t, q, q̇, q̈), hex; what the flight image prints.
    pub setpoint_digest: String,
}

/// A re-timed η: the setpoints and the figures of the solve.
pub struct Retimed<const N: usize> {
    /// Every setpoint, `k = 0..=K`.
    pub setpoints: Vec<Setpoint<N>>,
    /// Minimum time on the grid (s).
    pub optimal_duration_s: f64,
    /// Arc length (rad).
    pub path_length_rad: f64,
    /// The limits in force.
    pub limits: Limits<N>,
    /// The original end configuration q_S (rad).
    pub q_final: [f64; N],
    /// The largest rate and acceleration ratios of the written q (spec §11).
    pub written: retime::Written,
}

/// Re-times `eta` of `task` on `grid` points under `qdd_max_deg` (deg/s²), the URDF rate
/// limits and `margin`.
pub fn compute<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &Eta<K>,
    qdd_max_deg: &[f64; N],
    grid: u32,
    margin: f64,
) -> Result<Retimed<N>, CliError> {
    let [eta, ..] = eta;
    if task.motion().segments() > 1 {
        return Err(CliError::input(format!(
            "re-timing a motion of {} segments is not supported yet: the path rests at each junction, and the re-timing needs a path that keeps moving",
            task.motion().segments()
        )));
    }
    let qd = task.robot().desc().joints.map(|j| j.velocity);
    let limits =
        Limits::new(qd, qdd_max_deg.map(f64::to_radians), margin).map_err(|e| match e.param() {
            Some(reactionless::Param::RetimeMargin) | None => {
                CliError::input(format!("[retime] margin = {margin}: {e}"))
            }
            Some(_) => CliError::input(format!("limits: {e}")),
        })?;
    let q_final = task
        .rollout(eta, &mut ())
        .or_failed(|| "rollout of eta failed")?
        .q_final;
    let mut storage = vec![GridPoint::<N>::ZERO; grid as usize];
    let path = retime::path_of_rollout(task, eta, &mut storage, grid).map_err(|e| {
        CliError::input(format!(
            "[retime] grid = {grid}: cannot build the path: {e}"
        ))
    })?;
    let (profile, written) =
        retime::solve_written(&mut storage, &path, &limits, task.motion().dt())
            .or_failed(|| "re-timing failed")?;
    let mut stream =
        Stream::new(&profile, task.motion().dt()).or_failed(|| "re-timed setpoints")?;
    let mut setpoints = Vec::with_capacity(stream.steps() as usize + 1);
    while let Some(sp) = stream.next(&storage) {
        setpoints.push(sp);
    }
    Ok(Retimed {
        setpoints,
        optimal_duration_s: profile.duration(),
        path_length_rad: path.length(),
        limits,
        q_final,
        written,
    })
}

/// Parses a re-timed `trajectory.csv` as [`write`] writes it: header [`header`], rows of
/// `1 + 3N` numbers, every value exactly as written; errors name `dir` and the row.
pub fn read_csv<const N: usize>(dir: &Path, csv: &str) -> Result<Vec<Setpoint<N>>, CliError> {
    let err = |m: String| CliError::input(format!("{}: trajectory.csv: {m}", dir.display()));
    let mut lines = csv.lines();
    let header = lines.next().ok_or_else(|| err("empty file".into()))?;
    let want = self::header(N);
    if header != want {
        return Err(err(format!("header {header:?}, expected {want:?}")));
    }
    let mut out = Vec::new();
    for (row, text) in lines.enumerate() {
        let v: Vec<f64> = text
            .split(',')
            .map(|v| v.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| err(format!("row {}: {e}", row + 1)))?;
        if v.len() != 1 + 3 * N {
            return Err(err(format!(
                "row {}: {} values, expected {}",
                row + 1,
                v.len(),
                1 + 3 * N
            )));
        }
        let mut s = Setpoint {
            step: row as u32,
            t: v[0],
            q: [0.0; N],
            qd: [0.0; N],
            qdd: [0.0; N],
        };
        s.q.copy_from_slice(&v[1..=N]);
        s.qd.copy_from_slice(&v[N + 1..=2 * N]);
        s.qdd.copy_from_slice(&v[2 * N + 1..]);
        out.push(s);
    }
    Ok(out)
}

/// The CSV header for `n` joints: `t,q1..qN,qd1..qdN,qdd1..qddN`.
pub fn header(n: usize) -> String {
    let mut h = String::from("t");
    for prefix in ["q", "qd", "qdd"] {
        for i in 1..=n {
            h.push_str(&format!(",{prefix}{i}"));
        }
    }
    h
}

/// The samples of `dir`'s `trajectory.csv` text: a plan's or rollout's
/// ([`crate::output::read_trajectory_csv`]) or a re-timed bundle's ([`read_csv`], its
/// accelerations dropped), told apart by the header.
pub fn read_samples<const N: usize>(
    dir: &Path,
    csv: &str,
) -> Result<Vec<reactionless::Sample<N>>, CliError> {
    if csv.lines().next() == Some(header(N).as_str()) {
        Ok(read_csv::<N>(dir, csv)?
            .iter()
            .map(|s| reactionless::Sample {
                step: s.step,
                t: s.t,
                q: s.q,
                qd: s.qd,
            })
            .collect())
    } else {
        crate::output::read_trajectory_csv::<N>(dir, csv)
    }
}

/// The digest of a setpoint sequence, as 16 hex digits.
pub fn digest<const N: usize>(setpoints: &[Setpoint<N>]) -> String {
    let mut d = TrajectoryDigest::new();
    for sp in setpoints {
        sp.digest(&mut d);
    }
    format!("{:016x}", d.value())
}

/// The truth model over the setpoints as written: its largest base rotation (deg).
pub fn base_disturbance_deg<const N: usize, const K: usize>(
    task: &Task<N, K>,
    setpoints: &[Setpoint<N>],
) -> Result<f64, CliError> {
    let mut truth = TruthModel::new(task, TRUTH_SUBSTEPS);
    for sp in setpoints {
        truth.push(&sp.q, sp.t);
    }
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    Ok(truth.max_angle().to_degrees())
}

/// Largest |value| per joint of `pick` over the setpoints.
pub fn max_abs<const N: usize>(
    setpoints: &[Setpoint<N>],
    pick: impl Fn(&Setpoint<N>) -> [f64; N],
) -> Vec<f64> {
    let mut m = vec![0.0f64; N];
    for sp in setpoints {
        for (o, v) in m.iter_mut().zip(pick(sp)) {
            *o = o.max(v.abs());
        }
    }
    m
}

/// Writes the re-timed bundle of `eta` into `dir` and returns its summary.
#[allow(clippy::too_many_arguments)]
pub fn write<const N: usize, const K: usize>(
    lt: &LoadedTask,
    task: &Task<N, K>,
    eta: &Eta<K>,
    qdd_max_deg: &[f64; N],
    grid: u32,
    margin: f64,
    dir: &OutDir,
    plots: bool,
) -> Result<RetimeSummary, CliError> {
    let r = compute(task, eta, qdd_max_deg, grid, margin)?;
    let sp = &r.setpoints;
    let last = sp
        .last()
        .ok_or_else(|| CliError::internal("no setpoints"))?;
    let mut csv = std::io::BufWriter::new(
        std::fs::File::create(dir.path("trajectory.csv"))
            .or_input(|| "cannot create trajectory.csv")?,
    );
    let mut text = header(N);
    text.push('\n');
    let mut buf = ryu::Buffer::new();
    for s in sp {
        text.push_str(buf.format(s.t));
        for v in s.q.iter().chain(&s.qd).chain(&s.qdd) {
            text.push(',');
            text.push_str(buf.format(*v));
        }
        text.push('\n');
    }
    csv.write_all(text.as_bytes())
        .and_then(|()| csv.flush())
        .or_input(|| "writing trajectory.csv")?;
    let end = task.end_pose(&last.q, IDENTITY_WXYZ);
    let dt = task.motion().dt();
    let summary = RetimeSummary {
        eta: eta_flat(eta, task.motion().segments()).collect(),
        duration_s: last.t,
        optimal_duration_s: r.optimal_duration_s,
        original_duration_s: task.motion().tf(),
        dt_s: dt,
        steps: last.step,
        grid,
        margin,
        path_length_rad: r.path_length_rad,
        qd_max: r.limits.qd_max().to_vec(),
        qdd_max: r.limits.qdd_max().to_vec(),
        max_abs_qdot: max_abs(sp, |s| s.qd),
        max_abs_qddot: max_abs(sp, |s| s.qdd),
        written_rate_ratio: r.written.rate,
        written_accel_ratio: r.written.accel,
        base_disturbance_deg: base_disturbance_deg(task, sp)?,
        end_pose: (&end).into(),
        f: end.error_to(task.target()).norm(),
        end_q_difference_rad: last
            .q
            .iter()
            .zip(&r.q_final)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max),
        setpoint_digest: digest(sp),
    };
    dir.write_json("summary.json", &summary)?;
    write_bundle(lt, dir, qdd_max_deg, grid, margin)?;
    if plots {
        write_figures(&dir.path(""), lt, &r)?;
    }
    Ok(summary)
}

/// The figures of a re-timed bundle: each joint's rate and acceleration against its
/// limits ([`plots::write_retime_data`]), stamped with the task and the build.
fn write_figures<const N: usize>(
    dir: &Path,
    lt: &LoadedTask,
    r: &Retimed<N>,
) -> Result<Vec<String>, CliError> {
    let sp = &r.setpoints;
    plots::write_retime_data(
        dir,
        &RetimePlotData {
            joint_names: lt.chain.joint_names.clone(),
            t: sp.iter().map(|s| s.t).collect(),
            qd: sp.iter().map(|s| s.qd.to_vec()).collect(),
            qdd: sp.iter().map(|s| s.qdd.to_vec()).collect(),
            qd_limit: r.limits.qd_max().to_vec(),
            qdd_limit: r.limits.qdd_max().to_vec(),
            stamp: format!(
                "{} · retimed · {}",
                lt.path.display(),
                Build::current().stamp()
            ),
        },
    )
}

/// The bundle with the limits and grid that were used, so `check` re-derives the same bits.
fn write_bundle<const N: usize>(
    lt: &LoadedTask,
    dir: &OutDir,
    qdd_max_deg: &[f64; N],
    grid: u32,
    margin: f64,
) -> Result<(), CliError> {
    let (text, urdf) = lt.bundle(None)?;
    let mut table: toml::Table = toml::from_str(&text).or_internal(|| "re-reading the task")?;
    let mut limits = toml::Table::new();
    limits.insert(
        "qdd_max_deg_s2".into(),
        toml::Value::Array(qdd_max_deg.iter().map(|v| toml::Value::Float(*v)).collect()),
    );
    table.insert("limits".into(), toml::Value::Table(limits));
    let mut rt = toml::Table::new();
    rt.insert("grid".into(), toml::Value::Integer(i64::from(grid)));
    rt.insert("margin".into(), toml::Value::Float(margin));
    table.insert("retime".into(), toml::Value::Table(rt));
    let text = toml::to_string(&table).or_internal(|| "writing the task")?;
    dir.write(taskfile::BUNDLE_TASK, text.as_bytes())?;
    dir.write(taskfile::BUNDLE_URDF, urdf.as_bytes())
}

/// Reads a plan's or rollout's bundle from `dir` (`task.toml`, `robot.urdf`, the η of
/// `summary.json`) and re-times it into `out` ([`write`]); the summary and where it went.
pub fn retime_bundle(
    dir: &Path,
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
    out: &Path,
    plots: bool,
) -> Result<(RetimeSummary, PathBuf), CliError> {
    let (lt, eta) = read_planned(dir)?;
    crate::with_dims!(
        lt.chain.dof(),
        write_dir,
        &lt,
        &eta,
        accel_deg_s2,
        grid,
        out,
        plots
    )
}

/// A bundle and its η: `dir`'s `task.toml`, `robot.urdf` and `summary.json`.
fn read_planned(dir: &Path) -> Result<(LoadedTask, Vec<f64>), CliError> {
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name)).map_err(|e| {
            CliError::input(format!(
                "{}: cannot read {name}: {e} (give the --out directory of plan or rollout)",
                dir.display()
            ))
        })
    };
    let lt = taskfile::from_texts(
        &dir.join(BUNDLE_TASK),
        &read(BUNDLE_TASK)?,
        &read(BUNDLE_URDF)?,
    )?;
    let summary: serde_json::Value = serde_json::from_str(&read("summary.json")?)
        .or_input(|| format!("{}: summary.json", dir.display()))?;
    let eta: Vec<f64> = summary
        .get("eta")
        .and_then(|v| serde_json::from_value(v.clone()).ok())
        .ok_or_else(|| CliError::input(format!("{}: summary.json has no eta", dir.display())))?;
    Ok((lt, eta))
}

/// Re-times a two-phase plan's directory `dir` whole into `out`: phase 1 as planned (the
/// fastest path within `[preshape]`'s acceleration limit and the wheels' bounds, which a
/// faster phase 1 would break), phase 2 re-timed into `out/phase2/`, the rest of `dir`
/// copied. Refused when the re-timing's acceleration limit of some joint is below phase 1's.
/// Phase 1's duration (s), phase 2's summary and where it went.
pub fn retime_two_phase(
    dir: &Path,
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
    out: &Path,
    plots: bool,
) -> Result<(f64, RetimeSummary, PathBuf), CliError> {
    use crate::artifacts::{PHASE1_CSV, PHASE2_DIR, phase2_dir};
    let read = |name: &str| {
        std::fs::read_to_string(dir.join(name))
            .or_input(|| format!("{}: cannot read {name}", dir.display()))
    };
    let lt = taskfile::from_texts(
        &dir.join(BUNDLE_TASK),
        &read(BUNDLE_TASK)?,
        &read(BUNDLE_URDF)?,
    )?;
    let section = lt.file.preshape.ok_or_else(|| {
        CliError::input(format!(
            "{}: {BUNDLE_TASK} has no [preshape]",
            dir.display()
        ))
    })?;
    let (lt2, eta) = read_planned(&phase2_dir(dir))?;
    // Phase 1 moves at up to [preshape]'s acceleration limit: the re-timing's must not be
    // lower, or the whole plan would break it in phase 1.
    if let Some(qdd) = lt2.qdd_values(accel_deg_s2, lt2.chain.dof())? {
        if let Some((j, a)) = qdd
            .iter()
            .enumerate()
            .find(|(_, a)| **a < section.qdd_max_deg_s2)
        {
            return Err(CliError::input(format!(
                "{}: phase 1 was planned at [preshape] qdd_max_deg_s2 = {}, above the re-timing's acceleration limit {a} deg/s² of joint {}: plan again with [preshape] qdd_max_deg_s2 ≤ {a}",
                dir.display(),
                section.qdd_max_deg_s2,
                j + 1
            )));
        }
    }
    let plan: serde_json::Value = serde_json::from_str(&read("plan.json")?)
        .or_input(|| format!("{}: plan.json", dir.display()))?;
    let phase1_s = plan
        .pointer("/phase1/duration_s")
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(f64::NAN);
    let od = OutDir::create(out)?;
    for name in [BUNDLE_TASK, BUNDLE_URDF, PHASE1_CSV, "plan.json"] {
        let bytes = std::fs::read(dir.join(name))
            .or_input(|| format!("{}: cannot read {name}", dir.display()))?;
        od.write(name, &bytes)?;
    }
    let (s, _) = crate::with_dims!(
        lt2.chain.dof(),
        write_dir,
        &lt2,
        &eta,
        accel_deg_s2,
        grid,
        &od.path(PHASE2_DIR),
        plots
    )?;
    Ok((phase1_s, s, od.commit()?))
}

/// Re-times `eta` of `lt` into the directory `out` through [`write`] under the task's (or
/// `accel_deg_s2`'s) acceleration limits and grid; its summary and where it went.
fn write_dir<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
    accel_deg_s2: Option<f64>,
    grid: Option<u32>,
    out: &Path,
    plots: bool,
) -> Result<(RetimeSummary, PathBuf), CliError> {
    let task = lt.task::<N, K>()?;
    let eta = crate::args::parse_eta::<K>(eta, task.motion().segments())?;
    let qdd = lt.qdd_max_deg::<N>(accel_deg_s2)?.ok_or_else(|| {
        CliError::input(format!(
            "{}: no acceleration limits: give --accel-deg-s2 or set [limits] qdd_max_deg_s2",
            lt.path.display()
        ))
    })?;
    let grid = grid.unwrap_or(lt.file.retime.grid);
    let dir = OutDir::create(out)?;
    let s = write(
        lt,
        &task,
        &eta,
        &qdd,
        grid,
        lt.file.retime.margin,
        &dir,
        plots,
    )?;
    let path = dir.commit()?;
    Ok((s, path))
}

/// What `retime` and `plan --retime` print for a re-timed bundle at `path`.
#[must_use]
pub fn describe(s: &RetimeSummary, path: &Path) -> String {
    format!(
        "retime: {:.2} s (was {:.2} s), base disturbance = {} deg -> {}",
        s.duration_s,
        s.original_duration_s,
        crate::goal::number(s.base_disturbance_deg),
        path.display()
    )
}

/// What `retime` and `plan --retime` print for a two-phase plan re-timed whole at `path`:
/// phase 1 (`phase1_s`, as planned) and phase 2's summary `s`.
#[must_use]
pub fn describe_two_phase(phase1_s: f64, s: &RetimeSummary, path: &Path) -> String {
    format!(
        "retime: two phases, {:.2} s: phase 1 {phase1_s:.2} s as planned (attitude controlled), phase 2 re-timed to {:.2} s (was {:.2} s), base disturbance = {} deg -> {}",
        phase1_s + s.duration_s,
        s.duration_s,
        s.original_duration_s,
        crate::goal::number(s.base_disturbance_deg),
        path.display()
    )
}
