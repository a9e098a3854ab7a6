//! Criterion benchmarks of the core's hot path on the reference task (spec §8):
//! one integration step and one full rollout (3000 steps), and the same rollout by RK4
//! and by AB5 (issue #32: 75 steps of 0.4 s, 150 of 0.2 s, the samples not taken), and the
//! Euler rollout with collision geometry (issue #33: chaser7's 8 primitives of
//! `spec/chaser7.urdf` and the 3 keep-outs of `tests/tasks/collision/paper-keep-outs.toml`,
//! 45 pairs).
//!
//! `cargo bench --bench rollout`
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use reactionless::clearance::CollisionSet;
use reactionless::collision::{Placed, Shape};
use reactionless::geometry::{Vec3, rpy_matrix};
use reactionless::reference::{ETA_HAT, paper_task};
use reactionless::{Integrator, Robot, Rollout, Task};
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

/// `shape` at `xyz` turned by `rpy` (rad).
fn at(shape: Shape, xyz: [f64; 3], rpy: [f64; 3]) -> Placed {
    Placed {
        shape,
        rot: rpy_matrix(rpy),
        pos: Vec3::from(xyz),
    }
}

/// spec/chaser7.urdf's collision geometry and paper-keep-outs.toml's keep-outs (0.02 m).
fn keep_outs(robot: &Robot<7>) -> CollisionSet<7> {
    let mut set = CollisionSet::new(0.02, 0.005).unwrap();
    let bus = Shape::Box {
        half: [0.74025, 1.17555, 0.64545],
    };
    set.add_primitive(robot, 0, &at(bus, [0.0; 3], [0.0; 3]))
        .unwrap();
    let along_x = [0.0, std::f64::consts::FRAC_PI_2, 0.0];
    let links = [
        (0.0565, 0.0, 0.0565),
        (0.6625, 1.1912, 0.0669),
        (0.04, 0.0, 0.04),
        (0.463, 0.8016, 0.0622),
        (0.04, 0.0, 0.04),
        (0.125, 0.1058, 0.0721),
        (0.02, 0.0, 0.02),
    ];
    for (i, (x, length, radius)) in links.into_iter().enumerate() {
        let capsule = Shape::Capsule { length, radius };
        set.add_primitive(robot, i as u8 + 1, &at(capsule, [x, 0.0, 0.0], along_x))
            .unwrap();
    }
    let deg = f64::to_radians;
    for placed in [
        at(
            Shape::Box {
                half: [0.6, 0.6, 0.7],
            },
            [2.0, 0.2, -2.4],
            [0.0; 3],
        ),
        at(
            Shape::Box {
                half: [0.5, 1.5, 0.01],
            },
            [2.0, 2.3, -2.2],
            [0.0, 0.0, deg(10.0)],
        ),
        at(
            Shape::Capsule {
                length: 0.3,
                radius: 0.04,
            },
            [2.0, -0.2, -1.55],
            [deg(90.0), 0.0, 0.0],
        ),
    ] {
        set.add_keep_out(&placed).unwrap();
    }
    set
}

fn bench_collision(c: &mut Criterion) {
    let task = paper_task().unwrap();
    let geo = task
        .clone()
        .with_collision(keep_outs(task.robot()))
        .unwrap();
    c.bench_function("rollout_3000_steps_keep_outs", |b| {
        b.iter(|| black_box(geo.rollout(black_box(&ETA_HAT), &mut ()).unwrap()))
    });
}

criterion_group!(benches, bench, bench_collision);
criterion_main!(benches);
