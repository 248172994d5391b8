//! Serving the router on a TCP listener: hyper's HTTP/1 connections, one task each, as
//! `axum::serve` does, with the limits `axum::serve` has no setting for. Without them, clients
//! that open connections and send half a request hold them for ever, and a few hundred of them
//! use up the process's open files (often 1 024): nobody else gets in.
//!
//! - **Header timeout** (`api.header_timeout_s`): a connection that has not sent a whole request
//!   head (request line and headers) this long after it opened, or after its last response
//!   (keep-alive), is closed (hyper's `header_read_timeout`).
//! - **Connection cap** (`api.max_connections`, lowered at start to fit the open-file limit):
//!   every connection counts, WebSockets too, until its socket closes. At the cap a new
//!   connection takes the place of the oldest one still *waiting* (not a whole request head
//!   yet), which is closed; when none waits (each has had a request: in flight, a WebSocket, kept
//!   alive), the new one is closed at once. So a flood of half-sent requests delays nobody: a
//!   user's connection sends its head at once and is served, the flood's wait their turn to be
//!   closed. (Waiting for a free place instead would leave the user behind the flood.)
//! - **Body deadline** (`api.body_timeout_s`): a request's body must have arrived this long after
//!   its head, else 408 (`harrier_http_refused_total{reason="body_timeout"}`).
//! - TCP_NODELAY on every connection, WebSocket upgrades, and a graceful stop: no new
//!   connection, the waiting ones closed, the requests in flight answered.
//!
//! [`ConnectionStats`] counts them for `/metrics`.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::fmt::Write as _;
use std::io;
use std::pin::{Pin, pin};
use std::sync::atomic::{AtomicU8, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, PoisonError};
use std::task::{Context, Poll};
use std::time::{Duration, Instant};

use axum::Router;
use axum::http::{Request, StatusCode};
use axum::response::{IntoResponse, Response};
use hyper::body::Incoming;
use hyper::service::Service as _;
use hyper_util::rt::{TokioIo, TokioTimer};
use hyper_util::service::TowerToHyperService;
use tokio::io::{AsyncRead, AsyncWrite, ReadBuf};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::{Notify, watch};
use tokio::task::JoinSet;
use tower_http::timeout::RequestBodyDeadlineLayer;

use crate::config::ApiConfig;

/// What [`serve`] allows a connection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Longest wait for a whole request head.
    pub header_timeout: Duration,
    /// Longest time from a request's head to the end of its body.
    pub body_timeout: Duration,
    /// Most connections open at once.
    pub max_connections: usize,
}

impl From<&ApiConfig> for Limits {
    fn from(api: &ApiConfig) -> Self {
        Self {
            header_timeout: Duration::from_secs_f64(api.header_timeout_s),
            body_timeout: Duration::from_secs_f64(api.body_timeout_s),
            max_connections: api.max_connections,
        }
    }
}

/// Open files the rest of the service may need beside the API's connections: the Zenoh
/// session's sockets, the recording (database, journal), the MAVLink sockets and `.tlog`, the
/// runtime's own (epoll, event fds), standard streams. `harrier serve` with all of them on
/// (recording, a GCS link, two router endpoints) holds 32 before its first API connection.
const RESERVED_FILES: u64 = 128;

/// `max` lowered, when the process's open-file limit is lower, so that the connections and
/// [`RESERVED_FILES`] fit under it.
fn fit_file_limit(max: usize) -> usize {
    let Some(limit) = file_limit() else {
        return max;
    };
    let room = usize::try_from(limit.saturating_sub(RESERVED_FILES)).unwrap_or(usize::MAX);
    if room >= max {
        return max;
    }
    let fitted = room.max(1);
    tracing::warn!(
        limit,
        "api.max_connections {max} lowered to {fitted} to fit the open-file limit (ulimit -n)"
    );
    fitted
}

/// The soft limit on open files (`ulimit -n`), when there is one.
#[cfg(unix)]
fn file_limit() -> Option<u64> {
    rustix::process::getrlimit(rustix::process::Resource::Nofile).current
}

/// No limit known.
#[cfg(not(unix))]
fn file_limit() -> Option<u64> {
    None
}

/// The API's connections, counted (`/metrics`).
#[derive(Debug, Default)]
pub struct ConnectionStats {
    open: AtomicUsize,
    max: AtomicUsize,
    accepted: AtomicU64,
    header_timeout: AtomicU64,
    idle: AtomicU64,
    evicted: AtomicU64,
    refused: AtomicU64,
    /// Told when a connection's socket closes.
    closed: Notify,
}

impl ConnectionStats {
    /// Connections open now (WebSockets included).
    pub fn open(&self) -> usize {
        self.open.load(Ordering::Relaxed)
    }

    /// The counters in the Prometheus text format.
    pub(super) fn render(&self, out: &mut String) {
        let n = |c: &AtomicU64| c.load(Ordering::Relaxed);
        let _ = writeln!(
            out,
            "# HELP harrier_http_connections Open connections of the API (HTTP and WebSocket).\n\
             # TYPE harrier_http_connections gauge\n\
             harrier_http_connections {}\n\
             # HELP harrier_http_connections_max Most connections at once: api.max_connections, \
             lowered to fit the open-file limit.\n\
             # TYPE harrier_http_connections_max gauge\n\
             harrier_http_connections_max {}\n\
             # HELP harrier_http_connections_accepted_total Connections accepted.\n\
             # TYPE harrier_http_connections_accepted_total counter\n\
             harrier_http_connections_accepted_total {}\n\
             # HELP harrier_http_connections_closed_total Connections the server closed, by \
             reason: header_timeout (no whole request head within api.header_timeout_s), idle \
             (kept alive after a response, then silent as long), evicted (at the cap, the oldest \
             connection without a request, to make room), refused (at the cap, every connection \
             had a request).\n\
             # TYPE harrier_http_connections_closed_total counter",
            self.open(),
            self.max.load(Ordering::Relaxed),
            n(&self.accepted),
        );
        for (reason, c) in [
            ("header_timeout", &self.header_timeout),
            ("idle", &self.idle),
            ("evicted", &self.evicted),
            ("refused", &self.refused),
        ] {
            let _ = writeln!(
                out,
                "harrier_http_connections_closed_total{{reason=\"{reason}\"}} {}",
                n(c)
            );
        }
    }
}

/// A connection has not sent a whole request head yet.
const WAITING: u8 = 0;
/// It has: it is not closed to make room.
const ADMITTED: u8 = 1;
/// It was closed to make room.
const EVICTED: u8 = 2;

/// One connection's place.
#[derive(Debug, Default)]
struct Slot {
    /// [`WAITING`], [`ADMITTED`] or [`EVICTED`].
    state: AtomicU8,
    /// Set when it is evicted.
    evicted: Notify,
}

impl Slot {
    /// Moves a waiting connection to `to`; false when it is not waiting.
    fn leave_waiting(&self, to: u8) -> bool {
        self.state
            .compare_exchange(WAITING, to, Ordering::AcqRel, Ordering::Acquire)
            .is_ok()
    }
}

/// The connections still waiting, oldest (lowest id) first.
#[derive(Debug, Default)]
struct Waiting(Mutex<BTreeMap<u64, Arc<Slot>>>);

impl Waiting {
    fn slots(&self) -> std::sync::MutexGuard<'_, BTreeMap<u64, Arc<Slot>>> {
        self.0.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Closes the oldest waiting connection; false when none waits.
    fn evict_oldest(&self) -> bool {
        let mut slots = self.slots();
        while let Some((_, slot)) = slots.pop_first() {
            if slot.leave_waiting(EVICTED) {
                slot.evicted.notify_one();
                return true;
            }
        }
        false
    }
}

/// A connection's entry in [`Waiting`], removed when the connection ends.
#[derive(Debug)]
struct Entry {
    id: u64,
    slot: Arc<Slot>,
    waiting: Arc<Waiting>,
}

impl Entry {
    fn new(id: u64, waiting: &Arc<Waiting>) -> Self {
        let slot = Arc::new(Slot::default());
        waiting.slots().insert(id, Arc::clone(&slot));
        Self {
            id,
            slot,
            waiting: Arc::clone(waiting),
        }
    }

    /// A request head has arrived: false when the connection was evicted just before.
    fn admit(&self) -> bool {
        if self.slot.leave_waiting(ADMITTED) {
            self.waiting.slots().remove(&self.id);
        }
        self.slot.state.load(Ordering::Acquire) == ADMITTED
    }
}

impl Drop for Entry {
    fn drop(&mut self) {
        self.waiting.slots().remove(&self.id);
    }
}

/// A TCP stream counted in [`ConnectionStats::open`] while it exists (after a WebSocket
/// upgrade too: the upgraded connection owns it).
#[derive(Debug)]
struct Counted {
    stream: TcpStream,
    stats: Arc<ConnectionStats>,
}

impl Counted {
    fn new(stream: TcpStream, stats: &Arc<ConnectionStats>) -> Self {
        stats.open.fetch_add(1, Ordering::Relaxed);
        Self {
            stream,
            stats: Arc::clone(stats),
        }
    }
}

impl Drop for Counted {
    fn drop(&mut self) {
        self.stats.open.fetch_sub(1, Ordering::Relaxed);
        self.stats.closed.notify_one();
    }
}

impl AsyncRead for Counted {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_read(cx, buf)
    }
}

impl AsyncWrite for Counted {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().stream).poll_write(cx, buf)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[io::IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        Pin::new(&mut self.get_mut().stream).poll_write_vectored(cx, bufs)
    }

    fn is_write_vectored(&self) -> bool {
        self.stream.is_write_vectored()
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_flush(cx)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().stream).poll_shutdown(cx)
    }
}

/// Pause after an `accept` that failed for want of resources (open files, memory).
const ACCEPT_PAUSE: Duration = Duration::from_millis(100);

/// Serves `app` on `listener` within `limits`, counting in `stats`, until `stop`; then stops
/// accepting, closes the waiting connections and returns once the others have been answered
/// (WebSockets end on the same `stop`, in [`super::ws`]).
pub async fn serve(
    listener: TcpListener,
    app: Router,
    limits: Limits,
    stats: Arc<ConnectionStats>,
    mut stop: watch::Receiver<bool>,
) {
    let max = fit_file_limit(limits.max_connections);
    stats.max.store(max, Ordering::Relaxed);
    let app =
        TowerToHyperService::new(app.layer(RequestBodyDeadlineLayer::new(limits.body_timeout)));
    let mut http = hyper::server::conn::http1::Builder::new();
    http.timer(TokioTimer::new())
        .header_read_timeout(limits.header_timeout);
    let waiting = Arc::new(Waiting::default());
    let mut connections = JoinSet::new();
    let mut next_id = 0u64;
    let mut warned: Option<Instant> = None;
    loop {
        let accepted = tokio::select! {
            a = listener.accept() => a,
            Some(done) = connections.join_next() => {
                if let Err(e) = done {
                    tracing::warn!("an API connection ended abnormally: {e}");
                }
                continue;
            }
            () = stopped(&mut stop) => break,
        };
        let stream = match accepted {
            Ok((stream, _)) => stream,
            Err(e) if is_connection_error(&e) => continue,
            Err(e) => {
                // Out of open files or memory: a waiting connection's file is the best use.
                if waiting.evict_oldest() {
                    stats.evicted.fetch_add(1, Ordering::Relaxed);
                }
                if warned.is_none_or(|t| t.elapsed() > Duration::from_secs(10)) {
                    tracing::warn!("api: accept: {e}");
                    warned = Some(Instant::now());
                }
                tokio::time::sleep(ACCEPT_PAUSE).await;
                continue;
            }
        };
        stats.accepted.fetch_add(1, Ordering::Relaxed);
        if stats.open() >= max {
            if !waiting.evict_oldest() {
                stats.refused.fetch_add(1, Ordering::Relaxed);
                continue;
            }
            stats.evicted.fetch_add(1, Ordering::Relaxed);
            // Its task drops it at once; waiting for that keeps the open files at `max`
            // however fast connections arrive.
            while stats.open() >= max {
                stats.closed.notified().await;
            }
        }
        // Small WebSocket messages must leave at once: Nagle's algorithm held them back by up
        // to 40 ms (p99 58 ms → 19 ms detection-to-WebSocket in `harrier bench`).
        if let Err(e) = stream.set_nodelay(true) {
            tracing::debug!("TCP_NODELAY: {e}");
        }
        next_id += 1;
        let entry = Arc::new(Entry::new(next_id, &waiting));
        let service = {
            let (app, entry) = (app.clone(), Arc::clone(&entry));
            hyper::service::service_fn(move |req: Request<Incoming>| {
                let call = entry.admit().then(|| app.call(req));
                async move {
                    match call {
                        Some(response) => response.await,
                        None => Ok::<Response, Infallible>(
                            StatusCode::SERVICE_UNAVAILABLE.into_response(),
                        ),
                    }
                }
            })
        };
        let conn = http
            .serve_connection(TokioIo::new(Counted::new(stream, &stats)), service)
            .with_upgrades();
        let (stats, stop) = (Arc::clone(&stats), stop.clone());
        connections.spawn(async move {
            let mut conn = pin!(conn);
            let mut stop = stop;
            let mut stopping = false;
            let ended = loop {
                tokio::select! {
                    r = conn.as_mut() => break r,
                    // Dropping the connection closes its socket.
                    () = entry.slot.evicted.notified() => return,
                    () = stopped(&mut stop), if !stopping => {
                        if entry.slot.leave_waiting(EVICTED) {
                            return;
                        }
                        stopping = true;
                        conn.as_mut().graceful_shutdown();
                    }
                }
            };
            match ended {
                Err(e) if e.is_timeout() => {
                    let admitted = entry.slot.state.load(Ordering::Acquire) == ADMITTED;
                    let c = if admitted {
                        &stats.idle
                    } else {
                        &stats.header_timeout
                    };
                    c.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => tracing::debug!("api connection: {e}"),
                Ok(()) => {}
            }
        });
    }
    drop(listener);
    while let Some(done) = connections.join_next().await {
        if let Err(e) = done {
            tracing::warn!("an API connection ended abnormally: {e}");
        }
    }
}

/// Resolves once `stop` is set (or its sender is gone).
async fn stopped(stop: &mut watch::Receiver<bool>) {
    let _ = stop.wait_for(|s| *s).await;
}

/// An `accept` error that concerns one connection only (the peer gave up), not the listener.
fn is_connection_error(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::ConnectionRefused
            | io::ErrorKind::ConnectionAborted
            | io::ErrorKind::ConnectionReset
    )
}

#[cfg(test)]
mod tests {
    use std::net::SocketAddr;

    use futures_util::StreamExt as _;
    use tokio::io::{AsyncReadExt as _, AsyncWriteExt as _};

    use super::super::testing::{TOKEN, TestApp, WAIT};
    use super::*;

    /// Limits of these tests: `header` and `body` timeouts, at most `max` connections.
    fn limits(header: u64, body: u64, max: usize) -> Limits {
        Limits {
            header_timeout: Duration::from_millis(header),
            body_timeout: Duration::from_millis(body),
            max_connections: max,
        }
    }

    /// `app` served within `limits` on a loopback port: its address, and the stop signal.
    async fn serving(app: &TestApp, limits: Limits) -> (SocketAddr, watch::Sender<bool>) {
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("a port");
        let addr = listener.local_addr().expect("its address");
        let (stop, stop_rx) = watch::channel(false);
        let router = super::super::app(app.state.clone(), None, &[]);
        let stats = Arc::clone(&app.state.service.connections);
        tokio::spawn(serve(listener, router, limits, stats, stop_rx));
        (addr, stop)
    }

    /// A connection that has sent `bytes`.
    async fn sent(addr: SocketAddr, bytes: &str) -> TcpStream {
        let mut s = TcpStream::connect(addr).await.expect("connect");
        s.write_all(bytes.as_bytes()).await.expect("send");
        s
    }

    /// Half a request head.
    const HALF: &str = "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n";
    /// A whole `GET /api/v1/health`, the connection kept alive.
    const HEALTH: &str = "GET /api/v1/health HTTP/1.1\r\nHost: x\r\n\r\n";

    /// What arrives until the server closes `s` (a reset counts as a close).
    async fn until_closed(s: &mut TcpStream) -> String {
        let mut all = Vec::new();
        let mut buf = [0u8; 4096];
        loop {
            let n = tokio::time::timeout(WAIT, s.read(&mut buf))
                .await
                .expect("closed in time")
                .unwrap_or(0);
            if n == 0 {
                return String::from_utf8_lossy(&all).into_owned();
            }
            all.extend_from_slice(&buf[..n]);
        }
    }

    /// Reads one response head and its `Content-Length` body from a kept-alive connection.
    async fn response(s: &mut TcpStream) -> String {
        let mut all = Vec::new();
        let mut buf = [0u8; 4096];
        loop {
            let n = tokio::time::timeout(WAIT, s.read(&mut buf))
                .await
                .expect("a response in time")
                .expect("read");
            assert!(
                n > 0,
                "closed before a response: {:?}",
                String::from_utf8_lossy(&all)
            );
            all.extend_from_slice(&buf[..n]);
            let text = String::from_utf8_lossy(&all).into_owned();
            if let Some((head, body)) = text.split_once("\r\n\r\n") {
                let length: usize = head
                    .lines()
                    .find_map(|l| l.strip_prefix("content-length: "))
                    .and_then(|n| n.parse().ok())
                    .expect("a content-length");
                if body.len() >= length {
                    return text;
                }
            }
        }
    }

    /// Waits until `f` holds.
    async fn until(what: &str, f: impl Fn() -> bool) {
        tokio::time::timeout(WAIT, async {
            while !f() {
                tokio::time::sleep(Duration::from_millis(5)).await;
            }
        })
        .await
        .unwrap_or_else(|_| panic!("not in time: {what}"));
    }

    fn counted(app: &TestApp, series: &str) -> String {
        let mut text = String::new();
        app.state.service.connections.render(&mut text);
        text.lines()
            .find_map(|l| l.strip_prefix(series)?.strip_prefix(' '))
            .unwrap_or_else(|| panic!("{series} not in\n{text}"))
            .to_owned()
    }

    #[tokio::test]
    async fn a_half_sent_request_is_closed_at_the_header_timeout_a_whole_one_answered() {
        let app = TestApp::new();
        let (addr, _stop) = serving(&app, limits(300, 10_000, 16)).await;
        let t0 = Instant::now();
        let mut half = sent(addr, HALF).await;
        let mut whole = sent(addr, HEALTH).await;
        assert!(response(&mut whole).await.starts_with("HTTP/1.1 200 OK"));
        assert_eq!(
            until_closed(&mut half).await,
            "",
            "no answer, only the close"
        );
        let waited = t0.elapsed();
        assert!(
            waited >= Duration::from_millis(300) && waited < Duration::from_secs(2),
            "{waited:?}"
        );
        // The kept-alive connection, silent after its response, is closed as idle.
        assert_eq!(until_closed(&mut whole).await, "");
        until("both counted", || {
            counted(
                &app,
                "harrier_http_connections_closed_total{reason=\"header_timeout\"}",
            ) == "1"
                && counted(
                    &app,
                    "harrier_http_connections_closed_total{reason=\"idle\"}",
                ) == "1"
        })
        .await;
        until("none open", || app.state.service.connections.open() == 0).await;
        assert_eq!(
            counted(&app, "harrier_http_connections_accepted_total"),
            "2"
        );
        assert_eq!(counted(&app, "harrier_http_connections_max"), "16");
    }

    #[tokio::test]
    async fn at_the_cap_a_new_connection_replaces_the_oldest_waiting_one_else_is_refused() {
        let app = TestApp::new();
        let stats = Arc::clone(&app.state.service.connections);
        let (addr, _stop) = serving(&app, limits(30_000, 10_000, 2)).await;
        let mut oldest = sent(addr, HALF).await;
        until("one open", || stats.open() == 1).await;
        let mut second = sent(addr, HALF).await;
        until("two open", || stats.open() == 2).await;
        // A user's whole request at the cap: answered; the oldest waiting connection closed.
        let mut user = sent(addr, HEALTH).await;
        assert!(response(&mut user).await.starts_with("HTTP/1.1 200 OK"));
        assert_eq!(until_closed(&mut oldest).await, "");
        // The second still waits; a second user replaces it.
        let mut other = sent(addr, HEALTH).await;
        assert!(response(&mut other).await.starts_with("HTTP/1.1 200 OK"));
        assert_eq!(until_closed(&mut second).await, "");
        // Both places hold kept-alive connections that have had a request: a new one is
        // closed at once, and they are not disturbed.
        let mut refused = sent(addr, HEALTH).await;
        assert_eq!(until_closed(&mut refused).await, "");
        user.write_all(HEALTH.as_bytes()).await.expect("send");
        assert!(response(&mut user).await.starts_with("HTTP/1.1 200 OK"));
        assert_eq!(
            (
                counted(
                    &app,
                    "harrier_http_connections_closed_total{reason=\"evicted\"}"
                ),
                counted(
                    &app,
                    "harrier_http_connections_closed_total{reason=\"refused\"}"
                ),
                counted(&app, "harrier_http_connections"),
            ),
            ("2".into(), "1".into(), "2".into())
        );
    }

    #[tokio::test]
    async fn a_body_that_does_not_arrive_in_time_gets_a_counted_408() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        // Without and with a recording: the body is read by the route, or by the guard.
        for app in [TestApp::new(), TestApp::new().with_recording(dir.path())] {
            let (addr, _stop) = serving(&app, limits(10_000, 300, 16)).await;
            let mut s = sent(
                addr,
                &format!(
                    "PUT /api/v1/estimator HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\n\
                     Content-Type: application/json\r\nContent-Length: 100\r\n\r\n{{\"name\":"
                ),
            )
            .await;
            let reply = until_closed(&mut s).await;
            assert!(reply.starts_with("HTTP/1.1 408 Request Timeout"), "{reply}");
            assert!(
                reply.ends_with(
                    r#"{"error":"the request body did not arrive in time (api.body_timeout_s)"}"#
                ),
                "{reply}"
            );
            assert_eq!(app.refused("body_timeout", 408), 1);
        }
    }

    #[tokio::test]
    async fn a_websocket_works_and_counts_until_it_closes() {
        let app = TestApp::new();
        let stats = Arc::clone(&app.state.service.connections);
        let (addr, _stop) = serving(&app, limits(10_000, 10_000, 16)).await;
        let (mut ws, _) = tokio_tungstenite::connect_async(format!("ws://{addr}/api/v1/ws"))
            .await
            .expect("a WebSocket");
        let first = tokio::time::timeout(WAIT, ws.next())
            .await
            .expect("a message in time")
            .expect("a message")
            .expect("a good message");
        assert!(first.into_text().expect("text").contains("\"snapshot\""));
        assert_eq!(stats.open(), 1, "upgraded, still counted");
        drop(ws);
        until("closed", || stats.open() == 0).await;
    }

    #[tokio::test]
    async fn a_stop_closes_the_waiting_connections_and_returns() {
        let app = TestApp::new();
        let listener = TcpListener::bind("127.0.0.1:0").await.expect("a port");
        let addr = listener.local_addr().expect("its address");
        let (stop, stop_rx) = watch::channel(false);
        let router = super::super::app(app.state.clone(), None, &[]);
        let stats = Arc::clone(&app.state.service.connections);
        let served = tokio::spawn(serve(
            listener,
            router,
            limits(30_000, 10_000, 16),
            stats,
            stop_rx,
        ));
        let mut half = sent(addr, HALF).await;
        let mut kept = sent(addr, HEALTH).await;
        assert!(response(&mut kept).await.starts_with("HTTP/1.1 200 OK"));
        until("both open", || app.state.service.connections.open() == 2).await;
        stop.send_replace(true);
        tokio::time::timeout(WAIT, served)
            .await
            .expect("serve returns at once")
            .expect("serve ends well");
        assert_eq!(until_closed(&mut half).await, "");
        assert_eq!(until_closed(&mut kept).await, "");
    }
}
