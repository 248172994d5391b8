//! The command line of `harrier bench` ([`BenchArgs`]), its checks, and the in-process
//! server's configuration it gives.

use std::fmt::Write as _;
use std::net::SocketAddr;
use std::path::PathBuf;

use harrier_server::config::Config;

use super::publish::Phase;

/// Arguments of `harrier bench`.
#[derive(Debug, Clone, clap::Args)]
pub struct BenchArgs {
    /// Simulated vehicles, each publishing `--sensors` sensors' scans on its own key.
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u8).range(1..))]
    pub vehicles: u8,
    /// Sensors per vehicle, each a source of its own (`cam` when 1, else `cam0`, `cam1` …: its
    /// own `seq` sequence, its own place in the reorder buffer): vehicles × sensors sources, e.g.
    /// 250 × 4 = 1 000 over MAVLink's 255 system ids.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=64))]
    pub sensors: u8,
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
    /// In-process server: track filter (ekf, cdkf, imm, cimm; default ekf).
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
    /// With `--url` or `--publish-only`: the Zenoh endpoint to publish to (the server's, or a
    /// router's), e.g. tcp/127.0.0.1:7447 (repeatable).
    #[arg(long, value_name = "ENDPOINT")]
    pub zenoh_connect: Vec<String>,
    /// Only publish: the vehicles' scans as a Zenoh client of `--zenoh-connect` (a router, or a
    /// server listening) for `--duration-s`, then print how many were published; no server, no
    /// WebSocket, no measurement. Several such processes (distinct `--first-vehicle` ranges)
    /// spread sources over the routers of a mesh (tests/tests/it/mesh.rs).
    #[arg(long, conflicts_with_all = ["url", "server_process", "sweep", "mavlink", "record"])]
    pub publish_only: bool,
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
    /// Every vehicle also flies: a PX4-like harrier-sim vehicle on its own UDP socket (all of
    /// them on a few threads of this process) sends its telemetry to the server's GCS link and
    /// answers its commands. The run counts the frames sent and received, the time until every
    /// vehicle is connected, and the vehicles that hear the ground station's HEARTBEAT.
    #[arg(long)]
    pub mavlink: bool,
    /// With --mavlink: rate (Hz) of GLOBAL_POSITION_INT, LOCAL_POSITION_NED and ATTITUDE (the
    /// other streams keep PX4's 0.5–5 Hz).
    #[arg(long, default_value_t = 10.0)]
    pub telemetry_hz: f64,
    /// With --mavlink and --url: the server's GCS link (UDP), HOST:PORT.
    #[arg(long, requires = "url")]
    pub gcs: Option<SocketAddr>,
    /// With --mavlink: once the warm-up is over, assign this many vehicles (the first ones) to
    /// the confirmed tracks (TOGVF, spread over the tracks, at most 16 a track), and report the
    /// guidance loop's lateness (with --url, give --token).
    #[arg(long, default_value_t = 0)]
    pub assign: usize,
    /// Record the session into this SQLite file (and the raw MAVLink beside it,
    /// FILE-session-N.tlog): the recorder's load too.
    #[arg(long, value_name = "FILE")]
    pub record: Option<PathBuf>,
    /// Run the server as a child process (`harrier serve`) instead of in this process, so that
    /// its CPU and memory are measured apart from the load's.
    #[arg(long)]
    pub server_process: bool,
    /// With --server-process: the `harrier` binary that serves (default: this one), e.g. an
    /// older build to compare.
    #[arg(long, value_name = "PATH", requires = "server_process")]
    pub server_bin: Option<PathBuf>,
    /// One run per vehicle count, e.g. 10,50,100,255 (each with a fresh server), then a table
    /// of how each figure grows with the number of vehicles; --vehicles is ignored.
    #[arg(long, value_delimiter = ',', value_name = "N,N,…")]
    pub sweep: Vec<u8>,
}

/// The highest vehicle id with `--mavlink`: 255 is the ground station's own system id.
const MAX_MAVLINK_ID: u16 = 254;

impl BenchArgs {
    /// Checks what clap cannot.
    pub(super) fn check(&self) -> anyhow::Result<()> {
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
        bad(
            self.zenoh_connect.is_empty() || self.url.is_some() || self.publish_only,
            "--zenoh-connect needs --url or --publish-only",
        )?;
        bad(
            !self.publish_only || !self.zenoh_connect.is_empty(),
            "--publish-only needs --zenoh-connect ENDPOINT",
        )?;
        if self.url.is_some() {
            bad(
                self.estimator.is_none()
                    && self.reorder_window_s.is_none()
                    && self.queue.is_none()
                    && self.ws_queue.is_none()
                    && self.record.is_none()
                    && !self.server_process,
                "--estimator, --reorder-window-s, --queue, --ws-queue, --record and \
                 --server-process configure the server this tool starts; with --url, configure \
                 the server you run",
            )?;
            bad(
                !self.mavlink || self.gcs.is_some(),
                "--mavlink with --url needs --gcs HOST:PORT, the server's GCS link (UDP)",
            )?;
        }
        bad(
            self.telemetry_hz.is_finite() && self.telemetry_hz > 0.0 && self.telemetry_hz <= 1000.0,
            "--telemetry-hz must be in (0, 1000]",
        )?;
        bad(
            self.assign == 0 || self.mavlink,
            "--assign needs --mavlink (the guidance flies vehicles over MAVLink)",
        )?;
        bad(
            !self.sweep.is_empty() || self.assign <= usize::from(self.vehicles),
            "--assign must be at most --vehicles",
        )?;
        bad(
            self.sweep
                .iter()
                .all(|&n| n >= 1 && u16::from(self.first_vehicle) + u16::from(n) - 1 <= 255),
            "every --sweep count must be ≥ 1, and --first-vehicle + count - 1 ≤ 255",
        )?;
        // The ground station has a MAVLink system id too (255 by default): a vehicle with it
        // would never be heard.
        let last = |n: u8| u16::from(self.first_vehicle) + u16::from(n) - 1;
        bad(
            !self.mavlink
                || std::iter::once(self.vehicles)
                    .chain(self.sweep.iter().copied())
                    .all(|n| last(n) <= MAX_MAVLINK_ID),
            "with --mavlink, --first-vehicle + count - 1 must be ≤ 254 (255 is the ground \
             station's own MAVLink system id)",
        )?;
        Ok(())
    }

    /// The runs a sweep makes: these arguments with `--vehicles` set to each count, no sweep.
    pub(super) fn sweep_runs(&self) -> Vec<Self> {
        self.sweep
            .iter()
            .map(|&n| Self {
                vehicles: n,
                assign: self.assign.min(usize::from(n)),
                sweep: Vec::new(),
                ..self.clone()
            })
            .collect()
    }

    /// The vehicles' MAVLink ids.
    pub(super) fn vehicle_ids(&self) -> Vec<u8> {
        (0..self.vehicles)
            .map(|k| self.first_vehicle.saturating_add(k))
            .collect()
    }

    /// The configuration (TOML) of the server this tool starts: its API on a free loopback
    /// port with `token`, its Zenoh session listening on `zenoh`, its GCS link on `gcs` (none:
    /// no MAVLink), no router endpoint, and the options given.
    pub(super) fn server_toml(&self, zenoh: &str, gcs: Option<SocketAddr>, token: &str) -> String {
        let q = |s: &str| format!("{s:?}");
        // Every client of the run at once, and room for its own requests (/metrics, /tracks).
        let clients = self.ws_clients + self.rest_connections + 16;
        let max_connections = Config::default().api.max_connections.max(clients);
        let mut t = String::new();
        let _ = writeln!(t, "[api]\nlisten = \"127.0.0.1:0\"\ntoken = {}", q(token));
        let _ = writeln!(t, "max_connections = {max_connections}");
        if let Some(n) = self.ws_queue {
            let _ = writeln!(t, "ws_queue = {n}");
        }
        let _ = writeln!(t, "[zenoh]\nlisten = [{}]\nconnect = []", q(zenoh));
        let _ = writeln!(t, "[tracker]");
        if let Some(e) = &self.estimator {
            let _ = writeln!(t, "estimator = {}", q(e));
        }
        if let Some(w) = self.reorder_window_s {
            let _ = writeln!(t, "reorder_window_s = {w:?}");
        }
        if let Some(n) = self.queue {
            let _ = writeln!(t, "queue = {n}");
        }
        let gcs = gcs.map_or(String::new(), |a| q(&format!("udpin:{a}")));
        let _ = writeln!(t, "[mavlink]\ngcs = [{gcs}]\nrouter = []");
        if let Some(path) = &self.record {
            let _ = writeln!(t, "[recorder]\npath = {}", q(&path.display().to_string()));
        }
        t
    }

    /// The in-process server's configuration ([`Self::server_toml`]).
    pub(super) fn server_config(
        &self,
        zenoh: &str,
        gcs: Option<SocketAddr>,
        token: &str,
    ) -> anyhow::Result<Config> {
        let text = self.server_toml(zenoh, gcs, token);
        Ok(Config::parse(&text, "the bench's server configuration")?)
    }
}
