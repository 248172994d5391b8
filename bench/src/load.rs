//! The load on the server ([`Load`]: the publishers, the WebSocket clients, the REST load) and
//! the probe of its counters ([`Probe`]).

use std::time::Duration;

use anyhow::Context as _;
use tokio::time::Instant;

use super::args::BenchArgs;
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

/// The load on the server: the publishers, the WebSocket clients, and the REST load from the
/// steady state on.
pub(super) struct Load {
    pub(super) publishers: Publishers,
    pub(super) clients: Option<Clients>,
    pub(super) rest: Option<tokio::task::JoinHandle<RestReport>>,
    /// When the publishers started.
    pub(super) started: Instant,
}

impl Load {
    /// Connects the WebSocket clients, starts the publishers and waits out the warm-up.
    pub(super) async fn start(args: &BenchArgs, target: &Target) -> anyhow::Result<Self> {
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
        let listen = free_loopback_endpoint()?;
        let publishers = Publishers::start(&Plan {
            vehicles: args.vehicle_ids(),
            rate_hz: args.rate_hz,
            detections: args.detections,
            origin: harrier_server::config::DEFAULT_ORIGIN,
            connect: target.zenoh.clone(),
            listen,
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
        Ok(Self {
            publishers,
            clients,
            rest: None,
            started,
        })
    }

    /// `scan` messages the WebSocket clients received so far.
    pub(super) fn ws_scans(&self) -> u64 {
        self.clients.as_ref().map_or(0, |c| c.stats().scans())
    }
}
