//! MAVLink links over UDP and the threads that run vehicles on them.
//!
//! A link is one UDP socket described by a connection string: `udpin:HOST:PORT` binds and answers
//! whoever sends to it (telemetry goes to every peer seen); `udpout:HOST:PORT` binds an ephemeral
//! port and sends to HOST:PORT. Replies go back on the link, and to the address, the request came
//! from, so a GCS and an API client never see each other's replies.

use std::net::{SocketAddr, ToSocketAddrs, UdpSocket};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use mavlink::dialects::common::MavMessage;
use mavlink::{MavHeader, MavlinkReader};

use crate::vehicle::{COMPONENT_ID, Vehicle, VehicleConfig};

/// Errors from setting up links.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The connection string is not `udpin:HOST:PORT` or `udpout:HOST:PORT`.
    #[error("bad connection string {0:?}: expected udpin:HOST:PORT or udpout:HOST:PORT")]
    BadAddress(String),
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

/// A parsed connection string.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// Bind here and answer whoever sends.
    UdpIn(SocketAddr),
    /// Send to this address from an ephemeral port.
    UdpOut(SocketAddr),
}

impl Endpoint {
    /// Parses `udpin:HOST:PORT` or `udpout:HOST:PORT` (`udp:` is `udpin:`).
    pub fn parse(s: &str) -> Result<Self, LinkError> {
        let bad = || LinkError::BadAddress(s.to_owned());
        let (kind, rest) = s.split_once(':').ok_or_else(bad)?;
        let addr = rest
            .to_socket_addrs()
            .ok()
            .and_then(|mut a| a.next())
            .ok_or_else(bad)?;
        match kind {
            "udpin" | "udp" => Ok(Self::UdpIn(addr)),
            "udpout" => Ok(Self::UdpOut(addr)),
            _ => Err(bad()),
        }
    }
}

/// One UDP link of a vehicle.
#[derive(Debug)]
pub struct Link {
    socket: UdpSocket,
    /// Fixed destination (udpout) or the peers seen so far (udpin).
    peers: Vec<SocketAddr>,
    sequence: u8,
}

/// Most peers a udpin link remembers (the oldest is forgotten first).
const MAX_PEERS: usize = 8;

impl Link {
    /// Opens a link.
    pub fn open(endpoint: &Endpoint) -> Result<Self, LinkError> {
        let io = |what, source| LinkError::Io {
            what,
            address: format!("{endpoint:?}"),
            source,
        };
        let (bind, peers): (SocketAddr, Vec<SocketAddr>) = match *endpoint {
            Endpoint::UdpIn(a) => (a, Vec::new()),
            Endpoint::UdpOut(a) => {
                let any: SocketAddr = if a.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                (any, vec![a])
            }
        };
        let socket = UdpSocket::bind(bind).map_err(|e| io("bind", e))?;
        socket
            .set_nonblocking(true)
            .map_err(|e| io("set_nonblocking", e))?;
        Ok(Self {
            socket,
            peers,
            sequence: 0,
        })
    }

    /// The bound local address.
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.socket.local_addr().ok()
    }

    fn send(&mut self, sysid: u8, msg: &MavMessage, to: SocketAddr) {
        let header = MavHeader {
            system_id: sysid.into(),
            component_id: COMPONENT_ID,
            sequence: self.sequence,
        };
        self.sequence = self.sequence.wrapping_add(1);
        let mut buf = Vec::with_capacity(280);
        if mavlink::write_v2_msg(&mut buf, header, msg).is_ok() {
            // UDP is lossy by nature: a failed send (no listener yet) is not an error.
            let _ = self.socket.send_to(&buf, to);
        }
    }

    fn broadcast(&mut self, sysid: u8, msg: &MavMessage) {
        for i in 0..self.peers.len() {
            let to = self.peers[i];
            self.send(sysid, msg, to);
        }
    }

    /// Receives every pending datagram; returns `(sender, messages)` per datagram (empty when it
    /// held no valid frame).
    fn poll(&mut self, buf: &mut [u8]) -> Vec<(SocketAddr, Vec<MavMessage>)> {
        let mut out = Vec::new();
        while let Ok((n, from)) = self.socket.recv_from(buf) {
            let mut reader = MavlinkReader::new(&buf[..n]);
            let mut msgs = Vec::new();
            while let Ok((_, m)) = reader.read_any_message::<MavMessage>() {
                msgs.push(m);
            }
            if !self.peers.contains(&from) && !msgs.is_empty() {
                if self.peers.len() >= MAX_PEERS {
                    self.peers.remove(0);
                }
                self.peers.push(from);
            }
            out.push((from, msgs));
        }
        out
    }
}

/// Links of one vehicle.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkConfig {
    /// Connection strings, e.g. `udpout:127.0.0.1:14550` (GCS) and `udpin:0.0.0.0:14540` (API).
    pub endpoints: Vec<String>,
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
        }
    }
}

/// A vehicle running on its own thread; stopped when dropped.
#[derive(Debug)]
pub struct SimHandle {
    vehicle: Arc<Mutex<Vehicle>>,
    local_addrs: Vec<Option<SocketAddr>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
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
    /// Stops the vehicle and waits for its thread.
    pub fn stop(mut self) {
        self.shutdown();
    }
    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for SimHandle {
    fn drop(&mut self) {
        self.shutdown();
    }
}

/// Wall-clock period of the simulation loop.
const TICK: Duration = Duration::from_millis(5);

/// Opens the links and runs a vehicle on a new thread.
pub fn spawn(config: VehicleConfig, links: &LinkConfig) -> Result<SimHandle, LinkError> {
    let mut opened = links
        .endpoints
        .iter()
        .map(|e| Link::open(&Endpoint::parse(e)?))
        .collect::<Result<Vec<_>, _>>()?;
    let local_addrs = opened.iter().map(Link::local_addr).collect();
    let start = Instant::now();
    let vehicle = Arc::new(Mutex::new(Vehicle::new(config, 0.0)));
    let stop = Arc::new(AtomicBool::new(false));
    let (v, s) = (Arc::clone(&vehicle), Arc::clone(&stop));
    let thread = std::thread::Builder::new()
        .name(format!("harrier-sim-{}", config.id))
        .spawn(move || {
            let mut buf = vec![0u8; 65_536];
            while !s.load(Ordering::Relaxed) {
                {
                    let mut v = v.lock().unwrap_or_else(PoisonError::into_inner);
                    run_once(&mut v, &mut opened, &mut buf, start.elapsed().as_secs_f64());
                }
                std::thread::sleep(TICK);
            }
        })
        .map_err(|e| LinkError::Io {
            what: "spawn thread for",
            address: links.endpoints.join(","),
            source: e,
        })?;
    Ok(SimHandle {
        vehicle,
        local_addrs,
        stop,
        thread: Some(thread),
    })
}

fn run_once(v: &mut Vehicle, links: &mut [Link], buf: &mut [u8], now: f64) {
    let sysid = v.id();
    for link in links.iter_mut() {
        for (from, msgs) in link.poll(buf) {
            if msgs.is_empty() {
                v.count_malformed();
            }
            for m in &msgs {
                for reply in v.handle(now, m) {
                    link.send(sysid, &reply, from);
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

    #[test]
    fn connection_strings() {
        assert_eq!(
            Endpoint::parse("udpin:127.0.0.1:14540").ok(),
            Some(Endpoint::UdpIn(([127, 0, 0, 1], 14540).into()))
        );
        assert_eq!(
            Endpoint::parse("udpout:127.0.0.1:14550").ok(),
            Some(Endpoint::UdpOut(([127, 0, 0, 1], 14550).into()))
        );
        for bad in [
            "",
            "udpin",
            "tcpin:0.0.0.0:5760",
            "udpin:nohost",
            "udpout:1.2.3.4:99999",
        ] {
            assert!(Endpoint::parse(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn garbage_is_counted_and_the_vehicle_keeps_answering() {
        let sim = spawn(
            VehicleConfig::new(1),
            &LinkConfig {
                endpoints: vec!["udpin:127.0.0.1:0".to_owned()],
            },
        )
        .expect("spawn");
        let addr = sim.local_addrs()[0].expect("bound");
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
}
