//! Checkpoint and restore through the Rust API (`reactionless_ffi::checkpoint`): a planner
//! restored from a checkpoint taken between two `step` calls finishes with the same plan,
//! bit for bit, as one that never stopped; damaged or foreign checkpoints are rejected.
//!
//! Requirements: RL-FFI (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::panic,
    clippy::indexing_slicing,
    missing_docs
)]

use reactionless::Status;
use reactionless::block::decode;
use reactionless_ffi::FlightPlanner;
use reactionless_ffi::checkpoint::{self, Fault, LEN};
use std::path::Path;

fn block(task: &str) -> Vec<u8> {
    let lt = host_sim::taskfile::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(task))
        .unwrap();
    host_sim::flight::task_block(&lt, &host_sim::taskfile::Overrides::default()).unwrap()
}

fn loaded(bytes: &[u8]) -> Box<FlightPlanner> {
    let mut p = Box::new(FlightPlanner::IDLE);
    decode::<7>(bytes).unwrap().load_into(&mut p).unwrap();
    p
}

/// Restored in the middle of planning, the planner ends on the very plan (η, f, counts,
/// budget spent) of an uninterrupted run.
/// Verifies RL-FFI-004.
#[test]
fn restore_continues_bit_identically() {
    let bytes = block("spec/tasks/paper.toml");
    let task = checkpoint::task_digest(&bytes);
    let budget = 3000;
    let mut straight = loaded(&bytes);
    let plan = loop {
        if let Status::Finished(p) = straight.step(budget, &mut ()).unwrap() {
            break p;
        }
    };
    let mut first = loaded(&bytes);
    for _ in 0..25 {
        assert!(matches!(
            first.step(budget, &mut ()).unwrap(),
            Status::Running(_)
        ));
    }
    let mut buf = vec![0u8; LEN];
    assert_eq!(checkpoint::write(&*first, task, &mut buf), Ok(LEN));
    drop(first);
    let mut second = Box::new(FlightPlanner::IDLE);
    // SAFETY: `buf` was written by checkpoint::write of this build just above.
    #[allow(unsafe_code)]
    let theirs = unsafe { checkpoint::restore(&mut *second, Some(task), &buf) };
    assert_eq!(theirs, Ok(task));
    let again = loop {
        if let Status::Finished(p) = second.step(budget, &mut ()).unwrap() {
            break p;
        }
    };
    assert_eq!(again, plan);
    assert_eq!(again.outcome.f.to_bits(), plan.outcome.f.to_bits());
    assert_eq!(second.spent(), straight.spent());
}

/// Every kind of damage has its fault, and a rejected checkpoint leaves the planner as it
/// was.
/// Verifies RL-FFI-005.
#[test]
fn damaged_checkpoints_are_rejected_by_kind() {
    let bytes = block("spec/tasks/paper.toml");
    let task = checkpoint::task_digest(&bytes);
    let p = loaded(&bytes);
    let mut buf = vec![0u8; LEN];
    assert_eq!(
        checkpoint::write(&*p, task, &mut buf[..LEN - 1]),
        Err(Fault::Buffer)
    );
    checkpoint::write(&*p, task, &mut buf).unwrap();
    assert_eq!(checkpoint::verify(&buf, Some(task)), Ok(task));
    assert_eq!(
        checkpoint::verify(&buf[..LEN - 1], None),
        Err(Fault::Length)
    );
    let other = checkpoint::task_digest(&block("tests/records/tasks/chaser7/task_002.toml"));
    assert_ne!(other, task);
    assert_eq!(checkpoint::verify(&buf, Some(other)), Err(Fault::Task));
    for (at, fault) in [
        (0, Fault::Magic),
        (8, Fault::Version),
        (12, Fault::Version),
        (16, Fault::Length),
        (20, Fault::Length),
        (24, Fault::Layout),
        (32, Fault::Checksum),
        (LEN / 2, Fault::Checksum),
        (LEN - 1, Fault::Checksum),
    ] {
        let mut bad = buf.clone();
        bad[at] ^= 0x40;
        assert_eq!(checkpoint::verify(&bad, None), Err(fault), "byte {at}");
        let mut q = loaded(&bytes);
        let before = (*q).clone();
        // SAFETY: a rejected checkpoint is never copied in (that is what is tested).
        #[allow(unsafe_code)]
        let r = unsafe { checkpoint::restore(&mut *q, None, &bad) };
        assert_eq!(r, Err(fault));
        assert!(*q == before, "byte {at}: the planner changed");
    }
}
