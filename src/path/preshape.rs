//! Phase 1 of a two-phase plan (spec §15): the rest-to-rest pre-shaping motion from the
//! task's start `q₀` to the start `q_s` of the reactionless phase, flown while the attitude
//! control system holds the base attitude.
//!
//! Owns [`Preshape`] (the path and its duration) and [`Demand`] (what the attitude control
//! absorbs). The path is the quintic `q(t) = q₀ + Δ·s(t/T)`, `s(u) = 10u³ − 15u⁴ + 6u⁵`,
//! `Δ = q_s − q₀`: at rest at both ends, `max |s'| = 15/8`, `max |s''| = 10/√3`. `T` is the
//! least multiple of `dt` with `15/8·|Δ_r|/T ≤ q̇max` and `10/√3·|Δ_r|/T² ≤ q̈max` for
//! every joint `r`, so the limits of spec §11 hold on the written samples too (a first
//! difference over `dt` is a mean of `q̇`, a second difference over `dt²` a weighted mean of
//! `q̈`). Every joint moves monotonically between `q₀` and `q_s`, so the path stays within
//! the joint limits when both ends do.
//!
//! **Wheels' demand.** With the base attitude held (`ω₀ = 0`) and zero total momentum, the
//! attitude control holds `h_w = −H~bm(q) q̇` (base frame, N m s); [`Preshape::demand`]
//! evaluates it on the written samples and reports the largest `|h_w|` and the largest
//! `|Δh_w|/dt` (N m), and how far the base has translated (CoM conservation) at `q_s`.
//!
//! May use: [`crate::physics`], [`crate::error`]. Sizes: `Preshape<7>` 128 B, `Demand` 40 B
//! (x86-64).

use crate::error::{Error, Param};
use crate::kinematics::Frames;
use crate::model::Robot;
use crate::momentum::Momentum;
use crate::retime::check_positive;
use crate::rollout::{Sample, Sink};
use crate::trajectory::MAX_STEPS;

/// `max |s'(u)|` of the quintic.
const PEAK_RATE: f64 = 15.0 / 8.0;
/// `max |s''(u)|` of the quintic, `10/√3`.
const PEAK_ACCEL: f64 = 5.773_502_691_896_258;

/// The pre-shaping path from `q₀` to `q_s` on the time grid `t_j = j·dt`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Preshape<const N: usize> {
    q0: [f64; N],
    qs: [f64; N],
    steps: u32,
    dt: f64,
}

/// What phase 1 demands of the attitude control, on the written samples (spec §15).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Demand {
    /// Largest `|h_w|` (N m s).
    pub momentum_nms: f64,
    /// Largest `|h_w(t_{j+1}) − h_w(t_j)|/dt` (N m).
    pub torque_nm: f64,
    /// Base translation at `q_s` (m, inertial frame = base frame at `t = 0`).
    pub base_shift_m: [f64; 3],
}

impl<const N: usize> Preshape<N> {
    /// The shortest quintic from `q0` to `qs` (rad) on the grid `dt` (s) with every joint's
    /// rate within `qd_max` (rad/s) and acceleration within `qdd_max` (rad/s²).
    ///
    /// # Errors
    /// A non-finite angle ([`Param::Start`]), a limit or `dt` not positive and finite, or
    /// more than [`MAX_STEPS`] steps.
    pub fn new(
        q0: &[f64; N],
        qs: &[f64; N],
        qd_max: f64,
        qdd_max: f64,
        dt: f64,
    ) -> Result<Self, Error> {
        check_positive(qd_max, Param::VelocityLimit(0))?;
        check_positive(qdd_max, Param::PreshapeAccel)?;
        check_positive(dt, Param::TimeStep)?;
        let mut duration = 0.0f64;
        for (i, (a, b)) in q0.iter().zip(qs.iter()).enumerate() {
            if !(a.is_finite() && b.is_finite()) {
                return Err(Error::NotFinite(Param::Start((i + 1) as u8)));
            }
            let d = libm::fabs(b - a);
            duration = duration
                .max(PEAK_RATE * d / qd_max)
                .max(libm::sqrt(PEAK_ACCEL * d / qdd_max));
        }
        let steps = libm::ceil(duration / dt);
        if steps.is_nan() || steps >= f64::from(MAX_STEPS) {
            return Err(Error::TooManySteps { max: MAX_STEPS });
        }
        Ok(Self {
            q0: *q0,
            qs: *qs,
            steps: steps as u32,
            dt,
        })
    }

    /// No motion: the arm stays at `q` (0 steps).
    #[must_use]
    pub fn at_rest(q: &[f64; N], dt: f64) -> Self {
        Self {
            q0: *q,
            qs: *q,
            steps: 0,
            dt,
        }
    }

    /// The same path flown slower: `steps` steps (s), at least the current number (a
    /// slower quintic keeps every limit the faster one kept).
    #[must_use]
    pub fn stretched(&self, steps: u32) -> Self {
        Self {
            steps: steps.max(self.steps).min(MAX_STEPS),
            ..*self
        }
    }

    /// The continuous minimum duration (s) before rounding up to the grid: the largest of
    /// `15/8·|Δ_r|/q̇max` and `√(10/√3·|Δ_r|/q̈max)` (a smooth measure for a search).
    #[must_use]
    pub fn min_duration(q0: &[f64; N], qs: &[f64; N], qd_max: f64, qdd_max: f64) -> f64 {
        let mut duration = 0.0f64;
        for (a, b) in q0.iter().zip(qs.iter()) {
            let d = libm::fabs(b - a);
            duration = duration
                .max(PEAK_RATE * d / qd_max)
                .max(libm::sqrt(PEAK_ACCEL * d / qdd_max));
        }
        duration
    }

    /// The shortest duration (s) at which the wheels' demand stays within `max_momentum`
    /// (N m s) and `max_torque` (N m), estimated on `points` (≥ 2) evenly spaced points of
    /// the path shape: with `g(u) = H~bm(q(u)) Δ s'(u)`, `h_w = −g/T` and `ḣ_w = −g'/T²`,
    /// so `T ≥ max|g|/max_momentum` and `T ≥ √(max|g'|/max_torque)` (`g'` by differences
    /// between the points). A smooth measure for a search; [`Preshape::demand`] is exact on
    /// the written samples.
    #[must_use]
    pub fn wheel_duration(
        robot: &Robot<N>,
        q0: &[f64; N],
        qs: &[f64; N],
        max_momentum: f64,
        max_torque: f64,
        points: u32,
    ) -> f64 {
        let points = points.max(2);
        let (mut g_max, mut dg_max) = (0.0f64, 0.0f64);
        let mut last = [0.0f64; 3];
        for k in 0..=points {
            let (q, qd) = quintic(q0, qs, f64::from(k) / f64::from(points));
            let g = Momentum::new(robot, &Frames::new(robot, &q)).coupling_momentum(&qd);
            let g = [g.x, g.y, g.z];
            g_max = g_max.max(norm3(&g));
            if k > 0 {
                let d = [g[0] - last[0], g[1] - last[1], g[2] - last[2]];
                dg_max = dg_max.max(norm3(&d) * f64::from(points));
            }
            last = g;
        }
        (g_max / max_momentum).max(libm::sqrt(dg_max / max_torque))
    }

    /// Integration steps `S₁` (`S₁ + 1` samples; 0 when `q_s = q₀`).
    #[must_use]
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Duration `T = S₁·dt` (s).
    #[must_use]
    pub fn duration(&self) -> f64 {
        f64::from(self.steps) * self.dt
    }

    /// The end configuration `q_s` (rad).
    #[must_use]
    pub fn end(&self) -> &[f64; N] {
        &self.qs
    }

    /// Sample `j` (clamped to `0..=S₁`): `(q, q̇)` in rad and rad/s; exactly `q₀` and `q_s`
    /// at the ends, at rest there.
    #[must_use]
    pub fn sample(&self, j: u32) -> ([f64; N], [f64; N]) {
        let j = j.min(self.steps);
        if self.steps == 0 || j == self.steps {
            return (self.qs, [0.0; N]);
        }
        let (q, dq_du) = quintic(&self.q0, &self.qs, f64::from(j) / f64::from(self.steps));
        let t = self.duration();
        (q, dq_du.map(|v| v / t))
    }

    /// Writes the samples `j = 0 … S₁` into `sink` as a rollout writes its own (`t = j·dt`,
    /// `q`, `q̇`): how `phase1.csv` and the flight image's phase-1 digest are made.
    pub fn write<S: Sink<N>>(&self, sink: &mut S) {
        for j in 0..=self.steps {
            let (q, qd) = self.sample(j);
            sink.sample(&Sample {
                step: j,
                t: f64::from(j) * self.dt,
                q,
                qd,
            });
        }
    }

    /// The attitude control's demand along the written samples (one kinematics and one
    /// coupling evaluation per sample, `S₁ + 1` of them).
    #[must_use]
    pub fn demand(&self, robot: &Robot<N>) -> Demand {
        let mut momentum = 0.0f64;
        let mut torque = 0.0f64;
        let mut last = [0.0f64; 3];
        for j in 0..=self.steps {
            let (q, qd) = self.sample(j);
            let h = Momentum::new(robot, &Frames::new(robot, &q)).coupling_momentum(&qd);
            let h = [-h.x, -h.y, -h.z];
            momentum = momentum.max(norm3(&h));
            if j > 0 {
                let d = [h[0] - last[0], h[1] - last[1], h[2] - last[2]];
                torque = torque.max(norm3(&d) / self.dt);
            }
            last = h;
        }
        let c0 = Frames::new(robot, &self.q0).com;
        let cs = Frames::new(robot, &self.qs).com;
        Demand {
            momentum_nms: momentum,
            torque_nm: torque,
            base_shift_m: [c0.x - cs.x, c0.y - cs.y, c0.z - cs.z],
        }
    }
}

/// The quintic at `u ∈ [0, 1]`: `q = q₀ + Δ s(u)` and `dq/du = Δ s'(u)`.
fn quintic<const N: usize>(q0: &[f64; N], qs: &[f64; N], u: f64) -> ([f64; N], [f64; N]) {
    let s = u * u * u * (10.0 + u * (-15.0 + 6.0 * u));
    let ds = 30.0 * u * u * (1.0 - u) * (1.0 - u);
    let mut q = *q0;
    let mut dq = [0.0; N];
    for ((q, dq), (a, b)) in q
        .iter_mut()
        .zip(dq.iter_mut())
        .zip(q0.iter().zip(qs.iter()))
    {
        *q = a + (b - a) * s;
        *dq = (b - a) * ds;
    }
    (q, dq)
}

fn norm3(v: &[f64; 3]) -> f64 {
    libm::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::indexing_slicing)]
mod tests {
    use super::*;
    use crate::model::CHASER7;

    fn path() -> (Robot<7>, Preshape<7>) {
        let robot = Robot::new(&CHASER7).unwrap();
        let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
        let qs = [-70f64, 30.0, 10.0, 60.0, -80.0, -40.0, 5.0].map(f64::to_radians);
        let p = Preshape::new(&q0, &qs, 15f64.to_radians(), 2f64.to_radians(), 0.01).unwrap();
        (robot, p)
    }

    /// The written samples keep the rate and acceleration limits (spec §11), start at q₀,
    /// end at q_s, at rest at both ends; one limit is nearly active.
    #[test]
    fn written_samples_keep_the_limits() {
        let (_, p) = path();
        let (qd_max, qdd_max, dt) = (15f64.to_radians(), 2f64.to_radians(), 0.01);
        let mut worst: f64 = 0.0;
        let s = p.steps();
        for j in 1..s {
            let (a, _) = p.sample(j - 1);
            let (b, _) = p.sample(j);
            let (c, _) = p.sample(j + 1);
            for r in 0..7 {
                assert!(libm::fabs(c[r] - b[r]) / dt <= qd_max);
                let acc = libm::fabs(c[r] - 2.0 * b[r] + a[r]) / (dt * dt);
                assert!(acc <= qdd_max * (1.0 + 1e-9), "{acc} {qdd_max}");
                worst = worst.max(acc / qdd_max);
            }
        }
        assert!(worst > 0.99, "{worst}");
        assert_eq!(
            p.sample(0).0,
            [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians)
        );
        assert_eq!(p.sample(s), (*p.end(), [0.0; 7]));
        assert_eq!(p.sample(0).1, [0.0; 7]);
    }

    /// The demand is positive and finite, and a slower phase 1 asks less momentum of the
    /// wheels (h_w = −H~bm q̇ scales with the rates).
    #[test]
    fn demand_is_finite_and_consistent() {
        let (robot, p) = path();
        let d = p.demand(&robot);
        assert!(d.momentum_nms > 0.0 && d.momentum_nms.is_finite());
        assert!(d.torque_nm > 0.0 && d.torque_nm.is_finite());
        // A path twice as long in time (half the limits) halves the momentum at most.
        let slow =
            Preshape::new(&p.q0, &p.qs, 7.5f64.to_radians(), 0.5f64.to_radians(), 0.01).unwrap();
        assert!(slow.duration() > p.duration());
        assert!(slow.demand(&robot).momentum_nms < d.momentum_nms);
        // The base moves so that the CoM stays put.
        let c0 = Frames::new(&robot, &p.q0).com;
        let cs = Frames::new(&robot, &p.qs).com;
        let shift = d.base_shift_m;
        assert!(libm::fabs(cs.x + shift[0] - c0.x) < 1e-12);
    }

    #[test]
    fn bad_limits_are_typed_errors() {
        let q = [0.0; 7];
        assert_eq!(
            Preshape::new(&q, &q, 1.0, 0.0, 0.01),
            Err(Error::NotPositive(Param::PreshapeAccel))
        );
        assert_eq!(
            Preshape::new(&q, &q, 1.0, 1.0, 0.01).map(|p| p.steps()),
            Ok(0)
        );
        let mut bad = q;
        bad[2] = f64::NAN;
        assert_eq!(
            Preshape::new(&q, &bad, 1.0, 1.0, 0.01),
            Err(Error::NotFinite(Param::Start(3)))
        );
    }
}
