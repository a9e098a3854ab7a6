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
use crate::lanes::{Mask, Real};
use nalgebra::Vector3;

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
#[inline(always)]
fn gram<const N: usize, T: Real>(a: &[Vector3<T>; N]) -> Sym3<T> {
    let mut g = Sym3::<T>::ZERO;
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

/// Factors `AAᵀ` and checks the rank of `A` (see [`RANK_TOLERANCE`]): per lane, whether
/// `AAᵀ` is positive definite with the estimated `σ_min/σ_max` above the tolerance.
#[inline(always)]
fn factor<const N: usize, T: Real>(a: &[Vector3<T>; N]) -> (Ldlt3<T>, T::Mask) {
    let g = gram(a);
    let (f, pd) = g.ldlt_masked();
    let ratio_sq = f.det() / (g.minor_sum() * g.trace());
    let conditioned = ratio_sq.ge(T::splat(RANK_TOLERANCE * RANK_TOLERANCE));
    (f, pd.and(conditioned))
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

#[inline(always)]
fn dot<const N: usize, T: Real>(x: &[T; N], y: &[T; N]) -> T {
    x.iter()
        .zip(y.iter())
        .fold(T::ZERO, |s, (a, b)| s + *a * *b)
}

/// `x ← P x = x − Aᵀ (AAᵀ)⁻¹ A x`.
#[inline(always)]
fn project<const N: usize, T: Real>(a: &[Vector3<T>; N], f: &Ldlt3<T>, x: &mut [T; N]) {
    let mut ax = Vector3::<T>::zeros();
    for (c, v) in a.iter().zip(x.iter()) {
        ax += c * *v;
    }
    let z = f.solve(&ax);
    for (c, v) in a.iter().zip(x.iter_mut()) {
        *v -= c.dot(&z);
    }
}

/// Per lane, which part of the transport failed: `AAᵀ` (rank of `A`) or a Gram–Schmidt
/// pivot. `true` = fine.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Conditioned<M> {
    /// `A` has full rank ([`RankLoss::Coupling`] where not).
    pub(crate) coupling: M,
    /// Every pivot is above [`PIVOT_TOLERANCE`] ([`RankLoss::Basis`] where not).
    pub(crate) basis: M,
}

impl Conditioned<bool> {
    /// The scalar verdict: the first failure, as the scalar transport reports it.
    #[inline(always)]
    pub(crate) fn result(self) -> Result<(), RankLoss> {
        match (self.coupling, self.basis) {
            (false, _) => Err(RankLoss::Coupling),
            (true, false) => Err(RankLoss::Basis),
            (true, true) => Ok(()),
        }
    }
}

/// `cols ← MGS(P·cols)` for `P` the null-space projector of `a`, in place, for one
/// configuration or several side by side. Where a lane fails, its columns are meaningless.
#[inline(always)]
fn orthonormalize_masked<const N: usize, const K: usize, T: Real>(
    a: &[Vector3<T>; N],
    cols: &mut [[T; N]; K],
) -> Conditioned<T::Mask> {
    let (f, coupling) = factor(a);
    let mut basis = coupling;
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
                *vi -= c * *ui;
            }
        }
        let norm = dot(v, v).sqrt();
        // A NaN norm fails too.
        basis = basis.and(norm.gt(T::splat(PIVOT_TOLERANCE)));
        let inv = T::ONE / norm;
        for vi in v.iter_mut() {
            *vi *= inv;
        }
    }
    Conditioned { coupling, basis }
}

/// `cols ← MGS(P·cols)` for `P` the null-space projector of `a`, in place.
#[inline(always)]
fn orthonormalize<const N: usize, const K: usize>(
    a: &[Vec3; N],
    cols: &mut [[f64; N]; K],
) -> Result<(), RankLoss> {
    orthonormalize_masked(a, cols).result()
}

/// An orthonormal basis of the reaction null space (columns, `K = N − 3` of them): of
/// one configuration (`f64`), or of several side by side ([`Real`] lanes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Basis<const N: usize, const K: usize, T = f64> {
    cols: [[T; N]; K],
}

impl<const N: usize, const K: usize, T: Real> Basis<N, K, T> {
    /// All zeros (a placeholder for statically allocated state).
    pub const IDLE: Self = Self {
        cols: [[T::ZERO; N]; K],
    };

    /// The basis vectors (unit joint-rate directions, dimensionless).
    #[must_use]
    pub fn columns(&self) -> &[[T; N]; K] {
        &self.cols
    }

    /// `MGS(cols)`: the columns made orthonormal again in column order, without projecting
    /// them (the continuous-path integrator's state drifts off orthonormality at its
    /// order of accuracy; this puts it back on the invariant `NᵀN = I`).
    ///
    /// # Errors
    /// [`RankLoss::Basis`] for a pivot at or below [`PIVOT_TOLERANCE`].
    pub(crate) fn reorthonormalized(cols: [[f64; N]; K]) -> Result<Basis<N, K>, RankLoss> {
        let mut cols = cols;
        for i in 0..K {
            let Some((done, rest)) = cols.split_at_mut_checked(i) else {
                break;
            };
            let Some(v) = rest.first_mut() else {
                break;
            };
            for u in done.iter() {
                let c = dot(u, v);
                for (vi, ui) in v.iter_mut().zip(u.iter()) {
                    *vi -= c * *ui;
                }
            }
            let norm = libm::sqrt(dot(v, v));
            // A NaN norm fails too.
            let pivots = norm > PIVOT_TOLERANCE;
            if !pivots {
                return Err(RankLoss::Basis);
            }
            let inv = 1.0 / norm;
            for vi in v.iter_mut() {
                *vi *= inv;
            }
        }
        Ok(Basis { cols })
    }

    /// A basis of columns `cols` as given (the continuous-path integrator's state, whose
    /// columns are orthonormal to its accuracy).
    pub(crate) fn from_columns(cols: [[T; N]; K]) -> Self {
        Self { cols }
    }

    /// The basis vectors, to write lane by lane.
    pub(crate) fn columns_mut(&mut self) -> &mut [[T; N]; K] {
        &mut self.cols
    }

    /// `Σ_i α_i n_i`.
    #[inline(always)]
    #[must_use]
    pub fn combine(&self, alpha: &[T; K]) -> [T; N] {
        let mut out = [T::ZERO; N];
        for (col, &w) in self.cols.iter().zip(alpha.iter()) {
            for (o, c) in out.iter_mut().zip(col.iter()) {
                *o += w * *c;
            }
        }
        out
    }

    /// `MGS(P(q')·N)` in place, for each lane: the basis carried to the configuration whose
    /// `H~bm` is `a`. Where a lane fails, its columns are meaningless.
    #[inline(always)]
    pub(crate) fn transport_masked(&mut self, a: &[Vector3<T>; N]) -> Conditioned<T::Mask> {
        orthonormalize_masked(a, &mut self.cols)
    }
}

impl<const N: usize, const K: usize> Basis<N, K> {
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

    /// The basis of spec §14 moving with the path: `Ṅ = −A⁺ Ȧ N = −Aᵀ(AAᵀ)⁻¹ Ȧ N` for
    /// `A = H~bm` (columns `a`) and its rate `ȧ` (per second), column by column. Keeps `A N`
    /// at 0 (`d(AN)/dt = ȦN + AṄ = 0`) and `NᵀṄ = 0` (parallel transport: `Ṅ` lies in the
    /// row space of `A`). Cost O(N·K): no Gram–Schmidt.
    ///
    /// # Errors
    /// [`RankLoss::Coupling`] if `A` is rank-deficient (as [`Basis::transported`]).
    #[inline(always)]
    pub fn rate(&self, a: &[Vec3; N], a_dot: &[Vec3; N]) -> Result<[[f64; N]; K], RankLoss> {
        Self::rate_of(&self.cols, a, a_dot)
    }

    /// [`Basis::rate`] of columns `cols` (orthonormal or not).
    #[inline(always)]
    pub(crate) fn rate_of(
        cols: &[[f64; N]; K],
        a: &[Vec3; N],
        a_dot: &[Vec3; N],
    ) -> Result<[[f64; N]; K], RankLoss> {
        let (f, ok) = factor(a);
        if !ok {
            return Err(RankLoss::Coupling);
        }
        let mut out = [[0.0; N]; K];
        for (o, col) in out.iter_mut().zip(cols.iter()) {
            let mut x = Vec3::zeros();
            for (c, v) in a_dot.iter().zip(col.iter()) {
                x += c * *v;
            }
            let z = f.solve(&x);
            for (oi, c) in o.iter_mut().zip(a.iter()) {
                *oi = -c.dot(&z);
            }
        }
        Ok(out)
    }

    #[inline(always)]
    fn orthonormalize(a: &[Vec3; N], mut cols: [[f64; N]; K]) -> Result<Self, RankLoss> {
        orthonormalize(a, &mut cols)?;
        Ok(Self { cols })
    }
}
