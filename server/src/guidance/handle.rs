//! The guidance loop as the rest of the service holds it: the handle ([`Guidance`]), the requests
//! it sends the actor, why an assignment is refused ([`AssignError`]) and the loop's counters.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::{broadcast, mpsc, oneshot, watch};

use super::plan::{AssignmentRequest, AssignmentView};
use crate::prom::{Family, Histogram};

/// Why an assignment request was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum AssignError {
    /// A parameter is out of range.
    #[error("{0}")]
    Invalid(String),
    /// The vehicle or the track does not exist.
    #[error("{0}")]
    NotFound(String),
    /// A vehicle already flies another assignment.
    #[error("{0}")]
    Conflict(String),
    /// The guidance loop is not running.
    #[error("the guidance loop is not running")]
    Stopped,
}

/// A request to the guidance actor.
#[derive(Debug)]
pub enum GuidanceRequest {
    /// Create an assignment.
    Create(
        AssignmentRequest,
        oneshot::Sender<Result<AssignmentView, AssignError>>,
    ),
    /// End one.
    End(u64, oneshot::Sender<Option<AssignmentView>>),
}

/// Counters of the loop.
#[derive(Debug)]
pub struct GuidanceMetrics {
    /// Ticks run.
    pub(super) ticks: AtomicU64,
    /// Setpoints sent.
    pub(super) setpoints: AtomicU64,
    /// How late each tick started (s), over [`LATE_BOUNDS_S`].
    late: Mutex<Histogram>,
    /// The latest a tick started (µs).
    max_late_us: AtomicU64,
    /// Assignments created.
    pub(super) created: AtomicU64,
    /// Assignments ended.
    pub(super) ended: AtomicU64,
}

/// Upper bounds (s) of the tick lateness histogram's buckets.
const LATE_BOUNDS_S: [f64; 5] = [0.0001, 0.0005, 0.001, 0.005, 0.02];

impl Default for GuidanceMetrics {
    fn default() -> Self {
        Self {
            ticks: AtomicU64::new(0),
            setpoints: AtomicU64::new(0),
            late: Mutex::new(Histogram::new(&LATE_BOUNDS_S)),
            max_late_us: AtomicU64::new(0),
            created: AtomicU64::new(0),
            ended: AtomicU64::new(0),
        }
    }
}

impl GuidanceMetrics {
    /// Appends the Prometheus text (`active`: the assignments active now).
    pub fn render(&self, active: usize, out: &mut String) {
        let v = |a: &AtomicU64| a.load(Ordering::Relaxed);
        Family::counter(
            out,
            "harrier_guidance_ticks_total",
            "Guidance loop iterations.",
        )
        .value(v(&self.ticks));
        Family::counter(
            out,
            "harrier_guidance_setpoints_total",
            "Velocity setpoints sent.",
        )
        .value(v(&self.setpoints));
        Family::gauge(
            out,
            "harrier_guidance_assignments",
            "Assignments: active now; created and ended since start.",
        )
        .sample(&[("state", &"active")], active)
        .sample(&[("state", &"created")], v(&self.created))
        .sample(&[("state", &"ended")], v(&self.ended));
        self.late
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .render(
                out,
                "harrier_guidance_tick_late_seconds",
                "How late each tick started against its schedule (jitter).",
            );
        Family::gauge(
            out,
            "harrier_guidance_tick_late_max_seconds",
            "Latest tick start seen.",
        )
        .value(v(&self.max_late_us) as f64 / 1e6);
    }

    /// A tick started `us` µs after its schedule.
    pub(super) fn late(&self, us: u64) {
        self.late
            .lock()
            .unwrap_or_else(PoisonError::into_inner)
            .observe(us as f64 / 1e6);
        self.max_late_us.fetch_max(us, Ordering::Relaxed);
    }
}

/// The guidance loop as the API uses it.
#[derive(Debug, Clone)]
pub struct Guidance {
    /// Requests to the actor.
    pub requests: mpsc::Sender<GuidanceRequest>,
    /// Every assignment (active and ended), updated each tick.
    pub assignments: watch::Receiver<Arc<Vec<AssignmentView>>>,
    /// Each created, changed (a vehicle's state) and ended assignment.
    pub events: broadcast::Sender<AssignmentView>,
    /// Counters.
    pub metrics: Arc<GuidanceMetrics>,
}

impl Guidance {
    /// Creates an assignment.
    pub async fn create(&self, r: AssignmentRequest) -> Result<AssignmentView, AssignError> {
        let (tx, rx) = oneshot::channel();
        self.requests
            .send(GuidanceRequest::Create(r, tx))
            .await
            .map_err(|_| AssignError::Stopped)?;
        rx.await.map_err(|_| AssignError::Stopped)?
    }

    /// Ends an assignment; `None` when there is no such id.
    pub async fn end(&self, id: u64) -> Result<Option<AssignmentView>, AssignError> {
        let (tx, rx) = oneshot::channel();
        self.requests
            .send(GuidanceRequest::End(id, tx))
            .await
            .map_err(|_| AssignError::Stopped)?;
        rx.await.map_err(|_| AssignError::Stopped)
    }
}
