//! One link of a vehicle ([`Link`]): its transport (UDP, or TCP as server or client), framing
//! and signing of what is sent, and what a poll received from each peer.

use std::io;
use std::net::{SocketAddr, TcpListener, TcpStream, UdpSocket};
use std::sync::Arc;
use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::time::{Duration, Instant};

use harrier_link::frame::{Endpoint, parse_datagram};
use harrier_link::signing::Signer;
use mavlink::MavHeader;
use mavlink::consts::MAX_FRAME_SIZE;

use super::config::LinkError;
use super::received::{Peer, Received};
use super::tcp::TcpConn;
use crate::vehicle::{Framed, Outgoing};

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
    /// Frames handed to the transport without an error (a UDP datagram per peer, a TCP write).
    sent: u64,
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
            sent: 0,
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

    /// Frames sent so far: UDP datagrams the socket accepted (one per peer) and frames queued
    /// on a TCP connection. A load tool compares it with what the receiver counted.
    pub fn frames_sent(&self) -> u64 {
        self.sent
    }

    /// Serialises a message as the vehicle's next MAVLink 2 frame on this link, from its
    /// component, with its extension fields (signed when the link signs: harrier-link's signer
    /// takes the common-dialect message alone, so a signed frame goes without extensions).
    fn frame(&mut self, sysid: u8, out: &Outgoing) -> Option<Vec<u8>> {
        let header = MavHeader {
            system_id: sysid.into(),
            component_id: out.component,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        match &self.signer {
            Some(s) => s.encode(header, &out.message),
            None => {
                let mut buf = Vec::with_capacity(MAX_FRAME_SIZE);
                mavlink::write_v2_msg(&mut buf, header, &Framed(out)).ok()?;
                Some(buf)
            }
        }
    }

    pub(super) fn send(&mut self, sysid: u8, msg: &Outgoing, to: Peer) {
        let Some(frame) = self.frame(sysid, msg) else {
            return;
        };
        match (&mut self.transport, to) {
            (Transport::Udp { socket, .. }, Peer::Udp(addr)) => {
                // UDP is lossy by nature: a failed send (no listener yet) is not an error.
                self.sent += u64::from(socket.send_to(&frame, addr).is_ok());
            }
            (Transport::TcpIn { clients, .. }, Peer::Tcp(id)) => {
                clients.retain_mut(|c| {
                    if c.id != id {
                        return true;
                    }
                    let ok = c.send(&frame);
                    self.sent += u64::from(ok);
                    ok
                });
            }
            (Transport::TcpOut { conn, retry_at, .. }, Peer::Tcp(id)) => {
                match conn.as_mut().filter(|c| c.id == id).map(|c| c.send(&frame)) {
                    Some(true) => self.sent += 1,
                    Some(false) => {
                        *conn = None;
                        *retry_at = Instant::now() + TCP_RETRY;
                    }
                    None => {}
                }
            }
            _ => {}
        }
    }

    pub(super) fn broadcast(&mut self, sysid: u8, msg: &Outgoing) {
        let Some(frame) = self.frame(sysid, msg) else {
            return;
        };
        match &mut self.transport {
            Transport::Udp { socket, peers } => {
                for to in peers.iter() {
                    if socket.send_to(&frame, to).is_ok() {
                        self.sent += 1;
                    }
                }
            }
            Transport::TcpIn { clients, .. } => clients.retain_mut(|c| {
                let ok = c.send(&frame);
                self.sent += u64::from(ok);
                ok
            }),
            Transport::TcpOut { conn, retry_at, .. } => match conn.as_mut().map(|c| c.send(&frame))
            {
                Some(true) => self.sent += 1,
                Some(false) => {
                    *conn = None;
                    *retry_at = Instant::now() + TCP_RETRY;
                }
                None => {}
            },
        }
    }

    /// Receives everything pending: one entry per UDP datagram (no messages when it held no valid
    /// frame) and per TCP connection. Accepts new TCP clients, drops closed connections and
    /// (re)connects `tcpout` links.
    pub(super) fn poll(&mut self, buf: &mut [u8]) -> Vec<Received> {
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
                    if !peers.contains(&from) && !got.frames.is_empty() {
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
