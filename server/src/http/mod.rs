//! The HTTP API (axum). Routes under `/api/v1`; the OpenAPI 3 document generated from this code
//! (utoipa) at `/api/openapi.json`; Prometheus text also at `/metrics`; the web dashboard
//! (`api.web_dir`) at `/`.
//!
//! | route | file |
//! |---|---|
//! | `GET /tracks[?all=true]`, `GET /tracks/{id}`, `GET /detections[?since=seq]` | [`tracks`] |
//! | `GET`/`PUT /estimator`, `GET /estimators` | [`estimator`] |
//! | `GET /biases` | [`biases`] |
//! | `GET /vehicles`, `GET /vehicles/{id}`, `POST /vehicles/{id}/commands`, `POST /vehicles/{id}/accept` | [`vehicles`] |
//! | `GET`/`POST /assignments`, `GET`/`DELETE /assignments/{id}`, `POST /assignments/{id}/vehicles/{vehicle}/resume` | [`assignments`] |
//! | `GET /truth`, `GET /world`, `GET /aircraft` | [`world`] |
//! | `GET /map`, and `GET /tiles/{z}/{x}/{y}` at the root | [`map`] |
//! | `GET /sessions`, `/sessions/{id}`, `/sessions/{id}/export` | [`sessions`] |
//! | `GET /health`, `GET /metrics` (and `GET /metrics` at the root) | [`service`] |
//! | `GET /ws` | [`ws`] |
//!
//! Each route file holds its handlers, their request and response types, its `routes()` and
//! its OpenAPI `Doc`; a handler takes the part of [`ApiState`] it reads (`State<Tracking>`, …)
//! and returns `Result<Json<T>, ApiError>`. Every refusal is one `ApiError` (`error.rs`): JSON
//! `{"error": "…"}` with its status — a body that is not JSON 400, JSON of the wrong shape 422
//! (naming the field), no or a wrong token 401, an unknown id or route 404, a body that did not
//! arrive in time 408 — counted once, by the `count_refusals` middleware, in
//! `harrier_http_refused_total{reason, status}`.
//!
//! Every mutating request needs `Authorization: Bearer <token>`: `api.token`, or one of the
//! named `[[api.tokens]]` before its expiry (a missing, wrong or expired token: 401, counted as
//! `auth_missing`, `auth_wrong`, `auth_expired`); reads need it too with `api.auth_reads` (the
//! WebSocket, which browsers cannot give headers, also takes `?token=`).
//! CORS is same-origin unless `api.cors_origins` lists origins. [`app`] builds the router from
//! an [`ApiState`], so tests call it in-process (`app(state).oneshot(request)`) or serve it on
//! any listener; the service serves it with [`serve`] (`serve.rs`: a header timeout, a cap on
//! open connections, a body deadline).

pub mod assignments;
pub mod biases;
mod error;
pub mod estimator;
mod extract;
pub mod map;
mod serve;
pub mod service;
pub mod sessions;
mod state;
pub mod tracks;
pub mod vehicles;
pub mod world;
pub mod ws;

#[cfg(test)]
mod testing;

use std::path::Path;
use std::time::SystemTime;

use axum::extract::{Request, State};
use axum::http::{HeaderValue, Method, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::{Json, Router};
use utoipa::OpenApi;

use self::error::{ApiError, count_refusals};
pub use self::serve::{ConnectionStats, Limits, serve};
use self::state::Verdict;
pub use self::state::{ApiState, ApiToken, Auth, Control, Recording, Service, Tracking};
use crate::clock::unix_now;
use harrier_recording::writer::Record;

/// The OpenAPI document's title, description, tags and security scheme; [`openapi`] adds the
/// paths of every route file.
#[derive(Debug, OpenApi)]
#[openapi(
    info(
        title = "Harrier ground station API",
        description = "Live multi-target tracks from UAV detections. Mutating requests need `Authorization: Bearer <token>` (printed at start when not configured).",
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

/// The whole OpenAPI document: [`ApiDoc`] with the paths (and their schemas) of every route file.
pub fn openapi() -> utoipa::openapi::OpenApi {
    let mut doc = ApiDoc::openapi();
    for part in [
        tracks::Doc::openapi(),
        biases::Doc::openapi(),
        vehicles::Doc::openapi(),
        assignments::Doc::openapi(),
        world::Doc::openapi(),
        map::Doc::openapi(),
        estimator::Doc::openapi(),
        service::Doc::openapi(),
        sessions::Doc::openapi(),
        ws::Doc::openapi(),
    ] {
        doc.merge(part);
    }
    doc
}

/// The router: the API under `/api/v1`, Prometheus text at `/metrics`, the OpenAPI document,
/// the dashboard from `web_dir` (when given) at `/`, CORS for `cors_origins`.
pub fn app(state: ApiState, web_dir: Option<&Path>, cors_origins: &[String]) -> Router {
    let guard = middleware::from_fn_with_state(state.clone(), guard);
    let count = middleware::from_fn_with_state(state.service.clone(), count_refusals);
    // Layers wrap from the inside out: the guard sees the request first, the count sees every
    // response last (the guard's refusals too).
    let api = Router::new()
        .merge(tracks::routes())
        .merge(biases::routes())
        .merge(vehicles::routes())
        .merge(assignments::routes())
        .merge(world::routes())
        .merge(map::routes())
        .merge(estimator::routes())
        .merge(service::routes())
        .merge(sessions::routes())
        .merge(ws::routes())
        .fallback(|| async { ApiError::not_found("no such route") })
        .layer(guard.clone())
        .layer(count.clone());
    let mut router = Router::new()
        .nest("/api/v1", api)
        .merge(service::root_routes().route_layer(guard).route_layer(count.clone()))
        // Tiles are open like the dashboard (a browser loads them as images, without a token);
        // their refusals are counted as the API's.
        .merge(map::root_routes().route_layer(count))
        .route("/api/openapi.json", get(openapi_json));
    router = match web_dir {
        Some(dir) => router.fallback_service(
            tower_http::services::ServeDir::new(dir).append_index_html_on_directories(true),
        ),
        None => router.fallback(|| async { ApiError::not_found("no such route") }),
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

async fn openapi_json() -> Json<utoipa::openapi::OpenApi> {
    Json(openapi())
}

/// Largest request body read (mutating routes take small JSON objects).
const MAX_BODY: usize = 64 * 1024;

/// Refuses requests without the token where it is needed; records every mutating request
/// (method, path, body, status), refused or not, when recording.
async fn guard(State(s): State<ApiState>, req: Request, next: Next) -> Response {
    let mutating = !matches!(*req.method(), Method::GET | Method::HEAD | Method::OPTIONS);
    let verdict = if mutating || s.service.auth.reads {
        s.service.auth.check(&req, SystemTime::now())
    } else {
        Verdict::Accepted
    };
    let refused = (verdict != Verdict::Accepted).then_some(ApiError::Unauthorized(verdict));
    let Some(recorder) = s.recording.recorder.as_ref().filter(|_| mutating) else {
        return match refused {
            None => next.run(req).await,
            Some(e) => e.into_response(),
        };
    };
    let method = req.method().to_string();
    let path = req.uri().path().to_string();
    let (parts, body) = req.into_parts();
    let (response, body) = match axum::body::to_bytes(body, MAX_BODY).await {
        Err(e) => {
            let e = ApiError::body_timeout(&e).unwrap_or_else(|| ApiError::PayloadTooLarge {
                reason: "too_large",
                message: format!("request bodies are limited to {MAX_BODY} bytes"),
            });
            (e.into_response(), String::new())
        }
        Ok(bytes) => {
            let text = String::from_utf8_lossy(&bytes).into_owned();
            let response = match refused {
                None => {
                    next.run(Request::from_parts(parts, axum::body::Body::from(bytes)))
                        .await
                }
                Some(e) => e.into_response(),
            };
            (response, text)
        }
    };
    recorder.record(Record::Action {
        time_unix: unix_now(),
        method,
        path,
        body,
        status: response.status().as_u16(),
    });
    response
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use axum::http::{Method, StatusCode, header};

    use super::testing::{TOKEN, TestApp, request};

    #[tokio::test]
    async fn a_mutating_request_without_a_good_token_is_refused_and_counted_by_reason() {
        let at = std::time::SystemTime::UNIX_EPOCH + Duration::from_secs(1_000_000);
        let app = TestApp::new().with_expired_token("ci", "ci-secret-0123456789abcdef", at);
        let put = |token: Option<&'static str>| {
            request(
                Method::PUT,
                "/api/v1/estimator",
                token,
                Some(r#"{"name":"ekf"}"#),
            )
        };
        let r = app.call(put(None)).await;
        assert_eq!(r.status, StatusCode::UNAUTHORIZED);
        assert_eq!(r.headers[header::WWW_AUTHENTICATE], "Bearer");
        assert!(r.error().contains("Authorization: Bearer"));
        let r = app.call(put(Some("not-the-token"))).await;
        assert_eq!(r.status, StatusCode::UNAUTHORIZED);
        assert_eq!(
            r.headers[header::WWW_AUTHENTICATE],
            "Bearer error=\"invalid_token\""
        );
        assert_eq!(r.error(), "the API token is not valid");
        let r = app.call(put(Some("ci-secret-0123456789abcdef"))).await;
        assert_eq!(r.status, StatusCode::UNAUTHORIZED);
        assert!(
            r.error()
                .starts_with("the API token \"ci\" expired at 1970-01-12T13:46:40Z")
        );
        assert_eq!(
            (
                app.refused("auth_missing", 401),
                app.refused("auth_wrong", 401),
                app.refused("auth_expired", 401)
            ),
            (1, 1, 1)
        );
        assert_eq!(app.call(put(Some(TOKEN))).await.status, StatusCode::OK);
        assert_eq!(app.refused_total(), 3);
    }

    #[tokio::test]
    async fn reads_are_open_unless_they_need_the_token() {
        let open = TestApp::new();
        assert_eq!(open.get("/api/v1/tracks").await.status, StatusCode::OK);
        let closed = TestApp::new().reads_need_token();
        for uri in ["/api/v1/tracks", "/api/v1/nothing-here", "/metrics"] {
            let r = closed.get(uri).await;
            assert_eq!(r.status, StatusCode::UNAUTHORIZED, "{uri}");
            assert!(r.error().contains("needs the API token"));
            assert_eq!(
                closed.get_with_token(uri).await.status.is_success(),
                uri != "/api/v1/nothing-here"
            );
        }
        assert_eq!(closed.refused("auth_missing", 401), 3);
        // The OpenAPI document is always open.
        assert_eq!(closed.get("/api/openapi.json").await.status, StatusCode::OK);
    }

    #[tokio::test]
    async fn a_body_that_is_not_json_gets_a_json_400_counted_once() {
        let app = TestApp::new();
        let r = app
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"#)
            .await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(r.headers[header::CONTENT_TYPE], "application/json");
        assert!(
            r.error()
                .starts_with("Failed to parse the request body as JSON")
        );
        assert_eq!((app.refused("json", 400), app.refused_total()), (1, 1));
    }

    #[tokio::test]
    async fn an_unknown_route_under_the_api_is_a_json_404() {
        let app = TestApp::new();
        let r = app.get("/api/v1/no/such/route").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(r.error(), "no such route");
        assert_eq!(app.refused("not_found", 404), 1);
        // Outside the API (no dashboard here): a 404 too, not counted as an API refusal.
        let r = app.get("/elsewhere").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(app.refused_total(), 1);
    }

    #[tokio::test]
    async fn a_mutating_body_over_the_limit_is_refused_and_every_action_recorded() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let app = TestApp::new().with_recording(dir.path());
        let big = format!(r#"{{"name":"{}"}}"#, "x".repeat(super::MAX_BODY));
        let r = app.send(Method::PUT, "/api/v1/estimator", &big).await;
        assert_eq!(r.status, StatusCode::PAYLOAD_TOO_LARGE);
        assert_eq!(r.error(), "request bodies are limited to 65536 bytes");
        assert_eq!(app.refused("too_large", 413), 1);
        let r = app
            .call(request(Method::DELETE, "/api/v1/assignments/1", None, None))
            .await;
        assert_eq!(r.status, StatusCode::UNAUTHORIZED);
        let stats = || {
            app.state
                .recording
                .recorder
                .as_ref()
                .expect("recording")
                .stats()
        };
        tokio::time::timeout(super::testing::WAIT, async {
            while stats().actions < 2 {
                tokio::time::sleep(Duration::from_millis(10)).await;
            }
        })
        .await
        .expect("both actions recorded");
    }

    #[tokio::test]
    async fn the_openapi_document_lists_every_route_with_the_bearer_scheme() {
        let doc = TestApp::new().get("/api/openapi.json").await.json();
        let mut paths: Vec<&str> = doc["paths"]
            .as_object()
            .expect("paths")
            .keys()
            .map(String::as_str)
            .collect();
        paths.sort_unstable();
        let v1 = [
            "aircraft",
            "assignments",
            "assignments/{id}",
            "assignments/{id}/vehicles/{vehicle}/resume",
            "biases",
            "detections",
            "estimator",
            "estimators",
            "health",
            "map",
            "metrics",
            "sessions",
            "sessions/{id}",
            "sessions/{id}/export",
            "tracks",
            "tracks/{id}",
            "truth",
            "vehicles",
            "vehicles/{id}",
            "vehicles/{id}/commands",
            "vehicles/{id}/accept",
            "world",
            "ws",
        ];
        let mut want: Vec<String> = v1.iter().map(|p| format!("/api/v1/{p}")).collect();
        want.push("/metrics".into());
        want.push("/tiles/{z}/{x}/{y}".into());
        want.sort_unstable();
        assert_eq!(paths, want);
        assert_eq!(doc["info"]["title"], "Harrier ground station API");
        assert_eq!(
            doc["components"]["securitySchemes"]["bearer"]["scheme"],
            "bearer"
        );
        for schema in [
            "ErrorBody",
            "TracksBody",
            "VehicleEntry",
            "AssignmentView",
            "WorldBody",
            "AircraftList",
            "MapBody",
            "TileSource",
        ] {
            assert!(doc["components"]["schemas"][schema].is_object(), "{schema}");
        }
        assert_eq!(doc["tags"].as_array().map(Vec::len), Some(7));
    }

    /// Every fixed set of values that leaves the server is an enum component with its values,
    /// referenced by the schemas that carry it, so that a client generates an enum type.
    #[tokio::test]
    async fn the_statuses_are_enum_components_referenced_where_they_are_sent() {
        let doc = TestApp::new().get("/api/openapi.json").await.json();
        let schemas = &doc["components"]["schemas"];
        let enums: [(&str, &[&str]); 12] = [
            ("TrackStatus", &["tentative", "confirmed"]),
            (
                "DeleteCause",
                &["misses", "covariance", "unconfirmed", "failed"],
            ),
            (
                "SlotState",
                &[
                    "waiting",
                    "arming",
                    "taking_off",
                    "offboard",
                    "handed_off",
                    "lost",
                    "failed",
                    "overridden",
                    "hold",
                ],
            ),
            ("VehicleAutopilot", &["px4", "ardupilot"]),
            ("VehicleAirframe", &["multirotor", "fixed_wing"]),
            ("AssignmentState", &["active", "ended"]),
            (
                "Law",
                &[
                    "togvf",
                    "lgvf",
                    "formation",
                    "handoff_orbit",
                    "handoff_follow",
                    "handoff_camera",
                ],
            ),
            ("OrbitDirection", &["ccw", "cw"]),
            (
                "LinkEventKind",
                &[
                    "connected",
                    "lost",
                    "recovered",
                    "mode",
                    "armed",
                    "disarmed",
                    "conflict",
                    "moved",
                    "accepted",
                ],
            ),
            ("HealthStatus", &["ok"]),
            (
                "MeasKind",
                &["position", "range_bearing", "az_el", "bearing_size"],
            ),
            ("LinkState", &["connected", "lost"]),
        ];
        for (name, values) in enums {
            assert_eq!(schemas[name]["type"], "string", "{name}: {}", schemas[name]);
            assert_eq!(schemas[name]["enum"], serde_json::json!(values), "{name}");
        }
        let results = schemas["CommandResult"]["enum"]
            .as_array()
            .expect("results");
        for r in ["accepted", "denied", "temporarily_rejected", "timeout"] {
            assert!(results.iter().any(|v| v == r), "{r}");
        }
        let refers = |schema: &str, field: &str, to: &str| {
            let text = schemas[schema]["properties"][field].to_string();
            assert!(
                text.contains(&format!("\"#/components/schemas/{to}\"")),
                "{schema}.{field}: {text}"
            );
        };
        refers("TrackDto", "status", "TrackStatus");
        refers("AssignmentView", "state", "AssignmentState");
        refers("AssignmentView", "law", "Law");
        refers("AssignmentView", "orbit", "OrbitDirection");
        refers("SlotView", "state", "SlotState");
        refers("AssignmentRequest", "law", "Law");
        refers("AssignmentRequest", "orbit", "OrbitDirection");
        refers("CommandOutcome", "result", "CommandResult");
        refers("LinkEvent", "event", "LinkEventKind");
        refers("HealthBody", "status", "HealthStatus");
        refers("ScanMessage", "kind", "MeasKind");
        refers("ScanView", "kind", "MeasKind");
        refers("VehicleLinkView", "system_status", "SystemStatus");
        refers("VehicleLinkView", "autopilot", "VehicleAutopilot");
        refers("VehicleLinkView", "airframe", "VehicleAirframe");
        let states = schemas["SystemStatus"]["enum"]
            .as_array()
            .expect("MAV_STATEs");
        assert!(states.iter().any(|v| v == "MAV_STATE_ACTIVE"), "{states:?}");
    }
}
