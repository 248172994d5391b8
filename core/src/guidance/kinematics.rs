//! UAV kinematics for closed-loop evaluation: the 3-DOF point mass of \[CIMM\] §2.2 with decoupled
//! horizontal and vertical motion,
//!
//! ```text
//! ẋ = V cos ψ,  ẏ = V sin ψ,  ż = v_z          (ψ from the x axis)
//! |ψ̇| ≤ min(ω_max, g·tan φ_max / V)  (r_min = V / that),  v_min ≤ V ≤ v_max,  |V̇| ≤ a_h
//! |v_z| ≤ v_z,max,  |v̇_z| ≤ a_z,max
//! ```
//!
//! The second turn-rate bound is a fixed wing's coordinated turn at its bank-angle limit φ_max
//! (the lift's horizontal part g·tan φ is the centripetal acceleration V·ψ̇: Beard & McLain,
//! *Small Unmanned Aircraft*, eq. 9.14); [`Limits::bank_max`] ≥ π/2 leaves it out.
//!
//! A [`Command`] is a desired velocity vector; [`step`] moves the state towards it for `dt` seconds
//! while enforcing every limit, so any command — including a non-finite one, which is replaced by
//! [`hold`] — yields a feasible trajectory.

use std::f64::consts::FRAC_PI_2;

use nalgebra::{Vector2, Vector3};

use super::geometry::{angle_between, clampf, perp, rotate};

/// Standard gravity (m/s²).
pub const GRAVITY: f64 = 9.80665;

/// A commanded velocity (ENU, m/s). The kinematics enforce the limits; laws already respect the
/// speed bounds where they can.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Command {
    /// Desired velocity `[vx, vy, vz]` (m/s).
    pub velocity: Vector3<f64>,
}

impl Command {
    /// A command with the horizontal velocity `vh` and the vertical speed `vz`.
    #[inline]
    pub fn new(vh: Vector2<f64>, vz: f64) -> Self {
        Self {
            velocity: Vector3::new(vh.x, vh.y, vz),
        }
    }
    /// Whether every component is finite.
    #[inline]
    pub fn is_finite(&self) -> bool {
        self.velocity.iter().all(|v| v.is_finite())
    }
    /// This command if it is finite, else [`hold`] for `uav`.
    #[inline]
    pub fn or_hold(self, uav: &UavState, limits: &Limits) -> Self {
        if self.is_finite() {
            self
        } else {
            hold(uav, limits)
        }
    }
}

/// The defined safe command when the target estimate is missing or invalid: keep station.
///
/// A vehicle that can hover ([`Limits::can_hover`]) is commanded to stop (zero velocity). A
/// fixed-wing vehicle is commanded into a left loiter turn at its minimum speed: the commanded
/// direction is the current velocity rotated by +90°, which the kinematics turn into a
/// minimum-radius circle. Vertical speed zero (hold altitude). With a non-finite UAV state the
/// command is zero, which the kinematics also treat as "hold".
pub fn hold(uav: &UavState, limits: &Limits) -> Command {
    let vh = uav.horizontal_velocity();
    if limits.can_hover() || !vh.iter().all(|v| v.is_finite()) {
        return Command::new(Vector2::zeros(), 0.0);
    }
    let dir = if vh.norm() > 1e-9 {
        vh / vh.norm()
    } else {
        Vector2::new(1.0, 0.0)
    };
    Command::new(perp(dir) * limits.v_min, 0.0)
}

/// Flight envelope of a vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Maximum horizontal speed (m/s).
    pub v_max: f64,
    /// Minimum horizontal speed (m/s): 0 for a vehicle that can hover, the stall margin otherwise.
    pub v_min: f64,
    /// Maximum turn rate of the horizontal velocity (rad/s).
    pub turn_rate_max: f64,
    /// Maximum bank angle of a coordinated turn (rad): the turn rate at speed V is also at most
    /// `g·tan(bank_max)/V`. π/2 or more: no such bound (a multirotor, or a profile given by its
    /// turn rate alone).
    pub bank_max: f64,
    /// Maximum rate of change of horizontal speed (m/s²).
    pub accel_max: f64,
    /// Maximum vertical speed, climb and descent (m/s).
    pub vz_max: f64,
    /// Maximum vertical acceleration (m/s²).
    pub az_max: f64,
    /// Below this horizontal speed a hovering vehicle may point its velocity anywhere (m/s); the
    /// turn-rate limit applies above it. Ignored for vehicles with `v_min > 0`.
    pub pivot_speed: f64,
}

impl Limits {
    /// Fixed-wing profile used by the \[CIMM\] cases: 12–35 m/s, 0.3 rad/s (r_min ≈ 83 m at
    /// 25 m/s), 3 m/s² along track, 5 m/s and 1 m/s² vertically (\[CIMM\] §5.2: critical altitude
    /// 312.5 m for H = 300 m).
    pub fn fixed_wing() -> Self {
        Self {
            v_max: 35.0,
            v_min: 12.0,
            turn_rate_max: 0.3,
            bank_max: FRAC_PI_2,
            accel_max: 3.0,
            vz_max: 5.0,
            az_max: 1.0,
            pivot_speed: 0.0,
        }
    }
    /// Multirotor profile: can hover, 0–15 m/s, 1 rad/s, 4 m/s², 5 m/s and 2 m/s² vertically.
    pub fn multirotor() -> Self {
        Self {
            v_max: 15.0,
            v_min: 0.0,
            turn_rate_max: 1.0,
            bank_max: FRAC_PI_2,
            accel_max: 4.0,
            vz_max: 5.0,
            az_max: 2.0,
            pivot_speed: 0.5,
        }
    }
    /// A fixed wing as an autopilot flies it: airspeed `v_min`–`v_max` (no wind: the ground
    /// speed), turns bounded by the bank limit `bank_max` (rad; rate g·tan φ/V, 1 rad/s at most),
    /// 2 m/s² along track, climb and sink `vz_max`, 1 m/s² vertically. ArduPlane's
    /// AIRSPEED_MIN/MAX and ROLL_LIMIT_DEG, PX4's FW_AIRSPD_MIN/MAX and FW_R_LIM.
    pub fn bank_limited(v_min: f64, v_max: f64, bank_max: f64, vz_max: f64) -> Self {
        Self {
            v_max,
            v_min,
            turn_rate_max: 1.0,
            bank_max,
            accel_max: 2.0,
            vz_max,
            az_max: 1.0,
            pivot_speed: 0.0,
        }
    }
    /// Largest turn rate at horizontal speed `v` (rad/s): `min(ω_max, g·tan φ_max / v)`.
    #[inline]
    pub fn turn_rate_at(&self, v: f64) -> f64 {
        let omega = self.turn_rate_max.max(0.0);
        // No bank limit at π/2 or more (or NaN).
        let banked = self.bank_max < FRAC_PI_2;
        if !banked || v.abs() < 1e-9 {
            return omega;
        }
        let bank = GRAVITY * self.bank_max.max(0.0).tan() / v.abs();
        if bank < omega { bank } else { omega }
    }
    /// Whether the vehicle can stop in the air (`v_min == 0`).
    #[inline]
    pub fn can_hover(&self) -> bool {
        self.v_min <= 0.0
    }
    /// Minimum turning radius at horizontal speed `v` (m): `V / ω` with ω the turn-rate bound
    /// of [`Self::turn_rate_at`] (`V²/(g tan φ_max)` when the bank limit governs).
    #[inline]
    pub fn min_turn_radius(&self, v: f64) -> f64 {
        v.abs() / self.turn_rate_at(v).max(1e-9)
    }
    /// Altitude band, above the goal height, at which a maximum-rate descent must start braking
    /// with the maximum deceleration: `v_z,max² / (2 a_z,max)` (\[CIMM\] §4.1; 12.5 m for 5 m/s and
    /// 1 m/s²).
    #[inline]
    pub fn braking_height(&self) -> f64 {
        self.vz_max * self.vz_max / (2.0 * self.az_max.max(1e-9))
    }
}

/// Position and velocity of a UAV (ENU, m and m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UavState {
    /// Position.
    pub position: Vector3<f64>,
    /// Velocity.
    pub velocity: Vector3<f64>,
}

impl UavState {
    /// A state from position and velocity.
    pub fn new(position: Vector3<f64>, velocity: Vector3<f64>) -> Self {
        Self { position, velocity }
    }
    /// Horizontal position `[x, y]`.
    #[inline]
    pub fn horizontal_position(&self) -> Vector2<f64> {
        self.position.xy()
    }
    /// Horizontal velocity `[vx, vy]`.
    #[inline]
    pub fn horizontal_velocity(&self) -> Vector2<f64> {
        self.velocity.xy()
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

/// Advances `state` by `dt` seconds towards the commanded velocity while enforcing `limits`.
///
/// Horizontal speed moves towards `clamp(|v_cmd|, v_min, v_max)` by at most `a_h·dt`; the
/// velocity direction turns towards the commanded one by at most `ω_max·dt` (a hovering vehicle
/// below [`Limits::pivot_speed`] may point anywhere); the vertical speed moves towards
/// `clamp(v_z,cmd, ±v_z,max)` by at most `a_z,max·dt`. Position is integrated with the mean of the
/// old and new velocity. A non-finite command is replaced by [`hold`]; a non-finite
/// state or `dt`, or a step whose result would not be finite (a position near `f64::MAX`, a `dt`
/// of 1e300), returns the state unchanged.
pub fn step(state: &UavState, cmd: &Command, limits: &Limits, dt: f64) -> UavState {
    if !state.is_finite() || !dt.is_finite() || dt <= 0.0 {
        return *state;
    }
    let cmd = cmd.or_hold(state, limits);
    let v = state.horizontal_velocity();
    let s = v.norm();
    let vd = cmd.velocity.xy();
    let sd_raw = vd.norm();
    let sd = clampf(sd_raw, limits.v_min, limits.v_max);
    let u = if s > 1e-9 {
        v / s
    } else if sd_raw > 1e-9 {
        vd / sd_raw
    } else {
        Vector2::new(1.0, 0.0)
    };
    let ud = if sd_raw > 1e-9 { vd / sd_raw } else { u };
    let dv = limits.accel_max * dt;
    let s_new = clampf(s + clampf(sd - s, -dv, dv), limits.v_min, limits.v_max);
    let u_new = if limits.can_hover() && s < limits.pivot_speed {
        ud
    } else {
        let dpsi = limits.turn_rate_at(s) * dt;
        rotate(u, clampf(angle_between(u, ud), -dpsi, dpsi))
    };
    let vh = u_new * s_new;
    let vz_cmd = clampf(cmd.velocity.z, -limits.vz_max, limits.vz_max);
    let daz = limits.az_max * dt;
    let vz = clampf(
        state.velocity.z + clampf(vz_cmd - state.velocity.z, -daz, daz),
        -limits.vz_max,
        limits.vz_max,
    );
    let velocity = Vector3::new(vh.x, vh.y, vz);
    let next = UavState {
        position: state.position + (state.velocity + velocity) * (0.5 * dt),
        velocity,
    };
    // Overflow of huge states or steps (found by the hostile-number tests): keep the state.
    if next.is_finite() { next } else { *state }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn check(prev: &UavState, next: &UavState, l: &Limits, dt: f64) {
        let tol = 1e-9;
        let s0 = prev.horizontal_velocity().norm();
        let s1 = next.horizontal_velocity().norm();
        assert!(next.is_finite());
        assert!(s1 <= l.v_max + tol && s1 >= l.v_min - tol, "speed {s1}");
        assert!(next.velocity.z.abs() <= l.vz_max + tol);
        assert!((next.velocity.z - prev.velocity.z).abs() <= l.az_max * dt + tol);
        if s0 >= l.v_min.max(l.pivot_speed) && s0 > 1e-6 {
            let turn = angle_between(prev.horizontal_velocity(), next.horizontal_velocity()).abs();
            assert!(turn <= l.turn_rate_at(s0) * dt + 1e-9, "turn {turn}");
            assert!((s1 - s0).abs() <= l.accel_max * dt + tol);
        }
    }

    fn finite_or_nan() -> impl Strategy<Value = f64> {
        prop_oneof![9 => -100.0..100.0f64, 1 => Just(f64::NAN), 1 => Just(f64::INFINITY)]
    }

    proptest! {
        #[test]
        fn limits_hold_for_any_command(
            vx in -40.0..40.0f64, vy in -40.0..40.0f64, vz in -5.0..5.0f64,
            cx in finite_or_nan(), cy in finite_or_nan(), cz in finite_or_nan(),
            kind in 0..3u8, dt in 0.01..1.0f64,
        ) {
            let l = match kind {
                0 => Limits::multirotor(),
                1 => Limits::fixed_wing(),
                _ => Limits::bank_limited(9.0, 22.0, 45f64.to_radians(), 5.0),
            };
            // Start from a feasible state.
            let v = Vector2::new(vx, vy);
            let s = v.norm().clamp(l.v_min.max(1.0), l.v_max);
            let v = if v.norm() > 1e-9 { v / v.norm() * s } else { Vector2::new(s, 0.0) };
            let prev = UavState::new(Vector3::new(1.0, 2.0, 300.0), Vector3::new(v.x, v.y, vz));
            let cmd = Command { velocity: Vector3::new(cx, cy, cz) };
            let next = step(&prev, &cmd, &l, dt);
            check(&prev, &next, &l, dt);
        }
    }

    #[test]
    fn nan_state_is_returned_unchanged() {
        let s = UavState::new(Vector3::new(f64::NAN, 0.0, 0.0), Vector3::zeros());
        let n = step(
            &s,
            &Command::new(Vector2::new(1.0, 0.0), 0.0),
            &Limits::fixed_wing(),
            0.1,
        );
        assert!(n.position.x.is_nan());
    }

    /// A 45° bank at 15 m/s turns at g/15 rad/s, a radius of V²/g ≈ 22.9 m; the [CIMM] profile
    /// keeps its 0.3 rad/s.
    #[test]
    fn bank_limit_bounds_the_turn_rate() {
        let l = Limits::bank_limited(9.0, 22.0, 45f64.to_radians(), 5.0);
        assert!((l.turn_rate_at(15.0) - GRAVITY / 15.0).abs() < 1e-9);
        assert!((l.min_turn_radius(15.0) - 225.0 / GRAVITY).abs() < 1e-6);
        // Slower than g·tan φ / ω_max the structural limit of 1 rad/s governs.
        assert_eq!(l.turn_rate_at(5.0), 1.0);
        assert_eq!(Limits::fixed_wing().turn_rate_at(25.0), 0.3);
        assert_eq!(Limits::multirotor().turn_rate_at(0.0), 1.0);
        // Flying a full-left command for 10 s at 15 m/s turns by at most g/15·10 rad.
        let mut s = UavState::new(Vector3::zeros(), Vector3::new(15.0, 0.0, 0.0));
        let cmd = Command::new(Vector2::new(0.0, 15.0), 0.0);
        let mut turned = 0.0;
        for _ in 0..100 {
            let n = step(&s, &cmd, &l, 0.1);
            turned += angle_between(s.horizontal_velocity(), n.horizontal_velocity());
            s = n;
        }
        assert!(
            turned <= GRAVITY / 15.0 * 10.0 + 1e-9 && turned > 1.5,
            "{turned}"
        );
    }

    #[test]
    fn braking_height_matches_cimm() {
        assert!((Limits::fixed_wing().braking_height() - 12.5).abs() < 1e-12);
    }
}
