//! Road networks (FORMAT.md §2 `roads`) and the road constraint of \[CIMM\] §3.1 as a
//! pseudo-measurement.
//!
//! A road is a centre line of [`RoadSegment`]s (lines and circular arcs) in travel order.
//! [`Road::project`] finds the nearest point of the centre line: the foot point, the unit tangent
//! (travel direction), the signed lateral offset (> 0 left of the travel direction) and its
//! gradient. Because consecutive segments share their end points, the foot point and the offset
//! are continuous across segment joins; at a kink the foot stays at the corner and the offset
//! gradient turns with `p − corner`. Beyond the free ends of a road the end segment is extended
//! along its tangent, so the constraint stays defined (and smooth) before the first and after the
//! last segment.
//!
//! [`RoadConstraint`] is the pseudo-measurement of \[CIMM\] §3.1 (Tahk & Speyer's "constraint as
//! an additional fictitious measurement"): `z^r = 0 = h_r(x) + v^r`. The paper writes the constraint
//! per segment (a line `y = tan θ·x + b` or an arc `(x − x_c)² + (y − y_c)² = R²`) with noise
//! variance `σ_road²`; here `h_r` is the signed distance to the centre line (which is that
//! constraint normalised to metres, on whichever segment is nearest) with std `sigma_m`, stacked
//! with the velocity component normal to the road (velocity along the tangent) with std
//! `sigma_v`. Both are nonlinear in the state; the EKF linearises them at each mode's predicted
//! mean (the CEKF of \[CIMM\] §3.1).
//!
//! # References
//! * \[CIMM\] `shared/papers/003`, §3.1.
//! * M. Tahk, J. L. Speyer, "Target tracking problems subject to kinematic constraints", IEEE TAC
//!   35(3), 1990.

use std::f64::consts::TAU;

use nalgebra::{Matrix2, SMatrix, SVector, Vector2};

use crate::measurement::MeasurementModel;
use crate::scenario::{self, Segment};
use crate::{EstimationError, Result};

/// Tolerance (m) on the geometry of a road read from a scenario (arc end points on the circle,
/// joins of consecutive segments).
pub const GEOMETRY_TOL_M: f64 = 1e-3;

/// Largest magnitude (m) of a road coordinate or arc radius: far beyond any road, well inside
/// what the projection can square without overflow.
pub const MAX_ROAD_COORD_M: f64 = 1e9;

/// A segment of a road's centre line.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum RoadSegment {
    /// Straight line from `start` to `end`.
    Line {
        /// Start point.
        start: Vector2<f64>,
        /// End point.
        end: Vector2<f64>,
    },
    /// Circular arc about `center`, from polar angle `start_angle`, sweeping `sweep` rad
    /// (> 0 counter-clockwise).
    Arc {
        /// Centre.
        center: Vector2<f64>,
        /// Radius (m).
        radius: f64,
        /// Polar angle of the start point about the centre (rad).
        start_angle: f64,
        /// Signed sweep (rad).
        sweep: f64,
    },
}

impl RoadSegment {
    /// Start point.
    pub fn start(&self) -> Vector2<f64> {
        self.point_at(0.0)
    }
    /// End point.
    pub fn end(&self) -> Vector2<f64> {
        self.point_at(self.length())
    }
    /// Length (m).
    pub fn length(&self) -> f64 {
        match *self {
            Self::Line { start, end } => (end - start).norm(),
            Self::Arc { radius, sweep, .. } => radius * sweep.abs(),
        }
    }
    /// Point at arc length `s` from the start (0 ≤ s ≤ length).
    fn point_at(&self, s: f64) -> Vector2<f64> {
        match *self {
            Self::Line { start, .. } => start + self.tangent_at(s) * s,
            Self::Arc {
                center,
                radius,
                start_angle,
                sweep,
            } => {
                let a = start_angle + sweep.signum() * s / radius;
                center + Vector2::new(a.cos(), a.sin()) * radius
            }
        }
    }
    /// Unit tangent (travel direction) at arc length `s`.
    fn tangent_at(&self, s: f64) -> Vector2<f64> {
        match *self {
            Self::Line { start, end } => (end - start) / (end - start).norm(),
            Self::Arc {
                radius,
                start_angle,
                sweep,
                ..
            } => {
                let a = start_angle + sweep.signum() * s / radius;
                Vector2::new(-a.sin(), a.cos()) * sweep.signum()
            }
        }
    }
    /// Signed curvature (> 0 turning left).
    fn curvature(&self) -> f64 {
        match *self {
            Self::Line { .. } => 0.0,
            Self::Arc { radius, sweep, .. } => sweep.signum() / radius,
        }
    }
    /// Arc length of the point of the (unbounded) segment nearest to `p`, not clamped.
    fn raw_param(&self, p: &Vector2<f64>) -> f64 {
        match *self {
            Self::Line { start, .. } => (p - start).dot(&self.tangent_at(0.0)),
            Self::Arc {
                center,
                radius,
                start_angle,
                sweep,
            } => {
                let d = p - center;
                let phi = d.y.atan2(d.x);
                // Angle travelled from the start in the sweep direction, in [0, 2π).
                let alpha = ((phi - start_angle) * sweep.signum()).rem_euclid(TAU);
                let len = sweep.abs();
                // Outside the arc: go to whichever end is angularly nearer (negative = before start).
                let alpha = if alpha > len && alpha - len > TAU - alpha {
                    alpha - TAU
                } else {
                    alpha
                };
                alpha * radius
            }
        }
    }
}

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

/// A segment with what the projection needs precomputed (end points and tangents, length,
/// curvature), so that projecting costs one `atan2` per arc and no other trigonometry.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Geom {
    seg: RoadSegment,
    start: Vector2<f64>,
    end: Vector2<f64>,
    t_start: Vector2<f64>,
    t_end: Vector2<f64>,
    len: f64,
    kappa: f64,
}

impl Geom {
    fn new(seg: RoadSegment) -> Self {
        let len = seg.length();
        Self {
            seg,
            start: seg.start(),
            end: seg.end(),
            t_start: seg.tangent_at(0.0),
            t_end: seg.tangent_at(len),
            len,
            kappa: seg.curvature(),
        }
    }

    /// Unclamped arc length of the nearest point (see [`RoadSegment::raw_param`]).
    fn raw_param(&self, p: &Vector2<f64>) -> f64 {
        match self.seg {
            RoadSegment::Line { .. } => (p - self.start).dot(&self.t_start),
            RoadSegment::Arc { .. } => self.seg.raw_param(p),
        }
    }

    /// Foot point and tangent for an interior arc length `s` (0 ≤ s ≤ len).
    fn interior(&self, p: &Vector2<f64>, s: f64) -> (Vector2<f64>, Vector2<f64>) {
        match self.seg {
            RoadSegment::Line { .. } => (self.start + self.t_start * s, self.t_start),
            RoadSegment::Arc {
                center,
                radius,
                sweep,
                ..
            } => {
                let d = p - center;
                let r = d.norm();
                if r > 0.0 {
                    (
                        center + d * (radius / r),
                        Vector2::new(-d.y, d.x) * (sweep.signum() / r),
                    )
                } else {
                    (self.seg.point_at(s), self.seg.tangent_at(s))
                }
            }
        }
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

/// The road traced by a piecewise constant-turn trajectory (FORMAT.md §2 `roads`): one straight
/// line per run of straight legs and one arc per turning leg, as the road of \[CIMM\] §5.1 is built
/// from its target's trajectory.
///
/// The trajectory is at `start` with `velocity` (non-zero; its speed is kept) when the first leg
/// begins. `legs` are `(start time s, turn rate rad/s)` in increasing time (rate > 0 turns left,
/// 0 is straight); each leg lasts until the next one starts, the last until `end_t`. A turning
/// leg is an arc of radius speed/|ω| about a centre on the inside of the turn, sweeping ω·duration;
/// consecutive straight legs merge into one line. To let the road begin before the point where a
/// target starts, begin the first (straight) leg earlier and at the matching point.
///
/// # Errors
/// [`EstimationError::InvalidParameter`] if a value is not finite, the speed is zero, the legs
/// are empty or their start times (then `end_t`) do not increase.
pub fn road_from_turn_legs(
    start: Vector2<f64>,
    velocity: Vector2<f64>,
    legs: &[(f64, f64)],
    end_t: f64,
    id: &str,
    width_m: Option<f64>,
    sigma_m: Option<f64>,
) -> Result<scenario::Road> {
    let bad = |what: &str| EstimationError::InvalidParameter(format!("road {id:?}: {what}"));
    let speed = velocity.x.hypot(velocity.y);
    if !(start.iter().all(|v| v.is_finite()) && speed.is_finite() && speed > 0.0) {
        return Err(bad("start and velocity must be finite, the speed > 0"));
    }
    if legs.is_empty() {
        return Err(bad("no legs"));
    }
    let ends = legs.iter().skip(1).map(|l| l.0).chain([end_t]);
    let durations: Vec<f64> = legs.iter().zip(ends).map(|(l, t1)| t1 - l.0).collect();
    if !legs
        .iter()
        .zip(&durations)
        .all(|(l, d)| l.1.is_finite() && d.is_finite() && *d > 0.0)
    {
        return Err(bad(
            "leg start times and end_t must be finite and increasing, turn rates finite",
        ));
    }
    let mut dir = [velocity.x / speed, velocity.y / speed];
    let mut p = [start.x, start.y];
    let mut line_start = p;
    let mut segments = Vec::new();
    let mut in_line = true;
    for (&(_, turn_rate), &duration) in legs.iter().zip(&durations) {
        if turn_rate == 0.0 {
            if !in_line {
                line_start = p;
                in_line = true;
            }
            p = [
                p[0] + dir[0] * speed * duration,
                p[1] + dir[1] * speed * duration,
            ];
            continue;
        }
        if in_line && p != line_start {
            segments.push(Segment::Line {
                start: line_start,
                end: p,
            });
        }
        in_line = false;
        let radius = speed / turn_rate.abs();
        let sign = turn_rate.signum();
        // Centre on the inside of the turn: the left normal for a left turn.
        let center = [p[0] - sign * dir[1] * radius, p[1] + sign * dir[0] * radius];
        let a0 = (p[1] - center[1]).atan2(p[0] - center[0]);
        let sweep = turn_rate * duration;
        let a1 = a0 + sweep;
        let end = [center[0] + radius * a1.cos(), center[1] + radius * a1.sin()];
        segments.push(Segment::Arc {
            center,
            radius,
            start: p,
            end,
            sweep_rad: sweep,
        });
        let (sn, cs) = sweep.sin_cos();
        dir = [dir[0] * cs - dir[1] * sn, dir[0] * sn + dir[1] * cs];
        p = end;
    }
    if in_line && p != line_start {
        segments.push(Segment::Line {
            start: line_start,
            end: p,
        });
    }
    Ok(scenario::Road {
        id: id.into(),
        width_m,
        sigma_m,
        segments,
    })
}

/// The road pseudo-measurement of \[CIMM\] §3.1 for a CV-layout state (`[p; v]`, planar or 3-D):
/// `h_r(x) = [offset(p), n(p)·v]`, measured as `z^r = [0, 0]` with noise
/// `diag(sigma_m², sigma_v²)`: the target is on the centre line (lateral offset 0, std `sigma_m`)
/// and moves along its tangent (normal velocity 0, std `sigma_v`).
#[derive(Debug, Clone, Copy)]
pub struct RoadConstraint<'a> {
    road: &'a Road,
    r: Matrix2<f64>,
}

impl<'a> RoadConstraint<'a> {
    /// Constraint to `road` with its `sigma_m` and normal-velocity std `sigma_v` (m/s, > 0).
    pub fn new(road: &'a Road, sigma_v: f64) -> Self {
        let s = road.sigma_m();
        Self {
            road,
            r: Matrix2::new(s * s, 0.0, 0.0, sigma_v * sigma_v),
        }
    }

    /// The pseudo-measurement value `z^r = [0, 0]`.
    pub fn z() -> Vector2<f64> {
        Vector2::zeros()
    }

    fn split<const N: usize>(x: &SVector<f64, N>) -> (Vector2<f64>, Vector2<f64>) {
        let d = N / 2;
        (Vector2::new(x[0], x[1]), Vector2::new(x[d], x[d + 1]))
    }
}

impl<const N: usize> MeasurementModel<N, 2> for RoadConstraint<'_> {
    fn function(&self, x: &SVector<f64, N>) -> Vector2<f64> {
        let (p, v) = Self::split(x);
        let rp = self.road.project(&p);
        Vector2::new(rp.offset, rp.normal.dot(&v))
    }
    fn jacobian(&self, x: &SVector<f64, N>) -> SMatrix<f64, 2, N> {
        let (p, v) = Self::split(x);
        let rp = self.road.project(&p);
        let d = N / 2;
        let dv = rp.normal_jacobian.transpose() * v;
        let mut j = SMatrix::<f64, 2, N>::zeros();
        j[(0, 0)] = rp.normal.x;
        j[(0, 1)] = rp.normal.y;
        j[(1, 0)] = dv.x;
        j[(1, 1)] = dv.y;
        j[(1, d)] = rp.normal.x;
        j[(1, d + 1)] = rp.normal.y;
        j
    }
    fn covar(&self) -> Matrix2<f64> {
        self.r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use nalgebra::Vector4;

    /// The road of the `cimm_road_*` scenarios: a line, a right arc, a left arc.
    fn road() -> Road {
        let json = r#"{"id":"r","sigma_m":2.0,"segments":[
          {"type":"line","start":[140.0,220.0],"end":[1040.0,1420.0]},
          {"type":"arc","center":[2040.0,670.0],"radius":1250.0,"start":[1040.0,1420.0],
           "end":[2964.6925767461007,1511.0966879679652],"sweep_rad":-1.76},
          {"type":"arc","center":[3704.4466381429806,2183.9740383423364],"radius":1000.0000000000066,
           "start":[2964.6925767461007,1511.0966879679652],"end":[4247.691708011238,3023.548212590115],
           "sweep_rad":3.4}]}"#;
        Road::from_scenario(&serde_json::from_str(json).unwrap()).unwrap()
    }

    #[test]
    fn road_from_turn_legs_rebuilds_the_cimm_road() {
        // (200, 300) m at (6, 8) m/s; the road begins 100 m (10 s) before it.
        let legs = [(-10.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
        let (start, v) = (Vector2::new(140.0, 220.0), Vector2::new(6.0, 8.0));
        let built = road_from_turn_legs(start, v, &legs, 700.0, "r", None, Some(2.0)).unwrap();
        let built = Road::from_scenario(&built).unwrap();
        let want = road();
        assert_eq!(built.segments().len(), want.segments().len());
        for (a, b) in built.segments().iter().zip(want.segments()) {
            assert_relative_eq!(a.start(), b.start(), epsilon = 1e-9);
            assert_relative_eq!(a.end(), b.end(), epsilon = 1e-9);
            assert_relative_eq!(a.length(), b.length(), epsilon = 1e-9);
        }
    }

    #[test]
    fn road_from_turn_legs_follows_the_constant_turn_model() {
        use crate::motion::{ConstantTurn, TransitionModel};
        let legs = [
            (0.0, 0.0),
            (20.0, 0.0),
            (50.0, 0.05),
            (80.0, 0.0),
            (90.0, -0.02),
        ];
        let (start, v) = (Vector2::new(10.0, -5.0), Vector2::new(3.0, -4.0));
        let sc = road_from_turn_legs(start, v, &legs, 150.0, "r", Some(7.0), Some(1.0)).unwrap();
        assert_eq!(
            (sc.id.as_str(), sc.width_m, sc.sigma_m),
            ("r", Some(7.0), Some(1.0))
        );
        // Straight legs merge: line, arc, line, arc.
        assert_eq!(sc.segments.len(), 4);
        let road = Road::from_scenario(&sc).unwrap();
        let mut x = Vector4::new(start.x, start.y, v.x, v.y);
        let mut t = 0.0;
        let ends = legs.iter().skip(1).map(|l| l.0).chain([150.0]);
        for (&(_, w), t1) in legs.iter().zip(ends) {
            while t < t1 - 1e-9 {
                let dt = (t1 - t).min(1.0);
                x = ConstantTurn::<4>::new(w, 0.0).function(&x, dt);
                t += dt;
                let rp = road.project(&Vector2::new(x[0], x[1]));
                assert!(rp.offset.abs() < 1e-6, "t {t}: offset {}", rp.offset);
                assert_relative_eq!(rp.tangent, Vector2::new(x[2], x[3]) / 5.0, epsilon = 1e-9);
            }
        }
        assert_relative_eq!(
            road.segments()[3].end(),
            Vector2::new(x[0], x[1]),
            epsilon = 1e-9
        );
    }

    #[test]
    fn road_from_turn_legs_refuses_bad_input() {
        let (p, v) = (Vector2::zeros(), Vector2::new(1.0, 0.0));
        let ok = |legs: &[(f64, f64)], end, v| {
            road_from_turn_legs(p, v, legs, end, "r", None, None).is_ok()
        };
        assert!(ok(&[(0.0, 0.1)], 1.0, v));
        assert!(!ok(&[], 1.0, v));
        assert!(!ok(&[(0.0, 0.1)], 0.0, v));
        assert!(!ok(&[(0.0, 0.0), (0.0, 0.1)], 1.0, v));
        assert!(!ok(&[(0.0, f64::NAN)], 1.0, v));
        assert!(!ok(&[(0.0, 0.1)], 1.0, Vector2::zeros()));
    }

    #[test]
    fn points_on_the_centre_line_have_zero_offset() {
        let r = road();
        for (k, seg) in r.segments().iter().enumerate() {
            for f in [0.1, 0.5, 0.9] {
                let s = f * seg.length();
                let rp = r.project(&seg.point_at(s));
                assert!(rp.offset.abs() < 1e-8, "{k} {f}: {}", rp.offset);
                assert_relative_eq!(rp.tangent, seg.tangent_at(s), epsilon = 1e-9);
                // 5 m to the left of travel.
                let left = Vector2::new(-rp.tangent.y, rp.tangent.x);
                let rp2 = r.project(&(seg.point_at(s) + left * 5.0));
                assert_relative_eq!(rp2.offset, 5.0, epsilon = 1e-8);
            }
        }
    }

    #[test]
    fn projection_is_continuous_across_joins() {
        let r = road();
        for w in r.segments().windows(2) {
            let join = w[0].end();
            let t = w[0].tangent_at(w[0].length());
            let left = Vector2::new(-t.y, t.x);
            for lateral in [-6.0, 0.0, 3.0] {
                let mut prev: Option<RoadPoint> = None;
                for i in -200..=200 {
                    let p = join + t * (f64::from(i) * 0.01) + left * lateral;
                    let rp = r.project(&p);
                    if let Some(q) = prev {
                        assert!((rp.point - q.point).norm() < 0.05, "foot jumps at {p}");
                        assert!((rp.offset - q.offset).abs() < 1e-3, "offset jumps at {p}");
                        assert!((rp.normal - q.normal).norm() < 1e-3, "normal jumps at {p}");
                    }
                    prev = Some(rp);
                }
            }
        }
    }

    #[test]
    fn free_ends_extend_along_the_tangent() {
        let r = road();
        let t = Vector2::new(0.6, 0.8);
        let rp = r.project(&(Vector2::new(140.0, 220.0) - t * 50.0 + Vector2::new(-0.8, 0.6)));
        assert_relative_eq!(rp.offset, 1.0, epsilon = 1e-9);
        assert_relative_eq!(
            rp.point,
            Vector2::new(140.0, 220.0) - t * 50.0,
            epsilon = 1e-9
        );
    }

    #[test]
    fn constraint_jacobian_matches_central_differences() {
        let r = road();
        let c = RoadConstraint::new(&r, 0.5);
        for x in [
            Vector4::new(600.0, 830.0, 6.0, 8.5),
            Vector4::new(2040.0 - 100.0, 670.0 + 1240.0, 10.0, -1.0),
            Vector4::new(3704.0 + 20.0, 2184.0 - 990.0, 9.0, 3.0),
        ] {
            let j = MeasurementModel::<4, 2>::jacobian(&c, &x);
            for col in 0..4 {
                let mut xp = x;
                let mut xm = x;
                xp[col] += 1e-4;
                xm[col] -= 1e-4;
                let num = (MeasurementModel::<4, 2>::function(&c, &xp)
                    - MeasurementModel::<4, 2>::function(&c, &xm))
                    / 2e-4;
                assert_relative_eq!(j.column(col).into_owned(), num, epsilon = 1e-6);
            }
        }
    }

    #[test]
    fn malformed_roads_are_refused() {
        let gap = r#"{"id":"r","sigma_m":2.0,"segments":[
          {"type":"line","start":[0,0],"end":[10,0]},{"type":"line","start":[11,0],"end":[20,0]}]}"#;
        assert!(Road::from_scenario(&serde_json::from_str(gap).unwrap()).is_err());
        let arc = r#"{"id":"r","sigma_m":2.0,"segments":[{"type":"arc","center":[0,0],"radius":10,
          "start":[10,0],"end":[0,10],"sweep_rad":-1.5707963267948966}]}"#;
        assert!(Road::from_scenario(&serde_json::from_str(arc).unwrap()).is_err());
    }
}
