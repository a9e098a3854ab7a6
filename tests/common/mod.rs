//! Shared fixtures of the integration tests: the reference task of spec §8.
#![allow(
    dead_code,
    unused_imports,
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::indexing_slicing,
    clippy::needless_range_loop
)]

use reactionless::{CHASER7, Outcome, Robot, Task};

pub use reactionless::reference::{ETA_HAT, Q0_DEG, TARGET};

pub fn q0() -> [f64; 7] {
    Q0_DEG.map(f64::to_radians)
}

pub fn robot() -> Robot<7> {
    Robot::new(&CHASER7).unwrap()
}

/// The reference task of spec §8.
pub fn paper_task() -> Task<7, 4> {
    reactionless::reference::paper_task().unwrap()
}

/// `|a − b| ≤ tol` element-wise, with a message naming the quantity.
pub fn assert_close(what: &str, got: &[f64], want: &[f64], tol: f64) {
    assert_eq!(got.len(), want.len(), "{what}: length");
    for (i, (g, w)) in got.iter().zip(want).enumerate() {
        assert!(
            (g - w).abs() <= tol,
            "{what}[{i}]: got {g:.17e}, want {w:.17e}, |diff| = {:.3e} > {tol:e}",
            (g - w).abs()
        );
    }
}

use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, Unit, UnitQuaternion, Vector3};
use rand::{Rng, SeedableRng, rngs::StdRng};
use reactionless::{BodyDesc, Inertia, JointDesc, Origin, RobotDesc};

/// A seeded RNG for reproducible random tests.
pub fn rng(seed: u64) -> StdRng {
    StdRng::seed_from_u64(seed)
}

fn random_unit(rng: &mut StdRng) -> [f64; 3] {
    loop {
        let v: Vector3<f64> = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.2 && n < 1.0 {
            let u = v / n;
            return [u.x, u.y, u.z];
        }
    }
}

fn random_rpy(rng: &mut StdRng) -> [f64; 3] {
    [
        rng.random_range(-3.1..3.1),
        rng.random_range(-1.5..1.5),
        rng.random_range(-3.1..3.1),
    ]
}

/// A physically valid inertia (principal moments obey the triangle inequality), rotated
/// so that it has products of inertia.
fn random_body(rng: &mut StdRng, mass: f64, size: f64) -> BodyDesc {
    let a: f64 = rng.random_range(0.2..1.0) * mass * size * size;
    let b: f64 = rng.random_range(0.2..1.0) * mass * size * size;
    let c: f64 = rng.random_range((a - b).abs() + 1e-3 * a..a + b);
    let r = Rotation3::from_euler_angles(
        rng.random_range(-3.0..3.0),
        rng.random_range(-1.5..1.5),
        rng.random_range(-3.0..3.0),
    );
    let m = r.matrix() * Matrix3::from_diagonal(&Vector3::new(a, b, c)) * r.matrix().transpose();
    BodyDesc {
        mass,
        inertial: Origin {
            xyz: [
                rng.random_range(-0.3..0.3) * size,
                rng.random_range(-0.3..0.3) * size,
                rng.random_range(-0.3..0.3) * size,
            ],
            rpy: random_rpy(rng),
        },
        inertia: Inertia {
            ixx: m[(0, 0)],
            ixy: m[(0, 1)],
            ixz: m[(0, 2)],
            iyy: m[(1, 1)],
            iyz: m[(1, 2)],
            izz: m[(2, 2)],
        },
    }
}

/// A random N-joint robot: non-zero origin rpy, arbitrary unit axes, full inertia tensors
/// with rotated inertial frames.
pub fn random_robot<const N: usize>(rng: &mut StdRng) -> RobotDesc<N> {
    let m = rng.random_range(300.0..1500.0);
    let base = random_body(rng, m, 1.5);
    let joints = core::array::from_fn(|_| JointDesc {
        origin: Origin {
            xyz: [
                rng.random_range(0.1..1.0),
                rng.random_range(-0.3..0.3),
                rng.random_range(-0.3..0.3),
            ],
            rpy: random_rpy(rng),
        },
        axis: random_unit(rng),
        lower: rng.random_range(-3.0..-1.5),
        upper: rng.random_range(1.5..3.0),
        velocity: rng.random_range(0.1..0.5),
    });
    let links = core::array::from_fn(|_| {
        let m = rng.random_range(2.0..30.0);
        random_body(rng, m, 0.6)
    });
    RobotDesc {
        base,
        joints,
        links,
        end_effector: Origin {
            xyz: [0.1, 0.02, -0.03],
            rpy: random_rpy(rng),
        },
    }
}

/// A random configuration strictly inside the limits of `d`.
pub fn random_q<const N: usize>(rng: &mut StdRng, d: &RobotDesc<N>) -> [f64; N] {
    core::array::from_fn(|i| {
        let j = &d.joints[i];
        rng.random_range(j.lower * 0.9..j.upper * 0.9)
    })
}

fn iso(o: &Origin) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(o.xyz[0], o.xyz[1], o.xyz[2]),
        UnitQuaternion::from_euler_angles(o.rpy[0], o.rpy[1], o.rpy[2]),
    )
}

/// Independent forward kinematics straight from the URDF conventions (nalgebra
/// isometries, std math): per body (base first) its world CoM, world inertia about the
/// CoM and attitude; plus the end-effector isometry. Base at `base`.
pub struct NaiveFk {
    pub com: Vec<Vector3<f64>>,
    pub inertia: Vec<Matrix3<f64>>,
    pub mass: Vec<f64>,
    pub ee: Isometry3<f64>,
}

pub fn naive_fk<const N: usize>(d: &RobotDesc<N>, q: &[f64; N], base: &Isometry3<f64>) -> NaiveFk {
    let body = |t: &Isometry3<f64>, b: &BodyDesc| {
        let frame = t * iso(&b.inertial);
        let i = &b.inertia;
        let local = Matrix3::new(
            i.ixx, i.ixy, i.ixz, i.ixy, i.iyy, i.iyz, i.ixz, i.iyz, i.izz,
        );
        let r = frame.rotation.to_rotation_matrix();
        (
            frame.translation.vector,
            r.matrix() * local * r.matrix().transpose(),
        )
    };
    let mut out = NaiveFk {
        com: vec![],
        inertia: vec![],
        mass: vec![],
        ee: Isometry3::identity(),
    };
    let (c, i) = body(base, &d.base);
    out.com.push(c);
    out.inertia.push(i);
    out.mass.push(d.base.mass);
    let mut t = *base;
    for k in 0..N {
        let j = &d.joints[k];
        let axis = Unit::new_normalize(Vector3::from(j.axis));
        t = t
            * iso(&j.origin)
            * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&axis, q[k]),
            );
        let (c, i) = body(&t, &d.links[k]);
        out.com.push(c);
        out.inertia.push(i);
        out.mass.push(d.links[k].mass);
    }
    out.ee = t * iso(&d.end_effector);
    out
}

impl NaiveFk {
    pub fn system_com(&self) -> Vector3<f64> {
        let m: f64 = self.mass.iter().sum();
        self.com
            .iter()
            .zip(&self.mass)
            .map(|(c, m)| c * *m)
            .sum::<Vector3<f64>>()
            / m
    }
}

/// Attitude of each body's link frame (base first) for joint values `q` and base pose
/// `base`, from the naive URDF chain.
pub fn body_rotations<const N: usize>(
    d: &RobotDesc<N>,
    q: &[f64; N],
    base: &Isometry3<f64>,
) -> Vec<Matrix3<f64>> {
    let mut out = vec![*base.rotation.to_rotation_matrix().matrix()];
    let mut t = *base;
    for k in 0..N {
        let j = &d.joints[k];
        let axis = Unit::new_normalize(Vector3::from(j.axis));
        t = t
            * iso(&j.origin)
            * Isometry3::from_parts(
                Translation3::identity(),
                UnitQuaternion::from_axis_angle(&axis, q[k]),
            );
        out.push(*t.rotation.to_rotation_matrix().matrix());
    }
    out
}

/// The bit patterns of every value of a rollout's outcome, for bit-for-bit comparisons.
pub fn outcome_bits<const N: usize>(o: &Outcome<N>) -> Vec<u64> {
    o.q_final
        .iter()
        .chain(&o.joint_min)
        .chain(&o.joint_max)
        .chain(&o.end_pose.position)
        .chain(&o.end_pose.quat_wxyz)
        .chain(&[o.phi, o.f, o.g, o.max_abs_qd])
        .map(|v| v.to_bits())
        .collect()
}
