//! `host-sim disperse` and `host-sim merge`: the nominal truth model reproduced bit for bit
//! at σ = 0, results independent of `--jobs` and of sharding, the exported URDF read back
//! to the drawn bits, and bad input refused with exit 2 and nothing written.
//!
//! Requirements: RL-SIM-DISP (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use host_sim::dispersion::{Draw, Settings};
use serde_json::Value;
use std::path::{Path, PathBuf};

const ETA_HAT: &str = "3.14771,0.809316,1.12249,0.754006,4.7352,0.406031,-4.1572,4.29895";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").unwrap()
}

/// The paper's rollout of η̂ (the plan directory every test flies).
fn rollout(tmp: &Path) -> PathBuf {
    let out = tmp.join("rollout");
    host_sim()
        .arg("rollout")
        .arg(root().join("spec/tasks/paper.toml"))
        .args(["--eta", ETA_HAT, "--out"])
        .arg(&out)
        .assert()
        .success();
    out
}

fn disperse(dir: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    host_sim()
        .arg("disperse")
        .arg(dir)
        .arg("--out")
        .arg(out)
        .args(extra)
        .output()
        .unwrap()
}

fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

fn read(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}

fn json(p: &Path) -> Value {
    serde_json::from_str(&read(p)).unwrap()
}

const DISPERSED: [&str; 12] = [
    "--mass-rel-sigma",
    "0.05",
    "--inertia-rel-sigma",
    "0.10",
    "--com-sigma-m",
    "0.01",
    "--axis-sigma-deg",
    "0.1",
    "--base-rate-sigma-deg-s",
    "0.001",
    "--seed",
    "7",
];

/// All σ = 0: every row's figures are the nominal truth model's of the directory's
/// `summary.json` (base disturbance, truth f, and the errors of the truth end pose), bit
/// for bit.
/// Verifies RL-SIM-DISP-001.
#[test]
fn zero_sigmas_reproduce_the_nominal_truth_model_bit_for_bit() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let out = tmp.path().join("d0");
    let o = disperse(&dir, &out, &["--samples", "3", "--seed", "1"]);
    ok(&o);
    // It says so: nothing was dispersed.
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("every dispersion is 0"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let s = json(&dir.join("summary.json"));
    // The task's target as the core holds it (its quaternion normalised).
    let task = host_sim::taskfile::load(&dir.join("task.toml"))
        .unwrap()
        .task::<7, 4>()
        .unwrap();
    let target = *task.target();
    let end = reactionless::Pose {
        position: serde_json::from_value(s["truth_end_pose"]["position"].clone()).unwrap(),
        quat_wxyz: serde_json::from_value(s["truth_end_pose"]["quat_wxyz"].clone()).unwrap(),
    };
    let e = end.error_to(&target);
    let mut rdr = csv::Reader::from_path(out.join("runs.csv")).unwrap();
    let head = rdr.headers().unwrap().clone();
    let col = |n: &str| head.iter().position(|h| h == n).unwrap();
    let mut rows = 0;
    for r in rdr.records() {
        let r = r.unwrap();
        let v = |n: &str| r[col(n)].parse::<f64>().unwrap();
        assert_eq!(
            v("base_disturbance_deg").to_bits(),
            s["base_disturbance_deg"].as_f64().unwrap().to_bits()
        );
        assert_eq!(v("f").to_bits(), s["truth_f"].as_f64().unwrap().to_bits());
        assert_eq!(v("position_error_m").to_bits(), e.position_m().to_bits());
        assert_eq!(
            v("orientation_error_deg").to_bits(),
            e.orientation_deg().to_bits()
        );
        rows += 1;
    }
    assert_eq!(rows, 3);
    let sum = json(&out.join("summary.json"));
    assert_eq!(sum["nominal"]["f"], s["truth_f"]);
    for k in ["p50", "p95", "p99", "max", "mean"] {
        assert_eq!(
            sum["statistics"]["base_disturbance_deg"][k], s["base_disturbance_deg"],
            "{k}"
        );
    }
}

/// `--jobs 1` and `--jobs 2` write the same files; two and three shards merged (given in
/// any order) write what one run writes, byte for byte.
/// Verifies RL-SIM-DISP-002, RL-SIM-DISP-003.
#[test]
fn jobs_and_shards_do_not_change_the_results() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let one = same_over_jobs_and_shards(tmp.path(), &dir, &[]);
    // The draws really moved the figures, and the drawn parameters are in the table.
    let csv = read(&one.join("runs.csv"));
    assert_eq!(csv.lines().count(), 1 + 7);
    assert!(csv.lines().next().unwrap().contains("link3.mass_kg"));
    let s = json(&one.join("summary.json"));
    assert_eq!(s["mode"], "open_loop");
    assert_ne!(
        s["statistics"]["base_disturbance_deg"]["max"],
        s["nominal"]["base_disturbance_deg"]
    );
}

/// `--closed-loop` flies the same robots as the open-loop run of the same seed (the drawn
/// columns of runs.csv are equal), adds the closed loop's columns and summary, commands
/// nothing beyond a rate limit, holds the base better than the open loop, and writes the
/// same files for any `--jobs` and any sharding.
/// Verifies RL-SIM-LOOP-001.
#[test]
fn closed_loop_runs_fly_the_same_robots_over_jobs_and_shards() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let closed = same_over_jobs_and_shards(tmp.path(), &dir, &["--closed-loop"]);
    let open = tmp.path().join("open");
    ok(&disperse(
        &dir,
        &open,
        &[&DISPERSED[..], &["--samples", "7"]].concat(),
    ));
    let table = |p: &Path| -> Vec<Vec<String>> {
        let text = read(&p.join("runs.csv"));
        text.lines()
            .map(|l| l.split(',').map(String::from).collect())
            .collect()
    };
    let (c, o) = (table(&closed), table(&open));
    let extra = host_sim::dispersion_report::LOOP_COLUMNS.len();
    assert_eq!(c[0].len(), o[0].len() + extra);
    assert_eq!(c[0][6], "extra_time_s");
    for (rc, ro) in c.iter().zip(&o) {
        // sample, then the drawn parameters after the figures (and the loop's columns).
        assert_eq!(rc[0], ro[0]);
        assert_eq!(rc[6 + extra..], ro[6..]);
    }
    let s = json(&closed.join("summary.json"));
    let so = json(&open.join("summary.json"));
    assert_eq!(s["mode"], "closed_loop");
    let cl = &s["closed_loop"];
    assert_eq!(cl["statistics"]["rate_violations"], 0);
    assert_eq!(cl["statistics"]["safe_stops"], 0);
    assert!(cl["statistics"]["extra_time_s"]["max"].as_f64().unwrap() <= 3.0 + 1e-9);
    let base = |v: &Value| {
        v["statistics"]["base_disturbance_deg"]["max"]
            .as_f64()
            .unwrap()
    };
    assert!(
        base(&s) < 0.25 * base(&so),
        "{} against {}",
        base(&s),
        base(&so)
    );
    assert!(read(&closed.join("summary.md")).contains("Flown closed-loop"));
}

/// `--closed-loop --export-sample K --out DIR` writes the sample's dispersed robot, its
/// flown joint path at the plan's step (t_f plus the 3 s extension), the task and the
/// per-cycle trace, and with `--plots` the flight's figures and the loop's (`closed_loop`:
/// the base rotation and its estimate, the commands less the plan, the end effector's
/// distance to the target); `--plots` with an open-loop export is refused.
/// Verifies RL-SIM-LOOP-003.
#[test]
fn a_closed_loop_sample_exports_its_flight() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let out = tmp.path().join("s2");
    ok(&disperse(
        &dir,
        &out,
        &[
            &DISPERSED[..],
            &["--closed-loop", "--export-sample", "2", "--plots"],
        ]
        .concat(),
    ));
    for f in [
        "robot.urdf",
        "task.toml",
        "joints.png",
        "base_attitude.svg",
        "summary.json",
        "closed_loop.png",
        "closed_loop.svg",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let path = read(&out.join("trajectory.csv"));
    assert!(path.starts_with("t,q1,q2,q3,q4,q5,q6,q7,qd1,qd2,qd3,qd4,qd5,qd6,qd7\n"));
    assert_eq!(path.lines().count(), 1 + 3301);
    assert!(
        path.lines().last().unwrap().starts_with("33.0"),
        "{:?}",
        path.lines().last()
    );
    let cycles = read(&out.join("cycles.csv"));
    assert!(cycles.starts_with("t_s,theta_x_deg"));
    assert_eq!(cycles.lines().count(), 1 + 330);
    let o = disperse(
        &dir,
        &tmp.path().join("bad.urdf"),
        &[&DISPERSED[..], &["--export-sample", "2", "--plots"]].concat(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--closed-loop"));
}

/// Runs `disperse` of 7 samples with `extra` at `--jobs` 1 and 2 and in 2 and 3 shards
/// merged, asserts every file is the same, and returns the first run's directory.
fn same_over_jobs_and_shards(tmp: &Path, dir: &Path, extra: &[&str]) -> PathBuf {
    let tag = extra.concat().replace('-', "");
    let one = tmp.join(format!("one{tag}"));
    let mut args: Vec<&str> = DISPERSED.to_vec();
    args.extend(["--samples", "7"]);
    args.extend(extra);
    ok(&disperse(
        dir,
        &one,
        &[&args[..], &["--jobs", "1"]].concat(),
    ));
    let two = tmp.join("two");
    ok(&disperse(
        dir,
        &two,
        &[&args[..], &["--jobs", "2"]].concat(),
    ));
    let files = ["runs.csv", "summary.json", "summary.md", "sensitivity.csv"];
    for f in files {
        assert_eq!(read(&one.join(f)), read(&two.join(f)), "{f}");
    }
    for m in [2, 3] {
        let mut shards = Vec::new();
        for i in (1..=m).rev() {
            let s = tmp.join(format!("s{i}of{m}"));
            let shard = format!("{i}/{m}");
            ok(&disperse(
                dir,
                &s,
                &[&args[..], &["--shard", &shard]].concat(),
            ));
            shards.push(s);
        }
        let merged = tmp.join(format!("merged{m}"));
        let o = host_sim()
            .arg("merge")
            .args(&shards)
            .arg("--out")
            .arg(&merged)
            .output()
            .unwrap();
        ok(&o);
        for f in files {
            assert_eq!(read(&one.join(f)), read(&merged.join(f)), "{m} shards: {f}");
        }
    }
    one
}

/// The exported URDF of a sample reads back to exactly the drawn parameters.
/// Verifies RL-SIM-DISP-004.
#[test]
fn an_exported_sample_reads_back_to_the_drawn_bits() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let file = tmp.path().join("s3.urdf");
    let o = host_sim()
        .arg("disperse")
        .arg(&dir)
        .args(["--export-sample", "3", "--out"])
        .arg(&file)
        .args(DISPERSED)
        .output()
        .unwrap();
    ok(&o);
    let nominal = host_sim::urdf::parse(&read(&dir.join("robot.urdf")), None).unwrap();
    let settings = Settings {
        mass_rel_sigma: 0.05,
        inertia_rel_sigma: 0.10,
        com_sigma_m: 0.01,
        axis_sigma_deg: 0.1,
        base_rate_sigma_deg_s: 0.001,
        truncation_sigmas: 3.0,
    };
    let want = Draw::sample(&nominal, &settings, 7, 3).unwrap();
    let back = host_sim::urdf::parse(&read(&file), None).unwrap();
    let got = Draw::nominal(&back);
    assert_eq!(got.mass, want.mass);
    assert_eq!(got.com, want.com);
    assert_eq!(got.inertia, want.inertia);
    assert_eq!(got.axis, want.axis);
    assert_ne!(got.mass, Draw::nominal(&nominal).mass);
    let orig = host_sim::urdf::parse(&read(&dir.join("robot.urdf")), None).unwrap();
    let round = host_sim::urdf::parse(&host_sim::urdf::write(&orig), None).unwrap();
    assert_eq!(round.desc::<7>().unwrap(), orig.desc::<7>().unwrap());
}

/// Bad input: each gets exit 2, a message naming what was wrong, and nothing written.
/// Verifies RL-SIM-DISP-005.
#[test]
fn bad_dispersion_input_is_refused_and_writes_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let out = tmp.path().join("never");
    for (args, want) in [
        (
            vec!["--samples", "2", "--seed", "1", "--mass-rel-sigma", "-0.1"],
            "--mass-rel-sigma = -0.1",
        ),
        (
            vec!["--samples", "2", "--seed", "1", "--com-sigma-m", "nan"],
            "--com-sigma-m = NaN",
        ),
        (
            vec!["--samples", "2", "--seed", "1", "--axis-sigma-deg", "inf"],
            "--axis-sigma-deg = inf",
        ),
        (
            vec!["--samples", "2", "--seed", "1", "--truncation-sigmas", "0"],
            "--truncation-sigmas = 0",
        ),
        (
            vec!["--samples", "2", "--seed", "1", "--shard", "3/2"],
            "shard 3 does not exist",
        ),
        (vec!["--samples", "0", "--seed", "1"], "--samples 0"),
        (
            vec!["--samples", "2", "--seed", "1", "--shard", "3/3"],
            "2 samples cannot be cut into 3 shards",
        ),
    ] {
        let o = disperse(&dir, &out, &args);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
    // An unknown key in the bundle's [dispersion] table.
    let bad = tmp.path().join("bad");
    std::fs::create_dir(&bad).unwrap();
    for f in ["summary.json", "trajectory.csv", "robot.urdf"] {
        std::fs::copy(dir.join(f), bad.join(f)).unwrap();
    }
    let task = read(&dir.join("task.toml")) + "\n[dispersion]\nmass_sigma = 0.05\n";
    std::fs::write(bad.join("task.toml"), task).unwrap();
    let o = disperse(&bad, &out, &["--samples", "2", "--seed", "1"]);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains("mass_sigma"), "{err}");
    assert!(!out.exists());

    // Merge: shards of different runs, a shard twice, a shard missing.
    let shard = |name: &str, seed: &str, s: &str| {
        let p = tmp.path().join(name);
        ok(&disperse(
            &dir,
            &p,
            &[
                "--samples",
                "4",
                "--seed",
                seed,
                "--mass-rel-sigma",
                "0.05",
                "--shard",
                s,
            ],
        ));
        p
    };
    let a1 = shard("a1", "1", "1/2");
    let a2 = shard("a2", "1", "2/2");
    let b2 = shard("b2", "2", "2/2");
    for (set, want) in [
        (vec![&a1, &b2], "not shards of one run"),
        (vec![&a1, &a1, &a2], "given twice"),
        (vec![&a1], "missing"),
        (vec![&a1, &dir], "manifest.json"),
    ] {
        let o = host_sim()
            .arg("merge")
            .args(&set)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set:?}: {err}");
        assert!(err.contains(want), "{set:?}: {err}");
        assert!(!out.exists());
    }
}

/// A campaign in two shards merged is the one-machine campaign (wall times aside).
/// Verifies RL-SIM-DISP-003.
#[test]
fn campaign_shards_merge_to_the_whole_campaign() {
    let tmp = tempfile::tempdir().unwrap();
    let task = root().join("tests/records/tasks/arm6/task_002.toml");
    let camp = |out: &Path, extra: &[&str]| {
        let o = host_sim()
            .arg("campaign")
            .arg(&task)
            .args(["--seeds", "1..3", "--out"])
            .arg(out)
            .args(extra)
            .output()
            .unwrap();
        ok(&o);
    };
    let one = tmp.path().join("one");
    camp(&one, &[]);
    let (s1, s2) = (tmp.path().join("s1"), tmp.path().join("s2"));
    camp(&s1, &["--shard", "1/2"]);
    camp(&s2, &["--shard", "2/2"]);
    let merged = tmp.path().join("merged");
    ok(&host_sim()
        .arg("merge")
        .args([&s2, &s1])
        .arg("--out")
        .arg(&merged)
        .output()
        .unwrap());
    let strip = |p: &Path| -> Vec<Vec<String>> {
        let mut r = csv::Reader::from_path(p).unwrap();
        let head = r.headers().unwrap().clone();
        let wall = head.iter().position(|h| h == "wall_time_s").unwrap();
        r.records()
            .map(|x| {
                let x = x.unwrap();
                x.iter()
                    .enumerate()
                    .filter(|(i, _)| *i != wall)
                    .map(|(_, v)| v.to_string())
                    .collect()
            })
            .collect()
    };
    assert_eq!(
        strip(&one.join("runs.csv")),
        strip(&merged.join("runs.csv"))
    );
    assert_eq!(strip(&one.join("runs.csv")).len(), 3);
}

/// Off a terminal (a batch log), a run of 100 samples or more reports its progress on
/// stderr at every tenth; a smaller one only its result.
/// Verifies RL-SIM-DISP-008.
#[test]
fn long_runs_log_their_progress_off_a_terminal() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = rollout(tmp.path());
    let o = disperse(
        &dir,
        &tmp.path().join("d100"),
        &[
            "--samples",
            "100",
            "--seed",
            "1",
            "--mass-rel-sigma",
            "0.05",
        ],
    );
    ok(&o);
    let err = String::from_utf8_lossy(&o.stderr);
    let lines: Vec<&str> = err
        .lines()
        .filter(|l| l.starts_with("disperse: ") && l.contains("/100 samples ("))
        .collect();
    assert_eq!(lines.len(), 10, "{err}");
    assert!(
        lines[9].starts_with("disperse: 100/100 samples (100%), "),
        "{err}"
    );
    let o = disperse(
        &dir,
        &tmp.path().join("d99"),
        &["--samples", "99", "--seed", "1", "--mass-rel-sigma", "0.05"],
    );
    ok(&o);
    assert!(!String::from_utf8_lossy(&o.stderr).contains("/99 samples ("));
}
