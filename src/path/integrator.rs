//! The integrators, in one place: the explicit Euler step of the joint path (eq. 19,
//! spec §5) and the midpoint sub-steps the truth model integrates the base attitude with.
//!
//! Owns [`euler_step`] (used by the rollout, and by `host-sim check` to verify every
//! written row) and [`midpoint_substeps`] (used by [`crate::TruthModel`]). Both are the
//! reference discretization: changing either moves every golden record.

use crate::lanes::Real;

/// `q ← q + dt·q̇`, joint by joint (rad, rad/s, s): the explicit Euler step of eq. 19, of
/// one rollout (`f64`) or of several side by side ([`Real`] lanes).
///
/// Verifies RL-ROLL-001.
///
/// ```
/// let mut q = [0.5, -1.0];
/// reactionless::integrator::euler_step(&mut q, &[0.1, 0.2], 0.01);
/// assert_eq!(q, [0.5 + 0.01 * 0.1, -1.0 + 0.01 * 0.2]);
/// ```
#[inline(always)]
pub fn euler_step<const N: usize, T: Real>(q: &mut [T; N], qd: &[T; N], dt: f64) {
    for (q, v) in q.iter_mut().zip(qd.iter()) {
        // `dt·v` written `v·dt`: the same bits (IEEE multiplication commutes), and it lets
        // `T` be lanes of several rollouts.
        *q += *v * dt;
    }
}

/// The midpoint rule on the straight joint segment `from → to`, in `m ≥ 1` sub-steps:
/// calls `f(q_mid, δq)` for sub-step `j = 0 … m−1`, with `q_mid = from + (j + ½)/m ·
/// (to − from)` and `δq = (to − from)/m`. Stops at the first error `f` returns.
///
/// The truth model integrates `δθ = −H~b⁻¹ H~bm(q_mid) δq` with it (spec §5: ≥ 10
/// sub-steps per step, the joint path piecewise linear between samples).
///
/// # Errors
/// The first error of `f`.
///
/// Verifies RL-TRUTH-001.
///
/// ```
/// let mut mids = Vec::new();
/// reactionless::integrator::midpoint_substeps(&[0.0], &[1.0], 4, |q, dq| {
///     mids.push((q[0], dq[0]));
///     Ok::<(), ()>(())
/// })
/// .unwrap();
/// assert_eq!(mids, [(0.125, 0.25), (0.375, 0.25), (0.625, 0.25), (0.875, 0.25)]);
/// ```
pub fn midpoint_substeps<const N: usize, E>(
    from: &[f64; N],
    to: &[f64; N],
    m: u32,
    mut f: impl FnMut(&[f64; N], &[f64; N]) -> Result<(), E>,
) -> Result<(), E> {
    for j in 0..m {
        let (mid, dq) = midpoint_substep(from, to, m, j);
        f(&mid, &dq)?;
    }
    Ok(())
}

/// Sub-step `j` of [`midpoint_substeps`]: `(q_mid, δq)`, for integrators that are resumed
/// between sub-steps (the planner's budgeted truth evaluation).
#[must_use]
pub fn midpoint_substep<const N: usize>(
    from: &[f64; N],
    to: &[f64; N],
    m: u32,
    j: u32,
) -> ([f64; N], [f64; N]) {
    let mf = f64::from(m);
    let mut dq = [0.0; N];
    for ((d, a), b) in dq.iter_mut().zip(from.iter()).zip(to.iter()) {
        *d = (b - a) / mf;
    }
    let frac = (f64::from(j) + 0.5) / mf;
    let mut mid = *from;
    for ((x, a), b) in mid.iter_mut().zip(from.iter()).zip(to.iter()) {
        *x = a + frac * (b - a);
    }
    (mid, dq)
}
