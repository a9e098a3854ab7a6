//! Rotations, poses and symmetric 3×3 tensors: the small fixed-size geometry the rest of
//! the core is built from.
//!
//! Owns: URDF roll-pitch-yaw ↔ rotation matrix, the orthonormal frame that puts a joint
//! axis on `z`, rotation matrix ↔ unit quaternion (`w ≥ 0`), the pose type used at the
//! interface, the pose error of spec §6 (position difference and rotation vector), and
//! [`Sym3`], a symmetric 3×3 matrix stored as its six distinct entries (inertia tensors,
//! `AAᵀ`) with an `LDLᵀ` solve that never divides by zero.
//!
//! Every transcendental function comes from `libm`, so results are bit-identical on every
//! target. Angles are radians, lengths metres.

use crate::lanes::{Mask, Real};
use core::ops::Mul;
use nalgebra::{Matrix3, Vector3};

/// 3-vector of `f64` (metres, radians or radians per second as documented at each use).
pub type Vec3 = Vector3<f64>;
/// 3×3 matrix of `f64` (rotations are proper orthonormal).
pub type Mat3 = Matrix3<f64>;

/// The zero vector, as a constant.
pub const ZERO3: Vec3 = Vec3::new(0.0, 0.0, 0.0);
/// The zero matrix, as a constant.
pub const ZERO33: Mat3 = Mat3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);

/// Rotation matrix of URDF roll-pitch-yaw angles (rad): `R = Rz(yaw)·Ry(pitch)·Rx(roll)`.
///
/// Zero angles give the identity exactly.
#[must_use]
pub fn rpy_matrix(rpy: [f64; 3]) -> Mat3 {
    let [roll, pitch, yaw] = rpy;
    let (sr, cr) = libm::sincos(roll);
    let (sp, cp) = libm::sincos(pitch);
    let (sy, cy) = libm::sincos(yaw);
    Mat3::new(
        cy * cp,
        cy * sp * sr - sy * cr,
        cy * sp * cr + sy * sr,
        sy * cp,
        sy * sp * sr + cy * cr,
        sy * sp * cr - cy * sr,
        -sp,
        cp * sr,
        cp * cr,
    )
}

/// URDF roll-pitch-yaw angles (rad) of a rotation matrix; inverse of [`rpy_matrix`].
///
/// Pitch is in `[−π/2, π/2]`; at gimbal lock (|cos pitch| < 1e-12) roll is set to 0.
#[must_use]
pub fn matrix_rpy(r: &Mat3) -> [f64; 3] {
    let cp = libm::hypot(r.m11, r.m21);
    let pitch = libm::atan2(-r.m31, cp);
    if cp < 1e-12 {
        // Gimbal lock: only yaw ∓ roll is defined; put it all in yaw.
        let yaw = libm::atan2(-r.m12, r.m22);
        [0.0, pitch, yaw]
    } else {
        [libm::atan2(r.m32, r.m33), pitch, libm::atan2(r.m21, r.m11)]
    }
}

/// Rotation that maps `e_z` onto the unit vector `k`: columns `[u, v, k]`, right-handed.
///
/// Duff et al., "Building an orthonormal basis, revisited" (JCGT 2017). Exact for the
/// coordinate axes (`k = e_z` gives the identity).
#[must_use]
pub fn frame_with_z(k: &Vec3) -> Mat3 {
    let sign = libm::copysign(1.0, k.z);
    let a = -1.0 / (sign + k.z);
    let b = k.x * k.y * a;
    let u = Vec3::new(1.0 + sign * k.x * k.x * a, sign * b, -sign * k.x);
    let v = Vec3::new(b, sign + k.y * k.y * a, -k.y);
    Mat3::from_columns(&[u, v, *k])
}

/// `a·b` for 3×3 matrices, written out (straight-line code for the hot path).
#[inline(always)]
pub(crate) fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    Mat3::new(
        a.m11 * b.m11 + a.m12 * b.m21 + a.m13 * b.m31,
        a.m11 * b.m12 + a.m12 * b.m22 + a.m13 * b.m32,
        a.m11 * b.m13 + a.m12 * b.m23 + a.m13 * b.m33,
        a.m21 * b.m11 + a.m22 * b.m21 + a.m23 * b.m31,
        a.m21 * b.m12 + a.m22 * b.m22 + a.m23 * b.m32,
        a.m21 * b.m13 + a.m22 * b.m23 + a.m23 * b.m33,
        a.m31 * b.m11 + a.m32 * b.m21 + a.m33 * b.m31,
        a.m31 * b.m12 + a.m32 * b.m22 + a.m33 * b.m32,
        a.m31 * b.m13 + a.m32 * b.m23 + a.m33 * b.m33,
    )
}

/// `a·v` for a 3×3 matrix (any [`Real`]) and a vector of `f64`, written out.
#[inline(always)]
pub(crate) fn mat_vec<T: Real>(a: &Matrix3<T>, v: &Vec3) -> Vector3<T> {
    Vector3::new(
        a.m11 * v.x + a.m12 * v.y + a.m13 * v.z,
        a.m21 * v.x + a.m22 * v.y + a.m23 * v.z,
        a.m31 * v.x + a.m32 * v.y + a.m33 * v.z,
    )
}

/// `v` in every lane.
#[inline(always)]
pub(crate) fn splat3<T: Real>(v: &Vec3) -> Vector3<T> {
    Vector3::new(T::splat(v.x), T::splat(v.y), T::splat(v.z))
}

/// `m` in every lane.
#[inline(always)]
pub(crate) fn splat33<T: Real>(m: &Mat3) -> Matrix3<T> {
    Matrix3::new(
        T::splat(m.m11),
        T::splat(m.m12),
        T::splat(m.m13),
        T::splat(m.m21),
        T::splat(m.m22),
        T::splat(m.m23),
        T::splat(m.m31),
        T::splat(m.m32),
        T::splat(m.m33),
    )
}

/// ZXZ angles `(a, b, c)` of a rotation: `m = Rz(a)·Rx(b)·Rz(c)`, `b ∈ [0, π]`.
///
/// `a` and `b` come from the third column (`m·e_z`); `c` is then fitted to the whole
/// matrix, so the product reproduces `m` to rounding even when `b` is 0 or π (parallel
/// axes), where the split between `a` and `c` is arbitrary.
#[must_use]
pub fn zxz_angles(m: &Mat3) -> (f64, f64, f64) {
    let b = libm::atan2(libm::hypot(m.m13, m.m23), m.m33);
    let a = libm::atan2(m.m13, -m.m23);
    let (sa, ca) = libm::sincos(a);
    let (sb, cb) = libm::sincos(b);
    // Rx(b)ᵀ·Rz(a)ᵀ·m ≈ Rz(c): take c from its first column.
    let r = Mat3::new(ca, sa, 0.0, -cb * sa, cb * ca, sb, sb * sa, -sb * ca, cb) * m;
    (a, b, libm::atan2(r.m21, r.m11))
}

/// Right-multiplies `r` by `Rx(b)` given `(sin b, cos b)`: only the last two columns change.
#[inline(always)]
pub(crate) fn mul_rx<T: Real + Mul<S, Output = T>, S: Copy>(
    r: &Matrix3<T>,
    s: S,
    c: S,
) -> Matrix3<T> {
    Matrix3::new(
        r.m11,
        r.m12 * c + r.m13 * s,
        r.m13 * c - r.m12 * s,
        r.m21,
        r.m22 * c + r.m23 * s,
        r.m23 * c - r.m22 * s,
        r.m31,
        r.m32 * c + r.m33 * s,
        r.m33 * c - r.m32 * s,
    )
}

/// Rotation about `z` by `θ` (rad).
#[must_use]
pub fn rot_z(theta: f64) -> Mat3 {
    let (s, c) = libm::sincos(theta);
    Mat3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0)
}

/// Rotation about `x` by `θ` (rad).
#[must_use]
pub fn rot_x(theta: f64) -> Mat3 {
    let (s, c) = libm::sincos(theta);
    Mat3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c)
}

/// Right-multiplies `r` by `Rz(θ)` given `(sin θ, cos θ)`: only the first two columns change.
#[inline(always)]
pub(crate) fn mul_rz<T: Real>(r: &Matrix3<T>, s: T, c: T) -> Matrix3<T> {
    Matrix3::new(
        r.m11 * c + r.m12 * s,
        r.m12 * c - r.m11 * s,
        r.m13,
        r.m21 * c + r.m22 * s,
        r.m22 * c - r.m21 * s,
        r.m23,
        r.m31 * c + r.m32 * s,
        r.m32 * c - r.m31 * s,
        r.m33,
    )
}

/// Unit quaternion `[w, x, y, z]` of a rotation matrix, with `w ≥ 0` (Shepperd's method).
#[must_use]
pub fn matrix_quat(r: &Mat3) -> [f64; 4] {
    let tr = r.m11 + r.m22 + r.m33;
    let q = if tr >= r.m11 && tr >= r.m22 && tr >= r.m33 {
        let s = 2.0 * libm::sqrt(1.0 + tr);
        [
            0.25 * s,
            (r.m32 - r.m23) / s,
            (r.m13 - r.m31) / s,
            (r.m21 - r.m12) / s,
        ]
    } else if r.m11 >= r.m22 && r.m11 >= r.m33 {
        let s = 2.0 * libm::sqrt(1.0 + r.m11 - r.m22 - r.m33);
        [
            (r.m32 - r.m23) / s,
            0.25 * s,
            (r.m12 + r.m21) / s,
            (r.m13 + r.m31) / s,
        ]
    } else if r.m22 >= r.m33 {
        let s = 2.0 * libm::sqrt(1.0 + r.m22 - r.m11 - r.m33);
        [
            (r.m13 - r.m31) / s,
            (r.m12 + r.m21) / s,
            0.25 * s,
            (r.m23 + r.m32) / s,
        ]
    } else {
        let s = 2.0 * libm::sqrt(1.0 + r.m33 - r.m11 - r.m22);
        [
            (r.m21 - r.m12) / s,
            (r.m13 + r.m31) / s,
            (r.m23 + r.m32) / s,
            0.25 * s,
        ]
    };
    canonical(normalized(q))
}

/// Rotation matrix of a unit quaternion `[w, x, y, z]` (not re-normalised).
#[must_use]
pub fn quat_matrix(q: [f64; 4]) -> Mat3 {
    let [w, x, y, z] = q;
    Mat3::new(
        1.0 - 2.0 * (y * y + z * z),
        2.0 * (x * y - w * z),
        2.0 * (x * z + w * y),
        2.0 * (x * y + w * z),
        1.0 - 2.0 * (x * x + z * z),
        2.0 * (y * z - w * x),
        2.0 * (x * z - w * y),
        2.0 * (y * z + w * x),
        1.0 - 2.0 * (x * x + y * y),
    )
}

/// Hamilton product `a ⊗ b` of quaternions `[w, x, y, z]`.
#[must_use]
pub fn quat_mul(a: [f64; 4], b: [f64; 4]) -> [f64; 4] {
    let [aw, ax, ay, az] = a;
    let [bw, bx, by, bz] = b;
    [
        aw * bw - ax * bx - ay * by - az * bz,
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
    ]
}

/// Unit quaternion of the rotation vector `θ` (rad): `exp(θ/2)`.
#[must_use]
pub fn quat_exp(theta: &Vec3) -> [f64; 4] {
    let angle = theta.norm();
    let half = 0.5 * angle;
    let (s, c) = libm::sincos(half);
    // sin(θ/2)/θ, with its series near 0 so tiny rotations stay accurate.
    let k = if angle < 1e-6 {
        0.5 - angle * angle / 48.0
    } else {
        s / angle
    };
    [c, k * theta.x, k * theta.y, k * theta.z]
}

/// Rotation vector (rad) of the unit quaternion `q`, angle in `[0, π]`.
#[must_use]
pub fn quat_log(q: [f64; 4]) -> Vec3 {
    let [w, x, y, z] = canonical(q);
    let v = Vec3::new(x, y, z);
    let s = v.norm();
    if s == 0.0 {
        return Vec3::zeros();
    }
    let angle = 2.0 * libm::atan2(s, w);
    v * (angle / s)
}

/// Rotation angle (rad, in `[0, π]`) of the unit quaternion `q`.
#[must_use]
pub fn quat_angle(q: [f64; 4]) -> f64 {
    let [w, x, y, z] = q;
    2.0 * libm::atan2(libm::sqrt(x * x + y * y + z * z), libm::fabs(w))
}

/// `q / ‖q‖` (a zero quaternion is returned unchanged; callers validate first).
#[must_use]
pub fn normalized(q: [f64; 4]) -> [f64; 4] {
    let [w, x, y, z] = q;
    let n = libm::sqrt(w * w + x * x + y * y + z * z);
    if n == 0.0 {
        return q;
    }
    [w / n, x / n, y / n, z / n]
}

/// The representative of `±q` with `w ≥ 0` (first non-zero component positive if `w = 0`).
#[must_use]
pub fn canonical(q: [f64; 4]) -> [f64; 4] {
    let [w, x, y, z] = q;
    let flip = if w != 0.0 {
        w < 0.0
    } else if x != 0.0 {
        x < 0.0
    } else if y != 0.0 {
        y < 0.0
    } else {
        z < 0.0
    };
    if flip { [-w, -x, -y, -z] } else { q }
}

/// A pose in the inertial frame: position (m) and attitude as a unit quaternion `[w,x,y,z]`.
///
/// The quaternion maps body coordinates to inertial coordinates (`p_I = R(q)·p_B`).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Pose {
    /// Position of the frame origin (m).
    pub position: [f64; 3],
    /// Attitude, unit quaternion `[w, x, y, z]` with `w ≥ 0`.
    pub quat_wxyz: [f64; 4],
}

impl Pose {
    /// All zeros (not a valid pose: a placeholder for statically allocated state).
    pub const ZERO: Self = Self {
        position: [0.0; 3],
        quat_wxyz: [0.0; 4],
    };

    /// Pose from a position and a rotation matrix.
    #[must_use]
    pub fn from_parts(position: &Vec3, rotation: &Mat3) -> Self {
        Self {
            position: [position.x, position.y, position.z],
            quat_wxyz: matrix_quat(rotation),
        }
    }

    /// Pose error of spec §6 of `self` against the desired pose `target`.
    ///
    /// `e = [p_des − p ; log(R_des Rᵀ)]` (m and rad, inertial frame).
    #[must_use]
    pub fn error_to(&self, target: &Pose) -> PoseError {
        let [pw, px, py, pz] = self.quat_wxyz;
        let conj = [pw, -px, -py, -pz];
        let dq = quat_mul(target.quat_wxyz, conj);
        let rot = quat_log(dq);
        let [tx, ty, tz] = target.position;
        let [sx, sy, sz] = self.position;
        PoseError {
            position: [tx - sx, ty - sy, tz - sz],
            rotation: [rot.x, rot.y, rot.z],
        }
    }
}

/// The 6-vector pose error `e` of spec §6 (eq. 16 with a rotation vector).
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PoseError {
    /// `p_des − p` (m, inertial frame).
    pub position: [f64; 3],
    /// `log(R_des Rᵀ)`, rotation vector (rad, inertial frame).
    pub rotation: [f64; 3],
}

impl PoseError {
    /// `f = ‖e‖₂`, the planner's cost (metres and radians mixed, as in the paper).
    #[must_use]
    pub fn norm(&self) -> f64 {
        let [a, b, c] = self.position;
        let [d, e, f] = self.rotation;
        libm::sqrt(a * a + b * b + c * c + d * d + e * e + f * f)
    }

    /// Position error ‖p_des − p‖ (m).
    #[must_use]
    pub fn position_m(&self) -> f64 {
        let [a, b, c] = self.position;
        libm::sqrt(a * a + b * b + c * c)
    }

    /// Orientation error: the angle of `R_des Rᵀ` (degrees, a report quantity).
    #[must_use]
    pub fn orientation_deg(&self) -> f64 {
        let [d, e, f] = self.rotation;
        libm::sqrt(d * d + e * e + f * f).to_degrees()
    }

    /// The error as a 6-vector `[dp; dθ]`.
    #[must_use]
    pub fn to_array(&self) -> [f64; 6] {
        let [a, b, c] = self.position;
        let [d, e, f] = self.rotation;
        [a, b, c, d, e, f]
    }
}

/// Symmetric 3×3 matrix stored as its six distinct entries (`f64`, or [`Real`] lanes in
/// the rollout's hot path).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Sym3<T = f64> {
    /// Entry (1,1).
    pub xx: T,
    /// Entry (2,2).
    pub yy: T,
    /// Entry (3,3).
    pub zz: T,
    /// Entries (1,2) = (2,1).
    pub xy: T,
    /// Entries (1,3) = (3,1).
    pub xz: T,
    /// Entries (2,3) = (3,2).
    pub yz: T,
}

impl Sym3 {
    /// `R·S·Rᵀ` (e.g. an inertia tensor expressed in a rotated frame).
    #[inline]
    #[must_use]
    pub fn rotated(&self, r: &Mat3) -> Self {
        // M = R·S, then (M·Rᵀ)_ab = row_a(M)·row_b(R) for the six entries a ≤ b.
        let m = mat_mul(r, &self.to_matrix());
        Self {
            xx: m.m11 * r.m11 + m.m12 * r.m12 + m.m13 * r.m13,
            yy: m.m21 * r.m21 + m.m22 * r.m22 + m.m23 * r.m23,
            zz: m.m31 * r.m31 + m.m32 * r.m32 + m.m33 * r.m33,
            xy: m.m11 * r.m21 + m.m12 * r.m22 + m.m13 * r.m23,
            xz: m.m11 * r.m31 + m.m12 * r.m32 + m.m13 * r.m33,
            yz: m.m21 * r.m31 + m.m22 * r.m32 + m.m23 * r.m33,
        }
    }

    /// Lower-triangular Cholesky factor `L` (`S = L·Lᵀ`), or `None` if `S` is not positive
    /// definite.
    #[must_use]
    pub fn cholesky(&self) -> Option<Mat3> {
        let l11 = libm::sqrt(self.xx);
        let l21 = self.xy / l11;
        let l31 = self.xz / l11;
        let l22 = libm::sqrt(self.yy - l21 * l21);
        let l32 = (self.yz - l31 * l21) / l22;
        let l33 = libm::sqrt(self.zz - l31 * l31 - l32 * l32);
        let l = Mat3::new(l11, 0.0, 0.0, l21, l22, 0.0, l31, l32, l33);
        (l.iter().all(|v| v.is_finite()) && l11 > 0.0 && l22 > 0.0 && l33 > 0.0).then_some(l)
    }

    /// The full 3×3 matrix.
    #[must_use]
    pub fn to_matrix(&self) -> Mat3 {
        Mat3::new(
            self.xx, self.xy, self.xz, self.xy, self.yy, self.yz, self.xz, self.yz, self.zz,
        )
    }

    /// Symmetric part `(M + Mᵀ)/2` of a full matrix.
    #[must_use]
    pub fn from_matrix(m: &Mat3) -> Self {
        Self {
            xx: m.m11,
            yy: m.m22,
            zz: m.m33,
            xy: 0.5 * (m.m12 + m.m21),
            xz: 0.5 * (m.m13 + m.m31),
            yz: 0.5 * (m.m23 + m.m32),
        }
    }

    /// `LDLᵀ` factorisation if every pivot is positive and finite, else `None`.
    #[inline]
    #[must_use]
    pub fn ldlt(&self) -> Option<Ldlt3> {
        let (f, ok) = self.ldlt_masked();
        ok.then_some(f)
    }
}

impl<T: Real> Sym3<T> {
    /// The zero matrix.
    pub const ZERO: Self = Self {
        xx: T::ZERO,
        yy: T::ZERO,
        zz: T::ZERO,
        xy: T::ZERO,
        xz: T::ZERO,
        yz: T::ZERO,
    };

    /// `(R·L)(R·L)ᵀ = R·S·Rᵀ` for `S = L·Lᵀ` with `L` lower-triangular: a tensor rotated into
    /// another frame at 36 multiplications instead of 45.
    #[inline(always)]
    #[must_use]
    pub fn rotated_factor(r: &Matrix3<T>, l: &Mat3) -> Self {
        // M = R·L, using L's zeros.
        let m11 = r.m11 * l.m11 + r.m12 * l.m21 + r.m13 * l.m31;
        let m21 = r.m21 * l.m11 + r.m22 * l.m21 + r.m23 * l.m31;
        let m31 = r.m31 * l.m11 + r.m32 * l.m21 + r.m33 * l.m31;
        let m12 = r.m12 * l.m22 + r.m13 * l.m32;
        let m22 = r.m22 * l.m22 + r.m23 * l.m32;
        let m32 = r.m32 * l.m22 + r.m33 * l.m32;
        let m13 = r.m13 * l.m33;
        let m23 = r.m23 * l.m33;
        let m33 = r.m33 * l.m33;
        Self {
            xx: m11 * m11 + m12 * m12 + m13 * m13,
            yy: m21 * m21 + m22 * m22 + m23 * m23,
            zz: m31 * m31 + m32 * m32 + m33 * m33,
            xy: m11 * m21 + m12 * m22 + m13 * m23,
            xz: m11 * m31 + m12 * m32 + m13 * m33,
            yz: m21 * m31 + m22 * m32 + m23 * m33,
        }
    }

    /// Inertia of a point mass `m` (kg) at offset `d` (m): `m(|d|²I − d dᵀ)`.
    #[inline(always)]
    #[must_use]
    pub fn point_mass(m: f64, d: &Vector3<T>) -> Self {
        let (x, y, z) = (d.x, d.y, d.z);
        // `m·a` written `a·m` (the same bits: IEEE multiplication commutes).
        Self {
            xx: (y * y + z * z) * m,
            yy: (x * x + z * z) * m,
            zz: (x * x + y * y) * m,
            xy: x * -m * y,
            xz: x * -m * z,
            yz: y * -m * z,
        }
    }

    /// Entry-wise sum.
    #[inline(always)]
    #[must_use]
    pub fn add(&self, o: &Self) -> Self {
        Self {
            xx: self.xx + o.xx,
            yy: self.yy + o.yy,
            zz: self.zz + o.zz,
            xy: self.xy + o.xy,
            xz: self.xz + o.xz,
            yz: self.yz + o.yz,
        }
    }

    /// `S·v`.
    #[inline(always)]
    #[must_use]
    pub fn mul_vec(&self, v: &Vector3<T>) -> Vector3<T> {
        Vector3::new(
            self.xx * v.x + self.xy * v.y + self.xz * v.z,
            self.xy * v.x + self.yy * v.y + self.yz * v.z,
            self.xz * v.x + self.yz * v.y + self.zz * v.z,
        )
    }

    /// Trace.
    #[inline(always)]
    #[must_use]
    pub fn trace(&self) -> T {
        self.xx + self.yy + self.zz
    }

    /// `LDLᵀ` factorisation, and per lane whether every pivot is positive and finite (where
    /// it is not, that lane's factors are meaningless, possibly infinite or NaN).
    #[inline(always)]
    #[must_use]
    pub fn ldlt_masked(&self) -> (Ldlt3<T>, T::Mask) {
        let pivot = |d: T| d.gt(T::ZERO).and(d.finite());
        let d1 = self.xx;
        let l21 = self.xy / d1;
        let l31 = self.xz / d1;
        let d2 = self.yy - l21 * self.xy;
        let l32 = (self.yz - l31 * self.xy) / d2;
        let d3 = self.zz - l31 * self.xz - l32 * (self.yz - l31 * self.xy);
        let f = Ldlt3 {
            l21,
            l31,
            l32,
            inv_d: [T::ONE / d1, T::ONE / d2, T::ONE / d3],
            det: d1 * d2 * d3,
        };
        (f, pivot(d1).and(pivot(d2)).and(pivot(d3)))
    }

    /// Sum of the three principal 2×2 minors (second invariant, `Σ λ_i λ_j`).
    #[inline(always)]
    #[must_use]
    pub fn minor_sum(&self) -> T {
        (self.xx * self.yy - self.xy * self.xy)
            + (self.xx * self.zz - self.xz * self.xz)
            + (self.yy * self.zz - self.yz * self.yz)
    }
}

/// `LDLᵀ` factors of a symmetric positive-definite 3×3 matrix.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ldlt3<T = f64> {
    l21: T,
    l31: T,
    l32: T,
    inv_d: [T; 3],
    det: T,
}

impl<T: Real> Ldlt3<T> {
    /// Solves `S·x = b`.
    #[inline(always)]
    #[must_use]
    pub fn solve(&self, b: &Vector3<T>) -> Vector3<T> {
        let [i1, i2, i3] = self.inv_d;
        let y1 = b.x;
        let y2 = b.y - self.l21 * y1;
        let y3 = b.z - self.l31 * y1 - self.l32 * y2;
        let x3 = y3 * i3;
        let x2 = y2 * i2 - self.l32 * x3;
        let x1 = y1 * i1 - self.l21 * x2 - self.l31 * x3;
        Vector3::new(x1, x2, x3)
    }

    /// Determinant (product of the pivots).
    #[must_use]
    pub fn det(&self) -> T {
        self.det
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use std::vec;

    fn close(a: &Mat3, b: &Mat3, tol: f64) -> bool {
        (a - b).abs().max() <= tol
    }

    /// rpy matrices are rotations (orthonormal, det 1) and round-trip through rpy within
    /// 1e-15.
    /// Verifies RL-MODEL-001.
    #[test]
    fn rpy_roundtrip_and_orthonormal() {
        for rpy in [
            [0.1, -0.4, 2.5],
            [-3.0, 1.2, 0.3],
            [0.0, 0.0, 0.0],
            [1.0, -1.5, -2.0],
        ] {
            let r = rpy_matrix(rpy);
            assert!(close(&(r * r.transpose()), &Mat3::identity(), 1e-15));
            assert!((r.determinant() - 1.0).abs() < 1e-15);
            let back = rpy_matrix(matrix_rpy(&r));
            assert!(close(&r, &back, 1e-15));
        }
        assert_eq!(rpy_matrix([0.0; 3]), Mat3::identity());
    }

    /// The rpy matrix is URDF's Rz(yaw)·Ry(pitch)·Rx(roll) within 1e-15.
    /// Verifies RL-MODEL-001.
    #[test]
    fn rpy_matches_urdf_composition() {
        // URDF: R = Rz(y) Ry(p) Rx(r), each an elementary rotation.
        let (r, p, y) = (0.3, -0.7, 1.9);
        let rx = quat_matrix([libm::cos(r / 2.0), libm::sin(r / 2.0), 0.0, 0.0]);
        let ry = quat_matrix([libm::cos(p / 2.0), 0.0, libm::sin(p / 2.0), 0.0]);
        let rz = quat_matrix([libm::cos(y / 2.0), 0.0, 0.0, libm::sin(y / 2.0)]);
        assert!(close(&rpy_matrix([r, p, y]), &(rz * ry * rx), 1e-15));
    }

    /// A joint frame is a rotation taking z onto its axis (±z and the coordinate axes
    /// included).
    /// Verifies RL-MODEL-001.
    #[test]
    fn frame_with_z_is_rotation_onto_axis() {
        for k in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 2.0, -3.0).normalize(),
            Vec3::new(-0.2, 0.1, -0.97).normalize(),
        ] {
            let q = frame_with_z(&k);
            assert!(close(&(q * q.transpose()), &Mat3::identity(), 1e-15));
            assert!((q.determinant() - 1.0).abs() < 1e-15);
            assert!((q * Vec3::z() - k).norm() < 1e-16);
        }
        assert_eq!(frame_with_z(&Vec3::z()), Mat3::identity());
    }

    /// ZXZ angles reproduce rotations within 4e-16, parallel and antiparallel axes
    /// included.
    /// Verifies RL-MODEL-001.
    #[test]
    fn zxz_reproduces_rotations_including_parallel_axes() {
        let mut cases = vec![
            Mat3::identity(),
            rot_x(core::f64::consts::PI),
            rot_z(0.3) * rot_x(core::f64::consts::PI) * rot_z(-1.1),
            rot_z(2.0),
            rpy_matrix([0.0, 0.0, core::f64::consts::FRAC_PI_2]),
            Mat3::new(0.0, 0.0, 1.0, 0.0, 1.0, 0.0, -1.0, 0.0, 0.0),
        ];
        for rpy in [
            [0.1, -0.4, 2.5],
            [3.0, 1.2, -0.3],
            [1e-12, 0.0, 0.0],
            [-2.0, 0.7, 1.9],
        ] {
            cases.push(rpy_matrix(rpy));
        }
        for m in cases {
            let (a, b, c) = zxz_angles(&m);
            assert!((0.0..=core::f64::consts::PI).contains(&b));
            let back = rot_z(a) * rot_x(b) * rot_z(c);
            assert!(close(&back, &m, 4e-16), "{m} vs {back}");
            let (s, cc) = libm::sincos(b);
            assert!(close(&mul_rx(&m, s, cc), &(m * rot_x(b)), 1e-16));
        }
    }

    /// A rotation's quaternion has w ≥ 0 and maps back to it within 1e-15.
    /// Verifies RL-MODEL-005.
    #[test]
    fn quaternion_roundtrip() {
        for rpy in [
            [0.1, -0.4, 2.5],
            [3.1, 0.2, -3.1],
            [0.0, 0.0, 3.1],
            [2.0, 1.5, 0.0],
        ] {
            let r = rpy_matrix(rpy);
            let q = matrix_quat(&r);
            assert!(q[0] >= 0.0);
            assert!(close(&quat_matrix(q), &r, 1e-15));
        }
    }

    /// The quaternion log inverts exp within 1e-15, tiny angles included.
    /// Verifies RL-POSE-002.
    #[test]
    fn log_inverts_exp() {
        for t in [
            Vec3::new(0.3, -0.2, 1.0),
            Vec3::new(1e-9, 0.0, 2e-9),
            Vec3::new(0.0, 3.0, 0.0),
        ] {
            let back = quat_log(quat_exp(&t));
            assert!((back - t).norm() < 1e-15 * (1.0 + t.norm()));
        }
        assert!((quat_angle(quat_exp(&Vec3::new(0.0, 0.5, 0.0))) - 0.5).abs() < 1e-15);
    }

    /// The pose error is [Δp; log(R_des Rᵀ)] (a rotation vector, within 1e-15) and f its
    /// norm.
    /// Verifies RL-POSE-002.
    #[test]
    fn pose_error_is_rotation_vector() {
        let a = Pose::from_parts(&Vec3::new(1.0, 2.0, 3.0), &rpy_matrix([0.1, 0.2, 0.3]));
        let delta = Vec3::new(0.01, -0.02, 0.03);
        // target = exp(delta) applied on the left: R_des = Exp(δ) R.
        let r_des = quat_matrix(quat_exp(&delta)) * rpy_matrix([0.1, 0.2, 0.3]);
        let b = Pose::from_parts(&Vec3::new(1.5, 2.0, 3.0), &r_des);
        let e = a.error_to(&b);
        assert!((Vec3::from(e.rotation) - delta).norm() < 1e-15);
        assert_eq!(e.position, [0.5, 0.0, 0.0]);
        assert!((e.norm() - libm::sqrt(0.25 + delta.norm_squared())).abs() < 1e-15);
    }

    /// Symmetric 3×3 rotation, LDLᵀ solve, determinant, minors and Cholesky match dense
    /// maths; indefinite is refused.
    /// Verifies RL-MODEL-001.
    #[test]
    fn sym3_rotation_and_solve() {
        let s = Sym3 {
            xx: 4.0,
            yy: 3.0,
            zz: 2.0,
            xy: 0.5,
            xz: -0.3,
            yz: 0.2,
        };
        let r = rpy_matrix([0.4, -0.1, 0.9]);
        let full = r * s.to_matrix() * r.transpose();
        assert!(close(&s.rotated(&r).to_matrix(), &full, 1e-14));
        let f = s.ldlt().unwrap();
        let b = Vec3::new(1.0, -2.0, 0.5);
        let x = f.solve(&b);
        assert!((s.to_matrix() * x - b).norm() < 1e-14);
        assert!((f.det() - s.to_matrix().determinant()).abs() < 1e-13);
        let m = s.to_matrix();
        let minors = m.m11 * m.m22 - m.m12 * m.m21 + m.m11 * m.m33 - m.m13 * m.m31 + m.m22 * m.m33
            - m.m23 * m.m32;
        assert!((s.minor_sum() - minors).abs() < 1e-14);
        let indefinite = Sym3 {
            xx: 1.0,
            yy: 1.0,
            zz: 1.0,
            xy: 2.0,
            ..Sym3::ZERO
        };
        assert!(indefinite.ldlt().is_none());
        assert!(indefinite.cholesky().is_none());
        let l = s.cholesky().unwrap();
        assert!(close(&(l * l.transpose()), &s.to_matrix(), 1e-15));
        assert!(close(
            &Sym3::rotated_factor(&r, &l).to_matrix(),
            &full,
            1e-14
        ));
    }
}
