//! The strategy seam: `[planner] strategy` resolved once, to the one search that runs.
//!
//! Owns [`Search`]: the running search, one arm per [`Strategy`] (the setting, with its one
//! name-and-wire-code table, in [`crate::config`]), so only the chosen strategy's state
//! occupies memory. Each arm implements [`Optimizer`] and [`Method`] (what the planner asks
//! of a strategy besides the ask/tell seam, in [`crate::optimizer`]).
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
//! a variant of [`Strategy`] with its row in its one table, and an arm of [`Search`] (each
//! `match` below has one line per strategy). The test-only random search
//! ([`crate::search`]'s `random_search`, compiled for the core's unit tests) is added
//! exactly that way.

use crate::config::{PlannerConfig, RefineAgainst, Strategy};
use crate::cpso::Cpso;
use crate::error::Error;
use crate::multistart::Multistart;
use crate::optimizer::{
    Candidate, Evaluation, Method, Next, Observer, Optimizer, SearchReport, Stop,
};
use crate::random::Stream;
use crate::refine::{RefineReport, RefineStop, Refiner};
use crate::rollout::Outcome;
use crate::swarm::Swarm;
use crate::task::Task;
use crate::trajectory::Eta;

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
    pub const IDLE: Self = Self::MULTISTART;
    const MULTISTART: Self = Search::Multistart(Multistart::IDLE);
    const CPSO: Self = Search::Cpso(Cpso::IDLE);
    #[cfg(test)]
    const RANDOM: Self = Search::Random(crate::search::random_search::RandomSearch::IDLE);

    /// Makes `self` the search `config.strategy` names and starts it in place (the state of
    /// another strategy is dropped; nothing search-sized passes through the stack).
    ///
    /// # Errors
    /// As [`Method::start`].
    pub fn start(
        &mut self,
        config: &PlannerConfig,
        task: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        // Each arm assigns a constant, which the compiler copies from read-only memory
        // straight into `self` (a `match` that yields the value builds it on the stack
        // first: 17 KB on the flight target).
        if self.strategy() != config.strategy {
            match config.strategy {
                Strategy::Multistart => *self = Self::MULTISTART,
                Strategy::Cpso => *self = Self::CPSO,
                #[cfg(test)]
                Strategy::Random => *self = Self::RANDOM,
            }
        }
        each!(self, s => Method::<N, K>::start(s, config, task, stream))
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
        eta: Eta<K>,
        outcome: Outcome<N>,
    ) -> Option<Refiner<N, K>> {
        let rc = config.refine()?;
        // The refiners step on one segment's η (the planner refuses them for several).
        let [eta, ..] = eta;
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
        task: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        Search::start(self, config, task, stream)
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
