//! Harrier on a real Zenoh router (`zenohd`, pinned and installed by `scripts/setup`), real processes
//! only: the `harrier-sim` and `harrier` binaries and `zenohd`, all Zenoh clients of the router,
//! `/api/v1/tracks` and `/api/v1/metrics` read over HTTP, the simulator's truth read by this test's own
//! Zenoh client of the same router. The world is the `radar` preset with two targets (a
//! grounded vehicle's range/bearing radar, 2 Hz, sped up 5×). No sleeps wait for readiness:
//! `zenohd` prints "Zenoh can be reached at", `harrier serve` its ready line, and every other wait
//! polls a real condition under a deadline; every process is killed when its guard drops.
//!
//! - `two_hosts_through_a_router`: the simulator and two servers in three network namespaces made
//!   here (`ip netns` + veth pairs, 10.x.y.0/30 each; the router in the root namespace), so the
//!   only path between them is the router (fallback when namespaces are not permitted: the same
//!   processes on loopback, said loudly). Both servers track each target within 10 m of the
//!   truth, and agree with each other within 5 m at matching times.
//! - `a_restarted_router_is_rejoined_and_the_loss_counted`: `zenohd` SIGKILLed for 3 s, then
//!   started again on the same endpoint: the same server process takes new scans again by
//!   itself, its tracks follow the truth again, and `harrier_seq_lost_total` counts the scans
//!   published during the outage.
//! - `tls_and_access_control`: certificates made with the `openssl` CLI; `zenohd` listens on TLS
//!   only, asks for client certificates (mTLS), and its access control lets the companion
//!   (`CN=harrier-sim`) put only on the detections and truth keys and the ground station
//!   (`CN=harrier-gcs`) subscribe; the server tracks through it; a plain-TCP session to the TLS
//!   port fails, and so does one with a certificate of another CA (even named `CN=harrier-sim`);
//!   a client with a certificate of the same CA but another name (`CN=intruder`), whose
//!   publisher sees the server's subscriber, puts on a detections key and the server receives
//!   nothing of it, while the same puts from the companion's certificate arrive; the server's
//!   tracks reach the test's client on `harrier/v1/tracks`.
//! - `latency_through_the_router_against_peer_to_peer`: 500 puts at 50 Hz, peer to peer and
//!   between two clients of `zenohd`, all on loopback (BENCHMARKS.md).
//!
//! `zenohd` is `$HARRIER_ZENOHD`, else `~/.cache/harrier/zenohd/bin/zenohd`; the binaries are
//! `target/<profile>/{harrier,harrier-sim}` (`cargo build -p harrier-cli -p harrier-sim`).

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harrier_core::detection::{TRACKS_KEY, TRUTH_KEY, TruthSample};
use harrier_link::bus::{BusConfig, Mode, TlsConfig};
use harrier_sim::setup::{Jitter, SimScenario, TargetMotion, TargetSpec};
use harrier_tests::net::{Netns, Proc, Veth, harrier_serve_in, metric_value, run, zenohd};
use harrier_tests::{free_tcp_port, http_get, target_bin, targets_at, test_certificates};
use serde_json::Value;
use zenoh::Wait as _;

/// Simulated seconds per wall second.
const SPEEDUP: f64 = 5.0;
/// Radar scans per simulated second.
const RATE_HZ: f64 = 2.0;
/// Largest track error against the truth (m).
const MAX_ERROR_M: f64 = 10.0;
/// Largest disagreement between two servers' tracks at the same time (m).
const MAX_DISAGREEMENT_M: f64 = 5.0;
/// Consecutive polls at distinct scan times that must each pass.
const STABLE_POLLS: usize = 6;
/// Longest wait for tracks.
const TRACKS_DEADLINE: Duration = Duration::from_secs(90);

/// Where a process runs: a namespace, or this one (loopback).
#[derive(Clone)]
struct Host {
    ns: Option<String>,
    /// The host's own address.
    addr: String,
    /// The router's address as this host reaches it.
    router: String,
}

impl Host {
    fn loopback() -> Self {
        Self {
            ns: None,
            addr: "127.0.0.1".into(),
            router: "127.0.0.1".into(),
        }
    }

    /// `program` run on this host.
    fn command(&self, program: &Path) -> Command {
        match &self.ns {
            Some(ns) => {
                let mut c = Command::new("ip");
                c.args(["netns", "exec", ns]).arg(program);
                c
            }
            None => Command::new(program),
        }
    }
}

/// The world: the `radar` preset with two targets 0.6-0.9 km from the grounded radar, 2 Hz,
/// written as a scenario file for `harrier-sim --scenario`.
fn scenario_file(dir: &Path) -> (PathBuf, SimScenario) {
    let mut s = SimScenario::load("radar").expect("preset");
    let target = |id: &str, position: [f64; 2], velocity: [f64; 2]| TargetSpec {
        id: id.into(),
        size_m: 5.0,
        size_known: false,
        motion: TargetMotion::Segments {
            position,
            velocity,
            z_m: 0.0,
            segments: Vec::new(),
        },
        jitter: Jitter::default(),
    };
    s.targets = vec![
        target("T0", [600.0, 400.0], [4.0, -2.0]),
        target("T1", [-500.0, 700.0], [-3.0, -3.0]),
    ];
    for sensor in &mut s.sensors {
        sensor.rate_hz = RATE_HZ;
        sensor.noise_std = vec![3.0, 0.003];
    }
    let path = dir.join("two-targets.json");
    std::fs::write(&path, s.to_json()).expect("write the scenario");
    (path, s)
}

/// `harrier-sim` as vehicle 1 on `host`, a Zenoh client of `router` (an endpoint), with `extra`
/// flags.
fn harrier_sim(dir: &Path, host: &Host, scenario: &Path, router: &str, extra: &[&str]) -> Proc {
    let mut cmd = host.command(&target_bin("harrier-sim"));
    cmd.arg("--scenario")
        .arg(scenario)
        .args(["--seed", "3", "--gcs", "none", "--truth-hz", "10"])
        .args(["--speedup", &SPEEDUP.to_string()])
        .args(["--api", &format!("udpin:{}:0", host.addr)])
        .args(["--zenoh-mode", "client", "--zenoh-connect", router])
        .args(extra);
    Proc::spawn("harrier-sim", cmd, dir.join("sim.log"))
}

/// A running `harrier serve` and its API address.
struct Server {
    proc: Proc,
    api: SocketAddr,
}

/// `harrier serve` on `host`: tracker `ekf`, a Zenoh client of `router` (an endpoint) with the
/// `[zenoh]` lines `zenoh_extra`, no MAVLink, its API on the host's address (port 0).
fn harrier_serve(
    dir: &Path,
    name: &str,
    host: &Host,
    scenario: &SimScenario,
    router: &str,
    zenoh_extra: &str,
) -> Server {
    let o = scenario.origin;
    let config = dir.join(format!("{name}.toml"));
    std::fs::write(
        &config,
        format!(
            "[frame]\norigin = {{ lat_deg = {:?}, lon_deg = {:?}, alt_m = {:?} }}\n\
             [tracker]\nestimator = \"ekf\"\nscan_period_s = {:?}\n\
             [clock]\nreal_time = false\n\
             [zenoh]\nmode = \"client\"\nlisten = []\nconnect = [\"{router}\"]\n{zenoh_extra}\n\
             [mavlink]\ngcs = []\nrouter = []\n",
            o.lat_deg,
            o.lon_deg,
            o.alt_m,
            1.0 / RATE_HZ,
        ),
    )
    .expect("write the configuration");
    let cmd = host.command(&target_bin("harrier"));
    let (proc, api) = harrier_serve_in(cmd, name, &config, &host.addr.to_string(), dir);
    Server { proc, api }
}

fn tracks(server: &Server) -> Value {
    let (status, body) = http_get(server.api, "/api/v1/tracks");
    assert_eq!(status, 200, "{body}");
    serde_json::from_str(&body).expect("tracks JSON")
}

/// The value of one series of the server's `/metrics` (0 when absent).
fn metric(server: &Server, series: &str) -> f64 {
    let (status, text) = http_get(server.api, "/api/v1/metrics");
    assert_eq!(status, 200, "{text}");
    metric_value(&text, series)
}

/// A Zenoh client session of this test's own.
fn client_session(router: &str, tls: TlsConfig) -> zenoh::Result<zenoh::Session> {
    let config = BusConfig {
        mode: Mode::Client,
        connect: vec![router.to_owned()],
        tls,
        ..BusConfig::default()
    }
    .to_zenoh()
    .expect("config");
    zenoh::open(config).wait()
}

/// The simulator's truth as it arrives (the last 400 samples).
struct Truth {
    samples: Arc<Mutex<Vec<TruthSample>>>,
    _sub: zenoh::pubsub::Subscriber<()>,
}

impl Truth {
    fn subscribe(session: &zenoh::Session) -> Self {
        let samples = Arc::new(Mutex::new(Vec::new()));
        let s = Arc::clone(&samples);
        let sub = session
            .declare_subscriber(TRUTH_KEY)
            .callback(move |sample| {
                if let Ok(t) = TruthSample::from_json(&sample.payload().to_bytes()) {
                    let mut v = s.lock().expect("lock");
                    v.push(t);
                    let n = v.len();
                    v.drain(..n.saturating_sub(400));
                }
            })
            .wait()
            .expect("subscribe to the truth");
        Self { samples, _sub: sub }
    }

    /// Target positions at UNIX time `t`, from the sample nearest in time, extrapolated.
    fn at(&self, t: f64) -> Option<Vec<[f64; 2]>> {
        let v = self.samples.lock().expect("lock");
        let s = v.iter().min_by(|a, b| {
            let d = |s: &TruthSample| (s.time_unix.unwrap_or(f64::NAN) - t).abs();
            d(a).total_cmp(&d(b))
        })?;
        let dt = t - s.time_unix?;
        (dt.abs() < 1.0).then(|| targets_at(s, t))
    }
}

fn dist(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// A track's time, position and velocity.
fn track_xy(k: &Value) -> (f64, [f64; 2], [f64; 2]) {
    let f = |i: usize| k["state"][i].as_f64().expect("state");
    (k["t"].as_f64().expect("t"), [f(0), f(1)], [f(3), f(4)])
}

/// One poll: the snapshot time and the largest error, when there is exactly one confirmed
/// track per target (each track's nearest target, all different).
fn poll(server: &Server, truth: &Truth, targets: usize) -> Option<(f64, f64, Value)> {
    let v = tracks(server);
    let list = v["tracks"].as_array()?;
    if list.len() != targets {
        return None;
    }
    let mut nearest = Vec::new();
    let mut worst: f64 = 0.0;
    for k in list {
        let (t, x, _) = track_xy(k);
        let (i, e) = truth
            .at(t)?
            .into_iter()
            .map(|g| dist(x, g))
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        nearest.push(i);
        worst = worst.max(e);
    }
    nearest.sort_unstable();
    nearest.dedup();
    (nearest.len() == targets).then_some((v["t"].as_f64()?, worst, v))
}

/// Polls until `STABLE_POLLS` polls at distinct scan times each show one track per target within
/// `MAX_ERROR_M`; returns the largest error over them.
fn stable_tracks(server: &mut Server, truth: &Truth, targets: usize) -> f64 {
    let start = Instant::now();
    let mut run: Vec<(f64, f64)> = Vec::new();
    loop {
        server.proc.assert_running();
        match poll(server, truth, targets) {
            Some((t, e, _)) if e <= MAX_ERROR_M => {
                if run.last().is_none_or(|last| last.0 < t) {
                    run.push((t, e));
                }
            }
            _ => run.clear(),
        }
        if run.len() >= STABLE_POLLS {
            return run.iter().map(|p| p.1).fold(0.0, f64::max);
        }
        assert!(
            start.elapsed() < TRACKS_DEADLINE,
            "{}: no stable tracks within {TRACKS_DEADLINE:?}: {}\n{}",
            server.proc.what,
            tracks(server),
            server.proc.log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

/// Largest distance between the two servers' tracks, each extrapolated to the later of their
/// times, over `polls` paired polls (each track paired with the nearest of the other's).
fn disagreement(a: &Server, b: &Server, targets: usize, polls: usize) -> f64 {
    let mut worst: f64 = 0.0;
    for _ in 0..polls {
        let (ta, tb) = (tracks(a), tracks(b));
        let (la, lb) = (
            ta["tracks"].as_array().expect("tracks"),
            tb["tracks"].as_array().expect("tracks"),
        );
        assert_eq!(
            (la.len(), lb.len()),
            (targets, targets),
            "the servers see different tracks:\n{ta}\n{tb}"
        );
        for k in la {
            let (t1, x1, v1) = track_xy(k);
            let d = lb
                .iter()
                .map(|m| {
                    let (t2, x2, v2) = track_xy(m);
                    let t = t1.max(t2);
                    let p1 = [x1[0] + v1[0] * (t - t1), x1[1] + v1[1] * (t - t1)];
                    let p2 = [x2[0] + v2[0] * (t - t2), x2[1] + v2[1] * (t - t2)];
                    dist(p1, p2)
                })
                .fold(f64::INFINITY, f64::min);
            worst = worst.max(d);
        }
        std::thread::sleep(Duration::from_millis(150));
    }
    worst
}

#[test]
fn two_hosts_through_a_router() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (scenario_path, scenario) = scenario_file(dir.path());
    let targets = scenario.targets.len();
    let port = free_tcp_port();

    // Three hosts: the simulator's and two ground stations', each joined to the root namespace
    // (the router's) by a veth pair.
    let namespaces: Result<Vec<(Netns, Veth)>, String> = (0..3)
        .map(|k| {
            let ns = Netns::new(&k.to_string())?;
            let veth = Veth::new(None, &ns, k)?;
            Ok((ns, veth))
        })
        .collect();
    let (hosts, _namespaces) = match namespaces {
        Ok(ns) => {
            let hosts: Vec<Host> = ns
                .iter()
                .map(|(n, v)| Host {
                    ns: Some(n.name.clone()),
                    addr: v.b_addr.clone(),
                    router: v.a_addr.clone(),
                })
                .collect();
            eprintln!(
                "network namespaces: {}",
                ns.iter()
                    .map(|(n, v)| format!("{} ({} via {})", n.name, v.b_addr, v.a_addr))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
            (hosts, ns)
        }
        Err(e) => {
            eprintln!(
                "!!!!!!!!!!\n!!! network namespaces are not permitted here ({e}):\n!!! FALLBACK: \
                 the simulator, the servers and zenohd run as processes on loopback\n!!!!!!!!!!"
            );
            (vec![Host::loopback(); 3], Vec::new())
        }
    };
    let mut listen = vec![format!("tcp/127.0.0.1:{port}")];
    for h in &hosts {
        let e = format!("tcp/{}:{port}", h.router);
        if !listen.contains(&e) {
            listen.push(e);
        }
    }
    let mut args = Vec::new();
    for e in &listen {
        args.push("-l".to_owned());
        args.push(e.clone());
    }
    let _router = zenohd(dir.path(), "zenohd.log", &args);
    let router_of = |h: &Host| format!("tcp/{}:{port}", h.router);

    if hosts[0].ns.is_some() {
        // The simulator's namespace has no route to the servers' but to the router.
        let ns = hosts[0].ns.as_deref().expect("namespace");
        assert!(
            run(&[
                "ip",
                "netns",
                "exec",
                ns,
                "ip",
                "route",
                "get",
                &hosts[1].addr
            ])
            .is_err(),
            "{ns} reaches {} without the router",
            hosts[1].addr
        );
    }

    let observer = client_session(&format!("tcp/127.0.0.1:{port}"), TlsConfig::default())
        .expect("this test's session");
    let truth = Truth::subscribe(&observer);
    let mut sim = harrier_sim(
        dir.path(),
        &hosts[0],
        &scenario_path,
        &router_of(&hosts[0]),
        &[],
    );
    let mut a = harrier_serve(
        dir.path(),
        "gcs-a",
        &hosts[1],
        &scenario,
        &router_of(&hosts[1]),
        "",
    );
    let mut b = harrier_serve(
        dir.path(),
        "gcs-b",
        &hosts[2],
        &scenario,
        &router_of(&hosts[2]),
        "",
    );
    let started = Instant::now();
    let err_a = stable_tracks(&mut a, &truth, targets);
    let err_b = stable_tracks(&mut b, &truth, targets);
    let apart = disagreement(&a, &b, targets, 10);
    sim.assert_running();
    eprintln!(
        "two hosts through zenohd: {targets} targets tracked by both servers after {:.1} s; \
         largest error {err_a:.2} m (gcs-a), {err_b:.2} m (gcs-b); largest disagreement {apart:.2} m",
        started.elapsed().as_secs_f64()
    );
    assert!(
        apart <= MAX_DISAGREEMENT_M,
        "the servers disagree by {apart} m"
    );
    for s in [&a, &b] {
        assert!(metric(s, "harrier_scans_ingested_total{vehicle=\"1\"}") > 0.0);
    }
}

#[test]
fn a_restarted_router_is_rejoined_and_the_loss_counted() {
    let dir = tempfile::tempdir().expect("tempdir");
    let (scenario_path, scenario) = scenario_file(dir.path());
    let targets = scenario.targets.len();
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let args = ["-l".to_owned(), endpoint.clone()];
    let mut router = zenohd(dir.path(), "zenohd-1.log", &args);
    let host = Host::loopback();
    let observer = client_session(&endpoint, TlsConfig::default()).expect("this test's session");
    let truth = Truth::subscribe(&observer);
    let mut sim = harrier_sim(dir.path(), &host, &scenario_path, &endpoint, &[]);
    let mut server = harrier_serve(dir.path(), "gcs", &host, &scenario, &endpoint, "");
    stable_tracks(&mut server, &truth, targets);

    let ingested = "harrier_scans_ingested_total{vehicle=\"1\"}";
    let lost = "harrier_seq_lost_total{vehicle=\"1\"}";
    let lost_before = metric(&server, lost);
    let uptime_before = metric(&server, "harrier_uptime_seconds");
    let pid = server.proc.child.id();

    // The outage: no scan reaches the server while the router is down.
    router.kill();
    let killed = Instant::now();
    let outage = Duration::from_secs(3);
    std::thread::sleep(Duration::from_millis(500));
    let frozen = metric(&server, ingested);
    std::thread::sleep(outage - Duration::from_millis(500));
    assert_eq!(
        metric(&server, ingested),
        frozen,
        "scans arrived without the router"
    );
    let mut router = zenohd(dir.path(), "zenohd-2.log", &args);
    let restarted = killed.elapsed();

    // Ingest resumes by itself: new scans, tracks following the truth again.
    let deadline = Instant::now() + Duration::from_secs(30);
    while metric(&server, ingested) < frozen + 5.0 {
        server.proc.assert_running();
        assert!(
            Instant::now() < deadline,
            "ingest did not resume within 30 s of the router's restart:\n{}",
            server.proc.log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let resumed = killed.elapsed();
    let err = stable_tracks(&mut server, &truth, targets);
    let lost_during = metric(&server, lost) - lost_before;
    let uptime_after = metric(&server, "harrier_uptime_seconds");
    sim.assert_running();
    router.assert_running();
    eprintln!(
        "router restart: down {:.2} s, scans again {:.2} s after the kill; {lost_during} scans \
         counted lost; tracks within {err:.2} m again; server uptime {uptime_before:.1} s → \
         {uptime_after:.1} s",
        restarted.as_secs_f64(),
        resumed.as_secs_f64()
    );
    // The same process, never restarted.
    assert_eq!(server.proc.child.id(), pid);
    assert!(uptime_after >= uptime_before + restarted.as_secs_f64());
    // What the simulator published while nobody received it (2 Hz × 5 speedup = 10 scans per
    // wall second) is counted: at least the time the router was down, at most until ingest
    // resumed.
    let per_s = RATE_HZ * SPEEDUP;
    assert!(
        lost_during >= (restarted.as_secs_f64() * per_s * 0.8).floor(),
        "{lost_during} scans counted lost for {:.2} s down",
        restarted.as_secs_f64()
    );
    assert!(
        lost_during <= (resumed.as_secs_f64() * per_s * 1.2).ceil(),
        "{lost_during} scans counted lost, resumed after {:.2} s",
        resumed.as_secs_f64()
    );
}

#[test]
fn tls_and_access_control() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    test_certificates(d, &["router", "harrier-sim", "harrier-gcs", "intruder"]);
    let path = |f: &str| d.join(f).display().to_string();
    let port = free_tcp_port();
    let endpoint = format!("tls/127.0.0.1:{port}");
    // The router of docs/deploy.md: TLS only, client certificates required, default deny.
    let config = d.join("zenohd.json5");
    std::fs::write(
        &config,
        serde_json::json!({
            "mode": "router",
            "listen": {"endpoints": [endpoint]},
            "transport": {"link": {"tls": {
                "root_ca_certificate": path("ca.pem"),
                "listen_certificate": path("router.pem"),
                "listen_private_key": path("router.key"),
                "enable_mtls": true,
            }}},
            "access_control": {
                "enabled": true,
                "default_permission": "deny",
                "rules": [
                    {"id": "publish-detections", "permission": "allow", "flows": ["ingress"],
                     "messages": ["put"],
                     "key_exprs": ["harrier/v1/vehicle/*/detections", "harrier/v1/sim/truth"]},
                    {"id": "see-subscribers", "permission": "allow", "flows": ["egress"],
                     "messages": ["declare_subscriber"], "key_exprs": ["harrier/v1/**"]},
                    {"id": "subscribe", "permission": "allow", "flows": ["ingress"],
                     "messages": ["declare_subscriber"], "key_exprs": ["harrier/v1/**"]},
                    {"id": "receive", "permission": "allow", "flows": ["egress"],
                     "messages": ["put"], "key_exprs": ["harrier/v1/**"]},
                    {"id": "publish-tracks", "permission": "allow", "flows": ["ingress"],
                     "messages": ["put"], "key_exprs": ["harrier/v1/tracks"]},
                ],
                "subjects": [
                    {"id": "companions", "cert_common_names": ["harrier-sim"]},
                    {"id": "ground-stations", "cert_common_names": ["harrier-gcs"]},
                    {"id": "any-client"},
                ],
                "policies": [
                    {"rules": ["publish-detections"], "subjects": ["companions"]},
                    {"rules": ["subscribe", "receive", "publish-tracks"],
                     "subjects": ["ground-stations"]},
                    {"rules": ["see-subscribers"], "subjects": ["any-client"]},
                ],
            },
        })
        .to_string(),
    )
    .expect("write the router's configuration");
    let _router = zenohd(
        d,
        "zenohd.log",
        &["--config".to_owned(), config.display().to_string()],
    );
    let tls_of = |name: &str| TlsConfig {
        root_ca_certificate: Some(path("ca.pem")),
        connect_certificate: Some(path(&format!("{name}.pem"))),
        connect_private_key: Some(path(&format!("{name}.key"))),
        enable_mtls: true,
        ..TlsConfig::default()
    };

    // Plain TCP to the TLS port: no session.
    let plain = client_session(&format!("tcp/127.0.0.1:{port}"), TlsConfig::default());
    assert!(plain.is_err(), "a plain-TCP session opened on the TLS port");
    // A client certificate of another CA, even with the companion's name: no session.
    let rogue = d.join("rogue");
    std::fs::create_dir(&rogue).expect("mkdir rogue");
    test_certificates(&rogue, &["harrier-sim"]);
    let forged = client_session(
        &endpoint,
        TlsConfig {
            connect_certificate: Some(rogue.join("harrier-sim.pem").display().to_string()),
            connect_private_key: Some(rogue.join("harrier-sim.key").display().to_string()),
            ..tls_of("harrier-sim")
        },
    );
    assert!(
        forged.is_err(),
        "a session opened with a certificate of another CA"
    );

    let (scenario_path, scenario) = scenario_file(d);
    let targets = scenario.targets.len();
    let observer = client_session(&endpoint, tls_of("harrier-gcs")).expect("observer session");
    let truth = Truth::subscribe(&observer);
    let published = observer
        .declare_subscriber(TRACKS_KEY)
        .wait()
        .expect("subscribe to the tracks");
    let host = Host::loopback();
    let (ca, cert, key) = (
        path("ca.pem"),
        path("harrier-sim.pem"),
        path("harrier-sim.key"),
    );
    let _sim = harrier_sim(
        d,
        &host,
        &scenario_path,
        &endpoint,
        &[
            "--zenoh-tls-root-ca",
            &ca,
            "--zenoh-tls-cert",
            &cert,
            "--zenoh-tls-key",
            &key,
        ],
    );
    let tls_lines = format!(
        "root_ca_certificate = '{}'\nenable_mtls = true\nconnect_certificate = '{}'\n\
         connect_private_key = '{}'\n",
        path("ca.pem"),
        path("harrier-gcs.pem"),
        path("harrier-gcs.key")
    );
    let mut server = harrier_serve(d, "gcs", &host, &scenario, &endpoint, &tls_lines);
    let err = stable_tracks(&mut server, &truth, targets);
    // The server's tracks reach the router's other clients too: the latest message has them.
    let mut seen = 0;
    while let Ok(Some(_)) = published.try_recv() {
        seen += 1;
    }
    assert!(seen > 0, "no tracks published through the router");
    let tracks_sample = published
        .recv_timeout(Duration::from_secs(10))
        .expect("tracks subscription")
        .expect("the server's tracks on harrier/v1/tracks within 10 s");
    let n = serde_json::from_slice::<Value>(&tracks_sample.payload().to_bytes())
        .expect("tracks JSON")["tracks"]
        .as_array()
        .map_or(0, Vec::len);
    assert_eq!(n, targets, "tracks published through the router");

    // The intruder (same CA, another name) and the companion put on detections keys of vehicles
    // the simulator does not have, side by side: only the companion's puts reach the server.
    let intruder = client_session(&endpoint, tls_of("intruder")).expect("intruder session");
    let companion = client_session(&endpoint, tls_of("harrier-sim")).expect("companion session");
    let denied = intruder
        .declare_publisher("harrier/v1/vehicle/8/detections")
        .wait()
        .expect("intruder publisher");
    let allowed = companion
        .declare_publisher("harrier/v1/vehicle/9/detections")
        .wait()
        .expect("companion publisher");
    let received = |v: u8| {
        metric(
            &server,
            &format!("harrier_payloads_received_total{{vehicle=\"{v}\"}}"),
        )
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut intruder_matched = false;
    let mut puts = 0;
    while received(9) < 20.0 {
        intruder_matched |= denied.matching_status().wait().is_ok_and(|m| m.matching());
        denied.put("probe").wait().expect("intruder put");
        allowed.put("probe").wait().expect("companion put");
        puts += 1;
        assert!(
            Instant::now() < deadline,
            "the companion's puts did not reach the server ({} of {puts})",
            received(9)
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let (from_intruder, from_companion) = (received(8), received(9));
    eprintln!(
        "TLS + access control: tracks within {err:.2} m through the TLS router; of {puts} puts \
         each, {from_companion} from CN=harrier-sim reached the server, {from_intruder} from \
         CN=intruder (whose publisher matched the server's subscriber: {intruder_matched})"
    );
    assert!(
        intruder_matched,
        "the intruder never saw a subscriber: its puts were not even sent"
    );
    assert_eq!(from_intruder, 0.0, "the intruder's puts reached the server");
    server.proc.assert_running();
}

/// One-way latency of `n` small puts at 50 Hz from `publisher` to `subscriber` (this process's
/// clock on both ends): sorted, in ms. Every put must arrive, in order.
fn latencies(publisher: &zenoh::Session, subscriber: &zenoh::Session, n: usize) -> Vec<f64> {
    let key = "harrier/v1/vehicle/1/detections";
    let epoch = Instant::now();
    let got = Arc::new(Mutex::new(Vec::<(u64, f64)>::new()));
    let g = Arc::clone(&got);
    let _sub = subscriber
        .declare_subscriber(key)
        .callback(move |s| {
            let at = epoch.elapsed().as_secs_f64();
            let bytes = s.payload().to_bytes();
            let text = String::from_utf8_lossy(&bytes);
            if let Some((k, sent)) = text.split_once(' ') {
                if let (Ok(k), Ok(sent)) = (k.parse(), sent.parse::<f64>()) {
                    g.lock().expect("lock").push((k, (at - sent) * 1e3));
                }
            }
        })
        .wait()
        .expect("subscribe");
    let p = publisher.declare_publisher(key).wait().expect("publisher");
    // Until the subscription has reached the publisher (no fixed sleep).
    let deadline = Instant::now() + Duration::from_secs(10);
    while !p.matching_status().wait().is_ok_and(|m| m.matching()) {
        assert!(Instant::now() < deadline, "the subscriber never matched");
        std::thread::sleep(Duration::from_millis(10));
    }
    for k in 0..n {
        p.put(format!("{k} {}", epoch.elapsed().as_secs_f64()))
            .wait()
            .expect("put");
        std::thread::sleep(Duration::from_millis(20));
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while got.lock().expect("lock").len() < n {
        assert!(
            Instant::now() < deadline,
            "{} of {n} puts arrived",
            got.lock().expect("lock").len()
        );
        std::thread::sleep(Duration::from_millis(10));
    }
    let v = got.lock().expect("lock").clone();
    assert!(
        v.iter().enumerate().all(|(i, (k, _))| *k == i as u64),
        "lost or reordered"
    );
    let mut ms: Vec<f64> = v.into_iter().map(|(_, l)| l).collect();
    ms.sort_by(f64::total_cmp);
    ms
}

/// The router's cost on the detection path (BENCHMARKS.md): the latency of 500 puts at 50 Hz,
/// peer to peer on loopback, and between two clients of `zenohd` on loopback.
#[test]
fn latency_through_the_router_against_peer_to_peer() {
    let dir = tempfile::tempdir().expect("tempdir");
    let n = 500;
    let q = |v: &[f64], p: f64| v[((v.len() - 1) as f64 * p).round() as usize];

    let direct = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let listener = BusConfig {
        listen: vec![direct.clone()],
        ..BusConfig::default()
    }
    .open()
    .expect("peer session");
    let dialer = BusConfig {
        connect: vec![direct],
        ..BusConfig::default()
    }
    .open()
    .expect("peer session");
    let peer = latencies(&listener, &dialer, n);

    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let _router = zenohd(
        dir.path(),
        "zenohd.log",
        &["-l".to_owned(), endpoint.clone()],
    );
    let a = client_session(&endpoint, TlsConfig::default()).expect("client session");
    let b = client_session(&endpoint, TlsConfig::default()).expect("client session");
    let routed = latencies(&a, &b, n);
    eprintln!(
        "latency of {n} puts at 50 Hz (ms): peer to peer p50 {:.3} p99 {:.3} max {:.3}; \
         through zenohd p50 {:.3} p99 {:.3} max {:.3}",
        q(&peer, 0.5),
        q(&peer, 0.99),
        q(&peer, 1.0),
        q(&routed, 0.5),
        q(&routed, 0.99),
        q(&routed, 1.0)
    );
    // One hop more on loopback: well under the 0.1 s reorder window the server waits anyway.
    assert!(
        q(&routed, 0.99) < 50.0,
        "p99 through the router {:.1} ms",
        q(&routed, 0.99)
    );
}
