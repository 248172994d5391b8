//! `GET /tracks[?all=true]`, `GET /tracks/{id}`, `GET /detections[?since=seq]`: the live tracks
//! and the scans they are made of.

use std::sync::Arc;

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::{AppPath, AppQuery};
use super::state::{ApiState, Tracking};
use crate::bound::BoundView;
use crate::wire::{MeasKindSchema, TrackDto};
use harrier_core::measurement::MeasKind;
use harrier_engine::TrackStatus;

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/tracks", get(tracks))
        .route("/tracks/{id}", get(track))
        .route("/detections", get(detections))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(tracks, track, detections))]
pub(super) struct Doc;

/// `?all=…`.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
struct TracksQuery {
    /// `true`: tentative tracks too.
    all: Option<bool>,
}

/// The track list.
#[derive(Debug, Serialize, ToSchema)]
pub struct TracksBody {
    /// Time of the last processed scan (the tracker's time line: UNIX s when scans carry it).
    t: Option<f64>,
    /// Scans processed so far.
    seq: u64,
    /// The tracks, in id order.
    tracks: Vec<TrackDto>,
}

/// The live tracks.
#[utoipa::path(get, path = "/api/v1/tracks", tag = "tracks", params(TracksQuery),
    responses(
        (status = 200, body = TracksBody),
        (status = 400, description = "Bad query", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn tracks(State(s): State<Tracking>, AppQuery(q): AppQuery<TracksQuery>) -> Json<TracksBody> {
    let all = q.all.unwrap_or(false);
    let snap = Arc::clone(&s.snapshot.borrow());
    let tracks = snap
        .tracks
        .iter()
        .filter(|k| all || k.status == TrackStatus::Confirmed)
        .map(TrackDto::from)
        .collect();
    Json(TracksBody {
        t: snap.t,
        seq: snap.seq,
        tracks,
    })
}

/// One track in full.
#[derive(Debug, Serialize, ToSchema)]
pub struct TrackDetail {
    /// The estimate, with its 95 % ellipse and ellipsoid.
    #[serde(flatten)]
    track: TrackDto,
    /// `[t, x, y, z]` after each update, oldest first (the last 200).
    history: Vec<[f64; 4]>,
    /// The set-membership (OBE) bound beside the track, when `tracker.bound.enabled`.
    bound: Option<BoundView>,
}

/// One track: estimate, confidence regions, history.
#[utoipa::path(get, path = "/api/v1/tracks/{id}", tag = "tracks",
    params(("id" = u64, Path, description = "Track id")),
    responses(
        (status = 200, body = TrackDetail),
        (status = 400, description = "The id is not a number", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
        (status = 404, description = "No such track (never was, or deleted)", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn track(
    State(s): State<Tracking>,
    AppPath(id): AppPath<String>,
) -> Result<Json<TrackDetail>, ApiError> {
    let id: u64 = id
        .parse()
        .map_err(|_| ApiError::bad_request("path", format!("track id {id:?} is not a number")))?;
    let snap = Arc::clone(&s.snapshot.borrow());
    let k = snap
        .tracks
        .iter()
        .find(|k| k.id == id)
        .ok_or_else(|| ApiError::not_found(format!("no track {id}")))?;
    Ok(Json(TrackDetail {
        track: TrackDto::from(k),
        history: s.recent.history(id),
        bound: s.recent.bound(id),
    }))
}

/// `?since=…`.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
#[into_params(parameter_in = Query)]
struct DetectionsQuery {
    /// Only scans with a larger `seq`.
    since: Option<u64>,
}

/// One processed scan.
#[derive(Debug, Serialize, ToSchema)]
pub struct ScanView {
    /// Processed-scan counter.
    seq: u64,
    /// Scan time.
    t: f64,
    /// Vehicle label.
    vehicle: String,
    /// Sensor id.
    sensor: String,
    /// Measurement kind (`position`, `range_bearing`, `az_el`, `bearing_size`).
    #[schema(value_type = MeasKindSchema)]
    kind: MeasKind,
    /// Sensor position (ENU, m).
    platform: [f64; 3],
    /// The detections (FORMAT.md §3 layout of `kind`, server frame).
    detections: Vec<Vec<f64>>,
}

/// The recent scans.
#[derive(Debug, Serialize, ToSchema)]
pub struct DetectionsBody {
    /// Oldest first, at most 512.
    scans: Vec<ScanView>,
}

/// The scans processed recently, with their detections.
#[utoipa::path(get, path = "/api/v1/detections", tag = "tracks", params(DetectionsQuery),
    responses(
        (status = 200, body = DetectionsBody),
        (status = 400, description = "Bad query", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn detections(
    State(s): State<Tracking>,
    AppQuery(q): AppQuery<DetectionsQuery>,
) -> Json<DetectionsBody> {
    let scans = s
        .recent
        .scans_after(q.since.unwrap_or(0))
        .iter()
        .map(|e| ScanView {
            seq: e.seq,
            t: e.t,
            vehicle: e.vehicle.clone(),
            sensor: e.sensor.clone(),
            kind: e.kind,
            platform: e.platform,
            detections: e.detections.clone(),
        })
        .collect();
    Json(DetectionsBody { scans })
}

#[cfg(test)]
mod tests {
    use axum::http::StatusCode;

    use super::super::testing::TestApp;

    #[tokio::test]
    async fn the_tracks_the_track_and_its_detections() {
        let app = TestApp::new();
        let empty = app.get("/api/v1/tracks").await;
        assert_eq!(empty.status, StatusCode::OK);
        assert_eq!(
            empty.json(),
            serde_json::json!({"t": null, "seq": 0, "tracks": []})
        );
        let id = app.confirmed_track().await;
        let list = app.get("/api/v1/tracks?all=true").await.json();
        assert!(
            list["tracks"]
                .as_array()
                .expect("tracks")
                .iter()
                .any(|k| k["id"] == id)
        );
        let one = app.get(&format!("/api/v1/tracks/{id}")).await;
        assert_eq!(one.status, StatusCode::OK);
        let one = one.json();
        assert_eq!(one["id"], id);
        assert_eq!(one["status"], "confirmed");
        let axes = &one["ellipse_95"]["semi_axes"];
        assert!(axes[0].as_f64().expect("a semi-axis") >= axes[1].as_f64().expect("another"));
        assert!(one["history"].as_array().is_some_and(|h| !h.is_empty()));
        let scans = app.get("/api/v1/detections?since=1").await.json();
        let scans = scans["scans"].as_array().expect("scans").clone();
        assert!(!scans.is_empty() && scans.iter().all(|s| s["seq"].as_u64() > Some(1)));
        assert_eq!(scans[0]["kind"], "position");
        assert_eq!(scans[0]["vehicle"], "2");
        assert_eq!(app.refused_total(), 0);
    }

    #[tokio::test]
    async fn a_bad_query_or_id_and_an_unknown_track_are_refused() {
        let app = TestApp::new();
        let r = app.get("/api/v1/tracks?all=maybe").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert!(r.error().starts_with("Failed to deserialize query string"));
        let r = app.get("/api/v1/detections?since=-1").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(app.refused("query", 400), 2);
        let r = app.get("/api/v1/tracks/abc").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(r.error(), "track id \"abc\" is not a number");
        assert_eq!(app.refused("path", 400), 1);
        let r = app.get("/api/v1/tracks/7").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(r.error(), "no track 7");
        assert_eq!(app.refused("not_found", 404), 1);
    }
}
