//! Central-difference Kalman filter (CDKF), the baseline of [ICDKF].
//!
//! Second-order Stirling interpolation with interval `h` (h² = 3 is optimal for Gaussian priors),
//! in the form of [NPR00] §3.3 / [VdM04] §3.3.2 with additive noise. With `sⱼ` the columns of the
//! lower Cholesky factor of P and `yⱼ± = g(x ± h sⱼ)` (g = f or h):
//!
//! ```text
//! ȳ   = (h² − n)/h² · g(x) + 1/(2h²) Σⱼ (yⱼ⁺ + yⱼ⁻)                         [VdM04] eq. (3.98)
//! Pyy = 1/(4h²) Σⱼ (yⱼ⁺ − yⱼ⁻)(…)ᵀ + (h² − 1)/(4h⁴) Σⱼ (yⱼ⁺ + yⱼ⁻ − 2g(x))(…)ᵀ   eq. (3.99)
//! Pxy = 1/(2h) Σⱼ sⱼ (yⱼ⁺ − yⱼ⁻)ᵀ                                            eq. (3.102)
//! ```
//!
//! Prediction: `x⁻ = ȳ`, `P⁻ = Pyy + Q`. Update: `S = Pzz + R`, `K = Pxz S⁻¹`, `x = x⁻ + K ν`. The
//! covariance update is written in Joseph form through the statistically linearised measurement
//! matrix `H̃ = Pxzᵀ P⁻⁻¹` and effective noise `R̃ = S − H̃ P⁻ H̃ᵀ` (≥ R): algebraically equal to
//! `P⁻ − K S Kᵀ`, but a sum of positive semi-definite terms. Differences of measurements use the
//! model's wrapped residual, so azimuths crossing ±π are handled.
//!
//! On linear models the CDKF reproduces the KF exactly (the second-order terms vanish).
//!
//! # References
//! * [NPR00] M. Nørgaard, N. K. Poulsen, O. Ravn, "New developments in state estimation for
//!   nonlinear systems", *Automatica* 36(11), 2000.
//! * [VdM04] R. van der Merwe, *Sigma-Point Kalman Filters for Probabilistic Inference in Dynamic
//!   State-Space Models*, PhD thesis, OGI 2004.
//! * [ICDKF] Q. Wang, "Research on target tracking technology of multi-rotor aircraft based on
//!   ICDKF" (`shared/papers/001`).
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::{Predictor, Updater};
use crate::linalg::{cholesky, ensure_finite, symmetrize};
use crate::measurement::MeasurementModel;
use crate::motion::TransitionModel;
use crate::state::{Gaussian, Posterior};
use crate::{EstimationError, Result};

/// Central-difference Kalman filter with interval `h` (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentralDifference {
    h: f64,
}

impl Default for CentralDifference {
    /// `h = √3`, optimal for Gaussian priors.
    fn default() -> Self {
        Self { h: 3f64.sqrt() }
    }
}

impl CentralDifference {
    /// CDKF with interval `h > 0` (usually √3).
    pub fn new(h: f64) -> Result<Self> {
        if h.is_finite() && h > 0.0 {
            Ok(Self { h })
        } else {
            Err(EstimationError::InvalidParameter(format!(
                "CDKF interval h must be > 0, got {h}"
            )))
        }
    }

    /// Central-difference moments of `g` about `Gaussian(x, P)` ([VdM04] eqs. (3.98)–(3.102)):
    /// returns `(ȳ, Pyy, Pxy)`. `diff(a, b)` is `a ⊖ b` (wrapped for angles).
    pub fn moments<const N: usize, const Y: usize>(
        &self,
        x: &SVector<f64, N>,
        P: &SMatrix<f64, N, N>,
        g: impl Fn(&SVector<f64, N>) -> SVector<f64, Y>,
        diff: impl Fn(&SVector<f64, Y>, &SVector<f64, Y>) -> SVector<f64, Y>,
    ) -> Result<(SVector<f64, Y>, SMatrix<f64, Y, Y>, SMatrix<f64, N, Y>)> {
        let h = self.h;
        let h2 = h * h;
        let L = cholesky(P, "state covariance")?.unpack();
        let y0 = g(x);
        let mut mean_dev = SVector::<f64, Y>::zeros();
        let mut Pyy1 = SMatrix::<f64, Y, Y>::zeros();
        let mut Pyy2 = SMatrix::<f64, Y, Y>::zeros();
        let mut Pxy = SMatrix::<f64, N, Y>::zeros();
        for j in 0..N {
            let s = L.column(j) * h;
            // Deviations from g(x), so that angles are differenced with wrapping.
            let dp = diff(&g(&(x + s)), &y0);
            let dm = diff(&g(&(x - s)), &y0);
            let d1 = dp - dm;
            let d2 = dp + dm;
            mean_dev += d2;
            Pyy1 += d1 * d1.transpose();
            Pyy2 += d2 * d2.transpose();
            Pxy += L.column(j) * d1.transpose();
        }
        // ȳ = g(x) + 1/(2h²) Σ (yⱼ⁺ + yⱼ⁻ − 2 g(x))   (same as eq. (3.98))
        let mean = y0 + mean_dev / (2.0 * h2);
        let Pyy = symmetrize(&(Pyy1 / (4.0 * h2) + Pyy2 * ((h2 - 1.0) / (4.0 * h2 * h2))));
        let Pxy = Pxy / (2.0 * h);
        ensure_finite(&mean, "sigma-point mean")?;
        ensure_finite(&Pyy, "sigma-point covariance")?;
        Ok((mean, Pyy, Pxy))
    }
}

impl<T: TransitionModel<N>, const N: usize> Predictor<T, N> for CentralDifference {
    type State = Gaussian<N>;
    /// `x⁻ = ȳ`, `P⁻ = Pyy + Q` with g = f ([VdM04] eqs. (3.98)–(3.99)).
    fn predict(&self, model: &T, prior: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        let (mean, Pyy, _) = self.moments(
            &prior.mean,
            &prior.cov,
            |x| model.function(x, dt),
            |a, b| a - b,
        )?;
        let cov = symmetrize(&(Pyy + model.covar(dt)));
        ensure_finite(&cov, "predicted covariance")?;
        Ok(Gaussian { mean, cov })
    }
}

impl<H: MeasurementModel<N, M>, const N: usize, const M: usize> Updater<H, N, M>
    for CentralDifference
{
    type State = Gaussian<N>;
    /// `ẑ = ȳ`, `S = Pzz + R`, `K = Pxz S⁻¹`, Joseph-form covariance through `H̃ = Pxzᵀ P⁻⁻¹`
    /// ([VdM04] eqs. (3.100)–(3.105)).
    fn update(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N>, M>> {
        let P = &predicted.cov;
        let (zhat, Pzz, Pxz) = self.moments(
            &predicted.mean,
            P,
            |x| model.function(x),
            |a, b| model.residual(a, b),
        )?;
        let R = model.covar();
        let S = symmetrize(&(Pzz + R));
        let chol_S = cholesky(&S, "innovation covariance")?;
        // K = Pxz S⁻¹
        let K = chol_S.solve(&Pxz.transpose()).transpose();
        let nu = model.residual(z, &zhat);
        ensure_finite(&nu, "innovation")?;
        let mean = predicted.mean + K * nu;
        // H̃ = Pxzᵀ P⁻¹ (statistical linearisation), R̃ = S − H̃ P H̃ᵀ.
        let Ht = cholesky(P, "predicted covariance")?.solve(&Pxz).transpose();
        let R_eff = symmetrize(&(S - Ht * Pxz));
        let I_KH = SMatrix::<f64, N, N>::identity() - K * Ht;
        let cov = symmetrize(&(I_KH * P * I_KH.transpose() + K * R_eff * K.transpose()));
        ensure_finite(&mean, "updated mean")?;
        ensure_finite(&cov, "updated covariance")?;
        Ok(Posterior {
            state: Gaussian { mean, cov },
            innovation: nu,
            innovation_cov: S,
        })
    }
}
