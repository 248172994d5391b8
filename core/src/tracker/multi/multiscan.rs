//! The step of the multi-scan associator ([`mht`](crate::tracker::mht)): grow every tree by the
//! scan, solve the global hypothesis cluster by cluster, prune by the window, confirm and delete,
//! start trees from the unused detections, and report each tree's chosen leaf as its track.

use nalgebra::SVector;

use super::{Track, TrackEvent, TrackStatus, Tracker};
use crate::Result;
use crate::measurement::{Locate, MeasurementModel};
use crate::state::{Gaussian, moment_match};
use crate::tracker::associate::{Gater, TrackHypotheses, hypothesise_scan};
use crate::tracker::delete::DeleteReason;
use crate::tracker::filter::TrackFilter;
use crate::tracker::initiate::Initiator;
use crate::tracker::mht::{Leaf, Mht, Options, Tree, Used, clusters, logit, max_marginals, solve};

/// What a confirmed tree's leaves get on top of their score in the global hypothesis, so that a
/// confirmed track keeps a leaf whenever one is compatible (far above any sum of track scores).
const CONFIRMED_BONUS: f64 = 1e9;

impl<F, I, const N: usize> Tracker<F, I, N>
where
    F: TrackFilter<N>,
    I: Initiator<N>,
{
    /// One scan of the multi-scan associator (the caller checked the input).
    pub(super) fn step_mht<H, const M: usize>(
        &mut self,
        m: &Mht,
        t: f64,
        dt: f64,
        sensor: &H,
        detections: &[SVector<f64, M>],
    ) -> Result<Vec<TrackEvent>>
    where
        H: MeasurementModel<N, M> + Locate<M>,
    {
        let seq = self.mht.seq + 1;
        let mut events = Vec::new();

        // Predict every leaf; a tree none of whose leaves can be predicted is deleted.
        let mut trees: Vec<Tree<F::State>> = Vec::with_capacity(self.mht.trees.len());
        for tree in &self.mht.trees {
            let mut leaves = Vec::with_capacity(tree.leaves.len());
            let mut chosen = None;
            let mut failure = None;
            for (i, l) in tree.leaves.iter().enumerate() {
                let state = if dt > 0.0 {
                    match self.filter.predict(&l.state, dt) {
                        Ok(s) => s,
                        Err(e) => {
                            failure = Some(e.to_string());
                            continue;
                        }
                    }
                } else {
                    l.state.clone()
                };
                if i == tree.chosen {
                    chosen = Some(leaves.len());
                }
                leaves.push(Leaf {
                    state,
                    existence: m.existence.predict(l.existence, dt),
                    ..l.clone()
                });
            }
            if leaves.is_empty() {
                events.push(TrackEvent::Deleted {
                    id: tree.id,
                    reason: DeleteReason::Failed(failure.unwrap_or_default()),
                });
                continue;
            }
            trees.push(Tree {
                leaves,
                chosen: chosen.unwrap_or(0),
                scans: tree.scans + 1,
                ..tree.clone()
            });
        }

        // Gate every leaf against the detections near it.
        let gaters: Vec<Gater> = trees
            .iter()
            .map(|k| self.config.gater_for(k.status))
            .collect();
        let states: Vec<(&F::State, &Gater)> = trees
            .iter()
            .zip(&gaters)
            .flat_map(|(k, g)| k.leaves.iter().map(move |l| (&l.state, g)))
            .collect();
        let mut hyps = hypothesise_scan(&self.filter, &states, sensor, detections).into_iter();

        // Grow: each leaf's "missed" child and one child per gated detection.
        let pd = m.detection.pd;
        let mut total = 0;
        for (tree, gater) in trees.iter_mut().zip(&gaters) {
            let mut children: Vec<(Leaf<F::State>, bool)> = Vec::new();
            let mut failed = None;
            for (li, leaf) in tree.leaves.iter().enumerate() {
                let h = hyps
                    .next()
                    .and_then(|h| h.map_err(|e| failed = Some(e)).ok());
                let h = h.unwrap_or_default();
                let pdpg = pd * gater.probability_for(h.dim.max(1));
                let psi = leaf.existence;
                let mut window = leaf.window.clone();
                window.push((seq, None));
                // The miss child of the reported leaf is kept whatever the bound: it keeps the
                // reported hypotheses feasible.
                children.push((
                    Leaf {
                        state: leaf.state.clone(),
                        score: leaf.score + (1.0 - pdpg).ln(),
                        existence: (1.0 - pdpg) * psi / (1.0 - pdpg * psi),
                        window,
                        consecutive_misses: leaf.consecutive_misses + 1,
                        reported: li == tree.chosen,
                        ..leaf.clone()
                    },
                    li == tree.chosen,
                ));
                let rho = m
                    .detection
                    .clutter_density
                    .unwrap_or_else(|| leaf_clutter(&h, pdpg * psi));
                for g in &h.gated {
                    let Ok(state) =
                        self.filter
                            .update(&leaf.state, sensor, &detections[g.detection])
                    else {
                        continue;
                    };
                    let ln_ratio = pd.ln() + h.log_likelihood(g.distance_sq) - rho.ln();
                    let ratio = ln_ratio.exp();
                    let delta = pdpg - ratio;
                    let mut window = leaf.window.clone();
                    window.push((seq, Some(g.detection)));
                    children.push((
                        Leaf {
                            state,
                            score: leaf.score + ln_ratio,
                            existence: ((1.0 - delta) * psi / (1.0 - delta * psi)).clamp(0.0, 1.0),
                            window,
                            hits: leaf.hits + 1,
                            consecutive_misses: 0,
                            last_update: t,
                            nis: g.distance_sq,
                            reported: li == tree.chosen,
                            weight: 0.0,
                        },
                        false,
                    ));
                }
            }
            if let Some(e) = failed {
                events.push(TrackEvent::Rejected {
                    id: Some(tree.id),
                    detection: None,
                    reason: format!("measurement prediction: {e}"),
                });
            }
            // Best first; the protected child first among equals, and always kept.
            children.sort_by(|a, b| b.0.score.total_cmp(&a.0.score).then(b.1.cmp(&a.1)));
            let keep = m.max_leaves.max(1);
            let protected = children.iter().position(|c| c.1);
            if let Some(p) = protected.filter(|&p| p >= keep) {
                children.swap(keep - 1, p);
            }
            children.truncate(keep);
            tree.leaves = children.into_iter().map(|c| c.0).collect();
            tree.chosen = 0;
            total += tree.leaves.len();
        }
        cap_hypotheses(&mut trees, total, m.max_hypotheses);

        // The global hypothesis, cluster by cluster.
        for c in clusters(&trees) {
            let opts: Vec<Options> = c
                .iter()
                .map(|&i| {
                    let bonus = if trees[i].status == TrackStatus::Confirmed {
                        CONFIRMED_BONUS
                    } else {
                        0.0
                    };
                    let options = trees[i]
                        .leaves
                        .iter()
                        .enumerate()
                        .map(|(li, l)| {
                            let sticky = if l.reported { m.hysteresis } else { 0.0 };
                            (l.score + bonus + sticky, li, l.used().collect())
                        })
                        .collect();
                    Options { options }
                })
                .collect();
            let (picks, stopped) = solve(&opts, m.max_search);
            self.stats.clusters += 1;
            self.stats.largest_cluster = self.stats.largest_cluster.max(c.len());
            // Each leaf's weight in its tree's reported mixture: its max-marginal against the
            // best one's (a lone tree: its score); within the search budget, else the chosen
            // leaf alone (counted).
            let marginals = if !m.mixture {
                None
            } else if c.len() == 1 {
                Some(vec![opts[0].options.iter().map(|o| o.0).collect()])
            } else {
                max_marginals(&opts, m.max_search)
            };
            self.stats.capped += u64::from(stopped || (m.mixture && marginals.is_none()));
            for (&i, p) in c.iter().zip(picks) {
                let tree = &mut trees[i];
                tree.selected = p.is_some();
                tree.chosen = p.unwrap_or(0);
                for (li, l) in tree.leaves.iter_mut().enumerate() {
                    l.weight = if li == tree.chosen { 1.0 } else { 0.0 };
                }
            }
            if let Some(values) = marginals {
                for ((&i, o), v) in c.iter().zip(&opts).zip(values) {
                    let top = v.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                    if !top.is_finite() {
                        continue;
                    }
                    for (&(_, leaf, _), v) in o.options.iter().zip(&v) {
                        trees[i].leaves[leaf].weight = (v - top).exp();
                    }
                }
            }
        }
        self.stats.largest_net = self
            .stats
            .largest_net
            .max(trees.iter().map(|k| k.leaves.len()).sum());

        // N-scan pruning of the oldest scan once the window is full.
        if trees
            .iter()
            .flat_map(|k| k.leaves.iter())
            .any(|l| l.window.len() >= m.window)
        {
            prune_oldest(&mut trees, m.window);
            // A tree every leaf of which the decision contradicts is gone.
            trees.retain(|k| {
                let alive = !k.leaves.is_empty();
                if !alive {
                    events.push(TrackEvent::Deleted {
                        id: k.id,
                        reason: super::gone_by_existence(k.status),
                    });
                }
                alive
            });
        }

        // Confirm, delete, report.
        let mut kept = Vec::with_capacity(trees.len() + detections.len());
        let mut used_now: Vec<bool> = vec![false; detections.len()];
        for mut tree in trees {
            let best = tree.leaves.iter().map(|l| l.existence).fold(0.0, f64::max);
            let leaf = &tree.leaves[tree.chosen];
            if best < m.existence.delete {
                events.push(TrackEvent::Deleted {
                    id: tree.id,
                    reason: super::gone_by_existence(tree.status),
                });
                continue;
            }
            match leaf.window.last() {
                Some(&(s, Some(d))) if s == seq => {
                    // Taken by this tree's best explanation (selected or not): no new tree.
                    used_now[d] = true;
                    events.push(TrackEvent::Updated {
                        id: tree.id,
                        detection: d,
                        nis: leaf.nis,
                    });
                }
                _ => events.push(TrackEvent::Coasted {
                    id: tree.id,
                    misses: leaf.consecutive_misses,
                }),
            }
            if tree.status == TrackStatus::Tentative
                && tree.selected
                && leaf.existence >= m.existence.confirm
            {
                tree.status = TrackStatus::Confirmed;
                events.push(TrackEvent::Confirmed { id: tree.id });
            }
            if tree.status == TrackStatus::Confirmed {
                let estimate = self.filter.estimate(&leaf.state);
                if let Some(reason) = self.config.deleter.judge(0, &estimate) {
                    events.push(TrackEvent::Deleted {
                        id: tree.id,
                        reason,
                    });
                    continue;
                }
            }
            kept.push(tree);
        }

        // New trees from the detections no tree's reported leaf took.
        let psi0 = m.existence.initial;
        for (j, z) in detections.iter().enumerate() {
            if used_now[j] {
                continue;
            }
            let k = match self.start(sensor, z, t, Some(psi0)) {
                Ok(k) => k,
                Err(reason) => {
                    events.push(TrackEvent::Rejected {
                        id: None,
                        detection: Some(j),
                        reason: format!("initiation: {reason}"),
                    });
                    continue;
                }
            };
            let id = self.next_id;
            self.next_id += 1;
            events.push(TrackEvent::Born { id, detection: j });
            let confirmed = psi0 >= m.existence.confirm;
            if confirmed {
                events.push(TrackEvent::Confirmed { id });
            }
            kept.push(Tree {
                id,
                status: if confirmed {
                    TrackStatus::Confirmed
                } else {
                    TrackStatus::Tentative
                },
                scans: 1,
                leaves: vec![Leaf {
                    state: k.state,
                    score: logit(psi0),
                    existence: psi0,
                    window: vec![(seq, Some(j))],
                    hits: 1,
                    consecutive_misses: 0,
                    last_update: t,
                    nis: f64::NAN,
                    reported: true,
                    weight: 1.0,
                }],
                chosen: 0,
                selected: false,
            });
        }
        kept.sort_by_key(|k| k.id);
        self.tracks = kept
            .iter()
            .map(|k| {
                let l = &k.leaves[k.chosen];
                Track {
                    id: k.id,
                    state: self.reported(k),
                    status: k.status,
                    scans: k.scans,
                    hits: l.hits,
                    consecutive_misses: l.consecutive_misses,
                    last_update: l.last_update,
                    existence: Some(l.existence),
                }
            })
            .collect();
        self.mht.trees = kept;
        self.mht.seq = seq;
        Ok(events)
    }
}

impl<F, I, const N: usize> Tracker<F, I, N>
where
    F: TrackFilter<N>,
    I: Initiator<N>,
{
    /// What a tree reports: its leaves' mixture by their weights, moment-matched
    /// ([`TrackFilter::recentre`] of the chosen leaf), or the chosen leaf alone when it is the
    /// only one weighed or the mixture cannot be formed.
    fn reported(&self, k: &Tree<F::State>) -> F::State {
        let chosen = &k.leaves[k.chosen].state;
        let total: f64 = k.leaves.iter().map(|l| l.weight).sum();
        if k.leaves.iter().filter(|l| l.weight > 0.0).count() < 2 || !total.is_finite() {
            return chosen.clone();
        }
        let (gs, ws): (Vec<Gaussian<N>>, Vec<f64>) = k
            .leaves
            .iter()
            .filter(|l| l.weight > 0.0)
            .map(|l| (self.filter.estimate(&l.state), l.weight / total))
            .unzip();
        self.filter
            .recentre(chosen, moment_match(&gs, &ws))
            .unwrap_or_else(|_| chosen.clone())
    }
}

/// The non-parametric clutter density of one leaf's gate (as JIPDA's of a lone track): the
/// detections in it beyond the `expected` target detection, over its volume.
fn leaf_clutter(h: &TrackHypotheses, expected: f64) -> f64 {
    let m = h.dim.max(1) as f64;
    let volume = crate::metrics::unit_ball_volume(h.dim.max(1))
        * (0.5 * m * h.gate.ln() + 0.5 * h.ln_det_s).exp();
    (h.gated.len() as f64 - expected).max(0.1) / volume
}

/// Drops the worst leaves of every tree but their best one until at most `max` remain.
fn cap_hypotheses<S>(trees: &mut [Tree<S>], total: usize, max: usize) {
    if total <= max {
        return;
    }
    // The score below which leaves go: the `max`-th best of the droppable ones.
    let mut scores: Vec<f64> = trees
        .iter()
        .flat_map(|k| k.leaves.iter().skip(1).map(|l| l.score))
        .collect();
    let keep = max.saturating_sub(trees.len()).min(scores.len());
    if keep == scores.len() {
        return;
    }
    scores.select_nth_unstable_by(keep, |a, b| b.total_cmp(a));
    let cut = scores[keep];
    for k in trees.iter_mut() {
        let mut first = true;
        k.leaves
            .retain(|l| std::mem::replace(&mut first, false) || l.score > cut);
    }
}

/// N-scan pruning (module doc of [`mht`](crate::tracker::mht)): the oldest scan of the full
/// windows is decided by the global hypothesis, then dropped from every window. A tree may be
/// left without leaves.
fn prune_oldest<S>(trees: &mut [Tree<S>], window: usize) {
    let oldest = |l: &Leaf<S>| (l.window.len() >= window).then(|| l.window[0]);
    // What the global hypothesis decided at that scan.
    let decided: Vec<Used> = trees
        .iter()
        .filter(|k| k.selected)
        .filter_map(|k| oldest(&k.leaves[k.chosen]).and_then(|(s, d)| d.map(|d| (s, d))))
        .collect();
    for k in trees.iter_mut() {
        let keep = if k.selected {
            oldest(&k.leaves[k.chosen])
        } else {
            // The best leaf whose oldest choice no selected tree contradicts.
            k.leaves
                .iter()
                .filter_map(oldest)
                .find(|(s, d)| d.is_none_or(|d| !decided.contains(&(*s, d))))
        };
        let chosen_window = k.leaves[k.chosen].window.clone();
        if let Some(w) = keep {
            k.leaves.retain(|l| oldest(l).is_none_or(|o| o == w));
        } else if !k.selected {
            k.leaves.retain(|l| {
                oldest(l).is_none_or(|(s, d)| d.is_none_or(|d| !decided.contains(&(s, d))))
            });
        }
        if k.leaves.is_empty() {
            continue;
        }
        k.chosen = k
            .leaves
            .iter()
            .position(|l| l.window == chosen_window)
            .unwrap_or(0);
        for l in &mut k.leaves {
            if l.window.len() >= window {
                l.window.remove(0);
            }
        }
    }
}
