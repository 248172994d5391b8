//! The multi-scan associator: a track-oriented multiple-hypothesis tracker (\[TOMHT\]) with
//! N-scan pruning over a sliding window of scans.
//!
//! Every track is a **tree** of hypotheses; its leaves are the different ways the last scans'
//! detections can have been its target's. A scan gives every leaf children: "missed" and one per
//! gated detection, each with the track score (\[BP99\] §6.2, the log-likelihood ratio of "a
//! target" against "clutter and nothing")
//!
//! ```text
//! L ← L + ln(1 − P_D P_G)                     (missed)
//! L ← L + ln(P_D N(zⱼ; ẑ, S) / ρ)              (detection j)
//! L₀ = ln(ψ₀ / (1 − ψ₀))                      (a tree started by one detection)
//! ```
//!
//! and its existence ψ by the IPDA recursion of [`existence`](super::existence) along its path.
//! The **global hypothesis** picks at most one leaf per tree so that no detection of the window
//! is used twice, maximising the summed scores (the MAP assignment over the window; a confirmed
//! tree always keeps one of its leaves when any is compatible): the trees are split into
//! clusters that share detections, and each cluster is solved exactly by branch and bound
//! (`solve`; a search stopped at its node budget keeps the best assignment found, the first of
//! which is the greedy one, and is counted). An id is a tree: a track's estimate may change with
//! the hypotheses, its id does not.
//!
//! **What a track reports** (`Mht::mixture`, the default). Reporting the global hypothesis'
//! leaf alone makes an estimate jump to its neighbour's detections whenever a hypothesis that
//! exchanges two trees' last detections is the best by a hair, and back when the next scans
//! tell. Each tree reports instead the mixture of its leaves, moment-matched, each weighed by its
//! max-marginal, the score of the best global hypothesis that holds it (`max_marginals`, one
//! constrained search per leaf of a cluster of several trees; a lone tree's leaves by their own
//! scores):
//!
//! ```text
//! w_l ∝ exp( max { L(H) : H ∋ l } ),   x̂ = Σ_l w_l x_l,   P = Σ_l w_l [P_l + (x_l − x̂)(x_l − x̂)ᵀ]
//! ```
//!
//! (each leaf's posterior probability over the global hypotheses approximated by its best one,
//! the max-product approximation; the mean is then the MMSE estimate over the leaves); the
//! recursion, the pruning and the confirmation still follow the best global hypothesis. A
//! cluster whose searches exceed `max_search` nodes together reports its chosen leaves
//! (counted).
//!
//! **N-scan pruning.** Once a leaf's history holds `window` scans, the oldest of them is decided
//! by the global hypothesis: a selected tree keeps the leaves that agree with its chosen leaf
//! there, an unselected one drops the leaves that use a detection the global hypothesis gave to
//! another tree there and keeps those that agree with its best remaining leaf. Each tree keeps at
//! most `max_leaves` leaves (the best scores, and the "missed" child of its reported leaf, so that
//! the reported hypotheses stay feasible), all trees together at most `max_hypotheses`. New trees
//! start from the detections that no tree's reported leaf took.
//!
//! # References
//! * \[TOMHT\] T. Kurien, "Issues in the design of practical multitarget tracking algorithms", in
//!   Y. Bar-Shalom (ed.), *Multitarget-Multisensor Tracking: Advanced Applications*, Artech House
//!   1990; S. Blackman, "Multiple hypothesis tracking for multiple target tracking", *IEEE
//!   Aerospace and Electronic Systems Magazine* 19(1), 5–18, 2004.
//! * \[BP99\] S. Blackman, R. Popoli, *Design and Analysis of Modern Tracking Systems*, Artech House
//!   1999, §6.2 (track score), §16.3 (N-scan pruning).

use std::collections::HashMap;

use super::existence::Existence;
use super::track::{DetectionModel, Track, TrackStatus};
use crate::{EstimationError, Result};

/// The multi-scan associator's tuning.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mht {
    /// `P_D` and the clutter density.
    pub detection: DetectionModel,
    /// Existence: the Markov chain, the initial value (also the initial score), and the
    /// thresholds that confirm and delete trees.
    pub existence: Existence,
    /// Scans of the sliding window (≥ 1): a scan's association is final `window − 1` scans later.
    pub window: usize,
    /// Leaves per tree (≥ 1).
    pub max_leaves: usize,
    /// Leaves of all trees together (≥ 1).
    pub max_hypotheses: usize,
    /// Nodes one cluster's search may visit before it keeps its best assignment so far.
    pub max_search: usize,
    /// `Δ ≥ 0`: the global hypothesis' search adds it to the score of every leaf that continues
    /// its tree's reported leaf, so that the reported hypothesis changes only when another is
    /// more likely by a factor `e^Δ` (a hysteresis against estimates flicking between nearly
    /// equal hypotheses).
    pub hysteresis: f64,
    /// What a tree reports: `true` (the default of [`Mht::new`]), the mixture of its leaves
    /// weighed by their max-marginals (module doc); `false`, the leaf of the best global
    /// hypothesis.
    pub mixture: bool,
}

impl Mht {
    /// Checked tuning.
    pub fn new(
        detection: DetectionModel,
        existence: Existence,
        window: usize,
        max_leaves: usize,
        max_hypotheses: usize,
        max_search: usize,
        hysteresis: f64,
    ) -> Result<Self> {
        if window == 0
            || max_leaves == 0
            || max_hypotheses == 0
            || max_search == 0
            || !(hysteresis >= 0.0 && hysteresis.is_finite())
        {
            return Err(EstimationError::InvalidParameter(format!(
                "the multi-scan associator needs a window, leaves, hypotheses and a search of at \
                 least 1 and a hysteresis ≥ 0, got {window}, {max_leaves}, {max_hypotheses}, \
                 {max_search}, {hysteresis}"
            )));
        }
        Ok(Self {
            detection,
            existence,
            window,
            max_leaves,
            max_hypotheses,
            max_search,
            hysteresis,
            mixture: true,
        })
    }
}

/// One detection of a scan: `(scan number, detection index)`.
pub(crate) type Used = (u64, usize);

/// A leaf: one history of a track over the window.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Leaf<S> {
    /// Filter state after the last scan.
    pub state: S,
    /// Track score `L` (module doc).
    pub score: f64,
    /// Existence ψ along this history.
    pub existence: f64,
    /// What the last scans gave it, oldest first: `(scan, detection or None)`.
    pub window: Vec<(u64, Option<usize>)>,
    /// Hits of the whole history.
    pub hits: u32,
    /// Consecutive misses up to the last scan.
    pub consecutive_misses: u32,
    /// Time of its last detection.
    pub last_update: f64,
    /// NIS of its last detection.
    pub nis: f64,
    /// Whether it continues the tree's leaf reported after the last scan.
    pub reported: bool,
    /// Its weight in the tree's reported mixture, this scan (unnormalised).
    pub weight: f64,
}

impl<S> Leaf<S> {
    /// The detections of its window.
    pub(crate) fn used(&self) -> impl Iterator<Item = Used> + '_ {
        self.window.iter().filter_map(|&(s, d)| d.map(|d| (s, d)))
    }
}

/// A track's tree.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Tree<S> {
    /// Track id.
    pub id: u64,
    /// Tentative or confirmed.
    pub status: TrackStatus,
    /// Scans since initiation.
    pub scans: u32,
    /// Its leaves (never empty).
    pub leaves: Vec<Leaf<S>>,
    /// The reported leaf: the global hypothesis' when the tree is in it, else its best.
    pub chosen: usize,
    /// Whether the global hypothesis holds the tree.
    pub selected: bool,
}

/// The multi-scan associator's trees and scan counter.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct MhtState<S> {
    /// The trees, in id order.
    pub trees: Vec<Tree<S>>,
    /// Number of the last scan.
    pub seq: u64,
}

impl<S> Default for MhtState<S> {
    fn default() -> Self {
        Self {
            trees: Vec::new(),
            seq: 0,
        }
    }
}

impl<S: Clone> MhtState<S> {
    /// Trees of one leaf from tracks (an adoption): the score is the existence's log-odds (0.99
    /// for a track without one), the window empty.
    pub(crate) fn adopt(tracks: &[Track<S>]) -> Self {
        let trees = tracks
            .iter()
            .map(|k| {
                let psi = k.existence.unwrap_or(0.99).clamp(1e-9, 1.0 - 1e-9);
                Tree {
                    id: k.id,
                    status: k.status,
                    scans: k.scans,
                    leaves: vec![Leaf {
                        state: k.state.clone(),
                        score: logit(psi),
                        existence: psi,
                        window: Vec::new(),
                        hits: k.hits,
                        consecutive_misses: k.consecutive_misses,
                        last_update: k.last_update,
                        nis: f64::NAN,
                        reported: true,
                        weight: 1.0,
                    }],
                    chosen: 0,
                    selected: true,
                }
            })
            .collect();
        Self { trees, seq: 0 }
    }
}

/// `ln(p / (1 − p))`.
pub(crate) fn logit(p: f64) -> f64 {
    (p / (1.0 - p)).ln()
}

/// One tree of a cluster as the search sees it: its options (score, the leaf, its detections)
/// best first, and whether it may be left out ("none", score 0).
#[derive(Debug, Clone)]
pub(crate) struct Options {
    /// `(score, leaf index, detections)`, best score first.
    pub options: Vec<(f64, usize, Vec<Used>)>,
}

/// The best compatible choice of one option (or none) per entry of `trees` (module doc): exact
/// branch and bound, stopped after `max_nodes` nodes with the best found. Returns the leaf of each
/// tree (`None`: left out) and whether it stopped early.
pub(crate) fn solve(trees: &[Options], max_nodes: usize) -> (Vec<Option<usize>>, bool) {
    let (_, picks, nodes) = search(trees, max_nodes);
    let picks = picks
        .iter()
        .zip(trees)
        .map(|(p, t)| p.map(|o| t.options[o].1))
        .collect();
    (picks, nodes > max_nodes)
}

/// Each option's max-marginal: the summed score of the best compatible choice (as [`solve`]'s)
/// that holds it, per tree in the order of its options; `f64::NEG_INFINITY` for an option that no
/// best choice holding it keeps (it is better left out). `None` when the searches, one per
/// option of every tree, visit more than `max_nodes` nodes together.
pub(crate) fn max_marginals(trees: &[Options], max_nodes: usize) -> Option<Vec<Vec<f64>>> {
    let mut spent = 0;
    let mut fixed = trees.to_vec();
    let mut out = Vec::with_capacity(trees.len());
    for (k, tree) in trees.iter().enumerate() {
        let mut values = Vec::with_capacity(tree.options.len());
        for o in &tree.options {
            fixed[k].options = vec![o.clone()];
            let (value, picks, nodes) = search(&fixed, max_nodes - spent);
            spent += nodes;
            if spent > max_nodes {
                return None;
            }
            values.push(if picks[k].is_some() {
                value
            } else {
                f64::NEG_INFINITY
            });
        }
        fixed[k].options.clone_from(&tree.options);
        out.push(values);
    }
    Some(out)
}

/// [`solve`]'s branch and bound: the best summed score, the option of each tree (`None`: left
/// out) and the nodes visited.
fn search(trees: &[Options], max_nodes: usize) -> (f64, Vec<Option<usize>>, usize) {
    struct Search<'a> {
        trees: &'a [Options],
        /// Σ of the best positive option of trees k.. (the bound of what is left).
        rest: Vec<f64>,
        taken: HashMap<Used, ()>,
        pick: Vec<Option<usize>>,
        best: (f64, Vec<Option<usize>>),
        nodes: usize,
        max_nodes: usize,
    }
    impl Search<'_> {
        fn go(&mut self, k: usize, value: f64) {
            self.nodes += 1;
            if k == self.trees.len() {
                if value > self.best.0 {
                    self.best = (value, self.pick.clone());
                }
                return;
            }
            if value + self.rest[k] <= self.best.0 || self.spent() {
                return;
            }
            for o in 0..self.trees[k].options.len() {
                let (score, _, used) = &self.trees[k].options[o];
                if used.iter().any(|u| self.taken.contains_key(u)) {
                    continue;
                }
                for u in used {
                    self.taken.insert(*u, ());
                }
                self.pick[k] = Some(o);
                self.go(k + 1, value + score);
                self.pick[k] = None;
                for u in used {
                    self.taken.remove(u);
                }
                if self.spent() {
                    return;
                }
            }
            self.go(k + 1, value);
        }
        /// The budget is spent once a complete assignment has been found (the first descent,
        /// the greedy one, always completes).
        fn spent(&self) -> bool {
            self.nodes > self.max_nodes && self.best.0 > f64::NEG_INFINITY
        }
    }
    let mut rest = vec![0.0; trees.len() + 1];
    for k in (0..trees.len()).rev() {
        let top = trees[k].options.first().map_or(0.0, |o| o.0.max(0.0));
        rest[k] = rest[k + 1] + top;
    }
    let mut s = Search {
        trees,
        rest,
        taken: HashMap::new(),
        pick: vec![None; trees.len()],
        best: (f64::NEG_INFINITY, vec![None; trees.len()]),
        nodes: 0,
        max_nodes,
    };
    s.go(0, 0.0);
    (s.best.0, s.best.1, s.nodes)
}

/// Clusters of trees (indices) whose leaves share a detection of the window, in order of their
/// first tree.
pub(crate) fn clusters<S>(trees: &[Tree<S>]) -> Vec<Vec<usize>> {
    fn find(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    let mut parent: Vec<usize> = (0..trees.len()).collect();
    let mut owner: HashMap<Used, usize> = HashMap::new();
    for (i, t) in trees.iter().enumerate() {
        for u in t.leaves.iter().flat_map(Leaf::used) {
            match owner.get(&u) {
                None => {
                    owner.insert(u, i);
                }
                Some(&o) => {
                    let (a, b) = (find(&mut parent, o), find(&mut parent, i));
                    if a != b {
                        parent[a.max(b)] = a.min(b);
                    }
                }
            }
        }
    }
    let mut slot = vec![usize::MAX; trees.len()];
    let mut out: Vec<Vec<usize>> = Vec::new();
    for i in 0..trees.len() {
        let r = find(&mut parent, i);
        if slot[r] == usize::MAX {
            slot[r] = out.len();
            out.push(Vec::new());
        }
        out[slot[r]].push(i);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn opts(o: &[(f64, &[Used])]) -> Options {
        let mut options: Vec<(f64, usize, Vec<Used>)> = o
            .iter()
            .enumerate()
            .map(|(i, (s, u))| (*s, i, u.to_vec()))
            .collect();
        options.sort_by(|a, b| b.0.total_cmp(&a.0));
        Options { options }
    }

    /// 1–4 trees of 1–3 options, each scored in −5..10 with 0–2 detections of 3 scans × 3.
    fn random_trees(rng: &mut rand_chacha::ChaCha8Rng) -> Vec<Options> {
        (0..rng.random_range(1..5))
            .map(|_| {
                let o: Vec<(f64, Vec<Used>)> = (0..rng.random_range(1..4))
                    .map(|_| {
                        let u: Vec<Used> = (0..rng.random_range(0..3))
                            .map(|s| (s, rng.random_range(0..3)))
                            .collect();
                        (rng.random_range(-5.0..10.0), u)
                    })
                    .collect();
                let r: Vec<(f64, &[Used])> = o.iter().map(|(s, u)| (*s, u.as_slice())).collect();
                opts(&r)
            })
            .collect()
    }

    #[test]
    fn the_search_finds_the_best_compatible_set() {
        // Tree 0 prefers detection (1, 0); tree 1 needs it more: 5 + 9 > 8 + 2.
        let trees = [
            opts(&[(8.0, &[(1, 0)]), (5.0, &[(1, 1)])]),
            opts(&[(9.0, &[(1, 0)]), (2.0, &[])]),
        ];
        assert_eq!(solve(&trees, 1000), (vec![Some(1), Some(0)], false));
        // A tree whose every option is negative is left out.
        let trees = [opts(&[(-1.0, &[(2, 3)])]), opts(&[(1.0, &[(2, 4)])])];
        assert_eq!(solve(&trees, 1000).0, vec![None, Some(0)]);
        // Against brute force on random small instances.
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for _ in 0..300 {
            let trees = random_trees(&mut rng);
            let (got, stopped) = solve(&trees, usize::MAX);
            assert!(!stopped);
            let value = |p: &[Option<usize>]| -> Option<f64> {
                let mut seen = std::collections::HashSet::new();
                let mut v = 0.0;
                for (t, o) in trees.iter().zip(p) {
                    if let Some(o) = o {
                        let (s, _, u) = t.options.iter().find(|x| x.1 == *o)?;
                        for x in u {
                            if !seen.insert(*x) {
                                return None;
                            }
                        }
                        v += s;
                    }
                }
                Some(v)
            };
            // Brute force over every choice.
            let mut best = f64::NEG_INFINITY;
            let mut pick = vec![None; trees.len()];
            fn all(
                k: usize,
                trees: &[Options],
                pick: &mut Vec<Option<usize>>,
                f: &mut dyn FnMut(&[Option<usize>]),
            ) {
                if k == trees.len() {
                    f(pick);
                    return;
                }
                for o in trees[k].options.iter().map(|o| Some(o.1)).chain([None]) {
                    pick[k] = o;
                    all(k + 1, trees, pick, f);
                }
            }
            all(0, &trees, &mut pick, &mut |p| {
                if let Some(v) = value(p) {
                    best = best.max(v);
                }
            });
            let v = value(&got).expect("a compatible set");
            assert!((v - best).abs() < 1e-9, "{v} vs {best}");
        }
        // A budget of one node keeps the greedy first path and says so.
        let trees = [
            opts(&[(8.0, &[(1, 0)]), (5.0, &[(1, 1)])]),
            opts(&[(9.0, &[(1, 0)]), (2.0, &[])]),
        ];
        let (p, stopped) = solve(&trees, 1);
        assert!(stopped);
        assert_eq!(p, vec![Some(0), Some(1)]);
    }

    /// Every option's max-marginal is the best compatible set that holds it (brute force over
    /// every set), or −∞ where leaving its tree out is better; a budget too small for the
    /// searches gives none.
    #[test]
    fn the_max_marginals_are_the_best_sets_holding_each_option() {
        // Two trees after the same two detections: 8 + 9 holds (0, a) and (1, b); the swap 9 + 5.
        let trees = [
            opts(&[(8.0, &[(1, 0)]), (9.0, &[(1, 1)])]),
            opts(&[(9.0, &[(1, 1)]), (5.0, &[(1, 0)])]),
        ];
        let m = max_marginals(&trees, 1000).expect("within the budget");
        // Options are best first: tree 0 (9, b), (8, a); tree 1 (9, b), (5, a).
        assert_eq!(m, vec![vec![14.0, 17.0], vec![17.0, 14.0]]);
        assert!(max_marginals(&trees, 2).is_none());
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..300 {
            let trees = random_trees(&mut rng);
            let got = max_marginals(&trees, usize::MAX).expect("no budget");
            // Brute force: every choice of an option index (or none) per tree.
            let n = trees.len();
            let mut choices: Vec<Vec<Option<usize>>> = vec![Vec::new()];
            for t in &trees {
                choices = choices
                    .into_iter()
                    .flat_map(|c| {
                        (0..t.options.len()).map(Some).chain([None]).map(move |o| {
                            let mut c = c.clone();
                            c.push(o);
                            c
                        })
                    })
                    .collect();
            }
            let value = |c: &[Option<usize>]| -> Option<f64> {
                let mut seen = std::collections::HashSet::new();
                let mut v = 0.0;
                for (t, o) in trees.iter().zip(c) {
                    if let Some(o) = o {
                        let (s, _, u) = &t.options[*o];
                        for x in u {
                            if !seen.insert(*x) {
                                return None;
                            }
                        }
                        v += s;
                    }
                }
                Some(v)
            };
            for k in 0..n {
                let without = choices
                    .iter()
                    .filter(|c| c[k].is_none())
                    .filter_map(|c| value(c))
                    .fold(f64::NEG_INFINITY, f64::max);
                for (o, &g) in got[k].iter().enumerate() {
                    let with = choices
                        .iter()
                        .filter(|c| c[k] == Some(o))
                        .filter_map(|c| value(c))
                        .fold(f64::NEG_INFINITY, f64::max);
                    let want = if with >= without {
                        with
                    } else {
                        f64::NEG_INFINITY
                    };
                    assert!(
                        g == want || (g - want).abs() < 1e-9,
                        "tree {k} option {o}: {g} vs {want}"
                    );
                }
            }
        }
    }
}
