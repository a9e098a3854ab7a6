//! The `host-sim` command line (see the library for what each subcommand does).

use clap::{Parser, Subcommand};
use host_sim::cmd;
use host_sim::error::CliError;
use std::path::PathBuf;
use std::process::ExitCode;

/// Host simulator for the reactionless planner.
#[derive(Debug, Parser)]
#[command(name = "host-sim", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// A comma-separated list of numbers (negative values allowed: `--q-deg -90,45,0`).
#[derive(Debug, Clone)]
struct List(Vec<f64>);

/// Seeds of a campaign.
type Seeds = Vec<u64>;

fn parse_list(s: &str) -> Result<List, String> {
    s.split(',')
        .map(|t| {
            let t = t.trim();
            t.parse::<f64>()
                .map_err(|_| format!("'{t}' is not a number (expected a comma-separated list)"))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(List)
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Model quantities at one configuration, as JSON on stdout: com, hb, hbm, rns_basis,
    /// jg, ee (base at the origin, identity attitude).
    Model {
        /// Robot description (URDF: serial chain of revolute joints, 4..=12).
        #[arg(long)]
        urdf: PathBuf,
        /// End-effector link (default: the only leaf link).
        #[arg(long)]
        ee: Option<String>,
        /// Joint angles (deg), comma-separated.
        #[arg(long, allow_hyphen_values = true, value_parser = parse_list)]
        q_deg: List,
    },
    /// Roll out one η of a task: writes DIR/trajectory.csv and DIR/summary.json.
    Rollout {
        /// Task file (TOML).
        task: PathBuf,
        /// η = a1,b1,...,aK,bK (K = N − 3), comma-separated.
        #[arg(long, allow_hyphen_values = true, value_parser = parse_list)]
        eta: List,
        /// Output directory (replaced atomically).
        #[arg(long)]
        out: PathBuf,
        /// Also write figures (PNG and SVG).
        #[arg(long)]
        plots: bool,
    },
    /// Plan a task with C-PSO (and refinement): writes DIR/plan.json, DIR/trajectory.csv,
    /// DIR/summary.json. Exit code 0 converged, 1 not converged, 2 bad input.
    Plan {
        /// Task file (TOML).
        task: PathBuf,
        /// Output directory (replaced atomically).
        #[arg(long)]
        out: PathBuf,
        /// Seed of the random stream (overrides the task's).
        #[arg(long)]
        seed: Option<u64>,
        /// Refine after C-PSO until f ≤ this (overrides the task's refine_tolerance).
        #[arg(long)]
        refine_tolerance: Option<f64>,
        /// Also write figures (PNG and SVG), convergence included.
        #[arg(long)]
        plots: bool,
    },
    /// Verify an output directory of `plan` or `rollout` independently: the trajectory as
    /// written against a fresh rollout, the integrator, every limit, the pose error and the
    /// base disturbance. Exit code 0 all pass, 1 a check failed, 2 unreadable.
    Check {
        /// Output directory of `plan` or `rollout`.
        dir: PathBuf,
    },
    /// Plan a task and write a certification record (task, URDF hash, build, outputs as bit
    /// patterns, trajectory digest) to REC.json.
    Record {
        /// Task file (TOML).
        task: PathBuf,
        /// Record file to write (replaced atomically).
        #[arg(long)]
        out: PathBuf,
        /// Seed (overrides the task's).
        #[arg(long)]
        seed: Option<u64>,
        /// Refinement tolerance (overrides the task's).
        #[arg(long)]
        refine_tolerance: Option<f64>,
    },
    /// Re-run a record and compare bit for bit; exit 1 naming the first difference.
    Replay {
        /// Record files.
        #[arg(required = true)]
        records: Vec<PathBuf>,
    },
    /// Write COUNT task files with reachable targets for a robot (random feasible η rolled
    /// out from the start, truth-model end pose as target).
    Generate {
        /// Robot description (URDF).
        #[arg(long)]
        urdf: PathBuf,
        /// End-effector link (default: the only leaf link).
        #[arg(long)]
        ee: Option<String>,
        /// Start configuration (deg), comma-separated.
        #[arg(long, allow_hyphen_values = true, value_parser = parse_list)]
        start_deg: List,
        /// Number of tasks.
        #[arg(long)]
        count: u32,
        /// Seed of the stream that draws η.
        #[arg(long)]
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
        /// Smallest end-effector displacement of a target from the start (m).
        #[arg(long, default_value_t = 0.2)]
        min_motion_m: f64,
        /// Half-width of the box η is drawn from.
        #[arg(long, default_value_t = 5.0)]
        eta_bound: f64,
    },
    /// Plan under a cyclic executive: at most FRAME_BUDGET integration steps per frame;
    /// report frames, steps per frame and wall time per frame.
    Frames {
        /// Task file (TOML).
        task: PathBuf,
        /// Integration steps per frame.
        #[arg(long)]
        frame_budget: u32,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Monte Carlo over tasks and seeds in parallel: DIR/runs.csv and DIR/summary.md.
    Campaign {
        /// Task files (TOML).
        #[arg(required = true)]
        tasks: Vec<PathBuf>,
        /// Seeds, inclusive range A..B.
        #[arg(long, value_parser = cmd::campaign::parse_seeds)]
        seeds: Seeds,
        /// Worker threads (default: one per core).
        #[arg(long)]
        jobs: Option<usize>,
        /// Output directory (replaced atomically).
        #[arg(long)]
        out: PathBuf,
    },
    /// Plan a task on the flight target (the Cortex-M7 image under QEMU) and compare bit for
    /// bit with the host; report instructions per step, per rollout and per call, stack,
    /// flash and static RAM. Exit 0 only when bit-identical and within budgets.
    Target {
        /// Task file (TOML) for the flight robot (7 joints).
        task: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        /// Use the image already built instead of building it first.
        #[arg(long)]
        no_build: bool,
        /// Give up on the emulation after this many seconds.
        #[arg(long, default_value_t = 1800)]
        timeout_s: u64,
    },
    /// Time the core on a task: one step, one rollout, and planning over seeds 1..10.
    Bench {
        /// Task file (TOML).
        task: PathBuf,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
}

fn run(cli: Cli) -> Result<(), CliError> {
    match cli.command {
        Command::Model { urdf, ee, q_deg } => cmd::model::run(&urdf, ee.as_deref(), &q_deg.0),
        Command::Rollout {
            task,
            eta,
            out,
            plots,
        } => cmd::rollout::run(&task, &eta.0, &out, plots),
        Command::Plan {
            task,
            out,
            seed,
            refine_tolerance,
            plots,
        } => cmd::plan::run(
            &task,
            &out,
            cmd::plan::PlanOptions {
                seed,
                refine: refine_tolerance,
                plots,
            },
        ),
        Command::Bench { task, json } => cmd::bench::run(&task, json),
        Command::Check { dir } => cmd::check::run(&dir),
        Command::Target {
            task,
            json,
            no_build,
            timeout_s,
        } => cmd::target::run(&task, json, !no_build, timeout_s),
        Command::Record {
            task,
            out,
            seed,
            refine_tolerance,
        } => cmd::record::record(&task, &out, seed, refine_tolerance),
        Command::Replay { records } => {
            // Every record is replayed; the first failure decides the exit code.
            let mut failed: Vec<CliError> = Vec::new();
            for r in &records {
                if let Err(e) = cmd::record::replay(r) {
                    eprintln!("error: {e}");
                    failed.push(e);
                }
            }
            match failed.first() {
                None => Ok(()),
                Some(e) => Err(CliError {
                    code: e.code,
                    message: format!(
                        "{} of {} records did not replay identically",
                        failed.len(),
                        records.len()
                    ),
                }),
            }
        }
        Command::Generate {
            urdf,
            ee,
            start_deg,
            count,
            seed,
            out,
            tf_s,
            dt_s,
            min_motion_m,
            eta_bound,
        } => cmd::generate::run(&cmd::generate::GenerateOptions {
            urdf,
            ee,
            start_deg: start_deg.0,
            count,
            seed,
            out,
            tf_s,
            dt_s,
            min_motion_m,
            eta_bound,
        }),
        Command::Frames {
            task,
            frame_budget,
            json,
        } => cmd::frames::run(&task, frame_budget, json),
        Command::Campaign {
            tasks,
            seeds,
            jobs,
            out,
        } => cmd::campaign::run(&tasks, &seeds, jobs, &out),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::from(e.code)
        }
    }
}
