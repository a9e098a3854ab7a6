//! Physics of the core against independent computations.
//!
//! The reference for H~b, H~bm and J_G is a naive forward kinematics written straight from
//! the URDF conventions with nalgebra isometries, differentiated by central differences.
//!
//! Requirements: RL-MODEL, RL-MOM, RL-RNS, RL-LAW, RL-ROLL (docs/requirements.md).
#![allow(
    clippy::unwrap_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop,
    missing_docs
)]

mod common;
use common::*;
use nalgebra::{Isometry3, Matrix3, SMatrix, Translation3, UnitQuaternion, Vector3};
use rand::Rng;
use reactionless::{
    Basis, BodyDesc, Frames, Inertia, JointDesc, Momentum, Motion, Origin, Pose, Progress,
    RankLoss, Robot, RobotDesc, Rollout, Sample, Task, TimeLaw, conditioning, generalized_jacobian,
};

const H: f64 = 1e-5;

/// Angular momentum about the system CoM of the velocity field `(before → after)/2h`,
/// from the naive kinematics: Σ I_i ω_i + m_i (c_i − r_g) × ċ_i.
fn momentum_fd(
    center: &NaiveFk,
    before: &NaiveFk,
    after: &NaiveFk,
    rot_before: &[Matrix3<f64>],
    rot_after: &[Matrix3<f64>],
    rg: &Vector3<f64>,
) -> Vector3<f64> {
    let mut l = Vector3::zeros();
    for i in 0..before.com.len() {
        let v = (after.com[i] - before.com[i]) / (2.0 * H);
        // vee((R − Rᵀ)/2) = sin θ · axis: accurate to O(θ³) for the tiny rotations here
        // (nalgebra's scaled_axis goes through acos of the trace, ill-conditioned near 0).
        let dr = rot_after[i] * rot_before[i].transpose();
        let w = Vector3::new(
            dr[(2, 1)] - dr[(1, 2)],
            dr[(0, 2)] - dr[(2, 0)],
            dr[(1, 0)] - dr[(0, 1)],
        ) / (4.0 * H);
        l += center.inertia[i] * w + center.mass[i] * (center.com[i] - rg).cross(&v);
    }
    l
}

fn rel_err(got: &Vector3<f64>, want: &Vector3<f64>, scale: f64) -> f64 {
    (got - want).norm() / scale
}

/// H~bm column j = angular momentum about r_g per unit q̇_j (base held); H~b ω = angular
/// momentum about r_g when the whole system spins rigidly about r_g with ω.
fn check_momentum<const N: usize>(d: &RobotDesc<N>, q: &[f64; N]) -> f64 {
    let robot = Robot::new(d).unwrap();
    let frames = Frames::new(&robot, q);
    let m = Momentum::new(&robot, &frames);
    let id = Isometry3::identity();
    let center = naive_fk(d, q, &id);
    let rg = center.system_com();
    assert!((rg - frames.com).norm() < 1e-12, "system CoM");
    let hbm_scale = m.hbm.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let mut worst: f64 = 0.0;
    for j in 0..N {
        let (mut qp, mut qm) = (*q, *q);
        qp[j] += H;
        qm[j] -= H;
        let (a, b) = (naive_fk(d, &qm, &id), naive_fk(d, &qp, &id));
        let (ra, rb) = (body_rotations(d, &qm, &id), body_rotations(d, &qp, &id));
        let col = momentum_fd(&center, &a, &b, &ra, &rb, &rg);
        worst = worst.max(rel_err(&m.hbm[j], &col, hbm_scale));
    }
    let hb = m.hb.to_matrix();
    for k in 0..3 {
        let axis = Vector3::ith_axis(k);
        // Rigid spin about r_g: base pose = rotation about r_g.
        let spin = |angle: f64| {
            let r = UnitQuaternion::from_axis_angle(&axis, angle);
            Isometry3::from_parts(nalgebra::Translation3::from(rg - r * rg), r)
        };
        let (pa, pb) = (spin(-H), spin(H));
        let (a, b) = (naive_fk(d, q, &pa), naive_fk(d, q, &pb));
        let (ra, rb) = (body_rotations(d, q, &pa), body_rotations(d, q, &pb));
        let l = momentum_fd(&center, &a, &b, &ra, &rb, &rg);
        worst = worst.max(rel_err(&hb.column(k).into_owned(), &l, hb.norm()));
    }
    worst
}

/// r_g, H~bm and H~b equal central differences of an independent kinematics (CHASER7,
/// random 6-/9-joint robots).
/// Verifies RL-MODEL-002, RL-MOM-001.
#[test]
fn momentum_matrices_match_finite_differences_on_random_configurations() {
    let mut rng = rng(11);
    let mut worst: f64 = 0.0;
    let chaser = reactionless::CHASER7;
    for _ in 0..100 {
        let q = random_q(&mut rng, &chaser);
        worst = worst.max(check_momentum(&chaser, &q));
    }
    for _ in 0..40 {
        let d = random_robot::<6>(&mut rng);
        let q = random_q(&mut rng, &d);
        worst = worst.max(check_momentum(&d, &q));
        let d = random_robot::<9>(&mut rng);
        let q = random_q(&mut rng, &d);
        worst = worst.max(check_momentum(&d, &q));
    }
    assert!(worst <= 1e-6, "worst relative error {worst:e}");
}

/// Link CoMs and the end pose equal an independent URDF chain within 1e-12 (random 8-joint
/// robots).
/// Verifies RL-MODEL-001.
#[test]
fn forward_kinematics_matches_naive_urdf_chain() {
    let mut rng = rng(5);
    for _ in 0..50 {
        let d = random_robot::<8>(&mut rng);
        let q = random_q(&mut rng, &d);
        let robot = Robot::new(&d).unwrap();
        let f = Frames::new(&robot, &q);
        let n = naive_fk(&d, &q, &Isometry3::identity());
        assert!((f.ee_position - n.ee.translation.vector).norm() < 1e-12);
        let r = UnitQuaternion::from_matrix(&f.ee_rotation);
        assert!(r.angle_to(&n.ee.rotation) < 1e-12);
        for i in 0..8 {
            assert!((f.links[i].com - n.com[i + 1]).norm() < 1e-12);
        }
    }
}

fn planner_pose<const N: usize>(robot: &Robot<N>, q: &[f64; N], com0: &Vector3<f64>) -> Pose {
    Frames::new(robot, q).end_pose(com0, [1.0, 0.0, 0.0, 0.0])
}

/// J_G·n = d(end pose)/ds along a null-space direction n, with the base moved by CoM
/// conservation and not rotating (first order).
fn check_jacobian<const N: usize, const K: usize>(d: &RobotDesc<N>, q: &[f64; N]) -> f64 {
    let robot = Robot::new(d).unwrap();
    let frames = Frames::new(&robot, q);
    let jg = generalized_jacobian(&robot, &frames).unwrap();
    let m = Momentum::new(&robot, &frames);
    let basis = Basis::<N, K>::initial(&m.hbm).unwrap();
    let com0 = frames.com;
    let mut worst: f64 = 0.0;
    for n in basis.columns() {
        let (mut qp, mut qm) = (*q, *q);
        for i in 0..N {
            qp[i] += H * n[i];
            qm[i] -= H * n[i];
        }
        let (a, b) = (
            planner_pose(&robot, &qm, &com0),
            planner_pose(&robot, &qp, &com0),
        );
        let v = (Vector3::from(b.position) - Vector3::from(a.position)) / (2.0 * H);
        let e = a.error_to(&b); // log(R_b R_aᵀ)
        let w = Vector3::from(e.rotation) / (2.0 * H);
        let nv = nalgebra::SVector::<f64, N>::from(*n);
        let jn = jg * nv;
        let scale = jg.norm();
        worst = worst.max((jn.fixed_rows::<3>(0) - v).norm() / scale);
        worst = worst.max((jn.fixed_rows::<3>(3) - w).norm() / scale);
    }
    worst
}

/// J_G along null-space directions equals central differences of the CoM-conserving pose
/// within 1e-8.
/// Verifies RL-MODEL-002, RL-MOM-004.
#[test]
fn generalized_jacobian_matches_finite_differences_along_null_space() {
    let mut rng = rng(7);
    let mut worst: f64 = 0.0;
    for _ in 0..50 {
        let q = random_q(&mut rng, &reactionless::CHASER7);
        worst = worst.max(check_jacobian::<7, 4>(&reactionless::CHASER7, &q));
        let d = random_robot::<6>(&mut rng);
        let q = random_q(&mut rng, &d);
        worst = worst.max(check_jacobian::<6, 3>(&d, &q));
    }
    assert!(worst < 1e-8, "worst relative error {worst:e}");
}

/// For arbitrary q̇ the base rate w₀ conserves momentum: ‖H~b w₀ + H~bm q̇‖ < 1e-12·‖H~b‖.
/// Verifies RL-MOM-002.
#[test]
fn jacobian_angular_rows_predict_base_rotation_for_general_motion() {
    // Off the null space the base turns: w_E = k + w0 must hold with w0 from H~b, H~bm.
    // Check w0 against momentum conservation: H~b w0 + H~bm q̇ = 0.
    let mut rng = rng(9);
    let robot = robot();
    for _ in 0..20 {
        let q = random_q(&mut rng, &reactionless::CHASER7);
        let qd: [f64; 7] = core::array::from_fn(|_| rand::Rng::random_range(&mut rng, -0.2..0.2));
        let m = Momentum::new(&robot, &Frames::new(&robot, &q));
        let w0 = m.base_angular_velocity(&qd).unwrap();
        let l = m.hb.mul_vec(&w0) + m.coupling_momentum(&qd);
        assert!(l.norm() < 1e-12 * m.hb.to_matrix().norm(), "L = {l}");
    }
}

fn a_times<const N: usize>(hbm: &[Vector3<f64>; N], n: &[f64; N]) -> Vector3<f64> {
    hbm.iter().zip(n).map(|(c, v)| c * *v).sum()
}

fn frob<const N: usize>(hbm: &[Vector3<f64>; N]) -> f64 {
    hbm.iter().map(|c| c.norm_squared()).sum::<f64>().sqrt()
}

fn check_basis<const N: usize, const K: usize>(hbm: &[Vector3<f64>; N], b: &Basis<N, K>) {
    let cols = b.columns();
    for (i, u) in cols.iter().enumerate() {
        assert!(
            a_times(hbm, u).norm() <= 1e-12 * frob(hbm),
            "A n_{i} = {}",
            a_times(hbm, u).norm()
        );
        for (j, v) in cols.iter().enumerate() {
            let d: f64 = u.iter().zip(v).map(|(a, b)| a * b).sum();
            let want = if i == j { 1.0 } else { 0.0 };
            assert!((d - want).abs() <= 1e-12, "NᵀN[{i},{j}] = {d}");
        }
    }
}

/// The initial basis is orthonormal and in the null space of H~bm (CHASER7, random 9-joint
/// robots).
/// Verifies RL-RNS-001.
#[test]
fn basis_is_orthonormal_null_space_on_random_configurations() {
    let mut rng = rng(3);
    for _ in 0..100 {
        let q = random_q(&mut rng, &reactionless::CHASER7);
        let robot = robot();
        let m = Momentum::new(&robot, &Frames::new(&robot, &q));
        check_basis(&m.hbm, &Basis::<7, 4>::initial(&m.hbm).unwrap());
        let d = random_robot::<9>(&mut rng);
        let q = random_q(&mut rng, &d);
        let r = Robot::new(&d).unwrap();
        let m = Momentum::new(&r, &Frames::new(&r, &q));
        check_basis(&m.hbm, &Basis::<9, 6>::initial(&m.hbm).unwrap());
    }
}

/// Along the η̂ rollout: the basis stays an orthonormal null-space basis, moves
/// continuously (consecutive bases differ by O(dt), no sign flips), and every q̇ is
/// reactionless (H~bm q̇ = 0).
/// Verifies RL-RNS-003, RL-RNS-004.
#[test]
fn basis_transport_is_continuous_along_a_rollout() {
    let task = paper_task();
    let robot = task.robot().clone();
    let mut r = Rollout::new(&task, &ETA_HAT).unwrap();
    let mut prev = *r.basis();
    let mut worst_step: f64 = 0.0;
    let mut worst_rns: f64 = 0.0;
    loop {
        let mut last: Option<Sample<7>> = None;
        let p = r
            .advance(&task, 1, &mut |s: &Sample<7>| last = Some(*s))
            .unwrap();
        let s = last.unwrap();
        let m = Momentum::new(&robot, &Frames::new(&robot, &s.q));
        let qd_norm = s.qd.iter().map(|v| v * v).sum::<f64>().sqrt();
        worst_rns =
            worst_rns.max(a_times(&m.hbm, &s.qd).norm() / (frob(&m.hbm) * qd_norm.max(1e-300)));
        if let Progress::Done(_) = p {
            break;
        }
        let b = *r.basis();
        let m = Momentum::new(&robot, &Frames::new(&robot, r.q()));
        check_basis(&m.hbm, &b);
        for (u, v) in b.columns().iter().zip(prev.columns()) {
            let d: f64 = u.iter().zip(v).map(|(a, b)| a * b).sum();
            assert!(d > 0.99, "column flipped or jumped: cos = {d}");
            let diff: f64 = u
                .iter()
                .zip(v)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            worst_step = worst_step.max(diff);
        }
        prev = b;
    }
    assert!(
        worst_step < 1e-3,
        "largest basis change per step {worst_step:e}"
    );
    assert!(
        worst_rns < 1e-12,
        "largest |H~bm q̇| / (|H~bm| |q̇|) = {worst_rns:e}"
    );
}

/// eq. 7 and eq. 9: q̇ = 0 exactly at both ends, |q̇| ≤ q̇_max at every sample, for η̂ and
/// random η (also on a random 6-DOF robot).
/// Verifies RL-LAW-002, RL-LAW-005, RL-ROLL-004.
#[test]
fn rates_vanish_at_the_ends_and_respect_the_bound() {
    let task = paper_task();
    let mut rng = rng(21);
    let mut etas = vec![ETA_HAT];
    for _ in 0..10 {
        etas.push(core::array::from_fn(|_| {
            [
                rand::Rng::random_range(&mut rng, -5.0..5.0),
                rand::Rng::random_range(&mut rng, -5.0..5.0),
            ]
        }));
    }
    let qd_max = task.robot().qd_max();
    for eta in etas {
        let mut first = None;
        let mut last = None;
        let mut worst: f64 = 0.0;
        let o = task
            .rollout(&eta, &mut |s: &Sample<7>| {
                if s.step == 0 {
                    first = Some(s.qd);
                }
                last = Some((s.t, s.qd));
                worst = worst.max(s.qd.iter().fold(0.0f64, |m, v| m.max(v.abs())));
            })
            .unwrap();
        assert_eq!(first.unwrap(), [0.0; 7]);
        let (t, qd) = last.unwrap();
        assert_eq!(t, 30.0);
        assert_eq!(qd, [0.0; 7]);
        assert!(worst <= qd_max, "max |qd| {worst} > {qd_max}");
        assert_eq!(worst, o.max_abs_qd);
    }
    let d = random_robot::<6>(&mut rng);
    let q0 = random_q(&mut rng, &d);
    let robot = Robot::new(&d).unwrap();
    let qd_max = robot.qd_max();
    let target = Pose {
        position: [0.0; 3],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    let task: Task<6, 3> =
        Task::new(robot, q0, target, Motion::new(5.0, 0.01, 2).unwrap()).unwrap();
    let mut worst: f64 = 0.0;
    task.rollout(
        &[[1.0, -2.0], [0.5, 0.1], [-3.0, 4.0]],
        &mut |s: &Sample<6>| {
            worst = worst.max(s.qd.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        },
    )
    .unwrap();
    assert!(
        worst <= qd_max && worst > 0.1 * qd_max,
        "{worst} vs {qd_max}"
    );
}

/// A planar arm (H~bm of rank 1) is a RankLoss at step 0 from the task constructor, never a
/// NaN basis.
/// Verifies RL-RNS-005.
#[test]
fn planar_arm_reports_rank_loss_instead_of_nan() {
    // All axes along z and everything in the xy-plane: H~bm has rank 1.
    let mut d = reactionless::CHASER7;
    for j in &mut d.joints {
        j.axis = [0.0, 0.0, 1.0];
        j.origin.xyz[2] = 0.0;
    }
    let robot = Robot::new(&d).unwrap();
    let err =
        Task::<7, 4>::new(robot, [0.0; 7], TARGET, Motion::new(1.0, 0.01, 1).unwrap()).unwrap_err();
    assert_eq!(
        err,
        reactionless::Error::RankLoss {
            step: 0,
            cause: reactionless::RankLoss::Coupling
        }
    );
    let _ = Matrix3::<f64>::identity();
}

/// With the base held at `base` (any attitude R and position), the angular momentum about
/// r_g of each joint's motion and of a rigid spin, by central differences of the naive
/// kinematics in the inertial frame, against the core's base-frame matrices: R·H~bm (the
/// rows rotate) and R·H~b·Rᵀ. Joint motion along each column of the core's basis carries
/// no angular momentum at any base attitude (the null space does not change).
fn check_rotated_base<const N: usize, const K: usize>(
    d: &RobotDesc<N>,
    q: &[f64; N],
    base: &Isometry3<f64>,
) -> f64 {
    let robot = Robot::new(d).unwrap();
    let m = Momentum::new(&robot, &Frames::new(&robot, q));
    let basis = Basis::<N, K>::initial(&m.hbm).unwrap();
    let r = *base.rotation.to_rotation_matrix().matrix();
    let center = naive_fk(d, q, base);
    let rg = center.system_com();
    let hbm_scale = m.hbm.iter().map(|c| c.norm()).fold(0.0, f64::max);
    let joint_motion = |dir: &[f64; N]| {
        let (mut qp, mut qm) = (*q, *q);
        for i in 0..N {
            qp[i] += H * dir[i];
            qm[i] -= H * dir[i];
        }
        let (a, b) = (naive_fk(d, &qm, base), naive_fk(d, &qp, base));
        let (ra, rb) = (body_rotations(d, &qm, base), body_rotations(d, &qp, base));
        momentum_fd(&center, &a, &b, &ra, &rb, &rg)
    };
    let mut worst: f64 = 0.0;
    for j in 0..N {
        let e: [f64; N] = core::array::from_fn(|i| f64::from(u8::from(i == j)));
        let want = r * m.hbm[j];
        worst = worst.max(rel_err(&joint_motion(&e), &want, hbm_scale));
    }
    let hb = r * m.hb.to_matrix() * r.transpose();
    for k in 0..3 {
        let axis = Vector3::ith_axis(k);
        let spin = |angle: f64| {
            let s = UnitQuaternion::from_axis_angle(&axis, angle);
            Isometry3::from_parts(Translation3::from(rg - s * rg), s) * base
        };
        let (pa, pb) = (spin(-H), spin(H));
        let (a, b) = (naive_fk(d, q, &pa), naive_fk(d, q, &pb));
        let (ra, rb) = (body_rotations(d, q, &pa), body_rotations(d, q, &pb));
        let l = momentum_fd(&center, &a, &b, &ra, &rb, &rg);
        worst = worst.max(rel_err(&hb.column(k).into_owned(), &l, hb.norm()));
    }
    for n in basis.columns() {
        worst = worst.max(joint_motion(n).norm() / hbm_scale);
    }
    worst
}

fn random_base(rng: &mut rand::rngs::StdRng) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
            rng.random_range(-5.0..5.0),
        ),
        UnitQuaternion::from_euler_angles(
            rng.random_range(-3.1..3.1),
            rng.random_range(-1.5..1.5),
            rng.random_range(-3.1..3.1),
        ),
    )
}

/// Rotating the base rotates the rows of H~bm (and H~b as a tensor) and leaves the
/// reaction null space unchanged: the core's base-frame H~bm, H~b and basis predict the
/// inertial-frame momentum of an independent kinematics for random base attitudes, within
/// 1e-6 relative (CHASER7 and random 6-joint robots).
/// Verifies RL-MOM-005.
#[test]
fn base_attitude_rotates_the_rows_of_hbm_and_keeps_its_null_space() {
    let mut rng = rng(13);
    let mut worst: f64 = 0.0;
    for _ in 0..20 {
        let q = random_q(&mut rng, &reactionless::CHASER7);
        let base = random_base(&mut rng);
        worst = worst.max(check_rotated_base::<7, 4>(
            &reactionless::CHASER7,
            &q,
            &base,
        ));
        let d = random_robot::<6>(&mut rng);
        let q = random_q(&mut rng, &d);
        let base = random_base(&mut rng);
        worst = worst.max(check_rotated_base::<6, 3>(&d, &q, &base));
    }
    assert!(worst <= 1e-6, "worst relative error {worst:e}");
}

/// eq. 14's q̇_max is the slowest joint's velocity limit: with unequal limits (the
/// smallest at each joint in turn) the model reports it, g of eq. 14 uses it (g·q̇_max is
/// the reference robot's), and every joint's rate stays within it.
/// Verifies RL-MODEL-004, RL-LAW-004, RL-LAW-005.
#[test]
fn the_rate_bound_is_the_smallest_joint_velocity_limit() {
    let limits = [0.40, 0.31, 0.27, 0.50, 0.35, 0.45, 0.29];
    let reference = paper_task().rollout(&ETA_HAT, &mut ()).unwrap();
    let reference_qd_max = paper_task().robot().qd_max();
    for slow in 0..7 {
        let mut d = reactionless::CHASER7;
        for (joint, v) in d.joints.iter_mut().zip(limits) {
            joint.velocity = v;
        }
        d.joints[slow].velocity = 0.12;
        let robot = Robot::new(&d).unwrap();
        assert_eq!(robot.qd_max(), 0.12, "slowest joint {}", slow + 1);
        let task = Task::<7, 4>::new(robot, q0(), TARGET, *paper_task().motion()).unwrap();
        let law = TimeLaw::new(&ETA_HAT, task.motion(), 0.12).unwrap();
        let mut fastest = [0.0f64; 7];
        let o = task
            .rollout(&ETA_HAT, &mut |s: &Sample<7>| {
                for (m, v) in fastest.iter_mut().zip(s.qd) {
                    *m = m.max(v.abs());
                }
            })
            .unwrap();
        assert_eq!(o.g, law.g());
        let scaled = (o.g * 0.12) / (reference.g * reference_qd_max);
        assert!(
            (scaled - 1.0).abs() < 4e-15,
            "g·q̇_max = {scaled} × reference"
        );
        assert!(fastest.iter().all(|&m| m <= 0.12), "{fastest:?}");
        assert_eq!(fastest.iter().fold(0.0f64, |a, &b| a.max(b)), o.max_abs_qd);
    }
}

/// `A = U·diag(s)·Vᵀ` (3×7 columns) for random rotations U and orthonormal columns V.
fn with_singular_values(rng: &mut rand::rngs::StdRng, s: [f64; 3]) -> [Vector3<f64>; 7] {
    let u = UnitQuaternion::from_euler_angles(
        rng.random_range(-3.1..3.1),
        rng.random_range(-1.5..1.5),
        rng.random_range(-3.1..3.1),
    );
    let v = SMatrix::<f64, 7, 3>::from_fn(|_, _| rng.random_range(-1.0..1.0))
        .qr()
        .q();
    let a =
        u.to_rotation_matrix().matrix() * Matrix3::from_diagonal(&Vector3::from(s)) * v.transpose();
    core::array::from_fn(|j| a.column(j).into_owned())
}

/// σ_min/σ_max of the 3×N matrix with columns `a`, by nalgebra's SVD (host-side reference).
fn svd_ratio(a: &[Vector3<f64>; 7]) -> f64 {
    let sv = SMatrix::<f64, 3, 7>::from_columns(a).singular_values();
    sv.min() / sv.max()
}

/// The rank estimate √(det(AAᵀ)/(c₂·tr AAᵀ)) lies in [σ_min/(3σ_max), σ_min/σ_max] of an
/// SVD, both ends reached (equal singular values; widely spread ones), so rank loss is
/// declared for every ratio below 1e-6 and never for one above 3e-6.
/// Verifies RL-RNS-005, RL-RNS-006.
#[test]
fn rank_estimate_lies_within_a_factor_3_below_the_singular_value_ratio() {
    let mut rng = rng(31);
    for _ in 0..2000 {
        // σ_min/σ_max log-uniform in [3e-7, 1], the middle value anywhere between.
        let ratio = 10f64.powf(-6.5 * rng.random::<f64>());
        let mid = ratio.powf(rng.random::<f64>());
        let scale = 10f64.powf(rng.random_range(-3.0..3.0));
        let a = with_singular_values(&mut rng, [scale, scale * mid, scale * ratio]);
        let truth = svd_ratio(&a);
        let est = conditioning(&a);
        // Forming AAᵀ costs relative accuracy ε/ratio² in its smallest eigenvalue.
        let slack = 1e-12 + 10.0 * f64::EPSILON / (truth * truth);
        assert!(
            est >= truth / 3.0 * (1.0 - slack) && est <= truth * (1.0 + slack),
            "estimate {est:e} for σ_min/σ_max = {truth:e}"
        );
    }
    // The ends: equal singular values give exactly a third, a wide spread the ratio.
    let equal = with_singular_values(&mut rng, [2.0, 2.0, 2.0]);
    assert!((conditioning(&equal) - 1.0 / 3.0).abs() < 1e-14);
    let spread = with_singular_values(&mut rng, [1.0, 1e-3, 1e-6]);
    assert!(conditioning(&spread) / svd_ratio(&spread) > 0.999);
    // The decision: a ratio below 1e-6 is always rank loss, one above 3e-6 never.
    for ratio in [1e-7f64, 5e-7, 0.99e-6, 3.03e-6, 1e-5, 1e-3, 1.0] {
        for mid in [ratio, ratio.sqrt(), 1.0] {
            let a = with_singular_values(&mut rng, [1.0, mid, ratio]);
            let got = Basis::<7, 4>::initial(&a);
            if ratio < 1e-6 {
                assert_eq!(got, Err(RankLoss::Coupling), "ratio {ratio:e}, mid {mid:e}");
            } else {
                assert_ne!(got, Err(RankLoss::Coupling), "ratio {ratio:e}, mid {mid:e}");
            }
        }
    }
}

/// Columns of a well-conditioned 3×4 A (all singular values 1) whose null space is
/// (0, 0, c, s), c = √(1 − s²): the initial basis column E = e₄ and a basis e₄ carried
/// here both have Gram–Schmidt pivot |P e₄| = s.
fn null_space_at(s: f64) -> [Vector3<f64>; 4] {
    let c = (1.0 - s * s).sqrt();
    [
        Vector3::new(1.0, 0.0, 0.0),
        Vector3::new(0.0, 1.0, 0.0),
        Vector3::new(0.0, 0.0, -s),
        Vector3::new(0.0, 0.0, c),
    ]
}

/// A Gram–Schmidt pivot ≤ 1e-6 while building or transporting the basis is
/// `RankLoss::Basis` (never a NaN basis), also for a well-conditioned H~bm; a task whose
/// start has such a pivot reports it at step 0. The robot: three coaxial joints at the
/// base, so the only reactionless motion counter-rotates them and never moves joint 4
/// (the initial basis direction e₄).
/// Verifies RL-RNS-007.
#[test]
fn a_vanishing_gram_schmidt_pivot_is_reported_as_basis_rank_loss() {
    // Pivot s: at or below 1e-6 a basis rank loss, above it a unit null-space column.
    let from = Basis::<4, 1>::initial(&null_space_at(1.0)).unwrap();
    assert_eq!(from.columns()[0], [0.0, 0.0, 0.0, 1.0]);
    for s in [0.0, 1e-12, 5e-7, 0.99e-6, 1.01e-6, 1e-5, 0.5] {
        let a = null_space_at(s);
        assert!((conditioning(&a) - 1.0 / 3.0).abs() < 1e-12);
        for got in [Basis::<4, 1>::initial(&a), from.transported(&a)] {
            if s <= 1e-6 {
                assert_eq!(got, Err(RankLoss::Basis), "pivot {s:e}");
            } else {
                let n = got.unwrap().columns()[0];
                let want = [0.0, 0.0, (1.0 - s * s).sqrt(), s];
                assert_close("basis column", &n, &want, 1e-9);
            }
        }
    }
    // Three coaxial joints (z, at the same point) on the base, then an off-axis link and a
    // fourth joint about y: H~bm has full rank, but its null space lies in joints 1–3.
    let body = |mass: f64, com: [f64; 3], i: [f64; 3]| BodyDesc {
        mass,
        inertial: Origin {
            xyz: com,
            rpy: [0.0; 3],
        },
        inertia: Inertia::diagonal(i[0], i[1], i[2]),
    };
    let joint = |xyz: [f64; 3], axis: [f64; 3]| JointDesc {
        origin: Origin { xyz, rpy: [0.0; 3] },
        axis,
        lower: -3.0,
        upper: 3.0,
        velocity: 0.3,
    };
    let z = [0.0, 0.0, 1.0];
    let d = RobotDesc::<4> {
        base: body(500.0, [0.0; 3], [100.0, 120.0, 140.0]),
        joints: [
            joint([0.0, 0.0, 0.5], z),
            joint([0.0; 3], z),
            joint([0.0; 3], z),
            joint([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]),
        ],
        links: [
            body(5.0, [0.0, 0.0, 0.1], [0.1, 0.1, 0.05]),
            body(4.0, [0.0, 0.0, 0.05], [0.08, 0.08, 0.04]),
            body(10.0, [0.5, 0.0, 0.0], [0.1, 1.0, 1.0]),
            body(3.0, [0.3, 0.1, 0.0], [0.02, 0.03, 0.03]),
        ],
        end_effector: Origin::IDENTITY,
    };
    let robot = Robot::new(&d).unwrap();
    let q = [0.3, -0.2, 0.5, 0.4];
    let m = Momentum::new(&robot, &Frames::new(&robot, &q));
    assert!(conditioning(&m.hbm) > 1e-4, "H~bm has full rank");
    // Links 1 and 2 spin about their own axis (I_zz = 0.05, 0.04): h₁ − h₂ = 0.05 k and
    // h₂ − h₃ = 0.04 k, so n = (0.04, −0.09, 0.05, 0) is reactionless.
    let n = [0.04, -0.09, 0.05, 0.0];
    assert!(a_times(&m.hbm, &n).norm() <= 1e-12 * frob(&m.hbm));
    assert_eq!(Basis::<4, 1>::initial(&m.hbm), Err(RankLoss::Basis));
    let target = Pose {
        position: [0.0; 3],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    assert_eq!(
        Task::<4, 1>::new(robot, q, target, Motion::new(1.0, 0.01, 1).unwrap()).unwrap_err(),
        reactionless::Error::RankLoss {
            step: 0,
            cause: RankLoss::Basis
        }
    );
}
