//! Hypothesiser, gater and global-nearest-neighbour associator (Stone Soup's `Hypothesiser`,
//! `Gater` and `GlobalNearestNeighbour` roles).
//!
//! ```text
//! d²ᵢⱼ = νᵢⱼᵀ Sᵢ⁻¹ νᵢⱼ,   νᵢⱼ = zⱼ ⊖ ẑᵢ                 (NIS of detection j under track i)
//! gate:  d²ᵢⱼ ≤ γ,   γ = χ²_M⁻¹(P_G)                    \[BLK01\] §7.4.2
//! ln N(zⱼ; ẑᵢ, Sᵢ) = −½ (d²ᵢⱼ + ln det Sᵢ + M ln 2π)   (what soft and multi-scan association weigh)
//! GNN:   min Σ cᵢⱼ,  cᵢⱼ = d²ᵢⱼ + ln det Sᵢ  (assigned),  γ + ln det Sᵢ (track i missed)
//! ```
//!
//! [`hypothesise_scan`] scores every track of a scan against only the detections near it (the
//! spatial index of [`gate`](super::gate)), which gives exactly the gated sets of testing every
//! pair. The GNN cost is −2 ln of the Gaussian likelihood up to a constant, so a track is left
//! without a detection exactly when every gated detection is farther than the gate: the usual 2-D
//! assignment with one "missed" column per track ([BP99] §6.5), solved optimally by
//! [`assign::solve`](super::assign::solve) on each cluster of tracks that share gated detections
//! ([`clusters`]; the cost matrix is block-diagonal over the clusters, so the optimum of the whole
//! is the union of the clusters' optima).
//!
//! # References
//! * \[BLK01\] Bar-Shalom, Li, Kirubarajan, *Estimation with Applications to Tracking and
//!   Navigation*, Wiley 2001.
//! * [BP99] S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House
//!   1999.

use nalgebra::SVector;

use super::assign;
use super::filter::TrackFilter;
use super::gate::DetectionIndex;
use crate::linalg::{cholesky, ln_det};
use crate::measurement::MeasurementModel;
use crate::metrics::{chi2_cdf, chi2_quantile};
use crate::{EstimationError, Result};

/// χ² gate on the NIS: a detection is a candidate for a track when `d² ≤ γ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Gater {
    threshold: f64,
    prob: f64,
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
            prob: gate_prob,
        })
    }
    /// The threshold γ on `d²`.
    pub fn threshold(&self) -> f64 {
        self.threshold
    }
    /// The gate probability `P_G` it was built for (a consistent detection of its dimension falls
    /// inside with this probability).
    pub fn probability(&self) -> f64 {
        self.prob
    }
    /// `P_G` for detections of dimension `dof` (the gate was built for one dimension; a scan of
    /// another sensor kind keeps γ, so its `P_G` is `χ²_dof(γ)`).
    pub fn probability_for(&self, dof: usize) -> f64 {
        chi2_cdf(self.threshold, dof)
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
    /// Measurement dimension M.
    pub dim: usize,
    /// The gate γ of this track (its "missed" cost is `γ + ln det S`).
    pub gate: f64,
    /// Detections inside the gate, in detection order.
    pub gated: Vec<Hypothesis>,
}

impl TrackHypotheses {
    /// The NIS `d²` of detection `detection`, NaN when it is not in the gate.
    pub fn nis(&self, detection: usize) -> f64 {
        self.gated
            .iter()
            .find(|g| g.detection == detection)
            .map_or(f64::NAN, |g| g.distance_sq)
    }

    /// `ln N(z; ẑ, S) = −½ (d² + ln det S + M ln 2π)` of a gated detection at NIS `d2`.
    pub fn log_likelihood(&self, d2: f64) -> f64 {
        -0.5 * (d2 + self.ln_det_s + self.dim as f64 * (2.0 * std::f64::consts::PI).ln())
    }
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
    let p = Predicted::new(filter, predicted, sensor, gater)?;
    Ok(p.gate(sensor, detections, 0..detections.len()))
}

/// Below this many detections a scan is not indexed: testing every pair is cheaper.
const INDEX_FROM: usize = 48;

/// [`hypothesise`] for every track of a scan (`states`, each with its gate), testing each track
/// only against the detections the spatial index finds near its predicted measurement — the same
/// gated sets as testing every pair. A track whose measurement prediction fails gets the error.
pub fn hypothesise_scan<F, H, const N: usize, const M: usize>(
    filter: &F,
    states: &[(&F::State, &Gater)],
    sensor: &H,
    detections: &[SVector<f64, M>],
) -> Vec<Result<TrackHypotheses>>
where
    F: TrackFilter<N>,
    H: MeasurementModel<N, M>,
{
    let predicted: Vec<Result<Predicted<M>>> = states
        .iter()
        .map(|(s, g)| Predicted::new(filter, s, sensor, g))
        .collect();
    if detections.len() < INDEX_FROM {
        return predicted
            .into_iter()
            .map(|p| Ok(p?.gate(sensor, detections, 0..detections.len())))
            .collect();
    }
    // Cells about as wide as a typical gate: a query then walks a few cells.
    let cell = std::array::from_fn(|a| {
        let mut w: Vec<f64> = predicted.iter().flatten().map(|p| p.half[a]).collect();
        if w.is_empty() {
            return 1.0;
        }
        let mid = w.len() / 2;
        *w.select_nth_unstable_by(mid, f64::total_cmp).1
    });
    let index = DetectionIndex::new(sensor, detections, cell);
    let mut candidates = Vec::new();
    predicted
        .into_iter()
        .map(|p| {
            let p = p?;
            candidates.clear();
            let centre = std::array::from_fn(|a| if a < M { p.zhat[a] } else { 0.0 });
            index.query(centre, p.half, |j| candidates.push(j));
            candidates.sort_unstable();
            Ok(p.gate(sensor, detections, candidates.iter().copied()))
        })
        .collect()
}

/// A track's predicted measurement with what gating needs: `ẑ`, the Cholesky factor of `S`, the
/// gate and the half-widths `√(γ Sᵢᵢ)` of the box around `ẑ` that holds the gate.
struct Predicted<const M: usize> {
    zhat: SVector<f64, M>,
    chol: nalgebra::Cholesky<f64, nalgebra::Const<M>>,
    gate: f64,
    half: [f64; 2],
}

impl<const M: usize> Predicted<M> {
    fn new<F, H, const N: usize>(
        filter: &F,
        state: &F::State,
        sensor: &H,
        gater: &Gater,
    ) -> Result<Self>
    where
        F: TrackFilter<N>,
        H: MeasurementModel<N, M>,
    {
        let mp = filter.predict_measurement(state, sensor)?;
        let chol = cholesky(&mp.cov, "innovation covariance")?;
        let gate = gater.threshold();
        let half = std::array::from_fn(|a| {
            if a < M {
                (gate * mp.cov[(a, a)]).sqrt()
            } else {
                0.0
            }
        });
        Ok(Self {
            zhat: mp.zhat,
            chol,
            gate,
            half,
        })
    }

    /// The gated detections among `candidates` (in increasing order).
    fn gate<H, const N: usize>(
        &self,
        sensor: &H,
        detections: &[SVector<f64, M>],
        candidates: impl Iterator<Item = usize>,
    ) -> TrackHypotheses
    where
        H: MeasurementModel<N, M>,
    {
        let mut gated = Vec::new();
        for j in candidates {
            let nu = sensor.residual(&detections[j], &self.zhat);
            let d2 = nu.dot(&self.chol.solve(&nu));
            if d2 <= self.gate {
                gated.push(Hypothesis {
                    detection: j,
                    distance_sq: d2,
                });
            }
        }
        TrackHypotheses {
            ln_det_s: ln_det(&self.chol),
            dim: M,
            gate: self.gate,
            gated,
        }
    }
}

/// Tracks that share gated detections, transitively: the association of one cluster does not
/// depend on any other's.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cluster {
    /// Track indices, increasing.
    pub tracks: Vec<usize>,
    /// Detection indices gated by any of them, increasing.
    pub detections: Vec<usize>,
}

/// The clusters of the tracks with at least one gated detection (union–find over the tracks,
/// joined through each detection they share), in order of their first track.
pub fn clusters(hypotheses: &[TrackHypotheses], n_detections: usize) -> Vec<Cluster> {
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..hypotheses.len()).collect();
    let mut owner = vec![usize::MAX; n_detections];
    for (i, h) in hypotheses.iter().enumerate() {
        for g in &h.gated {
            match owner.get(g.detection).copied() {
                Some(usize::MAX) => owner[g.detection] = i,
                Some(o) => {
                    let (a, b) = (find(&mut parent, o), find(&mut parent, i));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                }
                None => {}
            }
        }
    }
    let mut slot = vec![usize::MAX; hypotheses.len()];
    let mut out: Vec<Cluster> = Vec::new();
    for (i, h) in hypotheses.iter().enumerate() {
        if h.gated.is_empty() {
            continue;
        }
        let root = find(&mut parent, i);
        if slot[root] == usize::MAX {
            slot[root] = out.len();
            out.push(Cluster::default());
        }
        let c = &mut out[slot[root]];
        c.tracks.push(i);
        c.detections.extend(h.gated.iter().map(|g| g.detection));
    }
    for c in &mut out {
        c.detections.sort_unstable();
        c.detections.dedup();
    }
    out
}

/// Cost of a forbidden cell (outside the gate); any finite value far above the gated costs works.
const FORBIDDEN: f64 = 1e12;

/// Global nearest neighbour: the jointly most likely assignment of detections to tracks, each track
/// getting at most one detection in its gate and each detection at most one track. Tracks with
/// different gates (confirmed and tentative) compete in the same assignment, each with its own
/// missed cost. Solved cluster by cluster ([`clusters`]). Returns the detection of each track.
pub fn global_nearest_neighbour(hypotheses: &[TrackHypotheses]) -> Result<Vec<Option<usize>>> {
    let n_det = hypotheses
        .iter()
        .flat_map(|h| h.gated.iter().map(|g| g.detection + 1))
        .max()
        .unwrap_or(0);
    gnn_clusters(hypotheses, &clusters(hypotheses, n_det))
}

/// [`global_nearest_neighbour`] over the clusters `clusters` of `hypotheses` (those of
/// [`clusters`]).
pub(crate) fn gnn_clusters(
    hypotheses: &[TrackHypotheses],
    clusters: &[Cluster],
) -> Result<Vec<Option<usize>>> {
    let mut out = vec![None; hypotheses.len()];
    for c in clusters {
        assign_cluster(hypotheses, c, &mut out)?;
    }
    Ok(out)
}

/// The optimal assignment of one cluster, written into `out`.
fn assign_cluster(
    hypotheses: &[TrackHypotheses],
    c: &Cluster,
    out: &mut [Option<usize>],
) -> Result<()> {
    let (rows, cols) = (&c.tracks, &c.detections);
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
    Ok(())
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
            dim: 2,
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

    #[test]
    fn the_indexed_scan_gates_exactly_like_testing_every_pair() {
        use crate::measurement::RangeBearing;
        use rand::{Rng, SeedableRng};
        use rand_chacha::ChaCha8Rng;
        let f = GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::<4>::new(1.0),
        };
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let plane = Position::new(Geometry::planar(0.0), [5.0, 5.0]);
        let radar = RangeBearing::new(
            Geometry::planar(0.0),
            nalgebra::Vector3::new(0.0, 0.0, 10.0),
            [5.0, 0.01],
        );
        let wide = Gater::chi2(0.999, 2).unwrap();
        let narrow = Gater::chi2(0.9, 2).unwrap();
        for round in 0..20 {
            let states: Vec<Gaussian<4>> = (0..rng.random_range(1..60))
                .map(|_| {
                    let p = Vector4::new(
                        rng.random_range(-2000.0..2000.0),
                        rng.random_range(-2000.0..2000.0),
                        0.0,
                        0.0,
                    );
                    Gaussian::new(p, Matrix4::identity() * rng.random_range(10.0..2000.0)).unwrap()
                })
                .collect();
            let with: Vec<_> = states
                .iter()
                .enumerate()
                .map(|(i, s)| (s, if i % 2 == 0 { &wide } else { &narrow }))
                .collect();
            if round % 2 == 0 {
                let dets: Vec<Vector2<f64>> = (0..400)
                    .map(|_| {
                        Vector2::new(
                            rng.random_range(-2100.0..2100.0),
                            rng.random_range(-2100.0..2100.0),
                        )
                    })
                    .collect();
                let got = hypothesise_scan(&f, &with, &plane, &dets);
                for ((s, g), h) in with.iter().zip(got) {
                    assert_eq!(h.unwrap(), hypothesise(&f, s, &plane, &dets, g).unwrap());
                }
            } else {
                // Range and bearing: the bearing axis wraps at ±π behind the radar.
                let dets: Vec<Vector2<f64>> = (0..400)
                    .map(|_| {
                        let x = Vector4::new(
                            rng.random_range(-2100.0..2100.0),
                            rng.random_range(-2100.0..2100.0),
                            0.0,
                            0.0,
                        );
                        MeasurementModel::<4, 2>::function(&radar, &x)
                    })
                    .collect();
                let got = hypothesise_scan(&f, &with, &radar, &dets);
                for ((s, g), h) in with.iter().zip(got) {
                    assert_eq!(h.unwrap(), hypothesise(&f, s, &radar, &dets, g).unwrap());
                }
            }
        }
    }

    #[test]
    fn clusters_join_tracks_through_shared_detections() {
        let h = [
            hyp(0.0, &[(0, 1.0), (1, 1.0)]),
            hyp(0.0, &[(5, 1.0)]),
            hyp(0.0, &[]),
            hyp(0.0, &[(1, 1.0), (2, 1.0)]),
            hyp(0.0, &[(2, 1.0)]),
        ];
        let c = clusters(&h, 6);
        assert_eq!(c.len(), 2);
        assert_eq!(
            (c[0].tracks.clone(), c[0].detections.clone()),
            (vec![0, 3, 4], vec![0, 1, 2])
        );
        assert_eq!(
            (c[1].tracks.clone(), c[1].detections.clone()),
            (vec![1], vec![5])
        );
    }
}
