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
//! Data flows one way: [`model`] → [`kinematics`] → [`momentum`] → [`nullspace`] →
//! [`trajectory`] / [`task`] → [`rollout`] → [`optimizer`] ([`cpso`] over [`swarm`],
//! [`refine`]) → [`planner`], and [`execute`] streams a plan's setpoints; [`config`] holds
//! every planner setting, [`truth`] checks a trajectory, [`random`] is the only source of
//! randomness, [`reference`] holds the reference scenario of spec §8; [`retime`] re-times a
//! planned path to minimum time under joint rate and acceleration limits.
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

pub mod batch;
pub mod block;
pub mod config;
pub mod cpso;
pub mod digest;
pub mod error;
pub mod execute;
pub mod geometry;
pub mod integrator;
pub mod kinematics;
pub mod lanes;
pub mod model;
pub mod momentum;
pub mod multistart;
pub mod nullspace;
pub mod optimizer;
pub mod planner;
pub mod random;
pub mod reference;
pub mod refine;
pub mod retime;
pub mod rollout;
pub mod swarm;
pub mod task;
pub mod trajectory;
pub mod truth;

pub use config::{
    MAX_WINDOW, PlannerConfig, RefineAgainst, RefineConfig, StagnationConfig, Strategy,
};
pub use cpso::Cpso;
pub use digest::TrajectoryDigest;
pub use error::{BlockFault, Body, Error, Param, RankLoss};
pub use execute::Setpoints;
pub use geometry::{Pose, PoseError, Sym3};
pub use kinematics::{Frames, IDENTITY_WXYZ, LinkFrame};
pub use model::{BodyDesc, CHASER7, Inertia, JointDesc, Origin, Robot, RobotDesc, UNIT_TOLERANCE};
pub use momentum::{Momentum, generalized_jacobian};
pub use multistart::{LmConfig, Multistart, MultistartReport};
pub use nullspace::{Basis, PIVOT_TOLERANCE, RANK_TOLERANCE, conditioning};
pub use optimizer::{Candidate, Evaluation, Event, Next, Observer, Optimizer, Stop};
pub use planner::{Plan, Planner, Running, Stage, Status};
pub use refine::{RefineReport, RefineStop};
pub use rollout::{Outcome, Progress, Rollout, Sample, Sink};
pub use swarm::{Cost, Swarm};
pub use task::Task;
pub use trajectory::{MAX_DEGREE, MAX_STEPS, Motion, TimeLaw, eta_pairs};
pub use truth::{TruthModel, TruthState};
