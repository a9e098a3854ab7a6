//! Property tests: invariants over random robots, configurations, η and planner settings,
//! with a fixed seed so CI is reproducible. A failing case shrinks and is printed; add it to
//! `proptest-regressions/` by hand if it should stay pinned.
//!
//! Requirements: RL-MOM, RL-RNS, RL-LAW, RL-ROLL, RL-TRUTH, RL-PLAN, RL-CORE, RL-ROB
//! (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    missing_docs
)]

mod common;
use common::*;
use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;
use reactionless::{
    Basis, Error, Frames, Momentum, Motion, Planner, PlannerConfig, Pose, Progress, Robot,
    RobotDesc, Rollout, Status, Task,
};

fn config(cases: u32) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(20_261_122),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

fn frob(hbm: &[Vector3<f64>]) -> f64 {
    hbm.iter().map(|c| c.norm_squared()).sum::<f64>().sqrt()
}

/// A·N ≈ 0 and NᵀN ≈ I, or a reported rank loss (never NaN).
fn basis_holds<const N: usize, const K: usize>(
    d: &RobotDesc<N>,
    q: &[f64; N],
) -> Result<(), TestCaseError> {
    let robot = Robot::new(d).unwrap();
    let m = Momentum::new(&robot, &Frames::new(&robot, q));
    // A rank loss is reported (never NaN); otherwise the basis must hold.
    if let Ok(b) = Basis::<N, K>::initial(&m.hbm) {
        {
            let cols = b.columns();
            for (i, u) in cols.iter().enumerate() {
                prop_assert!(u.iter().all(|v| v.is_finite()));
                let an: Vector3<f64> = m.hbm.iter().zip(u).map(|(c, v)| c * *v).sum();
                prop_assert!(
                    an.norm() <= 1e-12 * frob(&m.hbm),
                    "|A n_{}| = {:e}",
                    i,
                    an.norm()
                );
                for (j, v) in cols.iter().enumerate() {
                    let dot: f64 = u.iter().zip(v).map(|(a, b)| a * b).sum();
                    prop_assert!(
                        (dot - f64::from(u8::from(i == j))).abs() <= 1e-12,
                        "NᵀN[{},{}] = {}",
                        i,
                        j,
                        dot
                    );
                }
            }
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(config(200))]

    /// For random robots and configurations the basis is finite, orthonormal and
    /// reactionless, or a rank loss.
    /// Verifies RL-RNS-001, RL-RNS-005.
    #[test]
    fn null_space_basis_is_orthonormal_and_reactionless(seed in any::<u64>(), which in 0u8..3) {
        let mut rng = rng(seed);
        match which {
            0 => {
                let q = random_q(&mut rng, &reactionless::CHASER7);
                basis_holds::<7, 4>(&reactionless::CHASER7, &q)?;
            }
            1 => {
                let d = random_robot::<6>(&mut rng);
                let q = random_q(&mut rng, &d);
                basis_holds::<6, 3>(&d, &q)?;
            }
            _ => {
                let d = random_robot::<9>(&mut rng);
                let q = random_q(&mut rng, &d);
                basis_holds::<9, 6>(&d, &q)?;
            }
        }
    }
}

/// Angular momentum about the system CoM of the whole free-floating system, by central
/// differences of an independent forward kinematics, when the joints move at `qd` and the
/// base turns at the truth model's `w0` and translates by CoM conservation.
fn total_momentum<const N: usize>(d: &RobotDesc<N>, q: &[f64; N], qd: &[f64; N]) -> (f64, f64) {
    let robot = Robot::new(d).unwrap();
    let frames = Frames::new(&robot, q);
    let w0 = Momentum::new(&robot, &frames)
        .base_angular_velocity(qd)
        .unwrap();
    let com0 = naive_fk(d, q, &Isometry3::identity()).system_com();
    let h = 1e-6;
    let state = |s: f64| {
        let qs: [f64; N] = core::array::from_fn(|i| q[i] + s * qd[i]);
        let r0 = UnitQuaternion::from_scaled_axis(w0 * s);
        let local = naive_fk(d, &qs, &Isometry3::identity()).system_com();
        let base = Isometry3::from_parts(Translation3::from(com0 - r0 * local), r0);
        (naive_fk(d, &qs, &base), body_rotations(d, &qs, &base))
    };
    let ((a, ra), (b, rb)) = (state(-h), state(h));
    let center = naive_fk(d, q, &Isometry3::identity());
    let rg = center.system_com();
    let mut l = Vector3::zeros();
    let mut scale = 0.0;
    for i in 0..center.com.len() {
        let v = (b.com[i] - a.com[i]) / (2.0 * h);
        let dr = rb[i] * ra[i].transpose();
        let w = Vector3::new(
            dr[(2, 1)] - dr[(1, 2)],
            dr[(0, 2)] - dr[(2, 0)],
            dr[(1, 0)] - dr[(0, 1)],
        ) / (4.0 * h);
        let spin = center.inertia[i] * w;
        let orbit = center.mass[i] * (center.com[i] - rg).cross(&v);
        scale += spin.norm() + orbit.norm();
        l += spin + orbit;
    }
    (l.norm(), scale)
}

proptest! {
    #![proptest_config(config(100))]

    /// The truth model's base motion conserves angular momentum (zero at start) for any
    /// joint motion, not only reactionless ones.
    /// Verifies RL-MOM-002, RL-TRUTH-003.
    #[test]
    fn truth_model_base_motion_conserves_momentum(seed in any::<u64>(), rates in prop::array::uniform7(-0.3f64..0.3)) {
        let mut rng = rng(seed);
        let q = random_q(&mut rng, &reactionless::CHASER7);
        let (l, scale) = total_momentum(&reactionless::CHASER7, &q, &rates);
        prop_assert!(l <= 1e-7 * scale.max(1e-12), "|L| = {:e}, scale {:e}", l, scale);
        let d = random_robot::<6>(&mut rng);
        let q6 = random_q(&mut rng, &d);
        let rates6: [f64; 6] = core::array::from_fn(|i| rates[i]);
        let (l, scale) = total_momentum(&d, &q6, &rates6);
        prop_assert!(l <= 1e-7 * scale.max(1e-12), "|L| = {:e}, scale {:e}", l, scale);
    }
}

/// Any bit pattern as η component.
fn any_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        any::<u64>().prop_map(f64::from_bits),
        Just(0.0),
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MIN_POSITIVE / 4.0),
        Just(1e300),
        Just(-1e-300),
        -5.0f64..5.0,
    ]
}

proptest! {
    #![proptest_config(config(300))]

    /// A rollout of any η is either rejected with a typed error or gives finite outputs.
    /// Verifies RL-LAW-005, RL-CORE-007, RL-ROB-005.
    #[test]
    fn rollout_of_any_eta_is_finite_or_a_typed_error(eta in prop::array::uniform8(any_f64())) {
        let task = short_task();
        let pairs = [[eta[0], eta[1]], [eta[2], eta[3]], [eta[4], eta[5]], [eta[6], eta[7]]];
        match Rollout::new(&task, &pairs) {
            Err(e) => prop_assert!(matches!(e, Error::NotFinite(_) | Error::EtaZero | Error::EtaTooLarge), "{:?}", e),
            Ok(mut r) => match r.advance(&task, u32::MAX, &mut ()) {
                Ok(Progress::Done(o)) => {
                    let scalars = [o.phi, o.f, o.max_abs_qd];
                    let all = o.q_final.iter().chain(&o.joint_min).chain(&o.joint_max)
                        .chain(&o.end_pose.position).chain(&o.end_pose.quat_wxyz)
                        .chain(&scalars);
                    for v in all { prop_assert!(v.is_finite()); }
                    prop_assert!(o.max_abs_qd <= task.robot().qd_max());
                }
                Ok(Progress::Running { .. }) => prop_assert!(false, "unlimited budget must finish"),
                Ok(Progress::Abandoned { .. }) => prop_assert!(false, "no cap: never abandoned"),
                Err(e) => prop_assert!(matches!(e, Error::RankLoss { .. } | Error::NonFiniteState { .. }), "{:?}", e),
            },
        }
    }

    /// The violation cap is exact: a capped rollout is abandoned only if the full rollout
    /// ends with Φ above the cap (and its partial Φ is a lower bound of it); otherwise it
    /// finishes bit-identical to the uncapped rollout.
    /// Verifies RL-ROLL-003, RL-ROLL-007.
    #[test]
    fn a_violation_cap_abandons_only_rollouts_that_would_exceed_it(
        eta in prop::array::uniform8(-8.0f64..8.0),
        cap in prop_oneof![Just(0.0), 0.0f64..0.5],
        budget in 1u32..4000,
    ) {
        // The reference task (30 s): many random η cross a joint limit somewhere.
        let task = reactionless::reference::paper_task().unwrap();
        let pairs = [[eta[0], eta[1]], [eta[2], eta[3]], [eta[4], eta[5]], [eta[6], eta[7]]];
        let Ok(full) = task.rollout(&pairs, &mut ()) else { return Ok(()) };
        let mut r = Rollout::new(&task, &pairs).unwrap().with_violation_cap(cap);
        let mut seen = Vec::new();
        let mut sink = |s: &reactionless::Sample<7>| seen.push(*s);
        let end = loop {
            match r.advance(&task, budget, &mut sink).unwrap() {
                Progress::Running { .. } => {}
                p => break p,
            }
        };
        match end {
            Progress::Abandoned { step, phi } => {
                prop_assert!(phi > cap && phi <= full.phi, "{} {} {}", phi, cap, full.phi);
                prop_assert_eq!(seen.len() as u32, step + 1);
                prop_assert_eq!(r.advance(&task, budget, &mut ()).unwrap(), end);
            }
            Progress::Done(o) => {
                prop_assert_eq!(o, full);
                // Only the final sample (not checked against the cap) may push Φ over it.
                let (mut lo, mut hi) = (*task.start(), *task.start());
                for s in &seen[..seen.len() - 1] {
                    for j in 0..7 {
                        lo[j] = lo[j].min(s.q[j]);
                        hi[j] = hi[j].max(s.q[j]);
                    }
                }
                prop_assert!(task.robot().violation(&lo, &hi) <= cap);
            }
            Progress::Running { .. } => unreachable!(),
        }
    }
}

/// The reference robot over 3 s (300 steps): quick enough for many cases.
fn short_task() -> Task<7, 4> {
    Task::new(robot(), q0(), TARGET, Motion::new(3.0, 0.01, 1).unwrap()).unwrap()
}

fn small_planner_config() -> impl Strategy<Value = PlannerConfig> {
    (
        1u32..12,
        1u32..6,
        0.0f64..3.0,
        0.0f64..3.0,
        (0.0f64..1.2, 0.0f64..1.0),
        prop_oneof![1e-3f64..1e-1, 1e-9f64..1e-6],
        prop_oneof![1e-3f64..10.0, 1e2f64..1e6],
        any::<u64>(),
        (1u32..5, 0.0f64..0.1, 0.0f64..2.0, -2.0f64..2.0),
        any::<bool>(),
    )
        .prop_map(
            |(
                particles,
                max_iterations,
                c1,
                c2,
                (wa, wb),
                tolerance,
                eta_bound,
                seed,
                (window, mri, eps1, eps2),
                refine,
            )| {
                PlannerConfig {
                    strategy: reactionless::Strategy::Cpso,
                    max_rollouts: 8040,
                    refine_against: reactionless::RefineAgainst::Planner,
                    particles,
                    max_iterations,
                    c1,
                    c2,
                    w_max: wa.max(wb),
                    w_min: wa.min(wb),
                    eta_bound,
                    stagnation: reactionless::StagnationConfig {
                        window,
                        min_relative_improvement: mri,
                        eps1,
                        eps2,
                    },
                    tolerance,
                    seed,
                    refine_tolerance: refine.then_some(1e-9),
                    refine_max_rollouts: 12,
                    frame_budget: 3000,
                }
            },
        )
}

fn run_planner(task: &Task<7, 4>, cfg: PlannerConfig, budget: u32) -> Result<Status<7, 4>, Error> {
    let mut p: Box<Planner<7, 4, 16>> = Box::new(Planner::new(task.clone(), cfg)?);
    loop {
        match p.step(budget, &mut ())? {
            Status::Running(_) => {}
            s => return Ok(s),
        }
    }
}

proptest! {
    #![proptest_config(config(40))]

    /// Any valid settings: the planner ends with finite values (never NaN), and the result
    /// does not depend on how the work is sliced.
    /// Verifies RL-LAW-005, RL-PLAN-003, RL-CORE-007.
    #[test]
    fn planner_is_finite_and_slicing_invariant(cfg in small_planner_config(), budget in 1u32..400) {
        let task = short_task();
        let whole = run_planner(&task, cfg, u32::MAX);
        let sliced = run_planner(&task, cfg, budget);
        prop_assert_eq!(whole, sliced);
        if let Ok(Status::Finished(p)) = whole {
            let o = &p.outcome;
            let scalars = [o.f, o.phi, o.g, p.search_f];
            for v in p.eta[0].iter().flatten().chain(&o.q_final).chain(&o.end_pose.position).chain(&scalars) {
                prop_assert!(v.is_finite(), "non-finite value in the plan");
            }
            prop_assert!(o.max_abs_qd <= task.robot().qd_max());
        }
    }
}

/// η scaled by 2^±300 and 2^±1000 rolls out bit-identically; a subnormal η still plans its
/// direction.
/// Verifies RL-LAW-007.
#[test]
fn a_huge_or_tiny_eta_plans_the_same_path_as_its_normalised_form() {
    // Scaling η by a power of two (keeping it normal) never changes a bit of the trajectory.
    let task = paper_task();
    let base = task.rollout(&ETA_HAT, &mut ()).unwrap();
    for e in [-1000, -300, 300, 1000] {
        let scaled = ETA_HAT.map(|p| p.map(|v| libm::scalbn(v, e)));
        let o = task.rollout(&scaled, &mut ()).unwrap();
        assert_eq!(o.q_final, base.q_final, "2^{e}");
        assert_eq!(o.end_pose, base.end_pose);
    }
    // Subnormal η has already lost mantissa bits before the core sees it: it still plans,
    // as the direction it still encodes.
    let tiny = ETA_HAT.map(|p| p.map(|v| libm::scalbn(v, -1060)));
    let o = task.rollout(&tiny, &mut ()).unwrap();
    assert!(
        o.q_final
            .iter()
            .zip(&base.q_final)
            .all(|(a, b)| (a - b).abs() < 1e-4)
    );
    let _ = Pose::ZERO;
}
