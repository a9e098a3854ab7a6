//! Criterion benchmarks of rollouts in lanes (issue #15), in the build of the kernel this
//! CPU runs (`REACTIONLESS_ISA` forces one): for N = 6, 7, 9 and 12 joints (an arm6, the
//! reference task, an arm9 and an arm12 task of `tests/tasks/a`) and L = 1 (the scalar
//! rollout), 2 and 4 lanes, one integration step and one full rollout (3000 steps). Each
//! lane integrates the η of a different plan (seeds 1..L); throughput is reported per
//! rollout (element = one rollout, or one integration step).
//!
//! `cargo bench -p reactionless-simd --bench lanes`
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing
)]

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use reactionless::batch::{Batch, Engine};
use reactionless::{Planner, Progress, Rollout, Status, Task};
use reactionless_simd::{Isa, Native};
use std::hint::black_box;
use std::path::Path;

/// The task of `path` (relative to the workspace) and the η of its plans for seeds 1..4.
fn task_and_etas<const N: usize, const K: usize>(path: &str) -> (Task<N, K>, Vec<[[f64; 2]; K]>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let lt = host_sim::taskfile::load(&root.join(path)).unwrap();
    let task = lt.task::<N, K>().unwrap();
    let etas = (1..=4)
        .map(|seed| {
            let overrides = host_sim::taskfile::Overrides {
                seed: Some(seed),
                ..Default::default()
            };
            let config = lt.planner(64, &overrides).unwrap();
            let mut p: Planner<N, K, 64> = Planner::new(task.clone(), config).unwrap();
            loop {
                if let Status::Finished(plan) = p.step(u32::MAX, &mut ()).unwrap() {
                    break plan.eta[0];
                }
            }
        })
        .collect();
    (task, etas)
}

/// A batch with lane i running `etas[i]`, advanced by `at` steps.
fn loaded<const N: usize, const K: usize, const L: usize>(
    task: &Task<N, K>,
    etas: &[[[f64; 2]; K]],
    at: u32,
) -> Batch<N, K, L> {
    let mut b = Batch::new(task);
    for (i, eta) in etas.iter().take(L).enumerate() {
        b.load(i, task, eta, f64::INFINITY).unwrap();
    }
    let mut done = 0;
    while done < at * L as u32 {
        done += Native::run(&mut b, task, at - done / L as u32, [false; L]);
    }
    b
}

fn lanes<const N: usize, const K: usize, const L: usize>(
    c: &mut Criterion,
    task: &Task<N, K>,
    etas: &[[[f64; 2]; K]],
) {
    let mut g = c.benchmark_group(format!("lanes/N{N}"));
    g.throughput(Throughput::Elements(L as u64));
    let mid = loaded::<N, K, L>(task, etas, 1500);
    g.bench_function(format!("step/L{L}"), |b| {
        b.iter_batched_ref(
            || mid,
            |batch| black_box(Native::run(batch, task, 1, [false; L])),
            BatchSize::SmallInput,
        )
    });
    g.bench_function(format!("rollout/L{L}"), |b| {
        b.iter(|| {
            let mut batch = loaded::<N, K, L>(task, etas, 0);
            while batch.running() > 0 {
                Native::run(&mut batch, task, u32::MAX, [false; L]);
            }
            black_box(batch.take(0))
        })
    });
    g.finish();
}

fn scalar<const N: usize, const K: usize>(
    c: &mut Criterion,
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
) {
    let mut g = c.benchmark_group(format!("lanes/N{N}"));
    g.throughput(Throughput::Elements(1));
    let mut mid = Rollout::new(task, eta).unwrap();
    mid.advance(task, 1500, &mut ()).unwrap();
    g.bench_function("step/L1", |b| {
        b.iter_batched_ref(
            || mid,
            |r| black_box(r.advance(task, 1, &mut ()).unwrap()),
            BatchSize::SmallInput,
        )
    });
    g.bench_function("rollout/L1", |b| {
        b.iter(|| {
            let mut r = Rollout::new(task, eta).unwrap();
            loop {
                if let Progress::Done(o) = r.advance(task, u32::MAX, &mut ()).unwrap() {
                    break black_box(o);
                }
            }
        })
    });
    g.finish();
}

fn size<const N: usize, const K: usize>(c: &mut Criterion, path: &str) {
    let (task, etas) = task_and_etas::<N, K>(path);
    scalar(c, &task, &etas[0]);
    lanes::<N, K, 2>(c, &task, &etas);
    lanes::<N, K, 4>(c, &task, &etas);
}

fn bench(c: &mut Criterion) {
    eprintln!("lane kernel build: {}", Isa::native().name());
    size::<6, 3>(c, "tests/tasks/a/arm6/task_001.toml");
    size::<7, 4>(c, "spec/tasks/paper.toml");
    size::<9, 6>(c, "tests/tasks/a/arm9/task_001.toml");
    size::<12, 9>(c, "tests/tasks/a/arm12/task_001.toml");
}

criterion_group!(benches, bench);
criterion_main!(benches);
