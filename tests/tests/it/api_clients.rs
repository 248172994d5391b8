//! The live server's API driven by real external clients, against a server fed by harrier-sim
//! over real Zenoh (two vehicles of the `cimm-road` world, sped up 10×, the CIMM track engine):
//!
//! - `tests/python/test_api_client.py` (pytest + httpx + websockets), a user's script: lists
//!   tracks, reads one, changes the estimator (401 without or with a wrong token, 400 on a body
//!   that is not JSON, 422 naming the field or the unknown estimator, 200 with the token and the
//!   tracks kept), sends every mutating route of the OpenAPI document without, with a wrong, a
//!   malformed and an expired token (401 each, counted by reason) and with both valid tokens,
//!   checks that CORS gives another origin nothing, watches the WebSocket (a snapshot, then scan messages with consecutive `seq`),
//!   subscribes to the tracks on Zenoh with eclipse-zenoh, and publishes bad payloads (garbage,
//!   NaN, negative noise, a short `z`) that `/metrics` must count by reason while tracking goes on,
//!   and reads the session being recorded (its scans, tracks and the API actions) and its export
//!   as `gcs-scenario/1`;
//! - schemathesis against `/api/openapi.json`, every check but two (see the test): no 5xx, every
//!   status, content type, header and body as documented;
//! - afterwards `/metrics` counts the refused requests, and tracking went on.
//!
//! `the_openapi_document_is_valid_openapi_3_1`: `GET /api/openapi.json` of a server with every
//! optional route (GCS link, guidance, recording) through `tests/python/openapi_check.py`: the
//! OpenAPI Initiative's 3.1 JSON Schema and the checks openapi-spec-validator makes beside it
//! (path templates and path parameters agree, no repeated parameter or operationId); and the
//! query parameters `all` and `since` are in the query, optional.
//!
//! The clients are installed by `scripts/setup` (httpx, websockets, pytest, schemathesis).
//!
//! `a_slow_websocket_client_is_dropped_to_the_latest_snapshot`: two WebSocket clients (Rust,
//! tokio-tungstenite) on a server fed scans over Zenoh by the test itself; one stops reading.
//! Once its socket buffers are full it falls behind the server's bounded per-client queue: it is
//! counted in `harrier_ws_dropped_total` and, when it reads again, gets a `snapshot` with the
//! number it missed, then consecutive scans again — while the other client saw every scan.

use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use harrier_server::config::{Config, MavlinkConfig, TokenConfig};
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
use harrier_sim::sensor_loop::SensorLoopConfig;
use harrier_sim::setup::SimScenario;
use harrier_tests::{
    free_tcp_port, http_get, kill_group, loopback_server, python_json, require_python_module,
    wait_with_deadline,
};

const TOKEN: &str = "api-clients-test-token";
/// A second token of `[[api.tokens]]`, valid until 2100.
const SECOND_TOKEN: &str = "api-clients-second-token";
/// A token of `[[api.tokens]]` that expired in 2020.
const EXPIRED_TOKEN: &str = "api-clients-expired-token";

/// Runs `cmd` (in its own process group) to completion within `timeout`; returns its output,
/// panicking with it when it fails.
fn run_client(mut cmd: Command, timeout: Duration, what: &str) -> String {
    use std::io::Read as _;
    use std::os::unix::process::CommandExt as _;
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .unwrap_or_else(|e| panic!("{what}: cannot start: {e}"));
    // Drain the pipes on threads so that a chatty client cannot block on a full pipe.
    let mut out = child.stdout.take().expect("stdout");
    let mut err = child.stderr.take().expect("stderr");
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = out.read_to_string(&mut s);
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = err.read_to_string(&mut s);
        s
    });
    let status = wait_with_deadline(&mut child, timeout, what);
    kill_group(&mut child);
    let text = format!(
        "{}{}",
        out.join().unwrap_or_default(),
        err.join().unwrap_or_default()
    );
    assert!(status.success(), "{what} failed ({status}):\n{text}");
    text
}

fn metrics(addr: SocketAddr) -> String {
    let mut s = std::net::TcpStream::connect(addr).expect("connect");
    use std::io::{Read as _, Write as _};
    s.set_read_timeout(Some(Duration::from_secs(5)))
        .expect("timeout");
    write!(
        s,
        "GET /api/v1/metrics HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("request");
    let mut text = String::new();
    s.read_to_string(&mut text).expect("response");
    text
}

/// The sum of every sample of the series `name` whose labels contain `label`.
fn metric_sum(text: &str, name: &str, label: &str) -> f64 {
    text.lines()
        .filter(|l| l.starts_with(name) && l.contains(label))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

#[test]
fn python_clients_and_schemathesis_use_the_live_api() {
    for (module, pip) in [
        ("zenoh", "eclipse-zenoh==1.10.2"),
        ("httpx", "httpx==0.28.1"),
        ("websockets", "websockets==17.4"),
        ("pytest", "pytest==9.2.0"),
        ("schemathesis", "schemathesis==4.32.5"),
    ] {
        require_python_module(module, pip);
    }
    let started = Instant::now();
    let scenario = SimScenario::load("cimm-road").expect("preset");
    let mut config = Config {
        mavlink: MavlinkConfig::ephemeral(),
        ..Config::default()
    };
    // The simulator runs 10 times faster than the server's clock.
    config.clock.real_time = false;
    config.frame.origin = scenario.origin;
    config.tracker.estimator = "cimm".into();
    config.tracker.roads = scenario.roads.clone();
    config.tracker.motion = scenario.estimator.motion.clone().expect("motion hints");
    config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.api.token = TOKEN.into();
    config.api.tokens = vec![
        TokenConfig {
            name: "ops".into(),
            token: SECOND_TOKEN.into(),
            expires: Some("2100-01-01T00:00:00Z".into()),
        },
        TokenConfig {
            name: "ci".into(),
            token: EXPIRED_TOKEN.into(),
            expires: Some("2020-01-01T00:00:00Z".into()),
        },
    ];
    config.check().expect("valid config");
    config.tracker.bound.enabled = true;
    let recording = tempfile::tempdir().expect("tempdir");
    config.recorder.path = recording
        .path()
        .join("session.sqlite")
        .display()
        .to_string();
    let sim_endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let server_endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    config.zenoh.listen = vec![server_endpoint.clone()];
    config.zenoh.connect = vec![sim_endpoint.clone()];
    let mut world = WorldConfig::new(SensorLoopConfig {
        scenario,
        seed: 5,
        speedup: 10.0,
        truth_hz: 10.0,
        clock: Default::default(),
    });
    world.vehicles = vec![WorldVehicle::grounded(1), WorldVehicle::grounded(2)];
    world.zenoh.listen = vec![sim_endpoint];
    let world = SimWorld::start(&world).expect("start the simulated world");

    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let server = runtime
        .block_on(async {
            tokio::time::timeout(Duration::from_secs(10), harrier_server::start(&config)).await
        })
        .expect("start within 10 s")
        .expect("start the live server");
    let addr = server.local_addr();
    let url = format!("http://{addr}");
    let tests_dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));

    let mut pytest = Command::new("python3");
    pytest
        .args(["-m", "pytest", "-q", "-s", "-p", "no:cacheprovider"])
        .arg(tests_dir.join("python/test_api_client.py"))
        .env("HARRIER_URL", &url)
        .env("HARRIER_TOKEN", TOKEN)
        .env("HARRIER_SECOND_TOKEN", SECOND_TOKEN)
        .env("HARRIER_EXPIRED_TOKEN", EXPIRED_TOKEN)
        .env("HARRIER_ZENOH", &server_endpoint);
    let out = run_client(
        pytest,
        Duration::from_secs(120),
        "pytest test_api_client.py",
    );
    eprintln!("{out}");

    let report = tempfile::tempdir().expect("tempdir");
    // The console script's entry point, so that no PATH lookup is involved.
    let mut st = Command::new("python3");
    st.args(["-c", "import sys; from schemathesis.cli import schemathesis; sys.exit(schemathesis())"])
        .args(["run", &format!("{url}/api/openapi.json")])
        .args(["--header", &format!("Authorization: Bearer {TOKEN}")])
        .args(["--checks", "all", "--max-examples", "25", "--seed", "1"])
        // Excluded: negative_data_rejection flags out-of-range or mistyped query values that the
        // HTTP layer cannot carry (they arrive as no parameter at all, which is valid), and
        // positive_data_acceptance flags parameter sets that are schema-valid but refused with
        // the documented 422 for constraints between fields (m ≤ n) that OpenAPI cannot state.
        .args([
            "--exclude-checks",
            "negative_data_rejection,positive_data_acceptance",
        ])
        .args(["--workers", "1", "--request-timeout", "5", "--no-color"])
        .arg("--report-dir")
        .arg(report.path())
        .current_dir(report.path());
    let out = run_client(st, Duration::from_secs(300), "schemathesis");
    eprintln!(
        "{}",
        out.lines().rev().take(25).collect::<Vec<_>>().join("\n")
    );

    let m = metrics(addr);
    assert!(
        metric_sum(&m, "harrier_http_refused_total", "reason=\"auth_expired\"") >= 4.0,
        "{m}"
    );
    assert!(
        metric_sum(&m, "harrier_http_refused_total", "reason=\"json\"") >= 2.0,
        "{m}"
    );
    assert!(
        metric_sum(&m, "harrier_scans_ingested_total", "vehicle=") > 0.0,
        "{m}"
    );
    eprintln!(
        "python client and schemathesis done in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    runtime.block_on(async {
        tokio::time::timeout(Duration::from_secs(20), server.shutdown())
            .await
            .expect("shutdown within 20 s");
    });
    world.stop();
}

#[test]
fn the_openapi_document_is_valid_openapi_3_1() {
    require_python_module("schemathesis", "schemathesis==4.32.5");
    let recording = tempfile::tempdir().expect("tempdir");
    let mut config = Config::default();
    config.recorder.path = recording
        .path()
        .join("session.sqlite")
        .display()
        .to_string();
    let (rt, server, _) = loopback_server(config);
    let (status, body) = http_get(server.local_addr(), "/api/openapi.json");
    assert_eq!(status, 200, "{body}");
    let doc: serde_json::Value = serde_json::from_str(&body).expect("JSON");
    // The routes of the GCS link, the guidance and the recording are in it.
    for path in [
        "/api/v1/vehicles",
        "/api/v1/assignments",
        "/api/v1/sessions",
        "/api/v1/tracks",
    ] {
        assert!(doc["paths"].get(path).is_some(), "{path} missing");
    }
    for (path, name) in [("/api/v1/tracks", "all"), ("/api/v1/detections", "since")] {
        let params = doc["paths"][path]["get"]["parameters"]
            .as_array()
            .unwrap_or_else(|| panic!("{path}: no parameters"));
        let p = params
            .iter()
            .find(|p| p["name"] == name)
            .unwrap_or_else(|| panic!("{path}: no {name}"));
        assert_eq!(p["in"], "query", "{path} {name}: {p}");
        assert_ne!(p["required"], true, "{path} {name}: {p}");
    }
    let file = tempfile::NamedTempFile::new().expect("temp file");
    std::fs::write(file.path(), &body).expect("write the document");
    let started = Instant::now();
    let out = python_json(
        "openapi_check.py",
        &[&file.path().display().to_string()],
        Duration::from_secs(60),
    );
    assert_eq!(out["ok"], true, "{out}");
    eprintln!(
        "openapi_check.py: {out} in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    rt.block_on(async {
        tokio::time::timeout(Duration::from_secs(20), server.shutdown())
            .await
            .expect("shutdown within 20 s");
    });
}

/// A position scan of vehicle 1 at `t` (UNIX s) with `n` detections on a line.
fn scan_json(seq: u64, t: f64, n: usize) -> String {
    use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, DetectionScan, PlatformPose};
    let origin = harrier_server::config::DEFAULT_ORIGIN;
    DetectionScan {
        schema: DETECTIONS_SCHEMA.into(),
        t,
        time_unix: Some(t),
        vehicle: 1,
        seq,
        sensor: "cam".into(),
        kind: harrier_core::measurement::MeasKind::Position,
        origin,
        platform: PlatformPose {
            pos: [0.0; 3],
            vel: [0.0; 3],
            attitude: [0.0; 3],
            geodetic: Some(origin),
        },
        noise_std: vec![5.0, 5.0],
        detections: (0..n)
            .map(|i| Detection {
                z: vec![100.0 * i as f64, 10.0 * (t % 100.0)],
            })
            .collect(),
    }
    .to_json()
}

#[test]
fn a_slow_websocket_client_is_dropped_to_the_latest_snapshot() {
    use futures_util::StreamExt as _;
    use serde_json::Value;
    use tokio_tungstenite::tungstenite::Message;

    let mut config = Config::default();
    // The scans below are on a time line of their own (from 10⁹ s, 1 ms apart), not real time.
    config.clock.real_time = false;
    config.mavlink.gcs.clear();
    config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.api.ws_queue = 512;
    config.zenoh.tracks_key = String::new();
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    config.zenoh.listen = vec![endpoint.clone()];
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    runtime.block_on(async {
        let within = |secs| Duration::from_secs(secs);
        let server = tokio::time::timeout(within(10), harrier_server::start(&config))
            .await
            .expect("start within 10 s")
            .expect("start the live server");
        let url = format!("ws://{}/api/v1/ws", server.local_addr());
        let connect = || async {
            let (ws, _) = tokio::time::timeout(within(10), tokio_tungstenite::connect_async(&url))
                .await
                .expect("connect within 10 s")
                .expect("WebSocket handshake");
            ws
        };
        let next = |m: Option<Result<Message, _>>| -> Value {
            match m {
                Some(Ok(Message::Text(t))) => serde_json::from_str(&t).expect("JSON message"),
                other => panic!("expected a text message, got {other:?}"),
            }
        };
        // The fast client: every message, in order.
        let mut fast = connect().await;
        let first = next(fast.next().await);
        assert_eq!(first["type"], "snapshot");
        let (stop_tx, mut stop_rx) = tokio::sync::watch::channel(false);
        let fast_task = tokio::spawn(async move {
            let (mut last, mut gaps, mut n) = (first["seq"].as_u64().expect("seq"), 0, 0u64);
            loop {
                tokio::select! {
                    m = fast.next() => {
                        let m = next(m);
                        assert_eq!(m["type"], "scan", "the fast client was dropped: {m}");
                        let seq = m["seq"].as_u64().expect("seq");
                        gaps += u64::from(seq != last + 1);
                        last = seq;
                        n += 1;
                    }
                    _ = stop_rx.changed() => break,
                }
            }
            (n, gaps, last)
        });
        // The slow client: reads a message every 10 ms (100 Hz) while scans come at 1 kHz.
        let mut slow = connect().await;
        assert_eq!(next(slow.next().await)["type"], "snapshot");
        let slow_task = tokio::spawn(async move {
            let (mut missed, mut after, mut last) = (None, 0, 0);
            while after < 20 {
                tokio::time::sleep(Duration::from_millis(10)).await;
                let m = next(slow.next().await);
                let s = m["seq"].as_u64().expect("seq");
                match (m["type"].as_str(), missed) {
                    (Some("snapshot"), _) => {
                        missed = Some(m["dropped"].as_u64().expect("dropped"));
                    }
                    (_, Some(_)) => {
                        assert_eq!(s, last + 1, "a gap after the snapshot");
                        after += 1;
                    }
                    _ => {}
                }
                last = s;
            }
            (missed.unwrap_or(0), last, slow)
        });

        let session = tokio::time::timeout(
            within(10),
            zenoh::open(
                harrier_sim::bus::BusConfig {
                    connect: vec![endpoint],
                    listen: vec!["tcp/127.0.0.1:0".into()],
                    ..harrier_sim::bus::BusConfig::default()
                }
                .to_zenoh()
                .expect("config"),
            ),
        )
        .await
        .expect("open within 10 s")
        .expect("open the publisher's session");
        let key = harrier_core::detection::detections_key(1);
        let t0 = 1.0e9;
        let (mut seq, deadline) = (0u64, Instant::now() + within(90));
        // Publish (about 1 kHz, 4 detections a scan) until the slow client was dropped to a
        // snapshot and caught up.
        while !slow_task.is_finished() {
            for _ in 0..50 {
                seq += 1;
                session
                    .put(&key, scan_json(seq, t0 + seq as f64 * 1e-3, 4))
                    .await
                    .expect("publish");
            }
            tokio::time::sleep(Duration::from_millis(50)).await;
            assert!(
                Instant::now() < deadline,
                "the slow client was never dropped"
            );
        }
        let (missed, slow_last, slow) = slow_task.await.expect("slow client");
        // Let the tracker finish what was published, then stop the fast client.
        let processed = loop {
            let now = server.snapshot().borrow().seq;
            if now >= seq {
                break now;
            }
            assert!(
                Instant::now() < deadline,
                "the tracker processed {now} of {seq} scans"
            );
            tokio::time::sleep(Duration::from_millis(20)).await;
        };
        let m = tokio::task::spawn_blocking({
            let addr = server.local_addr();
            move || metrics(addr)
        })
        .await
        .expect("metrics");
        let dropped = metric_sum(&m, "harrier_ws_dropped_total", "");
        let fast_done = Instant::now() + within(10);
        while server.metrics().scans_ingested() < processed && Instant::now() < fast_done {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        tokio::time::sleep(Duration::from_millis(200)).await;
        let _ = stop_tx.send(true);
        let (n, gaps, last) = fast_task.await.expect("fast client");
        assert_eq!((gaps, last), (0, processed), "the fast client missed scans");
        assert!(
            missed > 0 && dropped >= missed as f64,
            "missed {missed}, counted {dropped}"
        );
        eprintln!(
            "{seq} scans published and processed; the fast client got all {n}; the slow one missed \
             {missed} (server counted {dropped}), then read 20 consecutive scans up to seq \
             {slow_last}"
        );
        drop(slow);
        tokio::time::timeout(within(10), session.close())
            .await
            .expect("close within 10 s")
            .expect("close");
        tokio::time::timeout(within(20), server.shutdown())
            .await
            .expect("shutdown within 20 s");
    });
}
