//! The robot description: bodies, joints and limits, from plain data, validated once.
//!
//! Owns [`RobotDesc`] (plain, URDF-shaped data a user or a loader fills in), [`Robot`] (the
//! validated, immutable model the rest of the core reads) and [`CHASER7`], the reference
//! robot of the specification (`spec/chaser7.urdf`).
//!
//! Conventions (URDF): joint `i` sits at `origin` (xyz in m, rpy in rad) in the frame of
//! body `i − 1` (body 0 is the base) and rotates body `i` about `axis` (a unit vector in the
//! joint frame). A body's mass properties are given at its inertial origin (xyz, rpy) in its
//! own frame; the inertia tensor (kg m²) is about the centre of mass in the inertial frame.
//! The end effector is a massless frame fixed to the last link.
//!
//! Internally each link is carried in a *joint frame* whose `z` axis is the joint axis, so
//! that forward kinematics needs one constant rotation and one rotation about `z` per joint;
//! see [`crate::kinematics`].

use crate::error::{Body, Error, Param};
use crate::geometry::{
    Mat3, Sym3, Vec3, ZERO3, ZERO33, frame_with_z, rot_z, rpy_matrix, zxz_angles,
};
use crate::lanes::Real;

/// Tolerance on the norm of unit vectors and quaternions in inputs: `|‖v‖ − 1| ≤ 1e-6`.
pub const UNIT_TOLERANCE: f64 = 1e-6;

/// A rigid transform as URDF writes it: translation (m) then roll-pitch-yaw (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Origin {
    /// Translation (m) in the parent frame.
    pub xyz: [f64; 3],
    /// Roll, pitch, yaw (rad): `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
    pub rpy: [f64; 3],
}

impl Origin {
    /// The identity transform.
    pub const IDENTITY: Self = Self {
        xyz: [0.0; 3],
        rpy: [0.0; 3],
    };

    /// Rotation part as a matrix.
    #[must_use]
    pub fn rotation(&self) -> Mat3 {
        rpy_matrix(self.rpy)
    }

    /// Translation part as a vector (m).
    #[must_use]
    pub fn translation(&self) -> Vec3 {
        Vec3::from(self.xyz)
    }

    fn is_finite(&self) -> bool {
        self.xyz
            .iter()
            .chain(self.rpy.iter())
            .all(|v| v.is_finite())
    }
}

/// Inertia tensor entries (kg m²) about the centre of mass, URDF names.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[allow(missing_docs)]
pub struct Inertia {
    pub ixx: f64,
    pub ixy: f64,
    pub ixz: f64,
    pub iyy: f64,
    pub iyz: f64,
    pub izz: f64,
}

impl Inertia {
    /// All zeros (a placeholder, not a valid tensor).
    pub const ZERO: Self = Self::diagonal(0.0, 0.0, 0.0);

    /// Diagonal tensor `diag(ixx, iyy, izz)`.
    #[must_use]
    pub const fn diagonal(ixx: f64, iyy: f64, izz: f64) -> Self {
        Self {
            ixx,
            ixy: 0.0,
            ixz: 0.0,
            iyy,
            iyz: 0.0,
            izz,
        }
    }

    /// As a symmetric matrix.
    #[must_use]
    pub fn to_sym(&self) -> Sym3 {
        Sym3 {
            xx: self.ixx,
            yy: self.iyy,
            zz: self.izz,
            xy: self.ixy,
            xz: self.ixz,
            yz: self.iyz,
        }
    }
}

/// Mass properties of one rigid body, URDF `<inertial>`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BodyDesc {
    /// Mass (kg), > 0.
    pub mass: f64,
    /// Inertial frame in the body frame: centre of mass (m) and tensor axes (rad).
    pub inertial: Origin,
    /// Inertia about the centre of mass in the inertial frame (kg m²), positive definite.
    pub inertia: Inertia,
}

/// One revolute joint, URDF `<joint type="revolute">`.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct JointDesc {
    /// Joint frame in the parent body's frame.
    pub origin: Origin,
    /// Rotation axis in the joint frame, unit length (within [`UNIT_TOLERANCE`]).
    pub axis: [f64; 3],
    /// Lower position limit (rad).
    pub lower: f64,
    /// Upper position limit (rad), > `lower`.
    pub upper: f64,
    /// Velocity limit (rad/s), > 0.
    pub velocity: f64,
}

/// Plain-data description of a free-floating base with an `N`-joint serial arm.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RobotDesc<const N: usize> {
    /// The free-floating base (body 0). Its frame is the inertial frame at `t = 0`.
    pub base: BodyDesc,
    /// Joints `1..=N`, base to tip.
    pub joints: [JointDesc; N],
    /// Links `1..=N`; link `i` is moved by joint `i`.
    pub links: [BodyDesc; N],
    /// End-effector frame in link `N`'s frame (massless).
    pub end_effector: Origin,
}

/// A link, expressed in its joint frame (`z` = joint axis).
///
/// Joint frames are chosen DH-style: the rotation from joint frame `i − 1` to joint frame
/// `i` at `q = 0` is `Rx(b_i)·Rz(θ_i)`, so forward kinematics applies two column-pair
/// rotations per joint instead of a full 3×3 product.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Segment {
    /// `(sin b_i, cos b_i)`: the twist between joint axes `i − 1` and `i`.
    pub(crate) twist: (f64, f64),
    /// Offset `θ_i` (rad) added to `q_i`.
    pub(crate) theta: f64,
    /// Joint position in the previous joint frame (m): `Q_{i−1}ᵀ · xyz`.
    pub(crate) offset: Vec3,
    /// Link mass (kg).
    pub(crate) mass: f64,
    /// Link centre of mass in the joint frame (m).
    pub(crate) com: Vec3,
    /// Cholesky factor `L` of the link inertia about its centre of mass, joint-frame axes
    /// (`I = L·Lᵀ`, kg m²; lower-triangular).
    pub(crate) inertia: Mat3,
}

/// A validated robot model. Immutable; construct with [`Robot::new`].
#[derive(Debug, Clone, PartialEq)]
pub struct Robot<const N: usize> {
    desc: RobotDesc<N>,
    pub(crate) segments: [Segment; N],
    /// Attitude of joint frame 0 in the base frame (a rotation about the base `z`).
    pub(crate) root: Mat3,
    /// Base mass (kg).
    pub(crate) base_mass: f64,
    /// Base centre of mass in the base frame (m).
    pub(crate) base_com: Vec3,
    /// Base inertia about its centre of mass, base-frame axes (kg m²).
    pub(crate) base_inertia: Sym3,
    /// End-effector position in joint frame `N` (m).
    pub(crate) ee_offset: Vec3,
    /// End-effector attitude relative to joint frame `N`.
    pub(crate) ee_rot: Mat3,
    total_mass: f64,
    lower: [f64; N],
    upper: [f64; N],
    qd_max: f64,
}

impl<const N: usize> Robot<N> {
    /// All zeros: not a usable model, a placeholder for statically allocated planners
    /// (see [`crate::Planner::IDLE`]).
    pub const IDLE: Self = {
        let body = BodyDesc {
            mass: 0.0,
            inertial: Origin::IDENTITY,
            inertia: Inertia::ZERO,
        };
        Self {
            desc: RobotDesc {
                base: body,
                joints: [JointDesc {
                    origin: Origin::IDENTITY,
                    axis: [0.0; 3],
                    lower: 0.0,
                    upper: 0.0,
                    velocity: 0.0,
                }; N],
                links: [body; N],
                end_effector: Origin::IDENTITY,
            },
            segments: [Segment {
                twist: (0.0, 0.0),
                theta: 0.0,
                offset: ZERO3,
                mass: 0.0,
                com: ZERO3,
                inertia: ZERO33,
            }; N],
            root: ZERO33,
            base_mass: 0.0,
            base_com: ZERO3,
            base_inertia: Sym3::ZERO,
            ee_offset: ZERO3,
            ee_rot: ZERO33,
            total_mass: 0.0,
            lower: [0.0; N],
            upper: [0.0; N],
            qd_max: 0.0,
        }
    };

    /// Validates `desc` and precomputes the joint frames.
    ///
    /// # Errors
    /// A typed error naming the first bad parameter: non-finite numbers, non-positive
    /// masses or velocity limits, inertia tensors that are not positive definite, axes that
    /// are not unit vectors, `lower ≥ upper`.
    ///
    /// Verifies RL-MODEL-003.
    ///
    /// ```
    /// use reactionless::{CHASER7, Robot};
    /// let robot = Robot::new(&CHASER7).unwrap();
    /// assert!((robot.total_mass() - 1093.0).abs() < 1e-12);
    /// ```
    pub fn new(desc: &RobotDesc<N>) -> Result<Self, Error> {
        let mut r = Self::IDLE;
        r.init(desc)?;
        Ok(r)
    }

    /// Validates `desc` and builds the model in place, exactly as [`Robot::new`] would (no
    /// model-sized temporaries: flight software keeps models in static memory).
    ///
    /// # Errors
    /// As [`Robot::new`]; the model is then unusable until a successful `init`.
    pub fn init(&mut self, desc: &RobotDesc<N>) -> Result<(), Error> {
        const { assert!(N >= 1 && N <= 255, "joint count must be in 1..=255") };
        let (base_mass, base_com, base_inertia) = validate_body(&desc.base, Body::Base)?;
        let mut qd_max = f64::INFINITY;
        let mut total_mass = base_mass;
        let (frames, zxz) = joint_frames(desc)?;
        // Pass 2: turn each joint frame about its axis by φ_i = a_{i+1} (φ_N = 0), which
        // leaves C'_i = Rz(−φ_{i−1}) C_i Rz(φ_i) = Rx(b_i) Rz(c_i + φ_i).
        let first_a = zxz.first().map_or(0.0, |z| z.0);
        let root = rot_z(first_a);
        let mut q_prev = root;
        let items = desc
            .joints
            .iter()
            .zip(desc.links.iter())
            .zip(self.segments.iter_mut())
            .zip(self.lower.iter_mut().zip(self.upper.iter_mut()))
            .zip(frames.iter().zip(zxz.iter()))
            .enumerate();
        for (i, ((((joint, link), seg), (lo, up)), (frame, &(_, b, c)))) in items {
            let j = (i + 1) as u8;
            let (mass, com, inertia) = validate_body(link, Body::Link(j))?;
            let q_this = frame * rot_z(zxz.get(i + 1).map_or(0.0, |z| z.0));
            let q_this_t = q_this.transpose();
            *seg = Segment {
                twist: libm::sincos(b),
                theta: c + zxz.get(i + 1).map_or(0.0, |z| z.0),
                offset: q_prev.transpose() * joint.origin.translation(),
                mass,
                com: q_this_t * com,
                inertia: inertia
                    .rotated(&q_this_t)
                    .cholesky()
                    .ok_or(Error::InertiaNotPositiveDefinite(Body::Link(j)))?,
            };
            *lo = joint.lower;
            *up = joint.upper;
            qd_max = qd_max.min(joint.velocity);
            total_mass += mass;
            q_prev = q_this;
        }
        if !desc.end_effector.is_finite() {
            return Err(Error::NotFinite(Param::EndEffector));
        }
        let q_last_t = q_prev.transpose();
        self.desc = *desc;
        self.root = root;
        self.base_mass = base_mass;
        self.base_com = base_com;
        self.base_inertia = base_inertia;
        self.ee_offset = q_last_t * desc.end_effector.translation();
        self.ee_rot = q_last_t * desc.end_effector.rotation();
        self.total_mass = total_mass;
        self.qd_max = qd_max;
        Ok(())
    }

    /// The description this model was built from.
    #[must_use]
    pub fn desc(&self) -> &RobotDesc<N> {
        &self.desc
    }

    /// Total mass of base and links (kg).
    #[must_use]
    pub fn total_mass(&self) -> f64 {
        self.total_mass
    }

    /// Lower joint limits (rad).
    #[must_use]
    pub fn lower(&self) -> &[f64; N] {
        &self.lower
    }

    /// Upper joint limits (rad).
    #[must_use]
    pub fn upper(&self) -> &[f64; N] {
        &self.upper
    }

    /// `q̇_max`: the smallest joint velocity limit (rad/s), the bound of eq. 14.
    #[must_use]
    pub fn qd_max(&self) -> f64 {
        self.qd_max
    }

    /// Constraint violation Φ of eq. 23 for joint extrema `q_min`, `q_max` (rad).
    #[must_use]
    pub fn violation(&self, q_min: &[f64; N], q_max: &[f64; N]) -> f64 {
        self.violation_of(q_min, q_max)
    }

    /// [`Robot::violation`] of one rollout's extrema (`f64`) or of several side by side
    /// ([`Real`] lanes): the same sum, in the same order, per lane.
    #[inline(always)]
    pub(crate) fn violation_of<T: Real>(&self, q_min: &[T; N], q_max: &[T; N]) -> T {
        let mut phi = T::ZERO;
        for (((lo, hi), mn), mx) in self
            .lower
            .iter()
            .zip(self.upper.iter())
            .zip(q_min.iter())
            .zip(q_max.iter())
        {
            phi += (*mx - *hi).max(T::ZERO) + (T::splat(*lo) - *mn).max(T::ZERO);
        }
        phi
    }
}

/// Pass 1 of [`Robot::init`]: a joint frame `Q_i` per joint (`z` on the axis, in URDF
/// link frame `i`'s axes; `Q_0` = base frame) and the ZXZ angles of
/// `C_i = Q_{i−1}ᵀ R_origin Q_i = Rz(a_i) Rx(b_i) Rz(c_i)`.
#[allow(clippy::type_complexity)]
fn joint_frames<const N: usize>(
    desc: &RobotDesc<N>,
) -> Result<([Mat3; N], [(f64, f64, f64); N]), Error> {
    let mut frames = [Mat3::identity(); N];
    let mut zxz = [(0.0, 0.0, 0.0); N];
    let mut q_prev = Mat3::identity();
    let items = desc
        .joints
        .iter()
        .zip(frames.iter_mut())
        .zip(zxz.iter_mut());
    for (i, ((joint, frame), angles)) in items.enumerate() {
        let axis = validate_joint(joint, (i + 1) as u8)?;
        *frame = frame_with_z(&axis);
        *angles = zxz_angles(&(q_prev.transpose() * joint.origin.rotation() * *frame));
        q_prev = *frame;
    }
    Ok((frames, zxz))
}

impl<const N: usize> Robot<N> {
    /// The attitude of each link's joint frame (the frame [`crate::Frames`] carries, `z` on
    /// the joint axis) in the axes of the URDF frame of the same link: a point `x` given in
    /// URDF link frame `i` is `Q_iᵀ x` in joint frame `i` (both frames have their origin on
    /// the joint). Used to carry geometry given in URDF link frames (collision primitives)
    /// into the frames the rollout computes.
    #[must_use]
    pub fn link_attitudes(&self) -> [Mat3; N] {
        let mut out = [Mat3::identity(); N];
        // The description was validated when the model was built, so pass 1 succeeds.
        if let Ok((frames, zxz)) = joint_frames(&self.desc) {
            for (i, (o, frame)) in out.iter_mut().zip(frames.iter()).enumerate() {
                *o = frame * rot_z(zxz.get(i + 1).map_or(0.0, |z| z.0));
            }
        }
        out
    }
}

fn validate_body(b: &BodyDesc, body: Body) -> Result<(f64, Vec3, Sym3), Error> {
    if !b.mass.is_finite() {
        return Err(Error::NotFinite(Param::Mass(body)));
    }
    if b.mass <= 0.0 {
        return Err(Error::NotPositive(Param::Mass(body)));
    }
    if !b.inertial.is_finite() {
        return Err(Error::NotFinite(Param::CenterOfMass(body)));
    }
    let i = b.inertia.to_sym();
    let entries = [i.xx, i.yy, i.zz, i.xy, i.xz, i.yz];
    if !entries.iter().all(|v| v.is_finite()) {
        return Err(Error::NotFinite(Param::Inertia(body)));
    }
    if i.ldlt().is_none() {
        return Err(Error::InertiaNotPositiveDefinite(body));
    }
    let r = b.inertial.rotation();
    Ok((b.mass, b.inertial.translation(), i.rotated(&r)))
}

fn validate_joint(j: &JointDesc, index: u8) -> Result<Vec3, Error> {
    if !j.origin.is_finite() {
        return Err(Error::NotFinite(Param::JointOrigin(index)));
    }
    let axis = Vec3::from(j.axis);
    if !j.axis.iter().all(|v| v.is_finite()) {
        return Err(Error::NotFinite(Param::JointAxis(index)));
    }
    let norm = axis.norm();
    // Components are finite here, so `norm` is finite or +∞ (never NaN).
    if (norm - 1.0).abs() > UNIT_TOLERANCE {
        return Err(Error::AxisNotUnit {
            joint: index,
            tolerance: UNIT_TOLERANCE,
        });
    }
    if !j.lower.is_finite() {
        return Err(Error::NotFinite(Param::LowerLimit(index)));
    }
    if !j.upper.is_finite() {
        return Err(Error::NotFinite(Param::UpperLimit(index)));
    }
    if j.lower >= j.upper {
        return Err(Error::LimitsInverted(index));
    }
    if !j.velocity.is_finite() {
        return Err(Error::NotFinite(Param::VelocityLimit(index)));
    }
    if j.velocity <= 0.0 {
        return Err(Error::NotPositive(Param::VelocityLimit(index)));
    }
    Ok(axis / norm)
}

const fn body(mass: f64, com_x: f64, inertia: Inertia) -> BodyDesc {
    BodyDesc {
        mass,
        inertial: Origin {
            xyz: [com_x, 0.0, 0.0],
            rpy: [0.0; 3],
        },
        inertia,
    }
}

const fn joint(x: f64, z: f64, axis: [f64; 3], lower: f64, upper: f64) -> JointDesc {
    JointDesc {
        origin: Origin {
            xyz: [x, 0.0, z],
            rpy: [0.0; 3],
        },
        axis,
        lower,
        upper,
        velocity: 0.2617993878,
    }
}

const AX_X: [f64; 3] = [1.0, 0.0, 0.0];
const AX_Z: [f64; 3] = [0.0, 0.0, 1.0];
const WIDE_LO: f64 = -4.8869219056;
const WIDE_HI: f64 = 0.1745329252;
const LIM: f64 = 1.7453292520;

/// The reference chaser of the specification: a 7-DOF arm on a 1022 kg base.
///
/// Mass properties and link lengths from Table 1 of the paper; joint layout (alternating
/// roll/yaw axes, links along +x) as in `spec/chaser7.urdf`, which host-sim loads to the
/// same bits (tested).
pub const CHASER7: RobotDesc<7> = RobotDesc {
    base: body(1022.0, 0.0, Inertia::diagonal(612.69, 328.61, 657.44)),
    joints: [
        joint(1.0, 0.5, AX_X, WIDE_LO, WIDE_HI),
        joint(0.113, 0.0, AX_Z, -LIM, LIM),
        joint(1.325, 0.0, AX_X, -LIM, LIM),
        joint(0.08, 0.0, AX_Z, -LIM, LIM),
        joint(0.926, 0.0, AX_X, WIDE_LO, WIDE_HI),
        joint(0.08, 0.0, AX_Z, WIDE_LO, WIDE_HI),
        joint(0.25, 0.0, AX_X, -LIM, LIM),
    ],
    links: [
        body(10.0, 0.0565, Inertia::diagonal(0.038, 0.047, 0.025)),
        body(25.0, 0.6625, Inertia::diagonal(0.056, 5.85, 5.84)),
        body(5.0, 0.04, Inertia::diagonal(0.009, 0.017, 0.017)),
        body(15.0, 0.463, Inertia::diagonal(0.029, 1.74, 1.74)),
        body(3.0, 0.04, Inertia::diagonal(0.008, 0.005, 0.008)),
        body(10.0, 0.125, Inertia::diagonal(0.026, 0.084, 0.076)),
        body(3.0, 0.02, Inertia::diagonal(0.0036, 0.0036, 0.0034)),
    ],
    end_effector: Origin {
        xyz: [0.04, 0.0, 0.0],
        rpy: [0.0; 3],
    },
};

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// CHASER7 validates, with 1093 kg in total and q̇_max = 15°/s.
    /// Verifies RL-MODEL-003.
    #[test]
    fn chaser7_is_valid() {
        let r = Robot::new(&CHASER7).unwrap();
        assert_eq!(
            r.total_mass(),
            1022.0 + 10.0 + 25.0 + 5.0 + 15.0 + 3.0 + 10.0 + 3.0
        );
        assert_eq!(r.qd_max(), 0.2617993878);
    }

    /// Each bad robot parameter is a typed error naming its body or joint, numbered from 1.
    /// Verifies RL-CORE-007, RL-ROB-001.
    #[test]
    fn each_bad_parameter_is_named() {
        let mut d = CHASER7;
        d.links[2].mass = -1.0;
        assert_eq!(
            Robot::new(&d),
            Err(Error::NotPositive(Param::Mass(Body::Link(3))))
        );
        let mut d = CHASER7;
        d.base.inertia.ixy = 1000.0;
        assert_eq!(
            Robot::new(&d),
            Err(Error::InertiaNotPositiveDefinite(Body::Base))
        );
        let mut d = CHASER7;
        d.joints[4].axis = [0.0, 0.0, 0.0];
        assert_eq!(
            Robot::new(&d),
            Err(Error::AxisNotUnit {
                joint: 5,
                tolerance: UNIT_TOLERANCE
            })
        );
        let mut d = CHASER7;
        d.joints[0].lower = 1.0;
        assert_eq!(Robot::new(&d), Err(Error::LimitsInverted(1)));
        let mut d = CHASER7;
        d.joints[6].velocity = 0.0;
        assert_eq!(
            Robot::new(&d),
            Err(Error::NotPositive(Param::VelocityLimit(7)))
        );
        let mut d = CHASER7;
        d.joints[1].origin.rpy[2] = f64::NAN;
        assert_eq!(Robot::new(&d), Err(Error::NotFinite(Param::JointOrigin(2))));
        let mut d = CHASER7;
        d.links[6].inertia.izz = f64::INFINITY;
        assert_eq!(
            Robot::new(&d),
            Err(Error::NotFinite(Param::Inertia(Body::Link(7))))
        );
        let mut d = CHASER7;
        d.end_effector.xyz[0] = f64::NAN;
        assert_eq!(Robot::new(&d), Err(Error::NotFinite(Param::EndEffector)));
    }

    /// Φ is 0 within the limits and the sum of the excursions beyond them (eq. 23).
    /// Verifies RL-ROLL-005.
    #[test]
    fn violation_is_eq_23() {
        let r = Robot::new(&CHASER7).unwrap();
        let mut lo = *r.lower();
        let mut hi = *r.upper();
        assert_eq!(r.violation(&lo, &hi), 0.0);
        lo[1] -= 0.25;
        hi[3] += 0.5;
        assert!((r.violation(&lo, &hi) - 0.75).abs() < 1e-15);
    }
}
