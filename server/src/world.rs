//! What the live service knows of the world besides the tracks: the simulator's truth (converted
//! into the server's frame by the service's Zenoh callback, `bus.rs`) and the static world of the
//! configuration (roads, obstacles). The HTTP routes `GET /api/v1/truth` and `GET /api/v1/world`
//! serve these values as they are, the truth with each track's error against it
//! ([`TruthBody::with_scores`]).

use harrier_core::detection::TruthSample;
use harrier_core::linalg::mahalanobis_sq;
use harrier_core::scenario::Segment;
use harrier_link::geo::LocalFrame;
use serde::Serialize;
use utoipa::ToSchema;

use super::config::Config;
use harrier_engine::TrackView;

/// Largest time (s) between a track's estimate and a truth sample that can be scored together.
const SCORE_MAX_DT_S: f64 = 5.0;
/// Largest horizontal distance (m) from a track to the nearest target for it to be scored.
const SCORE_MAX_ERROR_M: f64 = 200.0;

/// One target of the simulator's truth, in the server's ENU frame.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct TruthTarget {
    /// Target id.
    pub id: String,
    /// Time (the detections' clock; UNIX s when the simulator gives it).
    pub t: f64,
    /// Position (ENU, m).
    pub position: [f64; 3],
    /// Velocity (ENU, m/s).
    pub velocity: [f64; 3],
}

/// A track scored against the nearest true target.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct TrackScore {
    /// The track.
    pub track: u64,
    /// The nearest target (horizontally, its last sample moved on at its velocity to the
    /// track's time).
    pub target: String,
    /// Time of the track's estimate.
    pub t: f64,
    /// Horizontal distance from the estimate to the target (m).
    pub error_m: f64,
    /// Position NEES `dᵀ P⁻¹ d` over the track's position covariance (`null` when it is not
    /// positive definite); its 95 % bound is the χ² quantile of `dof` degrees of freedom.
    pub nees: Option<f64>,
    /// Degrees of freedom of `nees`: 3 when the covariance covers z, else 2.
    pub dof: u8,
}

/// The latest truth.
#[derive(Debug, Clone, Default, Serialize, ToSchema)]
pub struct TruthBody {
    /// Every target of the last truth sample; empty when no simulator publishes truth.
    pub targets: Vec<TruthTarget>,
    /// Every track within 200 m and 5 s of a target, scored against the nearest one (filled
    /// when served, against the live tracks).
    pub scores: Vec<TrackScore>,
}

impl TruthBody {
    /// A truth sample (in its own frame) in the `server`'s ENU frame.
    pub fn of(t: &TruthSample, server: &LocalFrame) -> Self {
        let theirs = LocalFrame::new(t.origin);
        let rot = theirs.rotation_to(server);
        Self {
            targets: t
                .targets
                .iter()
                .map(|k| {
                    let [x, y, z, vx, vy, vz] = k.state;
                    let p = theirs.enu_to_frame(server, &nalgebra::Vector3::new(x, y, z));
                    let v = rot * nalgebra::Vector3::new(vx, vy, vz);
                    TruthTarget {
                        id: k.id.clone(),
                        t: t.time_unix.unwrap_or(t.t),
                        position: p.into(),
                        velocity: v.into(),
                    }
                })
                .collect(),
            scores: Vec::new(),
        }
    }

    /// This truth with every track of `tracks` near a target scored against the nearest one.
    pub fn with_scores(&self, tracks: &[TrackView]) -> Self {
        Self {
            targets: self.targets.clone(),
            scores: tracks.iter().filter_map(|k| self.score(k)).collect(),
        }
    }

    /// `k` against the nearest target, when one is near enough.
    fn score(&self, k: &TrackView) -> Option<TrackScore> {
        let (target, d) = self
            .targets
            .iter()
            .filter(|s| (k.t - s.t).abs() <= SCORE_MAX_DT_S)
            .map(|s| {
                let d: [f64; 3] = std::array::from_fn(|i| {
                    k.state[i] - (s.position[i] + s.velocity[i] * (k.t - s.t))
                });
                (s, d)
            })
            .min_by(|a, b| a.1[0].hypot(a.1[1]).total_cmp(&b.1[0].hypot(b.1[1])))?;
        let error_m = d[0].hypot(d[1]);
        if error_m.is_nan() || error_m >= SCORE_MAX_ERROR_M {
            return None;
        }
        let block = |dims: &[usize]| -> Option<Vec<Vec<f64>>> {
            let at: Vec<usize> = dims
                .iter()
                .map(|d| k.cov_dims.iter().position(|c| c == d))
                .collect::<Option<_>>()?;
            Some(
                at.iter()
                    .map(|&i| at.iter().map(|&j| k.cov[i][j]).collect())
                    .collect(),
            )
        };
        let (nees, dof) = if let Some(p) = block(&[0, 1, 2]) {
            let p = nalgebra::Matrix3::from_fn(|i, j| p[i][j]);
            let v = nalgebra::Vector3::from(d);
            (mahalanobis_sq(&v, &p, "track covariance").ok(), 3)
        } else {
            let p = block(&[0, 1])?;
            let p = nalgebra::Matrix2::from_fn(|i, j| p[i][j]);
            let v = nalgebra::Vector2::new(d[0], d[1]);
            (mahalanobis_sq(&v, &p, "track covariance").ok(), 2)
        };
        Some(TrackScore {
            track: k.id,
            target: target.id.clone(),
            t: k.t,
            error_m,
            nees,
            dof,
        })
    }
}

/// A road's centre line as a polyline (ENU, m).
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct RoadView {
    /// Road id.
    pub id: String,
    /// Physical width (m), when given.
    pub width_m: Option<f64>,
    /// Centre-line points in travel order, arcs sampled at most every 5° or 10 m.
    pub points: Vec<[f64; 2]>,
}

/// An obstacle the `formation` law steers around.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct ObstacleView {
    /// Centre east (m).
    pub x_m: f64,
    /// Centre north (m).
    pub y_m: f64,
    /// Radius (m).
    pub radius_m: f64,
}

/// The static world of the deployment: what the map draws under the live picture.
#[derive(Debug, Clone, Default, PartialEq, Serialize, ToSchema)]
pub struct WorldBody {
    /// The road network of the configuration (`tracker.roads`).
    pub roads: Vec<RoadView>,
    /// The obstacles of the configuration (`guidance.obstacles`).
    pub obstacles: Vec<ObstacleView>,
}

impl WorldBody {
    /// The world of a configuration.
    pub fn of(config: &Config) -> Self {
        Self {
            roads: config
                .tracker
                .roads
                .iter()
                .map(|r| RoadView {
                    id: r.id.clone(),
                    width_m: r.width_m,
                    points: polyline(&r.segments),
                })
                .collect(),
            obstacles: config
                .guidance
                .obstacles
                .iter()
                .map(|o| ObstacleView {
                    x_m: o.x_m,
                    y_m: o.y_m,
                    radius_m: o.radius_m,
                })
                .collect(),
        }
    }
}

/// The centre line of road `segments`: line ends, and arcs sampled at most every 5° or 10 m.
fn polyline(segments: &[Segment]) -> Vec<[f64; 2]> {
    let mut points: Vec<[f64; 2]> = Vec::new();
    let mut push = |p: [f64; 2]| {
        if points.last() != Some(&p) {
            points.push(p);
        }
    };
    for seg in segments {
        match seg {
            Segment::Line { start, end } => {
                push(*start);
                push(*end);
            }
            Segment::Arc {
                center,
                radius,
                start,
                sweep_rad,
                ..
            } => {
                let a0 = (start[1] - center[1]).atan2(start[0] - center[0]);
                let step = 5f64.to_radians().min(10.0 / radius.max(1e-3));
                // At most 720 points an arc whatever the configuration says.
                let n = ((sweep_rad.abs() / step).ceil() as usize).clamp(1, 720);
                for k in 0..=n {
                    let a = a0 + sweep_rad * k as f64 / n as f64;
                    push([center[0] + radius * a.cos(), center[1] + radius * a.sin()]);
                }
            }
        }
    }
    points
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_road_is_its_line_ends_and_its_arcs_sampled_every_5_degrees() {
        let segments = [
            Segment::Line {
                start: [0.0, 0.0],
                end: [100.0, 0.0],
            },
            Segment::Arc {
                center: [100.0, 50.0],
                radius: 50.0,
                start: [100.0, 0.0],
                end: [150.0, 50.0],
                sweep_rad: std::f64::consts::FRAC_PI_2,
            },
        ];
        let p = polyline(&segments);
        assert_eq!(p[..2], [[0.0, 0.0], [100.0, 0.0]]);
        // The arc from the line's end (not repeated): a quarter circle in 18 steps of 5°.
        let arc = &p[1..];
        assert_eq!(arc.len(), 19);
        for w in arc.windows(2) {
            let step = (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]);
            assert!(step <= 50.0 * 5f64.to_radians() + 1e-9, "{step}");
        }
        let end = arc[arc.len() - 1];
        assert!(
            (end[0] - 150.0).abs() < 1e-9 && (end[1] - 50.0).abs() < 1e-9,
            "{end:?}"
        );
    }
}
