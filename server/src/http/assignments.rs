//! `GET`/`POST /assignments`, `GET`/`DELETE /assignments/{id}`: vehicles tied to a track by a
//! guidance law, through the guidance actor.

use axum::extract::State;
use axum::http::StatusCode;
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::Serialize;
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::{AppJson, AppPath};
use super::state::{ApiState, Control};
use crate::guidance::{AssignmentRequest, AssignmentView, Guidance};

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/assignments", get(assignments).post(create_assignment))
        .route("/assignments/{id}", get(assignment).delete(end_assignment))
        .route(
            "/assignments/{id}/vehicles/{vehicle}/resume",
            post(resume_vehicle),
        )
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(
    assignments,
    create_assignment,
    assignment,
    end_assignment,
    resume_vehicle
))]
pub(super) struct Doc;

/// The assignments.
#[derive(Debug, Serialize, ToSchema)]
pub struct AssignmentList {
    /// Active and ended, by id.
    pub assignments: Vec<AssignmentView>,
}

/// The guidance, or 503 when it does not run.
fn guidance(c: &Control) -> Result<&Guidance, ApiError> {
    c.guidance
        .as_ref()
        .ok_or_else(|| ApiError::unavailable("no_link", "no guidance: set mavlink.gcs"))
}

/// Every assignment, active and ended.
#[utoipa::path(get, path = "/api/v1/assignments", tag = "guidance",
    responses(
        (status = 200, body = AssignmentList),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn assignments(State(c): State<Control>) -> Json<AssignmentList> {
    Json(AssignmentList {
        assignments: c
            .guidance
            .as_ref()
            .map(|g| g.assignments.borrow().to_vec())
            .unwrap_or_default(),
    })
}

/// Ties vehicles to a track with a law (standoff or formation).
#[utoipa::path(post, path = "/api/v1/assignments", tag = "guidance",
    request_body = AssignmentRequest,
    responses(
        (status = 201, description = "Created; the vehicles launch and fly it", body = AssignmentView),
        (status = 400, description = "Malformed JSON", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such vehicle or track", body = ErrorBody),
        (status = 409, description = "A vehicle already flies another assignment", body = ErrorBody),
        (status = 415, description = "Not JSON", body = ErrorBody),
        (status = 422, description = "A parameter is out of range", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn create_assignment(
    State(c): State<Control>,
    AppJson(req): AppJson<AssignmentRequest>,
) -> Result<(StatusCode, Json<AssignmentView>), ApiError> {
    let created = guidance(&c)?.create(req).await?;
    Ok((StatusCode::CREATED, Json(created)))
}

/// One assignment.
#[utoipa::path(get, path = "/api/v1/assignments/{id}", tag = "guidance",
    params(("id" = u64, Path, description = "Assignment id")),
    responses(
        (status = 200, body = AssignmentView),
        (status = 400, description = "Not an id", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
        (status = 404, description = "No such assignment", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn assignment(
    State(c): State<Control>,
    AppPath(id): AppPath<u64>,
) -> Result<Json<AssignmentView>, ApiError> {
    c.guidance
        .as_ref()
        .and_then(|g| g.assignments.borrow().iter().find(|a| a.id == id).cloned())
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("no assignment {id}")))
}

/// Ends an assignment: its vehicles go to Hold.
#[utoipa::path(delete, path = "/api/v1/assignments/{id}", tag = "guidance",
    params(("id" = u64, Path, description = "Assignment id")),
    responses(
        (status = 200, description = "Ended (or already ended)", body = AssignmentView),
        (status = 400, description = "Not an id", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such assignment", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn end_assignment(
    State(c): State<Control>,
    AppPath(id): AppPath<u64>,
) -> Result<Json<AssignmentView>, ApiError> {
    guidance(&c)?
        .end(id)
        .await?
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("no assignment {id}")))
}

/// The operator takes a vehicle back into its slot (it was `overridden`: someone else took it,
/// or `failed`): the guidance flies it again from its launch, and the ring re-spaces.
#[utoipa::path(post, path = "/api/v1/assignments/{id}/vehicles/{vehicle}/resume", tag = "guidance",
    params(
        ("id" = u64, Path, description = "Assignment id"),
        ("vehicle" = u8, Path, description = "MAVLink system id of a vehicle of the assignment"),
    ),
    responses(
        (status = 200, description = "Back in its slot (`waiting`, then its launch)", body = AssignmentView),
        (status = 400, description = "Not an id", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such assignment, or the vehicle is not in it", body = ErrorBody),
        (status = 409, description = "The assignment ended, the vehicle is in its slot already, or it flies another assignment", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn resume_vehicle(
    State(c): State<Control>,
    AppPath((id, vehicle)): AppPath<(u64, u8)>,
) -> Result<Json<AssignmentView>, ApiError> {
    Ok(Json(guidance(&c)?.resume(id, vehicle).await?))
}

#[cfg(test)]
mod tests {
    use axum::http::{Method, StatusCode};

    use super::super::testing::TestApp;
    use crate::guidance::{AssignError, GuidanceRequest};

    const REQUEST: &str = r#"{"vehicles":[1,2],"track":7,"law":"togvf"}"#;

    #[tokio::test]
    async fn the_assignments_are_listed_and_the_guidance_answers_for_them() {
        let (app, mut guidance) = TestApp::new().with_guidance();
        tokio::spawn(async move {
            while let Some(r) = guidance.recv().await {
                match r {
                    GuidanceRequest::Create(req, reply) => {
                        let m = format!("vehicle {} flies another assignment", req.vehicles[0]);
                        let _ = reply.send(Err(AssignError::Conflict(m)));
                    }
                    GuidanceRequest::End(_, reply) => {
                        let _ = reply.send(None);
                    }
                    GuidanceRequest::Resume(id, vehicle, reply) => {
                        let m = format!("vehicle {vehicle} is in its slot of assignment {id}");
                        let _ = reply.send(Err(AssignError::Conflict(m)));
                    }
                    GuidanceRequest::Release(_, _, reply) => {
                        let _ = reply.send(None);
                    }
                }
            }
        });
        let r = app.get("/api/v1/assignments").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.json(), serde_json::json!({"assignments": []}));
        let r = app.send(Method::POST, "/api/v1/assignments", REQUEST).await;
        assert_eq!(r.status, StatusCode::CONFLICT);
        assert_eq!(r.error(), "vehicle 1 flies another assignment");
        assert_eq!(app.refused("conflict", 409), 1);
        let r = app.send(Method::DELETE, "/api/v1/assignments/5", "").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(r.error(), "no assignment 5");
        let r = app.get("/api/v1/assignments/5").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(app.refused("not_found", 404), 2);
        let r = app
            .send(Method::POST, "/api/v1/assignments/3/vehicles/2/resume", "")
            .await;
        assert_eq!(r.status, StatusCode::CONFLICT);
        assert_eq!(r.error(), "vehicle 2 is in its slot of assignment 3");
        let r = app
            .send(
                Method::POST,
                "/api/v1/assignments/3/vehicles/256/resume",
                "",
            )
            .await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
    }

    #[tokio::test]
    async fn without_guidance_or_with_a_bad_body_or_id_an_assignment_is_refused() {
        let app = TestApp::new();
        let r = app.send(Method::POST, "/api/v1/assignments", REQUEST).await;
        assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(r.error(), "no guidance: set mavlink.gcs");
        let r = app.send(Method::POST, "/api/v1/assignments", "{}").await;
        assert_eq!(r.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(r.error().contains("missing field `vehicles`"));
        assert_eq!(
            app.get("/api/v1/assignments/x").await.status,
            StatusCode::BAD_REQUEST
        );
        assert_eq!(app.refused("no_link", 503), 1);
        assert_eq!(app.refused("json", 422), 1);
        assert_eq!(app.refused("path", 400), 1);
        // A guidance that has stopped: 503, and counted (it was not before).
        let (app, guidance) = TestApp::new().with_guidance();
        drop(guidance);
        let r = app.send(Method::DELETE, "/api/v1/assignments/5", "").await;
        assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(app.refused("no_link", 503), 1);
    }
}
