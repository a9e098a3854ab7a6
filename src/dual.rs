//! Forward-mode derivatives: a number that carries its rate along one direction, so the
//! hot path's own kinematics and `H~bm` give `dA/dt` beside `A` in one pass.
//!
//! Owns [`Dual`] (`v + d·ε`, `ε² = 0`) and its [`Real`] implementation. Evaluating any
//! [`Real`]-generic computation at `q + q̇·ε` yields its value at `q` (the `v` parts, the
//! same bits as the `f64` computation: every value operation is the `f64` one) and its
//! directional derivative along `q̇` (the `d` parts), exact up to rounding. The
//! continuous-path integrator ([`crate::integrator`]) uses it for `Ȧ = dH~bm/dt` in the
//! basis transport `Ṅ = −A⁺ Ȧ N` (spec §14).
//!
//! Rules: `(a + a'ε)(b + b'ε) = ab + (a'b + ab')ε`, `√(a + a'ε) = √a + a'/(2√a) ε`,
//! `sincos(a + a'ε) = (sin a + a' cos a ε, cos a − a' sin a ε)`. `min`, `max` and `abs` pick
//! by value (their derivative is one-sided at a tie); comparisons compare values.

use crate::lanes::Real;
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Sub, SubAssign};

/// `v + d·ε`: a value and its rate along one direction (units of `v` per unit of the
/// direction's parameter: per second for a path `q(t)`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual {
    /// The value.
    pub v: f64,
    /// The directional derivative.
    pub d: f64,
}

impl Dual {
    /// `v + d·ε`.
    #[inline(always)]
    #[must_use]
    pub const fn new(v: f64, d: f64) -> Self {
        Self { v, d }
    }
}

impl Add for Dual {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        Self::new(self.v + o.v, self.d + o.d)
    }
}

impl Sub for Dual {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        Self::new(self.v - o.v, self.d - o.d)
    }
}

impl Mul for Dual {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        Self::new(self.v * o.v, self.d * o.v + self.v * o.d)
    }
}

impl Div for Dual {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        Self::new(v, (self.d - v * o.d) / o.v)
    }
}

impl Neg for Dual {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        Self::new(-self.v, -self.d)
    }
}

impl Add<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: f64) -> Self {
        Self::new(self.v + o, self.d)
    }
}

impl Sub<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: f64) -> Self {
        Self::new(self.v - o, self.d)
    }
}

impl Mul<f64> for Dual {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        Self::new(self.v * o, self.d * o)
    }
}

macro_rules! assign_ops {
    ($($tr:ident $f:ident $op:tt),*) => {$(
        impl $tr for Dual {
            #[inline(always)]
            fn $f(&mut self, o: Self) {
                *self = *self $op o;
            }
        }
    )*};
}

assign_ops!(AddAssign add_assign +, SubAssign sub_assign -, MulAssign mul_assign *, DivAssign div_assign /);

impl num_traits::Zero for Dual {
    #[inline(always)]
    fn zero() -> Self {
        Self::new(0.0, 0.0)
    }
    fn is_zero(&self) -> bool {
        self.v == 0.0 && self.d == 0.0
    }
}

impl num_traits::One for Dual {
    #[inline(always)]
    fn one() -> Self {
        Self::new(1.0, 0.0)
    }
}

impl Real for Dual {
    type Mask = bool;
    const ZERO: Self = Self::new(0.0, 0.0);
    const ONE: Self = Self::new(1.0, 0.0);
    #[inline(always)]
    fn splat(v: f64) -> Self {
        Self::new(v, 0.0)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        let s = libm::sqrt(self.v);
        Self::new(s, self.d / (2.0 * s))
    }
    #[inline(always)]
    fn abs(self) -> Self {
        let d = if self.v < 0.0 { -self.d } else { self.d };
        Self::new(libm::fabs(self.v), d)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        if o.v < self.v || self.v.is_nan() {
            o
        } else {
            self
        }
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        if o.v > self.v || self.v.is_nan() {
            o
        } else {
            self
        }
    }
    #[inline(always)]
    fn sincos(self) -> (Self, Self) {
        let (s, c) = libm::sincos(self.v);
        (Self::new(s, self.d * c), Self::new(c, -(self.d * s)))
    }
    #[inline(always)]
    fn gt(self, o: Self) -> bool {
        self.v > o.v
    }
    #[inline(always)]
    fn ge(self, o: Self) -> bool {
        self.v >= o.v
    }
    #[inline(always)]
    fn finite(self) -> bool {
        self.v.is_finite() && self.d.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Verifies RL-CONT-001: each rule against a central difference.
    #[test]
    fn rules_match_finite_differences() {
        let f = |x: Dual| {
            let (s, c) = (x * 1.3 + 0.2).sincos();
            (s * c + x * x) / (x + 2.0) - (x * 3.0).sqrt()
        };
        let g = |x: f64| f(Dual::splat(x)).v;
        for x in [0.3, 0.9, 1.7] {
            let d = f(Dual::new(x, 1.0)).d;
            let h = 1e-6;
            let fd = (g(x + h) - g(x - h)) / (2.0 * h);
            assert!((d - fd).abs() < 1e-8, "x = {x}: {d} vs {fd}");
            assert_eq!(f(Dual::new(x, 1.0)).v, g(x));
        }
    }
}
