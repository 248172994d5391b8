//! Time-optimal guidance vector field (TOGVF, \[CIMM\] §4).
//!
//! **Horizontal** (\[CIMM\] §4.1, Fig. 3), in the frame of the target, `d = p − p_t`, `r = |d|`:
//!
//! * outside the limit cycle (`r > R`) the shortest path is the tangent line. The two tangents
//!   leave the line of sight to the centre at `±asin(R/r)`; the law flies the one that needs the
//!   smaller change of the current (relative) heading ([`Orbit::Auto`]), or the one of a fixed
//!   orbit direction (several UAVs);
//! * inside (`r ≤ R`) the route is a tangent line to an *inner tangential circle* of radius
//!   `r_min` (the minimum turning radius) internally tangent to the limit cycle, then an arc of
//!   that circle, which joins the limit cycle tangentially. The inner-circle centre equations of
//!   the paper are lost in our copy; Harrier's construction: the centre `c` lies on the circle of
//!   radius `R − r_min` about the target and the inner circle passes through the UAV, `|d − c| =
//!   r_min`; of the two solutions the one that carries the UAV outwards is taken, so the same
//!   circle is selected again at the next step. When no inner circle passes through the UAV
//!   (`r < |R − 2 r_min|`) the UAV flies radially outwards, the shortest way towards them.
//!
//! The commanded relative velocity is `v₀` along that direction (\[CIMM\] eq. (30), garbled here:
//! `v_d = v₀ (cos ψ_d, sin ψ_d)`).
//!
//! **Moving target** (\[CIMM\] §4.2): the target velocity is added, `v = v_rel + v_t`, with the
//! relative part scaled by the largest `α ≤ 1` that keeps `|v| ≤ v_max`.
//!
//! **Several UAVs** (\[CIMM\] §4.3): the relative speed `v₀` is corrected by
//! [`phase::speed_correction`](super::phase::speed_correction) (gains `k₂`, `k₃`).
//!
//! **Vertical** (\[CIMM\] §4.1, eqs. (31)–(33)): maximum climb/descent rate until the critical
//! altitude `H + v_z,max²/(2 a_z,max)` (312.5 m for H = 300 m, 5 m/s, 1 m/s², \[CIMM\] §5.2), then
//! uniform deceleration with `a_z,max` so that the vertical speed is zero at H:
//! `v_z = −sign(e) · min(v_z,max, √(2 a_z,max |e|))`, `e = z − z_t − H` (the bang-bang
//! minimum-time law in feedback form).

use nalgebra::Vector2;

use super::phase::{PhaseGains, PhaseNeighbours, phase_of, speed_correction};
use super::{
    Command, Limits, Orbit, StandoffLaw, TargetEstimate, UavState, add_target_velocity,
    angle_between, clampf, hold, perp, rotate, valid_inputs,
};

/// TOGVF parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Togvf {
    /// Standoff radius R (m).
    pub radius: f64,
    /// Observation height H above the target (m).
    pub height: f64,
    /// Nominal horizontal speed relative to the target, `v₀` (m/s).
    pub speed: f64,
    /// Orbit direction.
    pub orbit: Orbit,
    /// Phase-coordination gains (used only when neighbours are given).
    pub gains: PhaseGains,
    /// Factor (≥ 1) applied to the minimum turning radius for the inner tangential circle, a
    /// margin for the kinematics' discrete turns.
    pub turn_margin: f64,
}

impl Togvf {
    /// TOGVF with radius `R`, height `H` and relative speed `v₀`, automatic orbit direction.
    pub fn new(radius: f64, height: f64, speed: f64) -> Self {
        Self {
            radius,
            height,
            speed,
            orbit: Orbit::Auto,
            gains: PhaseGains::default(),
            turn_margin: 1.1,
        }
    }

    /// Orbit direction actually used at relative position `d` with relative velocity `v`.
    fn orbit_sign(&self, d: Vector2<f64>, v: Vector2<f64>) -> f64 {
        match self.orbit {
            Orbit::Ccw => 1.0,
            Orbit::Cw => -1.0,
            Orbit::Auto => {
                let r = d.norm();
                if r > self.radius {
                    // [CIMM] §4.1: the tangent with the smaller deviation from the velocity.
                    let (ccw, cw) = tangents(d, self.radius);
                    if angle_between(v, cw).abs() < angle_between(v, ccw).abs() - 1e-12 {
                        -1.0
                    } else {
                        1.0
                    }
                } else if d.x * v.y - d.y * v.x < 0.0 {
                    -1.0
                } else {
                    1.0
                }
            }
        }
    }

    /// Unit horizontal direction in the target frame for relative position `d`, orbit sign `s`
    /// and minimum turning radius `r_min` (\[CIMM\] §4.1).
    pub fn direction(&self, d: Vector2<f64>, s: f64, r_min: f64) -> Vector2<f64> {
        let big_r = self.radius;
        let r = d.norm();
        if r > big_r {
            let (ccw, cw) = tangents(d, big_r);
            return if s >= 0.0 { ccw } else { cw };
        }
        if r < 1e-9 {
            return Vector2::new(1.0, 0.0);
        }
        let r_min = r_min.min(0.49 * big_r).max(1e-6);
        let rho = big_r - r_min;
        // Circle–circle intersection: |c| = rho, |c − d| = r_min.
        let a = (rho * rho - r_min * r_min + r * r) / (2.0 * r);
        let h2 = rho * rho - a * a;
        let dh = d / r;
        if h2 < 0.0 {
            return dh; // no inner circle through the UAV: straight out.
        }
        let h = h2.sqrt();
        let base = dh * a;
        let mut best = dh;
        let mut best_radial = f64::NEG_INFINITY;
        for c in [base + perp(dh) * h, base - perp(dh) * h] {
            // Motion on the inner circle in the orbit sense.
            let t = perp(d - c) * (s / r_min);
            let radial = t.dot(&dh);
            if radial > best_radial {
                best_radial = radial;
                best = t;
            }
        }
        let n = best.norm();
        if n > 1e-12 { best / n } else { dh }
    }

    /// Vertical speed command for a height error `e = z − z_t − H` (\[CIMM\] §4.1).
    pub fn vertical_speed(e: f64, limits: &Limits) -> f64 {
        let v = limits.vz_max.min((2.0 * limits.az_max * e.abs()).sqrt());
        -e.signum() * v
    }
}

/// The two tangent directions from relative position `d` (|d| > R) to the circle of radius R:
/// `(ccw, cw)` orbit senses.
pub fn tangents(d: Vector2<f64>, radius: f64) -> (Vector2<f64>, Vector2<f64>) {
    let r = d.norm();
    let to_c = -d / r;
    let a = (radius / r).clamp(-1.0, 1.0).asin();
    (rotate(to_c, -a), rotate(to_c, a))
}

impl StandoffLaw for Togvf {
    fn command(
        &self,
        uav: &UavState,
        target: Option<&TargetEstimate>,
        limits: &Limits,
        phase: Option<&PhaseNeighbours>,
    ) -> Command {
        let Some(t) = valid_inputs(uav, target) else {
            return hold(uav, limits);
        };
        let d = uav.horizontal_position() - t.position.xy();
        let vt = t.velocity.xy();
        let v_rel = uav.horizontal_velocity() - vt;
        let s = self.orbit_sign(d, v_rel);
        let mut speed = self.speed;
        if let Some(nb) = phase {
            let theta = phase_of(uav.horizontal_position(), t.position.xy());
            speed += speed_correction(theta, s, nb, &self.gains, self.radius);
        }
        let speed = clampf(speed, limits.v_min, limits.v_max);
        let r_min = limits.min_turn_radius(speed) * self.turn_margin;
        let dir = self.direction(d, s, r_min);
        let vh = add_target_velocity(dir * speed, vt, limits.v_min, limits.v_max);
        let e = uav.position.z - t.position.z - self.height;
        Command::new(vh, Self::vertical_speed(e, limits) + t.velocity.z).or_hold(uav, limits)
    }
    fn radius(&self) -> f64 {
        self.radius
    }
    fn height(&self) -> f64 {
        self.height
    }
}

/// Geometric optimum for reaching the limit cycle from outside: the shortest curvature-bounded
/// path from position `d` (relative to the target, `|d| > R`) with unit heading `u` that first
/// turns with radius `r_min` and then flies the tangent to the circle of radius `R` in orbit sense
/// `s` (a Dubins-type "turn + straight" path). Returns its length (m), or `None` when no such
/// path exists (the UAV starts too close to the circle to turn onto a tangent).
///
/// The turn angle φ solves "heading after the turn equals the tangent direction from the point
/// reached", found by bisection on φ ∈ [0, π] for both turn senses; the length is
/// `r_min φ + √(|d(φ)|² − R²)`.
pub fn optimal_entry_length(
    d: Vector2<f64>,
    u: Vector2<f64>,
    radius: f64,
    r_min: f64,
    s: f64,
) -> Option<f64> {
    let n = u.norm();
    if n.is_nan() || n <= 0.0 || d.norm().is_nan() || d.norm() <= radius {
        return None;
    }
    let u = u / n;
    let mut best: Option<f64> = None;
    for turn in [1.0f64, -1.0] {
        // Position and heading after turning φ with radius r_min in sense `turn`.
        let at = |phi: f64| {
            let c = d + perp(u) * (turn * r_min);
            let p = c + rotate(d - c, turn * phi);
            (p, rotate(u, turn * phi))
        };
        let mismatch = |phi: f64| -> Option<f64> {
            let (p, h) = at(phi);
            if p.norm() <= radius {
                return None;
            }
            let (ccw, cw) = tangents(p, radius);
            let t = if s >= 0.0 { ccw } else { cw };
            Some(angle_between(h, t) * turn)
        };
        // Scan for a sign change of the mismatch, then bisect.
        let steps = 720;
        let mut prev = (0.0, mismatch(0.0));
        for k in 1..=steps {
            let phi = std::f64::consts::PI * k as f64 / steps as f64;
            let cur = (phi, mismatch(phi));
            if let (Some(a), Some(b)) = (prev.1, cur.1) {
                if a == 0.0 || (a > 0.0) != (b > 0.0) && (a - b).abs() < 1.0 {
                    let (mut lo, mut hi) = (prev.0, cur.0);
                    for _ in 0..60 {
                        let mid = 0.5 * (lo + hi);
                        match mismatch(mid) {
                            Some(m) if (m > 0.0) == (a > 0.0) => lo = mid,
                            Some(_) => hi = mid,
                            None => break,
                        }
                    }
                    let phi = 0.5 * (lo + hi);
                    let (p, _) = at(phi);
                    let len = r_min * phi + (p.norm_squared() - radius * radius).max(0.0).sqrt();
                    best = Some(best.map_or(len, |b: f64| b.min(len)));
                    break;
                }
            }
            prev = cur;
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    fn law() -> Togvf {
        Togvf::new(300.0, 300.0, 25.0)
    }

    #[test]
    fn outside_flies_a_tangent() {
        let d = Vector2::new(-400.0, -800.0);
        let (ccw, cw) = tangents(d, 300.0);
        // Both tangents are perpendicular to the radius at the tangent point:
        // the distance from the centre to the tangent line is R.
        for t in [ccw, cw] {
            let dist = (d.x * t.y - d.y * t.x).abs();
            assert!((dist - 300.0).abs() < 1e-9);
        }
        // ccw: the target is on the left of the direction of flight.
        assert!(ccw.x * (-d.y) - ccw.y * (-d.x) > 0.0);
    }

    #[test]
    fn inside_turns_outwards_onto_the_orbit() {
        let l = law();
        for r in [10.0, 150.0, 250.0, 299.0] {
            let d = Vector2::new(r, 0.0);
            let t = l.direction(d, 1.0, 90.0);
            assert!((t.norm() - 1.0).abs() < 1e-9);
            assert!(t.x >= -1e-9, "moves outwards at r = {r}: {t:?}");
        }
        // Near the circle the direction is the ccw tangent.
        let t = l.direction(Vector2::new(299.999, 0.0), 1.0, 90.0);
        assert!(t.y > 0.99);
    }

    /// From inside the circle (even from the centre) the UAV joins the orbit along the inner
    /// tangential circle, within the limits of the kinematics.
    #[test]
    fn closed_loop_from_inside_joins_the_circle() {
        let lim = Limits::fixed_wing();
        let tgt = TargetEstimate::fixed(Vector3::zeros());
        for (start, vel) in [
            (Vector3::new(50.0, 0.0, 300.0), Vector3::new(0.0, 25.0, 0.0)),
            (Vector3::new(0.0, 0.0, 300.0), Vector3::new(-25.0, 0.0, 0.0)),
            (
                Vector3::new(-200.0, 100.0, 300.0),
                Vector3::new(25.0, 0.0, 0.0),
            ),
        ] {
            let mut uav = UavState::new(start, vel);
            let mut joined = None;
            for k in 0..1200 {
                let cmd = law().command(&uav, Some(&tgt), &lim, None);
                uav = crate::guidance::kinematics::step(&uav, &cmd, &lim, 0.1);
                let d = uav.horizontal_position();
                let radial = d.dot(&uav.horizontal_velocity()) / (d.norm() * 25.0);
                if (d.norm() - 300.0).abs() <= 3.0 && radial.abs() < 0.02 {
                    joined = Some(k);
                    break;
                }
            }
            // Within 60 s (the circle is 1885 m around; this is well under half an orbit).
            assert!(
                joined.is_some_and(|k| k < 600),
                "from {start:?}: {joined:?}"
            );
        }
    }

    #[test]
    fn vertical_profile() {
        let lim = Limits::fixed_wing();
        assert_eq!(Togvf::vertical_speed(100.0, &lim), -5.0);
        assert!((Togvf::vertical_speed(12.5, &lim) + 5.0).abs() < 1e-12);
        assert!((Togvf::vertical_speed(2.0, &lim) + 2.0).abs() < 1e-12);
        assert_eq!(Togvf::vertical_speed(-100.0, &lim), 5.0);
    }

    #[test]
    fn optimum_is_tangent_length_when_already_aligned() {
        let d = Vector2::new(-1000.0, 0.0);
        let (ccw, _) = tangents(d, 300.0);
        let len = optimal_entry_length(d, ccw, 300.0, 80.0, 1.0).unwrap();
        assert!((len - (1000.0f64.powi(2) - 300.0f64.powi(2)).sqrt()).abs() < 1e-3);
    }

    proptest! {
        #[test]
        fn never_panics_and_holds_on_bad_input(
            x in -2000.0..2000.0f64, y in -2000.0..2000.0f64, z in 0.0..600.0f64,
            vx in -30.0..30.0f64, vy in -30.0..30.0f64,
            bad in 0usize..4,
        ) {
            let uav = UavState::new(Vector3::new(x, y, z), Vector3::new(vx, vy, 0.0));
            let lim = Limits::fixed_wing();
            let tgt = TargetEstimate::fixed(Vector3::new(100.0, -50.0, 0.0));
            let cmd = law().command(&uav, Some(&tgt), &lim, None);
            prop_assert!(cmd.is_finite());
            prop_assert!(cmd.velocity.xy().norm() <= lim.v_max + 1e-9);
            prop_assert!(cmd.velocity.z.abs() <= lim.vz_max + 1e-9);
            let mut t2 = tgt;
            match bad {
                0 => t2.position.x = f64::NAN,
                1 => t2.velocity.y = f64::INFINITY,
                _ => {}
            }
            let c2 = law().command(&uav, if bad == 3 { None } else { Some(&t2) }, &lim, None);
            prop_assert!(c2.is_finite());
            if bad != 2 {
                prop_assert_eq!(c2, hold(&uav, &lim));
            }
        }
    }
}
