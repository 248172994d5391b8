//! The live ground-station service (`harrier serve`): detections from Zenoh in, tracks out over
//! HTTP.
//!
//! Three actors (tokio tasks) joined by bounded channels, data flowing one way:
//!
//! ```text
//! Zenoh subscriber ─try_send─▶ [ingest] ─send─▶ [tracker] ─watch (latest snapshot)──▶ [API]
//!   (callback, drops when full)  decode, frame   reorder,    └broadcast (track events)─▶ subscribers
//! ```
//!
//! - [`ingest`]: payloads of `harrier/v1/vehicle/*/detections` decoded and validated
//!   ([`harrier_core::detection::DetectionScan::from_json`]), `seq` gaps counted, converted into
//!   the server's ENU frame (harrier-link's `scan_in_frame`) as [`crate::engine::SensorScan`]s.
//! - [`tracker`]: the `Box<dyn TrackEngine>` of [`crate::registry::build_track_engine`], fed in
//!   time order through a short reorder buffer; snapshots to a `watch`, events to a `broadcast`.
//!   Scans are put on one time line by their `time_unix` (UNIX time on the sender's clock) when
//!   they carry it, else by their `t` — so publishers without `time_unix` are only fused with
//!   others on the same clock.
//! - [`api`]: axum routes under `/api/v1` (tracks, health, estimators, Prometheus metrics).
//! - [`config`]: the TOML configuration and the deployment [`Scenario`](harrier_core::scenario::Scenario)
//!   it describes; [`metrics`]: the counters.
//!
//! Nothing from the network can panic the service: bad payloads are counted per vehicle and
//! reason, logged at a bounded rate and dropped. A slow consumer never stalls tracking: the
//! Zenoh callback never blocks (a full queue drops), the snapshot is a `watch` and events a
//! bounded `broadcast` (lagging receivers lose events).

pub mod api;
pub mod config;
pub mod ingest;
pub mod metrics;
pub mod recorder;
pub mod tracker;

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Instant;

use harrier_core::detection::DETECTIONS_KEY_ALL;
use harrier_core::measurement::Geometry;
use harrier_link::geo::LocalFrame;
use tokio::sync::{broadcast, mpsc, oneshot, watch};
use tokio::task::JoinHandle;

use self::config::{Config, ConfigError};
use self::ingest::{Ingest, Payload};
use self::metrics::{DropReason, Metrics};
use self::tracker::{ScanEvents, Snapshot, TrackerActor};
use crate::engine::EngineError;

/// Why the service could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    /// The configuration is unusable.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The track engine cannot be built.
    #[error("track engine: {0}")]
    Engine(#[from] EngineError),
    /// The API address cannot be bound.
    #[error("cannot listen on {addr}: {source}")]
    Bind {
        /// The address.
        addr: SocketAddr,
        /// Why.
        source: std::io::Error,
    },
    /// The Zenoh session or subscriber cannot be opened.
    #[error("zenoh: {0}")]
    Zenoh(String),
}

/// Capacity of the track-event broadcast (scans; a receiver further behind loses events).
const EVENTS_CAPACITY: usize = 256;

/// The running service. Stop it with [`LiveServer::shutdown`].
#[derive(Debug)]
pub struct LiveServer {
    addr: SocketAddr,
    metrics: Arc<Metrics>,
    snapshot: watch::Receiver<Arc<Snapshot>>,
    events: broadcast::Sender<Arc<ScanEvents>>,
    stop_api: oneshot::Sender<()>,
    tasks: Vec<JoinHandle<()>>,
    subscriber: zenoh::pubsub::Subscriber<()>,
    session: zenoh::Session,
}

impl LiveServer {
    /// The address the API listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }
    /// The counters.
    pub fn metrics(&self) -> &Metrics {
        &self.metrics
    }
    /// The latest snapshot (updated after every processed scan).
    pub fn snapshot(&self) -> watch::Receiver<Arc<Snapshot>> {
        self.snapshot.clone()
    }
    /// The track events of every scan processed from now on.
    pub fn subscribe_events(&self) -> broadcast::Receiver<Arc<ScanEvents>> {
        self.events.subscribe()
    }

    /// Stops the subscription, lets the actors finish what they hold, stops the API.
    pub async fn shutdown(self) {
        if let Err(e) = self.subscriber.undeclare().await {
            tracing::warn!("zenoh: undeclare the subscriber: {e}");
        }
        if let Err(e) = self.session.close().await {
            tracing::warn!("zenoh: close the session: {e}");
        }
        let _ = self.stop_api.send(());
        for t in self.tasks {
            if let Err(e) = t.await {
                tracing::warn!("a live actor ended abnormally: {e}");
            }
        }
    }
}

/// Starts the service: builds the engine, binds the API, opens the Zenoh session and subscribes.
/// Returns once all of it is up (the API accepts connections).
pub async fn start(config: &Config) -> Result<LiveServer, LiveError> {
    config.check()?;
    let scenario = config.scenario()?;
    let engine_name = config.tracker.estimator.clone();
    let engine = crate::registry::build_track_engine(&engine_name, &scenario, &config.params())?;
    let metrics = Arc::new(Metrics::default());
    let started = Instant::now();

    let listener = tokio::net::TcpListener::bind(config.api.listen)
        .await
        .map_err(|source| LiveError::Bind {
            addr: config.api.listen,
            source,
        })?;
    let addr = listener.local_addr().map_err(|source| LiveError::Bind {
        addr: config.api.listen,
        source,
    })?;

    let queue = config.tracker.queue;
    let (payload_tx, payload_rx) = mpsc::channel::<Payload>(queue);
    let (scan_tx, scan_rx) = mpsc::channel(queue);
    let (snap_tx, snap_rx) = watch::channel(Arc::new(Snapshot::default()));
    let (events_tx, _) = broadcast::channel(EVENTS_CAPACITY);

    let zenoh_config = config
        .bus()?
        .to_zenoh()
        .map_err(|e| LiveError::Zenoh(e.to_string()))?;
    let session = zenoh::open(zenoh_config)
        .await
        .map_err(|e| LiveError::Zenoh(format!("cannot open a session: {e}")))?;
    let m = Arc::clone(&metrics);
    let subscriber = session
        .declare_subscriber(DETECTIONS_KEY_ALL)
        .callback(move |sample| {
            let p = Payload::new(
                sample.key_expr().as_str(),
                sample.payload().to_bytes().into_owned(),
            );
            m.received(&p.vehicle);
            if let Err(mpsc::error::TrySendError::Full(p)) = payload_tx.try_send(p) {
                m.dropped(&p.vehicle, DropReason::QueueFull);
            }
        })
        .await
        .map_err(|e| LiveError::Zenoh(format!("subscribe {DETECTIONS_KEY_ALL}: {e}")))?;

    let frame = LocalFrame::new(config.frame.origin);
    let ingest = Ingest::new(
        frame,
        Geometry::planar(config.frame.plane_z),
        Arc::clone(&metrics),
    );
    let actor = TrackerActor::new(
        engine,
        config.tracker.reorder_window_s,
        Arc::clone(&metrics),
        snap_tx,
        events_tx.clone(),
    );
    let app = api::app(api::ApiState {
        snapshot: snap_rx.clone(),
        metrics: Arc::clone(&metrics),
        engine: engine_name,
        started,
    });
    let (stop_api, stop_rx) = oneshot::channel::<()>();
    let serve = async move {
        let shutdown = async move {
            let _ = stop_rx.await;
        };
        if let Err(e) = axum::serve(listener, app)
            .with_graceful_shutdown(shutdown)
            .await
        {
            tracing::error!("api: {e}");
        }
    };
    let tasks = vec![
        tokio::spawn(ingest.run(payload_rx, scan_tx)),
        tokio::spawn(actor.run(scan_rx)),
        tokio::spawn(serve),
    ];
    tracing::info!(%addr, "live service started");
    Ok(LiveServer {
        addr,
        metrics,
        snapshot: snap_rx,
        events: events_tx,
        stop_api,
        tasks,
        subscriber,
        session,
    })
}
