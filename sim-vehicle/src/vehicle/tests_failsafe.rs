//! Unit tests of what changes a vehicle's mode without a command: the pilot's mode switch, the
//! battery and its failsafes, and RTL (PX4 AUTO.RTL, ArduCopter and ArduPlane RTL).

use super::tests_ardupilot::{ack_of, run};
use super::*;
use harrier_link::command::{arm, command_long, set_mode, takeoff_relative};
use mavlink::MessageData;
use mavlink::dialects::common::{
    HEARTBEAT_DATA, MavCmd, MavMessage, MavParamType, MavResult, MavState, PARAM_SET_DATA,
};

const PX4_MC: Personality = Personality::PX4_MULTIROTOR;
const PX4_FW: Personality = Personality::new(Autopilot::Px4, Frame::FixedWing);
const COPTER: Personality = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
const PLANE: Personality = Personality::new(Autopilot::ArduPilot, Frame::FixedWing);

fn heartbeat(v: &Vehicle) -> HEARTBEAT_DATA {
    match v.message(HEARTBEAT_DATA::ID) {
        Some(MavMessage::HEARTBEAT(hb)) => hb,
        other => panic!("{other:?}"),
    }
}

fn param_set(v: &mut Vehicle, t: f64, name: &str, value: f32, kind: MavParamType) {
    let value = if v.personality().autopilot == Autopilot::Px4
        && kind != MavParamType::MAV_PARAM_TYPE_REAL32
    {
        // PX4 integers travel bytewise.
        f32::from_bits(value as i32 as u32)
    } else {
        value
    };
    v.handle(
        t,
        &MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
            param_type: kind,
        }),
    );
}

/// A vehicle of `p` in the air at `height` m above home (about), hovering or loitering, at
/// time 60 s.
fn up(p: Personality, height: f32) -> Vehicle {
    let mut v = Vehicle::new(VehicleConfig::new(1).with_personality(p), 0.0);
    match p.autopilot {
        Autopilot::Px4 => {
            param_set(
                &mut v,
                0.0,
                "MIS_TAKEOFF_ALT",
                height,
                MavParamType::MAV_PARAM_TYPE_REAL32,
            );
            assert_eq!(
                ack_of(&v.handle(0.0, &arm(1))),
                MavResult::MAV_RESULT_ACCEPTED
            );
            let takeoff = command_long(1, MavCmd::MAV_CMD_NAV_TAKEOFF, [f32::NAN; 7]);
            assert_eq!(
                ack_of(&v.handle(0.0, &takeoff)),
                MavResult::MAV_RESULT_ACCEPTED
            );
        }
        Autopilot::ArduPilot if p.frame == Frame::Multirotor => {
            let guided = Mode::Copter(CopterMode::Guided);
            assert_eq!(
                ack_of(&v.handle(0.0, &set_mode(1, guided))),
                MavResult::MAV_RESULT_ACCEPTED
            );
            assert_eq!(
                ack_of(&v.handle(0.0, &arm(1))),
                MavResult::MAV_RESULT_ACCEPTED
            );
            let r = v.handle(0.0, &takeoff_relative(1, height));
            assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
        }
        Autopilot::ArduPilot => {
            param_set(
                &mut v,
                0.0,
                "TKOFF_ALT",
                height,
                MavParamType::MAV_PARAM_TYPE_INT16,
            );
            let takeoff = Mode::Plane(PlaneMode::Takeoff);
            assert_eq!(
                ack_of(&v.handle(0.0, &set_mode(1, takeoff))),
                MavResult::MAV_RESULT_ACCEPTED
            );
            assert_eq!(
                ack_of(&v.handle(0.0, &arm(1))),
                MavResult::MAV_RESULT_ACCEPTED
            );
        }
    }
    run(&mut v, 0.0, 60.0, |_, _| {});
    assert!(
        (v.state().position.z - f64::from(height)).abs() < 2.0,
        "{:?} at {:?}",
        p,
        v.state().position
    );
    v
}

/// Flies `v` away from home with the personality's hold mode somewhere else: `dist` m east.
fn away(v: &mut Vehicle, t: f64, dist: f64) {
    v.state.position.x += dist;
    v.hold_point.x += dist;
    v.advance(t);
}

/// The pilot's switch changes the mode by itself — no reply, the HEARTBEAT shows it — under
/// the autopilot's own rules (PX4 OFFBOARD needs setpoints; an unflown mode is refused).
#[test]
fn a_pilot_switch_changes_the_mode_without_a_command() {
    let mut v = up(PX4_MC, 10.0);
    assert!(v.pilot_switch(Mode::Px4(FlightMode::Position)));
    assert_eq!(
        heartbeat(&v).custom_mode,
        Mode::Px4(FlightMode::Position).custom_mode()
    );
    assert!(
        !v.pilot_switch(Mode::Px4(FlightMode::Offboard)),
        "no setpoints"
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Position));
    assert_eq!(v.counters().refused_commands, 0, "no command was refused");

    let mut c = up(COPTER, 10.0);
    assert_eq!(c.mode(), Mode::Copter(CopterMode::Guided));
    let loiter = COPTER.mode_named("LOITER").expect("LOITER");
    assert!(c.pilot_switch(loiter));
    assert_eq!(heartbeat(&c).custom_mode, 5);
    let here = c.state().position;
    run(&mut c, 60.0, 70.0, |_, _| {});
    assert!((c.state().position - here).norm() < 0.5, "LOITER holds");
    assert!(
        !c.pilot_switch(Mode::Copter(CopterMode::Flip)),
        "not simulated"
    );
    assert_eq!(c.mode(), loiter);
}

/// The battery drains at the configured rate while armed, and not disarmed.
#[test]
fn the_battery_drains_at_the_configured_rate() {
    let config = VehicleConfig::new(1).with_battery_drain(10.0);
    let mut v = Vehicle::new(config, 0.0);
    run(&mut v, 0.0, 60.0, |_, _| {});
    assert_eq!(v.battery_remaining(), 1.0, "disarmed: no drain");
    assert_eq!(
        ack_of(&v.handle(60.0, &arm(1))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    run(&mut v, 60.0, 120.0, |_, _| {});
    assert!(
        (v.battery_remaining() - 0.9).abs() < 1e-3,
        "{}",
        v.battery_remaining()
    );
    // The default: 30 minutes.
    let d = Vehicle::new(VehicleConfig::new(1), 0.0);
    assert!((d.config().battery_drain_pct_min - 100.0 / 30.0).abs() < 1e-12);
}

/// PX4's low-battery failsafe: COM_LOW_BAT_ACT 0 (default) only warns; 3 returns at
/// BAT_CRIT_THR and lands at BAT_EMERGEN_THR; the HEARTBEAT is CRITICAL meanwhile.
#[test]
fn px4_low_battery_returns_then_lands_with_com_low_bat_act_3() {
    let mut v = up(PX4_MC, 10.0);
    v.set_battery(0.06);
    run(&mut v, 60.0, 61.0, |_, _| {});
    assert_eq!(v.battery_level(), battery::BatteryLevel::Critical);
    assert_eq!(
        v.mode(),
        Mode::Px4(FlightMode::Hold),
        "default: warning only"
    );
    assert_eq!(heartbeat(&v).system_status, MavState::MAV_STATE_ACTIVE);

    let mut v = up(PX4_MC, 10.0);
    param_set(
        &mut v,
        60.0,
        "COM_LOW_BAT_ACT",
        3.0,
        MavParamType::MAV_PARAM_TYPE_INT32,
    );
    assert_eq!(v.param("COM_LOW_BAT_ACT"), Some(3.0));
    away(&mut v, 60.0, 40.0);
    v.set_battery(0.10);
    run(&mut v, 60.0, 61.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold), "low: warning");
    v.set_battery(0.07);
    run(&mut v, 61.0, 62.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Rtl), "critical: return");
    assert_eq!(heartbeat(&v).system_status, MavState::MAV_STATE_CRITICAL);
    v.set_battery(0.05);
    run(&mut v, 62.0, 63.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Land), "emergency: land");
    run(&mut v, 63.0, 120.0, |_, _| {});
    assert!(!v.armed(), "landed and disarmed");
    assert_eq!(heartbeat(&v).system_status, MavState::MAV_STATE_STANDBY);
}

/// ArduPilot's: BATT_LOW_MAH with BATT_FS_LOW_ACT 2 sends a Copter to RTL (CRITICAL), BATT_CRT_VOLT
/// with BATT_FS_CRT_ACT 1 lands it; an ArduPlane with BATT_FS_LOW_ACT 1 returns. With the
/// default action the failsafe is in force (CRITICAL) but the mode stays.
#[test]
fn ardupilot_low_battery_failsafe_acts_by_batt_fs_low_act() {
    let mut v = up(COPTER, 10.0);
    param_set(
        &mut v,
        60.0,
        "BATT_LOW_MAH",
        1000.0,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    );
    v.set_battery(0.5);
    run(&mut v, 60.0, 61.0, |_, _| {});
    assert_eq!(
        v.mode(),
        Mode::Copter(CopterMode::Guided),
        "above 1000 mAh of 3300"
    );
    v.set_battery(0.29);
    run(&mut v, 61.0, 62.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Guided), "action 0: none");
    assert_eq!(heartbeat(&v).system_status, MavState::MAV_STATE_CRITICAL);

    let mut v = up(COPTER, 10.0);
    param_set(
        &mut v,
        60.0,
        "BATT_LOW_MAH",
        1000.0,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    );
    param_set(
        &mut v,
        60.0,
        "BATT_FS_LOW_ACT",
        2.0,
        MavParamType::MAV_PARAM_TYPE_INT8,
    );
    param_set(
        &mut v,
        60.0,
        "BATT_CRT_VOLT",
        15.0,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    );
    param_set(
        &mut v,
        60.0,
        "BATT_FS_CRT_ACT",
        1.0,
        MavParamType::MAV_PARAM_TYPE_INT8,
    );
    v.set_battery(0.29);
    run(&mut v, 60.0, 61.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Rtl));
    v.set_battery(0.09); // 14.98 V
    run(&mut v, 61.0, 62.0, |_, _| {});
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Land));

    let mut p = up(PLANE, 50.0);
    param_set(
        &mut p,
        60.0,
        "BATT_LOW_VOLT",
        15.5,
        MavParamType::MAV_PARAM_TYPE_REAL32,
    );
    param_set(
        &mut p,
        60.0,
        "BATT_FS_LOW_ACT",
        1.0,
        MavParamType::MAV_PARAM_TYPE_INT8,
    );
    p.set_battery(0.3); // 15.4 V
    run(&mut p, 60.0, 61.0, |_, _| {});
    assert_eq!(p.mode(), Mode::Plane(PlaneMode::Rtl));
    assert_eq!(heartbeat(&p).system_status, MavState::MAV_STATE_CRITICAL);
}

/// PX4 AUTO.RTL, by DO_SET_MODE and by NAV_RETURN_TO_LAUNCH (what MAVSDK's return_to_launch
/// sends): climbs to RTL_RETURN_ALT, flies home at MPC_XY_CRUISE, lands and disarms.
#[test]
fn px4_rtl_climbs_to_return_alt_flies_home_lands_and_disarms() {
    let mut v = up(PX4_MC, 10.0);
    away(&mut v, 60.0, 100.0);
    let rtl = command_long(1, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]);
    assert_eq!(
        ack_of(&v.handle(60.0, &rtl)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Rtl));
    assert_eq!(
        heartbeat(&v).custom_mode,
        (4 << 16) | (5 << 24),
        "AUTO.RTL: main 4, sub 5"
    );
    let (mut top, mut fastest) = (0.0f64, 0.0f64);
    run(&mut v, 60.0, 200.0, |v, _| {
        top = top.max(v.state().position.z);
        fastest = fastest.max(v.state().horizontal_velocity().norm());
    });
    assert!((top - 60.0).abs() < 1.0, "RTL_RETURN_ALT 60 m: {top}");
    assert!(fastest < 5.2, "MPC_XY_CRUISE 5 m/s: {fastest}");
    assert!(
        !v.armed() && v.state().position.norm() < 1.0,
        "{:?}",
        v.state()
    );

    // Above the return altitude it keeps its height; DO_SET_MODE reaches it too.
    let mut v = up(PX4_MC, 80.0);
    away(&mut v, 60.0, 30.0);
    let r = v.handle(60.0, &set_mode(1, Mode::Px4(FlightMode::Rtl)));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let mut worst = 0.0f64;
    run(&mut v, 60.0, 120.0, |v, _| {
        if v.state().position.x > 2.0 {
            worst = worst.max((v.state().position.z - 80.0).abs());
        }
    });
    assert!(worst < 1.0, "flew home at 80 m: {worst}");
    assert!(v.state().position.xy().norm() < 1.0, "home");
}

/// Fixed wings return and loiter over home: a PX4 fixed wing at RTL_DESCEND_ALT, an ArduPlane at
/// RTL_ALTITUDE; neither disarms.
#[test]
fn fixed_wings_return_and_loiter_over_home() {
    for (p, alt) in [(PX4_FW, 30.0), (PLANE, 100.0)] {
        let mut v = up(p, 50.0);
        away(&mut v, 60.0, 600.0);
        let rtl = p.mode_named("RTL").expect("RTL");
        assert_eq!(
            ack_of(&v.handle(60.0, &set_mode(1, rtl))),
            MavResult::MAV_RESULT_ACCEPTED
        );
        let mut far = 0.0f64;
        run(&mut v, 60.0, 260.0, |v, t| {
            if t > 200.0 {
                far = far.max(v.state().position.xy().norm());
            }
        });
        assert!(far < 200.0, "{p:?} loiters over home: {far}");
        assert!(
            (v.state().position.z - alt).abs() < 3.0,
            "{p:?} {:?}",
            v.state().position
        );
        assert!(v.armed());
    }
}
