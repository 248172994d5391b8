//! The adaptive neural-network element of \[BOT\] §II.D: a single-hidden-layer network, trained
//! online on the filter residuals, that estimates the unknown target acceleration the estimator's
//! motion model leaves out.
//!
//! \[BOT\] follows the NN-augmented estimators of its refs. \[14\], \[15\] (Hovakimyan, Calise et al.):
//! the network output `â = Ŵᵀ σ(V̂ᵀ x̄)` enters the process model, and its weights follow a
//! gradient adaptive law driven by the training signal the filter residuals produce, with an
//! e-modification leak for boundedness:
//!
//! ```text
//! Ŵ̇ = Γ_W (σ(V̂ᵀx̄) eᵀ − κ ‖e‖ Ŵ)
//! V̂̇ = Γ_V (x̄ eᵀ Ŵᵀ σ′(V̂ᵀx̄) − κ ‖e‖ V̂)
//! ```
//!
//! Here `e` is the training error in acceleration units (the caller maps the residual through the
//! filter's gain, see `harrier-engine`'s `mpekf-nn`). The discrete law below is this gradient
//! step, normalised by `1 + ‖σ‖²` (normalised LMS, so that the step `γ < 1` is scale-free), plus a
//! projection of Ŵ onto a Frobenius ball of radius `w_max`: since |σᵢ| ≤ 1 the output is bounded by
//! `w_max·√H` whatever the data. The training error is saturated at that bound and V̂ is projected
//! onto a ball of RMS 4 (tanh saturates beyond), so every step is bounded too.
//!
//! Initialisation is deterministic (no RNG): Ŵ = 0, so the network starts as the plain filter, and
//! V̂ is a fixed, well-spread pattern `V̂ᵢⱼ = cos(1 + 2.3 i + 1.7 j)` (a fixed pseudo-random-looking
//! matrix, not tuned). All arrays are fixed-size; a step does not allocate.
//!
//! # References
//! * \[BOT\] "Vision-based estimation and formation control of multiple aircraft"
//!   (`shared/papers/002`), §II.D.
//! * N. Hovakimyan, A. J. Calise, V. Madyastha, "An adaptive observer design methodology for
//!   bounded nonlinear processes", IEEE CDC 2002 (the paper's ref. \[14\]).

use nalgebra::{SMatrix, SVector};

use crate::linalg::ensure_finite;
use crate::{EstimationError, Result};

/// RMS bound on the hidden weights: beyond a few units tanh saturates, larger weights add nothing.
const V_MAX: f64 = 4.0;

/// Single-hidden-layer network with I inputs (the first is a constant bias 1), H hidden units (the
/// last is a constant bias unit) and O outputs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AdaptiveNn<const I: usize, const H: usize, const O: usize> {
    /// Hidden-layer weights V̂ (row j feeds hidden unit j).
    v: SMatrix<f64, H, I>,
    /// Output weights Ŵ (row k feeds output k).
    w: SMatrix<f64, O, H>,
    gamma: f64,
    kappa: f64,
    w_max: f64,
}

impl<const I: usize, const H: usize, const O: usize> AdaptiveNn<I, H, O> {
    /// Network with normalised step `gamma ∈ (0, 1]`, e-modification gain `kappa ≥ 0` and output
    /// weight bound `w_max > 0`.
    pub fn new(gamma: f64, kappa: f64, w_max: f64) -> Result<Self> {
        const { assert!(I >= 1 && H >= 2 && O >= 1) };
        let valid = gamma > 0.0
            && gamma <= 1.0
            && kappa >= 0.0
            && kappa.is_finite()
            && w_max > 0.0
            && w_max.is_finite();
        if !valid {
            return Err(EstimationError::InvalidParameter(format!(
                "network: need 0 < gamma ≤ 1, kappa ≥ 0, w_max > 0; got {gamma}, {kappa}, {w_max}"
            )));
        }
        Ok(Self {
            v: SMatrix::from_fn(|i, j| (1.0 + 2.3 * i as f64 + 1.7 * j as f64).cos()),
            w: SMatrix::zeros(),
            gamma,
            kappa,
            w_max,
        })
    }

    /// Hidden activations `σ(V̂ᵀ x̄)` (tanh), the last one the constant bias 1.
    fn hidden(&self, x: &SVector<f64, I>) -> SVector<f64, H> {
        let mut s = (self.v * x).map(f64::tanh);
        s[H - 1] = 1.0;
        s
    }

    /// Network output `Ŵ σ(V̂ x̄)`.
    pub fn output(&self, x: &SVector<f64, I>) -> SVector<f64, O> {
        self.w * self.hidden(x)
    }

    /// Bound on any output component: `w_max·√H`.
    pub fn output_bound(&self) -> f64 {
        self.w_max * (H as f64).sqrt()
    }

    /// One step of the adaptive law (module docs) for input `x` and training error `e` (target −
    /// output). Weights are left unchanged if the inputs are not finite.
    pub fn train(&mut self, x: &SVector<f64, I>, e: &SVector<f64, O>) -> Result<()> {
        ensure_finite(x, "network input")?;
        ensure_finite(e, "network training error")?;
        // An error larger than anything the network can output carries no more direction
        // information: saturate it at the output bound (keeps the step and the leak bounded).
        let bound = self.output_bound();
        let en = e.norm();
        let e = if en > bound { e * (bound / en) } else { *e };
        let s = self.hidden(x);
        let step = self.gamma / (1.0 + s.norm_squared() + x.norm_squared());
        let leak = (self.kappa * e.norm()).min(1.0);
        // Back-propagated error at the hidden layer: σ′ ⊙ (Ŵᵀ e), zero for the bias unit.
        let mut back = self.w.transpose() * e;
        for j in 0..H {
            back[j] = if j == H - 1 {
                0.0
            } else {
                back[j] * (1.0 - s[j] * s[j])
            };
        }
        let w = self.w + (e * s.transpose() - self.w * leak) * step;
        let v = self.v + (back * x.transpose() - self.v * leak) * step;
        ensure_finite(&w, "network weights")?;
        ensure_finite(&v, "network weights")?;
        let n = w.norm();
        self.w = if n > self.w_max {
            w * (self.w_max / n)
        } else {
            w
        };
        let n = v.norm();
        self.v = if n > V_MAX * ((H * I) as f64).sqrt() {
            v * (V_MAX * ((H * I) as f64).sqrt() / n)
        } else {
            v
        };
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Vector3, Vector4};

    #[test]
    fn learns_a_constant_and_a_direction_dependent_target() {
        let mut nn = AdaptiveNn::<4, 8, 3>::new(0.5, 0.0, 50.0).unwrap();
        // acceleration perpendicular to the (unit) velocity input, as in a coordinated turn
        let target = |x: &Vector4<f64>| Vector3::new(-x[2], x[1], 0.0) * 2.0;
        for k in 0..100_000 {
            let th = 0.7 * (k as f64 * 0.01).sin();
            let x = Vector4::new(1.0, th.sin(), th.cos(), 0.0);
            let e = target(&x) - nn.output(&x);
            nn.train(&x, &e).unwrap();
        }
        let x = Vector4::new(1.0, 0.3f64.sin(), 0.3f64.cos(), 0.0);
        assert!(
            (nn.output(&x) - target(&x)).norm() < 0.3,
            "{}",
            nn.output(&x)
        );
    }

    #[test]
    fn stays_bounded_under_adversarial_errors() {
        let mut nn = AdaptiveNn::<4, 8, 3>::new(1.0, 0.01, 3.0).unwrap();
        for k in 0..10000 {
            let x = Vector4::new(1.0, (k as f64).sin() * 1e3, (k as f64).cos(), -5.0);
            let e = Vector3::new(1e6, -1e6, (k as f64).sin() * 1e9);
            nn.train(&x, &e).unwrap();
            assert!(
                nn.output(&x)
                    .iter()
                    .all(|o| o.abs() <= nn.output_bound() + 1e-9)
            );
        }
        let before = nn;
        assert!(
            nn.train(&Vector4::new(1.0, f64::NAN, 0.0, 0.0), &Vector3::zeros())
                .is_err()
        );
        assert_eq!(nn, before);
    }

    #[test]
    fn rejects_bad_parameters() {
        assert!(AdaptiveNn::<2, 3, 1>::new(0.0, 0.0, 1.0).is_err());
        assert!(AdaptiveNn::<2, 3, 1>::new(0.5, -1.0, 1.0).is_err());
        assert!(AdaptiveNn::<2, 3, 1>::new(0.5, 0.0, f64::INFINITY).is_err());
    }
}
