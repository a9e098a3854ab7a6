//! The shape of host-sim that keeps it cheap to extend: subcommands are leaves, and every
//! planner setting names its task-file key.
//!
//! Requirements: RL-SIM-CLI, RL-SIM-TASK (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use reactionless::{Error, Param, PlannerConfig};
use std::path::Path;

/// No `cmd/` file imports another: shared pieces live in named modules.
/// Verifies RL-SIM-CLI-007.
#[test]
fn subcommands_are_leaves() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cmd");
    let mut leaves = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.file_name().unwrap() == "mod.rs" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            !text.contains("crate::cmd::") && !text.contains("super::"),
            "{} imports another subcommand",
            path.display()
        );
        assert!(
            text.contains("pub struct Args") && text.contains("pub fn run(self)"),
            "{} does not own its clap::Args",
            path.display()
        );
        leaves += 1;
    }
    assert!(leaves >= 11);
}

/// Every setting the planner validates names a key that the task file's `[planner]` table
/// really has (the serialized defaults), so errors point at the right key.
/// Verifies RL-SIM-TASK-004.
#[test]
fn every_planner_setting_has_a_task_key() {
    let table = toml::Value::try_from(PlannerConfig::default()).unwrap();
    let params = [
        Param::Particles,
        Param::MaxIterations,
        Param::C1,
        Param::C2,
        Param::WMax,
        Param::WMin,
        Param::Tolerance,
        Param::EtaBound,
        Param::StagnationWindow,
        Param::MinImprovement,
        Param::Eps1,
        Param::Eps2,
        Param::RefineTolerance,
        Param::RefineRollouts,
        Param::FrameBudget,
    ];
    for p in params {
        let key = p.key().unwrap();
        let below = key.strip_prefix("planner.").unwrap();
        let mut v = &table;
        for part in below.split('.') {
            match v.get(part) {
                Some(x) => v = x,
                // refine_tolerance defaults to "none": absent from the serialized table.
                None if p == Param::RefineTolerance => break,
                None => panic!("{p:?}: no key {key} in {table}"),
            }
        }
        assert_eq!(Error::NotPositive(p).param(), Some(p));
    }
}
