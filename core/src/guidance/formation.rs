//! LOS-range formation control (\[BOT\] §III.A, eqs. (5)–(6); Sattigeri, Calise & Evers 2004).
//!
//! Aircraft i regulates its line-of-sight range `r_ij` to each neighbour j. The range command
//! `R_com` is filtered through a first-order reference model (time constant τ), giving `r_c` and
//! `ṙ_c`; the pseudo-control is (\[BOT\] eq. (5))
//!
//! ```text
//! v_(i,j) = ṙ_c + k_p (r_c − r_ij) − v_ad(i,j)
//! ```
//!
//! and the commanded velocity is the vector sum along the LOS unit vectors `û_ij` (from i to j),
//! \[BOT\] eq. (6): `V_FC,i = −Σ_j v_(i,j) û_ij`.
//!
//! The adaptive element `v_ad` compensates the unknown velocity of the neighbour along the LOS
//! (`V_j·û_ij`). \[BOT\] uses a neural network fed with delayed range/angle histories; Harrier uses
//! the simplest adaptive element that makes the loop Lyapunov-stable for a neighbour of constant
//! velocity: with `e = r_c − r`, `ė = −k_p e + (v_ad − V_j·û)` and the update law
//! `v̇_ad = −γ e`, `V = ½e² + (v_ad − V_j·û)²/(2γ)` has `V̇ = −k_p e² ≤ 0`. `v_ad` is clamped to
//! `±v_ad,max`.
//!
//! The reference-model and adaptive states are explicit ([`PairState`]); [`RangeRegulator::advance`]
//! is a pure function from the old to the new pair state.

use nalgebra::Vector2;

use super::clampf;

/// Gains of the range regulator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RangeRegulator {
    /// Proportional compensator gain `k_p` (1/s).
    pub kp: f64,
    /// Reference-model time constant τ (s).
    pub tau: f64,
    /// Adaptation gain γ (1/s²).
    pub gamma: f64,
    /// Bound on the adaptive element (m/s).
    pub v_ad_max: f64,
}

impl Default for RangeRegulator {
    fn default() -> Self {
        Self {
            kp: 0.4,
            tau: 5.0,
            gamma: 0.04,
            v_ad_max: 40.0,
        }
    }
}

/// Per-neighbour state: reference-model output and adaptive element.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairState {
    /// Reference-model range `r_c` (m).
    pub r_c: f64,
    /// Adaptive element `v_ad` (m/s).
    pub v_ad: f64,
}

impl PairState {
    /// Starts the reference model at the current range `r`, with no adaptation yet.
    pub fn start(r: f64) -> Self {
        Self { r_c: r, v_ad: 0.0 }
    }
}

impl RangeRegulator {
    /// Reference-model rate `ṙ_c = (R_com − r_c)/τ`.
    #[inline]
    pub fn r_c_dot(&self, pair: &PairState, r_com: f64) -> f64 {
        (r_com - pair.r_c) / self.tau.max(1e-9)
    }

    /// Pseudo-control `v_(i,j)`, \[BOT\] eq. (5), for measured (or estimated) range `r`.
    #[inline]
    pub fn pseudo_control(&self, pair: &PairState, r: f64, r_com: f64) -> f64 {
        self.r_c_dot(pair, r_com) + self.kp * (pair.r_c - r) - pair.v_ad
    }

    /// The pair state after `dt` seconds: reference model (Euler) and adaptive law `v̇_ad = −γ e`.
    /// A non-finite range, a non-finite or negative `dt`, or a step whose result would not be
    /// finite (`dt` = 1e308) leaves the state unchanged.
    pub fn advance(&self, pair: &PairState, r: f64, r_com: f64, dt: f64) -> PairState {
        if !r.is_finite() || !r_com.is_finite() || !dt.is_finite() || dt < 0.0 {
            return *pair;
        }
        let e = pair.r_c - r;
        let next = PairState {
            r_c: pair.r_c + self.r_c_dot(pair, r_com) * dt,
            v_ad: clampf(
                pair.v_ad - self.gamma * e * dt,
                -self.v_ad_max,
                self.v_ad_max,
            ),
        };
        // Overflow (found by the hostile-number tests, core/tests/it/hostile.rs): keep the state.
        if next.r_c.is_finite() && next.v_ad.is_finite() {
            next
        } else {
            *pair
        }
    }
}

impl RangeRegulator {
    /// Pseudo-control hedging (\[BOT\] Fig. 2, PCH), in its simplest form: while the vehicle cannot
    /// follow the formation command (obstacle avoidance has replaced it), the reference model is
    /// moved to the achieved range, `r_c ← r`, and adaptation is frozen, so that neither the
    /// reference model nor the adaptive element winds up; afterwards the reference model brings
    /// `r_c` back to `R_com` with its time constant. A non-finite range leaves the state unchanged.
    pub fn hedge(&self, pair: &PairState, r: f64) -> PairState {
        if !r.is_finite() {
            return *pair;
        }
        PairState {
            r_c: r,
            v_ad: pair.v_ad,
        }
    }
}

/// \[BOT\] eq. (6): `V_FC = −Σ v_(i,j) û_ij` over `(û_ij, v_(i,j))` pairs; non-finite terms are
/// skipped.
pub fn vector_sum(terms: impl IntoIterator<Item = (Vector2<f64>, f64)>) -> Vector2<f64> {
    terms
        .into_iter()
        .filter(|(u, v)| v.is_finite() && u.iter().all(|c| c.is_finite()))
        .fold(Vector2::zeros(), |acc, (u, v)| acc - u * v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One follower behind a leader at constant velocity: the range error vanishes and the
    /// adaptive element converges to the leader's LOS velocity.
    #[test]
    fn regulates_range_to_a_constant_velocity_leader() {
        let reg = RangeRegulator::default();
        let (mut pl, vl) = (Vector2::new(0.0, 0.0), Vector2::new(0.0, 15.0));
        let mut pf = Vector2::new(0.0, -200.0);
        let mut pair = PairState::start(200.0);
        let dt = 0.1;
        for _ in 0..3000 {
            let rel = pl - pf;
            let r = rel.norm();
            let v = reg.pseudo_control(&pair, r, 100.0);
            let cmd = vector_sum([(rel / r, v)]);
            pair = reg.advance(&pair, r, 100.0, dt);
            pf += cmd * dt;
            pl += vl * dt;
        }
        assert!(((pl - pf).norm() - 100.0).abs() < 0.5);
        assert!((pair.v_ad - 15.0).abs() < 0.5);
        let same = reg.advance(&pair, f64::NAN, 100.0, dt);
        assert_eq!(same, pair);
    }
}
