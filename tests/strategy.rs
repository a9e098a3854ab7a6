//! The planner's strategies (issue #11): the multistart default and C-PSO side by side,
//! refinement against the truth model, the one total budget, and what "converged" means.
//! Requirements: RL-PLAN, RL-MS (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

mod common;
use common::*;
use proptest::prelude::*;
use reactionless::{
    Motion, Plan, Planner, PlannerConfig, Pose, RefineAgainst, RefineStop, Robot, Stop, Strategy,
    Task, TruthModel,
};

fn finish<const N: usize, const K: usize, const P: usize>(
    p: &mut Planner<N, K, P>,
    budget: u32,
) -> Plan<N, K> {
    for _ in 0..10_000_000u32 {
        if let reactionless::Status::Finished(plan) = p.step(budget, &mut ()).unwrap() {
            return plan;
        }
    }
    panic!("the planner did not finish");
}

fn multistart(seed: u64) -> PlannerConfig {
    PlannerConfig::default_with_seed(seed)
}

/// The default strategy is the multistart; the reference task converges for seeds 1..10
/// within 300 rollouts, and every converged plan is its η's fresh rollout.
/// Verifies RL-PLAN-009, RL-MS-001, RL-MS-003.
#[test]
fn the_default_multistart_converges_on_the_reference_task() {
    assert_eq!(PlannerConfig::default().strategy, Strategy::Multistart);
    let task = paper_task();
    let mut rollouts = Vec::new();
    for seed in 1..=10 {
        let mut p: Box<Planner<7, 4, 64>> =
            Box::new(Planner::new(task.clone(), multistart(seed)).unwrap());
        let plan = finish(&mut p, u32::MAX);
        assert_eq!(plan.stop, Stop::Converged, "seed {seed}");
        assert_eq!(plan.strategy, Strategy::Multistart);
        let again = task.rollout_of(&plan.eta, &mut ()).unwrap();
        assert_eq!(again, plan.outcome);
        assert!(again.f <= 0.05 && again.phi == 0.0);
        assert_eq!(plan.first_hit, Some(plan.rollouts));
        rollouts.push(plan.rollouts);
    }
    rollouts.sort_unstable();
    assert!(rollouts[9] <= 300, "{rollouts:?}");
}

/// Budgets 1, 7, 1000 and unlimited per call give the same bits, for the multistart with
/// its planner-model refinement and for refinement against the truth model (whose
/// truth sub-steps are budget units too).
/// Verifies RL-PLAN-002, RL-MS-002, RL-REF-006.
#[test]
fn slicing_gives_the_same_bits_for_every_strategy() {
    let task = paper_task();
    let mut truth = PlannerConfig::reference(3);
    truth.refine_tolerance = Some(1e-9);
    truth.refine_against = RefineAgainst::Truth;
    let mut ms = multistart(4);
    ms.refine_tolerance = Some(1e-8);
    for config in [ms, truth] {
        let mut whole: Box<Planner<7, 4, 64>> =
            Box::new(Planner::new(task.clone(), config).unwrap());
        let want = finish(&mut whole, u32::MAX);
        for budget in [1, 7, 1000] {
            let mut p: Box<Planner<7, 4, 64>> =
                Box::new(Planner::new(task.clone(), config).unwrap());
            let before = p.spent();
            let got = finish(&mut p, budget);
            assert_eq!(got, want, "budget {budget}, {:?}", config.strategy);
            assert!(p.spent() > before);
        }
    }
}

/// Refinement against the truth model (spec §11) drives truth_f below 1e-9 on the
/// reference task: checked with an independent truth-model pass over a fresh rollout.
/// Verifies RL-REF-006.
#[test]
fn refinement_against_the_truth_reaches_1e_9() {
    let task = paper_task();
    for strategy in [Strategy::Multistart, Strategy::Cpso] {
        let mut config = multistart(1);
        config.strategy = strategy;
        config.refine_tolerance = Some(1e-9);
        config.refine_against = RefineAgainst::Truth;
        let mut p: Box<Planner<7, 4, 64>> = Box::new(Planner::new(task.clone(), config).unwrap());
        let plan = finish(&mut p, u32::MAX);
        assert!(plan.converged());
        let r = plan.refine.unwrap();
        assert_eq!(r.stop, RefineStop::Reached, "{strategy:?}: {r:?}");
        let mut truth = TruthModel::new(&task, 10);
        let again = task.rollout_of(&plan.eta, &mut truth).unwrap();
        assert_eq!(again, plan.outcome);
        let truth_f = truth.end_pose().unwrap().error_to(task.target()).norm();
        assert!(truth_f <= 1e-9, "{strategy:?}: truth_f {truth_f}");
        assert_eq!(r.truth_f.unwrap().to_bits(), truth_f.to_bits());
        // The planner-model f is the drift the truth refinement took into account.
        assert!(plan.outcome.f > 1e-6);
    }
}

/// A short task whose target is out of reach: a whole rollout takes 100 steps.
fn unreachable_task() -> Task<7, 4> {
    let m = Motion::new(1.0, 0.01, 1).unwrap();
    let far = Pose {
        position: [10.0, -8.0, 6.0],
        ..TARGET
    };
    Task::new(Robot::new(&reactionless::CHASER7).unwrap(), q0(), far, m).unwrap()
}

/// An unreachable target ends `Exhausted` within the budget, never later: with the
/// default budget (8,040) and with a small one, for both strategies.
/// Verifies RL-PLAN-009, RL-MS-002.
#[test]
fn an_unreachable_target_ends_exhausted_within_the_budget() {
    let task = unreachable_task();
    for strategy in [Strategy::Multistart, Strategy::Cpso] {
        for budget in [8040, 37] {
            let mut config = multistart(2);
            config.strategy = strategy;
            config.max_rollouts = budget;
            config.refine_tolerance = Some(1e-9);
            let mut p: Box<Planner<7, 4, 64>> =
                Box::new(Planner::new(task.clone(), config).unwrap());
            let plan = finish(&mut p, 5000);
            assert_eq!(plan.stop, Stop::Exhausted, "{strategy:?} {budget}");
            assert!(
                plan.rollouts <= budget,
                "{strategy:?}: {} > {budget}",
                plan.rollouts
            );
            if strategy == Strategy::Multistart {
                assert_eq!(plan.rollouts, budget);
            }
            assert!(plan.outcome.f > 1.0);
        }
    }
}

/// Planning with the multistart allocates nothing.
/// Verifies RL-CORE-002.
#[test]
fn the_multistart_never_allocates() {
    let task = paper_task();
    let mut p: Box<Planner<7, 4, 64>> = Box::new(Planner::new(task, multistart(5)).unwrap());
    let mut plan = None;
    let info = allocation_counter::measure(|| plan = Some(finish(&mut p, 50_000)));
    assert!(plan.unwrap().converged());
    assert_eq!(info.count_total, 0);
}

/// A reachable task for a random 6-joint robot: its target is a rollout's planner-model
/// end pose (exactly reachable in the planner model).
fn random_task(seed: u64) -> Task<6, 3> {
    let mut rng = rng(seed);
    let d = random_robot::<6>(&mut rng);
    let q0 = random_q(&mut rng, &d);
    let robot = Robot::new(&d).unwrap();
    let motion = Motion::new(3.0, 0.01, 1).unwrap();
    let probe = Task::<6, 3>::new(robot.clone(), q0, TARGET, motion).unwrap();
    let s = seed as f64;
    let eta = [[1.0 + s.sin(), -2.0], [0.5, 3.0 * s.cos()], [-2.0, 1.0]];
    let target = probe
        .rollout(&eta, &mut ())
        .map(|o| o.end_pose)
        .unwrap_or(TARGET);
    Task::new(robot, q0, target, motion).unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 12, ..ProptestConfig::default() })]

    /// No plan is reported converged unless a fresh rollout of its η gives f within the
    /// tolerance (the refinement's, when it says it reached it) and Φ = 0; random robots,
    /// tasks, seeds and both strategies.
    /// Verifies RL-PLAN-010, RL-MS-003.
    #[test]
    fn converged_means_a_fresh_rollout_meets_the_tolerance(
        task_seed in 0u64..1000,
        seed in 0u64..1000,
        cpso in any::<bool>(),
        refine in any::<bool>(),
    ) {
        let task = random_task(task_seed);
        let mut config = multistart(seed);
        if cpso {
            config.strategy = Strategy::Cpso;
            config.particles = 16;
            config.max_iterations = 20;
        }
        config.max_rollouts = 600;
        if refine {
            config.refine_tolerance = Some(1e-8);
        }
        let mut p: Box<Planner<6, 3, 16>> = Box::new(Planner::new(task.clone(), config).unwrap());
        let plan = finish(&mut p, 777);
        prop_assert!(plan.rollouts <= 600);
        let again = task.rollout_of(&plan.eta, &mut ()).unwrap();
        prop_assert_eq!(again, plan.outcome);
        if plan.converged() {
            prop_assert!(again.phi == 0.0 && again.f <= config.tolerance);
        }
        if let Some(r) = plan.refine {
            if r.stop == RefineStop::Reached {
                prop_assert!(again.f <= 1e-8);
            }
        }
    }
}
