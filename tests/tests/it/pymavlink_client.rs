//! A real MAVLink client flies harrier-sim: the vehicle runs in-process on real UDP sockets and
//! `tests/python/pymavlink_flight.py` (pymavlink, installed by `scripts/setup`) connects to its API link,
//! reads telemetry and parameters, arms, takes off, flies OFFBOARD velocity setpoints (sending a
//! NaN setpoint and a garbage datagram in flight, which must be refused, counted and survived) and
//! lands.
//!
//! A second link plays the GCS (`udpout` to a socket held here): it must receive the telemetry
//! but none of the replies meant for the API client.
//!
//! `pymavlink_flies_a_signed_only_vehicle`: the same flight with MAVLink 2 signing, the vehicle
//! in `signed_only` mode and pymavlink signing with the same key (`setup_signing`; every message
//! it accepts from the vehicle is signed); then a pymavlink client with another key is ignored
//! (no answer, no arming; its frames counted as `bad_signature`).

use std::net::UdpSocket;
use std::time::Duration;

use harrier_link::signing::{Signing, SigningKey, SigningMode};
use harrier_sim::mavlink::MavlinkReader;
use harrier_sim::mavlink::dialects::common::MavMessage;
use harrier_sim::net::{LinkConfig, spawn};
use harrier_sim::vehicle::{FlightMode, VehicleConfig};
use harrier_tests::{python_script, require_python_module, wait_with_deadline};

#[test]
fn pymavlink_flies_the_simulated_vehicle() {
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind GCS socket");
    gcs.set_nonblocking(true).expect("nonblocking");
    let gcs_port = gcs.local_addr().expect("GCS address").port();
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec![
                format!("udpout:127.0.0.1:{gcs_port}"),
                "udpin:127.0.0.1:0".to_owned(),
            ],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let api_port = sim.local_addrs()[1].expect("API link bound").port();

    require_python_module("pymavlink", "pymavlink==2.4.50");
    let mut child = python_script("pymavlink_flight.py")
        .args(["--port", &api_port.to_string()])
        .spawn()
        .expect("run pymavlink_flight.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(120), "pymavlink_flight.py");
    assert!(status.success(), "pymavlink_flight.py failed: {status}");

    {
        let v = sim.vehicle();
        assert!(!v.armed());
        assert_eq!(
            v.mode(),
            harrier_link::autopilot::Mode::Px4(FlightMode::Hold)
        );
        assert!(v.state().position.y > 8.0, "{:?}", v.state()); // flew north (ENU y)
        assert_eq!(v.param("MIS_TAKEOFF_ALT"), Some(4.0));
        assert_eq!(v.counters().rejected_params, 1);
        // The NaN setpoint and the garbage datagram sent in flight, and nothing else.
        assert_eq!(v.counters().rejected_setpoints, 1);
        assert_eq!(v.counters().malformed, 1);
    }

    // The GCS link saw telemetry, but no reply to the API client's requests.
    let mut buf = [0u8; 2048];
    let (mut heartbeats, mut replies) = (0, 0);
    while let Ok(n) = gcs.recv(&mut buf) {
        let mut reader = MavlinkReader::new(&buf[..n]);
        while let Ok((_, m)) = reader.read_any_message::<MavMessage>() {
            match m {
                MavMessage::HEARTBEAT(_) => heartbeats += 1,
                MavMessage::COMMAND_ACK(_)
                | MavMessage::PARAM_VALUE(_)
                | MavMessage::AUTOPILOT_VERSION(_) => replies += 1,
                _ => {}
            }
        }
    }
    assert!(heartbeats >= 5, "GCS saw {heartbeats} heartbeats");
    assert_eq!(replies, 0, "replies leaked to the GCS link");
    sim.stop();
}

#[test]
fn pymavlink_flies_a_signed_only_vehicle() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    let key = "5f".repeat(8) + &"a3".repeat(24);
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            signing: Some(Signing {
                key: SigningKey::from_hex(&key).expect("key"),
                mode: SigningMode::SignedOnly,
                link_id: 0,
            }),
        },
    )
    .expect("start the vehicle");
    let port = sim.local_addrs()[0]
        .expect("API link bound")
        .port()
        .to_string();
    let mut child = python_script("pymavlink_flight.py")
        .args(["--port", &port, "--signing-key", &key])
        .spawn()
        .expect("run pymavlink_flight.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(120), "signed flight");
    assert!(
        status.success(),
        "signed pymavlink_flight.py failed: {status}"
    );
    {
        let v = sim.vehicle();
        assert!(v.state().position.y > 8.0, "{:?}", v.state()); // flew north (ENU y)
        assert!(!v.armed());
        // Only the flight's deliberate bad input; nothing of pymavlink's was refused.
        assert_eq!(
            (v.counters().rejected_setpoints, v.counters().malformed),
            (1, 1)
        );
        assert_eq!(v.counters().rejected.total(), 0, "{:?}", v.counters());
    }

    let wrong = "00".repeat(31) + "01";
    let mut child = python_script("pymavlink_flight.py")
        .args([
            "--port",
            &port,
            "--signing-key",
            &wrong,
            "--expect-ignored",
            "3",
        ])
        .spawn()
        .expect("run pymavlink_flight.py --expect-ignored");
    let status = wait_with_deadline(&mut child, Duration::from_secs(60), "wrong-key client");
    assert!(
        status.success(),
        "the wrong-key client was answered: {status}"
    );
    let v = sim.vehicle();
    assert!(!v.armed(), "armed by a client with the wrong key");
    let r = v.counters().rejected;
    // At least 2 frames per 0.2 s for 3 s, all refused for their signature.
    assert!(r.bad_signature >= 20, "{r:?}");
    assert_eq!((r.unsigned, r.replay), (0, 0));
    drop(v);
    sim.stop();
}
