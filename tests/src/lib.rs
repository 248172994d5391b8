//! Helpers for Harrier's end-to-end tests: where the reference scenarios are, how to replay one
//! in-process, how to run the independent scorer (`shared/scenarios/score.py`), how to run
//! the real external clients (Python scripts in `tests/python`) with a deadline, and the
//! simulated sources the live tests feed a server with (a `harrier-sim` process, a standing
//! target's scans on Zenoh) and read its truth with.

pub mod net;

use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// `shared/scenarios`, which CI places beside the repository (`../shared`). `HARRIER_SHARED`
/// overrides the location of `shared/`.
pub fn scenarios_dir() -> PathBuf {
    let shared = std::env::var_os("HARRIER_SHARED").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
        PathBuf::from,
    );
    shared.join("scenarios")
}

/// Path of one reference scenario.
pub fn scenario(name: &str) -> PathBuf {
    scenarios_dir().join(name)
}

/// Runs `python3 score.py <dir> <estimates> --json -` and returns its JSON.
pub fn score_py(dir: &Path, estimates: &Path) -> anyhow::Result<serde_json::Value> {
    let out = Command::new("python3")
        .arg(scenarios_dir().join("score.py"))
        .arg(dir)
        .arg(estimates)
        .args(["--json", "-"])
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "score.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(serde_json::from_slice(&out.stdout)?)
}

/// Replays the reference scenario `name` with `estimator` and default parameters.
pub fn replay(name: &str, estimator: &str) -> harrier_tools::replay::ReplayReport {
    let data = harrier_tools::replay::load(&scenario(name)).expect("reference scenario loads");
    harrier_tools::replay::run(&data, estimator, &harrier_engine::Params::default())
        .expect("replay runs")
}

/// Replays `name` with `estimator`, checks that no step was rejected, prints and returns the score.
pub fn replay_score(name: &str, estimator: &str) -> harrier_core::metrics::Score {
    let r = replay(name, estimator);
    assert!(
        r.rejected.is_empty(),
        "{estimator} on {name} rejected steps: {:?}",
        r.rejected
    );
    let s = r.score.expect("reference scenarios have truth");
    println!(
        "{name:<22} {estimator:<14} pos RMSE {:8.3} m  NEES-95% ok {:.3}",
        s.pos_rmse.unwrap_or(f64::NAN),
        s.nees.as_ref().map_or(f64::NAN, |n| n.frac_within_95)
    );
    s
}

/// Writes the estimates of `report` (a replay of the reference scenario `name`) to a temporary file,
/// scores it with `score.py` and asserts that the state metrics harrier-core computed agree to 1e-9.
pub fn assert_score_py_agrees(name: &str, report: &harrier_tools::replay::ReplayReport) {
    let s = report
        .score
        .clone()
        .expect("reference scenarios have truth");
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("estimates.jsonl");
    harrier_tools::replay::write_estimates(&out, &report.estimates).expect("write estimates");
    let py = score_py(&scenario(name), &out).expect("score.py runs");
    let close = |what: &str, a: f64, b: &serde_json::Value| {
        let b = b.as_f64().unwrap_or(f64::NAN);
        assert!(
            (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
            "{name} {what}: rust {a} vs score.py {b}"
        );
    };
    close("pos_rmse", s.pos_rmse.unwrap_or(f64::NAN), &py["pos_rmse"]);
    close("vel_rmse", s.vel_rmse.unwrap_or(f64::NAN), &py["vel_rmse"]);
    close("pos_max", s.pos_max.unwrap_or(f64::NAN), &py["pos_max"]);
    for (mode, v) in &s.pos_rmse_by_mode {
        close("pos_rmse_by_mode", *v, &py["pos_rmse_by_mode"][mode]);
    }
    if let Some(n) = &s.nees {
        close("nees.mean", n.mean, &py["nees"]["mean"]);
        close(
            "nees.frac_within_95",
            n.frac_within_95,
            &py["nees"]["frac_within_95"],
        );
        close(
            "nees.chi2_95_bound",
            n.chi2_95_bound,
            &py["nees"]["chi2_95_bound"],
        );
    }
    if let Some(n) = &s.nees_pos {
        close("nees_pos.mean", n.mean, &py["nees_pos"]["mean"]);
    }
}

/// Position RMSE of a score (panics if the estimator wrote no states).
pub fn pos_rmse(s: &harrier_core::metrics::Score) -> f64 {
    s.pos_rmse.expect("state estimates")
}

/// Fraction of epochs with NEES within the χ² 95 % bound; NaN when there are no covariances (so
/// any bound on it fails).
pub fn nees_ok(s: &harrier_core::metrics::Score) -> f64 {
    s.nees.as_ref().map_or(f64::NAN, |n| n.frac_within_95)
}

/// Panics with an install hint unless `python3` can import `module` (`pip` names the pinned
/// package, as `tests/python/requirements.lock` has it; `scripts/setup` installs the lock into a
/// venv that `scripts/test` puts first on `PATH`).
pub fn require_python_module(module: &str, pip: &str) {
    let ok = Command::new("python3")
        .args(["-W", "ignore", "-c", &format!("import {module}")])
        .stderr(Stdio::null())
        .status()
        .expect("python3 not found")
        .success();
    assert!(
        ok,
        "python3 lacks {module} ({pip}): run the tests with scripts/test, or first \
         `eval \"$(scripts/setup --env)\"` to put the venv of tests/python/requirements.lock on PATH"
    );
}

/// `python3 tests/python/<script>` in its own process group (so that whatever it starts, such as
/// mavsdk_server, can be killed with it), stdin closed.
pub fn python_script(script: &str) -> Command {
    let mut c = Command::new("python3");
    c.arg(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("python")
            .join(script),
    )
    .stdin(Stdio::null())
    .process_group(0);
    c
}

/// Kills a child's whole process group (started with [`python_script`] or `process_group(0)`)
/// and reaps the child.
pub fn kill_group(child: &mut Child) {
    let _ = Command::new("kill")
        .args(["-KILL", "--", &format!("-{}", child.id())])
        .stderr(Stdio::null())
        .status();
    let _ = child.wait();
}

/// Waits for `child` to exit; past `timeout`, kills its process group and panics naming `what`.
pub fn wait_with_deadline(child: &mut Child, timeout: Duration, what: &str) -> ExitStatus {
    let deadline = Instant::now() + timeout;
    loop {
        if let Some(status) = child.try_wait().expect("wait for a child process") {
            return status;
        }
        if Instant::now() > deadline {
            kill_group(child);
            panic!("{what} did not finish within {timeout:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// A free TCP port on loopback. Zenoh's stable API does not report the port it bound for port 0,
/// so the Zenoh tests take one from the OS and pass it as an explicit listen endpoint.
pub fn free_tcp_port() -> u16 {
    std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("free port")
        .port()
}

/// `target/<profile>/<name>`, a binary of the workspace beside the running test executable's
/// `deps/` directory: `cargo test --workspace` builds them; run alone, build it first (`cargo
/// build -p harrier-cli` for `harrier`, `-p harrier-sim` for `harrier-sim`).
pub fn target_bin(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    let bin = exe
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join(name))
        .expect("target directory");
    assert!(
        bin.is_file(),
        "{} not found: build it with `cargo build` (cargo test --workspace does)",
        bin.display()
    );
    bin
}

/// A `harrier-sim` process, killed with SIGKILL and reaped when dropped (so a failing test leaves
/// none behind).
#[derive(Debug)]
pub struct SimProcess(Child);

impl SimProcess {
    /// `harrier-sim` as vehicle `id` sending its telemetry to the GCS link at `gcs`
    /// (`--gcs udpout:GCS`), its API link on a port of the OS's choice, silent (stdio null),
    /// started with the further arguments `args` (a world, `--no-zenoh`, signing …).
    pub fn start<I, S>(id: u8, gcs: std::net::SocketAddr, args: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: AsRef<std::ffi::OsStr>,
    {
        let bin = target_bin("harrier-sim");
        let child = Command::new(&bin)
            .args(["--id", &id.to_string(), "--gcs", &format!("udpout:{gcs}")])
            .args(["--api", "udpin:127.0.0.1:0"])
            .args(args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", bin.display()));
        Self(child)
    }

    /// SIGKILL, and reap.
    pub fn kill(&mut self) {
        self.0.kill().expect("SIGKILL harrier-sim");
        let _ = self.0.wait();
    }
}

impl Drop for SimProcess {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Publishes `position` scans of a target standing at `at` (server frame, m), seen from a
/// platform standing at `platform` (server frame, m), on vehicle `vehicle`'s key, `hz` times a
/// second, stamped with the wall time, until aborted. The detections jitter by up to 2 m
/// around the target (σ given as 2 m).
pub async fn publish_standing_target(
    session: &zenoh::Session,
    vehicle: u8,
    at: [f64; 2],
    platform: [f64; 3],
    hz: f64,
) -> tokio::task::JoinHandle<()> {
    use harrier_core::detection::{
        DETECTIONS_SCHEMA, Detection, DetectionScan, PlatformPose, detections_key,
    };
    let publisher = tokio::time::timeout(
        Duration::from_secs(10),
        session.declare_publisher(detections_key(vehicle)),
    )
    .await
    .expect("a publisher within 10 s")
    .expect("publisher");
    let origin = harrier_server::config::DEFAULT_ORIGIN;
    tokio::spawn(async move {
        let frame = harrier_link::geo::LocalFrame::new(origin);
        let pos = nalgebra::Vector3::from(platform);
        let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
        for seq in 0u64.. {
            tick.tick().await;
            let now = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64());
            let scan = DetectionScan {
                schema: DETECTIONS_SCHEMA.into(),
                t: seq as f64 / hz,
                time_unix: Some(now),
                vehicle,
                seq,
                sensor: "cam".into(),
                kind: harrier_core::measurement::MeasKind::Position,
                origin,
                platform: PlatformPose {
                    pos: platform,
                    vel: [0.0; 3],
                    attitude: [0.0; 3],
                    geodetic: Some(frame.from_enu(&pos)),
                },
                noise_std: vec![2.0, 2.0],
                detections: vec![Detection {
                    z: vec![at[0] + (seq % 3) as f64, at[1] - (seq % 5) as f64 * 0.5],
                }],
            };
            if publisher.put(scan.to_json()).await.is_err() {
                return;
            }
        }
    })
}

/// The simulator's truth target positions (server frame, m) of `s`, extrapolated with their
/// velocities to UNIX time `t` (the server's time line). Panics if `s` has no `time_unix`.
pub fn targets_at(s: &harrier_core::detection::TruthSample, t: f64) -> Vec<[f64; 2]> {
    let dt = t - s.time_unix.expect("truth carries time_unix");
    s.targets
        .iter()
        .map(|g| [g.state[0] + g.state[3] * dt, g.state[1] + g.state[4] * dt])
        .collect()
}

/// Awaits `f`, panicking with `what` when it takes longer than `secs` seconds: every await of a
/// test on something outside it goes through this, so a hang fails the test instead.
pub async fn within<T>(secs: u64, what: &str, f: impl std::future::IntoFuture<Output = T>) -> T {
    match tokio::time::timeout(Duration::from_secs(secs), f.into_future()).await {
        Ok(v) => v,
        Err(_) => panic!("{what}: no answer within {secs} s"),
    }
}

/// The tests' tokio runtime: two worker threads (the machines have two cores), time and I/O.
pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime")
}

/// `GET path` (HTTP/1.1, `Connection: close`): status and body.
pub fn http_get(addr: std::net::SocketAddr, path: &str) -> (u16, String) {
    use std::io::{Read as _, Write as _};
    let mut s = std::net::TcpStream::connect_timeout(&addr, Duration::from_secs(5))
        .unwrap_or_else(|e| panic!("connect {addr}: {e}"));
    s.set_read_timeout(Some(Duration::from_secs(10)))
        .expect("timeout");
    write!(
        s,
        "GET {path} HTTP/1.1\r\nHost: {addr}\r\nConnection: close\r\n\r\n"
    )
    .expect("send the request");
    let mut raw = Vec::new();
    s.read_to_end(&mut raw).expect("read the response");
    let text = String::from_utf8(raw).expect("utf-8 response");
    let (head, body) = text.split_once("\r\n\r\n").expect("HTTP head");
    let status = head
        .split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .expect("status");
    let body = if head
        .to_ascii_lowercase()
        .contains("transfer-encoding: chunked")
    {
        dechunk(body)
    } else {
        body.to_owned()
    };
    (status, body)
}

/// The payload of a chunked body.
fn dechunk(mut body: &str) -> String {
    let mut out = String::new();
    while let Some((size, rest)) = body.split_once("\r\n") {
        let n = usize::from_str_radix(size.trim(), 16).expect("chunk size");
        if n == 0 {
            break;
        }
        out.push_str(&rest[..n]);
        body = &rest[n + 2..];
    }
    out
}

/// `GET path` as JSON: status and value; panics naming the path when the body is not JSON.
pub fn http_get_json(addr: std::net::SocketAddr, path: &str) -> (u16, serde_json::Value) {
    let (status, body) = http_get(addr, path);
    let v = serde_json::from_str(&body).unwrap_or_else(|e| panic!("{path}: {e}: {body}"));
    (status, v)
}

/// A Zenoh session of the test's own, connected to `endpoints`, listening on a free loopback
/// port.
pub async fn open_session(endpoints: Vec<String>) -> zenoh::Session {
    let config = harrier_sim::bus::BusConfig {
        connect: endpoints,
        listen: vec![format!("tcp/127.0.0.1:{}", free_tcp_port())],
        ..harrier_sim::bus::BusConfig::default()
    }
    .to_zenoh()
    .expect("config");
    within(10, "open a session", zenoh::open(config))
        .await
        .expect("open the test's session")
}

/// A live server's configuration for a test: the defaults with the API on a free loopback port,
/// Zenoh listening on `zenoh` and no MAVLink endpoint (the default ones are fixed ports that
/// tests running at once would share). Returns it with its Zenoh endpoint.
pub fn server_config() -> (harrier_server::config::Config, String) {
    let zenoh = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let mut config = harrier_server::config::Config::default();
    config.api.listen = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    config.zenoh.listen = vec![zenoh.clone()];
    config.mavlink.gcs = Vec::new();
    config.mavlink.router = Vec::new();
    (config, zenoh)
}

/// The JSON lines a child (started with a piped stdout) prints, as they come, on a channel (a
/// line that is not JSON is skipped); the channel ends with the child's stdout.
pub fn json_lines(child: &mut Child) -> std::sync::mpsc::Receiver<serde_json::Value> {
    use std::io::BufRead as _;
    let out = child.stdout.take().expect("the child's stdout is piped");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(out).lines().map_while(Result::ok) {
            if let Ok(v) = serde_json::from_str::<serde_json::Value>(&line)
                && tx.send(v).is_err()
            {
                return;
            }
        }
    });
    rx
}

/// Makes a test certificate authority and certificates for `names` (their common names, each
/// for `localhost` and 127.0.0.1, for servers and clients) with the `openssl` CLI, in `dir`:
/// `ca.pem`, `NAME.pem`, `NAME.key` (P-256, valid 2 days).
pub fn test_certificates(dir: &Path, names: &[&str]) {
    let openssl = |args: &[&str]| {
        let out = Command::new("openssl")
            .args(args)
            .current_dir(dir)
            .stdin(Stdio::null())
            .output()
            .unwrap_or_else(|e| panic!("openssl not found ({e}): scripts/setup installs it"));
        assert!(
            out.status.success(),
            "openssl {}: {}",
            args.join(" "),
            String::from_utf8_lossy(&out.stderr)
        );
    };
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1"];
    openssl(
        &[
            &[
                "req",
                "-x509",
                "-nodes",
                "-days",
                "2",
                "-subj",
                "/CN=harrier-test-ca",
            ][..],
            &ec,
            &["-keyout", "ca.key", "-out", "ca.pem"],
        ]
        .concat(),
    );
    for name in names {
        let ext = format!("{name}.ext");
        std::fs::write(
            dir.join(&ext),
            "basicConstraints=CA:FALSE\nextendedKeyUsage=serverAuth,clientAuth\n\
             subjectAltName=DNS:localhost,IP:127.0.0.1\n",
        )
        .expect("write the extensions");
        let (key, csr, pem) = (
            format!("{name}.key"),
            format!("{name}.csr"),
            format!("{name}.pem"),
        );
        let subj = format!("/CN={name}");
        openssl(
            &[
                &["req", "-nodes", "-subj", &subj][..],
                &ec,
                &["-keyout", &key, "-out", &csr],
            ]
            .concat(),
        );
        openssl(&[
            "x509",
            "-req",
            "-in",
            &csr,
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-days",
            "2",
            "-extfile",
            &ext,
            "-out",
            &pem,
        ]);
    }
}

/// Runs `tests/python/<script>` with `args` to its end within `timeout` and returns the JSON of
/// the last line it printed; panics, with what it printed, when it fails or prints no JSON.
pub fn python_json(script: &str, args: &[&str], timeout: Duration) -> serde_json::Value {
    use std::io::Read as _;
    let mut child = python_script(script)
        .args(args)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap_or_else(|e| panic!("start {script}: {e}"));
    let mut stdout = child.stdout.take().expect("stdout");
    // Read on a thread, so that a long output cannot fill the pipe and stall the script.
    let reader = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let status = wait_with_deadline(&mut child, timeout, script);
    let out = reader.join().unwrap_or_default();
    assert!(status.success(), "{script} failed ({status}): {out}");
    let last = out
        .lines()
        .rev()
        .find(|l| !l.trim().is_empty())
        .unwrap_or("");
    serde_json::from_str(last).unwrap_or_else(|e| panic!("{script}: no JSON ({e}): {out}"))
}

/// Every confirmed track estimate a live server's snapshot showed (what `GET /api/v1/tracks`
/// serves): its position (server frame, m) by (track id, estimate time in ms). Clones share it.
#[derive(Debug, Clone, Default)]
pub struct ConfirmedStates(std::sync::Arc<std::sync::Mutex<StatesByTime>>);

/// Positions (server frame, m) by (track id, estimate time in ms).
type StatesByTime = std::collections::BTreeMap<(u64, i64), [f64; 3]>;

impl ConfirmedStates {
    /// The confirmed position of track `id` at `ms` (an event's `start`, the estimate's time;
    /// ±2 ms, for times that went through a float), if the snapshot showed it.
    pub fn at(&self, id: u64, ms: i64) -> Option<[f64; 3]> {
        let seen = self.0.lock().expect("seen");
        (ms - 2..=ms + 2).find_map(|t| seen.get(&(id, t)).copied())
    }

    /// The position the snapshot showed for track `id` at exactly `ms`.
    fn exactly(&self, id: u64, ms: i64) -> Option<[f64; 3]> {
        self.0.lock().expect("seen").get(&(id, ms)).copied()
    }
}

/// Checks a track event as `tests/python/cot_listen.py` prints it (a JSON line) against what
/// [`StandingTargetServer`]'s CoT feed sends — type `a-u-G`, how `m-f`, uid
/// `harrier.it.track.<id>`, callsign `T<id>`, stale 10 s after its time, `start` (the
/// estimate's time) at most 1 s before its time — and returns the track id and `start` (ms).
pub fn track_event(e: &serde_json::Value) -> (u64, i64) {
    assert_eq!(e["type"], "a-u-G", "{e}");
    assert_eq!(e["how"], "m-f", "{e}");
    let uid = e["uid"].as_str().expect("uid");
    let id: u64 = uid
        .strip_prefix("harrier.it.track.")
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("uid {uid}"));
    assert_eq!(e["callsign"], format!("T{id}"), "{e}");
    let time = e["time_ms"].as_i64().expect("time");
    let start = e["start_ms"].as_i64().expect("start");
    let stale = e["stale_ms"].as_i64().expect("stale");
    // takproto's XML times go through a float: ±1 ms.
    assert!((stale - time - 10_000).abs() <= 1, "{e}");
    assert!(start <= time + 1 && time - start < 1_000, "{e}");
    (id, start)
}

/// A live server ([`harrier_server::start`]) with `config` made to listen on loopback only (the
/// API on port 0, Zenoh on a free port, the GCS link on UDP port 0, no MAVLink router: tests run
/// at once), on a runtime of its own; and the Zenoh endpoint it listens on.
pub fn loopback_server(
    mut config: harrier_server::config::Config,
) -> (tokio::runtime::Runtime, harrier_server::LiveServer, String) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    config.api.listen = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    config.zenoh.listen = vec![endpoint.clone()];
    config.mavlink = harrier_server::config::MavlinkConfig::ephemeral();
    let rt = runtime();
    let server = rt
        .block_on(within(
            10,
            "start the server",
            harrier_server::start(&config),
        ))
        .expect("start the live server");
    (rt, server, endpoint)
}

/// A Zenoh session (client of nobody else) connected to `endpoint`.
pub async fn zenoh_client(endpoint: &str) -> zenoh::Session {
    let bus = harrier_link::bus::BusConfig {
        connect: vec![endpoint.to_owned()],
        listen: Vec::new(),
        ..harrier_link::bus::BusConfig::default()
    }
    .to_zenoh()
    .expect("zenoh config");
    within(10, "open a session", zenoh::open(bus))
        .await
        .expect("zenoh session")
}

/// A live server ([`harrier_server::start`]) on loopback fed over Zenoh with the scans of one
/// standing target ([`publish_standing_target`]: vehicle [`Self::VEHICLE`] sees it at
/// [`Self::TARGET`] from a platform standing at [`Self::PLATFORM`], 10 Hz), recording every
/// confirmed estimate its snapshot shows: what the CoT tests (`field_cot`, `field_tak`) compare
/// the events they decode with.
pub struct StandingTargetServer {
    /// The runtime the server runs on.
    pub rt: tokio::runtime::Runtime,
    /// The server.
    pub server: harrier_server::LiveServer,
    /// Every confirmed estimate its snapshot showed so far (kept by clones after [`Self::stop`]).
    pub seen: ConfirmedStates,
    session: zenoh::Session,
    tasks: [tokio::task::JoinHandle<()>; 2],
}

impl std::fmt::Debug for StandingTargetServer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StandingTargetServer")
            .field("api", &self.server.local_addr())
            .finish_non_exhaustive()
    }
}

impl StandingTargetServer {
    /// The vehicle whose scans see the target.
    pub const VEHICLE: u8 = 8;
    /// Where the target stands (server frame, m).
    pub const TARGET: [f64; 2] = [80.0, 40.0];
    /// Where the vehicle's platform stands (server frame, m).
    pub const PLATFORM: [f64; 3] = [0.0, 0.0, 50.0];

    /// Starts the server with `config` made to listen on loopback only (the API on port 0,
    /// Zenoh on a free port, the GCS link on UDP port 0, no MAVLink router: tests run at once),
    /// then the target's scans and the recording of the snapshot.
    pub fn start(config: harrier_server::config::Config) -> Self {
        let (rt, server, endpoint) = loopback_server(config);
        let seen = ConfirmedStates::default();
        let mut snapshot = server.snapshot();
        let recorder = {
            let seen = seen.clone();
            rt.spawn(async move {
                loop {
                    {
                        let s = snapshot.borrow_and_update();
                        let mut seen = seen.0.lock().expect("seen");
                        for t in s.tracks.iter() {
                            if t.status == harrier_engine::TrackStatus::Confirmed {
                                let key = (t.id, (t.t * 1e3).round() as i64);
                                seen.insert(key, [t.state[0], t.state[1], t.state[2]]);
                            }
                        }
                    }
                    if snapshot.changed().await.is_err() {
                        return;
                    }
                }
            })
        };
        let (session, publisher) = rt.block_on(async {
            let session = zenoh_client(&endpoint).await;
            let publisher = publish_standing_target(
                &session,
                Self::VEHICLE,
                Self::TARGET,
                Self::PLATFORM,
                10.0,
            )
            .await;
            (session, publisher)
        });
        Self {
            rt,
            server,
            seen,
            session,
            tasks: [recorder, publisher],
        }
    }

    /// Checks that `GET /api/v1/tracks` serves the snapshot's tracks: it has a confirmed track,
    /// and every confirmed track it serves at a time the snapshot showed is where the snapshot
    /// had it. Returns the number of confirmed tracks served.
    pub fn check_rest_tracks(&self) -> usize {
        let (status, tracks) = http_get_json(self.server.local_addr(), "/api/v1/tracks");
        assert_eq!(status, 200);
        let rest = tracks["tracks"].as_array().expect("tracks");
        let confirmed: Vec<_> = rest.iter().filter(|k| k["status"] == "confirmed").collect();
        assert!(!confirmed.is_empty(), "no confirmed track: {tracks}");
        for k in &confirmed {
            let id = k["id"].as_u64().expect("id");
            let t = (k["t"].as_f64().expect("t") * 1e3).round() as i64;
            let s = k["state"].as_array().expect("state");
            let got = [0, 1, 2].map(|i| s[i].as_f64().expect("state value"));
            if let Some(p) = self.seen.exactly(id, t) {
                let d = nalgebra::Vector3::from(p) - nalgebra::Vector3::from(got);
                assert!(
                    d.norm() < 1e-6,
                    "track {id} at {t} ms: {got:?}, snapshot {p:?}"
                );
            }
        }
        confirmed.len()
    }

    /// Stops the scans, the recording and the server.
    pub fn stop(self) {
        for task in &self.tasks {
            task.abort();
        }
        self.rt.block_on(async {
            let _ = self.session.close().await;
            self.server.shutdown().await;
        });
    }
}
