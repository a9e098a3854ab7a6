//! Criterion benchmarks of the core's hot path on the reference task (spec §8):
//! one integration step and one full rollout (3000 steps).
//!
//! `cargo bench --bench rollout`
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use reactionless::{CHASER7, Motion, Pose, Robot, Rollout, Task};
use std::hint::black_box;

const ETA_HAT: [[f64; 2]; 4] = [
    [3.14771, 0.809316],
    [1.12249, 0.754006],
    [4.7352, 0.406031],
    [-4.1572, 4.29895],
];

fn paper_task() -> Task<7, 4> {
    let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
    let target = Pose {
        position: [2.0166710746921925, 0.13996636886034725, -1.43192511932475],
        quat_wxyz: [
            0.3874560731031927,
            0.2654610699800615,
            -0.37163840872581944,
            0.8008077827420479,
        ],
    };
    let robot = Robot::new(&CHASER7).unwrap();
    Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1).unwrap()).unwrap()
}

fn bench(c: &mut Criterion) {
    let task = paper_task();
    let mut mid = Rollout::new(&task, &ETA_HAT).unwrap();
    mid.advance(&task, 1500, &mut ()).unwrap();
    c.bench_function("integration_step", |b| {
        b.iter(|| {
            let mut r = black_box(mid);
            black_box(r.advance(&task, 1, &mut ()).unwrap())
        })
    });
    c.bench_function("rollout_3000_steps", |b| {
        b.iter(|| black_box(task.rollout(black_box(&ETA_HAT), &mut ()).unwrap()))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
