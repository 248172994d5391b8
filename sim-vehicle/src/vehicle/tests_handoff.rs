//! Unit tests of a target handed to the autopilot: PX4's DO_ORBIT, FOLLOW_TARGET in PX4's
//! AUTO.FOLLOW_TARGET and ArduCopter's FOLLOW, the ROI and the gimbal manager.

use super::tests_ardupilot::{ack_of, run};
use super::*;
use harrier_link::command::{arm, command_long, set_mode, takeoff};
use harrier_link::handoff::{follow_target, orbit, roi};
use mavlink::MessageData;
use mavlink::dialects::common::{GIMBAL_MANAGER_INFORMATION_DATA, MavCmd, MavMessage, MavResult};

/// A PX4 multirotor hovering 20 m up.
fn px4_up() -> Vehicle {
    let mut v = Vehicle::new(VehicleConfig::new(1), 0.0);
    assert_eq!(
        ack_of(&v.handle(0.0, &arm(1))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let r = v.handle(0.0, &takeoff(1, Some(508.0)));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    run(&mut v, 0.0, 15.0, |_, _| {});
    v
}

/// DO_ORBIT: POSCTL.ORBIT around the centre at the radius, in its sense, at its speed; refused on
/// the ground and by ArduPilot.
#[test]
fn px4_orbits_the_centre_of_a_do_orbit() {
    let mut ground = Vehicle::new(VehicleConfig::new(1), 0.0);
    let centre = ground.frame.from_enu(&Vector3::new(100.0, 50.0, 25.0));
    let r = ground.handle(0.0, &orbit(1, &centre, 40.0, true, 5.0));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_DENIED);
    let mut v = px4_up();
    let r = v.handle(15.0, &orbit(1, &centre, 40.0, true, 5.0));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Orbit));
    let mut samples = Vec::new();
    run(&mut v, 15.0, 120.0, |v, t| {
        if t > 70.0 {
            let d = v.state().horizontal_position() - nalgebra::Vector2::new(100.0, 50.0);
            let vel = v.state().horizontal_velocity();
            samples.push((
                d.norm(),
                d.x * vel.y - d.y * vel.x,
                vel.norm(),
                v.state().position.z,
            ));
        }
    });
    for (r, turn, speed, z) in samples {
        assert!((r - 40.0).abs() < 1.0, "radius {r}");
        assert!(turn > 0.0, "counter-clockwise");
        assert!(
            (speed - 5.0).abs() < 0.3 && (z - 25.0).abs() < 0.5,
            "{speed} {z}"
        );
    }
    let copter = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let mut a = Vehicle::new(VehicleConfig::new(1).with_personality(copter), 0.0);
    assert_eq!(
        ack_of(&a.handle(0.0, &orbit(1, &centre, 40.0, true, 5.0))),
        MavResult::MAV_RESULT_UNSUPPORTED
    );
}

/// FOLLOW_TARGET: PX4 flies FLW_TGT_DST (8 m) behind the moving target and FLW_TGT_HT (8 m) above
/// it; ArduCopter's FOLLOW keeps the offset it had when engaged.
#[test]
fn follow_modes_follow_the_target_messages() {
    let mut v = px4_up();
    assert_eq!(
        ack_of(&v.handle(15.0, &set_mode(1, Mode::Px4(FlightMode::FollowTarget)))),
        MavResult::MAV_RESULT_ACCEPTED
    );
    let frame = v.frame;
    let target_at = |t: f64| Vector3::new(30.0 + 2.0 * (t - 15.0), 10.0, 0.0);
    let east = Vector3::new(2.0, 0.0, 0.0);
    run(&mut v, 15.0, 60.0, |v, t| {
        let m = follow_target(0, &frame.from_enu(&target_at(t)), &east, [1.0; 3]);
        v.handle(t, &m);
    });
    let want = target_at(60.0) + Vector3::new(-8.0, 0.0, 8.0);
    assert!(
        (v.state().position - want).norm() < 1.0,
        "{:?} vs {want}",
        v.state()
    );
    assert!((v.state().velocity - east).norm() < 0.2);

    let copter = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let mut c = Vehicle::new(VehicleConfig::new(1).with_personality(copter), 0.0);
    c.handle(0.0, &set_mode(1, Mode::Copter(CopterMode::Guided)));
    c.handle(0.0, &arm(1));
    c.handle(0.0, &harrier_link::command::takeoff_relative(1, 20.0));
    run(&mut c, 0.0, 15.0, |_, _| {});
    let here = c.state().position;
    let first = target_at(15.0);
    c.handle(
        15.0,
        &follow_target(0, &frame.from_enu(&first), &east, [1.0; 3]),
    );
    let r = c.handle(15.0, &set_mode(1, Mode::Copter(CopterMode::Follow)));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    run(&mut c, 15.0, 60.0, |v, t| {
        v.handle(
            t,
            &follow_target(0, &frame.from_enu(&target_at(t)), &east, [1.0; 3]),
        );
    });
    let want = target_at(60.0) + (here - first);
    assert!(
        (c.state().position - want).norm() < 1.0,
        "{:?} vs {want}",
        c.state()
    );
}

/// DO_SET_ROI_LOCATION points the gimbal at the point; the autopilot answers as the gimbal
/// manager of its gimbal; ROI_NONE clears it; another gimbal device is refused.
#[test]
fn the_roi_points_the_gimbal() {
    let mut v = px4_up();
    assert_eq!(v.gimbal_direction(), None);
    let r = v.handle(
        15.0,
        &command_long(
            1,
            MavCmd::MAV_CMD_REQUEST_MESSAGE,
            [
                GIMBAL_MANAGER_INFORMATION_DATA::ID as f32,
                0.,
                0.,
                0.,
                0.,
                0.,
                0.,
            ],
        ),
    );
    let Some(MavMessage::GIMBAL_MANAGER_INFORMATION(g)) = r.get(1) else {
        panic!("{r:?}")
    };
    assert_eq!(g.gimbal_device_id, GIMBAL_DEVICE_ID);
    let point = Vector3::new(200.0, -100.0, 0.0);
    let target = v.frame.from_enu(&point);
    let r = v.handle(15.0, &roi(1, 1, GIMBAL_DEVICE_ID, &target));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let d = v.gimbal_direction().expect("pointed");
    let want = (point - v.state().position).normalize();
    assert!(d.angle(&want) < 1e-3, "{d} vs {want}");
    assert_eq!(
        ack_of(&v.handle(15.0, &roi(1, 1, 7, &target))),
        MavResult::MAV_RESULT_DENIED
    );
    let none = command_long(1, MavCmd::MAV_CMD_DO_SET_ROI_NONE, [0.0; 7]);
    assert_eq!(
        ack_of(&v.handle(15.0, &none)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(v.gimbal_direction(), None);
}

/// MAVSDK's do_orbit sends the centre's altitude AMSL in a COMMAND_INT whose frame says
/// relative: PX4 (and the simulator) orbit at that AMSL altitude, not that far above home.
#[test]
fn px4_reads_the_orbit_altitude_as_amsl_whatever_the_frame() {
    use harrier_link::command::command_int;
    let mut v = px4_up();
    let centre = v.frame.from_enu(&Vector3::new(30.0, 0.0, 0.0));
    let home_plus_10 = v.config().origin.alt_m as f32 + 10.0;
    let orbit = command_int(
        1,
        MavCmd::MAV_CMD_DO_ORBIT,
        mavlink::dialects::common::MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT,
        [15.0, 3.0, f32::NAN, f32::NAN],
        (
            (centre.lat_deg * 1e7).round() as i32,
            (centre.lon_deg * 1e7).round() as i32,
            home_plus_10,
        ),
    );
    assert_eq!(
        ack_of(&v.handle(15.0, &orbit)),
        MavResult::MAV_RESULT_ACCEPTED
    );
    run(&mut v, 15.0, 60.0, |_, _| {});
    assert!(
        (v.state().position.z - 10.0).abs() < 0.5,
        "{:?}",
        v.state().position
    );
}

/// FLW_TGT_FA turns the follow position around the target's course: 90° puts the follower on
/// its right (a target driving east: south of it), FLW_TGT_DST away, FLW_TGT_HT above home.
#[test]
fn px4_follows_at_flw_tgt_fa_around_the_course() {
    let mut v = px4_up();
    let set = MavMessage::PARAM_SET(mavlink::dialects::common::PARAM_SET_DATA {
        param_value: 90.0,
        target_system: 1,
        target_component: 1,
        param_id: "FLW_TGT_FA".into(),
        param_type: mavlink::dialects::common::MavParamType::MAV_PARAM_TYPE_REAL32,
    });
    v.handle(15.0, &set);
    assert_eq!(v.param("FLW_TGT_FA"), Some(90.0));
    let r = v.handle(15.0, &set_mode(1, Mode::Px4(FlightMode::FollowTarget)));
    assert_eq!(ack_of(&r), MavResult::MAV_RESULT_ACCEPTED);
    let frame = v.frame;
    let target_at = |t: f64| Vector3::new(30.0 + 2.0 * (t - 15.0), 10.0, 0.0);
    let east = Vector3::new(2.0, 0.0, 0.0);
    run(&mut v, 15.0, 60.0, |v, t| {
        let m = follow_target(0, &frame.from_enu(&target_at(t)), &east, [1.0; 3]);
        v.handle(t, &m);
    });
    let want = target_at(60.0) + Vector3::new(0.0, -8.0, 8.0);
    assert!(
        (v.state().position - want).norm() < 1.0,
        "{:?} vs {want}",
        v.state()
    );
}
