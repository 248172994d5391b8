//! Two bias-dynamics modes in an IMM: the registration filter as configured ("steady") and the
//! same filter with every random-walk term drifting `factor` times faster ("drifting").
//!
//! **Why.** No single drift suits every bias: a drift large enough to follow a Gauss–Markov
//! offset (σ tens of metres, τ of minutes) lets a steady bias wander while the radar alone
//! carries the target (the innovations of one sensor cannot tell the bias's drift from the
//! target's manoeuvres), and a small one lags a drifting bias. While the sensors share the
//! target, the innovations tell which drift the data follow; the IMM weighs the two models by
//! their likelihood and carries that weight through the outages.
//!
//! The recursion is \[BLK01\] §11.6.6 (as [`crate::filter::Imm`]), over the registration state:
//! mixing with `μ_{i|j} = p_ij μ_i / c̄_j`, `c̄_j = Σ_i p_ij μ_i`, of the mean and of both
//! covariances (`P` and the full filter's `P_f`, with the same spread term); each mode predicted
//! and updated by its [`Registration`] (its own gain projection); `μ_j ∝ c̄_j Λ_j` from each
//! mode's innovation likelihood; the output moment-matched. The mode switches as a two-state
//! continuous-time Markov chain with mean sojourn `T`: `p_ij = ½ (1 − e^{−2Δt/T})` for `i ≠ j`.
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
//!   and Navigation*, Wiley 2001, §11.6.6.

use nalgebra::SMatrix;

use super::filter::{Observation, Registration, RegistrationState, Seen};
use crate::filter::{PROB_FLOOR, log_normalize};
use crate::linalg::symmetrize;
use crate::state::Gaussian;
use crate::state::moment_match;
use crate::{EstimationError, Result};

/// The modes' tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftModes {
    /// How much faster the random-walk terms drift in the drifting mode (≥ 1; 1: one mode).
    pub factor: f64,
    /// Mean time in a mode before switching (s).
    pub sojourn: f64,
    /// Initial probability of the drifting mode.
    pub initial: f64,
}

impl Default for DriftModes {
    /// 20 times the drift, 300 s sojourn, drifting with probability 0.1 at the start.
    fn default() -> Self {
        Self {
            factor: 20.0,
            sojourn: 300.0,
            initial: 0.1,
        }
    }
}

/// The registration filter in its two drift modes.
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationImm<const K: usize, const N: usize> {
    modes: [Registration<K, N>; 2],
    drift: DriftModes,
}

/// The IMM's state: one registration state per mode and the mode probabilities
/// (`[steady, drifting]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegistrationImmState<const N: usize> {
    /// Mode-conditioned states.
    pub modes: [RegistrationState<N>; 2],
    /// Mode probabilities.
    pub probs: [f64; 2],
}

impl<const K: usize, const N: usize> RegistrationImm<K, N> {
    /// The two modes of `steady` (see the module docs).
    pub fn new(steady: Registration<K, N>, drift: DriftModes) -> Result<Self> {
        let ok = drift.factor.is_finite()
            && drift.factor >= 1.0
            && drift.sojourn.is_finite()
            && drift.sojourn > 0.0
            && (0.0..=1.0).contains(&drift.initial);
        if !ok {
            return Err(EstimationError::InvalidParameter(format!(
                "drift modes need factor ≥ 1, sojourn > 0 and an initial probability in [0, 1], \
                 got {drift:?}"
            )));
        }
        let drifting = steady.with_drift_factor(drift.factor);
        Ok(Self {
            modes: [steady, drifting],
            drift,
        })
    }

    /// The steady mode's filter (layout, priors and tuning are the same in both modes).
    pub fn filter(&self) -> &Registration<K, N> {
        &self.modes[0]
    }

    /// Both modes start from the filter's initial state for `kinematic`.
    pub fn initial(&self, kinematic: &Gaussian<K>) -> Result<RegistrationImmState<N>> {
        let s = self.modes[0].initial(kinematic)?;
        Ok(RegistrationImmState {
            modes: [s, s],
            probs: [1.0 - self.drift.initial, self.drift.initial],
        })
    }

    /// Mixing, then each mode's prediction over `dt`.
    pub fn predict(
        &self,
        state: &RegistrationImmState<N>,
        dt: f64,
    ) -> Result<RegistrationImmState<N>> {
        if dt == 0.0 {
            return Ok(*state);
        }
        let p = 0.5 * (1.0 - (-2.0 * dt / self.drift.sojourn).exp());
        let tpm = [[1.0 - p, p], [p, 1.0 - p]];
        let mut out = *state;
        for (j, (mode, filter)) in out.modes.iter_mut().zip(&self.modes).enumerate() {
            let w = [tpm[0][j] * state.probs[0], tpm[1][j] * state.probs[1]];
            let cbar = w[0] + w[1];
            let mixed = if cbar > 0.0 {
                mix(&state.modes, &[w[0] / cbar, w[1] / cbar])
            } else {
                // Mode j cannot be reached (a zero probability, a switch too rare to register):
                // keep its own state.
                state.modes[j]
            };
            *mode = filter.predict(&mixed, dt)?;
            out.probs[j] = cbar.max(PROB_FLOOR);
        }
        let sum = out.probs[0] + out.probs[1];
        out.probs = out.probs.map(|v| v / sum);
        Ok(out)
    }

    /// Each mode's update with one detection, then the mode probabilities.
    pub fn update(
        &self,
        state: &RegistrationImmState<N>,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<RegistrationImmState<N>> {
        let mut out = *state;
        let mut log_w = [0.0; 2];
        for (j, (lw, mode)) in log_w.iter_mut().zip(out.modes.iter_mut()).enumerate() {
            let up = self.modes[j].update(&state.modes[j], obs, seen)?;
            *lw = state.probs[j].ln() + up.log_likelihood;
            *mode = up.state;
        }
        out.probs = log_normalize(log_w)?;
        Ok(out)
    }

    /// The moment-matched state (estimate and full covariance).
    pub fn combined(&self, state: &RegistrationImmState<N>) -> RegistrationState<N> {
        mix(&state.modes, &state.probs)
    }
}

/// `Σ w_i` of registration states, moment-matched: the estimates as Gaussians, the full
/// covariances with the same spread of the means.
fn mix<const N: usize>(modes: &[RegistrationState<N>; 2], w: &[f64; 2]) -> RegistrationState<N> {
    let estimate = moment_match(&modes.map(|m| m.estimate), w);
    let mut full_cov = SMatrix::<f64, N, N>::zeros();
    for (m, wi) in modes.iter().zip(w) {
        let d = m.estimate.mean - estimate.mean;
        full_cov += m.full_cov * *wi;
        full_cov.ger(*wi, &d, &d, 1.0);
    }
    RegistrationState {
        estimate,
        full_cov: symmetrize(&full_cov),
        projection: None,
    }
}
