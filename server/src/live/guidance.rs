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
//! - Each vehicle flies harrier-link's [`OffboardSequence`]: arm and take off if needed, stream
//!   setpoints, then OFFBOARD (PX4 refuses OFFBOARD before setpoints arrive), and OFFBOARD again
//!   whenever it is seen out of it. COMMAND_ACKs come from the link's ACK broadcast.
//! - A vehicle that is lost pauses (`lost`); when it speaks again its sequence restarts and it
//!   flies the assignment again. A vehicle whose sequence fails (a refused or unacknowledged
//!   command) goes to Hold and stays out (`failed`).
//! - When the track is deleted, or the assignment is ended through the API, every vehicle of it
//!   is sent to Hold (AUTO.LOITER) and the assignment is `ended` with the reason.
//!
//! \[CIMM\]: the constrained-IMM / TOGVF paper (`shared/papers/003_*.txt`).
//! \[BOT\]: Calise et al., *Estimation and Guidance Strategies for Vision-based Target Tracking*
//! (`shared/papers/002_*.txt`).

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::obstacle::{Avoidance, Obstacle, avoid};
use harrier_core::guidance::phase::{PhaseNeighbours, phase_of};
use harrier_core::guidance::togvf::Togvf;
use harrier_core::guidance::{Command, Limits, Orbit, StandoffLaw, TargetEstimate, UavState};
use harrier_link::command::set_mode;
use harrier_link::offboard::{OffboardConfig, OffboardSequence, Phase};
use harrier_link::px4::FlightMode;
use nalgebra::{Vector2, Vector3};
use serde::{Deserialize, Serialize};
use tokio::sync::{broadcast, mpsc, oneshot, watch};
use utoipa::ToSchema;

use super::clock::unix_now;
use super::gcs::transport::stopped;
use super::gcs::vehicle::LinkState;
use super::gcs::{GcsLink, Request, VehicleSample};
use super::tracker::Snapshot;
use crate::engine::TrackView;
use crate::prom::{Family, Histogram};

/// A new assignment, as `POST /api/v1/assignments` takes it.
#[derive(Debug, Clone, PartialEq, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct AssignmentRequest {
    /// MAVLink system ids of the vehicles (1–255, each in no other active assignment).
    #[schema(min_items = 1, max_items = 16)]
    pub vehicles: Vec<u8>,
    /// The track to follow (a live track id).
    pub track: u64,
    /// `togvf`, `lgvf` or `formation`.
    pub law: String,
    /// Standoff radius R (m).
    #[serde(default)]
    pub radius_m: Option<f64>,
    /// Observation height H above the target (m).
    #[serde(default)]
    pub height_m: Option<f64>,
    /// Phase spacing between neighbours on the circle (degrees); default 360/n.
    #[serde(default)]
    pub spacing_deg: Option<f64>,
    /// Nominal speed relative to the target (m/s); default `guidance.speed_m_s`.
    #[serde(default)]
    pub speed_m_s: Option<f64>,
    /// `ccw` or `cw` (default `ccw`).
    #[serde(default)]
    pub orbit: Option<String>,
}

/// Default standoff radius (m).
pub const DEFAULT_RADIUS_M: f64 = 60.0;
/// Default observation height (m).
pub const DEFAULT_HEIGHT_M: f64 = 40.0;

/// An assignment's checked geometry: what [`AssignmentRequest::plan`] makes of a request.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plan {
    /// Standoff radius (m).
    pub radius: f64,
    /// Observation height (m).
    pub height: f64,
    /// Phase spacing (rad).
    pub spacing: f64,
    /// Speed relative to the target (m/s).
    pub speed: f64,
    /// Direction of the orbit.
    pub orbit: Orbit,
}

impl AssignmentRequest {
    /// Checks the request against the flight envelope and fills in the defaults: every value
    /// finite and in range, or an error naming the field. (Whether the vehicles and the track
    /// exist is the guidance loop's to say.)
    pub fn plan(&self, settings: &GuidanceSettings) -> Result<Plan, String> {
        let bad = |m: String| Err(m);
        if self.vehicles.is_empty() || self.vehicles.len() > 16 {
            return bad("vehicles: give 1 to 16 system ids".into());
        }
        let mut ids = self.vehicles.clone();
        ids.sort_unstable();
        ids.dedup();
        if ids.len() != self.vehicles.len() || ids.contains(&0) {
            return bad("vehicles: ids must be 1-255 and distinct".into());
        }
        if !matches!(self.law.as_str(), "togvf" | "lgvf" | "formation") {
            return bad(format!(
                "law {:?}: expected togvf, lgvf or formation",
                self.law
            ));
        }
        let radius = self.radius_m.unwrap_or(DEFAULT_RADIUS_M);
        let height = self.height_m.unwrap_or(DEFAULT_HEIGHT_M);
        let speed = self.speed_m_s.unwrap_or(settings.speed);
        let n = self.vehicles.len();
        let spacing = self.spacing_deg.unwrap_or(360.0 / n as f64).to_radians();
        let limits = settings.limits;
        if !(radius.is_finite() && radius > 0.0 && radius <= 10_000.0) {
            return bad(format!("radius_m must be in (0, 10000], got {radius}"));
        }
        let r_min = limits.min_turn_radius(speed);
        if radius < r_min {
            return bad(format!(
                "radius_m {radius} is below the vehicles' turning radius {r_min:.1} m at {speed} m/s"
            ));
        }
        if !(height.is_finite() && height > 0.0 && height <= 5_000.0) {
            return bad(format!("height_m must be in (0, 5000], got {height}"));
        }
        if !(speed.is_finite() && speed > 0.0 && speed <= limits.v_max) {
            return bad(format!(
                "speed_m_s must be in (0, {}], got {speed}",
                limits.v_max
            ));
        }
        if !(spacing.is_finite()
            && spacing > 0.0
            && spacing * n as f64 <= std::f64::consts::TAU + 1e-9)
        {
            return bad(format!(
                "spacing_deg must be > 0 with n × spacing ≤ 360, got {}",
                spacing.to_degrees()
            ));
        }
        let orbit = match self.orbit.as_deref() {
            None | Some("ccw") => Orbit::Ccw,
            Some("cw") => Orbit::Cw,
            Some(o) => return bad(format!("orbit {o:?}: expected ccw or cw")),
        };
        Ok(Plan {
            radius,
            height,
            spacing,
            speed,
            orbit,
        })
    }
}

/// Where one vehicle of an assignment is.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct SlotView {
    /// The vehicle.
    pub vehicle: u8,
    /// `waiting` (no telemetry yet), `arming`, `taking_off`, `offboard`, `lost`, `failed`, `hold`
    /// (the assignment ended).
    pub state: String,
    /// Why it failed, when it did.
    pub error: Option<String>,
    /// Horizontal distance to the track estimate minus R (m).
    pub range_error_m: Option<f64>,
    /// Phase around the track estimate (degrees, from east, counter-clockwise).
    pub phase_deg: Option<f64>,
    /// The last commanded velocity (ENU, m/s).
    pub commanded_velocity: Option<[f64; 3]>,
}

/// An assignment as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, ToSchema)]
pub struct AssignmentView {
    /// Assignment id.
    pub id: u64,
    /// The track.
    pub track: u64,
    /// The law.
    pub law: String,
    /// R (m).
    pub radius_m: f64,
    /// H (m).
    pub height_m: f64,
    /// Phase spacing (degrees).
    pub spacing_deg: f64,
    /// Speed relative to the target (m/s).
    pub speed_m_s: f64,
    /// `ccw` or `cw`.
    pub orbit: String,
    /// `active` or `ended`.
    pub state: String,
    /// Why it ended.
    pub ended_reason: Option<String>,
    /// When it was created (UNIX s).
    pub created_unix: f64,
    /// Its vehicles.
    pub vehicles: Vec<SlotView>,
}

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

/// Look-ahead and margin of the formation's obstacle avoidance (\[BOT\] §III.B), scaled to
/// multirotor speeds.
const AVOIDANCE: Avoidance = Avoidance {
    lookahead: 120.0,
    margin: 15.0,
};

/// The \[BOT\] range regulators of a formation: one per ordered pair of members (0 = the leader).
#[derive(Debug, Default)]
struct FormationState {
    pairs: Vec<Vec<PairState>>,
    last_t: Option<f64>,
}

/// Desired LOS range between members `i` and `j` of the shape: the leader (0) at the centre,
/// follower `k` at `R (cos((k−1)Δ), sin((k−1)Δ))`.
fn shape_range(i: usize, j: usize, radius: f64, spacing: f64) -> f64 {
    let at = |k: usize| {
        if k == 0 {
            Vector2::zeros()
        } else {
            let a = (k - 1) as f64 * spacing;
            Vector2::new(a.cos(), a.sin()) * radius
        }
    };
    (at(i) - at(j)).norm()
}

/// The formation's commands at tracker time `t`, one per vehicle (`None` without telemetry):
/// \[BOT\] eq. (6), the vector sum of eq. (5)'s pseudo-controls along every line of sight to the
/// leader (the track estimate) and to the other vehicles, then §III.B's silhouette-edge
/// avoidance (a regulator is hedged, not advanced, while its vehicle avoids); vertically
/// \[CIMM\] §4.1's climb to H above the target.
#[allow(clippy::too_many_arguments)]
fn formation_commands(
    f: &mut FormationState,
    states: &[Option<UavState>],
    target: &TargetEstimate,
    radius: f64,
    height: f64,
    spacing: f64,
    t: f64,
    limits: &Limits,
    obstacles: &[Obstacle],
) -> Vec<Option<Command>> {
    let reg = RangeRegulator::default();
    let n = states.len() + 1;
    let pos = |j: usize| {
        if j == 0 {
            Some(target.position.xy())
        } else {
            states[j - 1].as_ref().map(UavState::horizontal_position)
        }
    };
    if f.pairs.len() != n {
        f.pairs = (0..n)
            .map(|i| {
                (0..n)
                    .map(|j| {
                        let r = match (pos(i), pos(j)) {
                            (Some(a), Some(b)) => (a - b).norm(),
                            _ => shape_range(i, j, radius, spacing),
                        };
                        PairState::start(r)
                    })
                    .collect()
            })
            .collect();
    }
    let dt = f.last_t.map_or(0.0, |last| (t - last).clamp(0.0, 1.0));
    f.last_t = Some(t);
    (1..n)
        .map(|k| {
            let u = states[k - 1].as_ref()?;
            let p = u.horizontal_position();
            let lines: Vec<(usize, Vector2<f64>, f64)> = (0..n)
                .filter(|&j| j != k)
                .filter_map(|j| {
                    let rel = pos(j)? - p;
                    let r = rel.norm();
                    Some((j, rel / r.max(1e-9), r))
                })
                .collect();
            // Eq. (6) with û along the line of sight to the neighbour, as in `guidance-sim`.
            let desired = vector_sum(lines.iter().map(|&(j, los, r)| {
                (
                    los,
                    reg.pseudo_control(&f.pairs[k][j], r, shape_range(k, j, radius, spacing)),
                )
            }));
            let (vh, avoiding) = avoid(p, u.horizontal_velocity(), desired, obstacles, &AVOIDANCE);
            for &(j, _, r) in &lines {
                let r_com = shape_range(k, j, radius, spacing);
                f.pairs[k][j] = if avoiding {
                    reg.hedge(&f.pairs[k][j], r)
                } else {
                    reg.advance(&f.pairs[k][j], r, r_com, dt)
                };
            }
            let vz = Togvf::vertical_speed(u.position.z - target.position.z - height, limits);
            Some(Command::new(vh, vz).or_hold(u, limits))
        })
        .collect()
}

#[derive(Debug)]
struct Slot {
    vehicle: u8,
    sequence: Option<OffboardSequence>,
    state: &'static str,
    error: Option<String>,
    range_error: Option<f64>,
    phase: Option<f64>,
    commanded: Option<Vector3<f64>>,
}

#[derive(Debug)]
struct Assignment {
    id: u64,
    track: u64,
    law: String,
    radius: f64,
    height: f64,
    spacing: f64,
    speed: f64,
    orbit: Orbit,
    created_unix: f64,
    ended: Option<String>,
    slots: Vec<Slot>,
    formation: FormationState,
}

impl Assignment {
    fn view(&self) -> AssignmentView {
        AssignmentView {
            id: self.id,
            track: self.track,
            law: self.law.clone(),
            radius_m: self.radius,
            height_m: self.height,
            spacing_deg: self.spacing.to_degrees(),
            speed_m_s: self.speed,
            orbit: if self.orbit == Orbit::Cw { "cw" } else { "ccw" }.into(),
            state: if self.ended.is_some() {
                "ended"
            } else {
                "active"
            }
            .into(),
            ended_reason: self.ended.clone(),
            created_unix: self.created_unix,
            vehicles: self
                .slots
                .iter()
                .map(|s| SlotView {
                    vehicle: s.vehicle,
                    state: s.state.into(),
                    error: s.error.clone(),
                    range_error_m: s.range_error,
                    phase_deg: s.phase.map(f64::to_degrees),
                    commanded_velocity: s.commanded.map(Into::into),
                })
                .collect(),
        }
    }

    fn law(&self) -> Box<dyn StandoffLaw + Send> {
        match self.law.as_str() {
            "lgvf" => Box::new(Lgvf {
                orbit: self.orbit,
                ..Lgvf::new(self.radius, self.height, self.speed)
            }),
            _ => Box::new(Togvf {
                orbit: self.orbit,
                ..Togvf::new(self.radius, self.height, self.speed)
            }),
        }
    }
}

/// A vehicle within this share of R of the circle takes part in the phase coordination.
const ON_CIRCLE: f64 = 0.25;

/// Longest extrapolation of a track to now (s): beyond it the last estimate is used as is.
const MAX_PREDICTION_S: f64 = 2.0;

/// The track's estimate at time `now` of the tracker's time line (constant velocity from its
/// last update).
fn predict(track: &TrackView, now: f64) -> TargetEstimate {
    let [x, y, z, vx, vy, vz] = track.state;
    let dt = (now - track.t).clamp(0.0, MAX_PREDICTION_S);
    let dt = if dt.is_finite() { dt } else { 0.0 };
    TargetEstimate {
        position: Vector3::new(x + vx * dt, y + vy * dt, z + vz * dt),
        velocity: Vector3::new(vx, vy, vz),
    }
}

struct Actor {
    settings: GuidanceSettings,
    link: GcsLink,
    snapshot: watch::Receiver<Arc<Snapshot>>,
    assignments: BTreeMap<u64, Assignment>,
    next_id: u64,
    watch: watch::Sender<Arc<Vec<AssignmentView>>>,
    events: broadcast::Sender<AssignmentView>,
    metrics: Arc<GuidanceMetrics>,
}

/// Starts the loop.
pub fn start(
    settings: GuidanceSettings,
    link: GcsLink,
    snapshot: watch::Receiver<Arc<Snapshot>>,
    stop: watch::Receiver<bool>,
) -> (Guidance, tokio::task::JoinHandle<()>) {
    let (requests, rx) = mpsc::channel(64);
    let (watch_tx, watch_rx) = watch::channel(Arc::new(Vec::new()));
    let (events, _) = broadcast::channel(256);
    let metrics = Arc::new(GuidanceMetrics::default());
    let acks = link.acks.subscribe();
    let actor = Actor {
        settings,
        link,
        snapshot,
        assignments: BTreeMap::new(),
        next_id: 1,
        watch: watch_tx,
        events: events.clone(),
        metrics: Arc::clone(&metrics),
    };
    let task = tokio::spawn(actor.run(rx, acks, stop));
    (
        Guidance {
            requests,
            assignments: watch_rx,
            events,
            metrics,
        },
        task,
    )
}

impl Actor {
    async fn run(
        mut self,
        mut requests: mpsc::Receiver<GuidanceRequest>,
        mut acks: broadcast::Receiver<(u8, harrier_link::mavlink::dialects::common::MavMessage)>,
        mut stop: watch::Receiver<bool>,
    ) {
        let period = Duration::from_secs_f64(1.0 / self.settings.rate_hz);
        let mut tick = tokio::time::interval(period);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                Some(r) = requests.recv() => self.on_request(r),
                a = acks.recv() => match a {
                    Ok((vehicle, msg)) => self.on_ack(vehicle, &msg),
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        tracing::warn!("guidance: {n} COMMAND_ACKs missed");
                    }
                    Err(broadcast::error::RecvError::Closed) => break,
                },
                scheduled = tick.tick() => {
                    let now = Instant::now();
                    // Lateness against the schedule: the jitter of the loop.
                    self.metrics.late(now.duration_since(scheduled.into_std()).as_micros() as u64);
                    self.on_tick(now);
                }
                () = stopped(&mut stop) => break,
            }
        }
    }

    fn t(&self, now: Instant) -> f64 {
        now.duration_since(self.link.epoch).as_secs_f64()
    }

    fn send(&self, vehicle: u8, message: harrier_link::mavlink::dialects::common::MavMessage) {
        if self
            .link
            .requests
            .try_send(Request::Send { vehicle, message })
            .is_err()
        {
            tracing::debug!(vehicle, "guidance: link queue full, message dropped");
        }
    }

    fn hold(&self, vehicle: u8) {
        let link = self.link.clone();
        tokio::spawn(async move {
            match link
                .command(vehicle, set_mode(vehicle, FlightMode::Hold))
                .await
            {
                Ok(o) if o.ok => tracing::info!(vehicle, "guidance: vehicle sent to Hold"),
                Ok(o) => tracing::warn!(vehicle, result = o.result, "guidance: Hold refused"),
                Err(e) => tracing::warn!(vehicle, "guidance: Hold not sent: {e}"),
            }
        });
    }

    fn on_request(&mut self, r: GuidanceRequest) {
        match r {
            GuidanceRequest::Create(req, reply) => {
                let r = self.create(req);
                if let Ok(v) = &r {
                    self.metrics.created.fetch_add(1, Ordering::Relaxed);
                    let _ = self.events.send(v.clone());
                    tracing::info!(id = v.id, track = v.track, vehicles = ?v.vehicles.iter().map(|s| s.vehicle).collect::<Vec<_>>(), law = v.law, "assignment created");
                }
                let _ = reply.send(r);
                self.publish();
            }
            GuidanceRequest::End(id, reply) => {
                let v = self.end(id, "ended by the operator".into());
                let _ = reply.send(v);
                self.publish();
            }
        }
    }

    fn create(&mut self, r: AssignmentRequest) -> Result<AssignmentView, AssignError> {
        let Plan {
            radius,
            height,
            spacing,
            speed,
            orbit,
        } = r.plan(&self.settings).map_err(AssignError::Invalid)?;
        let vehicles = self.link.vehicles.borrow().clone();
        for id in &r.vehicles {
            if !vehicles.iter().any(|s| s.view.id == *id) {
                return Err(AssignError::NotFound(format!("no vehicle {id}")));
            }
            if let Some(a) = self
                .assignments
                .values()
                .find(|a| a.ended.is_none() && a.slots.iter().any(|s| s.vehicle == *id))
            {
                return Err(AssignError::Conflict(format!(
                    "vehicle {id} already flies assignment {}",
                    a.id
                )));
            }
        }
        if !self
            .snapshot
            .borrow()
            .tracks
            .iter()
            .any(|t| t.id == r.track)
        {
            return Err(AssignError::NotFound(format!("no track {}", r.track)));
        }
        let id = self.next_id;
        self.next_id += 1;
        let a = Assignment {
            id,
            track: r.track,
            law: r.law,
            radius,
            height,
            spacing,
            speed,
            orbit,
            created_unix: unix_now(),
            ended: None,
            formation: FormationState::default(),
            slots: r
                .vehicles
                .iter()
                .map(|&vehicle| Slot {
                    vehicle,
                    sequence: None,
                    state: "waiting",
                    error: None,
                    range_error: None,
                    phase: None,
                    commanded: None,
                })
                .collect(),
        };
        let view = a.view();
        self.assignments.insert(id, a);
        Ok(view)
    }

    fn end(&mut self, id: u64, reason: String) -> Option<AssignmentView> {
        let a = self.assignments.get_mut(&id)?;
        if a.ended.is_none() {
            tracing::info!(id, reason, "assignment ended");
            a.ended = Some(reason);
            let holds: Vec<u8> = a
                .slots
                .iter_mut()
                .filter(|s| s.state != "lost" && s.state != "waiting")
                .map(|s| {
                    s.state = "hold";
                    s.sequence = None;
                    s.vehicle
                })
                .collect();
            let view = a.view();
            for v in holds {
                self.hold(v);
            }
            self.metrics.ended.fetch_add(1, Ordering::Relaxed);
            let _ = self.events.send(view);
        }
        self.assignments.get(&id).map(Assignment::view)
    }

    fn on_ack(&mut self, vehicle: u8, msg: &harrier_link::mavlink::dialects::common::MavMessage) {
        let t = self.t(Instant::now());
        let mut failed = None;
        for a in self.assignments.values_mut().filter(|a| a.ended.is_none()) {
            for s in a.slots.iter_mut().filter(|s| s.vehicle == vehicle) {
                if let Some(seq) = &mut s.sequence
                    && let Err(e) = seq.handle(t, msg)
                {
                    s.state = "failed";
                    s.error = Some(e.to_string());
                    s.sequence = None;
                    failed = Some(vehicle);
                }
            }
        }
        if let Some(v) = failed {
            tracing::warn!(vehicle = v, "guidance: launch failed; vehicle to Hold");
            self.hold(v);
        }
    }

    fn on_tick(&mut self, now: Instant) {
        self.metrics.ticks.fetch_add(1, Ordering::Relaxed);
        if self.assignments.values().all(|a| a.ended.is_some()) {
            return;
        }
        let t = self.t(now);
        let snapshot = self.snapshot.borrow().clone();
        let vehicles = Arc::clone(&self.link.vehicles.borrow());
        let limits = self.settings.limits;
        let takeoff_height = self.settings.takeoff_height;
        let mut to_end = Vec::new();
        let mut to_send = Vec::new();
        let mut to_hold = Vec::new();
        let mut changed = Vec::new();
        for a in self.assignments.values_mut().filter(|a| a.ended.is_none()) {
            let Some(track) = snapshot.tracks.iter().find(|k| k.id == a.track) else {
                to_end.push((a.id, format!("track {} deleted", a.track)));
                continue;
            };
            // To the tracker's latest scan time: its time line may run ahead of the wall clock
            // (a simulator with a speed-up), so the wall clock is not used.
            let target = predict(track, snapshot.t.unwrap_or(track.t));
            let law = a.law();
            // Measured states of the flying vehicles, and their ring order along the orbit.
            let states: Vec<Option<(UavState, &VehicleSample)>> = a
                .slots
                .iter()
                .map(|s| {
                    let v = vehicles.iter().find(|v| v.view.id == s.vehicle)?;
                    if v.view.state != LinkState::Connected {
                        return None;
                    }
                    let p = v.view.position?;
                    let vel = v.view.velocity?;
                    Some((UavState::new(p.into(), vel.into()), v))
                })
                .collect();
            // The ring: the vehicles on the circle. One still on its way flies the law alone,
            // at full speed: its phase error would only slow its approach ([CIMM] §4.3
            // coordinates UAVs already on the limit cycle).
            let mut ring: Vec<(usize, f64)> = states
                .iter()
                .enumerate()
                .filter_map(|(i, s)| {
                    let (u, _) = s.as_ref()?;
                    let d = u.horizontal_position() - target.position.xy();
                    ((d.norm() - a.radius).abs() <= ON_CIRCLE * a.radius)
                        .then(|| (i, d.y.atan2(d.x)))
                })
                .collect();
            let sign = a.orbit.sign();
            ring.sort_by(|x, y| (sign * x.1).total_cmp(&(sign * y.1)));
            let phases: Vec<f64> = ring.iter().map(|r| r.1).collect();
            let n_slots = a.slots.len();
            let formation = (a.law == "formation").then(|| {
                let uavs: Vec<Option<UavState>> =
                    states.iter().map(|s| s.as_ref().map(|(u, _)| *u)).collect();
                formation_commands(
                    &mut a.formation,
                    &uavs,
                    &target,
                    a.radius,
                    a.height,
                    a.spacing,
                    snapshot.t.unwrap_or(track.t),
                    &limits,
                    &self.settings.obstacles,
                )
            });
            for (i, slot) in a.slots.iter_mut().enumerate() {
                let before = (slot.state, slot.error.clone());
                let known = vehicles.iter().find(|v| v.view.id == slot.vehicle);
                match (&states[i], known) {
                    (None, Some(v)) if v.view.state == LinkState::Lost => {
                        if slot.state != "failed" {
                            slot.state = "lost";
                            slot.sequence = None;
                        }
                    }
                    (None, _) => {
                        if slot.state != "failed" && slot.state != "lost" {
                            slot.state = "waiting";
                        }
                    }
                    (Some(_), _) if slot.state == "failed" => {}
                    (Some((uav, v)), _) => {
                        let d: Vector2<f64> = uav.horizontal_position() - target.position.xy();
                        slot.range_error = Some(d.norm() - a.radius);
                        slot.phase =
                            Some(phase_of(uav.horizontal_position(), target.position.xy()));
                        let neighbours = ring.iter().position(|r| r.0 == i).and_then(|k| {
                            PhaseNeighbours::ring(&phases, k).map(|mut nb| {
                                // The assignment's spacing once all are on the circle.
                                if phases.len() == n_slots {
                                    nb.spacing = a.spacing;
                                }
                                nb
                            })
                        });
                        let cmd = match formation.as_ref().and_then(|c| c[i]) {
                            Some(c) => c,
                            None => law
                                .command(uav, Some(&target), &limits, neighbours.as_ref())
                                .or_hold(uav, &limits),
                        };
                        let status = v.status.unwrap_or(harrier_link::px4::VehicleStatus {
                            armed: false,
                            mode: None,
                            at: 0.0,
                        });
                        let seq = slot.sequence.get_or_insert_with(|| {
                            let takeoff = v.home_amsl.map(|h| (h + takeoff_height) as f32);
                            OffboardSequence::new(slot.vehicle, OffboardConfig::new(takeoff))
                        });
                        match seq.next(t, &status, Some(cmd.velocity)) {
                            Ok(msgs) => {
                                for m in msgs {
                                    to_send.push((slot.vehicle, m));
                                }
                                slot.state = match seq.phase() {
                                    Phase::Arming => "arming",
                                    Phase::TakingOff => "taking_off",
                                    Phase::Offboard => "offboard",
                                };
                                slot.commanded = Some(cmd.velocity);
                            }
                            Err(e) => {
                                slot.state = "failed";
                                slot.error = Some(e.to_string());
                                slot.sequence = None;
                                to_hold.push(slot.vehicle);
                            }
                        }
                    }
                }
                if before != (slot.state, slot.error.clone()) {
                    changed.push(a.id);
                }
            }
        }
        let mut sent = 0;
        for (vehicle, m) in to_send {
            if matches!(
                m,
                harrier_link::mavlink::dialects::common::MavMessage::SET_POSITION_TARGET_LOCAL_NED(
                    _
                )
            ) {
                sent += 1;
            }
            self.send(vehicle, m);
        }
        self.metrics.setpoints.fetch_add(sent, Ordering::Relaxed);
        for v in to_hold {
            self.hold(v);
        }
        for (id, reason) in to_end {
            self.end(id, reason);
        }
        changed.dedup();
        for id in changed {
            if let Some(a) = self.assignments.get(&id) {
                let _ = self.events.send(a.view());
            }
        }
        self.publish();
    }

    fn publish(&self) {
        let views: Vec<AssignmentView> = self.assignments.values().map(Assignment::view).collect();
        self.watch.send_replace(Arc::new(views));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A follower south of the leader closes in along the line of sight; with an obstacle on that
    /// line it is steered around it (§III.B), and its regulators are hedged meanwhile.
    #[test]
    fn the_formation_closes_in_and_steers_around_an_obstacle() {
        let limits = Limits::multirotor();
        let target = TargetEstimate::fixed(Vector3::zeros());
        let uav = UavState::new(Vector3::new(0.0, -300.0, 60.0), Vector3::new(0.0, 5.0, 0.0));
        let run = |obstacles: &[Obstacle]| {
            let mut f = FormationState::default();
            let mut cmd = None;
            for k in 0..5 {
                cmd = formation_commands(
                    &mut f,
                    &[Some(uav)],
                    &target,
                    80.0,
                    60.0,
                    std::f64::consts::TAU,
                    f64::from(k) * 0.1,
                    &limits,
                    obstacles,
                )[0];
            }
            cmd.expect("a command").velocity
        };
        let free = run(&[]);
        assert!(free.y > 1.0 && free.x.abs() < 1e-6, "{free:?}");
        let blocked = run(&[Obstacle {
            center: Vector2::new(0.0, -220.0),
            radius: 20.0,
        }]);
        assert!(blocked.x.abs() > 0.5, "{blocked:?}");
        // Three followers 120° apart on R = 80 m: √3 R from each other, R from the leader.
        let third = std::f64::consts::TAU / 3.0;
        assert!((shape_range(1, 2, 80.0, third) - 80.0 * 3f64.sqrt()).abs() < 1e-9);
        assert!((shape_range(3, 0, 80.0, third) - 80.0).abs() < 1e-9);
    }

    #[test]
    fn prediction_is_bounded() {
        let track = TrackView {
            id: 1,
            status: "confirmed",
            t: 100.0,
            state: [0.0, 0.0, 0.0, 2.0, -1.0, 0.0],
            cov: Vec::new(),
            cov_dims: Vec::new(),
            updated: true,
            age: 3,
            last_update: 100.0,
            mode_probabilities: Vec::new(),
        };
        let e = predict(&track, 100.5);
        assert_eq!(e.position, Vector3::new(1.0, -0.5, 0.0));
        // Far ahead: at most MAX_PREDICTION_S; behind or non-finite: the estimate as is.
        assert_eq!(predict(&track, 1e9).position.x, 2.0 * MAX_PREDICTION_S);
        assert_eq!(predict(&track, 0.0).position.x, 0.0);
        assert_eq!(predict(&track, f64::NAN).position.x, 0.0);
    }
}
