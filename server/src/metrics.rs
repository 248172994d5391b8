//! The live service's counters, shared by the actors and rendered in the Prometheus text format
//! for `GET /api/v1/metrics`.
//!
//! Vehicle labels come from the Zenoh key (`harrier/v1/vehicle/{id}/detections`); anything that is
//! not a MAVLink system id 1–255 is counted under `other`, so a sender cannot grow the label set
//! without bound.

use std::collections::BTreeMap;
use std::sync::{Mutex, PoisonError};

use super::clock::ClockEstimate;
use crate::prom::{Family, Histogram};
use harrier_recording::writer::RecorderStats;

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
    /// Scans older than the last processed one, within the lag, that the engine took by
    /// retrodiction.
    pub retrodicted: u64,
    /// Its clock, as estimated from its scans' `time_unix` and arrival times.
    pub clock: Option<ClockEstimate>,
}

/// Every counter of the service.
#[derive(Debug, Default)]
pub struct Metrics {
    inner: Mutex<Inner>,
}

#[derive(Debug)]
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

impl Default for Inner {
    fn default() -> Self {
        Self {
            vehicles: BTreeMap::new(),
            tracks_confirmed: 0,
            ws_clients: 0,
            bound_resets: 0,
            latency: Histogram::new(&LATENCY_BUCKETS),
            ws_sent: 0,
            ws_dropped: 0,
            http_refused: BTreeMap::new(),
            truth_refused: BTreeMap::new(),
            tracks_tentative: 0,
            last_scan_t: None,
        }
    }
}

/// Upper bounds (s) of the latency histogram's buckets.
const LATENCY_BUCKETS: [f64; 12] = [
    0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 5.0,
];

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

    /// A scan of `vehicle` came late (within the lag) and was retrodicted.
    pub fn retrodicted(&self, vehicle: &str) {
        self.vehicle(vehicle, |v| v.retrodicted += 1);
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
            i.render_vehicles(&mut out);
            i.render_service(&mut out);
            i.latency.render(
                &mut out,
                "harrier_scan_latency_seconds",
                "From a payload's arrival to its scan processed by the track engine.",
            );
            Family::gauge(
                &mut out,
                "harrier_uptime_seconds",
                "Seconds since the service started.",
            )
            .value(format_args!("{uptime_s:.3}"));
            out
        })
    }
}

impl Inner {
    /// The counters per vehicle, their drops and clocks, and the refused truth samples.
    fn render_vehicles(&self, out: &mut String) {
        let per = |out: &mut String, name, help, f: &dyn Fn(&VehicleCounters) -> u64| {
            let mut family = Family::counter(out, name, help);
            for (id, v) in &self.vehicles {
                family.sample(&[("vehicle", id)], f(v));
            }
        };
        per(
            out,
            "harrier_payloads_received_total",
            "Detection payloads received per vehicle key.",
            &|v| v.received,
        );
        per(
            out,
            "harrier_scans_ingested_total",
            "Scans processed by the track engine.",
            &|v| v.ingested,
        );
        per(
            out,
            "harrier_detections_total",
            "Detections in the processed scans.",
            &|v| v.detections,
        );
        let mut drops = Family::counter(
            out,
            "harrier_scans_dropped_total",
            "Payloads and scans dropped, by reason.",
        );
        for (id, v) in &self.vehicles {
            for (r, n) in &v.dropped {
                drops.sample(&[("vehicle", id), ("reason", &r.as_str())], n);
            }
        }
        per(
            out,
            "harrier_scans_late_total",
            "Scans older than the last processed scan (dropped).",
            &|v| v.dropped.get(&DropReason::Late).copied().unwrap_or(0),
        );
        let clock = |out: &mut String, name, help, f: &dyn Fn(&ClockEstimate) -> f64| {
            let mut family = Family::gauge(out, name, help);
            for (id, v) in &self.vehicles {
                if let Some(c) = &v.clock {
                    family.sample(&[("vehicle", id)], f(c));
                }
            }
        };
        clock(
            out,
            "harrier_clock_offset_seconds",
            "Each vehicle's clock minus the server's, estimated from its scans.",
            &|c| c.offset_s,
        );
        clock(
            out,
            "harrier_clock_offset_sigma_seconds",
            "Standard uncertainty of harrier_clock_offset_seconds.",
            &|c| c.sigma_s,
        );
        clock(
            out,
            "harrier_clock_drift_ppm",
            "How fast each vehicle's clock offset grows (µs per s).",
            &|c| c.drift_ppm,
        );
        let mut truth = Family::counter(
            out,
            "harrier_truth_refused_total",
            "Truth samples not used, by reason (invalid, clock).",
        );
        for (r, n) in &self.truth_refused {
            truth.sample(&[("reason", r)], n);
        }
        per(
            out,
            "harrier_seq_lost_total",
            "Scans missing from the per-sensor seq sequences.",
            &|v| v.seq_lost,
        );
        per(
            out,
            "harrier_scans_retrodicted_total",
            "Scans older than the last processed one (within tracker.late_lag_s) taken by \
             retrodiction.",
            &|v| v.retrodicted,
        );
    }

    /// The tracks, the set-membership bounds, the WebSocket clients and the refused requests.
    fn render_service(&self, out: &mut String) {
        Family::gauge(out, "harrier_tracks", "Live tracks by status.")
            .sample(&[("status", &"confirmed")], self.tracks_confirmed)
            .sample(&[("status", &"tentative")], self.tracks_tentative);
        if let Some(t) = self.last_scan_t {
            Family::gauge(
                out,
                "harrier_last_scan_time_seconds",
                "Scan time of the last processed scan.",
            )
            .value(t);
        }
        Family::counter(
            out,
            "harrier_bound_resets_total",
            "Set-membership bounds found inconsistent with a detection and restarted from it.",
        )
        .value(self.bound_resets);
        Family::gauge(out, "harrier_ws_clients", "WebSocket clients connected.")
            .value(self.ws_clients);
        Family::counter(
            out,
            "harrier_ws_messages_sent_total",
            "Scan messages sent to WebSocket clients.",
        )
        .value(self.ws_sent);
        Family::counter(
            out,
            "harrier_ws_dropped_total",
            "Scan messages slow WebSocket clients missed (each got a snapshot instead).",
        )
        .value(self.ws_dropped);
        let mut refused = Family::counter(
            out,
            "harrier_http_refused_total",
            "API requests refused, by reason and status.",
        );
        for ((r, status), n) in &self.http_refused {
            refused.sample(&[("reason", r), ("status", status)], n);
        }
    }
}

/// Appends the recorder's counters ([`RecorderStats`]) in the Prometheus text format.
pub fn render_recorder(stats: &RecorderStats, out: &mut String) {
    Family::counter(
        out,
        "harrier_recorder_rows_total",
        "Rows committed to the session file, by table.",
    )
    .sample(&[("table", &"scans")], stats.scans)
    .sample(&[("table", &"detections")], stats.detections)
    .sample(&[("table", &"tracks")], stats.track_rows)
    .sample(&[("table", &"truth")], stats.truth_rows)
    .sample(&[("table", &"actions")], stats.actions)
    .sample(&[("table", &"vehicle_log")], stats.vehicle_rows)
    .sample(&[("table", &"biases")], stats.bias_rows);
    Family::counter(
        out,
        "harrier_recorder_dropped_total",
        "Records dropped because the writer's queue was full.",
    )
    .value(stats.dropped);
    Family::counter(
        out,
        "harrier_recorder_errors_total",
        "Failed writes to the session file.",
    )
    .value(stats.errors);
    Family::counter(
        out,
        "harrier_recorder_commits_total",
        "Transactions committed.",
    )
    .value(stats.commits);
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
