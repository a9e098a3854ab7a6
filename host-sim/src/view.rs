//! The 3-D replay page of an output directory: one self-contained HTML file.
//!
//! Owns [`ViewData`] (everything the page draws, computed here in Rust, per sample) and
//! [`render_dir`] / [`write_dir`], which read a `plan`, `rollout` or `retime` directory
//! **as written** (`task.toml`, `robot.urdf`, `summary.json`, `trajectory.csv`; a
//! two-phase plan's `phase1.csv` and `phase2/`, re-timed or not) and fill the
//! page template `host-sim/assets/view.html` (hand-written Canvas 2-D and JavaScript, no
//! library, nothing loaded from the network: scripts, styles and data are inline).
//!
//! The page only indexes the data: for every written sample it holds `t`, `q`, `q̇`, the
//! planner-model end-effector position (full precision, computed by the same
//! [`reactionless::Task::end_pose`] that writes `summary.json`, so the last sample is
//! `summary.json`'s `end_pose.position` to the bit; checked here) and the truth model's
//! base rotation (10 midpoint sub-steps, zero momentum, as `summary.json`), plus the
//! drawing geometry (joint positions and axes, end-effector attitude, inertial frame,
//! rounded to 1e-5 m / 1e-4 since it is only drawn). `FILE.html?t=T` shows the sample
//! nearest `T` (no interpolation) and writes `<pre id="rl-state">` with JSON
//! `{t, sample, q, ee_position_m, base_angle_deg}`; see docs/view.md.
//!
//! The arm is drawn in the planner model (base attitude identity, base placed by
//! centre-of-mass conservation); the truth model's base attitude (~1e-3°) is drawn as a
//! magnified triad at the base centre of mass, its true value printed beside it.

use crate::artifacts::{read_bundle, read_output_file};
use crate::error::{CliError, Context};
use crate::output::{FileKind, read_trajectory_csv, write_file};
use crate::taskfile::LoadedTask;
use crate::version::Build;
use crate::with_dims;
use nalgebra::{Matrix3, Quaternion, UnitQuaternion};
use reactionless::TRUTH_SUBSTEPS;
use reactionless::{Frames, IDENTITY_WXYZ, Sink, Task, TruthModel};
use serde::Serialize;
use std::path::Path;

/// The page template; `/*RL_DATA*/null` is replaced by the [`ViewData`] JSON.
static TEMPLATE: &str = include_str!("../assets/view.html");

/// The placeholder in [`TEMPLATE`].
const PLACEHOLDER: &str = "/*RL_DATA*/null";

/// The largest drawn base rotation (deg) the magnification aims at.
const MAGNIFIED_DEG: f64 = 20.0;

/// Everything the page shows (SI units and radians, except names ending `_deg`).
#[derive(Debug, Clone, Serialize)]
pub struct ViewData {
    /// What made it: task file, build.
    pub stamp: String,
    /// Robot name (URDF).
    pub robot: String,
    /// Joint count N.
    pub n: usize,
    /// Joint names (URDF).
    pub joint_names: Vec<String>,
    /// Lower joint limits (rad).
    pub lower: Vec<f64>,
    /// Upper joint limits (rad).
    pub upper: Vec<f64>,
    /// Joint rate limits (rad/s).
    pub qd_limit: Vec<f64>,
    /// Sample times (s) as written.
    pub t: Vec<f64>,
    /// Joint positions per sample (rad), as written.
    pub q: Vec<Vec<f64>>,
    /// Joint rates per sample (rad/s), as written.
    pub qd: Vec<Vec<f64>>,
    /// Planner-model end-effector position per sample (m, inertial frame), full precision.
    pub ee: Vec<[f64; 3]>,
    /// Truth-model base rotation angle per sample (deg).
    pub base_angle_deg: Vec<f64>,
    /// Truth-model base attitude per sample (unit quaternion `[w, x, y, z]`).
    pub base_wxyz: Vec<[f64; 4]>,
    /// Drawing geometry per sample (m, inertial frame, rounded to 1e-5 m and 1e-4):
    /// base origin (3), joint positions (3N), joint axes (3N), end-effector position (3)
    /// and attitude (9, row major).
    pub draw: Vec<Vec<f64>>,
    /// The base as a box of uniform density with the base's mass and inertia.
    pub base_box: BaseBox,
    /// Target end-effector pose: position (m) and attitude (row-major matrix).
    pub target: Frame,
    /// The drawn base attitude is the truth attitude's angle times this.
    pub magnification: f64,
    /// Largest base rotation over the motion (deg, truth model).
    pub base_disturbance_deg: f64,
    /// The base-disturbance requirement (deg).
    pub base_limit_deg: f64,
    /// A two-phase plan: the time phase 1 (attitude controlled) ends and phase 2 (free
    /// floating) begins (s); `None` for one phase.
    pub phase1_end_s: Option<f64>,
    /// A closed-loop flight (`disperse --closed-loop --export-sample K --out DIR`): the
    /// loop's per-cycle estimate beside the truth; `None` for a plan or rollout.
    pub closed_loop: Option<LoopView>,
}

/// What the page shows of a closed-loop flight, per control cycle (cycles.csv).
#[derive(Debug, Clone, Serialize)]
pub struct LoopView {
    /// The run's seed and the sample.
    pub seed: u64,
    /// The sample (0-based).
    pub sample: u64,
    /// Time of each cycle's measurement (s).
    pub t: Vec<f64>,
    /// The loop's estimate of the base rotation at each cycle (deg).
    pub estimate_deg: Vec<f64>,
    /// The true base rotation at each cycle (deg).
    pub truth_deg: Vec<f64>,
    /// The fault that sent the loop to its safe state, or `None`.
    pub fault: Option<String>,
    /// Extra time beyond t_f (s).
    pub extra_time_s: f64,
    /// End-effector position error at the end of the flight (m, truth model).
    pub position_error_m: f64,
    /// End-effector orientation error at the end of the flight (deg, truth model).
    pub orientation_error_deg: f64,
}

/// A position and an attitude.
#[derive(Debug, Clone, Serialize)]
pub struct Frame {
    /// Position (m, inertial frame).
    pub position: [f64; 3],
    /// Attitude, row major.
    pub rotation: [f64; 9],
}

/// The base's box, in the base frame.
#[derive(Debug, Clone, Serialize)]
pub struct BaseBox {
    /// Centre: the base centre of mass (m).
    pub center: [f64; 3],
    /// Edge lengths along the principal axes (m).
    pub size: [f64; 3],
    /// Principal axes as columns, row major.
    pub axes: [f64; 9],
}

/// The box of uniform density with mass `m` (kg) and principal moments `i` (kg m²):
/// `I₁ = m (b² + c²)/12`, …, so `a² = 6 (I₂ + I₃ − I₁)/m`. Moments that break the
/// triangle inequality (no box has them) give edges of at least 1 cm.
fn box_edges(m: f64, i: [f64; 3]) -> [f64; 3] {
    let edge = |a: f64, b: f64, c: f64| (6.0 * (b + c - a) / m).max(1e-4).sqrt();
    [
        edge(i[0], i[1], i[2]),
        edge(i[1], i[2], i[0]),
        edge(i[2], i[0], i[1]),
    ]
}

fn rows(m: &Matrix3<f64>) -> [f64; 9] {
    [
        m[(0, 0)],
        m[(0, 1)],
        m[(0, 2)],
        m[(1, 0)],
        m[(1, 1)],
        m[(1, 2)],
        m[(2, 0)],
        m[(2, 1)],
        m[(2, 2)],
    ]
}

/// `v` rounded to `1/scale` (drawing only).
fn round(v: f64, scale: f64) -> f64 {
    (v * scale).round() / scale
}

/// A magnification of 1, 2 or 5 × 10^k that draws `max_deg` as at most
/// [`MAGNIFIED_DEG`] (1 when nothing turned).
fn magnification(max_deg: f64) -> f64 {
    if !(max_deg.is_finite() && max_deg > 0.0) {
        return 1.0;
    }
    let raw = MAGNIFIED_DEG / max_deg;
    let decade = 10f64.powf(raw.log10().floor());
    let mantissa = [5.0, 2.0, 1.0]
        .into_iter()
        .find(|m| m * decade <= raw)
        .unwrap_or(1.0);
    (mantissa * decade).max(1.0)
}

/// The page data of output directory `dir` (see the module doc); the page names the
/// directory `shown` (plan and rollout write into a temporary directory first).
pub fn data_of_dir(dir: &Path, shown: &Path) -> Result<ViewData, CliError> {
    if crate::artifacts::is_two_phase(dir) {
        return data_of_two_phase(dir, shown);
    }
    let lt = read_bundle(dir)?;
    let text = read_output_file(dir, "summary.json")?;
    let summary: EndPoseOf =
        serde_json::from_str(&text).or_input(|| format!("{}: summary.json", dir.display()))?;
    let csv = read_output_file(dir, "trajectory.csv")?;
    let mut momentum = [0.0; 3];
    let flight = if summary.kind.as_deref() == Some(crate::closed_loop::FLIGHT_KIND) {
        let f: crate::closed_loop::FlightSummary = serde_json::from_str(&text)
            .or_input(|| format!("{}: summary.json of a closed-loop flight", dir.display()))?;
        momentum = f.initial_momentum;
        Some(loop_view(dir, &f)?)
    } else {
        None
    };
    let mut data = with_dims!(
        lt.chain.dof(),
        data_n,
        &lt,
        dir,
        shown,
        &summary.end_pose.position,
        &csv,
        momentum
    )?;
    if let Some(v) = flight {
        data.stamp = format!(
            "{} · closed loop · sample {} of seed {}",
            data.stamp, v.sample, v.seed
        );
        data.closed_loop = Some(v);
    }
    Ok(data)
}

/// The per-cycle estimate and truth of an exported closed-loop flight (cycles.csv: `t_s`,
/// …, `theta_deg`, `estimate_deg`, …).
fn loop_view(dir: &Path, f: &crate::closed_loop::FlightSummary) -> Result<LoopView, CliError> {
    let text = read_output_file(dir, "cycles.csv")?;
    let err = |m: String| CliError::input(format!("{}: cycles.csv: {m}", dir.display()));
    let mut lines = text.lines();
    let header: Vec<&str> = lines
        .next()
        .ok_or_else(|| err("empty file".into()))?
        .split(',')
        .collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| *h == name)
            .ok_or_else(|| err(format!("no column {name}")))
    };
    let (ct, ctruth, cest) = (col("t_s")?, col("theta_deg")?, col("estimate_deg")?);
    let mut v = LoopView {
        seed: f.seed,
        sample: f.sample,
        t: Vec::new(),
        estimate_deg: Vec::new(),
        truth_deg: Vec::new(),
        fault: f.fault.clone(),
        extra_time_s: f.loop_figures.extra_time_s,
        position_error_m: f.figures.position_error_m,
        orientation_error_deg: f.figures.orientation_error_deg,
    };
    for (row, line) in lines.enumerate() {
        let cells: Vec<f64> = line
            .split(',')
            .map(str::parse)
            .collect::<Result<_, _>>()
            .map_err(|e| err(format!("row {}: {e}", row + 1)))?;
        let get = |c: usize| {
            cells
                .get(c)
                .copied()
                .ok_or_else(|| err(format!("row {}: too few values", row + 1)))
        };
        v.t.push(get(ct)?);
        v.truth_deg.push(get(ctruth)?);
        v.estimate_deg.push(get(cest)?);
    }
    if v.t.len() != f.cycles {
        return Err(err(format!(
            "{} rows, summary.json says {} cycles (files from different runs?)",
            v.t.len(),
            f.cycles
        )));
    }
    Ok(v)
}

/// The end pose of a `summary.json`: a plan's or rollout's ([`crate::artifacts::Summary`]),
/// a re-timed bundle's ([`crate::retiming::RetimeSummary`]) or a closed-loop flight's
/// ([`crate::closed_loop::FlightSummary`], told by its `kind`); the rest is not read here.
#[derive(serde::Deserialize)]
struct EndPoseOf {
    end_pose: PositionOf,
    #[serde(default)]
    kind: Option<String>,
}

#[derive(serde::Deserialize)]
struct PositionOf {
    position: [f64; 3],
}

/// A two-phase plan's page: phase 1 (`phase1.csv`, base attitude held) then phase 2
/// (`phase2/trajectory.csv`, truth model), both drawn in the task's inertial frame (the
/// CoM of `t = 0` stays put through both), phase 2's times after phase 1's.
fn data_of_two_phase(dir: &Path, shown: &Path) -> Result<ViewData, CliError> {
    let lt = read_bundle(dir)?;
    let p2 = crate::artifacts::phase2_dir(dir);
    let lt2 = read_bundle(&p2)?;
    let csv1 = read_output_file(dir, crate::artifacts::PHASE1_CSV)?;
    let csv2 = read_output_file(&p2, "trajectory.csv")?;
    with_dims!(
        lt.chain.dof(),
        two_phase_n,
        &lt,
        &lt2,
        dir,
        shown,
        &csv1,
        &csv2
    )
}

fn two_phase_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    lt2: &LoadedTask,
    dir: &Path,
    shown: &Path,
    csv1: &str,
    csv2: &str,
) -> Result<ViewData, CliError> {
    let task: Task<N, K> = lt.task::<N, K>()?;
    let task2: Task<N, K> = lt2.task::<N, K>()?;
    let phase1 = read_trajectory_csv::<N>(dir, csv1)?;
    let phase2 = crate::retiming::read_samples::<N>(&crate::artifacts::phase2_dir(dir), csv2)?;
    if phase1.last().map(|s| s.q) != phase2.first().map(|s| s.q) {
        return Err(CliError::input(format!(
            "{}: phase 1 does not end where phase 2 starts (files from different runs?)",
            dir.display()
        )));
    }
    build(lt, &task, &phase1, &phase2, &task2, [0.0; 3], shown)
}

fn data_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    dir: &Path,
    shown: &Path,
    end: &[f64; 3],
    csv: &str,
    momentum: [f64; 3],
) -> Result<ViewData, CliError> {
    let task: Task<N, K> = lt.task::<N, K>()?;
    let samples = crate::retiming::read_samples::<N>(dir, csv)?;
    let data = build(lt, &task, &[], &samples, &task, momentum, shown)?;
    let last = data.ee.last().copied().unwrap_or([f64::NAN; 3]);
    if &last != end {
        return Err(CliError::input(format!(
            "{}: the end pose of trajectory.csv's last sample, {last:?}, is not summary.json's \
             end_pose.position {:?} (files from different runs?)",
            dir.display(),
            end
        )));
    }
    Ok(data)
}

/// What a sample is on the page.
#[derive(Clone, Copy)]
enum Row {
    /// Phase 1: base attitude held by the attitude control.
    Held,
    /// Phase 2's first sample, phase 1's last: for the truth model only.
    Joint,
    /// Free floating: the truth model's base attitude.
    Floating,
}

/// The page's data: `held` samples with the base attitude held (phase 1 of a two-phase
/// plan; none for one phase), then `floating` samples with the base attitude integrated by
/// the truth model of `floating_task` from angular momentum `momentum` (kg m²/s; zero but
/// for a closed-loop flight whose draw gave the base an initial rate); all drawn in `task`'s
/// inertial frame (planner model: base placed by CoM conservation), the floating samples'
/// times after the held ones.
fn build<const N: usize, const K: usize>(
    lt: &LoadedTask,
    task: &Task<N, K>,
    held: &[reactionless::Sample<N>],
    floating: &[reactionless::Sample<N>],
    floating_task: &Task<N, K>,
    momentum: [f64; 3],
    shown: &Path,
) -> Result<ViewData, CliError> {
    if floating.is_empty() {
        return Err(CliError::input(format!(
            "{}: trajectory.csv has no samples",
            shown.display()
        )));
    }
    let robot = task.robot();
    let com0 = task.com0();
    let mut truth = TruthModel::from_state(
        floating_task,
        reactionless::TruthState::new(TRUTH_SUBSTEPS).with_momentum(momentum),
    );
    let offset = held.last().map_or(0.0, |s| s.t);
    let n = held.len() + floating.len();
    let (mut t, mut q, mut qd) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    let (mut ee, mut angle, mut wxyz, mut draw) = (
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
        Vec::with_capacity(n),
    );
    // Phase 2's first sample is phase 1's last: drawn once (the truth model still sees it).
    let skip = usize::from(!held.is_empty());
    let all = held.iter().map(|s| (s, Row::Held)).chain(
        floating
            .iter()
            .enumerate()
            .map(|(i, s)| (s, if i < skip { Row::Joint } else { Row::Floating })),
    );
    for (s, kind) in all {
        match kind {
            Row::Held => {
                angle.push(0.0);
                wxyz.push(IDENTITY_WXYZ);
                t.push(s.t);
            }
            Row::Joint => {
                truth.sample(s);
                continue;
            }
            Row::Floating => {
                truth.sample(s);
                angle.push(truth.angle().to_degrees());
                wxyz.push(truth.attitude());
                t.push(s.t + offset);
            }
        }
        q.push(s.q.to_vec());
        qd.push(s.qd.to_vec());
        let frames = Frames::new(robot, &s.q);
        let end = task.end_pose(&s.q, IDENTITY_WXYZ);
        ee.push(end.position);
        // Planner model: identity base attitude, base origin p₀ = r_g(0) − r_g(q).
        let p0 = com0 - frames.com;
        let mut row = Vec::with_capacity(3 + 6 * N + 12);
        let mm = |v: f64| round(v, 1e5);
        row.extend(p0.iter().map(|&v| mm(v)));
        for l in &frames.links {
            row.extend((p0 + l.joint).iter().map(|&v| mm(v)));
        }
        for l in &frames.links {
            row.extend(l.axis().iter().map(|&v| round(v, 1e4)));
        }
        row.extend(end.position.iter().map(|&v| mm(v)));
        row.extend(rows(&frames.ee_rotation).iter().map(|&v| round(v, 1e4)));
        draw.push(row);
    }
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    let base = &robot.desc().base;
    let inertia = base.inertia.to_sym();
    let local = Matrix3::new(
        inertia.xx, inertia.xy, inertia.xz, inertia.xy, inertia.yy, inertia.yz, inertia.xz,
        inertia.yz, inertia.zz,
    );
    let r = base.inertial.rotation();
    let eig = (r * local * r.transpose()).symmetric_eigen();
    let moments = [eig.eigenvalues[0], eig.eigenvalues[1], eig.eigenvalues[2]];
    let target = task.target();
    let [w, x, y, z] = target.quat_wxyz;
    let target_rot = UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z))
        .to_rotation_matrix()
        .into_inner();
    let max_deg = truth.max_angle().to_degrees();
    Ok(ViewData {
        stamp: format!("{} · {}", shown.display(), Build::current().stamp()),
        robot: lt.chain.name.clone(),
        n: N,
        joint_names: lt.chain.joint_names.clone(),
        lower: robot.lower().to_vec(),
        upper: robot.upper().to_vec(),
        qd_limit: lt.chain.joints.iter().map(|j| j.velocity).collect(),
        t,
        q,
        qd,
        ee,
        base_angle_deg: angle,
        base_wxyz: wxyz,
        draw,
        base_box: BaseBox {
            center: base.inertial.xyz,
            size: box_edges(base.mass, moments),
            axes: rows(&eig.eigenvectors),
        },
        target: Frame {
            position: target.position,
            rotation: rows(&target_rot),
        },
        magnification: magnification(max_deg),
        base_disturbance_deg: max_deg,
        base_limit_deg: lt.max_base_disturbance_deg(),
        phase1_end_s: (!held.is_empty()).then_some(offset),
        closed_loop: None,
    })
}

/// The page for `data`: the template with the data inlined (`<` escaped as `\u003c`, so
/// nothing in the data can close the script element).
pub fn page(data: &ViewData) -> Result<String, CliError> {
    let json = serde_json::to_string(data)
        .or_internal(|| "view data JSON")?
        .replace('<', "\\u003c");
    if !TEMPLATE.contains(PLACEHOLDER) {
        return Err(CliError::internal(
            "the view template has no data placeholder",
        ));
    }
    Ok(TEMPLATE.replacen(PLACEHOLDER, &json, 1))
}

/// The page of output directory `dir`, naming it `shown`.
pub fn render_dir(dir: &Path, shown: &Path) -> Result<String, CliError> {
    page(&data_of_dir(dir, shown)?)
}

/// Writes the page of output directory `dir` to `out` (atomically).
pub fn write_dir(dir: &Path, out: &Path) -> Result<(), CliError> {
    let html = render_dir(dir, dir)?;
    write_file(out, html.as_bytes(), FileKind::Page)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A cube of edge a and mass m has I = m a²/6 about each axis: the edges come back.
    #[test]
    fn a_cube_gives_back_its_edges() {
        let (m, a) = (3.0, 0.7);
        let i = m * a * a / 6.0;
        for e in box_edges(m, [i, i, i]) {
            assert!((e - a).abs() < 1e-12);
        }
    }

    /// The magnification is 1, 2 or 5 × 10^k and draws the largest angle at ≤ 20°.
    #[test]
    fn magnification_is_a_round_number_within_twenty_degrees() {
        assert_eq!(magnification(1.5e-3), 1e4);
        assert_eq!(magnification(3e-3), 5e3);
        assert_eq!(magnification(0.0), 1.0);
        assert_eq!(magnification(90.0), 1.0);
        for d in [1.234e-3, 7.7e-4, 0.05] {
            let m = magnification(d);
            assert!(m * d <= MAGNIFIED_DEG && m * d > MAGNIFIED_DEG / 5.0 - 1e-9);
        }
    }
}
