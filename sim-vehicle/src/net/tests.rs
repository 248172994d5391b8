//! Tests of the links over real loopback sockets: TCP reassembly, replies to their own client,
//! `tcpout` reconnects, garbage, and MAVLink 2 signing.

use std::io::Write;
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use harrier_link::frame::{Frame, parse_datagram};
use harrier_link::signing::{SigningKey, SigningMode};
use mavlink::dialects::common::{
    COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, MavCmd, MavMessage, MavResult,
    PARAM_REQUEST_READ_DATA,
};
use mavlink::{MavHeader, MavlinkReader, MessageData};

use super::*;
use crate::vehicle::VehicleConfig;

fn gcs_frame(msg: &MavMessage, sequence: u8) -> Vec<u8> {
    let header = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence,
    };
    harrier_link::frame::encode(header, msg).expect("serialise")
}

fn command(command: MavCmd, param1: f32, param2: f32) -> MavMessage {
    MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1,
        param2,
        command,
        target_system: 1,
        target_component: 1,
        ..COMMAND_LONG_DATA::DEFAULT
    })
}

/// A blocking TCP client of a test vehicle.
struct Client(MavlinkReader<TcpStream>);

impl Client {
    fn connect(addr: SocketAddr) -> Self {
        let stream = TcpStream::connect(addr).expect("connect");
        stream
            .set_read_timeout(Some(Duration::from_millis(100)))
            .expect("timeout");
        Self(MavlinkReader::new(stream))
    }
    fn write(&mut self, bytes: &[u8]) {
        self.0.get_mut().write_all(bytes).expect("write");
    }
    /// Reads messages until one satisfies `done` (within 5 s); returns all of them.
    fn read_until(&mut self, mut done: impl FnMut(&MavMessage) -> bool) -> Vec<MavMessage> {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut got = Vec::new();
        while Instant::now() < deadline {
            if let Ok((h, m)) = self.0.read_any_message::<MavMessage>() {
                assert_eq!((h.system_id, h.component_id), (1, 1));
                let stop = done(&m);
                got.push(m);
                if stop {
                    return got;
                }
            }
        }
        panic!("no expected message within 5 s; got {got:?}");
    }
}

fn is_ack(m: &MavMessage, command: MavCmd) -> bool {
    matches!(m, MavMessage::COMMAND_ACK(a) if a.command == command)
}

/// Vehicle 1 with one link, `endpoint`, and that link's bound address.
fn vehicle_on(endpoint: &str) -> (SimHandle, SocketAddr) {
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec![endpoint.to_owned()],
            signing: None,
        },
    )
    .expect("spawn");
    let addr = sim.local_addrs()[0].expect("bound");
    (sim, addr)
}

/// Returns once the simulation loop has run a whole tick after this call.
fn wait_one_tick(sim: &SimHandle) {
    let t0 = sim.vehicle().sim_time();
    let deadline = Instant::now() + Duration::from_secs(5);
    while sim.vehicle().sim_time() == t0 {
        assert!(Instant::now() < deadline, "the simulation loop stalled");
        std::thread::yield_now();
    }
}

#[test]
fn tcp_frames_split_over_two_writes_are_reassembled() {
    let (sim, addr) = vehicle_on("tcpin:127.0.0.1:0");
    let mut c = Client::connect(addr);
    // Telemetry flows as soon as the client is connected.
    c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
    let frame = gcs_frame(&command(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0, 0.0), 0);
    let (head, tail) = frame.split_at(frame.len() / 2);
    let mut first = b"garbage".to_vec();
    first.extend_from_slice(head);
    c.write(&first);
    // The loop reads the garbage and the half frame, and waits for the rest.
    wait_one_tick(&sim);
    c.write(tail);
    let got = c.read_until(|m| is_ack(m, MavCmd::MAV_CMD_REQUEST_MESSAGE));
    let Some(MavMessage::COMMAND_ACK(ack)) = got.last() else {
        unreachable!()
    };
    assert_eq!(ack.result, MavResult::MAV_RESULT_ACCEPTED);
    c.read_until(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)));
    assert_eq!(sim.vehicle().counters().malformed, 1);
}

#[test]
fn two_tcp_clients_each_get_only_their_own_replies() {
    let (sim, addr) = vehicle_on("tcpin:127.0.0.1:0");
    let mut a = Client::connect(addr);
    let mut b = Client::connect(addr);
    for c in [&mut a, &mut b] {
        c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
    }
    let ack_a = MavCmd::MAV_CMD_REQUEST_MESSAGE;
    let ack_b = MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL;
    a.write(&gcs_frame(&command(ack_a, 148.0, 0.0), 0));
    a.read_until(|m| is_ack(m, ack_a));
    // A's reply was sent before B's: had it leaked to B, B would read it before its own.
    b.write(&gcs_frame(&command(ack_b, 33.0, 50_000.0), 0));
    let seen_b = b.read_until(|m| is_ack(m, ack_b));
    assert!(!seen_b.iter().any(|m| is_ack(m, ack_a)), "{seen_b:?}");
    assert!(
        !seen_b
            .iter()
            .any(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)))
    );
    // Likewise B's reply would reach A before the answer to A's next request.
    let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
        param_index: -1,
        target_system: 1,
        target_component: 1,
        param_id: "MIS_TAKEOFF_ALT".into(),
    });
    a.write(&gcs_frame(&read, 1));
    let seen_a = a.read_until(|m| matches!(m, MavMessage::PARAM_VALUE(_)));
    assert!(!seen_a.iter().any(|m| is_ack(m, ack_b)), "{seen_a:?}");
    // B's command took effect for everyone: position at 20 Hz.
    let iv = sim.vehicle().stream_interval(GLOBAL_POSITION_INT_DATA::ID);
    assert!(iv.is_some_and(|iv| (iv - 0.05).abs() < 1e-9), "{iv:?}");
    assert_eq!(sim.vehicle().counters().malformed, 0);
}

#[test]
fn tcpout_connects_and_reconnects_after_the_server_drops_it() {
    let server = TcpListener::bind("127.0.0.1:0").expect("listen");
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec![format!("tcpout:{}", server.local_addr().expect("addr"))],
            signing: None,
        },
    )
    .expect("spawn");
    assert_eq!(sim.local_addrs(), &[None]);
    for round in 0..2 {
        let (stream, _) = server.accept().expect("the vehicle connects");
        stream
            .set_read_timeout(Some(Duration::from_millis(100)))
            .expect("timeout");
        let mut c = Client(MavlinkReader::new(stream));
        c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
        c.write(&gcs_frame(
            &command(MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0),
            round,
        ));
        let got = c.read_until(|m| is_ack(m, MavCmd::MAV_CMD_NAV_LAND));
        let Some(MavMessage::COMMAND_ACK(ack)) = got.last() else {
            unreachable!()
        };
        assert_eq!(ack.result, MavResult::MAV_RESULT_DENIED); // not armed
        // Dropping the client closes the connection; the vehicle connects again.
    }
    assert_eq!(sim.vehicle().counters().refused_commands, 2);
}

#[test]
fn tcpout_to_nowhere_does_not_stall_the_vehicle() {
    // A port with no listener: every attempt is refused, the loop keeps running.
    let port = TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("free port")
        .port();
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec![format!("tcpout:127.0.0.1:{port}")],
            signing: None,
        },
    )
    .expect("spawn");
    for _ in 0..20 {
        wait_one_tick(&sim);
    }
}

#[test]
fn garbage_is_counted_and_the_vehicle_keeps_answering() {
    let (sim, addr) = vehicle_on("udpin:127.0.0.1:0");
    let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
    client
        .set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    client
        .send_to(&[0xFD, 9, 0, 0, 1, 2, 3], addr)
        .expect("send");
    client.send_to(b"hello", addr).expect("send");
    // A valid GCS heartbeat makes the client a peer: telemetry follows.
    let hb = MavMessage::HEARTBEAT(mavlink::dialects::common::HEARTBEAT_DATA::DEFAULT);
    let mut frame = Vec::new();
    mavlink::write_v2_msg(
        &mut frame,
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        },
        &hb,
    )
    .expect("serialise");
    client.send_to(&frame, addr).expect("send");
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut got = None;
    let mut rbuf = [0u8; 512];
    while got.is_none() && Instant::now() < deadline {
        if let Ok(n) = client.recv(&mut rbuf) {
            let mut r = MavlinkReader::new(&rbuf[..n]);
            if let Ok((h, MavMessage::HEARTBEAT(_))) = r.read_any_message::<MavMessage>() {
                got = Some(h);
            }
        }
    }
    let h = got.expect("heartbeat within 5 s");
    assert_eq!((h.system_id, h.component_id), (1, 1));
    assert_eq!(sim.vehicle().counters().malformed, 2);
}

/// Vehicle 1 on a loopback `udpin` link signing with key 1 in `mode`, and a UDP client
/// connected to it (100 ms read timeout).
fn signed_vehicle(mode: SigningMode) -> (SimHandle, UdpSocket) {
    let sim = spawn(
        VehicleConfig::new(1),
        &LinkConfig {
            endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            signing: Some(signing(1, mode)),
        },
    )
    .expect("spawn");
    let addr = sim.local_addrs()[0].expect("bound");
    let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
    client
        .set_read_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    client.connect(addr).expect("connect");
    (sim, client)
}

fn signing(key: u8, mode: SigningMode) -> Signing {
    Signing {
        key: SigningKey::new([key; 32]),
        mode,
        link_id: 0,
    }
}

/// The frames of the next datagram from the vehicle (within 5 s).
fn recv_frames(socket: &UdpSocket) -> Vec<Frame> {
    let deadline = Instant::now() + Duration::from_secs(5);
    let mut buf = [0u8; 2048];
    while Instant::now() < deadline {
        if let Ok(n) = socket.recv(&mut buf) {
            return parse_datagram(&buf[..n]).frames;
        }
    }
    panic!("nothing from the vehicle within 5 s");
}

#[test]
fn signed_only_vehicle_refuses_unsigned_forged_and_replayed_frames() {
    const N: u64 = 20;
    let (sim, client) = signed_vehicle(SigningMode::SignedOnly);
    let gcs = signing(1, SigningMode::SignedOnly)
        .signer()
        .expect("signer");
    let intruder = signing(2, SigningMode::SignedOnly)
        .signer()
        .expect("signer");
    let header = |sequence| MavHeader {
        system_id: 255,
        component_id: 190,
        sequence,
    };
    let arm = |on: bool| {
        command(
            MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            f32::from(u8::from(on)),
            0.0,
        )
    };
    // Sends a correctly signed command and returns its signed ACK: every datagram sent
    // before it has been handled by then.
    let confirmed = |msg: &MavMessage, sequence| {
        let frame = gcs.encode(header(sequence), msg).expect("frame");
        client.send(&frame).expect("send");
        loop {
            for f in recv_frames(&client) {
                if let MavMessage::COMMAND_ACK(ack) = &f.message {
                    // The vehicle signs what it sends, with the shared key.
                    assert_eq!(gcs.check(&f), Ok(()));
                    assert_eq!(ack.result, MavResult::MAV_RESULT_ACCEPTED);
                    return frame;
                }
            }
        }
    };
    for i in 0..N {
        let seq = u8::try_from(i).expect("small");
        client
            .send(&gcs_frame(&arm(true), seq))
            .expect("send unsigned");
        client
            .send(&intruder.encode(header(seq), &arm(true)).expect("frame"))
            .expect("send forged");
    }
    // A refused sender is no peer: no telemetry (HEARTBEAT at 1 Hz) in 1.5 s.
    let mut buf = [0u8; 2048];
    let quiet = Instant::now() + Duration::from_millis(1500);
    while Instant::now() < quiet {
        assert!(
            client.recv(&mut buf).is_err(),
            "a refused sender got telemetry"
        );
    }
    assert!(!sim.vehicle().armed());
    let captured = confirmed(&arm(true), 100);
    assert!(sim.vehicle().armed());
    confirmed(&arm(false), 101);
    assert!(!sim.vehicle().armed());
    for _ in 0..N {
        client.send(&captured).expect("replay");
    }
    confirmed(&command(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0, 0.0), 102);
    let c = sim.vehicle().counters();
    assert!(!sim.vehicle().armed(), "a replayed arm armed the vehicle");
    assert_eq!(
        c.rejected,
        Rejections {
            unsigned: N,
            bad_signature: N,
            replay: N
        }
    );
    assert_eq!((c.malformed, c.refused_commands), (0, 0));
    sim.stop();
}

#[test]
fn sign_mode_vehicle_accepts_unsigned_commands_and_signs_its_replies() {
    let (sim, client) = signed_vehicle(SigningMode::Sign);
    let intruder = signing(2, SigningMode::Sign).signer().expect("signer");
    let arm = command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0);
    let forged = intruder
        .encode(
            MavHeader {
                system_id: 255,
                component_id: 190,
                sequence: 0,
            },
            &arm,
        )
        .expect("frame");
    client.send(&forged).expect("send");
    client.send(&gcs_frame(&arm, 1)).expect("send");
    let verify = signing(1, SigningMode::SignedOnly)
        .signer()
        .expect("signer");
    loop {
        let frames = recv_frames(&client);
        if let Some(f) = frames
            .iter()
            .find(|f| matches!(f.message, MavMessage::COMMAND_ACK(_)))
        {
            assert_eq!(verify.check(f), Ok(()));
            break;
        }
    }
    assert!(sim.vehicle().armed());
    let c = sim.vehicle().counters().rejected;
    assert_eq!((c.unsigned, c.bad_signature, c.replay), (0, 1, 0));
    sim.stop();
}

/// Five vehicles on two fleet threads, sending to one ground-station socket: each is heard with
/// its own system id, each answers a command sent to its own address, each counts the ground
/// station's HEARTBEAT, and the frames they count as sent are the frames that arrived.
#[test]
fn a_fleet_runs_many_vehicles_on_few_threads() {
    use mavlink::dialects::common::{HEARTBEAT_DATA, MavAutopilot, MavModeFlag, MavState, MavType};
    use std::sync::atomic::Ordering;
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("bind");
    gcs.set_read_timeout(Some(Duration::from_millis(100)))
        .expect("timeout");
    let to_gcs = format!("udpout:{}", gcs.local_addr().expect("addr"));
    let fleet = spawn_fleet(
        (1..=5)
            .map(|id| {
                let links = LinkConfig {
                    endpoints: vec![to_gcs.clone()],
                    signing: None,
                };
                (VehicleConfig::new(id), links)
            })
            .collect(),
        2,
        Duration::from_millis(10),
    )
    .expect("fleet");
    assert_eq!(fleet.len(), 5);
    // Every vehicle heard, from its own address.
    let mut from = std::collections::BTreeMap::new();
    let mut received = 0u64;
    let mut buf = [0u8; 2048];
    let deadline = Instant::now() + Duration::from_secs(5);
    while from.len() < 5 {
        assert!(Instant::now() < deadline, "heard only {from:?}");
        if let Ok((n, addr)) = gcs.recv_from(&mut buf) {
            for f in parse_datagram(&buf[..n]).frames {
                received += 1;
                from.insert(f.header.system_id, addr);
            }
        }
    }
    let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    });
    for (&id, addr) in &from {
        let mut arm = command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0);
        if let MavMessage::COMMAND_LONG(c) = &mut arm {
            c.target_system = u8::try_from(id).expect("a system id");
        }
        gcs.send_to(&gcs_frame(&heartbeat, 0), addr).expect("send");
        gcs.send_to(&gcs_frame(&arm, 1), addr).expect("send");
    }
    let mut acked = std::collections::BTreeSet::new();
    let deadline = Instant::now() + Duration::from_secs(5);
    while acked.len() < 5 {
        assert!(Instant::now() < deadline, "acknowledged only {acked:?}");
        if let Ok((n, _)) = gcs.recv_from(&mut buf) {
            for f in parse_datagram(&buf[..n]).frames {
                received += 1;
                if is_ack(&f.message, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM) {
                    acked.insert(f.header.system_id);
                }
            }
        }
    }
    for i in 0..5 {
        assert!(fleet.vehicle(i).armed(), "vehicle {} not armed", i + 1);
        assert_eq!(
            fleet.counters(i).gcs_heartbeats.load(Ordering::Relaxed),
            1,
            "vehicle {}",
            i + 1
        );
    }
    // Stopped, every frame sent has arrived (loopback loses nothing at this rate).
    let sent = fleet.stop();
    while let Ok((n, _)) = gcs.recv_from(&mut buf) {
        received += parse_datagram(&buf[..n]).frames.len() as u64;
    }
    assert!(sent > 5, "{sent} sent");
    assert_eq!(sent, received);
}
