//! The roles every filter plays (Stone Soup's `Predictor`, `Updater` and `MeasurementPredictor`),
//! the [`MeasurementPrediction`] they share, and [`NonlinearFilter`] for the Gaussian filters that
//! take every measurement model.

use nalgebra::{SMatrix, SVector};

use crate::Result;
use crate::measurement::MeasurementModel;
use crate::state::{Gaussian, Posterior};

/// Time update: propagates a state through a transition model `T` over `dt` seconds.
pub trait Predictor<T, const N: usize> {
    /// State representation (Gaussian, ellipsoid, …).
    type State;
    /// Predicts `prior` forward by `dt` seconds. The prior is left untouched on error.
    fn predict(&self, model: &T, prior: &Self::State, dt: f64) -> Result<Self::State>;
}

/// Measurement update with a model `H` producing M-dimensional measurements.
pub trait Updater<H, const N: usize, const M: usize> {
    /// State representation.
    type State;
    /// Updates `predicted` with measurement `z`, returning the posterior with its innovation.
    fn update(
        &self,
        model: &H,
        predicted: &Self::State,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Self::State, M>>;
}

/// Predicted measurement of a state: `ẑ` and the innovation covariance `S` (Stone Soup's
/// `MeasurementPrediction`): what gating and association need before any detection is used.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasurementPrediction<const M: usize> {
    /// Predicted measurement `ẑ`.
    pub zhat: SVector<f64, M>,
    /// Innovation covariance `S = cov(z − ẑ)`, measurement noise included.
    pub cov: SMatrix<f64, M, M>,
}

/// Measurement prediction with a model `H` (Stone Soup's `MeasurementPredictor` role).
pub trait MeasurementPredictor<H, const N: usize, const M: usize> {
    /// State representation.
    type State;
    /// `ẑ` and `S` of `predicted` under `model`. The state is not changed.
    fn predict_measurement(
        &self,
        model: &H,
        predicted: &Self::State,
    ) -> Result<MeasurementPrediction<M>>;
}

/// A Gaussian filter that works with every [`MeasurementModel`] (the EKF and the sigma-point
/// filters, not the linear KF): what a tracker needs when each scan brings its own sensor kind.
/// Its methods are generic over the model, so one filter value serves every sensor.
pub trait NonlinearFilter<const N: usize> {
    /// [`Updater::update`] for any model.
    fn update_with<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
        z: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N>, M>>;
    /// [`MeasurementPredictor::predict_measurement`] for any model.
    fn predict_measurement_with<H: MeasurementModel<N, M>, const M: usize>(
        &self,
        model: &H,
        predicted: &Gaussian<N>,
    ) -> Result<MeasurementPrediction<M>>;
}

/// [`NonlinearFilter`] for filters whose [`Updater`] and [`MeasurementPredictor`] take every
/// [`MeasurementModel`].
macro_rules! nonlinear_filter {
    ($($filter:ty),*) => {$(
        impl<const N: usize> NonlinearFilter<N> for $filter {
            fn update_with<H: MeasurementModel<N, M>, const M: usize>(
                &self,
                model: &H,
                predicted: &Gaussian<N>,
                z: &SVector<f64, M>,
            ) -> Result<Posterior<Gaussian<N>, M>> {
                self.update(model, predicted, z)
            }
            fn predict_measurement_with<H: MeasurementModel<N, M>, const M: usize>(
                &self,
                model: &H,
                predicted: &Gaussian<N>,
            ) -> Result<MeasurementPrediction<M>> {
                self.predict_measurement(model, predicted)
            }
        }
    )*};
}
pub(super) use nonlinear_filter;
