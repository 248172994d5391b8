//! `harrier bench`: the live service's load tool.
//!
//! ```not_rust
//! harrier bench --vehicles 10 --rate-hz 50 --detections 4 --duration-s 600 --ws-clients 1
//! harrier bench --vehicles 10 --rate-hz 1 --ws-clients 500
//! harrier bench --rest-connections 32 --rest-duration-s 10 --duration-s 10 --ws-clients 0
//! harrier bench --url http://127.0.0.1:8080 --zenoh-connect tcp/127.0.0.1:7447 --server-pid 4242
//! harrier bench --duration-s 30 --overload-factor 10 --overload-s 60 --recovery-s 30 --ws-clients 0
//! harrier bench --server-process --vehicles 255 --rate-hz 10 --mavlink --assign 50 --duration-s 600
//! harrier bench --server-process --sweep 10,50,100,255 --rate-hz 10 --mavlink --assign 50
//! harrier bench --publish-only --zenoh-connect tcp/10.0.0.1:7447 --vehicles 250 --sensors 4 --rate-hz 1
//! ```
//!
//! By default the service runs in this process ([`harrier_server::start`], API on a free loopback
//! port, Zenoh listening on another) on a tokio runtime of its own; `--server-process` runs it as
//! a child process (`harrier serve`, `child`) with the same configuration, so that its CPU and
//! memory are its own; `--url` and `--zenoh-connect` attach to one running elsewhere instead.
//! Everything goes through real sockets either way:
//!
//! - simulated vehicles publish `DetectionScan`s on their Zenoh keys from a session of their own
//!   (`publish`); with `--mavlink` each also flies as a PX4-like harrier-sim vehicle sending its
//!   telemetry to the server's GCS link over UDP (`fleet`), and `--assign` hands some of them to
//!   the guidance;
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
//! every `--progress-s`; the summary to stdout, as a table or (`--json`) as JSON. `--sweep
//! 10,50,100,255` makes one run per vehicle count and prints how each figure grows. `--publish-only`
//! runs only the publishers, as a Zenoh client of a router, until `--duration-s` is over.
//!
//! The code follows a run: `args` (the command line and the configuration of the server it
//! starts), `load` (what loads the server: publishers, vehicles, WebSocket clients, REST, and
//! the probe of its counters), `phases` (warm-up, steady state, overload, drain), `report` (the
//! figures and the summary), `sweep` (runs by vehicle count), over `publish`, `fleet`, `ws`,
//! `rest`, `stats` and `child`.

mod args;
mod child;
mod fleet;
mod load;
mod outcome;
mod phases;
mod publish;
mod report;
mod rest;
mod stats;
mod sweep;
mod target;
#[cfg(test)]
mod tests;
mod ws;

use anyhow::Context as _;

pub use self::args::BenchArgs;
use self::phases::drive;
pub use self::publish::Phase;
pub use self::report::{
    GuidanceReport, MavlinkReport, OverloadReport, PhaseReport, PublishReport, Report, RssReport,
    ServerReport, Setup, summary_lines,
};
use self::rest::Api;
pub use self::rest::RestReport;
pub use self::stats::{Counters, CpuUse, LinkCounters, Machine, Percentiles, ServerLatency};
pub use self::sweep::sweep_lines;
use self::target::{Target, free_loopback_endpoint, free_loopback_udp};
pub use self::ws::WsReport;

/// Runs the load test (or the sweep, or only the publishers) and prints its figures.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let text = if args.publish_only {
        publish_only(args)?
    } else if args.sweep.is_empty() {
        let report = measure(args)?;
        if args.json {
            serde_json::to_string_pretty(&report)?
        } else {
            summary_lines(&report).join("\n")
        }
    } else {
        args.check()?;
        let mut reports = Vec::new();
        for run in args.sweep_runs() {
            eprintln!("harrier bench: sweep: {} vehicles", run.vehicles);
            let r = measure(&run)?;
            eprintln!("{}", summary_lines(&r).join("\n"));
            reports.push(r);
        }
        if args.json {
            serde_json::to_string_pretty(&reports)?
        } else {
            sweep_lines(&reports).join("\n")
        }
    };
    use std::io::Write as _;
    let _ = writeln!(std::io::stdout().lock(), "{text}");
    Ok(())
}

/// `--publish-only`: the vehicles' sensors publish to `--zenoh-connect` (as a Zenoh client)
/// for `--duration-s` once a subscriber matches each; returns what was published.
fn publish_only(args: &BenchArgs) -> anyhow::Result<String> {
    args.check()?;
    let rt = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("bench-load")
        .build()?;
    let sources = usize::from(args.vehicles) * usize::from(args.sensors);
    let (scans, failed) = rt.block_on(async {
        let publishers = publish::Publishers::start(&publish::Plan {
            vehicles: args.vehicle_ids(),
            sensors: args.sensors,
            rate_hz: args.rate_hz,
            detections: args.detections,
            origin: harrier_server::config::DEFAULT_ORIGIN,
            connect: args.zenoh_connect.clone(),
            listen: None,
            phase: args.phase,
        })
        .await?;
        eprintln!(
            "harrier bench: publishing: {sources} sources ({} vehicles from {} × {} sensors) × \
             {} Hz × {} detections to {} for {} s",
            args.vehicles,
            args.first_vehicle,
            args.sensors,
            args.rate_hz,
            args.detections,
            args.zenoh_connect.join(", "),
            args.duration_s
        );
        tokio::time::sleep(std::time::Duration::from_secs_f64(args.duration_s)).await;
        anyhow::Ok(publishers.stop().await)
    })?;
    Ok(if args.json {
        serde_json::json!({"sources": sources, "scans": scans, "failed": failed,
            "duration_s": args.duration_s})
        .to_string()
    } else {
        format!(
            "harrier bench: published {scans} scans from {sources} sources in {} s ({failed} \
             failed puts)",
            args.duration_s
        )
    })
}

/// A random API token for a server this tool starts.
fn token() -> String {
    use rand::Rng as _;
    let mut rng = rand::rng();
    (0..32)
        .map(|_| char::from_digit(rng.random_range(0..16), 16).unwrap_or('0'))
        .collect()
}

/// Runs the load test: starts the server (in this process, or as a child with
/// `--server-process`; or attaches to `--url`), loads it, and returns the figures.
pub fn measure(args: &BenchArgs) -> anyhow::Result<Report> {
    args.check()?;
    let machine = Machine::now();
    let load = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .thread_name("bench-load")
        .build()?;
    let Some(url) = &args.url else {
        let endpoint = free_loopback_endpoint()?;
        let gcs = if args.mavlink {
            Some(free_loopback_udp()?)
        } else {
            None
        };
        let token = token();
        let target = |addr, rss_pid, in_process| Target {
            api: Api {
                addr,
                token: Some(token.clone()),
            },
            zenoh: vec![endpoint.clone()],
            url: format!("http://{addr}"),
            rss_pid,
            in_process,
            configured: true,
            gcs,
        };
        if args.server_process {
            let bin = match &args.server_bin {
                Some(b) => b.clone(),
                None => std::env::current_exe().context("the harrier binary")?,
            };
            let server =
                child::ServerProcess::start(&bin, &args.server_toml(&endpoint, gcs, &token))?;
            let report = load.block_on(drive(
                args,
                &target(server.addr, Some(server.pid()), false),
                machine,
            ));
            server.stop();
            return report;
        }
        let server_rt = tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .thread_name("bench-server")
            .build()?;
        let config = args.server_config(&endpoint, gcs, &token)?;
        let server = server_rt
            .block_on(harrier_server::start(&config))
            .context("starting the in-process server")?;
        let report = load.block_on(drive(
            args,
            &target(server.local_addr(), None, true),
            machine,
        ));
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
        configured: false,
        gcs: args.gcs,
    };
    load.block_on(drive(args, &target, machine))
}
