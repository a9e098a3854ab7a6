//! A two-phase block (a task with `[preshape]`, magic `RLTASK04`) through the C ABI: the
//! budgeted planner plans single-phase tasks only, so `rl_planner_load_block` refuses it by
//! name and the planner is left without a task; it never plans the block as one phase.
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
