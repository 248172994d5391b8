//! MAVProxy, headless, connects to harrier-sim over TCP: the vehicle runs in-process with a
//! `tcpin` API link and MAVProxy (installed by `scripts/setup`) is its `--master=tcp:…` client, logging
//! to a telemetry log (tlog) and forwarding to a UDP `--out` socket held here. Its `--cmd` sends a
//! MAV_CMD_REQUEST_MESSAGE (AUTOPILOT_VERSION) through the link, so the round trip is checked too.
//!
//! MAVProxy must still be running at the end (it did not crash); its process group is killed
//! then, whatever happened.

use std::net::UdpSocket;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use harrier_sim::mavlink::MavlinkReader;
use harrier_sim::mavlink::dialects::common::{MavCmd, MavMessage, MavResult};
use harrier_sim::net::{LinkConfig, spawn};
use harrier_sim::vehicle::VehicleConfig;
use harrier_tests::{kill_group, require_python_module};

/// The messages of a telemetry log: records of an 8-byte big-endian timestamp (µs since the Unix
/// epoch) and one raw MAVLink frame, as `(timestamp, sysid, message)`. Frames outside the common
/// dialect are skipped; an incomplete record at the end (the log is still growing) is ignored.
fn read_tlog(data: &[u8]) -> Vec<(u64, u32, MavMessage)> {
    let mut out = Vec::new();
    let mut p = 0;
    while p + 8 + 2 <= data.len() {
        let mut stamp = [0u8; 8];
        stamp.copy_from_slice(&data[p..p + 8]);
        let f = p + 8;
        let len = match data[f] {
            0xFD if f + 3 <= data.len() => {
                let signature = if data[f + 2] & 1 != 0 { 13 } else { 0 };
                12 + usize::from(data[f + 1]) + signature
            }
            0xFE => 8 + usize::from(data[f + 1]),
            0xFD => break,
            other => {
                panic!("not a tlog: byte {other:#04x} at offset {f} is no MAVLink frame start")
            }
        };
        if f + len > data.len() {
            break;
        }
        let mut reader = MavlinkReader::new(&data[f..f + len]);
        if let Ok((h, m)) = reader.read_any_message::<MavMessage>() {
            out.push((u64::from_be_bytes(stamp), h.system_id, m));
        }
        p = f + len;
    }
    out
}

#[test]
fn mavproxy_logs_and_forwards_the_simulated_vehicle_over_tcp() {
    require_python_module("MAVProxy", "MAVProxy==1.8.75");
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec!["tcpin:127.0.0.1:0".to_owned()],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let api_port = sim.local_addrs()[0].expect("API link listening").port();
    let out = UdpSocket::bind("127.0.0.1:0").expect("bind the --out socket");
    out.set_nonblocking(true).expect("nonblocking");
    let out_port = out.local_addr().expect("--out address").port();

    let dir = tempfile::tempdir().expect("temporary directory");
    let tlog = dir.path().join("flight.tlog");
    let console = std::fs::File::create(dir.path().join("mavproxy.out")).expect("console log");
    let mut child = Command::new("python3")
        .args(["-m", "MAVProxy.mavproxy"])
        .arg(format!("--master=tcp:127.0.0.1:{api_port}"))
        .arg(format!("--out=udpout:127.0.0.1:{out_port}"))
        .args(["--daemon", "--non-interactive"])
        .arg(format!("--logfile={}", tlog.display()))
        .arg(format!("--state-basedir={}", dir.path().display()))
        .arg("--cmd=long REQUEST_MESSAGE 148")
        .current_dir(dir.path())
        .stdin(Stdio::null())
        .stdout(console.try_clone().expect("console log"))
        .stderr(console)
        .process_group(0)
        .spawn()
        .expect("run MAVProxy");
    let console_text =
        || std::fs::read_to_string(dir.path().join("mavproxy.out")).unwrap_or_default();

    let deadline = Instant::now() + Duration::from_secs(40);
    let mut forwarded_heartbeats = 0;
    let mut buf = [0u8; 2048];
    let logged = loop {
        if let Some(status) = child.try_wait().expect("poll MAVProxy") {
            panic!("MAVProxy exited early ({status}):\n{}", console_text());
        }
        while let Ok(n) = out.recv(&mut buf) {
            let mut reader = MavlinkReader::new(&buf[..n]);
            while let Ok((h, m)) = reader.read_any_message::<MavMessage>() {
                if h.system_id == 1 && matches!(m, MavMessage::HEARTBEAT(_)) {
                    forwarded_heartbeats += 1;
                }
            }
        }
        let logged = read_tlog(&std::fs::read(&tlog).unwrap_or_default());
        let from_vehicle = |want: fn(&MavMessage) -> bool| {
            logged
                .iter()
                .filter(|(_, sysid, m)| *sysid == 1 && want(m))
                .count()
        };
        let heartbeats = from_vehicle(|m| matches!(m, MavMessage::HEARTBEAT(_)));
        let positions = from_vehicle(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
        let acks = from_vehicle(|m| {
            matches!(m, MavMessage::COMMAND_ACK(a)
                if a.command == MavCmd::MAV_CMD_REQUEST_MESSAGE
                    && a.result == MavResult::MAV_RESULT_ACCEPTED)
        });
        let versions = from_vehicle(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)));
        if heartbeats >= 3
            && positions >= 1
            && acks >= 1
            && versions >= 1
            && forwarded_heartbeats >= 3
        {
            break logged;
        }
        if Instant::now() > deadline {
            kill_group(&mut child);
            panic!(
                "within 40 s the tlog held {heartbeats} heartbeats, {positions} positions, {acks} \
                 acks and {versions} autopilot versions from the vehicle, and the --out socket \
                 got {forwarded_heartbeats} heartbeats:\n{}",
                console_text()
            );
        }
        std::thread::sleep(Duration::from_millis(100));
    };
    let still_running = child.try_wait().expect("poll MAVProxy").is_none();
    kill_group(&mut child);
    assert!(still_running, "MAVProxy crashed:\n{}", console_text());

    // The tlog's timestamps are wall-clock µs since the epoch, in order.
    let now_us = SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .expect("clock")
        .as_micros() as u64;
    let stamps: Vec<u64> = logged.iter().map(|(t, _, _)| *t).collect();
    assert!(stamps.is_sorted(), "tlog timestamps out of order");
    assert!(
        stamps
            .iter()
            .all(|&t| t <= now_us && now_us - t < 120_000_000),
        "tlog timestamps are not recent wall-clock times"
    );
    // MAVProxy sent its own heartbeats (logged too) and the command; the vehicle read them all.
    assert!(
        logged
            .iter()
            .any(|(_, sysid, m)| *sysid == 255 && matches!(m, MavMessage::COMMAND_LONG(_)))
    );
    let c = sim.vehicle().counters();
    assert_eq!(c.malformed, 0, "{c:?}");
    assert_eq!(c.refused_commands, 0, "{c:?}");
}

/// MAVProxy, ArduPilot's own ground station, on an ArduCopter-personality vehicle: it names the
/// modes from the HEARTBEAT (`Mode STABILIZE`, its prompt), and its own commands typed on its
/// console — `mode GUIDED`, `arm throttle`, `takeoff 10` — switch the vehicle to GUIDED, arm it
/// and take it off to 10 m above home. MAVProxy reads its commands from a pipe here (no
/// `--daemon`), each written once the previous one took effect.
#[test]
fn mavproxy_switches_an_ardu_copter_to_guided_arms_and_takes_it_off() {
    use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
    use harrier_sim::vehicle::CopterMode;
    use std::io::Write as _;

    require_python_module("MAVProxy", "MAVProxy==1.8.75");
    let copter = Personality::new(Autopilot::ArduPilot, Frame::Multirotor);
    let sim = spawn(
        VehicleConfig::new(1).with_personality(copter),
        &LinkConfig {
            endpoints: vec!["tcpin:127.0.0.1:0".to_owned()],
            signing: None,
        },
    )
    .expect("start the vehicle");
    let api_port = sim.local_addrs()[0].expect("API link listening").port();
    let dir = tempfile::tempdir().expect("temporary directory");
    let tlog = dir.path().join("flight.tlog");
    let console = std::fs::File::create(dir.path().join("mavproxy.out")).expect("console log");
    let mut child = Command::new("python3")
        .args(["-m", "MAVProxy.mavproxy"])
        .arg(format!("--master=tcp:127.0.0.1:{api_port}"))
        .arg(format!("--logfile={}", tlog.display()))
        .arg(format!("--state-basedir={}", dir.path().display()))
        .current_dir(dir.path())
        .stdin(Stdio::piped())
        .stdout(console.try_clone().expect("console log"))
        .stderr(console)
        .process_group(0)
        .spawn()
        .expect("run MAVProxy");
    let console_text =
        || std::fs::read_to_string(dir.path().join("mavproxy.out")).unwrap_or_default();
    let mut stdin = child.stdin.take().expect("MAVProxy's stdin");
    let wait_for = |what: &str, done: &dyn Fn(&str) -> bool, child: &mut std::process::Child| {
        let deadline = Instant::now() + Duration::from_secs(40);
        loop {
            if let Some(status) = child.try_wait().expect("poll MAVProxy") {
                panic!(
                    "MAVProxy exited ({status}) waiting for {what}:\n{}",
                    console_text()
                );
            }
            if done(&console_text()) {
                return;
            }
            if Instant::now() > deadline {
                kill_group(child);
                panic!("no {what} within 40 s:\n{}", console_text());
            }
            std::thread::sleep(Duration::from_millis(100));
        }
    };
    // MAVProxy names the mode of the first HEARTBEAT with ArduCopter's table.
    wait_for(
        "the STABILIZE mode",
        &|c| c.contains("Mode STABILIZE"),
        &mut child,
    );
    writeln!(stdin, "mode GUIDED").expect("type mode GUIDED");
    wait_for(
        "GUIDED",
        &|c| c.contains("Mode GUIDED") && sim.vehicle().mode() == Mode::Copter(CopterMode::Guided),
        &mut child,
    );
    writeln!(stdin, "arm throttle").expect("type arm throttle");
    wait_for(
        "arming",
        &|c| c.contains("ARMED") && sim.vehicle().armed(),
        &mut child,
    );
    writeln!(stdin, "takeoff 10").expect("type takeoff 10");
    wait_for(
        "the climb to 10 m",
        &|_| (sim.vehicle().state().position.z - 10.0).abs() < 0.3,
        &mut child,
    );
    let still_running = child.try_wait().expect("poll MAVProxy").is_none();
    kill_group(&mut child);
    assert!(still_running, "MAVProxy crashed:\n{}", console_text());

    // The acknowledgements MAVProxy logged: GUIDED, arm and takeoff all accepted.
    let logged = read_tlog(&std::fs::read(&tlog).unwrap_or_default());
    for command in [
        MavCmd::MAV_CMD_DO_SET_MODE,
        MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
        MavCmd::MAV_CMD_NAV_TAKEOFF,
    ] {
        assert!(
            logged.iter().any(|(_, sysid, m)| *sysid == 1
                && matches!(m, MavMessage::COMMAND_ACK(a)
                    if a.command == command && a.result == MavResult::MAV_RESULT_ACCEPTED)),
            "no accepted {command:?} in the tlog"
        );
    }
    let v = sim.vehicle();
    assert_eq!(v.mode(), Mode::Copter(CopterMode::Guided));
    assert!(v.armed());
    let c = v.counters();
    assert_eq!(c.malformed, 0, "{c:?}");
    assert_eq!(c.refused_commands, 0, "{c:?}");
}
