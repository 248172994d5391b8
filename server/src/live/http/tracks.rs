//! `GET /tracks[?all=true]`, `GET /tracks/{id}`, `GET /detections[?since=seq]`: the live tracks
//! and the scans they are made of.

use std::sync::Arc;

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use harrier_core::linalg::ellipse_axes;
use nalgebra::{Matrix2, Matrix3, SymmetricEigen};
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::{AppPath, AppQuery};
use super::state::{ApiState, Tracking};
use crate::engine::TrackView;
use crate::live::bound::BoundView;

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
    tracks: Vec<TrackView>,
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
        .filter(|k| all || k.status == "confirmed")
        .cloned()
        .collect();
    Json(TracksBody {
        t: snap.t,
        seq: snap.seq,
        tracks,
    })
}

/// The 95 % confidence ellipse of a planar position.
#[derive(Debug, Serialize, ToSchema)]
pub struct Ellipse {
    /// Semi-axes (m), major first.
    semi_axes: [f64; 2],
    /// Direction of the major axis (rad, counter-clockwise from East).
    angle_rad: f64,
}

/// The 95 % confidence ellipsoid of a 3-D position.
#[derive(Debug, Serialize, ToSchema)]
pub struct Ellipsoid {
    /// Semi-axes (m), largest first.
    semi_axes: [f64; 3],
    /// Unit axis directions (ENU), in the order of `semi_axes`.
    axes: [[f64; 3]; 3],
}

/// One track in full.
#[derive(Debug, Serialize, ToSchema)]
pub struct TrackDetail {
    /// The estimate.
    #[serde(flatten)]
    track: TrackView,
    /// 95 % position ellipse (x, y).
    ellipse_95: Option<Ellipse>,
    /// 95 % position ellipsoid (3-D tracks).
    ellipsoid_95: Option<Ellipsoid>,
    /// `[t, x, y, z]` after each update, oldest first (the last 200).
    history: Vec<[f64; 4]>,
    /// The set-membership (OBE) bound beside the track, when `tracker.bound.enabled`.
    bound: Option<BoundView>,
}

/// χ² quantiles of 0.95 for 2 and 3 degrees of freedom.
const CHI2_95_2: f64 = 5.991_464_547_107_979;
const CHI2_95_3: f64 = 7.814_727_903_251_178;

/// The position block of `k`'s covariance over the state indices `dims` (`None` when absent).
fn position_cov(k: &TrackView, dims: &[usize]) -> Option<Vec<Vec<f64>>> {
    let at: Option<Vec<usize>> = dims
        .iter()
        .map(|d| k.cov_dims.iter().position(|c| c == d))
        .collect();
    let at = at?;
    Some(
        at.iter()
            .map(|&i| at.iter().map(|&j| k.cov[i][j]).collect())
            .collect(),
    )
}

fn ellipse(k: &TrackView) -> Option<Ellipse> {
    let c = position_cov(k, &[0, 1])?;
    let m = Matrix2::new(c[0][0], c[0][1], c[1][0], c[1][1]);
    let (semi_axes, angle_rad) = ellipse_axes(&(m * CHI2_95_2));
    Some(Ellipse {
        semi_axes,
        angle_rad,
    })
}

fn ellipsoid(k: &TrackView) -> Option<Ellipsoid> {
    let c = position_cov(k, &[0, 1, 2])?;
    let m = Matrix3::from_fn(|i, j| c[i][j]);
    let e = SymmetricEigen::new(0.5 * (m + m.transpose()));
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| e.eigenvalues[b].total_cmp(&e.eigenvalues[a]));
    let axis = |i: usize| {
        let v = e.eigenvectors.column(i);
        [v[0], v[1], v[2]]
    };
    Some(Ellipsoid {
        semi_axes: order.map(|i| (CHI2_95_3 * e.eigenvalues[i].max(0.0)).sqrt()),
        axes: order.map(axis),
    })
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
        ellipse_95: ellipse(k),
        ellipsoid_95: ellipsoid(k),
        history: s.recent.history(id),
        bound: s.recent.bound(id),
        track: k.clone(),
    }))
}

/// `?since=…`.
#[derive(Debug, Deserialize, utoipa::IntoParams)]
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
    kind: String,
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
            kind: e.kind.as_str().to_string(),
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
