//! The default search strategy: multistart Levenberg–Marquardt on the unit sphere of η.
//!
//! Owns [`LmConfig`], [`Multistart`] and [`MultistartReport`]. Like [`crate::refine`] it is
//! an [`Optimizer`] that never runs a rollout: the planner evaluates each candidate
//! (honouring its violation cap) and hands the evaluation back.
//!
//! **Unknowns.** Only η's direction matters, so the iterate `x` is a unit vector of
//! `ℝ^{2K}` and the search runs in the `2K − 1` dimensional tangent space at `x`, spanned by
//! the Householder basis `u_c` (the columns of `I − v vᵀ/(1 + |x_p|)`, `v = x + sgn(x_p)e_p`,
//! `p = argmax |x_i|`, column `p` left out). A tangent step `δ` becomes the ambient step
//! `s = Σ δ_c u_c` and the new iterate `(x + s)/‖x + s‖`.
//!
//! **Free amplitude** ([`LmConfig::free_amplitude`], for [`Family::FreeAmplitude`](crate::Family::FreeAmplitude)): η's
//! magnitude is the motion's amplitude (linear in η below the rate bound), so the iterate
//! is any point of `ℝ^{2K}`, the search runs along the `2K` axes `u_c = e_c`, and a trial is
//! `x + s` as it is. Screening draws the same points of the unit sphere.
//!
//! **Segments** ([`LmConfig::segments`], a free-amplitude motion of several segments,
//! [`crate::Motion::with_segments`]): the iterate is the segments' η side by side
//! (`2K·segments ≤` [`MAX_DIM`] ambient unknowns, searched as the free amplitude's), and a
//! screening point puts each segment's `2K` components on its own unit sphere. One segment
//! is the search above, bit for bit.
//!
//! **Residual.** `r = [e; w·p]` (`6 + N` rows, `7 + N` with collision geometry): the pose error `e` of spec §6 and, per joint
//! `j`, `p_j = max(0, q_max,j − (hi_j − m)) + max(0, (lo_j + m) − q_min,j)`, the joint-limit
//! excess beyond a margin `m` inside the limits ([`LmConfig::penalty_weight`] `w`,
//! [`LmConfig::margin`] `m`). With collision geometry ([`crate::Task::with_collision`])
//! one more row, `w·max(0, c_lim − c)`: the path's clearance bound `c`
//! ([`crate::Outcome::clearance`]) below the required clearance plus the set's margin
//! `c_lim` ([`crate::clearance::CollisionSet::limit`]). With `w = 0` the rows are left out
//! and a trial with `Φ > 0` is rejected instead.
//!
//! **One LM start.**
//! 1. Jacobian of `r` along the `2K − 1` tangent directions by forward differences
//!    (`h` = [`LmConfig::fd_step`]), kept as an ambient matrix `J` (`J x = 0`).
//! 2. Step `(J_tᵀJ_t + λ·d_max·I) δ = −J_tᵀ r`, `J_t = J U`, `d_max` = the largest diagonal
//!    entry of `J_tᵀJ_t`; `λ` starts at [`LmConfig::lambda0`].
//! 3. One trial rollout at the new iterate. Accepted iff `‖r‖²` decreases; then
//!    `λ ← λ·max(1/3, 1 − (2ρ − 1)³)` (Nielsen; `ρ` = actual / predicted decrease), else
//!    `λ ← λ·ν, ν ← 2ν`.
//! 4. With [`LmConfig::broyden`], every trial (accepted or not) corrects `J` by the rank-1
//!    Broyden update `J ← J + (Δr − J s) sᵀ/(sᵀs)`, and the next trial follows from the
//!    corrected `J` without new differences; with [`LmConfig::refresh`] each iteration also
//!    re-differences one tangent direction (cycling), a rank-1 update too. A full rebuild
//!    (step 1) happens after [`LmConfig::rebuild_after`] consecutive rejections on a
//!    corrected `J`, or when the step cannot be computed. Without Broyden every accepted
//!    step is followed by a full rebuild.
//!
//! **Restarts.** A start is dropped when `‖r‖` has not fallen below
//! [`LmConfig::shrink`] times its value at the last checkpoint within `patience` rollouts
//! (the checkpoint moves every time it does; [`LmConfig::patience`] while `‖r‖ > σ_e`,
//! [`LmConfig::refine_patience`] after), or when `λ` exceeds `1e10`, or the step is
//! below `1e-15`, on a freshly built `J`. Starts come from screening batches: a batch draws
//! [`LmConfig::screen`] directions and evaluates them, and the best
//! [`LmConfig::starts_per_screen`] of them (smallest `‖r‖`, in order) are started one after
//! the other; then a new batch is drawn.
//!
//! **Randomness.** Only the screening batches draw: `2K·segments` uniforms per candidate
//! (`2u − 1`, components in the order a₁, b₁, …, a_K, b_K of each segment in turn),
//! candidates in order, a batch
//! when it starts (the first one in [`Multistart::new`]). Nothing else is random, so the
//! same seed and the same outcomes give the same bits.
//!
//! **Termination.** Done when an evaluated rollout (any kind: screening, difference,
//! trial) has `Φ = 0` and `f ≤ tolerance` (converged, and that η is [`Multistart::best`]),
//! or when [`LmConfig::max_rollouts`] rollouts have been told (not converged; the best
//! feasible rollout so far, or the least violating). Every `tell` counts one rollout, so the
//! work is bounded by `max_rollouts` rollouts plus `O((2K)³)` arithmetic per `tell`.
//! The first rollout with `Φ = 0` and `f ≤ σ_e` is recorded ([`MultistartReport::first_hit`])
//! so one run can be measured against both σ_e and a refinement tolerance.

use crate::clearance::CollisionSet;
use crate::config::{PlannerConfig, RefineAgainst};
use crate::error::NeedsOneSegment;
use crate::error::{Error, Param};
use crate::model::Robot;
use crate::optimizer::{Candidate, Evaluation, Next, Observer, Optimizer, Stop};
use crate::optimizer::{Method, SearchReport};
use crate::random::Stream;
use crate::refine::solve_spd_in_place;
use crate::rollout::Outcome;
use crate::task::Task;
use crate::trajectory::{Eta, Motion, one_segment};

/// Below this `f` (m and rad, as σ_e) a start that stalls is handed to the refinement
/// against the truth model instead of being restarted, when the planner refines against
/// the truth model: the planner model's own floor on a target the truth model made
/// (measured `1e-5…5e-5`), not a local minimum (measured `3e-3…2e-2`). See
/// [`LmConfig::floor`].
pub const TRUTH_HANDOVER_FLOOR: f64 = 1e-3;

/// Starts stalled below σ_e after which a search with fewer unknowns than pose equations
/// (6 joints) refining against the planner model stops at its floor
/// ([`LmConfig::floor_starts`]).
pub const FLOOR_STARTS: u32 = 3;

/// Largest number of unknowns `2K·segments`: `2K ≤ 18` (K ≤ 9 for N ≤ 12), and four
/// segments of a 7-joint arm (K = 4).
pub const MAX_DIM: usize = 32;
/// Largest residual length `6 + N`.
pub const MAX_ROWS: usize = 19;
/// Largest screening batch.
pub const MAX_SCREEN: usize = 16;
/// Damping at which a start counts as stalled.
const LAMBDA_MAX: f64 = 1e10;
/// Smallest damping.
const LAMBDA_MIN: f64 = 1e-15;
/// Tangent steps below this norm count as stalled.
const STEP_MIN: f64 = 1e-15;

/// Settings of the multistart LM.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LmConfig {
    /// Total rollout budget (≥ 1).
    pub max_rollouts: u32,
    /// σ_e: the first feasible rollout with `f ≤ sigma_e` is recorded.
    pub sigma_e: f64,
    /// Directions per screening batch (`1..=MAX_SCREEN`).
    pub screen: u32,
    /// LM starts taken from each batch (`1..=screen`).
    pub starts_per_screen: u32,
    /// Rank-1 Broyden corrections between full difference Jacobians.
    pub broyden: bool,
    /// With Broyden: re-difference one tangent direction per iteration.
    pub refresh: bool,
    /// With Broyden: consecutive rejected trials before a full rebuild (≥ 1).
    pub rebuild_after: u32,
    /// Weight `w` of the joint-limit rows (0: no rows; violating trials are rejected).
    pub penalty_weight: f64,
    /// Margin `m` inside the limits where the rows start (rad, ≥ 0).
    pub margin: f64,
    /// Initial damping, relative to the largest diagonal entry of `J_tᵀJ_t`.
    pub lambda0: f64,
    /// Rollouts without progress before a start is dropped while its `‖r‖ > σ_e`
    /// (0: `2(2K − 1) + 8`).
    pub patience: u32,
    /// The same once the start has reached `‖r‖ ≤ σ_e` (0: `4(2K − 1) + 8`): a start near a
    /// solution gets longer to refine.
    pub refine_patience: u32,
    /// Progress means `‖r‖` falls below `shrink` times its checkpoint value (`0 < shrink < 1`).
    pub shrink: f64,
    /// Search η's magnitude too ([`crate::Family::FreeAmplitude`]): `2K` ambient unknowns
    /// instead of `2K − 1` on the sphere (module docs).
    pub free_amplitude: bool,
    /// Segments of the motion ([`crate::Motion::with_segments`], with the free amplitude):
    /// the iterate holds each segment's `2K` components in turn, `2K·segments ≤`
    /// [`MAX_DIM`] unknowns.
    pub segments: u32,
    /// Forward-difference step on the unit sphere.
    pub fd_step: f64,
    /// Stop (instead of restarting) when a start that has reached `‖r‖ ≤ σ_e` runs out of
    /// patience at `‖r‖ ≤ floor`: its floor is as far as the planner model gets, and a later
    /// stage (the refinement against the truth model) takes it from there. `0` never stops
    /// early. A start that stalls above `floor` (a local minimum, not the planner model's
    /// mismatch with the truth model) is restarted as usual. Measured: the mismatch floors
    /// of truth-made targets are `1e-5…5e-5` (`examples/floor.rs`), the local minima that
    /// the truth refinement cannot leave `3e-3…2e-2`.
    pub floor: f64,
    /// Stop (instead of restarting) once this many starts have stalled at `‖r‖ ≤ σ_e`
    /// without reaching the tolerance (0: never). With fewer unknowns than pose equations
    /// (`2K − 1 < 6`: 6 joints) a target that the planner model does not reach exactly
    /// (one the truth model made) has a floor every start stalls at; more starts cannot
    /// get below it, so the search ends [`Stop::Stalled`] at its best instead of spending
    /// the whole budget.
    pub floor_starts: u32,
}

impl LmConfig {
    /// The settings measured in issue #11.
    #[must_use]
    pub const fn reference() -> Self {
        Self {
            max_rollouts: 8040,
            sigma_e: 0.05,
            screen: 8,
            starts_per_screen: 2,
            broyden: true,
            refresh: false,
            rebuild_after: 2,
            penalty_weight: 1.0,
            margin: 0.005,
            lambda0: 1e-3,
            patience: 0,
            refine_patience: 0,
            shrink: 0.5,
            fd_step: 1e-7,
            floor: 0.0,
            floor_starts: 0,
            free_amplitude: false,
            segments: 1,
        }
    }

    /// Checks the settings.
    ///
    /// # Errors
    /// The first bad setting.
    pub fn validate(&self) -> Result<(), Error> {
        if self.max_rollouts == 0 {
            return Err(Error::NotPositive(Param::RefineRollouts));
        }
        let positive = [self.sigma_e, self.lambda0, self.fd_step, self.shrink];
        if positive.iter().any(|v| !(v.is_finite() && *v > 0.0)) || self.shrink >= 1.0 {
            return Err(Error::NotPositive(Param::RefineTolerance));
        }
        let non_negative = [self.penalty_weight, self.margin];
        if non_negative.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
            return Err(Error::NotPositive(Param::RefineTolerance));
        }
        if self.segments == 0 {
            return Err(Error::NotPositive(Param::Segments));
        }
        if self.segments > 1 && !self.free_amplitude {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::PaperFamily));
        }
        if self.screen == 0
            || self.screen as usize > MAX_SCREEN
            || self.starts_per_screen == 0
            || self.starts_per_screen > self.screen
            || self.rebuild_after == 0
        {
            return Err(Error::NotPositive(Param::RefineRollouts));
        }
        Ok(())
    }
}

/// What the multistart did so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct MultistartReport {
    /// Rollouts told.
    pub rollouts: u32,
    /// LM starts begun.
    pub starts: u32,
    /// Screening batches drawn.
    pub screens: u32,
    /// Full difference Jacobians completed.
    pub jacobians: u32,
    /// Accepted LM steps.
    pub accepted: u32,
    /// Rollout count at the first feasible rollout with `f ≤ σ_e`.
    pub first_hit: Option<u32>,
    /// A feasible rollout with `f ≤ tolerance` was evaluated.
    pub converged: bool,
    /// Stopped at a start's floor below σ_e ([`LmConfig::floor`]).
    pub floor: bool,
    /// Starts that stalled at `‖r‖ ≤ σ_e` without reaching the tolerance.
    pub floored: u32,
    /// Stopped after [`LmConfig::floor_starts`] such starts.
    pub stalled: bool,
}

impl MultistartReport {
    /// Nothing done yet.
    pub const NONE: Self = Self {
        rollouts: 0,
        starts: 0,
        screens: 0,
        jacobians: 0,
        accepted: 0,
        first_hit: None,
        converged: false,
        floor: false,
        floored: 0,
        stalled: false,
    };
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Evaluating screening candidate `i`.
    Screen(usize),
    /// Full Jacobian, tangent direction `c`.
    Column(usize),
    /// One re-differenced tangent direction `c`.
    Refresh(usize),
    /// The trial point.
    Trial,
    /// Finished.
    Done,
}

type Col = [f64; MAX_DIM];
type Res = [f64; MAX_ROWS];

/// The multistart state (fixed size).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Multistart<const N: usize, const K: usize> {
    config: LmConfig,
    tolerance: f64,
    patience: u32,
    refine_patience: u32,
    lower: [f64; N],
    upper: [f64; N],
    /// With collision geometry: the required clearance plus the margin (m), where the
    /// clearance row starts.
    clearance_limit: Option<f64>,
    phase: Phase,
    pool: [Col; MAX_SCREEN],
    pool_r: [Res; MAX_SCREEN],
    pool_merit: [f64; MAX_SCREEN],
    pool_used: [bool; MAX_SCREEN],
    pool_starts: u32,
    x: Col,
    r: Res,
    merit: f64,
    jac: [Col; MAX_ROWS],
    stale: u32,
    lambda: f64,
    nu: f64,
    rejects: u32,
    cursor: usize,
    trial: Col,
    step: Col,
    pred: f64,
    ref_merit: f64,
    ref_rollout: u32,
    report: MultistartReport,
    /// A start is running (its end is counted in [`MultistartReport::floored`]).
    live: bool,
    best_eta: Eta<K>,
    best: Option<Outcome<N>>,
    /// Scratch of each step's solve (not state: rebuilt every time): `J_t = J U`.
    jt: [Col; MAX_ROWS],
    /// Scratch: `J_tᵀJ_t + λ d_max I`, then its Cholesky factor.
    a: [Col; MAX_DIM],
}

impl<const N: usize, const K: usize> Multistart<N, K> {
    const FITS: () = assert!(2 * K <= MAX_DIM && 7 + N <= MAX_ROWS && K >= 1);

    /// No search (a placeholder, `const`, for statically allocated planners).
    pub const IDLE: Self = Self {
        config: LmConfig::reference(),
        tolerance: 0.05,
        patience: 0,
        refine_patience: 0,
        lower: [0.0; N],
        upper: [0.0; N],
        clearance_limit: None,
        phase: Phase::Done,
        pool: [[0.0; MAX_DIM]; MAX_SCREEN],
        pool_r: [[0.0; MAX_ROWS]; MAX_SCREEN],
        pool_merit: [f64::INFINITY; MAX_SCREEN],
        pool_used: [false; MAX_SCREEN],
        pool_starts: 0,
        x: [0.0; MAX_DIM],
        r: [0.0; MAX_ROWS],
        merit: f64::INFINITY,
        jac: [[0.0; MAX_DIM]; MAX_ROWS],
        stale: 0,
        lambda: 1e-3,
        nu: 2.0,
        rejects: 0,
        cursor: 0,
        trial: [0.0; MAX_DIM],
        step: [0.0; MAX_DIM],
        pred: 0.0,
        ref_merit: f64::INFINITY,
        ref_rollout: 0,
        report: MultistartReport::NONE,
        live: false,
        best_eta: one_segment([[0.0; 2]; K]),
        best: None,
        jt: [[0.0; MAX_DIM]; MAX_ROWS],
        a: [[0.0; MAX_DIM]; MAX_DIM],
    };

    /// Starts a search with the limits of `robot`, stopping at `f ≤ tolerance` (> 0); draws
    /// the first screening batch from `stream`.
    ///
    /// # Errors
    /// A bad setting or tolerance.
    pub fn new(
        config: &LmConfig,
        robot: &Robot<N>,
        tolerance: f64,
        stream: &mut Stream,
    ) -> Result<Self, Error> {
        let mut s = Self::IDLE;
        s.reset(config, robot, tolerance, stream)?;
        Ok(s)
    }

    /// [`Multistart::new`] in place (no search-sized temporaries: flight software keeps the
    /// planner in static memory).
    ///
    /// # Errors
    /// As [`Multistart::new`]; the search is then finished with nothing found.
    pub fn reset(
        &mut self,
        config: &LmConfig,
        robot: &Robot<N>,
        tolerance: f64,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        let () = Self::FITS;
        self.phase = Phase::Done;
        config.validate()?;
        if !(tolerance.is_finite() && tolerance > 0.0) {
            return Err(Error::NotPositive(Param::Tolerance));
        }
        let ambient = 2 * K * config.segments as usize;
        if ambient > MAX_DIM {
            return Err(Error::CapacityExceeded {
                param: Param::Segments,
                requested: config.segments,
                capacity: (MAX_DIM / (2 * K)) as u32,
            });
        }
        let tangent = Self::unknowns(config.free_amplitude, config.segments) as u32;
        self.patience = if config.patience == 0 {
            2 * tangent + 8
        } else {
            config.patience
        };
        self.refine_patience = if config.refine_patience == 0 {
            4 * tangent + 8
        } else {
            config.refine_patience
        };
        self.config = *config;
        self.tolerance = tolerance;
        self.lower = *robot.lower();
        self.upper = *robot.upper();
        self.clearance_limit = None;
        for p in &mut self.pool {
            *p = [0.0; MAX_DIM];
        }
        for r in &mut self.pool_r {
            *r = [0.0; MAX_ROWS];
        }
        self.pool_merit = [f64::INFINITY; MAX_SCREEN];
        self.pool_used = [false; MAX_SCREEN];
        self.pool_starts = 0;
        self.x = [0.0; MAX_DIM];
        self.r = [0.0; MAX_ROWS];
        self.merit = f64::INFINITY;
        for row in &mut self.jac {
            *row = [0.0; MAX_DIM];
        }
        self.stale = 0;
        self.lambda = config.lambda0;
        self.nu = 2.0;
        self.rejects = 0;
        self.cursor = 0;
        self.trial = [0.0; MAX_DIM];
        self.step = [0.0; MAX_DIM];
        self.pred = 0.0;
        self.ref_merit = f64::INFINITY;
        self.ref_rollout = 0;
        self.report = MultistartReport::NONE;
        self.live = false;
        self.best_eta = one_segment([[0.0; 2]; K]);
        self.best = None;
        self.draw_batch(stream);
        Ok(())
    }

    /// The next η to evaluate and its violation cap (`∞`: evaluate to the end). Once
    /// finished it returns the best η.
    #[must_use]
    fn ask(&self) -> (Eta<K>, f64) {
        let cap = f64::INFINITY;
        match self.phase {
            Phase::Screen(i) => (to_eta(self.pool.get(i).unwrap_or(&self.x)), cap),
            Phase::Column(c) | Phase::Refresh(c) => (to_eta(&self.column_point(c)), cap),
            Phase::Trial => (to_eta(&self.trial), self.trial_cap()),
            Phase::Done => (self.best_eta, cap),
        }
    }

    /// The violation cap of a trial: without penalty rows a violating trial is rejected
    /// anyway (cap 0); with them, `Φ > √N‖r‖/w` implies `‖r_trial‖ > ‖r‖` (rejected).
    fn trial_cap(&self) -> f64 {
        let w = self.config.penalty_weight;
        let rows = N + usize::from(self.clearance_limit.is_some());
        if w == 0.0 {
            0.0
        } else {
            libm::sqrt(rows as f64 * self.merit) / w * (1.0 + 1e-9)
        }
    }

    /// Takes the outcome of the last asked η (`None`: the rollout failed or was abandoned at
    /// its violation cap). Draws from `stream` only when a new screening batch starts.
    /// `false` once finished.
    fn tell(&mut self, result: Option<&Outcome<N>>, stream: &mut Stream) -> bool {
        if self.phase == Phase::Done {
            return false;
        }
        self.report.rollouts = self.report.rollouts.saturating_add(1);
        if let Some(o) = result {
            let (eta, _) = self.ask();
            self.observe(&eta, o);
            if self.report.converged {
                self.phase = Phase::Done;
                return false;
            }
        }
        let valid = result.filter(|o| self.config.penalty_weight > 0.0 || o.phi == 0.0);
        match self.phase {
            Phase::Screen(i) => {
                let (res, m) = match valid {
                    Some(o) => {
                        let res = self.residual(o);
                        (res, norm2(&res))
                    }
                    None => ([0.0; MAX_ROWS], f64::INFINITY),
                };
                if let Some(slot) = self.pool_r.get_mut(i) {
                    *slot = res;
                }
                if let Some(slot) = self.pool_merit.get_mut(i) {
                    *slot = if m.is_finite() { m } else { f64::INFINITY };
                }
                if i + 1 < self.config.screen as usize {
                    self.phase = Phase::Screen(i + 1);
                } else {
                    self.start_next(stream);
                }
            }
            Phase::Column(c) => {
                if c == 0 {
                    self.jac = [[0.0; MAX_DIM]; MAX_ROWS];
                }
                self.difference(c, result);
                if c + 1 < self.dims() {
                    self.phase = Phase::Column(c + 1);
                } else {
                    self.report.jacobians += 1;
                    self.stale = 0;
                    self.rejects = 0;
                    self.plan_trial(stream);
                }
            }
            Phase::Refresh(c) => {
                self.difference(c, result);
                self.stale += 1;
                self.plan_trial(stream);
            }
            Phase::Trial => self.judge(valid, stream),
            Phase::Done => {}
        }
        if self.phase != Phase::Done && self.report.rollouts >= self.config.max_rollouts {
            self.phase = Phase::Done;
        }
        self.phase != Phase::Done
    }

    /// The best rollout so far (feasible with the smallest f, else the least violating).
    #[must_use]
    pub fn best(&self) -> Option<(&Eta<K>, &Outcome<N>)> {
        self.best.as_ref().map(|o| (&self.best_eta, o))
    }

    /// Counters and events so far.
    #[must_use]
    pub fn report(&self) -> MultistartReport {
        self.report
    }

    /// `true` once finished.
    #[must_use]
    pub fn done(&self) -> bool {
        self.phase == Phase::Done
    }

    /// Best-so-far bookkeeping, σ_e first hit and convergence for one evaluated rollout.
    fn observe(&mut self, eta: &Eta<K>, o: &Outcome<N>) {
        let feasible = o.phi == 0.0;
        if feasible && o.f <= self.config.sigma_e && self.report.first_hit.is_none() {
            self.report.first_hit = Some(self.report.rollouts);
        }
        let better = match &self.best {
            None => true,
            Some(b) => match (feasible, b.phi == 0.0) {
                (true, true) => o.f < b.f,
                (true, false) => true,
                (false, true) => false,
                (false, false) => o.phi < b.phi,
            },
        };
        if better && o.f.is_finite() {
            self.best = Some(*o);
            self.best_eta = *eta;
        }
        if feasible && o.f <= self.tolerance {
            self.report.converged = true;
        }
    }

    /// `r = [e; w·p]`.
    fn residual(&self, o: &Outcome<N>) -> Res {
        let mut r = [0.0; MAX_ROWS];
        for (v, e) in r.iter_mut().zip(o.error.to_array().iter()) {
            *v = *e;
        }
        let (w, m) = (self.config.penalty_weight, self.config.margin);
        if w > 0.0 {
            let limits = self.lower.iter().zip(self.upper.iter());
            let extrema = o.joint_min.iter().zip(o.joint_max.iter());
            for (v, ((lo, hi), (mn, mx))) in r.iter_mut().skip(6).zip(limits.zip(extrema)) {
                *v = w * ((mx - (hi - m)).max(0.0) + ((lo + m) - mn).max(0.0));
            }
            if let (Some(limit), Some(v)) = (self.clearance_limit, r.get_mut(6 + N)) {
                *v = w * (limit - o.clearance).max(0.0);
            }
        }
        r
    }

    /// The draws of one screening batch (normalised directions); phase → `Screen(0)`.
    fn draw_batch(&mut self, stream: &mut Stream) {
        let d = 2 * K;
        let segments = self.config.segments as usize;
        for (p, used) in self
            .pool
            .iter_mut()
            .zip(self.pool_used.iter_mut())
            .take(self.config.screen as usize)
        {
            *p = [0.0; MAX_DIM];
            for v in p.iter_mut().take(d * segments) {
                *v = 2.0 * stream.uniform() - 1.0;
            }
            // Each segment's components on its unit sphere (one segment: the whole point).
            for block in p.chunks_exact_mut(d).take(segments) {
                normalise(block);
            }
            *used = false;
        }
        self.pool_merit = [f64::INFINITY; MAX_SCREEN];
        self.pool_starts = 0;
        self.report.screens += 1;
        self.phase = Phase::Screen(0);
    }

    /// Begins the next LM start from the current batch, or draws a new batch.
    fn start_next(&mut self, stream: &mut Stream) {
        let floor = self.config.floor;
        if self.report.first_hit.is_some() && self.merit <= floor * floor {
            self.report.floor = true;
            self.phase = Phase::Done;
            return;
        }
        if self.live {
            // The start just dropped: did it stall below σ_e?
            self.live = false;
            let sigma = self.config.sigma_e;
            if self.merit <= sigma * sigma {
                self.report.floored += 1;
                if self.config.floor_starts > 0 && self.report.floored >= self.config.floor_starts {
                    self.report.stalled = true;
                    self.phase = Phase::Done;
                    return;
                }
            }
        }
        let mut pick: Option<usize> = None;
        if self.pool_starts < self.config.starts_per_screen {
            let mut best = f64::INFINITY;
            for (i, (m, used)) in self
                .pool_merit
                .iter()
                .zip(self.pool_used.iter())
                .take(self.config.screen as usize)
                .enumerate()
            {
                if !used && *m < best {
                    best = *m;
                    pick = Some(i);
                }
            }
        }
        let Some(i) = pick else {
            self.draw_batch(stream);
            return;
        };
        if let Some(u) = self.pool_used.get_mut(i) {
            *u = true;
        }
        self.pool_starts += 1;
        self.report.starts += 1;
        self.live = true;
        self.x = self.pool.get(i).copied().unwrap_or([0.0; MAX_DIM]);
        self.r = self.pool_r.get(i).copied().unwrap_or([0.0; MAX_ROWS]);
        self.merit = self.pool_merit.get(i).copied().unwrap_or(f64::INFINITY);
        self.lambda = self.config.lambda0;
        self.nu = 2.0;
        self.rejects = 0;
        self.cursor = 0;
        self.stale = 0;
        self.ref_merit = self.merit;
        self.ref_rollout = self.report.rollouts;
        self.phase = Phase::Column(0);
    }

    /// Search directions: `2K − 1` on the sphere, `2K` with a free amplitude.
    const fn unknowns(free_amplitude: bool, segments: u32) -> usize {
        2 * K * segments as usize - if free_amplitude { 0 } else { 1 }
    }

    /// [`Self::unknowns`] of this search.
    fn dims(&self) -> usize {
        Self::unknowns(self.config.free_amplitude, self.config.segments)
    }

    /// The point that differences direction `c`: `x + h·u_c`.
    fn column_point(&self, c: usize) -> Col {
        let u = self.tangent(c);
        let mut p = self.x;
        for (v, d) in p.iter_mut().zip(u.iter()) {
            *v += self.config.fd_step * d;
        }
        p
    }

    /// Tangent direction `c` (`0..2K−1`) at `x`: column `c'` of the Householder matrix, `c'`
    /// skipping the pivot.
    fn tangent(&self, c: usize) -> Col {
        let d = 2 * K;
        if self.config.free_amplitude {
            let mut e = [0.0; MAX_DIM];
            if let Some(v) = e.get_mut(c) {
                *v = 1.0;
            }
            return e;
        }
        let mut p = 0;
        let mut big = -1.0;
        for (i, v) in self.x.iter().take(d).enumerate() {
            if libm::fabs(*v) > big {
                big = libm::fabs(*v);
                p = i;
            }
        }
        let xp = self.x.get(p).copied().unwrap_or(1.0);
        let mut v = self.x;
        if let Some(vp) = v.get_mut(p) {
            *vp += libm::copysign(1.0, xp);
        }
        let col = if c < p { c } else { c + 1 };
        let vc = v.get(col).copied().unwrap_or(0.0);
        let scale = vc / (1.0 + libm::fabs(xp));
        let mut u = [0.0; MAX_DIM];
        for (i, (ui, vi)) in u.iter_mut().zip(v.iter()).take(d).enumerate() {
            *ui = if i == col { 1.0 } else { 0.0 } - scale * vi;
        }
        u
    }

    /// Rank-1 update of `J` from the difference along tangent direction `c`:
    /// `J ← J + (y − J u) uᵀ`, `y = (r(x + h u) − r(x))/h` (no update if it failed).
    fn difference(&mut self, c: usize, result: Option<&Outcome<N>>) {
        let Some(o) = result else { return };
        let rp = self.residual(o);
        let h = self.config.fd_step;
        let u = self.tangent(c);
        let mut y = [0.0; MAX_ROWS];
        for ((y, a), b) in y.iter_mut().zip(rp.iter()).zip(self.r.iter()) {
            *y = (a - b) / h;
        }
        self.rank1(&y, &u, 1.0);
    }

    /// `J ← J + (y − J s) sᵀ / ss`.
    fn rank1(&mut self, y: &Res, s: &Col, ss: f64) {
        if !(ss > 0.0 && ss.is_finite() && y.iter().all(|v| v.is_finite())) {
            return;
        }
        for (row, yi) in self.jac.iter_mut().zip(y.iter()) {
            let js = dot(row, s);
            let k = (yi - js) / ss;
            for (j, sj) in row.iter_mut().zip(s.iter()) {
                *j += k * sj;
            }
        }
    }

    /// Decides a trial; plans the next rollout.
    fn judge(&mut self, valid: Option<&Outcome<N>>, stream: &mut Stream) {
        let mut accepted = false;
        if let Some(o) = valid {
            let rt = self.residual(o);
            let mt = norm2(&rt);
            if self.config.broyden {
                let mut y = [0.0; MAX_ROWS];
                for ((y, a), b) in y.iter_mut().zip(rt.iter()).zip(self.r.iter()) {
                    *y = a - b;
                }
                let s = self.step;
                self.rank1(&y, &s, dot(&s, &s));
                self.stale += 1;
            }
            if mt < self.merit {
                accepted = true;
                let rho = if self.pred > 0.0 {
                    (self.merit - mt) / self.pred
                } else {
                    0.0
                };
                let t = 2.0 * rho - 1.0;
                let factor = (1.0 - t * t * t).max(1.0 / 3.0);
                self.lambda = (self.lambda * factor).max(LAMBDA_MIN);
                self.nu = 2.0;
                self.rejects = 0;
                self.x = self.trial;
                self.r = rt;
                self.merit = mt;
                self.report.accepted += 1;
                if libm::sqrt(mt) <= self.config.shrink * libm::sqrt(self.ref_merit) {
                    self.ref_merit = mt;
                    self.ref_rollout = self.report.rollouts;
                }
            }
        }
        if self.out_of_patience() {
            self.start_next(stream);
            return;
        }
        if accepted {
            if !self.config.broyden {
                self.phase = Phase::Column(0);
            } else if self.config.refresh {
                let c = self.cursor % self.dims().max(1);
                self.cursor = self.cursor.wrapping_add(1);
                self.phase = Phase::Refresh(c);
            } else {
                self.plan_trial(stream);
            }
            return;
        }
        self.lambda *= self.nu;
        self.nu *= 2.0;
        self.rejects += 1;
        if self.config.broyden && self.stale > 0 && self.rejects >= self.config.rebuild_after {
            self.phase = Phase::Column(0);
        } else {
            self.plan_trial(stream);
        }
    }

    /// No checkpoint progress for longer than the patience that applies.
    fn out_of_patience(&self) -> bool {
        let sigma = self.config.sigma_e;
        let limit = if self.merit <= sigma * sigma {
            self.refine_patience
        } else {
            self.patience
        };
        self.report.rollouts.saturating_sub(self.ref_rollout) > limit
    }

    /// Drops the start after a stall, or rebuilds `J` first if it is a corrected one.
    fn stalled(&mut self, stream: &mut Stream) {
        if self.stale > 0 {
            self.lambda = self.config.lambda0;
            self.nu = 2.0;
            self.phase = Phase::Column(0);
        } else {
            self.start_next(stream);
        }
    }

    /// Computes the trial point from `J`, `r`, λ; phase → `Trial` (or a stall).
    fn plan_trial(&mut self, stream: &mut Stream) {
        if self.out_of_patience() {
            self.start_next(stream);
            return;
        }
        if self.lambda > LAMBDA_MAX {
            self.stalled(stream);
            return;
        }
        let m = self.dims();
        // J_t = J U (rows × m), tangent directions as columns; kept in the struct (like A
        // below) so that the 32×32 scratch matrices live in static memory, not the stack.
        for row in &mut self.jt {
            *row = [0.0; MAX_DIM];
        }
        for c in 0..m {
            let uc = self.tangent(c);
            for (jt_row, j_row) in self.jt.iter_mut().zip(self.jac.iter()) {
                if let Some(v) = jt_row.get_mut(c) {
                    *v = dot(j_row, &uc);
                }
            }
        }
        // A = J_tᵀ J_t, g = J_tᵀ r; unused dimensions get a unit diagonal.
        for row in &mut self.a {
            *row = [0.0; MAX_DIM];
        }
        let mut g = [0.0; MAX_DIM];
        for (jt_row, ri) in self.jt.iter().zip(self.r.iter()) {
            for (i, (ai, gi)) in self.a.iter_mut().zip(g.iter_mut()).enumerate().take(m) {
                let ji = jt_row.get(i).copied().unwrap_or(0.0);
                *gi -= ji * ri;
                for (aij, jj) in ai.iter_mut().zip(jt_row.iter()).take(m) {
                    *aij += ji * jj;
                }
            }
        }
        let mut dmax = 0.0f64;
        for (i, ai) in self.a.iter().enumerate().take(m) {
            dmax = dmax.max(ai.get(i).copied().unwrap_or(0.0));
        }
        if !(dmax > 0.0 && dmax.is_finite()) {
            self.stalled(stream);
            return;
        }
        let damping = self.lambda * dmax;
        for (i, ai) in self.a.iter_mut().enumerate() {
            if let Some(v) = ai.get_mut(i) {
                *v += if i < m { damping } else { 1.0 };
            }
        }
        let Some(delta) = solve_spd_in_place(&mut self.a, &g) else {
            self.stalled(stream);
            return;
        };
        let norm = libm::sqrt(dot(&delta, &delta));
        if !(norm >= STEP_MIN && norm.is_finite()) {
            self.stalled(stream);
            return;
        }
        // Predicted ‖r‖² after the step: ‖r + J_t δ‖².
        let mut predicted = 0.0;
        for (jt_row, ri) in self.jt.iter().zip(self.r.iter()) {
            let v = ri + dot(jt_row, &delta);
            predicted += v * v;
        }
        self.pred = self.merit - predicted;
        let mut s = [0.0; MAX_DIM];
        for (c, dc) in delta.iter().enumerate().take(m) {
            let uc = self.tangent(c);
            for (si, ui) in s.iter_mut().zip(uc.iter()) {
                *si += dc * ui;
            }
        }
        let mut t = self.x;
        for (ti, si) in t.iter_mut().zip(s.iter()) {
            *ti += si;
        }
        if !self.config.free_amplitude {
            normalise(&mut t);
        }
        self.step = s;
        self.trial = t;
        self.phase = Phase::Trial;
    }
}

fn dot(a: &[f64; MAX_DIM], b: &[f64; MAX_DIM]) -> f64 {
    a.iter().zip(b.iter()).fold(0.0, |s, (x, y)| s + x * y)
}

fn norm2(r: &Res) -> f64 {
    r.iter().fold(0.0, |s, v| s + v * v)
}

impl<const N: usize, const K: usize> Multistart<N, K> {
    /// The multistart's settings for the planner's `config`: [`LmConfig::reference`] with
    /// the total budget, σ_e, and the truth hand-over floor when refining against the
    /// truth model, and η's magnitude searched too for `family`
    /// [`Family::FreeAmplitude`](crate::Family::FreeAmplitude); and the f it searches to: the refinement tolerance when
    /// there is one (it refines as it searches; against the truth it stops at its
    /// planner-model floor and the truth refinement takes over), else σ_e.
    #[must_use]
    pub fn settings(config: &PlannerConfig, motion: &Motion) -> (LmConfig, f64) {
        let (family, segments) = (motion.family(), motion.segments());
        let lm = LmConfig {
            max_rollouts: config.max_rollouts,
            sigma_e: config.tolerance,
            floor: match (config.refine_tolerance, config.refine_against) {
                (Some(_), RefineAgainst::Truth) => TRUTH_HANDOVER_FLOOR,
                _ => 0.0,
            },
            floor_starts: match (config.refine_tolerance, config.refine_against) {
                // Fewer unknowns than the 6 pose equations.
                (Some(_), RefineAgainst::Planner)
                    if Self::unknowns(family.free_amplitude(), segments) < 6 =>
                {
                    FLOOR_STARTS
                }
                _ => 0,
            },
            free_amplitude: family.free_amplitude(),
            segments,
            ..LmConfig::reference()
        };
        let tolerance = match config.refine_tolerance {
            Some(r) => r.min(config.tolerance),
            None => config.tolerance,
        };
        (lm, tolerance)
    }
}

impl<const N: usize, const K: usize> Method<N, K> for Multistart<N, K> {
    /// [`Multistart::reset`] with [`Multistart::settings`]: draws the first screening
    /// batch.
    fn start(
        &mut self,
        config: &PlannerConfig,
        task: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        let (lm, tolerance) = Self::settings(config, task.motion());
        self.reset(&lm, task.robot(), tolerance, stream)?;
        self.clearance_limit = task.collision().map(CollisionSet::limit);
        Ok(())
    }

    fn tolerance(&self) -> f64 {
        self.tolerance
    }

    fn refines_as_it_searches(&self) -> bool {
        true
    }

    /// Accepted LM steps, and the starts after the first.
    fn report(&self) -> SearchReport {
        SearchReport {
            iterations: self.report.accepted,
            stagnation_events: 0,
            restarts: self.report.starts.saturating_sub(1),
        }
    }
}

impl<const N: usize, const K: usize> Optimizer<N, K> for Multistart<N, K> {
    fn candidate(&self) -> Candidate<K> {
        let (eta, cap) = self.ask();
        Candidate::segmented(eta, cap)
    }

    /// A finished rollout is an outcome; an abandoned or failed one counts like a failed
    /// rollout (`None`).
    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        stream: &mut Stream,
        _: &mut O,
    ) -> Next {
        if self.tell(evaluation.outcome(), stream) {
            Next::Continue
        } else if self.report.converged || self.report.floor {
            Next::Done(Stop::Converged)
        } else if self.report.stalled {
            Next::Done(Stop::Stalled)
        } else {
            Next::Done(Stop::Exhausted)
        }
    }

    /// Accepted LM steps, and the LM start in progress.
    fn progress(&self) -> (u32, u32) {
        (self.report.accepted, self.report.starts)
    }

    /// The rest of a screening batch, or of a full difference Jacobian (the iterate does
    /// not move while its columns are differenced).
    fn ahead(&self, j: usize) -> Option<Candidate<K>> {
        let cap = f64::INFINITY;
        match self.phase {
            Phase::Screen(i) => {
                let i = i.checked_add(j)?;
                if i >= self.config.screen as usize {
                    return None;
                }
                self.pool
                    .get(i)
                    .map(|p| Candidate::segmented(to_eta(p), cap))
            }
            Phase::Column(c) => {
                let c = c.checked_add(j)?;
                if c >= self.dims() {
                    return None;
                }
                Some(Candidate::segmented(to_eta(&self.column_point(c)), cap))
            }
            Phase::Refresh(_) | Phase::Trial | Phase::Done => None,
        }
    }
}

/// Scales to unit length (a zero vector becomes `e_0`).
fn normalise(v: &mut [f64]) {
    let n = libm::sqrt(v.iter().fold(0.0, |s, x| s + x * x));
    if n > 0.0 && n.is_finite() {
        for x in v.iter_mut() {
            *x /= n;
        }
    } else {
        v.fill(0.0);
        if let Some(x) = v.first_mut() {
            *x = 1.0;
        }
    }
}

/// The iterate as η: segment `k` takes components `2K·k … 2K·(k+1)` (zero past the
/// search's segments, which the iterate leaves zero).
fn to_eta<const K: usize>(v: &Col) -> Eta<K> {
    let mut eta = one_segment([[0.0; 2]; K]);
    for (segment, block) in eta.iter_mut().zip(v.chunks(2 * K)) {
        for (pair, chunk) in segment.iter_mut().zip(block.chunks_exact(2)) {
            if let [a, b] = chunk {
                *pair = [*a, *b];
            }
        }
    }
    eta
}
