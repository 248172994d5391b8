//! Three bias hypotheses in an IMM: **no bias** (every term pinned at its prior mean, nothing
//! learnt), the registration filter as configured (**steady**), and the same filter with every
//! random-walk term drifting `factor` times faster (**drifting**); in the output, each biased
//! mode is split over the **sets of biased sensors**.
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
//! **Why the sets of biased sensors.** The same holds sensor by sensor: when the cameras are
//! mounted off and the radar is not, the biased modes learn the radar's terms too and pay for
//! them (17 % over the filter told the biases, BENCHMARKS.md). Each non-empty set `S` of the
//! sensors that carry terms (7 for a radar and two cameras; only the set of all above
//! [`MAX_SET_SENSORS`] sensors) is a hypothesis nested in the biased mode: the terms of the
//! sensors outside `S` are exactly at their prior means `μ_c`. Its Bayes factor against the
//! free terms is the Savage–Dickey density ratio, the posterior density of the pinned block at
//! `μ_c` over its prior density there (Dickey 1971; Verdinelli & Wasserman 1995), and its
//! estimate the biased mode's conditioned on the block at `μ_c`
//! ([`Registration::given_prior`]):
//!
//! ```text
//! B_S = N(μ_c; b̂_c, P_cc) / N(μ_c; μ_c, Σ_c),     P(S | mode) = B_S / Σ_S' B_S'   (equal priors)
//! x̂_S = x̂ + P_·c P_cc⁻¹ (μ_c − b̂_c),   P_S = P − P_·c P_cc⁻¹ P_c·
//! ```
//!
//! For a linear-Gaussian model with constant biases, every term estimated, both are exact: the
//! conditioned estimate is the filter told those sensors are unbiased, without running it
//! (here they are first-order, and a held direction is conditioned through the consider
//! filter's covariance). Computing them from the biased mode's posterior, rather than running a
//! filter per set and weighing the sets by their own innovations, is what keeps the early scans
//! safe: while a block is not determined its posterior is its prior, the ratio near 1 and the
//! conditioning a small move; a filter per set commits to its set from the first scan, and on
//! the mounted cameras the sets that trusted a mounted camera took the weight for the first
//! 40–90 s (measured: 1.70 × the unbiased run, against 1.08 × with the ratio; after 150 s the
//! same, 1.006 against 1.005). The set weights live in the output only; the modes' recursion is
//! unchanged.
//!
//! **Why a time offset apart.** A camera's latency `δ` on a UAV orbiting the target shifts its
//! azimuth by about `δ s / R`, as a mounting azimuth would, while the orbit holds its speed: a
//! camera with neither reads a little of both (`~15 ms` and `0.08°` on two of eight seeds, in
//! step on both cameras, BENCHMARKS.md). So within a set each biased sensor whose terms are all
//! constant, a time offset among them, is biased one of three ways, each with a third of the
//! set's prior: every term free, its time offset alone pinned at the prior mean, or its time
//! offset alone free (the other terms pinned); the weights and estimates as above (the pinned
//! block is the set's unbiased sensors' terms and the pinned ways'). Measured on the mounted
//! cameras: every azimuth within 0.045° (0.083° before), the latency case's 200 ms within
//! 1.4 ms (8.3). Not for a sensor with a drifting term: pinning its time offset beside a
//! random walk moved the tracks the wrong way when the deployment's drift model was not the
//! data's (Gauss–Markov offsets, live registrar: 1.078 × the filter told the model, 1.022
//! without). Above [`MAX_SETS`] sets, the sensors alone.
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
//! alone, renormalised: what the data determine about a bias *if* there is one. So is the
//! reported covariance of the terms of a sensor whose bias the data do not determine: the "no
//! bias" mode holds its terms exactly at their prior means, and when the data cannot tell a
//! bias from none (one radar alone) it keeps much of the weight, so the mixture's variance
//! shrinks with it while the true offsets may be tens of metres (measured: a bias NEES inside
//! its 95 % band in 0 % of scans); the biased modes' is what a bias, if there is one, could be.
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
//!   and Navigation*, Wiley 2001, §11.6.6, §11.7.
//! * J. M. Dickey, "The weighted likelihood ratio, linear hypotheses on normal location
//!   parameters", *Ann. Math. Statist.* 42(1), 1971.
//! * I. Verdinelli, L. Wasserman, "Computing Bayes factors using a generalization of the
//!   Savage–Dickey density ratio", *JASA* 90(430), 1995.
//! * A. S. Willsky, H. L. Jones, "A generalized likelihood ratio approach to the detection and
//!   estimation of jumps in linear systems", *IEEE Trans. AC* 21(1), 1976.

use nalgebra::SMatrix;

use super::filter::{Observation, Registration, RegistrationState, Seen};
use super::model::{Dynamics, Term};
use crate::filter::{PROB_FLOOR, log_normalize};
use crate::linalg::symmetrize;
use crate::state::Gaussian;
use crate::state::moment_match;
use crate::{EstimationError, Result};

/// Number of modes: `[none, steady, drifting]`.
const MODES: usize = 3;

/// Above this many sensors with bias terms the output weighs "every sensor biased" alone
/// (`2^S − 1` sets: 15 for 4 sensors).
pub const MAX_SET_SENSORS: usize = 4;

/// Above this many sets the output does not split a sensor's time offset from its other terms
/// (63 for three sensors with a time offset each).
pub const MAX_SETS: usize = 64;

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
    /// Weigh, in the output, every set of biased sensors (up to [`MAX_SET_SENSORS`] sensors with
    /// terms; see the module docs); `false`: every sensor biased, or none.
    pub per_sensor: bool,
}

impl Default for DriftModes {
    /// 20 times the drift, 300 s sojourn, drifting with probability 0.1 of the biased share at
    /// the start; no bias with probability 0.5 at the start, a bias going after 3 600 s on
    /// average; the sets of biased sensors weighed.
    fn default() -> Self {
        Self {
            factor: 20.0,
            sojourn: 300.0,
            initial: 0.1,
            unbiased: 0.5,
            presence_sojourn: 3600.0,
            per_sensor: true,
        }
    }
}

impl DriftModes {
    /// Errors unless `factor ≥ 1`, both sojourns are finite and positive and both initial
    /// probabilities lie in [0, 1].
    pub(super) fn validate(&self) -> Result<()> {
        let ok = self.factor.is_finite()
            && self.factor >= 1.0
            && self.sojourn.is_finite()
            && self.sojourn > 0.0
            && (0.0..=1.0).contains(&self.initial)
            && (0.0..=1.0).contains(&self.unbiased)
            && self.presence_sojourn.is_finite()
            && self.presence_sojourn > 0.0;
        if ok {
            Ok(())
        } else {
            Err(EstimationError::InvalidParameter(format!(
                "bias modes need factor ≥ 1, sojourns > 0 and initial probabilities in [0, 1], \
                 got {self:?}"
            )))
        }
    }
}

/// The registration filter in its three modes.
#[derive(Debug, Clone, PartialEq)]
pub struct RegistrationImm<const K: usize, const N: usize> {
    modes: [Registration<K, N>; MODES],
    drift: DriftModes,
    /// The sets of biased sensors the output weighs (the last: every sensor with terms).
    sets: Vec<BiasedSet>,
}

/// One set of biased sensors: which sensors (in the filter's order) and the state indices of
/// the terms it takes at their prior (the other sensors').
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BiasedSet {
    pub(super) biased: Vec<bool>,
    pub(super) pinned: Vec<usize>,
    /// Its prior probability within the biased hypothesis (the sets' sum to 1).
    pub(super) prior: f64,
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
        drift.validate()?;
        let drifting = steady.with_drift_factor(drift.factor);
        let sets = biased_sets(&steady, drift.per_sensor);
        Ok(Self {
            modes: [steady.pinned(), steady, drifting],
            drift,
            sets,
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
                let from: [_; MODES] = std::array::from_fn(|i| self.convert(&state.modes[i], i, j));
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

    /// The moment-matched state: the estimate over the "no bias" mode (its biases exactly at
    /// their means) and each biased mode under each set of biased sensors (see the module
    /// docs), the full covariance over the biased modes (observability if there is a bias).
    pub fn combined(&self, state: &RegistrationImmState<N>) -> RegistrationState<N> {
        self.output(state).0
    }

    /// [`RegistrationImm::combined`], and the probability that each sensor (in the filter's
    /// order) is biased: the weight of the sets that hold it biased.
    pub fn output(&self, state: &RegistrationImmState<N>) -> (RegistrationState<N>, Vec<f64>) {
        let components = self.components(state);
        let mut biased_probs = vec![0.0; self.modes[1].sensors().len()];
        for c in &components {
            let Some(set) = c.set else { continue };
            for (p, biased) in biased_probs.iter_mut().zip(&self.sets[set].biased) {
                if *biased {
                    *p += c.weight;
                }
            }
        }
        let (states, weights): (Vec<_>, Vec<_>) =
            components.into_iter().map(|c| (c.state, c.weight)).unzip();
        let biased = state.probs[1] + state.probs[2];
        let w = [0.0, state.probs[1] / biased, state.probs[2] / biased];
        let given_bias = mix(&state.modes, &w);
        let combined = reported(&self.modes[1], &states, &weights, &given_bias);
        (combined, biased_probs)
    }

    /// The output's components: the unbiased mode, and each biased mode conditioned on each
    /// set's pinned terms at their prior means, weighed by the mode's probability times the
    /// set's posterior probability given the mode (Savage–Dickey, see the module docs).
    fn components(&self, state: &RegistrationImmState<N>) -> Vec<Component<N>> {
        let mut out = vec![Component {
            state: self.modes[1].reset_biases(&state.modes[0]),
            weight: state.probs[0],
            set: None,
        }];
        // Each set weighed by its prior; the set of all pins nothing and is always there, so
        // each mode's weights sum to its probability.
        for m in 1..MODES {
            let conditioned: Vec<_> = self
                .sets
                .iter()
                .enumerate()
                .filter_map(|(i, set)| {
                    let (s, log_bf) = self.modes[m].given_prior(&state.modes[m], &set.pinned)?;
                    Some((i, s, log_bf + set.prior.ln()))
                })
                .collect();
            let max = conditioned
                .iter()
                .map(|c| c.2)
                .fold(f64::NEG_INFINITY, f64::max);
            let total: f64 = conditioned.iter().map(|c| (c.2 - max).exp()).sum();
            out.extend(conditioned.into_iter().map(|(i, s, l)| Component {
                state: s,
                weight: state.probs[m] * (l - max).exp() / total,
                set: Some(i),
            }));
        }
        out
    }
}

/// A component of the output: a state, its weight and its set of biased sensors (`None`: the
/// unbiased mode).
struct Component<const N: usize> {
    state: RegistrationState<N>,
    weight: f64,
    set: Option<usize>,
}

/// The sets of biased sensors of `filter` the output weighs: every non-empty set of the sensors
/// that carry terms when `per_sensor` and there are at most [`MAX_SET_SENSORS`] of them, else
/// the set of all; the set of all, every term free, is the last. Within a set, a biased sensor
/// whose terms are all constant, a time offset and others, is biased in one of three ways, each
/// with a third of its prior: every term free, its time offset alone at the prior (a latency it
/// does not have), or its time offset alone free (see the module docs); not when that makes
/// more than [`MAX_SETS`] sets.
pub(super) fn biased_sets<const K: usize, const N: usize>(
    filter: &Registration<K, N>,
    per_sensor: bool,
) -> Vec<BiasedSet> {
    let sensors = filter.sensors();
    let carrying: Vec<usize> = (0..sensors.len())
        .filter(|&i| sensors[i].terms().next().is_some())
        .collect();
    let all = (1usize << carrying.len()) - 1;
    let masks: Vec<usize> = if all > 0 && per_sensor && carrying.len() <= MAX_SET_SENSORS {
        (1..=all).collect()
    } else {
        vec![all]
    };
    // Per sensor, the ways it may be biased: the terms each pins; every term free is the last.
    let ways = |split: bool, s: usize| -> Vec<Vec<usize>> {
        let terms: Vec<(Term, usize)> = sensors[s].terms().collect();
        let (time, rest): (Vec<_>, Vec<_>) =
            terms.iter().partition(|(t, _)| *t == Term::TimeOffset);
        let index = |v: Vec<&(Term, usize)>| v.into_iter().map(|(_, i)| *i).collect();
        let constant = terms.iter().all(|(_, i)| {
            filter
                .prior_of(*i)
                .is_some_and(|p| p.dynamics == Dynamics::Constant)
        });
        if split && constant && !time.is_empty() && !rest.is_empty() {
            vec![index(time), index(rest), Vec::new()]
        } else {
            vec![Vec::new()]
        }
    };
    let count = |split: bool| -> usize {
        masks
            .iter()
            .map(|&mask| {
                (0..carrying.len())
                    .filter(|bit| mask & (1 << bit) != 0)
                    .map(|bit| ways(split, carrying[bit]).len())
                    .product::<usize>()
            })
            .sum()
    };
    let split = per_sensor && count(true) <= MAX_SETS;
    let mut out = Vec::new();
    for &mask in &masks {
        let mut biased = vec![false; sensors.len()];
        for (bit, &s) in carrying.iter().enumerate() {
            biased[s] = mask & (1 << bit) != 0;
        }
        let unbiased: Vec<usize> = sensors
            .iter()
            .zip(&biased)
            .filter(|(_, b)| !**b)
            .flat_map(|(s, _)| s.terms().map(|(_, i)| i))
            .collect();
        // Every combination of the biased sensors' ways, the last way of each last.
        let options: Vec<Vec<Vec<usize>>> = (0..sensors.len())
            .filter(|&s| biased[s])
            .map(|s| ways(split, s))
            .collect();
        let combinations: usize = options.iter().map(Vec::len).product();
        let prior = 1.0 / (masks.len() * combinations) as f64;
        for mut c in 0..combinations {
            let mut pinned = unbiased.clone();
            for o in options.iter().rev() {
                pinned.extend(&o[c % o.len()]);
                c /= o.len();
            }
            pinned.sort_unstable();
            out.push(BiasedSet {
                biased: biased.clone(),
                pinned,
                prior,
            });
        }
    }
    out
}

/// What the output reports of `components` weighed by `w` (the unbiased hypothesis and the
/// biased ones under each set): their mixture, with the full covariance of `given_bias` (the
/// biased modes: observability if there is a bias), and a sensor whose bias the data do not
/// determine reporting `given_bias`'s covariance of its terms (see the module docs).
pub(super) fn reported<const K: usize, const N: usize>(
    filter: &Registration<K, N>,
    components: &[RegistrationState<N>],
    w: &[f64],
    given_bias: &RegistrationState<N>,
) -> RegistrationState<N> {
    let all = mix(components, w);
    let mut out = RegistrationState {
        full_cov: given_bias.full_cov,
        ..all
    };
    for sensor in filter.estimates(&out) {
        if sensor.observable {
            continue;
        }
        for t in &sensor.terms {
            let i = t.index;
            let (row, column) = (
                given_bias.estimate.cov.row(i).into_owned(),
                given_bias.estimate.cov.column(i).into_owned(),
            );
            out.estimate.cov.set_row(i, &row);
            out.estimate.cov.set_column(i, &column);
        }
    }
    out
}

/// `Σ w_i` of registration states, moment-matched: the estimates as Gaussians, the full
/// covariances with the same spread of the means.
fn mix<const N: usize>(modes: &[RegistrationState<N>], w: &[f64]) -> RegistrationState<N> {
    let estimates: Vec<_> = modes.iter().map(|m| m.estimate).collect();
    let estimate = moment_match(&estimates, w);
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
