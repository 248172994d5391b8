//! The guidance loop as the rest of the service holds it: the handle ([`Guidance`]), the requests
//! it sends the actor, why an assignment is refused ([`AssignError`]) and the loop's counters.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use tokio::sync::{broadcast, mpsc, oneshot, watch};

use super::plan::{AssignmentRequest, AssignmentView, OverrideSource};
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
    /// Take a vehicle out of its slot before an operator's command (`String`: what, for the
    /// slot's `overridden`); the answer names the assignment it flew, if any.
    Release(u8, String, oneshot::Sender<Option<u64>>),
    /// The operator takes a vehicle back into its slot of an assignment.
    Resume(
        u64,
        u8,
        oneshot::Sender<Result<AssignmentView, AssignError>>,
    ),
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
    /// Vehicles taken out of their slots by someone else, by [`OverrideSource`] (api, router
    /// client, vehicle).
    overrides: [AtomicU64; 3],
    /// Vehicles the operator took back into their slots.
    pub(super) resumed: AtomicU64,
    /// Setpoints the safety envelope clipped.
    clipped: AtomicU64,
    /// Vehicles the safety envelope found outside the fence (sent to Hold).
    fenced_out: AtomicU64,
    /// Vehicles the safety envelope sent home for their battery.
    pub(super) battery_rtl: AtomicU64,
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
            overrides: Default::default(),
            resumed: AtomicU64::new(0),
            clipped: AtomicU64::new(0),
            fenced_out: AtomicU64::new(0),
            battery_rtl: AtomicU64::new(0),
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
        let mut overrides = Family::counter(
            out,
            "harrier_guidance_overrides_total",
            "Vehicles taken out of their assignment slots by someone else, by who: api (an operator's command), router_client, vehicle (RC switch, failsafe, landing).",
        );
        for (by, n) in OverrideSource::ALL.iter().zip(&self.overrides) {
            overrides.sample(&[("by", &by.as_str())], v(n));
        }
        Family::counter(
            out,
            "harrier_guidance_resumed_total",
            "Vehicles the operator took back into their assignment slots.",
        )
        .value(v(&self.resumed));
        Family::counter(
            out,
            "harrier_guidance_safety_total",
            "The safety envelope's actions ([guidance.safety]): setpoints clipped to the geofence, vehicles found outside it (out of their slots, sent to Hold), vehicles below the battery floor (out, sent home).",
        )
        .sample(&[("action", &"clipped")], v(&self.clipped))
        .sample(&[("action", &"outside_hold")], v(&self.fenced_out))
        .sample(&[("action", &"battery_rtl")], v(&self.battery_rtl));
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

    /// A tick's safety actions: setpoints clipped, vehicles found outside.
    pub(super) fn safety(&self, clipped: u64, fenced_out: u64) {
        self.clipped.fetch_add(clipped, Ordering::Relaxed);
        self.fenced_out.fetch_add(fenced_out, Ordering::Relaxed);
    }

    /// A vehicle was taken out of its slot by `by`.
    pub(super) fn overridden(&self, by: OverrideSource) {
        self.overrides[by as usize].fetch_add(1, Ordering::Relaxed);
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

    /// Takes vehicle `vehicle` out of its slot before an operator's command (`what`, e.g.
    /// `hold through the API`): the assignment it flew, if any.
    pub async fn release(&self, vehicle: u8, what: String) -> Result<Option<u64>, AssignError> {
        let (tx, rx) = oneshot::channel();
        self.requests
            .send(GuidanceRequest::Release(vehicle, what, tx))
            .await
            .map_err(|_| AssignError::Stopped)?;
        rx.await.map_err(|_| AssignError::Stopped)
    }

    /// The operator takes vehicle `vehicle` back into its slot of assignment `id`.
    pub async fn resume(&self, id: u64, vehicle: u8) -> Result<AssignmentView, AssignError> {
        let (tx, rx) = oneshot::channel();
        self.requests
            .send(GuidanceRequest::Resume(id, vehicle, tx))
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
