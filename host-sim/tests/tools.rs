//! End-to-end tests of check, record/replay, plots, generate, frames, campaign and target,
//! failures included. Exit codes: 0 ok, 1 failed/not converged, 2 bad input.
//!
//! Requirements: RL-SIM-CLI, RL-SIM-TASK, RL-SIM-OUT, RL-SIM-CHK, RL-SIM-REC, RL-SIM-GEN,
//! RL-SIM-CAMP, RL-SIM-FRM, RL-SIM-PLOT, RL-FW, RL-BLOCK, RL-ROB, and through host-sim
//! RL-ROLL, RL-TRUTH, RL-PSO, RL-PLAN, RL-GOLD, RL-PROP, RL-CORE (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").unwrap()
}

/// A fast task: the 6-DOF test arm, converges in a few iterations.
/// `host-sim generate` of `urdf` (relative to the repository) from `q_deg`, end effector
/// `ee`, with `extra` flags, into `out`.
fn generate(urdf: &str, q_deg: &str, extra: &[&str], out: &Path) -> std::process::Output {
    let mut c = host_sim();
    c.args(["generate", "--urdf"])
        .arg(root().join(urdf))
        .args(["--ee", "ee", "--q-deg", q_deg])
        .args(extra)
        .arg("--out")
        .arg(out);
    c.output().unwrap()
}

fn arm6() -> PathBuf {
    root().join("tests/records/tasks/arm6/task_002.toml")
}

fn run(args: &[&str], paths: &[&Path]) -> (Option<i32>, String, String) {
    let mut c = host_sim();
    let mut p = paths.iter();
    for a in args {
        if *a == "{}" {
            c.arg(p.next().unwrap());
        } else {
            c.arg(a);
        }
    }
    let o = c.output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

// --- check -------------------------------------------------------------------------

/// `check` passes a plan (0), fails one edited digit naming row and column (1), rejects a
/// non-output (2).
/// Verifies RL-ROLL-001, RL-SIM-CLI-001, RL-SIM-OUT-003, RL-SIM-CHK-001, RL-SIM-CHK-002, RL-SIM-CHK-003.
#[test]
fn check_passes_a_plan_and_fails_a_hand_edited_trajectory() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    // 6 joints: the paper's σ_e (the pose goal stops at this truth-made target's floor).
    let (code, _, err) = run(&["plan", "{}", "--paper", "--out", "{}"], &[&arm6(), &out]);
    assert_eq!(code, Some(0), "{err}");
    let (code, table, err) = run(&["check", "{}"], &[&out]);
    assert_eq!(code, Some(0), "{table}{err}");
    assert!(
        table.contains("bit for bit") && !table.contains("FAIL"),
        "{table}"
    );
    for check in [
        "joint limits",
        "joint rates",
        "qd = 0",
        "pose error",
        "base disturbance",
    ] {
        assert!(table.contains(check), "table lacks {check}: {table}");
    }
    // Edit one digit of one value in the middle of the file.
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let row = &mut lines[1234];
    let comma = row.find(',').unwrap();
    let digit = row[comma + 1..]
        .find(|c: char| c.is_ascii_digit() && c != '0')
        .unwrap()
        + comma
        + 1;
    let d = row.as_bytes()[digit];
    row.replace_range(
        digit..=digit,
        &char::from(if d == b'9' { b'1' } else { d + 1 }).to_string(),
    );
    std::fs::write(out.join("trajectory.csv"), lines.join("\n") + "\n").unwrap();
    let (code, table, err) = run(&["check", "{}"], &[&out]);
    assert_eq!(code, Some(1), "{table}{err}");
    assert!(table.contains("row 1233, q1"), "{table}");
    assert!(err.contains("verification failed"), "{err}");
    // A directory that is not an output: bad input.
    let (code, _, err) = run(&["check", "{}"], &[tmp.path()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("task.toml"), "{err}");
}

/// A stricter `[check] max_base_disturbance_deg` in the bundle makes `check` fail the same
/// trajectory (exit 1).
/// Verifies RL-SIM-OUT-003, RL-SIM-CHK-004.
#[test]
fn check_fails_a_trajectory_that_breaks_a_limit_or_the_disturbance_threshold() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    assert_eq!(
        run(&["plan", "{}", "--paper", "--out", "{}"], &[&arm6(), &out]).0,
        Some(0)
    );
    // A stricter threshold in the bundled task: the same trajectory must now fail.
    let task = std::fs::read_to_string(out.join("task.toml")).unwrap();
    std::fs::write(
        out.join("task.toml"),
        format!("{task}\n[check]\nmax_base_disturbance_deg = 1e-9\n"),
    )
    .unwrap();
    let (code, table, _) = run(&["check", "{}"], &[&out]);
    assert_eq!(code, Some(1));
    assert!(
        table
            .lines()
            .any(|l| l.starts_with("base disturbance") && l.contains("FAIL")),
        "{table}"
    );
}

// --- record / replay -----------------------------------------------------------------

/// Every golden record in tests/records replays bit for bit, with the planner's lanes in
/// each build of the kernel forced in turn (the SSE2 baseline, and AVX2 where this CPU has
/// it; `REACTIONLESS_ISA`), and a bad `REACTIONLESS_ISA` is bad input.
/// Verifies RL-PSO-010, RL-PLAN-004, RL-CORE-008, RL-SIM-REC-003, RL-LANE-004.
#[test]
fn golden_records_replay_bit_for_bit() {
    let mut records: Vec<PathBuf> = std::fs::read_dir(root().join("tests/records"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json"))
        .collect();
    records.sort();
    assert!(records.len() >= 5, "{records:?}");
    let mut isas = vec!["auto", "sse2"];
    if reactionless_simd::Isa::Avx2.available() {
        isas.push("avx2");
    }
    for isa in isas {
        let mut c = host_sim();
        c.env("REACTIONLESS_ISA", isa).arg("replay").args(&records);
        let o = c.output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{isa}: {err}");
        assert_eq!(
            err.matches("identical").count(),
            records.len(),
            "{isa}: {err}"
        );
    }
    let o = host_sim()
        .env("REACTIONLESS_ISA", "avx512")
        .arg("replay")
        .args(&records)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("REACTIONLESS_ISA=avx512"));
}

/// `record` writes a record that replays; a changed η bit, digest or URDF is named (exit
/// 1), a non-record exits 2.
/// Verifies RL-SIM-CLI-001, RL-SIM-TASK-002, RL-SIM-REC-001, RL-SIM-REC-002.
#[test]
fn a_changed_record_or_robot_fails_replay_naming_the_quantity() {
    let tmp = tempfile::tempdir().unwrap();
    // Record a copy of the task whose URDF sits beside it, so the robot can be edited.
    std::fs::copy(
        root().join("tests/robots/arm6.urdf"),
        tmp.path().join("arm6.urdf"),
    )
    .unwrap();
    let task = std::fs::read_to_string(arm6())
        .unwrap()
        .replace("../../../robots/arm6.urdf", "arm6.urdf");
    std::fs::write(tmp.path().join("task.toml"), task).unwrap();
    let rec = tmp.path().join("rec.json");
    let (code, _, err) = run(
        &["record", "{}", "--out", "{}"],
        &[&tmp.path().join("task.toml"), &rec],
    );
    assert_eq!(code, Some(0), "{err}");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&rec).unwrap()).unwrap();
    assert_eq!(v["format"], "reactionless-record/1");
    assert_eq!(v["urdf_sha256"].as_str().unwrap().len(), 64);
    for key in ["crate_version", "git_revision", "target", "profile"] {
        assert!(v["build"][key].is_string(), "build.{key}");
    }
    assert!(
        v["outputs"]["trajectory_digest"]
            .as_str()
            .unwrap()
            .starts_with("0x")
    );
    assert_eq!(run(&["replay", "{}"], &[&rec]).0, Some(0));
    // One bit of eta[2].
    let mut bad = v.clone();
    let bits = bad["outputs"]["eta_bits"][2].as_str().unwrap().to_string();
    let flipped = format!("{:#018x}", u64::from_str_radix(&bits[2..], 16).unwrap() ^ 1);
    bad["outputs"]["eta_bits"][2] = Value::String(flipped);
    let bad_path = tmp.path().join("bad.json");
    std::fs::write(&bad_path, serde_json::to_string_pretty(&bad).unwrap()).unwrap();
    let (code, _, err) = run(&["replay", "{}"], &[&bad_path]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("mismatch in eta[2]"), "{err}");
    // The digest.
    let mut bad = v.clone();
    bad["outputs"]["trajectory_digest"] = Value::String("0x0000000000000000".into());
    std::fs::write(&bad_path, serde_json::to_string_pretty(&bad).unwrap()).unwrap();
    let (code, _, err) = run(&["replay", "{}"], &[&bad_path]);
    assert_eq!(code, Some(1));
    assert!(err.contains("mismatch in trajectory_digest"), "{err}");
    // The robot changed under the record.
    let urdf = std::fs::read_to_string(tmp.path().join("arm6.urdf")).unwrap();
    std::fs::write(
        tmp.path().join("arm6.urdf"),
        urdf.replacen("<mass value=\"40.0\"/>", "<mass value=\"41.0\"/>", 1),
    )
    .unwrap();
    let (code, _, err) = run(&["replay", "{}"], &[&rec]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("urdf_sha256"), "{err}");
    // Not a record.
    std::fs::write(&bad_path, "{}").unwrap();
    assert_eq!(run(&["replay", "{}"], &[&bad_path]).0, Some(2));
}

// --- plots --------------------------------------------------------------------------

/// `plan --plots` writes all five figures, `rollout --plots` all but convergence; the
/// rollout output checks.
/// Verifies RL-SIM-CHK-001, RL-SIM-PLOT-001.
#[test]
fn plots_on_plan_and_rollout() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    assert_eq!(
        run(
            &["plan", "{}", "--paper", "--plots", "--out", "{}"],
            &[&arm6(), &out]
        )
        .0,
        Some(0)
    );
    for f in [
        "joints",
        "joint_rates",
        "ee_path",
        "base_attitude",
        "convergence",
    ] {
        for ext in ["png", "svg"] {
            let p = out.join(format!("{f}.{ext}"));
            assert!(
                std::fs::metadata(&p).unwrap().len() > 1000,
                "{}",
                p.display()
            );
        }
    }
    let svg = std::fs::read_to_string(out.join("joints.svg")).unwrap();
    assert!(svg.contains("time (s)") && svg.contains("angle (deg)") && svg.contains("limits"));
    // rollout --plots: no convergence figure.
    let eta: Vec<String> = {
        let p: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
        p["eta"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.to_string())
            .collect()
    };
    let out2 = tmp.path().join("roll");
    let mut c = host_sim();
    c.arg("rollout")
        .arg(arm6())
        .arg(format!("--eta={}", eta.join(",")))
        .arg("--paper")
        .arg("--plots")
        .arg("--out")
        .arg(&out2);
    assert!(c.output().unwrap().status.success());
    assert!(out2.join("ee_path.png").exists() && !out2.join("convergence.png").exists());
    // And the rollout's output checks too.
    assert_eq!(run(&["check", "{}"], &[&out2]).0, Some(0));
}

// --- generate -----------------------------------------------------------------------

/// `generate` repeats itself; its targets are reached (truth_f < 1e-12) and planned; bad
/// input writes nothing.
/// Verifies RL-TRUTH-004, RL-PROP-001, RL-SIM-GEN-001, RL-SIM-GEN-002, RL-ROB-012.
#[test]
fn generate_writes_reachable_tasks_deterministically() {
    let tmp = tempfile::tempdir().unwrap();
    let make = |out: &Path| {
        generate(
            "tests/robots/arm6.urdf",
            "10,-20,30,-40,50,-60",
            &["--count", "3", "--seed", "11"],
            out,
        )
    };
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    assert!(make(&a).status.success());
    assert!(make(&b).status.success());
    for k in 1..=3 {
        let name = format!("task_{k:03}.toml");
        let ta = std::fs::read_to_string(a.join(&name)).unwrap();
        assert_eq!(
            ta,
            std::fs::read_to_string(b.join(&name)).unwrap(),
            "same arguments, same tasks"
        );
    }
    // The target is reachable: the generating eta (in the comment) reaches it with the
    // truth model, and the planner finds a plan for it against the truth model (a 6-joint
    // arm reaches a truth-made target only there).
    let out = tmp.path().join("plan");
    let (code, _, err) = run(
        &["plan", "{}", "--refine-against", "truth", "--out", "{}"],
        &[&a.join("task_001.toml"), &out],
    );
    assert_eq!(code, Some(0), "{err}");
    let text = std::fs::read_to_string(a.join("task_001.toml")).unwrap();
    let eta = text
        .split("eta = [")
        .nth(1)
        .unwrap()
        .split(']')
        .next()
        .unwrap()
        .replace(' ', "");
    let out2 = tmp.path().join("roll");
    let mut c = host_sim();
    c.arg("rollout")
        .arg(a.join("task_001.toml"))
        .arg(format!("--eta={eta}"))
        .arg("--out")
        .arg(&out2);
    assert!(c.output().unwrap().status.success());
    let s: Value =
        serde_json::from_str(&std::fs::read_to_string(out2.join("summary.json")).unwrap()).unwrap();
    assert!(
        s["truth_f"].as_f64().unwrap() < 1e-12,
        "truth_f {}",
        s["truth_f"]
    );
    // Bad inputs write nothing.
    let bad = tmp.path().join("bad");
    let o = generate(
        "tests/robots/arm6.urdf",
        "10,-20,30,-40,50,-600",
        &["--count", "2", "--seed", "1"],
        &bad,
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("outside the limits of joint 'j6'"));
    assert!(!bad.exists());
}

/// `generate --family free_amplitude` writes `[motion] family` (and nothing else changes:
/// the same targets as without it), and the task plans with that family.
/// Verifies RL-SIM-TWO-005.
#[test]
fn generate_writes_the_family_it_is_asked_for() {
    let tmp = tempfile::tempdir().unwrap();
    let make = |out: &Path, family: &[&str]| {
        let mut extra = vec!["--count", "1", "--seed", "3", "--kind", "perturbed"];
        extra.extend_from_slice(family);
        assert!(
            generate(
                "tests/robots/arm9.urdf",
                "10,-20,30,-40,50,-60,15,-25,35",
                &extra,
                out
            )
            .status
            .success()
        );
        std::fs::read_to_string(out.join("task_001.toml")).unwrap()
    };
    let paper = make(&tmp.path().join("p"), &[]);
    let free = make(&tmp.path().join("f"), &["--family", "free_amplitude"]);
    assert!(!paper.contains("family"));
    let line = free.lines().find(|l| l.starts_with("family")).unwrap();
    assert!(line.starts_with("family = \"free_amplitude\""), "{line}");
    let without: String = free
        .lines()
        .filter(|l| !l.starts_with("family"))
        .map(|l| format!("{l}\n"))
        .collect();
    assert_eq!(without, paper);
    let out = tmp.path().join("plan");
    let (code, _, err) = run(
        &["plan", "{}", "--paper", "--out", "{}"],
        &[&tmp.path().join("f/task_001.toml"), &out],
    );
    assert_eq!(code, Some(0), "{err}");
    let bundle = std::fs::read_to_string(out.join("task.toml")).unwrap();
    assert!(bundle.contains("free_amplitude"));
}

// --- frames -------------------------------------------------------------------------

/// `frames --frame-budget 2000 --json` stays within 2000 steps per frame and converges;
/// budget 0 exits 2.
/// Verifies RL-PLAN-001, RL-SIM-FRM-001.
#[test]
fn frames_respects_the_budget_and_reports_json() {
    let (code, out, err) = run(
        &[
            "frames",
            "{}",
            "--paper",
            "--frame-budget",
            "2000",
            "--json",
        ],
        &[&arm6()],
    );
    assert_eq!(code, Some(0), "{err}");
    let v: Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(v["converged"], true);
    assert!(v["max_steps_per_frame"].as_u64().unwrap() <= 2000);
    assert!(v["frames"].as_u64().unwrap() > 10);
    assert!(v["mean_steps_per_frame"].as_f64().unwrap() > 1000.0);
    let (code, _, err) = run(&["frames", "{}", "--frame-budget", "0"], &[&arm6()]);
    assert_eq!(code, Some(2), "{err}");
}

// --- campaign -----------------------------------------------------------------------

/// `campaign` writes the same runs.csv (wall time aside) on 1 and 2 jobs, and a summary; an
/// empty seed range exits 2.
/// Verifies RL-SIM-CLI-008, RL-SIM-CAMP-001.
#[test]
fn campaign_is_the_same_for_any_number_of_jobs() {
    let tmp = tempfile::tempdir().unwrap();
    let go = |jobs: &str, out: &Path| {
        let mut c = host_sim();
        c.arg("campaign")
            .arg(arm6())
            .arg(root().join("tests/records/tasks/arm6/task_001.toml"));
        c.args(["--seeds", "1..3", "--jobs", jobs, "--out"])
            .arg(out);
        c.output().unwrap()
    };
    let (a, b) = (tmp.path().join("a"), tmp.path().join("b"));
    assert!(go("1", &a).status.success());
    assert!(go("2", &b).status.success());
    let strip = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p.join("runs.csv"))
            .unwrap()
            .lines()
            .map(|l| l.rsplit_once(',').unwrap().0.to_string())
            .collect()
    };
    let rows = strip(&a);
    assert_eq!(rows.len(), 1 + 6);
    assert_eq!(rows, strip(&b), "everything but wall time is deterministic");
    let md = std::fs::read_to_string(a.join("summary.md")).unwrap();
    assert!(
        md.contains("| iterations |") && md.contains("all tasks") && md.contains("converged"),
        "{md}"
    );
    let (code, _, err) = run(
        &["campaign", "{}", "--seeds", "5..1", "--out", "{}"],
        &[&arm6(), &tmp.path().join("c")],
    );
    assert_eq!(code, Some(2), "{err}");
}

/// A task path with a comma is quoted in runs.csv: the row reads back with every column and
/// the path as given.
/// Verifies RL-SIM-CAMP-003.
#[test]
fn campaign_quotes_a_task_path_with_a_comma() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("tasks, v2");
    std::fs::create_dir(&dir).unwrap();
    let urdf = root().join("tests/robots/arm6.urdf");
    let text = std::fs::read_to_string(arm6())
        .unwrap()
        .replace("../../../robots/arm6.urdf", &urdf.display().to_string());
    let task = dir.join("task.toml");
    std::fs::write(&task, text).unwrap();
    let out = tmp.path().join("out");
    let (code, _, err) = run(
        &["campaign", "{}", "--seeds", "1", "--out", "{}"],
        &[&task, &out],
    );
    assert_eq!(code, Some(0), "{err}");
    let mut rows = csv::Reader::from_path(out.join("runs.csv")).unwrap();
    let headers = rows.headers().unwrap().clone();
    let records: Vec<csv::StringRecord> = rows.records().map(Result::unwrap).collect();
    assert_eq!(records.len(), 1);
    assert_eq!(records[0].len(), headers.len());
    assert_eq!(&records[0][0], task.display().to_string());
}

// --- target (the QEMU run itself is in .ci/run; here what needs no emulator) -------------

/// `target` refuses a 6-joint task for the 7-joint image, naming both counts (exit 2).
/// Verifies RL-FW-007.
#[test]
fn target_rejects_a_robot_the_flight_image_is_not_built_for() {
    let (code, _, err) = run(&["target", "{}", "--no-build"], &[&arm6()]);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("built for 7 joints; this robot has 6"),
        "{err}"
    );
}

/// paper.toml's task block decodes to CHASER7, q₀ and the defaults; `load_into` builds the
/// task host-sim builds.
/// Verifies RL-PLAN-007, RL-GOLD-006, RL-CORE-010, RL-BLOCK-001, RL-BLOCK-005, RL-SIM-TASK-003.
#[test]
fn task_blocks_round_trip_through_the_core() {
    // What host-sim sends to the target decodes to the same task, bit for bit.
    let lt = host_sim::taskfile::load(&root().join("spec/tasks/paper.toml")).unwrap();
    let bytes =
        host_sim::cmd::target::task_block(&lt, &host_sim::taskfile::Overrides::default()).unwrap();
    let block = reactionless::block::decode::<7>(&bytes).unwrap();
    assert_eq!(block.robot, reactionless::CHASER7);
    assert_eq!(
        block.q0,
        reactionless::reference::Q0_DEG.map(f64::to_radians)
    );
    assert_eq!(block.planner.frame_budget, 3000);
    assert_eq!(block.planner.seed, 1);
    let mut planner: Box<reactionless::Planner<7, 4, 64>> = Box::new(reactionless::Planner::IDLE);
    block.load_into(&mut planner).unwrap();
    let direct = lt.task::<7, 4>().unwrap();
    assert_eq!(
        planner.task(),
        &direct,
        "load_into builds the task host-sim builds"
    );
}
