//! Deterministic slices of a long run (`--shard I/M`) and the manifest that lets `merge`
//! put them back together.
//!
//! Owns [`Shard`] (parsed from `I/M`, 1-based: the I-th of M slices), its slice of a run's
//! items (`[⌊n(I−1)/M⌋, ⌊nI/M⌋)`: every item in exactly one shard, in order), the
//! [`Manifest`] every sharded subcommand writes (`manifest.json`: what ran, which slice,
//! the run's identity) and [`check_set`], which accepts a set of shard outputs only if
//! they are every shard `1..=M` of one run exactly once.

use crate::error::{CliError, Context};
use crate::version::Build;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The manifest's file name.
pub const MANIFEST: &str = "manifest.json";

/// Most shards one run may be cut into.
pub const MAX_SHARDS: usize = 100_000;

/// The I-th of M slices (1 ≤ I ≤ M).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Shard {
    /// 1-based index.
    pub index: usize,
    /// Number of shards.
    pub count: usize,
}

impl Shard {
    /// The whole run (shard 1 of 1).
    pub const WHOLE: Self = Self { index: 1, count: 1 };

    /// This shard's items of a run of `n`, or an error if it would hold none (more shards
    /// than items): an empty shard has no statistics and nothing to merge.
    pub fn items(&self, n: usize, what: &str) -> Result<Range<usize>, CliError> {
        if self.count > n {
            return Err(CliError::input(format!(
                "--shard {self}: {n} {what} cannot be cut into {} shards (at most {n})",
                self.count
            )));
        }
        Ok(self.range(n))
    }

    /// This shard's items of a run of `n`.
    pub fn range(&self, n: usize) -> Range<usize> {
        let at = |i: usize| {
            // n · i / M without overflow for any n and M ≤ MAX_SHARDS.
            ((n as u128 * i as u128) / self.count as u128) as usize
        };
        at(self.index - 1)..at(self.index)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Parses `I/M` (clap value parser).
pub fn parse_shard(s: &str) -> Result<Shard, String> {
    let bad = || format!("'{s}' is not a shard: expected I/M with 1 <= I <= M, e.g. 2/4");
    let (i, m) = s.split_once('/').ok_or_else(bad)?;
    let index: usize = i.trim().parse().map_err(|_| bad())?;
    let count: usize = m.trim().parse().map_err(|_| bad())?;
    if count == 0 || count > MAX_SHARDS {
        return Err(format!(
            "'{s}': the shard count must be in 1..={MAX_SHARDS}"
        ));
    }
    if index == 0 || index > count {
        return Err(format!(
            "'{s}': shard {index} does not exist, there are {count} (1..={count})"
        ));
    }
    Ok(Shard { index, count })
}

/// `manifest.json`: what a (sharded) run wrote.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// The subcommand: `disperse` or `campaign`.
    pub kind: String,
    /// SHA-256 of everything that decides the run's results (inputs and settings, not the
    /// shard): shards of one run share it.
    pub run_id: String,
    /// This shard (1-based).
    pub shard: usize,
    /// Shards of the run.
    pub shards: usize,
    /// First item of the run in this output (0-based).
    pub first: usize,
    /// One past the last item.
    pub end: usize,
    /// Items of the whole run.
    pub total: usize,
    /// The build that wrote it (`host-sim <version> (<git revision>)`).
    pub build: String,
    /// Whether figures were asked for.
    pub plots: bool,
    /// Kind-specific facts that `merge` needs to rebuild the summaries (campaign: seeds).
    pub context: serde_json::Value,
    /// Wall time of the run (s): the only figure that depends on the machine.
    pub wall_time_s: f64,
}

/// The manifest's `build`: this binary's [`Build::stamp`].
pub fn build() -> String {
    Build::current().stamp()
}

/// SHA-256 (hex) over `parts`, each prefixed by its length (so no two lists collide).
pub fn run_id(parts: &[&[u8]]) -> String {
    let mut h = Sha256::new();
    for p in parts {
        h.update((p.len() as u64).to_le_bytes());
        h.update(p);
    }
    h.finalize().iter().map(|b| format!("{b:02x}")).collect()
}

/// Reads `dir/manifest.json`.
pub fn read_manifest(dir: &Path) -> Result<Manifest, CliError> {
    let path = dir.join(MANIFEST);
    let text = std::fs::read_to_string(&path).or_input(|| {
        format!(
            "{}: cannot read {MANIFEST} (is it the --out of disperse or campaign?)",
            dir.display()
        )
    })?;
    serde_json::from_str(&text).or_input(|| path.display())
}

/// Reads the manifests of `dirs` and checks that they are every shard of one run exactly
/// once; returns them ordered by shard.
pub fn check_set(dirs: &[PathBuf]) -> Result<Vec<(PathBuf, Manifest)>, CliError> {
    let mut set: Vec<(PathBuf, Manifest)> = dirs
        .iter()
        .map(|d| read_manifest(d).map(|m| (d.clone(), m)))
        .collect::<Result<_, _>>()?;
    let Some((first_dir, first)) = set.first().cloned() else {
        return Err(CliError::input("merge needs at least one shard directory"));
    };
    for (d, m) in &set {
        let differs = |what: &str, a: &str, b: &str| {
            CliError::input(format!(
                "{} and {} are not shards of one run: {what} {a} vs {b}",
                first_dir.display(),
                d.display()
            ))
        };
        if m.kind != first.kind {
            return Err(differs("kind", &first.kind, &m.kind));
        }
        if m.run_id != first.run_id {
            return Err(differs("run id", &first.run_id, &m.run_id));
        }
        if m.shards != first.shards || m.total != first.total {
            return Err(differs(
                "shard count / items",
                &format!("{}/{}", first.shards, first.total),
                &format!("{}/{}", m.shards, m.total),
            ));
        }
        if m.build != first.build {
            return Err(differs("build", &first.build, &m.build));
        }
        let want = Shard {
            index: m.shard,
            count: m.shards,
        };
        if m.shard == 0 || m.shard > m.shards || want.range(m.total) != (m.first..m.end) {
            return Err(CliError::input(format!(
                "{}: {MANIFEST} is inconsistent (shard {}/{}, items {}..{} of {})",
                d.display(),
                m.shard,
                m.shards,
                m.first,
                m.end,
                m.total
            )));
        }
    }
    set.sort_by_key(|(_, m)| m.shard);
    for w in set.windows(2) {
        if w[0].1.shard == w[1].1.shard {
            return Err(CliError::input(format!(
                "shard {}/{} given twice: {} and {}",
                w[0].1.shard,
                w[0].1.shards,
                w[0].0.display(),
                w[1].0.display()
            )));
        }
    }
    let have: Vec<usize> = set.iter().map(|(_, m)| m.shard).collect();
    let missing: Vec<String> = (1..=first.shards)
        .filter(|i| !have.contains(i))
        .map(|i| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(CliError::input(format!(
            "shards missing from the set of {}: {}",
            first.shards,
            missing.join(", ")
        )));
    }
    Ok(set)
}

/// The data rows of a CSV file (everything after the header line, byte for byte) and its
/// header line.
pub fn split_header(text: &str) -> (&str, &str) {
    match text.find('\n') {
        Some(i) => text.split_at(i + 1),
        None => (text, ""),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every item is in exactly one shard, in order, for any n and M.
    /// Verifies RL-SIM-DISP-003.
    #[test]
    fn shards_cover_every_item_once() {
        for n in [0usize, 1, 5, 12, 1000] {
            for m in 1..=7 {
                let mut next = 0;
                for i in 1..=m {
                    let r = Shard { index: i, count: m }.range(n);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, n);
            }
        }
    }

    /// `I/M` parses; 0, I > M and garbage do not.
    /// Verifies RL-SIM-DISP-003.
    #[test]
    fn shard_syntax() {
        assert_eq!(parse_shard("2/3"), Ok(Shard { index: 2, count: 3 }));
        for bad in ["3/2", "0/2", "1/0", "a/b", "2", "1/2/3", "-1/2"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }
}
