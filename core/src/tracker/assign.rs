//! Optimal rectangular assignment on `f64` costs: the shortest-augmenting-path Hungarian method
//! with row/column potentials (Jonker & Volgenant 1987; the O(n²m) form of Kuhn–Munkres).
//!
//! ```text
//! minimise Σᵢ C[i, σ(i)]  over injective σ: rows → columns  (rows ≤ columns;
//!                                                            otherwise solved on Cᵀ)
//! ```
//!
//! Each row is added in turn and joined to the current matching by a shortest augmenting path in
//! the reduced costs `C[i, j] − u[i] − v[j] ≥ 0` (a Dijkstra sweep over columns); the potentials
//! `u, v` stay dual-feasible, so the final matching is optimal.
//!
//! # References
//! * R. Jonker, A. Volgenant, "A shortest augmenting path algorithm for dense and sparse linear
//!   assignment problems", *Computing* 38, 325–340, 1987.
//! * H. W. Kuhn, "The Hungarian method for the assignment problem", *Naval Research Logistics
//!   Quarterly* 2, 83–97, 1955.

use crate::{EstimationError, Result};

/// An optimal assignment: `row_to_col[i]` is the column given to row `i` (`None` when there are
/// more rows than columns and row `i` got none), `cost` the summed cost of the chosen cells.
#[derive(Debug, Clone, PartialEq)]
pub struct Assignment {
    /// Column of each row.
    pub row_to_col: Vec<Option<usize>>,
    /// Total cost of the assignment.
    pub cost: f64,
}

/// Solves the rectangular linear assignment problem for a row-major `rows × cols` cost matrix.
///
/// Every cost must be finite (forbid a cell with a large finite cost instead of ∞). When
/// `rows ≤ cols` every row gets a distinct column; otherwise every column gets a distinct row.
pub fn solve(cost: &[f64], rows: usize, cols: usize) -> Result<Assignment> {
    if cost.len() != rows * cols {
        return Err(EstimationError::InvalidParameter(format!(
            "assignment: {} costs for a {rows}×{cols} matrix",
            cost.len()
        )));
    }
    if !cost.iter().all(|c| c.is_finite()) {
        return Err(EstimationError::NonFinite("assignment cost matrix"));
    }
    if rows <= cols {
        let cols_of = solve_wide(|i, j| cost[i * cols + j], rows, cols)?;
        let total = cols_of
            .iter()
            .enumerate()
            .map(|(i, &j)| cost[i * cols + j])
            .sum();
        Ok(Assignment {
            row_to_col: cols_of.into_iter().map(Some).collect(),
            cost: total,
        })
    } else {
        // Solve on the transpose: columns become rows.
        let rows_of = solve_wide(|j, i| cost[i * cols + j], cols, rows)?;
        let mut row_to_col = vec![None; rows];
        let mut total = 0.0;
        for (j, &i) in rows_of.iter().enumerate() {
            row_to_col[i] = Some(j);
            total += cost[i * cols + j];
        }
        Ok(Assignment {
            row_to_col,
            cost: total,
        })
    }
}

/// Core of [`solve`] for `n ≤ m`: returns the column of each row. Arrays are 1-based with column 0
/// as the virtual source of the augmenting path.
fn solve_wide(a: impl Fn(usize, usize) -> f64, n: usize, m: usize) -> Result<Vec<usize>> {
    let mut u = vec![0.0; n + 1];
    let mut v = vec![0.0; m + 1];
    // p[j]: row (1-based) matched to column j, 0 = free; way[j]: previous column on the path.
    let mut p = vec![0usize; m + 1];
    let mut way = vec![0usize; m + 1];
    let mut minv = vec![0.0; m + 1];
    let mut used = vec![false; m + 1];
    for i in 1..=n {
        p[0] = i;
        let mut j0 = 0;
        minv.fill(f64::INFINITY);
        used.fill(false);
        loop {
            used[j0] = true;
            let i0 = p[j0];
            let mut delta = f64::INFINITY;
            let mut j1 = 0;
            for j in 1..=m {
                if !used[j] {
                    // Reduced cost of extending the path from row i0 to column j.
                    let cur = a(i0 - 1, j - 1) - u[i0] - v[j];
                    if cur < minv[j] {
                        minv[j] = cur;
                        way[j] = j0;
                    }
                    if minv[j] < delta {
                        delta = minv[j];
                        j1 = j;
                    }
                }
            }
            if j1 == 0 || !delta.is_finite() {
                return Err(EstimationError::NonFinite("assignment potentials"));
            }
            for j in 0..=m {
                if used[j] {
                    u[p[j]] += delta;
                    v[j] -= delta;
                } else {
                    minv[j] -= delta;
                }
            }
            j0 = j1;
            if p[j0] == 0 {
                break;
            }
        }
        // Flip the augmenting path.
        loop {
            let j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
            if j0 == 0 {
                break;
            }
        }
    }
    let mut col_of = vec![0usize; n];
    for j in 1..=m {
        if p[j] != 0 {
            col_of[p[j] - 1] = j - 1;
        }
    }
    Ok(col_of)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    /// Minimum over all injective maps of the smaller side into the larger one.
    fn brute_force(cost: &[f64], rows: usize, cols: usize) -> f64 {
        fn rec(
            cost: &[f64],
            cols: usize,
            k: usize,
            n: usize,
            used: &mut Vec<bool>,
            transpose: bool,
        ) -> f64 {
            if k == n {
                return 0.0;
            }
            let mut best = f64::INFINITY;
            for j in 0..used.len() {
                if !used[j] {
                    used[j] = true;
                    let c = if transpose {
                        cost[j * cols + k]
                    } else {
                        cost[k * cols + j]
                    };
                    best = best.min(c + rec(cost, cols, k + 1, n, used, transpose));
                    used[j] = false;
                }
            }
            best
        }
        if rows <= cols {
            rec(cost, cols, 0, rows, &mut vec![false; cols], false)
        } else {
            rec(cost, cols, 0, cols, &mut vec![false; rows], true)
        }
    }

    #[test]
    fn matches_brute_force_on_random_matrices() {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        for _ in 0..400 {
            let rows = rng.random_range(1..=6);
            let cols = rng.random_range(1..=6);
            // Integer-valued costs half of the time, to exercise ties.
            let ints = rng.random_bool(0.5);
            let cost: Vec<f64> = (0..rows * cols)
                .map(|_| {
                    if ints {
                        f64::from(rng.random_range(0..5))
                    } else {
                        rng.random_range(-10.0..10.0)
                    }
                })
                .collect();
            let a = solve(&cost, rows, cols).unwrap();
            let best = brute_force(&cost, rows, cols);
            assert!(
                (a.cost - best).abs() < 1e-9,
                "{rows}×{cols}: {} vs {best}",
                a.cost
            );
            // A valid injective assignment of min(rows, cols) pairs with the reported cost.
            let chosen: Vec<usize> = a.row_to_col.iter().flatten().copied().collect();
            assert_eq!(chosen.len(), rows.min(cols));
            let mut sorted = chosen.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), chosen.len());
            let sum: f64 = a
                .row_to_col
                .iter()
                .enumerate()
                .filter_map(|(i, j)| j.map(|j| cost[i * cols + j]))
                .sum();
            assert!((sum - a.cost).abs() < 1e-9);
        }
    }

    #[test]
    fn known_example_and_edge_cases() {
        // Classic 3×3: optimum 1 + 2 + 2 = 5 on the anti-diagonal-ish cells.
        let c = [4.0, 1.0, 3.0, 2.0, 0.0, 5.0, 3.0, 2.0, 2.0];
        let a = solve(&c, 3, 3).unwrap();
        assert_eq!(a.row_to_col, vec![Some(1), Some(0), Some(2)]);
        assert_eq!(a.cost, 5.0);
        assert_eq!(solve(&[], 0, 3).unwrap().row_to_col, vec![]);
        assert_eq!(solve(&[], 2, 0).unwrap().row_to_col, vec![None, None]);
        assert!(solve(&[1.0, f64::INFINITY], 1, 2).is_err());
        assert!(solve(&[1.0], 1, 2).is_err());
    }
}
