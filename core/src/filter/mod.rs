//! Filters: *how* a state is propagated through a model (Stone Soup's `Predictor` / `Updater`
//! roles). A filter is a small value (its tuning); the models are passed to each call, so one filter
//! serves sensors with different positions, kinds and rates.
//!
//! | filter | state | predictor needs | updater needs |
//! |---|---|---|---|
//! | [`Kalman`] | [`Gaussian`] | [`LinearTransition`] | [`LinearMeasurement`] |
//! | [`Extended`] | [`Gaussian`] | [`TransitionModel`] | [`MeasurementModel`] |
//! | [`CentralDifference`] | [`Gaussian`] | [`TransitionModel`] | [`MeasurementModel`] |
//!
//! [`Gaussian`]: crate::state::Gaussian
//! [`TransitionModel`]: crate::motion::TransitionModel
//! [`LinearTransition`]: crate::motion::LinearTransition
//! [`MeasurementModel`]: crate::measurement::MeasurementModel
//! [`LinearMeasurement`]: crate::measurement::LinearMeasurement

mod cdkf;
mod kalman;

pub use cdkf::CentralDifference;
pub use kalman::{Extended, Kalman, joseph_update};

use nalgebra::SVector;

use crate::Result;
use crate::state::Posterior;

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
