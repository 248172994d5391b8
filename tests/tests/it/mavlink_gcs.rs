//! The ground station's MAVLink GCS link and router, with real UDP and TCP, real processes where
//! it matters, and real clients.
//!
//! - `commands_router_and_tlog`: the live server's GCS link on a free UDP port, a harrier-sim
//!   vehicle (in-process, on real sockets) sending to it, a silent fake vehicle (HEARTBEATs only,
//!   never an ACK) and a garbage datagram. `tests/python/gcs_router_client.py` then drives the
//!   vehicle routes with httpx (401, 404, 422, a refused command's ACK result, an accepted arm, a
//!   timeout after three attempts, assignment errors, the counters), and, with pymavlink through
//!   the router's UDP and TCP endpoints, sees the ground station's and every vehicle's HEARTBEAT
//!   and commands vehicle 1 (its COMMAND_ACK comes back through the router). After the server
//!   stops, pymavlink reads the session's `.tlog`, and the session file holds the vehicle's
//!   telemetry, its link events and the commands' outcomes.
//! - `a_killed_simulator_is_lost_then_found`: a `harrier-sim` process killed with SIGKILL is marked
//!   lost 3 ± 0.5 s after its last frame; started again, it is heard again (`recovered`).
//! - `a_lost_vehicle_flies_its_assignment_again`: a `harrier-sim` process assigned to a track
//!   (made from detections the test publishes on Zenoh) is armed, taken off and flown in
//!   OFFBOARD by the guidance; killed, its place in the assignment is `lost`; restarted (on the
//!   ground, disarmed) it speaks from a new address: `waiting`, sent nothing for 2 s, until the
//!   operator accepts it; then the guidance launches it again and it flies the assignment in
//!   OFFBOARD.
//! - `signed_only_link_refuses_unsigned_forged_and_replayed_frames`: the GCS link and router in
//!   MAVLink 2 `signed_only` mode and a `harrier-sim` process with the same key file: commands are
//!   ACKed, pymavlink (same key) sees the ground station and the vehicle through the router and
//!   commands it. Over real UDP, N unsigned frames, N frames signed with another key and N replays
//!   of captured valid frames are sent to the GCS port (HEARTBEATs of new system ids, an "armed"
//!   HEARTBEAT of the disarmed vehicle) and to the router (arm commands): every one is refused and
//!   counted by side and reason in `/metrics`, no vehicle appears, the vehicle stays disarmed.
//! - `router_filters_rate_limit_and_block_per_endpoint`: three harrier-sim vehicles (ATTITUDE at
//!   10 Hz) and two pymavlink clients counting messages for 10 s on two router endpoints, one
//!   filtered (`[[mavlink.router_filter]]`: ATTITUDE ≤ 2 Hz per vehicle, GPS_RAW_INT and
//!   EXTENDED_SYS_STATE blocked, systems 3 and 255 blocked; COMMAND_LONG from its clients
//!   blocked), one not: the limited client gets each vehicle's ATTITUDE at 1.8–2.1 Hz and
//!   nothing blocked, and its three COMMAND_LONGs are never acknowledged; the other gets
//!   everything at the full rate; `harrier_router_filtered_total` counts what the first did not
//!   get and what it could not send.

use std::collections::BTreeMap;
use std::ffi::OsStr;
use std::net::{SocketAddr, UdpSocket};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use harrier_link::frame::{Frame, parse_datagram};
use harrier_link::signing::{Signer, Signing, SigningKey, SigningMode};
use harrier_server::LiveServer;
use harrier_server::config::{
    Config, MavlinkConfig, MessageRef, RouterFilterConfig, SigningConfig,
};
use harrier_server::gcs::LinkEventKind;
use harrier_server::gcs::vehicle::LinkState;
use harrier_server::guidance::{AssignmentState, SlotState};
use harrier_sim::mavlink::MavHeader;
use harrier_sim::mavlink::dialects::common::{
    COMMAND_LONG_DATA, HEARTBEAT_DATA, MavCmd, MavMessage, MavModeFlag, MavType,
};
use harrier_sim::net::{LinkConfig, spawn};
use harrier_sim::vehicle::VehicleConfig;
use harrier_tests::{
    SimProcess, free_tcp_port, publish_standing_target, python_script, require_python_module,
    runtime, wait_with_deadline, within,
};

/// A server with a GCS link and a router on free loopback ports, its Zenoh session listening on
/// `zenoh_port`.
async fn server(record: Option<&Path>, router: Vec<String>) -> LiveServer {
    server_on(record, router, free_tcp_port()).await
}

async fn server_on(record: Option<&Path>, router: Vec<String>, zenoh_port: u16) -> LiveServer {
    let mut config = Config::default();
    config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.zenoh.listen = vec![format!("tcp/127.0.0.1:{zenoh_port}")];
    config.zenoh.tracks_key = String::new();
    config.mavlink = MavlinkConfig {
        router,
        command_timeout_ms: 300,
        ..MavlinkConfig::ephemeral()
    };
    if let Some(p) = record {
        config.recorder.path = p.display().to_string();
    }
    within(20, "start the server", harrier_server::start(&config))
        .await
        .expect("start the server")
}

fn gcs_addr(s: &LiveServer) -> SocketAddr {
    s.link()
        .and_then(|l| l.gcs().next().map(|e| e.addr()))
        .expect("a GCS endpoint")
}

/// Waits until the link has heard vehicle `id`.
async fn heard(s: &LiveServer, id: u8) {
    let mut rx = s.link().expect("link").vehicles.clone();
    within(20, &format!("vehicle {id} heard"), async {
        loop {
            if rx.borrow_and_update().iter().any(|v| v.view.id == id) {
                return;
            }
            rx.changed().await.expect("link running");
        }
    })
    .await;
}

/// A fake vehicle that sends HEARTBEATs as system `id` to `gcs` and never answers anything.
fn silent_vehicle(id: u8, gcs: SocketAddr, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<()> {
    std::thread::spawn(move || {
        let socket = UdpSocket::bind("127.0.0.1:0").expect("bind");
        let mut sequence = 0u8;
        while !stop.load(Ordering::Relaxed) {
            let mut frame = Vec::new();
            let header = MavHeader {
                system_id: id.into(),
                component_id: 1,
                sequence,
            };
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                mavtype: MavType::MAV_TYPE_QUADROTOR,
                ..HEARTBEAT_DATA::DEFAULT
            });
            harrier_sim::mavlink::write_v2_msg(&mut frame, header, &hb).expect("frame");
            let _ = socket.send_to(&frame, gcs);
            sequence = sequence.wrapping_add(1);
            std::thread::sleep(Duration::from_millis(200));
        }
    })
}

#[test]
fn commands_router_and_tlog() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    require_python_module("httpx", "httpx==0.28.1");
    let dir = tempfile::tempdir().expect("temporary directory");
    let db = dir.path().join("gcs.sqlite");
    let rt = runtime();
    let server = rt.block_on(server(
        Some(&db),
        vec!["udpin:127.0.0.1:0".into(), "tcpin:127.0.0.1:0".into()],
    ));
    let gcs = gcs_addr(&server);
    let vehicle = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec![format!("udpout:{gcs}")],
            signing: None,
        },
    )
    .expect("start vehicle 1");
    let stop = Arc::new(AtomicBool::new(false));
    let silent = silent_vehicle(42, gcs, Arc::clone(&stop));
    rt.block_on(async {
        heard(&server, 1).await;
        heard(&server, 42).await;
    });
    // Garbage on the GCS port: counted and skipped.
    UdpSocket::bind("127.0.0.1:0")
        .and_then(|s| s.send_to(b"\xfd\x09garbage, not MAVLink", gcs))
        .expect("send garbage");

    let router: Vec<String> = server
        .link()
        .expect("link")
        .router()
        .map(|e| match e {
            harrier_link::frame::Endpoint::UdpIn(a) => format!("udpout:{a}"),
            other => format!("tcp:{}", other.addr()),
        })
        .collect();
    let api = format!("http://{}", server.local_addr());
    let token = server.token().0.to_owned();
    let mut args = vec![
        "--api".to_owned(),
        api,
        "--token".to_owned(),
        token,
        "--vehicles".to_owned(),
        "1,42".to_owned(),
        "--silent".to_owned(),
        "42".to_owned(),
        "--command".to_owned(),
        "1".to_owned(),
    ];
    for r in &router {
        args.extend(["--connect".to_owned(), r.clone()]);
    }
    let mut child = python_script("gcs_router_client.py")
        .args(&args)
        .spawn()
        .expect("run gcs_router_client.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(120), "gcs_router_client.py");
    assert!(status.success(), "gcs_router_client.py failed: {status}");
    // The router took the client's command to vehicle 1: it disarmed.
    assert!(!vehicle.vehicle().armed());

    stop.store(true, Ordering::Relaxed);
    silent.join().expect("silent vehicle");
    rt.block_on(server.shutdown());
    vehicle.stop();
    let tlog: PathBuf = dir.path().join("gcs-session-1.tlog");
    assert!(tlog.is_file(), "{} missing", tlog.display());
    let mut child = python_script("gcs_router_client.py")
        .args([
            "--tlog",
            &tlog.display().to_string(),
            "--db",
            &db.display().to_string(),
            "--vehicles",
            "1,42",
        ])
        .spawn()
        .expect("run gcs_router_client.py --tlog");
    let status = wait_with_deadline(&mut child, Duration::from_secs(60), "reading the tlog");
    assert!(status.success(), "the .tlog did not read back: {status}");
}

/// `harrier-sim` as vehicle `id`, telemetry to `gcs`, no Zenoh.
fn sim_process(id: u8, gcs: SocketAddr) -> SimProcess {
    SimProcess::start(id, gcs, ["--no-zenoh"])
}

#[test]
fn a_killed_simulator_is_lost_then_found() {
    let rt = runtime();
    rt.block_on(async {
        let server = server(None, Vec::new()).await;
        let gcs = gcs_addr(&server);
        let mut events = server.link().expect("link").events.subscribe();
        let mut next_event = async |what: LinkEventKind| loop {
            let e = within(20, &format!("{what:?}"), events.recv())
                .await
                .expect("link events");
            if e.vehicle == 7 && e.event == what {
                return e;
            }
        };
        let mut sim = sim_process(7, gcs);
        next_event(LinkEventKind::Connected).await;
        // Let it fly its telemetry for a moment, then kill it without warning.
        heard(&server, 7).await;
        sim.kill();
        let killed = Instant::now();
        next_event(LinkEventKind::Lost).await;
        let after = killed.elapsed().as_secs_f64();
        eprintln!("harrier-sim killed: marked lost after {after:.2} s");
        assert!((2.5..=3.5).contains(&after), "lost after {after} s");
        let view = server.link().expect("link").vehicles.borrow().clone();
        assert_eq!(
            view.iter().find(|v| v.view.id == 7).map(|v| v.view.state),
            Some(LinkState::Lost)
        );
        // Started again: heard again.
        let restarted = Instant::now();
        let mut sim = sim_process(7, gcs);
        next_event(LinkEventKind::Recovered).await;
        eprintln!(
            "harrier-sim restarted: recovered after {:.2} s",
            restarted.elapsed().as_secs_f64()
        );
        sim.kill();
        server.shutdown().await;
    });
}

/// Waits until assignment 1's slot of `vehicle` is in `state`.
async fn slot_state(s: &LiveServer, vehicle: u8, state: SlotState) {
    let mut rx = s.guidance().expect("guidance").assignments.clone();
    within(60, &format!("vehicle {vehicle} {state:?}"), async {
        loop {
            let now = rx
                .borrow_and_update()
                .first()
                .and_then(|a| a.vehicles.iter().find(|v| v.vehicle == vehicle))
                .map(|v| v.state);
            if now == Some(state) {
                return;
            }
            rx.changed().await.expect("guidance running");
        }
    })
    .await;
}

#[test]
fn a_lost_vehicle_flies_its_assignment_again() {
    let rt = runtime();
    rt.block_on(async {
        let zenoh_port = free_tcp_port();
        let server = server_on(None, Vec::new(), zenoh_port).await;
        let gcs = gcs_addr(&server);
        let config = harrier_link::bus::BusConfig {
            connect: vec![format!("tcp/127.0.0.1:{zenoh_port}")],
            listen: Vec::new(),
            ..harrier_link::bus::BusConfig::default()
        }
        .to_zenoh()
        .expect("zenoh config");
        let session = within(10, "open a session", zenoh::open(config))
            .await
            .expect("zenoh session");
        let publisher =
            publish_standing_target(&session, 7, [80.0, 0.0], [0.0, 0.0, 30.0], 10.0).await;
        let mut sim = sim_process(7, gcs);
        heard(&server, 7).await;
        let mut snapshot = server.snapshot();
        let track = within(30, "a confirmed track", async {
            loop {
                if let Some(t) = snapshot
                    .borrow_and_update()
                    .tracks
                    .iter()
                    .find(|t| t.status == harrier_engine::TrackStatus::Confirmed)
                {
                    return t.id;
                }
                snapshot.changed().await.expect("tracker running");
            }
        })
        .await;
        let a = server
            .guidance()
            .expect("guidance")
            .create(harrier_server::guidance::AssignmentRequest {
                vehicles: vec![7],
                track,
                law: "togvf".into(),
                radius_m: Some(40.0),
                height_m: Some(20.0),
                spacing_deg: None,
                speed_m_s: Some(5.0),
                orbit: None,
            })
            .await
            .expect("assignment");
        assert_eq!(a.state, AssignmentState::Active);
        slot_state(&server, 7, SlotState::Offboard).await;
        let in_offboard = async {
            let mut rx = server.link().expect("link").vehicles.clone();
            loop {
                let mode = rx
                    .borrow_and_update()
                    .iter()
                    .find(|v| v.view.id == 7)
                    .and_then(|v| v.view.mode.clone());
                if mode.as_deref() == Some("OFFBOARD") {
                    return;
                }
                rx.changed().await.expect("link running");
            }
        };
        within(30, "vehicle 7 in OFFBOARD", in_offboard).await;
        sim.kill();
        let killed = Instant::now();
        slot_state(&server, 7, SlotState::Lost).await;
        eprintln!(
            "assigned harrier-sim killed: slot lost after {:.2} s",
            killed.elapsed().as_secs_f64()
        );
        // Restarted, it speaks from a new address: a new identity, not flown until accepted.
        let mut sim = sim_process(7, gcs);
        let restarted = Instant::now();
        let link = server.link().expect("link");
        let mut rx = link.vehicles.clone();
        within(30, "vehicle 7 heard again, unconfirmed", async {
            loop {
                if rx
                    .borrow_and_update()
                    .iter()
                    .any(|v| v.view.id == 7 && v.view.state == LinkState::Connected && !v.confirmed)
                {
                    return;
                }
                rx.changed().await.expect("link running");
            }
        })
        .await;
        let sent = || {
            link.vehicles
                .borrow()
                .iter()
                .find(|v| v.view.id == 7)
                .map_or(0, |v| v.view.commands_sent)
        };
        let before = sent();
        // Two seconds of guidance ticks (40) that must send it nothing.
        tokio::time::sleep(Duration::from_secs(2)).await;
        assert_eq!(
            sent(),
            before,
            "the guidance commanded an unconfirmed vehicle"
        );
        assert_eq!(
            server
                .guidance()
                .expect("guidance")
                .assignments
                .borrow()
                .first()
                .and_then(|a| a.vehicles.first().map(|s| s.state)),
            Some(SlotState::Waiting)
        );
        assert_eq!(link.accept(7).await, Ok(true));
        slot_state(&server, 7, SlotState::Offboard).await;
        let mut rx = server.link().expect("link").vehicles.clone();
        within(30, "vehicle 7 in OFFBOARD again", async {
            loop {
                let v = rx
                    .borrow_and_update()
                    .iter()
                    .find(|v| v.view.id == 7)
                    .map(|v| (v.view.mode.clone(), v.view.armed));
                if matches!(&v, Some((Some(m), true)) if m == "OFFBOARD") {
                    return;
                }
                rx.changed().await.expect("link running");
            }
        })
        .await;
        eprintln!(
            "restarted harrier-sim flies the assignment again after {:.2} s",
            restarted.elapsed().as_secs_f64()
        );
        sim.kill();
        publisher.abort();
        let _ = session.close().await;
        server.shutdown().await;
    });
}

/// The shared key of the signing test (64 hex characters).
const KEY: &str = "c0ffee00c0ffee00c0ffee00c0ffee00c0ffee00c0ffee00c0ffee00c0ffee00";

fn signer(key: &str, link_id: u8) -> Signer {
    Signing {
        key: SigningKey::from_hex(key).expect("key"),
        mode: SigningMode::SignedOnly,
        link_id,
    }
    .signer()
    .expect("signer")
}

/// The next frames (one datagram) on `socket` (within 5 s).
fn next_frames(socket: &UdpSocket) -> Vec<Frame> {
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut buf = [0u8; 2048];
    while Instant::now() < deadline {
        if let Ok(n) = socket.recv(&mut buf) {
            return parse_datagram(&buf[..n]).frames;
        }
    }
    panic!("nothing received within 5 s");
}

/// The first frame on `socket` satisfying `want` (within 10 s).
fn frame_where(socket: &UdpSocket, want: impl Fn(&Frame) -> bool) -> Frame {
    let deadline = Instant::now() + Duration::from_secs(10);
    while Instant::now() < deadline {
        if let Some(f) = next_frames(socket).into_iter().find(|f| want(f)) {
            return f;
        }
    }
    panic!("no such frame within 10 s");
}

fn is_heartbeat_of(f: &Frame, id: u32) -> Option<bool> {
    match &f.message {
        MavMessage::HEARTBEAT(hb) if f.header.system_id == id => Some(
            hb.base_mode
                .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED),
        ),
        _ => None,
    }
}

fn heartbeat(mavtype: MavType) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        mavtype,
        ..HEARTBEAT_DATA::DEFAULT
    })
}

fn header(system_id: u8, component_id: u8, sequence: u8) -> MavHeader {
    MavHeader {
        system_id: system_id.into(),
        component_id,
        sequence,
    }
}

/// The value of one `/metrics` line (`name{labels}`).
fn metric(s: &LiveServer, series: &str) -> u64 {
    let mut out = String::new();
    s.link().expect("link").render_metrics(&mut out);
    out.lines()
        .find_map(|l| l.strip_prefix(series)?.trim().parse().ok())
        .unwrap_or_else(|| panic!("{series} not in /metrics:\n{out}"))
}

#[test]
fn signed_only_link_refuses_unsigned_forged_and_replayed_frames() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    require_python_module("httpx", "httpx==0.28.1"); // imported by gcs_router_client.py
    const N: u64 = 25;
    let dir = tempfile::tempdir().expect("temporary directory");
    let key_file = dir.path().join("mavlink.key");
    std::fs::write(&key_file, format!("{KEY}\n")).expect("write the key file");
    let rt = runtime();
    let server = rt.block_on(async {
        let mut config = Config::default();
        config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
        config.zenoh.listen = vec![format!("tcp/127.0.0.1:{}", free_tcp_port())];
        config.zenoh.tracks_key = String::new();
        config.mavlink = MavlinkConfig {
            router: vec!["udpin:127.0.0.1:0".into()],
            command_timeout_ms: 300,
            signing: SigningConfig {
                mode: "signed_only".into(),
                key_file: key_file.display().to_string(),
                ..SigningConfig::default()
            },
            ..MavlinkConfig::ephemeral()
        };
        within(20, "start the server", harrier_server::start(&config))
            .await
            .expect("start the server")
    });
    let link = server.link().expect("link").clone();
    let gcs = gcs_addr(&server);
    let router = link.router().next().expect("a router endpoint").addr();
    let _sim = SimProcess::start(
        7,
        gcs,
        [
            OsStr::new("--no-zenoh"),
            OsStr::new("--signing-key-file"),
            key_file.as_os_str(),
        ],
    );
    rt.block_on(heard(&server, 7));

    // A router client signing with the key (link id 2): it becomes a peer and sees vehicle 7's
    // frames, signed by the vehicle and forwarded unchanged.
    let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
    client
        .set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    client.connect(router).expect("connect");
    let me = signer(KEY, 2);
    let verify = signer(KEY, 9);
    let gcs_hb = me.encode(header(200, 191, 0), &heartbeat(MavType::MAV_TYPE_GCS));
    client.send(&gcs_hb.expect("frame")).expect("send");

    // Commands through the API are signed by the ground station and ACKed by the vehicle.
    let arm = rt.block_on(within(
        10,
        "arm",
        link.command(7, harrier_link::command::arm(7)),
    ));
    assert!(arm.expect("arm").ok);
    let armed_hb = frame_where(&client, |f| is_heartbeat_of(f, 7) == Some(true));
    assert_eq!(
        verify.check(&armed_hb),
        Ok(()),
        "the vehicle's frame is not signed with the key"
    );
    let disarm = harrier_link::command::disarm(7, false);
    let disarm = rt.block_on(within(10, "disarm", link.command(7, disarm)));
    assert!(disarm.expect("disarm").ok);
    frame_where(&client, |f| is_heartbeat_of(f, 7) == Some(false));

    // To the GCS port: unsigned and wrongly signed HEARTBEATs of new vehicles, and replays of the
    // vehicle's own "armed" HEARTBEAT; then a good HEARTBEAT of vehicle 60 marks the end (one
    // socket, one endpoint task: handled in order).
    let intruder = UdpSocket::bind("127.0.0.1:0").expect("bind");
    let forger = signer(&"11".repeat(32), 0);
    let quad = heartbeat(MavType::MAV_TYPE_QUADROTOR);
    for i in 0..N {
        let seq = u8::try_from(i).expect("small");
        let unsigned = harrier_link::frame::encode(header(50, 1, seq), &quad).expect("frame");
        let forged = forger.encode(header(51, 1, seq), &quad).expect("frame");
        for frame in [&unsigned, &forged, &armed_hb.bytes] {
            intruder.send_to(frame, gcs).expect("send");
        }
    }
    let last = me.encode(header(60, 1, 0), &quad).expect("frame");
    intruder.send_to(&last, gcs).expect("send");
    rt.block_on(heard(&server, 60));
    for (reason, n) in [("unsigned", N), ("bad_signature", N), ("replay", N)] {
        let series = format!("harrier_mavlink_rejected_total{{side=\"gcs\",reason=\"{reason}\"}}");
        assert_eq!(metric(&server, &series), n, "{series}");
    }
    let ids: Vec<u8> = link.vehicles.borrow().iter().map(|v| v.view.id).collect();
    assert_eq!(ids, [7, 60], "a refused HEARTBEAT made a vehicle");
    let seven = link
        .vehicles
        .borrow()
        .iter()
        .find(|v| v.view.id == 7)
        .map(|v| v.view.armed);
    assert_eq!(seven, Some(false), "a replayed HEARTBEAT armed vehicle 7");

    // To the router: a good arm (captured), a good disarm, then N unsigned, N forged and N
    // replayed arms; a good request's ACK marks the end. The vehicle stays disarmed.
    let ack_of = |cmd: MavCmd| move |f: &Frame| matches!(&f.message, MavMessage::COMMAND_ACK(a) if a.command == cmd && f.header.system_id == 7);
    let command = |param1: f32, command: MavCmd| {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 7,
            target_component: 1,
            command,
            param1,
            ..COMMAND_LONG_DATA::DEFAULT
        })
    };
    let arm_cmd = MavCmd::MAV_CMD_COMPONENT_ARM_DISARM;
    let captured = me
        .encode(header(200, 191, 1), &command(1.0, arm_cmd))
        .expect("frame");
    client.send(&captured).expect("send");
    frame_where(&client, ack_of(arm_cmd));
    frame_where(&client, |f| is_heartbeat_of(f, 7) == Some(true));
    client
        .send(
            &me.encode(header(200, 191, 2), &command(0.0, arm_cmd))
                .expect("frame"),
        )
        .expect("send");
    frame_where(&client, ack_of(arm_cmd));
    frame_where(&client, |f| is_heartbeat_of(f, 7) == Some(false));
    for i in 0..N {
        let seq = u8::try_from(i).expect("small");
        let unsigned = harrier_link::frame::encode(header(200, 191, seq), &command(1.0, arm_cmd))
            .expect("frame");
        let forged = forger
            .encode(header(200, 191, seq), &command(1.0, arm_cmd))
            .expect("frame");
        for frame in [&unsigned, &forged, &captured] {
            client.send(frame).expect("send");
        }
    }
    let request = MavCmd::MAV_CMD_REQUEST_MESSAGE;
    client
        .send(
            &me.encode(header(200, 191, 3), &command(148.0, request))
                .expect("frame"),
        )
        .expect("send");
    frame_where(&client, ack_of(request));
    // The vehicle's next HEARTBEAT: still disarmed.
    let hb = frame_where(&client, |f| is_heartbeat_of(f, 7).is_some());
    assert_eq!(
        is_heartbeat_of(&hb, 7),
        Some(false),
        "a refused arm reached the vehicle"
    );
    for (reason, n) in [("unsigned", N), ("bad_signature", N), ("replay", N)] {
        let series =
            format!("harrier_mavlink_rejected_total{{side=\"router\",reason=\"{reason}\"}}");
        assert_eq!(metric(&server, &series), n, "{series}");
    }

    // pymavlink with the same key through the router: sees the ground station and vehicle 7,
    // commands it (disarm) and gets its ACK.
    let mut child = python_script("gcs_router_client.py")
        .args(["--connect", &format!("udpout:{router}"), "--vehicles", "7"])
        .args(["--command", "7", "--signing-key", KEY])
        .spawn()
        .expect("run gcs_router_client.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(60), "signed router client");
    assert!(
        status.success(),
        "gcs_router_client.py --signing-key failed: {status}"
    );
    // Nothing of it was refused.
    let refused: u64 = ["unsigned", "bad_signature", "replay"]
        .iter()
        .map(|r| {
            metric(
                &server,
                &format!("harrier_mavlink_rejected_total{{side=\"router\",reason=\"{r}\"}}"),
            )
        })
        .sum();
    assert_eq!(refused, 3 * N);
    rt.block_on(server.shutdown());
}

/// Runs `gcs_router_client.py --count` with `args` and returns its `COUNTS` line's messages:
/// `SYSTEM/TYPE` → (number received, rate in Hz).
fn spawn_counting_client(
    args: Vec<String>,
) -> std::thread::JoinHandle<BTreeMap<String, (u64, f64)>> {
    std::thread::spawn(move || {
        use std::io::Read as _;
        let mut child = python_script("gcs_router_client.py")
            .args(&args)
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("run gcs_router_client.py --count");
        let mut stdout = child.stdout.take().expect("stdout");
        let reader = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = stdout.read_to_string(&mut s);
            s
        });
        let status = wait_with_deadline(&mut child, Duration::from_secs(90), "counting client");
        let out = reader.join().unwrap_or_default();
        assert!(
            status.success(),
            "gcs_router_client.py {args:?} failed ({status}): {out}"
        );
        let line = out
            .lines()
            .find_map(|l| l.strip_prefix("COUNTS "))
            .unwrap_or_else(|| panic!("no COUNTS line: {out}"));
        let v: serde_json::Value = serde_json::from_str(line).expect("COUNTS json");
        v["messages"]
            .as_object()
            .expect("messages")
            .iter()
            .map(|(k, m)| {
                let n = m["n"].as_u64().expect("n");
                (k.clone(), (n, m["hz"].as_f64().expect("hz")))
            })
            .collect()
    })
}

/// The router's per-endpoint filters, end to end: three harrier-sim vehicles (ATTITUDE at 10 Hz)
/// and two pymavlink clients counting for 10 s, one on an endpoint with ATTITUDE ≤ 2 Hz, two
/// blocked messages (GPS_RAW_INT by name, EXTENDED_SYS_STATE by id) and systems 3 and 255 (the
/// ground station's HEARTBEAT, `router_heartbeat`) blocked, the other unfiltered; the drops
/// counted in `/metrics` by endpoint and reason.
#[test]
fn router_filters_rate_limit_and_block_per_endpoint() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    require_python_module("httpx", "httpx==0.28.1"); // imported by gcs_router_client.py
    const LIMITED: &str = "udpin:127.0.0.1:0";
    const SECONDS: f64 = 10.0;
    let rt = runtime();
    let server = rt.block_on(async {
        let mut config = Config::default();
        config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
        config.zenoh.listen = vec![format!("tcp/127.0.0.1:{}", free_tcp_port())];
        config.zenoh.tracks_key = String::new();
        config.mavlink = MavlinkConfig {
            // Two endpoints that differ in their address, so that the filter can name one.
            router: vec![LIMITED.into(), "udpin:127.0.0.2:0".into()],
            router_filter: vec![RouterFilterConfig {
                endpoint: LIMITED.into(),
                block_msg: vec![MessageRef::Name("GPS_RAW_INT".into()), MessageRef::Id(245)],
                // The ground station's own frames pass the same filter.
                block_src_sys: vec![3, 255],
                max_rate_hz: BTreeMap::from([("ATTITUDE".to_owned(), 2.0)]),
                // Its clients may not command the vehicles.
                block_msg_in: vec![MessageRef::Name("COMMAND_LONG".into())],
                ..RouterFilterConfig::default()
            }],
            router_heartbeat: true,
            ..MavlinkConfig::ephemeral()
        };
        within(20, "start the server", harrier_server::start(&config))
            .await
            .expect("start the server")
    });
    let started = Instant::now();
    let gcs = gcs_addr(&server);
    let vehicles: Vec<_> = (1..=3)
        .map(|id| {
            spawn(
                VehicleConfig::new(id),
                &LinkConfig {
                    endpoints: vec![format!("udpout:{gcs}")],
                    signing: None,
                },
            )
            .expect("start a vehicle")
        })
        .collect();
    rt.block_on(async {
        for id in 1..=3 {
            heard(&server, id).await;
        }
    });
    let link = server.link().expect("link").clone();
    let router: Vec<SocketAddr> = link.router().map(|e| e.addr()).collect();
    let client = |addr: SocketAddr, vehicles: &str, extra: &[&str]| {
        let mut args: Vec<String> = [
            "--connect",
            &format!("udpout:{addr}"),
            "--vehicles",
            vehicles,
            "--count",
            &SECONDS.to_string(),
            "--gcs-heartbeat",
        ]
        .map(str::to_owned)
        .to_vec();
        args.extend(extra.iter().map(|s| (*s).to_owned()));
        spawn_counting_client(args)
    };
    // The limited client first sends vehicle 1 three disarm commands that must not reach it.
    let limited = client(router[0], "1,2", &["--command", "1", "--blocked"]);
    let open = client(router[1], "1,2,3", &[]);
    let limited = limited.join().expect("limited client");
    let open = open.join().expect("unfiltered client");
    let lifetime = started.elapsed().as_secs_f64();
    let get = |m: &BTreeMap<String, (u64, f64)>, k: &str| m.get(k).copied().unwrap_or((0, 0.0));
    for id in [1, 2] {
        let (n, hz) = get(&limited, &format!("{id}/ATTITUDE"));
        let (n_open, hz_open) = get(&open, &format!("{id}/ATTITUDE"));
        eprintln!(
            "vehicle {id} ATTITUDE: limited client {n} in {SECONDS} s, {hz:.3} Hz; unfiltered \
             {n_open}, {hz_open:.3} Hz"
        );
        assert!(
            (1.8..=2.1).contains(&hz),
            "vehicle {id}: limited ATTITUDE at {hz} Hz"
        );
        assert!(
            hz_open >= 9.0,
            "vehicle {id}: unfiltered ATTITUDE at {hz_open} Hz"
        );
        // Only ATTITUDE is limited: the position comes at the full rate.
        let (_, pos) = get(&limited, &format!("{id}/GLOBAL_POSITION_INT"));
        assert!(pos >= 9.0, "vehicle {id}: GLOBAL_POSITION_INT at {pos} Hz");
    }
    for blocked in ["GPS_RAW_INT", "EXTENDED_SYS_STATE"] {
        for id in [1, 2, 3] {
            let k = format!("{id}/{blocked}");
            assert_eq!(get(&limited, &k).0, 0, "{k} reached the limited client");
            assert!(
                get(&open, &k).0 > 0,
                "{k} did not reach the unfiltered client"
            );
        }
    }
    assert!(
        limited
            .keys()
            .all(|k| !k.starts_with("3/") && !k.starts_with("255/")),
        "system 3 or the ground station reached the limited client: {limited:?}"
    );
    assert!(get(&open, "3/ATTITUDE").0 > 0, "{open:?}");
    assert!(get(&open, "255/HEARTBEAT").0 > 0, "{open:?}");

    // The counters: at least what the unfiltered client got and the limited one did not over
    // the 10 s (10 % less, as the two windows do not quite coincide), at most what the vehicles
    // sent over the server's life.
    let series = |endpoint: SocketAddr, reason: &str| {
        metric(
            &server,
            &format!(
                "harrier_router_filtered_total{{endpoint=\"udpin:{endpoint}\",direction=\"out\",reason=\"{reason}\"}}"
            ),
        ) as f64
    };
    let sum = |m: &BTreeMap<String, (u64, f64)>, want: &dyn Fn(&str) -> bool, hz: bool| -> f64 {
        m.iter()
            .filter(|(k, _)| want(k))
            .map(|(_, &(n, r))| if hz { r } else { n as f64 })
            .sum()
    };
    let is_blocked_msg =
        |k: &str| k.ends_with("/GPS_RAW_INT") || k.ends_with("/EXTENDED_SYS_STATE");
    let is_blocked_sys =
        |k: &str| (k.starts_with("3/") || k.starts_with("255/")) && !is_blocked_msg(k);
    let is_attitude = |k: &str| k == "1/ATTITUDE" || k == "2/ATTITUDE";
    /// Which `SYSTEM/TYPE` keys a reason is about.
    type Pick<'a> = &'a dyn Fn(&str) -> bool;
    let checks: [(&str, Pick<'_>, f64); 3] = [
        ("blocked_msg", &is_blocked_msg, 0.0),
        ("blocked_sys", &is_blocked_sys, 0.0),
        ("rate", &is_attitude, sum(&limited, &is_attitude, false)),
    ];
    for (reason, want, passed) in checks {
        let counted = series(router[0], reason);
        let low = 0.9 * (sum(&open, want, false) - passed);
        let high = 1.2 * sum(&open, want, true) * lifetime + 10.0;
        eprintln!("filtered {reason}: {counted} (window: ≥ {low:.0}; life: ≤ {high:.0})");
        assert!(
            counted > 0.0 && counted >= low && counted <= high,
            "{reason}: {counted}"
        );
    }
    for reason in [
        "not_allowed_msg",
        "blocked_comp",
        "not_allowed_comp",
        "not_allowed_sys",
    ] {
        assert_eq!(series(router[0], reason), 0.0, "{reason}");
    }
    for reason in [
        "blocked_msg",
        "not_allowed_msg",
        "blocked_comp",
        "not_allowed_comp",
        "blocked_sys",
        "not_allowed_sys",
        "rate",
    ] {
        assert_eq!(
            series(router[1], reason),
            0.0,
            "unfiltered endpoint: {reason}"
        );
    }
    // The way in: exactly the three commands, and nothing of what the clients sent else.
    let incoming = |endpoint: SocketAddr, reason: &str| {
        metric(
            &server,
            &format!(
                "harrier_router_filtered_total{{endpoint=\"udpin:{endpoint}\",direction=\"in\",reason=\"{reason}\"}}"
            ),
        )
    };
    assert_eq!(incoming(router[0], "blocked_msg"), 3);
    assert_eq!(incoming(router[1], "blocked_msg"), 0);
    assert_eq!(incoming(router[0], "blocked_sys"), 0);
    rt.block_on(server.shutdown());
    for v in vehicles {
        v.stop();
    }
}
