//! `GET /health`, `GET /metrics` (Prometheus text; also at the root, `GET /metrics`, where
//! scrapers look by default).

use std::sync::Arc;

use axum::extract::State;
use axum::http::header;
use axum::response::IntoResponse;
use axum::routing::get;
use axum::{Json, Router};
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::error::ErrorBody;
use super::state::{ApiState, Control, Recording, Service, Tracking};
use crate::guidance::AssignmentState;
use crate::map::MapService;
use crate::prom::Family;

/// The routes of this file under `/api/v1`.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/health", get(health))
        .route("/metrics", get(metrics))
}

/// The route of this file at the root: `/metrics`.
pub(super) fn root_routes() -> Router<ApiState> {
    Router::new().route("/metrics", get(root_metrics))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(health, metrics, root_metrics))]
pub(super) struct Doc;

/// The service's state, as `GET /health` reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum HealthStatus {
    /// Serving (the only state it answers in; a service that cannot serve does not answer).
    Ok,
}

/// Service health.
#[derive(Debug, Serialize, ToSchema)]
pub struct HealthBody {
    /// `ok`.
    status: HealthStatus,
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
async fn health(
    State(s): State<Service>,
    State(t): State<Tracking>,
    State(r): State<Recording>,
) -> Json<HealthBody> {
    Json(HealthBody {
        status: HealthStatus::Ok,
        uptime_s: s.started.elapsed().as_secs_f64(),
        estimator: t.snapshot.borrow().estimator.name.clone(),
        last_scan_t: s.metrics.last_scan_t(),
        scans_ingested: s.metrics.scans_ingested(),
        recording_error: r.error.as_deref().map(str::to_owned),
    })
}

/// Prometheus metrics.
#[utoipa::path(get, path = "/api/v1/metrics", tag = "service",
    responses(
        (status = 200, description = "Prometheus text exposition format 0.0.4", content_type = "text/plain", body = String),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn metrics(
    State(s): State<Service>,
    State(r): State<Recording>,
    State(c): State<Control>,
    State(m): State<Arc<MapService>>,
) -> impl IntoResponse {
    let mut text = s.metrics.render(s.started.elapsed().as_secs_f64());
    s.connections.render(&mut text);
    s.feeds.render(&mut text);
    m.render_metrics(&mut text);
    if let Some(recorder) = &r.recorder {
        crate::metrics::render_recorder(&recorder.stats(), &mut text);
    }
    if r.recorder.is_some() || r.error.is_some() {
        Family::gauge(
            &mut text,
            "harrier_recorder_up",
            "1: recording; 0: recorder.path is set but the file could not be opened (see \
             /api/v1/health).",
        )
        .value(u8::from(r.recorder.is_some()));
    }
    if let Some(l) = &c.link {
        l.render_metrics(&mut text);
    }
    if let Some(g) = &c.guidance {
        let active = g
            .assignments
            .borrow()
            .iter()
            .filter(|a| a.state == AssignmentState::Active)
            .count();
        g.metrics.render(active, &mut text);
    }
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text)
}

/// Prometheus metrics at the conventional path: the same text, and the same access rule, as
/// `GET /api/v1/metrics`.
#[utoipa::path(get, path = "/metrics", tag = "service",
    responses(
        (status = 200, description = "Prometheus text exposition format 0.0.4", content_type = "text/plain", body = String),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn root_metrics(
    s: State<Service>,
    r: State<Recording>,
    c: State<Control>,
    m: State<Arc<MapService>>,
) -> impl IntoResponse {
    metrics(s, r, c, m).await
}

#[cfg(test)]
mod tests {
    use axum::http::{StatusCode, header};

    use super::super::testing::TestApp;

    /// The Prometheus text without the uptime, which moves between two reads.
    fn without_uptime(body: &[u8]) -> String {
        String::from_utf8_lossy(body)
            .lines()
            .filter(|l| !l.starts_with("harrier_uptime_seconds "))
            .collect::<Vec<_>>()
            .join("\n")
    }

    #[tokio::test]
    async fn health_and_the_metrics_at_both_paths() {
        let app = TestApp::new();
        let h = app.get("/api/v1/health").await;
        assert_eq!(h.status, StatusCode::OK);
        let h = h.json();
        assert_eq!(
            (h["status"].as_str(), h["estimator"].as_str()),
            (Some("ok"), Some("ekf"))
        );
        assert!(h.get("recording_error").is_none());
        let m = app.get("/api/v1/metrics").await;
        assert_eq!(m.status, StatusCode::OK);
        assert_eq!(m.headers[header::CONTENT_TYPE], "text/plain; version=0.0.4");
        let root = app.get("/metrics").await;
        assert_eq!(root.status, StatusCode::OK);
        assert_eq!(
            root.headers[header::CONTENT_TYPE],
            "text/plain; version=0.0.4"
        );
        assert_eq!(without_uptime(&root.body), without_uptime(&m.body));
        assert!(without_uptime(&m.body).contains("# TYPE harrier_http_refused_total counter"));
    }

    #[tokio::test]
    async fn health_and_metrics_need_the_token_when_reads_do() {
        let app = TestApp::new().reads_need_token();
        for uri in ["/api/v1/health", "/api/v1/metrics", "/metrics"] {
            let r = app.get(uri).await;
            assert_eq!(r.status, StatusCode::UNAUTHORIZED, "{uri}");
            assert_eq!(r.headers[header::WWW_AUTHENTICATE], "Bearer");
        }
        assert_eq!(app.refused("auth_missing", 401), 3);
        let m = app.get_with_token("/metrics").await;
        let text = String::from_utf8_lossy(&m.body).into_owned();
        assert!(
            text.contains("harrier_http_refused_total{reason=\"auth_missing\",status=\"401\"} 3")
        );
    }
}
