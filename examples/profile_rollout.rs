//! Runs 300 rollouts of the reference task (for profilers such as callgrind); the first
//! argument, if any, sets the count.
#![allow(missing_docs, clippy::unwrap_used)]

use reactionless::reference::{ETA_HAT, paper_task};

fn main() {
    let task = paper_task().unwrap();
    let count: u32 = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(300);
    let mut f = 0.0;
    for _ in 0..count {
        f += task
            .rollout(std::hint::black_box(&ETA_HAT), &mut ())
            .unwrap()
            .f;
    }
    println!("{f}");
}
