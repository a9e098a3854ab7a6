//! The planner that flies: C-PSO (spec §7) followed by optional refinement, as one
//! resumable, budgeted, deterministic state machine.
//!
//! Owns [`Planner`], its configuration [`PlannerConfig`], and what it reports ([`Status`],
//! [`Plan`], [`Event`]). The planner evaluates one η at a time with a [`Rollout`] it keeps
//! between calls. [`Planner::step`] performs at most `budget` integration steps, so a
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
//! **Early abandonment** (exact): each rollout carries a violation cap
//! ([`Rollout::with_violation_cap`]) above which its result could change no decision: the
//! particle's personal-best Φ during C-PSO, 0 for a refinement trial, none for a Jacobian
//! column. Φ of the samples so far never exceeds Φ of the whole rollout, so a rollout that
//! passes its cap is stopped there; η, f, iterations, rollout counts and every later random
//! draw are bit-identical to evaluating it to the end (the golden records, blessed before
//! this existed, replay unchanged). [`Plan::abandoned`] counts them.
//!
//! Iterations are counted as in the paper: the initial generation is iteration 0, and
//! `iterations` is the number of generations after it. A feasible particle with
//! `f ≤ tolerance` stops C-PSO at once, even in the middle of a generation.

use crate::error::{Error, Param};
use crate::random::Stream;
use crate::refine::{Next, RefineConfig, RefineReport, Refiner};
use crate::rollout::{Outcome, Progress, Rollout};
use crate::swarm::{Cost, Swarm, SwarmConfig};
use crate::task::Task;

/// Everything the planner needs besides the task.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PlannerConfig {
    /// The swarm.
    pub swarm: SwarmConfig,
    /// σ_e: success when a feasible particle has `f ≤ tolerance` (> 0).
    pub tolerance: f64,
    /// Seed of the random stream.
    pub seed: u64,
    /// Refinement after C-PSO succeeds (`None`: none).
    pub refine: Option<RefineConfig>,
}

impl PlannerConfig {
    /// The spec §7 settings for the reference task: 40 particles, σ_e = 0.05, no refinement.
    #[must_use]
    pub const fn reference(seed: u64) -> Self {
        Self {
            swarm: SwarmConfig::reference(40),
            tolerance: 0.05,
            seed,
            refine: None,
        }
    }

    /// Checks every setting against a capacity of `capacity` particles.
    ///
    /// # Errors
    /// The first bad setting, named.
    pub fn validate(&self, capacity: usize) -> Result<(), Error> {
        self.swarm.validate(capacity)?;
        if !self.tolerance.is_finite() {
            return Err(Error::NotFinite(Param::Tolerance));
        }
        if self.tolerance <= 0.0 {
            return Err(Error::NotPositive(Param::Tolerance));
        }
        if let Some(r) = &self.refine {
            r.validate()?;
        }
        Ok(())
    }
}

/// Which stage the planner is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stage {
    /// C-PSO.
    Swarm,
    /// Levenberg–Marquardt refinement.
    Refine,
}

/// Where a running planner is.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Running {
    /// Current stage.
    pub stage: Stage,
    /// Current generation (0 = initial).
    pub iteration: u32,
    /// Particle being evaluated.
    pub particle: u32,
    /// Rollouts finished so far.
    pub rollouts: u32,
    /// Best cost so far.
    pub best: Cost,
}

/// A plan: the chosen η and the rollout that was evaluated for it.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Plan<const N: usize, const K: usize> {
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

/// What [`Planner::step`] returns.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Status<const N: usize, const K: usize> {
    /// Budget spent, more to do.
    Running(Running),
    /// A feasible η with `f ≤ tolerance` (refined if configured).
    Converged(Plan<N, K>),
    /// m_max generations without success: the best feasible η found (or the least
    /// violating one if none is feasible).
    Exhausted(Plan<N, K>),
}

/// Something the planner did, for logs and histories.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// A generation was evaluated completely.
    Generation {
        /// Its number (0 = initial).
        iteration: u32,
        /// gbest's cost after it.
        best: Cost,
        /// Rollouts so far.
        rollouts: u32,
    },
    /// The stagnation alarm fired after generation `iteration`.
    Stagnation {
        /// The generation.
        iteration: u32,
    },
    /// C-PSO met σ_e during generation `iteration`.
    SwarmConverged {
        /// The generation.
        iteration: u32,
        /// f of the successful particle.
        f: f64,
    },
    /// A refinement trial was evaluated.
    RefineTrial {
        /// f of the best point after the trial.
        f: f64,
        /// Damping after the trial.
        lambda: f64,
    },
}

/// Receives planner events. Implemented for `()` (discard) and `FnMut(&Event)`.
pub trait Observer {
    /// Called as things happen.
    fn event(&mut self, e: &Event);
}

impl Observer for () {
    fn event(&mut self, _: &Event) {}
}

impl<F: FnMut(&Event)> Observer for F {
    fn event(&mut self, e: &Event) {
        self(e);
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Phase<const N: usize, const K: usize> {
    Swarm { iteration: u32, particle: usize },
    Refine(Refiner<N, K>),
    Done(Status<N, K>),
    Failed(Error),
}

/// The planner for `N` joints, null-space dimension `K = N − 3` and a swarm capacity of `P`
/// particles.
#[derive(Debug, Clone, PartialEq)]
pub struct Planner<const N: usize, const K: usize, const P: usize> {
    task: Task<N, K>,
    config: PlannerConfig,
    stream: Stream,
    swarm: Swarm<K, P>,
    phase: Phase<N, K>,
    rollout: Option<Rollout<N, K>>,
    /// η of the rollout in flight (or last evaluated).
    eta: [[f64; 2]; K],
    /// Best evaluated point of C-PSO, by domination.
    best: Option<([[f64; 2]; K], Outcome<N>)>,
    rollouts: u32,
    swarm_rollouts: u32,
    abandoned: u32,
    iterations: u32,
    swarm_f: f64,
    last_error: Option<Error>,
    /// Budget consumed so far (integration steps, plus one per rejected candidate).
    spent: u64,
}

fn cost_of<const N: usize>(o: &Outcome<N>) -> Cost {
    Cost { phi: o.phi, f: o.f }
}

/// How the rollout of one candidate ended.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Evaluation<const N: usize> {
    Finished(Outcome<N>),
    /// Stopped with Φ of its samples so far (rad) above the cap it was given.
    Abandoned(f64),
    Failed(Error),
}

impl<const N: usize, const K: usize, const P: usize> Planner<N, K, P> {
    /// A planner without a task, `const`: flight software places it in static memory and
    /// gives it work with [`Planner::reset`], so the 20-odd KiB of state never pass through
    /// the stack. [`Planner::step`] returns [`Error::NotInitialized`] until then.
    pub const IDLE: Self = Self {
        task: Task::IDLE,
        config: PlannerConfig::reference(0),
        stream: Stream::IDLE,
        swarm: Swarm::IDLE,
        phase: Phase::Failed(Error::NotInitialized),
        rollout: None,
        eta: [[0.0; 2]; K],
        best: None,
        rollouts: 0,
        swarm_rollouts: 0,
        abandoned: 0,
        iterations: 0,
        swarm_f: f64::INFINITY,
        last_error: None,
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
        self.best = None;
        self.eta = [[0.0; 2]; K];
        self.rollouts = 0;
        self.swarm_rollouts = 0;
        self.abandoned = 0;
        self.iterations = 0;
        self.swarm_f = f64::INFINITY;
        self.last_error = None;
        self.spent = 0;
        if let Err(e) = config.validate(P) {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.config = config;
        self.stream = Stream::new(config.seed);
        if let Err(e) = self.swarm.reset(&config.swarm, &mut self.stream) {
            self.phase = Phase::Failed(e);
            return Err(e);
        }
        self.phase = Phase::Swarm {
            iteration: 0,
            particle: 0,
        };
        Ok(())
    }

    /// A planner for `task`, its swarm at its initial positions.
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
    ///     _ => unreachable!(),
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
    ///     match planner.step(100_000, &mut ()).unwrap() {
    ///         Status::Running(_) => continue,
    ///         Status::Converged(plan) => break plan,
    ///         Status::Exhausted(_) => panic!("no plan"),
    ///     }
    /// };
    /// assert!(plan.outcome.f <= 0.05 && plan.outcome.phi == 0.0);
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
        &self.swarm
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
                Phase::Done(s) => return Ok(s),
                Phase::Failed(e) => return Err(e),
                _ => {}
            }
            let mut rollout = match self.rollout.take() {
                Some(r) => r,
                None => {
                    self.eta = self.next_eta();
                    match Rollout::new(&self.task, &self.eta) {
                        Ok(r) => r.with_violation_cap(self.violation_cap()),
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
            Phase::Done(s) => Ok(s),
            Phase::Failed(e) => Err(e),
            _ => Ok(Status::Running(self.running())),
        }
    }

    fn running(&self) -> Running {
        let (stage, iteration, particle) = match self.phase {
            Phase::Swarm {
                iteration,
                particle,
            } => (Stage::Swarm, iteration, particle as u32),
            _ => (Stage::Refine, self.iterations, 0),
        };
        let best = match &self.phase {
            Phase::Refine(r) => cost_of(r.best().1),
            _ => self.best.map_or(Cost::FAILED, |(_, o)| cost_of(&o)),
        };
        Running {
            stage,
            iteration,
            particle,
            rollouts: self.rollouts,
            best,
        }
    }

    /// The Φ above which the rollout of the next candidate cannot change any decision.
    ///
    /// - A swarm particle: its personal best's Φ. A finished `Φ > pbest.Φ` never dominates
    ///   pbest (feasible beats infeasible; among infeasible, smaller Φ first), so pbest
    ///   stays; nor can it dominate the planner's best (which dominates or equals every
    ///   pbest), nor meet σ_e (which needs Φ = 0). A particle without a finished
    ///   evaluation has pbest Φ = ∞ and is never cut short.
    /// - A refinement trial: 0 (only `Φ = 0` is accepted). Jacobian columns: ∞ (every
    ///   column is used).
    fn violation_cap(&self) -> f64 {
        match &self.phase {
            Phase::Swarm { particle, .. } => self
                .swarm
                .particle(*particle)
                .map_or(f64::INFINITY, |p| p.best_cost.phi),
            Phase::Refine(r) if r.at_trial() => 0.0,
            _ => f64::INFINITY,
        }
    }

    fn next_eta(&self) -> [[f64; 2]; K] {
        match &self.phase {
            Phase::Swarm { particle, .. } => self
                .swarm
                .particle(*particle)
                .map_or([[0.0; 2]; K], |p| p.position),
            Phase::Refine(r) => r.next_eta(),
            _ => self.eta,
        }
    }

    fn plan(
        &self,
        eta: [[f64; 2]; K],
        outcome: Outcome<N>,
        refine: Option<RefineReport>,
    ) -> Plan<N, K> {
        Plan {
            eta,
            outcome,
            iterations: self.iterations,
            rollouts: self.rollouts,
            swarm_rollouts: self.swarm_rollouts,
            abandoned: self.abandoned,
            stagnation_events: self.swarm.stagnation_events(),
            swarm_f: self.swarm_f,
            refine,
        }
    }

    /// Takes the result of the rollout of `self.eta`.
    fn absorb<O: Observer>(&mut self, result: Evaluation<N>, observer: &mut O) {
        self.rollouts += 1;
        match result {
            Evaluation::Failed(e) => self.last_error = Some(e),
            Evaluation::Abandoned(_) => self.abandoned += 1,
            Evaluation::Finished(_) => {}
        }
        match self.phase {
            Phase::Swarm {
                iteration,
                particle,
            } => self.absorb_swarm(iteration, particle, result, observer),
            Phase::Refine(mut r) => {
                let trial = r.at_trial();
                let outcome = match &result {
                    Evaluation::Finished(o) => Some(o),
                    Evaluation::Abandoned(_) | Evaluation::Failed(_) => None,
                };
                let next = r.absorb(outcome);
                let (eta, best) = r.best();
                if trial {
                    observer.event(&Event::RefineTrial {
                        f: best.f,
                        lambda: r.lambda(),
                    });
                }
                self.phase = match next {
                    Next::Continue => Phase::Refine(r),
                    Next::Done => {
                        Phase::Done(Status::Converged(self.plan(*eta, *best, Some(r.report()))))
                    }
                };
            }
            Phase::Done(_) | Phase::Failed(_) => {}
        }
    }

    fn absorb_swarm<O: Observer>(
        &mut self,
        iteration: u32,
        particle: usize,
        result: Evaluation<N>,
        observer: &mut O,
    ) {
        self.swarm_rollouts += 1;
        let cost = match &result {
            Evaluation::Finished(o) => cost_of(o),
            // A lower bound: Φ only grows along the rest of the rollout.
            Evaluation::Abandoned(phi) => Cost {
                phi: *phi,
                f: f64::INFINITY,
            },
            Evaluation::Failed(_) => Cost::FAILED,
        };
        self.swarm.record(particle, cost);
        if let Evaluation::Finished(o) = &result {
            let better = self
                .best
                .as_ref()
                .is_none_or(|(_, b)| cost.dominates(&cost_of(b)));
            if better {
                self.best = Some((self.eta, *o));
            }
            if cost.feasible() && o.f <= self.config.tolerance {
                self.iterations = iteration;
                self.swarm_f = o.f;
                observer.event(&Event::SwarmConverged { iteration, f: o.f });
                self.phase = match self.config.refine {
                    Some(rc) => {
                        let r = Refiner::new(rc, self.eta, *o);
                        if r.done() {
                            Phase::Done(Status::Converged(self.plan(
                                self.eta,
                                *o,
                                Some(r.report()),
                            )))
                        } else {
                            Phase::Refine(r)
                        }
                    }
                    None => Phase::Done(Status::Converged(self.plan(self.eta, *o, None))),
                };
                return;
            }
        }
        if particle + 1 < self.swarm.count() {
            self.phase = Phase::Swarm {
                iteration,
                particle: particle + 1,
            };
            return;
        }
        // End of a generation.
        let alarm = self.swarm.end_generation();
        let (_, best) = self.swarm.gbest();
        self.iterations = iteration;
        observer.event(&Event::Generation {
            iteration,
            best,
            rollouts: self.rollouts,
        });
        if alarm {
            observer.event(&Event::Stagnation { iteration });
        }
        if iteration >= self.config.swarm.max_iterations {
            self.phase = match self.best {
                Some((eta, o)) => {
                    self.swarm_f = o.f;
                    Phase::Done(Status::Exhausted(self.plan(eta, o, None)))
                }
                None => Phase::Failed(self.last_error.unwrap_or(Error::EtaZero)),
            };
            return;
        }
        self.swarm.advance(iteration + 1, &mut self.stream);
        self.phase = Phase::Swarm {
            iteration: iteration + 1,
            particle: 0,
        };
    }
}
