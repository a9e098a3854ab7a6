//! End-to-end tests of the 3-D replay page (`host-sim view`, `plan/rollout --plots`)
//! without a browser: the file is self-contained and its embedded data is the run's.
//! The browser half (DOM state, screenshot) is scripts/view-test.sh.
//!
//! Requirements: RL-SIM-VIEW (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use host_sim::taskfile;
use serde_json::Value;
use std::path::{Path, PathBuf};

const ETA_HAT: &str = "3.14771,0.809316,1.12249,0.754006,4.7352,0.406031,-4.1572,4.29895";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").unwrap()
}

/// The η a generated task was made from (its first comment lines).
fn generated_eta(task: &Path) -> String {
    let text = std::fs::read_to_string(task).unwrap();
    let start = text.find("eta = [").unwrap() + "eta = [".len();
    let end = start + text[start..].find(']').unwrap();
    text[start..end].replace([' ', '\n', '#'], "")
}

/// `rollout --plots` of `task` with `eta` into `out`.
fn rollout(task: &Path, eta: &str, out: &Path) {
    let o = host_sim()
        .arg("rollout")
        .arg(task)
        .arg(format!("--eta={eta}"))
        .args(["--plots", "--out"])
        .arg(out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// The JSON the page embeds.
fn embedded(page: &str) -> Value {
    let open = r#"<script id="rl-data" type="application/json">"#;
    let start = page.find(open).unwrap() + open.len();
    let end = start + page[start..].find("</script>").unwrap();
    serde_json::from_str(&page[start..end]).unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn f64s(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

/// What a page may not contain: anything that would load from elsewhere (a URL scheme
/// as a word of its own, an attribute or call that fetches).
fn external_references(page: &str) -> Vec<String> {
    let lower = page.to_ascii_lowercase();
    let mut found = Vec::new();
    for pat in [
        "http:",
        "https:",
        "ftp:",
        "ws:",
        "wss:",
        "file:",
        "data:",
        "blob:",
        "src=",
        "href=",
        "url(",
        "@import",
        "import(",
        "fetch(",
        "xmlhttprequest",
        "<link",
        "<iframe",
        "<img",
    ] {
        for (at, _) in lower.match_indices(pat) {
            let word_start = at == 0 || !lower.as_bytes()[at - 1].is_ascii_alphanumeric();
            if word_start || !pat.ends_with(':') {
                found.push(format!("{pat:?} at byte {at}"));
            }
        }
    }
    found
}

/// The page of the reference robot (7 joints) and of a 9-joint arm: one file that
/// references nothing outside itself; its data holds every written sample (q, q̇ as in
/// trajectory.csv), the planner-model end effector at t = 0 equal to the task's start pose
/// and at t_f to summary.json's end_pose.position (bit for bit), the truth-model base
/// angle starting at 0 with its largest value summary.json's base_disturbance_deg (bit for
/// bit), and `host-sim view DIR` writes the same page as `rollout --plots`.
/// Verifies RL-SIM-VIEW-001, RL-SIM-VIEW-002, RL-SIM-VIEW-003.
#[test]
fn the_page_is_self_contained_and_carries_the_runs_own_numbers() {
    let tmp = tempfile::tempdir().unwrap();
    let arm9 = root().join("tests/tasks/a/arm9/task_001.toml");
    let cases = [
        (
            "chaser7",
            root().join("spec/tasks/paper.toml"),
            ETA_HAT.to_string(),
            7,
        ),
        ("arm9", arm9.clone(), generated_eta(&arm9), 9),
    ];
    for (name, task, eta, n) in cases {
        let out = tmp.path().join(name);
        rollout(&task, &eta, &out);
        let page = std::fs::read_to_string(out.join("view.html")).unwrap();
        assert!(
            external_references(&page).is_empty(),
            "{name}: {:?}",
            external_references(&page)
        );
        assert!(page.len() < 8_000_000, "{name}: {} bytes", page.len());
        let d = embedded(&page);
        let summary = json(&out.join("summary.json"));
        let samples = summary["steps"].as_u64().unwrap() as usize + 1;
        assert_eq!(d["n"], n);
        for key in ["t", "q", "qd", "ee", "base_angle_deg", "base_wxyz", "draw"] {
            assert_eq!(d[key].as_array().unwrap().len(), samples, "{name}: {key}");
        }
        assert_eq!(d["draw"][0].as_array().unwrap().len(), 3 + 6 * n + 12);
        // q and q̇ exactly as written.
        let csv = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
        for (s, line) in csv.lines().skip(1).enumerate().step_by(397) {
            let row: Vec<f64> = line.split(',').map(|v| v.parse().unwrap()).collect();
            assert_eq!(d["t"][s].as_f64().unwrap(), row[0]);
            assert_eq!(f64s(&d["q"][s]), row[1..=n]);
            assert_eq!(f64s(&d["qd"][s]), row[n + 1..]);
        }
        // End effector: the start pose at t = 0, summary.json's end pose at t_f.
        let lt = taskfile::load(&task).unwrap();
        let start = match n {
            7 => lt.task::<7, 4>().unwrap().start_pose().position,
            _ => lt.task::<9, 6>().unwrap().start_pose().position,
        };
        assert_eq!(f64s(&d["ee"][0]), start, "{name}: t = 0");
        assert_eq!(
            f64s(&d["ee"][samples - 1]),
            f64s(&summary["end_pose"]["position"]),
            "{name}: t_f"
        );
        assert_eq!(f64s(&d["q"][samples - 1]), f64s(&summary["q_final"]));
        // Truth-model base angle.
        let angle = f64s(&d["base_angle_deg"]);
        assert_eq!(angle[0], 0.0);
        let max = angle.iter().copied().fold(0.0, f64::max);
        assert_eq!(max, summary["base_disturbance_deg"].as_f64().unwrap());
        assert_eq!(d["base_disturbance_deg"], summary["base_disturbance_deg"]);
        // The magnified attitude is visible and not absurd: largest drawn angle in (4°, 20°].
        let drawn = max * d["magnification"].as_f64().unwrap();
        assert!(drawn > 4.0 && drawn <= 20.0, "{name}: drawn {drawn}°");
        // `host-sim view DIR` writes the same page.
        let again = tmp.path().join(format!("{name}.html"));
        let o = host_sim()
            .arg("view")
            .arg(&out)
            .arg("--out")
            .arg(&again)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert_eq!(std::fs::read_to_string(&again).unwrap(), page, "{name}");
    }
}

/// `view` of a re-timed bundle (`retime`'s output) draws its setpoints: the same count and
/// times as its trajectory.csv, q exactly as written, the end at summary.json's end pose,
/// and the truth model's base angle peaking at the bundle's own base disturbance.
/// Verifies RL-SIM-VIEW-005.
#[test]
fn a_retimed_bundle_is_drawn_from_its_setpoints() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("rollout");
    rollout(&root().join("spec/tasks/paper.toml"), ETA_HAT, &plan);
    let re = tmp.path().join("retimed");
    let o = host_sim()
        .arg("retime")
        .arg(&plan)
        .args(["--accel-deg-s2", "5", "--out"])
        .arg(&re)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page_path = tmp.path().join("retimed.html");
    let o = host_sim()
        .arg("view")
        .arg(&re)
        .arg("--out")
        .arg(&page_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let d = embedded(&std::fs::read_to_string(&page_path).unwrap());
    let summary = json(&re.join("summary.json"));
    let csv = std::fs::read_to_string(re.join("trajectory.csv")).unwrap();
    let rows: Vec<Vec<f64>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(d["t"].as_array().unwrap().len(), rows.len());
    assert!(rows.len() < 3001, "re-timed: {} setpoints", rows.len());
    for (s, row) in rows.iter().enumerate().step_by(97) {
        assert_eq!(d["t"][s].as_f64().unwrap(), row[0]);
        assert_eq!(f64s(&d["q"][s]), row[1..=7]);
    }
    assert_eq!(
        f64s(&d["ee"][rows.len() - 1]),
        f64s(&summary["end_pose"]["position"])
    );
    let max = f64s(&d["base_angle_deg"]).into_iter().fold(0.0, f64::max);
    let want = summary["base_disturbance_deg"].as_f64().unwrap();
    assert!((max - want).abs() <= 1e-9 * want, "{max} vs {want}");
}

/// `view` refuses what is not a consistent output directory (exit code 2, a message naming
/// the file, nothing written): no directory, no summary.json, and a summary.json whose end
/// pose is not the trajectory's.
/// Verifies RL-SIM-VIEW-004.
#[test]
fn view_refuses_inconsistent_or_missing_inputs() {
    let tmp = tempfile::tempdir().unwrap();
    let page = tmp.path().join("page.html");
    let view = |dir: &Path| {
        let o = host_sim()
            .arg("view")
            .arg(dir)
            .arg("--out")
            .arg(&page)
            .output()
            .unwrap();
        (
            o.status.code(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let (code, err) = view(&tmp.path().join("nothing"));
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("no such directory"), "{err}");
    let out = tmp.path().join("roll");
    rollout(&root().join("spec/tasks/paper.toml"), ETA_HAT, &out);
    let summary = out.join("summary.json");
    let text = std::fs::read_to_string(&summary).unwrap();
    let mut v: Value = serde_json::from_str(&text).unwrap();
    v["end_pose"]["position"][0] =
        Value::from(v["end_pose"]["position"][0].as_f64().unwrap() + 1e-9);
    std::fs::write(&summary, serde_json::to_string(&v).unwrap()).unwrap();
    let (code, err) = view(&out);
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("summary.json") && err.contains("trajectory.csv"),
        "{err}"
    );
    std::fs::remove_file(&summary).unwrap();
    let (code, err) = view(&out);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("summary.json"), "{err}");
    assert!(!page.exists());
}

/// `view` of an exported closed-loop flight (`disperse --closed-loop --export-sample K
/// --out DIR`, here with an initial base rate) draws the flown path on the dispersed robot:
/// every flown sample as written,
/// the end at the flight's `summary.json` end pose, the truth model's base angle peaking
/// at the flight's base disturbance bit for bit, and the loop's estimate per control cycle
/// as cycles.csv gives it; the page stays self-contained. A cycles.csv of another length is
/// refused.
/// Verifies RL-SIM-VIEW-006.
#[test]
fn a_closed_loop_flight_is_drawn_with_the_loops_estimate() {
    let tmp = tempfile::tempdir().unwrap();
    let plan = tmp.path().join("plan");
    rollout(&root().join("spec/tasks/paper.toml"), ETA_HAT, &plan);
    let flight = tmp.path().join("f2");
    let o = host_sim()
        .arg("disperse")
        .arg(&plan)
        .args([
            "--seed",
            "1",
            "--mass-rel-sigma",
            "0.05",
            "--inertia-rel-sigma",
            "0.1",
        ])
        .args([
            "--com-sigma-m",
            "0.01",
            "--closed-loop",
            "--export-sample",
            "2",
            "--out",
        ])
        .arg(&flight)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page_path = tmp.path().join("f2.html");
    let o = host_sim()
        .arg("view")
        .arg(&flight)
        .arg("--out")
        .arg(&page_path)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let page = std::fs::read_to_string(&page_path).unwrap();
    assert!(external_references(&page).is_empty());
    let d = embedded(&page);
    let summary = json(&flight.join("summary.json"));
    assert_eq!(summary["kind"], "closed_loop_sample");
    // Every flown sample, t_f plus the 3 s the loop goes on.
    let csv = std::fs::read_to_string(flight.join("trajectory.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    let t = f64s(&d["t"]);
    assert_eq!(t.len(), rows.len());
    assert_eq!(t.len(), 3301);
    let last: Vec<f64> = rows[rows.len() - 1]
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    assert_eq!(f64s(&d["q"][rows.len() - 1]), last[1..8].to_vec());
    let ee = f64s(&d["ee"][rows.len() - 1]);
    assert_eq!(ee, f64s(&summary["end_pose"]["position"]));
    let angles = f64s(&d["base_angle_deg"]);
    let max = angles.iter().copied().fold(0.0, f64::max);
    assert_eq!(
        max,
        summary["figures"]["base_disturbance_deg"].as_f64().unwrap()
    );
    assert_eq!(
        d["base_disturbance_deg"],
        summary["figures"]["base_disturbance_deg"]
    );
    // The loop's estimate per cycle, as cycles.csv writes it.
    let l = &d["closed_loop"];
    assert_eq!(
        (l["seed"].as_u64(), l["sample"].as_u64()),
        (Some(1), Some(2))
    );
    let cycles = std::fs::read_to_string(flight.join("cycles.csv")).unwrap();
    let est: Vec<f64> = cycles
        .lines()
        .skip(1)
        .map(|r| r.split(',').nth(8).unwrap().parse().unwrap())
        .collect();
    assert_eq!(est.len(), 330);
    assert_eq!(f64s(&l["estimate_deg"]), est);
    assert!(l["fault"].is_null());
    assert!(d["stamp"].as_str().unwrap().contains("closed loop"));

    // A cycles.csv cut short is not this flight's.
    let cut: Vec<&str> = cycles.lines().take(100).collect();
    std::fs::write(flight.join("cycles.csv"), cut.join("\n") + "\n").unwrap();
    let o = host_sim()
        .arg("view")
        .arg(&flight)
        .arg("--out")
        .arg(tmp.path().join("bad.html"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cycles.csv"));
    assert!(!tmp.path().join("bad.html").exists());
}
