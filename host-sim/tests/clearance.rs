//! Clearance (spec §13, issue #33): the collision geometry of the URDF and the task's
//! keep-outs read or refused, and the clearance of a path measured with no tunnelling.
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use assert_cmd::Command;
use host_sim::clearance::{Scene, Side};
use host_sim::taskfile::{LoadedTask, from_texts};
use proptest::prelude::*;
use std::path::{Path, PathBuf};

const ETA_HAT: &str = "3.14771,0.809316,1.12249,0.754006,4.7352,0.406031,-4.1572,4.29895";

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn paper_text() -> String {
    std::fs::read_to_string(root().join("spec/tasks/paper.toml")).unwrap()
}

fn urdf_text() -> String {
    std::fs::read_to_string(root().join("spec/chaser7.urdf")).unwrap()
}

fn q0() -> Vec<f64> {
    [-90.0f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0]
        .iter()
        .map(|d| d.to_radians())
        .collect()
}

fn loaded(extra: &str) -> LoadedTask {
    let text = paper_text().replace("\"../chaser7.urdf\"", "\"robot.urdf\"") + extra;
    from_texts(Path::new("task.toml"), &text, &urdf_text()).unwrap()
}

/// `rollout` of the reference η on a task and URDF edited by `task` and `urdf`: refused
/// with exit 2, one message containing every `want`, and nothing written.
fn refused(task: &str, urdf: impl Fn(String) -> String, want: &[&str]) {
    let tmp = tempfile::tempdir().unwrap();
    std::fs::write(tmp.path().join("robot.urdf"), urdf(urdf_text())).unwrap();
    let text = paper_text().replace("\"../chaser7.urdf\"", "\"robot.urdf\"") + task;
    std::fs::write(tmp.path().join("task.toml"), text).unwrap();
    let out = tmp.path().join("out");
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .arg("rollout")
        .arg(tmp.path().join("task.toml"))
        .args([&format!("--eta={ETA_HAT}"), "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "one message: {err}");
    for w in want {
        assert!(err.contains(w), "message {err:?} lacks {w:?}");
    }
    assert!(!out.exists(), "output created on bad input");
}

fn keep_out(body: &str) -> String {
    format!("\n[[keep_out]]\nname = \"probe\"\n{body}\n")
}

/// Bad collision input is refused with exit 2, one message naming the file and the key,
/// and nothing written.
/// Verifies RL-COLL-003.
#[test]
fn bad_collision_input_is_named_and_writes_nothing() {
    let same = |s: String| s;
    let far = "position_m = [5.0, 5.0, 5.0]";
    refused(
        &keep_out(&format!("shape = \"sphere\"\n{far}\nradius_m = -0.1")),
        same,
        &["task.toml", "[[keep_out]] 'probe'", "finite numbers >= 0"],
    );
    refused(
        &keep_out(&format!(
            "shape = \"box\"\n{far}\nhalf_extents_m = [0.1, inf, 0.1]"
        )),
        same,
        &["task.toml", "half_extents_m", "3 finite numbers"],
    );
    refused(
        &keep_out("shape = \"sphere\"\nposition_m = [1.0, 0.0, 0.5]\nradius_m = 0.2"),
        same,
        &[
            "task.toml",
            "keep-out 'probe' overlaps 'link",
            "start configuration",
        ],
    );
    refused(
        &keep_out(&format!("shape = \"cone\"\n{far}\nradius_m = 0.1")),
        same,
        &["task.toml", "shape", "\"box\", \"sphere\" or \"capsule\""],
    );
    refused(
        &keep_out(&format!("shape = \"capsule\"\n{far}\nradius_m = 0.1")),
        same,
        &["task.toml", "length_m is missing"],
    );
    refused(
        "\n[collision]\nclearance_m = -0.01\n",
        same,
        &["task.toml", "[collision] clearance_m = -0.01"],
    );
    refused(
        "\n[collision]\nignore = [[\"link2\", \"antenna\"]]\n",
        same,
        &["task.toml", "[collision] ignore[0]", "'antenna'"],
    );
    let many: String = (0..9)
        .map(|k| format!("\n[[keep_out]]\nname = \"k{k}\"\nshape = \"sphere\"\nposition_m = [9.0, {k}.0, 9.0]\nradius_m = 0.1\n"))
        .collect();
    refused(
        &many,
        same,
        &["task.toml", "[[keep_out]] has 9 entries", "at most 8"],
    );
    let mesh = |s: String| {
        s.replacen(
            r#"<geometry><box size="1.4805 2.3511 1.2909"/></geometry>"#,
            r#"<geometry><mesh filename="bus.stl"/></geometry>"#,
            1,
        )
    };
    refused("", mesh, &["robot.urdf", "link 'base'", "mesh 'bus.stl'"]);
    let cylinder = |s: String| s.replacen("name=\"link2_capsule\"", "name=\"link2_tube\"", 1);
    refused(
        "",
        cylinder,
        &["robot.urdf", "link 'link2'", "<cylinder>", "capsule"],
    );
    let negative = |s: String| s.replacen("radius=\"0.0669\"", "radius=\"-0.0669\"", 1);
    refused(
        "",
        negative,
        &["robot.urdf", "link 'link2'", "negative or non-finite size"],
    );
    let crowded = |s: String| {
        let extra: String = (0..10)
            .map(|k| format!("<collision name=\"s{k}\"><origin xyz=\"0 0 0\" rpy=\"0 0 0\"/><geometry><sphere radius=\"0.01\"/></geometry></collision>"))
            .collect();
        s.replacen(
            "<collision name=\"bus\">",
            &format!("{extra}<collision name=\"bus\">"),
            1,
        )
    };
    refused(
        "",
        crowded,
        &["robot.urdf", "18 collision primitives", "at most 16"],
    );
}

/// The pairs of spec §13: links with no joint between them, each link but the first
/// against the base, every body against every keep-out, less the ignored pairs.
/// Verifies RL-COLL-004.
#[test]
fn the_checked_pairs_are_those_of_the_spec() {
    let scene = loaded("").scene(&q0()).unwrap();
    let body = |i: usize| Side::Body(i);
    assert_eq!(scene.pairs.len(), 21, "{:?}", scene.pairs);
    assert!(scene.pairs.contains(&(body(0), body(2))));
    assert!(
        !scene.pairs.contains(&(body(0), body(1))),
        "the first link is not checked against the base"
    );
    assert!(
        !scene
            .pairs
            .iter()
            .any(|(a, b)| matches!((a, b), (Side::Body(i), Side::Body(j)) if j - i < 2))
    );
    assert!(
        !scene.enforced,
        "no [collision] and no keep-out: reported, not required"
    );
    let ko = loaded(
        "\n[[keep_out]]\nname = \"probe\"\nshape = \"sphere\"\nposition_m = [5.0, 5.0, 5.0]\nradius_m = 0.1\n\
         \n[collision]\nignore = [[\"link4\", \"link6\"], [\"probe\", \"base\"]]\n",
    );
    let scene = ko.scene(&q0()).unwrap();
    assert_eq!(scene.pairs.len(), 21 - 1 + 8 - 1);
    assert!(scene.enforced);
    assert!(!scene.pairs.contains(&(body(4), body(6))));
    assert!(!scene.pairs.contains(&(body(0), Side::KeepOut(0))));
}

/// The point of link 7's frame, inertial frame (m).
fn wrist(scene: &Scene, q: &[f64]) -> [f64; 3] {
    let f = scene.frames(q);
    let p = f[7].1;
    [p.x, p.y, p.z]
}

/// A plate across the path of the wrist between two samples: the plate's normal along the
/// chord between the wrist's two positions, at its midpoint, 1 mm thick, 0.24 m wide.
fn plate_between(scene: &Scene, qa: &[f64], qb: &[f64]) -> String {
    let (a, b) = (wrist(scene, qa), wrist(scene, qb));
    let d: Vec<f64> = (0..3).map(|k| b[k] - a[k]).collect();
    let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    let mid: Vec<f64> = (0..3).map(|k| 0.5 * (a[k] + b[k])).collect();
    let yaw = d[1].atan2(d[0]).to_degrees();
    let pitch = (-d[2] / n).asin().to_degrees();
    format!(
        "\n[[keep_out]]\nname = \"plate\"\nshape = \"box\"\nposition_m = [{}, {}, {}]\nrpy_deg = [0.0, {pitch}, {yaw}]\nhalf_extents_m = [0.0005, 0.12, 0.12]\n",
        mid[0], mid[1], mid[2]
    )
}

/// A link that sweeps through a thin plate between two samples is caught: at both samples
/// the wrist is clear of the plate by tens of centimetres, yet the path's clearance is
/// negative. No tunnelling.
/// Verifies RL-COLL-005.
#[test]
fn a_link_sweeping_through_a_thin_plate_between_two_samples_is_caught() {
    let qa = q0();
    let mut qb = qa.clone();
    qb[0] += 0.8;
    let probe = loaded("").scene(&qa).unwrap();
    let lt = loaded(&plate_between(&probe, &qa, &qb));
    let scene = lt.scene(&qa).unwrap();
    let sweep = scene.sweep(&[0.0, 1.0], &[qa.clone(), qb.clone()]);
    let plate: Vec<_> = sweep
        .pairs
        .iter()
        .filter(|p| matches!(p.pair.1, Side::KeepOut(0)))
        .collect();
    let at_samples = plate
        .iter()
        .map(|p| p.min_at_samples_m)
        .fold(f64::INFINITY, f64::min);
    let on_path = plate.iter().map(|p| p.min_m).fold(f64::INFINITY, f64::min);
    let (a, b) = (wrist(&probe, &qa), wrist(&probe, &qb));
    let chord = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
    let detail: Vec<_> = plate
        .iter()
        .map(|p| (p.pair, p.min_at_samples_m, p.min_m))
        .collect();
    assert!(
        at_samples > 0.1,
        "clear at both samples: {at_samples}, chord {chord}: {detail:?}"
    );
    assert!(
        on_path < 0.0,
        "the plate is crossed between them: {on_path}"
    );
    assert!(!sweep.pass());
}

fn dense_min(scene: &Scene, qa: &[f64], qb: &[f64], pair: (Side, Side), m: usize) -> f64 {
    (0..=m)
        .map(|k| {
            let u = k as f64 / m as f64;
            let q: Vec<f64> = qa.iter().zip(qb).map(|(a, b)| a + u * (b - a)).collect();
            scene.pair_distance(&scene.frames(&q), pair.0, pair.1).0
        })
        .fold(f64::INFINITY, f64::min)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(24))]

    /// A reported clearance is never larger than a dense evaluation of the same path finds
    /// (2,000 points per interval): the reported minimum is attained by the path.
    /// Verifies RL-COLL-005.
    #[test]
    fn a_reported_clearance_is_never_larger_than_a_dense_evaluation(
        dq in prop::collection::vec(-0.5..0.5f64, 7),
        ox in -0.3..0.3f64, oy in -0.3..0.3f64, oz in -0.3..0.3f64,
    ) {
        let qa = q0();
        let qb: Vec<f64> = qa.iter().zip(&dq).map(|(a, d)| a + d).collect();
        let probe = loaded("").scene(&qa).unwrap();
        let w = wrist(&probe, &qb);
        let ko = format!(
            "\n[[keep_out]]\nname = \"ball\"\nshape = \"sphere\"\nposition_m = [{}, {}, {}]\nradius_m = 0.05\n",
            w[0] + ox, w[1] + oy, w[2] + oz
        );
        let text = paper_text().replace("\"../chaser7.urdf\"", "\"robot.urdf\"") + &ko;
        let Ok(lt) = from_texts(Path::new("task.toml"), &text, &urdf_text()) else {
            return Ok(()); // the ball touches the start: refused, nothing to sweep
        };
        let scene = lt.scene(&qa).unwrap();
        let sweep = scene.sweep(&[0.0, 1.0], &[qa.clone(), qb.clone()]);
        for p in &sweep.pairs {
            let dense = dense_min(&scene, &qa, &qb, p.pair, 2000);
            prop_assert!(p.min_m <= dense + 1e-12, "{:?}: reported {} > dense {dense}", p.pair, p.min_m);
        }
    }
}

/// `generate --keep-out-radius-m` writes a keep-out across the straight line from the
/// start's end effector to the target and a `[collision]` table, and the generating η's own
/// path keeps the required clearance (a collision-free plan exists).
/// Verifies RL-COLL-007.
#[test]
fn generate_blocks_the_straight_line_and_keeps_a_clear_witness() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("gen");
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .args(["generate", "--urdf"])
        .arg(root().join("tests/robots/arm6.urdf"))
        .args([
            "--ee",
            "ee",
            "--q-deg=10,-20,30,-40,50,-60",
            "--count",
            "1",
            "--seed",
            "3",
        ])
        .args([
            "--min-motion-m",
            "0.5",
            "--keep-out-radius-m",
            "0.1",
            "--clearance-m",
            "0.01",
        ])
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let task = out.join("task_001.toml");
    let text = std::fs::read_to_string(&task).unwrap();
    assert!(
        text.contains("[[keep_out]]") && text.contains("clearance_m = 0.01"),
        "{text}"
    );
    let eta = text
        .lines()
        .find_map(|l| l.strip_prefix("# rolling out eta = ["))
        .and_then(|l| l.split(']').next())
        .unwrap()
        .replace(' ', "");
    let dir = tmp.path().join("witness");
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .arg("rollout")
        .arg(&task)
        .arg(format!("--eta={eta}"))
        .args(["--paper", "--out"])
        .arg(&dir)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .arg("check")
        .arg(&dir)
        .output()
        .unwrap();
    let table = String::from_utf8_lossy(&o.stdout);
    let line = table
        .lines()
        .find(|l| l.starts_with("clearance ("))
        .unwrap();
    assert!(line.contains(" pass "), "{line}");
    assert!(line.contains(">= 0.01 m"), "{line}");
}

/// Verifies RL-COLL-009 and RL-COLL-012: a keep-out beside the unconstrained plan's
/// end-effector path, into which that plan runs (a task of the benchmark set,
/// `scripts/blocked-set.py`), is planned around: the plan converges, states its clearance,
/// and `check` passes it, clearance included; the same task without `[collision]` and the
/// keep-out plans a path that `check` fails on the keep-out.
/// `host-sim ARGS…`: its exit code and everything it printed (the summaries go to stderr
/// when stdout is not a terminal).
fn host_sim(args: &[&std::ffi::OsStr]) -> (Option<i32>, String) {
    let o = Command::cargo_bin("host-sim")
        .unwrap()
        .args(args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&o.stdout) + String::from_utf8_lossy(&o.stderr);
    (o.status.code(), text.into_owned())
}

#[test]
fn a_keep_out_on_the_unconstrained_path_is_planned_around() {
    let task = root().join("tests/tasks/collision/blocked/arm9/b-task_006.toml");
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("plan");
    let (code, text) = host_sim(&[
        "plan".as_ref(),
        task.as_ref(),
        "--out".as_ref(),
        out.as_ref(),
    ]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("plan: converged"), "{text}");
    let line = text
        .lines()
        .find(|l| l.contains("smallest clearance"))
        .unwrap();
    assert!(line.contains("requirement ≥ 0.02 m: ok"), "{line}");
    let json = tmp.path().join("clearance.json");
    let (code, report) = host_sim(&[
        "check".as_ref(),
        out.as_ref(),
        "--clearance-json".as_ref(),
        json.as_ref(),
    ]);
    assert_eq!(code, Some(0), "{report}");
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(v["pass"], true);
    let keep = v["pairs"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["b_is_keep_out"] == true)
        .map(|p| p["min_m"].as_f64().unwrap())
        .fold(f64::INFINITY, f64::min);
    assert!(keep >= 0.02, "keep-out at {keep} m");
    // Without [collision] and [[keep_out]], the plan runs into the sphere: the constraint
    // changed the path.
    let text = std::fs::read_to_string(&task).unwrap();
    let free = &text[..text.find("\n# Beside the unconstrained plan").unwrap()];
    let robots = format!("urdf = \"{}/tests/robots/", root().display());
    std::fs::write(
        tmp.path().join("free.toml"),
        free.replace("urdf = \"../../../../robots/", &robots),
    )
    .unwrap();
    let (free_toml, free_out) = (tmp.path().join("free.toml"), tmp.path().join("free"));
    let (code, text) = host_sim(&[
        "plan".as_ref(),
        free_toml.as_ref(),
        "--out".as_ref(),
        free_out.as_ref(),
    ]);
    assert_eq!(code, Some(0), "{text}");
    // The written plan against the task with the keep-out (its URDF the plan's copy).
    let with = text_of(&task).replace(
        "urdf = \"../../../../robots/arm9.urdf\"",
        "urdf = \"robot.urdf\"",
    );
    std::fs::write(free_out.join("task.toml"), with).unwrap();
    let (code, report) = host_sim(&["check".as_ref(), free_out.as_ref()]);
    assert_eq!(code, Some(1), "the unconstrained plan collides: {report}");
    assert!(report.contains("keep-out 'blocker'"), "{report}");
}

fn text_of(p: &Path) -> String {
    std::fs::read_to_string(p).unwrap()
}
