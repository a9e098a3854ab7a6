//! Each build of the lane kernel, forced in turn (the SSE2 baseline, and AVX2 where this
//! CPU has it), gives every lane the bits of the scalar rollout, and the planner the plan
//! of the scalar planner. (The golden records are replayed in each build by host-sim's
//! `golden_records_replay_bit_for_bit`.)
#![allow(
    missing_docs,
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic
)]

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use reactionless::batch::{Batch, Ended, Engine, Lane};
use reactionless::reference::{ETA_HAT, paper_task};
use reactionless::{
    Motion, Planner, PlannerConfig, Pose, Progress, Robot, Rollout, Status, Strategy, Task,
};
use reactionless_simd::{ForceAvx2, ForceBaseline, Isa, Threaded};

fn scalar<const N: usize, const K: usize>(t: &Task<N, K>, eta: &[[f64; 2]; K], cap: f64) -> String {
    let end = match Rollout::new(t, eta) {
        Err(e) => Ended::Failed(e),
        Ok(r) => {
            let mut r = r.with_violation_cap(cap);
            loop {
                match r.advance(t, u32::MAX, &mut ()) {
                    Ok(Progress::Running { .. }) => {}
                    Ok(Progress::Done(o)) => break Ended::Done(o),
                    Ok(Progress::Abandoned { step, phi }) => break Ended::Abandoned { step, phi },
                    Err(e) => break Ended::Failed(e),
                }
            }
        }
    };
    format!("{end:?}")
}

/// Every η through `L` lanes of engine `E`, lanes refilled as they free up.
fn lanes<E: Engine, const N: usize, const K: usize, const L: usize>(
    t: &Task<N, K>,
    etas: &[([[f64; 2]; K], f64)],
) -> Vec<String> {
    let mut b: Batch<N, K, L> = Batch::new(t);
    let mut owner = [usize::MAX; L];
    let mut out = vec![String::new(); etas.len()];
    let mut next = 0;
    loop {
        for lane in 0..L {
            if let Some(e) = b.take(lane) {
                out[owner[lane]] = format!("{e:?}");
            }
            if matches!(b.lane(lane), Some(Lane::Empty)) && next < etas.len() {
                let (eta, cap) = &etas[next];
                b.load(lane, t, eta, *cap).unwrap();
                owner[lane] = next;
                next += 1;
            }
        }
        if b.running() == 0 && next >= etas.len() {
            return out;
        }
        E::run(&mut b, t, 211, [false; L]);
    }
}

/// A random robot's task (joint offsets and twists of every kind), short.
fn task<const N: usize, const K: usize>(seed: u64) -> Task<N, K> {
    let mut r = StdRng::seed_from_u64(seed);
    let mut d = reactionless::RobotDesc::<N> {
        base: reactionless::CHASER7.base,
        joints: core::array::from_fn(|i| reactionless::CHASER7.joints[i % 7]),
        links: core::array::from_fn(|i| reactionless::CHASER7.links[i % 7]),
        end_effector: reactionless::CHASER7.end_effector,
    };
    for j in &mut d.joints {
        j.axis = [
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
            r.random_range(0.5..1.0),
        ];
        let n = (j.axis.iter().map(|v| v * v).sum::<f64>()).sqrt();
        j.axis = j.axis.map(|v| v / n);
        j.origin.rpy = [
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
            r.random_range(-1.0..1.0),
        ];
        j.lower = -3.0;
        j.upper = 3.0;
    }
    let robot = Robot::new(&d).unwrap();
    let q0 = core::array::from_fn(|_| r.random_range(-1.0..1.0));
    let target = Pose {
        position: [1.0, 0.0, 0.0],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    Task::new(robot, q0, target, Motion::new(8.0, 0.01, 1).unwrap()).unwrap()
}

fn etas<const K: usize>(seed: u64) -> Vec<([[f64; 2]; K], f64)> {
    let mut r = StdRng::seed_from_u64(seed);
    (0..11)
        .map(|i| {
            let eta =
                core::array::from_fn(|_| [r.random_range(-5.0..5.0), r.random_range(-5.0..5.0)]);
            (eta, if i % 3 == 0 { 0.05 } else { f64::INFINITY })
        })
        .collect()
}

fn check<E: Engine, const N: usize, const K: usize>(t: &Task<N, K>, seed: u64) {
    let etas = etas::<K>(seed);
    let want: Vec<String> = etas.iter().map(|(e, c)| scalar(t, e, *c)).collect();
    assert_eq!(lanes::<E, N, K, 4>(t, &etas), want, "N = {N}, 4 lanes");
    assert_eq!(lanes::<E, N, K, 2>(t, &etas), want, "N = {N}, 2 lanes");
}

/// Chunks of 4 lanes on rayon's threads ([`Threaded`]): 8 lanes (two chunks) and 12
/// (three), every lane the scalar rollout, bit for bit (N = 6, 7, 9, 12).
/// Verifies RL-LANE-006.
#[test]
fn threaded_lanes_are_the_scalar_rollout() {
    fn wide<const N: usize, const K: usize>(t: &Task<N, K>, seed: u64) {
        let etas = etas::<K>(seed);
        let want: Vec<String> = etas.iter().map(|(e, c)| scalar(t, e, *c)).collect();
        assert_eq!(
            lanes::<Threaded, N, K, 8>(t, &etas),
            want,
            "N = {N}, 8 lanes"
        );
        assert_eq!(
            lanes::<Threaded, N, K, 12>(t, &etas),
            want,
            "N = {N}, 12 lanes"
        );
    }
    wide::<7, 4>(&paper_task().unwrap(), 1);
    wide::<6, 3>(&task::<6, 3>(2), 2);
    wide::<9, 6>(&task::<9, 6>(3), 3);
    wide::<12, 9>(&task::<12, 9>(4), 4);
}

fn every_size<E: Engine>() {
    check::<E, 7, 4>(&paper_task().unwrap(), 1);
    check::<E, 6, 3>(&task::<6, 3>(2), 2);
    check::<E, 9, 6>(&task::<9, 6>(3), 3);
    check::<E, 12, 9>(&task::<12, 9>(4), 4);
}

/// The SSE2 baseline build: every lane is the scalar rollout, bit for bit (N = 6, 7, 9, 12;
/// 2 and 4 lanes; capped and uncapped).
/// Verifies RL-LANE-004.
#[test]
fn the_baseline_build_is_the_scalar_rollout() {
    every_size::<ForceBaseline>();
}

/// The AVX2 build (where this CPU has AVX2): every lane is the scalar rollout, bit for bit.
/// Verifies RL-LANE-004.
#[test]
fn the_avx2_build_is_the_scalar_rollout() {
    if !Isa::Avx2.available() {
        eprintln!("this CPU has no AVX2: the AVX2 build is not exercised here");
        return;
    }
    every_size::<ForceAvx2>();
}

fn plan<const L: usize, E: Engine>(cfg: PlannerConfig) -> String {
    plan_sliced::<L, E>(cfg, 3000)
}

/// The plan, in calls of `budget`; no call spends more than `budget`.
fn plan_sliced<const L: usize, E: Engine>(cfg: PlannerConfig, budget: u32) -> String {
    let mut p: Planner<7, 4, 64, L, E> = Planner::new(paper_task().unwrap(), cfg).unwrap();
    loop {
        let before = p.spent();
        let status = p.step(budget, &mut ()).unwrap();
        assert!(p.spent() - before <= u64::from(budget), "a call overspent");
        if let Status::Finished(plan) = status {
            return format!("{plan:?}");
        }
    }
}

/// Planning with 4 lanes in each build gives the scalar planner's plan, bit for bit
/// (default strategy, two seeds, and C-PSO).
/// Verifies RL-LANE-003, RL-LANE-004.
#[test]
fn every_build_plans_the_scalar_plan() {
    let mut cpso = PlannerConfig::reference(5);
    cpso.strategy = Strategy::Cpso;
    cpso.max_iterations = 3;
    for cfg in [
        PlannerConfig::default_with_seed(1),
        PlannerConfig::default_with_seed(2),
        cpso,
    ] {
        let want = plan::<1, reactionless::batch::Portable>(cfg);
        assert_eq!(plan::<4, ForceBaseline>(cfg), want);
        if Isa::Avx2.available() {
            assert_eq!(plan::<4, ForceAvx2>(cfg), want);
        }
        assert_eq!(plan::<8, Threaded>(cfg), want, "8 lanes on threads");
    }
    let _ = ETA_HAT;
}

/// Planning with 8 lanes on threads ([`Threaded`]) gives the scalar planner's plan under
/// any slicing, and no call spends more than its budget.
/// Verifies RL-LANE-006.
#[test]
fn threaded_planning_gives_the_scalar_plan_under_any_slicing() {
    let cfg = PlannerConfig::default_with_seed(3);
    let want = plan::<1, reactionless::batch::Portable>(cfg);
    for budget in [1, 7, 1000, u32::MAX] {
        assert_eq!(
            plan_sliced::<8, Threaded>(cfg, budget),
            want,
            "budget {budget}"
        );
    }
}
