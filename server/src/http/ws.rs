//! The WebSocket stream, `GET /api/v1/ws`: every processed scan as it happens, after a snapshot.
//!
//! Messages are JSON text frames, each a [`WsMessage`] (OpenAPI component `WsMessage`, built in
//! `crate::wire`), told apart by `type`:
//!
//! - `snapshot` ([`SnapshotMessage`]): sent on connect, and again after the client fell behind:
//!   `{"type": "snapshot", "seq", "t", "tracks": [TrackDto…], "vehicles": [VehicleEntry…],
//!   "estimator": {"name", "params"}, "dropped"}` (`dropped`: scan messages this client missed
//!   since the last snapshot, 0 on connect).
//! - `scan` ([`ScanMessage`]): one per scan the tracker processed, in order: `{"type": "scan",
//!   "seq", "t", "vehicle", "sensor", "kind", "platform": [x, y, z], "detections": [z…],
//!   "events": [TrackEventDto…], "tracks": [TrackDto…]}`; an event is `{"type": "born" |
//!   "confirmed" | "updated" | "coasted" | "deleted" | "rejected", "id", …}`
//!   ([`TrackEventDto`]), the tracks are those the scan started, confirmed or updated (a deleted
//!   track has a `deleted` event, a coasted one keeps its last state). `seq` counts processed
//!   scans: a client sees consecutive values unless it was dropped to a snapshot.
//! - `vehicles` ([`VehiclesMessage`], at 10 Hz, [`VEHICLES_PERIOD`], when the MAVLink link
//!   runs): `{"type": "vehicles", "vehicles": [VehicleEntry…], "assignments":
//!   [AssignmentView…]}`, as `GET /api/v1/vehicles` and `GET /api/v1/assignments`.
//! - `vehicle_event`: `{"type": "vehicle_event", "event": LinkEvent}` (`{"vehicle", "event":
//!   "connected" | "lost" | "recovered" | "mode" | "armed" | "disarmed", "mode", "time_unix"}`).
//! - `assignment`: `{"type": "assignment", "assignment": AssignmentView}` when one is created,
//!   a vehicle of it changes state, or it ends.
//!
//! A track has one shape everywhere (REST, WebSocket, Zenoh): [`TrackDto`], with its 95 %
//! `ellipse_95` and (3-D) `ellipsoid_95`. A vehicle has one shape everywhere: [`VehicleEntry`]
//! (`{"id", "link", "detections", "clock", "clock_refused"}`).
//!
//! Each client has a bounded queue (`api.ws_queue` messages, the tracker's broadcast ring): the
//! tracker never waits for a client. A client that falls further behind loses the oldest
//! messages, gets a fresh `snapshot` with the count (also in `harrier_ws_dropped_total`) and goes
//! on from the latest state. A client whose socket accepts nothing for [`SEND_TIMEOUT`] is
//! disconnected. Messages from the client are ignored (pings are answered).
//!
//! The client loop (`client`) is written over any `Sink` and `Stream` of messages (axum's
//! testing-websockets example), so its tests drive it through channels.

use std::sync::Arc;
use std::time::Duration;

use axum::Router;
use axum::extract::State;
use axum::extract::ws::rejection::WebSocketUpgradeRejection;
use axum::extract::ws::{Message, WebSocketUpgrade};
use axum::response::Response;
use axum::routing::get;
use futures_util::{Sink, SinkExt as _, Stream, StreamExt as _};
use tokio::sync::broadcast;
use tokio::sync::broadcast::error::RecvError;
use utoipa::OpenApi;

use super::error::{ApiError, ErrorBody};
use super::state::{ApiState, Control, Tracking};
use super::vehicles::vehicle_entries;
use crate::metrics::Metrics;
use crate::tracker::Snapshot;
use crate::wire::{
    DeleteCause, Ellipse, Ellipsoid, ScanMessage, SnapshotMessage, TrackDto, TrackEventDto,
    TracksFrame, TracksMessage, VehicleEntry, VehiclesMessage, WsMessage, scan_json, to_json,
};

/// The route of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new().route("/ws", get(ws))
}

/// The OpenAPI path of this file, and the schemas of every streamed message: the WebSocket's
/// [`WsMessage`] and the Zenoh [`TracksMessage`] (which the stream's route cannot name).
#[derive(Debug, OpenApi)]
#[openapi(
    paths(ws),
    components(schemas(
        WsMessage,
        SnapshotMessage,
        ScanMessage,
        VehiclesMessage,
        TrackEventDto,
        DeleteCause,
        TrackDto,
        Ellipse,
        Ellipsoid,
        VehicleEntry,
        TracksMessage,
        TracksFrame,
    ))
)]
pub(super) struct Doc;

/// Longest time one message may take to leave; past it the client is disconnected.
pub const SEND_TIMEOUT: Duration = Duration::from_secs(10);

/// Period of the `vehicles` message (10 Hz; the link's vehicle table changes at 20 Hz).
pub const VEHICLES_PERIOD: Duration = Duration::from_millis(100);

/// The `snapshot` message of `s`, after `dropped` lost scan messages.
fn snapshot_message(s: &Snapshot, c: &Control, t: &Tracking, m: &Metrics, dropped: u64) -> String {
    let vehicles = vehicle_entries(c, t, m);
    to_json(&WsMessage::Snapshot(SnapshotMessage::new(
        s, vehicles, dropped,
    )))
}

/// The `vehicles` message.
fn vehicles_message(c: &Control, t: &Tracking, m: &Metrics) -> String {
    to_json(&WsMessage::Vehicles(VehiclesMessage {
        vehicles: vehicle_entries(c, t, m),
        assignments: c
            .guidance
            .as_ref()
            .map(|g| g.assignments.borrow().to_vec())
            .unwrap_or_default(),
    }))
}

/// Upgrades the connection and streams to it.
#[utoipa::path(
    get,
    path = "/api/v1/ws",
    tag = "stream",
    responses(
        (status = 101, description = "Switching to the WebSocket protocol: JSON text frames, each a `WsMessage` (component schema; `type`: `snapshot`, `scan`, `vehicles`, `vehicle_event`, `assignment`)"),
        (status = 400, description = "Not a WebSocket upgrade request (or an unsupported WebSocket version)", body = ErrorBody),
        (status = 401, description = "Reads need the token (`api.auth_reads`) and it is missing or wrong", body = ErrorBody),
    )
)]
async fn ws(
    State(s): State<ApiState>,
    ws: Result<WebSocketUpgrade, WebSocketUpgradeRejection>,
) -> Result<Response, ApiError> {
    Ok(ws?.on_upgrade(move |socket| {
        let (tx, rx) = socket.split();
        client(tx, rx, s)
    }))
}

/// The next item of an optional event stream (lagged items are skipped; `None` when there is
/// no stream or it closed, which disables the branch).
async fn next<T: Clone>(rx: &mut Option<broadcast::Receiver<T>>) -> Option<T> {
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
async fn send<W: Sink<Message> + Unpin>(tx: &mut W, text: &str) -> bool {
    matches!(
        tokio::time::timeout(SEND_TIMEOUT, tx.send(Message::text(text))).await,
        Ok(Ok(()))
    )
}

/// Streams to one client (`tx`) until it closes (`rx`), cannot keep up with [`SEND_TIMEOUT`],
/// or the service stops.
pub(super) async fn client<W, R, E>(mut tx: W, mut rx: R, s: ApiState)
where
    W: Sink<Message> + Unpin,
    R: Stream<Item = Result<Message, E>> + Unpin,
{
    let (t, c, metrics) = (&s.tracking, &s.control, &s.service.metrics);
    // Subscribe before reading the snapshot, so that no scan falls between them.
    let mut scans = t.events.subscribe();
    let snap = Arc::clone(&t.snapshot.borrow());
    let mut last = snap.seq;
    let mut stop = s.service.stop.clone();
    metrics.ws_clients(1);
    let mut link_events = c.link.as_ref().map(|l| l.events.subscribe());
    let mut assignments = c.guidance.as_ref().map(|g| g.events.subscribe());
    let mut vehicles = tokio::time::interval(VEHICLES_PERIOD);
    vehicles.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let first = snapshot_message(&snap, c, t, metrics, 0);
    if send(&mut tx, &first).await {
        loop {
            let ok = tokio::select! {
                _ = vehicles.tick(), if c.link.is_some() => {
                    // At most half a period old: the link's table changes at 20 Hz.
                    let text = c
                        .vehicles_message
                        .get(VEHICLES_PERIOD / 2, || vehicles_message(c, t, metrics));
                    send(&mut tx, &text).await
                }
                Some(event) = next(&mut link_events) => {
                    send(&mut tx, &to_json(&WsMessage::VehicleEvent { event })).await
                }
                Some(assignment) = next(&mut assignments) => {
                    send(&mut tx, &to_json(&WsMessage::Assignment { assignment })).await
                }
                r = scans.recv() => match r {
                    Ok(scan) if scan.seq <= last => true,
                    Ok(scan) => {
                        last = scan.seq;
                        metrics.ws_sent(1);
                        send(&mut tx, scan_json(&scan)).await
                    }
                    Err(RecvError::Lagged(n)) => {
                        metrics.ws_dropped(n);
                        let snap = Arc::clone(&t.snapshot.borrow());
                        last = snap.seq;
                        send(&mut tx, &snapshot_message(&snap, c, t, metrics, n)).await
                    }
                    Err(RecvError::Closed) => false,
                },
                // The `Ref` the wait returns is not `Send`: drop it inside.
                _ = async { stop.wait_for(|s| *s).await.is_ok() } => false,
                m = rx.next() => !matches!(m, Some(Ok(Message::Close(_)) | Err(_)) | None),
            };
            if !ok {
                break;
            }
        }
    }
    metrics.ws_clients(-1);
}

#[cfg(test)]
mod tests {
    use std::convert::Infallible;
    use std::time::Instant;

    use axum::extract::ws::Message;
    use axum::http::StatusCode;
    use serde_json::Value;
    use tokio::sync::mpsc;
    use tokio::task::JoinHandle;

    use super::super::testing::{TestApp, WAIT};
    use super::{VEHICLES_PERIOD, client};

    /// A client on channels: what the server sends, what it reads, its task.
    struct Client {
        from_server: mpsc::Receiver<Message>,
        to_server: mpsc::Sender<Result<Message, Infallible>>,
        task: JoinHandle<()>,
    }

    /// Connects a client whose socket holds `capacity` messages.
    fn connect(app: &TestApp, capacity: usize) -> Client {
        let (tx, from_server) = mpsc::channel(capacity);
        let sink = Box::pin(futures_util::sink::unfold(
            tx,
            |tx, m: Message| async move { tx.send(m).await.map(|()| tx) },
        ));
        let (to_server, mut rx) = mpsc::channel(8);
        let stream = futures_util::stream::poll_fn(move |cx| rx.poll_recv(cx));
        let task = tokio::spawn(client(sink, stream, app.state.clone()));
        Client {
            from_server,
            to_server,
            task,
        }
    }

    impl Client {
        async fn next(&mut self) -> Value {
            let m = tokio::time::timeout(WAIT, self.from_server.recv())
                .await
                .expect("a message in time")
                .expect("the stream is open");
            match m {
                Message::Text(t) => serde_json::from_str(t.as_str()).expect("JSON"),
                m => panic!("not a text message: {m:?}"),
            }
        }

        async fn ended(self) {
            tokio::time::timeout(WAIT, self.task)
                .await
                .expect("the client ended in time")
                .expect("the client did not panic");
        }
    }

    fn clients(app: &TestApp) -> String {
        let text = app.state.service.metrics.render(0.0);
        text.lines()
            .find(|l| l.starts_with("harrier_ws_clients "))
            .expect("the gauge")
            .to_owned()
    }

    #[tokio::test]
    async fn the_snapshot_comes_first_then_every_scan_in_order() {
        let app = TestApp::new();
        app.scan(2, 0.0, &[[100.0, 50.0]]).await;
        let mut c = connect(&app, 16);
        let first = c.next().await;
        assert_eq!(
            (first["type"].as_str(), first["seq"].as_u64()),
            (Some("snapshot"), Some(1))
        );
        assert_eq!(first["dropped"], 0);
        assert_eq!(first["estimator"]["name"], "ekf");
        // The one vehicle shape: as GET /vehicles.
        let v = &first["vehicles"][0];
        assert_eq!((v["id"].as_u64(), v["link"].is_null()), (Some(2), true));
        assert_eq!(v["detections"]["vehicle"], "2");
        for k in 1..=3_u32 {
            app.scan(2, f64::from(k), &[[100.0, 50.0]]).await;
            let m = c.next().await;
            assert_eq!(
                (m["type"].as_str(), m["seq"].as_u64()),
                (Some("scan"), Some(u64::from(k) + 1))
            );
            assert_eq!(m["vehicle"], "2");
        }
        assert_eq!(clients(&app), "harrier_ws_clients 1");
    }

    #[tokio::test]
    async fn a_lagging_client_gets_a_fresh_snapshot_with_the_count() {
        let app = TestApp::with_queue(2);
        let mut c = connect(&app, 1);
        assert_eq!(c.next().await["type"], "snapshot");
        // The client reads nothing while six scans pass a queue of two.
        for k in 0..6 {
            app.scan(2, f64::from(k), &[[100.0, 50.0]]).await;
        }
        let mut seen = 0;
        let snapshot = loop {
            let m = c.next().await;
            if m["type"] == "snapshot" {
                break m;
            }
            seen += 1;
            assert_eq!(
                (m["type"].as_str(), m["seq"].as_u64()),
                (Some("scan"), Some(seen))
            );
        };
        let dropped = snapshot["dropped"].as_u64().expect("the count");
        assert!(
            dropped > 0 && seen + dropped <= 6,
            "{seen} seen, {dropped} dropped"
        );
        assert_eq!(snapshot["seq"], 6);
        let text = app.state.service.metrics.render(0.0);
        assert!(text.contains(&format!("harrier_ws_dropped_total {dropped}")));
        // It goes on from the latest state.
        app.scan(2, 6.0, &[[100.0, 50.0]]).await;
        assert_eq!(c.next().await["seq"], 7);
    }

    #[tokio::test]
    async fn a_close_a_gone_client_or_the_service_stopping_ends_the_stream() {
        let app = TestApp::new();
        let mut c = connect(&app, 16);
        assert_eq!(c.next().await["type"], "snapshot");
        // Pings and other messages are ignored.
        c.to_server
            .send(Ok(Message::Ping(Default::default())))
            .await
            .expect("open");
        c.to_server
            .send(Ok(Message::Close(None)))
            .await
            .expect("open");
        c.ended().await;
        assert_eq!(clients(&app), "harrier_ws_clients 0");

        let mut c = connect(&app, 16);
        assert_eq!(c.next().await["type"], "snapshot");
        drop(c.to_server);
        tokio::time::timeout(WAIT, c.task)
            .await
            .expect("ended")
            .expect("no panic");

        let mut c = connect(&app, 16);
        assert_eq!(c.next().await["type"], "snapshot");
        app.stop.send_replace(true);
        c.ended().await;
        assert_eq!(clients(&app), "harrier_ws_clients 0");
    }

    #[tokio::test]
    async fn with_a_link_the_vehicles_come_at_10_hz_in_the_one_shape() {
        let (app, _link) = TestApp::new().with_link();
        app.scan(2, 0.0, &[[100.0, 50.0]]).await;
        let mut c = connect(&app, 64);
        let snapshot = c.next().await;
        let mut at = Vec::new();
        while at.len() < 5 {
            let m = c.next().await;
            if m["type"] == "vehicles" {
                at.push(Instant::now());
                assert_eq!(m["vehicles"], snapshot["vehicles"]);
                assert_eq!(m["assignments"], serde_json::json!([]));
            }
        }
        // Four periods of 0.1 s (at the former 2 Hz: 2 s).
        let four = at[4] - at[0];
        assert!(
            four >= VEHICLES_PERIOD * 3 && four < VEHICLES_PERIOD * 12,
            "{four:?}"
        );
    }

    #[tokio::test]
    async fn a_request_that_is_not_an_upgrade_is_refused() {
        let app = TestApp::new();
        let r = app.get("/api/v1/ws").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(r.error(), "Connection header did not include 'upgrade'");
        assert_eq!(app.refused("websocket", 400), 1);
    }
}
