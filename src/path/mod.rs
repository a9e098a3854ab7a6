//! The path layer: a joint path from a start and an η, and what is measured along it.
//!
//! Owns the time law and its grid ([`trajectory`]), the task ([`task`]: robot, start,
//! target, grid), the integrators ([`integrator`]), the rollout of one candidate
//! ([`rollout`]) or of several in lanes ([`batch`]), the truth model that integrates the
//! base attitude along a path ([`truth`]), the trajectory digest ([`digest`]) and
//! minimum-time re-timing of a finished path ([`retime`]), and the pre-shaping phase of a
//! two-phase plan ([`preshape`]).
//!
//! May use: [`crate::physics`], [`crate::error`], [`crate::lanes`]. Nothing here knows of a
//! search or a planner: a rollout evaluates the η it is given.

pub mod batch;
pub mod digest;
pub mod integrator;
pub mod preshape;
pub mod retime;
pub mod rollout;
pub mod task;
pub mod trajectory;
pub mod truth;
