//! One function per fuzz target: it runs one input through the same public functions the product
//! applies to outside data and asserts what must hold for any input (no panic, errors that name
//! the line, finite outputs for accepted inputs).
//!
//! This file is compiled twice: by each fuzz target (`fuzz/fuzz_targets/*.rs`, nightly,
//! cargo-fuzz) and by the stable replay test `tests/tests/it/fuzz_regressions.rs`, which runs every
//! file under `fuzz/regressions/<target>/` and `fuzz/seeds/<target>/` through it. Both include it
//! with `#[path]`, so the two cannot drift apart.

#![allow(dead_code)]

use std::path::Path;
use std::sync::OnceLock;

use harrier_core::detection::{DetectionScan, GeoPoint, TruthSample};
use harrier_core::filter::Extended;
use harrier_core::measurement::{Geometry, TargetSize};
use harrier_core::motion::{ConstantVelocity, TransitionModel};
use harrier_core::scenario::{
    self, FormatError, Scenario, group_by_time, parse_measurements, parse_truth, truth_at,
};
use harrier_core::tracker::format::{MultiScenario, parse_multi_truth};
use harrier_core::tracker::{
    Association, Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, Tracker, TrackerConfig,
};
use harrier_link::ardupilot::TargetMask;
use harrier_link::autopilot::{Personality, VehicleStatus};
use harrier_link::command::Setpoint;
use harrier_link::detections::scan_in_frame;
use harrier_link::frame::{Frame, StreamParser, parse_datagram};
use harrier_link::geo::LocalFrame;
use harrier_sim::mavlink::dialects::common::{
    HEARTBEAT_DATA, MavMessage, SET_POSITION_TARGET_LOCAL_NED_DATA,
};
use harrier_sim::mavlink::{self, MavHeader, MavlinkVersion, Message, MessageData};
use harrier_sim::sensors::{SensorSuite, platform_pose};
use harrier_sim::setup::SimScenario;
use harrier_sim::vehicle::{Vehicle, VehicleConfig};
use harrier_sim::world::World;

/// A fuzz target: its name (the directory under `fuzz/seeds` and `fuzz/regressions`) and body.
pub(crate) type Target = (&'static str, fn(&[u8]));

/// The fuzz targets.
pub(crate) const TARGETS: &[Target] = &[
    ("detections", detections),
    ("scenario", scenario),
    ("vehicle", vehicle),
    ("stream", stream),
    ("sim_scenario", sim_scenario),
    ("link", link),
    ("gcs", gcs),
    ("rest", rest),
];

/// Reads input bytes front to back; past the end every read is 0.
struct Bytes<'a> {
    data: &'a [u8],
}

impl<'a> Bytes<'a> {
    fn is_empty(&self) -> bool {
        self.data.is_empty()
    }
    fn u8(&mut self) -> u8 {
        let (first, rest) = self
            .data
            .split_first()
            .map_or((0, &[][..]), |(f, r)| (*f, r));
        self.data = rest;
        first
    }
    fn take(&mut self, n: usize) -> &'a [u8] {
        let (a, b) = self.data.split_at(n.min(self.data.len()));
        self.data = b;
        a
    }
    fn f32(&mut self) -> f32 {
        let b = self.take(4);
        let mut a = [0; 4];
        a[..b.len()].copy_from_slice(b);
        f32::from_le_bytes(a)
    }
}

// ---------------------------------------------------------------------------------------------
// 1. Detection and truth payloads (Zenoh), and the server-side frame conversion.

/// `DetectionScan::from_json` and `TruthSample::from_json` on the raw payload; an accepted scan
/// must re-validate, survive its own JSON round trip, and convert with `scan_in_frame` into
/// finite numbers in the publisher's and in a distant consumer's frame, whose detections a
/// tracker then takes.
pub(crate) fn detections(data: &[u8]) {
    if let Ok(scan) = DetectionScan::from_json(data) {
        assert_eq!(
            scan.validate(),
            Ok(()),
            "from_json returned an invalid scan"
        );
        let again = DetectionScan::from_json(scan.to_json().as_bytes());
        assert!(again.is_ok(), "a valid scan does not round-trip: {again:?}");
        let frames = [
            LocalFrame::new(scan.origin),
            LocalFrame::new(GeoPoint::new(47.397_742, 8.545_594, 488.0)),
            LocalFrame::new(GeoPoint::new(-33.9, 151.2, 10.0)),
        ];
        let geometries = [
            Geometry::planar(0.0),
            Geometry::planar(-250.0),
            Geometry {
                up_in_state: true,
                plane_z: 0.0,
            },
        ];
        for frame in &frames {
            for &geometry in &geometries {
                let Ok(f) = scan_in_frame(&scan, frame, geometry) else {
                    continue;
                };
                let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
                assert!(
                    finite(f.platform_pos.as_slice()) && finite(f.platform_vel.as_slice()),
                    "non-finite platform in frame: {:?} {:?}",
                    f.platform_pos,
                    f.platform_vel
                );
                for z in &f.detections {
                    assert!(finite(z), "non-finite detection in frame: {z:?}");
                }
                let _ = f.sensor_model(None);
                if let Ok(sensor) = f.sensor_model(Some(TargetSize::Known(2.0))) {
                    track(&f, &sensor);
                }
            }
        }
    }
    if let Ok(truth) = TruthSample::from_json(data) {
        let again = TruthSample::from_json(truth.to_json().as_bytes());
        assert!(again.is_ok(), "a valid truth sample does not round-trip");
        // As the session export does: every target into another frame.
        let from = LocalFrame::new(truth.origin);
        let to = LocalFrame::new(GeoPoint::new(-33.9, 151.2, 10.0));
        let rot = from.rotation_to(&to);
        for g in &truth.targets {
            let p = from.enu_to_frame(
                &to,
                &nalgebra::Vector3::new(g.state[0], g.state[1], g.state[2]),
            );
            let v = rot * nalgebra::Vector3::new(g.state[3], g.state[4], g.state[5]);
            assert!(
                p.iter().chain(v.iter()).all(|x| x.is_finite()),
                "truth {g:?} not finite in another frame: {p:?} {v:?}"
            );
        }
    }
}

/// The ground station's next step: the scan's detections into a fresh multi-target tracker
/// (EKF per track, the live service's default tuning), twice so that tracks are updated. The
/// tracker must not panic and its tracks stay finite.
fn track(f: &harrier_link::detections::FrameScan, sensor: &harrier_core::measurement::SensorModel) {
    fn run<const N: usize>(
        f: &harrier_link::detections::FrameScan,
        sensor: &harrier_core::measurement::SensorModel,
    ) where
        ConstantVelocity<N>: TransitionModel<N>,
    {
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).expect("gate"),
            tentative_gater: Gater::chi2(0.95, 2).expect("gate"),
            confirm: MOfN::new(2, 4).expect("m of n"),
            deleter: Deleter::new(5, 1e5, if N == 4 { 2 } else { 3 }).expect("deleter"),
            association: Association::Gnn,
        };
        let mut tracker: Tracker<_, _, N> = Tracker::new(
            GaussianFilter {
                filter: Extended,
                motion: ConstantVelocity::<N>::new(1.0),
            },
            SinglePointInitiator::new(12.0, 50.0).expect("initiator"),
            config,
        );
        let dets: Vec<&[f64]> = f.detections.iter().map(Vec::as_slice).collect();
        for t in [f.t, f.t + 1.0] {
            let _ = tracker.step_any(t, sensor, &dets);
            for s in tracker.snapshot() {
                assert!(
                    s.estimate
                        .mean
                        .iter()
                        .chain(s.estimate.cov.iter())
                        .all(|x| x.is_finite()),
                    "non-finite track {s:?}"
                );
            }
        }
    }
    if f.geometry.up_in_state {
        run::<6>(f, sensor);
    } else {
        run::<4>(f, sensor);
    }
}

// ---------------------------------------------------------------------------------------------
// 2. The scenario directory format (gcs-scenario/1 and FORMAT-MULTI).

/// Separates `scenario.json`, `measurements.jsonl` and `truth.csv` in one fuzz input.
pub(crate) const FILE_SEPARATOR: char = '\u{1e}';

/// A scenario with one sensor of every kind, for measurement lines when the input's own
/// `scenario.json` does not parse.
const REFERENCE_SCENARIO: &str = r#"{"format":"gcs-scenario/1","name":"fuzz","dims":3,
 "time":{"t0":0,"dt":0.5,"t_end":20},"target":{"id":"multi","size_m":4.5},
 "targets":[{"id":"a"},{"id":"b"}],
 "sensors":[
  {"id":"p2","platform":"u","kind":"position","ncomp":2,"noise":{"type":"gaussian","std":[1,1]}},
  {"id":"p3","platform":"u","kind":"position","noise":{"type":"bounded","bound":[1,1,1]}},
  {"id":"rb","platform":"u","kind":"range_bearing","noise":{"type":"gaussian","std":[5,0.01]}},
  {"id":"ae","platform":"u","kind":"az_el","noise":{"type":"gaussian","std":[0.01,0.01]}},
  {"id":"bs","platform":"u","kind":"bearing_size","noise":{"type":"gaussian","std":[0.01,0.01,0.001]}}]}"#;

fn reference() -> &'static (Scenario, MultiScenario) {
    static R: OnceLock<(Scenario, MultiScenario)> = OnceLock::new();
    R.get_or_init(|| {
        let sc = Scenario::parse(REFERENCE_SCENARIO).expect("reference scenario");
        let multi = MultiScenario::parse(REFERENCE_SCENARIO, "", None).expect("reference multi");
        (sc, multi)
    })
}

/// A line-oriented file's error must name a line of the file (1 when the file is empty).
fn names_a_line(e: &FormatError, text: &str) {
    let lines = text.lines().count().max(1);
    match e.line {
        Some(l) => assert!(
            (1..=lines).contains(&l),
            "error names line {l} of a {lines}-line file: {e}"
        ),
        None => panic!("error names no line: {e}"),
    }
}

fn use_measurements(meas: &[scenario::Measurement]) {
    let groups = group_by_time(meas);
    assert!(groups.windows(2).all(|w| w[0].0 <= w[1].0));
    for m in meas {
        let _ = m.is_finite();
    }
}

fn use_truth(rows: &[scenario::TruthRow]) {
    for t in [f64::NEG_INFINITY, -1.0, 0.0, 0.5, 1.0, 1e9, f64::NAN] {
        let _ = truth_at(rows, t);
    }
    if let Some(r) = rows.first() {
        let _ = truth_at(rows, r.t);
    }
}

/// `scenario.json ␞ measurements.jsonl ␞ truth.csv` through `Scenario::parse`,
/// `parse_measurements` (against the input's scenario and a reference one), `parse_truth`,
/// `MultiScenario::parse` and `parse_multi_truth`. Errors of the line-oriented files must name
/// a line within the file.
pub(crate) fn scenario(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let mut parts = text.splitn(3, FILE_SEPARATOR);
    let json = parts.next().unwrap_or("");
    let meas = parts.next().unwrap_or("");
    let truth = parts.next().unwrap_or("");
    let (ref_sc, ref_multi) = reference();

    match parse_measurements(meas, ref_sc) {
        Ok(m) => use_measurements(&m),
        Err(e) => names_a_line(&e, meas),
    }
    match parse_truth(truth) {
        Ok(rows) => use_truth(&rows),
        Err(e) => names_a_line(&e, truth),
    }
    match parse_multi_truth(truth, &ref_multi.targets) {
        Ok(per_target) => per_target.iter().for_each(|r| use_truth(r)),
        Err(e) => names_a_line(&e, truth),
    }

    let Ok(sc) = Scenario::parse(json) else {
        return;
    };
    let _ = (sc.plane_z(), sc.active_dims(), sc.accel_q());
    for s in &sc.sensors {
        let _ = (s.dim(), s.noise.std());
    }
    if let Some(p) = &sc.prior {
        for i in 0..p.dims().len() {
            let _ = p.variance(i);
        }
    }
    match parse_measurements(meas, &sc) {
        Ok(m) => use_measurements(&m),
        Err(e) => names_a_line(&e, meas),
    }
    if let Ok(m) = MultiScenario::parse(json, meas, Some(truth)) {
        let _ = m.truth_at(sc.time.t0);
        assert!(m.scans.windows(2).all(|w| w[0].t < w[1].t));
    }
}

// ---------------------------------------------------------------------------------------------
// 3. The simulator: MAVLink command handling, the TCP stream parser, scenario files.

/// Messages a vehicle answers or may receive, by id (MAVLink common).
const MESSAGE_IDS: &[u32] = &[
    0,   // HEARTBEAT
    11,  // SET_MODE
    20,  // PARAM_REQUEST_READ
    21,  // PARAM_REQUEST_LIST
    23,  // PARAM_SET
    66,  // REQUEST_DATA_STREAM
    75,  // COMMAND_INT
    76,  // COMMAND_LONG
    84,  // SET_POSITION_TARGET_LOCAL_NED
    86,  // SET_POSITION_TARGET_GLOBAL_INT
    111, // TIMESYNC
    4,   // PING
    77,  // COMMAND_ACK
    30,  // ATTITUDE
    33,  // GLOBAL_POSITION_INT
];

/// A message from fuzz bytes: its id from a short list (or any id), then its payload, decoded as
/// a receiver decodes a frame's payload.
fn message(b: &mut Bytes<'_>, version: MavlinkVersion) -> Option<MavMessage> {
    let sel = b.u8();
    let id = if sel == 255 {
        u32::from(b.u8()) | (u32::from(b.u8()) << 8)
    } else {
        MESSAGE_IDS[usize::from(sel) % MESSAGE_IDS.len()]
    };
    let len = usize::from(b.u8());
    MavMessage::parse(version, id, b.take(len)).ok()
}

/// The frame a sender puts on the wire for `msg`.
fn frame(msg: &MavMessage, version: MavlinkVersion, sequence: u8) -> Vec<u8> {
    let header = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence,
    };
    let mut out = Vec::new();
    let r = match version {
        MavlinkVersion::V1 => mavlink::write_v1_msg(&mut out, header, msg),
        MavlinkVersion::V2 => mavlink::write_v2_msg(&mut out, header, msg),
    };
    assert!(r.is_ok(), "cannot frame {msg:?}");
    out
}

fn check_vehicle(v: &Vehicle) {
    let s = v.state();
    assert!(
        s.position
            .iter()
            .chain(s.velocity.iter())
            .all(|x| x.is_finite()),
        "vehicle state not finite: {s:?}"
    );
    assert!(s.position.z >= 0.0, "vehicle below ground: {s:?}");
    assert!(v.attitude().iter().all(|x| x.is_finite()));
    let g = v.position();
    assert!(g.lat_deg.is_finite() && g.lon_deg.is_finite() && g.alt_m.is_finite());
}

fn deliver(v: &mut Vehicle, now: f64, msg: &MavMessage) {
    for reply in v.handle(now, msg) {
        let _ = frame(&reply, MavlinkVersion::V2, 0);
    }
    check_vehicle(v);
}

/// One vehicle (`Vehicle::new(VehicleConfig::new(1), 0)`, of the personality the first byte's two
/// low bits name: airframe, then PX4 or ArduPilot) driven by a program in the input:
/// physics ticks, messages decoded from payload bytes (v1 and v2), raw bytes through the TCP
/// link's `StreamParser`, and messages re-framed with a checksum through the parser in pieces.
/// The vehicle's state stays finite and above ground; replies and telemetry can be framed.
pub(crate) fn vehicle(data: &[u8]) {
    let mut b = Bytes { data };
    let kind = b.u8();
    let airframe = if kind & 1 == 0 {
        harrier_sim::vehicle::Airframe::Multirotor
    } else {
        harrier_sim::vehicle::Airframe::FixedWing
    };
    let autopilot = if kind & 2 == 0 {
        harrier_link::autopilot::Autopilot::Px4
    } else {
        harrier_link::autopilot::Autopilot::ArduPilot
    };
    let mut v = Vehicle::new(
        VehicleConfig {
            airframe,
            autopilot,
            ..VehicleConfig::new(1)
        },
        0.0,
    );
    let mut parser = StreamParser::default();
    let mut now = 0.0;
    let mut steps = 0;
    while !b.is_empty() && steps < 512 {
        steps += 1;
        match b.u8() % 6 {
            0 => {
                now += match b.u8() {
                    255 => 1e6,
                    254 => 30.0,
                    d => f64::from(d) * 0.02,
                };
                v.advance(now);
                for m in v.telemetry(now) {
                    let _ = frame(&m, MavlinkVersion::V2, 0);
                }
                check_vehicle(&v);
            }
            op @ (1 | 2) => {
                let version = if op == 1 {
                    MavlinkVersion::V2
                } else {
                    MavlinkVersion::V1
                };
                if let Some(m) = message(&mut b, version) {
                    deliver(&mut v, now, &m);
                }
            }
            3 => {
                let len = usize::from(b.u8());
                let parsed = parser.push(b.take(len));
                for f in &parsed.frames {
                    deliver(&mut v, now, &f.message);
                }
            }
            4 | 5 => {
                let Some(m) = message(&mut b, MavlinkVersion::V2) else {
                    continue;
                };
                let version = if b.u8() & 1 == 0 {
                    MavlinkVersion::V2
                } else {
                    MavlinkVersion::V1
                };
                if version == MavlinkVersion::V1 && m.message_id() > 255 {
                    continue;
                }
                let bytes = frame(&m, version, b.u8());
                let cut = usize::from(b.u8()) % (bytes.len() + 1);
                for piece in [&bytes[..cut], &bytes[cut..]] {
                    for f in parser.push(piece).frames {
                        deliver(&mut v, now, &f.message);
                    }
                }
            }
            _ => unreachable!(),
        }
    }
    let _ = v.counters();
}

/// The payload bytes of `m` as `version` carries them.
fn payload(m: &MavMessage, version: MavlinkVersion) -> (u32, Vec<u8>) {
    let mut buf = [0u8; 255];
    let n = m.ser(version, &mut buf);
    (m.message_id(), buf[..n].to_vec())
}

/// harrier-link's `StreamParser` (the TCP links of the simulator and the ground station) and
/// `parse_datagram` (UDP) against an oracle: a stream of valid frames (v1 and v2) and garbage that
/// holds no start-of-frame byte, delivered in pieces of fuzzed sizes, must give back exactly the
/// frames — bytes, header, version and message — in order; raw fuzz bytes anywhere switch the
/// oracle off. What waits for the rest of a frame never exceeds one frame.
pub(crate) fn stream(data: &[u8]) {
    let mut b = Bytes { data };
    let mut wire = Vec::new();
    // (version, sequence, (message id, payload), frame bytes) of every frame put on the wire.
    type Sent = (MavlinkVersion, u8, (u32, Vec<u8>), Vec<u8>);
    let mut expected: Vec<Sent> = Vec::new();
    let mut exact = true;
    let mut pieces = Vec::new();
    while !b.is_empty() && wire.len() < 64 * 1024 {
        match b.u8() % 4 {
            0 => {
                let len = usize::from(b.u8());
                wire.extend(b.take(len).iter().map(|&x| match x {
                    0xFD | 0xFE => 0x00,
                    x => x,
                }));
            }
            1 => {
                let version = if b.u8() & 1 == 0 {
                    MavlinkVersion::V2
                } else {
                    MavlinkVersion::V1
                };
                let Some(m) = message(&mut b, version) else {
                    continue;
                };
                if version == MavlinkVersion::V1 && m.message_id() > 255 {
                    continue;
                }
                let sequence = b.u8();
                let bytes = frame(&m, version, sequence);
                wire.extend_from_slice(&bytes);
                expected.push((version, sequence, payload(&m, version), bytes));
            }
            2 => {
                let len = usize::from(b.u8());
                wire.extend_from_slice(b.take(len));
                exact = false;
            }
            _ => pieces.push(usize::from(b.u8()) + 1),
        }
    }
    if pieces.is_empty() {
        pieces.push(wire.len().max(1));
    }
    let mut parser = StreamParser::default();
    let mut got: Vec<Frame> = Vec::new();
    let mut at = 0;
    for size in pieces.iter().cycle() {
        if at >= wire.len() {
            break;
        }
        let end = (at + size).min(wire.len());
        let parsed = parser.push(&wire[at..end]);
        at = end;
        assert!(
            parser.pending() <= mavlink::consts::MAX_FRAME_SIZE,
            "{} bytes pending",
            parser.pending()
        );
        got.extend(parsed.frames);
    }
    let datagram = parse_datagram(&wire);
    for f in got.iter().chain(&datagram.frames) {
        let _ = f.target_system();
    }
    if exact {
        for frames in [&got, &datagram.frames] {
            assert_eq!(frames.len(), expected.len(), "frames lost or invented");
            for (f, (version, sequence, want, bytes)) in frames.iter().zip(&expected) {
                assert_eq!(f.version, *version);
                assert_eq!(f.header.sequence, *sequence);
                assert_eq!(f.header.system_id, 255);
                assert_eq!(&f.bytes, bytes, "frame bytes altered");
                assert_eq!(&payload(&f.message, *version), want, "message altered");
            }
        }
    }
}

/// `SimScenario::from_json` (the `--scenario FILE` of harrier-sim); an accepted scenario must
/// build its world and sensors, give finite truth, and publish scans that pass the ground
/// station's `DetectionScan::validate`.
pub(crate) fn sim_scenario(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let Ok(sc) = SimScenario::from_json(text, Path::new("fuzz.json")) else {
        return;
    };
    let _ = sc.to_json();
    let Ok(mut world) = World::new(&sc, 7) else {
        return;
    };
    let Ok(mut sensors) = SensorSuite::new(&sc, 7, 1) else {
        return;
    };
    let vehicle = Vehicle::new(VehicleConfig::new(1), 0.0);
    let pose = platform_pose(&vehicle);
    let origin = sc.origin;
    for t in [0.0, 0.25, 1.0, 2.5] {
        world.advance(t);
        for target in world.truth() {
            assert!(
                target.state.iter().all(|x| x.is_finite()),
                "non-finite truth {target:?}"
            );
        }
        for scan in sensors.scan(t, 1, &pose, origin, &world) {
            assert_eq!(scan.validate(), Ok(()), "the simulator published {scan:?}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 4. harrier-link's MAVLink decoders.

/// `Setpoint::from_message`, ArduPilot's `TargetMask::of`, every personality's
/// `requested_mode` / `decode` and `VehicleStatus::from_heartbeat` on fuzzed fields; a decoded
/// setpoint or mode encodes back to itself.
pub(crate) fn link(data: &[u8]) {
    let mut b = Bytes { data };
    while !b.is_empty() {
        match b.u8() % 3 {
            0 => {
                let bytes = b.take(SET_POSITION_TARGET_LOCAL_NED_DATA::ENCODED_LEN);
                let Ok(s) = SET_POSITION_TARGET_LOCAL_NED_DATA::deser(MavlinkVersion::V2, bytes)
                else {
                    continue;
                };
                let _ = TargetMask::of(s.type_mask);
                if let Some(sp) = Setpoint::from_message(&s) {
                    let (Setpoint::Position(v) | Setpoint::Velocity(v)) = sp;
                    assert!(v.iter().all(|x| x.is_finite()));
                    let MavMessage::SET_POSITION_TARGET_LOCAL_NED(back) = sp.to_message(1) else {
                        panic!("to_message gave another message");
                    };
                    assert_eq!(Setpoint::from_message(&back), Some(sp));
                }
            }
            1 => {
                let (p1, p2, p3) = (b.f32(), b.f32(), b.f32());
                let personalities = ["px4-mc", "px4-fw", "ardupilot-mc", "ardupilot-fw"]
                    .into_iter()
                    .filter_map(Personality::from_label);
                for p in personalities {
                    if let Ok(mode) = p.requested_mode(p1, p2, p3) {
                        let [q1, q2, q3] = mode.set_mode_params();
                        assert_eq!(p.requested_mode(q1, q2, q3), Ok(mode));
                    }
                    if let Some(mode) = p.decode(p1.to_bits()) {
                        assert_eq!(p.decode(mode.custom_mode()), Some(mode));
                        assert_eq!(p.mode_named(mode.name()), Some(mode));
                    }
                }
            }
            _ => {
                let bytes = b.take(HEARTBEAT_DATA::ENCODED_LEN);
                if let Ok(hb) = HEARTBEAT_DATA::deser(MavlinkVersion::V2, bytes) {
                    let _ = VehicleStatus::from_heartbeat(&hb, f64::from(b.u8()));
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// 7. The ground station's MAVLink link: what a vehicle's frames do to its state.

/// Frames from the wire (`parse_datagram`, as the GCS endpoint tasks do) or decoded from fuzzed
/// payloads, fed to the server's per-vehicle link state (`VehicleLink::on_frame`) with fuzzed
/// headers and times, then `check` (lost detection) and `view` (what `/vehicles` serves): every
/// number in the view is finite (JSON has no NaN), the rate and loss are within their ranges,
/// and a lost vehicle that speaks again is connected.
pub(crate) fn gcs(data: &[u8]) {
    use harrier_server::gcs::transport::Peer;
    use harrier_server::gcs::vehicle::{LinkState, VehicleLink};
    use std::time::{Duration, Instant};

    let mut b = Bytes { data };
    let start = Instant::now();
    let mut now = start;
    let peer = Peer::Udp(std::net::SocketAddr::from(([127, 0, 0, 1], 14540)));
    let mut v = VehicleLink::new(1, 0, peer, now);
    let frame = LocalFrame::new(GeoPoint::new(47.397_742, 8.545_594, 488.0));
    let mut steps = 0;
    while !b.is_empty() && steps < 256 {
        steps += 1;
        let mut frames: Vec<(MavHeader, MavMessage)> = Vec::new();
        match b.u8() % 4 {
            0 => {
                let len = usize::from(b.u8()) + usize::from(b.u8());
                let datagram = b.take(len);
                let parsed = parse_datagram(datagram);
                frames.extend(parsed.frames.into_iter().map(|f| (f.header, f.message)));
            }
            1 => {
                let header = MavHeader {
                    system_id: 1,
                    component_id: b.u8(),
                    sequence: b.u8(),
                };
                if let Some(m) = message(&mut b, MavlinkVersion::V2) {
                    frames.push((header, m));
                }
            }
            2 => {
                now += match b.u8() {
                    255 => Duration::from_secs(3600),
                    d => Duration::from_millis(u64::from(d) * 20),
                };
                let was = v.state();
                let lost = v.check(now, 3.0);
                assert!(!lost || was != LinkState::Lost, "lost twice");
            }
            _ => {
                let _ = v.kinematics(&frame);
            }
        }
        for (header, m) in frames {
            let was = v.state();
            let t = now.duration_since(start).as_secs_f64();
            let back = v.on_frame(&header, &m, now, t);
            assert_eq!(back, was == LinkState::Lost, "recovered flag wrong");
            assert_eq!(v.state(), LinkState::Connected);
        }
        let view = v.view(&frame, now);
        let json = serde_json::to_value(&view).expect("a view serialises");
        assert_no_null_numbers(&json, &view);
        assert!((0.0..=100.0).contains(&view.loss_pct), "{view:?}");
        assert!(view.rate_hz >= 0.0 && view.last_seen_s >= 0.0, "{view:?}");
    }
}

/// Every number of the view is finite: `serde_json` writes a NaN or an infinity as `null`,
/// which is not a number to the API's clients.
fn assert_no_null_numbers(
    json: &serde_json::Value,
    view: &harrier_server::gcs::vehicle::VehicleLinkView,
) {
    let finite = |v: &[f64]| v.iter().all(|x| x.is_finite());
    let opt = |x: Option<f64>| x.is_none_or(f64::is_finite);
    assert!(
        view.position.is_none_or(|p| finite(&p))
            && view.velocity.is_none_or(|p| finite(&p))
            && view.attitude_deg.is_none_or(|p| finite(&p))
            && opt(view.heading_deg)
            && opt(view.relative_alt_m)
            && opt(view.battery_pct)
            && opt(view.battery_v)
            && view.geodetic.is_none_or(|g| g.lat_deg.is_finite()
                && g.lon_deg.is_finite()
                && g.alt_m.is_finite()),
        "non-finite number in the vehicle view: {json}"
    );
}

// ---------------------------------------------------------------------------------------------
// 8. REST request bodies.

/// The JSON bodies of the mutating routes through the functions their handlers call:
/// `POST /assignments` (`AssignmentRequest::plan`: an accepted plan is finite and inside the
/// envelope), `POST /vehicles/{id}/commands` (`CommandRequest::messages`, for every autopilot
/// and airframe: an accepted command frames and parses back to itself) and `PUT /estimator` (the
/// estimator built from the name and
/// parameters, as the tracker does, then run on a scan: finite tracks or an error).
pub(crate) fn rest(data: &[u8]) {
    use harrier_server::guidance::{AssignmentRequest, GuidanceSettings};
    use harrier_server::http::estimator::EstimatorChange;
    use harrier_server::http::vehicles::CommandRequest;

    let Some((&which, body)) = data.split_first() else {
        return;
    };
    match which % 3 {
        0 => {
            let Ok(r) = serde_json::from_slice::<AssignmentRequest>(body) else {
                return;
            };
            let settings = GuidanceSettings {
                rate_hz: 20.0,
                multirotor: harrier_core::guidance::Limits::multirotor(),
                fixed_wing: harrier_core::guidance::Limits::bank_limited(10.0, 20.0, 0.8, 5.0),
                frame: harrier_link::geo::LocalFrame::new(harrier_link::geo::Geodetic::new(
                    47.0, 8.0, 400.0,
                )),
                speed: 10.0,
                takeoff_height: 30.0,
                obstacles: Vec::new(),
                envelope: harrier_server::guidance::Envelope::default(),
            };
            if let Ok(p) = r.plan(&settings, &[]) {
                assert!(
                    p.radius.is_finite()
                        && p.radius > 0.0
                        && p.height.is_finite()
                        && p.height > 0.0,
                    "{p:?}"
                );
                assert!(
                    p.speed.is_finite() && p.speed > 0.0 && p.speed <= settings.multirotor.v_max
                );
                let spacing = p.spacing_of(r.vehicles.len());
                assert!(spacing.is_finite() && spacing > 0.0);
                assert!(!r.vehicles.is_empty() && !r.vehicles.contains(&0));
            }
        }
        1 => {
            let Ok(r) = serde_json::from_slice::<CommandRequest>(body) else {
                return;
            };
            let personalities = ["px4-mc", "px4-fw", "ardupilot-mc", "ardupilot-fw"]
                .into_iter()
                .filter_map(harrier_link::autopilot::Personality::from_label);
            for (home, p) in personalities.flat_map(|p| [(None, p), (Some(488.0), p)]) {
                let Ok((first, then)) = r.messages(7, home, p) else {
                    continue;
                };
                for m in std::iter::once(first).chain(then) {
                    let bytes = frame(&m, MavlinkVersion::V2, 0);
                    let parsed = parse_datagram(&bytes);
                    assert_eq!((parsed.frames.len(), parsed.malformed), (1, 0));
                    // NaN parameters (MAVLink's "unset") make `==` useless: compare the bytes.
                    assert_eq!(
                        frame(&parsed.frames[0].message, MavlinkVersion::V2, 0),
                        bytes
                    );
                    assert_eq!(harrier_link::frame::target_system(&m), Some(7));
                }
            }
        }
        _ => {
            let Ok(change) = serde_json::from_slice::<EstimatorChange>(body) else {
                return;
            };
            estimator_change(&change);
        }
    }
}

/// Builds the estimator of a `PUT /estimator` body as the tracker does and runs it on two scans.
fn estimator_change(change: &harrier_server::http::estimator::EstimatorChange) {
    use harrier_engine::{Deployment, Params, SensorScan};
    static DEPLOYMENT: OnceLock<Deployment> = OnceLock::new();
    let deployment =
        DEPLOYMENT.get_or_init(|| harrier_server::config::Config::default().deployment());
    let params = Params::from(&change.params);
    let Ok(mut engine) =
        harrier_engine::registry::build_track_filter(&change.name, deployment, &params)
    else {
        return;
    };
    let sensor = harrier_core::measurement::SensorModel::new(
        harrier_core::measurement::MeasKind::Position,
        Geometry::planar(0.0),
        nalgebra::Vector3::zeros(),
        &[5.0, 5.0],
        None,
    )
    .expect("a position sensor");
    for (k, t) in [0.0, 0.5, 1.0].into_iter().enumerate() {
        let scan = SensorScan {
            t,
            sensor,
            detections: vec![vec![100.0 + 5.0 * k as f64, -20.0]],
        };
        let _ = engine.ingest(&scan);
        for track in engine.snapshot() {
            assert!(
                track
                    .state
                    .iter()
                    .chain(track.cov.iter().flatten())
                    .all(|x| x.is_finite()),
                "{}: non-finite track {track:?} with {:?}",
                change.name,
                change.params
            );
        }
    }
}
