//! One mode of a [`BiasBank`](super::BiasBank): its prediction, its joint update with a
//! detection, the tracker's covariance changes carried into it, and the modes' mixture (the
//! module docs of `bank` give the form and the equations).
#![allow(non_snake_case)]

use nalgebra::{DMatrix, DVector, SMatrix, SVector};

use super::Mode;
use crate::linalg::ensure_finite;
use crate::motion::TransitionModel;
use crate::registration::filter::{Augmented, Observation, Registration, RegistrationState, Seen};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// One mode's update with a detection: its normalised innovation squared and log-likelihood,
/// and the updated track means and covariances (the bank's order).
pub(super) struct ModeUpdate<const K: usize> {
    pub(super) nis: f64,
    pub(super) log_likelihood: f64,
    pub(super) tracks: Vec<Gaussian<K>>,
}

impl<const K: usize, const N: usize> Mode<K, N> {
    /// Index of the bias block in `cov`.
    pub(super) fn b0(&self) -> usize {
        self.offset.len()
    }

    /// The bias terms' mean and covariance, as a registration state with a placeholder target
    /// (mean 0, identity covariance, uncorrelated).
    pub(super) fn state(&self) -> RegistrationState<N> {
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

    /// This mode under "no bias": every bias term pinned at its prior mean (variance 0,
    /// uncorrelated), the tracks as they are.
    pub(super) fn pinned(&self) -> Self {
        let mut out = self.clone();
        out.reg = self.reg.pinned();
        let b0 = self.b0();
        for i in K..N {
            if let Some(p) = self.reg.prior_of(i) {
                out.bias[i] = p.mean;
            }
            for cov in std::iter::once(&mut out.cov).chain(out.full.as_mut()) {
                cov.row_mut(b0 + i - K).fill(0.0);
                cov.column_mut(b0 + i - K).fill(0.0);
            }
        }
        out
    }

    /// The stacked mean `[offsets; b_K..N]` (the layout of `cov`).
    pub(super) fn stacked(&self) -> DVector<f64> {
        let b0 = self.b0();
        DVector::from_fn(b0 + N - K, |i, _| {
            if i < b0 {
                self.offset[i]
            } else {
                self.bias[K + i - b0]
            }
        })
    }

    /// The biases' dynamics over `dt > 0` seconds and the CV prediction of the tracks'
    /// covariances and offsets (`P ← F P Fᵀ + Q`).
    pub(super) fn predict(&mut self, dt: f64) {
        let model = Augmented { reg: &self.reg };
        let Fa = model.jacobian(&self.bias, dt);
        let Qa = model.covar(dt);
        self.bias = model.function(&self.bias, dt);
        self.bias.fixed_rows_mut::<K>(0).fill(0.0);
        let (b0, d) = (self.b0(), self.cov.nrows());
        let mut F = DMatrix::zeros(d, d);
        let mut Q = DMatrix::zeros(d, d);
        let blocks = (0..b0 / K).map(|t| (t * K, 0, K));
        for (at, from, n) in blocks.chain(std::iter::once((b0, K, N - K))) {
            for i in 0..n {
                for j in 0..n {
                    F[(at + i, at + j)] = Fa[(from + i, from + j)];
                    Q[(at + i, at + j)] = Qa[(from + i, from + j)];
                }
            }
        }
        self.offset = F.view((0, 0), (b0, b0)) * &self.offset;
        let predict = |P: &DMatrix<f64>| {
            let P = &F * P * F.transpose() + &Q;
            (&P + P.transpose()) * 0.5
        };
        if let Some(full) = self.full.take() {
            self.full = Some(predict(&full));
        }
        self.cov = predict(&self.cov);
    }

    /// The tracker's changes to the tracks' covariances since the bank's (an IMM's
    /// moment-matched prediction, a road update), carried into this mode: each track's rows and
    /// columns and its offset mapped by `maps` (see [`track_maps`]): `P_ij ← A_i P_ij A_jᵀ`,
    /// `δ_i ← A_i δ_i`, so that the modes' mixture has the tracker's covariances and the whole
    /// stays positive semi-definite; where a map failed, the tracker's `P_ii` alone.
    pub(super) fn follow(&mut self, tracks: &[Gaussian<K>], maps: &[Option<SMatrix<f64, K, K>>]) {
        for (t, (g, a)) in tracks.iter().zip(maps).enumerate() {
            let at = t * K;
            match a {
                Some(a) => {
                    let a = DMatrix::from_column_slice(K, K, a.as_slice());
                    let rows = &a * self.cov.rows(at, K);
                    self.cov.rows_mut(at, K).copy_from(&rows);
                    let cols = self.cov.columns(at, K) * a.transpose();
                    self.cov.columns_mut(at, K).copy_from(&cols);
                    let offset = &a * self.offset.rows(at, K);
                    self.offset.rows_mut(at, K).copy_from(&offset);
                }
                None => {
                    for r in 0..K {
                        for c in 0..K {
                            self.cov[(at + r, at + c)] = g.cov[(r, c)];
                        }
                    }
                }
            }
        }
        self.cov = (&self.cov + self.cov.transpose()) * 0.5;
    }

    /// The joint update with one detection (see the module docs) from the tracks `tracks` (the
    /// tracker's, in the bank's order) moved by this mode's offsets, `j` the detected track
    /// (none for a reference), `seen` what was seen; the mode keeps its new biases and
    /// covariances, and returns its track means (see [`ModeUpdate`]). With the hold, the gain's
    /// bias rows are projected onto the directions the data determine, as [`Registration`]'s (a
    /// Schmidt–Kalman consider update: the expanded Joseph form of [`joint`] is the covariance
    /// of any gain, so the other directions keep their prior and the tracks carry their
    /// uncertainty), and the full covariance takes the optimal update that says which
    /// directions are determined.
    pub(super) fn update(
        &mut self,
        tracks: &[Gaussian<K>],
        j: Option<usize>,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<ModeUpdate<K>> {
        let mine: Vec<Gaussian<K>> = tracks
            .iter()
            .enumerate()
            .map(|(t, g)| Gaussian {
                mean: g.mean + self.offset.fixed_rows::<K>(t * K),
                cov: self.cov.fixed_view::<K, K>(t * K, t * K).into_owned(),
            })
            .collect();
        let mut x = self.bias;
        if let Some(j) = j {
            x.fixed_rows_mut::<K>(0).copy_from(&mine[j].mean);
        }
        let (nu, H, R) = self.reg.linearised(&x, obs, seen)?;
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
        let up = joint(
            &self.cov,
            &Hd,
            &nu,
            &R,
            projection.as_ref().map(|T| (b0, T)),
        )?;
        let full = match &self.full {
            Some(f) => Some(joint(f, &Hd, &nu, &R, None)?.P),
            None => None,
        };
        let out = mine
            .iter()
            .enumerate()
            .map(|(t, g)| Gaussian {
                mean: g.mean + up.dx.fixed_rows::<K>(t * K),
                cov: SMatrix::<f64, K, K>::from_fn(|r, s| up.P[(t * K + r, t * K + s)]),
            })
            .collect();
        for i in K..N {
            self.bias[i] += up.dx[b0 + i - K];
        }
        self.cov = up.P;
        if full.is_some() {
            self.full = full;
        }
        Ok(ModeUpdate {
            nis: up.nis,
            log_likelihood: up.log_likelihood,
            tracks: out,
        })
    }
}

/// Per track (the bank's order), the map `A_i = L_c L_b⁻¹` of the Cholesky factors of the
/// tracker's `P_ii` (`tracks`) and of the bank's, the modes' mixture `Σ p_m (P_ii,m + δ_i,m
/// δ_i,mᵀ)` (`δ` the modes' offsets): the tracker's change to the track's covariance as a
/// change of its error, `e ← A_i e` ([`Mode::follow`]); `None` where a factor fails.
pub(super) fn track_maps<const K: usize, const N: usize>(
    modes: &[Mode<K, N>],
    probs: &[f64],
    tracks: &[Gaussian<K>],
) -> Result<Vec<Option<SMatrix<f64, K, K>>>> {
    tracks
        .iter()
        .enumerate()
        .map(|(t, g)| {
            ensure_finite(&g.cov, "track covariance")?;
            let at = t * K;
            let mut bank = SMatrix::<f64, K, K>::zeros();
            for (m, p) in modes.iter().zip(probs) {
                let d = m.offset.fixed_rows::<K>(at);
                bank += (m.cov.fixed_view::<K, K>(at, at) + d * d.transpose()) * *p;
            }
            Ok(g.cov
                .cholesky()
                .zip(bank.cholesky())
                .and_then(|(lc, lb)| Some(lc.l() * lb.l().try_inverse()?)))
        })
        .collect()
}

/// The modes `modes` weighed by `w`, moment-matched, as a mode of filter `reg`: the means
/// `[offsets; b]` and both covariances with the spread of the means (\[BLK01\] §11.6.6).
pub(super) fn mix<const K: usize, const N: usize>(
    modes: &[Mode<K, N>],
    w: &[f64],
    reg: &Registration<K, N>,
) -> Mode<K, N> {
    let means: Vec<DVector<f64>> = modes.iter().map(Mode::stacked).collect();
    let mut mean = DVector::zeros(means[0].len());
    for (m, wi) in means.iter().zip(w) {
        mean.axpy(*wi, m, 1.0);
    }
    let spread = |cov: &dyn Fn(&Mode<K, N>) -> &DMatrix<f64>| {
        let mut out = DMatrix::zeros(mean.len(), mean.len());
        for ((mode, m), wi) in modes.iter().zip(&means).zip(w) {
            let d = m - &mean;
            out += cov(mode) * *wi;
            out.ger(*wi, &d, &d, 1.0);
        }
        (&out + out.transpose()) * 0.5
    };
    let cov = spread(&|m| &m.cov);
    let full = modes[0]
        .full
        .is_some()
        .then(|| spread(&|m| m.full.as_ref().unwrap_or(&m.cov)));
    let b0 = modes[0].b0();
    let mut bias = SVector::<f64, N>::zeros();
    for i in K..N {
        bias[i] = mean[b0 + i - K];
    }
    Mode {
        reg: reg.clone(),
        bias,
        offset: mean.rows(0, b0).into_owned(),
        cov,
        full,
    }
}

/// One EKF update's outcome ([`joint`]).
struct Joint {
    dx: DVector<f64>,
    P: DMatrix<f64>,
    nis: f64,
    log_likelihood: f64,
}

/// One EKF update of `[x_1; …; x_T; b]` (covariance `P`, the stacked `Hd`) with the innovation
/// `nu` of noise `R`, with `projection = (b0, T)` the gain's bias rows (from `b0`) projected by
/// `T` (`K_b ← T K_b`): the correction, the covariance of that gain (the Joseph form
/// (5.2.3-18) expanded, `P − K H P − (K H P)ᵀ + K S Kᵀ`, exact for any gain), the normalised
/// innovation squared and the log-likelihood `log N(ν; 0, S)`.
fn joint(
    P: &DMatrix<f64>,
    Hd: &DMatrix<f64>,
    nu: &DVector<f64>,
    R: &DMatrix<f64>,
    projection: Option<(usize, &DMatrix<f64>)>,
) -> Result<Joint> {
    let PHt = P * Hd.transpose();
    let S = Hd * &PHt + R;
    let S = (&S + S.transpose()) * 0.5;
    let chol = S
        .clone()
        .cholesky()
        .ok_or(EstimationError::NotPositiveDefinite(
            "innovation covariance",
        ))?;
    let log_det = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
    let Si = chol.inverse();
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
    let nis = (nu.transpose() * Si * nu)[0];
    let log_likelihood =
        -0.5 * (nis + log_det + nu.len() as f64 * (2.0 * std::f64::consts::PI).ln());
    Ok(Joint {
        dx,
        P,
        nis,
        log_likelihood,
    })
}
