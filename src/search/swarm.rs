//! The constrained particle swarm of spec §7 (paper §5): particles, constraint domination,
//! global-best selection, the stagnation alarm and the split into subswarms.
//!
//! Owns [`Swarm`] and [`Cost`]; it never runs a rollout (the planner evaluates particles and
//! reports their costs with [`Swarm::record`]). Fixed size: capacity `P` particles, the
//! task's count `T ≤ P` in use.
//!
//! Rules:
//! - **Domination** ([`Cost::dominates`]): feasible (Φ = 0) beats infeasible; of two
//!   infeasible, smaller Φ wins (then smaller f); of two feasible, smaller f wins. Ties do
//!   not dominate, so an incumbent stays.
//! - **pbest** is replaced only by a dominating evaluation; **gbest** is the best pbest (the
//!   lowest index among equals) — the best feasible one if any is feasible, else the least
//!   violating.
//! - **Stagnation alarm**: after each generation gbest's cost joins a window of
//!   `window + 1` values (a `heapless` deque). When it is full and gbest improved by less
//!   than `min_relative_improvement` (relative) from its oldest to its newest entry, the
//!   alarm fires, the window restarts, and the next move splits the swarm.
//! - **Split**: a random permutation (Fisher–Yates) puts `⌊T/2⌋` particles in S1 and the
//!   rest in S2. S1 particles restart at `gbest + ε₁·U(0,1)` per component with zero
//!   velocity; S2 particles get `ω + |ε₂|·U(0,1)` for their next update.
//!
//! **Draw order** (one stream, documented because golden records depend on it): at
//! construction, `T·2K` draws for the initial positions (particle by particle, components
//! `a₁, b₁, …, a_K, b_K`), each `B·(2u − 1)`. In each move: if a split is pending, `T − 1`
//! draws for the permutation (`i = T−1 … 1`), then per particle in index order `2K` draws
//! (S1) or one draw (S2); then per particle not in S1, per component, `r₁` then `r₂`.

use crate::config::{MAX_WINDOW, PlannerConfig};
use crate::error::Error;
use crate::random::Stream;
use heapless::Deque;

/// A point's cost: constraint violation Φ (eq. 23, rad) and pose error f.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Cost {
    /// Φ (rad); 0 when the joint limits hold.
    pub phi: f64,
    /// f = ‖e‖.
    pub f: f64,
}

impl Cost {
    /// The cost of a point whose rollout failed (rank loss, non-finite state): infeasible
    /// and worse than any evaluated point.
    pub const FAILED: Self = Self {
        phi: f64::INFINITY,
        f: f64::INFINITY,
    };

    /// Φ = 0.
    #[must_use]
    pub fn feasible(&self) -> bool {
        self.phi == 0.0
    }

    /// Constraint domination (strict).
    #[must_use]
    pub fn dominates(&self, other: &Self) -> bool {
        match (self.feasible(), other.feasible()) {
            (true, false) => true,
            (false, true) => false,
            (true, true) => self.f < other.f,
            (false, false) => self.phi < other.phi || (self.phi == other.phi && self.f < other.f),
        }
    }
}

/// One particle: position, velocity and personal best in η space (pairs `(a_i, b_i)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Particle<const K: usize> {
    /// Current position η_j.
    pub position: [[f64; 2]; K],
    /// Current velocity ν_j.
    pub velocity: [[f64; 2]; K],
    /// Personal best position.
    pub best: [[f64; 2]; K],
    /// Cost of the personal best.
    pub best_cost: Cost,
    /// Cost of the current position (after its evaluation).
    pub cost: Cost,
    /// Inertia boost for the next update (S2 after a split).
    boost: f64,
    /// Restarted around gbest by a split this move (S1).
    restart: bool,
}

/// The swarm: capacity `P`, `T` particles in use.
#[derive(Debug, Clone, PartialEq)]
pub struct Swarm<const K: usize, const P: usize> {
    config: PlannerConfig,
    particles: [Particle<K>; P],
    count: usize,
    gbest: usize,
    history: Deque<Cost, { MAX_WINDOW + 1 }>,
    split_pending: bool,
    stagnation_events: u32,
}

impl<const K: usize, const P: usize> Swarm<K, P> {
    /// No particles in use (a placeholder, `const`, for statically allocated planners).
    pub const IDLE: Self = Self {
        config: PlannerConfig::reference(0),
        particles: [Particle {
            position: [[0.0; 2]; K],
            velocity: [[0.0; 2]; K],
            best: [[0.0; 2]; K],
            best_cost: Cost::FAILED,
            cost: Cost::FAILED,
            boost: 0.0,
            restart: false,
        }; P],
        count: 0,
        gbest: 0,
        history: Deque::new(),
        split_pending: false,
        stagnation_events: 0,
    };

    /// A swarm at its initial positions (drawn from `stream`), zero velocities, costs
    /// unknown ([`Cost::FAILED`] until recorded).
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]).
    pub fn new(config: &PlannerConfig, stream: &mut Stream) -> Result<Self, Error> {
        let mut s = Self::IDLE;
        s.reset(config, stream)?;
        Ok(s)
    }

    /// Re-initialises the swarm in place, exactly as [`Swarm::new`] would build it (no
    /// large temporaries: flight software keeps the swarm in static memory).
    ///
    /// # Errors
    /// A bad setting (see [`PlannerConfig::validate`]); the swarm is then left empty.
    pub fn reset(&mut self, config: &PlannerConfig, stream: &mut Stream) -> Result<(), Error> {
        self.count = 0;
        config.validate(P)?;
        let count = config.particles as usize;
        let b = config.eta_bound;
        for (j, p) in self.particles.iter_mut().enumerate() {
            p.velocity = [[0.0; 2]; K];
            p.best_cost = Cost::FAILED;
            p.cost = Cost::FAILED;
            p.boost = 0.0;
            p.restart = false;
            if j < count {
                for v in p.position.iter_mut().flatten() {
                    *v = b * (2.0 * stream.uniform() - 1.0);
                }
            } else {
                p.position = [[0.0; 2]; K];
            }
            p.best = p.position;
        }
        self.config = *config;
        self.count = count;
        self.gbest = 0;
        self.history.clear();
        self.split_pending = false;
        self.stagnation_events = 0;
        Ok(())
    }

    /// The settings.
    #[must_use]
    pub fn config(&self) -> &PlannerConfig {
        &self.config
    }

    /// Particles in use, T.
    #[must_use]
    pub fn count(&self) -> usize {
        self.count
    }

    /// Particle `j`, if `j < T`.
    #[must_use]
    pub fn particle(&self, j: usize) -> Option<&Particle<K>> {
        self.particles.get(j).filter(|_| j < self.count)
    }

    /// Records the cost of particle `j`'s current position and updates its personal best
    /// by domination. Ignores `j ≥ T`.
    pub fn record(&mut self, j: usize, cost: Cost) {
        if j >= self.count {
            return;
        }
        if let Some(p) = self.particles.get_mut(j) {
            p.cost = cost;
            if cost.dominates(&p.best_cost) {
                p.best = p.position;
                p.best_cost = cost;
            }
        }
    }

    /// gbest: position and cost of the best personal best.
    #[must_use]
    pub fn gbest(&self) -> ([[f64; 2]; K], Cost) {
        match self.particles.get(self.gbest) {
            Some(p) => (p.best, p.best_cost),
            None => ([[0.0; 2]; K], Cost::FAILED),
        }
    }

    /// Index of gbest's particle.
    #[must_use]
    pub fn gbest_index(&self) -> usize {
        self.gbest
    }

    /// Stagnation alarms so far.
    #[must_use]
    pub fn stagnation_events(&self) -> u32 {
        self.stagnation_events
    }

    /// Closes a generation: selects gbest and feeds the stagnation window. Returns `true`
    /// when the alarm fires (the next [`Swarm::advance`] splits the swarm).
    pub fn end_generation(&mut self) -> bool {
        let mut best = 0;
        let mut best_cost = Cost::FAILED;
        for (j, p) in self.particles.iter().take(self.count).enumerate() {
            if j == 0 || p.best_cost.dominates(&best_cost) {
                best = j;
                best_cost = p.best_cost;
            }
        }
        self.gbest = best;
        let window = self.config.stagnation.window as usize;
        if self.history.is_full() {
            self.history.pop_front();
        }
        let _ = self.history.push_back(best_cost);
        if self.history.len() <= window {
            return false;
        }
        let alarm = match self.history.front() {
            Some(old) => stagnating(
                old,
                &best_cost,
                self.config.stagnation.min_relative_improvement,
            ),
            None => false,
        };
        if alarm {
            self.history.clear();
            let _ = self.history.push_back(best_cost);
            self.split_pending = true;
            self.stagnation_events += 1;
        } else {
            self.history.pop_front();
        }
        alarm
    }

    /// Moves every particle for generation `m ≥ 1` (eqs. 20–22), splitting first if the
    /// alarm fired.
    pub fn advance(&mut self, m: u32, stream: &mut Stream) {
        let (g, _) = self.gbest();
        if self.split_pending {
            self.split(&g, stream);
            self.split_pending = false;
        }
        let w = self.config.inertia_weight(m);
        let (c1, c2) = (self.config.c1, self.config.c2);
        for p in self.particles.iter_mut().take(self.count) {
            if p.restart {
                p.restart = false;
                continue;
            }
            let wj = w + p.boost;
            p.boost = 0.0;
            let comps = p
                .position
                .iter_mut()
                .flatten()
                .zip(p.velocity.iter_mut().flatten())
                .zip(p.best.iter().flatten())
                .zip(g.iter().flatten());
            for (((x, v), pb), gb) in comps {
                let r1 = stream.uniform();
                let r2 = stream.uniform();
                *v = wj * *v + c1 * r1 * (pb - *x) + c2 * r2 * (gb - *x);
                *x += *v;
            }
        }
    }

    /// The split of paper §5.2 (see the module documentation for the draw order).
    fn split(&mut self, g: &[[f64; 2]; K], stream: &mut Stream) {
        let mut perm = [0usize; P];
        for (i, v) in perm.iter_mut().enumerate() {
            *v = i;
        }
        let n = self.count;
        for i in (1..n).rev() {
            let r = stream.index(i + 1);
            if i < P && r < P {
                perm.swap(i, r);
            }
        }
        let half = n / 2;
        for (k, &j) in perm.iter().take(n).enumerate() {
            if let Some(p) = self.particles.get_mut(j) {
                p.restart = k < half;
            }
        }
        let (eps1, eps2) = (
            self.config.stagnation.eps1,
            libm::fabs(self.config.stagnation.eps2),
        );
        for p in self.particles.iter_mut().take(n) {
            if p.restart {
                for (x, gb) in p.position.iter_mut().flatten().zip(g.iter().flatten()) {
                    *x = gb + eps1 * stream.uniform();
                }
                p.velocity = [[0.0; 2]; K];
            } else {
                p.boost = eps2 * stream.uniform();
            }
        }
    }
}

/// `true` if gbest improved by less than `min_rel` (relative) from `old` to `new`.
/// A non-finite comparison (both failed) counts as stagnation.
#[must_use]
pub fn stagnating(old: &Cost, new: &Cost, min_rel: f64) -> bool {
    let improved = match (old.feasible(), new.feasible()) {
        (true, true) => old.f - new.f >= min_rel * old.f,
        (false, false) => old.phi - new.phi >= min_rel * old.phi,
        (false, true) => true,
        (true, false) => false,
    };
    !improved
}
