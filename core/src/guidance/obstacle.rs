//! "Steer towards silhouette edge" static obstacle avoidance (\[BOT\] §III.B, after Reynolds 1988).
//!
//! Obstacles are circles (bounding circles in 2-D) with known centre and radius, enlarged by a
//! margin for the vehicle size, its turning lag and the uncertainty. An imaginary line of length
//! `D_o` (the look-ahead) starts at the vehicle and points along the commanded direction of
//! flight; an obstacle is a threat when the line meets its enlarged circle. The heading is then
//! changed towards the silhouette edge of that circle — the tangent from the vehicle — closest to
//! the current heading ("the most efficient direction to turn is toward the portion of the
//! projected shape that is closest to the origin"); no speed change is used. The corrected command
//! replaces the formation command while a threat exists; when the hazard has passed the
//! formation command comes back by itself.
//!
//! The line is taken along the *commanded* direction (the paper: along the velocity vector), so
//! that the avoidance filters the command rather than reacting only after the vehicle has turned
//! into the obstacle; several obstacles are handled by re-testing the corrected direction.

use nalgebra::Vector2;

use super::{angle_between, perp, rotate};

/// A circular obstacle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Obstacle {
    /// Centre (m, ENU x/y).
    pub center: Vector2<f64>,
    /// Radius (m).
    pub radius: f64,
}

/// Avoidance parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Avoidance {
    /// Length `D_o` of the look-ahead line (m).
    pub lookahead: f64,
    /// Enlargement of every obstacle radius (m).
    pub margin: f64,
}

/// Where the look-ahead segment from `p` along unit `dir` of length `len` first meets the circle,
/// as a distance along the segment, or `None`.
fn hit(p: Vector2<f64>, dir: Vector2<f64>, len: f64, c: Vector2<f64>, r: f64) -> Option<f64> {
    let m = p - c;
    let b = m.dot(&dir);
    let cc = m.norm_squared() - r * r;
    if cc <= 0.0 {
        return Some(0.0);
    }
    let disc = b * b - cc;
    if disc <= 1e-9 || b > 0.0 {
        return None;
    }
    let t = -b - disc.sqrt();
    (t <= len).then_some(t)
}

/// Corrects the horizontal velocity command `cmd` of a vehicle at `p` flying with `vel` so that
/// the look-ahead line clears every obstacle. Returns the (possibly) corrected command and
/// whether an obstacle forced a correction. A non-finite position, velocity, look-ahead or margin
/// returns `(cmd, false)`, and an obstacle that is not finite is ignored.
pub fn avoid(
    p: Vector2<f64>,
    vel: Vector2<f64>,
    cmd: Vector2<f64>,
    obstacles: &[Obstacle],
    params: &Avoidance,
) -> (Vector2<f64>, bool) {
    let speed = cmd.norm();
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    if speed.is_nan()
        || speed <= 1e-9
        || !finite(p.as_slice())
        || !finite(vel.as_slice())
        || !finite(&[params.lookahead, params.margin])
    {
        return (cmd, false);
    }
    let heading = if vel.norm() > 1e-9 { vel } else { cmd };
    let mut dir = cmd / speed;
    let mut changed = false;
    for _ in 0..=obstacles.len() {
        let threat = obstacles
            .iter()
            // An obstacle that is not finite cannot be steered around: it is ignored.
            .filter(|o| finite(o.center.as_slice()) && o.radius.is_finite())
            .filter_map(|o| {
                hit(p, dir, params.lookahead, o.center, o.radius + params.margin).map(|t| (t, o))
            })
            .min_by(|a, b| a.0.total_cmp(&b.0));
        let Some((_, o)) = threat else { break };
        changed = true;
        let re = o.radius + params.margin;
        let to_c = o.center - p;
        let dist = to_c.norm();
        dir = if dist <= re + 1e-6 {
            // Inside the enlarged circle: slide along it, away from the centre.
            let out = -to_c / dist.max(1e-9);
            let t = perp(out);
            let t = if angle_between(heading, t).abs() <= angle_between(heading, -t).abs() {
                t
            } else {
                -t
            };
            (t + out * 0.5).normalize()
        } else {
            let a = (re / dist).asin() * (1.0 + 1e-6);
            let u = to_c / dist;
            let (e1, e2) = (rotate(u, a), rotate(u, -a));
            if angle_between(heading, e1).abs() <= angle_between(heading, e2).abs() {
                e1
            } else {
                e2
            }
        };
    }
    // Degenerate geometry (a zero-radius circle at the vehicle, overflow) gives no correction.
    if finite(dir.as_slice()) {
        (dir * speed, changed)
    } else {
        (cmd, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clear_path_is_untouched_and_blocked_path_steers_to_an_edge() {
        let obs = [Obstacle {
            center: Vector2::new(0.0, 200.0),
            radius: 50.0,
        }];
        let av = Avoidance {
            lookahead: 300.0,
            margin: 10.0,
        };
        let (c, changed) = avoid(
            Vector2::zeros(),
            Vector2::new(0.0, 15.0),
            Vector2::new(15.0, 0.0),
            &obs,
            &av,
        );
        assert!(!changed);
        assert_eq!(c, Vector2::new(15.0, 0.0));
        let (c, changed) = avoid(
            Vector2::new(5.0, 0.0),
            Vector2::new(0.0, 15.0),
            Vector2::new(0.0, 15.0),
            &obs,
            &av,
        );
        assert!(changed);
        assert!((c.norm() - 15.0).abs() < 1e-9);
        // The corrected line is tangent to (clears) the enlarged circle.
        assert!(hit(Vector2::new(5.0, 0.0), c / 15.0, 300.0, obs[0].center, 60.0).is_none());
        let nan = avoid(
            Vector2::new(f64::NAN, 0.0),
            Vector2::zeros(),
            Vector2::new(1.0, 0.0),
            &obs,
            &av,
        );
        assert!(!nan.1);
    }
}
