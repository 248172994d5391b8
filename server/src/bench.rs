//! `harrier bench`: the live service's load tool.
//!
//! ```not_rust
//! harrier bench --vehicles 10 --rate-hz 50 --detections 4 --duration-s 600 --ws-clients 1
//! harrier bench --vehicles 10 --rate-hz 1 --ws-clients 500
//! harrier bench --rest-connections 32 --rest-duration-s 10 --duration-s 10 --ws-clients 0
//! harrier bench --url http://127.0.0.1:8080 --zenoh-connect tcp/127.0.0.1:7447 --server-pid 4242
//! harrier bench --duration-s 30 --overload-factor 10 --overload-s 60 --recovery-s 30 --ws-clients 0
//! ```
//!
//! By default the service runs in this process ([`crate::live::start`], API on a free loopback
//! port, Zenoh listening on another) on a tokio runtime of its own; `--url` and
//! `--zenoh-connect` attach to one running elsewhere instead. Everything goes through real
//! sockets either way:
//!
//! - simulated vehicles publish `DetectionScan`s on their Zenoh keys from a session of their own
//!   (`publish`);
//! - WebSocket clients follow `/api/v1/ws`, check that `seq` has no gap and measure publication
//!   → receipt latency (`ws`);
//! - keep-alive HTTP/1 connections load a REST route (`rest`);
//! - the server's counters (`GET /api/v1/metrics`) say what it received, processed and dropped,
//!   compared at the end with what was published.
//!
//! A run is a warm-up (publishing, not measured), then the measured steady state (rates,
//! latency, resident memory at its start and end, REST load from its start), then the drain:
//! the publishers stop and the tool waits until the server has processed or dropped every
//! payload it received and every WebSocket client has the last scan. With `--overload-s`, the
//! steady state is followed by an overload (every vehicle at `--overload-factor` × its rate) and
//! a nominal phase again, both sampled each second: drops by reason, tracker lag, resident
//! memory, and when the service recovered (lag back under `--recovered-lag-ms`, no more drops). Progress goes to stderr
//! every `--progress-s`; the summary to stdout, as a table or (`--json`) as JSON.

mod publish;
mod rest;
mod stats;
mod ws;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use serde::Serialize;
use tokio::time::Instant;

pub use self::publish::Phase;
use self::publish::{Plan, Publishers};
pub use self::rest::RestReport;
use self::rest::{Api, RestLoad};
pub use self::stats::{Counters, CpuUse, Machine, Percentiles, ServerLatency};
use self::stats::{CpuSample, load_1m, now_unix, rss_kib};
use self::ws::Clients;
pub use self::ws::WsReport;
use crate::live::{self, config::Config};

/// Arguments of `harrier bench`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchArgs {
    /// Simulated vehicles, each publishing one sensor's scans on its own key.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u8).range(1..))]
    pub vehicles: u8,
    /// MAVLink system id of the first vehicle (the others follow).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..))]
    pub first_vehicle: u8,
    /// Scans per second of each vehicle.
    #[arg(long, default_value_t = 50.0)]
    pub rate_hz: f64,
    /// Where in the scan period each vehicle publishes: spread (evenly), random (seeded) or
    /// same (synchronised). A scan is processed once every vehicle has published a newer one.
    #[arg(long, value_enum, default_value_t = Phase::Spread)]
    pub phase: Phase,
    /// Detections per scan: one of each target (the targets circle 300 m apart).
    #[arg(long, default_value_t = 4)]
    pub detections: usize,
    /// Length of the measured steady state (s).
    #[arg(long, default_value_t = 60.0)]
    pub duration_s: f64,
    /// Publishing before the measurement starts (s): tracks form, buffers fill.
    #[arg(long, default_value_t = 2.0)]
    pub warmup_s: f64,
    /// WebSocket clients following `/api/v1/ws`.
    #[arg(long, default_value_t = 1)]
    pub ws_clients: usize,
    /// Concurrent keep-alive HTTP/1 connections loading `--rest-path` (0: no REST load).
    #[arg(long, default_value_t = 0)]
    pub rest_connections: usize,
    /// How long the REST load runs, from the start of the steady state (s; at most
    /// `--duration-s`).
    #[arg(long, default_value_t = 10.0)]
    pub rest_duration_s: f64,
    /// Route of the REST load.
    #[arg(long, default_value = "/api/v1/tracks")]
    pub rest_path: String,
    /// Interval of the progress lines on stderr (s).
    #[arg(long, default_value_t = 5.0)]
    pub progress_s: f64,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// In-process server: track engine (ekf, cdkf, imm, cimm; default ekf).
    #[arg(long, short)]
    pub estimator: Option<String>,
    /// In-process server: `tracker.reorder_window_s` (default: the server's, 0.1 s). Scans wait
    /// this long for older ones, so it is a floor of the latency.
    #[arg(long)]
    pub reorder_window_s: Option<f64>,
    /// In-process server: `tracker.queue`, payloads and scans queued between its actors.
    #[arg(long)]
    pub queue: Option<usize>,
    /// In-process server: `api.ws_queue`, messages queued per WebSocket client.
    #[arg(long)]
    pub ws_queue: Option<usize>,
    /// Attach to a running server: its API, `http://HOST:PORT`.
    #[arg(long, requires = "zenoh_connect")]
    pub url: Option<String>,
    /// With `--url`: the server's Zenoh endpoint, e.g. tcp/127.0.0.1:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT", requires = "url")]
    pub zenoh_connect: Vec<String>,
    /// With `--url`: the API token (sent with every request; needed with `api.auth_reads`).
    #[arg(long, requires = "url")]
    pub token: Option<String>,
    /// With `--url`: the server's process id, to measure its resident memory.
    #[arg(long, requires = "url")]
    pub server_pid: Option<u32>,
    /// Overload after the steady state: every vehicle publishes at this factor × `--rate-hz`
    /// for `--overload-s`, then at `--rate-hz` again for `--recovery-s` (1: no overload).
    #[arg(long, default_value_t = 1.0)]
    pub overload_factor: f64,
    /// Length of the overload (s; 0: none).
    #[arg(long, default_value_t = 0.0)]
    pub overload_s: f64,
    /// Length of the nominal phase after the overload, measured for recovery (s).
    #[arg(long, default_value_t = 30.0)]
    pub recovery_s: f64,
    /// Recovered: from the first sample after the overload whose tracker lag is at most this
    /// (ms), no more drops and no larger lag until the end.
    #[arg(long, default_value_t = 250.0)]
    pub recovered_lag_ms: f64,
}

impl BenchArgs {
    /// Checks what clap cannot.
    fn check(&self) -> anyhow::Result<()> {
        let bad = |ok: bool, m: &str| {
            if ok {
                Ok(())
            } else {
                Err(anyhow::anyhow!("{m}"))
            }
        };
        bad(
            self.rate_hz.is_finite() && self.rate_hz > 0.0 && self.rate_hz <= 10_000.0,
            "--rate-hz must be in (0, 10000]",
        )?;
        bad(self.detections <= 10_000, "--detections must be ≤ 10000")?;
        bad(
            self.duration_s.is_finite() && self.duration_s > 0.0,
            "--duration-s must be > 0",
        )?;
        bad(
            self.warmup_s.is_finite() && self.warmup_s >= 0.0,
            "--warmup-s must be ≥ 0",
        )?;
        bad(
            self.progress_s.is_finite() && self.progress_s > 0.0,
            "--progress-s must be > 0",
        )?;
        bad(
            self.rest_connections == 0
                || (self.rest_duration_s.is_finite() && self.rest_duration_s > 0.0),
            "--rest-duration-s must be > 0",
        )?;
        bad(
            self.ws_clients <= 10_000 && self.rest_connections <= 10_000,
            "--ws-clients and --rest-connections must be ≤ 10000",
        )?;
        bad(
            u16::from(self.first_vehicle) + u16::from(self.vehicles) - 1 <= 255,
            "--first-vehicle + --vehicles - 1 must be ≤ 255 (MAVLink system ids)",
        )?;
        bad(
            self.rest_path.starts_with('/'),
            "--rest-path must start with /",
        )?;
        bad(
            self.overload_factor.is_finite()
                && self.overload_factor >= 1.0
                && self.rate_hz * self.overload_factor <= 10_000.0,
            "--overload-factor must be ≥ 1, and --rate-hz × --overload-factor ≤ 10000",
        )?;
        bad(
            self.overload_s.is_finite()
                && self.overload_s >= 0.0
                && self.recovery_s.is_finite()
                && self.recovery_s > 0.0
                && self.recovered_lag_ms.is_finite()
                && self.recovered_lag_ms > 0.0,
            "--overload-s must be ≥ 0, --recovery-s and --recovered-lag-ms > 0",
        )?;
        if self.url.is_some() {
            bad(
                self.estimator.is_none()
                    && self.reorder_window_s.is_none()
                    && self.queue.is_none()
                    && self.ws_queue.is_none(),
                "--estimator, --reorder-window-s, --queue and --ws-queue configure the \
                 in-process server; with --url, configure the server you run",
            )?;
        }
        Ok(())
    }

    /// The vehicles' MAVLink ids.
    fn vehicle_ids(&self) -> Vec<u8> {
        (0..self.vehicles)
            .map(|k| self.first_vehicle.saturating_add(k))
            .collect()
    }

    /// The in-process server's configuration, its Zenoh session listening on `endpoint`.
    fn server_config(&self, endpoint: String) -> Config {
        let mut c = Config::default();
        c.mavlink.gcs.clear();
        c.api.listen = SocketAddr::from(([127, 0, 0, 1], 0));
        c.zenoh.listen = vec![endpoint];
        c.zenoh.connect = Vec::new();
        if let Some(e) = &self.estimator {
            c.tracker.estimator.clone_from(e);
        }
        if let Some(w) = self.reorder_window_s {
            c.tracker.reorder_window_s = w;
        }
        if let Some(q) = self.queue {
            c.tracker.queue = q;
        }
        if let Some(q) = self.ws_queue {
            c.api.ws_queue = q;
        }
        // Every client of the run at once, and room for its own requests (/metrics, /tracks).
        let clients = self.ws_clients + self.rest_connections + 16;
        c.api.max_connections = c.api.max_connections.max(clients);
        c
    }
}

/// How the run was set up.
#[derive(Debug, Clone, Serialize)]
pub struct Setup {
    /// `in-process`, or the URL of the server attached to.
    pub server: String,
    /// Track engine of the in-process server.
    pub estimator: Option<String>,
    /// `tracker.reorder_window_s` of the in-process server.
    pub reorder_window_s: Option<f64>,
    /// `tracker.queue` of the in-process server.
    pub queue: Option<usize>,
    /// `api.ws_queue` of the in-process server.
    pub ws_queue: Option<usize>,
    /// Vehicles publishing.
    pub vehicles: u8,
    /// Scans per second per vehicle.
    pub rate_hz: f64,
    /// Publication phases.
    pub phase: Phase,
    /// Detections per scan.
    pub detections: usize,
    /// Warm-up (s).
    pub warmup_s: f64,
    /// Measured steady state (s).
    pub duration_s: f64,
    /// Lag (ms) below which the service counts as recovered after an overload.
    pub recovered_lag_ms: f64,
}

/// What the vehicles published.
#[derive(Debug, Clone, Serialize)]
pub struct PublishReport {
    /// Scans published (`put` accepted by Zenoh), warm-up and steady state.
    pub scans: u64,
    /// Detections in them.
    pub detections: u64,
    /// Failed `put`s.
    pub failed: u64,
    /// How long they published (s).
    pub seconds: f64,
    /// Scans per second achieved over the steady state (asked: vehicles × rate).
    pub scans_per_s: f64,
}

/// What the server did with it.
#[derive(Debug, Clone, Serialize)]
pub struct ServerReport {
    /// The counters of the vehicles (since the run started).
    pub counters: Counters,
    /// Scans published but not processed: never received plus dropped.
    pub lost: u64,
    /// Scans published but never received (lost in transport).
    pub not_received: u64,
    /// Scans processed per second over the steady state.
    pub scans_per_s: f64,
    /// Detections processed per second over the steady state.
    pub detections_per_s: f64,
    /// Largest tracker lag seen at a progress line: wall time − time of the last processed scan
    /// (ms; the reorder window and a scan period are part of it).
    pub max_lag_ms: f64,
    /// Whether the server had processed or dropped everything it received when the run ended.
    pub drained: bool,
    /// The server's own latency over the steady state (`harrier_scan_latency_seconds`: payload
    /// arrival → scan processed, reorder buffer included), if it reports it.
    pub latency: Option<ServerLatency>,
}

/// Resident memory over the steady state.
#[derive(Debug, Clone, Serialize)]
pub struct RssReport {
    /// What was measured: this whole process (server, publishers and clients), or the server's
    /// process (`--server-pid`), or nothing.
    pub scope: String,
    /// At the start of the steady state (KiB).
    pub start_kib: Option<u64>,
    /// At its end (KiB).
    pub end_kib: Option<u64>,
    /// End − start (KiB).
    pub growth_kib: Option<i64>,
}

/// One phase of an overload run, sampled about once a second.
#[derive(Debug, Clone, Serialize)]
pub struct PhaseReport {
    /// Scans per second asked of each vehicle.
    pub rate_hz: f64,
    /// Length (s).
    pub seconds: f64,
    /// Scans published in it (`put` accepted).
    pub published: u64,
    /// Scans processed per second.
    pub scans_per_s: f64,
    /// Drops in it, by reason (`harrier_scans_dropped_total`).
    pub dropped: std::collections::BTreeMap<String, u64>,
    /// Largest tracker lag at a sample (ms): wall time − time of the last processed scan.
    pub max_lag_ms: f64,
    /// Tracker lag at its last sample (ms).
    pub end_lag_ms: f64,
    /// Largest resident memory at a sample (KiB).
    pub rss_max_kib: Option<u64>,
}

/// The overload: 10× (say) the nominal rate for a while, then the nominal rate again.
#[derive(Debug, Clone, Serialize)]
pub struct OverloadReport {
    /// Rate factor of the overload.
    pub factor: f64,
    /// Resident memory at the end of the steady state, before the overload (KiB).
    pub rss_before_kib: Option<u64>,
    /// The overload phase.
    pub overload: PhaseReport,
    /// The nominal phase after it.
    pub recovery: PhaseReport,
    /// Seconds from the end of the overload to the first sample from which on the lag stays
    /// ≤ `--recovered-lag-ms` and nothing is dropped (`None`: not within `--recovery-s`).
    pub recovered_after_s: Option<f64>,
    /// Drops from that sample to the end (0 when recovered).
    pub dropped_after_recovery: u64,
}

/// Everything a run measured.
#[derive(Debug, Clone, Serialize)]
pub struct Report {
    /// The run.
    pub setup: Setup,
    /// The machine.
    pub machine: Machine,
    /// The publishers.
    pub publish: PublishReport,
    /// The server's side.
    pub server: ServerReport,
    /// The WebSocket clients (none: `--ws-clients 0`).
    pub websocket: Option<WsReport>,
    /// The REST load (none: `--rest-connections 0`).
    pub rest: Option<RestReport>,
    /// Resident memory.
    pub rss: RssReport,
    /// CPU over the steady state: the measured processes (this one, and the server's with
    /// `--server-pid`), the machine, everything else (unknown without `/proc`).
    pub cpu: Option<CpuUse>,
    /// The overload and the recovery after it (`--overload-s`).
    pub overload: Option<OverloadReport>,
}

/// Runs the load test and prints its figures.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    crate::init_logging("warn,zenoh=error");
    let report = measure(args)?;
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        summary_lines(&report).join("\n")
    };
    use std::io::Write as _;
    let _ = writeln!(std::io::stdout().lock(), "{text}");
    Ok(())
}

/// A Zenoh TCP endpoint on a loopback port that is free now.
fn free_loopback_endpoint() -> anyhow::Result<String> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .context("no free loopback port for a Zenoh endpoint")?
        .port();
    Ok(format!("tcp/127.0.0.1:{port}"))
}

/// The server a run loads.
#[derive(Debug)]
struct Target {
    api: Api,
    zenoh: Vec<String>,
    url: String,
    rss_pid: Option<u32>,
    in_process: bool,
}

/// Runs the load test: starts the in-process server (or attaches to `--url`), loads it, and
/// returns the figures.
pub fn measure(args: &BenchArgs) -> anyhow::Result<Report> {
    args.check()?;
    let machine = Machine::now();
    let load = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("bench-load")
        .build()?;
    let Some(url) = &args.url else {
        let server_rt = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("bench-server")
            .build()?;
        let endpoint = free_loopback_endpoint()?;
        let config = args.server_config(endpoint.clone());
        let server = server_rt
            .block_on(live::start(&config))
            .context("starting the in-process server")?;
        let addr = server.local_addr();
        let target = Target {
            api: Api { addr, token: None },
            zenoh: vec![endpoint],
            url: format!("http://{addr}"),
            rss_pid: None,
            in_process: true,
        };
        let report = load.block_on(drive(args, &target, machine));
        server_rt.block_on(server.shutdown());
        return report;
    };
    let host = url
        .strip_prefix("http://")
        .map(|h| h.trim_end_matches('/'))
        .filter(|h| !h.is_empty() && !h.contains('/'))
        .with_context(|| format!("--url {url:?}: expected http://HOST:PORT"))?;
    let addr = load
        .block_on(tokio::net::lookup_host(host))
        .with_context(|| format!("--url {url:?}"))?
        .next()
        .with_context(|| format!("--url {url:?}: no address"))?;
    let target = Target {
        api: Api {
            addr,
            token: args.token.clone(),
        },
        zenoh: args.zenoh_connect.clone(),
        url: url.clone(),
        rss_pid: args.server_pid,
        in_process: false,
    };
    load.block_on(drive(args, &target, machine))
}

/// Longest wait for the server to process what it received, and for the WebSocket clients to
/// receive it, after the publishers stopped.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(20);

/// The load, on the load's runtime.
async fn drive(args: &BenchArgs, target: &Target, mut machine: Machine) -> anyhow::Result<Report> {
    let ids = args.vehicle_ids();
    let ours = |v: &str| v.parse::<u8>().is_ok_and(|id| ids.contains(&id));
    let api = &target.api;
    let counters = || async {
        let text = api
            .get("/api/v1/metrics")
            .await
            .context("reading the server's counters")?;
        Ok::<_, anyhow::Error>(Counters::parse(&text, &ours))
    };
    let base = counters().await?;

    let clients = if args.ws_clients > 0 {
        let mut url = format!("ws://{}/api/v1/ws", api.addr);
        if let Some(t) = &api.token {
            url.push_str(&format!("?token={t}"));
        }
        let c = Clients::connect(&url, args.ws_clients).await?;
        eprintln!(
            "harrier bench: {} WebSocket clients connected",
            args.ws_clients
        );
        Some(c)
    } else {
        None
    };
    let listen = free_loopback_endpoint()?;
    let publishers = Publishers::start(&Plan {
        vehicles: ids.clone(),
        rate_hz: args.rate_hz,
        detections: args.detections,
        origin: live::config::DEFAULT_ORIGIN,
        connect: target.zenoh.clone(),
        listen,
        phase: args.phase,
    })
    .await?;
    let started = Instant::now();
    eprintln!(
        "harrier bench: {} vehicles × {} Hz × {} detections publishing to {}; warm-up {} s, \
         then {} s measured",
        args.vehicles, args.rate_hz, args.detections, target.url, args.warmup_s, args.duration_s
    );
    tokio::time::sleep(Duration::from_secs_f64(args.warmup_s)).await;

    // The steady state.
    let steady = Instant::now();
    let end = steady + Duration::from_secs_f64(args.duration_s);
    let rss_start = rss_kib(target.rss_pid);
    let cpu_start = CpuSample::now(target.rss_pid);
    let c0 = counters().await?;
    let published0 = publishers.scans();
    if let Some(c) = &clients {
        c.stats().record(true);
    }
    let rest_load = Arc::new(RestLoad::default());
    let rest = (args.rest_connections > 0).then(|| {
        tokio::spawn(Arc::clone(&rest_load).run(
            api.clone(),
            args.rest_path.clone(),
            args.rest_connections,
            Duration::from_secs_f64(args.rest_duration_s.min(args.duration_s)),
        ))
    });
    let mut max_lag_s: f64 = 0.0;
    let ws0 = clients.as_ref().map_or(0, |c| c.stats().scans());
    let mut cpu_last = cpu_start;
    let mut last = (Instant::now(), c0.clone(), published0, ws0, 0);
    loop {
        let next = (Instant::now() + Duration::from_secs_f64(args.progress_s)).min(end);
        tokio::time::sleep_until(next).await;
        let c = counters().await?;
        let lag = c.last_scan_t.map_or(0.0, |t| now_unix() - t);
        max_lag_s = max_lag_s.max(lag);
        let now = Instant::now();
        let ws_scans = clients.as_ref().map_or(0, |c| c.stats().scans());
        let published = publishers.scans();
        let dt = (now - last.0).as_secs_f64().max(1e-9);
        let rate = |a: u64, b: u64| a.saturating_sub(b) as f64 / dt;
        let ws = clients.as_ref().map_or(String::new(), |cl| {
            format!(
                "  ws {:.0} msg/s p99 {:.1} ms",
                rate(ws_scans, last.3),
                cl.stats().latency().p99
            )
        });
        let rest_ok = rest_load.ok();
        let cpu_now = CpuSample::now(target.rss_pid);
        let cpu_line = cpu_last.zip(cpu_now).map_or(String::new(), |(a, b)| {
            let u = a.until(&b);
            format!(
                "  cpu {:.2} + others {:.2}",
                u.measured_cores, u.others_cores
            )
        });
        cpu_last = cpu_now;
        let rss_line = rss_kib(target.rss_pid).map_or(String::new(), |k| {
            format!("  rss {:.1} MiB", k as f64 / 1024.0)
        });
        let rest_line = if rest.is_some() {
            format!("  rest {:.0} req/s", rate(rest_ok, last.4))
        } else {
            String::new()
        };
        eprintln!(
            "[{:7.1} s] published {:.0} scans/s  processed {:.0} scans/s {:.0} det/s  lag {:.1} ms  \
             dropped {}{ws}{rest_line}{cpu_line}{rss_line}",
            (now - steady).as_secs_f64(),
            rate(published, last.2),
            rate(c.ingested, last.1.ingested),
            rate(c.detections, last.1.detections),
            lag * 1e3,
            c.since(&base).dropped_total(),
        );
        last = (now, c, published, ws_scans, rest_ok);
        if now >= end {
            break;
        }
    }
    let steady_s = steady.elapsed().as_secs_f64();
    let c1 = &last.1;
    let published1 = last.2;
    let rss_end = rss_kib(target.rss_pid);
    let cpu = cpu_start
        .zip(CpuSample::now(target.rss_pid))
        .map(|(a, b)| a.until(&b));
    if let Some(c) = &clients {
        c.stats().record(false);
    }

    // The overload, then the nominal rate again.
    let overload = if args.overload_s > 0.0 {
        let sample = async || -> anyhow::Result<Sample> {
            let c = counters().await?;
            Ok(Sample {
                at: Instant::now(),
                lag_s: c.last_scan_t.map_or(0.0, |t| now_unix() - t),
                rss_kib: rss_kib(target.rss_pid),
                published: publishers.scans(),
                counters: c,
            })
        };
        let every = Duration::from_secs_f64(args.progress_s.min(1.0));
        let mut phases: Vec<(f64, Vec<Sample>)> = Vec::new();
        for (factor, seconds) in [
            (args.overload_factor, args.overload_s),
            (1.0, args.recovery_s),
        ] {
            publishers.set_rate_factor(factor);
            // A phase starts where the one before ended, so that no drop falls between them.
            let start = match phases.last() {
                Some((_, samples)) => samples[samples.len() - 1].clone(),
                None => sample().await?,
            };
            let end = start.at + Duration::from_secs_f64(seconds);
            let mut samples = vec![start];
            loop {
                tokio::time::sleep_until((Instant::now() + every).min(end)).await;
                let s = sample().await?;
                let last = samples.last().map_or(&s, |l| l);
                eprintln!(
                    "[{:5.1} s at {factor}×] published {:.0} scans/s  processed {:.0} scans/s  \
                     lag {:.1} ms  dropped {}{}",
                    (s.at - samples[0].at).as_secs_f64(),
                    s.published.saturating_sub(last.published) as f64
                        / (s.at - last.at).as_secs_f64().max(1e-9),
                    s.counters.ingested.saturating_sub(last.counters.ingested) as f64
                        / (s.at - last.at).as_secs_f64().max(1e-9),
                    s.lag_s * 1e3,
                    s.counters.since(&base).dropped_total(),
                    s.rss_kib.map_or(String::new(), |k| format!(
                        "  rss {:.1} MiB",
                        k as f64 / 1024.0
                    )),
                );
                let done = s.at >= end;
                samples.push(s);
                if done {
                    break;
                }
            }
            phases.push((args.rate_hz * factor, samples));
        }
        Some(overload_report(args, rss_end, &phases))
    } else {
        None
    };

    // The drain.
    let (published, failed) = publishers.stop().await;
    let publish_s = started.elapsed().as_secs_f64();
    let drain_start = Instant::now();
    let (totals, drained) = loop {
        let c = counters().await?.since(&base);
        let settled = c.ingested + c.dropped_total() >= c.received;
        if settled && c.received >= published {
            break (c, true);
        }
        // Payloads lost on the way never arrive: settled and still for a second is the end.
        if settled && drain_start.elapsed() > Duration::from_secs(1) {
            break (c, true);
        }
        if drain_start.elapsed() > DRAIN_TIMEOUT {
            break (c, false);
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    let final_seq = {
        let body = api.get("/api/v1/tracks").await?;
        let v: serde_json::Value = serde_json::from_str(&body).context("GET /api/v1/tracks")?;
        v["seq"]
            .as_u64()
            .context("GET /api/v1/tracks: no seq in the answer")?
    };
    let websocket = match clients {
        Some(c) => Some(c.finish(final_seq, DRAIN_TIMEOUT).await),
        None => None,
    };
    let rest = match rest {
        Some(t) => Some(t.await.context("the REST load")?),
        None => None,
    };
    machine.load_end = load_1m();

    let steady_counts = c1.since(&c0);
    let lost = published.saturating_sub(totals.ingested);
    let rss_scope = match (target.in_process, target.rss_pid) {
        (true, _) => "this process: server, publishers and clients".to_string(),
        (false, Some(pid)) => format!("server process {pid}"),
        (false, None) => "not measured (give --server-pid)".to_string(),
    };
    let rss_known = target.in_process || target.rss_pid.is_some();
    Ok(Report {
        setup: Setup {
            server: if target.in_process {
                "in-process".into()
            } else {
                target.url.clone()
            },
            estimator: target
                .in_process
                .then(|| args.estimator.clone().unwrap_or_else(|| "ekf".into())),
            reorder_window_s: target.in_process.then(|| {
                args.reorder_window_s
                    .unwrap_or(Config::default().tracker.reorder_window_s)
            }),
            queue: target
                .in_process
                .then(|| args.queue.unwrap_or(Config::default().tracker.queue)),
            ws_queue: target
                .in_process
                .then(|| args.ws_queue.unwrap_or(Config::default().api.ws_queue)),
            vehicles: args.vehicles,
            rate_hz: args.rate_hz,
            phase: args.phase,
            detections: args.detections,
            warmup_s: args.warmup_s,
            duration_s: args.duration_s,
            recovered_lag_ms: args.recovered_lag_ms,
        },
        machine,
        publish: PublishReport {
            scans: published,
            detections: published * args.detections as u64,
            failed,
            seconds: publish_s,
            scans_per_s: published1.saturating_sub(published0) as f64 / steady_s,
        },
        server: ServerReport {
            not_received: published.saturating_sub(totals.received),
            counters: totals,
            lost,
            scans_per_s: steady_counts.ingested as f64 / steady_s,
            detections_per_s: steady_counts.detections as f64 / steady_s,
            max_lag_ms: max_lag_s * 1e3,
            drained,
            latency: steady_counts.server_latency(),
        },
        websocket,
        rest,
        rss: RssReport {
            scope: rss_scope,
            start_kib: rss_start.filter(|_| rss_known),
            end_kib: rss_end.filter(|_| rss_known),
            growth_kib: match (rss_start, rss_end) {
                (Some(a), Some(b)) if rss_known => Some(b as i64 - a as i64),
                _ => None,
            },
        },
        cpu,
        overload,
    })
}

/// One sample of an overload phase.
#[derive(Debug, Clone)]
struct Sample {
    at: Instant,
    lag_s: f64,
    rss_kib: Option<u64>,
    published: u64,
    counters: Counters,
}

/// A phase's figures from its samples (the first at its start).
fn phase_report(rate_hz: f64, samples: &[Sample]) -> PhaseReport {
    let (first, last) = (&samples[0], &samples[samples.len() - 1]);
    let seconds = (last.at - first.at).as_secs_f64();
    let d = last.counters.since(&first.counters);
    PhaseReport {
        rate_hz,
        seconds,
        published: last.published.saturating_sub(first.published),
        scans_per_s: d.ingested as f64 / seconds.max(1e-9),
        dropped: d.dropped.into_iter().filter(|(_, n)| *n > 0).collect(),
        max_lag_ms: samples.iter().map(|s| s.lag_s).fold(0.0, f64::max) * 1e3,
        end_lag_ms: last.lag_s * 1e3,
        rss_max_kib: samples.iter().filter_map(|s| s.rss_kib).max(),
    }
}

/// The overload report from the samples of the overload and of the recovery phase.
fn overload_report(
    args: &BenchArgs,
    rss_before: Option<u64>,
    phases: &[(f64, Vec<Sample>)],
) -> OverloadReport {
    let (over, after) = (&phases[0], &phases[1]);
    let samples = &after.1;
    let ok = |k: usize| {
        samples[k].lag_s * 1e3 <= args.recovered_lag_ms
            && (k == 0
                || samples[k]
                    .counters
                    .since(&samples[k - 1].counters)
                    .dropped_total()
                    == 0)
    };
    // The first sample from which on every sample is fine.
    let mut from = samples.len();
    while from > 0 && ok(from - 1) {
        from -= 1;
    }
    let end = &samples[samples.len() - 1];
    let (recovered_after_s, dropped_after_recovery) = match samples.get(from) {
        Some(s) => (
            Some((s.at - samples[0].at).as_secs_f64()),
            end.counters.since(&s.counters).dropped_total(),
        ),
        None => (
            None,
            end.counters.since(&samples[0].counters).dropped_total(),
        ),
    };
    OverloadReport {
        factor: args.overload_factor,
        rss_before_kib: rss_before,
        overload: phase_report(over.0, &over.1),
        recovery: phase_report(after.0, samples),
        recovered_after_s,
        dropped_after_recovery,
    }
}

/// Formats a percentile set (ms).
fn percentiles_line(p: &Percentiles) -> String {
    format!(
        "p50 {:.2}  p90 {:.2}  p99 {:.2}  p99.9 {:.2}  max {:.2}  mean {:.2} ms  (n = {})",
        p.p50, p.p90, p.p99, p.p999, p.max, p.mean, p.count
    )
}

/// The summary table.
pub fn summary_lines(r: &Report) -> Vec<String> {
    let s = &r.setup;
    let mut out = Vec::new();
    let server = match (&s.estimator, s.reorder_window_s, s.queue, s.ws_queue) {
        (Some(e), Some(w), Some(q), Some(wq)) => {
            format!("in-process server: {e}, reorder window {w} s, queue {q}, ws_queue {wq}")
        }
        _ => format!("server {}", s.server),
    };
    out.push(format!(
        "harrier bench: {} vehicles × {} Hz ({} phases) × {} detections; {} s measured after {} s warm-up; {server}",
        s.vehicles,
        s.rate_hz,
        format!("{:?}", s.phase).to_lowercase(),
        s.detections, s.duration_s, s.warmup_s
    ));
    let m = &r.machine;
    out.push(format!(
        "machine      {} CPUs ({}), {} MiB; load average {:.2} at start, {:.2} at end",
        m.cpus, m.cpu_model, m.mem_total_mib, m.load_start, m.load_end
    ));
    let p = &r.publish;
    out.push(format!(
        "published    {} scans, {} detections in {:.1} s ({:.1} scans/s in the steady state, asked {:.1}); {} failed",
        p.scans,
        p.detections,
        p.seconds,
        p.scans_per_s,
        f64::from(s.vehicles) * s.rate_hz,
        p.failed
    ));
    let v = &r.server;
    let c = &v.counters;
    let drops = if c.dropped.is_empty() {
        "none".to_string()
    } else {
        c.dropped
            .iter()
            .map(|(r, n)| format!("{r} {n}"))
            .collect::<Vec<_>>()
            .join(", ")
    };
    out.push(format!(
        "server       received {}, processed {} scans ({} detections); lost {} (not received {}, dropped: {drops}); seq gaps {}{}",
        c.received,
        c.ingested,
        c.detections,
        v.lost,
        v.not_received,
        c.seq_lost,
        if v.drained { "" } else { "; NOT DRAINED" }
    ));
    out.push(format!(
        "ingest       {:.1} scans/s, {:.0} detections/s (steady state); tracker lag max {:.1} ms",
        v.scans_per_s, v.detections_per_s, v.max_lag_ms
    ));
    if let Some(l) = &v.latency {
        let ms = |x: Option<f64>| x.map_or("> last bucket".to_string(), |x| format!("≤ {x}"));
        out.push(format!(
            "server lat.  arrival → processed: mean {:.2} ms; p50 {}  p99 {}  p99.9 {} ms  (n = {})",
            l.mean_ms,
            ms(l.p50_le_ms),
            ms(l.p99_le_ms),
            ms(l.p999_le_ms),
            l.count
        ));
    }
    if let Some(w) = &r.websocket {
        out.push(format!(
            "websocket    {} clients: {} scan messages of {} expected; missing {}, resyncs {}, out of order {}, errors {}",
            w.clients, w.scan_messages, w.expected, w.missing, w.resyncs, w.out_of_order, w.errors
        ));
        out.push(format!(
            "latency      {}  (publication → WebSocket receipt)",
            percentiles_line(&w.latency_ms)
        ));
    }
    if let Some(h) = &r.rest {
        out.push(format!(
            "rest         GET {} on {} connections for {:.1} s: {} ok ({:.0} req/s), {} not 200, {} errors",
            h.path, h.connections, h.duration_s, h.ok, h.req_per_s, h.non_ok, h.errors
        ));
        out.push(format!("rest latency {}", percentiles_line(&h.latency_ms)));
    }
    if let Some(c) = &r.cpu {
        out.push(format!(
            "cpu          {:.2} cores measured ({}), machine {:.2}, others {:.2} (steady state)",
            c.measured_cores,
            match (
                r.setup.server == "in-process",
                r.rss.scope.starts_with("server process")
            ) {
                (true, _) => "this process",
                (false, true) => "this process and the server's",
                (false, false) => "this process only",
            },
            c.machine_cores,
            c.others_cores
        ));
    }
    let mib = |k: Option<u64>| k.map_or("?".to_string(), |k| format!("{:.1}", k as f64 / 1024.0));
    if let Some(o) = &r.overload {
        let drops = |p: &PhaseReport| {
            if p.dropped.is_empty() {
                "none".to_string()
            } else {
                p.dropped
                    .iter()
                    .map(|(r, n)| format!("{r} {n}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            }
        };
        for (name, p) in [("overload", &o.overload), ("after", &o.recovery)] {
            out.push(format!(
                "{name:<12} {:.0} Hz per vehicle for {:.1} s: published {}, processed {:.0} scans/s; \
                 dropped: {}; lag max {:.1} ms, at the end {:.1} ms; rss max {} MiB",
                p.rate_hz,
                p.seconds,
                p.published,
                p.scans_per_s,
                drops(p),
                p.max_lag_ms,
                p.end_lag_ms,
                mib(p.rss_max_kib)
            ));
        }
        out.push(format!(
            "recovery     {} ({} drops after); rss before the overload {} MiB",
            o.recovered_after_s
                .map_or("NOT recovered".to_string(), |s| format!(
                    "lag ≤ {} ms and no drop from {s:.1} s after the overload on",
                    r.setup.recovered_lag_ms
                )),
            o.dropped_after_recovery,
            mib(o.rss_before_kib)
        ));
    }
    out.push(format!(
        "rss          {} → {} MiB, growth {} MiB ({})",
        mib(r.rss.start_kib),
        mib(r.rss.end_kib),
        r.rss
            .growth_kib
            .map_or("?".to_string(), |g| format!("{:+.2}", g as f64 / 1024.0)),
        r.rss.scope
    ));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser as _;

    #[derive(Debug, clap::Parser)]
    struct Cli {
        #[command(flatten)]
        bench: BenchArgs,
    }

    fn args(line: &[&str]) -> BenchArgs {
        Cli::try_parse_from(std::iter::once("bench").chain(line.iter().copied()))
            .expect("arguments")
            .bench
    }

    #[test]
    fn bad_arguments_are_named() {
        for (line, what) in [
            (&["--rate-hz", "0"][..], "--rate-hz"),
            (
                &["--first-vehicle", "250", "--vehicles", "10"],
                "--first-vehicle",
            ),
            (&["--rest-path", "tracks"], "--rest-path"),
            (
                &[
                    "--url",
                    "http://x:1",
                    "--zenoh-connect",
                    "tcp/x:2",
                    "--queue",
                    "4",
                ],
                "--queue",
            ),
        ] {
            let e = args(line).check().expect_err(what).to_string();
            assert!(e.contains(what), "{line:?}: {e}");
        }
        assert!(Cli::try_parse_from(["bench", "--url", "http://x:1"]).is_err());
        assert!(Cli::try_parse_from(["bench", "--vehicles", "0"]).is_err());
    }

    /// Overload: 2 vehicles × 10 Hz × 100 detections, then 50× that (1 000 scans/s of 100
    /// detections: 100 000 detections/s, past what the GNN assignment of 100 tracks keeps up
    /// with) for 3 s into a queue of 8, then 10 Hz again for 6 s (a reorder window of 0.3 s, so
    /// that the two vehicles' scans wait for each other): the overload's drops are
    /// counted by reason in `/metrics` (`queue_full`), memory stops growing, and the service
    /// recovers within 4 s (lag back under 250 ms, no drop after).
    #[test]
    fn an_overload_drops_and_counts_then_recovers() {
        let a = args(&[
            "--vehicles",
            "2",
            "--rate-hz",
            "10",
            "--detections",
            "100",
            "--reorder-window-s",
            "0.3",
            "--duration-s",
            "1",
            "--warmup-s",
            "1",
            "--ws-clients",
            "0",
            "--queue",
            "8",
            "--overload-factor",
            "50",
            "--overload-s",
            "3",
            "--recovery-s",
            "6",
        ]);
        let r = measure(&a).expect("bench run");
        let o = r.overload.as_ref().expect("overload report");
        eprintln!("{}", summary_lines(&r).join("\n"));
        let queue_full = o.overload.dropped.get("queue_full").copied().unwrap_or(0);
        assert!(queue_full > 0, "no queue_full drop in the overload: {o:?}");
        assert!(
            r.server.counters.dropped.get("queue_full").copied() >= Some(queue_full),
            "{:?}",
            r.server.counters
        );
        let rate = |p: &PhaseReport| p.published as f64 / p.seconds;
        assert!(rate(&o.overload) > 5.0 * rate(&o.recovery), "{o:?}");
        let after = o.recovered_after_s.expect("recovered");
        assert!(after <= 4.0, "recovered {after} s after the overload");
        assert_eq!(o.dropped_after_recovery, 0);
        assert!(o.recovery.end_lag_ms <= 250.0, "{o:?}");
        // Every drop is in the overload or in the backlog it left (Zenoh's buffers drain into
        // the first second or two after it).
        assert_eq!(
            r.server.counters.dropped_total(),
            o.overload.dropped.values().sum::<u64>() + o.recovery.dropped.values().sum::<u64>(),
            "{:?}",
            r.server.counters
        );
        // Bounded memory: the queues are bounded; what the overload grew (allocator, tracks,
        // Zenoh buffers of the publishers in this process) stops growing after it.
        let (before, max, after) = (
            o.rss_before_kib.expect("rss"),
            o.overload.rss_max_kib.expect("rss"),
            o.recovery.rss_max_kib.expect("rss"),
        );
        assert!(max < before + 128 * 1024, "rss {before} → {max} KiB");
        assert!(
            after <= max + 16 * 1024,
            "rss {max} → {after} KiB after the overload"
        );
    }

    /// 2 vehicles × 20 Hz for 1 s, every part in: every published scan is processed, and every
    /// processed scan reaches both WebSocket clients.
    #[test]
    fn every_published_scan_is_accounted_for() {
        let a = args(&[
            "--vehicles",
            "2",
            "--rate-hz",
            "20",
            "--detections",
            "2",
            "--duration-s",
            "1",
            "--warmup-s",
            "0.3",
            "--ws-clients",
            "2",
            "--rest-connections",
            "1",
            "--rest-duration-s",
            "0.5",
            "--reorder-window-s",
            "0.01",
        ]);
        let r = measure(&a).expect("bench run");
        assert!(r.publish.scans >= 30, "{:?}", r.publish);
        assert_eq!(r.publish.failed, 0);
        assert!(r.server.drained);
        assert_eq!(r.server.lost, 0, "{:?}", r.server);
        assert_eq!(r.server.counters.received, r.publish.scans);
        assert_eq!(r.server.counters.ingested, r.publish.scans);
        assert_eq!(r.server.counters.detections, r.publish.detections);
        assert_eq!(r.server.counters.seq_lost, 0);
        let w = r.websocket.as_ref().expect("websocket report");
        assert_eq!(w.expected, 2 * r.publish.scans);
        assert_eq!((w.scan_messages, w.missing, w.errors), (w.expected, 0, 0));
        assert!(w.latency_ms.count > 0 && w.latency_ms.max < 1000.0, "{w:?}");
        let rest = r.rest.as_ref().expect("rest report");
        assert!(rest.ok > 0 && rest.errors == 0, "{rest:?}");
        assert!(r.rss.growth_kib.is_some());
        assert!(summary_lines(&r).iter().any(|l| l.starts_with("latency")));
    }
}
