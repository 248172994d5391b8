//! Set-membership bounds beside the tracks (`[tracker.bound] enabled = true`): an optimal bounding
//! ellipsoid filter (\[ELL\], `harrier_core::filter::Obe`, minimum volume) per track, on the same
//! associated detections as the track's Kalman-family filter, so that the page can draw the
//! guaranteed set next to the 95 % covariance ellipse.
//!
//! The set is guaranteed under the bounded-error model it assumes: every component of a
//! detection's noise within `sigmas` × its published standard deviation, the target's
//! acceleration within `accel_max` (held constant over each interval between updates), its speed
//! within `speed_max` at birth. Gaussian noise breaks the first now and then; then the update
//! finds the data inconsistent with the set, and the set restarts from the detection (counted in
//! `harrier_bound_resets_total`).
//!
//! Planar tracks (`[x, y, vx, vy]`) and `position` detections only: a track started or updated by
//! another kind of detection gets no set, or keeps its last one (with its time).

use std::collections::HashMap;

use harrier_core::filter::{
    BoundedLinearMeasurement, BoundedLinearTransition, Obe, ObeCriterion, Predictor, Updater,
};
use harrier_core::linalg::ellipse_axes;
use harrier_core::measurement::MeasKind;
use harrier_core::state::Ellipsoid;
use harrier_core::tracker::TrackEvent;
use nalgebra::{Matrix2, Matrix4, SMatrix, Vector2, Vector4};
use serde::{Deserialize, Serialize};

/// `[tracker.bound]`.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct BoundConfig {
    /// Run a bound beside every track.
    pub enabled: bool,
    /// Noise bound: this many published standard deviations per component.
    pub sigmas: f64,
    /// Acceleration bound (m/s²).
    pub accel_max: f64,
    /// Speed bound at birth (m/s).
    pub speed_max: f64,
}

impl Default for BoundConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            sigmas: 4.0,
            accel_max: 3.0,
            speed_max: 40.0,
        }
    }
}

impl BoundConfig {
    /// Checks the bounds; names the bad key.
    pub fn check(&self) -> Result<(), String> {
        for (name, v) in [
            ("sigmas", self.sigmas),
            ("accel_max", self.accel_max),
            ("speed_max", self.speed_max),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return Err(format!("tracker.bound.{name} must be > 0, got {v}"));
            }
        }
        Ok(())
    }
}

/// A track's set as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct BoundView {
    /// Time of the set (its last update).
    pub t: f64,
    /// Centre `[x, y, vx, vy]`.
    pub center: [f64; 4],
    /// Shape matrix `P` of `{s : (s − c)ᵀ P⁻¹ (s − c) ≤ 1}`, rows.
    pub shape: [[f64; 4]; 4],
    /// The set's projection on the (x, y) plane: semi-axes (m), major first.
    pub semi_axes: [f64; 2],
    /// Direction of the major axis (rad, counter-clockwise from East).
    pub angle_rad: f64,
}

/// The sets of every track.
#[derive(Debug)]
pub struct Bounds {
    config: BoundConfig,
    obe: Obe,
    sets: HashMap<u64, (f64, Ellipsoid<4>)>,
    resets: u64,
}

impl Bounds {
    /// No sets yet.
    pub fn new(config: BoundConfig) -> Self {
        Self {
            config,
            obe: Obe::new(ObeCriterion::MinVolume),
            sets: HashMap::new(),
            resets: 0,
        }
    }

    /// Times a set was found inconsistent with a detection and restarted from it.
    pub fn resets(&self) -> u64 {
        self.resets
    }

    /// The set started from a position fix `z` with noise `std`.
    fn birth(&self, z: Vector2<f64>, std: Vector2<f64>) -> Option<Ellipsoid<4>> {
        let h = std * self.config.sigmas;
        let v = self.config.speed_max;
        // The box of half-widths (h, v) lies inside the ellipsoid of semi-axes √4 × them.
        let shape = Matrix4::from_diagonal(&Vector4::new(h.x * h.x, h.y * h.y, v * v, v * v)) * 4.0;
        Ellipsoid::new(Vector4::new(z.x, z.y, 0.0, 0.0), shape).ok()
    }

    /// The set of `prior` at `dt` later, the acceleration bounded (\[ELL\] Theorems 2–4 through
    /// `Obe::predict`).
    fn predict(&self, prior: &Ellipsoid<4>, dt: f64) -> Option<Ellipsoid<4>> {
        if dt <= 0.0 {
            return Some(*prior);
        }
        let a = Matrix4::new(
            1.0, 0.0, dt, 0.0, //
            0.0, 1.0, 0.0, dt, //
            0.0, 0.0, 1.0, 0.0, //
            0.0, 0.0, 0.0, 1.0,
        );
        let h = 0.5 * dt * dt;
        let b = SMatrix::<f64, 4, 2>::new(h, 0.0, 0.0, h, dt, 0.0, 0.0, dt);
        let model = BoundedLinearTransition::new(a, b, self.config.accel_max).ok()?;
        self.obe.predict(&model, prior, dt).ok()
    }

    /// Takes one processed scan: sets start with `born` tracks, are predicted and updated with
    /// `updated` ones' detections, end with deleted ones. Returns the ids whose set changed.
    pub fn on_scan(
        &mut self,
        t: f64,
        kind: MeasKind,
        noise_std: &[f64],
        detections: &[Vec<f64>],
        events: &[TrackEvent],
    ) -> Vec<u64> {
        let position = kind == MeasKind::Position && noise_std.len() >= 2;
        let fix = |j: usize| {
            let z = detections.get(j).filter(|z| z.len() >= 2)?;
            Some((
                Vector2::new(z[0], z[1]),
                Vector2::new(noise_std[0], noise_std[1]),
            ))
        };
        let mut changed = Vec::new();
        for e in events {
            match *e {
                TrackEvent::Born { id, detection } if position => {
                    if let Some(set) = fix(detection).and_then(|(z, std)| self.birth(z, std)) {
                        self.sets.insert(id, (t, set));
                        changed.push(id);
                    }
                }
                TrackEvent::Updated { id, detection, .. } if position => {
                    let Some((z, std)) = fix(detection) else {
                        continue;
                    };
                    let updated = self.sets.get(&id).and_then(|(t0, set)| {
                        let predicted = self.predict(set, t - t0)?;
                        let model = BoundedLinearMeasurement::new(
                            SMatrix::<f64, 2, 4>::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0),
                            std * self.config.sigmas,
                        )
                        .ok()?;
                        self.obe
                            .update(&model, &predicted, &z)
                            .ok()
                            .map(|p| p.state)
                    });
                    let set = match updated {
                        Some(set) => Some(set),
                        None => {
                            // Inconsistent data (or a track that had no set): start again.
                            self.resets += u64::from(self.sets.contains_key(&id));
                            self.birth(z, std)
                        }
                    };
                    if let Some(set) = set {
                        self.sets.insert(id, (t, set));
                        changed.push(id);
                    }
                }
                TrackEvent::Deleted { id, .. } => {
                    self.sets.remove(&id);
                }
                _ => {}
            }
        }
        changed
    }

    /// Track `id`'s set, if it has one.
    pub fn view(&self, id: u64) -> Option<BoundView> {
        let (t, set) = self.sets.get(&id)?;
        let p = &set.shape;
        let xy = Matrix2::new(p[(0, 0)], p[(0, 1)], p[(1, 0)], p[(1, 1)]);
        let (semi_axes, angle_rad) = ellipse_axes(&xy);
        Some(BoundView {
            t: *t,
            center: set.center.into(),
            shape: std::array::from_fn(|i| std::array::from_fn(|j| p[(i, j)])),
            semi_axes,
            angle_rad,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    #[test]
    fn the_set_holds_the_truth_under_bounded_noise_and_shrinks() {
        let mut b = Bounds::new(BoundConfig {
            enabled: true,
            ..BoundConfig::default()
        });
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let std = [5.0, 5.0];
        let truth = |t: f64| Vector4::new(100.0 + 8.0 * t, -50.0 + 3.0 * t, 8.0, 3.0);
        let mut first = None;
        for k in 0..60 {
            let t = f64::from(k);
            let x = truth(t);
            // Uniform noise within ±2σ: inside the 4σ bound.
            let z = vec![
                x[0] + rng.random_range(-10.0..10.0),
                x[1] + rng.random_range(-10.0..10.0),
            ];
            let ev = if k == 0 {
                TrackEvent::Born {
                    id: 1,
                    detection: 0,
                }
            } else {
                TrackEvent::Updated {
                    id: 1,
                    detection: 0,
                    nis: 0.0,
                }
            };
            assert_eq!(b.on_scan(t, MeasKind::Position, &std, &[z], &[ev]), [1]);
            let v = b.view(1).expect("a set");
            let set = Ellipsoid::new(
                Vector4::from(v.center),
                Matrix4::from_fn(|i, j| v.shape[i][j]),
            )
            .expect("valid");
            assert!(
                set.normalized_distance_sq(&x).expect("d") <= 1.0 + 1e-9,
                "k = {k}"
            );
            first.get_or_insert(v.shape[2][2].sqrt());
        }
        assert_eq!(b.resets(), 0);
        // The velocity becomes known: its bound shrinks from the birth's 80 m/s.
        let v = b.view(1).expect("set");
        let (first, last) = (first.unwrap_or(0.0), v.shape[2][2].sqrt());
        eprintln!(
            "vx bound {first} → {last} m/s; position semi-axes {:?} m",
            v.semi_axes
        );
        assert!(last < 0.4 * first, "{first} → {last}");
        assert!(v.semi_axes[0] < 60.0, "{:?}", v.semi_axes);
        // An outlier far outside the bound restarts the set; a deletion removes it.
        let far = vec![vec![1e4, 1e4]];
        let up = TrackEvent::Updated {
            id: 1,
            detection: 0,
            nis: 0.0,
        };
        b.on_scan(60.0, MeasKind::Position, &std, &far, &[up]);
        assert_eq!(b.resets(), 1);
        assert_eq!(b.view(1).expect("restarted").center[0], 1e4);
        let gone = TrackEvent::Deleted {
            id: 1,
            reason: harrier_core::tracker::DeleteReason::Misses,
        };
        b.on_scan(61.0, MeasKind::AzEl, &[0.01, 0.01], &[], &[gone]);
        assert!(b.view(1).is_none());
    }
}
