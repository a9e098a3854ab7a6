//! Two-phase plans through the command line (issue #30): a task with `[preshape]` plans in
//! two phases, `check` verifies both and catches an edited phase 1, phase 2 is an ordinary
//! bundle, bad bounds and targets beyond reach are named, `campaign` counts them.
//! Requirements: RL-SIM-TWO (docs/requirements.md).
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

/// A checked-in generic target (the end pose at a configuration 20° per joint away).
fn generic_task() -> PathBuf {
    root().join("tests/tasks/g/chaser7/joint20/task_001.toml")
}

/// The task file with its `[preshape]` table replaced by `table` (its URDF made absolute).
fn with_preshape(dir: &Path, table: &str) -> PathBuf {
    let text = std::fs::read_to_string(generic_task()).unwrap();
    let urdf = root().join("spec/chaser7.urdf");
    let mut out = String::new();
    for line in text.lines() {
        if line.starts_with("urdf = ") {
            out.push_str(&format!("urdf = {:?}\n", urdf.display().to_string()));
        } else if line.starts_with("[preshape]") {
            out.push_str(table);
            out.push('\n');
        } else {
            out.push_str(line);
            out.push('\n');
        }
    }
    let path = dir.join("task.toml");
    std::fs::write(&path, out).unwrap();
    path
}

/// Plan, check, and the files a reader needs: phase 1 within its bounds, phase 2 at the
/// pose and reactionless, phase 2's bundle checkable on its own, both phases on the replay
/// page; an edited phase 1 fails.
/// Verifies RL-SIM-TWO-001, RL-SIM-TWO-002.
#[test]
fn a_two_phase_plan_is_written_and_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("p");
    let (code, _, err) = host_sim(args!("plan", &generic_task(), "--out", &out));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("converged in two phases"), "{err}");
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert_eq!(plan["status"], "converged");
    let p1 = &plan["phase1"];
    assert!(p1["momentum_nms"].as_f64().unwrap() <= p1["max_momentum_nms"].as_f64().unwrap());
    assert!(p1["torque_nm"].as_f64().unwrap() <= p1["max_torque_nm"].as_f64().unwrap());
    let p2 = &plan["phase2"];
    assert!(p2["position_error_m"].as_f64().unwrap() <= 1e-6);
    assert!(p2["orientation_error_deg"].as_f64().unwrap() <= 1e-4);
    assert!(p2["base_disturbance_deg"].as_f64().unwrap() < 0.01);

    let (code, table, err) = host_sim(args!("check", &out));
    assert_eq!(code, Some(0), "{table}{err}");
    assert!(table.contains("phase 1 wheels' torque"), "{table}");
    assert!(table.contains("phase 2: base disturbance"), "{table}");
    let (code, table, err) = host_sim(args!("check", &out.join("phase2")));
    assert_eq!(code, Some(0), "{table}{err}");

    // The replay page draws both phases: phase 1's samples, then phase 2's after them.
    let page = tmp.path().join("view.html");
    let (code, _, err) = host_sim(args!("view", &out, "--out", &page));
    assert_eq!(code, Some(0), "{err}");
    let html = std::fs::read_to_string(&page).unwrap();
    let t1 = p1["duration_s"].as_f64().unwrap();
    assert!(
        html.contains(&format!("\"phase1_end_s\":{t1}")),
        "phase1_end_s {t1}"
    );

    // One written sample of phase 1 moved by 1e-3 rad: check names it.
    let csv = std::fs::read_to_string(out.join("phase1.csv")).unwrap();
    let mut lines: Vec<String> = csv.lines().map(String::from).collect();
    let mid = lines.len() / 2;
    let mut cells: Vec<String> = lines[mid].split(',').map(String::from).collect();
    let q1: f64 = cells[1].parse().unwrap();
    cells[1] = format!("{}", q1 + 1e-3);
    lines[mid] = cells.join(",");
    std::fs::write(out.join("phase1.csv"), lines.join("\n") + "\n").unwrap();
    let (code, table, err) = host_sim(args!("check", &out));
    assert_eq!(code, Some(1), "{table}{err}");
    assert!(err.contains("phase 1 matches a fresh phase 1"), "{err}");
}

/// Bad `[preshape]` values are refused before planning, naming the key; a target beyond
/// the arm's reach ends at once with a status that says so.
/// Verifies RL-SIM-TWO-003.
#[test]
fn bad_bounds_and_unreachable_targets_are_named() {
    let tmp = tempfile::tempdir().unwrap();
    let task = with_preshape(tmp.path(), "[preshape]\nmax_torque_nm = -1.0");
    let (code, _, err) = host_sim(args!("plan", &task, "--out", &tmp.path().join("p")));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("[preshape] max_torque_nm"), "{err}");

    // The target 3 m further along x: outside the arm's reach from every configuration,
    // but inside the coarse reach check of the task file.
    let text = std::fs::read_to_string(with_preshape(tmp.path(), "[preshape]")).unwrap();
    let far: String = text
        .lines()
        .map(|l| {
            if let Some(rest) = l.strip_prefix("position_m = [") {
                let v: Vec<f64> = rest
                    .trim_end_matches(']')
                    .split(',')
                    .map(|x| x.trim().parse().unwrap())
                    .collect();
                format!("position_m = [{}, {}, {}]", v[0] + 0.9, v[1], v[2] - 0.9)
            } else {
                l.to_string()
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let task = tmp.path().join("far.toml");
    std::fs::write(&task, far).unwrap();
    let out = tmp.path().join("far");
    let (code, _, err) = host_sim(args!("plan", &task, "--out", &out));
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("beyond the arm's reach"), "{err}");
    let plan: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("plan.json")).unwrap()).unwrap();
    assert_eq!(plan["stop"], "beyond_reach");
    assert_eq!(plan["rollouts"], 0);
}

/// `campaign` plans two-phase tasks in two phases and counts them by what they reached.
/// Verifies RL-SIM-TWO-004.
#[test]
fn campaign_runs_two_phase_tasks() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("c");
    let (code, _, err) = host_sim(args!(
        "campaign",
        &generic_task(),
        "--seeds",
        "1..2",
        "--out",
        &out
    ));
    assert_eq!(code, Some(0), "{err}");
    let runs = std::fs::read_to_string(out.join("runs.csv")).unwrap();
    assert_eq!(runs.matches("two-phase").count(), 2, "{runs}");
    assert_eq!(runs.matches(",converged,").count(), 2, "{runs}");
}

/// `generate`'s generic-target flags refuse bad values before anything is written, naming
/// the flag.
/// Verifies RL-SIM-TWO-003.
#[test]
fn generate_refuses_bad_generic_flags() {
    let tmp = tempfile::tempdir().unwrap();
    let urdf = root().join("spec/chaser7.urdf");
    for (flag, value) in [
        ("--distance-deg", "0"),
        ("--move-m", "-0.01"),
        ("--move-deg", "nan"),
        ("--family", "fast"),
    ] {
        let out = tmp.path().join("g");
        let (code, _, err) = host_sim(args!(
            "generate",
            "--urdf",
            &urdf,
            "--ee",
            "ee",
            "--q-deg=-90,45,0,80,-90,-45,-10",
            "--count",
            "1",
            "--seed",
            "1",
            "--kind",
            "joint",
            flag,
            value,
            "--out",
            &out
        ));
        assert_eq!(code, Some(2), "{flag} {value}: {err}");
        assert!(err.contains(flag), "{flag}: {err}");
        assert!(!out.exists());
    }
}

/// The generic task planned in two phases into `dir/p` (converged).
fn planned(dir: &Path) -> PathBuf {
    let plan = dir.join("p");
    let (code, _, err) = host_sim(args!("plan", &generic_task(), "--out", &plan));
    assert_eq!(code, Some(0), "{err}");
    plan
}

/// `retime` of a two-phase plan: phase 1 as planned, phase 2 re-timed into `OUT/phase2/`,
/// and `check OUT` verifies phase 1, the join and the re-timed phase 2 within the limits;
/// `plan --retime` writes the same into `OUT/retimed/`; limits below phase 1's
/// acceleration are refused, naming the key, nothing written.
/// Verifies RL-SIM-TWO-006.
#[test]
fn a_two_phase_plan_is_retimed_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = planned(tmp.path());
    let out = tmp.path().join("r");
    let (code, _, err) = host_sim(args!("retime", &plan, "--out", &out, "--accel-deg-s2", "5"));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("phase 2 re-timed"), "{err}");
    assert_eq!(
        std::fs::read(out.join("phase1.csv")).unwrap(),
        std::fs::read(plan.join("phase1.csv")).unwrap()
    );
    let summary: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("phase2/summary.json")).unwrap())
            .unwrap();
    assert!(
        summary["duration_s"].as_f64().unwrap() < summary["original_duration_s"].as_f64().unwrap()
    );
    let (code, table, err) = host_sim(args!("check", &out));
    assert_eq!(code, Some(0), "{table}{err}");
    assert!(table.contains("phase 1 wheels' torque"), "{table}");
    assert!(table.contains("phase 2: "), "{table}");

    // `plan --retime` writes the same whole re-timed plan into OUT/retimed/.
    let both = tmp.path().join("b");
    let (code, _, err) = host_sim(args!(
        "plan",
        &generic_task(),
        "--out",
        &both,
        "--retime",
        "--accel-deg-s2",
        "5"
    ));
    assert_eq!(code, Some(0), "{err}");
    for f in ["phase1.csv", "phase2/trajectory.csv"] {
        assert_eq!(
            std::fs::read(both.join("retimed").join(f)).unwrap(),
            std::fs::read(out.join(f)).unwrap(),
            "{f}"
        );
    }

    // Phase 1 accelerates at up to 2 °/s²: a re-timing limit of 1 °/s² is refused.
    let refused = tmp.path().join("x");
    let (code, _, err) = host_sim(args!(
        "retime",
        &plan,
        "--out",
        &refused,
        "--accel-deg-s2",
        "1"
    ));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("[preshape] qdd_max_deg_s2"), "{err}");
    assert!(!refused.exists());
}

/// `disperse` of a two-phase plan flies phase 2 from where phase 1 moved each dispersed
/// robot's base: the base disturbance is phase 2's, sample by sample, while the end-pose
/// error adds the dispersed robot's phase-1 base shift against the nominal one, recomputed
/// here from `model`'s CoM of the exported dispersed URDF (the end position differs from
/// phase 2's alone by exactly that shift, so their errors obey the triangle inequality).
/// Verifies RL-SIM-TWO-007.
#[test]
fn a_two_phase_plan_is_dispersed_whole() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = planned(tmp.path());
    // The same draws for every command: seed 7, 5 % mass, 1 cm CoM.
    let draws = [
        "--seed",
        "7",
        "--mass-rel-sigma",
        "0.05",
        "--com-sigma-m",
        "0.01",
    ];
    let run = |head: &[&std::ffi::OsStr], tail: &[&std::ffi::OsStr]| {
        let mut a: Vec<&std::ffi::OsStr> = head.to_vec();
        a.extend(draws.iter().map(std::ffi::OsStr::new));
        a.extend(tail);
        let (code, _, err) = host_sim(&a);
        assert_eq!(code, Some(0), "{err}");
    };
    let whole = tmp.path().join("w");
    let only2 = tmp.path().join("o");
    for (dir, out) in [(plan.clone(), &whole), (plan.join("phase2"), &only2)] {
        run(
            args!("disperse", &dir, "--samples", "4"),
            args!("--out", out),
        );
    }
    let rows = |dir: &Path| -> Vec<std::collections::HashMap<String, String>> {
        let mut r = csv::Reader::from_path(dir.join("runs.csv")).unwrap();
        r.deserialize().map(|x| x.unwrap()).collect()
    };
    let (w, o) = (rows(&whole), rows(&only2));
    assert_eq!(w.len(), 4);
    let num =
        |r: &std::collections::HashMap<String, String>, k: &str| -> f64 { r[k].parse().unwrap() };
    for (a, b) in w.iter().zip(&o) {
        assert_eq!(a["base_disturbance_deg"], b["base_disturbance_deg"]);
        assert_eq!(a["orientation_error_deg"], b["orientation_error_deg"]);
    }
    // Sample 0's phase-1 base shift, dispersed minus nominal, from the CoM in the base frame.
    let urdf = tmp.path().join("s0.urdf");
    run(
        args!("disperse", &plan),
        args!("--export-sample", "0", "--out", &urdf),
    );
    let start = |p: &Path| -> String {
        let t: toml::Table = toml::from_str(&std::fs::read_to_string(p).unwrap()).unwrap();
        t["start"]["q_deg"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_float().unwrap().to_string())
            .collect::<Vec<_>>()
            .join(",")
    };
    let (q0, qs) = (
        start(&plan.join("task.toml")),
        start(&plan.join("phase2/task.toml")),
    );
    let com = |u: &Path, q: &str| -> [f64; 3] {
        let (code, out, err) = host_sim(args!("model", "--urdf", u, "--q-deg", q));
        assert_eq!(code, Some(0), "{err}");
        let v: Value = serde_json::from_str(&out).unwrap();
        [0, 1, 2].map(|i| v["com"][i].as_f64().unwrap())
    };
    let nominal = root().join("spec/chaser7.urdf");
    let moved = |u: &Path| -> [f64; 3] {
        let (a, b) = (com(u, &q0), com(u, &qs));
        [0, 1, 2].map(|i| a[i] - b[i])
    };
    let (md, mn) = (moved(&urdf), moved(&nominal));
    let d = [0, 1, 2].map(|i| md[i] - mn[i]);
    let shift = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let (ew, eo) = (
        num(&w[0], "position_error_m"),
        num(&o[0], "position_error_m"),
    );
    assert!(shift > 1e-4, "the draw moves the base: {shift}");
    assert!(
        (ew - shift).abs() <= eo + 1e-12,
        "whole {ew}, shift {shift}, phase 2 {eo}"
    );
}

/// `record` of a two-phase task records the two-phase plan (phase 2's plan, how the search
/// ended, phase 1's digest, the wheels' demand, `q_s`), and `replay` reproduces it; a
/// changed `q_s` bit or phase-1 digest, or the two-phase part removed, is named (exit 1).
/// Verifies RL-SIM-TWO-008.
#[test]
fn a_two_phase_plan_is_recorded_and_replayed() {
    let tmp = tempfile::tempdir().unwrap();
    let rec = tmp.path().join("rec.json");
    let (code, _, err) = host_sim(&[
        "record".as_ref(),
        generic_task().as_os_str(),
        "--out".as_ref(),
        rec.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{err}");
    let v: Value = serde_json::from_str(&std::fs::read_to_string(&rec).unwrap()).unwrap();
    let two = &v["outputs"]["two_phase"];
    assert_eq!(two["stop"], "converged");
    assert_eq!(v["outputs"]["status"], "converged");
    assert_eq!(two["q_s_bits"].as_array().unwrap().len(), 7);
    assert!(two["phase1_steps"].as_u64().unwrap() > 0);
    assert_eq!(
        two["phase1_samples"].as_u64().unwrap(),
        two["phase1_steps"].as_u64().unwrap() + 1
    );
    let (code, _, err) = host_sim(&["replay".as_ref(), rec.as_os_str()]);
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("identical"), "{err}");
    let bad_path = tmp.path().join("bad.json");
    let flip = |s: &str| format!("{:#018x}", u64::from_str_radix(&s[2..], 16).unwrap() ^ 1);
    let mut cases: Vec<(Value, &str)> = Vec::new();
    let mut bad = v.clone();
    let q = bad["outputs"]["two_phase"]["q_s_bits"][3]
        .as_str()
        .unwrap()
        .to_string();
    bad["outputs"]["two_phase"]["q_s_bits"][3] = Value::String(flip(&q));
    cases.push((bad, "mismatch in two_phase.q_s[3]"));
    let mut bad = v.clone();
    let d = bad["outputs"]["two_phase"]["phase1_digest"]
        .as_str()
        .unwrap()
        .to_string();
    bad["outputs"]["two_phase"]["phase1_digest"] = Value::String(flip(&d));
    cases.push((bad, "mismatch in two_phase.digest1"));
    let mut bad = v.clone();
    bad["outputs"].as_object_mut().unwrap().remove("two_phase");
    cases.push((bad, "mismatch in phases: recorded one, replayed two"));
    for (bad, want) in cases {
        std::fs::write(&bad_path, serde_json::to_string_pretty(&bad).unwrap()).unwrap();
        let (code, _, err) = host_sim(&["replay".as_ref(), bad_path.as_os_str()]);
        assert_eq!(code, Some(1), "{want}: {err}");
        assert!(err.contains(want), "{want}: {err}");
    }
}
