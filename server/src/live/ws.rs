//! The WebSocket stream, `GET /api/v1/ws`: every processed scan as it happens, after a snapshot.
//!
//! Messages are JSON text frames with a `type`:
//!
//! - `snapshot`: sent on connect, and again after the client fell behind:
//!   `{"type": "snapshot", "seq", "t", "tracks": [TrackView…], "vehicles": [VehicleView…],
//!   "estimator": {"name", "params"}, "dropped"}` (`dropped`: scan messages this client missed
//!   since the last snapshot, 0 on connect).
//! - `scan`: one per scan the tracker processed, in order: `{"type": "scan", "seq", "t",
//!   "vehicle", "sensor", "kind", "platform": [x, y, z], "detections": [z…], "events": [{"type":
//!   "born" | "confirmed" | "updated" | "coasted" | "deleted" | "rejected", "id", …}], "tracks":
//!   [TrackView…]}` (the tracks the scan started, confirmed or updated; a deleted track has a
//!   `deleted` event, a coasted one keeps its last state). `seq` counts processed scans: a client
//!   sees consecutive values unless it was dropped to a snapshot.
//!
//! - `vehicles` (every 0.5 s when the MAVLink link runs): `{"type": "vehicles", "vehicles":
//!   [VehicleEntry…], "assignments": [AssignmentView…]}`, as `GET /api/v1/vehicles` and
//!   `GET /api/v1/assignments`.
//! - `vehicle_event`: `{"type": "vehicle_event", "event": {"vehicle", "event": "connected" |
//!   "lost" | "recovered" | "mode" | "armed" | "disarmed", "mode", "time_unix"}}`.
//! - `assignment`: `{"type": "assignment", "assignment": AssignmentView}` when one is created,
//!   a vehicle of it changes state, or it ends.
//!
//! Each client has a bounded queue (`api.ws_queue` messages, the tracker's broadcast ring): the
//! tracker never waits for a client. A client that falls further behind loses the oldest
//! messages, gets a fresh `snapshot` with the count (also in `harrier_ws_dropped_total`) and goes
//! on from the latest state. A client whose socket accepts nothing for [`SEND_TIMEOUT`] is
//! disconnected. Messages from the client are ignored (pings are answered).

use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::http::StatusCode;
use axum::response::Response;
use tokio::sync::broadcast::error::RecvError;

use super::api::ApiState;
use super::tracker::Snapshot;

/// Longest time one message may take to leave; past it the client is disconnected.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(10);

/// The `snapshot` message.
pub fn snapshot_message(s: &Snapshot, dropped: u64) -> String {
    serde_json::json!({
        "type": "snapshot",
        "seq": s.seq,
        "t": s.t,
        "tracks": *s.tracks,
        "vehicles": *s.vehicles,
        "estimator": *s.estimator,
        "dropped": dropped,
    })
    .to_string()
}

/// Upgrades the connection and streams to it.
#[utoipa::path(
    get,
    path = "/api/v1/ws",
    tag = "stream",
    responses(
        (status = 101, description = "Switching to the WebSocket protocol: `snapshot` and `scan` JSON messages (see the live::ws module docs)"),
        (status = 400, description = "Not a WebSocket upgrade request (or an unsupported WebSocket version)", body = super::api::ErrorBody),
        (status = 401, description = "Reads need the token (`api.auth_reads`) and it is missing or wrong", body = super::api::ErrorBody),
    )
)]
pub async fn ws(
    State(s): State<ApiState>,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Response {
    match ws {
        Ok(ws) => ws.on_upgrade(move |socket| client(socket, s)),
        Err(e) => {
            s.metrics.http_refused("websocket", 400);
            super::api::error(StatusCode::BAD_REQUEST, e.body_text())
        }
    }
}

/// Period of the `vehicles` message.
pub const VEHICLES_PERIOD: Duration = Duration::from_millis(500);

/// The next item of an optional event stream (lagged items are skipped; `None` when there is
/// no stream or it closed, which disables the branch).
async fn next<T: Clone>(rx: &mut Option<tokio::sync::broadcast::Receiver<T>>) -> Option<T> {
    let r = rx.as_mut()?;
    loop {
        match r.recv().await {
            Ok(v) => return Some(v),
            Err(RecvError::Lagged(_)) => {}
            Err(RecvError::Closed) => {
                *rx = None;
                return None;
            }
        }
    }
}

/// Sends one text message, within [`SEND_TIMEOUT`]; `false` when the client is gone.
async fn send(socket: &mut WebSocket, text: &str) -> bool {
    matches!(
        tokio::time::timeout(SEND_TIMEOUT, socket.send(Message::text(text))).await,
        Ok(Ok(()))
    )
}

async fn client(mut socket: WebSocket, s: ApiState) {
    // Subscribe before reading the snapshot, so that no scan falls between them.
    let mut rx = s.events.subscribe();
    let snap = Arc::clone(&s.snapshot.borrow());
    let mut last = snap.seq;
    let mut stop = s.stop.clone();
    s.metrics.ws_clients(1);
    let mut link_events = s.link.as_ref().map(|l| l.events.subscribe());
    let mut assignments = s.guidance.as_ref().map(|g| g.events.subscribe());
    let mut vehicles = tokio::time::interval(VEHICLES_PERIOD);
    vehicles.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    if send(&mut socket, &snapshot_message(&snap, 0)).await {
        loop {
            tokio::select! {
                _ = vehicles.tick(), if s.link.is_some() => {
                    let body = serde_json::json!({
                        "type": "vehicles",
                        "vehicles": super::control::vehicle_entries(&s),
                        "assignments": s.guidance.as_ref().map(|g| g.assignments.borrow().to_vec()).unwrap_or_default(),
                    });
                    if !send(&mut socket, &body.to_string()).await {
                        break;
                    }
                }
                Some(e) = next(&mut link_events) => {
                    let body = serde_json::json!({"type": "vehicle_event", "event": e});
                    if !send(&mut socket, &body.to_string()).await {
                        break;
                    }
                }
                Some(a) = next(&mut assignments) => {
                    let body = serde_json::json!({"type": "assignment", "assignment": a});
                    if !send(&mut socket, &body.to_string()).await {
                        break;
                    }
                }
                r = rx.recv() => {
                    let ok = match r {
                        Ok(scan) if scan.seq <= last => true,
                        Ok(scan) => {
                            last = scan.seq;
                            s.metrics.ws_sent(1);
                            send(&mut socket, scan.message()).await
                        }
                        Err(RecvError::Lagged(n)) => {
                            s.metrics.ws_dropped(n);
                            let snap = Arc::clone(&s.snapshot.borrow());
                            last = snap.seq;
                            send(&mut socket, &snapshot_message(&snap, n)).await
                        }
                        Err(RecvError::Closed) => false,
                    };
                    if !ok {
                        break;
                    }
                }
                _ = async { stop.wait_for(|s| *s).await.is_ok() } => break,
                m = socket.recv() => match m {
                    Some(Ok(Message::Close(_)) | Err(_)) | None => break,
                    Some(Ok(_)) => {}
                },
            }
        }
    }
    s.metrics.ws_clients(-1);
}
