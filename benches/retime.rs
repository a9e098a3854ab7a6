//! Criterion benchmark of re-timing ([`reactionless::retime`]) on the reference plan
//! (spec §8) at 15 °/s and 5 °/s²: the solve (backward + forward pass) on a 3000-point
//! grid, and the whole setpoint stream at `dt` = 0.01 s.
//!
//! `cargo bench --bench retime`
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use reactionless::reference::{ETA_HAT, paper_task};
use reactionless::retime::{self, GridPoint, Limits, Stream};
use std::hint::black_box;

fn bench(c: &mut Criterion) {
    let task = paper_task().unwrap();
    let mut grid = vec![GridPoint::<7>::ZERO; 3000];
    let path = retime::path_of_rollout(&task, &ETA_HAT, &mut grid, 3000).unwrap();
    let limits = Limits::new(
        task.robot().desc().joints.map(|j| j.velocity),
        [5f64.to_radians(); 7],
        1.0,
    )
    .unwrap();
    c.bench_function("retime_solve_3000_points", |b| {
        b.iter_batched_ref(
            || grid.clone(),
            |g| black_box(retime::solve(g, &path, &limits).unwrap()),
            BatchSize::LargeInput,
        )
    });
    let profile = retime::solve(&mut grid, &path, &limits).unwrap();
    c.bench_function("retime_stream_all_setpoints", |b| {
        b.iter(|| {
            let mut s = Stream::new(&profile, 0.01).unwrap();
            let mut n = 0u32;
            while let Some(sp) = s.next(&grid) {
                n += black_box(sp).step & 1;
            }
            n
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
