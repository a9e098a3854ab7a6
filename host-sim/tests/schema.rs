//! Every JSON output has a published schema (docs/schema/*.schema.json), generated from the
//! types that write it, and real outputs validate against it. Bless a justified change of
//! an output with `BLESS=1 cargo test -p host-sim --test schema` and review the diff.
//! Requirements: RL-SIM-OUT (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

use assert_cmd::Command;
use schemars::schema_for;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn schemas() -> Vec<(&'static str, Value)> {
    let v = |s: schemars::Schema| serde_json::to_value(s).unwrap();
    vec![
        ("plan", v(schema_for!(host_sim::cmd::plan::PlanJson))),
        (
            "plan-two-phase",
            v(schema_for!(host_sim::preshaping::TwoPhaseJson)),
        ),
        ("summary", v(schema_for!(host_sim::artifacts::Summary))),
        ("retime", v(schema_for!(host_sim::retiming::RetimeSummary))),
        ("record", v(schema_for!(host_sim::records::Record))),
        ("bench", v(schema_for!(host_sim::cmd::bench::BenchJson))),
        ("frames", v(schema_for!(host_sim::cmd::frames::FramesJson))),
        ("target", v(schema_for!(host_sim::cmd::target::TargetJson))),
        ("model", v(schema_for!(host_sim::cmd::model::ModelReport))),
        (
            "disperse",
            v(schema_for!(host_sim::dispersion_report::Report)),
        ),
        ("manifest", v(schema_for!(host_sim::shards::Manifest))),
        (
            "flight",
            v(schema_for!(host_sim::closed_loop::FlightSummary)),
        ),
    ]
}

/// The checked-in schemas are the ones the code generates.
/// Verifies RL-SIM-OUT-004.
#[test]
fn published_schemas_match_the_code() {
    let dir = root().join("docs/schema");
    let bless = std::env::var_os("BLESS").is_some();
    for (name, schema) in schemas() {
        let path = dir.join(format!("{name}.schema.json"));
        let text = serde_json::to_string_pretty(&schema).unwrap() + "\n";
        if bless {
            std::fs::write(&path, &text).unwrap();
            continue;
        }
        let on_disk = std::fs::read_to_string(&path)
            .unwrap_or_else(|e| panic!("{}: {e} (BLESS=1 to write it)", path.display()));
        assert_eq!(
            on_disk, text,
            "{name}: the schema changed; BLESS=1 to accept"
        );
    }
}

fn valid(name: &str, instance: &Value) {
    let (_, schema) = schemas().into_iter().find(|(n, _)| *n == name).unwrap();
    let validator = jsonschema::validator_for(&schema).unwrap();
    let errors: Vec<String> = validator
        .iter_errors(instance)
        .map(|e| format!("{} at {}", e, e.instance_path))
        .collect();
    assert!(errors.is_empty(), "{name}: {errors:#?}");
}

fn host_sim() -> Command {
    Command::cargo_bin("host-sim").unwrap()
}

fn json_of(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

/// Real outputs of plan (both strategies, refined and not), rollout, record, bench,
/// frames, model and disperse (its summary and manifest) validate against their schemas.
/// Verifies RL-SIM-OUT-004.
#[test]
fn every_output_validates_against_its_schema() {
    let tmp = tempfile::tempdir().unwrap();
    let paper = root().join("spec/tasks/paper.toml");
    for (i, args) in [
        vec!["--strategy", "multistart"],
        vec!["--strategy", "cpso", "--seed", "3"],
        vec!["--refine-tolerance", "1e-9", "--refine-against", "truth"],
    ]
    .into_iter()
    .enumerate()
    {
        let out = tmp.path().join(format!("plan{i}"));
        let r = host_sim()
            .arg("plan")
            .arg(&paper)
            .args(&args)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        valid("plan", &json_of(&out.join("plan.json")));
        valid("summary", &json_of(&out.join("summary.json")));
    }
    let rec = tmp.path().join("rec.json");
    let r = host_sim()
        .arg("record")
        .arg(&paper)
        .arg("--out")
        .arg(&rec)
        .output()
        .unwrap();
    assert!(r.status.success());
    valid("record", &json_of(&rec));
    for old in std::fs::read_dir(root().join("tests/records")).unwrap() {
        let p = old.unwrap().path();
        if p.extension().is_some_and(|e| e == "json") {
            valid("record", &json_of(&p));
        }
    }
    let stdout_json = |args: &[&str]| -> Value {
        let r = host_sim().args(args).output().unwrap();
        assert!(
            r.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&r.stderr)
        );
        serde_json::from_slice(&r.stdout).unwrap()
    };
    let p = paper.to_str().unwrap();
    valid("frames", &stdout_json(&["frames", p, "--json"]));
    valid("bench", &stdout_json(&["bench", p, "--json"]));
    let urdf = root().join("spec/chaser7.urdf");
    valid(
        "model",
        &stdout_json(&[
            "model",
            "--urdf",
            urdf.to_str().unwrap(),
            "--q-deg",
            "-90,45,0,80,-90,-45,-10",
        ]),
    );
    let disp = tmp.path().join("disperse");
    let r = host_sim()
        .arg("disperse")
        .arg(tmp.path().join("plan0"))
        .args(["--samples", "3", "--seed", "1", "--mass-rel-sigma", "0.05"])
        .args(["--base-rate-sigma-deg-s", "0.001", "--out"])
        .arg(&disp)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    valid("disperse", &json_of(&disp.join("summary.json")));
    valid("manifest", &json_of(&disp.join("manifest.json")));
    // An exported closed-loop flight, its base given an initial rate.
    let flight = tmp.path().join("flight");
    let r = host_sim()
        .arg("disperse")
        .arg(tmp.path().join("plan0"))
        .args(["--seed", "1", "--mass-rel-sigma", "0.05"])
        .args(["--base-rate-sigma-deg-s", "0.001", "--closed-loop"])
        .args(["--export-sample", "1", "--out"])
        .arg(&flight)
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let f = json_of(&flight.join("summary.json"));
    valid("flight", &f);
    assert!(f["initial_momentum"][0].as_f64().unwrap() != 0.0);
}
