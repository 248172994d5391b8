//! The service on the Zenoh bus: one session, two subscriptions and the publication of the tracks.
//!
//! - `harrier/v1/vehicle/*/detections`: each payload goes to the pipeline's bounded queue by
//!   `try_send`; a full queue drops it (counted), so the callback never blocks Zenoh.
//! - `harrier/v1/sim/truth`: the simulator's truth, bounded in time as scans are, to a `watch`
//!   in the server's frame ([`TruthBody::of`]) and to the recording.
//! - `zenoh.tracks_key`: the publisher of the confirmed tracks, which the pipeline runs.

use std::sync::Arc;

use harrier_core::detection::{DETECTIONS_KEY_ALL, TRUTH_KEY, TruthSample};
use harrier_link::geo::LocalFrame;
use tokio::sync::{mpsc, watch};
use zenoh::pubsub::{Publisher, Subscriber};

use super::clock::{self, ClockConfig};
use super::config::Config;
use super::ingest::Payload;
use super::metrics::{DropReason, Metrics};
use super::world::TruthBody;
use crate::error::LiveError;
use harrier_recording::writer::{Record, Recorder};

/// The session and its subscriptions.
#[derive(Debug)]
pub(super) struct Bus {
    session: zenoh::Session,
    subscribers: Vec<Subscriber<()>>,
}

/// What the subscriptions feed.
#[derive(Debug)]
pub(super) struct Inputs {
    /// Detection payloads as they arrived, for ingest.
    pub(super) payloads: mpsc::Receiver<Payload>,
    /// The latest truth, in the server's frame.
    pub(super) truth: watch::Receiver<Arc<TruthBody>>,
}

impl Bus {
    /// Opens the session of `[zenoh]` and subscribes to the detections and the truth (recorded
    /// when `recorder` is given and `recorder.truth` is set).
    pub(super) async fn subscribe(
        config: &Config,
        metrics: &Arc<Metrics>,
        recorder: Option<&Recorder>,
    ) -> Result<(Self, Inputs), LiveError> {
        let zenoh_config = config
            .bus()?
            .to_zenoh()
            .map_err(|e| LiveError::Zenoh(e.to_string()))?;
        let session = zenoh::open(zenoh_config)
            .await
            .map_err(|e| LiveError::Zenoh(format!("cannot open a session: {e}")))?;
        let (payload_tx, payloads) = mpsc::channel::<Payload>(config.tracker.queue);
        let m = Arc::clone(metrics);
        let detections = session
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
        let (truth_tx, truth) = watch::channel(Arc::new(TruthBody::default()));
        let on_truth = OnTruth {
            frame: LocalFrame::new(config.frame.origin),
            bound: config.clock.clone(),
            metrics: Arc::clone(metrics),
            recorder: recorder.filter(|_| config.recorder.truth).cloned(),
            latest: truth_tx,
        };
        let truth_subscriber = session
            .declare_subscriber(TRUTH_KEY)
            .callback(move |sample| on_truth.sample(&sample.payload().to_bytes()))
            .await
            .map_err(|e| LiveError::Zenoh(format!("subscribe {TRUTH_KEY}: {e}")))?;
        let bus = Self {
            session,
            subscribers: vec![detections, truth_subscriber],
        };
        Ok((bus, Inputs { payloads, truth }))
    }

    /// The publisher of the confirmed tracks on `zenoh.tracks_key`; `None` when it is empty.
    pub(super) async fn tracks_publisher(
        &self,
        config: &Config,
    ) -> Result<Option<Publisher<'static>>, LiveError> {
        let key = &config.zenoh.tracks_key;
        if key.is_empty() {
            return Ok(None);
        }
        let publisher = self
            .session
            .declare_publisher(key.clone())
            .await
            .map_err(|e| LiveError::Zenoh(format!("publish on {key}: {e}")))?;
        Ok(Some(publisher))
    }

    /// The session.
    pub(super) fn session(&self) -> &zenoh::Session {
        &self.session
    }

    /// Ends the subscriptions: no payload enters the pipeline any more.
    pub(super) async fn unsubscribe(&mut self) {
        for s in self.subscribers.drain(..) {
            if let Err(e) = s.undeclare().await {
                tracing::warn!("zenoh: undeclare a subscriber: {e}");
            }
        }
    }

    /// Closes the session.
    pub(super) async fn close(self) {
        if let Err(e) = self.session.close().await {
            tracing::warn!("zenoh: close the session: {e}");
        }
    }
}

/// The truth subscription's callback.
struct OnTruth {
    /// The server's frame.
    frame: LocalFrame,
    /// How far `time_unix` may be from the server's clock.
    bound: ClockConfig,
    metrics: Arc<Metrics>,
    /// Where the samples are recorded, if they are.
    recorder: Option<Recorder>,
    latest: watch::Sender<Arc<TruthBody>>,
}

impl OnTruth {
    /// A truth payload: refused (counted) when it is not a truth sample or its time is out of
    /// the clock bound (no input moves a clock far); else the latest truth, and recorded.
    fn sample(&self, payload: &[u8]) {
        let t = match TruthSample::from_json(payload) {
            Ok(t) => t,
            Err(e) => {
                self.metrics.truth_refused("invalid");
                tracing::debug!("truth sample not used: {e}");
                return;
            }
        };
        let refused = t
            .time_unix
            .and_then(|tu| self.bound.refusal(tu, clock::unix_now()));
        if let Some(why) = refused {
            self.metrics.truth_refused("clock");
            tracing::debug!("truth sample not used: {why}");
            return;
        }
        self.latest
            .send_replace(Arc::new(TruthBody::of(&t, &self.frame)));
        if let Some(r) = &self.recorder {
            r.record(Record::Truth(t));
        }
    }
}
