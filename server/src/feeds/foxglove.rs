//! The live scene for Foxglove (and Lichtblick): a Foxglove WebSocket server, the official
//! `foxglove` SDK's, on `foxglove.listen`, with its own SDK context (nothing global). At
//! `foxglove.hz` the tracker's latest snapshot is logged on the channels of
//! [`harrier_recording::foxglove`] (tracks as a scene and as location fixes, vehicles as
//! location fixes and frame transforms) — also when nothing changed, so a client that connects
//! sees the scene at once — and every processed scan's detections as it comes (the tracker's
//! scan events, a `broadcast`: a lagging feed skips scans, counted as `lagged`); a channel's
//! messages are built only while a client or the MCAP file subscribes to it. With
//! `foxglove.mcap`, the SDK's MCAP writer on the same context records every message into that
//! file (buffered writes on this task, never the tracker's), closed at `stop`.
//!
//! Never blocks the tracker: it reads the snapshot `watch`, and the SDK keeps a bounded backlog
//! per client (a slow client loses the oldest messages, not the service). Counters
//! (`harrier_feed_events_total{feed="foxglove"}`): `scenes` (track scenes published), `scans`
//! (detection scenes published), `lagged` (scans skipped) and `messages` (messages logged).

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use foxglove::Context;
use foxglove::messages::{FrameTransforms, LocationFix, SceneUpdate};
use harrier_recording::foxglove::{
    DETECTIONS, ScanLines, TF, TRACK_FIXES, TRACKS, VEHICLE_FIXES, VehiclePose, detections_entity,
    scene_update, timestamp, track_fix, vehicle_fix, vehicle_transforms,
};
use tokio::sync::broadcast::error::RecvError;
use tokio::task::JoinHandle;

use super::FeedContext;
use crate::config::FoxgloveConfig;
use crate::error::LiveError;
use crate::tracker::{ScanEvents, VehicleView};

/// The counters' feed label.
const FEED: &str = "foxglove";

/// Starts the WebSocket server when `foxglove.enabled` (failing when `listen` cannot be bound),
/// the MCAP recording when `foxglove.mcap` is set (failing when the file cannot be created), and
/// the task that publishes on them until `stop`; returns the task and the server's address.
pub(super) async fn start(
    config: &FoxgloveConfig,
    plane_z: f64,
    ctx: FeedContext,
) -> Result<(JoinHandle<()>, Option<SocketAddr>), LiveError> {
    let fail = |message: String| LiveError::Feed {
        feed: FEED,
        message,
    };
    let fctx = Context::new();
    let mcap = match config.mcap.as_str() {
        "" => None,
        path => {
            let writer = fctx
                .mcap_writer()
                .create_new_buffered_file(path)
                .map_err(|e| fail(format!("cannot create the MCAP file {path}: {e}")))?;
            tracing::info!(
                feed = FEED,
                path,
                "recording the Foxglove channels into MCAP"
            );
            Some((writer, path.to_owned()))
        }
    };
    let server = if config.enabled {
        let server = fctx
            .websocket_server()
            .name("harrier")
            .bind(config.listen.ip().to_string(), config.listen.port())
            .start()
            .await
            .map_err(|e| {
                fail(format!(
                    "cannot serve the Foxglove WebSocket on {}: {e}",
                    config.listen
                ))
            })?;
        let addr = SocketAddr::new(config.listen.ip(), server.port());
        tracing::info!(feed = FEED, %addr, "Foxglove WebSocket server (ws://{addr})");
        Some((server, addr))
    } else {
        None
    };
    let addr = server.as_ref().map(|(_, a)| *a);
    let tracks = fctx.channel_builder(TRACKS).build::<SceneUpdate>();
    let track_fixes = fctx.channel_builder(TRACK_FIXES).build::<LocationFix>();
    let detections = fctx.channel_builder(DETECTIONS).build::<SceneUpdate>();
    let vehicle_fixes = fctx.channel_builder(VEHICLE_FIXES).build::<LocationFix>();
    let tf = fctx.channel_builder(TF).build::<FrameTransforms>();
    let period = Duration::from_secs_f64(1.0 / config.hz);
    let FeedContext {
        mut snapshot,
        events,
        frame,
        counters,
        mut stop,
    } = ctx;
    let mut scans = events.subscribe();
    let task = tokio::spawn(async move {
        // The channels live as long as their context: it is held here until the end.
        let _context = fctx;
        let mut tick = tokio::time::interval(period);
        tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                _ = tick.tick() => {}
                scan = scans.recv() => {
                    match scan {
                        Ok(scan) => {
                            if detections.has_sinks() {
                                detections.log(&scan_update(&scan, plane_z));
                                counters.add(FEED, "scans", 1);
                                counters.add(FEED, "messages", 1);
                            }
                        }
                        Err(RecvError::Lagged(n)) => counters.add(FEED, "lagged", n),
                        Err(RecvError::Closed) => break,
                    }
                    continue;
                }
                () = crate::gcs::transport::stopped(&mut stop) => break,
            }
            let snap = Arc::clone(&snapshot.borrow_and_update());
            let stamp = timestamp(snap.t.unwrap_or_else(crate::clock::unix_now));
            // Only what some client or the MCAP file subscribes to is built.
            let mut n = 0;
            if tracks.has_sinks() {
                tracks.log(&scene_update(&snap.tracks, stamp));
                counters.add(FEED, "scenes", 1);
                n += 1;
            }
            if track_fixes.has_sinks() {
                for fix in snap
                    .tracks
                    .iter()
                    .filter_map(|t| track_fix(t, &frame, stamp))
                {
                    track_fixes.log(&fix);
                    n += 1;
                }
            }
            if vehicle_fixes.has_sinks() || tf.has_sinks() {
                let poses: Vec<_> = snap.vehicles.iter().map(|v| pose(v)).collect();
                if vehicle_fixes.has_sinks() {
                    for fix in poses.iter().filter_map(|v| vehicle_fix(v, stamp)) {
                        vehicle_fixes.log(&fix);
                        n += 1;
                    }
                }
                if tf.has_sinks() {
                    tf.log(&vehicle_transforms(&poses, stamp));
                    n += 1;
                }
            }
            if n > 0 {
                counters.add(FEED, "messages", n);
            }
        }
        if let Some((server, _)) = server {
            server.stop().wait().await;
        }
        if let Some((writer, path)) = mcap {
            match writer.close() {
                Ok(_) => tracing::info!(feed = FEED, path, "MCAP file closed"),
                Err(e) => tracing::warn!(feed = FEED, path, "closing the MCAP file: {e}"),
            }
        }
    });
    Ok((task, addr))
}

/// A vehicle as the scene shows it.
fn pose(v: &VehicleView) -> VehiclePose<'_> {
    VehiclePose {
        label: &v.vehicle,
        position: v.position,
        geodetic: v.geodetic,
    }
}

/// A processed scan's detections as a scene update.
fn scan_update(scan: &ScanEvents, plane_z: f64) -> SceneUpdate {
    SceneUpdate {
        deletions: Vec::new(),
        entities: vec![detections_entity(
            &ScanLines {
                vehicle: &scan.vehicle,
                sensor: &scan.sensor,
                kind: scan.kind,
                platform: scan.platform,
                detections: &scan.detections,
                plane_z,
            },
            timestamp(scan.t),
        )],
    }
}
