//! Handing a target to the autopilot instead of streaming setpoints: the messages a ground
//! station sends, and the ones the simulator reads back.
//!
//! - **Orbit** it: PX4's `MAV_CMD_DO_ORBIT` (centre, radius — positive clockwise —, tangential
//!   speed; the vehicle switches to POSCTL.ORBIT), or ArduPlane's guided loiter:
//!   `MAV_CMD_DO_REPOSITION` with the change-mode flag, param3 the loiter radius and param4
//!   non-zero for counter-clockwise (`GCS_MAVLINK_Plane::handle_command_int_do_reposition`).
//!   ArduCopter 4.x has neither (DO_ORBIT in Copter's GUIDED is still a pull request, ArduPilot
//!   #32434).
//! - **Follow** it: `FOLLOW_TARGET` with the target's position, velocity and position covariance,
//!   to a vehicle in PX4's AUTO.FOLLOW_TARGET or ArduCopter's FOLLOW.
//! - **Point a camera** at it: `MAV_CMD_DO_SET_ROI_LOCATION`, param1 the gimbal device a gimbal
//!   manager announced (GIMBAL_MANAGER_INFORMATION), or 0 for the vehicle's own mount.
//!
//! Every command here is a COMMAND_INT in `MAV_FRAME_GLOBAL` (latitude and longitude in degE7,
//! altitude AMSL).

use mavlink::dialects::common::{
    FOLLOW_TARGET_DATA, MavCmd, MavDoRepositionFlags, MavFrame, MavMessage,
};
use nalgebra::Vector3;

use crate::command::command_int;
use crate::geo::{Geodetic, enu_to_ned};

/// `FOLLOW_TARGET.est_capabilities`: position and velocity are given (bits 0 and 1).
pub const FOLLOW_POS_VEL: u8 = 0b11;

fn deg_e7(deg: f64) -> i32 {
    (deg * 1e7).round() as i32
}

/// PX4's `MAV_CMD_DO_ORBIT` around `centre` (AMSL), `radius_m` counter-clockwise when `ccw`, at
/// `speed_m_s` tangentially, facing the centre, forever.
pub fn orbit(
    target: u8,
    centre: &Geodetic,
    radius_m: f32,
    ccw: bool,
    speed_m_s: f32,
) -> MavMessage {
    let signed = if ccw { -radius_m } else { radius_m };
    command_int(
        target,
        MavCmd::MAV_CMD_DO_ORBIT,
        MavFrame::MAV_FRAME_GLOBAL,
        [signed, speed_m_s, 0.0, 0.0],
        (
            deg_e7(centre.lat_deg),
            deg_e7(centre.lon_deg),
            centre.alt_m as f32,
        ),
    )
}

/// ArduPlane's guided loiter: `MAV_CMD_DO_REPOSITION` to `centre` (AMSL), switching to GUIDED,
/// loitering `radius_m` counter-clockwise when `ccw`.
pub fn loiter_at(target: u8, centre: &Geodetic, radius_m: f32, ccw: bool) -> MavMessage {
    let change_mode = f32::from(MavDoRepositionFlags::MAV_DO_REPOSITION_FLAGS_CHANGE_MODE.bits());
    command_int(
        target,
        MavCmd::MAV_CMD_DO_REPOSITION,
        MavFrame::MAV_FRAME_GLOBAL,
        [-1.0, change_mode, radius_m, if ccw { 1.0 } else { 0.0 }],
        (
            deg_e7(centre.lat_deg),
            deg_e7(centre.lon_deg),
            centre.alt_m as f32,
        ),
    )
}

/// `MAV_CMD_DO_SET_ROI_LOCATION` at `point` (AMSL), to component `component` of vehicle `target`
/// (a gimbal manager's, or the autopilot's), for gimbal device `gimbal_device` (0: all).
pub fn roi(target: u8, component: u8, gimbal_device: u8, point: &Geodetic) -> MavMessage {
    let mut m = command_int(
        target,
        MavCmd::MAV_CMD_DO_SET_ROI_LOCATION,
        MavFrame::MAV_FRAME_GLOBAL,
        [f32::from(gimbal_device), 0.0, 0.0, 0.0],
        (
            deg_e7(point.lat_deg),
            deg_e7(point.lon_deg),
            point.alt_m as f32,
        ),
    );
    if let MavMessage::COMMAND_INT(c) = &mut m {
        c.target_component = component;
    }
    m
}

/// `FOLLOW_TARGET` at time `timestamp_ms`: the target at `position` (AMSL) moving at `velocity`
/// (ENU, m/s), with the variances of its position `cov_ned` (north, east, down; m²; the
/// message's `position_cov`).
pub fn follow_target(
    timestamp_ms: u64,
    position: &Geodetic,
    velocity: &Vector3<f64>,
    cov_ned: [f64; 3],
) -> MavMessage {
    let v = enu_to_ned(velocity).cast::<f32>();
    MavMessage::FOLLOW_TARGET(FOLLOW_TARGET_DATA {
        timestamp: timestamp_ms,
        custom_state: 0,
        lat: deg_e7(position.lat_deg),
        lon: deg_e7(position.lon_deg),
        alt: position.alt_m as f32,
        vel: [v.x, v.y, v.z],
        acc: [0.0; 3],
        attitude_q: [0.0; 4],
        rates: [0.0; 3],
        position_cov: cov_ned.map(|c| c as f32),
        est_capabilities: FOLLOW_POS_VEL,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hand_off_messages_carry_the_point_and_the_geometry() {
        let c = Geodetic::new(47.397_742, 8.545_594, 500.0);
        let MavMessage::COMMAND_INT(o) = orbit(2, &c, 60.0, true, 5.0) else {
            panic!("not a command");
        };
        assert_eq!(
            (o.command, o.param1, o.param2),
            (MavCmd::MAV_CMD_DO_ORBIT, -60.0, 5.0)
        );
        assert_eq!((o.x, o.y, o.z), (473_977_420, 85_455_940, 500.0));
        let MavMessage::COMMAND_INT(r) = loiter_at(2, &c, 80.0, false) else {
            panic!("not a command");
        };
        assert_eq!((r.param2, r.param3, r.param4), (1.0, 80.0, 0.0));
        let MavMessage::COMMAND_INT(i) = roi(2, 154, 154, &c) else {
            panic!("not a command");
        };
        assert_eq!(
            (i.command, i.target_component, i.param1),
            (MavCmd::MAV_CMD_DO_SET_ROI_LOCATION, 154, 154.0)
        );
        let MavMessage::FOLLOW_TARGET(f) =
            follow_target(7, &c, &Vector3::new(1.0, 2.0, 0.0), [4.0, 9.0, 1.0])
        else {
            panic!("not FOLLOW_TARGET");
        };
        // NED: north first.
        assert_eq!(
            (f.vel, f.position_cov, f.est_capabilities),
            ([2.0, 1.0, -0.0], [4.0, 9.0, 1.0], 3)
        );
    }
}
