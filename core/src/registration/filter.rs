//! The registration filter: an EKF on the target's CV state augmented with every sensor's bias
//! terms, with Schmidt–Kalman "consider" updates for the terms the data do not determine yet
//! (the equations are in the [module docs](super)).
#![allow(non_snake_case)]

use nalgebra::{Cholesky, DMatrix, DVector, Dyn, Matrix3, SMatrix, SVector, Vector3};

use super::model::{BiasPrior, Dynamics, MAX_COMPONENTS, SensorBias, Term};
use crate::filter::{Extended, Predictor, consider_update, joseph_update};
use crate::linalg::{ensure_finite, symmetric_eigen, symmetrize};
use crate::measurement::{Locate, MeasurementModel, SensorModel, TargetSize, WithSensor};
use crate::motion::{ConstantVelocity, TransitionModel};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Where one sensor's bias terms sit in the state vector.
#[derive(Debug, Clone, PartialEq)]
pub struct SensorSlots {
    /// Number of measurement components of the sensor.
    pub dim: usize,
    /// State index of the offset of each component.
    pub offset: [Option<usize>; MAX_COMPONENTS],
    /// State index of the scale of each component.
    pub scale: [Option<usize>; MAX_COMPONENTS],
    /// State index of the time offset.
    pub time_offset: Option<usize>,
}

impl SensorSlots {
    /// Every term of the sensor with its state index, in state order.
    pub fn terms(&self) -> impl Iterator<Item = (Term, usize)> + '_ {
        let offsets = self.offset.iter().enumerate();
        let offsets = offsets.filter_map(|(i, s)| s.map(|s| (Term::Offset(i), s)));
        let scales = self.scale.iter().enumerate();
        let scales = scales.filter_map(|(i, s)| s.map(|s| (Term::Scale(i), s)));
        offsets
            .chain(scales)
            .chain(self.time_offset.map(|s| (Term::TimeOffset, s)))
    }
}

/// What a state component is.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Slot {
    /// Part of the target's CV state.
    Kinematic,
    /// A bias term with its model.
    Bias(BiasPrior),
    /// A bias term of a group the mode takes as unbiased ([`RegistrationImm`](super::RegistrationImm)'s
    /// "no bias" hypothesis): exactly its prior mean, never estimated; its column of `H` is zero
    /// and its variance a placeholder (1), as padding's.
    Pinned(BiasPrior),
    /// Padding up to the const size N: never observed, never estimated.
    Unused,
}

/// The registration filter's tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tuning {
    /// Observability threshold κ: a bias term (or a combination of terms) is determined by the
    /// data once the standard deviation a filter estimating every term would have is at most κ
    /// times its prior's.
    pub kappa: f64,
    /// Hold the bias directions that are not determined yet at their prior (Schmidt–Kalman
    /// consider updates); `false` estimates every term from the start (the plain augmented EKF).
    pub hold: bool,
}

impl Default for Tuning {
    /// κ = 0.3, hold.
    fn default() -> Self {
        Self {
            kappa: 0.3,
            hold: true,
        }
    }
}

/// The filter: the target's nearly-constant-velocity state (`K` = 4, planar `[x, y, vx, vy]` on
/// the plane `z = plane_z`, or `K` = 6, `[x, y, z, vx, vy, vz]`) followed by the bias terms of
/// every sensor, padded to the const size `N`.
#[derive(Debug, Clone, PartialEq)]
pub struct Registration<const K: usize, const N: usize> {
    motion: ConstantVelocity<K>,
    plane_z: f64,
    slots: [Slot; N],
    sensors: Vec<SensorSlots>,
    tuning: Tuning,
}

/// The filter's state: the estimate (mean and the true error covariance of the consider
/// updates) and `full_cov`, the covariance a filter that estimated every bias term from the
/// start would have — what the data determine, the measure of observability.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RegistrationState<const N: usize> {
    /// Mean and covariance of `[target; biases]`.
    pub estimate: Gaussian<N>,
    /// Covariance of the full augmented filter along the same linearisation points.
    pub full_cov: SMatrix<f64, N, N>,
    /// The gain projection of the updates of the current time (see
    /// [`Registration::update`]): computed at the first one, `None` after a prediction.
    pub projection: Option<SMatrix<f64, N, N>>,
}

/// A known object a sensor saw (a cooperative reference: a UAV reporting its own GPS position):
/// its position, velocity and the covariance of the position (ENU, m, m/s, m²).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KnownObject {
    /// Position.
    pub pos: Vector3<f64>,
    /// Velocity.
    pub vel: Vector3<f64>,
    /// Covariance of `pos`.
    pub cov: Matrix3<f64>,
}

/// What a detection is of.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Seen {
    /// The target being estimated.
    Target,
    /// A known object (cooperative reference): updates the biases only.
    Known(KnownObject),
}

/// One detection of one sensor.
#[derive(Debug, Clone, Copy)]
pub struct Observation<'a> {
    /// Index of the sensor (the order [`Registration::new`] was given).
    pub sensor: usize,
    /// The sensor's unbiased model at its platform's position, built with
    /// [`Geometry::spatial`](crate::measurement::Geometry::spatial) (the filter puts the target
    /// on the plane itself); `bearing_size` needs a known target size.
    pub model: &'a SensorModel,
    /// Velocity of the sensor's platform (ENU, m/s), for the time offset.
    pub platform_vel: Vector3<f64>,
    /// The measurement.
    pub z: &'a [f64],
}

/// The result of [`Registration::update`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Updated<const N: usize> {
    /// The new state.
    pub state: RegistrationState<N>,
    /// Normalised innovation squared of the detection.
    pub nis: f64,
    /// Gaussian log-likelihood `ln N(ν; 0, S)` of the detection.
    pub log_likelihood: f64,
}

/// A block of bias terms taken at its prior means ([`Registration::savage_dickey`]): the
/// Cholesky factor of its covariance `P_cc`, `a = P_cc⁻¹ (μ_c − x̂_c)`, the means `μ_c` and the
/// log of the Savage–Dickey ratio.
#[derive(Debug, Clone)]
pub(super) struct PinnedBlock {
    pub(super) chol: Cholesky<f64, Dyn>,
    pub(super) a: DVector<f64>,
    means: Vec<f64>,
    pub(super) log_bf: f64,
}

impl<const K: usize, const N: usize> Registration<K, N> {
    /// The filter for sensors `sensors` (each its number of measurement components and its bias
    /// model, `None` for an unbiased sensor), CV acceleration spectral density `q` (m²/s³),
    /// planar target height `plane_z` (for `K` = 4). Errors when the terms do not fit in `N`.
    pub fn new(
        q: f64,
        plane_z: f64,
        sensors: &[(usize, Option<&SensorBias>)],
        tuning: Tuning,
    ) -> Result<Self> {
        const { assert!((K == 4 || K == 6) && K <= N) };
        if !(q.is_finite() && q >= 0.0 && plane_z.is_finite()) {
            return Err(EstimationError::InvalidParameter(format!(
                "registration needs q ≥ 0 and a finite plane height, got q = {q}, plane_z = {plane_z}"
            )));
        }
        if !(tuning.kappa.is_finite() && tuning.kappa > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "observability threshold κ must be > 0, got {}",
                tuning.kappa
            )));
        }
        let mut slots = [Slot::Unused; N];
        slots[..K].fill(Slot::Kinematic);
        let mut next = K;
        let mut out = Vec::with_capacity(sensors.len());
        for &(dim, bias) in sensors {
            let mut s = SensorSlots {
                dim,
                offset: [None; MAX_COMPONENTS],
                scale: [None; MAX_COMPONENTS],
                time_offset: None,
            };
            if let Some(bias) = bias {
                bias.check(dim)?;
                for (term, prior) in bias.terms() {
                    if next == N {
                        return Err(EstimationError::InvalidParameter(format!(
                            "{} bias terms do not fit in a state of {N} ({K} kinematic)",
                            sensors
                                .iter()
                                .filter_map(|(_, b)| *b)
                                .map(|b| b.terms().count())
                                .sum::<usize>()
                        )));
                    }
                    match term {
                        Term::Offset(i) => s.offset[i] = Some(next),
                        Term::Scale(i) => s.scale[i] = Some(next),
                        Term::TimeOffset => s.time_offset = Some(next),
                    }
                    slots[next] = Slot::Bias(prior);
                    next += 1;
                }
            }
            out.push(s);
        }
        Ok(Self {
            motion: ConstantVelocity::new(q),
            plane_z,
            slots,
            sensors: out,
            tuning,
        })
    }

    /// This filter with every random-walk term drifting `factor` times faster (its drift
    /// intensity times `factor`), the other terms as they are.
    pub fn with_drift_factor(&self, factor: f64) -> Self {
        let mut out = self.clone();
        for slot in &mut out.slots {
            if let Slot::Bias(p) = slot {
                if let Dynamics::RandomWalk { drift } = p.dynamics {
                    p.dynamics = Dynamics::RandomWalk {
                        drift: drift * factor,
                    };
                }
            }
        }
        out
    }

    /// This filter under the "no bias" hypothesis: every bias term pinned at its prior mean
    /// (neither estimated nor uncertain; [`RegistrationImm`](super::RegistrationImm)'s first
    /// mode).
    pub(super) fn pinned(&self) -> Self {
        let mut out = self.clone();
        for slot in &mut out.slots {
            if let Slot::Bias(p) = *slot {
                *slot = Slot::Pinned(p);
            }
        }
        out
    }

    /// `state` with every bias term of this filter at its prior mean exactly (variance 0,
    /// uncorrelated), in the estimate and in the full covariance; a pinned term at its mean with
    /// the placeholder variance 1. The target's part stays.
    pub(super) fn reset_biases(&self, state: &RegistrationState<N>) -> RegistrationState<N> {
        let mut out = *state;
        for (i, slot) in self.slots.iter().enumerate() {
            let (mean, var) = match slot {
                Slot::Bias(p) => (p.mean, 0.0),
                Slot::Pinned(p) => (p.mean, 1.0),
                Slot::Kinematic | Slot::Unused => continue,
            };
            out.estimate.mean[i] = mean;
            for cov in [&mut out.estimate.cov, &mut out.full_cov] {
                cov.row_mut(i).fill(0.0);
                cov.column_mut(i).fill(0.0);
                cov[(i, i)] = var;
            }
        }
        out.projection = None;
        out
    }

    /// `state` conditioned on the bias terms at state indices `pinned` being exactly at their
    /// prior means `μ_c` (the sensors they belong to taken as unbiased), with the log of the
    /// Savage–Dickey ratio, the Bayes factor of that nested hypothesis against the free terms
    /// (Dickey 1971; Verdinelli & Wasserman 1995):
    ///
    /// ```text
    /// log B = log N(μ_c; x̂_c, P_cc) − log N(μ_c; μ_c, Σ_c)        (Σ_c: the prior variances)
    /// x̂' = x̂ + P_·c P_cc⁻¹ (μ_c − x̂_c),   P' = P − P_·c P_cc⁻¹ P_c·   (the joint Gaussian's conditional)
    /// ```
    ///
    /// The pinned terms end exactly at `μ_c` with variance 0 (the full covariance is left as it
    /// is). `None` when `P_cc` is not positive definite or an index is not a bias term.
    pub(super) fn given_prior(
        &self,
        state: &RegistrationState<N>,
        pinned: &[usize],
    ) -> Option<(RegistrationState<N>, f64)> {
        if pinned.is_empty() {
            return Some((*state, 0.0));
        }
        let block = self.savage_dickey(state, pinned)?;
        Some((self.conditioned(state, pinned, &block), block.log_bf))
    }

    /// The Savage–Dickey ratio of [`Registration::given_prior`] alone, with what its
    /// conditioning needs. `None` as there.
    pub(super) fn savage_dickey(
        &self,
        state: &RegistrationState<N>,
        pinned: &[usize],
    ) -> Option<PinnedBlock> {
        let priors: Vec<BiasPrior> = pinned
            .iter()
            .map(|&i| self.prior_of(i))
            .collect::<Option<_>>()?;
        let (x, P) = (&state.estimate.mean, &state.estimate.cov);
        let k = pinned.len();
        let Pcc = DMatrix::from_fn(k, k, |i, j| P[(pinned[i], pinned[j])]);
        let chol = Pcc.cholesky()?;
        let r = DVector::from_fn(k, |i, _| priors[i].mean - x[pinned[i]]);
        let a = chol.solve(&r);
        let log_det = 2.0 * chol.l().diagonal().iter().map(|v| v.ln()).sum::<f64>();
        let log_prior_det: f64 = priors.iter().map(|p| (p.std * p.std).ln()).sum();
        let log_bf = -0.5 * r.dot(&a) - 0.5 * log_det + 0.5 * log_prior_det;
        log_bf.is_finite().then_some(PinnedBlock {
            chol,
            a,
            means: priors.iter().map(|p| p.mean).collect(),
            log_bf,
        })
    }

    /// `state` conditioned on the block `pinned` at its prior means ([`Registration::given_prior`]),
    /// `block` its [`Registration::savage_dickey`].
    pub(super) fn conditioned(
        &self,
        state: &RegistrationState<N>,
        pinned: &[usize],
        block: &PinnedBlock,
    ) -> RegistrationState<N> {
        let P = &state.estimate.cov;
        let k = pinned.len();
        let Pnc = DMatrix::from_fn(N, k, |i, j| P[(i, pinned[j])]);
        let gain = block.chol.solve(&Pnc.transpose()).transpose();
        let mut out = *state;
        let shift = &Pnc * &block.a;
        let drop = &gain * Pnc.transpose();
        for i in 0..N {
            out.estimate.mean[i] += shift[i];
            for j in 0..N {
                out.estimate.cov[(i, j)] -= drop[(i, j)];
            }
        }
        for (&i, &mean) in pinned.iter().zip(&block.means) {
            out.estimate.mean[i] = mean;
            out.estimate.cov.row_mut(i).fill(0.0);
            out.estimate.cov.column_mut(i).fill(0.0);
        }
        out.estimate.cov = symmetrize(&out.estimate.cov);
        out.projection = None;
        out
    }

    /// Where each sensor's terms are, in the order of [`Registration::new`].
    pub fn sensors(&self) -> &[SensorSlots] {
        &self.sensors
    }

    /// The tuning.
    pub fn tuning(&self) -> Tuning {
        self.tuning
    }

    /// The model of the bias term at state index `i`, if it is one.
    pub fn prior_of(&self, i: usize) -> Option<BiasPrior> {
        match self.slots.get(i) {
            Some(Slot::Bias(p)) => Some(*p),
            _ => None,
        }
    }

    /// The initial state: the target's prior `kinematic`, each bias term at its prior, the two
    /// covariances equal.
    pub fn initial(&self, kinematic: &Gaussian<K>) -> Result<RegistrationState<N>> {
        let mut mean = SVector::<f64, N>::zeros();
        let mut cov = SMatrix::<f64, N, N>::zeros();
        mean.fixed_rows_mut::<K>(0).copy_from(&kinematic.mean);
        cov.fixed_view_mut::<K, K>(0, 0).copy_from(&kinematic.cov);
        for (i, slot) in self.slots.iter().enumerate().skip(K) {
            let (m, var) = match slot {
                Slot::Bias(p) => (p.mean, p.std * p.std),
                Slot::Pinned(p) => (p.mean, 1.0),
                Slot::Kinematic | Slot::Unused => (0.0, 1.0),
            };
            mean[i] = m;
            cov[(i, i)] = var;
        }
        let estimate = Gaussian::new(mean, cov)?;
        Ok(RegistrationState {
            estimate,
            full_cov: cov,
            projection: None,
        })
    }

    /// The target's part of a state.
    pub fn kinematic(&self, state: &RegistrationState<N>) -> Gaussian<K> {
        Gaussian {
            mean: state.estimate.mean.fixed_rows::<K>(0).into_owned(),
            cov: state.estimate.cov.fixed_view::<K, K>(0, 0).into_owned(),
        }
    }

    /// Whether the bias term at state index `i` is determined by the data on its own (is
    /// observable): `full_cov[i][i] ≤ κ² σ_prior²`.
    pub fn determined(&self, state: &RegistrationState<N>, i: usize) -> bool {
        match self.slots.get(i) {
            Some(Slot::Bias(p)) => {
                state.full_cov[(i, i)] <= self.tuning.kappa.powi(2) * p.std * p.std
            }
            _ => false,
        }
    }

    /// The projection `T` of the optimal gain (`K = T K_opt`, [`consider_update`]): the target is
    /// always estimated; of the bias terms, only the directions the data determine — the
    /// eigenvectors of the normalised full covariance `C = D^{-1/2} P_f,bb D^{-1/2}` (`D` the
    /// prior variances) whose eigenvalue is at most κ², so that a combination the data know
    /// (a camera's azimuth offset with its latency, a radar's range offset with its scale) is
    /// estimated while each term alone may not be; `T_bb = D^{1/2} V_o V_oᵀ D^{-1/2}`. Every
    /// bias direction when the tuning does not hold; padding never.
    pub(super) fn gain_projection(&self, state: &RegistrationState<N>) -> SMatrix<f64, N, N> {
        let mut T = SMatrix::<f64, N, N>::zeros();
        let sd: [Option<f64>; N] = std::array::from_fn(|i| match self.slots[i] {
            Slot::Bias(p) => Some(p.std),
            Slot::Kinematic | Slot::Pinned(_) | Slot::Unused => None,
        });
        for (i, slot) in self.slots.iter().enumerate() {
            let keep = match slot {
                Slot::Kinematic => true,
                Slot::Bias(_) => !self.tuning.hold,
                Slot::Pinned(_) | Slot::Unused => false,
            };
            T[(i, i)] = if keep { 1.0 } else { 0.0 };
        }
        if !self.tuning.hold {
            return T;
        }
        // Components that are not bias terms get an eigenvalue far above κ², alone.
        const APART: f64 = 1e6;
        let C = SMatrix::<f64, N, N>::from_fn(|i, j| match (sd[i], sd[j]) {
            (Some(a), Some(b)) => state.full_cov[(i, j)] / (a * b),
            _ if i == j => APART,
            _ => 0.0,
        });
        let (values, vectors) = symmetric_eigen(&C);
        let k2 = self.tuning.kappa * self.tuning.kappa;
        let mut Vo = SMatrix::<f64, N, N>::zeros();
        for (c, &l) in values.iter().enumerate() {
            if l <= k2 {
                let v = vectors.column(c);
                Vo += v * v.transpose();
            }
        }
        for i in 0..N {
            for j in 0..N {
                if let (Some(a), Some(b)) = (sd[i], sd[j]) {
                    T[(i, j)] = a * Vo[(i, j)] / b;
                }
            }
        }
        T
    }

    /// Predicts both covariances and the mean `dt ≥ 0` seconds ahead: CV for the target, each
    /// term's [`Dynamics`](super::Dynamics) for the biases.
    pub fn predict(&self, state: &RegistrationState<N>, dt: f64) -> Result<RegistrationState<N>> {
        if !(dt.is_finite() && dt >= 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "prediction interval must be finite and ≥ 0, got {dt}"
            )));
        }
        if dt == 0.0 {
            return Ok(*state);
        }
        let model = Augmented { reg: self };
        let estimate = Extended.predict(&model, &state.estimate, dt)?;
        let full = Gaussian {
            mean: state.estimate.mean,
            cov: state.full_cov,
        };
        let full_cov = Extended.predict(&model, &full, dt)?.cov;
        Ok(RegistrationState {
            estimate,
            full_cov,
            projection: None,
        })
    }

    /// Updates the state with one detection of `seen` (the target, or a known object whose
    /// detection updates only the biases — and, through their correlation, the target). The
    /// bias directions it estimates are those determined before the first update of the time
    /// (the gain projection is computed once per time and kept in the state until the next
    /// prediction), so the detections of one scan are weighed alike.
    pub fn update(
        &self,
        state: &RegistrationState<N>,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<Updated<N>> {
        let slots = self.check(obs, seen)?;
        obs.model.apply(Update {
            reg: self,
            state,
            slots,
            obs,
            seen,
        })
    }

    /// The sensor's slots, after checking the detection against them.
    fn check(&self, obs: &Observation<'_>, seen: &Seen) -> Result<&SensorSlots> {
        let slots = self.sensors.get(obs.sensor).ok_or_else(|| {
            EstimationError::InvalidParameter(format!("no sensor {}", obs.sensor))
        })?;
        if obs.model.dim() != slots.dim || obs.z.len() != slots.dim {
            return Err(EstimationError::InvalidParameter(format!(
                "sensor {} has {} components, its model {} and the measurement {}",
                obs.sensor,
                slots.dim,
                obs.model.dim(),
                obs.z.len()
            )));
        }
        if let SensorModel::BearingSize(b) = obs.model {
            if !matches!(b.size(), TargetSize::Known(_)) {
                return Err(EstimationError::InvalidParameter(
                    "registration needs bearing_size models with a known target size".into(),
                ));
            }
        }
        ensure_finite(&obs.platform_vel, "platform velocity")?;
        if let Seen::Known(k) = seen {
            ensure_finite(&k.pos, "reference position")?;
            ensure_finite(&k.vel, "reference velocity")?;
            ensure_finite(&k.cov, "reference covariance")?;
        }
        Ok(slots)
    }

    /// The innovation `ν = z ⊖ ẑ`, the Jacobian `H` (M × N) and the noise `R` of one detection
    /// at the state vector `x`, in dynamic sizes (for the [`BiasBank`](super::BiasBank)).
    pub(super) fn linearised(
        &self,
        x: &SVector<f64, N>,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<(DVector<f64>, DMatrix<f64>, DMatrix<f64>)> {
        let slots = self.check(obs, seen)?;
        obs.model.apply(Linearised {
            reg: self,
            x,
            slots,
            obs,
            seen,
        })
    }

    /// Target position and velocity (3-D) in a state vector.
    fn target(&self, x: &SVector<f64, N>) -> (Vector3<f64>, Vector3<f64>) {
        if K == 4 {
            (
                Vector3::new(x[0], x[1], self.plane_z),
                Vector3::new(x[2], x[3], 0.0),
            )
        } else {
            (
                Vector3::new(x[0], x[1], x[2]),
                Vector3::new(x[3], x[4], x[5]),
            )
        }
    }

    /// The biased measurement model at `x`: innovation `ν = z ⊖ ẑ`, Jacobian `H` (M × N) and
    /// noise covariance `R` (see the module docs).
    fn linearise<H: MeasurementModel<6, M>, const M: usize>(
        &self,
        model: &H,
        x: &SVector<f64, N>,
        slots: &SensorSlots,
        obs: &Observation<'_>,
        seen: &Seen,
    ) -> Result<(SVector<f64, M>, SMatrix<f64, M, N>, SMatrix<f64, M, M>)> {
        let (p, v) = match seen {
            Seen::Target => self.target(x),
            Seen::Known(k) => (k.pos, k.vel),
        };
        let delta = slots.time_offset.map_or(0.0, |i| x[i]);
        let vrel = v - obs.platform_vel;
        // The world at t − δ: p − δ (v − v_platform), to first order.
        let shifted = p - vrel * delta;
        let x6 =
            SVector::<f64, 6>::from_column_slice(&[shifted.x, shifted.y, shifted.z, 0.0, 0.0, 0.0]);
        let h0 = model.function(&x6);
        let Hp: SMatrix<f64, M, 3> = model.jacobian(&x6).fixed_columns::<3>(0).into_owned();
        // g_i = 1 + s_i
        let g = SVector::<f64, M>::from_fn(|i, _| 1.0 + slots.scale[i].map_or(0.0, |s| x[s]));
        let mut zhat = g.component_mul(&h0);
        let gHp = SMatrix::<f64, M, M>::from_diagonal(&g) * Hp;
        let mut H = SMatrix::<f64, M, N>::zeros();
        if matches!(seen, Seen::Target) {
            let d = K / 2;
            for c in 0..d {
                H.set_column(c, &gHp.column(c));
                H.set_column(d + c, &(gHp.column(c) * -delta));
            }
        }
        for i in 0..M {
            if let Some(s) = slots.offset[i] {
                zhat[i] += x[s];
                H[(i, s)] = 1.0;
            }
            if let Some(s) = slots.scale[i] {
                H[(i, s)] = h0[i];
            }
        }
        if let Some(s) = slots.time_offset {
            H.set_column(s, &(gHp * -vrel));
        }
        // A pinned term is its prior mean exactly: in ẑ, not in H.
        for (c, slot) in self.slots.iter().enumerate() {
            if matches!(slot, Slot::Pinned(_)) {
                H.column_mut(c).fill(0.0);
            }
        }
        let mut R = model.covar();
        if let Seen::Known(k) = seen {
            R += gHp * k.cov * gHp.transpose();
        }
        let z = SVector::<f64, M>::from_column_slice(obs.z);
        Ok((model.residual(&z, &zhat), H, R))
    }
}

/// The visit of [`Registration::update`] with the concrete model.
struct Update<'a, const K: usize, const N: usize> {
    reg: &'a Registration<K, N>,
    state: &'a RegistrationState<N>,
    slots: &'a SensorSlots,
    obs: &'a Observation<'a>,
    seen: &'a Seen,
}

impl<const K: usize, const N: usize> WithSensor<6> for Update<'_, K, N> {
    type Output = Result<Updated<N>>;
    fn with<H, const M: usize>(self, model: &H) -> Self::Output
    where
        H: MeasurementModel<6, M> + Locate<M>,
    {
        let x = &self.state.estimate.mean;
        let (nu, Hx, R) = self
            .reg
            .linearise(model, x, self.slots, self.obs, self.seen)?;
        let T = match self.state.projection {
            Some(T) => T,
            None => self.reg.gain_projection(self.state),
        };
        let post = consider_update(&self.state.estimate, nu, &Hx, &R, &T)?;
        let full = Gaussian {
            mean: *x,
            cov: self.state.full_cov,
        };
        let full_cov = joseph_update(&full, nu, &Hx, &R)?.state.cov;
        Ok(Updated {
            nis: post.nis()?,
            log_likelihood: post.log_likelihood()?,
            state: RegistrationState {
                estimate: post.state,
                full_cov,
                projection: Some(T),
            },
        })
    }
}

/// The visit of [`Registration::linearised`] with the concrete model.
struct Linearised<'a, const K: usize, const N: usize> {
    reg: &'a Registration<K, N>,
    x: &'a SVector<f64, N>,
    slots: &'a SensorSlots,
    obs: &'a Observation<'a>,
    seen: &'a Seen,
}

impl<const K: usize, const N: usize> WithSensor<6> for Linearised<'_, K, N> {
    type Output = Result<(DVector<f64>, DMatrix<f64>, DMatrix<f64>)>;
    fn with<H, const M: usize>(self, model: &H) -> Self::Output
    where
        H: MeasurementModel<6, M> + Locate<M>,
    {
        let (nu, Hx, R) = self
            .reg
            .linearise(model, self.x, self.slots, self.obs, self.seen)?;
        Ok((
            DVector::from_column_slice(nu.as_slice()),
            DMatrix::from_column_slice(M, N, Hx.as_slice()),
            DMatrix::from_column_slice(M, M, R.as_slice()),
        ))
    }
}

/// The augmented transition: CV for the target, each bias term's dynamics, padding unchanged.
pub(super) struct Augmented<'a, const K: usize, const N: usize> {
    pub reg: &'a Registration<K, N>,
}

impl<const K: usize, const N: usize> TransitionModel<N> for Augmented<'_, K, N> {
    fn function(&self, x: &SVector<f64, N>, dt: f64) -> SVector<f64, N> {
        let mut y = *x;
        y.fixed_rows_mut::<K>(0).copy_from(
            &self
                .reg
                .motion
                .function(&x.fixed_rows::<K>(0).into_owned(), dt),
        );
        for (i, slot) in self.reg.slots.iter().enumerate() {
            if let Slot::Bias(p) = slot {
                // b − μ = φ (b − μ)
                y[i] = p.mean + p.transition(dt).0 * (x[i] - p.mean);
            }
        }
        y
    }
    fn jacobian(&self, x: &SVector<f64, N>, dt: f64) -> SMatrix<f64, N, N> {
        let mut F = SMatrix::<f64, N, N>::identity();
        F.fixed_view_mut::<K, K>(0, 0).copy_from(
            &self
                .reg
                .motion
                .jacobian(&x.fixed_rows::<K>(0).into_owned(), dt),
        );
        for (i, slot) in self.reg.slots.iter().enumerate() {
            if let Slot::Bias(p) = slot {
                F[(i, i)] = p.transition(dt).0;
            }
        }
        F
    }
    fn covar(&self, dt: f64) -> SMatrix<f64, N, N> {
        let mut Q = SMatrix::<f64, N, N>::zeros();
        Q.fixed_view_mut::<K, K>(0, 0)
            .copy_from(&TransitionModel::<K>::covar(&self.reg.motion, dt));
        for (i, slot) in self.reg.slots.iter().enumerate() {
            if let Slot::Bias(p) = slot {
                Q[(i, i)] = p.transition(dt).1;
            }
        }
        Q
    }
}

#[cfg(test)]
#[path = "filter_tests.rs"]
mod tests;
