//! Three bias hypotheses in an IMM: **no bias** (every term pinned at its prior mean, nothing
//! learnt), the registration filter as configured (**steady**), and the same filter with every
//! random-walk term drifting `factor` times faster (**drifting**).
//!
//! **Why the "no bias" mode.** A filter that learns ten bias terms pays for them when there is
//! nothing to learn: over 600 s its target error is 15 % above a filter told there is no bias
//! (BENCHMARKS.md), and it is near the Cramér–Rao bound of that model, so no better estimator of
//! *the same model* removes the cost. Model selection does: the unbiased hypothesis is a model
//! with no free bias parameters, and the innovations weigh it against the biased ones with the
//! Bayes factor's Occam penalty built in (each mode's likelihood `N(ν; 0, S)` has the bias
//! uncertainty inside `S`; \[BLK01\] §11.7 on model selection, and the "detect, then estimate"
//! view of Willsky & Jones's GLR, 1976). Without a bias the unbiased mode soon carries all the
//! weight and the estimate is the told-bias filter's; with one, a few scans of shared targets
//! reject it (its innovations carry the whole offset).
//!
//! **Why two drift modes.** No single drift suits every bias: a drift large enough to follow a
//! Gauss–Markov offset (σ tens of metres, τ of minutes) lets a steady bias wander while the radar
//! alone carries the target (the innovations of one sensor cannot tell the bias's drift from the
//! target's manoeuvres), and a small one lags a drifting bias. While the sensors share the
//! target, the innovations tell which drift the data follow; the IMM weighs the two models by
//! their likelihood and carries that weight through the outages.
//!
//! The recursion is \[BLK01\] §11.6.6 (as [`crate::filter::Imm`]), over the registration state:
//! mixing with `μ_{i|j} = p_ij μ_i / c̄_j`, `c̄_j = Σ_i p_ij μ_i`, of the mean and of both
//! covariances (`P` and the full filter's `P_f`, with the same spread term); each mode predicted
//! and updated by its [`Registration`] (its own gain projection); `μ_j ∝ c̄_j Λ_j` from each
//! mode's innovation likelihood; the output moment-matched. The modes' state spaces differ in
//! meaning, so a state is converted when it crosses into the unbiased mode: its bias block is
//! pinned (mean μ, no correlation), the target's part kept; in the output the unbiased mode's
//! biases are exactly μ (variance 0). The switches over Δt:
//!
//! ```text
//!            to:  none        steady                 drifting
//! from none       1           0                      0
//!      steady     p_a         (1 − p_a)(1 − p_d)     (1 − p_a) p_d
//!      drifting   p_a         (1 − p_a) p_d          (1 − p_a)(1 − p_d)
//! p_a = 1 − e^{−Δt/T_a},  p_d = ½ (1 − e^{−2Δt/T})     (T_a, T: mean sojourns)
//! ```
//!
//! Nothing flows out of the unbiased mode: once the data reject it its target estimate, fitted
//! to biased detections, is far off, and even a weight of 10⁻⁴ of it mixed into the biased
//! modes spread their covariance by metres (measured: the constant-offset cost rose from 1.16
//! to 1.21 with a symmetric switch). The biased modes keep their own estimates of the biases
//! all along, so a bias that appears later is still found: the likelihood lifts them from the
//! probability floor (10⁻¹²) in a few scans. The flow into the unbiased mode re-seeds its target
//! estimate from theirs, so that a bias that vanishes is found too.
//!
//! The reported observability (the full covariance of the output) is that of the biased modes
//! alone, renormalised: what the data determine about a bias *if* there is one.
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
//!   and Navigation*, Wiley 2001, §11.6.6, §11.7.
//! * A. S. Willsky, H. L. Jones, "A generalized likelihood ratio approach to the detection and
//!   estimation of jumps in linear systems", *IEEE Trans. AC* 21(1), 1976.

use nalgebra::SMatrix;

use super::filter::{Observation, Registration, RegistrationState, Seen};
use crate::filter::{PROB_FLOOR, log_normalize};
use crate::linalg::symmetrize;
use crate::state::Gaussian;
use crate::state::moment_match;
use crate::{EstimationError, Result};

/// Number of modes: `[none, steady, drifting]`.
const MODES: usize = 3;

/// The modes' tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DriftModes {
    /// How much faster the random-walk terms drift in the drifting mode (≥ 1).
    pub factor: f64,
    /// Mean time in a drift mode before switching to the other (s).
    pub sojourn: f64,
    /// Initial probability of the drifting mode (of the biased hypothesis' share).
    pub initial: f64,
    /// Initial probability of the "no bias" mode.
    pub unbiased: f64,
    /// Mean time before a bias disappears (s): re-seeds the "no bias" mode from the biased ones.
    pub presence_sojourn: f64,
}

impl Default for DriftModes {
    /// 20 times the drift, 300 s sojourn, drifting with probability 0.1 of the biased share at
    /// the start; no bias with probability 0.5 at the start, a bias going after 3 600 s on
    /// average.
    fn default() -> Self {
        Self {
            factor: 20.0,
            sojourn: 300.0,
            initial: 0.1,
            unbiased: 0.5,
            presence_sojourn: 3600.0,
        }
    }
}

/// The registration filter in its three modes.
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationImm<const K: usize, const N: usize> {
    modes: [Registration<K, N>; MODES],
    drift: DriftModes,
}

/// The IMM's state: one registration state per mode and the mode probabilities
/// (`[none, steady, drifting]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegistrationImmState<const N: usize> {
    /// Mode-conditioned states (the unbiased mode's bias block pinned).
    pub modes: [RegistrationState<N>; MODES],
    /// Mode probabilities.
    pub probs: [f64; MODES],
}

impl<const N: usize> RegistrationImmState<N> {
    /// Probability that there is no bias.
    pub fn unbiased_prob(&self) -> f64 {
        self.probs[0]
    }

    /// Probability of the drifting mode.
    pub fn drifting_prob(&self) -> f64 {
        self.probs[2]
    }
}

impl<const K: usize, const N: usize> RegistrationImm<K, N> {
    /// The three modes of `steady` (see the module docs).
    pub fn new(steady: Registration<K, N>, drift: DriftModes) -> Result<Self> {
        let ok = drift.factor.is_finite()
            && drift.factor >= 1.0
            && drift.sojourn.is_finite()
            && drift.sojourn > 0.0
            && (0.0..=1.0).contains(&drift.initial)
            && (0.0..=1.0).contains(&drift.unbiased)
            && drift.presence_sojourn.is_finite()
            && drift.presence_sojourn > 0.0;
        if !ok {
            return Err(EstimationError::InvalidParameter(format!(
                "bias modes need factor ≥ 1, sojourns > 0 and initial probabilities in [0, 1], \
                 got {drift:?}"
            )));
        }
        let drifting = steady.with_drift_factor(drift.factor);
        Ok(Self {
            modes: [steady.pinned(), steady, drifting],
            drift,
        })
    }

    /// The steady mode's filter (layout, priors and tuning are the same in the biased modes).
    pub fn filter(&self) -> &Registration<K, N> {
        &self.modes[1]
    }

    /// Every mode starts from the filter's initial state for `kinematic`.
    pub fn initial(&self, kinematic: &Gaussian<K>) -> Result<RegistrationImmState<N>> {
        let s = self.modes[1].initial(kinematic)?;
        let d = self.drift;
        Ok(RegistrationImmState {
            modes: [self.modes[0].reset_biases(&s), s, s],
            probs: [
                d.unbiased,
                (1.0 - d.unbiased) * (1.0 - d.initial),
                (1.0 - d.unbiased) * d.initial,
            ],
        })
    }

    /// `state`, a state of mode `from`, in mode `to`'s terms (see the module docs; nothing
    /// goes from the unbiased mode to a biased one).
    fn convert(
        &self,
        state: &RegistrationState<N>,
        from: usize,
        to: usize,
    ) -> RegistrationState<N> {
        if from != 0 && to == 0 {
            self.modes[0].reset_biases(state)
        } else {
            *state
        }
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
        let pa = 1.0 - (-dt / self.drift.presence_sojourn).exp();
        let pd = 0.5 * (1.0 - (-2.0 * dt / self.drift.sojourn).exp());
        let tpm = [
            [1.0, 0.0, 0.0],
            [pa, (1.0 - pa) * (1.0 - pd), (1.0 - pa) * pd],
            [pa, (1.0 - pa) * pd, (1.0 - pa) * (1.0 - pd)],
        ];
        let mut out = *state;
        for (j, filter) in self.modes.iter().enumerate() {
            let w: [f64; MODES] = std::array::from_fn(|i| tpm[i][j] * state.probs[i]);
            let cbar: f64 = w.iter().sum();
            let mixed = if cbar > 0.0 {
                let from = std::array::from_fn(|i| self.convert(&state.modes[i], i, j));
                mix(&from, &w.map(|v| v / cbar))
            } else {
                // Mode j cannot be reached (a zero probability, a switch too rare to register):
                // keep its own state.
                state.modes[j]
            };
            out.modes[j] = filter.predict(&mixed, dt)?;
            out.probs[j] = cbar.max(PROB_FLOOR);
        }
        let sum: f64 = out.probs.iter().sum();
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
        let mut log_w = [0.0; MODES];
        for (j, (lw, mode)) in log_w.iter_mut().zip(out.modes.iter_mut()).enumerate() {
            let up = self.modes[j].update(&state.modes[j], obs, seen)?;
            *lw = state.probs[j].ln() + up.log_likelihood;
            *mode = up.state;
        }
        out.probs = log_normalize(log_w)?;
        Ok(out)
    }

    /// The moment-matched state: the estimate over the three modes (the unbiased mode's biases
    /// exactly at their means), the full covariance over the biased modes (observability if
    /// there is a bias).
    pub fn combined(&self, state: &RegistrationImmState<N>) -> RegistrationState<N> {
        let unbiased = self.modes[1].reset_biases(&state.modes[0]);
        let all = mix(&[unbiased, state.modes[1], state.modes[2]], &state.probs);
        let biased = state.probs[1] + state.probs[2];
        let w = [0.0, state.probs[1] / biased, state.probs[2] / biased];
        RegistrationState {
            full_cov: mix(&state.modes, &w).full_cov,
            ..all
        }
    }
}

/// `Σ w_i` of registration states, moment-matched: the estimates as Gaussians, the full
/// covariances with the same spread of the means.
fn mix<const N: usize>(
    modes: &[RegistrationState<N>; MODES],
    w: &[f64; MODES],
) -> RegistrationState<N> {
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
