//! Coalescence avoidance for JPDA-class association: the JPDA* hypothesis pruning of
//! \[JPDA*\].
//!
//! Two tracks that gate each other's detections (close parallel targets) both take weight from
//! both detections in JPDA; their updates pull them towards each other, which raises the weight
//! of the crossed assignment in the next scans, until the tracks coalesce and, when they part
//! again, often swap. JPDA* keeps the soft association's treatment of clutter and misses but
//! drops the permutations: joint events `e` that detect the same set of tracks `T(e)` with the
//! same set of detections `D(e)` differ only by which of those tracks took which detection, and
//! of each such class only the most likely one is kept (\[JPDA*\], the pruned hypothesis set
//! `Ω*`):
//!
//! ```text
//! Ω* = { e : P(e) = max { P(e') : T(e') = T(e), D(e') = D(e) } }
//! m*_τ(x) = Σ_{e ∈ Ω*, e_τ = x} P(e) / Σ_{e ∈ Ω*} P(e)            (x = ∅ or a detection)
//! ```
//!
//! with `P(e)` the joint-event weight of [`ehm`](super::ehm) (`Π_τ w_τ(e_τ)`).
//!
//! **Only among tracks that move together** (Harrier's restriction, not the paper's): an event
//! is pruned only when the tracks in which it differs from its class' best all move together
//! pairwise ([`move_together`]: their velocity difference inside a χ² ellipsoid of its
//! covariance). Coalescence is a failure of tracks that share detections for a long time (close
//! parallel targets); targets that cross with distinct velocities share them for a few scans,
//! and there the permutations are nearly equally likely, so that keeping one is a hard guess
//! and plain JPDA's mixture, which keeps each track's momentum through the crossing, loses
//! fewer identities (BENCHMARKS.md, "Association under ambiguity", the sweep of the gate).
//!
//! For a lone track,
//! and for tracks that share no detection, every class has one event and `m* = m` (JPDA's
//! marginals). The classes are not a product over tracks, so the exact EHM net does not carry
//! them: the cluster's events are enumerated depth first, each class keeping its best event,
//! up to a budget of visited nodes; a larger cluster returns `None` and the caller uses the
//! exact JPDA marginals of [`ehm::marginals`](super::ehm::marginals) instead (counted).
//!
//! # References
//! * \[JPDA*\] H. A. P. Blom, E. A. Bloem, "Probabilistic data association avoiding track
//!   coalescence", *IEEE Trans. Automatic Control* 45(2), 247–259, 2000 (§IV, JPDA*).

use std::collections::HashMap;

use nalgebra::{Matrix3, Vector3};

use super::ehm::{Marginals, Row, check_rows};
use crate::state::Gaussian;
use crate::{EstimationError, Result};

/// Whether two tracks' estimates move together: the difference of their velocities (the
/// constant-velocity layouts' `[p, v]` blocks, N = 4 or 6) inside the ellipsoid of squared
/// Mahalanobis radius `gate` of the sum of their velocity covariances,
/// `(v_a − v_b)ᵀ (P_a,vv + P_b,vv)⁻¹ (v_a − v_b) ≤ gate`. Any other layout, or a sum that is not
/// positive definite, counts as moving together (JPDA*'s pruning applies).
pub fn move_together<const N: usize>(a: &Gaussian<N>, b: &Gaussian<N>, gate: f64) -> bool {
    let d = match N {
        4 => 2,
        6 => 3,
        _ => return true,
    };
    let mut s = Matrix3::identity();
    let mut dv = Vector3::zeros();
    for i in 0..d {
        dv[i] = a.mean[d + i] - b.mean[d + i];
        for j in 0..d {
            s[(i, j)] = a.cov[(d + i, d + j)] + b.cov[(d + i, d + j)];
        }
    }
    s.cholesky().is_none_or(|c| dv.dot(&c.solve(&dv)) <= gate)
}

/// The JPDA* marginals of the rows' joint events (module doc), or `None` when enumerating them
/// would visit more than `max_nodes` nodes. Fails like [`ehm::marginals`](super::ehm::marginals)
/// on a negative or non-finite weight, or when no joint event has a positive weight.
///
/// `together(a, b)` says whether rows `a` and `b` move together: an event is pruned only for a
/// better event of its class that differs from it in rows that all move together (`|_, _| true`:
/// JPDA*).
pub fn marginals(
    rows: &[Row],
    n_det: usize,
    max_nodes: usize,
    together: impl Fn(usize, usize) -> bool,
) -> Result<Option<Marginals>> {
    check_rows(rows, n_det)?;
    let n = rows.len();
    // Log weights, each row scaled to a largest weight of 1 (the marginals do not change).
    let logs: Vec<(f64, Vec<(usize, f64)>)> = rows
        .iter()
        .map(|r| {
            let top = r.detections.iter().map(|d| d.1).fold(r.miss, f64::max);
            let s = if top > 0.0 { top.ln() } else { 0.0 };
            (
                r.miss.ln() - s,
                r.detections.iter().map(|&(d, w)| (d, w.ln() - s)).collect(),
            )
        })
        .collect();
    let (track_words, det_words) = (n.div_ceil(64), n_det.div_ceil(64));
    let mut search = Search {
        logs: &logs,
        track_words,
        key: vec![0u64; track_words + det_words],
        choice: vec![usize::MAX; n],
        lw: 0.0,
        best: HashMap::new(),
        events: Vec::new(),
        visited: 0,
        max_nodes,
    };
    if !search.visit(0) {
        return Ok(None);
    }
    let top = search
        .best
        .values()
        .map(|b| b.0)
        .fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return Err(EstimationError::NonFinite("association marginals"));
    }
    let mut miss = vec![0.0; n];
    let mut dets: Vec<Vec<f64>> = rows.iter().map(|r| vec![0.0; r.detections.len()]).collect();
    let mut total = 0.0;
    let kept = search.events.iter().filter(|(key, lw, event)| {
        let Some((best_lw, best)) = search.best.get(key) else {
            return true;
        };
        if lw >= best_lw {
            return true;
        }
        let differ: Vec<usize> = (0..n).filter(|&i| event[i] != best[i]).collect();
        let pruned = differ
            .iter()
            .enumerate()
            .all(|(k, &a)| differ[k + 1..].iter().all(|&b| together(a, b)));
        !pruned
    });
    for (_, lw, event) in kept {
        let p = (lw - top).exp();
        total += p;
        for (i, &c) in event.iter().enumerate() {
            if c == usize::MAX {
                miss[i] += p;
            } else {
                dets[i][c] += p;
            }
        }
    }
    miss.iter_mut().for_each(|v| *v /= total);
    dets.iter_mut()
        .for_each(|r| r.iter_mut().for_each(|v| *v /= total));
    Ok(Some(Marginals {
        miss,
        detections: dets,
        nodes: search.visited,
        capped: false,
    }))
}

/// The depth-first enumeration of one cluster's joint events.
struct Search<'a> {
    /// Per row: `ln w(∅)` and `(detection, ln w(j))`.
    logs: &'a [(f64, Vec<(usize, f64)>)],
    /// Words of the detected-tracks part of `key`.
    track_words: usize,
    /// The class of the current partial event: detected tracks' bits, then used detections'.
    key: Vec<u64>,
    /// The current event: per row, the index into its detections or `usize::MAX` (missed).
    choice: Vec<usize>,
    /// Its log weight.
    lw: f64,
    /// Per class: the largest log weight and its event.
    best: HashMap<Vec<u64>, (f64, Vec<usize>)>,
    /// Every complete event: its class, log weight and choices.
    events: Vec<(Vec<u64>, f64, Vec<usize>)>,
    /// Nodes visited.
    visited: usize,
    /// The budget.
    max_nodes: usize,
}

impl Search<'_> {
    /// Extends the current event from row `k`; `false` when the budget ran out.
    fn visit(&mut self, k: usize) -> bool {
        self.visited += 1;
        if self.visited > self.max_nodes {
            return false;
        }
        if k == self.logs.len() {
            if self.lw > f64::NEG_INFINITY {
                let e = self
                    .best
                    .entry(self.key.clone())
                    .or_insert((f64::NEG_INFINITY, Vec::new()));
                if self.lw > e.0 {
                    *e = (self.lw, self.choice.clone());
                }
                self.events
                    .push((self.key.clone(), self.lw, self.choice.clone()));
            }
            return true;
        }
        let logs = self.logs;
        let (miss, detections) = &logs[k];
        self.choice[k] = usize::MAX;
        self.lw += miss;
        let ok = self.visit(k + 1);
        self.lw -= miss;
        if !ok {
            return false;
        }
        let (tw, tb) = (k / 64, 1u64 << (k % 64));
        for (e, &(d, l)) in detections.iter().enumerate() {
            let (dw, db) = (self.track_words + d / 64, 1u64 << (d % 64));
            if self.key[dw] & db != 0 || l == f64::NEG_INFINITY {
                continue;
            }
            self.key[dw] |= db;
            self.key[tw] |= tb;
            self.choice[k] = e;
            self.lw += l;
            let ok = self.visit(k + 1);
            self.lw -= l;
            self.key[dw] &= !db;
            self.key[tw] &= !tb;
            if !ok {
                return false;
            }
        }
        self.choice[k] = usize::MAX;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tracker::ehm;

    #[test]
    fn independent_tracks_are_jpda() {
        // No shared detection: every class has one event, the marginals are EHM's.
        let rows = [
            Row {
                miss: 0.2,
                detections: vec![(0, 1.0), (1, 0.3)],
            },
            Row {
                miss: 0.5,
                detections: vec![(2, 0.7)],
            },
        ];
        let star = marginals(&rows, 3, 1000, |_, _| true).unwrap().unwrap();
        let exact = ehm::marginals(&rows, 3, usize::MAX).unwrap();
        assert_same(&star, &exact);
    }

    /// Two tracks, two detections, each track nearer its own.
    fn two_tracks() -> [Row; 2] {
        [
            Row {
                miss: 0.1,
                detections: vec![(0, 1.0), (1, 0.4)],
            },
            Row {
                miss: 0.1,
                detections: vec![(0, 0.5), (1, 1.0)],
            },
        ]
    }

    fn assert_same(a: &Marginals, b: &Marginals) {
        for i in 0..a.miss.len() {
            assert!((a.miss[i] - b.miss[i]).abs() < 1e-12, "{a:?} vs {b:?}");
            for (x, y) in a.detections[i].iter().zip(&b.detections[i]) {
                assert!((x - y).abs() < 1e-12, "{a:?} vs {b:?}");
            }
        }
    }

    #[test]
    fn the_crossed_permutation_is_pruned() {
        // JPDA gives each track some weight of the other's detection; JPDA* none (the crossed
        // event is the less likely permutation of {τ₀, τ₁} ← {z₀, z₁}), while the
        // one-detection events stay.
        let rows = two_tracks();
        let exact = ehm::marginals(&rows, 2, usize::MAX).unwrap();
        let star = marginals(&rows, 2, 1000, |_, _| true).unwrap().unwrap();
        assert!(exact.detections[0][1] > 0.1, "{exact:?}");
        // Kept: ∅∅ 0.01, z₀∅ 0.1, z₁∅ 0.04, ∅z₀ 0.05, ∅z₁ 0.1, z₀z₁ 1 (z₁z₀ 0.2 pruned).
        let total = 0.01 + 0.1 + 0.04 + 0.05 + 0.1 + 1.0;
        assert!(
            (star.detections[0][0] - 1.1 / total).abs() < 1e-12,
            "{star:?}"
        );
        assert!((star.detections[0][1] - 0.04 / total).abs() < 1e-12);
        assert!((star.detections[1][0] - 0.05 / total).abs() < 1e-12);
        assert!((star.miss[1] - 0.15 / total).abs() < 1e-12);
        for i in 0..2 {
            let s = star.miss[i] + star.detections[i].iter().sum::<f64>();
            assert!((s - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn permutations_of_tracks_that_do_not_move_together_are_kept() {
        // The rows of the pruning test, but the tracks pass each other: nothing is pruned and
        // the marginals are JPDA's.
        let rows = two_tracks();
        let exact = ehm::marginals(&rows, 2, usize::MAX).unwrap();
        let star = marginals(&rows, 2, 1000, |_, _| false).unwrap().unwrap();
        assert_same(&star, &exact);
    }

    #[test]
    fn tracks_move_together_when_their_velocities_are_within_the_gate() {
        let track = |vx: f64, vy: f64| {
            let mut cov = nalgebra::SMatrix::<f64, 4, 4>::identity() * 100.0;
            cov[(2, 2)] = 4.0;
            cov[(3, 3)] = 4.0;
            Gaussian::new(nalgebra::SVector::<f64, 4>::new(0.0, 0.0, vx, vy), cov).unwrap()
        };
        // Sum of the velocity variances 8 (m/s)²: 2 m/s apart is 0.5, 8 m/s apart 8.
        let gate = crate::metrics::chi2_quantile(0.9, 2);
        assert!(move_together(&track(10.0, 0.0), &track(12.0, 0.0), gate));
        assert!(!move_together(&track(10.0, 0.0), &track(10.0, 8.0), gate));
        // Positions do not matter; an infinite gate takes every pair.
        assert!(move_together(
            &track(10.0, 0.0),
            &track(-10.0, 0.0),
            f64::INFINITY
        ));
        // A layout without the [p, v] blocks: together (JPDA*'s pruning applies).
        let g3 = Gaussian::new(
            nalgebra::SVector::<f64, 3>::new(0.0, 1.0, 2.0),
            nalgebra::SMatrix::<f64, 3, 3>::identity(),
        )
        .unwrap();
        let g3b = Gaussian::new(nalgebra::SVector::<f64, 3>::new(0.0, 50.0, 2.0), g3.cov).unwrap();
        assert!(move_together(&g3, &g3b, 1.0));
    }

    #[test]
    fn the_budget_and_bad_weights() {
        let chain: Vec<Row> = (0..12)
            .map(|i| Row {
                miss: 0.2,
                detections: vec![(i, 1.0), (i + 1, 0.5)],
            })
            .collect();
        assert!(marginals(&chain, 13, 100, |_, _| true).unwrap().is_none());
        assert!(
            marginals(&chain, 13, 10_000_000, |_, _| true)
                .unwrap()
                .is_some()
        );
        let bad = [Row {
            miss: f64::NAN,
            detections: vec![],
        }];
        assert!(marginals(&bad, 0, 10, |_, _| true).is_err());
        let none = [Row {
            miss: 0.0,
            detections: vec![],
        }];
        assert!(marginals(&none, 0, 10, |_, _| true).is_err());
    }
}
