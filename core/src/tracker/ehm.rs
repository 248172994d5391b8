//! Exact marginal association probabilities of a cluster of tracks without enumerating its joint
//! events: efficient hypothesis management (\[EHM\], with the ordering that keeps the net narrow).
//!
//! A joint event gives each track of the cluster "no detection" or one of its gated detections,
//! no detection to two tracks, and has the weight `Π_τ w_τ(e_τ)` (for JIPDA
//! `w_τ(∅) = 1 − P_D P_G ψ_τ`, `w_τ(j) = P_D ψ_τ N(zⱼ) / ρ`). The marginals
//! `P(τ ← j) = Σ_{e: e_τ = j} Π w / Σ_e Π w` need no list of events: process the tracks in an order
//! τ₁ … τ_n; what the tracks after τ_k can still do depends on the earlier choices only through
//! the set of used detections that a later track also gates. These sets are the nodes of a layered
//! net (layer k: the nodes before τ_k decides); each choice of τ_k is an edge to the node of layer
//! k + 1 of the set it leaves. Forward weights `F` (sum over the paths from the root) and backward
//! weights `B` (sum over the paths to the leaf) give
//!
//! ```text
//! F_{k+1}(s') = Σ_{s, e: s →e s'} F_k(s) w_{τ_k}(e)          B_k(s) = Σ_{e: s →e s'} w_{τ_k}(e) B_{k+1}(s')
//! P(τ_k ← e) = Σ_{s →e s'} F_k(s) w_{τ_k}(e) B_{k+1}(s') / B_0(∅)
//! ```
//!
//! exactly the brute-force marginals (tested against enumeration). The net's width is the number
//! of distinct "used and still contested" sets, small when tracks are ordered so that a detection
//! is decided soon after it is first used: tracks are ordered breadth first over the
//! track–detection graph from its least connected track (what \[EHM2\] achieves with its tree of
//! conditionally independent sub-clusters; a lone track is one layer, IPDA). A detection that only
//! one track gates never enters a node.
//!
//! **Bound.** A layer with more than `max_nodes` nodes keeps the `max_nodes` of largest forward
//! weight (the joint events through the others are dropped, and every track's marginals are
//! renormalised): the fallback for a huge cluster, reported as `capped` so that the tracker counts
//! it.
//!
//! # References
//! * \[EHM\] S. Maskell, M. Briers, R. Wright, "Fast mutual exclusion", *Signal and Data
//!   Processing of Small Targets*, Proc. SPIE 5428, 526–536, 2004.
//! * \[EHM2\] P. Horridge, S. Maskell, "Real-time tracking of hundreds of targets with efficient
//!   exact JPDAF implementation", 9th Int. Conf. on Information Fusion, 2006.

use std::collections::{HashMap, VecDeque};

use crate::{EstimationError, Result};

/// One track of a cluster: the weight of "no detection" and of each gated detection.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Row {
    /// `w(∅) ≥ 0`.
    pub miss: f64,
    /// `(detection, w(j) ≥ 0)`, detections as indices `0..n_det` of the cluster, each once.
    pub detections: Vec<(usize, f64)>,
}

/// The marginal probabilities of one cluster.
#[derive(Debug, Clone, PartialEq)]
pub struct Marginals {
    /// `P(τ ← ∅)` of each row.
    pub miss: Vec<f64>,
    /// `P(τ ← j)` of each row, in the order of its `detections`.
    pub detections: Vec<Vec<f64>>,
    /// Nodes of the net (all layers).
    pub nodes: usize,
    /// Whether a layer was cut to `max_nodes` (the marginals are then approximate).
    pub capped: bool,
}

/// A set of contested detections: one bit per detection gated by two tracks or more.
type Key = Box<[u64]>;

/// The exact marginals of the rows' joint events (module doc), the net capped at `max_nodes`
/// nodes per layer (≥ 1). Fails when a weight is negative or not finite, or no joint event has a
/// positive weight.
pub fn marginals(rows: &[Row], n_det: usize, max_nodes: usize) -> Result<Marginals> {
    let n = rows.len();
    check_rows(rows, n_det)?;
    // Scale each row to a largest weight of 1: every joint event has one factor per row, so the
    // marginals do not change, and products stay in range.
    let rows: Vec<Row> = rows
        .iter()
        .map(|r| {
            let top = r.detections.iter().map(|d| d.1).fold(r.miss, f64::max);
            let s = if top > 0.0 { 1.0 / top } else { 1.0 };
            Row {
                miss: r.miss * s,
                detections: r.detections.iter().map(|&(d, w)| (d, w * s)).collect(),
            }
        })
        .collect();
    if let [row] = rows.as_slice() {
        // A lone track: one layer, the weights normalised (IPDA).
        let total = row.miss + row.detections.iter().map(|d| d.1).sum::<f64>();
        if !(total > 0.0 && total.is_finite()) {
            return Err(EstimationError::NonFinite("association marginals"));
        }
        return Ok(Marginals {
            miss: vec![row.miss / total],
            detections: vec![row.detections.iter().map(|d| d.1 / total).collect()],
            nodes: 2,
            capped: false,
        });
    }
    let order = breadth_first(&rows, n_det);
    // Position in `order` of the last row that gates each detection, and the contested
    // detections' bit numbers.
    let mut last = vec![0usize; n_det];
    let mut users = vec![0usize; n_det];
    for (p, &i) in order.iter().enumerate() {
        for &(d, _) in &rows[i].detections {
            last[d] = p;
            users[d] += 1;
        }
    }
    let mut bit = vec![usize::MAX; n_det];
    let mut n_bits = 0;
    for d in 0..n_det {
        if users[d] > 1 {
            bit[d] = n_bits;
            n_bits += 1;
        }
    }
    let words = n_bits.div_ceil(64).max(1);
    let empty: Key = vec![0u64; words].into_boxed_slice();
    // alive[p]: the bits of the contested detections that a row after position p still gates.
    let alive: Vec<Key> = (0..n)
        .map(|p| {
            let mut k = empty.clone();
            for d in 0..n_det {
                let b = bit[d];
                if b != usize::MAX && last[d] > p {
                    k[b / 64] |= 1u64 << (b % 64);
                }
            }
            k
        })
        .collect();

    // Forward pass: the layers' nodes with their forward weights, and each node's edges
    // (choice: usize::MAX = miss, else the index into the row's detections; child node).
    let mut layers: Vec<Vec<(Key, f64)>> = vec![vec![(empty.clone(), 1.0)]];
    let mut edges: Vec<Vec<Vec<(usize, usize)>>> = Vec::with_capacity(n);
    let mut capped = false;
    for (p, &i) in order.iter().enumerate() {
        let row = &rows[i];
        let mut next: Vec<(Key, f64)> = Vec::new();
        let mut at: HashMap<Key, usize> = HashMap::new();
        let mut layer_edges = Vec::with_capacity(layers[p].len());
        for (key, f) in &layers[p] {
            let mut out = Vec::with_capacity(row.detections.len() + 1);
            let mut go = |child: Key, w: f64, choice: usize| {
                let c = *at.entry(child.clone()).or_insert_with(|| {
                    next.push((child, 0.0));
                    next.len() - 1
                });
                next[c].1 += f * w;
                out.push((choice, c));
            };
            // Bits of detections that no row after this one gates are dropped from the child.
            let keep = |mut k: Key| {
                k.iter_mut().zip(alive[p].iter()).for_each(|(w, a)| *w &= a);
                k
            };
            go(keep(key.clone()), row.miss, usize::MAX);
            for (e, &(d, w)) in row.detections.iter().enumerate() {
                let b = bit[d];
                if b != usize::MAX && key[b / 64] & (1u64 << (b % 64)) != 0 {
                    continue; // used by an earlier row of this path
                }
                let mut child = key.clone();
                if b != usize::MAX {
                    child[b / 64] |= 1u64 << (b % 64);
                }
                go(keep(child), w, e);
            }
            layer_edges.push(out);
        }
        if next.len() > max_nodes.max(1) {
            capped = true;
            let mut by_weight: Vec<usize> = (0..next.len()).collect();
            by_weight.sort_by(|&a, &b| next[b].1.total_cmp(&next[a].1));
            let mut remap = vec![usize::MAX; next.len()];
            let mut kept = Vec::with_capacity(max_nodes);
            for (new, &old) in by_weight.iter().take(max_nodes.max(1)).enumerate() {
                remap[old] = new;
                kept.push(next[old].clone());
            }
            for out in &mut layer_edges {
                out.retain_mut(|(_, c)| {
                    *c = remap[*c];
                    *c != usize::MAX
                });
            }
            next = kept;
        }
        // Keep the forward weights of a layer summing to 1 (the marginals are ratios).
        let total: f64 = next.iter().map(|x| x.1).sum();
        if total > 0.0 {
            next.iter_mut().for_each(|x| x.1 /= total);
        }
        edges.push(layer_edges);
        layers.push(next);
    }

    // Backward pass and marginals, layer by layer from the leaf.
    let mut back = vec![1.0; layers[n].len()];
    let mut miss = vec![0.0; n];
    let mut dets: Vec<Vec<f64>> = rows.iter().map(|r| vec![0.0; r.detections.len()]).collect();
    for p in (0..n).rev() {
        let i = order[p];
        let row = &rows[i];
        let mut b = vec![0.0; layers[p].len()];
        for (s, out) in edges[p].iter().enumerate() {
            let f = layers[p][s].1;
            for &(choice, c) in out {
                let w = if choice == usize::MAX {
                    row.miss
                } else {
                    row.detections[choice].1
                };
                let wb = w * back[c];
                b[s] += wb;
                if choice == usize::MAX {
                    miss[i] += f * wb;
                } else {
                    dets[i][choice] += f * wb;
                }
            }
        }
        let total = miss[i] + dets[i].iter().sum::<f64>();
        if !(total > 0.0 && total.is_finite()) {
            return Err(EstimationError::NonFinite("association marginals"));
        }
        miss[i] /= total;
        dets[i].iter_mut().for_each(|v| *v /= total);
        let scale: f64 = b.iter().sum();
        if scale > 0.0 {
            b.iter_mut().for_each(|v| *v /= scale);
        }
        back = b;
    }
    Ok(Marginals {
        miss,
        detections: dets,
        nodes: layers.iter().map(Vec::len).sum(),
        capped,
    })
}

/// The rows in breadth-first order over the row–detection graph, each component started from its
/// row with the fewest neighbours, neighbours taken in index order.
fn breadth_first(rows: &[Row], n_det: usize) -> Vec<usize> {
    let mut by_det: Vec<Vec<usize>> = vec![Vec::new(); n_det];
    for (i, r) in rows.iter().enumerate() {
        for &(d, _) in &r.detections {
            by_det[d].push(i);
        }
    }
    let neighbours = |i: usize| {
        let mut v: Vec<usize> = rows[i]
            .detections
            .iter()
            .flat_map(|&(d, _)| by_det[d].iter().copied())
            .filter(|&j| j != i)
            .collect();
        v.sort_unstable();
        v.dedup();
        v
    };
    let degree: Vec<usize> = (0..rows.len()).map(|i| neighbours(i).len()).collect();
    let mut starts: Vec<usize> = (0..rows.len()).collect();
    starts.sort_by_key(|&i| (degree[i], i));
    let mut seen = vec![false; rows.len()];
    let mut order = Vec::with_capacity(rows.len());
    for s in starts {
        if seen[s] {
            continue;
        }
        seen[s] = true;
        let mut queue = VecDeque::from([s]);
        while let Some(i) = queue.pop_front() {
            order.push(i);
            for j in neighbours(i) {
                if !seen[j] {
                    seen[j] = true;
                    queue.push_back(j);
                }
            }
        }
    }
    order
}

/// Every weight of `rows` finite and ≥ 0, every detection one of the cluster's `n_det`.
pub(super) fn check_rows(rows: &[Row], n_det: usize) -> Result<()> {
    let bad = |w: f64| !(w.is_finite() && w >= 0.0);
    if rows
        .iter()
        .any(|r| bad(r.miss) || r.detections.iter().any(|&(d, w)| bad(w) || d >= n_det))
    {
        return Err(EstimationError::InvalidParameter(
            "association weights must be finite, ≥ 0, of detections of the cluster".into(),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Marginals by enumerating every joint event.
    fn brute(rows: &[Row], n_det: usize) -> (Vec<f64>, Vec<Vec<f64>>) {
        fn rec(
            rows: &[Row],
            k: usize,
            used: &mut Vec<bool>,
            w: f64,
            pick: &mut Vec<Option<usize>>,
            acc: &mut (Vec<f64>, Vec<Vec<f64>>, f64),
        ) {
            if k == rows.len() {
                acc.2 += w;
                for (i, p) in pick.iter().enumerate() {
                    match p {
                        None => acc.0[i] += w,
                        Some(e) => acc.1[i][*e] += w,
                    }
                }
                return;
            }
            pick.push(None);
            rec(rows, k + 1, used, w * rows[k].miss, pick, acc);
            pick.pop();
            for (e, &(d, wd)) in rows[k].detections.iter().enumerate() {
                if !used[d] {
                    used[d] = true;
                    pick.push(Some(e));
                    rec(rows, k + 1, used, w * wd, pick, acc);
                    pick.pop();
                    used[d] = false;
                }
            }
        }
        let mut acc = (
            vec![0.0; rows.len()],
            rows.iter().map(|r| vec![0.0; r.detections.len()]).collect(),
            0.0,
        );
        rec(
            rows,
            0,
            &mut vec![false; n_det],
            1.0,
            &mut Vec::new(),
            &mut acc,
        );
        let z = acc.2;
        (
            acc.0.iter().map(|v| v / z).collect(),
            acc.1
                .iter()
                .map(|r| r.iter().map(|v| v / z).collect())
                .collect(),
        )
    }

    fn cluster() -> impl Strategy<Value = (Vec<Row>, usize)> {
        (1usize..=6, 1usize..=7).prop_flat_map(|(n, d)| {
            let row = (
                0.01f64..2.0,
                proptest::collection::btree_map(0..d, 1e-4f64..50.0, 0..=d.min(4)),
            )
                .prop_map(|(miss, m)| Row {
                    miss,
                    detections: m.into_iter().collect(),
                });
            (proptest::collection::vec(row, n), Just(d))
        })
    }

    proptest! {
        #[test]
        fn equal_brute_force_enumeration((rows, n_det) in cluster()) {
            let m = marginals(&rows, n_det, usize::MAX).unwrap();
            let (miss, dets) = brute(&rows, n_det);
            prop_assert!(!m.capped);
            for i in 0..rows.len() {
                prop_assert!((m.miss[i] - miss[i]).abs() < 1e-9, "{} vs {}", m.miss[i], miss[i]);
                for (a, b) in m.detections[i].iter().zip(&dets[i]) {
                    prop_assert!((a - b).abs() < 1e-9, "{a} vs {b}");
                }
            }
        }
    }

    #[test]
    fn a_lone_track_is_ipda_and_the_cap_is_reported() {
        // One track: P(j) ∝ w(j), P(∅) ∝ w(∅).
        let rows = [Row {
            miss: 0.1,
            detections: vec![(0, 0.3), (1, 0.6)],
        }];
        let m = marginals(&rows, 2, 10).unwrap();
        assert!((m.miss[0] - 0.1).abs() < 1e-12);
        assert!((m.detections[0][1] - 0.6).abs() < 1e-12);
        assert_eq!(m.nodes, 2);
        // A chain of 12 tracks sharing neighbours' detections stays narrow; a cap of 1 node
        // per layer is reported and still gives probabilities.
        let chain: Vec<Row> = (0..12)
            .map(|i| Row {
                miss: 0.2,
                detections: vec![(i, 1.0), (i + 1, 0.5)],
            })
            .collect();
        let exact = marginals(&chain, 13, usize::MAX).unwrap();
        assert!(exact.nodes < 40, "{} nodes", exact.nodes);
        let cut = marginals(&chain, 13, 1).unwrap();
        assert!(cut.capped && !exact.capped);
        for i in 0..12 {
            let s = cut.miss[i] + cut.detections[i].iter().sum::<f64>();
            assert!((s - 1.0).abs() < 1e-12);
        }
        assert!(
            marginals(
                &[Row {
                    miss: -1.0,
                    detections: vec![]
                }],
                0,
                1
            )
            .is_err()
        );
        assert!(
            marginals(
                &[Row {
                    miss: 0.0,
                    detections: vec![]
                }],
                0,
                1
            )
            .is_err()
        );
    }
}
