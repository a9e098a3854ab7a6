//! The C ABI from C: `tests/c/abi_test.c` compiled with `gcc -std=c99 -Wall -Wextra
//! -Wpedantic -Werror` against this crate's staticlib, run on the reference task's block,
//! and compared with host-sim's record of the same task; the header compiled as C++11.
//!
//! Requirements: RL-FFI (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    clippy::indexing_slicing,
    missing_docs
)]

use host_sim::taskfile::{self, Overrides};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The staticlib next to this test (`target/<profile>/libreactionless_ffi.a`). `cargo test`
/// builds only the rlib for the tests, so this asks cargo for the staticlib of the same
/// profile first (a no-op when it is up to date; the build lock is free while tests run).
fn staticlib() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let profile_dir = exe.parent().unwrap().parent().unwrap();
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".into());
    let mut build = Command::new(cargo);
    build.args(["build", "-q", "-p", "reactionless-ffi"]);
    if profile_dir.file_name().is_some_and(|n| n == "release") {
        build.arg("--release");
    }
    let status = build.current_dir(root()).status().unwrap();
    assert!(status.success(), "cargo build -p reactionless-ffi failed");
    let lib = profile_dir.join("libreactionless_ffi.a");
    assert!(lib.exists(), "no staticlib at {}", lib.display());
    lib
}

fn out_dir() -> PathBuf {
    let d = staticlib().parent().unwrap().join("c-abi");
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn block_of(task: &str, out: &Path) {
    let lt = taskfile::load(&root().join(task)).unwrap();
    let bytes = host_sim::flight::task_block(&lt, &Overrides::default()).unwrap();
    std::fs::write(out, bytes).unwrap();
}

fn run(cmd: &mut Command) -> String {
    let o = cmd.output().unwrap();
    let text = String::from_utf8_lossy(&o.stdout).into_owned();
    assert!(
        o.status.success(),
        "{cmd:?} failed:\n{text}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    text
}

/// Compiles `sources` (in ffi/tests/c) as C99 with every warning an error, against the
/// checked-in header, and links them with the staticlib into `exe`.
fn compile_c(sources: &[&str], exe: &Path) {
    compile_c_in("ffi/tests/c", sources, exe);
}

/// [`compile_c`] of sources in `dir` (relative to the repository).
fn compile_c_in(dir: &str, sources: &[&str], exe: &Path) {
    let c = root().join(dir);
    let mut gcc = Command::new("gcc");
    gcc.args([
        "-std=c99",
        "-O2",
        "-Wall",
        "-Wextra",
        "-Wpedantic",
        "-Werror",
    ])
    .arg("-I")
    .arg(root().join("ffi/include"));
    for s in sources {
        gcc.arg(c.join(s));
    }
    gcc.arg(staticlib())
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(exe);
    run(&mut gcc);
}

/// Lines `KEY value` (and `ETA i value`) of the C program's output.
fn parse(text: &str) -> BTreeMap<String, String> {
    text.lines()
        .filter_map(|l| l.rsplit_once(' '))
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// The C program plans paper.toml's block through the C ABI at the task's frame budget,
/// checkpoints and restores once in the middle, streams the setpoints, and gets the bits of
/// host-sim's record: η, f, the counts and the trajectory digest; then flies the plan
/// closed-loop through `rl_loop` and gets the core's commands bit for bit. Every misuse check
/// (NULL pointers, bad ABI version and size, corrupted blocks and checkpoints, another
/// task's checkpoint, wrong states) returns its error.
/// Verifies RL-FFI-001, RL-FFI-002, RL-FFI-003, RL-FFI-004, RL-FFI-005, RL-FFI-014.
#[test]
fn c_program_matches_the_record_across_a_checkpoint() {
    let dir = out_dir();
    let (block, other) = (dir.join("paper.block"), dir.join("other.block"));
    block_of("spec/tasks/paper.toml", &block);
    block_of("tests/records/tasks/chaser7/task_002.toml", &other);
    let exe = dir.join("abi_test");
    compile_c(&["abi_test.c", "host_main.c"], &exe);
    let text = run(Command::new(&exe).arg(&block).arg(&other));
    println!("{text}");
    let got = parse(&text);

    let lt = taskfile::load(&root().join("spec/tasks/paper.toml")).unwrap();
    let rec = host_sim::records::outputs_of::<7, 4>(&lt, &Overrides::default())
        .unwrap()
        .outputs;
    let want = |k: &str, v: String| {
        assert_eq!(got.get(k), Some(&v), "{k}: C output\n{text}");
    };
    matches_record(&got, &text, &rec);
    want("FAILURES", "0".into());
    want("ITERATIONS", rec.iterations.to_string());
    want("STAGNATION", rec.stagnation_events.to_string());
    want("RESTARTS", rec.restarts.to_string());
    want("BUDGET", "3000".into());
    // The restore happened in the middle of planning, not after it.
    let frames: u32 = got["FRAMES"].parse().unwrap();
    let at: u32 = got["RESTORED_AT_FRAME"].parse().unwrap();
    assert!(at > 1 && at < frames, "restored at frame {at} of {frames}");
    let checks: u32 = got["CHECKS"].parse().unwrap();
    assert!(checks > 60, "{checks} checks");
    // The plan flown closed-loop through rl_loop: the core's commands bit for bit.
    let (digest, commands, _) = core_flight(&block);
    want("LOOP_DIGEST", digest);
    want("LOOP_CYCLES", (commands - 1).to_string());
    want(
        "LOOP_MODE",
        reactionless_ffi::closed_loop::RL_LOOP_DONE.to_string(),
    );
}

/// The same C program on the reference task integrated by AB5 (the block's integrator code
/// and stride, issue #32): host-sim's record of that task bit for bit, and the core's
/// closed-loop commands.
/// Verifies RL-CONT-010.
#[test]
fn c_program_plans_an_ab5_block() {
    let dir = out_dir();
    let mut lt = taskfile::load(&root().join("spec/tasks/paper.toml")).unwrap();
    lt.set_integrator(Some(reactionless::Integrator::Ab5))
        .unwrap();
    let block = dir.join("paper-ab5.block");
    std::fs::write(
        &block,
        host_sim::flight::task_block(&lt, &Overrides::default()).unwrap(),
    )
    .unwrap();
    let other = dir.join("other-ab5.block");
    block_of("tests/records/tasks/chaser7/task_002.toml", &other);
    let exe = dir.join("abi_test_ab5");
    compile_c(&["abi_test.c", "host_main.c"], &exe);
    let text = run(Command::new(&exe).arg(&block).arg(&other));
    let got = parse(&text);
    let rec = host_sim::records::outputs_of::<7, 4>(&lt, &Overrides::default())
        .unwrap()
        .outputs;
    matches_record(&got, &text, &rec);
    let (digest, commands, _) = core_flight(&block);
    assert_eq!(got.get("LOOP_DIGEST"), Some(&digest), "{text}");
    assert_eq!(
        got.get("LOOP_CYCLES"),
        Some(&(commands - 1).to_string()),
        "{text}"
    );
}

/// The C program's plan (`got`, parsed from its output `text`) is `rec`'s bit for bit:
/// status, rollouts, f, η, samples and the trajectory digest.
fn matches_record(got: &BTreeMap<String, String>, text: &str, rec: &host_sim::records::Outputs) {
    let want = |k: &str, v: String| {
        assert_eq!(got.get(k), Some(&v), "{k}: C output\n{text}");
    };
    want("RESULT", "ok".into());
    want("STATUS", rec.status.clone());
    want("ROLLOUTS", rec.rollouts.to_string());
    want("F", rec.f_bits.clone());
    for (i, b) in rec.eta_bits.iter().enumerate() {
        want(&format!("ETA {i}"), b.clone());
    }
    want("SAMPLES", rec.trajectory_samples.to_string());
    want("DIGEST", rec.trajectory_digest.clone());
}

/// The checked-in header compiles as C++11 with every warning an error, and links.
/// Verifies RL-FFI-006.
#[test]
fn header_compiles_as_cpp11() {
    let dir = out_dir();
    let exe = dir.join("header_cpp");
    run(Command::new("g++")
        .args(["-std=c++11", "-Wall", "-Wextra", "-Wpedantic", "-Werror"])
        .arg("-I")
        .arg(root().join("ffi/include"))
        .arg(root().join("ffi/tests/c/header_cpp.cpp"))
        .arg(staticlib())
        .args(["-lpthread", "-ldl", "-lm", "-o"])
        .arg(&exe));
    run(&mut Command::new(&exe));
}

/// A C program plans a two-phase block (the joint-space target 20° per joint away) with
/// `rl_two_phase` in frames of 25 units, through the checked-in header, and gets the bits
/// the host plans for the same task file: `q_s`, η, `f`, the counts, the inverse's `f`, the
/// base disturbance and the wheels' demand; then streams both phases, whose digests are the
/// host's (phase1.csv's, and phase 2's rollout from `q_s`). At frame 10 it checkpoints the
/// search, wipes its storage, initialises and restores it, and the bits stay the host's.
/// Verifies RL-FFI-011, RL-FFI-012.
#[test]
fn c_program_plans_a_two_phase_block() {
    let dir = out_dir();
    let task = "tests/tasks/g/chaser7/joint20/task_001.toml";
    let block = dir.join("two_phase.block");
    block_of(task, &block);
    let exe = dir.join("two_phase_test");
    compile_c(&["two_phase_test.c", "two_phase_main.c"], &exe);
    let text = run(Command::new(&exe).arg(&block));
    println!("{text}");
    let got = parse(&text);
    let lt = taskfile::load(&root().join(task)).unwrap();
    let host = host_sim::flight::flight_outputs(&lt, &Overrides::default()).unwrap();
    let field = |k: &str| {
        host.line
            .iter()
            .find(|(key, _)| key == k)
            .unwrap()
            .1
            .clone()
    };
    let want = |k: &str, v: String| {
        let k = format!("TWO_{k}");
        assert_eq!(got.get(&k), Some(&v), "{k}: C output\n{text}");
    };
    want("STATUS", reactionless_ffi::RL_CONVERGED.to_string());
    want("ROLLOUTS", host.outputs.rollouts.to_string());
    want("F", host.outputs.f_bits.clone());
    want("STARTS", field("starts"));
    want("STEPS1", field("steps1"));
    want("REACH_F", field("reach_f"));
    want("BASE", field("base"));
    want("MOMENTUM", field("momentum"));
    want("TORQUE", field("torque"));
    for (i, b) in host.q_s_bits.iter().enumerate() {
        want(&format!("QS{i}"), b.clone());
    }
    for (i, b) in host.outputs.eta_bits.iter().enumerate() {
        want(&format!("ETA{i}"), b.clone());
    }
    want("DIGEST1", field("digest1"));
    want("SAMPLES1", field("samples1"));
    want("DIGEST2", host.outputs.trajectory_digest.clone());
    want("SAMPLES2", host.outputs.trajectory_samples.to_string());
    let frames: u32 = got["TWO_FRAMES"].parse().unwrap();
    assert!(frames > 10, "{frames} frames");
}

/// `examples/c`, the cFS-style app, compiled as C99 with every warning an error against
/// the checked-in header and the staticlib: it plans the reference task across a simulated
/// processor reset, streams the record's trajectory digest, and flies the plan closed-loop
/// through `rl_loop` with one control cycle per wakeup, its commands bit-identical to the
/// core's `PlanLoop` under the same stand-in hardware (joints that follow each command
/// exactly, a base held still). With the encoders reading NaN from the 50th flight wakeup
/// on, the app reports the fault once as an error event and ends at rest in its safe state.
/// Verifies RL-FFI-008, RL-FFI-014.
#[test]
fn cfs_example_flies_the_plan_closed_loop() {
    let dir = out_dir();
    let block = dir.join("paper.block");
    block_of("spec/tasks/paper.toml", &block);
    let exe = dir.join("rl_app_demo");
    compile_c_in("examples/c", &["main.c", "rl_app.c"], &exe);
    let text = run(Command::new(&exe).arg(&block));
    println!("{text}");
    let got = parse(&text);

    let lt = taskfile::load(&root().join("spec/tasks/paper.toml")).unwrap();
    let rec = host_sim::records::outputs_of::<7, 4>(&lt, &Overrides::default())
        .unwrap()
        .outputs;
    assert_eq!(got.get("DIGEST"), Some(&rec.trajectory_digest), "{text}");

    let (digest, commands, q) = core_flight(&block);
    assert_eq!(got["COMMANDS"], commands.to_string(), "{text}");
    assert_eq!(
        got["LOOP_MODE"],
        reactionless_ffi::closed_loop::RL_LOOP_DONE.to_string()
    );
    assert_eq!(got["LOOP_DIGEST"], digest, "{text}");
    for (i, v) in q.iter().enumerate() {
        let c: f64 = got[&format!("Q{}", i + 1)].parse().unwrap();
        assert_eq!(c.to_bits(), v.to_bits(), "joint {}", i + 1);
    }

    let text = run(Command::new(&exe).arg(&block).arg("50"));
    let got = parse(&text);
    assert_eq!(
        got["LOOP_MODE"],
        reactionless_ffi::closed_loop::RL_LOOP_STOPPED.to_string()
    );
    assert_eq!(
        got["LOOP_FAULT"],
        reactionless_ffi::closed_loop::RL_FAULT_NOT_FINITE.to_string()
    );
    let faults = text
        .lines()
        .filter(|l| l.contains("RL_FAULT_NOT_FINITE"))
        .count();
    assert_eq!(faults, 1, "the fault is reported once:\n{text}");
    assert!(text.contains("arm at rest in the safe state"), "{text}");
}

/// The closed-loop flight of `block`'s plan through the core's `PlanLoop` (the default
/// settings) on the C programs' stand-in hardware: joints that follow each command exactly
/// over its period, encoders that read them exactly, a base held still. The digest of every
/// command (cycle 0's first, the one that comes to rest last), their count, and where the
/// joints end.
fn core_flight(block: &Path) -> (String, u32, [f64; 7]) {
    use reactionless::closed_loop::{LoopConfig, Measurement, Mode, PlanLoop};
    use reactionless::{Planner, Status, TrajectoryDigest};
    let bytes = std::fs::read(block).unwrap();
    let decoded = reactionless::block::decode::<7>(&bytes).unwrap();
    let mut planner: Box<Planner<7, 4, 64>> = Box::new(Planner::IDLE);
    decoded.load_into(&mut planner).unwrap();
    let eta = loop {
        if let Status::Finished(p) = planner.step(u32::MAX, &mut ()).unwrap() {
            break p.eta;
        }
    };
    let task = planner.task();
    let config = LoopConfig::DEFAULT;
    let (mut flight, first) = PlanLoop::new(config, task, &eta).unwrap();
    let mut digest = TrajectoryDigest::new();
    let mut q = *task.start();
    let mut held = first;
    let mut commands = 0;
    loop {
        for v in &held {
            digest.push(*v);
        }
        commands += 1;
        let m = Measurement {
            star_tracker: Some([1.0, 0.0, 0.0, 0.0]),
            gyro: Some([0.0; 3]),
            joints: Some(q),
        };
        let c = flight.step(task, &m);
        for (qi, v) in q.iter_mut().zip(held.iter()) {
            *qi += v * config.period;
        }
        held = c.rate;
        if matches!(c.mode, Mode::Done) && c.rate.iter().all(|v| *v == 0.0) {
            for v in &held {
                digest.push(*v);
            }
            commands += 1;
            break;
        }
        assert!(commands < 1000, "the flight does not end");
    }
    (format!("0x{:016x}", digest.value()), commands, q)
}
