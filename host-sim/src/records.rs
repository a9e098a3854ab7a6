//! Certification records: what a record holds, how a plan becomes one, and how two are
//! compared bit for bit.
//!
//! Owns [`Record`] (format [`FORMAT`]): the task (its text, with the URDF path relative to
//! the record), the SHA-256 of the URDF's content, the seed and refinement setting, the
//! [`Build`] that made it (`crate::version`), and the [`Outputs`]: status, iteration, rollout and stagnation
//! counts, η, f and the end pose as exact IEEE-754 bit patterns ([`bits`]), and the
//! FNV-1a-64 digest over the bit patterns of the whole trajectory
//! ([`reactionless::TrajectoryDigest`]); for a two-phase plan ([`TwoPhaseOutputs`]) also how
//! the search ended, phase 1's digest, the wheels' demand and `q_s`. [`outputs_of`] plans a
//! task into outputs;
//! [`first_difference`] compares two output sets in a fixed order. `record`, `replay` and
//! `target` use them.
//!
//! **Re-blessing** a justified change (an intended algorithm change, a dependency bump that
//! moves the bits): regenerate every golden record with `scripts/bless-records.sh`, review
//! the diff of `tests/records/` (which quantities moved, and why) and commit the new records
//! together with the change and a message that says why the bits moved.

use crate::drive::{self, HOST_CAPACITY};
use crate::error::{CliError, Context};
use crate::taskfile::{LoadedTask, Overrides};
use crate::version::Build;
use reactionless::{TrajectoryDigest, eta_flat};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// Record format identifier.
pub const FORMAT: &str = "reactionless-record/1";

/// A certification record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Record {
    /// [`FORMAT`].
    pub format: String,
    /// The task file the record was made from (informational).
    pub task_file: String,
    /// The task's text; `[robot] urdf` is relative to the record file.
    pub task_toml: String,
    /// SHA-256 of the URDF's bytes (hex).
    pub urdf_sha256: String,
    /// Seed used.
    pub seed: u64,
    /// Refinement target, if refinement ran.
    pub refine_tolerance: Option<f64>,
    /// The search strategy (`multistart` or `cpso`); records made before strategies
    /// existed have none and were planned with `cpso`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub strategy: Option<String>,
    /// What refinement drove (`planner` or `truth`); absent: `planner`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub refine_against: Option<String>,
    /// The build that made the record.
    pub build: Build,
    /// What was planned.
    pub outputs: Outputs,
}

/// A pose as bit patterns.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoseBits {
    /// Position (m), hex bit patterns.
    pub position: Vec<String>,
    /// Quaternion `[w, x, y, z]`, hex bit patterns.
    pub quat_wxyz: Vec<String>,
}

/// The outputs a replay must reproduce.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Outputs {
    /// `converged` or `not_converged`.
    pub status: String,
    /// C-PSO generations after the initial one.
    pub iterations: u32,
    /// All rollouts.
    pub rollouts: u32,
    /// Stagnation alarms.
    pub stagnation_events: u32,
    /// Multistart restarts (absent in older records: 0).
    #[serde(default)]
    pub restarts: u32,
    /// η, hex bit patterns.
    pub eta_bits: Vec<String>,
    /// f, hex bit pattern.
    pub f_bits: String,
    /// End pose, bit patterns.
    pub end_pose_bits: PoseBits,
    /// Samples in the trajectory.
    pub trajectory_samples: u32,
    /// FNV-1a-64 over every sample's bit patterns (hex).
    pub trajectory_digest: String,
    /// η as numbers (informational; the bits are authoritative).
    pub eta: Vec<f64>,
    /// f as a number (informational).
    pub f: f64,
    /// A two-phase plan's other outputs (a task with `[preshape]`; the fields above are
    /// phase 2's, from `q_s`); absent for a single-phase plan.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub two_phase: Option<TwoPhaseOutputs>,
}

/// What a two-phase plan adds to [`Outputs`]: how the search ended, phase 1 and the wheels'
/// demand, `q_s`; numbers as bit patterns. The flight image reports the same (its
/// `TWOPHASE` and `QS` lines), so `target` compares them too.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TwoPhaseOutputs {
    /// `converged`, `exhausted`, `beyond_reach` or `preshape_bounds`.
    pub stop: String,
    /// LM starts begun.
    pub starts: u32,
    /// The kinematic inverse's `f`, hex bit pattern.
    pub reach_f_bits: String,
    /// Phase 2's base disturbance on the truth model (rad; NaN when not flown), hex.
    pub base_disturbance_bits: String,
    /// Phase 1's integration steps.
    pub phase1_steps: u32,
    /// Phase 1's written samples.
    pub phase1_samples: u32,
    /// FNV-1a-64 over phase 1's samples (hex).
    pub phase1_digest: String,
    /// The wheels' largest momentum (N m s), hex.
    pub momentum_bits: String,
    /// The wheels' largest torque (N m), hex.
    pub torque_bits: String,
    /// The base shift at `q_s` (m), hex bit patterns.
    pub base_shift_bits: Vec<String>,
    /// `q_s` (rad), hex bit patterns.
    pub q_s_bits: Vec<String>,
}

impl TwoPhaseOutputs {
    /// Every field as `(name, value)`, in a fixed order; the names are the flight image's
    /// `TWOPHASE` keys (then `q_s[i]`).
    pub fn fields(&self) -> Vec<(String, String)> {
        let mut v: Vec<(String, String)> = [
            ("stop", self.stop.clone()),
            ("starts", self.starts.to_string()),
            ("reach_f", self.reach_f_bits.clone()),
            ("base", self.base_disturbance_bits.clone()),
            ("steps1", self.phase1_steps.to_string()),
            ("samples1", self.phase1_samples.to_string()),
            ("digest1", self.phase1_digest.clone()),
            ("momentum", self.momentum_bits.clone()),
            ("torque", self.torque_bits.clone()),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        for (axis, b) in ["shift_x", "shift_y", "shift_z"]
            .iter()
            .zip(&self.base_shift_bits)
        {
            v.push(((*axis).to_string(), b.clone()));
        }
        v
    }
}

/// `0x` and 16 hex digits of an `f64`'s bit pattern.
pub fn bits(v: f64) -> String {
    format!("{:#018x}", v.to_bits())
}

/// SHA-256 of bytes, lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes)
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect()
}

/// `to` relative to the directory `from` (both made absolute first).
pub fn relative(from: &Path, to: &Path) -> Result<PathBuf, CliError> {
    let abs = |p: &Path| std::path::absolute(p).or_input(|| p.display().to_string());
    let (from, to) = (abs(from)?, abs(to)?);
    pathdiff::diff_paths(&to, &from).ok_or_else(|| {
        CliError::input(format!(
            "{} cannot be reached from {}",
            to.display(),
            from.display()
        ))
    })
}

/// A record's path text for `path` relative to `dir`, with `/` separators.
pub fn relative_text(dir: &Path, path: &Path) -> Result<String, CliError> {
    Ok(relative(dir, path)?.to_string_lossy().replace('\\', "/"))
}

/// A plan's outputs as a record holds them, with the effective seed and refinement
/// tolerance it was planned with.
#[derive(Debug, Clone, PartialEq)]
pub struct RecordedRun {
    /// The outputs.
    pub outputs: Outputs,
    /// The seed used.
    pub seed: u64,
    /// The refinement tolerance used, if refinement ran.
    pub refine_tolerance: Option<f64>,
    /// The strategy used.
    pub strategy: reactionless::Strategy,
    /// What refinement drove.
    pub refine_against: reactionless::RefineAgainst,
}

/// Plans `lt` (with the overrides) and computes the outputs a record holds; in two phases
/// for a task with `[preshape]` ([`two_phase_outputs_of`]).
pub fn outputs_of<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
) -> Result<RecordedRun, CliError> {
    if lt.file.preshape.is_some() {
        let run = two_phase_outputs_of::<N, K>(lt, overrides, HOST_CAPACITY)?;
        return Ok(RecordedRun {
            outputs: run.outputs,
            seed: run.planner.seed,
            // The tolerance the search was given: replayed as the refinement tolerance
            // (with σ_e as the goal), it asks the same of the search.
            refine_tolerance: Some(run.config.tolerance),
            strategy: run.planner.strategy,
            refine_against: run.planner.refine_against,
        });
    }
    let config = lt.planner(HOST_CAPACITY, overrides)?;
    let task = lt.task::<N, K>()?;
    let p = drive::plan::<N, K>(lt, config, false)?.plan;
    let mut digest = TrajectoryDigest::new();
    let again = task
        .rollout_of(&p.eta, &mut digest)
        .or_failed(|| "rollout failed")?;
    if again != p.outcome {
        return Err(CliError::internal(
            "the digest rollout differs from the plan's",
        ));
    }
    let o = &p.outcome;
    Ok(RecordedRun {
        outputs: Outputs {
            status: crate::goal::status_name(p.converged()).into(),
            iterations: p.iterations,
            rollouts: p.rollouts,
            stagnation_events: p.stagnation_events,
            restarts: p.restarts,
            eta_bits: eta_flat(&p.eta, task.motion().segments())
                .map(bits)
                .collect(),
            f_bits: bits(o.f),
            end_pose_bits: PoseBits {
                position: o.end_pose.position.iter().map(|v| bits(*v)).collect(),
                quat_wxyz: o.end_pose.quat_wxyz.iter().map(|v| bits(*v)).collect(),
            },
            trajectory_samples: digest.samples(),
            trajectory_digest: format!("{:#018x}", digest.value()),
            eta: eta_flat(&p.eta, task.motion().segments()).collect(),
            f: o.f,
            two_phase: None,
        },
        seed: config.seed,
        refine_tolerance: config.refine_tolerance,
        strategy: config.strategy,
        refine_against: config.refine_against,
    })
}

/// A two-phase plan as a record holds it ([`two_phase_outputs_of`]).
pub struct TwoPhaseRun<const N: usize, const K: usize> {
    /// Phase 2's plan as a record's outputs, with [`Outputs::two_phase`] set.
    pub outputs: Outputs,
    /// The settings the search was given.
    pub config: reactionless::TwoPhaseConfig,
    /// The planner settings they were made from (seed, strategy, refinement).
    pub planner: reactionless::PlannerConfig,
    /// Phase 2's task (the task from `q_s`).
    pub phase2: reactionless::Task<N, K>,
}

/// Plans `lt` (a task with `[preshape]`) in two phases with the settings of a planner of
/// swarm capacity `capacity` and the overrides: phase 2's plan as a record's outputs (from
/// the task moved to `q_s`; no rollout when the target is beyond reach: `f` NaN, no pose,
/// the empty digest) and the rest in [`Outputs::two_phase`]. The flight image reports the
/// same for a two-phase block (`crate::flight::flight_outputs`).
pub fn two_phase_outputs_of<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
    capacity: usize,
) -> Result<TwoPhaseRun<N, K>, CliError> {
    let section = lt
        .file
        .preshape
        .ok_or_else(|| CliError::input(format!("{}: no [preshape] section", lt.path.display())))?;
    let (config, asked) = lt.plan_settings(capacity, overrides)?;
    let (mut task, tp, p, _) =
        crate::preshaping::solve::<N, K>(lt, &section, &config, &asked, false)?;
    task.move_start(&p.q_s)
        .map_err(|e| CliError::internal(format!("phase 2's start: {e}")))?;
    let mut digest = TrajectoryDigest::new();
    let (f, pose) = match &p.outcome {
        Some(o) => {
            task.rollout(&p.eta, &mut digest)
                .map_err(|e| CliError::internal(format!("phase 2's rollout: {e}")))?;
            (o.f, Some(o.end_pose))
        }
        None => (f64::NAN, None),
    };
    let mut phase1 = TrajectoryDigest::new();
    p.preshape.write(&mut phase1);
    let d = &p.demand;
    let eta: Vec<f64> = p.eta.iter().flatten().copied().collect();
    let outputs = Outputs {
        status: crate::goal::status_name(p.converged()).into(),
        iterations: 0,
        rollouts: p.rollouts,
        stagnation_events: 0,
        restarts: 0,
        eta_bits: eta.iter().map(|v| bits(*v)).collect(),
        eta,
        f_bits: bits(f),
        f,
        end_pose_bits: PoseBits {
            position: pose.map_or(vec![], |q| q.position.iter().map(|v| bits(*v)).collect()),
            quat_wxyz: pose.map_or(vec![], |q| q.quat_wxyz.iter().map(|v| bits(*v)).collect()),
        },
        trajectory_samples: digest.samples(),
        trajectory_digest: format!("{:#018x}", digest.value()),
        two_phase: Some(TwoPhaseOutputs {
            stop: p.stop.name().into(),
            starts: p.starts,
            reach_f_bits: bits(p.reach_f),
            base_disturbance_bits: bits(p.base_disturbance),
            phase1_steps: p.preshape.steps(),
            phase1_samples: phase1.samples(),
            phase1_digest: format!("{:#018x}", phase1.value()),
            momentum_bits: bits(d.momentum_nms),
            torque_bits: bits(d.torque_nm),
            base_shift_bits: d.base_shift_m.iter().map(|v| bits(*v)).collect(),
            q_s_bits: p.q_s.iter().map(|v| bits(*v)).collect(),
        }),
    };
    Ok(TwoPhaseRun {
        outputs,
        config: tp,
        planner: config,
        phase2: task,
    })
}

/// Reads a record file.
pub fn read_record(path: &Path) -> Result<Record, CliError> {
    let text = std::fs::read_to_string(path)
        .or_input(|| format!("{}: cannot read record", path.display()))?;
    let rec: Record = serde_json::from_str(&text).or_input(|| {
        format!(
            "{}: not a certification record (the JSON that host-sim record writes)",
            path.display()
        )
    })?;
    if rec.format != FORMAT {
        return Err(CliError::input(format!(
            "{}: format {:?}, this host-sim reads {FORMAT:?}",
            path.display(),
            rec.format
        )));
    }
    Ok(rec)
}

/// A quantity that differs between two output sets.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Difference {
    /// Which quantity (`eta[2]`, `trajectory_digest`, …).
    pub what: String,
    /// Its value in the first set (the record).
    pub first: String,
    /// Its value in the second set (the replay).
    pub second: String,
}

/// The first quantity that differs between two output sets, in a fixed order.
pub fn first_difference(a: &Outputs, b: &Outputs) -> Option<Difference> {
    let phases = |o: &Outputs| o.two_phase.as_ref().map_or("one", |_| "two").to_string();
    let mut pairs: Vec<(String, String, String)> = vec![
        ("phases".into(), phases(a), phases(b)),
        ("status".into(), a.status.clone(), b.status.clone()),
        (
            "iterations".into(),
            a.iterations.to_string(),
            b.iterations.to_string(),
        ),
        (
            "rollouts".into(),
            a.rollouts.to_string(),
            b.rollouts.to_string(),
        ),
        (
            "stagnation_events".into(),
            a.stagnation_events.to_string(),
            b.stagnation_events.to_string(),
        ),
        (
            "restarts".into(),
            a.restarts.to_string(),
            b.restarts.to_string(),
        ),
        (
            "eta length".into(),
            a.eta_bits.len().to_string(),
            b.eta_bits.len().to_string(),
        ),
    ];
    for (i, (x, y)) in a.eta_bits.iter().zip(&b.eta_bits).enumerate() {
        pairs.push((format!("eta[{i}]"), x.clone(), y.clone()));
    }
    pairs.push(("f".into(), a.f_bits.clone(), b.f_bits.clone()));
    for (i, (x, y)) in a
        .end_pose_bits
        .position
        .iter()
        .zip(&b.end_pose_bits.position)
        .enumerate()
    {
        pairs.push((format!("end_pose.position[{i}]"), x.clone(), y.clone()));
    }
    for (i, (x, y)) in a
        .end_pose_bits
        .quat_wxyz
        .iter()
        .zip(&b.end_pose_bits.quat_wxyz)
        .enumerate()
    {
        pairs.push((format!("end_pose.quat_wxyz[{i}]"), x.clone(), y.clone()));
    }
    pairs.push((
        "trajectory_samples".into(),
        a.trajectory_samples.to_string(),
        b.trajectory_samples.to_string(),
    ));
    pairs.push((
        "trajectory_digest".into(),
        a.trajectory_digest.clone(),
        b.trajectory_digest.clone(),
    ));
    if let (Some(x), Some(y)) = (&a.two_phase, &b.two_phase) {
        pairs.push((
            "two_phase.base_shift length".into(),
            x.base_shift_bits.len().to_string(),
            y.base_shift_bits.len().to_string(),
        ));
        for ((k, u), (_, v)) in x.fields().into_iter().zip(y.fields()) {
            pairs.push((format!("two_phase.{k}"), u, v));
        }
        pairs.push((
            "two_phase.q_s length".into(),
            x.q_s_bits.len().to_string(),
            y.q_s_bits.len().to_string(),
        ));
        for (i, (u, v)) in x.q_s_bits.iter().zip(&y.q_s_bits).enumerate() {
            pairs.push((format!("two_phase.q_s[{i}]"), u.clone(), v.clone()));
        }
    }
    pairs
        .into_iter()
        .find(|(_, x, y)| x != y)
        .map(|(what, first, second)| Difference {
            what,
            first,
            second,
        })
}
