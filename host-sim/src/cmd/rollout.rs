//! `host-sim rollout`: one η through the reference discretization, with the truth model.
//!
//! Writes `trajectory.csv` (every sample, s / rad / rad/s) and `summary.json` into the
//! output directory, atomically.

use crate::error::CliError;
use crate::output::{CsvSink, OutDir};
use crate::taskfile::{self, LoadedTask};
use crate::with_dims;
use reactionless::{
    Error as CoreError, Outcome, Param, Pose, Progress, Rollout, Sample, Sink, Task, TruthModel,
    eta_pairs,
};
use serde::Serialize;
use std::path::Path;

/// Truth-model midpoint sub-steps per integration step.
pub const TRUTH_SUBSTEPS: u32 = 10;

/// `summary.json`.
#[derive(Serialize)]
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
#[derive(Serialize)]
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

/// Runs the subcommand.
pub fn run(task_path: &Path, eta: &[f64], out: &Path) -> Result<(), CliError> {
    let lt = taskfile::load(task_path)?;
    with_dims!(lt.chain.dof(), run_n, &lt, eta, out)
}

/// η from the command line as pairs, every problem named.
pub fn parse_eta<const K: usize>(eta: &[f64]) -> Result<[[f64; 2]; K], CliError> {
    eta_pairs::<K>(eta).map_err(|_| {
        CliError::input(format!(
            "--eta has {} values; this robot needs 2K = {} (a1,b1,...,a{K},b{K})",
            eta.len(),
            2 * K
        ))
    })
}

/// The error for an η the core rejects.
pub fn eta_error(e: CoreError) -> CliError {
    match e {
        CoreError::NotFinite(Param::Eta(i)) => {
            CliError::input(format!("--eta component {i} is not a finite number"))
        }
        CoreError::EtaZero => CliError::input("--eta is all zeros: no motion is defined"),
        other => CliError::input(format!("--eta: {other}")),
    }
}

/// Writes `trajectory.csv` and returns the rollout outcome and the truth model's report.
pub fn write_rollout<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    dir: &OutDir,
) -> Result<(Outcome<N>, TruthReport), CliError> {
    let mut rollout = Rollout::new(task, eta).map_err(eta_error)?;
    let mut csv = CsvSink::create(&dir.path("trajectory.csv"), N)?;
    let mut truth = TruthModel::new(task, TRUTH_SUBSTEPS);
    let mut sink = |s: &Sample<N>| {
        csv.push(s);
        truth.sample(s);
    };
    let outcome = match rollout.advance(task, u32::MAX, &mut sink) {
        Ok(Progress::Done(o)) => o,
        Ok(Progress::Running { .. }) => return Err(CliError::internal("rollout did not finish")),
        Err(e) => return Err(CliError::failed(format!("rollout failed: {e}"))),
    };
    csv.finish()?;
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    let end = truth
        .end_pose()
        .ok_or_else(|| CliError::internal("truth model saw no samples"))?;
    let report = TruthReport {
        base_disturbance_deg: truth.max_angle().to_degrees(),
        f: end.error_to(task.target()).norm(),
        end_pose: end,
    };
    Ok((outcome, report))
}

/// What the truth model found.
pub struct TruthReport {
    /// Largest base rotation (deg).
    pub base_disturbance_deg: f64,
    /// End pose with the integrated base attitude.
    pub end_pose: Pose,
    /// f of that pose against the target.
    pub f: f64,
}

/// `summary.json` of a finished rollout.
pub fn summary<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    o: &Outcome<N>,
    truth: &TruthReport,
) -> Summary {
    let m = task.motion();
    Summary {
        eta: eta.iter().flatten().copied().collect(),
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

fn run_n<const N: usize, const K: usize>(
    lt: &LoadedTask,
    eta: &[f64],
    out: &Path,
) -> Result<(), CliError> {
    let task = lt.task::<N, K>()?;
    let eta = parse_eta::<K>(eta)?;
    // Validate η before anything is created on disk.
    Rollout::new(&task, &eta).map_err(eta_error)?;
    let dir = OutDir::create(out)?;
    let (outcome, truth) = write_rollout(&task, &eta, &dir)?;
    dir.write_json("summary.json", &summary(&task, &eta, &outcome, &truth))?;
    let path = dir.commit()?;
    eprintln!(
        "rollout: f = {:.3e}, phi = {}, base disturbance = {:.3e} deg -> {}",
        outcome.f,
        outcome.phi,
        truth.base_disturbance_deg,
        path.display()
    );
    Ok(())
}
