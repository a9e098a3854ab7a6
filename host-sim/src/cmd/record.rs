//! `host-sim record` and `host-sim replay`: certification records compared bit for bit.
//!
//! A record stores the task (its text, with the URDF path relative to the record), the
//! SHA-256 of the URDF's content, the seed and refinement setting, the build that made it
//! (crate version, git revision, target, profile), and the outputs: status, iteration,
//! rollout and stagnation counts, η, f and the end pose as exact IEEE-754 bit patterns, and
//! the FNV-1a-64 digest over the bit patterns of the whole trajectory
//! ([`reactionless::TrajectoryDigest`]).
//!
//! `replay` plans again with the record's task and settings and compares every output in a
//! fixed order; the first difference is named and the exit code is 1. The build that
//! replays may differ (debug or release, another machine): the bits must not.
//!
//! **Re-blessing** a justified change (an intended algorithm change, a dependency bump that
//! moves the bits): regenerate every golden record with `scripts/bless-records.sh`, review
//! the diff of `tests/records/` (which quantities moved, and why) and commit the new records
//! together with the change and a message that says why the bits moved.

use crate::cmd::plan::{HOST_CAPACITY, plan};
use crate::cmd::rollout::eta_error;
use crate::error::CliError;
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use reactionless::{Rollout, Status, TrajectoryDigest};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Component, Path, PathBuf};

/// Record format identifier.
pub const FORMAT: &str = "reactionless-record/1";

/// A certification record.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    /// The build that made the record.
    pub build: Build,
    /// What was planned.
    pub outputs: Outputs,
}

/// A build of host-sim.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Build {
    /// Crate version.
    pub crate_version: String,
    /// Git revision (`-dirty` with local changes), or `unknown`.
    pub git_revision: String,
    /// Target triple.
    pub target: String,
    /// Cargo profile (`debug` or `release`).
    pub profile: String,
    /// Optimisation level.
    pub opt_level: String,
}

impl Build {
    /// This build.
    pub fn current() -> Self {
        Self {
            crate_version: env!("CARGO_PKG_VERSION").into(),
            git_revision: env!("HOST_SIM_GIT_REV").into(),
            target: env!("HOST_SIM_TARGET").into(),
            profile: env!("HOST_SIM_PROFILE").into(),
            opt_level: env!("HOST_SIM_OPT_LEVEL").into(),
        }
    }
}

/// A pose as bit patterns.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseBits {
    /// Position (m), hex bit patterns.
    pub position: Vec<String>,
    /// Quaternion `[w, x, y, z]`, hex bit patterns.
    pub quat_wxyz: Vec<String>,
}

/// The outputs a replay must reproduce.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
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
    let abs = |p: &Path| {
        std::path::absolute(p).map_err(|e| CliError::input(format!("{}: {e}", p.display())))
    };
    let (from, to) = (abs(from)?, abs(to)?);
    fn norm(p: &Path) -> Vec<Component<'_>> {
        let mut v: Vec<Component> = Vec::new();
        for c in p.components() {
            match c {
                Component::ParentDir => {
                    v.pop();
                }
                Component::CurDir => {}
                c => v.push(c),
            }
        }
        v
    }
    let (f, t) = (norm(&from), norm(&to));
    let common = f.iter().zip(&t).take_while(|(a, b)| a == b).count();
    let mut out = PathBuf::new();
    for _ in common..f.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c.as_os_str());
    }
    Ok(out)
}

/// Plans `lt` and computes the outputs a record holds (with the effective seed and
/// refinement tolerance).
pub fn outputs_of<const N: usize, const K: usize>(
    lt: &LoadedTask,
    seed: Option<u64>,
    refine: Option<f64>,
) -> Result<(Outputs, u64, Option<f64>), CliError> {
    let config = lt.planner(
        HOST_CAPACITY,
        &Overrides {
            seed,
            refine_tolerance: refine,
        },
    )?;
    let task = lt.task::<N, K>()?;
    let done = plan::<N, K>(lt, config, false)?;
    let (status, p) = match done.status {
        Status::Finished(p) if p.converged() => ("converged", p),
        Status::Finished(p) => ("not_converged", p),
        Status::Running(_) => return Err(CliError::internal("planner still running")),
    };
    let mut digest = TrajectoryDigest::new();
    let mut r = Rollout::new(&task, &p.eta).map_err(eta_error)?;
    match r.advance(&task, u32::MAX, &mut digest) {
        Ok(reactionless::Progress::Done(o)) if o == p.outcome => {}
        Ok(_) => {
            return Err(CliError::internal(
                "the digest rollout differs from the plan's",
            ));
        }
        Err(e) => return Err(CliError::failed(format!("rollout failed: {e}"))),
    }
    let o = &p.outcome;
    Ok((
        Outputs {
            status: status.into(),
            iterations: p.iterations,
            rollouts: p.rollouts,
            stagnation_events: p.stagnation_events,
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
        config.seed,
        config.refine().map(|r| r.tolerance),
    ))
}

/// `host-sim record`.
pub fn record(
    task_path: &Path,
    out: &Path,
    seed: Option<u64>,
    refine: Option<f64>,
) -> Result<(), CliError> {
    let lt = taskfile::load(task_path)?;
    let (outputs, seed, refine) = with_dims!(lt.chain.dof(), outputs_of, &lt, seed, refine)?;
    // The task text, with the URDF path made relative to where the record will live.
    let record_dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut table: toml::Table =
        toml::from_str(&lt.text).map_err(|e| CliError::internal(e.to_string()))?;
    let urdf_rel = relative(&record_dir, &lt.urdf_path)?;
    if let Some(toml::Value::Table(robot)) = table.get_mut("robot") {
        robot.insert(
            "urdf".into(),
            toml::Value::String(urdf_rel.to_string_lossy().replace('\\', "/")),
        );
    }
    let rec = Record {
        format: FORMAT.into(),
        task_file: task_path.display().to_string(),
        task_toml: toml::to_string(&table).map_err(|e| CliError::internal(e.to_string()))?,
        urdf_sha256: sha256_hex(lt.urdf_text.as_bytes()),
        seed,
        refine_tolerance: refine,
        build: Build::current(),
        outputs,
    };
    let mut text =
        serde_json::to_string_pretty(&rec).map_err(|e| CliError::internal(e.to_string()))?;
    text.push('\n');
    // Atomic: a temporary file beside the target, then a rename.
    std::fs::create_dir_all(&record_dir)
        .map_err(|e| CliError::input(format!("{}: {e}", record_dir.display())))?;
    let tmp = record_dir.join(format!(
        ".{}.tmp-{}",
        out.file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default(),
        std::process::id()
    ));
    std::fs::write(&tmp, text).map_err(|e| CliError::input(format!("{}: {e}", tmp.display())))?;
    std::fs::rename(&tmp, out).map_err(|e| {
        let _ = std::fs::remove_file(&tmp);
        CliError::input(format!("{}: {e}", out.display()))
    })?;
    eprintln!(
        "record: {} after {} iterations, {} rollouts, digest {} -> {}",
        rec.outputs.status,
        rec.outputs.iterations,
        rec.outputs.rollouts,
        rec.outputs.trajectory_digest,
        out.display()
    );
    Ok(())
}

/// Reads a record file.
pub fn read_record(path: &Path) -> Result<Record, CliError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| CliError::input(format!("{}: cannot read record: {e}", path.display())))?;
    let rec: Record = serde_json::from_str(&text)
        .map_err(|e| CliError::input(format!("{}: not a record: {e}", path.display())))?;
    if rec.format != FORMAT {
        return Err(CliError::input(format!(
            "{}: format {:?}, this host-sim reads {FORMAT:?}",
            path.display(),
            rec.format
        )));
    }
    Ok(rec)
}

/// The first quantity that differs between two output sets, in a fixed order.
pub fn first_difference(a: &Outputs, b: &Outputs) -> Option<(String, String, String)> {
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
    pairs.into_iter().find(|(_, x, y)| x != y)
}

/// `host-sim replay`.
pub fn replay(path: &Path) -> Result<(), CliError> {
    let rec = read_record(path)?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let table: toml::Table = toml::from_str(&rec.task_toml)
        .map_err(|e| CliError::input(format!("{}: task_toml: {e}", path.display())))?;
    let urdf_rel = table
        .get("robot")
        .and_then(|r| r.get("urdf"))
        .and_then(toml::Value::as_str)
        .ok_or_else(|| {
            CliError::input(format!("{}: task_toml has no [robot] urdf", path.display()))
        })?;
    let urdf_path = dir.join(urdf_rel);
    let urdf_text = std::fs::read_to_string(&urdf_path).map_err(|e| {
        CliError::input(format!(
            "{}: URDF {}: {e}",
            path.display(),
            urdf_path.display()
        ))
    })?;
    let sha = sha256_hex(urdf_text.as_bytes());
    if sha != rec.urdf_sha256 {
        return Err(CliError::failed(format!(
            "{}: mismatch in urdf_sha256 ({}): recorded {}, found {sha}",
            path.display(),
            urdf_path.display(),
            rec.urdf_sha256
        )));
    }
    let lt = taskfile::from_texts(
        &urdf_path.with_file_name("record-task.toml"),
        &rec.task_toml,
        &urdf_text,
    )?;
    let (now, _, _) = with_dims!(
        lt.chain.dof(),
        outputs_of,
        &lt,
        Some(rec.seed),
        rec.refine_tolerance
    )?;
    let build = Build::current();
    if let Some((what, recorded, replayed)) = first_difference(&rec.outputs, &now) {
        return Err(CliError::failed(format!(
            "{}: mismatch in {what}: recorded {recorded}, replayed {replayed} (recorded by {} {} {}, replayed by {} {} {})",
            path.display(),
            rec.build.git_revision,
            rec.build.target,
            rec.build.profile,
            build.git_revision,
            build.target,
            build.profile
        )));
    }
    eprintln!(
        "replay: {} identical ({} iterations, {} rollouts, digest {}; {} build of {} on {})",
        path.display(),
        now.iterations,
        now.rollouts,
        now.trajectory_digest,
        build.profile,
        build.git_revision,
        build.target
    );
    Ok(())
}
