//! Track-to-track fusion of Gaussian estimates of one target from several platforms (\[CIMM\] §3.3).
//!
//! * [`state_vector_fusion`]: the state-vector fusion of \[CIMM\] §3.3 (after Ng, Tan & Ng 2005),
//!   which ignores the cross-covariance between the tracks, in information form:
//!   `P = (Σ_t P_t⁻¹)⁻¹`, `x = P Σ_t P_t⁻¹ x_t`. For two tracks this is the paper's
//!   `x = x_t + P_t (P_t + P_q)⁻¹ (x_q − x_t)`, `P = P_t − P_t (P_t + P_q)⁻¹ P_t` (with `x_q, P_q`
//!   the fused estimate of the other UAVs). It is exact for independent errors but optimistic when
//!   the tracks share process noise, prior or road pseudo-measurements.
//! * [`covariance_intersection`]: Julier & Uhlmann's covariance intersection,
//!   `P⁻¹ = ω P_a⁻¹ + (1 − ω) P_b⁻¹`, `x = P (ω P_a⁻¹ x_a + (1 − ω) P_b⁻¹ x_b)`, with ω ∈ [0, 1]
//!   minimising `trace P` or `det P` (golden-section search; both criteria are convex in ω). It is
//!   consistent whatever the (unknown) cross-correlation. More than two tracks are fused
//!   sequentially, pairwise, which keeps that guarantee.
//!
//! Every inverse goes through a Cholesky solve; nothing allocates.
//!
//! # References
//! * \[CIMM\] `shared/papers/003`, §3.3.
//! * G. W. Ng, C. H. Tan, T. P. Ng, "Tracking ground targets using state vector fusion", Fusion 2005.
//! * S. J. Julier, J. K. Uhlmann, "A non-divergent estimation algorithm in the presence of unknown
//!   correlations", ACC 1997.

use nalgebra::{SMatrix, SVector};

use crate::linalg::{cholesky, ensure_covariance, ensure_finite, ln_det, symmetrize};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// `(P⁻¹, P⁻¹ x)` of a Gaussian, by Cholesky solves.
fn information<const N: usize>(g: &Gaussian<N>) -> Result<(SMatrix<f64, N, N>, SVector<f64, N>)> {
    let chol = cholesky(&g.cov, "track covariance")?;
    Ok((
        symmetrize(&chol.solve(&SMatrix::<f64, N, N>::identity())),
        chol.solve(&g.mean),
    ))
}

/// Back from information form: `P = Y⁻¹`, `x = P y`.
fn from_information<const N: usize>(
    y_mat: &SMatrix<f64, N, N>,
    y_vec: &SVector<f64, N>,
) -> Result<Gaussian<N>> {
    let chol = cholesky(&symmetrize(y_mat), "fused information matrix")?;
    let cov = symmetrize(&chol.solve(&SMatrix::<f64, N, N>::identity()));
    let mean = chol.solve(y_vec);
    ensure_finite(&mean, "fused mean")?;
    Ok(Gaussian { mean, cov })
}

/// At least one track, and every track a finite Gaussian with no negative variance: a single
/// track is returned as it is, so a corrupt one must be refused here (found by the
/// hostile-number tests, `core/tests/it/hostile.rs`).
fn nonempty<const N: usize>(tracks: &[Gaussian<N>]) -> Result<()> {
    if tracks.is_empty() {
        return Err(EstimationError::InvalidParameter(
            "fusion needs at least one track".into(),
        ));
    }
    for g in tracks {
        ensure_finite(&g.mean, "track mean")?;
        ensure_covariance(&g.cov, "track covariance")?;
    }
    Ok(())
}

/// State-vector fusion ignoring cross-covariances (\[CIMM\] §3.3), see the module docs.
pub fn state_vector_fusion<const N: usize>(tracks: &[Gaussian<N>]) -> Result<Gaussian<N>> {
    nonempty(tracks)?;
    if let [only] = tracks {
        return Ok(*only);
    }
    let mut y_mat = SMatrix::<f64, N, N>::zeros();
    let mut y_vec = SVector::<f64, N>::zeros();
    for g in tracks {
        let (i_mat, i_vec) = information(g)?;
        y_mat += i_mat;
        y_vec += i_vec;
    }
    from_information(&y_mat, &y_vec)
}

/// What covariance intersection minimises.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CiCriterion {
    /// `trace P`.
    Trace,
    /// `det P` (the volume of the covariance ellipsoid).
    Det,
}

/// Covariance intersection of two tracks: ω ∈ [0, 1] minimising the criterion, and the fused
/// Gaussian (Julier & Uhlmann 1997).
pub fn covariance_intersection_pair<const N: usize>(
    a: &Gaussian<N>,
    b: &Gaussian<N>,
    criterion: CiCriterion,
) -> Result<(f64, Gaussian<N>)> {
    let (ia, ya) = information(a)?;
    let (ib, yb) = information(b)?;
    let cost = |w: f64| -> Result<f64> {
        let chol = cholesky(&symmetrize(&(ia * w + ib * (1.0 - w))), "CI information")?;
        Ok(match criterion {
            // ln det P = −ln det P⁻¹
            CiCriterion::Det => -ln_det(&chol),
            CiCriterion::Trace => chol.solve(&SMatrix::<f64, N, N>::identity()).trace(),
        })
    };
    // Golden-section search on [0, 1]: 60 iterations shrink the bracket to ~1e-12.
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
    let mut x1 = hi - g * (hi - lo);
    let mut x2 = lo + g * (hi - lo);
    let (mut f1, mut f2) = (cost(x1)?, cost(x2)?);
    for _ in 0..60 {
        if f1 <= f2 {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = cost(x1)?;
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = cost(x2)?;
        }
    }
    let mut w = 0.5 * (lo + hi);
    // The optimum may sit on the boundary (one track dominates the other).
    for edge in [0.0, 1.0] {
        if cost(edge)? < cost(w)? {
            w = edge;
        }
    }
    let fused = from_information(&(ia * w + ib * (1.0 - w)), &(ya * w + yb * (1.0 - w)))?;
    Ok((w, fused))
}

/// Covariance intersection of any number of tracks, fused pairwise in order (consistent for
/// unknown cross-correlations).
pub fn covariance_intersection<const N: usize>(
    tracks: &[Gaussian<N>],
    criterion: CiCriterion,
) -> Result<Gaussian<N>> {
    nonempty(tracks)?;
    let mut fused = tracks[0];
    for g in &tracks[1..] {
        fused = covariance_intersection_pair(&fused, g, criterion)?.1;
    }
    Ok(fused)
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix2, Vector2};

    fn g(x: f64, y: f64, p: Matrix2<f64>) -> Gaussian<2> {
        Gaussian::new(Vector2::new(x, y), p).unwrap()
    }

    #[test]
    fn svf_of_independent_equal_tracks_halves_the_covariance() {
        let a = g(0.0, 0.0, Matrix2::new(4.0, 1.0, 1.0, 2.0));
        let b = g(2.0, 2.0, Matrix2::new(4.0, 1.0, 1.0, 2.0));
        let f = state_vector_fusion(&[a, b]).unwrap();
        assert_relative_eq!(f.mean, Vector2::new(1.0, 1.0), epsilon = 1e-12);
        assert_relative_eq!(f.cov, a.cov * 0.5, epsilon = 1e-12);
        // Two-track form of [CIMM] §3.3.
        let c = g(1.0, -1.0, Matrix2::new(1.0, 0.0, 0.0, 9.0));
        let f = state_vector_fusion(&[a, c]).unwrap();
        let k = a.cov * (a.cov + c.cov).try_inverse().unwrap();
        assert_relative_eq!(f.mean, a.mean + k * (c.mean - a.mean), epsilon = 1e-12);
        assert_relative_eq!(f.cov, a.cov - k * a.cov, epsilon = 1e-12);
    }

    #[test]
    fn ci_is_consistent_and_picks_the_better_track() {
        // Identical tracks (fully correlated): CI must not shrink the covariance.
        let a = g(1.0, 2.0, Matrix2::new(4.0, 1.0, 1.0, 2.0));
        for c in [CiCriterion::Trace, CiCriterion::Det] {
            let f = covariance_intersection(&[a, a, a], c).unwrap();
            assert_relative_eq!(f.cov, a.cov, epsilon = 1e-9);
            assert_relative_eq!(f.mean, a.mean, epsilon = 1e-9);
        }
        // A much better track dominates: ω → 1.
        let b = g(0.0, 0.0, Matrix2::identity() * 100.0);
        let (w, f) = covariance_intersection_pair(&a, &b, CiCriterion::Trace).unwrap();
        assert!(w > 0.95, "{w}");
        assert!(f.cov.trace() <= a.cov.trace() + 1e-9);
        // Complementary tracks: the fused ellipse is smaller than both and ω is interior.
        let x = g(0.0, 0.0, Matrix2::new(1.0, 0.0, 0.0, 100.0));
        let y = g(0.0, 0.0, Matrix2::new(100.0, 0.0, 0.0, 1.0));
        let (w, f) = covariance_intersection_pair(&x, &y, CiCriterion::Det).unwrap();
        assert_relative_eq!(w, 0.5, epsilon = 1e-6);
        assert!(f.cov.determinant() < x.cov.determinant());
        // CI covariance bounds every convex combination of the inputs: P⁻¹ = ω A⁻¹ + (1−ω) B⁻¹.
        let inv = f.cov.try_inverse().unwrap();
        let expect = x.cov.try_inverse().unwrap() * w + y.cov.try_inverse().unwrap() * (1.0 - w);
        assert_relative_eq!(inv, expect, epsilon = 1e-9);
    }
}
