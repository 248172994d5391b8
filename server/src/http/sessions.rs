//! `GET /sessions`, `GET /sessions/{id}`, `GET /sessions/{id}/export`: the sessions of this
//! server's recording file ([`harrier_recording`]'s reader and export read it).

use std::path::Path;

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::AppPath;
use super::state::{ApiState, Recording};
use harrier_recording::export::{Exported, export};
use harrier_recording::reader::{self, SessionError, SessionInfo};

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/sessions", get(list_sessions))
        .route("/sessions/{id}", get(session))
        .route("/sessions/{id}/export", get(export_session))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(list_sessions, session, export_session))]
pub(super) struct Doc;

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

/// Runs a read of the recording file off the async threads.
async fn with_file<T: Send + 'static>(
    r: &Recording,
    read: impl FnOnce(&Path) -> Result<T, SessionError> + Send + 'static,
) -> Result<T, ApiError> {
    let recorder = r
        .recorder
        .as_ref()
        .ok_or_else(|| ApiError::not_found("recording is off (set recorder.path or --record)"))?;
    let path = recorder.path().to_path_buf();
    let v = tokio::task::spawn_blocking(move || read(&path))
        .await
        .map_err(|e| ApiError::Internal(e.to_string()))??;
    Ok(v)
}

/// A session id from the path.
fn session_id(id: &str) -> Result<i64, ApiError> {
    id.parse()
        .map_err(|_| ApiError::bad_request("path", format!("session id {id:?} is not a number")))
}

/// The recorded sessions (this server's recording file).
#[utoipa::path(get, path = "/api/v1/sessions", tag = "sessions",
    responses(
        (status = 200, body = SessionsBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn list_sessions(State(r): State<Recording>) -> Result<Json<SessionsBody>, ApiError> {
    let Some(recorder) = &r.recorder else {
        return Ok(Json(SessionsBody {
            file: None,
            current: None,
            sessions: Vec::new(),
        }));
    };
    let file = recorder.path().display().to_string();
    let current = recorder.session_id();
    Ok(Json(SessionsBody {
        file: Some(file),
        current: Some(current),
        sessions: with_file(&r, reader::list).await?,
    }))
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
async fn session(
    State(r): State<Recording>,
    AppPath(id): AppPath<String>,
) -> Result<Json<SessionInfo>, ApiError> {
    let id = session_id(&id)?;
    Ok(Json(with_file(&r, move |p| reader::info(p, id)).await?))
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
async fn export_session(
    State(r): State<Recording>,
    AppPath(id): AppPath<String>,
) -> Result<Json<Exported>, ApiError> {
    let id = session_id(&id)?;
    Ok(Json(with_file(&r, move |p| export(p, id)).await?))
}

#[cfg(test)]
mod tests {
    use axum::http::StatusCode;

    use super::super::testing::TestApp;

    #[tokio::test]
    async fn the_sessions_of_the_recording_file() {
        let dir = tempfile::tempdir().expect("a temporary directory");
        let app = TestApp::new().with_recording(dir.path());
        let list = app.get("/api/v1/sessions").await;
        assert_eq!(list.status, StatusCode::OK);
        let list = list.json();
        let current = list["current"].as_i64().expect("this server's session");
        assert!(
            list["file"]
                .as_str()
                .is_some_and(|f| f.ends_with("session.sqlite"))
        );
        assert_eq!(list["sessions"][0]["id"], current);
        let one = app.get(&format!("/api/v1/sessions/{current}")).await;
        assert_eq!(one.status, StatusCode::OK);
        assert_eq!(one.json()["estimator"], "ekf");
        // Nothing to export yet.
        let r = app.get(&format!("/api/v1/sessions/{current}/export")).await;
        assert_eq!(r.status, StatusCode::CONFLICT);
        assert!(
            r.error().ends_with("cannot export: it has no scans"),
            "{}",
            r.error()
        );
        assert_eq!(app.refused("export", 409), 1);
        let r = app.get("/api/v1/sessions/99").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert!(r.error().ends_with("no session 99"));
        let r = app.get("/api/v1/sessions/x/export").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(r.error(), "session id \"x\" is not a number");
        assert_eq!(
            (app.refused("not_found", 404), app.refused("path", 400)),
            (1, 1)
        );
    }

    #[tokio::test]
    async fn without_recording_there_is_no_session() {
        let app = TestApp::new();
        let list = app.get("/api/v1/sessions").await;
        assert_eq!(list.status, StatusCode::OK);
        assert_eq!(
            list.json(),
            serde_json::json!({"file": null, "current": null, "sessions": []})
        );
        let r = app.get("/api/v1/sessions/1").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(
            r.error(),
            "recording is off (set recorder.path or --record)"
        );
        assert_eq!(app.refused("not_found", 404), 1);
    }
}
