//! MAVSDK flies harrier-sim: the vehicle runs in-process on real UDP sockets and
//! `tests/python/mavsdk_flight.py` (MAVSDK-Python with its bundled `mavsdk_server`, installed by
//! `scripts/setup`) connects to its API link, waits for the connection and for health all ok, sets
//! MIS_TAKEOFF_ALT, arms, takes off, flies OFFBOARD NED velocity setpoints east, stops offboard,
//! lands and sees the automatic disarm after landing. `tests/python/mavsdk_ardupilot.py` flies an
//! ArduCopter-personality vehicle through MAVSDK's ArduPilot path: arm, takeoff (GUIDED, then
//! NAV_TAKEOFF above home), goto (DO_REPOSITION), hold, land.
//!
//! The script runs in its own process group (it starts `mavsdk_server`), which is killed at the
//! end, whatever happened.

use std::time::Duration;

use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
use harrier_sim::net::{LinkConfig, spawn};
use harrier_sim::vehicle::{CopterMode, FlightMode, VehicleConfig};
use harrier_tests::{kill_group, python_script, require_python_module, wait_with_deadline};

#[test]
fn mavsdk_flies_the_simulated_vehicle() {
    require_python_module("mavsdk", "mavsdk==3.17.4");
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let api_port = sim.local_addrs()[0].expect("API link bound").port();

    let mut child = python_script("mavsdk_flight.py")
        .args(["--url", &format!("udpout://127.0.0.1:{api_port}")])
        .args(["--takeoff-alt", "4.0"])
        .spawn()
        .expect("run mavsdk_flight.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(60), "mavsdk_flight.py");
    // mavsdk_server normally exits with the script; make sure nothing outlives the test.
    kill_group(&mut child);
    assert!(status.success(), "mavsdk_flight.py failed: {status}");

    let v = sim.vehicle();
    assert!(!v.armed(), "PX4 disarms after landing");
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Hold));
    let s = v.state();
    assert!(s.position.x > 8.0, "flew east (ENU x): {s:?}");
    assert!(s.position.y.abs() < 1.0 && s.position.z == 0.0, "{s:?}");
    assert_eq!(v.param("MIS_TAKEOFF_ALT"), Some(4.0));
    let c = v.counters();
    assert_eq!(c.malformed, 0, "{c:?}");
    assert_eq!(c.rejected_setpoints, 0, "{c:?}");
    assert_eq!(c.rejected_params, 0, "{c:?}");
    // Every command MAVSDK sent on the way (message requests and intervals, arm, takeoff, mode
    // changes, land) was understood and accepted.
    assert_eq!(c.refused_commands, 0, "{c:?}");
}

#[test]
fn mavsdk_flies_an_ardu_copter_through_its_ardupilot_path() {
    require_python_module("mavsdk", "mavsdk==3.17.4");
    let copter = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let sim = spawn(
        VehicleConfig::new(1).with_personality(copter),
        &LinkConfig {
            endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let api_port = sim.local_addrs()[0].expect("API link bound").port();
    let mut child = python_script("mavsdk_ardupilot.py")
        .args(["--url", &format!("udpout://127.0.0.1:{api_port}")])
        .args(["--takeoff-alt", "10.0"])
        .spawn()
        .expect("run mavsdk_ardupilot.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(90), "mavsdk_ardupilot.py");
    kill_group(&mut child);
    assert!(status.success(), "mavsdk_ardupilot.py failed: {status}");

    let v = sim.vehicle();
    assert!(!v.armed(), "ArduCopter disarms after landing");
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Land));
    let s = v.state();
    assert!(
        (s.position.x - 30.0).abs() < 1.0 && (s.position.y - 20.0).abs() < 1.0,
        "landed at the goto point: {s:?}"
    );
    let c = v.counters();
    assert_eq!(c.malformed, 0, "{c:?}");
    assert_eq!(c.rejected_params, 0, "{c:?}");
    assert_eq!(c.refused_commands, 0, "{c:?}");
}
