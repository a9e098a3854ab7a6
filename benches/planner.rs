//! Criterion benchmark of planning the reference task (spec §8) to σ_e with both
//! strategies: the default multistart and the paper's C-PSO (seed 1 each).
//!
//! `cargo bench --bench planner`
#![allow(missing_docs, clippy::unwrap_used, clippy::panic)]

use criterion::{Criterion, criterion_group, criterion_main};
use reactionless::reference::paper_task;
use reactionless::{Planner, PlannerConfig, Status, Strategy};
use std::hint::black_box;

fn plan(config: PlannerConfig) -> f64 {
    let mut p: Box<Planner<7, 4, 64>> =
        Box::new(Planner::new(paper_task().unwrap(), config).unwrap());
    loop {
        if let Status::Finished(plan) = p.step(u32::MAX, &mut ()).unwrap() {
            return plan.outcome.f;
        }
    }
}

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("plan_reference_task_seed_1");
    group.sample_size(10);
    for strategy in [Strategy::Multistart, Strategy::Cpso] {
        let mut config = PlannerConfig::default_with_seed(1);
        config.strategy = strategy;
        group.bench_function(strategy.name(), |b| {
            b.iter(|| black_box(plan(black_box(config))))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
