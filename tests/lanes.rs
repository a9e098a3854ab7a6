//! Rollouts in lanes (issue #15): every lane of a [`Batch`] gives the bits of the scalar
//! rollout, and a planner that evaluates candidates in lanes gives the plan of the scalar
//! planner, under any budget slicing.
#![allow(missing_docs, clippy::unwrap_used, clippy::indexing_slicing)]

mod common;

use common::{paper_task, random_q, random_robot, rng};
use rand::Rng;
use reactionless::batch::{Batch, Ended, Lane};
use reactionless::{
    Error, Motion, Plan, Planner, PlannerConfig, Pose, Progress, Robot, Rollout, Status, Strategy,
    Task,
};

/// How the scalar rollout of `eta` with violation cap `cap` ends, as a lane reports it.
fn scalar<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    cap: f64,
) -> Ended<N> {
    let mut r = match Rollout::new(task, eta) {
        Ok(r) => r.with_violation_cap(cap),
        Err(e) => return Ended::Failed(e),
    };
    loop {
        match r.advance(task, u32::MAX, &mut ()) {
            Ok(Progress::Running { .. }) => {}
            Ok(Progress::Done(o)) => return Ended::Done(o),
            Ok(Progress::Abandoned { step, phi }) => return Ended::Abandoned { step, phi },
            Err(e) => return Ended::Failed(e),
        }
    }
}

/// Bit-exact comparison through `Debug` (which prints every f64 exactly, `-0.0` and NaN
/// included).
fn same<T: core::fmt::Debug>(a: &T, b: &T) -> bool {
    format!("{a:?}") == format!("{b:?}")
}

/// Runs `etas` through an `L`-lane batch, loading a lane as soon as one is free and
/// advancing by `slice` lane-steps at a time, holding lanes by a pseudo-random pattern
/// now and then; returns each η's end in order.
fn through_lanes<const N: usize, const K: usize, const L: usize>(
    task: &Task<N, K>,
    etas: &[([[f64; 2]; K], f64)],
    slice: u32,
    seed: u64,
) -> Vec<Ended<N>> {
    let mut r = rng(seed);
    let mut b: Batch<N, K, L> = Batch::new(task);
    let mut owner = [usize::MAX; L];
    let mut out: Vec<Option<Ended<N>>> = vec![None; etas.len()];
    let mut next = 0;
    loop {
        for lane in 0..L {
            if let Some(e) = b.take(lane) {
                out[owner[lane]] = Some(e);
                owner[lane] = usize::MAX;
            }
            if matches!(b.lane(lane), Some(Lane::Empty)) && next < etas.len() {
                let (eta, cap) = &etas[next];
                match b.load(lane, task, eta, *cap) {
                    Ok(()) => owner[lane] = next,
                    Err(e) => out[next] = Some(Ended::Failed(e)),
                }
                next += 1;
            }
        }
        if b.running() == 0 && next >= etas.len() {
            break;
        }
        let hold: [bool; L] = core::array::from_fn(|_| r.random_range(0..4) == 0);
        b.advance(task, slice, hold);
    }
    out.into_iter().map(Option::unwrap).collect()
}

fn random_etas<const K: usize>(seed: u64, count: usize) -> Vec<([[f64; 2]; K], f64)> {
    let mut r = rng(seed);
    (0..count)
        .map(|i| {
            let eta =
                core::array::from_fn(|_| [r.random_range(-5.0..5.0), r.random_range(-5.0..5.0)]);
            // Every third one capped (some abandon), one rejected (η = 0).
            let cap = match i % 3 {
                0 => r.random_range(0.0..0.2),
                _ => f64::INFINITY,
            };
            if i == 5 {
                ([[0.0; 2]; K], cap)
            } else {
                (eta, cap)
            }
        })
        .collect()
}

/// Checks 23 random η of `task` in lanes; returns how many the scalar rollout abandons.
fn check_lanes<const N: usize, const K: usize>(task: &Task<N, K>, seed: u64) -> usize {
    let etas = random_etas::<K>(seed, 23);
    let want: Vec<_> = etas.iter().map(|(e, c)| scalar(task, e, *c)).collect();
    assert!(want.iter().any(|e| matches!(e, Ended::Done(_))));
    assert!(want.iter().any(|e| matches!(e, Ended::Failed(_))));
    for (slice, l2, l4, l8) in [
        (
            u32::MAX,
            through_lanes::<N, K, 2>(task, &etas, u32::MAX, seed),
            through_lanes::<N, K, 4>(task, &etas, u32::MAX, seed),
            through_lanes::<N, K, 8>(task, &etas, u32::MAX, seed),
        ),
        (
            37,
            through_lanes::<N, K, 2>(task, &etas, 37, seed),
            through_lanes::<N, K, 4>(task, &etas, 37, seed),
            through_lanes::<N, K, 8>(task, &etas, 37, seed),
        ),
    ] {
        for (i, w) in want.iter().enumerate() {
            assert!(
                same(&l2[i], w),
                "N={N} L=2 slice {slice} η #{i}: {:?} vs {w:?}",
                l2[i]
            );
            assert!(same(&l4[i], w), "N={N} L=4 slice {slice} η #{i}");
            assert!(same(&l8[i], w), "N={N} L=8 slice {slice} η #{i}");
        }
    }
    want.iter()
        .filter(|e| matches!(e, Ended::Abandoned { .. }))
        .count()
}

/// A short task of a random robot, target at a random pose (reachability is not needed to
/// compare rollouts).
fn random_task<const N: usize, const K: usize>(seed: u64) -> Task<N, K> {
    let mut r = rng(seed);
    let desc = random_robot::<N>(&mut r);
    let q0 = random_q(&mut r, &desc);
    let robot = Robot::new(&desc).unwrap();
    let target = Pose {
        position: [1.0, 0.2, -0.3],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    Task::new(robot, q0, target, Motion::new(4.0, 0.01, 1).unwrap()).unwrap()
}

/// Each lane of a batch ends exactly as the scalar rollout of its η and cap (outcome,
/// abandonment step and Φ, or error), bit for bit, for 2, 4 and 8 lanes, lanes loaded
/// while others run, any slicing and held lanes; robots of 7, 6, 9 and 12 joints.
/// Verifies RL-LANE-001.
#[test]
fn every_lane_is_the_scalar_rollout_bit_for_bit() {
    let abandoned = check_lanes(&paper_task(), 1)
        + check_lanes(&random_task::<6, 3>(2), 2)
        + check_lanes(&random_task::<9, 6>(3), 3)
        + check_lanes(&random_task::<12, 9>(4), 4);
    assert!(
        abandoned > 0,
        "no lane was abandoned: the caps are not exercised"
    );
}

/// A lane whose rollout fails (here a state that overflows) reports the scalar error at the
/// scalar step; lanes failing at different steps and lanes loaded later are not disturbed.
/// Verifies RL-LANE-001.
#[test]
fn a_failing_lane_reports_the_scalar_error_at_the_scalar_step() {
    let mut d = reactionless::CHASER7;
    for j in &mut d.joints {
        j.velocity = 1e305;
    }
    let robot = Robot::new(&d).unwrap();
    let target = Pose {
        position: [2.0, 0.1, -1.4],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let task: Task<7, 4> = Task::new(
        robot,
        common::q0(),
        target,
        Motion::new(1e7, 1e6, 1).unwrap(),
    )
    .unwrap();
    let etas: Vec<_> = random_etas::<4>(11, 9)
        .into_iter()
        .map(|(e, _)| (e, f64::INFINITY))
        .collect();
    let want: Vec<_> = etas.iter().map(|(e, c)| scalar(&task, e, *c)).collect();
    assert!(
        want.iter()
            .filter(|e| matches!(e, Ended::Failed(Error::NonFiniteState { .. })))
            .count()
            >= 4,
        "{want:?}"
    );
    for got in [
        through_lanes::<7, 4, 2>(&task, &etas, 1, 9),
        through_lanes::<7, 4, 4>(&task, &etas, 3, 9),
    ] {
        for (g, w) in got.iter().zip(&want) {
            assert!(same(g, w), "{g:?} vs {w:?}");
        }
    }
}

type P1 = Planner<7, 4, 64>;
type P2 = Planner<7, 4, 64, 2>;
type P4 = Planner<7, 4, 64, 4>;

fn plan_with<const L: usize>(cfg: PlannerConfig, budget: u32) -> (Plan<7, 4>, u64) {
    let mut p: Planner<7, 4, 64, L> = Planner::new(paper_task(), cfg).unwrap();
    loop {
        if let Status::Finished(plan) = p.step(budget, &mut ()).unwrap() {
            return (plan, p.spent());
        }
    }
}

/// The planner with candidates in 2 or 4 lanes gives the plan of the scalar planner, bit
/// for bit, for both strategies and a refinement, under budget slicing of 1, 7, 3000 and
/// unlimited steps per call; every call stays within its budget.
/// Verifies RL-LANE-003.
#[test]
fn planning_in_lanes_gives_the_scalar_plan_under_any_slicing() {
    let _ = (P1::IDLE, P2::IDLE, P4::IDLE);
    let mut configs = Vec::new();
    for seed in [1, 2] {
        configs.push(PlannerConfig::default_with_seed(seed));
    }
    let mut cpso = PlannerConfig::reference(3);
    cpso.strategy = Strategy::Cpso;
    cpso.max_iterations = 4;
    configs.push(cpso);
    let mut refined = PlannerConfig::reference(2);
    refined.strategy = Strategy::Cpso;
    refined.max_iterations = 3;
    refined.tolerance = 10.0;
    refined.refine_tolerance = Some(1e-3);
    refined.refine_max_rollouts = 40;
    configs.push(refined);
    for cfg in configs {
        let (want, _) = plan_with::<1>(cfg, u32::MAX);
        for budget in [u32::MAX, 3000, 7, 1] {
            if budget < 7 && cfg.strategy == Strategy::Cpso {
                continue; // budget 1 over a C-PSO run takes minutes unoptimised
            }
            let (p2, _) = plan_with::<2>(cfg, budget);
            let (p4, _) = plan_with::<4>(cfg, budget);
            assert!(same(&p2, &want), "L=2 budget {budget} {cfg:?}");
            assert!(same(&p4, &want), "L=4 budget {budget} {cfg:?}");
        }
    }
}

/// `step(budget)` never spends more than `budget` units with lanes (one unit per lane's
/// integration step).
/// Verifies RL-LANE-003.
#[test]
fn a_call_never_spends_more_than_its_budget_in_lanes() {
    let cfg = PlannerConfig::default_with_seed(1);
    for budget in [1u32, 2, 3, 5, 4000] {
        let mut p: P4 = Planner::new(paper_task(), cfg).unwrap();
        let mut before = 0;
        for _ in 0..200 {
            let s = p.step(budget, &mut ()).unwrap();
            assert!(p.spent() - before <= u64::from(budget), "budget {budget}");
            before = p.spent();
            if let Status::Finished(_) = s {
                break;
            }
        }
    }
}
