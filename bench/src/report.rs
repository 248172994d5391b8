//! What a run of `harrier bench` measured ([`Report`], serialised by `--json`): the report put
//! together from the run's phases, the overload's figures from its samples, and the summary
//! table.

use serde::Serialize;
use tokio::time::Instant;

use super::args::BenchArgs;
use super::outcome::{Drained, Steady};
use super::publish::Phase;
use super::rest::RestReport;
use super::stats::{Counters, CpuUse, Machine, Percentiles, ServerLatency};
use super::target::Target;
use super::ws::WsReport;
use harrier_server::config::Config;

/// How the run was set up.
#[derive(Debug, Clone, Serialize)]
pub struct Setup {
    /// `in-process`, or the URL of the server attached to.
    pub server: String,
    /// Track filter of the in-process server.
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
    /// Whether the vehicles flew over MAVLink, at which telemetry rate (Hz).
    pub mavlink_telemetry_hz: Option<f64>,
    /// Vehicles assigned to tracks.
    pub assign: usize,
    /// The session recording of the server this tool started, if any.
    pub record: Option<String>,
}

/// The vehicles' MAVLink (`--mavlink`).
#[derive(Debug, Clone, Serialize)]
pub struct MavlinkReport {
    /// Seconds from the vehicles' start until the server heard every one (`None`: not
    /// within 30 s).
    pub connect_s: Option<f64>,
    /// Frames the vehicles sent.
    pub frames_sent: u64,
    /// Frames the server's GCS link received.
    pub frames_received: u64,
    /// Sent but not received (UDP: dropped by a full socket buffer).
    pub frames_lost: u64,
    /// Frames missing from the vehicles' MAVLink 2 sequence numbers, as the server counted.
    pub sequence_gaps: u64,
    /// Frames per second the server received over the steady state.
    pub frames_per_s: f64,
    /// Vehicles marked lost by the server (silent for its `mavlink.lost_after_s`).
    pub links_lost: u64,
    /// Vehicles that heard the ground station's HEARTBEAT.
    pub hearing_gcs: usize,
    /// The guidance of the assigned vehicles (`--assign`).
    pub guidance: Option<GuidanceReport>,
}

/// The guidance loop over the steady state (`--assign`).
#[derive(Debug, Clone, Serialize)]
pub struct GuidanceReport {
    /// Vehicles assigned.
    pub vehicles: usize,
    /// Assignments made.
    pub assignments: usize,
    /// Their vehicles by slot state at the end (`orbiting`, `taking_off`, …).
    pub slots: std::collections::BTreeMap<String, usize>,
    /// Loop iterations.
    pub ticks: u64,
    /// Share of ticks that started at most 1 ms late.
    pub within_1ms: Option<f64>,
    /// At most 5 ms late.
    pub within_5ms: Option<f64>,
    /// The latest a tick started since the server started (ms).
    pub late_max_ms: f64,
    /// Setpoints sent per second.
    pub setpoints_per_s: f64,
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
    /// The vehicles' MAVLink (`--mavlink`).
    pub mavlink: Option<MavlinkReport>,
}

/// The report of a run from what its phases measured.
pub(super) fn report(
    args: &BenchArgs,
    target: &Target,
    machine: Machine,
    steady: &Steady,
    d: Drained,
    overload: Option<OverloadReport>,
) -> Report {
    let steady_counts = steady.last.counters.since(&steady.c0);
    let rss_known = target.in_process || target.rss_pid.is_some();
    let (rss_start, rss_end) = (steady.rss_start, steady.rss_end);
    let mut websocket = d.websocket;
    if let Some(w) = &mut websocket {
        let per_client = steady.seconds * w.clients.max(1) as f64;
        w.bytes_per_s = steady.ws_bytes.0 as f64 / per_client;
        w.vehicles_bytes_per_s = steady.ws_bytes.1 as f64 / per_client;
    }
    let mavlink = d.link.as_ref().map(|l| {
        let m = &d.totals.mavlink;
        let s = &steady_counts.mavlink;
        MavlinkReport {
            connect_s: l.connect_s,
            frames_sent: l.frames_sent,
            frames_received: m.frames_received,
            frames_lost: l.frames_sent.saturating_sub(m.frames_received),
            sequence_gaps: m.frames_lost,
            frames_per_s: s.frames_received as f64 / steady.seconds,
            links_lost: m.link_lost,
            hearing_gcs: l.hearing_gcs,
            guidance: (args.assign > 0).then(|| GuidanceReport {
                vehicles: args.assign,
                assignments: l.assignments,
                slots: l.slots.clone(),
                ticks: s.guidance_ticks,
                within_1ms: s.ticks_within(0.001),
                within_5ms: s.ticks_within(0.005),
                late_max_ms: m.tick_late_max_s * 1e3,
                setpoints_per_s: s.setpoints as f64 / steady.seconds,
            }),
        }
    });
    Report {
        mavlink,
        setup: setup(args, target),
        machine,
        publish: PublishReport {
            scans: d.published,
            detections: d.published * args.detections as u64,
            failed: d.failed,
            seconds: d.publish_s,
            scans_per_s: steady.last.published.saturating_sub(steady.published0) as f64
                / steady.seconds,
        },
        server: ServerReport {
            not_received: d.published.saturating_sub(d.totals.received),
            lost: d.published.saturating_sub(d.totals.ingested),
            counters: d.totals,
            scans_per_s: steady_counts.ingested as f64 / steady.seconds,
            detections_per_s: steady_counts.detections as f64 / steady.seconds,
            max_lag_ms: steady.max_lag_s * 1e3,
            drained: d.drained,
            latency: steady_counts.server_latency(),
        },
        websocket,
        rest: d.rest,
        rss: RssReport {
            scope: match (target.in_process, target.rss_pid) {
                (true, _) => "this process: server, publishers and clients".to_string(),
                (false, Some(pid)) => format!("server process {pid}"),
                (false, None) => "not measured (give --server-pid)".to_string(),
            },
            start_kib: rss_start.filter(|_| rss_known),
            end_kib: rss_end.filter(|_| rss_known),
            growth_kib: match (rss_start, rss_end) {
                (Some(a), Some(b)) if rss_known => Some(b as i64 - a as i64),
                _ => None,
            },
        },
        cpu: steady.cpu,
        overload,
    }
}

/// How the run was set up (the in-process server's settings, with their defaults).
fn setup(args: &BenchArgs, target: &Target) -> Setup {
    let defaults = Config::default();
    Setup {
        server: match (target.in_process, target.configured, target.rss_pid) {
            (true, _, _) => "in-process".into(),
            (false, true, Some(pid)) => format!("child process {pid}"),
            _ => target.url.clone(),
        },
        estimator: target
            .configured
            .then(|| args.estimator.clone().unwrap_or_else(|| "ekf".into())),
        reorder_window_s: target.configured.then(|| {
            args.reorder_window_s
                .unwrap_or(defaults.tracker.reorder_window_s)
        }),
        queue: target
            .configured
            .then(|| args.queue.unwrap_or(defaults.tracker.queue)),
        ws_queue: target
            .configured
            .then(|| args.ws_queue.unwrap_or(defaults.api.ws_queue)),
        mavlink_telemetry_hz: args.mavlink.then_some(args.telemetry_hz),
        assign: args.assign,
        record: args.record.as_ref().map(|p| p.display().to_string()),
        vehicles: args.vehicles,
        rate_hz: args.rate_hz,
        phase: args.phase,
        detections: args.detections,
        warmup_s: args.warmup_s,
        duration_s: args.duration_s,
        recovered_lag_ms: args.recovered_lag_ms,
    }
}

/// One sample of an overload phase.
#[derive(Debug, Clone)]
pub(super) struct Sample {
    pub(super) at: Instant,
    pub(super) lag_s: f64,
    pub(super) rss_kib: Option<u64>,
    pub(super) published: u64,
    pub(super) counters: Counters,
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
pub(super) fn overload_report(
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
        (Some(e), Some(w), Some(q), Some(wq)) => format!(
            "{} server: {e}, reorder window {w} s, queue {q}, ws_queue {wq}{}",
            s.server,
            s.record
                .as_ref()
                .map_or(String::new(), |r| format!(", recording to {r}"))
        ),
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
    if let Some(m) = &r.mavlink {
        out.push(format!(
            "mavlink      {} vehicles at {} Hz: all connected {}; {} frames sent, {} received ({:.0}/s), lost {}, sequence gaps {}; links lost {}; {} hear the ground station",
            s.vehicles,
            s.mavlink_telemetry_hz.unwrap_or(0.0),
            m.connect_s.map_or("NOT within 30 s".to_string(), |t| format!("after {t:.2} s")),
            m.frames_sent,
            m.frames_received,
            m.frames_per_s,
            m.frames_lost,
            m.sequence_gaps,
            m.links_lost,
            m.hearing_gcs
        ));
        if let Some(g) = &m.guidance {
            let pct =
                |x: Option<f64>| x.map_or("–".to_string(), |x| format!("{:.1} %", 100.0 * x));
            out.push(format!(
                "guidance     {} vehicles in {} assignments ({}); {} ticks: {} within 1 ms, {} within 5 ms late, latest {:.2} ms; {:.0} setpoints/s",
                g.vehicles,
                g.assignments,
                g.slots
                    .iter()
                    .map(|(k, n)| format!("{n} {k}"))
                    .collect::<Vec<_>>()
                    .join(", "),
                g.ticks,
                pct(g.within_1ms),
                pct(g.within_5ms),
                g.late_max_ms,
                g.setpoints_per_s
            ));
        }
    }
    if let Some(w) = &r.websocket {
        out.push(format!(
            "websocket    {} clients: {} scan messages of {} expected; missing {}, resyncs {}, out of order {}, errors {}; {:.1} kB/s per client ({:.1} kB/s of it `vehicles`)",
            w.clients, w.scan_messages, w.expected, w.missing, w.resyncs, w.out_of_order, w.errors,
            w.bytes_per_s / 1e3, w.vehicles_bytes_per_s / 1e3
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
            "cpu          {:.2} cores measured ({}){}, machine {:.2}, others {:.2} (steady state)",
            c.measured_cores,
            match (
                r.setup.server == "in-process",
                r.rss.scope.starts_with("server process")
            ) {
                (true, _) => "this process",
                (false, true) => "this process and the server's",
                (false, false) => "this process only",
            },
            c.server_cores
                .map_or(String::new(), |s| format!(", the server alone {s:.3}")),
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
