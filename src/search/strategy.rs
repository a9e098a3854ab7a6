//! The strategy seam: `[planner] strategy` resolved once, to the one search that runs.
//!
//! Owns [`Strategy`] (the setting, with its one name-and-wire-code table), the [`Method`]
//! trait (what the planner asks of a strategy besides the [`Optimizer`] seam), [`Search`]
//! (the running search: one arm per strategy, so only the chosen one's state occupies
//! memory) and [`SearchReport`] (the counters a plan reports).
//!
//! [`Search`] is built in place by [`Search::start`] when the planner (re)starts, and is
//! itself an [`Optimizer`] and a [`Method`]: the planner never asks which strategy runs.
//! It answers for
//! - the f the search stops at ([`Method::tolerance`]: σ_e, or tighter for a strategy that
//!   refines as it searches);
//! - the refinement that follows a hit ([`Search::follow_up`]);
//! - what the plan reports ([`Method::report`], [`Search::search_refinement`]).
//!
//! **Adding a strategy** is one file and one arm: a module of this folder with a
//! fixed-size state implementing [`Optimizer`] and [`Method`] (its draw order documented),
//! a variant of [`Strategy`] with its row in [`Strategy::entry`], and an arm of [`Search`]
//! (each `match` below has one line per strategy). The test-only random search
//! ([`crate::search`]'s `random_search`, compiled for the core's unit tests) is added
//! exactly that way.

use crate::config::{PlannerConfig, RefineAgainst};
use crate::cpso::Cpso;
use crate::error::Error;
use crate::model::Robot;
use crate::multistart::Multistart;
use crate::optimizer::{Candidate, Evaluation, Next, Observer, Optimizer, Stop};
use crate::random::Stream;
use crate::refine::{RefineReport, RefineStop, Refiner};
use crate::rollout::Outcome;
use crate::swarm::Swarm;

/// How the planner searches η (`[planner] strategy`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "lowercase")
)]
pub enum Strategy {
    /// Multistart Levenberg–Marquardt on the unit sphere of η ([`crate::multistart`]): the
    /// default.
    Multistart,
    /// The paper's constrained PSO (spec §7, [`crate::cpso`]), then the optional
    /// refinement ([`crate::refine`]).
    Cpso,
    /// A test-only random search (the core's unit tests): the proof that a strategy is one
    /// file and one arm.
    #[cfg(test)]
    Random,
}

impl Strategy {
    /// Every strategy, in wire-code order.
    pub const ALL: &'static [Strategy] = &[
        Strategy::Multistart,
        Strategy::Cpso,
        #[cfg(test)]
        Strategy::Random,
    ];

    /// The one table: task-file name and wire code (task block, C ABI `rl_plan.strategy`).
    const fn entry(self) -> (&'static str, u32) {
        match self {
            Strategy::Multistart => ("multistart", 0),
            Strategy::Cpso => ("cpso", 1),
            #[cfg(test)]
            Strategy::Random => ("random", 2),
        }
    }

    /// The task-file name (`"multistart"`, `"cpso"`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        self.entry().0
    }

    /// The wire code (u32) of the task block and the C ABI.
    #[must_use]
    pub const fn code(self) -> u32 {
        self.entry().1
    }

    /// The strategy of a task-file name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|s| s.name() == name)
    }

    /// The strategy of a wire code.
    #[must_use]
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.iter().copied().find(|s| s.code() == code)
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
    /// Starts the search in place for `config` on `robot`, drawing what it draws at its
    /// start from `stream` (the strategy documents its draw order).
    ///
    /// # Errors
    /// A bad setting; the search is then finished with nothing found.
    fn start(
        &mut self,
        config: &PlannerConfig,
        robot: &Robot<N>,
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

/// The running search: the chosen strategy's state, and only its.
// The variants differ in size by design: the enum is the one place a strategy's state
// lives, in place (no allocation to box into), and the planner pays for the largest.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Search<const N: usize, const K: usize, const P: usize> {
    /// [`Strategy::Multistart`].
    Multistart(Multistart<N, K>),
    /// [`Strategy::Cpso`] over a swarm of capacity `P`.
    Cpso(Cpso<K, P>),
    /// [`Strategy::Random`] (test-only).
    #[cfg(test)]
    Random(crate::search::random_search::RandomSearch<N, K>),
}

/// `$body` with `$s` bound to the running strategy's state, whichever it is.
macro_rules! each {
    ($search:expr, $s:ident => $body:expr) => {
        match $search {
            Search::Multistart($s) => $body,
            Search::Cpso($s) => $body,
            #[cfg(test)]
            Search::Random($s) => $body,
        }
    };
}

impl<const N: usize, const K: usize, const P: usize> Search<N, K, P> {
    /// No search (the multistart's placeholder), `const`, for statically allocated planners.
    pub const IDLE: Self = Search::Multistart(Multistart::IDLE);

    /// Makes `self` the search `config.strategy` names and starts it in place (the state of
    /// another strategy is dropped; nothing search-sized passes through the stack).
    ///
    /// # Errors
    /// As [`Method::start`].
    pub fn start(
        &mut self,
        config: &PlannerConfig,
        robot: &Robot<N>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        if self.strategy() != config.strategy {
            *self = match config.strategy {
                Strategy::Multistart => Search::Multistart(Multistart::IDLE),
                Strategy::Cpso => Search::Cpso(Cpso::IDLE),
                #[cfg(test)]
                Strategy::Random => {
                    Search::Random(crate::search::random_search::RandomSearch::IDLE)
                }
            };
        }
        each!(self, s => Method::<N, K>::start(s, config, robot, stream))
    }

    /// The strategy that runs.
    #[must_use]
    pub fn strategy(&self) -> Strategy {
        match self {
            Search::Multistart(_) => Strategy::Multistart,
            Search::Cpso(_) => Strategy::Cpso,
            #[cfg(test)]
            Search::Random(_) => Strategy::Random,
        }
    }

    /// The swarm, if C-PSO runs.
    #[must_use]
    pub fn swarm(&self) -> Option<&Swarm<K, P>> {
        match self {
            Search::Cpso(c) => Some(c.swarm()),
            _ => None,
        }
    }

    /// The refinement that follows a hit at `eta` (rollout `outcome`) under `config`: none
    /// without a refinement tolerance; against the truth model whenever it is asked for;
    /// against the planner model unless the search refines as it searches.
    #[must_use]
    pub fn follow_up(
        &self,
        config: &PlannerConfig,
        eta: [[f64; 2]; K],
        outcome: Outcome<N>,
    ) -> Option<Refiner<N, K>> {
        let rc = config.refine()?;
        match config.refine_against {
            RefineAgainst::Truth => Some(Refiner::against_truth(rc, eta, outcome)),
            RefineAgainst::Planner if self.refines_as_it_searches() => None,
            RefineAgainst::Planner => Some(Refiner::new(rc, eta, outcome)),
        }
    }

    /// For a search that refines as it searches: its refinement against the planner model,
    /// reported as a refinement from the first rollout that met σ_e (`hit` rollouts, f
    /// `hit_f`) to `best` after `rollouts`, the search having ended `ended` (`None` if it
    /// does not refine as it searches, without a refinement tolerance, against the truth
    /// model, or without a hit).
    #[must_use]
    pub fn search_refinement(
        &self,
        config: &PlannerConfig,
        hit: Option<(u32, f64)>,
        best: &Outcome<N>,
        rollouts: u32,
        ended: Stop,
    ) -> Option<RefineReport> {
        let (true, Some(tolerance), RefineAgainst::Planner, Some((hit, f_start))) = (
            self.refines_as_it_searches(),
            config.refine_tolerance,
            config.refine_against,
            hit,
        ) else {
            return None;
        };
        Some(RefineReport {
            iterations: self.report().iterations,
            rollouts: rollouts.saturating_sub(hit),
            stop: match (best.phi == 0.0 && best.f <= tolerance, ended) {
                (true, _) => RefineStop::Reached,
                (false, Stop::Stalled) => RefineStop::Stalled,
                (false, _) => RefineStop::Budget,
            },
            f_start,
            truth_f: None,
        })
    }
}

impl<const N: usize, const K: usize, const P: usize> Method<N, K> for Search<N, K, P> {
    fn start(
        &mut self,
        config: &PlannerConfig,
        robot: &Robot<N>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        Search::start(self, config, robot, stream)
    }

    fn tolerance(&self) -> f64 {
        each!(self, s => Method::<N, K>::tolerance(s))
    }

    fn refines_as_it_searches(&self) -> bool {
        each!(self, s => Method::<N, K>::refines_as_it_searches(s))
    }

    fn report(&self) -> SearchReport {
        each!(self, s => Method::<N, K>::report(s))
    }
}

impl<const N: usize, const K: usize, const P: usize> Optimizer<N, K> for Search<N, K, P> {
    fn candidate(&self) -> Candidate<K> {
        each!(self, s => Optimizer::<N, K>::candidate(s))
    }

    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        stream: &mut Stream,
        observer: &mut O,
    ) -> Next {
        each!(self, s => Optimizer::<N, K>::absorb(s, evaluation, stream, observer))
    }

    fn progress(&self) -> (u32, u32) {
        each!(self, s => Optimizer::<N, K>::progress(s))
    }

    fn ahead(&self, j: usize) -> Option<Candidate<K>> {
        each!(self, s => Optimizer::<N, K>::ahead(s, j))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Names and wire codes are unique and round-trip.
    #[test]
    fn names_and_codes_round_trip() {
        for (i, s) in Strategy::ALL.iter().enumerate() {
            assert_eq!(Strategy::from_name(s.name()), Some(*s));
            assert_eq!(Strategy::from_code(s.code()), Some(*s));
            assert_eq!(s.code() as usize, i);
        }
        assert_eq!(Strategy::from_name("pso"), None);
        assert_eq!(Strategy::from_code(99), None);
    }
}
