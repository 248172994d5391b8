//! Joint integrated probabilistic data association (\[JIPDA\]): the tracks of a cluster (tracks
//! that share gated detections, [`clusters`](super::associate::clusters)) are associated
//! jointly, each with its probability of existence ψ.
//!
//! A joint event `e` gives each track τ of the cluster no detection or one of its gated
//! detections, no detection to two tracks. With `P_D`, each track's gate probability `P_G,τ`, its
//! predicted existence `ψ_τ` and the clutter density `ρ`, its weight is (\[JIPDA\], the joint
//! event probabilities)
//!
//! ```text
//! P(e) ∝ Π_{τ: e_τ = ∅} (1 − P_D P_G,τ ψ_τ) · Π_{τ: e_τ = j} ψ_τ P_D N(zⱼ; ẑ_τ, S_τ) / ρ
//! ```
//!
//! (`N/P_G` is the likelihood of a detection inside the gate; the `P_G` cancel.) The marginals
//! `m_τ(e) = Σ_{e': e'_τ = e} P(e')` come from [`ehm::marginals`](super::ehm::marginals) without
//! enumerating the events. Then, per track,
//!
//! ```text
//! ψ'_τ = Σⱼ m_τ(j) + m_τ(∅) (1 − P_D P_G,τ) ψ_τ / (1 − P_D P_G,τ ψ_τ)      (existence)
//! βⱼ = m_τ(j) / ψ'_τ,   β₀ = 1 − Σⱼ βⱼ                                   (given existence)
//! ```
//!
//! and the track's state is the mixture of its prediction (weight β₀) and its updates with each
//! gated detection (βⱼ), reduced to one Gaussian ([`TrackFilter::update_mixture`]; per mode for
//! IMM tracks). For a lone track this is the IPDA update of [`existence`](super::existence).
//! The probability that detection j is a known target's is `Σ_τ m_τ(j)`; a detection for which
//! it is low starts a new track.
//!
//! **Clutter density.** Known (`ρ`, e.g. `clutter_rate / area` of FORMAT-MULTI's `detection`
//! block for position sensors), or estimated per cluster with the non-parametric rule of
//! \[IPDA\]: the detections in the cluster's gates beyond the targets' expected ones, over
//! the gates' volume, `ρ̂ = max(m − Σ_τ P_D P_G,τ ψ_τ, 0.1) / Σ_τ V_τ` with
//! `V_τ = c_M γ^{M/2} √det S_τ` (`c_M` the unit ball's volume).
//!
//! **Coalescence avoidance** (the default): the marginals are those of JPDA*'s pruned event
//! set, the most likely permutation of each class of events that detect the same tracks with the
//! same detections, among tracks that move together ([`jpda_star`],
//! \[JPDA*\]), so that close parallel tracks do not take weight from each other's detections and
//! merge; clutter and misses are weighted as above. A cluster too large to enumerate within the
//! budget gets the exact marginals (counted).
//!
//! [`TrackFilter::update_mixture`]: super::TrackFilter::update_mixture
//!
//! # References
//! * \[JIPDA\] D. Mušicki, R. Evans, "Joint integrated probabilistic data association: JIPDA",
//!   *IEEE Trans. Aerospace and Electronic Systems* 40(3), 1093–1099, 2004.
//! * \[IPDA\] D. Mušicki, R. Evans, S. Stanković, "Integrated probabilistic data association",
//!   *IEEE Trans. Automatic Control* 39(6), 1237–1241, 1994.
//! * \[JPDA*\] H. A. P. Blom, E. A. Bloem, "Probabilistic data association avoiding track
//!   coalescence", *IEEE Trans. Automatic Control* 45(2), 247–259, 2000.

use super::associate::{Cluster, TrackHypotheses};
use super::ehm::{Row, marginals};
use super::jpda_star;
use crate::Result;
use crate::metrics::unit_ball_volume;

/// One track of a cluster as JIPDA sees it.
#[derive(Debug, Clone, Copy)]
pub struct Candidate<'a> {
    /// Predicted existence `ψ`.
    pub existence: f64,
    /// Gate probability `P_G` of its gate.
    pub gate_prob: f64,
    /// Its gated detections.
    pub hypotheses: &'a TrackHypotheses,
}

/// What JIPDA gives one track.
#[derive(Debug, Clone, PartialEq)]
pub struct Soft {
    /// Posterior existence `ψ'`.
    pub existence: f64,
    /// `β₀`: no detection is the target's, given that it exists.
    pub miss: f64,
    /// `(detection, βⱼ)` for each gated detection, given that the target exists.
    pub detections: Vec<(usize, f64)>,
}

/// The outcome of one cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterOutcome {
    /// Per track of the cluster, in the order given.
    pub tracks: Vec<Soft>,
    /// `(detection, Σ_τ m_τ(j))`: the probability that each of the cluster's detections is a
    /// known target's.
    pub taken: Vec<(usize, f64)>,
    /// Nodes of the EHM net.
    pub nodes: usize,
    /// Whether the net was cut, or JPDA* fell back to the exact marginals (its budget ran out).
    pub capped: bool,
}

/// The non-parametric clutter density of a cluster (module doc).
pub fn estimated_clutter(cluster: &Cluster, tracks: &[Candidate<'_>], pd: f64) -> f64 {
    let expected: f64 = tracks.iter().map(|c| pd * c.gate_prob * c.existence).sum();
    let volume: f64 = tracks
        .iter()
        .map(|c| {
            let h = c.hypotheses;
            let m = h.dim as f64;
            unit_ball_volume(h.dim) * (0.5 * m * h.gate.ln() + 0.5 * h.ln_det_s).exp()
        })
        .sum();
    (cluster.detections.len() as f64 - expected).max(0.1) / volume
}

/// JIPDA on one cluster: `tracks` (in the cluster's order) with `P_D`, the clutter density `rho`
/// and the EHM bound; with `star_nodes > 0`, JPDA*'s pruned marginals
/// ([`jpda_star`], pruning the permutations among the tracks `together(a, b)`
/// says move together, by their index in `tracks`) when enumerating the cluster's events visits
/// at most `star_nodes` nodes, else the exact JIPDA marginals, reported as `capped`.
pub fn associate(
    cluster: &Cluster,
    tracks: &[Candidate<'_>],
    pd: f64,
    rho: f64,
    max_nodes: usize,
    star_nodes: usize,
    together: impl Fn(usize, usize) -> bool,
) -> Result<ClusterOutcome> {
    let ln_pd_rho = pd.ln() - rho.ln();
    let rows: Vec<Row> = tracks
        .iter()
        .map(|c| {
            let miss = (1.0 - pd * c.gate_prob * c.existence).ln();
            let lw: Vec<(usize, f64)> = c
                .hypotheses
                .gated
                .iter()
                .map(|g| {
                    let local = cluster
                        .detections
                        .binary_search(&g.detection)
                        .unwrap_or(usize::MAX);
                    let l =
                        c.existence.ln() + ln_pd_rho + c.hypotheses.log_likelihood(g.distance_sq);
                    (local, l)
                })
                .collect();
            // Each row scaled by its largest weight (the marginals do not change).
            let top = lw.iter().map(|x| x.1).fold(miss, f64::max);
            Row {
                miss: (miss - top).exp(),
                detections: lw.iter().map(|&(d, l)| (d, (l - top).exp())).collect(),
            }
        })
        .collect();
    let n_det = cluster.detections.len();
    let star = if star_nodes > 0 && rows.len() > 1 {
        jpda_star::marginals(&rows, n_det, star_nodes, together)?
    } else {
        None
    };
    let m = match star {
        Some(m) => m,
        None => {
            let mut m = marginals(&rows, n_det, max_nodes)?;
            m.capped |= star_nodes > 0 && rows.len() > 1;
            m
        }
    };
    let mut taken = vec![0.0; cluster.detections.len()];
    let soft = tracks
        .iter()
        .zip(&rows)
        .enumerate()
        .map(|(i, (c, row))| {
            let pdpg = pd * c.gate_prob;
            let miss_exists = m.miss[i] * (1.0 - pdpg) * c.existence / (1.0 - pdpg * c.existence);
            let hit: f64 = m.detections[i].iter().sum();
            let existence = (hit + miss_exists).clamp(0.0, 1.0);
            let detections: Vec<(usize, f64)> = row
                .detections
                .iter()
                .zip(&m.detections[i])
                .map(|(&(local, _), &p)| {
                    taken[local] += p;
                    let beta = if existence > 0.0 { p / existence } else { 0.0 };
                    (cluster.detections[local], beta)
                })
                .collect();
            let miss = (1.0 - detections.iter().map(|d| d.1).sum::<f64>()).clamp(0.0, 1.0);
            Soft {
                existence,
                miss,
                detections,
            }
        })
        .collect();
    Ok(ClusterOutcome {
        tracks: soft,
        taken: cluster.detections.iter().copied().zip(taken).collect(),
        nodes: m.nodes,
        capped: m.capped,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::Hypothesis;
    use crate::tracker::existence::ipda;

    fn hyps(gated: &[(usize, f64)]) -> TrackHypotheses {
        TrackHypotheses {
            ln_det_s: 2.0 * 100f64.ln(),
            dim: 2,
            gate: 13.8,
            gated: gated
                .iter()
                .map(|&(detection, distance_sq)| Hypothesis {
                    detection,
                    distance_sq,
                })
                .collect(),
        }
    }

    #[test]
    fn a_lone_track_is_ipda() {
        let h = hyps(&[(3, 1.0), (7, 4.0)]);
        let c = Candidate {
            existence: 0.6,
            gate_prob: 0.999,
            hypotheses: &h,
        };
        let cluster = Cluster {
            tracks: vec![0],
            detections: vec![3, 7],
        };
        let (pd, rho) = (0.9, 1e-5);
        let out = associate(&cluster, &[c], pd, rho, 100, 1000, |_, _| true).unwrap();
        let ratios: Vec<f64> = h
            .gated
            .iter()
            .map(|g| pd * h.log_likelihood(g.distance_sq).exp() / rho)
            .collect();
        let want = ipda(0.6, pd * 0.999, &ratios);
        let got = &out.tracks[0];
        assert!(
            (got.existence - want.existence).abs() < 1e-12,
            "{got:?} {want:?}"
        );
        assert!((got.miss - want.miss).abs() < 1e-12);
        for ((d, b), w) in got.detections.iter().zip(&want.detections) {
            assert!((b - w).abs() < 1e-12);
            assert!(*d == 3 || *d == 7);
        }
        // P(detection 3 is the target's) = ψ' β₃.
        assert!((out.taken[0].1 - want.existence * want.detections[0]).abs() < 1e-12);
    }

    #[test]
    fn two_tracks_share_one_detection() {
        // Both tracks gate detection 0; only track 0 gates detection 1. Track 1's best
        // explanation of detection 0 competes with track 0's.
        let (a, b) = (hyps(&[(0, 1.0), (1, 0.5)]), hyps(&[(0, 0.2)]));
        let cands = [
            Candidate {
                existence: 0.99,
                gate_prob: 0.999,
                hypotheses: &a,
            },
            Candidate {
                existence: 0.99,
                gate_prob: 0.999,
                hypotheses: &b,
            },
        ];
        let cluster = Cluster {
            tracks: vec![0, 1],
            detections: vec![0, 1],
        };
        let out = associate(&cluster, &cands, 0.9, 1e-6, 100, 0, |_, _| true).unwrap();
        // Detection 0 mostly goes to track 1 (nearer), detection 1 to track 0.
        assert!(out.tracks[1].detections[0].1 > 0.9, "{out:?}");
        assert!(out.tracks[0].detections[1].1 > 0.9, "{out:?}");
        for t in &out.tracks {
            let s = t.miss + t.detections.iter().map(|d| d.1).sum::<f64>();
            assert!((s - 1.0).abs() < 1e-12 && t.existence > 0.99);
        }
        // Each detection is assigned with probability ≤ 1.
        assert!(
            out.taken
                .iter()
                .all(|&(_, p)| (0.0..=1.0 + 1e-12).contains(&p))
        );
    }
}
