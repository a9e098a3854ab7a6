//! host-sim: the std host simulator for the reactionless core.
//!
//! Feeds the no_std core tasks from TOML and robots from URDF, writes results (CSV, JSON),
//! and checks them. Exit codes: 0 success, 1 a result that does not pass, 2 bad input.
//! The binary is a thin CLI over this library; tests use the library directly.
//!
//! Data flows one way: `urdf`/`clearance` (the robot, its collision geometry and a path's
//! clearance) → `taskfile` (inputs, with `goal`: what a plan must reach) → `drive` (the planner) → `artifacts`,
//! `records`, `plots`, `view` (outputs, through `output`'s atomic writes), `flight` (the task
//! block of the flight image and C clients), `dispersion`/`sensors` → `closed_loop` (the
//! core's executor flown on the truth model) → `cmd/*` (one leaf per
//! subcommand, which only these shared modules feed). `version` names the build in every
//! output that carries one.
// A host tool: an out-of-range index here is a bug that should stop the program loudly.
#![allow(clippy::indexing_slicing)]

pub mod args;
pub mod artifacts;
pub mod campaign_report;
pub mod clearance;
pub mod cli;
pub mod closed_loop;
pub mod cmd;
pub mod dispatch;
pub mod dispersion;
pub mod dispersion_report;
pub mod drive;
pub mod error;
pub mod flight;
pub mod goal;
pub mod output;
pub mod plots;
pub mod preshaping;
pub mod records;
pub mod retiming;
pub mod sensors;
pub mod shards;
pub mod stats;
pub mod taskfile;
pub mod urdf;
pub mod version;
pub mod view;
