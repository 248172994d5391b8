//! What each mode of each autopilot does in the simulator ([`Behaviour`]), when a mode may be
//! entered or the motors armed, and what entering one sets up.
//!
//! | behaviour | PX4 | ArduCopter | ArduPlane |
//! |---|---|---|---|
//! | `Pilot` (no RC: the sticks stay centred, it keeps station) | | STABILIZE, ACRO, ALT_HOLD, SPORT, DRIFT | MANUAL, STABILIZE, TRAINING, ACRO, FBWA, FBWB, CRUISE |
//! | `Hold` (hover; a fixed wing loiters at its loiter radius) | POSCTL, AUTO.LOITER | LOITER, POSHOLD, BRAKE | LOITER, CIRCLE |
//! | `Takeoff` | AUTO.TAKEOFF (then Hold) | — (NAV_TAKEOFF in GUIDED or LOITER) | TAKEOFF (then loiters) |
//! | `Land` (descend, disarm on touchdown) | AUTO.LAND | LAND | — (RTL) |
//! | `Rtl` | AUTO.RTL (home at RTL_RETURN_ALT, land, disarm; fixed wing: loiter at RTL_DESCEND_ALT) | RTL, SMART_RTL (home at RTL_ALT, land, disarm) | RTL (home at RTL_ALTITUDE, loiter) |
//! | `External` (the ground station's targets) | OFFBOARD | GUIDED | GUIDED |
//! | `Orbit` (a DO_ORBIT's circle) | POSCTL.ORBIT | — | — |
//! | `Follow` (the FOLLOW_TARGET messages' target) | AUTO.FOLLOW_TARGET | FOLLOW | — |
//! | `Mission` (the uploaded mission, `auto.rs`) | AUTO.MISSION | AUTO | AUTO |
//!
//! Every other mode of the tables (FLIP, the QuadPlane modes, …) is answered
//! `MAV_RESULT_UNSUPPORTED`: the simulator does not fly it. A mission mode without a mission is
//! refused (PX4 DENIED, ArduPilot FAILED).

use harrier_link::ardupilot::{CopterMode, PlaneMode};
use harrier_link::autopilot::{Autopilot, Frame, Mode};
use harrier_link::px4::FlightMode;
use mavlink::dialects::common::MavResult;
use nalgebra::Vector3;

use super::{PlaneGuided, Target, Vehicle};

/// What the vehicle does in a mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Behaviour {
    /// A pilot mode without a pilot: it keeps station (hovers, or loiters) where it was entered.
    Pilot,
    /// Holds position; a fixed wing circles the point.
    Hold,
    /// Climbs to the takeoff altitude, then holds (PX4: switches to Hold).
    Takeoff,
    /// Descends where it is and disarms on touchdown.
    Land,
    /// Returns home: a multirotor lands there, a fixed wing loiters over it.
    Rtl,
    /// Flies the ground station's targets.
    External,
    /// Circles the centre of a MAV_CMD_DO_ORBIT.
    Orbit,
    /// Follows the target of the FOLLOW_TARGET messages.
    Follow,
    /// Flies the uploaded mission (`auto.rs`).
    Mission,
}

/// The behaviour of `mode`, `None` when the simulator does not fly it.
pub(super) fn behaviour(mode: Mode) -> Option<Behaviour> {
    use Behaviour as B;
    Some(match mode {
        Mode::Px4(m) => match m {
            FlightMode::Position | FlightMode::Hold => B::Hold,
            FlightMode::Takeoff => B::Takeoff,
            FlightMode::Land => B::Land,
            FlightMode::Offboard => B::External,
            FlightMode::Orbit => B::Orbit,
            FlightMode::FollowTarget => B::Follow,
            FlightMode::Rtl => B::Rtl,
            FlightMode::Mission => B::Mission,
        },
        Mode::Copter(m) => match m {
            CopterMode::Stabilize
            | CopterMode::Acro
            | CopterMode::AltHold
            | CopterMode::Sport
            | CopterMode::Drift => B::Pilot,
            CopterMode::Loiter | CopterMode::PosHold | CopterMode::Brake => B::Hold,
            CopterMode::Guided => B::External,
            CopterMode::Rtl | CopterMode::SmartRtl => B::Rtl,
            CopterMode::Land => B::Land,
            CopterMode::Follow => B::Follow,
            CopterMode::Auto => B::Mission,
            _ => return None,
        },
        Mode::Plane(m) => match m {
            PlaneMode::Manual
            | PlaneMode::Stabilize
            | PlaneMode::Training
            | PlaneMode::Acro
            | PlaneMode::Fbwa
            | PlaneMode::Fbwb
            | PlaneMode::Cruise => B::Pilot,
            PlaneMode::Loiter | PlaneMode::Circle => B::Hold,
            PlaneMode::Takeoff => B::Takeoff,
            PlaneMode::Guided => B::External,
            PlaneMode::Rtl => B::Rtl,
            PlaneMode::Auto => B::Mission,
            _ => return None,
        },
    })
}

impl Vehicle {
    pub(super) fn is_copter(&self) -> bool {
        self.personality.autopilot == Autopilot::ArduPilot
            && self.personality.frame == Frame::Multirotor
    }

    pub(super) fn is_plane(&self) -> bool {
        self.personality.autopilot == Autopilot::ArduPilot
            && self.personality.frame == Frame::FixedWing
    }

    /// Asks for `mode` at wall time `now` (DO_SET_MODE, SET_MODE, and the ArduPilot commands
    /// that switch modes): the answer, the mode switched when accepted. PX4 refuses OFFBOARD
    /// without fresh setpoints and AUTO.TAKEOFF disarmed (DENIED); a mode the simulator does not
    /// fly is UNSUPPORTED.
    pub(super) fn request_mode(&mut self, now: f64, mode: Mode) -> MavResult {
        let Some(b) = behaviour(mode) else {
            return MavResult::MAV_RESULT_UNSUPPORTED;
        };
        match (mode, b) {
            (Mode::Px4(_), Behaviour::External) if !self.setpoints_fresh(now) => {
                MavResult::MAV_RESULT_DENIED
            }
            (Mode::Px4(_), Behaviour::Takeoff) if !self.armed => MavResult::MAV_RESULT_DENIED,
            (_, Behaviour::Mission) if !self.has_mission() => MavResult::MAV_RESULT_DENIED,
            // POSCTL.ORBIT is entered by a DO_ORBIT, not by a mode switch.
            (Mode::Px4(_), Behaviour::Orbit) if self.orbit.is_none() => {
                MavResult::MAV_RESULT_DENIED
            }
            _ => {
                self.set_mode(now, mode);
                MavResult::MAV_RESULT_ACCEPTED
            }
        }
    }

    /// Whether the motors may be armed now: on the ground, and for ArduCopter in a mode that
    /// allows it (not RTL or LAND: "Arm: Mode not armable").
    pub(super) fn may_arm(&self) -> bool {
        let mode_ok = !self.is_copter()
            || matches!(
                self.behaviour(),
                Behaviour::Pilot | Behaviour::Hold | Behaviour::External
            );
        self.on_ground() && mode_ok
    }

    /// What arming sets up: station is kept where it stands; an ArduPlane armed in TAKEOFF
    /// launches.
    pub(super) fn on_armed(&mut self, now: f64) {
        self.landed_since = Some(self.sim_time);
        self.set_mode(now, self.mode);
    }

    /// Switches to `mode` and sets up what it flies.
    pub(super) fn set_mode(&mut self, now: f64, mode: Mode) {
        let b = behaviour(mode).unwrap_or(Behaviour::Hold);
        let p = self.state.position;
        let fixed_wing = !self.limits().can_hover();
        // A takeoff climbs only in its own mode (ArduCopter's user takeoff in GUIDED or LOITER
        // ends with the mode).
        if mode != self.mode {
            self.taking_off = false;
        }
        self.reposition = None;
        match b {
            Behaviour::Pilot | Behaviour::Hold | Behaviour::Land | Behaviour::Orbit => {
                self.hold_point = if fixed_wing { p } else { self.stop_point() };
            }
            Behaviour::Follow => {
                self.hold_point = self.stop_point();
                self.follow_offset = self.followed.map(|f| p - f.position);
            }
            Behaviour::Takeoff => {
                self.hold_point = p;
                if self.armed {
                    self.start_takeoff(self.takeoff_height());
                }
            }
            Behaviour::Rtl => {
                self.hold_point = Vector3::new(0.0, 0.0, self.return_altitude());
            }
            Behaviour::Mission => {
                self.hold_point = if fixed_wing { p } else { self.stop_point() };
                if mode != self.mode {
                    self.enter_mission();
                }
            }
            Behaviour::External => {
                if self.is_copter() && mode != self.mode {
                    // ModeGuided::init: hold where a brake stops it.
                    self.target = Some(Target::Position(self.stop_point()));
                    self.last_target = Some(now);
                    self.guided_speed = None;
                }
                if self.is_plane() {
                    // ModeGuided::_enter: loiter around the current location at WP_LOITER_RAD.
                    self.hold_point = p;
                    self.plane = PlaneGuided::NONE;
                }
            }
        }
        self.mode = mode;
    }

    /// The altitude RTL flies home at (m above home): ArduPlane RTL_ALTITUDE (the 4.5 name of
    /// ALT_HOLD_RTL, in metres); ArduCopter RTL_ALT (cm) and PX4 RTL_RETURN_ALT, each climbed to
    /// first only if lower than where the vehicle is (a PX4 fixed wing likewise).
    pub(super) fn return_altitude(&self) -> f64 {
        let z = self.state.position.z;
        match self.personality.autopilot {
            Autopilot::ArduPilot if self.is_plane() => self.param_f64("RTL_ALTITUDE", 100.0),
            Autopilot::ArduPilot => (self.param_f64("RTL_ALT", 1500.0) * 0.01).max(z),
            Autopilot::Px4 => self.param_f64("RTL_RETURN_ALT", 60.0).max(z),
        }
    }

    /// Where a maximum deceleration stops a multirotor (PX4 and ArduCopter brake before
    /// holding), at the current height.
    pub(super) fn stop_point(&self) -> Vector3<f64> {
        let limits = self.limits();
        let mut point = self.state.position;
        if limits.can_hover() {
            let vh = self.state.horizontal_velocity();
            let d = vh * (vh.norm() / (2.0 * limits.accel_max.max(1e-9)));
            point.x += d.x;
            point.y += d.y;
        }
        point
    }

    /// The height a takeoff mode climbs to: ArduPlane TKOFF_ALT, PX4 MIS_TAKEOFF_ALT.
    fn takeoff_height(&self) -> f64 {
        if self.is_plane() {
            self.param_f64("TKOFF_ALT", 50.0)
        } else {
            self.param_f64("MIS_TAKEOFF_ALT", 2.5)
        }
    }

    /// Starts a climb to `height` m: a multirotor lifts off vertically; a fixed wing is launched
    /// (a catapult: at its cruise airspeed along its heading, climbing).
    pub(super) fn start_takeoff(&mut self, height: f64) {
        self.takeoff_alt = height;
        self.taking_off = true;
        self.hold_point.x = self.state.position.x;
        self.hold_point.y = self.state.position.y;
        if !self.limits().can_hover() && self.on_ground() {
            let v = self.cruise_speed();
            let (s, c) = self.yaw.sin_cos();
            self.state.velocity = Vector3::new(v * s, v * c, 0.0);
        }
    }

    /// A fixed wing's cruise airspeed (m/s): ArduPlane AIRSPEED_CRUISE, PX4 FW_AIRSPD_TRIM.
    pub(super) fn cruise_speed(&self) -> f64 {
        if self.is_plane() {
            self.param_f64("AIRSPEED_CRUISE", 15.0)
        } else {
            self.param_f64("FW_AIRSPD_TRIM", 15.0)
        }
    }

    /// A fixed wing's loiter radius (m): ArduPlane WP_LOITER_RAD, PX4 NAV_LOITER_RAD; in
    /// ArduPlane's GUIDED the radius of the last DO_REPOSITION when it gave one.
    pub(super) fn loiter_radius(&self) -> f64 {
        if self.is_plane() {
            if self.behaviour() == Behaviour::External && self.plane.radius > 0.0 {
                return self.plane.radius;
            }
            self.param_f64("WP_LOITER_RAD", 60.0).abs()
        } else {
            self.param_f64("NAV_LOITER_RAD", 80.0).abs()
        }
    }

    /// Whether a fixed wing loiters counter-clockwise: ArduPlane by the sign of WP_LOITER_RAD
    /// (negative: counter-clockwise) or, in GUIDED, its DO_REPOSITION; PX4 clockwise.
    pub(super) fn loiter_ccw(&self) -> bool {
        if self.is_plane() {
            if self.behaviour() == Behaviour::External && self.plane.radius > 0.0 {
                return self.plane.ccw;
            }
            return self.param_f64("WP_LOITER_RAD", 60.0) < 0.0;
        }
        false
    }
}
