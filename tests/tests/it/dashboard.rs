//! The web dashboard (`web/`) in a real browser: `tests/python/test_map.py`, then
//! `tests/python/test_dashboard.py`, drive headless Chromium (Debian's `/usr/bin/chromium`) with
//! Playwright for Python against `harrier demo`'s world started here in-process
//! (`harrier_cli::demo::start`, three UAVs on the ground with their MAVLink link, `no_assign`, a
//! road with two cars, the CIMM track engine, the offline map the demo renders of its world;
//! nothing on the page comes from outside this machine):
//!
//! - the geographic map (test_map.py): the offline tiles under the tracks in a screenshot, every
//!   track and UAV at its WGS-84 place (within 2 m of REST's, through Leaflet's and PROJ's
//!   conversions), no console error, the local grid as a choice, ≥ 30 fps with 20 tracks and 10
//!   UAVs; and a second server this test starts with `[map] tile_url` pointing at the script's
//!   own tile server (asked with a line `HARRIER-TILE-SERVER URL`, answered `tile-server
//!   http://ADDR`), whose tiles the page requests and draws;
//! - the page loads with no console error (Chromium's log of a 404 for the details of a track
//!   the tracker deleted meanwhile is the race the page expects, set apart) and, within 30 s, draws at least one track with its
//!   95 % ellipse and three UAVs in the map, and the same with its ellipsoid in the 3-D view (what
//!   the page exposes in `window.harrier` and data attributes, cross-checked with REST);
//!   screenshots of the live page go to
//!   `target/screenshots/{dashboard,map,3d,map-zoom,assignment,stress}.png`;
//! - a wrong token shows the server's 401 as an error, the right one changes the estimator;
//! - a vehicle command from the page shows the vehicle's COMMAND_ACK (Hold `accepted`, Land on
//!   the ground `denied`);
//! - the assignment form: with a wrong token the 401 is shown and nothing is created; with the
//!   right one UAVs 1 and 2 are assigned to a track (TOGVF, R 150 m, H 120 m), which
//!   `GET /api/v1/assignments` lists as asked, the page shows it with its vehicles leaving
//!   `waiting` and draws its standoff circle (map and 3-D); assigning a busy vehicle shows the
//!   409; ending it from the page makes it `ended` in REST and on the page; then a `formation`
//!   of the three UAVs from the form, whose links the map draws until it is ended;
//! - the map draws the demo's road and the no-fly disc it was started with (`GET /api/v1/world`);
//! - a vehicle whose link is lost gets a LINK LOST card, a banner and a toast, gone when it
//!   recovers: a real `harrier-sim` process (vehicle 4, MAVLink only) that this test starts to the
//!   demo's GCS link (a line `HARRIER-VEHICLE-START`, answered `connected 4` once the link has it),
//!   SIGKILLs (`HARRIER-VEHICLE-KILL`, answered `killed 4`) and starts again;
//! - malformed payloads published on vehicle 9's key (when the script asks with a line
//!   `HARRIER-DROPS`, answered `dropped N`) are dropped and counted; the top bar's badge shows
//!   the count `/metrics` has, with the reason (screenshot `drops.png`);
//! - the manned aircraft of an ADS-B receiver (an SBS-1 source this test runs: three aircraft
//!   circling near the road, `harrier demo --adsb`) are drawn as aircraft, apart from the
//!   tracks, as `GET /api/v1/aircraft` lists them (screenshot `aircraft.png`);
//! - the server is stopped and a new one started on the same port: the page reconnects by itself
//!   and draws again, without a reload. The script asks for the restart with a line
//!   `HARRIER-RESTART` on its stdout and waits for `restarted` on its stdin;
//! - in another tab, with 20 synthetic tracks and 7 more UAVs fed into the page's store at 10 Hz,
//!   the page's own work per frame stays ≤ 20 ms (90th percentile: room for ≥ 30 fps) and its
//!   frame rate ≥ 20 fps (software WebGL on a shared CPU; the 3-D view lowers its resolution and
//!   update rate to keep the page smooth).
//!
//! Needs `/usr/bin/chromium` (`apt-get install chromium`) and `playwright` for Python (`scripts/setup`
//! installs both, pinned).

use std::io::{BufRead as _, BufReader, Read as _, Write as _};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use harrier_cli::demo::{self, Demo, DemoConfig};
use harrier_core::scenario::Segment;
use harrier_server::config::ObstacleConfig;
use harrier_server::gcs::vehicle::LinkState;
use harrier_tests::{SimProcess, kill_group, require_python_module};

/// The vehicle whose link the page sees lost: a `harrier-sim` process this test starts and kills.
const LOST_VEHICLE: u8 = 4;

/// Where the screenshots go: `$CARGO_TARGET_DIR/screenshots`, else the workspace's
/// `target/screenshots`.
fn screenshots_dir() -> PathBuf {
    std::env::var_os("CARGO_TARGET_DIR")
        .map_or_else(
            || Path::new(env!("CARGO_MANIFEST_DIR")).join("../target"),
            PathBuf::from,
        )
        .join("screenshots")
}

/// An ADS-B receiver's SBS-1 output for the demo: three aircraft (`HRR001`–`HRR003`) circling
/// 400 m around the start of the demo's road at 1 000–3 000 ft, each reported twice a second to
/// every client that connects (the demo, and the demo started again after the restart).
fn start_sbs_source() -> SocketAddr {
    let listener = std::net::TcpListener::bind("127.0.0.1:0").expect("bind the SBS-1 source");
    let addr = listener.local_addr().expect("address");
    let scenario = demo::scenario().expect("the demo's scenario");
    let frame = harrier_link::geo::LocalFrame::new(scenario.origin);
    let [cx, cy] = match &scenario.roads[0].segments[0] {
        Segment::Line { start, .. } | Segment::Arc { start, .. } => *start,
    };
    std::thread::spawn(move || {
        for mut conn in listener.incoming().map_while(Result::ok) {
            std::thread::spawn(move || {
                let t0 = Instant::now();
                loop {
                    let t = t0.elapsed().as_secs_f64();
                    let mut out = String::new();
                    for k in 1..=3_u32 {
                        // 60 m/s on a 400 m circle, a third of a turn apart.
                        let a = 0.15 * t + f64::from(k) * 2.1;
                        let p =
                            nalgebra::Vector3::new(cx + 400.0 * a.cos(), cy + 400.0 * a.sin(), 0.0);
                        let g = frame.from_enu(&p);
                        let course = (-a.sin()).atan2(a.cos()).to_degrees().rem_euclid(360.0);
                        let hex = format!("A0000{k}");
                        let alt = 1000 * k;
                        out.push_str(&format!("MSG,1,1,1,{hex},1,,,,,HRR00{k},,,,,,,,,,,0\r\n"));
                        out.push_str(&format!(
                            "MSG,3,1,1,{hex},1,,,,,,{alt},,,{:.5},{:.5},,,0,0,0,0\r\n",
                            g.lat_deg, g.lon_deg
                        ));
                        out.push_str(&format!(
                            "MSG,4,1,1,{hex},1,,,,,,,117,{course:.0},,,0,,,,,0\r\n"
                        ));
                    }
                    if conn.write_all(out.as_bytes()).is_err() {
                        return;
                    }
                    std::thread::sleep(Duration::from_millis(500));
                }
            });
        }
    });
    addr
}

fn config(listen: SocketAddr, adsb: SocketAddr) -> DemoConfig {
    // A no-fly disc of 40 m beside the start of the demo's road, where the map is looking.
    let road = &demo::scenario().expect("the demo's scenario").roads[0];
    let [x, y] = match &road.segments[0] {
        Segment::Line { start, .. } | Segment::Arc { start, .. } => *start,
    };
    DemoConfig {
        listen,
        obstacles: vec![ObstacleConfig {
            x_m: x + 60.0,
            y_m: y + 60.0,
            radius_m: 40.0,
        }],
        // Twice real time: tracks confirm sooner, and the page still sees every scan.
        speedup: 2.0,
        // The UAVs wait on the ground: the page assigns them.
        no_assign: true,
        adsb: Some(adsb.to_string()),
        // The offline map the demo renders of its world on its first run (then cached).
        mbtiles: None,
        ..DemoConfig::ephemeral(listen)
    }
}

/// Starts the demo on `listen`; a port just released may take a moment to bind again.
async fn start_demo(listen: SocketAddr, adsb: SocketAddr) -> Demo {
    let deadline = Instant::now() + Duration::from_secs(20);
    loop {
        match tokio::time::timeout(Duration::from_secs(30), demo::start(&config(listen, adsb)))
            .await
        {
            Ok(Ok(d)) => return d,
            Ok(Err(e)) if Instant::now() < deadline => {
                eprintln!("demo on {listen} did not start yet: {e}");
                tokio::time::sleep(Duration::from_millis(200)).await;
            }
            Ok(Err(e)) => panic!("demo on {listen}: {e}"),
            Err(_) => panic!("demo on {listen} did not start within 30 s"),
        }
    }
}

#[test]
fn the_dashboard_draws_the_demo_in_a_real_browser_and_reconnects() {
    require_python_module("playwright", "playwright==1.65.2");
    require_python_module("pytest", "pytest==9.2.0");
    require_python_module("httpx", "httpx==0.28.1");
    assert!(
        Path::new("/usr/bin/chromium").exists(),
        "/usr/bin/chromium is missing: apt-get install -y chromium (scripts/setup installs it)"
    );
    let started = Instant::now();
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .expect("runtime");
    let sbs = start_sbs_source();
    let mut demo = Some(runtime.block_on(start_demo(SocketAddr::from(([127, 0, 0, 1], 0)), sbs)));
    let addr = demo.as_ref().expect("demo").server().local_addr();
    let token = demo.as_ref().expect("demo").server().token().0.to_owned();
    let shots = screenshots_dir();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/test_dashboard.py");
    let map_script = Path::new(env!("CARGO_MANIFEST_DIR")).join("python/test_map.py");

    use std::os::unix::process::CommandExt as _;
    let mut child = Command::new("python3")
        .args(["-m", "pytest", "-q", "-s", "-p", "no:cacheprovider"])
        .arg(&map_script)
        .arg(&script)
        .env("HARRIER_URL", format!("http://{addr}"))
        .env("HARRIER_TOKEN", &token)
        .env("HARRIER_SCREENSHOTS", &shots)
        .env("HARRIER_RESTART_CONTROL", "stdio")
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .process_group(0)
        .spawn()
        .expect("start python3 -m pytest");
    let mut stdin = child.stdin.take().expect("stdin");
    let stdout = child.stdout.take().expect("stdout");
    let mut stderr = child.stderr.take().expect("stderr");
    let (lines, rx) = mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines() {
            let Ok(line) = line else { break };
            if lines.send(line).is_err() {
                break;
            }
        }
    });
    let errors = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });

    let deadline = Instant::now() + Duration::from_secs(240);
    let mut output = String::new();
    let mut restarts = 0;
    let mut vehicle: Option<SimProcess> = None;
    let mut tile_url_server: Option<harrier_server::LiveServer> = None;
    let status = loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(line) => {
                output.push_str(&line);
                output.push('\n');
                // pytest's progress dots may precede it on the line.
                if line.trim_end().ends_with("HARRIER-DROPS") {
                    // Malformed payloads on vehicle 9's key, from the server's own Zenoh
                    // session: each is dropped and counted (`json`).
                    let n: u64 = 30;
                    runtime.block_on(async {
                        let session = demo.as_ref().expect("demo").server().session();
                        let key = harrier_core::detection::detections_key(9);
                        for i in 0..n {
                            session
                                .put(&key, format!("{{not a scan {i}"))
                                .await
                                .expect("put a malformed payload");
                        }
                        let m = demo.as_ref().expect("demo").server().metrics();
                        let dropped = || m.vehicle_counters("9").dropped.values().sum::<u64>();
                        let from = Instant::now();
                        while dropped() < n {
                            assert!(
                                from.elapsed() < Duration::from_secs(10),
                                "{} of {n} bad payloads counted",
                                dropped()
                            );
                            tokio::time::sleep(Duration::from_millis(20)).await;
                        }
                    });
                    writeln!(stdin, "dropped {n}").expect("answer the script");
                    stdin.flush().expect("flush");
                }
                if line.trim_end().ends_with("HARRIER-VEHICLE-START") {
                    // A real vehicle 4 (harrier-sim, MAVLink only) to the demo's GCS link,
                    // answered once the link has it `connected`.
                    let server = demo.as_ref().expect("demo").server();
                    let link = server.link().expect("the demo's GCS link");
                    let gcs = link.gcs().next().expect("a GCS endpoint").addr();
                    vehicle = Some(SimProcess::start(LOST_VEHICLE, gcs, ["--no-zenoh"]));
                    let mut rx = link.vehicles.clone();
                    runtime.block_on(async {
                        tokio::time::timeout(Duration::from_secs(20), async {
                            while !rx.borrow_and_update().iter().any(|v| {
                                v.view.id == LOST_VEHICLE && v.view.state == LinkState::Connected
                            }) {
                                rx.changed().await.expect("the GCS link runs");
                            }
                        })
                        .await
                        .expect("vehicle 4 connected within 20 s");
                    });
                    writeln!(stdin, "connected {LOST_VEHICLE}").expect("answer the script");
                    stdin.flush().expect("flush");
                }
                if line.trim_end().ends_with("HARRIER-VEHICLE-KILL") {
                    vehicle.as_mut().expect("vehicle 4 started").kill();
                    writeln!(stdin, "killed {LOST_VEHICLE}").expect("answer the script");
                    stdin.flush().expect("flush");
                }
                if let Some((_, template)) = line.split_once("HARRIER-TILE-SERVER ") {
                    // A plain server (no vehicles) whose map's tiles come from the script's tile
                    // server.
                    let (mut config, _) = harrier_tests::server_config();
                    config.map.tile_url = template.trim().to_owned();
                    config.map.attribution = "© Harrier test tiles".into();
                    let server = runtime.block_on(async {
                        tokio::time::timeout(
                            Duration::from_secs(20),
                            harrier_server::start(&config),
                        )
                        .await
                        .expect("the tile-URL server started within 20 s")
                        .expect("the tile-URL server starts")
                    });
                    writeln!(stdin, "tile-server http://{}", server.local_addr())
                        .expect("answer the script");
                    stdin.flush().expect("flush");
                    tile_url_server = Some(server);
                }
                if line.trim_end().ends_with("HARRIER-RESTART") {
                    let t = Instant::now();
                    runtime.block_on(async {
                        demo.take().expect("demo").stop().await;
                        demo = Some(start_demo(addr, sbs).await);
                    });
                    restarts += 1;
                    eprintln!(
                        "demo restarted on {addr} in {:.1} s",
                        t.elapsed().as_secs_f64()
                    );
                    writeln!(stdin, "restarted").expect("answer the script");
                    stdin.flush().expect("flush");
                }
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {}
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                // stdout closed: the script is ending.
                break child.wait().expect("wait for pytest");
            }
        }
        if let Some(status) = child.try_wait().expect("wait for pytest") {
            while let Ok(line) = rx.recv_timeout(Duration::from_millis(200)) {
                output.push_str(&line);
                output.push('\n');
            }
            break status;
        }
        if Instant::now() > deadline {
            kill_group(&mut child);
            panic!("the dashboard test did not finish within 240 s:\n{output}");
        }
    };
    kill_group(&mut child);
    let _ = reader.join();
    let err = errors.join().unwrap_or_default();
    eprintln!("{output}{err}");
    assert!(
        status.success(),
        "pytest test_dashboard.py failed ({status})"
    );
    assert_eq!(restarts, 1, "the script asked for one restart");
    assert!(
        output.contains("14 passed"),
        "every test ran (none skipped):\n{output}"
    );
    for name in [
        "dashboard.png",
        "map.png",
        "3d.png",
        "geomap.png",
        "geomap-url.png",
    ] {
        assert!(
            shots.join(name).is_file(),
            "no {name} in {}",
            shots.display()
        );
    }
    runtime.block_on(async {
        if let Some(s) = tile_url_server.take() {
            s.shutdown().await;
        }
        demo.take().expect("demo").stop().await;
    });
    eprintln!("dashboard test: {:.1} s", started.elapsed().as_secs_f64());
}
