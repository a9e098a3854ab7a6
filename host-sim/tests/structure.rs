//! The shape of host-sim that keeps it cheap to extend: subcommands are leaves, and every
//! planner setting names its task-file key.
//!
//! Requirements: RL-SIM-CLI, RL-SIM-TASK (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use host_sim::taskfile::DispersionSection;
use reactionless::{Error, Param, PlannerConfig};
use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

/// No `cmd/` file imports another: shared pieces live in named modules.
/// Verifies RL-SIM-CLI-007.
#[test]
fn subcommands_are_leaves() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/cmd");
    let mut leaves = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.file_name().unwrap() == "mod.rs" {
            continue;
        }
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            !text.contains("crate::cmd::") && !text.contains("super::"),
            "{} imports another subcommand",
            path.display()
        );
        assert!(
            text.contains("pub struct Args") && text.contains("pub fn run(self)"),
            "{} does not own its clap::Args",
            path.display()
        );
        leaves += 1;
    }
    assert!(leaves >= 11);
}

/// Every setting the planner validates names a key that the task file's `[planner]` table
/// really has (the serialized defaults), so errors point at the right key; the list below
/// holds every `Param` that `Param::key` puts under `planner.` (read from src/error.rs).
/// Verifies RL-SIM-TASK-004.
#[test]
fn every_planner_setting_has_a_task_key() {
    let table = toml::Value::try_from(PlannerConfig::default()).unwrap();
    let params = [
        Param::Particles,
        Param::MaxIterations,
        Param::C1,
        Param::C2,
        Param::WMax,
        Param::WMin,
        Param::Tolerance,
        Param::EtaBound,
        Param::StagnationWindow,
        Param::MinImprovement,
        Param::Eps1,
        Param::Eps2,
        Param::RefineTolerance,
        Param::RefineRollouts,
        Param::FrameBudget,
        Param::MaxRollouts,
    ];
    let error_rs =
        std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../src/error.rs"))
            .unwrap();
    let keyed: BTreeSet<String> = error_rs
        .lines()
        .filter(|l| l.contains("=> \"planner."))
        .map(|l| l.trim().strip_prefix("Param::").unwrap())
        .map(|l| l.split([' ', '(']).next().unwrap().to_string())
        .collect();
    let listed: BTreeSet<String> = params.iter().map(|p| format!("{p:?}")).collect();
    assert_eq!(listed, keyed, "the [planner] Params of Param::key");
    for p in params {
        let key = p.key().unwrap();
        let below = key.strip_prefix("planner.").unwrap();
        let mut v = &table;
        for part in below.split('.') {
            match v.get(part) {
                Some(x) => v = x,
                // refine_tolerance defaults to "none": absent from the serialized table.
                None if p == Param::RefineTolerance => break,
                None => panic!("{p:?}: no key {key} in {table}"),
            }
        }
        assert_eq!(Error::NotPositive(p).param(), Some(p));
    }
}

/// Every `[dispersion]` key is declared once, in `DispersionSection::KEYS`: the list holds
/// the task file's keys in table order, `disperse` has a flag of each key's name, and
/// docs/task-format.md a row with its unit. Verifies RL-SIM-DISP-005.
#[test]
fn every_dispersion_key_is_declared_once() {
    let names: Vec<&str> = DispersionSection::KEYS.iter().map(|k| k.name).collect();
    let table = toml::to_string(&DispersionSection::default()).unwrap();
    let fields: Vec<&str> = table
        .lines()
        .filter_map(|l| l.split(" = ").next())
        .collect();
    assert_eq!(fields, names, "the task file's keys");
    let cli = <host_sim::cli::Cli as clap::CommandFactory>::command();
    let disperse = cli.find_subcommand("disperse").unwrap();
    let docs = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/task-format.md"),
    )
    .unwrap();
    for key in DispersionSection::KEYS {
        let flag = disperse
            .get_arguments()
            .find(|a| a.get_id() == key.name)
            .unwrap_or_else(|| panic!("no flag for {}", key.name));
        assert_eq!(flag.get_long(), Some(key.long().as_str()));
        let row = format!("| `[dispersion] {}` | {}", key.name, key.unit);
        assert!(docs.contains(&row), "docs/task-format.md has no row {row}");
    }
    assert_eq!(docs.matches("| `[dispersion] ").count(), names.len());
}

/// host-sim's modules, as `use crate::` edges between them: `cmd/NAME.rs` is `cmd::NAME`,
/// every file of a directory module (`plots/`) is that module, and a file that imports
/// `crate::cmd` reaches `cmd::NAME` through `cmd::NAME::`. Comments are not imports.
fn module_imports() -> BTreeMap<String, BTreeSet<String>> {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    let mut dirs = vec![src.clone()];
    while let Some(dir) = dirs.pop() {
        for entry in std::fs::read_dir(&dir).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                dirs.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                files.push(path);
            }
        }
    }
    let module = |path: &Path| -> Option<String> {
        let rel = path.strip_prefix(&src).unwrap().with_extension("");
        let parts: Vec<&str> = rel.iter().map(|p| p.to_str().unwrap()).collect();
        match parts.as_slice() {
            ["lib" | "main"] => None,
            ["cmd", "mod"] => Some("cmd".into()),
            ["cmd", leaf] => Some(format!("cmd::{leaf}")),
            [top, ..] => Some((*top).to_string()),
            [] => None,
        }
    };
    let modules: BTreeSet<String> = files.iter().filter_map(|f| module(f)).collect();
    let ident = |s: &str| -> String {
        s.chars()
            .take_while(|c| c.is_ascii_alphanumeric() || *c == '_')
            .collect()
    };
    let mut edges = BTreeMap::new();
    for file in &files {
        let Some(from) = module(file) else { continue };
        let code: String = std::fs::read_to_string(file)
            .unwrap()
            .lines()
            .map(|l| l.split("//").next().unwrap())
            .collect::<Vec<_>>()
            .join("\n");
        let mut targets = BTreeSet::new();
        if code.contains("use crate::cmd;") {
            for rest in code.split("cmd::").skip(1) {
                targets.insert(format!("cmd::{}", ident(rest)));
            }
        }
        for rest in code.split("crate::").skip(1) {
            let top = ident(rest);
            let to = if top == "cmd" {
                let leaf = ident(rest.strip_prefix("cmd::").unwrap_or(""));
                format!("cmd::{leaf}")
            } else {
                top
            };
            targets.insert(to);
        }
        targets.retain(|t| *t != from && modules.contains(t));
        edges
            .entry(from)
            .or_insert_with(BTreeSet::new)
            .extend(targets);
    }
    edges
}

/// Data flows one way between host-sim's modules: the only import cycle is the command
/// line's, whose `completions` and `manpage` leaves generate their output from the parser
/// that lists them. Verifies RL-SIM-CLI-007.
#[test]
fn modules_import_without_cycles() {
    let edges = module_imports();
    // Every module reachable from `start`.
    let reach = |start: &str| {
        let mut seen = BTreeSet::new();
        let mut todo = vec![start.to_string()];
        while let Some(m) = todo.pop() {
            for n in edges.get(&m).into_iter().flatten() {
                if seen.insert(n.clone()) {
                    todo.push(n.clone());
                }
            }
        }
        seen
    };
    let mut cyclic = BTreeSet::new();
    for m in edges.keys() {
        if reach(m).contains(m) {
            cyclic.insert(m.clone());
        }
    }
    let allowed = ["cli", "cmd::completions", "cmd::manpage"];
    cyclic.retain(|m| !allowed.contains(&m.as_str()));
    assert!(
        cyclic.is_empty(),
        "modules on an import cycle: {cyclic:?}; edges: {edges:#?}"
    );
}
