//! End-to-end tests of the `host-sim` binary (model, rollout, plan, bench): outputs,
//! argument forms, exit codes, and nothing written on bad input.
//!
//! Requirements: RL-SIM-CLI, RL-SIM-TASK, RL-SIM-OUT, RL-SIM-BENCH, RL-ROB, and through
//! host-sim RL-MOM, RL-RNS, RL-LAW, RL-TRUTH, RL-PSO, RL-PLAN, RL-REF, RL-GOLD, RL-CORE
//! (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use serde_json::Value;
use std::path::{Path, PathBuf};

const ETA_HAT: &str = "3.14771,0.809316,1.12249,0.754006,4.7352,0.406031,-4.1572,4.29895";
const Q0: &str = "-90,45,0,80,-90,-45,-10";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").unwrap()
}

fn paper() -> PathBuf {
    root().join("spec/tasks/paper.toml")
}

/// A copy of paper.toml with `edit` applied, in `dir` (URDF path made absolute).
fn task_with(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let text = std::fs::read_to_string(paper()).unwrap();
    let urdf = root().join("spec/chaser7.urdf");
    let text = text.replace(
        "\"../chaser7.urdf\"",
        &format!("{:?}", urdf.display().to_string()),
    );
    let path = dir.join("task.toml");
    std::fs::write(&path, edit(text)).unwrap();
    path
}

/// `model` at q₀ prints one JSON object with the spec §8 values, for `--q-deg -90,…` and
/// `--q-deg=-90,…`.
/// Verifies RL-MOM-004, RL-RNS-002, RL-GOLD-001, RL-SIM-CLI-002, RL-SIM-CLI-003.
#[test]
fn model_prints_the_spec_golden_values_with_both_list_syntaxes() {
    for args in [vec!["--q-deg", Q0], vec![&*format!("--q-deg={Q0}")]] {
        let out = host_sim()
            .args(["model", "--urdf"])
            .arg(root().join("spec/chaser7.urdf"))
            .args(&args)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: Value = serde_json::from_slice(&out.stdout).unwrap();
        let row1: Vec<f64> = v["hbm"][0]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!((row1[0] - 64.21266294418797).abs() < 1e-9);
        assert!((row1[6] + 0.00146008723562147).abs() < 1e-9);
        assert!((v["hb"][2][2].as_f64().unwrap() - 831.1288323973174).abs() < 1e-9);
        assert_eq!(v["hbm"].as_array().unwrap().len(), 3);
        assert_eq!(v["hbm"][0].as_array().unwrap().len(), 7);
        assert_eq!(v["rns_basis"].as_array().unwrap().len(), 7);
        assert_eq!(v["rns_basis"][0].as_array().unwrap().len(), 4);
        assert_eq!(v["jg"].as_array().unwrap().len(), 6);
        assert_eq!(v["com"].as_array().unwrap().len(), 3);
        assert!((v["ee"]["position"][0].as_f64().unwrap() - 1.411848994172882).abs() < 1e-12);
        assert_eq!(v["ee"]["quat_wxyz"].as_array().unwrap().len(), 4);
        assert!((v["hbm_condition"].as_f64().unwrap() - 16.4).abs() < 0.05);
    }
}

/// A token that is not a number, a list of the wrong length and a missing URDF: named, exit
/// 2.
/// Verifies RL-SIM-CLI-002, RL-ROB-010.
#[test]
fn model_rejects_bad_lists_with_exit_code_2() {
    let urdf = root().join("spec/chaser7.urdf");
    let out = host_sim()
        .args(["model", "--urdf"])
        .arg(&urdf)
        .args(["--q-deg", "-90,abc"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("'abc' is not a number"));
    let out = host_sim()
        .args(["model", "--urdf"])
        .arg(&urdf)
        .args(["--q-deg", "1,2,3"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("has 3 values; the robot has 7 joints"));
    let out = host_sim()
        .args(["model", "--urdf", "/nonexistent.urdf", "--q-deg", "0"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("/nonexistent.urdf"));
}

fn floats(line: &str) -> Vec<f64> {
    line.split(',').map(|x| x.parse().unwrap()).collect()
}

/// `rollout` of η̂ writes the core's bits to trajectory.csv and the spec §8 values to
/// summary.json; reruns replace it.
/// Verifies RL-LAW-002, RL-TRUTH-002, RL-TRUTH-004, RL-GOLD-002, RL-GOLD-004, RL-GOLD-005, RL-GOLD-006, RL-CORE-010, RL-SIM-CLI-004, RL-SIM-OUT-001, RL-SIM-OUT-002.
#[test]
fn rollout_writes_trajectory_and_summary() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("paper");
    host_sim()
        .arg("rollout")
        .arg(paper())
        .args(["--eta", ETA_HAT, "--out"])
        .arg(&out)
        .assert()
        .success();
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(
        lines[0],
        "t,q1,q2,q3,q4,q5,q6,q7,qd1,qd2,qd3,qd4,qd5,qd6,qd7"
    );
    assert_eq!(lines.len(), 1 + 3001);
    let first = floats(lines[1]);
    let last = floats(lines[3001]);
    assert_eq!(first[0], 0.0);
    assert_eq!(last[0], 30.0);
    assert!(
        first[8..].iter().chain(&last[8..]).all(|v| *v == 0.0),
        "q̇ = 0 at both ends"
    );
    // The CSV is the core's output to the bit (shortest round-trip printing).
    let task = {
        use reactionless::{CHASER7, Motion, Pose, Robot, Task};
        let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
        let t = Pose {
            position: [0.0; 3],
            quat_wxyz: [1.0, 0.0, 0.0, 0.0],
        };
        Task::<7, 4>::new(
            Robot::new(&CHASER7).unwrap(),
            q0,
            t,
            Motion::new(30.0, 0.01, 1).unwrap(),
        )
        .unwrap()
    };
    let eta = [
        [3.14771, 0.809316],
        [1.12249, 0.754006],
        [4.7352, 0.406031],
        [-4.1572, 4.29895],
    ];
    let mut row = 1;
    task.rollout(&eta, &mut |s: &reactionless::Sample<7>| {
        let v = floats(lines[row]);
        let want: Vec<f64> = std::iter::once(s.t).chain(s.q).chain(s.qd).collect();
        assert_eq!(
            v.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            want.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            "row {row}"
        );
        row += 1;
    })
    .unwrap();
    let s: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for key in [
        "q_final",
        "end_pose",
        "f",
        "phi",
        "joint_min",
        "joint_max",
        "max_abs_qdot",
        "g",
        "base_disturbance_deg",
    ] {
        assert!(s.get(key).is_some(), "summary.json lacks {key}");
    }
    assert!((s["f"].as_f64().unwrap() - 3.27e-5).abs() < 0.01e-5);
    assert_eq!(s["phi"].as_f64().unwrap(), 0.0);
    assert!((s["g"].as_f64().unwrap() / 520546.2259291871 - 1.0).abs() < 1e-9);
    let d = s["base_disturbance_deg"].as_f64().unwrap();
    assert!((d / 7.27e-4 - 1.0).abs() < 0.01, "{d}");
    assert!(s["truth_f"].as_f64().unwrap() < 1e-6);
    // A second run replaces the directory (it carries host-sim's marker).
    host_sim()
        .arg("rollout")
        .arg(paper())
        .args([&format!("--eta={ETA_HAT}"), "--out"])
        .arg(&out)
        .assert()
        .success();
}

/// Runs `rollout` on a task edited by `edit`; expects exit 2, a message containing every
/// string in `want`, and no output directory.
fn rejects(edit: impl Fn(String) -> String, eta: &str, want: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), edit);
    let out = tmp.path().join("out");
    let o = host_sim()
        .arg("rollout")
        .arg(&task)
        .args([&format!("--eta={eta}"), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for w in want {
        assert!(err.contains(w), "message {err:?} lacks {w:?}");
    }
    assert!(err.contains("task.toml") || err.contains("--eta"), "{err}");
    assert!(!out.exists(), "output created on bad input");
    let leftovers: Vec<_> = std::fs::read_dir(tmp.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "stray files: {leftovers:?}");
}

/// Every bad task-file value, key, URDF or `--eta` is one message naming it, exit 2,
/// nothing written.
/// Verifies RL-LAW-006, RL-LAW-007, RL-SIM-CLI-001, RL-SIM-TASK-001, RL-SIM-OUT-001, RL-ROB-004, RL-ROB-009, RL-ROB-010, RL-ROB-011, RL-ROB-012.
#[test]
fn bad_task_files_are_named_and_write_nothing() {
    let id = |s: String| s;
    rejects(
        |s| s.replace("tf_s = 30.0", "tf_s = 30.0\nspeed = 3"),
        ETA_HAT,
        &["speed"],
    );
    rejects(
        |s| s.replace("dt_s = 0.01", "dt_s = \"fast\""),
        ETA_HAT,
        &["dt_s"],
    );
    rejects(
        |s| s.replace("dt_s = 0.01", "dt_s = 0.007"),
        ETA_HAT,
        &["tf_s = 30", "dt_s = 0.007", "whole multiple"],
    );
    rejects(
        |s| s.replace("dt_s = 0.01", "dt_s = -0.01"),
        ETA_HAT,
        &["dt_s = -0.01"],
    );
    rejects(
        |s| s.replace("dt_s = 0.01", "dt_s = 0.01\nfamily = \"fast\""),
        ETA_HAT,
        &["family", "paper", "free_amplitude"],
    );
    rejects(
        |s| s.replace("tf_s = 30.0", "tf_s = nan"),
        ETA_HAT,
        &["tf_s = NaN"],
    );
    rejects(
        |s| s.replace("dt_s = 0.01", "dt_s = 0.01\nsegments = 2"),
        ETA_HAT,
        &["[motion] segments = 2", "free_amplitude"],
    );
    rejects(
        |s| {
            s.replace(
                "dt_s = 0.01",
                "dt_s = 0.01\nfamily = \"free_amplitude\"\nsegments = 7",
            )
        },
        ETA_HAT,
        &["[motion] segments = 7", "capacity of 4"],
    );
    rejects(
        |s| {
            s.replace(
                "dt_s = 0.01",
                "dt_s = 0.01\nfamily = \"free_amplitude\"\nsegments = 4",
            )
        },
        ETA_HAT,
        &["--eta has 8 values", "32 for its 4 segments"],
    );
    rejects(
        |s| s.replace("-90.0, 45.0, 0.0, 80.0", "-90.0, 45.0, 80.0"),
        ETA_HAT,
        &["[start] q_deg has 6 values, expected 7"],
    );
    rejects(
        |s| s.replace("45.0, 0.0, 80.0", "45.0, 0.0, 120.0"),
        ETA_HAT,
        &["q_deg[3] = 120", "joint 'j4'"],
    );
    rejects(
        |s| s.replace("45.0, 0.0, 80.0", "45.0, inf, 80.0"),
        ETA_HAT,
        &["q_deg[2] = inf"],
    );
    rejects(
        |s| s.replace("0.3874560731031927,", "0.5,"),
        ETA_HAT,
        &["quat_wxyz", "norm"],
    );
    rejects(
        |s| s.replace("urdf = \"", "urdf = \"/missing"),
        ETA_HAT,
        &["[robot] urdf", "cannot read URDF"],
    );
    rejects(
        |s| s.replace("ee_link = \"ee\"", "ee_link = \"hand\""),
        ETA_HAT,
        &["'hand'"],
    );
    rejects(
        |s| s.replace("[motion]", "[motion\n"),
        ETA_HAT,
        &["task.toml"],
    );
    rejects(
        |s| s.replace("tf_s = 30.0", "tf_s = 0.0"),
        ETA_HAT,
        &["[motion] tf_s = 0"],
    );
    rejects(
        |s| s.replace("n = 1 ", "n = 0 "),
        ETA_HAT,
        &["[motion] n = 0"],
    );
    rejects(
        |s| s.replace("tf_s = 30.0", "tf_s = 1e9"),
        ETA_HAT,
        &["exceeds the maximum of 1000000 steps"],
    );
    rejects(
        |s| {
            s.replace("quat_wxyz = [0.3874560731031927, 0.2654610699800615, -0.37163840872581944, 0.8008077827420479]", "quat_wxyz = [0.0, 0.0, 0.0, 0.0]")
        },
        ETA_HAT,
        &["quat_wxyz", "norm 0"],
    );
    rejects(
        |s| {
            s.replace(
                "position_m = [2.0166710746921925, 0.13996636886034725, -1.43192511932475]",
                "position_m = [2.0, 0.1]",
            )
        },
        ETA_HAT,
        &["[target] position_m has 2 values, expected 3"],
    );
    rejects(
        |s| s.replace("[start]", "[start]\nextra = 1"),
        ETA_HAT,
        &["extra"],
    );
    rejects(id, "1,2,3", &["--eta has 3 values", "2K = 8"]);
    rejects(id, "0,0,0,0,0,0,0,0", &["all zeros"]);
}

/// A `[check] max_base_disturbance_deg` that is not a finite number > 0 (zero, negative,
/// NaN, ∞) is named with its value, exit code 2, and nothing is written.
/// Verifies RL-SIM-OUT-001, RL-ROB-015.
#[test]
fn a_bad_disturbance_threshold_is_named_and_writes_nothing() {
    for (value, shown) in [
        ("0.0", "= 0 "),
        ("-0.01", "= -0.01 "),
        ("nan", "= NaN "),
        ("inf", "= inf "),
    ] {
        rejects(
            |s| format!("{s}\n[check]\nmax_base_disturbance_deg = {value}\n"),
            ETA_HAT,
            &[
                &format!("[check] max_base_disturbance_deg {shown}"),
                "must be a finite number > 0",
            ],
        );
    }
}

/// An `--out` directory without host-sim's marker is refused (exit 2) and left as it was.
/// Verifies RL-SIM-OUT-001.
#[test]
fn a_foreign_output_directory_is_never_replaced() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("mine");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), "keep me").unwrap();
    let o = host_sim()
        .arg("rollout")
        .arg(paper())
        .args([&format!("--eta={ETA_HAT}"), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("not written by host-sim"));
    assert_eq!(
        std::fs::read_to_string(out.join("notes.txt")).unwrap(),
        "keep me"
    );
}

// --- plan and bench -------------------------------------------------------------------

fn read_json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// `plan --seed 2 --refine-tolerance 1e-6` converges, refines, writes plan.json and the
/// plan's trajectory; one report line.
/// Verifies RL-PSO-007, RL-PLAN-004, RL-PLAN-005, RL-PLAN-008, RL-REF-001, RL-REF-004, RL-GOLD-007, RL-SIM-CLI-005, RL-SIM-CLI-006.
#[test]
fn plan_converges_writes_everything_and_refines() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let o = host_sim()
        .arg("plan")
        .arg(paper())
        .args([
            "--seed",
            "2",
            "--refine-tolerance",
            "1e-6",
            "--strategy",
            "cpso",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    // Not a terminal: no progress bar, just the summary, which names what was asked and
    // the base disturbance against its requirement.
    assert!(!err.contains('\r') && !err.contains('\u{1b}'), "{err:?}");
    assert!(
        err.starts_with(
            "plan: converged; asked position ≤ 1e-6 m, orientation ≤ 1e-4 deg (planner model)"
        ),
        "{err}"
    );
    assert!(
        err.contains("requirement ≤ 0.01 deg: ok") && err.contains("position error"),
        "{err}"
    );
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["status"], "converged");
    assert_eq!(p["seed"], 2);
    for key in [
        "eta",
        "f",
        "phi",
        "position_error_m",
        "orientation_error_deg",
        "iterations",
        "rollouts",
        "abandoned_rollouts",
        "integration_steps",
        "stagnation_events",
        "seed",
        "best_f_history",
    ] {
        assert!(p.get(key).is_some(), "plan.json lacks {key}");
    }
    // Finished rollouts cost 3000 steps each, abandoned ones fewer (seed 2 abandons some).
    // host-sim plans in 4 lanes: candidates integrated ahead that the search then no longer
    // asks for (at most L − 1 = 3 when the search ends, and again when the refinement ends)
    // count in the integration steps but not in the rollouts.
    let rollouts = p["rollouts"].as_u64().unwrap();
    let abandoned = p["abandoned_rollouts"].as_u64().unwrap();
    let steps = p["integration_steps"].as_u64().unwrap();
    assert!(
        abandoned > 0 && abandoned < rollouts,
        "{abandoned} of {rollouts}"
    );
    assert!(
        steps > (rollouts - abandoned) * 3000 && steps < (rollouts + 6) * 3000,
        "{steps}"
    );
    assert_eq!(p["eta"].as_array().unwrap().len(), 8);
    assert!(p["f"].as_f64().unwrap() <= 1e-6);
    assert_eq!(p["phi"].as_f64().unwrap(), 0.0);
    assert!(p["search_f"].as_f64().unwrap() <= 0.05);
    assert_eq!(p["refine"]["stop"], "reached");
    let history = p["best_f_history"].as_array().unwrap();
    // One entry per completed generation (0..iterations), then the successful f.
    assert_eq!(history.len() as u64, p["iterations"].as_u64().unwrap() + 1);
    assert_eq!(history.last().unwrap(), &p["search_f"]);
    // The trajectory and summary are the plan's.
    let s = read_json(&out.join("summary.json"));
    assert_eq!(s["eta"], p["eta"]);
    assert_eq!(s["f"], p["f"]);
    assert!(s["base_disturbance_deg"].as_f64().unwrap() < 0.01);
    let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    assert_eq!(csv.lines().count(), 3002);
}

/// A plan that cannot converge within m_max = 1 exits 1 and still writes plan.json (80
/// rollouts).
/// Verifies RL-PSO-008, RL-SIM-CLI-001, RL-SIM-CLI-005.
#[test]
fn plan_that_does_not_converge_exits_1_and_still_reports() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), |s| {
        s.replace("max_iterations = 200", "max_iterations = 1")
            .replace("tolerance = 0.05", "tolerance = 1e-9")
    });
    let out = tmp.path().join("out");
    let o = host_sim()
        .arg("plan")
        .arg(&task)
        .args(["--strategy", "cpso", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(String::from_utf8_lossy(&o.stderr).contains("not converged"));
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["status"], "not_converged");
    assert_eq!(p["strategy"], "cpso");
    assert_eq!(p["iterations"], 1);
    assert_eq!(p["rollouts"], 80);
}

/// The default strategy is the multistart; it refines to the asked tolerance as it
/// searches, and reports the strategy, its restarts and the first hit of σ_e.
/// Verifies RL-PLAN-009, RL-PLAN-010.
#[test]
fn plan_with_the_default_strategy_refines_to_the_asked_tolerance() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let o = host_sim()
        .arg("plan")
        .arg(paper())
        .args(["--seed", "2", "--refine-tolerance", "1e-9", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["strategy"], "multistart");
    assert_eq!(p["status"], "converged");
    assert!(p["f"].as_f64().unwrap() <= 1e-9);
    assert_eq!(p["refine"]["stop"], "reached");
    let hit = p["first_hit_rollouts"].as_u64().unwrap();
    assert!(hit <= p["rollouts"].as_u64().unwrap());
    assert!(p["restarts"].is_u64());
}

/// With no flags, `plan` aims at the pose: the reference plan ends within the default
/// 1e-6 m and 1e-4°, and says so; `--paper` asks for σ_e only.
/// Verifies RL-SIM-TASK-005, RL-PLAN-011.
#[test]
fn plan_is_accurate_by_default() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let o = host_sim()
        .arg("plan")
        .arg(paper())
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.starts_with(
            "plan: converged; asked position ≤ 1e-6 m, orientation ≤ 1e-4 deg (planner model)"
        ),
        "{err}"
    );
    let p = read_json(&out.join("plan.json"));
    assert!(p["position_error_m"].as_f64().unwrap() <= 1e-6);
    assert!(p["orientation_error_deg"].as_f64().unwrap() <= 1e-4);
    assert_eq!(p["stop"], "converged");
    let o = host_sim()
        .arg("plan")
        .arg(paper())
        .args(["--paper", "--out"])
        .arg(tmp.path().join("paper"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.starts_with("plan: converged; asked f ≤ σ_e = 0.05 (the paper's test)"),
        "{err}"
    );
}

/// A plan that meets σ_e but not the tolerance asked for is not converged: it exits 1,
/// says what it reached against what was asked, and a campaign counts it as a miss.
/// Verifies RL-PLAN-011.
#[test]
fn a_plan_that_misses_the_asked_tolerance_is_not_converged() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), |s| {
        s.replace("tolerance = 0.05", "tolerance = 0.05\nmax_rollouts = 150")
    });
    let out = tmp.path().join("out");
    let o = host_sim()
        .arg("plan")
        .arg(&task)
        .args(["--refine-tolerance", "1e-18", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("NOT converged: the budget was spent first"),
        "{err}"
    );
    assert!(
        err.contains("f ≤ 1e-18") && err.contains("σ_e = 0.05 was met"),
        "{err}"
    );
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["status"], "not_converged");
    assert_eq!(p["stop"], "exhausted");
    assert!(p["first_hit_rollouts"].is_u64());
    let camp = tmp.path().join("camp");
    let o = host_sim()
        .arg("campaign")
        .arg(&task)
        .args(["--seeds", "1", "--refine-tolerance", "1e-18", "--out"])
        .arg(&camp)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("campaign: 0 of 1 runs converged"), "{err}");
    let csv = std::fs::read_to_string(camp.join("runs.csv")).unwrap();
    assert!(csv.contains(",not_converged,"), "{csv}");
}

/// `host-sim plan` of the repository's task file `task` (a path from the root) into `out`.
fn plan_into(task: &str, out: &Path) -> std::process::Output {
    host_sim()
        .arg("plan")
        .arg(root().join(task))
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// A 6-joint arm reaches a target the truth model made only to the planner model's floor
/// (5 unknowns for 6 pose equations): the default goal stops there after a few starts,
/// reports the plan as stalled and names the floor and the way to reach the target.
/// Verifies RL-PLAN-013.
#[test]
fn a_six_joint_arm_reports_its_floor() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let o = plan_into("tests/records/tasks/arm6/task_002.toml", &out);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("is this target's floor on the planner model"),
        "{err}"
    );
    assert!(err.contains("--refine-against truth"), "{err}");
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["stop"], "stalled");
    assert_eq!(p["refine"]["stop"], "stalled");
    assert!(p["rollouts"].as_u64().unwrap() < 1000, "{}", p["rollouts"]);
}

/// The refinement against the truth model reaches truth_f ≤ 1e-9 well within its budget on
/// two set-B chaser7 targets where it used to spend its 1,000 rollouts and stop at 5e-6
/// and 1e-8 (issue #28): task_006 (λ bounced by decades between a rejected value and an
/// over-damped one) and task_009 (λ held at a floor far above the weakest σ²/μ), seed 1.
/// Verifies RL-REF-006.
#[test]
fn truth_refinement_reaches_1e_9_on_thin_targets() {
    let tmp = tempfile::tempdir().unwrap();
    for task in ["task_006", "task_009"] {
        let out = tmp.path().join(task);
        let o = host_sim()
            .arg("plan")
            .arg(root().join(format!("tests/tasks/b/chaser7/{task}.toml")))
            .args(["--seed", "1", "--refine-tolerance", "1e-9"])
            .args(["--refine-against", "truth", "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{task}: {err}");
        let p = read_json(&out.join("plan.json"));
        assert_eq!(p["refine"]["stop"], "reached", "{task}");
        assert!(p["truth_f"].as_f64().unwrap() <= 1e-9, "{task}");
        assert!(p["refine"]["rollouts"].as_u64().unwrap() <= 500, "{task}");
    }
}

/// Bad input is refused before any search, with exit 2 and the key or flag named: a path
/// of 3 steps (`dt_s = 10`, a user thinking in milliseconds), a target 100 m away, a
/// negative acceleration limit that `plan` does not even use, a negative refinement
/// tolerance after a space, and a negative seed.
/// Verifies RL-SIM-TASK-006, RL-SIM-CLI-011.
#[test]
fn bad_inputs_are_refused_before_any_search() {
    let tmp = tempfile::tempdir().unwrap();
    let far = task_with(tmp.path(), |s| {
        let start = s.find("position_m = [").unwrap();
        let end = start + s[start..].find(']').unwrap() + 1;
        format!("{}position_m = [100.0, 0.0, 0.0]{}", &s[..start], &s[end..])
    });
    let far_path = tmp.path().join("far.toml");
    std::fs::rename(&far, &far_path).unwrap();
    let coarse = task_with(tmp.path(), |s| s.replace("dt_s = 0.01", "dt_s = 10.0"));
    let coarse_path = tmp.path().join("coarse.toml");
    std::fs::rename(&coarse, &coarse_path).unwrap();
    let limits = task_with(tmp.path(), |s| {
        format!("{s}\n[limits]\nqdd_max_deg_s2 = -5\n")
    });
    let task = paper();
    let out = tmp.path().join("out");
    let cases: [(Vec<&std::ffi::OsStr>, &str); 5] = [
        (
            vec![coarse_path.as_os_str()],
            "[motion] dt_s = 10 gives tf_s / dt_s = 3 steps",
        ),
        (vec![far_path.as_os_str()], "out of reach"),
        (vec![limits.as_os_str()], "[limits] qdd_max_deg_s2 = -5"),
        (
            vec![
                task.as_os_str(),
                "--refine-tolerance".as_ref(),
                "-1e-6".as_ref(),
            ],
            "--refine-tolerance -0.000001: must be > 0",
        ),
        (
            vec![task.as_os_str(), "--seed".as_ref(), "-1".as_ref()],
            "'-1' is not a seed",
        ),
    ];
    for (args, want) in cases {
        let started = std::time::Instant::now();
        let o = host_sim()
            .arg("plan")
            .args(&args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
        assert!(started.elapsed().as_secs_f64() < 5.0, "{args:?} searched");
    }
}

/// A single file that host-sim did not write is never replaced (`view`, `record`); a
/// directory given as the file is refused with a hint; the file host-sim writes has the
/// mode the user's umask gives, and replacing host-sim's own file works.
/// Verifies RL-SIM-OUT-005.
#[test]
fn single_file_outputs_never_replace_a_users_file() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan");
    let o = host_sim()
        .arg("plan")
        .arg(paper())
        .args(["--paper", "--out"])
        .arg(&plan)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mine = tmp.path().join("notes.html");
    std::fs::write(&mine, "keep me").unwrap();
    let rec = tmp.path().join("notes.json");
    std::fs::write(&rec, "{\"mine\": 1}").unwrap();
    for (args, file) in [
        (vec!["view".into(), plan.clone().into_os_string()], &mine),
        (
            vec!["record".into(), paper().into_os_string(), "--paper".into()],
            &rec,
        ),
    ] {
        let o = host_sim()
            .args(&args)
            .arg("--out")
            .arg(file)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("refusing to replace it"), "{err}");
    }
    assert_eq!(std::fs::read_to_string(&mine).unwrap(), "keep me");
    assert_eq!(std::fs::read_to_string(&rec).unwrap(), "{\"mine\": 1}");
    let o = host_sim()
        .arg("view")
        .arg(&plan)
        .arg("--out")
        .arg(tmp.path())
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("is a directory; give a file name"), "{err}");
    // Written under umask 027, then replaced (it is host-sim's own page).
    let page = tmp.path().join("page.html");
    for _ in 0..2 {
        let o = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!(
                "umask 027 && exec {:?} view {:?} --out {:?}",
                env!("CARGO_BIN_EXE_host-sim"),
                plan,
                page
            ))
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&page).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode, 0o640, "{mode:o}");
    }
}

/// A plan whose budget is spent exits 1 after exactly `max_rollouts` rollouts.
/// Verifies RL-PLAN-009.
#[test]
fn the_total_budget_ends_a_plan_exactly() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), |s| {
        s.replace("tolerance = 0.05", "tolerance = 1e-12\nmax_rollouts = 25")
    });
    let out = tmp.path().join("out");
    let o = host_sim()
        .arg("plan")
        .arg(&task)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let p = read_json(&out.join("plan.json"));
    assert_eq!(p["status"], "not_converged");
    assert_eq!(p["rollouts"], 25);
}

fn plan_rejects(edit: impl Fn(String) -> String, want: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), edit);
    let out = tmp.path().join("out");
    let o = host_sim()
        .arg("plan")
        .arg(&task)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    for w in want {
        assert!(err.contains(w), "{err:?} lacks {w:?}");
    }
    assert!(!out.exists());
}

/// Bad `[planner]` settings are reported as `[planner] key = value` with the reason, exit
/// 2, nothing written.
/// Verifies RL-SIM-TASK-004, RL-ROB-013.
#[test]
fn bad_planner_settings_are_named() {
    plan_rejects(
        |s| s.replace("particles = 40", "particles = 0"),
        &["[planner] particles = 0", "> 0"],
    );
    plan_rejects(
        |s| s.replace("particles = 40", "particles = 1000\nstrategy = \"cpso\""),
        &["particles = 1000", "capacity of 256"],
    );
    plan_rejects(
        |s| s.replace("max_iterations = 200", "max_iterations = 0"),
        &["max_iterations = 0"],
    );
    plan_rejects(
        |s| s.replace("c1 = 1.49618", "c1 = -1.0"),
        &["[planner] c1 = -1", "negative"],
    );
    plan_rejects(
        |s| s.replace("w_min = 0.4", "w_min = 0.95"),
        &["w_min = 0.95", "w_max"],
    );
    plan_rejects(
        |s| s.replace("tolerance = 0.05", "tolerance = 0.0"),
        &["tolerance = 0"],
    );
    plan_rejects(
        |s| s.replace("eta_bound = 5.0", "eta_bound = -5.0"),
        &["eta_bound = -5"],
    );
    plan_rejects(
        |s| s.replace("window = 10", "window = 100"),
        &["[planner.stagnation] window = 100"],
    );
    plan_rejects(|s| s.replace("seed = 1", "seed = -1"), &["seed"]);
    plan_rejects(
        |s| s.replace("seed = 1", "seed = 1\nstrategy = \"pso\""),
        &["strategy", "pso"],
    );
    plan_rejects(
        |s| s.replace("seed = 1", "seed = 1\nmax_rollouts = 0"),
        &["[planner] max_rollouts = 0", "> 0"],
    );
    plan_rejects(
        |s| s.replace("seed = 1", "seed = 1\nrefine_tolerance = 0.0"),
        &["refine_tolerance = 0"],
    );
}

/// `bench --json` prints one JSON object of positive timings, with 10 of seeds 1…10
/// converged.
/// Verifies RL-GOLD-007, RL-SIM-BENCH-001.
#[test]
fn bench_prints_one_json_object() {
    let o = host_sim()
        .arg("bench")
        .arg(paper())
        .arg("--json")
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert_eq!(text.trim().lines().count(), 1);
    let v: Value = serde_json::from_str(text.trim()).unwrap();
    for key in [
        "step_ns",
        "rollout_us",
        "plan_s_median",
        "plan_iterations_median",
    ] {
        assert!(v[key].as_f64().unwrap() > 0.0, "{key}");
    }
    assert_eq!(v["plan_converged"], 10);
}

/// URDF problems reach the user through the task file, named, with exit code 2.
/// Verifies RL-SIM-TASK-002, RL-ROB-010, RL-ROB-011.
#[test]
fn bad_robot_files_are_named_through_the_task() {
    let tmp = tempfile::tempdir().unwrap();
    let urdf = std::fs::read_to_string(root().join("spec/chaser7.urdf")).unwrap();
    let cases: [(&str, String, &[&str]); 3] = [
        (
            "not XML",
            "this is not a robot".into(),
            &["not a readable URDF"],
        ),
        (
            "NaN mass",
            urdf.replace(r#"<mass value="25"/>"#, r#"<mass value="NaN"/>"#),
            &["link 'link2'", "not a finite number"],
        ),
        (
            "NaN origin",
            urdf.replace(
                r#"<origin xyz="0.113 0 0" rpy="0 0 0"/>"#,
                r#"<origin xyz="0.113 nan 0" rpy="0 0 0"/>"#,
            ),
            &["joint 'j2'", "not a finite number"],
        ),
    ];
    for (what, text, want) in cases {
        let path = tmp.path().join("robot.urdf");
        std::fs::write(&path, text).unwrap();
        let task = std::fs::read_to_string(paper())
            .unwrap()
            .replace("\"../chaser7.urdf\"", "\"robot.urdf\"");
        std::fs::write(tmp.path().join("task.toml"), task).unwrap();
        let out = tmp.path().join("out");
        let o = host_sim()
            .arg("rollout")
            .arg(tmp.path().join("task.toml"))
            .args([&format!("--eta={ETA_HAT}"), "--out"])
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{what}: {err}");
        for w in want {
            assert!(err.contains(w), "{what}: {err:?} lacks {w:?}");
        }
        assert!(!out.exists());
    }
    let o = host_sim()
        .args(["plan", "/nonexistent/task.toml", "--out"])
        .arg(tmp.path().join("x"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr)
            .contains("/nonexistent/task.toml: cannot read task file")
    );
}

/// Every subcommand that plans takes `--strategy` (campaign a list) and `--refine-against`
/// where it refines: the flags parse into their fields (a missing task file is then the
/// error, exit 2, not a panic), and a bad strategy names the flag.
/// Verifies RL-PLAN-009, RL-SIM-CLI-001.
#[test]
fn every_planning_subcommand_takes_the_strategy() {
    let tmp = tempfile::tempdir().unwrap();
    let missing = tmp.path().join("missing.toml");
    let out = tmp.path().join("out");
    let m = missing.to_str().unwrap();
    let o = out.to_str().unwrap();
    let cases: Vec<Vec<&str>> = vec![
        vec![
            "plan",
            m,
            "--out",
            o,
            "--strategy",
            "cpso",
            "--refine-against",
            "truth",
        ],
        vec![
            "record",
            m,
            "--out",
            o,
            "--strategy",
            "multistart",
            "--refine-against",
            "planner",
        ],
        vec!["frames", m, "--frame-budget", "10", "--strategy", "cpso"],
        vec![
            "target",
            m,
            "--no-build",
            "--strategy",
            "cpso",
            "--refine-against",
            "truth",
        ],
        vec!["bench", m, "--strategy", "multistart"],
        vec![
            "campaign",
            m,
            "--seeds",
            "1",
            "--out",
            o,
            "--strategy",
            "cpso,multistart",
            "--refine-against",
            "truth",
        ],
    ];
    for args in cases {
        let r = host_sim().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("missing.toml"), "{args:?}: {err}");
    }
    let r = host_sim()
        .args(["plan", m, "--out", o, "--strategy", "pso"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2));
    assert!(
        err.contains("--strategy") && err.contains("multistart or cpso"),
        "{err}"
    );
}

/// A campaign compares strategies: one row per (task, strategy, seed), an overview row
/// per strategy and robot.
/// Verifies RL-SIM-CAMP-001, RL-PLAN-009.
#[test]
fn a_campaign_compares_strategies() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("c");
    let task = root().join("tests/records/tasks/arm6/task_002.toml");
    let r = host_sim()
        .arg("campaign")
        .arg(&task)
        .args(["--seeds", "1,2", "--strategy", "cpso,multistart", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    assert_eq!(csv.lines().count(), 1 + 4);
    assert_eq!(csv.matches(",cpso,").count(), 2);
    assert_eq!(csv.matches(",multistart,").count(), 2);
    let md = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(
        md.contains("| cpso · arm6 |") && md.contains("| multistart · arm6 |"),
        "{md}"
    );
}

/// An error caused by a command-line value names the flag, not the task file.
/// Verifies RL-SIM-CLI-001, RL-ROB-013.
#[test]
fn an_error_in_a_flag_names_the_flag() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let p = paper();
    let task = p.to_str().unwrap();
    let o = out.to_str().unwrap();
    for (args, flag) in [
        (
            vec!["plan", task, "--out", o, "--refine-tolerance", "0"],
            "--refine-tolerance 0",
        ),
        (
            vec!["plan", task, "--out", o, "--refine-tolerance", "nan"],
            "--refine-tolerance NaN",
        ),
        (
            vec!["frames", task, "--frame-budget", "0"],
            "--frame-budget 0",
        ),
        (
            vec!["campaign", task, "--seeds", "3..1", "--out", o],
            "--seeds",
        ),
        (vec!["plan", task, "--out", o, "--seed", "x"], "--seed"),
    ] {
        let r = host_sim().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&r.stderr);
        assert_eq!(r.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(flag), "{args:?}: {err}");
        assert!(
            !err.contains("paper.toml"),
            "{args:?} blames the file: {err}"
        );
        assert!(!out.exists());
    }
}

/// Every subcommand that takes a seed list accepts `3`, `1,2,5` and `1..10`.
/// Verifies RL-SIM-CLI-008.
#[test]
fn seed_lists_take_every_form() {
    let tmp = tempfile::tempdir().unwrap();
    let task = root().join("tests/records/tasks/arm6/task_002.toml");
    for (seeds, rows) in [("3", 1), ("1,2,5", 3), ("1..4", 4)] {
        let out = tmp.path().join(seeds.replace(['.', ','], "_"));
        let r = host_sim()
            .arg("campaign")
            .arg(&task)
            .args(["--seeds", seeds, "--out"])
            .arg(&out)
            .output()
            .unwrap();
        assert!(
            r.status.success(),
            "{seeds}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        let csv = std::fs::read_to_string(out.join("runs.csv")).unwrap();
        assert_eq!(csv.lines().count(), 1 + rows, "{seeds}");
    }
}

/// Shell completions and man pages come from the clap definitions.
/// Verifies RL-SIM-CLI-009.
#[test]
fn completions_and_man_pages() {
    let r = host_sim().args(["completions", "bash"]).output().unwrap();
    assert!(r.status.success());
    let text = String::from_utf8_lossy(&r.stdout);
    assert!(text.contains("host-sim") && text.contains("campaign"));
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("man");
    let r = host_sim()
        .arg("manpage")
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let page = std::fs::read_to_string(out.join("host-sim-plan.1")).unwrap();
    assert!(
        page.contains(".TH") && page.contains("refine\\-tolerance"),
        "{page}"
    );
}

/// `[target] position_tolerance_m` and `orientation_tolerance_deg`: the plan is refined until
/// both errors are within them, `check` holds it to each, and a bad value is named.
/// Verifies RL-SIM-TASK-005.
#[test]
fn pose_tolerances_are_met_and_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let task = task_with(tmp.path(), |t| {
        t.replace(
            "[target]\n",
            "[target]\nposition_tolerance_m = 1e-4\norientation_tolerance_deg = 0.001\n",
        )
    });
    let out = tmp.path().join("out");
    let r = host_sim()
        .arg("plan")
        .arg(&task)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    let bundle: toml::Table =
        toml::from_str(&std::fs::read_to_string(out.join("task.toml")).unwrap()).unwrap();
    let tol = bundle["planner"]["refine_tolerance"].as_float().unwrap();
    assert_eq!(tol, 1e-4_f64.min(0.001_f64.to_radians()));
    assert!(plan["position_error_m"].as_f64().unwrap() <= 1e-4);
    assert!(plan["orientation_error_deg"].as_f64().unwrap() <= 0.001);
    let c = host_sim().arg("check").arg(&out).output().unwrap();
    let text = String::from_utf8_lossy(&c.stdout);
    assert!(c.status.success(), "{text}");
    assert!(text.contains("[target] position_tolerance_m"), "{text}");
    assert!(
        text.contains("[target] orientation_tolerance_deg"),
        "{text}"
    );

    let bad = task_with(tmp.path(), |t| {
        t.replace("[target]\n", "[target]\nposition_tolerance_m = -1.0\n")
    });
    let out2 = tmp.path().join("out2");
    let r = host_sim()
        .arg("plan")
        .arg(&bad)
        .arg("--out")
        .arg(&out2)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{err}");
    assert!(err.contains("[target] position_tolerance_m = -1"), "{err}");
    assert!(!out2.exists());
}

/// `block TASK --out FILE` writes exactly the bytes `target` gives QEMU, which decode to
/// the task; a robot the flight image is not built for is refused with exit code 2 and
/// nothing written.
/// Verifies RL-FFI-009.
#[test]
fn block_writes_the_bytes_target_gives_qemu() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("paper.block");
    host_sim()
        .args([
            "block",
            paper().to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .assert()
        .success();
    let written = std::fs::read(&out).unwrap();
    let lt = host_sim::taskfile::load(&paper()).unwrap();
    let expected =
        host_sim::flight::task_block(&lt, &host_sim::taskfile::Overrides::default()).unwrap();
    assert_eq!(written, expected);
    let block = reactionless::block::decode::<7>(&written).unwrap();
    assert_eq!(block.planner.frame_budget, 3000);

    let six = root().join("tests/records/tasks/arm6/task_002.toml");
    let bad = tmp.path().join("six.block");
    host_sim()
        .args([
            "block",
            six.to_str().unwrap(),
            "--out",
            bad.to_str().unwrap(),
        ])
        .assert()
        .code(2);
    assert!(!bad.exists());
}

/// A task of four segments (`[motion] segments = 4`) plans from the fixed start to its
/// pose goal, writes the segments' 32 η values, and `check` passes it: the written samples
/// are a fresh rollout of that η bit for bit, within the limits, at rest at both ends.
/// Verifies RL-PLAN-015.
#[test]
fn a_task_of_four_segments_plans_and_checks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let r = plan_into("tests/tasks/fixed/segments/ref/1cm/ref-0.toml", &out);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert_eq!(plan["status"], "converged");
    assert_eq!(plan["eta"].as_array().unwrap().len(), 32);
    let c = host_sim().arg("check").arg(&out).output().unwrap();
    let text = String::from_utf8_lossy(&c.stdout);
    assert!(c.status.success(), "{text}");
    assert!(text.contains("matches a fresh rollout of eta"), "{text}");
}
