//! The rollout's contract: resumable in slices of any size with identical bits, streaming
//! samples without storing them, and never allocating (REQ: issue 2, "Rollout").
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

mod common;
use common::*;
use reactionless::{Error, Outcome, Progress, Rollout, Sample};

/// Drives a rollout of η̂ with `budget` steps per call; returns the outcome, the number of
/// calls and an FNV-1a hash over the bits of every sample.
fn sliced(budget: u32) -> (Outcome<7>, u32, u64, u32) {
    let task = paper_task();
    let mut r = Rollout::new(&task, &ETA_HAT).unwrap();
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    let mut samples = 0;
    let mut sink = |s: &Sample<7>| {
        samples += 1;
        for v in core::iter::once(s.t).chain(s.q).chain(s.qd) {
            for b in v.to_bits().to_le_bytes() {
                hash = (hash ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
            }
        }
    };
    let mut calls = 0;
    loop {
        calls += 1;
        if let Progress::Done(o) = r.advance(&task, budget, &mut sink).unwrap() {
            return (o, calls, hash, samples);
        }
    }
}

fn bits(o: &Outcome<7>) -> Vec<u64> {
    o.q_final
        .iter()
        .chain(&o.joint_min)
        .chain(&o.joint_max)
        .chain(&o.end_pose.position)
        .chain(&o.end_pose.quat_wxyz)
        .chain(&[o.phi, o.f, o.g, o.max_abs_qd])
        .map(|v| v.to_bits())
        .collect()
}

#[test]
fn budget_slicing_is_bit_identical() {
    let (reference, calls, hash, samples) = sliced(u32::MAX);
    assert_eq!(calls, 1);
    assert_eq!(samples, 3001);
    for budget in [1, 7, 1000, 2999, 3000] {
        let (o, calls, h, n) = sliced(budget);
        assert_eq!(bits(&o), bits(&reference), "budget {budget}");
        assert_eq!(h, hash, "sample stream, budget {budget}");
        assert_eq!(n, 3001);
        assert_eq!(calls, 3000u32.div_ceil(budget), "budget {budget}");
    }
}

#[test]
fn a_finished_rollout_stays_finished_and_zero_budget_does_nothing() {
    let task = paper_task();
    let mut r = Rollout::new(&task, &ETA_HAT).unwrap();
    assert_eq!(
        r.advance(&task, 0, &mut ()).unwrap(),
        Progress::Running {
            step: 0,
            steps: 3000
        }
    );
    let done = r.advance(&task, 5000, &mut ()).unwrap();
    let mut called = false;
    assert_eq!(
        r.advance(&task, 10, &mut |_: &Sample<7>| called = true)
            .unwrap(),
        done
    );
    assert!(!called);
}

#[test]
fn errors_are_sticky_and_typed() {
    let task = paper_task();
    assert_eq!(
        Rollout::new(&task, &[[0.0; 2]; 4]).unwrap_err(),
        Error::EtaZero
    );
    let mut eta = ETA_HAT;
    eta[2][1] = f64::INFINITY;
    assert_eq!(
        Rollout::new(&task, &eta).unwrap_err(),
        Error::NotFinite(reactionless::Param::Eta(6))
    );
}

#[test]
fn a_full_rollout_never_allocates() {
    let task = paper_task();
    let mut out = None;
    let info = allocation_counter::measure(|| {
        let mut r = Rollout::new(&task, &ETA_HAT).unwrap();
        let mut last = 0.0;
        let mut sink = |s: &Sample<7>| last = s.t;
        loop {
            if let Progress::Done(o) = r.advance(&task, 100, &mut sink).unwrap() {
                out = Some((o.f, last));
                break;
            }
        }
    });
    assert_eq!(info.count_total, 0, "allocations during a rollout");
    let (f, last) = out.unwrap();
    assert!(f < 1e-4);
    assert_eq!(last, 30.0);
}

#[test]
fn repeated_runs_are_bit_identical() {
    let (a, _, ha, _) = sliced(3000);
    let (b, _, hb, _) = sliced(3000);
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(ha, hb);
}
