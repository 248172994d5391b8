//! The filter a track runs, behind one small trait ([`TrackFilter`]) so that the tracker does not
//! care whether a track is a single Gaussian filter ([`GaussianFilter`]: KF, EKF, CDKF, …) or a
//! mixture such as an IMM, which implements the trait on its own state type.

use nalgebra::{SMatrix, SVector};

use crate::Result;
use crate::filter::{Predictor, Updater};
use crate::measurement::MeasurementModel;
use crate::state::Gaussian;

/// Predicted measurement of a track: `ẑ` and the innovation covariance `S` (Stone Soup's
/// `MeasurementPrediction`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasurementPrediction<const M: usize> {
    /// Predicted measurement `ẑ`.
    pub zhat: SVector<f64, M>,
    /// Innovation covariance `S`.
    pub cov: SMatrix<f64, M, M>,
}

/// What the tracker needs from a track's filter: predict, predict the measurement (for gating and
/// association), update, and a Gaussian summary for output and deletion.
///
/// Implement it for an IMM with `State` = the mode-conditioned mixture: `start` spreads a Gaussian
/// over the modes, `predict_measurement` and `estimate` moment-match the mixture.
pub trait TrackFilter<const N: usize, const M: usize> {
    /// Per-track filter state.
    type State: Clone + std::fmt::Debug;
    /// Filter state of a new track from the initiator's Gaussian.
    fn start(&self, initial: Gaussian<N>) -> Result<Self::State>;
    /// Predicts `state` forward by `dt` seconds.
    fn predict(&self, state: &Self::State, dt: f64) -> Result<Self::State>;
    /// Predicted measurement of `predicted`. `probe` is one of the scan's detections; filters whose
    /// `ẑ` and `S` do not depend on the measurement may use it to get them from an update.
    fn predict_measurement(
        &self,
        predicted: &Self::State,
        probe: &SVector<f64, M>,
    ) -> Result<MeasurementPrediction<M>>;
    /// `z ⊖ ẑ` (angle components wrapped).
    fn residual(&self, z: &SVector<f64, M>, zhat: &SVector<f64, M>) -> SVector<f64, M>;
    /// Updates `predicted` with the detection `z`.
    fn update(&self, predicted: &Self::State, z: &SVector<f64, M>) -> Result<Self::State>;
    /// Gaussian summary of `state` (moment-matched for mixtures).
    fn estimate(&self, state: &Self::State) -> Gaussian<N>;
}

/// Any Gaussian filter `F` (implementing Stone Soup's [`Predictor`] and [`Updater`] roles) with its
/// transition model `T` and the sensor's measurement model `H`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GaussianFilter<F, T, H> {
    /// The filter (`Kalman`, `Extended`, `CentralDifference`, …).
    pub filter: F,
    /// Transition model.
    pub motion: T,
    /// Measurement model of the sensor.
    pub sensor: H,
}

impl<F, T, H, const N: usize, const M: usize> TrackFilter<N, M> for GaussianFilter<F, T, H>
where
    F: Predictor<T, N, State = Gaussian<N>> + Updater<H, N, M, State = Gaussian<N>>,
    H: MeasurementModel<N, M>,
{
    type State = Gaussian<N>;

    fn start(&self, initial: Gaussian<N>) -> Result<Gaussian<N>> {
        Ok(initial)
    }

    fn predict(&self, state: &Gaussian<N>, dt: f64) -> Result<Gaussian<N>> {
        self.filter.predict(&self.motion, state, dt)
    }

    /// For the KF, EKF and sigma-point filters `ẑ` and `S` depend on the predicted state only, so
    /// one update with the probe gives them: `S` from the posterior and `ẑ = z − ν`.
    fn predict_measurement(
        &self,
        predicted: &Gaussian<N>,
        probe: &SVector<f64, M>,
    ) -> Result<MeasurementPrediction<M>> {
        let post = self.filter.update(&self.sensor, predicted, probe)?;
        Ok(MeasurementPrediction {
            zhat: probe - post.innovation,
            cov: post.innovation_cov,
        })
    }

    fn residual(&self, z: &SVector<f64, M>, zhat: &SVector<f64, M>) -> SVector<f64, M> {
        self.sensor.residual(z, zhat)
    }

    fn update(&self, predicted: &Gaussian<N>, z: &SVector<f64, M>) -> Result<Gaussian<N>> {
        Ok(self.filter.update(&self.sensor, predicted, z)?.state)
    }

    fn estimate(&self, state: &Gaussian<N>) -> Gaussian<N> {
        *state
    }
}
