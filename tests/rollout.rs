//! The rollout's contract: resumable in slices of any size with identical bits, streaming
//! samples without storing them, never allocating, and failing for good.
//!
//! Requirements: RL-LAW, RL-ROLL, RL-EXEC, RL-CORE, RL-ROB (docs/requirements.md).
#![allow(clippy::unwrap_used, clippy::indexing_slicing, missing_docs)]

mod common;
use common::*;
use reactionless::{Error, Motion, Outcome, Progress, Rollout, Sample, Setpoints, Task};

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
    outcome_bits(o)
}

/// Budgets 1, 7, 1000, 2999, 3000 give the one-call samples and outcome bit for bit, in
/// ⌈S/budget⌉ calls.
/// Verifies RL-ROLL-002, RL-ROLL-003.
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

/// Budget 0 does nothing; a finished rollout returns its outcome again without calling the
/// sink.
/// Verifies RL-ROLL-003.
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

/// `Rollout::new` rejects η = 0 as `EtaZero` and names an infinite b₃ as
/// `NotFinite(Eta(6))`.
/// Verifies RL-LAW-006, RL-LAW-007, RL-ROB-004.
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

/// A whole rollout of η̂, in slices of 100 steps, makes no heap allocation.
/// Verifies RL-CORE-002.
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

/// Two rollouts of η̂ give the same outcome and sample stream bit for bit.
/// Verifies RL-ROLL-006.
#[test]
fn repeated_runs_are_bit_identical() {
    let (a, _, ha, _) = sliced(3000);
    let (b, _, hb, _) = sliced(3000);
    assert_eq!(bits(&a), bits(&b));
    assert_eq!(ha, hb);
}

/// CHASER7 with an absurd velocity limit (1e305 rad/s on every joint) over 10 steps of
/// dt = 1e6 s: q̇₀ = 0, so q₁ = q₀, and the Euler step q₂ = q₁ + dt·q̇₁ overflows to ∞.
fn overflowing_task() -> Task<7, 4> {
    let mut d = reactionless::CHASER7;
    for j in &mut d.joints {
        j.velocity = 1e305;
    }
    let robot = reactionless::Robot::new(&d).unwrap();
    Task::new(robot, q0(), TARGET, Motion::new(1e7, 1e6, 1).unwrap()).unwrap()
}

/// A state that overflows is reported as `NonFiniteState` at the step of the first
/// non-finite q (never propagated as NaN or ∞ into a sample), and every later call
/// returns that error without doing work, whatever its budget.
/// Verifies RL-ROLL-008, RL-ROB-005, RL-ROB-006.
#[test]
fn a_non_finite_state_is_reported_at_its_step_and_stays() {
    let task = overflowing_task();
    let mut r = Rollout::new(&task, &ETA_HAT).unwrap();
    let mut samples: Vec<Sample<7>> = Vec::new();
    assert_eq!(
        r.advance(&task, 1, &mut |s: &Sample<7>| samples.push(*s))
            .unwrap(),
        Progress::Running { step: 1, steps: 10 }
    );
    let err = r
        .advance(&task, 1, &mut |s: &Sample<7>| samples.push(*s))
        .unwrap_err();
    assert_eq!(err, Error::NonFiniteState { step: 2 });
    // Samples 0 and 1 were handed out, both finite; q₂ = q₁ + dt·q̇₁ (by hand) is not.
    assert_eq!(samples.len(), 2);
    for s in &samples {
        assert!(s.q.iter().chain(&s.qd).all(|v| v.is_finite()), "{s:?}");
    }
    assert_eq!(samples[1].q, q0());
    let q2: Vec<f64> = samples[1]
        .q
        .iter()
        .zip(&samples[1].qd)
        .map(|(q, qd)| q + 1e6 * qd)
        .collect();
    assert!(q2.iter().any(|v| !v.is_finite()), "{q2:?}");
    // Sticky: the same error on every later call, and the sink is never called again.
    for budget in [0, 1, 7, u32::MAX] {
        let mut called = false;
        assert_eq!(
            r.advance(&task, budget, &mut |_: &Sample<7>| called = true),
            Err(err),
            "budget {budget}"
        );
        assert!(!called, "budget {budget}");
    }
    // The same error in one call, and from a whole rollout.
    let mut whole = Rollout::new(&task, &ETA_HAT).unwrap();
    assert_eq!(whole.advance(&task, u32::MAX, &mut ()), Err(err));
    assert_eq!(whole.advance(&task, u32::MAX, &mut ()), Err(err));
    assert_eq!(task.rollout(&ETA_HAT, &mut ()), Err(err));
}

/// A setpoint stream whose rollout fails returns that error on every later call: no
/// setpoint after the failure, no outcome.
/// Verifies RL-EXEC-003.
#[test]
fn a_failed_setpoint_stream_stays_failed() {
    let task = overflowing_task();
    let mut sp = Setpoints::new(&task, &ETA_HAT).unwrap();
    let mut flown = Vec::new();
    let err = loop {
        match sp.next(&task) {
            Ok(Some(s)) => flown.push(s),
            Ok(None) => unreachable!("the stream cannot finish"),
            Err(e) => break e,
        }
    };
    assert_eq!(err, Error::NonFiniteState { step: 2 });
    assert!(!flown.is_empty() && flown.len() <= 2, "{flown:?}");
    for (k, s) in flown.iter().enumerate() {
        assert_eq!(s.step, k as u32);
        assert!(s.q.iter().chain(&s.qd).all(|v| v.is_finite()));
    }
    for _ in 0..5 {
        assert_eq!(sp.next(&task), Err(err));
    }
    assert!(sp.outcome().is_none());
}
