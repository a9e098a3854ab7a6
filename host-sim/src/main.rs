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
        Command::Rollout { task, eta, out } => cmd::rollout::run(&task, &eta.0, &out),
        Command::Plan {
            task,
            out,
            seed,
            refine_tolerance,
        } => cmd::plan::run(&task, &out, seed, refine_tolerance),
        Command::Bench { task, json } => cmd::bench::run(&task, json),
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
