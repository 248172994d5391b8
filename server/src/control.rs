//! The vehicles' side of the service, when `mavlink.gcs` is set: the MAVLink GCS link and
//! router ([`super::gcs`]), the confirmed tracks as traffic to the router's clients
//! ([`super::feeds::adsb_out`]), the guidance loop ([`super::guidance`]) and, when recording, the
//! vehicles' telemetry, events and assignments in the recording.

use std::sync::Arc;

use tokio::sync::watch;
use tokio::task::JoinHandle;

use super::clock;
use super::config::Config;
use super::gcs::{self, GcsLink};
use super::guidance::{self, Guidance};
use super::tracker::Snapshot;
use crate::error::LiveError;
use harrier_recording::writer::{Record, Recorder};

/// The running link and guidance, and their tasks.
#[derive(Debug, Default)]
pub(super) struct Control {
    /// The MAVLink GCS link, when `mavlink.gcs` is set.
    pub(super) link: Option<GcsLink>,
    /// The guidance loop, when the link runs.
    pub(super) guidance: Option<Guidance>,
    /// The link, the traffic, the guidance and the vehicles' recording: they end at `stop`.
    tasks: Vec<JoinHandle<()>>,
}

impl Control {
    /// Starts the link (nothing when `mavlink.gcs` is empty), the traffic (`mavlink.tracks_hz`,
    /// when there is a router), the guidance on the tracker's `snapshot`, and the recording
    /// of the vehicles when `recorder` is given; all of them end at `stop`.
    pub(super) async fn spawn(
        config: &Config,
        snapshot: &watch::Receiver<Arc<Snapshot>>,
        recorder: Option<&Recorder>,
        stop: &watch::Receiver<bool>,
    ) -> Result<Self, LiveError> {
        let Some(c) =
            crate::gcs::GcsConfig::from_config(config, recorder.map(Recorder::session_id))?
        else {
            return Ok(Self::default());
        };
        if let Some(p) = &c.tlog {
            tracing::info!(path = %p.display(), "raw MAVLink log");
        }
        let frame = c.frame;
        let (link, task) = gcs::start(c, stop.clone()).await?;
        let mut tasks = vec![task];
        let hz = config.mavlink.tracks_hz;
        if hz > 0.0 && link.router().next().is_some() {
            tasks.push(tokio::spawn(crate::feeds::adsb_out::run(
                link.clone(),
                snapshot.clone(),
                frame,
                hz,
                stop.clone(),
            )));
        }
        let settings = guidance::GuidanceSettings::from(config);
        let (guidance, task) =
            guidance::start(settings, link.clone(), snapshot.clone(), stop.clone());
        tasks.push(task);
        if let Some(r) = recorder {
            tasks.push(tokio::spawn(record_vehicles(
                r.clone(),
                link.clone(),
                guidance.clone(),
                stop.clone(),
            )));
        }
        Ok(Self {
            link: Some(link),
            guidance: Some(guidance),
            tasks,
        })
    }

    /// Waits for the tasks, which end once `stop` is set.
    pub(super) async fn join(self) {
        for t in self.tasks {
            if let Err(e) = t.await {
                tracing::warn!("the MAVLink link or the guidance ended abnormally: {e}");
            }
        }
    }
}

/// Records every vehicle's telemetry once a second, the link's events and the assignments'
/// changes, until `stop`.
async fn record_vehicles(
    r: Recorder,
    link: GcsLink,
    guidance: Guidance,
    mut stop: watch::Receiver<bool>,
) {
    let mut events = link.events.subscribe();
    let mut assignments = guidance.events.subscribe();
    let mut tick = tokio::time::interval(std::time::Duration::from_secs(1));
    let row = |vehicle, kind, json: Result<String, serde_json::Error>| {
        r.record(Record::Vehicle {
            time_unix: clock::unix_now(),
            vehicle,
            kind,
            json: json.unwrap_or_default(),
        });
    };
    loop {
        tokio::select! {
            _ = tick.tick() => {
                let vehicles = link.vehicles.borrow().clone();
                for v in vehicles.iter() {
                    row(Some(v.view.id), "telemetry", serde_json::to_string(&v.view));
                }
            }
            Ok(e) = events.recv() => row(Some(e.vehicle), "event", serde_json::to_string(&e)),
            Ok(a) = assignments.recv() => row(None, "assignment", serde_json::to_string(&a)),
            () = gcs::transport::stopped(&mut stop) => break,
        }
    }
}
