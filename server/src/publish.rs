//! The track publisher: the confirmed tracks on Zenoh (`zenoh.tracks_key`, default
//! `harrier/v1/tracks`) at most `zenoh.tracks_hz` times a second, whenever a scan changed them,
//! so that other consumers (a second ground station, a Python script) can subscribe.
//!
//! Each message is a JSON object, schema `harrier-tracks/1` (DETECTIONS.md §Tracks): a
//! [`TracksMessage`] (OpenAPI component `TracksMessage`), tracks in the server's ENU frame.

use std::sync::Arc;
use std::time::Duration;

use harrier_core::detection::GeoPoint;
use tokio::sync::watch;

use super::tracker::Snapshot;
use super::wire::{TracksFrame, TracksMessage, to_json};

/// The message for `snap`, as JSON text.
pub fn tracks_message(snap: &Snapshot, origin: GeoPoint, plane_z: f64) -> String {
    let frame = TracksFrame { origin, plane_z };
    to_json(&TracksMessage::new(snap, frame, super::clock::unix_now()))
}

/// Publishes until the tracker ends (its snapshot channel closes).
pub async fn run(
    publisher: zenoh::pubsub::Publisher<'static>,
    mut snapshot: watch::Receiver<Arc<Snapshot>>,
    hz: f64,
    origin: GeoPoint,
    plane_z: f64,
) {
    let mut tick = tokio::time::interval(Duration::from_secs_f64(1.0 / hz));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut last_seq = 0;
    let mut failures = 0u64;
    loop {
        tick.tick().await;
        if snapshot.has_changed().is_err() {
            break;
        }
        let snap = Arc::clone(&snapshot.borrow_and_update());
        if snap.seq == last_seq {
            continue;
        }
        last_seq = snap.seq;
        if let Err(e) = publisher.put(tracks_message(&snap, origin, plane_z)).await {
            failures += 1;
            if failures.is_power_of_two() {
                tracing::warn!(failures, "zenoh: publishing the tracks: {e}");
            }
        }
    }
    if let Err(e) = publisher.undeclare().await {
        tracing::debug!("zenoh: undeclare the track publisher: {e}");
    }
}
