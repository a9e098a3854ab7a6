//! Certification records: what a record holds, how a plan becomes one, and how two are
//! compared bit for bit.
//!
//! Owns [`Record`] (format [`FORMAT`]): the task (its text, with the URDF path relative to
//! the record), the SHA-256 of the URDF's content, the seed and refinement setting, the
//! [`Build`] that made it (`crate::version`), and the [`Outputs`]: status, iteration, rollout and stagnation
//! counts, η, f and the end pose as exact IEEE-754 bit patterns ([`bits`]), and the
//! FNV-1a-64 digest over the bit patterns of the whole trajectory
//! ([`reactionless::TrajectoryDigest`]). [`outputs_of`] plans a task into outputs;
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
use reactionless::TrajectoryDigest;
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

/// Plans `lt` (with the overrides) and computes the outputs a record holds.
pub fn outputs_of<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
) -> Result<RecordedRun, CliError> {
    let config = lt.planner(HOST_CAPACITY, overrides)?;
    let task = lt.task::<N, K>()?;
    let p = drive::plan::<N, K>(lt, config, false)?.plan;
    let mut digest = TrajectoryDigest::new();
    let again = task
        .rollout(&p.eta, &mut digest)
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
            eta_bits: p.eta.iter().flatten().map(|v| bits(*v)).collect(),
            f_bits: bits(o.f),
            end_pose_bits: PoseBits {
                position: o.end_pose.position.iter().map(|v| bits(*v)).collect(),
                quat_wxyz: o.end_pose.quat_wxyz.iter().map(|v| bits(*v)).collect(),
            },
            trajectory_samples: digest.samples(),
            trajectory_digest: format!("{:#018x}", digest.value()),
            eta: p.eta.iter().flatten().copied().collect(),
            f: o.f,
        },
        seed: config.seed,
        refine_tolerance: config.refine_tolerance,
        strategy: config.strategy,
        refine_against: config.refine_against,
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
    let mut pairs: Vec<(String, String, String)> = vec![
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
    pairs
        .into_iter()
        .find(|(_, x, y)| x != y)
        .map(|(what, first, second)| Difference {
            what,
            first,
            second,
        })
}
