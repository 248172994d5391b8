//! What the phases of a run measured ([`Steady`] and its [`Progress`] samples, [`Drained`]), which
//! the report turns into figures.

use tokio::time::Instant;

use super::rest::RestReport;
use super::stats::{Counters, CpuSample, CpuUse};
use super::ws::WsReport;

/// What the steady state measured.
pub(super) struct Steady {
    /// The counters at its start.
    pub(super) c0: Counters,
    /// Scans published at its start.
    pub(super) published0: u64,
    /// Its last progress sample: its end.
    pub(super) last: Progress,
    /// Its length (s).
    pub(super) seconds: f64,
    /// Largest tracker lag at a progress sample (s).
    pub(super) max_lag_s: f64,
    pub(super) rss_start: Option<u64>,
    pub(super) rss_end: Option<u64>,
    pub(super) cpu: Option<CpuUse>,
    /// Bytes the WebSocket clients received in it: all, and the `vehicles` messages.
    pub(super) ws_bytes: (u64, u64),
}

/// One progress sample of the steady state.
#[derive(Clone)]
pub(super) struct Progress {
    /// When.
    pub(super) at: Instant,
    /// The server's counters.
    pub(super) counters: Counters,
    /// Scans published so far.
    pub(super) published: u64,
    /// Scans the WebSocket clients received.
    pub(super) ws_scans: u64,
    /// REST requests answered 200.
    pub(super) rest_ok: u64,
    /// Bytes the WebSocket clients received: all, and the `vehicles` messages.
    pub(super) ws_bytes: (u64, u64),
    /// CPU time so far.
    pub(super) cpu: Option<CpuSample>,
}

/// What the run published, and what the server and the clients made of it once drained.
pub(super) struct Drained {
    /// Scans published (`put` accepted), and failed `put`s.
    pub(super) published: u64,
    pub(super) failed: u64,
    /// How long the publishers ran (s).
    pub(super) publish_s: f64,
    /// The counters since the run started.
    pub(super) totals: Counters,
    /// Whether the server processed or dropped everything it received in time.
    pub(super) drained: bool,
    pub(super) websocket: Option<WsReport>,
    pub(super) rest: Option<RestReport>,
    /// The vehicles' MAVLink (`--mavlink`).
    pub(super) link: Option<LinkOutcome>,
}

/// What the vehicles' MAVLink side ended with.
pub(super) struct LinkOutcome {
    /// Frames the vehicles sent in all.
    pub(super) frames_sent: u64,
    /// Vehicles that heard the ground station's HEARTBEAT.
    pub(super) hearing_gcs: usize,
    /// Seconds until the server heard every vehicle.
    pub(super) connect_s: Option<f64>,
    /// The assignments' vehicles by slot state at the end (`orbiting`, `taking_off`, …).
    pub(super) slots: std::collections::BTreeMap<String, usize>,
    /// Assignments made.
    pub(super) assignments: usize,
}
