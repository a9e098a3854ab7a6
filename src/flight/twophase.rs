//! Two-phase plans (spec §15): the search chooses the start `q_s` of the reactionless phase
//! together with its η, so that a generic target (one no rollout of the task made) becomes a
//! problem as well posed as inverse kinematics; phase 1 ([`crate::preshape`]) brings the
//! arm from the task's start to `q_s` while the attitude control holds the base.
//!
//! Owns [`TwoPhaseConfig`], [`TwoPhasePlan`], [`TwoPhaseStop`], the resumable, budgeted
//! search [`TwoPhaseSearch`] (what it reports: [`TwoPhaseStatus`], [`TwoPhaseStage`]) and
//! [`plan`] ([`plan_in`] with the search in the caller's static memory).
//!
//! **Reach first.** A kinematic inverse (no rollouts: the end pose of a configuration with
//! the base attitude held and the CoM fixed, which is where a reactionless phase 2 ends)
//! decides whether the target lies within the arm's reach and limits at all. If its best
//! error stays above [`REACH_TOLERANCE`] the search ends at once,
//! [`TwoPhaseStop::BeyondReach`], without spending the rollout budget.
//!
//! **Starts.** Each start draws a direction `x` (2K uniforms `2u − 1`, normalised, from the
//! planner's stream), rolls it out from the task's start `q₀` (one rollout) to learn the
//! joint displacement `Δq` that motion makes, and starts at `q_s = q_ik − Δq` (clamped
//! inside the limits by the margin): phase 2 of that η from there ends near the inverse
//! solution `q_ik`.
//!
//! **One start** is a Levenberg–Marquardt run over `z = [q_s; x]` (`N + 2K` unknowns; `x`
//! renormalised after every accepted step, its scale being irrelevant, except with
//! [`crate::Family::FreeAmplitude`], whose amplitude is `x`'s scale) on the residual
//! `r = [e; w·p; s; d]` (`6 + N + 2` rows): the pose error `e` of phase 2's end (spec §6),
//! the joint-limit excess `p` of phase 2's path beyond the margin (as the multistart's),
//! the standoff shortfall `s = max(0, standoff_m − ‖p_ee(q_s) − p_target‖)` while the angle
//! to the target is below the standoff angle, and `d = max(0, T₁ − max_duration)/10 s` for
//! phase 1's duration `T₁`: its continuous estimate under the rate and acceleration limits
//! and the wheels' bounds, asked with 5 % to spare ([`Preshape::estimate`]), so the search
//! prefers starts the wheels can serve in time. Steps solve `(J Jᵀ + μ I) y = −r`,
//! `δ = Jᵀ y` (the minimum-norm LM step, `μ = λ·max diag JᵀJ`), `J` by forward differences
//! and rank-1 Broyden corrections between rebuilds; `λ` as the multistart's (Nielsen).
//! A start ends when `‖r‖` has not halved within `4(N + 2K) + 8` rollouts.
//!
//! **Done** when a rollout has `f ≤ tolerance`, `Φ = 0`, the standoff kept and `T₁` within
//! bounds ([`TwoPhaseStop::Converged`]); phase 1 is then slowed, if needed, until the
//! wheels' momentum and torque demand on its written samples is within the task's bounds
//! (both scale as `1/T` and `1/T²`), and phase 2 is flown on the truth model: a plan whose
//! base turns more than `max_base_disturbance` is not accepted (the next start is tried);
//! a plan that needs longer than `max_duration` for that
//! is refused and the next start tried; after 24 starts that end (converged and
//! refused, or stalled) where phase 1 needs longer than the longest allowed, the search
//! ends [`TwoPhaseStop::PreshapeBounds`]. Otherwise after
//! `max_rollouts` rollouts ([`TwoPhaseStop::Exhausted`], the closest plan reached).
//!
//! **Budgeted and resumable.** [`TwoPhaseSearch::step`] does at most `budget` units (one
//! evaluation each at most: a forward kinematics of the inverse, a rollout, or the test of
//! a start that met the goal), keeping the search's state between calls; any slicing gives
//! the bits of one unlimited call ([`plan_in`]).
//!
//! Loops are bounded by the rollout budget and constants; nothing allocates. Sizes:
//! `TwoPhasePlan<7, 4>` and `TwoPhaseSearch<7, 4>`, see `tests/sizes.rs`.

use crate::error::{Error, NeedsOneSegment, Param};
use crate::geometry::Pose;
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::model::Robot;
use crate::preshape::{Demand, Preshape, PreshapeLimits};
use crate::random::Stream;
use crate::retime::check_positive;
use crate::rollout::{Outcome, Progress, Rollout, Sample};
use crate::search::refine::solve_spd_in_place;
use crate::task::Task;
use crate::truth::{TRUTH_SUBSTEPS, TruthState};

/// Largest number of unknowns `N + 2K` (12 joints, K ≤ 9).
pub const MAX_Z: usize = 30;
/// Largest residual length `6 + N + 2`.
pub const MAX_R: usize = 20;
/// Most joints the two-phase search holds (`N + 2K ≤ MAX_Z` and `6 + N + 2 ≤ MAX_R`).
pub const MAX_JOINTS: usize = MAX_R - 8;
/// A kinematic inverse worse than this `f` (m and rad) means the target is out of reach.
pub const REACH_TOLERANCE: f64 = 1e-6;
/// Largest damping before a start counts as stalled.
const LAMBDA_MAX: f64 = 1e10;
/// Smallest damping.
const LAMBDA_MIN: f64 = 1e-15;
/// Kinematic-inverse starts (the task's start, then random configurations).
const IK_STARTS: u32 = 64;
/// Iterations per kinematic-inverse start.
const IK_ITERATIONS: u32 = 200;
/// Evaluations after which a kinematic-inverse start ends at its last accepted point: the
/// bound of its loop (its LM ends on damping, failure or an exact solution long before; a
/// start of the reference robot takes about 230).
const IK_MAX_EVALUATIONS: u32 = 100_000;
/// Directions per screening batch.
const SCREEN: usize = 8;
/// LM starts taken from each batch, the shortest pre-shapes first.
const STARTS_PER_SCREEN: usize = 3;
/// The search asks for phase 1 to fit its bounds with this much to spare on the estimate.
const WHEEL_MARGIN: f64 = 1.05;
/// Starts that end where phase 1 needs longer than the longest allowed, after which the
/// search ends [`TwoPhaseStop::PreshapeBounds`].
const REFUSED_STARTS: u32 = 24;
/// Slow-downs of phase 1 tried to meet the wheels' bounds.
const STRETCHES: u32 = 4;
/// Integration steps of phase 2 flown on the truth model per unit, when a start that met
/// the goal is tested: each step is one planner-model step and [`TRUTH_SUBSTEPS`]
/// sub-steps of the truth model (about 63,000 instructions on the Cortex-M7), so a unit
/// costs about what one planner-model rollout of the reference task does (13.8 M).
pub const TRUTH_STEPS_PER_UNIT: u32 = 200;
/// Against the truth model ([`TwoPhaseConfig::against_truth`]): corrections of a start that
/// met the goal on the planner model, each one flight of phase 2 on the truth model.
pub const TRUTH_CORRECTIONS: u32 = 8;

type Col = [f64; MAX_Z];
type Res = [f64; MAX_R];

/// Settings of a two-phase plan (SI units, radians).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TwoPhaseConfig {
    /// Phase 1's joint acceleration limit (rad/s²); its rate limit is the robot's `q̇max`.
    pub qdd_max: f64,
    /// Longest phase 1 (s).
    pub max_duration: f64,
    /// Angular momentum the attitude control can absorb (N m s).
    pub max_momentum: f64,
    /// Torque the attitude control can apply (N m).
    pub max_torque: f64,
    /// Distance from the target the end effector keeps at `q_s` (m) …
    pub standoff_m: f64,
    /// … or this angle from its attitude (rad); either is enough.
    pub standoff_rad: f64,
    /// Phase 2's success test on `f` (m and rad).
    pub tolerance: f64,
    /// Rollout budget.
    pub max_rollouts: u32,
    /// Joint-limit margin where the penalty rows start (rad).
    pub margin: f64,
    /// Largest base rotation phase 2 may cause on the truth model (rad): a plan that meets
    /// the pose on the planner model but turns the base more is not accepted.
    pub max_base_disturbance: f64,
    /// Phase 2's success test on the truth model's end pose (`truth_f ≤ tolerance`, spec
    /// §11) instead of the planner model's: a start that meets the goal on the planner
    /// model is corrected against the truth model (at most [`TRUTH_CORRECTIONS`] steps).
    /// In a task block it is the planner's `refine_against` ([`crate::RefineAgainst`]).
    pub against_truth: bool,
}

impl TwoPhaseConfig {
    /// Placeholder settings of an idle search (never validated, never used).
    const IDLE: Self = Self {
        qdd_max: 0.0,
        max_duration: 0.0,
        max_momentum: 0.0,
        max_torque: 0.0,
        standoff_m: 0.0,
        standoff_rad: 0.0,
        tolerance: 0.0,
        max_rollouts: 0,
        margin: 0.0,
        max_base_disturbance: 0.0,
        against_truth: false,
    };

    /// The documented defaults: 2 °/s², 60 s, 20 N m s, 1 N m, 0.2 m or 10°, f ≤ 1e-6 on
    /// the planner model, 8,040 rollouts, 0.005 rad.
    #[must_use]
    pub fn reference() -> Self {
        Self {
            qdd_max: 2f64.to_radians(),
            max_duration: 60.0,
            max_momentum: 20.0,
            max_torque: 1.0,
            standoff_m: 0.2,
            standoff_rad: 10f64.to_radians(),
            tolerance: 1e-6,
            max_rollouts: 8040,
            margin: 0.005,
            max_base_disturbance: 0.01f64.to_radians(),
            against_truth: false,
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// The first one that is not finite and positive (the standoffs may be 0).
    pub fn validate(&self) -> Result<(), Error> {
        check_positive(self.qdd_max, Param::PreshapeAccel)?;
        check_positive(self.max_duration, Param::PreshapeDuration)?;
        check_positive(self.max_momentum, Param::WheelMomentum)?;
        check_positive(self.max_torque, Param::WheelTorque)?;
        check_positive(self.tolerance, Param::RefineTolerance)?;
        check_positive(self.max_base_disturbance, Param::BaseDisturbance)?;
        for (v, p) in [
            (self.standoff_m, Param::StandoffDistance),
            (self.standoff_rad, Param::StandoffAngle),
        ] {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v < 0.0 {
                return Err(Error::Negative(p));
            }
        }
        if self.max_rollouts == 0 {
            return Err(Error::NotPositive(Param::MaxRollouts));
        }
        Ok(())
    }
}

/// How a two-phase search ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TwoPhaseStop {
    /// Phase 2 ends within the tolerance, phase 1 within its bounds.
    Converged,
    /// The budget is spent; the plan is the closest reached.
    Exhausted,
    /// No configuration within the limits puts the end effector on the target.
    BeyondReach,
    /// Plans reached the target, but none whose phase 1 the attitude control can serve
    /// within the longest phase 1.
    PreshapeBounds,
}

/// A two-phase plan: phase 1 from the task's start to `q_s`, phase 2 the rollout of `eta`
/// from `q_s`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TwoPhasePlan<const N: usize, const K: usize> {
    /// Start of phase 2 (rad).
    pub q_s: [f64; N],
    /// Phase 2's η (unit norm).
    pub eta: [[f64; 2]; K],
    /// Phase 1.
    pub preshape: Preshape<N>,
    /// What phase 1 demands of the attitude control.
    pub demand: Demand,
    /// Phase 2's rollout (planner model) of the closest plan; `None` when none was
    /// evaluated (a target beyond reach).
    pub outcome: Option<Outcome<N>>,
    /// Rollouts spent.
    pub rollouts: u32,
    /// LM starts begun.
    pub starts: u32,
    /// `f` of the kinematic inverse (how well the target lies within reach).
    pub reach_f: f64,
    /// Phase 2's largest base rotation on the truth model (rad; NaN when not flown: only a
    /// converged plan's is computed).
    pub base_disturbance: f64,
    /// How it ended.
    pub stop: TwoPhaseStop,
}

impl TwoPhaseStop {
    /// The name in outputs: `converged`, `exhausted`, `beyond_reach`, `preshape_bounds`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            TwoPhaseStop::Converged => "converged",
            TwoPhaseStop::Exhausted => "exhausted",
            TwoPhaseStop::BeyondReach => "beyond_reach",
            TwoPhaseStop::PreshapeBounds => "preshape_bounds",
        }
    }
}

impl<const N: usize, const K: usize> TwoPhasePlan<N, K> {
    /// Whether the plan meets what was asked.
    #[must_use]
    pub fn converged(&self) -> bool {
        self.stop == TwoPhaseStop::Converged
    }
}

/// The search's working memory: phase 2's task, the LM's Jacobian and normal matrix, the
/// screening pool (part of [`TwoPhaseSearch`]).
struct TwoPhaseScratch<const N: usize, const K: usize> {
    phase2: Task<N, K>,
    work: LmWork,
    pool: [(Col, f64); SCREEN],
}

impl<const N: usize, const K: usize> TwoPhaseScratch<N, K> {
    /// Scratch before any search (placeable in a `static`).
    const IDLE: Self = Self {
        phase2: Task::IDLE,
        work: LmWork::ZERO,
        pool: [([0.0; MAX_Z], f64::INFINITY); SCREEN],
    };
}

/// The LM's matrices: the Jacobian and the normal matrix of its step.
struct LmWork {
    jac: [[f64; MAX_Z]; MAX_R],
    normal: [[f64; MAX_R]; MAX_R],
}

impl LmWork {
    const ZERO: Self = Self {
        jac: [[0.0; MAX_Z]; MAX_R],
        normal: [[0.0; MAX_R]; MAX_R],
    };
}

/// Plans `task` in two phases with the planner's stream of `seed`, the search on the stack
/// (about 17 KB for `N = 7`); [`plan_in`] with a search the caller keeps.
///
/// # Errors
/// As [`plan_in`].
pub fn plan<const N: usize, const K: usize>(
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    seed: u64,
) -> Result<TwoPhasePlan<N, K>, Error> {
    let mut search = TwoPhaseSearch::IDLE;
    plan_in(&mut search, task, config, seed)
}

/// Plans `task` in two phases with the planner's stream of `seed`, in `search` (any
/// earlier content is overwritten; the result does not depend on it): [`TwoPhaseSearch`]
/// stepped with an unlimited budget until it finishes.
///
/// # Errors
/// Bad settings ([`TwoPhaseConfig::validate`]), a robot beyond the search's capacity
/// ([`MAX_JOINTS`]), or a rollout error from the task's own start (a rank-deficient start).
pub fn plan_in<const N: usize, const K: usize>(
    search: &mut TwoPhaseSearch<N, K>,
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    seed: u64,
) -> Result<TwoPhasePlan<N, K>, Error> {
    search.reset(task, config, seed)?;
    // Each call does u32::MAX units and every unit moves the search on; the search ends
    // within its rollout budget and the inverse's bounded starts.
    loop {
        if let TwoPhaseStatus::Finished(p) = search.step(u32::MAX)? {
            return Ok(p);
        }
    }
}

/// What [`TwoPhaseSearch::step`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[allow(
    clippy::large_enum_variant,
    reason = "returned by value, never stored in bulk"
)]
pub enum TwoPhaseStatus<const N: usize, const K: usize> {
    /// The budget is spent and the search has more to do.
    Running,
    /// The search has ended; every later call returns the same plan.
    Finished(TwoPhasePlan<N, K>),
}

/// Where a two-phase search is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum TwoPhaseStage {
    /// No task yet ([`TwoPhaseSearch::IDLE`]).
    Idle,
    /// The reach check: the kinematic inverse from the task's start and random starts.
    Reach,
    /// A screening batch: directions rolled out from the task's start, each with its own
    /// inverse.
    Screen,
    /// An LM start over `[q_s; η]`, or the test of how it ended.
    Search,
    /// Finished (or failed).
    Done,
}

/// The search's state between units (private: only [`TwoPhaseSearch`] moves it).
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant, reason = "one per search, in place")]
enum At<const N: usize, const K: usize> {
    Idle,
    /// The reach check's inverse is running (`run`, `ask`, `inverse`).
    Reach,
    /// The top of the search loop: the budget test, then a screening batch or the pool.
    Head,
    /// The screening batch's slot `slot` is to be drawn and rolled out.
    Screen,
    /// The inverse of slot `slot`'s rollout end is running.
    ScreenInverse,
    /// Take the pool's next start (right after a batch, without the budget test).
    Pick,
    /// An LM start is running (`run`, `ask`).
    Search,
    /// The start ended without meeting the goal at `point`.
    Consider,
    /// The start met the goal at `point`: fit phase 1, then fly phase 2 on the truth model.
    Accept,
    /// Phase 2 of the start at `point` is being flown on the truth model.
    Fly(Fly<N, K>),
    Done(TwoPhasePlan<N, K>),
    Failed(Error),
}

/// The two-phase search (spec §15) as a resumable, budgeted, deterministic state machine:
/// the loop of [`plan_in`] with its state kept between calls, so a flight scheduler can
/// give it a fixed slice of every frame.
///
/// **A unit** of [`TwoPhaseSearch::step`]'s budget is one move of the search, doing at most
/// one of:
/// - one kinematic-inverse evaluation (one forward kinematics) and its LM step (at most a
///   20 × 20 Cholesky and O(N) for the final pose);
/// - one rollout on the planner model (a screening direction from the task's start, or
///   phase 2 of an LM point from its `q_s`, with [`Preshape::estimate`]'s 33 points) and its
///   LM step;
/// - accepting a start that met the goal: phase 1 fitted to the wheels' bounds
///   ([`fit_preshape`]: at most 5 evaluations of its demand on the written samples);
/// - flying that start's phase 2 on the truth model: [`TRUTH_STEPS_PER_UNIT`] integration
///   steps, each with [`TRUTH_SUBSTEPS`] truth-model sub-steps (the whole rollout counts
///   as one of the budget's rollouts).
///
/// The unit that ends the search also fits the reported plan's phase 1 when it did not
/// converge (as above, without the truth model) and moves phase 2's task to `q_s`
/// ([`TwoPhaseSearch::phase2_task`]). A kinematic-inverse start ends after at most
/// 100,000 evaluations. The rollouts spent can pass
/// [`TwoPhaseConfig::max_rollouts`] by at most 2: a start taken right after a screening
/// batch spent the budget evaluates its first point, and accepts it if it met the goal.
///
/// Stepping with budget 1 per call gives the same bits as one call with an unlimited
/// budget: the state carried between calls is exactly the loop state, and every random
/// draw happens at a fixed point of the sequence. The search owns a copy of its task.
/// Size: `TwoPhaseSearch<7, 4>`, see `tests/sizes.rs`.
#[repr(C)]
pub struct TwoPhaseSearch<const N: usize, const K: usize> {
    // In this order (`repr(C)`): the state every unit touches first, the large and the
    // rarely touched after, so that the hot fields keep short offsets on the flight image
    // (Thumb-2 loads reach 4,095 bytes from a base register).
    /// The LM run in progress (the inverse's or a start's) and what it asks for.
    run: LmRun,
    ask: Ask,
    inverse: Inverse<N>,
    stream: Stream,
    /// The screening slot, its direction and its rollout's end (the inverse's first start).
    slot: usize,
    x: Col,
    /// Where the last start ended (Consider, Accept).
    point: Col,
    /// The pool's next start.
    next: usize,
    refused_starts: u32,
    /// Truth-model corrections of the start being accepted.
    corrections: u32,
    refused: bool,
    /// Once finished: whether phase 2's task was moved to the plan's `q_s` (then
    /// [`TwoPhaseSearch::phase2_task`] is it), or could not be.
    phase2_ready: Option<bool>,
    spent: u64,
    config: TwoPhaseConfig,
    task: Task<N, K>,
    scratch: TwoPhaseScratch<N, K>,
    best: Best<N, K>,
    at: At<N, K>,
}

impl<const N: usize, const K: usize> TwoPhaseSearch<N, K> {
    /// A search with no task (placeable in a `static`); [`TwoPhaseSearch::reset`] gives it
    /// one.
    pub const IDLE: Self = Self {
        task: Task::IDLE,
        config: TwoPhaseConfig::IDLE,
        scratch: TwoPhaseScratch::IDLE,
        stream: Stream::IDLE,
        best: Best::IDLE,
        run: LmRun::IDLE,
        ask: Ask::Done(false),
        inverse: Inverse::IDLE,
        slot: 0,
        x: [0.0; MAX_Z],
        point: [0.0; MAX_Z],
        next: 0,
        refused: false,
        refused_starts: 0,
        corrections: 0,
        at: At::Idle,
        spent: 0,
        phase2_ready: None,
    };

    /// Starts a search of `task` with `config` and the planner's stream of `seed`, in place
    /// (nothing task-sized passes through the stack); any earlier search is dropped.
    ///
    /// # Errors
    /// As [`TwoPhaseSearch::restart`].
    pub fn reset(
        &mut self,
        task: &Task<N, K>,
        config: &TwoPhaseConfig,
        seed: u64,
    ) -> Result<(), Error> {
        self.at = At::Idle;
        config.validate()?;
        self.task.clone_from(task);
        self.restart(config, seed)
    }

    /// Starts a search of the task it holds ([`TwoPhaseSearch::task_mut`], where flight
    /// software builds it in place), as [`TwoPhaseSearch::reset`].
    ///
    /// # Errors
    /// Bad settings ([`TwoPhaseConfig::validate`]), or a robot of more than
    /// [`MAX_JOINTS`] joints ([`Error::CapacityExceeded`] naming [`Param::Joints`]), or a
    /// motion of several segments ([`Error::NeedsOneSegment`]); the
    /// search is then idle.
    pub fn restart(&mut self, config: &TwoPhaseConfig, seed: u64) -> Result<(), Error> {
        self.at = At::Idle;
        config.validate()?;
        if N > MAX_JOINTS || N + 2 * K > MAX_Z {
            return Err(Error::CapacityExceeded {
                param: Param::Joints,
                requested: N.min(u32::MAX as usize) as u32,
                capacity: MAX_JOINTS as u32,
            });
        }
        if self.task.motion().segments() > 1 {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::TwoPhase));
        }
        self.config = *config;
        self.stream = Stream::new(seed);
        self.spent = 0;
        self.phase2_ready = None;
        let q0 = *self.task.start();
        self.best = Best::new(q0);
        self.inverse = Inverse::new(&self.task, &q0, IK_STARTS);
        (self.run, self.ask) = self
            .inverse
            .begin(&self.task, config.margin, &mut self.stream);
        self.at = At::Reach;
        Ok(())
    }

    /// The task, to build in place before [`TwoPhaseSearch::restart`]; the search is idle
    /// until then.
    pub fn task_mut(&mut self) -> &mut Task<N, K> {
        self.at = At::Idle;
        &mut self.task
    }

    /// Makes the search idle with `e`: every later step returns it (a task that failed to
    /// load).
    pub fn fail(&mut self, e: Error) {
        self.at = At::Failed(e);
    }

    /// Moves the search on by at most `budget` units (see [`TwoPhaseSearch`]); `Finished`
    /// with the plan once it has ended (then at once, whatever the budget).
    ///
    /// # Errors
    /// [`Error::NotInitialized`] before [`TwoPhaseSearch::reset`]; a rollout error from the
    /// task's own start (a rank-deficient start), returned again by every later call.
    pub fn step(&mut self, budget: u32) -> Result<TwoPhaseStatus<N, K>, Error> {
        for _ in 0..budget {
            match self.at {
                At::Done(p) => return Ok(TwoPhaseStatus::Finished(p)),
                At::Failed(e) => return Err(e),
                At::Idle => return Err(Error::NotInitialized),
                _ => {}
            }
            self.spent += 1;
            if let Err(e) = self.unit() {
                self.at = At::Failed(e);
            }
            if let (At::Done(p), None) = (&self.at, self.phase2_ready) {
                // In the unit that finished: phase 2's task from the plan's start, for
                // streaming (the plan's bits do not depend on it).
                self.phase2_ready = Some(self.scratch.phase2.move_start(&p.q_s).is_ok());
            }
        }
        match self.at {
            At::Done(p) => Ok(TwoPhaseStatus::Finished(p)),
            At::Failed(e) => Err(e),
            At::Idle => Err(Error::NotInitialized),
            _ => Ok(TwoPhaseStatus::Running),
        }
    }

    /// Where the search is.
    #[must_use]
    pub fn stage(&self) -> TwoPhaseStage {
        match self.at {
            At::Idle => TwoPhaseStage::Idle,
            At::Reach => TwoPhaseStage::Reach,
            At::Screen | At::ScreenInverse => TwoPhaseStage::Screen,
            At::Head | At::Pick | At::Search | At::Consider | At::Accept | At::Fly(_) => {
                TwoPhaseStage::Search
            }
            At::Done(_) | At::Failed(_) => TwoPhaseStage::Done,
        }
    }

    /// Rollouts spent so far (of [`TwoPhaseConfig::max_rollouts`]).
    #[must_use]
    pub fn rollouts(&self) -> u32 {
        self.best.rollouts
    }

    /// LM starts begun so far.
    #[must_use]
    pub fn starts(&self) -> u32 {
        self.best.starts
    }

    /// Units spent since [`TwoPhaseSearch::reset`].
    #[must_use]
    pub fn spent(&self) -> u64 {
        self.spent
    }

    /// The task being planned.
    #[must_use]
    pub fn task(&self) -> &Task<N, K> {
        &self.task
    }

    /// The finished plan (`None` while running, idle or failed).
    #[must_use]
    pub fn plan(&self) -> Option<&TwoPhasePlan<N, K>> {
        match &self.at {
            At::Done(p) => Some(p),
            _ => None,
        }
    }

    /// Phase 2's task once the search has finished: the task from the plan's `q_s` (the
    /// base moved by phase 1, the CoM kept), against which phase 2's setpoints are
    /// streamed ([`crate::Setpoints`] of the plan's η). `None` while running, or if that
    /// start lost rank.
    #[must_use]
    pub fn phase2_task(&self) -> Option<&Task<N, K>> {
        match (&self.at, self.phase2_ready) {
            (At::Done(_), Some(true)) => Some(&self.scratch.phase2),
            _ => None,
        }
    }

    /// One unit. Each state's work is a function of its own, so that the stack holds only
    /// the deepest one's frame (fitting phase 1 in [`At::Accept`]).
    fn unit(&mut self) -> Result<(), Error> {
        match self.at {
            At::Reach | At::ScreenInverse => self.inverse_unit(),
            At::Head => self.head_unit(),
            At::Screen => self.screen_unit(),
            At::Pick => self.pick_unit(),
            At::Search => self.search_unit(),
            At::Consider => self.consider_unit(),
            At::Accept => return self.accept_unit(),
            At::Fly(_) => self.fly_unit(),
            At::Idle | At::Done(_) | At::Failed(_) => {}
        }
        Ok(())
    }

    /// An evaluation of the running inverse, or the end of one of its starts; when the
    /// inverse is over, the reach check's verdict or the screening slot's start.
    #[inline(never)]
    fn inverse_unit(&mut self) {
        let Self {
            task,
            config: c,
            scratch,
            stream,
            best,
            run,
            ask,
            inverse,
            slot,
            x,
            next,
            refused,
            refused_starts,
            at,
            ..
        } = self;
        let TwoPhaseScratch { phase2, work, pool } = scratch;
        match ask {
            Ask::Eval => {
                *ask = if inverse.count() {
                    run.tell(work, ik_eval(task, c.margin, run.point()), 0)
                } else {
                    run.stop()
                };
                return;
            }
            Ask::Done(_) => {
                if inverse.end_start(task, run.point()) {
                    (*run, *ask) = inverse.begin(task, c.margin, stream);
                    return;
                }
            }
        }
        let (q_ik, f) = inverse.best;
        if matches!(*at, At::Reach) {
            phase2.clone_from(task);
            best.reach_f = f;
            if f > REACH_TOLERANCE {
                best.stop = TwoPhaseStop::BeyondReach;
                *at = At::Done(best.finish(task, c));
                return;
            }
            *refused = false;
            *refused_starts = 0;
            for p in pool.iter_mut() {
                *p = ([0.0; MAX_Z], f64::INFINITY);
            }
            *next = STARTS_PER_SCREEN;
            *at = At::Head;
        } else {
            if let Some(s) = pool.get_mut(*slot) {
                *s = screened(task, c, x, &inverse.first, &q_ik, f);
            }
            *slot += 1;
            *at = At::Screen;
        }
    }

    /// The top of the search loop: the budget test, then a screening batch or the pool.
    #[inline(never)]
    fn head_unit(&mut self) {
        if self.best.rollouts >= self.config.max_rollouts {
            self.at = At::Done(end_search(
                &mut self.best,
                self.refused,
                &self.task,
                &self.config,
            ));
        } else if self.next >= STARTS_PER_SCREEN {
            self.slot = 0;
            self.at = At::Screen;
        } else {
            self.at = At::Pick;
        }
    }

    /// The screening slot's direction and its rollout from the task's start (one rollout),
    /// then its inverse; or, after the last slot, the batch sorted.
    #[inline(never)]
    fn screen_unit(&mut self) {
        let Self {
            task,
            config: c,
            scratch,
            stream,
            best,
            run,
            ask,
            inverse,
            slot,
            x,
            next,
            at,
            ..
        } = self;
        let pool = &mut scratch.pool;
        if *slot >= SCREEN {
            sort_pool(pool);
            *next = 0;
            *at = At::Pick;
            return;
        }
        // A direction: 2K uniforms 2u − 1, normalised.
        *x = [0.0; MAX_Z];
        for v in x.iter_mut().take(2 * K) {
            *v = 2.0 * stream.uniform() - 1.0;
        }
        normalise(x, 0, 2 * K);
        if let Some(s) = pool.get_mut(*slot) {
            *s = ([0.0; MAX_Z], f64::INFINITY);
        }
        let rolled = if best.rollouts < c.max_rollouts {
            best.rollouts = best.rollouts.saturating_add(1);
            task.rollout(&to_eta::<K>(x, 0), &mut ()).ok()
        } else {
            None
        };
        if let Some(o) = rolled {
            *inverse = Inverse::new(task, &o.q_final, 1);
            (*run, *ask) = inverse.begin(task, c.margin, stream);
            *at = At::ScreenInverse;
        } else {
            *slot += 1;
        }
    }

    /// The pool's next start: an LM run over `[q_s; η]` from it.
    #[inline(never)]
    fn pick_unit(&mut self) {
        let Some((z, gap)) = self.scratch.pool.get(self.next).copied() else {
            self.at = At::Done(end_search(
                &mut self.best,
                self.refused,
                &self.task,
                &self.config,
            ));
            return;
        };
        self.next += 1;
        if !gap.is_finite() {
            self.next = STARTS_PER_SCREEN;
            self.at = At::Head;
            return;
        }
        self.best.starts += 1;
        let nz = N + 2 * K;
        let lm = Lm {
            nz,
            nr: 6 + N + 2,
            // η is a direction in the paper's family; with a free amplitude its scale is
            // the amplitude and stays as the search leaves it.
            sphere_from: if self.task.motion().family().free_amplitude() {
                MAX_Z
            } else {
                N
            },
            fd_step: 1e-7,
            patience: 4 * nz as u32 + 8,
            broyden: true,
        };
        (self.run, self.ask) = LmRun::begin(lm, &z, self.config.max_rollouts);
        self.at = At::Search;
    }

    /// One evaluation of the running start (one rollout), or how it ended.
    #[inline(never)]
    fn search_unit(&mut self) {
        let Self {
            task,
            config: c,
            scratch,
            best,
            run,
            ask,
            point,
            at,
            ..
        } = self;
        let TwoPhaseScratch { phase2, work, .. } = scratch;
        match ask {
            Ask::Eval => {
                best.rollouts = best.rollouts.saturating_add(1);
                let reply = evaluate(task, phase2, c, run.point());
                *ask = run.tell(work, reply, best.rollouts);
            }
            Ask::Done(met) => {
                *point = *run.point();
                *at = if *met { At::Accept } else { At::Consider };
                self.corrections = 0;
            }
        }
    }

    /// A start that did not meet the goal: kept if closest (one rollout); counted if it
    /// ended on phase 1's bounds.
    #[inline(never)]
    fn consider_unit(&mut self) {
        self.at = At::Head;
        let phase2 = &mut self.scratch.phase2;
        if self
            .best
            .consider(&self.task, phase2, &self.config, &self.point)
        {
            self.refused_starts += 1;
            self.refused = true;
            if self.refused_starts >= REFUSED_STARTS {
                self.at = At::Done(end_search(
                    &mut self.best,
                    self.refused,
                    &self.task,
                    &self.config,
                ));
            }
        }
    }

    /// A start that met the goal: phase 1 fitted within the wheels' bounds, then phase 2's
    /// rollout from its `q_s` set up on the truth model ([`At::Fly`]), or the next start.
    #[inline(never)]
    fn accept_unit(&mut self) -> Result<(), Error> {
        let phase2 = &mut self.scratch.phase2;
        match self
            .best
            .accept(&self.task, phase2, &self.config, &self.point)?
        {
            Some(fly) => self.at = At::Fly(fly),
            None => self.refuse(),
        }
        Ok(())
    }

    /// [`TRUTH_STEPS_PER_UNIT`] steps of phase 2 on the truth model; once it ends, the plan
    /// if the base stayed put, or the next start.
    #[inline(never)]
    fn fly_unit(&mut self) {
        let At::Fly(fly) = &mut self.at else {
            return;
        };
        let phase2 = &self.scratch.phase2;
        let Fly { rollout, truth, .. } = fly;
        let mut sink = |s: &Sample<N>| truth.push(phase2, &s.q, s.t);
        let o = match rollout.advance(phase2, TRUTH_STEPS_PER_UNIT, &mut sink) {
            Ok(Progress::Running { .. }) => return,
            Ok(Progress::Done(o)) => Some(o),
            Ok(Progress::Abandoned { .. }) | Err(_) => None,
        };
        if self.config.against_truth {
            if let Some(o) = o {
                if let Some(z) = self.truth_correction(&o) {
                    // Not yet on the truth model's goal: fit phase 1 to the corrected
                    // start and fly it again.
                    self.point = z;
                    self.at = At::Accept;
                    return;
                }
            }
        }
        let At::Fly(fly) = &self.at else {
            return;
        };
        let landed = o.is_some_and(|o| self.best.landed(&self.config, fly, &o, &self.point));
        if landed {
            self.at = At::Done(self.best.finish(&self.task, &self.config));
        } else if self.config.against_truth && self.corrections > 0 {
            // Corrected and still refused: the start ends where it got to.
            self.at = At::Consider;
        } else {
            self.refuse();
        }
    }

    /// Against the truth model, the flight of the start at `point` just ended in `o`: the
    /// corrected start if the truth model's end pose misses the goal, the base stayed put,
    /// the planner-model path keeps the joint limits and the standoff, and corrections are
    /// left. `z ← z + δ`, `δ = Jᵀ y`, `(J Jᵀ + μ I) y = −e`, with `e` the truth model's
    /// pose error and `J` the pose rows of the start's last Jacobian (planner model,
    /// Broyden-updated), `μ` 1e-12 of its largest column norm: the smallest change of
    /// `[q_s; η]` that moves the planner model's end pose by `−e` to first order. The
    /// models differ by the Euler path's discretisation, smoothly, so the corrections
    /// contract quickly.
    fn truth_correction(&mut self, o: &Outcome<N>) -> Option<Col> {
        let At::Fly(fly) = &self.at else {
            return None;
        };
        let phase2 = &self.scratch.phase2;
        let e = fly.truth.end_pose(phase2)?.error_to(phase2.target());
        if e.norm() <= self.config.tolerance
            || fly.base_disturbance(&self.config).is_none()
            || o.phi > 0.0
            || standoff_shortfall(phase2.start_pose(), self.task.target(), &self.config) > 0.0
            || self.corrections >= TRUTH_CORRECTIONS
            || !self.run.has_jacobian()
        {
            return None;
        }
        self.corrections += 1;
        let nz = N + 2 * K;
        let lm = Lm {
            nr: 6,
            ..self.run.lm
        };
        let mut r = [0.0; MAX_R];
        for (v, x) in r.iter_mut().zip(e.to_array()) {
            *v = x;
        }
        let LmWork { jac, normal } = &mut self.scratch.work;
        let (step, _) = lm.step(jac, normal, &r, 1e-12)?;
        let mut z = self.point;
        for (v, d) in z.iter_mut().zip(step.iter()).take(nz) {
            *v += d;
        }
        if lm.sphere_from < nz {
            normalise(&mut z, lm.sphere_from, nz);
        }
        Some(z)
    }

    /// A start that met the goal but was refused (phase 1's bounds, or the truth model):
    /// the next start, or the end once [`REFUSED_STARTS`] were.
    fn refuse(&mut self) {
        self.refused = true;
        self.refused_starts += 1;
        self.at = if self.refused_starts >= REFUSED_STARTS {
            At::Done(end_search(
                &mut self.best,
                self.refused,
                &self.task,
                &self.config,
            ))
        } else {
            At::Head
        };
    }
}

/// Phase 2 of a start that met the goal, being flown on the truth model: the rollout from
/// `q_s`, the truth model riding along, and the phase 1 fitted for that start.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Fly<const N: usize, const K: usize> {
    rollout: Rollout<N, K>,
    truth: TruthState<N>,
    preshape: Preshape<N>,
    demand: Demand,
}

impl<const N: usize, const K: usize> Fly<N, K> {
    /// The largest base rotation of the flight so far (rad), if the truth model met no
    /// error and the base stayed within `c.max_base_disturbance`.
    fn base_disturbance(&self, c: &TwoPhaseConfig) -> Option<f64> {
        let d = self.truth.max_angle();
        (self.truth.error().is_none() && !d.is_nan() && d <= c.max_base_disturbance).then_some(d)
    }
}

/// How the search ends when it gives up: on phase 1's bounds if any start ended there.
fn end_search<const N: usize, const K: usize>(
    best: &mut Best<N, K>,
    refused: bool,
    task: &Task<N, K>,
    c: &TwoPhaseConfig,
) -> TwoPhasePlan<N, K> {
    best.stop = if refused {
        TwoPhaseStop::PreshapeBounds
    } else {
        TwoPhaseStop::Exhausted
    };
    best.finish(task, c)
}

/// The best plan so far.
struct Best<const N: usize, const K: usize> {
    z: Col,
    f: f64,
    outcome: Option<Outcome<N>>,
    preshape: Option<(Preshape<N>, Demand)>,
    rollouts: u32,
    starts: u32,
    reach_f: f64,
    base_disturbance: f64,
    stop: TwoPhaseStop,
    q0: [f64; N],
}

impl<const N: usize, const K: usize> Best<N, K> {
    const IDLE: Self = Self::new([0.0; N]);

    const fn new(q0: [f64; N]) -> Self {
        Self {
            z: [0.0; MAX_Z],
            f: f64::INFINITY,
            outcome: None,
            preshape: None,
            rollouts: 0,
            starts: 0,
            reach_f: f64::INFINITY,
            base_disturbance: f64::NAN,
            stop: TwoPhaseStop::Exhausted,
            q0,
        }
    }

    /// Records `z`'s rollout if it is the closest yet (one rollout); whether the start
    /// ended where phase 1 needs longer than the longest allowed (the bounds, not the pose,
    /// stopped it).
    fn consider(
        &mut self,
        task: &Task<N, K>,
        phase2: &mut Task<N, K>,
        c: &TwoPhaseConfig,
        z: &Col,
    ) -> bool {
        if self.rollouts >= c.max_rollouts {
            return false;
        }
        self.rollouts = self.rollouts.saturating_add(1);
        let Some(o) = phase2_rollout(task, phase2, z) else {
            return false;
        };
        let score = o.f + o.phi;
        if score < self.f {
            self.f = score;
            self.z = *z;
            self.outcome = Some(o);
        }
        phase1_duration(task, c, &q_of::<N>(z)) > c.max_duration
    }

    /// A converged `z`: fits phase 1 to the wheels' bounds and, if it fits, sets up phase 2
    /// from `z`'s `q_s` on the truth model (counted as a rollout); `None` if it does not fit
    /// or phase 2 cannot start there.
    fn accept(
        &mut self,
        task: &Task<N, K>,
        phase2: &mut Task<N, K>,
        c: &TwoPhaseConfig,
        z: &Col,
    ) -> Result<Option<Fly<N, K>>, Error> {
        let qs = q_of::<N>(z);
        let (preshape, demand, fits) = fit_preshape(task, c, &qs)?;
        if !fits {
            return Ok(None);
        }
        // Phase 2 on the truth model: the plan is accepted only if the base stays put.
        let qc = clamped(task.robot(), &qs);
        self.rollouts = self.rollouts.saturating_add(1);
        if phase2.move_start(&qc).is_err() {
            return Ok(None);
        }
        Ok(Rollout::new(phase2, &to_eta::<K>(z, N))
            .ok()
            .map(|rollout| Fly {
                rollout,
                truth: TruthState::new(TRUTH_SUBSTEPS),
                preshape,
                demand,
            }))
    }

    /// Phase 2 of `z` flown (`fly`, ending in `o`): kept as the converged plan if the base
    /// stayed within the limit on the truth model.
    fn landed(&mut self, c: &TwoPhaseConfig, fly: &Fly<N, K>, o: &Outcome<N>, z: &Col) -> bool {
        let Some(disturbance) = fly.base_disturbance(c) else {
            return false;
        };
        self.base_disturbance = disturbance;
        self.z = *z;
        self.f = o.f;
        self.outcome = Some(*o);
        self.preshape = Some((fly.preshape, fly.demand));
        self.stop = TwoPhaseStop::Converged;
        true
    }

    fn finish(&self, task: &Task<N, K>, c: &TwoPhaseConfig) -> TwoPhasePlan<N, K> {
        let robot = task.robot();
        // The start phase 2 was rolled out from: z's q_s clamped into the limits.
        let qs = clamped(
            robot,
            &if self.outcome.is_some() {
                q_of::<N>(&self.z)
            } else {
                self.q0
            },
        );
        let dt = task.motion().dt();
        // A plan that did not converge: phase 1 to its q_s as a converged one's would be
        // (the wheels' bounds asked, slowed as needed), whether or not it fits.
        let (preshape, demand) = self.preshape.unwrap_or_else(|| {
            fit_preshape(task, c, &qs).map_or_else(
                |_| {
                    let p = Preshape::at_rest(&self.q0, dt);
                    (p, p.demand(robot))
                },
                |(p, d, _)| (p, d),
            )
        });
        TwoPhasePlan {
            q_s: qs,
            eta: to_eta::<K>(&self.z, N),
            preshape,
            demand,
            outcome: self.outcome,
            rollouts: self.rollouts,
            starts: self.starts,
            reach_f: self.reach_f,
            base_disturbance: self.base_disturbance,
            stop: self.stop,
        }
    }
}

/// Phase 1 from the task's start to `qs` (rad): the fastest within the robot's rate limit,
/// `c.qdd_max` and the wheels' bounds by their estimate ([`Preshape::fastest`]), slowed (at
/// most [`STRETCHES`] times, each by the ratio its demand exceeds the bounds by, since
/// `|h_w|` scales as `1/T` and its rate as `1/T²`) until the wheels' demand on its written
/// samples is within `c.max_momentum` and `c.max_torque`; and whether it fits those bounds
/// and `c.max_duration`.
///
/// # Errors
/// As [`Preshape::fastest`].
pub fn fit_preshape<const N: usize, const K: usize>(
    task: &Task<N, K>,
    c: &TwoPhaseConfig,
    qs: &[f64; N],
) -> Result<(Preshape<N>, Demand, bool), Error> {
    let robot = task.robot();
    let dt = task.motion().dt();
    let mut p = Preshape::fastest(robot, task.start(), qs, &limits(robot, c, 1.0), dt)?;
    let mut d = p.demand(robot);
    for _ in 0..STRETCHES {
        let scale = (d.momentum_nms / c.max_momentum).max(libm::sqrt(d.torque_nm / c.max_torque));
        if scale <= 1.0 {
            break;
        }
        let steps = libm::ceil(f64::from(p.steps()) * scale * 1.001) + 1.0;
        p = p.stretched(if steps < f64::from(u32::MAX) {
            steps as u32
        } else {
            u32::MAX
        });
        d = p.demand(robot);
    }
    let fits = d.momentum_nms <= c.max_momentum
        && d.torque_nm <= c.max_torque
        && p.duration() <= c.max_duration;
    Ok((p, d, fits))
}

/// Phase 1's limits from the robot and `c`, the wheels' bounds divided by `margin` (their
/// demand scales as `1/T` and `1/T²`, so the duration grows by `margin`).
fn limits<const N: usize>(robot: &Robot<N>, c: &TwoPhaseConfig, margin: f64) -> PreshapeLimits {
    PreshapeLimits {
        qd_max: robot.qd_max(),
        qdd_max: c.qdd_max,
        max_momentum: c.max_momentum / margin,
        max_torque: c.max_torque / (margin * margin),
    }
}

/// `q` (rad) clamped into the robot's joint limits: the start phase 2 is rolled out from.
fn clamped<const N: usize>(robot: &Robot<N>, q: &[f64; N]) -> [f64; N] {
    let mut q = *q;
    for ((q, lo), hi) in q
        .iter_mut()
        .zip(robot.lower().iter())
        .zip(robot.upper().iter())
    {
        *q = q.max(*lo).min(*hi);
    }
    q
}

/// Phase 2's rollout of `z` (its `q_s` clamped into the limits).
fn phase2_rollout<const N: usize, const K: usize>(
    task: &Task<N, K>,
    phase2: &mut Task<N, K>,
    z: &Col,
) -> Option<Outcome<N>> {
    phase2
        .move_start(&clamped(task.robot(), &q_of::<N>(z)))
        .ok()?;
    phase2.rollout(&to_eta::<K>(z, N), &mut ()).ok()
}

/// Phase 1's duration as the search sees it (s): [`Preshape::estimate`] with the wheels'
/// bounds asked with [`WHEEL_MARGIN`] to spare.
fn phase1_duration<const N: usize, const K: usize>(
    task: &Task<N, K>,
    c: &TwoPhaseConfig,
    qs: &[f64; N],
) -> f64 {
    let robot = task.robot();
    Preshape::estimate(robot, task.start(), qs, &limits(robot, c, WHEEL_MARGIN))
}

/// The residual of `z` and whether it meets the goal (one rollout).
fn evaluate<const N: usize, const K: usize>(
    task: &Task<N, K>,
    phase2: &mut Task<N, K>,
    c: &TwoPhaseConfig,
    z: &Col,
) -> Option<(Res, bool)> {
    let robot = task.robot();
    let qs_raw = q_of::<N>(z);
    let o = phase2_rollout(task, phase2, z)?;
    let mut r = [0.0; MAX_R];
    for (v, e) in r.iter_mut().zip(o.error.to_array().iter()) {
        *v = *e;
    }
    let m = c.margin;
    let limits = robot.lower().iter().zip(robot.upper().iter());
    let extrema = o
        .joint_min
        .iter()
        .zip(o.joint_max.iter())
        .zip(qs_raw.iter());
    for (v, ((lo, hi), ((mn, mx), qs))) in r.iter_mut().skip(6).zip(limits.zip(extrema)) {
        let (mn, mx) = (mn.min(*qs), mx.max(*qs));
        *v = (mx - (hi - m)).max(0.0) + ((lo + m) - mn).max(0.0);
    }
    let start = phase2.start_pose();
    let target = task.target();
    let standoff = standoff_shortfall(start, target, c);
    let t1 = phase1_duration(task, c, &qs_raw);
    let over = (t1 - c.max_duration).max(0.0) / 10.0;
    if let Some(v) = r.get_mut(6 + N) {
        *v = standoff;
    }
    if let Some(v) = r.get_mut(7 + N) {
        *v = over;
    }
    let inside = qs_raw
        .iter()
        .zip(robot.lower().iter().zip(robot.upper().iter()))
        .all(|(q, (lo, hi))| q >= lo && q <= hi);
    let met = o.f <= c.tolerance && o.phi == 0.0 && standoff == 0.0 && over == 0.0 && inside;
    Some((r, met))
}

/// How far the end effector at `start` is inside the standoff (m); 0 when it is far
/// enough in distance or in angle.
fn standoff_shortfall(start: &Pose, target: &Pose, c: &TwoPhaseConfig) -> f64 {
    let e = start.error_to(target);
    let [a, b, d] = e.position;
    let [u, v, w] = e.rotation;
    let distance = libm::sqrt(a * a + b * b + d * d);
    let angle = libm::sqrt(u * u + v * v + w * w);
    if angle >= c.standoff_rad {
        0.0
    } else {
        (c.standoff_m - distance).max(0.0)
    }
}

/// A screening slot's start: `q_s = q₀ + (q_ik − q_S)` (clamped inside the limits by the
/// margin) with direction `x`, where `q_S` ends `x`'s rollout from `q₀` and `q_ik` is the
/// kinematic inverse nearest it (`f` its error), so phase 2 from `q_s` ends near `q_ik`;
/// and the pre-shape's largest joint move `max |q_ik − q_S|` (infinite when the inverse
/// failed).
fn screened<const N: usize, const K: usize>(
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    x: &Col,
    q_end: &[f64; N],
    q_ik: &[f64; N],
    f: f64,
) -> (Col, f64) {
    if f > REACH_TOLERANCE {
        return ([0.0; MAX_Z], f64::INFINITY);
    }
    let robot = task.robot();
    let (lo, hi) = (robot.lower(), robot.upper());
    let q0 = task.start();
    let mut z = [0.0; MAX_Z];
    let mut gap = 0.0f64;
    for (j, zj) in z.iter_mut().enumerate().take(N) {
        let (l, h) = (at(lo, j) + config.margin, at(hi, j) - config.margin);
        let d = at(q_ik, j) - at(q_end, j);
        gap = gap.max(libm::fabs(d));
        *zj = (at(q0, j) + d).max(l).min(h);
    }
    for (zj, xj) in z.iter_mut().skip(N).zip(x.iter()).take(2 * K) {
        *zj = *xj;
    }
    (z, gap)
}

/// Sorts a screening batch by the pre-shape's largest joint move (insertion sort: stable,
/// bounded by [`SCREEN`]²).
fn sort_pool(pool: &mut [(Col, f64); SCREEN]) {
    for i in 1..SCREEN {
        let mut j = i;
        while j > 0 {
            let (Some(a), Some(b)) = (pool.get(j - 1), pool.get(j)) else {
                break;
            };
            if b.1 < a.1 {
                pool.swap(j - 1, j);
                j -= 1;
            } else {
                break;
            }
        }
    }
}

/// The kinematic inverse: a configuration within the limits (by the margin) whose end pose,
/// base attitude held and CoM fixed, is the target; and its `f`. No rollouts.
/// The first attempt starts at `first`, up to `starts − 1` more at random configurations.
pub fn inverse<const N: usize, const K: usize>(
    task: &Task<N, K>,
    margin: f64,
    first: &[f64; N],
    starts: u32,
    stream: &mut Stream,
) -> ([f64; N], f64) {
    if starts == 0 {
        return (*task.start(), f64::INFINITY);
    }
    let mut work = LmWork::ZERO;
    let mut inverse = Inverse::new(task, first, starts);
    let (mut run, mut ask) = inverse.begin(task, margin, stream);
    // Every start ends within IK_MAX_EVALUATIONS, and the starts are at most IK_STARTS.
    loop {
        match ask {
            Ask::Eval => {
                ask = if inverse.count() {
                    run.tell(&mut work, ik_eval(task, margin, run.point()), 0)
                } else {
                    run.stop()
                };
            }
            Ask::Done(_) => {
                if !inverse.end_start(task, run.point()) {
                    return inverse.best;
                }
                (run, ask) = inverse.begin(task, margin, stream);
            }
        }
    }
}

/// A kinematic inverse in progress: its starts, each an LM run over `q` alone.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Inverse<const N: usize> {
    /// The current start, of `starts` (at least 1).
    s: u32,
    /// Evaluations of the current start.
    evaluations: u32,
    starts: u32,
    /// The first start.
    first: [f64; N],
    /// The best configuration so far and its `f`.
    best: ([f64; N], f64),
}

impl<const N: usize> Inverse<N> {
    const IDLE: Self = Self {
        s: 0,
        evaluations: 0,
        starts: 1,
        first: [0.0; N],
        best: ([0.0; N], f64::INFINITY),
    };

    /// An inverse from `first`, then up to `starts − 1` random starts (at least one start,
    /// at most [`IK_STARTS`]).
    fn new<const K: usize>(task: &Task<N, K>, first: &[f64; N], starts: u32) -> Self {
        Self {
            s: 0,
            evaluations: 0,
            starts: starts.clamp(1, IK_STARTS),
            first: *first,
            best: (*task.start(), f64::INFINITY),
        }
    }

    /// The LM run of the current start: `first`, or a uniform configuration within the
    /// limits by the margin (N draws of `stream`).
    fn begin<const K: usize>(
        &mut self,
        task: &Task<N, K>,
        margin: f64,
        stream: &mut Stream,
    ) -> (LmRun, Ask) {
        self.evaluations = 0;
        let robot = task.robot();
        let (lo, hi) = (robot.lower(), robot.upper());
        let mut z = [0.0; MAX_Z];
        for (j, zj) in z.iter_mut().enumerate().take(N) {
            *zj = if self.s == 0 {
                at(&self.first, j)
            } else {
                let (l, h) = (at(lo, j) + margin, at(hi, j) - margin);
                l + (h - l) * stream.uniform()
            };
        }
        let lm = Lm {
            nz: N,
            nr: 6 + N,
            sphere_from: MAX_Z,
            fd_step: 1e-7,
            patience: IK_ITERATIONS,
            broyden: false,
        };
        LmRun::begin(lm, &z, IK_ITERATIONS * (N as u32 + 2))
    }

    /// Counts an evaluation of the current start; whether it is within
    /// [`IK_MAX_EVALUATIONS`].
    fn count(&mut self) -> bool {
        self.evaluations = self.evaluations.saturating_add(1);
        self.evaluations <= IK_MAX_EVALUATIONS
    }

    /// The current start ended at `z`: keeps it if it is the best; whether another start
    /// follows (not after an exact solution, nor after the last start).
    fn end_start<const K: usize>(&mut self, task: &Task<N, K>, z: &Col) -> bool {
        let robot = task.robot();
        let (lo, hi) = (robot.lower(), robot.upper());
        let q = q_of::<N>(z);
        let pose = Frames::new(robot, &q).end_pose(&task.com0(), IDENTITY_WXYZ);
        let inside = q
            .iter()
            .zip(lo.iter().zip(hi.iter()))
            .all(|(q, (l, h))| *q >= *l && *q <= *h);
        let f = if inside {
            pose.error_to(task.target()).norm()
        } else {
            f64::INFINITY
        };
        if f < self.best.1 {
            self.best = (q, f);
        }
        if self.best.1 <= 1e-12 {
            return false;
        }
        self.s += 1;
        self.s < self.starts
    }
}

/// The kinematic inverse's residual at `z` (its first N components a configuration): the
/// end pose's error (base attitude held, CoM fixed) and the joint-limit excess beyond the
/// margin; and whether it is exact (`f ≤ 1e-12`) within the limits. One forward kinematics.
fn ik_eval<const N: usize, const K: usize>(
    task: &Task<N, K>,
    margin: f64,
    z: &Col,
) -> Option<(Res, bool)> {
    let robot = task.robot();
    let (lo, hi) = (robot.lower(), robot.upper());
    let q = q_of::<N>(z);
    let pose = Frames::new(robot, &q).end_pose(&task.com0(), IDENTITY_WXYZ);
    let e = pose.error_to(task.target()).to_array();
    let mut r = [0.0; MAX_R];
    for (v, e) in r.iter_mut().zip(e.iter()) {
        *v = *e;
    }
    for (j, v) in r.iter_mut().skip(6).enumerate().take(N) {
        let (l, h, qj) = (at(lo, j), at(hi, j), at(&q, j));
        *v = (qj - (h - margin)).max(0.0) + ((l + margin) - qj).max(0.0);
    }
    let f = libm::sqrt(e.iter().fold(0.0, |s, v| s + v * v));
    let inside = r.iter().skip(6).all(|v| *v == 0.0);
    Some((r, f <= 1e-12 && inside))
}

/// A Levenberg–Marquardt run's settings (minimum-norm steps, Broyden or full differences).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Lm {
    nz: usize,
    nr: usize,
    /// Components from here on are a direction: renormalised after every accepted step.
    sphere_from: usize,
    fd_step: f64,
    /// Evaluations without `‖r‖` halving before the run ends.
    patience: u32,
    broyden: bool,
}

/// What a running LM asks for next.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Ask {
    /// Evaluate [`LmRun::point`] and tell the run ([`LmRun::tell`]).
    Eval,
    /// The run is over: whether it met the goal, at [`LmRun::point`] (if not, the last
    /// accepted point).
    Done(bool),
}

/// Which evaluation a run waits for.
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::large_enum_variant, reason = "one per search, in place")]
enum Wait {
    /// The start point's.
    First,
    /// Column `c` of the forward-difference Jacobian, at this point.
    Column(usize, Col),
    /// A trial step: the point, the step and its predicted decrease of `‖r‖²`.
    Trial(Col, Col, f64),
    /// None: the run is over.
    Over,
}

/// A Levenberg–Marquardt run as a state machine, one evaluation per [`LmRun::tell`]: from
/// `z0` until an evaluation meets the goal, the run stalls (`‖r‖` has not halved within
/// `patience` counted evaluations, or the damping passes [`LAMBDA_MAX`]) or the count
/// reaches `budget`. Steps solve `(J Jᵀ + μ I) y = −r`, `δ = Jᵀ y`; `λ` as the
/// multistart's (Nielsen). The caller counts the evaluations it wants counted.
#[derive(Debug, Clone, Copy, PartialEq)]
struct LmRun {
    lm: Lm,
    budget: u32,
    z: Col,
    r: Res,
    merit: f64,
    fresh: bool,
    lambda: f64,
    nu: f64,
    rejects: u32,
    ref_merit: f64,
    ref_count: u32,
    wait: Wait,
    /// A Jacobian of this run is in the work (differenced at least once).
    jacobian: bool,
}

impl LmRun {
    const IDLE: Self = Self {
        lm: Lm {
            nz: 0,
            nr: 0,
            sphere_from: MAX_Z,
            fd_step: 1e-7,
            patience: 0,
            broyden: false,
        },
        budget: 0,
        z: [0.0; MAX_Z],
        r: [0.0; MAX_R],
        merit: f64::INFINITY,
        fresh: false,
        lambda: 1e-3,
        nu: 2.0,
        rejects: 0,
        ref_merit: f64::INFINITY,
        ref_count: 0,
        wait: Wait::First,
        jacobian: false,
    };

    /// The point asked for ([`Ask::Eval`]), or where the run ended ([`Ask::Done`]).
    fn point(&self) -> &Col {
        match &self.wait {
            Wait::Column(_, zc) => zc,
            Wait::Trial(trial, _, _) => trial,
            Wait::First | Wait::Over => &self.z,
        }
    }

    /// Whether a Jacobian of this run is in the work ([`LmWork::jac`]).
    fn has_jacobian(&self) -> bool {
        self.jacobian
    }

    /// Ends the run at its last accepted point, without the evaluation it asked for.
    fn stop(&mut self) -> Ask {
        self.done(false)
    }

    /// Ends the run at `z`.
    fn done(&mut self, met: bool) -> Ask {
        self.wait = Wait::Over;
        Ask::Done(met)
    }

    /// A run from `z0`; it asks for `z0` first.
    fn begin(lm: Lm, z0: &Col, budget: u32) -> (Self, Ask) {
        let run = Self {
            lm,
            budget,
            z: *z0,
            ..Self::IDLE
        };
        (run, Ask::Eval)
    }

    /// The evaluation asked for: its residual and whether it meets the goal (`None`: it
    /// failed); `count` after counting it. What the run asks for next.
    fn tell(&mut self, work: &mut LmWork, reply: Option<(Res, bool)>, count: u32) -> Ask {
        match self.wait {
            // Told after it ended (the search never does): it stays over.
            Wait::Over => Ask::Done(false),
            Wait::First => {
                let Some((r, met)) = reply else {
                    return self.done(false);
                };
                if met {
                    return self.done(true);
                }
                self.r = r;
                self.merit = norm2(&r);
                work.jac = [[0.0; MAX_Z]; MAX_R];
                self.ref_merit = self.merit;
                self.ref_count = count;
                self.head(work, count)
            }
            Wait::Column(c, zc) => {
                let Some((rc, met)) = reply else {
                    return self.done(false);
                };
                if met {
                    self.z = zc;
                    return self.done(true);
                }
                for (row, (a, b)) in work.jac.iter_mut().zip(rc.iter().zip(self.r.iter())) {
                    if let Some(v) = row.get_mut(c) {
                        *v = (a - b) / self.lm.fd_step;
                    }
                }
                self.column(work, c + 1, count)
            }
            Wait::Trial(trial, step, predicted) => {
                let Some((rt, met)) = reply else {
                    self.lambda *= self.nu;
                    self.nu *= 2.0;
                    return self.head(work, count);
                };
                if met {
                    self.z = trial;
                    return self.done(true);
                }
                self.judge(work, &trial, &step, predicted, &rt, count);
                self.head(work, count)
            }
        }
    }

    /// The loop's head: the budget and patience tests, then the Jacobian or a step.
    fn head(&mut self, work: &mut LmWork, count: u32) -> Ask {
        if count >= self.budget || count.saturating_sub(self.ref_count) > self.lm.patience {
            return self.done(false);
        }
        if self.fresh {
            self.trial(work, count)
        } else {
            self.column(work, 0, count)
        }
    }

    /// Forward differences, column `c` on; then a step.
    fn column(&mut self, work: &mut LmWork, c: usize, count: u32) -> Ask {
        if c >= self.lm.nz {
            self.fresh = true;
            self.jacobian = true;
            self.rejects = 0;
            return self.trial(work, count);
        }
        if count >= self.budget {
            return self.done(false);
        }
        let mut zc = self.z;
        if let Some(v) = zc.get_mut(c) {
            *v += self.lm.fd_step;
        }
        self.wait = Wait::Column(c, zc);
        Ask::Eval
    }

    /// A trial step from the current Jacobian and damping.
    fn trial(&mut self, work: &mut LmWork, count: u32) -> Ask {
        if self.lambda > LAMBDA_MAX {
            return self.done(false);
        }
        let Some((step, predicted)) =
            self.lm
                .step(&work.jac, &mut work.normal, &self.r, self.lambda)
        else {
            return self.done(false);
        };
        let mut trial = self.z;
        for (t, s) in trial.iter_mut().zip(step.iter()).take(self.lm.nz) {
            *t += s;
        }
        if count >= self.budget {
            return self.done(false);
        }
        self.wait = Wait::Trial(trial, step, predicted);
        Ask::Eval
    }

    /// A trial's residual `rt`: the Broyden update, then the step accepted (damping
    /// lowered) or rejected (raised).
    fn judge(
        &mut self,
        work: &mut LmWork,
        trial: &Col,
        step: &Col,
        predicted: f64,
        rt: &Res,
        count: u32,
    ) {
        let nz = self.lm.nz;
        let mt = norm2(rt);
        if self.lm.broyden {
            let ss = step.iter().take(nz).fold(0.0, |s, v| s + v * v);
            if ss > 0.0 {
                for (row, (a, b)) in work.jac.iter_mut().zip(rt.iter().zip(self.r.iter())) {
                    let js = row
                        .iter()
                        .zip(step.iter())
                        .take(nz)
                        .fold(0.0, |s, (x, y)| s + x * y);
                    let k = ((a - b) - js) / ss;
                    for (j, s) in row.iter_mut().zip(step.iter()).take(nz) {
                        *j += k * s;
                    }
                }
                self.fresh = false;
            }
        }
        if mt < self.merit {
            let rho = if predicted > 0.0 {
                (self.merit - mt) / predicted
            } else {
                0.0
            };
            let t = 2.0 * rho - 1.0;
            self.lambda = (self.lambda * (1.0 - t * t * t).max(1.0 / 3.0)).max(LAMBDA_MIN);
            self.nu = 2.0;
            self.rejects = 0;
            self.z = *trial;
            self.r = *rt;
            self.merit = mt;
            if self.lm.sphere_from < nz {
                // Renormalising leaves r unchanged (η's scale is irrelevant).
                normalise(&mut self.z, self.lm.sphere_from, nz);
            }
            if libm::sqrt(mt) <= 0.5 * libm::sqrt(self.ref_merit) {
                self.ref_merit = mt;
                self.ref_count = count;
            }
            if !self.lm.broyden {
                self.fresh = false;
            }
        } else {
            self.lambda *= self.nu;
            self.nu *= 2.0;
            self.rejects += 1;
            if self.lm.broyden && self.rejects >= 2 {
                self.fresh = false;
                self.rejects = 0;
            }
        }
    }
}

impl Lm {
    /// `δ = Jᵀ y`, `(J Jᵀ + μ I) y = −r`; and the predicted decrease of `‖r‖²`.
    fn step(
        &self,
        jac: &[[f64; MAX_Z]; MAX_R],
        a: &mut [[f64; MAX_R]; MAX_R],
        r: &Res,
        lambda: f64,
    ) -> Option<(Col, f64)> {
        let mut dmax = 0.0f64;
        for c in 0..self.nz {
            let d = jac.iter().take(self.nr).fold(0.0, |s, row| {
                let v = row.get(c).copied().unwrap_or(0.0);
                s + v * v
            });
            dmax = dmax.max(d);
        }
        if !(dmax > 0.0 && dmax.is_finite()) {
            return None;
        }
        let mu = lambda * dmax;
        *a = [[0.0; MAX_R]; MAX_R];
        let mut b = [0.0; MAX_R];
        for (i, (ai, bi)) in a.iter_mut().zip(b.iter_mut()).enumerate() {
            if i >= self.nr {
                *ai.get_mut(i)? = 1.0;
                continue;
            }
            let ji = jac.get(i)?;
            for (k, aik) in ai.iter_mut().enumerate().take(self.nr) {
                let jk = jac.get(k)?;
                *aik = ji
                    .iter()
                    .zip(jk.iter())
                    .take(self.nz)
                    .fold(0.0, |s, (x, y)| s + x * y);
            }
            *ai.get_mut(i)? += mu;
            *bi = -*r.get(i)?;
        }
        let y = solve_spd_in_place(a, &b)?;
        let mut step = [0.0; MAX_Z];
        for (row, yi) in jac.iter().zip(y.iter()).take(self.nr) {
            for (s, j) in step.iter_mut().zip(row.iter()).take(self.nz) {
                *s += j * yi;
            }
        }
        if !step.iter().all(|v| v.is_finite()) {
            return None;
        }
        let mut after = 0.0;
        for (row, ri) in jac.iter().zip(r.iter()).take(self.nr) {
            let v = ri
                + row
                    .iter()
                    .zip(step.iter())
                    .take(self.nz)
                    .fold(0.0, |s, (x, y)| s + x * y);
            after += v * v;
        }
        Some((step, norm2(r) - after))
    }
}

fn norm2(r: &Res) -> f64 {
    r.iter().fold(0.0, |s, v| s + v * v)
}

/// Scales `x[from..to]` to unit length (a zero part stays zero).
fn normalise(x: &mut Col, from: usize, to: usize) {
    let part = x.get_mut(from..to).unwrap_or(&mut []);
    let n = libm::sqrt(part.iter().fold(0.0, |s, v| s + v * v));
    if n > 0.0 {
        for v in part.iter_mut() {
            *v /= n;
        }
    }
}

fn at<const N: usize>(a: &[f64; N], j: usize) -> f64 {
    a.get(j).copied().unwrap_or(0.0)
}

fn q_of<const N: usize>(z: &Col) -> [f64; N] {
    let mut q = [0.0; N];
    for (q, v) in q.iter_mut().zip(z.iter()) {
        *q = *v;
    }
    q
}

fn to_eta<const K: usize>(z: &Col, from: usize) -> [[f64; 2]; K] {
    let mut eta = [[0.0; 2]; K];
    for (i, pair) in eta.iter_mut().enumerate() {
        pair[0] = z.get(from + 2 * i).copied().unwrap_or(0.0);
        pair[1] = z.get(from + 2 * i + 1).copied().unwrap_or(0.0);
    }
    eta
}
