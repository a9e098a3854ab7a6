//! Forward kinematics of the free-floating chain, the system centre of mass, and the
//! end-effector pose with the base moved by centre-of-mass conservation (spec §1).
//!
//! Owns [`Frames`]: for a joint configuration `q` (rad), every joint's position and axis,
//! every link's centre of mass and attitude, the system centre of mass `r_g` and the
//! end-effector pose, all in the **base frame** (base at the origin, identity attitude).
//! Inertial-frame quantities follow from a base pose: with base attitude `R₀`, every point
//! `x` of the base frame is at `p₀ + R₀ x`, and linear-momentum conservation fixes
//! `p₀ = r_g(0) − R₀ r_g(q)` (the system CoM never moves, [`Frames::end_pose`]).
//!
//! Cost per joint: one `sincos`, two column-pair rotations (`Rx` of the twist, `Rz` of the
//! joint angle) and two 3×3·vector products.

use crate::geometry::{Pose, Vec3, mat_mul, mat_vec, mul_rx, mul_rz, quat_matrix, splat3, splat33};
use crate::lanes::Real;
use crate::model::Robot;
use nalgebra::{Matrix3, Vector3};

/// Attitude (joint frame, `z` = joint axis) and positions of one link, base frame (`f64`,
/// or [`Real`] lanes in the rollout's hot path).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkFrame<T = f64> {
    /// Joint-frame attitude: its third column is the joint axis `k_i`.
    pub(crate) rot: Matrix3<T>,
    /// Joint position `p_i` (m): a point on the joint axis.
    pub joint: Vector3<T>,
    /// Link centre of mass `c_i` (m).
    pub com: Vector3<T>,
}

impl<T: Real> LinkFrame<T> {
    /// Unit joint axis `k_i` (base frame).
    #[inline(always)]
    #[must_use]
    pub fn axis(&self) -> Vector3<T> {
        Vector3::new(self.rot.m13, self.rot.m23, self.rot.m33)
    }
}

/// Forward kinematics of configuration `q`, in the base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frames<const N: usize, T = f64> {
    /// Links `1..=N`.
    pub links: [LinkFrame<T>; N],
    /// Base centre of mass (m).
    pub base_com: Vector3<T>,
    /// System centre of mass `r_g` (m).
    pub com: Vector3<T>,
    /// End-effector position (m).
    pub ee_position: Vector3<T>,
    /// End-effector attitude.
    pub ee_rotation: Matrix3<T>,
}

impl<const N: usize> Frames<N> {
    /// Forward kinematics at `q` (rad).
    ///
    /// Verifies RL-MODEL-001.
    ///
    /// ```
    /// use reactionless::{CHASER7, Frames, Robot};
    /// let robot = Robot::new(&CHASER7).unwrap();
    /// let f = Frames::new(&robot, &[0.0; 7]);
    /// // Stretched along +x from the shoulder at (1, 0, 0.5): 0.113+1.325+…+0.04 m.
    /// assert!((f.ee_position.x - (1.0 + 2.814)).abs() < 1e-12);
    /// ```
    #[inline(always)]
    #[must_use]
    pub fn new(robot: &Robot<N>, q: &[f64; N]) -> Self {
        let mut f = Self::IDLE;
        f.update(robot, q);
        f
    }

    /// Recomputes `self` for configuration `q` (rad), in place.
    #[inline(always)]
    fn update(&mut self, robot: &Robot<N>, q: &[f64; N]) {
        let (r_last, p_last) = self.update_chain(robot, q);
        self.ee_position = p_last + mat_vec(&r_last, &robot.ee_offset);
        self.ee_rotation = mat_mul(&r_last, &robot.ee_rot);
    }

    /// End-effector pose in the inertial frame for base attitude `base_wxyz` (unit
    /// quaternion, base → inertial), with the base placed so that the system CoM is at
    /// `com0` (m, inertial frame; its position at `t = 0`).
    ///
    /// The planner model uses the identity attitude (the reactionless assumption); the
    /// truth model passes the integrated base attitude.
    #[must_use]
    pub fn end_pose(&self, com0: &Vec3, base_wxyz: [f64; 4]) -> Pose {
        let r0 = quat_matrix(base_wxyz);
        let p = com0 + r0 * (self.ee_position - self.com);
        Pose::from_parts(&p, &(r0 * self.ee_rotation))
    }

    /// End-effector pose with base at the origin, identity attitude (m).
    #[must_use]
    pub fn ee_pose(&self) -> Pose {
        Pose::from_parts(&self.ee_position, &self.ee_rotation)
    }
}

impl<const N: usize, T: Real> Frames<N, T> {
    /// All zeros, identity attitudes: a placeholder to [`Frames::update`].
    pub(crate) const IDLE: Self = {
        let (o, i) = (T::ZERO, T::ONE);
        Self {
            links: [LinkFrame {
                rot: Matrix3::new(i, o, o, o, i, o, o, o, i),
                joint: Vector3::new(o, o, o),
                com: Vector3::new(o, o, o),
            }; N],
            base_com: Vector3::new(o, o, o),
            com: Vector3::new(o, o, o),
            ee_position: Vector3::new(o, o, o),
            ee_rotation: Matrix3::new(i, o, o, o, i, o, o, o, i),
        }
    };

    /// Recomputes everything but the end-effector fields (left as they were) for `q`
    /// (rad), in place, and returns the last joint frame's attitude and position: the
    /// rollout's hot path, which needs only the links and the centre of mass, reuses one
    /// `Frames` instead of building and moving a new one every step.
    #[inline(always)]
    pub(crate) fn update_chain(
        &mut self,
        robot: &Robot<N>,
        q: &[T; N],
    ) -> (Matrix3<T>, Vector3<T>) {
        // All sincos calls first: a call clobbers every float register, so keeping them out
        // of the recursion below lets the carried frame stay in registers.
        let mut trig = [(T::ZERO, T::ONE); N];
        for ((t, qi), seg) in trig.iter_mut().zip(q.iter()).zip(robot.segments.iter()) {
            *t = (*qi + seg.theta).sincos();
        }
        let mut r_prev: Matrix3<T> = splat33(&robot.root);
        let mut p_prev = Vector3::<T>::zeros();
        let mut moment: Vector3<T> = splat3(&(robot.base_com * robot.base_mass));
        let items = self
            .links
            .iter_mut()
            .zip(robot.segments.iter())
            .zip(trig.iter());
        for ((link, seg), &(s, c)) in items {
            let p = p_prev + mat_vec(&r_prev, &seg.offset);
            let (sb, cb) = seg.twist;
            let r = mul_rz(&mul_rx(&r_prev, sb, cb), s, c);
            let com = p + mat_vec(&r, &seg.com);
            moment += com * T::splat(seg.mass);
            link.rot = r;
            link.joint = p;
            link.com = com;
            r_prev = r;
            p_prev = p;
        }
        self.base_com = splat3(&robot.base_com);
        self.com = moment / T::splat(robot.total_mass());
        (r_prev, p_prev)
    }
}

/// The identity attitude `[1, 0, 0, 0]`.
pub const IDENTITY_WXYZ: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
