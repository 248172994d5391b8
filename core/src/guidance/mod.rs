//! Guidance laws: from a UAV state and a target estimate to a commanded velocity vector.
//!
//! Every law here is a pure function of `(UAV state, target estimate, limits, parameters)` that
//! returns a [`Command`] (a desired ENU velocity, m/s). None of them panics: a missing or
//! non-finite target estimate, or a non-finite UAV state, gives the defined safe command
//! [`hold`]. The [`kinematics`] module closes the loop for evaluation: a 3-DOF point mass that
//! enforces the speed, turn-rate and vertical limits of a [`Limits`] profile.
//!
//! | law | module | paper |
//! |---|---|---|
//! | time-optimal guidance vector field (tangent to the limit cycle, time-optimal climb/descent) | [`togvf`] | \[CIMM\] §4.1–4.2 |
//! | Lyapunov guidance vector field (baseline) | [`lgvf`] | Frew, Lawrence & Morris 2008 |
//! | phase spacing of several UAVs on the circle (speed correction) | [`phase`] | \[CIMM\] §4.3 |
//! | LOS-range formation control with reference model, P compensator, adaptive element | [`formation`] | \[BOT\] §III.A eqs. (5)–(6) |
//! | "steer towards silhouette edge" obstacle avoidance | [`obstacle`] | \[BOT\] §III.B |
//! | range-observability maneuver for bearings-only followers | [`observability`] | \[BOT\] §II.B eqs. (2)–(4) |
//!
//! Frame: ENU metres (x East, y North, z Up), FORMAT.md §1. Phases `θ = atan2(y − y_t, x − x_t)`
//! are measured from the x axis as in \[CIMM\] §4.3.
//!
//! # References
//! * \[CIMM\] the constrained-IMM / TOGVF paper (`shared/papers/003_*.txt`).
//! * \[BOT\] Calise, Johnson, Sattigeri, Watanabe, Madyastha, *Estimation and Guidance Strategies
//!   for Vision-based Target Tracking* (`shared/papers/002_*.txt`).
//! * \[FLM08\] E. W. Frew, D. A. Lawrence, S. Morris, "Coordinated Standoff Tracking of Moving
//!   Targets Using Lyapunov Guidance Vector Fields", JGCD 31(2), 2008.
//! * \[LFP08\] D. A. Lawrence, E. W. Frew, W. J. Pisano, "Lyapunov Vector Fields for Autonomous
//!   Unmanned Aircraft Flight Control", JGCD 31(5), 2008.

pub mod formation;
mod geometry;
pub mod kinematics;
pub mod lgvf;
pub mod observability;
pub mod obstacle;
pub mod phase;
pub mod togvf;

use nalgebra::{Vector2, Vector3};

pub(crate) use geometry::{angle_between, clampf, perp, rotate};
pub use kinematics::{Command, Limits, UavState, hold};

/// What the guidance knows about the target: a ground position and velocity estimate (ENU).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TargetEstimate {
    /// Position (m); `z` is the ground height of the target.
    pub position: Vector3<f64>,
    /// Velocity (m/s).
    pub velocity: Vector3<f64>,
}

impl TargetEstimate {
    /// A static target at `position`.
    pub fn fixed(position: Vector3<f64>) -> Self {
        Self {
            position,
            velocity: Vector3::zeros(),
        }
    }
    /// Whether position and velocity are finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.position
            .iter()
            .chain(self.velocity.iter())
            .all(|v| v.is_finite())
    }
}

/// Sense of rotation on the limit cycle (seen from above).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Orbit {
    /// Counter-clockwise (phase increasing).
    Ccw,
    /// Clockwise (phase decreasing).
    Cw,
    /// Whichever needs the smaller heading change now (\[CIMM\] §4.1; ties go to `Ccw`).
    Auto,
}

impl Orbit {
    /// `+1` for counter-clockwise, `−1` for clockwise (`Auto` counts as `+1`).
    #[inline]
    pub fn sign(self) -> f64 {
        match self {
            Orbit::Cw => -1.0,
            Orbit::Ccw | Orbit::Auto => 1.0,
        }
    }
}

/// The validated inputs shared by the standoff laws, or `None` when [`hold`] applies.
pub(crate) fn valid_inputs<'a>(
    uav: &UavState,
    target: Option<&'a TargetEstimate>,
) -> Option<&'a TargetEstimate> {
    target.filter(|t| t.is_finite() && uav.is_finite())
}

/// Scales a relative horizontal velocity `v_rel` by the largest `α ∈ [0, 1]` such that
/// `|α v_rel + v_t| ≤ v_max` and returns `α v_rel + v_t` (\[CIMM\] §4.2/§4.3: "the horizontal speed
/// in the relative frame is `α v₀`"). If even `α = 0` violates the bound the target is faster than
/// the UAV and the result is `v_t` clipped to `v_max`.
///
/// A vehicle that cannot hover flies no slower than `v_min` over the ground (no wind): when
/// `|v_rel + v_t| < v_min` the relative velocity is stretched instead, by the smallest `α ≥ 1`
/// with `|α v_rel + v_t| = v_min`, so the vehicle keeps its course relative to the target (the
/// guidance vector field's direction) at the speed it can fly, rather than the kinematics
/// speeding it up along the commanded ground course, off the field.
pub(crate) fn add_target_velocity(
    v_rel: Vector2<f64>,
    v_t: Vector2<f64>,
    v_min: f64,
    v_max: f64,
) -> Vector2<f64> {
    let full = v_rel + v_t;
    let n = full.norm();
    if n < v_min && v_rel.norm_squared() > 0.0 {
        // |α a + b|² = v_min² → the larger root, ≥ 1 since |a + b| < v_min.
        let a2 = v_rel.norm_squared();
        let ab = v_rel.dot(&v_t);
        let c = v_t.norm_squared() - v_min * v_min;
        let alpha = (-ab + (ab * ab - a2 * c).max(0.0).sqrt()) / a2;
        return if alpha.is_finite() {
            v_rel * alpha.max(1.0) + v_t
        } else {
            full
        };
    }
    if n <= v_max {
        return full;
    }
    // |α a + b|² = v²  →  α²|a|² + 2α a·b + |b|² − v² = 0, the larger root.
    let a2 = v_rel.norm_squared();
    let ab = v_rel.dot(&v_t);
    let c = v_t.norm_squared() - v_max * v_max;
    if a2 <= 0.0 || c > 0.0 {
        let n = v_t.norm();
        return if n > v_max { v_t * (v_max / n) } else { v_t };
    }
    let alpha = ((-ab + (ab * ab - a2 * c).max(0.0).sqrt()) / a2).clamp(0.0, 1.0);
    v_rel * alpha + v_t
}

/// Common interface of the standoff laws ([`togvf::Togvf`], [`lgvf::Lgvf`]) so that the simulator
/// and the tests can swap them.
pub trait StandoffLaw {
    /// Commanded velocity for one UAV. `phase` carries the phases of its neighbours on the circle
    /// when several UAVs share the target (\[CIMM\] §4.3); `None` for a single UAV.
    fn command(
        &self,
        uav: &UavState,
        target: Option<&TargetEstimate>,
        limits: &Limits,
        phase: Option<&phase::PhaseNeighbours>,
    ) -> Command;
    /// Standoff radius R (m).
    fn radius(&self) -> f64;
    /// Observation height H above the target (m).
    fn height(&self) -> f64;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn add_target_velocity_respects_vmax() {
        let v = add_target_velocity(Vector2::new(25.0, 0.0), Vector2::new(10.0, 0.0), 0.0, 30.0);
        assert!((v.norm() - 30.0).abs() < 1e-9);
        let v = add_target_velocity(Vector2::new(25.0, 0.0), Vector2::new(-10.0, 0.0), 0.0, 30.0);
        assert!((v.x - 15.0).abs() < 1e-12);
        let v = add_target_velocity(Vector2::new(5.0, 0.0), Vector2::new(0.0, 50.0), 0.0, 30.0);
        assert!(v.norm() <= 30.0 + 1e-9);
    }

    /// A fixed wing orbiting against the target's motion: 12 m/s relative west, the target 5 m/s
    /// east, 7 m/s over the ground is below its 10 m/s floor: the relative velocity is stretched
    /// to 15 m/s west, so it still flies west (the field's way) at 10 m/s.
    #[test]
    fn add_target_velocity_respects_the_speed_floor() {
        let v = add_target_velocity(Vector2::new(-12.0, 0.0), Vector2::new(5.0, 0.0), 10.0, 22.0);
        assert!((v - Vector2::new(-10.0, 0.0)).norm() < 1e-9, "{v}");
        // Across the target's motion the direction relative to it is kept.
        let v = add_target_velocity(Vector2::new(0.0, 6.0), Vector2::new(5.0, 0.0), 10.0, 22.0);
        assert!(
            (v.norm() - 10.0).abs() < 1e-9 && v.x == 5.0 && v.y > 6.0,
            "{v}"
        );
        // A multirotor (v_min 0) is left alone, and no relative velocity stays none.
        let v = add_target_velocity(Vector2::new(-5.0, 0.0), Vector2::new(5.0, 0.0), 0.0, 15.0);
        assert_eq!(v, Vector2::zeros());
        let v = add_target_velocity(Vector2::zeros(), Vector2::new(5.0, 0.0), 10.0, 15.0);
        assert_eq!(v, Vector2::new(5.0, 0.0));
    }

    /// Nonsense limits or gains must not panic (no `f64::clamp` on caller-supplied bounds).
    #[test]
    fn bad_limits_do_not_panic() {
        let bad = Limits {
            v_max: f64::NAN,
            v_min: 40.0,
            turn_rate_max: -1.0,
            bank_max: f64::NAN,
            accel_max: f64::NAN,
            vz_max: -5.0,
            az_max: f64::INFINITY,
            pivot_speed: f64::NAN,
        };
        let uav = UavState::new(Vector3::new(0.0, 0.0, 100.0), Vector3::new(20.0, 0.0, 0.0));
        let tgt = TargetEstimate::fixed(Vector3::new(1000.0, 0.0, 0.0));
        let c1 = togvf::Togvf::new(300.0, 300.0, 25.0).command(&uav, Some(&tgt), &bad, None);
        let c2 = lgvf::Lgvf::new(300.0, 300.0, 25.0).command(&uav, Some(&tgt), &bad, None);
        for c in [c1, c2, hold(&uav, &bad)] {
            let _ = kinematics::step(&uav, &c, &bad, 0.1);
        }
        let reg = formation::RangeRegulator {
            v_ad_max: -1.0,
            ..Default::default()
        };
        let _ = reg.advance(&formation::PairState::start(100.0), 90.0, 100.0, 0.1);
    }

    #[test]
    fn hold_is_finite() {
        let uav = UavState::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::zeros());
        assert!(hold(&uav, &Limits::fixed_wing()).is_finite());
        assert!(hold(&uav, &Limits::multirotor()).is_finite());
    }
}
