//! Gating that scales: a uniform grid over a scan's detections in measurement space, so that each
//! track looks only at the detections near its predicted measurement instead of at all of them.
//!
//! The χ² gate `νᵀ S⁻¹ ν ≤ γ` lies inside the box `|νᵢ| ≤ √(γ Sᵢᵢ)` (the largest `νᵢ` on the
//! ellipsoid `νᵀ S⁻¹ ν = γ` is `√(γ Sᵢᵢ)`, by Cauchy–Schwarz on `S^{-1/2} ν`). So the detections
//! whose first two components lie in that box around `ẑ` are a superset of the gated ones, and
//! testing only them gives exactly the gated set of a test of every detection. Angle components
//! (an azimuth, [`MeasurementModel::is_angle`]) are indexed on the circle: a box that crosses ±π
//! is queried on both sides.
//!
//! The grid's cells are sorted by `(column, row)`, so the detections of one column's rows
//! `r₀..=r₁` are one contiguous run found by two binary searches: a query costs
//! `O(columns · log D + candidates)` and building the index `O(D log D)` for D detections.

use std::f64::consts::PI;

use nalgebra::SVector;

use crate::linalg::wrap_angle;
use crate::measurement::MeasurementModel;

/// Largest number of grid columns a query walks before it falls back to every detection.
const MAX_COLUMNS: i64 = 4096;

/// A scan's detections on a uniform grid over their first (up to) two components.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectionIndex {
    /// Indexed components (1 or 2).
    axes: usize,
    /// Cell size per axis.
    cell: [f64; 2],
    /// Whether each indexed axis is an angle on the circle.
    angle: [bool; 2],
    /// `(column, row)` of each entry of `order`, sorted.
    keys: Vec<(i64, i64)>,
    /// Detection indices in cell order.
    order: Vec<usize>,
    /// Number of detections.
    len: usize,
}

impl DetectionIndex {
    /// Indexes `detections` on a grid of `cell` (per axis, in the measurement's units; values
    /// that are not finite and > 0 become 1) under `sensor`'s angle convention.
    pub fn new<H, const N: usize, const M: usize>(
        sensor: &H,
        detections: &[SVector<f64, M>],
        cell: [f64; 2],
    ) -> Self
    where
        H: MeasurementModel<N, M>,
    {
        let axes = M.min(2);
        let cell = cell.map(|c| if c.is_finite() && c > 0.0 { c } else { 1.0 });
        let angle = [sensor.is_angle(0), axes > 1 && sensor.is_angle(1)];
        let mut entries: Vec<((i64, i64), usize)> = detections
            .iter()
            .enumerate()
            .map(|(j, z)| {
                let key = |a: usize| {
                    if a >= axes {
                        return 0;
                    }
                    let v = if angle[a] { wrap_angle(z[a]) } else { z[a] };
                    cell_of(v, cell[a])
                };
                ((key(0), key(1)), j)
            })
            .collect();
        entries.sort_unstable();
        Self {
            axes,
            cell,
            angle,
            keys: entries.iter().map(|e| e.0).collect(),
            order: entries.iter().map(|e| e.1).collect(),
            len: detections.len(),
        }
    }

    /// Calls `visit` with every detection whose indexed components lie within `half[a]` of
    /// `centre[a]` (on the circle for angles), and maybe a few more; never misses one that does.
    /// Each detection is visited at most once.
    pub fn query(&self, centre: [f64; 2], half: [f64; 2], mut visit: impl FnMut(usize)) {
        let ranges: [Vec<(i64, i64)>; 2] =
            std::array::from_fn(|a| self.cell_ranges(a, centre[a], half[a]));
        let columns: i64 = ranges[0].iter().map(|(lo, hi)| hi - lo + 1).sum();
        if ranges.iter().any(Vec::is_empty) || columns > MAX_COLUMNS {
            (0..self.len).for_each(visit);
            return;
        }
        for &(c0, c1) in &ranges[0] {
            for c in c0..=c1 {
                for &(r0, r1) in &ranges[1] {
                    let lo = self.keys.partition_point(|k| *k < (c, r0));
                    let hi = self.keys.partition_point(|k| *k <= (c, r1));
                    for &j in &self.order[lo..hi] {
                        visit(j);
                    }
                }
            }
        }
    }

    /// The cell ranges of axis `a` that cover `[centre − half, centre + half]` (empty: the query
    /// cannot be indexed, e.g. a non-finite bound), split at ±π on an angle axis.
    fn cell_ranges(&self, a: usize, centre: f64, half: f64) -> Vec<(i64, i64)> {
        if a >= self.axes {
            return vec![(0, 0)];
        }
        if !(centre.is_finite() && half.is_finite() && half >= 0.0) {
            return Vec::new();
        }
        let w = self.cell[a];
        let span = |lo: f64, hi: f64| (cell_of(lo, w), cell_of(hi, w));
        if !self.angle[a] {
            return vec![span(centre - half, centre + half)];
        }
        if half >= PI {
            return vec![span(-PI, PI)];
        }
        let c = wrap_angle(centre);
        let (lo, hi) = (c - half, c + half);
        if lo < -PI {
            vec![span(-PI, hi), span(lo + 2.0 * PI, PI)]
        } else if hi >= PI {
            vec![span(lo, PI), span(-PI, hi - 2.0 * PI)]
        } else {
            vec![span(lo, hi)]
        }
    }
}

/// The grid cell of `v` for cells of size `w` (saturating far outside any real scene).
fn cell_of(v: f64, w: f64) -> i64 {
    (v / w).floor().clamp(-1e15, 1e15) as i64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{AzEl, Geometry, Position};
    use nalgebra::{Vector2, Vector3};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn brute<H: MeasurementModel<4, 2>>(
        h: &H,
        dets: &[Vector2<f64>],
        c: Vector2<f64>,
        half: [f64; 2],
    ) -> Vec<usize> {
        (0..dets.len())
            .filter(|&j| {
                let r = h.residual(&dets[j], &c);
                r[0].abs() <= half[0] && r[1].abs() <= half[1]
            })
            .collect()
    }

    #[test]
    fn finds_every_detection_in_the_box_on_the_plane_and_on_the_circle() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let plane = Position::new(Geometry::planar(0.0), [1.0, 1.0]);
        let cam = AzEl::new(Geometry::planar(0.0), Vector3::zeros(), [0.01, 0.01]);
        for round in 0..200 {
            let angles = round % 2 == 1;
            let dets: Vec<Vector2<f64>> = (0..rng.random_range(0..300))
                .map(|_| {
                    if angles {
                        Vector2::new(rng.random_range(-PI..PI), rng.random_range(-1.5..0.0))
                    } else {
                        Vector2::new(
                            rng.random_range(-500.0..500.0),
                            rng.random_range(-80.0..80.0),
                        )
                    }
                })
                .collect();
            let (scale, cell) = if angles {
                (0.5, [0.05, 0.05])
            } else {
                (60.0, [20.0, 7.0])
            };
            let c = if angles {
                Vector2::new(rng.random_range(-PI..PI), rng.random_range(-1.5..0.0))
            } else {
                Vector2::new(
                    rng.random_range(-550.0..550.0),
                    rng.random_range(-90.0..90.0),
                )
            };
            let half = [rng.random_range(0.0..scale), rng.random_range(0.0..scale)];
            let mut got = Vec::new();
            let want = if angles {
                let index = DetectionIndex::new::<_, 4, 2>(&cam, &dets, cell);
                index.query([c.x, c.y], half, |j| got.push(j));
                brute(&cam, &dets, c, half)
            } else {
                let index = DetectionIndex::new::<_, 4, 2>(&plane, &dets, cell);
                index.query([c.x, c.y], half, |j| got.push(j));
                brute(&plane, &dets, c, half)
            };
            let mut sorted = got.clone();
            sorted.sort_unstable();
            sorted.dedup();
            assert_eq!(sorted.len(), got.len(), "a detection visited twice");
            assert!(
                want.iter().all(|j| got.contains(j)),
                "round {round}: missed one"
            );
        }
    }

    #[test]
    fn unbounded_queries_visit_everything() {
        let plane = Position::new(Geometry::planar(0.0), [1.0, 1.0]);
        let dets = [Vector2::new(0.0, 0.0), Vector2::new(1e6, -1e6)];
        let index = DetectionIndex::new::<_, 4, 2>(&plane, &dets, [f64::NAN, 0.0]);
        let mut n = 0;
        index.query([0.0, 0.0], [f64::INFINITY, 1.0], |_| n += 1);
        assert_eq!(n, 2);
        let mut n = 0;
        index.query([0.0, 0.0], [1.0, 1.0], |_| n += 1);
        assert_eq!(n, 1);
    }
}
