//! `GET /truth`, `GET /world`, `GET /aircraft`: the simulator's latest truth, the
//! configuration's roads and obstacles ([`crate::world`]) and the manned aircraft of the ADS-B
//! feed ([`crate::feeds`]), for the map.

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use utoipa::OpenApi;

use super::error::ErrorBody;
use super::state::{ApiState, Tracking};
use crate::wire::aircraft::AircraftList;
use crate::world::{TruthBody, WorldBody};

/// The routes of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new()
        .route("/truth", get(truth))
        .route("/world", get(world))
        .route("/aircraft", get(aircraft))
}

/// The OpenAPI paths of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(truth, world, aircraft))]
pub(super) struct Doc;

/// The latest simulation truth (`harrier/v1/sim/truth`), for drawing, with each live track's
/// error and NEES against the nearest target.
#[utoipa::path(get, path = "/api/v1/truth", tag = "tracks",
    responses(
        (status = 200, body = TruthBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn truth(State(s): State<Tracking>) -> Json<TruthBody> {
    let truth = std::sync::Arc::clone(&s.truth.borrow());
    let snap = std::sync::Arc::clone(&s.snapshot.borrow());
    Json(truth.with_scores(&snap.tracks))
}

/// The static world: roads and obstacles of the configuration, for the map.
#[utoipa::path(get, path = "/api/v1/world", tag = "tracks",
    responses(
        (status = 200, body = WorldBody),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn world(State(s): State<Tracking>) -> Json<WorldBody> {
    Json(s.world.as_ref().clone())
}

/// The manned aircraft of the ADS-B feed (`[adsb]`, docs/adsb.md): tracks of their own kind,
/// by 24-bit address, never among the ground tracks. Empty, with `feed` `off`, when the feed
/// is off.
#[utoipa::path(get, path = "/api/v1/aircraft", tag = "tracks",
    responses(
        (status = 200, body = AircraftList),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn aircraft(State(s): State<Tracking>) -> Json<AircraftList> {
    Json(s.aircraft.borrow().as_ref().clone())
}

#[cfg(test)]
mod tests {
    use std::sync::Arc;

    use axum::http::StatusCode;

    use super::super::testing::TestApp;
    use crate::world::{ObstacleView, TruthBody, TruthTarget, WorldBody};

    #[tokio::test]
    async fn the_truth_and_the_world_are_served_as_they_are() {
        let mut app = TestApp::new();
        app.state.tracking.world = Arc::new(WorldBody {
            roads: Vec::new(),
            obstacles: vec![ObstacleView {
                x_m: 10.0,
                y_m: -5.0,
                radius_m: 3.0,
            }],
        });
        assert_eq!(
            app.get("/api/v1/truth").await.json(),
            serde_json::json!({"targets": [], "scores": []})
        );
        app.truth.send_replace(Arc::new(TruthBody {
            targets: vec![TruthTarget {
                id: "car-1".into(),
                t: 12.5,
                position: [1.0, 2.0, 0.0],
                velocity: [3.0, 0.0, 0.0],
            }],
            scores: Vec::new(),
        }));
        let r = app.get("/api/v1/truth").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.json()["targets"][0]["id"], "car-1");
        assert_eq!(r.json()["scores"], serde_json::json!([]));
        let r = app.get("/api/v1/world").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(
            r.json(),
            serde_json::json!({"roads": [], "obstacles": [{"x_m": 10.0, "y_m": -5.0, "radius_m": 3.0}]})
        );
    }

    #[tokio::test]
    async fn the_aircraft_are_served_as_the_feed_lists_them() {
        use crate::wire::aircraft::{AdsbFeedState, AircraftDto, AircraftList};
        let mut app = TestApp::new();
        let r = app.get("/api/v1/aircraft").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(
            r.json(),
            serde_json::json!({"time_unix": 0.0, "feed": "off", "aircraft": []})
        );
        let a = AircraftDto {
            icao: "4CA2D6".into(),
            callsign: Some("RYR4TX".into()),
            squawk: None,
            on_ground: Some(false),
            time_unix: 99.5,
            age_s: 0.5,
            lat_deg: 47.5,
            lon_deg: 8.6,
            altitude_m: 3000.0,
            state: [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
            course_deg: 38.7,
            speed_mps: 6.4,
            climb_mps: 6.0,
            sigma_h_m: 7.0,
            updates: 12,
            messages: 20,
        };
        let list = AircraftList {
            time_unix: 100.0,
            feed: AdsbFeedState::Connected,
            aircraft: vec![a],
        };
        app.state.tracking.aircraft = tokio::sync::watch::channel(Arc::new(list)).1;
        let body = app.get("/api/v1/aircraft").await.json();
        assert_eq!(body["feed"], "connected");
        assert_eq!(body["aircraft"][0]["icao"], "4CA2D6");
        assert_eq!(body["aircraft"][0]["callsign"], "RYR4TX");
        assert_eq!(body["aircraft"][0]["squawk"], serde_json::Value::Null);
        assert_eq!(body["aircraft"][0]["state"][5], 6.0);
    }

    #[tokio::test]
    async fn a_track_near_a_target_is_scored_against_it() {
        let app = TestApp::new();
        let id = app.confirmed_track().await;
        let t = app.state.tracking.snapshot.borrow().t.expect("a scan");
        // Two targets: the track (at about (100, 50)) is scored against the nearer one, moved
        // on to the track's time.
        let target = |id: &str, x: f64| TruthTarget {
            id: id.into(),
            t: t - 1.0,
            position: [x - 3.0, 50.0, 0.0],
            velocity: [3.0, 0.0, 0.0],
        };
        app.truth.send_replace(Arc::new(TruthBody {
            targets: vec![target("far", 160.0), target("near", 103.0)],
            scores: Vec::new(),
        }));
        let body = app.get("/api/v1/truth").await.json();
        let s = &body["scores"][0];
        assert_eq!(
            (&s["track"], &s["target"], &s["dof"]),
            (&id.into(), &"near".into(), &2.into())
        );
        let error = s["error_m"].as_f64().expect("an error");
        assert!((1.0..5.0).contains(&error), "{s}");
        assert!(s["nees"].as_f64().is_some_and(|n| n > 0.0), "{s}");
    }

    #[tokio::test]
    async fn the_world_needs_the_token_when_reads_do() {
        let app = TestApp::new().reads_need_token();
        for uri in ["/api/v1/truth", "/api/v1/world"] {
            assert_eq!(app.get(uri).await.status, StatusCode::UNAUTHORIZED);
            assert_eq!(app.get_with_token(uri).await.status, StatusCode::OK);
        }
        assert_eq!(app.refused("auth_missing", 401), 2);
    }
}
