//! The tracking pipeline of the diagram in [`super`]: [`super::ingest`] decodes and frames the
//! detection payloads, the [`super::tracker`] actor runs the track engine on them in time order
//! and hands each processed scan to its sinks (the recording), and [`super::publish`] puts the
//! confirmed tracks on Zenoh.

use std::sync::Arc;

use harrier_core::measurement::Geometry;
use harrier_link::geo::LocalFrame;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

use super::config::Config;
use super::ingest::{Ingest, Payload};
use super::metrics::Metrics;
use super::publish;
use super::tracker::{Command, Recent, ScanEvents, Snapshot, TrackFilterState, TrackerActor};
use harrier_engine::Deployment;
use harrier_engine::{TrackEngine, TrackView};
use harrier_recording::writer::{Record, Recorder};

/// The track engine the tracker starts with, and what it was built from.
#[derive(Debug)]
pub(super) struct Engine {
    /// The engine.
    pub(super) engine: Box<dyn TrackEngine>,
    /// The deployment it was built for.
    pub(super) deployment: Deployment,
    /// Its name and parameters.
    pub(super) estimator: TrackFilterState,
}

/// The running pipeline: what it shows the rest of the service, and its tasks.
#[derive(Debug)]
pub(super) struct Pipeline {
    /// The tracker's latest snapshot.
    pub(super) snapshot: watch::Receiver<Arc<Snapshot>>,
    /// Every processed scan.
    pub(super) events: broadcast::Sender<Arc<ScanEvents>>,
    /// Requests to the tracker (change the estimator).
    pub(super) commands: mpsc::Sender<Command>,
    /// Recent scans and track histories.
    pub(super) recent: Arc<Recent>,
    /// Ingest, tracker and the track publisher: they end when the payloads end.
    tasks: Vec<JoinHandle<()>>,
}

impl Pipeline {
    /// Spawns ingest on `payloads`, the tracker after it (its scans recorded when `recorder` is
    /// given) and, when given, the publisher of the tracks.
    pub(super) fn spawn(
        config: &Config,
        engine: Engine,
        payloads: mpsc::Receiver<Payload>,
        publisher: Option<zenoh::pubsub::Publisher<'static>>,
        metrics: &Arc<Metrics>,
        recorder: Option<&Recorder>,
    ) -> Self {
        let queue = config.tracker.queue;
        let (scan_tx, scan_rx) = mpsc::channel(queue);
        let (commands, command_rx) = mpsc::channel(16);
        let (snapshot_tx, snapshot) = watch::channel(Arc::new(Snapshot::default()));
        let (events, _) = broadcast::channel(config.api.ws_queue);
        let ingest = Ingest::new(
            LocalFrame::new(config.frame.origin),
            Geometry::planar(config.frame.plane_z),
            Arc::clone(metrics),
        )
        .with_sensors(config.tracker.sensors.clone())
        .with_clock(config.clock.clone())
        .with_target_size(config.tracker.target_size_m)
        .with_recorder(recorder.cloned());
        let recent = Arc::new(Recent::default());
        let mut tracker = TrackerActor::new(
            engine.engine,
            engine.deployment,
            engine.estimator,
            config.tracker.reorder_window_s,
            Arc::clone(metrics),
            Arc::clone(&recent),
            snapshot_tx,
            events.clone(),
        )
        .with_late_lag(config.tracker.late_lag_s)
        .with_bounds(config.tracker.bound);
        if let Some(r) = recorder {
            let r = r.clone();
            tracker.add_sink(Box::new(move |scan| {
                let changed: Vec<TrackView> = scan.changed_tracks().cloned().collect();
                if !changed.is_empty() {
                    r.record(Record::Tracks {
                        t: scan.t,
                        tracks: changed,
                    });
                }
                if let Some(b) = &scan.biases {
                    r.record(Record::Biases {
                        t: scan.t,
                        json: serde_json::to_string(&**b).unwrap_or_default(),
                    });
                }
            }));
        }
        let mut tasks = Vec::new();
        if let Some(publisher) = publisher {
            tasks.push(tokio::spawn(publish::run(
                publisher,
                snapshot.clone(),
                config.zenoh.tracks_hz,
                config.frame.origin,
                config.frame.plane_z,
            )));
        }
        tasks.push(tokio::spawn(ingest.run(payloads, scan_tx)));
        tasks.push(tokio::spawn(tracker.run(scan_rx, command_rx)));
        Self {
            snapshot,
            events,
            commands,
            recent,
            tasks,
        }
    }

    /// Waits for the tasks, which end once the payloads have ended and been processed.
    pub(super) async fn join(&mut self) {
        for t in self.tasks.drain(..) {
            if let Err(e) = t.await {
                tracing::warn!("a live actor ended abnormally: {e}");
            }
        }
    }
}
