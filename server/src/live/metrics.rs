//! The live service's counters, shared by the actors and rendered in the Prometheus text format
//! for `GET /api/v1/metrics`.
//!
//! Vehicle labels come from the Zenoh key (`harrier/v1/vehicle/{id}/detections`); anything that is
//! not a MAVLink system id 1–255 is counted under `other`, so a sender cannot grow the label set
//! without bound.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::sync::{Mutex, PoisonError};

use super::clock::ClockEstimate;

/// Why a payload or scan was dropped (the `reason` label).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum DropReason {
    /// Not JSON, or not a `DetectionScan` object.
    Json,
    /// A `DetectionScan` that fails validation (schema, non-finite numbers, lengths, ranges).
    Invalid,
    /// The key's vehicle id differs from the payload's `vehicle`.
    KeyMismatch,
    /// Cannot be expressed in the server's frame, or has no usable sensor model.
    Frame,
    /// The ingest queue was full (the tracker is behind).
    QueueFull,
    /// The track engine refused the scan.
    Rejected,
    /// Older than the last processed scan (arrived after the reorder window).
    Late,
    /// From a sensor not in `tracker.sensors`.
    SensorFiltered,
    /// Its `time_unix` is outside the bound around the server's clock (`[clock]`).
    Clock,
}

impl DropReason {
    /// The label value.
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Json => "json",
            Self::Invalid => "invalid",
            Self::KeyMismatch => "key_mismatch",
            Self::Frame => "frame",
            Self::QueueFull => "queue_full",
            Self::Rejected => "rejected",
            Self::Late => "late",
            Self::SensorFiltered => "sensor_filtered",
            Self::Clock => "clock",
        }
    }
}

/// Counters of one vehicle.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct VehicleCounters {
    /// Payloads received on its key.
    pub received: u64,
    /// Scans the track engine ingested.
    pub ingested: u64,
    /// Detections in those scans.
    pub detections: u64,
    /// Drops by reason.
    pub dropped: BTreeMap<DropReason, u64>,
    /// Scans missing from the `seq` sequences of its sensors.
    pub seq_lost: u64,
    /// Its clock, as estimated from its scans' `time_unix` and arrival times.
    pub clock: Option<ClockEstimate>,
}

/// Every counter of the service.
#[derive(Debug, Default)]
pub struct Metrics {
    inner: Mutex<Inner>,
}

#[derive(Debug, Default)]
struct Inner {
    vehicles: BTreeMap<String, VehicleCounters>,
    tracks_confirmed: usize,
    ws_clients: i64,
    bound_resets: u64,
    latency: Histogram,
    ws_sent: u64,
    ws_dropped: u64,
    http_refused: BTreeMap<(&'static str, u16), u64>,
    truth_refused: BTreeMap<&'static str, u64>,
    tracks_tentative: usize,
    last_scan_t: Option<f64>,
}

/// Upper bounds (s) of the latency histogram's buckets.
const LATENCY_BUCKETS: [f64; 12] = [
    0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 5.0,
];

/// A Prometheus histogram over [`LATENCY_BUCKETS`].
#[derive(Debug, Default)]
struct Histogram {
    counts: [u64; LATENCY_BUCKETS.len()],
    count: u64,
    sum: f64,
}

impl Histogram {
    fn observe(&mut self, v: f64) {
        if let Some(i) = LATENCY_BUCKETS.iter().position(|&b| v <= b) {
            self.counts[i] += 1;
        }
        self.count += 1;
        self.sum += v;
    }

    /// `name_bucket{le=…}` (cumulative), `name_sum`, `name_count`.
    fn render(&self, out: &mut String, name: &str, help: &str) {
        let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} histogram");
        let mut cumulative = 0;
        for (b, n) in LATENCY_BUCKETS.iter().zip(self.counts) {
            cumulative += n;
            let _ = writeln!(out, "{name}_bucket{{le=\"{b}\"}} {cumulative}");
        }
        let _ = writeln!(out, "{name}_bucket{{le=\"+Inf\"}} {}", self.count);
        let _ = writeln!(out, "{name}_sum {}", self.sum);
        let _ = writeln!(out, "{name}_count {}", self.count);
    }
}

/// The label of a key's vehicle segment.
pub fn vehicle_label(segment: &str) -> String {
    match segment.parse::<u8>() {
        Ok(id) if id >= 1 && segment == id.to_string() => segment.to_string(),
        _ => "other".to_string(),
    }
}

impl Metrics {
    fn with<R>(&self, f: impl FnOnce(&mut Inner) -> R) -> R {
        f(&mut self.inner.lock().unwrap_or_else(PoisonError::into_inner))
    }

    fn vehicle<R>(&self, vehicle: &str, f: impl FnOnce(&mut VehicleCounters) -> R) -> R {
        self.with(|i| f(i.vehicles.entry(vehicle.to_string()).or_default()))
    }

    /// A truth sample not used (`reason`: `invalid`, `clock`).
    pub fn truth_refused(&self, reason: &'static str) {
        self.with(|i| *i.truth_refused.entry(reason).or_default() += 1);
    }

    /// The estimate of `vehicle`'s clock.
    pub fn clock(&self, vehicle: &str, estimate: ClockEstimate) {
        self.vehicle(vehicle, |v| v.clock = Some(estimate));
    }

    /// The estimate of every vehicle's clock that has one, by vehicle label.
    pub fn clocks(&self) -> BTreeMap<String, ClockEstimate> {
        self.with(|i| {
            i.vehicles
                .iter()
                .filter_map(|(id, v)| Some((id.clone(), v.clock?)))
                .collect()
        })
    }

    /// A payload arrived on `vehicle`'s key.
    pub fn received(&self, vehicle: &str) {
        self.vehicle(vehicle, |v| v.received += 1);
    }

    /// A payload or scan of `vehicle` was dropped.
    pub fn dropped(&self, vehicle: &str, reason: DropReason) {
        self.vehicle(vehicle, |v| *v.dropped.entry(reason).or_default() += 1);
    }

    /// `n` scans of `vehicle` are missing from a `seq` sequence.
    pub fn seq_lost(&self, vehicle: &str, n: u64) {
        self.vehicle(vehicle, |v| v.seq_lost += n);
    }

    /// The track engine ingested a scan of `vehicle` with `detections` detections at `t`; the
    /// engine now holds these tracks.
    pub fn ingested(&self, vehicle: &str, detections: usize, t: f64, confirmed: usize, all: usize) {
        self.with(|i| {
            let v = i.vehicles.entry(vehicle.to_string()).or_default();
            v.ingested += 1;
            v.detections += detections as u64;
            i.last_scan_t = Some(t);
            i.tracks_confirmed = confirmed;
            i.tracks_tentative = all - confirmed;
        });
    }

    /// A scan was processed `seconds` after its payload arrived (decoding, the reorder buffer
    /// and the track engine).
    pub fn latency(&self, seconds: f64) {
        self.with(|i| i.latency.observe(seconds));
    }

    /// The set-membership bounds have restarted `total` times so far.
    pub fn bound_resets(&self, total: u64) {
        self.with(|i| i.bound_resets = total);
    }

    /// WebSocket clients connected (`+1`) or gone (`-1`).
    pub fn ws_clients(&self, delta: i64) {
        self.with(|i| i.ws_clients += delta);
    }

    /// Scan messages sent to WebSocket clients.
    pub fn ws_sent(&self, n: u64) {
        self.with(|i| i.ws_sent += n);
    }

    /// Scan messages a slow WebSocket client missed (it got a snapshot instead).
    pub fn ws_dropped(&self, n: u64) {
        self.with(|i| i.ws_dropped += n);
    }

    /// An API request refused with `status` (`reason`: `json`, `auth`, `not_found`, …).
    pub fn http_refused(&self, reason: &'static str, status: u16) {
        self.with(|i| *i.http_refused.entry((reason, status)).or_default() += 1);
    }

    /// The counters of `vehicle` (a label).
    pub fn vehicle_counters(&self, vehicle: &str) -> VehicleCounters {
        self.with(|i| i.vehicles.get(vehicle).cloned().unwrap_or_default())
    }

    /// Time of the last scan the track engine ingested.
    pub fn last_scan_t(&self) -> Option<f64> {
        self.with(|i| i.last_scan_t)
    }

    /// Scans ingested over every vehicle.
    pub fn scans_ingested(&self) -> u64 {
        self.with(|i| i.vehicles.values().map(|v| v.ingested).sum())
    }

    /// The Prometheus text exposition (format 0.0.4).
    pub fn render(&self, uptime_s: f64) -> String {
        self.with(|i| {
            let mut out = String::new();
            let mut family = |name: &str, kind: &str, help: &str, rows: Vec<(String, String)>| {
                let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}");
                for (labels, value) in rows {
                    let _ = writeln!(out, "{name}{labels} {value}");
                }
            };
            let per = |f: &dyn Fn(&VehicleCounters) -> u64| {
                i.vehicles
                    .iter()
                    .map(|(id, v)| (format!("{{vehicle=\"{id}\"}}"), f(v).to_string()))
                    .collect::<Vec<_>>()
            };
            family(
                "harrier_payloads_received_total",
                "counter",
                "Detection payloads received per vehicle key.",
                per(&|v| v.received),
            );
            family(
                "harrier_scans_ingested_total",
                "counter",
                "Scans processed by the track engine.",
                per(&|v| v.ingested),
            );
            family(
                "harrier_detections_total",
                "counter",
                "Detections in the processed scans.",
                per(&|v| v.detections),
            );
            let drops = i
                .vehicles
                .iter()
                .flat_map(|(id, v)| {
                    v.dropped.iter().map(move |(r, n)| {
                        (
                            format!("{{vehicle=\"{id}\",reason=\"{}\"}}", r.as_str()),
                            n.to_string(),
                        )
                    })
                })
                .collect();
            family(
                "harrier_scans_dropped_total",
                "counter",
                "Payloads and scans dropped, by reason.",
                drops,
            );
            family(
                "harrier_scans_late_total",
                "counter",
                "Scans older than the last processed scan (dropped).",
                per(&|v| v.dropped.get(&DropReason::Late).copied().unwrap_or(0)),
            );
            let clocks: Vec<_> = i
                .vehicles
                .iter()
                .filter_map(|(id, v)| Some((id, v.clock?)))
                .collect();
            let clock = |f: &dyn Fn(&ClockEstimate) -> f64| {
                clocks
                    .iter()
                    .map(|(id, c)| (format!("{{vehicle=\"{id}\"}}"), f(c).to_string()))
                    .collect::<Vec<_>>()
            };
            family(
                "harrier_clock_offset_seconds",
                "gauge",
                "Each vehicle's clock minus the server's, estimated from its scans.",
                clock(&|c| c.offset_s),
            );
            family(
                "harrier_clock_offset_sigma_seconds",
                "gauge",
                "Standard uncertainty of harrier_clock_offset_seconds.",
                clock(&|c| c.sigma_s),
            );
            family(
                "harrier_clock_drift_ppm",
                "gauge",
                "How fast each vehicle's clock offset grows (µs per s).",
                clock(&|c| c.drift_ppm),
            );
            family(
                "harrier_truth_refused_total",
                "counter",
                "Truth samples not used, by reason (invalid, clock).",
                i.truth_refused
                    .iter()
                    .map(|(r, n)| (format!("{{reason=\"{r}\"}}"), n.to_string()))
                    .collect(),
            );
            family(
                "harrier_seq_lost_total",
                "counter",
                "Scans missing from the per-sensor seq sequences.",
                per(&|v| v.seq_lost),
            );
            family(
                "harrier_tracks",
                "gauge",
                "Live tracks by status.",
                vec![
                    (
                        "{status=\"confirmed\"}".into(),
                        i.tracks_confirmed.to_string(),
                    ),
                    (
                        "{status=\"tentative\"}".into(),
                        i.tracks_tentative.to_string(),
                    ),
                ],
            );
            if let Some(t) = i.last_scan_t {
                family(
                    "harrier_last_scan_time_seconds",
                    "gauge",
                    "Scan time of the last processed scan.",
                    vec![(String::new(), t.to_string())],
                );
            }
            family(
                "harrier_bound_resets_total",
                "counter",
                "Set-membership bounds found inconsistent with a detection and restarted from it.",
                vec![(String::new(), i.bound_resets.to_string())],
            );
            family(
                "harrier_ws_clients",
                "gauge",
                "WebSocket clients connected.",
                vec![(String::new(), i.ws_clients.to_string())],
            );
            family(
                "harrier_ws_messages_sent_total",
                "counter",
                "Scan messages sent to WebSocket clients.",
                vec![(String::new(), i.ws_sent.to_string())],
            );
            family(
                "harrier_ws_dropped_total",
                "counter",
                "Scan messages slow WebSocket clients missed (each got a snapshot instead).",
                vec![(String::new(), i.ws_dropped.to_string())],
            );
            family(
                "harrier_http_refused_total",
                "counter",
                "API requests refused, by reason and status.",
                i.http_refused
                    .iter()
                    .map(|((r, st), n)| {
                        (format!("{{reason=\"{r}\",status=\"{st}\"}}"), n.to_string())
                    })
                    .collect(),
            );
            i.latency.render(
                &mut out,
                "harrier_scan_latency_seconds",
                "From a payload's arrival to its scan processed by the track engine.",
            );
            let mut family = |name: &str, kind: &str, help: &str, rows: Vec<(String, String)>| {
                let _ = writeln!(out, "# HELP {name} {help}\n# TYPE {name} {kind}");
                for (labels, value) in rows {
                    let _ = writeln!(out, "{name}{labels} {value}");
                }
            };
            family(
                "harrier_uptime_seconds",
                "gauge",
                "Seconds since the service started.",
                vec![(String::new(), format!("{uptime_s:.3}"))],
            );
            out
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn labels_are_bounded_and_rendered() {
        assert_eq!(vehicle_label("7"), "7");
        for bad in ["0", "256", "07", "x", ""] {
            assert_eq!(vehicle_label(bad), "other", "{bad}");
        }
        let m = Metrics::default();
        m.received("9");
        m.dropped("9", DropReason::Json);
        m.dropped("1", DropReason::Late);
        m.seq_lost("1", 3);
        m.ingested("1", 2, 4.5, 1, 3);
        m.latency(0.003);
        m.latency(0.03);
        let text = m.render(1.0);
        for line in [
            "harrier_scans_dropped_total{vehicle=\"9\",reason=\"json\"} 1",
            "harrier_scans_late_total{vehicle=\"1\"} 1",
            "harrier_seq_lost_total{vehicle=\"1\"} 3",
            "harrier_detections_total{vehicle=\"1\"} 2",
            "harrier_tracks{status=\"tentative\"} 2",
            "harrier_last_scan_time_seconds 4.5",
            "harrier_scan_latency_seconds_bucket{le=\"0.002\"} 0",
            "harrier_scan_latency_seconds_bucket{le=\"0.005\"} 1",
            "harrier_scan_latency_seconds_bucket{le=\"0.05\"} 2",
            "harrier_scan_latency_seconds_bucket{le=\"+Inf\"} 2",
            "harrier_scan_latency_seconds_count 2",
        ] {
            assert!(text.lines().any(|l| l == line), "{line} missing in\n{text}");
        }
    }
}
