//! Clearance of a joint path (spec §13): the robot's collision geometry and the task's
//! keep-outs, the pairs that are checked, and the smallest signed distance of each pair
//! over the continuous path.
//!
//! Owns [`Scene`] (built once from a task: bodies, keep-outs, the pair list, the required
//! clearance, the per-joint reach bounds) and [`Sweep`] (what a path's clearance is, pair
//! by pair). The signed distance of two primitives is the core's
//! ([`reactionless::collision::signed_distance`]); the kinematics here are this module's
//! own URDF chain, so `check` does not lean on the planner's forward kinematics.
//!
//! **Where the bodies are.** Body `i`'s frame is the URDF frame of its link: `T_i = T_{i−1}
//! · origin_i · Rot(axis_i, q_i)`, `T_0` the base. The base keeps the planner model's
//! identity attitude and moves by centre-of-mass conservation, `p₀(q) = r_g(q₀) − r_g(q)`
//! (spec §1); keep-outs are fixed in the inertial frame (the base frame at `t = 0`). The
//! truth model's base rotation (7e-4° on the reference plan) is not applied.
//!
//! **The pairs** (spec §13): every two links with no joint between them (`|i − j| ≥ 2`),
//! each link but the first against the base, and every body against every keep-out, less
//! `[collision] ignore`; a pair exists only if both sides carry geometry.
//!
//! **No tunnelling.** The path is piecewise linear in `q` between the written samples.
//! Along an interval, a point of body `i` moves at most `δ_i = Σ_{j ≤ i} |Δq_j|·ρ_j +
//! |Δp₀|`, where `ρ_j` bounds the distance from joint `j` to any point of the bodies it
//! carries (link lengths plus the largest primitive extent) and `|Δp₀| ≤ Σ_j |Δq_j|·ρ_j
//! m_{≥j}/M`. A signed distance is 1-Lipschitz in such a displacement, so on an interval
//! whose ends give `d₀`, `d₁` and whose pair moves by `δ = δ_a + δ_b`, `d ≥ (d₀ + d₁ −
//! δ)/2`. An interval whose bound is not above the pair's smallest value found so far
//! (less [`RESOLUTION_M`]) is bisected, until its `δ` is below the resolution. So the
//! reported minimum is a value the path attains, and the path's true minimum is at most
//! [`RESOLUTION_M`] below it: `check` passes a pair only if `min − RESOLUTION_M ≥` the
//! required clearance.

use crate::error::CliError;
use crate::urdf::Chain;
use reactionless::Robot;
use reactionless::clearance::{CollisionSet, Side as CoreSide};
use reactionless::collision::{Placed, Shape, signed_distance};
use reactionless::geometry::{Mat3, Vec3, rpy_matrix};
use serde::Deserialize;
use std::collections::BTreeSet;

/// The path's clearance is resolved to this (m): the reported minimum of a pair is attained
/// by the path, and no point of the path is closer by more than this.
pub const RESOLUTION_M: f64 = 1e-6;

/// Most collision primitives on one robot (base and links): the core's capacity.
pub const MAX_PRIMITIVES: usize = reactionless::clearance::MAX_PRIMITIVES;
/// Most keep-outs in one task: the core's capacity.
pub const MAX_KEEP_OUTS: usize = reactionless::clearance::MAX_KEEP_OUTS;

/// Most bisections of one sample interval for one pair: a bound on the work (`2^20`
/// evaluations would be reached only by a pair that keeps its smallest distance, to within
/// the resolution, over a whole interval of more than a metre's motion).
const MAX_SPLITS: u32 = 1 << 20;

/// A primitive on a body or in the scene: the shape and its frame (in the body's frame, or
/// the inertial frame for a keep-out).
#[derive(Debug, Clone)]
pub struct Part {
    /// Name for reports.
    pub name: String,
    /// The primitive.
    pub shape: Shape,
    /// Attitude of its frame.
    pub rot: Mat3,
    /// Origin of its frame (m).
    pub pos: Vec3,
}

/// One side of a pair.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Side {
    /// Body `i`: 0 the base, `1..=N` the links.
    Body(usize),
    /// Keep-out `k` of the task.
    KeepOut(usize),
}

/// One `[[keep_out]]`: a box, sphere or capsule fixed in the inertial frame (the base
/// frame at `t = 0`).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeepOutSection {
    /// Name in reports and in `[collision] ignore`, unique among links and keep-outs.
    pub name: String,
    /// `"box"`, `"sphere"` or `"capsule"`.
    pub shape: String,
    /// Centre (m), inertial frame.
    pub position_m: Vec<f64>,
    /// Attitude as URDF roll, pitch, yaw (deg); default none. A capsule's segment lies
    /// along its `z` axis.
    pub rpy_deg: Option<Vec<f64>>,
    /// A box's half extents (m), each ≥ 0.
    pub half_extents_m: Option<Vec<f64>>,
    /// A sphere's or capsule's radius (m), ≥ 0.
    pub radius_m: Option<f64>,
    /// A capsule's segment length (m), ≥ 0 (the whole capsule is `length_m + 2·radius_m`).
    pub length_m: Option<f64>,
}

/// `[collision]`: what clearance a path must keep (spec §13).
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct CollisionSection {
    /// Required clearance (m), ≥ 0; default 0 (touching is allowed, overlap is not).
    pub clearance_m: f64,
    /// Pairs not checked, by link or keep-out name: `[["link2", "link5"], ["base", "probe"]]`.
    pub ignore: Vec<[String; 2]>,
    /// How far above `clearance_m` the planner aims (m), ≥ 0; default
    /// [`DEFAULT_MARGIN_M`]. The planner evaluates pairs only when they come within this of
    /// the required clearance.
    pub margin_m: Option<f64>,
}

/// `[collision] margin_m` when not given (m).
pub const DEFAULT_MARGIN_M: f64 = 0.005;

/// The robot's geometry and the task's keep-outs, fixed at load time.
#[derive(Debug, Clone)]
pub struct Scene {
    /// Body names (the base link, then the links).
    pub body_names: Vec<String>,
    /// Primitives of each body, in its frame.
    pub bodies: Vec<Vec<Part>>,
    /// Keep-outs, in the inertial frame.
    pub keep_outs: Vec<Part>,
    /// The checked pairs, in a fixed order (body pairs first, then keep-outs).
    pub pairs: Vec<(Side, Side)>,
    /// Required clearance (m), `[collision] clearance_m`.
    pub required_m: f64,
    /// `true` if the task asks for clearance (`[collision]` or a `[[keep_out]]`); if not,
    /// the robot's own clearance is only reported.
    pub enforced: bool,
    /// `[collision] margin_m` (m).
    pub margin_m: f64,
    /// Joint frames: rotation and translation of each joint's origin, and its unit axis.
    joints: Vec<(Mat3, Vec3, Vec3)>,
    /// Mass and centre of mass (body frame) of each body.
    masses: Vec<(f64, Vec3)>,
    /// `ρ_j`: a bound on the distance from joint `j` to any point it carries (m).
    reach: Vec<f64>,
    /// `ρ_j·m_{≥j}/M`: a bound on how far joint `j` moves the base per radian (m).
    base_reach: Vec<f64>,
    /// System centre of mass at the start (m, inertial frame).
    com0: Vec3,
}

fn origin(xyz: [f64; 3], rpy: [f64; 3]) -> (Mat3, Vec3) {
    (rpy_matrix(rpy), Vec3::from(xyz))
}

/// Rotation by `angle` (rad) about unit `axis` (Rodrigues).
fn axis_angle(axis: &Vec3, angle: f64) -> Mat3 {
    let (s, c) = angle.sin_cos();
    let k = Mat3::new(
        0.0, -axis.z, axis.y, axis.z, 0.0, -axis.x, -axis.y, axis.x, 0.0,
    );
    Mat3::identity() + k * s + k * k * (1.0 - c)
}

/// `"body 'link3'"` or `"keep-out 'panel'"`, for messages and reports.
fn side_name(scene: &Scene, s: Side) -> String {
    match s {
        Side::Body(i) => format!("'{}'", scene.body_names.get(i).map_or("?", String::as_str)),
        Side::KeepOut(k) => format!(
            "keep-out '{}'",
            scene.keep_outs.get(k).map_or("?", |p| p.name.as_str())
        ),
    }
}

impl Scene {
    /// The scene of a task: the URDF's collision geometry (`chain`, read from `urdf`),
    /// `[[keep_out]]` (`keep`) and `[collision]`, each checked (sizes, capacities, names, a
    /// keep-out the start `q0` touches). `err` names the task file in a message.
    ///
    /// # Errors
    /// An input error naming the file, the key and the reason.
    pub fn new(
        chain: &Chain,
        keep: &[KeepOutSection],
        collision: Option<&CollisionSection>,
        q0: &[f64],
        err: &dyn Fn(String) -> CliError,
        urdf: &std::path::Path,
    ) -> Result<Self, CliError> {
        let count = chain.collider_count();
        if count > MAX_PRIMITIVES {
            return Err(CliError::input(format!(
                "{}: the robot has {count} collision primitives; at most {MAX_PRIMITIVES} are supported",
                urdf.display()
            )));
        }
        if keep.len() > MAX_KEEP_OUTS {
            return Err(err(format!(
                "[[keep_out]] has {} entries; at most {MAX_KEEP_OUTS} are supported",
                keep.len()
            )));
        }
        let mut keep_outs = Vec::with_capacity(keep.len());
        for (k, ko) in keep.iter().enumerate() {
            keep_outs.push(keep_out(err, k, ko)?);
        }
        let mut body_names = vec![chain.base_link.clone()];
        body_names.extend(chain.link_names.iter().cloned());
        let names: BTreeSet<&str> = body_names
            .iter()
            .map(String::as_str)
            .chain(keep.iter().map(|k| k.name.as_str()))
            .collect();
        if names.len() != body_names.len() + keep.len() {
            return Err(err(
                "[[keep_out]] name: two keep-outs, or a keep-out and a link, share a name".into(),
            ));
        }
        let default = CollisionSection::default();
        let c = collision.unwrap_or(&default);
        if !(c.clearance_m.is_finite() && c.clearance_m >= 0.0) {
            return Err(err(format!(
                "[collision] clearance_m = {} must be a finite number >= 0 (m)",
                c.clearance_m
            )));
        }
        let margin_m = c.margin_m.unwrap_or(DEFAULT_MARGIN_M);
        if !(margin_m.is_finite() && margin_m >= 0.0) {
            return Err(err(format!(
                "[collision] margin_m = {margin_m} must be a finite number >= 0 (m)"
            )));
        }
        let mut ignore = BTreeSet::new();
        for (i, [a, b]) in c.ignore.iter().enumerate() {
            for n in [a, b] {
                if !names.contains(n.as_str()) {
                    return Err(err(format!(
                        "[collision] ignore[{i}] names '{n}', which is neither a link of the robot nor a keep-out"
                    )));
                }
            }
            ignore.insert((a.clone(), b.clone()));
            ignore.insert((b.clone(), a.clone()));
        }
        let bodies: Vec<Vec<Part>> = chain
            .collision
            .iter()
            .map(|cs| {
                cs.iter()
                    .map(|c| {
                        let (rot, pos) = origin(c.origin.xyz, c.origin.rpy);
                        Part {
                            name: c.name.clone(),
                            shape: c.shape,
                            rot,
                            pos,
                        }
                    })
                    .collect()
            })
            .collect();
        let mut scene = Self {
            body_names,
            bodies,
            keep_outs,
            pairs: Vec::new(),
            required_m: c.clearance_m,
            enforced: collision.is_some() || !keep.is_empty(),
            margin_m,
            joints: chain
                .joints
                .iter()
                .map(|j| {
                    let (r, t) = origin(j.origin.xyz, j.origin.rpy);
                    (r, t, Vec3::from(j.axis).normalize())
                })
                .collect(),
            masses: std::iter::once(&chain.base)
                .chain(&chain.links)
                .map(|b| (b.mass, Vec3::from(b.inertial.xyz)))
                .collect(),
            reach: Vec::new(),
            base_reach: Vec::new(),
            com0: Vec3::zeros(),
        };
        scene.pairs = scene.pair_list(&ignore);
        scene.bounds(chain);
        scene.com0 = scene.com(q0);
        // A keep-out the start configuration touches cannot be left without collision.
        let frames = scene.frames(q0);
        for (a, b) in &scene.pairs {
            if let (Side::Body(_), Side::KeepOut(_)) = (a, b) {
                let d = scene.pair_distance(&frames, *a, *b).0;
                if d < 0.0 {
                    return Err(err(format!(
                        "[[keep_out]] {} overlaps {} at the start configuration (signed distance {d:.4} m)",
                        side_name(&scene, *b),
                        side_name(&scene, *a)
                    )));
                }
            }
        }
        Ok(scene)
    }

    /// `true` if no pair is checked (no geometry on either side of any pair).
    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// The planner's constraint: the core's collision set of this scene on `robot` (the
    /// same primitives, keep-outs and pairs, each body pair expanded to its primitives), or
    /// an empty set if the task does not require clearance.
    ///
    /// # Errors
    /// The core's refusal (a capacity), as a message.
    pub fn collision_set<const N: usize>(
        &self,
        robot: &Robot<N>,
    ) -> Result<CollisionSet<N>, String> {
        if !self.enforced || self.is_empty() {
            return Ok(CollisionSet::EMPTY);
        }
        let core = |e: reactionless::Error| e.to_string();
        let mut set = CollisionSet::new(self.required_m, self.margin_m).map_err(core)?;
        let placed = |p: &Part| Placed {
            shape: p.shape,
            rot: p.rot,
            pos: p.pos,
        };
        let mut index: Vec<Vec<u8>> = Vec::with_capacity(self.bodies.len());
        for (i, parts) in self.bodies.iter().enumerate() {
            let body = u8::try_from(i).map_err(|_| "more than 255 bodies".to_string())?;
            let mut ids = Vec::with_capacity(parts.len());
            for p in parts {
                ids.push(set.add_primitive(robot, body, &placed(p)).map_err(core)?);
            }
            index.push(ids);
        }
        let mut keep = Vec::with_capacity(self.keep_outs.len());
        for p in &self.keep_outs {
            keep.push(set.add_keep_out(&placed(p)).map_err(core)?);
        }
        // The core checks spec §13's pairs; what this scene leaves out, it ignores.
        let side = |s: Side| match s {
            Side::Body(i) => u8::try_from(i).ok().map(CoreSide::Body),
            Side::KeepOut(k) => keep.get(k).copied().map(CoreSide::KeepOut),
        };
        let n = self.bodies.len();
        let rule = (0..n)
            .flat_map(|i| (i + 2..n).map(move |j| (Side::Body(i), Side::Body(j))))
            .chain((0..n).flat_map(|i| {
                (0..self.keep_outs.len()).map(move |k| (Side::Body(i), Side::KeepOut(k)))
            }));
        for (a, b) in rule {
            if !self.pairs.contains(&(a, b)) {
                let (Some(a), Some(b)) = (side(a), side(b)) else {
                    return Err("a body or keep-out index above the core's capacity".into());
                };
                set.ignore(a, b).map_err(core)?;
            }
        }
        Ok(set)
    }

    /// `"'link2' ↔ keep-out 'panel'"`.
    pub fn pair_name(&self, (a, b): (Side, Side)) -> String {
        format!("{} - {}", side_name(self, a), side_name(self, b))
    }

    fn pair_list(&self, ignore: &BTreeSet<(String, String)>) -> Vec<(Side, Side)> {
        let n = self.bodies.len();
        let has = |s: Side| match s {
            Side::Body(i) => self.bodies.get(i).is_some_and(|b| !b.is_empty()),
            Side::KeepOut(_) => true,
        };
        let name = |s: Side| match s {
            Side::Body(i) => self.body_names[i].clone(),
            Side::KeepOut(k) => self.keep_outs[k].name.clone(),
        };
        let mut pairs = Vec::new();
        for i in 0..n {
            for j in i + 2..n {
                // Base (0) against link j ≥ 2; links i, j with |i − j| ≥ 2.
                pairs.push((Side::Body(i), Side::Body(j)));
            }
        }
        for i in 0..n {
            for k in 0..self.keep_outs.len() {
                pairs.push((Side::Body(i), Side::KeepOut(k)));
            }
        }
        pairs
            .into_iter()
            .filter(|&(a, b)| has(a) && has(b) && !ignore.contains(&(name(a), name(b))))
            .collect()
    }

    /// `ρ_j` and the base's share of it.
    fn bounds(&mut self, chain: &Chain) {
        let n = self.joints.len();
        let extent = |k: usize| {
            let prims = self.bodies[k]
                .iter()
                .map(|p| p.pos.norm() + p.shape.bounding_radius())
                .fold(0.0, f64::max);
            prims.max(self.masses[k].1.norm())
        };
        let total: f64 = self.masses.iter().map(|m| m.0).sum();
        self.reach = (1..=n)
            .map(|j| {
                // Joint j sits at body j's origin; body k ≥ j is at most the joint offsets
                // between them plus its extent away.
                let mut path = 0.0;
                let mut best: f64 = extent(j);
                for k in j + 1..=n {
                    path += self.joints[k - 1].1.norm();
                    best = best.max(path + extent(k));
                }
                let ee = path + Vec3::from(chain.end_effector.xyz).norm();
                best.max(ee)
            })
            .collect();
        self.base_reach = (1..=n)
            .map(|j| {
                let carried: f64 = self.masses[j..].iter().map(|m| m.0).sum();
                self.reach[j - 1] * carried / total
            })
            .collect();
    }

    /// Body frames at `q` (rad), inertial frame: attitude and origin of each body, the
    /// base placed by centre-of-mass conservation.
    pub fn frames(&self, q: &[f64]) -> Vec<(Mat3, Vec3)> {
        let mut out = self.frames_unshifted(q);
        let shift = self.com0 - self.com_of(&out);
        for f in &mut out {
            f.1 += shift;
        }
        out
    }

    fn com_of(&self, frames: &[(Mat3, Vec3)]) -> Vec3 {
        let (mut m, mut s) = (0.0, Vec3::zeros());
        for ((r, t), (mass, c)) in frames.iter().zip(&self.masses) {
            m += mass;
            s += (t + r * c) * *mass;
        }
        s / m
    }

    /// System centre of mass at `q` with the base at the origin (m).
    fn com(&self, q: &[f64]) -> Vec3 {
        self.com_of(&self.frames_unshifted(q))
    }

    /// Body frames at `q` with the base at the origin.
    fn frames_unshifted(&self, q: &[f64]) -> Vec<(Mat3, Vec3)> {
        let mut out = vec![(Mat3::identity(), Vec3::zeros())];
        let (mut r, mut t) = (Mat3::identity(), Vec3::zeros());
        for ((jr, jt, axis), qj) in self.joints.iter().zip(q) {
            t += r * jt;
            r = r * jr * axis_angle(axis, *qj);
            out.push((r, t));
        }
        out
    }

    /// Every body's primitives placed at the body frames `frames`.
    fn placed(&self, frames: &[(Mat3, Vec3)]) -> Vec<Vec<Placed>> {
        self.bodies
            .iter()
            .zip(frames)
            .map(|(parts, (r, t))| {
                parts
                    .iter()
                    .map(|p| Placed {
                        shape: p.shape,
                        rot: r * p.rot,
                        pos: t + r * p.pos,
                    })
                    .collect()
            })
            .collect()
    }

    /// Signed distance of a pair given every body's placed primitives (m), and the indices
    /// of the closest primitives on each side.
    fn distance_placed(&self, placed: &[Vec<Placed>], a: Side, b: Side) -> (f64, usize, usize) {
        let keep: Vec<Placed>;
        let side = |s: Side| -> &[Placed] {
            match s {
                Side::Body(i) => &placed[i],
                Side::KeepOut(_) => &[],
            }
        };
        let pb: &[Placed] = match b {
            Side::KeepOut(k) => {
                let p = &self.keep_outs[k];
                keep = vec![Placed {
                    shape: p.shape,
                    rot: p.rot,
                    pos: p.pos,
                }];
                &keep
            }
            Side::Body(_) => side(b),
        };
        let mut best = (f64::INFINITY, 0, 0);
        for (i, x) in side(a).iter().enumerate() {
            for (j, y) in pb.iter().enumerate() {
                let d = signed_distance(x, y);
                if d < best.0 {
                    best = (d, i, j);
                }
            }
        }
        best
    }

    /// Signed distance of a pair at the body frames `frames` (m), and the indices of the
    /// closest primitives on each side (`a` is a body; `b` a body or a keep-out).
    pub fn pair_distance(&self, frames: &[(Mat3, Vec3)], a: Side, b: Side) -> (f64, usize, usize) {
        self.distance_placed(&self.placed(frames), a, b)
    }

    /// How far any point of side `s` can move between configurations differing by `dq`.
    fn motion_bound(&self, s: Side, dq: &[f64]) -> f64 {
        let base: f64 = dq
            .iter()
            .zip(&self.base_reach)
            .map(|(d, r)| d.abs() * r)
            .sum();
        match s {
            Side::Body(i) => {
                base + dq
                    .iter()
                    .zip(&self.reach)
                    .take(i)
                    .map(|(d, r)| d.abs() * r)
                    .sum::<f64>()
            }
            Side::KeepOut(_) => 0.0,
        }
    }

    /// The clearance of the piecewise-linear path through `samples` (configurations,
    /// rad) at times `times` (s), pair by pair.
    pub fn sweep(&self, times: &[f64], samples: &[Vec<f64>]) -> Sweep {
        let placed: Vec<Vec<Vec<Placed>>> = samples
            .iter()
            .map(|q| self.placed(&self.frames(q)))
            .collect();
        // Motion bound of every side over every interval (the keep-outs do not move).
        let moves: Vec<Vec<f64>> = samples
            .windows(2)
            .map(|w| {
                let dq: Vec<f64> = w[1].iter().zip(&w[0]).map(|(x, y)| x - y).collect();
                (0..self.bodies.len())
                    .map(|i| self.motion_bound(Side::Body(i), &dq))
                    .collect()
            })
            .collect();
        let mut pairs = Vec::with_capacity(self.pairs.len());
        let mut evaluations = 0u64;
        for &(a, b) in &self.pairs {
            let at: Vec<(f64, usize, usize)> = placed
                .iter()
                .map(|p| self.distance_placed(p, a, b))
                .collect();
            let (s_min, best_at) = at
                .iter()
                .enumerate()
                .fold(
                    (f64::INFINITY, 0),
                    |acc, (s, d)| if d.0 < acc.0 { (d.0, s) } else { acc },
                );
            let mut best = PairMin {
                pair: (a, b),
                min_m: s_min,
                t_s: times.get(best_at).copied().unwrap_or(0.0),
                parts: (at[best_at].1, at[best_at].2),
                min_at_samples_m: s_min,
                sample: best_at,
                resolved: true,
            };
            let bound = |m: &[f64], s: Side| match s {
                Side::Body(i) => m[i],
                Side::KeepOut(_) => 0.0,
            };
            for (s, m) in moves.iter().enumerate() {
                let (q0, q1) = (&samples[s], &samples[s + 1]);
                let delta = bound(m, a) + bound(m, b);
                let (t0, t1) = (times[s], times[s + 1]);
                let mut stack = vec![(0.0f64, at[s].0, 1.0f64, at[s + 1].0)];
                let mut splits = 0u32;
                while let Some((u0, d0, u1, d1)) = stack.pop() {
                    let dl = delta * (u1 - u0);
                    let lower = if (d0 - d1).abs() >= dl {
                        d0.min(d1)
                    } else {
                        0.5 * (d0 + d1 - dl)
                    };
                    if lower >= best.min_m - RESOLUTION_M || dl < RESOLUTION_M {
                        continue;
                    }
                    if splits >= MAX_SPLITS {
                        best.resolved = false;
                        break;
                    }
                    splits += 1;
                    let um = 0.5 * (u0 + u1);
                    let q: Vec<f64> = q0.iter().zip(q1).map(|(x, y)| x + um * (y - x)).collect();
                    let (dm, i, j) = self.pair_distance(&self.frames(&q), a, b);
                    evaluations += 1;
                    if dm < best.min_m {
                        best.min_m = dm;
                        best.t_s = t0 + um * (t1 - t0);
                        best.parts = (i, j);
                    }
                    stack.push((u0, d0, um, dm));
                    stack.push((um, dm, u1, d1));
                }
            }
            pairs.push(best);
        }
        Sweep {
            pairs,
            evaluations,
            required_m: self.required_m,
            enforced: self.enforced,
        }
    }

    /// Names of the closest primitives of a pair minimum.
    pub fn part_names(&self, p: &PairMin) -> (String, String) {
        let name = |s: Side, k: usize| match s {
            Side::Body(i) => self.bodies[i]
                .get(k)
                .map_or(String::new(), |p| p.name.clone()),
            Side::KeepOut(k) => self.keep_outs[k].name.clone(),
        };
        (name(p.pair.0, p.parts.0), name(p.pair.1, p.parts.1))
    }
}

/// The smallest signed distance of one pair over a path.
#[derive(Debug, Clone)]
pub struct PairMin {
    /// The pair.
    pub pair: (Side, Side),
    /// Smallest signed distance over the continuous path (m), attained at `t_s`.
    pub min_m: f64,
    /// When (s).
    pub t_s: f64,
    /// The closest primitives (indices on each side).
    pub parts: (usize, usize),
    /// Smallest over the written samples only (m).
    pub min_at_samples_m: f64,
    /// The sample where that is.
    pub sample: usize,
    /// `false` if an interval ran out of bisections ([`MAX_SPLITS`]) before its bound
    /// cleared: the minimum is then not certified to [`RESOLUTION_M`].
    pub resolved: bool,
}

/// A path's clearance, pair by pair.
#[derive(Debug, Clone)]
pub struct Sweep {
    /// Every checked pair, in the scene's order.
    pub pairs: Vec<PairMin>,
    /// Evaluations between the samples that the bound asked for.
    pub evaluations: u64,
    /// The required clearance (m).
    pub required_m: f64,
    /// Whether the task requires it ([`Scene::enforced`]).
    pub enforced: bool,
}

impl Sweep {
    /// `true` if the path keeps the clearance the task requires (always, if it requires none).
    pub fn pass(&self) -> bool {
        !self.enforced || self.clear()
    }

    /// The pair with the smallest clearance, if any pair is checked.
    pub fn worst(&self) -> Option<&PairMin> {
        self.pairs.iter().min_by(|a, b| a.min_m.total_cmp(&b.min_m))
    }

    /// `true` if every pair keeps the required clearance, resolution included (whether or
    /// not the task requires it).
    pub fn clear(&self) -> bool {
        self.pairs.iter().all(|p| self.keeps(p))
    }

    /// `true` if pair `p` keeps the required clearance, resolution included.
    pub fn keeps(&self, p: &PairMin) -> bool {
        p.resolved && p.min_m - RESOLUTION_M >= self.required_m
    }
}

/// A keep-out of the task as a part, its keys checked.
fn keep_out(
    err: &dyn Fn(String) -> CliError,
    k: usize,
    ko: &KeepOutSection,
) -> Result<Part, CliError> {
    let key = |name: &str| format!("[[keep_out]] '{}' (entry {}) {name}", ko.name, k + 1);
    let three = |name: &str, v: &Option<Vec<f64>>| -> Result<Option<[f64; 3]>, CliError> {
        match v {
            None => Ok(None),
            Some(v) => match <[f64; 3]>::try_from(v.as_slice()) {
                Ok(a) if a.iter().all(|x| x.is_finite()) => Ok(Some(a)),
                _ => Err(err(format!(
                    "{} = {v:?} must be 3 finite numbers",
                    key(name)
                ))),
            },
        }
    };
    if ko.name.is_empty() {
        return Err(err(format!(
            "[[keep_out]] entry {}: name must not be empty",
            k + 1
        )));
    }
    let position = three("position_m", &Some(ko.position_m.clone()))?.unwrap_or([0.0; 3]);
    let rpy = three("rpy_deg", &ko.rpy_deg)?
        .unwrap_or([0.0; 3])
        .map(f64::to_radians);
    let need = |name: &str, v: Option<f64>| {
        v.ok_or_else(|| {
            err(format!(
                "{} is missing (a {} needs it)",
                key(name),
                ko.shape
            ))
        })
    };
    let forbid = |name: &str, present: bool| {
        if present {
            Err(err(format!(
                "{} does not apply to a {}",
                key(name),
                ko.shape
            )))
        } else {
            Ok(())
        }
    };
    let shape = match ko.shape.as_str() {
        "box" => {
            forbid("radius_m", ko.radius_m.is_some())?;
            forbid("length_m", ko.length_m.is_some())?;
            let half = three("half_extents_m", &ko.half_extents_m)?.ok_or_else(|| {
                err(format!(
                    "{} is missing (a box needs it)",
                    key("half_extents_m")
                ))
            })?;
            Shape::Box { half }
        }
        "sphere" => {
            forbid("half_extents_m", ko.half_extents_m.is_some())?;
            forbid("length_m", ko.length_m.is_some())?;
            Shape::Sphere {
                radius: need("radius_m", ko.radius_m)?,
            }
        }
        "capsule" => {
            forbid("half_extents_m", ko.half_extents_m.is_some())?;
            Shape::Capsule {
                length: need("length_m", ko.length_m)?,
                radius: need("radius_m", ko.radius_m)?,
            }
        }
        other => {
            return Err(err(format!(
                "{} = {other:?}: expected \"box\", \"sphere\" or \"capsule\"",
                key("shape")
            )));
        }
    };
    if !shape.is_valid() {
        return Err(err(format!(
            "{}: sizes must be finite numbers >= 0 (m)",
            key("shape")
        )));
    }
    Ok(Part {
        name: ko.name.clone(),
        shape,
        rot: rpy_matrix(rpy),
        pos: Vec3::from(position),
    })
}

/// The clearance of a path (`times` in s, configurations `qs` in rad) in one line of a
/// summary: the smallest, between what and when, and whether the task requires it; and
/// `true` if a required clearance is violated. `None` if no pair is checked.
pub fn summary_line(scene: &Scene, times: &[f64], qs: &[Vec<f64>]) -> Option<(String, bool)> {
    if scene.is_empty() {
        return None;
    }
    let sweep = scene.sweep(times, qs);
    let w = sweep.worst()?;
    let verdict = if !sweep.enforced {
        "not required: no [collision], no [[keep_out]]".to_string()
    } else if sweep.pass() {
        format!("requirement ≥ {} m: ok", sweep.required_m)
    } else {
        format!("requirement ≥ {} m: VIOLATED", sweep.required_m)
    };
    let text = format!(
        "{:.4} m, {} at t = {:.2} s ({verdict})",
        w.min_m,
        scene.pair_name(w.pair),
        w.t_s
    );
    Some((text, !sweep.pass()))
}

/// The written samples of a rollout of `eta` on `task`: times (s) and configurations (rad).
///
/// # Errors
/// The rollout's error, as an input error.
pub fn path_of<const N: usize, const K: usize>(
    task: &reactionless::Task<N, K>,
    eta: &reactionless::Eta<K>,
) -> Result<(Vec<f64>, Vec<Vec<f64>>), CliError> {
    let (mut times, mut qs) = (Vec::new(), Vec::new());
    let mut sink = |s: &reactionless::Sample<N>| {
        times.push(s.t);
        qs.push(s.q.to_vec());
    };
    task.rollout_of(eta, &mut sink)
        .map_err(|e| CliError::input(format!("rollout: {e}")))?;
    Ok((times, qs))
}
