//! Sensors of the truth model (spec §12): what flight software measures of a flight, with
//! the noise, quantisation and dropouts the specification gives each sensor.
//!
//! Owns [`Sensors`], one flight's sensors, built from [`Settings`] (the task file's
//! `[sensors]` table, [`crate::taskfile::SensorsSection`]). Each call measures one quantity
//! of the truth model at one instant and returns `None` when that measurement drops out:
//!
//! - star tracker: `R_meas = exp([n]×) R₀`, `n ~ N(0, σ_st² I₃)` (inertial frame), σ_st from
//!   `star_tracker_arcsec`;
//! - gyro: `ω_meas = ω̄ + b + w` (base frame), `ω̄` the true mean base rate over the sample
//!   period `T_c` (what a rate-integrating gyro delivers), `w` white with standard
//!   deviation `σ_arw/√T_c` per axis (`gyro_arw_deg_rt_h`), `b` one constant per flight
//!   drawn `N(0, σ_b²)` per axis (`gyro_bias_deg_h`);
//! - joint encoders: `q_meas = round(q/r)·r`, `r = 2π/2^bits` (`encoder_bits`), no noise;
//! - wheel momentum (phase 1 of spec §15): `h_meas = h_w + n`, `n ~ N(0, σ_h² I₃)`
//!   (`wheel_momentum_sigma_nms`);
//! - dropout: each measurement is missing with probability `dropout_probability`.
//!
//! Latency (one control period) and the control period belong to the flight that calls
//! these, not to the sensors.
//!
//! **Streams.** Every draw comes from a stream keyed by `(seed, sample, sensor)`
//! ([`crate::dispersion::keyed_stream`] with the keys of [`Kind`], disjoint from the
//! dispersion's), so a flight's measurements depend only on the run's seed and the sample's
//! index, never on `--jobs` or shards. Each sensor's dropouts have a stream of their own,
//! so a dropout probability changes which measurements are missing, not the noise of the
//! others; and a noise-free sensor (σ = 0) still draws, so setting one σ to 0 leaves the
//! other sensors' noise bit for bit.

use crate::dispersion::{keyed_stream, normal};
pub use crate::taskfile::SensorsSection as Settings;
use reactionless::geometry::{Vec3, normalized, quat_exp, quat_mul};
use reactionless::random::Stream;

/// What a stream draws: its key's last input (16 and up: 1–5 are the dispersion's
/// [`crate::dispersion::Kind`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Kind {
    /// Star-tracker noise.
    StarTracker = 16,
    /// Gyro white noise.
    GyroNoise = 17,
    /// The gyro's bias (three draws per flight).
    GyroBias = 18,
    /// Wheel-momentum noise.
    Wheel = 19,
    /// Star-tracker dropouts.
    StarTrackerDropout = 20,
    /// Gyro dropouts.
    GyroDropout = 21,
    /// Encoder dropouts.
    EncoderDropout = 22,
    /// Wheel-momentum dropouts.
    WheelDropout = 23,
}

/// Radians per arcsecond.
pub const RAD_PER_ARCSEC: f64 = core::f64::consts::PI / (180.0 * 3600.0);

/// Three independent normal draws of standard deviation `sigma` (the dispersion's
/// Box–Muller, untruncated).
fn normal3(s: &mut Stream, sigma: f64) -> [f64; 3] {
    let x = normal(s, f64::INFINITY);
    let y = normal(s, f64::INFINITY);
    let z = normal(s, f64::INFINITY);
    [sigma * x, sigma * y, sigma * z]
}

/// One flight's sensors: the settings in SI units and radians, and the streams.
#[derive(Debug, Clone)]
pub struct Sensors {
    /// Star-tracker noise per axis (rad).
    st_sigma: f64,
    /// Gyro white noise per axis over one sample period (rad/s).
    gyro_sigma: f64,
    /// The gyro's bias this flight (rad/s, base frame).
    gyro_bias: [f64; 3],
    /// Encoder resolution (rad).
    resolution: f64,
    /// Wheel-momentum noise per axis (N m s).
    wheel_sigma: f64,
    /// Dropout probability of each measurement.
    dropout: f64,
    st: Stream,
    gyro: Stream,
    wheel: Stream,
    st_drop: Stream,
    gyro_drop: Stream,
    enc_drop: Stream,
    wheel_drop: Stream,
}

impl Sensors {
    /// The sensors of `sample` in the run seeded `seed`; `s` must have passed
    /// [`Settings::validate`].
    pub fn new(s: &Settings, seed: u64, sample: u64) -> Self {
        let key = |k: Kind| keyed_stream(seed, sample, k as u64);
        let deg = core::f64::consts::PI / 180.0;
        // σ_arw in °/√h is σ_arw·(π/180)/60 rad/√s; its mean over T_c has σ_arw/√T_c.
        let arw = s.gyro_arw_deg_rt_h * deg / 60.0;
        let mut bias = key(Kind::GyroBias);
        Self {
            st_sigma: s.star_tracker_arcsec * RAD_PER_ARCSEC,
            gyro_sigma: arw / libm::sqrt(s.control_period_s),
            gyro_bias: normal3(&mut bias, s.gyro_bias_deg_h * deg / 3600.0),
            resolution: 2.0 * core::f64::consts::PI / libm::exp2(f64::from(s.encoder_bits)),
            wheel_sigma: s.wheel_momentum_sigma_nms,
            dropout: s.dropout_probability,
            st: key(Kind::StarTracker),
            gyro: key(Kind::GyroNoise),
            wheel: key(Kind::Wheel),
            st_drop: key(Kind::StarTrackerDropout),
            gyro_drop: key(Kind::GyroDropout),
            enc_drop: key(Kind::EncoderDropout),
            wheel_drop: key(Kind::WheelDropout),
        }
    }

    /// The gyro's bias this flight (rad/s, base frame).
    pub fn gyro_bias(&self) -> [f64; 3] {
        self.gyro_bias
    }

    /// The encoders' resolution (rad).
    pub fn resolution(&self) -> f64 {
        self.resolution
    }

    /// Whether the next measurement of the sensor whose dropouts `s` draws is missing.
    /// Always one draw, so the sequence does not depend on the probability's value.
    fn drops(s: &mut Stream, p: f64) -> bool {
        s.uniform() < p
    }

    /// The star tracker's measurement of the base attitude `attitude_wxyz` (inertial from
    /// base, unit quaternion `[w, x, y, z]`), or `None` when it drops out.
    pub fn star_tracker(&mut self, attitude_wxyz: [f64; 4]) -> Option<[f64; 4]> {
        let n = normal3(&mut self.st, self.st_sigma);
        if Self::drops(&mut self.st_drop, self.dropout) {
            return None;
        }
        let e = quat_exp(&Vec3::new(n[0], n[1], n[2]));
        Some(normalized(quat_mul(e, attitude_wxyz)))
    }

    /// The gyro's measurement of the base rate whose mean over the last sample period is
    /// `mean_rate` (rad/s, base frame), or `None` when it drops out.
    pub fn gyro(&mut self, mean_rate: [f64; 3]) -> Option<[f64; 3]> {
        let w = normal3(&mut self.gyro, self.gyro_sigma);
        if Self::drops(&mut self.gyro_drop, self.dropout) {
            return None;
        }
        Some(core::array::from_fn(|i| {
            mean_rate[i] + self.gyro_bias[i] + w[i]
        }))
    }

    /// The encoders' reading of the joint angles `q` (rad), or `None` when it drops out
    /// (all joints at once: one bus message).
    pub fn encoders<const N: usize>(&mut self, q: &[f64; N]) -> Option<[f64; N]> {
        if Self::drops(&mut self.enc_drop, self.dropout) {
            return None;
        }
        let r = self.resolution;
        Some(q.map(|x| libm::round(x / r) * r))
    }

    /// The wheels' angular momentum `h` as measured (N m s, base frame), or `None` when it
    /// drops out.
    pub fn wheel_momentum(&mut self, h: [f64; 3]) -> Option<[f64; 3]> {
        let n = normal3(&mut self.wheel, self.wheel_sigma);
        if Self::drops(&mut self.wheel_drop, self.dropout) {
            return None;
        }
        Some(core::array::from_fn(|i| h[i] + n[i]))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)] // a test that fails should stop loudly
mod tests {
    use super::*;
    use reactionless::geometry::{quat_angle, quat_log};

    fn conj(q: [f64; 4]) -> [f64; 4] {
        [q[0], -q[1], -q[2], -q[3]]
    }

    /// Sample standard deviation and mean of `x`.
    fn std_mean(x: &[f64]) -> (f64, f64) {
        let n = x.len() as f64;
        let m = x.iter().sum::<f64>() / n;
        let v = x.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
        (v.sqrt(), m)
    }

    const DRAWS: usize = 20_000;

    /// Verifies RL-SIM-SENS-001: each sensor's noise has the standard deviation spec §12 gives it
    /// (within 3 % over 20,000 draws: the sampling error of a σ estimate is 0.5 %).
    #[test]
    fn noise_has_the_specified_standard_deviation() {
        let s = Settings::default();
        let mut sensors = Sensors::new(&s, 7, 3);
        let att = normalized([0.9, 0.1, -0.3, 0.2]);
        let (mut st, mut gy, mut wh) = (Vec::new(), Vec::new(), Vec::new());
        for _ in 0..DRAWS {
            let m = sensors.star_tracker(att).unwrap();
            // exp([n]×) = R_meas R₀ᵀ: the inertial-frame error.
            st.extend(quat_log(quat_mul(m, conj(att))).iter().copied());
            let g = sensors.gyro([0.01, -0.02, 0.0]).unwrap();
            gy.push(g[0] - 0.01 - sensors.gyro_bias()[0]);
            let h = sensors.wheel_momentum([1.0, 2.0, 3.0]).unwrap();
            wh.push(h[2] - 3.0);
        }
        let check = |x: &[f64], want: f64, what: &str| {
            let (sd, m) = std_mean(x);
            assert!(
                (sd / want - 1.0).abs() < 0.03,
                "{what}: σ {sd} against {want}"
            );
            assert!(
                m.abs() < 4.0 * want / (x.len() as f64).sqrt(),
                "{what}: mean {m}"
            );
        };
        check(&st, 5.0 * RAD_PER_ARCSEC, "star tracker");
        let deg = core::f64::consts::PI / 180.0;
        check(&gy, 0.01 * deg / 60.0 / 0.1f64.sqrt(), "gyro");
        check(&wh, 2e-4, "wheel momentum");
    }

    /// Verifies RL-SIM-SENS-001: the gyro bias is one constant per flight, drawn per flight.
    #[test]
    fn gyro_bias_is_constant_per_flight_with_its_sigma() {
        let s = Settings {
            gyro_arw_deg_rt_h: 0.0,
            ..Settings::default()
        };
        let mut one = Sensors::new(&s, 1, 0);
        let b = one.gyro_bias();
        for _ in 0..10 {
            assert_eq!(one.gyro([0.0; 3]), Some(b));
        }
        let biases: Vec<f64> = (0..DRAWS as u64)
            .map(|k| Sensors::new(&s, 1, k).gyro_bias()[1])
            .collect();
        let deg = core::f64::consts::PI / 180.0;
        let (sd, _) = std_mean(&biases);
        assert!(
            (sd / (0.05 * deg / 3600.0) - 1.0).abs() < 0.03,
            "bias σ {sd}"
        );
    }

    /// Verifies RL-SIM-SENS-001: encoders quantise to 2π/2^bits, within half a count.
    #[test]
    fn encoders_quantise_to_their_resolution() {
        let s = Settings {
            encoder_bits: 12,
            ..Settings::default()
        };
        let mut sensors = Sensors::new(&s, 1, 0);
        let r = 2.0 * core::f64::consts::PI / 4096.0;
        assert_eq!(sensors.resolution(), r);
        let q = [0.1234, -2.5, 3.0, 0.0, 1e-9, -1e-3, 0.7];
        let m = sensors.encoders(&q).unwrap();
        for (a, b) in q.iter().zip(&m) {
            assert!((a - b).abs() <= r / 2.0);
            assert_eq!((b / r).round() * r, *b);
        }
    }

    /// Verifies RL-SIM-SENS-002: a flight's measurements depend only on (seed, sample); the
    /// dropout probability changes which are missing, not the others' noise; the star
    /// tracker's error never exceeds what its σ allows at 6σ.
    #[test]
    fn draws_depend_on_seed_and_sample_only_and_dropouts_leave_the_noise() {
        let s = Settings::default();
        let att = normalized([1.0, 0.0, 0.0, 0.0]);
        let run = |s: &Settings, seed, sample| {
            let mut x = Sensors::new(s, seed, sample);
            (0..200)
                .map(|_| (x.star_tracker(att), x.gyro([0.0; 3]), x.encoders(&[0.3; 7])))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(&s, 5, 9), run(&s, 5, 9));
        assert_ne!(run(&s, 5, 9), run(&s, 5, 10));
        assert_ne!(run(&s, 5, 9), run(&s, 6, 9));
        let dropping = Settings {
            dropout_probability: 0.3,
            ..s
        };
        let (a, b) = (run(&s, 5, 9), run(&dropping, 5, 9));
        let mut missing = 0;
        for (x, y) in a.iter().zip(&b) {
            match y.0 {
                Some(m) => assert_eq!(Some(m), x.0),
                None => missing += 1,
            }
            if let Some(g) = y.1 {
                assert_eq!(Some(g), x.1);
            }
            for m in x.0.iter() {
                assert!(
                    quat_angle(quat_mul(*m, conj(att))) < 6.0 * 3f64.sqrt() * 5.0 * RAD_PER_ARCSEC
                );
            }
        }
        // 200 draws at p = 0.3: 60 expected, σ ≈ 6.5.
        assert!(
            (35..=85).contains(&missing),
            "{missing} star-tracker dropouts of 200"
        );
    }

    /// Verifies RL-SIM-SENS-003: a task file's `[sensors]` table is read with its defaults,
    /// and a bad or unknown value is refused naming the file and the key.
    #[test]
    fn the_sensors_table_is_read_and_bad_values_are_named() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let task = root.join("spec/tasks/paper.toml");
        let text = std::fs::read_to_string(&task).unwrap();
        let urdf = std::fs::read_to_string(root.join("spec/chaser7.urdf")).unwrap();
        let lt = crate::taskfile::from_texts(&task, &text, &urdf).unwrap();
        assert_eq!(lt.file.sensors, Settings::default());
        let with = |table: &str| {
            crate::taskfile::from_texts(&task, &format!("{text}\n[sensors]\n{table}\n"), &urdf)
        };
        let lt = with("star_tracker_arcsec = 50.0\nencoder_bits = 16").unwrap();
        assert_eq!(lt.file.sensors.star_tracker_arcsec, 50.0);
        assert_eq!(lt.file.sensors.encoder_bits, 16);
        for (table, key) in [
            ("star_tracker_arcsec = -1.0", "star_tracker_arcsec"),
            ("gyro_arw_deg_rt_h = nan", "gyro_arw_deg_rt_h"),
            ("control_period_s = 0.0", "control_period_s"),
            ("dropout_probability = 1.0", "dropout_probability"),
            ("latency_cycles = 11", "latency_cycles"),
            ("encoder_bits = 0", "encoder_bits"),
            ("gyro_noise = 1.0", "gyro_noise"),
        ] {
            let e = with(table).err().unwrap().to_string();
            assert!(e.contains(key) && e.contains("paper.toml"), "{table}: {e}");
        }
    }
}
