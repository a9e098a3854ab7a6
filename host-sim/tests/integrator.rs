//! The RK4 discretization through the command line (issue #32): chosen in the task or with
//! `--integrator`, written into the bundle, planned and checked; a bad step is refused.
//! Requirements: RL-CONT (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn host_sim(args: &[&std::ffi::OsStr]) -> (Option<i32>, String, String) {
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

macro_rules! args {
    ($($a:expr),*) => { &[$(std::ffi::OsStr::new($a)),*] };
}

/// The reference task with `extra` lines added to `[motion]` (its URDF made absolute).
fn paper_with(dir: &Path, extra: &str) -> PathBuf {
    let text = std::fs::read_to_string(root().join("spec/tasks/paper.toml")).unwrap();
    let urdf = root().join("spec/chaser7.urdf");
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with("urdf = ") {
            out.push_str(&format!("urdf = {:?}\n", urdf.display().to_string()));
        } else {
            out.push_str(line);
            out.push('\n');
            if line.starts_with("[motion]") {
                out.push_str(extra);
                out.push('\n');
            }
        }
    }
    let path = dir.join("task.toml");
    std::fs::write(&path, out).unwrap();
    path
}

/// An RK4 task plans, its bundle says rk4, `check` passes it (rows to rounding, the fresh
/// RK4 rollout bit for bit), and its flown base disturbance is far below Euler's 7.3e-4°;
/// `--integrator rk4` on the Euler task gives the same files.
/// Verifies RL-CONT-006.
#[test]
fn an_rk4_task_plans_and_checks() {
    let (tmp, plan) = plans_and_checks("rk4", "0.4");

    let flagged = tmp.path().join("q");
    let (code, _, err) = host_sim(args!(
        "plan",
        &root().join("spec/tasks/paper.toml"),
        "--integrator",
        "rk4",
        "--out",
        &flagged
    ));
    assert_eq!(code, Some(0), "{err}");
    let again: Value =
        serde_json::from_str(&std::fs::read_to_string(flagged.join("plan.json")).unwrap()).unwrap();
    assert_eq!(again["eta"], plan["eta"]);
    let bundle = std::fs::read_to_string(flagged.join("task.toml")).unwrap();
    assert!(bundle.contains("integrator = \"rk4\""), "{bundle}");
    let (code, table, _) = host_sim(args!("check", &flagged));
    assert_eq!(code, Some(0), "{table}");
}

/// `integrator` set in the reference task: it plans (the summary saying the step), the
/// bundle says it, `check` passes, the flown base disturbance is ≤ 1e-5°. Returns the
/// directory and the plan.
fn plans_and_checks(integrator: &str, step: &str) -> (tempfile::TempDir, Value) {
    let tmp = tempfile::tempdir().unwrap();
    let task = paper_with(tmp.path(), &format!("integrator = \"{integrator}\""));
    let out = tmp.path().join("p");
    let (code, _, err) = host_sim(args!("plan", &task, "--out", &out));
    assert_eq!(code, Some(0), "{err}");
    assert!(
        err.contains(&format!("({integrator}, step {step} s)")),
        "{err}"
    );
    let bundle = std::fs::read_to_string(out.join("task.toml")).unwrap();
    assert!(
        bundle.contains(&format!("integrator = \"{integrator}\"")),
        "{bundle}"
    );
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    let (code, table, err) = host_sim(args!("check", &out));
    assert_eq!(code, Some(0), "{table}{err}");
    assert!(table.contains("rows follow q' = q + dt*qd"), "{table}");
    assert!(
        table.contains("matches a fresh rollout of eta                  bit for bit"),
        "{table}"
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let disturbance = summary["base_disturbance_deg"].as_f64().unwrap();
    assert!(disturbance <= 1e-5, "{disturbance}");
    (tmp, plan)
}

/// The same for AB5 (step 0.2 s).
/// Verifies RL-CONT-010.
#[test]
fn an_ab5_task_plans_and_checks() {
    plans_and_checks("ab5", "0.2");
}

/// A step that is not a whole divisor, a step without rk4, and an unknown integrator are
/// refused with exit 2, the key named, nothing written.
/// Verifies RL-CONT-005, RL-CONT-006.
#[test]
fn a_bad_integrator_step_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    for (extra, says) in [
        (
            "integrator = \"rk4\"\nintegrator_step_s = 0.07",
            "[motion] integrator_step_s = 0.07: 7 steps of dt_s do not divide",
        ),
        (
            "integrator = \"rk4\"\nintegrator_step_s = 0.015",
            "must be a whole multiple of dt_s",
        ),
        (
            "integrator_step_s = 0.4",
            "only with integrator = \"rk4\" or \"ab5\"",
        ),
        ("integrator = \"rk5\"", "rk5"),
    ] {
        let task = paper_with(tmp.path(), extra);
        let out = tmp.path().join("never");
        let (code, _, err) = host_sim(args!("plan", &task, "--out", &out));
        assert_eq!(code, Some(2), "{extra}: {err}");
        assert!(err.contains(says), "{extra}: {err}");
        assert!(!out.exists());
    }
    let (code, _, err) = host_sim(args!(
        "plan",
        &root().join("spec/tasks/paper.toml"),
        "--integrator",
        "heun",
        "--out",
        &tmp.path().join("never")
    ));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("expected euler, rk4 or ab5"), "{err}");
}

/// `generate --integrator rk4` writes tasks whose targets are RK4's truth poses and that
/// say `integrator = "rk4"`; such a task plans to its goal (the truth model refined).
/// Verifies RL-CONT-006.
#[test]
fn generate_makes_rk4_tasks() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("set");
    let (code, _, err) = host_sim(args!(
        "generate",
        "--urdf",
        &root().join("spec/chaser7.urdf"),
        "--ee",
        "ee",
        "--q-deg=-60,30,20,60,-100,-60,20",
        "--count",
        "1",
        "--seed",
        "101",
        "--integrator",
        "rk4",
        "--out",
        &dir
    ));
    assert_eq!(code, Some(0), "{err}");
    let task = dir.join("task_001.toml");
    let text = std::fs::read_to_string(&task).unwrap();
    assert!(text.contains("integrator = \"rk4\""), "{text}");
    let out = tmp.path().join("p");
    let (code, _, err) = host_sim(args!(
        "plan",
        &task,
        "--refine-tolerance",
        "1e-9",
        "--refine-against",
        "truth",
        "--out",
        &out
    ));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("(rk4, step 0.4 s)"), "{err}");
}
