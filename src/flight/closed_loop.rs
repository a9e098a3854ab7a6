//! Closed-loop execution of a plan (spec §12): one call per control cycle turns the
//! cycle's measurements into the joint-rate command of the next cycle, so that the base
//! holds its attitude on a robot whose mass properties differ from the planner's model.
//!
//! Owns [`LoopConfig`] (gains, filter and fault settings: immutable, validated once),
//! [`Measurement`] (what the sensors gave at the start of a cycle), [`Executor`] (the
//! estimates and the mode), [`Command`] (what it returns each cycle), the mode machine
//! [`Mode`] / [`Fault`], and [`PlanLoop`] (an executor with the plan's rollout it follows,
//! for a caller without a plan stream: the C ABI's `rl_loop`).
//!
//! **Timing** (spec §12). Measurements taken at `t_k = k T_c` give the command applied
//! through cycle `k + 1`, `[t_{k+1}, t_{k+2})`, held constant (one period of latency). The
//! command of cycle 0 is the plan's own ([`Executor::new`]); [`Executor::step`] is the cycle. The caller passes, with the
//! measurements of cycle `k`, the plan's configuration at `t_{k+2}` (its last one once the
//! plan has ended): the nominal command is the plan's chord `(q_p(t_{k+2}) − q_p(t_{k+1}))/T_c`.
//!
//! **Validation at the edge**, before any arithmetic. A measurement that is not finite or
//! out of range (a star-tracker quaternion whose norm is not 1 within 1e-6, a gyro rate
//! above [`LoopConfig::max_gyro_rate`], a joint beyond its limits by more than
//! [`JOINT_RANGE_MARGIN`]) is a fault at once. A missing one is tolerated (the mode is
//! [`Mode::Degraded`]: joints dead-reckoned from the commands, the attitude propagated with
//! the model's base rate for the commands when the gyro is missing) for
//! [`LoopConfig::max_missing_cycles`] consecutive cycles, then it is a fault. A joint whose
//! reading moved more than [`LoopConfig::tracking_tolerance`] away from where the commands
//! took it (a frozen encoder, a joint that does not follow) is a fault, as is a base
//! attitude estimate beyond [`LoopConfig::base_limit`].
//!
//! **Safe state.** On a fault the executor stops the arm: every joint's rate goes to zero
//! by at most `qdd_max T_c` per cycle ([`Mode::Stopping`]), then stays zero
//! ([`Mode::Stopped`]); the fault is reported in the [`Command`] of the cycle that found it
//! ([`Command::event`]) and in the mode. Nothing leaves the safe state.
//!
//! **Attitude estimate.** `A`, the base attitude in the star tracker's frame: the gyro's
//! increments, pulled toward each star-tracker reading by [`LoopConfig::filter_gain`];
//! `R̂₀`, the attitude at `t = 0`: the running mean of `reading · G⁻¹` over every star
//! reading, `G` the gyro's rotation since `t = 0` (gain `1/n`, `n` capped at
//! [`MEAN_CAP`]). The base rotation the loop holds to zero is `θ̂ = log(R̂₀⁻¹ A)`; at the
//! first reading it is exactly 0, as the base rotation is by definition.
//!
//! **Law** (nominal model, at the configuration `q₁` predicted for `t_{k+1}` from the
//! reading and the pending command; `θ₁` likewise, with the model's base rate):
//! - base: `c_b = k_b Bᵀ(B Bᵀ + μ² I)⁻¹ θ₁`, `B = H~b⁻¹ H~bm` (the base turns at
//!   `−B q̇`, so this makes `θ̇ = −k_b θ`);
//! - end effector: `c_e = (J P)ᵀ (J P (J P)ᵀ + λ² I)⁻¹ k_e W e`, `P = I − Bᵀ(BBᵀ)⁻¹B` the
//!   projector on the reaction null space, `J` the generalized Jacobian, `e` the pose error
//!   (spec §6) of `(q₁, θ₁)` against the plan's pose at `t_{k+1}`, `W` = 1 on position
//!   (m) and [`LoopConfig::orientation_length`] on orientation (rad → m); `c_e` turns the
//!   base not at all on the nominal model;
//! - command `u = chord + c_b + c_e`, then limited per joint: its change from the previous
//!   command to `qdd_max T_c`, then its rate to the joint's velocity limit, the position
//!   it reaches at `t_{k+2}` to the joint limits, and, near the end of the flight, to what
//!   can still be stopped within the acceleration limit by the last cycle (the acceleration
//!   limit wins when they conflict, then the rate limit).
//!
//! After `t_f` the loop goes on for [`LoopConfig::extend_cycles`] with the plan at rest,
//! then commands zero: [`Mode::Done`].
//!
//! Every loop is bounded by `N` or a constant; nothing allocates; one cycle costs two
//! forward kinematics, one momentum pass and one generalized Jacobian of the nominal
//! model, and small solves (3×3, 6×6). `size_of::<Executor<7>>()` is in `tests/sizes.rs`.

use crate::error::{Error, Param};
use crate::geometry::{Sym3, Vec3, normalized, quat_exp, quat_log, quat_mul};
use crate::kinematics::{Frames, IDENTITY_WXYZ};
use crate::model::Robot;
use crate::momentum::{Momentum, generalized_jacobian};
use crate::refine::solve_spd;
use nalgebra::{SMatrix, SVector};

/// How far (rad) a joint reading may lie beyond the joint's limits before it is out of
/// range (the limits are the plan's; a real joint may overshoot them slightly).
pub const JOINT_RANGE_MARGIN: f64 = 0.05;

/// Largest accepted `|‖q‖ − 1|` of a star-tracker quaternion.
pub const QUATERNION_TOLERANCE: f64 = 1e-6;

/// Most cycles [`fly_ideal`] waits for the arm to come to rest after a fault.
pub const MAX_STOP_CYCLES: u32 = 10_000;

/// Cap of the sample count of the running mean of the initial attitude (the gain stays at
/// least `1/MEAN_CAP`).
pub const MEAN_CAP: u32 = 10_000;

/// Gains, filter and fault settings of the loop (immutable; [`LoopConfig::validate`] once).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LoopConfig {
    /// Control period `T_c` (s): a whole multiple of the plan's `dt`.
    pub period: f64,
    /// Base-attitude gain `k_b` (1/s).
    pub base_gain: f64,
    /// End-effector gain `k_e` (1/s); 0 turns the end-effector task off.
    pub ee_gain: f64,
    /// Damping `μ` of the base pseudo-inverse (dimensionless, as `B`).
    pub base_damping: f64,
    /// Damping `λ` of the end-effector pseudo-inverse (m/rad).
    pub ee_damping: f64,
    /// Length (m) that weighs orientation errors against position errors in the
    /// end-effector task.
    pub orientation_length: f64,
    /// Weight `w_d` (1/m²) of the end effector's motion in the base correction (0: the
    /// minimum-norm joint rate).
    pub drag_weight: f64,
    /// Pull of the attitude estimate toward each star-tracker reading, in (0, 1].
    pub filter_gain: f64,
    /// Pull of the drift estimate (the base rate the model does not explain) toward each
    /// cycle's, in [0, 1]; 0 turns the drift feed-forward off.
    pub drift_gain: f64,
    /// Consecutive cycles a sensor may be missing before it is a fault.
    pub max_missing_cycles: u32,
    /// Base attitude estimate (rad) beyond which the loop goes to the safe state.
    pub base_limit: f64,
    /// Largest difference (rad) between a joint's reading and where the commands took it.
    pub tracking_tolerance: f64,
    /// Largest gyro rate (rad/s) that is in range.
    pub max_gyro_rate: f64,
    /// Joint acceleration limit `qdd_max` (rad/s²): the most a command changes per
    /// cycle is `qdd_max T_c`.
    pub qdd_max: f64,
    /// Cycles of correction after `t_f`, the plan at rest.
    pub extend_cycles: u32,
}

impl LoopConfig {
    /// The defaults: 10 Hz, `k_b` = 4 /s, `k_e` = 1 /s, `μ` = 1e-3, `λ` = 0.05 m,
    /// orientation length 1 m, no drag weight, filter gain 0.05, no drift feed-forward,
    /// 3 missing cycles, base limit 0.1°,
    /// tracking tolerance 1e-3 rad, gyro range 0.2 rad/s, `qdd_max` = 0.5 rad/s²,
    /// 30 cycles (3 s) after `t_f`.
    pub const DEFAULT: Self = Self {
        period: 0.1,
        base_gain: 4.0,
        ee_gain: 1.0,
        base_damping: 1e-3,
        ee_damping: 0.05,
        orientation_length: 1.0,
        drag_weight: 0.0,
        filter_gain: 0.05,
        drift_gain: 0.0,
        max_missing_cycles: 3,
        base_limit: 0.1 * core::f64::consts::PI / 180.0,
        tracking_tolerance: 1e-3,
        max_gyro_rate: 0.2,
        qdd_max: 0.5,
        extend_cycles: 30,
    };

    /// Checks every setting.
    ///
    /// # Errors
    /// [`Error::NotFinite`] / [`Error::NotPositive`] / [`Error::Negative`] naming the
    /// setting ([`Param::ControlPeriod`] …); a filter gain above 1 is
    /// [`Error::LoopSetting`].
    pub fn validate(&self) -> Result<(), Error> {
        let positive = [
            (self.period, Param::ControlPeriod),
            (self.orientation_length, Param::OrientationLength),
            (self.filter_gain, Param::FilterGain),
            (self.base_limit, Param::BaseLimit),
            (self.tracking_tolerance, Param::TrackingTolerance),
            (self.max_gyro_rate, Param::GyroRange),
            (self.qdd_max, Param::LoopAccel),
        ];
        for (v, p) in positive {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v <= 0.0 {
                return Err(Error::NotPositive(p));
            }
        }
        let non_negative = [
            (self.base_gain, Param::BaseGain),
            (self.ee_gain, Param::EeGain),
            (self.base_damping, Param::BaseDamping),
            (self.ee_damping, Param::EeDamping),
            (self.drag_weight, Param::DragWeight),
            (self.drift_gain, Param::DriftGain),
        ];
        for (v, p) in non_negative {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v < 0.0 {
                return Err(Error::Negative(p));
            }
        }
        if self.filter_gain > 1.0 {
            return Err(Error::LoopSetting(Param::FilterGain));
        }
        if self.drift_gain > 1.0 {
            return Err(Error::LoopSetting(Param::DriftGain));
        }
        // With the one-cycle prediction an error decays as (1 − k T_c) per cycle: it
        // oscillates from k T_c > 1 and diverges from 2.
        if self.base_gain * self.period >= 1.0 {
            return Err(Error::LoopSetting(Param::BaseGain));
        }
        if self.ee_gain * self.period >= 1.0 {
            return Err(Error::LoopSetting(Param::EeGain));
        }
        if self.ee_gain > 0.0 && self.ee_damping <= 0.0 {
            // J P has rank N − 3 < 6 at most: without damping its system is singular.
            return Err(Error::NotPositive(Param::EeDamping));
        }
        Ok(())
    }
}

/// What the sensors gave at the start of a cycle; `None` is a missing measurement.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Measurement<const N: usize> {
    /// Star tracker: base attitude in its frame, unit quaternion `[w, x, y, z]`.
    pub star_tracker: Option<[f64; 4]>,
    /// Gyro: the base's mean angular rate over the last cycle (rad/s, base frame); ignored
    /// at cycle 0.
    pub gyro: Option<[f64; 3]>,
    /// Joint encoders (rad).
    pub joints: Option<[f64; N]>,
}

/// Which sensor a fault concerns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Sensor {
    /// The star tracker.
    StarTracker,
    /// The gyro.
    Gyro,
    /// The joint encoders.
    Joints,
}

/// Why the loop went to the safe state.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Fault {
    /// A measurement is NaN or infinite.
    NotFinite(Sensor),
    /// A measurement is out of range (joint `joint` 1-based for the encoders, 0 otherwise).
    OutOfRange {
        /// The sensor.
        sensor: Sensor,
        /// The joint (1-based), 0 for the star tracker and the gyro.
        joint: u8,
    },
    /// A sensor gave nothing for more than [`LoopConfig::max_missing_cycles`] cycles.
    Stale(Sensor),
    /// Joint `joint` (1-based) is not where the commands since `t = 0` took it (a joint not
    /// following, a frozen encoder).
    Tracking {
        /// The joint (1-based).
        joint: u8,
        /// Reading minus the start plus every command times its cycle (rad).
        error: f64,
    },
    /// The base attitude estimate (rad) is beyond [`LoopConfig::base_limit`].
    BaseError(f64),
    /// The nominal model failed at the measured configuration.
    Model(Error),
}

/// The executor's mode.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Mode {
    /// Every sensor fresh, the plan and the corrections flown.
    Nominal,
    /// A sensor missing for at most [`LoopConfig::max_missing_cycles`] cycles: flown on
    /// dead reckoning.
    Degraded(Sensor),
    /// A fault: the joints decelerate to rest within the acceleration limit.
    Stopping(Fault),
    /// At rest after a fault.
    Stopped(Fault),
    /// The flight is over (`t_f` and the extension): commands are zero.
    Done,
}

/// What one cycle returns.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Command<const N: usize> {
    /// Joint rates (rad/s) to hold through the next cycle.
    pub rate: [f64; N],
    /// The mode after this cycle.
    pub mode: Mode,
    /// The fault found in this cycle, if it found one (the transition to the safe state).
    pub event: Option<Fault>,
    /// Whether a limit changed the command of some joint.
    pub limited: bool,
}

/// The closed-loop executor's state: estimates, the pending command, the mode.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Executor<const N: usize> {
    config: LoopConfig,
    /// Plan cycles `round(t_f / T_c)`.
    plan_cycles: u32,
    /// The next measurement's cycle `k`.
    cycle: u32,
    /// CoM at `t = 0` of the nominal model (m).
    com0: Vec3,
    /// Velocity limit per joint (rad/s).
    qd_limit: [f64; N],
    /// The plan's configuration at `t_{k+1}`.
    plan_next: [f64; N],
    /// The command applied through cycle `k` (decided at `k − 1`).
    applying: [f64; N],
    /// The command applied through cycle `k − 1`.
    applied: [f64; N],
    /// Joint estimate at `t_k` before the reading: the last reading plus the commands.
    joints: [f64; N],
    /// Where every command since `t = 0` took the joints (rad), for the tracking check.
    reckoned: [f64; N],
    /// Filtered base attitude in the star tracker's frame.
    attitude: [f64; 4],
    /// The gyro's (or the model's) rotation since `t = 0`.
    gyro_rotation: [f64; 4],
    /// Running mean of the initial attitude, and its sample count (0: no reading yet).
    initial: [f64; 4],
    readings: u32,
    /// The base rate the model does not explain (rad/s): the gyro's less the model's for
    /// the commands, low-passed by [`LoopConfig::drift_gain`].
    drift: Vec3,
    /// Consecutive missing cycles per sensor (star tracker, gyro, joints).
    missing: [u32; 3],
    mode: Mode,
}

impl<const N: usize> Executor<N> {
    /// The executor of a plan for `robot` (the nominal model) starting at `q0`, of
    /// duration `tf` (s); `plan_first` is the plan's configuration at `t_1 = T_c` and
    /// the returned command, the plan's chord over cycle 0, is what to fly through it.
    ///
    /// # Errors
    /// An invalid configuration ([`LoopConfig::validate`]); [`Error::LoopSetting`] with
    /// [`Param::ControlPeriod`] if `tf` is not a whole number of periods (relative
    /// tolerance 1e-9); [`Error::NotFinite`] for a non-finite `q0` or `plan_first`.
    pub fn new(
        config: LoopConfig,
        robot: &Robot<N>,
        q0: &[f64; N],
        tf: f64,
        plan_first: &[f64; N],
    ) -> Result<(Self, [f64; N]), Error> {
        config.validate()?;
        if !tf.is_finite() {
            return Err(Error::NotFinite(Param::FinalTime));
        }
        let cycles = libm::round(tf / config.period);
        if !(1.0..=f64::from(u32::MAX / 2)).contains(&cycles)
            || libm::fabs(cycles * config.period - tf) > 1e-9 * tf
        {
            return Err(Error::LoopSetting(Param::ControlPeriod));
        }
        for (i, (a, b)) in q0.iter().zip(plan_first.iter()).enumerate() {
            if !a.is_finite() {
                return Err(Error::NotFinite(Param::Start(joint_label(i))));
            }
            if !b.is_finite() {
                return Err(Error::NotFinite(Param::Start(joint_label(i))));
            }
        }
        let desc = robot.desc();
        let qd_limit = core::array::from_fn(|i| {
            let v = desc.joints.get(i).map_or(0.0, |j| j.velocity);
            if v > 0.0 { v } else { robot.qd_max() }
        });
        // The plan's chord over cycle 0, from rest: within one cycle's acceleration (which
        // the last cycle can stop) and the rate limit.
        let dv = config.qdd_max * config.period;
        let first: [f64; N] = core::array::from_fn(|i| {
            let v = (get(plan_first, i) - get(q0, i)) / config.period;
            let bound = dv.min(get(&qd_limit, i));
            v.max(-bound).min(bound)
        });
        let mut exec = Self::parked(config);
        // In range by the check above.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        {
            exec.plan_cycles = cycles as u32;
        }
        exec.com0 = Frames::new(robot, q0).com;
        exec.qd_limit = qd_limit;
        exec.plan_next = *plan_first;
        exec.applying = first;
        exec.joints = *q0;
        exec.reckoned = *q0;
        exec.mode = Mode::Nominal;
        Ok((exec, first))
    }

    /// An executor that flies nothing (no cycles, at rest at the origin, done): what
    /// [`Executor::new`] starts from, and the placeholder [`PlanLoop::start_in`] replaces
    /// before any use.
    fn parked(config: LoopConfig) -> Self {
        Self {
            config,
            plan_cycles: 0,
            cycle: 0,
            com0: Vec3::zeros(),
            qd_limit: [0.0; N],
            plan_next: [0.0; N],
            applying: [0.0; N],
            applied: [0.0; N],
            joints: [0.0; N],
            reckoned: [0.0; N],
            attitude: IDENTITY_WXYZ,
            gyro_rotation: IDENTITY_WXYZ,
            initial: IDENTITY_WXYZ,
            readings: 0,
            drift: Vec3::zeros(),
            missing: [0; 3],
            mode: Mode::Done,
        }
    }

    /// The mode.
    #[must_use]
    pub fn mode(&self) -> Mode {
        self.mode
    }

    /// Each joint's rate limit as the executor applies it (rad/s): the joint's own
    /// velocity limit, or the robot's `q̇_max` where the joint has none.
    #[must_use]
    pub fn rate_limits(&self) -> &[f64; N] {
        &self.qd_limit
    }

    /// The next measurement's cycle `k`.
    #[must_use]
    pub fn cycle(&self) -> u32 {
        self.cycle
    }

    /// Cycles of the whole flight: the plan's and the extension.
    #[must_use]
    pub fn total_cycles(&self) -> u32 {
        self.plan_cycles.saturating_add(self.config.extend_cycles)
    }

    /// The base rotation since `t = 0` the loop estimates (rotation vector, rad).
    #[must_use]
    pub fn base_estimate(&self) -> [f64; 3] {
        let v = quat_log(quat_mul(conj(self.initial), self.attitude));
        [v.x, v.y, v.z]
    }

    /// The joint estimate at the last measurement (rad).
    #[must_use]
    pub fn joint_estimate(&self) -> &[f64; N] {
        &self.joints
    }

    /// One control cycle: the measurements taken at `t_k` and the plan's configuration at
    /// `t_{k+2}` (its last once the plan has ended) give the command to hold through cycle
    /// `k + 1`. Never fails: a bad measurement or a model failure is a [`Fault`], and the
    /// command then brings the arm to rest.
    ///
    /// Verifies RL-LOOP-001.
    ///
    /// ```
    /// use reactionless::closed_loop::{Executor, Fault, LoopConfig, Measurement, Mode, Sensor};
    /// use reactionless::reference;
    /// let task = reference::paper_task().unwrap();
    /// let q0 = *task.start();
    /// // A plan that holds still (t_1's configuration is the start): cycle 0's command is 0.
    /// let (mut exec, first) = Executor::new(LoopConfig::DEFAULT, task.robot(), &q0, 30.0, &q0).unwrap();
    /// assert_eq!(first, [0.0; 7]);
    /// let fine = Measurement { star_tracker: Some([1.0, 0.0, 0.0, 0.0]), gyro: Some([0.0; 3]), joints: Some(q0) };
    /// assert_eq!(exec.step(task.robot(), &fine, &q0).mode, Mode::Nominal);
    /// let bad = Measurement { joints: Some([f64::NAN; 7]), ..fine };
    /// let c = exec.step(task.robot(), &bad, &q0);
    /// let fault = Fault::NotFinite(Sensor::Joints);
    /// assert_eq!(c.event, Some(fault));
    /// assert_eq!(c.mode, Mode::Stopped(fault)); // already at rest
    /// assert_eq!(c.rate, [0.0; 7]);
    /// ```
    pub fn step(
        &mut self,
        robot: &Robot<N>,
        m: &Measurement<N>,
        plan_ahead: &[f64; N],
    ) -> Command<N> {
        let k = self.cycle;
        self.cycle = self.cycle.saturating_add(1);
        if let Mode::Stopping(f) | Mode::Stopped(f) = self.mode {
            return self.stop(f, None);
        }
        if self.mode == Mode::Done {
            return self.finish();
        }
        let mut fault = self.validate(robot, m, k);
        if fault.is_none() {
            fault = self.estimate(robot, m, k).err();
        }
        if let Some(f) = fault {
            self.mode = Mode::Stopping(f);
            return self.stop(f, Some(f));
        }
        if k.saturating_add(1) >= self.total_cycles() {
            return self.finish();
        }
        match self.law(robot, plan_ahead, k) {
            Ok((rate, limited)) => {
                self.advance(rate);
                Command {
                    rate,
                    mode: self.mode,
                    event: None,
                    limited,
                }
            }
            Err(e) => {
                let f = Fault::Model(e);
                self.mode = Mode::Stopping(f);
                self.stop(f, Some(f))
            }
        }
    }

    /// Checks the measurements; sets the mode (nominal, degraded) and the missing counts.
    #[inline(never)]
    fn validate(&mut self, robot: &Robot<N>, m: &Measurement<N>, k: u32) -> Option<Fault> {
        let cfg = &self.config;
        if let Some(q) = &m.star_tracker {
            if q.iter().any(|v| !v.is_finite()) {
                return Some(Fault::NotFinite(Sensor::StarTracker));
            }
            let n = libm::sqrt(q.iter().fold(0.0, |s, v| s + v * v));
            if libm::fabs(n - 1.0) > QUATERNION_TOLERANCE {
                return Some(Fault::OutOfRange {
                    sensor: Sensor::StarTracker,
                    joint: 0,
                });
            }
        }
        // The gyro's rate over the last cycle means nothing at cycle 0: not checked there.
        if let Some(w) = m.gyro.as_ref().filter(|_| k > 0) {
            if w.iter().any(|v| !v.is_finite()) {
                return Some(Fault::NotFinite(Sensor::Gyro));
            }
            let n = libm::sqrt(w.iter().fold(0.0, |s, v| s + v * v));
            if n > cfg.max_gyro_rate {
                return Some(Fault::OutOfRange {
                    sensor: Sensor::Gyro,
                    joint: 0,
                });
            }
        }
        if let Some(q) = &m.joints {
            let limits = robot.lower().iter().zip(robot.upper().iter());
            for (i, (v, (lo, hi))) in q.iter().zip(limits).enumerate() {
                if !v.is_finite() {
                    return Some(Fault::NotFinite(Sensor::Joints));
                }
                if *v < lo - JOINT_RANGE_MARGIN || *v > hi + JOINT_RANGE_MARGIN {
                    return Some(Fault::OutOfRange {
                        sensor: Sensor::Joints,
                        joint: joint_label(i),
                    });
                }
            }
            // The joints where every command since t = 0 took them: a joint that does not
            // follow (slips, lags) or a frozen reading drifts away from it, cycle after
            // cycle (the sum telescopes, so the encoders' rounding does not add up).
            for (i, (v, e)) in q.iter().zip(self.reckoned.iter()).enumerate() {
                let error = v - e;
                if libm::fabs(error) > cfg.tracking_tolerance {
                    return Some(Fault::Tracking {
                        joint: joint_label(i),
                        error,
                    });
                }
            }
        }
        // The gyro's rate over the last cycle means nothing at cycle 0: not missed there.
        let present = [
            m.star_tracker.is_some(),
            m.gyro.is_some() || k == 0,
            m.joints.is_some(),
        ];
        let sensors = [Sensor::StarTracker, Sensor::Gyro, Sensor::Joints];
        let mut mode = Mode::Nominal;
        for ((count, here), sensor) in self.missing.iter_mut().zip(present).zip(sensors) {
            if here {
                *count = 0;
            } else {
                *count = count.saturating_add(1);
                if *count > cfg.max_missing_cycles {
                    return Some(Fault::Stale(sensor));
                }
                if mode == Mode::Nominal {
                    mode = Mode::Degraded(sensor);
                }
            }
        }
        self.mode = mode;
        None
    }

    /// Updates the joint and attitude estimates with the (valid) measurements of cycle `k`.
    #[inline(never)]
    fn estimate(&mut self, robot: &Robot<N>, m: &Measurement<N>, k: u32) -> Result<(), Fault> {
        if let Some(q) = m.joints {
            self.joints = q;
        }
        // Propagate over cycle k − 1: the gyro's mean rate, or the model's for the command.
        if k > 0 {
            // The model's base rate for the command of cycle k − 1, at its mid-configuration,
            // plus the drift estimated so far.
            let mid = add_scaled(&self.joints, &self.applied, -0.5 * self.config.period);
            let mom = Momentum::new(robot, &Frames::new(robot, &mid));
            let model = mom
                .base_angular_velocity(&self.applied)
                .map_err(Fault::Model)?;
            let w = match m.gyro {
                Some(w) => {
                    let w = Vec3::new(w[0], w[1], w[2]);
                    let d = &mut self.drift;
                    *d += (w - model - *d) * self.config.drift_gain;
                    w
                }
                None => model + self.drift,
            };
            let step = quat_exp(&(w * self.config.period));
            self.attitude = normalized(quat_mul(self.attitude, step));
            self.gyro_rotation = normalized(quat_mul(self.gyro_rotation, step));
        }
        if let Some(r) = m.star_tracker {
            if self.readings == 0 {
                // The first reading: the attitude at t = 0 is the reading less the rotation
                // since then, and the estimate is the reading.
                self.initial = normalized(quat_mul(r, conj(self.gyro_rotation)));
                self.attitude = r;
            } else {
                let pull = quat_log(quat_mul(conj(self.attitude), r)) * self.config.filter_gain;
                self.attitude = normalized(quat_mul(self.attitude, quat_exp(&pull)));
                let sample = quat_mul(r, conj(self.gyro_rotation));
                let n = self.readings.saturating_add(1).min(MEAN_CAP);
                let step = quat_log(quat_mul(conj(self.initial), sample)) * (1.0 / f64::from(n));
                self.initial = normalized(quat_mul(self.initial, quat_exp(&step)));
            }
            self.readings = self.readings.saturating_add(1);
        }
        let theta = quat_log(quat_mul(conj(self.initial), self.attitude));
        let angle = theta.norm();
        if !angle.is_finite() {
            return Err(Fault::Model(Error::NonFiniteState { step: k }));
        }
        if angle > self.config.base_limit {
            return Err(Fault::BaseError(angle));
        }
        Ok(())
    }

    /// The command for cycle `k + 1` and whether a limit changed it.
    #[inline(never)]
    fn law(
        &mut self,
        robot: &Robot<N>,
        plan_ahead: &[f64; N],
        k: u32,
    ) -> Result<([f64; N], bool), Error> {
        let cfg = self.config;
        let tc = cfg.period;
        // Predicted state at t_{k+1}.
        let q1 = add_scaled(&self.joints, &self.applying, tc);
        let frames = Frames::new(robot, &q1);
        let mom = Momentum::new(robot, &frames);
        let hb = mom.hb.ldlt().ok_or(Error::SingularInertia)?;
        let mut b = SMatrix::<f64, 3, N>::zeros();
        for (mut col, h) in b.column_iter_mut().zip(mom.hbm.iter()) {
            col.copy_from(&hb.solve(h));
        }
        let u_prev = SVector::<f64, N>::from_column_slice(&self.applying);
        let est = self.base_estimate();
        let theta1 = Vec3::new(est[0], est[1], est[2]) + (self.drift - b * u_prev) * tc;
        // The generalized Jacobian, orientation rows weighed by the length.
        let w = cfg.orientation_length;
        let mut jac = generalized_jacobian(robot, &frames)?;
        for mut row in jac.row_iter_mut().skip(3) {
            row *= w;
        }
        // Base: c_b = k_b M⁻¹Bᵀ (B M⁻¹ Bᵀ + μ²I)⁻¹ θ₁ with M = I + w_d JᵀJ: of the rates
        // that turn the base back, the one that moves the joints and the end effector least.
        let bbt = b * b.transpose();
        let mut minv_bt = b.transpose();
        if cfg.drag_weight > 0.0 {
            let m = SMatrix::<f64, N, N>::identity() + jac.transpose() * jac * cfg.drag_weight;
            let mut rows = [[0.0; N]; N];
            for (i, row) in rows.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = m.get((i, j)).copied().unwrap_or(0.0);
                }
            }
            for (mut col, bt) in minv_bt.column_iter_mut().zip(b.row_iter()) {
                let rhs: [f64; N] = core::array::from_fn(|i| bt.get(i).copied().unwrap_or(0.0));
                let x = solve_spd(&rows, &rhs).ok_or(Error::SingularInertia)?;
                col.copy_from_slice(&x);
            }
        }
        let mu2 = cfg.base_damping * cfg.base_damping;
        let damped = Sym3::from_matrix(&(b * minv_bt + nalgebra::Matrix3::identity() * mu2));
        let y = damped
            .ldlt()
            .ok_or(Error::SingularInertia)?
            .solve(&(theta1 * cfg.base_gain + self.drift));
        let mut c = minv_bt * y;
        // End effector, in the null space of B.
        let in_plan = k.saturating_add(1) < self.plan_cycles;
        if cfg.ee_gain > 0.0 {
            let plan_pose = Frames::new(robot, &self.plan_next).end_pose(&self.com0, IDENTITY_WXYZ);
            let pose = frames.end_pose(&self.com0, quat_exp(&theta1));
            let e = pose.error_to(&plan_pose).to_array();
            let exact = Sym3::from_matrix(&bbt)
                .ldlt()
                .ok_or(Error::SingularInertia)?;
            let mut p = SMatrix::<f64, N, N>::identity();
            for (mut col, bc) in p.column_iter_mut().zip(b.column_iter()) {
                // Column j of P = e_j − Bᵀ (BBᵀ)⁻¹ B e_j.
                let z = exact.solve(&bc.clone_owned());
                col -= b.transpose() * z;
            }
            let jp = jac * p;
            let a = jp * jp.transpose();
            let l2 = cfg.ee_damping * cfg.ee_damping;
            let mut rows = [[0.0; 6]; 6];
            for (i, row) in rows.iter_mut().enumerate() {
                for (j, v) in row.iter_mut().enumerate() {
                    *v = a.get((i, j)).copied().unwrap_or(0.0) + if i == j { l2 } else { 0.0 };
                }
            }
            let mut rhs = [0.0; 6];
            for (i, (r, ev)) in rhs.iter_mut().zip(e.iter()).enumerate() {
                *r = cfg.ee_gain * ev * if i < 3 { 1.0 } else { w };
            }
            let z = solve_spd(&rows, &rhs).ok_or(Error::SingularInertia)?;
            c += jp.transpose() * SVector::<f64, 6>::from_column_slice(&z);
        }
        // The plan's chord over cycle k + 1.
        let next = if in_plan { *plan_ahead } else { self.plan_next };
        let mut rate = [0.0; N];
        let mut limited = false;
        let remaining = f64::from(self.total_cycles().saturating_sub(k.saturating_add(1)));
        let dv = cfg.qdd_max * tc;
        let lower = robot.lower();
        let upper = robot.upper();
        for i in 0..N {
            let chord = (get(&next, i) - get(&self.plan_next, i)) / tc;
            let want = chord + c.get(i).copied().unwrap_or(0.0);
            if !want.is_finite() {
                return Err(Error::NonFiniteState { step: k });
            }
            let prev = get(&self.applying, i);
            let vmax = get(&self.qd_limit, i);
            let q = get(&q1, i);
            // The soft bounds: the position at t_{k+2} within the joint limits, a rate that
            // can still be stopped by the last cycle; the hard one: the rate limit.
            let stop = dv * remaining;
            let soft_lo = (-stop).max((get(lower, i) - q) / tc);
            let soft_hi = stop.min((get(upper, i) - q) / tc);
            let (lo, hi) = ((-vmax).max(soft_lo), vmax.min(soft_hi));
            let mut v = if lo <= hi {
                want.max(lo).min(hi)
            } else {
                // A joint already beyond a limit: back toward it, as fast as stopping by
                // the last cycle and the rate limit allow.
                want.max(soft_lo)
                    .min(soft_hi)
                    .max(-stop)
                    .min(stop)
                    .max(-vmax)
                    .min(vmax)
            };
            // The acceleration limit wins; `prev` and `v` both lie within the rate limit,
            // so whatever lies between them does too.
            v = v.max(prev - dv).min(prev + dv);
            if v.to_bits() != want.to_bits() {
                limited = true;
            }
            if let Some(slot) = rate.get_mut(i) {
                *slot = v;
            }
        }
        self.plan_next = next;
        Ok((rate, limited))
    }

    /// A fault found outside [`Executor::step`] (by [`PlanLoop`]): the cycle is spent as
    /// `step` spends a faulty one, toward rest; a flight already stopping, stopped or done
    /// stays so, as in `step`.
    fn fail(&mut self, fault: Fault) -> Command<N> {
        self.cycle = self.cycle.saturating_add(1);
        if let Mode::Stopping(f) | Mode::Stopped(f) = self.mode {
            return self.stop(f, None);
        }
        if self.mode == Mode::Done {
            return self.finish();
        }
        self.mode = Mode::Stopping(fault);
        self.stop(fault, Some(fault))
    }

    /// The safe state: each joint's rate toward zero by at most `qdd_max T_c`.
    fn stop(&mut self, fault: Fault, event: Option<Fault>) -> Command<N> {
        let rate = self.toward_rest();
        self.advance(rate);
        self.mode = if rate.iter().all(|v| *v == 0.0) {
            Mode::Stopped(fault)
        } else {
            Mode::Stopping(fault)
        };
        Command {
            rate,
            mode: self.mode,
            event,
            limited: false,
        }
    }

    /// The end of the flight: each joint's rate toward zero by at most `qdd_max T_c` (the
    /// last commands are already within it, unless a joint limit forced them), then zero
    /// from then on ([`Mode::Done`]).
    fn finish(&mut self) -> Command<N> {
        let rate = self.toward_rest();
        self.advance(rate);
        if rate.iter().all(|v| *v == 0.0) {
            self.mode = Mode::Done;
        }
        Command {
            rate,
            mode: self.mode,
            event: None,
            limited: false,
        }
    }

    /// The pending command brought toward zero by at most `qdd_max T_c` per joint.
    fn toward_rest(&self) -> [f64; N] {
        let dv = self.config.qdd_max * self.config.period;
        core::array::from_fn(|i| {
            let v = get(&self.applying, i);
            v - v.max(-dv).min(dv)
        })
    }

    /// Shifts the commands: `rate` is applied through the next cycle.
    fn advance(&mut self, rate: [f64; N]) {
        self.joints = add_scaled(&self.joints, &self.applying, self.config.period);
        self.reckoned = add_scaled(&self.reckoned, &self.applying, self.config.period);
        self.applied = self.applying;
        self.applying = rate;
    }
}

/// A robot description whose link masses the model gets wrong: link `i`'s mass (1-based)
/// scaled by 1.05 for odd `i` and 0.95 for even `i`, everything else as `desc`. The truth
/// robot of [`fly_ideal`]'s self-test (the flight image, `host-sim target`).
#[must_use]
pub fn mistaken<const N: usize>(desc: &crate::model::RobotDesc<N>) -> crate::model::RobotDesc<N> {
    let mut out = *desc;
    for (i, link) in out.links.iter_mut().enumerate() {
        link.mass *= if i % 2 == 0 { 1.05 } else { 0.95 };
    }
    out
}

/// What [`fly_ideal`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IdealFlight {
    /// Control cycles flown.
    pub cycles: u32,
    /// Digest of every command's bits, in order ([`crate::TrajectoryDigest`]).
    pub digest: u64,
    /// The truth model's largest base rotation (rad).
    pub max_angle: f64,
    /// The end effector's pose at the end of the flight (truth model).
    pub end: crate::geometry::Pose,
    /// The executor's mode at the end.
    pub mode: Mode,
}

/// Flies the plan `eta` of `nominal` closed-loop on `truth` (the same task on the robot
/// the flight really has) with ideal sensors: the truth model's attitude, its mean rate
/// over the last cycle, the exact joints. The joints follow each command held over its
/// cycle, integrated by the truth model at the plan's `dt` ([`crate::TRUTH_SUBSTEPS`]
/// sub-steps). `hook(true)` runs just before and `hook(false)` just after each
/// [`Executor::step`] (the flight image counts instructions there). Deterministic: the
/// same bits on every target.
///
/// # Errors
/// [`Error::LoopSetting`] with [`Param::ControlPeriod`] if `T_c` is not a whole number of
/// `dt`; errors of the plan's rollout ([`crate::Setpoints::of`]) or of the truth model.
///
/// ```
/// use reactionless::closed_loop::{LoopConfig, fly_ideal, mistaken};
/// use reactionless::{Robot, Task, reference};
/// let task = reference::paper_task().unwrap();
/// let robot = Robot::new(&mistaken(task.robot().desc())).unwrap();
/// let truth = Task::new(robot, *task.start(), *task.target(), *task.motion()).unwrap();
/// let eta = reactionless::one_segment(reference::ETA_HAT);
/// let f = fly_ideal(&task, &truth, &eta, LoopConfig::DEFAULT, &mut |_| {}).unwrap();
/// assert_eq!(f.cycles, 330);
/// assert!(f.max_angle.to_degrees() < 0.005);
/// ```
pub fn fly_ideal<const N: usize, const K: usize>(
    nominal: &crate::Task<N, K>,
    truth: &crate::Task<N, K>,
    eta: &crate::Eta<K>,
    config: LoopConfig,
    hook: &mut impl FnMut(bool),
) -> Result<IdealFlight, Error> {
    let dt = nominal.motion().dt();
    // Built in place: a copy of the loop beside it would sit under every cycle's frames.
    let mut slot = None;
    let mut rate = PlanLoop::start_in(&mut slot, config, nominal, eta)?;
    let Some(flight) = slot.as_mut() else {
        return Err(Error::NotInitialized);
    };
    let per = flight.steps_per_cycle;
    let q0 = *nominal.start();
    let mut state = crate::TruthState::<N>::new(crate::TRUTH_SUBSTEPS);
    let mut q = q0;
    let mut t = 0.0;
    state.push(truth, &q, t);
    let mut prev = state.attitude();
    let mut digest = crate::TrajectoryDigest::new();
    // Bounded: the flight's cycles, then at most MAX_STOP_CYCLES to come to rest.
    let most = flight
        .executor
        .total_cycles()
        .saturating_add(MAX_STOP_CYCLES);
    let mut cycles = 0;
    for k in 0..most {
        let att = state.attitude();
        let w = quat_log(quat_mul(conj(prev), att)) * (1.0 / config.period);
        prev = att;
        let m = Measurement {
            star_tracker: Some(att),
            gyro: Some([w.x, w.y, w.z]),
            joints: Some(q),
        };
        let ahead = flight.ahead(nominal)?;
        hook(true);
        let c = flight.executor.step(nominal.robot(), &m, &ahead);
        hook(false);
        for v in &c.rate {
            digest.push(*v);
        }
        for _ in 0..per {
            for (qi, v) in q.iter_mut().zip(rate.iter()) {
                *qi += v * dt;
            }
            t += dt;
            state.push(truth, &q, t);
        }
        if let Some(e) = state.error() {
            return Err(e);
        }
        rate = c.rate;
        cycles = k.saturating_add(1);
        if matches!(c.mode, Mode::Done | Mode::Stopped(_)) && rate.iter().all(|v| *v == 0.0) {
            break;
        }
    }
    Ok(IdealFlight {
        cycles,
        digest: digest.value(),
        max_angle: state.max_angle(),
        end: state.end_pose(truth).ok_or(Error::NotInitialized)?,
        mode: flight.executor.mode(),
    })
}

/// An [`Executor`] and the plan it flies: what a flight application holds between
/// control cycles when it has no plan stream of its own (the C ABI's `rl_loop`). Each
/// [`PlanLoop::step`] advances the plan's setpoints by one control period (the rollout,
/// `T_c / dt` integration steps) and runs the executor on the plan's configuration two
/// periods ahead, as [`Executor::step`] asks.
#[derive(Debug, Clone, Copy)]
pub struct PlanLoop<const N: usize, const K: usize> {
    executor: Executor<N>,
    plan: PlanCursor<N, K>,
    /// Integration steps per control period, `T_c / dt`.
    steps_per_cycle: u32,
}

impl<const N: usize, const K: usize> PlanLoop<N, K> {
    /// The closed-loop flight of the plan `eta` of `task` (the nominal model), and the
    /// command to fly through cycle 0 ([`Executor::new`]).
    ///
    /// # Errors
    /// [`Error::LoopSetting`] with [`Param::ControlPeriod`] if `T_c` is not a whole number
    /// of the task's `dt` (relative tolerance 1e-9); an invalid configuration
    /// ([`LoopConfig::validate`]); errors of the plan's rollout ([`crate::Setpoints::of`]).
    pub fn new(
        config: LoopConfig,
        task: &crate::Task<N, K>,
        eta: &crate::Eta<K>,
    ) -> Result<(Self, [f64; N]), Error> {
        let mut slot = None;
        let command = Self::start_in(&mut slot, config, task, eta)?;
        slot.map(|l| (l, command)).ok_or(Error::NotInitialized)
    }

    /// [`PlanLoop::new`] built in place in `slot` (left `None` on an error), returning the
    /// command for cycle 0. The plan's first cycle is rolled out on the loop in `slot`,
    /// from a small frame: a loop is kilobytes (its rollout), and a copy of it under the
    /// rollout's own frames was the flight image's deepest stack.
    ///
    /// # Errors
    /// As [`PlanLoop::new`].
    #[inline(never)]
    pub fn start_in(
        slot: &mut Option<Self>,
        config: LoopConfig,
        task: &crate::Task<N, K>,
        eta: &crate::Eta<K>,
    ) -> Result<[f64; N], Error> {
        *slot = None;
        let per = Self::place(slot, config, task, eta)?;
        let Some(this) = slot.as_mut() else {
            return Err(Error::NotInitialized);
        };
        let made = this.plan.at(task, per).and_then(|first| {
            Executor::new(
                config,
                task.robot(),
                task.start(),
                task.motion().tf(),
                &first,
            )
        });
        match made {
            Ok((executor, command)) => {
                this.executor = executor;
                Ok(command)
            }
            Err(e) => {
                *slot = None;
                Err(e)
            }
        }
    }

    /// The loop's plan stream at `t = 0` into `slot`, its executor a placeholder until the
    /// plan's first cycle is known; returns the integration steps per cycle.
    #[inline(never)]
    fn place(
        slot: &mut Option<Self>,
        config: LoopConfig,
        task: &crate::Task<N, K>,
        eta: &crate::Eta<K>,
    ) -> Result<u32, Error> {
        config.validate()?;
        let motion = task.motion();
        let dt = motion.dt();
        let per = libm::round(config.period / dt);
        if !(1.0..=1e6).contains(&per)
            || libm::fabs(per * dt - config.period) > 1e-9 * config.period
        {
            return Err(Error::LoopSetting(Param::ControlPeriod));
        }
        // In range by the check above.
        #[allow(clippy::cast_possible_truncation, clippy::cast_sign_loss)]
        let per = per as u32;
        *slot = Some(Self {
            executor: Executor::parked(config),
            plan: PlanCursor {
                setpoints: crate::Setpoints::of(task, eta)?,
                last: *task.start(),
                step: 0,
            },
            steps_per_cycle: per,
        });
        Ok(per)
    }

    /// One control cycle (see [`Executor::step`]) with the measurements taken at `t_k`;
    /// `task` is the one given to [`PlanLoop::new`]. Never fails: a plan whose rollout
    /// fails is a [`Fault::Model`] and the arm is brought to rest. Once the flight is
    /// stopping, stopped or done the plan's rollout no longer advances (a cycle then costs
    /// the executor alone).
    pub fn step(&mut self, task: &crate::Task<N, K>, m: &Measurement<N>) -> Command<N> {
        // Stopping, stopped or done, the executor flies no plan: its rollout stays put.
        if let Mode::Stopping(_) | Mode::Stopped(_) | Mode::Done = self.executor.mode() {
            let last = self.plan.last;
            return self.executor.step(task.robot(), m, &last);
        }
        match self.ahead(task) {
            Ok(ahead) => self.executor.step(task.robot(), m, &ahead),
            Err(e) => self.executor.fail(Fault::Model(e)),
        }
    }

    /// The executor (mode, estimates, cycle, rate limits).
    #[must_use]
    pub fn executor(&self) -> &Executor<N> {
        &self.executor
    }

    /// Integration steps of the plan per control period (`T_c / dt`).
    #[must_use]
    pub fn steps_per_cycle(&self) -> u32 {
        self.steps_per_cycle
    }

    /// The plan's configuration at `t_{k+2}` for the executor's next cycle `k`.
    fn ahead(&mut self, task: &crate::Task<N, K>) -> Result<[f64; N], Error> {
        let s = self
            .executor
            .cycle()
            .saturating_add(2)
            .saturating_mul(self.steps_per_cycle);
        self.plan.at(task, s)
    }
}

/// The plan's configuration at integration step `s`, streamed forward only.
#[derive(Debug, Clone, Copy)]
struct PlanCursor<const N: usize, const K: usize> {
    setpoints: crate::Setpoints<N, K>,
    last: [f64; N],
    step: u32,
}

impl<const N: usize, const K: usize> PlanCursor<N, K> {
    /// The configuration at step `s` (the last one past the end); `s` never decreases.
    #[inline(never)]
    fn at(&mut self, task: &crate::Task<N, K>, s: u32) -> Result<[f64; N], Error> {
        // Bounded: each call advances the stream, which ends after MAX_STEPS + 1 samples.
        while self.step < s {
            match self.setpoints.next(task)? {
                Some(sample) => {
                    self.last = sample.q;
                    self.step = sample.step;
                }
                None => break,
            }
        }
        Ok(self.last)
    }
}

/// `a + s·b`.
fn add_scaled<const N: usize>(a: &[f64; N], b: &[f64; N], s: f64) -> [f64; N] {
    core::array::from_fn(|i| get(a, i) + s * get(b, i))
}

fn get<const N: usize>(a: &[f64; N], i: usize) -> f64 {
    a.get(i).copied().unwrap_or(0.0)
}

fn conj(q: [f64; 4]) -> [f64; 4] {
    [q[0], -q[1], -q[2], -q[3]]
}

/// Joint `i` (0-based) as the 1-based label of errors.
fn joint_label(i: usize) -> u8 {
    u8::try_from(i.saturating_add(1)).unwrap_or(u8::MAX)
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing, clippy::panic)]
    use super::*;
    use crate::geometry::quat_exp;
    use crate::reference::{ETA_HAT, paper_task};
    use crate::rollout::Sample;
    use crate::task::Task;
    use crate::truth::TruthState;
    use crate::{Setpoints, TRUTH_SUBSTEPS};
    use rand_core::{Rng, SeedableRng};
    use rand_xoshiro::Xoshiro256PlusPlus;
    use std::vec::Vec;

    /// The reference plan's configuration at every control cycle boundary (10 Hz).
    fn plan_at_cycles(task: &Task<7, 4>) -> Vec<[f64; 7]> {
        let mut sp = Setpoints::new(task, &ETA_HAT).unwrap();
        let mut out = Vec::new();
        while let Some(Sample { step, q, .. }) = sp.next(task).unwrap() {
            if step % 10 == 0 {
                out.push(q);
            }
        }
        out
    }

    fn limits(task: &Task<7, 4>) -> [f64; 7] {
        let q0 = *task.start();
        let (exec, _) = Executor::new(LoopConfig::DEFAULT, task.robot(), &q0, 30.0, &q0).unwrap();
        *exec.rate_limits()
    }

    /// A flight of the reference plan on `task`'s robot with perfect sensors (the truth
    /// model's attitude and mean rate, exact joints); `fault(k, m)` may spoil cycle `k`'s
    /// measurements. Returns every command and the truth model's largest base angle.
    fn fly(
        task: &Task<7, 4>,
        config: LoopConfig,
        mut fault: impl FnMut(u32, &mut Measurement<7>),
    ) -> (Vec<Command<7>>, f64, [f64; 7], TruthState<7>) {
        let plan = plan_at_cycles(task);
        let at = |j: usize| plan[j.min(plan.len() - 1)];
        let q0 = *task.start();
        let (mut exec, mut rate) = Executor::new(config, task.robot(), &q0, 30.0, &at(1)).unwrap();
        let mut truth = TruthState::<7>::new(TRUTH_SUBSTEPS);
        let mut q = q0;
        let mut t = 0.0;
        truth.push(task, &q, t);
        let mut prev = truth.attitude();
        let mut out = Vec::new();
        for k in 0..400u32 {
            let att = truth.attitude();
            let d = quat_log(quat_mul(conj(prev), att)) * (1.0 / config.period);
            prev = att;
            let mut m = Measurement {
                star_tracker: Some(att),
                gyro: Some([d.x, d.y, d.z]),
                joints: Some(q),
            };
            fault(k, &mut m);
            let c = exec.step(task.robot(), &m, &at(k as usize + 2));
            for _ in 0..10 {
                for (qi, v) in q.iter_mut().zip(&rate) {
                    *qi += v * 0.01;
                }
                t += 0.01;
                truth.push(task, &q, t);
            }
            rate = c.rate;
            out.push(c);
            if matches!(c.mode, Mode::Done | Mode::Stopped(_)) && rate == [0.0; 7] {
                break;
            }
        }
        (out, truth.max_angle(), q, truth)
    }

    /// Every command within the rate limits, every change within `qdd_max T_c`: from rest
    /// to the first command (cycle 0's, from [`Executor::new`]), then from each to the next.
    fn within_limits(task: &Task<7, 4>, config: &LoopConfig, first: [f64; 7], cmds: &[Command<7>]) {
        let lim = limits(task);
        let dv = config.qdd_max * config.period * (1.0 + 1e-12);
        let mut prev = [0.0; 7];
        let all = core::iter::once(first).chain(cmds.iter().map(|c| c.rate));
        for (k, rate) in all.enumerate() {
            for i in 0..7 {
                assert!(
                    rate[i].abs() <= lim[i],
                    "command {k} joint {i}: {}",
                    rate[i]
                );
                assert!(
                    (rate[i] - prev[i]).abs() <= dv + 1e-15,
                    "command {k} joint {i}: {} after {}",
                    rate[i],
                    prev[i]
                );
            }
            prev = rate;
        }
        assert_eq!(prev, [0.0; 7], "the last command is not at rest");
    }

    /// On the planner's own robot with perfect sensors the loop does no harm: the base
    /// turns less than the open-loop flight of the Euler path (7.3e-4°), the end effector
    /// ends within 0.1 mm and 0.001° of the target, and the flight ends on time
    /// (t_f + the extension), at rest.
    /// Verifies RL-LOOP-003.
    #[test]
    fn the_nominal_flight_holds_the_base_and_reaches_the_target() {
        let task = paper_task().unwrap();
        let (cmds, max_angle, _, truth) = fly(&task, LoopConfig::DEFAULT, |_, _| {});
        assert!(max_angle.to_degrees() < 1e-4, "{}", max_angle.to_degrees());
        let e = truth.end_pose(&task).unwrap().error_to(task.target());
        assert!(e.position_m() < 1e-4, "{}", e.position_m());
        assert!(e.orientation_deg() < 1e-3, "{}", e.orientation_deg());
        assert_eq!(cmds.len(), 330);
        assert_eq!(cmds.last().unwrap().mode, Mode::Done);
        assert!(cmds.iter().all(|c| c.event.is_none()));
        let plan = plan_at_cycles(&task);
        let cfg = LoopConfig::DEFAULT;
        let (_, first) = Executor::new(cfg, task.robot(), task.start(), 30.0, &plan[1]).unwrap();
        within_limits(&task, &cfg, first, &cmds);
    }

    /// Each fault ends in the safe state, reported once with its reason, and the arm comes
    /// to rest within the acceleration and rate limits: a NaN joint reading, a NaN star
    /// tracker, a frozen encoder, a star-tracker outage longer than allowed, a gyro out of
    /// range, and a base attitude past its limit (a star tracker that jumps 1°).
    /// Verifies RL-LOOP-001.
    #[test]
    fn every_fault_ends_at_rest_within_the_limits() {
        let task = paper_task().unwrap();
        let cfg = LoopConfig::DEFAULT;
        type Spoil = fn(u32, &mut Measurement<7>, &mut Option<[f64; 7]>);
        type Want = fn(&Fault) -> bool;
        let cases: [(&str, Spoil, Want); 6] = [
            (
                "NaN joint",
                |k, m, _| {
                    if k == 100 {
                        m.joints.as_mut().unwrap()[3] = f64::NAN;
                    }
                },
                |f| *f == Fault::NotFinite(Sensor::Joints),
            ),
            (
                "NaN star tracker",
                |k, m, _| {
                    if k == 100 {
                        m.star_tracker = Some([f64::NAN; 4]);
                    }
                },
                |f| *f == Fault::NotFinite(Sensor::StarTracker),
            ),
            (
                "frozen encoder",
                |k, m, held| {
                    if k >= 100 {
                        let q = m.joints.as_mut().unwrap();
                        let h = held.get_or_insert(*q);
                        q[0] = h[0];
                    }
                },
                |f| matches!(f, Fault::Tracking { joint: 1, .. }),
            ),
            (
                "star-tracker outage",
                |k, m, _| {
                    if k >= 100 {
                        m.star_tracker = None;
                    }
                },
                |f| *f == Fault::Stale(Sensor::StarTracker),
            ),
            (
                "gyro out of range",
                |k, m, _| {
                    if k == 100 {
                        m.gyro = Some([1.0, 0.0, 0.0]);
                    }
                },
                |f| {
                    *f == Fault::OutOfRange {
                        sensor: Sensor::Gyro,
                        joint: 0,
                    }
                },
            ),
            (
                "base error",
                |k, m, _| {
                    if k >= 100 {
                        let r = m.star_tracker.unwrap();
                        let jump = quat_exp(&Vec3::new(1f64.to_radians(), 0.0, 0.0));
                        m.star_tracker = Some(normalized(quat_mul(r, jump)));
                    }
                },
                |f| matches!(f, Fault::BaseError(_)),
            ),
        ];
        for (name, spoil, want) in cases {
            let mut held = None;
            let (cmds, _, _, _) = fly(&task, cfg, |k, m| spoil(k, m, &mut held));
            let events: Vec<(usize, Fault)> = cmds
                .iter()
                .enumerate()
                .filter_map(|(k, c)| c.event.map(|f| (k, f)))
                .collect();
            assert_eq!(events.len(), 1, "{name}: {events:?}");
            let (at, fault) = events[0];
            assert!(want(&fault), "{name}: {fault:?}");
            assert!(at >= 100, "{name}: at cycle {at}");
            let last = cmds.last().unwrap();
            assert_eq!(last.mode, Mode::Stopped(fault), "{name}");
            assert_eq!(last.rate, [0.0; 7], "{name}");
            let plan = plan_at_cycles(&task);
            let (_, first) =
                Executor::new(cfg, task.robot(), task.start(), 30.0, &plan[1]).unwrap();
            within_limits(&task, &cfg, first, &cmds);
            // At rest within the time the largest rate needs at qdd_max.
            let lim = limits(&task).iter().fold(0.0f64, |m, v| m.max(*v));
            let most = (lim / (cfg.qdd_max * cfg.period)).ceil() as usize + 1;
            assert!(
                cmds.len() - at <= most,
                "{name}: {} cycles to rest",
                cmds.len() - at
            );
        }
    }

    /// A sensor missing for no more than the allowed cycles degrades the mode and is no
    /// fault; the flight still ends on time with the base held.
    /// Verifies RL-LOOP-001.
    #[test]
    fn short_dropouts_degrade_without_a_fault() {
        let task = paper_task().unwrap();
        let (cmds, max_angle, _, _) = fly(&task, LoopConfig::DEFAULT, |k, m| {
            if (100..103).contains(&k) {
                *m = Measurement {
                    star_tracker: None,
                    gyro: None,
                    joints: None,
                };
            }
        });
        assert_eq!(cmds[100].mode, Mode::Degraded(Sensor::StarTracker));
        assert_eq!(cmds[103].mode, Mode::Nominal);
        assert!(cmds.iter().all(|c| c.event.is_none()));
        assert_eq!(cmds.last().unwrap().mode, Mode::Done);
        assert!(max_angle.to_degrees() < 1e-4, "{}", max_angle.to_degrees());
    }

    /// Whatever the measurements (random joints across their range and beyond, random
    /// attitudes and rates, random dropouts, NaNs), every command stays within the rate
    /// limits and changes by at most `qdd_max T_c` per cycle, the arm ends at rest, and
    /// nothing panics.
    /// Verifies RL-LOOP-002.
    #[test]
    fn commands_stay_within_limits_under_random_measurements() {
        let task = paper_task().unwrap();
        let robot = task.robot();
        let plan = plan_at_cycles(&task);
        for seed in 0..40u64 {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
            let mut u = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
            let cfg = LoopConfig {
                base_gain: 9.9 * u(),
                ee_gain: 5.0 * u(),
                drift_gain: u(),
                max_missing_cycles: 1_000,
                base_limit: 1.0,
                tracking_tolerance: 10.0,
                max_gyro_rate: 10.0,
                ..LoopConfig::DEFAULT
            };
            let q0 = *task.start();
            let (mut exec, first) = Executor::new(cfg, robot, &q0, 30.0, &plan[1]).unwrap();
            let mut cmds = Vec::new();
            for k in 0..400usize {
                let mut joints: [f64; 7] = core::array::from_fn(|i| {
                    let (lo, hi) = (robot.lower()[i], robot.upper()[i]);
                    lo - 0.04 + (hi - lo + 0.08) * u()
                });
                if u() < 0.02 {
                    joints[(u() * 7.0) as usize % 7] = f64::NAN;
                }
                let axis = Vec3::new(u() - 0.5, u() - 0.5, u() - 0.5) * (0.2 * u());
                let m = Measurement {
                    star_tracker: (u() < 0.9).then(|| quat_exp(&axis)),
                    gyro: (u() < 0.9).then(|| [u() - 0.5, u() - 0.5, u() - 0.5]),
                    joints: (u() < 0.9).then_some(joints),
                };
                let c = exec.step(robot, &m, &plan[(k + 2).min(plan.len() - 1)]);
                cmds.push(c);
            }
            within_limits(&task, &cfg, first, &cmds);
        }
    }

    /// On a robot whose link masses are 5 % off, the open-loop flight of the reference plan
    /// turns the base by more than the 0.01° requirement; the closed loop with ideal
    /// sensors holds it within 0.002°, and on the planner's own robot `fly_ideal` gives
    /// what the test flight above gives.
    /// Verifies RL-LOOP-003.
    #[test]
    fn the_loop_holds_the_base_the_open_loop_loses() {
        let task = paper_task().unwrap();
        let robot = crate::model::Robot::new(&mistaken(task.robot().desc())).unwrap();
        let truth = Task::new(robot, *task.start(), *task.target(), *task.motion()).unwrap();
        let eta = crate::one_segment(ETA_HAT);
        let mut open = TruthState::<7>::new(TRUTH_SUBSTEPS);
        let mut sp = Setpoints::new(&task, &ETA_HAT).unwrap();
        while let Some(s) = sp.next(&task).unwrap() {
            open.push(&truth, &s.q, s.t);
        }
        let mut calls = 0;
        let f = fly_ideal(&task, &truth, &eta, LoopConfig::DEFAULT, &mut |_| {
            calls += 1
        })
        .unwrap();
        std::println!(
            "open {:e} deg, closed {:e} deg, end {:?}",
            open.max_angle().to_degrees(),
            f.max_angle.to_degrees(),
            f.end.error_to(task.target()).position_m()
        );
        assert!(open.max_angle().to_degrees() > 0.01);
        assert!(
            f.max_angle.to_degrees() < 0.002,
            "{}",
            f.max_angle.to_degrees()
        );
        assert_eq!(calls, 2 * f.cycles);
        assert_eq!(f.mode, Mode::Done);
        let same = fly_ideal(&task, &task, &eta, LoopConfig::DEFAULT, &mut |_| {}).unwrap();
        let (_, max_angle, _, state) = fly(&task, LoopConfig::DEFAULT, |_, _| {});
        assert_eq!(same.max_angle.to_bits(), max_angle.to_bits());
        assert_eq!(same.end, state.end_pose(&task).unwrap());
    }

    /// Bad settings are refused, naming the setting.
    /// Verifies RL-LOOP-004.
    #[test]
    fn bad_settings_are_refused() {
        let task = paper_task().unwrap();
        let q0 = *task.start();
        let d = LoopConfig::DEFAULT;
        let cases = [
            (
                LoopConfig {
                    base_gain: -1.0,
                    ..d
                },
                Error::Negative(Param::BaseGain),
            ),
            (
                LoopConfig {
                    filter_gain: 1.5,
                    ..d
                },
                Error::LoopSetting(Param::FilterGain),
            ),
            (
                LoopConfig {
                    drift_gain: 2.0,
                    ..d
                },
                Error::LoopSetting(Param::DriftGain),
            ),
            (
                LoopConfig {
                    period: f64::NAN,
                    ..d
                },
                Error::NotFinite(Param::ControlPeriod),
            ),
            (
                LoopConfig { qdd_max: 0.0, ..d },
                Error::NotPositive(Param::LoopAccel),
            ),
            (
                LoopConfig {
                    ee_damping: 0.0,
                    ..d
                },
                Error::NotPositive(Param::EeDamping),
            ),
            (
                LoopConfig { period: 0.07, ..d },
                Error::LoopSetting(Param::ControlPeriod),
            ),
        ];
        for (c, want) in cases {
            let got = Executor::new(c, task.robot(), &q0, 30.0, &q0).err();
            assert_eq!(got, Some(want), "{c:?}");
        }
    }
}
