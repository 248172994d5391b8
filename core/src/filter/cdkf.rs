//! Central-difference Kalman filter (CDKF), the baseline of \[ICDKF\].
//!
//! Second-order Stirling interpolation with interval `h` (h² = 3 is optimal for Gaussian priors),
//! in the form of \[NPR00\] §3.3 / \[VdM04\] §3.3.2 with additive noise. With `sⱼ` the columns of the
//! lower Cholesky factor of P and `yⱼ± = g(x ± h sⱼ)` (g = f or h):
//!
//! ```text
//! ȳ   = (h² − n)/h² · g(x) + 1/(2h²) Σⱼ (yⱼ⁺ + yⱼ⁻)                         \[VdM04\] eq. (3.98)
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
//! * \[NPR00\] M. Nørgaard, N. K. Poulsen, O. Ravn, "New developments in state estimation for
//!   nonlinear systems", *Automatica* 36(11), 2000.
//! * \[VdM04\] R. van der Merwe, *Sigma-Point Kalman Filters for Probabilistic Inference in Dynamic
//!   State-Space Models*, PhD thesis, OGI 2004.
//! * \[ICDKF\] Q. Wang, "Research on target tracking technology of multi-rotor aircraft based on
//!   ICDKF" (`shared/papers/001`).
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::traits::{
    MeasurementPrediction, MeasurementPredictor, NonlinearFilter, Predictor, Updater,
    nonlinear_filter,
};
use crate::linalg::{cholesky, ensure_covariance, ensure_finite, symmetrize};
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

    /// Central-difference moments of `g` about `Gaussian(x, P)` (\[VdM04\] eqs. (3.98)–(3.102)):
    /// returns `(ȳ, Pyy, Pxy)`. `diff(a, b)` is `a ⊖ b` (wrapped for angles).
    pub fn moments<const N: usize, const Y: usize>(
        &self,
        x: &SVector<f64, N>,
        P: &SMatrix<f64, N, N>,
        g: impl Fn(&SVector<f64, N>) -> SVector<f64, Y>,
        diff: impl Fn(&SVector<f64, Y>, &SVector<f64, Y>) -> SVector<f64, Y>,
    ) -> Result<(SVector<f64, Y>, SMatrix<f64, Y, Y>, SMatrix<f64, N, Y>)> {
        let L = cholesky(P, "state covariance")?.unpack();
        let y0 = g(x);
        let mut acc = Stirling::new();
        for j in 0..N {
            let s = L.column(j) * self.h;
            acc.add(
                diff(&g(&(x + s)), &y0),
                diff(&g(&(x - s)), &y0),
                Some(&L.column(j).into_owned()),
            );
        }
        acc.finish(y0, self.h)
    }

    /// Moments of a function with non-additive noise, `y = g(x, w)`, `w ~ N(0, W)`: the noise is
    /// augmented into the sigma points (\[NPR00\] §4, "general" form). The interval points perturb the
    /// state with w = 0 and the noise with x = x̂; `Pxy` is the cross-covariance with the state only.
    pub fn moments_with_noise<const N: usize, const W: usize, const Y: usize>(
        &self,
        x: &SVector<f64, N>,
        P: &SMatrix<f64, N, N>,
        noise_cov: &SMatrix<f64, W, W>,
        g: impl Fn(&SVector<f64, N>, &SVector<f64, W>) -> SVector<f64, Y>,
        diff: impl Fn(&SVector<f64, Y>, &SVector<f64, Y>) -> SVector<f64, Y>,
    ) -> Result<(SVector<f64, Y>, SMatrix<f64, Y, Y>, SMatrix<f64, N, Y>)> {
        let L = cholesky(P, "state covariance")?.unpack();
        let Lw = cholesky(noise_cov, "noise covariance")?.unpack();
        let w0 = SVector::<f64, W>::zeros();
        let y0 = g(x, &w0);
        let mut acc = Stirling::new();
        for j in 0..N {
            let s = L.column(j) * self.h;
            acc.add(
                diff(&g(&(x + s), &w0), &y0),
                diff(&g(&(x - s), &w0), &y0),
                Some(&L.column(j).into_owned()),
            );
        }
        for j in 0..W {
            let s = Lw.column(j) * self.h;
            acc.add(
                diff(&g(x, &(w0 + s)), &y0),
                diff(&g(x, &(w0 - s)), &y0),
                None,
            );
        }
        acc.finish(y0, self.h)
    }
}

/// Accumulates the Stirling-interpolation sums of \[VdM04\] eqs. (3.98)–(3.102) from the deviations
/// `dⱼ± = g(x̂ ± h sⱼ) ⊖ g(x̂)`.
struct Stirling<const N: usize, const Y: usize> {
    mean_dev: SVector<f64, Y>,
    pyy1: SMatrix<f64, Y, Y>,
    pyy2: SMatrix<f64, Y, Y>,
    pxy: SMatrix<f64, N, Y>,
}

impl<const N: usize, const Y: usize> Stirling<N, Y> {
    fn new() -> Self {
        Self {
            mean_dev: SVector::zeros(),
            pyy1: SMatrix::zeros(),
            pyy2: SMatrix::zeros(),
            pxy: SMatrix::zeros(),
        }
    }

    /// One interval pair; `s` is the state column sⱼ (None for noise columns).
    fn add(&mut self, dp: SVector<f64, Y>, dm: SVector<f64, Y>, s: Option<&SVector<f64, N>>) {
        let d1 = dp - dm;
        let d2 = dp + dm;
        self.mean_dev += d2;
        self.pyy1 += d1 * d1.transpose();
        self.pyy2 += d2 * d2.transpose();
        if let Some(s) = s {
            self.pxy += s * d1.transpose();
        }
    }

    fn finish(
        self,
        y0: SVector<f64, Y>,
        h: f64,
    ) -> Result<(SVector<f64, Y>, SMatrix<f64, Y, Y>, SMatrix<f64, N, Y>)> {
        let h2 = h * h;
        // ȳ = g(x) + 1/(2h²) Σ (yⱼ⁺ + yⱼ⁻ − 2 g(x))   (eq. (3.98) in deviation form)
        let mean = y0 + self.mean_dev / (2.0 * h2);
        // Pyy = 1/(4h²) Σ d1 d1ᵀ + (h² − 1)/(4h⁴) Σ d2 d2ᵀ   (eq. (3.99))
        let Pyy =
            symmetrize(&(self.pyy1 / (4.0 * h2) + self.pyy2 * ((h2 - 1.0) / (4.0 * h2 * h2))));
        // Pxy = 1/(2h) Σ sⱼ d1ᵀ   (eq. (3.102))
        let Pxy = self.pxy / (2.0 * h);
        ensure_finite(&mean, "sigma-point mean")?;
        ensure_covariance(&Pyy, "sigma-point covariance")?;
        Ok((mean, Pyy, Pxy))
    }
}

impl<T: TransitionModel<N>, const N: usize> Predictor<T, N> for CentralDifference {
    type State = Gaussian<N>;
    /// `x⁻ = ȳ`, `P⁻ = Pyy + Q` with g = f (\[VdM04\] eqs. (3.98)–(3.99)).
    fn predict(&self, model: &T, prior: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        let (mean, Pyy, _) = self.moments(
            &prior.mean,
            &prior.cov,
            |x| model.function(x, dt),
            |a, b| a - b,
        )?;
        let cov = symmetrize(&(Pyy + model.covar(dt)));
        ensure_covariance(&cov, "predicted covariance")?;
        Ok(Gaussian { mean, cov })
    }
}

impl CentralDifference {
    /// The measurement moments of `predicted` under `model`: `ẑ = z̄`, `S = Pzz + R` (symmetrised)
    /// and `Pxz` (\[VdM04\] eqs. (3.98)–(3.102) on h, then (3.100)): what the update and the
    /// measurement prediction share.
    fn measurement_moments<H: MeasurementModel<N, M>, const N: usize, const M: usize>(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
    ) -> Result<(SVector<f64, M>, SMatrix<f64, M, M>, SMatrix<f64, N, M>)> {
        let (zhat, Pzz, Pxz) = self.moments(
            &predicted.mean,
            &predicted.cov,
            |x| model.function(x),
            |a, b| model.residual(a, b),
        )?;
        Ok((zhat, symmetrize(&(Pzz + model.covar())), Pxz))
    }
}

impl<H: MeasurementModel<N, M>, const N: usize, const M: usize> Updater<H, N, M>
    for CentralDifference
{
    type State = Gaussian<N>;
    /// `ẑ = ȳ`, `S = Pzz + R`, `K = Pxz S⁻¹`, Joseph-form covariance through `H̃ = Pxzᵀ P⁻⁻¹`
    /// (\[VdM04\] eqs. (3.100)–(3.105)).
    fn update(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N>, M>> {
        let (zhat, S, Pxz) = self.measurement_moments(model, predicted)?;
        let nu = model.residual(z, &zhat);
        sigma_point_update(predicted, S, &Pxz, nu)
    }
}

impl<H: MeasurementModel<N, M>, const N: usize, const M: usize> MeasurementPredictor<H, N, M>
    for CentralDifference
{
    type State = Gaussian<N>;
    /// `ẑ = ȳ`, `S = Pzz + R` (\[VdM04\] eqs. (3.98)–(3.99) on h, then (3.100)).
    fn predict_measurement(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
    ) -> Result<MeasurementPrediction<M>> {
        let (zhat, cov, _) = self.measurement_moments(model, predicted)?;
        ensure_covariance(&cov, "innovation covariance")?;
        Ok(MeasurementPrediction { zhat, cov })
    }
}

nonlinear_filter!(CentralDifference);

/// The measurement update shared by the sigma-point filters (CDKF, ICDKF), given the innovation
/// covariance `S`, the cross-covariance `Pxz` and the innovation `ν`:
/// `K = Pxz S⁻¹`, `x = x⁻ + K ν`, and the Joseph form through the statistically linearised
/// `H̃ = Pxzᵀ P⁻⁻¹` and `R̃ = S − H̃ Pxz` (\[VdM04\] eqs. (3.103)–(3.105) with the covariance written
/// as `(I − K H̃) P⁻ (I − K H̃)ᵀ + K R̃ Kᵀ`).
pub(crate) fn sigma_point_update<const N: usize, const M: usize>(
    predicted: &Gaussian<N>,
    S: SMatrix<f64, M, M>,
    Pxz: &SMatrix<f64, N, M>,
    nu: SVector<f64, M>,
) -> Result<Posterior<Gaussian<N>, M>> {
    ensure_finite(&nu, "innovation")?;
    let P = &predicted.cov;
    // K = Pxz S⁻¹
    let K = cholesky(&S, "innovation covariance")?
        .solve(&Pxz.transpose())
        .transpose();
    let mean = predicted.mean + K * nu;
    // H̃ = Pxzᵀ P⁻¹ (statistical linearisation), R̃ = S − H̃ Pxz.
    let Ht = cholesky(P, "predicted covariance")?.solve(Pxz).transpose();
    let R_eff = symmetrize(&(S - Ht * Pxz));
    let I_KH = SMatrix::<f64, N, N>::identity() - K * Ht;
    let cov = symmetrize(&(I_KH * P * I_KH.transpose() + K * R_eff * K.transpose()));
    ensure_finite(&mean, "updated mean")?;
    ensure_covariance(&cov, "updated covariance")?;
    Ok(Posterior {
        state: Gaussian { mean, cov },
        innovation: nu,
        innovation_cov: S,
    })
}
