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

use super::filter::{Augmented, KnownObject, Observation, Registration, RegistrationState, Seen};
use super::report::SensorEstimate;
use crate::linalg::ensure_finite;
use crate::motion::TransitionModel;
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// A track's identity in the bank (the tracker's track id).
pub type TrackId = u64;

/// The tracks of one update: every track of the bank with its current state, which the update
/// replaces.
pub type Tracks<'a, const K: usize> = [(TrackId, &'a mut Gaussian<K>)];

/// Every sensor's bias terms shared by the tracks (see the module docs). `K`, `N`: as
/// [`Registration`]'s (the bias terms sit at indices `K..N` of its state).
#[derive(Debug, Clone, PartialEq)]
pub struct BiasBank<const K: usize, const N: usize> {
    reg: Registration<K, N>,
    /// The bias terms at `K..N` (the first `K` unused, zero).
    bias: SVector<f64, N>,
    /// The tracks, in the order of their blocks in `cov`.
    ids: Vec<TrackId>,
    /// Covariance of `[x_1; …; x_T; b_K..N]` (with the hold: of the consider updates).
    cov: DMatrix<f64>,
    /// With the hold (`reg`'s `Tuning::hold`): the covariance of the same layout a bank
    /// estimating every term would have, which says what the data determine.
    full: Option<DMatrix<f64>>,
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

impl<const K: usize, const N: usize> BiasBank<K, N> {
    /// A bank for `reg`'s sensors and bias models, every term at its prior, no track.
    pub fn new(reg: Registration<K, N>) -> Result<Self> {
        let placeholder = Gaussian {
            mean: SVector::zeros(),
            cov: SMatrix::identity(),
        };
        let s = reg.initial(&placeholder)?;
        let cov = s.estimate.cov.view((K, K), (N - K, N - K)).into_owned();
        let cov = DMatrix::from_column_slice(N - K, N - K, cov.as_slice());
        Ok(Self {
            bias: s.estimate.mean,
            ids: Vec::new(),
            full: reg.tuning().hold.then(|| cov.clone()),
            cov,
            reg,
        })
    }

    /// The layout, the bias models and the linearisation.
    pub fn registration(&self) -> &Registration<K, N> {
        &self.reg
    }

    /// Index of the bias block in `cov`.
    fn b0(&self) -> usize {
        self.ids.len() * K
    }

    /// The bias terms' mean and covariance, as a registration state with a placeholder target
    /// (mean 0, identity covariance, uncorrelated).
    pub fn state(&self) -> RegistrationState<N> {
        let b0 = self.b0();
        let of = |all: &DMatrix<f64>| {
            SMatrix::<f64, N, N>::from_fn(|i, j| match (i < K, j < K) {
                (true, true) => f64::from(u8::from(i == j)),
                (false, false) => all[(b0 + i - K, b0 + j - K)],
                _ => 0.0,
            })
        };
        let cov = of(&self.cov);
        RegistrationState {
            estimate: Gaussian {
                mean: self.bias,
                cov,
            },
            full_cov: self.full.as_ref().map_or(cov, of),
            projection: None,
        }
    }

    /// Every sensor's bias estimate, its standard deviation and observability.
    pub fn estimates(&self) -> Vec<SensorEstimate> {
        self.reg.estimates(&self.state())
    }

    /// The tracks, in the bank's order.
    pub fn tracks(&self) -> &[TrackId] {
        &self.ids
    }

    /// The cross-covariance `P_ib` of a track (columns `K..N`, the first `K` zero).
    pub fn cross(&self, id: TrackId) -> Option<SMatrix<f64, K, N>> {
        let i = self.ids.iter().position(|t| *t == id)?;
        let b0 = self.b0();
        Some(SMatrix::from_fn(|r, c| {
            if c < K {
                0.0
            } else {
                self.cov[(i * K + r, b0 + c - K)]
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
        let b0 = self.b0();
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
        if let Some(full) = self.full.take() {
            self.full = Some(grow(&full));
        }
        self.cov = grow(&self.cov);
        self.ids.push(id);
        Ok(())
    }

    /// Forgets a track.
    pub fn remove_track(&mut self, id: TrackId) {
        if let Some(i) = self.ids.iter().position(|t| *t == id) {
            let d = self.cov.nrows();
            let keep: Vec<usize> = (0..d)
                .filter(|r| !(i * K..(i + 1) * K).contains(r))
                .collect();
            self.cov = self.cov.select_rows(&keep).select_columns(&keep);
            self.full = self
                .full
                .as_ref()
                .map(|f| f.select_rows(&keep).select_columns(&keep));
            self.ids.remove(i);
        }
    }

    /// The biases' dynamics over `dt ≥ 0` seconds and the bank's CV prediction of the tracks'
    /// covariances (`P ← F P Fᵀ + Q`); the tracker predicts the tracks themselves over the same
    /// `dt`.
    pub fn predict(&mut self, dt: f64) -> Result<()> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "prediction interval must be finite and ≥ 0, got {dt}"
            )));
        }
        if dt == 0.0 {
            return Ok(());
        }
        let model = Augmented { reg: &self.reg };
        let Fa = model.jacobian(&self.bias, dt);
        let Qa = model.covar(dt);
        self.bias = model.function(&self.bias, dt);
        self.bias.fixed_rows_mut::<K>(0).fill(0.0);
        let d = self.cov.nrows();
        let mut F = DMatrix::zeros(d, d);
        let mut Q = DMatrix::zeros(d, d);
        let blocks = (0..self.ids.len()).map(|t| (t * K, 0, K));
        for (at, from, n) in blocks.chain(std::iter::once((self.b0(), K, N - K))) {
            for i in 0..n {
                for j in 0..n {
                    F[(at + i, at + j)] = Fa[(from + i, from + j)];
                    Q[(at + i, at + j)] = Qa[(from + i, from + j)];
                }
            }
        }
        let predict = |P: &DMatrix<f64>| {
            let P = &F * P * F.transpose() + &Q;
            (&P + P.transpose()) * 0.5
        };
        if let Some(full) = self.full.take() {
            self.full = Some(predict(&full));
        }
        self.cov = predict(&self.cov);
        Ok(())
    }

    /// Updates every track (their states `tracks`, at the bank's time: every track of the bank)
    /// and the biases with one detection associated with track `id`; returns the detection's
    /// normalised innovation squared. The tracks' states are replaced by the updated ones.
    pub fn update(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        id: TrackId,
        obs: &Observation<'_>,
    ) -> Result<f64> {
        let j = self.ids.iter().position(|t| *t == id).ok_or_else(|| {
            EstimationError::InvalidParameter(format!("no track {id} in the bank"))
        })?;
        let order = self.order(tracks)?;
        let mut x = self.bias;
        x.fixed_rows_mut::<K>(0).copy_from(&tracks[order[j]].1.mean);
        let (nu, H, R) = self.reg.linearised(&x, obs, &Seen::Target)?;
        self.apply(tracks, &order, Some(j), &nu, &H, &R)
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
        let order = self.order(tracks)?;
        let (nu, H, R) = self.reg.linearised(&self.bias, obs, &Seen::Known(*known))?;
        self.apply(tracks, &order, None, &nu, &H, &R)
    }

    /// For each of the bank's tracks, its index in `tracks`; errors unless `tracks` holds
    /// exactly the bank's tracks.
    fn order(&self, tracks: &Tracks<'_, K>) -> Result<Vec<usize>> {
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

    /// The joint update with one detection (see the module docs), `j` the detected track (none
    /// for a reference); returns its normalised innovation squared. With the hold, the gain's
    /// bias rows are projected onto the directions the data determine, as
    /// [`Registration`]'s (a Schmidt–Kalman consider update: the expanded Joseph form of
    /// [`joint`] is the covariance of any gain, so the other directions keep their prior and the
    /// tracks carry their uncertainty), and the full covariance takes the optimal update that
    /// says which directions are determined.
    fn apply(
        &mut self,
        tracks: &mut Tracks<'_, K>,
        order: &[usize],
        j: Option<usize>,
        nu: &DVector<f64>,
        H: &DMatrix<f64>,
        R: &DMatrix<f64>,
    ) -> Result<f64> {
        let (b0, d, m) = (self.b0(), self.cov.nrows(), H.nrows());
        let mut Hd = DMatrix::zeros(m, d);
        for r in 0..m {
            if let Some(j) = j {
                for c in 0..K {
                    Hd[(r, j * K + c)] = H[(r, c)];
                }
            }
            for c in K..N {
                Hd[(r, b0 + c - K)] = H[(r, c)];
            }
        }
        // The bias rows of the gain projected onto the directions the data determine
        // (`Registration::gain_projection`, from the full covariance).
        let projection = self.full.is_some().then(|| {
            let T = self.reg.gain_projection(&self.state());
            DMatrix::from_fn(N - K, N - K, |r, c| T[(K + r, K + c)])
        });
        let P = self.with_tracks(&self.cov, tracks, order)?;
        let (dx, P, nis) = joint(&P, &Hd, nu, R, projection.as_ref().map(|T| (b0, T)))?;
        let full = match &self.full {
            Some(f) => Some(joint(f, &Hd, nu, R, None)?.1),
            None => None,
        };
        for (t, &k) in order.iter().enumerate() {
            let g = &mut *tracks[k].1;
            for r in 0..K {
                g.mean[r] += dx[t * K + r];
                for s in 0..K {
                    g.cov[(r, s)] = P[(t * K + r, t * K + s)];
                }
            }
        }
        for i in K..N {
            self.bias[i] += dx[b0 + i - K];
        }
        self.cov = P;
        if full.is_some() {
            self.full = full;
        }
        Ok(nis)
    }

    /// `cov` with the tracker's predicted `P_ii` in place of the bank's: each track's error
    /// taken as the bank's transformed by `A_i = L_c L_b⁻¹` (the Cholesky factors of the
    /// tracker's `P_ii` and of the bank's), so that its cross-covariances follow, `P_ij ← A_i
    /// P_ij A_jᵀ`, and the whole stays positive semi-definite however the tracker changed `P_ii`
    /// (an IMM's moment-matched prediction, a road update); where a factor fails, `P_ii` alone.
    fn with_tracks(
        &self,
        cov: &DMatrix<f64>,
        tracks: &Tracks<'_, K>,
        order: &[usize],
    ) -> Result<DMatrix<f64>> {
        let mut P = cov.clone();
        for (t, &k) in order.iter().enumerate() {
            let c = &tracks[k].1.cov;
            ensure_finite(c, "track covariance")?;
            let at = t * K;
            let own = P.view((at, at), (K, K)).into_owned();
            let own = SMatrix::<f64, K, K>::from_iterator(own.iter().copied());
            let a = c
                .cholesky()
                .zip(own.cholesky())
                .and_then(|(lc, lb)| Some(lc.l() * lb.l().try_inverse()?));
            if let Some(a) = a {
                let a = DMatrix::from_column_slice(K, K, a.as_slice());
                let rows = &a * P.rows(at, K);
                P.rows_mut(at, K).copy_from(&rows);
                let cols = P.columns(at, K) * a.transpose();
                P.columns_mut(at, K).copy_from(&cols);
            }
            for r in 0..K {
                for s in 0..K {
                    P[(at + r, at + s)] = c[(r, s)];
                }
            }
        }
        Ok((&P + P.transpose()) * 0.5)
    }

    /// A detection `z` of sensor `sensor` with the offsets and scales taken out, the bias
    /// uncertainty to add to its noise, and the time offset (see [`Corrected`]).
    pub fn correct(&self, sensor: usize, z: &[f64]) -> Result<Corrected> {
        let slots = self
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
        let cov = self.state().estimate.cov;
        let dim = slots.dim;
        let mut out = Vec::with_capacity(dim);
        // J: dim × N, ∂z'/∂b.
        let mut J = DMatrix::<f64>::zeros(dim, N);
        for (i, zi) in z.iter().enumerate() {
            let o = slots.offset[i].map_or(0.0, |s| self.bias[s]);
            let g = 1.0 + slots.scale[i].map_or(0.0, |s| self.bias[s]);
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
            .map_or((0.0, 0.0), |s| (self.bias[s], cov[(s, s)]));
        Ok(Corrected {
            z: out,
            extra_cov: (&extra + extra.transpose()) * 0.5,
            time_offset,
            time_offset_var,
        })
    }
}

/// One EKF update of `[x_1; …; x_T; b]` (covariance `P`, the stacked `Hd`) with the innovation
/// `nu` of noise `R`, with `projection = (b0, T)` the gain's bias rows (from `b0`) projected by
/// `T` (`K_b ← T K_b`): the correction, the covariance of that gain (the Joseph form
/// (5.2.3-18) expanded, `P − K H P − (K H P)ᵀ + K S Kᵀ`, exact for any gain) and the
/// normalised innovation squared.
fn joint(
    P: &DMatrix<f64>,
    Hd: &DMatrix<f64>,
    nu: &DVector<f64>,
    R: &DMatrix<f64>,
    projection: Option<(usize, &DMatrix<f64>)>,
) -> Result<(DVector<f64>, DMatrix<f64>, f64)> {
    let PHt = P * Hd.transpose();
    let S = Hd * &PHt + R;
    let S = (&S + S.transpose()) * 0.5;
    let Si = S
        .clone()
        .cholesky()
        .ok_or(EstimationError::NotPositiveDefinite(
            "innovation covariance",
        ))?
        .inverse();
    let mut Kd = &PHt * &Si;
    if let Some((b0, T)) = projection {
        let kb = T * Kd.rows(b0, T.nrows());
        Kd.rows_mut(b0, T.nrows()).copy_from(&kb);
    }
    let dx = &Kd * nu;
    let KHP = &Kd * PHt.transpose();
    let P = P - &KHP - KHP.transpose() + &Kd * &S * Kd.transpose();
    let P = (&P + P.transpose()) * 0.5;
    if !(dx.iter().all(|v| v.is_finite()) && P.iter().all(|v| v.is_finite())) {
        return Err(EstimationError::NonFinite("bias bank update"));
    }
    Ok((dx, P, (nu.transpose() * Si * nu)[0]))
}

#[cfg(test)]
#[path = "bank_tests.rs"]
mod tests;
