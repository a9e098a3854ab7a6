//! A test-only strategy: pure random search of η's direction. It exists to prove the seam:
//! a strategy is this one file plus one arm of [`crate::strategy::Search`] (and its row in
//! [`crate::config::Strategy`]'s table); the planner needed no change.
//!
//! Owns [`RandomSearch`]. Every candidate is `2u − 1` per component (a₁, b₁, …, a_K, b_K),
//! drawn when the search starts and after each evaluation; the search stops at the first
//! feasible rollout with `f ≤ σ_e` or after `max_rollouts` evaluations.

use crate::config::PlannerConfig;
use crate::error::Error;
use crate::optimizer::{Candidate, Evaluation, Next, Observer, Optimizer, Stop};
use crate::optimizer::{Method, SearchReport};
use crate::random::Stream;
use crate::task::Task;

/// Random search over η (test-only).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RandomSearch<const N: usize, const K: usize> {
    next: [[f64; 2]; K],
    tolerance: f64,
    max_rollouts: u32,
    rollouts: u32,
}

impl<const N: usize, const K: usize> RandomSearch<N, K> {
    /// No search.
    pub const IDLE: Self = Self {
        next: [[0.0; 2]; K],
        tolerance: 0.05,
        max_rollouts: 0,
        rollouts: 0,
    };

    fn draw(&mut self, stream: &mut Stream) {
        for v in self.next.iter_mut().flatten() {
            *v = 2.0 * stream.uniform() - 1.0;
        }
    }
}

impl<const N: usize, const K: usize> Method<N, K> for RandomSearch<N, K> {
    fn start(
        &mut self,
        config: &PlannerConfig,
        _: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        self.tolerance = config.tolerance;
        self.max_rollouts = config.max_rollouts;
        self.rollouts = 0;
        self.draw(stream);
        Ok(())
    }

    fn tolerance(&self) -> f64 {
        self.tolerance
    }

    fn report(&self) -> SearchReport {
        SearchReport::default()
    }
}

impl<const N: usize, const K: usize> Optimizer<N, K> for RandomSearch<N, K> {
    fn candidate(&self) -> Candidate<K> {
        Candidate::plain(self.next, f64::INFINITY)
    }

    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        stream: &mut Stream,
        _: &mut O,
    ) -> Next {
        self.rollouts += 1;
        if evaluation
            .outcome()
            .is_some_and(|o| o.phi == 0.0 && o.f <= self.tolerance)
        {
            return Next::Done(Stop::Converged);
        }
        if self.rollouts >= self.max_rollouts {
            return Next::Done(Stop::Exhausted);
        }
        self.draw(stream);
        Next::Continue
    }

    fn progress(&self) -> (u32, u32) {
        (self.rollouts, 0)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use crate::config::PlannerConfig;
    use crate::config::Strategy;
    use crate::optimizer::Stop;
    use crate::planner::{Planner, Status};
    use crate::reference::paper_task;

    fn plan(budget: u32) -> crate::planner::Plan<7, 4> {
        let mut config = PlannerConfig::default_with_seed(3);
        config.strategy = Strategy::Random;
        config.max_rollouts = 12;
        let mut p: Planner<7, 4, 8> = Planner::new(paper_task().unwrap(), config).unwrap();
        for _ in 0..1_000_000 {
            if let Status::Finished(plan) = p.step(budget, &mut ()).unwrap() {
                return plan;
            }
        }
        unreachable!("the budget bounds the plan")
    }

    /// A strategy added as one file and one arm runs under the planner unchanged: it is
    /// the strategy the plan reports, it spends the budget it was given, its best point is
    /// the plan, and the plan is bit-identical under any budget slicing.
    /// Verifies RL-PLAN-012.
    #[test]
    fn a_strategy_is_one_file_and_one_arm() {
        let whole = plan(u32::MAX);
        assert_eq!(whole.strategy, Strategy::Random);
        assert_eq!(whole.rollouts, 12);
        assert_eq!(whole.stop, Stop::Exhausted);
        assert!(whole.outcome.f.is_finite());
        assert_eq!(plan(1), whole);
        assert_eq!(plan(2999), whole);
    }
}
