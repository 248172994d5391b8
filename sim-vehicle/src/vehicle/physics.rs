//! Point-mass flight: harrier-core's guidance kinematics with the airframe's limits, what each
//! behaviour commands, ground contact, the fall-backs when the ground station's targets stop
//! (PX4: Hold after COM_OF_LOSS_T; ArduCopter: stop after GUID_TIMEOUT), and ArduCopter's
//! automatic disarm on the ground.
//!
//! A fixed wing never hovers: it keeps at least its minimum airspeed and turns no tighter than
//! its bank limit allows (`Limits::bank_limited`), and where a multirotor would hold a point
//! it circles it at its loiter radius and cruise airspeed ("In LOITER mode the plane will
//! circle around the point where you started the loiter", ArduPlane's LOITER Mode page; PX4's
//! Hold: "circles around the GPS hold position", NAV_LOITER_RAD). The circle is flown on a
//! Lyapunov guidance vector field (harrier-core's `Lgvf`), which converges onto it from
//! anywhere, as an L1 loiter controller does.

use harrier_core::guidance::kinematics::{GRAVITY, step};
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::{Command, Limits};
use harrier_link::autopilot::{Autopilot, Mode};
use harrier_link::px4::FlightMode;
use nalgebra::Vector3;

use super::modes::Behaviour;
use super::{CLIMB_SPEED, GROUND_EPS, MAX_STEP, POS_GAIN, Target, Vehicle};

/// Gain of a follow mode's position loop (1/s): soft, so that a moving goal does not make a
/// turn-rate-limited multirotor circle it.
const FOLLOW_GAIN: f64 = 0.3;

/// Gain of a fixed wing's altitude hold (1/s).
const ALT_GAIN: f64 = 0.5;

/// `x` within ±`bound` (never panics, whatever the parameters make `bound`).
fn bounded(x: f64, bound: f64) -> f64 {
    x.max(-bound).min(bound)
}

impl Vehicle {
    /// Advances the flight to wall time `now` (simulated time runs `speedup` times faster).
    pub fn advance(&mut self, now: f64) {
        let wall_dt = now - self.last_advance;
        if !wall_dt.is_finite() || wall_dt <= 0.0 {
            return;
        }
        self.last_advance = now;
        // Offboard loss: back to Hold when setpoints stop (wall time, as a client streams them).
        if self.mode == Mode::Px4(FlightMode::Offboard) && !self.setpoints_fresh(now) {
            self.target = None;
            self.set_mode(now, Mode::Px4(FlightMode::Hold));
        }
        self.guided_timeout(now);
        let mut remaining = (wall_dt * self.config.speedup).min(10.0);
        while remaining > 1e-9 {
            let dt = remaining.min(MAX_STEP);
            self.physics_step(dt);
            remaining -= dt;
        }
    }

    /// ArduCopter's GUIDED: a velocity target not renewed within GUID_TIMEOUT (3 s) is dropped
    /// and the vehicle stops ("if no updates received for 3 seconds", `ModeGuided`).
    fn guided_timeout(&mut self, now: f64) {
        let moving = matches!(
            self.target,
            Some(Target::Velocity(_) | Target::PositionVelocity(..))
        );
        if !(moving && self.personality.autopilot == Autopilot::ArduPilot) {
            return;
        }
        let timeout = self.param_f64("GUID_TIMEOUT", 3.0);
        if self.last_target.is_none_or(|t| now - t > timeout) {
            self.target = Some(Target::Position(self.stop_point()));
        }
    }

    /// A multirotor's velocity towards `target`: proportional (3-D), and never faster than it
    /// can stop within the distance left (√(2·a·d) with 80 % of its horizontal and vertical
    /// acceleration limits), so that it arrives without overshooting, as PX4's and ArduCopter's
    /// position controllers (their jerk-limited trajectories) do.
    pub(super) fn hover_at(&self, target: Vector3<f64>) -> Vector3<f64> {
        let limits = self.limits();
        let d = target - self.state.position;
        let cap = |dist: f64, accel: f64| (2.0 * 0.8 * accel * dist).sqrt();
        let dh = d.xy();
        let vh = dh * POS_GAIN;
        let vh = match vh.norm() {
            n if n > 1e-9 => vh * (n.min(cap(dh.norm(), limits.accel_max)) / n),
            _ => vh,
        };
        let vz = d.z * POS_GAIN;
        let vz = vz.signum() * vz.abs().min(cap(d.z.abs(), limits.az_max));
        Vector3::new(vh.x, vh.y, vz)
    }

    /// A fixed wing's velocity circling `centre` at its loiter radius and `speed`, holding
    /// `centre.z`.
    fn loiter(&self, centre: Vector3<f64>, speed: f64, limits: &Limits) -> Vector3<f64> {
        self.circle(
            centre,
            self.loiter_radius(),
            self.loiter_ccw(),
            speed,
            limits,
        )
    }

    /// The velocity circling `centre` at `radius` (no tighter than the turn the limits allow),
    /// counter-clockwise when `ccw`, at `speed`, holding `centre.z`.
    fn circle(
        &self,
        centre: Vector3<f64>,
        radius: f64,
        ccw: bool,
        speed: f64,
        limits: &Limits,
    ) -> Vector3<f64> {
        let radius = radius.max(limits.min_turn_radius(speed) * 1.2);
        let sense = if ccw { 1.0 } else { -1.0 };
        let d = self.state.horizontal_position() - centre.xy();
        let dir = Lgvf::new(radius, 0.0, speed).direction(d, sense);
        let vz = bounded((centre.z - self.state.position.z) * ALT_GAIN, limits.vz_max);
        Vector3::new(dir.x * speed, dir.y * speed, vz)
    }

    /// Keeps station at `point`: hovers there, or (fixed wing) circles it at cruise airspeed.
    pub(super) fn hold_command(&self, point: Vector3<f64>, limits: &Limits) -> Vector3<f64> {
        if limits.can_hover() {
            self.hover_at(point)
        } else {
            self.loiter(point, self.cruise_speed(), limits)
        }
    }

    /// The velocity the current behaviour commands, and the limits to fly it with.
    fn flight_command(&mut self, limits: &Limits) -> (Vector3<f64>, Limits) {
        let mut limits = *limits;
        if self.taking_off {
            return (self.climb_command(&limits), limits);
        }
        let cmd = match self.behaviour() {
            Behaviour::Pilot | Behaviour::Hold | Behaviour::Takeoff => match self.reposition {
                // A PX4 DO_REPOSITION: flown to at its speed.
                Some(speed) if limits.can_hover() => self.towards(self.hold_point, speed, &limits),
                _ => self.hold_command(self.hold_point, &limits),
            },
            Behaviour::Land => {
                let mut c = self.hold_command(self.hold_point, &limits);
                c.z = -self.land_speed();
                c
            }
            Behaviour::Rtl => self.rtl_command(&limits),
            Behaviour::Mission => self.mission_flight(&limits),
            Behaviour::External => self.external_command(&mut limits),
            Behaviour::Orbit => match self.orbit {
                Some(o) => self.circle(o.centre, o.radius, o.ccw, o.speed, &limits),
                None => self.hold_command(self.hold_point, &limits),
            },
            Behaviour::Follow => match self.follow_goal() {
                Some((goal, v)) if limits.can_hover() => {
                    v + (goal - self.state.position) * FOLLOW_GAIN
                }
                _ => self.hold_command(self.hold_point, &limits),
            },
        };
        (cmd, limits)
    }

    /// Landing descent rate (m/s): PX4 MPC_LAND_SPEED, ArduCopter LAND_SPEED (cm/s); a fixed
    /// wing sinks at 1 m/s on its circle.
    pub(super) fn land_speed(&self) -> f64 {
        match self.personality.autopilot {
            Autopilot::Px4 if self.limits().can_hover() => self.param_f64("MPC_LAND_SPEED", 0.7),
            Autopilot::ArduPilot if self.limits().can_hover() => {
                self.param_f64("LAND_SPEED", 50.0) * 0.01
            }
            _ => 1.0,
        }
    }

    /// The climb of a takeoff: a multirotor straight up over its takeoff point; a fixed wing
    /// along its heading at cruise airspeed.
    fn climb_command(&self, limits: &Limits) -> Vector3<f64> {
        let dz = self.takeoff_alt - self.state.position.z;
        if limits.can_hover() {
            let mut c = self.hover_at(Vector3::new(
                self.hold_point.x,
                self.hold_point.y,
                self.takeoff_alt,
            ));
            c.z = (dz * POS_GAIN * 2.0).clamp(-CLIMB_SPEED, CLIMB_SPEED);
            if self.on_ground() {
                c.x = 0.0;
                c.y = 0.0;
            }
            c
        } else {
            let v = self.cruise_speed();
            let (s, c) = self.yaw.sin_cos();
            Vector3::new(v * s, v * c, (dz * ALT_GAIN).max(0.5).min(limits.vz_max))
        }
    }

    /// RTL: a multirotor climbs to its return altitude, flies home (PX4 at MPC_XY_CRUISE,
    /// ArduCopter at WPNAV_SPEED) and lands; a fixed wing loiters over home (ArduPlane at
    /// RTL_ALTITUDE, PX4 descending to RTL_DESCEND_ALT once there).
    pub(super) fn rtl_command(&self, limits: &Limits) -> Vector3<f64> {
        let p = self.state.position;
        let px4 = self.personality.autopilot == Autopilot::Px4;
        if !limits.can_hover() {
            let mut centre = self.hold_point;
            if px4 && p.xy().norm() < self.loiter_radius() * 1.5 {
                centre.z = self.param_f64("RTL_DESCEND_ALT", 30.0);
            }
            return self.loiter(centre, self.cruise_speed(), limits);
        }
        let to_home = -p.xy();
        if to_home.norm() > 1.0 {
            if p.z < self.hold_point.z - 1.0 {
                return Vector3::new(0.0, 0.0, CLIMB_SPEED);
            }
            let speed = if px4 {
                self.param_f64("MPC_XY_CRUISE", 5.0)
            } else {
                self.param_f64("WPNAV_SPEED", 1000.0) * 0.01
            };
            let v = to_home * POS_GAIN;
            let v = if v.norm() > speed {
                v * (speed / v.norm())
            } else {
                v
            };
            return Vector3::new(v.x, v.y, (self.hold_point.z - p.z) * POS_GAIN);
        }
        let mut c = self.hover_at(Vector3::new(0.0, 0.0, p.z));
        c.z = -self.descent_speed();
        c
    }

    /// How fast a multirotor descends over home in RTL: its landing speed near the ground;
    /// higher up PX4 at MPC_Z_V_AUTO_DN (above MPC_LAND_ALT1, 10 m), ArduCopter at
    /// WPNAV_SPEED_DN (above LAND_ALT_LOW, 10 m).
    fn descent_speed(&self) -> f64 {
        let z = self.state.position.z;
        match self.personality.autopilot {
            Autopilot::Px4 if z > self.param_f64("MPC_LAND_ALT1", 10.0) => {
                self.param_f64("MPC_Z_V_AUTO_DN", 1.5)
            }
            Autopilot::ArduPilot if z > 10.0 => self.param_f64("WPNAV_SPEED_DN", 150.0) * 0.01,
            _ => self.land_speed(),
        }
    }

    /// The ground station's targets: PX4 OFFBOARD setpoints, ArduCopter GUIDED targets, or
    /// ArduPlane's guided loiter point, course, airspeed and altitude.
    fn external_command(&self, limits: &mut Limits) -> Vector3<f64> {
        let hover = limits.can_hover();
        if self.is_plane() {
            let speed = self.plane.airspeed.unwrap_or_else(|| self.cruise_speed());
            return match self.plane.course {
                Some((course, accel)) => {
                    // MAV_CMD_GUIDED_CHANGE_HEADING: bank limited to atan(a / g).
                    limits.bank_max = limits.bank_max.min((accel / GRAVITY).atan());
                    let vz = bounded(
                        (self.hold_point.z - self.state.position.z) * ALT_GAIN,
                        limits.vz_max,
                    );
                    Vector3::new(speed * course.sin(), speed * course.cos(), vz)
                }
                None => self.loiter(self.hold_point, speed, limits),
            };
        }
        if self.personality.autopilot == Autopilot::ArduPilot && self.on_ground() {
            // A landed Copter flies no target before a takeoff (its motors stay at idle).
            return Vector3::zeros();
        }
        match self.target {
            Some(Target::Velocity(v)) => v,
            Some(Target::Position(p)) if hover => self.to_position(p),
            Some(Target::Position(p)) => self.loiter(p, self.cruise_speed(), limits),
            Some(Target::PositionVelocity(p, v)) => v + self.hover_at(p),
            None => self.hold_command(self.hold_point, limits),
        }
    }

    /// A multirotor's velocity to a position target: PX4 converges at its own pace;
    /// ArduCopter flies there at WPNAV_SPEED (or a DO_CHANGE_SPEED) and WPNAV_SPEED_UP/_DN.
    fn to_position(&self, p: Vector3<f64>) -> Vector3<f64> {
        let v = self.hover_at(p);
        if self.personality.autopilot == Autopilot::Px4 {
            return v;
        }
        let speed = self
            .guided_speed
            .unwrap_or_else(|| self.param_f64("WPNAV_SPEED", 1000.0) * 0.01);
        let vh = v.xy();
        let vh = if vh.norm() > speed {
            vh * (speed / vh.norm())
        } else {
            vh
        };
        let up = self.param_f64("WPNAV_SPEED_UP", 250.0) * 0.01;
        let down = self.param_f64("WPNAV_SPEED_DN", 150.0) * 0.01;
        Vector3::new(vh.x, vh.y, v.z.max(-down).min(up))
    }

    fn physics_step(&mut self, dt: f64) {
        self.sim_time += dt;
        self.battery_step(dt);
        if !self.armed {
            self.state.velocity = Vector3::zeros();
            self.accel = Vector3::zeros();
            return;
        }
        let base = self.limits();
        let grounded = self.on_ground();
        let (cmd, mut limits) = self.flight_command(&base);
        let fixed_wing = !base.can_hover();
        if grounded && (cmd.z <= 0.0 || fixed_wing && !self.taking_off) {
            self.on_the_ground();
            return;
        }
        self.landed_since = None;
        if grounded && !fixed_wing {
            // A multirotor lifts off from standstill.
            limits.v_min = 0.0;
        }
        let prev = self.state;
        let mut next = step(&prev, &Command { velocity: cmd }, &limits, dt);
        if next.position.z < 0.0 {
            next.position.z = 0.0;
            next.velocity.z = next.velocity.z.max(0.0);
        }
        self.accel = (next.velocity - prev.velocity) / dt;
        let vh = next.horizontal_velocity();
        if vh.norm() > 0.3 {
            // NED yaw: clockwise from north.
            self.yaw = vh.x.atan2(vh.y);
        }
        self.state = next;
        if self.state.position.z > GROUND_EPS {
            let speed = vh.norm();
            self.slowest_airborne = Some(self.slowest_airborne.map_or(speed, |s| s.min(speed)));
        }
        if self.taking_off && self.state.position.z >= self.takeoff_alt - 0.1 {
            self.takeoff_done();
        }
    }

    /// Sitting on the ground: nothing moves until a climb is commanded; touchdown in Land (or a
    /// multirotor's RTL) disarms; an armed ArduCopter left there DISARM_DELAY s disarms.
    fn on_the_ground(&mut self) {
        self.state.position.z = 0.0;
        self.state.velocity = Vector3::zeros();
        self.accel = Vector3::zeros();
        let mission_landed = self.behaviour() == Behaviour::Mission && self.mission_touchdown();
        match self.behaviour() {
            _ if mission_landed => {
                // A mission's NAV_LAND or NAV_RETURN_TO_LAUNCH: disarmed, in the mission mode.
                self.armed = false;
                self.target = None;
            }
            Behaviour::Land | Behaviour::Rtl => {
                self.armed = false;
                self.target = None;
                if self.personality.autopilot == Autopilot::Px4 {
                    // PX4 disarms after landing and its navigator falls back to Hold.
                    self.set_mode(self.last_advance, Mode::Px4(FlightMode::Hold));
                }
            }
            _ if self.personality.autopilot == Autopilot::ArduPilot
                && self.limits().can_hover() =>
            {
                let since = *self.landed_since.get_or_insert(self.sim_time);
                if self.sim_time - since >= self.param_f64("DISARM_DELAY", 10.0).max(0.1) {
                    self.armed = false;
                    self.target = None;
                }
            }
            _ => {}
        }
    }

    /// The end of a takeoff's climb: PX4 switches to Hold; an ArduCopter holds where it is (in
    /// GUIDED as a position target); a fixed wing loiters around the point it reached.
    fn takeoff_done(&mut self) {
        self.taking_off = false;
        let p = Vector3::new(
            self.state.position.x,
            self.state.position.y,
            self.takeoff_alt,
        );
        self.hold_point = p;
        match self.mode {
            Mode::Px4(FlightMode::Takeoff) => {
                self.set_mode(self.last_advance, Mode::Px4(FlightMode::Hold));
            }
            Mode::Copter(_) if self.behaviour() == Behaviour::External => {
                self.target = Some(Target::Position(p));
            }
            _ => {}
        }
    }
}
