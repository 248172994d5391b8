//! Track initiation (Stone Soup's `Initiator`): a new tentative track from one unassociated
//! detection of any sensor kind, through the detection's position fix
//! ([`Locate`](crate::measurement::Locate): direct for `position`, slant range for
//! `range_bearing`, the ground-plane constraint for angle-only `az_el`, the known size for
//! `bearing_size`), and the M-of-N rule that confirms or drops it.

use nalgebra::{SMatrix, SVector};

use crate::measurement::PositionFix;
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Builds the initial Gaussian of a tentative track from one detection's position fix.
pub trait Initiator<const N: usize> {
    /// Initial state of a track started by a detection that fixes the target at `fix`.
    fn initiate(&self, fix: &PositionFix) -> Result<Gaussian<N>>;
}

/// Single-point initiation for constant-velocity layouts: planar `[x, y, vx, vy]` (N = 4) or 3-D
/// `[x, y, z, vx, vy, vz]` (N = 6). `x₀ = [p; 0]`, `P₀ = diag(P_fix, σ_v² I)`; in 3-D an Up
/// component the fix leaves open (zero variance: a 2-component position, a ground-plane fix) gets
/// the prior `σ_up²`. The velocity prior `σ_v` should cover the target speeds (≈ v_max / 2), so
/// that the second detection falls in the gate of the first prediction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SinglePointInitiator {
    vel_std: f64,
    up_std: f64,
}

impl SinglePointInitiator {
    /// Initiator with velocity prior std `vel_std` (m/s) and height prior std `up_std` (m), both > 0.
    pub fn new(vel_std: f64, up_std: f64) -> Result<Self> {
        if !(vel_std.is_finite() && vel_std > 0.0 && up_std.is_finite() && up_std > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "velocity and height prior std must be > 0, got {vel_std}, {up_std}"
            )));
        }
        Ok(Self { vel_std, up_std })
    }
}

impl<const N: usize> Initiator<N> for SinglePointInitiator {
    fn initiate(&self, fix: &PositionFix) -> Result<Gaussian<N>> {
        let d = match N {
            4 => 2,
            6 => 3,
            _ => {
                return Err(EstimationError::InvalidParameter(format!(
                    "single-point initiation needs a planar or 3-D CV state (4 or 6), got {N}"
                )));
            }
        };
        let mut mean = SVector::<f64, N>::zeros();
        let mut cov = SMatrix::<f64, N, N>::zeros();
        for i in 0..d {
            mean[i] = fix.pos[i];
            for j in 0..d {
                cov[(i, j)] = fix.cov[(i, j)];
            }
            cov[(d + i, d + i)] = self.vel_std * self.vel_std;
        }
        if d == 3 && fix.cov[(2, 2)] == 0.0 {
            cov[(2, 2)] = self.up_std * self.up_std;
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
    use nalgebra::{Matrix3, Vector3};

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
        let i = SinglePointInitiator::new(10.0, 30.0).unwrap();
        let fix = PositionFix {
            pos: Vector3::new(100.0, -50.0, 0.0),
            cov: Matrix3::from_diagonal(&Vector3::new(25.0, 25.0, 0.0)),
        };
        let g: Gaussian<4> = i.initiate(&fix).unwrap();
        assert_eq!(g.mean.as_slice(), &[100.0, -50.0, 0.0, 0.0]);
        assert_eq!(g.cov[(0, 0)], 25.0);
        assert_eq!(g.cov[(3, 3)], 100.0);
        assert_eq!(g.cov[(0, 2)], 0.0);
        let g: Gaussian<6> = i.initiate(&fix).unwrap();
        assert_eq!(g.cov[(2, 2)], 900.0); // open Up: the height prior
        assert_eq!(g.cov[(5, 5)], 100.0);
        let wrong: Result<Gaussian<5>> = i.initiate(&fix);
        assert!(wrong.is_err());
        assert!(SinglePointInitiator::new(0.0, 1.0).is_err());
        assert!(SinglePointInitiator::new(1.0, f64::NAN).is_err());
    }
}
