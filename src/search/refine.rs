//! Local refinement beyond the paper: Levenberg–Marquardt on η after C-PSO reaches σ_e.
//!
//! Owns [`RefineReport`] and the refinement state machine [`Refiner`], an
//! [`Optimizer`]: it never runs a rollout; the planner asks for each candidate and hands
//! its evaluation back, which keeps it budgeted and resumable exactly like the swarm.
//!
//! One iteration:
//! 1. **Jacobian** of the 6-vector `e` (spec §6) by forward differences: `2K` rollouts at
//!    `η + h·e_c`, `h = 1e-7·max|η|`.
//! 2. **Step** `δ = −Jᵀ(J Jᵀ + λ μ I)⁻¹ e`, `μ = tr(J Jᵀ)/6`. By the push-through identity
//!    this is Levenberg's `−(JᵀJ + λμI)⁻¹Jᵀe`, but it needs only a 6×6 solve whatever K is.
//!    The step lies in the row space of J, so it ignores the direction along η, which leaves
//!    the path unchanged.
//! 3. **Trial** rollout at `η + δ`: accepted if it keeps the joint limits (Φ = 0) and lowers
//!    f (then `λ ← λ/10` and a new Jacobian), else rejected (`λ ← 10λ`, same Jacobian).
//!
//! It stops when `f ≤ tolerance`, after `max_rollouts` rollouts, or when λ exceeds 1e8 on a
//! freshly differenced Jacobian (no descent left at rounding level). Only improvements are
//! accepted, so the result is never worse than the C-PSO result.
//!
//! **Against the truth model** ([`Refiner::against_truth`]) the damping follows the
//! multistart's schedule instead: on an accepted trial Nielsen's
//! `λ ← λ·max(1/3, 1 − (2ρ − 1)³)` (ρ = actual / predicted decrease of `‖e‖²`), `ν ← 2`; on
//! a rejected one `λ ← λν`, `ν ← 2ν`; floor 1e-15. The truth-made targets sit in a thin
//! reachable set (singular values of the 6 × 2K Jacobian spread over 6–8 decades), and the
//! truth solution can lie some distance along a curved valley from the planner-model point
//! the search hands over. There the decade schedule bounced between a rejected λ and an accepted
//! one ten times larger that shrinks `truth_f` by 0.7–1.5 % per step, and its floor of 1e-12
//! damped the weakest direction to 0.2 % of its Gauss–Newton step (issue #28: set B chaser7
//! tasks 006, 008, 009 ran out of the 1,000-rollout budget at 1e-8…6e-6 on every seed).
//! The Jacobian is differenced (planner model) once and then corrected by Broyden's rank-1
//! update with the truth-model error of every trial, accepted or not, so a step costs one
//! rollout instead of `2K + 1`; it is differenced afresh after two consecutive failed trials
//! on a corrected Jacobian (rejected, or accepted with less than 0.1 of the predicted
//! decrease: MINPACK `hybrd`'s rule), or when λ passes 1e8 on one (then λ restarts at 1e-3).
//! Damping and Broyden scheme are the multistart's measured choices ([`crate::multistart`]).
//! Refinement against the planner model keeps the decade schedule and a new Jacobian per
//! step (its records are pinned).

use crate::config::{RefineAgainst, RefineConfig};
use crate::geometry::PoseError;
use crate::optimizer::{Candidate, Evaluation, Event, Next, Observer, Optimizer, Stop};
use crate::random::Stream;
use crate::rollout::Outcome;
use crate::trajectory::one_segment;

/// Relative finite-difference step.
const FD_STEP: f64 = 1e-7;
/// Initial damping (relative to μ).
const LAMBDA_START: f64 = 1e-3;
/// Damping at which refinement gives up.
const LAMBDA_MAX: f64 = 1e8;
/// Smallest damping.
const LAMBDA_MIN: f64 = 1e-12;
/// Against the truth model: consecutive failed trials on a Broyden-corrected Jacobian
/// before it is differenced afresh (the multistart's `rebuild_after`).
const REBUILD_AFTER: u32 = 2;
/// Against the truth model: an accepted trial whose decrease of `‖e‖²` is below this
/// fraction of the predicted one counts as failed too (MINPACK `hybrd`'s test before it
/// re-differences a Broyden-updated Jacobian).
const POOR_MODEL: f64 = 0.1;
/// Smallest damping against the truth model (the multistart's floor): the weakest singular
/// value of the 6 × 2K Jacobian is down to `σ²/μ ≈ 2e-15` (chaser7), and a floor above it
/// leaves that direction only `σ²/(σ² + λμ)` of its Gauss–Newton step per iteration.
const TRUTH_LAMBDA_MIN: f64 = 1e-15;

/// Why refinement stopped.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum RefineStop {
    /// `f ≤ tolerance`.
    Reached,
    /// The rollout budget is spent.
    Budget,
    /// λ grew past its limit: no descent direction left at rounding level.
    Stalled,
}

impl RefineStop {
    /// `"reached"`, `"budget"` or `"stalled"`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            RefineStop::Reached => "reached",
            RefineStop::Budget => "budget",
            RefineStop::Stalled => "stalled",
        }
    }
}

/// What refinement did.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RefineReport {
    /// Accepted steps.
    pub iterations: u32,
    /// Rollouts spent.
    pub rollouts: u32,
    /// Why it stopped.
    pub stop: RefineStop,
    /// f before refinement (the C-PSO result).
    pub f_start: f64,
    /// Against the truth model: `truth_f` of the best point (`None`: refined against the
    /// planner model).
    pub truth_f: Option<f64>,
}

/// Which rollout the refiner waits for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Awaiting {
    /// The start point with the truth model (refinement against the truth).
    Start,
    /// Jacobian column `c` (`0..2K`).
    Column(usize),
    /// The trial point.
    Trial,
}

/// The refinement state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Refiner<const N: usize, const K: usize> {
    config: RefineConfig,
    eta: [[f64; 2]; K],
    outcome: Outcome<N>,
    e: [f64; 6],
    h: f64,
    jac: [[[f64; 6]; 2]; K],
    lambda: f64,
    awaiting: Awaiting,
    trial: [[f64; 2]; K],
    iterations: u32,
    rollouts: u32,
    f_start: f64,
    stop: Option<RefineStop>,
    /// Against the truth model: `truth_f` of the current point once evaluated (then `e`
    /// is its truth error); `None` against the planner model.
    truth: Option<f64>,
    against: RefineAgainst,
    /// Against the truth: Nielsen's growth factor ν for the next rejection.
    nu: f64,
    /// Against the truth: the decrease of `‖e‖²` the linear model predicts for the trial.
    pred: f64,
    /// Against the truth: consecutive failed trials (rejected, or accepted with a decrease
    /// below [`POOR_MODEL`] of the predicted one).
    failures: u32,
    /// Against the truth: the Jacobian carries Broyden corrections since it was differenced.
    corrected: bool,
}

impl<const N: usize, const K: usize> Refiner<N, K> {
    /// Starts from `eta` with its rollout `outcome`.
    #[must_use]
    pub fn new(config: RefineConfig, eta: [[f64; 2]; K], outcome: Outcome<N>) -> Self {
        let largest = eta
            .iter()
            .flatten()
            .fold(0.0f64, |m, v| m.max(libm::fabs(*v)));
        let stop = (outcome.f <= config.tolerance).then_some(RefineStop::Reached);
        Self {
            config,
            eta,
            outcome,
            e: outcome.error.to_array(),
            h: FD_STEP * largest,
            jac: [[[0.0; 6]; 2]; K],
            lambda: LAMBDA_START,
            awaiting: Awaiting::Column(0),
            trial: eta,
            iterations: 0,
            rollouts: 0,
            f_start: outcome.f,
            stop,
            truth: None,
            against: RefineAgainst::Planner,
            nu: 2.0,
            pred: 0.0,
            failures: 0,
            corrected: false,
        }
    }

    /// Starts from `eta` with its (planner-model) rollout `outcome`, driving the truth-model
    /// end-pose error below the tolerance (spec §11): the first rollout re-evaluates `eta`
    /// with the truth model; Jacobian columns are the planner model's (cheap, and close to
    /// the truth's: the drift is small and smooth in η); trials are evaluated with the
    /// truth model and accepted when they lower `truth_f` with Φ = 0.
    #[must_use]
    pub fn against_truth(config: RefineConfig, eta: [[f64; 2]; K], outcome: Outcome<N>) -> Self {
        let mut r = Self::new(config, eta, outcome);
        r.stop = None;
        r.against = RefineAgainst::Truth;
        r.awaiting = Awaiting::Start;
        r
    }

    /// The f refinement drives: `truth_f` against the truth model, else f.
    fn merit(&self) -> f64 {
        self.truth.unwrap_or(self.outcome.f)
    }

    /// `true` once refinement has stopped.
    #[must_use]
    pub fn done(&self) -> bool {
        self.stop.is_some()
    }

    /// The best point so far and its rollout.
    #[must_use]
    pub fn best(&self) -> (&[[f64; 2]; K], &Outcome<N>) {
        (&self.eta, &self.outcome)
    }

    /// The report (stop reason `Budget` while still running).
    #[must_use]
    pub fn report(&self) -> RefineReport {
        RefineReport {
            iterations: self.iterations,
            rollouts: self.rollouts,
            stop: self.stop.unwrap_or(RefineStop::Budget),
            f_start: self.f_start,
            truth_f: self.truth,
        }
    }

    /// Current damping λ (relative to μ).
    #[must_use]
    pub fn lambda(&self) -> f64 {
        self.lambda
    }

    /// The η to evaluate next.
    #[must_use]
    pub fn next_eta(&self) -> [[f64; 2]; K] {
        match self.awaiting {
            Awaiting::Column(c) => self.column_eta(c),
            Awaiting::Start => self.eta,
            Awaiting::Trial => self.trial,
        }
    }

    /// η of Jacobian column `c`: component `c` perturbed by `h`.
    fn column_eta(&self, c: usize) -> [[f64; 2]; K] {
        let mut eta = self.eta;
        if let Some(v) = eta.get_mut(c / 2).and_then(|p| p.get_mut(c % 2)) {
            *v += self.h;
        }
        eta
    }

    /// `true` if the next rollout is a trial step (not a Jacobian column).
    #[must_use]
    pub fn at_trial(&self) -> bool {
        self.awaiting == Awaiting::Trial
    }

    /// `true` if the next rollout needs the truth model.
    fn wants_truth(&self) -> bool {
        self.against == RefineAgainst::Truth && !matches!(self.awaiting, Awaiting::Column(_))
    }

    /// Takes the rollout of [`Refiner::next_eta`] (`None` if it failed or was abandoned)
    /// and, against the truth, its truth-model error; `true` while refinement goes on.
    fn take(&mut self, result: Option<&Outcome<N>>, truth: Option<&PoseError>) -> bool {
        if self.stop.is_some() {
            return false;
        }
        self.rollouts += 1;
        match self.awaiting {
            Awaiting::Start => match (result, truth) {
                (Some(_), Some(te)) => {
                    self.e = te.to_array();
                    let f = te.norm();
                    self.truth = Some(f);
                    self.f_start = f;
                    if f <= self.config.tolerance {
                        self.stop = Some(RefineStop::Reached);
                    } else {
                        self.awaiting = Awaiting::Column(0);
                    }
                }
                _ => self.stop = Some(RefineStop::Stalled),
            },
            Awaiting::Column(c) => {
                // Columns difference the planner model about the current point's own
                // planner-model error (against the planner, `e` is that error too).
                let base = self.outcome.error.to_array();
                let column = match result {
                    Some(o) => {
                        let ep = o.error.to_array();
                        let mut d = [0.0; 6];
                        for ((d, a), b) in d.iter_mut().zip(ep.iter()).zip(base.iter()) {
                            *d = (a - b) / self.h;
                        }
                        d
                    }
                    // A failed perturbed rollout: leave that direction out of this step.
                    None => [0.0; 6],
                };
                if let Some(col) = self.jac.get_mut(c / 2).and_then(|p| p.get_mut(c % 2)) {
                    *col = column;
                }
                if c + 1 < 2 * K {
                    self.awaiting = Awaiting::Column(c + 1);
                } else {
                    self.corrected = false;
                    self.failures = 0;
                    self.plan_trial();
                }
            }
            Awaiting::Trial => match (result, self.against) {
                (Some(o), RefineAgainst::Planner) if o.phi == 0.0 && o.f < self.outcome.f => {
                    self.eta = self.trial;
                    self.outcome = *o;
                    self.e = o.error.to_array();
                    self.iterations += 1;
                    self.lambda = (self.lambda * 0.1).max(LAMBDA_MIN);
                    if o.f <= self.config.tolerance {
                        self.stop = Some(RefineStop::Reached);
                    } else {
                        self.awaiting = Awaiting::Column(0);
                    }
                }
                (Some(o), RefineAgainst::Truth)
                    if o.phi == 0.0 && truth.is_some_and(|te| te.norm() < self.merit()) =>
                {
                    let te = truth.map_or([0.0; 6], PoseError::to_array);
                    let f = truth.map_or(f64::INFINITY, PoseError::norm);
                    self.broyden(&te);
                    let rho = self.nielsen_accept(f);
                    self.failures = if rho < POOR_MODEL {
                        self.failures + 1
                    } else {
                        0
                    };
                    self.eta = self.trial;
                    self.outcome = *o;
                    self.e = te;
                    self.truth = Some(f);
                    self.iterations += 1;
                    if f <= self.config.tolerance {
                        self.stop = Some(RefineStop::Reached);
                    } else if self.corrected && self.failures >= REBUILD_AFTER {
                        // Accepted, but the corrected Jacobian no longer predicts the truth
                        // (such steps crept at < 1 % each): difference it afresh.
                        self.awaiting = Awaiting::Column(0);
                    } else {
                        // The corrected Jacobian plans the next trial: no new differences.
                        self.plan_trial();
                    }
                }
                (_, RefineAgainst::Truth) => {
                    if let (Some(_), Some(te)) = (result, truth) {
                        self.broyden(&te.to_array());
                    }
                    self.lambda *= self.nu;
                    self.nu *= 2.0;
                    self.failures += 1;
                    if self.lambda > LAMBDA_MAX && self.corrected {
                        // No descent on a corrected Jacobian: difference it afresh first.
                        self.lambda = LAMBDA_START;
                        self.nu = 2.0;
                        self.awaiting = Awaiting::Column(0);
                    } else if self.lambda > LAMBDA_MAX {
                        self.stop = Some(RefineStop::Stalled);
                    } else if self.corrected && self.failures >= REBUILD_AFTER {
                        self.awaiting = Awaiting::Column(0);
                    } else {
                        self.plan_trial();
                    }
                }
                (_, RefineAgainst::Planner) => {
                    self.lambda *= 10.0;
                    if self.lambda > LAMBDA_MAX {
                        self.stop = Some(RefineStop::Stalled);
                    } else {
                        self.plan_trial();
                    }
                }
            },
        }
        if self.stop.is_none() && self.rollouts >= self.config.max_rollouts {
            self.stop = Some(RefineStop::Budget);
        }
        self.stop.is_none()
    }

    /// Against the truth, an accepted trial with `truth_f = f`: Nielsen's update
    /// `λ ← λ·max(1/3, 1 − (2ρ − 1)³)`, `ν ← 2` (the multistart's), with `ρ` the actual
    /// over the predicted decrease of `‖e‖²`. A good model (`ρ ≈ 1`) divides λ by 3, a
    /// poor one keeps it; λ then settles where trials are accepted instead of jumping by
    /// decades between an accepted, over-damped value and a rejected one.
    /// Returns ρ.
    fn nielsen_accept(&mut self, f: f64) -> f64 {
        let m = self.merit();
        let rho = if self.pred > 0.0 {
            (m * m - f * f) / self.pred
        } else {
            0.0
        };
        let t = 2.0 * rho - 1.0;
        let factor = (1.0 - t * t * t).max(1.0 / 3.0);
        self.lambda = (self.lambda * factor).max(TRUTH_LAMBDA_MIN);
        self.nu = 2.0;
        rho
    }

    /// Against the truth, after the trial's truth-model error `et`: Broyden's rank-1
    /// correction `J ← J + (Δe − J s) sᵀ/(sᵀs)`, `s` = trial − η, `Δe = et − e`. The
    /// difference columns are the planner model's; the correction makes J reproduce the
    /// truth model's change along the step just taken, and the next trial costs one
    /// rollout instead of `2K + 1` (the multistart's scheme).
    fn broyden(&mut self, et: &[f64; 6]) {
        let mut s = [[0.0; 2]; K];
        for ((d, t), x) in s
            .iter_mut()
            .flatten()
            .zip(self.trial.iter().flatten())
            .zip(self.eta.iter().flatten())
        {
            *d = t - x;
        }
        let ss: f64 = s.iter().flatten().fold(0.0, |a, v| a + v * v);
        // k = (Δe − J s)/(sᵀs).
        let mut k = [0.0; 6];
        for ((k, a), b) in k.iter_mut().zip(et.iter()).zip(self.e.iter()) {
            *k = a - b;
        }
        for (col, sc) in self.jac.iter().flatten().zip(s.iter().flatten()) {
            for (k, c) in k.iter_mut().zip(col.iter()) {
                *k -= c * sc;
            }
        }
        if !(ss > 0.0 && ss.is_finite() && k.iter().all(|v| v.is_finite())) {
            return;
        }
        for (col, sc) in self.jac.iter_mut().flatten().zip(s.iter().flatten()) {
            for (c, k) in col.iter_mut().zip(k.iter()) {
                *c += k * sc / ss;
            }
        }
        self.corrected = true;
    }

    /// Computes the trial point from the current Jacobian and λ.
    fn plan_trial(&mut self) {
        // A = J Jᵀ (6×6) = Σ_c j_c j_cᵀ.
        let mut a = [[0.0; 6]; 6];
        for col in self.jac.iter().flatten() {
            for (row, ci) in a.iter_mut().zip(col.iter()) {
                for (v, cj) in row.iter_mut().zip(col.iter()) {
                    *v += ci * cj;
                }
            }
        }
        let mut trace = 0.0;
        for (i, row) in a.iter().enumerate() {
            trace += row.get(i).copied().unwrap_or(0.0);
        }
        let damping = self.lambda * trace / 6.0;
        for (i, row) in a.iter_mut().enumerate() {
            if let Some(v) = row.get_mut(i) {
                *v += damping;
            }
        }
        let Some(y) = solve_spd(&a, &self.e) else {
            self.stop = Some(RefineStop::Stalled);
            return;
        };
        let mut trial = self.eta;
        // The linear model's residual e + Jδ, δ = −Jᵀy.
        let mut model = self.e;
        for (t, col) in trial.iter_mut().flatten().zip(self.jac.iter().flatten()) {
            let dot: f64 = col.iter().zip(y.iter()).fold(0.0, |s, (c, y)| s + c * y);
            *t -= dot;
            for (m, c) in model.iter_mut().zip(col.iter()) {
                *m -= c * dot;
            }
        }
        let norm2 = |v: &[f64; 6]| v.iter().fold(0.0, |s, x| s + x * x);
        self.pred = norm2(&self.e) - norm2(&model);
        self.trial = trial;
        self.awaiting = Awaiting::Trial;
    }
}

impl<const N: usize, const K: usize> Optimizer<N, K> for Refiner<N, K> {
    /// The next η; a trial must keep Φ = 0 (cap 0), a Jacobian column is always used;
    /// against the truth, the start point and the trials take the truth model along.
    fn candidate(&self) -> Candidate<K> {
        Candidate {
            eta: one_segment(self.next_eta()),
            cap: if self.at_trial() { 0.0 } else { f64::INFINITY },
            truth: self.wants_truth(),
        }
    }

    fn absorb<O: Observer>(
        &mut self,
        evaluation: &Evaluation<N>,
        _: &mut Stream,
        observer: &mut O,
    ) -> Next {
        let trial = self.at_trial();
        let more = self.take(evaluation.outcome(), evaluation.truth());
        if trial {
            observer.event(&Event::RefineTrial {
                f: self.merit(),
                lambda: self.lambda,
            });
        }
        match (more, self.stop) {
            (true, _) => Next::Continue,
            (false, Some(RefineStop::Reached)) => Next::Done(Stop::Converged),
            (false, Some(RefineStop::Stalled)) => Next::Done(Stop::Stalled),
            (false, _) => Next::Done(Stop::Exhausted),
        }
    }

    fn progress(&self) -> (u32, u32) {
        let c = match self.awaiting {
            Awaiting::Start => 0,
            Awaiting::Column(c) => c as u32,
            Awaiting::Trial => 2 * K as u32,
        };
        (self.iterations, c)
    }

    /// The rest of the Jacobian's columns (each perturbs one component of the unchanging
    /// η; planner model, never cut short).
    fn ahead(&self, j: usize) -> Option<Candidate<K>> {
        let Awaiting::Column(c) = self.awaiting else {
            return None;
        };
        let c = c.checked_add(j)?;
        if c >= 2 * K || self.stop.is_some() {
            return None;
        }
        Some(Candidate::plain(self.column_eta(c), f64::INFINITY))
    }
}

/// Solves `A x = b` for a symmetric positive-definite `A` (Cholesky); `None` if a pivot is
/// not positive or not finite.
pub(crate) fn solve_spd<const M: usize>(a: &[[f64; M]; M], b: &[f64; M]) -> Option<[f64; M]> {
    let mut l = *a;
    solve_spd_in_place(&mut l, b)
}

/// [`solve_spd`], factoring `a` in place: its lower triangle becomes the Cholesky factor
/// `L` (no second M×M matrix on the stack). The same bits as [`solve_spd`].
pub(crate) fn solve_spd_in_place<const M: usize>(
    l: &mut [[f64; M]; M],
    b: &[f64; M],
) -> Option<[f64; M]> {
    // L row by row: L[i][j] = (A[i][j] − Σ_{k<j} L[i][k] L[j][k]) / L[j][j]; row i of the
    // matrix holds A[i][j] until L[i][j] replaces it.
    for i in 0..M {
        let (done, rest) = l.split_at_mut_checked(i)?;
        let li = rest.first_mut()?;
        for j in 0..i {
            let lj = done.get(j)?;
            let dot: f64 = li
                .iter()
                .zip(lj.iter())
                .take(j)
                .fold(0.0, |s, (x, y)| s + x * y);
            let d = *lj.get(j)?;
            let aij = *li.get(j)?;
            *li.get_mut(j)? = (aij - dot) / d;
        }
        let dot: f64 = li.iter().take(i).fold(0.0, |s, x| s + x * x);
        let pivot = li.get(i)? - dot;
        if pivot.is_nan() || pivot <= 0.0 || !pivot.is_finite() {
            return None;
        }
        *li.get_mut(i)? = libm::sqrt(pivot);
    }
    // L y = b, then Lᵀ x = y.
    let mut y = [0.0; M];
    for i in 0..M {
        let li = l.get(i)?;
        let dot: f64 = li
            .iter()
            .zip(y.iter())
            .take(i)
            .fold(0.0, |s, (x, v)| s + x * v);
        *y.get_mut(i)? = (b.get(i)? - dot) / li.get(i)?;
    }
    let mut x = [0.0; M];
    for i in (0..M).rev() {
        let mut s = *y.get(i)?;
        for k in i + 1..M {
            s -= l.get(k)?.get(i)? * x.get(k)?;
        }
        *x.get_mut(i)? = s / l.get(i)?.get(i)?;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// The Cholesky solve leaves a residual < 1e-15 and refuses indefinite and NaN systems.
    /// Verifies RL-REF-002.
    #[test]
    fn spd_solve_matches_the_system() {
        let a = [[4.0, 1.0, 0.5], [1.0, 3.0, 0.2], [0.5, 0.2, 2.0]];
        let b = [1.0, -2.0, 0.5];
        let x = solve_spd(&a, &b).unwrap();
        for i in 0..3 {
            let r: f64 = (0..3).map(|j| a[i][j] * x[j]).sum::<f64>() - b[i];
            assert!(r.abs() < 1e-15);
        }
        assert!(solve_spd(&[[1.0, 2.0], [2.0, 1.0]], &[1.0, 1.0]).is_none());
        assert!(solve_spd(&[[f64::NAN]], &[1.0]).is_none());
    }
}
