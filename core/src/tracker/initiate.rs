//! Track initiation (Stone Soup's `Initiator`): a new tentative track from one unassociated
//! detection, and the M-of-N rule that confirms or drops it.

use nalgebra::{SMatrix, SVector};

use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Builds the initial Gaussian of a tentative track from one detection.
pub trait Initiator<const N: usize, const M: usize> {
    /// Initial state of a track started by detection `z`.
    fn initiate(&self, z: &SVector<f64, M>) -> Result<Gaussian<N>>;
}

/// Single-point initiation for position detections and a constant-velocity layout
/// (`N = 2M`, state `[p; v]`): `x₀ = [z; 0]`, `P₀ = diag(R, σ_v² I)`. The velocity prior
/// `σ_v` should cover the target speeds (≈ v_max / 2), so that the second detection falls in the
/// gate of the first prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinglePointInitiator<const M: usize> {
    r: SMatrix<f64, M, M>,
    vel_std: f64,
}

impl<const M: usize> SinglePointInitiator<M> {
    /// Initiator with measurement-noise covariance `r` and velocity prior std `vel_std` (m/s).
    pub fn new(r: SMatrix<f64, M, M>, vel_std: f64) -> Result<Self> {
        if !(vel_std.is_finite() && vel_std > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "velocity prior std must be > 0, got {vel_std}"
            )));
        }
        crate::linalg::cholesky(&r, "initiator measurement covariance")?;
        Ok(Self { r, vel_std })
    }
}

impl<const N: usize, const M: usize> Initiator<N, M> for SinglePointInitiator<M> {
    fn initiate(&self, z: &SVector<f64, M>) -> Result<Gaussian<N>> {
        if N != 2 * M {
            return Err(EstimationError::InvalidParameter(format!(
                "single-point initiation needs a [position; velocity] state of size {}, got {N}",
                2 * M
            )));
        }
        let mut mean = SVector::<f64, N>::zeros();
        let mut cov = SMatrix::<f64, N, N>::zeros();
        for i in 0..M {
            mean[i] = z[i];
            for j in 0..M {
                cov[(i, j)] = self.r[(i, j)];
            }
            cov[(M + i, M + i)] = self.vel_std * self.vel_std;
        }
        Gaussian::new(mean, cov)
    }
}

/// The M-of-N confirmation rule: a tentative track is confirmed once it has `m` hits within its
/// first `n` scans (the initiating detection counts as the first hit) and dropped as soon as that
/// can no longer happen.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MOfN {
    m: u32,
    n: u32,
}

/// What [`MOfN::judge`] decides for a tentative track.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// `m` hits reached: confirm.
    Confirm,
    /// Still possible: keep it tentative.
    Pending,
    /// `m` hits can no longer be reached within `n` scans: drop it.
    Drop,
}

impl MOfN {
    /// Rule with `1 ≤ m ≤ n`.
    pub fn new(m: u32, n: u32) -> Result<Self> {
        if m == 0 || m > n {
            return Err(EstimationError::InvalidParameter(format!(
                "M-of-N needs 1 ≤ M ≤ N, got {m} of {n}"
            )));
        }
        Ok(Self { m, n })
    }
    /// `M`.
    pub fn m(&self) -> u32 {
        self.m
    }
    /// `N`.
    pub fn n(&self) -> u32 {
        self.n
    }
    /// Verdict after `scans` scans (including the initiating one) with `hits` hits.
    pub fn judge(&self, hits: u32, scans: u32) -> Verdict {
        if hits >= self.m {
            Verdict::Confirm
        } else if hits + self.n.saturating_sub(scans) < self.m {
            Verdict::Drop
        } else {
            Verdict::Pending
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Matrix2, Vector2};

    #[test]
    fn m_of_n_verdicts() {
        let r = MOfN::new(2, 3).unwrap();
        assert_eq!(r.judge(1, 1), Verdict::Pending); // initiating hit only
        assert_eq!(r.judge(2, 2), Verdict::Confirm); // hit, hit
        assert_eq!(r.judge(1, 2), Verdict::Pending); // hit, miss: one scan left
        assert_eq!(r.judge(2, 3), Verdict::Confirm); // hit, miss, hit
        assert_eq!(r.judge(1, 3), Verdict::Drop); // hit, miss, miss
        let r = MOfN::new(3, 5).unwrap();
        assert_eq!(r.judge(1, 3), Verdict::Pending);
        assert_eq!(r.judge(1, 4), Verdict::Drop);
        assert_eq!(r.judge(3, 5), Verdict::Confirm);
        let r = MOfN::new(1, 1).unwrap();
        assert_eq!(r.judge(1, 1), Verdict::Confirm);
        assert!(MOfN::new(0, 3).is_err());
        assert!(MOfN::new(4, 3).is_err());
    }

    #[test]
    fn single_point_initiation() {
        let i = SinglePointInitiator::new(Matrix2::identity() * 25.0, 10.0).unwrap();
        let g: Gaussian<4> = i.initiate(&Vector2::new(100.0, -50.0)).unwrap();
        assert_eq!(g.mean.as_slice(), &[100.0, -50.0, 0.0, 0.0]);
        assert_eq!(g.cov[(0, 0)], 25.0);
        assert_eq!(g.cov[(3, 3)], 100.0);
        assert_eq!(g.cov[(0, 2)], 0.0);
        let wrong: Result<Gaussian<6>> = i.initiate(&Vector2::zeros());
        assert!(wrong.is_err());
        assert!(SinglePointInitiator::new(Matrix2::identity(), 0.0).is_err());
    }
}
