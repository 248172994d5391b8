//! The guidance loop (an actor): assignments tie vehicles to a track with a law, and at
//! `guidance.rate_hz` each assigned vehicle gets a velocity setpoint computed by harrier-core's
//! law from the track predicted to now and the vehicle's **measured** state (its
//! GLOBAL_POSITION_INT, in the server's ENU frame).
//!
//! - Laws: `togvf` (time-optimal guidance vector field, \[CIMM\] §4.1–4.2) and `lgvf` (the Lyapunov
//!   baseline), both with the phase coordination of \[CIMM\] §4.3 when several vehicles share the
//!   target (ring order from the current phases, spacing `spacing_deg`, default 360°/n); and
//!   `formation` (\[BOT\] §III): the track leads, the vehicles hold the LOS ranges of a shape (each
//!   at R from the leader, `spacing_deg` apart around it) with the range regulator of eqs.
//!   (5)–(6), steered around `guidance.obstacles` (§III.B).
//! - Each vehicle flies harrier-link's
//!   [`OffboardSequence`](harrier_link::offboard::OffboardSequence): arm and take off if
//!   needed, stream setpoints, then OFFBOARD (PX4 refuses OFFBOARD before setpoints arrive), and
//!   OFFBOARD again whenever it is seen out of it. COMMAND_ACKs come from the link's ACK
//!   broadcast.
//! - A vehicle that is lost pauses (`lost`); when it speaks again its sequence restarts and it
//!   flies the assignment again. A vehicle whose sequence fails (a refused or unacknowledged
//!   command) goes to Hold and stays out (`failed`).
//! - When the track is deleted, or the assignment is ended through the API, every vehicle of it
//!   is sent to Hold (AUTO.LOITER) and the assignment is `ended` with the reason.
//!
//! The files: [`plan`] (the request, its checked [`plan::Plan`], the views and their enums:
//! [`Law`], [`OrbitDirection`], [`AssignmentState`], [`SlotState`]; pure),
//! `formation` (the \[BOT\] formation's commands; pure) and `actor` ([`start`]: the assignments
//! and the loop); this one holds the handle ([`Guidance`]), its requests, errors, settings and
//! counters.
//!
//! \[CIMM\]: the constrained-IMM / TOGVF paper (`shared/papers/003_*.txt`).
//! \[BOT\]: Calise et al., *Estimation and Guidance Strategies for Vision-based Target Tracking*
//! (`shared/papers/002_*.txt`).

mod actor;
mod formation;
pub mod plan;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};

use harrier_core::guidance::Limits;
use harrier_core::guidance::obstacle::Obstacle;
use tokio::sync::{broadcast, mpsc, oneshot, watch};

pub use self::actor::start;
pub use self::plan::{
    AssignmentRequest, AssignmentState, AssignmentView, Law, OrbitDirection, SlotState, SlotView,
};
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
    ticks: AtomicU64,
    setpoints: AtomicU64,
    /// How late each tick started (s), over [`LATE_BOUNDS_S`].
    late: Mutex<Histogram>,
    max_late_us: AtomicU64,
    created: AtomicU64,
    ended: AtomicU64,
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
    fn late(&self, us: u64) {
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

/// Settings of the loop.
#[derive(Debug, Clone, PartialEq)]
pub struct GuidanceSettings {
    /// Setpoint rate (Hz).
    pub rate_hz: f64,
    /// Flight envelope.
    pub limits: Limits,
    /// Default speed (m/s).
    pub speed: f64,
    /// Takeoff height above home (m).
    pub takeoff_height: f64,
    /// Obstacles the `formation` law steers around (ENU).
    pub obstacles: Vec<Obstacle>,
}
