//! MAVLink messages a ground station sends a vehicle: `COMMAND_LONG` builders (arm, disarm,
//! takeoff, land, mode switch in the vehicle's own encoding), ArduPlane's guided heading, speed
//! and altitude commands (`COMMAND_INT`), and offboard setpoints (`SET_POSITION_TARGET_LOCAL_NED`
//! in `MAV_FRAME_LOCAL_NED`, velocity or position, with the type masks PX4 expects and ArduCopter
//! reads the same way), encoded and decoded here so the simulator reads exactly what the ground
//! station writes.
//!
//! Setpoints are given in ENU, Harrier's frame; the conversion to MAVLink's NED happens here
//! through [`crate::geo`].

use mavlink::dialects::common::{
    COMMAND_INT_DATA, COMMAND_LONG_DATA, HeadingType, MavCmd, MavFrame, MavMessage,
    PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA, SpeedType,
};
use nalgebra::Vector3;

use crate::autopilot::Mode;
use crate::geo::{enu_to_ned, ned_to_enu};
use crate::px4::COMPONENT_ID;

/// `param2` of a disarm that PX4 honours in the air.
pub const FORCE_DISARM: f32 = 21196.0;

/// A COMMAND_LONG to the autopilot of vehicle `target` with parameters `p`.
pub fn command_long(target: u8, command: MavCmd, p: [f32; 7]) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        param5: p[4],
        param6: p[5],
        param7: p[6],
        command,
        target_system: target,
        target_component: COMPONENT_ID,
        confirmation: 0,
    })
}

/// Arm the motors.
pub fn arm(target: u8) -> MavMessage {
    command_long(
        target,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    )
}

/// Disarm; `force` also in the air ([`FORCE_DISARM`]).
pub fn disarm(target: u8, force: bool) -> MavMessage {
    let p2 = if force { FORCE_DISARM } else { 0.0 };
    command_long(
        target,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        [0.0, p2, 0.0, 0.0, 0.0, 0.0, 0.0],
    )
}

/// Take off to `amsl_m` (altitude AMSL, PX4's param7), or to the vehicle's `MIS_TAKEOFF_ALT`
/// above home when `None`.
pub fn takeoff(target: u8, amsl_m: Option<f32>) -> MavMessage {
    let mut p = [f32::NAN; 7];
    p[6] = amsl_m.unwrap_or(f32::NAN);
    command_long(target, MavCmd::MAV_CMD_NAV_TAKEOFF, p)
}

/// Take off to `height_m` above home: ArduCopter's NAV_TAKEOFF, whose param7 is relative
/// (`GCS_MAVLINK_Copter::mav_frame_for_command_long`: `MAV_FRAME_GLOBAL_RELATIVE_ALT`); it
/// must be armed in GUIDED.
pub fn takeoff_relative(target: u8, height_m: f32) -> MavMessage {
    command_long(
        target,
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        [0.0, 0.0, 0.0, f32::NAN, 0.0, 0.0, height_m],
    )
}

/// A COMMAND_INT to the autopilot of vehicle `target`: params 1–4, then `x`, `y` (degE7 for a
/// global frame) and `z`.
pub fn command_int(
    target: u8,
    command: MavCmd,
    frame: MavFrame,
    p: [f32; 4],
    xyz: (i32, i32, f32),
) -> MavMessage {
    MavMessage::COMMAND_INT(COMMAND_INT_DATA {
        param1: p[0],
        param2: p[1],
        param3: p[2],
        param4: p[3],
        x: xyz.0,
        y: xyz.1,
        z: xyz.2,
        command,
        target_system: target,
        target_component: COMPONENT_ID,
        frame,
        current: 0,
        autocontinue: 0,
    })
}

/// ArduPlane in GUIDED: fly the course over ground `course_deg` (clockwise from north, `[0,
/// 360)`), turning with at most `accel_m_s2` of lateral acceleration (its bank limit is
/// `atan(accel / g)`, at most ROLL_LIMIT_DEG). `MAV_CMD_GUIDED_CHANGE_HEADING`,
/// `HEADING_TYPE_COURSE_OVER_GROUND` ("Plane Commands in Guided Mode").
pub fn guided_heading(target: u8, course_deg: f32, accel_m_s2: f32) -> MavMessage {
    let p1 = HeadingType::HEADING_TYPE_COURSE_OVER_GROUND as u8;
    command_int(
        target,
        MavCmd::MAV_CMD_GUIDED_CHANGE_HEADING,
        MavFrame::MAV_FRAME_GLOBAL,
        [f32::from(p1), course_deg, accel_m_s2, 0.0],
        (0, 0, 0.0),
    )
}

/// ArduPlane in GUIDED: fly at `airspeed_m_s` (refused outside AIRSPEED_MIN…AIRSPEED_MAX).
/// `MAV_CMD_GUIDED_CHANGE_SPEED`, `SPEED_TYPE_AIRSPEED`, taking effect at once.
pub fn guided_speed(target: u8, airspeed_m_s: f32) -> MavMessage {
    let p1 = SpeedType::SPEED_TYPE_AIRSPEED as u8;
    command_int(
        target,
        MavCmd::MAV_CMD_GUIDED_CHANGE_SPEED,
        MavFrame::MAV_FRAME_GLOBAL,
        [f32::from(p1), airspeed_m_s, 0.0, 0.0],
        (0, 0, 0.0),
    )
}

/// ArduPlane in GUIDED: climb or descend to `amsl_m` (altitude above mean sea level,
/// `MAV_FRAME_GLOBAL`) at `rate_m_s` (0: as fast as it can). `MAV_CMD_GUIDED_CHANGE_ALTITUDE`.
pub fn guided_altitude(target: u8, amsl_m: f32, rate_m_s: f32) -> MavMessage {
    command_int(
        target,
        MavCmd::MAV_CMD_GUIDED_CHANGE_ALTITUDE,
        MavFrame::MAV_FRAME_GLOBAL,
        [0.0, 0.0, rate_m_s, 0.0],
        (0, 0, amsl_m),
    )
}

/// Land where the vehicle is.
pub fn land(target: u8) -> MavMessage {
    command_long(target, MavCmd::MAV_CMD_NAV_LAND, [f32::NAN; 7])
}

/// Switch to `mode` (`MAV_CMD_DO_SET_MODE` in the vehicle's encoding: PX4 main and sub mode, or
/// ArduPilot's mode number).
pub fn set_mode(target: u8, mode: Mode) -> MavMessage {
    let [p1, p2, p3] = mode.set_mode_params();
    command_long(
        target,
        MavCmd::MAV_CMD_DO_SET_MODE,
        [p1, p2, p3, 0.0, 0.0, 0.0, 0.0],
    )
}

/// Position ignored (x, y, z).
const POSITION_IGNORED: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_X_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Y_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE);
/// Velocity ignored (vx, vy, vz).
const VELOCITY_IGNORED: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VX_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VY_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_VZ_IGNORE);
/// Acceleration, yaw and yaw rate ignored.
const REST_IGNORED: PositionTargetTypemask =
    PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AX_IGNORE
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AY_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_AZ_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_IGNORE)
        .union(PositionTargetTypemask::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE);

/// Type mask of a velocity setpoint: only vx, vy, vz are used (0x0DC7).
pub const VELOCITY_TYPE_MASK: PositionTargetTypemask = POSITION_IGNORED.union(REST_IGNORED);
/// Type mask of a position setpoint: only x, y, z are used (0x0DF8).
pub const POSITION_TYPE_MASK: PositionTargetTypemask = VELOCITY_IGNORED.union(REST_IGNORED);

/// An offboard setpoint in ENU (m, m/s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Setpoint {
    /// Fly this velocity.
    Velocity(Vector3<f64>),
    /// Go to and hold this position (relative to the local origin).
    Position(Vector3<f64>),
}

impl Setpoint {
    /// The SET_POSITION_TARGET_LOCAL_NED for vehicle `target`.
    pub fn to_message(&self, target: u8) -> MavMessage {
        let (type_mask, v) = match self {
            Self::Velocity(v) => (VELOCITY_TYPE_MASK, v),
            Self::Position(p) => (POSITION_TYPE_MASK, p),
        };
        let ned = enu_to_ned(v).cast::<f32>();
        let mut data = SET_POSITION_TARGET_LOCAL_NED_DATA {
            type_mask,
            target_system: target,
            target_component: COMPONENT_ID,
            coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
            ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
        };
        match self {
            Self::Velocity(_) => (data.vx, data.vy, data.vz) = (ned.x, ned.y, ned.z),
            Self::Position(_) => (data.x, data.y, data.z) = (ned.x, ned.y, ned.z),
        }
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(data)
    }

    /// The setpoint a SET_POSITION_TARGET_LOCAL_NED asks for, as PX4 reads it: a position when x,
    /// y, z are all used, else a velocity when x, y, z are all ignored and vx, vy, vz used. `None`
    /// for any other mask, a frame other than LOCAL_NED / LOCAL_OFFSET_NED, or non-finite values.
    pub fn from_message(s: &SET_POSITION_TARGET_LOCAL_NED_DATA) -> Option<Self> {
        let mask = s.type_mask;
        let local = matches!(
            s.coordinate_frame,
            MavFrame::MAV_FRAME_LOCAL_NED | MavFrame::MAV_FRAME_LOCAL_OFFSET_NED
        );
        let ned = |x: f32, y: f32, z: f32| {
            ned_to_enu(&Vector3::new(f64::from(x), f64::from(y), f64::from(z)))
        };
        let sp = if !mask.intersects(POSITION_IGNORED) {
            Self::Position(ned(s.x, s.y, s.z))
        } else if mask.contains(POSITION_IGNORED) && !mask.intersects(VELOCITY_IGNORED) {
            Self::Velocity(ned(s.vx, s.vy, s.vz))
        } else {
            return None;
        };
        let (Self::Position(v) | Self::Velocity(v)) = sp;
        (local && v.iter().all(|x| x.is_finite())).then_some(sp)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn type_masks_are_px4s() {
        assert_eq!(VELOCITY_TYPE_MASK.bits(), 0b0000_1101_1100_0111);
        assert_eq!(POSITION_TYPE_MASK.bits(), 0b0000_1101_1111_1000);
    }

    #[test]
    fn setpoints_round_trip_through_ned() {
        for sp in [
            Setpoint::Velocity(Vector3::new(1.0, 2.0, -0.5)),
            Setpoint::Position(Vector3::new(-5.0, 10.0, 8.0)),
        ] {
            let MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) = sp.to_message(3) else {
                panic!("not a setpoint");
            };
            assert_eq!((m.target_system, m.target_component), (3, COMPONENT_ID));
            assert_eq!(Setpoint::from_message(&m), Some(sp));
            // NED: north first, down positive.
            match sp {
                Setpoint::Velocity(_) => assert_eq!([m.vx, m.vy, m.vz], [2.0, 1.0, 0.5]),
                Setpoint::Position(_) => assert_eq!([m.x, m.y, m.z], [10.0, -5.0, -8.0]),
            }
        }
    }

    #[test]
    fn unusable_setpoints_decode_to_none() {
        let MavMessage::SET_POSITION_TARGET_LOCAL_NED(good) =
            Setpoint::Velocity(Vector3::new(1.0, 0.0, 0.0)).to_message(1)
        else {
            panic!("not a setpoint");
        };
        let nan = SET_POSITION_TARGET_LOCAL_NED_DATA {
            vx: f32::NAN,
            ..good
        };
        let global = SET_POSITION_TARGET_LOCAL_NED_DATA {
            coordinate_frame: MavFrame::MAV_FRAME_GLOBAL,
            ..good
        };
        let partial = SET_POSITION_TARGET_LOCAL_NED_DATA {
            type_mask: PositionTargetTypemask::POSITION_TARGET_TYPEMASK_X_IGNORE,
            ..good
        };
        for bad in [nan, global, partial] {
            assert_eq!(Setpoint::from_message(&bad), None);
        }
    }

    #[test]
    fn commands_carry_the_autopilots_parameters() {
        use crate::ardupilot::CopterMode;
        use crate::px4::FlightMode;
        let MavMessage::COMMAND_LONG(c) = set_mode(2, Mode::Px4(FlightMode::Offboard)) else {
            panic!("not a command");
        };
        assert_eq!(c.command, MavCmd::MAV_CMD_DO_SET_MODE);
        assert_eq!([c.param1, c.param2, c.param3], [1.0, 6.0, 0.0]);
        assert_eq!((c.target_system, c.target_component), (2, 1));
        let MavMessage::COMMAND_LONG(c) = takeoff(2, Some(498.0)) else {
            panic!("not a command");
        };
        assert!(c.param1.is_nan() && c.param7 == 498.0);
        let MavMessage::COMMAND_LONG(c) = disarm(2, true) else {
            panic!("not a command");
        };
        assert_eq!([c.param1, c.param2], [0.0, FORCE_DISARM]);
        let MavMessage::COMMAND_LONG(c) = set_mode(2, Mode::Copter(CopterMode::Guided)) else {
            panic!("not a command");
        };
        assert_eq!([c.param1, c.param2, c.param3], [1.0, 4.0, 0.0]);
        let MavMessage::COMMAND_LONG(c) = takeoff_relative(2, 30.0) else {
            panic!("not a command");
        };
        assert_eq!((c.command, c.param7), (MavCmd::MAV_CMD_NAV_TAKEOFF, 30.0));
        for (m, command, p1, p2, z) in [
            (
                guided_heading(2, 90.0, 3.0),
                MavCmd::MAV_CMD_GUIDED_CHANGE_HEADING,
                0.0,
                90.0,
                0.0,
            ),
            (
                guided_speed(2, 14.0),
                MavCmd::MAV_CMD_GUIDED_CHANGE_SPEED,
                0.0,
                14.0,
                0.0,
            ),
            (
                guided_altitude(2, 600.0, 2.0),
                MavCmd::MAV_CMD_GUIDED_CHANGE_ALTITUDE,
                0.0,
                0.0,
                600.0,
            ),
        ] {
            let MavMessage::COMMAND_INT(c) = m else {
                panic!("not a COMMAND_INT");
            };
            assert_eq!((c.command, c.param1, c.param2, c.z), (command, p1, p2, z));
            assert_eq!(c.frame, MavFrame::MAV_FRAME_GLOBAL);
        }
    }
}
