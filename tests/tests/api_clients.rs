//! The live server's API driven by real external clients, against a server fed by harrier-sim
//! over real Zenoh (two vehicles of the `cimm-road` world, sped up 10×, the CIMM track engine):
//!
//! - `tests/python/test_api_client.py` (pytest + httpx + websockets), a user's script: lists
//!   tracks, reads one, changes the estimator (401 without or with a wrong token, 400 on a body
//!   that is not JSON, 422 naming the field or the unknown estimator, 200 with the token and the
//!   tracks kept), watches the WebSocket (a snapshot, then scan messages with consecutive `seq`),
//!   subscribes to the tracks on Zenoh with eclipse-zenoh, and publishes bad payloads (garbage,
//!   NaN, negative noise, a short `z`) that `/metrics` must count by reason while tracking goes on,
//!   and reads the session being recorded (its scans, tracks and the API actions) and its export
//!   as `gcs-scenario/1`;
//! - schemathesis against `/api/openapi.json`, every check but two (see the test): no 5xx, every
//!   status, content type, header and body as documented;
//! - afterwards `/metrics` counts the refused requests, and tracking went on.
//!
//! The clients are installed by `.ci/run` (httpx, websockets, pytest, schemathesis).

use std::net::SocketAddr;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use harrier_server::live::{self, config::Config};
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
use harrier_sim::live::LiveConfig;
use harrier_sim::setup::SimScenario;
use harrier_tests::{free_tcp_port, kill_group, require_python_module, wait_with_deadline};

const TOKEN: &str = "api-clients-test-token";

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
    let mut config = Config::default();
    config.frame.origin = scenario.origin;
    config.tracker.estimator = "cimm".into();
    config.tracker.roads = scenario.roads.clone();
    config.tracker.motion = scenario.estimator.motion.clone().expect("motion hints");
    config.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
    config.api.token = TOKEN.into();
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
    let mut world = WorldConfig::new(LiveConfig {
        scenario,
        seed: 5,
        speedup: 10.0,
        truth_hz: 10.0,
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
            tokio::time::timeout(Duration::from_secs(10), live::start(&config)).await
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
        metric_sum(&m, "harrier_http_refused_total", "reason=\"auth\"") >= 2.0,
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
