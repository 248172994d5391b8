//! A road ([`Road`]): its centre line, checked when built, and the projection of a position onto
//! it ([`Road::project`], [`RoadPoint`]); and all roads of a scenario ([`RoadNetwork`]).

use std::f64::consts::TAU;

use nalgebra::{Matrix2, Vector2};

use super::segment::{Geom, RoadSegment};
use crate::scenario::{self, Segment};
use crate::{EstimationError, Result};

/// Tolerance (m) on the geometry of a road read from a scenario (arc end points on the circle,
/// joins of consecutive segments).
pub const GEOMETRY_TOL_M: f64 = 1e-3;

/// Largest magnitude (m) of a road coordinate or arc radius: far beyond any road, well inside
/// what the projection can square without overflow.
pub const MAX_ROAD_COORD_M: f64 = 1e9;
/// The nearest point of a road's centre line to a position, see [`Road::project`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RoadPoint {
    /// Foot point on the centre line.
    pub point: Vector2<f64>,
    /// Unit tangent at the foot (travel direction).
    pub tangent: Vector2<f64>,
    /// Signed lateral offset of the position from the centre line, > 0 left of the travel
    /// direction (m). Its magnitude is the distance to the centre line.
    pub offset: f64,
    /// Gradient of `offset` with respect to the position (a unit vector: the left normal at an
    /// interior foot point).
    pub normal: Vector2<f64>,
    /// Derivative of `normal` with respect to the position (what the velocity constraint's
    /// Jacobian needs): `−κ/(1 − κ·offset)·t tᵀ` on an arc, 0 on a line.
    pub normal_jacobian: Matrix2<f64>,
    /// Index of the segment the foot is on.
    pub segment: usize,
}

/// One road: centre-line segments in travel order and the lateral-offset std.
#[derive(Debug, Clone, PartialEq)]
pub struct Road {
    segments: Vec<RoadSegment>,
    geoms: Vec<Geom>,
    sigma_m: f64,
}

impl Road {
    /// A road from its segments (non-empty, consecutive segments joined within
    /// [`GEOMETRY_TOL_M`]) and the std `sigma_m > 0` of the lateral offset.
    pub fn new(segments: Vec<RoadSegment>, sigma_m: f64) -> Result<Self> {
        if segments.is_empty() {
            return Err(EstimationError::InvalidParameter(
                "a road needs at least one segment".into(),
            ));
        }
        if !(sigma_m.is_finite() && sigma_m > 0.0) {
            return Err(EstimationError::InvalidParameter(format!(
                "road sigma_m must be > 0, got {sigma_m}"
            )));
        }
        for (k, s) in segments.iter().enumerate() {
            // Every defining number finite and of a physical size (|·| ≤ MAX_ROAD_COORD_M): an
            // arc's length alone does not see a NaN centre, and a projection onto coordinates
            // near f64::MAX overflows (found by the hostile-number tests,
            // core/tests/it/hostile.rs).
            let finite = match *s {
                RoadSegment::Line { start, end } => start
                    .iter()
                    .chain(end.iter())
                    .all(|v| v.abs() <= MAX_ROAD_COORD_M),
                RoadSegment::Arc {
                    center,
                    radius,
                    start_angle,
                    sweep,
                } => {
                    center
                        .iter()
                        .chain(&[radius])
                        .all(|v| v.abs() <= MAX_ROAD_COORD_M)
                        && start_angle.is_finite()
                        && sweep.is_finite()
                }
            };
            if !finite {
                return Err(EstimationError::InvalidParameter(format!(
                    "road segment {k} has a coordinate that is not finite or beyond ±{MAX_ROAD_COORD_M:e} m"
                )));
            }
            if !(s.length().is_finite() && s.length() > 0.0) {
                return Err(EstimationError::InvalidParameter(format!(
                    "road segment {k} has no length"
                )));
            }
        }
        for (k, w) in segments.windows(2).enumerate() {
            let gap = (w[0].end() - w[1].start()).norm();
            if gap > GEOMETRY_TOL_M {
                return Err(EstimationError::InvalidParameter(format!(
                    "road segments {k} and {} are not joined (gap {gap} m)",
                    k + 1
                )));
            }
        }
        let geoms = segments.iter().copied().map(Geom::new).collect();
        Ok(Self {
            segments,
            geoms,
            sigma_m,
        })
    }

    /// A road of FORMAT.md §2; `sigma_m` defaults to `width_m / 4` (a vehicle anywhere within the
    /// width, ±2σ), else an error.
    pub fn from_scenario(road: &scenario::Road) -> Result<Self> {
        let sigma = road
            .sigma_m
            .or(road.width_m.map(|w| w / 4.0))
            .ok_or_else(|| {
                EstimationError::InvalidParameter(format!(
                    "road {:?} has neither sigma_m nor width_m",
                    road.id
                ))
            })?;
        let segments = road
            .segments
            .iter()
            .enumerate()
            .map(|(k, s)| match *s {
                Segment::Line { start, end } => Ok(RoadSegment::Line {
                    start: start.into(),
                    end: end.into(),
                }),
                Segment::Arc {
                    center,
                    radius,
                    start,
                    end,
                    sweep_rad,
                } => {
                    let (c, a, b) = (
                        Vector2::from(center),
                        Vector2::from(start),
                        Vector2::from(end),
                    );
                    let on_circle = |p: Vector2<f64>| ((p - c).norm() - radius).abs();
                    if !(radius > 0.0 && sweep_rad != 0.0 && sweep_rad.abs() <= TAU)
                        || on_circle(a).max(on_circle(b)) > GEOMETRY_TOL_M.max(1e-9 * radius)
                    {
                        return Err(EstimationError::InvalidParameter(format!(
                            "road {:?} segment {k}: inconsistent arc",
                            road.id
                        )));
                    }
                    let seg = RoadSegment::Arc {
                        center: c,
                        radius,
                        start_angle: (a.y - c.y).atan2(a.x - c.x),
                        sweep: sweep_rad,
                    };
                    if (seg.end() - b).norm() > GEOMETRY_TOL_M.max(1e-9 * radius) {
                        return Err(EstimationError::InvalidParameter(format!(
                            "road {:?} segment {k}: arc end does not match its sweep",
                            road.id
                        )));
                    }
                    Ok(seg)
                }
            })
            .collect::<Result<Vec<_>>>()?;
        Self::new(segments, sigma)
    }

    /// Std of the lateral offset (m).
    pub fn sigma_m(&self) -> f64 {
        self.sigma_m
    }

    /// The segments.
    pub fn segments(&self) -> &[RoadSegment] {
        &self.segments
    }

    /// Nearest point of the centre line to `p` (see the module docs). No allocation; one `atan2`
    /// per arc. Finite for a finite `p` within ±1e150 m; beyond, the offset may overflow to ±∞ or
    /// NaN, which [`crate::tracker::CimmFilter`] takes as off every road.
    pub fn project(&self, p: &Vector2<f64>) -> RoadPoint {
        let last = self.geoms.len() - 1;
        let mut best: Option<(f64, RoadPoint)> = None;
        for (k, g) in self.geoms.iter().enumerate() {
            let raw = g.raw_param(p);
            // (foot, tangent, curvature); curvature NaN marks a foot clamped to a segment end.
            let (foot, tangent, kappa) = if k == 0 && raw < 0.0 {
                // Free ends of the road extend along the end tangents.
                (
                    g.start + g.t_start * (p - g.start).dot(&g.t_start),
                    g.t_start,
                    0.0,
                )
            } else if k == last && raw > g.len {
                (g.end + g.t_end * (p - g.end).dot(&g.t_end), g.t_end, 0.0)
            } else if raw < 0.0 {
                (g.start, g.t_start, f64::NAN)
            } else if raw > g.len {
                (g.end, g.t_end, f64::NAN)
            } else {
                let (foot, tangent) = g.interior(p, raw);
                (foot, tangent, g.kappa)
            };
            let d = p - foot;
            let dist = d.norm();
            if best.as_ref().is_some_and(|(b, _)| *b <= dist) {
                continue;
            }
            let left = Vector2::new(-tangent.y, tangent.x);
            let rp = if kappa.is_nan() && dist > 1e-9 {
                // Foot clamped to a segment end (a corner): the gradient of the distance turns with
                // p − corner.
                let u = d / dist;
                let sign = if left.dot(&d) >= 0.0 { 1.0 } else { -1.0 };
                RoadPoint {
                    point: foot,
                    tangent,
                    offset: sign * dist,
                    normal: u * sign,
                    normal_jacobian: (Matrix2::identity() - u * u.transpose()) * (sign / dist),
                    segment: k,
                }
            } else {
                let kappa = if kappa.is_nan() { 0.0 } else { kappa };
                let offset = left.dot(&d);
                RoadPoint {
                    point: foot,
                    tangent,
                    offset,
                    normal: left,
                    normal_jacobian: tangent
                        * tangent.transpose()
                        * (-kappa / (1.0 - kappa * offset)),
                    segment: k,
                }
            };
            best = Some((dist, rp));
        }
        // `geoms` is never empty (checked in `new`).
        best.map_or_else(
            || RoadPoint {
                point: *p,
                tangent: Vector2::x(),
                offset: 0.0,
                normal: Vector2::y(),
                normal_jacobian: Matrix2::zeros(),
                segment: 0,
            },
            |(_, rp)| rp,
        )
    }
}

/// All roads of a scenario.
#[derive(Debug, Clone, PartialEq)]
pub struct RoadNetwork {
    roads: Vec<Road>,
}

impl RoadNetwork {
    /// The road network of FORMAT.md §2 `roads` (may be empty).
    pub fn from_scenario(roads: &[scenario::Road]) -> Result<Self> {
        Ok(Self {
            roads: roads
                .iter()
                .map(Road::from_scenario)
                .collect::<Result<_>>()?,
        })
    }
    /// The roads.
    pub fn roads(&self) -> &[Road] {
        &self.roads
    }
    /// Whether there is no road.
    pub fn is_empty(&self) -> bool {
        self.roads.is_empty()
    }
    /// The road whose centre line is nearest to `p`, if any.
    pub fn nearest(&self, p: &Vector2<f64>) -> Option<&Road> {
        self.roads
            .iter()
            .map(|r| (r.project(p).offset.abs(), r))
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .map(|(_, r)| r)
    }
}
