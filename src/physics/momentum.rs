//! Reduced momentum matrices of eq. 1 (spec §2): the system inertia `H~b`, the coupling
//! inertia `H~bm`, the base angular velocity they imply, and the generalized Jacobian.
//!
//! Owns the composite-body recursion. With `d_i = c_i − r_g` and `e_j = p_j − r_g`,
//! column `j` of `H~bm` is
//!
//! `Σ_{i≥j} [I_i k_j + m_i d_i × (k_j × (d_i − e_j))] = Ī_j k_j − (Σ_{i≥j} m_i d_i) × (k_j × e_j)`
//!
//! where `Ī_j = Σ_{i≥j} [I_i + m_i(|d_i|² 1 − d_i d_iᵀ)]` is the inertia of the subtree
//! `j..N` about `r_g`. One backward pass accumulates `Ī_j` and the first moment, so the
//! cost is O(N); `H~b` is `Ī_1` plus the base. All quantities are in the frame of the
//! [`Frames`] they come from (the base frame); units kg m².

use crate::dual::Dual;
use crate::error::Error;
use crate::geometry::{Sym3, Vec3};
use crate::kinematics::Frames;
use crate::lanes::Real;
use crate::model::Robot;
use nalgebra::{SMatrix, Vector3, Vector6};

/// `H~b` and `H~bm` at one configuration, base frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Momentum<const N: usize> {
    /// Columns of the coupling inertia `H~bm` (3×N, kg m²).
    pub hbm: [Vec3; N],
    /// System inertia about the system CoM, `H~b` (3×3, kg m²).
    pub hb: Sym3,
}

/// Mass and first moment about `r_g` of the subtree `j..N` (kg, kg m).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Subtree<T> {
    mass: f64,
    moment: Vector3<T>,
}

/// The backward pass: writes `H~bm` columns and subtree data, returns `Ī_1` (kg m²).
#[inline(always)]
fn backward_pass<const N: usize, T: Real>(
    robot: &Robot<N>,
    frames: &Frames<N, T>,
    hbm: &mut [Vector3<T>; N],
    subtrees: &mut [Subtree<T>; N],
) -> Sym3<T> {
    let rg = frames.com;
    let mut inertia = Sym3::<T>::ZERO;
    let mut moment = Vector3::<T>::zeros();
    let mut mass = 0.0;
    let items = hbm
        .iter_mut()
        .zip(subtrees.iter_mut())
        .zip(frames.links.iter())
        .zip(robot.segments.iter())
        .rev();
    for (((col, sub), link), seg) in items {
        let d = link.com - rg;
        inertia = inertia
            .add(&Sym3::rotated_factor(&link.rot, &seg.inertia))
            .add(&Sym3::point_mass(seg.mass, &d));
        moment += d * T::splat(seg.mass);
        mass += seg.mass;
        let k = link.axis();
        let e = link.joint - rg;
        *col = inertia.mul_vec(&k) - moment.cross(&k.cross(&e));
        *sub = Subtree { mass, moment };
    }
    inertia
}

/// The whole pass: `H~bm` columns, subtree data and `H~b` (the arm's `Ī_1` plus the base).
#[inline(always)]
fn full_pass<const N: usize>(
    robot: &Robot<N>,
    frames: &Frames<N>,
) -> ([Vec3; N], [Subtree<f64>; N], Sym3) {
    let mut hbm = [Vec3::zeros(); N];
    let mut subtrees = [Subtree {
        mass: 0.0,
        moment: Vec3::zeros(),
    }; N];
    let arm = backward_pass(robot, frames, &mut hbm, &mut subtrees);
    let d0 = frames.base_com - frames.com;
    let hb = arm
        .add(&robot.base_inertia)
        .add(&Sym3::point_mass(robot.base_mass, &d0));
    (hbm, subtrees, hb)
}

impl<const N: usize> Momentum<N> {
    /// `H~b` and `H~bm` for the configuration of `frames`.
    ///
    /// Verifies RL-GOLD-001.
    ///
    /// ```
    /// use reactionless::{CHASER7, Frames, Momentum, Robot};
    /// let robot = Robot::new(&CHASER7).unwrap();
    /// let q0 = [-90f64, 45.0, 0.0, 80.0, -90.0, -45.0, -10.0].map(f64::to_radians);
    /// let m = Momentum::new(&robot, &Frames::new(&robot, &q0));
    /// assert!((m.hbm[0].x - 64.21266294418797).abs() < 1e-9); // spec §8
    /// ```
    #[must_use]
    pub fn new(robot: &Robot<N>, frames: &Frames<N>) -> Self {
        let (hbm, _, hb) = full_pass(robot, frames);
        Self { hbm, hb }
    }

    /// `H~bm q̇` (kg m²/s): the coupling angular momentum of joint rates `qd` (rad/s).
    #[must_use]
    pub fn coupling_momentum(&self, qd: &[f64; N]) -> Vec3 {
        let mut h = Vec3::zeros();
        for (col, v) in self.hbm.iter().zip(qd.iter()) {
            h += col * *v;
        }
        h
    }

    /// Base angular velocity `w₀ = −H~b⁻¹ H~bm q̇` (rad/s, base frame) under zero momentum.
    ///
    /// # Errors
    /// [`Error::SingularInertia`] if `H~b` is not positive definite (never for a validated
    /// model with finite `q`).
    pub fn base_angular_velocity(&self, qd: &[f64; N]) -> Result<Vec3, Error> {
        let f = self.hb.ldlt().ok_or(Error::SingularInertia)?;
        Ok(-f.solve(&self.coupling_momentum(qd)))
    }
}

/// `H~bm` only: the hot path of the rollout (columns, kg m²), for one configuration
/// (`f64`) or several side by side ([`Real`] lanes).
#[inline(always)]
#[must_use]
pub fn coupling<const N: usize, T: Real>(
    robot: &Robot<N>,
    frames: &Frames<N, T>,
) -> [Vector3<T>; N] {
    let mut hbm = [Vector3::<T>::zeros(); N];
    let mut subtrees = [Subtree {
        mass: 0.0,
        moment: Vector3::<T>::zeros(),
    }; N];
    let _ = backward_pass(robot, frames, &mut hbm, &mut subtrees);
    hbm
}

/// `H~bm` at `q` and its rate `dH~bm/dt` along joint rates `qd` (columns, kg m² and
/// kg m²/s): the kinematics and [`coupling`] evaluated once in [`Dual`] numbers. The value
/// part has the bits of [`coupling`] at `q`. `frames` is scratch (its end-effector fields
/// are left as they were).
///
/// Verifies RL-CONT-001.
///
/// ```
/// use reactionless::{CHASER7, Frames, Robot};
/// use reactionless::momentum::{coupling, coupling_rate};
/// let robot = Robot::new(&CHASER7).unwrap();
/// let q = [0.3, -0.2, 0.5, 1.0, -0.4, 0.2, 0.1];
/// let qd = [0.1, 0.2, -0.1, 0.05, 0.3, -0.2, 0.1];
/// let (a, a_dot) = coupling_rate(&robot, &mut Default::default(), &q, &qd);
/// assert_eq!(a, coupling(&robot, &Frames::new(&robot, &q)));
/// let h = 1e-6;
/// let at = |s: f64| coupling(&robot, &Frames::new(&robot, &core::array::from_fn(|i| q[i] + s * qd[i])));
/// let (p, m) = (at(h), at(-h));
/// for j in 0..7 {
///     assert!(((p[j] - m[j]) / (2.0 * h) - a_dot[j]).norm() < 1e-7);
/// }
/// ```
#[inline]
#[must_use]
pub fn coupling_rate<const N: usize>(
    robot: &Robot<N>,
    frames: &mut DualFrames<N>,
    q: &[f64; N],
    qd: &[f64; N],
) -> ([Vec3; N], [Vec3; N]) {
    let mut x = [Dual::ZERO; N];
    for ((x, v), d) in x.iter_mut().zip(q.iter()).zip(qd.iter()) {
        *x = Dual::new(*v, *d);
    }
    let _ = frames.0.update_chain(robot, &x);
    let both = coupling(robot, &frames.0);
    (both.map(|c| c.map(|x| x.v)), both.map(|c| c.map(|x| x.d)))
}

/// Scratch kinematics in [`Dual`] numbers for [`coupling_rate`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DualFrames<const N: usize>(Frames<N, Dual>);

impl<const N: usize> Default for DualFrames<N> {
    fn default() -> Self {
        Self(Frames::IDLE)
    }
}

/// The generalized Jacobian `J_G` (6×N): end-effector linear (m/s, rows 1–3) and angular
/// (rad/s, rows 4–6) velocity per joint rate under zero momentum, base frame.
///
/// With `w₀ = −H~b⁻¹ H~bm q̇` and the system CoM fixed, column `j` is
/// `[k_j × (p_E − p_j) − k_j × (Σ_{i≥j} m_i(c_i − p_j))/M − (p_E − r_g) × w₀_j ; k_j + w₀_j]`
/// with `w₀_j = −H~b⁻¹ H~bm[:, j]`.
///
/// # Errors
/// [`Error::SingularInertia`] if `H~b` is not positive definite.
pub fn generalized_jacobian<const N: usize>(
    robot: &Robot<N>,
    frames: &Frames<N>,
) -> Result<SMatrix<f64, 6, N>, Error> {
    let (hbm, subtrees, hb) = full_pass(robot, frames);
    let hb = hb.ldlt().ok_or(Error::SingularInertia)?;
    let rg = frames.com;
    let pe = frames.ee_position;
    let total = robot.total_mass();
    let mut jg = SMatrix::<f64, 6, N>::zeros();
    let items = jg
        .column_iter_mut()
        .zip(frames.links.iter())
        .zip(hbm.iter())
        .zip(subtrees.iter());
    for (((mut col, link), h), sub) in items {
        let k = link.axis();
        let e = link.joint - rg;
        // Σ_{i≥j} m_i (c_i − p_j) = Σ m_i d_i − M_j e_j.
        let lever = sub.moment - e * sub.mass;
        let w0 = -hb.solve(h);
        let v = k.cross(&(pe - link.joint)) - k.cross(&lever) / total - (pe - rg).cross(&w0);
        let w = k + w0;
        col.copy_from(&Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z));
    }
    Ok(jg)
}
