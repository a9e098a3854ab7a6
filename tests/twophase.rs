//! Two-phase plans (spec §15, issue #30) on generic targets of the reference robot: the end
//! pose at a configuration 10° per joint from the start, which no rollout from the start
//! reaches (the single-phase planner misses it by decimetres).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::indexing_slicing)]

mod common;

use reactionless::reference::paper_task;
use reactionless::twophase::{TwoPhaseConfig, TwoPhaseStop, plan};
use reactionless::{IDENTITY_WXYZ, Pose, Preshape, Task, TruthModel};

/// The reference task with its target moved to the end pose at `q0 + offsets`.
fn joint_space_task(offsets_deg: [f64; 7]) -> Task<7, 4> {
    let base = paper_task().unwrap();
    let mut q = *base.start();
    for (q, d) in q.iter_mut().zip(offsets_deg) {
        *q += d.to_radians();
    }
    let target = base.end_pose(&q, IDENTITY_WXYZ);
    Task::new(base.robot().clone(), *base.start(), target, *base.motion()).unwrap()
}

const OFFSETS: [f64; 7] = [10.0, -10.0, 10.0, -10.0, 10.0, 10.0, -10.0];

/// A generic target is reached to f ≤ 1e-6 (planner model) with phase 2 reactionless on
/// the truth model (< 0.01°), phase 1 within the rate, acceleration, duration and wheel
/// bounds on its written samples, the standoff kept at q_s, and the whole thing repeated
/// bit for bit from the same seed.
/// Verifies RL-TWO-001, RL-TWO-002, RL-TWO-003.
#[test]
fn a_joint_space_target_is_reached_in_two_phases() {
    let task = joint_space_task(OFFSETS);
    let config = TwoPhaseConfig::reference();
    let p = plan(&task, &config, 1).unwrap();
    assert_eq!(p.stop, TwoPhaseStop::Converged, "{p:?}");
    assert!(p.rollouts <= 500, "{} rollouts", p.rollouts);
    let o = p.outcome.unwrap();
    assert!(
        o.f <= 1e-6 && o.phi == 0.0,
        "f = {:e}, phi = {}",
        o.f,
        o.phi
    );

    // Phase 2 from q_s, flown on the truth model: the base stays put.
    let mut phase2 = task.clone();
    phase2.move_start(&p.q_s).unwrap();
    let mut truth = TruthModel::new(&phase2, 10);
    let again = phase2.rollout(&p.eta, &mut truth).unwrap();
    assert_eq!(again, o, "phase 2 replays bit for bit");
    let deg = truth.max_angle().to_degrees();
    assert!(deg < 0.01, "phase-2 base disturbance {deg}°");
    assert_eq!(
        truth.max_angle(),
        p.base_disturbance,
        "the plan reports what it flew"
    );

    // Phase 1: the written samples keep the limits; the demand is within the bounds.
    let robot = task.robot();
    let (qd, qdd, dt) = (robot.qd_max(), config.qdd_max, task.motion().dt());
    let s = p.preshape.steps();
    assert_eq!(p.preshape.sample(0).0, *task.start());
    assert_eq!(p.preshape.sample(s).0, p.q_s);
    for j in 1..s {
        let (a, b, c) = (
            p.preshape.sample(j - 1).0,
            p.preshape.sample(j).0,
            p.preshape.sample(j + 1).0,
        );
        for r in 0..7 {
            assert!((c[r] - b[r]).abs() / dt <= qd);
            assert!((c[r] - 2.0 * b[r] + a[r]).abs() / (dt * dt) <= qdd * (1.0 + 1e-9));
            assert!(b[r] >= robot.lower()[r] && b[r] <= robot.upper()[r]);
        }
    }
    assert!(p.preshape.duration() <= config.max_duration);
    assert!(p.demand.momentum_nms <= config.max_momentum);
    assert!(p.demand.torque_nm <= config.max_torque);
    assert_eq!(p.demand, p.preshape.demand(robot));

    // The standoff: phase 2 is a real final approach.
    let start = phase2.start_pose();
    let e = start.error_to(task.target());
    let dist = e.position.iter().map(|v| v * v).sum::<f64>().sqrt();
    let angle = e.rotation.iter().map(|v| v * v).sum::<f64>().sqrt();
    assert!(
        dist >= config.standoff_m || angle >= config.standoff_rad,
        "{dist} m {angle} rad"
    );

    assert_eq!(plan(&task, &config, 1).unwrap(), p, "same seed, same bits");
}

/// Phase 1's base: the CoM does not move, so the base shift is the CoM offset change; the
/// arm's momentum that the wheels hold vanishes at both rests.
#[test]
fn phase_one_conserves_the_centre_of_mass() {
    let task = joint_space_task(OFFSETS);
    let robot = task.robot();
    let q0 = *task.start();
    let mut qs = q0;
    qs[1] += 0.3;
    let p = Preshape::new(&q0, &qs, robot.qd_max(), 0.05, 0.01).unwrap();
    let d = p.demand(robot);
    // The end effector at q_s, placed with the base shifted, equals the task's own
    // CoM-conserving end pose at q_s.
    let f = reactionless::Frames::new(robot, &qs);
    let direct = Pose::from_parts(
        &(f.ee_position + nalgebra::Vector3::from(d.base_shift_m)),
        &f.ee_rotation,
    );
    let conserved = task.end_pose(&qs, IDENTITY_WXYZ);
    for i in 0..3 {
        assert!((direct.position[i] - conserved.position[i]).abs() < 1e-12);
    }
}

/// A target 10 m away ends at once, before any rollout, with a status that says so.
/// Verifies RL-TWO-004.
#[test]
fn a_target_beyond_reach_ends_early() {
    let base = paper_task().unwrap();
    let target = Pose {
        position: [12.0, 0.0, 0.0],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let task: Task<7, 4> =
        Task::new(base.robot().clone(), *base.start(), target, *base.motion()).unwrap();
    let p = plan(&task, &TwoPhaseConfig::reference(), 1).unwrap();
    assert_eq!(p.stop, TwoPhaseStop::BeyondReach);
    assert_eq!(p.rollouts, 0);
    assert!(p.reach_f > 1.0);
    assert!(!p.converged());
}

/// Wheels too weak for any phase 1 within the longest duration: refused, never converged.
/// Verifies RL-TWO-004.
#[test]
fn phase_one_beyond_the_wheels_is_refused() {
    let task = joint_space_task(OFFSETS);
    let config = TwoPhaseConfig {
        max_torque: 1e-4,
        max_rollouts: 400,
        ..TwoPhaseConfig::reference()
    };
    let p = plan(&task, &config, 1).unwrap();
    assert_eq!(p.stop, TwoPhaseStop::PreshapeBounds, "{p:?}");
    assert!(!p.converged());
    assert!(p.rollouts <= 400 + 1);
}

#[test]
fn bad_settings_are_typed_errors() {
    let task = joint_space_task(OFFSETS);
    let config = TwoPhaseConfig {
        standoff_m: -1.0,
        ..TwoPhaseConfig::reference()
    };
    assert_eq!(
        plan(&task, &config, 1).map(|p| p.stop),
        Err(reactionless::Error::Negative(
            reactionless::Param::StandoffDistance
        ))
    );
}

/// The search stepped in slices of any size (1 unit per call, 7, 1,000) gives the bits of
/// one unlimited call, for a plan that converges, one beyond reach, one refused on the
/// wheels and one whose budget runs out; each call does at most its budget; the stages
/// come in order and the rollouts never pass the budget by more than two.
/// Verifies RL-TWO-006.
#[test]
fn any_slicing_gives_the_bits_of_one_call() {
    use reactionless::twophase::{TwoPhaseSearch, TwoPhaseStage, TwoPhaseStatus};
    let near = joint_space_task(OFFSETS);
    let base = paper_task().unwrap();
    let far: Task<7, 4> = Task::new(
        base.robot().clone(),
        *base.start(),
        Pose {
            position: [12.0, 0.0, 0.0],
            quat_wxyz: [1.0, 0.0, 0.0, 0.0],
        },
        *base.motion(),
    )
    .unwrap();
    let reference = TwoPhaseConfig::reference();
    let cases = [
        (&near, reference, TwoPhaseStop::Converged),
        (&far, reference, TwoPhaseStop::BeyondReach),
        (
            &near,
            TwoPhaseConfig {
                max_torque: 1e-4,
                max_rollouts: 400,
                ..reference
            },
            TwoPhaseStop::PreshapeBounds,
        ),
        (
            &near,
            TwoPhaseConfig {
                max_rollouts: 30,
                ..reference
            },
            TwoPhaseStop::Exhausted,
        ),
    ];
    let mut search = Box::new(TwoPhaseSearch::<7, 4>::IDLE);
    for (task, config, stop) in cases {
        let whole = plan(task, &config, 1).unwrap();
        assert_eq!(whole.stop, stop, "{whole:?}");
        for budget in [1u32, 7, 1000] {
            search.reset(task, &config, 1).unwrap();
            let mut stages = vec![search.stage()];
            let sliced = loop {
                let before = search.spent();
                let status = search.step(budget).unwrap();
                assert!(search.spent() - before <= u64::from(budget));
                assert!(search.rollouts() <= config.max_rollouts + 2);
                if stages.last() != Some(&search.stage()) {
                    stages.push(search.stage());
                }
                if let TwoPhaseStatus::Finished(p) = status {
                    break p;
                }
            };
            assert_eq!(
                format!("{sliced:?}"),
                format!("{whole:?}"),
                "{stop:?}, budget {budget}: the same bits"
            );
            let mut order = stages.clone();
            order.dedup();
            assert!(
                order.first() == Some(&TwoPhaseStage::Reach)
                    && order.last() == Some(&TwoPhaseStage::Done),
                "{stages:?}"
            );
            assert!(
                order.windows(2).all(|w| w[0] != TwoPhaseStage::Done),
                "{stages:?}"
            );
            // Finished is final and free.
            let spent = search.spent();
            let again = search.step(5).unwrap();
            assert_eq!(
                format!("{again:?}"),
                format!("{:?}", TwoPhaseStatus::Finished(sliced)),
                "{stop:?}"
            );
            assert_eq!(search.spent(), spent);
        }
    }
}

/// A search with no task, or whose settings were refused, says so on every call.
/// Verifies RL-TWO-006.
#[test]
fn an_idle_search_is_a_typed_error() {
    use reactionless::twophase::TwoPhaseSearch;
    let mut search = Box::new(TwoPhaseSearch::<7, 4>::IDLE);
    assert_eq!(search.step(10), Err(reactionless::Error::NotInitialized));
    let task = joint_space_task(OFFSETS);
    let bad = TwoPhaseConfig {
        max_rollouts: 0,
        ..TwoPhaseConfig::reference()
    };
    assert!(search.reset(&task, &bad, 1).is_err());
    assert_eq!(search.step(10), Err(reactionless::Error::NotInitialized));
}

/// A robot beyond the search's fixed capacity (13 joints: 13 + 2·10 unknowns, 21
/// residuals) is refused with a typed error naming the joint count, not planned on a
/// truncated state.
/// Verifies RL-TWO-006.
#[test]
fn a_robot_beyond_capacity_is_a_typed_error() {
    use reactionless::twophase::{MAX_JOINTS, TwoPhaseSearch};
    use reactionless::{Error, Motion, Param, Robot};
    let mut rng = common::rng(13);
    let desc = common::random_robot::<13>(&mut rng);
    let q0 = common::random_q(&mut rng, &desc);
    let robot = Robot::new(&desc).unwrap();
    let task: Task<13, 10> = {
        let target = Task::<13, 10>::new(
            robot.clone(),
            q0,
            Pose {
                position: [1.0, 0.0, 0.0],
                quat_wxyz: IDENTITY_WXYZ,
            },
            Motion::new(30.0, 0.01, 1).unwrap(),
        )
        .unwrap()
        .end_pose(&q0, IDENTITY_WXYZ);
        Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1).unwrap()).unwrap()
    };
    let want = Err(Error::CapacityExceeded {
        param: Param::Joints,
        requested: 13,
        capacity: MAX_JOINTS as u32,
    });
    assert_eq!(
        plan(&task, &TwoPhaseConfig::reference(), 1).map(|_| ()),
        want
    );
    let mut search = Box::new(TwoPhaseSearch::<13, 10>::IDLE);
    assert_eq!(search.reset(&task, &TwoPhaseConfig::reference(), 1), want);
    assert_eq!(search.step(10).map(|_| ()), Err(Error::NotInitialized));
}

/// Against the truth model (`[planner] refine_against = "truth"`), a start that meets the
/// goal on the planner model is corrected until the truth model's end pose meets it: the
/// plan's phase 2, flown again here on an independent truth model from `q_s`, ends within
/// 1e-6 (its planner-model f is then the models' difference, about 1e-5), for one or two
/// more rollouts than the planner-model plan; and the same bits from any slicing.
/// Verifies RL-TWO-007.
#[test]
fn a_plan_against_the_truth_model_meets_the_goal_there() {
    use reactionless::twophase::{TwoPhaseSearch, TwoPhaseStatus};
    let task = joint_space_task(OFFSETS);
    let planner = TwoPhaseConfig::reference();
    let truth = TwoPhaseConfig {
        against_truth: true,
        ..planner
    };
    let flown = |p: &reactionless::twophase::TwoPhasePlan<7, 4>| {
        let mut phase2 = task.clone();
        phase2.move_start(&p.q_s).unwrap();
        let mut model = TruthModel::new(&phase2, 10);
        let o = phase2.rollout(&p.eta, &mut model).unwrap();
        let e = model.end_pose().unwrap().error_to(phase2.target());
        (o.f, e.norm(), model.max_angle())
    };
    for seed in 1..=3 {
        let a = plan(&task, &planner, seed).unwrap();
        let b = plan(&task, &truth, seed).unwrap();
        assert_eq!(a.stop, TwoPhaseStop::Converged);
        assert_eq!(b.stop, TwoPhaseStop::Converged, "seed {seed}: {b:?}");
        let (fa, truth_fa, _) = flown(&a);
        let (fb, truth_fb, base) = flown(&b);
        assert!(
            fa <= 1e-6 && truth_fa > 1e-6,
            "seed {seed}: {fa:e} {truth_fa:e}"
        );
        assert!(truth_fb <= 1e-6, "seed {seed}: truth_f {truth_fb:e}");
        assert!(
            fb > 1e-6,
            "seed {seed}: the planner model's f {fb:e} is the models' gap"
        );
        assert!(base < 0.01f64.to_radians());
        assert_eq!(b.outcome.unwrap().f.to_bits(), fb.to_bits());
        assert!(
            b.rollouts > a.rollouts && b.rollouts <= a.rollouts + 3,
            "seed {seed}: {} against {}",
            b.rollouts,
            a.rollouts
        );
        // Sliced into single units, the same plan.
        let mut search = Box::new(TwoPhaseSearch::<7, 4>::IDLE);
        search.reset(&task, &truth, seed).unwrap();
        let sliced = loop {
            if let TwoPhaseStatus::Finished(p) = search.step(1).unwrap() {
                break p;
            }
        };
        assert_eq!(format!("{sliced:?}"), format!("{b:?}"));
    }
}
