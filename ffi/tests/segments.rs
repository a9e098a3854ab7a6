//! A motion of several segments through the C ABI (issue #30): the block carries the
//! segment count, `rl_plan` the segments' η, and the stream flies the whole motion.
//!
//! Requirements: RL-FFI (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

use host_sim::taskfile::{self, Overrides};
use reactionless_ffi::*;
use std::path::Path;

const TASK: &str = "tests/tasks/fixed/segments/ref/1cm/ref-0.toml";

/// The four-segment task through `rl_planner`: `rl_plan` says 4 segments and holds the
/// host's 32 η values and f bit for bit (host-sim's record of the same file); the stream
/// yields the host's 3,001 samples, at rest at each junction.
/// Verifies RL-FFI-013.
#[test]
#[allow(unsafe_code)]
fn a_block_of_four_segments_is_planned_and_streamed() {
    let lt = taskfile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(TASK)).unwrap();
    let bytes = host_sim::flight::task_block(&lt, &Overrides::default()).unwrap();
    let host = host_sim::records::outputs_of::<7, 4>(&lt, &Overrides::default())
        .unwrap()
        .outputs;
    assert_eq!(host.eta.len(), 32);
    let mut p = Box::new(rl_planner::ZEROED);
    let mut plan = rl_plan::ZEROED;
    let mut s = Box::new(rl_setpoints::ZEROED);
    let mut sp = rl_setpoint::ZEROED;
    let mut samples = Vec::new();
    // SAFETY: `p` and `s` are valid, exclusive storage; `bytes` is readable for its length.
    unsafe {
        assert_eq!(
            rl_planner_init(&mut *p, RL_ABI_VERSION, core::mem::size_of::<rl_planner>()),
            RL_OK
        );
        assert_eq!(
            rl_planner_load_block(&mut *p, bytes.as_ptr(), bytes.len()),
            RL_OK
        );
        let status = loop {
            match rl_planner_step(&mut *p, 3000, &mut plan) {
                RL_RUNNING => {}
                other => break other,
            }
        };
        assert_eq!(status, RL_CONVERGED);
        assert_eq!(rl_setpoints_init(&mut *s, &*p), RL_OK);
        while rl_setpoints_next(&mut *s, &*p, &mut sp) == RL_OK {
            samples.push(sp);
        }
    }
    assert_eq!(plan.segments, 4);
    let eta: Vec<String> = plan
        .eta
        .iter()
        .map(|v| host_sim::records::bits(*v))
        .collect();
    assert_eq!(eta, host.eta_bits);
    assert_eq!(host_sim::records::bits(plan.f), host.f_bits);
    assert_eq!(plan.rollouts, host.rollouts);
    assert_eq!(samples.len(), 3001);
    for i in [0, 750, 1500, 2250, 3000] {
        assert!(samples[i].qd.iter().all(|v| *v == 0.0), "sample {i}");
    }
    let mut digest = reactionless::TrajectoryDigest::new();
    for (n, s) in samples.iter().enumerate() {
        digest.push_sample(&reactionless::Sample {
            step: n as u32,
            t: s.t,
            q: s.q,
            qd: s.qd,
        });
    }
    assert_eq!(format!("{:#018x}", digest.value()), host.trajectory_digest);
}
