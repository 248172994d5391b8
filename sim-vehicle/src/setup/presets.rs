//! The built-in scenarios ([`PRESETS`](super::PRESETS)), after the papers' experiments.

use harrier_core::road::road_from_turn_legs;
use harrier_core::scenario::{Motion, MotionModelSpec};
use nalgebra::Vector2;

use super::{
    AirframeSpec, Behaviour, BiasModel, CameraOutput, EstimatorHints, Jitter, MotionSegment,
    Pointing, SensorSpec, SensorType, SimScenario, TargetMotion, TargetSpec, VehicleSpec,
    default_origin,
};

impl SimScenario {
    /// The built-in scenario `name` (see [`PRESETS`](super::PRESETS)).
    pub fn preset(name: &str) -> Option<Self> {
        match name {
            "cimm-road" => Some(cimm_road()),
            "leader" => Some(leader()),
            "radar" => Some(radar(BiasModel::None, "radar")),
            "radar-abrupt" => Some(radar(
                BiasModel::Abrupt {
                    t_on: 100.0,
                    t_off: 200.0,
                    scale: [0.01, 0.0],
                    offset: [100.0, 0.01],
                },
                "radar-abrupt",
            )),
            "radar-markov" => Some(radar(
                BiasModel::Markov {
                    mean: [60.0, 0.006],
                    std: [30.0, 0.004],
                    tau_s: 40.0,
                    scale: [0.005, 0.0],
                },
                "radar-markov",
            )),
            "crossing" => Some(crossing()),
            _ => None,
        }
    }
}

/// Hints for a single white-noise-acceleration CV model, scored from t = 5 s.
fn cv_hints(accel_std: f64, prior_std: [f64; 4]) -> EstimatorHints {
    EstimatorHints {
        motion: Some(Motion {
            models: vec![model("CV", None)],
            initial_probs: None,
            transition_matrix: None,
            accel_std: Some(accel_std),
            accel_bound: None,
        }),
        prior_std,
        scoring_t_start: 5.0,
    }
}

fn model(name: &str, turn_rate: Option<f64>) -> MotionModelSpec {
    MotionModelSpec {
        name: name.into(),
        kind: if turn_rate.is_some() { "CT" } else { "CV" }.into(),
        turn_rate,
    }
}

/// \[CIMM\] §5.1: a ground vehicle at 10 m/s on a road, straight 140 s, right turn (−0.008 rad/s)
/// 220 s, left turn (0.01 rad/s) 340 s; camera geolocation with 10 m noise at 1 Hz; fixed wings
/// orbiting it at R = 300 m, 300 m above, 20 m/s (LGVF).
fn cimm_road() -> SimScenario {
    // The target starts at (200, 300) m with (6, 8) m/s: straight 140 s, right 220 s, left
    // 340 s. The road begins 100 m (10 s) before it.
    let v0 = Vector2::new(6.0, 8.0);
    let start = Vector2::new(200.0, 300.0) - v0 * 10.0;
    let legs = [(-10.0, 0.0), (140.0, -0.008), (360.0, 0.01)];
    let road = road_from_turn_legs(start, v0, &legs, 700.0, "road1", Some(7.0), Some(2.0))
        .expect("the CIMM road's legs are valid");
    SimScenario {
        name: "cimm-road".into(),
        description: "[CIMM] §5.1: ground vehicle on a road (straight, right turn, left turn), \
                      camera geolocation 10 m at 1 Hz, UAVs orbiting at R 300 m, 300 m above."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "tgt".into(),
            size_m: 5.0,
            size_known: false,
            motion: TargetMotion::Road {
                road: "road1".into(),
                speed_mps: 10.0,
                start_m: 100.0,
                lateral_std_m: 0.0,
            },
            jitter: Jitter::default(),
        }],
        roads: vec![road],
        sensors: vec![SensorSpec {
            id: "cam".into(),
            rate_hz: 1.0,
            pd: 1.0,
            clutter_rate: 0.0,
            time_offset_s: 0.0,
            max_range_m: 2000.0,
            noise_std: vec![10.0, 10.0],
            model: SensorType::Camera {
                output: CameraOutput::Position,
                fov_deg: 30.0,
                pointing: Pointing::Track { target: 0 },
                mounting_deg: [0.0, 0.0],
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::FixedWing,
            preroll_s: 90.0,
            behaviour: Behaviour::Orbit {
                target: 0,
                radius_m: 300.0,
                height_m: 300.0,
                speed_mps: 20.0,
            },
        },
        estimator: EstimatorHints {
            motion: Some(Motion {
                models: vec![
                    model("CV", None),
                    model("right", Some(-0.008)),
                    model("left", Some(0.01)),
                ],
                initial_probs: Some(vec![0.98, 0.01, 0.01]),
                transition_matrix: Some(vec![
                    vec![0.98, 0.01, 0.01],
                    vec![0.01, 0.98, 0.01],
                    vec![0.01, 0.01, 0.98],
                ]),
                accel_std: Some(0.05),
                accel_bound: None,
            }),
            prior_std: [20.0, 20.0, 2.0, 2.0],
            scoring_t_start: 5.0,
        },
    }
}

/// \[BOT\] §IV: a leader aircraft at 25 m/s with sinusoidal heading (±40°, 30 s), 10 m wing span,
/// seen by a follower's `bearing_size` camera at 10 Hz (1 mrad noise); the follower flies 60 m
/// left of and 120 m behind the leader.
fn leader() -> SimScenario {
    SimScenario {
        name: "leader".into(),
        description: "[BOT] §IV: leader with sinusoidal heading, follower's bearing/size camera."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "leader".into(),
            size_m: 10.0,
            size_known: false,
            motion: TargetMotion::Leader {
                position: [60.0, 120.0],
                z_m: 100.0,
                speed_mps: 25.0,
                heading_deg: 0.0,
                amplitude_deg: 40.0,
                period_s: 30.0,
            },
            jitter: Jitter::default(),
        }],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "cam".into(),
            rate_hz: 10.0,
            pd: 1.0,
            clutter_rate: 0.0,
            time_offset_s: 0.0,
            max_range_m: 2000.0,
            noise_std: vec![0.001, 0.001, 0.001],
            model: SensorType::Camera {
                output: CameraOutput::BearingSize,
                fov_deg: 40.0,
                pointing: Pointing::Track { target: 0 },
                mounting_deg: [0.0, 0.0],
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::FixedWing,
            preroll_s: 30.0,
            behaviour: Behaviour::Follow {
                target: 0,
                offset_m: [-60.0, -120.0],
                height_m: 0.0,
                spacing_m: 30.0,
            },
        },
        estimator: cv_hints(2.0, [40.0, 40.0, 5.0, 5.0]),
    }
}

/// \[ICDKF\] §4: a target manoeuvring in the plane (CV 80 s, left 0.05 rad/s 30 s, CV 70 s, right
/// −0.04 rad/s 30 s, CV) seen by a radar (5 m, 5 mrad, 1 Hz) on a multirotor cruising east at
/// 5 m/s, with the given bias.
fn radar(bias: BiasModel, name: &str) -> SimScenario {
    let seg = |mode: &str, turn_rate, duration_s| MotionSegment {
        mode: mode.into(),
        turn_rate,
        duration_s,
    };
    SimScenario {
        name: name.into(),
        description: "[ICDKF] §4: manoeuvring target, range/bearing radar on a moving multirotor."
            .into(),
        origin: default_origin(),
        targets: vec![TargetSpec {
            id: "tgt".into(),
            size_m: 10.0,
            size_known: false,
            motion: TargetMotion::Segments {
                position: [1000.0, 5000.0],
                velocity: [15.0, -10.0],
                z_m: 0.0,
                segments: vec![
                    seg("CV", 0.0, 80.0),
                    seg("left", 0.05, 30.0),
                    seg("CV", 0.0, 70.0),
                    seg("right", -0.04, 30.0),
                    seg("CV", 0.0, 90.0),
                ],
            },
            jitter: Jitter::default(),
        }],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "radar".into(),
            rate_hz: 1.0,
            pd: 1.0,
            clutter_rate: 0.0,
            time_offset_s: 0.0,
            max_range_m: 20_000.0,
            noise_std: vec![5.0, 0.005],
            model: SensorType::Radar {
                bias,
                paints_vehicles: false,
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::Multirotor,
            preroll_s: 10.0,
            behaviour: Behaviour::Cruise {
                velocity: [5.0, 0.0],
                altitude_m: 20.0,
            },
        },
        estimator: cv_hints(1.0, [100.0, 100.0, 5.0, 5.0]),
    }
}

/// Four ground vehicles crossing under a multirotor hovering 400 m up, seen by a nadir gimbal
/// camera (`az_el`, 90° field of view, Pd 0.9, one clutter detection per scan) at 2 Hz.
fn crossing() -> SimScenario {
    let straight = |id: &str, position: [f64; 2], velocity: [f64; 2]| TargetSpec {
        id: id.into(),
        size_m: 5.0,
        size_known: false,
        motion: TargetMotion::Segments {
            position,
            velocity,
            z_m: 0.0,
            segments: Vec::new(),
        },
        jitter: Jitter {
            position_m: 20.0,
            heading_deg: 5.0,
            speed_mps: 1.0,
        },
    };
    SimScenario {
        name: "crossing".into(),
        description: "Ground vehicles crossing under a hovering multirotor; nadir camera with \
                      Pd < 1 and Poisson clutter (FORMAT-MULTI.md)."
            .into(),
        origin: default_origin(),
        targets: vec![
            straight("T0", [-300.0, 0.0], [8.0, 0.0]),
            straight("T1", [0.0, -300.0], [0.0, 8.0]),
            straight("T2", [250.0, 250.0], [-6.0, -6.0]),
            straight("T3", [-250.0, 250.0], [6.0, -6.0]),
        ],
        roads: Vec::new(),
        sensors: vec![SensorSpec {
            id: "gimbal".into(),
            rate_hz: 2.0,
            pd: 0.9,
            clutter_rate: 1.0,
            time_offset_s: 0.0,
            max_range_m: 1500.0,
            noise_std: vec![0.002, 0.002],
            model: SensorType::Camera {
                output: CameraOutput::AzEl,
                fov_deg: 90.0,
                pointing: Pointing::Nadir,
                mounting_deg: [0.0, 0.0],
            },
        }],
        vehicles: VehicleSpec {
            airframe: AirframeSpec::Multirotor,
            preroll_s: 100.0,
            behaviour: Behaviour::Hold {
                position: [0.0, 0.0, 400.0],
                spacing_m: 30.0,
            },
        },
        estimator: cv_hints(0.3, [20.0, 20.0, 2.0, 2.0]),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{PRESETS, Source};
    use super::*;
    use std::path::Path;

    #[test]
    fn presets_are_valid_and_round_trip() {
        for name in PRESETS {
            let s = SimScenario::preset(name).expect(name);
            s.validate(&Source::Preset(name.into())).expect(name);
            let back = SimScenario::from_json(&s.to_json(), Path::new("x.json")).expect(name);
            // serde_json's float parser may be off by an ulp: compare the JSON values closely.
            let a: serde_json::Value = serde_json::from_str(&s.to_json()).expect("json");
            let b: serde_json::Value = serde_json::from_str(&back.to_json()).expect("json");
            assert!(close_json(&a, &b), "{name}");
        }
        assert!(SimScenario::preset("nope").is_none());
        assert!(SimScenario::preset("crossing").is_some_and(|s| s.is_multi()));
        assert!(SimScenario::preset("cimm-road").is_some_and(|s| !s.is_multi()));
    }

    #[test]
    fn cimm_road_matches_the_reference_geometry() {
        use harrier_core::scenario::Segment;
        let s = cimm_road();
        let segs = &s.roads[0].segments;
        assert_eq!(segs.len(), 3);
        let close = |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).hypot(a[1] - b[1]) < 1e-6;
        match (&segs[0], &segs[1], &segs[2]) {
            (
                Segment::Line { start, end },
                Segment::Arc {
                    center,
                    radius,
                    sweep_rad,
                    ..
                },
                Segment::Arc {
                    center: c2,
                    radius: r2,
                    end: e2,
                    sweep_rad: s2,
                    ..
                },
            ) => {
                assert!(close(*start, [140.0, 220.0]) && close(*end, [1040.0, 1420.0]));
                assert!(close(*center, [2040.0, 670.0]));
                assert!((radius - 1250.0).abs() < 1e-9 && (sweep_rad + 1.76).abs() < 1e-12);
                assert!(close(
                    *c2,
                    [3_704.446_638_142_980_6, 2_183.974_038_342_336_4]
                ));
                assert!((r2 - 1000.0).abs() < 1e-6 && (s2 - 3.4).abs() < 1e-12);
                assert!(close(*e2, [4_247.691_708_011_238, 3_023.548_212_590_115]));
            }
            other => panic!("unexpected segments {other:?}"),
        }
    }

    fn close_json(a: &serde_json::Value, b: &serde_json::Value) -> bool {
        use serde_json::Value as V;
        match (a, b) {
            (V::Number(x), V::Number(y)) => {
                let (x, y) = (
                    x.as_f64().unwrap_or(f64::NAN),
                    y.as_f64().unwrap_or(f64::NAN),
                );
                (x - y).abs() <= 1e-12 * (1.0 + x.abs())
            }
            (V::Array(x), V::Array(y)) => {
                x.len() == y.len() && x.iter().zip(y).all(|(p, q)| close_json(p, q))
            }
            (V::Object(x), V::Object(y)) => {
                x.len() == y.len()
                    && x.iter()
                        .all(|(k, v)| y.get(k).is_some_and(|w| close_json(v, w)))
            }
            _ => a == b,
        }
    }
}
