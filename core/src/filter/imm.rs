//! Interacting multiple model (IMM) estimator over any Gaussian mode filter, and its
//! road-constrained form (CIMM, \[CIMM\] §3.2).
//!
//! The recursion is the standard IMM of \[BLK01\] §11.6.6 (the equations of \[CIMM\] §3.2 are the same
//! algorithm but are garbled in our copy of the paper, so the \[BLK01\] form is the one implemented).
//! With `p_ij` the Markov transition probability from mode i to mode j and `μ_i` the mode
//! probabilities at k−1:
//!
//! ```text
//! 1. mixing probabilities  c̄_j = Σ_i p_ij μ_i,  μ_{i|j} = p_ij μ_i / c̄_j
//!                          (\[BLK01\] §11.6.6 step 1; \[CIMM\] §3.2 step 1, "input interaction")
//! 2. mixing                x⁰ʲ = Σ_i μ_{i|j} xⁱ,  P⁰ʲ = Σ_i μ_{i|j} [Pⁱ + (xⁱ − x⁰ʲ)(xⁱ − x⁰ʲ)ᵀ]
//!                          (\[BLK01\] step 2; \[CIMM\] eqs. (18)–(19))
//! 3. mode-matched filters  predict x⁰ʲ with mode j's model, update with z;
//!                          Λ_j = N(ν_j; 0, S_j) from the innovation (Posterior::log_likelihood)
//!                          (\[BLK01\] step 3; \[CIMM\] §3.2 steps 2–3, the likelihood Λ_k^j)
//! 4. mode probabilities    μ_j = Λ_j c̄_j / Σ_t Λ_t c̄_t
//!                          (\[BLK01\] step 4; \[CIMM\] §3.2 step 3, normalising factor c)
//! 5. combination           x = Σ_j μ_j xʲ,  P = Σ_j μ_j [Pʲ + (xʲ − x)(xʲ − x)ᵀ]
//!                          (\[BLK01\] step 5; \[CIMM\] §3.2 step 4, "estimation fusion")
//! ```
//!
//! The recursion is split into [`Imm::predict`] (steps 1–2 and the prediction of step 3; the
//! predicted mode probabilities are `c̄_j`) and [`Imm::update`] (the update of step 3 and step 4),
//! so several measurements of one time are applied sequentially: each update multiplies the mode
//! probabilities by that measurement's likelihood, which is the joint likelihood of independent
//! measurements. The CIMM of \[CIMM\] §3.2 is this IMM with the road pseudo-measurement of
//! [`crate::road::RoadConstraint`] applied as one more update in every mode filter (the augmented
//! measurement `z^a = [z; z^r]` of \[CIMM\] §3.1, applied sequentially), see [`Imm::update`].
//!
//! Mode probabilities are updated in the log domain (log-sum-exp) and floored at
//! [`PROB_FLOOR`], so a mode never underflows to zero and can come back.
//!
//! Everything is on the stack: `[Gaussian<N>; R]` arrays, no heap allocation per step.
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001, §11.6.6.
//! * \[CIMM\] `shared/papers/003`: constrained IMM for multi-UAV standoff tracking, §3.
//! * \[IMMPDA\] B. Chen, J. K. Tugnait, "Tracking of multiple maneuvering targets in clutter using
//!   IMM/JPDA filtering and fixed-lag smoothing", *Automatica* 37(2), 239–249, 2001; D. Mušicki,
//!   B. F. La Scala, "Multi-target tracking in clutter without measurement assignment", *IEEE
//!   Trans. Aerospace and Electronic Systems* 44(3), 2008 (IMM-JIPDA).

use nalgebra::{SMatrix, SVector};

use super::traits::{MeasurementPrediction, NonlinearFilter, Predictor, Updater};
use crate::linalg::{ensure_covariance, ensure_finite, symmetrize};
use crate::measurement::MeasurementModel;
use crate::motion::{ConstantTurn, ConstantVelocity, LinearTransition, TransitionModel};
use crate::state::{Gaussian, Posterior, moment_match};
use crate::{EstimationError, Result};

/// Smallest mode probability kept after an update (guards against underflow, so that a mode
/// never becomes unreachable).
pub const PROB_FLOOR: f64 = 1e-12;

/// A motion model of one IMM mode: nearly-constant velocity or a constant turn at a known rate
/// (the `CV` / `CT` models of FORMAT.md `motion.models`). Layouts and noise as in
/// [`crate::motion`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ModeModel {
    /// [`ConstantVelocity`] with acceleration spectral density `q` (m²/s³).
    Cv {
        /// Acceleration spectral density, m²/s³.
        q: f64,
    },
    /// [`ConstantTurn`] at rate `omega` (rad/s, > 0 counter-clockwise) with density `q`.
    Ct {
        /// Turn rate, rad/s.
        omega: f64,
        /// Acceleration spectral density, m²/s³.
        q: f64,
    },
}

impl<const N: usize> TransitionModel<N> for ModeModel {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        self.matrix(dt) * x
    }
    fn jacobian(&self, _x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        self.matrix(dt)
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        match *self {
            Self::Cv { q } => ConstantVelocity::<N>::new(q).covar(dt),
            Self::Ct { omega, q } => ConstantTurn::<N>::new(omega, q).covar(dt),
        }
    }
    /// The CV mode uses the block form of [`ConstantVelocity`]; CT the dense `F P Fᵀ`.
    fn propagate_cov(
        &self,
        x: &SVector<f64, N>,
        p: &SMatrix<f64, N, N>,
        dt: f64,
    ) -> SMatrix<f64, N, N> {
        match *self {
            Self::Cv { q } => ConstantVelocity::<N>::new(q).propagate_cov(x, p, dt),
            Self::Ct { omega, q } => ConstantTurn::<N>::new(omega, q).propagate_cov(x, p, dt),
        }
    }
}

impl<const N: usize> LinearTransition<N> for ModeModel {
    fn matrix(&self, dt: f64) -> SMatrix<f64, N, N> {
        match *self {
            Self::Cv { q } => ConstantVelocity::<N>::new(q).matrix(dt),
            Self::Ct { omega, q } => ConstantTurn::<N>::new(omega, q).matrix(dt),
        }
    }
}

/// IMM state: one Gaussian per mode and the mode probabilities (summing to 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImmState<const N: usize, const R: usize> {
    /// Mode-conditioned estimates.
    pub modes: [Gaussian<N>; R],
    /// Mode probabilities μ_j.
    pub probs: [f64; R],
}

impl<const N: usize, const R: usize> ImmState<N, R> {
    /// Every mode starts from `prior`, with probabilities `probs` (non-negative, normalised here).
    pub fn new(prior: Gaussian<N>, probs: [f64; R]) -> Result<Self> {
        Ok(Self {
            modes: [prior; R],
            probs: normalized(probs)?,
        })
    }

    /// The moment-matched single Gaussian (\[BLK01\] §11.6.6 step 5, \[CIMM\] §3.2 step 4).
    pub fn combined(&self) -> Gaussian<N> {
        moment_match(&self.modes, &self.probs)
    }
}

/// Normalises non-negative weights to sum to 1.
fn normalized<const R: usize>(p: [f64; R]) -> Result<[f64; R]> {
    let sum: f64 = p.iter().sum();
    if p.iter().any(|v| !(v.is_finite() && *v >= 0.0)) || !(sum > 0.0 && sum.is_finite()) {
        return Err(EstimationError::InvalidParameter(format!(
            "mode probabilities must be finite, ≥ 0 and not all 0, got {p:?}"
        )));
    }
    Ok(p.map(|v| v / sum))
}

/// The IMM estimator: a mode filter `F` (any Gaussian [`Predictor`] / [`Updater`]), the motion
/// model of each of the R modes and the Markov transition matrix (row i = from mode i).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Imm<F, T, const R: usize> {
    filter: F,
    models: [T; R],
    transition: [[f64; R]; R],
}

impl<F, T, const R: usize> Imm<F, T, R> {
    /// IMM with mode filter `filter`, mode models `models` and transition matrix `transition`
    /// (rows non-negative, summing to 1 within 1e-6; they are renormalised).
    pub fn new(filter: F, models: [T; R], transition: [[f64; R]; R]) -> Result<Self> {
        const { assert!(R >= 1, "an IMM needs at least one mode") };
        let mut rows = transition;
        for row in &mut rows {
            let sum: f64 = row.iter().sum();
            if (sum - 1.0).abs() > 1e-6 {
                return Err(EstimationError::InvalidParameter(format!(
                    "transition matrix rows must sum to 1, got {row:?}"
                )));
            }
            *row = normalized(*row)?;
        }
        Ok(Self {
            filter,
            models,
            transition: rows,
        })
    }

    /// The mode models.
    pub fn models(&self) -> &[T; R] {
        &self.models
    }

    /// Mixing and mode-matched prediction over `dt` (\[BLK01\] §11.6.6 steps 1–3, \[CIMM\] §3.2
    /// step 1 and eqs. (18)–(19)). The returned probabilities are the predicted mode probabilities
    /// `c̄_j = Σ_i p_ij μ_i`. `state` is left untouched on error.
    pub fn predict<const N: usize>(&self, state: &ImmState<N, R>, dt: f64) -> Result<ImmState<N, R>>
    where
        F: Predictor<T, N, State = Gaussian<N>>,
    {
        let mut out = *state;
        for j in 0..R {
            // c̄_j and μ_{i|j}
            let mut w = [0.0; R];
            for (i, wi) in w.iter_mut().enumerate() {
                *wi = self.transition[i][j] * state.probs[i];
            }
            let cbar: f64 = w.iter().sum();
            let mixed = if cbar > 0.0 {
                moment_match(&state.modes, &w.map(|v| v / cbar))
            } else {
                // Mode j cannot be reached from any mode: keep its own estimate.
                state.modes[j]
            };
            out.modes[j] = self.filter.predict(&self.models[j], &mixed, dt)?;
            out.probs[j] = cbar;
        }
        out.probs = normalized(out.probs)?;
        combinable(out)
    }

    /// Mode-matched update with one measurement and mode-probability update (\[BLK01\] §11.6.6
    /// steps 3–4, \[CIMM\] §3.2 steps 2–3): `μ_j ∝ μ_j⁻ Λ_j`, `Λ_j` from each mode's innovation
    /// ([`crate::state::Posterior::log_likelihood`]), normalised with log-sum-exp and floored at
    /// [`PROB_FLOOR`]. Applying it once per measurement of a time step is the sequential form of
    /// the stacked update. `predicted` is left untouched on error.
    pub fn update<H, const N: usize, const M: usize>(
        &self,
        model: &H,
        predicted: &ImmState<N, R>,
        z: &SVector<f64, M>,
    ) -> Result<ImmState<N, R>>
    where
        F: Updater<H, N, M, State = Gaussian<N>>,
    {
        update_modes(predicted, |g| self.filter.update(model, g, z))
    }

    /// [`Imm::update`] for a mode filter that takes any measurement model (the tracker's case,
    /// where each scan brings its own sensor).
    pub fn update_with<H, const N: usize, const M: usize>(
        &self,
        model: &H,
        predicted: &ImmState<N, R>,
        z: &SVector<f64, M>,
    ) -> Result<ImmState<N, R>>
    where
        F: NonlinearFilter<N>,
        H: MeasurementModel<N, M>,
    {
        update_modes(predicted, |g| self.filter.update_with(model, g, z))
    }

    /// The update with a mixture of association hypotheses, per mode (IMM-PDA, \[IMMPDA\];
    /// the per-mode form of IMM-JIPDA): hypothesis 0 ("no detection of this track") has weight
    /// `β₀ = miss`, detection `zⱼ` weight `βⱼ` (the weights sum to 1). Each mode m is updated
    /// with each detection in Joseph form, with likelihood `N_mⱼ`, and
    ///
    /// ```text
    /// w(m, 0) = β₀ μ_m,   w(m, j) = βⱼ μ_m N_mⱼ / Σ_t μ_t N_tⱼ      (P(mode m | zⱼ) in the second)
    /// μ'_m = Σ_e w(m, e),   x'_m, P'_m = the moments of Σ_e w(m, e)/μ'_m N(x_m,e, P_m,e)
    /// ```
    ///
    /// with `x_m,0 = x_m` (the prediction): the mixture over modes and hypotheses reduced to one
    /// Gaussian per mode by moment matching, and the mode probabilities floored at
    /// [`PROB_FLOOR`]. One hypothesis of weight 1 is [`Imm::update_with`].
    pub fn update_mixture_with<H, const N: usize, const M: usize>(
        &self,
        model: &H,
        predicted: &ImmState<N, R>,
        detections: &[(SVector<f64, M>, f64)],
        miss: f64,
    ) -> Result<ImmState<N, R>>
    where
        F: NonlinearFilter<N>,
        H: MeasurementModel<N, M>,
    {
        let mut comps: Vec<[Gaussian<N>; R]> = Vec::with_capacity(detections.len());
        let mut given: Vec<[f64; R]> = Vec::with_capacity(detections.len());
        for (z, _) in detections {
            let mut g = predicted.modes;
            let mut log_w = [0.0; R];
            for m in 0..R {
                let post = self.filter.update_with(model, &predicted.modes[m], z)?;
                g[m] = post.state;
                log_w[m] = predicted.probs[m].ln() + post.log_likelihood()?;
            }
            comps.push(g);
            given.push(log_normalize(log_w)?);
        }
        let mut out = *predicted;
        let mut probs = [0.0; R];
        let mut gs = Vec::with_capacity(detections.len() + 1);
        let mut ws = Vec::with_capacity(detections.len() + 1);
        for m in 0..R {
            gs.clear();
            ws.clear();
            gs.push(predicted.modes[m]);
            ws.push(miss * predicted.probs[m]);
            for ((_, beta), (g, p)) in detections.iter().zip(comps.iter().zip(&given)) {
                gs.push(g[m]);
                ws.push(beta * p[m]);
            }
            let total: f64 = ws.iter().sum();
            if total > 0.0 && total.is_finite() {
                ws.iter_mut().for_each(|w| *w /= total);
                out.modes[m] = moment_match(&gs, &ws);
            }
            probs[m] = total.max(0.0);
        }
        out.probs = normalized(probs.map(|p| p.max(PROB_FLOOR)))?;
        for g in &out.modes {
            ensure_finite(&g.mean, "IMM mode mean")?;
        }
        combinable(out)
    }

    /// Predicted measurement of the mixture: each mode's `ẑ_j`, `S_j` moment-matched with the
    /// mode probabilities, `ẑ = Σ μ_j ẑ_j`, `S = Σ μ_j [S_j + (ẑ_j ⊖ ẑ)(ẑ_j ⊖ ẑ)ᵀ]` (\[BLK01\]
    /// §11.6.6 step 5 applied in measurement space), residuals through the model's `⊖`.
    pub fn predict_measurement_with<H, const N: usize, const M: usize>(
        &self,
        model: &H,
        predicted: &ImmState<N, R>,
    ) -> Result<MeasurementPrediction<M>>
    where
        F: NonlinearFilter<N>,
        H: MeasurementModel<N, M>,
    {
        let mut preds = [MeasurementPrediction {
            zhat: SVector::zeros(),
            cov: SMatrix::zeros(),
        }; R];
        for (p, g) in preds.iter_mut().zip(&predicted.modes) {
            *p = self.filter.predict_measurement_with(model, g)?;
        }
        // Mean as an offset from the most probable mode's ẑ, so that wrapped angles average right.
        let best = (0..R)
            .max_by(|&a, &b| predicted.probs[a].total_cmp(&predicted.probs[b]))
            .unwrap_or(0);
        let base = preds[best].zhat;
        let mut offset = SVector::<f64, M>::zeros();
        for (p, w) in preds.iter().zip(&predicted.probs) {
            offset.axpy(*w, &model.residual(&p.zhat, &base), 1.0);
        }
        let zhat = base + offset;
        let mut cov = SMatrix::<f64, M, M>::zeros();
        for (p, w) in preds.iter().zip(&predicted.probs) {
            let d = model.residual(&p.zhat, &zhat);
            cov += p.cov * *w;
            cov.ger(*w, &d, &d, 1.0);
        }
        let cov = symmetrize(&cov);
        ensure_covariance(&cov, "IMM innovation covariance")?;
        Ok(MeasurementPrediction { zhat, cov })
    }
}

/// The mode-matched update and mode-probability update of [`Imm::update`], given each mode's
/// update `up`.
fn update_modes<const N: usize, const M: usize, const R: usize>(
    predicted: &ImmState<N, R>,
    up: impl Fn(&Gaussian<N>) -> Result<Posterior<Gaussian<N>, M>>,
) -> Result<ImmState<N, R>> {
    let mut out = *predicted;
    let mut log_w = [0.0; R];
    for (j, lw) in log_w.iter_mut().enumerate() {
        let post = up(&predicted.modes[j])?;
        *lw = predicted.probs[j].ln() + post.log_likelihood()?;
        out.modes[j] = post.state;
    }
    out.probs = log_normalize(log_w)?;
    for g in &out.modes {
        ensure_finite(&g.mean, "IMM mode mean")?;
    }
    combinable(out)
}

/// `s` when its moment-matched combination is finite. Modes far apart (means beyond ~1e154 m)
/// overflow the spread term `(x_j − x̄)(x_j − x̄)ᵀ` although each mode is finite; such a state is
/// refused rather than handed on (found by the hostile-number tests, `core/tests/it/hostile.rs`).
fn combinable<const N: usize, const R: usize>(s: ImmState<N, R>) -> Result<ImmState<N, R>> {
    let c = s.combined();
    ensure_finite(&c.mean, "IMM combined mean")?;
    ensure_covariance(&c.cov, "IMM combined covariance")?;
    Ok(s)
}

/// `exp(l_j) / Σ_t exp(l_t)` by log-sum-exp, then floored at [`PROB_FLOOR`] and renormalised.
pub(crate) fn log_normalize<const R: usize>(log_w: [f64; R]) -> Result<[f64; R]> {
    let max = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !max.is_finite() {
        return Err(EstimationError::NonFinite("IMM mode likelihoods"));
    }
    let p = log_w.map(|l| (l - max).exp());
    let sum: f64 = p.iter().sum();
    normalized(p.map(|v| (v / sum).max(PROB_FLOOR)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::kalman::{Extended, Kalman};
    use crate::measurement::{Geometry, Position};
    use approx::assert_relative_eq;
    use nalgebra::{Matrix4, Vector2, Vector4};

    fn prior() -> Gaussian<4> {
        Gaussian::new(
            Vector4::new(200.0, 300.0, 6.0, 8.0),
            Matrix4::from_diagonal(&Vector4::new(400.0, 400.0, 4.0, 4.0)),
        )
        .unwrap()
    }

    #[test]
    fn one_mode_imm_equals_its_inner_filter() {
        let cv = ModeModel::Cv { q: 0.0025 };
        let imm = Imm::new(Kalman, [cv], [[1.0]]).unwrap();
        let cam = Position::<2>::new(Geometry::planar(0.0), [10.0, 10.0]);
        let mut s = ImmState::new(prior(), [1.0]).unwrap();
        let mut g = prior();
        for k in 1..50 {
            let z = Vector2::new(200.0 + 6.0 * f64::from(k), 300.0 + 8.0 * f64::from(k) + 3.0);
            s = imm.predict(&s, 1.0).unwrap();
            g = Kalman.predict(&cv, &g, 1.0).unwrap();
            s = imm.update(&cam, &s, &z).unwrap();
            g = Kalman.update(&cam, &g, &z).unwrap().state;
            assert_eq!(s.probs, [1.0]);
            assert_eq!(s.modes[0], g);
            assert_eq!(s.combined(), g);
        }
    }

    #[test]
    fn probabilities_sum_to_one_and_follow_the_turn() {
        let q = 0.0025;
        let models = [
            ModeModel::Cv { q },
            ModeModel::Ct { omega: -0.05, q },
            ModeModel::Ct { omega: 0.05, q },
        ];
        let tpm = [[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]];
        let imm = Imm::new(Extended, models, tpm).unwrap();
        let cam = Position::<2>::new(Geometry::planar(0.0), [1.0, 1.0]);
        let mut s = ImmState::new(prior(), [0.98, 0.01, 0.01]).unwrap();
        // Truth turns left at 0.05 rad/s from the prior's mean.
        let left = models[2];
        let mut x = Vector4::new(200.0, 300.0, 6.0, 8.0);
        for _ in 0..40 {
            x = TransitionModel::<4>::function(&left, &x, 1.0);
            s = imm.predict(&s, 1.0).unwrap();
            let sum: f64 = s.probs.iter().sum();
            assert_relative_eq!(sum, 1.0, epsilon = 1e-12);
            s = imm.update(&cam, &s, &Vector2::new(x[0], x[1])).unwrap();
            let sum: f64 = s.probs.iter().sum();
            assert_relative_eq!(sum, 1.0, epsilon = 1e-12);
            assert!(s.probs.iter().all(|p| *p >= PROB_FLOOR * 0.5));
        }
        assert!(s.probs[2] > 0.9, "{:?}", s.probs);
        assert!((s.combined().mean - x).norm() < 1.0);
    }

    #[test]
    fn underflowing_likelihoods_are_normalised() {
        let p = log_normalize([-1e4, -1e4 - 2.0_f64.ln(), -2e5]).unwrap();
        assert_relative_eq!(p[0], 2.0 / 3.0, epsilon = 1e-9);
        assert_relative_eq!(p[1], 1.0 / 3.0, epsilon = 1e-9);
        assert!(p[2] > 0.0);
        assert!(log_normalize([f64::NEG_INFINITY; 2]).is_err());
        assert!(
            Imm::new(
                Kalman,
                [ModeModel::Cv { q: 1.0 }; 2],
                [[0.5, 0.6], [0.5, 0.5]]
            )
            .is_err()
        );
    }
}
