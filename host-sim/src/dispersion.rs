//! Dispersed truth models: what a planned joint path does to a spacecraft whose mass
//! properties, joint axes and initial base rate differ from the nominal model.
//!
//! Reads its settings as [`Settings`] (the task file's `[dispersion]` table, whose keys
//! `taskfile::DispersionSection::KEYS` declares once for the task file, `disperse`'s flags
//! and the reports). Owns the draws of one sample ([`Draw`], from random streams derived
//! from `(seed, sample, kind)` only, so a sample is the same on any thread and in any
//! shard), their application to a URDF chain ([`Draw::apply`]), the flight of a joint path
//! through the dispersed truth model ([`fly`]) and the one-at-a-time sensitivity
//! ([`sensitivity`]).
//!
//! The dispersed quantities (σ = 0 leaves a quantity exactly nominal, bit for bit):
//!
//! - mass of every body `m·(1 + σ_m z)` (kg);
//! - CoM of every body `c + σ_c z` per axis of its link frame (the URDF `<inertial>`
//!   origin, m);
//! - inertia tensor of every body (kg m², inertial frame), through the second moments of
//!   its mass distribution `Σ = ½tr(I)·1 − I` (so that a slender link's nearly tight
//!   triangle inequality cannot be broken): `Σ_ii·(1 + σ_I z)` on the diagonal,
//!   `Σ_ij + σ_I z √(Σ_ii Σ_jj)` off it, then `I = tr(Σ)·1 − Σ`; redrawn (bounded) until
//!   `I` is positive definite and meets the triangle inequality `I_ii ≤ I_jj + I_kk`;
//! - joint axes: two perpendicular tilts of `σ_a z` (rad), then normalised;
//! - the initial base rate `ω(0) = σ_ω z` per base axis (rad/s), i.e. the angular momentum
//!   `L = H~b(q₀) ω(0)` that the truth model carries (spec §11).
//!
//! Every `z` is a standard normal (Box–Muller, libm), truncated to `|z| ≤
//! truncation_sigmas` by redrawing. Bodies are drawn base first, then link 1..N; joints
//! 1..N. Stream keys: `splitmix(splitmix(splitmix(seed) ^ sample) ^ kind)` with the kinds
//! [`Kind`]; each key seeds a [`reactionless::random::Stream`].

use crate::error::CliError;
use crate::retiming;
pub use crate::taskfile::DispersionSection as Settings;
use crate::taskfile::LoadedTask;
use crate::urdf::Chain;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::random::Stream;
use reactionless::{BodyDesc, Frames, Inertia, Momentum, Pose, Task, TruthModel, TruthState};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// Redraws allowed for one truncated normal or one physical inertia before giving up.
pub const MAX_REDRAWS: u32 = 1000;

/// What a stream draws (its key's last input).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u64)]
pub enum Kind {
    /// Masses.
    Mass = 1,
    /// CoM offsets.
    Com = 2,
    /// Inertia tensors.
    Inertia = 3,
    /// Joint axes.
    Axis = 4,
    /// The initial base rate.
    Rate = 5,
}

/// SplitMix64's finaliser (Steele, Lea, Flood 2014).
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The stream of `kind` for `sample` of the run seeded `seed`.
pub fn stream(seed: u64, sample: u64, kind: Kind) -> Stream {
    keyed_stream(seed, sample, kind as u64)
}

/// The stream keyed `(seed, sample, key)`: [`Kind`]'s keys here, the sensors' keys
/// (`crate::sensors::Kind`, 16 and up) for a flight's measurements.
pub fn keyed_stream(seed: u64, sample: u64, key: u64) -> Stream {
    Stream::new(splitmix(splitmix(splitmix(seed) ^ sample) ^ key))
}

/// A standard normal truncated to `|z| ≤ c`: Box–Muller (the cosine branch) with libm,
/// redrawn beyond `c`; after [`MAX_REDRAWS`] (never seen for `c ≥ 1`) it is clamped.
/// `c = ∞` gives an untruncated normal from exactly two draws (the sensors' noise).
pub(crate) fn normal(s: &mut Stream, c: f64) -> f64 {
    let mut z = 0.0;
    for _ in 0..MAX_REDRAWS {
        let u1 = 1.0 - s.uniform(); // (0, 1]
        let u2 = s.uniform();
        z = libm::sqrt(-2.0 * libm::log(u1)) * libm::cos(2.0 * core::f64::consts::PI * u2);
        if z.abs() <= c {
            return z;
        }
    }
    if z > c {
        c
    } else if z < -c {
        -c
    } else {
        z
    }
}

/// One sample's dispersed parameters (SI units, radians inside).
#[derive(Debug, Clone, PartialEq)]
pub struct Draw {
    /// Masses, base then links (kg).
    pub mass: Vec<f64>,
    /// CoM positions (the `<inertial>` origins) in each body's link frame (m).
    pub com: Vec<[f64; 3]>,
    /// Inertia tensors (kg m²).
    pub inertia: Vec<Inertia>,
    /// Joint axes (unit vectors).
    pub axis: Vec<[f64; 3]>,
    /// Initial base rate, base frame (rad/s).
    pub base_rate: [f64; 3],
}

fn bodies(chain: &Chain) -> impl Iterator<Item = &BodyDesc> {
    std::iter::once(&chain.base).chain(chain.links.iter())
}

fn is_physical(i: &Inertia) -> bool {
    let m = [
        [i.ixx, i.ixy, i.ixz],
        [i.ixy, i.iyy, i.iyz],
        [i.ixz, i.iyz, i.izz],
    ];
    let det2 = m[0][0] * m[1][1] - m[0][1] * m[0][1];
    let det3 = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[1][2])
        - m[0][1] * (m[0][1] * m[2][2] - m[1][2] * m[0][2])
        + m[0][2] * (m[0][1] * m[1][2] - m[1][1] * m[0][2]);
    if !(m[0][0] > 0.0 && det2 > 0.0 && det3 > 0.0) {
        return false;
    }
    // Triangle inequality of the principal moments ⇔ ½tr(I)·1 − I is positive
    // semi-definite (its eigenvalues are (I_j + I_k − I_i)/2).
    let h = 0.5 * (i.ixx + i.iyy + i.izz);
    let t = [
        [h - i.ixx, -i.ixy, -i.ixz],
        [-i.ixy, h - i.iyy, -i.iyz],
        [-i.ixz, -i.iyz, h - i.izz],
    ];
    // Every principal minor ≥ 0 (with a relative slack for rounding of flat bodies).
    let eps = -1e-12 * h * h * h;
    let d1 = [t[0][0], t[1][1], t[2][2]];
    let d2 = [
        t[0][0] * t[1][1] - t[0][1] * t[0][1],
        t[0][0] * t[2][2] - t[0][2] * t[0][2],
        t[1][1] * t[2][2] - t[1][2] * t[1][2],
    ];
    let d3 = t[0][0] * (t[1][1] * t[2][2] - t[1][2] * t[1][2])
        - t[0][1] * (t[0][1] * t[2][2] - t[1][2] * t[0][2])
        + t[0][2] * (t[0][1] * t[1][2] - t[1][1] * t[0][2]);
    d1.iter().all(|&d| d >= -1e-12 * h) && d2.iter().all(|&d| d >= -1e-12 * h * h) && d3 >= eps
}

/// The nominal value's tilt: `a + σ(z₁ e₁ + z₂ e₂)` normalised, `e₁ ⟂ e₂ ⟂ a`.
fn tilt(a: [f64; 3], z1: f64, z2: f64, sigma_rad: f64) -> [f64; 3] {
    // e1: a × (the coordinate axis least aligned with a).
    let k = if a[0].abs() <= a[1].abs() && a[0].abs() <= a[2].abs() {
        [1.0, 0.0, 0.0]
    } else if a[1].abs() <= a[2].abs() {
        [0.0, 1.0, 0.0]
    } else {
        [0.0, 0.0, 1.0]
    };
    let cross = |u: [f64; 3], v: [f64; 3]| {
        [
            u[1] * v[2] - u[2] * v[1],
            u[2] * v[0] - u[0] * v[2],
            u[0] * v[1] - u[1] * v[0],
        ]
    };
    let unit = |v: [f64; 3]| {
        let n = libm::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
        [v[0] / n, v[1] / n, v[2] / n]
    };
    let e1 = unit(cross(a, k));
    let e2 = unit(cross(a, e1));
    let (d1, d2) = (sigma_rad * z1, sigma_rad * z2);
    unit([
        a[0] + d1 * e1[0] + d2 * e2[0],
        a[1] + d1 * e1[1] + d2 * e2[1],
        a[2] + d1 * e1[2] + d2 * e2[2],
    ])
}

impl Draw {
    /// The truth model's state at the start of a flight of `task` (the dispersed robot):
    /// at rest, or with the angular momentum of the drawn initial base rate,
    /// `L = H~b(q₀) ω(0)` (spec §11).
    pub fn truth_state<const N: usize, const K: usize>(&self, task: &Task<N, K>) -> TruthState<N> {
        let state = TruthState::<N>::new(TRUTH_SUBSTEPS);
        if self.base_rate == [0.0; 3] {
            return state;
        }
        state.with_momentum(self.initial_momentum(task))
    }

    /// The angular momentum (kg m²/s) of the drawn initial base rate on `task` (the
    /// dispersed robot), `L = H~b(q₀) ω(0)`: zero without a base rate.
    pub fn initial_momentum<const N: usize, const K: usize>(&self, task: &Task<N, K>) -> [f64; 3] {
        if self.base_rate == [0.0; 3] {
            return [0.0; 3];
        }
        let hb = Momentum::new(task.robot(), &Frames::new(task.robot(), task.start())).hb;
        let w = self.base_rate;
        let l = hb.mul_vec(&nalgebra::Vector3::new(w[0], w[1], w[2]));
        [l.x, l.y, l.z]
    }

    /// The nominal parameters of `chain` (every σ = 0).
    pub fn nominal(chain: &Chain) -> Self {
        Self {
            mass: bodies(chain).map(|b| b.mass).collect(),
            com: bodies(chain).map(|b| b.inertial.xyz).collect(),
            inertia: bodies(chain).map(|b| b.inertia).collect(),
            axis: chain.joints.iter().map(|j| j.axis).collect(),
            base_rate: [0.0; 3],
        }
    }

    /// Sample `sample` of the run seeded `seed` (0-based). Errors when no physical inertia
    /// can be drawn (σ too large for a body).
    pub fn sample(chain: &Chain, s: &Settings, seed: u64, sample: u64) -> Result<Self, CliError> {
        let mut d = Self::nominal(chain);
        let c = s.truncation_sigmas;
        if s.mass_rel_sigma > 0.0 {
            let mut st = stream(seed, sample, Kind::Mass);
            for m in &mut d.mass {
                *m *= 1.0 + s.mass_rel_sigma * normal(&mut st, c);
            }
        }
        if s.com_sigma_m > 0.0 {
            let mut st = stream(seed, sample, Kind::Com);
            for com in &mut d.com {
                for v in com.iter_mut() {
                    *v += s.com_sigma_m * normal(&mut st, c);
                }
            }
        }
        if s.inertia_rel_sigma > 0.0 {
            let mut st = stream(seed, sample, Kind::Inertia);
            for (b, i) in d.inertia.iter_mut().enumerate() {
                let sg = s.inertia_rel_sigma;
                // The second moments of the mass distribution, Σ = ½tr(I)·1 − I: any
                // positive definite Σ gives an inertia I = tr(Σ)·1 − Σ that is positive
                // definite and meets the triangle inequality, so Σ is what is dispersed.
                let h = 0.5 * (i.ixx + i.iyy + i.izz);
                let n = [h - i.ixx, h - i.iyy, h - i.izz, -i.ixy, -i.ixz, -i.iyz];
                let mut done = false;
                for _ in 0..MAX_REDRAWS {
                    let z: [f64; 6] = core::array::from_fn(|_| normal(&mut st, c));
                    let sxx = n[0] * (1.0 + sg * z[0]);
                    let syy = n[1] * (1.0 + sg * z[1]);
                    let szz = n[2] * (1.0 + sg * z[2]);
                    let sxy = n[3] + sg * z[3] * libm::sqrt(n[0] * n[1]);
                    let sxz = n[4] + sg * z[4] * libm::sqrt(n[0] * n[2]);
                    let syz = n[5] + sg * z[5] * libm::sqrt(n[1] * n[2]);
                    let cand = Inertia {
                        ixx: syy + szz,
                        iyy: sxx + szz,
                        izz: sxx + syy,
                        ixy: -sxy,
                        ixz: -sxz,
                        iyz: -syz,
                    };
                    if is_physical(&cand) {
                        *i = cand;
                        done = true;
                        break;
                    }
                }
                if !done {
                    return Err(CliError::input(format!(
                        "sample {sample}: no physical inertia for {} in {MAX_REDRAWS} draws: inertia_rel_sigma = {sg} is too large",
                        body_label(chain, b)
                    )));
                }
            }
        }
        if s.axis_sigma_deg > 0.0 {
            let mut st = stream(seed, sample, Kind::Axis);
            let sigma = s.axis_sigma_deg.to_radians();
            for a in &mut d.axis {
                let (z1, z2) = (normal(&mut st, c), normal(&mut st, c));
                *a = tilt(*a, z1, z2, sigma);
            }
        }
        if s.base_rate_sigma_deg_s > 0.0 {
            let mut st = stream(seed, sample, Kind::Rate);
            let sigma = s.base_rate_sigma_deg_s.to_radians();
            for w in &mut d.base_rate {
                *w = sigma * normal(&mut st, c);
            }
        }
        Ok(d)
    }

    /// `chain` with these parameters.
    pub fn apply(&self, chain: &Chain) -> Chain {
        let mut out = chain.clone();
        let set = |b: &mut BodyDesc, i: usize| {
            b.mass = self.mass[i];
            b.inertial.xyz = self.com[i];
            b.inertia = self.inertia[i];
        };
        set(&mut out.base, 0);
        for (k, l) in out.links.iter_mut().enumerate() {
            set(l, k + 1);
        }
        for (j, a) in out.joints.iter_mut().zip(&self.axis) {
            j.axis = *a;
        }
        out
    }
}

/// Body `b` (0 = base) for messages and column names.
pub fn body_label(chain: &Chain, b: usize) -> String {
    match b {
        0 => chain.base_link.clone(),
        b => chain
            .link_names
            .get(b - 1)
            .cloned()
            .unwrap_or_else(|| format!("link{b}")),
    }
}

/// The joint path of an output directory: times (s) and configurations (rad).
#[derive(Debug, Clone, PartialEq)]
pub struct JointPath<const N: usize> {
    /// Times (s).
    pub t: Vec<f64>,
    /// Configurations (rad), one per time.
    pub q: Vec<[f64; N]>,
    /// The start (rad) of an attitude-controlled phase 1 flown before this path (phase 2
    /// of a two-phase plan, which starts where phase 1 ended): the base then starts this
    /// path where phase 1 moved it on the flown robot, not where it moved the nominal one,
    /// and [`fly`]'s end pose includes the difference. `None` for a single-phase path.
    pub preshaped_from: Option<[f64; N]>,
}

impl<const N: usize> JointPath<N> {
    /// Reads `dir`'s `trajectory.csv` text, a plan's or a re-timed bundle's
    /// ([`crate::retiming::read_samples`]); only `t` and `q` are used. The path must have
    /// two samples or more, finite, at increasing times. Errors name the file, the row and
    /// what was wrong.
    pub fn parse(dir: &Path, csv: &str) -> Result<Self, CliError> {
        let (t, q): (Vec<f64>, Vec<[f64; N]>) = retiming::read_samples::<N>(dir, csv)?
            .iter()
            .map(|s| (s.t, s.q))
            .unzip();
        let err = |m: String| CliError::input(format!("{}: trajectory.csv: {m}", dir.display()));
        for (row, (tk, qk)) in t.iter().zip(&q).enumerate() {
            if !tk.is_finite() || qk.iter().any(|v| !v.is_finite()) {
                return Err(err(format!("row {}: a value is not finite", row + 1)));
            }
            if row > 0 && *tk <= t[row - 1] {
                return Err(err(format!("row {}: time does not increase", row + 1)));
            }
        }
        if t.len() < 2 {
            return Err(err("fewer than two samples".into()));
        }
        Ok(Self {
            t,
            q,
            preshaped_from: None,
        })
    }
}

/// What one flight through a (dispersed) truth model gives.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Figures {
    /// Largest base rotation over the motion (deg).
    pub base_disturbance_deg: f64,
    /// Base rotation at the end of the motion (deg).
    pub final_attitude_error_deg: f64,
    /// End-effector position error against the target (m).
    pub position_error_m: f64,
    /// End-effector orientation error against the target (deg).
    pub orientation_error_deg: f64,
    /// f = ‖e‖ of the end pose against the target.
    pub f: f64,
}

/// Flies `path` open-loop through the truth model of `lt` with `draw` applied: the base
/// starts at rest with the identity attitude unless the draw has a base rate. After a
/// phase 1 ([`JointPath::preshaped_from`]) the attitude control held the base attitude
/// and the CoM stayed put, so the base starts displaced by the difference between the
/// dispersed and the nominal robot's shift `c(q₀) − c(q_s)` (system CoM in the base frame),
/// and the end pose is moved by it.
pub fn fly<const N: usize, const K: usize>(
    lt: &LoadedTask,
    path: &JointPath<N>,
    draw: &Draw,
) -> Result<(Figures, Pose), CliError> {
    let mut dispersed = lt.clone();
    dispersed.chain = draw.apply(&lt.chain);
    let task: Task<N, K> = dispersed.task::<N, K>()?;
    let mut truth = TruthModel::from_state(&task, draw.truth_state(&task));
    for (t, q) in path.t.iter().zip(&path.q) {
        truth.push(q, *t);
    }
    if let Some(e) = truth.error() {
        return Err(CliError::failed(format!("truth model failed: {e}")));
    }
    let mut end = truth
        .end_pose()
        .ok_or_else(|| CliError::internal("truth model saw no samples"))?;
    if let Some(q0) = &path.preshaped_from {
        let nominal: Task<N, K> = lt.task::<N, K>()?;
        let shift = |t: &Task<N, K>| {
            let (c0, cs) = (
                Frames::new(t.robot(), q0).com,
                Frames::new(t.robot(), t.start()).com,
            );
            c0 - cs
        };
        let d = shift(&task) - shift(&nominal);
        for (p, dv) in end.position.iter_mut().zip(d.iter()) {
            *p += dv;
        }
    }
    let e = end.error_to(task.target());
    Ok((
        Figures {
            base_disturbance_deg: truth.max_angle().to_degrees(),
            final_attitude_error_deg: truth.angle().to_degrees(),
            position_error_m: e.position_m(),
            orientation_error_deg: e.orientation_deg(),
            f: e.norm(),
        },
        end,
    ))
}

/// One row of the sensitivity table: one parameter moved by +1σ from nominal.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Sensitivity {
    /// What moved, e.g. `link3 mass` or `joint2 axis tilt 1`.
    pub parameter: String,
    /// By how much, with its unit, e.g. `+5% (1.2 kg)`.
    pub step: String,
    /// Change of the base disturbance (deg).
    pub d_base_disturbance_deg: f64,
    /// Change of the end-effector position error (m).
    pub d_position_error_m: f64,
    /// Change of the end-effector orientation error (deg).
    pub d_orientation_error_deg: f64,
}

/// One-at-a-time sensitivity: every dispersed parameter (σ > 0) moved by +1σ alone,
/// flown, and differenced against the nominal flight `nominal`. Inertia moves as a
/// whole-tensor scale `(1 + σ_I)` (always physical); axes tilt about each perpendicular.
pub fn sensitivity<const N: usize, const K: usize>(
    lt: &LoadedTask,
    path: &JointPath<N>,
    s: &Settings,
    nominal: &Figures,
) -> Result<Vec<Sensitivity>, CliError> {
    let base = Draw::nominal(&lt.chain);
    let mut moves: Vec<(String, String, Draw)> = Vec::new();
    let nb = base.mass.len();
    for b in 0..nb {
        let name = body_label(&lt.chain, b);
        if s.mass_rel_sigma > 0.0 {
            let mut d = base.clone();
            d.mass[b] *= 1.0 + s.mass_rel_sigma;
            moves.push((
                format!("{name} mass"),
                format!(
                    "+{}% ({:.4} kg)",
                    100.0 * s.mass_rel_sigma,
                    base.mass[b] * s.mass_rel_sigma
                ),
                d,
            ));
        }
        if s.com_sigma_m > 0.0 {
            for (a, axis) in ["x", "y", "z"].iter().enumerate() {
                let mut d = base.clone();
                d.com[b][a] += s.com_sigma_m;
                moves.push((
                    format!("{name} CoM {axis}"),
                    format!("+{} m", s.com_sigma_m),
                    d,
                ));
            }
        }
        if s.inertia_rel_sigma > 0.0 {
            let mut d = base.clone();
            let k = 1.0 + s.inertia_rel_sigma;
            let i = &mut d.inertia[b];
            for v in [
                &mut i.ixx, &mut i.ixy, &mut i.ixz, &mut i.iyy, &mut i.iyz, &mut i.izz,
            ] {
                *v *= k;
            }
            moves.push((
                format!("{name} inertia"),
                format!("+{}% (whole tensor)", 100.0 * s.inertia_rel_sigma),
                d,
            ));
        }
    }
    if s.axis_sigma_deg > 0.0 {
        for (j, jn) in lt.chain.joint_names.iter().enumerate() {
            for (k, (z1, z2)) in [(1.0, 0.0), (0.0, 1.0)].into_iter().enumerate() {
                let mut d = base.clone();
                d.axis[j] = tilt(base.axis[j], z1, z2, s.axis_sigma_deg.to_radians());
                moves.push((
                    format!("{jn} axis tilt {}", k + 1),
                    format!("{} deg", s.axis_sigma_deg),
                    d,
                ));
            }
        }
    }
    if s.base_rate_sigma_deg_s > 0.0 {
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let mut d = base.clone();
            d.base_rate[a] = s.base_rate_sigma_deg_s.to_radians();
            moves.push((
                format!("base rate {axis}"),
                format!("+{} deg/s", s.base_rate_sigma_deg_s),
                d,
            ));
        }
    }
    moves
        .into_iter()
        .map(|(parameter, step, d)| {
            let (f, _) = fly::<N, K>(lt, path, &d)?;
            Ok(Sensitivity {
                parameter,
                step,
                d_base_disturbance_deg: f.base_disturbance_deg - nominal.base_disturbance_deg,
                d_position_error_m: f.position_error_m - nominal.position_error_m,
                d_orientation_error_deg: f.orientation_error_deg - nominal.orientation_error_deg,
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drawn normal stays within the truncation, and the streams of different samples
    /// and kinds differ while the same key repeats exactly.
    /// Verifies RL-SIM-DISP-002.
    #[test]
    fn streams_are_keyed_and_normals_truncated() {
        let mut a = stream(7, 3, Kind::Mass);
        let mut b = stream(7, 3, Kind::Mass);
        assert_eq!(a.next_u64(), b.next_u64());
        assert_ne!(
            stream(7, 3, Kind::Com).next_u64(),
            stream(7, 4, Kind::Com).next_u64()
        );
        assert_ne!(
            stream(7, 3, Kind::Com).next_u64(),
            stream(7, 3, Kind::Mass).next_u64()
        );
        let mut s = stream(1, 0, Kind::Rate);
        let z: Vec<f64> = (0..20_000).map(|_| normal(&mut s, 2.0)).collect();
        assert!(z.iter().all(|v| v.abs() <= 2.0));
        let mean = z.iter().sum::<f64>() / z.len() as f64;
        let var = z.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / z.len() as f64;
        // A standard normal truncated at ±2: mean 0, variance 0.774.
        assert!(mean.abs() < 0.02, "{mean}");
        assert!((var - 0.774).abs() < 0.02, "{var}");
    }

    /// The physical-inertia test: a cube passes, a non-PD tensor and one that breaks the
    /// triangle inequality fail.
    /// Verifies RL-SIM-DISP-002.
    #[test]
    fn inertia_must_be_positive_definite_and_satisfy_the_triangle_inequality() {
        assert!(is_physical(&Inertia::diagonal(1.0, 1.0, 1.0)));
        assert!(is_physical(&Inertia::diagonal(1.0, 1.0, 2.0)));
        assert!(!is_physical(&Inertia::diagonal(1.0, 1.0, 2.1)));
        let mut i = Inertia::diagonal(1.0, 1.0, 1.0);
        i.ixy = 1.0;
        assert!(!is_physical(&i));
    }

    /// A tilt keeps the axis a unit vector and turns it by about σ for z = 1.
    /// Verifies RL-SIM-DISP-002.
    #[test]
    fn a_tilt_turns_the_axis_by_sigma() {
        let a = [0.0, 0.0, 1.0];
        let t = tilt(a, 1.0, 0.0, 0.01);
        let n = (t[0] * t[0] + t[1] * t[1] + t[2] * t[2]).sqrt();
        assert!((n - 1.0).abs() < 1e-15);
        let angle = t[2].acos();
        assert!((angle - 0.01).abs() < 1e-6, "{angle}");
    }
}
