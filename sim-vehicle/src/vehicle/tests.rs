//! Unit tests of the PX4 vehicle: commands, modes, offboard timeout, parameters, intervals
//! (ArduPilot's in `tests_ardupilot.rs`).

use super::tables::STREAMS;
use super::*;
use harrier_link::command::command_long;
use mavlink::MessageData;
use mavlink::dialects::common::{
    AUTOPILOT_VERSION_DATA, GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA,
    LOCAL_POSITION_NED_DATA, MavCmd, MavFrame, MavMessage, MavModeFlag, MavParamType, MavResult,
    MavType, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA, PARAM_SET_DATA,
    PositionTargetTypemask, SET_POSITION_TARGET_LOCAL_NED_DATA,
};

fn cmd(command: MavCmd, p: [f32; 7]) -> MavMessage {
    command_long(1, command, p)
}

fn ack_of(replies: &[MavMessage]) -> MavResult {
    match replies.first() {
        Some(MavMessage::COMMAND_ACK(a)) => a.result,
        other => panic!("no COMMAND_ACK: {other:?}"),
    }
}

fn velocity_sp(vn: f32, ve: f32, vd: f32) -> MavMessage {
    use PositionTargetTypemask as M;
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        vx: vn,
        vy: ve,
        vz: vd,
        type_mask: M::from_bits_truncate(0b0000_1101_1100_0111),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
    })
}

const CUSTOM: f32 = 1.0; // MAV_MODE_FLAG_CUSTOM_MODE_ENABLED

fn run(v: &mut Vehicle, from: f64, to: f64) {
    let mut t = from;
    while t < to {
        t += 0.05;
        v.advance(t);
    }
}

fn airborne(airframe: Airframe) -> Vehicle {
    let mut v = Vehicle::new(
        VehicleConfig {
            airframe,
            ..VehicleConfig::new(1)
        },
        0.0,
    );
    let r = v.handle(
        0.0,
        &cmd(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [1.0, 0., 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let r = v.handle(
        0.0,
        &cmd(
            MavCmd::MAV_CMD_NAV_TAKEOFF,
            [0., 0., 0., f32::NAN, f32::NAN, f32::NAN, f32::NAN],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Takeoff));
    run(&mut v, 0.0, 10.0);
    v
}

#[test]
fn arm_takeoff_to_mis_takeoff_alt_then_hold() {
    let v = airborne(Airframe::Multirotor);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold));
    assert!((v.state().position.z - 2.5).abs() < 0.2, "{:?}", v.state());
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_IN_AIR);
}

#[test]
fn commands_are_refused_when_they_do_not_apply() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let nan = [f32::NAN; 7];
    // Takeoff and land need the motors armed.
    assert_eq!(
        ack_of(&v.handle(0.0, &cmd(MavCmd::MAV_CMD_NAV_TAKEOFF, nan))),
        MavResult::MAV_RESULT_DENIED
    );
    assert_eq!(
        ack_of(&v.handle(0.0, &cmd(MavCmd::MAV_CMD_NAV_LAND, nan))),
        MavResult::MAV_RESULT_DENIED
    );
    // Commands the simulator does not implement.
    let r = v.handle(0.0, &cmd(MavCmd::MAV_CMD_DO_FLIGHTTERMINATION, [0.0; 7]));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_UNSUPPORTED);
    // A goto needs the vehicle in the air.
    let r = v.handle(0.0, &cmd(MavCmd::MAV_CMD_DO_REPOSITION, [0.0; 7]));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    // Arm with a NaN parameter.
    let r = v.handle(0.0, &cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, nan));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    assert!(!v.armed());
    assert_eq!(v.counters().refused_commands, 5);
    // Commands for another system are ignored.
    let mut other = cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0; 7]);
    if let MavMessage::COMMAND_LONG(c) = &mut other {
        c.target_system = 9;
    }
    assert!(v.handle(0.0, &other).is_empty());
}

#[test]
fn disarm_in_flight_needs_force() {
    let mut v = airborne(Airframe::Multirotor);
    let r = v.handle(10.0, &cmd(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    assert!(v.armed());
    let r = v.handle(
        10.0,
        &cmd(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            [0.0, 21196.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert!(!v.armed());
}

#[test]
fn do_set_mode_follows_px4_modes() {
    let mut v = airborne(Airframe::Multirotor);
    let r = v.handle(
        10.0,
        &cmd(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [CUSTOM, 3.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Position));
    let hb = v.message(HEARTBEAT_DATA::ID);
    let Some(MavMessage::HEARTBEAT(hb)) = hb else {
        panic!()
    };
    assert_eq!(hb.custom_mode, 3 << 16);
    assert!(hb.base_mode.contains(
        MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED | MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
    ));
    // MISSION without a mission is refused; a mode without the custom flag is not understood.
    let r = v.handle(
        10.0,
        &cmd(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [CUSTOM, 4.0, 4.0, 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    let r = v.handle(
        10.0,
        &cmd(MavCmd::MAV_CMD_DO_SET_MODE, [0.0, 4.0, 3.0, 0., 0., 0., 0.]),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_UNSUPPORTED);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Position));
    // Land: descends, touches down, disarms.
    let r = v.handle(
        10.0,
        &cmd(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [CUSTOM, 4.0, 6.0, 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_LANDING);
    run(&mut v, 10.0, 20.0);
    assert!(!v.armed());
    assert_eq!(v.state().position.z, 0.0);
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_ON_GROUND);
}

#[test]
fn offboard_needs_setpoints_and_times_out_to_hold() {
    let mut v = airborne(Airframe::Multirotor);
    let offboard = cmd(
        MavCmd::MAV_CMD_DO_SET_MODE,
        [CUSTOM, 6.0, 0., 0., 0., 0., 0.],
    );
    assert_eq!(
        ack_of(&v.handle(10.0, &offboard)),
        MavResult::MAV_RESULT_DENIED
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold));
    // Stream 2 m/s north.
    v.handle(10.0, &velocity_sp(2.0, 0.0, 0.0));
    assert_eq!(
        ack_of(&v.handle(10.1, &offboard)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Offboard));
    let x0 = v.state().position;
    let mut t = 10.1;
    while t < 15.0 {
        t += 0.1;
        v.handle(t, &velocity_sp(2.0, 0.0, 0.0));
    }
    let d = v.state().position - x0;
    assert!(d.y > 7.0 && d.x.abs() < 0.1 && d.z.abs() < 0.1, "{d:?}"); // ENU: north is y
    // NaN setpoints are ignored and counted; they do not keep offboard alive.
    v.handle(15.2, &velocity_sp(f32::NAN, 0.0, 0.0));
    assert_eq!(v.counters().rejected_setpoints, 1);
    v.advance(15.45);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Offboard));
    v.advance(15.7);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold));
    // Hold brakes to a stop.
    let p0 = v.state().position;
    run(&mut v, 15.7, 19.7);
    assert!(v.state().velocity.norm() < 0.2, "{:?}", v.state());
    assert!((v.state().position - p0).norm() < 2.0, "{:?}", v.state());
}

#[test]
fn position_setpoints_are_flown() {
    use PositionTargetTypemask as M;
    let mut v = airborne(Airframe::Multirotor);
    let sp = MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        x: 10.0,
        y: -5.0,
        z: -8.0,
        type_mask: M::from_bits_truncate(0b0000_1101_1111_1000),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_LOCAL_NED,
        ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
    });
    v.handle(10.0, &sp);
    let r = v.handle(
        10.0,
        &cmd(
            MavCmd::MAV_CMD_DO_SET_MODE,
            [CUSTOM, 6.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let mut t = 10.0;
    while t < 30.0 {
        t += 0.1;
        v.handle(t, &sp);
    }
    let p = v.state().position;
    assert!((p - Vector3::new(-5.0, 10.0, 8.0)).norm() < 0.3, "{p:?}");
}

#[test]
fn fixed_wing_keeps_flying_in_hold() {
    let mut v = airborne(Airframe::FixedWing);
    run(&mut v, 10.0, 60.0);
    let s = v.state();
    // FW_AIRSPD_MIN, above FW_AIRSPD_STALL.
    assert!(s.horizontal_velocity().norm() >= 10.0 - 1e-9);
    assert_eq!(v.stall_speed(), Some(7.0));
    assert!(s.horizontal_position().norm() < 200.0, "{s:?}");
    assert!((s.position.z - 2.5).abs() < 1.0);
    let Some(MavMessage::HEARTBEAT(hb)) = v.message(HEARTBEAT_DATA::ID) else {
        panic!()
    };
    assert_eq!(hb.mavtype, MavType::MAV_TYPE_FIXED_WING);
}

#[test]
fn parameters_list_read_set() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let list = v.handle(
        0.0,
        &MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA {
            target_system: 1,
            target_component: 1,
        }),
    );
    // A PX4 multirotor's 19: takeoff, offboard loss, landing, RTL, battery, acceptance radius,
    // cruise and descent speeds, follow-me (6).
    assert_eq!(list.len(), 19);
    let read = |v: &mut Vehicle, name: &str| {
        v.handle(
            0.0,
            &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: -1,
                target_system: 1,
                target_component: 1,
                param_id: name.into(),
            }),
        )
    };
    let r = read(&mut v, "MIS_TAKEOFF_ALT");
    let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
        panic!("{r:?}")
    };
    assert_eq!(p.param_value, 2.5);
    assert!(read(&mut v, "NO_SUCH").is_empty());
    let set = |v: &mut Vehicle, name: &str, value: f32| {
        v.handle(
            0.0,
            &MavMessage::PARAM_SET(PARAM_SET_DATA {
                param_value: value,
                target_system: 1,
                target_component: 1,
                param_id: name.into(),
                param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
            }),
        )
    };
    let r = set(&mut v, "MIS_TAKEOFF_ALT", 5.0);
    let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
        panic!("{r:?}")
    };
    assert_eq!(p.param_value, 5.0);
    for bad in [f32::NAN, -1.0, 1e6] {
        let r = set(&mut v, "MIS_TAKEOFF_ALT", bad);
        let Some(MavMessage::PARAM_VALUE(p)) = r.first() else {
            panic!("{r:?}")
        };
        assert_eq!(p.param_value, 5.0);
    }
    assert!(set(&mut v, "NO_SUCH", 1.0).is_empty());
    assert_eq!(v.counters().rejected_params, 4);
    assert_eq!(v.param("MIS_TAKEOFF_ALT"), Some(5.0));
}

#[test]
fn message_intervals_and_requests() {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    let all = v.telemetry(0.0);
    assert_eq!(all.len(), STREAMS.len());
    let id = GLOBAL_POSITION_INT_DATA::ID as f32;
    let r = v.handle(
        0.0,
        &cmd(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [id, 50_000.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let iv = v.stream_interval(GLOBAL_POSITION_INT_DATA::ID);
    assert!(iv.is_some_and(|iv| (iv - 0.05).abs() < 1e-9), "{iv:?}");
    let r = v.handle(
        0.0,
        &cmd(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [id, -1.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.stream_interval(GLOBAL_POSITION_INT_DATA::ID), None);
    let r = v.handle(
        0.0,
        &cmd(
            MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
            [id, 0.0, 0., 0., 0., 0., 0.],
        ),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.stream_interval(GLOBAL_POSITION_INT_DATA::ID), Some(0.1));
    for bad in [[id, 10.0], [id, f32::NAN], [9999.0, 1e5], [f32::NAN, 1e5]] {
        let r = v.handle(
            0.0,
            &cmd(
                MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                [bad[0], bad[1], 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    }
    // 0.95 s of telemetry at the default rates: 10 Hz position, 1 Hz heartbeat.
    let mut count = std::collections::HashMap::<u32, usize>::new();
    let mut t = 0.0;
    while t < 0.95 {
        t += 0.01;
        for m in v.telemetry(t) {
            *count.entry(mavlink::Message::message_id(&m)).or_default() += 1;
        }
    }
    assert_eq!(count.get(&LOCAL_POSITION_NED_DATA::ID), Some(&9));
    assert_eq!(count.get(&HEARTBEAT_DATA::ID), None);
    for (msg, expect) in [
        (AUTOPILOT_VERSION_DATA::ID, true),
        (HOME_POSITION_DATA::ID, true),
        (12_345, false),
    ] {
        let r = v.handle(
            1.0,
            &cmd(
                MavCmd::MAV_CMD_REQUEST_MESSAGE,
                [msg as f32, 0., 0., 0., 0., 0., 0.],
            ),
        );
        assert_eq!(r.len(), if expect { 2 } else { 1 });
        assert_eq!(ack_of(&r) == MavResult::MAV_RESULT_ACCEPTED, expect);
    }
}

#[test]
fn telemetry_is_consistent_with_the_state() {
    let mut v = airborne(Airframe::Multirotor);
    let Some(MavMessage::GLOBAL_POSITION_INT(g)) = v.message(GLOBAL_POSITION_INT_DATA::ID) else {
        panic!()
    };
    assert!((g.relative_alt - 2500).abs() < 200);
    assert!((f64::from(g.alt) - 490_500.0).abs() < 200.0);
    let Some(MavMessage::LOCAL_POSITION_NED(l)) = v.message(LOCAL_POSITION_NED_DATA::ID) else {
        panic!()
    };
    assert!((l.z + 2.5).abs() < 0.2);
    assert!(v.handle(10.0, &velocity_sp(0.0, 0.0, 0.0)).is_empty());
}
