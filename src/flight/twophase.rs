//! Two-phase plans (spec §15): the search chooses the start `q_s` of the reactionless phase
//! together with its η, so that a generic target (one no rollout of the task made) becomes a
//! problem as well posed as inverse kinematics; phase 1 ([`crate::preshape`]) brings the
//! arm from the task's start to `q_s` while the attitude control holds the base.
//!
//! Owns [`TwoPhaseConfig`], [`TwoPhasePlan`], [`TwoPhaseStop`], [`TwoPhaseScratch`] and
//! [`plan`] ([`plan_in`] with the scratch in the caller's static memory).
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
//! Loops are bounded by the rollout budget and constants; nothing allocates. Sizes:
//! `TwoPhasePlan<7, 4>` and the search's scratch, see `tests/sizes.rs`.

use crate::error::{Error, Param};
use crate::geometry::Pose;
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::model::Robot;
use crate::preshape::{Demand, Preshape, PreshapeLimits};
use crate::random::Stream;
use crate::retime::check_positive;
use crate::rollout::Outcome;
use crate::search::refine::solve_spd_in_place;
use crate::task::Task;
use crate::truth::{TRUTH_SUBSTEPS, TruthModel};

/// Largest number of unknowns `N + 2K` (12 joints, K ≤ 9).
pub const MAX_Z: usize = 30;
/// Largest residual length `6 + N + 2`.
pub const MAX_R: usize = 20;
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
}

impl TwoPhaseConfig {
    /// The documented defaults: 2 °/s², 60 s, 20 N m s, 1 N m, 0.2 m or 10°, f ≤ 1e-6,
    /// 8,040 rollouts, 0.005 rad.
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
/// screening pool. Flight software keeps one in static memory ([`plan_in`]) so that
/// nothing task-sized passes through the stack; [`plan`] keeps one on its own stack.
/// Size: `TwoPhaseScratch<7, 4>`, see `tests/sizes.rs`.
pub struct TwoPhaseScratch<const N: usize, const K: usize> {
    phase2: Task<N, K>,
    work: LmWork,
    pool: [(Col, f64); SCREEN],
}

impl<const N: usize, const K: usize> TwoPhaseScratch<N, K> {
    /// Scratch before any search (placeable in a `static`).
    pub const IDLE: Self = Self {
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

/// Plans `task` in two phases with the planner's stream of `seed`, its scratch on the
/// stack (about 12 KB for `N = 7`); [`plan_in`] with scratch the caller keeps.
///
/// # Errors
/// As [`plan_in`].
pub fn plan<const N: usize, const K: usize>(
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    seed: u64,
) -> Result<TwoPhasePlan<N, K>, Error> {
    let mut scratch = TwoPhaseScratch::IDLE;
    plan_in(&mut scratch, task, config, seed)
}

/// Plans `task` in two phases with the planner's stream of `seed`, in `scratch` (any
/// earlier content is overwritten; the result does not depend on it).
///
/// # Errors
/// Bad settings ([`TwoPhaseConfig::validate`]), or a rollout error from the task's own
/// start (a rank-deficient start).
pub fn plan_in<const N: usize, const K: usize>(
    scratch: &mut TwoPhaseScratch<N, K>,
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    seed: u64,
) -> Result<TwoPhasePlan<N, K>, Error> {
    config.validate()?;
    let TwoPhaseScratch { phase2, work, pool } = scratch;
    let mut stream = Stream::new(seed);
    let q0 = *task.start();
    let (_, reach_f) = inverse_in(work, task, config.margin, &q0, IK_STARTS, &mut stream);
    phase2.clone_from(task);
    let mut best = Best::<N, K>::new(q0);
    best.reach_f = reach_f;
    if reach_f > REACH_TOLERANCE {
        best.stop = TwoPhaseStop::BeyondReach;
        return Ok(best.finish(task, config));
    }
    let nz = N + 2 * K;
    let nr = 6 + N + 2;
    let patience = 4 * nz as u32 + 8;
    let mut refused = false;
    let mut refused_starts = 0u32;
    *pool = [([0.0; MAX_Z], f64::INFINITY); SCREEN];
    let mut next = STARTS_PER_SCREEN;
    while best.rollouts < config.max_rollouts {
        if next >= STARTS_PER_SCREEN {
            screen(task, config, work, pool, &mut best.rollouts, &mut stream);
            next = 0;
        }
        let Some((z, gap)) = pool.get(next).copied() else {
            break;
        };
        next += 1;
        if !gap.is_finite() {
            next = STARTS_PER_SCREEN;
            continue;
        }
        best.starts += 1;
        let mut eval = |z: &Col, count: &mut u32| -> Option<(Res, bool)> {
            *count += 1;
            evaluate(task, phase2, config, z)
        };
        let mut lm = Lm {
            nz,
            nr,
            // η is a direction in the paper's family; with a free amplitude its scale is
            // the amplitude and stays as the search leaves it.
            sphere_from: if task.motion().family().free_amplitude() {
                MAX_Z
            } else {
                N
            },
            fd_step: 1e-7,
            patience,
            broyden: true,
        };
        let budget = config.max_rollouts;
        let (found, zf) = lm.run(work, &z, &mut eval, &mut best.rollouts, budget);
        let Some(found) = found else {
            if best.consider(task, phase2, config, &zf) {
                refused_starts += 1;
                refused = true;
                if refused_starts >= REFUSED_STARTS {
                    break;
                }
            }
            continue;
        };
        // Phase 1 within the wheels' bounds, or the next start.
        match best.accept(task, phase2, config, &found) {
            Ok(true) => return Ok(best.finish(task, config)),
            Ok(false) => {
                refused = true;
                refused_starts += 1;
                if refused_starts >= REFUSED_STARTS {
                    break;
                }
            }
            Err(e) => return Err(e),
        }
    }
    best.stop = if refused {
        TwoPhaseStop::PreshapeBounds
    } else {
        TwoPhaseStop::Exhausted
    };
    Ok(best.finish(task, config))
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
    fn new(q0: [f64; N]) -> Self {
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
        self.rollouts += 1;
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

    /// A converged `z`: fits phase 1 to the wheels' bounds; `Ok(true)` if it fits.
    fn accept(
        &mut self,
        task: &Task<N, K>,
        phase2: &mut Task<N, K>,
        c: &TwoPhaseConfig,
        z: &Col,
    ) -> Result<bool, Error> {
        let qs = q_of::<N>(z);
        let (p, d, fits) = fit_preshape(task, c, &qs)?;
        if !fits {
            return Ok(false);
        }
        // Phase 2 on the truth model: the plan is accepted only if the base stays put.
        let qc = clamped(task.robot(), &qs);
        self.rollouts += 1;
        if phase2.move_start(&qc).is_err() {
            return Ok(false);
        }
        let mut truth = TruthModel::new(phase2, TRUTH_SUBSTEPS);
        let o = phase2.rollout(&to_eta::<K>(z, N), &mut truth).ok();
        let disturbance = truth.max_angle();
        if truth.error().is_some() || disturbance.is_nan() || disturbance > c.max_base_disturbance {
            return Ok(false);
        }
        if let Some(o) = o {
            self.base_disturbance = disturbance;
            self.z = *z;
            self.f = o.f;
            self.outcome = Some(o);
            self.preshape = Some((p, d));
            self.stop = TwoPhaseStop::Converged;
            return Ok(true);
        }
        Ok(false)
    }

    fn finish(self, task: &Task<N, K>, c: &TwoPhaseConfig) -> TwoPhasePlan<N, K> {
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

/// A screening batch: [`SCREEN`] directions, each rolled out from `q₀` (one rollout each);
/// its start `q_s = q₀ + (q_ik − q_S)` with `q_ik` the kinematic inverse nearest the end
/// `q_S` of that rollout, so phase 2 from `q_s` ends near `q_ik`; sorted by the pre-shape's
/// largest joint move `max |q_ik − q_S|` (infinite when the inverse fails).
fn screen<const N: usize, const K: usize>(
    task: &Task<N, K>,
    config: &TwoPhaseConfig,
    work: &mut LmWork,
    pool: &mut [(Col, f64); SCREEN],
    rollouts: &mut u32,
    stream: &mut Stream,
) {
    let robot = task.robot();
    let (lo, hi) = (*robot.lower(), *robot.upper());
    let q0 = *task.start();
    for slot in pool.iter_mut() {
        let mut x = [0.0; MAX_Z];
        for v in x.iter_mut().take(2 * K) {
            *v = 2.0 * stream.uniform() - 1.0;
        }
        normalise(&mut x, 2 * K);
        *slot = ([0.0; MAX_Z], f64::INFINITY);
        if *rollouts >= config.max_rollouts {
            continue;
        }
        *rollouts += 1;
        let Ok(o) = task.rollout(&to_eta::<K>(&x, 0), &mut ()) else {
            continue;
        };
        let (q_ik, f) = inverse_in(work, task, config.margin, &o.q_final, 1, stream);
        if f > REACH_TOLERANCE {
            continue;
        }
        let mut z = [0.0; MAX_Z];
        let mut gap = 0.0f64;
        for (j, zj) in z.iter_mut().enumerate().take(N) {
            let (l, h) = (at(&lo, j) + config.margin, at(&hi, j) - config.margin);
            let d = at(&q_ik, j) - at(&o.q_final, j);
            gap = gap.max(libm::fabs(d));
            *zj = (at(&q0, j) + d).max(l).min(h);
        }
        for (zj, xj) in z.iter_mut().skip(N).zip(x.iter()).take(2 * K) {
            *zj = *xj;
        }
        *slot = (z, gap);
    }
    // Insertion sort by gap (stable, bounded by SCREEN²).
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
    let mut work = LmWork::ZERO;
    inverse_in(&mut work, task, margin, first, starts, stream)
}

/// [`inverse`] with the LM's matrices in `work`.
fn inverse_in<const N: usize, const K: usize>(
    work: &mut LmWork,
    task: &Task<N, K>,
    margin: f64,
    first: &[f64; N],
    starts: u32,
    stream: &mut Stream,
) -> ([f64; N], f64) {
    let robot = task.robot();
    let com0 = task.com0();
    let target = *task.target();
    let (lo, hi) = (*robot.lower(), *robot.upper());
    let mut eval = |z: &Col, _: &mut u32| -> Option<(Res, bool)> {
        let q = q_of::<N>(z);
        let pose = Frames::new(robot, &q).end_pose(&com0, IDENTITY_WXYZ);
        let e = pose.error_to(&target).to_array();
        let mut r = [0.0; MAX_R];
        for (v, e) in r.iter_mut().zip(e.iter()) {
            *v = *e;
        }
        for (j, v) in r.iter_mut().skip(6).enumerate().take(N) {
            let (l, h, qj) = (at(&lo, j), at(&hi, j), at(&q, j));
            *v = (qj - (h - margin)).max(0.0) + ((l + margin) - qj).max(0.0);
        }
        let f = libm::sqrt(e.iter().fold(0.0, |s, v| s + v * v));
        let inside = r.iter().skip(6).all(|v| *v == 0.0);
        Some((r, f <= 1e-12 && inside))
    };
    let mut best = (*task.start(), f64::INFINITY);
    for s in 0..starts.min(IK_STARTS) {
        let mut z = [0.0; MAX_Z];
        for (j, zj) in z.iter_mut().enumerate().take(N) {
            *zj = if s == 0 {
                at(first, j)
            } else {
                let (l, h) = (at(&lo, j) + margin, at(&hi, j) - margin);
                l + (h - l) * stream.uniform()
            };
        }
        let mut lm = Lm {
            nz: N,
            nr: 6 + N,
            sphere_from: MAX_Z,
            fd_step: 1e-7,
            patience: IK_ITERATIONS,
            broyden: false,
        };
        let mut count = 0;
        let budget = IK_ITERATIONS * (N as u32 + 2);
        let (found, zf) = lm.run(work, &z, &mut eval, &mut count, budget);
        let zf = found.unwrap_or(zf);
        let q = q_of::<N>(&zf);
        let pose = Frames::new(robot, &q).end_pose(&com0, IDENTITY_WXYZ);
        let inside = q
            .iter()
            .zip(lo.iter().zip(hi.iter()))
            .all(|(q, (l, h))| *q >= *l && *q <= *h);
        let f = if inside {
            pose.error_to(&target).norm()
        } else {
            f64::INFINITY
        };
        if f < best.1 {
            best = (q, f);
        }
        if best.1 <= 1e-12 {
            break;
        }
    }
    best
}

/// A Levenberg–Marquardt run (minimum-norm steps, Broyden or full differences).
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

impl Lm {
    /// Runs from `z0` until an evaluation meets the goal (`Some(z)`), the run stalls or
    /// `count` reaches `budget` (`None`, with the best `z`). `eval` counts into `count`.
    fn run<F: FnMut(&Col, &mut u32) -> Option<(Res, bool)>>(
        &mut self,
        work: &mut LmWork,
        z0: &Col,
        eval: &mut F,
        count: &mut u32,
        budget: u32,
    ) -> (Option<Col>, Col) {
        let mut z = *z0;
        let Some((mut r, met)) = eval(&z, count) else {
            return (None, z);
        };
        if met {
            return (Some(z), z);
        }
        let mut merit = norm2(&r);
        let LmWork { jac, normal } = work;
        *jac = [[0.0; MAX_Z]; MAX_R];
        let mut fresh = false;
        let mut lambda = 1e-3;
        let mut nu = 2.0;
        let mut rejects = 0u32;
        let (mut ref_merit, mut ref_count) = (merit, *count);
        while *count < budget {
            if count.saturating_sub(ref_count) > self.patience {
                break;
            }
            if !fresh {
                // Forward differences, column by column.
                for c in 0..self.nz {
                    if *count >= budget {
                        return (None, z);
                    }
                    let mut zc = z;
                    if let Some(v) = zc.get_mut(c) {
                        *v += self.fd_step;
                    }
                    let Some((rc, met)) = eval(&zc, count) else {
                        return (None, z);
                    };
                    if met {
                        return (Some(zc), zc);
                    }
                    for (row, (a, b)) in jac.iter_mut().zip(rc.iter().zip(r.iter())) {
                        if let Some(v) = row.get_mut(c) {
                            *v = (a - b) / self.fd_step;
                        }
                    }
                }
                fresh = true;
                rejects = 0;
            }
            if lambda > LAMBDA_MAX {
                return (None, z);
            }
            let Some((step, predicted)) = self.step(jac, normal, &r, lambda) else {
                return (None, z);
            };
            let mut trial = z;
            for (t, s) in trial.iter_mut().zip(step.iter()).take(self.nz) {
                *t += s;
            }
            if *count >= budget {
                break;
            }
            let Some((rt, met)) = eval(&trial, count) else {
                lambda *= nu;
                nu *= 2.0;
                continue;
            };
            if met {
                return (Some(trial), trial);
            }
            let mt = norm2(&rt);
            if self.broyden {
                let ss = step.iter().take(self.nz).fold(0.0, |s, v| s + v * v);
                if ss > 0.0 {
                    for (row, (a, b)) in jac.iter_mut().zip(rt.iter().zip(r.iter())) {
                        let js = row
                            .iter()
                            .zip(step.iter())
                            .take(self.nz)
                            .fold(0.0, |s, (x, y)| s + x * y);
                        let k = ((a - b) - js) / ss;
                        for (j, s) in row.iter_mut().zip(step.iter()).take(self.nz) {
                            *j += k * s;
                        }
                    }
                    fresh = false;
                }
            }
            if mt < merit {
                let rho = if predicted > 0.0 {
                    (merit - mt) / predicted
                } else {
                    0.0
                };
                let t = 2.0 * rho - 1.0;
                lambda = (lambda * (1.0 - t * t * t).max(1.0 / 3.0)).max(LAMBDA_MIN);
                nu = 2.0;
                rejects = 0;
                z = trial;
                r = rt;
                merit = mt;
                if self.sphere_from < self.nz {
                    let tail = z.get_mut(self.sphere_from..self.nz).unwrap_or(&mut []);
                    let n = libm::sqrt(tail.iter().fold(0.0, |s, v| s + v * v));
                    if n > 0.0 {
                        for v in tail.iter_mut() {
                            *v /= n;
                        }
                    }
                    // Renormalising leaves r unchanged (η's scale is irrelevant).
                }
                if libm::sqrt(mt) <= 0.5 * libm::sqrt(ref_merit) {
                    ref_merit = mt;
                    ref_count = *count;
                }
                if !self.broyden {
                    fresh = false;
                }
            } else {
                lambda *= nu;
                nu *= 2.0;
                rejects += 1;
                if self.broyden && rejects >= 2 {
                    fresh = false;
                    rejects = 0;
                }
            }
        }
        (None, z)
    }

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

fn normalise(x: &mut Col, n: usize) {
    let s = libm::sqrt(x.iter().take(n).fold(0.0, |s, v| s + v * v));
    if s > 0.0 {
        for v in x.iter_mut().take(n) {
            *v /= s;
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
