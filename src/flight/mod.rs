//! The flight layer: what flight software calls.
//!
//! Owns the resumable, budgeted [`planner`] that drives a search over rollouts, the
//! fixed byte layout of a whole task ([`block`]), the setpoint stream of a finished plan
//! ([`execute`]) and the reference scenario of spec §8 for code without a file system
//! ([`reference`]), and two-phase plans for generic targets ([`twophase`]: pre-shaping
//! under attitude control, then the reactionless motion), and the [`closed_loop`] executor
//! that flies a plan on measurements (spec §12).
//!
//! May use every layer below: [`crate::search`], [`crate::path`], [`crate::physics`],
//! [`crate::error`], [`crate::lanes`].

pub mod block;
pub mod closed_loop;
pub mod execute;
pub mod planner;
pub mod reference;
pub mod twophase;
