//! The paper's constrained PSO (spec §7) as an [`Optimizer`]: the swarm's particles
//! evaluated one by one, generation after generation.
//!
//! Owns [`Cpso`], the walk through the [`Swarm`]: evaluate particle 0 … T−1 of a
//! generation, close the generation (gbest, stagnation window), move the swarm, repeat
//! until a feasible particle has `f ≤ σ_e` (success, at once, even mid-generation) or
//! generation m_max is closed (exhausted). Random draws happen only in the swarm's
//! construction and moves (see [`crate::swarm`] for their order).
//!
//! Violation cap of a particle's rollout: its personal best's Φ. A finished `Φ > pbest.Φ`
//! never dominates pbest (feasible beats infeasible; among infeasible, smaller Φ first),
//! so pbest stays; nor can it dominate the planner's best (which dominates or equals every
//! pbest), nor meet σ_e (which needs Φ = 0). A particle without a finished evaluation has
//! pbest Φ = ∞ and is never cut short.

use crate::config::PlannerConfig;
use crate::error::Error;
use crate::optimizer::{Candidate, Evaluation, Event, Next, Observer, Optimizer, Stop};
use crate::optimizer::{Method, SearchReport};
use crate::random::Stream;
use crate::swarm::Swarm;
use crate::task::Task;

/// C-PSO over a swarm of capacity `P`.
#[derive(Debug, Clone, PartialEq)]
pub struct Cpso<const K: usize, const P: usize> {
    swarm: Swarm<K, P>,
    tolerance: f64,
    max_iterations: u32,
    /// Current generation (0 = initial).
    iteration: u32,
    /// Particle being evaluated.
    particle: usize,
    /// Rollouts absorbed.
    rollouts: u32,
}

impl<const K: usize, const P: usize> Cpso<K, P> {
    /// No particles (a placeholder, `const`, for statically allocated planners).
    pub const IDLE: Self = Self {
        swarm: Swarm::IDLE,
        tolerance: 0.05,
        max_iterations: 0,
        iteration: 0,
        particle: 0,
        rollouts: 0,
    };

    /// Starts C-PSO in place: the swarm at its initial positions drawn from `stream`.
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]).
    pub fn reset(&mut self, config: &PlannerConfig, stream: &mut Stream) -> Result<(), Error> {
        self.iteration = 0;
        self.particle = 0;
        self.rollouts = 0;
        self.tolerance = config.tolerance;
        self.max_iterations = config.max_iterations;
        self.swarm.reset(config, stream)
    }

    /// The swarm (for inspection).
    #[must_use]
    pub fn swarm(&self) -> &Swarm<K, P> {
        &self.swarm
    }

    /// Generations completed after the initial one (the paper's iteration count), or the
    /// generation in which C-PSO succeeded.
    #[must_use]
    pub fn iterations(&self) -> u32 {
        self.iteration
    }
}

impl<const N: usize, const K: usize, const P: usize> Method<N, K> for Cpso<K, P> {
    /// [`Cpso::reset`]: the swarm at its initial positions.
    fn start(
        &mut self,
        config: &PlannerConfig,
        _: &Task<N, K>,
        stream: &mut Stream,
    ) -> Result<(), Error> {
        self.reset(config, stream)
    }

    /// σ_e.
    fn tolerance(&self) -> f64 {
        self.tolerance
    }

    /// Generations after the initial one, and the stagnation alarms.
    fn report(&self) -> SearchReport {
        SearchReport {
            iterations: self.iteration,
            stagnation_events: self.swarm.stagnation_events(),
            restarts: 0,
        }
    }
}

impl<const N: usize, const K: usize, const P: usize> Optimizer<N, K> for Cpso<K, P> {
    fn candidate(&self) -> Candidate<K> {
        match self.swarm.particle(self.particle) {
            Some(p) => Candidate::plain(p.position, p.best_cost.phi),
            None => Candidate::plain([[0.0; 2]; K], f64::INFINITY),
        }
    }

    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        stream: &mut Stream,
        observer: &mut O,
    ) -> Next {
        self.rollouts += 1;
        let cost = evaluation.cost();
        self.swarm.record(self.particle, cost);
        if let Some(o) = evaluation
            .outcome()
            .filter(|o| o.phi == 0.0 && o.f <= self.tolerance)
        {
            observer.event(&Event::SwarmConverged {
                iteration: self.iteration,
                f: o.f,
            });
            return Next::Done(Stop::Converged);
        }
        if self.particle + 1 < self.swarm.count() {
            self.particle += 1;
            return Next::Continue;
        }
        // End of a generation.
        let alarm = self.swarm.end_generation();
        let (_, best) = self.swarm.gbest();
        observer.event(&Event::Generation {
            iteration: self.iteration,
            best,
            rollouts: self.rollouts,
        });
        if alarm {
            observer.event(&Event::Stagnation {
                iteration: self.iteration,
            });
        }
        if self.iteration >= self.max_iterations {
            return Next::Done(Stop::Exhausted);
        }
        self.iteration += 1;
        self.particle = 0;
        self.swarm.advance(self.iteration, stream);
        Next::Continue
    }

    fn progress(&self) -> (u32, u32) {
        (self.iteration, self.particle as u32)
    }

    /// The rest of the generation: particle `i + j`, with its personal best's Φ as the cap
    /// (which only its own evaluation changes).
    fn ahead(&self, j: usize) -> Option<Candidate<K>> {
        let i = self.particle.checked_add(j)?;
        if i >= self.swarm.count() {
            return None;
        }
        self.swarm
            .particle(i)
            .map(|p| Candidate::plain(p.position, p.best_cost.phi))
    }
}
