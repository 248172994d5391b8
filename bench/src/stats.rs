//! What `harrier bench` measures with: a lock-free latency histogram, the process's resident
//! memory, the wall clock as UNIX time, the machine, and the server's Prometheus counters.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use serde::Serialize;

/// Sub-buckets per power of two: a recorded value is known to within 1/128 (0.8 %).
const SUB_BITS: u32 = 7;
const SUB: u64 = 1 << SUB_BITS;
/// Largest value kept (ns, ≈ 18 min); larger ones count as this.
const MAX_NS: u64 = (1 << 40) - 1;
/// Buckets: exact below `SUB`, then `SUB` per power of two up to `MAX_NS`.
const BUCKETS: usize = ((40 - SUB_BITS as usize) + 1) * SUB as usize;

/// A log-linear histogram of durations (ns), shared by many recorders without a lock: a fixed
/// array of counters allocated once, so recording neither allocates nor grows memory.
#[derive(Debug)]
pub(super) struct Histogram {
    buckets: Vec<AtomicU64>,
    max_ns: AtomicU64,
    sum_ns: AtomicU64,
}

impl Default for Histogram {
    fn default() -> Self {
        Self {
            buckets: (0..BUCKETS).map(|_| AtomicU64::new(0)).collect(),
            max_ns: AtomicU64::new(0),
            sum_ns: AtomicU64::new(0),
        }
    }
}

fn bucket_of(ns: u64) -> usize {
    if ns < SUB {
        return ns as usize;
    }
    let shift = (63 - ns.leading_zeros()) - SUB_BITS;
    let mantissa = ns >> shift;
    ((shift as u64 + 1) * SUB + (mantissa - SUB)) as usize
}

/// The midpoint (ns) of bucket `i`.
fn value_of(i: usize) -> f64 {
    let i = i as u64;
    if i < SUB {
        return i as f64;
    }
    let shift = i / SUB - 1;
    let low = (SUB + i % SUB) << shift;
    low as f64 + ((1u64 << shift) as f64 - 1.0) / 2.0
}

/// Percentiles of a histogram, in milliseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Percentiles {
    /// Values recorded.
    pub count: u64,
    /// Mean.
    pub mean: f64,
    /// Median.
    pub p50: f64,
    /// 90th percentile.
    pub p90: f64,
    /// 99th percentile.
    pub p99: f64,
    /// 99.9th percentile.
    pub p999: f64,
    /// Largest value (exact).
    pub max: f64,
}

impl Histogram {
    /// Records one duration in seconds (negative values count as 0).
    pub(super) fn record_s(&self, seconds: f64) {
        let ns = (seconds.max(0.0) * 1e9).min(MAX_NS as f64) as u64;
        self.buckets[bucket_of(ns)].fetch_add(1, Relaxed);
        self.max_ns.fetch_max(ns, Relaxed);
        self.sum_ns.fetch_add(ns, Relaxed);
    }

    /// The value (ms) below which a fraction `q` of the recorded values lie, to the bucket's
    /// midpoint; 0 when empty.
    fn quantile_ms(&self, counts: &[u64], total: u64, q: f64) -> f64 {
        if total == 0 {
            return 0.0;
        }
        let rank = ((q * total as f64).ceil() as u64).clamp(1, total);
        let mut seen = 0;
        for (i, c) in counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return value_of(i) / 1e6;
            }
        }
        self.max_ns.load(Relaxed) as f64 / 1e6
    }

    /// The percentiles so far (ms). A quantile is at most the exact maximum.
    pub(super) fn percentiles(&self) -> Percentiles {
        let counts: Vec<u64> = self.buckets.iter().map(|b| b.load(Relaxed)).collect();
        let total: u64 = counts.iter().sum();
        let max = self.max_ns.load(Relaxed) as f64 / 1e6;
        let q = |q| self.quantile_ms(&counts, total, q).min(max);
        Percentiles {
            count: total,
            mean: if total == 0 {
                0.0
            } else {
                self.sum_ns.load(Relaxed) as f64 / total as f64 / 1e6
            },
            p50: q(0.5),
            p90: q(0.9),
            p99: q(0.99),
            p999: q(0.999),
            max,
        }
    }
}

/// Wall-clock time as UNIX seconds (the time line of `time_unix`).
pub(super) fn now_unix() -> f64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// Resident memory (KiB) of process `pid` (`None`: this process), from `/proc/PID/status`.
pub(super) fn rss_kib(pid: Option<u32>) -> Option<u64> {
    let path = pid.map_or_else(
        || "/proc/self/status".to_string(),
        |p| format!("/proc/{p}/status"),
    );
    let text = std::fs::read_to_string(path).ok()?;
    text.lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))?
        .trim()
        .strip_suffix("kB")?
        .trim()
        .parse()
        .ok()
}

/// The machine the figures come from.
#[derive(Debug, Clone, Serialize)]
pub struct Machine {
    /// Logical CPUs available to this process.
    pub cpus: usize,
    /// `model name` of `/proc/cpuinfo`.
    pub cpu_model: String,
    /// `MemTotal` of `/proc/meminfo` (MiB).
    pub mem_total_mib: u64,
    /// 1-minute load average when the run started.
    pub load_start: f64,
    /// 1-minute load average when the run ended.
    pub load_end: f64,
}

impl Machine {
    /// What `/proc` says now (unknown values empty or 0).
    pub(super) fn now() -> Self {
        let read = |p: &str| std::fs::read_to_string(p).unwrap_or_default();
        let field = |text: &str, name: &str| {
            text.lines()
                .find_map(|l| l.strip_prefix(name))
                .and_then(|rest| rest.trim_start().strip_prefix(':'))
                .map(|v| v.trim().to_string())
        };
        let meminfo = read("/proc/meminfo");
        Self {
            cpus: std::thread::available_parallelism().map_or(0, usize::from),
            cpu_model: field(&read("/proc/cpuinfo"), "model name").unwrap_or_default(),
            mem_total_mib: field(&meminfo, "MemTotal")
                .and_then(|v| v.strip_suffix("kB").and_then(|k| k.trim().parse().ok()))
                .map_or(0, |k: u64| k / 1024),
            load_start: load_1m(),
            load_end: 0.0,
        }
    }
}

/// Clock ticks per second of `/proc/stat` and `/proc/PID/stat` (Linux's `USER_HZ`).
const USER_HZ: f64 = 100.0;

/// CPU time so far: the whole machine's busy time and some processes' own.
#[derive(Debug, Clone, Copy)]
pub(super) struct CpuSample {
    at: std::time::Instant,
    /// ns.
    machine_busy: u64,
    /// Ticks.
    processes: u64,
    /// Ticks of the other process alone (`pid`), if one.
    server: Option<u64>,
}

/// CPU time (ns) the whole machine has been busy: the root cgroup's precise usage (cgroup v1
/// `cpuacct.usage`, else v2 `cpu.stat`), else `/proc/stat` (tick-sampled: it misses much of a
/// load made of short bursts, like this tool's).
fn machine_busy_ns() -> Option<u64> {
    let read = |p: &str| std::fs::read_to_string(p).ok();
    if let Some(ns) =
        read("/sys/fs/cgroup/cpuacct/cpuacct.usage").and_then(|t| t.trim().parse().ok())
    {
        return Some(ns);
    }
    if let Some(us) = read("/sys/fs/cgroup/cpu.stat").and_then(|t| {
        t.lines()
            .find_map(|l| l.strip_prefix("usage_usec "))
            .and_then(|v| v.trim().parse::<u64>().ok())
    }) {
        return Some(us * 1000);
    }
    let text = read("/proc/stat")?;
    let line = text.lines().find(|l| l.starts_with("cpu "))?;
    let v: Vec<u64> = line
        .split_whitespace()
        .skip(1)
        .filter_map(|x| x.parse().ok())
        .collect();
    // user nice system idle iowait irq softirq steal (guest time is inside user).
    let ticks = v.iter().take(8).sum::<u64>() - v.get(3)? - v.get(4)?;
    Some((ticks as f64 * 1e9 / USER_HZ) as u64)
}

/// User + system ticks of process `pid` (`None`: this process).
fn process_ticks(pid: Option<u32>) -> Option<u64> {
    let path = pid.map_or_else(
        || "/proc/self/stat".to_string(),
        |p| format!("/proc/{p}/stat"),
    );
    let text = std::fs::read_to_string(path).ok()?;
    // Fields after the command name (which may hold spaces): state is field 3, utime 14.
    let rest = text.rsplit_once(')')?.1;
    let f: Vec<&str> = rest.split_whitespace().collect();
    Some(f.get(11)?.parse::<u64>().ok()? + f.get(12)?.parse::<u64>().ok()?)
}

/// Where the CPU went between two samples, in cores (1.0: one core busy all the time).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct CpuUse {
    /// The measured processes: this one, and the server's with `--server-pid`.
    pub measured_cores: f64,
    /// The whole machine.
    pub machine_cores: f64,
    /// Everything else on the machine: other processes (other users' work disturbs the
    /// figures) and kernel work not charged to a process.
    pub others_cores: f64,
    /// The server's process alone, when it is another process (`--server-process`,
    /// `--server-pid`).
    pub server_cores: Option<f64>,
}

impl CpuSample {
    /// Now, for this process and `pid` (if any); `None` without `/proc`.
    pub(super) fn now(pid: Option<u32>) -> Option<Self> {
        let mine = process_ticks(None)?;
        let theirs = match pid {
            Some(p) => Some(process_ticks(Some(p))?),
            None => None,
        };
        Some(Self {
            at: std::time::Instant::now(),
            machine_busy: machine_busy_ns()?,
            processes: mine + theirs.unwrap_or(0),
            server: theirs,
        })
    }

    /// The CPU used from `self` to `later`.
    pub(super) fn until(&self, later: &Self) -> CpuUse {
        let dt = (later.at - self.at).as_secs_f64().max(1e-9);
        let measured = later.processes.saturating_sub(self.processes) as f64 / USER_HZ / dt;
        let machine = later.machine_busy.saturating_sub(self.machine_busy) as f64 / 1e9 / dt;
        CpuUse {
            measured_cores: measured,
            machine_cores: machine,
            others_cores: (machine - measured).max(0.0),
            server_cores: self
                .server
                .zip(later.server)
                .map(|(a, b)| b.saturating_sub(a) as f64 / USER_HZ / dt),
        }
    }
}

/// The 1-minute load average (0 when unknown).
pub(super) fn load_1m() -> f64 {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|t| t.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0)
}

/// The server's counters of a set of vehicles, from `GET /api/v1/metrics`.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct Counters {
    /// Payloads received on the vehicles' keys.
    pub received: u64,
    /// Scans the track engine processed.
    pub ingested: u64,
    /// Detections in them.
    pub detections: u64,
    /// Drops by reason.
    pub dropped: BTreeMap<String, u64>,
    /// Scans missing from the `seq` sequences.
    pub seq_lost: u64,
    /// Scan messages slow WebSocket clients missed (over every client).
    pub ws_dropped: u64,
    /// Scan time of the last processed scan (UNIX s), if any.
    #[serde(skip)]
    pub last_scan_t: Option<f64>,
    /// The server's `harrier_scan_latency_seconds` histogram (payload arrival → scan processed,
    /// every vehicle): cumulative counts by upper bound (s), ascending.
    #[serde(skip)]
    pub latency_buckets: Vec<(f64, u64)>,
    /// Its sum (s).
    #[serde(skip)]
    pub latency_sum: f64,
    /// The MAVLink link and the guidance (`--mavlink`).
    pub mavlink: LinkCounters,
}

/// The server's counters of its MAVLink GCS link and its guidance loop.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LinkCounters {
    /// Frames the GCS link received (every vehicle: `harrier_mavlink_frames_received_total`).
    pub frames_received: u64,
    /// Frames of the vehicles missing from their MAVLink 2 sequence numbers.
    pub frames_lost: u64,
    /// Vehicles heard now (`harrier_vehicle_connected` 1).
    pub connected: u64,
    /// Vehicles marked lost (every vehicle, silent for `mavlink.lost_after_s`).
    pub link_lost: u64,
    /// Guidance loop iterations.
    pub guidance_ticks: u64,
    /// Velocity setpoints the guidance sent.
    pub setpoints: u64,
    /// How late the guidance ticks started: cumulative counts by upper bound (s), ascending.
    #[serde(skip)]
    pub tick_late_buckets: Vec<(f64, u64)>,
    /// The latest a tick started since the server started (s).
    pub tick_late_max_s: f64,
}

impl LinkCounters {
    /// Takes one sample line's figure if it is one of these (`ours`: the run's vehicles).
    fn take(&mut self, name: &str, labels: &BTreeMap<&str, &str>, value: f64, ours: bool) {
        let n = value as u64;
        match name {
            "harrier_mavlink_frames_received_total" => self.frames_received = n,
            "harrier_mavlink_vehicle_lost_total" => self.link_lost = n,
            "harrier_guidance_ticks_total" => self.guidance_ticks = n,
            "harrier_guidance_setpoints_total" => self.setpoints = n,
            "harrier_guidance_tick_late_max_seconds" => self.tick_late_max_s = value,
            "harrier_guidance_tick_late_seconds_bucket" => {
                if let Some(le) = labels.get("le").and_then(|b| b.parse::<f64>().ok()) {
                    self.tick_late_buckets.push((le, n));
                }
            }
            "harrier_vehicle_frames_lost_total" if ours => self.frames_lost += n,
            "harrier_vehicle_connected" if ours => self.connected += n,
            _ => {}
        }
    }

    fn since(&self, base: &Self) -> Self {
        Self {
            frames_received: self.frames_received.saturating_sub(base.frames_received),
            frames_lost: self.frames_lost.saturating_sub(base.frames_lost),
            connected: self.connected,
            link_lost: self.link_lost.saturating_sub(base.link_lost),
            guidance_ticks: self.guidance_ticks.saturating_sub(base.guidance_ticks),
            setpoints: self.setpoints.saturating_sub(base.setpoints),
            tick_late_buckets: buckets_since(&self.tick_late_buckets, &base.tick_late_buckets),
            tick_late_max_s: self.tick_late_max_s,
        }
    }

    /// The share of guidance ticks (since the base these counters were taken from) that
    /// started at most `le` s late, `le` one of the histogram's bounds; `None` without ticks.
    pub fn ticks_within(&self, le: f64) -> Option<f64> {
        let all = self
            .tick_late_buckets
            .iter()
            .find(|(b, _)| b.is_infinite())?
            .1;
        let within = self
            .tick_late_buckets
            .iter()
            .find(|(b, _)| (*b - le).abs() < 1e-12)?
            .1;
        (all > 0).then(|| within as f64 / all as f64)
    }
}

/// Cumulative histogram counts since `base` (bucket by bucket).
fn buckets_since(now: &[(f64, u64)], base: &[(f64, u64)]) -> Vec<(f64, u64)> {
    now.iter()
        .map(|&(le, n)| {
            let before = base.iter().find(|(b, _)| *b == le).map_or(0, |(_, m)| *m);
            (le, n.saturating_sub(before))
        })
        .collect()
}

/// The server's own latency (payload arrival → scan processed) over part of a run.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ServerLatency {
    /// Scans observed.
    pub count: u64,
    /// Mean (ms).
    pub mean_ms: f64,
    /// Upper bound (ms) of the histogram bucket holding the median (`None`: beyond the last).
    pub p50_le_ms: Option<f64>,
    /// The same for the 99th percentile.
    pub p99_le_ms: Option<f64>,
    /// The same for the 99.9th percentile.
    pub p999_le_ms: Option<f64>,
}

/// Splits a sample line into name, labels and value.
fn sample(line: &str) -> Option<(&str, BTreeMap<&str, &str>, f64)> {
    let (series, value) = line.rsplit_once(' ')?;
    let value = value.parse().ok()?;
    let (name, labels) = match series.split_once('{') {
        Some((name, rest)) => {
            let labels = rest
                .strip_suffix('}')?
                .split(',')
                .filter_map(|kv| {
                    let (k, v) = kv.split_once('=')?;
                    Some((k, v.trim_matches('"')))
                })
                .collect();
            (name, labels)
        }
        None => (series, BTreeMap::new()),
    };
    Some((name, labels, value))
}

impl Counters {
    /// The counters of the vehicles `ours` accepts in a Prometheus text exposition.
    pub(super) fn parse(text: &str, ours: &dyn Fn(&str) -> bool) -> Self {
        let mut c = Self::default();
        for line in text.lines().filter(|l| !l.starts_with('#')) {
            let Some((name, labels, value)) = sample(line) else {
                continue;
            };
            if name == "harrier_last_scan_time_seconds" {
                c.last_scan_t = Some(value);
                continue;
            }
            if name == "harrier_ws_dropped_total" {
                c.ws_dropped = value as u64;
                continue;
            }
            if name == "harrier_scan_latency_seconds_bucket" {
                if let Some(le) = labels.get("le").and_then(|b| b.parse::<f64>().ok()) {
                    c.latency_buckets.push((le, value as u64));
                }
                continue;
            }
            if name == "harrier_scan_latency_seconds_sum" {
                c.latency_sum = value;
                continue;
            }
            let mine = labels.get("vehicle").is_some_and(|v| ours(v));
            c.mavlink.take(name, &labels, value, mine);
            if !mine {
                continue;
            }
            let n = value as u64;
            match name {
                "harrier_payloads_received_total" => c.received += n,
                "harrier_scans_ingested_total" => c.ingested += n,
                "harrier_detections_total" => c.detections += n,
                "harrier_seq_lost_total" => c.seq_lost += n,
                "harrier_scans_dropped_total" => {
                    let reason = labels.get("reason").copied().unwrap_or("unknown");
                    *c.dropped.entry(reason.to_string()).or_default() += n;
                }
                _ => {}
            }
        }
        c
    }

    /// Payloads dropped for any reason.
    pub fn dropped_total(&self) -> u64 {
        self.dropped.values().sum()
    }

    /// What was counted since `base` (counters of an external server that ran before).
    pub(super) fn since(&self, base: &Self) -> Self {
        let mut dropped = self.dropped.clone();
        for (r, n) in &base.dropped {
            if let Some(v) = dropped.get_mut(r) {
                *v = v.saturating_sub(*n);
            }
        }
        dropped.retain(|_, n| *n > 0);
        Self {
            received: self.received.saturating_sub(base.received),
            ingested: self.ingested.saturating_sub(base.ingested),
            detections: self.detections.saturating_sub(base.detections),
            dropped,
            seq_lost: self.seq_lost.saturating_sub(base.seq_lost),
            ws_dropped: self.ws_dropped.saturating_sub(base.ws_dropped),
            last_scan_t: self.last_scan_t,
            latency_buckets: buckets_since(&self.latency_buckets, &base.latency_buckets),
            latency_sum: self.latency_sum - base.latency_sum,
            mavlink: self.mavlink.since(&base.mavlink),
        }
    }

    /// The server's latency histogram summarised (`None` when the server has none).
    pub(super) fn server_latency(&self) -> Option<ServerLatency> {
        let mut buckets = self.latency_buckets.clone();
        buckets.sort_by(|a, b| a.0.total_cmp(&b.0));
        let count = buckets.last()?.1;
        let le = |q: f64| {
            let rank = ((q * count as f64).ceil() as u64).max(1);
            buckets
                .iter()
                .find(|(_, n)| *n >= rank)
                .map(|(b, _)| b * 1e3)
                .filter(|b| b.is_finite())
        };
        Some(ServerLatency {
            count,
            mean_ms: if count == 0 {
                0.0
            } else {
                self.latency_sum / count as f64 * 1e3
            },
            p50_le_ms: le(0.5),
            p99_le_ms: le(0.99),
            p999_le_ms: le(0.999),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_round_trip_within_their_precision() {
        for ns in [0, 1, 127, 128, 129, 1_000, 123_456, 20_000_000, MAX_NS] {
            let v = value_of(bucket_of(ns));
            assert!(
                (v - ns as f64).abs() <= ns as f64 / SUB as f64 + 0.5,
                "{ns} → {v}"
            );
        }
        assert!(bucket_of(MAX_NS) < BUCKETS);
        let h = Histogram::default();
        for ms in 1..=1000 {
            h.record_s(f64::from(ms) * 1e-3);
        }
        let p = h.percentiles();
        assert_eq!(p.count, 1000);
        assert!((p.p50 - 500.0).abs() < 4.0, "{p:?}");
        assert!((p.p99 - 990.0).abs() < 8.0, "{p:?}");
        assert!((p.max - 1000.0).abs() < 1e-9, "{p:?}");
        assert!((p.mean - 500.5).abs() < 1e-6, "{p:?}");
    }

    #[test]
    fn counters_of_our_vehicles_are_summed() {
        let text = "# HELP x\n\
            harrier_payloads_received_total{vehicle=\"1\"} 10\n\
            harrier_payloads_received_total{vehicle=\"2\"} 5\n\
            harrier_payloads_received_total{vehicle=\"9\"} 99\n\
            harrier_scans_ingested_total{vehicle=\"1\"} 9\n\
            harrier_scans_dropped_total{vehicle=\"2\",reason=\"queue_full\"} 2\n\
            harrier_scans_dropped_total{vehicle=\"9\",reason=\"json\"} 7\n\
            harrier_seq_lost_total{vehicle=\"1\"} 1\n\
            harrier_last_scan_time_seconds 1795430412.25\n\
            harrier_ws_dropped_total 3\n\
            harrier_scan_latency_seconds_bucket{le=\"0.001\"} 90\n\
            harrier_scan_latency_seconds_bucket{le=\"0.01\"} 99\n\
            harrier_scan_latency_seconds_bucket{le=\"+Inf\"} 100\n\
            harrier_scan_latency_seconds_sum 0.25\n\
            harrier_mavlink_frames_received_total 400\n\
            harrier_vehicle_connected{vehicle=\"1\"} 1\n\
            harrier_vehicle_connected{vehicle=\"2\"} 0\n\
            harrier_vehicle_connected{vehicle=\"9\"} 1\n\
            harrier_vehicle_frames_lost_total{vehicle=\"2\"} 3\n\
            harrier_vehicle_frames_lost_total{vehicle=\"9\"} 5\n\
            harrier_guidance_tick_late_seconds_bucket{le=\"0.001\"} 80\n\
            harrier_guidance_tick_late_seconds_bucket{le=\"0.005\"} 99\n\
            harrier_guidance_tick_late_seconds_bucket{le=\"+Inf\"} 100\n\
            harrier_guidance_tick_late_max_seconds 0.0071\n";
        let c = Counters::parse(text, &|v| v == "1" || v == "2");
        assert_eq!((c.received, c.ingested, c.seq_lost), (15, 9, 1));
        assert_eq!(c.dropped_total(), 2);
        assert_eq!(c.last_scan_t, Some(1_795_430_412.25));
        assert_eq!(c.ws_dropped, 3);
        let d = c.since(&Counters {
            received: 5,
            dropped: BTreeMap::from([("queue_full".to_string(), 2)]),
            ..Counters::default()
        });
        assert_eq!((d.received, d.dropped_total()), (10, 0));
        let l = c.server_latency().expect("latency histogram");
        assert_eq!(
            (l.count, l.p50_le_ms, l.p99_le_ms),
            (100, Some(1.0), Some(10.0))
        );
        assert_eq!(l.p999_le_ms, None);
        assert!((l.mean_ms - 2.5).abs() < 1e-9, "{l:?}");
        let m = &c.mavlink;
        assert_eq!((m.frames_received, m.connected, m.frames_lost), (400, 1, 3));
        assert_eq!(m.ticks_within(0.005), Some(0.99));
        assert_eq!(m.tick_late_max_s, 0.0071);
        let mut base = c.clone();
        base.mavlink.tick_late_buckets = vec![(0.001, 40), (0.005, 49), (f64::INFINITY, 50)];
        base.mavlink.frames_received = 100;
        let d = c.since(&base).mavlink;
        assert_eq!((d.frames_received, d.ticks_within(0.001)), (300, Some(0.8)));
    }
}
