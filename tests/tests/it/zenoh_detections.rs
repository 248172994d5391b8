//! The real Zenoh Python API (eclipse-zenoh, installed by `scripts/setup`) receives harrier-sim's
//! detections: two in-process vehicles on real UDP sockets, the live sensor loop publishing over a
//! real Zenoh session that listens on loopback (scouting off), and
//! `tests/python/zenoh_subscriber.py` connecting to that explicit tcp endpoint. The subscriber
//! decodes every field of DETECTIONS.md and measures the rate; this test checks the rate and that
//! the subscriber saw what was published.

use std::process::Stdio;
use std::time::Duration;

use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
use harrier_sim::sensor_loop::SensorLoopConfig;
use harrier_sim::setup::SimScenario;
use harrier_tests::{free_tcp_port, python_script, require_python_module, wait_with_deadline};

const RATE_HZ: f64 = 20.0;
const SCANS: usize = 60;

#[test]
fn eclipse_zenoh_subscriber_decodes_the_detections() {
    require_python_module("zenoh", "eclipse-zenoh==1.10.2");

    let mut scenario = SimScenario::load("radar").expect("preset");
    for s in &mut scenario.sensors {
        s.rate_hz = RATE_HZ;
    }
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let mut world = WorldConfig::new(SensorLoopConfig {
        scenario,
        seed: 7,
        speedup: 1.0,
        truth_hz: 5.0,
        clock: Default::default(),
    });
    world.vehicles = vec![WorldVehicle::grounded(1), WorldVehicle::grounded(2)];
    world.zenoh.listen = vec![endpoint.clone()];
    let running = SimWorld::start(&world).expect("start the simulated world");

    let mut child = python_script("zenoh_subscriber.py")
        .args(["--connect", &endpoint, "--vehicles", "1,2"])
        .args(["--scans", &SCANS.to_string(), "--timeout", "40"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("run zenoh_subscriber.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(60), "zenoh_subscriber.py");
    let out = child.wait_with_output().expect("script output");
    assert!(status.success(), "zenoh_subscriber.py failed: {status}");
    let summary: serde_json::Value =
        serde_json::from_slice(&out.stdout).expect("a JSON summary line");

    for id in ["1", "2"] {
        let v = &summary["vehicles"][id];
        assert_eq!(v["scans"], SCANS, "{summary}");
        // Sensor time: scans at k / rate exactly.
        let sim = v["rate_sim_hz"].as_f64().expect("rate");
        assert!((sim - RATE_HZ).abs() < 0.05 * RATE_HZ, "{summary}");
        // Wall time: the loop keeps up with the configured rate.
        let wall = v["rate_wall_hz"].as_f64().expect("rate");
        assert!((wall - RATE_HZ).abs() < 0.15 * RATE_HZ, "{summary}");
        // The radar sees its target (20 km range, Pd 1) in every scan.
        assert_eq!(v["detections"], SCANS, "{summary}");
    }
    assert!(
        summary["truth"].as_u64().expect("truth count") >= 1,
        "{summary}"
    );
    let c = running.counters();
    assert_eq!(c.failed, 0);
    assert!(c.scans >= 2 * SCANS as u64, "{c:?}");
    running.stop();
}
