//! Criterion benchmarks of rollouts in lanes (issue #15): one full rollout of the reference
//! task at L = 1 (the scalar [`Task::rollout`]) and L candidates in lockstep
//! ([`Batch`], the portable build), reported per rollout-equivalent.
//!
//! `cargo bench --bench lanes`
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use reactionless::batch::Batch;
use reactionless::reference::{ETA_HAT, paper_task};
use std::hint::black_box;

fn lanes<const L: usize>(c: &mut Criterion) {
    let task = paper_task().unwrap();
    let mut g = c.benchmark_group("rollout_lanes");
    g.throughput(Throughput::Elements(L as u64));
    g.bench_function(format!("L{L}"), |b| {
        b.iter(|| {
            let mut batch: Batch<7, 4, L> = Batch::new(&task);
            for i in 0..L {
                let mut eta = ETA_HAT;
                eta[0][0] += i as f64 * 1e-3;
                batch.load(i, &task, &eta, f64::INFINITY).unwrap();
            }
            while batch.running() > 0 {
                batch.advance(&task, u32::MAX, [false; L]);
            }
            black_box(batch.take(0))
        })
    });
    g.finish();
}

fn bench(c: &mut Criterion) {
    let task = paper_task().unwrap();
    c.bench_function("rollout_lanes/scalar", |b| {
        b.iter(|| black_box(task.rollout(black_box(&ETA_HAT), &mut ()).unwrap()))
    });
    lanes::<1>(c);
    lanes::<2>(c);
    lanes::<4>(c);
}

criterion_group!(benches, bench);
criterion_main!(benches);
