//! Clearance as a constraint of the rollout (spec §13): the step bound never exceeds the
//! distance the path attains between samples, the shortfall is part of Φ, a task without
//! geometry is unchanged bit for bit, and what cannot evaluate geometry refuses it.
//!
//! Requirements: RL-COLL (docs/requirements.md).

#![allow(
    clippy::indexing_slicing,
    clippy::unwrap_used,
    clippy::panic,
    missing_docs
)]

use reactionless::batch::Batch;
use reactionless::clearance::{CollisionSet, MAX_KEEP_OUTS, Side};
use reactionless::collision::{Placed, Shape, signed_distance};
use reactionless::geometry::{Mat3, Vec3};
use reactionless::{
    CHASER7, Error, Frames, Integrator, Motion, Outcome, Pose, Progress, Robot, Rollout, Sample,
    Task,
};

const Q0_DEG: [f64; 7] = [-90.0, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0];
const ETA: [[f64; 2]; 4] = [
    [3.14771, 0.809316],
    [1.12249, 0.754006],
    [4.7352, 0.406031],
    [-4.1572, 4.29895],
];

fn task() -> Task<7, 4> {
    let robot = Robot::new(&CHASER7).unwrap();
    let q0 = Q0_DEG.map(f64::to_radians);
    let target = Pose {
        position: [2.0, 0.1, -1.4],
        quat_wxyz: [1.0, 0.0, 0.0, 0.0],
    };
    Task::new(robot, q0, target, Motion::new(30.0, 0.01, 1).unwrap()).unwrap()
}

fn at(shape: Shape, pos: [f64; 3]) -> Placed {
    Placed {
        shape,
        rot: Mat3::identity(),
        pos: Vec3::from(pos),
    }
}

/// A ball on every link at its centre of mass (URDF link frame), a box on the base, and a
/// keep-out ball at `keep` (inertial frame).
fn set(robot: &Robot<7>, required: f64, keep: [f64; 3], radius: f64) -> CollisionSet<7> {
    let mut s = CollisionSet::new(required, 0.005).unwrap();
    let desc = robot.desc();
    let base = s
        .add_primitive(
            robot,
            0,
            &at(
                Shape::Box {
                    half: [0.7, 1.1, 0.6],
                },
                [0.0; 3],
            ),
        )
        .unwrap();
    assert_eq!(base, 0);
    for (i, link) in desc.links.iter().enumerate() {
        let ball = at(Shape::Sphere { radius: 0.08 }, link.inertial.xyz);
        s.add_primitive(robot, (i + 1) as u8, &ball).unwrap();
    }
    s.add_keep_out(&at(Shape::Sphere { radius }, keep)).unwrap();
    // Spec §13's pairs: 21 between bodies two or more apart, 8 against the keep-out.
    assert_eq!(s.pair_count(), 29);
    s
}

fn run(task: &Task<7, 4>, samples: &mut Vec<Sample<7>>) -> Outcome<7> {
    task.rollout(&ETA, &mut |s: &Sample<7>| samples.push(*s))
        .unwrap()
}

/// The placed primitives of `set`'s construction above at configuration `q`, by a direct
/// forward kinematics of the URDF description (not the rollout's frames).
fn distances(robot: &Robot<7>, com0: &Vec3, q: &[f64; 7], keep: &Placed) -> f64 {
    // URDF chain: T_i = T_{i−1} · origin_i · Rot(axis_i, q_i).
    let desc = robot.desc();
    let mut frames = vec![(Mat3::identity(), Vec3::zeros())];
    let (mut r, mut t) = (Mat3::identity(), Vec3::zeros());
    for (j, qj) in desc.joints.iter().zip(q.iter()) {
        t += r * j.origin.translation();
        let axis = nalgebra::Unit::new_normalize(Vec3::from(j.axis));
        r = r * j.origin.rotation() * nalgebra::Rotation3::from_axis_angle(&axis, *qj).matrix();
        frames.push((r, t));
    }
    let bodies: Vec<(f64, Vec3)> = std::iter::once(&desc.base)
        .chain(desc.links.iter())
        .map(|b| (b.mass, Vec3::from(b.inertial.xyz)))
        .collect();
    let (mut m, mut c) = (0.0, Vec3::zeros());
    for ((r, t), (mass, com)) in frames.iter().zip(&bodies) {
        m += mass;
        c += (t + r * com) * *mass;
    }
    let shift = com0 - c / m;
    let mut placed = vec![Placed {
        shape: Shape::Box {
            half: [0.7, 1.1, 0.6],
        },
        rot: Mat3::identity(),
        pos: shift,
    }];
    for ((r, t), (_, com)) in frames.iter().zip(&bodies).skip(1) {
        placed.push(Placed {
            shape: Shape::Sphere { radius: 0.08 },
            rot: *r,
            pos: t + r * com + shift,
        });
    }
    let mut best = f64::INFINITY;
    for a in 0..placed.len() {
        for b in a + 2..placed.len() {
            best = best.min(signed_distance(&placed[a], &placed[b]));
        }
        best = best.min(signed_distance(&placed[a], keep));
    }
    best
}

/// Verifies RL-COLL-008: the clearance a rollout reports is never above the distance the
/// straight joint path between its samples attains (10 points per step, by an independent
/// forward kinematics), and is below the smallest of them by at most the step motion.
#[test]
fn the_step_bound_is_below_the_path_between_samples() {
    let plain = task();
    let mut samples = Vec::new();
    run(&plain, &mut samples);
    // A keep-out ball across the path at its middle sample's wrist.
    let mid = samples[samples.len() / 2].q;
    let f = Frames::new(plain.robot(), &mid);
    let wrist = plain.com0() + (f.links[5].joint - f.com);
    let keep_at = [wrist.x, wrist.y, wrist.z + 0.3];
    let geo = plain
        .clone()
        .with_collision(set(plain.robot(), 0.0, keep_at, 0.1))
        .unwrap();
    let mut again = Vec::new();
    let o = run(&geo, &mut again);
    assert_eq!(again, samples, "geometry changes no sample");
    let keep = at(Shape::Sphere { radius: 0.1 }, keep_at);
    let mut dense = f64::INFINITY;
    for w in samples.windows(2) {
        for k in 0..=10 {
            let s = f64::from(k) / 10.0;
            let q: [f64; 7] = std::array::from_fn(|j| w[0].q[j] + s * (w[1].q[j] - w[0].q[j]));
            dense = dense.min(distances(plain.robot(), &plain.com0(), &q, &keep));
        }
    }
    assert!(o.clearance.is_finite());
    assert!(
        o.clearance <= dense + 1e-12,
        "bound {} above the path's {dense}",
        o.clearance
    );
    assert!(
        dense - o.clearance < 0.01,
        "bound {} far below {dense}",
        o.clearance
    );
    eprintln!("bound {:.6} m, dense {dense:.6} m", o.clearance);
}

/// Verifies RL-COLL-009: a shortfall below the required clearance is constraint violation
/// (Φ grows by it, 1 rad per m), and a path above the limit reports the limit.
#[test]
fn the_shortfall_is_part_of_phi() {
    let plain = task();
    let none = run(&plain, &mut Vec::new());
    assert_eq!(none.clearance, f64::INFINITY);
    // Far away: the limit (required + margin) is reported and Φ is unchanged.
    let far = plain
        .clone()
        .with_collision(set(plain.robot(), 0.0, [30.0, 0.0, 0.0], 0.1))
        .unwrap();
    let o = run(&far, &mut Vec::new());
    assert_eq!(o.phi.to_bits(), none.phi.to_bits());
    // Self pairs alone decide it here; the limit caps what is reported.
    assert!(o.clearance <= 0.005);
    // Required clearance 1 m: every path falls short, by exactly what Φ adds.
    let strict = plain
        .clone()
        .with_collision(set(plain.robot(), 1.0, [30.0, 0.0, 0.0], 0.1))
        .unwrap();
    let o = run(&strict, &mut Vec::new());
    let shortfall = 1.0 - o.clearance;
    assert!(shortfall > 0.0);
    assert_eq!(o.phi, none.phi + shortfall);
    assert_eq!(o.f.to_bits(), none.f.to_bits());
}

/// Verifies RL-COLL-010: an empty set leaves a task's rollouts bit for bit, a rollout in
/// slices of any size gives the clearance of one in a single call, and what does not
/// evaluate geometry (lanes, RK4) refuses a task with it.
#[test]
fn empty_sets_slices_and_refusals() {
    let plain = task();
    let empty = plain.clone().with_collision(CollisionSet::EMPTY).unwrap();
    assert_eq!(empty, plain);
    let geo = plain
        .clone()
        .with_collision(set(plain.robot(), 0.02, [2.0, 0.0, -1.5], 0.2))
        .unwrap();
    let whole = run(&geo, &mut Vec::new());
    for budget in [1, 7, 1000] {
        let mut r = Rollout::new(&geo, &ETA).unwrap();
        let o = loop {
            match r.advance(&geo, budget, &mut ()).unwrap() {
                Progress::Done(o) => break o,
                Progress::Running { .. } => {}
                Progress::Abandoned { .. } => panic!("no cap"),
            }
        };
        assert_eq!(o.clearance.to_bits(), whole.clearance.to_bits());
        assert_eq!(o.phi.to_bits(), whole.phi.to_bits());
    }
    // Lanes and RK4 do not evaluate geometry: refused, not ignored.
    let mut batch = Batch::<7, 4, 4>::new(&geo);
    assert_eq!(
        batch.load(0, &geo, &ETA, f64::INFINITY),
        Err(Error::NeedsScalarEuler)
    );
    let rk4 = Task::<7, 4>::new(
        plain.robot().clone(),
        *plain.start(),
        *plain.target(),
        Motion::new(30.0, 0.01, 1)
            .unwrap()
            .with_integrator(Integrator::Rk4)
            .unwrap(),
    )
    .unwrap();
    let s = set(plain.robot(), 0.0, [30.0, 0.0, 0.0], 0.1);
    assert_eq!(rk4.with_collision(s).err(), Some(Error::NeedsScalarEuler));
}

/// Verifies RL-COLL-011: bad geometry is refused with a typed error naming what was wrong.
#[test]
fn bad_geometry_is_refused() {
    let robot = Robot::new(&CHASER7).unwrap();
    assert!(CollisionSet::<7>::new(-0.1, 0.0).is_err());
    assert!(CollisionSet::<7>::new(0.0, f64::NAN).is_err());
    let mut s = CollisionSet::<7>::new(0.0, 0.0).unwrap();
    let bad = at(Shape::Sphere { radius: -1.0 }, [0.0; 3]);
    assert!(matches!(
        s.add_primitive(&robot, 1, &bad),
        Err(Error::Negative(reactionless::Param::Collider(1)))
    ));
    let ball = at(Shape::Sphere { radius: 0.1 }, [0.0; 3]);
    assert!(
        s.add_primitive(&robot, 8, &ball).is_err(),
        "no body 8 on 7 joints"
    );
    let mut nan = ball;
    nan.pos.x = f64::NAN;
    assert!(s.add_keep_out(&nan).is_err());
    assert!(
        s.ignore(Side::Body(1), Side::KeepOut(0)).is_err(),
        "no keep-out yet"
    );
    assert!(
        s.ignore(Side::Body(1), Side::Body(16)).is_err(),
        "beyond the capacity"
    );
    for _ in 0..MAX_KEEP_OUTS {
        s.add_keep_out(&ball).unwrap();
    }
    assert!(matches!(
        s.add_keep_out(&ball),
        Err(Error::CapacityExceeded { .. })
    ));
}

/// Verifies RL-COLL-011: the pairs are spec §13's, less the ignored ones, in either order.
#[test]
fn ignored_pairs_are_not_checked() {
    let robot = Robot::new(&CHASER7).unwrap();
    let mut s = set(&robot, 0.0, [30.0, 0.0, 0.0], 0.1);
    s.ignore(Side::Body(2), Side::Body(0)).unwrap();
    assert_eq!(s.pair_count(), 28);
    s.ignore(Side::Body(0), Side::Body(2)).unwrap();
    assert_eq!(s.pair_count(), 28, "the same pair");
    s.ignore(Side::KeepOut(0), Side::Body(3)).unwrap();
    assert_eq!(s.pair_count(), 27);
    // Adjacent bodies are never checked; ignoring them changes nothing.
    s.ignore(Side::Body(3), Side::Body(4)).unwrap();
    assert_eq!(s.pair_count(), 27);
    assert!(s.ignore(Side::KeepOut(0), Side::KeepOut(0)).is_err());
}
