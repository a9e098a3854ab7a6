//! The sizes of the core's state are documented figures (README, "Memory"); this test
//! pins them so the documentation cannot drift.
//!
//! Requirements: RL-CORE (docs/requirements.md).
#![allow(missing_docs)]

use core::mem::size_of;
use reactionless::{Basis, Frames, Multistart, Outcome, Planner, Robot, Rollout, Task, TimeLaw};

/// `size_of` of Task<7, 4>, Rollout<7, 4> and Planner<7, 4, 64> equal the README's x86-64
/// figures.
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
        ("Multistart<7, 4>", size_of::<Multistart<7, 4>>()),
        ("Planner<7, 4, 64>", size_of::<Planner<7, 4, 64>>()),
    ];
    for (name, size) in sizes {
        println!("{name}: {size} bytes");
    }
    assert_eq!(size_of::<Task<7, 4>>(), 3432);
    assert_eq!(size_of::<Rollout<7, 4>>(), 856);
    assert_eq!(size_of::<Planner<7, 4, 64>>(), 37072);
    assert_eq!(size_of::<Multistart<7, 4>>(), 13808);
}
