//! The reaction null-space (RNS) basis and its transport along a path (spec §3).
//!
//! Owns [`Basis`]: `K = N − 3` orthonormal joint-rate directions spanning the null space of
//! `A = H~bm(q)`. The projector is `P = I − Aᵀ(AAᵀ)⁻¹A`, applied with an `LDLᵀ` solve of
//! the 3×3 `AAᵀ` (no SVD: nalgebra's has panic paths, and SVD bases are not unique).
//!
//! - Initial basis: `N₀ = MGS(P(q₀)·E)`, `E` = the last `K` columns of `I_N`.
//! - Transport: `N_{s+1} = MGS(P(q_{s+1})·N_s)`, which keeps the columns continuous (no sign
//!   flips) along a path.
//!
//! MGS is modified Gram–Schmidt in column order. Rank loss is reported as
//! [`RankLoss`], never as NaN: `H~bm` is rank-deficient when its estimated `σ_min/σ_max`
//! is below [`RANK_TOLERANCE`], and the basis degenerates when a Gram–Schmidt pivot
//! (remaining norm of a unit input column) is below [`PIVOT_TOLERANCE`].

use crate::error::RankLoss;
use crate::geometry::{Ldlt3, Sym3, Vec3};

/// Smallest accepted estimate of `σ_min(H~bm)/σ_max(H~bm)`.
///
/// The estimate `√(det(AAᵀ)/(c₂·tr(AAᵀ)))` (`c₂` the sum of the principal 2×2 minors)
/// lies in `[σ_min/(3σ_max), σ_min/σ_max]`, so rank loss is declared whenever the true
/// ratio is below `1e-6` and never while it is above `3e-6`.
pub const RANK_TOLERANCE: f64 = 1e-6;

/// Smallest accepted Gram–Schmidt pivot (remaining norm of a unit column after projection
/// and orthogonalisation against the earlier columns).
pub const PIVOT_TOLERANCE: f64 = 1e-6;

/// The dimension check `K = N − 3` (N ≥ 4), evaluated at compile time where used.
pub(crate) struct Dims<const N: usize, const K: usize>;

impl<const N: usize, const K: usize> Dims<N, K> {
    pub(crate) const VALID: () = assert!(
        K >= 1 && K + 3 == N && N <= 255,
        "the null-space dimension K must equal N - 3, with 4 <= N <= 255"
    );
}

/// `AAᵀ` of `A = [a_1 … a_N]` (columns).
#[inline]
fn gram<const N: usize>(a: &[Vec3; N]) -> Sym3 {
    let mut g = Sym3::ZERO;
    for c in a {
        g = g.add(&Sym3 {
            xx: c.x * c.x,
            yy: c.y * c.y,
            zz: c.z * c.z,
            xy: c.x * c.y,
            xz: c.x * c.z,
            yz: c.y * c.z,
        });
    }
    g
}

/// Factors `AAᵀ` and checks the rank of `A` (see [`RANK_TOLERANCE`]).
#[inline]
fn factor<const N: usize>(a: &[Vec3; N]) -> Result<Ldlt3, RankLoss> {
    let g = gram(a);
    let f = g.ldlt().ok_or(RankLoss::Coupling)?;
    let ratio_sq = f.det() / (g.minor_sum() * g.trace());
    if ratio_sq >= RANK_TOLERANCE * RANK_TOLERANCE {
        Ok(f)
    } else {
        Err(RankLoss::Coupling)
    }
}

/// Estimated `σ_min/σ_max` of `A` (within a factor 3 below the true value), or 0 when
/// `AAᵀ` is not positive definite.
#[must_use]
pub fn conditioning<const N: usize>(a: &[Vec3; N]) -> f64 {
    let g = gram(a);
    match g.ldlt() {
        Some(f) => libm::sqrt(f.det() / (g.minor_sum() * g.trace())),
        None => 0.0,
    }
}

#[inline]
fn dot<const N: usize>(x: &[f64; N], y: &[f64; N]) -> f64 {
    x.iter().zip(y.iter()).fold(0.0, |s, (a, b)| s + a * b)
}

/// `x ← P x = x − Aᵀ (AAᵀ)⁻¹ A x`.
#[inline]
fn project<const N: usize>(a: &[Vec3; N], f: &Ldlt3, x: &mut [f64; N]) {
    let mut ax = Vec3::zeros();
    for (c, v) in a.iter().zip(x.iter()) {
        ax += c * *v;
    }
    let z = f.solve(&ax);
    for (c, v) in a.iter().zip(x.iter_mut()) {
        *v -= c.dot(&z);
    }
}

/// `cols ← MGS(P·cols)` for `P` the null-space projector of `a`, in place.
#[inline(always)]
fn orthonormalize<const N: usize, const K: usize>(
    a: &[Vec3; N],
    cols: &mut [[f64; N]; K],
) -> Result<(), RankLoss> {
    let f = factor(a)?;
    for i in 0..K {
        let Some((done, rest)) = cols.split_at_mut_checked(i) else {
            break;
        };
        let Some(v) = rest.first_mut() else {
            break;
        };
        project(a, &f, v);
        for u in done.iter() {
            let c = dot(u, v);
            for (vi, ui) in v.iter_mut().zip(u.iter()) {
                *vi -= c * ui;
            }
        }
        let norm = libm::sqrt(dot(v, v));
        if norm.is_nan() || norm <= PIVOT_TOLERANCE {
            return Err(RankLoss::Basis);
        }
        let inv = 1.0 / norm;
        for vi in v.iter_mut() {
            *vi *= inv;
        }
    }
    Ok(())
}

/// An orthonormal basis of the reaction null space (columns, `K = N − 3` of them).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Basis<const N: usize, const K: usize> {
    cols: [[f64; N]; K],
}

impl<const N: usize, const K: usize> Basis<N, K> {
    /// All zeros (a placeholder for statically allocated state).
    pub const IDLE: Self = Self {
        cols: [[0.0; N]; K],
    };

    /// `N₀ = MGS(P(q)·E)` for `A = H~bm(q)` given by its columns.
    ///
    /// # Errors
    /// [`RankLoss`] if `A` is rank-deficient or `P·E` does not span the null space.
    pub fn initial(a: &[Vec3; N]) -> Result<Self, RankLoss> {
        let () = Dims::<N, K>::VALID;
        let mut cols = [[0.0; N]; K];
        // E = last K columns of I_N: column i is the unit vector e_{3+i}.
        for (i, col) in cols.iter_mut().enumerate() {
            if let Some(v) = col.get_mut(3 + i) {
                *v = 1.0;
            }
        }
        Self::orthonormalize(a, cols)
    }

    /// `MGS(P(q')·N)`: the basis carried to the configuration whose `H~bm` is `a`.
    ///
    /// # Errors
    /// [`RankLoss`] as for [`Basis::initial`].
    #[inline(always)]
    pub fn transported(&self, a: &[Vec3; N]) -> Result<Self, RankLoss> {
        Self::orthonormalize(a, self.cols)
    }

    /// [`Basis::transported`] in place (the rollout's hot path: no copy of the basis). On
    /// error the basis is left partly updated; the rollout that owns it has failed.
    #[inline(always)]
    pub(crate) fn transport(&mut self, a: &[Vec3; N]) -> Result<(), RankLoss> {
        orthonormalize(a, &mut self.cols)
    }

    #[inline(always)]
    fn orthonormalize(a: &[Vec3; N], mut cols: [[f64; N]; K]) -> Result<Self, RankLoss> {
        orthonormalize(a, &mut cols)?;
        Ok(Self { cols })
    }

    /// The basis vectors (unit joint-rate directions, dimensionless).
    #[must_use]
    pub fn columns(&self) -> &[[f64; N]; K] {
        &self.cols
    }

    /// `Σ_i α_i n_i`.
    #[inline]
    #[must_use]
    pub fn combine(&self, alpha: &[f64; K]) -> [f64; N] {
        let mut out = [0.0; N];
        for (col, &w) in self.cols.iter().zip(alpha.iter()) {
            for (o, c) in out.iter_mut().zip(col.iter()) {
                *o += w * c;
            }
        }
        out
    }
}
