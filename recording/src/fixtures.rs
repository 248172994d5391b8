//! Records for the tests of the recording and of its readers (harrier-tools' `sessions`):
//! built with the `fixtures` feature, never in a product build.

use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, PlatformPose, TargetTruth};
use harrier_core::detection::{DetectionScan, GeoPoint, TRUTH_SCHEMA, TruthSample};
use harrier_core::measurement::MeasKind;

use crate::writer::{Record, SessionMeta};
use harrier_engine::TrackView;

/// PX4 SITL's home (harrier-server's `config::DEFAULT_ORIGIN`), the session's origin.
pub const HOME: GeoPoint = GeoPoint {
    lat_deg: 47.397_742,
    lon_deg: 8.545_594,
    alt_m: 488.0,
};
/// UNIX time of the tests' scan time 0.
pub const T0_UNIX: f64 = 1_795_430_400.25;

/// The session of a server at [`HOME`] on the ground plane z = 0.
pub fn meta(estimator: &str) -> SessionMeta {
    SessionMeta {
        started_unix: T0_UNIX - 5.0,
        origin: HOME,
        plane_z: 0.0,
        estimator: estimator.into(),
        config_json: serde_json::json!({"tracker": {
            "scan_period_s": 1.0,
            "motion": {"accel_std": 0.5, "models": [{"name": "CV", "type": "CV"}]}
        }})
        .to_string(),
    }
}

/// A `position` scan (10 m noise) of `vehicle`'s `cam` at time `t` (UNIX `T0_UNIX + t`)
/// from a platform at `pos`, with detections `z`.
pub fn scan(vehicle: u8, seq: u64, t: f64, pos: [f64; 3], z: &[[f64; 2]]) -> Record {
    let frame = harrier_link::geo::LocalFrame::new(HOME);
    Record::Scan {
        received_unix: T0_UNIX + t + 0.01,
        scan: DetectionScan {
            schema: DETECTIONS_SCHEMA.into(),
            t,
            time_unix: Some(T0_UNIX + t),
            vehicle,
            seq,
            sensor: "cam".into(),
            kind: MeasKind::Position,
            origin: HOME,
            platform: PlatformPose {
                pos,
                vel: [1.0, 0.0, 0.0],
                attitude: [0.0; 3],
                geodetic: Some(frame.from_enu(&nalgebra::Vector3::from(pos))),
            },
            noise_std: vec![10.0, 10.0],
            detections: z.iter().map(|z| Detection { z: z.to_vec() }).collect(),
        },
    }
}

/// Truth at `t` of targets `(id, state)`.
pub fn truth(t: f64, targets: &[(&str, [f64; 6])]) -> Record {
    Record::Truth(TruthSample {
        schema: TRUTH_SCHEMA.into(),
        t,
        time_unix: Some(T0_UNIX + t),
        origin: HOME,
        targets: targets
            .iter()
            .map(|(id, state)| TargetTruth {
                id: (*id).into(),
                state: *state,
                mode: "CV".into(),
            })
            .collect(),
    })
}

/// A confirmed planar track `id` at `state`.
pub fn track(id: u64, t: f64, state: [f64; 6]) -> TrackView {
    TrackView {
        id,
        status: harrier_engine::TrackStatus::Confirmed,
        t,
        state,
        cov: vec![vec![4.0, 0.0, 0.0, 0.0]; 4],
        cov_dims: vec![0, 1, 3, 4],
        updated: true,
        age: 3,
        last_update: t,
        mode_probabilities: vec![0.9, 0.1],
        existence: None,
    }
}
