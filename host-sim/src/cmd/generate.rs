//! `host-sim generate`: task files with reachable targets for a user's robot.
//!
//! Targets are made as the reference target was (spec §10): roll out a random η from the
//! start and take the pose reached — with the true base drift (truth model, 10 sub-steps),
//! so the target is exactly reachable by that η. A candidate is kept only if its rollout
//! succeeds, respects the joint limits (Φ = 0) and moves the end effector by at least
//! `--min-motion-m`. η is drawn uniform in `[−B, B]^(2K)` from the generator's own stream
//! of the seed (`reactionless::random::Purpose::Generator`, not the planner's), so the same
//! arguments always write the same tasks and a plan with that seed does not start from the
//! generating η.
//!
//! `--kind` chooses what a target is (issue #30's generic targets):
//! - `rollout` (the default): as above, a pose some reactionless motion from the start
//!   reaches;
//! - `joint`: the planner-model end pose (base attitude held, CoM fixed) at a configuration
//!   `--distance-deg` away: every joint moved by a uniform `d/2…d` with a random sign,
//!   reflected back about the start if that would leave its limits (by 0.5°); no rollout
//!   made it;
//! - `perturbed`: a rollout target as above, then moved by `--move-m` in a uniformly random
//!   direction and turned by `--move-deg` about a uniformly random axis.
//!
//! `--keep-out-radius-m R` (rollout targets) puts a spherical keep-out of radius `R` across
//! the straight line from the start's end-effector position to the target (at its
//! midpoint) and asks for `--clearance-m` (a `[collision]` table): benchmark tasks whose
//! direct motion is blocked (issue #33). A candidate is kept only if the generating η's own
//! path keeps that clearance from the keep-out and from the robot itself (spec §13), so a
//! collision-free plan is known to exist.
//!
//! `--preshape` adds a `[preshape]` table (its defaults): the tasks ask for two-phase plans.
//! `--family free_amplitude` writes `[motion] family`: the planner then plans with the
//! free-amplitude family (the targets are made as always, by the paper family's rollouts).

use crate::args::{List, RobotArgs, parse_family, parse_list};
use crate::clearance::{CollisionSection, KeepOutSection, Scene};
use crate::error::CliError;
use crate::output::OutDir;
use crate::records::relative_text;
use crate::urdf::Chain;
use crate::with_dims;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::random::{Purpose, Stream};
use reactionless::{Family, IDENTITY_WXYZ, Motion, Pose, Task, TruthModel};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Write COUNT task files for a robot: reachable targets (random feasible η rolled out from
/// the start, truth-model end pose as target), or generic ones (--kind joint, perturbed).
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    #[command(flatten)]
    robot: RobotArgs,
    /// Start configuration (deg), comma-separated: the tasks' `[start] q_deg`.
    #[arg(long, alias = "start-deg", allow_hyphen_values = true, value_parser = parse_list)]
    q_deg: List,
    /// Number of tasks.
    #[arg(long, value_parser = crate::args::parse_u32)]
    count: u32,
    /// Seed of the stream that draws η.
    #[arg(long, value_parser = crate::args::parse_seed)]
    seed: u64,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
    /// Motion duration (s).
    #[arg(long, default_value_t = 30.0)]
    tf_s: f64,
    /// Integration step (s).
    #[arg(long, default_value_t = 0.01)]
    dt_s: f64,
    /// Smallest end-effector displacement of a target from the start (m, > 0).
    #[arg(long, default_value_t = 0.2)]
    min_motion_m: f64,
    /// Half-width of the box η is drawn from (> 0).
    #[arg(long, default_value_t = 5.0)]
    eta_bound: f64,
    /// What a target is: rollout, joint or perturbed (see `host-sim generate --help`).
    #[arg(long, value_enum, default_value_t = Kind::Rollout)]
    kind: Kind,
    /// `--kind joint`: largest move of each joint from the start (deg, > 0).
    #[arg(long, default_value_t = 10.0)]
    distance_deg: f64,
    /// `--kind perturbed`: how far the target moves (m, ≥ 0).
    #[arg(long, default_value_t = 0.01)]
    move_m: f64,
    /// `--kind perturbed`: how far the target turns (deg, ≥ 0).
    #[arg(long, default_value_t = 0.5)]
    move_deg: f64,
    /// Add a `[preshape]` table: the tasks ask for two-phase plans (spec §15).
    #[arg(long)]
    preshape: bool,
    /// The motion family the tasks ask for (`[motion] family`): paper (eq. 14, written as
    /// nothing) or free_amplitude (for targets near a fixed start's reach).
    #[arg(long, value_parser = parse_family, default_value = "paper")]
    family: Family,
    /// Put a spherical keep-out of this radius (m, > 0) across the straight line from the
    /// start's end-effector position to each target, and keep only targets whose
    /// generating path clears it and the robot itself by `--clearance-m` (rollout targets).
    #[arg(long)]
    keep_out_radius_m: Option<f64>,
    /// With `--keep-out-radius-m`: the required clearance written to `[collision]` (m, ≥ 0).
    #[arg(long, default_value_t = 0.02)]
    clearance_m: f64,
    /// How the targets' rollouts integrate the path, written as `[motion] integrator`:
    /// euler (the reference, written as nothing), rk4 or ab5 (the targets are then that path's truth
    /// poses, whose base drift is far smaller than Euler's).
    #[arg(long, value_parser = crate::args::parse_integrator, default_value = "euler")]
    integrator: reactionless::Integrator,
}

/// What a generated target is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Kind {
    /// A pose a random reactionless motion from the start reaches (truth model).
    Rollout,
    /// The end pose at a random configuration `--distance-deg` from the start.
    Joint,
    /// A rollout target moved by `--move-m` and turned by `--move-deg`.
    Perturbed,
}

/// Tries per requested task before giving up.
const ATTEMPTS_PER_TASK: u32 = 200;

/// A finite number > 0, or an error naming `flag`.
fn positive(flag: &str, v: f64) -> Result<(), CliError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(CliError::input(format!(
            "{flag} {v} must be a finite number > 0"
        )))
    }
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        if self.count == 0 {
            return Err(CliError::input("--count must be at least 1"));
        }
        positive("--min-motion-m", self.min_motion_m)?;
        positive("--eta-bound", self.eta_bound)?;
        positive("--distance-deg", self.distance_deg)?;
        for (flag, v) in [("--move-m", self.move_m), ("--move-deg", self.move_deg)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(CliError::input(format!(
                    "{flag} {v} must be a finite number >= 0"
                )));
            }
        }
        if let Some(r) = self.keep_out_radius_m {
            positive("--keep-out-radius-m", r)?;
            if self.kind != Kind::Rollout {
                return Err(CliError::input(
                    "--keep-out-radius-m needs --kind rollout (a generating path to keep clear)",
                ));
            }
        }
        if !(self.clearance_m.is_finite() && self.clearance_m >= 0.0) {
            return Err(CliError::input(format!(
                "--clearance-m {} must be a finite number >= 0",
                self.clearance_m
            )));
        }
        let chain = self.robot.load()?;
        with_dims!(chain.dof(), generate_n, &chain, &self)
    }
}

fn fmt_list(v: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|x| ryu::Buffer::new().format(*x).to_string())
        .collect();
    format!("[{}]", items.join(", "))
}

fn distance(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y) * (x - y))
        .sum::<f64>()
        .sqrt()
}

/// A uniformly random unit vector (rejection in the unit ball).
fn direction(stream: &mut Stream) -> [f64; 3] {
    for _ in 0..64 {
        let v = [0, 1, 2].map(|_| 2.0 * stream.uniform() - 1.0);
        let n = v.iter().map(|x| x * x).sum::<f64>().sqrt();
        if n > 1e-3 && n <= 1.0 {
            return v.map(|x| x / n);
        }
    }
    [1.0, 0.0, 0.0]
}

/// `pose` moved by `m` metres in a random direction and turned by `angle` rad about a
/// random axis (inertial frame).
fn perturb(pose: &Pose, m: f64, angle: f64, stream: &mut Stream) -> Pose {
    let u = direction(stream);
    let a = direction(stream);
    let (s, c) = ((angle / 2.0).sin(), (angle / 2.0).cos());
    let d = [c, a[0] * s, a[1] * s, a[2] * s];
    let q = pose.quat_wxyz;
    let mut r = [
        d[0] * q[0] - d[1] * q[1] - d[2] * q[2] - d[3] * q[3],
        d[0] * q[1] + d[1] * q[0] + d[2] * q[3] - d[3] * q[2],
        d[0] * q[2] - d[1] * q[3] + d[2] * q[0] + d[3] * q[1],
        d[0] * q[3] + d[1] * q[2] - d[2] * q[1] + d[3] * q[0],
    ];
    if r[0] < 0.0 {
        r = r.map(|x| -x);
    }
    Pose {
        position: [0, 1, 2].map(|i| pose.position[i] + m * u[i]),
        quat_wxyz: r,
    }
}

/// A kept target: what made it (η, or q in deg), the target, how far the end effector
/// moves (m), and the centre of its keep-out (m) if one blocks the straight line.
type Found = (Vec<f64>, Pose, f64, Option<[f64; 3]>);

/// `true` if the path of `eta` from `q0` keeps `--clearance-m` from a sphere of radius `r`
/// at `centre` and from the robot itself (every pair of spec §13), with no tunnelling.
fn clear_of<const N: usize, const K: usize>(
    chain: &Chain,
    o: &Args,
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    q0: &[f64; N],
    centre: [f64; 3],
    r: f64,
) -> bool {
    let keep = [KeepOutSection {
        name: "obstacle".into(),
        shape: "sphere".into(),
        position_m: centre.to_vec(),
        rpy_deg: None,
        half_extents_m: None,
        radius_m: Some(r),
        length_m: None,
    }];
    let collision = CollisionSection {
        clearance_m: o.clearance_m,
        ignore: Vec::new(),
        margin_m: None,
    };
    let err = |m: String| CliError::input(m);
    let Ok(scene) = Scene::new(chain, &keep, Some(&collision), q0, &err, &o.robot.urdf) else {
        return false; // the sphere touches the start
    };
    let Ok((times, qs)) =
        crate::clearance::path_of(task, &reactionless::trajectory::one_segment(*eta))
    else {
        return false;
    };
    scene.sweep(&times, &qs).pass()
}

fn generate_n<const N: usize, const K: usize>(chain: &Chain, o: &Args) -> Result<(), CliError> {
    let robot = chain.robot::<N>(&o.robot.urdf)?;
    let start_deg = &o.q_deg.0;
    if start_deg.len() != N {
        return Err(CliError::input(format!(
            "--q-deg has {} values; the robot has {N} joints",
            start_deg.len()
        )));
    }
    let mut q0 = [0.0; N];
    for (q, d) in q0.iter_mut().zip(start_deg) {
        *q = d.to_radians();
    }
    let motion = Motion::new(o.tf_s, o.dt_s, 1)
        .and_then(|m| m.with_integrator(o.integrator))
        .map_err(|e| CliError::input(format!("--tf-s {} --dt-s {}: {e}", o.tf_s, o.dt_s)))?;
    let identity = Pose {
        position: [0.0; 3],
        quat_wxyz: IDENTITY_WXYZ,
    };
    let probe = Task::<N, K>::new(robot, q0, identity, motion).map_err(|e| {
        let msg = match e {
            reactionless::Error::StartOutsideLimits(j) => {
                format!(
                    "--q-deg: {} is outside the limits of {}",
                    start_deg[usize::from(j) - 1],
                    chain.joint_name(j)
                )
            }
            other => format!("--q-deg: {other}"),
        };
        CliError::input(msg)
    })?;
    let start = probe.start_pose().position;
    let mut stream = Stream::for_purpose(o.seed, Purpose::Generator);
    let mut found: Vec<Found> = Vec::new();
    let mut attempts = 0;
    while found.len() < o.count as usize && attempts < ATTEMPTS_PER_TASK * o.count {
        attempts += 1;
        if o.kind == Kind::Joint {
            let mut q = q0;
            let (lo, hi) = (probe.robot().lower(), probe.robot().upper());
            let edge = 0.5f64.to_radians();
            for (j, v) in q.iter_mut().enumerate() {
                let sign = if stream.uniform() < 0.5 { -1.0 } else { 1.0 };
                let d = sign * o.distance_deg.to_radians() * (0.5 + 0.5 * stream.uniform());
                *v += d;
                if *v < lo[j] + edge || *v > hi[j] - edge {
                    *v -= 2.0 * d;
                }
            }
            let inside = q
                .iter()
                .enumerate()
                .all(|(j, v)| *v >= lo[j] + edge && *v <= hi[j] - edge);
            if !inside {
                continue;
            }
            let end = probe.end_pose(&q, IDENTITY_WXYZ);
            let moved = distance(&end.position, &start);
            let deg: Vec<f64> = q.iter().map(|v| v.to_degrees()).collect();
            found.push((deg, end, moved, None));
            continue;
        }
        let mut eta = [[0.0; 2]; K];
        for v in eta.iter_mut().flatten() {
            *v = o.eta_bound * (2.0 * stream.uniform() - 1.0);
        }
        let mut truth = TruthModel::new(&probe, TRUTH_SUBSTEPS);
        let Ok(out) = probe.rollout(&eta, &mut truth) else {
            continue;
        };
        let Some(mut end) = truth.end_pose() else {
            continue;
        };
        if out.phi == 0.0
            && truth.error().is_none()
            && distance(&end.position, &start) >= o.min_motion_m
        {
            if o.kind == Kind::Perturbed {
                end = perturb(&end, o.move_m, o.move_deg.to_radians(), &mut stream);
            }
            let keep_out = match o.keep_out_radius_m {
                None => None,
                Some(r) => {
                    let centre = [0, 1, 2].map(|i| 0.5 * (start[i] + end.position[i]));
                    if !clear_of(chain, o, &probe, &eta, &q0, centre, r) {
                        continue;
                    }
                    Some(centre)
                }
            };
            let moved = distance(&end.position, &start);
            found.push((
                eta.iter().flatten().copied().collect(),
                end,
                moved,
                keep_out,
            ));
        }
    }
    if found.len() < o.count as usize {
        return Err(CliError::failed(format!(
            "found {} of {} reachable targets in {attempts} attempts (try a smaller --min-motion-m or another start)",
            found.len(),
            o.count
        )));
    }
    let dir = OutDir::create(&o.out)?;
    let urdf_rel = relative_text(&o.out, &o.robot.urdf)?;
    for (k, (eta, target, moved, keep_out)) in found.iter().enumerate() {
        let mut t = String::new();
        let how = match o.kind {
            Kind::Rollout => format!(
                "a reachable target made by\n# rolling out eta = {} from the start\n# (truth model, {TRUTH_SUBSTEPS} sub-steps",
                fmt_list(eta)
            ),
            Kind::Joint => format!(
                "a generic target: the end pose\n# (base attitude held, CoM fixed) at q_deg = {}\n# ({} deg per joint at most from the start",
                fmt_list(eta),
                ryu::Buffer::new().format(o.distance_deg)
            ),
            Kind::Perturbed => format!(
                "a generic target: the pose\n# reached by rolling out eta = {} from the start (truth model), moved by {} m\n# and turned by {} deg (random direction and axis",
                fmt_list(eta),
                ryu::Buffer::new().format(o.move_m),
                ryu::Buffer::new().format(o.move_deg)
            ),
        };
        let _ = writeln!(
            t,
            "# Generated by host-sim generate (seed {}, task {} of {}): {how}; end effector {moved:.3} m from its start).\n",
            o.seed,
            k + 1,
            o.count,
        );
        let _ = writeln!(t, "[robot]\nurdf = {urdf_rel:?}");
        if let Some(ee) = &o.robot.ee {
            let _ = writeln!(t, "ee_link = {ee:?}");
        } else {
            let _ = writeln!(t, "ee_link = {:?}", chain.ee_link);
        }
        let _ = writeln!(t, "\n[start]\nq_deg = {}\n", fmt_list(start_deg));
        let _ = writeln!(
            t,
            "[target]\nposition_m = {}\nquat_wxyz = {}\n",
            fmt_list(&target.position),
            fmt_list(&target.quat_wxyz)
        );
        let family = match o.family {
            Family::Paper => "",
            Family::FreeAmplitude => {
                "family = \"free_amplitude\"  # planned so; any eta above is the paper family's\n"
            }
        };
        let integrator = match o.integrator {
            reactionless::Integrator::Euler => String::new(),
            other => format!("integrator = \"{}\"\n", other.name()),
        };
        let _ = writeln!(
            t,
            "[motion]\ntf_s = {}\ndt_s = {}\nn = 1\n{family}{integrator}\n[planner]\nseed = 1",
            ryu::Buffer::new().format(o.tf_s),
            ryu::Buffer::new().format(o.dt_s)
        );
        if o.preshape {
            let _ = writeln!(
                t,
                "\n[preshape]  # plan in two phases (spec §15); every key has a default"
            );
        }
        if let (Some(c), Some(r)) = (keep_out, o.keep_out_radius_m) {
            let _ = writeln!(
                t,
                "\n# Across the straight line from the start's end effector to the target; the\n# generating eta's path keeps the clearance.\n[[keep_out]]\nname = \"obstacle\"\nshape = \"sphere\"\nposition_m = {}\nradius_m = {}\n\n[collision]\nclearance_m = {}",
                fmt_list(c),
                ryu::Buffer::new().format(r),
                ryu::Buffer::new().format(o.clearance_m)
            );
        }
        dir.write(&format!("task_{:03}.toml", k + 1), t.as_bytes())?;
    }
    let path = dir.commit()?;
    eprintln!(
        "generate: {} tasks in {attempts} attempts -> {}",
        found.len(),
        path.display()
    );
    Ok(())
}
