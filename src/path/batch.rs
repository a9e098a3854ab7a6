//! Rollouts in lanes: `L` candidates of one task integrated in lockstep, each lane with the
//! bits of the scalar [`Rollout`].
//!
//! Owns [`Batch`] (the lanes' state), [`Lane`] (what one lane holds), [`Ended`] (how a
//! lane's rollout ended) and the [`Engine`] seam (which build of the kernel runs it).
//!
//! **Same bits per lane.** The kernel ([`Batch::kernel`]) runs the scalar rollout's loop
//! body ([`crate::rollout`]'s `State`: rates, fold, Euler step, forward kinematics, `H~bm`,
//! basis transport) on [`Lanes<L>`] instead of `f64`: every lane performs the scalar
//! operations in the scalar order (see [`crate::lanes`]), so lane `i` of a batch ends with
//! exactly the [`Outcome`] (or abandonment, or error, at the same step) that
//! [`Rollout::advance`] gives for the same η and violation cap. The last sample and the end
//! pose are evaluated by the scalar [`Rollout`] itself, on the lane taken out.
//!
//! **Independent lanes.** Each lane has its own η, step index and time, so a lane can be
//! loaded while the others are half-way ([`Batch::load`]), and lanes end independently.
//! A lane that holds no running rollout sits at rest at `q₀` (time 0, so `q̇ = 0`) and
//! costs only its share of the vector work.
//!
//! **Work.** One *lane-step* advances every running lane by one integration step: per lane,
//! the work of one scalar step (one forward kinematics, one `H~bm`, one basis transport).
//! [`Batch::kernel`] reports the integration steps it did, summed over the lanes, which is
//! what the planner charges to its budget; `hold` keeps chosen lanes where they are, so a
//! budget smaller than the number of running lanes is honoured exactly.

use crate::error::{Error, NeedsOneSegment, RankLoss};
use crate::kinematics::Frames;
use crate::lanes::{LaneMask, Lanes, Mask};
use crate::rollout::{Outcome, Rollout, State, Stepped};
use crate::task::Task;
use crate::trajectory::{Integrator, TimeLaw};
use core::fmt::Debug;

/// How a lane's rollout ended (as [`Rollout::advance`] would have ended it).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Ended<const N: usize> {
    /// It finished.
    Done(Outcome<N>),
    /// Stopped at `step` with the violation `phi` of its samples so far above its cap.
    Abandoned {
        /// Integration steps completed when it stopped.
        step: u32,
        /// Φ of the samples `0..=step` (rad).
        phi: f64,
    },
    /// It failed (rank loss or a non-finite state, at the step it happened).
    Failed(Error),
}

/// What one lane holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Lane<const N: usize, const K: usize> {
    /// Nothing: at rest at `q₀`.
    Empty,
    /// A rollout being integrated.
    Running {
        /// Its time law.
        law: TimeLaw<K>,
        /// Integration steps completed.
        step: u32,
        /// Its violation cap (rad; `∞` never abandons).
        cap: f64,
    },
    /// A rollout that ended, until [`Batch::take`] collects it (the lane is at rest).
    Ended(Ended<N>),
}

/// `L` rollouts of one task, integrated side by side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Batch<const N: usize, const K: usize, const L: usize> {
    state: State<N, K, Lanes<L>>,
    /// Normalised `(a_i, b_i)` of each lane's η (zero in lanes without a rollout).
    ab: [[Lanes<L>; 2]; K],
    /// `1/g` of each lane's η.
    inv_g: Lanes<L>,
    lanes: [Lane<N, K>; L],
}

/// Which build of [`Batch::kernel`] integrates a batch: [`Portable`] everywhere, or a host's
/// build of the same kernel for a wider instruction set (host-sim picks AVX2 at run time on
/// x86-64). Every build gives the same bits.
pub trait Engine: Copy + Debug + PartialEq {
    /// [`Batch::kernel`], as built by this engine.
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32;
}

/// The kernel as the crate is compiled (the target's baseline instruction set).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Portable;

impl Engine for Portable {
    #[inline(never)]
    fn run<const N: usize, const K: usize, const L: usize>(
        batch: &mut Batch<N, K, L>,
        task: &Task<N, K>,
        lane_steps: u32,
        hold: [bool; L],
    ) -> u32 {
        batch.kernel(task, lane_steps, hold)
    }
}

impl<const N: usize, const K: usize, const L: usize> Batch<N, K, L> {
    /// No lanes in use, no task (a placeholder for statically allocated state; call
    /// [`Batch::reset`] before loading a lane).
    pub const IDLE: Self = Self {
        state: State {
            q: [Lanes([0.0; L]); N],
            basis: crate::nullspace::Basis::IDLE,
            q_min: [Lanes([0.0; L]); N],
            q_max: [Lanes([0.0; L]); N],
            max_abs_qd: Lanes([0.0; L]),
        },
        ab: [[Lanes([0.0; L]); 2]; K],
        inv_g: Lanes([0.0; L]),
        lanes: [Lane::Empty; L],
    };

    /// Every lane empty, at rest at `q₀` of `task`.
    pub fn reset(&mut self, task: &Task<N, K>) {
        for i in 0..L {
            self.park(i, task);
        }
    }

    /// A batch for `task`, every lane empty.
    #[must_use]
    pub fn new(task: &Task<N, K>) -> Self {
        let mut b = Self::IDLE;
        b.reset(task);
        b
    }

    /// Lane `i` at rest at `q₀`, holding nothing.
    fn park(&mut self, i: usize, task: &Task<N, K>) {
        self.state.set_lane(i, &State::start(task));
        for pair in &mut self.ab {
            for v in pair {
                v.set(i, 0.0);
            }
        }
        self.inv_g.set(i, 0.0);
        if let Some(l) = self.lanes.get_mut(i) {
            *l = Lane::Empty;
        }
    }

    /// Starts a rollout of `eta` in lane `i` (which must be empty) with violation cap `cap`
    /// (rad; NaN or `∞`: never abandon), as [`Rollout::new`] and
    /// [`Rollout::with_violation_cap`] would.
    ///
    /// # Errors
    /// As [`Rollout::new`] (the lane stays empty); [`Error::NotInitialized`] for a lane
    /// index out of range or a lane that is not empty; [`Error::NeedsEuler`] for a motion
    /// integrated by RK4; [`Error::NeedsScalarEuler`] for a task with collision geometry.
    pub fn load(
        &mut self,
        i: usize,
        task: &Task<N, K>,
        eta: &[[f64; 2]; K],
        cap: f64,
    ) -> Result<(), Error> {
        if !matches!(self.lanes.get(i), Some(Lane::Empty)) {
            return Err(Error::NotInitialized);
        }
        if task.motion().integrator() != Integrator::Euler {
            return Err(Error::NeedsEuler);
        }
        if task.collision().is_some() {
            return Err(Error::NeedsScalarEuler);
        }
        let law = TimeLaw::new(eta, task.motion(), task.robot().qd_max()).map_err(|e| {
            if task.motion().segments() > 1 {
                Error::NeedsOneSegment(NeedsOneSegment::Lanes)
            } else {
                e
            }
        })?;
        let (ab, inv_g) = law.weights(0);
        for (to, from) in self.ab.iter_mut().zip(ab.iter()) {
            for (t, f) in to.iter_mut().zip(from.iter()) {
                t.set(i, *f);
            }
        }
        self.inv_g.set(i, inv_g);
        self.state.set_lane(i, &State::start(task));
        if let Some(l) = self.lanes.get_mut(i) {
            *l = Lane::Running {
                law,
                step: 0,
                cap: if cap.is_nan() { f64::INFINITY } else { cap },
            };
        }
        Ok(())
    }

    /// What lane `i` holds.
    #[must_use]
    pub fn lane(&self, i: usize) -> Option<&Lane<N, K>> {
        self.lanes.get(i)
    }

    /// The lanes.
    #[must_use]
    pub fn lanes(&self) -> &[Lane<N, K>; L] {
        &self.lanes
    }

    /// Collects how lane `i`'s rollout ended, if it has; the lane is then empty.
    pub fn take(&mut self, i: usize) -> Option<Ended<N>> {
        match self.lanes.get(i) {
            Some(Lane::Ended(e)) => {
                let e = *e;
                if let Some(l) = self.lanes.get_mut(i) {
                    *l = Lane::Empty;
                }
                Some(e)
            }
            _ => None,
        }
    }

    /// Lanes with a running rollout.
    #[must_use]
    pub fn running(&self) -> u32 {
        self.lanes
            .iter()
            .filter(|l| matches!(l, Lane::Running { .. }))
            .count() as u32
    }

    /// Copies lane `i` (its state, its η's weights and what it holds) into lane `j` of
    /// `to`, a batch of the same task with any lane count. A wide batch can so be cut into
    /// narrower ones, integrated apart (on several threads: `reactionless-simd`'s
    /// `Threaded`) and put back together, each lane keeping the bits it would have had:
    /// lanes never mix. Nothing happens for an index out of range.
    pub fn copy_lane<const M: usize>(&self, i: usize, to: &mut Batch<N, K, M>, j: usize) {
        let (Some(lane), Some(slot)) = (self.lanes.get(i), to.lanes.get_mut(j)) else {
            return;
        };
        *slot = *lane;
        to.state.set_lane(j, &self.state.lane(i));
        for (t, f) in to.ab.iter_mut().zip(self.ab.iter()) {
            for (tv, fv) in t.iter_mut().zip(f.iter()) {
                tv.set(j, fv.lane(i));
            }
        }
        to.inv_g.set(j, self.inv_g.lane(i));
    }

    /// Whether a lane would move in a lane-step with `hold`: one runs and is not held
    /// ([`Batch::kernel`] does no work otherwise).
    #[inline(always)]
    #[must_use]
    pub fn moves(&self, hold: [bool; L]) -> bool {
        self.lanes
            .iter()
            .zip(hold)
            .any(|(l, h)| !h && matches!(l, Lane::Running { .. }))
    }

    /// Empties lane `i`, whatever it holds (a rollout whose result is no longer wanted).
    pub fn clear(&mut self, i: usize, task: &Task<N, K>) {
        self.park(i, task);
    }

    /// At most `lane_steps` lane-steps; returns the integration steps done (summed over the
    /// lanes). Stops after the lane-step in which a lane's rollout ended, and at once if no
    /// lane runs. Lanes marked in `hold` do not move. Runs the kernel as the crate is built
    /// ([`Portable`]).
    ///
    /// Verifies RL-LANE-001.
    ///
    /// ```
    /// use reactionless::batch::Batch;
    /// use reactionless::reference::{ETA_HAT, paper_task};
    /// let task = paper_task().unwrap();
    /// let mut b: Batch<7, 4, 2> = Batch::new(&task);
    /// let mut other = ETA_HAT;
    /// other[0][0] = 2.0;
    /// b.load(0, &task, &ETA_HAT, f64::INFINITY).unwrap();
    /// b.load(1, &task, &other, f64::INFINITY).unwrap();
    /// let mut steps = 0;
    /// while b.running() > 0 {
    ///     steps += b.advance(&task, 500, [false; 2]);
    /// }
    /// assert_eq!(steps, 2 * 3000);
    /// let Some(reactionless::batch::Ended::Done(o)) = b.take(0) else { panic!() };
    /// assert_eq!(o, task.rollout(&ETA_HAT, &mut ()).unwrap()); // bit for bit
    /// ```
    pub fn advance(&mut self, task: &Task<N, K>, lane_steps: u32, hold: [bool; L]) -> u32 {
        Portable::run(self, task, lane_steps, hold)
    }

    /// The kernel behind [`Batch::advance`] and every [`Engine`]: inlined into its caller,
    /// so that an engine compiled for a wider instruction set compiles all of it so.
    #[inline(always)]
    pub fn kernel(&mut self, task: &Task<N, K>, lane_steps: u32, hold: [bool; L]) -> u32 {
        let motion = task.motion();
        let robot = task.robot();
        let dt = motion.dt();
        let steps = motion.steps();
        if lane_steps == 0 {
            return 0;
        }
        let capped = self
            .lanes
            .iter()
            .zip(hold)
            .any(|(l, h)| !h && matches!(l, Lane::Running { cap, .. } if *cap < f64::INFINITY));
        let holding = self
            .lanes
            .iter()
            .zip(hold)
            .any(|(l, h)| h && matches!(l, Lane::Running { .. }));
        if !self.moves(hold) {
            // Nothing would move: no work, and nothing would ever end the loop.
            return 0;
        }
        // Per lane: its step (as f64, exact; 0 where nothing runs), 1 where it moves, its
        // cap; and the lane-steps until the first moving lane reaches `S`.
        let mut at = Lanes([0.0; L]);
        let mut inc = Lanes([0.0; L]);
        let mut caps = Lanes([f64::INFINITY; L]);
        let mut until = u32::MAX;
        let mut movers = 0u32;
        for (i, (lane, h)) in self.lanes.iter().zip(hold).enumerate() {
            if let Lane::Running { step, cap, .. } = lane {
                at.set(i, f64::from(*step));
                if !h {
                    inc.set(i, 1.0);
                    caps.set(i, *cap);
                    until = until.min(steps.saturating_sub(*step));
                    movers += 1;
                }
            }
        }
        let mut frames = Frames::<N, Lanes<L>>::IDLE;
        let mut done = 0u32;
        loop {
            let saved = if holding { Some(self.state) } else { None };
            // t_s = s·dt, as `Motion::time` computes it (s < S here).
            let t = at * dt;
            let qd = self.state.rates(&self.ab, self.inv_g, motion, t);
            self.state.fold(&qd);
            let phi = capped.then(|| robot.violation_of(&self.state.q_min, &self.state.q_max));
            let stepped = self.state.step(robot, &qd, dt, &mut frames);
            done += 1;
            // The common lane-step: nothing holds, ends, fails or passes its cap.
            let quiet = !holding
                && done < until
                && stepped.finite.all()
                && stepped.conditioned.coupling.all()
                && stepped.conditioned.basis.all()
                && phi.is_none_or(|p| !p.0.iter().zip(caps.0).any(|(p, c)| *p > c));
            if quiet {
                at += inc;
                if done >= lane_steps {
                    self.sync_steps(at, hold);
                    break;
                }
                continue;
            }
            self.sync_steps(at, hold);
            self.settle(task, &stepped, phi, hold);
            if let Some(saved) = saved {
                for (i, (lane, h)) in self.lanes.iter().zip(hold).enumerate() {
                    if h && matches!(lane, Lane::Running { .. }) {
                        self.state.set_lane(i, &saved.lane(i));
                    }
                }
            }
            break;
        }
        movers * done
    }

    /// Writes the lanes' step counters `at` back into the moving lanes.
    #[inline(always)]
    fn sync_steps(&mut self, at: Lanes<L>, hold: [bool; L]) {
        for (i, (lane, h)) in self.lanes.iter_mut().zip(hold).enumerate() {
            if let Lane::Running { step, .. } = lane
                && !h
            {
                *step = at.lane(i) as u32;
            }
        }
    }

    /// After a lane-step in which something happened: each moving lane, as the scalar
    /// rollout would take its step (abandoned at its cap, failed, finished, or one step
    /// further); lanes that ended are put at rest.
    #[inline(always)]
    fn settle(
        &mut self,
        task: &Task<N, K>,
        stepped: &Stepped<LaneMask<L>>,
        phi: Option<Lanes<L>>,
        hold: [bool; L],
    ) {
        let steps = task.motion().steps();
        let mut ended = [false; L];
        for (i, ((lane, h), e)) in self
            .lanes
            .iter_mut()
            .zip(hold)
            .zip(ended.iter_mut())
            .enumerate()
        {
            if h {
                continue;
            }
            let Lane::Running { law, step, cap } = lane else {
                continue;
            };
            let phi_i = phi.map_or(0.0, |p| p.lane(i));
            let next = if *cap < f64::INFINITY && phi_i > *cap {
                Some(Ended::Abandoned {
                    step: *step,
                    phi: phi_i,
                })
            } else {
                *step += 1;
                let rank = |cause| Ended::Failed(Error::RankLoss { step: *step, cause });
                if !stepped.finite.lane(i) {
                    Some(Ended::Failed(Error::NonFiniteState { step: *step }))
                } else if !stepped.conditioned.coupling.lane(i) {
                    Some(rank(RankLoss::Coupling))
                } else if !stepped.conditioned.basis.lane(i) {
                    Some(rank(RankLoss::Basis))
                } else if *step >= steps {
                    let mut r = Rollout::resume(*law, *step, self.state.lane(i));
                    Some(Ended::Done(r.conclude(task, &mut ())))
                } else {
                    None
                }
            };
            if let Some(end) = next {
                *lane = Lane::Ended(end);
                *e = true;
            }
        }
        for (i, _) in ended.iter().enumerate().filter(|(_, e)| **e) {
            // At rest, keeping how it ended.
            let kept = self.lanes.get(i).copied();
            self.park(i, task);
            if let (Some(l), Some(k)) = (self.lanes.get_mut(i), kept) {
                *l = k;
            }
        }
    }
}
