//! Hypothesiser, gater and global-nearest-neighbour associator (Stone Soup's `Hypothesiser`,
//! `Gater` and `GlobalNearestNeighbour` roles).
//!
//! ```text
//! d²ᵢⱼ = νᵢⱼᵀ Sᵢ⁻¹ νᵢⱼ,   νᵢⱼ = zⱼ ⊖ ẑᵢ                 (NIS of detection j under track i)
//! gate:  d²ᵢⱼ ≤ γ,   γ = χ²_M⁻¹(P_G)                    \[BLK01\] §7.4.2
//! GNN:   min Σ cᵢⱼ,  cᵢⱼ = d²ᵢⱼ + ln det Sᵢ  (assigned),  γ + ln det Sᵢ (track i missed)
//! ```
//!
//! The GNN cost is −2 ln of the Gaussian likelihood up to a constant, so a track is left without
//! a detection exactly when every gated detection is farther than the gate: the usual 2-D
//! assignment with one "missed" column per track ([BP99] §6.5), solved optimally by
//! [`assign::solve`](super::assign::solve).
//!
//! # References
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
//! * [BP99] S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House
//!   1999.

use nalgebra::SVector;

use super::assign;
use super::filter::TrackFilter;
use crate::linalg::{cholesky, ln_det};
use crate::measurement::MeasurementModel;
use crate::metrics::chi2_quantile;
use crate::{EstimationError, Result};

/// χ² gate on the NIS: a detection is a candidate for a track when `d² ≤ γ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gater {
    threshold: f64,
}

impl Gater {
    /// Gate that keeps a consistent detection with probability `gate_prob` (`γ = χ²_M⁻¹(P_G)`,
    /// M = measurement dimension).
    pub fn chi2(gate_prob: f64, dof: usize) -> Result<Self> {
        if !(gate_prob > 0.0 && gate_prob < 1.0) || dof == 0 {
            return Err(EstimationError::InvalidParameter(format!(
                "gate probability must be in (0, 1) and dof > 0, got {gate_prob}, {dof}"
            )));
        }
        Ok(Self {
            threshold: chi2_quantile(gate_prob, dof),
        })
    }
    /// The threshold γ on `d²`.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }
    /// Whether a detection at squared Mahalanobis distance `d2` passes.
    pub fn admits(&self, d2: f64) -> bool {
        d2 <= self.threshold
    }
}

/// One gated track–detection pair.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hypothesis {
    /// Index of the detection in the scan.
    pub detection: usize,
    /// `d² = νᵀ S⁻¹ ν`.
    pub distance_sq: f64,
}

/// The gated hypotheses of one predicted track.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct TrackHypotheses {
    /// `ln det S` of the track's predicted measurement.
    pub ln_det_s: f64,
    /// The gate γ of this track (its "missed" cost is `γ + ln det S`).
    pub gate: f64,
    /// Detections inside the gate.
    pub gated: Vec<Hypothesis>,
}

/// Scores every detection of a scan against one predicted track under the scan's sensor model and
/// keeps those in the gate (Stone Soup's `DistanceHypothesiser` + `DistanceGater`).
pub fn hypothesise<F, H, const N: usize, const M: usize>(
    filter: &F,
    predicted: &F::State,
    sensor: &H,
    detections: &[SVector<f64, M>],
    gater: &Gater,
) -> Result<TrackHypotheses>
where
    F: TrackFilter<N>,
    H: MeasurementModel<N, M>,
{
    let mp = filter.predict_measurement(predicted, sensor)?;
    let chol = cholesky(&mp.cov, "innovation covariance")?;
    let mut gated = Vec::new();
    for (j, z) in detections.iter().enumerate() {
        let nu = sensor.residual(z, &mp.zhat);
        let d2 = nu.dot(&chol.solve(&nu));
        if gater.admits(d2) {
            gated.push(Hypothesis {
                detection: j,
                distance_sq: d2,
            });
        }
    }
    Ok(TrackHypotheses {
        ln_det_s: ln_det(&chol),
        gate: gater.threshold(),
        gated,
    })
}

/// Cost of a forbidden cell (outside the gate); any finite value far above the gated costs works.
const FORBIDDEN: f64 = 1e12;

/// Global nearest neighbour: the jointly most likely assignment of detections to tracks, each track
/// getting at most one detection in its gate and each detection at most one track. Tracks with
/// different gates (confirmed and tentative) compete in the same assignment, each with its own
/// missed cost. Returns the detection of each track.
pub fn global_nearest_neighbour(hypotheses: &[TrackHypotheses]) -> Result<Vec<Option<usize>>> {
    let mut out = vec![None; hypotheses.len()];
    // Only tracks with a gated detection and detections in some gate take part.
    let rows: Vec<usize> = (0..hypotheses.len())
        .filter(|&i| !hypotheses[i].gated.is_empty())
        .collect();
    let mut cols: Vec<usize> = rows
        .iter()
        .flat_map(|&i| hypotheses[i].gated.iter().map(|h| h.detection))
        .collect();
    cols.sort_unstable();
    cols.dedup();
    if rows.is_empty() {
        return Ok(out);
    }
    // Columns: the detections, then one "missed" column per row.
    let (n, m) = (rows.len(), cols.len() + rows.len());
    let mut cost = vec![FORBIDDEN; n * m];
    for (r, &i) in rows.iter().enumerate() {
        let h = &hypotheses[i];
        for g in &h.gated {
            if let Ok(c) = cols.binary_search(&g.detection) {
                cost[r * m + c] = g.distance_sq + h.ln_det_s;
            }
        }
        cost[r * m + cols.len() + r] = h.gate + h.ln_det_s;
    }
    let a = assign::solve(&cost, n, m)?;
    for (r, &i) in rows.iter().enumerate() {
        out[i] = a.row_to_col[r]
            .and_then(|c| cols.get(c).copied())
            .filter(|&d| hypotheses[i].gated.iter().any(|h| h.detection == d));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::filter::Extended;
    use crate::measurement::{Geometry, Position};
    use crate::motion::ConstantVelocity;
    use crate::state::Gaussian;
    use crate::tracker::filter::GaussianFilter;
    use nalgebra::{Matrix4, Vector2, Vector4};

    fn hyp(ln_det_s: f64, g: &[(usize, f64)]) -> TrackHypotheses {
        TrackHypotheses {
            ln_det_s,
            gate: Gater::chi2(0.99, 2).unwrap().threshold(),
            gated: g
                .iter()
                .map(|&(detection, distance_sq)| Hypothesis {
                    detection,
                    distance_sq,
                })
                .collect(),
        }
    }

    #[test]
    fn gate_threshold_is_the_chi2_quantile() {
        let g = Gater::chi2(0.99, 2).unwrap();
        // scipy.stats.chi2.ppf(0.99, 2) = −2 ln 0.01
        assert!((g.threshold() - 9.210_340_371_976_182).abs() < 1e-9);
        assert!(g.admits(9.2) && !g.admits(9.22));
        assert!(Gater::chi2(1.0, 2).is_err());
        assert!(Gater::chi2(0.5, 0).is_err());
    }

    #[test]
    fn hypothesiser_gates_on_nis() {
        let f = GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::<4>::new(1.0),
        };
        let sensor = Position::new(Geometry::planar(0.0), [1.0, 1.0]);
        // Predicted position (0, 0) with unit variance: S = 2 I.
        let x = Gaussian::new(Vector4::zeros(), Matrix4::identity()).unwrap();
        let dets = [
            Vector2::new(2.0, 0.0),  // d² = 2
            Vector2::new(10.0, 0.0), // d² = 50, outside
            Vector2::new(0.0, -4.0), // d² = 8
        ];
        let gater = Gater::chi2(0.99, 2).unwrap();
        let h = hypothesise(&f, &x, &sensor, &dets, &gater).unwrap();
        assert!((h.ln_det_s - 4f64.ln()).abs() < 1e-12);
        assert_eq!(h.gate, gater.threshold());
        let got: Vec<_> = h
            .gated
            .iter()
            .map(|h| (h.detection, h.distance_sq))
            .collect();
        assert_eq!(got.len(), 2);
        assert_eq!(got[0].0, 0);
        assert!((got[0].1 - 2.0).abs() < 1e-12);
        assert_eq!(got[1].0, 2);
        assert!((got[1].1 - 8.0).abs() < 1e-12);
    }

    #[test]
    fn gnn_prefers_the_joint_optimum_over_greedy() {
        // Greedy would give detection 0 to track 0 (1.0) and leave track 1 with a miss;
        // jointly, 0 → 1 and 1 → 0 is cheaper (2 + 2 < 1 + γ).
        let h = [hyp(0.0, &[(0, 1.0), (1, 2.0)]), hyp(0.0, &[(0, 2.0)])];
        assert_eq!(
            global_nearest_neighbour(&h).unwrap(),
            vec![Some(1), Some(0)]
        );
        // No gated detection: a miss; empty input.
        let h = [hyp(0.0, &[]), hyp(0.0, &[(3, 0.5)])];
        assert_eq!(global_nearest_neighbour(&h).unwrap(), vec![None, Some(3)]);
        assert!(global_nearest_neighbour(&[]).unwrap().is_empty());
    }
}
