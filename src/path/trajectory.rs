//! The time law of eqs. 4–14 (spec §4) and the time grid of the rollout (spec §5).
//!
//! Owns [`Motion`] (duration `t_f`, step `dt`, degree `n`, step count `S = t_f/dt`, family,
//! segments), [`Eta`] and [`TimeLaw`]: from `η = [a₁, b₁, …, a_K, b_K]` the polynomials
//!
//! `β_i(t) = a_i t^{n+2} + b_i t^{n+1} + c_i t^n`, `c_i = −(a_i t_f² + b_i t_f)` (eq. 10),
//!
//! evaluated in the equal factored form `β_i(t) = tⁿ (t − t_f)(a_i (t + t_f) + b_i)`, which
//! is exactly zero at `t = 0` and `t = t_f` (eq. 7 holds to the bit). `β_i,max` is the
//! largest `|β_i|` over the critical points in `[0, t_f]` (eqs. 11–13) and
//! `g = Σ β_i,max / q̇_max` (eq. 14), so `|q̇_r(t)| ≤ q̇_max` for every joint.
//!
//! **Families.** [`Family::Paper`] is the above, bit for bit. [`Family::FreeAmplitude`]
//! (for tasks whose start is fixed, issue #30) keeps the same polynomials and frees the two
//! things eq. 14 fixes: the bound is the exact one on the samples the rollout writes,
//! `g = max_s ‖β(t_s)‖₂ / q̇_max` over `t_s = s·dt`, `s = 0 … S` (the basis columns are
//! orthonormal, so `‖q̇_s‖₂ = ‖β(t_s)‖₂/g` and every joint keeps `|q̇| ≤ q̇_max`; eq. 14's
//! sum over-estimates that norm by up to `√K`); and η's magnitude becomes the amplitude:
//! `g = max(G₀, max_s ‖β(t_s)‖₂ / q̇_max)` with the fixed `G₀ = t_f^{n+2}/(4 q̇_max)`, so
//! `q̇ = Σ β_i n_i / G₀` is linear in η (smooth for the search) until η reaches the rate
//! bound, and every longer η of that direction is the bound's motion. The search then has
//! `2K` unknowns, not `2K − 1`.
//!
//! **Segments** ([`Motion::with_segments`], free-amplitude family): the motion is cut into
//! up to [`MAX_SEGMENTS`] equal rest-to-rest segments, each the time law above on the local
//! time of its segment with its own `(a_i, b_i)` ([`Eta`]: one set of pairs per segment;
//! [`TimeLaw::of`]). The search then has `2K·segments` unknowns. One segment is the motion
//! above, bit for bit.
//!
//! Only η's direction matters (paper family). η is first scaled by an exact power of two so that its
//! largest component lies in `[1, 2)`: results are bit-identical to the unscaled η for any
//! ordinary magnitude, and extreme magnitudes (1e±300, subnormals) work. The one limit is
//! that `g`, reported for η as given, must be a finite `f64`: an η for which it overflows
//! (`|η|·t_f^{n+2}/q̇_max ≳ 1e308`) is rejected with [`Error::EtaTooLarge`].

use crate::error::{Error, NeedsOneSegment, Param};
use crate::lanes::Real;

/// Largest accepted time-law degree `n`.
pub const MAX_DEGREE: u32 = 8;
/// Largest accepted step count `S = t_f/dt`.
pub const MAX_STEPS: u32 = 1_000_000;
/// Most segments of one motion ([`Motion::with_segments`]).
pub const MAX_SEGMENTS: usize = 4;

/// η of a whole motion: the pairs `(a_i, b_i)` of each segment, in time order. Segments past
/// the motion's count ([`Motion::segments`]) are not read; by convention they are zero.
pub type Eta<const K: usize> = [[[f64; 2]; K]; MAX_SEGMENTS];

/// The η of a one-segment motion: `pairs`, then zero segments.
#[must_use]
pub const fn one_segment<const K: usize>(pairs: [[f64; 2]; K]) -> Eta<K> {
    let zero = [[0.0; 2]; K];
    [pairs, zero, zero, zero]
}

/// The first `segments` segments of `eta`, flat: `a₁, b₁, …, a_K, b_K` of segment 1, then
/// segment 2's, … (`2K·segments` numbers).
pub fn eta_flat<const K: usize>(eta: &Eta<K>, segments: u32) -> impl Iterator<Item = f64> + '_ {
    eta.iter()
        .take(segments as usize)
        .flat_map(|s| s.iter().flat_map(|p| p.iter().copied()))
}

/// η of `segments` segments from its flat form ([`eta_flat`]).
///
/// # Errors
/// [`Error::WrongLength`] unless `flat.len() == 2K·segments`;
/// [`Error::CapacityExceeded`] for more than [`MAX_SEGMENTS`] segments.
pub fn eta_from_flat<const K: usize>(flat: &[f64], segments: u32) -> Result<Eta<K>, Error> {
    if segments as usize > MAX_SEGMENTS || segments == 0 {
        return Err(Error::CapacityExceeded {
            param: Param::Segments,
            requested: segments,
            capacity: MAX_SEGMENTS as u32,
        });
    }
    let want = 2 * K * segments as usize;
    if flat.len() != want {
        return Err(Error::WrongLength {
            expected: want.min(u16::MAX as usize) as u16,
            got: flat.len().min(u16::MAX as usize) as u16,
        });
    }
    let mut out = one_segment([[0.0; 2]; K]);
    for (seg, chunk) in out.iter_mut().zip(flat.chunks_exact(2 * K)) {
        *seg = eta_pairs::<K>(chunk)?;
    }
    Ok(out)
}

/// Which velocity profiles one η names (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum Family {
    /// Eqs. 4–14 as the paper has them: direction-only η, `g = Σ β_i,max / q̇_max`.
    #[default]
    Paper,
    /// The exact rate bound on the written samples, and η's magnitude as the amplitude.
    FreeAmplitude,
}

impl Family {
    /// Both families, in wire-code order.
    pub const ALL: [Family; 2] = [Family::Paper, Family::FreeAmplitude];

    /// The name used in task files and reports.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Family::Paper => "paper",
            Family::FreeAmplitude => "free_amplitude",
        }
    }

    /// The family of `name` ([`Family::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Wire code (0 paper, 1 free amplitude).
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Family::Paper => 0,
            Family::FreeAmplitude => 1,
        }
    }

    /// The family of wire `code`.
    #[must_use]
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.code() == code)
    }

    /// Whether η's magnitude matters (the search then has `2K` unknowns).
    #[must_use]
    pub const fn free_amplitude(self) -> bool {
        matches!(self, Family::FreeAmplitude)
    }
}

/// How a rollout integrates the joint path and its null-space basis (spec §5, §14).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[cfg_attr(
    feature = "serde",
    derive(serde::Deserialize, serde::Serialize),
    serde(rename_all = "snake_case")
)]
pub enum Integrator {
    /// The reference discretization: explicit Euler on the `dt` grid, the basis carried by
    /// `MGS(P N)` (eq. 19, spec §3, §5). The paper's mode; golden records use it.
    #[default]
    Euler,
    /// The continuous path of spec §14 integrated to fourth order: classical Runge–Kutta
    /// on `(q, N)` with `q̇ = N α(t)` and `Ṅ = −A⁺ Ȧ N` (`Ȧ` exact, from [`crate::dual`]),
    /// in steps of a whole number of `dt` ([`Motion::stride`]), and the samples on the `dt`
    /// grid from a cubic Hermite dense output ([`crate::integrator`]).
    Rk4,
    /// The same continuous path and dense output as [`Integrator::Rk4`], integrated by the
    /// fifth-order Adams–Bashforth method: one evaluation of `(q̇, Ṅ)` per step from the
    /// rates of the four steps before it, the first four steps of each segment by RK4. Half
    /// RK4's step ([`AB5_STEP_S`]) for the same accuracy at about half the evaluations, at
    /// the price of four past rates in the rollout's state.
    Ab5,
}

impl Integrator {
    /// Every integrator, in wire-code order.
    pub const ALL: [Integrator; 3] = [Integrator::Euler, Integrator::Rk4, Integrator::Ab5];

    /// The name used in task files and reports.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Integrator::Euler => "euler",
            Integrator::Rk4 => "rk4",
            Integrator::Ab5 => "ab5",
        }
    }

    /// The integrator of `name` ([`Integrator::name`]).
    #[must_use]
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Wire code (0 Euler, 1 RK4, 2 AB5).
    #[must_use]
    pub const fn code(self) -> u8 {
        match self {
            Integrator::Euler => 0,
            Integrator::Rk4 => 1,
            Integrator::Ab5 => 2,
        }
    }

    /// The integrator of wire `code`.
    #[must_use]
    pub fn from_code(code: u8) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.code() == code)
    }

    /// The default step (s): [`RK4_STEP_S`], [`AB5_STEP_S`], or 0 for Euler (its step is
    /// the motion's `dt`).
    #[must_use]
    pub const fn default_step_s(self) -> f64 {
        match self {
            Integrator::Euler => 0.0,
            Integrator::Rk4 => RK4_STEP_S,
            Integrator::Ab5 => AB5_STEP_S,
        }
    }
}

/// The default step of [`Integrator::Rk4`] (s): [`Motion::with_integrator`] takes the
/// largest whole number of `dt` that divides a segment and is at most this.
pub const RK4_STEP_S: f64 = 0.4;

/// The default step of [`Integrator::Ab5`] (s), as [`RK4_STEP_S`] is RK4's: the end pose
/// of the reference task within 1e-8 m of the continuous path (`tests/continuous.rs`).
pub const AB5_STEP_S: f64 = 0.2;

/// The largest default RK4 (or AB5) stride (samples per step): what a task block carries (bits
/// 8–15 of its degree word), so that a default RK4 motion always fits a block.
pub const RK4_MAX_DEFAULT_STRIDE: u32 = 255;

/// Duration and time grid of a motion.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Motion {
    tf: f64,
    dt: f64,
    steps: u32,
    /// `n ≤ MAX_DEGREE`; 16 bits so that the family and segment count fit beside it (24
    /// bytes in all).
    n: u16,
    family: Family,
    /// `1..=MAX_SEGMENTS`, dividing `steps`.
    segments: u8,
    integrator: Integrator,
    /// Samples (steps of `dt`) per integrator step: 1 for Euler; for RK4 it divides a
    /// segment's steps.
    stride: u16,
}

impl Motion {
    /// Zero steps (a placeholder for statically allocated state).
    pub const IDLE: Self = Self {
        tf: 0.0,
        dt: 0.0,
        steps: 0,
        n: 1,
        family: Family::Paper,
        segments: 1,
        integrator: Integrator::Euler,
        stride: 1,
    };

    /// A motion of duration `tf_s` (s) integrated with step `dt_s` (s), time-law degree `n`.
    ///
    /// # Errors
    /// Non-finite or non-positive `tf_s`/`dt_s`, `t_f/dt` not a whole number (relative
    /// tolerance 1e-9) or above [`MAX_STEPS`], `n` outside `1..=`[`MAX_DEGREE`].
    ///
    /// Verifies RL-ROB-003.
    ///
    /// ```
    /// let m = reactionless::Motion::new(30.0, 0.01, 1).unwrap();
    /// assert_eq!(m.steps(), 3000);
    /// assert!(reactionless::Motion::new(30.0, 0.007, 1).is_err());
    /// ```
    pub fn new(tf_s: f64, dt_s: f64, n: u32) -> Result<Self, Error> {
        for (v, p) in [(tf_s, Param::FinalTime), (dt_s, Param::TimeStep)] {
            if !v.is_finite() {
                return Err(Error::NotFinite(p));
            }
            if v <= 0.0 {
                return Err(Error::NotPositive(p));
            }
        }
        if !(1..=MAX_DEGREE).contains(&n) {
            return Err(Error::DegreeOutOfRange { max: MAX_DEGREE });
        }
        let ratio = tf_s / dt_s;
        // tf, dt are finite and positive, so `ratio` is positive or +∞ (never NaN).
        if ratio >= f64::from(MAX_STEPS) + 0.5 {
            return Err(Error::TooManySteps { max: MAX_STEPS });
        }
        let steps = libm::round(ratio);
        if steps < 1.0 || libm::fabs(steps - ratio) > 1e-9 * ratio {
            return Err(Error::StepsNotInteger);
        }
        Ok(Self {
            tf: tf_s,
            dt: dt_s,
            steps: steps as u32,
            n: n as u16,
            family: Family::Paper,
            segments: 1,
            integrator: Integrator::Euler,
            stride: 1,
        })
    }

    /// The same grid with the velocity profiles of `family` ([`Motion::new`] gives
    /// [`Family::Paper`]).
    #[must_use]
    pub fn with_family(self, family: Family) -> Self {
        Self { family, ..self }
    }

    /// The family of velocity profiles.
    #[must_use]
    pub fn family(&self) -> Family {
        self.family
    }

    /// The same motion cut into `segments` equal segments, each a rest-to-rest motion of
    /// its own η ([`TimeLaw::of`]; [`Motion::new`] gives one).
    ///
    /// # Errors
    /// [`Error::NotPositive`] for 0 and [`Error::CapacityExceeded`] above [`MAX_SEGMENTS`]
    /// (both naming [`Param::Segments`]); [`Error::SegmentsUneven`] unless the segment
    /// count divides `t_f/dt`; [`Error::NeedsOneSegment`] for several segments of the
    /// paper's family; [`Error::StrideUneven`] if an RK4 stride no longer divides a
    /// segment.
    ///
    /// ```
    /// use reactionless::{Family, Motion};
    /// let m = Motion::new(30.0, 0.01, 1).unwrap().with_family(Family::FreeAmplitude);
    /// let four = m.with_segments(4).unwrap();
    /// assert_eq!((four.segments(), four.segment().steps(), four.segment().tf()), (4, 750, 7.5));
    /// assert!(m.with_segments(7).is_err()); // 3,000 steps do not split into 7 (and 7 > 4)
    /// assert!(m.with_family(Family::Paper).with_segments(2).is_err());
    /// ```
    pub fn with_segments(self, segments: u32) -> Result<Self, Error> {
        if segments == 0 {
            return Err(Error::NotPositive(Param::Segments));
        }
        if segments as usize > MAX_SEGMENTS {
            return Err(Error::CapacityExceeded {
                param: Param::Segments,
                requested: segments,
                capacity: MAX_SEGMENTS as u32,
            });
        }
        if self.steps % segments != 0 {
            return Err(Error::SegmentsUneven { segments });
        }
        if segments > 1 && self.family == Family::Paper {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::PaperFamily));
        }
        let cut = Self {
            segments: segments as u8,
            ..self
        };
        // An RK4 stride stays as it was; it must still divide a segment.
        cut.with_integrator_stride(cut.stride())
    }

    /// The same motion integrated by `integrator`, with its default step: 1 step of `dt`
    /// for [`Integrator::Euler`]; for [`Integrator::Rk4`] the largest whole number of `dt`
    /// that divides a segment's steps and is at most [`RK4_STEP_S`] and at most
    /// [`RK4_MAX_DEFAULT_STRIDE`] (at least one `dt`). Cut the motion into segments first:
    /// [`Motion::with_segments`] keeps the stride, and refuses one that does not divide.
    ///
    /// # Errors
    /// None: the default always divides (kept as a `Result` for the stride's check).
    ///
    /// ```
    /// use reactionless::{Integrator, Motion};
    /// let m = Motion::new(30.0, 0.01, 1).unwrap().with_integrator(Integrator::Rk4).unwrap();
    /// assert_eq!((m.integrator(), m.stride()), (Integrator::Rk4, 40));
    /// ```
    pub fn with_integrator(self, integrator: Integrator) -> Result<Self, Error> {
        let stride = match integrator {
            Integrator::Euler => 1,
            Integrator::Rk4 | Integrator::Ab5 => {
                let per = self.segment().steps();
                let most = libm::floor(integrator.default_step_s() / self.dt + 1e-9)
                    .min(f64::from(RK4_MAX_DEFAULT_STRIDE))
                    .max(1.0);
                let most = (most as u32).min(per);
                // Bounded by `most ≤ per ≤ MAX_STEPS`; `1` always divides.
                (1..=most).rev().find(|d| per % d == 0).unwrap_or(1)
            }
        };
        Self { integrator, ..self }.with_integrator_stride(stride)
    }

    /// The same motion with `stride` samples (steps of `dt`) per integrator step.
    ///
    /// # Errors
    /// [`Error::StrideUneven`] unless `stride` is 1 for [`Integrator::Euler`], or for
    /// [`Integrator::Rk4`] at least 1, at most 65,535, and a divisor of each segment's
    /// steps.
    pub fn with_integrator_stride(self, stride: u32) -> Result<Self, Error> {
        let per = self.segment().steps();
        let fits = match self.integrator {
            Integrator::Euler => stride == 1,
            Integrator::Rk4 | Integrator::Ab5 => {
                stride >= 1 && stride <= u32::from(u16::MAX) && per % stride == 0
            }
        };
        if !fits {
            return Err(Error::StrideUneven { stride });
        }
        Ok(Self {
            stride: stride as u16,
            ..self
        })
    }

    /// How the path is integrated.
    #[must_use]
    pub fn integrator(&self) -> Integrator {
        self.integrator
    }

    /// Samples (steps of `dt`) per integrator step (1 for Euler).
    #[must_use]
    pub fn stride(&self) -> u32 {
        u32::from(self.stride)
    }

    /// Number of segments (1 unless [`Motion::with_segments`]).
    #[must_use]
    pub fn segments(&self) -> u32 {
        u32::from(self.segments)
    }

    /// The grid of one segment: duration `t_f/segments`, `S/segments` steps of `dt`, one
    /// segment (the motion itself when it has one).
    #[must_use]
    pub fn segment(&self) -> Motion {
        if self.segments <= 1 {
            return *self;
        }
        let count = u32::from(self.segments);
        Motion {
            tf: self.tf / f64::from(count),
            steps: self.steps / count,
            segments: 1,
            ..*self
        }
    }

    /// Duration `t_f` (s).
    #[must_use]
    pub fn tf(&self) -> f64 {
        self.tf
    }

    /// Integration step `dt` (s).
    #[must_use]
    pub fn dt(&self) -> f64 {
        self.dt
    }

    /// Time-law degree `n`.
    #[must_use]
    pub fn degree(&self) -> u32 {
        u32::from(self.n)
    }

    /// Number of integration steps `S`.
    #[must_use]
    pub fn steps(&self) -> u32 {
        self.steps
    }

    /// Sample time `t_s = s·dt` (s); the last sample (`s ≥ S`) is exactly `t_f`.
    #[must_use]
    pub fn time(&self, s: u32) -> f64 {
        if s >= self.steps {
            self.tf
        } else {
            f64::from(s) * self.dt
        }
    }
}

/// Parses the flat `η = [a₁, b₁, …, a_K, b_K]` (length `2K`) into pairs.
///
/// # Errors
/// [`Error::WrongLength`] unless `eta.len() == 2K`.
pub fn eta_pairs<const K: usize>(eta: &[f64]) -> Result<[[f64; 2]; K], Error> {
    let mut out = [[0.0; 2]; K];
    if eta.len() != 2 * K {
        return Err(Error::WrongLength {
            expected: (2 * K) as u16,
            got: eta.len().min(u16::MAX as usize) as u16,
        });
    }
    for (pair, chunk) in out.iter_mut().zip(eta.chunks_exact(2)) {
        if let [a, b] = chunk {
            *pair = [*a, *b];
        }
    }
    Ok(out)
}

/// Relative margin on the free-amplitude family's exact bound, so that rounding in the
/// basis (orthonormal to ~1e-15) never lifts a written `|q̇|` above `q̇_max`.
const RATE_MARGIN: f64 = 1e-12;

/// The free-amplitude family's fixed scale `G₀ = t_f^{n+2} / (4 q̇_max)`: the `g` of every η
/// slower than the rate bound, so that `q̇` is linear in η there. A unit `a_i` alone
/// (`b_i = 0`) then peaks at `4·max|τⁿ(τ² − 1)|·q̇_max` (1.54 q̇_max for `n = 1`): points of
/// the unit sphere of η are about as fast as the bound allows.
fn free_scale(tf: f64, n: u32, qd_max: f64) -> f64 {
    powi(tf, n + 2) / (4.0 * qd_max)
}

/// `max_s ‖β(t_s)‖₂` over the written samples `t_s` (`s = 0 … S`) of `motion`, for the
/// normalised `(a_i, b_i)`: the same expression and times as [`alpha`] in the rollout.
fn grid_peak_norm<const K: usize>(ab: &[[f64; 2]; K], motion: &Motion) -> f64 {
    let (tf, n) = (motion.tf(), motion.degree());
    let mut best = 0.0f64;
    for s in 0..=motion.steps().min(MAX_STEPS) {
        let beta = alpha(ab, 1.0, tf, n, motion.time(s));
        best = best.max(beta.iter().fold(0.0, |acc, v| acc + v * v));
    }
    libm::sqrt(best)
}

/// `tⁿ` by repeated multiplication (`n ≤ MAX_DEGREE`).
#[inline(always)]
fn powi<T: Real>(t: T, n: u32) -> T {
    let mut p = t;
    for _ in 1..n.min(MAX_DEGREE) {
        p *= t;
    }
    p
}

/// The velocity profile of one η: `β_i(t)`, `β_i,max` and `g` (eqs. 5–14), per segment
/// when the motion has several ([`Motion::with_segments`]).
///
/// **Segments.** Segment `k` (0-based) covers the steps `k·m … (k+1)·m` (`m = S/segments`)
/// with its own `(a_i, b_i)` and `g`, on the local time `τ = (s − k·m)·dt` of one segment
/// ([`Motion::segment`]): its `β_i(τ)` vanishes at both ends, so the motion rests at every
/// junction and `q̇` stays continuous. One segment is the time law above, bit for bit.
#[derive(Debug, Clone, Copy, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TimeLaw<const K: usize> {
    /// Normalised `(a_i, b_i)` of each segment.
    ab: Eta<K>,
    /// One segment's duration (s): `t_f` for one segment.
    tf: f64,
    /// The whole motion's `t_f` (s).
    total: f64,
    n: u32,
    /// Segments (`1..=MAX_SEGMENTS`).
    segments: u32,
    /// `β_i,max` of the first segment, normalised.
    beta_max: [f64; K],
    /// `1/g` for each segment's normalised η (s·rad⁻¹ scale).
    inv_g: [f64; MAX_SEGMENTS],
    /// `g` for each segment's normalised η.
    g: [f64; MAX_SEGMENTS],
    /// Each segment's η was multiplied by `2^scale_exp`.
    scale_exp: [i32; MAX_SEGMENTS],
}

/// One segment of a [`TimeLaw`]: normalised pairs, `β_i,max`, `g`, scale exponent.
type Segment<const K: usize> = ([[f64; 2]; K], [f64; K], f64, i32);

impl<const K: usize> TimeLaw<K> {
    /// The time law of `eta` (pairs `(a_i, b_i)`) for a one-segment `motion`, with joint
    /// rate bound `qd_max` (rad/s).
    ///
    /// # Errors
    /// [`Error::NotFinite`] for a non-finite component, [`Error::EtaZero`] if all are zero,
    /// [`Error::NotPositive`] / [`Error::NotFinite`] for a bad `qd_max`,
    /// [`Error::WrongLength`] for a motion of several segments ([`TimeLaw::of`]).
    ///
    /// Verifies RL-LAW-004.
    ///
    /// ```
    /// use reactionless::{Motion, TimeLaw};
    /// let law = TimeLaw::new(&[[1.0, 0.0]], &Motion::new(2.0, 0.01, 1).unwrap(), 1.0).unwrap();
    /// // β = t(t−2)(t+2): |β| peaks at t = 2/√3 with value 16/(3√3).
    /// assert!((law.g() - 16.0 / (3.0 * 3f64.sqrt())).abs() < 1e-14);
    /// ```
    pub fn new(eta: &[[f64; 2]; K], motion: &Motion, qd_max: f64) -> Result<Self, Error> {
        if motion.segments() > 1 {
            return Err(Error::WrongLength {
                expected: (2 * K as u32 * motion.segments()).min(u32::from(u16::MAX)) as u16,
                got: (2 * K).min(u16::MAX as usize) as u16,
            });
        }
        Self::of(&one_segment(*eta), motion, qd_max)
    }

    /// The time law of `eta` (the first [`Motion::segments`] segments are read) for
    /// `motion`, with joint rate bound `qd_max` (rad/s).
    ///
    /// # Errors
    /// As [`TimeLaw::new`], per segment ([`Param::Eta`] counts the flat η of
    /// [`eta_flat`]); [`Error::NeedsOneSegment`] for several segments of the paper's family.
    pub fn of(eta: &Eta<K>, motion: &Motion, qd_max: f64) -> Result<Self, Error> {
        if !qd_max.is_finite() {
            return Err(Error::NotFinite(Param::VelocityLimit(0)));
        }
        if qd_max <= 0.0 {
            return Err(Error::NotPositive(Param::VelocityLimit(0)));
        }
        let segments = motion.segments().clamp(1, MAX_SEGMENTS as u32);
        if segments > 1 && motion.family() == Family::Paper {
            return Err(Error::NeedsOneSegment(NeedsOneSegment::PaperFamily));
        }
        let grid = motion.segment();
        let mut law = Self {
            ab: one_segment([[0.0; 2]; K]),
            tf: grid.tf(),
            total: motion.tf(),
            n: motion.degree(),
            segments,
            beta_max: [0.0; K],
            inv_g: [0.0; MAX_SEGMENTS],
            g: [0.0; MAX_SEGMENTS],
            scale_exp: [0; MAX_SEGMENTS],
        };
        for (k, pairs) in eta.iter().enumerate().take(segments as usize) {
            let (ab, beta_max, g, scale_exp) = segment(pairs, &grid, qd_max, 2 * K * k)?;
            if k == 0 {
                law.beta_max = beta_max;
            }
            if let (Some(a), Some(i), Some(gg), Some(e)) = (
                law.ab.get_mut(k),
                law.inv_g.get_mut(k),
                law.g.get_mut(k),
                law.scale_exp.get_mut(k),
            ) {
                *a = ab;
                *i = 1.0 / g;
                *gg = g;
                *e = scale_exp;
            }
        }
        Ok(law)
    }

    /// The segment of time `t` (s) and the local time in it.
    fn locate(&self, t: f64) -> (usize, f64) {
        if self.segments <= 1 {
            return (0, t);
        }
        let last = self.segments as usize - 1;
        if t >= self.total {
            return (last, self.tf);
        }
        let k = (libm::floor(t / self.tf).max(0.0) as usize).min(last);
        (k, t - k as f64 * self.tf)
    }

    /// `β_i(t)` for the η as given (not normalised).
    #[must_use]
    pub fn beta(&self, t: f64) -> [f64; K] {
        let (k, t) = self.locate(t);
        let (Some(ab), Some(&e)) = (self.ab.get(k), self.scale_exp.get(k)) else {
            return [0.0; K];
        };
        let tn = powi(t, self.n);
        ab.map(|[a, b]| libm::scalbn(tn * (t - self.tf) * (a * (t + self.tf) + b), -e))
    }

    /// `α_i(t) = β_i(t)/g` (rad/s): the weights of the basis vectors in `q̇` (eq. 4 with unit
    /// columns). Scale-invariant in η for [`Family::Paper`]; for [`Family::FreeAmplitude`]
    /// it is linear in η below the rate bound and invariant above it.
    #[inline]
    #[must_use]
    pub fn alpha(&self, t: f64) -> [f64; K] {
        let (k, t) = self.locate(t);
        let (ab, inv_g) = self.weights(k);
        alpha(ab, inv_g, self.tf, self.n, t)
    }

    /// The normalised `(a_i, b_i)` and `1/g` of segment `k` that [`TimeLaw::alpha`]
    /// evaluates (zero past the last segment).
    pub(crate) fn weights(&self, k: usize) -> (&[[f64; 2]; K], f64) {
        let [first, ..] = &self.ab;
        match (self.ab.get(k), self.inv_g.get(k)) {
            (Some(ab), Some(&inv_g)) => (ab, inv_g),
            _ => (first, 0.0),
        }
    }

    /// Number of segments.
    #[must_use]
    pub fn segments(&self) -> u32 {
        self.segments
    }

    /// `β_i,max` for the η as given (the first segment's).
    #[must_use]
    pub fn beta_max(&self) -> [f64; K] {
        let e = self.scale_exp.first().copied().unwrap_or(0);
        self.beta_max.map(|b| libm::scalbn(b, -e))
    }

    /// `g` for the η as given: eq. 14's, or the free-amplitude family's (module docs); the
    /// largest segment's; finite (see [`Error::EtaTooLarge`]).
    #[must_use]
    pub fn g(&self) -> f64 {
        let mut best = 0.0f64;
        for (g, e) in self
            .g
            .iter()
            .zip(self.scale_exp.iter())
            .take(self.segments as usize)
        {
            best = best.max(libm::scalbn(*g, -*e));
        }
        best
    }
}

/// One segment's normalised pairs, `β_i,max`, `g` and scale exponent, on the grid of one
/// segment; `offset` numbers its components in the flat η (for errors).
fn segment<const K: usize>(
    eta: &[[f64; 2]; K],
    motion: &Motion,
    qd_max: f64,
    offset: usize,
) -> Result<Segment<K>, Error> {
    let mut largest = 0.0f64;
    for (i, v) in eta.iter().flatten().enumerate() {
        if !v.is_finite() {
            return Err(Error::NotFinite(
                Param::Eta((offset + i + 1).min(255) as u8),
            ));
        }
        largest = largest.max(libm::fabs(*v));
    }
    if largest == 0.0 {
        return Err(Error::EtaZero);
    }
    // largest = m·2^e with m in [0.5, 1): scale by 2^(1−e) to bring it into [1, 2).
    let (_, e) = libm::frexp(largest);
    let scale_exp = 1 - e;
    let ab = eta.map(|[a, b]| [libm::scalbn(a, scale_exp), libm::scalbn(b, scale_exp)]);
    let tf = motion.tf();
    let n = motion.degree();
    let mut beta_max = [0.0; K];
    let mut sum = 0.0;
    for (bm, &[a, b]) in beta_max.iter_mut().zip(ab.iter()) {
        *bm = peak(a, b, tf, n);
        sum += *bm;
    }
    let g = match motion.family() {
        Family::Paper => sum / qd_max,
        Family::FreeAmplitude => {
            // `max(G₀, max_s ‖β(t_s)‖₂ / q̇_max)` in the scaled frame (β is linear in η,
            // so only G₀ needs the frame's factor); [`TimeLaw::g`] scales it back.
            let g0 = libm::scalbn(free_scale(tf, n, qd_max), scale_exp);
            g0.max(grid_peak_norm(&ab, motion) / qd_max * (1.0 + RATE_MARGIN))
        }
    };
    if !(g > 0.0 && g.is_finite()) {
        // Every β_i ≡ 0 up to rounding (cannot happen for a non-zero η; kept as a guard),
        // or a free-amplitude η so short (≲ 1e-300) that its g overflows: no motion.
        return Err(Error::EtaZero);
    }
    if !libm::scalbn(g, -scale_exp).is_finite() {
        return Err(Error::EtaTooLarge);
    }
    Ok((ab, beta_max, g, scale_exp))
}

/// `α_i(t) = tⁿ (t − t_f)(a_i (t + t_f) + b_i)/g` for normalised `(a_i, b_i)` and `1/g`:
/// [`TimeLaw::alpha`] of one η (`f64`), or of several side by side ([`Real`] lanes, each
/// lane its own η and time).
#[inline(always)]
pub(crate) fn alpha<const K: usize, T: Real>(
    ab: &[[T; 2]; K],
    inv_g: T,
    tf: f64,
    n: u32,
    t: T,
) -> [T; K] {
    let tn = powi(t, n);
    let w = t - tf;
    ab.map(|[a, b]| tn * w * (a * (t + tf) + b) * inv_g)
}

/// `max |β|` over the critical points in `[0, t_f]` of `β(t) = tⁿ(t − t_f)(a(t + t_f) + b)`.
///
/// `β' = t^{n−1}[(n+2)a t² + (n+1)b t + n c]` (eq. 11); the roots of the bracket (eq. 13)
/// are taken with the cancellation-free form `r₁ = q/A`, `r₂ = C/q`.
fn peak(a: f64, b: f64, tf: f64, n: u32) -> f64 {
    let nf = f64::from(n);
    let c = -(a * tf * tf + b * tf);
    let qa = (nf + 2.0) * a;
    let qb = (nf + 1.0) * b;
    let qc = nf * c;
    // Δ ≥ 0 by Rolle's theorem; clamp rounding noise.
    let disc = (qb * qb - 4.0 * qa * qc).max(0.0);
    let q = -0.5 * (qb + libm::copysign(libm::sqrt(disc), qb));
    let beta = |t: f64| libm::fabs(powi(t, n) * (t - tf) * (a * (t + tf) + b));
    let mut best = 0.0f64;
    if qa != 0.0 {
        let r = q / qa;
        if (0.0..=tf).contains(&r) {
            best = best.max(beta(r));
        }
    }
    if q != 0.0 {
        let r = qc / q;
        if (0.0..=tf).contains(&r) {
            best = best.max(beta(r));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;

    /// β_max by dense sampling, for comparison.
    fn sampled_peak(a: f64, b: f64, tf: f64, n: u32) -> f64 {
        let mut best = 0.0f64;
        for i in 0..=200_000 {
            let t = tf * f64::from(i) / 200_000.0;
            let c = -(a * tf * tf + b * tf);
            let v = a * t.powi(n as i32 + 2) + b * t.powi(n as i32 + 1) + c * t.powi(n as i32);
            best = best.max(v.abs());
        }
        best
    }

    /// β_max from the critical points (eqs. 11–13) matches dense sampling, never below it
    /// (n = 1…4, a = 0 included).
    /// Verifies RL-LAW-003.
    #[test]
    fn peak_matches_sampling_eqs_11_to_13() {
        for &(a, b) in &[
            (3.14771, 0.809316),
            (-4.1572, 4.29895),
            (0.0, 1.0),
            (1.0, -40.0),
            (-2.0, 55.0),
            (1e-9, 3.0),
        ] {
            for n in 1..=4 {
                let tf = 30.0;
                let exact = peak(a, b, tf, n);
                let sampled = sampled_peak(a, b, tf, n);
                assert!(exact >= sampled * (1.0 - 1e-12), "{a} {b} {n}");
                assert!(
                    (exact - sampled) / exact < 1e-6,
                    "{a} {b} {n}: {exact} {sampled}"
                );
            }
        }
    }

    /// The factored time law equals eq. 5 within 1e-12 and is exactly 0 at t = 0 and t =
    /// t_f.
    /// Verifies RL-LAW-001, RL-LAW-002.
    #[test]
    fn factored_form_equals_eq_5() {
        let (a, b, tf) = (1.3, -2.7, 4.0);
        let law = TimeLaw::<1>::new(&[[a, b]], &Motion::new(tf, 0.01, 2).unwrap(), 1.0).unwrap();
        let c = -(a * tf * tf + b * tf);
        for t in [0.3f64, 1.7, 3.99] {
            let eq5 = a * t.powi(4) + b * t.powi(3) + c * t.powi(2);
            assert!((law.beta(t)[0] - eq5).abs() < 1e-12);
        }
        assert_eq!(law.beta(0.0)[0], 0.0);
        assert_eq!(law.beta(tf)[0], 0.0);
    }

    /// 2^e·η gives a bit-identical α(t), subnormal and huge η too; η = 0, NaN and an
    /// overflowing g are errors.
    /// Verifies RL-LAW-007, RL-ROB-004.
    #[test]
    fn scaling_eta_by_powers_of_two_is_exact() {
        let m = Motion::new(30.0, 0.01, 1).unwrap();
        let eta = [[3.14771, 0.809316], [1.12249, 0.754006]];
        let base = TimeLaw::new(&eta, &m, 0.26).unwrap();
        for e in [-1000, -300, -1, 1, 7, 900] {
            let scaled = eta.map(|p| p.map(|v| libm::scalbn(v, e)));
            let law = TimeLaw::new(&scaled, &m, 0.26).unwrap();
            for t in [0.0, 0.01, 12.34, 29.99, 30.0] {
                assert_eq!(law.alpha(t), base.alpha(t));
            }
        }
        assert_eq!(
            TimeLaw::new(&[[0.0, 0.0], [0.0, 0.0]], &m, 0.26),
            Err(Error::EtaZero)
        );
        assert_eq!(
            TimeLaw::new(&[[1.0, f64::NAN], [0.0, 0.0]], &m, 0.26),
            Err(Error::NotFinite(Param::Eta(2)))
        );
        // Subnormals and huge values are direction-only too.
        let tiny = TimeLaw::new(&[[5e-324, 0.0], [0.0, 0.0]], &m, 0.26).unwrap();
        let one = TimeLaw::new(&[[1.0, 0.0], [0.0, 0.0]], &m, 0.26).unwrap();
        assert_eq!(tiny.alpha(7.0), one.alpha(7.0));
        let huge = TimeLaw::new(&[[libm::scalbn(1.0, 990), 0.0], [0.0, 0.0]], &m, 0.26).unwrap();
        assert_eq!(huge.alpha(7.0), one.alpha(7.0));
        // 1e300 still works; near f64::MAX, g itself would overflow: a clear error.
        let big = TimeLaw::new(&[[1e300, 0.0], [0.0, 0.0]], &m, 0.26).unwrap();
        assert!(big.g().is_finite());
        assert!((big.alpha(7.0)[0] - one.alpha(7.0)[0]).abs() < 1e-15);
        assert_eq!(
            TimeLaw::new(&[[f64::MAX, 0.0], [0.0, 0.0]], &m, 0.26),
            Err(Error::EtaTooLarge)
        );
    }

    /// The free-amplitude family: on every written sample `‖α(t_s)‖₂ ≤ q̇_max`, with
    /// equality (to the margin) at the fastest one once η reaches the bound; below it α is
    /// linear in η (`g = G₀`); the paper family is untouched by the family field (its g is
    /// eq. 14's, bit for bit) and the free bound is never below the exact one.
    /// Verifies RL-LAW-008.
    #[test]
    fn free_amplitude_bound_is_exact_on_the_samples() {
        let qd = 0.26;
        let paper = Motion::new(30.0, 0.01, 1).unwrap();
        let free = paper.with_family(Family::FreeAmplitude);
        assert_eq!(paper.family(), Family::Paper);
        let eta = [[3.14771, 0.809316], [1.12249, 0.754006], [4.7352, 0.406031]];
        let lp = TimeLaw::new(&eta, &paper, qd).unwrap();
        let lf = TimeLaw::new(&eta, &free, qd).unwrap();
        let peak = |law: &TimeLaw<3>, m: &Motion| {
            (0..=m.steps())
                .map(|s| {
                    law.alpha(m.time(s))
                        .iter()
                        .map(|a| a * a)
                        .sum::<f64>()
                        .sqrt()
                })
                .fold(0.0f64, f64::max)
        };
        // This η is past the bound: the fastest sample sits on it.
        let fastest = peak(&lf, &free);
        assert!(fastest <= qd && fastest > qd * (1.0 - 1e-11), "{fastest}");
        // Eq. 14's sum is more conservative: the paper's motion is slower.
        assert!(peak(&lp, &paper) < fastest);
        assert!(lf.g() < lp.g());
        // A short η is below the bound: g = G₀ and α scales with η.
        let short = eta.map(|p| p.map(|v| v * 1e-3));
        let half = eta.map(|p| p.map(|v| v * 5e-4));
        let ls = TimeLaw::new(&short, &free, qd).unwrap();
        let lh = TimeLaw::new(&half, &free, qd).unwrap();
        let g0 = 30f64.powi(3) / (4.0 * qd);
        assert!((ls.g() - g0).abs() <= 1e-12 * g0);
        for t in [0.5, 7.0, 21.3] {
            for (a, b) in ls.alpha(t).iter().zip(lh.alpha(t).iter()) {
                assert!((a - 2.0 * b).abs() <= 1e-15 * a.abs().max(1e-300));
            }
        }
        assert!(peak(&ls, &free) < qd);
        // Names and codes round-trip.
        for f in Family::ALL {
            assert_eq!(Family::from_name(f.name()), Some(f));
            assert_eq!(Family::from_code(f.code()), Some(f));
        }
        assert_eq!(Family::from_name("fast"), None);
    }

    /// Each bad motion (t_f, dt, whole steps, step count, degree) is its typed error; the
    /// last sample is at t_f.
    /// Verifies RL-ROB-003.
    #[test]
    fn motion_validation() {
        assert_eq!(Motion::new(30.0, 0.01, 1).unwrap().time(3000), 30.0);
        assert_eq!(
            Motion::new(0.0, 0.01, 1),
            Err(Error::NotPositive(Param::FinalTime))
        );
        assert_eq!(
            Motion::new(1.0, -0.01, 1),
            Err(Error::NotPositive(Param::TimeStep))
        );
        assert_eq!(
            Motion::new(f64::NAN, 0.01, 1),
            Err(Error::NotFinite(Param::FinalTime))
        );
        assert_eq!(Motion::new(1.0, 0.3, 1), Err(Error::StepsNotInteger));
        assert_eq!(
            Motion::new(1e6, 1e-3, 1),
            Err(Error::TooManySteps { max: MAX_STEPS })
        );
        assert_eq!(
            Motion::new(1.0, 0.01, 0),
            Err(Error::DegreeOutOfRange { max: MAX_DEGREE })
        );
        assert_eq!(
            Motion::new(1.0, 0.01, MAX_DEGREE + 1),
            Err(Error::DegreeOutOfRange { max: MAX_DEGREE })
        );
        assert_eq!(Motion::new(1.0, 2.0, 1), Err(Error::StepsNotInteger));
    }
}
