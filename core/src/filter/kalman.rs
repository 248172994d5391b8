//! Kalman filter and extended Kalman filter.
//!
//! ```text
//! predict:  x⁻ = f(x),             P⁻ = F P Fᵀ + Q                    \[BLK01\] eq. (5.2.3-5), (5.2.3-9)
//! update:   ν  = z ⊖ h(x⁻),        S  = H P⁻ Hᵀ + R                   \[BLK01\] eq. (5.2.3-13), (5.2.3-15)
//!           K  = P⁻ Hᵀ S⁻¹  (S⁻¹ from the Cholesky factor of S)         eq. (5.2.3-11)
//!           x  = x⁻ + K ν
//!           P  = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ  (Joseph form)      eq. (5.2.3-18)
//! ```
//! The Joseph form keeps P symmetric positive semi-definite for any gain; P is symmetrised after
//! every step. For the EKF, F and H are the Jacobians at x and x⁻ (\[BLK01\] §10.3.2).
//!
//! # References
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::traits::{
    MeasurementPrediction, MeasurementPredictor, NonlinearFilter, Predictor, Updater,
    nonlinear_filter,
};
use crate::Result;
use crate::linalg::{cholesky, ensure_covariance, ensure_finite, symmetrize};
use crate::measurement::{LinearMeasurement, MeasurementModel};
use crate::motion::{LinearTransition, TransitionModel};
use crate::state::{Gaussian, Posterior};

/// Linear Kalman filter: needs linear models.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Kalman;

/// Extended Kalman filter: first-order linearisation about the current estimate.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Extended;

/// `P⁻ = F P Fᵀ + Q` (`FPFt` from [`TransitionModel::propagate_cov`]), symmetrised and checked.
fn propagate<const N: usize>(
    mean: SVector<f64, N>,
    FPFt: &SMatrix<f64, N, N>,
    Q: &SMatrix<f64, N, N>,
) -> Result<Gaussian<N>> {
    ensure_finite(&mean, "predicted mean")?;
    let cov = symmetrize(&(FPFt + Q));
    ensure_covariance(&cov, "predicted covariance")?;
    Ok(Gaussian { mean, cov })
}

impl<T: LinearTransition<N>, const N: usize> Predictor<T, N> for Kalman {
    type State = Gaussian<N>;
    /// `x⁻ = F x`, `P⁻ = F P Fᵀ + Q` (\[BLK01\] eq. (5.2.3-5), (5.2.3-9)).
    fn predict(&self, model: &T, prior: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        let FPFt = model.propagate_cov(&prior.mean, &prior.cov, dt);
        propagate(model.matrix(dt) * prior.mean, &FPFt, &model.covar(dt))
    }
}

impl<T: TransitionModel<N>, const N: usize> Predictor<T, N> for Extended {
    type State = Gaussian<N>;
    /// `x⁻ = f(x)`, `P⁻ = F P Fᵀ + Q` with `F = ∂f/∂x(x)` (\[BLK01\] §10.3.2).
    fn predict(&self, model: &T, prior: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        let FPFt = model.propagate_cov(&prior.mean, &prior.cov, dt);
        propagate(model.function(&prior.mean, dt), &FPFt, &model.covar(dt))
    }
}

/// The Joseph-form Kalman update shared by the KF, EKF and the filters built on them.
///
/// Given the predicted state, the innovation `ν = z ⊖ ẑ`, the (linearised) measurement matrix `H`
/// and the noise covariance `R`:
/// `S = H P⁻ Hᵀ + R`, `K = P⁻ Hᵀ S⁻¹` (S⁻¹ from the Cholesky factor), `x = x⁻ + K ν`,
/// `P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ` (\[BLK01\] eq. (5.2.3-18)), symmetrised.
pub fn joseph_update<const N: usize, const M: usize>(
    predicted: &Gaussian<N>,
    innovation: SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    R: &SMatrix<f64, M, M>,
) -> Result<Posterior<Gaussian<N>, M>> {
    joseph_with(predicted, innovation, H, R, None)
}

/// The Joseph-form update of a Schmidt–Kalman ("consider") filter restricted to a subspace: the
/// optimal gain is projected by `T`, so that only the directions `T` keeps are estimated and the
/// others are *considered* — their mean stays as predicted while the covariance of every
/// component, and the cross-covariances with the considered directions, stay the true error
/// covariance of the suboptimal gain:
///
/// ```text
/// K = T K_opt,  K_opt = P⁻ Hᵀ S⁻¹
/// x = x⁻ + K ν,  P = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ
/// ```
/// (Schmidt 1966, whose considered states are the components `T` zeroes, `T` diagonal with
/// zeros and ones; the Joseph form holds for any gain, \[BLK01\] eq. (5.2.3-18)). With
/// `T = I` it is [`joseph_update`].
///
/// # References
/// * S. F. Schmidt, "Application of state-space methods to navigation problems", *Advances in
///   Control Systems* 3, 1966.
/// * R. Zanetti, C. D'Souza, "Recursive implementations of the consider filter", AAS 12-619, 2012.
pub fn consider_update<const N: usize, const M: usize>(
    predicted: &Gaussian<N>,
    innovation: SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    R: &SMatrix<f64, M, M>,
    T: &SMatrix<f64, N, N>,
) -> Result<Posterior<Gaussian<N>, M>> {
    ensure_finite(T, "gain projection")?;
    joseph_with(predicted, innovation, H, R, Some(T))
}

fn joseph_with<const N: usize, const M: usize>(
    predicted: &Gaussian<N>,
    innovation: SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    R: &SMatrix<f64, M, M>,
    projection: Option<&SMatrix<f64, N, N>>,
) -> Result<Posterior<Gaussian<N>, M>> {
    ensure_finite(&innovation, "innovation")?;
    ensure_finite(H, "measurement Jacobian")?;
    let P = &predicted.cov;
    let PHt = P * H.transpose();
    // S = H P Hᵀ + R
    let S = symmetrize(&(H * PHt + R));
    let chol = cholesky(&S, "innovation covariance")?;
    // K = P Hᵀ S⁻¹ with the explicit M × M inverse S⁻¹ = L⁻ᵀ L⁻¹ from the Cholesky factor L of S
    // (M triangular solves against the identity, cheaper than solving for the M × N right-hand
    // side Hᵀ P when M < N; S is SPD and checked by the factorisation, so the inverse is stable).
    let mut K = PHt * chol.inverse();
    if let Some(T) = projection {
        K = T * K;
    }
    let mean = predicted.mean + K * innovation;
    // P = (I − K H) P (I − K H)ᵀ + K R Kᵀ, evaluated through the rank-M factors so that no N×N×N
    // product is formed:  A = (I − K H) P = P − K (H P),  A (I − K H)ᵀ = A − (A Hᵀ) Kᵀ.
    let A = P - K * PHt.transpose();
    let cov = symmetrize(&(A - (A * H.transpose()) * K.transpose() + K * R * K.transpose()));
    ensure_finite(&mean, "updated mean")?;
    ensure_covariance(&cov, "updated covariance")?;
    Ok(Posterior {
        state: Gaussian { mean, cov },
        innovation,
        innovation_cov: S,
    })
}

impl<H: LinearMeasurement<N, M>, const N: usize, const M: usize> Updater<H, N, M> for Kalman {
    type State = Gaussian<N>;
    /// Joseph-form KF update, see [`joseph_update`].
    fn update(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N>, M>> {
        let Hm = model.matrix();
        let nu = model.residual(z, &(Hm * predicted.mean));
        joseph_update(predicted, nu, &Hm, &model.covar())
    }
}

impl<H: MeasurementModel<N, M>, const N: usize, const M: usize> Updater<H, N, M> for Extended {
    type State = Gaussian<N>;
    /// EKF update: `ν = z ⊖ h(x⁻)`, `H = ∂h/∂x(x⁻)`, then [`joseph_update`] (\[BLK01\] §10.3.2).
    fn update(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N>, M>> {
        let nu = model.residual(z, &model.function(&predicted.mean));
        joseph_update(
            predicted,
            nu,
            &model.jacobian(&predicted.mean),
            &model.covar(),
        )
    }
}

/// `ẑ = h(x⁻)`, `S = H P⁻ Hᵀ + R` with `H` the model's matrix or Jacobian at `x⁻`
/// (\[BLK01\] eq. (5.2.3-13), (5.2.3-15)), symmetrised and checked.
fn linearised_prediction<const N: usize, const M: usize>(
    zhat: SVector<f64, M>,
    H: &SMatrix<f64, M, N>,
    predicted: &Gaussian<N>,
    R: &SMatrix<f64, M, M>,
) -> Result<MeasurementPrediction<M>> {
    let cov = symmetrize(&(H * predicted.cov * H.transpose() + R));
    ensure_finite(&zhat, "predicted measurement")?;
    ensure_covariance(&cov, "innovation covariance")?;
    Ok(MeasurementPrediction { zhat, cov })
}

impl<H: LinearMeasurement<N, M>, const N: usize, const M: usize> MeasurementPredictor<H, N, M>
    for Kalman
{
    type State = Gaussian<N>;
    /// `ẑ = H x⁻`, `S = H P⁻ Hᵀ + R` (\[BLK01\] eq. (5.2.3-13), (5.2.3-15)).
    fn predict_measurement(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
    ) -> Result<MeasurementPrediction<M>> {
        let Hm = model.matrix();
        linearised_prediction(Hm * predicted.mean, &Hm, predicted, &model.covar())
    }
}

impl<H: MeasurementModel<N, M>, const N: usize, const M: usize> MeasurementPredictor<H, N, M>
    for Extended
{
    type State = Gaussian<N>;
    /// `ẑ = h(x⁻)`, `S = H P⁻ Hᵀ + R`, `H = ∂h/∂x(x⁻)` (\[BLK01\] §10.3.2).
    fn predict_measurement(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
    ) -> Result<MeasurementPrediction<M>> {
        linearised_prediction(
            model.function(&predicted.mean),
            &model.jacobian(&predicted.mean),
            predicted,
            &model.covar(),
        )
    }
}

nonlinear_filter!(Extended);
