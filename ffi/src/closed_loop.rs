//! Closed-loop flight (spec §12) through the C ABI: the executor of
//! `reactionless::closed_loop` and the plan it flies (`PlanLoop<7, 4>`) in caller-owned
//! storage, one call per control cycle.
//!
//! Owns [`rl_loop`] (the storage), [`rl_loop_config`] (gains, filter and fault settings,
//! SI units in the member names), [`rl_measurement`] (what the sensors gave at the start
//! of a cycle), [`rl_loop_command`] (what a cycle returns: the joint rates to hold through
//! the next cycle, the mode, the fault) and the functions `rl_loop_config_default`,
//! `rl_loop_init`, `rl_loop_step`, `rl_loop_fault_str`. The contract is
//! [`crate::rl_planner`]'s: the caller's header version and `sizeof(rl_loop)` are checked
//! at init, storage is the caller's, every pointer is checked for NULL and every object
//! for its state, nothing panics or allocates.
//!
//! Timing, as the core's: `rl_loop_init` returns the command of cycle 0 (the plan's own,
//! from rest); the measurements taken at `t_k = k T_c` go to the `k`-th `rl_loop_step`,
//! whose command is held through cycle `k + 1`. A bad measurement is not an error of the
//! call: the loop reports the fault in the command (`event` = 1 in the cycle that found
//! it) and brings the arm to rest within `qdd_max_rad_s2`.
//!
//! Verifies RL-FFI-014.

use core::ffi::c_char;
use core::mem::{align_of, size_of};
use reactionless::closed_loop::{Command, Fault, LoopConfig, Measurement, Mode, PlanLoop, Sensor};
use reactionless::{Error, Param};

use crate::{
    RL_ABI_VERSION, RL_DONE, RL_E_ABI_VERSION, RL_E_MISMATCH, RL_E_NO_PLAN, RL_E_NULL, RL_E_SIZE,
    RL_E_STREAM, RL_E_UNINITIALIZED, RL_JOINTS, RL_OK, rl_planner, rl_status,
};

/// The flight's closed loop: 7 joints, null-space dimension 4.
pub type FlightLoop = PlanLoop<7, 4>;

/// Words (u64) of loop storage inside [`rl_loop`]: room for the loop on every target, with
/// headroom so that a small growth of the core keeps the ABI.
pub const RL_LOOP_WORDS: usize = 512;

/// [`rl_loop_config`] holds a value the loop refuses: a setting not finite or out of its
/// range, an unstable gain `k T_c ≥ 1`, or a control period that is not a whole number of
/// the plan's `dt` or does not divide its `t_f`.
pub const RL_E_LOOP_SETTING: rl_status = -26;

/// `rl_measurement.valid`: the star tracker's quaternion is present.
pub const RL_MEASURED_STAR_TRACKER: u32 = 1;
/// `rl_measurement.valid`: the gyro's rate is present.
pub const RL_MEASURED_GYRO: u32 = 2;
/// `rl_measurement.valid`: the joint encoders' angles are present.
pub const RL_MEASURED_JOINTS: u32 = 4;

/// `rl_loop_command.mode`: every sensor fresh, the plan and its corrections flown.
pub const RL_LOOP_NOMINAL: u32 = 0;
/// `rl_loop_command.mode`: a sensor (`sensor`) missing for a few cycles, flown on dead
/// reckoning.
pub const RL_LOOP_DEGRADED: u32 = 1;
/// `rl_loop_command.mode`: a fault; the joints decelerate to rest.
pub const RL_LOOP_STOPPING: u32 = 2;
/// `rl_loop_command.mode`: at rest after a fault (the safe state; nothing leaves it).
pub const RL_LOOP_STOPPED: u32 = 3;
/// `rl_loop_command.mode`: the flight is over (`t_f` and the correction after it).
pub const RL_LOOP_DONE: u32 = 4;

/// `rl_loop_command.sensor`: none.
pub const RL_SENSOR_NONE: u32 = 0;
/// `rl_loop_command.sensor`: the star tracker.
pub const RL_SENSOR_STAR_TRACKER: u32 = 1;
/// `rl_loop_command.sensor`: the gyro.
pub const RL_SENSOR_GYRO: u32 = 2;
/// `rl_loop_command.sensor`: the joint encoders.
pub const RL_SENSOR_JOINTS: u32 = 3;

/// `rl_loop_command.fault`: none.
pub const RL_FAULT_NONE: u32 = 0;
/// A measurement is NaN or infinite (`sensor`).
pub const RL_FAULT_NOT_FINITE: u32 = 1;
/// A measurement is out of range (`sensor`; `fault_joint` for the encoders).
pub const RL_FAULT_OUT_OF_RANGE: u32 = 2;
/// A sensor gave nothing for more than `max_missing_cycles` cycles (`sensor`).
pub const RL_FAULT_STALE: u32 = 3;
/// Joint `fault_joint` is not where the commands took it by `fault_value` rad.
pub const RL_FAULT_TRACKING: u32 = 4;
/// The base attitude estimate, `fault_value` rad, is beyond `base_limit_rad`.
pub const RL_FAULT_BASE_ERROR: u32 = 5;
/// The nominal model (or the plan's rollout) failed at the measured configuration.
pub const RL_FAULT_MODEL: u32 = 6;

const LOOP_MAGIC: u32 = 0x524c_4c50; // "RLLP"

const _: () = assert!(size_of::<FlightLoop>() <= RL_LOOP_WORDS * 8);
const _: () = assert!(align_of::<FlightLoop>() <= align_of::<u64>());

/// The loop's settings (`reactionless::closed_loop::LoopConfig`, documented in
/// docs/closed-loop.md); `rl_loop_config_default` fills the defaults.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_loop_config {
    /// Control period `T_c` (s): a whole multiple of the plan's `dt`.
    pub period_s: f64,
    /// Base-attitude gain `k_b` (1/s); `k_b T_c < 1`.
    pub base_gain_per_s: f64,
    /// End-effector gain `k_e` (1/s), `k_e T_c < 1`; 0 turns the end-effector task off.
    pub ee_gain_per_s: f64,
    /// Damping `μ` of the base pseudo-inverse (dimensionless).
    pub base_damping: f64,
    /// Damping `λ` of the end-effector pseudo-inverse (m).
    pub ee_damping_m: f64,
    /// Length (m) weighing orientation errors against position errors.
    pub orientation_length_m: f64,
    /// Weight `w_d` (1/m²) of the end effector's motion in the base correction.
    pub drag_weight_per_m2: f64,
    /// Pull of the attitude estimate toward each star-tracker reading, in (0, 1].
    pub filter_gain: f64,
    /// Pull of the drift estimate toward each cycle's, in [0, 1]; 0 turns it off.
    pub drift_gain: f64,
    /// Base attitude estimate (rad) beyond which the loop goes to the safe state.
    pub base_limit_rad: f64,
    /// Largest difference (rad) between a joint's reading and where the commands took it.
    pub tracking_tolerance_rad: f64,
    /// Largest gyro rate (rad/s) in range.
    pub max_gyro_rate_rad_s: f64,
    /// Joint acceleration limit (rad/s²) of every command change.
    pub qdd_max_rad_s2: f64,
    /// Consecutive cycles a sensor may be missing before it is a fault.
    pub max_missing_cycles: u32,
    /// Cycles of correction after `t_f`, the plan at rest.
    pub extend_cycles: u32,
}

impl rl_loop_config {
    /// The core's defaults ([`LoopConfig::DEFAULT`]).
    pub const DEFAULT: Self = Self::of(&LoopConfig::DEFAULT);

    const fn of(c: &LoopConfig) -> Self {
        Self {
            period_s: c.period,
            base_gain_per_s: c.base_gain,
            ee_gain_per_s: c.ee_gain,
            base_damping: c.base_damping,
            ee_damping_m: c.ee_damping,
            orientation_length_m: c.orientation_length,
            drag_weight_per_m2: c.drag_weight,
            filter_gain: c.filter_gain,
            drift_gain: c.drift_gain,
            base_limit_rad: c.base_limit,
            tracking_tolerance_rad: c.tracking_tolerance,
            max_gyro_rate_rad_s: c.max_gyro_rate,
            qdd_max_rad_s2: c.qdd_max,
            max_missing_cycles: c.max_missing_cycles,
            extend_cycles: c.extend_cycles,
        }
    }

    fn core(&self) -> LoopConfig {
        LoopConfig {
            period: self.period_s,
            base_gain: self.base_gain_per_s,
            ee_gain: self.ee_gain_per_s,
            base_damping: self.base_damping,
            ee_damping: self.ee_damping_m,
            orientation_length: self.orientation_length_m,
            drag_weight: self.drag_weight_per_m2,
            filter_gain: self.filter_gain,
            drift_gain: self.drift_gain,
            max_missing_cycles: self.max_missing_cycles,
            base_limit: self.base_limit_rad,
            tracking_tolerance: self.tracking_tolerance_rad,
            max_gyro_rate: self.max_gyro_rate_rad_s,
            qdd_max: self.qdd_max_rad_s2,
            extend_cycles: self.extend_cycles,
        }
    }
}

/// What the sensors gave at the start of a cycle. A sensor whose bit is clear in `valid`
/// is missing this cycle (its members are ignored).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_measurement {
    /// `RL_MEASURED_STAR_TRACKER | RL_MEASURED_GYRO | RL_MEASURED_JOINTS`, each bit set if
    /// that sensor's reading is present.
    pub valid: u32,
    /// Star tracker: the base attitude in its frame, unit quaternion `w, x, y, z`.
    pub star_tracker_wxyz: [f64; 4],
    /// Gyro: the base's mean angular rate over the last cycle (rad/s, base frame).
    pub gyro_rad_s: [f64; 3],
    /// Joint encoders (rad).
    pub joints_rad: [f64; RL_JOINTS],
}

/// What one cycle returns.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct rl_loop_command {
    /// Joint rates (rad/s) to hold through the next cycle: never beyond a joint's rate
    /// limit, never changed by more than `qdd_max_rad_s2 · period_s` from the last.
    pub rate_rad_s: [f64; RL_JOINTS],
    /// The base rotation since `t = 0` the loop estimates (rotation vector, rad).
    pub base_estimate_rad: [f64; 3],
    /// With `RL_FAULT_TRACKING` the joint's error (rad), with `RL_FAULT_BASE_ERROR` the
    /// base estimate's angle (rad); 0 otherwise.
    pub fault_value: f64,
    /// The cycle `k` of the measurements this command answered (0 for `rl_loop_init`'s).
    pub cycle: u32,
    /// `RL_LOOP_NOMINAL`, `RL_LOOP_DEGRADED`, `RL_LOOP_STOPPING`, `RL_LOOP_STOPPED` or
    /// `RL_LOOP_DONE`, after this cycle.
    pub mode: u32,
    /// `RL_FAULT_*`: why the loop is stopping or stopped (`RL_FAULT_NONE` otherwise).
    pub fault: u32,
    /// `RL_SENSOR_*`: the sensor of the fault, or the missing one when degraded.
    pub sensor: u32,
    /// The joint (1-based) of an out-of-range or tracking fault, 0 otherwise.
    pub fault_joint: u32,
    /// 1 in the cycle that found the fault (report it once), else 0.
    pub event: u32,
    /// 1 if a limit changed the command of some joint, else 0.
    pub limited: u32,
    /// 1 once nothing more is to be flown (`RL_LOOP_DONE` or `RL_LOOP_STOPPED`, at rest).
    pub finished: u32,
}

impl rl_loop_command {
    /// All zero.
    pub const ZEROED: Self = Self {
        rate_rad_s: [0.0; RL_JOINTS],
        base_estimate_rad: [0.0; 3],
        fault_value: 0.0,
        cycle: 0,
        mode: 0,
        fault: 0,
        sensor: 0,
        fault_joint: 0,
        event: 0,
        limited: 0,
        finished: 0,
    };

    fn of(c: &Command<7>, exec: &reactionless::closed_loop::Executor<7>, cycle: u32) -> Self {
        let (mode, fault) = match c.mode {
            Mode::Nominal => (RL_LOOP_NOMINAL, None),
            Mode::Degraded(_) => (RL_LOOP_DEGRADED, None),
            Mode::Stopping(f) => (RL_LOOP_STOPPING, Some(f)),
            Mode::Stopped(f) => (RL_LOOP_STOPPED, Some(f)),
            Mode::Done => (RL_LOOP_DONE, None),
        };
        let (code, sensor, joint, value) = match fault {
            None => (
                RL_FAULT_NONE,
                match c.mode {
                    Mode::Degraded(s) => sensor_code(s),
                    _ => RL_SENSOR_NONE,
                },
                0,
                0.0,
            ),
            Some(Fault::NotFinite(s)) => (RL_FAULT_NOT_FINITE, sensor_code(s), 0, 0.0),
            Some(Fault::OutOfRange { sensor, joint }) => (
                RL_FAULT_OUT_OF_RANGE,
                sensor_code(sensor),
                u32::from(joint),
                0.0,
            ),
            Some(Fault::Stale(s)) => (RL_FAULT_STALE, sensor_code(s), 0, 0.0),
            Some(Fault::Tracking { joint, error }) => {
                (RL_FAULT_TRACKING, RL_SENSOR_JOINTS, u32::from(joint), error)
            }
            Some(Fault::BaseError(a)) => (RL_FAULT_BASE_ERROR, RL_SENSOR_NONE, 0, a),
            Some(Fault::Model(_)) => (RL_FAULT_MODEL, RL_SENSOR_NONE, 0, 0.0),
        };
        let at_rest = c.rate.iter().all(|v| *v == 0.0);
        Self {
            rate_rad_s: c.rate,
            base_estimate_rad: exec.base_estimate(),
            fault_value: value,
            cycle,
            mode,
            fault: code,
            sensor,
            fault_joint: joint,
            event: u32::from(c.event.is_some()),
            limited: u32::from(c.limited),
            finished: u32::from(at_rest && matches!(c.mode, Mode::Done | Mode::Stopped(_))),
        }
    }
}

fn sensor_code(s: Sensor) -> u32 {
    match s {
        Sensor::StarTracker => RL_SENSOR_STAR_TRACKER,
        Sensor::Gyro => RL_SENSOR_GYRO,
        Sensor::Joints => RL_SENSOR_JOINTS,
    }
}

impl rl_measurement {
    fn core(&self) -> Measurement<7> {
        let has = |bit: u32| self.valid & bit != 0;
        Measurement {
            star_tracker: has(RL_MEASURED_STAR_TRACKER).then_some(self.star_tracker_wxyz),
            gyro: has(RL_MEASURED_GYRO).then_some(self.gyro_rad_s),
            joints: has(RL_MEASURED_JOINTS).then_some(self.joints_rad),
        }
    }
}

/// A closed-loop flight in caller-owned storage (static app data). Initialise with
/// `rl_loop_init`; the members are private to the library.
#[repr(C)]
pub struct rl_loop {
    /// Set by `rl_loop_init`.
    magic: u32,
    /// Unused (alignment).
    reserved: u32,
    /// Digest of the task block of the planner whose plan it flies.
    task: u64,
    /// The loop itself.
    storage: [u64; RL_LOOP_WORDS],
}

impl rl_loop {
    /// All zero: not initialised (for Rust callers that need a value to box).
    pub const ZEROED: Self = Self {
        magic: 0,
        reserved: 0,
        task: 0,
        storage: [0; RL_LOOP_WORDS],
    };

    /// The loop, if `rl_loop_init` has run on this storage.
    #[allow(unsafe_code)]
    fn flight_mut(&mut self) -> Option<&mut FlightLoop> {
        (self.magic == LOOP_MAGIC).then(|| {
            // SAFETY: the magic is written only by rl_loop_init, right after it wrote a
            // FlightLoop into `storage` (size and alignment asserted above); `&mut self`
            // makes the borrow exclusive.
            unsafe { &mut *self.storage.as_mut_ptr().cast::<FlightLoop>() }
        })
    }

    fn step(&mut self, p: &rl_planner, m: &rl_measurement, out: &mut rl_loop_command) -> rl_status {
        let task = self.task;
        let Some(flight) = self.flight_mut() else {
            return RL_E_UNINITIALIZED;
        };
        let planner = match p.loaded() {
            Ok(pl) => pl,
            Err(s) => return s,
        };
        if p.task != task {
            return RL_E_MISMATCH;
        }
        let cycle = flight.executor().cycle();
        let c = flight.step(planner.task(), &m.core());
        *out = rl_loop_command::of(&c, flight.executor(), cycle);
        if out.finished == 1 { RL_DONE } else { RL_OK }
    }
}

/// Fills `*out` with the loop's defaults: 10 Hz, `k_b` 4/s, `k_e` 1/s, filter gain 0.05,
/// base limit 0.1°, `qdd_max` 0.5 rad/s², 3 missing cycles, 30 cycles after `t_f`
/// (docs/closed-loop.md).
///
/// # Safety
/// `out` is NULL or writable.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_loop_config_default(out: *mut rl_loop_config) -> rl_status {
    // SAFETY: as_mut checks for NULL; the contract makes the reference valid.
    match unsafe { out.as_mut() } {
        Some(out) => {
            *out = rl_loop_config::DEFAULT;
            RL_OK
        }
        None => RL_E_NULL,
    }
}

/// Starts the closed-loop flight of the planner's finished plan: `l` holds it from now on,
/// `*first` gets the command of cycle 0 (the plan's own, from rest: fly it through
/// `[0, T_c)`). `config` NULL takes the defaults. `abi_version` and `size` are the
/// caller's `RL_ABI_VERSION` and `sizeof(rl_loop)` (`RL_E_ABI_VERSION`, `RL_E_SIZE`).
/// A planner without a task is `RL_E_NO_TASK`, one without a finished plan
/// `RL_E_NO_PLAN`; a setting the loop refuses (also a period that does not divide the
/// plan's `t_f` or is not a whole number of its `dt`) is `RL_E_LOOP_SETTING`, a plan whose rollout
/// fails `RL_E_STREAM`. On an error `l` is left as it was.
///
/// # Safety
/// `l` is NULL or writable, aligned storage of `sizeof(rl_loop)` bytes (it need not be
/// initialised); `p` NULL or an initialised planner; `config` NULL or readable; `first`
/// NULL or writable; none accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_loop_init(
    l: *mut rl_loop,
    abi_version: u32,
    size: usize,
    p: *const rl_planner,
    config: *const rl_loop_config,
    first: *mut rl_loop_command,
) -> rl_status {
    // SAFETY: as_ref/as_mut check for NULL; the contract makes the references valid and
    // `first` exclusive.
    let (Some(p), Some(first)) = (unsafe { p.as_ref() }, unsafe { first.as_mut() }) else {
        return RL_E_NULL;
    };
    if l.is_null() {
        return RL_E_NULL;
    }
    if abi_version != RL_ABI_VERSION {
        return RL_E_ABI_VERSION;
    }
    if size != size_of::<rl_loop>() {
        return RL_E_SIZE;
    }
    // SAFETY: as above; NULL means the defaults.
    let config = unsafe { config.as_ref() }.map_or(LoopConfig::DEFAULT, rl_loop_config::core);
    let planner = match p.loaded() {
        Ok(pl) => pl,
        Err(s) => return s,
    };
    let Some(plan) = planner.result() else {
        return RL_E_NO_PLAN;
    };
    let (flight, command) = match FlightLoop::new(config, planner.task(), &plan.eta) {
        Ok(v) => v,
        Err(e) => return init_error(e),
    };
    *first = rl_loop_command {
        rate_rad_s: command,
        ..rl_loop_command::ZEROED
    };
    // SAFETY: `l` is non-NULL and, by the contract, valid for writes of one rl_loop; only
    // writes happen. The loop fits `storage` (asserted at compile time).
    unsafe {
        core::ptr::addr_of_mut!((*l).storage)
            .cast::<FlightLoop>()
            .write(flight);
        core::ptr::addr_of_mut!((*l).reserved).write(0);
        core::ptr::addr_of_mut!((*l).task).write(p.task);
        core::ptr::addr_of_mut!((*l).magic).write(LOOP_MAGIC);
    }
    RL_OK
}

/// Why `PlanLoop::new` refused: a setting, or the plan's rollout.
fn init_error(e: Error) -> rl_status {
    match e {
        Error::LoopSetting(_)
        | Error::NotFinite(
            Param::ControlPeriod
            | Param::BaseGain
            | Param::EeGain
            | Param::BaseDamping
            | Param::EeDamping
            | Param::OrientationLength
            | Param::FilterGain
            | Param::BaseLimit
            | Param::TrackingTolerance
            | Param::GyroRange
            | Param::LoopAccel
            | Param::DragWeight
            | Param::DriftGain,
        )
        | Error::NotPositive(_)
        | Error::Negative(_) => RL_E_LOOP_SETTING,
        _ => RL_E_STREAM,
    }
}

/// One control cycle: the measurements taken at `t_k` in, the command to hold through
/// cycle `k + 1` out. `RL_OK` while there is more to fly; `RL_DONE` with the command that
/// finishes the flight (at rest: `t_f` and the correction after it are over, or the safe
/// state is reached) and on every later call. A bad, missing or stale measurement is not
/// an error of the call: see `out->mode`, `out->fault` and `out->event`. `p` must be the
/// planner the loop was started from (its task: `RL_E_MISMATCH` otherwise). Costs one
/// executor cycle and `T_c / dt` steps of the plan's rollout.
///
/// # Safety
/// `l` NULL, or zero-filled storage of `sizeof(rl_loop)` bytes (`RL_E_UNINITIALIZED`), or
/// a loop initialised by `rl_loop_init`; `p` NULL or an initialised planner; `m` NULL or
/// readable; `out` NULL or writable; none accessed elsewhere during the call.
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub unsafe extern "C" fn rl_loop_step(
    l: *mut rl_loop,
    p: *const rl_planner,
    m: *const rl_measurement,
    out: *mut rl_loop_command,
) -> rl_status {
    // SAFETY: as_mut/as_ref check for NULL; the contract makes the references valid and
    // `l`, `out` exclusive.
    match unsafe { (l.as_mut(), p.as_ref(), m.as_ref(), out.as_mut()) } {
        (Some(l), Some(p), Some(m), Some(out)) => l.step(p, m, out),
        _ => RL_E_NULL,
    }
}

/// Static text naming an `RL_FAULT_*` code (never NULL; unknown codes get a text too).
#[allow(unsafe_code)]
#[unsafe(no_mangle)]
pub extern "C" fn rl_loop_fault_str(fault: u32) -> *const c_char {
    let text: &'static core::ffi::CStr = match fault {
        RL_FAULT_NONE => c"RL_FAULT_NONE: no fault",
        RL_FAULT_NOT_FINITE => c"RL_FAULT_NOT_FINITE: a measurement is NaN or infinite",
        RL_FAULT_OUT_OF_RANGE => c"RL_FAULT_OUT_OF_RANGE: a measurement is out of range",
        RL_FAULT_STALE => c"RL_FAULT_STALE: a sensor is missing beyond max_missing_cycles",
        RL_FAULT_TRACKING => {
            c"RL_FAULT_TRACKING: a joint is not where the commands took it (not following, frozen encoder)"
        }
        RL_FAULT_BASE_ERROR => c"RL_FAULT_BASE_ERROR: the base attitude estimate is beyond base_limit_rad",
        RL_FAULT_MODEL => c"RL_FAULT_MODEL: the nominal model or the plan's rollout failed",
        _ => c"unknown RL_FAULT code",
    };
    text.as_ptr()
}
