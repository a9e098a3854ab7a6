//! Command-line values shared by several subcommands, parsed one way everywhere.
//!
//! Owns [`List`] (comma-separated numbers, negative values allowed), [`parse_seeds`] (`3`,
//! `1,2,5`, `1..10`), [`RobotArgs`] (`--urdf`, `--ee`), [`GoalArgs`] (what a plan must
//! reach) and [`PlanArgs`] (with the seed and the strategy: the flags of every subcommand
//! that plans one run), both turned into [`Overrides`] of the task file, and the η helpers [`parse_eta`] / [`eta_error`], which
//! name the `--eta` flag in their messages.

use crate::error::CliError;
use crate::taskfile::Overrides;
use crate::urdf::{self, Chain};
use reactionless::{
    Error as CoreError, Eta, Family, Integrator, Param, RefineAgainst, Strategy, eta_from_flat,
};
use std::path::PathBuf;

/// A comma-separated list of numbers (negative values allowed: `--q-deg -90,45,0`).
#[derive(Debug, Clone, PartialEq)]
pub struct List(pub Vec<f64>);

/// Parses a [`List`] (clap value parser).
pub fn parse_list(s: &str) -> Result<List, String> {
    s.split(',')
        .map(|t| {
            let t = t.trim();
            t.parse::<f64>()
                .map_err(|_| format!("'{t}' is not a number (expected a comma-separated list)"))
        })
        .collect::<Result<Vec<_>, _>>()
        .map(List)
}

/// Parses a whole number of type `T` for an integer flag (clap value parser), saying what
/// is expected when it is not one: `'-1' is not a whole number from 0 to 4294967295`.
fn whole<T: std::str::FromStr + std::fmt::Display>(
    s: &str,
    max: T,
    what: &str,
) -> Result<T, String> {
    s.trim()
        .parse::<T>()
        .map_err(|_| format!("'{s}' is not {what}: a whole number from 0 to {max}"))
}

/// A seed (clap value parser): a whole number from 0 to 2⁶⁴ − 1.
pub fn parse_seed(s: &str) -> Result<u64, String> {
    whole(s, u64::MAX, "a seed")
}

/// A count or size that fits a `u32` (clap value parser).
pub fn parse_u32(s: &str) -> Result<u32, String> {
    whole(s, u32::MAX, "a count")
}

/// A count that fits a `u64` (clap value parser).
pub fn parse_u64(s: &str) -> Result<u64, String> {
    whole(s, u64::MAX, "a count")
}

/// A count that fits a `usize` (clap value parser).
pub fn parse_usize(s: &str) -> Result<usize, String> {
    whole(s, usize::MAX, "a count")
}

/// Most seeds one list may name.
const MAX_SEEDS: u64 = 1_000_000;

/// Parses a seed list (clap value parser): comma-separated items, each a seed `3` or an
/// inclusive range `1..10` (also `1..=10`). Seeds keep their order; a repeat is an error.
pub fn parse_seeds(s: &str) -> Result<Vec<u64>, String> {
    let seed = |t: &str| {
        t.trim().parse::<u64>().map_err(|_| {
            format!(
                "'{}' is not a seed (expected e.g. 3, 1,2,5 or 1..10)",
                t.trim()
            )
        })
    };
    let mut out: Vec<u64> = Vec::new();
    for item in s.split(',') {
        match item.split_once("..") {
            Some((a, b)) => {
                let (a, b) = (seed(a)?, seed(b.trim_start_matches('='))?);
                if b < a {
                    return Err(format!("empty range {a}..{b}"));
                }
                if b - a >= MAX_SEEDS || out.len() as u64 + (b - a) >= MAX_SEEDS {
                    return Err(format!("'{s}' names more than {MAX_SEEDS} seeds"));
                }
                out.extend(a..=b);
            }
            None => out.push(seed(item)?),
        }
    }
    let mut sorted = out.clone();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!("seed {} appears twice in '{s}'", w[0]));
    }
    Ok(out)
}

/// The robot of the subcommands that take a URDF directly (`model`, `generate`).
#[derive(Debug, Clone, clap::Args)]
pub struct RobotArgs {
    /// Robot description (URDF: serial chain of revolute joints, 4..=12).
    #[arg(long)]
    pub urdf: PathBuf,
    /// End-effector link (default: the only leaf link).
    #[arg(long)]
    pub ee: Option<String>,
}

impl RobotArgs {
    /// Reads the chain.
    pub fn load(&self) -> Result<Chain, CliError> {
        urdf::load(&self.urdf, self.ee.as_deref())
    }
}

/// The flags that say what a plan must reach: they override the task file's `[planner]`
/// refinement settings and `[target] goal` (every subcommand that plans; `campaign` too).
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct GoalArgs {
    /// Refine until f ≤ this (overrides `[planner] refine_tolerance`; with the pose goal,
    /// the tighter of this and the pose tolerances is used).
    #[arg(long, allow_negative_numbers = true)]
    pub refine_tolerance: Option<f64>,
    /// What refinement drives below the refinement tolerance: planner (f) or truth
    /// (truth_f, the base drift included) (overrides `[planner] refine_against`).
    #[arg(long, value_parser = parse_refine_against)]
    pub refine_against: Option<RefineAgainst>,
    /// The paper's success test, f ≤ σ_e (`[planner] tolerance`), instead of the pose
    /// tolerances (as `[target] goal = "sigma_e"`, and the task's pose tolerances are
    /// ignored); --refine-tolerance still refines below it.
    #[arg(long)]
    pub paper: bool,
}

impl GoalArgs {
    /// The overrides these flags make.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            refine_tolerance: self.refine_tolerance,
            refine_against: self.refine_against,
            paper: self.paper,
            ..Overrides::default()
        }
    }
}

/// The flags of every subcommand that plans one run: the seed, the strategy and the goal.
#[derive(Debug, Clone, Copy, Default, clap::Args)]
pub struct PlanArgs {
    /// Seed of the random stream (overrides `[planner] seed`).
    #[arg(long, value_parser = parse_seed)]
    pub seed: Option<u64>,
    /// Search strategy: multistart or cpso (overrides `[planner] strategy`).
    #[arg(long, value_parser = parse_strategy)]
    pub strategy: Option<Strategy>,
    /// What the plan must reach.
    #[command(flatten)]
    pub goal: GoalArgs,
    /// How rollouts integrate the path: euler (the reference), rk4 or ab5 (overrides `[motion]
    /// integrator`; the written bundle's task says which).
    #[arg(long, value_parser = parse_integrator)]
    pub integrator: Option<Integrator>,
}

impl PlanArgs {
    /// The overrides these flags make.
    pub fn overrides(&self) -> Overrides {
        Overrides {
            seed: self.seed,
            strategy: self.strategy,
            integrator: self.integrator,
            ..self.goal.overrides()
        }
    }
}

/// Parses an integrator name (clap value parser).
pub fn parse_integrator(s: &str) -> Result<Integrator, String> {
    Integrator::from_name(s.trim())
        .ok_or_else(|| format!("'{s}' is not an integrator (expected euler, rk4 or ab5)"))
}

/// Parses a strategy name (clap value parser).
pub fn parse_strategy(s: &str) -> Result<Strategy, String> {
    Strategy::from_name(s.trim())
        .ok_or_else(|| format!("'{s}' is not a strategy (expected multistart or cpso)"))
}

/// Parses a motion family name (clap value parser).
pub fn parse_family(s: &str) -> Result<Family, String> {
    Family::from_name(s.trim())
        .ok_or_else(|| format!("'{s}' is not a motion family (expected paper or free_amplitude)"))
}

/// A comma-separated list of strategies.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Strategies(pub Vec<Strategy>);

/// Parses a comma-separated list of strategies (clap value parser); no repeats.
pub fn parse_strategies(s: &str) -> Result<Strategies, String> {
    let list: Vec<Strategy> = s.split(',').map(parse_strategy).collect::<Result<_, _>>()?;
    for (i, a) in list.iter().enumerate() {
        if list.iter().skip(i + 1).any(|b| b == a) {
            return Err(format!("strategy {} appears twice in '{s}'", a.name()));
        }
    }
    Ok(Strategies(list))
}

/// Parses `planner` or `truth` (clap value parser).
pub fn parse_refine_against(s: &str) -> Result<RefineAgainst, String> {
    RefineAgainst::from_name(s.trim())
        .ok_or_else(|| format!("'{s}' is not a refinement target (expected planner or truth)"))
}

/// η from `--eta` as pairs, every problem named.
/// η of a motion of `segments` segments from its flat form (`2K·segments` values,
/// [`reactionless::eta_flat`]).
///
/// # Errors
/// The wrong number of values, named with what the task needs.
pub fn parse_eta<const K: usize>(eta: &[f64], segments: u32) -> Result<Eta<K>, CliError> {
    eta_from_flat::<K>(eta, segments).map_err(|_| {
        let per = if segments == 1 {
            String::new()
        } else {
            format!(
                " per segment, {} for its {segments} segments",
                2 * K * segments as usize
            )
        };
        CliError::input(format!(
            "--eta has {} values; this task needs 2K = {}{per} (a1,b1,...,a{K},b{K})",
            eta.len(),
            2 * K
        ))
    })
}

/// The error for an η the core rejects, naming `--eta`.
pub fn eta_error(e: CoreError) -> CliError {
    match e {
        CoreError::NotFinite(Param::Eta(i)) => {
            CliError::input(format!("--eta component {i} is not a finite number"))
        }
        CoreError::EtaZero => CliError::input("--eta is all zeros: no motion is defined"),
        CoreError::EtaTooLarge => CliError::input(
            "--eta is so large that g of eq. 14 overflows; only its direction matters: scale it down",
        ),
        other => CliError::input(format!("--eta: {other}")),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// Seed lists: seeds, comma lists and inclusive ranges (`1..10`, `1..=3`); empty, bad,
    /// repeated or huge ones named.
    /// Verifies RL-SIM-CLI-008.
    #[test]
    fn seed_lists_take_single_seeds_lists_and_ranges() {
        assert_eq!(parse_seeds("3"), Ok(vec![3]));
        assert_eq!(parse_seeds("1,2,5"), Ok(vec![1, 2, 5]));
        assert_eq!(parse_seeds("1..10"), Ok((1..=10).collect()));
        assert_eq!(parse_seeds("1..=3,7"), Ok(vec![1, 2, 3, 7]));
        assert!(parse_seeds("5..1").unwrap_err().contains("empty range"));
        assert!(
            parse_seeds("1,x")
                .unwrap_err()
                .contains("'x' is not a seed")
        );
        assert!(parse_seeds("1..3,2").unwrap_err().contains("twice"));
        assert!(parse_seeds("0..2000000").unwrap_err().contains("more than"));
    }
}
