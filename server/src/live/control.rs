//! The API routes of the vehicles and the guidance: vehicles (their MAVLink link and their
//! detections), commands with their COMMAND_ACK result, assignments, and the simulator's truth
//! and the configuration's world ([`super::world`]).

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::{JsonRejection, PathRejection};
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use harrier_link::command::{arm, disarm, land, set_mode, takeoff};
use harrier_link::mavlink::dialects::common::MavMessage;
use harrier_link::px4::FlightMode;
use serde::{Deserialize, Serialize};
use utoipa::ToSchema;

use super::api::{ApiState, ErrorBody, bad_json, error};
use super::gcs::vehicle::VehicleLinkView;
use super::gcs::{CommandError, CommandOutcome};
use super::guidance::{AssignError, AssignmentRequest, AssignmentView};
use super::tracker::VehicleView;
use super::world::{TruthBody, WorldBody};

/// A vehicle: its MAVLink link (when the GCS link hears it) and its detections (when it
/// publishes any), joined on the system id.
#[derive(Debug, Clone, Serialize, ToSchema)]
pub struct VehicleEntry {
    /// MAVLink system id (the `{id}` of `harrier/v1/vehicle/{id}/detections`).
    pub id: u8,
    /// Telemetry and link state; `null` when the GCS link has not heard it.
    pub link: Option<VehicleLinkView>,
    /// Its detections; `null` when none was processed.
    pub detections: Option<VehicleView>,
}

/// The vehicles.
#[derive(Debug, Serialize, ToSchema)]
pub struct VehicleList {
    /// By system id.
    pub vehicles: Vec<VehicleEntry>,
}

/// Every vehicle, from both sources.
pub fn vehicle_entries(s: &ApiState) -> Vec<VehicleEntry> {
    let mut out: std::collections::BTreeMap<u8, VehicleEntry> = Default::default();
    if let Some(link) = &s.link {
        for v in link.vehicles.borrow().iter() {
            out.insert(
                v.view.id,
                VehicleEntry {
                    id: v.view.id,
                    link: Some(v.view.clone()),
                    detections: None,
                },
            );
        }
    }
    let snap = Arc::clone(&s.snapshot.borrow());
    for d in snap.vehicles.iter() {
        let Ok(id) = d.vehicle.parse::<u8>() else {
            continue;
        };
        out.entry(id)
            .or_insert_with(|| VehicleEntry {
                id,
                link: None,
                detections: None,
            })
            .detections = Some(d.clone());
    }
    out.into_values().collect()
}

/// The vehicles.
#[utoipa::path(get, path = "/api/v1/vehicles", tag = "vehicles",
    responses(
        (status = 200, body = VehicleList),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
pub async fn vehicles(State(s): State<ApiState>) -> Json<VehicleList> {
    Json(VehicleList {
        vehicles: vehicle_entries(&s),
    })
}

fn bad_path(s: &ApiState, e: &PathRejection) -> Response {
    s.metrics.http_refused("path", 400);
    error(StatusCode::BAD_REQUEST, e.body_text())
}

/// One vehicle.
#[utoipa::path(get, path = "/api/v1/vehicles/{id}", tag = "vehicles",
    params(("id" = u8, Path, description = "MAVLink system id")),
    responses(
        (status = 200, body = VehicleEntry),
        (status = 400, description = "Not a system id", body = ErrorBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
        (status = 404, description = "No such vehicle", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
pub async fn vehicle(State(s): State<ApiState>, id: Result<Path<u8>, PathRejection>) -> Response {
    let id = match id {
        Ok(Path(id)) => id,
        Err(e) => return bad_path(&s, &e),
    };
    match vehicle_entries(&s).into_iter().find(|v| v.id == id) {
        Some(v) => Json(v).into_response(),
        None => {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, format!("no vehicle {id}"))
        }
    }
}

/// A command to a vehicle.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CommandRequest {
    /// `arm`, `disarm`, `takeoff`, `land`, `hold` or `set_mode`.
    #[schema(pattern = "^(arm|disarm|takeoff|land|hold|set_mode)$")]
    pub command: String,
    /// `takeoff`: height above home (m); default: the vehicle's own takeoff altitude.
    #[serde(default)]
    pub altitude_m: Option<f64>,
    /// `set_mode`: `hold`, `position`, `offboard`, `takeoff` or `land`.
    #[serde(default)]
    pub mode: Option<String>,
    /// `disarm`: force it in flight.
    #[serde(default)]
    pub force: Option<bool>,
}

impl CommandRequest {
    /// The COMMAND_LONG for vehicle `id` (`home`: its home altitude AMSL, when known), or an
    /// error naming the bad field.
    pub fn message(&self, id: u8, home: Option<f64>) -> Result<MavMessage, String> {
        Ok(match self.command.as_str() {
            "arm" => arm(id),
            "disarm" => disarm(id, self.force.unwrap_or(false)),
            "land" => land(id),
            "hold" => set_mode(id, FlightMode::Hold),
            "takeoff" => {
                let amsl = match (self.altitude_m, home) {
                    (None, _) => None,
                    (Some(h), Some(home)) if h.is_finite() && h > 0.0 && h <= 10_000.0 => {
                        Some((home + h) as f32)
                    }
                    (Some(h), None) if h.is_finite() && h > 0.0 && h <= 10_000.0 => {
                        return Err(format!(
                            "vehicle {id}: home altitude unknown yet (no GLOBAL_POSITION_INT); omit altitude_m"
                        ));
                    }
                    (Some(h), _) => {
                        return Err(format!("altitude_m must be in (0, 10000], got {h}"));
                    }
                };
                takeoff(id, amsl)
            }
            "set_mode" => {
                let mode = match self.mode.as_deref() {
                    Some("hold") => FlightMode::Hold,
                    Some("position") => FlightMode::Position,
                    Some("offboard") => FlightMode::Offboard,
                    Some("takeoff") => FlightMode::Takeoff,
                    Some("land") => FlightMode::Land,
                    m => {
                        return Err(format!(
                            "mode {m:?}: expected hold, position, offboard, takeoff or land"
                        ));
                    }
                };
                set_mode(id, mode)
            }
            c => {
                return Err(format!(
                    "command {c:?}: expected arm, disarm, takeoff, land, hold or set_mode"
                ));
            }
        })
    }
}

/// Sends a command and answers with the vehicle's COMMAND_ACK.
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/commands", tag = "vehicles",
    params(("id" = u8, Path, description = "MAVLink system id")),
    request_body = CommandRequest,
    responses(
        (status = 200, description = "The vehicle answered (`ok` false: it refused; `result` says why)", body = CommandOutcome),
        (status = 400, description = "Malformed path or JSON", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such vehicle", body = ErrorBody),
        (status = 409, description = "The vehicle is lost, or the same command is waiting for its ACK", body = ErrorBody),
        (status = 415, description = "Not JSON", body = ErrorBody),
        (status = 422, description = "Unknown command or bad parameter", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
        (status = 504, description = "No acknowledgement after every attempt (`result` = `timeout`)", body = CommandOutcome),
    ),
    security(("bearer" = [])))]
pub async fn command(
    State(s): State<ApiState>,
    id: Result<Path<u8>, PathRejection>,
    body: Result<Json<CommandRequest>, JsonRejection>,
) -> Response {
    let id = match id {
        Ok(Path(id)) => id,
        Err(e) => return bad_path(&s, &e),
    };
    let Json(req) = match body {
        Ok(b) => b,
        Err(e) => return bad_json(&s, &e),
    };
    let Some(link) = &s.link else {
        s.metrics.http_refused("no_link", 503);
        return error(
            StatusCode::SERVICE_UNAVAILABLE,
            "no MAVLink link: set mavlink.gcs",
        );
    };
    let home = link
        .vehicles
        .borrow()
        .iter()
        .find(|v| v.view.id == id)
        .and_then(|v| v.home_amsl);
    let message = match req.message(id, home) {
        Ok(m) => m,
        Err(m) => {
            s.metrics.http_refused("invalid", 422);
            return error(StatusCode::UNPROCESSABLE_ENTITY, m);
        }
    };
    let outcome = link.command(id, message).await;
    if let (Some(r), Ok(o)) = (&s.recorder, &outcome) {
        r.record(super::recorder::Record::Vehicle {
            time_unix: super::clock::unix_now(),
            vehicle: Some(id),
            kind: "command",
            json: serde_json::to_string(o).unwrap_or_default(),
        });
    }
    match outcome {
        Ok(o) if o.result == "timeout" => (StatusCode::GATEWAY_TIMEOUT, Json(o)).into_response(),
        Ok(o) => Json(o).into_response(),
        Err(e @ CommandError::UnknownVehicle(_)) => {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, e.to_string())
        }
        Err(e @ (CommandError::Lost(..) | CommandError::Busy(..))) => {
            s.metrics.http_refused("conflict", 409);
            error(StatusCode::CONFLICT, e.to_string())
        }
        Err(e) => error(StatusCode::SERVICE_UNAVAILABLE, e.to_string()),
    }
}

/// The assignments.
#[derive(Debug, Serialize, ToSchema)]
pub struct AssignmentList {
    /// Active and ended, by id.
    pub assignments: Vec<AssignmentView>,
}

/// Every assignment, active and ended.
#[utoipa::path(get, path = "/api/v1/assignments", tag = "guidance",
    responses(
        (status = 200, body = AssignmentList),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
pub async fn assignments(State(s): State<ApiState>) -> Json<AssignmentList> {
    Json(AssignmentList {
        assignments: s
            .guidance
            .as_ref()
            .map(|g| g.assignments.borrow().to_vec())
            .unwrap_or_default(),
    })
}

fn no_guidance(s: &ApiState) -> Response {
    s.metrics.http_refused("no_link", 503);
    error(
        StatusCode::SERVICE_UNAVAILABLE,
        "no guidance: set mavlink.gcs",
    )
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
pub async fn create_assignment(
    State(s): State<ApiState>,
    body: Result<Json<AssignmentRequest>, JsonRejection>,
) -> Response {
    let Json(req) = match body {
        Ok(b) => b,
        Err(e) => return bad_json(&s, &e),
    };
    let Some(g) = &s.guidance else {
        return no_guidance(&s);
    };
    match g.create(req).await {
        Ok(v) => (StatusCode::CREATED, Json(v)).into_response(),
        Err(e) => {
            let (status, reason) = match e {
                AssignError::Invalid(_) => (StatusCode::UNPROCESSABLE_ENTITY, "invalid"),
                AssignError::NotFound(_) => (StatusCode::NOT_FOUND, "not_found"),
                AssignError::Conflict(_) => (StatusCode::CONFLICT, "conflict"),
                AssignError::Stopped => (StatusCode::SERVICE_UNAVAILABLE, "no_link"),
            };
            s.metrics.http_refused(reason, status.as_u16());
            error(status, e.to_string())
        }
    }
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
pub async fn assignment(
    State(s): State<ApiState>,
    id: Result<Path<u64>, PathRejection>,
) -> Response {
    let id = match id {
        Ok(Path(id)) => id,
        Err(e) => return bad_path(&s, &e),
    };
    let found = s
        .guidance
        .as_ref()
        .and_then(|g| g.assignments.borrow().iter().find(|a| a.id == id).cloned());
    match found {
        Some(a) => Json(a).into_response(),
        None => {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, format!("no assignment {id}"))
        }
    }
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
pub async fn end_assignment(
    State(s): State<ApiState>,
    id: Result<Path<u64>, PathRejection>,
) -> Response {
    let id = match id {
        Ok(Path(id)) => id,
        Err(e) => return bad_path(&s, &e),
    };
    let Some(g) = &s.guidance else {
        return no_guidance(&s);
    };
    match g.end(id).await {
        Ok(Some(a)) => Json(a).into_response(),
        Ok(None) => {
            s.metrics.http_refused("not_found", 404);
            error(StatusCode::NOT_FOUND, format!("no assignment {id}"))
        }
        Err(e) => error(StatusCode::SERVICE_UNAVAILABLE, e.to_string()),
    }
}

/// The latest simulation truth (`harrier/v1/sim/truth`), for drawing and for error figures.
#[utoipa::path(get, path = "/api/v1/truth", tag = "tracks",
    responses(
        (status = 200, body = TruthBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
pub async fn truth(State(s): State<ApiState>) -> Json<TruthBody> {
    Json((*s.truth.borrow()).as_ref().clone())
}

/// The static world: roads and obstacles of the configuration, for the map.
#[utoipa::path(get, path = "/api/v1/world", tag = "tracks",
    responses(
        (status = 200, body = WorldBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
pub async fn world(State(s): State<ApiState>) -> Json<WorldBody> {
    Json(s.world.as_ref().clone())
}
