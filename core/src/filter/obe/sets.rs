//! The set operations of the OBE filter (see the `obe` module docs): the outer ellipsoid of an
//! ellipsoid cut by a strip ([`intersect_strip`]), of a Minkowski sum ([`minkowski_outer`]), and
//! of the predicted measurement set, each the smallest by an [`ObeCriterion`].

use nalgebra::{SMatrix, SVector};

use super::solve::{kappa_min_volume, rho_min_trace, rho_min_volume, sym_eigenvalues};
use crate::linalg::{cholesky, ensure_finite, symmetrize};
use crate::state::Ellipsoid;
use crate::{EstimationError, Result};

/// A tightened strip narrower than this fraction of the ellipsoid's extent along `a` is widened
/// to it, so that a strip just touching the ellipsoid still yields a (thin) positive definite
/// outer ellipsoid. Widening a strip keeps the bound an outer bound.
const MIN_STRIP_FRACTION: f64 = 1e-9;

/// Which size measure of the outer ellipsoid each step minimises.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum ObeCriterion {
    /// Minimum volume (`det P`): Fogel & Huang's closed form for the update, a convex
    /// one-dimensional root search for the prediction (\[FH82\], \[ELL\] Theorem 4).
    #[default]
    MinVolume,
    /// Minimum trace (sum of squared semi-axes): closed form for the prediction, a bounded
    /// one-dimensional root search for the update (\[MN96\]).
    MinTrace,
}

/// Outer ellipsoid of `E(c, P) ∩ {x : |y − aᵀx| ≤ σ}` minimising `criterion` (the `obe` module
/// docs, \[Sch68\], \[FH82\], \[MN96\]). Returns `e` unchanged when the strip covers it, and
/// [`EstimationError::EmptyIntersection`] when the strip misses it.
pub fn intersect_strip<const N: usize>(
    e: &Ellipsoid<N>,
    a: &SVector<f64, N>,
    y: f64,
    sigma: f64,
    criterion: ObeCriterion,
) -> Result<Ellipsoid<N>> {
    match strip_step(e, a, y, sigma, criterion)? {
        Some(post) => {
            cholesky(&post.shape, "OBE updated shape")?;
            Ok(post)
        }
        None => Ok(*e),
    }
}

/// [`intersect_strip`] without the final positive-definiteness check (the vector update checks
/// once after all strips); `None` when the ellipsoid is unchanged.
pub(super) fn strip_step<const N: usize>(
    e: &Ellipsoid<N>,
    a: &SVector<f64, N>,
    y: f64,
    sigma: f64,
    criterion: ObeCriterion,
) -> Result<Option<Ellipsoid<N>>> {
    ensure_finite(a, "strip normal")?;
    if !y.is_finite() {
        return Err(EstimationError::NonFinite("measurement"));
    }
    if !(sigma.is_finite() && sigma > 0.0) {
        return Err(EstimationError::InvalidParameter(format!(
            "strip half-width must be finite and > 0, got {sigma}"
        )));
    }
    let P = &e.shape;
    let Pa = P * a;
    let g = a.dot(&Pa);
    let ac = a.dot(&e.center);
    if !(g.is_finite() && ac.is_finite()) {
        return Err(EstimationError::NonFinite("ellipsoid"));
    }
    // Support interval of the ellipsoid along a, and the tightened strip.
    let sg = g.max(0.0).sqrt();
    let (lo, hi) = ((y - sigma).max(ac - sg), (y + sigma).min(ac + sg));
    if lo > hi {
        return Err(EstimationError::EmptyIntersection);
    }
    if y - sigma <= ac - sg && y + sigma >= ac + sg {
        return Ok(None); // the strip covers the ellipsoid (always the case when g = 0)
    }
    let y = 0.5 * (lo + hi);
    let sigma = (0.5 * (hi - lo)).max(MIN_STRIP_FRACTION * sg);
    let innov = y - ac;
    if N == 1 {
        // Exact: the intersection of two intervals. g > 0 here, so a[0] ≠ 0.
        let a0 = a[0];
        let center = SVector::<f64, N>::from_element(y / a0);
        let shape = SMatrix::<f64, N, N>::from_element((sigma / a0).powi(2));
        return finite(center, shape).map(Some);
    }
    let sigma2 = sigma * sigma;
    let q = g / sigma2;
    let eps = innov * innov / sigma2;
    let rho_volume = rho_min_volume(N as f64, q, eps);
    let rho = match criterion {
        ObeCriterion::MinVolume => rho_volume,
        ObeCriterion::MinTrace => {
            rho_min_trace(q, eps, P.trace(), Pa.norm_squared() / sigma2, rho_volume)
        }
    };
    if rho.is_nan() || rho <= 0.0 {
        return Ok(None);
    }
    let s = 1.0 + rho * q; // (σ² + ρg)/σ²
    let delta = 1.0 + rho - rho * eps / s;
    if !(delta.is_finite() && delta > 0.0) {
        return Err(EstimationError::NotPositiveDefinite("OBE updated shape"));
    }
    let k = rho / (sigma2 * s); // ρ / (σ² + ρg)
    let center = e.center + Pa * (k * innov);
    let shape = symmetrize(&((P - Pa * Pa.transpose() * k) * delta));
    finite(center, shape).map(Some)
}

/// Checks that a new ellipsoid is finite.
fn finite<const N: usize>(
    center: SVector<f64, N>,
    shape: SMatrix<f64, N, N>,
) -> Result<Ellipsoid<N>> {
    ensure_finite(&center, "OBE centre")?;
    ensure_finite(&shape, "OBE shape")?;
    Ok(Ellipsoid { center, shape })
}

/// Outer ellipsoid of the Minkowski sum `A E(c, P) ⊕ {H w : ‖w‖₂ ≤ 1}` (`H = r B`) minimising
/// `criterion` within the family of \[ELL\] Theorems 3–4 (the `obe` module docs). Needs
/// `A P Aᵀ` positive definite (A invertible).
pub fn minkowski_outer<const N: usize, const W: usize>(
    e: &Ellipsoid<N>,
    A: &SMatrix<f64, N, N>,
    H: &SMatrix<f64, N, W>,
    criterion: ObeCriterion,
) -> Result<Ellipsoid<N>> {
    let center = A * e.center;
    let Q1 = symmetrize(&(A * e.shape * A.transpose()));
    let chol = cholesky(&Q1, "A P Aᵀ")?;
    let t2 = H.norm_squared(); // tr(H Hᵀ)
    ensure_finite(H, "process-noise input")?;
    if t2 == 0.0 {
        return finite(center, Q1); // no process noise: the image is exact
    }
    let kappa_trace = (Q1.trace() / t2).sqrt();
    let kappa = match criterion {
        ObeCriterion::MinTrace => kappa_trace,
        ObeCriterion::MinVolume => {
            // K = Hᵀ Q1⁻¹ H = Gᵀ G with L G = H; its eigenvalues kᵢ ≥ 0.
            let G = chol
                .l_dirty()
                .solve_lower_triangular(H)
                .ok_or(EstimationError::NotPositiveDefinite("A P Aᵀ"))?;
            let k = sym_eigenvalues(G.transpose() * G).map(|v| v.max(0.0));
            ensure_finite(&k, "process-noise ellipsoid")?;
            if k.sum() > 0.0 {
                kappa_min_volume(N as f64, &k, kappa_trace)
            } else {
                kappa_trace // K underflowed: any κ > 0 still gives an outer bound
            }
        }
    };
    if !(kappa.is_finite() && kappa > 0.0) {
        return Err(EstimationError::NonFinite("OBE prediction weight"));
    }
    let shape = symmetrize(&(Q1 * (1.0 + 1.0 / kappa) + H * H.transpose() * (1.0 + kappa)));
    ensure_finite(&center, "OBE predicted centre")?;
    ensure_finite(&shape, "OBE predicted shape")?;
    Ok(Ellipsoid { center, shape })
}

/// Shape of an outer ellipsoid of the predicted measurement set `C E(c, P) ⊕ box(σ)` (module
/// docs): `(1 + 1/κ) C P Cᵀ + (1 + κ) M diag σ²`, `κ = √(tr C P Cᵀ / (M Σσᵢ²))`.
pub(super) fn measurement_set_shape<const N: usize, const M: usize>(
    C: &SMatrix<f64, M, N>,
    P: &SMatrix<f64, N, N>,
    half_width: &SVector<f64, M>,
) -> SMatrix<f64, M, M> {
    let cpc = symmetrize(&(C * P * C.transpose()));
    let noise =
        SMatrix::<f64, M, M>::from_diagonal(&half_width.component_mul(half_width)) * M as f64;
    let t1 = cpc.trace();
    if t1.is_nan() || t1 <= 0.0 {
        return noise;
    }
    let kappa = (t1 / noise.trace()).sqrt();
    cpc * (1.0 + 1.0 / kappa) + noise * (1.0 + kappa)
}
