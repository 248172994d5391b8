use super::*;
use crate::ardupilot::CopterMode;
use crate::px4::FlightMode;
use mavlink::dialects::common::COMMAND_ACK_DATA;

fn ack(command: MavCmd, result: MavResult) -> MavMessage {
    MavMessage::COMMAND_ACK(COMMAND_ACK_DATA { command, result })
}

fn accepted(command: MavCmd) -> MavMessage {
    ack(command, MavResult::MAV_RESULT_ACCEPTED)
}

fn commands(out: &[MavMessage]) -> Vec<MavCmd> {
    out.iter()
        .filter_map(|m| match m {
            MavMessage::COMMAND_LONG(c) => Some(c.command),
            MavMessage::COMMAND_INT(c) => Some(c.command),
            _ => None,
        })
        .collect()
}

fn setpoints(out: &[MavMessage]) -> usize {
    out.iter()
        .filter(|m| matches!(m, MavMessage::SET_POSITION_TARGET_LOCAL_NED(_)))
        .count()
}

fn px4(armed: bool, mode: FlightMode, at: f64) -> VehicleStatus {
    VehicleStatus {
        armed,
        personality: Personality::PX4_MULTIROTOR,
        mode: Some(Mode::Px4(mode)),
        at,
    }
}

const V: Option<Steer> = Some(Steer {
    velocity: Vector3::new(1.0, 2.0, 0.0),
    altitude_amsl_m: None,
});

/// Over a slow link: one command per acknowledgement, setpoints before the switch, the switch
/// asked for once; a status newer than its acknowledgement in another mode is an override.
#[test]
fn px4_launch_waits_for_each_acknowledgement() {
    use MavCmd::*;
    let config = OffboardConfig::new(Some(20.0), Some(480.0));
    let mut s = OffboardSequence::new(1, Personality::PX4_MULTIROTOR, config);
    let hold = px4(false, FlightMode::Hold, 0.0);
    let out = s.next(0.0, &hold, Some(0.0), V).expect("next");
    assert_eq!(commands(&out), [MAV_CMD_COMPONENT_ARM_DISARM]);
    assert_eq!(setpoints(&out), 0);
    // Nothing new until the acknowledgement.
    assert!(s.next(0.1, &hold, Some(0.0), V).expect("next").is_empty());
    s.handle(0.2, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    let out = s
        .next(0.2, &px4(true, FlightMode::Hold, 0.2), Some(0.0), V)
        .expect("next");
    assert_eq!(commands(&out), [MAV_CMD_NAV_TAKEOFF]);
    // PX4's param7 is AMSL: home + height.
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!(c.param7, 500.0);
    s.handle(0.3, &accepted(MAV_CMD_NAV_TAKEOFF)).expect("ack");
    assert_eq!(s.phase(), Phase::Offboard);
    let climbing = px4(true, FlightMode::Takeoff, 0.3);
    let out = s.next(0.4, &climbing, Some(1.0), V).expect("next");
    assert_eq!(commands(&out), [MAV_CMD_DO_SET_MODE]);
    assert_eq!(setpoints(&out), 1);
    // One setpoint per time, not per call.
    assert!(
        s.next(0.4, &climbing, Some(1.0), V)
            .expect("next")
            .is_empty()
    );
    s.handle(0.5, &accepted(MAV_CMD_DO_SET_MODE)).expect("ack");
    // A heartbeat from before the switch does not trigger another request…
    let out = s.next(0.6, &climbing, Some(2.0), V).expect("next");
    assert_eq!((commands(&out).len(), setpoints(&out)), (0, 1));
    // …in OFFBOARD: setpoints, no request; without a velocity, nothing.
    let offboard = px4(true, FlightMode::Offboard, 0.7);
    let out = s.next(0.8, &offboard, Some(3.0), V).expect("next");
    assert_eq!((commands(&out).len(), setpoints(&out)), (0, 1));
    assert!(
        s.next(0.85, &offboard, Some(3.0), None)
            .expect("next")
            .is_empty()
    );
    // A later one out of OFFBOARD is someone else's Hold: the sequence ends, asking for nothing.
    let held = px4(true, FlightMode::Hold, 0.9);
    assert_eq!(
        s.next(1.0, &held, Some(3.0), V),
        Err(OffboardError::Overridden(Override {
            from: Some(Mode::Px4(FlightMode::Offboard)),
            to: Some(Mode::Px4(FlightMode::Hold)),
            disarmed: false,
            at: 0.9,
        }))
    );
}

/// The launch's own modes pass; any other mode, or a disarm once armed, is an override, and so
/// is leaving the guided mode of a vehicle found flying in it.
#[test]
fn changes_the_sequence_did_not_command_are_overrides() {
    use MavCmd::*;
    let config = OffboardConfig::new(Some(20.0), Some(480.0));
    let fw = Personality::new(Autopilot::Px4, Frame::FixedWing);
    let st = |p, armed, mode, at| VehicleStatus {
        armed,
        personality: p,
        mode: Some(Mode::Px4(mode)),
        at,
    };
    // A PX4 fixed wing climbing in AUTO.TAKEOFF, then in the Hold its takeoff ends in: fine.
    let mut s = OffboardSequence::new(5, fw, config);
    s.next(0.0, &st(fw, false, FlightMode::Position, 0.0), Some(0.0), V)
        .expect("next");
    s.handle(0.1, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    s.next(0.2, &st(fw, true, FlightMode::Position, 0.2), Some(0.0), V)
        .expect("next");
    s.handle(0.3, &accepted(MAV_CMD_NAV_TAKEOFF)).expect("ack");
    for (t, mode) in [(1.0, FlightMode::Takeoff), (2.0, FlightMode::Hold)] {
        s.next(t, &st(fw, true, mode, t), Some(10.0), V)
            .expect("a launch mode");
    }
    // Then the pilot's RTL... (a mode outside the launch's): someone else's.
    let rtl = VehicleStatus {
        mode: None,
        ..st(fw, true, FlightMode::Hold, 3.0)
    };
    let e = s.next(3.0, &rtl, Some(12.0), V).expect_err("overridden");
    assert_eq!(
        e.to_string(),
        "mode changed by no command of ours: HOLD -> an unknown mode"
    );
    // A disarm once armed (a landing, or a kill switch).
    let mut s = OffboardSequence::new(5, fw, config);
    s.next(0.0, &st(fw, false, FlightMode::Hold, 0.0), Some(0.0), V)
        .expect("next");
    s.handle(0.1, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    // A status from before the acknowledgement still shows it disarmed: not judged.
    s.next(0.2, &st(fw, false, FlightMode::Hold, 0.05), Some(0.0), V)
        .expect("older than the arming");
    let e = s
        .next(0.5, &st(fw, false, FlightMode::Hold, 0.4), Some(0.0), V)
        .expect_err("disarmed");
    assert!(matches!(e, OffboardError::Overridden(o) if o.disarmed));
    // A multirotor found flying in OFFBOARD is held to it from that status on.
    let mut s = OffboardSequence::new(1, Personality::PX4_MULTIROTOR, config);
    let out = s
        .next(0.0, &px4(true, FlightMode::Offboard, 0.0), Some(30.0), V)
        .expect("next");
    assert_eq!((commands(&out).len(), setpoints(&out)), (0, 1));
    let e = s
        .next(1.0, &px4(true, FlightMode::Land, 0.5), Some(30.0), V)
        .expect_err("landed by someone");
    assert!(matches!(
        e,
        OffboardError::Overridden(Override {
            to: Some(Mode::Px4(FlightMode::Land)),
            ..
        })
    ));
}

#[test]
fn unanswered_commands_are_retried_then_given_up() {
    let mut s = OffboardSequence::new(
        4,
        Personality::PX4_MULTIROTOR,
        OffboardConfig::new(None, None),
    );
    let st = px4(false, FlightMode::Hold, 0.0);
    let first = s.next(0.0, &st, None, V).expect("next");
    let again = s.next(1.0, &st, None, V).expect("next");
    let (MavMessage::COMMAND_LONG(a), MavMessage::COMMAND_LONG(b)) = (&first[0], &again[0]) else {
        panic!("{first:?} {again:?}");
    };
    assert_eq!((a.confirmation, b.confirmation), (0, 1));
    assert_eq!(s.next(2.0, &st, None, V).expect("next").len(), 1);
    let e = s.next(3.0, &st, None, V).expect_err("gives up");
    assert_eq!(
        e,
        OffboardError::NoAck {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            attempts: 3
        }
    );
    // Without a known home PX4 takes off to its MIS_TAKEOFF_ALT: param7 NaN.
    let mut s = OffboardSequence::new(
        4,
        Personality::PX4_MULTIROTOR,
        OffboardConfig::new(Some(30.0), None),
    );
    s.next(0.0, &st, None, V).expect("next");
    s.handle(0.0, &accepted(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    let out = s.next(0.0, &st, None, V).expect("next");
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert!(c.param7.is_nan());
}

#[test]
fn refusals_stop_the_sequence_and_armed_vehicles_skip_the_launch() {
    let cfg = OffboardConfig::new(None, None);
    let mut s = OffboardSequence::new(1, Personality::PX4_MULTIROTOR, cfg);
    s.next(0.0, &px4(false, FlightMode::Hold, 0.0), None, V)
        .expect("next");
    let e = s.handle(
        0.0,
        &ack(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            MavResult::MAV_RESULT_DENIED,
        ),
    );
    assert!(e.is_err_and(|e| e.to_string().contains("MAV_RESULT_DENIED")));
    // An acknowledgement of some other command is not ours.
    let mut s = OffboardSequence::new(1, Personality::PX4_MULTIROTOR, cfg);
    let flying = px4(true, FlightMode::Hold, 0.0);
    let out = s.next(0.0, &flying, Some(40.0), V).expect("next");
    assert_eq!(commands(&out), [MavCmd::MAV_CMD_DO_SET_MODE]);
    s.handle(
        0.0,
        &ack(MavCmd::MAV_CMD_NAV_LAND, MavResult::MAV_RESULT_DENIED),
    )
    .expect("not ours");
    assert_eq!(s.phase(), Phase::Offboard);
}

fn copter(armed: bool, mode: CopterMode, at: f64) -> VehicleStatus {
    VehicleStatus {
        armed,
        personality: Personality::new(Autopilot::ArduPilot, Frame::Multirotor),
        mode: Some(Mode::Copter(mode)),
        at,
    }
}

/// ArduCopter: GUIDED, arm, NAV_TAKEOFF with the height above home, no target until it is up,
/// then velocity targets; leaving GUIDED is an override.
#[test]
fn ardu_copter_launch_goes_through_guided() {
    use MavCmd::*;
    let p = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let mut s = OffboardSequence::new(2, p, OffboardConfig::new(Some(20.0), Some(480.0)));
    let out = s
        .next(
            0.0,
            &copter(false, CopterMode::Stabilize, 0.0),
            Some(0.0),
            V,
        )
        .expect("next");
    assert_eq!(commands(&out), [MAV_CMD_DO_SET_MODE]);
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!([c.param1, c.param2], [1.0, 4.0]);
    s.handle(0.1, &accepted(MAV_CMD_DO_SET_MODE)).expect("ack");
    let guided = copter(false, CopterMode::Guided, 0.1);
    let out = s.next(0.1, &guided, Some(0.0), V).expect("next");
    assert_eq!(commands(&out), [MAV_CMD_COMPONENT_ARM_DISARM]);
    s.handle(0.2, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    let out = s
        .next(0.2, &copter(true, CopterMode::Guided, 0.2), Some(0.0), V)
        .expect("next");
    assert_eq!(commands(&out), [MAV_CMD_NAV_TAKEOFF]);
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!(c.param7, 20.0, "relative, not AMSL");
    s.handle(0.3, &accepted(MAV_CMD_NAV_TAKEOFF)).expect("ack");
    assert_eq!(s.phase(), Phase::Climbing);
    let up = copter(true, CopterMode::Guided, 1.0);
    assert!(s.next(1.0, &up, Some(10.0), V).expect("next").is_empty());
    let out = s.next(5.0, &up, Some(18.5), V).expect("next");
    assert_eq!((commands(&out).len(), setpoints(&out)), (0, 1));
    assert_eq!(s.phase(), Phase::Offboard);
    // Switched to LOITER by someone: theirs, never GUIDED again.
    let e = s
        .next(6.0, &copter(true, CopterMode::Loiter, 5.5), Some(18.5), V)
        .expect_err("overridden");
    assert_eq!(
        e.to_string(),
        "mode changed by no command of ours: GUIDED -> LOITER"
    );
}

/// ArduPlane: arm, TAKEOFF mode, climb, GUIDED, then course, airspeed and altitude at most
/// every `plane_interval_s`, only while in GUIDED.
#[test]
fn ardu_plane_launch_takes_off_in_takeoff_mode_and_steers_by_course() {
    use MavCmd::*;
    let p = Personality::new(Autopilot::ArduPilot, Frame::FixedWing);
    let plane = |armed, mode, at| VehicleStatus {
        armed,
        personality: p,
        mode: Some(Mode::Plane(mode)),
        at,
    };
    let mut s = OffboardSequence::new(3, p, OffboardConfig::new(Some(40.0), None));
    let out = s
        .next(0.0, &plane(false, PlaneMode::Manual, 0.0), Some(0.0), V)
        .expect("next");
    assert_eq!(commands(&out), [MAV_CMD_COMPONENT_ARM_DISARM]);
    s.handle(0.0, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    let out = s
        .next(0.1, &plane(true, PlaneMode::Manual, 0.1), Some(0.0), V)
        .expect("next");
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!((c.command, c.param2), (MAV_CMD_DO_SET_MODE, 13.0));
    s.handle(0.2, &accepted(MAV_CMD_DO_SET_MODE)).expect("ack");
    assert_eq!(s.phase(), Phase::Climbing);
    let climbing = plane(true, PlaneMode::Takeoff, 1.0);
    assert!(
        s.next(1.0, &climbing, Some(20.0), V)
            .expect("next")
            .is_empty()
    );
    let out = s.next(2.0, &climbing, Some(37.0), V).expect("next");
    let MavMessage::COMMAND_LONG(c) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!((c.command, c.param2), (MAV_CMD_DO_SET_MODE, 15.0));
    s.handle(2.1, &accepted(MAV_CMD_DO_SET_MODE)).expect("ack");
    let steer = Some(Steer {
        velocity: Vector3::new(10.0, 0.0, 1.0),
        altitude_amsl_m: Some(600.0),
    });
    // Still seen in TAKEOFF (a heartbeat from before the switch): nothing.
    assert!(
        s.next(2.2, &climbing, Some(38.0), steer)
            .expect("next")
            .is_empty()
    );
    let guided = plane(true, PlaneMode::Guided, 2.5);
    let out = s.next(2.6, &guided, Some(39.0), steer).expect("next");
    assert_eq!(
        commands(&out),
        [
            MAV_CMD_GUIDED_CHANGE_HEADING,
            MAV_CMD_GUIDED_CHANGE_SPEED,
            MAV_CMD_GUIDED_CHANGE_ALTITUDE
        ]
    );
    let MavMessage::COMMAND_INT(h) = &out[0] else {
        panic!("{out:?}");
    };
    assert_eq!(h.param2, 90.0, "east is a course of 90°");
    // Not again before the interval.
    assert!(
        s.next(2.7, &guided, Some(39.0), steer)
            .expect("next")
            .is_empty()
    );
    assert_eq!(
        s.next(2.9, &guided, Some(39.0), steer).expect("next").len(),
        3
    );
    assert_eq!(setpoints(&out), 0, "no SET_POSITION_TARGET to a plane");
}

/// A PX4 fixed wing waits for its takeoff to climb before OFFBOARD.
#[test]
fn px4_fixed_wing_switches_to_offboard_once_up() {
    use MavCmd::*;
    let p = Personality::new(Autopilot::Px4, Frame::FixedWing);
    let st = |armed, mode, at| VehicleStatus {
        armed,
        personality: p,
        mode: Some(Mode::Px4(mode)),
        at,
    };
    let mut s = OffboardSequence::new(5, p, OffboardConfig::new(Some(30.0), Some(480.0)));
    s.next(0.0, &st(false, FlightMode::Hold, 0.0), Some(0.0), V)
        .expect("next");
    s.handle(0.0, &accepted(MAV_CMD_COMPONENT_ARM_DISARM))
        .expect("ack");
    let out = s
        .next(0.1, &st(true, FlightMode::Hold, 0.1), Some(0.0), V)
        .expect("next");
    assert_eq!(commands(&out), [MAV_CMD_NAV_TAKEOFF]);
    s.handle(0.2, &accepted(MAV_CMD_NAV_TAKEOFF)).expect("ack");
    let climbing = st(true, FlightMode::Takeoff, 1.0);
    assert!(
        s.next(1.0, &climbing, Some(10.0), V)
            .expect("next")
            .is_empty()
    );
    let out = s.next(9.0, &climbing, Some(27.5), V).expect("next");
    assert_eq!(
        (commands(&out), setpoints(&out)),
        (vec![MAV_CMD_DO_SET_MODE], 1)
    );
}
