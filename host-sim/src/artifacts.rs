//! What `plan` and `rollout` write: the trajectory, the summary, the task bundle and the
//! figures of one η; the names of a two-phase plan's files.
//!
//! Owns the files of an output directory: `trajectory.csv` (every sample, s / rad /
//! rad/s, through [`CsvSink`]), `summary.json` ([`Summary`], read back by `check`), the
//! self-contained bundle `task.toml` + `robot.urdf` ([`write_bundle`]) and the figures
//! ([`write_figures`]). [`write_rollout`] re-runs η through the core with the truth model
//! and the trajectory digest attached, so every file comes from one pass over the samples.

use crate::error::{CliError, Context};
use crate::output::{CsvSink, OutDir};
use crate::plots::{self, PlotData};
use crate::taskfile::{self, LoadedTask};
use crate::version::Build;
use reactionless::{
    Eta, IDENTITY_WXYZ, Outcome, Pose, Rollout, Sample, Sink, TRUTH_SUBSTEPS, Task,
    TrajectoryDigest, TruthModel, eta_flat,
};
use serde::{Deserialize, Serialize};

/// Phase 2's sub-directory of a two-phase plan ([`crate::preshaping`]).
pub const PHASE2_DIR: &str = "phase2";
/// Phase 1's samples of a two-phase plan.
pub const PHASE1_CSV: &str = "phase1.csv";

/// Whether output directory `dir` holds a two-phase plan.
pub fn is_two_phase(dir: &std::path::Path) -> bool {
    dir.join(PHASE1_CSV).is_file()
}

/// Phase 2's directory inside a two-phase plan's `dir`.
pub fn phase2_dir(dir: &std::path::Path) -> std::path::PathBuf {
    dir.join(PHASE2_DIR)
}

/// `summary.json`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Summary {
    /// η as given.
    pub eta: Vec<f64>,
    /// q_S (rad).
    pub q_final: Vec<f64>,
    /// Planner-model end pose (m, unit quaternion).
    pub end_pose: PoseJson,
    /// f = ‖e‖ against the task target.
    pub f: f64,
    /// ‖p_des − p‖ (m).
    pub position_error_m: f64,
    /// Angle of R_des Rᵀ (deg).
    pub orientation_error_deg: f64,
    /// Φ of eq. 23 (rad).
    pub phi: f64,
    /// Joint minima over the motion (rad).
    pub joint_min: Vec<f64>,
    /// Joint maxima over the motion (rad).
    pub joint_max: Vec<f64>,
    /// Largest |q̇| (rad/s).
    pub max_abs_qdot: f64,
    /// g of eq. 14.
    pub g: f64,
    /// Largest base rotation over the motion, truth model (deg).
    pub base_disturbance_deg: f64,
    /// End pose with the truth-model base attitude (m, unit quaternion).
    pub truth_end_pose: PoseJson,
    /// f of the truth-model end pose against the target.
    pub truth_f: f64,
    /// Truth-model sub-steps per integration step.
    pub truth_substeps: u32,
    /// Integration steps S.
    pub steps: u32,
    /// dt (s).
    pub dt_s: f64,
    /// t_f (s).
    pub tf_s: f64,
}

/// A pose in JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseJson {
    /// Position (m).
    pub position: [f64; 3],
    /// Unit quaternion `[w, x, y, z]`.
    pub quat_wxyz: [f64; 4],
}

impl From<&Pose> for PoseJson {
    fn from(p: &Pose) -> Self {
        Self {
            position: p.position,
            quat_wxyz: p.quat_wxyz,
        }
    }
}

/// What one written rollout produced.
pub struct RolloutRun<const N: usize> {
    /// The core's outcome.
    pub outcome: Outcome<N>,
    /// The truth model's findings.
    pub truth: TruthReport,
    /// FNV-1a-64 digest of every sample's bits (see `reactionless::digest`).
    pub digest: TrajectoryDigest,
    /// Largest |q̇| of each joint over the samples (rad/s).
    pub max_abs_qd: Vec<f64>,
    /// Samples (for plots), when asked for.
    pub trace: Option<Trace>,
}

/// The samples of a rollout, kept for plots.
#[derive(Default)]
pub struct Trace {
    /// Times (s).
    pub t: Vec<f64>,
    /// Joint positions (rad).
    pub q: Vec<Vec<f64>>,
    /// Joint rates (rad/s).
    pub qd: Vec<Vec<f64>>,
    /// Planner-model end-effector positions (m).
    pub ee: Vec<[f64; 3]>,
    /// Truth-model base rotation angle (deg).
    pub base_angle_deg: Vec<f64>,
    /// Truth-model base attitude (unit quaternion `[w, x, y, z]`, base → inertial).
    pub base_wxyz: Vec<[f64; 4]>,
}

/// What the truth model found.
#[derive(Debug, Clone, PartialEq)]
pub struct TruthReport {
    /// Largest base rotation (deg).
    pub base_disturbance_deg: f64,
    /// End pose with the integrated base attitude.
    pub end_pose: Pose,
    /// f of that pose against the target.
    pub f: f64,
}

/// Rolls `eta` out with the truth model and the digest; writes `trajectory.csv` into `dir`
/// if given, and keeps the samples if `keep` is set.
pub fn write_rollout<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &Eta<K>,
    dir: Option<&OutDir>,
    keep: bool,
) -> Result<RolloutRun<N>, CliError> {
    // η first (a bad one is the caller's input), then the rollout (a failure is a result).
    Rollout::of(task, eta).map_err(crate::args::eta_error)?;
    let mut csv = match dir {
        Some(d) => Some(CsvSink::create(&d.path("trajectory.csv"), N)?),
        None => None,
    };
    let mut truth = TruthModel::new(task, TRUTH_SUBSTEPS);
    let mut digest = TrajectoryDigest::new();
    let mut trace = keep.then(Trace::default);
    let mut max_abs_qd = vec![0.0f64; N];
    let mut sink = |s: &Sample<N>| {
        for (m, v) in max_abs_qd.iter_mut().zip(s.qd.iter()) {
            *m = m.max(v.abs());
        }
        if let Some(c) = csv.as_mut() {
            c.push(s);
        }
        truth.sample(s);
        digest.sample(s);
        if let Some(tr) = trace.as_mut() {
            tr.t.push(s.t);
            tr.q.push(s.q.to_vec());
            tr.qd.push(s.qd.to_vec());
            tr.ee.push(task.end_pose(&s.q, IDENTITY_WXYZ).position);
            tr.base_angle_deg.push(truth.angle().to_degrees());
            tr.base_wxyz.push(truth.attitude());
        }
    };
    let outcome = task
        .rollout_of(eta, &mut sink)
        .or_failed(|| "rollout failed")?;
    if let Some(c) = csv {
        c.finish()?;
    }
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    let end = truth
        .end_pose()
        .ok_or_else(|| CliError::internal("truth model saw no samples"))?;
    Ok(RolloutRun {
        outcome,
        truth: TruthReport {
            base_disturbance_deg: truth.max_angle().to_degrees(),
            f: end.error_to(task.target()).norm(),
            end_pose: end,
        },
        digest,
        max_abs_qd,
        trace,
    })
}

/// Writes the self-contained task bundle (`task.toml`, `robot.urdf`) into `dir`: for a
/// plan, with every setting it used ([`LoadedTask::bundle`]). Returns the task as the
/// bundle holds it (what `check` and `retime` of `dir` will read).
pub fn write_bundle(
    lt: &LoadedTask,
    dir: &OutDir,
    used: Option<(&reactionless::PlannerConfig, &crate::goal::Asked)>,
) -> Result<LoadedTask, CliError> {
    let (task, urdf) = lt.bundle(used)?;
    dir.write(taskfile::BUNDLE_TASK, task.as_bytes())?;
    dir.write(taskfile::BUNDLE_URDF, urdf.as_bytes())?;
    taskfile::from_texts(&lt.path, &task, &urdf)
}

/// Reads `name` from output directory `dir`; the error says where to point instead.
pub fn read_output_file(dir: &std::path::Path, name: &str) -> Result<String, CliError> {
    std::fs::read_to_string(dir.join(name)).map_err(|e| {
        CliError::input(format!(
            "{}: cannot read {name}: {e} (is this a host-sim output directory?)",
            dir.display()
        ))
    })
}

/// The task bundle (`task.toml` + `robot.urdf`) of output directory `dir`, read as
/// [`write_bundle`] wrote it; a missing directory is named as such.
pub fn read_bundle(dir: &std::path::Path) -> Result<LoadedTask, CliError> {
    if !dir.is_dir() {
        return Err(CliError::input(format!(
            "{}: no such directory (give the --out directory of plan or rollout)",
            dir.display()
        )));
    }
    let task_text = read_output_file(dir, taskfile::BUNDLE_TASK)?;
    let urdf_text = read_output_file(dir, taskfile::BUNDLE_URDF)?;
    taskfile::from_texts(&dir.join(taskfile::BUNDLE_TASK), &task_text, &urdf_text)
}

/// What a plan adds to the figures of its rollout.
pub struct PlanFigures {
    /// The best f after each rollout.
    pub history: Vec<f64>,
    /// The seed planned with.
    pub seed: u64,
    /// The strategy.
    pub strategy: reactionless::Strategy,
    /// The rollout that first met σ_e.
    pub first_hit: Option<u32>,
}

/// Writes the figures of a rollout (and a plan's convergence) into `dir`, each stamped
/// with the task, seed, strategy and build.
pub fn write_figures<const N: usize, const K: usize>(
    lt: &LoadedTask,
    task: &Task<N, K>,
    trace: Trace,
    plan: Option<PlanFigures>,
    dir: &OutDir,
) -> Result<Vec<String>, CliError> {
    let (seed, strategy) = plan
        .as_ref()
        .map_or((lt.file.planner.seed, lt.file.planner.strategy), |p| {
            (p.seed, p.strategy)
        });
    let stamp = format!(
        "{} · {} · {}",
        lt.path.display(),
        if plan.is_some() {
            format!("seed {seed} · {}", strategy.name())
        } else {
            "rollout".to_string()
        },
        Build::current().stamp()
    );
    let robot = task.robot();
    let data = PlotData {
        joint_names: lt.chain.joint_names.clone(),
        t: trace.t,
        q: trace.q,
        qd: trace.qd,
        lower: robot.lower().to_vec(),
        upper: robot.upper().to_vec(),
        qd_limit: lt.chain.joints.iter().map(|j| j.velocity).collect(),
        ee: trace.ee,
        target: task.target().position,
        base_angle_deg: trace.base_angle_deg,
        base_wxyz: trace.base_wxyz,
        tolerance: lt.file.planner.tolerance,
        first_hit: plan.as_ref().and_then(|p| p.first_hit),
        best_f_history: plan.map(|p| p.history),
        base_limit_deg: lt.max_base_disturbance_deg(),
        stamp,
    };
    plots::write_plots(&dir.path(""), &data)
}

/// `summary.json` of a finished rollout.
pub fn summary<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &Eta<K>,
    o: &Outcome<N>,
    truth: &TruthReport,
) -> Summary {
    let m = task.motion();
    Summary {
        eta: eta_flat(eta, m.segments()).collect(),
        q_final: o.q_final.to_vec(),
        end_pose: (&o.end_pose).into(),
        f: o.f,
        position_error_m: o.error.position_m(),
        orientation_error_deg: o.error.orientation_deg(),
        phi: o.phi,
        joint_min: o.joint_min.to_vec(),
        joint_max: o.joint_max.to_vec(),
        max_abs_qdot: o.max_abs_qd,
        g: o.g,
        base_disturbance_deg: truth.base_disturbance_deg,
        truth_end_pose: (&truth.end_pose).into(),
        truth_f: truth.f,
        truth_substeps: TRUTH_SUBSTEPS,
        steps: m.steps(),
        dt_s: m.dt(),
        tf_s: m.tf(),
    }
}
