//! `host-sim replay`: re-run certification records and compare bit for bit.
//!
//! Each record is planned again with its task and settings and every output is compared
//! in a fixed order ([`crate::records::first_difference`]); the first difference is named
//! and the exit code is 1. The build that replays may differ (debug or release, another
//! machine): the bits must not. Every record is replayed; the first failure decides the
//! exit code.

use crate::error::{CliError, Context};
use crate::records::{Record, first_difference, outputs_of, read_record, sha256_hex};
use crate::taskfile::{self, Overrides};
use crate::version::Build;
use crate::with_dims;
use reactionless::{RefineAgainst, Strategy};
use std::path::{Path, PathBuf};

/// Re-run records and compare bit for bit; exit 1 naming the first difference.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Record files.
    #[arg(required = true)]
    records: Vec<PathBuf>,
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        // Every file is read first: one that is not a record is bad input (exit 2), named
        // alone, and nothing is replayed.
        let records = self
            .records
            .iter()
            .map(|r| read_record(r).map(|rec| (r, rec)))
            .collect::<Result<Vec<_>, _>>()?;
        let mut failed: Vec<CliError> = Vec::new();
        for (path, rec) in &records {
            if let Err(e) = replay(path, rec) {
                eprintln!("error: {e}");
                failed.push(e);
            }
        }
        match failed.first() {
            None => Ok(()),
            Some(e) => Err(CliError {
                code: e.code,
                message: format!(
                    "{} of {} records did not replay identically",
                    failed.len(),
                    records.len()
                ),
            }),
        }
    }
}

/// Replays one record, read from `path`.
pub fn replay(path: &Path, rec: &Record) -> Result<(), CliError> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let table: toml::Table =
        toml::from_str(&rec.task_toml).or_input(|| format!("{}: task_toml", path.display()))?;
    let urdf_rel = table
        .get("robot")
        .and_then(|r| r.get("urdf"))
        .and_then(toml::Value::as_str)
        .ok_or_else(|| {
            CliError::input(format!("{}: task_toml has no [robot] urdf", path.display()))
        })?;
    let urdf_path = dir.join(urdf_rel);
    let urdf_text = std::fs::read_to_string(&urdf_path)
        .or_input(|| format!("{}: URDF {}", path.display(), urdf_path.display()))?;
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
    let strategy = match rec.strategy.as_deref() {
        None => Strategy::Cpso,
        Some(name) => Strategy::from_name(name).ok_or_else(|| {
            CliError::input(format!("{}: unknown strategy {name:?}", path.display()))
        })?,
    };
    let refine_against = match rec.refine_against.as_deref() {
        None => RefineAgainst::Planner,
        Some(name) => RefineAgainst::from_name(name).ok_or_else(|| {
            CliError::input(format!(
                "{}: unknown refine_against {name:?}",
                path.display()
            ))
        })?,
    };
    // The record holds the refinement tolerance the planner was given (resolved from the
    // goal when it was made): replayed as is, with σ_e as the success test, it gives the
    // planner the same settings whatever the goal's defaults are today.
    let overrides = Overrides {
        seed: Some(rec.seed),
        refine_tolerance: rec.refine_tolerance,
        strategy: Some(strategy),
        refine_against: Some(refine_against),
        paper: true,
        integrator: None,
    };
    let now = with_dims!(lt.chain.dof(), outputs_of, &lt, &overrides)?.outputs;
    let build = Build::current();
    if let Some(d) = first_difference(&rec.outputs, &now) {
        return Err(CliError::failed(format!(
            "{}: mismatch in {}: recorded {}, replayed {} (recorded by {} {} {}, replayed by {} {} {})",
            path.display(),
            d.what,
            d.first,
            d.second,
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
