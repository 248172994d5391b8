//! Filters: *how* a state is propagated through a model (Stone Soup's `Predictor` / `Updater`
//! roles). A filter is a small value (its tuning); the models are passed to each call, so one filter
//! serves sensors with different positions, kinds and rates.
//!
//! | filter | state | predictor needs | updater needs |
//! |---|---|---|---|
//! | [`Kalman`] | [`Gaussian`] | [`LinearTransition`] | [`LinearMeasurement`] |
//! | [`Extended`] | [`Gaussian`] | [`TransitionModel`] | [`MeasurementModel`] |
//! | [`CentralDifference`] | [`Gaussian`] | [`TransitionModel`] | [`MeasurementModel`] |
//! | [`StrongTracking`] | [`StfState`] (Gaussian + `V_k`) | [`LinearTransition`] | [`LinearMeasurement`] (one combined step) |
//! | [`ErrorSpacePredictor`] | two [`Gaussian`]s (guide data, guide error) | [`LinearTransition`] | [`LinearMeasurement`] (predicts the next measurement) |
//! | [`IncrementalCdkf`] | [`Gaussian`] `[x_k; x_{k−1}]` | [`TransitionModel`] | [`MeasurementModel`] (increments) |
//! | [`Obe`] (set membership) | [`Ellipsoid`] | [`BoundedLinearTransition`] | [`BoundedLinearMeasurement`] |
//!
//! [`Gaussian`]: crate::state::Gaussian
//! [`Ellipsoid`]: crate::state::Ellipsoid
//! [`TransitionModel`]: crate::motion::TransitionModel
//! [`LinearTransition`]: crate::motion::LinearTransition
//! [`MeasurementModel`]: crate::measurement::MeasurementModel
//! [`LinearMeasurement`]: crate::measurement::LinearMeasurement

mod bias;
mod cdkf;
mod ese;
mod icdkf;
mod imm;
mod kalman;
pub mod mpekf;
pub mod nn;
mod obe;
mod stf;
mod traits;

pub use bias::{BiasAwareCdkf, BiasUpdate, BiasedMeasurement, WithBias};
pub use cdkf::CentralDifference;
pub use ese::{
    DifferenceStart, ErrorSpace, ErrorSpacePredictor, EseStage, EseState, difference_start,
};
pub use icdkf::{IcdkfForm, IncrementalCdkf, current};
pub(crate) use imm::log_normalize;
pub use imm::{Imm, ImmState, ModeModel, PROB_FLOOR};
pub use kalman::{Extended, Kalman, consider_update, joseph_update};
pub use obe::{
    BoundedLinearMeasurement, BoundedLinearTransition, Obe, ObeCriterion, intersect_strip,
    minkowski_outer,
};
pub use stf::{StfState, StfStep, StrongTracking};
pub use traits::{
    MeasurementPrediction, MeasurementPredictor, NonlinearFilter, Predictor, Updater,
};
