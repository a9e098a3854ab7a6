//! Phase 1 of a two-phase plan (spec §15): the rest-to-rest pre-shaping motion from the
//! task's start `q₀` to the start `q_s` of the reactionless phase, flown while the attitude
//! control system holds the base attitude.
//!
//! Owns [`Preshape`] (the path, its time law and duration), [`PreshapeLimits`] (what it
//! keeps), [`Demand`] (what the attitude control absorbs) and [`PreshapeSetpoints`] (its
//! written samples, one per call, for streaming).
//!
//! **Path and time law.** The path is the straight line `q(t) = q₀ + Δ·s(t/T)`,
//! `Δ = q_s − q₀`, flown with a trapezoidal rate profile of blend fraction `b ∈ (0, ½]`:
//! `s'` rises at the constant `A = V/b` for `u < b`, cruises at `V = 1/(1 − b)`, falls at
//! `−A` for `u > 1 − b` (`b = ½` is the triangle, `V = 2`, `A = 4`). It is at rest at both
//! ends, and every joint moves monotonically between `q₀` and `q_s`, so the path stays within
//! the joint limits when both ends do. The rate is continuous and the acceleration
//! piecewise constant: the time-optimal law for rate and acceleration limits, which the
//! former quintic (`max s' = 15/8`, `max s'' = 10/√3`, issue #30) exceeded by up to 88 %.
//!
//! **Duration.** [`Preshape::fastest`] picks `b` from [`BLENDS`] candidates `j/128` and
//! the least `T` for which, with `d = max_r |Δ_r|`, `V·d/T ≤ q̇max` and `A·d/T² ≤ q̈max`, and
//! the wheels' estimate on [`WHEEL_POINTS`] + 1 evenly spaced points of the path holds:
//! with `g(s) = H~bm(q(s)) Δ`, `h_w = −g ṡ` and `ḣ_w = −(g_s ṡ² + g s̈)`, so
//! `T ≥ max |g| s'/h_max` and `T² ≥ max |g_s s'² + g s''|/τ_max` (`g_s` by differences, the
//! two corners of the profile, where `s' = V` and `|s''| = A`, evaluated explicitly). `T`
//! is then rounded up to a whole number of steps `dt`; the limits of spec §11 hold on the
//! written samples too (a first difference over `dt` is a mean of `q̇`, a second difference
//! over `dt²` a weighted mean of `q̈`), and [`Preshape::demand`] gives the wheels' demand on
//! them exactly. [`Preshape::estimate`] is that `T` before rounding, a continuous measure
//! for a search.
//!
//! **Wheels' demand.** With the base attitude held (`ω₀ = 0`) and zero total momentum, the
//! attitude control holds `h_w = −H~bm(q) q̇` (base frame, N m s); [`Preshape::demand`]
//! evaluates it on the written samples and reports the largest `|h_w|` and the largest
//! `|Δh_w|/dt` (N m), and how far the base has translated (CoM conservation) at `q_s`.
//!
//! May use: [`crate::physics`], [`crate::error`]. Sizes: `Preshape<7>` 136 B, `Demand` 40 B
//! (x86-64). The estimate keeps `WHEEL_POINTS + 1` momentum vectors (792 B) on the stack.

use crate::error::{Error, Param};
use crate::kinematics::Frames;
use crate::model::Robot;
use crate::momentum::Momentum;
use crate::retime::check_positive;
use crate::rollout::{Sample, Sink};
use crate::trajectory::MAX_STEPS;

/// Candidate blend fractions `b = j/128`, `j = 2 … BLENDS + 1` (`1/64 … 1/2`).
pub const BLENDS: u32 = 63;
/// Intervals of the path on which the wheels' demand is estimated.
pub const WHEEL_POINTS: usize = 32;

/// The limits phase 1 keeps (SI units, radians).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PreshapeLimits {
    /// Every joint's rate limit (rad/s).
    pub qd_max: f64,
    /// Every joint's acceleration limit (rad/s²).
    pub qdd_max: f64,
    /// Angular momentum the attitude control can absorb (N m s); `f64::INFINITY` for none.
    pub max_momentum: f64,
    /// Torque the attitude control can apply (N m); `f64::INFINITY` for none.
    pub max_torque: f64,
}

/// The pre-shaping path from `q₀` to `q_s` on the time grid `t_j = j·dt`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Preshape<const N: usize> {
    q0: [f64; N],
    qs: [f64; N],
    /// The blend fraction `b` of the rate profile.
    blend: f64,
    steps: u32,
    dt: f64,
}

/// Phase 1's setpoints `(t, q, q̇)`, one per call, exactly the samples of
/// [`Preshape::write`] (so their digest is `phase1.csv`'s and the flight image's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreshapeSetpoints<const N: usize> {
    preshape: Preshape<N>,
    /// The next sample's index (`S₁ + 1` once the last was produced).
    next: u32,
}

impl<const N: usize> Iterator for PreshapeSetpoints<N> {
    type Item = Sample<N>;

    /// The next setpoint (`t` from 0 to phase 1's duration in steps of `dt`), or `None`
    /// after the last.
    fn next(&mut self) -> Option<Sample<N>> {
        if self.next > self.preshape.steps {
            return None;
        }
        let s = self.preshape.setpoint(self.next);
        self.next = self.next.saturating_add(1);
        Some(s)
    }
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

/// `g(s_k) = H~bm(q(s_k)) Δ` at `s_k = k/WHEEL_POINTS` (N m s per unit of `ṡ`).
type Coupling = [[f64; 3]; WHEEL_POINTS + 1];

impl<const N: usize> Preshape<N> {
    /// The shortest path from `q0` to `qs` (rad) on the grid `dt` (s) with every joint's
    /// rate within `qd_max` (rad/s) and acceleration within `qdd_max` (rad/s²); the wheels
    /// are not asked ([`Preshape::fastest`] asks them).
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
        let limits = PreshapeLimits {
            qd_max,
            qdd_max,
            max_momentum: f64::INFINITY,
            max_torque: f64::INFINITY,
        };
        let d = checked_span(q0, qs, &limits, dt)?;
        let (blend, duration) = shortest(d, &limits, None);
        Self::on_grid(q0, qs, blend, duration, dt)
    }

    /// The shortest path from `q0` to `qs` (rad) on the grid `dt` (s) within `limits`, the
    /// wheels' by their estimate (module docs; [`Preshape::demand`] is exact).
    ///
    /// # Errors
    /// As [`Preshape::new`]; a wheel bound NaN or not positive ([`Param::WheelMomentum`],
    /// [`Param::WheelTorque`]); either may be infinite.
    pub fn fastest(
        robot: &Robot<N>,
        q0: &[f64; N],
        qs: &[f64; N],
        limits: &PreshapeLimits,
        dt: f64,
    ) -> Result<Self, Error> {
        let d = checked_span(q0, qs, limits, dt)?;
        let (blend, duration) = shortest(d, limits, Some(&coupling(robot, q0, qs)));
        Self::on_grid(q0, qs, blend, duration, dt)
    }

    /// [`Preshape::fastest`]'s duration before rounding to the grid (s): a continuous
    /// measure for a search. Infinite where [`Preshape::fastest`] returns an error (a
    /// non-finite angle, a rate or acceleration limit not positive and finite, a wheel
    /// bound NaN or not positive); an infinite wheel bound is no bound.
    #[must_use]
    pub fn estimate(
        robot: &Robot<N>,
        q0: &[f64; N],
        qs: &[f64; N],
        limits: &PreshapeLimits,
    ) -> f64 {
        match checked_span(q0, qs, limits, 1.0) {
            Ok(d) => shortest(d, limits, Some(&coupling(robot, q0, qs))).1,
            Err(_) => f64::INFINITY,
        }
    }

    fn on_grid(
        q0: &[f64; N],
        qs: &[f64; N],
        blend: f64,
        duration: f64,
        dt: f64,
    ) -> Result<Self, Error> {
        let steps = libm::ceil(duration / dt);
        if steps.is_nan() || steps >= f64::from(MAX_STEPS) {
            return Err(Error::TooManySteps { max: MAX_STEPS });
        }
        Ok(Self {
            q0: *q0,
            qs: *qs,
            blend,
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
            blend: 0.5,
            steps: 0,
            dt,
        }
    }

    /// The same path flown slower: `steps` steps (s), at least the current number (the
    /// same profile stretched in time keeps every limit the faster one kept).
    #[must_use]
    pub fn stretched(&self, steps: u32) -> Self {
        Self {
            steps: steps.max(self.steps).min(MAX_STEPS),
            ..*self
        }
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
        let (q, dq_du) = along(
            &self.q0,
            &self.qs,
            self.blend,
            f64::from(j) / f64::from(self.steps),
        );
        let t = self.duration();
        (q, dq_du.map(|v| v / t))
    }

    /// Writes the samples `j = 0 … S₁` into `sink` as a rollout writes its own (`t = j·dt`,
    /// `q`, `q̇`): how `phase1.csv` and the flight image's phase-1 digest are made.
    pub fn write<S: Sink<N>>(&self, sink: &mut S) {
        for j in 0..=self.steps {
            sink.sample(&self.setpoint(j));
        }
    }

    /// Sample `j` as [`Preshape::write`] writes it (`t = j·dt`).
    fn setpoint(&self, j: u32) -> Sample<N> {
        let (q, qd) = self.sample(j);
        Sample {
            step: j,
            t: f64::from(j) * self.dt,
            q,
            qd,
        }
    }

    /// The samples of [`Preshape::write`], one per call: how
    /// flight software streams phase 1 to the joint controllers (an [`Iterator`]).
    #[must_use]
    pub fn setpoints(&self) -> PreshapeSetpoints<N> {
        PreshapeSetpoints {
            preshape: *self,
            next: 0,
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

/// The largest `|Δ_r|` (rad), after checking the angles, limits and `dt`.
fn checked_span<const N: usize>(
    q0: &[f64; N],
    qs: &[f64; N],
    limits: &PreshapeLimits,
    dt: f64,
) -> Result<f64, Error> {
    check_positive(limits.qd_max, Param::VelocityLimit(0))?;
    check_positive(limits.qdd_max, Param::PreshapeAccel)?;
    check_positive(dt, Param::TimeStep)?;
    for (v, p) in [
        (limits.max_momentum, Param::WheelMomentum),
        (limits.max_torque, Param::WheelTorque),
    ] {
        if v.is_nan() {
            return Err(Error::NotFinite(p));
        }
        if v <= 0.0 {
            return Err(Error::NotPositive(p));
        }
    }
    let mut d = 0.0f64;
    for (i, (a, b)) in q0.iter().zip(qs.iter()).enumerate() {
        if !(a.is_finite() && b.is_finite()) {
            return Err(Error::NotFinite(Param::Start((i + 1) as u8)));
        }
        d = d.max(libm::fabs(b - a));
    }
    Ok(d)
}

/// The wheels' coupling `g(s_k)` on the estimate's points.
fn coupling<const N: usize>(robot: &Robot<N>, q0: &[f64; N], qs: &[f64; N]) -> Coupling {
    let mut delta = [0.0; N];
    for (d, (a, b)) in delta.iter_mut().zip(q0.iter().zip(qs.iter())) {
        *d = b - a;
    }
    let mut g = [[0.0; 3]; WHEEL_POINTS + 1];
    for (k, g) in g.iter_mut().enumerate() {
        let s = k as f64 / WHEEL_POINTS as f64;
        let mut q = *q0;
        for (q, d) in q.iter_mut().zip(delta.iter()) {
            *q += d * s;
        }
        let v = Momentum::new(robot, &Frames::new(robot, &q)).coupling_momentum(&delta);
        *g = [v.x, v.y, v.z];
    }
    g
}

/// The blend and the least duration (s) for the span `d` (rad) within `limits`, the
/// wheels' estimated on `g` when given (module docs).
fn shortest(d: f64, limits: &PreshapeLimits, g: Option<&Coupling>) -> (f64, f64) {
    let mut best = (0.5, f64::INFINITY);
    if d == 0.0 {
        return (0.5, 0.0);
    }
    for j in 2..=BLENDS + 1 {
        let b = f64::from(j) / 128.0;
        let v = 1.0 / (1.0 - b);
        let a = v / b;
        let mut t = (v * d / limits.qd_max).max(libm::sqrt(a * d / limits.qdd_max));
        if let Some(g) = g {
            let (momentum, torque) = wheel_peaks(g, b);
            t = t
                .max(momentum / limits.max_momentum)
                .max(libm::sqrt(torque / limits.max_torque));
        }
        if t < best.1 {
            best = (b, t);
        }
    }
    best
}

/// The largest `|g| s'` and `|g_s s'² + g s''|` of blend `b` over the points and the
/// profile's two corners.
fn wheel_peaks(g: &Coupling, b: f64) -> (f64, f64) {
    let p = WHEEL_POINTS as f64;
    let v = 1.0 / (1.0 - b);
    let a = v / b;
    let corner = v * b / 2.0;
    let (mut momentum, mut torque) = (0.0f64, 0.0f64);
    for (k, gk) in g.iter().enumerate() {
        let s = k as f64 / p;
        let (sd, sdd) = if s < corner {
            (libm::sqrt(2.0 * a * s), a)
        } else if s > 1.0 - corner {
            (libm::sqrt(2.0 * a * (1.0 - s)), -a)
        } else {
            (v, 0.0)
        };
        let gs = slope(g, k);
        momentum = momentum.max(norm3(gk) * sd);
        torque = torque.max(norm3(&combine(&gs, sd * sd, gk, sdd)));
    }
    for (s, sdd) in [(corner, a), (1.0 - corner, -a)] {
        let x = s * p;
        let k = (libm::floor(x) as usize).min(WHEEL_POINTS - 1);
        let w = x - k as f64;
        let (lo, hi) = (g.get(k), g.get(k + 1));
        if let (Some(lo), Some(hi)) = (lo, hi) {
            let gk = [
                lo[0] + (hi[0] - lo[0]) * w,
                lo[1] + (hi[1] - lo[1]) * w,
                lo[2] + (hi[2] - lo[2]) * w,
            ];
            let gs = [
                (hi[0] - lo[0]) * p,
                (hi[1] - lo[1]) * p,
                (hi[2] - lo[2]) * p,
            ];
            momentum = momentum.max(norm3(&gk) * v);
            torque = torque.max(norm3(&combine(&gs, v * v, &gk, sdd)));
        }
    }
    (momentum, torque)
}

/// `dg/ds` at point `k`: central differences inside, one-sided at the ends.
fn slope(g: &Coupling, k: usize) -> [f64; 3] {
    let lo = k.saturating_sub(1);
    let hi = (k + 1).min(WHEEL_POINTS);
    match (g.get(lo), g.get(hi)) {
        (Some(a), Some(b)) => {
            let h = (hi - lo) as f64 / WHEEL_POINTS as f64;
            [(b[0] - a[0]) / h, (b[1] - a[1]) / h, (b[2] - a[2]) / h]
        }
        _ => [0.0; 3],
    }
}

/// `x·α + y·β`.
fn combine(x: &[f64; 3], alpha: f64, y: &[f64; 3], beta: f64) -> [f64; 3] {
    [
        x[0] * alpha + y[0] * beta,
        x[1] * alpha + y[1] * beta,
        x[2] * alpha + y[2] * beta,
    ]
}

/// The path at `u ∈ [0, 1]` with blend `b`: `q = q₀ + Δ s(u)` and `dq/du = Δ s'(u)`.
fn along<const N: usize>(q0: &[f64; N], qs: &[f64; N], b: f64, u: f64) -> ([f64; N], [f64; N]) {
    let v = 1.0 / (1.0 - b);
    let a = v / b;
    let (s, ds) = if u < b {
        (0.5 * a * u * u, a * u)
    } else if u > 1.0 - b {
        let w = 1.0 - u;
        (1.0 - 0.5 * a * w * w, a * w)
    } else {
        (v * (u - 0.5 * b), v)
    };
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

    /// With only rate and acceleration limits, the duration is the time-optimal one,
    /// `d/q̇max + q̇max/q̈max` (cruising) or `2√(d/q̈max)` (not), to the blend grid's
    /// resolution and one step; the quintic it replaced was up to 88 % longer.
    #[test]
    fn joint_limited_duration_is_time_optimal() {
        let (v, a, dt) = (15f64.to_radians(), 2f64.to_radians(), 0.01);
        for deg in [1.0f64, 5.0, 20.0, 56.25, 90.0, 150.0] {
            let d = deg.to_radians();
            let optimum = if d >= v * v / a {
                d / v + v / a
            } else {
                2.0 * libm::sqrt(d / a)
            };
            let p = Preshape::new(&[0.0; 7], &[d, 0.0, 0.0, 0.0, 0.0, 0.0, -d / 2.0], v, a, dt)
                .unwrap();
            let t = p.duration();
            assert!(t >= optimum - 1e-12, "{deg}: {t} < {optimum}");
            assert!(t <= optimum * 1.01 + dt, "{deg}: {t} vs {optimum}");
            let quintic = (15.0 / 8.0 * d / v).max(libm::sqrt(10.0 / libm::sqrt(3.0) * d / a));
            assert!(t < quintic, "{deg}: {t} vs the quintic's {quintic}");
        }
    }

    /// When the wheels bind, [`Preshape::fastest`] flies longer than the joints alone need,
    /// and its estimate of the wheels' demand is within 2 % of the exact demand on the
    /// written samples; [`Preshape::estimate`] is its duration before rounding.
    #[test]
    fn fastest_meets_the_wheels_by_its_estimate() {
        let (robot, joints_only) = path();
        let free = joints_only.demand(&robot);
        for (momentum, torque) in [
            (free.momentum_nms / 2.0, f64::INFINITY),
            (f64::INFINITY, free.torque_nm / 3.0),
            (free.momentum_nms / 2.0, free.torque_nm / 5.0),
        ] {
            let limits = PreshapeLimits {
                qd_max: 15f64.to_radians(),
                qdd_max: 2f64.to_radians(),
                max_momentum: momentum,
                max_torque: torque,
            };
            let p =
                Preshape::fastest(&robot, &joints_only.q0, &joints_only.qs, &limits, 0.01).unwrap();
            assert!(p.duration() > joints_only.duration());
            let t = Preshape::estimate(&robot, &joints_only.q0, &joints_only.qs, &limits);
            assert!(t <= p.duration() && p.duration() < t + 0.01);
            let d = p.demand(&robot);
            let worst = (d.momentum_nms / momentum).max(d.torque_nm / torque);
            assert!(worst <= 1.02 && worst > 0.9, "{worst}");
        }
    }

    /// A NaN or non-positive wheel bound is a typed error naming it; infinity is none.
    #[test]
    fn wheel_bounds_are_checked() {
        let (robot, p) = path();
        let mut limits = PreshapeLimits {
            qd_max: 1.0,
            qdd_max: 1.0,
            max_momentum: f64::NAN,
            max_torque: f64::INFINITY,
        };
        assert_eq!(
            Preshape::fastest(&robot, &p.q0, &p.qs, &limits, 0.01),
            Err(Error::NotFinite(Param::WheelMomentum))
        );
        limits.max_momentum = 1.0;
        limits.max_torque = 0.0;
        assert_eq!(
            Preshape::fastest(&robot, &p.q0, &p.qs, &limits, 0.01),
            Err(Error::NotPositive(Param::WheelTorque))
        );
        assert_eq!(
            Preshape::estimate(&robot, &p.q0, &p.qs, &limits),
            f64::INFINITY
        );
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
