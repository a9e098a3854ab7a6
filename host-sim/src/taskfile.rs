//! Task files (TOML): schema, loading, and conversion into the core's [`Task`].
//!
//! Owns the on-disk format of `spec/tasks/paper.toml`. Every table rejects unknown keys;
//! angles are degrees (`_deg`), everything else SI with the unit in the key name. Paths are
//! relative to the task file. Every error names the file, the key and the value.

use crate::clearance::{CollisionSection, KeepOutSection};
use crate::error::{CliError, Context};
use crate::goal::{Asked, Goal};
use crate::urdf::{self, Chain};
use reactionless::{
    Error as CoreError, Family, Integrator, Motion, Param, PlannerConfig, Pose, RefineAgainst,
    Robot, Strategy, Task,
};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A whole task file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TaskFile {
    /// `[robot]`.
    pub robot: RobotSection,
    /// `[start]`.
    pub start: StartSection,
    /// `[target]`.
    pub target: TargetSection,
    /// `[motion]`.
    pub motion: MotionSection,
    /// `[planner]`: the core's settings, read straight into them (defaults: spec §7).
    #[serde(default)]
    pub planner: PlannerConfig,
    /// `[check]`: thresholds of `host-sim check`.
    #[serde(default)]
    pub check: CheckSection,
    /// `[limits]`: joint limits beyond the URDF's (acceleration, for `retime`).
    #[serde(default)]
    pub limits: LimitsSection,
    /// `[retime]`: settings of `host-sim retime` and `plan --retime`.
    #[serde(default)]
    pub retime: RetimeSection,
    /// `[dispersion]`: settings of `host-sim disperse` (see `crate::dispersion`).
    #[serde(default)]
    pub dispersion: DispersionSection,
    /// `[preshape]`: when present, plan in two phases (spec §15, docs/twophase.md).
    #[serde(default)]
    pub preshape: Option<PreshapeSection>,
    /// `[sensors]`: the truth model's sensors of a closed-loop flight (spec §12, see
    /// `crate::sensors`).
    #[serde(default)]
    pub sensors: SensorsSection,
    /// `[closed_loop]`: the executor of a closed-loop flight (`disperse --closed-loop`,
    /// see `crate::closed_loop`).
    #[serde(default)]
    pub closed_loop: LoopSection,
    /// `[[keep_out]]`: volumes of the inertial frame the robot must keep out of (spec §13,
    /// see `crate::clearance`).
    #[serde(default)]
    pub keep_out: Vec<KeepOutSection>,
    /// `[collision]`: the required clearance and the pairs not checked. Its presence (or
    /// a `[[keep_out]]`) makes clearance a requirement of the plan and of `check`; without
    /// either, the clearance of the robot's own geometry is reported, not required.
    #[serde(default)]
    pub collision: Option<CollisionSection>,
}

/// One number for every joint, or one per joint.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(untagged)]
pub enum PerJoint {
    /// The same value for every joint.
    One(f64),
    /// One value per joint, in URDF order.
    Each(Vec<f64>),
}

/// `[dispersion]`: the standard deviations (all ≥ 0; 0 = not dispersed).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct DispersionSection {
    /// Relative mass dispersion of every body (1 = 100 %).
    pub mass_rel_sigma: f64,
    /// Relative inertia dispersion of every body.
    pub inertia_rel_sigma: f64,
    /// CoM offset per axis (m).
    pub com_sigma_m: f64,
    /// Joint-axis misalignment per perpendicular direction (deg).
    pub axis_sigma_deg: f64,
    /// Initial base rate per base axis (deg/s).
    pub base_rate_sigma_deg_s: f64,
    /// Normal draws beyond this many sigmas are redrawn (> 0).
    pub truncation_sigmas: f64,
}

impl Default for DispersionSection {
    fn default() -> Self {
        Self {
            mass_rel_sigma: 0.0,
            inertia_rel_sigma: 0.0,
            com_sigma_m: 0.0,
            axis_sigma_deg: 0.0,
            base_rate_sigma_deg_s: 0.0,
            truncation_sigmas: 3.0,
        }
    }
}

/// One `[dispersion]` key: the task file's key, `disperse`'s flag of the same name, its
/// unit (as docs/task-format.md gives it) and its bound. [`DispersionSection::KEYS`] lists
/// them; the flags, [`DispersionSection::validate`], `summary.md` and the run's identity
/// all read that list.
#[derive(Debug, Clone, Copy)]
pub struct DispersionKey {
    /// The key, e.g. `mass_rel_sigma` (a field of [`DispersionSection`]).
    pub name: &'static str,
    /// Unit, as the task-format table gives it (`—` for a ratio).
    pub unit: &'static str,
    /// Whether 0 is allowed (a σ: 0 is not dispersed) or the value must be > 0.
    pub zero_allowed: bool,
    /// The help of the flag `--NAME` (`_` written `-`).
    pub help: &'static str,
    field: fn(&mut DispersionSection) -> &mut f64,
}

impl DispersionKey {
    /// The flag's long name: the key with `-` for `_` (`mass-rel-sigma`).
    pub fn long(&self) -> String {
        self.name.replace('_', "-")
    }

    /// This key's value in `s`.
    pub fn get(&self, s: &DispersionSection) -> f64 {
        let mut copy = *s;
        *(self.field)(&mut copy)
    }

    /// Sets this key's value in `s`.
    pub fn set(&self, s: &mut DispersionSection, value: f64) {
        *(self.field)(s) = value;
    }
}

/// The [`DispersionKey`] of field `$field`, named after it.
macro_rules! dispersion_key {
    ($field:ident, $unit:literal, zero_allowed: $zero:literal, $help:literal) => {
        DispersionKey {
            name: stringify!($field),
            unit: $unit,
            zero_allowed: $zero,
            help: $help,
            field: |s| &mut s.$field,
        }
    };
}

impl DispersionSection {
    /// Every key, in table order (the order of `summary.md` and of the run's identity).
    pub const KEYS: [DispersionKey; 6] = [
        dispersion_key!(mass_rel_sigma, "—", zero_allowed: true,
            "Relative mass dispersion of every body (0.05 = 5 %)"),
        dispersion_key!(inertia_rel_sigma, "—", zero_allowed: true,
            "Relative inertia dispersion of every body"),
        dispersion_key!(com_sigma_m, "m", zero_allowed: true,
            "CoM offset per axis (m)"),
        dispersion_key!(axis_sigma_deg, "deg", zero_allowed: true,
            "Joint-axis misalignment per perpendicular direction (deg)"),
        dispersion_key!(base_rate_sigma_deg_s, "deg/s", zero_allowed: true,
            "Initial base rate per base axis (deg/s)"),
        dispersion_key!(truncation_sigmas, "σ", zero_allowed: false,
            "Normal draws beyond this many sigmas are redrawn (default 3)"),
    ];

    /// Each setting's key and value, in table order.
    pub fn entries(&self) -> [(&'static str, f64); 6] {
        Self::KEYS.map(|k| (k.name, k.get(self)))
    }

    /// Checks every value; `source(key)` names where a bad value came from (the flag or
    /// the task file's key).
    pub fn validate(&self, source: impl Fn(&str) -> String) -> Result<(), CliError> {
        for key in Self::KEYS {
            let v = key.get(self);
            let (ok, want) = if key.zero_allowed {
                (v.is_finite() && v >= 0.0, "a finite number >= 0")
            } else {
                (v.is_finite() && v > 0.0, "a finite number > 0")
            };
            if !ok {
                return Err(CliError::input(format!(
                    "{} = {v}: must be {want}",
                    source(key.name)
                )));
            }
        }
        if self.mass_rel_sigma * self.truncation_sigmas >= 1.0 {
            return Err(CliError::input(format!(
                "{} = {} with truncation_sigmas = {}: masses could reach zero (need mass_rel_sigma × truncation_sigmas < 1)",
                source("mass_rel_sigma"),
                self.mass_rel_sigma,
                self.truncation_sigmas
            )));
        }
        Ok(())
    }
}

/// `[sensors]`: the truth model's sensors (spec §12; `crate::sensors`). Defaults: a 5″
/// star tracker, a gyro of 0.01 °/√h and 0.05 °/h, 20-bit encoders, a 10 Hz control cycle
/// with one period of latency, no dropouts.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SensorsSection {
    /// Control period T_c (s, > 0): measurements at the start of each cycle.
    pub control_period_s: f64,
    /// Control periods between a measurement and the cycle its command is applied through
    /// (0..=10; spec §12: 1).
    pub latency_cycles: u32,
    /// Star-tracker noise per axis, 1σ (arcsec, ≥ 0).
    pub star_tracker_arcsec: f64,
    /// Gyro angle random walk (deg/√h, ≥ 0).
    pub gyro_arw_deg_rt_h: f64,
    /// Gyro bias per axis, 1σ, constant over a flight (deg/h, ≥ 0).
    pub gyro_bias_deg_h: f64,
    /// Joint-encoder resolution (bits, 1..=40): 2π/2^bits rad per count.
    pub encoder_bits: u32,
    /// Wheel-momentum measurement noise per axis, 1σ (N m s, ≥ 0).
    pub wheel_momentum_sigma_nms: f64,
    /// Probability that any one measurement is missing (0 ≤ p < 1).
    pub dropout_probability: f64,
}

/// `[closed_loop]`: the executor's gains, filter and fault settings (the control period
/// is `[sensors] control_period_s`). Defaults: [`reactionless::closed_loop::LoopConfig::DEFAULT`].
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct LoopSection {
    /// Base-attitude gain k_b (1/s, ≥ 0).
    pub base_gain_per_s: f64,
    /// End-effector gain k_e (1/s, ≥ 0; 0 turns the end-effector task off).
    pub ee_gain_per_s: f64,
    /// Damping of the base pseudo-inverse (≥ 0).
    pub base_damping: f64,
    /// Damping of the end-effector pseudo-inverse (m, > 0 when ee_gain_per_s > 0).
    pub ee_damping_m: f64,
    /// Length weighing orientation against position in the end-effector task (m, > 0).
    pub orientation_length_m: f64,
    /// Weight of the end effector's motion in the base correction (1/m², ≥ 0; 0: the
    /// minimum-norm joint rate).
    pub drag_weight_per_m2: f64,
    /// Pull of the attitude estimate toward each star-tracker reading (0 < g ≤ 1).
    pub filter_gain: f64,
    /// Pull of the drift estimate (the base rate the model does not explain) toward each
    /// cycle's (0 ≤ g ≤ 1; 0: no drift feed-forward).
    pub drift_gain: f64,
    /// Consecutive cycles a sensor may be missing before the safe state.
    pub max_missing_cycles: u32,
    /// Base attitude estimate beyond which the arm stops (deg, > 0).
    pub base_limit_deg: f64,
    /// Largest joint tracking error before the safe state (deg, > 0).
    pub tracking_tolerance_deg: f64,
    /// Largest gyro rate in range (deg/s, > 0).
    pub max_gyro_rate_deg_s: f64,
    /// Joint acceleration limit of every command change and of the stop (deg/s², > 0).
    pub qdd_max_deg_s2: f64,
    /// Correction time after t_f (s, ≥ 0; a whole number of control periods).
    pub extend_s: f64,
}

impl Default for LoopSection {
    fn default() -> Self {
        let d = reactionless::closed_loop::LoopConfig::DEFAULT;
        Self {
            base_gain_per_s: d.base_gain,
            ee_gain_per_s: d.ee_gain,
            base_damping: d.base_damping,
            ee_damping_m: d.ee_damping,
            orientation_length_m: d.orientation_length,
            drag_weight_per_m2: d.drag_weight,
            filter_gain: d.filter_gain,
            drift_gain: d.drift_gain,
            max_missing_cycles: d.max_missing_cycles,
            base_limit_deg: d.base_limit.to_degrees(),
            tracking_tolerance_deg: d.tracking_tolerance.to_degrees(),
            max_gyro_rate_deg_s: d.max_gyro_rate.to_degrees(),
            qdd_max_deg_s2: d.qdd_max.to_degrees(),
            extend_s: f64::from(d.extend_cycles) * d.period,
        }
    }
}

impl LoopSection {
    /// The core's settings for the control period `period` (s); `source(key)` names where
    /// a bad value came from.
    pub fn config(
        &self,
        period: f64,
        source: impl Fn(&str) -> String,
    ) -> Result<reactionless::closed_loop::LoopConfig, CliError> {
        let cycles = (self.extend_s / period).round();
        if !(self.extend_s.is_finite() && self.extend_s >= 0.0)
            || (cycles * period - self.extend_s).abs() > 1e-9 * period.max(self.extend_s)
            || cycles > 1e6
        {
            return Err(CliError::input(format!(
                "{} = {}: must be a whole number of control periods ({period} s), >= 0",
                source("extend_s"),
                self.extend_s
            )));
        }
        let c = reactionless::closed_loop::LoopConfig {
            period,
            base_gain: self.base_gain_per_s,
            ee_gain: self.ee_gain_per_s,
            base_damping: self.base_damping,
            ee_damping: self.ee_damping_m,
            orientation_length: self.orientation_length_m,
            drag_weight: self.drag_weight_per_m2,
            filter_gain: self.filter_gain,
            drift_gain: self.drift_gain,
            max_missing_cycles: self.max_missing_cycles,
            base_limit: self.base_limit_deg.to_radians(),
            tracking_tolerance: self.tracking_tolerance_deg.to_radians(),
            max_gyro_rate: self.max_gyro_rate_deg_s.to_radians(),
            qdd_max: self.qdd_max_deg_s2.to_radians(),
            extend_cycles: cycles as u32,
        };
        c.validate().map_err(|e| {
            let key = match &e {
                reactionless::Error::NotFinite(p)
                | reactionless::Error::NotPositive(p)
                | reactionless::Error::Negative(p)
                | reactionless::Error::LoopSetting(p) => p.key(),
                _ => None,
            };
            let name = key.map_or_else(String::new, |k| {
                let k = k.rsplit('.').next().unwrap_or(k);
                format!("{}: ", source(k))
            });
            CliError::input(format!("{name}{e}"))
        })?;
        Ok(c)
    }
}

impl Default for SensorsSection {
    fn default() -> Self {
        Self {
            control_period_s: 0.1,
            latency_cycles: 1,
            star_tracker_arcsec: 5.0,
            gyro_arw_deg_rt_h: 0.01,
            gyro_bias_deg_h: 0.05,
            encoder_bits: 20,
            wheel_momentum_sigma_nms: 2e-4,
            dropout_probability: 0.0,
        }
    }
}

impl SensorsSection {
    /// Longest latency (control periods).
    pub const MAX_LATENCY_CYCLES: u32 = 10;
    /// Finest encoder (bits).
    pub const MAX_ENCODER_BITS: u32 = 40;

    /// Checks every value; `source(key)` names where a bad value came from (a flag or the
    /// task file's key).
    pub fn validate(&self, source: impl Fn(&str) -> String) -> Result<(), CliError> {
        let bad = |key: &str, v: String, want: &str| {
            Err(CliError::input(format!(
                "{} = {v}: must be {want}",
                source(key)
            )))
        };
        for (key, v) in [
            ("star_tracker_arcsec", self.star_tracker_arcsec),
            ("gyro_arw_deg_rt_h", self.gyro_arw_deg_rt_h),
            ("gyro_bias_deg_h", self.gyro_bias_deg_h),
            ("wheel_momentum_sigma_nms", self.wheel_momentum_sigma_nms),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(key, v.to_string(), "a finite number >= 0");
            }
        }
        let t = self.control_period_s;
        if !(t.is_finite() && t > 0.0) {
            return bad("control_period_s", t.to_string(), "a finite number > 0 (s)");
        }
        let p = self.dropout_probability;
        if !(p.is_finite() && (0.0..1.0).contains(&p)) {
            return bad("dropout_probability", p.to_string(), "in [0, 1)");
        }
        if self.latency_cycles > Self::MAX_LATENCY_CYCLES {
            return bad(
                "latency_cycles",
                self.latency_cycles.to_string(),
                "an integer in 0..=10",
            );
        }
        if !(1..=Self::MAX_ENCODER_BITS).contains(&self.encoder_bits) {
            return bad(
                "encoder_bits",
                self.encoder_bits.to_string(),
                "an integer in 1..=40",
            );
        }
        Ok(())
    }
}

/// `[preshape]`: a two-phase plan (spec §15): phase 1 pre-shapes the arm from `[start]` to a
/// start the planner chooses while the attitude control holds the base, phase 2 is the
/// reactionless motion from there. Every key has a default, so `[preshape]` alone asks for
/// a two-phase plan.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PreshapeSection {
    /// Phase 1's joint acceleration limit (deg/s², > 0); its rate limit is the robot's.
    pub qdd_max_deg_s2: f64,
    /// Longest phase 1 (s, > 0).
    pub max_duration_s: f64,
    /// Angular momentum the attitude control can absorb (N m s, > 0).
    pub max_momentum_nms: f64,
    /// Torque the attitude control can apply (N m, > 0).
    pub max_torque_nm: f64,
    /// Distance the end effector keeps from the target at phase 2's start (m, ≥ 0) …
    pub standoff_m: f64,
    /// … or this angle from its attitude (deg, ≥ 0); either is enough.
    pub standoff_deg: f64,
}

impl Default for PreshapeSection {
    fn default() -> Self {
        let c = reactionless::TwoPhaseConfig::reference();
        Self {
            qdd_max_deg_s2: c.qdd_max.to_degrees(),
            max_duration_s: c.max_duration,
            max_momentum_nms: c.max_momentum,
            max_torque_nm: c.max_torque,
            standoff_m: c.standoff_m,
            standoff_deg: c.standoff_rad.to_degrees(),
        }
    }
}

impl PreshapeSection {
    /// The core's settings: these bounds, phase 2's success test `tolerance` on f, the
    /// rollout budget and the base-disturbance limit (deg, `[check]`).
    #[must_use]
    pub fn config(
        &self,
        tolerance: f64,
        max_rollouts: u32,
        max_base_disturbance_deg: f64,
    ) -> reactionless::TwoPhaseConfig {
        reactionless::TwoPhaseConfig {
            qdd_max: self.qdd_max_deg_s2.to_radians(),
            max_duration: self.max_duration_s,
            max_momentum: self.max_momentum_nms,
            max_torque: self.max_torque_nm,
            standoff_m: self.standoff_m,
            standoff_rad: self.standoff_deg.to_radians(),
            tolerance,
            max_rollouts,
            max_base_disturbance: max_base_disturbance_deg.to_radians(),
            ..reactionless::TwoPhaseConfig::reference()
        }
    }
}

/// `[limits]`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LimitsSection {
    /// Joint acceleration limits (deg/s²), one number or one per joint, > 0.
    pub qdd_max_deg_s2: Option<PerJoint>,
}

/// `[retime]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RetimeSection {
    /// Arc-length grid points (≥ 3).
    pub grid: u32,
    /// Factor applied to every rate and acceleration limit, in (0, 1].
    pub margin: f64,
}

impl Default for RetimeSection {
    fn default() -> Self {
        Self {
            grid: reactionless::retime::DEFAULT_GRID,
            margin: 1.0,
        }
    }
}

/// `[check]`: what `host-sim check` accepts.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CheckSection {
    /// Largest acceptable base rotation over the motion, truth model (deg), > 0.
    pub max_base_disturbance_deg: f64,
}

impl Default for CheckSection {
    fn default() -> Self {
        Self {
            max_base_disturbance_deg: 0.01,
        }
    }
}

/// `[robot]`: which robot and which link is the end effector.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotSection {
    /// URDF path, relative to the task file.
    pub urdf: PathBuf,
    /// End-effector link (default: the URDF's only leaf link).
    pub ee_link: Option<String>,
}

/// `[start]`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StartSection {
    /// Start configuration, one angle per revolute joint (deg).
    pub q_deg: Vec<f64>,
}

/// `[target]`: the desired end-effector pose in the inertial frame (the base frame at t=0).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TargetSection {
    /// Position (m), 3 values.
    pub position_m: Vec<f64>,
    /// Attitude as a unit quaternion `[w, x, y, z]` (|‖q‖ − 1| ≤ 1e-6).
    pub quat_wxyz: Vec<f64>,
    /// Largest acceptable end-effector position error (m), > 0 (default
    /// [`crate::goal::DEFAULT_POSITION_TOLERANCE_M`]). The planner is asked to refine to
    /// `f ≤` this (`‖e_p‖ ≤ f`), and `check` holds the plan to it.
    pub position_tolerance_m: Option<f64>,
    /// Largest acceptable end-effector orientation error (deg), > 0 (default
    /// [`crate::goal::DEFAULT_ORIENTATION_TOLERANCE_DEG`]). The planner is asked to refine
    /// to `f ≤` this in radians (the rotation angle is `≤ f`), and `check` holds the plan
    /// to it.
    pub orientation_tolerance_deg: Option<f64>,
    /// What a plan must reach: `"pose"` (the tolerances above, the default) or `"sigma_e"`
    /// (the paper's `f ≤ σ_e`; `--paper`). See [`crate::goal`].
    #[serde(default)]
    pub goal: Goal,
}

/// `[motion]`: duration and time grid.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MotionSection {
    /// Duration t_f (s), > 0, a whole multiple of `dt_s`.
    pub tf_s: f64,
    /// Integration step (s), > 0.
    pub dt_s: f64,
    /// Time-law degree n (1..=8), default 1.
    #[serde(default = "default_n")]
    pub n: u32,
    /// The velocity profiles η names: `"paper"` (eq. 14, the default) or
    /// `"free_amplitude"` (the exact rate bound on the written samples and η's magnitude as
    /// the amplitude, for targets near a fixed start's reach; see `reactionless::Family`).
    #[serde(default)]
    pub family: Family,
    /// Equal rest-to-rest segments of the motion, each with its own η (`1..=4`, default 1;
    /// more than one needs `family = "free_amplitude"` and the multistart, and must divide
    /// `tf_s / dt_s`; see `reactionless::Motion::with_segments`).
    #[serde(default = "default_segments")]
    pub segments: u32,
    /// How the path is integrated: `"euler"` (the reference discretization of spec §5,
    /// the default, the paper's) or `"rk4"` (the continuous path of spec §14 to fourth
    /// order in steps of several `dt`, the samples at `dt` from a dense output; see
    /// `reactionless::Integrator`). `--integrator` overrides it.
    #[serde(default)]
    pub integrator: Integrator,
    /// The RK4 step (s): a whole multiple of `dt_s` that divides each segment (default:
    /// the largest one up to 0.4 s). Only with `integrator = "rk4"`.
    pub integrator_step_s: Option<f64>,
}

fn default_n() -> u32 {
    1
}

fn default_segments() -> u32 {
    1
}

/// A parsed task file with its robot.
#[derive(Debug, Clone)]
pub struct LoadedTask {
    /// The task file path as given.
    pub path: PathBuf,
    /// The task file's text as read.
    pub text: String,
    /// The URDF's text as read.
    pub urdf_text: String,
    /// Parsed contents.
    pub file: TaskFile,
    /// The robot chain.
    pub chain: Chain,
    /// Resolved URDF path.
    pub urdf_path: PathBuf,
}

/// Reads a task file and the URDF it names.
pub fn load(path: &Path) -> Result<LoadedTask, CliError> {
    let shown = path.display();
    let text =
        std::fs::read_to_string(path).or_input(|| format!("{shown}: cannot read task file"))?;
    let file: TaskFile = toml::from_str(&text).map_err(|e| toml_error(&shown, &e))?;
    let urdf_path = path
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .join(&file.robot.urdf);
    let urdf_err = |m: String| {
        CliError::input(format!(
            "{shown}: [robot] urdf = {:?}: {m}",
            file.robot.urdf.display().to_string()
        ))
    };
    let urdf_text = std::fs::read_to_string(&urdf_path).map_err(|e| {
        urdf_err(format!(
            "cannot read URDF {} (resolved relative to the task file): {e}",
            urdf_path.display()
        ))
    })?;
    let chain = urdf::parse(&urdf_text, file.robot.ee_link.as_deref()).map_err(urdf_err)?;
    let lt = LoadedTask {
        path: path.to_path_buf(),
        text,
        urdf_text,
        file,
        chain,
        urdf_path,
    };
    lt.sanity()?;
    Ok(lt)
}

/// Parses a task from its text, with the URDF given as text (for replays and checks of
/// self-contained bundles). `origin` names the source in messages.
pub fn from_texts(origin: &Path, text: &str, urdf_text: &str) -> Result<LoadedTask, CliError> {
    let shown = origin.display();
    let file: TaskFile = toml::from_str(text).map_err(|e| toml_error(&shown, &e))?;
    let chain = urdf::parse(urdf_text, file.robot.ee_link.as_deref())
        .map_err(|m| CliError::input(format!("{shown}: robot: {m}")))?;
    let lt = LoadedTask {
        path: origin.to_path_buf(),
        text: text.to_string(),
        urdf_text: urdf_text.to_string(),
        urdf_path: origin.with_file_name(&file.robot.urdf),
        file,
        chain,
    };
    lt.sanity()?;
    Ok(lt)
}

/// Fewest integration steps a task's path may have (`[motion] tf_s / dt_s`): the Euler path
/// leaves the reaction null space by about 0.073°·dt/s of base rotation (spec §8), so a
/// coarser grid cannot give a reactionless plan, and a search on it only burns its budget.
pub const MIN_STEPS: u32 = 100;

/// The reach bound's margin over the sum of link lengths and the base's drift.
const REACH_MARGIN: f64 = 1.1;

/// File names of a self-contained task bundle in an output directory.
pub const BUNDLE_TASK: &str = "task.toml";
/// The URDF copy of a bundle.
pub const BUNDLE_URDF: &str = "robot.urdf";

/// A TOML error with its file name, keeping toml's report: the line and column, the
/// snippet with the offending span marked, and the reason.
fn toml_error(shown: &impl std::fmt::Display, e: &toml::de::Error) -> CliError {
    CliError::input(format!("{shown}: {}", e.to_string().trim_end()))
}

impl LoadedTask {
    /// The closed loop's settings: `[closed_loop]` at `[sensors] control_period_s`.
    pub fn loop_config(&self) -> Result<reactionless::closed_loop::LoopConfig, CliError> {
        self.file
            .closed_loop
            .config(self.file.sensors.control_period_s, |key| {
                format!("{}: [closed_loop] {key}", self.path.display())
            })
    }

    /// The task as a self-contained bundle: the task file re-written with `[robot] urdf =
    /// "robot.urdf"` and, for a plan, every planner setting it used (`used`: the whole
    /// `[planner]` table, flags applied and the refinement tolerance resolved, and `[target]
    /// goal`), so that `check` judges the bundle by the settings that made it; and the
    /// URDF's text.
    pub fn bundle(
        &self,
        used: Option<(&PlannerConfig, &Asked)>,
    ) -> Result<(String, String), CliError> {
        let mut table: toml::Table =
            toml::from_str(&self.text).or_internal(|| "re-reading the task")?;
        if let Some(toml::Value::Table(robot)) = table.get_mut("robot") {
            robot.insert("urdf".into(), toml::Value::String(BUNDLE_URDF.into()));
        }
        if let Some((config, asked)) = used {
            if i64::try_from(config.seed).is_err() {
                return Err(CliError::input(format!(
                    "--seed {} does not fit a TOML integer (at most {})",
                    config.seed,
                    i64::MAX
                )));
            }
            let planner = toml::Value::try_from(config).or_internal(|| "writing [planner]")?;
            table.insert("planner".into(), planner);
            if let Some(toml::Value::Table(target)) = table.get_mut("target") {
                target.insert("goal".into(), toml::Value::String(asked.goal.name().into()));
            }
        }
        let text = toml::to_string(&table).or_internal(|| "writing the task")?;
        Ok((text, self.urdf_text.clone()))
    }

    /// The goal of this task for `config` (the task's `[planner]` with the command line's
    /// overrides applied), resolved ([`Asked::resolve`]). `paper` (`--paper`) makes it σ_e
    /// whatever the task says, its pose tolerances ignored.
    pub fn asked(&self, config: &PlannerConfig, paper: bool) -> Result<Asked, CliError> {
        let t = &self.file.target;
        let name = self.path.display().to_string();
        if paper {
            return Asked::resolve(Goal::SigmaE, config, None, None, &name);
        }
        Asked::resolve(
            t.goal,
            config,
            t.position_tolerance_m,
            t.orientation_tolerance_deg,
            &name,
        )
    }

    /// `[limits] qdd_max_deg_s2` (deg/s², or `accel_deg_s2` for every joint when given),
    /// checked for length, finiteness and sign; `None` if neither is set.
    pub fn qdd_max_deg<const N: usize>(
        &self,
        accel_deg_s2: Option<f64>,
    ) -> Result<Option<[f64; N]>, CliError> {
        let Some(values) = self.qdd_values(accel_deg_s2, N)? else {
            return Ok(None);
        };
        let mut out = [0.0; N];
        for (o, v) in out.iter_mut().zip(&values) {
            *o = *v;
        }
        Ok(Some(out))
    }

    /// [`LoadedTask::qdd_max_deg`] for `n` joints.
    pub fn qdd_values(
        &self,
        accel_deg_s2: Option<f64>,
        n: usize,
    ) -> Result<Option<Vec<f64>>, CliError> {
        let key = "[limits] qdd_max_deg_s2";
        let values: Vec<f64> = match (accel_deg_s2, &self.file.limits.qdd_max_deg_s2) {
            (Some(a), _) => vec![a; n],
            (None, Some(PerJoint::One(a))) => vec![*a; n],
            (None, Some(PerJoint::Each(v))) => {
                self.length(key, v, n)?;
                v.clone()
            }
            (None, None) => return Ok(None),
        };
        for (i, v) in values.iter().enumerate() {
            if !(v.is_finite() && *v > 0.0) {
                let what = match (accel_deg_s2, &self.file.limits.qdd_max_deg_s2) {
                    (Some(_), _) => "--accel-deg-s2".to_string(),
                    (None, Some(PerJoint::One(_))) => key.to_string(),
                    (None, _) => format!("{key}[{i}]"),
                };
                return Err(self.err(format!("{what} = {v} must be a finite number > 0")));
            }
        }
        Ok(Some(values))
    }

    /// Every value of the task file checked before any search, whether or not this run
    /// uses it: the motion grid and its fewest steps ([`MIN_STEPS`]), `[check]`, `[limits]`,
    /// `[retime]`, `[dispersion]`, the goal and its tolerances, and a target within the
    /// arm's reach ([`LoadedTask::reach_m`]). Each error names the key and the reason.
    fn sanity(&self) -> Result<(), CliError> {
        let d = self.file.check.max_base_disturbance_deg;
        if !(d.is_finite() && d > 0.0) {
            return Err(self.err(format!(
                "[check] max_base_disturbance_deg = {d} must be a finite number > 0"
            )));
        }
        let m = &self.file.motion;
        let motion = self.motion()?;
        if motion.steps() < MIN_STEPS {
            return Err(self.err(format!(
                "[motion] dt_s = {} gives tf_s / dt_s = {} steps; a reactionless path needs at least {MIN_STEPS} (dt_s <= {} s; dt_s is in seconds)",
                m.dt_s,
                motion.steps(),
                m.tf_s / f64::from(MIN_STEPS)
            )));
        }
        self.qdd_values(None, self.chain.dof())?;
        let rt = &self.file.retime;
        if rt.grid < reactionless::retime::MIN_GRID {
            return Err(self.err(format!(
                "[retime] grid = {} must be at least {}",
                rt.grid,
                reactionless::retime::MIN_GRID
            )));
        }
        if !(rt.margin.is_finite() && rt.margin > 0.0 && rt.margin <= 1.0) {
            return Err(self.err(format!(
                "[retime] margin = {} must lie in (0, 1]",
                rt.margin
            )));
        }
        self.file
            .dispersion
            .validate(|key| format!("{}: [dispersion] {key}", self.path.display()))?;
        self.file
            .sensors
            .validate(|key| format!("{}: [sensors] {key}", self.path.display()))?;
        self.loop_config()?;
        self.asked(&self.file.planner, false)?;
        if let Some(ps) = &self.file.preshape {
            ps.config(1e-6, 1, 0.01).validate().map_err(|e| {
                let key = e.param().and_then(|p| p.key()).unwrap_or("preshape");
                let name = key.strip_prefix("preshape.").unwrap_or(key);
                self.err(format!("[preshape] {name}: {e}"))
            })?;
        }
        self.scene(&self.start_rad())?;
        let t = &self.file.target.position_m;
        if t.len() == 3 && t.iter().all(|v| v.is_finite()) {
            let distance = t.iter().map(|v| v * v).sum::<f64>().sqrt();
            let reach = self.reach_m();
            if reach.is_finite() && distance > reach {
                return Err(self.err(format!(
                    "[target] position_m = {t:?} is {distance:.3} m from the base; the arm reaches at most {reach:.3} m (its link lengths, the base's drift and a 10 % margin): out of reach"
                )));
            }
        }
        Ok(())
    }

    /// `[start] q_deg` in radians, as many values as the file gives.
    pub fn start_rad(&self) -> Vec<f64> {
        self.file
            .start
            .q_deg
            .iter()
            .map(|d| d.to_radians())
            .collect()
    }

    /// The collision scene of this task (`crate::clearance`) with the robot at `q0` (rad) at
    /// the start: the URDF's geometry, `[[keep_out]]` and `[collision]`, checked.
    pub fn scene(&self, q0: &[f64]) -> Result<crate::clearance::Scene, CliError> {
        crate::clearance::Scene::new(
            &self.chain,
            &self.file.keep_out,
            self.file.collision.as_ref(),
            q0,
            &|m| self.err(m),
            &self.urdf_path,
        )
    }

    /// The farthest the end effector can be from the base frame's origin at `t = 0` (m): the
    /// first joint's offset plus every later joint's and the end effector's (the sum of link
    /// lengths) plus the largest link CoM offset, `R`; the base drifts by at most
    /// `2R·m_arm/m_total` (the CoM stays put); times a 10 % margin.
    pub fn reach_m(&self) -> f64 {
        let norm = |v: &[f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
        let c = &self.chain;
        let links: f64 =
            c.joints.iter().map(|j| norm(&j.origin.xyz)).sum::<f64>() + norm(&c.end_effector.xyz);
        let com = c
            .links
            .iter()
            .map(|l| norm(&l.inertial.xyz))
            .fold(0.0, f64::max);
        let r = links + com;
        let arm: f64 = c.links.iter().map(|l| l.mass).sum();
        let total = arm + c.base.mass;
        r * (1.0 + 2.0 * arm / total) * REACH_MARGIN
    }

    /// `[check] max_base_disturbance_deg`.
    pub fn max_base_disturbance_deg(&self) -> f64 {
        self.file.check.max_base_disturbance_deg
    }

    /// A bad-input error naming this task file.
    pub fn err(&self, msg: impl std::fmt::Display) -> CliError {
        CliError::input(format!("{}: {msg}", self.path.display()))
    }

    /// Checks that every number in `values` is finite; names the key and index.
    fn finite(&self, key: &str, values: &[f64]) -> Result<(), CliError> {
        for (i, v) in values.iter().enumerate() {
            if !v.is_finite() {
                return Err(self.err(format!("{key}[{i}] = {v} is not a finite number")));
            }
        }
        Ok(())
    }

    fn length(&self, key: &str, values: &[f64], want: usize) -> Result<(), CliError> {
        if values.len() != want {
            return Err(self.err(format!(
                "{key} has {} values, expected {want}",
                values.len()
            )));
        }
        Ok(())
    }

    /// The validated robot model.
    pub fn robot<const N: usize>(&self) -> Result<Robot<N>, CliError> {
        let desc = self.chain.desc::<N>()?;
        Robot::new(&desc).map_err(|e| {
            self.err(format!(
                "URDF {}: {}",
                self.urdf_path.display(),
                self.chain.explain(&e)
            ))
        })
    }

    /// The validated motion grid.
    pub fn motion(&self) -> Result<Motion, CliError> {
        let m = &self.file.motion;
        let motion = Motion::new(m.tf_s, m.dt_s, m.n).map_err(|e| {
            let what = match e {
                CoreError::NotFinite(Param::FinalTime)
                | CoreError::NotPositive(Param::FinalTime) => {
                    format!("[motion] tf_s = {}: must be a finite number > 0", m.tf_s)
                }
                CoreError::NotFinite(Param::TimeStep) | CoreError::NotPositive(Param::TimeStep) => {
                    format!("[motion] dt_s = {}: must be a finite number > 0", m.dt_s)
                }
                CoreError::StepsNotInteger => format!(
                    "[motion] tf_s = {} is not a whole multiple of dt_s = {}",
                    m.tf_s, m.dt_s
                ),
                CoreError::TooManySteps { max } => format!(
                    "[motion] tf_s / dt_s = {} exceeds the maximum of {max} steps",
                    m.tf_s / m.dt_s,
                ),
                CoreError::DegreeOutOfRange { max } => {
                    format!("[motion] n = {} is outside 1..={max}", m.n)
                }
                other => other.to_string(),
            };
            self.err(what)
        })?;
        let motion = motion
            .with_family(m.family)
            .with_segments(m.segments)
            .map_err(|e| self.err(format!("[motion] segments = {}: {e}", m.segments)))?
            .with_integrator(m.integrator)
            .map_err(|e| {
                self.err(format!(
                    "[motion] integrator = {:?}: {e}",
                    m.integrator.name()
                ))
            })?;
        let Some(step) = m.integrator_step_s else {
            return Ok(motion);
        };
        let key = format!("[motion] integrator_step_s = {step}");
        if m.integrator == Integrator::Euler {
            return Err(self.err(format!("{key}: only with integrator = \"rk4\" or \"ab5\"")));
        }
        let ratio = step / m.dt_s;
        let stride = ratio.round();
        if !(step.is_finite() && step > 0.0)
            || (stride - ratio).abs() > 1e-9 * ratio
            || stride > f64::from(u32::MAX)
        {
            return Err(self.err(format!(
                "{key}: must be a whole multiple of dt_s = {} s",
                m.dt_s
            )));
        }
        motion.with_integrator_stride(stride as u32).map_err(|_| {
            self.err(format!(
                "{key}: {stride} steps of dt_s do not divide each segment's {} steps",
                motion.segment().steps()
            ))
        })
    }

    /// Makes the task integrate with `integrator` (the `--integrator` flag), in its parsed
    /// form and in its text (so the bundle a plan writes says so); its `integrator_step_s`,
    /// if any, stays. Nothing for `None`.
    ///
    /// # Errors
    /// The task's motion then invalid (as [`LoadedTask::motion`]).
    pub fn set_integrator(&mut self, integrator: Option<Integrator>) -> Result<(), CliError> {
        let Some(integrator) = integrator else {
            return Ok(());
        };
        if integrator == self.file.motion.integrator {
            return Ok(());
        }
        let mut table: toml::Table =
            toml::from_str(&self.text).or_internal(|| "re-reading the task")?;
        if let Some(toml::Value::Table(motion)) = table.get_mut("motion") {
            motion.insert(
                "integrator".into(),
                toml::Value::String(integrator.name().into()),
            );
            if integrator == Integrator::Euler {
                motion.remove("integrator_step_s");
                self.file.motion.integrator_step_s = None;
            }
        }
        self.text = toml::to_string(&table).or_internal(|| "writing the task")?;
        self.file.motion.integrator = integrator;
        self.motion().map(|_| ())
    }

    /// Start configuration (rad), checked for length and finiteness.
    pub fn start<const N: usize>(&self) -> Result<[f64; N], CliError> {
        let q = &self.file.start.q_deg;
        self.length("[start] q_deg", q, N)?;
        self.finite("[start] q_deg", q)?;
        let mut out = [0.0; N];
        for (o, v) in out.iter_mut().zip(q) {
            *o = v.to_radians();
        }
        Ok(out)
    }

    /// Target pose, checked for lengths and finiteness (unit norm is checked by the core).
    pub fn target(&self) -> Result<Pose, CliError> {
        let t = &self.file.target;
        self.length("[target] position_m", &t.position_m, 3)?;
        self.length("[target] quat_wxyz", &t.quat_wxyz, 4)?;
        self.finite("[target] position_m", &t.position_m)?;
        self.finite("[target] quat_wxyz", &t.quat_wxyz)?;
        let mut p = Pose {
            position: [0.0; 3],
            quat_wxyz: [0.0; 4],
        };
        p.position.copy_from_slice(&t.position_m);
        p.quat_wxyz.copy_from_slice(&t.quat_wxyz);
        Ok(p)
    }

    /// The core task, every input validated.
    pub fn task<const N: usize, const K: usize>(&self) -> Result<Task<N, K>, CliError> {
        let robot = self.robot::<N>()?;
        let q0 = self.start::<N>()?;
        let target = self.target()?;
        let motion = self.motion()?;
        let (lower, upper) = (*robot.lower(), *robot.upper());
        let set = self
            .scene(&q0)?
            .collision_set(&robot)
            .map_err(|m| self.err(format!("[collision]: {m}")))?;
        let task = Task::new(robot, q0, target, motion).map_err(|e| match e {
            CoreError::StartOutsideLimits(j) => {
                let i = usize::from(j) - 1;
                let get = |a: &[f64]| a.get(i).copied().unwrap_or(f64::NAN).to_degrees();
                self.err(format!(
                    "[start] q_deg[{i}] = {} is outside the limits of {} [{:.6}, {:.6}] deg",
                    self.file.start.q_deg.get(i).copied().unwrap_or(f64::NAN),
                    self.chain.joint_name(j),
                    get(&lower),
                    get(&upper)
                ))
            }
            CoreError::QuaternionNotUnit { tolerance } => {
                let q = &self.file.target.quat_wxyz;
                let n = q.iter().map(|v| v * v).sum::<f64>().sqrt();
                self.err(format!(
                    "[target] quat_wxyz = {q:?} has norm {n}, not 1 (tolerance {tolerance:e})"
                ))
            }
            CoreError::RankLoss { .. } => self.err(format!(
                "[start] q_deg = {:?}: the coupling inertia H~bm is rank-deficient there ({e})",
                self.file.start.q_deg
            )),
            other => self.err(other),
        })?;
        task.with_collision(set).map_err(|e| {
            self.err(format!(
                "[planner] integrator: {e} (the task has [collision] or [[keep_out]])"
            ))
        })
    }

    /// The planner settings of `[planner]`, with the command line's overrides applied,
    /// validated against a swarm capacity of `capacity`. An error names the flag when the
    /// bad value came from the command line, else the task file's key.
    pub fn planner(
        &self,
        capacity: usize,
        overrides: &Overrides,
    ) -> Result<PlannerConfig, CliError> {
        Ok(self.plan_settings(capacity, overrides)?.0)
    }

    /// [`LoadedTask::planner`] and the goal it was resolved from.
    pub fn plan_settings(
        &self,
        capacity: usize,
        overrides: &Overrides,
    ) -> Result<(PlannerConfig, Asked), CliError> {
        let mut config = self.file.planner;
        if let Some(s) = overrides.seed {
            config.seed = s;
        }
        if let Some(r) = overrides.refine_tolerance {
            config.refine_tolerance = Some(r);
        }
        if let Some(st) = overrides.strategy {
            config.strategy = st;
        }
        if let Some(a) = overrides.refine_against {
            config.refine_against = a;
        }
        let asked = self.asked(&config, overrides.paper)?;
        config.refine_tolerance = asked.refine_tolerance;
        config.validate(capacity).map_err(|e| {
            let flag = e.param().and_then(|p| overrides.flag_for(p));
            match flag {
                Some(flag) => CliError::input(format!("{flag}: {}", reason(&e, &config))),
                None => self.err(setting_error(&e, &config)),
            }
        })?;
        Ok((config, asked))
    }
}

/// Command-line values that replace task-file settings.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Overrides {
    /// `--seed`.
    pub seed: Option<u64>,
    /// `--refine-tolerance`.
    pub refine_tolerance: Option<f64>,
    /// `--strategy`.
    pub strategy: Option<Strategy>,
    /// `--refine-against`.
    pub refine_against: Option<RefineAgainst>,
    /// `--paper`: the goal is the paper's `f ≤ σ_e`, not the pose tolerances.
    pub paper: bool,
    /// `--integrator` ([`LoadedTask::set_integrator`]).
    pub integrator: Option<Integrator>,
}

impl Overrides {
    /// The flag that set `param`, if the command line set it.
    fn flag_for(&self, param: Param) -> Option<String> {
        match param {
            Param::RefineTolerance => self
                .refine_tolerance
                .map(|v| format!("--refine-tolerance {v}")),
            _ => None,
        }
    }
}

/// The value of `key` (dotted, below `[planner]`) in the effective settings, as text.
fn setting_value(config: &PlannerConfig, key: &str) -> String {
    let Ok(toml::Value::Table(table)) = toml::Value::try_from(config) else {
        return "?".into();
    };
    let mut value = toml::Value::Table(table);
    for part in key.split('.') {
        match value.get(part) {
            Some(v) => value = v.clone(),
            None => return "?".into(),
        }
    }
    value.to_string()
}

/// Why a setting was rejected, without naming it.
fn reason(e: &CoreError, config: &PlannerConfig) -> String {
    match e {
        CoreError::NotFinite(_) => "is not a finite number".into(),
        CoreError::NotPositive(_) => "must be > 0".into(),
        CoreError::Negative(_) => "must not be negative".into(),
        CoreError::CapacityExceeded { capacity, .. } => {
            format!("exceeds the capacity of {capacity}")
        }
        CoreError::InertiaWeightsInverted => format!("must not exceed w_max = {}", config.w_max),
        other => other.to_string(),
    }
}

/// `[table] key = value why` for a rejected planner setting, from [`Param::key`].
fn setting_error(e: &CoreError, config: &PlannerConfig) -> String {
    let param = match e {
        CoreError::InertiaWeightsInverted => Some(Param::WMin),
        other => other.param(),
    };
    match param.and_then(|p| p.key()) {
        Some(path) => {
            let (table, key) = path.rsplit_once('.').unwrap_or(("planner", path));
            let below = path.strip_prefix("planner.").unwrap_or(path);
            format!(
                "[{table}] {key} = {} {}",
                setting_value(config, below),
                reason(e, config)
            )
        }
        None => format!("[planner]: {e}"),
    }
}
