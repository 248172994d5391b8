//! MAVLink links over UDP and TCP, and the threads that run vehicles on them.
//!
//! A link is described by a connection string:
//!
//! - `udpin:HOST:PORT` binds a UDP socket and answers whoever sends to it (telemetry goes to every
//!   peer seen); `udpout:HOST:PORT` binds an ephemeral port and sends to HOST:PORT.
//! - `tcpin:HOST:PORT` listens and accepts any number of clients, each a peer that gets the
//!   telemetry from the moment it connects; `tcpout:HOST:PORT` connects to a server and reconnects
//!   (every [`TCP_RETRY`]) when the connection fails or drops, without ever blocking the
//!   simulation loop (the connect runs on a short-lived helper thread).
//!
//! Replies go back on the link, and to the peer (address or TCP connection), the request came
//! from, so a GCS and an API client never see each other's replies. Sockets are non-blocking. TCP
//! is a byte stream: each connection keeps a receive buffer and frames are parsed across reads
//! ([`StreamParser`]), so a frame split over several segments waits for its end.
//!
//! With [`LinkConfig::signing`] (MAVLink 2 signing, harrier-link's [`Signer`], one per vehicle
//! for all its links) every frame sent is signed, and every frame received is checked before the
//! vehicle sees it: a refused frame (unsigned in `signed_only` mode, wrong signature, replay) is
//! counted in [`Counters::rejected`](crate::vehicle::Counters::rejected) by reason, never handled,
//! and never makes its UDP sender a peer that gets telemetry. Refusals are logged on stderr at most
//! once per [`REJECT_LOG_EVERY`].

use std::io::{self, Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{Duration, Instant};

use mavlink::MavHeader;
use mavlink::dialects::common::{MavMessage, TIMESYNC_DATA};

pub use harrier_link::frame::{Endpoint, EndpointError, StreamParser};
use harrier_link::frame::{Frame, parse_datagram};
use harrier_link::px4::COMPONENT_ID;
pub use harrier_link::signing::{Rejection, Rejections, Signer, Signing};

use crate::vehicle::{ClockSkew, Vehicle, VehicleConfig};
use crate::worker::Worker;

/// Errors from setting up links.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The connection string is not one of the supported forms.
    #[error(transparent)]
    BadAddress(#[from] EndpointError),
    /// A socket operation failed.
    #[error("{what} {address}: {source}")]
    Io {
        /// What was attempted.
        what: &'static str,
        /// The connection string.
        address: String,
        /// The error.
        source: std::io::Error,
    },
}

/// Where a message came from, so that its replies go back there.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Peer {
    /// A UDP sender.
    Udp(SocketAddr),
    /// A TCP connection of the link, by its number.
    Tcp(u64),
}

/// Messages received from one peer in one poll.
#[derive(Debug)]
struct Received {
    from: Peer,
    messages: Vec<MavMessage>,
    /// Datagrams without a valid frame, skipped stretches of a stream, undecodable frames.
    malformed: u64,
    /// Frames refused by the signature check.
    rejected: Vec<Rejection>,
}

impl Received {
    fn new(from: Peer) -> Self {
        Self {
            from,
            messages: Vec::new(),
            malformed: 0,
            rejected: Vec::new(),
        }
    }

    /// Keeps the frames `signer` accepts (all of them without signing) and counts the others.
    fn take(&mut self, frames: Vec<Frame>, signer: Option<&Signer>) {
        for f in frames {
            match signer.map_or(Ok(()), |s| s.check(&f)) {
                Ok(()) => self.messages.push(f.message),
                Err(r) => self.rejected.push(r),
            }
        }
    }
}

/// Most bytes queued for a slow TCP peer; further frames to it are dropped (telemetry is lossy,
/// and a frame is never cut).
const MAX_TX_BACKLOG: usize = 256 * 1024;

/// Most reads from one TCP connection per poll (the rest waits for the next tick).
const MAX_TCP_READS: usize = 16;

/// One TCP connection: non-blocking stream, receive parser and send backlog.
#[derive(Debug)]
struct TcpConn {
    id: u64,
    stream: TcpStream,
    parser: StreamParser,
    backlog: Vec<u8>,
}

impl TcpConn {
    fn new(id: u64, stream: TcpStream) -> io::Result<Self> {
        stream.set_nonblocking(true)?;
        stream.set_nodelay(true)?;
        Ok(Self {
            id,
            stream,
            parser: StreamParser::default(),
            backlog: Vec::new(),
        })
    }

    /// Reads what is available (at most [`MAX_TCP_READS`] buffers, so that a flooding client
    /// cannot stall the loop); `None` when the connection is closed or broken.
    fn receive(&mut self, buf: &mut [u8], signer: Option<&Signer>) -> Option<Received> {
        let mut got = Received::new(Peer::Tcp(self.id));
        for _ in 0..MAX_TCP_READS {
            match self.stream.read(buf) {
                Ok(0) => return None,
                Ok(n) => {
                    let p = self.parser.push(&buf[..n]);
                    got.malformed += p.malformed;
                    got.take(p.frames, signer);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => break,
                Err(_) => return None,
            }
        }
        Some(got)
    }

    /// Queues a frame and writes as much of the backlog as the socket takes; `false` when the
    /// connection is broken.
    fn send(&mut self, frame: &[u8]) -> bool {
        if self.backlog.len() + frame.len() <= MAX_TX_BACKLOG {
            self.backlog.extend_from_slice(frame);
        }
        self.flush()
    }

    fn flush(&mut self) -> bool {
        while !self.backlog.is_empty() {
            match self.stream.write(&self.backlog) {
                Ok(0) => return false,
                Ok(n) => {
                    self.backlog.drain(..n);
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => return true,
                Err(_) => return false,
            }
        }
        true
    }
}

/// Wait between two connection attempts of a `tcpout` link.
pub const TCP_RETRY: Duration = Duration::from_secs(1);
/// Longest a `tcpout` connection attempt may take (on its helper thread).
const TCP_CONNECT_TIMEOUT: Duration = Duration::from_secs(3);

/// The sockets of a link.
#[derive(Debug)]
enum Transport {
    Udp {
        socket: UdpSocket,
        /// Fixed destination (udpout) or the peers seen so far (udpin).
        peers: Vec<SocketAddr>,
    },
    TcpIn {
        listener: TcpListener,
        clients: Vec<TcpConn>,
    },
    TcpOut {
        server: SocketAddr,
        conn: Option<TcpConn>,
        /// The connection attempt under way, on its helper thread.
        connecting: Option<Receiver<io::Result<TcpStream>>>,
        /// When the next attempt may start.
        retry_at: Instant,
    },
}

/// One link of a vehicle.
#[derive(Debug)]
pub struct Link {
    transport: Transport,
    sequence: u8,
    /// Number of the next TCP connection (replies find their connection by it).
    next_conn: u64,
    /// Signs what is sent and checks what is received (shared by the vehicle's links).
    signer: Option<Arc<Signer>>,
}

/// Most peers a udpin link remembers (the oldest is forgotten first).
const MAX_PEERS: usize = 8;

impl Link {
    /// Opens a link, signing with `signer` if given. A `tcpout` link starts connecting on the
    /// first poll.
    pub fn open(endpoint: &Endpoint, signer: Option<Arc<Signer>>) -> Result<Self, LinkError> {
        let io = |what, source| LinkError::Io {
            what,
            address: endpoint.to_string(),
            source,
        };
        let transport = match *endpoint {
            Endpoint::UdpIn(a) | Endpoint::UdpOut(a) => {
                let (bind, peers): (SocketAddr, Vec<SocketAddr>) = match endpoint {
                    Endpoint::UdpOut(_) => {
                        let any: SocketAddr = if a.is_ipv4() {
                            ([0, 0, 0, 0], 0).into()
                        } else {
                            (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                        };
                        (any, vec![a])
                    }
                    _ => (a, Vec::new()),
                };
                let socket = UdpSocket::bind(bind).map_err(|e| io("bind", e))?;
                socket
                    .set_nonblocking(true)
                    .map_err(|e| io("set_nonblocking", e))?;
                Transport::Udp { socket, peers }
            }
            Endpoint::TcpIn(a) => {
                let listener = TcpListener::bind(a).map_err(|e| io("listen", e))?;
                listener
                    .set_nonblocking(true)
                    .map_err(|e| io("set_nonblocking", e))?;
                Transport::TcpIn {
                    listener,
                    clients: Vec::new(),
                }
            }
            Endpoint::TcpOut(server) => Transport::TcpOut {
                server,
                conn: None,
                connecting: None,
                retry_at: Instant::now(),
            },
        };
        Ok(Self {
            transport,
            sequence: 0,
            next_conn: 0,
            signer,
        })
    }

    /// The bound local address (`None` for `tcpout`, whose connections come and go).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        match &self.transport {
            Transport::Udp { socket, .. } => socket.local_addr().ok(),
            Transport::TcpIn { listener, .. } => listener.local_addr().ok(),
            Transport::TcpOut { .. } => None,
        }
    }

    /// Serialises a message as the vehicle's next MAVLink 2 frame on this link (signed when the
    /// link signs).
    fn frame(&mut self, sysid: u8, msg: &MavMessage) -> Option<Vec<u8>> {
        let header = MavHeader {
            system_id: sysid.into(),
            component_id: COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        match &self.signer {
            Some(s) => s.encode(header, msg),
            None => harrier_link::frame::encode(header, msg),
        }
    }

    fn send(&mut self, sysid: u8, msg: &MavMessage, to: Peer) {
        let Some(frame) = self.frame(sysid, msg) else {
            return;
        };
        match (&mut self.transport, to) {
            (Transport::Udp { socket, .. }, Peer::Udp(addr)) => {
                // UDP is lossy by nature: a failed send (no listener yet) is not an error.
                let _ = socket.send_to(&frame, addr);
            }
            (Transport::TcpIn { clients, .. }, Peer::Tcp(id)) => {
                clients.retain_mut(|c| c.id != id || c.send(&frame));
            }
            (Transport::TcpOut { conn, retry_at, .. }, Peer::Tcp(id)) => {
                let broken = conn.as_mut().is_some_and(|c| c.id == id && !c.send(&frame));
                if broken {
                    *conn = None;
                    *retry_at = Instant::now() + TCP_RETRY;
                }
            }
            _ => {}
        }
    }

    fn broadcast(&mut self, sysid: u8, msg: &MavMessage) {
        let Some(frame) = self.frame(sysid, msg) else {
            return;
        };
        match &mut self.transport {
            Transport::Udp { socket, peers } => {
                for to in peers.iter() {
                    let _ = socket.send_to(&frame, to);
                }
            }
            Transport::TcpIn { clients, .. } => clients.retain_mut(|c| c.send(&frame)),
            Transport::TcpOut { conn, retry_at, .. } => {
                if conn.as_mut().is_some_and(|c| !c.send(&frame)) {
                    *conn = None;
                    *retry_at = Instant::now() + TCP_RETRY;
                }
            }
        }
    }

    /// Receives everything pending: one entry per UDP datagram (no messages when it held no valid
    /// frame) and per TCP connection. Accepts new TCP clients, drops closed connections and
    /// (re)connects `tcpout` links.
    fn poll(&mut self, buf: &mut [u8]) -> Vec<Received> {
        let mut out = Vec::new();
        let signer = self.signer.as_deref();
        match &mut self.transport {
            Transport::Udp { socket, peers } => {
                while let Ok((n, from)) = socket.recv_from(buf) {
                    let parsed = parse_datagram(&buf[..n]);
                    let mut got = Received::new(Peer::Udp(from));
                    got.malformed = parsed.malformed;
                    got.take(parsed.frames, signer);
                    // Only a sender of accepted frames gets the telemetry.
                    if !peers.contains(&from) && !got.messages.is_empty() {
                        if peers.len() >= MAX_PEERS {
                            peers.remove(0);
                        }
                        peers.push(from);
                    }
                    out.push(got);
                }
            }
            Transport::TcpIn { listener, clients } => {
                while let Ok((stream, _)) = listener.accept() {
                    if let Ok(c) = TcpConn::new(self.next_conn, stream) {
                        clients.push(c);
                    }
                    self.next_conn += 1;
                }
                clients.retain_mut(|c| match c.receive(buf, signer) {
                    Some(r) => {
                        out.push(r);
                        c.flush()
                    }
                    None => false,
                });
            }
            Transport::TcpOut {
                server,
                conn,
                connecting,
                retry_at,
            } => {
                if conn.is_none() {
                    *conn = Self::connect(*server, connecting, retry_at, &mut self.next_conn);
                }
                if let Some(c) = conn {
                    match c.receive(buf, signer) {
                        Some(r) if c.flush() => out.push(r),
                        _ => {
                            *conn = None;
                            *retry_at = Instant::now() + TCP_RETRY;
                        }
                    }
                }
            }
        }
        out
    }

    /// Advances a `tcpout` connection attempt without blocking: collects the result of the one
    /// under way, or starts one on a helper thread when it is time to.
    fn connect(
        server: SocketAddr,
        connecting: &mut Option<Receiver<io::Result<TcpStream>>>,
        retry_at: &mut Instant,
        next_conn: &mut u64,
    ) -> Option<TcpConn> {
        if let Some(rx) = connecting {
            let result = match rx.try_recv() {
                Err(TryRecvError::Empty) => return None,
                Ok(Ok(stream)) => {
                    *next_conn += 1;
                    TcpConn::new(*next_conn, stream).ok()
                }
                Ok(Err(_)) | Err(TryRecvError::Disconnected) => None,
            };
            *connecting = None;
            if result.is_none() {
                *retry_at = Instant::now() + TCP_RETRY;
            }
            return result;
        }
        if Instant::now() >= *retry_at {
            let (tx, rx) = mpsc::channel();
            let spawned = std::thread::Builder::new()
                .name("harrier-sim-connect".to_owned())
                .spawn(move || {
                    // The link may be gone by now: then nobody wants the result.
                    let _ = tx.send(TcpStream::connect_timeout(&server, TCP_CONNECT_TIMEOUT));
                });
            match spawned {
                Ok(_) => *connecting = Some(rx),
                Err(_) => *retry_at = Instant::now() + TCP_RETRY,
            }
        }
        None
    }
}

/// Links of one vehicle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkConfig {
    /// Connection strings, e.g. `udpout:127.0.0.1:14550` (GCS) and `udpin:0.0.0.0:14540` (API).
    pub endpoints: Vec<String>,
    /// MAVLink 2 signing on every link (`None`: off).
    pub signing: Option<Signing>,
}

impl LinkConfig {
    /// PX4 SITL-like defaults for vehicle `id`: GCS on `udpout:127.0.0.1:14550`, API on
    /// `udpin:0.0.0.0:{14540 + id - 1}`.
    pub fn px4_defaults(id: u8) -> Self {
        Self {
            endpoints: vec![
                "udpout:127.0.0.1:14550".to_owned(),
                format!("udpin:0.0.0.0:{}", 14540 + u16::from(id) - 1),
            ],
            signing: None,
        }
    }
}

/// A vehicle running on its own thread; stopped when dropped.
#[derive(Debug)]
pub struct SimHandle {
    vehicle: Arc<Mutex<Vehicle>>,
    local_addrs: Vec<Option<SocketAddr>>,
    worker: Worker,
}

impl SimHandle {
    /// The bound local address of each link, in the order of [`LinkConfig::endpoints`].
    pub fn local_addrs(&self) -> &[Option<SocketAddr>] {
        &self.local_addrs
    }
    /// Locks the vehicle (to inspect it; the simulation waits meanwhile).
    pub fn vehicle(&self) -> MutexGuard<'_, Vehicle> {
        self.vehicle.lock().unwrap_or_else(PoisonError::into_inner)
    }
    /// A shared reference to the vehicle (for other threads: the Zenoh sensor loop).
    pub fn shared(&self) -> Arc<Mutex<Vehicle>> {
        Arc::clone(&self.vehicle)
    }
    /// Stops the vehicle and waits for its thread.
    pub fn stop(mut self) {
        self.worker.stop();
    }
}

/// Wall-clock period of the simulation loop.
const TICK: Duration = Duration::from_millis(5);

/// Shortest time between two log lines about refused frames of one vehicle.
pub const REJECT_LOG_EVERY: Duration = Duration::from_secs(5);

/// Opens the links and runs a vehicle on a new thread.
pub fn spawn(config: VehicleConfig, links: &LinkConfig) -> Result<SimHandle, LinkError> {
    let signer = links
        .signing
        .as_ref()
        .and_then(Signing::signer)
        .map(Arc::new);
    let mut opened = links
        .endpoints
        .iter()
        .map(|e| Link::open(&Endpoint::parse(e)?, signer.clone()))
        .collect::<Result<Vec<_>, _>>()?;
    let local_addrs = opened.iter().map(Link::local_addr).collect();
    let start = Instant::now();
    let vehicle = Arc::new(Mutex::new(Vehicle::new(config, 0.0)));
    let v = Arc::clone(&vehicle);
    let mut buf = vec![0u8; 65_536];
    let mut log = RejectLog::default();
    let worker = Worker::spawn(format!("harrier-sim-{}", config.id), move || {
        {
            let mut v = v.lock().unwrap_or_else(PoisonError::into_inner);
            run_once(&mut v, &mut opened, &mut buf, start.elapsed().as_secs_f64());
            log.maybe_log(v.id(), v.counters().rejected, Instant::now());
        }
        std::thread::sleep(TICK);
    })
    .map_err(|e| LinkError::Io {
        what: "spawn thread for",
        address: links.endpoints.join(","),
        source: e,
    })?;
    Ok(SimHandle {
        vehicle,
        local_addrs,
        worker,
    })
}

/// Rate-limited log of refused frames: one line per [`REJECT_LOG_EVERY`] at most, with what was
/// refused since the last line.
#[derive(Debug, Default)]
struct RejectLog {
    logged: Rejections,
    at: Option<Instant>,
}

impl RejectLog {
    fn maybe_log(&mut self, id: u8, now_counts: Rejections, now: Instant) {
        if now_counts == self.logged || self.at.is_some_and(|t| now - t < REJECT_LOG_EVERY) {
            return;
        }
        let new = |r| now_counts.get(r) - self.logged.get(r);
        eprintln!(
            "harrier-sim: vehicle {id}: refused MAVLink frames: unsigned={} bad_signature={} replay={} (totals {} {} {})",
            new(Rejection::Unsigned),
            new(Rejection::BadSignature),
            new(Rejection::Replay),
            now_counts.unsigned,
            now_counts.bad_signature,
            now_counts.replay,
        );
        self.logged = now_counts;
        self.at = Some(now);
    }
}

/// The answer to a time-sync request (TIMESYNC with tc1 = 0): this vehicle's clock in ns, `now`
/// s after its start, as PX4 and ArduPilot answer it (theirs reads time since boot; this one
/// reads UNIX time, wrong by `clock`). `None` for every other message.
fn timesync_reply(clock: &ClockSkew, m: &MavMessage, now: f64) -> Option<MavMessage> {
    let MavMessage::TIMESYNC(t) = m else {
        return None;
    };
    if t.tc1 != 0 {
        return None;
    }
    let reading = harrier_link::clock::unix_now() + clock.offset_s + clock.drift_ppm * 1e-6 * now;
    Some(MavMessage::TIMESYNC(TIMESYNC_DATA {
        tc1: (reading * 1e9) as i64,
        ts1: t.ts1,
    }))
}

fn run_once(v: &mut Vehicle, links: &mut [Link], buf: &mut [u8], now: f64) {
    let sysid = v.id();
    for link in links.iter_mut() {
        for r in link.poll(buf) {
            for _ in 0..r.malformed {
                v.count_malformed();
            }
            for &reason in &r.rejected {
                v.count_rejected(reason);
            }
            for m in &r.messages {
                if let Some(reply) = timesync_reply(&v.config().clock, m, now) {
                    link.send(sysid, &reply, r.from);
                    continue;
                }
                for reply in v.handle(now, m) {
                    link.send(sysid, &reply, r.from);
                }
            }
        }
    }
    for m in v.telemetry(now) {
        for link in links.iter_mut() {
            link.broadcast(sysid, &m);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use harrier_link::signing::{SigningKey, SigningMode};
    use mavlink::dialects::common::{
        COMMAND_LONG_DATA, GLOBAL_POSITION_INT_DATA, MavCmd, MavResult, PARAM_REQUEST_READ_DATA,
    };
    use mavlink::{MavlinkReader, MessageData};

    fn gcs_frame(msg: &MavMessage, sequence: u8) -> Vec<u8> {
        let header = MavHeader {
            system_id: 255,
            component_id: 190,
            sequence,
        };
        harrier_link::frame::encode(header, msg).expect("serialise")
    }

    fn command(command: MavCmd, param1: f32, param2: f32) -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            param1,
            param2,
            command,
            target_system: 1,
            target_component: 1,
            ..COMMAND_LONG_DATA::DEFAULT
        })
    }

    /// A blocking TCP client of a test vehicle.
    struct Client(MavlinkReader<TcpStream>);

    impl Client {
        fn connect(addr: SocketAddr) -> Self {
            let stream = TcpStream::connect(addr).expect("connect");
            stream
                .set_read_timeout(Some(Duration::from_millis(100)))
                .expect("timeout");
            Self(MavlinkReader::new(stream))
        }
        fn write(&mut self, bytes: &[u8]) {
            self.0.get_mut().write_all(bytes).expect("write");
        }
        /// Reads messages until one satisfies `done` (within 5 s); returns all of them.
        fn read_until(&mut self, mut done: impl FnMut(&MavMessage) -> bool) -> Vec<MavMessage> {
            let deadline = Instant::now() + Duration::from_secs(5);
            let mut got = Vec::new();
            while Instant::now() < deadline {
                if let Ok((h, m)) = self.0.read_any_message::<MavMessage>() {
                    assert_eq!((h.system_id, h.component_id), (1, 1));
                    let stop = done(&m);
                    got.push(m);
                    if stop {
                        return got;
                    }
                }
            }
            panic!("no expected message within 5 s; got {got:?}");
        }
    }

    fn is_ack(m: &MavMessage, command: MavCmd) -> bool {
        matches!(m, MavMessage::COMMAND_ACK(a) if a.command == command)
    }

    /// Vehicle 1 with one link, `endpoint`, and that link's bound address.
    fn vehicle_on(endpoint: &str) -> (SimHandle, SocketAddr) {
        let sim = spawn(
            VehicleConfig::new(1),
            &LinkConfig {
                endpoints: vec![endpoint.to_owned()],
                signing: None,
            },
        )
        .expect("spawn");
        let addr = sim.local_addrs()[0].expect("bound");
        (sim, addr)
    }

    /// Returns once the simulation loop has run a whole tick after this call.
    fn wait_one_tick(sim: &SimHandle) {
        let t0 = sim.vehicle().sim_time();
        let deadline = Instant::now() + Duration::from_secs(5);
        while sim.vehicle().sim_time() == t0 {
            assert!(Instant::now() < deadline, "the simulation loop stalled");
            std::thread::yield_now();
        }
    }

    #[test]
    fn tcp_frames_split_over_two_writes_are_reassembled() {
        let (sim, addr) = vehicle_on("tcpin:127.0.0.1:0");
        let mut c = Client::connect(addr);
        // Telemetry flows as soon as the client is connected.
        c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
        let frame = gcs_frame(&command(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0, 0.0), 0);
        let (head, tail) = frame.split_at(frame.len() / 2);
        let mut first = b"garbage".to_vec();
        first.extend_from_slice(head);
        c.write(&first);
        // The loop reads the garbage and the half frame, and waits for the rest.
        wait_one_tick(&sim);
        c.write(tail);
        let got = c.read_until(|m| is_ack(m, MavCmd::MAV_CMD_REQUEST_MESSAGE));
        let Some(MavMessage::COMMAND_ACK(ack)) = got.last() else {
            unreachable!()
        };
        assert_eq!(ack.result, MavResult::MAV_RESULT_ACCEPTED);
        c.read_until(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)));
        assert_eq!(sim.vehicle().counters().malformed, 1);
    }

    #[test]
    fn two_tcp_clients_each_get_only_their_own_replies() {
        let (sim, addr) = vehicle_on("tcpin:127.0.0.1:0");
        let mut a = Client::connect(addr);
        let mut b = Client::connect(addr);
        for c in [&mut a, &mut b] {
            c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
        }
        let ack_a = MavCmd::MAV_CMD_REQUEST_MESSAGE;
        let ack_b = MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL;
        a.write(&gcs_frame(&command(ack_a, 148.0, 0.0), 0));
        a.read_until(|m| is_ack(m, ack_a));
        // A's reply was sent before B's: had it leaked to B, B would read it before its own.
        b.write(&gcs_frame(&command(ack_b, 33.0, 50_000.0), 0));
        let seen_b = b.read_until(|m| is_ack(m, ack_b));
        assert!(!seen_b.iter().any(|m| is_ack(m, ack_a)), "{seen_b:?}");
        assert!(
            !seen_b
                .iter()
                .any(|m| matches!(m, MavMessage::AUTOPILOT_VERSION(_)))
        );
        // Likewise B's reply would reach A before the answer to A's next request.
        let read = MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: 1,
            target_component: 1,
            param_id: "MIS_TAKEOFF_ALT".into(),
        });
        a.write(&gcs_frame(&read, 1));
        let seen_a = a.read_until(|m| matches!(m, MavMessage::PARAM_VALUE(_)));
        assert!(!seen_a.iter().any(|m| is_ack(m, ack_b)), "{seen_a:?}");
        // B's command took effect for everyone: position at 20 Hz.
        let iv = sim.vehicle().stream_interval(GLOBAL_POSITION_INT_DATA::ID);
        assert!(iv.is_some_and(|iv| (iv - 0.05).abs() < 1e-9), "{iv:?}");
        assert_eq!(sim.vehicle().counters().malformed, 0);
    }

    #[test]
    fn tcpout_connects_and_reconnects_after_the_server_drops_it() {
        let server = TcpListener::bind("127.0.0.1:0").expect("listen");
        let sim = spawn(
            VehicleConfig::new(1),
            &LinkConfig {
                endpoints: vec![format!("tcpout:{}", server.local_addr().expect("addr"))],
                signing: None,
            },
        )
        .expect("spawn");
        assert_eq!(sim.local_addrs(), &[None]);
        for round in 0..2 {
            let (stream, _) = server.accept().expect("the vehicle connects");
            stream
                .set_read_timeout(Some(Duration::from_millis(100)))
                .expect("timeout");
            let mut c = Client(MavlinkReader::new(stream));
            c.read_until(|m| matches!(m, MavMessage::GLOBAL_POSITION_INT(_)));
            c.write(&gcs_frame(
                &command(MavCmd::MAV_CMD_NAV_LAND, 0.0, 0.0),
                round,
            ));
            let got = c.read_until(|m| is_ack(m, MavCmd::MAV_CMD_NAV_LAND));
            let Some(MavMessage::COMMAND_ACK(ack)) = got.last() else {
                unreachable!()
            };
            assert_eq!(ack.result, MavResult::MAV_RESULT_DENIED); // not armed
            // Dropping the client closes the connection; the vehicle connects again.
        }
        assert_eq!(sim.vehicle().counters().refused_commands, 2);
    }

    #[test]
    fn tcpout_to_nowhere_does_not_stall_the_vehicle() {
        // A port with no listener: every attempt is refused, the loop keeps running.
        let port = TcpListener::bind("127.0.0.1:0")
            .and_then(|l| l.local_addr())
            .expect("free port")
            .port();
        let sim = spawn(
            VehicleConfig::new(1),
            &LinkConfig {
                endpoints: vec![format!("tcpout:127.0.0.1:{port}")],
                signing: None,
            },
        )
        .expect("spawn");
        for _ in 0..20 {
            wait_one_tick(&sim);
        }
    }

    #[test]
    fn garbage_is_counted_and_the_vehicle_keeps_answering() {
        let (sim, addr) = vehicle_on("udpin:127.0.0.1:0");
        let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
        client
            .set_read_timeout(Some(Duration::from_millis(200)))
            .expect("timeout");
        client
            .send_to(&[0xFD, 9, 0, 0, 1, 2, 3], addr)
            .expect("send");
        client.send_to(b"hello", addr).expect("send");
        // A valid GCS heartbeat makes the client a peer: telemetry follows.
        let hb = MavMessage::HEARTBEAT(mavlink::dialects::common::HEARTBEAT_DATA::DEFAULT);
        let mut frame = Vec::new();
        mavlink::write_v2_msg(
            &mut frame,
            MavHeader {
                system_id: 255,
                component_id: 190,
                sequence: 0,
            },
            &hb,
        )
        .expect("serialise");
        client.send_to(&frame, addr).expect("send");
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut got = None;
        let mut rbuf = [0u8; 512];
        while got.is_none() && Instant::now() < deadline {
            if let Ok(n) = client.recv(&mut rbuf) {
                let mut r = MavlinkReader::new(&rbuf[..n]);
                if let Ok((h, MavMessage::HEARTBEAT(_))) = r.read_any_message::<MavMessage>() {
                    got = Some(h);
                }
            }
        }
        let h = got.expect("heartbeat within 5 s");
        assert_eq!((h.system_id, h.component_id), (1, 1));
        assert_eq!(sim.vehicle().counters().malformed, 2);
    }

    /// Vehicle 1 on a loopback `udpin` link signing with key 1 in `mode`, and a UDP client
    /// connected to it (100 ms read timeout).
    fn signed_vehicle(mode: SigningMode) -> (SimHandle, UdpSocket) {
        let sim = spawn(
            VehicleConfig::new(1),
            &LinkConfig {
                endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
                signing: Some(signing(1, mode)),
            },
        )
        .expect("spawn");
        let addr = sim.local_addrs()[0].expect("bound");
        let client = UdpSocket::bind("127.0.0.1:0").expect("bind");
        client
            .set_read_timeout(Some(Duration::from_millis(100)))
            .expect("timeout");
        client.connect(addr).expect("connect");
        (sim, client)
    }

    fn signing(key: u8, mode: SigningMode) -> Signing {
        Signing {
            key: SigningKey::new([key; 32]),
            mode,
            link_id: 0,
        }
    }

    /// The frames of the next datagram from the vehicle (within 5 s).
    fn recv_frames(socket: &UdpSocket) -> Vec<Frame> {
        let deadline = Instant::now() + Duration::from_secs(5);
        let mut buf = [0u8; 2048];
        while Instant::now() < deadline {
            if let Ok(n) = socket.recv(&mut buf) {
                return parse_datagram(&buf[..n]).frames;
            }
        }
        panic!("nothing from the vehicle within 5 s");
    }

    #[test]
    fn signed_only_vehicle_refuses_unsigned_forged_and_replayed_frames() {
        const N: u64 = 20;
        let (sim, client) = signed_vehicle(SigningMode::SignedOnly);
        let gcs = signing(1, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let intruder = signing(2, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        let header = |sequence| MavHeader {
            system_id: 255,
            component_id: 190,
            sequence,
        };
        let arm = |on: bool| {
            command(
                MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
                f32::from(u8::from(on)),
                0.0,
            )
        };
        // Sends a correctly signed command and returns its signed ACK: every datagram sent
        // before it has been handled by then.
        let confirmed = |msg: &MavMessage, sequence| {
            let frame = gcs.encode(header(sequence), msg).expect("frame");
            client.send(&frame).expect("send");
            loop {
                for f in recv_frames(&client) {
                    if let MavMessage::COMMAND_ACK(ack) = &f.message {
                        // The vehicle signs what it sends, with the shared key.
                        assert_eq!(gcs.check(&f), Ok(()));
                        assert_eq!(ack.result, MavResult::MAV_RESULT_ACCEPTED);
                        return frame;
                    }
                }
            }
        };
        for i in 0..N {
            let seq = u8::try_from(i).expect("small");
            client
                .send(&gcs_frame(&arm(true), seq))
                .expect("send unsigned");
            client
                .send(&intruder.encode(header(seq), &arm(true)).expect("frame"))
                .expect("send forged");
        }
        // A refused sender is no peer: no telemetry (HEARTBEAT at 1 Hz) in 1.5 s.
        let mut buf = [0u8; 2048];
        let quiet = Instant::now() + Duration::from_millis(1500);
        while Instant::now() < quiet {
            assert!(
                client.recv(&mut buf).is_err(),
                "a refused sender got telemetry"
            );
        }
        assert!(!sim.vehicle().armed());
        let captured = confirmed(&arm(true), 100);
        assert!(sim.vehicle().armed());
        confirmed(&arm(false), 101);
        assert!(!sim.vehicle().armed());
        for _ in 0..N {
            client.send(&captured).expect("replay");
        }
        confirmed(&command(MavCmd::MAV_CMD_REQUEST_MESSAGE, 148.0, 0.0), 102);
        let c = sim.vehicle().counters();
        assert!(!sim.vehicle().armed(), "a replayed arm armed the vehicle");
        assert_eq!(
            c.rejected,
            Rejections {
                unsigned: N,
                bad_signature: N,
                replay: N
            }
        );
        assert_eq!((c.malformed, c.refused_commands), (0, 0));
        sim.stop();
    }

    #[test]
    fn sign_mode_vehicle_accepts_unsigned_commands_and_signs_its_replies() {
        let (sim, client) = signed_vehicle(SigningMode::Sign);
        let intruder = signing(2, SigningMode::Sign).signer().expect("signer");
        let arm = command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, 1.0, 0.0);
        let forged = intruder
            .encode(
                MavHeader {
                    system_id: 255,
                    component_id: 190,
                    sequence: 0,
                },
                &arm,
            )
            .expect("frame");
        client.send(&forged).expect("send");
        client.send(&gcs_frame(&arm, 1)).expect("send");
        let verify = signing(1, SigningMode::SignedOnly)
            .signer()
            .expect("signer");
        loop {
            let frames = recv_frames(&client);
            if let Some(f) = frames
                .iter()
                .find(|f| matches!(f.message, MavMessage::COMMAND_ACK(_)))
            {
                assert_eq!(verify.check(f), Ok(()));
                break;
            }
        }
        assert!(sim.vehicle().armed());
        let c = sim.vehicle().counters().rejected;
        assert_eq!((c.unsigned, c.bad_signature, c.replay), (0, 1, 0));
        sim.stop();
    }
}
