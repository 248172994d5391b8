//! The segments of a road's centre line (lines and circular arcs) and their geometry, and
//! `Geom`, a segment with what the projection needs precomputed.

use std::f64::consts::TAU;

use nalgebra::Vector2;

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
    pub(super) fn point_at(&self, s: f64) -> Vector2<f64> {
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
    pub(super) fn tangent_at(&self, s: f64) -> Vector2<f64> {
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
/// A segment with what the projection needs precomputed (end points and tangents, length,
/// curvature), so that projecting costs one `atan2` per arc and no other trigonometry.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Geom {
    seg: RoadSegment,
    pub(super) start: Vector2<f64>,
    pub(super) end: Vector2<f64>,
    pub(super) t_start: Vector2<f64>,
    pub(super) t_end: Vector2<f64>,
    pub(super) len: f64,
    pub(super) kappa: f64,
}

impl Geom {
    pub(super) fn new(seg: RoadSegment) -> Self {
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
    pub(super) fn raw_param(&self, p: &Vector2<f64>) -> f64 {
        match self.seg {
            RoadSegment::Line { .. } => (p - self.start).dot(&self.t_start),
            RoadSegment::Arc { .. } => self.seg.raw_param(p),
        }
    }

    /// Foot point and tangent for an interior arc length `s` (0 ≤ s ≤ len).
    pub(super) fn interior(&self, p: &Vector2<f64>, s: f64) -> (Vector2<f64>, Vector2<f64>) {
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
