//! The seam between the planner and the optimizers that search η: ask for a candidate,
//! tell the outcome of its rollout.
//!
//! Owns the [`Optimizer`] trait and what crosses it: [`Candidate`] (the η to evaluate and
//! the violation cap above which its result cannot matter), [`Evaluation`] (how its
//! rollout ended), [`Next`] and [`Stop`] (whether the optimizer is done, and how), and the
//! [`Event`]s an optimizer reports to an [`Observer`]. An optimizer never runs a rollout:
//! the planner ([`crate::planner`]) evaluates every candidate under its budget, so each
//! optimizer is resumable and budgeted for free. The C-PSO of the paper
//! ([`crate::cpso::Cpso`]) and the Levenberg–Marquardt refinement
//! ([`crate::refine::Refiner`]) implement it; a strategy also implements
//! [`Method`] and takes one arm of [`crate::strategy::Search`].
//!
//! Contract: the planner calls [`Optimizer::candidate`], evaluates it, then calls
//! [`Optimizer::absorb`] exactly once with the evaluation, until `absorb` returns
//! [`Next::Done`]. Every random draw an optimizer makes happens inside `absorb`, from the
//! planner's one stream, at points the optimizer documents (golden records depend on them).

use crate::config::PlannerConfig;
use crate::error::Error;
use crate::geometry::PoseError;
use crate::random::Stream;
use crate::rollout::Outcome;
use crate::swarm::Cost;
use crate::task::Task;
use crate::trajectory::{Eta, one_segment};

/// What the planner evaluates next.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate<const K: usize> {
    /// η as pairs `(a_i, b_i)`, one set per segment of the task's motion.
    pub eta: Eta<K>,
    /// Violation cap (rad): a rollout whose Φ exceeds it may be stopped early
    /// ([`crate::Rollout::with_violation_cap`]) because its result cannot change any
    /// decision of the optimizer; `f64::INFINITY` never stops early.
    pub cap: f64,
    /// Evaluate the truth model along the rollout too ([`Evaluation::Truth`]): the
    /// end-pose error with the integrated base attitude (spec §11). Costs about
    /// `1 + truth sub-steps` times a plain rollout.
    pub truth: bool,
}

impl<const K: usize> Candidate<K> {
    /// A candidate of one segment without the truth model.
    #[must_use]
    pub const fn plain(eta: [[f64; 2]; K], cap: f64) -> Self {
        Self::segmented(one_segment(eta), cap)
    }

    /// A candidate of one η per segment without the truth model.
    #[must_use]
    pub const fn segmented(eta: Eta<K>, cap: f64) -> Self {
        Self {
            eta,
            cap,
            truth: false,
        }
    }
}

/// How the rollout of a candidate ended.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Evaluation<const N: usize> {
    /// It finished.
    Finished(Outcome<N>),
    /// It finished, with the truth model along (the candidate asked for it): the outcome
    /// and the truth-model end-pose error against the target.
    Truth(Outcome<N>, PoseError),
    /// It was stopped with Φ of its samples so far (rad, a lower bound of the whole
    /// rollout's Φ) above the candidate's cap.
    Abandoned(f64),
    /// It failed (rank loss, non-finite state) or η was rejected before integration.
    Failed(Error),
}

impl<const N: usize> Evaluation<N> {
    /// The cost the evaluation establishes: the outcome's, a lower bound (Φ, f = ∞) for an
    /// abandoned rollout, [`Cost::FAILED`] for a failed one.
    #[must_use]
    pub fn cost(&self) -> Cost {
        match self {
            Evaluation::Finished(o) | Evaluation::Truth(o, _) => Cost { phi: o.phi, f: o.f },
            Evaluation::Abandoned(phi) => Cost {
                phi: *phi,
                f: f64::INFINITY,
            },
            Evaluation::Failed(_) => Cost::FAILED,
        }
    }

    /// The outcome, if the rollout finished.
    #[must_use]
    pub fn outcome(&self) -> Option<&Outcome<N>> {
        match self {
            Evaluation::Finished(o) | Evaluation::Truth(o, _) => Some(o),
            Evaluation::Abandoned(_) | Evaluation::Failed(_) => None,
        }
    }

    /// The truth-model end-pose error, if it was evaluated.
    #[must_use]
    pub fn truth(&self) -> Option<&PoseError> {
        match self {
            Evaluation::Truth(_, e) => Some(e),
            _ => None,
        }
    }
}

/// How an optimizer ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Stop {
    /// The last candidate is feasible (Φ = 0) with `f` within the tolerance. For a plan:
    /// the plan meets what was asked (σ_e, and the refinement tolerance when one is set).
    Converged,
    /// The optimizer's budget is spent: the planner reports the best point it evaluated.
    Exhausted,
    /// The optimizer can get no closer (no descent left at rounding level) before its
    /// budget is spent: the planner reports the best point it evaluated.
    Stalled,
}

impl Stop {
    /// `"converged"`, `"exhausted"` or `"stalled"`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Stop::Converged => "converged",
            Stop::Exhausted => "exhausted",
            Stop::Stalled => "stalled",
        }
    }
}

/// What an optimizer says after absorbing an evaluation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Next {
    /// Evaluate [`Optimizer::candidate`] next.
    Continue,
    /// Finished.
    Done(Stop),
}

/// An ask/tell optimizer of η for `N` joints and null-space dimension `K`.
pub trait Optimizer<const N: usize, const K: usize> {
    /// The candidate to evaluate next (the same until [`Optimizer::absorb`] is called).
    fn candidate(&self) -> Candidate<K>;

    /// Takes the evaluation of [`Optimizer::candidate`]; may draw from `stream` and report
    /// to `observer`.
    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        stream: &mut Stream,
        observer: &mut O,
    ) -> Next;

    /// Where the optimizer is, for progress reports: its iteration and the index of the
    /// candidate within it.
    fn progress(&self) -> (u32, u32);

    /// The candidate `j ≥ 1` places after [`Optimizer::candidate`], if it is known already:
    /// the one the optimizer will ask for after `j` more evaluations, unless one of them
    /// ends the search or changes its course (C-PSO: the rest of a generation; the
    /// multistart: the rest of a screening batch or of a difference Jacobian). The planner
    /// evaluates such candidates ahead, side by side in lanes ([`crate::batch`]), and uses
    /// a result only if the optimizer then asks for exactly that candidate (η, cap and
    /// truth flag, bit for bit), so a wrong guess costs work, never a different result.
    /// Must not draw randomness. Default: none known.
    fn ahead(&self, j: usize) -> Option<Candidate<K>> {
        let _ = j;
        None
    }
}

/// The counters of a search that a plan reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SearchReport {
    /// C-PSO: generations after the initial one; multistart: accepted LM steps.
    pub iterations: u32,
    /// C-PSO's stagnation alarms (0 for other strategies).
    pub stagnation_events: u32,
    /// The multistart's LM starts after the first (0 for other strategies).
    pub restarts: u32,
}

/// What the planner asks of a strategy besides the [`Optimizer`] seam.
pub trait Method<const N: usize, const K: usize>: Optimizer<N, K> {
    /// Starts the search in place for `config` on `task` (its joint limits and its motion
    /// family), drawing what it draws at its start from `stream` (the strategy documents
    /// its draw order).
    ///
    /// # Errors
    /// A bad setting; the search is then finished with nothing found.
    fn start(
        &mut self,
        config: &PlannerConfig,
        task: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error>;

    /// The f (m and rad, as σ_e) at which the search stops with a hit.
    fn tolerance(&self) -> f64;

    /// `true` if the search drives f below a refinement tolerance itself (against the
    /// planner model), so no separate refinement against the planner model follows.
    fn refines_as_it_searches(&self) -> bool {
        false
    }

    /// Counters for the plan.
    fn report(&self) -> SearchReport;
}

/// Something the planner did, for logs and histories.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Event {
    /// A rollout was evaluated (every candidate of every stage).
    Evaluated {
        /// Rollouts so far.
        rollouts: u32,
        /// The best cost so far (the search's best, then refinement's).
        best: Cost,
    },
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
