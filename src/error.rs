//! The error type: every way an input can be rejected or a computation can fail.
//!
//! Owns [`Error`] and the small enums that name *which* parameter was wrong. Errors are
//! `Copy`, carry no heap data, and say what was wrong; a spent budget is a status, never an
//! error. Joint and link numbers are 1-based (`q1 … qN`, `link1 … linkN`) as in the URDF and
//! the paper.

use core::fmt;

/// A body of the robot: the free-floating base or link `1..=N`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Body {
    /// The base (body 0).
    Base,
    /// Link `i` (1-based): the body moved by joint `i`.
    Link(u8),
}

/// The parameter an [`Error`] refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Param {
    /// Mass of a body (kg).
    Mass(Body),
    /// Centre-of-mass offset or inertial-frame angles of a body (m, rad).
    CenterOfMass(Body),
    /// Inertia tensor of a body (kg m²).
    Inertia(Body),
    /// Origin (xyz, rpy) of joint `i` in its parent frame (m, rad).
    JointOrigin(u8),
    /// Axis of joint `i`.
    JointAxis(u8),
    /// Lower position limit of joint `i` (rad).
    LowerLimit(u8),
    /// Upper position limit of joint `i` (rad).
    UpperLimit(u8),
    /// Velocity limit of joint `i` (rad/s); `0` is the common bound `q̇_max` of eq. 14.
    VelocityLimit(u8),
    /// Origin of the end-effector frame in the last link's frame (m, rad).
    EndEffector,
    /// Start angle of joint `i` (rad).
    Start(u8),
    /// Target position (m).
    TargetPosition,
    /// Target attitude quaternion.
    TargetAttitude,
    /// Motion duration `t_f` (s).
    FinalTime,
    /// Integration step `dt` (s).
    TimeStep,
    /// Component `i` (1-based) of the parameter vector η.
    Eta(u8),
    /// Swarm size T.
    Particles,
    /// Iteration limit m_max.
    MaxIterations,
    /// Cognitive factor c1.
    C1,
    /// Social factor c2.
    C2,
    /// Inertia weight at the first iteration, ω_max.
    WMax,
    /// Inertia weight at the last iteration, ω_min.
    WMin,
    /// Success threshold σ_e on f.
    Tolerance,
    /// Half-width B of the initial box of η.
    EtaBound,
    /// Stagnation window (iterations).
    StagnationWindow,
    /// Relative improvement below which the swarm stagnates.
    MinImprovement,
    /// Re-initialisation spread ε₁ of subswarm S1.
    Eps1,
    /// Inertia boost ε₂ of subswarm S2.
    Eps2,
    /// Refinement target on f.
    RefineTolerance,
    /// Refinement budget (rollouts).
    RefineRollouts,
    /// Integration steps per [`crate::Planner::step`] call of the flight driver.
    FrameBudget,
    /// The total rollout budget.
    MaxRollouts,
    /// Acceleration limit of joint `i` (rad/s²) for re-timing ([`crate::retime`]).
    AccelLimit(u8),
    /// Re-timing grid size `M` (points).
    RetimeGrid,
    /// Re-timing limit margin factor, in (0, 1].
    RetimeMargin,
    /// Pre-shaping (phase 1) acceleration limit (rad/s²), spec §15.
    PreshapeAccel,
    /// Longest pre-shaping phase (s).
    PreshapeDuration,
    /// Angular momentum the attitude control can absorb in phase 1 (N m s).
    WheelMomentum,
    /// Torque the attitude control can apply in phase 1 (N m).
    WheelTorque,
    /// Standoff distance at the start of phase 2 (m).
    StandoffDistance,
    /// Standoff angle at the start of phase 2 (rad).
    StandoffAngle,
    /// Largest acceptable base rotation of a plan on the truth model (rad).
    BaseDisturbance,
    /// Number of joints N of the robot (a capacity of the two-phase search).
    Joints,
    /// Number of segments of a motion ([`crate::Motion::with_segments`]).
    Segments,
    /// Control period `T_c` of the closed loop (s), spec §12.
    ControlPeriod,
    /// Base-attitude gain of the closed loop (1/s).
    BaseGain,
    /// End-effector gain of the closed loop (1/s).
    EeGain,
    /// Damping of the closed loop's base pseudo-inverse.
    BaseDamping,
    /// Damping of the closed loop's end-effector pseudo-inverse (m/rad).
    EeDamping,
    /// Length weighing orientation against position in the closed loop's end-effector
    /// task (m).
    OrientationLength,
    /// Pull of the closed loop's attitude estimate toward a star-tracker reading.
    FilterGain,
    /// Base attitude error that sends the closed loop to its safe state (rad).
    BaseLimit,
    /// Largest joint tracking error of the closed loop (rad).
    TrackingTolerance,
    /// Largest gyro rate in range (rad/s).
    GyroRange,
    /// Joint acceleration limit of the closed loop (rad/s²).
    LoopAccel,
    /// Weight of the end effector's motion in the closed loop's base correction (1/m²).
    DragWeight,
    /// Pull of the closed loop's drift estimate toward each cycle's.
    DriftGain,
    /// Collision primitive `i` (1-based, in the order given) of the robot: its body index or
    /// a size (m), spec §13.
    Collider(u8),
    /// Keep-out `k` (1-based): a size or its pose (m).
    KeepOut(u8),
    /// A checked pair of the collision set: an index that names no primitive or keep-out.
    CollisionPair,
    /// Required clearance (m), or the planning margin above it.
    Clearance,
}

impl Param {
    /// The task-file key of this parameter as `table.key` (`"planner.particles"`,
    /// `"planner.stagnation.window"`, `"motion.tf_s"`), or `None` for what a task file does
    /// not hold directly (the robot's URDF values, η).
    ///
    /// Verifies RL-SIM-TASK-004.
    ///
    /// ```
    /// use reactionless::Param;
    /// assert_eq!(Param::StagnationWindow.key(), Some("planner.stagnation.window"));
    /// assert_eq!(Param::Eta(1).key(), None);
    /// ```
    #[must_use]
    pub const fn key(&self) -> Option<&'static str> {
        Some(match self {
            Param::Start(_) => "start.q_deg",
            Param::TargetPosition => "target.position_m",
            Param::TargetAttitude => "target.quat_wxyz",
            Param::FinalTime => "motion.tf_s",
            Param::TimeStep => "motion.dt_s",
            Param::Particles => "planner.particles",
            Param::MaxIterations => "planner.max_iterations",
            Param::C1 => "planner.c1",
            Param::C2 => "planner.c2",
            Param::WMax => "planner.w_max",
            Param::WMin => "planner.w_min",
            Param::Tolerance => "planner.tolerance",
            Param::EtaBound => "planner.eta_bound",
            Param::StagnationWindow => "planner.stagnation.window",
            Param::MinImprovement => "planner.stagnation.min_relative_improvement",
            Param::Eps1 => "planner.stagnation.eps1",
            Param::Eps2 => "planner.stagnation.eps2",
            Param::RefineTolerance => "planner.refine_tolerance",
            Param::RefineRollouts => "planner.refine_max_rollouts",
            Param::FrameBudget => "planner.frame_budget",
            Param::MaxRollouts => "planner.max_rollouts",
            Param::AccelLimit(_) => "limits.qdd_max_deg_s2",
            Param::RetimeGrid => "retime.grid",
            Param::RetimeMargin => "retime.margin",
            Param::PreshapeAccel => "preshape.qdd_max_deg_s2",
            Param::PreshapeDuration => "preshape.max_duration_s",
            Param::WheelMomentum => "preshape.max_momentum_nms",
            Param::WheelTorque => "preshape.max_torque_nm",
            Param::StandoffDistance => "preshape.standoff_m",
            Param::StandoffAngle => "preshape.standoff_deg",
            Param::BaseDisturbance => "check.max_base_disturbance_deg",
            Param::Segments => "motion.segments",
            Param::ControlPeriod => "sensors.control_period_s",
            Param::BaseGain => "closed_loop.base_gain_per_s",
            Param::EeGain => "closed_loop.ee_gain_per_s",
            Param::BaseDamping => "closed_loop.base_damping",
            Param::EeDamping => "closed_loop.ee_damping_m",
            Param::OrientationLength => "closed_loop.orientation_length_m",
            Param::FilterGain => "closed_loop.filter_gain",
            Param::BaseLimit => "closed_loop.base_limit_deg",
            Param::TrackingTolerance => "closed_loop.tracking_tolerance_deg",
            Param::GyroRange => "closed_loop.max_gyro_rate_deg_s",
            Param::LoopAccel => "closed_loop.qdd_max_deg_s2",
            Param::DragWeight => "closed_loop.drag_weight_per_m2",
            Param::DriftGain => "closed_loop.drift_gain",
            Param::Clearance => "collision.clearance_m",
            Param::KeepOut(_) => "keep_out",
            Param::Mass(_)
            | Param::CenterOfMass(_)
            | Param::Inertia(_)
            | Param::JointOrigin(_)
            | Param::JointAxis(_)
            | Param::LowerLimit(_)
            | Param::UpperLimit(_)
            | Param::VelocityLimit(_)
            | Param::EndEffector
            | Param::Joints
            | Param::Collider(_)
            | Param::CollisionPair
            | Param::Eta(_) => return None,
        })
    }
}

/// Why a null-space computation lost rank.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RankLoss {
    /// `H~bm` is (numerically) rank-deficient: the estimated `σ_min/σ_max` fell below
    /// [`crate::RANK_TOLERANCE`].
    Coupling,
    /// A modified Gram–Schmidt pivot fell below [`crate::PIVOT_TOLERANCE`]: the projected
    /// basis no longer spans the null space.
    Basis,
}

/// What is wrong with a task block ([`crate::block`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum BlockFault {
    /// The magic bytes are not the current version's (`block::MAGIC`).
    Magic,
    /// The block is for another joint count.
    JointCount,
    /// The length field does not match the layout.
    Length,
    /// The CRC-32 does not match.
    Checksum,
    /// The data ends early, or the output buffer is too small.
    Truncated,
    /// A field holds a value outside its encoding (e.g. a refine flag other than 0 or 1).
    Field,
}

/// What does not (yet) take a motion of several segments ([`crate::Motion::with_segments`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum NeedsOneSegment {
    /// The paper's family (eq. 14 normalises η's direction; segments free each amplitude).
    PaperFamily,
    /// The C-PSO strategy (it searches the paper's `2K` parameters).
    Cpso,
    /// The two-phase search (phase 2 is one segment).
    TwoPhase,
    /// The refinement against the truth model (it steps on one segment's sphere).
    TruthRefinement,
    /// Several rollouts side by side ([`crate::batch::Batch`]).
    Lanes,
}

/// Everything that can go wrong, as a small `Copy` value. A variant that breaks a limit
/// carries the limit, so this module depends on no other.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A value that must be finite is NaN or infinite.
    NotFinite(Param),
    /// A value that must be strictly positive is zero or negative.
    NotPositive(Param),
    /// An inertia tensor is not positive definite.
    InertiaNotPositiveDefinite(Body),
    /// A joint axis is not a unit vector: `|‖axis‖ − 1| > tolerance`
    /// ([`crate::UNIT_TOLERANCE`]).
    AxisNotUnit {
        /// The joint (1-based).
        joint: u8,
        /// The largest accepted `|‖axis‖ − 1|`.
        tolerance: f64,
    },
    /// A joint's lower limit is not below its upper limit.
    LimitsInverted(u8),
    /// A start angle lies outside its joint limits.
    StartOutsideLimits(u8),
    /// A quaternion's norm differs from 1 by more than `tolerance`
    /// ([`crate::UNIT_TOLERANCE`]).
    QuaternionNotUnit {
        /// The largest accepted `|‖q‖ − 1|`.
        tolerance: f64,
    },
    /// `t_f` is not a whole multiple of `dt` (relative tolerance 1e-9).
    StepsNotInteger,
    /// `t_f / dt` exceeds `max` ([`crate::MAX_STEPS`]).
    TooManySteps {
        /// The most integration steps a path may have.
        max: u32,
    },
    /// The time-law degree `n` is outside `1..=max` ([`crate::MAX_DEGREE`]).
    DegreeOutOfRange {
        /// The largest degree.
        max: u32,
    },
    /// A slice has the wrong length.
    WrongLength {
        /// Length required.
        expected: u16,
        /// Length given.
        got: u16,
    },
    /// η is zero (all β ≡ 0): no motion is defined.
    EtaZero,
    /// η is so large that `g` of eq. 14 overflows an `f64` (only η's direction matters:
    /// scale it down).
    EtaTooLarge,
    /// The reaction null space lost rank at integration step `step` (0 = start).
    RankLoss {
        /// Integration step (0-based; 0 is the start configuration).
        step: u32,
        /// Which test failed.
        cause: RankLoss,
    },
    /// A non-finite value appeared in the state at integration step `step`.
    NonFiniteState {
        /// Integration step (0-based).
        step: u32,
    },
    /// The system inertia `H~b` is not positive definite (never for a valid model).
    SingularInertia,
    /// A value that must not be negative is.
    Negative(Param),
    /// More than the fixed capacity was asked for.
    CapacityExceeded {
        /// What was asked for.
        param: Param,
        /// How many.
        requested: u32,
        /// The capacity compiled in.
        capacity: u32,
    },
    /// ω_min is larger than ω_max.
    InertiaWeightsInverted,
    /// A task block is malformed.
    Block(BlockFault),
    /// The planner has no task yet ([`crate::Planner::IDLE`] before
    /// [`crate::Planner::reset`]).
    NotInitialized,
    /// A single-phase task block given to the two-phase search
    /// ([`crate::block::TaskBlock::load_two_phase_into`]).
    NotTwoPhase,
    /// A re-timing margin factor above 1 (it must lie in (0, 1]).
    MarginAboveOne,
    /// A closed-loop setting out of its range ([`crate::closed_loop::LoopConfig`]): a
    /// filter or drift gain above 1, a gain whose product with the control period is 1
    /// or more, or a control period that does not divide `t_f`.
    LoopSetting(Param),
    /// The `t_f/dt` steps do not split into `segments` equal segments.
    SegmentsUneven {
        /// The segment count asked for.
        segments: u32,
    },
    /// An integrator step that is not a whole divisor of a segment's `dt` steps (or not
    /// one `dt` for Euler): [`crate::Motion::with_integrator_stride`].
    StrideUneven {
        /// The samples per integrator step asked for.
        stride: u32,
    },
    /// A motion integrated by [`crate::Integrator::Rk4`] was given to several rollouts side
    /// by side ([`crate::batch::Batch`]), which integrate with the reference Euler step.
    NeedsEuler,
    /// A task with collision geometry ([`crate::Task::with_collision`]) was given to
    /// something that does not evaluate it: several rollouts side by side, or a motion
    /// integrated by RK4 or AB5. Its clearance is evaluated by the scalar Euler rollout.
    NeedsScalarEuler,
    /// A motion of several segments was given to something that plans or rolls out one.
    NeedsOneSegment(NeedsOneSegment),
    /// A re-timing grid of fewer than `min` points ([`crate::retime::MIN_GRID`]).
    GridTooSmall {
        /// The fewest grid points.
        min: u32,
    },
    /// A path to re-time has no length (fewer than two distinct samples, or not finite).
    PathTooShort,
    /// The path's speed vanishes inside it (it stops and moves on, or turns back) at
    /// sample `sample` (0-based): no finite-time re-timing with acceleration limits exists.
    PathStalls {
        /// The sample where the path stops.
        sample: u32,
    },
    /// The samples given to [`crate::retime::PathBuilder`] are not those measured by
    /// [`crate::retime::ArcLength`], or a grid does not match its path.
    PathMismatch,
    /// Re-timing found no positive speed at interior grid point `point` (the path needs
    /// infinite time there, e.g. at a corner).
    RetimeStalled {
        /// Grid point (0-based).
        point: u32,
    },
}

impl Error {
    /// The parameter the error names, if it names one.
    #[must_use]
    pub const fn param(&self) -> Option<Param> {
        match self {
            Error::NotFinite(p) | Error::NotPositive(p) | Error::Negative(p) => Some(*p),
            Error::CapacityExceeded { param, .. } => Some(*param),
            _ => None,
        }
    }
}

impl fmt::Display for Body {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Body::Base => f.write_str("base"),
            Body::Link(i) => write!(f, "link {i}"),
        }
    }
}

impl fmt::Display for Param {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Param::Mass(b) => write!(f, "mass of {b}"),
            Param::CenterOfMass(b) => write!(f, "inertial origin of {b}"),
            Param::Inertia(b) => write!(f, "inertia of {b}"),
            Param::JointOrigin(j) => write!(f, "origin of joint {j}"),
            Param::JointAxis(j) => write!(f, "axis of joint {j}"),
            Param::LowerLimit(j) => write!(f, "lower limit of joint {j}"),
            Param::UpperLimit(j) => write!(f, "upper limit of joint {j}"),
            Param::VelocityLimit(j) => write!(f, "velocity limit of joint {j}"),
            Param::EndEffector => f.write_str("end-effector origin"),
            Param::Start(j) => write!(f, "start angle of joint {j}"),
            Param::TargetPosition => f.write_str("target position"),
            Param::TargetAttitude => f.write_str("target quaternion"),
            Param::FinalTime => f.write_str("motion duration t_f"),
            Param::TimeStep => f.write_str("time step dt"),
            Param::Eta(i) => write!(f, "eta component {i}"),
            Param::Particles => f.write_str("particle count"),
            Param::MaxIterations => f.write_str("max_iterations"),
            Param::C1 => f.write_str("c1"),
            Param::C2 => f.write_str("c2"),
            Param::WMax => f.write_str("w_max"),
            Param::WMin => f.write_str("w_min"),
            Param::Tolerance => f.write_str("tolerance"),
            Param::EtaBound => f.write_str("eta_bound"),
            Param::StagnationWindow => f.write_str("stagnation window"),
            Param::MinImprovement => f.write_str("min_relative_improvement"),
            Param::Eps1 => f.write_str("eps1"),
            Param::Eps2 => f.write_str("eps2"),
            Param::RefineTolerance => f.write_str("refine_tolerance"),
            Param::RefineRollouts => f.write_str("refine_max_rollouts"),
            Param::FrameBudget => f.write_str("frame_budget"),
            Param::MaxRollouts => f.write_str("max_rollouts"),
            Param::AccelLimit(j) => write!(f, "acceleration limit of joint {j}"),
            Param::RetimeGrid => f.write_str("retime grid size"),
            Param::RetimeMargin => f.write_str("retime margin"),
            Param::PreshapeAccel => f.write_str("pre-shaping acceleration limit"),
            Param::PreshapeDuration => f.write_str("pre-shaping duration limit"),
            Param::WheelMomentum => f.write_str("attitude-control momentum capacity"),
            Param::WheelTorque => f.write_str("attitude-control torque capacity"),
            Param::StandoffDistance => f.write_str("standoff distance"),
            Param::StandoffAngle => f.write_str("standoff angle"),
            Param::BaseDisturbance => f.write_str("base disturbance limit"),
            Param::Joints => f.write_str("number of joints"),
            Param::Segments => f.write_str("segment count"),
            Param::ControlPeriod => f.write_str("control period"),
            Param::BaseGain => f.write_str("closed-loop base gain"),
            Param::EeGain => f.write_str("closed-loop end-effector gain"),
            Param::BaseDamping => f.write_str("closed-loop base damping"),
            Param::EeDamping => f.write_str("closed-loop end-effector damping"),
            Param::OrientationLength => f.write_str("closed-loop orientation length"),
            Param::FilterGain => f.write_str("attitude filter gain"),
            Param::BaseLimit => f.write_str("closed-loop base error limit"),
            Param::TrackingTolerance => f.write_str("joint tracking tolerance"),
            Param::GyroRange => f.write_str("gyro range"),
            Param::LoopAccel => f.write_str("closed-loop acceleration limit"),
            Param::DragWeight => f.write_str("closed-loop drag weight"),
            Param::DriftGain => f.write_str("drift estimate gain"),
            Param::Collider(i) => write!(f, "collision primitive {i}"),
            Param::KeepOut(k) => write!(f, "keep-out {k}"),
            Param::CollisionPair => f.write_str("collision pair"),
            Param::Clearance => f.write_str("clearance (m)"),
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::NotFinite(p) => write!(f, "{p} is not a finite number"),
            Error::NotPositive(p) => write!(f, "{p} must be strictly positive"),
            Error::InertiaNotPositiveDefinite(b) => {
                write!(f, "inertia of {b} is not positive definite")
            }
            Error::AxisNotUnit { joint, tolerance } => write!(
                f,
                "axis of joint {joint} is not a unit vector (|norm - 1| > {tolerance:e})"
            ),
            Error::LimitsInverted(j) => {
                write!(f, "joint {j}: lower limit is not below the upper limit")
            }
            Error::StartOutsideLimits(j) => {
                write!(f, "start angle of joint {j} is outside its limits")
            }
            Error::QuaternionNotUnit { tolerance } => write!(
                f,
                "quaternion is not unit length (|norm - 1| > {tolerance:e})"
            ),
            Error::StepsNotInteger => f.write_str("t_f is not a whole multiple of dt"),
            Error::TooManySteps { max } => {
                write!(f, "t_f / dt exceeds the maximum of {max} integration steps")
            }
            Error::DegreeOutOfRange { max } => {
                write!(f, "time-law degree n must be in 1..={max}")
            }
            Error::WrongLength { expected, got } => {
                write!(f, "expected {expected} values, got {got}")
            }
            Error::EtaZero => f.write_str("eta is zero: no motion is defined"),
            Error::EtaTooLarge => f.write_str(
                "eta is so large that g of eq. 14 overflows (only its direction matters: scale it down)",
            ),
            Error::RankLoss { step, cause } => match cause {
                RankLoss::Coupling => write!(
                    f,
                    "coupling inertia H~bm lost rank at integration step {step}"
                ),
                RankLoss::Basis => write!(
                    f,
                    "reaction null-space basis degenerated at integration step {step}"
                ),
            },
            Error::NonFiniteState { step } => {
                write!(f, "non-finite state at integration step {step}")
            }
            Error::SingularInertia => f.write_str("system inertia H~b is singular"),
            Error::Negative(p) => write!(f, "{p} must not be negative"),
            Error::CapacityExceeded {
                param,
                requested,
                capacity,
            } => write!(f, "{param} {requested} exceeds the capacity of {capacity}"),
            Error::InertiaWeightsInverted => f.write_str("w_min must not exceed w_max"),
            Error::NotInitialized => f.write_str("the planner has no task yet (call reset)"),
            Error::NotTwoPhase => {
                f.write_str("a single-phase task block (no two-phase settings): plan it with the planner")
            }
            Error::MarginAboveOne => f.write_str("retime margin must lie in (0, 1]"),
            Error::LoopSetting(Param::FilterGain) => {
                f.write_str("attitude filter gain must lie in (0, 1]")
            }
            Error::LoopSetting(Param::DriftGain) => f.write_str("drift gain must lie in [0, 1]"),
            Error::LoopSetting(p @ (Param::BaseGain | Param::EeGain)) => write!(
                f,
                "{p} times the control period must stay below 1 (the loop oscillates beyond)"
            ),
            Error::LoopSetting(Param::ControlPeriod) => {
                f.write_str("control period must divide t_f into a whole number of cycles")
            }
            Error::LoopSetting(p) => write!(f, "{p} is out of range"),
            Error::SegmentsUneven { segments } => write!(
                f,
                "the t_f/dt integration steps do not split into {segments} equal segments"
            ),
            Error::NeedsEuler => f.write_str(
                "rollouts side by side (lanes) integrate with Euler only: roll an rk4 motion out one at a time",
            ),
            Error::NeedsScalarEuler => f.write_str(
                "collision geometry is evaluated by the scalar Euler rollout only: not in lanes, not with rk4 or ab5",
            ),
            Error::StrideUneven { stride } => write!(
                f,
                "an integrator step of {stride} dt does not divide each segment's steps \
                 (Euler integrates every dt)"
            ),
            Error::NeedsOneSegment(what) => write!(
                f,
                "motion.segments above 1 {}",
                match what {
                    NeedsOneSegment::PaperFamily => {
                        "needs motion.family = \"free_amplitude\" (the paper's family is one segment)"
                    }
                    NeedsOneSegment::Cpso => {
                        "needs planner.strategy = \"multistart\" (cpso searches one segment)"
                    }
                    NeedsOneSegment::TwoPhase => "is not taken by two-phase tasks (phase 2 is one segment)",
                    NeedsOneSegment::TruthRefinement => {
                        "is not taken by the refinement against the truth model"
                    }
                    NeedsOneSegment::Lanes => "is not taken by the rollout lanes",
                }
            ),
            Error::GridTooSmall { min } => {
                write!(f, "retime grid must have at least {min} points")
            }
            Error::PathTooShort => f.write_str("the path to re-time has no length"),
            Error::PathStalls { sample } => write!(
                f,
                "the path's speed vanishes inside it at sample {sample} (it stops or turns back)"
            ),
            Error::PathMismatch => {
                f.write_str("the re-timing grid does not match its path (not the same samples)")
            }
            Error::RetimeStalled { point } => write!(
                f,
                "re-timing found no positive speed at grid point {point}"
            ),
            Error::Block(fault) => write!(
                f,
                "task block: {}",
                match fault {
                    BlockFault::Magic => "wrong magic bytes",
                    BlockFault::JointCount => "built for another joint count",
                    BlockFault::Length => "wrong length",
                    BlockFault::Checksum => "CRC-32 mismatch",
                    BlockFault::Truncated => "too short",
                    BlockFault::Field => "a field is out of range",
                }
            ),
        }
    }
}

impl core::error::Error for Error {}
