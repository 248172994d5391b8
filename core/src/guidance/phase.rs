//! Phase coordination of several UAVs on the same limit cycle (\[CIMM\] §4.3).
//!
//! The phase of UAV i is `θᵢ = atan2(yᵢ − y_t, xᵢ − x_t)` (angle from the x axis, \[CIMM\] §4.3).
//! With n UAVs in a ring the desired gap to the neighbour ahead (in the orbit direction) is
//! `Δ = 2π/n`. The gap errors are `e_a = gap_ahead − Δ` and `e_b = gap_behind − Δ`, gaps taken in
//! `[0, 2π)` along the orbit so that the ring order never flips.
//!
//! \[CIMM\] eqs. (36)–(39) (the Lyapunov phase function and its derivative) are lost in our copy of
//! the paper; we use the standard form of \[FLM08\] §IV with the two gains the paper names:
//! Lyapunov phase function `V_q = ½ Σ eᵢ²` and the speed correction
//!
//! ```text
//! vᵢ = v₀ + k₂ R e_a − k₃ R e_b
//! ```
//!
//! i.e. a UAV with too large a gap ahead speeds up and one with too large a gap behind slows
//! down. For a ring on a static target, `dV_q/dt = −Σ (k₂ e_a − k₃ e_b)(…) ≤ 0` as long as the
//! speeds do not saturate; on a moving target the relative speed is `α v₀` instead of `v₀` and the
//! phases oscillate about the set value, as \[CIMM\] §4.3 notes.
//!
//! [FLM08]: super#references

use nalgebra::Vector2;

use std::f64::consts::TAU;

/// Phase of a UAV around the target, `atan2(y − y_t, x − x_t)` (rad, \[CIMM\] §4.3).
#[inline]
pub fn phase_of(uav: Vector2<f64>, target: Vector2<f64>) -> f64 {
    let d = uav - target;
    d.y.atan2(d.x)
}

/// Gap from phase `from` to phase `to` along the orbit of sign `s` (`+1` ccw), in `[0, 2π)`.
#[inline]
pub fn gap(from: f64, to: f64, s: f64) -> f64 {
    (s * (to - from)).rem_euclid(TAU)
}

/// What one UAV knows about its neighbours on the circle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseNeighbours {
    /// Phase of the next UAV in the orbit direction (rad), if any.
    pub ahead: Option<f64>,
    /// Phase of the previous UAV (rad), if any.
    pub behind: Option<f64>,
    /// Desired gap Δ between neighbours (rad), `2π/n` for an even ring.
    pub spacing: f64,
}

impl PhaseNeighbours {
    /// The neighbours of UAV `i` in a ring of `phases` ordered along the orbit (index `i + 1` is
    /// ahead), with even spacing `2π/n`. `None` for fewer than two UAVs.
    pub fn ring(phases: &[f64], i: usize) -> Option<Self> {
        let n = phases.len();
        if n < 2 || i >= n {
            return None;
        }
        Some(Self {
            ahead: Some(phases[(i + 1) % n]),
            behind: Some(phases[(i + n - 1) % n]),
            spacing: TAU / n as f64,
        })
    }
}

/// Gains of the speed correction: `k₂` on the gap ahead, `k₃` on the gap behind (1/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PhaseGains {
    /// Gain on the gap-ahead error (1/s).
    pub k2: f64,
    /// Gain on the gap-behind error (1/s).
    pub k3: f64,
}

impl Default for PhaseGains {
    fn default() -> Self {
        Self { k2: 0.05, k3: 0.05 }
    }
}

/// The speed correction `k₂ R e_a − k₃ R e_b` (m/s) for a UAV at phase `theta` on an orbit of
/// sign `s` and radius `radius`. Zero when a neighbour phase is not finite.
pub fn speed_correction(
    theta: f64,
    s: f64,
    neighbours: &PhaseNeighbours,
    gains: &PhaseGains,
    radius: f64,
) -> f64 {
    let mut dv = 0.0;
    if let Some(a) = neighbours.ahead.filter(|a| a.is_finite()) {
        dv += gains.k2 * radius * (gap(theta, a, s) - neighbours.spacing);
    }
    if let Some(b) = neighbours.behind.filter(|b| b.is_finite()) {
        dv -= gains.k3 * radius * (gap(b, theta, s) - neighbours.spacing);
    }
    if dv.is_finite() { dv } else { 0.0 }
}

/// Largest absolute spacing error `|gap − 2π/n|` (rad) of a ring of phases on an orbit of sign `s`
/// (UAV order along the orbit as given).
pub fn spacing_errors(phases: &[f64], s: f64) -> impl Iterator<Item = f64> + '_ {
    let n = phases.len();
    let spacing = TAU / n.max(1) as f64;
    (0..n).map(move |i| gap(phases[i], phases[(i + 1) % n], s) - spacing)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn even_ring_needs_no_correction() {
        let phases = [0.0, TAU / 3.0, 2.0 * TAU / 3.0];
        for i in 0..3 {
            let nb = PhaseNeighbours::ring(&phases, i).unwrap();
            let dv = speed_correction(phases[i], 1.0, &nb, &PhaseGains::default(), 300.0);
            assert!(dv.abs() < 1e-9);
        }
        assert!(spacing_errors(&phases, 1.0).all(|e| e.abs() < 1e-12));
    }

    #[test]
    fn large_gap_ahead_speeds_up() {
        let nb = PhaseNeighbours {
            ahead: Some(PI),
            behind: Some(-0.5),
            spacing: 2.0,
        };
        assert!(speed_correction(0.0, 1.0, &nb, &PhaseGains::default(), 300.0) > 0.0);
        let nan = PhaseNeighbours {
            ahead: Some(f64::NAN),
            behind: None,
            spacing: 2.0,
        };
        assert_eq!(
            speed_correction(0.0, 1.0, &nan, &PhaseGains::default(), 300.0),
            0.0
        );
    }
}
