//! # harrier-server
//!
//! The live ground-station service (`harrier serve`): detections from Zenoh in, tracks out over
//! HTTP, WebSocket and Zenoh.
//!
//! An actor (tokio task) per concern, joined by bounded channels, data flowing one way:
//!
//! ```text
//! Zenoh subscriber ─try_send─▶ [ingest] ─send─▶ [tracker] ─watch (latest snapshot)──▶ [http], [publisher] ─▶ Zenoh
//!   (callback, drops when full)  decode, frame   reorder,    ├broadcast (each scan)──▶ WebSocket clients
//!                                                 estimator   └sinks (try_send)──────▶ [recorder] ─▶ SQLite
//!                                                   ▲ commands (change estimator) ◀─ [http]
//! ```
//!
//! - [`ingest`]: payloads of `harrier/v1/vehicle/*/detections` decoded and validated
//!   ([`harrier_core::detection::DetectionScan::from_json`]), `seq` gaps counted, converted into
//!   the server's ENU frame (harrier-link's `scan_in_frame`) as [`harrier_engine::SensorScan`]s.
//! - [`tracker`]: the `Box<dyn TrackEngine>` of [`harrier_engine::registry::build_track_filter`], fed in
//!   time order through a short reorder buffer; snapshots to a `watch`, each processed scan to a
//!   bounded `broadcast`. Scans are put on one time line by their `time_unix` (UNIX time on the
//!   sender's clock) when they carry it, else by their `t` — so publishers without `time_unix`
//!   are only fused with others on the same clock. The estimator can be changed at run time; the
//!   live tracks are handed over.
//! - [`http`]: the HTTP layer (axum), the only module that knows HTTP: [`http::app`] (routes
//!   under `/api/v1`, the OpenAPI document, `/metrics`, the dashboard), one file per resource,
//!   the WebSocket stream ([`http::ws`]) and one error type; nothing else in the service
//!   imports it. [`world`]: the simulator's truth in the server's frame and the configuration's
//!   roads and obstacles; [`publish`]: the tracks on Zenoh (the recording is [`harrier_recording`]).
//!   [`wire`]: the typed messages that leave on a stream (WebSocket, Zenoh tracks) and the
//!   track as the API sends it.
//! - [`config`]: the TOML configuration and the [`Deployment`](harrier_engine::Deployment) it
//!   describes; [`metrics`]: the counters.
//!
//! [`start`] puts it together in the diagram's order, a step per private module: the recording
//! (`open_recording`), `bus` (the Zenoh session: the two subscriptions and the tracks'
//! publisher), `pipeline` (ingest, tracker, publisher), `control` (when `mavlink.gcs` is set:
//! [`gcs`], its traffic, [`guidance`], the vehicles' recording), then the HTTP API
//! ([`http::app`] served on the bound listener).
//!
//! Nothing from the network can panic the service: bad payloads are counted per vehicle and
//! reason, logged at a bounded rate and dropped. A slow consumer never stalls tracking: the
//! Zenoh callback never blocks (a full queue drops), the snapshot is a `watch`, scans go to a
//! bounded `broadcast` (a lagging WebSocket client is dropped to the latest snapshot) and to the
//! recorder by `try_send`.

pub mod bound;
mod bus;
pub mod clock;
pub mod config;
mod control;
mod error;
pub mod feeds;
pub mod gcs;
pub mod guidance;
pub mod http;
pub mod ingest;
pub mod map;
pub mod metrics;
mod pipeline;
pub mod prom;
pub mod publish;
pub mod tracker;
pub mod wire;
pub mod world;

use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

use tokio::sync::{broadcast, watch};
use tokio::task::JoinHandle;

use self::bus::Bus;
use self::config::Config;
use self::control::Control;
use self::feeds::{FeedContext, FeedCounters, Feeds};
use self::http::{ApiState, Auth, Service, Tracking};
use self::metrics::Metrics;
use self::pipeline::Pipeline;
use self::tracker::{ScanEvents, Snapshot, TrackFilterState};
use self::world::{TruthBody, WorldBody};
use harrier_recording::writer::{Recorder, SessionMeta};

pub use self::error::LiveError;

/// Where the API token came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TokenSource {
    /// `api.token` of the configuration.
    Config,
    /// The `HARRIER_TOKEN` environment variable.
    Env,
    /// Generated at start (print it for the operator).
    Generated,
}

/// The API token: `HARRIER_TOKEN`, else `api.token`, else 32 random hex digits.
fn token(config: &Config) -> (String, TokenSource) {
    match std::env::var("HARRIER_TOKEN") {
        Ok(t) if !t.is_empty() => (t, TokenSource::Env),
        _ if !config.api.token.is_empty() => (config.api.token.clone(), TokenSource::Config),
        _ => {
            use rand::Rng as _;
            let mut rng = rand::rng();
            let t = (0..16)
                .map(|_| format!("{:02x}", rng.random::<u8>()))
                .collect();
            (t, TokenSource::Generated)
        }
    }
}

/// The directory of the dashboard: `api.web_dir`, else the repository's `web/` when it exists.
fn web_dir(config: &Config) -> Option<PathBuf> {
    if !config.api.web_dir.is_empty() {
        return Some(PathBuf::from(&config.api.web_dir));
    }
    let repo = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../web"));
    repo.is_dir().then_some(repo)
}

/// The running service. Stop it with [`LiveServer::shutdown`].
#[derive(Debug)]
pub struct LiveServer {
    addr: SocketAddr,
    token: (String, TokenSource),
    metrics: Arc<Metrics>,
    bus: Bus,
    pipeline: Pipeline,
    recording: http::Recording,
    control: Control,
    feeds: Feeds,
    feed_counters: Arc<FeedCounters>,
    api: JoinHandle<()>,
    stop: watch::Sender<bool>,
}

impl LiveServer {
    /// The MAVLink GCS link, when `mavlink.gcs` is set.
    pub fn link(&self) -> Option<&gcs::GcsLink> {
        self.control.link.as_ref()
    }
    /// The guidance loop, when the link runs.
    pub fn guidance(&self) -> Option<&guidance::Guidance> {
        self.control.guidance.as_ref()
    }
    /// The address the API listens on.
    pub fn local_addr(&self) -> SocketAddr {
        self.addr
    }
    /// The API token mutating requests need, and where it came from.
    pub fn token(&self) -> (&str, TokenSource) {
        (&self.token.0, self.token.1)
    }
    /// The counters.
    pub fn metrics(&self) -> &Metrics {
        &self.metrics
    }
    /// The field-format feeds' counters (they outlive the service: read them after
    /// [`LiveServer::shutdown`] for the final counts).
    pub fn feed_counters(&self) -> Arc<FeedCounters> {
        Arc::clone(&self.feed_counters)
    }
    /// The address of the Foxglove WebSocket server, when `[foxglove]` is on.
    pub fn foxglove_addr(&self) -> Option<SocketAddr> {
        self.feeds.foxglove
    }
    /// The latest snapshot (updated after every processed scan).
    pub fn snapshot(&self) -> watch::Receiver<Arc<Snapshot>> {
        self.pipeline.snapshot.clone()
    }
    /// Every scan processed from now on, with its track events.
    pub fn subscribe_events(&self) -> broadcast::Receiver<Arc<ScanEvents>> {
        self.pipeline.events.subscribe()
    }
    /// The session recorder, when `recorder.path` is set.
    pub fn recorder(&self) -> Option<&Recorder> {
        self.recording.recorder.as_ref()
    }
    /// Why the service runs without a recording although `recorder.path` is set (the file or
    /// its directory could not be opened: read-only, full, not a session file).
    pub fn recording_error(&self) -> Option<&str> {
        self.recording.error.as_deref()
    }
    /// The Zenoh session of the service (for an in-process peer, e.g. `harrier demo`).
    pub fn session(&self) -> &zenoh::Session {
        self.bus.session()
    }

    /// Stops the subscriptions, lets the actors finish what they hold (the recorder commits),
    /// then stops the API and closes the Zenoh session.
    pub async fn shutdown(mut self) {
        self.bus.unsubscribe().await;
        self.pipeline.join().await;
        if let Some(r) = self.recording.recorder {
            match tokio::task::spawn_blocking(move || r.close()).await {
                Ok(Ok(stats)) => tracing::info!(?stats, "recording closed"),
                Ok(Err(e)) => tracing::warn!("closing the recording: {e}"),
                Err(e) => tracing::warn!("closing the recording: {e}"),
            }
        }
        let _ = self.stop.send(true);
        if let Err(e) = self.api.await {
            tracing::warn!("the API ended abnormally: {e}");
        }
        self.control.join().await;
        self.feeds.join().await;
        self.bus.close().await;
    }
}

/// Starts the service in the order of the diagram above: the recording, the Zenoh
/// subscriptions, the pipeline (ingest, tracker, publisher), the vehicles' side (link, traffic,
/// guidance) and the HTTP API. Returns once all of it is up (the API accepts connections).
pub async fn start(config: &Config) -> Result<LiveServer, LiveError> {
    config.check()?;
    let deployment = config.deployment();
    let estimator = TrackFilterState::of(&config.tracker);
    let engine = estimator.build(&deployment)?;
    let engine = pipeline::Engine {
        engine,
        deployment,
        estimator,
    };
    let metrics = Arc::new(Metrics::default());
    let started = Instant::now();
    let (listener, addr) = bind(config.api.listen)?;
    // Before anything is spawned: a bad `map.mbtiles` stops the start at once.
    let tiles = Arc::new(map::MapService::open(config).await?);
    let (stop, stop_rx) = watch::channel(false);

    let recording = open_recording(config, &config.tracker.estimator);
    let recorder = recording.recorder.as_ref();
    let (bus, inputs) = Bus::subscribe(config, &metrics, recorder).await?;
    let publisher = bus.tracks_publisher(config).await?;
    let pipeline = Pipeline::spawn(
        config,
        engine,
        inputs.payloads,
        publisher,
        &metrics,
        recorder,
    );
    let control = Control::spawn(config, &pipeline.snapshot, recorder, &stop_rx).await?;
    if let Some(link) = control
        .link
        .as_ref()
        .filter(|_| !config.registration.sensors.is_empty())
    {
        // The UAVs' own GPS positions: the cooperative references of sensor registration.
        let vehicles = tracker::Command::References(link.vehicles.clone());
        if pipeline.commands.send(vehicles).await.is_err() {
            tracing::warn!("the tracker stopped before it got the link's vehicles");
        }
    }
    let feed_counters = Arc::new(FeedCounters::default());
    let feeds = Feeds::spawn(
        config,
        &FeedContext {
            snapshot: pipeline.snapshot.clone(),
            events: pipeline.events.clone(),
            frame: harrier_link::geo::LocalFrame::new(config.frame.origin),
            counters: Arc::clone(&feed_counters),
            stop: stop_rx.clone(),
        },
    )
    .await?;

    let token = token(config);
    let connections = Arc::new(http::ConnectionStats::default());
    let service = Service {
        metrics: Arc::clone(&metrics),
        auth: Arc::new(Auth::new(&token.0, &config.api)),
        started,
        stop: stop_rx.clone(),
        connections: Arc::clone(&connections),
        feeds: Arc::clone(&feed_counters),
    };
    let state = api_state(
        config,
        &pipeline,
        inputs.truth,
        &feeds,
        &control,
        &recording,
        service,
        tiles,
    );
    let app = http::app(state, web_dir(config).as_deref(), &config.api.cors_origins);
    let limits = http::Limits::from(&config.api);
    let api = tokio::spawn(http::serve(listener, app, limits, connections, stop_rx));
    tracing::info!(%addr, estimator = config.tracker.estimator, "live service started");
    Ok(LiveServer {
        addr,
        token,
        metrics,
        bus,
        pipeline,
        recording,
        control,
        feeds,
        feed_counters,
        api,
        stop,
    })
}

/// What the HTTP handlers read: the parts of the running service, the configuration's world.
// One argument per part of the running service, as `start` made them.
#[allow(clippy::too_many_arguments)]
fn api_state(
    config: &Config,
    pipeline: &Pipeline,
    truth: watch::Receiver<Arc<TruthBody>>,
    feeds: &Feeds,
    control: &Control,
    recording: &http::Recording,
    service: Service,
    map: Arc<map::MapService>,
) -> ApiState {
    ApiState {
        tracking: Tracking {
            snapshot: pipeline.snapshot.clone(),
            events: pipeline.events.clone(),
            recent: Arc::clone(&pipeline.recent),
            commands: pipeline.commands.clone(),
            truth,
            world: Arc::new(WorldBody::of(config)),
            aircraft: feeds.aircraft.clone(),
        },
        control: http::Control {
            link: control.link.clone(),
            guidance: control.guidance.clone(),
            vehicles_message: Arc::default(),
        },
        recording: recording.clone(),
        service,
        map,
    }
}

/// Connections the kernel completes and queues for the API before they are accepted (capped by
/// `net.core.somaxconn`, 4 096 on Linux since 5.4). tokio's 1 024 overflowed under a flood of
/// connections on a busy machine, and a dropped SYN costs a client a 1 s retransmission.
const BACKLOG: u32 = 4096;

/// The API's listener and the address it got.
fn bind(addr: SocketAddr) -> Result<(tokio::net::TcpListener, SocketAddr), LiveError> {
    let bind = |source| LiveError::Bind { addr, source };
    let socket = match addr {
        SocketAddr::V4(_) => tokio::net::TcpSocket::new_v4(),
        SocketAddr::V6(_) => tokio::net::TcpSocket::new_v6(),
    }
    .map_err(bind)?;
    // As `TcpListener::bind` does on Unix: a restarted server binds its port while the old
    // one's connections linger (TIME_WAIT).
    #[cfg(unix)]
    socket.set_reuseaddr(true).map_err(bind)?;
    socket.bind(addr).map_err(bind)?;
    let listener = socket.listen(BACKLOG).map_err(bind)?;
    let local = listener.local_addr().map_err(bind)?;
    Ok((listener, local))
}

/// The session recorder of `recorder.path`, when set. A read-only, full or unusable recording
/// place must not stop live tracking: the service then runs without a recording and says so
/// (log, `/health`, `/metrics`).
fn open_recording(config: &Config, estimator: &str) -> http::Recording {
    let path = config.recorder.path.as_str();
    if path.is_empty() {
        return http::Recording::default();
    }
    let meta = SessionMeta {
        started_unix: clock::unix_now(),
        origin: config.frame.origin,
        plane_z: config.frame.plane_z,
        estimator: estimator.to_owned(),
        config_json: serde_json::to_string(config).unwrap_or_default(),
    };
    match Recorder::open(
        std::path::Path::new(path),
        &meta,
        std::time::Duration::from_millis(config.recorder.flush_ms),
        config.recorder.queue,
    ) {
        Ok(r) => {
            tracing::info!(path, session = r.session_id(), "recording");
            http::Recording {
                recorder: Some(r),
                error: None,
            }
        }
        Err(e) => {
            tracing::error!("recording is OFF, live tracking goes on without it: {e}");
            http::Recording {
                recorder: None,
                error: Some(Arc::from(e.to_string())),
            }
        }
    }
}
