//! The sizes of the core's state are documented figures (README, "Memory"); this test
//! pins them so the documentation cannot drift.
//!
//! Requirements: RL-CORE (docs/requirements.md).
#![allow(missing_docs)]

use core::mem::size_of;
use reactionless::{
    Basis, Cpso, Frames, Multistart, Outcome, Planner, Robot, Rollout, Search, Task, TimeLaw,
};

/// `size_of` of Task<7, 4>, Rollout<7, 4> and Planner<7, 4, 64> equal the README's x86-64
/// figures, and the planner holds one strategy's search, not all of them.
/// Verifies RL-CORE-005.
#[test]
fn documented_sizes_for_the_reference_robot() {
    let sizes = [
        ("Robot<7>", size_of::<Robot<7>>()),
        ("Task<7, 4>", size_of::<Task<7, 4>>()),
        ("Rollout<7, 4>", size_of::<Rollout<7, 4>>()),
        ("Basis<7, 4>", size_of::<Basis<7, 4>>()),
        ("TimeLaw<4>", size_of::<TimeLaw<4>>()),
        ("Frames<7>", size_of::<Frames<7>>()),
        ("Outcome<7>", size_of::<Outcome<7>>()),
        (
            "CollisionSet<7>",
            size_of::<reactionless::CollisionSet<7>>(),
        ),
        (
            "Multistart<7, 4> (the default strategy's state)",
            size_of::<Multistart<7, 4>>(),
        ),
        (
            "Cpso<4, 64> (C-PSO's state, 64 particles)",
            size_of::<Cpso<4, 64>>(),
        ),
        (
            "Search<7, 4, 64> (the larger of the two)",
            size_of::<Search<7, 4, 64>>(),
        ),
        ("Planner<7, 4, 64>", size_of::<Planner<7, 4, 64>>()),
    ];
    for (name, size) in sizes {
        println!("{name}: {size} bytes");
    }
    assert_eq!(size_of::<Task<7, 4>>(), 7032);
    assert_eq!(size_of::<Rollout<7, 4>>(), 2536);
    assert_eq!(size_of::<Planner<7, 4, 64>>(), 39976);
    assert_eq!(size_of::<Multistart<7, 4>>(), 26448);
    assert_eq!(size_of::<reactionless::CollisionSet<7>>(), 3584);
    assert_eq!(size_of::<Cpso<4, 64>>(), 16608);
    // Only the chosen strategy's state occupies the planner: the search is the larger of
    // the two (its tag lives in a niche), not both.
    assert_eq!(
        size_of::<Search<7, 4, 64>>(),
        size_of::<Multistart<7, 4>>().max(size_of::<Cpso<4, 64>>())
    );
}

/// `GridPoint<N>` is `8(N+1)` bytes (docs/retime.md, "Storage"); the stream's state is
/// O(1): a fixed size independent of the grid.
/// Verifies RL-RETIME-002.
#[test]
fn documented_retime_sizes() {
    use reactionless::retime::{GridPoint, Stream};
    assert_eq!(size_of::<GridPoint<7>>(), 64);
    assert_eq!(size_of::<GridPoint<9>>(), 80);
    println!("Stream: {} bytes", size_of::<Stream>());
    assert!(size_of::<Stream>() <= 96);
}

/// The two-phase plan's state (docs/twophase.md, "Memory"): the plan, phase 1 and its
/// demand, and the resumable search (static in the flight image, on the stack in `plan`).
/// Verifies RL-CORE-005.
#[test]
fn documented_two_phase_sizes() {
    use reactionless::{Demand, Preshape, TwoPhasePlan, TwoPhaseSearch};
    let sizes = [
        ("Preshape<7>", size_of::<Preshape<7>>()),
        ("Demand", size_of::<Demand>()),
        ("TwoPhasePlan<7, 4>", size_of::<TwoPhasePlan<7, 4>>()),
        ("TwoPhaseSearch<7, 4>", size_of::<TwoPhaseSearch<7, 4>>()),
    ];
    for (name, size) in sizes {
        println!("{name}: {size} bytes");
    }
    assert_eq!(
        sizes,
        [
            ("Preshape<7>", 136),
            ("Demand", 40),
            ("TwoPhasePlan<7, 4>", 648),
            ("TwoPhaseSearch<7, 4>", 29672),
        ]
    );
}

/// The closed-loop executor's state and one cycle's command (docs/core.md).
#[test]
fn documented_closed_loop_sizes() {
    use reactionless::closed_loop::{Command, Executor, LoopConfig, Measurement, PlanLoop};
    let sizes = [
        ("LoopConfig", size_of::<LoopConfig>()),
        ("Executor<7>", size_of::<Executor<7>>()),
        ("PlanLoop<7, 4>", size_of::<PlanLoop<7, 4>>()),
        ("Measurement<7>", size_of::<Measurement<7>>()),
        ("Command<7>", size_of::<Command<7>>()),
    ];
    for (name, size) in sizes {
        println!("{name}: {size} bytes");
    }
    assert_eq!(
        sizes,
        [
            ("LoopConfig", 112),
            ("Executor<7>", 648),
            ("PlanLoop<7, 4>", 3712),
            ("Measurement<7>", 136),
            ("Command<7>", 120),
        ]
    );
}
