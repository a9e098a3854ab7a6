//! The README's five-minute tour, run as written: every `host-sim` command of its shell
//! block (with `out/` moved to a temporary directory) must succeed, and every bundle the
//! tour writes must pass `host-sim check`. `host-sim target` (it needs QEMU) is not in the
//! block, and `export` lines are the reader's set-up.
//!
//! Requirements: RL-SIM-CLI (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The commands of the tour's shell block, continuation lines joined, comments dropped.
fn tour_commands() -> Vec<String> {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let tour = readme
        .split("## A five-minute tour")
        .nth(1)
        .expect("the README has a tour")
        .split("\n## ")
        .next()
        .unwrap();
    let block = tour
        .split("```sh\n")
        .nth(1)
        .expect("the tour has a sh block")
        .split("```")
        .next()
        .unwrap();
    let mut commands = Vec::new();
    let mut current = String::new();
    for line in block.lines() {
        let code = match line.find("  #") {
            Some(i) => &line[..i],
            None => line,
        }
        .trim_end();
        let (code, more) = match code.strip_suffix('\\') {
            Some(c) => (c, true),
            None => (code, false),
        };
        current.push_str(code.trim_start());
        current.push(' ');
        if !more {
            let c = current.trim().to_string();
            if !c.is_empty() {
                commands.push(c);
            }
            current.clear();
        }
    }
    commands
}

/// Every directory under `dir` that holds a plan's or re-timing's bundle.
fn bundles(dir: &Path, out: &mut Vec<PathBuf>) {
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            if p.join("task.toml").exists() && p.join("trajectory.csv").exists() {
                out.push(p.clone());
            }
            bundles(&p, out);
        }
    }
}

/// Every command of the README's tour succeeds, and every bundle it writes passes `check`.
/// Verifies RL-SIM-CLI-010.
#[test]
fn the_readme_tour_runs_and_every_bundle_checks() {
    let tmp = tempfile::tempdir().unwrap();
    let bin = PathBuf::from(env!("CARGO_BIN_EXE_host-sim"));
    let path = format!(
        "{}:{}",
        bin.parent().unwrap().display(),
        std::env::var("PATH").unwrap_or_default()
    );
    let out = tmp.path().join("out");
    let commands = tour_commands();
    assert!(commands.len() >= 10, "{commands:?}");
    let mut ran = 0;
    for c in &commands {
        if c.starts_with("export ") {
            continue;
        }
        assert!(c.starts_with("host-sim "), "not a host-sim command: {c}");
        let c = c.replace("out/", &format!("{}/", out.display()));
        std::fs::create_dir_all(&out).unwrap();
        let o = Command::new("sh")
            .arg("-c")
            .arg(&c)
            .current_dir(root())
            .env("PATH", &path)
            .output()
            .unwrap();
        assert!(
            o.status.success(),
            "{c}: {}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
        ran += 1;
    }
    let mut found = Vec::new();
    bundles(&out, &mut found);
    assert!(found.len() >= 5, "{found:?}");
    for b in &found {
        let o = Command::new(&bin).arg("check").arg(b).output().unwrap();
        assert!(
            o.status.success(),
            "check {}: {}{}",
            b.display(),
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        );
    }
    println!("{ran} tour commands, {} bundles checked", found.len());
}
