//! The physics layer: the robot and what one configuration of it is.
//!
//! Owns the rigid-body description and the quantities of a single configuration `q`:
//! [`geometry`] (rotations, quaternions, pose error), [`model`] (the robot, validated once),
//! [`kinematics`] (forward kinematics of the free-floating chain), [`momentum`] (`H~b`,
//! `H~bm`) and [`nullspace`] (the reaction null-space basis and its transport) and [`collision`]
//! (collision primitives and their signed distance, spec §13) and [`clearance`] (the
//! robot's primitives in the rollout's frames, keep-outs, pairs: the clearance bound of one
//! step).
//!
//! May use: [`crate::error`] and [`crate::lanes`]. Nothing here knows of a path, a time
//! law, a search or a planner.

pub mod clearance;
pub mod collision;
pub mod geometry;
pub mod kinematics;
pub mod model;
pub mod momentum;
pub mod nullspace;
