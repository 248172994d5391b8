//! CoT out (`[cot]`, docs/cot.md): the live server sends its confirmed tracks to a TAK end point
//! played by `tests/python/cot_listen.py`, which listens on UDP and TCP (loopback, port 0) and
//! decodes every event with takproto, the independent TAK protocol library. The server gets
//! simulated detections of one standing target over Zenoh (10 Hz, jittered by up to 2 m) and
//! sends at 5 Hz to both of the listener's ports; once both have heard enough events, every
//! event is checked against the tracker's snapshot of the same track at the same time (the
//! event's `start`, the estimate's time; the snapshot's tracks are what `GET /api/v1/tracks`
//! serves, checked too): position within 0.5 m, uid `harrier.it.track.<id>` of that track and
//! one uid for the one target throughout, callsign, type and stale time. The publishing vehicle
//! (`cot.vehicles`) comes as friendly air `harrier.it.uav.8` where its platform stands. Run once per encoding:
//! TAK protocol v1 protobuf (mesh on UDP, stream on TCP) and CoT XML (on both), each also to
//! TAK's multicast group 239.2.3.1 when the host can join it. In the XML run the listener
//! closes its TCP connection after 10 events, and the feed must connect again. In the protobuf
//! run the feed also connects over TLS (`tls://`, as to a TAK server's 8089) with a client
//! certificate the listener requires (a test CA made with the openssl command).

use std::collections::BTreeSet;
use std::process::Stdio;
use std::time::Duration;

use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_server::config::{Config, CotEncoding};
use harrier_tests::{
    StandingTargetServer, http_get, json_lines, kill_group, python_script, require_python_module,
    target_bin, test_certificates, track_event, wait_with_deadline,
};
use nalgebra::Vector3;
use serde_json::Value;

/// Events (the track's and the vehicle's) each transport must deliver.
const EVENTS: usize = 40;
/// The acceptance tolerance, m.
const TOLERANCE_M: f64 = 0.5;

/// TAK's mesh multicast group.
const GROUP: &str = "239.2.3.1";

/// One run: `encoding` to the listener's UDP, TCP and (when the host can join it) multicast
/// ports, and with `tls` to its TLS port (client certificates required); with
/// `drop_tcp_after`, the listener closes the first TCP connection after that many events, and
/// the feed must connect again.
fn run(encoding: CotEncoding, drop_tcp_after: usize, tls: bool) {
    require_python_module("takproto", "takproto==3.0.1");
    let dir = tempfile::tempdir().expect("tempdir");
    let mut listener = python_script("cot_listen.py");
    listener
        .args(["--timeout", "90", "--multicast", GROUP])
        .args(["--drop-tcp-after", &drop_tcp_after.to_string()]);
    if tls {
        test_certificates(dir.path(), &["server", "client"]);
        let file = |f: &str| dir.path().join(f).to_string_lossy().into_owned();
        listener
            .args([
                "--tls-cert",
                &file("server.pem"),
                "--tls-key",
                &file("server.key"),
            ])
            .args(["--tls-ca", &file("ca.pem")]);
    }
    let mut listener = listener
        .stdout(Stdio::piped())
        .spawn()
        .expect("start cot_listen.py");
    let rx = json_lines(&mut listener);
    let ready = rx
        .recv_timeout(Duration::from_secs(20))
        .expect("cot_listen.py did not say it listens");
    let (udp, tcp) = (&ready["ready"]["udp"], &ready["ready"]["tcp"]);
    let multicast = ready["ready"]["multicast"].as_u64();
    if multicast.is_none() {
        eprintln!("this host cannot join {GROUP}: multicast not tested");
    }

    let mut config = Config::default();
    config.cot.enabled = true;
    config.cot.hz = 5.0;
    config.cot.encoding = encoding;
    config.cot.uid_prefix = "it".into();
    config.cot.vehicles = true;
    config.cot.destinations = vec![
        format!("udp://127.0.0.1:{udp}"),
        format!("tcp://127.0.0.1:{tcp}"),
    ];
    let mut vias = vec!["udp", "tcp"];
    if let Some(port) = ready["ready"]["tls"].as_u64() {
        config
            .cot
            .destinations
            .push(format!("tls://127.0.0.1:{port}"));
        let file = |f: &str| dir.path().join(f).to_string_lossy().into_owned();
        config.cot.tls_ca = file("ca.pem");
        config.cot.tls_cert = file("client.pem");
        config.cot.tls_key = file("client.key");
        vias.push("tls");
    }
    if let Some(port) = multicast {
        config
            .cot
            .destinations
            .push(format!("udp://{GROUP}:{port}"));
        vias.push("multicast");
    }
    let frame = LocalFrame::new(config.frame.origin);
    // Both encodings' tests run at once: the server listens on free ports only.
    let live = StandingTargetServer::start(config);
    let addr = live.server.local_addr();

    // Every transport delivers EVENTS events (takproto decodes each, or says why not).
    let mut events: Vec<Value> = Vec::new();
    let (mut connections, mut closed) = (0, false);
    let count = |events: &[Value], via: &str| events.iter().filter(|e| e["via"] == via).count();
    while vias.iter().any(|via| count(&events, via) < EVENTS) {
        let Ok(v) = rx.recv_timeout(Duration::from_secs(30)) else {
            kill_group(&mut listener);
            let counts: Vec<_> = vias.iter().map(|v| (v, count(&events, v))).collect();
            panic!("cot_listen.py: 30 s without an event; so far {counts:?}");
        };
        assert!(v.get("error").is_none(), "takproto could not decode: {v}");
        if v.get("uid").is_some() {
            events.push(v);
        } else if v.get("tls_connected").is_some() {
            assert_eq!(v["client_cert"], true, "{v}");
        } else if v.get("connected").is_some() {
            connections += 1;
        } else if v.get("closed").is_some() {
            closed = true;
        }
    }
    kill_group(&mut listener);

    // The REST API serves the snapshot's tracks.
    live.check_rest_tracks();

    let counters = live.server.feed_counters();
    let (_, metrics) = http_get(addr, "/api/v1/metrics");
    assert!(
        metrics.contains("harrier_feed_events_total{feed=\"cot\",event=\"sent\"}"),
        "{metrics}"
    );
    let want_encoding = match encoding {
        CotEncoding::Xml => "xml",
        CotEncoding::Protobuf => "protobuf",
    };
    if drop_tcp_after > 0 {
        assert!(closed, "the listener never closed its TCP connection");
        assert!(connections >= 2, "no reconnection after the close");
        assert!(counters.get("cot", "connects") >= 2);
    } else {
        assert_eq!(connections, 1);
    }
    let mut uids = BTreeSet::new();
    let (mut matched, mut worst) = (0, 0.0_f64);
    let (mut uav_events, mut uav_worst) = (0, 0.0_f64);
    for e in &events {
        assert_eq!(e["encoding"], want_encoding, "{e}");
        let uid = e["uid"].as_str().expect("uid");
        let geo = Geodetic {
            lat_deg: e["lat"].as_f64().expect("lat"),
            lon_deg: e["lon"].as_f64().expect("lon"),
            alt_m: e["hae"].as_f64().expect("hae"),
        };
        let got = frame.to_enu(&geo);
        if uid.starts_with("harrier.it.uav.") {
            // The publishing vehicle, friendly air, where its platform stands.
            assert_eq!(
                uid,
                format!("harrier.it.uav.{}", StandingTargetServer::VEHICLE),
                "{e}"
            );
            assert_eq!(e["type"], "a-f-A", "{e}");
            assert_eq!(e["callsign"], "UAV 8", "{e}");
            let err = (got - Vector3::from(StandingTargetServer::PLATFORM)).norm();
            assert!(err < TOLERANCE_M, "the vehicle {err:.3} m off: {e}");
            uav_worst = uav_worst.max(err);
            uav_events += 1;
            continue;
        }
        let (id, start) = track_event(e);
        uids.insert(uid.to_owned());
        if let Some(p) = live.seen.at(id, start) {
            let err = (got - Vector3::from(p)).norm();
            assert!(
                err < TOLERANCE_M,
                "{uid}: {err:.3} m from the snapshot: {e}"
            );
            worst = worst.max(err);
            matched += 1;
        }
    }
    eprintln!(
        "{want_encoding}: {} events (udp {}, tcp {}, multicast {}, tls {}), {matched} track events matched to the \
         snapshot, worst {worst:.4} m; uids {uids:?}; {connections} TCP connections; cot \
         counters sent {} dropped {} errors {} disconnects {}",
        events.len(),
        count(&events, "udp"),
        count(&events, "tcp"),
        count(&events, "multicast"),
        count(&events, "tls"),
        counters.get("cot", "sent"),
        counters.get("cot", "dropped"),
        counters.get("cot", "errors"),
        counters.get("cot", "disconnects"),
    );
    eprintln!("{uav_events} vehicle events, worst {uav_worst:.4} m from the platform");
    assert!(uav_events > 0, "no vehicle event");
    // One standing target: one track, one uid throughout.
    assert_eq!(uids.len(), 1, "{uids:?}");
    // The snapshot watch may skip a state between two looks; nearly every event is matched.
    let track_events = events.len() - uav_events;
    assert!(
        matched * 10 >= track_events * 9,
        "only {matched} of {track_events} track events matched a snapshot state"
    );
    if drop_tcp_after == 0 {
        assert_eq!(counters.get("cot", "errors"), 0);
    }

    live.stop();
}

#[test]
fn takproto_decodes_the_protobuf_events_over_udp_tcp_and_tls() {
    run(CotEncoding::Protobuf, 0, true);
}

#[test]
fn takproto_decodes_the_xml_events_over_udp_and_tcp_across_a_reconnection() {
    run(CotEncoding::Xml, 10, false);
}

/// The acceptance check (scripts/cot_demo_check.py, BENCHMARKS.md) in short: 30 s of `harrier
/// demo` (this build's binary) with `--cot` to cot_listen.py's UDP and TCP ports, once per
/// encoding, both demos at once. takproto decodes every event; each track event is the API's
/// state of its track at its `start` (the WebSocket's scans and `GET /api/v1/tracks` polled)
/// within 0.5 m, or a coasted prediction the poll did not see (listed by the script, never
/// more than a few); uids `harrier.harrier.track.<id>`, one per track.
#[test]
fn takproto_decodes_every_event_of_a_30_s_demo_where_the_api_says() {
    use std::os::unix::process::CommandExt as _;
    require_python_module("takproto", "takproto==3.0.1");
    require_python_module("websockets", "websockets");
    let dir = tempfile::tempdir().expect("tempdir");
    let summary_file = dir.path().join("summary.json");
    let script =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/cot_demo_check.py");
    let mut child = std::process::Command::new("python3")
        .arg(script)
        .args(["--seconds", "30", "--encoding", "both", "--parallel"])
        .arg("--bin")
        .arg(target_bin("harrier"))
        .arg("--json")
        .arg(&summary_file)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .process_group(0)
        .spawn()
        .expect("start cot_demo_check.py");
    let status = wait_with_deadline(&mut child, Duration::from_secs(100), "cot_demo_check.py");
    let text = std::fs::read_to_string(&summary_file)
        .unwrap_or_else(|e| panic!("cot_demo_check.py ({status}) wrote no summary: {e}"));
    let summary: Value = serde_json::from_str(&text).expect("the summary is JSON");
    let runs = summary["runs"].as_array().expect("runs");
    assert_eq!(runs.len(), 2, "{summary}");
    for (r, encoding) in runs.iter().zip(["xml", "protobuf"]) {
        assert_eq!(r["encoding"], encoding, "{r}");
        assert_eq!(r["failures"], serde_json::json!([]), "{r}");
        assert_eq!(r["error_lines"], 0, "{r}");
        for via in ["udp", "tcp"] {
            // Two cars, confirmed within seconds, at 1 Hz for 30 s.
            let n = r["by_transport"][via].as_u64().unwrap_or(0);
            assert!(n >= 20, "{via}: {n} events: {r}");
        }
        let track_events = r["track_events"].as_u64().expect("track_events");
        let matched = r["matched"].as_u64().expect("matched");
        let coasted = r["unmatched_coasted"].as_u64().expect("unmatched_coasted");
        assert_eq!(r["unexplained"], 0, "{r}");
        assert_eq!(matched + coasted, track_events, "{r}");
        assert!(matched * 100 >= track_events * 95, "{r}");
        assert!(r["worst_m"].as_f64().expect("worst") < TOLERANCE_M, "{r}");
        assert_eq!(r["stable_uids"], true, "{r}");
        let uids = r["uids"].as_object().expect("uids");
        assert!(!uids.is_empty(), "{r}");
        assert!(
            uids.keys().all(|u| u.starts_with("harrier.harrier.track.")),
            "{r}"
        );
    }
    assert!(status.success(), "cot_demo_check.py: {status}: {summary}");
    assert_eq!(summary["ok"], true, "{summary}");
}
