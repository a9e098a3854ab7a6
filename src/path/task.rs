//! A planning task: robot, start configuration, target pose and motion grid, validated once.
//!
//! Owns [`Task`] and everything that depends only on the task (not on η): the start
//! kinematics, the system CoM at `t = 0` (which never moves, spec §1), the start pose of
//! the end effector, and the initial null-space basis `N₀` shared by every rollout.
//! The inertial frame is the base frame at `t = 0`.

use crate::clearance::CollisionSet;
use crate::error::{Error, Param, RankLoss};
use crate::geometry::{Pose, Vec3, canonical, normalized};
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::model::{Robot, UNIT_TOLERANCE};
use crate::momentum::coupling;
use crate::nullspace::{Basis, Dims};
use crate::trajectory::Motion;

/// Everything a rollout or a plan needs besides η. Immutable.
///
/// `clone_from` works in place, field by field: a flight stack never holds a whole task.
#[derive(Debug, PartialEq)]
pub struct Task<const N: usize, const K: usize> {
    robot: Robot<N>,
    q0: [f64; N],
    target: Pose,
    motion: Motion,
    com0: Vec3,
    start_pose: Pose,
    basis0: Basis<N, K>,
    collision: CollisionSet<N>,
    /// `collision` checks at least one pair.
    colliding: bool,
}

impl<const N: usize, const K: usize> Clone for Task<N, K> {
    fn clone(&self) -> Self {
        let mut t = Self::IDLE;
        t.clone_from(self);
        t
    }

    fn clone_from(&mut self, source: &Self) {
        self.robot.clone_from(&source.robot);
        self.q0 = source.q0;
        self.target = source.target;
        self.motion = source.motion;
        self.com0 = source.com0;
        self.start_pose = source.start_pose;
        self.basis0 = source.basis0;
        self.collision.copy_from(&source.collision);
        self.colliding = source.colliding;
    }
}

impl<const N: usize, const K: usize> Task<N, K> {
    /// A placeholder (zero robot, no steps) for statically allocated planners; see
    /// [`crate::Planner::IDLE`].
    pub const IDLE: Self = Self {
        robot: Robot::IDLE,
        q0: [0.0; N],
        target: Pose::ZERO,
        motion: Motion::IDLE,
        com0: crate::geometry::ZERO3,
        start_pose: Pose::ZERO,
        basis0: Basis::IDLE,
        collision: CollisionSet::EMPTY,
        colliding: false,
    };

    /// Validates the start `q0` (rad) against the limits and the target (position in m,
    /// unit quaternion `[w,x,y,z]` within [`UNIT_TOLERANCE`], re-normalised), and computes
    /// the start frames and the initial basis.
    ///
    /// # Errors
    /// Non-finite values, a start outside the joint limits, a non-unit quaternion, or
    /// [`Error::RankLoss`] at step 0 if `H~bm(q0)` is rank-deficient.
    ///
    /// Verifies RL-POSE-001, RL-GOLD-001.
    ///
    /// ```
    /// use reactionless::{CHASER7, Motion, Pose, Robot, Task};
    /// let robot = Robot::new(&CHASER7).unwrap();
    /// let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
    /// let target = Pose { position: [2.0, 0.1, -1.4], quat_wxyz: [1.0, 0.0, 0.0, 0.0] };
    /// let task: Task<7, 4> = Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1).unwrap()).unwrap();
    /// assert!((task.start_pose().position[0] - 1.411848994172882).abs() < 1e-12);
    /// ```
    pub fn new(robot: Robot<N>, q0: [f64; N], target: Pose, motion: Motion) -> Result<Self, Error> {
        let mut t = Self::IDLE;
        t.robot = robot;
        t.finish(q0, target, motion)?;
        Ok(t)
    }

    /// Builds the task in place from a robot description, exactly as [`Task::new`] with
    /// [`Robot::new`] would (no task-sized temporaries, for static memory).
    ///
    /// # Errors
    /// As [`Robot::new`] and [`Task::new`]; the task is then unusable.
    pub fn init(
        &mut self,
        robot: &crate::model::RobotDesc<N>,
        q0: [f64; N],
        target: Pose,
        motion: Motion,
    ) -> Result<(), Error> {
        self.collision = CollisionSet::EMPTY;
        self.colliding = false;
        self.robot.init(robot)?;
        self.finish(q0, target, motion)
    }

    /// Moves the start to `q_s` (rad) after a pre-shaping phase (spec §15): the base
    /// attitude was held at identity and the system CoM has not moved, so `com0` is kept and
    /// the start frames, start pose and initial basis are those of `q_s`. A rollout of the
    /// result is phase 2 of a two-phase plan, in the same inertial frame as the task.
    ///
    /// # Errors
    /// As [`Task::new`] for the start: non-finite, outside the limits, or a rank-deficient
    /// `H~bm(q_s)`; the task is then unchanged.
    pub fn move_start(&mut self, q_s: &[f64; N]) -> Result<(), Error> {
        let robot = &self.robot;
        check_start(robot, q_s)?;
        let frames = Frames::new(robot, q_s);
        self.basis0 = Basis::initial(&coupling(robot, &frames)).map_err(rank_error(0))?;
        self.start_pose = frames.end_pose(&self.com0, IDENTITY_WXYZ);
        self.q0 = *q_s;
        Ok(())
    }

    /// Everything after the robot: start, target, motion, start frames, initial basis.
    fn finish(&mut self, q0: [f64; N], target: Pose, motion: Motion) -> Result<(), Error> {
        let () = Dims::<N, K>::VALID;
        let robot = &self.robot;
        check_start(robot, &q0)?;
        let target = validate_pose(&target)?;
        let frames = Frames::new(robot, &q0);
        let basis0 = Basis::initial(&coupling(robot, &frames)).map_err(rank_error(0))?;
        self.com0 = frames.com;
        self.start_pose = frames.end_pose(&self.com0, IDENTITY_WXYZ);
        self.q0 = q0;
        self.target = target;
        self.motion = motion;
        self.basis0 = basis0;
        Ok(())
    }

    /// The task with collision geometry (spec §13): every rollout of it evaluates the
    /// clearance of its path ([`crate::Outcome::clearance`]), and a shortfall below the
    /// required clearance counts as constraint violation in Φ, so both strategies plan
    /// around it. An empty set leaves the task as it was, bit for bit.
    ///
    /// # Errors
    /// [`Error::NeedsScalarEuler`] if the motion is integrated by RK4 or AB5 (their
    /// rollouts do not evaluate the geometry).
    pub fn with_collision(mut self, set: CollisionSet<N>) -> Result<Self, Error> {
        self.set_collision(set)?;
        Ok(self)
    }

    /// [`Task::with_collision`] in place.
    ///
    /// # Errors
    /// As [`Task::with_collision`]; the task then keeps its geometry.
    pub fn set_collision(&mut self, set: CollisionSet<N>) -> Result<(), Error> {
        if !set.is_empty() && self.motion.integrator() != crate::trajectory::Integrator::Euler {
            return Err(Error::NeedsScalarEuler);
        }
        self.collision = set;
        self.colliding = !self.collision.is_empty();
        if self.colliding {
            self.collision.bound(&self.robot);
        }
        Ok(())
    }

    /// The collision geometry, if any pair is checked.
    #[must_use]
    pub fn collision(&self) -> Option<&CollisionSet<N>> {
        self.colliding.then_some(&self.collision)
    }

    /// The robot model.
    #[must_use]
    pub fn robot(&self) -> &Robot<N> {
        &self.robot
    }

    /// Start configuration (rad).
    #[must_use]
    pub fn start(&self) -> &[f64; N] {
        &self.q0
    }

    /// Target end-effector pose (inertial frame; quaternion normalised, `w ≥ 0`).
    #[must_use]
    pub fn target(&self) -> &Pose {
        &self.target
    }

    /// The time grid.
    #[must_use]
    pub fn motion(&self) -> &Motion {
        &self.motion
    }

    /// System CoM (m, inertial frame), fixed for the whole motion.
    #[must_use]
    pub fn com0(&self) -> Vec3 {
        self.com0
    }

    /// End-effector pose at the start (inertial frame).
    #[must_use]
    pub fn start_pose(&self) -> &Pose {
        &self.start_pose
    }

    /// The initial null-space basis `N₀ = MGS(P(q₀)E)`.
    #[must_use]
    pub fn initial_basis(&self) -> &Basis<N, K> {
        &self.basis0
    }

    /// End-effector pose (inertial frame) at configuration `q` with base attitude
    /// `base_wxyz` and the base placed by CoM conservation.
    #[must_use]
    pub fn end_pose(&self, q: &[f64; N], base_wxyz: [f64; 4]) -> Pose {
        Frames::new(&self.robot, q).end_pose(&self.com0, base_wxyz)
    }
}

/// A start configuration (rad): finite, within the joint limits.
fn check_start<const N: usize>(robot: &Robot<N>, q: &[f64; N]) -> Result<(), Error> {
    let limits = robot.lower().iter().zip(robot.upper().iter());
    for (i, (q, (lo, hi))) in q.iter().zip(limits).enumerate() {
        let j = (i + 1) as u8;
        if !q.is_finite() {
            return Err(Error::NotFinite(Param::Start(j)));
        }
        if q < lo || q > hi {
            return Err(Error::StartOutsideLimits(j));
        }
    }
    Ok(())
}

/// Checks a pose: finite numbers, quaternion within [`UNIT_TOLERANCE`] of unit length.
/// Returns it normalised with `w ≥ 0`.
///
/// # Errors
/// [`Error::NotFinite`] for the position or quaternion, [`Error::QuaternionNotUnit`].
pub fn validate_pose(p: &Pose) -> Result<Pose, Error> {
    if !p.position.iter().all(|v| v.is_finite()) {
        return Err(Error::NotFinite(Param::TargetPosition));
    }
    if !p.quat_wxyz.iter().all(|v| v.is_finite()) {
        return Err(Error::NotFinite(Param::TargetAttitude));
    }
    let [w, x, y, z] = p.quat_wxyz;
    let norm = libm::sqrt(w * w + x * x + y * y + z * z);
    // Components are finite here, so `norm` is finite or +∞ (never NaN).
    if libm::fabs(norm - 1.0) > UNIT_TOLERANCE {
        return Err(Error::QuaternionNotUnit {
            tolerance: UNIT_TOLERANCE,
        });
    }
    Ok(Pose {
        position: p.position,
        quat_wxyz: canonical(normalized(p.quat_wxyz)),
    })
}

/// Maps a null-space failure at `step` to the error type.
pub(crate) fn rank_error(step: u32) -> impl Fn(RankLoss) -> Error {
    move |cause| Error::RankLoss { step, cause }
}
