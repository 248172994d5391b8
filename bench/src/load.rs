//! The load on the server ([`Load`]: the publishers, the vehicles' MAVLink, the WebSocket
//! clients, the REST load, the assignments) and the probe of its counters ([`Probe`]).

use std::time::Duration;

use anyhow::Context as _;
use tokio::time::Instant;

use super::args::BenchArgs;
use super::fleet::Fleet;
use super::publish::{Plan, Publishers};
use super::rest::{Api, RestReport};
use super::stats::{Counters, now_unix};
use super::target::{Target, free_loopback_endpoint};
use super::ws::Clients;

/// The server's counters of this run's vehicles, from its `/api/v1/metrics`.
pub(super) struct Probe<'a> {
    pub(super) api: &'a Api,
    pub(super) ids: Vec<u8>,
}

impl Probe<'_> {
    pub(super) async fn counters(&self) -> anyhow::Result<Counters> {
        let text = self
            .api
            .get("/api/v1/metrics")
            .await
            .context("reading the server's counters")?;
        let ours = |v: &str| v.parse::<u8>().is_ok_and(|id| self.ids.contains(&id));
        Ok(Counters::parse(&text, &ours))
    }
}

/// The tracker's lag: wall time − time of the last processed scan (s; 0 before the first).
pub(super) fn lag_s(c: &Counters) -> f64 {
    c.last_scan_t.map_or(0.0, |t| now_unix() - t)
}

/// Longest wait for every vehicle to be connected, and for confirmed tracks to assign to.
const LINK_TIMEOUT: Duration = Duration::from_secs(30);
/// Most vehicles in one assignment (the API's limit).
const MAX_PER_ASSIGNMENT: usize = 16;

/// The load on the server: the publishers, the vehicles' MAVLink, the WebSocket clients, and the
/// REST load from the steady state on.
pub(super) struct Load {
    pub(super) publishers: Publishers,
    pub(super) fleet: Option<Fleet>,
    /// Seconds from the vehicles' start until the server heard every one (`None`: not within
    /// [`LINK_TIMEOUT`], or no `--mavlink`).
    pub(super) connect_s: Option<f64>,
    /// The assignments made after the warm-up, and their vehicles.
    pub(super) assignments: Vec<(u64, Vec<u8>)>,
    pub(super) clients: Option<Clients>,
    pub(super) rest: Option<tokio::task::JoinHandle<RestReport>>,
    /// When the publishers started.
    pub(super) started: Instant,
}

/// Starts the vehicles' MAVLink and waits until the server has heard every one: the vehicles
/// and the seconds that took (`None` past [`LINK_TIMEOUT`]).
async fn fly(
    args: &BenchArgs,
    target: &Target,
    probe: &Probe<'_>,
) -> anyhow::Result<(Fleet, Option<f64>)> {
    let gcs = target
        .gcs
        .context("--mavlink: the server has no GCS link to send to")?;
    let ids = args.vehicle_ids();
    let t0 = Instant::now();
    let fleet = Fleet::start(
        &ids,
        gcs,
        args.telemetry_hz,
        harrier_server::config::DEFAULT_ORIGIN,
    )?;
    loop {
        let heard = probe.counters().await?.mavlink.connected;
        if heard >= ids.len() as u64 {
            let s = t0.elapsed().as_secs_f64();
            eprintln!(
                "harrier bench: {} vehicles connected over MAVLink in {s:.2} s",
                ids.len()
            );
            return Ok((fleet, Some(s)));
        }
        if t0.elapsed() > LINK_TIMEOUT {
            eprintln!(
                "harrier bench: only {heard} of {} vehicles connected within {LINK_TIMEOUT:?}",
                ids.len()
            );
            return Ok((fleet, None));
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Assigns the first `--assign` vehicles to the confirmed tracks (waiting for some), spread
/// evenly, at most [`MAX_PER_ASSIGNMENT`] in one: the assignments' ids and vehicles.
async fn assign(args: &BenchArgs, probe: &Probe<'_>) -> anyhow::Result<Vec<(u64, Vec<u8>)>> {
    let waited = Instant::now();
    let tracks = loop {
        let body = probe.api.get("/api/v1/tracks").await?;
        let v: serde_json::Value = serde_json::from_str(&body).context("GET /api/v1/tracks")?;
        let ids: Vec<u64> = v["tracks"]
            .as_array()
            .into_iter()
            .flatten()
            .filter(|k| k["status"] == "confirmed")
            .filter_map(|k| k["id"].as_u64())
            .collect();
        if !ids.is_empty() {
            break ids;
        }
        anyhow::ensure!(
            waited.elapsed() < LINK_TIMEOUT,
            "--assign: no confirmed track within {LINK_TIMEOUT:?}"
        );
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    let vehicles = &args.vehicle_ids()[..args.assign];
    let groups = vehicles
        .len()
        .div_ceil(MAX_PER_ASSIGNMENT)
        .max(tracks.len().min(vehicles.len()));
    let mut made = Vec::new();
    for g in 0..groups {
        let members: Vec<u8> = vehicles.iter().copied().skip(g).step_by(groups).collect();
        let track = tracks[g % tracks.len()];
        let body = serde_json::json!({"vehicles": members, "track": track, "law": "togvf"});
        let answer = probe.api.post("/api/v1/assignments", &body).await?;
        let v: serde_json::Value =
            serde_json::from_str(&answer).context("POST /api/v1/assignments")?;
        made.push((v["id"].as_u64().unwrap_or(0), members));
    }
    eprintln!(
        "harrier bench: {} vehicles assigned to {} tracks in {} assignments",
        vehicles.len(),
        tracks.len(),
        made.len()
    );
    Ok(made)
}

impl Load {
    /// Connects the WebSocket clients, starts the vehicles' MAVLink and waits for them, starts
    /// the publishers, waits out the warm-up and makes the assignments.
    pub(super) async fn start(
        args: &BenchArgs,
        target: &Target,
        probe: &Probe<'_>,
    ) -> anyhow::Result<Self> {
        let clients = if args.ws_clients > 0 {
            let mut url = format!("ws://{}/api/v1/ws", target.api.addr);
            if let Some(t) = &target.api.token {
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
        let (fleet, connect_s) = if args.mavlink {
            let (f, s) = fly(args, target, probe).await?;
            (Some(f), s)
        } else {
            (None, None)
        };
        let listen = free_loopback_endpoint()?;
        let publishers = Publishers::start(&Plan {
            vehicles: args.vehicle_ids(),
            sensors: args.sensors,
            rate_hz: args.rate_hz,
            detections: args.detections,
            origin: harrier_server::config::DEFAULT_ORIGIN,
            connect: target.zenoh.clone(),
            listen: Some(listen),
            phase: args.phase,
        })
        .await?;
        let started = Instant::now();
        eprintln!(
            "harrier bench: {} vehicles × {} Hz × {} detections publishing to {}; warm-up {} s, \
             then {} s measured",
            args.vehicles,
            args.rate_hz,
            args.detections,
            target.url,
            args.warmup_s,
            args.duration_s
        );
        tokio::time::sleep(Duration::from_secs_f64(args.warmup_s)).await;
        let assignments = if args.assign > 0 {
            assign(args, probe).await?
        } else {
            Vec::new()
        };
        Ok(Self {
            publishers,
            fleet,
            connect_s,
            assignments,
            clients,
            rest: None,
            started,
        })
    }

    /// `scan` messages the WebSocket clients received so far.
    pub(super) fn ws_scans(&self) -> u64 {
        self.clients.as_ref().map_or(0, |c| c.stats().scans())
    }

    /// Bytes the WebSocket clients received so far: all, and the `vehicles` messages.
    pub(super) fn ws_bytes(&self) -> (u64, u64) {
        self.clients.as_ref().map_or((0, 0), |c| c.stats().bytes())
    }
}
