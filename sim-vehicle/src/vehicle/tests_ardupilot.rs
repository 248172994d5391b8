//! Unit tests of the ArduPilot personalities (ArduCopter, ArduPlane) and of the fixed-wing
//! physics: modes, guided takeoff, GUIDED targets and their type masks, ArduPlane's guided
//! commands, loiter, parameters and data streams.

// SET_MODE, REQUEST_DATA_STREAM and the BODY_NED frame are superseded, and ArduPilot still
// takes them from the clients that send them.
#![allow(deprecated)]

use super::*;
use harrier_core::guidance::kinematics::GRAVITY;
use harrier_link::command::{
    command_int, command_long, guided_altitude, guided_heading, guided_speed, set_mode,
};
use mavlink::MessageData;
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MISSION_REQUEST_LIST_DATA, MavAutopilot, MavCmd, MavDataStream, MavFrame,
    MavMessage, MavModeFlag, MavParamType, MavResult, MavState, MavType, PARAM_REQUEST_READ_DATA,
    PositionTargetTypemask, REQUEST_DATA_STREAM_DATA, SET_MODE_DATA,
    SET_POSITION_TARGET_GLOBAL_INT_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA, VFR_HUD_DATA,
};

const COPTER: Personality = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
const PLANE: Personality = Personality::new(Autopilot::ArduPilot, Frame::FixedWing);

fn vehicle(p: Personality) -> Vehicle {
    Vehicle::new(VehicleConfig::new(1).with_personality(p), 0.0)
}

/// The result of the COMMAND_ACK a command was answered with (shared with `tests_handoff`).
pub(super) fn ack_of(replies: &[MavMessage]) -> MavResult {
    match replies.first() {
        Some(MavMessage::COMMAND_ACK(a)) => a.result,
        other => panic!("no COMMAND_ACK: {other:?}"),
    }
}

fn arm(v: &mut Vehicle, t: f64) -> MavResult {
    ack_of(&v.handle(t, &harrier_link::command::arm(1)))
}

fn mode(v: &mut Vehicle, t: f64, m: Mode) -> MavResult {
    ack_of(&v.handle(t, &set_mode(1, m)))
}

fn takeoff(v: &mut Vehicle, t: f64, height: f32) -> MavResult {
    ack_of(&v.handle(t, &harrier_link::command::takeoff_relative(1, height)))
}

/// Advances `v` from `from` to `to` in 50 ms steps, calling `each` after every step (shared with
/// `tests_handoff`).
pub(super) fn run(v: &mut Vehicle, from: f64, to: f64, mut each: impl FnMut(&mut Vehicle, f64)) {
    let mut t = from;
    while t < to {
        t += 0.05;
        v.advance(t);
        each(v, t);
    }
}

fn velocity_target(frame: MavFrame, mask: u16, ned: [f32; 3]) -> MavMessage {
    MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
        vx: ned[0],
        vy: ned[1],
        vz: ned[2],
        type_mask: PositionTargetTypemask::from_bits_truncate(mask),
        target_system: 1,
        target_component: 1,
        coordinate_frame: frame,
        ..SET_POSITION_TARGET_LOCAL_NED_DATA::DEFAULT
    })
}

fn heartbeat(v: &Vehicle) -> mavlink::dialects::common::HEARTBEAT_DATA {
    match v.message(HEARTBEAT_DATA::ID) {
        Some(MavMessage::HEARTBEAT(hb)) => hb,
        other => panic!("{other:?}"),
    }
}

/// A Copter in GUIDED, up at `height` m.
fn copter_up(height: f32) -> Vehicle {
    let mut v = vehicle(COPTER);
    assert_eq!(
        mode(&mut v, 0.0, Mode::Copter(CopterMode::Guided)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(arm(&mut v, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(takeoff(&mut v, 0.0, height), MavResult::MAV_RESULT_ACCEPTED);
    run(&mut v, 0.0, f64::from(height) / 2.0 + 5.0, |_, _| {});
    v
}

/// ArduCopter announces itself, boots in STABILIZE, takes off in GUIDED to a height above home
/// and holds there.
#[test]
fn copter_takes_off_in_guided_to_a_relative_height() {
    let mut v = vehicle(COPTER);
    let hb = heartbeat(&v);
    assert_eq!(hb.autopilot, MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA);
    assert_eq!(hb.mavtype, MavType::MAV_TYPE_QUADROTOR);
    assert_eq!(hb.custom_mode, 0, "STABILIZE");
    assert!(
        hb.base_mode
            .contains(MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED)
    );
    assert_eq!(hb.system_status, MavState::MAV_STATE_STANDBY);
    // Takeoff needs the motors armed, and a mode with a user takeoff (not STABILIZE).
    assert_eq!(takeoff(&mut v, 0.0, 10.0), MavResult::MAV_RESULT_FAILED);
    assert_eq!(arm(&mut v, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(takeoff(&mut v, 0.0, 10.0), MavResult::MAV_RESULT_FAILED);
    // SET_MODE (the message) is answered with a DO_SET_MODE acknowledgement.
    let r = v.handle(
        0.1,
        &MavMessage::SET_MODE(SET_MODE_DATA {
            custom_mode: 4,
            target_system: 1,
            base_mode: MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
        }),
    );
    let Some(MavMessage::COMMAND_ACK(a)) = r.first() else {
        panic!("{r:?}")
    };
    assert_eq!(
        (a.command, a.result),
        (MavCmd::MAV_CMD_DO_SET_MODE, MavResult::MAV_RESULT_ACCEPTED)
    );
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Guided));
    // A COMMAND_INT takeoff in another frame is refused as bad parameters.
    let int = command_int(
        1,
        MavCmd::MAV_CMD_NAV_TAKEOFF,
        MavFrame::MAV_FRAME_GLOBAL,
        [0.0; 4],
        (0, 0, 10.0),
    );
    assert_eq!(ack_of(&v.handle(0.1, &int)), MavResult::MAV_RESULT_DENIED);
    assert_eq!(takeoff(&mut v, 0.1, 10.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_TAKEOFF);
    run(&mut v, 0.1, 12.0, |_, _| {});
    let s = v.state();
    assert!(
        (s.position.z - 10.0).abs() < 0.2 && s.horizontal_position().norm() < 0.1,
        "{s:?}"
    );
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Guided));
    assert_eq!(heartbeat(&v).system_status, MavState::MAV_STATE_ACTIVE);
    // A second takeoff in the air is refused.
    assert_eq!(takeoff(&mut v, 12.0, 20.0), MavResult::MAV_RESULT_FAILED);
}

/// Velocity targets fly only in GUIDED, stop GUID_TIMEOUT s after the last one; a mask with a
/// partly given group, or an unknown frame, stops the vehicle; body frames turn with it.
#[test]
fn copter_guided_targets_follow_ardupilots_rules() {
    let mut v = copter_up(10.0);
    let t0 = 10.0;
    // 4 m/s north in LOCAL_NED, for 5 s.
    let north = velocity_target(MavFrame::MAV_FRAME_LOCAL_NED, 0x0DC7, [4.0, 0.0, 0.0]);
    let p0 = v.state().position;
    run(&mut v, t0, t0 + 5.0, |v, t| {
        v.handle(t, &north);
    });
    let d = v.state().position - p0;
    assert!(d.y > 15.0 && d.x.abs() < 0.5, "{d:?}");
    // No more targets: it keeps the velocity until GUID_TIMEOUT (3 s), then stops.
    run(&mut v, t0 + 5.0, t0 + 7.5, |_, _| {});
    assert!(v.state().velocity.norm() > 3.5, "{:?}", v.state());
    run(&mut v, t0 + 7.5, t0 + 12.0, |_, _| {});
    assert!(v.state().velocity.norm() < 0.2, "{:?}", v.state());
    assert_eq!(v.counters().rejected_setpoints, 0);
    // Only vx of the velocity group given (0x0DCF): refused; the vehicle stops.
    let partial = velocity_target(MavFrame::MAV_FRAME_LOCAL_NED, 0x0DCF, [4.0, 0.0, 0.0]);
    let east = velocity_target(MavFrame::MAV_FRAME_LOCAL_NED, 0x0DC7, [0.0, 4.0, 0.0]);
    run(&mut v, 22.0, 25.0, |v, t| {
        v.handle(t, &east);
    });
    assert!(v.state().velocity.x > 3.5);
    v.handle(25.0, &partial);
    run(&mut v, 25.0, 29.0, |_, _| {});
    assert!(v.state().velocity.norm() < 0.2, "{:?}", v.state());
    assert_eq!(v.counters().rejected_setpoints, 1);
    // BODY_NED: forward is where the nose points (east, after flying east).
    let yaw = v.yaw();
    assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 0.1, "{yaw}");
    let forward = velocity_target(MavFrame::MAV_FRAME_BODY_NED, 0x0DC7, [3.0, 0.0, 0.0]);
    run(&mut v, 29.0, 32.0, |v, t| {
        v.handle(t, &forward);
    });
    let vel = v.state().velocity;
    assert!(vel.x > 2.8 && vel.y.abs() < 0.3, "{vel:?}");
    // Outside GUIDED targets are ignored (and counted).
    assert_eq!(
        mode(&mut v, 32.0, Mode::Copter(CopterMode::Loiter)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let before = v.counters().rejected_setpoints;
    run(&mut v, 32.0, 37.0, |v, t| {
        v.handle(t, &north);
    });
    assert!(
        v.state().velocity.norm() < 0.2,
        "LOITER holds: {:?}",
        v.state()
    );
    assert!(v.counters().rejected_setpoints > before);
}

/// SET_POSITION_TARGET_GLOBAL_INT with an altitude above home, flown at WPNAV_SPEED, and the
/// same point with DO_REPOSITION from LOITER (switching to GUIDED by its flag).
#[test]
fn copter_flies_global_targets_at_wpnav_speed() {
    let mut v = copter_up(10.0);
    let goal = v.frame.from_enu(&Vector3::new(60.0, 80.0, 0.0));
    let target = MavMessage::SET_POSITION_TARGET_GLOBAL_INT(SET_POSITION_TARGET_GLOBAL_INT_DATA {
        lat_int: (goal.lat_deg * 1e7).round() as i32,
        lon_int: (goal.lon_deg * 1e7).round() as i32,
        alt: 20.0,
        type_mask: PositionTargetTypemask::from_bits_truncate(0x0DF8),
        target_system: 1,
        target_component: 1,
        coordinate_frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        ..SET_POSITION_TARGET_GLOBAL_INT_DATA::DEFAULT
    });
    v.handle(10.0, &target);
    let mut top = 0.0f64;
    run(&mut v, 10.0, 40.0, |v, _| {
        top = top.max(v.state().horizontal_velocity().norm());
    });
    let p = v.state().position;
    assert!((p - Vector3::new(60.0, 80.0, 20.0)).norm() < 0.5, "{p:?}");
    assert!(
        top <= 10.0 + 1e-6 && top > 9.0,
        "WPNAV_SPEED 1000 cm/s: {top}"
    );
    // DO_REPOSITION back home, from LOITER with the change-mode flag.
    mode(&mut v, 40.0, Mode::Copter(CopterMode::Loiter));
    let home = v.config.origin;
    let rep = |flags: f32| {
        command_int(
            1,
            MavCmd::MAV_CMD_DO_REPOSITION,
            MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            [-1.0, flags, 0.0, f32::NAN],
            (
                (home.lat_deg * 1e7).round() as i32,
                (home.lon_deg * 1e7).round() as i32,
                15.0,
            ),
        )
    };
    assert_eq!(
        ack_of(&v.handle(40.0, &rep(0.0))),
        MavResult::MAV_RESULT_DENIED
    );
    assert_eq!(
        ack_of(&v.handle(40.0, &rep(1.0))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Guided));
    run(&mut v, 40.0, 70.0, |_, _| {});
    let p = v.state().position;
    assert!((p - Vector3::new(0.0, 0.0, 15.0)).norm() < 0.5, "{p:?}");
}

/// LAND lands and disarms (staying in LAND); RTL and LAND refuse arming; an armed Copter left on
/// the ground disarms after DISARM_DELAY.
#[test]
fn copter_lands_disarms_and_refuses_to_arm_in_rtl() {
    let mut v = copter_up(10.0);
    let r = v.handle(10.0, &harrier_link::command::land(1));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Land));
    run(&mut v, 10.0, 40.0, |_, _| {});
    assert!(!v.armed());
    assert_eq!(v.state().position.z, 0.0);
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Land));
    assert_eq!(arm(&mut v, 40.0), MavResult::MAV_RESULT_FAILED);
    assert_eq!(
        mode(&mut v, 40.0, Mode::Copter(CopterMode::Rtl)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(arm(&mut v, 40.0), MavResult::MAV_RESULT_FAILED);
    // AUTO without a mission.
    assert_eq!(
        mode(&mut v, 40.0, Mode::Copter(CopterMode::Auto)),
        MavResult::MAV_RESULT_FAILED
    );
    assert_eq!(
        mode(&mut v, 40.0, Mode::Copter(CopterMode::Loiter)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(arm(&mut v, 40.0), MavResult::MAV_RESULT_ACCEPTED);
    run(&mut v, 40.0, 49.0, |_, _| {});
    assert!(v.armed());
    run(&mut v, 49.0, 51.0, |_, _| {});
    assert!(!v.armed(), "DISARM_DELAY 10 s");
}

/// RTL climbs to RTL_ALT, flies home and lands.
#[test]
fn copter_returns_home_and_lands() {
    let mut v = copter_up(5.0);
    let east = velocity_target(MavFrame::MAV_FRAME_LOCAL_NED, 0x0DC7, [0.0, 5.0, 0.0]);
    run(&mut v, 10.0, 20.0, |v, t| {
        v.handle(t, &east);
    });
    assert!(v.state().position.x > 40.0);
    let r = v.handle(
        20.0,
        &command_long(1, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]),
    );
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let mut top = 0.0f64;
    run(&mut v, 20.0, 80.0, |v, _| {
        top = top.max(v.state().position.z)
    });
    assert!(top > 14.5, "climbed to RTL_ALT 15 m: {top}");
    assert!(
        !v.armed() && v.state().position.norm() < 1.0,
        "{:?}",
        v.state()
    );
}

/// ArduPlane: boots in MANUAL, refuses NAV_TAKEOFF, takes off in TAKEOFF mode to TKOFF_ALT along
/// its heading and then loiters, never below AIRSPEED_MIN.
#[test]
fn plane_takes_off_in_takeoff_mode_and_loiters() {
    let mut v = vehicle(PLANE);
    let hb = heartbeat(&v);
    assert_eq!(
        (hb.mavtype, hb.custom_mode),
        (MavType::MAV_TYPE_FIXED_WING, 0)
    );
    assert_eq!(v.mode(), Mode::Plane(PlaneMode::Manual));
    assert_eq!(arm(&mut v, 0.0), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(takeoff(&mut v, 0.0, 30.0), MavResult::MAV_RESULT_FAILED);
    assert_eq!(
        mode(&mut v, 0.0, Mode::Plane(PlaneMode::Takeoff)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_TAKEOFF);
    let stall = v.stall_speed().expect("a fixed wing");
    assert_eq!(stall, 9.0);
    let mut slowest = f64::INFINITY;
    run(&mut v, 0.0, 120.0, |v, _| {
        slowest = slowest.min(v.state().horizontal_velocity().norm());
    });
    assert!(slowest >= stall, "{slowest}");
    let s = v.state();
    assert!((s.position.z - 50.0).abs() < 2.0, "TKOFF_ALT 50 m: {s:?}");
    assert_eq!(v.mode(), Mode::Plane(PlaneMode::Takeoff));
    assert_eq!(v.landed_state(), MavLandedState::MAV_LANDED_STATE_IN_AIR);
    // Loitering: the distance to the centre settles at WP_LOITER_RAD (60 m).
    let centre = v.hold_point;
    let mut r = Vec::new();
    run(&mut v, 120.0, 180.0, |v, _| {
        r.push((v.state().horizontal_position() - centre.xy()).norm());
    });
    let (lo, hi) = r
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(lo > 55.0 && hi < 65.0, "loiter radius {lo}..{hi}");
}

/// ArduPlane in GUIDED: course, airspeed and altitude by the guided commands (refused outside
/// GUIDED or out of range), a bank-limited turn, DO_REPOSITION's radius and direction; of
/// SET_POSITION_TARGET_GLOBAL_INT only the altitude.
#[test]
fn plane_guided_commands_steer_it() {
    let mut v = vehicle(PLANE);
    arm(&mut v, 0.0);
    mode(&mut v, 0.0, Mode::Plane(PlaneMode::Takeoff));
    run(&mut v, 0.0, 60.0, |_, _| {});
    // Outside GUIDED the guided commands fail.
    let r = v.handle(60.0, &guided_heading(1, 90.0, 9.81));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_FAILED);
    assert_eq!(
        mode(&mut v, 60.0, Mode::Plane(PlaneMode::Guided)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    for (m, want) in [
        (guided_heading(1, 90.0, 2.0), MavResult::MAV_RESULT_ACCEPTED),
        (guided_heading(1, 400.0, 2.0), MavResult::MAV_RESULT_DENIED),
        (guided_speed(1, 20.0), MavResult::MAV_RESULT_ACCEPTED),
        (guided_speed(1, 30.0), MavResult::MAV_RESULT_FAILED),
        (
            guided_altitude(1, (488.0 + 80.0) as f32, 0.0),
            MavResult::MAV_RESULT_ACCEPTED,
        ),
    ] {
        assert_eq!(ack_of(&v.handle(60.0, &m)), want, "{m:?}");
    }
    // A gentle turn (2 m/s² lateral: a bank of 11.5°) east takes a wide radius: V²/a = 200 m.
    let mut headings = Vec::new();
    run(&mut v, 60.0, 140.0, |v, _| {
        headings.push((v.yaw(), v.state().horizontal_velocity().norm()))
    });
    let s = v.state();
    assert!((s.horizontal_velocity().norm() - 20.0).abs() < 0.1, "{s:?}");
    assert!(
        (v.yaw() - std::f64::consts::FRAC_PI_2).abs() < 0.05,
        "{}",
        v.yaw()
    );
    assert!((s.position.z - 80.0).abs() < 1.0, "{s:?}");
    let fastest_turn = headings
        .windows(2)
        .map(|w| {
            let d = (w[1].0 - w[0].0 + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
                - std::f64::consts::PI;
            d.abs() / 0.05
        })
        .fold(0.0f64, f64::max);
    let bank = (2.0 / GRAVITY).atan();
    assert!(
        fastest_turn <= GRAVITY * bank.tan() / 15.0 + 1e-6,
        "{fastest_turn} rad/s"
    );
    // Of SET_POSITION_TARGET_GLOBAL_INT only the altitude counts.
    let here = v.position();
    let alt_only =
        MavMessage::SET_POSITION_TARGET_GLOBAL_INT(SET_POSITION_TARGET_GLOBAL_INT_DATA {
            lat_int: 0,
            lon_int: 0,
            alt: 60.0,
            type_mask: PositionTargetTypemask::from_bits_truncate(0x0DF8),
            target_system: 1,
            target_component: 1,
            coordinate_frame: MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
            ..SET_POSITION_TARGET_GLOBAL_INT_DATA::DEFAULT
        });
    v.handle(140.0, &alt_only);
    run(&mut v, 140.0, 170.0, |_, _| {});
    assert!((v.state().position.z - 60.0).abs() < 1.0);
    // DO_REPOSITION: loiter 120 m counter-clockwise around where it was at 140 s.
    let rep = command_int(
        1,
        MavCmd::MAV_CMD_DO_REPOSITION,
        MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        [-1.0, 0.0, 120.0, 1.0],
        (
            (here.lat_deg * 1e7).round() as i32,
            (here.lon_deg * 1e7).round() as i32,
            60.0,
        ),
    );
    assert_eq!(
        ack_of(&v.handle(170.0, &rep)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let centre = v.frame.to_enu(&here).xy();
    let mut r = Vec::new();
    let mut turning = Vec::new();
    run(&mut v, 170.0, 400.0, |v, t| {
        if t > 300.0 {
            let d = v.state().horizontal_position() - centre;
            r.push(d.norm());
            let vel = v.state().horizontal_velocity();
            turning.push(d.x * vel.y - d.y * vel.x);
        }
    });
    let (lo, hi) = r
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(*x), b.max(*x)));
    assert!(lo > 112.0 && hi < 128.0, "{lo}..{hi}");
    assert!(turning.iter().all(|c| *c > 0.0), "counter-clockwise");
}

/// ArduPilot's parameters (typed, C-cast), SYSID_THISMAV, REQUEST_DATA_STREAM and an empty
/// mission list.
#[test]
fn ardupilot_parameters_streams_and_mission() {
    let mut v = Vehicle::new(VehicleConfig::new(7).with_personality(COPTER), 0.0);
    let read = |v: &mut Vehicle, name: &str| match v
        .handle(
            0.0,
            &MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
                param_index: -1,
                target_system: 7,
                target_component: 1,
                param_id: name.into(),
            }),
        )
        .first()
    {
        Some(MavMessage::PARAM_VALUE(p)) => (p.param_value, p.param_type),
        other => panic!("{name}: {other:?}"),
    };
    assert_eq!(
        read(&mut v, "SYSID_THISMAV"),
        (7.0, MavParamType::MAV_PARAM_TYPE_INT16)
    );
    assert_eq!(
        read(&mut v, "WPNAV_SPEED"),
        (1000.0, MavParamType::MAV_PARAM_TYPE_REAL32)
    );
    assert_eq!(
        read(&mut v, "ARMING_CHECK").1,
        MavParamType::MAV_PARAM_TYPE_INT32
    );
    // A data stream at 2 Hz: POSITION's two messages.
    let r = v.handle(
        0.0,
        &MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
            req_message_rate: 2,
            target_system: 7,
            target_component: 1,
            req_stream_id: MavDataStream::MAV_DATA_STREAM_POSITION,
            start_stop: 1,
        }),
    );
    assert!(r.is_empty());
    assert_eq!(v.stream_interval(GLOBAL_POSITION_INT_DATA_ID), Some(0.5));
    assert_eq!(v.stream_interval(VFR_HUD_DATA::ID), Some(0.25));
    let r = v.handle(
        0.0,
        &MavMessage::MISSION_REQUEST_LIST(MISSION_REQUEST_LIST_DATA {
            target_system: 7,
            target_component: 1,
        }),
    );
    let Some(MavMessage::MISSION_COUNT(c)) = r.first() else {
        panic!("{r:?}")
    };
    assert_eq!(c.count, 1, "ArduPilot's mission always holds home");
    let plane = vehicle(PLANE);
    assert_eq!(plane.param("AIRSPEED_MIN"), Some(9.0));
    assert_eq!(plane.param("WP_LOITER_RAD"), Some(60.0));
}

const GLOBAL_POSITION_INT_DATA_ID: u32 = mavlink::dialects::common::GLOBAL_POSITION_INT_DATA::ID;
