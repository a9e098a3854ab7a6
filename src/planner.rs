//! The planner that flies: a search (C-PSO, spec §7) followed by optional refinement, as
//! one resumable, budgeted, deterministic state machine.
//!
//! Owns [`Planner`] and what it reports ([`Status`], [`Plan`], [`Running`]). The planner
//! drives [`Optimizer`]s: it asks each for a candidate η, evaluates it with a [`Rollout`]
//! it keeps between calls, and tells the optimizer how it ended. [`Planner::step`] performs at most `budget` integration steps, so a
//! flight scheduler can give it a fixed slice of every frame. Driving it with budget 1 per
//! call gives the same bits as driving it with an unlimited budget: the state carried
//! between calls is exactly the loop state, and every random draw happens at a fixed point
//! of the sequence (see [`crate::swarm`] for the draw order).
//!
//! **Worst-case work per call**: `budget` integration steps (each one FK, one `H~bm`, one
//! basis transport, and O(N) for the violation cap below), plus bookkeeping:
//! - per finished rollout: one end-pose FK and O(K) to start the next rollout;
//! - per generation boundary: O(T) to select gbest, plus the swarm move (`T·2K` velocity
//!   updates with `4K` draws per particle, and, after a stagnation alarm, a permutation of
//!   T);
//! - per refinement step: a 6×6 Cholesky and O(K) vector work.
//!
//! A candidate rejected before integration (non-finite η), or abandoned before its first
//! step, costs one unit of budget, so every call ends.
//!
//! **Early abandonment** (exact): each rollout carries the violation cap of its
//! [`crate::optimizer::Candidate`] ([`Rollout::with_violation_cap`]), above which its result
//! could change no decision: the particle's personal-best Φ during C-PSO, 0 for a
//! refinement trial, none for a Jacobian column. A cap is applied only once a finished
//! rollout is on record, so the planner always has a plan to report when the search ends. Φ of the samples so far never exceeds Φ of the whole rollout, so a rollout that
//! passes its cap is stopped there; η, f, iterations, rollout counts and every later random
//! draw are bit-identical to evaluating it to the end (the golden records, blessed before
//! this existed, replay unchanged). [`Plan::abandoned`] counts them.
//!
//! Iterations are counted as in the paper: the initial generation is iteration 0, and
//! `iterations` is the number of generations after it. A feasible particle with
//! `f ≤ tolerance` stops C-PSO at once, even in the middle of a generation.

use crate::config::PlannerConfig;
use crate::cpso::Cpso;
use crate::error::Error;
use crate::optimizer::{Evaluation, Next, Observer, Optimizer, Stop};
use crate::random::Stream;
use crate::refine::{RefineReport, Refiner};
use crate::rollout::{Outcome, Progress, Rollout};
use crate::swarm::{Cost, Swarm};
use crate::task::Task;

/// Which stage the planner is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// The search for a feasible η within σ_e (C-PSO).
    Search,
    /// Levenberg–Marquardt refinement.
    Refine,
}

/// Where a running planner is.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Running {
    /// Current stage.
    pub stage: Stage,
    /// Current generation of C-PSO (0 = initial); during refinement, the one it
    /// succeeded in.
    pub iteration: u32,
    /// Particle being evaluated (0 during refinement).
    pub particle: u32,
    /// Rollouts finished so far.
    pub rollouts: u32,
    /// Best cost so far.
    pub best: Cost,
}

/// A finished plan: the chosen η, the rollout that was evaluated for it, and how the
/// planner got there.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Plan<const N: usize, const K: usize> {
    /// Why planning stopped: [`Stop::Converged`] (a feasible η with `f ≤ σ_e`, refined if
    /// configured) or [`Stop::Exhausted`] (m_max generations without success: the best
    /// feasible η found, or the least violating one if none is feasible).
    pub stop: Stop,
    /// η as pairs `(a_i, b_i)`.
    pub eta: [[f64; 2]; K],
    /// The rollout of `eta`: final configuration, extrema, Φ, end pose, error, f.
    pub outcome: Outcome<N>,
    /// C-PSO generations after the initial one.
    pub iterations: u32,
    /// All rollouts (C-PSO and refinement).
    pub rollouts: u32,
    /// Rollouts spent by C-PSO.
    pub swarm_rollouts: u32,
    /// Rollouts (of `rollouts`) stopped early because their violation Φ already ruled
    /// them out ([`Rollout::with_violation_cap`]); they change no decision.
    pub abandoned: u32,
    /// Stagnation alarms.
    pub stagnation_events: u32,
    /// f when C-PSO stopped.
    pub swarm_f: f64,
    /// Refinement, if it ran.
    pub refine: Option<RefineReport>,
}

impl<const N: usize, const K: usize> Plan<N, K> {
    /// `true` if the plan met its tolerance ([`Stop::Converged`]).
    #[must_use]
    pub fn converged(&self) -> bool {
        self.stop == Stop::Converged
    }
}

/// What [`Planner::step`] returns.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status<const N: usize, const K: usize> {
    /// Budget spent, more to do.
    Running(Running),
    /// Planning is over; the plan says why ([`Plan::stop`]).
    Finished(Plan<N, K>),
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase<const N: usize, const K: usize> {
    Search,
    Refine(Refiner<N, K>),
    Done(Plan<N, K>),
    Failed(Error),
}

/// The best point of the search, by constraint domination ([`Cost::dominates`]).
#[derive(Debug, Clone, Copy, PartialEq)]
enum Record<const N: usize, const K: usize> {
    /// No rollout has finished: the last error ([`Error::NotInitialized`] before the
    /// first evaluation).
    Failed(Error),
    /// The best finished rollout.
    Found([[f64; 2]; K], Outcome<N>),
}

impl<const N: usize, const K: usize> Record<N, K> {
    /// Folds in the evaluation of `eta`.
    fn fold(self, eta: &[[f64; 2]; K], evaluation: &Evaluation<N>) -> Self {
        match (self, evaluation) {
            (Record::Found(_, best), Evaluation::Finished(_))
                if !evaluation.cost().dominates(&cost_of(&best)) =>
            {
                self
            }
            (_, Evaluation::Finished(o)) => Record::Found(*eta, *o),
            (Record::Failed(_), Evaluation::Failed(e)) => Record::Failed(*e),
            (kept, _) => kept,
        }
    }
}

/// The planner for `N` joints, null-space dimension `K = N − 3` and a swarm capacity of `P`
/// particles.
#[derive(Debug, Clone, PartialEq)]
pub struct Planner<const N: usize, const K: usize, const P: usize> {
    task: Task<N, K>,
    config: PlannerConfig,
    stream: Stream,
    cpso: Cpso<K, P>,
    phase: Phase<N, K>,
    rollout: Option<Rollout<N, K>>,
    /// η of the rollout in flight (or last evaluated).
    eta: [[f64; 2]; K],
    record: Record<N, K>,
    rollouts: u32,
    swarm_rollouts: u32,
    abandoned: u32,
    swarm_f: f64,
    /// Budget consumed so far (integration steps, plus one per rejected candidate).
    spent: u64,
}

fn cost_of<const N: usize>(o: &Outcome<N>) -> Cost {
    Cost { phi: o.phi, f: o.f }
}

impl<const N: usize, const K: usize, const P: usize> Planner<N, K, P> {
    /// A planner without a task, `const`: flight software places it in static memory and
    /// gives it work with [`Planner::reset`], so the 20-odd KiB of state never pass through
    /// the stack. [`Planner::step`] returns [`Error::NotInitialized`] until then.
    pub const IDLE: Self = Self {
        task: Task::IDLE,
        config: PlannerConfig::reference(0),
        stream: Stream::IDLE,
        cpso: Cpso::IDLE,
        phase: Phase::Failed(Error::NotInitialized),
        rollout: None,
        eta: [[0.0; 2]; K],
        record: Record::Failed(Error::NotInitialized),
        rollouts: 0,
        swarm_rollouts: 0,
        abandoned: 0,
        swarm_f: f64::INFINITY,
        spent: 0,
    };

    /// Starts planning `task` from scratch, in place: the planner ends up exactly as
    /// [`Planner::new`] would build it. Only small temporaries are used.
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]); the planner is then idle and
    /// [`Planner::step`] returns the same error.
    pub fn reset(&mut self, task: Task<N, K>, config: PlannerConfig) -> Result<(), Error> {
        self.task = task;
        self.restart(config)
    }

    /// Leaves the planner idle with error `e` (returned by every [`Planner::step`]).
    pub(crate) fn fail(&mut self, e: Error) {
        self.phase = Phase::Failed(e);
    }

    /// The task, for building it in place ([`Task::init`]) before [`Planner::restart`].
    pub fn task_mut(&mut self) -> &mut Task<N, K> {
        self.phase = Phase::Failed(Error::NotInitialized);
        &mut self.task
    }

    /// Starts planning the planner's current task from scratch with `config`, in place.
    ///
    /// # Errors
    /// As [`Planner::reset`].
    pub fn restart(&mut self, config: PlannerConfig) -> Result<(), Error> {
        self.rollout = None;
        self.record = Record::Failed(Error::NotInitialized);
        self.eta = [[0.0; 2]; K];
        self.rollouts = 0;
        self.swarm_rollouts = 0;
        self.abandoned = 0;
        self.swarm_f = f64::INFINITY;
        self.spent = 0;
        if let Err(e) = config.validate(P) {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.config = config;
        self.stream = Stream::new(config.seed);
        if let Err(e) = self.cpso.reset(&config, &mut self.stream) {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.phase = Phase::Search;
        Ok(())
    }

    /// A planner for `task`, its swarm at its initial positions.
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]).
    ///
    /// Verifies RL-PLAN-001, RL-PLAN-008.
    ///
    /// One flight frame gives the planner a slice of work:
    ///
    /// ```
    /// use reactionless::{Planner, PlannerConfig, Status, reference};
    /// let task = reference::paper_task().unwrap();
    /// let mut planner: Planner<7, 4, 64> = Planner::new(task, PlannerConfig::reference(1)).unwrap();
    /// // At most 4000 integration steps this frame: one rollout (3000 steps) and a third.
    /// match planner.step(4000, &mut ()).unwrap() {
    ///     Status::Running(r) => assert_eq!(r.rollouts, 1),
    ///     Status::Finished(_) => unreachable!(),
    /// }
    /// ```
    ///
    /// Planning to the end (≈ 0.4 s optimised for the reference task):
    ///
    /// ```no_run
    /// # use reactionless::{Planner, PlannerConfig, Status, reference};
    /// # let task = reference::paper_task().unwrap();
    /// # let mut planner: Planner<7, 4, 64> = Planner::new(task, PlannerConfig::reference(1)).unwrap();
    /// let plan = loop {
    ///     if let Status::Finished(plan) = planner.step(100_000, &mut ()).unwrap() {
    ///         break plan;
    ///     }
    /// };
    /// assert!(plan.converged() && plan.outcome.f <= 0.05 && plan.outcome.phi == 0.0);
    /// ```
    pub fn new(task: Task<N, K>, config: PlannerConfig) -> Result<Self, Error> {
        let mut p = Self::IDLE;
        p.reset(task, config)?;
        Ok(p)
    }

    /// The task.
    #[must_use]
    pub fn task(&self) -> &Task<N, K> {
        &self.task
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &PlannerConfig {
        &self.config
    }

    /// The swarm (for inspection).
    #[must_use]
    pub fn swarm(&self) -> &Swarm<K, P> {
        self.cpso.swarm()
    }

    /// The finished plan, once [`Planner::step`] has returned [`Status::Finished`].
    #[must_use]
    pub fn result(&self) -> Option<&Plan<N, K>> {
        match &self.phase {
            Phase::Done(p) => Some(p),
            Phase::Search | Phase::Refine(_) | Phase::Failed(_) => None,
        }
    }

    /// Budget consumed so far: integration steps, plus one per candidate rejected before
    /// integration. Each [`Planner::step`] call adds at most its `budget`.
    #[must_use]
    pub fn spent(&self) -> u64 {
        self.spent
    }

    /// Advances by at most `budget` integration steps; reports events to `observer`.
    ///
    /// # Errors
    /// Only if no rollout at all could be evaluated (every candidate failed): the last
    /// rollout error. Once finished, every call returns the same result without work.
    pub fn step<O: Observer>(
        &mut self,
        budget: u32,
        observer: &mut O,
    ) -> Result<Status<N, K>, Error> {
        let mut left = budget;
        let result = self.run(&mut left, observer);
        self.spent += u64::from(budget - left);
        result
    }

    fn run<O: Observer>(
        &mut self,
        left: &mut u32,
        observer: &mut O,
    ) -> Result<Status<N, K>, Error> {
        while *left > 0 {
            match self.phase {
                Phase::Done(p) => return Ok(Status::Finished(p)),
                Phase::Failed(e) => return Err(e),
                Phase::Search | Phase::Refine(_) => {}
            }
            let mut rollout = match self.rollout.take() {
                Some(r) => r,
                None => {
                    let (eta, cap) = self.candidate();
                    self.eta = eta;
                    match Rollout::new(&self.task, &eta) {
                        Ok(r) => r.with_violation_cap(cap),
                        Err(e) => {
                            *left -= 1;
                            self.absorb(Evaluation::Failed(e), observer);
                            continue;
                        }
                    }
                }
            };
            let before = rollout.step();
            let result = rollout.advance(&self.task, *left, &mut ());
            *left = left.saturating_sub(rollout.step().saturating_sub(before));
            match result {
                Ok(Progress::Running { .. }) => self.rollout = Some(rollout),
                Ok(Progress::Done(o)) => self.absorb(Evaluation::Finished(o), observer),
                Ok(Progress::Abandoned { step, phi }) => {
                    if step == 0 {
                        // No integration step was spent: charge one unit, as for a
                        // rejected candidate, so every call ends. (Not expected: pbest's
                        // Φ includes the start, and refinement starts feasible.)
                        *left = left.saturating_sub(1);
                    }
                    self.absorb(Evaluation::Abandoned(phi), observer);
                }
                Err(e) => self.absorb(Evaluation::Failed(e), observer),
            }
        }
        match self.phase {
            Phase::Done(p) => Ok(Status::Finished(p)),
            Phase::Failed(e) => Err(e),
            Phase::Search | Phase::Refine(_) => Ok(Status::Running(self.running())),
        }
    }

    fn running(&self) -> Running {
        let (stage, (iteration, particle), best) = match &self.phase {
            Phase::Refine(r) => (
                Stage::Refine,
                (self.cpso.iterations(), 0),
                cost_of(r.best().1),
            ),
            _ => (
                Stage::Search,
                Optimizer::<N, K>::progress(&self.cpso),
                match &self.record {
                    Record::Found(_, o) => cost_of(o),
                    Record::Failed(_) => Cost::FAILED,
                },
            ),
        };
        Running {
            stage,
            iteration,
            particle,
            rollouts: self.rollouts,
            best,
        }
    }

    /// The next η and its violation cap (applied only once a finished rollout is on
    /// record, so that an abandoned rollout never leaves the search without a result).
    fn candidate(&self) -> ([[f64; 2]; K], f64) {
        let c = match &self.phase {
            Phase::Refine(r) => r.candidate(),
            _ => Optimizer::<N, K>::candidate(&self.cpso),
        };
        match self.record {
            Record::Found(..) => (c.eta, c.cap),
            Record::Failed(_) => (c.eta, f64::INFINITY),
        }
    }

    fn plan(&self, stop: Stop, eta: [[f64; 2]; K], outcome: Outcome<N>) -> Plan<N, K> {
        Plan {
            stop,
            eta,
            outcome,
            iterations: self.cpso.iterations(),
            rollouts: self.rollouts,
            swarm_rollouts: self.swarm_rollouts,
            abandoned: self.abandoned,
            stagnation_events: self.cpso.swarm().stagnation_events(),
            swarm_f: self.swarm_f,
            refine: None,
        }
    }

    /// Takes the result of the rollout of `self.eta`.
    fn absorb<O: Observer>(&mut self, evaluation: Evaluation<N>, observer: &mut O) {
        self.rollouts += 1;
        if let Evaluation::Abandoned(_) = evaluation {
            self.abandoned += 1;
        }
        match self.phase {
            Phase::Search => self.absorb_search(&evaluation, observer),
            Phase::Refine(mut r) => {
                self.phase = match r.absorb(&evaluation, &mut self.stream, observer) {
                    Next::Continue => Phase::Refine(r),
                    Next::Done(stop) => {
                        let (eta, best) = r.best();
                        let mut plan = self.plan(stop, *eta, *best);
                        plan.refine = Some(r.report());
                        Phase::Done(plan)
                    }
                };
            }
            Phase::Done(_) | Phase::Failed(_) => {}
        }
    }

    fn absorb_search<O: Observer>(&mut self, evaluation: &Evaluation<N>, observer: &mut O) {
        self.swarm_rollouts += 1;
        self.record = self.record.fold(&self.eta, evaluation);
        let next = self.cpso.absorb(evaluation, &mut self.stream, observer);
        self.phase = match (next, evaluation, self.record) {
            (Next::Continue, ..) => Phase::Search,
            (Next::Done(Stop::Converged), Evaluation::Finished(o), _) => {
                self.swarm_f = o.f;
                match self.config.refine() {
                    Some(rc) => {
                        let r = Refiner::new(rc, self.eta, *o);
                        if r.done() {
                            let mut plan = self.plan(Stop::Converged, self.eta, *o);
                            plan.refine = Some(r.report());
                            Phase::Done(plan)
                        } else {
                            Phase::Refine(r)
                        }
                    }
                    None => Phase::Done(self.plan(Stop::Converged, self.eta, *o)),
                }
            }
            (Next::Done(_), _, Record::Found(eta, o)) => {
                self.swarm_f = o.f;
                Phase::Done(self.plan(Stop::Exhausted, eta, o))
            }
            (Next::Done(_), _, Record::Failed(e)) => Phase::Failed(e),
        };
    }
}
