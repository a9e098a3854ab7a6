//! `host-sim campaign`: Monte Carlo over tasks and seeds, in parallel.
//!
//! Every (task, seed) pair is planned with the task's settings and checked with the truth
//! model. Runs are spread over `--jobs` threads (rayon); each run is independent and
//! deterministic, so the table is the same for any number of jobs (wall times aside). Writes
//! `runs.csv` (one row per run, sorted by task then seed) and `summary.md` (per task and
//! overall: success rate, and median / p90 / max of iterations, rollouts, f, base
//! disturbance and wall time) atomically.

use crate::args::{GoalArgs, Strategies, parse_seeds, parse_strategies};
use crate::artifacts::write_rollout;
use crate::campaign_report::{Run, summary};
use crate::drive::{self, HOST_CAPACITY};
use crate::error::{CliError, Context};
use crate::goal::status_name;
use crate::output::OutDir;
use crate::shards::{self, Manifest, Shard, parse_shard};
use crate::taskfile::{self, LoadedTask, Overrides};
use crate::with_dims;
use rayon::prelude::*;
use reactionless::Strategy;
use std::path::{Path, PathBuf};

fn one<const N: usize, const K: usize>(
    lt: &LoadedTask,
    overrides: &Overrides,
) -> Result<Run, CliError> {
    let (config, asked) = lt.plan_settings(HOST_CAPACITY, overrides)?;
    if let Some(section) = &lt.file.preshape {
        let (p, truth, converged, seconds) =
            crate::preshaping::plan_in_memory::<N, K>(lt, section, &config, &asked)?;
        let o = p.outcome;
        let pick = |g: fn(&reactionless::Outcome<N>) -> f64| o.as_ref().map_or(f64::NAN, g);
        return Ok(Run {
            task: lt.path.display().to_string(),
            robot: lt.chain.name.clone(),
            strategy: "two-phase".to_string(),
            seed: config.seed,
            status: status_name(converged).to_string(),
            stop: p.stop.name().to_string(),
            asked: asked.describe(),
            iterations: p.starts,
            rollouts: p.rollouts,
            f: pick(|o| o.f),
            phi: pick(|o| o.phi),
            position_error_m: pick(|o| o.error.position_m()),
            orientation_error_deg: pick(|o| o.error.orientation_deg()),
            base_disturbance_deg: truth.as_ref().map_or(f64::NAN, |t| t.base_disturbance_deg),
            truth_f: truth.as_ref().map_or(f64::NAN, |t| t.f),
            sigma_e_met: o.is_some_and(|o| o.phi == 0.0 && o.f <= asked.sigma_e),
            clearance_m: None,
            wall_time_s: seconds,
        });
    }
    let task = lt.task::<N, K>()?;
    let done = drive::plan::<N, K>(lt, config, false)?;
    let p = done.plan;
    let truth = write_rollout(&task, &p.eta, None, false)?.truth;
    // The written path's clearance, where the task requires one: a run that reaches the
    // target but violates it is not a success.
    let scene = lt.scene(&lt.start_rad())?;
    let sweep = if scene.enforced && !scene.is_empty() {
        let (times, qs) = crate::clearance::path_of(&task, &p.eta)?;
        Some(scene.sweep(&times, &qs))
    } else {
        None
    };
    let status = match &sweep {
        Some(s) if p.converged() && !s.pass() => "collides",
        _ => status_name(p.converged()),
    };
    Ok(Run {
        task: lt.path.display().to_string(),
        robot: lt.chain.name.clone(),
        strategy: config.strategy.name().to_string(),
        seed: config.seed,
        status: status.to_string(),
        stop: p.stop.name().to_string(),
        asked: asked.describe(),
        iterations: p.iterations,
        rollouts: p.rollouts,
        f: p.outcome.f,
        phi: p.outcome.phi,
        position_error_m: p.outcome.error.position_m(),
        orientation_error_deg: p.outcome.error.orientation_deg(),
        base_disturbance_deg: truth.base_disturbance_deg,
        truth_f: truth.f,
        sigma_e_met: p.first_hit.is_some(),
        clearance_m: sweep.and_then(|s| s.worst().map(|w| w.min_m)),
        wall_time_s: done.seconds,
    })
}

/// Monte Carlo over tasks and seeds in parallel: DIR/runs.csv and DIR/summary.md.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Task files (TOML).
    #[arg(required = true)]
    tasks: Vec<PathBuf>,
    /// Seeds: `3`, `1,2,5` or `1..10` (inclusive).
    #[arg(long, value_parser = parse_seeds)]
    seeds: Seeds,
    /// Strategies to compare, comma-separated (default: each task's `[planner] strategy`).
    #[arg(long, value_parser = parse_strategies)]
    strategy: Option<Strategies>,
    #[command(flatten)]
    goal: GoalArgs,
    /// How rollouts integrate the path, for every task: euler, rk4 or ab5 (overrides `[motion]
    /// integrator`).
    #[arg(long, value_parser = crate::args::parse_integrator)]
    integrator: Option<reactionless::Integrator>,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = crate::args::parse_usize)]
    jobs: Option<usize>,
    /// Run only the I-th of M deterministic slices of the (task, strategy, seed) list
    /// (1-based); `host-sim merge` puts the shards back together.
    #[arg(long, value_parser = parse_shard, value_name = "I/M")]
    shard: Option<Shard>,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
}

/// A list of seeds.
type Seeds = Vec<u64>;

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let strategies: Vec<Option<Strategy>> = match &self.strategy {
            Some(list) => list.0.iter().copied().map(Some).collect(),
            None => vec![None],
        };
        let base = Overrides {
            integrator: self.integrator,
            ..self.goal.overrides()
        };
        run(
            &self.tasks,
            &self.seeds,
            &strategies,
            &base,
            self.jobs,
            self.shard.unwrap_or(Shard::WHOLE),
            &self.out,
        )
    }
}

fn run(
    tasks: &[PathBuf],
    seeds: &[u64],
    strategies: &[Option<Strategy>],
    base: &Overrides,
    jobs: Option<usize>,
    shard: Shard,
    out: &Path,
) -> Result<(), CliError> {
    let started = std::time::Instant::now();
    if tasks.is_empty() {
        return Err(CliError::input("campaign needs at least one task file"));
    }
    let loaded: Vec<LoadedTask> = tasks
        .iter()
        .map(|t| {
            let mut lt = taskfile::load(t)?;
            lt.set_integrator(base.integrator)?;
            Ok(lt)
        })
        .collect::<Result<_, CliError>>()?;
    // Validate every task and its planner settings before anything runs.
    for lt in &loaded {
        for st in strategies {
            lt.planner(
                HOST_CAPACITY,
                &Overrides {
                    strategy: *st,
                    ..*base
                },
            )?;
        }
        with_dims!(lt.chain.dof(), validate, lt)?;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs.unwrap_or(0))
        .build()
        .or_input(|| "--jobs")?;
    let pairs: Vec<(&LoadedTask, Overrides)> = loaded
        .iter()
        .flat_map(|lt| {
            strategies.iter().flat_map(move |st| {
                seeds.iter().map(move |s| {
                    (
                        lt,
                        Overrides {
                            seed: Some(*s),
                            strategy: *st,
                            ..*base
                        },
                    )
                })
            })
        })
        .collect();
    let total = pairs.len();
    let range = shard.items(total, "runs")?;
    let pairs = &pairs[range.clone()];
    let bar = drive::Progress::new("campaign", pairs.len() as u64, "runs");
    let results: Vec<Result<Run, CliError>> = pool.install(|| {
        pairs
            .par_iter()
            .map(|(lt, overrides)| {
                let r = with_dims!(lt.chain.dof(), one, lt, overrides);
                bar.inc();
                r
            })
            .collect()
    });
    bar.finish();
    let runs: Vec<Run> = results.into_iter().collect::<Result<_, _>>()?;
    let dir = OutDir::create(out)?;
    let mut csv = csv::Writer::from_path(dir.path("runs.csv")).or_input(|| "runs.csv")?;
    for r in &runs {
        csv.serialize(r).or_input(|| "runs.csv")?;
    }
    csv.flush().or_input(|| "runs.csv")?;

    let md = summary(&runs, seeds);
    dir.write("summary.md", md.as_bytes())?;
    let mut id: Vec<Vec<u8>> = vec![b"campaign".to_vec()];
    for lt in &loaded {
        id.push(lt.path.display().to_string().into_bytes());
        id.push(lt.text.clone().into_bytes());
        id.push(lt.urdf_text.clone().into_bytes());
    }
    id.push(format!("{seeds:?} {strategies:?} {base:?}").into_bytes());
    let parts: Vec<&[u8]> = id.iter().map(Vec::as_slice).collect();
    dir.write_json(
        shards::MANIFEST,
        &Manifest {
            kind: "campaign".into(),
            run_id: shards::run_id(&parts),
            shard: shard.index,
            shards: shard.count,
            first: range.start,
            end: range.end,
            total,
            build: shards::build(),
            plots: false,
            context: serde_json::json!({ "seeds": seeds }),
            wall_time_s: started.elapsed().as_secs_f64(),
        },
    )?;
    let path = dir.commit()?;
    let ok = runs.iter().filter(|r| r.converged()).count();
    let part = if shard == Shard::WHOLE {
        String::new()
    } else {
        format!(
            " (shard {shard}: runs {}..{} of {total})",
            range.start, range.end
        )
    };
    eprintln!(
        "campaign: {ok} of {} runs converged{part} -> {}",
        runs.len(),
        path.display()
    );
    Ok(())
}

fn validate<const N: usize, const K: usize>(lt: &LoadedTask) -> Result<(), CliError> {
    lt.task::<N, K>().map(|_| ())
}
