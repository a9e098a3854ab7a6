//! Every planner setting, in one place: what a task file's `[planner]` table holds.
//!
//! Owns [`PlannerConfig`], [`StagnationConfig`] and [`RefineConfig`] (the refinement
//! settings [`PlannerConfig::refine`] derives from the flat keys). The fields are the task file's keys
//! (`[planner] particles = 40`, `[planner.stagnation] window = 10`); the defaults are the
//! spec §7 values ([`PlannerConfig::reference`]). With the optional `serde` feature the
//! types derive `Deserialize` (and `Serialize`) with `deny_unknown_fields`, so a host reads
//! a task file straight into them, and every error of [`PlannerConfig::validate`] names
//! the bad setting as a [`Param`] whose [`Param::key`] is its task-file key.
//!
//! A new setting touches this file, the task block layout ([`crate::block`]) and the
//! documentation, nothing else.

use crate::error::{Error, Param};

/// Longest stagnation window (generations).
pub const MAX_WINDOW: usize = 64;

/// The planner's settings (spec §7 unless noted). Validate with [`PlannerConfig::validate`].
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(deny_unknown_fields, default)
)]
pub struct PlannerConfig {
    /// How η is searched: [`Strategy::Multistart`] (the default) or the paper's
    /// [`Strategy::Cpso`].
    pub strategy: Strategy,
    /// The total budget in rollouts, search and refinement together (≥ 1; default 8,040,
    /// the paper's worst case of 40 × 201). A plan that has not met its tolerance when it is
    /// spent ends [`crate::Stop::Exhausted`].
    pub max_rollouts: u32,
    /// Swarm size T, `1..=P` (the planner's capacity; C-PSO only).
    pub particles: u32,
    /// m_max ≥ 1: generations after the initial one.
    pub max_iterations: u32,
    /// Cognitive factor c1 ≥ 0.
    pub c1: f64,
    /// Social factor c2 ≥ 0.
    pub c2: f64,
    /// Inertia weight ω at the first generation.
    pub w_max: f64,
    /// ω at generation m_max, `0 ≤ w_min ≤ w_max`.
    pub w_min: f64,
    /// σ_e (f, metres and radians mixed): success when a feasible candidate has
    /// `f ≤ tolerance` (> 0).
    pub tolerance: f64,
    /// Initial positions are uniform in `[−B, B]^(2K)`, B > 0.
    pub eta_bound: f64,
    /// Seed of the random stream.
    pub seed: u64,
    /// Refine after success until `f ≤ refine_tolerance` (> 0); `None`: no refinement.
    pub refine_tolerance: Option<f64>,
    /// Most rollouts refinement may spend (≥ 1; C-PSO's refinement and the refinement
    /// against the truth model).
    pub refine_max_rollouts: u32,
    /// Which end pose refinement drives below `refine_tolerance`: the planner model's
    /// ([`RefineAgainst::Planner`], f) or the truth model's ([`RefineAgainst::Truth`],
    /// `truth_f`, spec §11).
    pub refine_against: RefineAgainst,
    /// Integration steps the flight software gives [`crate::Planner::step`] per frame
    /// (≥ 1). The planner does not read it; the task block carries it to the driver.
    pub frame_budget: u32,
    /// The stagnation alarm (`[planner.stagnation]`).
    pub stagnation: StagnationConfig,
}

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
    /// A test-only random search (the core's unit tests, [`crate::strategy`]): the proof
    /// that a strategy is one file and one arm.
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

/// Which end pose refinement drives (`[planner] refine_against`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "lowercase")
)]
pub enum RefineAgainst {
    /// The planner model's end pose (base attitude identity): f.
    Planner,
    /// The truth model's (the base drift integrated, spec §11): `truth_f`.
    Truth,
}

impl RefineAgainst {
    /// Both targets, in wire-code order.
    pub const ALL: &'static [RefineAgainst] = &[RefineAgainst::Planner, RefineAgainst::Truth];

    /// The one table: task-file name and wire code (task block).
    const fn entry(self) -> (&'static str, u32) {
        match self {
            RefineAgainst::Planner => ("planner", 0),
            RefineAgainst::Truth => ("truth", 1),
        }
    }

    /// The task-file name (`"planner"`, `"truth"`).
    #[must_use]
    pub const fn name(self) -> &'static str {
        self.entry().0
    }

    /// The wire code (u32) of the task block.
    #[must_use]
    pub const fn code(self) -> u32 {
        self.entry().1
    }

    /// The target of a task-file name.
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|s| s.name() == name)
    }

    /// The target of a wire code.
    #[must_use]
    pub fn from_code(code: u32) -> Option<Self> {
        Self::ALL.iter().copied().find(|s| s.code() == code)
    }
}

/// The stagnation alarm of paper §5.2 (`[planner.stagnation]`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(deny_unknown_fields, default)
)]
pub struct StagnationConfig {
    /// Generations over which gbest must improve, `1..=MAX_WINDOW`.
    pub window: u32,
    /// Relative improvement below which the swarm stagnates (≥ 0; 0 disables the alarm).
    pub min_relative_improvement: f64,
    /// Spread ε₁ ≥ 0 of the S1 restart around gbest.
    pub eps1: f64,
    /// Inertia boost ε₂ of S2 (its magnitude is used).
    pub eps2: f64,
}

impl Default for PlannerConfig {
    /// [`PlannerConfig::default_with_seed`] with seed 1: what a task file without a
    /// `[planner]` table plans with.
    fn default() -> Self {
        Self::default_with_seed(1)
    }
}

impl Default for StagnationConfig {
    /// The spec §7 alarm: window 10, 1e-3, ε₁ = 0.5, ε₂ = 0.3.
    fn default() -> Self {
        Self::REFERENCE
    }
}

impl StagnationConfig {
    /// The spec §7 alarm: window 10, 1e-3, ε₁ = 0.5, ε₂ = 0.3.
    pub const REFERENCE: Self = Self {
        window: 10,
        min_relative_improvement: 1e-3,
        eps1: 0.5,
        eps2: 0.3,
    };
}

impl PlannerConfig {
    /// The default settings: the multistart strategy with a budget of 8,040 rollouts, and
    /// the spec §7 values for everything C-PSO reads ([`PlannerConfig::reference`]).
    #[must_use]
    pub const fn default_with_seed(seed: u64) -> Self {
        let mut c = Self::reference(seed);
        c.strategy = Strategy::Multistart;
        c
    }

    /// The spec §7 settings, the paper's C-PSO: 40 particles, m_max = 200, c1 = c2 =
    /// 1.49618, ω 0.9 → 0.4, σ_e = 0.05, B = 5, no refinement (1000 rollouts if enabled,
    /// against the planner model), the reference alarm, a total budget of 8,040 rollouts and
    /// a frame budget of 3000 integration steps (one reference rollout).
    #[must_use]
    pub const fn reference(seed: u64) -> Self {
        Self {
            strategy: Strategy::Cpso,
            max_rollouts: 8040,
            particles: 40,
            max_iterations: 200,
            c1: 1.49618,
            c2: 1.49618,
            w_max: 0.9,
            w_min: 0.4,
            tolerance: 0.05,
            eta_bound: 5.0,
            seed,
            refine_tolerance: None,
            refine_max_rollouts: 1000,
            refine_against: RefineAgainst::Planner,
            frame_budget: 3000,
            stagnation: StagnationConfig::REFERENCE,
        }
    }

    /// Checks every setting against a capacity of `capacity` particles (C-PSO).
    ///
    /// # Errors
    /// The first bad setting, named by its [`Param`] (whose [`Param::key`] is the task
    /// file's key).
    ///
    /// Verifies RL-SIM-TASK-004, RL-ROB-007.
    ///
    /// ```
    /// use reactionless::{Error, Param, PlannerConfig};
    /// let mut c = PlannerConfig::reference(1);
    /// c.particles = 0;
    /// assert_eq!(c.validate(64), Err(Error::NotPositive(Param::Particles)));
    /// assert_eq!(Param::Particles.key(), Some("planner.particles"));
    /// ```
    pub fn validate(&self, capacity: usize) -> Result<(), Error> {
        if self.particles == 0 {
            return Err(Error::NotPositive(Param::Particles));
        }
        // The swarm's capacity matters only to C-PSO.
        if self.strategy == Strategy::Cpso && self.particles as usize > capacity {
            return Err(Error::CapacityExceeded {
                param: Param::Particles,
                requested: self.particles,
                capacity: capacity.min(u32::MAX as usize) as u32,
            });
        }
        if self.max_iterations == 0 {
            return Err(Error::NotPositive(Param::MaxIterations));
        }
        let s = &self.stagnation;
        for (v, p) in [
            (self.c1, Param::C1),
            (self.c2, Param::C2),
            (self.w_max, Param::WMax),
            (self.w_min, Param::WMin),
            (s.min_relative_improvement, Param::MinImprovement),
            (s.eps1, Param::Eps1),
        ] {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v < 0.0 {
                return Err(Error::Negative(p));
            }
        }
        if !s.eps2.is_finite() {
            return Err(Error::NotFinite(Param::Eps2));
        }
        if self.w_min > self.w_max {
            return Err(Error::InertiaWeightsInverted);
        }
        for (v, p) in [
            (self.eta_bound, Param::EtaBound),
            (self.tolerance, Param::Tolerance),
        ] {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v <= 0.0 {
                return Err(Error::NotPositive(p));
            }
        }
        if s.window == 0 {
            return Err(Error::NotPositive(Param::StagnationWindow));
        }
        if s.window as usize > MAX_WINDOW {
            return Err(Error::CapacityExceeded {
                param: Param::StagnationWindow,
                requested: s.window,
                capacity: MAX_WINDOW as u32,
            });
        }
        if let Some(r) = self.refine() {
            r.validate()?;
        }
        if self.frame_budget == 0 {
            return Err(Error::NotPositive(Param::FrameBudget));
        }
        if self.max_rollouts == 0 {
            return Err(Error::NotPositive(Param::MaxRollouts));
        }
        Ok(())
    }

    /// The refinement settings, if refinement is on.
    #[must_use]
    pub fn refine(&self) -> Option<RefineConfig> {
        self.refine_tolerance.map(|tolerance| RefineConfig {
            tolerance,
            max_rollouts: self.refine_max_rollouts,
        })
    }

    /// ω(m) = ω_max − m (ω_max − ω_min)/m_max (eq. 22).
    #[must_use]
    pub fn inertia_weight(&self, m: u32) -> f64 {
        self.w_max - f64::from(m) * (self.w_max - self.w_min) / f64::from(self.max_iterations)
    }
}

/// Refinement settings.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefineConfig {
    /// Target on f (> 0), e.g. 1e-6.
    pub tolerance: f64,
    /// Most rollouts refinement may spend (≥ 1).
    pub max_rollouts: u32,
}

impl RefineConfig {
    /// Checks the settings.
    ///
    /// # Errors
    /// A non-finite or non-positive tolerance; a zero rollout budget.
    pub fn validate(&self) -> Result<(), Error> {
        if !self.tolerance.is_finite() {
            return Err(Error::NotFinite(Param::RefineTolerance));
        }
        if self.tolerance <= 0.0 {
            return Err(Error::NotPositive(Param::RefineTolerance));
        }
        if self.max_rollouts == 0 {
            return Err(Error::NotPositive(Param::RefineRollouts));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::Strategy;

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
