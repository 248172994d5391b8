//! `GET /vehicles`, `GET /vehicles/{id}`, `POST /vehicles/{id}/commands`: the vehicles (their
//! MAVLink link and their detections) and commands with their COMMAND_ACK result.

use std::collections::BTreeMap;
use std::sync::Arc;

use axum::extract::State;
use axum::http::StatusCode;
use axum::routing::{get, post};
use axum::{Json, Router};
use harrier_link::ardupilot::PlaneMode;
use harrier_link::autopilot::{Autopilot, Frame, Mode, Personality};
use harrier_link::command::{arm, disarm, land, set_mode, takeoff, takeoff_relative};
use harrier_link::mavlink::dialects::common::MavMessage;
use harrier_link::offboard::DEFAULT_TAKEOFF_HEIGHT_M;
use harrier_link::px4::FlightMode;
use serde::{Deserialize, Serialize};
use utoipa::{OpenApi, ToSchema};

use super::error::{ApiError, ErrorBody};
use super::extract::{AppJson, AppPath};
use super::state::{ApiState, Control, Recording, Service, Tracking};
use crate::clock::unix_now;
use crate::gcs::{CommandOutcome, CommandResult};
use crate::metrics::{DropReason, Metrics};
use crate::wire::VehicleEntry;
use harrier_recording::writer::Record;

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/vehicles", get(vehicles))
        .route("/vehicles/{id}", get(vehicle))
        .route("/vehicles/{id}/commands", post(command))
        .route("/vehicles/{id}/accept", post(accept))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(vehicles, vehicle, command, accept))]
pub(super) struct Doc;

/// The MAVLink link, or 503 when it does not run.
fn link(c: &Control) -> Result<&crate::gcs::GcsLink, ApiError> {
    c.link
        .as_ref()
        .ok_or_else(|| ApiError::unavailable("no_link", "no MAVLink link: set mavlink.gcs"))
}

/// The vehicles.
#[derive(Debug, Serialize, ToSchema)]
pub struct VehicleList {
    /// By system id.
    pub vehicles: Vec<VehicleEntry>,
}

/// Every vehicle, from both sources, by system id.
pub(super) fn vehicle_entries(
    control: &Control,
    tracking: &Tracking,
    metrics: &Metrics,
) -> Vec<VehicleEntry> {
    let mut out: BTreeMap<u8, VehicleEntry> = BTreeMap::new();
    if let Some(link) = &control.link {
        for v in link.vehicles.borrow().iter() {
            let id = v.view.id;
            out.entry(id).or_insert_with(|| VehicleEntry::new(id)).link = Some(v.view.clone());
        }
    }
    let snap = Arc::clone(&tracking.snapshot.borrow());
    for d in snap.vehicles.iter() {
        // Scans are only taken from a key whose id is the payload's system id.
        let Ok(id) = d.vehicle.parse::<u8>() else {
            continue;
        };
        out.entry(id)
            .or_insert_with(|| VehicleEntry::new(id))
            .detections = Some((**d).clone());
    }
    for (label, estimate) in metrics.clocks() {
        let Ok(id) = label.parse::<u8>() else {
            continue;
        };
        let e = out.entry(id).or_insert_with(|| VehicleEntry::new(id));
        e.clock = Some(estimate);
        e.clock_refused = metrics
            .vehicle_counters(&label)
            .dropped
            .get(&DropReason::Clock)
            .copied()
            .unwrap_or(0);
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
async fn vehicles(
    State(c): State<Control>,
    State(t): State<Tracking>,
    State(s): State<Service>,
) -> Json<VehicleList> {
    Json(VehicleList {
        vehicles: vehicle_entries(&c, &t, &s.metrics),
    })
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
async fn vehicle(
    State(c): State<Control>,
    State(t): State<Tracking>,
    State(s): State<Service>,
    AppPath(id): AppPath<u8>,
) -> Result<Json<VehicleEntry>, ApiError> {
    vehicle_entries(&c, &t, &s.metrics)
        .into_iter()
        .find(|v| v.id == id)
        .map(Json)
        .ok_or_else(|| ApiError::not_found(format!("no vehicle {id}")))
}

/// A command to a vehicle.
#[derive(Debug, Deserialize, ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CommandRequest {
    /// `arm`, `disarm`, `takeoff`, `land`, `hold` or `set_mode`, each in the vehicle's autopilot's
    /// terms (docs/autopilots.md): `hold` is PX4 Hold, ArduPilot LOITER; `land` is PX4 and
    /// ArduCopter LAND, ArduPlane RTL; `takeoff` is PX4's NAV_TAKEOFF, ArduCopter's GUIDED then
    /// NAV_TAKEOFF (as MAVSDK does), ArduPlane's TAKEOFF mode.
    #[schema(pattern = "^(arm|disarm|takeoff|land|hold|set_mode)$")]
    pub command: String,
    /// `takeoff`: height above home (m); default: the vehicle's own (PX4 MIS_TAKEOFF_ALT,
    /// ArduPlane TKOFF_ALT, which it always climbs to; ArduCopter 2.5 m).
    #[serde(default)]
    pub altitude_m: Option<f64>,
    /// `set_mode`: `hold`, `position`, `offboard` (or `guided`: PX4 OFFBOARD, ArduPilot GUIDED),
    /// `takeoff` or `land`, or a mode of the vehicle's own table by its name (`CIRCLE`, `RTL`,
    /// `BRAKE`, …).
    #[serde(default)]
    pub mode: Option<String>,
    /// `disarm`: force it in flight.
    #[serde(default)]
    pub force: Option<bool>,
}

impl CommandRequest {
    /// The COMMAND_LONG for vehicle `id` of `personality` (`home`: its home altitude AMSL, when
    /// known), and the one to send once it is accepted (ArduCopter's takeoff after GUIDED), or an
    /// error naming the bad field.
    pub fn messages(
        &self,
        id: u8,
        home: Option<f64>,
        personality: Personality,
    ) -> Result<(MavMessage, Option<MavMessage>), String> {
        let (autopilot, frame) = (personality.autopilot, personality.frame);
        let one = |m: MavMessage| Ok((m, None));
        match self.command.as_str() {
            "arm" => one(arm(id)),
            "disarm" => one(disarm(id, self.force.unwrap_or(false))),
            "land" if frame == Frame::FixedWing && autopilot == Autopilot::ArduPilot => {
                one(set_mode(id, personality.land()))
            }
            "land" => one(land(id)),
            "hold" => one(set_mode(id, personality.hold())),
            "takeoff" => {
                let height = match self.altitude_m {
                    None => None,
                    Some(h) if h.is_finite() && h > 0.0 && h <= 10_000.0 => Some(h),
                    Some(h) => return Err(format!("altitude_m must be in (0, 10000], got {h}")),
                };
                match (autopilot, frame) {
                    (Autopilot::Px4, _) => {
                        let amsl = match (height, home) {
                            (None, _) => None,
                            (Some(h), Some(home)) => Some((home + h) as f32),
                            (Some(_), None) => {
                                return Err(format!(
                                    "vehicle {id}: home altitude unknown yet (no GLOBAL_POSITION_INT); omit altitude_m"
                                ));
                            }
                        };
                        one(takeoff(id, amsl))
                    }
                    (Autopilot::ArduPilot, Frame::Multirotor) => {
                        let h = height.map_or(DEFAULT_TAKEOFF_HEIGHT_M, |h| h as f32);
                        Ok((
                            set_mode(id, personality.guided()),
                            Some(takeoff_relative(id, h)),
                        ))
                    }
                    (Autopilot::ArduPilot, Frame::FixedWing) => {
                        one(set_mode(id, Mode::Plane(PlaneMode::Takeoff)))
                    }
                }
            }
            "set_mode" => {
                let name = self.mode.as_deref().unwrap_or("");
                let mode = match (name, autopilot, frame) {
                    ("hold", ..) => Some(personality.hold()),
                    ("offboard" | "guided", ..) => Some(personality.guided()),
                    ("land", ..) => Some(personality.land()),
                    ("position", Autopilot::Px4, _) => Some(Mode::Px4(FlightMode::Position)),
                    ("takeoff", Autopilot::Px4, _) => Some(Mode::Px4(FlightMode::Takeoff)),
                    ("takeoff", Autopilot::ArduPilot, Frame::FixedWing) => {
                        Some(Mode::Plane(PlaneMode::Takeoff))
                    }
                    (name, ..) => personality.mode_named(name),
                };
                match mode {
                    Some(m) => one(set_mode(id, m)),
                    None => Err(format!(
                        "mode {:?}: expected hold, position, offboard, guided, takeoff, land or one of this {} vehicle's modes",
                        self.mode,
                        personality.label()
                    )),
                }
            }
            c => Err(format!(
                "command {c:?}: expected arm, disarm, takeoff, land, hold or set_mode"
            )),
        }
    }
}

/// A command's outcome, and the assignment it took the vehicle out of.
#[derive(Debug, Serialize, ToSchema)]
pub struct CommandAnswer {
    /// The vehicle's answer.
    #[serde(flatten)]
    pub outcome: CommandOutcome,
    /// The assignment the vehicle flew, which the command took it out of first (its slot is
    /// `overridden`: the guidance commands it no more until the operator resumes it); `null`
    /// when it flew none (`arm` never takes a vehicle out).
    pub released_from_assignment: Option<u64>,
}

/// Sends a command and answers with the vehicle's COMMAND_ACK. Any command but `arm` to a
/// vehicle flying an assignment takes it out of its slot first (the operator wins over the
/// guidance; `released_from_assignment` says which).
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/commands", tag = "vehicles",
    params(("id" = u8, Path, description = "MAVLink system id")),
    request_body = CommandRequest,
    responses(
        (status = 200, description = "The vehicle answered (`ok` false: it refused; `result` says why)", body = CommandAnswer),
        (status = 400, description = "Malformed path or JSON", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such vehicle", body = ErrorBody),
        (status = 409, description = "The vehicle is lost, or the same command is waiting for its ACK", body = ErrorBody),
        (status = 415, description = "Not JSON", body = ErrorBody),
        (status = 422, description = "Unknown command or bad parameter", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
        (status = 504, description = "No acknowledgement after every attempt (`result` = `timeout`)", body = CommandAnswer),
    ),
    security(("bearer" = [])))]
async fn command(
    State(c): State<Control>,
    State(r): State<Recording>,
    AppPath(id): AppPath<u8>,
    AppJson(req): AppJson<CommandRequest>,
) -> Result<(StatusCode, Json<CommandAnswer>), ApiError> {
    let link = link(&c)?;
    let (home, personality) = link
        .vehicles
        .borrow()
        .iter()
        .find(|v| v.view.id == id)
        .map_or((None, Personality::PX4_MULTIROTOR), |v| {
            (
                v.home_amsl,
                v.status
                    .map_or(Personality::PX4_MULTIROTOR, |s| s.personality),
            )
        });
    let (first, then) =
        req.messages(id, home, personality)
            .map_err(|message| ApiError::Unprocessable {
                reason: "invalid",
                message,
            })?;
    // The operator wins: out of its slot before the command, so the guidance neither fights
    // it nor takes the change for someone else's.
    let released_from_assignment = match &c.guidance {
        Some(g) if req.command != "arm" => {
            let what = match &req.mode {
                Some(m) if req.command == "set_mode" => format!("set_mode {m} through the API"),
                _ => format!("{} through the API", req.command),
            };
            g.release(id, what).await?
        }
        _ => None,
    };
    let mut outcome = link.command(id, first).await?;
    if let Some(next) = then.filter(|_| outcome.ok) {
        outcome = link.command(id, next).await?;
    }
    if let Some(r) = &r.recorder {
        r.record(Record::Vehicle {
            time_unix: unix_now(),
            vehicle: Some(id),
            kind: "command",
            json: serde_json::to_string(&outcome).unwrap_or_default(),
        });
    }
    let status = if outcome.result == CommandResult::Timeout {
        StatusCode::GATEWAY_TIMEOUT
    } else {
        StatusCode::OK
    };
    Ok((
        status,
        Json(CommandAnswer {
            outcome,
            released_from_assignment,
        }),
    ))
}

/// The answer to an acceptance.
#[derive(Debug, Serialize, ToSchema)]
pub struct Accepted {
    /// The vehicle.
    pub vehicle: u8,
    /// `true`: its new address was accepted (the guidance may command it again); `false`: its
    /// address was confirmed already.
    pub accepted: bool,
}

/// The operator accepts a vehicle's new address: a vehicle that was lost and speaks again from
/// another address is not commanded by the guidance until then (`identity.state` =
/// `unconfirmed`).
#[utoipa::path(post, path = "/api/v1/vehicles/{id}/accept", tag = "vehicles",
    params(("id" = u8, Path, description = "MAVLink system id")),
    responses(
        (status = 200, description = "Accepted, or nothing to accept (`accepted` false)", body = Accepted),
        (status = 400, description = "Not a system id", body = ErrorBody),
        (status = 401, description = "Missing or wrong token", body = ErrorBody),
        (status = 404, description = "No such vehicle on the MAVLink link", body = ErrorBody),
        (status = 503, description = "No MAVLink link configured", body = ErrorBody),
    ),
    security(("bearer" = [])))]
async fn accept(
    State(c): State<Control>,
    AppPath(id): AppPath<u8>,
) -> Result<Json<Accepted>, ApiError> {
    let link = link(&c)?;
    let accepted = link.accept(id).await?;
    Ok(Json(Accepted {
        vehicle: id,
        accepted,
    }))
}

#[cfg(test)]
mod tests {
    use axum::http::{Method, StatusCode};

    use super::super::testing::TestApp;
    use super::*;
    use crate::gcs::{CommandOutcome, CommandResult, Request};

    #[tokio::test]
    async fn a_vehicle_seen_in_its_detections_has_the_one_vehicle_shape() {
        let app = TestApp::new();
        assert_eq!(
            app.get("/api/v1/vehicles").await.json()["vehicles"],
            serde_json::json!([])
        );
        app.scan(2, 0.0, &[[100.0, 50.0]]).await;
        let list = app.get("/api/v1/vehicles").await;
        assert_eq!(list.status, StatusCode::OK);
        let v = &list.json()["vehicles"][0];
        assert_eq!((v["id"].as_u64(), v["link"].is_null()), (Some(2), true));
        assert_eq!(v["detections"]["vehicle"], "2");
        assert_eq!(v["detections"]["sensors"], serde_json::json!(["cam"]));
        let one = app.get("/api/v1/vehicles/2").await;
        assert_eq!(one.status, StatusCode::OK);
        assert_eq!(&one.json(), v);
    }

    #[tokio::test]
    async fn an_unknown_or_malformed_vehicle_is_refused() {
        let app = TestApp::new();
        let r = app.get("/api/v1/vehicles/9").await;
        assert_eq!(r.status, StatusCode::NOT_FOUND);
        assert_eq!(r.error(), "no vehicle 9");
        let r = app.get("/api/v1/vehicles/300").await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(r.error(), "Invalid URL: Cannot parse `300` to a `u8`");
        assert_eq!(
            (app.refused("not_found", 404), app.refused("path", 400)),
            (1, 1)
        );
    }

    #[tokio::test]
    async fn a_command_is_answered_with_its_ack_or_504_after_the_attempts() {
        let (app, mut link) = TestApp::new().with_link();
        tokio::spawn(async move {
            while let Some(Request::Command { vehicle, reply, .. }) = link.recv().await {
                let result = if vehicle == 1 {
                    CommandResult::Accepted
                } else {
                    CommandResult::Timeout
                };
                let _ = reply.send(Ok(CommandOutcome {
                    vehicle,
                    command: "MAV_CMD_COMPONENT_ARM_DISARM".into(),
                    result,
                    ok: vehicle == 1,
                    attempts: 3,
                    elapsed_ms: 1.0,
                }));
            }
        });
        let arm = r#"{"command":"arm"}"#;
        let r = app
            .send(Method::POST, "/api/v1/vehicles/1/commands", arm)
            .await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(
            (r.json()["result"].as_str(), r.json()["ok"].as_bool()),
            (Some("accepted"), Some(true))
        );
        let r = app
            .send(Method::POST, "/api/v1/vehicles/4/commands", arm)
            .await;
        assert_eq!(r.status, StatusCode::GATEWAY_TIMEOUT);
        assert_eq!(r.json()["result"], "timeout");
        assert_eq!(app.refused_total(), 0);
    }

    /// Each command in the vehicle's autopilot's terms: hold is LOITER to ArduPilot, land RTL to
    /// an ArduPlane, takeoff GUIDED then NAV_TAKEOFF (above home) to an ArduCopter and TAKEOFF
    /// mode to an ArduPlane; `set_mode` takes the vehicle's own mode names.
    #[test]
    fn commands_follow_the_vehicles_autopilot() {
        use harrier_link::mavlink::dialects::common::MavCmd;
        let req = |command: &str, mode: Option<&str>, altitude_m: Option<f64>| CommandRequest {
            command: command.into(),
            altitude_m,
            mode: mode.map(Into::into),
            force: None,
        };
        let long = |m: &MavMessage| match m {
            MavMessage::COMMAND_LONG(c) => (c.command, c.param2, c.param7),
            other => panic!("{other:?}"),
        };
        let p = |l: &str| Personality::from_label(l).expect("label");
        let (copter, plane, px4) = (p("ardupilot-mc"), p("ardupilot-fw"), p("px4-mc"));
        let set_mode = MavCmd::MAV_CMD_DO_SET_MODE;
        for (r, personality, first, then) in [
            (req("hold", None, None), copter, (set_mode, 5.0), None),
            (req("hold", None, None), plane, (set_mode, 12.0), None),
            (req("hold", None, None), px4, (set_mode, 4.0), None),
            (req("land", None, None), plane, (set_mode, 11.0), None),
            (
                req("land", None, None),
                copter,
                (MavCmd::MAV_CMD_NAV_LAND, f32::NAN),
                None,
            ),
            (
                req("takeoff", None, Some(20.0)),
                copter,
                (set_mode, 4.0),
                Some((MavCmd::MAV_CMD_NAV_TAKEOFF, 20.0)),
            ),
            (req("takeoff", None, None), plane, (set_mode, 13.0), None),
            (
                req("set_mode", Some("guided"), None),
                plane,
                (set_mode, 15.0),
                None,
            ),
            (
                req("set_mode", Some("offboard"), None),
                px4,
                (set_mode, 6.0),
                None,
            ),
            (
                req("set_mode", Some("BRAKE"), None),
                copter,
                (set_mode, 17.0),
                None,
            ),
        ] {
            let (m, next) = r.messages(3, Some(488.0), personality).expect("a command");
            let (c, p2, _) = long(&m);
            assert_eq!(c, first.0, "{r:?} {personality:?}");
            assert!(
                p2 == first.1 || (p2.is_nan() && first.1.is_nan()),
                "{r:?}: {p2}"
            );
            assert_eq!(next.as_ref().map(|n| (long(n).0, long(n).2)), then, "{r:?}");
        }
        let e = req("set_mode", Some("BRAKE"), None)
            .messages(3, None, plane)
            .expect_err("no BRAKE on a plane");
        assert!(e.contains("ardupilot-fw"), "{e}");
    }

    #[tokio::test]
    async fn a_command_without_link_out_of_range_or_to_a_stopped_link_is_refused() {
        let app = TestApp::new();
        let r = app
            .send(
                Method::POST,
                "/api/v1/vehicles/1/commands",
                r#"{"command":"arm"}"#,
            )
            .await;
        assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(r.error(), "no MAVLink link: set mavlink.gcs");
        let (app, link) = TestApp::new().with_link();
        let fly = r#"{"command":"takeoff","altitude_m":-3}"#;
        let r = app
            .send(Method::POST, "/api/v1/vehicles/1/commands", fly)
            .await;
        assert_eq!(r.status, StatusCode::UNPROCESSABLE_ENTITY);
        assert_eq!(r.error(), "altitude_m must be in (0, 10000], got -3");
        assert_eq!(app.refused("invalid", 422), 1);
        let r = app
            .send(
                Method::POST,
                "/api/v1/vehicles/x/commands",
                r#"{"command":"arm"}"#,
            )
            .await;
        assert_eq!(r.status, StatusCode::BAD_REQUEST);
        assert_eq!(app.refused("path", 400), 1);
        // The link's actor has stopped: 503, and counted (it was not before).
        drop(link);
        let r = app
            .send(
                Method::POST,
                "/api/v1/vehicles/1/commands",
                r#"{"command":"arm"}"#,
            )
            .await;
        assert_eq!(r.status, StatusCode::SERVICE_UNAVAILABLE);
        assert_eq!(r.error(), "the MAVLink link is not running");
        assert_eq!(app.refused("no_link", 503), 1);
    }
}
