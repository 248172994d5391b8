//! The phases of a run, on the load's runtime ([`drive`]): warm-up, the measured steady state
//! with its progress lines, the overload and recovery if asked, and the drain.

use std::sync::Arc;
use std::time::Duration;

use anyhow::Context as _;
use tokio::time::Instant;

use super::args::BenchArgs;
use super::load::{Load, Probe, lag_s};
use super::outcome::{Drained, LinkOutcome, Progress, Steady};
use super::report::{OverloadReport, Report, Sample, overload_report, report};
use super::rest::RestLoad;
use super::stats::{Counters, CpuSample, Machine, load_1m, rss_kib};
use super::target::Target;

/// Longest wait for the server to process what it received, and for the WebSocket clients to
/// receive it, after the publishers stopped.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(20);

/// The load, on the load's runtime: the warm-up, the steady state, the overload if asked, the
/// drain; then the report.
pub(super) async fn drive(
    args: &BenchArgs,
    target: &Target,
    mut machine: Machine,
) -> anyhow::Result<Report> {
    let probe = Probe {
        api: &target.api,
        ids: args.vehicle_ids(),
    };
    let base = probe.counters().await?;
    let mut load = Load::start(args, target, &probe).await?;
    let steady = steady_state(args, target, &probe, &mut load, &base).await?;
    let overload = if args.overload_s > 0.0 {
        Some(overload(args, target, &probe, &load, &base, steady.rss_end).await?)
    } else {
        None
    };
    let drained = drain(&probe, load, &base).await?;
    machine.load_end = load_1m();
    Ok(report(args, target, machine, &steady, drained, overload))
}

/// The measured steady state: the REST load starts, the WebSocket clients record latencies,
/// and a progress line goes to stderr every `--progress-s`.
async fn steady_state(
    args: &BenchArgs,
    target: &Target,
    probe: &Probe<'_>,
    load: &mut Load,
    base: &Counters,
) -> anyhow::Result<Steady> {
    let steady = Instant::now();
    let end = steady + Duration::from_secs_f64(args.duration_s);
    let rss_start = rss_kib(target.rss_pid);
    let cpu_start = CpuSample::now(target.rss_pid);
    let c0 = probe.counters().await?;
    let published0 = load.publishers.scans();
    let ws_bytes0 = load.ws_bytes();
    if let Some(c) = &load.clients {
        c.stats().record(true);
    }
    let rest_load = Arc::new(RestLoad::default());
    load.rest = (args.rest_connections > 0).then(|| {
        tokio::spawn(Arc::clone(&rest_load).run(
            target.api.clone(),
            args.rest_path.clone(),
            args.rest_connections,
            Duration::from_secs_f64(args.rest_duration_s.min(args.duration_s)),
        ))
    });
    let mut max_lag_s: f64 = 0.0;
    let mut last = Progress {
        at: Instant::now(),
        counters: c0.clone(),
        published: published0,
        ws_scans: load.ws_scans(),
        rest_ok: 0,
        ws_bytes: ws_bytes0,
        cpu: cpu_start,
    };
    loop {
        let next = (Instant::now() + Duration::from_secs_f64(args.progress_s)).min(end);
        tokio::time::sleep_until(next).await;
        let counters = probe.counters().await?;
        let lag = lag_s(&counters);
        max_lag_s = max_lag_s.max(lag);
        let now = Progress {
            at: Instant::now(),
            counters,
            published: load.publishers.scans(),
            ws_scans: load.ws_scans(),
            rest_ok: rest_load.ok(),
            ws_bytes: load.ws_bytes(),
            cpu: CpuSample::now(target.rss_pid),
        };
        eprintln!(
            "[{:7.1} s] {}",
            (now.at - steady).as_secs_f64(),
            progress_line(&last, &now, lag, base, load, target.rss_pid)
        );
        last = now;
        if last.at >= end {
            break;
        }
    }
    let seconds = steady.elapsed().as_secs_f64();
    let rss_end = rss_kib(target.rss_pid);
    let cpu = cpu_start
        .zip(CpuSample::now(target.rss_pid))
        .map(|(a, b)| a.until(&b));
    if let Some(c) = &load.clients {
        c.stats().record(false);
    }
    let ws_bytes = (
        last.ws_bytes.0.saturating_sub(ws_bytes0.0),
        last.ws_bytes.1.saturating_sub(ws_bytes0.1),
    );
    Ok(Steady {
        ws_bytes,
        c0,
        published0,
        last,
        seconds,
        max_lag_s,
        rss_start,
        rss_end,
        cpu,
    })
}

/// A progress line: the rates between two samples, the lag, the drops since the run started,
/// the WebSocket clients' latency, the REST rate, CPU and resident memory.
fn progress_line(
    last: &Progress,
    now: &Progress,
    lag: f64,
    base: &Counters,
    load: &Load,
    rss_pid: Option<u32>,
) -> String {
    let dt = (now.at - last.at).as_secs_f64().max(1e-9);
    let rate = |a: u64, b: u64| a.saturating_sub(b) as f64 / dt;
    let ws = load.clients.as_ref().map_or(String::new(), |cl| {
        format!(
            "  ws {:.0} msg/s {:.0} kB/s p99 {:.1} ms",
            rate(now.ws_scans, last.ws_scans),
            rate(now.ws_bytes.0, last.ws_bytes.0) / 1e3,
            cl.stats().latency().p99
        )
    });
    let (m, m_last) = (&now.counters.mavlink, &last.counters.mavlink);
    let mav = if load.fleet.is_some() {
        format!(
            "  mavlink {:.0} frames/s, {} connected, {} lost",
            rate(m.frames_received, m_last.frames_received),
            m.connected,
            m.frames_lost.saturating_sub(base.mavlink.frames_lost),
        )
    } else {
        String::new()
    };
    let cpu = last.cpu.zip(now.cpu).map_or(String::new(), |(a, b)| {
        let u = a.until(&b);
        format!(
            "  cpu {:.2} + others {:.2}",
            u.measured_cores, u.others_cores
        )
    });
    let rss = rss_kib(rss_pid).map_or(String::new(), |k| {
        format!("  rss {:.1} MiB", k as f64 / 1024.0)
    });
    let rest = if load.rest.is_some() {
        format!("  rest {:.0} req/s", rate(now.rest_ok, last.rest_ok))
    } else {
        String::new()
    };
    let (c, c_last) = (&now.counters, &last.counters);
    format!(
        "published {:.0} scans/s  processed {:.0} scans/s {:.0} det/s  lag {:.1} ms  \
         dropped {}{ws}{mav}{rest}{cpu}{rss}",
        rate(now.published, last.published),
        rate(c.ingested, c_last.ingested),
        rate(c.detections, c_last.detections),
        lag * 1e3,
        c.since(base).dropped_total(),
    )
}

/// The overload: every vehicle at `--overload-factor` × its rate for `--overload-s`, then the
/// nominal rate for `--recovery-s`, each phase sampled about once a second.
async fn overload(
    args: &BenchArgs,
    target: &Target,
    probe: &Probe<'_>,
    load: &Load,
    base: &Counters,
    rss_before: Option<u64>,
) -> anyhow::Result<OverloadReport> {
    let sample = async || -> anyhow::Result<Sample> {
        let c = probe.counters().await?;
        Ok(Sample {
            at: Instant::now(),
            lag_s: lag_s(&c),
            rss_kib: rss_kib(target.rss_pid),
            published: load.publishers.scans(),
            counters: c,
        })
    };
    let every = Duration::from_secs_f64(args.progress_s.min(1.0));
    let mut phases: Vec<(f64, Vec<Sample>)> = Vec::new();
    for (factor, seconds) in [
        (args.overload_factor, args.overload_s),
        (1.0, args.recovery_s),
    ] {
        load.publishers.set_rate_factor(factor);
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
                s.counters.since(base).dropped_total(),
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
    Ok(overload_report(args, rss_before, &phases))
}

/// Stops the publishers, waits (at most [`DRAIN_TIMEOUT`]) until the server has processed or
/// dropped every payload it received and every WebSocket client has the last scan, and
/// collects the REST load's report.
async fn drain(probe: &Probe<'_>, load: Load, base: &Counters) -> anyhow::Result<Drained> {
    let (published, failed) = load.publishers.stop().await;
    let publish_s = load.started.elapsed().as_secs_f64();
    let hearing_gcs = load
        .fleet
        .as_ref()
        .map_or(0, super::fleet::Fleet::hearing_gcs);
    let frames_sent = load.fleet.map(super::fleet::Fleet::stop);
    let drain_start = Instant::now();
    let (totals, drained) = loop {
        let c = probe.counters().await?.since(base);
        let settled = c.ingested + c.dropped_total() >= c.received;
        let frames_in = frames_sent.is_none_or(|n| c.mavlink.frames_received >= n);
        if settled && c.received >= published && frames_in {
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
        let body = probe.api.get("/api/v1/tracks").await?;
        let v: serde_json::Value = serde_json::from_str(&body).context("GET /api/v1/tracks")?;
        v["seq"]
            .as_u64()
            .context("GET /api/v1/tracks: no seq in the answer")?
    };
    let websocket = match load.clients {
        Some(c) => Some(c.finish(final_seq, DRAIN_TIMEOUT).await),
        None => None,
    };
    let rest = match load.rest {
        Some(t) => Some(t.await.context("the REST load")?),
        None => None,
    };
    let link = match frames_sent {
        Some(frames_sent) => Some(LinkOutcome {
            frames_sent,
            hearing_gcs,
            connect_s: load.connect_s,
            slots: slot_states(probe, &load.assignments).await?,
            assignments: load.assignments.len(),
        }),
        None => None,
    };
    Ok(Drained {
        link,
        published,
        failed,
        publish_s,
        totals,
        drained,
        websocket,
        rest,
    })
}

/// The vehicles of the run's assignments by slot state (`GET /api/v1/assignments`).
async fn slot_states(
    probe: &Probe<'_>,
    made: &[(u64, Vec<u8>)],
) -> anyhow::Result<std::collections::BTreeMap<String, usize>> {
    let mut states = std::collections::BTreeMap::new();
    if made.is_empty() {
        return Ok(states);
    }
    let body = probe.api.get("/api/v1/assignments").await?;
    let v: serde_json::Value = serde_json::from_str(&body).context("GET /api/v1/assignments")?;
    let ours = |a: &&serde_json::Value| {
        a["id"]
            .as_u64()
            .is_some_and(|id| made.iter().any(|(m, _)| *m == id))
    };
    let all = v["assignments"].as_array().cloned().unwrap_or_default();
    for a in all.iter().filter(ours) {
        for s in a["vehicles"].as_array().into_iter().flatten() {
            let state = s["state"].as_str().unwrap_or("unknown").to_string();
            *states.entry(state).or_default() += 1;
        }
    }
    Ok(states)
}
