//! What MAVSDK-Python's example programs do, flown against harrier-sim directly
//! (`tests/python/mavsdk_examples.py`, one example per test; the vehicle in-process on a real
//! UDP link on a port of the OS's choice, sped up where MAVSDK does not mind), pymavlink's
//! `mavwp` round trip of a QGroundControl plan (`tests/python/mavwp_roundtrip.py`), and the
//! `harrier-sim` binary's pilot switch on stdin. Each script runs in its own process group,
//! killed at the end whatever happened; every wait has a deadline.

use std::io::{BufRead, BufReader, Write};
use std::net::UdpSocket;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
use harrier_sim::mavlink::MavlinkReader;
use harrier_sim::mavlink::dialects::common::MavMessage;
use harrier_sim::net::{LinkConfig, SimHandle, spawn};
use harrier_sim::vehicle::{FlightMode, VehicleConfig};
use harrier_tests::{
    kill_group, python_script, require_python_module, target_bin, wait_with_deadline,
};

const PX4: Personality = Personality::PX4_MULTIROTOR;
const COPTER: Personality = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);

fn plan() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("python/plans/square.plan")
        .display()
        .to_string()
}

/// A vehicle of `p` at `speedup`, its API link on a free UDP port.
fn vehicle(p: Personality, speedup: f64) -> (SimHandle, u16) {
    let sim = spawn(
        VehicleConfig {
            speedup,
            ..VehicleConfig::new(1).with_personality(p)
        },
        &LinkConfig {
            endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let port = sim.local_addrs()[0].expect("API link bound").port();
    (sim, port)
}

/// Runs `mavsdk_examples.py EXAMPLE` against the vehicle at `port`: its JSON summary.
fn example(name: &str, port: u16, extra: &[&str], timeout: Duration) -> serde_json::Value {
    require_python_module("mavsdk", "mavsdk==3.17.4");
    let out = tempfile::NamedTempFile::new().expect("temp file");
    let started = Instant::now();
    let mut child = python_script("mavsdk_examples.py")
        .arg(name)
        .args(["--url", &format!("udpout://127.0.0.1:{port}")])
        .args(extra)
        .stdout(out.reopen().expect("reopen"))
        .spawn()
        .expect("run mavsdk_examples.py");
    let status = wait_with_deadline(&mut child, timeout, name);
    kill_group(&mut child);
    let text = std::fs::read_to_string(out.path()).unwrap_or_default();
    eprintln!("{text}");
    assert!(status.success(), "{name} failed: {status}");
    eprintln!("{name}: {:.1} s", started.elapsed().as_secs_f64());
    let last = text.lines().last().unwrap_or("{}");
    serde_json::from_str(last).unwrap_or_else(|e| panic!("{name}: summary {last:?}: {e}"))
}

fn counters_clean(sim: &SimHandle) {
    let c = sim.vehicle().counters();
    assert_eq!(c.malformed, 0, "{c:?}");
    assert_eq!(c.rejected_params, 0, "{c:?}");
}

#[test]
fn mavsdk_takeoff_and_land_px4_and_ardupilot() {
    for p in [PX4, COPTER] {
        let (sim, port) = vehicle(p, 2.0);
        let s = example("takeoff_and_land", port, &[], Duration::from_secs(90));
        assert!(s["climbed_m"].as_f64().is_some_and(|h| h > 4.7), "{s}");
        let v = sim.vehicle();
        assert!(!v.armed() && v.state().position.z == 0.0, "{:?}", v.state());
        drop(v);
        counters_clean(&sim);
    }
}

#[test]
fn mavsdk_goto_px4_and_ardupilot() {
    for p in [PX4, COPTER] {
        let (sim, port) = vehicle(p, 2.0);
        let s = example("goto", port, &[], Duration::from_secs(120));
        assert!(s["goto_miss_m"].as_f64().is_some_and(|m| m < 2.0), "{s}");
        let v = sim.vehicle();
        let at = v.state().position;
        assert!(
            (at.x - 30.0).abs() < 2.0 && (at.y - 20.0).abs() < 2.0,
            "landed there: {at:?}"
        );
        drop(v);
        counters_clean(&sim);
        assert_eq!(sim.vehicle().counters().refused_commands, 0);
    }
}

#[test]
fn mavsdk_mission_px4() {
    let (sim, port) = vehicle(PX4, 4.0);
    let s = example("mission", port, &[], Duration::from_secs(150));
    let progress = s["progress"].as_array().expect("progress");
    assert_eq!(progress.last(), Some(&serde_json::json!([3, 3])), "{s}");
    let v = sim.vehicle();
    assert!(
        !v.armed() && v.state().position.norm() < 2.0,
        "{:?}",
        v.state()
    );
    assert_eq!(v.mode(), Mode::Px4(FlightMode::Mission));
    drop(v);
    counters_clean(&sim);
}

#[test]
fn mavsdk_mission_ardupilot() {
    let (sim, port) = vehicle(COPTER, 4.0);
    let s = example(
        "mission",
        port,
        &["--autopilot", "ardupilot"],
        Duration::from_secs(150),
    );
    let progress = s["progress"].as_array().expect("progress");
    assert_eq!(progress.last(), Some(&serde_json::json!([3, 3])), "{s}");
    let v = sim.vehicle();
    assert!(
        !v.armed() && v.state().position.norm() < 2.0,
        "{:?}",
        v.state()
    );
    drop(v);
    counters_clean(&sim);
}

#[test]
fn mavsdk_mission_import_of_a_qgc_plan_px4() {
    let (sim, port) = vehicle(PX4, 4.0);
    let plan = plan();
    let s = example(
        "mission_import",
        port,
        &["--plan", &plan],
        Duration::from_secs(150),
    );
    let progress = s["progress"].as_array().expect("progress");
    assert_eq!(progress.last(), Some(&serde_json::json!([6, 6])), "{s}");
    let v = sim.vehicle();
    assert_eq!(
        (
            v.mission_items(0).len(),
            v.mission_items(1).len(),
            v.mission_items(2).len()
        ),
        (6, 5, 1)
    );
    drop(v);
    counters_clean(&sim);
}

#[test]
fn mavsdk_geofence_px4() {
    let (sim, port) = vehicle(PX4, 1.0);
    let s = example("geofence", port, &[], Duration::from_secs(60));
    assert_eq!(s["vertices"], 4, "{s}");
    let fence = sim.vehicle().mission_items(1).to_vec();
    assert_eq!(fence.len(), 5, "four vertices and a circle: {fence:?}");
    counters_clean(&sim);
}

#[test]
fn mavsdk_do_orbit_then_return_to_launch_px4() {
    let (sim, port) = vehicle(PX4, 2.0);
    let s = example("do_orbit", port, &[], Duration::from_secs(180));
    assert!(
        s["orbit_height_err_m"].as_f64().is_some_and(|e| e < 2.0),
        "{s}"
    );
    let v = sim.vehicle();
    assert!(
        !v.armed() && v.state().position.xy().norm() < 2.0,
        "{:?}",
        v.state()
    );
    drop(v);
    counters_clean(&sim);
}

#[test]
fn pymavlink_mavwp_round_trips_a_qgc_plan_px4_and_ardupilot() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    for (p, autopilot, n) in [(PX4, "px4", 6), (COPTER, "ardupilot", 7)] {
        let (sim, port) = vehicle(p, 1.0);
        let plan = plan();
        let mut child = python_script("mavwp_roundtrip.py")
            .args([
                "--port",
                &port.to_string(),
                "--plan",
                &plan,
                "--autopilot",
                autopilot,
            ])
            .spawn()
            .expect("run mavwp_roundtrip.py");
        let status = wait_with_deadline(&mut child, Duration::from_secs(60), "mavwp_roundtrip.py");
        kill_group(&mut child);
        assert!(
            status.success(),
            "mavwp_roundtrip.py ({autopilot}) failed: {status}"
        );
        assert_eq!(sim.vehicle().mission_items(0).len(), n);
        counters_clean(&sim);
    }
}

/// The `harrier-sim` binary's stdin: `pilot 1 POSCTL` switches the vehicle by itself — the next
/// HEARTBEATs show POSCTL, no COMMAND_ACK is ever sent — and an unknown mode is refused with a
/// reason on stderr.
#[test]
fn the_binary_takes_the_pilots_switch_on_stdin() {
    let bin = target_bin("harrier-sim");
    let mut child = Command::new(&bin)
        .args(["--no-zenoh", "--gcs", "none", "--api", "udpin:127.0.0.1:0"])
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start harrier-sim");
    let stderr = child.stderr.take().expect("stderr");
    let (tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let next_line = |what: &str| {
        lines
            .recv_timeout(Duration::from_secs(20))
            .unwrap_or_else(|_| panic!("no stderr line: {what}"))
    };
    // "harrier-sim: vehicle 1 up, links [Some(127.0.0.1:PORT)]"
    let up = next_line("vehicle up");
    let port: u16 = up
        .rsplit(':')
        .next()
        .and_then(|p| p.trim_end_matches(")]").parse().ok())
        .unwrap_or_else(|| panic!("no port in {up:?}"));

    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind");
    gcs.set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    let hb = MavMessage::HEARTBEAT(harrier_sim::mavlink::dialects::common::HEARTBEAT_DATA {
        mavtype: harrier_sim::mavlink::dialects::common::MavType::MAV_TYPE_GCS,
        ..harrier_sim::mavlink::dialects::common::HEARTBEAT_DATA::DEFAULT
    });
    let mut frame = Vec::new();
    harrier_sim::mavlink::write_v2_msg(&mut frame, harrier_sim::mavlink::MavHeader::default(), &hb)
        .expect("frame");
    // Heartbeats' custom modes until `until` holds (sending ours each second), and whether a
    // COMMAND_ACK came.
    let mut acks = 0;
    let mut watch = |until: &dyn Fn(u32) -> bool| {
        let deadline = Instant::now() + Duration::from_secs(10);
        let mut buf = [0u8; 2048];
        let mut sent = Instant::now() - Duration::from_secs(2);
        while Instant::now() < deadline {
            if sent.elapsed() > Duration::from_secs(1) {
                gcs.send_to(&frame, ("127.0.0.1", port)).expect("send");
                sent = Instant::now();
            }
            let Ok(n) = gcs.recv(&mut buf) else { continue };
            let mut r = MavlinkReader::with_capacity(0, &buf[..n]);
            while let Ok((_, m)) = r.read_any_message::<MavMessage>() {
                match m {
                    MavMessage::HEARTBEAT(h) if until(h.custom_mode) => return,
                    MavMessage::COMMAND_ACK(_) => acks += 1,
                    _ => {}
                }
            }
        }
        panic!("no such HEARTBEAT within 10 s");
    };
    let hold = Mode::Px4(FlightMode::Hold).custom_mode();
    let posctl = Mode::Px4(FlightMode::Position).custom_mode();
    watch(&|c| c == hold);
    let stdin = child.stdin.as_mut().expect("stdin");
    writeln!(stdin, "pilot 1 POSCTL").expect("write stdin");
    assert!(next_line("switch").contains("vehicle 1: pilot switched to POSCTL"));
    watch(&|c| c == posctl);
    writeln!(stdin, "pilot 1 GUIDED").expect("write stdin");
    assert!(next_line("refusal").contains("not a px4-mc mode"));
    writeln!(stdin, "battery 1 42").expect("write stdin");
    assert!(next_line("battery").contains("battery at 42 %"));
    assert_eq!(acks, 0, "a pilot's switch sends no COMMAND_ACK");
    let _ = child.kill();
    let _ = child.wait();
}
