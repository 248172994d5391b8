//! The session recording survives a SIGKILL (RECORDING.md), real parts only: the real `harrier`
//! binary (`harrier serve`, `ekf` track engine, `[recorder]` on a SQLite file in a temporary
//! directory) tracks harrier-sim's `cimm-road` world (two grounded vehicles in this process whose
//! cameras geolocate the road target at 1 Hz, sped up 5×) over real Zenoh on loopback.
//!
//! Once the file holds enough scans (polled read-only through `harrier_server::sessions`, as a
//! user would while the server runs) the server is killed with SIGKILL. Checked then: the file
//! opens, its session is not marked ended, the last scan it holds was received at most 1 s before
//! the kill, it holds at least as many scans as this test's own Zenoh subscriber received from
//! the server's first scan up to 1 s before the kill, and the session exports as a single-target `gcs-scenario/1` directory
//! that `kf` replays (`harrier_server::replay`) and `score.py` scores, agreeing with harrier's
//! own score. A new recorder then opens the same file and starts session 2, the killed one
//! unchanged.
//!
//! The binary is `target/<profile>/harrier`, next to this test's directory: `cargo test
//! --workspace` builds it (server/tests/cli.rs needs it); run alone, build it first with `cargo
//! build -p harrier-server`. Every wait polls a real condition under a deadline; the server is
//! killed if the test fails.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harrier_core::detection::DETECTIONS_KEY_ALL;
use harrier_server::engine::Params;
use harrier_server::live::recorder::{Recorder, SessionMeta};
use harrier_server::replay;
use harrier_server::sessions::{self, SessionInfo};
use harrier_sim::bus::BusConfig;
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
use harrier_sim::live::LiveConfig;
use harrier_sim::setup::SimScenario;
use harrier_tests::free_tcp_port;
use zenoh::Wait as _;

/// Simulated seconds per wall second.
const SPEEDUP: f64 = 5.0;
/// Scans to wait for before the kill (2 vehicles × 5 scans per wall second: about 10 s).
const SCANS: u64 = 100;
/// What a kill may lose (RECORDING.md): scans received up to this long before it are in the file.
const MAX_LOSS_S: f64 = 1.0;
/// Longest wait for the recording to fill.
const DEADLINE: Duration = Duration::from_secs(90);

fn unix_now() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// `target/<profile>/harrier`, beside this test executable's `deps/` directory.
fn harrier_bin() -> PathBuf {
    let exe = std::env::current_exe().expect("test executable");
    let bin = exe
        .parent()
        .and_then(Path::parent)
        .map(|d| d.join("harrier"))
        .expect("target directory");
    assert!(
        bin.is_file(),
        "{} not found: build it with `cargo build -p harrier-server` (cargo test --workspace does)",
        bin.display()
    );
    bin
}

/// The server process; killed (SIGKILL) and reaped when dropped, so a failing test leaves none.
struct Server {
    child: Child,
    stderr: PathBuf,
}

impl Server {
    fn log(&self) -> String {
        std::fs::read_to_string(&self.stderr).unwrap_or_default()
    }
    /// Panics with the server's log when it has exited.
    fn assert_running(&mut self) {
        if let Some(status) = self.child.try_wait().expect("wait for the server") {
            panic!("harrier serve exited ({status}):\n{}", self.log());
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Polls the session file until its one session has `SCANS` scans and some truth.
fn wait_for_rows(db: &Path, server: &mut Server) -> SessionInfo {
    let start = Instant::now();
    loop {
        server.assert_running();
        // Before the server has created its schema the file is missing or empty: not an error.
        if let Ok(mut all) = sessions::list(db) {
            if let Some(s) = all.pop().filter(|s| s.scans >= SCANS && s.truth_rows > 0) {
                assert!(all.is_empty(), "one session expected, also {all:?}");
                return s;
            }
        }
        assert!(
            start.elapsed() < DEADLINE,
            "the recording did not reach {SCANS} scans within {DEADLINE:?}: {:?}\n{}",
            sessions::list(db).map_err(|e| e.to_string()),
            server.log()
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_killed_server_keeps_its_recording_which_exports_replays_and_scores() {
    let started = Instant::now();
    let bin = harrier_bin();
    let dir = tempfile::tempdir().expect("tempdir");
    let db = dir.path().join("sessions.sqlite");
    let scenario = SimScenario::load("cimm-road").expect("preset");
    let o = scenario.origin;

    // The simulated world, publishing on its own Zenoh endpoint.
    let sim_endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let mut world = WorldConfig::new(LiveConfig {
        scenario,
        seed: 5,
        speedup: SPEEDUP,
        truth_hz: 10.0,
    });
    world.vehicles = vec![WorldVehicle::grounded(1), WorldVehicle::grounded(2)];
    world.zenoh.listen = vec![sim_endpoint.clone()];
    let sim = SimWorld::start(&world).expect("start the simulated world");

    // This test's own subscriber: the wall time each scan arrived.
    let session = zenoh::open(
        BusConfig {
            connect: vec![sim_endpoint.clone()],
            ..BusConfig::default()
        }
        .to_zenoh()
        .expect("zenoh config"),
    )
    .wait()
    .expect("open the test's Zenoh session");
    let arrivals = Arc::new(Mutex::new(Vec::<f64>::new()));
    let a = Arc::clone(&arrivals);
    let subscriber = session
        .declare_subscriber(DETECTIONS_KEY_ALL)
        .callback(move |_| a.lock().expect("lock").push(unix_now()))
        .wait()
        .expect("subscribe");

    // The server, recording.
    let config = dir.path().join("harrier.toml");
    std::fs::write(
        &config,
        format!(
            "[frame]\norigin = {{ lat_deg = {:?}, lon_deg = {:?}, alt_m = {:?} }}\n\
             [tracker]\nestimator = \"ekf\"\n\
             [zenoh]\nlisten = [\"tcp/127.0.0.1:{}\"]\nconnect = [\"{sim_endpoint}\"]\n\
             tracks_key = \"\"\n\
             [recorder]\npath = '{}'\nflush_ms = 200\ntruth = true\n\
             [mavlink]\ngcs = [\"udpin:127.0.0.1:0\"]\nrouter = []\n",
            o.lat_deg,
            o.lon_deg,
            o.alt_m,
            free_tcp_port(),
            db.display()
        ),
    )
    .expect("write the configuration");
    let stderr = dir.path().join("serve.log");
    let mut server = Server {
        child: Command::new(&bin)
            .arg("serve")
            .arg("--config")
            .arg(&config)
            .args(["--listen", "127.0.0.1:0"])
            .env("RUST_LOG", "info,zenoh=warn")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(std::fs::File::create(&stderr).expect("log file"))
            .spawn()
            .unwrap_or_else(|e| panic!("start {}: {e}", bin.display())),
        stderr,
    };

    let before = wait_for_rows(&db, &mut server);
    let kill_unix = unix_now();
    server.child.kill().expect("SIGKILL the server");
    let status = server.child.wait().expect("reap the server");
    assert!(!status.success(), "killed, not exited: {status}");
    // Scans this test received while the server surely was subscribed too (from 0.5 s after its
    // first recorded scan) up to 1 s before the kill.
    let from = before.first_received_unix.expect("scans") + 0.5;
    let seen_before = arrivals
        .lock()
        .expect("lock")
        .iter()
        .filter(|t| (from..=kill_unix - MAX_LOSS_S).contains(*t))
        .count() as u64;
    subscriber.undeclare().wait().expect("undeclare");
    session.close().wait().expect("close the test's session");
    sim.stop();

    // The file opens (read-only, after the kill) and holds what was received up to 1 s before.
    let all = sessions::list(&db).expect("the killed server's file opens");
    assert_eq!(all.len(), 1, "{all:?}");
    let s = &all[0];
    assert!(
        s.ended_unix.is_none(),
        "a killed session is not marked ended: {s:?}"
    );
    assert!(s.scans >= before.scans, "{s:?} vs {before:?}");
    let last = s.last_received_unix.expect("scans");
    let lag = kill_unix - last;
    assert!(
        (0.0..=MAX_LOSS_S).contains(&lag),
        "the last recorded scan was received {lag:.3} s before the kill"
    );
    assert!(
        s.scans >= seen_before,
        "{} scans recorded, but this test received {seen_before} between the server's first \
         scan and {MAX_LOSS_S} s before the kill",
        s.scans
    );
    assert_eq!(s.vehicles, ["1", "2"]);
    assert_eq!(s.estimator, "ekf");

    // Export, replay, score.
    let e = sessions::export(&db, s.id).expect("export");
    assert!(
        !e.multi && e.truth_csv.is_some() && e.time_line == "time_unix",
        "{e:?}"
    );
    let out = dir.path().join("export");
    e.write_to(&out).expect("write the scenario");
    let data = replay::load(&out).expect("the export loads");
    let report = replay::run(&data, "kf", &Params::default()).expect("kf replays the export");
    assert!(report.rejected.is_empty(), "{:?}", report.rejected);
    let estimates = out.join("estimates.jsonl");
    replay::write_estimates(&estimates, &report.estimates).expect("write estimates");
    let py = harrier_tests::score_py(&out, &estimates).expect("score.py scores the export");
    let rust = report
        .score
        .as_ref()
        .and_then(|s| s.pos_rmse)
        .expect("pos RMSE");
    let python = py["pos_rmse"].as_f64().expect("score.py pos_rmse");
    assert!(
        (rust - python).abs() <= 1e-9 * (1.0 + python),
        "{rust} vs {python}"
    );
    // Geolocation noise is 10 m per axis: a CV Kalman filter on two cameras does better.
    assert!(python < 10.0, "kf position RMSE {python} m");

    // A new server carries on in the same file: the killed session stays as it was.
    let meta = SessionMeta {
        started_unix: unix_now(),
        origin: o,
        plane_z: 0.0,
        estimator: "imm".into(),
        config_json: "{}".into(),
    };
    let next = Recorder::open(&db, &meta, Duration::from_millis(200), 16).expect("reopen");
    assert_eq!(next.session_id(), s.id + 1);
    next.close().expect("close");
    let all = sessions::list(&db).expect("list");
    assert_eq!((all.len(), &all[0]), (2, s));
    assert!(all[1].ended_unix.is_some(), "{:?}", all[1]);

    eprintln!(
        "recording: {} scans, {} detections, {} track rows, {} truth rows ({} dropped); \
         last scan received {lag:.3} s before the SIGKILL; {seen_before} scans received by the \
         test from the server's first scan to {MAX_LOSS_S} s before it, {} recorded; export: {} lines, {} truth rows over {:.0} s; \
         kf position RMSE {python:.2} m (score.py), {:.1} s in all",
        s.scans,
        s.detections,
        s.track_rows,
        s.truth_rows,
        s.dropped,
        s.scans,
        e.lines,
        e.truth_rows,
        data.scenario.time.t_end,
        started.elapsed().as_secs_f64()
    );
}
