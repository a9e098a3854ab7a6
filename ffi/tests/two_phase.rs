//! A two-phase block (a task with `[preshape]`, magic `RLTASK04`) through the C ABI:
//! `rl_planner` plans single-phase tasks only, so `rl_planner_load_block` refuses it by
//! name and the planner is left without a task (it never plans the block as one phase);
//! `rl_two_phase` plans it, in frames, bit-identically to the host.
//!
//! Requirements: RL-FFI (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use reactionless_ffi::*;
use std::path::Path;

fn block(task: &str) -> Vec<u8> {
    let lt = host_sim::taskfile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(task))
        .unwrap();
    host_sim::flight::task_block(&lt, &host_sim::taskfile::Overrides::default()).unwrap()
}

/// Verifies RL-FFI-010.
#[test]
#[allow(unsafe_code)]
fn a_two_phase_block_is_refused_by_name() {
    let two = block("tests/tasks/g/chaser7/joint20/task_001.toml");
    assert_eq!(&two[..8], b"RLTASK04");
    let one = block("spec/tasks/paper.toml");
    let mut p = Box::new(rl_planner::ZEROED);
    let mut plan = rl_plan::ZEROED;
    // SAFETY: `p` is a valid, exclusive rl_planner; the blocks are readable for their length.
    unsafe {
        assert_eq!(
            rl_planner_init(&mut *p, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()),
            RL_OK
        );
        assert_eq!(
            rl_planner_load_block(&mut *p, one.as_ptr(), one.len()),
            RL_OK
        );
        assert_eq!(
            rl_planner_load_block(&mut *p, two.as_ptr(), two.len()),
            RL_E_TWO_PHASE
        );
        // The task loaded before is gone, not planned in its place.
        assert_eq!(rl_planner_step(&mut *p, 100, &mut plan), RL_E_NO_TASK);
        let name = core::ffi::CStr::from_ptr(rl_status_str(RL_E_TWO_PHASE));
        assert!(name.to_str().unwrap().starts_with("RL_E_TWO_PHASE"));
    }
}

/// Streams phase `phase` of `t`'s plan through the C ABI: its digest (as the host writes
/// it) and sample count, or the status that refused it.
#[allow(unsafe_code)]
fn stream(t: &rl_two_phase, phase: u32) -> Result<(String, u32), rl_status> {
    let mut s = Box::new(rl_setpoints::ZEROED);
    let mut sp = rl_setpoint::ZEROED;
    let mut digest = reactionless::TrajectoryDigest::new();
    let mut n = 0u32;
    // SAFETY: `s` is writable storage of one rl_setpoints; `t` an initialised search.
    unsafe {
        let st = rl_two_phase_setpoints_init(&mut *s, t, phase);
        if st != RL_OK {
            return Err(st);
        }
        loop {
            match rl_two_phase_setpoints_next(&mut *s, t, &mut sp) {
                RL_OK => {}
                RL_DONE => break,
                e => return Err(e),
            }
            digest.push_sample(&reactionless::Sample {
                step: n,
                t: sp.t,
                q: sp.q,
                qd: sp.qd,
            });
            n += 1;
        }
        assert_eq!(rl_two_phase_setpoints_next(&mut *s, t, &mut sp), RL_DONE);
    }
    Ok((format!("{:#018x}", digest.value()), n))
}

fn field<'a>(line: &'a [(String, String)], key: &str) -> &'a str {
    &line.iter().find(|(k, _)| k == key).unwrap().1
}

/// A two-phase block through `rl_two_phase`, stepped in frames of 50 units: the plan the
/// host plans for the same task file (host-sim's two-phase path, as `host-sim target`
/// compares with the flight image), bit for bit: `q_s`, η, `f`, how the search ended, its
/// starts, the inverse's `f`, the base disturbance, phase 1's steps, the wheels' demand and
/// the base shift; then both phases streamed, each the host's samples bit for bit (phase
/// 1's digest as phase1.csv's, phase 2's as the host's rollout from `q_s`). A target beyond
/// reach ends `RL_BEYOND_REACH` before any rollout, and has no phase 2 to stream.
/// Verifies RL-FFI-011.
#[test]
#[allow(unsafe_code)]
fn a_two_phase_block_is_planned_by_rl_two_phase() {
    use host_sim::records::bits;
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let cases = [
        ("tests/tasks/g/chaser7/joint20/task_001.toml", RL_CONVERGED),
        (
            "tests/tasks/g/chaser7/moved5cm/task_002.toml",
            RL_BEYOND_REACH,
        ),
    ];
    let mut t = Box::new(rl_two_phase::ZEROED);
    for (task, want) in cases {
        let two = block(task);
        let lt = host_sim::taskfile::load(&root.join(task)).unwrap();
        let host = host_sim::flight::flight_outputs(&lt, &host_sim::taskfile::Overrides::default())
            .unwrap();
        let mut plan = rl_two_phase_plan::ZEROED;
        let mut frames = 0u32;
        // SAFETY: `t` is a valid, exclusive rl_two_phase; the block is readable for its length.
        let status = unsafe {
            assert_eq!(
                rl_two_phase_init(
                    &mut *t,
                    RL_ABI_VERSION,
                    core::mem::size_of::<rl_two_phase>()
                ),
                RL_OK
            );
            assert_eq!(
                rl_two_phase_load_block(&mut *t, two.as_ptr(), two.len()),
                RL_OK
            );
            loop {
                frames += 1;
                let s = rl_two_phase_step(&mut *t, 50, &mut plan);
                if s != RL_RUNNING {
                    break s;
                }
                assert_eq!(plan, rl_two_phase_plan::ZEROED, "untouched while running");
            }
        };
        assert_eq!(status, want, "{task}");
        assert!(frames > 1, "{task}: sliced into frames");
        let line = &host.line;
        let q_s: Vec<String> = plan.q_s.iter().map(|v| bits(*v)).collect();
        assert_eq!(q_s, host.q_s_bits, "{task}: q_s");
        let eta: Vec<String> = plan.eta.iter().map(|v| bits(*v)).collect();
        assert_eq!(eta, host.outputs.eta_bits, "{task}: eta");
        assert_eq!(bits(plan.f), host.outputs.f_bits, "{task}: f");
        assert_eq!(plan.rollouts, host.outputs.rollouts, "{task}: rollouts");
        assert_eq!(plan.starts.to_string(), field(line, "starts"));
        assert_eq!(bits(plan.reach_f), field(line, "reach_f"));
        assert_eq!(bits(plan.base_disturbance_rad), field(line, "base"));
        assert_eq!(plan.phase1_steps.to_string(), field(line, "steps1"));
        assert_eq!(bits(plan.wheel_momentum_nms), field(line, "momentum"));
        assert_eq!(bits(plan.wheel_torque_nm), field(line, "torque"));
        for (v, k) in plan
            .base_shift_m
            .iter()
            .zip(["shift_x", "shift_y", "shift_z"])
        {
            assert_eq!(bits(*v), field(line, k), "{task}: {k}");
        }
        assert_eq!(plan.converged, u32::from(want == RL_CONVERGED));
        // Both phases streamed: phase 1's samples are phase1.csv's (the host's digest), and
        // phase 2's are the rollout of η from q_s (the host's trajectory digest).
        let (digest1, samples1) = stream(&t, 1).unwrap();
        assert_eq!(digest1, field(line, "digest1"), "{task}: phase 1 digest");
        assert_eq!(samples1.to_string(), field(line, "samples1"));
        if want == RL_CONVERGED {
            let (digest2, samples2) = stream(&t, 2).unwrap();
            assert_eq!(
                digest2, host.outputs.trajectory_digest,
                "{task}: phase 2 digest"
            );
            assert_eq!(samples2, host.outputs.trajectory_samples);
        } else {
            assert_eq!(stream(&t, 2), Err(RL_E_NO_PLAN), "{task}: no phase 2");
        }
        // Finished is final: the same plan again, at once.
        let again = plan;
        // SAFETY: as above.
        unsafe {
            assert_eq!(rl_two_phase_step(&mut *t, 1, &mut plan), want);
        }
        assert_eq!(format!("{plan:?}"), format!("{again:?}"));
    }
}

/// `rl_two_phase` checks what it is given: NULLs, another ABI version or size, a
/// single-phase block (named), a corrupt block, stepping with no task, streaming before the
/// plan is finished or a phase other than 1 and 2, a two-phase stream given to
/// `rl_setpoints_next` or to another search; none panics, and a failed load leaves no task.
/// Verifies RL-FFI-011.
#[test]
#[allow(unsafe_code)]
fn rl_two_phase_names_what_is_wrong() {
    let one = block("spec/tasks/paper.toml");
    let mut two = block("tests/tasks/g/chaser7/joint20/task_001.toml");
    let size = core::mem::size_of::<rl_two_phase>();
    let mut t = Box::new(rl_two_phase::ZEROED);
    let mut plan = rl_two_phase_plan::ZEROED;
    // SAFETY: `t` is a valid, exclusive rl_two_phase; the blocks are readable for their
    // length; NULLs are what is being tested.
    unsafe {
        assert_eq!(
            rl_two_phase_init(core::ptr::null_mut(), RL_ABI_VERSION, size),
            RL_E_NULL
        );
        assert_eq!(
            rl_two_phase_init(&mut *t, RL_ABI_VERSION - 1, size),
            RL_E_ABI_VERSION
        );
        assert_eq!(
            rl_two_phase_init(&mut *t, RL_ABI_VERSION, size - 8),
            RL_E_SIZE
        );
        assert_eq!(
            rl_two_phase_load_block(&mut *t, two.as_ptr(), two.len()),
            RL_E_UNINITIALIZED
        );
        assert_eq!(
            rl_two_phase_step(&mut *t, 10, &mut plan),
            RL_E_UNINITIALIZED
        );
        assert_eq!(rl_two_phase_init(&mut *t, RL_ABI_VERSION, size), RL_OK);
        assert_eq!(rl_two_phase_step(&mut *t, 10, &mut plan), RL_E_NO_TASK);
        assert_eq!(
            rl_two_phase_step(&mut *t, 10, core::ptr::null_mut()),
            RL_E_NULL
        );
        assert_eq!(
            rl_two_phase_load_block(&mut *t, core::ptr::null(), 10),
            RL_E_NULL
        );
        assert_eq!(
            rl_two_phase_load_block(&mut *t, one.as_ptr(), one.len()),
            RL_E_ONE_PHASE
        );
        assert_eq!(rl_two_phase_step(&mut *t, 10, &mut plan), RL_E_NO_TASK);
        assert_eq!(
            rl_two_phase_load_block(&mut *t, two.as_ptr(), two.len()),
            RL_OK
        );
        assert_eq!(rl_two_phase_step(&mut *t, 10, &mut plan), RL_RUNNING);
        let last = two.len() - 1;
        two[last] ^= 1;
        assert_eq!(
            rl_two_phase_load_block(&mut *t, two.as_ptr(), two.len()),
            RL_E_BLOCK_CRC
        );
        assert_eq!(rl_two_phase_step(&mut *t, 10, &mut plan), RL_E_NO_TASK);
        // Streams: none before the plan is finished; phases 1 and 2 only.
        let mut s: Box<rl_setpoints> = Box::new(rl_setpoints::ZEROED);
        let mut sp = rl_setpoint::ZEROED;
        assert_eq!(rl_two_phase_setpoints_init(&mut *s, &*t, 1), RL_E_NO_TASK);
        assert_eq!(
            rl_two_phase_load_block(&mut *t, one.as_ptr(), one.len()),
            RL_E_ONE_PHASE
        );
        two[last] ^= 1;
        assert_eq!(
            rl_two_phase_load_block(&mut *t, two.as_ptr(), two.len()),
            RL_OK
        );
        assert_eq!(rl_two_phase_setpoints_init(&mut *s, &*t, 1), RL_E_NO_PLAN);
        while rl_two_phase_step(&mut *t, 1000, &mut plan) == RL_RUNNING {}
        assert_eq!(rl_two_phase_setpoints_init(&mut *s, &*t, 3), RL_E_PHASE);
        assert_eq!(rl_two_phase_setpoints_init(&mut *s, &*t, 0), RL_E_PHASE);
        assert_eq!(
            rl_two_phase_setpoints_init(core::ptr::null_mut(), &*t, 1),
            RL_E_NULL
        );
        assert_eq!(rl_two_phase_setpoints_init(&mut *s, &*t, 2), RL_OK);
        assert_eq!(
            rl_two_phase_setpoints_next(&mut *s, &*t, core::ptr::null_mut()),
            RL_E_NULL
        );
        // A two-phase stream is not a planner's, nor the stream of another search.
        let mut p = Box::new(rl_planner::ZEROED);
        assert_eq!(
            rl_planner_init(&mut *p, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()),
            RL_OK
        );
        assert_eq!(
            rl_planner_load_block(&mut *p, one.as_ptr(), one.len()),
            RL_OK
        );
        assert_eq!(rl_setpoints_next(&mut *s, &*p, &mut sp), RL_E_MISMATCH);
        let mut other = Box::new(rl_two_phase::ZEROED);
        assert_eq!(rl_two_phase_init(&mut *other, RL_ABI_VERSION, size), RL_OK);
        let far = block("tests/tasks/g/chaser7/moved5cm/task_002.toml");
        assert_eq!(
            rl_two_phase_load_block(&mut *other, far.as_ptr(), far.len()),
            RL_OK
        );
        assert_eq!(
            rl_two_phase_setpoints_next(&mut *s, &*other, &mut sp),
            RL_E_MISMATCH
        );
        assert_eq!(rl_two_phase_setpoints_next(&mut *s, &*t, &mut sp), RL_OK);
        for s in [
            RL_BEYOND_REACH,
            RL_PRESHAPE_BOUNDS,
            RL_E_ONE_PHASE,
            RL_E_PHASE,
        ] {
            let name = core::ffi::CStr::from_ptr(rl_status_str(s));
            assert!(!name.to_str().unwrap().starts_with("unknown"), "{s}");
        }
    }
    assert_eq!(plan.converged, 1);
}
