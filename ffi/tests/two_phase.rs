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
    for (task, want) in cases {
        let two = block(task);
        let lt = host_sim::taskfile::load(&root.join(task)).unwrap();
        let host = host_sim::flight::flight_outputs(&lt, &host_sim::taskfile::Overrides::default())
            .unwrap();
        let mut plan = rl_two_phase_plan::ZEROED;
        let mut frames = 0u32;
        let mut t = search(Some(&two));
        // SAFETY: `t` is an initialised search with the block loaded.
        let status = unsafe {
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
        let p = loaded_planner(&one);
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

/// A fresh `rl_planner` with the single-phase `block` loaded.
#[allow(unsafe_code)]
fn loaded_planner(block: &[u8]) -> Box<rl_planner> {
    let mut p = Box::new(rl_planner::ZEROED);
    // SAFETY: `p` is a valid, exclusive rl_planner; the block is readable for its length.
    unsafe {
        assert_eq!(
            rl_planner_init(&mut *p, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()),
            RL_OK
        );
        assert_eq!(
            rl_planner_load_block(&mut *p, block.as_ptr(), block.len()),
            RL_OK
        );
    }
    p
}

/// A fresh, initialised `rl_two_phase` (boxed: 20 KB), with `block` loaded if given.
#[allow(unsafe_code)]
fn search(block: Option<&[u8]>) -> Box<rl_two_phase> {
    let mut t = Box::new(rl_two_phase::ZEROED);
    // SAFETY: `t` is a valid, exclusive rl_two_phase; the block is readable for its length.
    unsafe {
        assert_eq!(
            rl_two_phase_init(
                &mut *t,
                RL_ABI_VERSION,
                core::mem::size_of::<rl_two_phase>()
            ),
            RL_OK
        );
        if let Some(b) = block {
            assert_eq!(rl_two_phase_load_block(&mut *t, b.as_ptr(), b.len()), RL_OK);
        }
    }
    t
}

/// Steps `t` by `units` units, one per call; the status of the last call.
#[allow(unsafe_code)]
fn step_units(t: &mut rl_two_phase, units: u32, plan: &mut rl_two_phase_plan) -> rl_status {
    let mut s = RL_RUNNING;
    for _ in 0..units {
        // SAFETY: `t` is an initialised search, `plan` writable.
        s = unsafe { rl_two_phase_step(t, 1, plan) };
    }
    s
}

/// A search checkpointed at any point (early in the search, in the middle of the
/// truth-model flight of the accepted start, after it finished) and restored into fresh
/// storage after a "reset" ends on the very plan of one that never stopped, and streams
/// the same samples of both phases, bit for bit.
/// Verifies RL-FFI-012.
#[test]
#[allow(unsafe_code)]
fn a_restored_two_phase_search_continues_bit_identically() {
    let two = block("tests/tasks/g/chaser7/joint20/task_001.toml");
    let mut straight = search(Some(&two));
    let mut want = rl_two_phase_plan::ZEROED;
    let mut units = 0u32;
    // SAFETY: as in `search`.
    while unsafe { rl_two_phase_step(&mut *straight, 1, &mut want) } == RL_RUNNING {
        units += 1;
    }
    let streams = (stream(&straight, 1).unwrap(), stream(&straight, 2).unwrap());
    let len = rl_two_phase_checkpoint_size();
    assert!(len <= RL_TWO_PHASE_CHECKPOINT_CAPACITY);
    // Units 150 (screening), `units − 5` (phase 2 of the accepted start on the truth model,
    // whose units are the last 15) and `units + 1` (finished).
    for at in [150, units - 5, units + 1] {
        let mut first = search(Some(&two));
        let mut plan = rl_two_phase_plan::ZEROED;
        let s = step_units(&mut first, at, &mut plan);
        assert_eq!(s, if at > units { RL_CONVERGED } else { RL_RUNNING });
        let mut buf = vec![0u8; len];
        // SAFETY: `buf` is writable for `len` bytes; `first` an initialised search.
        unsafe {
            assert_eq!(
                rl_two_phase_checkpoint(&*first, buf.as_mut_ptr(), buf.len()),
                RL_OK
            );
        }
        drop(first);
        let mut second = search(None);
        // SAFETY: `buf` was written by rl_two_phase_checkpoint of this build just above.
        let got = unsafe {
            assert_eq!(
                rl_two_phase_restore(&mut *second, buf.as_ptr(), buf.len()),
                RL_OK
            );
            loop {
                let s = rl_two_phase_step(&mut *second, 7, &mut plan);
                if s != RL_RUNNING {
                    break s;
                }
            }
        };
        assert_eq!(got, RL_CONVERGED, "checkpoint at unit {at}");
        assert_eq!(format!("{plan:?}"), format!("{want:?}"), "unit {at}");
        let again = (stream(&second, 1).unwrap(), stream(&second, 2).unwrap());
        assert_eq!(again, streams, "unit {at}");
    }
}

/// Two-phase checkpoints are checked before a byte is copied: a short buffer, a flipped
/// bit, a planner's checkpoint, another task's, NULLs, an uninitialised or task-less
/// search; a refused restore leaves the search as it was.
/// Verifies RL-FFI-012.
#[test]
#[allow(unsafe_code)]
fn a_bad_two_phase_checkpoint_is_refused() {
    let two = block("tests/tasks/g/chaser7/joint20/task_001.toml");
    let far = block("tests/tasks/g/chaser7/moved5cm/task_002.toml");
    let len = rl_two_phase_checkpoint_size();
    let mut buf = vec![0u8; len];
    let mut plan = rl_two_phase_plan::ZEROED;
    let mut t = search(Some(&two));
    assert_eq!(step_units(&mut t, 20, &mut plan), RL_RUNNING);
    // SAFETY: every buffer is readable/writable for the length given; NULLs are what is
    // being tested; the searches are initialised unless the test says otherwise.
    unsafe {
        assert_eq!(
            rl_two_phase_checkpoint(&*t, buf.as_mut_ptr(), len - 1),
            RL_E_BUFFER
        );
        assert_eq!(
            rl_two_phase_checkpoint(&*t, core::ptr::null_mut(), len),
            RL_E_NULL
        );
        assert_eq!(
            rl_two_phase_checkpoint(core::ptr::null(), buf.as_mut_ptr(), len),
            RL_E_NULL
        );
        let idle = search(None);
        assert_eq!(
            rl_two_phase_checkpoint(&*idle, buf.as_mut_ptr(), len),
            RL_E_NO_TASK
        );
        let mut zeroed = Box::new(rl_two_phase::ZEROED);
        assert_eq!(
            rl_two_phase_checkpoint(&*zeroed, buf.as_mut_ptr(), len),
            RL_E_UNINITIALIZED
        );
        assert_eq!(rl_two_phase_checkpoint(&*t, buf.as_mut_ptr(), len), RL_OK);
        assert_eq!(
            rl_two_phase_restore(&mut *zeroed, buf.as_ptr(), len),
            RL_E_UNINITIALIZED
        );
        assert_eq!(
            rl_two_phase_restore(&mut *t, core::ptr::null(), len),
            RL_E_NULL
        );
        // Another task's search refuses it and keeps planning its own task.
        let mut other = search(Some(&far));
        assert_eq!(
            rl_two_phase_restore(&mut *other, buf.as_ptr(), len),
            RL_E_CKPT_TASK
        );
        let mut s;
        loop {
            s = rl_two_phase_step(&mut *other, 1000, &mut plan);
            if s != RL_RUNNING {
                break;
            }
        }
        assert_eq!(s, RL_BEYOND_REACH);
        let mut fresh = search(None);
        assert_eq!(
            rl_two_phase_restore(&mut *fresh, buf.as_ptr(), len - 1),
            RL_E_CKPT_LENGTH
        );
        for at in [0, 8, 24, 100, len - 1] {
            let mut bad = buf.clone();
            bad[at] ^= 1;
            let want = match at {
                0 => RL_E_CKPT_MAGIC,
                8 => RL_E_CKPT_VERSION,
                24 => RL_E_CKPT_LAYOUT,
                _ => RL_E_CKPT_CRC,
            };
            assert_eq!(
                rl_two_phase_restore(&mut *fresh, bad.as_ptr(), len),
                want,
                "byte {at}"
            );
        }
        // Refused restores left `fresh` with no task.
        assert_eq!(rl_two_phase_step(&mut *fresh, 1, &mut plan), RL_E_NO_TASK);
        // A planner's checkpoint is not a search's, and a search's is not a planner's.
        let one = block("spec/tasks/paper.toml");
        let p = loaded_planner(&one);
        let mut pbuf = vec![0u8; rl_checkpoint_size().max(len)];
        assert_eq!(
            rl_planner_checkpoint(&*p, pbuf.as_mut_ptr(), pbuf.len()),
            RL_OK
        );
        assert_eq!(
            rl_two_phase_restore(&mut *fresh, pbuf.as_ptr(), pbuf.len()),
            RL_E_CKPT_MAGIC
        );
        let mut q = Box::new(rl_planner::ZEROED);
        assert_eq!(
            rl_planner_init(&mut *q, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()),
            RL_OK
        );
        let mut big = buf.clone();
        big.resize(rl_checkpoint_size().max(len), 0);
        assert_ne!(rl_planner_restore(&mut *q, big.as_ptr(), big.len()), RL_OK);
    }
}
