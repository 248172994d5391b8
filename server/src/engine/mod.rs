//! The engine's interface: what an estimator looks like once its filter types are erased, in its
//! two shapes.
//!
//! - [`replay`]: every estimator Harrier can run by name over a scenario implements
//!   [`ReplayEstimator`] and is described by an [`EstimatorInfo`]. A `Box<dyn ReplayEstimator>` is
//!   the only form in which the offline tools (`replay`, `guidance-sim`) see a filter.
//! - [`track`]: the live service's multi-target tracker, [`TrackEngine`], described by a
//!   [`TrackFilterInfo`].
//!
//! The drivers in [`crate::estimators`] build both from a scenario and [`Params`], and
//! [`crate::registry`] lists them and builds one by name. This module re-exports what its two
//! children define, so users name `crate::engine::…`.
//!
//! This module is a leaf: it imports nothing from the crate, so drivers depend on it and never on
//! the registry.

pub mod replay;
pub mod track;

use harrier_core::EstimationError;

pub use replay::{BuildFn, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step};
pub use track::{
    Deployment, Handover, SensorScan, TrackEngine, TrackFilterBuildFn, TrackFilterInfo,
    TrackStatus, TrackView,
};

/// Why an estimator could not be built or could not process a time step.
#[derive(Debug, thiserror::Error)]
pub enum EngineError {
    /// The scenario lacks something the estimator needs, or a parameter is wrong.
    #[error("{0}")]
    Setup(String),
    /// A numeric failure on this step's data; the estimator's state is unchanged.
    #[error(transparent)]
    Estimation(#[from] EstimationError),
}

/// Shorthand for a setup error.
pub fn setup(msg: impl Into<String>) -> EngineError {
    EngineError::Setup(msg.into())
}
