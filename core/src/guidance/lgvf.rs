//! Lyapunov guidance vector field (LGVF), the baseline of \[CIMM\] §5 (\[FLM08\] eq. (9), \[LFP08\]).
//!
//! In the frame of the target, `d = (x, y) = p − p_t`, `r = |d|`, standoff radius R and orbit sign
//! `s` (`+1` counter-clockwise), the desired relative velocity is
//!
//! ```text
//! v_d = −v₀ / (r (r² + R²)) · [ x (r² − R²) + s·y (2 r R) ]
//!                             [ y (r² − R²) − s·x (2 r R) ]
//! ```
//!
//! It has magnitude `v₀` everywhere and the circle `r = R` as its globally attracting limit
//! cycle; it is the gradient-plus-circulation field of the Lyapunov function `V = (r² − R²)²`.
//! Our copy of \[CIMM\] gives no equation for the LGVF; this is the standard form of \[FLM08\].
//! Moving target and several UAVs are handled as for [TOGVF](super::togvf): the target velocity is
//! added and the speed corrected by the phase function.
//!
//! The LGVF is planar; for the vertical channel Harrier's baseline uses a proportional height
//! hold `v_z = clamp(−k_z e, ±v_z,max)`, `e = z − z_t − H`, `k_z` = [`Lgvf::kz`].
//!
//! [FLM08]: super#references
//! [LFP08]: super#references

use nalgebra::Vector2;

use super::phase::{PhaseGains, PhaseNeighbours, phase_of, speed_correction};
use super::{
    Command, Limits, Orbit, StandoffLaw, TargetEstimate, UavState, add_target_velocity, clampf,
    hold, valid_inputs,
};

/// LGVF parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lgvf {
    /// Standoff radius R (m).
    pub radius: f64,
    /// Observation height H above the target (m).
    pub height: f64,
    /// Nominal horizontal speed relative to the target, `v₀` (m/s).
    pub speed: f64,
    /// Orbit direction (`Auto` is counter-clockwise: the field itself fixes the sense).
    pub orbit: Orbit,
    /// Phase-coordination gains.
    pub gains: PhaseGains,
    /// Height-hold gain (1/s).
    pub kz: f64,
}

impl Lgvf {
    /// LGVF with radius `R`, height `H` and relative speed `v₀`, counter-clockwise.
    pub fn new(radius: f64, height: f64, speed: f64) -> Self {
        Self {
            radius,
            height,
            speed,
            orbit: Orbit::Ccw,
            gains: PhaseGains::default(),
            kz: 0.1,
        }
    }

    /// Unit direction of the field at relative position `d` for orbit sign `s`.
    pub fn direction(&self, d: Vector2<f64>, s: f64) -> Vector2<f64> {
        let r = d.norm();
        if r < 1e-9 {
            return Vector2::new(1.0, 0.0);
        }
        let rr = self.radius;
        let k = -1.0 / (r * (r * r + rr * rr));
        let v = Vector2::new(
            d.x * (r * r - rr * rr) + s * d.y * (2.0 * r * rr),
            d.y * (r * r - rr * rr) - s * d.x * (2.0 * r * rr),
        ) * k;
        let n = v.norm();
        if n > 1e-12 {
            v / n
        } else {
            Vector2::new(1.0, 0.0)
        }
    }
}

impl StandoffLaw for Lgvf {
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
        let s = self.orbit.sign();
        let d = uav.horizontal_position() - t.position.xy();
        let mut speed = self.speed;
        if let Some(nb) = phase {
            let theta = phase_of(uav.horizontal_position(), t.position.xy());
            speed += speed_correction(theta, s, nb, &self.gains, self.radius);
        }
        let speed = clampf(speed, limits.v_min, limits.v_max);
        let vh = add_target_velocity(
            self.direction(d, s) * speed,
            t.velocity.xy(),
            limits.v_min,
            limits.v_max,
        );
        let e = uav.position.z - t.position.z - self.height;
        let vz = clampf(-self.kz * e, -limits.vz_max, limits.vz_max) + t.velocity.z;
        Command::new(vh, vz).or_hold(uav, limits)
    }
    fn radius(&self) -> f64 {
        self.radius
    }
    fn height(&self) -> f64 {
        self.height
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_is_tangent_on_the_circle_and_inward_outside() {
        let l = Lgvf::new(300.0, 300.0, 20.0);
        let t = l.direction(Vector2::new(300.0, 0.0), 1.0);
        assert!((t - Vector2::new(0.0, 1.0)).norm() < 1e-12);
        let t = l.direction(Vector2::new(3000.0, 0.0), 1.0);
        assert!(t.x < -0.9);
        let t = l.direction(Vector2::new(30.0, 0.0), 1.0);
        assert!(t.x > 0.5);
    }
}
