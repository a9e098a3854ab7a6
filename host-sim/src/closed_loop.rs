//! Closed-loop flight of a planned path on a truth model (spec §12): the core's
//! [`Executor`] fed by the truth model's sensors ([`crate::sensors`]) once per control
//! cycle, its commands held over the cycle and integrated by the truth model.
//!
//! Owns one flight ([`fly`]) and what it gives ([`LoopFigures`]); its settings are the
//! task's `[closed_loop]` table ([`LoopSection`], in `crate::taskfile` with the other
//! tables: degrees at this edge, the core's [`LoopConfig`] in SI inside).
//!
//! A flight of `sample` in the run seeded `seed`: the robot is `disperse`'s draw for the
//! same `(seed, sample)`, the sensors' noise comes from their own streams keyed by the
//! same pair ([`Sensors::new`]), so a flight depends on nothing else (not `--jobs`, not
//! shards). The truth model integrates the flown path at the plan's `dt` (≥ 10 midpoint
//! sub-steps per `dt`, [`TRUTH_SUBSTEPS`]), the joints moving at the commanded rates.

use crate::dispersion::{Draw, Figures, JointPath};
use crate::error::CliError;
use crate::sensors::{Sensors, Settings as SensorSettings};
use crate::taskfile::LoadedTask;
use reactionless::closed_loop::{Command, Executor, Fault, LoopConfig, Measurement, Mode};
use reactionless::geometry::quat_log;
use reactionless::{Task, TruthModel};
use serde::{Deserialize, Serialize};

pub use crate::taskfile::LoopSection;

const DEG: f64 = core::f64::consts::PI / 180.0;

/// What one closed-loop flight gives beyond the open-loop [`Figures`] (spec §12).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct LoopFigures {
    /// End of flight − t_f (s).
    pub extra_time_s: f64,
    /// Σ_r ∫|q̇_r| dt flown − the same for the plan (deg).
    pub extra_travel_deg: f64,
    /// Largest |commanded joint rate| over the flight (deg/s).
    pub largest_command_deg_s: f64,
    /// Largest |commanded joint rate| / the joint's velocity limit (≤ 1).
    pub largest_rate_fraction: f64,
    /// Cycles whose command a limit changed.
    pub limited_cycles: u32,
    /// Commands beyond a rate limit (0 unless something is wrong).
    pub rate_violations: u32,
    /// Whether the flight ended in the safe state.
    pub safe_stop: bool,
}

/// One closed-loop flight: its figures, the loop's, and the fault that stopped it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Flight {
    /// The truth model's figures over the whole flight.
    pub figures: Figures,
    /// The loop's figures.
    pub loop_figures: LoopFigures,
    /// The fault that sent the loop to its safe state, if one did.
    pub fault: Option<Fault>,
}

/// `summary.json` of an exported closed-loop flight (`disperse --closed-loop
/// --export-sample K --out DIR`): what the sample is, how it ended, and what `host-sim
/// view DIR` needs to draw it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FlightSummary {
    /// Always `closed_loop_sample`.
    pub kind: String,
    /// The run's seed.
    pub seed: u64,
    /// The sample (0-based).
    pub sample: u64,
    /// Planner-model end pose of the last flown configuration on the dispersed robot
    /// (identity base attitude, base placed by CoM conservation; m, unit quaternion): the
    /// last row of trajectory.csv, as `plan`'s `summary.json` gives it.
    pub end_pose: crate::artifacts::PoseJson,
    /// The truth model's figures of the flight (as runs.csv's row of the sample).
    pub figures: Figures,
    /// The loop's figures.
    pub loop_figures: LoopFigures,
    /// The fault that sent the loop to its safe state (the core's `Fault`, debug text), or
    /// null.
    pub fault: Option<String>,
    /// Angular momentum of the flight at `t = 0` (kg m²/s, inertial frame): zero unless the
    /// draw gives the base an initial rate.
    pub initial_momentum: [f64; 3],
    /// Control cycles flown (rows of cycles.csv).
    pub cycles: usize,
}

/// The `kind` of a [`FlightSummary`].
pub const FLIGHT_KIND: &str = "closed_loop_sample";

/// Per-cycle trace of a flight, for `fly`-style plots (one entry per control cycle).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Trace {
    /// Time of the measurement (s).
    pub t: Vec<f64>,
    /// True base rotation since t = 0 (rad, rotation vector).
    pub theta: Vec<[f64; 3]>,
    /// The executor's estimate of it (rad).
    pub theta_estimate: Vec<[f64; 3]>,
    /// The command decided this cycle (rad/s).
    pub command: Vec<Vec<f64>>,
    /// The flown joint path, every sample the truth model integrated: times (s).
    pub flown_t: Vec<f64>,
    /// The flown joint path: configurations (rad).
    pub flown_q: Vec<Vec<f64>>,
    /// The joint rates flown from each sample to the next, over `[t_s, t_{s+1})` (rad/s;
    /// zero at the last), as a rollout's samples hold them.
    pub flown_qd: Vec<Vec<f64>>,
    /// The truth model's base attitude at each sample (`[w, x, y, z]`).
    pub flown_base: Vec<[f64; 4]>,
}

impl Trace {
    /// The per-cycle trace as `cycles.csv` text: `t` (s), the true base rotation vector and
    /// the executor's estimate of it (deg, base frame), their magnitudes (deg), and the
    /// command decided that cycle per joint (deg/s).
    pub fn cycles_csv(&self) -> String {
        let n = self.command.first().map_or(0, Vec::len);
        let mut out = String::from(
            "t_s,theta_x_deg,theta_y_deg,theta_z_deg,estimate_x_deg,estimate_y_deg,estimate_z_deg,theta_deg,estimate_deg",
        );
        for j in 1..=n {
            out.push_str(&format!(",command{j}_deg_s"));
        }
        out.push('\n');
        let mut b = ryu::Buffer::new();
        let norm = |v: &[f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        for (k, t) in self.t.iter().enumerate() {
            let (th, es) = (self.theta[k], self.theta_estimate[k]);
            let mut row = vec![*t];
            row.extend(th.iter().map(|v| v.to_degrees()));
            row.extend(es.iter().map(|v| v.to_degrees()));
            row.push(norm(&th).to_degrees());
            row.push(norm(&es).to_degrees());
            row.extend(self.command[k].iter().map(|v| v.to_degrees()));
            let cells: Vec<String> = row.iter().map(|v| b.format(*v).to_string()).collect();
            out.push_str(&cells.join(","));
            out.push('\n');
        }
        out
    }

    /// The flown joint path as `trajectory.csv` text (`t,q1..qN,qd1..qdN`, s, rad and
    /// rad/s, each number in its shortest round-trip form; `qd` the rate flown from each
    /// sample to the next, zero at the last, as a plan's trajectory.csv): what
    /// `scripts/disperse-check.py` re-flies and `host-sim view` draws.
    pub fn flown_csv(&self) -> String {
        let n = self.flown_q.first().map_or(0, Vec::len);
        let mut out = String::from("t");
        for j in 1..=n {
            out.push_str(&format!(",q{j}"));
        }
        for j in 1..=n {
            out.push_str(&format!(",qd{j}"));
        }
        out.push('\n');
        let mut b = ryu::Buffer::new();
        for ((t, q), qd) in self.flown_t.iter().zip(&self.flown_q).zip(&self.flown_qd) {
            out.push_str(b.format(*t));
            for v in q.iter().chain(qd) {
                out.push(',');
                out.push_str(b.format(*v));
            }
            out.push('\n');
        }
        out
    }
}

/// Flies `path` (uniform `dt`, `T_c` a whole multiple of it) closed-loop on the truth model
/// of `lt` with `draw` applied, with `sample`'s sensors of the run seeded `seed`.
#[allow(clippy::too_many_arguments)]
pub fn fly<const N: usize, const K: usize>(
    lt: &LoadedTask,
    path: &JointPath<N>,
    draw: &Draw,
    sensors: &SensorSettings,
    config: &LoopConfig,
    seed: u64,
    sample: u64,
    mut trace: Option<&mut Trace>,
) -> Result<Flight, CliError> {
    let nominal: Task<N, K> = lt.task::<N, K>()?;
    let mut dispersed = lt.clone();
    dispersed.chain = draw.apply(&lt.chain);
    let task: Task<N, K> = dispersed.task::<N, K>()?;
    let (per, dt) = cycle_steps(path, config.period)?;
    let tf = path.t[path.t.len() - 1] - path.t[0];
    let plan_at = |j: usize| path.q[(j * per).min(path.q.len() - 1)];
    let mut truth = TruthModel::from_state(&task, draw.truth_state(&task));
    let mut sensors = Sensors::new(sensors, seed, sample);
    let q0 = path.q[0];
    let (mut exec, mut rate) = Executor::new(*config, nominal.robot(), &q0, tf, &plan_at(1))
        .map_err(|e| CliError::input(format!("closed loop: {e}")))?;
    let limits = *exec.rate_limits();
    let mut q = q0;
    let mut t = 0.0;
    truth.push(&q, t);
    if let Some(tr) = trace.as_deref_mut() {
        tr.flown_t.push(t);
        tr.flown_q.push(q.to_vec());
        tr.flown_qd.push(vec![0.0; N]);
        tr.flown_base.push(truth.attitude());
    }
    let mut prev = truth.attitude();
    let mut figures = LoopFigures {
        extra_time_s: 0.0,
        extra_travel_deg: 0.0,
        largest_command_deg_s: 0.0,
        largest_rate_fraction: 0.0,
        limited_cycles: 0,
        rate_violations: 0,
        safe_stop: false,
    };
    let note = |rate: &[f64; N], figures: &mut LoopFigures| {
        for (v, l) in rate.iter().zip(&limits) {
            figures.largest_command_deg_s = figures.largest_command_deg_s.max(v.abs() / DEG);
            figures.largest_rate_fraction = figures.largest_rate_fraction.max(v.abs() / l);
            if v.abs() > *l {
                figures.rate_violations += 1;
            }
        }
    };
    note(&rate, &mut figures);
    let mut travel = 0.0;
    let mut fault = None;
    // Bounded: the flight's cycles, then a stop from at most the rate limit.
    let stop_cycles =
        limits.iter().fold(0.0f64, |m, l| m.max(*l)) / (config.qdd_max * config.period);
    let most = exec.total_cycles() as usize + stop_cycles.ceil() as usize + 2;
    let mut cycle = 0usize;
    while cycle < most {
        let k = cycle;
        cycle += 1;
        // Measure at t_k.
        let att = truth.attitude();
        let w = if k == 0 {
            [0.0; 3]
        } else {
            let d = quat_log(reactionless::geometry::quat_mul(
                [prev[0], -prev[1], -prev[2], -prev[3]],
                att,
            ));
            [
                d.x / config.period,
                d.y / config.period,
                d.z / config.period,
            ]
        };
        let m = Measurement {
            star_tracker: sensors.star_tracker(att),
            gyro: sensors.gyro(w),
            joints: sensors.encoders(&q),
        };
        prev = att;
        let cmd: Command<N> = exec.step(nominal.robot(), &m, &plan_at(k + 2));
        if let Some(tr) = trace.as_deref_mut() {
            let th = quat_log(att);
            tr.t.push(t);
            tr.theta.push([th.x, th.y, th.z]);
            tr.theta_estimate.push(exec.base_estimate());
            tr.command.push(cmd.rate.to_vec());
        }
        if cmd.event.is_some() {
            fault = cmd.event;
        }
        if cmd.limited {
            figures.limited_cycles += 1;
        }
        note(&cmd.rate, &mut figures);
        // Fly cycle k at the rate decided one cycle ago.
        {
            for _ in 0..per {
                for (qi, v) in q.iter_mut().zip(&rate) {
                    *qi += v * dt;
                    travel += (v * dt).abs();
                }
                t += dt;
                truth.push(&q, t);
                if let Some(tr) = trace.as_deref_mut() {
                    // The rate just flown is the previous sample's, over [t_prev, t).
                    if let Some(last) = tr.flown_qd.last_mut() {
                        last.copy_from_slice(&rate);
                    }
                    tr.flown_t.push(t);
                    tr.flown_q.push(q.to_vec());
                    tr.flown_qd.push(vec![0.0; N]);
                    tr.flown_base.push(truth.attitude());
                }
            }
        }
        rate = cmd.rate;
        match cmd.mode {
            Mode::Done | Mode::Stopped(_) if rate.iter().all(|v| *v == 0.0) => break,
            _ => {}
        }
    }
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    let end = truth
        .end_pose()
        .ok_or_else(|| CliError::internal("truth model saw no samples"))?;
    let e = end.error_to(task.target());
    let plan_travel: f64 = path
        .q
        .windows(2)
        .map(|w| {
            w[0].iter()
                .zip(&w[1])
                .map(|(a, b)| (b - a).abs())
                .sum::<f64>()
        })
        .sum();
    figures.extra_time_s = t - tf;
    figures.extra_travel_deg = (travel - plan_travel) / DEG;
    figures.safe_stop = matches!(exec.mode(), Mode::Stopping(_) | Mode::Stopped(_));
    Ok(Flight {
        figures: Figures {
            base_disturbance_deg: truth.max_angle().to_degrees(),
            final_attitude_error_deg: truth.angle().to_degrees(),
            position_error_m: e.position_m(),
            orientation_error_deg: e.orientation_deg(),
            f: e.norm(),
        },
        loop_figures: figures,
        fault,
    })
}

/// The plan steps per control cycle and the plan's `dt` (s): the path's times must be
/// uniform and `period` a whole multiple of its step.
pub fn cycle_steps<const N: usize>(
    path: &JointPath<N>,
    period: f64,
) -> Result<(usize, f64), CliError> {
    let n = path.t.len();
    let dt = (path.t[n - 1] - path.t[0]) / (n - 1) as f64;
    let uniform = path
        .t
        .windows(2)
        .all(|w| ((w[1] - w[0]) - dt).abs() <= 1e-9 * dt.max(1.0));
    if !uniform {
        return Err(CliError::input(
            "closed loop: the path's samples are not at a uniform step (a re-timed path?): fly a plan's or a rollout's"
                .to_string(),
        ));
    }
    let per = (period / dt).round();
    if per < 1.0 || (per * dt - period).abs() > 1e-9 * period {
        return Err(CliError::input(format!(
            "closed loop: [sensors] control_period_s = {period} is not a whole multiple of the path's step {dt} s"
        )));
    }
    let per = per as usize;
    if (n - 1) % per != 0 {
        return Err(CliError::input(format!(
            "closed loop: the path's {} steps are not a whole number of control periods ({per} steps each)",
            n - 1
        )));
    }
    Ok((per, dt))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    /// `[closed_loop]` defaults to the core's [`LoopConfig::DEFAULT`] (to the last bit, at
    /// the default 0.1 s period), and a bad value or an unknown key is refused naming the
    /// file and the key.
    /// Verifies RL-SIM-LOOP-002.
    #[test]
    fn the_closed_loop_table_defaults_to_the_core_and_names_bad_values() {
        let s = LoopSection::default();
        let c = s
            .config(0.1, |k| format!("t.toml: [closed_loop] {k}"))
            .unwrap();
        let d = LoopConfig::DEFAULT;
        assert_eq!(c.base_gain, d.base_gain);
        assert_eq!(c.extend_cycles, d.extend_cycles);
        assert!((c.base_limit - d.base_limit).abs() <= 1e-18);
        assert!((c.qdd_max - d.qdd_max).abs() <= 1e-15);
        let bad = |s: LoopSection| {
            s.config(0.1, |k| format!("t.toml: [closed_loop] {k}"))
                .unwrap_err()
                .message
        };
        let m = bad(LoopSection {
            filter_gain: 2.0,
            ..s
        });
        assert!(m.contains("[closed_loop] filter_gain"), "{m}");
        let m = bad(LoopSection {
            base_gain_per_s: -1.0,
            ..s
        });
        assert!(m.contains("[closed_loop] base_gain_per_s"), "{m}");
        let m = bad(LoopSection {
            extend_s: 0.25,
            ..s
        });
        assert!(m.contains("[closed_loop] extend_s = 0.25"), "{m}");
        let e = toml::from_str::<LoopSection>("gain = 1").unwrap_err();
        assert!(e.to_string().contains("unknown field `gain`"), "{e}");
    }
}
