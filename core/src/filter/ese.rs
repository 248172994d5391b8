//! Error-space estimate method (ESE) of \[ESE\] §3.3: two Kalman filters working concurrently, one on
//! the *guide data* and one on the *guide error*, whose outputs are added to predict the next
//! measurement of an optical tracker.
//!
//! # Time indices
//!
//! `Z(k)` is the measurement at time `t_k`. For an equivalent generalised synergic target the guide
//! data of time k is the previous measurement, `L(k) = Z(k−1)` (\[ESE\] eq. (3)). After `Z(k)` has
//! been processed the method holds
//!
//! * filter 1 — the target kinematic model (eqs. (5)–(6)) run on the guide-data sequence `L(·)`:
//!   `x̂_L(k+1|k+1)`, its estimate after observing `L(k+1) = Z(k)`, so `L̂(k+1) = H x̂_L(k+1|k+1)`
//!   (step 4 of §3.3);
//! * filter 2 — the guide-error model (eqs. (11)–(12)) run on the guide errors
//!   `e(k) = Z(k) − L̂(k)` (eq. (13), `L̂(k)` being filter 1's estimate *before* `Z(k)` arrived):
//!   `x̂_e(k|k)`, whose one-step prediction is `ê(k+1|k) = H_e Φ_e x̂_e(k|k)` (step 3);
//!
//! and predicts the measurement at `t_{k+1}` as `Ẑ(k+1|k) = L̂(k+1) + ê(k+1|k)` (eq. (14), step 5).
//! Both filters advance by the measurement interval `t_k − t_{k−1}` at step k: the guide sequence is
//! the measurement sequence delayed by one sample, so its sample intervals are the same.
//!
//! `e(k)` is, up to filter 1's small lag, the increment `Z(k) − Z(k−1)`: it varies slowly even when
//! `Z` manoeuvres hard, which is why a CA model on it predicts much better than a CA model on `Z`
//! (the point of \[ESE\] §3.2).
//!
//! # Models of \[ESE\] §4
//!
//! The paper uses "the CA model" of its ref. [2] for both filters with process-noise std q and
//! measurement-noise std r. [`WienerAcceleration`](crate::motion::WienerAcceleration) is that model in the discrete Wiener-process
//! acceleration form (\[BLK01\] §6.3.3): `X(k) = Φ X(k−1) + Γ W(k−1)` with `Γ = [T²/2, T, 1]ᵀ` and
//! `W` the acceleration increment over one sample, std q (eq. (5) with this Γ). [`DirectPosition`](crate::measurement::DirectPosition)
//! is the observation eq. (6)/(12) with `H = [I 0 0]`. The paper gives q = r = 2·10⁻⁶ without
//! units; this reading of q (per-axis CA, T = 0.02 s) reproduces the independent reference figures
//! for the `zenith_pass` scenario — largest one-step azimuth prediction error ≈ 654 µrad (CA-KF),
//! 12.5 µrad (STF), 9.8 µrad (ESE); we measure 653.6, 12.49 and 9.77 µrad. The other readings
//! give, for KF / STF / ESE: continuous white jerk of density q² 4376 / 12.5 / 346 µrad; discrete
//! white jerk with `Γ = [T³/6, T²/2, T]ᵀ` 25604 / 12.5 / 6581 µrad; `Q = q² I` 731 / 12.6 / 13.5 µrad
//! (ESE worse than STF, contrary to the paper).
//!
//! # Start-up
//!
//! [`ErrorSpacePredictor`] starts each filter by polynomial differencing ([`difference_start`], the
//! three-point extension of the two-point differencing of \[BLK01\] §5.5): filter 1 from its first
//! three guide data `L(1..3) = Z(0..2)`, filter 2 from its first three guide errors `e(3..5)`. No
//! prior is guessed, so there is no start-up transient beyond the measurement noise. While filter 2
//! is starting, the prediction is filter 1's own `H Φ x̂_L` — exactly the CA-KF's eq. (8).
//!
//! # References
//! * \[ESE\] M. Cen, C. Fu, K. Chen, X. Liu, "Error-space estimate method for generalized synergic
//!   target tracking", Higher Education Press & Springer 2008, translated from *J. Univ. Electron.
//!   Sci. Technol. China* 36(2), 2007 (`shared/papers/004`).
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
#![allow(non_snake_case)]

use nalgebra::{SMatrix, SVector};

use super::kalman::Kalman;
use super::traits::{Predictor, Updater};
use crate::linalg::ensure_finite;
use crate::measurement::LinearMeasurement;
use crate::motion::LinearTransition;
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Starts a CA-layout state (`N = 3M`, blocks `[p; v; a]`) from three samples `z` at increasing
/// times `t` by fitting the quadratic through them: at `t[2]`
///
/// ```text
/// p = z₂,   v = f[t₁,t₂] + (t₂ − t₁)·f[t₀,t₁,t₂],   a = 2·f[t₀,t₁,t₂]
/// ```
///
/// (Newton divided differences; for equal steps T: `v = (3z₂ − 4z₁ + z₀)/2T`, `a = (z₂ − 2z₁ + z₀)/T²`).
/// Its covariance is that of the linear map `A` applied to independent noises of covariance `r`:
/// `P = (A Aᵀ) ⊗ r`. The three-point extension of \[BLK01\] §5.5's two-point differencing; exact
/// for noise-free constant-acceleration data.
pub fn difference_start<const N: usize, const M: usize>(
    t: [f64; 3],
    z: [SVector<f64, M>; 3],
    r: &SMatrix<f64, M, M>,
) -> Result<Gaussian<N>> {
    const { assert!(N == 3 * M, "CA layout: N = 3 M") };
    let (h1, h2) = (t[1] - t[0], t[2] - t[1]);
    if !(h1.is_finite() && h2.is_finite() && h1 > 0.0 && h2 > 0.0) {
        return Err(EstimationError::InvalidParameter(format!(
            "difference start needs strictly increasing times, got {t:?}"
        )));
    }
    // Rows: coefficients of (z₀, z₁, z₂) in p, v, a.
    let f12 = [0.0, -1.0 / h2, 1.0 / h2];
    let f012 = [1.0 / h1, -1.0 / h1 - 1.0 / h2, 1.0 / h2].map(|c| c / (h1 + h2));
    let a = SMatrix::<f64, 3, 3>::from_fn(|i, j| match i {
        0 => f64::from(u8::from(j == 2)),
        1 => f12[j] + h2 * f012[j],
        _ => 2.0 * f012[j],
    });
    let aat = a * a.transpose();
    let mut mean = SVector::<f64, N>::zeros();
    let mut cov = SMatrix::<f64, N, N>::zeros();
    for i in 0..3 {
        for c in 0..M {
            mean[i * M + c] = (0..3).map(|j| a[(i, j)] * z[j][c]).sum();
        }
        for j in 0..3 {
            for c in 0..M {
                for d in 0..M {
                    cov[(i * M + c, j * M + d)] = aat[(i, j)] * r[(c, d)];
                }
            }
        }
    }
    Gaussian::new(mean, cov)
}

/// Up to three timed samples for [`difference_start`]. A plain value: no allocation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DifferenceStart<const M: usize> {
    t: [f64; 3],
    z: [SVector<f64, M>; 3],
    len: usize,
}

impl<const M: usize> Default for DifferenceStart<M> {
    fn default() -> Self {
        Self {
            t: [0.0; 3],
            z: [SVector::zeros(); 3],
            len: 0,
        }
    }
}

impl<const M: usize> DifferenceStart<M> {
    /// Number of samples held (0..=3).
    pub fn len(&self) -> usize {
        self.len
    }
    /// Whether no sample is held yet.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// Adds a sample; once three are held the state at the last sample's time comes back (and the
    /// buffer is left full). Errors, leaving the buffer as it was, on a non-finite sample or a time
    /// that does not increase.
    pub fn push<const N: usize>(
        &mut self,
        t: f64,
        z: &SVector<f64, M>,
        r: &SMatrix<f64, M, M>,
    ) -> Result<Option<Gaussian<N>>> {
        ensure_finite(z, "start-up sample")?;
        if self.len >= 3 {
            return Err(EstimationError::InvalidParameter(
                "difference start already has its three samples".into(),
            ));
        }
        if !t.is_finite() || (self.len > 0 && t <= self.t[self.len - 1]) {
            return Err(EstimationError::InvalidParameter(format!(
                "start-up sample time {t} does not increase"
            )));
        }
        let mut next = *self;
        next.t[next.len] = t;
        next.z[next.len] = *z;
        next.len += 1;
        let out = if next.len == 3 {
            Some(difference_start(next.t, next.z, r)?)
        } else {
            None
        };
        *self = next;
        Ok(out)
    }
}

/// The two models of the ESE: the target kinematic model for filter 1 (\[ESE\] eqs. (5)–(6)) and the
/// guide-error model for filter 2 (eqs. (11)–(12)). \[ESE\] §4 uses the same CA model and the same
/// q, r for both.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSpace<T, H> {
    /// Φ, Γ, Q of eq. (5), used on the guide data.
    pub guide_motion: T,
    /// H, R of eq. (6).
    pub guide_measurement: H,
    /// Φ_e, Γ_e, Q_e of eq. (11), used on the guide errors.
    pub error_motion: T,
    /// H_e, R_e of eq. (12).
    pub error_measurement: H,
}

/// The running state of the ESE after the measurement `Z(k)` at time `t = t_k`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EseState<const N: usize> {
    /// `t_k`, time of the last measurement.
    pub t: f64,
    /// Filter 1: `x̂_L(k+1|k+1)`, after observing the guide datum `L(k+1) = Z(k)`.
    pub guide: Gaussian<N>,
    /// Filter 2: `x̂_e(k|k)`, after observing the guide error `e(k)`.
    pub error: Gaussian<N>,
}

impl<T, H> ErrorSpace<T, H> {
    /// The same model for both filters, as in \[ESE\] §4.
    pub fn symmetric(motion: T, measurement: H) -> Self
    where
        T: Clone,
        H: Clone,
    {
        Self {
            guide_motion: motion.clone(),
            guide_measurement: measurement.clone(),
            error_motion: motion,
            error_measurement: measurement,
        }
    }

    /// One ESE step with the measurement `z = Z(k)` at time `t = t_k > state.t`:
    ///
    /// 1. `e(k) = Z(k) ⊖ L̂(k)`, `L̂(k) = H x̂_L(k|k)` (eq. (13));
    /// 2. filter 2: KF predict over `t_k − t_{k−1}` with eq. (11), update with `e(k)` by eq. (12),
    ///    giving `x̂_e(k|k)` (step 3 of §3.3);
    /// 3. filter 1: KF predict over the guide interval (= `t_k − t_{k−1}`) with eq. (5), update with
    ///    `L(k+1) = Z(k)` (eq. (3)) by eq. (6), giving `x̂_L(k+1|k+1)` (step 4).
    ///
    /// Both KFs use the Joseph form. The input state is untouched on error.
    pub fn step<const N: usize, const M: usize>(
        &self,
        state: &EseState<N>,
        z: &SVector<f64, M>,
        t: f64,
    ) -> Result<EseState<N>>
    where
        T: LinearTransition<N>,
        H: LinearMeasurement<N, M>,
    {
        ensure_finite(z, "measurement")?;
        let dt = t - state.t;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "ESE measurement time {t} is not after {}",
                state.t
            )));
        }
        // eq. (13): e(k) = Z(k) − L̂(k).
        let l_hat = self.guide_measurement.matrix() * state.guide.mean;
        let e = self.guide_measurement.residual(z, &l_hat);
        // Filter 2, eqs. (11)–(12): x̂_e(k|k).
        let pe = Kalman.predict(&self.error_motion, &state.error, dt)?;
        let error = Kalman.update(&self.error_measurement, &pe, &e)?.state;
        // Filter 1, eqs. (5)–(6) with L(k+1) = Z(k) (eq. (3)): x̂_L(k+1|k+1).
        let pl = Kalman.predict(&self.guide_motion, &state.guide, dt)?;
        let guide = Kalman.update(&self.guide_measurement, &pl, z)?.state;
        Ok(EseState { t, guide, error })
    }

    /// `L̂(k+1) = H x̂_L(k+1|k+1)`: filter 1's estimate of the latest guide datum.
    pub fn guide_estimate<const N: usize, const M: usize>(
        &self,
        state: &EseState<N>,
    ) -> SVector<f64, M>
    where
        H: LinearMeasurement<N, M>,
    {
        self.guide_measurement.matrix() * state.guide.mean
    }

    /// The one-step prediction `Ẑ(k+1|k) = L̂(k+1) + ê(k+1|k)` (eq. (14)) for the measurement at
    /// `t_next > t_k`, with `ê(k+1|k) = H_e Φ_e(t_next − t_k) x̂_e(k|k)` (eqs. (11)–(12)). The sum
    /// is a plain one: wrap angle components afterwards.
    pub fn predict<const N: usize, const M: usize>(
        &self,
        state: &EseState<N>,
        t_next: f64,
    ) -> Result<SVector<f64, M>>
    where
        T: LinearTransition<N>,
        H: LinearMeasurement<N, M>,
    {
        let dt = t_next - state.t;
        if !dt.is_finite() {
            return Err(EstimationError::NonFinite("prediction interval"));
        }
        let e_pred =
            self.error_measurement.matrix() * (self.error_motion.matrix(dt) * state.error.mean);
        let z = self.guide_estimate(state) + e_pred;
        ensure_finite(&z, "ESE prediction")?;
        Ok(z)
    }
}

/// Where an [`ErrorSpacePredictor`] is in its start-up.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EseStage<const N: usize, const M: usize> {
    /// Collecting the first three guide data `L(1..3) = Z(0..2)` for filter 1.
    Guide(DifferenceStart<M>),
    /// Filter 1 runs (`guide` = `x̂_L(k+1|k+1)` after `Z(k)` at time `t`); collecting the first
    /// three guide errors for filter 2.
    Error {
        /// `t_k`.
        t: f64,
        /// Filter 1 state.
        guide: Gaussian<N>,
        /// Guide errors collected so far.
        start: DifferenceStart<M>,
    },
    /// Both filters run.
    Running(EseState<N>),
}

/// The ESE as a one-step-ahead measurement predictor, with its start-up (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorSpacePredictor<T, H, const N: usize, const M: usize> {
    /// The two models.
    pub models: ErrorSpace<T, H>,
    stage: EseStage<N, M>,
}

impl<T, H, const N: usize, const M: usize> ErrorSpacePredictor<T, H, N, M>
where
    T: LinearTransition<N>,
    H: LinearMeasurement<N, M>,
{
    /// A predictor that has seen no measurement yet.
    pub fn new(models: ErrorSpace<T, H>) -> Self {
        Self {
            models,
            stage: EseStage::Guide(DifferenceStart::default()),
        }
    }

    /// Start-up stage.
    pub fn stage(&self) -> &EseStage<N, M> {
        &self.stage
    }

    /// Processes `Z(k)` at time `t`. On error nothing changes.
    pub fn step(&mut self, z: &SVector<f64, M>, t: f64) -> Result<()> {
        let next = match self.stage {
            EseStage::Guide(mut start) => {
                // L(k+1) = Z(k): the first guide data start filter 1.
                let r = self.models.guide_measurement.covar();
                match start.push::<N>(t, z, &r)? {
                    Some(guide) => EseStage::Error {
                        t,
                        guide,
                        start: DifferenceStart::default(),
                    },
                    None => EseStage::Guide(start),
                }
            }
            EseStage::Error {
                t: t_prev,
                guide,
                mut start,
            } => {
                let dt = t - t_prev;
                if !(dt.is_finite() && dt > 0.0) {
                    return Err(EstimationError::InvalidParameter(format!(
                        "ESE measurement time {t} is not after {t_prev}"
                    )));
                }
                ensure_finite(z, "measurement")?;
                // eq. (13) with filter 1's L̂(k), then filter 1 takes L(k+1) = Z(k).
                let l_hat = self.models.guide_measurement.matrix() * guide.mean;
                let e = self.models.guide_measurement.residual(z, &l_hat);
                let pl = Kalman.predict(&self.models.guide_motion, &guide, dt)?;
                let guide = Kalman.update(&self.models.guide_measurement, &pl, z)?.state;
                let r = self.models.error_measurement.covar();
                match start.push::<N>(t, &e, &r)? {
                    Some(error) => EseStage::Running(EseState { t, guide, error }),
                    None => EseStage::Error { t, guide, start },
                }
            }
            EseStage::Running(s) => EseStage::Running(self.models.step(&s, z, t)?),
        };
        self.stage = next;
        Ok(())
    }

    /// One-step prediction of the measurement at `t_next`: eq. (14) once both filters run, filter 1's
    /// `H Φ x̂_L` (the CA-KF's eq. (8)) while filter 2 starts, `None` before filter 1 has started.
    pub fn predict(&self, t_next: f64) -> Result<Option<SVector<f64, M>>> {
        match &self.stage {
            EseStage::Guide(_) => Ok(None),
            EseStage::Error { t, guide, .. } => {
                let z = self.models.guide_measurement.matrix()
                    * (self.models.guide_motion.matrix(t_next - t) * guide.mean);
                ensure_finite(&z, "ESE prediction")?;
                Ok(Some(z))
            }
            EseStage::Running(s) => self.models.predict(s, t_next).map(Some),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::DirectPosition;
    use crate::motion::WienerAcceleration;
    use approx::assert_relative_eq;
    use nalgebra::{Vector1, Vector2, Vector3};
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};

    type Ese = ErrorSpacePredictor<WienerAcceleration<3>, DirectPosition<1>, 3, 1>;

    fn ese(q: f64, r: f64) -> Ese {
        ErrorSpacePredictor::new(ErrorSpace::symmetric(
            WienerAcceleration::new(q),
            DirectPosition::new([r]),
        ))
    }

    #[test]
    fn difference_start_is_exact_on_quadratics() {
        let p = |t: f64| 1.0 - 2.0 * t + 0.75 * t * t;
        let ts = [0.3, 0.5, 1.1]; // uneven steps
        let r = SMatrix::<f64, 1, 1>::new(1e-4);
        let g: Gaussian<3> = difference_start(ts, ts.map(|t| Vector1::new(p(t))), &r).unwrap();
        assert_relative_eq!(
            g.mean,
            Vector3::new(p(1.1), -2.0 + 1.5 * 1.1, 1.5),
            epsilon = 1e-12
        );
        // Equal steps T: var v = 6.5 r/T², var a = 6 r/T⁴, cov(p, v) = 1.5 r/T.
        let t = 0.1;
        let g: Gaussian<3> =
            difference_start([0.0, t, 2.0 * t], [Vector1::zeros(); 3], &r).unwrap();
        assert_relative_eq!(g.cov[(0, 0)], 1e-4);
        assert_relative_eq!(g.cov[(1, 1)], 6.5e-4 / (t * t), max_relative = 1e-12);
        assert_relative_eq!(g.cov[(2, 2)], 6e-4 / t.powi(4), max_relative = 1e-12);
        assert_relative_eq!(g.cov[(0, 1)], 1.5e-4 / t, max_relative = 1e-12);
        // Two axes share the time map.
        let r2 = SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(1.0, 4.0));
        let z = [
            Vector2::new(0.0, 0.0),
            Vector2::new(1.0, 2.0),
            Vector2::new(4.0, 8.0),
        ];
        let g: Gaussian<6> = difference_start([0.0, 1.0, 2.0], z, &r2).unwrap();
        assert_relative_eq!(
            g.mean,
            SVector::<f64, 6>::from_column_slice(&[4.0, 8.0, 4.0, 8.0, 2.0, 4.0])
        );
        assert_relative_eq!(g.cov[(5, 5)], 4.0 * 6.0);
        assert!(difference_start::<3, 1>([0.0, 0.0, 1.0], [Vector1::zeros(); 3], &r).is_err());
    }

    #[test]
    fn start_buffer_rejects_bad_samples_without_changing() {
        let r = SMatrix::<f64, 1, 1>::new(1.0);
        let mut s = DifferenceStart::<1>::default();
        assert!(s.push::<3>(0.0, &Vector1::new(1.0), &r).unwrap().is_none());
        let before = s;
        assert!(s.push::<3>(0.0, &Vector1::new(1.0), &r).is_err());
        assert!(s.push::<3>(1.0, &Vector1::new(f64::NAN), &r).is_err());
        assert_eq!(s, before);
        assert!(s.push::<3>(1.0, &Vector1::new(2.0), &r).unwrap().is_none());
        assert!(s.push::<3>(2.0, &Vector1::new(3.0), &r).unwrap().is_some());
        assert_eq!(s.len(), 3);
    }

    #[test]
    fn predicts_a_constant_acceleration_angle_exactly() {
        // Noise-free CA angle: both filters start exactly, innovations stay zero, and every
        // prediction (fallback and eq. (14)) is exact.
        let th = |t: f64| 0.3 + 0.02 * t - 0.004 * t * t;
        let dt = 0.02;
        let mut f = ese(2e-6, 2e-6);
        for k in 0..500 {
            let t = dt * f64::from(k);
            f.step(&Vector1::new(th(t)), t).unwrap();
            if let Some(z) = f.predict(t + dt).unwrap() {
                assert_relative_eq!(z[0], th(t + dt), epsilon = 1e-13);
            } else {
                assert!(k < 2);
            }
        }
        assert!(matches!(f.stage(), EseStage::Running(_)));
    }

    #[test]
    fn index_bookkeeping_matches_the_paper() {
        // Filter 1 is the CA-KF on Z (eq. (3)); e(k) = Z(k) − L̂(k) (eq. (13)) with L̂(k) filter 1's
        // estimate before Z(k); Ẑ(k+1|k) = L̂(k+1) + ê(k+1|k) (eq. (14)). Rebuild them by hand.
        let models = ErrorSpace::symmetric(
            WienerAcceleration::<3>::new(1e-3),
            DirectPosition::new([1e-2]),
        );
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = Normal::new(0.0, 1e-2).unwrap();
        let dt = 0.1;
        let zs: Vec<f64> = (0..40)
            .map(|k| (0.5 * dt * f64::from(k)).sin() + n.sample(&mut rng))
            .collect();
        let r = SMatrix::<f64, 1, 1>::new(1e-4);
        let t = |k: usize| dt * k as f64;
        // Filter 1 by hand: start from Z(0..2), then a plain KF on Z(3..).
        let mut l: Vec<Option<Gaussian<3>>> = vec![None; zs.len()];
        let mut g: Gaussian<3> = difference_start(
            [t(0), t(1), t(2)],
            [0, 1, 2].map(|k| Vector1::new(zs[k])),
            &r,
        )
        .unwrap();
        l[2] = Some(g);
        for k in 3..zs.len() {
            let p = Kalman.predict(&models.guide_motion, &g, dt).unwrap();
            g = Kalman
                .update(&models.guide_measurement, &p, &Vector1::new(zs[k]))
                .unwrap()
                .state;
            l[k] = Some(g); // x̂_L(k+1|k+1)
        }
        let l_hat = |k: usize| l[k - 1].unwrap().mean[0]; // L̂(k) = H x̂_L(k|k), stored at k−1
        // Filter 2 by hand on e(k) = Z(k) − L̂(k), k ≥ 3.
        let e = |k: usize| Vector1::new(zs[k] - l_hat(k));
        let mut x_e: Gaussian<3> =
            difference_start([t(3), t(4), t(5)], [e(3), e(4), e(5)], &r).unwrap();
        let mut f = ErrorSpacePredictor::new(models);
        for k in 0..zs.len() {
            f.step(&Vector1::new(zs[k]), t(k)).unwrap();
            if k > 5 {
                let p = Kalman.predict(&models.error_motion, &x_e, dt).unwrap();
                x_e = Kalman
                    .update(&models.error_measurement, &p, &e(k))
                    .unwrap()
                    .state;
            }
            let want = match k {
                0 | 1 => None,
                2..=4 => Some((models.guide_motion.matrix(dt) * l[k].unwrap().mean)[0]),
                _ => Some(l_hat(k + 1) + (models.error_motion.matrix(dt) * x_e.mean)[0]),
            };
            let got = f.predict(t(k + 1)).unwrap().map(|z| z[0]);
            match (got, want) {
                (Some(a), Some(b)) => assert_relative_eq!(a, b, epsilon = 1e-12),
                (a, b) => assert_eq!(a, b, "k = {k}"),
            }
        }
    }

    #[test]
    fn beats_the_kf_on_a_fast_angle_with_small_q() {
        // A zenith-pass-like azimuth: atan(v t / d), q = r tiny. The KF lags; the ESE does not.
        let (v, d, dt, r) = (200.0, 800.0, 0.02, 2e-6);
        let az = |t: f64| (v * (t - 20.0) / d).atan();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let n = Normal::new(0.0, r).unwrap();
        let model = WienerAcceleration::<3>::new(2e-6);
        let meas = DirectPosition::<1>::new([r]);
        let mut f = ese(2e-6, r);
        let mut kf: Option<Gaussian<3>> = None;
        let mut start = DifferenceStart::<1>::default();
        let (mut e_ese, mut e_kf) = (0.0f64, 0.0f64);
        for k in 0..2000 {
            let t = dt * f64::from(k);
            let z = Vector1::new(az(t) + n.sample(&mut rng));
            f.step(&z, t).unwrap();
            kf = match kf {
                None => start
                    .push::<3>(t, &z, &SMatrix::<f64, 1, 1>::new(r * r))
                    .unwrap(),
                Some(g) => {
                    let p = Kalman.predict(&model, &g, dt).unwrap();
                    Some(Kalman.update(&meas, &p, &z).unwrap().state)
                }
            };
            if t >= 1.0 {
                let zp = f.predict(t + dt).unwrap().unwrap()[0];
                let kp = (model.matrix(dt) * kf.unwrap().mean)[0];
                e_ese = e_ese.max((zp - az(t + dt)).abs());
                e_kf = e_kf.max((kp - az(t + dt)).abs());
            }
        }
        assert!(e_ese < 20.0 * r, "ESE max error {e_ese}");
        assert!(e_ese * 10.0 < e_kf, "ESE {e_ese} vs KF {e_kf}");
    }

    #[test]
    fn errors_leave_the_state_alone() {
        let mut f = ese(1e-3, 1e-2);
        for k in 0..10 {
            f.step(&Vector1::new(f64::from(k)), f64::from(k)).unwrap();
        }
        let before = f;
        assert!(f.step(&Vector1::new(1.0), 9.0).is_err());
        assert!(f.step(&Vector1::new(f64::INFINITY), 10.0).is_err());
        assert_eq!(f, before);
        assert_relative_eq!(f.predict(10.0).unwrap().unwrap()[0], 10.0, epsilon = 1e-9);
    }
}
