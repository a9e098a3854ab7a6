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

use crate::args::{List, RobotArgs, parse_list};
use crate::error::CliError;
use crate::output::OutDir;
use crate::records::relative_text;
use crate::urdf::Chain;
use crate::with_dims;
use reactionless::TRUTH_SUBSTEPS;
use reactionless::random::{Purpose, Stream};
use reactionless::{IDENTITY_WXYZ, Motion, Pose, Task, TruthModel};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Write COUNT task files with reachable targets for a robot (random feasible η rolled
/// out from the start, truth-model end pose as target).
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
    let urdf_rel = relative_text(&o.out, &o.robot.urdf)?;
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
