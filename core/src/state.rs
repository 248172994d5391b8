//! State representations: Gaussian (mean + covariance) and ellipsoidal sets (centre + shape), and the
//! [`Posterior`] an update returns.

use std::f64::consts::PI;

use nalgebra::{SMatrix, SVector};

use crate::Result;
use crate::linalg::{cholesky, ensure_finite, ln_det, mahalanobis_sq};

/// A Gaussian state estimate `x ~ N(mean, cov)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gaussian<const N: usize> {
    /// State mean.
    pub mean: SVector<f64, N>,
    /// State covariance, symmetric positive definite.
    pub cov: SMatrix<f64, N, N>,
}

impl<const N: usize> Gaussian<N> {
    /// Builds a Gaussian after checking that the mean is finite and the covariance SPD.
    pub fn new(mean: SVector<f64, N>, cov: SMatrix<f64, N, N>) -> Result<Self> {
        ensure_finite(&mean, "state mean")?;
        cholesky(&cov, "state covariance")?;
        Ok(Self { mean, cov })
    }
}

/// `Σ wᵢ N(xᵢ, Pᵢ)` collapsed to one Gaussian by moment matching (Bar-Shalom, Li & Kirubarajan 2001, §11.6.6 step 5):
/// `x = Σ wᵢ xᵢ`, `P = Σ wᵢ [Pᵢ + (xᵢ − x)(xᵢ − x)ᵀ]`, symmetrised. The weights should sum to 1;
/// `components` and `weights` are paired in order.
pub fn moment_match<const N: usize>(components: &[Gaussian<N>], weights: &[f64]) -> Gaussian<N> {
    let mut mean = SVector::<f64, N>::zeros();
    for (g, wi) in components.iter().zip(weights) {
        mean.axpy(*wi, &g.mean, 1.0);
    }
    let mut cov = SMatrix::<f64, N, N>::zeros();
    for (g, wi) in components.iter().zip(weights) {
        let d = g.mean - mean;
        cov += g.cov * *wi;
        cov.ger(*wi, &d, &d, 1.0);
    }
    Gaussian {
        mean,
        cov: crate::linalg::symmetrize(&cov),
    }
}

/// An ellipsoidal set `E(c, P) = {x : (x − c)ᵀ P⁻¹ (x − c) ≤ 1}`, the set-membership counterpart of a
/// Gaussian (FORMAT.md §5 `ellipsoid`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ellipsoid<const N: usize> {
    /// Centre `c`.
    pub center: SVector<f64, N>,
    /// Shape matrix `P`, symmetric positive definite.
    pub shape: SMatrix<f64, N, N>,
}

impl<const N: usize> Ellipsoid<N> {
    /// Builds an ellipsoid after checking that the centre is finite and the shape SPD.
    pub fn new(center: SVector<f64, N>, shape: SMatrix<f64, N, N>) -> Result<Self> {
        ensure_finite(&center, "ellipsoid centre")?;
        cholesky(&shape, "ellipsoid shape")?;
        Ok(Self { center, shape })
    }

    /// `(x − c)ᵀ P⁻¹ (x − c)`: ≤ 1 inside the set.
    pub fn normalized_distance_sq(&self, x: &SVector<f64, N>) -> Result<f64> {
        mahalanobis_sq(&(x - self.center), &self.shape, "ellipsoid shape")
    }

    /// Whether `x` lies in the set (with a relative tolerance `tol` on the normalised distance).
    pub fn contains(&self, x: &SVector<f64, N>, tol: f64) -> Result<bool> {
        Ok(self.normalized_distance_sq(x)? <= 1.0 + tol)
    }

    /// Volume `V_N · sqrt(det P)`, `V_N` the unit-ball volume.
    pub fn volume(&self) -> Result<f64> {
        let chol = cholesky(&self.shape, "ellipsoid shape")?;
        Ok(crate::metrics::unit_ball_volume(N) * (0.5 * ln_det(&chol)).exp())
    }
}

/// What an update produced: the new state plus the innovation `ν = z ⊖ ẑ` and its covariance `S`
/// (Stone Soup's `Update.hypothesis`). For set-membership filters `innovation_cov` is the shape of
/// the predicted measurement set instead.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Posterior<S, const M: usize> {
    /// Posterior state.
    pub state: S,
    /// Innovation `ν = z ⊖ ẑ` (angle components wrapped).
    pub innovation: SVector<f64, M>,
    /// Innovation covariance `S`.
    pub innovation_cov: SMatrix<f64, M, M>,
}

impl<S, const M: usize> Posterior<S, M> {
    /// Normalised innovation squared `νᵀ S⁻¹ ν` (χ² with M degrees of freedom when consistent).
    pub fn nis(&self) -> Result<f64> {
        mahalanobis_sq(
            &self.innovation,
            &self.innovation_cov,
            "innovation covariance",
        )
    }

    /// Gaussian log-likelihood `ln N(ν; 0, S)` of the measurement, what IMM mode weights need.
    pub fn log_likelihood(&self) -> Result<f64> {
        let chol = cholesky(&self.innovation_cov, "innovation covariance")?;
        let d2 = self.innovation.dot(&chol.solve(&self.innovation));
        Ok(-0.5 * (d2 + ln_det(&chol) + M as f64 * (2.0 * PI).ln()))
    }
}
