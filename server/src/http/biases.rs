//! `GET /biases`: the registered sensors' bias estimates of live sensor registration
//! (`[registration]`).

use axum::extract::State;
use axum::routing::get;
use axum::{Json, Router};
use utoipa::OpenApi;

use super::error::ErrorBody;
use super::state::{ApiState, Tracking};
use harrier_engine::{BiasTermView, SensorBiasView};

/// The route of this file.
pub(super) fn routes() -> Router<ApiState> {
    Router::new().route("/biases", get(biases))
}

/// The OpenAPI path of this file.
#[derive(Debug, OpenApi)]
#[openapi(paths(biases), components(schemas(SensorBiasView, BiasTermView)))]
pub(super) struct Doc;

/// Every registered sensor's bias terms: each term's estimate, standard deviation and whether
/// it is observable yet, and the detections that updated them; empty when registration is off.
/// Refreshed at most every 0.5 s of scan time.
#[utoipa::path(get, path = "/api/v1/biases", tag = "tracks",
    responses(
        (status = 200, body = [SensorBiasView]),
        (status = 401, description = "Reads need the token", body = ErrorBody),
    ),
    security((), ("bearer" = [])))]
async fn biases(State(s): State<Tracking>) -> Json<Vec<SensorBiasView>> {
    Json(s.snapshot.borrow().biases.to_vec())
}

#[cfg(test)]
mod tests {
    use axum::http::StatusCode;
    use harrier_core::measurement::MeasKind;
    use serde_json::{Value, json};

    use super::super::testing::{Sensor, TestApp};
    use crate::config::{Config, RegistrationSensor};

    /// A target standing at (300, 400) m; vehicle 2's `position` sensor sees it unbiased,
    /// vehicle 1's radar at the origin with a range offset of 30 m and an azimuth offset of
    /// 5 mrad (no noise in either).
    const RANGE_OFFSET: f64 = 30.0;
    const AZIMUTH_OFFSET: f64 = 0.005;

    fn registered() -> Config {
        let mut config = Config::default();
        config.registration.sensors = vec![RegistrationSensor {
            vehicle: "1".into(),
            sensor: "radar".into(),
            kind: MeasKind::RangeBearing,
            bias: Some(json!({"offset": [
                {"model": "constant", "std": 50.0},
                {"model": "constant", "std": 0.01},
            ]})),
        }];
        config
    }

    fn term<'a>(sensor: &'a Value, name: &str) -> &'a Value {
        sensor["terms"]
            .as_array()
            .and_then(|t| t.iter().find(|t| t["term"] == name))
            .unwrap_or_else(|| panic!("no term {name} in {sensor}"))
    }

    #[tokio::test]
    async fn without_registration_there_are_no_biases() {
        let app = TestApp::new();
        let r = app.get("/api/v1/biases").await;
        assert_eq!(r.status, StatusCode::OK);
        assert_eq!(r.json(), json!([]));
        let spec = app.get("/api/openapi.json").await.json();
        assert!(spec["paths"]["/api/v1/biases"]["get"].is_object(), "{spec}");
    }

    #[tokio::test]
    async fn a_biased_radar_and_an_unbiased_sensor_on_one_target_give_the_radar_bias() {
        let app = TestApp::with_config(&registered(), 256);
        // At the start: the prior, not observable.
        let r = app.get("/api/v1/biases").await;
        assert_eq!(r.status, StatusCode::OK);
        let list = r.json();
        assert_eq!(list.as_array().map(Vec::len), Some(1), "{list}");
        let radar = &list[0];
        assert_eq!(
            (&radar["vehicle"], &radar["sensor"], &radar["kind"]),
            (&json!("1"), &json!("radar"), &json!("range_bearing"))
        );
        assert_eq!(radar["observable"], false);
        assert_eq!(radar["updates"], 0);
        let range = term(radar, "offset0");
        assert_eq!(
            (&range["value"], &range["std"]),
            (&json!(0.0), &json!(50.0))
        );

        let cam = Sensor {
            id: "cam",
            kind: MeasKind::Position,
            platform: [0.0, 0.0, 50.0],
            noise_std: &[2.0, 2.0],
        };
        let radar_sensor = Sensor {
            id: "radar",
            kind: MeasKind::RangeBearing,
            platform: [0.0, 0.0, 0.0],
            noise_std: &[5.0, 0.002],
        };
        let (x, y) = (300.0_f64, 400.0_f64);
        let z = vec![vec![x.hypot(y) + RANGE_OFFSET, x.atan2(y) + AZIMUTH_OFFSET]];
        for k in 0..40 {
            let t = f64::from(k);
            app.scan_of(2, &cam, t, vec![vec![x, y]]).await;
            app.scan_of(1, &radar_sensor, t + 0.5, z.clone()).await;
        }
        let list = app.get("/api/v1/biases").await.json();
        let radar = &list[0];
        assert!(radar["updates"].as_u64() > Some(20), "{radar}");
        for (name, truth) in [("offset0", RANGE_OFFSET), ("offset1", AZIMUTH_OFFSET)] {
            let t = term(radar, name);
            let (v, sd) = (t["value"].as_f64(), t["std"].as_f64());
            let (Some(v), Some(sd)) = (v, sd) else {
                panic!("{t}");
            };
            assert!(
                (v - truth).abs() <= 3.0 * sd,
                "{name}: {v} ± {sd}, truth {truth}"
            );
            assert_eq!(t["observable"], true, "{name}: {t}");
        }
        assert_eq!(radar["observable"], true, "{radar}");
        // The track sits on the target, not on the biased radar's fix.
        let tracks = app.get("/api/v1/tracks").await.json();
        let k = &tracks["tracks"][0];
        let (tx, ty) = (k["state"][0].as_f64(), k["state"][1].as_f64());
        let (Some(tx), Some(ty)) = (tx, ty) else {
            panic!("{k}");
        };
        assert!((tx - x).hypot(ty - y) < 5.0, "{k}");
    }
}
