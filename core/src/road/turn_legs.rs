//! A road built from a piecewise constant-turn trajectory ([`road_from_turn_legs`]).

use nalgebra::Vector2;

use crate::scenario::{self, Segment};
use crate::{EstimationError, Result};

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
