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

use crate::geometry::{Mat3, Pose, Vec3, mat_mul, mat_vec, mul_rx, mul_rz, quat_matrix};
use crate::model::Robot;

/// Attitude (joint frame, `z` = joint axis) and positions of one link, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkFrame {
    /// Joint-frame attitude: its third column is the joint axis `k_i`.
    pub(crate) rot: Mat3,
    /// Joint position `p_i` (m): a point on the joint axis.
    pub joint: Vec3,
    /// Link centre of mass `c_i` (m).
    pub com: Vec3,
}

impl LinkFrame {
    /// Unit joint axis `k_i` (base frame).
    #[inline]
    #[must_use]
    pub fn axis(&self) -> Vec3 {
        Vec3::new(self.rot.m13, self.rot.m23, self.rot.m33)
    }
}

/// Forward kinematics of configuration `q`, in the base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frames<const N: usize> {
    /// Links `1..=N`.
    pub links: [LinkFrame; N],
    /// Base centre of mass (m).
    pub base_com: Vec3,
    /// System centre of mass `r_g` (m).
    pub com: Vec3,
    /// End-effector position (m).
    pub ee_position: Vec3,
    /// End-effector attitude.
    pub ee_rotation: Mat3,
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

    /// All zeros, identity attitudes: a placeholder to [`Frames::update`].
    pub(crate) const IDLE: Self = Self {
        links: [LinkFrame {
            rot: Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
            joint: Vec3::new(0.0, 0.0, 0.0),
            com: Vec3::new(0.0, 0.0, 0.0),
        }; N],
        base_com: Vec3::new(0.0, 0.0, 0.0),
        com: Vec3::new(0.0, 0.0, 0.0),
        ee_position: Vec3::new(0.0, 0.0, 0.0),
        ee_rotation: Mat3::new(1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0),
    };

    /// Recomputes `self` for configuration `q` (rad), in place.
    #[inline(always)]
    fn update(&mut self, robot: &Robot<N>, q: &[f64; N]) {
        let (r_last, p_last) = self.update_chain(robot, q);
        self.ee_position = p_last + mat_vec(&r_last, &robot.ee_offset);
        self.ee_rotation = mat_mul(&r_last, &robot.ee_rot);
    }

    /// Recomputes everything but the end-effector fields (left as they were) for `q`
    /// (rad), in place, and returns the last joint frame's attitude and position: the
    /// rollout's hot path, which needs only the links and the centre of mass, reuses one
    /// `Frames` instead of building and moving a new one every step.
    #[inline(always)]
    pub(crate) fn update_chain(&mut self, robot: &Robot<N>, q: &[f64; N]) -> (Mat3, Vec3) {
        // All sincos calls first: a call clobbers every float register, so keeping them out
        // of the recursion below lets the carried frame stay in registers.
        let mut trig = [(0.0, 1.0); N];
        for ((t, qi), seg) in trig.iter_mut().zip(q.iter()).zip(robot.segments.iter()) {
            *t = libm::sincos(qi + seg.theta);
        }
        let mut r_prev = robot.root;
        let mut p_prev = Vec3::zeros();
        let mut moment = robot.base_com * robot.base_mass;
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
            moment += com * seg.mass;
            link.rot = r;
            link.joint = p;
            link.com = com;
            r_prev = r;
            p_prev = p;
        }
        self.base_com = robot.base_com;
        self.com = moment / robot.total_mass();
        (r_prev, p_prev)
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

/// The identity attitude `[1, 0, 0, 0]`.
pub const IDENTITY_WXYZ: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
