//! `host-sim generate`: task files with reachable targets for a user's robot.
//!
//! Targets are made as the reference target was (spec §10): roll out a random η from the
//! start and take the pose reached — with the true base drift (truth model, 10 sub-steps),
//! so the target is exactly reachable by that η. A candidate is kept only if its rollout
//! succeeds, respects the joint limits (Φ = 0) and moves the end effector by at least
//! `--min-motion-m`. η is drawn from the seeded xoshiro256++ stream, uniform in
//! `[−B, B]^(2K)`, so the same arguments always write the same tasks.

use crate::cmd::record::relative;
use crate::cmd::rollout::TRUTH_SUBSTEPS;
use crate::error::CliError;
use crate::output::OutDir;
use crate::urdf::{self, Chain};
use crate::with_dims;
use reactionless::random::Stream;
use reactionless::{Motion, Pose, Robot, Task, TruthModel};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What to generate.
#[derive(Debug, Clone)]
pub struct GenerateOptions {
    /// Robot.
    pub urdf: PathBuf,
    /// End-effector link (default: the only leaf).
    pub ee: Option<String>,
    /// Start configuration (deg).
    pub start_deg: Vec<f64>,
    /// How many tasks.
    pub count: u32,
    /// Seed of the stream that draws η.
    pub seed: u64,
    /// Output directory.
    pub out: PathBuf,
    /// Motion duration (s).
    pub tf_s: f64,
    /// Integration step (s).
    pub dt_s: f64,
    /// Smallest end-effector displacement (m).
    pub min_motion_m: f64,
    /// Half-width of the η box.
    pub eta_bound: f64,
}

/// Tries per requested task before giving up.
const ATTEMPTS_PER_TASK: u32 = 200;

/// Runs the subcommand.
pub fn run(o: &GenerateOptions) -> Result<(), CliError> {
    if o.count == 0 {
        return Err(CliError::input("--count must be at least 1"));
    }
    for (v, name) in [
        (o.min_motion_m, "--min-motion-m"),
        (o.eta_bound, "--eta-bound"),
    ] {
        if !(v.is_finite() && v >= 0.0) || (name == "--eta-bound" && v == 0.0) {
            return Err(CliError::input(format!(
                "{name} {v} must be a finite number > 0"
            )));
        }
    }
    let chain = urdf::load(&o.urdf, o.ee.as_deref())?;
    with_dims!(chain.dof(), generate_n, &chain, o)
}

fn fmt_list(v: &[f64]) -> String {
    let items: Vec<String> = v
        .iter()
        .map(|x| ryu::Buffer::new().format(*x).to_string())
        .collect();
    format!("[{}]", items.join(", "))
}

fn generate_n<const N: usize, const K: usize>(
    chain: &Chain,
    o: &GenerateOptions,
) -> Result<(), CliError> {
    let robot = Robot::new(&chain.desc::<N>()?)
        .map_err(|e| CliError::input(format!("{}: {}", o.urdf.display(), chain.explain(&e))))?;
    if o.start_deg.len() != N {
        return Err(CliError::input(format!(
            "--start-deg has {} values; the robot has {N} joints",
            o.start_deg.len()
        )));
    }
    let mut q0 = [0.0; N];
    for (q, d) in q0.iter_mut().zip(&o.start_deg) {
        *q = d.to_radians();
    }
    let motion = Motion::new(o.tf_s, o.dt_s, 1)
        .map_err(|e| CliError::input(format!("--tf-s {} --dt-s {}: {e}", o.tf_s, o.dt_s)))?;
    let identity = Pose {
        position: [0.0; 3],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let probe = Task::<N, K>::new(robot, q0, identity, motion).map_err(|e| {
        let msg = match e {
            reactionless::Error::StartOutsideLimits(j) => {
                format!(
                    "--start-deg: {} is outside the limits of {}",
                    o.start_deg[usize::from(j) - 1],
                    chain.joint_name(j)
                )
            }
            other => format!("--start-deg: {other}"),
        };
        CliError::input(msg)
    })?;
    let start = probe.start_pose().position;
    let mut stream = Stream::new(o.seed);
    let mut found: Vec<(Vec<f64>, Pose, f64)> = Vec::new();
    let mut attempts = 0;
    while found.len() < o.count as usize && attempts < ATTEMPTS_PER_TASK * o.count {
        attempts += 1;
        let mut eta = [[0.0; 2]; K];
        for v in eta.iter_mut().flatten() {
            *v = o.eta_bound * (2.0 * stream.uniform() - 1.0);
        }
        let mut truth = TruthModel::new(&probe, TRUTH_SUBSTEPS);
        let Ok(out) = probe.rollout(&eta, &mut truth) else {
            continue;
        };
        let Some(end) = truth.end_pose() else {
            continue;
        };
        let moved = end
            .position
            .iter()
            .zip(&start)
            .map(|(a, b)| (a - b) * (a - b))
            .sum::<f64>()
            .sqrt();
        if out.phi == 0.0 && truth.error().is_none() && moved >= o.min_motion_m {
            found.push((eta.iter().flatten().copied().collect(), end, moved));
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
    let urdf_rel = relative(&o.out, &o.urdf)?
        .to_string_lossy()
        .replace('\\', "/");
    for (k, (eta, target, moved)) in found.iter().enumerate() {
        let mut t = String::new();
        let _ = writeln!(
            t,
            "# Generated by host-sim generate (seed {}, task {} of {}): a reachable target made by\n\
             # rolling out eta = {} from the start\n\
             # (truth model, {TRUTH_SUBSTEPS} sub-steps; end effector moved {moved:.3} m).\n",
            o.seed,
            k + 1,
            o.count,
            fmt_list(eta)
        );
        let _ = writeln!(t, "[robot]\nurdf = {urdf_rel:?}");
        if let Some(ee) = &o.ee {
            let _ = writeln!(t, "ee_link = {ee:?}");
        } else {
            let _ = writeln!(t, "ee_link = {:?}", chain.ee_link);
        }
        let _ = writeln!(t, "\n[start]\nq_deg = {}\n", fmt_list(&o.start_deg));
        let _ = writeln!(
            t,
            "[target]\nposition_m = {}\nquat_wxyz = {}\n",
            fmt_list(&target.position),
            fmt_list(&target.quat_wxyz)
        );
        let _ = writeln!(
            t,
            "[motion]\ntf_s = {}\ndt_s = {}\nn = 1\n\n[planner]\nseed = 1",
            ryu::Buffer::new().format(o.tf_s),
            ryu::Buffer::new().format(o.dt_s)
        );
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

/// The urdf path relative to the output directory, for tests.
pub fn urdf_relative(out: &Path, urdf: &Path) -> Result<String, CliError> {
    Ok(relative(out, urdf)?.to_string_lossy().replace('\\', "/"))
}
