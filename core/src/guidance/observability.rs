//! Range-observability maneuver for bearings-only followers (\[BOT\] §II.B, eqs. (2)–(4)).
//!
//! With bearings only, range is observable only through motion across the line of sight; the
//! best relative motion maximises `β̇²` while keeping β near its desired value β_d and bounding β̈:
//!
//! ```text
//! min ∫ { −β̇² + K₁/2 (β − β_d)² + K₂/2 β̈² } dt
//! ```
//!
//! The Euler–Lagrange equations (\[BOT\] eq. (2); the copy's Hamiltonian has a typo, `K₂/2 β̇²`
//! for `K₂/2 β̈²`) give `β(t) = Σ Aᵢ e^{cᵢ t}` with `K₂ c⁴ + 2 c² + K₁ = 0` (eq. (3)); for
//! `K₁ K₂ = 1` the solution is the pure oscillation `β − β_d = A cos ωt + B sin ωt`, `ω = √K₁`
//! (eq. (4)). For `K₁K₂ < 1` the roots are `c² = (−1 ± √(1 − K₁K₂))/K₂`, two frequencies; we
//! use the lower one.
//!
//! Harrier realises the maneuver as a velocity added across the LOS: with `û` the unit LOS from
//! the follower to the leader and `n̂` = `û` turned by +90°, the follower adds `−r̂ β̇_d(t) n̂`,
//! where `β̇_d = B ω cos ωt` and `r̂` the current range estimate, so that the relative LOS angle
//! follows `β_d + B sin ωt` while the formation law keeps the range.

use nalgebra::Vector2;

use super::perp;

/// The sinusoidal bearing maneuver of \[BOT\] eq. (4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObservabilityManeuver {
    /// Bearing amplitude B (rad).
    pub amplitude: f64,
    /// Angular frequency ω (rad/s).
    pub omega: f64,
}

impl ObservabilityManeuver {
    /// The maneuver for weights `K₁`, `K₂` (\[BOT\] eq. (3)) with bearing amplitude `amplitude`:
    /// `ω² = (1 − √(1 − K₁K₂))/K₂` (`= K₁` when `K₁K₂ = 1`). `None` when `K₁K₂ > 1` (the optimal
    /// bearing then grows or decays exponentially) or a weight is not positive.
    pub fn from_weights(k1: f64, k2: f64, amplitude: f64) -> Option<Self> {
        if k1.is_nan() || k2.is_nan() || k1 <= 0.0 || k2 <= 0.0 || k1 * k2 > 1.0 + 1e-12 {
            return None;
        }
        let w2 = (1.0 - (1.0 - k1 * k2).max(0.0).sqrt()) / k2;
        Some(Self {
            amplitude,
            omega: w2.sqrt(),
        })
    }

    /// Desired bearing rate `β̇_d = B ω cos ωt` (rad/s).
    #[inline]
    pub fn bearing_rate(&self, t: f64) -> f64 {
        self.amplitude * self.omega * (self.omega * t).cos()
    }

    /// Velocity to add across the LOS (m/s): `−r̂ β̇_d(t) n̂` with `û = los / |los|` (follower to
    /// leader) and `n̂ = perp(û)`. Zero for a non-finite or degenerate input.
    pub fn lateral_velocity(&self, los: Vector2<f64>, range_estimate: f64, t: f64) -> Vector2<f64> {
        let n = los.norm();
        if n.is_nan() || n <= 1e-9 || !range_estimate.is_finite() || !n.is_finite() {
            return Vector2::zeros();
        }
        let v = perp(los / n) * (-range_estimate * self.bearing_rate(t));
        if v.iter().all(|c| c.is_finite()) {
            v
        } else {
            Vector2::zeros()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_product_gives_sqrt_k1() {
        let m = ObservabilityManeuver::from_weights(0.04, 25.0, 0.2).unwrap();
        assert!((m.omega - 0.2).abs() < 1e-12);
        assert!(ObservabilityManeuver::from_weights(1.0, 2.0, 0.1).is_none());
        assert_eq!(
            m.lateral_velocity(Vector2::zeros(), 100.0, 0.0),
            Vector2::zeros()
        );
        // β̇ at t = 0 is B ω; the lateral speed is r B ω.
        let v = m.lateral_velocity(Vector2::new(0.0, 100.0), 100.0, 0.0);
        assert!((v.norm() - 100.0 * 0.2 * 0.2).abs() < 1e-9);
    }
}
