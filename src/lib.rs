//! # reactionless
//!
//! Reactionless motion planning for a free-floating space robot: joint trajectories in the
//! reaction null space of the coupling inertia, so that the end effector moves while the
//! base attitude does not.
//!
//! `#![no_std]`, no allocation, no recursion, every loop bounded by a constant or a
//! caller-given budget, fixed-size state (`N` joints, null-space dimension `K = N − 3`,
//! both const generics; `K` is checked at compile time). Every failure is a typed
//! [`Error`]. All maths uses `libm`, so results are bit-identical across targets.
//!
//! Units: SI and radians throughout (m, kg, kg m², s, rad, rad/s). The inertial frame is
//! the base frame at `t = 0`; matrices that describe one configuration ([`Frames`],
//! [`Momentum`], [`Basis`]) are in the base frame.
//!
//! The modules are grouped by layer, and data flows one way, from the bottom up:
//! - foundations: [`error`] (every failure, a small `Copy` enum) and [`lanes`] (the
//!   arithmetic of one number or of several side by side);
//! - [`physics`]: [`model`] → [`kinematics`] → [`momentum`] → [`nullspace`], one
//!   configuration of the robot;
//! - [`path`]: [`trajectory`] / [`task`] → [`rollout`] (and [`batch`] in lanes), [`truth`]
//!   along a path, [`digest`], [`retime`];
//! - [`search`]: [`config`] (every planner setting), [`random`] (the only source of
//!   randomness), the [`optimizer`] seam and the strategies behind it ([`strategy`]:
//!   [`multistart`], [`cpso`] over [`swarm`]), [`refine`];
//! - [`flight`]: the [`planner`] that drives a search over rollouts under a budget,
//!   [`block`] (a whole task as bytes), [`execute`] (a plan's setpoints) and [`reference`]
//!   (the scenario of spec §8).
//!
//! Each folder's `mod.rs` says what its layer owns and what it may use; every module keeps
//! its flat path (`reactionless::planner`).
//!
//! Verifies RL-GOLD-004.
//!
//! ```
//! use reactionless::{CHASER7, Motion, Pose, Robot, Task};
//! let robot = Robot::new(&CHASER7)?;
//! let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
//! let target = Pose {
//!     position: [2.0166710746921925, 0.13996636886034725, -1.43192511932475],
//!     quat_wxyz: [0.3874560731031927, 0.2654610699800615, -0.37163840872581944, 0.8008077827420479],
//! };
//! let task: Task<7, 4> = Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1)?)?;
//! let eta = [[3.14771, 0.809316], [1.12249, 0.754006], [4.7352, 0.406031], [-4.1572, 4.29895]];
//! let outcome = task.rollout(&eta, &mut ())?;
//! assert_eq!(outcome.phi, 0.0);
//! assert!(outcome.f < 1e-3);
//! # Ok::<(), reactionless::Error>(())
//! ```
//!
//! Verifies RL-CORE-005.
//!
//! A null-space dimension other than `N − 3` does not compile:
//!
//! ```compile_fail
//! use reactionless::{CHASER7, Motion, Pose, Robot, Task};
//! let robot = Robot::new(&CHASER7).unwrap();
//! let target = Pose { position: [0.0; 3], quat_wxyz: [1.0, 0.0, 0.0, 0.0] };
//! let task = Task::<7, 3>::new(robot, [-1.0; 7], target, Motion::new(1.0, 0.1, 1).unwrap());
//! ```
#![no_std]

#[cfg(any(test, feature = "std"))]
extern crate std;

pub mod dual;
pub mod error;
pub mod flight;
pub mod lanes;
pub mod path;
pub mod physics;
pub mod search;

// Every module keeps its flat path (`reactionless::planner`, `crate::rollout`): the folders
// group them by layer, the paths stay what they were.
pub use flight::{block, closed_loop, execute, planner, reference, twophase};
pub use path::{batch, digest, integrator, preshape, retime, rollout, task, trajectory, truth};
pub use physics::{clearance, collision, geometry, kinematics, model, momentum, nullspace};
pub use search::{config, cpso, multistart, optimizer, random, refine, strategy, swarm};

pub use clearance::CollisionSet;
pub use config::{
    MAX_WINDOW, PlannerConfig, RefineAgainst, RefineConfig, StagnationConfig, Strategy,
};
pub use cpso::Cpso;
pub use digest::TrajectoryDigest;
pub use error::{BlockFault, Body, Error, NeedsOneSegment, Param, RankLoss};
pub use execute::Setpoints;
pub use geometry::{Pose, PoseError, Sym3};
pub use kinematics::{Frames, IDENTITY_WXYZ, LinkFrame};
pub use model::{BodyDesc, CHASER7, Inertia, JointDesc, Origin, Robot, RobotDesc, UNIT_TOLERANCE};
pub use momentum::{Momentum, generalized_jacobian};
pub use multistart::{LmConfig, Multistart, MultistartReport};
pub use nullspace::{Basis, PIVOT_TOLERANCE, RANK_TOLERANCE, conditioning};
pub use optimizer::{
    Candidate, Evaluation, Event, Method, Next, Observer, Optimizer, SearchReport, Stop,
};
pub use planner::{Plan, Planner, Running, Stage, Status};
pub use preshape::{Demand, Preshape, PreshapeLimits, PreshapeSetpoints};
pub use refine::{RefineReport, RefineStop};
pub use rollout::{Outcome, Progress, Rollout, Sample, Sink};
pub use strategy::Search;
pub use swarm::{Cost, Swarm};
pub use task::Task;
pub use trajectory::{
    AB5_STEP_S, Eta, Family, Integrator, MAX_DEGREE, MAX_SEGMENTS, MAX_STEPS, Motion,
    RK4_MAX_DEFAULT_STRIDE, RK4_STEP_S, TimeLaw, eta_flat, eta_from_flat, eta_pairs, one_segment,
};
pub use truth::{TRUTH_SUBSTEPS, TruthModel, TruthState};
pub use twophase::{
    TwoPhaseConfig, TwoPhasePlan, TwoPhaseSearch, TwoPhaseStage, TwoPhaseStatus, TwoPhaseStop,
};
