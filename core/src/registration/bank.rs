//! The tracker-level form of registration: a [`BiasBank`] holds every sensor's bias terms,
//! shared by every track, beside the tracks a multi-target tracker keeps.
//!
//! **The form.** The augmented state over every track and the biases, `X = [x_1; …; x_T; b]`
//! (Lin, Bar-Shalom & Kirubarajan 2005's augmented form, over several targets), with its whole
//! covariance: the bank keeps the bias mean `b̂` and the covariance `P` of `X` (the tracks'
//! blocks `P_ii`, their cross-covariances with the biases `P_ib` **and with each other** `P_ij`,
//! which a shared bias builds); the tracks' means stay with the tracker, which passes them (and
//! its own predicted `P_ii`) to every update and gets them back updated. So nothing is dropped:
//! an update with a detection of track `j` (or of a cooperative reference: no track columns in
//! `H`) is the augmented EKF's on the whole `X`, exact to first order, and moves every track
//! through its correlation with the biases:
//!
//! ```text
//! ν = z ⊖ ẑ(x_j, b),  H = [0 … H_x … 0  H_b],  S = H P Hᵀ + R,  K = P Hᵀ S⁻¹         ([BLK01] §5.2)
//! X⁺ = X + K ν,  P⁺ = P − K H P − (K H P)ᵀ + K S Kᵀ       (the Joseph form (5.2.3-18), expanded:
//!                                                          (I − KH) P (I − KH)ᵀ + K R Kᵀ)
//! ```
//!
//! Its cost is `O(D² M)` per detection and `O(D³)` per scan (`D = T K + n_b`: 20 planar tracks
//! and ten bias terms, `D = 90`), and memory `D²`: a tracker of tens of tracks affords it, and
//! the separate-bias forms that drop `P_ij` lose positive definiteness of the pairs they update
//! (tried first here: the innovation covariance of a later pair stopped being positive
//! definite). Between scans the biases follow their dynamics and the tracks the bank's CV model
//! (`P ← F P Fᵀ + Q`, `F = diag(F_cv, …, F_cv, Φ)`); at each update the tracker's own predicted
//! `P_ii` replaces the bank's (its motion model may differ: an IMM's moment-matched prediction,
//! a road-constrained one's road update), the track's cross-covariances transformed with it
//! (`A_i = L_c L_b⁻¹` of the two Cholesky factors: `P_ij ← A_i P_ij A_jᵀ`) so that `P` stays
//! positive semi-definite.
//!
//! With one track this is [`Registration`] with `hold: false` exactly (a test checks it). With
//! `hold` (the default tuning, the live registrar's) the bank keeps, as [`Registration`] does,
//! the covariance a bank estimating every term would have beside its own, and projects the
//! gain's bias rows onto the directions that one says the data determine
//! (`Registration::gain_projection`): a Schmidt–Kalman consider update, the other directions
//! held at their prior and their uncertainty carried by the tracks.
//!
//! **Drift modes** ([`BiasBank::with_drift`], the live registrar's): no single drift suits every
//! bias (a drift large enough to follow a Gauss–Markov offset lets a steady one wander while the
//! radar alone carries the target; a small one lags a drifting one), so the bank can run the
//! replay estimator's two biased modes ([`super::RegistrationImm`]), the bias model as
//! configured (**steady**) and every random-walk term drifting `factor` times faster
//! (**drifting**), as an IMM over the augmented state (\[BLK01\] §11.6.6). Each mode keeps its
//! own bias mean, its own covariance of `X` and its own track means, as offsets from the
//! tracker's (which stays the moment-matched mixture): mixing at each prediction
//! (`μ_{i|j} = p_ij μ_i / c̄_j`, the means and both covariances with the spread of the means),
//! each mode predicted and updated as above, `μ_j ∝ μ_j Λ_j` from each mode's innovation
//! likelihood per detection, and the tracks handed back moment-matched. A mixture collapsed at
//! every update (GPB1) was tried first: the two hypotheses then differ by one step's process
//! noise and cannot be told apart (BENCHMARKS.md). A third mode is the replay estimator's
//! **no bias** (every term pinned at its prior mean: its tracks those of a tracker told there is
//! none; nothing flows out of it, the biased modes flow into it after `presence_sojourn` on
//! average, their biases pinned on the way): without a bias it soon carries the weight and
//! registration costs nothing, where conditioning the biased modes on the prior means could
//! not undo what their held directions had cost the tracks (a radar's range offset and scale,
//! which its data do not tell apart). The biases the bank reports ([`BiasBank::state`]) and
//! takes out of detections for the tracker's gating ([`BiasBank::correct`]) are the biased
//! modes': what a bias, if there is one, may be. Taking them from every mode instead let "no
//! bias" split a biased radar's detections off the cameras' track (its gate shrank with the
//! bias uncertainty), after which nothing contradicted it (BENCHMARKS.md).
//!
//! **What the bank reports** ([`BiasBank::output`]): the tracks weighed over which sensors are
//! biased (none, or any set of them), each hypothesis by its Savage–Dickey ratio, as the replay
//! estimator's output; the recursion above is unchanged by it.
//!
//! **For the tracker's own update** (gating, association, or a track filter that does not go
//! through the bank), [`BiasBank::correct`] gives a scan's detections with the biases taken out
//! and the bias uncertainty to add to the noise (the consider form without the cross-covariance).
//!
//! # References
//! * \[BLK01\] Y. Bar-Shalom, X. R. Li, T. Kirubarajan, *Estimation with Applications to Tracking
//!   and Navigation*, Wiley 2001.
//! * X. Lin, Y. Bar-Shalom, T. Kirubarajan, "Multisensor multitarget bias estimation for general
//!   asynchronous sensors", *IEEE Trans. AES* 41(3), 2005.
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::filter::{KnownObject, Observation, PinnedBlock, Registration, RegistrationState, Seen};
use super::imm::{BiasedSet, DriftModes, biased_sets, reported};
use super::model::Dynamics;
use super::report::SensorEstimate;
use crate::filter::PROB_FLOOR;
use crate::linalg::ensure_finite;
use crate::state::{Gaussian, moment_match};
use crate::{EstimationError, Result};
use mode::{mix, track_maps};

/// A track's identity in the bank (the tracker's track id).
pub type TrackId = u64;

/// The tracks of one update: every track of the bank with its current state, which the update
/// replaces.
pub type Tracks<'a, const K: usize> = [(TrackId, &'a mut Gaussian<K>)];

/// Every sensor's bias terms shared by the tracks (see the module docs). `K`, `N`: as
/// [`Registration`]'s (the bias terms sit at indices `K..N` of its state).
#[derive(Debug, Clone, PartialEq)]
pub struct BiasBank<const K: usize, const N: usize> {
    /// `[steady]`, or `[steady, drifting]` ([`BiasBank::with_drift`]).
    modes: Vec<Mode<K, N>>,
    /// The modes' probabilities.
    probs: Vec<f64>,
    /// The drift modes' tuning (`None`: one mode).
    drift: Option<DriftModes>,
    /// The tracks, in the order of their blocks in each mode's `cov`.
    ids: Vec<TrackId>,
    /// The sets of biased sensors [`BiasBank::output`] weighs.
    sets: Vec<BiasedSet>,
}

/// One bias mode of the bank: its filter, bias mean, track means and covariances.
#[derive(Debug, Clone, PartialEq)]
struct Mode<const K: usize, const N: usize> {
    reg: Registration<K, N>,
    /// The bias terms at `K..N` (the first `K` unused, zero).
    bias: SVector<f64, N>,
    /// This mode's track means less the tracker's (the moment-matched ones), stacked as the
    /// tracks' blocks of `cov`.
    offset: DVector<f64>,
    /// Covariance of `[x_1; …; x_T; b_K..N]` (with the hold: of the consider updates).
    cov: DMatrix<f64>,
    /// With the hold (`reg`'s `Tuning::hold`): the covariance of the same layout a bank
    /// estimating every term would have, which says what the data determine.
    full: Option<DMatrix<f64>>,
}

/// The modes' indices: the bias model as configured, every random-walk term drifting faster,
/// no bias ([`BiasBank::with_drift`]).
const STEADY: usize = 0;
const DRIFTING: usize = 1;
const UNBIASED: usize = 2;

/// The prior probability that no sensor is biased in [`BiasBank::output`] (the replay
/// estimator's, [`DriftModes::unbiased`]); the sets of biased sensors share the rest.
pub const UNBIASED_PRIOR: f64 = 0.5;

/// A hypothesis of [`BiasBank::output`] this far below the likeliest in log weight (e⁻⁴⁰ of it)
/// is left out before its conditioning.
const NEGLIGIBLE_LOG_WEIGHT: f64 = 40.0;

/// The bank's tracks weighed over which sensors are biased ([`BiasBank::output`]).
#[derive(Debug, Clone, PartialEq)]
pub struct BankOutput<const K: usize> {
    /// Each track's estimate: the moment-matched mixture over the hypotheses, in the order given.
    pub tracks: Vec<(TrackId, Gaussian<K>)>,
    /// Per sensor (the registration's order), the probability that it is biased.
    pub biased: Vec<f64>,
}

/// A scan's detection with the biases taken out ([`BiasBank::correct`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Corrected {
    /// `z_i' = (z_i − ô_i) / (1 + ŝ_i)`, per component.
    pub z: Vec<f64>,
    /// The bias uncertainty to add to the noise: `J P_bb Jᵀ`, `J = ∂z'/∂(o, s)` (dim × dim).
    pub extra_cov: DMatrix<f64>,
    /// The time offset `δ̂` (s): the detection stamped `t` shows the world at `t − δ̂`.
    pub time_offset: f64,
    /// Its variance (s²): a track adds `σ_δ² (H v_rel)(H v_rel)ᵀ`, `v_rel` its velocity
    /// relative to the sensor's platform.
    pub time_offset_var: f64,
}

/// One hypothesis of which sensors are biased ([`BiasBank::output`]): those it holds biased
/// (the registration's order), its weight (normalised) and the tracks conditioned on it.
struct Hypothesis<const K: usize, const N: usize> {
    biased: Vec<bool>,
    weight: f64,
    tracks: Vec<Gaussian<K>>,
    biases: Biases<N>,
}

/// What a hypothesis holds of the biases, conditioned only when they are reported
/// ([`BiasBank::state`]; the tracks' output does not need them).
enum Biases<const N: usize> {
    /// Every term free: the bank's.
    Free,
    /// The terms at these state indices at their prior means.
    Pinned(Vec<usize>, PinnedBlock),
    /// A state of its own (the "no bias" mode's).
    Own(RegistrationState<N>),
}

/// The hypotheses of [`BiasBank::output`], weighed, and the biased modes' biases they
/// condition.
struct Weighed<const K: usize, const N: usize> {
    bank: RegistrationState<N>,
    hypotheses: Vec<Hypothesis<K, N>>,
}

/// Per sensor (of `sensors`), the weight of the hypotheses that hold it biased.
fn biased_probs<const K: usize, const N: usize>(
    weighed: &[Hypothesis<K, N>],
    sensors: usize,
) -> Vec<f64> {
    let mut out = vec![0.0; sensors];
    for h in weighed {
        for (p, b) in out.iter_mut().zip(&h.biased) {
            if *b {
                *p += h.weight;
            }
        }
    }
    out
}

impl<const K: usize, const N: usize> BiasBank<K, N> {
    /// A bank for `reg`'s sensors and bias models, every term at its prior, no track; one
    /// mode, the bias model as configured.
    pub fn new(reg: Registration<K, N>) -> Result<Self> {
        let placeholder = Gaussian {
            mean: SVector::zeros(),
            cov: SMatrix::identity(),
        };
        let s = reg.initial(&placeholder)?;
        let cov = s.estimate.cov.view((K, K), (N - K, N - K)).into_owned();
        let cov = DMatrix::from_column_slice(N - K, N - K, cov.as_slice());
        let sets = biased_sets(&reg, true);
        Ok(Self {
            modes: vec![Mode {
                bias: s.estimate.mean,
                offset: DVector::zeros(0),
                full: reg.tuning().hold.then(|| cov.clone()),
                cov,
                reg,
            }],
            probs: vec![1.0],
            drift: None,
            ids: Vec::new(),
            sets,
        })
    }

    /// [`BiasBank::new`] with the drift modes and "no bias" (see the module docs): `drift`'s
    /// `factor`, `sojourn`, `initial` (the drifting mode's share of the biased probability at
    /// the start), `unbiased` ("no bias" at the start) and `presence_sojourn`.
    pub fn with_drift(reg: Registration<K, N>, drift: DriftModes) -> Result<Self> {
        drift.validate()?;
        let mut bank = Self::new(reg)?;
        let mut drifting = bank.modes[0].clone();
        drifting.reg = drifting.reg.with_drift_factor(drift.factor);
        let none = bank.modes[0].pinned();
        bank.modes.extend([drifting, none]);
        let biased = 1.0 - drift.unbiased;
        bank.probs = vec![
            (biased * (1.0 - drift.initial)).max(PROB_FLOOR),
            (biased * drift.initial).max(PROB_FLOOR),
            drift.unbiased.max(PROB_FLOOR),
        ];
        bank.drift = Some(drift);
        Ok(bank)
    }

    /// The layout, the bias models and the linearisation (the steady mode's).
    pub fn registration(&self) -> &Registration<K, N> {
        &self.modes[0].reg
    }

    /// The probability of the drifting mode (`None` without drift modes).
    pub fn drifting_prob(&self) -> Option<f64> {
        self.drift.map(|_| self.probs[DRIFTING])
    }

    /// The probability that no sensor is biased, the "no bias" mode's (`None` without the
    /// modes).
    pub fn unbiased_prob(&self) -> Option<f64> {
        self.drift.map(|_| self.probs[UNBIASED])
    }

    /// The biased modes (every mode but "no bias") moment-matched: what the biases are if there
    /// are any.
    fn biased_modes(modes: &[Mode<K, N>], probs: &[f64]) -> Mode<K, N> {
        if modes.len() == 1 {
            return modes[0].clone();
        }
        let total = probs[STEADY] + probs[DRIFTING];
        let mut w = vec![0.0; modes.len()];
        w[STEADY] = probs[STEADY] / total;
        w[DRIFTING] = probs[DRIFTING] / total;
        mix(modes, &w, &modes[STEADY].reg)
    }

    /// The modes moment-matched, with the steady mode's filter: the bank's estimate.
    fn combined(&self) -> Mode<K, N> {
        if self.modes.len() == 1 {
            return self.modes[0].clone();
        }
        mix(&self.modes, &self.probs, &self.modes[0].reg)
    }

    /// The bias terms' mean and covariance, as a registration state with a placeholder target
    /// (mean 0, identity covariance, uncorrelated), reported as the replay estimator's
    /// ([`super::RegistrationImm::output`]): the mixture over the hypotheses of
    /// [`BiasBank::output`], the full covariance the biased modes' (observability if there is a
    /// bias), and a sensor whose bias the data do not determine with the biased modes'
    /// covariance of its terms. The biases taken out for gating ([`BiasBank::correct`]) are
    /// the biased modes'.
    pub fn state(&self) -> RegistrationState<N> {
        // The hypotheses' weights are finite unless the bank's covariance is not (then the
        // biased modes' state says so too).
        match self.weighed(&[]) {
            Ok(weighed) => self.reported(&weighed),
            Err(_) => Self::biased_modes(&self.modes, &self.probs).state(),
        }
    }

    /// [`BiasBank::state`] from the hypotheses `weighed`.
    fn reported(&self, weighed: &Weighed<K, N>) -> RegistrationState<N> {
        let given_bias = Self::biased_modes(&self.modes, &self.probs).state();
        let (states, w): (Vec<_>, Vec<_>) = weighed
            .hypotheses
            .iter()
            .map(|h| {
                let state = match &h.biases {
                    Biases::Free => weighed.bank,
                    Biases::Pinned(pinned, block) => {
                        self.registration()
                            .conditioned(&weighed.bank, pinned, block)
                    }
                    Biases::Own(state) => *state,
                };
                (state, h.weight)
            })
            .unzip();
        reported(self.registration(), &states, &w, &given_bias)
    }

    /// Every sensor's bias estimate, its standard deviation and observability.
    pub fn estimates(&self) -> Vec<SensorEstimate> {
        self.registration().estimates(&self.state())
    }

    /// [`BiasBank::estimates`] and, per sensor, the probability that it is biased (the weight
    /// of the hypotheses of [`BiasBank::output`] that hold it biased; they depend on the biases
    /// alone), from one weighing.
    pub fn report(&self) -> Result<(Vec<SensorEstimate>, Vec<f64>)> {
        let weighed = self.weighed(&[])?;
        Ok((
            self.registration().estimates(&self.reported(&weighed)),
            biased_probs(&weighed.hypotheses, self.registration().sensors().len()),
        ))
    }

    /// The tracks, in the bank's order.
    pub fn tracks(&self) -> &[TrackId] {
        &self.ids
    }

    /// The cross-covariance `P_ib` of a track (columns `K..N`, the first `K` zero).
    pub fn cross(&self, id: TrackId) -> Option<SMatrix<f64, K, N>> {
        let i = self.ids.iter().position(|t| *t == id)?;
        let c = self.combined();
        let b0 = c.b0();
        Some(SMatrix::from_fn(|r, col| {
            if col < K {
                0.0
            } else {
                c.cov[(i * K + r, b0 + col - K)]
            }
        }))
    }

    /// A new track, of state `track`, uncorrelated with the biases and the other tracks (a
    /// track started from bias-corrected detections, [`BiasBank::correct`]: their correlation
    /// with the biases is dropped). Errors if the bank has it already.
    pub fn add_track(&mut self, id: TrackId, track: &Gaussian<K>) -> Result<()> {
        if self.ids.contains(&id) {
            return Err(EstimationError::InvalidParameter(format!(
                "track {id} is in the bank already"
            )));
        }
        ensure_finite(&track.cov, "track covariance")?;
        let b0 = self.ids.len() * K;
        // Old tracks, then the new one, then the biases.
        let grow = |old: &DMatrix<f64>| {
            let d = old.nrows();
            let mut cov = DMatrix::zeros(d + K, d + K);
            let map = |i: usize| if i < b0 { i } else { i + K };
            for i in 0..d {
                for j in 0..d {
                    cov[(map(i), map(j))] = old[(i, j)];
                }
            }
            for i in 0..K {
                for j in 0..K {
                    cov[(b0 + i, b0 + j)] = track.cov[(i, j)];
                }
            }
            cov
        };
        for m in &mut self.modes {
            if let Some(full) = m.full.take() {
                m.full = Some(grow(&full));
            }
            m.cov = grow(&m.cov);
            m.offset = m.offset.clone().resize_vertically(b0 + K, 0.0);
        }
        self.ids.push(id);
        Ok(())
    }

    /// Forgets a track.
    pub fn remove_track(&mut self, id: TrackId) {
        if let Some(i) = self.ids.iter().position(|t| *t == id) {
            for m in &mut self.modes {
                let d = m.cov.nrows();
                let keep: Vec<usize> = (0..d)
                    .filter(|r| !(i * K..(i + 1) * K).contains(r))
                    .collect();
                m.cov = m.cov.select_rows(&keep).select_columns(&keep);
                m.full = m
                    .full
                    .as_ref()
                    .map(|f| f.select_rows(&keep).select_columns(&keep));
                let offsets = m.offset.len();
                let rows: Vec<usize> = keep.iter().copied().filter(|&r| r < offsets).collect();
                m.offset = m.offset.select_rows(&rows);
            }
            self.ids.remove(i);
        }
    }

    /// The biases' dynamics over `dt ≥ 0` seconds and the bank's CV prediction of the tracks'
    /// covariances (`P ← F P Fᵀ + Q`); the tracker predicts the tracks themselves over the same
    /// `dt`. With drift modes, the IMM's mixing first, the switch probability over `dt`
    /// `p_d = ½ (1 − e^{−2 dt / T})` (`T` the sojourn; \[BLK01\] §11.6.6).
    pub fn predict(&mut self, dt: f64) -> Result<()> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "prediction interval must be finite and ≥ 0, got {dt}"
            )));
        }
        if dt == 0.0 {
            return Ok(());
        }
        if let Some(drift) = self.drift {
            let pd = 0.5 * (1.0 - (-2.0 * dt / drift.sojourn).exp());
            let pa = 1.0 - (-dt / drift.presence_sojourn).exp();
            // [steady, drifting, none]: nothing flows out of "no bias" (see the module docs).
            let tpm = [
                [(1.0 - pa) * (1.0 - pd), (1.0 - pa) * pd, pa],
                [(1.0 - pa) * pd, (1.0 - pa) * (1.0 - pd), pa],
                [0.0, 0.0, 1.0],
            ];
            // A state entering "no bias" has its biases pinned at their prior means.
            let into_none: Vec<Mode<K, N>> = self
                .modes
                .iter()
                .enumerate()
                .map(|(i, m)| if i == UNBIASED { m.clone() } else { m.pinned() })
                .collect();
            let mut mixed = Vec::with_capacity(3);
            let mut probs = Vec::with_capacity(3);
            for (j, mode) in self.modes.iter().enumerate() {
                let w: Vec<f64> = (0..3).map(|i| tpm[i][j] * self.probs[i]).collect();
                let cbar: f64 = w.iter().sum();
                let w: Vec<f64> = w.iter().map(|v| v / cbar).collect();
                let from = if j == UNBIASED {
                    &into_none
                } else {
                    &self.modes
                };
                mixed.push(mix(from, &w, &mode.reg));
                probs.push(cbar.max(PROB_FLOOR));
            }
            let sum: f64 = probs.iter().sum();
            self.probs = probs.iter().map(|p| p / sum).collect();
            self.modes = mixed;
        }
        for m in &mut self.modes {
            m.predict(dt);
        }
        Ok(())
    }

    /// Updates every track (their states `tracks`, at the bank's time: every track of the bank)
    /// and the biases with one detection associated with track `id`; returns the detection's
    /// normalised innovation squared (the modes', weighed by their probabilities before it).
    /// The tracks' states are replaced by the updated ones.
    pub fn update(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        id: TrackId,
        obs: &Observation<'_>,
    ) -> Result<f64> {
        let j = self.ids.iter().position(|t| *t == id).ok_or_else(|| {
            EstimationError::InvalidParameter(format!("no track {id} in the bank"))
        })?;
        self.apply(tracks, Some(j), obs, &Seen::Target)
    }

    /// Updates the biases with a detection of a cooperative reference (a known object), and
    /// every track through its correlation with them (`tracks`: every track of the bank, at its
    /// time, replaced by the updated states); returns the detection's normalised innovation
    /// squared.
    pub fn update_reference(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        obs: &Observation<'_>,
        known: &KnownObject,
    ) -> Result<f64> {
        self.apply(tracks, None, obs, &Seen::Known(*known))
    }

    /// Every mode's update (see [`Mode::update`]); then, with drift modes, the modes'
    /// probabilities from their likelihoods, and the tracks handed back moment-matched over the
    /// modes, each mode keeping its means as offsets from them. Nothing changes on an error.
    fn apply(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        j: Option<usize>,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<f64> {
        let order = self.order(tracks)?;
        let given: Vec<Gaussian<K>> = order.iter().map(|&k| *tracks[k].1).collect();
        let maps = track_maps(&self.modes, &self.probs, &given)?;
        let mut modes = self.modes.clone();
        for m in &mut modes {
            m.follow(&given, &maps);
        }
        let ups = modes
            .iter_mut()
            .map(|m| m.update(&given, j, obs, seen))
            .collect::<Result<Vec<_>>>()?;
        let nis = ups.iter().zip(&self.probs).map(|(u, p)| u.nis * p).sum();
        let probs = if ups.len() == 1 {
            vec![1.0]
        } else {
            let log_w: Vec<f64> = ups
                .iter()
                .zip(&self.probs)
                .map(|(u, p)| p.ln() + u.log_likelihood)
                .collect();
            let max = log_w.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            if !max.is_finite() {
                return Err(EstimationError::NonFinite("bias bank mode likelihoods"));
            }
            let w: Vec<f64> = log_w.iter().map(|l| (l - max).exp()).collect();
            let sum: f64 = w.iter().sum();
            let w: Vec<f64> = w.iter().map(|v| (v / sum).max(PROB_FLOOR)).collect();
            let sum: f64 = w.iter().sum();
            w.iter().map(|v| v / sum).collect()
        };
        for (t, &k) in order.iter().enumerate() {
            let per_mode: Vec<Gaussian<K>> = ups.iter().map(|u| u.tracks[t]).collect();
            let g = moment_match(&per_mode, &probs);
            for (m, own) in modes.iter_mut().zip(&per_mode) {
                m.offset
                    .fixed_rows_mut::<K>(t * K)
                    .copy_from(&(own.mean - g.mean));
            }
            *tracks[k].1 = g;
        }
        self.modes = modes;
        self.probs = probs;
        Ok(nis)
    }

    /// The tracks `tracks` (every track of the bank, the tracker's estimates at the bank's
    /// time) weighed over the hypotheses of which sensors are biased, as the replay estimator's
    /// output ([`super::RegistrationImm`]): no sensor biased (prior [`UNBIASED_PRIOR`]), and each
    /// non-empty set of the sensors with terms (equal priors; the set of all alone above
    /// [`super::MAX_SET_SENSORS`] sensors), a constant sensor's time offset weighed apart from
    /// its other terms (the replay estimator's module docs). A hypothesis holds the terms of the
    /// sensors it takes as unbiased (and the pinned ways') at their prior means `μ_c`; its
    /// Bayes factor against every term free is the
    /// Savage–Dickey ratio and its estimate the bank's conditioned on them
    /// (`Registration::given_prior`, over the bank's joint covariance):
    ///
    /// ```text
    /// B_S = N(μ_c; b̂_c, P_cc) / N(μ_c; μ_c, Σ_c),   P(S | data) ∝ P(S) B_S
    /// x̂_i,S = x̂_i + P_ic P_cc⁻¹ (μ_c − b̂_c),   P_ii,S = P_ii − P_ic P_cc⁻¹ P_ci
    /// ```
    ///
    /// exact, for constant biases and a linear model, as the filter told those sensors are
    /// unbiased (Dickey 1971; Verdinelli & Wasserman 1995). The recursion is unchanged: the
    /// bank keeps estimating every term and the tracker keeps its tracks; this is what they
    /// report. A hypothesis whose `P_cc` is not positive definite is left out. With the modes
    /// ([`BiasBank::with_drift`]) "no sensor biased" is the "no bias" mode, its tracks and its
    /// probability, and the sets share the biased modes' (moment-matched) probability.
    pub fn output(&self, tracks: &[(TrackId, Gaussian<K>)]) -> Result<BankOutput<K>> {
        let order = self.order(tracks)?;
        let given: Vec<Gaussian<K>> = order.iter().map(|&k| tracks[k].1).collect();
        let weighed = self.weighed(&given)?.hypotheses;
        let w: Vec<f64> = weighed.iter().map(|h| h.weight).collect();
        let tracks = order
            .iter()
            .enumerate()
            .map(|(t, &k)| {
                let components: Vec<Gaussian<K>> = weighed.iter().map(|h| h.tracks[t]).collect();
                (tracks[k].0, moment_match(&components, &w))
            })
            .collect();
        Ok(BankOutput {
            tracks,
            biased: biased_probs(&weighed, self.registration().sensors().len()),
        })
    }

    /// The hypotheses of [`BiasBank::output`], weighed, each with the tracks `given` (every
    /// track in the bank's order, or none) conditioned on it.
    fn weighed(&self, given: &[Gaussian<K>]) -> Result<Weighed<K, N>> {
        let maps = track_maps(&self.modes, &self.probs, given)?;
        let mut modes = self.modes.clone();
        for m in &mut modes {
            m.follow(given, &maps);
        }
        let bank = Self::biased_modes(&modes, &self.probs);
        // With the modes, "no bias" is a mode of its own: its tracks, its probability; the
        // biased modes share the rest over the non-empty sets.
        let (none, biased_share) = match self.drift {
            Some(_) => {
                let m = &modes[UNBIASED];
                let tracks = (0..given.len())
                    .map(|t| Gaussian {
                        mean: given[t].mean + m.offset.fixed_rows::<K>(t * K),
                        cov: m.cov.fixed_view::<K, K>(t * K, t * K).into_owned(),
                    })
                    .collect();
                (
                    Some((self.probs[UNBIASED], tracks, m.state())),
                    1.0 - self.probs[UNBIASED],
                )
            }
            None => (None, 1.0),
        };
        let P = &bank.cov;
        let b0 = bank.b0();
        let sensors = bank.reg.sensors();
        let sets = &self.sets;
        let every_term: Vec<usize> = sensors
            .iter()
            .flat_map(|s| s.terms().map(|(_, i)| i))
            .collect();
        let biased_prior = 1.0 - UNBIASED_PRIOR;
        // A Gauss–Markov term wanders about its mean: its value there says nothing of whether
        // the sensor is biased, so no hypothesis holds such a sensor unbiased.
        let wanders = |i: &usize| {
            bank.reg
                .prior_of(*i)
                .is_some_and(|p| matches!(p.dynamics, Dynamics::GaussMarkov { .. }))
        };
        let empty = none
            .is_none()
            .then(|| (vec![false; sensors.len()], every_term, UNBIASED_PRIOR));
        let hypotheses = empty
            .into_iter()
            .chain(
                sets.iter()
                    .map(|s| (s.biased.clone(), s.pinned.clone(), biased_prior * s.prior)),
            )
            .filter(|(_, pinned, _)| !pinned.iter().any(wanders));
        let own = |t: usize| Gaussian {
            mean: given[t].mean + bank.offset.fixed_rows::<K>(t * K),
            cov: SMatrix::<f64, K, K>::from_fn(|r, s| P[(t * K + r, t * K + s)]),
        };
        let bank_state = bank.state();
        // Each hypothesis's Savage–Dickey ratio first (its pinned block alone), then the
        // conditioning for those whose weight is not negligible against the largest's.
        let scored: Vec<_> = hypotheses
            .filter_map(|(biased, pinned, prior)| {
                let block = if pinned.is_empty() {
                    None
                } else {
                    Some(bank.reg.savage_dickey(&bank_state, &pinned)?)
                };
                let weight = prior.ln() + block.as_ref().map_or(0.0, |b| b.log_bf);
                Some((biased, pinned, block, weight))
            })
            .collect();
        let max = scored.iter().map(|h| h.3).fold(f64::NEG_INFINITY, f64::max);
        if !max.is_finite() {
            return Err(EstimationError::NonFinite("bias hypotheses"));
        }
        let mut weighed: Vec<Hypothesis<K, N>> = Vec::new();
        for (biased, pinned, block, weight) in scored {
            if weight < max - NEGLIGIBLE_LOG_WEIGHT {
                continue;
            }
            let Some(block) = block else {
                let tracks = (0..given.len()).map(own).collect();
                weighed.push(Hypothesis {
                    biased,
                    weight,
                    tracks,
                    biases: Biases::Free,
                });
                continue;
            };
            let c: Vec<usize> = pinned.iter().map(|&i| b0 + i - K).collect();
            let tracks = (0..given.len())
                .map(|t| {
                    let mut g = own(t);
                    let Ptc = DMatrix::from_fn(K, c.len(), |r, j| P[(t * K + r, c[j])]);
                    let shift = &Ptc * &block.a;
                    let drop = &Ptc * block.chol.solve(&Ptc.transpose());
                    for r in 0..K {
                        g.mean[r] += shift[r];
                        for s in 0..K {
                            g.cov[(r, s)] -= drop[(r, s)];
                        }
                    }
                    g.cov = (g.cov + g.cov.transpose()) * 0.5;
                    g
                })
                .collect();
            weighed.push(Hypothesis {
                biased,
                weight,
                tracks,
                biases: Biases::Pinned(pinned, block),
            });
        }
        let total: f64 = weighed.iter().map(|h| (h.weight - max).exp()).sum();
        for h in &mut weighed {
            h.weight = biased_share * (h.weight - max).exp() / total;
        }
        if let Some((p, tracks, state)) = none {
            weighed.push(Hypothesis {
                biased: vec![false; sensors.len()],
                weight: p,
                tracks,
                biases: Biases::Own(state),
            });
        }
        Ok(Weighed {
            bank: bank_state,
            hypotheses: weighed,
        })
    }

    /// For each of the bank's tracks, its index in `tracks`; errors unless `tracks` holds
    /// exactly the bank's tracks.
    fn order<G>(&self, tracks: &[(TrackId, G)]) -> Result<Vec<usize>> {
        let order: Option<Vec<usize>> = self
            .ids
            .iter()
            .map(|id| tracks.iter().position(|(t, _)| t == id))
            .collect();
        match order {
            Some(o) if tracks.len() == self.ids.len() => Ok(o),
            _ => Err(EstimationError::InvalidParameter(format!(
                "an update needs every track of the bank ({:?}), got {:?}",
                self.ids,
                tracks.iter().map(|(t, _)| *t).collect::<Vec<_>>()
            ))),
        }
    }

    /// A detection `z` of sensor `sensor` with the offsets and scales taken out, the bias
    /// uncertainty to add to its noise, and the time offset (see [`Corrected`]), from the biased
    /// modes (see the module docs).
    pub fn correct(&self, sensor: usize, z: &[f64]) -> Result<Corrected> {
        let bank = Self::biased_modes(&self.modes, &self.probs);
        let slots = bank
            .reg
            .sensors()
            .get(sensor)
            .ok_or_else(|| EstimationError::InvalidParameter(format!("no sensor {sensor}")))?;
        if z.len() != slots.dim || z.iter().any(|v| !v.is_finite()) {
            return Err(EstimationError::InvalidParameter(format!(
                "sensor {sensor} has {} components, got {z:?}",
                slots.dim
            )));
        }
        let cov = bank.state().estimate.cov;
        let dim = slots.dim;
        let mut out = Vec::with_capacity(dim);
        // J: dim × N, ∂z'/∂b.
        let mut J = DMatrix::<f64>::zeros(dim, N);
        for (i, zi) in z.iter().enumerate() {
            let o = slots.offset[i].map_or(0.0, |s| bank.bias[s]);
            let g = 1.0 + slots.scale[i].map_or(0.0, |s| bank.bias[s]);
            if g.abs() < 1e-6 {
                return Err(EstimationError::InvalidParameter(format!(
                    "sensor {sensor}: scale estimate {g} of component {i}"
                )));
            }
            let zc = (zi - o) / g;
            out.push(zc);
            if let Some(s) = slots.offset[i] {
                J[(i, s)] = -1.0 / g;
            }
            if let Some(s) = slots.scale[i] {
                J[(i, s)] = -zc / g;
            }
        }
        let P = DMatrix::from_column_slice(N, N, cov.as_slice());
        let extra = &J * P * J.transpose();
        let (time_offset, time_offset_var) = slots
            .time_offset
            .map_or((0.0, 0.0), |s| (bank.bias[s], cov[(s, s)]));
        Ok(Corrected {
            z: out,
            extra_cov: (&extra + extra.transpose()) * 0.5,
            time_offset,
            time_offset_var,
        })
    }
}

#[path = "bank_mode.rs"]
mod mode;

#[cfg(test)]
#[path = "bank_tests.rs"]
mod tests;
