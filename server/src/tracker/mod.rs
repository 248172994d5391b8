//! The tracker actor: owns the `Box<dyn TrackEngine>` and feeds it scans in time order.
//!
//! Scans wait in a short reorder buffer until no older scan can still come: a scan is processed
//! once every active source (vehicle and sensor) has delivered a scan at least as new — a source
//! is active while its newest scan is within `reorder_window_s` (scan time) of the newest scan of
//! all — or once a scan `reorder_window_s` newer has arrived, or when nothing has arrived for that
//! long in wall time (at least 20 ms). So a scan waits for the slowest active source, never longer
//! than the window; a lone source is not delayed at all. A scan older than the last processed one
//! by at most `late_lag_s` is processed at once: the engine retrodicts it into the tracks it
//! updates (harrier-core's `tracker::retrodict`), counted as retrodicted; an older one is late:
//! counted and dropped.
//!
//! The actor keeps the list of live tracks from what each scan returns (the engine's
//! [`ScanOutcome`]: the events and the views of the tracks the scan changed), asking the engine
//! for all of them ([`TrackEngine::snapshot`]) only at the start and after a change of track
//! filter. After each scan it publishes that list on a `watch` channel (the latest state, never
//! blocking) and the scan's track events on a bounded `broadcast` channel (a slow subscriber
//! loses events, tracking never waits for it).

use std::collections::{BTreeMap, HashMap};
use std::sync::{Arc, OnceLock, PoisonError};
use std::time::Duration;

use harrier_core::registration::KnownObject;
use harrier_core::tracker::TrackEvent;
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;
use tokio::sync::{broadcast, mpsc, oneshot, watch};

use super::bound::{BoundConfig, Bounds};
use super::gcs::VehicleSample;
use super::gcs::vehicle::LinkState;
use super::ingest::ReadyScan;
use super::metrics::{DropReason, Metrics};
use harrier_engine::{
    Deployment, EngineError, Params, ScanOutcome, ScanSource, SensorBiasView, TrackEngine,
    TrackStatus, TrackView,
};

/// Scans kept for `GET /api/v1/detections`.
pub const RECENT_SCANS: usize = 512;
/// Positions kept per track for its history.
pub const HISTORY_LEN: usize = 200;
/// Standard deviation (m) of a UAV's GPS position as a cooperative reference.
pub const GPS_STD_M: f64 = 3.0;
/// A vehicle whose last position is further than this (s) from a scan's time is no cooperative
/// reference of the scan.
pub const REFERENCE_MAX_AGE_S: f64 = 2.0;
/// Standard deviation (s) of the time of a vehicle's position as a reference: the server stamps
/// a GLOBAL_POSITION_INT when it arrives, a transport delay after the vehicle's fix.
pub const REFERENCE_TIMING_STD_S: f64 = 0.05;
/// Scan time (s) between two refreshes of the bias estimates (WebSocket, snapshot, recording):
/// at most 2 Hz.
pub const BIAS_PERIOD_S: f64 = 0.5;

/// The track filter the tracker runs, and its parameters. On the wire it keeps the name
/// "estimator": `GET`/`PUT /api/v1/estimator` read and select the track filter.
#[derive(Debug, Clone, Default, PartialEq, Serialize, utoipa::ToSchema)]
#[schema(as = EstimatorState)]
pub struct TrackFilterState {
    /// Track filter name (`ekf`, `cdkf`, `imm`, `cimm`; `GET /api/v1/estimators`).
    pub name: String,
    /// Associator name (`gnn`, `jipda`, `mht`; `GET /api/v1/estimators`).
    pub associator: String,
    /// Parameters given, of the track filter and the associator (the others have their
    /// defaults).
    pub params: BTreeMap<String, f64>,
}

impl TrackFilterState {
    /// The track filter and associator `[tracker]` starts with.
    pub fn of(config: &crate::config::TrackerConfig) -> Self {
        Self {
            name: config.estimator.clone(),
            associator: config.associator.clone(),
            params: config.params.clone(),
        }
    }

    /// Their track engine for `deployment`.
    pub fn build(&self, deployment: &Deployment) -> Result<Box<dyn TrackEngine>, EngineError> {
        harrier_engine::registry::build_track_engine(
            &self.name,
            &self.associator,
            deployment,
            &Params::from(&self.params),
        )
    }
}

mod view;

pub use self::view::{Recent, ScanEvents, Snapshot, VehicleView, changes};

/// What the API asks of the tracker.
#[derive(Debug)]
pub enum Command {
    /// Change the estimator; live tracks are handed over (ids kept).
    SetEstimator {
        /// The new estimator.
        to: TrackFilterState,
        /// The result: the estimator now running, or why the change was refused.
        reply: oneshot::Sender<Result<TrackFilterState, SetError>>,
    },
    /// The MAVLink link's vehicles: with sensor registration, their GPS positions are the
    /// cooperative references of every scan (`ScanSource::references`).
    References(watch::Receiver<Arc<Vec<VehicleSample>>>),
}

/// Why a change of estimator was refused (nothing changed).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SetError {
    /// Unknown estimator or parameter, or a parameter out of range.
    #[error("{0}")]
    Invalid(String),
    /// The live tracks cannot be handed over to the new estimator.
    #[error("{0}")]
    Handover(String),
}

/// The tracker actor.
#[derive(Debug)]
pub struct TrackerActor {
    engine: Box<dyn TrackEngine>,
    /// The engine's live tracks, in id order: its snapshot at the start and after a change of
    /// track filter, then kept up to date from each scan's [`ScanOutcome`].
    tracks: Arc<Vec<TrackView>>,
    deployment: Deployment,
    estimator: Arc<TrackFilterState>,
    window: f64,
    /// How much older than the last processed scan a scan may be and still be taken
    /// (retrodicted); 0: none.
    late_lag: f64,
    metrics: Arc<Metrics>,
    pending: Vec<ReadyScan>,
    /// Newest scan time of each source (`vehicle/sensor`).
    sources: HashMap<String, f64>,
    seq: u64,
    vehicles: BTreeMap<String, Arc<VehicleView>>,
    recent: Arc<Recent>,
    snapshot: watch::Sender<Arc<Snapshot>>,
    events: broadcast::Sender<Arc<ScanEvents>>,
    /// Called with every processed scan (the recorder, the Zenoh publisher): must not block.
    sinks: Sinks,
    /// The set-membership bounds, when they run.
    bounds: Option<Bounds>,
    /// The bias estimates and the scan time of their last refresh (registration only).
    biases: Arc<Vec<SensorBiasView>>,
    biases_t: Option<f64>,
    /// The MAVLink link's vehicles (their GPS positions), once `Command::References` gave them.
    link_vehicles: Option<watch::Receiver<Arc<Vec<VehicleSample>>>>,
}

/// A consumer of every processed scan.
pub type Sink = Box<dyn Fn(&Arc<ScanEvents>) + Send>;

/// The consumers of every processed scan.
#[derive(Default)]
struct Sinks(Vec<Sink>);

impl std::fmt::Debug for Sinks {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} sinks", self.0.len())
    }
}

impl TrackerActor {
    /// An actor over `engine` (built as `estimator` for `deployment`) holding scans `window`
    /// seconds of scan time.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        engine: Box<dyn TrackEngine>,
        deployment: Deployment,
        estimator: TrackFilterState,
        window: f64,
        metrics: Arc<Metrics>,
        recent: Arc<Recent>,
        snapshot: watch::Sender<Arc<Snapshot>>,
        events: broadcast::Sender<Arc<ScanEvents>>,
    ) -> Self {
        let estimator = Arc::new(estimator);
        let biases = Arc::new(engine.biases());
        snapshot.send_modify(|s| {
            *s = Arc::new(Snapshot {
                estimator: Arc::clone(&estimator),
                biases: Arc::clone(&biases),
                ..Snapshot::default()
            });
        });
        Self {
            tracks: Arc::new(engine.snapshot()),
            engine,
            deployment,
            estimator,
            window,
            late_lag: 0.0,
            metrics,
            pending: Vec::new(),
            sources: HashMap::new(),
            seq: 0,
            vehicles: BTreeMap::new(),
            recent,
            snapshot,
            events,
            sinks: Sinks::default(),
            bounds: None,
            biases,
            biases_t: None,
            link_vehicles: None,
        }
    }

    /// Takes scans up to `lag` s older than the last processed one, by retrodiction. An engine
    /// that cannot (the multi-scan associator) keeps dropping them, with a warning.
    pub fn with_late_lag(mut self, lag: f64) -> Self {
        self.late_lag = match self.engine.set_retrodiction_lag(lag) {
            Ok(()) => lag,
            Err(e) => {
                tracing::warn!("late scans will be dropped: {e}");
                0.0
            }
        };
        self
    }

    /// Runs a set-membership bound beside every track ([`super::bound`]).
    pub fn with_bounds(mut self, config: BoundConfig) -> Self {
        self.bounds = config.enabled.then(|| Bounds::new(config));
        self
    }

    /// Adds a consumer of every processed scan; it runs on the tracker's task, so it must only
    /// hand the scan on (`try_send`).
    pub fn add_sink(&mut self, sink: Sink) {
        self.sinks.0.push(sink);
    }

    /// Takes one scan into the reorder buffer, then processes what the window releases.
    pub fn push(&mut self, s: ReadyScan) {
        if let Some(last) = self.engine.time().filter(|last| s.scan.t < *last) {
            if s.scan.t >= last - self.late_lag {
                self.metrics.retrodicted(&s.vehicle);
                tracing::debug!(
                    vehicle = s.vehicle,
                    t = s.scan.t,
                    last,
                    "late scan retrodicted"
                );
                self.process(s);
            } else {
                self.metrics.dropped(&s.vehicle, DropReason::Late);
                tracing::debug!(vehicle = s.vehicle, t = s.scan.t, last, "late scan dropped");
            }
            return;
        }
        let source = format!("{}/{}", s.vehicle, s.sensor);
        let t = s.scan.t;
        let newest_of_source = self.sources.entry(source).or_insert(t);
        *newest_of_source = newest_of_source.max(t);
        let newest = self.sources.values().copied().fold(t, f64::max);
        let floor = newest - self.window;
        // Sources silent for longer than the window are forgotten: they no longer hold scans back.
        self.sources.retain(|_, &mut last| last >= floor);
        let all_caught_up = self.sources.values().copied().fold(newest, f64::min);
        self.pending.push(s);
        self.release(all_caught_up.max(floor));
    }

    /// Processes every buffered scan with time ≤ `until`, oldest first (equal times by vehicle
    /// and sensor).
    pub fn release(&mut self, until: f64) {
        self.pending.sort_by(|a, b| {
            a.scan
                .t
                .total_cmp(&b.scan.t)
                .then_with(|| a.vehicle.cmp(&b.vehicle))
                .then_with(|| a.sensor.cmp(&b.sensor))
        });
        let n = self.pending.partition_point(|p| p.scan.t <= until);
        let ready: Vec<ReadyScan> = self.pending.drain(..n).collect();
        for s in ready {
            self.process(s);
        }
    }

    fn process(&mut self, s: ReadyScan) {
        let late = self.engine.time().is_some_and(|last| s.scan.t < last);
        let references = self.references(&s.vehicle, s.scan.t);
        let source = ScanSource {
            vehicle: &s.vehicle,
            sensor: &s.sensor,
            platform: s.platform,
            platform_vel: s.platform_vel,
            noise_std: &s.noise_std,
            references: &references,
        };
        let outcome: ScanOutcome = match self.engine.ingest_from(&s.scan, &source) {
            Ok(outcome) => outcome,
            Err(e) => {
                self.metrics.dropped(&s.vehicle, DropReason::Rejected);
                tracing::warn!(vehicle = s.vehicle, t = s.scan.t, "scan rejected: {e}");
                return;
            }
        };
        let (tracks, events) = outcome.apply(&self.tracks);
        // The tracks' time: a late scan leaves it where it was.
        let now = self.engine.time().unwrap_or(s.scan.t);
        let tracks = Arc::new(tracks);
        self.tracks = Arc::clone(&tracks);
        self.metrics.latency(s.received.elapsed().as_secs_f64());
        let confirmed = tracks
            .iter()
            .filter(|k| k.status == TrackStatus::Confirmed)
            .count();
        self.metrics.ingested(
            &s.vehicle,
            s.scan.detections.len(),
            now,
            confirmed,
            tracks.len(),
        );
        self.seq += 1;
        let v = self.vehicles.entry(s.vehicle.clone()).or_insert_with(|| {
            Arc::new(VehicleView {
                vehicle: s.vehicle.clone(),
                last_t: s.scan.t,
                scans: 0,
                sensors: Vec::new(),
                position: s.platform,
                geodetic: s.geodetic,
            })
        });
        // The last snapshot holds this view too: only it is copied.
        let v = Arc::make_mut(v);
        v.last_t = v.last_t.max(s.scan.t);
        v.scans += 1;
        v.position = s.platform;
        v.geodetic = s.geodetic;
        if !v.sensors.contains(&s.sensor) {
            v.sensors.push(s.sensor.clone());
            v.sensors.sort();
        }
        self.remember(&events, &tracks);
        // The set-membership bounds move forward in time only: a late scan leaves them.
        if let Some(b) = self.bounds.as_mut().filter(|_| !late) {
            let kind = s.scan.sensor.kind();
            let changed = b.on_scan(s.scan.t, kind, &s.noise_std, &s.scan.detections, &events);
            self.metrics.bound_resets(b.resets());
            let mut views = self
                .recent
                .bounds
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            for e in &events {
                if let TrackEvent::Deleted { id, .. } = e {
                    views.remove(id);
                }
            }
            for id in changed {
                if let Some(v) = b.view(id) {
                    views.insert(id, v);
                }
            }
        }
        let biases = self.refresh_biases(now);
        let scan = Arc::new(ScanEvents {
            biases,
            seq: self.seq,
            t: s.scan.t,
            kind: s.scan.sensor.kind(),
            vehicle: s.vehicle,
            sensor: s.sensor,
            platform: s.platform,
            detections: s.scan.detections,
            events,
            tracks: Arc::clone(&tracks),
            json: OnceLock::new(),
        });
        self.publish(Some(now), tracks);
        {
            let mut q = self
                .recent
                .scans
                .lock()
                .unwrap_or_else(PoisonError::into_inner);
            if q.len() >= RECENT_SCANS {
                q.pop_front();
            }
            q.push_back(Arc::clone(&scan));
        }
        for sink in &self.sinks.0 {
            sink(&scan);
        }
        // No subscriber is not an error.
        let _ = self.events.send(scan);
    }

    /// Appends updated tracks to their histories, forgets deleted ones.
    fn remember(&self, events: &[TrackEvent], tracks: &[TrackView]) {
        let mut h = self
            .recent
            .history
            .lock()
            .unwrap_or_else(PoisonError::into_inner);
        for e in events {
            match e {
                TrackEvent::Updated { id, .. } | TrackEvent::Born { id, .. } => {
                    if let Some(k) = tracks.iter().find(|k| k.id == *id) {
                        let q = h.entry(*id).or_default();
                        if q.len() >= HISTORY_LEN {
                            q.pop_front();
                        }
                        q.push_back([k.t, k.state[0], k.state[1], k.state[2]]);
                    }
                }
                TrackEvent::Deleted { id, .. } => {
                    h.remove(id);
                }
                _ => {}
            }
        }
    }

    /// The bias estimates, refreshed when registration runs and [`BIAS_PERIOD_S`] of scan time
    /// passed since the last refresh (at `t`): `Some` when they were.
    fn refresh_biases(&mut self, t: f64) -> Option<Arc<Vec<SensorBiasView>>> {
        if self.deployment.registration.is_empty()
            || self.biases_t.is_some_and(|last| t - last < BIAS_PERIOD_S)
        {
            return None;
        }
        self.biases_t = Some(t);
        self.biases = Arc::new(self.engine.biases());
        Some(Arc::clone(&self.biases))
    }

    fn publish(&self, t: Option<f64>, tracks: Arc<Vec<TrackView>>) {
        self.snapshot.send_replace(Arc::new(Snapshot {
            t,
            seq: self.seq,
            tracks,
            // One reference per vehicle: no view is copied here.
            vehicles: Arc::new(self.vehicles.values().map(Arc::clone).collect()),
            estimator: Arc::clone(&self.estimator),
            biases: Arc::clone(&self.biases),
        }));
    }

    /// Builds `to` for the deployment and hands the live tracks over to it.
    fn set_estimator(&mut self, to: TrackFilterState) -> Result<TrackFilterState, SetError> {
        let mut engine = to
            .build(&self.deployment)
            .map_err(|e| SetError::Invalid(e.to_string()))?;
        engine.adopt(&self.engine.handover()).map_err(|e| {
            SetError::Handover(format!("handing the tracks over to {}: {e}", to.name))
        })?;
        tracing::info!(
            from = self.estimator.name,
            from_associator = self.estimator.associator,
            to = to.name,
            to_associator = to.associator,
            "estimator changed"
        );
        if let Err(e) = engine.set_retrodiction_lag(self.late_lag) {
            tracing::warn!(to = to.name, "late scans will be dropped: {e}");
            self.late_lag = 0.0;
        }
        self.engine = engine;
        self.estimator = Arc::new(to.clone());
        let t = self.engine.time();
        self.tracks = Arc::new(self.engine.snapshot());
        // The new engine's bank starts from the priors: refreshed at the next scan.
        self.biases = Arc::new(self.engine.biases());
        self.biases_t = None;
        self.publish(t, Arc::clone(&self.tracks));
        Ok(to)
    }

    fn command(&mut self, c: Command) {
        match c {
            Command::SetEstimator { to, reply } => {
                // Scans already received are processed by the engine they arrived under.
                self.release(f64::INFINITY);
                let _ = reply.send(self.set_estimator(to));
            }
            Command::References(vehicles) => self.link_vehicles = Some(vehicles),
        }
    }

    /// The cooperative references of a scan of `vehicle` at `t` (registration only): every other
    /// vehicle of the link, connected, whose last GPS position arrived within
    /// [`REFERENCE_MAX_AGE_S`] of `t`, moved along its velocity from its arrival to `t` (a UAV
    /// at 15 m/s moves 1.5 m in the 0.1 s between a frame and a scan), with the variance
    /// [`GPS_STD_M`]² plus that of its motion over [`REFERENCE_TIMING_STD_S`]. The scan's time
    /// and the frame's are both the server's UNIX time only for sources on real time
    /// (`[clock] real_time`): a simulator that runs faster gets no references.
    fn references(&self, vehicle: &str, t: f64) -> Vec<KnownObject> {
        let Some(link) = self
            .link_vehicles
            .as_ref()
            .filter(|_| !self.deployment.registration.is_empty())
        else {
            return Vec::new();
        };
        let own = vehicle.parse::<u8>().ok();
        link.borrow()
            .iter()
            .filter(|v| v.view.state == LinkState::Connected && Some(v.view.id) != own)
            .filter_map(|v| {
                let dt = Some(t - v.position_unix?).filter(|dt| dt.abs() <= REFERENCE_MAX_AGE_S)?;
                let vel = Vector3::from(v.view.velocity.unwrap_or_default());
                let pos = Vector3::from(v.view.position?) + vel * dt;
                let var = GPS_STD_M.powi(2) + (vel.norm() * REFERENCE_TIMING_STD_S).powi(2);
                Some(KnownObject {
                    pos,
                    vel,
                    cov: Matrix3::from_diagonal_element(var),
                })
            })
            .collect()
    }

    /// Runs until the scan queue closes, then processes what is left.
    pub async fn run(
        mut self,
        mut rx: mpsc::Receiver<ReadyScan>,
        mut commands: mpsc::Receiver<Command>,
    ) {
        let idle = Duration::from_secs_f64(self.window).max(Duration::from_millis(20));
        loop {
            tokio::select! {
                biased;
                Some(c) = commands.recv() => self.command(c),
                r = tokio::time::timeout(idle, rx.recv()) => match r {
                    Ok(Some(s)) => self.push(s),
                    Ok(None) => break,
                    Err(_) => self.release(f64::INFINITY),
                },
            }
        }
        self.release(f64::INFINITY);
    }
}

#[cfg(test)]
mod tests;
