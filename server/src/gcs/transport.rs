//! The sockets of the GCS link and the router: one task per endpoint (and per TCP connection),
//! turning bytes into [`Inbound`] frames for the link actor and sending the actor's
//! [`Outbound`] bytes.
//!
//! - `udpin` binds and answers whoever sent a valid frame (at most [`MAX_UDP_PEERS`], oldest
//!   forgotten first: a swarm of 255 vehicles, each from its own port, all fit and all get the
//!   ground station's HEARTBEAT); `udpout` sends to its address from an ephemeral port. A UDP
//!   socket's receive buffer is raised to [`UDP_RECV_BUFFER`] (within the system's
//!   `net.core.rmem_max`), so that a busy moment of the server does not drop a swarm's frames.
//! - `tcpin` accepts any number of clients; `tcpout` connects and reconnects every
//!   [`TCP_RETRY`] while the server is away. Each connection has a bounded send queue: a client
//!   that does not read loses frames (counted), it never slows the link.
//!
//! A datagram is parsed on its own ([`parse_datagram`]), a TCP stream across reads
//! ([`StreamParser`]). With MAVLink 2 signing every frame is checked here, before anything else
//! sees it ([`screen`]): a refused frame goes no further than the [`Inbound::rejected`] count,
//! and a UDP sender of refused frames only does not become a peer (it gets no telemetry).

use std::collections::{HashMap, HashSet, VecDeque};
use std::io;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

use harrier_link::frame::{Endpoint, Parsed, StreamParser, parse_datagram};
use harrier_link::signing::{Rejection, Signer};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::{mpsc, watch};

/// Most UDP peers an `udpin` endpoint answers: every MAVLink system id (255) four times over
/// (a vehicle heard from several addresses, router clients).
pub const MAX_UDP_PEERS: usize = 1024;
/// Receive buffer asked for every UDP endpoint (bytes; the kernel caps it at
/// `net.core.rmem_max`): at 10 000 frames/s (255 vehicles × 40) the default 208 KiB holds about
/// 20 ms of them, 4 MiB about half a second.
pub const UDP_RECV_BUFFER: usize = 4 << 20;
/// Pause between two connection attempts of a `tcpout` endpoint.
pub const TCP_RETRY: Duration = Duration::from_secs(1);
/// Frames queued for one TCP connection before further ones are dropped.
const TCP_QUEUE: usize = 4096;

/// Who sent a frame, or where to send one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Peer {
    /// A UDP address.
    Udp(SocketAddr),
    /// A TCP connection, by its number on the endpoint.
    Tcp(u64),
}

impl std::fmt::Display for Peer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Udp(a) => write!(f, "udp:{a}"),
            Self::Tcp(n) => write!(f, "tcp#{n}"),
        }
    }
}

/// What one read of one peer gave.
#[derive(Debug)]
pub struct Inbound {
    /// Index of the endpoint (in the order the link opened them).
    pub endpoint: usize,
    /// The sender.
    pub peer: Peer,
    /// Its frames (those the signing accepted) and malformed stretches.
    pub parsed: Parsed,
    /// Frames refused by the signing.
    pub rejected: Vec<Rejected>,
    /// When it was read.
    pub at: Instant,
}

/// A frame refused by the signing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rejected {
    /// Why.
    pub reason: Rejection,
    /// The system id it claims.
    pub system_id: u32,
    /// The component id it claims.
    pub component_id: u8,
}

/// Keeps the frames `signer` accepts (every frame without signing) and returns the others.
pub fn screen(signer: Option<&Signer>, parsed: &mut Parsed) -> Vec<Rejected> {
    let Some(signer) = signer else {
        return Vec::new();
    };
    let mut rejected = Vec::new();
    parsed.frames.retain(|f| match signer.check(f) {
        Ok(()) => true,
        Err(reason) => {
            rejected.push(Rejected {
                reason,
                system_id: f.header.system_id,
                component_id: f.header.component_id,
            });
            false
        }
    });
    rejected
}

/// The peers of an `udpin` endpoint, oldest first, with a set beside the order so that each
/// datagram's check is O(1) whatever their number.
#[derive(Debug, Default)]
struct UdpPeers {
    order: VecDeque<SocketAddr>,
    known: HashSet<SocketAddr>,
    /// Impostors (gcs::identity): never peers while quarantined.
    quarantined: HashSet<SocketAddr>,
}

impl UdpPeers {
    /// Adds `from` unless known or quarantined; the oldest is forgotten beyond
    /// [`MAX_UDP_PEERS`].
    fn add(&mut self, from: SocketAddr) {
        if !self.quarantined.contains(&from) && self.known.insert(from) {
            self.order.push_back(from);
            if self.order.len() > MAX_UDP_PEERS
                && let Some(old) = self.order.pop_front()
            {
                self.known.remove(&old);
            }
        }
    }

    /// Quarantines `peer` (it is no peer until released) or releases it.
    fn quarantine(&mut self, peer: SocketAddr, on: bool) {
        if on {
            self.quarantined.insert(peer);
            if self.known.remove(&peer) {
                self.order.retain(|p| *p != peer);
            }
        } else {
            self.quarantined.remove(&peer);
        }
    }
}

/// Asks for a [`UDP_RECV_BUFFER`] receive buffer (a smaller one stays if refused).
fn widen_recv_buffer(socket: &UdpSocket) {
    if let Err(e) = socket2::SockRef::from(socket).set_recv_buffer_size(UDP_RECV_BUFFER) {
        tracing::debug!("udp endpoint: receive buffer not widened: {e}");
    }
}

/// Bytes to send on an endpoint.
#[derive(Debug, Clone)]
pub enum Outbound {
    /// To one peer.
    To(Peer, Arc<[u8]>),
    /// To every peer of the endpoint.
    All(Arc<[u8]>),
    /// Quarantine a peer (`true`: an impostor, gcs::identity; nothing goes to it, not even what
    /// goes to every peer) or release it (`false`).
    Quarantine(Peer, bool),
}

/// Counters of an endpoint.
#[derive(Debug, Default)]
pub struct EndpointCounters {
    /// Frames sent.
    pub sent: AtomicU64,
    /// Frames dropped: a TCP client's queue was full, or a send failed.
    pub send_dropped: AtomicU64,
    /// Frames a router endpoint's filter kept from its clients (`Direction::Out`) or from the
    /// vehicles (`Direction::In`), by [`Direction`](super::filter::Direction) and
    /// [`Filtered`](super::filter::Filtered) reason (in the order of their `ALL`).
    pub filtered: [[AtomicU64; 7]; 2],
}

/// An open endpoint: where it is bound, and the queue of bytes to send on it.
#[derive(Debug, Clone)]
pub struct EndpointHandle {
    /// The endpoint as bound (an `*in` endpoint of port 0 gets its real port here).
    pub endpoint: Endpoint,
    /// Bytes to send.
    pub tx: mpsc::Sender<Outbound>,
    /// Its counters.
    pub counters: Arc<EndpointCounters>,
}

/// Opens `endpoint`; frames read (those `signer` accepts) go to `inbound` tagged with `index`.
/// Runs until `stop` turns true or the link actor goes away.
pub async fn open(
    index: usize,
    endpoint: Endpoint,
    inbound: mpsc::Sender<Inbound>,
    stop: watch::Receiver<bool>,
    signer: Option<Arc<Signer>>,
) -> io::Result<EndpointHandle> {
    let input = Input {
        index,
        inbound,
        signer,
    };
    let (tx, rx) = mpsc::channel(TCP_QUEUE);
    let counters = Arc::new(EndpointCounters::default());
    let bound = match endpoint {
        Endpoint::UdpIn(addr) => {
            let socket = UdpSocket::bind(addr).await?;
            widen_recv_buffer(&socket);
            let bound = Endpoint::UdpIn(socket.local_addr()?);
            let c = Arc::clone(&counters);
            tokio::spawn(udp(input, socket, None, rx, stop, c));
            bound
        }
        Endpoint::UdpOut(remote) => {
            let any = if remote.is_ipv4() {
                SocketAddr::from((Ipv4Addr::UNSPECIFIED, 0))
            } else {
                SocketAddr::from((Ipv6Addr::UNSPECIFIED, 0))
            };
            let socket = UdpSocket::bind(any).await?;
            widen_recv_buffer(&socket);
            let c = Arc::clone(&counters);
            tokio::spawn(udp(input, socket, Some(remote), rx, stop, c));
            endpoint
        }
        Endpoint::TcpIn(addr) => {
            let listener = TcpListener::bind(addr).await?;
            let bound = Endpoint::TcpIn(listener.local_addr()?);
            let c = Arc::clone(&counters);
            tokio::spawn(tcp_in(input, listener, rx, stop, c));
            bound
        }
        Endpoint::TcpOut(remote) => {
            let c = Arc::clone(&counters);
            tokio::spawn(tcp_out(input, remote, rx, stop, c));
            endpoint
        }
    };
    Ok(EndpointHandle {
        endpoint: bound,
        tx,
        counters,
    })
}

/// Where an endpoint's input goes, and what screens it.
#[derive(Debug, Clone)]
struct Input {
    /// The endpoint's index.
    index: usize,
    /// The link actor.
    inbound: mpsc::Sender<Inbound>,
    /// The signing, if on.
    signer: Option<Arc<Signer>>,
}

impl Input {
    /// Screens `parsed` and hands what is left to the actor; `false` when the actor is gone.
    async fn send(&self, peer: Peer, mut parsed: Parsed) -> bool {
        let rejected = screen(self.signer.as_deref(), &mut parsed);
        if parsed.frames.is_empty() && parsed.malformed == 0 && rejected.is_empty() {
            return true;
        }
        let msg = Inbound {
            endpoint: self.index,
            peer,
            parsed,
            rejected,
            at: Instant::now(),
        };
        self.inbound.send(msg).await.is_ok()
    }
}

async fn udp(
    input: Input,
    socket: UdpSocket,
    remote: Option<SocketAddr>,
    mut rx: mpsc::Receiver<Outbound>,
    mut stop: watch::Receiver<bool>,
    counters: Arc<EndpointCounters>,
) {
    let mut peers = UdpPeers::default();
    if let Some(r) = remote {
        peers.add(r);
    }
    let mut buf = vec![0u8; 65_536];
    let send = |to: SocketAddr, bytes: &[u8]| match socket.try_send_to(bytes, to) {
        Ok(_) => counters.sent.fetch_add(1, Ordering::Relaxed),
        // UDP is lossy by nature: a full socket buffer or an absent listener drops the frame.
        Err(_) => counters.send_dropped.fetch_add(1, Ordering::Relaxed),
    };
    loop {
        tokio::select! {
            r = socket.recv_from(&mut buf) => {
                let (n, from) = match r {
                    Ok(r) => r,
                    // ICMP port unreachable of an earlier send, and the like.
                    Err(e) => {
                        tracing::trace!("udp endpoint {}: {e}", input.index);
                        continue;
                    }
                };
                let mut parsed = parse_datagram(&buf[..n]);
                let rejected = screen(input.signer.as_deref(), &mut parsed);
                // Only a sender of accepted frames becomes a peer.
                if remote.is_none() && !parsed.frames.is_empty() {
                    peers.add(from);
                }
                let msg = Inbound {
                    endpoint: input.index,
                    peer: Peer::Udp(from),
                    parsed,
                    rejected,
                    at: Instant::now(),
                };
                if input.inbound.send(msg).await.is_err() {
                    return;
                }
            }
            o = rx.recv() => match o {
                Some(Outbound::To(Peer::Udp(to), bytes)) => { send(to, &bytes); }
                Some(Outbound::To(Peer::Tcp(_), _)) => {}
                Some(Outbound::All(bytes)) => {
                    for &to in &peers.order {
                        send(to, &bytes);
                    }
                }
                Some(Outbound::Quarantine(Peer::Udp(p), on)) => peers.quarantine(p, on),
                Some(Outbound::Quarantine(Peer::Tcp(_), _)) => {}
                None => return,
            },
            () = stopped(&mut stop) => return,
        }
    }
}

/// Reads frames from one TCP connection and writes what its queue holds, until either side
/// closes.
async fn connection(
    input: Input,
    id: u64,
    stream: TcpStream,
    mut rx: mpsc::Receiver<Arc<[u8]>>,
    counters: Arc<EndpointCounters>,
) {
    let _ = stream.set_nodelay(true);
    let (mut read, mut write) = stream.into_split();
    let mut parser = StreamParser::default();
    let mut buf = vec![0u8; 16_384];
    loop {
        tokio::select! {
            r = read.read(&mut buf) => {
                let n = match r {
                    Ok(0) | Err(_) => return,
                    Ok(n) => n,
                };
                if !input.send(Peer::Tcp(id), parser.push(&buf[..n])).await {
                    return;
                }
            }
            o = rx.recv() => match o {
                Some(bytes) => {
                    if write.write_all(&bytes).await.is_err() {
                        return;
                    }
                    counters.sent.fetch_add(1, Ordering::Relaxed);
                }
                None => return,
            },
        }
    }
}

async fn tcp_in(
    input: Input,
    listener: TcpListener,
    mut rx: mpsc::Receiver<Outbound>,
    mut stop: watch::Receiver<bool>,
    counters: Arc<EndpointCounters>,
) {
    let mut clients: HashMap<u64, mpsc::Sender<Arc<[u8]>>> = HashMap::new();
    // Impostors' connections (gcs::identity): nothing goes to them.
    let mut quarantined: HashSet<u64> = HashSet::new();
    let mut next = 0u64;
    let push =
        |tx: &mpsc::Sender<Arc<[u8]>>, bytes: &Arc<[u8]>| match tx.try_send(Arc::clone(bytes)) {
            Ok(()) => true,
            Err(mpsc::error::TrySendError::Full(_)) => {
                counters.send_dropped.fetch_add(1, Ordering::Relaxed);
                true
            }
            Err(mpsc::error::TrySendError::Closed(_)) => false,
        };
    loop {
        tokio::select! {
            a = listener.accept() => {
                let Ok((stream, from)) = a else { continue };
                next += 1;
                tracing::debug!("tcp endpoint {}: client #{next} from {from}", input.index);
                let (tx, crx) = mpsc::channel(TCP_QUEUE);
                clients.insert(next, tx);
                tokio::spawn(connection(input.clone(), next, stream, crx, Arc::clone(&counters)));
            }
            o = rx.recv() => match o {
                Some(Outbound::To(Peer::Tcp(id), bytes)) => {
                    if clients.get(&id).is_some_and(|tx| !push(tx, &bytes)) {
                        clients.remove(&id);
                    }
                }
                Some(Outbound::To(Peer::Udp(_), _) | Outbound::Quarantine(Peer::Udp(_), _)) => {}
                Some(Outbound::All(bytes)) => {
                    clients.retain(|id, tx| quarantined.contains(id) || push(tx, &bytes));
                }
                Some(Outbound::Quarantine(Peer::Tcp(id), on)) => {
                    if on {
                        quarantined.insert(id);
                    } else {
                        quarantined.remove(&id);
                    }
                }
                None => return,
            },
            () = stopped(&mut stop) => return,
        }
    }
}

async fn tcp_out(
    input: Input,
    remote: SocketAddr,
    mut rx: mpsc::Receiver<Outbound>,
    mut stop: watch::Receiver<bool>,
    counters: Arc<EndpointCounters>,
) {
    let mut id = 0u64;
    loop {
        let connect = tokio::time::timeout(TCP_RETRY, TcpStream::connect(remote));
        let stream = tokio::select! {
            c = connect => match c {
                Ok(Ok(s)) => Some(s),
                _ => None,
            },
            () = stopped(&mut stop) => return,
        };
        let Some(stream) = stream else {
            // Frames for an absent server are dropped while waiting to retry.
            let retry = tokio::time::sleep(TCP_RETRY);
            tokio::pin!(retry);
            loop {
                tokio::select! {
                    () = &mut retry => break,
                    o = rx.recv() => match o {
                        Some(_) => { counters.send_dropped.fetch_add(1, Ordering::Relaxed); }
                        None => return,
                    },
                    () = stopped(&mut stop) => return,
                }
            }
            continue;
        };
        id += 1;
        tracing::info!("tcp endpoint {}: connected to {remote}", input.index);
        let (tx, crx) = mpsc::channel(TCP_QUEUE);
        let conn = connection(input.clone(), id, stream, crx, Arc::clone(&counters));
        tokio::pin!(conn);
        loop {
            tokio::select! {
                () = &mut conn => break,
                o = rx.recv() => match o {
                    Some(Outbound::To(_, bytes) | Outbound::All(bytes)) => {
                        if tx.try_send(bytes).is_err() {
                            counters.send_dropped.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    // The one server this endpoint connects to is no impostor to quarantine.
                    Some(Outbound::Quarantine(..)) => {}
                    None => return,
                },
                () = stopped(&mut stop) => return,
            }
        }
        tracing::info!(
            "tcp endpoint {}: {remote} closed the connection; reconnecting",
            input.index
        );
    }
}

/// Resolves once `stop` turns true (or its sender is gone).
pub async fn stopped(stop: &mut watch::Receiver<bool>) {
    let _ = stop.wait_for(|s| *s).await;
}

#[cfg(test)]
mod tests {
    use harrier_link::mavlink::MavHeader;
    use harrier_link::mavlink::dialects::common::{
        HEARTBEAT_DATA, MavAutopilot, MavMessage, MavModeFlag, MavState, MavType,
    };

    use super::*;

    fn heartbeat(system_id: u8, mavtype: MavType) -> Vec<u8> {
        let header = MavHeader {
            system_id: system_id.into(),
            component_id: 1,
            sequence: 0,
        };
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            custom_mode: 0,
            mavtype,
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            base_mode: MavModeFlag::empty(),
            system_status: MavState::MAV_STATE_ACTIVE,
            mavlink_version: 3,
        });
        harrier_link::frame::encode(header, &hb).expect("encode")
    }

    /// A swarm of 255 vehicles, each from its own port, on one `udpin` endpoint: every one is a
    /// peer, so every one gets what goes to all (the ground station's HEARTBEAT).
    #[tokio::test]
    async fn every_vehicle_of_a_swarm_gets_what_goes_to_all() {
        let (inbound, mut rx) = mpsc::channel(1024);
        let (_stop_tx, stop) = watch::channel(false);
        let any = Endpoint::UdpIn(SocketAddr::from((Ipv4Addr::LOCALHOST, 0)));
        let h = open(0, any, inbound, stop, None).await.expect("open");
        let Endpoint::UdpIn(addr) = h.endpoint else {
            panic!("bound as {:?}", h.endpoint);
        };
        let mut vehicles = Vec::new();
        for id in 1..=255u8 {
            let s = UdpSocket::bind((Ipv4Addr::LOCALHOST, 0))
                .await
                .expect("bind");
            s.send_to(&heartbeat(id, MavType::MAV_TYPE_QUADROTOR), addr)
                .await
                .expect("send");
            vehicles.push(s);
        }
        let wait = Duration::from_secs(10);
        for _ in 0..255 {
            let i = tokio::time::timeout(wait, rx.recv())
                .await
                .expect("every frame in time")
                .expect("open");
            assert_eq!(i.parsed.frames.len(), 1);
        }
        let gcs: Arc<[u8]> = heartbeat(255, MavType::MAV_TYPE_GCS).into();
        h.tx.send(Outbound::All(Arc::clone(&gcs)))
            .await
            .expect("queued");
        let mut buf = [0u8; 512];
        for (k, s) in vehicles.iter().enumerate() {
            let n = tokio::time::timeout(wait, s.recv(&mut buf))
                .await
                .unwrap_or_else(|_| panic!("vehicle {} got nothing", k + 1))
                .expect("recv");
            assert_eq!(&buf[..n], &gcs[..]);
        }
        assert_eq!(h.counters.sent.load(Ordering::Relaxed), 255);
    }

    #[test]
    fn the_oldest_peer_is_forgotten_beyond_the_limit() {
        let mut p = UdpPeers::default();
        let addr = |k: usize| SocketAddr::from((Ipv4Addr::LOCALHOST, 1000 + k as u16));
        for k in 0..=MAX_UDP_PEERS {
            p.add(addr(k));
            p.add(addr(k)); // known: no change
        }
        assert_eq!(
            (p.order.len(), p.known.len()),
            (MAX_UDP_PEERS, MAX_UDP_PEERS)
        );
        assert!(!p.known.contains(&addr(0)));
        assert_eq!(p.order.front(), Some(&addr(1)));
    }
}
