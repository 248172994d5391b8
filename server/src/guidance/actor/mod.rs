//! The guidance actor ([`start`]): it owns the assignments, answers the API's requests, follows
//! the COMMAND_ACKs and, every tick, flies each active assignment (see the module documentation
//! of [`super`]).

use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::phase::{PhaseNeighbours, phase_of};
use harrier_core::guidance::togvf::Togvf;
use harrier_core::guidance::{Command, Limits, Orbit, StandoffLaw, TargetEstimate, UavState};
use harrier_link::autopilot::{Frame, Mode, Personality, VehicleStatus};
use harrier_link::command::{command_long, set_mode};
use harrier_link::mavlink::dialects::common::{MavCmd, MavMessage};
use harrier_link::offboard::{
    OffboardConfig, OffboardError, OffboardSequence, Override, Phase, Steer,
};
use nalgebra::Vector3;
use tokio::sync::{broadcast, mpsc, watch};

use super::formation::FormationState;
use super::handle::{AssignError, Guidance, GuidanceMetrics, GuidanceRequest};
use super::handoff::{Handoff, airborne};
use super::plan::{
    AssignmentRequest, AssignmentState, AssignmentView, ENDED_BY_OPERATOR, GuidanceSettings, Law,
    OverrideSource, OverrideView, Plan, SlotState, SlotView,
};
use crate::clock::unix_now;
use crate::gcs::transport::stopped;
use crate::gcs::vehicle::LinkState;
use crate::gcs::{GcsLink, Request, VehicleSample};
use crate::tracker::Snapshot;
use harrier_engine::TrackView;

mod tick;

use self::tick::{Decisions, Tick};

/// One vehicle of an assignment.
#[derive(Debug)]
struct Slot {
    vehicle: u8,
    sequence: Option<OffboardSequence>,
    handoff: Handoff,
    state: SlotState,
    error: Option<String>,
    /// Who took it, while `overridden`.
    overridden: Option<OverrideView>,
    /// The mode its vehicle was in when its link was lost (`Some(None)`: one its table lacks),
    /// while `lost`.
    lost_in: Option<Option<Mode>>,
    range_error: Option<f64>,
    phase: Option<f64>,
    commanded: Option<Vector3<f64>>,
}

impl Slot {
    fn new(vehicle: u8) -> Self {
        Self {
            vehicle,
            sequence: None,
            handoff: Handoff::default(),
            state: SlotState::Waiting,
            error: None,
            overridden: None,
            lost_in: None,
            range_error: None,
            phase: None,
            commanded: None,
        }
    }

    /// Whether it is out of the assignment (failed, or someone else's): the guidance sends its
    /// vehicle nothing.
    fn is_out(&self) -> bool {
        matches!(self.state, SlotState::Failed | SlotState::Overridden)
    }

    /// Whether the guidance is flying its vehicle now (a Hold is due when the assignment ends).
    fn is_flown(&self) -> bool {
        matches!(
            self.state,
            SlotState::Arming | SlotState::TakingOff | SlotState::Offboard | SlotState::HandedOff
        )
    }

    /// Takes it out of the assignment: someone else's now (`o`).
    fn take_out(&mut self, o: OverrideView) {
        self.state = SlotState::Overridden;
        self.overridden = Some(o);
        self.sequence = None;
        self.handoff = Handoff::default();
        self.commanded = None;
    }
}

/// An assignment: its track, law and plan, and its vehicles.
#[derive(Debug)]
struct Assignment {
    id: u64,
    track: u64,
    plan: Plan,
    created_unix: f64,
    ended: Option<String>,
    slots: Vec<Slot>,
    formation: FormationState,
}

impl Assignment {
    /// The vehicles flying its ring: every slot not out of it.
    fn flying(&self) -> usize {
        self.slots.iter().filter(|s| !s.is_out()).count()
    }

    fn view(&self) -> AssignmentView {
        let p = &self.plan;
        AssignmentView {
            id: self.id,
            track: self.track,
            law: p.law,
            radius_m: p.radius,
            height_m: p.height,
            spacing_deg: p.spacing_of(self.flying()).to_degrees(),
            speed_m_s: p.speed,
            orbit: p.orbit,
            state: if self.ended.is_some() {
                AssignmentState::Ended
            } else {
                AssignmentState::Active
            },
            ended_reason: self.ended.clone(),
            created_unix: self.created_unix,
            vehicles: self
                .slots
                .iter()
                .map(|s| SlotView {
                    vehicle: s.vehicle,
                    state: s.state,
                    error: s.error.clone(),
                    overridden: s.overridden.clone(),
                    range_error_m: s.range_error,
                    phase_deg: s.phase.map(f64::to_degrees),
                    commanded_velocity: s.commanded.map(Into::into),
                })
                .collect(),
        }
    }

    fn law(&self) -> Box<dyn StandoffLaw + Send> {
        let p = &self.plan;
        match p.law {
            Law::Lgvf => Box::new(Lgvf {
                orbit: p.orbit.into(),
                ..Lgvf::new(p.radius, p.height, p.speed)
            }),
            // The formation's vehicles fly TOGVF when the formation has no command for one; a
            // hand-off flies no law (its slots never ask for one).
            Law::Togvf
            | Law::Formation
            | Law::HandoffOrbit
            | Law::HandoffFollow
            | Law::HandoffCamera => Box::new(Togvf {
                orbit: p.orbit.into(),
                ..Togvf::new(p.radius, p.height, p.speed)
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
    /// When the tracker's snapshot last changed (wall clock): a hand-off predicts the track on
    /// from the snapshot's time by the wall time since.
    snapshot_at: Instant,
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
        snapshot_at: Instant::now(),
    };
    // Its own thread and single-threaded runtime: on a loaded two-core machine the shared
    // runtime's workers are busy with ingest and the WebSocket when a tick falls due, and
    // 20 Hz ticks within 5 ms need a thread that is idle then.
    let (done, finished) = tokio::sync::oneshot::channel::<()>();
    std::thread::Builder::new()
        .name("harrier-guidance".into())
        .spawn(move || {
            match tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
            {
                Ok(rt) => rt.block_on(actor.run(rx, acks, stop)),
                Err(e) => tracing::error!("guidance: no runtime for its thread: {e}"),
            }
            let _ = done.send(());
        })
        .expect("start the guidance thread");
    let task = tokio::spawn(async move {
        let _ = finished.await;
    });
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

/// How early the loop's timer is set before a tick falls due: tokio's timer has a 1-ms grain and
/// may fire a millisecond late, so the loop sleeps the last stretch on the thread's own clock.
const TIMER_SLACK: Duration = Duration::from_millis(2);

/// When to wake for a tick due at `due`.
fn early(due: Instant) -> Instant {
    due.checked_sub(TIMER_SLACK).unwrap_or(due)
}

impl Actor {
    async fn run(
        mut self,
        mut requests: mpsc::Receiver<GuidanceRequest>,
        mut acks: broadcast::Receiver<(u8, harrier_link::mavlink::dialects::common::MavMessage)>,
        mut stop: watch::Receiver<bool>,
    ) {
        let period = Duration::from_secs_f64(1.0 / self.settings.rate_hz);
        let mut scheduled = Instant::now() + period;
        let wake = tokio::time::sleep_until(early(scheduled).into());
        tokio::pin!(wake);
        let mut updates = self.snapshot.clone();
        loop {
            tokio::select! {
                Some(r) = requests.recv() => self.on_request(r),
                // Every update of the tracks: the camera hand-offs point at them at once.
                changed = updates.changed() => match changed {
                    Ok(()) => self.on_tracks(),
                    Err(_) => break,
                },
                a = acks.recv() => match a {
                    Ok((vehicle, msg)) => self.on_ack(vehicle, &msg),
                    Err(broadcast::error::RecvError::Lagged(n)) => {
                        tracing::warn!("guidance: {n} COMMAND_ACKs missed");
                    }
                    Err(broadcast::error::RecvError::Closed) => break,
                },
                () = &mut wake => {
                    // The timer wakes early; the rest is slept on the thread's clock.
                    if let Some(rest) = scheduled.checked_duration_since(Instant::now()) {
                        std::thread::sleep(rest);
                    }
                    let now = Instant::now();
                    // Lateness against the schedule: the jitter of the loop.
                    self.metrics.late(now.saturating_duration_since(scheduled).as_micros() as u64);
                    self.on_tick(now);
                    // The next tick one period on; after an overrun, one period from now.
                    scheduled += period;
                    let now = Instant::now();
                    if scheduled <= now {
                        scheduled = now + period;
                    }
                    wake.as_mut().reset(early(scheduled).into());
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

    /// Sends `vehicle` to its autopilot's hold mode (PX4 Hold, ArduPilot LOITER: a fixed wing
    /// circles where it is).
    fn hold(&self, vehicle: u8) {
        let link = self.link.clone();
        let personality = personality_of(&self.link.vehicles.borrow(), vehicle);
        tokio::spawn(async move {
            match link
                .command(vehicle, set_mode(vehicle, personality.hold()))
                .await
            {
                Ok(o) if o.ok => tracing::info!(vehicle, "guidance: vehicle sent to Hold"),
                Ok(o) => {
                    tracing::warn!(
                        vehicle,
                        result = o.result.as_str(),
                        "guidance: Hold refused"
                    );
                }
                Err(e) => tracing::warn!(vehicle, "guidance: Hold not sent: {e}"),
            }
        });
    }

    /// Sends `vehicle` home (MAV_CMD_NAV_RETURN_TO_LAUNCH: PX4 AUTO.RTL, ArduPilot RTL), for the
    /// safety envelope's battery floor.
    fn return_home(&self, vehicle: u8) {
        let link = self.link.clone();
        self.metrics.battery_rtl.fetch_add(1, Ordering::Relaxed);
        tokio::spawn(async move {
            let rtl = command_long(vehicle, MavCmd::MAV_CMD_NAV_RETURN_TO_LAUNCH, [0.0; 7]);
            match link.command(vehicle, rtl).await {
                Ok(o) if o.ok => tracing::info!(vehicle, "guidance: vehicle sent home (RTL)"),
                Ok(o) => {
                    tracing::warn!(vehicle, result = o.result.as_str(), "guidance: RTL refused")
                }
                Err(e) => tracing::warn!(vehicle, "guidance: RTL not sent: {e}"),
            }
        });
    }

    fn on_request(&mut self, r: GuidanceRequest) {
        match r {
            GuidanceRequest::Create(req, reply) => {
                let r = self.create(&req);
                if let Ok(v) = &r {
                    self.metrics.created.fetch_add(1, Ordering::Relaxed);
                    let _ = self.events.send(v.clone());
                    tracing::info!(id = v.id, track = v.track, vehicles = ?v.vehicles.iter().map(|s| s.vehicle).collect::<Vec<_>>(), law = v.law.as_str(), "assignment created");
                }
                let _ = reply.send(r);
                self.publish();
            }
            GuidanceRequest::End(id, reply) => {
                let v = self.end(id, ENDED_BY_OPERATOR.into());
                let _ = reply.send(v);
                self.publish();
            }
            GuidanceRequest::Release(vehicle, what, reply) => {
                let _ = reply.send(self.release(vehicle, &what));
                self.publish();
            }
            GuidanceRequest::Resume(id, vehicle, reply) => {
                let _ = reply.send(self.resume(id, vehicle));
                self.publish();
            }
        }
    }

    /// Takes `vehicle` out of the slot it flies, before the operator's command `what`: the
    /// assignment, if it flew one.
    fn release(&mut self, vehicle: u8, what: &str) -> Option<u64> {
        let mode = self
            .link
            .vehicles
            .borrow()
            .iter()
            .find(|v| v.view.id == vehicle)
            .and_then(|v| v.view.mode.clone());
        let a = self.assignments.values_mut().find(|a| {
            a.ended.is_none() && a.slots.iter().any(|s| s.vehicle == vehicle && !s.is_out())
        })?;
        let slot = a.slots.iter_mut().find(|s| s.vehicle == vehicle)?;
        slot.take_out(OverrideView {
            from_mode: mode,
            to_mode: None,
            disarmed: false,
            by: OverrideSource::Api,
            detail: format!("the operator's {what}"),
            time_unix: unix_now(),
        });
        tracing::warn!(
            vehicle,
            assignment = a.id,
            "guidance: vehicle taken out of its slot for the operator's {what}"
        );
        self.metrics.overridden(OverrideSource::Api);
        let _ = self.events.send(a.view());
        Some(a.id)
    }

    /// Takes `vehicle` back into its slot of assignment `id` (it was overridden or failed): it
    /// flies the assignment again from its launch.
    fn resume(&mut self, id: u64, vehicle: u8) -> Result<AssignmentView, AssignError> {
        if let Some(other) = self.assignments.values().find(|a| {
            a.id != id
                && a.ended.is_none()
                && a.slots.iter().any(|s| s.vehicle == vehicle && !s.is_out())
        }) {
            return Err(AssignError::Conflict(format!(
                "vehicle {vehicle} flies assignment {}",
                other.id
            )));
        }
        let a = self
            .assignments
            .get_mut(&id)
            .ok_or_else(|| AssignError::NotFound(format!("no assignment {id}")))?;
        if a.ended.is_some() {
            return Err(AssignError::Conflict(format!("assignment {id} has ended")));
        }
        let slot = a
            .slots
            .iter_mut()
            .find(|s| s.vehicle == vehicle)
            .ok_or_else(|| {
                AssignError::NotFound(format!("vehicle {vehicle} is not in assignment {id}"))
            })?;
        if !slot.is_out() {
            return Err(AssignError::Conflict(format!(
                "vehicle {vehicle} is in its slot of assignment {id} ({})",
                serde_json::to_value(slot.state)
                    .ok()
                    .and_then(|v| v.as_str().map(str::to_owned))
                    .unwrap_or_default()
            )));
        }
        *slot = Slot::new(vehicle);
        tracing::info!(
            vehicle,
            assignment = id,
            "guidance: the operator resumed the vehicle"
        );
        self.metrics.resumed.fetch_add(1, Ordering::Relaxed);
        let view = a.view();
        let _ = self.events.send(view.clone());
        Ok(view)
    }

    fn create(&mut self, r: &AssignmentRequest) -> Result<AssignmentView, AssignError> {
        let vehicles = self.link.vehicles.borrow().clone();
        let personalities: Vec<Personality> = r
            .vehicles
            .iter()
            .map(|&id| personality_of(&vehicles, id))
            .collect();
        let plan = r
            .plan(&self.settings, &personalities)
            .map_err(AssignError::Invalid)?;
        for id in &r.vehicles {
            if !vehicles.iter().any(|s| s.view.id == *id) {
                return Err(AssignError::NotFound(format!("no vehicle {id}")));
            }
            if let Some(a) = self.assignments.values().find(|a| {
                a.ended.is_none() && a.slots.iter().any(|s| s.vehicle == *id && !s.is_out())
            }) {
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
            plan,
            created_unix: unix_now(),
            ended: None,
            formation: FormationState::default(),
            slots: r
                .vehicles
                .iter()
                .map(|&vehicle| Slot::new(vehicle))
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
            let camera = a.plan.law == Law::HandoffCamera;
            // Only the vehicles it flies now: not a lost or waiting one, nor one that is out
            // (failed: already sent to Hold; overridden: someone else's).
            let holds: Vec<u8> = a
                .slots
                .iter_mut()
                .filter(|s| s.is_flown())
                .map(|s| {
                    s.state = SlotState::Hold;
                    s.sequence = None;
                    s.vehicle
                })
                .collect();
            let view = a.view();
            for v in holds {
                if camera {
                    // The camera is released; the vehicle flies on as it was.
                    let none = command_long(v, MavCmd::MAV_CMD_DO_SET_ROI_NONE, [0.0; 7]);
                    self.send(v, none);
                } else {
                    self.hold(v);
                }
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
                    s.state = SlotState::Failed;
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

    /// One tick of the loop: every active assignment flown on the latest snapshot and vehicle
    /// states, then what that decided done, and the assignments published.
    fn on_tick(&mut self, now: Instant) {
        self.metrics.ticks.fetch_add(1, Ordering::Relaxed);
        if self.assignments.values().all(|a| a.ended.is_some()) {
            return;
        }
        let snapshot = self.snapshot.borrow().clone();
        let vehicles = Arc::clone(&self.link.vehicles.borrow());
        let tick = Tick {
            t: self.t(now),
            since_snapshot: now
                .saturating_duration_since(self.snapshot_at)
                .as_secs_f64(),
            snapshot: &snapshot,
            vehicles: &vehicles,
            settings: &self.settings,
        };
        let mut decisions = Decisions::default();
        for a in self.assignments.values_mut().filter(|a| a.ended.is_none()) {
            tick.fly(a, &mut decisions);
        }
        self.carry_out(decisions);
        self.publish();
    }

    /// An update of the tracks: every camera hand-off points its vehicles at its track's new
    /// estimate, at once.
    fn on_tracks(&mut self) {
        let now = Instant::now();
        self.snapshot_at = now;
        let t = self.t(now);
        let snapshot = self.snapshot.borrow().clone();
        let vehicles = Arc::clone(&self.link.vehicles.borrow());
        let frame = self.settings.frame;
        let mut send = Vec::new();
        for a in self
            .assignments
            .values_mut()
            .filter(|a| a.ended.is_none() && a.plan.law == Law::HandoffCamera)
        {
            let Some(track) = snapshot.tracks.iter().find(|k| k.id == a.track) else {
                continue;
            };
            let target = predict(track, snapshot.t.unwrap_or(track.t));
            for slot in a.slots.iter_mut().filter(|s| !s.is_out()) {
                if let Some(v) = vehicles
                    .iter()
                    .find(|v| v.view.id == slot.vehicle && v.confirmed)
                {
                    let msgs = slot.handoff.roi(t, track.t, v, &target, &frame);
                    send.extend(msgs.into_iter().map(|m| (slot.vehicle, m)));
                }
            }
        }
        for (v, m) in send {
            self.send(v, m);
        }
    }

    /// Does what a tick decided: sends the messages (counting the setpoints), sends vehicles to
    /// Hold, ends assignments, and announces the assignments whose vehicles changed state.
    fn carry_out(&mut self, d: Decisions) {
        let setpoints = d.send.iter().filter(|(_, m)| is_setpoint(m)).count() as u64;
        for (vehicle, m) in d.send {
            self.send(vehicle, m);
        }
        self.metrics
            .setpoints
            .fetch_add(setpoints, Ordering::Relaxed);
        for v in d.hold {
            self.hold(v);
        }
        for by in d.overridden {
            self.metrics.overridden(by);
        }
        for v in d.rtl {
            self.return_home(v);
        }
        self.metrics.safety(d.clipped, d.fenced_out);
        for (id, reason) in d.end {
            self.end(id, reason);
        }
        let mut changed = d.changed;
        changed.dedup();
        for id in changed {
            if let Some(a) = self.assignments.get(&id) {
                let _ = self.events.send(a.view());
            }
        }
    }

    fn publish(&self) {
        let views: Vec<AssignmentView> = self.assignments.values().map(Assignment::view).collect();
        self.watch.send_replace(Arc::new(views));
    }
}

/// The personality of vehicle `id` from its last HEARTBEAT (a PX4 multirotor before one).
fn personality_of(vehicles: &[VehicleSample], id: u8) -> Personality {
    vehicles
        .iter()
        .find(|v| v.view.id == id)
        .and_then(|v| v.status)
        .map_or(Personality::PX4_MULTIROTOR, |s| s.personality)
}

/// Whether a message steers a vehicle: an offboard setpoint or GUIDED target, or ArduPlane's
/// course command.
fn is_setpoint(m: &MavMessage) -> bool {
    match m {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(_) => true,
        MavMessage::COMMAND_INT(c) => c.command == MavCmd::MAV_CMD_GUIDED_CHANGE_HEADING,
        _ => false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn prediction_is_bounded() {
        let track = TrackView {
            id: 1,
            status: harrier_engine::TrackStatus::Confirmed,
            t: 100.0,
            state: [0.0, 0.0, 0.0, 2.0, -1.0, 0.0],
            cov: Vec::new(),
            cov_dims: Vec::new(),
            updated: true,
            age: 3,
            last_update: 100.0,
            mode_probabilities: Vec::new(),
            existence: None,
        };
        let e = predict(&track, 100.5);
        assert_eq!(e.position, Vector3::new(1.0, -0.5, 0.0));
        // Far ahead: at most MAX_PREDICTION_S; behind or non-finite: the estimate as is.
        assert_eq!(predict(&track, 1e9).position.x, 2.0 * MAX_PREDICTION_S);
        assert_eq!(predict(&track, 0.0).position.x, 0.0);
        assert_eq!(predict(&track, f64::NAN).position.x, 0.0);
    }
}
