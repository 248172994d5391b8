//! The one error type of the estimation core.

/// Why an estimation step could not be carried out. The input state is never modified when a step
/// fails, so a caller can skip the measurement and carry on.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimationError {
    /// A matrix that must be symmetric positive definite (a covariance, an innovation covariance, an
    /// ellipsoid's shape matrix) failed its Cholesky factorisation.
    #[error("{0} is not positive definite")]
    NotPositiveDefinite(&'static str),
    /// A NaN or infinity appeared in an input or a result.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// A set-membership update found that the measurement strip does not meet the feasible set:
    /// the bounded-noise assumption is violated.
    #[error("measurement is inconsistent with the feasible set (empty intersection)")]
    EmptyIntersection,
    /// A parameter is out of its valid range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
}
