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

#[path = "bank_output.rs"]
mod output;
pub use output::BankOutput;

#[path = "bank_mode.rs"]
mod mode;

#[cfg(test)]
#[path = "bank_tests.rs"]
mod tests;
