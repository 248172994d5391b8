//! The HTTP API (axum). Routes under `/api/v1`; the OpenAPI 3 document generated from this code
//! (utoipa) at `/api/openapi.json`; the web dashboard (`api.web_dir`) at `/`.
//!
//! | route | |
//! |---|---|
//! | `GET /tracks[?all=true]` | confirmed tracks (all with `all=true`) |
//! | `GET /tracks/{id}` | one track: state, covariance, 95 % ellipse / ellipsoid, history |
//! | `GET /detections[?since=seq]` | the scans processed recently (after `since`) |
//! | `GET /vehicles` | the vehicles as seen in their detections |
//! | `GET /estimator`, `PUT /estimator` | the running track estimator; change it (tracks kept) |
//! | `GET /estimators` | the track estimators (name, summary, parameters) |
//! | `GET /health` | status, uptime, estimator, last scan time, scans ingested |
//! | `GET /metrics` | Prometheus text format ([`super::metrics`]) |
//! | `GET /ws` | the WebSocket stream ([`super::ws`]) |
//! | `GET /sessions`, `/sessions/{id}`, `/sessions/{id}/export` | the recorded sessions; one exported as `gcs-scenario/1` |
//!
//! Every error is JSON `{"error": "…"}` with its status: a body that is not JSON 400, JSON of
//! the wrong shape 422 (naming the field), no or a wrong token 401, an unknown id or route 404.
//! Every mutating request needs `Authorization: Bearer <token>`: `api.token`, or one of the
//! named `[[api.tokens]]` before its expiry (a missing, wrong or expired token: 401, counted as
//! `auth_missing`, `auth_wrong`, `auth_expired`); reads need it too with `api.auth_reads` (the
//! WebSocket, which browsers cannot give headers, also takes `?token=`).
//! CORS is same-origin unless `api.cors_origins` lists origins. [`app`] builds the router from
//! an [`ApiState`], so tests can serve it on any listener.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::{Instant, SystemTime};

use axum::Json;
use axum::Router;
use axum::extract::rejection::{JsonRejection, QueryRejection};
use axum::extract::{Path, Query, Request, State};
use axum::http::{HeaderValue, Method, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use harrier_core::linalg::ellipse_axes;
use nalgebra::{Matrix2, Matrix3, SymmetricEigen};
use serde::{Deserialize, Serialize};
use tokio::sync::{broadcast, mpsc, oneshot, watch};
use utoipa::{OpenApi, ToSchema};

use super::metrics::Metrics;
use super::recorder::{Record, Recorder, RecorderStats};
use super::tracker::{Command, Recent, ScanEvents, Snapshot, TrackFilterState as EstimatorState};
use crate::engine::TrackView;
use crate::registry::TRACK_FILTERS as TRACK_ENGINES;
use crate::sessions::{self, Exported, SessionError, SessionInfo};

/// What the handlers read.
#[derive(Debug, Clone)]
pub struct ApiState {
    /// The tracker's latest snapshot.
    pub snapshot: watch::Receiver<Arc<Snapshot>>,
    /// Every processed scan (the WebSocket's source).
    pub events: broadcast::Sender<Arc<ScanEvents>>,
    /// Recent scans and track histories.
    pub recent: Arc<Recent>,
    /// Requests to the tracker.
    pub commands: mpsc::Sender<Command>,
    /// The counters.
    pub metrics: Arc<Metrics>,
    /// The bearer token and whether reads need it.
    pub auth: Arc<Auth>,
    /// When the service started.
    pub started: Instant,
    /// Becomes `true` when the service stops (ends the WebSocket streams).
    pub stop: watch::Receiver<bool>,
    /// The session recorder (records the API actions; its file serves `/sessions`).
    pub recorder: Option<Recorder>,
    /// Why there is no recorder although `recorder.path` is set.
    pub recording_error: Option<Arc<str>>,
    /// The MAVLink GCS link, when configured.
    pub link: Option<super::gcs::GcsLink>,
    /// The guidance loop, when the link runs.
    pub guidance: Option<super::guidance::Guidance>,
    /// The latest simulation truth.
    pub truth: watch::Receiver<Arc<super::control::TruthBody>>,
    /// Roads and obstacles of the configuration.
    pub world: Arc<super::control::WorldBody>,
}

/// The API's access rule.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Auth {
    /// The tokens accepted: `api.token` (named `main`, no expiry) and `api.tokens`.
    pub tokens: Vec<ApiToken>,
    /// Reads need a token too.
    pub reads: bool,
}

/// One accepted bearer token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ApiToken {
    /// Who holds it.
    pub name: String,
    /// The secret.
    pub secret: String,
    /// When it stops being accepted.
    pub expires: Option<SystemTime>,
}

/// What [`Auth::check`] found.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Verdict {
    Accepted,
    /// No `Authorization: Bearer` header (or WebSocket `token=`).
    Missing,
    /// A token no entry has.
    Wrong,
    /// A known token past its expiry.
    Expired {
        name: String,
        at: SystemTime,
    },
}

impl Auth {
    /// What `req` carries (header, or `token=` in the query of a WebSocket upgrade), judged at
    /// `now`. Every token is compared, each in constant time.
    fn check(&self, req: &Request, now: SystemTime) -> Verdict {
        let header = req
            .headers()
            .get(header::AUTHORIZATION)
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.strip_prefix("Bearer "));
        let query = req.uri().query().and_then(|q| {
            q.split('&')
                .find_map(|kv| kv.strip_prefix("token="))
                .filter(|_| req.uri().path().ends_with("/ws"))
        });
        let Some(given) = header.or(query) else {
            return Verdict::Missing;
        };
        let found = self.tokens.iter().fold(None, |found, t| {
            if constant_time_eq(given.as_bytes(), t.secret.as_bytes()) {
                Some(t)
            } else {
                found
            }
        });
        match found {
            None => Verdict::Wrong,
            Some(t) => match t.expires {
                Some(at) if now >= at => Verdict::Expired {
                    name: t.name.clone(),
                    at,
                },
                _ => Verdict::Accepted,
            },
        }
    }
}

fn constant_time_eq(a: &[u8], b: &[u8]) -> bool {
    a.len() == b.len() && a.iter().zip(b).fold(0u8, |acc, (x, y)| acc | (x ^ y)) == 0
}

/// The body of every error response.
#[derive(Debug, Serialize, ToSchema)]
pub struct ErrorBody {
    /// What went wrong.
    pub error: String,
}

/// A JSON error response.
pub fn error(status: StatusCode, message: impl Into<String>) -> Response {
    (
        status,
        Json(ErrorBody {
            error: message.into(),
        }),
    )
        .into_response()
}

/// The OpenAPI document.
#[derive(Debug, OpenApi)]
#[openapi(
    info(
        title = "Harrier ground station API",
        description = "Live multi-target tracks from UAV detections. Mutating requests need `Authorization: Bearer <token>` (printed at start when not configured).",
    ),
    paths(
        tracks,
        track,
        detections,
        super::control::vehicles,
        super::control::vehicle,
        super::control::command,
        super::control::assignments,
        super::control::create_assignment,
        super::control::assignment,
        super::control::end_assignment,
        super::control::truth,
        super::control::world,
        get_estimator,
        put_estimator,
        estimators,
        health,
        metrics,
        list_sessions,
        session,
        export_session,
        super::ws::ws
    ),
    modifiers(&BearerAuth),
    tags(
        (name = "tracks", description = "Live tracks and what they are made of"),
        (name = "control", description = "The running estimator"),
        (name = "vehicles", description = "Vehicles on the MAVLink link, and commands"),
        (name = "guidance", description = "Assignments of vehicles to tracks"),
        (name = "service", description = "Health and metrics"),
        (name = "sessions", description = "Recorded sessions (SQLite, RECORDING.md)"),
        (name = "stream", description = "The WebSocket stream"),
    )
)]
pub struct ApiDoc;

/// Declares the bearer-token scheme.
struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        let components = openapi.components.get_or_insert_with(Default::default);
        components.add_security_scheme(
            "bearer",
            SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
        );
    }
}

/// The router: the API under `/api/v1`, the OpenAPI document, the dashboard from `web_dir`
/// (when given) at `/`, CORS for `cors_origins`.
pub fn app(state: ApiState, web_dir: Option<&std::path::Path>, cors_origins: &[String]) -> Router {
    let api = Router::new()
        .route("/tracks", get(tracks))
        .route("/tracks/{id}", get(track))
        .route("/detections", get(detections))
        .route("/vehicles", get(super::control::vehicles))
        .route("/vehicles/{id}", get(super::control::vehicle))
        .route("/vehicles/{id}/commands", post(super::control::command))
        .route(
            "/assignments",
            get(super::control::assignments).post(super::control::create_assignment),
        )
        .route(
            "/assignments/{id}",
            get(super::control::assignment).delete(super::control::end_assignment),
        )
        .route("/truth", get(super::control::truth))
        .route("/world", get(super::control::world))
        .route("/estimator", get(get_estimator).put(put_estimator))
        .route("/estimators", get(estimators))
        .route("/health", get(health))
        .route("/metrics", get(metrics))
        .route("/ws", get(super::ws::ws))
        .route("/sessions", get(list_sessions))
        .route("/sessions/{id}", get(session))
        .route("/sessions/{id}/export", get(export_session))
        .fallback(|State(s): State<ApiState>| async move {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, "no such route")
        })
        .layer(middleware::from_fn_with_state(state.clone(), guard));
    let mut router = Router::new()
        .nest("/api/v1", api)
        .route("/api/openapi.json", get(openapi));
    router = match web_dir {
        Some(dir) => router.fallback_service(
            tower_http::services::ServeDir::new(dir).append_index_html_on_directories(true),
        ),
        None => router.fallback(|| async { error(StatusCode::NOT_FOUND, "no such route") }),
    };
    let router = router.with_state(state);
    if cors_origins.is_empty() {
        return router;
    }
    let origins: Vec<HeaderValue> = cors_origins
        .iter()
        .filter_map(|o| HeaderValue::from_str(o).ok())
        .collect();
    router.layer(
        tower_http::cors::CorsLayer::new()
            .allow_origin(origins)
            .allow_methods([Method::GET, Method::PUT, Method::POST, Method::DELETE])
            .allow_headers([header::AUTHORIZATION, header::CONTENT_TYPE]),
    )
}

/// Largest request body read (mutating routes take small JSON objects).
const MAX_BODY: usize = 64 * 1024;

/// Refuses requests without the token where it is needed and counts refusals; records every
/// mutating request (method, path, body, status), refused or not, when recording.
async fn guard(State(s): State<ApiState>, req: Request, next: Next) -> Response {
    let mutating = !matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    let verdict = if mutating || s.auth.reads {
        s.auth.check(&req, SystemTime::now())
    } else {
        Verdict::Accepted
    };
    let allowed = verdict == Verdict::Accepted;
    let Some(recorder) = s.recorder.as_ref().filter(|_| mutating) else {
        return if allowed {
            next.run(req).await
        } else {
            unauthorized(&s, verdict)
        };
    };
    let method = req.method().to_string();
    let path = req.uri().path().to_string();
    let (parts, body) = req.into_parts();
    let (response, body) = match axum::body::to_bytes(body, MAX_BODY).await {
        Err(_) => {
            s.metrics.http_refused("too_large", 413);
            let r = error(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!("request bodies are limited to {MAX_BODY} bytes"),
            );
            (r, String::new())
        }
        Ok(bytes) => {
            let text = String::from_utf8_lossy(&bytes).into_owned();
            let r = if allowed {
                next.run(Request::from_parts(parts, axum::body::Body::from(bytes)))
                    .await
            } else {
                unauthorized(&s, verdict)
            };
            (r, text)
        }
    };
    recorder.record(Record::Action {
        time_unix: super::clock::unix_now(),
        method,
        path,
        body,
        status: response.status().as_u16(),
    });
    response
}

/// 401 with `WWW-Authenticate: Bearer` (RFC 6750: `error="invalid_token"` for a wrong or expired
/// one), counted by reason (`auth_missing`, `auth_wrong`, `auth_expired`).
fn unauthorized(s: &ApiState, verdict: Verdict) -> Response {
    let (reason, message, challenge) = match verdict {
        Verdict::Missing | Verdict::Accepted => (
            "auth_missing",
            "this request needs the API token: Authorization: Bearer <token>".to_owned(),
            "Bearer",
        ),
        Verdict::Wrong => (
            "auth_wrong",
            "the API token is not valid".to_owned(),
            "Bearer error=\"invalid_token\"",
        ),
        Verdict::Expired { name, at } => (
            "auth_expired",
            format!(
                "the API token {name:?} expired at {}",
                humantime::format_rfc3339_seconds(at)
            ),
            "Bearer error=\"invalid_token\", error_description=\"expired\"",
        ),
    };
    s.metrics.http_refused(reason, 401);
    let mut r = error(StatusCode::UNAUTHORIZED, message);
    r.headers_mut().insert(
        header::WWW_AUTHENTICATE,
        HeaderValue::from_static(challenge),
    );
    r
}

async fn openapi() -> Json<utoipa::openapi::OpenApi> {
    Json(ApiDoc::openapi())
}

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

/// A refused query string.
fn bad_query(s: &ApiState, e: &QueryRejection) -> Response {
    s.metrics.http_refused("query", 400);
    error(StatusCode::BAD_REQUEST, e.body_text())
}

/// The live tracks.
#[utoipa::path(get, path = "/api/v1/tracks", tag = "tracks", params(TracksQuery),
    responses(
        (status = 200, body = TracksBody),
        (status = 400, description = "Bad query", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn tracks(
    State(s): State<ApiState>,
    q: Result<Query<TracksQuery>, QueryRejection>,
) -> Response {
    let all = match q {
        Ok(q) => q.all.unwrap_or(false),
        Err(e) => return bad_query(&s, &e),
    };
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
    .into_response()
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
    bound: Option<super::bound::BoundView>,
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
async fn track(State(s): State<ApiState>, Path(id): Path<String>) -> Response {
    let Ok(id) = id.parse::<u64>() else {
        s.metrics.http_refused("path", 400);
        return error(
            StatusCode::BAD_REQUEST,
            format!("track id {id:?} is not a number"),
        );
    };
    let snap = Arc::clone(&s.snapshot.borrow());
    match snap.tracks.iter().find(|k| k.id == id) {
        Some(k) => Json(TrackDetail {
            ellipse_95: ellipse(k),
            ellipsoid_95: ellipsoid(k),
            history: s.recent.history(id),
            bound: s.recent.bound(id),
            track: k.clone(),
        })
        .into_response(),
        None => {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, format!("no track {id}"))
        }
    }
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
    State(s): State<ApiState>,
    q: Result<Query<DetectionsQuery>, QueryRejection>,
) -> Response {
    let since = match q {
        Ok(q) => q.since.unwrap_or(0),
        Err(e) => return bad_query(&s, &e),
    };
    let scans = s
        .recent
        .scans_after(since)
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
    Json(DetectionsBody { scans }).into_response()
}

/// The running estimator.
#[utoipa::path(get, path = "/api/v1/estimator", tag = "control",
    responses(
        (status = 200, body = EstimatorState),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn get_estimator(State(s): State<ApiState>) -> Json<EstimatorState> {
    Json((*s.snapshot.borrow().estimator).clone())
}

/// A change of estimator.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct EstimatorChange {
    /// Track estimator name (`GET /api/v1/estimators`).
    #[schema(schema_with = estimator_names)]
    pub name: String,
    /// Parameters, name → value (the others default).
    #[serde(default)]
    pub params: BTreeMap<String, f64>,
}

/// The schema of an estimator name: one of [`TRACK_ENGINES`].
fn estimator_names() -> utoipa::openapi::Object {
    utoipa::openapi::ObjectBuilder::new()
        .schema_type(utoipa::openapi::schema::Type::String)
        .enum_values(Some(TRACK_ENGINES.iter().map(|e| e.name)))
        .description(Some("Track estimator name (`GET /api/v1/estimators`)"))
        .build()
}

/// Changes the estimator; the live tracks are handed over (ids, status and estimates kept).
#[utoipa::path(put, path = "/api/v1/estimator", tag = "control", request_body = EstimatorChange,
    responses(
        (status = 200, description = "Now running", body = EstimatorState),
        (status = 400, description = "The body is not JSON", body = ErrorBody),
        (status = 401, description = "No or a wrong token", body = ErrorBody),
        (status = 409, description = "The tracks cannot be handed over to this estimator", body = ErrorBody),
        (status = 415, description = "Not `Content-Type: application/json`", body = ErrorBody),
        (status = 422, description = "Unknown estimator or parameter, or a field of the wrong type", body = ErrorBody),
        (status = 503, description = "The tracker is not running", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn put_estimator(
    State(s): State<ApiState>,
    body: Result<Json<EstimatorChange>, JsonRejection>,
) -> Response {
    let change = match body {
        Ok(Json(c)) => c,
        Err(e) => return bad_json(&s, &e),
    };
    let (reply, answer) = oneshot::channel();
    let to = EstimatorState {
        name: change.name,
        params: change.params,
    };
    let gone = || {
        error(
            StatusCode::SERVICE_UNAVAILABLE,
            "the tracker is not running",
        )
    };
    if s.commands
        .send(Command::SetEstimator { to, reply })
        .await
        .is_err()
    {
        return gone();
    }
    match answer.await {
        Ok(Ok(now)) => Json(now).into_response(),
        Ok(Err(SetError::Invalid(m))) => {
            s.metrics.http_refused("estimator", 422);
            error(StatusCode::UNPROCESSABLE_ENTITY, m)
        }
        Ok(Err(SetError::Handover(m))) => {
            s.metrics.http_refused("estimator", 409);
            error(StatusCode::CONFLICT, m)
        }
        Err(_) => gone(),
    }
}

pub use super::tracker::SetError;

/// A track estimator parameter.
#[derive(Debug, Serialize, ToSchema)]
pub struct ParamInfo {
    /// Name.
    name: &'static str,
    /// Meaning and default.
    description: &'static str,
}

/// A track estimator.
#[derive(Debug, Serialize, ToSchema)]
pub struct EstimatorInfoBody {
    /// Name.
    name: &'static str,
    /// One line.
    summary: &'static str,
    /// Its parameters.
    params: Vec<ParamInfo>,
}

/// The estimator list.
#[derive(Debug, Serialize, ToSchema)]
pub struct EstimatorsBody {
    /// Every track estimator.
    estimators: Vec<EstimatorInfoBody>,
}

/// The track estimators that can run live.
#[utoipa::path(get, path = "/api/v1/estimators", tag = "control",
    responses(
        (status = 200, body = EstimatorsBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn estimators() -> Json<EstimatorsBody> {
    Json(EstimatorsBody {
        estimators: TRACK_ENGINES
            .iter()
            .map(|e| EstimatorInfoBody {
                name: e.name,
                summary: e.summary,
                params: e
                    .params
                    .iter()
                    .map(|&(name, description)| ParamInfo { name, description })
                    .collect(),
            })
            .collect(),
    })
}

/// Service health.
#[derive(Debug, Serialize, ToSchema)]
pub struct HealthBody {
    /// `ok`.
    status: &'static str,
    /// Seconds since start.
    uptime_s: f64,
    /// The running track estimator.
    estimator: String,
    /// Time of the last processed scan.
    last_scan_t: Option<f64>,
    /// Scans processed.
    scans_ingested: u64,
    /// Why the service runs without a recording although `recorder.path` is set (the file
    /// could not be opened: read-only, full, not a session file); absent otherwise.
    #[serde(skip_serializing_if = "Option::is_none")]
    recording_error: Option<String>,
}

/// Health.
#[utoipa::path(get, path = "/api/v1/health", tag = "service",
    responses(
        (status = 200, body = HealthBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn health(State(s): State<ApiState>) -> Json<HealthBody> {
    Json(HealthBody {
        status: "ok",
        uptime_s: s.started.elapsed().as_secs_f64(),
        estimator: s.snapshot.borrow().estimator.name.clone(),
        last_scan_t: s.metrics.last_scan_t(),
        scans_ingested: s.metrics.scans_ingested(),
        recording_error: s.recording_error.as_deref().map(str::to_owned),
    })
}

/// Prometheus metrics.
#[utoipa::path(get, path = "/api/v1/metrics", tag = "service",
    responses(
        (status = 200, description = "Prometheus text exposition format 0.0.4", content_type = "text/plain", body = String),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn metrics(State(s): State<ApiState>) -> Response {
    let mut text = s.metrics.render(s.started.elapsed().as_secs_f64());
    if let Some(r) = &s.recorder {
        render_recorder(&mut text, &r.stats());
    }
    if s.recorder.is_some() || s.recording_error.is_some() {
        use std::fmt::Write as _;
        let _ = writeln!(
            text,
            "# HELP harrier_recorder_up 1: recording; 0: recorder.path is set but the file could \
             not be opened (see /api/v1/health).\n# TYPE harrier_recorder_up gauge\n\
             harrier_recorder_up {}",
            u8::from(s.recorder.is_some())
        );
    }
    if let Some(l) = &s.link {
        l.render_metrics(&mut text);
    }
    if let Some(g) = &s.guidance {
        let active = g
            .assignments
            .borrow()
            .iter()
            .filter(|a| a.state == "active")
            .count();
        g.metrics.render(active, &mut text);
    }
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response()
}

/// The recorder's counters in the Prometheus text format.
fn render_recorder(out: &mut String, st: &RecorderStats) {
    use std::fmt::Write as _;
    let _ = writeln!(
        out,
        "# HELP harrier_recorder_rows_total Rows committed to the session file, by table.\n\
         # TYPE harrier_recorder_rows_total counter"
    );
    for (table, n) in [
        ("scans", st.scans),
        ("detections", st.detections),
        ("tracks", st.track_rows),
        ("truth", st.truth_rows),
        ("actions", st.actions),
        ("vehicle_log", st.vehicle_rows),
    ] {
        let _ = writeln!(out, "harrier_recorder_rows_total{{table=\"{table}\"}} {n}");
    }
    for (name, help, v) in [
        (
            "harrier_recorder_dropped_total",
            "Records dropped because the writer's queue was full.",
            st.dropped,
        ),
        (
            "harrier_recorder_errors_total",
            "Failed writes to the session file.",
            st.errors,
        ),
        (
            "harrier_recorder_commits_total",
            "Transactions committed.",
            st.commits,
        ),
    ] {
        let _ = writeln!(
            out,
            "# HELP {name} {help}\n# TYPE {name} counter\n{name} {v}"
        );
    }
}

/// The sessions of the recording file.
#[derive(Debug, Serialize, ToSchema)]
pub struct SessionsBody {
    /// The recording file; `null` when recording is off.
    file: Option<String>,
    /// The id of this server's session.
    current: Option<i64>,
    /// Every session in the file, oldest first.
    sessions: Vec<SessionInfo>,
}

/// Runs a read of the recording file off the async threads; maps its errors to responses.
async fn with_file<T: Send + 'static>(
    s: &ApiState,
    read: impl FnOnce(&std::path::Path) -> Result<T, SessionError> + Send + 'static,
) -> Result<T, Response> {
    let Some(r) = &s.recorder else {
        s.metrics.http_refused("not_found", 404);
        return Err(error(
            StatusCode::NOT_FOUND,
            "recording is off (set recorder.path or --record)",
        ));
    };
    let path = r.path().to_path_buf();
    match tokio::task::spawn_blocking(move || read(&path)).await {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e @ SessionError::NotFound { .. })) => {
            s.metrics.http_refused("not_found", 404);
            Err(error(StatusCode::NOT_FOUND, e.to_string()))
        }
        Ok(Err(e @ SessionError::Export { .. })) => {
            s.metrics.http_refused("export", 409);
            Err(error(StatusCode::CONFLICT, e.to_string()))
        }
        Ok(Err(e)) => Err(error(StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
        Err(e) => Err(error(StatusCode::INTERNAL_SERVER_ERROR, e.to_string())),
    }
}

/// The answer to a body axum's `Json` refused (400 syntax, 415 content type, 422 data), counted
/// under `json`.
pub(super) fn bad_json(s: &ApiState, e: &JsonRejection) -> Response {
    let status = e.status();
    s.metrics.http_refused("json", status.as_u16());
    error(status, e.body_text())
}

/// The 400 of a session id that is not a number.
fn bad_session_id(s: &ApiState, id: &str) -> Response {
    s.metrics.http_refused("path", 400);
    error(
        StatusCode::BAD_REQUEST,
        format!("session id {id:?} is not a number"),
    )
}

/// The recorded sessions (this server's recording file).
#[utoipa::path(get, path = "/api/v1/sessions", tag = "sessions",
    responses(
        (status = 200, body = SessionsBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn list_sessions(State(s): State<ApiState>) -> Response {
    let Some(r) = &s.recorder else {
        return Json(SessionsBody {
            file: None,
            current: None,
            sessions: Vec::new(),
        })
        .into_response();
    };
    let (file, current) = (r.path().display().to_string(), r.session_id());
    match with_file(&s, sessions::list).await {
        Ok(list) => Json(SessionsBody {
            file: Some(file),
            current: Some(current),
            sessions: list,
        })
        .into_response(),
        Err(r) => r,
    }
}

/// One recorded session's summary.
#[utoipa::path(get, path = "/api/v1/sessions/{id}", tag = "sessions",
    params(("id" = i64, Path, description = "Session id")),
    responses(
        (status = 200, body = SessionInfo),
        (status = 400, description = "The id is not a number", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
        (status = 404, description = "No such session, or recording is off", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn session(State(s): State<ApiState>, Path(id): Path<String>) -> Response {
    let Ok(id) = id.parse::<i64>() else {
        return bad_session_id(&s, &id);
    };
    match with_file(&s, move |p| sessions::info(p, id)).await {
        Ok(info) => Json(info).into_response(),
        Err(r) => r,
    }
}

/// A recorded session exported as a `gcs-scenario/1` directory's files (`harrier replay` and
/// `score.py` read them once written out; `harrier sessions export` writes them).
#[utoipa::path(get, path = "/api/v1/sessions/{id}/export", tag = "sessions",
    params(("id" = i64, Path, description = "Session id")),
    responses(
        (status = 200, body = Exported),
        (status = 400, description = "The id is not a number", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
        (status = 404, description = "No such session, or recording is off", body = ErrorBody),
        (status = 409, description = "The session cannot be exported (e.g. no scans yet)", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn export_session(State(s): State<ApiState>, Path(id): Path<String>) -> Response {
    let Ok(id) = id.parse::<i64>() else {
        return bad_session_id(&s, &id);
    };
    match with_file(&s, move |p| sessions::export(p, id)).await {
        Ok(e) => Json(e).into_response(),
        Err(r) => r,
    }
}
