//! Small numerical helpers shared by the filters: symmetrisation, Cholesky solves, angle wrapping.
//!
//! All of them work on statically sized nalgebra types and never allocate.

use std::f64::consts::{PI, TAU};

use nalgebra::{Cholesky, Const, SMatrix, SVector};

use crate::{EstimationError, Result};

/// Wraps an angle to `[-π, π)` (FORMAT.md §1).
#[inline]
pub fn wrap_angle(a: f64) -> f64 {
    let w = (a + PI).rem_euclid(TAU) - PI;
    // rem_euclid can round up to TAU for tiny negative inputs; keep the half-open interval.
    if w >= PI { w - TAU } else { w }
}

/// `(A + Aᵀ) / 2`: removes the asymmetry that rounding leaves in a covariance.
#[inline]
pub fn symmetrize<const N: usize>(a: &SMatrix<f64, N, N>) -> SMatrix<f64, N, N> {
    (a + a.transpose()) * 0.5
}

/// Cholesky factorisation of an SPD matrix, or [`EstimationError::NotPositiveDefinite`] naming `what`.
#[inline]
pub fn cholesky<const N: usize>(
    a: &SMatrix<f64, N, N>,
    what: &'static str,
) -> Result<Cholesky<f64, Const<N>>> {
    if !a.iter().all(|v| v.is_finite()) {
        return Err(EstimationError::NonFinite(what));
    }
    Cholesky::new(*a).ok_or(EstimationError::NotPositiveDefinite(what))
}

/// Checks that every element is finite.
#[inline]
pub fn ensure_finite<const R: usize, const C: usize>(
    a: &SMatrix<f64, R, C>,
    what: &'static str,
) -> Result<()> {
    if a.iter().all(|v| v.is_finite()) {
        Ok(())
    } else {
        Err(EstimationError::NonFinite(what))
    }
}

/// Checks what every covariance a filter returns must satisfy at least: finite, and no variance
/// below zero (a necessary condition of positive semi-definiteness, O(N)). Rounding may leave a
/// zero variance at −1e-12 of the largest one; anything more negative comes from a corrupt
/// input — a negative process-noise density or measurement variance, a prior that is not a
/// covariance — and is refused (found by the hostile-number tests, `core/tests/it/hostile.rs`).
#[inline]
pub fn ensure_covariance<const N: usize>(a: &SMatrix<f64, N, N>, what: &'static str) -> Result<()> {
    ensure_finite(a, what)?;
    let d = a.diagonal();
    let tol = 1e-12 * d.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    if d.iter().all(|&v| v >= -tol) {
        Ok(())
    } else {
        Err(EstimationError::NotPositiveDefinite(what))
    }
}

/// `vᵀ A⁻¹ v` through a Cholesky solve (never an explicit inverse).
#[inline]
pub fn mahalanobis_sq<const N: usize>(
    v: &SVector<f64, N>,
    a: &SMatrix<f64, N, N>,
    what: &'static str,
) -> Result<f64> {
    let chol = cholesky(a, what)?;
    Ok(v.dot(&chol.solve(v)))
}

/// `ln det A` of an SPD matrix from its Cholesky factor.
#[inline]
pub fn ln_det<const N: usize>(chol: &Cholesky<f64, Const<N>>) -> f64 {
    2.0 * chol
        .l_dirty()
        .diagonal()
        .iter()
        .map(|d| d.ln())
        .sum::<f64>()
}

/// Eigenvalues and unit eigenvectors (the columns, in the same order) of a symmetric `N × N`
/// matrix by the cyclic Jacobi method (Golub & Van Loan, *Matrix Computations*, 4th ed.,
/// §8.5.3): rotations annihilate each off-diagonal entry in turn until they are below 1e-12 of
/// the matrix's norm (at most 50 sweeps; a sweep is O(N³)). Stack matrices, no allocation, any
/// const `N` (nalgebra's `SymmetricEigen` needs a type-level dimension).
pub fn symmetric_eigen<const N: usize>(
    a: &SMatrix<f64, N, N>,
) -> (SVector<f64, N>, SMatrix<f64, N, N>) {
    let mut a = symmetrize(a);
    let mut v = SMatrix::<f64, N, N>::identity();
    let scale = a.norm();
    for _ in 0..50 {
        let off: f64 = (0..N)
            .flat_map(|i| (0..N).filter(move |j| *j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[(i, j)] * a[(i, j)])
            .sum();
        if off.sqrt() <= 1e-12 * scale {
            break;
        }
        for p in 0..N {
            for q in p + 1..N {
                let apq = a[(p, q)];
                if apq == 0.0 {
                    continue;
                }
                // The rotation (c, s) that zeroes a[p][q]: t = tan θ, the smaller root of
                // t² + 2τt − 1 = 0, τ = (a_qq − a_pp) / (2 a_pq).
                let tau = (a[(q, q)] - a[(p, p)]) / (2.0 * apq);
                let t = tau.signum() / (tau.abs() + (1.0 + tau * tau).sqrt());
                let t = if tau == 0.0 { 1.0 } else { t };
                let c = 1.0 / (1.0 + t * t).sqrt();
                let s = t * c;
                for k in 0..N {
                    let (akp, akq) = (a[(k, p)], a[(k, q)]);
                    a[(k, p)] = c * akp - s * akq;
                    a[(k, q)] = s * akp + c * akq;
                }
                for k in 0..N {
                    let (apk, aqk) = (a[(p, k)], a[(q, k)]);
                    a[(p, k)] = c * apk - s * aqk;
                    a[(q, k)] = s * apk + c * aqk;
                }
                for k in 0..N {
                    let (vkp, vkq) = (v[(k, p)], v[(k, q)]);
                    v[(k, p)] = c * vkp - s * vkq;
                    v[(k, q)] = s * vkp + c * vkq;
                }
            }
        }
    }
    (a.diagonal(), v)
}

/// The ellipse `{x : xᵀ M⁻¹ x ≤ 1}` of a symmetric positive semi-definite 2 × 2 matrix `M`: its
/// semi-axes `[√λ_max, √λ_min]` and the direction of the major axis (rad, counter-clockwise from
/// the first axis). Scale `M` by a χ² quantile first for a confidence ellipse.
pub fn ellipse_axes(m: &nalgebra::Matrix2<f64>) -> ([f64; 2], f64) {
    let e = nalgebra::SymmetricEigen::new(symmetrize(m));
    let (major, minor) = if e.eigenvalues[0] >= e.eigenvalues[1] {
        (0, 1)
    } else {
        (1, 0)
    };
    let v = e.eigenvectors.column(major);
    (
        [
            e.eigenvalues[major].max(0.0).sqrt(),
            e.eigenvalues[minor].max(0.0).sqrt(),
        ],
        v[1].atan2(v[0]),
    )
}

/// The ellipsoid `{x : xᵀ M⁻¹ x ≤ 1}` of a symmetric positive semi-definite 3 × 3 matrix `M`: its
/// semi-axes `√λ`, largest first, and the unit axis directions in the same order. Scale `M` by a
/// χ² quantile first for a confidence ellipsoid.
pub fn ellipsoid_axes(m: &nalgebra::Matrix3<f64>) -> ([f64; 3], [[f64; 3]; 3]) {
    let e = nalgebra::SymmetricEigen::new(symmetrize(m));
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
    let axis = |i: usize| {
        let v = e.eigenvectors.column(i);
        [v[0], v[1], v[2]]
    };
    (
        order.map(|i| e.eigenvalues[i].max(0.0).sqrt()),
        order.map(axis),
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn wrap_is_half_open() {
        assert_relative_eq!(wrap_angle(PI), -PI);
        assert_relative_eq!(wrap_angle(-PI), -PI);
        assert_relative_eq!(wrap_angle(3.0 * PI + 0.1), -PI + 0.1, epsilon = 1e-12);
        assert_relative_eq!(wrap_angle(-0.1), -0.1);
        assert!(wrap_angle(-1e-18) < PI);
    }

    #[test]
    fn cholesky_rejects_indefinite_and_nan() {
        let m = SMatrix::<f64, 2, 2>::new(1.0, 2.0, 2.0, 1.0);
        assert_eq!(
            cholesky(&m, "m").unwrap_err(),
            EstimationError::NotPositiveDefinite("m")
        );
        let n = SMatrix::<f64, 2, 2>::new(f64::NAN, 0.0, 0.0, 1.0);
        assert_eq!(
            cholesky(&n, "n").unwrap_err(),
            EstimationError::NonFinite("n")
        );
    }

    #[test]
    fn jacobi_eigen_matches_nalgebra() {
        let b = SMatrix::<f64, 5, 5>::from_fn(|i, j| ((i * 7 + j * 3) % 11) as f64 - 4.0);
        let m = b * b.transpose() + SMatrix::<f64, 5, 5>::from_diagonal_element(0.1);
        let (values, vectors) = symmetric_eigen(&m);
        let mut ours: Vec<f64> = values.iter().copied().collect();
        let mut theirs: Vec<f64> = nalgebra::SymmetricEigen::new(m)
            .eigenvalues
            .iter()
            .copied()
            .collect();
        ours.sort_by(f64::total_cmp);
        theirs.sort_by(f64::total_cmp);
        for (a, b) in ours.iter().zip(&theirs) {
            assert_relative_eq!(a, b, epsilon = 1e-9, max_relative = 1e-10);
        }
        // M V = V Λ, Vᵀ V = I.
        let lambda = SMatrix::<f64, 5, 5>::from_diagonal(&values);
        assert_relative_eq!(m * vectors, vectors * lambda, epsilon = 1e-8);
        assert_relative_eq!(
            vectors.transpose() * vectors,
            SMatrix::<f64, 5, 5>::identity(),
            epsilon = 1e-10
        );
        let (d, _) = symmetric_eigen(&SMatrix::<f64, 2, 2>::new(3.0, 0.0, 0.0, 1.0));
        assert_eq!(d, nalgebra::Vector2::new(3.0, 1.0));
    }

    #[test]
    fn ellipse_axes_of_a_rotated_ellipse() {
        let (c, s) = (0.3f64.cos(), 0.3f64.sin());
        let r = nalgebra::Matrix2::new(c, -s, s, c);
        let m = r * nalgebra::Matrix2::new(16.0, 0.0, 0.0, 4.0) * r.transpose();
        let (axes, angle) = ellipse_axes(&m);
        assert!(
            (axes[0] - 4.0).abs() < 1e-12 && (axes[1] - 2.0).abs() < 1e-12,
            "{axes:?}"
        );
        assert!(
            (wrap_angle(2.0 * (angle - 0.3)) / 2.0).abs() < 1e-12,
            "{angle}"
        );
    }

    #[test]
    fn ellipsoid_axes_largest_first_with_their_directions() {
        let m = nalgebra::Matrix3::new(4.0, 0.0, 0.0, 0.0, 25.0, 0.0, 0.0, 0.0, 9.0);
        let (axes, dirs) = ellipsoid_axes(&m);
        assert_eq!(axes, [5.0, 3.0, 2.0]);
        for (d, unit) in dirs.iter().zip([1, 2, 0]) {
            assert!((d[unit].abs() - 1.0).abs() < 1e-12, "{dirs:?}");
        }
    }
}
