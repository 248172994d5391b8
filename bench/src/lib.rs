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
//! By default the service runs in this process ([`harrier_server::start`], API on a free loopback
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
//!
//! The code follows a run: `args` (the command line and the in-process server's
//! configuration), `load` (what loads the server: publishers, WebSocket clients, REST, and the
//! probe of its counters), `phases` (warm-up, steady state, overload, drain), `report` (the
//! figures and the summary), over `publish`, `ws`, `rest` and `stats`.

mod args;
mod load;
mod outcome;
mod phases;
mod publish;
mod report;
mod rest;
mod stats;
mod target;
#[cfg(test)]
mod tests;
mod ws;

use anyhow::Context as _;

pub use self::args::BenchArgs;
use self::phases::drive;
pub use self::publish::Phase;
pub use self::report::{
    OverloadReport, PhaseReport, PublishReport, Report, RssReport, ServerReport, Setup,
    summary_lines,
};
use self::rest::Api;
pub use self::rest::RestReport;
pub use self::stats::{Counters, CpuUse, Machine, Percentiles, ServerLatency};
use self::target::{Target, free_loopback_endpoint};
pub use self::ws::WsReport;

/// Runs the load test and prints its figures.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
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
            .block_on(harrier_server::start(&config))
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
