//! Track deletion (Stone Soup's `UpdateTimeStepsDeleter` and `CovarianceBasedDeleter`): a confirmed
//! track is deleted after too many consecutive missed scans or when its position uncertainty grows
//! too large.

use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Why a track was deleted.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum DeleteReason {
    /// A confirmed track missed too many consecutive scans (JIPDA, MHT: its existence fell below
    /// the deletion threshold, which only missed scans do).
    Misses,
    /// A confirmed track's position uncertainty grew past the bound.
    Covariance,
    /// A tentative track can no longer meet the M-of-N rule (JIPDA, MHT: its existence fell below
    /// the deletion threshold before it was confirmed).
    Unconfirmed,
    /// The track's filter failed to predict it (the message says why).
    Failed(String),
}

/// Deletes a track after `max_misses` consecutive misses, or when the trace of its position
/// covariance (the first `position_dims` state components) exceeds `max_position_var`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Deleter {
    max_misses: u32,
    max_position_var: f64,
    position_dims: usize,
}

impl Deleter {
    /// Deleter with `max_misses ≥ 1` consecutive misses, a position-variance trace bound (m²) and
    /// the number of leading state components that are the position.
    pub fn new(max_misses: u32, max_position_var: f64, position_dims: usize) -> Result<Self> {
        let bound_ok = max_position_var > 0.0;
        if max_misses == 0 || !bound_ok || position_dims == 0 {
            return Err(EstimationError::InvalidParameter(format!(
                "deleter needs max_misses ≥ 1, a positive variance bound and position dims, got \
                 {max_misses}, {max_position_var}, {position_dims}"
            )));
        }
        Ok(Self {
            max_misses,
            max_position_var,
            position_dims,
        })
    }
    /// Why a track with this many consecutive misses and this estimate should go, if it should.
    pub fn judge<const N: usize>(
        &self,
        consecutive_misses: u32,
        g: &Gaussian<N>,
    ) -> Option<DeleteReason> {
        let trace: f64 = (0..self.position_dims.min(N)).map(|i| g.cov[(i, i)]).sum();
        if consecutive_misses >= self.max_misses {
            Some(DeleteReason::Misses)
        } else if trace.is_nan() || trace > self.max_position_var {
            Some(DeleteReason::Covariance)
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix4, Vector4};

    #[test]
    fn deletes_on_misses_or_covariance() {
        let d = Deleter::new(3, 1000.0, 2).unwrap();
        let small = Gaussian::new(Vector4::zeros(), Matrix4::identity() * 100.0).unwrap();
        let big = Gaussian::new(Vector4::zeros(), Matrix4::identity() * 600.0).unwrap();
        assert_eq!(d.judge(2, &small), None);
        assert_eq!(d.judge(3, &small), Some(DeleteReason::Misses));
        assert_eq!(d.judge(0, &big), Some(DeleteReason::Covariance));
        assert!(Deleter::new(0, 1.0, 2).is_err());
    }
}
