//! `GET /estimator`, `PUT /estimator`, `GET /estimators`: the track filter and the associator the
//! tracker runs, changing them at run time (the live tracks are handed over), and the ones it
//! can run.

use std::collections::BTreeMap;

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use tokio::sync::oneshot;
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::AppJson;
use super::state::{ApiState, Tracking};
use crate::tracker::{Command, TrackFilterState};
use harrier_engine::registry::{ASSOCIATORS, TRACK_FILTERS};

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/estimator", get(get_estimator).put(put_estimator))
        .route("/estimators", get(estimators))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(get_estimator, put_estimator, estimators))]
pub(super) struct Doc;

/// The running estimator.
#[utoipa::path(get, path = "/api/v1/estimator", tag = "control",
    responses(
        (status = 200, body = TrackFilterState),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn get_estimator(State(s): State<Tracking>) -> Json<TrackFilterState> {
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
    /// Associator name (`GET /api/v1/estimators`); absent: the running one.
    #[serde(default)]
    #[schema(schema_with = associator_names)]
    pub associator: Option<String>,
}

/// The schema of an estimator name: one of [`TRACK_FILTERS`].
fn estimator_names() -> utoipa::openapi::Object {
    utoipa::openapi::ObjectBuilder::new()
        .schema_type(utoipa::openapi::schema::Type::String)
        .enum_values(Some(TRACK_FILTERS.iter().map(|e| e.name)))
        .description(Some("Track estimator name (`GET /api/v1/estimators`)"))
        .build()
}

/// The schema of an associator name: one of [`ASSOCIATORS`].
fn associator_names() -> utoipa::openapi::Object {
    utoipa::openapi::ObjectBuilder::new()
        .schema_type(utoipa::openapi::schema::Type::String)
        .enum_values(Some(ASSOCIATORS.iter().map(|a| a.name)))
        .description(Some(
            "Associator name (`GET /api/v1/estimators`); absent: the running one",
        ))
        .build()
}

/// Changes the track filter and, when given, the associator; the live tracks are handed over
/// (ids, status, estimates and existence kept).
#[utoipa::path(put, path = "/api/v1/estimator", tag = "control", request_body = EstimatorChange,
    responses(
        (status = 200, description = "Now running", body = TrackFilterState),
        (status = 400, description = "The body is not JSON", body = ErrorBody),
        (status = 401, description = "No or a wrong token", body = ErrorBody),
        (status = 409, description = "The tracks cannot be handed over to this estimator", body = ErrorBody),
        (status = 415, description = "Not `Content-Type: application/json`", body = ErrorBody),
        (status = 422, description = "Unknown estimator or parameter, or a field of the wrong type", body = ErrorBody),
        (status = 503, description = "The tracker is not running", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn put_estimator(
    State(s): State<Tracking>,
    AppJson(change): AppJson<EstimatorChange>,
) -> Result<Json<TrackFilterState>, ApiError> {
    let gone = || ApiError::unavailable("stopped", "the tracker is not running");
    let (reply, answer) = oneshot::channel();
    let associator = change
        .associator
        .unwrap_or_else(|| s.snapshot.borrow().estimator.associator.clone());
    let to = TrackFilterState {
        name: change.name,
        associator,
        params: change.params,
    };
    s.commands
        .send(Command::SetEstimator { to, reply })
        .await
        .map_err(|_| gone())?;
    let now = answer.await.map_err(|_| gone())??;
    Ok(Json(now))
}

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
    /// Every associator (any runs with any track estimator).
    associators: Vec<EstimatorInfoBody>,
}

/// The body of a named entry of the registry.
fn info_body(
    name: &'static str,
    summary: &'static str,
    params: &'static [(&'static str, &'static str)],
) -> EstimatorInfoBody {
    EstimatorInfoBody {
        name,
        summary,
        params: params
            .iter()
            .map(|&(name, description)| ParamInfo { name, description })
            .collect(),
    }
}

/// The track estimators and the associators that can run live.
#[utoipa::path(get, path = "/api/v1/estimators", tag = "control",
    responses(
        (status = 200, body = EstimatorsBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn estimators() -> Json<EstimatorsBody> {
    Json(EstimatorsBody {
        estimators: TRACK_FILTERS
            .iter()
            .map(|e| info_body(e.name, e.summary, e.params))
            .collect(),
        associators: ASSOCIATORS
            .iter()
            .map(|a| info_body(a.name, a.summary, a.params))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use axum::http::{Method, StatusCode};

    use super::super::testing::{TOKEN, TestApp, request};

    #[tokio::test]
    async fn the_estimator_is_read_listed_and_changed() {
        let app = TestApp::new();
        let r = app.get("/api/v1/estimator").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(
            r.json(),
            serde_json::json!({"name": "ekf", "associator": "gnn", "params": {}})
        );
        let list = app.get("/api/v1/estimators").await.json();
        let names: Vec<&str> = list["estimators"]
            .as_array()
            .expect("estimators")
            .iter()
            .filter_map(|e| e["name"].as_str())
            .collect();
        assert!(
            names.contains(&"ekf") && names.contains(&"cdkf"),
            "{names:?}"
        );
        let r = app
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"cdkf"}"#)
            .await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.json()["name"], "cdkf");
        assert_eq!(app.get("/api/v1/estimator").await.json()["name"], "cdkf");
        // The associators are listed, and one is chosen with its parameters; the next change
        // without one keeps it.
        let associators: Vec<&str> = list["associators"]
            .as_array()
            .expect("associators")
            .iter()
            .filter_map(|e| e["name"].as_str())
            .collect();
        assert_eq!(associators, ["gnn", "jipda", "mht"]);
        let r = app
            .send(
                Method::PUT,
                "/api/v1/estimator",
                r#"{"name":"ekf","associator":"jipda","params":{"pd":0.8}}"#,
            )
            .await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(
            r.json(),
            serde_json::json!({"name": "ekf", "associator": "jipda", "params": {"pd": 0.8}})
        );
        let r = app
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"imm"}"#)
            .await;
        assert_eq!(r.json()["associator"], "jipda");
        let r = app
            .send(
                Method::PUT,
                "/api/v1/estimator",
                r#"{"name":"imm","associator":"nope"}"#,
            )
            .await;
        assert_eq!(r.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(
            r.error().contains("unknown associator \"nope\""),
            "{}",
            r.error()
        );
        assert_eq!(
            app.get("/api/v1/estimator").await.json()["associator"],
            "jipda"
        );
    }

    #[tokio::test]
    async fn an_unknown_estimator_a_wrong_shape_or_type_and_a_stopped_tracker_are_refused() {
        let app = TestApp::new();
        let r = app
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"nope"}"#)
            .await;
        assert_eq!(r.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(r.error().starts_with("unknown track filter \"nope\""));
        assert_eq!(app.refused("estimator", 422), 1);
        let r = app
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"ekf","x":1}"#)
            .await;
        assert_eq!(r.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(r.error().contains("unknown field `x`"));
        assert_eq!(app.refused("json", 422), 1);
        let plain = request(Method::PUT, "/api/v1/estimator", Some(TOKEN), None);
        let r = app.call(plain).await;
        assert_eq!(r.status, StatusCode::UNSUPPORTED_MEDIA_TYPE);
        assert_eq!(app.refused("json", 415), 1);

        // A tracker that has stopped: 503, and counted (it was not before).
        let mut stopped = TestApp::new();
        stopped.state.tracking.commands = tokio::sync::mpsc::channel(1).0;
        let r = stopped
            .send(Method::PUT, "/api/v1/estimator", r#"{"name":"cdkf"}"#)
            .await;
        assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(r.error(), "the tracker is not running");
        assert_eq!(stopped.refused("stopped", 503), 1);
    }
}
