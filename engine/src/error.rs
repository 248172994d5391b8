//! Why an estimator could not be built or could not run a step: a leaf both shapes use.

use harrier_core::EstimationError;

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
