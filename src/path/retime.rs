//! Minimum-time re-timing of a planned joint path under per-joint rate and acceleration
//! limits, rest to rest (spec §10: `H~bm q̇ = 0` constrains only the direction of `q̇`, so
//! any re-timing of the same geometric path keeps the base still and ends at the same pose).
//!
//! Owns [`GridPoint`] (the caller-supplied storage, one per grid point), [`PathBuilder`]
//! (samples → an arc-length grid), [`Limits`], [`Profile`] (the solved `s(t)`) and
//! [`Stream`] (setpoints `(t, q, q̇, q̈)` every `dt`).
//!
//! **Path.** The rollout's samples `q_0 … q_S` are joined by straight segments (the Euler
//! step `q_{s+1} = q_s + dt q̇_s` is exactly that path) and parameterised by joint-space arc
//! length `s ∈ [0, L]`, never by `t`: the rate vanishes at both rest ends, the arc-length
//! tangent does not. `M` grid points `s_i = i·Δ`, `Δ = L/(M−1)`, hold `q(s_i)`; `q'` at a
//! grid point is a second-order finite difference of the neighbouring points (one-sided at
//! the ends). Between two grid points the path written is the cubic Hermite through both
//! with those tangents: C¹ in `s`, so no velocity jump at a grid point that a written
//! second difference could see whole (joining the grid points by chords did: up to 7× the
//! limit on slow paths). Feeding the samples needs two passes (the first, [`ArcLength`],
//! measures `L`); a rollout is deterministic, so the planner re-runs it from `(q₀, η)`.
//!
//! **Solve** (TOPP-RA, Pham & Pham 2018, on `x = ṡ²`, `u = s̈`, `x_{i+1} = x_i + 2Δu_i`),
//! on the model `q'` linear in `s` within a segment and `q''` constant over it,
//! `(q'_{i+1} − q'_i)/Δ`. Segment `i` (constant `u_i`) is constrained at both of its ends:
//! `|q'_j u + q''_j ṡ²| ≤ q̈max_j` at `s_i` and at `s_{i+1}`, and `x_i ≤ (q̇max_j/|q'_j|)²`
//! with the largest `|q'_j|` of the point and its neighbours. Within a segment `q'` and
//! `ṡ²` are linear in `s`, so both `q̇_j²` and `q̈_j` of the model stay within their end
//! values. A backward pass computes the upper end of each controllable set `K_i = [0,
//! x̄_i]` (`x̄_{M−1} = 0`, rest at the end) by eliminating `u` in closed form (every lower
//! bound of `u` below every upper bound: exact for this 2-D LP; the pair condition is
//! concave piecewise linear in `x`, its root found by Newton steps on the active pair, at
//! most one per pair, typically one or two of O(N) each); a greedy forward pass from
//! `x_0 = 0` takes the largest admissible `u_i` that keeps `x_{i+1} ∈ K_{i+1}`. Work
//! O(M·N) in practice, bounded by O(M·N³), no LP solver. Each segment lasts
//! `2Δ/(√x_i + √x_{i+1})`.
//!
//! **What is written keeps the limits** (spec §11: first and second differences of the
//! written `q` over `dt` and `dt²`): [`solve_written`] measures a solution's stream with
//! [`WrittenCheck`] and tightens the limits until it does.
//!
//! **Stream.** The optimal duration `T*` is rounded up to a whole step, `T = K·dt`, by a
//! uniform time scale `r = T*/T ≤ 1` (rates scale by `r`, accelerations by `r²`, so no
//! limit can be exceeded by the rounding). Sample `k` lies at `τ = k·dt·r` of the optimal
//! profile; within its segment `ṡ = √x_i + u τ`, `q` is the Hermite's at `s`, `q'` is
//! interpolated linearly in `s`, `q̇ = q' ṡ r`, `q̈ = (q' u + q'' ṡ²) r²` (the model's). The first sample is `q_0`, the
//! last is exactly the last path sample, both with `q̇ = 0`. The stream carries O(1) state
//! (the segment index and its start time) and walks the grid once.
//!
//! Storage: [`GridPoint<N>`] is `8(N+1)` bytes (64 for `N = 7`); the recommended grid
//! [`DEFAULT_GRID`] = 2000 points takes 128,000 bytes for `N = 7`. Everything is `libm`,
//! sequential and FMA-free, so host and Cortex-M7 produce the same bits.

use crate::error::{Error, Param};
use crate::rollout::Sample;
use crate::task::Task;
use crate::trajectory::MAX_STEPS;

/// Smallest grid: the finite differences need three points.
pub const MIN_GRID: u32 = 3;
/// Recommended grid size `M` (points): durations within 0.1% of a 3000-point grid on the
/// test plans, 128 kB of storage for `N = 7`.
pub const DEFAULT_GRID: u32 = 2000;
/// A joint whose tangent component is below this (of a unit tangent) imposes no bound on
/// `s̈`, only `|q''_j| x ≤ q̈max_j`.
pub const TANGENT_FLOOR: f64 = 1e-12;

/// One grid point of the caller-supplied storage: `8(N+1)` bytes.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GridPoint<const N: usize> {
    /// `q(s_i)` (rad).
    pub q: [f64; N],
    /// `ṡ²` at `s_i` ((rad/s)², arc length in rad); the controllable-set bound during the
    /// backward pass, the solution after the forward pass.
    pub x: f64,
}

impl<const N: usize> GridPoint<N> {
    /// An empty grid point (for static storage).
    pub const ZERO: Self = Self {
        q: [0.0; N],
        x: 0.0,
    };
}

/// Per-joint limits (rad/s, rad/s²), validated once.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits<const N: usize> {
    qd_max: [f64; N],
    qdd_max: [f64; N],
}

impl<const N: usize> Limits<N> {
    /// Rate limits `qd_max` (rad/s) and acceleration limits `qdd_max` (rad/s²), both
    /// multiplied by `margin` ∈ (0, 1].
    ///
    /// # Errors
    /// [`Error::NotFinite`] / [`Error::NotPositive`] naming [`Param::VelocityLimit`],
    /// [`Param::AccelLimit`] (1-based joint) or [`Param::RetimeMargin`]; a margin above 1 is
    /// [`Error::MarginAboveOne`].
    ///
    /// ```
    /// use reactionless::retime::Limits;
    /// assert!(Limits::new([0.26; 7], [0.09; 7], 1.0).is_ok());
    /// assert!(Limits::new([0.26; 7], [0.0; 7], 1.0).is_err());
    /// ```
    pub fn new(qd_max: [f64; N], qdd_max: [f64; N], margin: f64) -> Result<Self, Error> {
        check_positive(margin, Param::RetimeMargin)?;
        if margin > 1.0 {
            return Err(Error::MarginAboveOne);
        }
        let mut out = Self { qd_max, qdd_max };
        for (j, (v, a)) in out
            .qd_max
            .iter_mut()
            .zip(out.qdd_max.iter_mut())
            .enumerate()
        {
            let joint = (j + 1) as u8;
            check_positive(*v, Param::VelocityLimit(joint))?;
            check_positive(*a, Param::AccelLimit(joint))?;
            *v *= margin;
            *a *= margin;
        }
        Ok(out)
    }

    /// The rate limits in force (after the margin, rad/s).
    #[must_use]
    pub fn qd_max(&self) -> &[f64; N] {
        &self.qd_max
    }

    /// The acceleration limits in force (after the margin, rad/s²).
    #[must_use]
    pub fn qdd_max(&self) -> &[f64; N] {
        &self.qdd_max
    }
}

/// `v` finite and > 0, or the error naming `p` (also used by [`crate::preshape`] and
/// [`crate::twophase`]).
pub(crate) fn check_positive(v: f64, p: Param) -> Result<(), Error> {
    if !v.is_finite() {
        return Err(Error::NotFinite(p));
    }
    if v <= 0.0 {
        return Err(Error::NotPositive(p));
    }
    Ok(())
}

/// `‖b − a‖₂`, sequential sum.
fn distance<const N: usize>(a: &[f64; N], b: &[f64; N]) -> f64 {
    let mut s = 0.0;
    for (x, y) in a.iter().zip(b) {
        let d = y - x;
        s += d * d;
    }
    libm::sqrt(s)
}

/// First pass: the joint-space arc length of a sample sequence.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcLength<const N: usize> {
    last: Option<[f64; N]>,
    length: f64,
    samples: u32,
}

impl<const N: usize> Default for ArcLength<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> ArcLength<N> {
    /// Nothing measured yet.
    #[must_use]
    pub const fn new() -> Self {
        Self {
            last: None,
            length: 0.0,
            samples: 0,
        }
    }

    /// Adds the next sample `q` (rad).
    pub fn push(&mut self, q: &[f64; N]) {
        if let Some(p) = &self.last {
            self.length += distance(p, q);
        }
        self.last = Some(*q);
        self.samples = self.samples.saturating_add(1);
    }

    /// The length so far (rad).
    #[must_use]
    pub fn length(&self) -> f64 {
        self.length
    }
}

/// A path on an arc-length grid: `M` points, spacing `Δ`, length `L`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Path {
    m: u32,
    ds: f64,
    length: f64,
}

impl Path {
    /// Grid points `M`.
    #[must_use]
    pub fn grid(&self) -> u32 {
        self.m
    }

    /// Path length `L` (rad of joint-space arc length).
    #[must_use]
    pub fn length(&self) -> f64 {
        self.length
    }
}

/// Second pass: fills the grid from the same samples, in the same order.
#[derive(Debug)]
pub struct PathBuilder<'g, const N: usize> {
    grid: &'g mut [GridPoint<N>],
    path: Path,
    next: u32,
    acc: f64,
    last: Option<[f64; N]>,
    last_step: [f64; N],
    /// Index of the first zero-length segment after the path started moving.
    stopped_at: Option<u32>,
    samples: u32,
    error: Option<Error>,
}

impl<'g, const N: usize> PathBuilder<'g, N> {
    /// A builder for `m` grid points in `grid` (which must hold at least `m`), of the path
    /// `length` measured by [`ArcLength`] on the same samples.
    ///
    /// # Errors
    /// [`Error::GridTooSmall`] for `m < `[`MIN_GRID`], [`Error::CapacityExceeded`] naming
    /// [`Param::RetimeGrid`] when `grid` holds fewer than `m` points, [`Error::PathTooShort`]
    /// for a length that is not finite and positive.
    pub fn new(grid: &'g mut [GridPoint<N>], m: u32, length: f64) -> Result<Self, Error> {
        if m < MIN_GRID {
            return Err(Error::GridTooSmall { min: MIN_GRID });
        }
        if (m as usize) > grid.len() {
            return Err(Error::CapacityExceeded {
                param: Param::RetimeGrid,
                requested: m,
                capacity: grid.len().min(u32::MAX as usize) as u32,
            });
        }
        if !length.is_finite() || length <= 0.0 {
            return Err(Error::PathTooShort);
        }
        let ds = length / f64::from(m - 1);
        Ok(Self {
            grid,
            path: Path { m, ds, length },
            next: 0,
            acc: 0.0,
            last: None,
            last_step: [0.0; N],
            stopped_at: None,
            samples: 0,
            error: None,
        })
    }

    /// Adds the next sample `q` (rad). The first error is kept and returned by
    /// [`PathBuilder::finish`].
    pub fn push(&mut self, q: &[f64; N]) {
        if self.error.is_some() {
            return;
        }
        let index = self.samples;
        self.samples = self.samples.saturating_add(1);
        if q.iter().any(|v| !v.is_finite()) {
            self.error = Some(Error::NonFiniteState { step: index });
            return;
        }
        let Some(prev) = self.last else {
            if let Some(g) = self.grid.first_mut() {
                g.q = *q;
            }
            self.next = 1;
            self.last = Some(*q);
            return;
        };
        let seg = distance(&prev, q);
        let mut step = [0.0; N];
        for ((d, a), b) in step.iter_mut().zip(&prev).zip(q) {
            *d = b - a;
        }
        if seg == 0.0 {
            if self.acc > 0.0 && self.stopped_at.is_none() {
                self.stopped_at = Some(index);
            }
            return;
        }
        // Moving again after a stop, or turning back: the speed vanished inside the path.
        let mut dot = 0.0;
        for (a, b) in self.last_step.iter().zip(&step) {
            dot += a * b;
        }
        if let Some(at) = self.stopped_at {
            self.error = Some(Error::PathStalls { sample: at });
            return;
        }
        if dot < 0.0 {
            self.error = Some(Error::PathStalls { sample: index - 1 });
            return;
        }
        let s_new = self.acc + seg;
        let m = self.path.m;
        while self.next < m - 1 {
            let target = f64::from(self.next) * self.path.ds;
            if target > s_new {
                break;
            }
            let sigma = (target - self.acc) / seg;
            if let Some(g) = self.grid.get_mut(self.next as usize) {
                for ((o, a), b) in g.q.iter_mut().zip(&prev).zip(q) {
                    *o = (1.0 - sigma) * a + sigma * b;
                }
                g.x = 0.0;
            }
            self.next += 1;
        }
        self.acc = s_new;
        self.last = Some(*q);
        self.last_step = step;
    }

    /// The grid is complete: the last sample becomes the last grid point exactly.
    ///
    /// # Errors
    /// The first error of [`PathBuilder::push`]; [`Error::PathMismatch`] if the samples'
    /// length differs from the one given to [`PathBuilder::new`] (not the same samples).
    pub fn finish(self) -> Result<Path, Error> {
        if let Some(e) = self.error {
            return Err(e);
        }
        let m = self.path.m;
        if self.acc != self.path.length || self.next != m - 1 {
            return Err(Error::PathMismatch);
        }
        if let (Some(g), Some(q)) = (self.grid.get_mut((m - 1) as usize), self.last) {
            g.q = q;
        }
        Ok(self.path)
    }
}

/// Builds the grid of `eta`'s rollout for `task` (two rollouts: length, then grid).
///
/// # Errors
/// As [`Task::rollout`] and [`PathBuilder`].
///
/// ```
/// use reactionless::{reference, retime::{self, GridPoint, Limits}};
/// let task = reference::paper_task()?;
/// let mut grid = [GridPoint::ZERO; 500];
/// let path = retime::path_of_rollout(&task, &reference::ETA_HAT, &mut grid, 500)?;
/// let qd = 15f64.to_radians();
/// let limits = Limits::new([qd; 7], [5f64.to_radians(); 7], 1.0)?;
/// let profile = retime::solve(&mut grid, &path, &limits)?;
/// assert!(profile.duration() < 12.0); // 30 s with the paper's scaling
/// # Ok::<(), reactionless::Error>(())
/// ```
pub fn path_of_rollout<const N: usize, const K: usize>(
    task: &Task<N, K>,
    eta: &[[f64; 2]; K],
    grid: &mut [GridPoint<N>],
    m: u32,
) -> Result<Path, Error> {
    let mut arc = ArcLength::<N>::new();
    task.rollout(eta, &mut |s: &Sample<N>| arc.push(&s.q))?;
    let mut b = PathBuilder::new(grid, m, arc.length())?;
    task.rollout(eta, &mut |s: &Sample<N>| b.push(&s.q))?;
    b.finish()
}

/// `q'` at grid point `i`: second-order finite differences (one-sided at the ends).
fn derivatives<const N: usize>(grid: &[GridPoint<N>], path: &Path, i: u32) -> [f64; N] {
    let mut d1 = [0.0; N];
    let m = path.m;
    let (lo, kind) = if i == 0 {
        (0, 0u8)
    } else if i >= m - 1 {
        (m - 3, 2)
    } else {
        (i - 1, 1)
    };
    let h2 = 2.0 * path.ds;
    if let Some([a, b, c]) = grid.get(lo as usize..lo as usize + 3) {
        for (j, o) in d1.iter_mut().enumerate() {
            let (Some(&qa), Some(&qb), Some(&qc)) = (a.q.get(j), b.q.get(j), c.q.get(j)) else {
                continue;
            };
            *o = match kind {
                0 => (-3.0 * qa + 4.0 * qb - qc) / h2,
                1 => (qc - qa) / h2,
                _ => (qa - 4.0 * qb + 3.0 * qc) / h2,
            };
        }
    }
    d1
}

/// One acceleration constraint of a segment, `|P u + W x| ≤ A` in `(u, x) = (s̈_i, ṡ_i²)`.
#[derive(Debug, Clone, Copy)]
struct Row {
    p: f64,
    w: f64,
    a: f64,
}

/// The `2N` rows of segment `i → i+1` with `q''` constant over it (`W = (q'_{i+1} −
/// q'_i)/Δ`): joint `j` at `s_i` (`P = q'_j(s_i)`) and at `s_{i+1}` with the same `u`
/// (`x_{i+1} = x + 2Δu`: `P = q'_j(s_{i+1}) + 2ΔW`). Within the segment `q̈_j = q'_j(s) u +
/// q''_j ṡ²(s)` is linear in `s` (both `q'` and `ṡ² = x + 2u(s − s_i)` are), so bounding it
/// at both ends bounds this model at every setpoint inside; what is written (the Hermite
/// of [`Stream`]) differs from it slightly, and [`solve_written`] closes that gap.
fn rows<const N: usize>(
    at: &[f64; N],
    next: &[f64; N],
    limits: &Limits<N>,
    ds: f64,
) -> ([Row; N], [Row; N]) {
    let zero = Row {
        p: 0.0,
        w: 0.0,
        a: 1.0,
    };
    let mut ra = [zero; N];
    let mut rb = [zero; N];
    for (j, (oa, ob)) in ra.iter_mut().zip(rb.iter_mut()).enumerate() {
        let a = limits.qdd_max.get(j).copied().unwrap_or(1.0);
        if let (Some(&p), Some(&pn)) = (at.get(j), next.get(j)) {
            let w = (pn - p) / ds;
            *oa = Row { p, w, a };
            *ob = Row {
                p: pn + 2.0 * ds * w,
                w,
                a,
            };
        }
    }
    (ra, rb)
}

/// The largest `x` at grid point `i` from which some `u` satisfying the segment's rows
/// reaches `[0, x_next]`: `u` eliminated in closed form (every lower bound of `u` below
/// every upper bound), each pair a bound `c·x ≤ d` with `d ≥ 0`, so `x = 0` is always in.
fn controllable_max<const N: usize>(
    tangent: &[f64; N],
    rows: &([Row; N], [Row; N]),
    qd_max: &[f64; N],
    ds: f64,
    x_next: f64,
) -> f64 {
    // The smallest d/c over bounds with c > 0, kept as a fraction (d, c) and compared by
    // cross-multiplication: one division per point instead of one per pair. (1, 0) is +∞.
    let (mut bd, mut bc) = (1.0f64, 0.0f64);
    let mut bound = |c: f64, d: f64| {
        if c > 0.0 && d * bc < bd * c {
            (bd, bc) = (d, c);
        }
    };
    for (ap, v) in tangent.iter().zip(qd_max) {
        if *ap > TANGENT_FLOOR {
            let r = v / ap;
            bound(1.0, r * r);
        }
    }
    // Per row: u ∈ [−l − σx, l − σx] with l = A/|P|, σ = W/P; rows with a vanishing P bound
    // only x (|W| x ≤ A).
    let mut l = [[0.0f64; 2]; N];
    let mut sl = [[0.0f64; 2]; N];
    let mut live = [[false; 2]; N];
    for (j, (ra, rb)) in rows.0.iter().zip(&rows.1).enumerate() {
        for (side, r) in [ra, rb].into_iter().enumerate() {
            let ap = libm::fabs(r.p);
            if ap <= TANGENT_FLOOR {
                bound(libm::fabs(r.w), r.a);
            } else if let (Some(lo), Some(so), Some(fo)) = (
                l.get_mut(j).and_then(|x| x.get_mut(side)),
                sl.get_mut(j).and_then(|x| x.get_mut(side)),
                live.get_mut(j).and_then(|x| x.get_mut(side)),
            ) {
                *lo = r.a / ap;
                *so = r.w / r.p;
                *fo = true;
            }
        }
    }
    let inv2 = 1.0 / (2.0 * ds);
    let rows_of = || {
        l.as_flattened()
            .iter()
            .zip(sl.as_flattened())
            .zip(live.as_flattened())
            .filter_map(|((l, s), f)| f.then_some((*l, *s)))
    };
    for (lj, sj) in rows_of() {
        // L_j ≤ (x_next − x)/(2Δ) and −x/(2Δ) ≤ U_j.
        bound(inv2 - sj, x_next * inv2 + lj);
        bound(sj - inv2, lj);
    }
    let mut x = if bc > 0.0 { bd / bc } else { f64::INFINITY };
    if !x.is_finite() {
        x = f64::MAX;
    }
    // Every lower bound of u below every upper bound: φ(x) = min_k U_k − max_j L_j ≥ 0,
    // φ(x) = min_k (l_k − σ_k x) + min_j (l_j + σ_j x), concave with φ(0) > 0. If φ < 0 at
    // the other bounds' x, Newton steps on the active pair's line walk down to the root
    // from above (each line lies above the concave φ) and stop on the final piece; at most
    // one step per pair.
    for _ in 0..(4 * N * N + 1) {
        let (mut a, mut ka) = (f64::INFINITY, (0.0, 0.0));
        let (mut b, mut kb) = (f64::INFINITY, (0.0, 0.0));
        for (lr, sr) in rows_of() {
            let up = lr - sr * x;
            if up < a {
                (a, ka) = (up, (lr, sr));
            }
            let lo = lr + sr * x;
            if lo < b {
                (b, kb) = (lo, (lr, sr));
            }
        }
        if a + b >= 0.0 || !(a + b).is_finite() {
            break;
        }
        let slope = ka.1 - kb.1;
        let root = if slope > 0.0 {
            (ka.0 + kb.0) / slope
        } else {
            0.0
        };
        if root.is_nan() || root >= x {
            break;
        }
        x = root.max(0.0);
    }
    x
}

/// The largest `u` the segment's rows admit at `x` that keeps `x + 2Δu ≤ x_next`.
fn greedy_u<const N: usize>(rows: &([Row; N], [Row; N]), ds: f64, x: f64, x_next: f64) -> f64 {
    let mut u = (x_next - x) / (2.0 * ds);
    for r in rows.0.iter().chain(&rows.1) {
        let ap = libm::fabs(r.p);
        if ap > TANGENT_FLOOR {
            u = u.min(r.a / ap - (r.w / r.p) * x);
        }
    }
    u
}

/// A solved re-timing: the grid's `x` hold `ṡ²`; [`Profile::duration`] is `T*`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    path: Path,
    duration: f64,
}

impl Profile {
    /// Minimum time `T*` (s) on the grid.
    #[must_use]
    pub fn duration(&self) -> f64 {
        self.duration
    }

    /// The path it re-times.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// `f64::clamp` without its panic (`lo > hi` or a NaN bound): the same two comparisons in
/// the same order, so the same bits whenever `clamp` would not panic; a NaN bound leaves
/// `v` unchanged on that side. (The flight image's link-time proof found `clamp`'s assert.)
fn clamp(v: f64, lo: f64, hi: f64) -> f64 {
    let mut v = v;
    if v < lo {
        v = lo;
    }
    if v > hi {
        v = hi;
    }
    v
}

/// Duration of segment `i` (s): `2Δ/(√x_i + √x_{i+1})`.
fn segment_time(ds: f64, xa: f64, xb: f64) -> f64 {
    2.0 * ds / (libm::sqrt(xa) + libm::sqrt(xb))
}

/// The time-optimal, rest-to-rest `s(t)` of `path` (built in `grid`) under `limits`:
/// backward controllable-set pass, greedy forward pass (see the module docs).
///
/// # Errors
/// [`Error::PathMismatch`] if `grid` is shorter than the path's grid;
/// [`Error::RetimeStalled`] if the speed would vanish at an interior grid point (a path
/// that cannot be traversed in finite time, e.g. a corner).
pub fn solve<const N: usize>(
    grid: &mut [GridPoint<N>],
    path: &Path,
    limits: &Limits<N>,
) -> Result<Profile, Error> {
    let m = path.m;
    if grid.len() < m as usize || m < MIN_GRID {
        return Err(Error::PathMismatch);
    }
    let ds = path.ds;
    // Backward pass: x̄_{M−1} = 0, x̄_i from x̄_{i+1}.
    let mut hi = 0.0;
    if let Some(g) = grid.get_mut((m - 1) as usize) {
        g.x = 0.0;
    }
    let mut next = derivatives(grid, path, m - 1);
    let mut at = derivatives(grid, path, m - 2);
    for i in (0..m - 1).rev() {
        let prev = if i == 0 {
            at
        } else {
            derivatives(grid, path, i - 1)
        };
        let r = rows(&at, &next, limits, ds);
        // The rate bound at s_i uses the largest |q'_j| of the point and its neighbours:
        // then both ends of each segment satisfy it for the segment's largest tangent, and
        // since q' and ṡ² are linear in s within a segment, so does every setpoint.
        let mut tangent = [0.0; N];
        for (((t, a), b), c) in tangent.iter_mut().zip(&prev).zip(&at).zip(&next) {
            *t = libm::fabs(*a).max(libm::fabs(*b)).max(libm::fabs(*c));
        }
        hi = controllable_max(&tangent, &r, &limits.qd_max, ds, hi);
        next = at;
        at = prev;
        if !(hi > 0.0 && hi.is_finite()) && i > 0 {
            return Err(Error::RetimeStalled { point: i });
        }
        if let Some(g) = grid.get_mut(i as usize) {
            g.x = hi;
        }
    }
    // Forward pass: x_0 = 0 (rest), greedy u, clamped into K_{i+1}.
    let mut x = 0.0;
    let mut duration = 0.0;
    if let Some(g) = grid.first_mut() {
        g.x = 0.0;
    }
    let mut at = derivatives(grid, path, 0);
    for i in 0..m - 1 {
        let following = derivatives(grid, path, i + 1);
        let r = rows(&at, &following, limits, ds);
        at = following;
        let x_next_max = grid.get((i + 1) as usize).map_or(0.0, |g| g.x);
        let u = greedy_u(&r, ds, x, x_next_max);
        let next = clamp(x + 2.0 * ds * u, 0.0, x_next_max);
        let next = if i + 1 == m - 1 { 0.0 } else { next };
        if (next.is_nan() || next <= 0.0) && i + 1 < m - 1 {
            return Err(Error::RetimeStalled { point: i + 1 });
        }
        duration += segment_time(ds, x, next);
        if let Some(g) = grid.get_mut((i + 1) as usize) {
            g.x = next;
        }
        x = next;
    }
    if !duration.is_finite() {
        return Err(Error::RetimeStalled { point: 0 });
    }
    Ok(Profile {
        path: *path,
        duration,
    })
}

/// The largest ratios of what a stream writes to the limits, by spec §11's definition:
/// per joint `r`, the rate `|q_r(τ_{j+1}) − q_r(τ_j)|/dt` over `q̇max_r` and the acceleration
/// `|q_r(τ_{j+1}) − 2q_r(τ_j) + q_r(τ_{j−1})|/dt²` over `q̈max_r`, on the written `q`
/// alone (not on the `q̇`, `q̈` a setpoint carries).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Written {
    /// Largest rate ratio (≤ 1 within the limits).
    pub rate: f64,
    /// Largest acceleration ratio (≤ 1 within the limits).
    pub accel: f64,
}

impl Written {
    /// Both ratios within 1.
    #[must_use]
    pub fn within(&self) -> bool {
        self.rate <= 1.0 && self.accel <= 1.0
    }
}

/// Measures [`Written`] over written positions, one at a time, in O(1) state: the
/// definition `check` and the flight image hold a re-timed stream to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WrittenCheck<const N: usize> {
    limits: Limits<N>,
    dt: f64,
    last: [Option<[f64; N]>; 2],
    worst: Written,
}

impl<const N: usize> WrittenCheck<N> {
    /// A check of samples `dt` (s) apart against `limits`.
    #[must_use]
    pub fn new(limits: &Limits<N>, dt: f64) -> Self {
        Self {
            limits: *limits,
            dt,
            last: [None, None],
            worst: Written::default(),
        }
    }

    /// The next written position `q` (rad).
    pub fn push(&mut self, q: &[f64; N]) {
        let dt = self.dt;
        if let Some(q1) = &self.last[1] {
            for ((a, b), v) in q1.iter().zip(q).zip(&self.limits.qd_max) {
                let r = libm::fabs(b - a) / dt / v;
                // A NaN ratio is kept: it fails every later test.
                if r > self.worst.rate || r.is_nan() {
                    self.worst.rate = r;
                }
            }
            if let Some(q0) = &self.last[0] {
                for (((a, b), c), l) in q0.iter().zip(q1).zip(q).zip(&self.limits.qdd_max) {
                    let r = libm::fabs(c - 2.0 * b + a) / (dt * dt) / l;
                    if r > self.worst.accel || r.is_nan() {
                        self.worst.accel = r;
                    }
                }
            }
        }
        self.last = [self.last[1], Some(*q)];
    }

    /// The largest ratios so far (NaN if a value was not finite).
    #[must_use]
    pub fn worst(&self) -> Written {
        self.worst
    }
}

/// Most solves of [`solve_written`].
pub const WRITTEN_PASSES: u32 = 8;

/// What [`solve_written`] aims its written ratios at when it must tighten: just below 1.
const WRITTEN_TARGET: f64 = 1.0 - 1e-6;

/// The factor one kind of limit (rates or accelerations) is scaled by, found by the secant
/// method on the written ratio it gives (the first step divides by the ratio).
#[derive(Debug, Clone, Copy)]
struct Tighten {
    f: f64,
    last: Option<(f64, f64)>,
}

impl Tighten {
    const NONE: Self = Self { f: 1.0, last: None };

    /// Takes the ratio `r` the current factor gave; returns `false` if it is within 1.
    fn update(&mut self, r: f64) -> bool {
        if r <= 1.0 {
            return false;
        }
        let guess = self.f * WRITTEN_TARGET / r;
        let next = match self.last {
            Some((f0, r0)) if r0 != r => {
                let secant = self.f + (WRITTEN_TARGET - r) * (self.f - f0) / (r - r0);
                if secant > 0.0 && secant < self.f {
                    secant
                } else {
                    guess
                }
            }
            _ => guess,
        };
        self.last = Some((self.f, r));
        self.f = next;
        true
    }
}

/// The time-optimal re-timing whose setpoints, written every `dt_s`, keep `limits` by spec
/// §11's definition ([`Written`]). [`solve`] bounds the continuous profile on the grid; the
/// written samples of the piecewise-linear path can exceed it by a fraction of a percent
/// (measured up to 0.35 % at 1 °/s² on the reference plan). Each pass solves, streams the
/// solution once (O(1) state) and measures what it writes; while a ratio exceeds 1, the
/// limits it measures are scaled by a factor found by the secant method on that ratio
/// (aimed at `1 − 1e-6`), at most [`WRITTEN_PASSES`] solves (three on every plan measured).
/// Returns the profile and its measured ratios.
///
/// # Errors
/// As [`solve`] and [`Stream::new`]; [`Error::NonFiniteState`] if a written value is not
/// finite; [`Error::RetimeStalled`] at point 0 if the written samples still exceed the
/// limits after the last pass (not seen in practice).
pub fn solve_written<const N: usize>(
    grid: &mut [GridPoint<N>],
    path: &Path,
    limits: &Limits<N>,
    dt_s: f64,
) -> Result<(Profile, Written), Error> {
    let (mut rate, mut accel) = (Tighten::NONE, Tighten::NONE);
    for _ in 0..WRITTEN_PASSES {
        let mut eff = *limits;
        for v in &mut eff.qd_max {
            *v *= rate.f;
        }
        for a in &mut eff.qdd_max {
            *a *= accel.f;
        }
        let profile = solve(grid, path, &eff)?;
        let mut stream = Stream::new(&profile, dt_s)?;
        let mut check = WrittenCheck::new(limits, dt_s);
        while let Some(sp) = stream.next(grid) {
            check.push(&sp.q);
        }
        let w = check.worst();
        if !(w.rate.is_finite() && w.accel.is_finite()) {
            return Err(Error::NonFiniteState { step: 0 });
        }
        let tighter_rate = rate.update(w.rate);
        let tighter_accel = accel.update(w.accel);
        if !(tighter_rate || tighter_accel) {
            return Ok((profile, w));
        }
    }
    Err(Error::RetimeStalled { point: 0 })
}

/// One re-timed setpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Setpoint<const N: usize> {
    /// Index `k` (`0..=K`).
    pub step: u32,
    /// `t = k·dt` (s).
    pub t: f64,
    /// Joint positions (rad).
    pub q: [f64; N],
    /// Joint rates (rad/s); zero at both ends.
    pub qd: [f64; N],
    /// Joint accelerations (rad/s²).
    pub qdd: [f64; N],
}

impl<const N: usize> Setpoint<N> {
    /// Folds this setpoint into `d`: `t`, then `q`, `q̇`, `q̈` (the digest host and target
    /// compare).
    pub fn digest(&self, d: &mut crate::digest::TrajectoryDigest) {
        d.push(self.t);
        for v in self.q.iter().chain(&self.qd).chain(&self.qdd) {
            d.push(*v);
        }
    }
}

/// The setpoints of a [`Profile`] every `dt`, from `0` to `K·dt ≥ T*`: O(1) state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stream {
    profile: Profile,
    dt: f64,
    steps: u32,
    scale: f64,
    k: u32,
    seg: u32,
    seg_t0: f64,
}

impl Stream {
    /// A stream at step `dt_s` (s).
    ///
    /// # Errors
    /// A non-finite or non-positive `dt_s` ([`Param::TimeStep`]); [`Error::TooManySteps`]
    /// if `T*/dt` exceeds [`MAX_STEPS`].
    pub fn new(profile: &Profile, dt_s: f64) -> Result<Self, Error> {
        check_positive(dt_s, Param::TimeStep)?;
        let ratio = profile.duration / dt_s;
        if ratio.is_nan() || ratio >= f64::from(MAX_STEPS) {
            return Err(Error::TooManySteps {
                max: crate::MAX_STEPS,
            });
        }
        // Round up to a whole step; a ratio within 1e-9 of an integer is that integer.
        let near = libm::round(ratio);
        let steps = if libm::fabs(near - ratio) <= 1e-9 * ratio {
            near
        } else {
            libm::ceil(ratio)
        };
        let steps = (steps as u32).max(1);
        Ok(Self {
            profile: *profile,
            dt: dt_s,
            steps,
            scale: profile.duration / (f64::from(steps) * dt_s),
            k: 0,
            seg: 0,
            seg_t0: 0.0,
        })
    }

    /// Steps `K`: the stream yields `K + 1` setpoints.
    #[must_use]
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Duration written, `K·dt` (s).
    #[must_use]
    pub fn duration(&self) -> f64 {
        f64::from(self.steps) * self.dt
    }

    /// The time scale `r = T*/(K·dt)` ∈ (0, 1].
    #[must_use]
    pub fn scale(&self) -> f64 {
        self.scale
    }

    /// The next setpoint, or `None` after the last. `grid` is the solved grid of the
    /// profile (unchanged since [`solve`]); a shorter grid ends the stream.
    pub fn next<const N: usize>(&mut self, grid: &[GridPoint<N>]) -> Option<Setpoint<N>> {
        let path = self.profile.path;
        let m = path.m;
        if self.k > self.steps || grid.len() < m as usize {
            return None;
        }
        let k = self.k;
        self.k += 1;
        let last = k == self.steps;
        let tau = if last {
            self.profile.duration
        } else {
            f64::from(k) * self.dt * self.scale
        };
        let ds = path.ds;
        let x_at = |i: u32| grid.get(i as usize).map_or(0.0, |g| g.x);
        while self.seg < m - 2 {
            let d = segment_time(ds, x_at(self.seg), x_at(self.seg + 1));
            if self.seg_t0 + d > tau {
                break;
            }
            self.seg_t0 += d;
            self.seg += 1;
        }
        let i = self.seg;
        let (xa, xb) = (x_at(i), x_at(i + 1));
        let u = (xb - xa) / (2.0 * ds);
        let dur = segment_time(ds, xa, xb);
        let local = clamp(tau - self.seg_t0, 0.0, dur);
        let sa = libm::sqrt(xa);
        let (sigma, sdot) = if last {
            (1.0, 0.0)
        } else {
            let s = clamp(sa * local + 0.5 * u * local * local, 0.0, ds);
            (s / ds, (sa + u * local).max(0.0))
        };
        let a1 = derivatives(grid, &path, i);
        let b1 = derivatives(grid, &path, i + 1);
        let (ga, gb) = (grid.get(i as usize)?, grid.get((i + 1) as usize)?);
        let r = self.scale;
        let mut sp = Setpoint {
            step: k,
            t: f64::from(k) * self.dt,
            q: [0.0; N],
            qd: [0.0; N],
            qdd: [0.0; N],
        };
        // The position written is the cubic Hermite in s through both grid points with the
        // tangents q' of the solve: C¹ in s, so no velocity jump at a grid point that a
        // written second difference would see whole (chords between grid points gave up to
        // 7× the limit on slow paths). The rate and acceleration carried are the solve's
        // model: q' linear in s, q'' = (q'_{i+1} − q'_i)/Δ constant over the segment.
        let x = sigma;
        let (x2, x3) = (x * x, x * x * x);
        let h = [
            2.0 * x3 - 3.0 * x2 + 1.0,
            x3 - 2.0 * x2 + x,
            3.0 * x2 - 2.0 * x3,
            x3 - x2,
        ];
        for j in 0..N {
            let at = |v: &[f64; N]| v.get(j).copied().unwrap_or(0.0);
            let (qa, qb, pa, pb) = (at(&ga.q), at(&gb.q), at(&a1), at(&b1));
            let q = h[0] * qa + h[1] * ds * pa + h[2] * qb + h[3] * ds * pb;
            let p = (1.0 - sigma) * pa + sigma * pb;
            let w = (pb - pa) / ds;
            if let (Some(oq), Some(od), Some(oa)) =
                (sp.q.get_mut(j), sp.qd.get_mut(j), sp.qdd.get_mut(j))
            {
                *oq = if last { qb } else { q };
                *od = p * sdot * r;
                *oa = (p * u + w * sdot * sdot) * (r * r);
            }
        }
        Some(sp)
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    fn line(grid: &mut [GridPoint<2>], m: u32, len: f64) -> Path {
        let samples = [[0.0, 0.0], [len * 0.6, len * 0.8]];
        let mut arc = ArcLength::new();
        samples.iter().for_each(|q| arc.push(q));
        let mut b = PathBuilder::new(grid, m, arc.length()).unwrap();
        samples.iter().for_each(|q| b.push(q));
        b.finish().unwrap()
    }

    /// A straight line under an acceleration limit only is bang-bang:
    /// `T = 2√(L/a)` with `a` the path acceleration the binding joint allows.
    /// Verifies RL-RETIME-001.
    #[test]
    fn straight_line_is_bang_bang() {
        let mut grid = [GridPoint::<2>::ZERO; 2001];
        let path = line(&mut grid, 2001, 1.0);
        let limits = Limits::new([100.0; 2], [1.0; 2], 1.0).unwrap();
        let p = solve(&mut grid, &path, &limits).unwrap();
        // Joint 2 binds: its tangent component is 0.8, so s̈ ≤ 1/0.8.
        let exact = 2.0 * libm::sqrt(1.0 / 1.25);
        assert!(
            (p.duration() - exact).abs() < 2e-3 * exact,
            "{}",
            p.duration()
        );
    }

    /// Verifies RL-RETIME-005.
    #[test]
    fn bad_inputs_are_typed_errors() {
        let mut grid = [GridPoint::<2>::ZERO; 4];
        assert_eq!(
            PathBuilder::new(&mut grid, 5, 1.0).err(),
            Some(Error::CapacityExceeded {
                param: Param::RetimeGrid,
                requested: 5,
                capacity: 4
            })
        );
        assert_eq!(
            PathBuilder::new(&mut grid, 2, 1.0).err(),
            Some(Error::GridTooSmall { min: MIN_GRID })
        );
        assert_eq!(
            PathBuilder::new(&mut grid, 4, 0.0).err(),
            Some(Error::PathTooShort)
        );
        assert_eq!(
            Limits::new([1.0, f64::NAN], [1.0; 2], 1.0).err(),
            Some(Error::NotFinite(Param::VelocityLimit(2)))
        );
        assert_eq!(
            Limits::new([1.0; 2], [1.0, -1.0], 1.0).err(),
            Some(Error::NotPositive(Param::AccelLimit(2)))
        );
        assert_eq!(
            Limits::new([1.0; 2], [1.0; 2], 1.5).err(),
            Some(Error::MarginAboveOne)
        );
        // A path that stops and moves on.
        let samples = [[0.0, 0.0], [1.0, 0.0], [1.0, 0.0], [2.0, 0.0]];
        let mut b = PathBuilder::new(&mut grid, 4, 2.0).unwrap();
        samples.iter().for_each(|q| b.push(q));
        assert_eq!(b.finish().err(), Some(Error::PathStalls { sample: 2 }));
        // A path that turns back.
        let samples = [[0.0, 0.0], [1.0, 0.0], [0.5, 0.0]];
        let mut b = PathBuilder::new(&mut grid, 4, 1.5).unwrap();
        samples.iter().for_each(|q| b.push(q));
        assert_eq!(b.finish().err(), Some(Error::PathStalls { sample: 1 }));
        // Other samples than the measured ones.
        let mut b = PathBuilder::new(&mut grid, 4, 2.0).unwrap();
        [[0.0, 0.0], [1.0, 0.0]].iter().for_each(|q| b.push(q));
        assert_eq!(b.finish().err(), Some(Error::PathMismatch));
    }
}
