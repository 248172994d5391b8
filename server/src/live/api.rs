//! The HTTP API (axum), under `/api/v1`:
//!
//! | route | |
//! |---|---|
//! | `GET /tracks[?all=true]` | `{"t": …, "tracks": [TrackView…]}`: confirmed tracks (all with `all=true`) |
//! | `GET /tracks/{id}` | one track, or 404 |
//! | `GET /health` | status, uptime, engine, last scan time, scans ingested |
//! | `GET /estimators` | the track engines (name, summary, parameters) |
//! | `GET /metrics` | Prometheus text format ([`super::metrics`]) |
//!
//! Every error is JSON `{"error": "…"}` with its status. [`app`] builds the router from an
//! [`ApiState`], so tests can serve it on any listener.

use std::sync::Arc;
use std::time::Instant;

use axum::Json;
use axum::Router;
use axum::extract::{Path, Query, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use serde_json::{Value, json};
use tokio::sync::watch;

use super::metrics::Metrics;
use super::tracker::Snapshot;
use crate::registry::TRACK_ENGINES;

/// What the handlers read.
#[derive(Debug, Clone)]
pub struct ApiState {
    /// The tracker's latest snapshot.
    pub snapshot: watch::Receiver<Arc<Snapshot>>,
    /// The counters.
    pub metrics: Arc<Metrics>,
    /// Name of the track engine.
    pub engine: String,
    /// When the service started.
    pub started: Instant,
}

/// A JSON error response.
fn error(status: StatusCode, message: impl Into<String>) -> Response {
    (status, Json(json!({"error": message.into()}))).into_response()
}

/// The router, every route under `/api/v1`.
pub fn app(state: ApiState) -> Router {
    let api = Router::new()
        .route("/tracks", get(tracks))
        .route("/tracks/{id}", get(track))
        .route("/health", get(health))
        .route("/estimators", get(estimators))
        .route("/metrics", get(metrics));
    Router::new()
        .nest("/api/v1", api)
        .fallback(|| async { error(StatusCode::NOT_FOUND, "no such route") })
        .with_state(state)
}

/// `?all=…`.
#[derive(Debug, serde::Deserialize)]
struct TracksQuery {
    all: Option<String>,
}

async fn tracks(
    State(s): State<ApiState>,
    q: Result<Query<TracksQuery>, axum::extract::rejection::QueryRejection>,
) -> Response {
    let all = match q.as_ref().map(|q| q.all.as_deref()) {
        Ok(None | Some("false" | "0")) => false,
        Ok(Some("true" | "1" | "")) => true,
        Ok(Some(other)) => {
            return error(
                StatusCode::BAD_REQUEST,
                format!("all={other:?}: expected true or false"),
            );
        }
        Err(e) => return error(StatusCode::BAD_REQUEST, e.body_text()),
    };
    let snap = Arc::clone(&s.snapshot.borrow());
    let tracks: Vec<_> = snap
        .tracks
        .iter()
        .filter(|k| all || k.status == "confirmed")
        .collect();
    Json(json!({"t": snap.t, "tracks": tracks})).into_response()
}

async fn track(State(s): State<ApiState>, Path(id): Path<String>) -> Response {
    let Ok(id) = id.parse::<u64>() else {
        return error(
            StatusCode::BAD_REQUEST,
            format!("track id {id:?} is not a number"),
        );
    };
    let snap = Arc::clone(&s.snapshot.borrow());
    match snap.tracks.iter().find(|k| k.id == id) {
        Some(k) => Json(k).into_response(),
        None => error(StatusCode::NOT_FOUND, format!("no track {id}")),
    }
}

async fn health(State(s): State<ApiState>) -> Json<Value> {
    Json(json!({
        "status": "ok",
        "uptime_s": s.started.elapsed().as_secs_f64(),
        "estimator": s.engine,
        "last_scan_t": s.metrics.last_scan_t(),
        "scans_ingested": s.metrics.scans_ingested(),
    }))
}

async fn estimators() -> Json<Value> {
    let list: Vec<_> = TRACK_ENGINES
        .iter()
        .map(|e| {
            let params: Vec<_> = e
                .params
                .iter()
                .map(|(n, d)| json!({"name": n, "description": d}))
                .collect();
            json!({"name": e.name, "summary": e.summary, "params": params})
        })
        .collect();
    Json(json!({"estimators": list}))
}

async fn metrics(State(s): State<ApiState>) -> Response {
    (
        [(header::CONTENT_TYPE, "text/plain; version=0.0.4")],
        s.metrics.render(s.started.elapsed().as_secs_f64()),
    )
        .into_response()
}
