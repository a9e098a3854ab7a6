//! Criterion benchmarks of the core's hot path on the reference task (spec §8):
//! one integration step and one full rollout (3000 steps), and the same rollout by RK4
//! and by AB5 (issue #32: 75 steps of 0.4 s, 150 of 0.2 s, the samples not taken).
//!
//! `cargo bench --bench rollout`
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use reactionless::reference::{ETA_HAT, paper_task};
use reactionless::{Integrator, Rollout, Task};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let task = paper_task().unwrap();
    let mut mid = Rollout::new(&task, &ETA_HAT).unwrap();
    mid.advance(&task, 1500, &mut ()).unwrap();
    // One `advance(&task, 1, …)` call at step 1500; the copy of the 856-byte state that
    // each iteration starts from is set-up, outside the timing.
    c.bench_function("integration_step", |b| {
        b.iter_batched_ref(
            || mid,
            |r| black_box(r.advance(&task, 1, &mut ()).unwrap()),
            BatchSize::SmallInput,
        )
    });
    c.bench_function("rollout_3000_steps", |b| {
        b.iter(|| black_box(task.rollout(black_box(&ETA_HAT), &mut ()).unwrap()))
    });
    for (integrator, name) in [
        (Integrator::Rk4, "rollout_rk4_75_steps"),
        (Integrator::Ab5, "rollout_ab5_150_steps"),
    ] {
        let motion = task.motion().with_integrator(integrator).unwrap();
        let by: Task<7, 4> =
            Task::new(task.robot().clone(), *task.start(), *task.target(), motion).unwrap();
        c.bench_function(name, |b| {
            b.iter(|| black_box(by.rollout(black_box(&ETA_HAT), &mut ()).unwrap()))
        });
    }
}

criterion_group!(benches, bench);
criterion_main!(benches);
