//! CoT out: every confirmed track of the tracker's latest snapshot (and, with `cot.vehicles`,
//! every vehicle), `cot.hz` times a second, as a Cursor-on-Target event ([`crate::wire::cot`]) to every `cot.destinations` entry: a UDP
//! datagram to a multicast group (TAK's mesh default `239.2.3.1:6969`, with `cot.multicast_ttl`
//! and loopback on, so a TAK client on this host hears it too) or to one host, or a TCP (or
//! TLS: rustls, the CA and client certificate of `cot.tls_*`) stream to a TAK server's input.
//! XML is sent as is on all; protobuf (TAK protocol version 1) in the mesh framing on UDP and the
//! stream framing on TCP and TLS.
//!
//! Never blocks the tracker: the snapshot is a `watch` read once per tick. A UDP datagram the
//! socket cannot take at once is dropped (`dropped`). Each TCP or TLS destination has its own task
//! and a queue of `cot.queue` events: when a slow or stalled peer lets it fill, events are
//! dropped (`dropped`); a lost or refused connection is retried with doubling waits up to
//! `cot.reconnect_max_s`, and what was queued meanwhile (stale by then) is dropped. Failures
//! are logged at most once per 5 s per destination.
//!
//! Counters (`harrier_feed_events_total{feed="cot"}`): `events` (events built per tick),
//! `sent` (event × destination), `dropped`, `errors`, `connects`, `connect_errors`,
//! `disconnects`.

use std::future::Future;
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use tokio::io::{AsyncWrite, AsyncWriteExt as _};
use tokio::net::{TcpStream, UdpSocket};
use tokio::sync::{mpsc, watch};
use tokio::task::JoinHandle;
use tokio_rustls::TlsConnector;
use tokio_rustls::rustls;
use tokio_rustls::rustls::pki_types::pem::PemObject as _;
use tokio_rustls::rustls::pki_types::{CertificateDer, PrivateKeyDer, ServerName};

use super::throttle::Throttle;
use super::{FeedContext, FeedCounters};
use crate::clock::unix_now;
use crate::config::{CotConfig, CotEncoding, CotTransport};
use crate::gcs::transport::stopped;
use crate::wire::cot::{CotEvent, CotSettings, track_event, vehicle_event};

/// The counters' feed label.
const FEED: &str = "cot";

/// One destination as the sending loop sees it.
enum Out {
    /// A bound UDP socket and where to.
    Udp {
        socket: UdpSocket,
        to: SocketAddr,
        log: Throttle,
    },
    /// The queue of a TCP destination's task.
    Tcp { queue: mpsc::Sender<Arc<[u8]>> },
}

/// Binds the UDP sockets and starts the TCP destinations' tasks; the returned future sends
/// until `stop`. Fails (naming the destination) when a UDP destination cannot be resolved or
/// no socket can be bound for it.
pub(super) async fn start(
    config: CotConfig,
    ctx: FeedContext,
) -> Result<impl Future<Output = ()> + Send + 'static, String> {
    let mut outs = Vec::new();
    let mut tcp_tasks = Vec::new();
    let mut connector: Option<TlsConnector> = None;
    let destinations = config.parsed_destinations().map_err(|e| e.to_string())?;
    for d in destinations {
        match d.transport {
            CotTransport::Udp => {
                let to = tokio::net::lookup_host(d.address.as_str())
                    .await
                    .map_err(|e| format!("udp://{}: {e}", d.address))?
                    .next()
                    .ok_or_else(|| format!("udp://{}: no address", d.address))?;
                outs.push(Out::Udp {
                    socket: udp_socket(to, config.multicast_ttl)
                        .await
                        .map_err(|e| format!("udp://{}: {e}", d.address))?,
                    to,
                    log: Throttle::default(),
                });
            }
            CotTransport::Tcp | CotTransport::Tls => {
                let tls = if d.transport == CotTransport::Tls {
                    let connector = match &connector {
                        Some(c) => c.clone(),
                        None => connector.insert(tls_connector(&config)?).clone(),
                    };
                    let name = ServerName::try_from(d.host().to_owned())
                        .map_err(|e| format!("tls://{}: {e}", d.address))?;
                    Some((connector, name))
                } else {
                    None
                };
                let (queue, rx) = mpsc::channel(config.queue);
                let task = tcp_peer(
                    d.address,
                    tls,
                    rx,
                    Arc::clone(&ctx.counters),
                    Duration::from_secs_f64(config.reconnect_max_s),
                    ctx.stop.clone(),
                );
                tcp_tasks.push(tokio::spawn(task));
                outs.push(Out::Tcp { queue });
            }
        }
    }
    Ok(run(config, ctx, outs, tcp_tasks))
}

/// The TLS client of the `tls://` destinations: trusts the authorities of `cot.tls_ca`, shows
/// `cot.tls_cert` when set; TLS 1.2 and 1.3 with rustls' ring provider.
fn tls_connector(config: &CotConfig) -> Result<TlsConnector, String> {
    let pem = |key: &str, path: &str, e: &dyn std::fmt::Display| format!("cot.{key} {path:?}: {e}");
    let mut roots = rustls::RootCertStore::empty();
    for c in CertificateDer::pem_file_iter(&config.tls_ca)
        .map_err(|e| pem("tls_ca", &config.tls_ca, &e))?
    {
        let c = c.map_err(|e| pem("tls_ca", &config.tls_ca, &e))?;
        roots
            .add(c)
            .map_err(|e| pem("tls_ca", &config.tls_ca, &e))?;
    }
    if roots.is_empty() {
        return Err(pem("tls_ca", &config.tls_ca, &"no certificate"));
    }
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let builder = rustls::ClientConfig::builder_with_provider(provider)
        .with_safe_default_protocol_versions()
        .map_err(|e| format!("TLS: {e}"))?
        .with_root_certificates(roots);
    let client = if config.tls_cert.is_empty() {
        builder.with_no_client_auth()
    } else {
        let chain = CertificateDer::pem_file_iter(&config.tls_cert)
            .map_err(|e| pem("tls_cert", &config.tls_cert, &e))?
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| pem("tls_cert", &config.tls_cert, &e))?;
        let key = PrivateKeyDer::from_pem_file(&config.tls_key)
            .map_err(|e| pem("tls_key", &config.tls_key, &e))?;
        builder
            .with_client_auth_cert(chain, key)
            .map_err(|e| pem("tls_cert", &config.tls_cert, &e))?
    };
    Ok(TlsConnector::from(Arc::new(client)))
}

/// A connected TCP or TLS stream, written only.
type Writer = Box<dyn AsyncWrite + Unpin + Send>;

/// Connects to `address`, then makes the TLS handshake when `tls` is given.
async fn connect(
    address: &str,
    tls: Option<&(TlsConnector, ServerName<'static>)>,
) -> std::io::Result<Writer> {
    let stream = TcpStream::connect(address).await?;
    // Small events, sent as they come.
    let _ = stream.set_nodelay(true);
    match tls {
        None => Ok(Box::new(stream)),
        Some((connector, name)) => Ok(Box::new(connector.connect(name.clone(), stream).await?)),
    }
}

/// A UDP socket for sending to `to`: of its address family, with the multicast TTL and
/// loopback set when `to` is a multicast group.
async fn udp_socket(to: SocketAddr, ttl: u32) -> std::io::Result<UdpSocket> {
    let any: SocketAddr = if to.is_ipv4() {
        ([0, 0, 0, 0], 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = UdpSocket::bind(any).await?;
    match to {
        SocketAddr::V4(a) if a.ip().is_multicast() => {
            socket.set_multicast_ttl_v4(ttl)?;
            socket.set_multicast_loop_v4(true)?;
        }
        SocketAddr::V6(a) if a.ip().is_multicast() => socket.set_multicast_loop_v6(true)?,
        _ => {}
    }
    Ok(socket)
}

/// The bytes of one event for UDP and for TCP, built once per event and only when needed.
struct Encoded<'a> {
    event: &'a CotEvent,
    encoding: CotEncoding,
    udp: Option<Arc<[u8]>>,
    tcp: Option<Arc<[u8]>>,
}

impl Encoded<'_> {
    fn udp(&mut self) -> Arc<[u8]> {
        let (event, encoding) = (self.event, self.encoding);
        Arc::clone(self.udp.get_or_insert_with(|| match encoding {
            CotEncoding::Xml => event.to_xml().into_bytes().into(),
            CotEncoding::Protobuf => event.to_mesh().into(),
        }))
    }

    fn tcp(&mut self) -> Arc<[u8]> {
        let (event, encoding) = (self.event, self.encoding);
        Arc::clone(self.tcp.get_or_insert_with(|| match encoding {
            CotEncoding::Xml => event.to_xml().into_bytes().into(),
            CotEncoding::Protobuf => event.to_stream().into(),
        }))
    }
}

/// The sending loop.
async fn run(
    config: CotConfig,
    ctx: FeedContext,
    mut outs: Vec<Out>,
    tcp_tasks: Vec<JoinHandle<()>>,
) {
    let settings = CotSettings {
        cot_type: config.cot_type.clone(),
        vehicle_type: config.vehicle_type.clone(),
        how: config.how.clone(),
        uid_prefix: config.uid_prefix.clone(),
        stale_s: config.stale_s,
    };
    let mut stop = ctx.stop.clone();
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / config.hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            () = stopped(&mut stop) => break,
        }
        let (tracks, vehicles) = {
            let s = ctx.snapshot.borrow();
            (Arc::clone(&s.tracks), Arc::clone(&s.vehicles))
        };
        let now = unix_now();
        let vehicles = vehicles
            .iter()
            .filter(|_| config.vehicles)
            .filter_map(|v| vehicle_event(v, &ctx.frame, &settings, now));
        for event in tracks
            .iter()
            .filter_map(|t| track_event(t, &ctx.frame, &settings, now))
            .chain(vehicles)
        {
            ctx.counters.add(FEED, "events", 1);
            let mut bytes = Encoded {
                event: &event,
                encoding: config.encoding,
                udp: None,
                tcp: None,
            };
            for out in &mut outs {
                send(out, &mut bytes, &ctx.counters);
            }
        }
    }
    drop(outs);
    for t in tcp_tasks {
        if let Err(e) = t.await {
            tracing::warn!(feed = FEED, "a CoT TCP destination ended abnormally: {e}");
        }
    }
}

/// Hands one event to one destination without waiting.
fn send(out: &mut Out, bytes: &mut Encoded<'_>, counters: &FeedCounters) {
    match out {
        Out::Udp { socket, to, log } => match socket.try_send_to(&bytes.udp(), *to) {
            Ok(_) => counters.add(FEED, "sent", 1),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                counters.add(FEED, "dropped", 1);
            }
            Err(e) => {
                counters.add(FEED, "errors", 1);
                if let Some(suppressed) = log.allow() {
                    tracing::warn!(feed = FEED, %to, suppressed, "CoT datagram not sent: {e}");
                }
            }
        },
        Out::Tcp { queue } => match queue.try_send(bytes.tcp()) {
            Ok(()) => {}
            Err(mpsc::error::TrySendError::Full(_) | mpsc::error::TrySendError::Closed(_)) => {
                counters.add(FEED, "dropped", 1);
            }
        },
    }
}

/// Drops what waits in `rx` (counted as `dropped`).
fn drain(rx: &mut mpsc::Receiver<Arc<[u8]>>, counters: &FeedCounters) {
    let mut n = 0;
    while rx.try_recv().is_ok() {
        n += 1;
    }
    if n > 0 {
        counters.add(FEED, "dropped", n);
    }
}

/// One TCP (or, with `tls`, TLS) destination: connects, writes what comes on `rx`, reconnects
/// with doubling waits up to `max_wait`; ends at `stop` (or when the sending loop is gone). A
/// connection (and handshake) that takes over 10 s is given up and tried again.
async fn tcp_peer(
    address: String,
    tls: Option<(TlsConnector, ServerName<'static>)>,
    mut rx: mpsc::Receiver<Arc<[u8]>>,
    counters: Arc<FeedCounters>,
    max_wait: Duration,
    mut stop: watch::Receiver<bool>,
) {
    let mut log = Throttle::default();
    let mut wait = Duration::from_millis(500);
    loop {
        let connected = tokio::select! {
            r = tokio::time::timeout(Duration::from_secs(10), connect(&address, tls.as_ref())) => {
                r.unwrap_or_else(|_| Err(std::io::ErrorKind::TimedOut.into()))
            }
            () = stopped(&mut stop) => return,
        };
        let mut stream = match connected {
            Ok(s) => s,
            Err(e) => {
                counters.add(FEED, "connect_errors", 1);
                if let Some(suppressed) = log.allow() {
                    tracing::warn!(
                        feed = FEED,
                        address,
                        suppressed,
                        "cannot connect to the CoT destination: {e}; again in {wait:?}"
                    );
                }
                drain(&mut rx, &counters);
                tokio::select! {
                    () = tokio::time::sleep(wait) => {}
                    () = stopped(&mut stop) => return,
                }
                drain(&mut rx, &counters);
                wait = (wait * 2).min(max_wait);
                continue;
            }
        };
        counters.add(FEED, "connects", 1);
        tracing::info!(feed = FEED, address, "connected to the CoT destination");
        wait = Duration::from_millis(500);
        loop {
            let bytes = tokio::select! {
                b = rx.recv() => match b {
                    Some(b) => b,
                    None => return,
                },
                () = stopped(&mut stop) => return,
            };
            // Flushed: TLS holds its records until then.
            let written = tokio::select! {
                r = async {
                    stream.write_all(&bytes).await?;
                    stream.flush().await
                } => r,
                () = stopped(&mut stop) => return,
            };
            match written {
                Ok(()) => counters.add(FEED, "sent", 1),
                Err(e) => {
                    counters.add(FEED, "errors", 1);
                    counters.add(FEED, "disconnects", 1);
                    if let Some(suppressed) = log.allow() {
                        tracing::warn!(
                            feed = FEED,
                            address,
                            suppressed,
                            "the CoT destination connection failed: {e}"
                        );
                    }
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::DEFAULT_ORIGIN;
    use harrier_engine::{TrackStatus, TrackView};
    use harrier_link::geo::LocalFrame;
    use std::time::Instant;

    fn event() -> CotEvent {
        let track = TrackView {
            id: 3,
            status: TrackStatus::Confirmed,
            t: 1_790_000_000.0,
            state: [10.0, 20.0, 0.0, 1.0, 0.0, 0.0],
            cov: Vec::new(),
            cov_dims: Vec::new(),
            updated: true,
            age: 5,
            last_update: 1_790_000_000.0,
            mode_probabilities: Vec::new(),
            existence: None,
        };
        let settings = CotSettings {
            cot_type: "a-u-G".into(),
            vehicle_type: "a-f-A".into(),
            how: "m-f".into(),
            uid_prefix: "t".into(),
            stale_s: 10.0,
        };
        let frame = LocalFrame::new(DEFAULT_ORIGIN);
        track_event(&track, &frame, &settings, 1_790_000_000.0).expect("an event")
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn a_stalled_tcp_peer_makes_events_drop_and_never_holds_the_sender() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let address = listener.local_addr().unwrap().to_string();
        let counters = Arc::new(FeedCounters::default());
        let (stop_tx, stop) = watch::channel(false);
        let (queue, rx) = mpsc::channel(4);
        let peer = tokio::spawn(tcp_peer(
            address,
            None,
            rx,
            Arc::clone(&counters),
            Duration::from_secs(1),
            stop,
        ));
        // Accepted, never read: the kernel's buffers fill, then the queue.
        let (_stalled, _) = listener.accept().await.unwrap();
        let e = event();
        let mut out = Out::Tcp { queue };
        let mut slowest = Duration::ZERO;
        let started = Instant::now();
        // Until the writer is stuck: nothing more written over 50 rounds.
        let (mut last_sent, mut still) = (0, 0);
        while still < 50 {
            assert!(started.elapsed() < Duration::from_secs(20), "never stuck");
            for _ in 0..100 {
                let mut bytes = Encoded {
                    event: &e,
                    encoding: CotEncoding::Xml,
                    udp: None,
                    tcp: None,
                };
                let t = Instant::now();
                send(&mut out, &mut bytes, &counters);
                slowest = slowest.max(t.elapsed());
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
            let sent = counters.get(FEED, "sent");
            still = if sent == last_sent { still + 1 } else { 0 };
            last_sent = sent;
        }
        assert!(slowest < Duration::from_millis(50), "{slowest:?}");
        assert!(last_sent > 0);
        assert!(counters.get(FEED, "dropped") > 0);
        // The task stops though its write is stuck.
        stop_tx.send_replace(true);
        tokio::time::timeout(Duration::from_secs(2), peer)
            .await
            .expect("the TCP task ends at stop")
            .unwrap();
    }

    #[tokio::test]
    async fn a_refused_connection_is_retried_and_what_waits_meanwhile_dropped() {
        let closed = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let address = closed.local_addr().unwrap().to_string();
        drop(closed);
        let counters = Arc::new(FeedCounters::default());
        let (stop_tx, stop) = watch::channel(false);
        let (queue, rx) = mpsc::channel(8);
        for _ in 0..3 {
            queue.try_send(Arc::from(&b"x"[..])).unwrap();
        }
        let peer = tokio::spawn(tcp_peer(
            address,
            None,
            rx,
            Arc::clone(&counters),
            Duration::from_secs(1),
            stop,
        ));
        tokio::time::timeout(Duration::from_secs(5), async {
            while counters.get(FEED, "connect_errors") < 2 {
                tokio::time::sleep(Duration::from_millis(20)).await;
            }
        })
        .await
        .expect("retried");
        assert_eq!(counters.get(FEED, "dropped"), 3);
        assert_eq!(counters.get(FEED, "sent"), 0);
        stop_tx.send_replace(true);
        tokio::time::timeout(Duration::from_secs(2), peer)
            .await
            .expect("the TCP task ends at stop")
            .unwrap();
    }
}
