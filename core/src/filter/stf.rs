//! Strong tracking filter (STF): a Kalman filter whose predicted covariance is inflated by a
//! suboptimal fading factor λ ≥ 1 whenever the innovations are larger than the model says they
//! should be, the baseline filter of \[ESE\] §4 (its ref. [9]).
//!
//! Single-fading-factor form of \[ZF96\] (the suboptimal fading factor of Zhou, Xi & Zhang
//! [ZXZ]), written for a linear model. With γ the innovation, β ≥ 1 the softening factor and
//! 0 < ρ ≤ 1 the forgetting factor, one step k is:
//!
//! ```text
//! x⁻  = F x                                                    prediction of the mean
//! γ   = z ⊖ H x⁻                                               innovation
//! V_k = γ γᵀ                       (first step)                innovation covariance estimate
//!     = (ρ V_{k−1} + γ γᵀ) / (1 + ρ)  (afterwards)
//! N_k = V_k − H Q Hᵀ − β R
//! M_k = H F P Fᵀ Hᵀ
//! c   = tr N_k / tr M_k,   λ = max(1, c)                       suboptimal fading factor
//! P⁻  = λ F P Fᵀ + Q
//! S   = H P⁻ Hᵀ + R,  K = P⁻ Hᵀ S⁻¹,  x = x⁻ + K γ
//! P   = (I − K H) P⁻ (I − K H)ᵀ + K R Kᵀ                       Joseph form, \[BLK01\] eq. (5.2.3-18)
//! ```
//!
//! The covariance update is the **Joseph form** ([`joseph_update`], \[BLK01\] eq. (5.2.3-18)) rather
//! than the short form `P = (I − K H) P⁻` of \[ZF96\]. The Joseph form is a sum of positive
//! semi-definite terms, so P stays symmetric positive semi-definite for any gain and any λ; the short
//! form relies on cancellation, which is fragile when P and R are tiny (the angle noise of \[ESE\] §4
//! is σ = 2·10⁻⁶ rad, R = 4·10⁻¹²) and λ jumps by orders of magnitude.
//!
//! Because λ depends on the innovation, prediction and update cannot be split into the
//! [`Predictor`](super::traits::Predictor) / [`Updater`](super::traits::Updater) roles;
//! [`StrongTracking::step`] does both. With λ = 1 at every step (innovations no larger than
//! predicted) the STF is exactly the Kalman filter [`Kalman`](super::kalman::Kalman).
//!
//! # References
//! * \[ZF96\] D. H. Zhou, P. M. Frank, "Strong tracking filtering of nonlinear time-varying stochastic
//!   systems with coloured noise: application to parameter estimation and empirical robustness
//!   analysis", *Int. J. Control* 65(2), 1996.
//! * [ZXZ] D. H. Zhou, Y. G. Xi, Z. J. Zhang, the suboptimal fading extended Kalman filter (single
//!   fading factor).
//! * \[ESE\] M. Cen, C. Fu, K. Chen, X. Liu, "Error-space estimate method for generalized synergic
//!   target tracking" (`shared/papers/004`), §4: β = 1, ρ = 0.95.
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::kalman::joseph_update;
use crate::linalg::{ensure_covariance, ensure_finite, symmetrize};
use crate::measurement::LinearMeasurement;
use crate::motion::LinearTransition;
use crate::state::{Gaussian, Posterior};
use crate::{EstimationError, Result};

/// Strong tracking filter with softening factor β and forgetting factor ρ (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StrongTracking {
    beta: f64,
    rho: f64,
}

impl Default for StrongTracking {
    /// β = 1, ρ = 0.95 (\[ESE\] §4).
    fn default() -> Self {
        Self {
            beta: 1.0,
            rho: 0.95,
        }
    }
}

/// What the STF carries between steps: the Gaussian estimate and the innovation covariance estimate
/// `V_{k−1}` (`None` before the first step).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StfState<const N: usize, const M: usize> {
    /// Filtered estimate `x̂(k|k)`, `P(k|k)`.
    pub estimate: Gaussian<N>,
    /// Innovation covariance estimate `V_k` of the last step; `None` before the first step.
    pub innovation_cov: Option<SMatrix<f64, M, M>>,
}

impl<const N: usize, const M: usize> StfState<N, M> {
    /// Starts the STF from an initial estimate (no innovation seen yet).
    pub fn new(estimate: Gaussian<N>) -> Self {
        Self {
            estimate,
            innovation_cov: None,
        }
    }
}

/// The result of one STF step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StfStep<const N: usize, const M: usize> {
    /// State to carry to the next step.
    pub state: StfState<N, M>,
    /// The Joseph-form update with its innovation `γ` and covariance `S = H P⁻ Hᵀ + R`.
    pub posterior: Posterior<Gaussian<N>, M>,
    /// The fading factor λ ≥ 1 applied to `F P Fᵀ` at this step.
    pub fading_factor: f64,
}

impl StrongTracking {
    /// STF with softening factor `beta > 0` (usually ≥ 1) and forgetting factor `0 < rho ≤ 1`.
    pub fn new(beta: f64, rho: f64) -> Result<Self> {
        if !(beta.is_finite() && beta > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "STF softening factor beta must be > 0, got {beta}"
            )));
        }
        if !(rho.is_finite() && rho > 0.0 && rho <= 1.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "STF forgetting factor rho must be in (0, 1], got {rho}"
            )));
        }
        Ok(Self { beta, rho })
    }

    /// Softening factor β.
    pub fn beta(&self) -> f64 {
        self.beta
    }

    /// Forgetting factor ρ.
    pub fn rho(&self) -> f64 {
        self.rho
    }

    /// The suboptimal fading factor `λ = max(1, tr N / tr M)` (\[ZF96\]) and the updated
    /// innovation covariance estimate `V_k`, for innovation `gamma`, previous estimate `v_prev`
    /// (`None` on the first step), `FPFᵀ`, `Q`, `H` and `R`. When `tr M ≤ 0` (a degenerate,
    /// singular `P`) scaling `F P Fᵀ` is meaningless and λ = 1.
    pub fn fading_factor<const N: usize, const M: usize>(
        &self,
        gamma: &SVector<f64, M>,
        v_prev: Option<&SMatrix<f64, M, M>>,
        FPFt: &SMatrix<f64, N, N>,
        Q: &SMatrix<f64, N, N>,
        H: &SMatrix<f64, M, N>,
        R: &SMatrix<f64, M, M>,
    ) -> Result<(f64, SMatrix<f64, M, M>)> {
        let ggt = gamma * gamma.transpose();
        // V_k = γγᵀ (first step), else (ρ V_{k−1} + γγᵀ)/(1 + ρ).
        let V = match v_prev {
            None => ggt,
            Some(v) => (v * self.rho + ggt) / (1.0 + self.rho),
        };
        ensure_finite(&V, "STF innovation covariance estimate")?;
        // N_k = V_k − H Q Hᵀ − β R,  M_k = H F P Fᵀ Hᵀ.
        let Nk = V - H * Q * H.transpose() - R * self.beta;
        let Mk = H * FPFt * H.transpose();
        let (tr_n, tr_m) = (Nk.trace(), Mk.trace());
        let lambda = if tr_m > 0.0 {
            (tr_n / tr_m).max(1.0)
        } else {
            1.0
        };
        if !lambda.is_finite() {
            return Err(EstimationError::NonFinite("STF fading factor"));
        }
        Ok((lambda, V))
    }

    /// One STF step over `dt` seconds with measurement `z` (see the module docs for the
    /// equations). The prior is left untouched on error.
    pub fn step<T, H, const N: usize, const M: usize>(
        &self,
        transition: &T,
        measurement: &H,
        prior: &StfState<N, M>,
        z: &SVector<f64, M>,
        dt: f64,
    ) -> Result<StfStep<N, M>>
    where
        T: LinearTransition<N>,
        H: LinearMeasurement<N, M>,
    {
        ensure_finite(z, "measurement")?;
        let F = transition.matrix(dt);
        let Q = transition.covar(dt);
        let Hm = measurement.matrix();
        let R = measurement.covar();
        let P = &prior.estimate.cov;
        // x⁻ = F x, γ = z ⊖ H x⁻.
        let mean = F * prior.estimate.mean;
        ensure_finite(&mean, "predicted mean")?;
        let gamma = measurement.residual(z, &(Hm * mean));
        let FPFt = transition.propagate_cov(&prior.estimate.mean, P, dt);
        let (lambda, V) =
            self.fading_factor(&gamma, prior.innovation_cov.as_ref(), &FPFt, &Q, &Hm, &R)?;
        // P⁻ = λ F P Fᵀ + Q.
        let cov = symmetrize(&(FPFt * lambda + Q));
        ensure_covariance(&cov, "predicted covariance")?;
        let posterior = joseph_update(&Gaussian { mean, cov }, gamma, &Hm, &R)?;
        Ok(StfStep {
            state: StfState {
                estimate: posterior.state,
                innovation_cov: Some(V),
            },
            posterior,
            fading_factor: lambda,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::kalman::Kalman;
    use crate::filter::traits::{Predictor, Updater};
    use crate::measurement::DirectPosition;
    use crate::motion::WienerAcceleration;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix3, Vector1, Vector3};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    fn prior() -> Gaussian<3> {
        Gaussian::new(
            Vector3::new(0.0, 1.0, 0.0),
            Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 0.1)),
        )
        .unwrap()
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(StrongTracking::new(0.0, 0.95).is_err());
        assert!(StrongTracking::new(1.0, 0.0).is_err());
        assert!(StrongTracking::new(1.0, 1.5).is_err());
        assert!(StrongTracking::new(f64::NAN, 0.95).is_err());
        assert!(StrongTracking::new(1.0, 1.0).is_ok());
    }

    #[test]
    fn with_small_innovations_it_is_the_kalman_filter() {
        // Consistent data (noise much smaller than R): N_k < 0, λ = 1 and the STF reproduces the
        // Joseph-form KF to rounding.
        let motion = WienerAcceleration::<3>::new(0.1);
        let meas = DirectPosition::<1>::new([1.0]);
        let stf = StrongTracking::new(1.0, 0.95).unwrap();
        let mut s = StfState::<3, 1>::new(prior());
        let mut k = prior();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let noise = Normal::new(0.0, 0.05).unwrap();
        for i in 1..200 {
            let t = 0.1 * f64::from(i);
            let z = Vector1::new(t + noise.sample(&mut rng));
            let out = stf.step(&motion, &meas, &s, &z, 0.1).unwrap();
            assert_eq!(out.fading_factor, 1.0, "step {i}");
            s = out.state;
            let pred = Kalman.predict(&motion, &k, 0.1).unwrap();
            k = Kalman.update(&meas, &pred, &z).unwrap().state;
            assert_relative_eq!(
                s.estimate.mean,
                k.mean,
                max_relative = 1e-12,
                epsilon = 1e-14
            );
            assert_relative_eq!(s.estimate.cov, k.cov, max_relative = 1e-12, epsilon = 1e-14);
        }
    }

    #[test]
    fn fades_on_a_manoeuvre_and_recovers_faster_than_the_kf() {
        // A constant-velocity ramp that suddenly turns with a large acceleration; the KF with small q
        // lags, the STF inflates P (λ > 1) and follows.
        let motion = WienerAcceleration::<3>::new(1e-3);
        let meas = DirectPosition::<1>::new([0.01]);
        let stf = StrongTracking::default();
        let x0 = Gaussian::new(Vector3::zeros(), Matrix3::identity() * 1e-2).unwrap();
        let mut s = StfState::<3, 1>::new(x0);
        let mut k = x0;
        let dt = 0.1;
        let truth = |t: f64| {
            if t < 5.0 {
                t
            } else {
                t + 2.0 * (t - 5.0).powi(2)
            }
        };
        let mut max_lambda: f64 = 1.0;
        let (mut err_stf, mut err_kf) = (0.0f64, 0.0f64);
        for i in 1..100 {
            let t = dt * f64::from(i);
            let z = Vector1::new(truth(t));
            let out = stf.step(&motion, &meas, &s, &z, dt).unwrap();
            max_lambda = max_lambda.max(out.fading_factor);
            s = out.state;
            let pred = Kalman.predict(&motion, &k, dt).unwrap();
            k = Kalman.update(&meas, &pred, &z).unwrap().state;
            if t > 7.0 {
                err_stf = err_stf.max((s.estimate.mean[0] - truth(t)).abs());
                err_kf = err_kf.max((k.mean[0] - truth(t)).abs());
            }
        }
        assert!(max_lambda > 10.0, "λ = {max_lambda}");
        assert!(err_stf < 0.2 * err_kf, "STF {err_stf} vs KF {err_kf}");
    }

    #[test]
    fn first_step_uses_the_outer_product_and_then_forgets() {
        let stf = StrongTracking::new(1.0, 0.5).unwrap();
        let H = SMatrix::<f64, 1, 3>::new(1.0, 0.0, 0.0);
        let R = SMatrix::<f64, 1, 1>::new(1.0);
        let Q = Matrix3::zeros();
        let FPFt = Matrix3::identity();
        let g = Vector1::new(3.0);
        let (l, v) = stf.fading_factor(&g, None, &FPFt, &Q, &H, &R).unwrap();
        assert_relative_eq!(v[(0, 0)], 9.0);
        assert_relative_eq!(l, 8.0); // (9 − 1) / 1
        let (l, v) = stf
            .fading_factor(&Vector1::new(0.0), Some(&v), &FPFt, &Q, &H, &R)
            .unwrap();
        assert_relative_eq!(v[(0, 0)], 0.5 * 9.0 / 1.5);
        assert_relative_eq!(l, 2.0);
        // Singular P: λ = 1.
        let (l, _) = stf
            .fading_factor(&g, None, &Matrix3::zeros(), &Q, &H, &R)
            .unwrap();
        assert_eq!(l, 1.0);
    }

    #[test]
    fn errors_leave_no_panic() {
        let stf = StrongTracking::default();
        let s = StfState::<3, 1>::new(prior());
        let motion = WienerAcceleration::<3>::new(0.1);
        let meas = DirectPosition::<1>::new([1.0]);
        assert_eq!(
            stf.step(&motion, &meas, &s, &Vector1::new(f64::NAN), 0.1)
                .unwrap_err(),
            EstimationError::NonFinite("measurement")
        );
    }
}
