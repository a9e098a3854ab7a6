//! The integrators, in one place: the explicit Euler step of the joint path (eq. 19,
//! spec §5), the fourth-order step of the continuous path (spec §14) with its dense
//! output, and the midpoint sub-steps the truth model integrates the base attitude with.
//!
//! Owns [`euler_step`] (used by the rollout, and by `host-sim check` to verify every
//! written row) and [`midpoint_substeps`] (used by [`crate::TruthModel`]): both are the
//! reference discretization, and changing either moves every golden record. Owns
//! [`rk4_step`], [`ab5_step`] and [`Cubic`], which [`crate::Integrator::Rk4`] and
//! [`crate::Integrator::Ab5`] rollouts use: classical Runge–Kutta and fifth-order
//! Adams–Bashforth on `(q, N)`, and the cubic Hermite interpolant of `q` between two steps.

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

/// The rates of the continuous path's state `(q, N)`: `(q̇, Ṅ)` (rad/s, 1/s).
pub type Rates<const N: usize, const K: usize> = ([f64; N], [[f64; N]; K]);

/// `out ← y + c·k` for the state `y = (q, cols)` and its rates `k`.
#[inline(always)]
fn offset<const N: usize, const K: usize>(
    out: &mut Rates<N, K>,
    q: &[f64; N],
    cols: &[[f64; N]; K],
    c: f64,
    k: &Rates<N, K>,
) {
    for ((o, x), v) in out.0.iter_mut().zip(q.iter()).zip(k.0.iter()) {
        *o = *x + c * *v;
    }
    for ((ocol, col), dcol) in out.1.iter_mut().zip(cols.iter()).zip(k.1.iter()) {
        for ((o, x), v) in ocol.iter_mut().zip(col.iter()).zip(dcol.iter()) {
            *o = *x + c * *v;
        }
    }
}

/// `acc ← acc + w·k`, component by component.
#[inline(always)]
fn accumulate<const N: usize, const K: usize>(acc: &mut Rates<N, K>, w: f64, k: &Rates<N, K>) {
    for (a, v) in acc.0.iter_mut().zip(k.0.iter()) {
        *a += w * *v;
    }
    for (acol, kcol) in acc.1.iter_mut().zip(k.1.iter()) {
        for (a, v) in acol.iter_mut().zip(kcol.iter()) {
            *a += w * *v;
        }
    }
}

/// One classical Runge–Kutta step of length `h` (s) from time `t` (s) of the state `q`
/// (rad) and `cols` (the basis columns), in place, for `ẏ = f(t, y)`:
/// `k₁ = f(t, y)`, `k₂ = f(t + h/2, y + h/2·k₁)`, `k₃ = f(t + h/2, y + h/2·k₂)`,
/// `k₄ = f(t + h, y + h·k₃)`, `y ← y + h/6·(((k₁ + 2k₂) + 2k₃) + k₄)`, each component in
/// that order (four evaluations of `f`, no FMA: the same bits on every target). Three
/// states live at a time (the stage, its rates, the running sum), for a small stack.
///
/// Returns `k₁`, the rates at the start (an [`ab5_step`] keeps them).
///
/// # Errors
/// The first error of `f`; `q` and `cols` are then unchanged.
///
/// Verifies RL-CONT-002.
///
/// ```
/// // ẏ = y from y(0) = 1: one step of 0.1 is e^0.1 to 1e-7 (local error h⁵/120).
/// let (mut q, mut n) = ([1.0], [[0.0]]);
/// reactionless::integrator::rk4_step(0.0, 0.1, &mut q, &mut n, |_, q, _| {
///     Ok::<_, ()>(([q[0]], [[0.0]]))
/// })
/// .unwrap();
/// assert!((q[0] - 0.1f64.exp()).abs() < 1e-7);
/// ```
pub fn rk4_step<const N: usize, const K: usize, E>(
    t: f64,
    h: f64,
    q: &mut [f64; N],
    cols: &mut [[f64; N]; K],
    mut f: impl FnMut(f64, &[f64; N], &[[f64; N]; K]) -> Result<Rates<N, K>, E>,
) -> Result<Rates<N, K>, E> {
    let half = 0.5 * h;
    let k1 = f(t, q, cols)?;
    let mut acc = k1;
    let mut stage = acc;
    offset(&mut stage, q, cols, half, &acc);
    let k = f(t + half, &stage.0, &stage.1)?;
    offset(&mut stage, q, cols, half, &k);
    accumulate(&mut acc, 2.0, &k);
    let k = f(t + half, &stage.0, &stage.1)?;
    offset(&mut stage, q, cols, h, &k);
    accumulate(&mut acc, 2.0, &k);
    let k = f(t + h, &stage.0, &stage.1)?;
    accumulate(&mut acc, 1.0, &k);
    advance(q, cols, h / 6.0, &acc);
    Ok(k1)
}

/// `y ← y + c·acc` for the state `y = (q, cols)`.
#[inline(always)]
fn advance<const N: usize, const K: usize>(
    q: &mut [f64; N],
    cols: &mut [[f64; N]; K],
    c: f64,
    acc: &Rates<N, K>,
) {
    for (x, a) in q.iter_mut().zip(acc.0.iter()) {
        *x += c * *a;
    }
    for (col, acol) in cols.iter_mut().zip(acc.1.iter()) {
        for (x, a) in col.iter_mut().zip(acol.iter()) {
            *x += c * *a;
        }
    }
}

/// The fifth-order Adams–Bashforth weights `b₀ … b₄` of `f_n … f_{n−4}`.
const AB5: [f64; 5] = [
    1901.0 / 720.0,
    -2774.0 / 720.0,
    2616.0 / 720.0,
    -1274.0 / 720.0,
    251.0 / 720.0,
];

/// One fifth-order Adams–Bashforth step of length `h` (s) of the state `q` (rad) and
/// `cols`, in place: `y ← y + h·((((b₀f_n + b₁f_{n−1}) + b₂f_{n−2}) + b₃f_{n−3}) +
/// b₄f_{n−4})`, each component in that order, with `rates = [f_n, f_{n−1}, …, f_{n−4}]`
/// the rates at this node and the four before it, `h` apart. No evaluation of its own:
/// the caller evaluated `f_n` and keeps the past ones.
///
/// Verifies RL-CONT-009.
///
/// ```
/// // ẏ = 1 + 4t³ (a quartic, which AB5 integrates exactly) from t = 0.4 to 0.5.
/// let h = 0.1;
/// let f = |t: f64| ([1.0 + 4.0 * t * t * t], [[0.0]]);
/// let (mut q, mut n) = ([0.4 + 0.4f64.powi(4)], [[0.0]]);
/// let rates = [f(0.4), f(0.3), f(0.2), f(0.1), f(0.0)];
/// reactionless::integrator::ab5_step(h, &mut q, &mut n, [&rates[0], &rates[1], &rates[2], &rates[3], &rates[4]]);
/// assert!((q[0] - (0.5 + 0.5f64.powi(4))).abs() < 1e-15);
/// ```
pub fn ab5_step<const N: usize, const K: usize>(
    h: f64,
    q: &mut [f64; N],
    cols: &mut [[f64; N]; K],
    rates: [&Rates<N, K>; 5],
) {
    let [b0, b1, b2, b3, b4] = AB5;
    let [f0, f1, f2, f3, f4] = rates;
    let mut acc = ([0.0; N], [[0.0; N]; K]);
    offset(&mut acc, &[0.0; N], &[[0.0; N]; K], b0, f0);
    accumulate(&mut acc, b1, f1);
    accumulate(&mut acc, b2, f2);
    accumulate(&mut acc, b3, f3);
    accumulate(&mut acc, b4, f4);
    advance(q, cols, h, &acc);
}

/// The cubic Hermite interpolant of one integrator step of `h` seconds, between `(q0, v0)`
/// at `θ = 0` and `(q1, v1)` at `θ = 1` (positions rad, rates rad/s), per joint
/// `p(θ) = c₀ + c₁θ + c₂θ² + c₃θ³`: the dense output of an [`rk4_step`] (third order in
/// `h`, exact at both ends up to rounding), with its exact range and rate bound over the
/// step.
///
/// Verifies RL-CONT-003.
///
/// ```
/// use reactionless::integrator::Cubic;
/// // A cubic is reproduced: q(t) = t³ on [1, 3] (h = 2), its range [1, 27], its rate ≤ 27.
/// let c = Cubic::hermite(&[1.0], &[3.0], &[27.0], &[27.0], 2.0);
/// for th in [0.0, 0.25, 0.5, 1.0] {
///     let t: f64 = 1.0 + 2.0 * th;
///     assert!((c.at(th)[0] - t.powi(3)).abs() < 1e-12);
/// }
/// let ([lo], [hi]) = c.range();
/// assert!(lo <= 1.0 && lo > 1.0 - 1e-12 && hi >= 27.0 && hi < 27.0 + 1e-12);
/// assert_eq!(c.rate_bound(2.0), 27.0);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cubic<const N: usize> {
    /// `[c₀, c₁, c₂, c₃]` per joint (rad).
    c: [[f64; 4]; N],
}

impl<const N: usize> Cubic<N> {
    /// All zeros.
    pub const IDLE: Self = Self { c: [[0.0; 4]; N] };

    /// The interpolant of `(q0, v0)`, `(q1, v1)` over a step of `h` seconds.
    #[must_use]
    pub fn hermite(q0: &[f64; N], v0: &[f64; N], q1: &[f64; N], v1: &[f64; N], h: f64) -> Self {
        let mut c = [[0.0; 4]; N];
        for (i, ci) in c.iter_mut().enumerate() {
            if let (Some(a), Some(va), Some(b), Some(vb)) =
                (q0.get(i), v0.get(i), q1.get(i), v1.get(i))
            {
                let (da, db, d) = (h * va, h * vb, b - a);
                *ci = [*a, da, 3.0 * d - 2.0 * da - db, da + db - 2.0 * d];
            }
        }
        Self { c }
    }

    /// `p(θ)` (rad), by Horner's rule.
    #[inline]
    #[must_use]
    pub fn at(&self, theta: f64) -> [f64; N] {
        self.c
            .map(|[c0, c1, c2, c3]| c0 + theta * (c1 + theta * (c2 + theta * c3)))
    }

    /// The smallest and largest `p(θ)` over `θ ∈ [0, 1]`, per joint (rad): the ends and
    /// the interior roots of `p′`, widened by [`Cubic::slack`], so that every value
    /// [`Cubic::at`] gives (rounded differently, at a rounded `θ`) lies within.
    #[must_use]
    pub fn range(&self) -> ([f64; N], [f64; N]) {
        let mut lo = [0.0; N];
        let mut hi = [0.0; N];
        for ((l, h), &[c0, c1, c2, c3]) in lo.iter_mut().zip(hi.iter_mut()).zip(self.c.iter()) {
            let end = c0 + c1 + c2 + c3;
            let (mut a, mut b) = (c0.min(end), c0.max(end));
            // p′(θ) = c₁ + 2c₂θ + 3c₃θ²: at most two roots.
            for th in quadratic_roots(3.0 * c3, 2.0 * c2, c1) {
                if th > 0.0 && th < 1.0 {
                    let v = c0 + th * (c1 + th * (c2 + th * c3));
                    a = a.min(v);
                    b = b.max(v);
                }
            }
            let slack = slack_of(c0, c1, c2, c3);
            *l = a - slack;
            *h = b + slack;
        }
        (lo, hi)
    }

    /// The largest rounding difference between two evaluations of `p` in `[0, 1]` (rad),
    /// over every joint: 8 ulps of `Σ|c_k|`, far above what Horner's rule and the range's
    /// rounded roots can differ by.
    #[must_use]
    pub fn slack(&self) -> f64 {
        self.c.iter().fold(0.0f64, |m, &[c0, c1, c2, c3]| {
            m.max(slack_of(c0, c1, c2, c3))
        })
    }

    /// The largest `|ṗ|` over the step (rad/s) for a step of `h` seconds: the ends and the
    /// vertex of the quadratic `p′`, over every joint. The rate of every chord of the step
    /// is at most this (mean value theorem).
    #[must_use]
    pub fn rate_bound(&self, h: f64) -> f64 {
        let mut most = 0.0f64;
        for &[_, c1, c2, c3] in &self.c {
            most = most
                .max(libm::fabs(c1))
                .max(libm::fabs(c1 + 2.0 * c2 + 3.0 * c3));
            if c3 != 0.0 {
                let th = -c2 / (3.0 * c3);
                if th > 0.0 && th < 1.0 {
                    most = most.max(libm::fabs(c1 + th * (2.0 * c2 + th * 3.0 * c3)));
                }
            }
        }
        most / h
    }
}

/// 8 ulps of `|c₀| + |c₁| + |c₂| + |c₃|`.
fn slack_of(c0: f64, c1: f64, c2: f64, c3: f64) -> f64 {
    8.0 * f64::EPSILON * (libm::fabs(c0) + libm::fabs(c1) + libm::fabs(c2) + libm::fabs(c3))
}

/// The real roots of `a x² + b x + c` (NaN where there is none; one root repeated for a
/// linear equation), in the numerically stable form.
fn quadratic_roots(a: f64, b: f64, c: f64) -> [f64; 2] {
    if a == 0.0 {
        let x = if b == 0.0 { f64::NAN } else { -c / b };
        return [x, x];
    }
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return [f64::NAN; 2];
    }
    let sq = libm::sqrt(disc);
    let q = -0.5 * (b + if b < 0.0 { -sq } else { sq });
    if q == 0.0 {
        return [0.0; 2];
    }
    [q / a, c / q]
}
