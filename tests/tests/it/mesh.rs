//! A mesh of four `zenohd` routers (docs/deploy.md), real processes only: every router, ground
//! station and publisher in a network namespace of its own (`ip netns` + veth pairs), so that the
//! only paths are the links drawn here. Fallback when namespaces are not permitted: the same
//! processes on loopback, said loudly.
//!
//! ```text
//!   p0 ── r0 ─────── r1 ── p1, g1        r_i: zenohd, full mesh (each connects to the 3 others)
//!         │  ╲     ╱ │                    g_k: harrier serve, a Zenoh client of r_k
//!         │    ╲ ╱   │                    p_i: harrier bench --publish-only, a client of r_i
//!         │    ╱ ╲   │
//!   p3 ── r3 ─────── r2 ── p2, g2
//!   g3 ───┘
//! ```
//!
//! The publishers (`harrier bench --publish-only`, distinct vehicle ids, several sensors each:
//! every (vehicle, sensor) a source of its own) publish the bench's four circling targets, which
//! move on the UNIX clock so every publisher sees the same ones. The test reads each ground
//! station over HTTP from the root namespace (one more veth pair each).
//!
//! - `four_routers_three_ground_stations`: the CI size (200 sources × 2 Hz). Every ground
//!   station's confirmed tracks agree within 1 m after a 3-s warm-up: the three are polled at once (one thread
//!   each), every track extrapolated at its own velocity to the latest track time of the poll,
//!   and paired with the nearest track of each other station. `r0` (which serves only `p0`) is
//!   SIGKILLed for 2 s and started again with the same configuration: the scans of `p0`'s
//!   vehicles arrive again at every ground station within 5 s of the restart (polled every
//!   50 ms), the scans published meanwhile are counted in `harrier_seq_lost_total`, and the
//!   tracks agree within 1 m again.
//! - `a_thousand_sources` (`#[ignore]`, BENCHMARKS.md "Router mesh"): the same at full size,
//!   knobs `HARRIER_MESH_VEHICLES` (per publisher, default 63), `HARRIER_MESH_SENSORS` (4),
//!   `HARRIER_MESH_RATE_HZ` (1), `HARRIER_MESH_MEASURE_S` (60: the steady window over which the
//!   routers' CPU is measured).
//!
//! `zenohd` is `$HARRIER_ZENOHD`, else `~/.cache/harrier/zenohd/bin/zenohd`; the binary is
//! `target/<profile>/harrier` (`cargo build -p harrier-cli`).

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};

use harrier_tests::net::{Netns, Proc, Veth, harrier_serve_in, zenohd_bin, zenohd_in};
use harrier_tests::{free_tcp_port, http_get, target_bin};
use serde_json::Value;

/// Routers in the mesh.
const ROUTERS: usize = 4;
/// The routers the ground stations are clients of (`r0` serves only publishers: it is the one
/// killed).
const GCS_ROUTERS: [usize; 3] = [1, 2, 3];
/// Targets (= detections per scan).
const TARGETS: usize = 4;
/// Largest disagreement between two ground stations' tracks (m).
const MAX_DISAGREEMENT_M: f64 = 1.0;
/// How long the killed router stays down.
const OUTAGE: Duration = Duration::from_secs(2);
/// Longest recovery after the restart.
const MAX_RECOVERY: Duration = Duration::from_secs(5);

/// The size of a run.
struct Size {
    /// Vehicles per publisher process.
    vehicles: u8,
    /// Sensors per vehicle.
    sensors: u8,
    /// Scans per second of each sensor.
    rate_hz: f64,
    /// The steady window measured for CPU and rates (s).
    measure_s: f64,
}

impl Size {
    fn sources(&self) -> usize {
        ROUTERS * usize::from(self.vehicles) * usize::from(self.sensors)
    }

    /// The vehicle ids of publisher `i`.
    fn vehicles_of(&self, i: usize) -> std::ops::RangeInclusive<u32> {
        let first = 1 + i as u32 * u32::from(self.vehicles);
        first..=first + u32::from(self.vehicles) - 1
    }
}

/// Where the processes run, and how each reaches the others.
struct Layout {
    /// Namespaces of the routers, ground stations and publishers (empty on loopback).
    ns: HashMap<String, Netns>,
    /// The veth pairs (kept until the end).
    _links: Vec<Veth>,
    /// Each router's listen and connect endpoints.
    routers: Vec<(Vec<String>, Vec<String>)>,
    /// Each ground station's router endpoint and API address (IP).
    gcs: Vec<(String, String)>,
    /// Each publisher's router endpoint.
    publishers: Vec<String>,
}

impl Layout {
    /// `program` run in the namespace `name` (or here, on loopback).
    fn command(&self, name: &str, program: &Path) -> Command {
        match self.ns.get(name) {
            Some(ns) => ns.command(program),
            None => Command::new(program),
        }
    }

    /// The namespaces and links of the drawing above; routers on port 7447 of each namespace.
    fn namespaces() -> Result<Self, String> {
        let mut ns = HashMap::new();
        for name in [
            "r0", "r1", "r2", "r3", "g1", "g2", "g3", "p0", "p1", "p2", "p3",
        ] {
            ns.insert(name.to_owned(), Netns::new(name)?);
        }
        let mut links = Vec::new();
        let mut k = 0;
        let mut link = |a: Option<&str>, b: &str| -> Result<(String, String), String> {
            let v = Veth::new(a.map(|a| &ns[a]), &ns[b], k)?;
            k += 1;
            let addrs = (v.a_addr.clone(), v.b_addr.clone());
            links.push(v);
            Ok(addrs)
        };
        let endpoint = |ip: &str| format!("tcp/{ip}:7447");
        let mut routers = vec![(vec!["tcp/0.0.0.0:7447".to_owned()], Vec::new()); ROUTERS];
        for i in 0..ROUTERS {
            for j in i + 1..ROUTERS {
                let (a, b) = link(Some(&format!("r{i}")), &format!("r{j}"))?;
                routers[i].1.push(endpoint(&b));
                routers[j].1.push(endpoint(&a));
            }
        }
        let mut gcs = Vec::new();
        for r in GCS_ROUTERS {
            let (router, _) = link(Some(&format!("r{r}")), &format!("g{r}"))?;
            let (_, api) = link(None, &format!("g{r}"))?;
            gcs.push((endpoint(&router), api));
        }
        let mut publishers = Vec::new();
        for i in 0..ROUTERS {
            let (router, _) = link(Some(&format!("r{i}")), &format!("p{i}"))?;
            publishers.push(endpoint(&router));
        }
        Ok(Self {
            ns,
            _links: links,
            routers,
            gcs,
            publishers,
        })
    }

    /// Every process on loopback, the routers on free ports.
    fn loopback() -> Self {
        let ports: Vec<u16> = (0..ROUTERS).map(|_| free_tcp_port()).collect();
        let endpoint = |i: usize| format!("tcp/127.0.0.1:{}", ports[i]);
        Self {
            ns: HashMap::new(),
            _links: Vec::new(),
            routers: (0..ROUTERS)
                .map(|i| {
                    let others = (0..ROUTERS).filter(|&j| j != i).map(endpoint).collect();
                    (vec![endpoint(i)], others)
                })
                .collect(),
            gcs: GCS_ROUTERS
                .iter()
                .map(|&r| (endpoint(r), "127.0.0.1".to_owned()))
                .collect(),
            publishers: (0..ROUTERS).map(endpoint).collect(),
        }
    }
}

/// Router `i` of `layout`, its configuration written to `dir/r{i}.json5`.
fn router(layout: &Layout, dir: &Path, i: usize, log: &str) -> Proc {
    let (listen, connect) = &layout.routers[i];
    let config = dir.join(format!("r{i}.json5"));
    std::fs::write(
        &config,
        serde_json::json!({
            "mode": "router",
            "listen": {"endpoints": listen},
            "connect": {"endpoints": connect},
            "scouting": {"multicast": {"enabled": false}},
        })
        .to_string(),
    )
    .expect("write the router's configuration");
    let mut p = zenohd_in(
        layout.command(&format!("r{i}"), &zenohd_bin()),
        dir,
        log,
        &["--config".to_owned(), config.display().to_string()],
    );
    p.what = format!("zenohd r{i}");
    p
}

/// A running `harrier serve` and its API address.
struct Gcs {
    name: String,
    proc: Proc,
    api: SocketAddr,
}

/// Ground station `k` of `layout`: `harrier serve` with the defaults (the bench's origin), a
/// Zenoh client of its router, no MAVLink, no track publication.
fn ground_station(layout: &Layout, dir: &Path, k: usize) -> Gcs {
    let name = format!("g{}", GCS_ROUTERS[k]);
    let (router, api) = &layout.gcs[k];
    let config = dir.join(format!("{name}.toml"));
    std::fs::write(
        &config,
        format!(
            "[zenoh]\nmode = \"client\"\nlisten = []\nconnect = [\"{router}\"]\n\
             tracks_key = \"\"\n[mavlink]\ngcs = []\nrouter = []\n"
        ),
    )
    .expect("write the configuration");
    let cmd = layout.command(&name, &target_bin("harrier"));
    let (proc, api) = harrier_serve_in(cmd, &name, &config, &api.to_string(), dir);
    Gcs { name, proc, api }
}

/// Publisher `i` of `layout`: `harrier bench --publish-only`, a client of its router, for
/// `run_s`; returned once it publishes (a subscriber matched each of its sensors).
fn publisher(layout: &Layout, dir: &Path, size: &Size, i: usize, run_s: f64) -> Proc {
    let name = format!("p{i}");
    let mut cmd = layout.command(&name, &target_bin("harrier"));
    cmd.args(["bench", "--publish-only", "--zenoh-connect"])
        .arg(&layout.publishers[i])
        .args(["--first-vehicle", &size.vehicles_of(i).start().to_string()])
        .args(["--vehicles", &size.vehicles.to_string()])
        .args(["--sensors", &size.sensors.to_string()])
        .args(["--rate-hz", &size.rate_hz.to_string()])
        .args(["--detections", &TARGETS.to_string()])
        .args(["--duration-s", &run_s.to_string()])
        .env("RUST_LOG", "warn");
    let mut p = Proc::spawn(
        &format!("harrier bench ({name})"),
        cmd,
        dir.join(format!("{name}.log")),
    );
    p.wait_for_line("harrier bench: publishing:", Duration::from_secs(30));
    p
}

/// A ground station's per-vehicle series `name{vehicle="N"}`, by vehicle.
fn per_vehicle(gcs: &Gcs, name: &str) -> HashMap<u32, f64> {
    let (status, text) = http_get(gcs.api, "/api/v1/metrics");
    assert_eq!(status, 200, "{text}");
    let prefix = format!("{name}{{vehicle=\"");
    text.lines()
        .filter_map(|l| {
            let (v, value) = l.strip_prefix(&prefix)?.split_once("\"} ")?;
            Some((v.parse().ok()?, value.parse().ok()?))
        })
        .collect()
}

/// The sum of a per-vehicle series over `vehicles`.
fn sum_over(series: &HashMap<u32, f64>, vehicles: std::ops::RangeInclusive<u32>) -> f64 {
    vehicles.filter_map(|v| series.get(&v)).sum()
}

/// The confirmed tracks of one poll: (t, position, velocity).
type Tracks = Vec<(f64, [f64; 2], [f64; 2])>;

fn confirmed(gcs: &Gcs) -> Tracks {
    let (status, body) = http_get(gcs.api, "/api/v1/tracks");
    assert_eq!(status, 200, "{body}");
    let v: Value = serde_json::from_str(&body).expect("tracks JSON");
    v["tracks"]
        .as_array()
        .expect("tracks")
        .iter()
        .filter(|k| k["status"] == "confirmed")
        .map(|k| {
            let f = |i: usize| k["state"][i].as_f64().expect("state");
            (k["t"].as_f64().expect("t"), [f(0), f(1)], [f(3), f(4)])
        })
        .collect()
}

/// The ground stations' confirmed tracks, polled at once (a thread each).
fn poll_all(stations: &[Gcs]) -> Vec<Tracks> {
    std::thread::scope(|s| {
        let polls: Vec<_> = stations
            .iter()
            .map(|g| s.spawn(move || confirmed(g)))
            .collect();
        polls.into_iter().map(|p| p.join().expect("poll")).collect()
    })
}

/// The largest distance between a track of one station and the nearest track of another, all
/// extrapolated to the latest track time of the poll; `None` unless every station has exactly
/// [`TARGETS`] confirmed tracks.
fn disagreement(polls: &[Tracks]) -> Option<f64> {
    if polls.iter().any(|p| p.len() != TARGETS) {
        return None;
    }
    let t = polls
        .iter()
        .flatten()
        .map(|k| k.0)
        .fold(f64::NEG_INFINITY, f64::max);
    let at = |k: &(f64, [f64; 2], [f64; 2])| {
        let dt = t - k.0;
        [k.1[0] + k.2[0] * dt, k.1[1] + k.2[1] * dt]
    };
    let mut worst: f64 = 0.0;
    for (i, a) in polls.iter().enumerate() {
        for b in &polls[i + 1..] {
            for k in a {
                let p = at(k);
                let d = b
                    .iter()
                    .map(|m| {
                        let q = at(m);
                        (p[0] - q[0]).hypot(p[1] - q[1])
                    })
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(d);
            }
        }
    }
    Some(worst)
}

/// `polls` polls 100 ms apart, each with every station at [`TARGETS`] tracks: the largest
/// disagreement (waits up to 60 s for the tracks).
fn agreement(stations: &mut [Gcs], polls: usize) -> f64 {
    let deadline = Instant::now() + Duration::from_secs(60);
    let mut worst: f64 = 0.0;
    let mut done = 0;
    while done < polls {
        for g in stations.iter_mut() {
            g.proc.assert_running();
        }
        let all = poll_all(stations);
        match disagreement(&all) {
            Some(d) => {
                worst = worst.max(d);
                done += 1;
            }
            None => {
                assert!(
                    done == 0 && Instant::now() < deadline,
                    "not {TARGETS} confirmed tracks on every ground station: {:?}",
                    all.iter().map(Vec::len).collect::<Vec<_>>()
                );
            }
        }
        std::thread::sleep(Duration::from_millis(100));
    }
    worst
}

/// Bytes received and sent so far on the interfaces of namespace `name` (but loopback), read with
/// `ip -s -j link`; zeros on loopback (no namespaces).
fn traffic(layout: &Layout, name: &str) -> (f64, f64) {
    let Some(ns) = layout.ns.get(name) else {
        return (0.0, 0.0);
    };
    let out = Command::new("ip")
        .args(["-n", &ns.name, "-s", "-j", "link", "show"])
        .output()
        .expect("ip -s -j link");
    let links: Value = serde_json::from_slice(&out.stdout).unwrap_or(Value::Null);
    let mut rx_tx = (0.0, 0.0);
    for l in links.as_array().into_iter().flatten() {
        if l["ifname"] == "lo" {
            continue;
        }
        rx_tx.0 += l["stats64"]["rx"]["bytes"].as_f64().unwrap_or(0.0);
        rx_tx.1 += l["stats64"]["tx"]["bytes"].as_f64().unwrap_or(0.0);
    }
    rx_tx
}

/// CPU seconds of each process so far.
fn cpu(procs: &[&Proc]) -> Vec<f64> {
    procs.iter().map(|p| p.cpu_s()).collect()
}

fn env_or<T: std::str::FromStr>(name: &str, default: T) -> T {
    std::env::var(name)
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn mesh_run(size: &Size) {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    let layout = match Layout::namespaces() {
        Ok(l) => {
            eprintln!(
                "mesh: {} network namespaces harrier-{}-*",
                l.ns.len(),
                std::process::id()
            );
            l
        }
        Err(e) => {
            eprintln!(
                "!!!!!!!!!!\n!!! network namespaces are not permitted here ({e}):\n!!! FALLBACK: \
                 the routers, the ground stations and the publishers run as processes on \
                 loopback\n!!!!!!!!!!"
            );
            Layout::loopback()
        }
    };
    let started = Instant::now();
    let mut routers: Vec<Proc> = (0..ROUTERS)
        .map(|i| router(&layout, d, i, &format!("r{i}.log")))
        .collect();
    let mut stations: Vec<Gcs> = (0..GCS_ROUTERS.len())
        .map(|k| ground_station(&layout, d, k))
        .collect();
    // Long enough for the whole run; killed when the test ends.
    let run_s = size.measure_s + 300.0;
    let mut publishers: Vec<Proc> = (0..ROUTERS)
        .map(|i| publisher(&layout, d, size, i, run_s))
        .collect();
    let sources = size.sources();
    let offered = sources as f64 * size.rate_hz;
    eprintln!(
        "mesh: {sources} sources × {} Hz = {offered:.0} scans/s publishing {:.1} s after the start",
        size.rate_hz,
        started.elapsed().as_secs_f64()
    );

    // Every station hears every publisher.
    let deadline = Instant::now() + Duration::from_secs(30);
    for g in &mut stations {
        loop {
            let ingested = per_vehicle(g, "harrier_scans_ingested_total");
            if (0..ROUTERS).all(|i| sum_over(&ingested, size.vehicles_of(i)) > 0.0) {
                break;
            }
            g.proc.assert_running();
            assert!(
                Instant::now() < deadline,
                "{} does not hear every publisher: {ingested:?}",
                g.name
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }
    // The tracks' warm-up (they converge from their first scans), as `harrier bench` has one.
    agreement(&mut stations, 1);
    std::thread::sleep(Duration::from_secs(3));
    let before = agreement(&mut stations, 10);
    eprintln!(
        "mesh: {TARGETS} tracks on every ground station {:.1} s after the start; largest \
         disagreement {before:.3} m",
        started.elapsed().as_secs_f64()
    );

    // The steady window: CPU of every process, scans in and out of the mesh.
    let ingested = |g: &Gcs| {
        per_vehicle(g, "harrier_scans_ingested_total")
            .values()
            .sum()
    };
    let in0: Vec<f64> = stations.iter().map(ingested).collect();
    let r_cpu0 = cpu(&routers.iter().collect::<Vec<_>>());
    let g_cpu0 = cpu(&stations.iter().map(|g| &g.proc).collect::<Vec<_>>());
    let p_cpu0 = cpu(&publishers.iter().collect::<Vec<_>>());
    let names = |prefix: &'static str| (0..ROUTERS).map(move |i| format!("{prefix}{i}"));
    let r_net0: Vec<(f64, f64)> = names("r").map(|n| traffic(&layout, &n)).collect();
    let p_net0: Vec<(f64, f64)> = names("p").map(|n| traffic(&layout, &n)).collect();
    let window = Instant::now();
    let steady = agreement(&mut stations, 1);
    std::thread::sleep(Duration::from_secs_f64(size.measure_s).saturating_sub(window.elapsed()));
    let secs = window.elapsed().as_secs_f64();
    let rate = |a: &[f64], b: &[f64]| -> Vec<f64> {
        a.iter().zip(b).map(|(a, b)| (b - a) / secs).collect()
    };
    let in1: Vec<f64> = stations.iter().map(ingested).collect();
    let r_cpu = rate(&r_cpu0, &cpu(&routers.iter().collect::<Vec<_>>()));
    let g_cpu = rate(
        &g_cpu0,
        &cpu(&stations.iter().map(|g| &g.proc).collect::<Vec<_>>()),
    );
    let p_cpu = rate(&p_cpu0, &cpu(&publishers.iter().collect::<Vec<_>>()));
    let delivered = rate(&in0, &in1);
    let r_net1: Vec<(f64, f64)> = names("r").map(|n| traffic(&layout, &n)).collect();
    let p_net1: Vec<(f64, f64)> = names("p").map(|n| traffic(&layout, &n)).collect();
    let kb_s = |a: &[(f64, f64)], b: &[(f64, f64)], tx: bool| -> Vec<f64> {
        a.iter()
            .zip(b)
            .map(|(a, b)| if tx { b.1 - a.1 } else { b.0 - a.0 } / secs / 1e3)
            .collect()
    };
    let r_in = kb_s(&r_net0, &r_net1, false);
    let r_out = kb_s(&r_net0, &r_net1, true);
    let p_out = kb_s(&p_net0, &p_net1, true);
    let per_scan = p_out.iter().sum::<f64>() * 1e3 / offered;
    let fmt = |v: &[f64], digits: usize| {
        v.iter()
            .map(|x| format!("{x:.digits$}"))
            .collect::<Vec<_>>()
            .join(" / ")
    };
    eprintln!(
        "mesh: steady {secs:.1} s: scans/s ingested per ground station {}; CPU (cores) routers \
         r0..r3 {}, ground stations {}, publishers {}; routers' traffic kB/s in {} out {}; \
         publishers' kB/s out {} ({per_scan:.0} B a scan on the wire); disagreement \
         {steady:.3} m; load {}",
        fmt(&delivered, 0),
        fmt(&r_cpu, 3),
        fmt(&g_cpu, 3),
        fmt(&p_cpu, 3),
        fmt(&r_in, 0),
        fmt(&r_out, 0),
        fmt(&p_out, 0),
        std::fs::read_to_string("/proc/loadavg")
            .unwrap_or_default()
            .trim()
    );
    for (g, r) in stations.iter().zip(&delivered) {
        assert!(
            *r >= 0.9 * offered,
            "{} ingested {r:.0} scans/s of {offered:.0}",
            g.name
        );
    }

    // r0 SIGKILLed: p0's scans stop reaching every station.
    let behind = size.vehicles_of(0);
    let of_p0 = |g: &Gcs, name: &str| sum_over(&per_vehicle(g, name), behind.clone());
    let lost_before: Vec<f64> = stations
        .iter()
        .map(|g| of_p0(g, "harrier_seq_lost_total"))
        .collect();
    let lost_all_before: Vec<f64> = stations
        .iter()
        .map(|g| per_vehicle(g, "harrier_seq_lost_total").values().sum())
        .collect();
    routers[0].kill();
    let killed = Instant::now();
    std::thread::sleep(Duration::from_millis(500));
    let frozen: Vec<f64> = stations
        .iter()
        .map(|g| of_p0(g, "harrier_scans_ingested_total"))
        .collect();
    std::thread::sleep(OUTAGE.saturating_sub(killed.elapsed()));
    for (g, f) in stations.iter().zip(&frozen) {
        assert_eq!(
            of_p0(g, "harrier_scans_ingested_total"),
            *f,
            "{}: scans of p0 arrived without its router",
            g.name
        );
    }
    routers[0] = router(&layout, d, 0, "r0-restarted.log");
    let restarted = Instant::now();
    let down = killed.elapsed();

    // p0's scans reach every station again.
    let mut recovered = vec![None; stations.len()];
    while recovered.iter().any(Option::is_none) {
        for (k, g) in stations.iter_mut().enumerate() {
            if recovered[k].is_none() && of_p0(g, "harrier_scans_ingested_total") > frozen[k] {
                recovered[k] = Some(restarted.elapsed());
            }
            g.proc.assert_running();
        }
        assert!(
            restarted.elapsed() < Duration::from_secs(30),
            "p0's scans not back within 30 s of r0's restart: {recovered:?}\n{}",
            publishers[0].log()
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let recovery: Vec<f64> = recovered
        .iter()
        .map(|r| r.map_or(f64::NAN, |r| r.as_secs_f64()))
        .collect();
    let slowest = recovery.iter().copied().fold(0.0, f64::max);
    // Settle, then the losses and the agreement again.
    std::thread::sleep(Duration::from_secs(2));
    let after = agreement(&mut stations, 10);
    let lost: Vec<f64> = stations
        .iter()
        .zip(&lost_before)
        .map(|(g, b)| of_p0(g, "harrier_seq_lost_total") - b)
        .collect();
    let lost_all: Vec<f64> = stations
        .iter()
        .zip(&lost_all_before)
        .map(|(g, b)| {
            per_vehicle(g, "harrier_seq_lost_total")
                .values()
                .sum::<f64>()
                - b
        })
        .collect();
    let p0_rate = f64::from(size.vehicles) * f64::from(size.sensors) * size.rate_hz;
    eprintln!(
        "mesh: r0 down {:.2} s; p0's scans back at every station {} s after the restart \
         (slowest {slowest:.2} s, {:.2} s after the kill); lost scans counted (p0's {} sources, \
         {p0_rate:.0}/s): {} (all vehicles: {}); tracks agree within {after:.3} m after",
        down.as_secs_f64(),
        fmt(&recovery, 2),
        slowest + (restarted - killed).as_secs_f64(),
        p0_rate / size.rate_hz,
        fmt(&lost, 0),
        fmt(&lost_all, 0)
    );
    for r in &mut routers {
        r.assert_running();
    }
    for p in &mut publishers {
        p.assert_running();
    }
    assert!(
        before <= MAX_DISAGREEMENT_M && steady <= MAX_DISAGREEMENT_M,
        "the ground stations disagree by {before:.3} / {steady:.3} m"
    );
    assert!(
        after <= MAX_DISAGREEMENT_M,
        "the ground stations disagree by {after:.3} m after the restart"
    );
    assert!(
        slowest <= MAX_RECOVERY.as_secs_f64(),
        "recovery {slowest:.2} s after the restart"
    );
    // What p0 published while its router was down is counted lost: at least most of the
    // outage, at most until the scans were back.
    for (g, l) in stations.iter().zip(&lost) {
        let low = (down.as_secs_f64() * p0_rate * 0.8).floor();
        let high = ((down.as_secs_f64() + slowest) * p0_rate * 1.2).ceil();
        assert!(
            (low..=high).contains(l),
            "{}: {l} scans of p0 counted lost, expected {low}..={high}",
            g.name
        );
    }
}

#[test]
fn four_routers_three_ground_stations() {
    mesh_run(&Size {
        vehicles: 25,
        sensors: 2,
        rate_hz: 2.0,
        measure_s: 5.0,
    });
}

/// The full-size run of BENCHMARKS.md "Router mesh" (knobs in the module's documentation).
#[test]
#[ignore = "several minutes at 1 000 sources: BENCHMARKS.md \"Router mesh\""]
fn a_thousand_sources() {
    mesh_run(&Size {
        vehicles: env_or("HARRIER_MESH_VEHICLES", 63),
        sensors: env_or("HARRIER_MESH_SENSORS", 4),
        rate_hz: env_or("HARRIER_MESH_RATE_HZ", 1.0),
        measure_s: env_or("HARRIER_MESH_MEASURE_S", 60.0),
    });
}
