//! A bias-robust radar estimator of Harrier's own design: CDKF on a state augmented with additive
//! measurement-bias states, plus a bias-jump hypothesis test.
//!
//! **Why.** \[ICDKF\] cancels a slowly varying bias by differencing, but increments carry no
//! absolute position, so its position random-walks (see
//! [`IncrementalCdkf`](super::icdkf::IncrementalCdkf)). Estimating the bias as a state (Friedland's
//! augmentation, which \[ICDKF\] §1 discusses) keeps the absolute information; the difficulty is
//! that a bias which is present from the start is indistinguishable from a shifted target, while a
//! bias that *switches* (abrupt on/off, \[ICDKF\] type 2) is detectable as a step in the
//! innovations that no admissible target motion explains.
//!
//! **Model.** State `[x; b]`, x the kinematic state (CV), `b ∈ R^M` an additive offset per
//! measurement component (the scale error `s·h` of \[ICDKF\] eq. (9) varies slowly with range and is
//! absorbed by b):
//!
//! ```text
//! z_k = h(x_k) + b_k + v_k                      (\[ICDKF\] eq. (10) with Γ_k = I)
//! b_k = φ b_{k−1} + η_k,  φ = exp(−Δt/τ)      (first-order Markov, or a random walk for τ = ∞)
//! ```
//!
//! **Jump test.** At every update two hypotheses are compared: H₀ "the bias evolved as modelled"
//! and H₁ "the bias jumped", i.e. the bias covariance is inflated by `J = diag(σ_jump²)` before
//! the update. With prior jump probability p, H₁ is accepted when
//! `ln N(ν₁; 0, S₁) + ln p > ln N(ν₀; 0, S₀) + ln(1 − p)` — a one-step generalised likelihood
//! ratio test between two Gaussian hypotheses (Willsky & Jones 1976). The posterior of the accepted
//! hypothesis is kept; its innovation and likelihood are returned so callers can log the decision.
//!
//! # References
//! * \[ICDKF\] Q. Wang, `shared/papers/001`.
//! * A. S. Willsky, H. L. Jones, "A generalized likelihood ratio approach to the detection and
//!   estimation of jumps in linear systems", *IEEE TAC* 21(1), 1976.
//! * B. Friedland, "Treatment of bias in recursive filtering", *IEEE TAC* 14(4), 1969.
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::cdkf::CentralDifference;
use super::traits::{Predictor, Updater};
use crate::measurement::MeasurementModel;
use crate::motion::TransitionModel;
use crate::state::{Gaussian, Posterior};
use crate::{EstimationError, Result};

/// Kinematic model `T` on the first `K` components, bias dynamics on the last `B`: a first-order
/// Markov process with correlation time τ, or a random walk when τ = ∞.
///
/// ```text
/// b_k = φ b_{k−1} + η_k,  φ = exp(−Δt/τ),  Var η = d² τ/2 (1 − φ²)   (→ d² Δt as τ → ∞)
/// ```
/// `d` is the drift intensity (std per √s); the stationary std of a Markov bias is `d √(τ/2)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WithBias<T, const K: usize, const B: usize> {
    /// Kinematic model.
    pub kinematic: T,
    /// Drift intensity per bias component (units per √s).
    pub drift: [f64; B],
    /// Correlation time τ (s), `f64::INFINITY` for a random walk.
    pub tau: f64,
}

impl<T, const K: usize, const B: usize> WithBias<T, K, B> {
    /// Bias with drift intensity `drift` (units/√s) and correlation time `tau` (s, may be ∞).
    pub fn new(kinematic: T, drift: [f64; B], tau: f64) -> Result<Self> {
        if tau.is_nan() || tau <= 0.0 || drift.iter().any(|s| !(s.is_finite() && *s >= 0.0)) {
            return Err(EstimationError::InvalidParameter(format!(
                "bias model needs τ > 0 and drift ≥ 0, got τ = {tau}, drift = {drift:?}"
            )));
        }
        Ok(Self {
            kinematic,
            drift,
            tau,
        })
    }

    fn phi(&self, dt: f64) -> f64 {
        if self.tau.is_finite() {
            (-dt / self.tau).exp()
        } else {
            1.0
        }
    }

    /// Variance of η over Δt per unit drift².
    fn var_unit(&self, dt: f64) -> f64 {
        if self.tau.is_finite() {
            0.5 * self.tau * (1.0 - (-2.0 * dt / self.tau).exp())
        } else {
            dt
        }
    }
}

impl<T: TransitionModel<K>, const K: usize, const B: usize, const N: usize> TransitionModel<N>
    for WithBias<T, K, B>
{
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        const { assert!(K + B == N) };
        let phi = self.phi(dt);
        let mut y = *x;
        y.fixed_rows_mut::<K>(0).copy_from(
            &self
                .kinematic
                .function(&x.fixed_rows::<K>(0).into_owned(), dt),
        );
        for i in K..N {
            y[i] *= phi;
        }
        y
    }
    fn jacobian(&self, x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        let phi = self.phi(dt);
        let mut j = SMatrix::<f64, N, N>::identity();
        j.fixed_view_mut::<K, K>(0, 0).copy_from(
            &self
                .kinematic
                .jacobian(&x.fixed_rows::<K>(0).into_owned(), dt),
        );
        for i in K..N {
            j[(i, i)] = phi;
        }
        j
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        let v = self.var_unit(dt);
        let mut q = SMatrix::<f64, N, N>::zeros();
        q.fixed_view_mut::<K, K>(0, 0)
            .copy_from(&self.kinematic.covar(dt));
        for (i, d) in self.drift.iter().enumerate() {
            q[(K + i, K + i)] = d * d * v;
        }
        q
    }
}

/// `h(x) + b`: a measurement model `H` on the kinematic part plus the additive bias states
/// `x[K..K+M]`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasedMeasurement<H, const K: usize> {
    /// Bias-free model.
    pub inner: H,
}

impl<H: MeasurementModel<K, M>, const K: usize, const M: usize, const N: usize>
    MeasurementModel<N, M> for BiasedMeasurement<H, K>
{
    fn function(&self, x: &SVector<f64, N>) -> SVector<f64, M> {
        self.inner.function(&x.fixed_rows::<K>(0).into_owned()) + x.fixed_rows::<M>(K)
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, M, N> {
        let mut j = SMatrix::<f64, M, N>::zeros();
        j.fixed_view_mut::<M, K>(0, 0)
            .copy_from(&self.inner.jacobian(&x.fixed_rows::<K>(0).into_owned()));
        j.fixed_view_mut::<M, M>(0, K).fill_with_identity();
        j
    }
    fn covar(&self) -> SMatrix<f64, M, M> {
        self.inner.covar()
    }
    fn residual(&self, a: &SVector<f64, M>, b: &SVector<f64, M>) -> SVector<f64, M> {
        self.inner.residual(a, b)
    }
}

/// CDKF on `[x; b]` with the bias-jump hypothesis test (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasAwareCdkf<const M: usize> {
    /// The sigma-point filter.
    pub cd: CentralDifference,
    /// Standard deviation of a bias jump, per component (H₁ inflates the bias covariance by its
    /// square).
    pub jump_std: [f64; M],
    /// Prior probability of a jump at any update.
    pub jump_prob: f64,
}

/// The result of [`BiasAwareCdkf::update`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BiasUpdate<const N: usize, const M: usize> {
    /// Posterior under the accepted hypothesis.
    pub posterior: Posterior<Gaussian<N>, M>,
    /// Whether a bias jump was declared.
    pub jump: bool,
}

impl<const M: usize> BiasAwareCdkf<M> {
    /// Prediction of `[x; b]`.
    pub fn predict<T: TransitionModel<N>, const N: usize>(
        &self,
        model: &T,
        prior: &Gaussian<N>,
        dt: f64,
    ) -> Result<Gaussian<N>> {
        self.cd.predict(model, prior, dt)
    }

    /// Update with the jump test; `K` is the kinematic state size (bias at `K..K+M`).
    pub fn update<H: MeasurementModel<K, M>, const K: usize, const N: usize>(
        &self,
        model: &BiasedMeasurement<H, K>,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<BiasUpdate<N, M>> {
        const { assert!(K + M == N) };
        let h0 = self.cd.update(model, predicted, z)?;
        if self.jump_prob <= 0.0 {
            return Ok(BiasUpdate {
                posterior: h0,
                jump: false,
            });
        }
        let mut jumped = *predicted;
        for (i, s) in self.jump_std.iter().enumerate() {
            jumped.cov[(K + i, K + i)] += s * s;
        }
        let h1 = self.cd.update(model, &jumped, z)?;
        let l0 = h0.log_likelihood()? + (1.0 - self.jump_prob).ln();
        let l1 = h1.log_likelihood()? + self.jump_prob.ln();
        Ok(if l1 > l0 {
            BiasUpdate {
                posterior: h1,
                jump: true,
            }
        } else {
            BiasUpdate {
                posterior: h0,
                jump: false,
            }
        })
    }
}
