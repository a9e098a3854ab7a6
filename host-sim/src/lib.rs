//! host-sim: the std host simulator for the reactionless core.
//!
//! Feeds the no_std core tasks from TOML and robots from URDF, writes results (CSV, JSON),
//! and checks them. Exit codes: 0 success, 1 a result that does not pass, 2 bad input.
//! The binary is a thin CLI over this library; tests use the library directly.
// A host tool: an out-of-range index here is a bug that should stop the program loudly.
#![allow(clippy::indexing_slicing)]

pub mod cmd;
pub mod dispatch;
pub mod error;
pub mod output;
pub mod plots;
pub mod taskfile;
pub mod urdf;
