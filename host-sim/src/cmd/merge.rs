//! `host-sim merge`: the shards of one `disperse` or `campaign` run put back together.
//!
//! The set is accepted only if it is every shard `1..=M` of one run exactly once (same
//! kind, run id, build and shard count; see `crate::shards`); otherwise nothing is
//! written. `runs.csv` is the shards' rows concatenated in shard order, byte for byte, so
//! it is what one machine writes (a campaign's `wall_time_s` column is the only value that
//! depends on the machine); the summaries are recomputed from the merged rows.

use crate::campaign_report::{Run, summary};
use crate::dispersion_report::{self as report, Report, Statistics};
use crate::error::{CliError, Context};
use crate::output::OutDir;
use crate::shards::{self, Manifest, split_header};
use std::path::{Path, PathBuf};

/// Combine the shards of one disperse or campaign run into what one machine writes.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The shards' output directories (any order).
    #[arg(required = true)]
    shards: Vec<PathBuf>,
    /// Output directory (replaced atomically).
    #[arg(long)]
    out: PathBuf,
}

fn read(dir: &Path, name: &str) -> Result<String, CliError> {
    std::fs::read_to_string(dir.join(name))
        .or_input(|| format!("{}: cannot read {name}", dir.display()))
}

/// The shards' `runs.csv` concatenated, as text and as the rows `parse` reads from each
/// shard's text (named by its origin), after checking that every shard has one header
/// and the rows its manifest promises.
fn concat<T>(
    set: &[(PathBuf, Manifest)],
    parse: impl Fn(&str, &str) -> Result<Vec<T>, CliError>,
) -> Result<(String, Vec<T>), CliError> {
    let mut out = String::new();
    let mut parsed = Vec::new();
    let mut head: Option<String> = None;
    for (dir, m) in set {
        let text = read(dir, "runs.csv")?;
        let (h, rows) = split_header(&text);
        match &head {
            None => {
                head = Some(h.to_string());
                out.push_str(h);
            }
            Some(first) if first != h => {
                return Err(CliError::input(format!(
                    "{}/runs.csv: its columns differ from the first shard's",
                    dir.display()
                )));
            }
            Some(_) => {}
        }
        let shard_rows = parse(&format!("{}/runs.csv", dir.display()), &text)?;
        let n = shard_rows.len();
        if n != m.end - m.first {
            return Err(CliError::input(format!(
                "{}/runs.csv has {n} rows, its manifest says {}",
                dir.display(),
                m.end - m.first
            )));
        }
        out.push_str(rows);
        parsed.extend(shard_rows);
    }
    Ok((out, parsed))
}

impl Args {
    /// Runs the subcommand.
    pub fn run(self) -> Result<(), CliError> {
        let set = shards::check_set(&self.shards)?;
        let (first_dir, first) = &set[0];
        let wall: f64 = set.iter().map(|(_, m)| m.wall_time_s).sum();
        let manifest = Manifest {
            shard: 1,
            shards: 1,
            first: 0,
            end: first.total,
            wall_time_s: wall,
            ..first.clone()
        };
        match first.kind.as_str() {
            "disperse" => {
                let (runs, rows) = concat(&set, report::read_figures)?;
                let figures: Vec<_> = rows.into_iter().map(|(_, f)| f).collect();
                let mut rep: Report = serde_json::from_str(&read(first_dir, "summary.json")?)
                    .or_input(|| format!("{}/summary.json", first_dir.display()))?;
                rep.rows = figures.len();
                rep.statistics = Statistics::of(&figures);
                if let Some(c) = rep.closed_loop.as_mut() {
                    let loops = report::read_loop_figures("runs.csv", &runs)?.ok_or_else(|| {
                        CliError::input(format!(
                            "{}/runs.csv: a closed-loop run without the closed-loop columns",
                            first_dir.display()
                        ))
                    })?;
                    c.statistics = report::LoopStatistics::of(&loops);
                }
                let out = OutDir::create(&self.out)?;
                out.write("runs.csv", runs.as_bytes())?;
                report::write_report(&out, &rep, first.plots, &figures)?;
                out.write_json(shards::MANIFEST, &manifest)?;
                let path = out.commit()?;
                eprintln!(
                    "merge: {} disperse shards, {} samples -> {}",
                    set.len(),
                    figures.len(),
                    path.display()
                );
            }
            "campaign" => {
                let parse = |origin: &str, text: &str| -> Result<Vec<Run>, CliError> {
                    csv::Reader::from_reader(text.as_bytes())
                        .deserialize()
                        .collect::<Result<_, _>>()
                        .or_input(|| origin.to_string())
                };
                let (runs_text, runs) = concat(&set, parse)?;
                let seeds: Vec<u64> = serde_json::from_value(first.context["seeds"].clone())
                    .or_input(|| {
                        format!(
                            "{}/{}: context.seeds",
                            first_dir.display(),
                            shards::MANIFEST
                        )
                    })?;
                let out = OutDir::create(&self.out)?;
                out.write("runs.csv", runs_text.as_bytes())?;
                out.write("summary.md", summary(&runs, &seeds).as_bytes())?;
                out.write_json(shards::MANIFEST, &manifest)?;
                let path = out.commit()?;
                eprintln!(
                    "merge: {} campaign shards, {} runs -> {}",
                    set.len(),
                    runs.len(),
                    path.display()
                );
            }
            other => {
                return Err(CliError::input(format!(
                    "{}: {}: unknown kind '{other}'",
                    first_dir.display(),
                    shards::MANIFEST
                )));
            }
        }
        Ok(())
    }
}
