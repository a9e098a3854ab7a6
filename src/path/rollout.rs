//! The rollout: integrating one η into a joint trajectory with the reference
//! discretization (eq. 19, spec §5), resumable step by step.
//!
//! Owns [`Rollout`] (the mutable state), [`Sample`] / [`Sink`] (each step's `(t, q, q̇)`
//! handed to the caller, never stored) and [`Outcome`] (what a finished rollout returns).
//! For `s = 0 … S−1`, `t_s = s·dt`:
//!
//! `q̇_s = Σ_i (β_i(t_s)/g) N_s[:, i]`,  `q_{s+1} = q_s + dt·q̇_s`,  `N_{s+1} = MGS(P(q_{s+1}) N_s)`.
//!
//! [`Rollout::advance`] performs at most `budget` integration steps per call; a rollout
//! driven in slices of any size is bit-identical to one driven in a single call, because the
//! state carried between calls is exactly the loop state. Per integration step the work is
//! one forward kinematics, one `H~bm`, one basis transport and one sink call; the call that
//! completes the last step also emits the final sample and evaluates the end pose (one more
//! forward kinematics).

use crate::error::Error;
use crate::geometry::{Pose, PoseError};
use crate::integrator::{Cubic, Rates, ab5_step, euler_step, rk4_step};
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::lanes::{Lanes, Real};
use crate::model::Robot;
use crate::momentum::coupling;
use crate::momentum::{DualFrames, coupling_rate};
use crate::nullspace::{Basis, Conditioned};
use crate::task::{Task, rank_error};
use crate::trajectory::{Eta, Integrator, Motion, TimeLaw, alpha};
use core::convert::Infallible;

/// One point of the trajectory.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sample<const N: usize> {
    /// Sample index `s` (`0..=S`).
    pub step: u32,
    /// Time `t_s` (s); the last sample is exactly `t_f`.
    pub t: f64,
    /// Joint positions `q_s` (rad).
    pub q: [f64; N],
    /// Joint rates `q̇_s` (rad/s), constant over `[t_s, t_{s+1})`; zero at both ends.
    pub qd: [f64; N],
}

/// Receives each sample of a rollout as it is computed.
///
/// Implemented for every `FnMut(&Sample<N>)` and for `()` (discard).
pub trait Sink<const N: usize> {
    /// Called once per sample, in order `s = 0, 1, …, S`.
    fn sample(&mut self, s: &Sample<N>);

    /// `true` if [`Sink::sample`] does nothing: an [`crate::Integrator::Rk4`] or
    /// [`crate::Integrator::Ab5`] rollout then skips computing the samples between its integrator steps (the outcome is the same).
    fn discards(&self) -> bool {
        false
    }
}

impl<const N: usize, F: FnMut(&Sample<N>)> Sink<N> for F {
    fn sample(&mut self, s: &Sample<N>) {
        self(s);
    }
}

impl<const N: usize> Sink<N> for () {
    fn sample(&mut self, _: &Sample<N>) {}

    fn discards(&self) -> bool {
        true
    }
}

/// What a finished rollout returns.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Outcome<const N: usize> {
    /// Final configuration `q_S` (rad).
    pub q_final: [f64; N],
    /// Smallest value of each joint over all samples (rad).
    pub joint_min: [f64; N],
    /// Largest value of each joint over all samples (rad).
    pub joint_max: [f64; N],
    /// Constraint violation: Φ of eq. 23 (rad), plus, with collision geometry, the
    /// clearance shortfall `max(0, required − clearance)` (m, counted 1 rad per m); 0 when
    /// the limits and the clearance hold.
    pub phi: f64,
    /// End-effector pose at `t_f`, planner model (base attitude identity, base position
    /// from CoM conservation).
    pub end_pose: Pose,
    /// Pose error `e` against the task target (spec §6).
    pub error: PoseError,
    /// `f = ‖e‖₂`.
    pub f: f64,
    /// Largest `|q̇_r|` over all samples and joints (rad/s).
    pub max_abs_qd: f64,
    /// `g` for the η as given: eq. 14's, or the motion family's ([`crate::TimeLaw::g`]).
    pub g: f64,
    /// With collision geometry ([`Task::with_collision`]): a lower bound of the path's
    /// clearance (m), certified between samples
    /// ([`crate::clearance::CollisionSet::step_bound`]), or the limit (required clearance
    /// plus margin) if the path stays above it; `∞` without geometry. Below the required
    /// clearance, the shortfall is part of [`Outcome::phi`].
    pub clearance: f64,
}

/// Where a rollout is.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Progress<const N: usize> {
    /// `step` of `steps` integration steps are done.
    Running {
        /// Integration steps completed.
        step: u32,
        /// Total integration steps `S`.
        steps: u32,
    },
    /// Finished.
    Done(Outcome<N>),
    /// Stopped early: the violation Φ of the samples so far already exceeds the cap set
    /// with [`Rollout::with_violation_cap`], so the finished rollout's Φ would too.
    Abandoned {
        /// Integration steps completed when it stopped.
        step: u32,
        /// Φ of the samples `0..=step` (rad), a lower bound of the full rollout's Φ.
        phi: f64,
    },
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase<const N: usize> {
    Running,
    Done(Outcome<N>),
    Abandoned { step: u32, phi: f64 },
    Failed(Error),
}

/// What the integration loop carries from step to step, for one rollout (`f64`) or for
/// several side by side ([`Lanes`], see [`crate::batch`]): the one source of the hot path.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct State<const N: usize, const K: usize, T> {
    /// Configuration `q_s` (rad).
    pub(crate) q: [T; N],
    /// Null-space basis at `q_s`.
    pub(crate) basis: Basis<N, K, T>,
    /// Smallest value of each joint over the samples so far (rad).
    pub(crate) q_min: [T; N],
    /// Largest value of each joint over the samples so far (rad).
    pub(crate) q_max: [T; N],
    /// Largest `|q̇_r|` over the samples so far (rad/s).
    pub(crate) max_abs_qd: T,
}

/// How one integration step went, per lane: `q_{s+1}` finite, and the basis transport.
pub(crate) struct Stepped<M> {
    pub(crate) finite: M,
    pub(crate) conditioned: Conditioned<M>,
}

impl<const N: usize, const K: usize, T: Real> State<N, K, T> {
    /// `q̇_s = Σ_i α_i(t_s) N_s[:, i]` for normalised weights `(a_i, b_i)` and `1/g`.
    #[inline(always)]
    pub(crate) fn rates(&self, ab: &[[T; 2]; K], inv_g: T, motion: &Motion, t: T) -> [T; N] {
        let w = alpha(ab, inv_g, motion.tf(), motion.degree(), t);
        self.basis.combine(&w)
    }

    /// Folds sample `s` (`q_s`, and its rates `qd`) into the extrema.
    #[inline(always)]
    pub(crate) fn fold(&mut self, qd: &[T; N]) {
        for ((q, lo), hi) in self
            .q
            .iter()
            .zip(self.q_min.iter_mut())
            .zip(self.q_max.iter_mut())
        {
            *lo = lo.min(*q);
            *hi = hi.max(*q);
        }
        for v in qd {
            self.max_abs_qd = self.max_abs_qd.max(v.abs());
        }
    }

    /// One integration step after sample `s`: `q_{s+1} = q_s + dt·q̇_s`, then the basis
    /// carried to `q_{s+1}`. Where a lane is not finite or not conditioned, its state is
    /// meaningless.
    #[inline(always)]
    pub(crate) fn step(
        &mut self,
        robot: &Robot<N>,
        qd: &[T; N],
        dt: f64,
        frames: &mut Frames<N, T>,
    ) -> Stepped<T::Mask> {
        euler_step(&mut self.q, qd, dt);
        let finite = self.q.iter().fold(T::ONE.finite(), |m, v| {
            crate::lanes::Mask::and(m, v.finite())
        });
        // Only links and CoM feed H~bm; the end-effector fields stay unused.
        let _ = frames.update_chain(robot, &self.q);
        let conditioned = self.basis.transport_masked(&coupling(robot, frames));
        Stepped {
            finite,
            conditioned,
        }
    }
}

impl<const N: usize, const K: usize> State<N, K, f64> {
    /// [`State::step`] of one rollout. On a bare-metal target (`target_os = "none"`: the
    /// flight image) it is compiled once and shared by every kind of scalar rollout (with
    /// or without a sink or a cap), which keeps the image small; on a host it is inlined
    /// into each, which is faster. The same operations either way, so the same bits.
    #[cfg_attr(target_os = "none", inline(never))]
    #[cfg_attr(not(target_os = "none"), inline(always))]
    pub(crate) fn step_one(
        &mut self,
        robot: &Robot<N>,
        qd: &[f64; N],
        dt: f64,
        frames: &mut Frames<N>,
    ) -> Stepped<bool> {
        self.step(robot, qd, dt, frames)
    }

    /// At `q₀` of `task`, nothing folded yet.
    pub(crate) fn start(task: &Task<N, K>) -> Self {
        let q = *task.start();
        Self {
            q,
            basis: *task.initial_basis(),
            q_min: q,
            q_max: q,
            max_abs_qd: 0.0,
        }
    }
}

impl<const N: usize, const K: usize, const L: usize> State<N, K, Lanes<L>> {
    /// Lane `i` as one rollout's state.
    pub(crate) fn lane(&self, i: usize) -> State<N, K, f64> {
        let pick = |v: &[Lanes<L>; N]| v.map(|x| x.lane(i));
        let mut basis = Basis::<N, K>::IDLE;
        for (to, from) in basis
            .columns_mut()
            .iter_mut()
            .zip(self.basis.columns().iter())
        {
            *to = pick(from);
        }
        State {
            q: pick(&self.q),
            basis,
            q_min: pick(&self.q_min),
            q_max: pick(&self.q_max),
            max_abs_qd: self.max_abs_qd.lane(i),
        }
    }

    /// Writes one rollout's state into lane `i`.
    pub(crate) fn set_lane(&mut self, i: usize, s: &State<N, K, f64>) {
        let put = |to: &mut [Lanes<L>; N], from: &[f64; N]| {
            for (t, f) in to.iter_mut().zip(from.iter()) {
                t.set(i, *f);
            }
        };
        for (to, from) in self
            .basis
            .columns_mut()
            .iter_mut()
            .zip(s.basis.columns().iter())
        {
            put(to, from);
        }
        put(&mut self.q, &s.q);
        put(&mut self.q_min, &s.q_min);
        put(&mut self.q_max, &s.q_max);
        self.max_abs_qd.set(i, s.max_abs_qd);
    }
}

/// The mutable state of one rollout. Create with [`Rollout::new`], drive with
/// [`Rollout::advance`] against the same [`Task`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Rollout<const N: usize, const K: usize> {
    law: TimeLaw<K>,
    step: u32,
    state: State<N, K, f64>,
    /// [`Integrator::Rk4`], [`Integrator::Ab5`]: the integrator step the samples are
    /// being taken from.
    span: Span<N, K>,
    /// Abandon once Φ of the samples so far exceeds this (rad); `∞` never abandons.
    phi_cap: f64,
    /// The clearance bound of the steps so far (m; `∞` before the first, or without
    /// geometry).
    clear: f64,
    phase: Phase<N>,
}

impl<const N: usize, const K: usize> Rollout<N, K> {
    /// A rollout of `eta` (pairs `(a_i, b_i)`) for `task`, at `t = 0`.
    ///
    /// # Errors
    /// η invalid (non-finite, all zero); see [`TimeLaw::new`].
    pub fn new(task: &Task<N, K>, eta: &[[f64; 2]; K]) -> Result<Self, Error> {
        let law = TimeLaw::new(eta, task.motion(), task.robot().qd_max())?;
        Ok(Self::resume(law, 0, State::start(task)))
    }

    /// A rollout of `eta` (one set of pairs per segment of the task's motion,
    /// [`TimeLaw::of`]) for `task`, at `t = 0`.
    ///
    /// # Errors
    /// As [`TimeLaw::of`].
    pub fn of(task: &Task<N, K>, eta: &Eta<K>) -> Result<Self, Error> {
        let law = TimeLaw::of(eta, task.motion(), task.robot().qd_max())?;
        Ok(Self::resume(law, 0, State::start(task)))
    }

    /// A rollout of `law` at step `step` with `state` (a lane of a batch, taken out).
    pub(crate) fn resume(law: TimeLaw<K>, step: u32, state: State<N, K, f64>) -> Self {
        Self {
            law,
            step,
            state,
            span: Span::IDLE,
            phi_cap: f64::INFINITY,
            clear: f64::INFINITY,
            phase: Phase::Running,
        }
    }

    /// Makes the rollout stop with [`Progress::Abandoned`] as soon as the constraint
    /// violation Φ (eq. 23, rad) of the samples so far exceeds `cap`.
    ///
    /// Φ of a prefix never exceeds Φ of the whole rollout (the extrema only widen, every
    /// term is non-decreasing in them, and the sum is taken in a fixed order, so this holds
    /// after rounding too). An abandoned rollout would therefore have finished with
    /// `Φ > cap`: a caller that discards such results (the planner: a particle whose
    /// personal best has `Φ ≤ cap`, a refinement trial that must keep `Φ = 0`) gets the same
    /// decisions for less work. A NaN or infinite cap never abandons.
    #[must_use]
    pub fn with_violation_cap(mut self, cap: f64) -> Self {
        self.phi_cap = if cap.is_nan() { f64::INFINITY } else { cap };
        self
    }

    /// The time law in use.
    #[must_use]
    pub fn law(&self) -> &TimeLaw<K> {
        &self.law
    }

    /// Integration steps completed.
    #[must_use]
    pub fn step(&self) -> u32 {
        self.step
    }

    /// The null-space basis at the current configuration.
    #[must_use]
    pub fn basis(&self) -> &Basis<N, K> {
        &self.state.basis
    }

    /// The current configuration (rad).
    #[must_use]
    pub fn q(&self) -> &[f64; N] {
        &self.state.q
    }

    /// Advances by at most `budget` integration steps, handing each sample to `sink`.
    ///
    /// Returns [`Progress::Running`] while steps remain and [`Progress::Done`] once the
    /// last step is done (again on every later call, without further work). With a
    /// violation cap it may instead return [`Progress::Abandoned`] (again on every later
    /// call); the final sample at `t_f` is not checked against the cap, so a finished
    /// rollout can still have `Φ > cap`.
    ///
    /// # Errors
    /// [`Error::RankLoss`] or [`Error::NonFiniteState`] at the step where it happened; the
    /// rollout then stays failed and returns the same error on every later call.
    ///
    /// Verifies RL-ROLL-002.
    ///
    /// ```
    /// use reactionless::{CHASER7, Motion, Pose, Progress, Robot, Rollout, Task};
    /// let robot = Robot::new(&CHASER7).unwrap();
    /// let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
    /// let target = Pose { position: [2.0, 0.1, -1.4], quat_wxyz: [1.0, 0.0, 0.0, 0.0] };
    /// let task: Task<7, 4> = Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1).unwrap()).unwrap();
    /// let eta = [[3.14771, 0.809316], [1.12249, 0.754006], [4.7352, 0.406031], [-4.1572, 4.29895]];
    /// let mut r = Rollout::new(&task, &eta).unwrap();
    /// let mut samples = 0;
    /// let mut count = |_: &reactionless::Sample<7>| samples += 1;
    /// while let Progress::Running { .. } = r.advance(&task, 500, &mut count).unwrap() {}
    /// assert_eq!(samples, 3001);
    /// ```
    pub fn advance<S: Sink<N>>(
        &mut self,
        task: &Task<N, K>,
        budget: u32,
        sink: &mut S,
    ) -> Result<Progress<N>, Error> {
        match self.phase {
            Phase::Done(o) => return Ok(Progress::Done(o)),
            Phase::Abandoned { step, phi } => return Ok(Progress::Abandoned { step, phi }),
            Phase::Failed(e) => return Err(e),
            Phase::Running => {}
        }
        match self.run(task, budget, sink) {
            Ok(p) => {
                match p {
                    Progress::Done(o) => self.phase = Phase::Done(o),
                    Progress::Abandoned { step, phi } => {
                        self.phase = Phase::Abandoned { step, phi };
                    }
                    Progress::Running { .. } => {}
                }
                Ok(p)
            }
            Err(e) => {
                self.phase = Phase::Failed(e);
                Err(e)
            }
        }
    }

    fn run<S: Sink<N>>(
        &mut self,
        task: &Task<N, K>,
        budget: u32,
        sink: &mut S,
    ) -> Result<Progress<N>, Error> {
        let steps = task.motion().steps();
        let end = self.step.saturating_add(budget).min(steps);
        if let Err(Abandon { step, phi }) =
            self.integrate(task, end, &PhiCap(self.phi_cap), sink)?
        {
            return Ok(Progress::Abandoned { step, phi });
        }
        if self.step < steps {
            return Ok(Progress::Running {
                step: self.step,
                steps,
            });
        }
        Ok(Progress::Done(self.conclude(task, sink)))
    }

    /// Integration steps up to step `end` (at most `S`). `Ok(Err(_))` if `cap` stopped it.
    #[inline(never)]
    fn integrate<S: Sink<N>, C: Cap>(
        &mut self,
        task: &Task<N, K>,
        end: u32,
        cap: &C,
        sink: &mut S,
    ) -> Result<Result<(), C::Stop>, Error> {
        let motion = task.motion();
        if motion.integrator() != Integrator::Euler {
            return self.integrate_nodes(task, end, cap, sink);
        }
        let robot = task.robot();
        let dt = motion.dt();
        // One segment's grid: the motion itself when it has one segment.
        let grid = motion.segment();
        let per = grid.steps().max(1);
        let mut frames = Frames::IDLE;
        let geometry = task.collision();
        if geometry.is_some() {
            // The frames of the sample the loop starts at (then each step leaves them at
            // the next one).
            let _ = frames.update_chain(robot, &self.state.q);
        }
        while self.step < end {
            // The segment of this step: its weights, its first step and where it ends.
            let k = (self.step / per).min(motion.segments().saturating_sub(1));
            let first = k * per;
            let seg_end = end.min(first.saturating_add(per)).max(self.step + 1);
            let (ab, inv_g) = self.law.weights(k as usize);
            let ab = *ab;
            while self.step < seg_end {
                let t = motion.time(self.step);
                let qd = self
                    .state
                    .rates(&ab, inv_g, &grid, grid.time(self.step - first));
                self.record(t, &qd, sink);
                if let Some(set) = geometry {
                    let bound = set.step_bound(&frames, &task.com0(), &qd, dt);
                    self.clear = self.clear.min(bound);
                }
                if let Err(stop) = cap.check(self.step, || self.violation(task)) {
                    return Ok(Err(stop));
                }
                let stepped = self.state.step_one(robot, &qd, dt, &mut frames);
                self.step += 1;
                if !stepped.finite {
                    return Err(Error::NonFiniteState { step: self.step });
                }
                stepped
                    .conditioned
                    .result()
                    .map_err(rank_error(self.step))?;
            }
        }
        Ok(Ok(()))
    }

    /// [`Rollout::integrate`] for [`Integrator::Rk4`] and [`Integrator::Ab5`]: at each
    /// integrator node (every [`Motion::stride`] samples of a segment) one step of `(q, N)`
    /// to the next node ([`Rollout::span_step`]), and the [`Cubic`] Hermite interpolant `p`
    /// of `q` over it. The samples are
    /// `q_s = p(t_s)` (the nodes exactly) and `q̇_s = (q_{s+1} − q_s)/(t_{s+1} − t_s)`, the
    /// rate of the written path over `[t_s, t_{s+1})` as Euler's; the joint extrema and the
    /// largest rate are those of `p` over the whole step (its range and rate bound), folded
    /// in at the node, where the violation cap is checked. So the outcome does not depend on
    /// the sink, and a sink that [`Sink::discards`] costs no sample work. An error inside an
    /// integrator step is reported at the step of its first sample plus one. A call that
    /// reaches a node does a whole RK4 step (four evaluations of the dual kinematics and
    /// `H~bm`; one for an AB5 step after the first four of a segment), whatever its
    /// budget: the largest work of one call is that, not one Euler step.
    #[inline(never)]
    fn integrate_nodes<S: Sink<N>, C: Cap>(
        &mut self,
        task: &Task<N, K>,
        end: u32,
        cap: &C,
        sink: &mut S,
    ) -> Result<Result<(), C::Stop>, Error> {
        if task.collision().is_some() {
            return Err(Error::NeedsScalarEuler);
        }
        let motion = task.motion();
        let robot = task.robot();
        let grid = motion.segment();
        let per = grid.steps().max(1);
        let stride = motion.stride().max(1);
        let mut frames = DualFrames::default();
        while self.step < end {
            let k = (self.step / per).min(motion.segments().saturating_sub(1));
            let local = self.step - k * per;
            let j = local % stride;
            if j == 0 {
                self.span_step(task, k, local, &mut frames)?;
                if let Err(stop) = cap.check(self.step, || {
                    robot.violation(&self.state.q_min, &self.state.q_max)
                }) {
                    return Ok(Err(stop));
                }
            }
            // The samples of this step that this call reaches.
            let last = (self.step + (stride - j)).min(end);
            if sink.discards() {
                let reached = last - self.step;
                self.step = last;
                self.state.q = self.span.sample(j + reached, stride);
                continue;
            }
            let mut i = j;
            while self.step < last {
                let next = self.span.sample(i + 1, stride);
                let t = motion.time(self.step);
                let dt = motion.time(self.step + 1) - t;
                let mut qd = [0.0; N];
                for ((v, b), a) in qd.iter_mut().zip(next.iter()).zip(self.state.q.iter()) {
                    *v = (b - a) / dt;
                }
                sink.sample(&Sample {
                    step: self.step,
                    t,
                    q: self.state.q,
                    qd,
                });
                self.state.q = next;
                self.step += 1;
                i += 1;
            }
        }
        Ok(Ok(()))
    }

    /// At the node of sample `local` of segment `k`: one step to the next node (an
    /// [`rk4_step`], or for [`Integrator::Ab5`] past the segment's first four nodes an
    /// [`ab5_step`] from the rates kept at the four nodes before), its interpolant, and its
    /// range and rate folded into the extrema.
    fn span_step(
        &mut self,
        task: &Task<N, K>,
        k: u32,
        local: u32,
        frames: &mut DualFrames<N>,
    ) -> Result<(), Error> {
        let motion = task.motion();
        let robot = task.robot();
        let grid = motion.segment();
        let (ab, inv_g) = self.law.weights(k as usize);
        let ab = *ab;
        let at = |t: f64, cols: &[[f64; N]; K]| {
            Basis::<N, K>::from_columns(*cols).combine(&alpha(
                &ab,
                inv_g,
                grid.tf(),
                grid.degree(),
                t,
            ))
        };
        let mut rates_with = |qd: [f64; N], q: &[f64; N], cols: &[[f64; N]; K]| {
            let (a, a_dot) = coupling_rate(robot, frames, q, &qd);
            Ok((qd, Basis::rate_of(cols, &a, &a_dot)?))
        };
        if self.step == 0 {
            self.span.q = self.state.q;
        }
        let stride = motion.stride();
        let (t0, t1) = (grid.time(local), grid.time(local + stride));
        let h = t1 - t0;
        let q0 = self.span.q;
        let mut q = q0;
        let mut cols = *self.state.basis.columns();
        let node = (local / stride.max(1)) as usize;
        let multistep = motion.integrator() == Integrator::Ab5;
        let now = if multistep && node >= AB5_START {
            let now = rates_with(at(t0, &cols), &q, &cols).map_err(rank_error(self.step + 1))?;
            let p = &self.span.past;
            let past = |back: usize| p.get((node + 4 - back) % 4).unwrap_or(&now);
            ab5_step(
                h,
                &mut q,
                &mut cols,
                [&now, past(1), past(2), past(3), past(4)],
            );
            now
        } else {
            let rates =
                |t: f64, q: &[f64; N], cols: &[[f64; N]; K]| rates_with(at(t, cols), q, cols);
            rk4_step(t0, h, &mut q, &mut cols, rates).map_err(rank_error(self.step + 1))?
        };
        if multistep {
            if let Some(slot) = self.span.past.get_mut(node % 4) {
                *slot = now;
            }
        }
        if !q.iter().chain(cols.iter().flatten()).all(|v| v.is_finite()) {
            return Err(Error::NonFiniteState {
                step: self.step + 1,
            });
        }
        let v0 = now.0;
        let v1 = at(t1, &cols);
        let p = Cubic::hermite(&q0, &v0, &q, &v1, h);
        let (lo, hi) = p.range();
        let s = &mut self.state;
        for (((a, b), l), u) in s.q_min.iter_mut().zip(s.q_max.iter_mut()).zip(lo).zip(hi) {
            *a = a.min(l);
            *b = b.max(u);
        }
        // A written rate is a chord between two samples `dt` apart, each within the slack
        // of the interpolant (the last node exact): at most the bound plus 2 slacks over
        // `dt` (taken as `dt/2`, for the rounding of the sample times).
        s.max_abs_qd = s
            .max_abs_qd
            .max(p.rate_bound(h) + 4.0 * p.slack() / motion.dt());
        // RK4 puts N back on NᵀN = I at each node. AB5 does not: the flow keeps NᵀN (it
        // is the flow of Ṅ = −A⁺ȦN from AN = 0), and a projection between steps is not in
        // the past rates, which made AB5 unstable on fast paths (its rates blowing up at
        // 0.15 s on a free-amplitude motion that RK4 and an unprojected AB5 integrate).
        // AB5's basis drifts off orthonormal by its integration error instead (2.9e-7 on
        // the reference task); a collapse ends in a non-finite state, caught above.
        s.basis = if multistep {
            Basis::<N, K>::from_columns(cols)
        } else {
            Basis::<N, K>::reorthonormalized(cols).map_err(rank_error(self.step + 1))?
        };
        self.span.p = p;
        self.span.q = q;
        Ok(())
    }

    /// After the last step: the final sample at `t_f` (β(t_f) = 0 exactly, so q̇_S = 0) and
    /// the outcome.
    pub(crate) fn conclude<S: Sink<N>>(&mut self, task: &Task<N, K>, sink: &mut S) -> Outcome<N> {
        let tf = task.motion().tf();
        let qd = self.state.basis.combine(&self.law.alpha(tf));
        self.record(tf, &qd, sink);
        let s = &self.state;
        let end_pose = task.end_pose(&s.q, IDENTITY_WXYZ);
        let error = end_pose.error_to(task.target());
        Outcome {
            q_final: s.q,
            joint_min: s.q_min,
            joint_max: s.q_max,
            phi: self.violation(task),
            end_pose,
            error,
            f: error.norm(),
            max_abs_qd: s.max_abs_qd,
            g: self.law.g(),
            clearance: self.clear,
        }
    }

    /// Φ of the samples so far, plus the clearance shortfall of the steps so far with
    /// collision geometry (without, Φ alone, bit for bit).
    #[inline]
    fn violation(&self, task: &Task<N, K>) -> f64 {
        let phi = task.robot().violation(&self.state.q_min, &self.state.q_max);
        match task.collision() {
            Some(set) => phi + (set.required() - self.clear).max(0.0),
            None => phi,
        }
    }

    /// Emits sample `self.step` and folds it into the extrema.
    #[inline]
    fn record<S: Sink<N>>(&mut self, t: f64, qd: &[f64; N], sink: &mut S) {
        sink.sample(&Sample {
            step: self.step,
            t,
            q: self.state.q,
            qd: *qd,
        });
        self.state.fold(qd);
    }
}

/// The nodes of a segment an [`Integrator::Ab5`] rollout takes by RK4 before it has the
/// four past rates a step needs.
const AB5_START: usize = 4;

/// The integrator step a [`Integrator::Rk4`] or [`Integrator::Ab5`] rollout is taking
/// samples from: the interpolant of `q` over it and `q` at its last node (the integrator's
/// state), and for AB5 the rates `(q̇, Ṅ)` at the last four nodes (node `n`'s in slot
/// `n mod 4`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Span<const N: usize, const K: usize> {
    p: Cubic<N>,
    q: [f64; N],
    past: [Rates<N, K>; 4],
}

impl<const N: usize, const K: usize> Span<N, K> {
    const IDLE: Self = Self {
        p: Cubic::IDLE,
        q: [0.0; N],
        past: [([0.0; N], [[0.0; N]; K]); 4],
    };

    /// Sample `i` of `stride` in this step: the last node exactly at `i = stride`, else
    /// the interpolant at `θ = i/stride`.
    #[inline]
    fn sample(&self, i: u32, stride: u32) -> [f64; N] {
        if i == stride {
            self.q
        } else {
            self.p.at(f64::from(i) / f64::from(stride))
        }
    }
}

/// Where an abandoned rollout stopped.
struct Abandon {
    step: u32,
    phi: f64,
}

/// How a rollout checks its violation cap (once per sample, after folding it in).
trait Cap {
    /// What stopping early carries (`Infallible`: never stops).
    type Stop;
    /// `Err` to stop at `step`; `phi` computes Φ of the samples so far.
    fn check(&self, step: u32, phi: impl FnOnce() -> f64) -> Result<(), Self::Stop>;
}

/// A finite cap stops a rollout once Φ exceeds it; an infinite one never computes Φ.
struct PhiCap(f64);

impl Cap for PhiCap {
    type Stop = Abandon;
    #[inline(always)]
    fn check(&self, step: u32, phi: impl FnOnce() -> f64) -> Result<(), Abandon> {
        if self.0 < f64::INFINITY {
            let phi = phi();
            if phi > self.0 {
                return Err(Abandon { step, phi });
            }
        }
        Ok(())
    }
}

/// No cap: the rollout always runs to the end.
struct NoCap;

impl Cap for NoCap {
    type Stop = Infallible;
    #[inline(always)]
    fn check(&self, _: u32, _: impl FnOnce() -> f64) -> Result<(), Infallible> {
        Ok(())
    }
}

impl<const N: usize, const K: usize> Task<N, K> {
    /// Runs a whole rollout of `eta` (pairs `(a_i, b_i)`) in one call.
    ///
    /// # Errors
    /// As [`Rollout::new`] and [`Rollout::advance`].
    pub fn rollout<S: Sink<N>>(
        &self,
        eta: &[[f64; 2]; K],
        sink: &mut S,
    ) -> Result<Outcome<N>, Error> {
        Self::run_whole(self, Rollout::new(self, eta), sink)
    }
    /// Runs a whole rollout of `eta` (one set of pairs per segment, [`Rollout::of`]) in one
    /// call.
    ///
    /// # Errors
    /// As [`Rollout::of`] and [`Rollout::advance`].
    pub fn rollout_of<S: Sink<N>>(&self, eta: &Eta<K>, sink: &mut S) -> Result<Outcome<N>, Error> {
        Self::run_whole(self, Rollout::of(self, eta), sink)
    }

    /// The rollout `made` run to the end, worked on where it was made: moving it out of
    /// the `Result` would put a second copy of it (2.5 KB) on the stack. Out of line, so
    /// that callers running several rollouts hold none in their own frames.
    #[inline(never)]
    fn run_whole<S: Sink<N>>(
        &self,
        mut made: Result<Rollout<N, K>, Error>,
        sink: &mut S,
    ) -> Result<Outcome<N>, Error> {
        let r = match &mut made {
            Ok(r) => r,
            Err(e) => return Err(*e),
        };
        let Ok(()) = r.integrate(self, self.motion().steps(), &NoCap, sink)?;
        Ok(r.conclude(self, sink))
    }
}
