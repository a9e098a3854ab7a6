//! Runs 300 rollouts of the reference task (for profilers such as callgrind).
#![allow(missing_docs, clippy::unwrap_used)]

use reactionless::reference::{ETA_HAT, paper_task};

fn main() {
    let task = paper_task().unwrap();
    let mut f = 0.0;
    for _ in 0..300 {
        f += task
            .rollout(std::hint::black_box(&ETA_HAT), &mut ())
            .unwrap()
            .f;
    }
    println!("{f}");
}
