//! The planner that flies: a search (the multistart LM by default, or the paper's C-PSO of
//! spec §7) followed by optional refinement, as one resumable, budgeted, deterministic
//! state machine.
//!
//! Owns [`Planner`] and what it reports ([`Status`], [`Plan`], [`Running`]). The planner
//! drives [`Optimizer`]s: it asks each for a candidate η, evaluates it with a [`Rollout`]
//! it keeps between calls, and tells the optimizer how it ended. [`Planner::step`] performs
//! at most `budget` units of work, so a flight scheduler can give it a fixed slice of every
//! frame. A unit is one integration step, or one truth-model sub-step when a candidate
//! asks for the truth model (refinement against the truth: a truth-evaluated step costs
//! `1 + 10` units). Driving it with budget 1 per
//! call gives the same bits as driving it with an unlimited budget: the state carried
//! between calls is exactly the loop state, and every random draw happens at a fixed point
//! of the sequence (see [`crate::swarm`] for the draw order).
//!
//! **Worst-case work per call**: `budget` integration steps (each one FK, one `H~bm`, one
//! basis transport, and O(N) for the violation cap below; with [`crate::Integrator::Rk4`]
//! a step that reaches an integrator node does a whole RK4 step, four evaluations of the
//! dual kinematics and `H~bm`, about 7 Euler steps of work on the host and 10 on the M7,
//! and the other steps almost nothing), plus bookkeeping:
//! - per finished rollout: one end-pose FK and O(K) to start the next rollout;
//! - per generation boundary: O(T) to select gbest, plus the swarm move (`T·2K` velocity
//!   updates with `4K` draws per particle, and, after a stagnation alarm, a permutation of
//!   T);
//! - per refinement step: a 6×6 Cholesky and O(K) vector work;
//! - per multistart rollout: at most a 32×32 Cholesky and O(32²) products (`2K·segments ≤
//!   32` unknowns, `6 + N ≤ 18` residual rows).
//!
//! **One total budget**: [`PlannerConfig::max_rollouts`] rollouts, search and refinement
//! together (default 8,040). When it is spent the plan ends exhausted (or, during
//! refinement, converged with the refinement stopped by its budget), never later.
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

use crate::batch::{Batch, Ended, Engine, Portable};
use crate::config::{PlannerConfig, RefineAgainst, Strategy};
use crate::error::{Error, NeedsOneSegment};
use crate::optimizer::Method;
use crate::optimizer::{Candidate, Evaluation, Event, Next, Observer, Optimizer, Stop};
use crate::random::Stream;
use crate::refine::{RefineReport, RefineStop, Refiner};
use crate::rollout::{Outcome, Progress, Rollout, Sample};
use crate::strategy::Search;
use crate::swarm::{Cost, Swarm};
use crate::task::Task;
use crate::trajectory::{Eta, one_segment};
use crate::truth::{TRUTH_SUBSTEPS, TruthState};
use core::marker::PhantomData;

/// Which stage the planner is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// The search for a feasible η within the tolerance (multistart or C-PSO).
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
    /// C-PSO: the current generation (0 = initial); multistart: accepted LM steps. During
    /// refinement, the search's value when it succeeded.
    pub iteration: u32,
    /// C-PSO: the particle being evaluated; multistart: the LM start (0 during
    /// refinement).
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
    /// Why planning stopped: [`Stop::Converged`] (the evaluated rollout of `eta` meets
    /// what was asked: Φ = 0, `f ≤ σ_e` and, when a refinement tolerance is set, f, or
    /// `truth_f` against the truth model, within it), [`Stop::Exhausted`] (a budget was
    /// spent first) or [`Stop::Stalled`] (the refinement could get no closer). When not
    /// converged, `eta` is the best found: feasible first, else the least violating.
    pub stop: Stop,
    /// The strategy that searched.
    pub strategy: Strategy,
    /// η as pairs `(a_i, b_i)`, one set per segment of the task's motion (segments past
    /// [`crate::Motion::segments`] are zero).
    pub eta: Eta<K>,
    /// The rollout of `eta`: final configuration, extrema, Φ, end pose, error, f.
    pub outcome: Outcome<N>,
    /// C-PSO: generations after the initial one; multistart: accepted LM steps.
    pub iterations: u32,
    /// All rollouts (search and refinement).
    pub rollouts: u32,
    /// Rollouts spent by the search.
    pub search_rollouts: u32,
    /// Rollouts (of `rollouts`) stopped early because their violation Φ already ruled
    /// them out ([`Rollout::with_violation_cap`]); they change no decision.
    pub abandoned: u32,
    /// C-PSO's stagnation alarms (0 for the multistart).
    pub stagnation_events: u32,
    /// The multistart's LM starts after the first (0 for C-PSO).
    pub restarts: u32,
    /// Rollouts spent when a feasible rollout first had `f ≤ σ_e`, if one did.
    pub first_hit: Option<u32>,
    /// f when the search stopped.
    pub search_f: f64,
    /// Refinement, if it ran.
    pub refine: Option<RefineReport>,
}

impl<const N: usize, const K: usize> Plan<N, K> {
    /// `true` if the plan meets what was asked ([`Stop::Converged`]).
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
    Found(Eta<K>, Outcome<N>),
}

impl<const N: usize, const K: usize> Record<N, K> {
    /// Folds in the evaluation of `eta`.
    fn fold(self, eta: &Eta<K>, evaluation: &Evaluation<N>) -> Self {
        match (self, evaluation.outcome(), evaluation) {
            (Record::Found(_, best), Some(_), _)
                if !evaluation.cost().dominates(&cost_of(&best)) =>
            {
                self
            }
            (_, Some(o), _) => Record::Found(*eta, *o),
            (Record::Failed(_), None, Evaluation::Failed(e)) => Record::Failed(*e),
            (kept, ..) => kept,
        }
    }
}

/// The truth model riding along a rollout: its state, and the samples not yet integrated
/// (a step emits one, the last step two).
#[derive(Debug, Clone, Copy, PartialEq)]
struct TruthFlight<const N: usize> {
    state: TruthState<N>,
    queue: [Option<([f64; N], f64)>; 2],
}

/// The rollout of the candidate in flight.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Flight<const N: usize, const K: usize> {
    rollout: Rollout<N, K>,
    truth: Option<TruthFlight<N>>,
    /// The outcome, once the rollout is done but the truth model still has sub-steps.
    done: Option<Outcome<N>>,
}

/// Candidates evaluated ahead, side by side in lanes ([`Optimizer::ahead`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Ahead<const N: usize, const K: usize, const L: usize> {
    batch: Batch<N, K, L>,
    /// The candidate each lane holds.
    queue: [Candidate<K>; L],
    /// The lane that holds the candidate the optimizer asks for now.
    head: usize,
    /// Lanes in use: `head`, `head + 1`, … (mod `L`) hold consecutive candidates.
    len: usize,
}

impl<const N: usize, const K: usize, const L: usize> Ahead<N, K, L> {
    const IDLE: Self = Self {
        batch: Batch::IDLE,
        queue: [Candidate::plain([[0.0; 2]; K], f64::INFINITY); L],
        head: 0,
        len: 0,
    };

    /// Every lane emptied (their work discarded).
    fn flush(&mut self, task: &Task<N, K>) {
        if L > 1 {
            self.batch.reset(task);
        }
        self.head = 0;
        self.len = 0;
    }

    /// The lane `j` places after the head.
    fn lane(&self, j: usize) -> usize {
        (self.head + j) % L
    }
}

/// `a` and `b` are the same candidate, bit for bit.
fn same<const K: usize>(a: &Candidate<K>, b: &Candidate<K>) -> bool {
    a.truth == b.truth
        && a.cap.to_bits() == b.cap.to_bits()
        && a.eta
            .iter()
            .flatten()
            .flatten()
            .zip(b.eta.iter().flatten().flatten())
            .all(|(x, y)| x.to_bits() == y.to_bits())
}

/// The planner for `N` joints, null-space dimension `K = N − 3` and a swarm capacity of `P`
/// particles (C-PSO only), evaluating up to `L` candidates side by side with engine `E`
/// ([`crate::batch`]; `L = 1`, the default: one at a time, as on the flight target).
///
/// With `L > 1`, candidates that the search knows in advance ([`Optimizer::ahead`]: the
/// rest of a C-PSO generation, of a multistart screening batch or of a difference
/// Jacobian) are integrated in lockstep, each lane with the bits of the scalar rollout;
/// each result is used only when the search asks for exactly that candidate, in the
/// search's order, so the plan is bit-identical to the one of `L = 1` (the work of a
/// candidate the search no longer wants is discarded: it counts in [`Planner::spent`], not
/// in the rollout count).
#[derive(Debug, Clone, PartialEq)]
pub struct Planner<
    const N: usize,
    const K: usize,
    const P: usize,
    const L: usize = 1,
    E: Engine = Portable,
> {
    task: Task<N, K>,
    config: PlannerConfig,
    stream: Stream,
    /// The chosen strategy's search (only its state).
    search: Search<N, K, P>,
    phase: Phase<N, K>,
    flight: Option<Flight<N, K>>,
    /// η of the rollout in flight (or last evaluated).
    eta: Eta<K>,
    record: Record<N, K>,
    rollouts: u32,
    search_rollouts: u32,
    abandoned: u32,
    first_hit: Option<u32>,
    /// f of the rollout that was the first hit.
    first_hit_f: f64,
    search_f: f64,
    /// Budget consumed so far (units, plus one per rejected candidate).
    spent: u64,
    /// Candidates in lanes (`L > 1`).
    ahead: Ahead<N, K, L>,
    engine: PhantomData<E>,
}

fn cost_of<const N: usize>(o: &Outcome<N>) -> Cost {
    Cost { phi: o.phi, f: o.f }
}

impl<const N: usize, const K: usize, const P: usize, const L: usize, E: Engine>
    Planner<N, K, P, L, E>
{
    /// A planner without a task, `const`: flight software places it in static memory and
    /// gives it work with [`Planner::reset`], so the 30-odd KiB of state never pass through
    /// the stack. [`Planner::step`] returns [`Error::NotInitialized`] until then.
    pub const IDLE: Self = Self {
        task: Task::IDLE,
        config: PlannerConfig::reference(0),
        stream: Stream::IDLE,
        search: Search::IDLE,
        phase: Phase::Failed(Error::NotInitialized),
        flight: None,
        eta: one_segment([[0.0; 2]; K]),
        record: Record::Failed(Error::NotInitialized),
        rollouts: 0,
        search_rollouts: 0,
        abandoned: 0,
        first_hit: None,
        first_hit_f: f64::INFINITY,
        search_f: f64::INFINITY,
        spent: 0,
        ahead: Ahead::IDLE,
        engine: PhantomData,
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
        self.flight = None;
        self.ahead.flush(&self.task);
        self.record = Record::Failed(Error::NotInitialized);
        self.eta = one_segment([[0.0; 2]; K]);
        self.rollouts = 0;
        self.search_rollouts = 0;
        self.abandoned = 0;
        self.first_hit = None;
        self.first_hit_f = f64::INFINITY;
        self.search_f = f64::INFINITY;
        self.spent = 0;
        if let Err(e) = config.validate(P).and(self.segments_fit(&config)) {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.config = config;
        self.stream = Stream::new(config.seed);
        let started = self.search.start(&config, &self.task, &mut self.stream);
        if let Err(e) = started {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.phase = Phase::Search;
        Ok(())
    }

    /// A motion of several segments is searched by the multistart alone, without the
    /// refinement against the truth model (both step on one segment's η).
    fn segments_fit(&self, config: &PlannerConfig) -> Result<(), Error> {
        if self.task.motion().segments() <= 1 {
            return Ok(());
        }
        if config.strategy != Strategy::Multistart {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::Cpso));
        }
        if config.refine_tolerance.is_some() && config.refine_against == RefineAgainst::Truth {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::TruthRefinement));
        }
        Ok(())
    }

    /// A planner for `task`, its search at its start (C-PSO: the swarm at its initial
    /// positions; multistart: the first screening batch drawn).
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]).
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
    /// Planning to the end with the default strategy (≈ 0.05 s optimised for the reference
    /// task):
    ///
    /// ```no_run
    /// # use reactionless::{Planner, PlannerConfig, Status, reference};
    /// # let task = reference::paper_task().unwrap();
    /// let config = PlannerConfig::default_with_seed(1);
    /// let mut planner: Planner<7, 4, 64> = Planner::new(task, config).unwrap();
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

    /// The swarm, if the planner runs C-PSO (for inspection).
    #[must_use]
    pub fn swarm(&self) -> Option<&Swarm<K, P>> {
        self.search.swarm()
    }

    /// The running search (for inspection).
    #[must_use]
    pub fn search(&self) -> &Search<N, K, P> {
        &self.search
    }

    /// The finished plan, once [`Planner::step`] has returned [`Status::Finished`].
    #[must_use]
    pub fn result(&self) -> Option<&Plan<N, K>> {
        match &self.phase {
            Phase::Done(p) => Some(p),
            Phase::Search | Phase::Refine(_) | Phase::Failed(_) => None,
        }
    }

    /// Budget consumed so far: units of work (integration steps and truth sub-steps), plus
    /// one per candidate rejected before integration. Each [`Planner::step`] call adds at
    /// most its `budget`.
    #[must_use]
    pub fn spent(&self) -> u64 {
        self.spent
    }

    /// Advances by at most `budget` units of work (integration steps, and truth-model
    /// sub-steps for the candidates that ask for the truth model); reports events to
    /// `observer`.
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
            if L > 1 && self.ahead.len > 0 {
                self.run_ahead(left, observer);
                continue;
            }
            let mut flight = match self.flight.take() {
                Some(f) => f,
                None => {
                    let c = self.candidate();
                    if L > 1 && self.start_ahead(&c) {
                        continue;
                    }
                    self.eta = c.eta;
                    match Rollout::of(&self.task, &c.eta) {
                        Ok(r) => Flight {
                            rollout: r.with_violation_cap(c.cap),
                            truth: c.truth.then(|| TruthFlight {
                                state: TruthState::new(TRUTH_SUBSTEPS),
                                queue: [None, None],
                            }),
                            done: None,
                        },
                        Err(e) => {
                            *left -= 1;
                            self.absorb(Evaluation::Failed(e), observer);
                            continue;
                        }
                    }
                }
            };
            if let Some(tf) = flight.truth.as_mut() {
                // The truth model first catches up with the samples emitted so far.
                if tf.state.pending() {
                    *left -= tf.state.integrate(&self.task, *left);
                    self.flight = Some(flight);
                    continue;
                }
                if let Some(slot) = tf.queue.iter_mut().find(|s| s.is_some()) {
                    if let Some((q, t)) = slot.take() {
                        tf.state.begin(&q, t);
                    }
                    self.flight = Some(flight);
                    continue;
                }
                if let Some(o) = flight.done {
                    let evaluation = match (tf.state.error(), tf.state.end_pose(&self.task)) {
                        (None, Some(end)) => Evaluation::Truth(o, end.error_to(self.task.target())),
                        (Some(e), _) => Evaluation::Failed(e),
                        (None, None) => Evaluation::Finished(o),
                    };
                    self.absorb(evaluation, observer);
                    continue;
                }
            }
            let before = flight.rollout.step();
            let result = match flight.truth.as_mut() {
                Some(tf) => {
                    let mut sink = |s: &Sample<N>| {
                        if let Some(slot) = tf.queue.iter_mut().find(|x| x.is_none()) {
                            *slot = Some((s.q, s.t));
                        }
                    };
                    flight.rollout.advance(&self.task, 1, &mut sink)
                }
                None => flight.rollout.advance(&self.task, *left, &mut ()),
            };
            *left = left.saturating_sub(flight.rollout.step().saturating_sub(before));
            match result {
                Ok(Progress::Running { .. }) => self.flight = Some(flight),
                Ok(Progress::Done(o)) if flight.truth.is_some() => {
                    flight.done = Some(o);
                    self.flight = Some(flight);
                }
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
                (self.search.progress().0, 0),
                cost_of(r.best().1),
            ),
            _ => (
                Stage::Search,
                self.search.progress(),
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

    /// The next candidate; its violation cap is applied only once a finished rollout is on
    /// record, so that an abandoned rollout never leaves the search without a result.
    fn candidate(&self) -> Candidate<K> {
        let c = match &self.phase {
            Phase::Refine(r) => r.candidate(),
            _ => self.search.candidate(),
        };
        self.capped(c)
    }

    /// The candidate `j` places after [`Planner::candidate`], if the search knows it and
    /// it needs no truth model (see [`Optimizer::ahead`]).
    fn ahead_candidate(&self, j: usize) -> Option<Candidate<K>> {
        let c = match &self.phase {
            Phase::Refine(r) => r.ahead(j),
            Phase::Search => self.search.ahead(j),
            Phase::Done(_) | Phase::Failed(_) => None,
        }?;
        (!c.truth).then(|| self.capped(c))
    }

    /// `c` with its violation cap lifted while no finished rollout is on record.
    fn capped(&self, c: Candidate<K>) -> Candidate<K> {
        match self.record {
            Record::Found(..) => c,
            Record::Failed(_) => Candidate {
                cap: f64::INFINITY,
                ..c
            },
        }
    }

    /// Starts `c` (the current candidate) and the candidates the search knows after it in
    /// lanes, if it knows at least one (`false`: evaluate `c` alone).
    fn start_ahead(&mut self, c: &Candidate<K>) -> bool {
        // Lanes roll out one segment with the reference discretization and no collision
        // geometry: a motion of several, one integrated by RK4, or a task with geometry goes
        // one candidate at a time.
        let motion = self.task.motion();
        if c.truth
            || motion.segments() > 1
            || motion.integrator() != crate::Integrator::Euler
            || self.task.collision().is_some()
            || self.ahead_candidate(1).is_none()
        {
            return false;
        }
        self.ahead.flush(&self.task);
        if !self.load_lane(0, c) {
            // Rejected before integration: the scalar path reports it.
            return false;
        }
        while self.ahead.len < L {
            match self.ahead_candidate(self.ahead.len) {
                Some(next) if self.load_lane(self.ahead.lane(self.ahead.len), &next) => {}
                _ => break,
            }
        }
        true
    }

    /// Loads `c` into lane `lane` as the next candidate of the window (`false`: η rejected).
    fn load_lane(&mut self, lane: usize, c: &Candidate<K>) -> bool {
        let a = &mut self.ahead;
        let [first, ..] = &c.eta;
        if a.batch.load(lane, &self.task, first, c.cap).is_err() {
            return false;
        }
        if let Some(q) = a.queue.get_mut(lane) {
            *q = *c;
        }
        a.len += 1;
        true
    }

    /// One move of the candidates in lanes: absorb the head's result if its rollout ended
    /// (after checking that the search asks for exactly it, else every lane is dropped),
    /// and load the freed lane with the next candidate the search knows; otherwise advance
    /// the lanes by as many lane-steps as `left` allows. Every lane's integration step
    /// counts one unit; when `left` is smaller than the number of running lanes, only the
    /// first `left` of them (from the head) move.
    fn run_ahead<O: Observer>(&mut self, left: &mut u32, observer: &mut O) {
        let head = self.ahead.head;
        if let Some(end) = self.ahead.batch.take(head) {
            let c = self.ahead.queue.get(head).copied();
            let now = self.candidate();
            let Some(c) = c.filter(|c| same(c, &now)) else {
                // The search changed course: what the lanes hold is not wanted.
                self.ahead.flush(&self.task);
                return;
            };
            self.ahead.head = (head + 1) % L;
            self.ahead.len -= 1;
            self.eta = c.eta;
            let evaluation = match end {
                Ended::Done(o) => Evaluation::Finished(o),
                Ended::Abandoned { phi, .. } => Evaluation::Abandoned(phi),
                Ended::Failed(e) => Evaluation::Failed(e),
            };
            self.absorb(evaluation, observer);
            if !matches!(self.phase, Phase::Search | Phase::Refine(_)) {
                self.ahead.flush(&self.task);
                return;
            }
            // The lane after the window (the one just freed when the window was full).
            if self.ahead.len > 0
                && let Some(next) = self.ahead_candidate(self.ahead.len)
            {
                self.load_lane(self.ahead.lane(self.ahead.len), &next);
            }
            return;
        }
        let running = self.ahead.batch.running();
        if running == 0 {
            // Not expected (the head's lane runs until it ends); start afresh.
            self.ahead.flush(&self.task);
            return;
        }
        let mut hold = [false; L];
        let steps = if *left >= running {
            *left / running
        } else {
            let mut moving = 0;
            for j in 0..self.ahead.len {
                let lane = self.ahead.lane(j);
                let runs = matches!(
                    self.ahead.batch.lane(lane),
                    Some(crate::batch::Lane::Running { .. })
                );
                if runs {
                    if let Some(h) = hold.get_mut(lane) {
                        *h = moving >= *left;
                    }
                    moving += 1;
                }
            }
            1
        };
        let work = E::run(&mut self.ahead.batch, &self.task, steps, hold);
        *left = left.saturating_sub(work.max(1));
    }

    fn plan(&self, stop: Stop, eta: Eta<K>, outcome: Outcome<N>) -> Plan<N, K> {
        let report = self.search.report();
        Plan {
            stop,
            strategy: self.search.strategy(),
            eta,
            outcome,
            iterations: report.iterations,
            rollouts: self.rollouts,
            search_rollouts: self.search_rollouts,
            abandoned: self.abandoned,
            stagnation_events: report.stagnation_events,
            restarts: report.restarts,
            first_hit: self.first_hit,
            search_f: self.search_f,
            refine: None,
        }
    }

    /// `true` if `outcome` (with `truth_f`, the truth model's f, if it was evaluated) meets
    /// what was asked: Φ = 0 and f ≤ σ_e and, when a refinement tolerance is set, f below
    /// it against the planner model or `truth_f` below it against the truth model.
    fn meets(&self, outcome: &Outcome<N>, truth_f: Option<f64>) -> bool {
        let c = &self.config;
        let refined = match (c.refine_tolerance, c.refine_against) {
            (None, _) => true,
            (Some(t), RefineAgainst::Planner) => outcome.f <= t,
            (Some(t), RefineAgainst::Truth) => truth_f.is_some_and(|f| f <= t),
        };
        outcome.phi == 0.0 && outcome.f <= c.tolerance && refined
    }

    /// How a plan ends: [`Stop::Converged`] if it meets what was asked, else how the
    /// stage that ended it stopped ([`Stop::Stalled`] or [`Stop::Exhausted`]).
    fn verdict(&self, met: bool, ended: Stop) -> Stop {
        match (met, ended) {
            (true, _) => Stop::Converged,
            (false, Stop::Stalled) => Stop::Stalled,
            (false, _) => Stop::Exhausted,
        }
    }

    /// Takes the result of the rollout of `self.eta`.
    fn absorb<O: Observer>(&mut self, evaluation: Evaluation<N>, observer: &mut O) {
        self.rollouts += 1;
        if let Evaluation::Abandoned(_) = evaluation {
            self.abandoned += 1;
        }
        if let Some(o) = evaluation
            .outcome()
            .filter(|o| self.first_hit.is_none() && o.phi == 0.0 && o.f <= self.config.tolerance)
        {
            self.first_hit = Some(self.rollouts);
            self.first_hit_f = o.f;
        }
        match self.phase {
            Phase::Search => self.absorb_search(&evaluation, observer),
            Phase::Refine(mut r) => {
                self.phase = match r.absorb(&evaluation, &mut self.stream, observer) {
                    Next::Continue if self.rollouts < self.config.max_rollouts => Phase::Refine(r),
                    Next::Continue | Next::Done(_) => self.refined(&r),
                };
            }
            Phase::Done(_) | Phase::Failed(_) => {}
        }
        let best = match (&self.phase, &self.record) {
            (Phase::Refine(r), _) => cost_of(r.best().1),
            (Phase::Done(p), _) => cost_of(&p.outcome),
            (_, Record::Found(_, o)) => cost_of(o),
            (_, Record::Failed(_)) => Cost::FAILED,
        };
        observer.event(&Event::Evaluated {
            rollouts: self.rollouts,
            best,
        });
    }

    /// The plan of a finished (or budget-stopped) refinement: converged if it met what
    /// was asked.
    fn refined(&self, r: &Refiner<N, K>) -> Phase<N, K> {
        let (eta, best) = r.best();
        let mut report = r.report();
        if !r.done() {
            report.stop = RefineStop::Budget;
        }
        let ended = match report.stop {
            RefineStop::Reached => Stop::Converged,
            RefineStop::Budget => Stop::Exhausted,
            RefineStop::Stalled => Stop::Stalled,
        };
        let stop = self.verdict(self.meets(best, report.truth_f), ended);
        let mut plan = self.plan(stop, one_segment(*eta), *best);
        plan.refine = Some(report);
        Phase::Done(plan)
    }

    fn absorb_search<O: Observer>(&mut self, evaluation: &Evaluation<N>, observer: &mut O) {
        self.search_rollouts += 1;
        self.record = self.record.fold(&self.eta, evaluation);
        let next = match self.search.absorb(evaluation, &mut self.stream, observer) {
            Next::Continue if self.rollouts >= self.config.max_rollouts => {
                Next::Done(Stop::Exhausted)
            }
            other => other,
        };
        self.phase = match (next, self.record) {
            (Next::Continue, _) => Phase::Search,
            // The search's best point: the evaluation that met its tolerance (it dominates
            // everything before it), or the multistart's floor below σ_e.
            (Next::Done(Stop::Converged), Record::Found(eta, o)) => {
                self.eta = eta;
                self.search_f = o.f;
                self.converged(o)
            }
            (Next::Done(ended), Record::Found(eta, o)) => {
                self.search_f = o.f;
                // The multistart searched to a refinement tolerance it did not reach: the
                // plan is not converged, even if σ_e was met.
                let mut plan = self.plan(self.verdict(self.meets(&o, None), ended), eta, o);
                plan.refine = self.search_refinement(&o, ended);
                Phase::Done(plan)
            }
            (Next::Done(_), Record::Failed(e)) => Phase::Failed(e),
        };
    }

    /// After the search hit its tolerance with the rollout `o` of `self.eta`: the
    /// refinement that follows, if any and not already met, else the plan.
    fn converged(&mut self, o: Outcome<N>) -> Phase<N, K> {
        match self.search.follow_up(&self.config, self.eta, o) {
            Some(r) if r.done() => self.refined(&r),
            Some(_) if self.rollouts >= self.config.max_rollouts => {
                let stop = self.verdict(self.meets(&o, None), Stop::Exhausted);
                Phase::Done(self.plan(stop, self.eta, o))
            }
            Some(r) => Phase::Refine(r),
            None => {
                let stop = self.verdict(self.meets(&o, None), Stop::Converged);
                let mut plan = self.plan(stop, self.eta, o);
                plan.refine = self.search_refinement(&o, Stop::Converged);
                Phase::Done(plan)
            }
        }
    }

    /// The search's own refinement, as a report ([`Search::search_refinement`]).
    fn search_refinement(&self, best: &Outcome<N>, ended: Stop) -> Option<RefineReport> {
        let hit = self.first_hit.map(|h| (h, self.first_hit_f));
        self.search
            .search_refinement(&self.config, hit, best, self.rollouts, ended)
    }
}
