//! MAVLink messages a ground station sends a PX4 vehicle: `COMMAND_LONG` builders (arm, disarm,
//! takeoff, land, mode switch) and offboard setpoints (`SET_POSITION_TARGET_LOCAL_NED` in
//! `MAV_FRAME_LOCAL_NED`, velocity or position, with the type masks PX4 expects), encoded and
//! decoded here so the simulator reads exactly what the ground station writes.
//!
//! Setpoints are given in ENU, Harrier's frame; the conversion to MAVLink's NED happens here
//! through [`crate::geo`].

use mavlink::dialects::common::{
    COMMAND_LONG_DATA, MavCmd, MavFrame, MavMessage, PositionTargetTypemask,
    SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use nalgebra::Vector3;

use crate::geo::{enu_to_ned, ned_to_enu};
use crate::px4::{COMPONENT_ID, FlightMode};

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

/// Land where the vehicle is.
pub fn land(target: u8) -> MavMessage {
    command_long(target, MavCmd::MAV_CMD_NAV_LAND, [f32::NAN; 7])
}

/// Switch to `mode` (`MAV_CMD_DO_SET_MODE` with the PX4 encoding).
pub fn set_mode(target: u8, mode: FlightMode) -> MavMessage {
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
    fn commands_carry_px4_parameters() {
        let MavMessage::COMMAND_LONG(c) = set_mode(2, FlightMode::Offboard) else {
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
    }
}
