//! `host-sim record`: plan a task and write its certification record.
//!
//! The record (see [`crate::records`]) holds the task's text with the URDF path made
//! relative to the record file, the URDF's SHA-256, the seed and refinement tolerance, the
//! build, and the outputs as bit patterns with the trajectory digest. Written atomically.

use crate::args::PlanArgs;
use crate::error::{CliError, Context};
use crate::output::{FileKind, write_file};
use crate::records::{FORMAT, Record, outputs_of, relative_text, sha256_hex};
use crate::taskfile;
use crate::version::Build;
use crate::with_dims;
use std::path::{Path, PathBuf};

/// Plan a task and write a certification record (task, URDF hash, build, outputs as bit
/// patterns, trajectory digest) to REC.json.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task file (TOML).
    task: PathBuf,
    /// Record file to write (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    planning: PlanArgs,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        record(&self.task, &self.out, &self.planning)
    }
}

fn record(task_path: &Path, out: &Path, planning: &PlanArgs) -> Result<(), CliError> {
    let mut lt = taskfile::load(task_path)?;
    lt.set_integrator(planning.integrator)?;
    let overrides = planning.overrides();
    let run = with_dims!(lt.chain.dof(), outputs_of, &lt, &overrides)?;
    // The task text, with the URDF path made relative to where the record will live.
    let record_dir = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut table: toml::Table = toml::from_str(&lt.text).or_internal(|| "re-reading the task")?;
    if let Some(toml::Value::Table(robot)) = table.get_mut("robot") {
        robot.insert(
            "urdf".into(),
            toml::Value::String(relative_text(&record_dir, &lt.urdf_path)?),
        );
    }
    let rec = Record {
        format: FORMAT.into(),
        task_file: task_path.display().to_string(),
        task_toml: toml::to_string(&table).or_internal(|| "writing the task")?,
        urdf_sha256: sha256_hex(lt.urdf_text.as_bytes()),
        seed: run.seed,
        refine_tolerance: run.refine_tolerance,
        strategy: Some(run.strategy.name().into()),
        refine_against: Some(run.refine_against.name().into()),
        build: Build::current(),
        outputs: run.outputs,
    };
    let mut text = serde_json::to_string_pretty(&rec).or_internal(|| "record JSON")?;
    text.push('\n');
    write_file(out, text.as_bytes(), FileKind::Record)?;
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
