//! The session recording survives a SIGKILL (RECORDING.md), real parts only: the real `harrier`
//! binary (`harrier serve`, `ekf` track engine, `[recorder]` on a SQLite file in a temporary
//! directory) tracks harrier-sim's `cimm-road` world (two grounded vehicles in this process whose
//! cameras geolocate the road target at 1 Hz, sped up 5×) over real Zenoh on loopback.
//!
//! Once the file holds enough scans (polled read-only through
//! `harrier_recording::reader`, as a user would while the server runs) the server is
//! killed with SIGKILL. Checked then: the file
//! opens, its session is not marked ended, the last scan it holds was received at most 1 s before
//! the kill, it holds at least as many scans as this test's own Zenoh subscriber received from
//! the server's first scan up to 1 s before the kill, and the session exports as a single-target `gcs-scenario/1` directory
//! that `kf` replays (`harrier_tools::replay`) and `score.py` scores, agreeing with harrier's
//! own score. SQLite itself (rusqlite, read-only) finds `PRAGMA integrity_check` ok and every
//! sensor's `seq` without a gap; the seconds between the last recorded scan and the kill (the
//! data lost) are printed. A new recorder then opens the same file and starts session 2, the
//! killed one unchanged.
//!
//! The binary is `target/<profile>/harrier`, next to this test's directory: `cargo test
//! --workspace` builds it (cli/tests/cli.rs needs it); run alone, build it first with `cargo
//! build -p harrier-cli`. Every wait polls a real condition under a deadline; the server is
//! killed if the test fails.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use harrier_core::detection::DETECTIONS_KEY_ALL;
use harrier_engine::Params;
use harrier_recording::export;
use harrier_recording::reader::{self, SessionInfo};
use harrier_recording::writer::{Recorder, SessionMeta};
use harrier_sim::bus::BusConfig;
use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
use harrier_sim::sensor_loop::SensorLoopConfig;
use harrier_sim::setup::SimScenario;
use harrier_tests::{free_tcp_port, publish_standing_target, within};
use harrier_tools::replay;
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
        "{} not found: build it with `cargo build -p harrier-cli` (cargo test --workspace does)",
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

/// What the killed server's file holds, checked with SQLite itself (rusqlite, read-only).
struct FileCheck {
    /// Seconds between the last committed scan's receipt and the kill: the data lost.
    lost_s: f64,
    /// Scans per sensor, as `(vehicle, sensor, scans, first seq, last seq)`.
    sensors: Vec<(i64, String, i64, i64, i64)>,
}

impl std::fmt::Display for FileCheck {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "integrity_check ok; {:.3} s of scans lost at the SIGKILL; per sensor (vehicle, sensor, \
             scans, seq first..last, no gap): {:?}",
            self.lost_s, self.sensors
        )
    }
}

/// Opens the file as any SQLite user would after the kill: `PRAGMA integrity_check` is `ok`, the
/// session row is there (not ended), and each sensor's scans have consecutive `seq`s (harrier-sim
/// numbers every scan: a gap would be a scan the server received but the file lost in the middle).
fn check_file(db: &Path, session: i64, kill_unix: f64) -> FileCheck {
    let c = rusqlite::Connection::open_with_flags(db, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
        .expect("open the killed server's file");
    let ok: String = c
        .query_row("PRAGMA integrity_check", [], |r| r.get(0))
        .expect("integrity_check");
    assert_eq!(ok, "ok", "PRAGMA integrity_check");
    let (ended, last): (Option<f64>, f64) = c
        .query_row(
            "SELECT ended_unix, (SELECT max(received_unix) FROM scans WHERE session = ?1) \
             FROM sessions WHERE id = ?1",
            [session],
            |r| Ok((r.get(0)?, r.get(1)?)),
        )
        .expect("the session row");
    assert!(ended.is_none(), "killed, yet ended at {ended:?}");
    let mut st = c
        .prepare(
            "SELECT vehicle, sensor, count(*), min(seq), max(seq) FROM scans WHERE session = ?1 \
             GROUP BY vehicle, sensor ORDER BY vehicle, sensor",
        )
        .expect("prepare");
    let sensors: Vec<(i64, String, i64, i64, i64)> = st
        .query_map([session], |r| {
            Ok((r.get(0)?, r.get(1)?, r.get(2)?, r.get(3)?, r.get(4)?))
        })
        .expect("query")
        .collect::<Result<_, _>>()
        .expect("rows");
    assert_eq!(sensors.len(), 2, "{sensors:?}");
    for (vehicle, sensor, n, first, last) in &sensors {
        assert_eq!(
            last - first + 1,
            *n,
            "vehicle {vehicle} {sensor}: {n} scans for seq {first}..={last}: a gap"
        );
    }
    FileCheck {
        lost_s: kill_unix - last,
        sensors,
    }
}

/// Polls the session file until its one session has `SCANS` scans and some truth.
fn wait_for_rows(db: &Path, server: &mut Server) -> SessionInfo {
    let start = Instant::now();
    loop {
        server.assert_running();
        // Before the server has created its schema the file is missing or empty: not an error.
        if let Ok(mut all) = reader::list(db) {
            if let Some(s) = all.pop().filter(|s| s.scans >= SCANS && s.truth_rows > 0) {
                assert!(all.is_empty(), "one session expected, also {all:?}");
                return s;
            }
        }
        assert!(
            start.elapsed() < DEADLINE,
            "the recording did not reach {SCANS} scans within {DEADLINE:?}: {:?}\n{}",
            reader::list(db).map_err(|e| e.to_string()),
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
    let mut world = WorldConfig::new(SensorLoopConfig {
        scenario,
        seed: 5,
        speedup: SPEEDUP,
        truth_hz: 10.0,
        clock: Default::default(),
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
             [clock]\nreal_time = false\n\
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
    let all = reader::list(&db).expect("the killed server's file opens");
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
    let file = check_file(&db, s.id, kill_unix);
    // Scans this test's subscriber received after the last recorded one, before the kill: what
    // the kill lost (as far as another subscriber can tell).
    let lost_scans = arrivals
        .lock()
        .expect("lock")
        .iter()
        .filter(|t| **t > last && **t < kill_unix)
        .count();

    // Export, replay, score.
    let e = export::export(&db, s.id).expect("export");
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
    let all = reader::list(&db).expect("list");
    assert_eq!((all.len(), &all[0]), (2, s));
    assert!(all[1].ended_unix.is_some(), "{:?}", all[1]);

    eprintln!(
        "recording: {} scans, {} detections, {} track rows, {} truth rows ({} dropped); \
         last scan received {lag:.3} s before the SIGKILL; {seen_before} scans received by the \
         test from the server's first scan to {MAX_LOSS_S} s before it, {} recorded; export: {} lines, {} truth rows over {:.0} s; \
         kf position RMSE {python:.2} m (score.py), {:.1} s in all; {file}; {lost_scans} scans arrived at \
         the test's subscriber after the last recorded one, before the kill",
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

/// A small tmpfs mounted on a temporary directory (unmounted when dropped); `None`, said loudly,
/// where mounting is not permitted (not root, no `CAP_SYS_ADMIN`).
struct Tmpfs {
    dir: tempfile::TempDir,
}

impl Tmpfs {
    fn mount(size: &str) -> Option<Self> {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .expect("run mount");
        if !out.status.success() {
            eprintln!(
                "\n*** SKIPPED: cannot mount a tmpfs here ({}): the read-only and full-disk \
                 recording faults are NOT tested. Run as root (CI does). ***\n",
                String::from_utf8_lossy(&out.stderr).trim()
            );
            return None;
        }
        Some(Self { dir })
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    /// `mount -o remount,ro`: root cannot write it either.
    fn read_only(&self) {
        let ok = Command::new("mount")
            .args(["-o", "remount,ro"])
            .arg(self.path())
            .status()
            .expect("run mount")
            .success();
        assert!(ok, "remount {} read-only", self.path().display());
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = Command::new("umount").arg("-l").arg(self.path()).status();
    }
}

/// `GET path` (HTTP/1.0 on a fresh connection): status and body.
async fn http_get(addr: std::net::SocketAddr, path: &str) -> (u16, String) {
    use tokio::io::{AsyncReadExt as _, AsyncWriteExt as _};
    within(10, path, async {
        let mut s = tokio::net::TcpStream::connect(addr).await.expect("connect");
        s.write_all(format!("GET {path} HTTP/1.0\r\nHost: {addr}\r\n\r\n").as_bytes())
            .await
            .expect("request");
        let mut raw = String::new();
        s.read_to_string(&mut raw).await.expect("response");
        let status = raw
            .split(' ')
            .nth(1)
            .and_then(|c| c.parse().ok())
            .unwrap_or(0);
        let body = raw.split_once("\r\n\r\n").map_or("", |(_, b)| b).to_owned();
        (status, body)
    })
    .await
}

/// The value of one sample line of the Prometheus text (`None` when absent).
fn metric(text: &str, series: &str) -> Option<f64> {
    text.lines()
        .find_map(|l| l.strip_prefix(series)?.strip_prefix(' ')?.parse().ok())
}

/// An in-process server recording into `path`, its Zenoh session on a free port, and a session
/// of the test's own publishing a target at 50 Hz to it.
async fn recording_server(
    path: &Path,
) -> (
    harrier_server::LiveServer,
    zenoh::Session,
    tokio::task::JoinHandle<()>,
) {
    let endpoint = format!("tcp/127.0.0.1:{}", free_tcp_port());
    let mut config = harrier_server::config::Config::default();
    config.api.listen = std::net::SocketAddr::from(([127, 0, 0, 1], 0));
    config.zenoh.listen = vec![endpoint.clone()];
    config.zenoh.tracks_key = String::new();
    config.mavlink.gcs.clear();
    config.recorder.path = path.display().to_string();
    config.recorder.flush_ms = 100;
    let server = within(20, "start", harrier_server::start(&config))
        .await
        .expect("the server starts, whatever its recording place");
    let session = within(
        10,
        "open a session",
        zenoh::open(
            BusConfig {
                connect: vec![endpoint],
                ..BusConfig::default()
            }
            .to_zenoh()
            .expect("zenoh config"),
        ),
    )
    .await
    .expect("the test's Zenoh session");
    let publisher =
        publish_standing_target(&session, 5, [80.0, 40.0], [0.0, 0.0, 50.0], 50.0).await;
    (server, session, publisher)
}

/// Waits until the server holds a confirmed track and has processed `more` scans after now.
async fn tracking_goes_on(server: &harrier_server::LiveServer, more: u64) {
    let from = server.metrics().scans_ingested();
    let mut snap = server.snapshot();
    within(30, "live tracking", async {
        loop {
            let confirmed = snap
                .borrow_and_update()
                .tracks
                .iter()
                .any(|t| t.status == harrier_engine::TrackStatus::Confirmed);
            if confirmed && server.metrics().scans_ingested() >= from + more {
                return;
            }
            snap.changed().await.expect("tracker running");
        }
    })
    .await;
}

/// Polls `f` every 20 ms until it is true, at most `secs`.
async fn until(secs: u64, what: &str, mut f: impl FnMut() -> bool) {
    within(secs, what, async {
        while !f() {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    })
    .await;
}

/// Fault: the recording place is read-only, or fills up, with a real filesystem (a tmpfs mounted
/// for the test; skipped, loudly, where mounting is not permitted).
///
/// (a) Read-only at start (`mount -o remount,ro`: root cannot write it either): `harrier_server::start`
/// succeeds without a recording, says why naming the path (`recording_error`, `/api/v1/health`,
/// `harrier_recorder_up 0` in `/metrics`), and tracks.
/// (b) Full during a session: once the recording holds scans, a file fills the tmpfs; the
/// writes fail and are counted (`harrier_recorder_errors_total`), tracking and the API go on;
/// the filler is deleted and recording resumes by itself (new scans committed, the file passes
/// `PRAGMA integrity_check`).
#[test]
fn a_read_only_or_full_recording_place_never_stops_tracking() {
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    // (a) Read-only.
    let Some(ro) = Tmpfs::mount("1m") else { return };
    ro.read_only();
    let path = ro.path().join("rec/sessions.sqlite");
    rt.block_on(async {
        let (server, session, publisher) = recording_server(&path).await;
        let why = server.recording_error().expect("no recording").to_owned();
        assert!(
            why.contains(&ro.path().join("rec/sessions.sqlite").display().to_string())
                && why.to_lowercase().contains("read-only"),
            "{why}"
        );
        assert!(server.recorder().is_none());
        tracking_goes_on(&server, 50).await;
        let addr = server.local_addr();
        let (status, health) = http_get(addr, "/api/v1/health").await;
        assert_eq!(status, 200, "{health}");
        let health: serde_json::Value = serde_json::from_str(&health).expect("health JSON");
        assert_eq!(health["recording_error"].as_str(), Some(why.as_str()));
        let (_, m) = http_get(addr, "/api/v1/metrics").await;
        assert_eq!(metric(&m, "harrier_recorder_up"), Some(0.0), "{m}");
        eprintln!("read-only recording place: {why}; tracking went on");
        publisher.abort();
        let _ = session.close().await;
        server.shutdown().await;
    });
    drop(ro);

    // (b) Full.
    let Some(fs) = Tmpfs::mount("2m") else { return };
    let path = fs.path().join("sessions.sqlite");
    let filler = fs.path().join("filler");
    rt.block_on(async {
        let (server, session, publisher) = recording_server(&path).await;
        assert_eq!(server.recording_error(), None);
        let r = server.recorder().expect("recording").clone();
        until(30, "scans recorded", || r.stats().scans >= 50).await;
        // Fill the filesystem to the last byte.
        let mut f = std::fs::File::create(&filler).expect("create the filler");
        let block = vec![0u8; 64 * 1024];
        let mut filled = 0usize;
        loop {
            use std::io::Write as _;
            match f.write(&block) {
                Ok(0) => break,
                Ok(n) => filled += n,
                Err(e) if e.raw_os_error() == Some(28) => break, // ENOSPC
                Err(e) => panic!("filling the tmpfs: {e}"),
            }
        }
        let _ = f.sync_all();
        let full_at = Instant::now();
        until(30, "a failed write counted", || r.stats().errors > 0).await;
        let first_error = full_at.elapsed().as_secs_f64();
        tracking_goes_on(&server, 100).await;
        let full = r.stats();
        let addr = server.local_addr();
        let (status, _) = http_get(addr, "/api/v1/tracks").await;
        assert_eq!(status, 200, "the API answers while the disk is full");
        let (_, m) = http_get(addr, "/api/v1/metrics").await;
        let errors = metric(&m, "harrier_recorder_errors_total").expect("errors counted");
        assert!(errors >= 1.0, "{m}");
        assert_eq!(metric(&m, "harrier_recorder_up"), Some(1.0), "{m}");
        // Room again: recording resumes by itself.
        drop(f);
        std::fs::remove_file(&filler).expect("delete the filler");
        until(30, "recording resumes", || {
            r.stats().scans >= full.scans + 50
        })
        .await;
        let resumed = r.stats();
        tracking_goes_on(&server, 10).await;
        publisher.abort();
        let _ = session.close().await;
        server.shutdown().await;
        let closed = r.stats();
        eprintln!(
            "full recording place: {filled} B of filler; first failed write {first_error:.2} s \
             later; {} errors while full, tracking went on; recording resumed ({} → {} scans), \
             {} scans and {} errors at the end",
            full.errors, full.scans, resumed.scans, closed.scans, closed.errors
        );
        let c = rusqlite::Connection::open_with_flags(
            &path,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY,
        )
        .expect("open the file");
        let ok: String = c
            .query_row("PRAGMA integrity_check", [], |r| r.get(0))
            .expect("integrity_check");
        assert_eq!(ok, "ok");
        let rows: i64 = c
            .query_row("SELECT count(*) FROM scans", [], |r| r.get(0))
            .expect("count");
        assert_eq!(rows as u64, closed.scans, "committed scans = counted scans");
    });
    drop(fs);
}
