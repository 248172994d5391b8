//! Multi-target metrics: GOSPA with its decomposition, and track-continuity counts (swaps, breaks,
//! false tracks, confirmation delays).
//!
//! GOSPA with α = 2 (\[GOSPA\] Prop. 1): for estimates X = {x₁..x_m} and truths Y = {y₁..y_n},
//!
//! ```text
//! d_p^(c,2)(X, Y) = [ min_γ ( Σ_{(i,j)∈γ} d(xᵢ, yⱼ)^p + c^p/2 · (m + n − 2|γ|) ) ]^(1/p)
//! ```
//!
//! over partial assignments γ whose pairs are closer than c. The three terms are the
//! localisation error of the assigned pairs, `c^p/2` per missed truth and `c^p/2` per false
//! estimate. Pairs at distance ≥ c cost exactly as much as leaving both unassigned, so the minimum
//! is found by the optimal assignment of the cost `min(d, c)^p`.
//!
//! # References
//! * \[GOSPA\] A. S. Rahmathullah, Á. F. García-Fernández, L. Svensson, "Generalized optimal
//!   sub-pattern assignment metric", 20th Int. Conf. on Information Fusion (FUSION), 2017.

use std::collections::BTreeMap;

use nalgebra::SVector;

use super::assign;
use crate::{EstimationError, Result};

/// GOSPA of one scan and its decomposition. The parts are in units of distance^p and add up to
/// `gospa^p`.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct GospaParts {
    /// `d_p^(c,2)(X, Y)`.
    pub gospa: f64,
    /// `Σ d^p` over the assigned pairs.
    pub localisation: f64,
    /// `c^p/2 ·` number of missed truths.
    pub missed: f64,
    /// `c^p/2 ·` number of false estimates.
    pub false_tracks: f64,
    /// Assigned pairs.
    pub n_assigned: usize,
    /// Missed truths.
    pub n_missed: usize,
    /// False estimates.
    pub n_false: usize,
}

/// GOSPA (α = 2) between estimated and true positions, cut-off `c > 0`, order `p ≥ 1`.
pub fn gospa<const D: usize>(
    estimates: &[SVector<f64, D>],
    truths: &[SVector<f64, D>],
    c: f64,
    p: f64,
) -> Result<GospaParts> {
    if !(c > 0.0 && c.is_finite() && p >= 1.0 && p.is_finite()) {
        return Err(EstimationError::InvalidParameter(format!(
            "GOSPA needs c > 0 and p ≥ 1, got c = {c}, p = {p}"
        )));
    }
    let (m, n) = (estimates.len(), truths.len());
    let cp = c.powf(p);
    let mut cost = Vec::with_capacity(m * n);
    for x in estimates {
        for y in truths {
            cost.push((x - y).norm().min(c).powf(p));
        }
    }
    let a = assign::solve(&cost, m, n)?;
    let mut parts = GospaParts::default();
    for (i, j) in a.row_to_col.iter().enumerate() {
        if let Some(j) = *j {
            let d = (estimates[i] - truths[j]).norm();
            if d < c {
                parts.localisation += d.powf(p);
                parts.n_assigned += 1;
            }
        }
    }
    parts.n_missed = n - parts.n_assigned;
    parts.n_false = m - parts.n_assigned;
    parts.missed = 0.5 * cp * parts.n_missed as f64;
    parts.false_tracks = 0.5 * cp * parts.n_false as f64;
    parts.gospa = (parts.localisation + parts.missed + parts.false_tracks).powf(1.0 / p);
    Ok(parts)
}

/// Per-truth record kept by [`Continuity`].
#[derive(Debug, Clone, Default, PartialEq)]
struct TruthRecord {
    first_scan: usize,
    first_assigned: Option<usize>,
    last_track: Option<u64>,
    assigned_now: bool,
}

/// Per-track record kept by [`Continuity`].
#[derive(Debug, Clone, Default, PartialEq)]
struct TrackRecord {
    scans: usize,
    assigned_scans: usize,
    last_truth: Option<usize>,
    /// `(scan, from truth)` of the track's last swap.
    last_swap: Option<(usize, usize)>,
}

/// A swap back to the truth a track left at most this many scans before is counted as undone.
const UNDONE_WITHIN: usize = 3;

/// Track-continuity counts over a run, scan by scan: each scan, last scan's track–truth pairs that
/// are still closer than `threshold` are kept, and the other confirmed tracks are assigned to the
/// other truths optimally (squared distance, pairs closer than `threshold` only).
#[derive(Debug, Clone, PartialEq)]
pub struct Continuity {
    threshold: f64,
    scan: usize,
    truths: BTreeMap<usize, TruthRecord>,
    tracks: BTreeMap<u64, TrackRecord>,
    swaps: usize,
    swaps_undone: usize,
    id_switches: usize,
    breaks: usize,
}

/// The continuity summary.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ContinuityReport {
    /// Scans seen.
    pub scans: usize,
    /// Times a track that followed one truth was next assigned to another truth (a swap at a
    /// crossing shows up here).
    pub swaps: usize,
    /// Swaps that took a track back to the truth it had left at most 3 scans before: a track
    /// whose estimate flipped to a neighbour and back counts 2 swaps and 1 of these.
    pub swaps_undone: usize,
    /// Times a truth's assigned track id changed from one track to another.
    pub id_switches: usize,
    /// Times a truth lost its track (assigned in one scan, unassigned in the next while alive).
    pub breaks: usize,
    /// Confirmed tracks assigned to a truth in fewer than half of their scans.
    pub false_tracks: usize,
    /// Confirmed tracks seen.
    pub tracks: usize,
    /// Per truth id: scans from its first scan to its first assigned confirmed track (0 = the same
    /// scan), `None` when never.
    pub confirmation_delays: BTreeMap<usize, Option<usize>>,
}

impl Continuity {
    /// Counter with the assignment distance threshold (m).
    pub fn new(threshold: f64) -> Result<Self> {
        if !(threshold > 0.0 && threshold.is_finite()) {
            return Err(EstimationError::InvalidParameter(format!(
                "continuity threshold must be > 0, got {threshold}"
            )));
        }
        Ok(Self {
            threshold,
            scan: 0,
            truths: BTreeMap::new(),
            tracks: BTreeMap::new(),
            swaps: 0,
            swaps_undone: 0,
            id_switches: 0,
            breaks: 0,
        })
    }

    /// Adds one scan: the truths alive `(truth id, position)` and the confirmed tracks
    /// `(track id, position)`.
    pub fn add_scan<const D: usize>(
        &mut self,
        truths: &[(usize, SVector<f64, D>)],
        tracks: &[(u64, SVector<f64, D>)],
    ) -> Result<()> {
        let (m, n) = (tracks.len(), truths.len());
        // Keep last scan's pairs that are still closer than the threshold (as CLEAR-MOT does), so
        // that two tracks passing through a crossing are not counted as swapping just because
        // the truths coincide; assign the rest optimally.
        let mut truth_of_track = vec![None; m];
        let mut truth_taken = vec![false; n];
        for (j, (tid, y)) in truths.iter().enumerate() {
            let Some(r) = self.truths.get(tid).filter(|r| r.assigned_now) else {
                continue;
            };
            let kept = tracks
                .iter()
                .position(|(kid, x)| Some(*kid) == r.last_track && (x - y).norm() < self.threshold);
            if let Some(i) = kept.filter(|&i| truth_of_track[i].is_none()) {
                truth_of_track[i] = Some(j);
                truth_taken[j] = true;
            }
        }
        let free_tracks: Vec<usize> = (0..m).filter(|&i| truth_of_track[i].is_none()).collect();
        let free_truths: Vec<usize> = (0..n).filter(|&j| !truth_taken[j]).collect();
        let mut cost = Vec::with_capacity(free_tracks.len() * free_truths.len());
        for &i in &free_tracks {
            for &j in &free_truths {
                let d2 = (tracks[i].1 - truths[j].1).norm_squared();
                cost.push(d2.min(self.threshold * self.threshold));
            }
        }
        let a = assign::solve(&cost, free_tracks.len(), free_truths.len())?;
        for (r, c) in a.row_to_col.iter().enumerate() {
            if let Some(c) = *c {
                let (i, j) = (free_tracks[r], free_truths[c]);
                if (tracks[i].1 - truths[j].1).norm() < self.threshold {
                    truth_of_track[i] = Some(j);
                }
            }
        }
        let scan = self.scan;
        let mut track_of_truth = vec![None; n];
        for (i, j) in truth_of_track.iter().enumerate() {
            if let Some(j) = *j {
                track_of_truth[j] = Some(tracks[i].0);
            }
        }
        for (j, (tid, _)) in truths.iter().enumerate() {
            let r = self.truths.entry(*tid).or_insert_with(|| TruthRecord {
                first_scan: scan,
                ..TruthRecord::default()
            });
            match track_of_truth[j] {
                Some(k) => {
                    if r.last_track.is_some_and(|l| l != k) {
                        self.id_switches += 1;
                    }
                    r.first_assigned.get_or_insert(scan);
                    r.last_track = Some(k);
                    r.assigned_now = true;
                }
                None => {
                    if r.assigned_now {
                        self.breaks += 1;
                    }
                    r.assigned_now = false;
                }
            }
        }
        for (i, (kid, _)) in tracks.iter().enumerate() {
            let r = self.tracks.entry(*kid).or_default();
            r.scans += 1;
            if let Some(j) = truth_of_track[i] {
                let tid = truths[j].0;
                if let Some(from) = r.last_truth.filter(|&l| l != tid) {
                    self.swaps += 1;
                    if r.last_swap
                        .is_some_and(|(s, back)| back == tid && scan - s <= UNDONE_WITHIN)
                    {
                        self.swaps_undone += 1;
                    }
                    r.last_swap = Some((scan, from));
                }
                r.last_truth = Some(tid);
                r.assigned_scans += 1;
            }
        }
        self.scan += 1;
        Ok(())
    }

    /// The counts so far.
    pub fn report(&self) -> ContinuityReport {
        ContinuityReport {
            scans: self.scan,
            swaps: self.swaps,
            swaps_undone: self.swaps_undone,
            id_switches: self.id_switches,
            breaks: self.breaks,
            false_tracks: self
                .tracks
                .values()
                .filter(|r| 2 * r.assigned_scans < r.scans)
                .count(),
            tracks: self.tracks.len(),
            confirmation_delays: self
                .truths
                .iter()
                .map(|(id, r)| (*id, r.first_assigned.map(|a| a - r.first_scan)))
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;

    fn v(x: f64, y: f64) -> Vector2<f64> {
        Vector2::new(x, y)
    }

    #[test]
    fn gospa_decomposition() {
        // c = 10, p = 2: one pair at distance 3, one false estimate, one missed truth, and one
        // estimate 20 m from a truth, which counts as one miss plus one false (not as a pair).
        let est = [v(0.0, 0.0), v(100.0, 100.0), v(50.0, 0.0)];
        let tru = [v(3.0, 0.0), v(-100.0, 0.0), v(70.0, 0.0)];
        let g = gospa(&est, &tru, 10.0, 2.0).unwrap();
        assert_eq!((g.n_assigned, g.n_missed, g.n_false), (1, 2, 2));
        assert!((g.localisation - 9.0).abs() < 1e-12);
        assert!((g.missed - 100.0).abs() < 1e-12);
        assert!((g.false_tracks - 100.0).abs() < 1e-12);
        assert!((g.gospa - 209f64.sqrt()).abs() < 1e-12);
        // Empty sets.
        assert_eq!(gospa::<2>(&[], &[], 10.0, 2.0).unwrap().gospa, 0.0);
        let g = gospa(&[], &tru, 10.0, 1.0).unwrap();
        assert!((g.gospa - 15.0).abs() < 1e-12);
        assert!(gospa(&est, &tru, 0.0, 2.0).is_err());
    }

    #[test]
    fn gospa_picks_the_optimal_pairing() {
        let est = [v(0.0, 0.0), v(4.0, 0.0)];
        let tru = [v(3.0, 0.0), v(-1.0, 0.0)];
        // Optimal: (0,0)–(−1,0) and (4,0)–(3,0): 1 + 1.
        let g = gospa(&est, &tru, 10.0, 2.0).unwrap();
        assert!((g.localisation - 2.0).abs() < 1e-12);
    }

    #[test]
    fn continuity_counts_swaps_breaks_and_false_tracks() {
        let mut c = Continuity::new(20.0).unwrap();
        // Truths 0 and 1; track 7 on truth 0, track 8 appears on truth 1 one scan late.
        c.add_scan(&[(0, v(0.0, 0.0)), (1, v(100.0, 0.0))], &[(7, v(1.0, 0.0))])
            .unwrap();
        c.add_scan(
            &[(0, v(10.0, 0.0)), (1, v(90.0, 0.0))],
            &[(7, v(11.0, 0.0)), (8, v(91.0, 0.0))],
        )
        .unwrap();
        // The tracks swap.
        c.add_scan(
            &[(0, v(20.0, 0.0)), (1, v(80.0, 0.0))],
            &[(8, v(21.0, 0.0)), (7, v(81.0, 0.0))],
        )
        .unwrap();
        // Truth 1 loses its track; a far-away false track appears.
        c.add_scan(
            &[(0, v(30.0, 0.0)), (1, v(70.0, 0.0))],
            &[(8, v(31.0, 0.0)), (9, v(500.0, 0.0))],
        )
        .unwrap();
        let r = c.report();
        assert_eq!(r.scans, 4);
        assert_eq!((r.swaps, r.swaps_undone), (2, 0));
        assert_eq!(r.id_switches, 2);
        assert_eq!(r.breaks, 1);
        assert_eq!(r.false_tracks, 1);
        assert_eq!(r.tracks, 3);
        assert_eq!(r.confirmation_delays[&0], Some(0));
        assert_eq!(r.confirmation_delays[&1], Some(1));
    }

    /// Two tracks whose estimates flip to each other's truth for one scan and back count 4
    /// swaps, 2 of them undone; an exchange that stays 4 scans is not undone when it ends.
    #[test]
    fn continuity_counts_the_swaps_undone() {
        let count = |flipped: std::ops::Range<usize>| {
            let mut c = Continuity::new(20.0).unwrap();
            for k in 0..10 {
                let (a, b) = (v(0.0, k as f64), v(50.0, k as f64));
                let (x, y) = if flipped.contains(&k) { (b, a) } else { (a, b) };
                c.add_scan(&[(0, a), (1, b)], &[(7, x), (8, y)]).unwrap();
            }
            let r = c.report();
            (r.swaps, r.swaps_undone)
        };
        assert_eq!(count(3..4), (4, 2));
        assert_eq!(count(3..6), (4, 2));
        assert_eq!(count(3..7), (4, 0));
        assert_eq!(count(3..10), (2, 0));
    }

    #[test]
    fn continuity_keeps_pairs_through_a_crossing() {
        let mut c = Continuity::new(20.0).unwrap();
        let scans = [
            ([v(0.0, 0.0), v(0.0, 20.0)], [v(1.0, 0.0), v(0.0, 21.0)]),
            // The truths coincide; each track is still within the threshold of its own truth, and
            // track 8 is nearer to both, which alone would not decide anything.
            (
                [v(10.0, 10.0), v(10.0, 10.0)],
                [v(14.0, 10.0), v(10.0, 11.0)],
            ),
            ([v(20.0, 20.0), v(20.0, 0.0)], [v(21.0, 20.0), v(20.0, 1.0)]),
        ];
        for (truths, tracks) in scans {
            c.add_scan(
                &[(0, truths[0]), (1, truths[1])],
                &[(7, tracks[0]), (8, tracks[1])],
            )
            .unwrap();
        }
        let r = c.report();
        assert_eq!(
            (r.swaps, r.id_switches, r.breaks, r.false_tracks),
            (0, 0, 0, 0)
        );
    }
}
