//! The search layer: how η is chosen.
//!
//! Owns the planner's settings ([`config`]), the one source of randomness ([`random`]), the
//! ask/tell seam every search implements ([`optimizer`]), the strategies behind it
//! ([`strategy`]: the one place that resolves `[planner] strategy` to a running search;
//! [`multistart`], the default; [`cpso`] over [`swarm`], the paper's) and the
//! Levenberg–Marquardt refinement that may follow a search ([`refine`]).
//!
//! May use: [`crate::path`] (a search reads a rollout's [`crate::Outcome`], never runs
//! one), [`crate::physics`], [`crate::error`]. The planner ([`crate::flight`]) evaluates
//! every candidate a search asks for.

pub mod config;
pub mod cpso;
pub mod multistart;
pub mod optimizer;
pub mod random;
#[cfg(test)]
pub(crate) mod random_search;
pub mod refine;
pub mod strategy;
pub mod swarm;
