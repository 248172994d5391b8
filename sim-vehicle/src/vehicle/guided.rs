//! The ground station's targets, as each autopilot reads them.
//!
//! - **PX4** OFFBOARD: SET_POSITION_TARGET_LOCAL_NED, velocity or position (harrier-link's
//!   `Setpoint`); SET_POSITION_TARGET_GLOBAL_INT is not simulated (counted as rejected).
//! - **ArduCopter** GUIDED ("Copter Commands in Guided Mode", `GCS_MAVLink_Copter.cpp`):
//!   SET_POSITION_TARGET_LOCAL_NED in LOCAL_NED (from home), LOCAL_OFFSET_NED (from the vehicle),
//!   BODY_NED / BODY_OFFSET_NED (from the vehicle, rotated by its heading), and
//!   SET_POSITION_TARGET_GLOBAL_INT (latitude, longitude, altitude AMSL, above home or above
//!   terrain), each read with harrier-link's [`TargetMask`]: position, velocity, or both.
//!   Outside GUIDED they are ignored; a mask, frame or value it refuses stops the vehicle where
//!   it is ("input is not valid so stop"). Acceleration targets are not simulated (they stop it
//!   too). MAV_CMD_DO_REPOSITION flies to a point (GUIDED, or switching to it with
//!   `MAV_DO_REPOSITION_FLAGS_CHANGE_MODE`), MAV_CMD_DO_CHANGE_SPEED sets the speed position
//!   targets are flown at (WPNAV_SPEED otherwise).
//! - **ArduPlane** GUIDED ("Plane Commands in Guided Mode", `GCS_MAVLink_Plane.cpp`,
//!   `mode_guided.cpp`): it loiters around the guided point at WP_LOITER_RAD, or at the radius
//!   and in the direction of a MAV_CMD_DO_REPOSITION (param3 radius, param4 non-zero: counter-
//!   clockwise); MAV_CMD_GUIDED_CHANGE_HEADING makes it fly a course instead (its bank limited to
//!   `atan(param3 / g)`), `_SPEED` an airspeed within AIRSPEED_MIN…AIRSPEED_MAX, `_ALTITUDE` an
//!   altitude, each refused (FAILED) outside GUIDED. Of SET_POSITION_TARGET_GLOBAL_INT it reads
//!   only the altitude, of SET_POSITION_TARGET_LOCAL_NED only an altitude offset in
//!   LOCAL_OFFSET_NED.

use harrier_link::ardupilot::TargetMask;
use harrier_link::autopilot::{Autopilot, Mode};
use harrier_link::command::Setpoint;
use harrier_link::geo::{Geodetic, ned_to_enu};
use harrier_link::px4::FlightMode;
use mavlink::dialects::common::{
    MavCmd, MavDoRepositionFlags, MavFrame, MavResult, PositionTargetTypemask,
    SET_POSITION_TARGET_GLOBAL_INT_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use nalgebra::{Rotation3, Vector3};

use super::modes::Behaviour;
use super::protocol::Cmd;
use super::{Target, Vehicle};

/// Largest speed or position component ArduCopter takes (`sane_vel_or_acc_vector`: 1000).
const SANE: f64 = 1000.0;

impl Vehicle {
    fn guided(&self) -> bool {
        self.behaviour() == Behaviour::External
    }

    /// A target ArduCopter refuses: it stops where it is; counted.
    fn refuse_target(&mut self, now: f64) {
        self.counters.rejected_setpoints += 1;
        if self.is_copter() && self.guided() {
            let stop = self.stop_point();
            self.replace_target(now, Target::Position(stop));
        }
    }

    /// The ENU height of an altitude in a MAVLink global frame: AMSL, above home (home is the
    /// origin), `None` for terrain-relative (no terrain data here) and other frames. ArduPilot
    /// takes the superseded `_INT` spellings of the frames too.
    #[allow(deprecated)]
    pub(super) fn enu_height(&self, frame: MavFrame, lat: f64, lon: f64, alt: f64) -> Option<f64> {
        use MavFrame as F;
        let amsl = match frame {
            F::MAV_FRAME_GLOBAL | F::MAV_FRAME_GLOBAL_INT => alt,
            F::MAV_FRAME_GLOBAL_RELATIVE_ALT | F::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT => {
                self.config.origin.alt_m + alt
            }
            _ => return None,
        };
        Some(self.frame.to_enu(&Geodetic::new(lat, lon, amsl)).z)
    }

    /// SET_POSITION_TARGET_LOCAL_NED (see the module documentation). ArduCopter still reads the
    /// superseded BODY_NED and BODY_OFFSET_NED frames.
    #[allow(deprecated)]
    pub(super) fn local_target(&mut self, now: f64, s: &SET_POSITION_TARGET_LOCAL_NED_DATA) {
        if self.personality.autopilot == Autopilot::Px4 {
            match Setpoint::from_message(s) {
                Some(Setpoint::Velocity(v)) => self.take_target(now, Target::Velocity(v)),
                Some(Setpoint::Position(p)) => self.take_target(now, Target::Position(p)),
                None => self.counters.rejected_setpoints += 1,
            }
            return;
        }
        if !self.guided() {
            self.counters.rejected_setpoints += 1;
            return;
        }
        if self.is_plane() {
            let z_ignored = s
                .type_mask
                .contains(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE);
            if s.coordinate_frame == MavFrame::MAV_FRAME_LOCAL_OFFSET_NED
                && !z_ignored
                && s.z.is_finite()
            {
                self.hold_point.z -= f64::from(s.z);
            } else {
                self.counters.rejected_setpoints += 1;
            }
            return;
        }
        use MavFrame as F;
        let (offset, body) = match s.coordinate_frame {
            F::MAV_FRAME_LOCAL_NED => (false, false),
            F::MAV_FRAME_LOCAL_OFFSET_NED => (true, false),
            F::MAV_FRAME_BODY_NED | F::MAV_FRAME_BODY_OFFSET_NED => (true, true),
            _ => return self.refuse_target(now),
        };
        let Some(mask) = TargetMask::of(s.type_mask) else {
            return self.refuse_target(now);
        };
        // Heading rotation of a body frame: NED yaw about down is ENU −yaw about up.
        let rot =
            Rotation3::from_axis_angle(&Vector3::z_axis(), if body { -self.yaw } else { 0.0 });
        let ned = |x: f32, y: f32, z: f32| {
            ned_to_enu(&Vector3::new(f64::from(x), f64::from(y), f64::from(z)))
        };
        let mut pos = rot * ned(s.x, s.y, s.z);
        if offset {
            pos += self.state.position;
        }
        let vel = rot * ned(s.vx, s.vy, s.vz);
        self.guided_target(now, mask, pos, vel);
    }

    /// SET_POSITION_TARGET_GLOBAL_INT (see the module documentation).
    pub(super) fn global_target(&mut self, now: f64, s: &SET_POSITION_TARGET_GLOBAL_INT_DATA) {
        if self.personality.autopilot == Autopilot::Px4 || !self.guided() {
            self.counters.rejected_setpoints += 1;
            return;
        }
        let (lat, lon) = (f64::from(s.lat_int) * 1e-7, f64::from(s.lon_int) * 1e-7);
        if self.is_plane() {
            let z_ignored = s
                .type_mask
                .contains(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE);
            // Only the altitude, over where the plane is.
            let here = self.position();
            let height = self.enu_height(
                s.coordinate_frame,
                here.lat_deg,
                here.lon_deg,
                f64::from(s.alt),
            );
            match height {
                Some(z) if !z_ignored && z.is_finite() => self.hold_point.z = z,
                _ => self.counters.rejected_setpoints += 1,
            }
            return;
        }
        let height = self.enu_height(s.coordinate_frame, lat, lon, f64::from(s.alt));
        let Some(mask) = TargetMask::of(s.type_mask) else {
            return self.refuse_target(now);
        };
        let position_used = matches!(mask, TargetMask::Position | TargetMask::PositionVelocity);
        let pos = if position_used {
            let latlon_ok = lat.abs() <= 90.0 && lon.abs() <= 180.0;
            match height {
                Some(z) if latlon_ok => {
                    let mut p = self.frame.to_enu(&Geodetic::new(lat, lon, 0.0));
                    p.z = z;
                    p
                }
                _ => return self.refuse_target(now),
            }
        } else {
            Vector3::zeros()
        };
        let vel = ned_to_enu(&Vector3::new(
            f64::from(s.vx),
            f64::from(s.vy),
            f64::from(s.vz),
        ));
        self.guided_target(now, mask, pos, vel);
    }

    /// An ArduCopter target read with its mask: position, velocity, or both; refused when a
    /// used part is not finite or beyond 1000, or an acceleration alone (not simulated).
    fn guided_target(&mut self, now: f64, mask: TargetMask, pos: Vector3<f64>, vel: Vector3<f64>) {
        let sane = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite() && x.abs() <= SANE);
        let target = match mask {
            TargetMask::Position if pos.iter().all(|x| x.is_finite()) => Target::Position(pos),
            TargetMask::Velocity if sane(&vel) => Target::Velocity(vel),
            TargetMask::PositionVelocity if pos.iter().all(|x| x.is_finite()) && sane(&vel) => {
                Target::PositionVelocity(pos, vel)
            }
            _ => return self.refuse_target(now),
        };
        self.replace_target(now, target);
    }

    /// An ArduCopter's new GUIDED target; it ends a takeoff still climbing (`set_destination`
    /// and `set_velaccel` change the guided submode).
    fn replace_target(&mut self, now: f64, target: Target) {
        self.taking_off = false;
        self.take_target(now, target);
    }

    /// MAV_CMD_DO_REPOSITION: a point (x, y degrees; z in the command's frame, a COMMAND_LONG's
    /// above home; NaN: the current altitude) to fly to (Copter) or loiter around (Plane, with
    /// param3's radius and param4's direction), in GUIDED or switching to it when param2 asks.
    pub(super) fn reposition(&mut self, now: f64, c: &Cmd) -> MavResult {
        let change = c.p[1].is_finite()
            && (c.p[1] as u32)
                & u32::from(MavDoRepositionFlags::MAV_DO_REPOSITION_FLAGS_CHANGE_MODE.bits())
                != 0;
        if !(self.guided() || change) {
            return MavResult::MAV_RESULT_DENIED;
        }
        if !(c.x.abs() <= 90.0 && c.y.abs() <= 180.0 && (c.x, c.y) != (0.0, 0.0)) {
            return MavResult::MAV_RESULT_DENIED;
        }
        let frame = c.frame.unwrap_or(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
        let z = if c.z.is_finite() {
            match self.enu_height(frame, c.x, c.y, f64::from(c.z)) {
                Some(z) => z,
                None => return MavResult::MAV_RESULT_DENIED,
            }
        } else {
            self.state.position.z
        };
        let mut point = self.frame.to_enu(&Geodetic::new(c.x, c.y, 0.0));
        point.z = z;
        if !self.guided() {
            self.set_mode(now, self.personality.guided());
        }
        if self.is_plane() {
            self.hold_point = point;
            self.plane.course = None;
            if c.p[2].is_finite() && c.p[2] > 0.0 {
                self.plane.radius = f64::from(c.p[2]);
                self.plane.ccw = c.p[3].is_finite() && c.p[3] != 0.0;
            }
        } else {
            self.replace_target(now, Target::Position(point));
        }
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// PX4's MAV_CMD_DO_REPOSITION (MAVSDK's goto_location): with the change-mode flag
    /// (param2 bit 0) it switches to AUTO.LOITER (Hold), which flies to the point — x, y
    /// degrees (unset: where it is), z AMSL in a COMMAND_LONG or the COMMAND_INT's frame (NaN:
    /// its altitude) — at param1 m/s (≤ 0: MPC_XY_CRUISE) and holds there (a fixed wing circles
    /// it). Without the flag only a vehicle in Hold takes the point. In the air only (DENIED).
    pub(super) fn px4_reposition(&mut self, now: f64, c: &Cmd) -> MavResult {
        let change = c.p[1].is_finite()
            && (c.p[1] as u32)
                & u32::from(MavDoRepositionFlags::MAV_DO_REPOSITION_FLAGS_CHANGE_MODE.bits())
                != 0;
        if !self.armed || self.on_ground() {
            return MavResult::MAV_RESULT_DENIED;
        }
        let hold = Mode::Px4(FlightMode::Hold);
        let in_hold = self.mode == hold;
        if !(change || in_hold) {
            // PX4 accepts it and flies it only once in Hold; nothing changes here.
            return MavResult::MAV_RESULT_ACCEPTED;
        }
        let frame = Cmd {
            frame: Some(c.frame.unwrap_or(MavFrame::MAV_FRAME_GLOBAL)),
            ..*c
        };
        let Some(point) = self.command_point(&frame) else {
            return MavResult::MAV_RESULT_DENIED;
        };
        if !in_hold {
            self.set_mode(now, hold);
        }
        self.hold_point = point;
        self.reposition = Some(if c.p[0].is_finite() && c.p[0] > 0.0 {
            f64::from(c.p[0])
        } else {
            self.param_f64("MPC_XY_CRUISE", 5.0)
        });
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// MAV_CMD_DO_CHANGE_SPEED (param2 m/s): ArduCopter's speed to position targets; ArduPlane's
    /// airspeed in GUIDED (FAILED elsewhere or outside AIRSPEED_MIN…AIRSPEED_MAX).
    pub(super) fn change_speed(&mut self, c: &Cmd) -> MavResult {
        let speed = f64::from(c.p[1]);
        if !(speed.is_finite() && speed > 0.0) {
            return MavResult::MAV_RESULT_DENIED;
        }
        if self.is_plane() {
            return self.plane_airspeed(speed);
        }
        self.guided_speed = Some(speed);
        MavResult::MAV_RESULT_ACCEPTED
    }

    fn plane_airspeed(&mut self, speed: f64) -> MavResult {
        let l = self.limits();
        if !self.guided() || speed < l.v_min || speed > l.v_max {
            return MavResult::MAV_RESULT_FAILED;
        }
        self.plane.airspeed = Some(speed);
        MavResult::MAV_RESULT_ACCEPTED
    }

    /// ArduPlane's MAV_CMD_GUIDED_CHANGE_HEADING / _SPEED / _ALTITUDE (only in GUIDED).
    pub(super) fn plane_guided_command(&mut self, c: &Cmd) -> MavResult {
        if !self.guided() {
            return MavResult::MAV_RESULT_FAILED;
        }
        match c.command {
            MavCmd::MAV_CMD_GUIDED_CHANGE_HEADING => {
                let kind = c.p[0];
                if kind == 2.0 {
                    // HEADING_TYPE_DEFAULT: back to the guided loiter.
                    self.plane.course = None;
                    return MavResult::MAV_RESULT_ACCEPTED;
                }
                if !(kind == 0.0 || kind == 1.0) || !(0.0..360.0).contains(&c.p[1]) {
                    return MavResult::MAV_RESULT_DENIED;
                }
                // No wind: course over ground and heading are one.
                let accel = if c.p[2].is_finite() {
                    f64::from(c.p[2]).max(0.05)
                } else {
                    0.05
                };
                self.plane.course = Some((f64::from(c.p[1]).to_radians(), accel));
                MavResult::MAV_RESULT_ACCEPTED
            }
            MavCmd::MAV_CMD_GUIDED_CHANGE_SPEED => {
                if c.p[0] != 0.0 {
                    // Only SPEED_TYPE_AIRSPEED.
                    return MavResult::MAV_RESULT_DENIED;
                }
                let speed = f64::from(c.p[1]);
                if !speed.is_finite() {
                    return MavResult::MAV_RESULT_DENIED;
                }
                self.plane_airspeed(speed)
            }
            _ => {
                // GUIDED_CHANGE_ALTITUDE: -1 and 0 are refused.
                if !c.z.is_finite() || c.z == -1.0 || c.z == 0.0 {
                    return MavResult::MAV_RESULT_DENIED;
                }
                let frame = c.frame.unwrap_or(MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT);
                let p = self.position();
                match self.enu_height(frame, p.lat_deg, p.lon_deg, f64::from(c.z)) {
                    Some(z) => {
                        self.hold_point.z = z;
                        MavResult::MAV_RESULT_ACCEPTED
                    }
                    None => MavResult::MAV_RESULT_DENIED,
                }
            }
        }
    }
}
