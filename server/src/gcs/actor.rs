//! The link actor ([`start`]): it owns the vehicle table, the pending commands, the `.tlog`
//! and the signer, and handles the endpoints' frames, the requests and a tick at
//! [`PUBLISH_HZ`] (see the `gcs` module's documentation).

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use harrier_link::mavlink::dialects::common::{
    HEARTBEAT_DATA, MavAutopilot, MavCmd, MavMessage, MavModeFlag, MavResult, MavState, MavType,
    TIMESYNC_DATA,
};
use harrier_link::mavlink::{MavHeader, Message};
use harrier_link::signing::{Rejection, Signer, Signing};
use tokio::sync::{broadcast, mpsc, oneshot, watch};

use super::filter::{Direction, FilterSpec, FrameKey, RouterFilter};
use super::handle::GcsLink;
use super::messages::{
    CommandError, CommandOutcome, CommandResult, GcsConfig, GcsError, LinkEvent, LinkEventKind,
    PUBLISH_HZ, Request, VehicleSample,
};
use super::metrics::LinkMetrics;
use super::timesync;
use super::tlog::Tlog;
use super::transport::{self, EndpointHandle, Inbound, Outbound, Peer, stopped};
use super::vehicle::{ClientCommand, LinkState, VehicleLink};
use crate::clock::unix_now;

/// A command waiting for its ACK.
#[derive(Debug)]
struct Pending {
    vehicle: u8,
    command: MavCmd,
    message: MavMessage,
    attempts: u32,
    first_sent: Instant,
    sent_at: Instant,
    reply: oneshot::Sender<Result<CommandOutcome, CommandError>>,
}

/// A COMMAND_LONG's MAV_CMD name.
fn command_name(c: MavCmd) -> String {
    format!("{c:?}")
}

/// Whether a message of the ground station's commands a vehicle: a command, a mode request, a
/// setpoint (not its HEARTBEAT, TIMESYNC or parameter traffic).
#[allow(deprecated)] // SET_MODE: superseded, still sent by older clients.
fn steers(m: &MavMessage) -> bool {
    matches!(
        m,
        MavMessage::COMMAND_LONG(_)
            | MavMessage::COMMAND_INT(_)
            | MavMessage::SET_MODE(_)
            | MavMessage::SET_POSITION_TARGET_LOCAL_NED(_)
            | MavMessage::SET_POSITION_TARGET_GLOBAL_INT(_)
            | MavMessage::SET_ATTITUDE_TARGET(_)
            | MavMessage::FOLLOW_TARGET(_)
    )
}

/// What a client's message asks of a vehicle's flight, if anything: a command's name,
/// `SET_MODE`, `RC override` (RC_CHANNELS_OVERRIDE, MANUAL_CONTROL).
#[allow(deprecated)] // SET_MODE: superseded, still sent by older clients (pymavlink's APM path).
fn client_command(m: &MavMessage) -> Option<String> {
    match m {
        MavMessage::COMMAND_LONG(c) => Some(command_name(c.command)),
        MavMessage::COMMAND_INT(c) => Some(command_name(c.command)),
        MavMessage::SET_MODE(_) => Some("SET_MODE".into()),
        MavMessage::RC_CHANNELS_OVERRIDE(_) | MavMessage::MANUAL_CONTROL(_) => {
            Some("RC override".into())
        }
        _ => None,
    }
}

/// The actor's state.
struct Actor {
    config: GcsConfig,
    endpoints: Vec<EndpointHandle>,
    vehicles: BTreeMap<u8, VehicleLink>,
    pending: Vec<Pending>,
    sequence: u8,
    epoch: Instant,
    metrics: Arc<LinkMetrics>,
    events: broadcast::Sender<LinkEvent>,
    acks: broadcast::Sender<(u8, MavMessage)>,
    watch: watch::Sender<Arc<Vec<VehicleSample>>>,
    tlog: Option<Tlog>,
    last_heartbeat: Option<Instant>,
    /// The TIMESYNC requests sent lately.
    timesync: timesync::Requests,
    /// Last (armed, mode) per vehicle, for the events.
    flight: HashMap<u8, (bool, Option<String>)>,
    /// Signs the ground station's frames (the endpoints check the incoming ones).
    signer: Option<Arc<Signer>>,
    /// Last log line about refused frames per (GCS side, reason), and the refusals since.
    reject_log: HashMap<(bool, Rejection), (Instant, u64)>,
    /// Each router endpoint's filter, in the order of the router endpoints.
    filters: Vec<RouterFilter>,
}

/// Shortest time between two log lines about refused frames of one side and reason.
const REJECT_LOG_EVERY: Duration = Duration::from_secs(5);

/// Opens every endpoint and starts the actor.
pub async fn start(
    config: GcsConfig,
    stop: watch::Receiver<bool>,
) -> Result<(GcsLink, tokio::task::JoinHandle<()>), GcsError> {
    let (inbound_tx, inbound_rx) = mpsc::channel(4096);
    let signer = config
        .signing
        .as_ref()
        .and_then(Signing::signer)
        .map(Arc::new);
    if let Some(s) = &config.signing {
        tracing::info!(mode = %s.mode, link_id = s.link_id, "mavlink signing");
    }
    let mut endpoints = Vec::new();
    for (i, e) in config.gcs.iter().chain(&config.router).enumerate() {
        let h = transport::open(i, *e, inbound_tx.clone(), stop.clone(), signer.clone())
            .await
            .map_err(|source| GcsError::Open {
                endpoint: *e,
                source,
            })?;
        tracing::info!(endpoint = %h.endpoint, role = if i < config.gcs.len() { "gcs" } else { "router" }, "mavlink endpoint open");
        endpoints.push(h);
    }
    drop(inbound_tx);
    let tlog = match &config.tlog {
        Some(path) => Some(Tlog::create(path).map_err(|source| GcsError::Tlog {
            path: path.clone(),
            source,
        })?),
        None => None,
    };
    let (requests, requests_rx) = mpsc::channel(1024);
    let (watch_tx, watch_rx) = watch::channel(Arc::new(Vec::new()));
    let (events, _) = broadcast::channel(256);
    let (acks, _) = broadcast::channel(256);
    let metrics = Arc::new(LinkMetrics::default());
    let epoch = Instant::now();
    let link = GcsLink {
        requests,
        vehicles: watch_rx,
        events: events.clone(),
        acks: acks.clone(),
        endpoints: endpoints.clone(),
        gcs_endpoints: config.gcs.len(),
        metrics: Arc::clone(&metrics),
        epoch,
    };
    let open = FilterSpec::default();
    let filters = (0..config.router.len())
        .map(|i| RouterFilter::new(config.router_filters.get(i).unwrap_or(&open)))
        .collect();
    let actor = Actor {
        filters,
        config,
        endpoints,
        vehicles: BTreeMap::new(),
        pending: Vec::new(),
        sequence: 0,
        epoch,
        metrics,
        events,
        acks,
        watch: watch_tx,
        tlog,
        last_heartbeat: None,
        timesync: timesync::Requests::default(),
        flight: HashMap::new(),
        signer,
        reject_log: HashMap::new(),
    };
    let task = tokio::spawn(actor.run(inbound_rx, requests_rx, stop));
    Ok((link, task))
}

impl Actor {
    async fn run(
        mut self,
        mut inbound: mpsc::Receiver<Inbound>,
        mut requests: mpsc::Receiver<Request>,
        mut stop: watch::Receiver<bool>,
    ) {
        let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / PUBLISH_HZ));
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                Some(i) = inbound.recv() => self.on_inbound(i),
                Some(r) = requests.recv() => self.on_request(r),
                _ = tick.tick() => self.on_tick(Instant::now()),
                () = stopped(&mut stop) => break,
            }
        }
        for p in self.pending.drain(..) {
            let _ = p.reply.send(Err(CommandError::Stopped));
        }
    }

    fn log(&self, bytes: &[u8]) {
        if let Some(t) = &self.tlog
            && !t.append((unix_now() * 1e6) as u64, bytes)
        {
            self.metrics.tlog_dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    fn is_gcs(&self, endpoint: usize) -> bool {
        endpoint < self.config.gcs.len()
    }

    fn on_inbound(&mut self, i: Inbound) {
        let gcs = self.is_gcs(i.endpoint);
        if i.parsed.malformed > 0 {
            let c = if gcs {
                &self.metrics.malformed_gcs
            } else {
                &self.metrics.malformed_router
            };
            c.fetch_add(i.parsed.malformed, Ordering::Relaxed);
        }
        for r in &i.rejected {
            self.metrics.reject(gcs, r.reason);
            self.log_rejected(gcs, i.peer, r);
        }
        for f in i.parsed.frames {
            self.log(&f.bytes);
            if gcs {
                self.metrics.frames_in.fetch_add(1, Ordering::Relaxed);
                self.on_vehicle_frame(i.endpoint, i.peer, i.at, &f);
            } else {
                self.on_client_frame(i.endpoint - self.config.gcs.len(), i.peer, i.at, &f);
            }
        }
    }

    /// Logs a refused frame, at most once per [`REJECT_LOG_EVERY`] per side and reason.
    fn log_rejected(&mut self, gcs: bool, peer: Peer, r: &transport::Rejected) {
        let now = Instant::now();
        match self.reject_log.get_mut(&(gcs, r.reason)) {
            Some((at, suppressed)) if now.duration_since(*at) < REJECT_LOG_EVERY => {
                *suppressed += 1;
            }
            entry => {
                let suppressed = entry.map_or(0, |(_, s)| *s);
                tracing::warn!(
                    side = if gcs { "gcs" } else { "router" },
                    reason = r.reason.as_str(),
                    %peer,
                    system_id = r.system_id,
                    component_id = r.component_id,
                    suppressed,
                    "refused a MAVLink frame (signing)"
                );
                self.reject_log.insert((gcs, r.reason), (now, 0));
            }
        }
    }

    fn on_vehicle_frame(
        &mut self,
        endpoint: usize,
        peer: Peer,
        at: Instant,
        f: &harrier_link::frame::Frame,
    ) {
        let id = u8::try_from(f.header.system_id)
            .ok()
            .filter(|&id| id != 0 && id != self.config.system_id);
        if let Some(id) = id
            && self.impostor(id, endpoint, peer, at)
        {
            return;
        }
        // Every vehicle frame goes to every client its endpoint's filter lets it through to,
        // unchanged (an impostor's goes nowhere).
        let routed = self.send_to_clients(&Arc::from(f.bytes.as_slice()), at);
        self.metrics
            .routed_to_clients
            .fetch_add(routed, Ordering::Relaxed);
        let Some(id) = id else {
            return;
        };
        let t = at.duration_since(self.epoch).as_secs_f64();
        let is_vehicle_heartbeat =
            matches!(&f.message, MavMessage::HEARTBEAT(hb) if hb.mavtype != MavType::MAV_TYPE_GCS);
        let v = match self.vehicles.get_mut(&id) {
            Some(v) => v,
            None if is_vehicle_heartbeat => {
                tracing::info!(vehicle = id, %peer, "vehicle connected");
                self.event(id, LinkEventKind::Connected, None);
                self.vehicles
                    .entry(id)
                    .or_insert_with(|| VehicleLink::new(id, endpoint, peer, at))
            }
            None => return,
        };
        if v.on_frame(&f.header, &f.message, at, t) {
            tracing::info!(vehicle = id, "vehicle recovered");
            self.event(id, LinkEventKind::Recovered, None);
        }
        match &f.message {
            MavMessage::HEARTBEAT(_) => self.flight_events(id),
            MavMessage::COMMAND_ACK(ack) => {
                let _ = self.acks.send((id, f.message.clone()));
                self.on_ack(id, ack.command, ack.result, at);
            }
            MavMessage::TIMESYNC(t) => self.on_timesync(id, t.tc1, t.ts1),
            _ => {}
        }
    }

    /// Whether a frame of system `id` from `peer` of `endpoint` at `now` is an impostor's
    /// (gcs::identity): another address than the vehicle's while the vehicle is connected. Its
    /// frames are counted and go nowhere; a new conflict is logged and announced. A lost vehicle
    /// heard from a new address moves there, unconfirmed.
    fn impostor(&mut self, id: u8, endpoint: usize, peer: Peer, now: Instant) -> bool {
        let Some(v) = self.vehicles.get_mut(&id) else {
            return false;
        };
        if (v.endpoint, v.peer) == (endpoint, peer) {
            return false;
        }
        if v.state() == LinkState::Lost {
            let previous = v.peer;
            v.moved(endpoint, peer);
            // It may have been quarantined as an impostor while the vehicle was still heard.
            let _ = self.endpoints[endpoint]
                .tx
                .try_send(Outbound::Quarantine(peer, false));
            tracing::warn!(
                vehicle = id,
                %previous,
                %peer,
                "vehicle heard again from a new address: not commanded by the guidance until \
                 the operator accepts it (POST /api/v1/vehicles/{id}/accept)"
            );
            let detail = format!("heard again from {peer}, was {previous}");
            self.event_detail(id, LinkEventKind::Moved, detail);
            return false;
        }
        self.metrics.impostor_frames.fetch_add(1, Ordering::Relaxed);
        if v.identity.impostor(peer, now) {
            let own = v.peer;
            // Nothing goes to it, not even the ground station's HEARTBEAT to every peer.
            let _ = self.endpoints[endpoint]
                .tx
                .try_send(Outbound::Quarantine(peer, true));
            self.metrics
                .identity_conflicts
                .fetch_add(1, Ordering::Relaxed);
            tracing::error!(
                vehicle = id,
                vehicle_address = %own,
                impostor = %peer,
                "a second source claims system id {id}: its frames are refused and nothing is \
                 sent to it"
            );
            let detail = format!("{peer} claims system id {id}, which {own} holds");
            self.event_detail(id, LinkEventKind::Conflict, detail);
        }
        true
    }

    /// A vehicle's answer to one of the link's TIMESYNC requests feeds its estimate; a request
    /// of its own is answered with the server's clock.
    fn on_timesync(&mut self, id: u8, tc1: i64, ts1: i64) {
        let now = timesync::now_ns(unix_now());
        if tc1 == 0 {
            let reply = MavMessage::TIMESYNC(TIMESYNC_DATA { tc1: now, ts1 });
            self.send_to(id, &reply);
        } else if self.timesync.sent(ts1)
            && let Some(v) = self.vehicles.get_mut(&id)
        {
            v.timesync.answer(tc1, ts1, now);
        }
    }

    fn flight_events(&mut self, id: u8) {
        let Some(v) = self.vehicles.get(&id) else {
            return;
        };
        let Some(s) = v.status() else { return };
        let mode = v.mode();
        let now = (s.armed, mode.clone());
        let before = self.flight.insert(id, now);
        match before {
            Some((armed, m)) => {
                if armed != s.armed {
                    let event = if s.armed {
                        LinkEventKind::Armed
                    } else {
                        LinkEventKind::Disarmed
                    };
                    self.event(id, event, mode.clone());
                }
                if m != mode {
                    self.event(id, LinkEventKind::Mode, mode);
                }
            }
            None => self.event(id, LinkEventKind::Mode, mode),
        }
    }

    fn event(&self, vehicle: u8, event: LinkEventKind, mode: Option<String>) {
        let _ = self.events.send(LinkEvent {
            vehicle,
            event,
            mode,
            time_unix: unix_now(),
            detail: None,
        });
    }

    fn event_detail(&self, vehicle: u8, event: LinkEventKind, detail: String) {
        let _ = self.events.send(LinkEvent {
            vehicle,
            event,
            mode: None,
            time_unix: unix_now(),
            detail: Some(detail),
        });
    }

    /// A frame from client `peer` of router endpoint `router` (its index among the router's),
    /// received at `at`: to its target vehicle, or to every vehicle, when the endpoint's incoming
    /// filter lets it through. A command to one vehicle is remembered as its last client command.
    fn on_client_frame(
        &mut self,
        router: usize,
        peer: Peer,
        at: Instant,
        f: &harrier_link::frame::Frame,
    ) {
        self.metrics
            .frames_from_clients
            .fetch_add(1, Ordering::Relaxed);
        let key = FrameKey {
            system: f.header.system_id,
            component: f.header.component_id,
            message: f.message.message_id(),
        };
        if let Err(why) = self.filters[router].check_incoming(key) {
            let e = &self.endpoints[self.config.gcs.len() + router];
            e.counters.filtered[Direction::In as usize][why as usize]
                .fetch_add(1, Ordering::Relaxed);
            return;
        }
        let bytes: Arc<[u8]> = Arc::from(f.bytes.as_slice());
        if let (Some(t), Some(command)) = (f.target_system(), client_command(&f.message))
            && let Some(v) = self.vehicles.get_mut(&t)
        {
            let endpoint = &self.endpoints[self.config.gcs.len() + router].endpoint;
            v.client_command = Some(ClientCommand {
                at: at.duration_since(self.epoch).as_secs_f64(),
                command,
                from: format!("router {endpoint}, client {peer}"),
            });
        }
        let targets: Vec<&VehicleLink> = match f.target_system() {
            Some(t) => match self.vehicles.get(&t) {
                Some(v) => vec![v],
                None => {
                    self.metrics.unroutable.fetch_add(1, Ordering::Relaxed);
                    return;
                }
            },
            None => self.vehicles.values().collect(),
        };
        for v in targets {
            let e = &self.endpoints[v.endpoint];
            if e.tx
                .try_send(Outbound::To(v.peer, Arc::clone(&bytes)))
                .is_ok()
            {
                self.metrics
                    .routed_to_vehicles
                    .fetch_add(1, Ordering::Relaxed);
            } else {
                e.counters.send_dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
    }

    /// Queues `bytes` for every router endpoint whose filter lets them through at `now` (counting
    /// the filtered and the dropped frames); the number queued.
    fn send_to_clients(&mut self, bytes: &Arc<[u8]>, now: Instant) -> u64 {
        let mut queued = 0;
        let router = &self.endpoints[self.config.gcs.len()..];
        for (e, filter) in router.iter().zip(&mut self.filters) {
            if let Err(why) = filter.check(bytes, now) {
                e.counters.filtered[Direction::Out as usize][why as usize]
                    .fetch_add(1, Ordering::Relaxed);
            } else if e.tx.try_send(Outbound::All(Arc::clone(bytes))).is_ok() {
                queued += 1;
            } else {
                e.counters.send_dropped.fetch_add(1, Ordering::Relaxed);
            }
        }
        queued
    }

    /// Serialises `msg` as the ground station's next frame (signed when signing is on).
    fn frame(&mut self, msg: &MavMessage) -> Option<Arc<[u8]>> {
        let header = MavHeader {
            system_id: self.config.system_id.into(),
            component_id: self.config.component_id,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let buf = match &self.signer {
            Some(s) => s.encode(header, msg)?,
            None => harrier_link::frame::encode(header, msg)?,
        };
        self.log(&buf);
        Some(Arc::from(buf))
    }

    fn send_to(&mut self, vehicle: u8, msg: &MavMessage) -> bool {
        let Some((endpoint, peer)) = self.vehicles.get(&vehicle).map(|v| (v.endpoint, v.peer))
        else {
            return false;
        };
        let Some(bytes) = self.frame(msg) else {
            return false;
        };
        let e = &self.endpoints[endpoint];
        if e.tx.try_send(Outbound::To(peer, bytes)).is_ok() {
            self.metrics.frames_out.fetch_add(1, Ordering::Relaxed);
            if steers(msg)
                && let Some(v) = self.vehicles.get_mut(&vehicle)
            {
                v.commands_sent += 1;
            }
            true
        } else {
            e.counters.send_dropped.fetch_add(1, Ordering::Relaxed);
            false
        }
    }

    fn on_request(&mut self, r: Request) {
        match r {
            Request::Send { vehicle, message } => {
                self.send_to(vehicle, &message);
            }
            Request::Accept { vehicle, reply } => {
                let answer = match self.vehicles.get_mut(&vehicle) {
                    None => Err(CommandError::UnknownVehicle(vehicle)),
                    Some(v) => Ok(v.identity.accept()),
                };
                if answer == Ok(true) {
                    tracing::info!(vehicle, "the operator accepted the vehicle's new address");
                    self.event(vehicle, LinkEventKind::Accepted, None);
                }
                let _ = reply.send(answer);
            }
            Request::ToClients(messages) => {
                for m in &messages {
                    let Some(bytes) = self.frame(m) else { continue };
                    self.send_to_clients(&bytes, Instant::now());
                    self.metrics.track_messages.fetch_add(1, Ordering::Relaxed);
                }
            }
            Request::Command {
                vehicle,
                message,
                reply,
            } => {
                let MavMessage::COMMAND_LONG(c) = &message else {
                    let _ = reply.send(Err(CommandError::NotACommand));
                    return;
                };
                let command = c.command;
                let now = Instant::now();
                let err = match self.vehicles.get(&vehicle) {
                    None => Some(CommandError::UnknownVehicle(vehicle)),
                    Some(v) if v.state() == LinkState::Lost => Some(CommandError::Lost(
                        vehicle,
                        v.view(&self.config.frame, now).last_seen_s,
                    )),
                    Some(_)
                        if self
                            .pending
                            .iter()
                            .any(|p| p.vehicle == vehicle && p.command == command) =>
                    {
                        Some(CommandError::Busy(vehicle, command_name(command)))
                    }
                    Some(_) => None,
                };
                if let Some(e) = err {
                    let _ = reply.send(Err(e));
                    return;
                }
                self.metrics.commands.fetch_add(1, Ordering::Relaxed);
                self.send_to(vehicle, &message);
                self.pending.push(Pending {
                    vehicle,
                    command,
                    message,
                    attempts: 1,
                    first_sent: now,
                    sent_at: now,
                    reply,
                });
            }
        }
    }

    fn on_ack(&mut self, vehicle: u8, command: MavCmd, result: MavResult, at: Instant) {
        let Some(i) = self
            .pending
            .iter()
            .position(|p| p.vehicle == vehicle && p.command == command)
        else {
            return;
        };
        if result == MavResult::MAV_RESULT_IN_PROGRESS {
            self.pending[i].sent_at = at;
            return;
        }
        let p = self.pending.swap_remove(i);
        let outcome = CommandResult::from(result);
        self.metrics.result(outcome);
        let _ = p.reply.send(Ok(CommandOutcome {
            vehicle,
            command: command_name(command),
            ok: outcome == CommandResult::Accepted,
            result: outcome,
            attempts: p.attempts,
            elapsed_ms: at.duration_since(p.first_sent).as_secs_f64() * 1e3,
        }));
    }

    fn on_tick(&mut self, now: Instant) {
        let lost_after = self.config.lost_after.as_secs_f64();
        let mut lost = Vec::new();
        for (id, v) in &mut self.vehicles {
            if v.check(now, lost_after) {
                lost.push(*id);
            }
            if let Some((impostor, frames)) = v.identity.expire(now, lost_after) {
                for e in &self.endpoints[..self.config.gcs.len()] {
                    let _ = e.tx.try_send(Outbound::Quarantine(impostor, false));
                }
                tracing::warn!(
                    vehicle = id,
                    %impostor,
                    frames,
                    "the second source claiming this system id fell silent"
                );
            }
        }
        // Commands: re-send after the timeout, give up after the last attempt.
        let timeout = self.config.command_timeout;
        let mut i = 0;
        while i < self.pending.len() {
            if now.duration_since(self.pending[i].sent_at) < timeout {
                i += 1;
                continue;
            }
            if self.pending[i].attempts >= self.config.command_attempts {
                let p = self.pending.swap_remove(i);
                self.metrics.result(CommandResult::Timeout);
                let _ = p.reply.send(Ok(CommandOutcome {
                    vehicle: p.vehicle,
                    command: command_name(p.command),
                    result: CommandResult::Timeout,
                    ok: false,
                    attempts: p.attempts,
                    elapsed_ms: now.duration_since(p.first_sent).as_secs_f64() * 1e3,
                }));
                continue;
            }
            let p = &mut self.pending[i];
            p.attempts += 1;
            p.sent_at = now;
            if let MavMessage::COMMAND_LONG(c) = &mut p.message {
                c.confirmation = c.confirmation.saturating_add(1);
            }
            let (vehicle, message) = (p.vehicle, p.message.clone());
            self.metrics.command_retries.fetch_add(1, Ordering::Relaxed);
            self.send_to(vehicle, &message);
            i += 1;
        }
        // The ground station's HEARTBEAT, 1 Hz, to every vehicle.
        if self
            .last_heartbeat
            .is_none_or(|t| now.duration_since(t) >= Duration::from_secs(1))
        {
            self.last_heartbeat = Some(now);
            let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
                custom_mode: 0,
                mavtype: MavType::MAV_TYPE_GCS,
                autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
                base_mode: MavModeFlag::empty(),
                system_status: MavState::MAV_STATE_ACTIVE,
                mavlink_version: 3,
            });
            if let Some(bytes) = self.frame(&hb) {
                // To the vehicles; to the router's clients only when configured (their scripts'
                // `wait_heartbeat()` would take the ground station for a vehicle), through
                // their filters.
                for e in &self.endpoints[..self.config.gcs.len()] {
                    let _ = e.tx.try_send(Outbound::All(Arc::clone(&bytes)));
                }
                if self.config.router_heartbeat {
                    self.send_to_clients(&bytes, now);
                }
                self.metrics.heartbeats.fetch_add(1, Ordering::Relaxed);
            }
            // And a TIMESYNC request to each vehicle (only to them: not to router clients).
            let request = self.timesync.request(timesync::now_ns(unix_now()));
            let ids: Vec<u8> = self.vehicles.keys().copied().collect();
            for id in ids {
                self.send_to(id, &request);
            }
        }
        let unix = unix_now();
        let samples: Vec<VehicleSample> = self
            .vehicles
            .values()
            .map(|v| VehicleSample {
                view: v.view(&self.config.frame, now),
                status: v.status(),
                home_amsl: v.home_amsl(),
                gimbal_manager: v.gimbal_manager(),
                position_unix: v.position_age(now).map(|age| unix - age),
                confirmed: v.identity.confirmed(),
                client_command: v.client_command.clone(),
            })
            .collect();
        self.watch.send_replace(Arc::new(samples));
        // After the watch shows them lost.
        for id in lost {
            tracing::warn!(vehicle = id, "vehicle lost (silent {lost_after} s)");
            self.metrics.vehicles_lost.fetch_add(1, Ordering::Relaxed);
            self.event(id, LinkEventKind::Lost, None);
        }
    }
}
