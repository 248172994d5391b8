//! The WebSocket clients: each connects to `/api/v1/ws`, expects a `snapshot` first, then one
//! `scan` message per processed scan with consecutive `seq` (`harrier_server::http::ws`). A gap in `seq`,
//! or a later `snapshot` with `dropped > 0`, is a missing update. The latency of a `scan` message is
//! its receipt's wall time minus its `t`: the scan's `time_unix`, stamped by the publisher.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};
use std::time::Duration;

use anyhow::Context as _;
use futures_util::StreamExt as _;
use serde::{Deserialize, Serialize};
use tokio::sync::watch;
use tokio::task::JoinHandle;
use tokio_tungstenite::tungstenite::Message;

use super::stats::{Histogram, Percentiles, now_unix};

/// Longest wait for a client's connection and first snapshot.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(30);

/// The fields of a stream message the clients look at.
#[derive(Debug, Deserialize)]
struct Header {
    #[serde(rename = "type")]
    kind: String,
    /// `scan` and `snapshot` messages only.
    #[serde(default)]
    seq: u64,
    t: Option<f64>,
    #[serde(default)]
    dropped: u64,
}

/// What every client counts, shared.
#[derive(Debug, Default)]
pub(super) struct WsStats {
    /// `scan` messages received.
    scans: AtomicU64,
    /// Scan messages missing: `seq` gaps and the scans a resync snapshot skipped.
    missing: AtomicU64,
    /// Later snapshots (the client fell behind and was dropped to the latest state).
    resyncs: AtomicU64,
    /// `scan` messages whose `seq` was not above the last one.
    out_of_order: AtomicU64,
    /// Connections refused or lost, messages that are not the stream's.
    errors: AtomicU64,
    /// Latency of `scan` messages received while `recording`.
    latency: Histogram,
    /// Whether latencies are recorded now (the steady state).
    recording: AtomicBool,
    /// Bytes of every text message received, over every client.
    bytes: AtomicU64,
    /// Bytes of the `vehicles` messages among them.
    vehicle_bytes: AtomicU64,
}

impl WsStats {
    /// `scan` messages received so far, over every client.
    pub(super) fn scans(&self) -> u64 {
        self.scans.load(Relaxed)
    }
    /// Starts or stops recording latencies.
    pub(super) fn record(&self, on: bool) {
        self.recording.store(on, Relaxed);
    }
    /// The latency percentiles so far (ms).
    pub(super) fn latency(&self) -> Percentiles {
        self.latency.percentiles()
    }
    /// Bytes received so far, over every client: all messages, and the `vehicles` ones.
    pub(super) fn bytes(&self) -> (u64, u64) {
        (self.bytes.load(Relaxed), self.vehicle_bytes.load(Relaxed))
    }
}

/// What the WebSocket clients measured.
#[derive(Debug, Clone, Default, Serialize)]
pub struct WsReport {
    /// Clients asked for.
    pub clients: usize,
    /// `scan` messages received, over every client.
    pub scan_messages: u64,
    /// `scan` messages expected: for each client, the scans the server processed after its first
    /// snapshot.
    pub expected: u64,
    /// Missing updates: `seq` gaps, the scans resync snapshots skipped, and what a client had
    /// not received when the run ended.
    pub missing: u64,
    /// Resync snapshots (a client fell behind).
    pub resyncs: u64,
    /// `scan` messages whose `seq` was not above the last.
    pub out_of_order: u64,
    /// Connection errors and unreadable messages.
    pub errors: u64,
    /// Scan publication (`time_unix`) → receipt by a client, steady state only (ms).
    pub latency_ms: Percentiles,
    /// Bytes per second one client received over the steady state (every message type).
    pub bytes_per_s: f64,
    /// Of which the `vehicles` messages (10 Hz, every vehicle).
    pub vehicles_bytes_per_s: f64,
}

/// One client's progress.
#[derive(Debug, Default)]
struct Client {
    /// `seq` of the first snapshot.
    first: AtomicU64,
    /// The last `seq` seen.
    last: AtomicU64,
}

/// The connected clients. End them with [`Clients::finish`].
#[derive(Debug)]
pub(super) struct Clients {
    stats: Arc<WsStats>,
    clients: Vec<Arc<Client>>,
    stop: watch::Sender<bool>,
    tasks: Vec<JoinHandle<()>>,
}

impl Clients {
    /// Connects `n` clients to `url` and waits until each has its first snapshot.
    pub(super) async fn connect(url: &str, n: usize) -> anyhow::Result<Self> {
        let stats = Arc::new(WsStats::default());
        let (stop, stop_rx) = watch::channel(false);
        let connects = (0..n).map(|_| async {
            let (mut socket, _) =
                tokio::time::timeout(CONNECT_TIMEOUT, tokio_tungstenite::connect_async(url))
                    .await
                    .context("no connection within 30 s")?
                    .with_context(|| format!("WebSocket {url}"))?;
            let first = tokio::time::timeout(CONNECT_TIMEOUT, socket.next())
                .await
                .context("no snapshot within 30 s")?
                .context("closed before the snapshot")??;
            let h = match &first {
                Message::Text(text) => serde_json::from_str::<Header>(text.as_str())?,
                m => anyhow::bail!("the first message is not a text frame: {m:?}"),
            };
            anyhow::ensure!(h.kind == "snapshot", "the first message is a {}", h.kind);
            let client = Arc::new(Client::default());
            client.first.store(h.seq, Relaxed);
            client.last.store(h.seq, Relaxed);
            Ok((socket, client))
        });
        let connected = futures_util::future::join_all(connects).await;
        let mut clients = Vec::new();
        let mut tasks = Vec::new();
        for c in connected {
            let (socket, client) = c.context("a WebSocket client")?;
            tasks.push(tokio::spawn(read(
                socket,
                Arc::clone(&client),
                Arc::clone(&stats),
                stop_rx.clone(),
            )));
            clients.push(client);
        }
        Ok(Self {
            stats,
            clients,
            stop,
            tasks,
        })
    }

    /// The shared counters.
    pub(super) fn stats(&self) -> &Arc<WsStats> {
        &self.stats
    }

    /// Waits (up to `timeout`) until every client has seen `final_seq`, then closes them.
    pub(super) async fn finish(self, final_seq: u64, timeout: Duration) -> WsReport {
        let waited = tokio::time::Instant::now();
        while waited.elapsed() < timeout
            && self
                .clients
                .iter()
                .any(|c| c.last.load(Relaxed) < final_seq)
        {
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
        let _ = self.stop.send(true);
        for t in self.tasks {
            if t.await.is_err() {
                self.stats.errors.fetch_add(1, Relaxed);
            }
        }
        let s = &self.stats;
        let tail: u64 = self
            .clients
            .iter()
            .map(|c| final_seq.saturating_sub(c.last.load(Relaxed)))
            .sum();
        WsReport {
            clients: self.clients.len(),
            scan_messages: s.scans.load(Relaxed),
            expected: self
                .clients
                .iter()
                .map(|c| final_seq.saturating_sub(c.first.load(Relaxed)))
                .sum(),
            missing: s.missing.load(Relaxed) + tail,
            resyncs: s.resyncs.load(Relaxed),
            out_of_order: s.out_of_order.load(Relaxed),
            errors: s.errors.load(Relaxed),
            latency_ms: s.latency.percentiles(),
            // Filled in by the report, from the steady state's samples.
            bytes_per_s: 0.0,
            vehicles_bytes_per_s: 0.0,
        }
    }
}

type Socket =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

/// One client's reading loop, until `stop` (then it closes the connection) or the server closes.
async fn read(
    mut socket: Socket,
    client: Arc<Client>,
    stats: Arc<WsStats>,
    mut stop: watch::Receiver<bool>,
) {
    loop {
        let m = tokio::select! {
            m = socket.next() => m,
            _ = async { stop.wait_for(|s| *s).await.is_ok() } => {
                let _ = socket.close(None).await;
                return;
            }
        };
        let received = now_unix();
        let text = match m {
            Some(Ok(Message::Text(text))) => text,
            Some(Ok(Message::Close(_))) | None => {
                // The server ended the stream before the run did.
                stats.errors.fetch_add(1, Relaxed);
                return;
            }
            Some(Ok(_)) => continue,
            Some(Err(_)) => {
                stats.errors.fetch_add(1, Relaxed);
                return;
            }
        };
        stats.bytes.fetch_add(text.len() as u64, Relaxed);
        let Ok(h) = serde_json::from_str::<Header>(text.as_str()) else {
            stats.errors.fetch_add(1, Relaxed);
            continue;
        };
        let last = client.last.load(Relaxed);
        match h.kind.as_str() {
            "scan" => {
                stats.scans.fetch_add(1, Relaxed);
                if h.seq <= last {
                    stats.out_of_order.fetch_add(1, Relaxed);
                    continue;
                }
                stats.missing.fetch_add(h.seq - last - 1, Relaxed);
                client.last.store(h.seq, Relaxed);
                if let Some(t) = h.t.filter(|_| stats.recording.load(Relaxed)) {
                    stats.latency.record_s(received - t);
                }
            }
            "vehicles" => {
                stats.vehicle_bytes.fetch_add(text.len() as u64, Relaxed);
            }
            "vehicle_event" | "assignment" => {}
            "snapshot" => {
                stats.resyncs.fetch_add(1, Relaxed);
                // The scans between the last one seen and the snapshot never came (the server's
                // `dropped` counts only those that fell out of the client's queue).
                let skipped = h.seq.saturating_sub(last).max(h.dropped);
                stats.missing.fetch_add(skipped, Relaxed);
                client.last.store(h.seq.max(last), Relaxed);
            }
            _ => {
                stats.errors.fetch_add(1, Relaxed);
            }
        }
    }
}
