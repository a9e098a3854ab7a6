//! The C-PSO planner: swarm rules on hand-made cases, determinism and budget slicing bit
//! for bit, the reference task for seeds 1..10, refinement, execution.
//!
//! Requirements: RL-MODEL, RL-PSO, RL-PLAN, RL-REF, RL-EXEC, RL-GOLD, RL-CORE, RL-ROB
//! (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::panic,
    missing_docs
)]

mod common;
use common::*;
use reactionless::random::Stream;
use reactionless::{
    Candidate, Cost, Cpso, Error, Evaluation, Event, Next, Optimizer, Param, Plan, Planner,
    PlannerConfig, RefineStop, Sample, Setpoints, Status, Stop, Swarm, Task, TruthModel,
};

type RefPlanner = Planner<7, 4, 64>;

fn run(planner: &mut RefPlanner, budget: u32) -> (Status<7, 4>, u64) {
    let mut calls = 0u64;
    loop {
        calls += 1;
        match planner.step(budget, &mut ()).unwrap() {
            Status::Running(_) => {}
            s => return (s, calls),
        }
    }
}

fn plan_of(s: &Status<7, 4>) -> &Plan<7, 4> {
    match s {
        Status::Finished(p) => p,
        Status::Running(_) => panic!("still running"),
    }
}

fn bits(p: &Plan<7, 4>) -> Vec<u64> {
    let o = &p.outcome;
    p.eta
        .iter()
        .flatten()
        .flatten()
        .chain(&o.q_final)
        .chain(&o.joint_min)
        .chain(&o.joint_max)
        .chain(&o.end_pose.position)
        .chain(&o.end_pose.quat_wxyz)
        .chain(&[o.f, o.phi, o.g, p.search_f])
        .map(|v| v.to_bits())
        .chain([
            u64::from(p.iterations),
            u64::from(p.rollouts),
            u64::from(p.stagnation_events),
        ])
        .collect()
}

// --- swarm rules on hand-made cases -------------------------------------------------

const FEAS: fn(f64) -> Cost = |f| Cost { phi: 0.0, f };
const INFEAS: fn(f64, f64) -> Cost = |phi, f| Cost { phi, f };

/// Constraint domination: feasible first, then smaller Φ, then smaller f; ties and failures
/// never dominate.
/// Verifies RL-PSO-003.
#[test]
fn constraint_domination_rules() {
    assert!(
        FEAS(10.0).dominates(&INFEAS(1e-9, 0.0)),
        "feasible beats infeasible"
    );
    assert!(!INFEAS(1e-9, 0.0).dominates(&FEAS(10.0)));
    assert!(FEAS(0.1).dominates(&FEAS(0.2)), "two feasible: smaller f");
    assert!(!FEAS(0.2).dominates(&FEAS(0.1)));
    assert!(
        INFEAS(0.1, 9.0).dominates(&INFEAS(0.2, 0.0)),
        "two infeasible: smaller Φ"
    );
    assert!(
        INFEAS(0.1, 1.0).dominates(&INFEAS(0.1, 2.0)),
        "equal Φ: smaller f"
    );
    assert!(!FEAS(0.1).dominates(&FEAS(0.1)), "ties do not dominate");
    assert!(INFEAS(5.0, 5.0).dominates(&Cost::FAILED));
    assert!(!Cost::FAILED.dominates(&Cost::FAILED));
}

fn small_swarm(particles: u32) -> (Swarm<2, 8>, Stream) {
    let mut stream = Stream::new(3);
    let mut cfg = PlannerConfig::reference(1);
    cfg.particles = particles;
    cfg.stagnation.window = 3;
    (Swarm::new(&cfg, &mut stream).unwrap(), stream)
}

/// gbest is the best feasible pbest, else the least violating, lowest index among equals;
/// pbest moves only on domination.
/// Verifies RL-PSO-004.
#[test]
fn gbest_is_the_best_feasible_pbest_else_the_least_violating() {
    let (mut s, _) = small_swarm(4);
    for (j, c) in [
        INFEAS(0.3, 0.0),
        INFEAS(0.1, 5.0),
        INFEAS(0.2, 0.0),
        INFEAS(0.1, 4.0),
    ]
    .into_iter()
    .enumerate()
    {
        s.record(j, c);
    }
    s.end_generation();
    assert_eq!(s.gbest_index(), 3, "least violating, then smaller f");
    s.record(0, FEAS(0.9));
    s.end_generation();
    assert_eq!(s.gbest_index(), 0, "any feasible beats every infeasible");
    s.record(2, FEAS(0.5));
    s.record(1, FEAS(0.5));
    s.end_generation();
    assert_eq!(s.gbest_index(), 1, "lowest index among equals");
    // pbest only moves on domination.
    let before = s.particle(1).unwrap().best;
    s.record(1, INFEAS(0.01, 0.0));
    assert_eq!(s.particle(1).unwrap().best, before);
    assert_eq!(s.particle(1).unwrap().best_cost, FEAS(0.5));
}

/// A flat window fires the alarm, and ⌊T/2⌋ particles restart near gbest at rest; steady
/// improvement never fires it.
/// Verifies RL-PSO-005, RL-PSO-006.
#[test]
fn stagnation_alarm_fires_on_a_flat_history_and_splits_half_and_half() {
    let (mut s, mut stream) = small_swarm(7);
    for j in 0..7 {
        s.record(j, FEAS(1.0 + j as f64));
    }
    // window = 3: generations 0..=2 fill it, generation 3 has no improvement → alarm.
    let alarms: Vec<bool> = (0..4).map(|_| s.end_generation()).collect();
    assert_eq!(alarms, [false, false, false, true]);
    assert_eq!(s.stagnation_events(), 1);
    // Give everyone a velocity, then move: S1 restarts with zero velocity near gbest.
    s.advance(1, &mut stream);
    let (g, _) = s.gbest();
    let mut s1 = 0;
    for j in 0..7 {
        let p = s.particle(j).unwrap();
        if p.velocity == [[0.0; 2]; 2] {
            s1 += 1;
            for (x, gb) in p.position.iter().flatten().zip(g.iter().flatten()) {
                assert!(
                    *x >= *gb && *x < *gb + 0.5,
                    "S1 restarts in gbest + ε₁·U(0,1)"
                );
            }
        }
    }
    assert_eq!(s1, 3, "⌊7/2⌋ particles in S1, the rest in S2");
    // A steady improvement never fires.
    let (mut s, _) = small_swarm(2);
    for k in 0..20 {
        s.record(0, FEAS(1.0 / (k as f64 + 1.0)));
        assert!(!s.end_generation());
    }
}

/// The initial swarm: T particles at B·(2u − 1) per component, u drawn from the task's
/// stream particle by particle (a₁, b₁, …, a_K, b_K), hence uniform in [−B, B]^{2K}, at
/// rest, each its own pbest; nothing else is drawn.
/// Verifies RL-PSO-001, RL-PSO-010.
#[test]
fn the_swarm_starts_uniform_in_the_eta_box_at_rest() {
    // The reference settings through the planner: T = 40, B = 5, 2K = 8.
    let p = RefPlanner::new(paper_task(), PlannerConfig::reference(4)).unwrap();
    let s = p.swarm().unwrap();
    assert_eq!(s.count(), 40);
    assert!(s.particle(40).is_none());
    let mut u = Stream::new(4);
    let mut components = Vec::new();
    for j in 0..40 {
        let part = s.particle(j).unwrap();
        for x in part.position.iter().flatten() {
            let want = 5.0 * (2.0 * u.uniform() - 1.0);
            assert_eq!(x.to_bits(), want.to_bits(), "particle {j}");
            components.push(*x);
        }
        assert_eq!(part.velocity, [[0.0; 2]; 4], "particle {j} starts at rest");
        assert_eq!(part.best, part.position);
    }
    // Uniform over [−5, 5): each unit-wide bin holds its share of the 320 components.
    assert!(components.iter().all(|x| (-5.0..5.0).contains(x)));
    let mut bins = [0u32; 10];
    for x in &components {
        bins[((x + 5.0).floor() as usize).min(9)] += 1;
    }
    assert!(bins.iter().all(|&n| (12..=52).contains(&n)), "{bins:?}");
    let mean = components.iter().sum::<f64>() / components.len() as f64;
    assert!(mean.abs() < 0.6, "mean {mean}");
    // Other T and B, directly on a swarm: exactly T·2K draws, each B·(2u − 1).
    let mut cfg = PlannerConfig::reference(1);
    cfg.particles = 5;
    cfg.eta_bound = 0.25;
    let mut stream = Stream::new(9);
    let swarm: Swarm<2, 8> = Swarm::new(&cfg, &mut stream).unwrap();
    assert_eq!(stream.draws(), 5 * 4);
    let mut u = Stream::new(9);
    for j in 0..5 {
        let part = swarm.particle(j).unwrap();
        for x in part.position.iter().flatten() {
            assert_eq!(x.to_bits(), (0.25 * (2.0 * u.uniform() - 1.0)).to_bits());
        }
        assert_eq!(part.velocity, [[0.0; 2]; 2]);
    }
}

/// Two swarm moves recomputed by hand from the same stream draws (r₁ then r₂ per
/// component, particle by particle): ν ← ω(m)·ν + c₁r₁(pbest − η) + c₂r₂(gbest − η),
/// η ← η + ν (eqs. 20–21), with ω(m) = ω_max − m(ω_max − ω_min)/m_max (eq. 22); and the
/// spec §7 defaults.
/// Verifies RL-PSO-002, RL-PSO-010.
#[test]
fn a_swarm_move_is_eqs_20_to_22() {
    let reference = PlannerConfig::reference(1);
    assert_eq!((reference.c1, reference.c2), (1.49618, 1.49618));
    assert_eq!(reference.inertia_weight(0), 0.9);
    assert!((reference.inertia_weight(200) - 0.4).abs() < 1e-15);
    // c₁ ≠ c₂ so that swapping the cognitive and social terms would show.
    let mut cfg = reference;
    cfg.particles = 4;
    cfg.max_iterations = 10;
    cfg.c1 = 1.2;
    cfg.c2 = 1.7;
    let (w_max, w_min, m_max) = (0.9, 0.4, 10.0);
    let mut stream = Stream::new(11);
    let mut s: Swarm<2, 8> = Swarm::new(&cfg, &mut stream).unwrap();
    // Generation 0: particle 2 is the best feasible point.
    for (j, c) in [INFEAS(0.3, 1.0), INFEAS(0.2, 1.0), FEAS(0.7), FEAS(0.9)]
        .into_iter()
        .enumerate()
    {
        s.record(j, c);
    }
    assert!(!s.end_generation());
    let later = [FEAS(0.1), INFEAS(0.5, 0.0), FEAS(0.8), FEAS(0.6)];
    for m in 1..=2u32 {
        let before: Vec<_> = (0..4).map(|j| *s.particle(j).unwrap()).collect();
        let (g, _) = s.gbest();
        let w = w_max - f64::from(m) * (w_max - w_min) / m_max;
        let mut hand = stream.clone();
        s.advance(m, &mut stream);
        for (j, b) in before.iter().enumerate() {
            let after = s.particle(j).unwrap();
            let comps = b
                .position
                .iter()
                .flatten()
                .zip(b.velocity.iter().flatten())
                .zip(b.best.iter().flatten())
                .zip(g.iter().flatten());
            let moved = after
                .position
                .iter()
                .flatten()
                .zip(after.velocity.iter().flatten());
            for (c, ((((x, v), pb), gb), (x_new, v_new))) in comps.zip(moved).enumerate() {
                let r1 = hand.uniform();
                let r2 = hand.uniform();
                let v_want = w * v + 1.2 * r1 * (pb - x) + 1.7 * r2 * (gb - x);
                assert_eq!(*v_new, v_want, "move {m}, particle {j}, component {c}: ν");
                assert_eq!(
                    *x_new,
                    x + v_want,
                    "move {m}, particle {j}, component {c}: η"
                );
            }
        }
        assert_eq!(stream, hand, "move {m} draws exactly r₁, r₂ per component");
        // New costs: pbest moves for particles 0 and 3 only, gbest becomes particle 0.
        for (j, c) in later.into_iter().enumerate() {
            s.record(j, c);
        }
        assert!(!s.end_generation());
        assert_eq!(s.gbest_index(), 0);
    }
}

/// With no feasible point anywhere (every joint limit within 1 mrad of the start), the
/// exhausted plan is the least violating of all evaluated rollouts: the same η and
/// outcome as the minimum of Φ (then f) over every C-PSO candidate rolled out to the end.
/// Verifies RL-PSO-008, RL-PSO-009, RL-PLAN-004, RL-PLAN-005.
#[test]
fn exhausted_without_a_feasible_point_reports_the_least_violating() {
    let mut d = reactionless::CHASER7;
    for (j, q) in d.joints.iter_mut().zip(q0()) {
        j.lower = q - 1e-3;
        j.upper = q + 1e-3;
    }
    let robot = reactionless::Robot::new(&d).unwrap();
    let task = Task::<7, 4>::new(robot, q0(), TARGET, *paper_task().motion()).unwrap();
    let mut cfg = PlannerConfig::reference(6);
    cfg.particles = 6;
    cfg.max_iterations = 3;
    let mut p = RefPlanner::new(task.clone(), cfg).unwrap();
    let (s, _) = run(&mut p, u32::MAX);
    let plan = *plan_of(&s);
    // The same C-PSO driven by hand, every candidate rolled out to the end (no cap).
    let mut stream = Stream::new(6);
    let mut cpso: Box<Cpso<4, 64>> = Box::new(Cpso::IDLE);
    cpso.reset(&cfg, &mut stream).unwrap();
    let mut evaluated = Vec::new();
    loop {
        let c: Candidate<4> = Optimizer::<7, 4>::candidate(&*cpso);
        let o = task.rollout_of(&c.eta, &mut ()).unwrap();
        evaluated.push((c.eta, o));
        if let Next::Done(stop) = cpso.absorb(&Evaluation::Finished(o), &mut stream, &mut ()) {
            assert_eq!(stop, Stop::Exhausted);
            break;
        }
    }
    assert_eq!(evaluated.len(), 6 * 4);
    assert!(
        evaluated.iter().all(|(_, o)| o.phi > 0.0),
        "nothing is feasible"
    );
    let (eta, least) = evaluated
        .iter()
        .min_by(|a, b| a.1.phi.total_cmp(&b.1.phi).then(a.1.f.total_cmp(&b.1.f)))
        .unwrap();
    assert_eq!(plan.stop, Stop::Exhausted);
    assert!(!plan.converged());
    assert_eq!(plan.rollouts, 6 * 4);
    assert_eq!(plan.eta, *eta);
    assert_eq!(plan.outcome, *least);
    assert_eq!(task.rollout_of(&plan.eta, &mut ()).unwrap(), plan.outcome);
}

/// m_max = 2 and an unreachable tolerance: exhausted after generation 2 (120 rollouts),
/// with a feasible plan.
/// Verifies RL-PSO-008, RL-PLAN-005.
#[test]
fn m_max_is_honoured() {
    let task = paper_task();
    let mut cfg = PlannerConfig::reference(1);
    cfg.max_iterations = 2;
    cfg.tolerance = 1e-12;
    let mut p = RefPlanner::new(task, cfg).unwrap();
    let (s, _) = run(&mut p, u32::MAX);
    let Status::Finished(plan) = s else {
        panic!("expected exhaustion")
    };
    assert_eq!(plan.stop, Stop::Exhausted);
    assert_eq!(plan.iterations, 2);
    assert_eq!(plan.rollouts, 40 * 3);
    assert_eq!(plan.outcome.phi, 0.0, "the best feasible point is reported");
}

/// Each bad planner setting is a typed error naming the setting.
/// Verifies RL-ROB-007.
#[test]
fn invalid_settings_are_typed_errors() {
    let task = paper_task();
    let bad = |edit: fn(&mut PlannerConfig)| {
        let mut c = PlannerConfig::reference(1);
        edit(&mut c);
        RefPlanner::new(task.clone(), c).unwrap_err()
    };
    assert_eq!(
        bad(|c| c.particles = 0),
        Error::NotPositive(Param::Particles)
    );
    assert_eq!(
        bad(|c| c.particles = 65),
        Error::CapacityExceeded {
            param: Param::Particles,
            requested: 65,
            capacity: 64
        }
    );
    assert_eq!(
        bad(|c| c.max_iterations = 0),
        Error::NotPositive(Param::MaxIterations)
    );
    assert_eq!(
        bad(|c| c.tolerance = 0.0),
        Error::NotPositive(Param::Tolerance)
    );
    assert_eq!(
        bad(|c| c.tolerance = f64::NAN),
        Error::NotFinite(Param::Tolerance)
    );
    assert_eq!(
        bad(|c| c.eta_bound = -1.0),
        Error::NotPositive(Param::EtaBound)
    );
    assert_eq!(bad(|c| c.w_min = 0.95), Error::InertiaWeightsInverted);
    assert_eq!(bad(|c| c.c1 = -0.1), Error::Negative(Param::C1));
    assert_eq!(bad(|c| c.c2 = f64::INFINITY), Error::NotFinite(Param::C2));
    assert_eq!(
        bad(|c| c.stagnation.window = 0),
        Error::NotPositive(Param::StagnationWindow)
    );
    assert_eq!(
        bad(|c| c.stagnation.window = 65),
        Error::CapacityExceeded {
            param: Param::StagnationWindow,
            requested: 65,
            capacity: 64
        }
    );
    assert_eq!(
        bad(|c| {
            c.refine_tolerance = Some(0.0);
            c.refine_max_rollouts = 10;
        }),
        Error::NotPositive(Param::RefineTolerance)
    );
    assert_eq!(
        bad(|c| {
            c.refine_tolerance = Some(1e-6);
            c.refine_max_rollouts = 0;
        }),
        Error::NotPositive(Param::RefineRollouts)
    );
}

// --- determinism --------------------------------------------------------------------

/// The same seed gives a bit-identical plan, another seed another η.
/// Verifies RL-PSO-011.
#[test]
fn same_seed_same_bits_different_seed_different_bits() {
    let plan = |seed| {
        *plan_of(
            &run(
                &mut RefPlanner::new(paper_task(), PlannerConfig::reference(seed)).unwrap(),
                u32::MAX,
            )
            .0,
        )
    };
    let (a, b, c) = (plan(2), plan(2), plan(5));
    assert_eq!(bits(&a), bits(&b));
    assert_ne!(a.eta, c.eta);
}

/// Budgets 1, 7, 1000, 3000 per call plan the unlimited call's bits, refinement included; a
/// finished planner repeats.
/// Verifies RL-PLAN-003, RL-REF-005.
#[test]
fn budget_slicing_gives_identical_bits() {
    let mut cfg = PlannerConfig::reference(2);
    cfg.refine_tolerance = Some(1e-8);
    cfg.refine_max_rollouts = 60;
    let (reference, calls) = run(&mut RefPlanner::new(paper_task(), cfg).unwrap(), u32::MAX);
    assert_eq!(calls, 1);
    let want = bits(plan_of(&reference));
    for budget in [1, 7, 1000, 3000] {
        let mut p = RefPlanner::new(paper_task(), cfg).unwrap();
        let (s, calls) = run(&mut p, budget);
        assert_eq!(bits(plan_of(&s)), want, "budget {budget}");
        assert!(calls > 1, "budget {budget} took {calls} calls");
        // Finished planners keep answering the same.
        assert_eq!(p.step(5, &mut ()).unwrap(), s);
    }
}

// --- the reference task ---------------------------------------------------------------

/// Seeds 1…10 converge, refine to f ≤ 1e-6 with Φ = 0, gbest never worsens and the base
/// turns < 0.01°.
/// Verifies RL-PSO-004, RL-PSO-007, RL-PLAN-005, RL-PLAN-008, RL-REF-001, RL-REF-003, RL-REF-004, RL-GOLD-007.
#[test]
fn reference_task_converges_for_seeds_1_to_10_and_refines_below_1e_6() {
    let mut iterations = Vec::new();
    for seed in 1..=10 {
        let task = paper_task();
        let mut cfg = PlannerConfig::reference(seed);
        cfg.refine_tolerance = Some(1e-6);
        cfg.refine_max_rollouts = 400;
        let mut history = Vec::new();
        let mut observer = |e: &Event| {
            if let Event::Generation { best, .. } = e {
                history.push(best.f);
            }
        };
        let mut p = RefPlanner::new(task.clone(), cfg).unwrap();
        let s = loop {
            match p.step(u32::MAX, &mut observer).unwrap() {
                Status::Running(_) => {}
                s => break s,
            }
        };
        let Status::Finished(plan) = s else {
            panic!("seed {seed} still running: {s:?}")
        };
        assert!(plan.converged(), "seed {seed} did not converge: {plan:?}");
        assert!(plan.iterations <= 200);
        assert!(
            plan.search_f <= 0.05,
            "seed {seed}: C-PSO f {}",
            plan.search_f
        );
        assert_eq!(plan.outcome.phi, 0.0);
        let r = plan.refine.unwrap();
        assert_eq!(r.stop, RefineStop::Reached, "seed {seed}");
        assert!(
            plan.outcome.f <= 1e-6,
            "seed {seed}: refined f {}",
            plan.outcome.f
        );
        assert!(plan.outcome.max_abs_qd <= task.robot().qd_max());
        assert!(
            history.windows(2).all(|w| w[1] <= w[0]),
            "gbest never gets worse"
        );
        // The truth model: the base barely moves.
        let mut truth = TruthModel::new(&task, 10);
        let again = task.rollout_of(&plan.eta, &mut truth).unwrap();
        assert_eq!(again, plan.outcome, "the plan's outcome is reproducible");
        let deg = truth.max_angle().to_degrees();
        assert!(deg < 0.01, "seed {seed}: base disturbance {deg}°");
        iterations.push(plan.iterations);
    }
    iterations.sort_unstable();
    println!("iterations for seeds 1..10: {iterations:?}");
}

// --- execution ----------------------------------------------------------------------

/// A plan's setpoint stream is its rollout bit for bit and ends with the plan's outcome.
/// Verifies RL-EXEC-001, RL-EXEC-002.
#[test]
fn streamed_setpoints_are_the_evaluated_rollout_bit_for_bit() {
    let task = paper_task();
    let (s, _) = run(
        &mut RefPlanner::new(task.clone(), PlannerConfig::reference(2)).unwrap(),
        u32::MAX,
    );
    let plan = plan_of(&s);
    // Reference stream: a plain rollout with a sink.
    let mut reference = Vec::new();
    task.rollout_of(&plan.eta, &mut |s: &Sample<7>| reference.push(*s))
        .unwrap();
    let mut sp = Setpoints::of(&task, &plan.eta).unwrap();
    let mut k = 0;
    while let Some(s) = sp.next(&task).unwrap() {
        assert_eq!(s, reference[k], "setpoint {k}");
        k += 1;
    }
    assert_eq!(k, reference.len());
    assert_eq!(
        sp.outcome().unwrap(),
        &plan.outcome,
        "the flown trajectory ends where the plan said"
    );
    assert_eq!(sp.next(&task).unwrap(), None);
}

/// A whole plan makes no heap allocation.
/// Verifies RL-CORE-002.
#[test]
fn planning_never_allocates() {
    let task = paper_task();
    let mut p = RefPlanner::new(task, PlannerConfig::reference(2)).unwrap();
    let mut done = false;
    let info = allocation_counter::measure(|| {
        while let Status::Running(_) = p.step(50_000, &mut ()).unwrap() {}
        done = true;
    });
    assert!(done);
    assert_eq!(info.count_total, 0);
}

/// A random 6-joint robot with capacity P = 32 plans to convergence (f ≤ 0.05, Φ = 0).
/// Verifies RL-PLAN-006.
#[test]
fn a_task_of_another_robot_plans_too() {
    // Generic over N: the 6-DOF random robot of the physics tests, target from a rollout.
    let mut rng = rng(42);
    let d = random_robot::<6>(&mut rng);
    let q0 = random_q(&mut rng, &d);
    let robot = reactionless::Robot::new(&d).unwrap();
    let motion = reactionless::Motion::new(10.0, 0.01, 1).unwrap();
    let probe = Task::<6, 3>::new(robot.clone(), q0, TARGET, motion).unwrap();
    let made = probe
        .rollout(&[[1.0, -2.0], [0.5, 3.0], [-2.0, 1.0]], &mut ())
        .unwrap();
    let task = Task::<6, 3>::new(robot, q0, made.end_pose, motion).unwrap();
    let mut cfg = PlannerConfig::reference(1);
    cfg.particles = 30;
    let mut p: Planner<6, 3, 32> = Planner::new(task, cfg).unwrap();
    let s = loop {
        match p.step(u32::MAX, &mut ()).unwrap() {
            Status::Running(_) => {}
            s => break s,
        }
    };
    match s {
        Status::Finished(plan) => {
            assert!(plan.converged() && plan.outcome.f <= 0.05 && plan.outcome.phi == 0.0)
        }
        other => panic!("{other:?}"),
    }
}

/// Rejected candidates are failed particles (Φ = f = ∞), progress is never NaN, and the
/// final error sticks.
/// Verifies RL-PSO-012, RL-PLAN-002, RL-PLAN-008, RL-ROB-004.
#[test]
fn failed_rollouts_are_infeasible_particles_with_a_defined_cost() {
    // Every candidate's η is so large that g overflows: each rollout is rejected
    // (EtaTooLarge), the particle gets Φ = f = ∞, progress stays finite-or-∞ (never NaN),
    // and with nothing ever evaluated the planner ends with the typed error.
    let mut cfg = PlannerConfig::reference(3);
    cfg.particles = 6;
    cfg.max_iterations = 2;
    cfg.eta_bound = 1e307;
    let mut p = RefPlanner::new(paper_task(), cfg).unwrap();
    let mut last = None;
    for _ in 0..1000 {
        match p.step(1, &mut ()) {
            Ok(Status::Running(r)) => {
                assert!(!r.best.f.is_nan() && !r.best.phi.is_nan());
                assert_eq!(r.best, Cost::FAILED);
            }
            Ok(s) => panic!("cannot succeed: {s:?}"),
            Err(e) => {
                last = Some(e);
                break;
            }
        }
    }
    assert_eq!(last, Some(Error::EtaTooLarge));
    assert_eq!(
        p.step(10, &mut ()),
        Err(Error::EtaTooLarge),
        "the failure is sticky"
    );
    assert_eq!(
        p.swarm().unwrap().particle(0).unwrap().best_cost,
        Cost::FAILED
    );
}

/// The task constructor names each bad start and target; a quaternion within 1e-6 of unit
/// is normalised.
/// Verifies RL-MODEL-005, RL-CORE-007, RL-ROB-002.
#[test]
fn task_constructor_names_every_bad_input() {
    use reactionless::{Motion, Pose, Robot, Task};
    let robot = || Robot::new(&reactionless::CHASER7).unwrap();
    let m = Motion::new(1.0, 0.01, 1).unwrap();
    let mut q = q0();
    q[3] = 3.0;
    assert_eq!(
        Task::<7, 4>::new(robot(), q, TARGET, m).unwrap_err(),
        Error::StartOutsideLimits(4)
    );
    let mut q = q0();
    q[6] = f64::NAN;
    assert_eq!(
        Task::<7, 4>::new(robot(), q, TARGET, m).unwrap_err(),
        Error::NotFinite(Param::Start(7))
    );
    let zero = Pose {
        quat_wxyz: [0.0; 4],
        ..TARGET
    };
    assert_eq!(
        Task::<7, 4>::new(robot(), q0(), zero, m).unwrap_err(),
        Error::QuaternionNotUnit {
            tolerance: reactionless::UNIT_TOLERANCE
        }
    );
    let nan = Pose {
        position: [0.0, f64::NAN, 0.0],
        ..TARGET
    };
    assert_eq!(
        Task::<7, 4>::new(robot(), q0(), nan, m).unwrap_err(),
        Error::NotFinite(Param::TargetPosition)
    );
    // A quaternion within 1e-6 of unit length is accepted and normalised.
    let near = Pose {
        quat_wxyz: TARGET.quat_wxyz.map(|v| v * (1.0 + 5e-7)),
        ..TARGET
    };
    let t = Task::<7, 4>::new(robot(), q0(), near, m).unwrap();
    let n: f64 = t.target().quat_wxyz.iter().map(|v| v * v).sum();
    assert!((n - 1.0).abs() < 1e-15);
}

/// An idle or failed-reset planner returns its error from `step`; a reset plans exactly as
/// a new planner.
/// Verifies RL-PLAN-007, RL-ROB-008.
#[test]
fn an_idle_planner_refuses_to_run() {
    let mut p: Box<RefPlanner> = Box::new(reactionless::Planner::IDLE);
    assert_eq!(p.step(100, &mut ()), Err(Error::NotInitialized));
    // A failed reset leaves it refusing, with that error.
    let mut bad = PlannerConfig::reference(1);
    bad.particles = 0;
    assert_eq!(
        p.reset(paper_task(), bad),
        Err(Error::NotPositive(Param::Particles))
    );
    assert_eq!(
        p.step(100, &mut ()),
        Err(Error::NotPositive(Param::Particles))
    );
    // And a good reset makes it plan exactly as a new planner.
    p.reset(paper_task(), PlannerConfig::reference(2)).unwrap();
    let a = run(&mut p, u32::MAX).0;
    let b = run(
        &mut RefPlanner::new(paper_task(), PlannerConfig::reference(2)).unwrap(),
        u32::MAX,
    )
    .0;
    assert_eq!(bits(plan_of(&a)), bits(plan_of(&b)));
}
