//! Numbers side by side: the arithmetic the rollout's hot path is written in, so that one
//! source integrates one candidate (`f64`) or `L` candidates in lockstep ([`Lanes`]).
//!
//! Owns the [`Real`] trait (what the hot path needs of a number), its two implementations
//! (`f64`, and [`Lanes<L>`]: `L` independent `f64`s), and [`Mask`] (one `bool` per lane).
//!
//! **Every lane gets the bits of the scalar computation.** The hot path is generic over
//! [`Real`] and the scalar rollout is its `f64` instance, so each lane of a [`Lanes`]
//! computation performs exactly the operations of the scalar one, in the same order:
//! - `+ − × ÷` and `sqrt` are IEEE-754 operations, correctly rounded, hence exact per lane
//!   whatever instructions carry them (scalar, SSE2, AVX2);
//! - no fused multiply-add: Rust never contracts `a * b + c` into an FMA, and nothing here
//!   calls `mul_add`; the x86-64 AVX2 build enables `avx2` only, not `fma`;
//! - `min`/`max` are `f64::min`/`f64::max` per lane, comparisons are per lane;
//! - `sincos` is `libm::sincos` per lane, or [`sincos_lanes`], proven bit-identical to it
//!   on `|x| < 2^20·π/2` by a test that sweeps that domain (larger arguments, infinities
//!   and NaNs fall back to `libm::sincos` lane by lane).
//!
//! Operations with an `f64` on the right (`Lanes<L> × f64`) broadcast it: the same bits as
//! an `f64 × f64` per lane. Since IEEE `+` and `×` are commutative bit for bit, the hot path
//! writes `v * dt` where the scalar formula reads `dt·v`.

use core::fmt::Debug;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// One `bool` per lane: the result of a comparison.
pub trait Mask: Copy + Debug + PartialEq {
    /// Lane-wise `and`.
    #[must_use]
    fn and(self, o: Self) -> Self;
    /// `true` if every lane is `true`.
    fn all(self) -> bool;
}

impl Mask for bool {
    #[inline(always)]
    fn and(self, o: Self) -> Self {
        self && o
    }
    #[inline(always)]
    fn all(self) -> bool {
        self
    }
}

/// The mask of [`Lanes`]: all ones (`true`) or all zeros (`false`) per lane, the form a
/// vector comparison produces. [`Mask::all`] is an `and`-reduction, which the compiler
/// keeps in vector registers (a short-circuiting test would make it split the comparisons,
/// and what feeds them, into per-lane scalar code).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LaneMask<const L: usize>(pub [u64; L]);

impl<const L: usize> LaneMask<L> {
    /// Lane `i` (`false` if out of range).
    #[inline(always)]
    #[must_use]
    pub fn lane(&self, i: usize) -> bool {
        self.0.get(i).is_some_and(|m| *m != 0)
    }
}

impl<const L: usize> Mask for LaneMask<L> {
    #[inline(always)]
    fn and(mut self, o: Self) -> Self {
        for (a, b) in self.0.iter_mut().zip(o.0) {
            *a &= b;
        }
        self
    }
    #[inline(always)]
    fn all(self) -> bool {
        self.0.iter().fold(u64::MAX, |m, v| m & v) != 0
    }
}

/// What the hot path needs of a number: IEEE arithmetic, also with an `f64` on the right,
/// `sqrt`, `abs`, `min`/`max`, `sincos` and comparisons, each exact per lane (see the
/// module documentation).
pub trait Real:
    Copy
    + Debug
    + PartialEq
    + 'static
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
    + DivAssign
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + num_traits::Zero
    + num_traits::One
{
    /// One `bool` per lane.
    type Mask: Mask;
    /// `0.0` in every lane.
    const ZERO: Self;
    /// `1.0` in every lane.
    const ONE: Self;
    /// `v` in every lane.
    fn splat(v: f64) -> Self;
    /// Correctly rounded square root, per lane.
    #[must_use]
    fn sqrt(self) -> Self;
    /// `|x|`, per lane.
    #[must_use]
    fn abs(self) -> Self;
    /// `f64::min`, per lane.
    #[must_use]
    fn min(self, o: Self) -> Self;
    /// `f64::max`, per lane.
    #[must_use]
    fn max(self, o: Self) -> Self;
    /// `libm::sincos`, per lane: `(sin x, cos x)`.
    fn sincos(self) -> (Self, Self);
    /// `self > o`, per lane (`false` with a NaN).
    fn gt(self, o: Self) -> Self::Mask;
    /// `self ≥ o`, per lane (`false` with a NaN).
    fn ge(self, o: Self) -> Self::Mask;
    /// Finite (not infinite, not NaN), per lane.
    fn finite(self) -> Self::Mask;
}

impl Real for f64 {
    type Mask = bool;
    const ZERO: Self = 0.0;
    const ONE: Self = 1.0;
    #[inline(always)]
    fn splat(v: f64) -> Self {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        libm::sqrt(self)
    }
    #[inline(always)]
    fn abs(self) -> Self {
        libm::fabs(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f64::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f64::max(self, o)
    }
    #[inline(always)]
    fn sincos(self) -> (Self, Self) {
        libm::sincos(self)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self > o
    }
    #[inline(always)]
    fn ge(self, o: Self) -> bool {
        self >= o
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.is_finite()
    }
}

/// `L` independent `f64` lanes, one per candidate integrated in lockstep. Plain arrays:
/// the compiler turns the per-lane loops into vector instructions of the target it builds
/// for (two lanes per SSE2 register, four per AVX2 register).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes<const L: usize>(pub [f64; L]);

impl<const L: usize> Lanes<L> {
    /// Lane `i` (0 if out of range).
    #[inline(always)]
    #[must_use]
    pub fn lane(&self, i: usize) -> f64 {
        self.0.get(i).copied().unwrap_or(0.0)
    }

    /// Sets lane `i` (nothing if out of range).
    #[inline(always)]
    pub fn set(&mut self, i: usize, v: f64) {
        if let Some(x) = self.0.get_mut(i) {
            *x = v;
        }
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut r = self.0;
        for v in &mut r {
            *v = f(*v);
        }
        Lanes(r)
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut r = self.0;
        for (a, b) in r.iter_mut().zip(o.0) {
            *a = f(*a, b);
        }
        Lanes(r)
    }

    #[inline(always)]
    fn test(self, o: Self, f: impl Fn(f64, f64) -> bool) -> LaneMask<L> {
        let mut m = [0; L];
        for ((m, a), b) in m.iter_mut().zip(self.0).zip(o.0) {
            *m = if f(a, b) { u64::MAX } else { 0 };
        }
        LaneMask(m)
    }
}

macro_rules! lane_ops {
    ($($tr:ident $f:ident $atr:ident $af:ident $op:tt),*) => {$(
        impl<const L: usize> $tr for Lanes<L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl<const L: usize> $tr<f64> for Lanes<L> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: f64) -> Self {
                self.map(|a| a $op o)
            }
        }
        impl<const L: usize> $atr for Lanes<L> {
            #[inline(always)]
            fn $af(&mut self, o: Self) {
                *self = *self $op o;
            }
        }
    )*};
}

lane_ops!(
    Add add AddAssign add_assign +,
    Sub sub SubAssign sub_assign -,
    Mul mul MulAssign mul_assign *,
    Div div DivAssign div_assign /
);

impl<const L: usize> Neg for Lanes<L> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}

impl<const L: usize> num_traits::Zero for Lanes<L> {
    #[inline(always)]
    fn zero() -> Self {
        Lanes([0.0; L])
    }
    fn is_zero(&self) -> bool {
        self.0.iter().all(|v| *v == 0.0)
    }
}

impl<const L: usize> num_traits::One for Lanes<L> {
    #[inline(always)]
    fn one() -> Self {
        Lanes([1.0; L])
    }
}

impl<const L: usize> Real for Lanes<L> {
    type Mask = LaneMask<L>;
    const ZERO: Self = Lanes([0.0; L]);
    const ONE: Self = Lanes([1.0; L]);
    #[inline(always)]
    fn splat(v: f64) -> Self {
        Lanes([v; L])
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        // With `std`: `f64::sqrt`, the compiler's own square root, which it vectorises (one
        // `vsqrtpd` for four lanes, and the division by the norm that follows with it).
        #[cfg(feature = "std")]
        {
            self.map(f64::sqrt)
        }
        // Without: libm's square root is one instruction per lane (`sqrtsd`, behind an
        // `asm!` block the compiler cannot widen). Passing the lanes through memory first
        // keeps the computation that produced them in vector registers: without it the
        // compiler splits, say, a whole dot product into per-lane scalar code to feed the
        // `asm!`.
        #[cfg(not(feature = "std"))]
        {
            core::hint::black_box(self).map(libm::sqrt)
        }
    }
    #[inline(always)]
    fn abs(self) -> Self {
        self.map(|v| f64::from_bits(v.to_bits() & !(1 << 63)))
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        self.zip(o, f64::min)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        self.zip(o, f64::max)
    }
    #[inline(always)]
    fn sincos(self) -> (Self, Self) {
        sincos_lanes(self)
    }
    #[inline(always)]
    fn gt(self, o: Self) -> LaneMask<L> {
        self.test(o, |a, b| a > b)
    }
    #[inline(always)]
    fn ge(self, o: Self) -> LaneMask<L> {
        self.test(o, |a, b| a >= b)
    }
    #[inline(always)]
    fn finite(self) -> LaneMask<L> {
        // x − x is 0 for a finite x and NaN otherwise: one subtraction and one comparison.
        #[allow(clippy::eq_op)]
        let d = self - self;
        d.test(Self::ZERO, |d, z| d == z)
    }
}

// libm 0.2's constants (FreeBSD msun: s_sin.c, k_sin.c, k_cos.c, e_rem_pio2.c), written
// digit for digit as there so they can be compared with the source; each parses to the
// same double as its shortest form.
#[allow(clippy::excessive_precision)]
const PIO2_1: f64 = 1.570_796_326_734_125_614_17e0;
#[allow(clippy::excessive_precision)]
const PIO2_1T: f64 = 6.077_100_506_506_192_249_32e-11;
#[allow(clippy::excessive_precision)]
const S1: f64 = -1.666_666_666_666_663_243_48e-1;
#[allow(clippy::excessive_precision)]
const S2: f64 = 8.333_333_333_322_489_461_24e-3;
#[allow(clippy::excessive_precision)]
const S3: f64 = -1.984_126_982_985_794_931_34e-4;
#[allow(clippy::excessive_precision)]
const S4: f64 = 2.755_731_370_707_006_767_89e-6;
#[allow(clippy::excessive_precision)]
const S5: f64 = -2.505_076_025_340_686_341_95e-8;
#[allow(clippy::excessive_precision)]
const S6: f64 = 1.589_690_995_211_550_102_21e-10;
#[allow(clippy::excessive_precision)]
const C1: f64 = 4.166_666_666_666_660_190_37e-2;
#[allow(clippy::excessive_precision)]
const C2: f64 = -1.388_888_888_887_410_957_49e-3;
#[allow(clippy::excessive_precision)]
const C3: f64 = 2.480_158_728_947_672_941_78e-5;
#[allow(clippy::excessive_precision)]
const C4: f64 = -2.755_731_435_139_066_330_35e-7;
#[allow(clippy::excessive_precision)]
const C5: f64 = 2.087_572_321_298_174_827_90e-9;
#[allow(clippy::excessive_precision)]
const C6: f64 = -1.135_964_755_778_819_482_65e-11;

/// `f(x_i)` for every lane.
#[inline(always)]
fn each<const L: usize>(x: [f64; L], f: impl Fn(f64) -> f64) -> [f64; L] {
    let mut out = [0.0; L];
    for (o, v) in out.iter_mut().zip(x) {
        *o = f(v);
    }
    out
}

/// `f(x_i, y_i)` for every lane.
#[inline(always)]
fn each2<const L: usize>(x: [f64; L], y: [f64; L], f: impl Fn(f64, f64) -> f64) -> [f64; L] {
    let mut out = [0.0; L];
    for ((o, a), b) in out.iter_mut().zip(x).zip(y) {
        *o = f(a, b);
    }
    out
}

/// `f(x_i, y_i, z_i)` for every lane.
#[inline(always)]
fn each3<const L: usize>(
    x: [f64; L],
    y: [f64; L],
    z: [f64; L],
    f: impl Fn(f64, f64, f64) -> f64,
) -> [f64; L] {
    let mut out = [0.0; L];
    for (((o, a), b), c) in out.iter_mut().zip(x).zip(y).zip(z) {
        *o = f(a, b, c);
    }
    out
}

/// The double whose bits are `h` in the high word and zeros below: `|x| < bound(H + 1)`
/// is libm's `high word of |x| ≤ H` (non-negative doubles are ordered as their bits).
const fn bound(h: u64) -> f64 {
    f64::from_bits(h << 32)
}

/// `libm::sincos` of every lane: `(sin x, cos x)`, bit for bit.
///
/// The lanes run libm's own operations side by side for the arguments joint angles have:
/// `|x| ≤ 9π/4` outside four windows of relative width `2⁻²⁰` at π/2, π, 3π/2 and 2π.
/// There libm takes one of three branches, decided by the high word of `|x|`: `(x, 1)`
/// below `2⁻²⁷·√2`, the unreduced kernels up to π/4, and otherwise the reduction by
/// `k = 1…4` quadrants (`y = x ∓ k·pio2_1 ∓ k·pio2_1t`, two terms) before the kernels and
/// the quadrant's swap and signs. Each lane evaluates every branch's operations in libm's
/// order and keeps the one libm takes, so each lane has libm's bits (a test sweeps the
/// domain, libm's branch thresholds and the multiples of π/2). If any lane is elsewhere
/// (the windows, larger, infinite or NaN), or `L = 1`, every lane is evaluated by
/// `libm::sincos` itself.
#[inline(always)]
#[must_use]
pub fn sincos_lanes<const L: usize>(x: Lanes<L>) -> (Lanes<L>, Lanes<L>) {
    let x = x.0;
    let ax = each(x, |v| f64::from_bits(v.to_bits() & !(1 << 63)));
    // Small: |x| ≤ π/4 (high word ≤ 0x3fe921fb): k = 0. Otherwise rem_pio2's quadrant:
    // k = 1 up to the high word 0x4002d97c, 2 up to 0x400f6a7a, 3 up to 0x4015fdbc, 4 up
    // to 0x401c463b. Branch-free (`&`, `|` and selects, no short-circuit), so that it
    // vectorises.
    let small_bound = bound(0x3fe9_21fc);
    let k = each(ax, |a| {
        let step = |h: u64| if a >= bound(h) { 1.0 } else { 0.0 };
        let k = 1.0 + step(0x4002_d97d) + step(0x400f_6a7b) + step(0x4015_fdbd);
        if a < small_bound { 0.0 } else { k }
    });
    // Elsewhere: beyond 9π/4 (infinite, NaN), or in the four windows where rem_pio2
    // reduces otherwise (high words 0x3ff921fb, 0x400921fb, 0x4012d97c, 0x401921fb).
    // The windows by their high words: 0x3ff921fb, 0x400921fb and 0x401921fb share the
    // low 20 bits 0x921fb (no other high word of the reduced range does).
    let elsewhere = each(ax, |a| {
        let hi = a.to_bits() >> 32;
        let windowed = ((hi & 0xfffff) == 0x921fb) | (hi == 0x4012_d97c);
        // `a >= b | nan` is `!(a < b)`: a NaN is elsewhere.
        let nan = a.is_nan();
        if ((a >= small_bound) | nan) & (windowed | (a >= bound(0x401c_463c)) | nan) {
            1.0
        } else {
            0.0
        }
    });
    if L == 1 || elsewhere.iter().any(|e| *e != 0.0) {
        let (mut s, mut c) = ([0.0; L], [0.0; L]);
        for ((s, c), x) in s.iter_mut().zip(c.iter_mut()).zip(x) {
            (*s, *c) = libm::sincos(x);
        }
        return (Lanes(s), Lanes(c));
    }
    // n = ±k (the sign of x). (−k)·p = −(k·p) exactly, and x − (−k·p) is libm's x + k·p:
    // the reduction y0 = (x − k·pio2_1) − k·pio2_1t, y1 = ((x − k·pio2_1) − y0) − k·pio2_1t.
    // With k = 0 (small |x|, never 0: that is tiny) it gives libm's unreduced (x, +0).
    let n = each2(x, k, |v, k| if v < 0.0 { -k } else { k });
    let z = each2(x, n, |v, n| v - n * PIO2_1);
    let y0 = each2(z, n, |z, n| z - n * PIO2_1T);
    let y1 = each3(z, y0, n, |z, y, n| (z - y) - n * PIO2_1T);
    let zz = each(y0, |v| v * v);
    let ww = each(zz, |z| z * z);
    let rs = each2(zz, ww, |z, w| {
        S2 + z * (S3 + z * S4) + z * w * (S5 + z * S6)
    });
    let v = each2(zz, y0, |z, x| z * x);
    // k_sin's branch: iy = 0 where small, 1 elsewhere.
    let (u, r) = (sin_unreduced(y0, zz, v, rs), sin_reduced(y0, y1, zz, v, rs));
    let sin = each3(k, u, r, |k, u, r| if k == 0.0 { u } else { r });
    let cos = each3(y0, y1, zz, |x, y, z| {
        let w = z * z;
        let r = z * (C1 + z * (C2 + z * C3)) + w * w * (C4 + z * (C5 + z * C6));
        let hz = 0.5 * z;
        let w = 1.0 - hz;
        w + (((1.0 - w) - hz) + (z * r - x * y))
    });
    // Quadrant q = n mod 4 (0 where small): (s, c), (c, −s), (−s, −c), (−c, s).
    let q = each(n, |n| {
        let q = if n < 0.0 { n + 4.0 } else { n };
        if q == 4.0 { 0.0 } else { q }
    });
    let s_out = each3(q, sin, cos, |q, s, c| {
        let v = if (q == 1.0) | (q == 3.0) { c } else { s };
        if q >= 2.0 { -v } else { v }
    });
    let c_out = each3(q, sin, cos, |q, s, c| {
        let v = if (q == 1.0) | (q == 3.0) { s } else { c };
        if (q == 1.0) | (q == 2.0) { -v } else { v }
    });
    // Tiny: |x| < 2^-27·√2 (high word < 0x3e46a09e).
    let tiny = bound(0x3e46_a09e);
    (
        Lanes(each3(ax, x, s_out, |a, v, s| if a < tiny { v } else { s })),
        Lanes(each2(ax, c_out, |a, c| if a < tiny { 1.0 } else { c })),
    )
}

/// k_sin's `iy = 0` branch (no reduction tail).
#[inline(always)]
fn sin_unreduced<const L: usize>(x: [f64; L], z: [f64; L], v: [f64; L], r: [f64; L]) -> [f64; L] {
    let mut out = [0.0; L];
    for ((((o, x), z), v), r) in out.iter_mut().zip(x).zip(z).zip(v).zip(r) {
        *o = x + v * (S1 + z * r);
    }
    out
}

/// k_sin's `iy = 1` branch (with the reduction tail `y`).
#[inline(always)]
fn sin_reduced<const L: usize>(
    x: [f64; L],
    y: [f64; L],
    z: [f64; L],
    v: [f64; L],
    r: [f64; L],
) -> [f64; L] {
    let mut out = [0.0; L];
    for (((((o, x), y), z), v), r) in out.iter_mut().zip(x).zip(y).zip(z).zip(v).zip(r) {
        *o = x - ((z * (0.5 * y - v * r) - y) - v * S1);
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::indexing_slicing)]
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Checks one set of four arguments in every lane order against `libm::sincos`.
    fn check4(x: [f64; 4]) {
        let (s, c) = sincos_lanes(Lanes(x));
        for (i, v) in x.iter().enumerate() {
            let (ls, lc) = libm::sincos(*v);
            assert_eq!(
                (s.0[i].to_bits(), c.0[i].to_bits()),
                (ls.to_bits(), lc.to_bits()),
                "x = {v:e} ({:#x})",
                v.to_bits()
            );
        }
    }

    /// The arguments around `v` (`±k` ulp) and their negatives.
    fn around(v: f64, k: i64, out: &mut std::vec::Vec<f64>) {
        let b = v.to_bits() as i64;
        for d in -k..=k {
            let x = f64::from_bits((b + d) as u64);
            out.push(x);
            out.push(-x);
        }
    }

    /// Verifies RL-LANE-002: `sincos_lanes` equals `libm::sincos` bit for bit on
    /// `|x| < 2^20·π/2` (random arguments over every binade, every multiple of π/2 up to
    /// 2^20·π/2 ± 64 ulp, every branch threshold of libm ± 64 ulp) and falls back to it
    /// beyond (large, infinite, NaN).
    #[test]
    fn sincos_lanes_is_libm_bit_for_bit() {
        let mut xs = std::vec::Vec::new();
        // Branch thresholds of sincos and rem_pio2 (high words), ± 64 ulp.
        for hi in [
            0x3e46_a09e_u64,
            0x3fe9_21fb,
            0x4002_d97c,
            0x400f_6a7a,
            0x4012_d97c,
            0x4015_fdbc,
            0x4019_21fb,
            0x401c_463b,
            0x4139_21fb,
            0x0010_0000,
        ] {
            around(f64::from_bits(hi << 32), 64, &mut xs);
            around(f64::from_bits((hi << 32) | 0xffff_ffff), 64, &mut xs);
        }
        // Multiples of π/2 (the cancellation cases), ± 64 ulp near 0, ± 4 ulp beyond.
        for k in 0..(1u64 << 20) {
            let v = k as f64 * core::f64::consts::FRAC_PI_2;
            around(v, if k < 64 { 64 } else { 4 }, &mut xs);
        }
        // Near the multiples of π/2 at every distance: the reduction's second and third
        // rounds start at 16 and 49 binades of cancellation.
        for k in (1..(1u64 << 20)).step_by(97) {
            let v = k as f64 * core::f64::consts::FRAC_PI_2;
            for j in 8..64 {
                let d = libm::scalbn(v, -j);
                for x in [v + d, v - d, v + 1.5 * d, v - 1.5 * d] {
                    xs.push(x);
                    xs.push(-x);
                }
            }
        }
        // Random arguments, uniform in each binade from 2^-1074 to 2^21.
        let mut rng = rand::rngs::StdRng::seed_from_u64(15);
        for e in -1074..21 {
            for _ in 0..4000 {
                let m: f64 = rng.random_range(1.0..2.0);
                xs.push(libm::scalbn(m, e) * if rng.random() { 1.0 } else { -1.0 });
            }
        }
        // Joint-angle-like arguments, densely.
        for _ in 0..2_000_000 {
            xs.push(rng.random_range(-8.0..8.0));
        }
        // Beyond the range, and the special values.
        xs.extend([
            0.0,
            -0.0,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            1e300,
            -3e7,
            f64::MIN_POSITIVE,
        ]);
        assert!(xs.len() > 10_000_000, "{} arguments", xs.len());
        for chunk in xs.chunks(4) {
            let mut x = [0.25; 4];
            x[..chunk.len()].copy_from_slice(chunk);
            check4(x);
            check4([x[3], x[1], x[2], x[0]]);
        }
        // A lane beyond the range sends the others through libm too.
        check4([0.5, 1e9, -2.0, 3.0]);
    }

    /// Verifies RL-LANE-002: the lanes' square root (`f64::sqrt` with the `std` feature,
    /// `libm::sqrt` without) is `libm::sqrt` bit for bit, the scalar rollout's: random
    /// arguments over every binade, and zeros, subnormals, infinities, negatives and NaN.
    #[test]
    fn lane_sqrt_is_libm_bit_for_bit() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(16);
        let mut xs = std::vec![0.0, -0.0, f64::INFINITY, -1.0, f64::NAN, 5e-324, f64::MAX];
        for e in -1074..1024 {
            for _ in 0..64 {
                let m: f64 = rng.random_range(1.0..2.0);
                xs.push(libm::scalbn(m, e));
            }
        }
        for chunk in xs.chunks(4) {
            let mut x = [1.0; 4];
            x[..chunk.len()].copy_from_slice(chunk);
            let r = Lanes(x).sqrt();
            for (v, got) in x.iter().zip(r.0) {
                assert_eq!(got.to_bits(), libm::sqrt(*v).to_bits(), "sqrt({v:e})");
            }
        }
    }
}
