//! Hand-off assignments end to end: a track handed to the autopilots instead of streaming
//! setpoints.
//!
//! - `pymavlink_vehicles_receive_every_hand_off`: `tests/python/handoff_vehicles.py` poses as
//!   three PX4 multirotors on a live server's GCS link (pymavlink, real UDP) while a standing
//!   target is tracked from Zenoh detections at 10 Hz; each vehicle is handed the track one way.
//!   The follower gets FOLLOW_TARGET at ≥ 9 Hz with the track's position (within 5 m) and its
//!   position variances, and is switched to AUTO.FOLLOW_TARGET; the orbiter gets DO_ORBIT
//!   centred within 5 m of the track estimate, R and speed as assigned; the camera vehicle is
//!   asked for its gimbal manager and gets DO_SET_ROI_LOCATION for its gimbal device within
//!   100 ms of each update of the track, at that update's estimate (within 5 cm), and at ≥ 9 Hz
//!   in all (the predicted track between updates).
//! - `the_simulators_camera_points_at_the_handed_target`: harrier-sim's embedded world (the
//!   `crossing` preset, its camera on the vehicle's gimbal, `pointing: roi`) feeding the server,
//!   a PX4 multirotor hovering 150 m over the crossing; handed a car's track, its gimbal (and so its
//!   camera) points within 1° of the car (the truth moved on at its velocity to the instant the
//!   gimbal is read).

use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use harrier_core::detection::GeoPoint;
use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_server::guidance::AssignmentRequest;
use harrier_server::tracker::Snapshot;
use nalgebra::Vector3;
use serde_json::Value;

use harrier_tests::{
    json_lines, open_session, publish_standing_target, python_script, require_python_module,
    runtime, server_config, within,
};

/// A track update as the test saw it: when (UNIX s), the estimate's time, position (ENU) and
/// position variances (x, y, z).
#[derive(Debug, Clone, Copy)]
struct Update {
    seen: f64,
    t: f64,
    position: Vector3<f64>,
    var: [f64; 3],
}

fn request(vehicle: u8, track: u64, law: &str) -> AssignmentRequest {
    AssignmentRequest {
        vehicles: vec![vehicle],
        track,
        law: law.into(),
        radius_m: Some(60.0),
        height_m: Some(40.0),
        spacing_deg: None,
        speed_m_s: Some(5.0),
        orbit: None,
    }
}

/// Records every change of track `id` in the snapshot.
fn record_updates(
    mut rx: tokio::sync::watch::Receiver<Arc<Snapshot>>,
    id: u64,
) -> (Arc<Mutex<Vec<Update>>>, tokio::task::JoinHandle<()>) {
    let updates = Arc::new(Mutex::new(Vec::<Update>::new()));
    let log = Arc::clone(&updates);
    let task = tokio::spawn(async move {
        while rx.changed().await.is_ok() {
            let seen = harrier_link::clock::unix_now();
            let snap = rx.borrow().clone();
            let Some(k) = snap.tracks.iter().find(|k| k.id == id) else {
                continue;
            };
            let mut log = log.lock().expect("updates");
            if log.last().is_some_and(|u| u.t == k.t) {
                continue;
            }
            let v = |i| k.cov_at(i, i).unwrap_or(0.0);
            log.push(Update {
                seen,
                t: k.t,
                position: Vector3::new(k.state[0], k.state[1], k.state[2]),
                var: [v(0), v(1), v(2)],
            });
        }
    });
    (updates, task)
}

/// The ENU point of a record's latitude, longitude and altitude.
fn enu(frame: &LocalFrame, r: &Value) -> Vector3<f64> {
    let f = |k: &str| r[k].as_f64().expect(k);
    frame.to_enu(&Geodetic::new(f("lat"), f("lon"), f("alt")))
}

/// The last update seen before `at`.
fn before(updates: &[Update], at: f64) -> Option<&Update> {
    updates.iter().rev().find(|u| u.seen <= at)
}

#[test]
fn pymavlink_vehicles_receive_every_hand_off() {
    require_python_module("pymavlink", "pymavlink==2.4.50");
    runtime().block_on(within(120, "the hand-off test", async {
        let (mut config, zenoh) = server_config();
        config.mavlink.gcs = vec!["udpin:127.0.0.1:0".into()];
        let server = harrier_server::start(&config)
            .await
            .expect("start the server");
        let gcs = server
            .link()
            .and_then(|l| l.gcs().next().map(|e| e.addr()))
            .expect("a GCS link");
        let frame = LocalFrame::new(config.frame.origin);
        let session = open_session(vec![zenoh]).await;
        let publisher =
            publish_standing_target(&session, 1, [80.0, 30.0], [0.0, 0.0, 50.0], 10.0).await;
        let mut snapshot = server.snapshot();
        let track = within(30, "a confirmed track", async {
            loop {
                snapshot.changed().await.expect("snapshot");
                if let Some(k) = snapshot
                    .borrow()
                    .tracks
                    .iter()
                    .find(|k| k.status == harrier_engine::TrackStatus::Confirmed)
                {
                    return k.id;
                }
            }
        })
        .await;
        let (updates, recorder) = record_updates(server.snapshot(), track);

        let mut child = python_script("handoff_vehicles.py")
            .args(["--gcs", &gcs.to_string(), "--seconds", "10"])
            .stdout(std::process::Stdio::piped())
            .spawn()
            .expect("run handoff_vehicles.py");
        let lines = json_lines(&mut child);
        let link = server.link().expect("link").clone();
        within(10, "the three vehicles heard", async {
            loop {
                if link
                    .vehicles
                    .borrow()
                    .iter()
                    .filter(|v| v.status.is_some())
                    .count()
                    == 3
                {
                    return;
                }
                tokio::time::sleep(Duration::from_millis(50)).await;
            }
        })
        .await;
        let guidance = server.guidance().expect("guidance").clone();
        for (vehicle, law) in [
            (11, "handoff_follow"),
            (12, "handoff_orbit"),
            (13, "handoff_camera"),
        ] {
            guidance
                .create(request(vehicle, track, law))
                .await
                .unwrap_or_else(|e| panic!("{law}: {e}"));
        }
        let records: Vec<Value> = tokio::task::spawn_blocking(move || {
            let records: Vec<Value> = lines.iter().collect();
            let _ = child.wait();
            records
        })
        .await
        .expect("the script's output");
        publisher.abort();
        recorder.abort();
        let updates = updates.lock().expect("updates").clone();
        assert!(
            records.last().is_some_and(|r| r["kind"] == "done"),
            "handoff_vehicles.py did not finish: {records:?}"
        );
        let of = |v: u64, kind: &str| -> Vec<&Value> {
            records
                .iter()
                .filter(|r| r["vehicle"] == v && r["kind"] == kind)
                .collect()
        };
        let time = |r: &Value| r["time_unix"].as_f64().expect("time");

        // FOLLOW_TARGET: ≥ 9 Hz, the track's position and variances (NED order).
        let follow = of(11, "follow");
        assert!(follow.len() > 20, "{} FOLLOW_TARGET", follow.len());
        let span = time(follow[follow.len() - 1]) - time(follow[0]);
        let rate = (follow.len() - 1) as f64 / span;
        let mut worst = 0.0f64;
        for r in &follow {
            let p = enu(&frame, r);
            let recent: Vec<&Update> = updates
                .iter()
                .filter(|u| u.seen <= time(r) + 0.01)
                .rev()
                .take(3)
                .collect();
            let u = recent.first().expect("a track update before it");
            worst = worst.max((p.xy() - u.position.xy()).norm());
            let cov: Vec<f64> = r["cov"]
                .as_array()
                .expect("cov")
                .iter()
                .map(|c| c.as_f64().unwrap_or(f64::NAN))
                .collect();
            assert!(
                recent.iter().any(|u| {
                    (cov[0] - u.var[1]).abs() <= 1e-3 * u.var[1].max(1e-3)
                        && (cov[1] - u.var[0]).abs() <= 1e-3 * u.var[0].max(1e-3)
                }),
                "FOLLOW_TARGET position_cov {cov:?} is no recent track covariance {recent:?}"
            );
            assert_eq!(r["caps"], 3, "position and velocity");
        }
        eprintln!(
            "hand-off: FOLLOW_TARGET {} at {rate:.2} Hz, worst {worst:.2} m from the track",
            follow.len()
        );
        assert!(rate >= 9.0, "FOLLOW_TARGET at {rate} Hz");
        assert!(worst <= 5.0, "FOLLOW_TARGET {worst} m from the track");
        assert!(
            of(11, "mode")
                .iter()
                .any(|r| r["main"] == 4 && r["sub"] == 8),
            "switched to AUTO.FOLLOW_TARGET"
        );

        // DO_ORBIT: centred on the track, H above it, R counter-clockwise, the speed.
        let orbits = of(12, "orbit");
        assert!(orbits.len() >= 10, "{} DO_ORBIT", orbits.len());
        let mut worst = 0.0f64;
        for r in &orbits {
            let u = before(&updates, time(r) + 0.01).expect("a track update before it");
            let c = enu(&frame, r);
            worst = worst.max((c.xy() - u.position.xy()).norm());
            assert!((c.z - u.position.z - 40.0).abs() < 1.0, "{c} vs {u:?}");
            assert_eq!(
                (r["param1"].as_f64(), r["param2"].as_f64()),
                (Some(-60.0), Some(5.0))
            );
        }
        eprintln!(
            "hand-off: DO_ORBIT {}, worst centre {worst:.2} m from the track",
            orbits.len()
        );
        assert!(worst <= 5.0, "DO_ORBIT centred {worst} m from the track");

        // DO_SET_ROI_LOCATION within 100 ms of each update, at its estimate, to the gimbal.
        assert!(
            !of(13, "gimbal_request").is_empty(),
            "asked for GIMBAL_MANAGER_INFORMATION"
        );
        let rois = of(13, "roi");
        let first = time(rois.first().expect("an ROI"));
        let last = time(rois.last().expect("an ROI"));
        let mut lags = Vec::new();
        for u in updates
            .iter()
            .filter(|u| u.seen > first + 0.5 && u.seen < last - 0.2)
        {
            let r = rois
                .iter()
                .find(|r| {
                    time(r) >= u.seen - 0.05
                        && (enu(&frame, r).xy() - u.position.xy()).norm() < 0.05
                })
                .unwrap_or_else(|| panic!("no ROI for the update {u:?}"));
            lags.push(time(r) - u.seen);
        }
        let worst = lags.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        eprintln!(
            "hand-off: {} ROI for {} track updates, latest {:.1} ms after its update",
            rois.len(),
            lags.len(),
            worst * 1e3
        );
        assert!(lags.len() >= 40, "{} updates checked", lags.len());
        // Between the updates, the track predicted to now at 10 Hz.
        let rate = (rois.len() - 1) as f64 / (last - first);
        assert!(rate >= 9.0, "ROIs at {rate} Hz");
        assert!(worst <= 0.1, "an ROI {worst} s after its track update");
        let gimbal = rois.iter().filter(|r| r["param1"] == 154.0).count();
        assert!(
            gimbal * 10 >= rois.len() * 9,
            "{gimbal} of {} ROIs to the gimbal device",
            rois.len()
        );
        server.shutdown().await;
    }));
}

#[test]
fn the_simulators_camera_points_at_the_handed_target() {
    use harrier_sim::embedded::{SimWorld, WorldConfig, WorldVehicle};
    use harrier_sim::sensor_loop::SensorLoopConfig;
    use harrier_sim::setup::{Pointing, SensorType, SimScenario};

    runtime().block_on(within(150, "the camera hand-off", async {
        let mut scenario = SimScenario::load("crossing").expect("preset");
        for s in &mut scenario.sensors {
            if let SensorType::Camera { pointing, .. } = &mut s.model {
                *pointing = Pointing::Roi;
            }
        }
        let (mut config, zenoh) = server_config();
        config.mavlink.gcs = vec!["udpin:127.0.0.1:0".into()];
        let o = scenario.origin;
        config.frame.origin = GeoPoint::new(o.lat_deg, o.lon_deg, o.alt_m);
        config.frame.plane_z = scenario.plane_z();
        let server = harrier_server::start(&config)
            .await
            .expect("start the server");
        let gcs: SocketAddr = server
            .link()
            .and_then(|l| l.gcs().next().map(|e| e.addr()))
            .expect("a GCS link");
        let mut world = WorldConfig::new(SensorLoopConfig {
            scenario: scenario.clone(),
            seed: 4,
            speedup: 1.0,
            truth_hz: 10.0,
            clock: Default::default(),
        });
        world.vehicles = vec![WorldVehicle::at(1, [0.0, 0.0, 150.0])];
        world.zenoh.connect = vec![zenoh];
        world.gcs = Some(gcs);
        let world = tokio::task::spawn_blocking(move || SimWorld::start(&world))
            .await
            .expect("start")
            .expect("the world");
        let mut snapshot = server.snapshot();
        let track = within(100, "a confirmed track, the vehicle on station", async {
            loop {
                snapshot.changed().await.expect("snapshot");
                let k = snapshot
                    .borrow()
                    .tracks
                    .iter()
                    .find(|k| k.status == harrier_engine::TrackStatus::Confirmed && k.age >= 10)
                    .map(|k| k.id);
                if let (Some(k), true) = (k, world.on_station()) {
                    return k;
                }
            }
        })
        .await;
        server
            .guidance()
            .expect("guidance")
            .create(request(1, track, "handoff_camera"))
            .await
            .expect("the camera hand-off");
        let mut worst = 0.0f64;
        let mut checked = 0;
        for _ in 0..40 {
            tokio::time::sleep(Duration::from_millis(250)).await;
            let snap = server.snapshot().borrow().clone();
            let Some(k) = snap.tracks.iter().find(|k| k.id == track) else {
                continue;
            };
            let est = Vector3::new(k.state[0], k.state[1], k.state[2]);
            let (gimbal, p, at) = {
                let v = world.vehicles()[0].vehicle();
                let at = harrier_link::clock::unix_now();
                (v.gimbal_direction(), v.state().position, at)
            };
            let Some(gimbal) = gimbal else {
                continue;
            };
            // The truth target the track follows (the one nearest its estimate), as the
            // server has it in its frame, moved on at its velocity (the crossing's cars drive
            // straight) from its sample's time to the gimbal's.
            let addr = server.local_addr();
            let truth = tokio::task::spawn_blocking(move || {
                harrier_tests::http_get_json(addr, "/api/v1/truth").1
            })
            .await
            .expect("GET /truth");
            let car = truth["targets"]
                .as_array()
                .expect("targets")
                .iter()
                .filter_map(|t| {
                    let xyz = |k: &str| -> Option<Vector3<f64>> {
                        let c = t[k].as_array()?;
                        Some(Vector3::new(c[0].as_f64()?, c[1].as_f64()?, c[2].as_f64()?))
                    };
                    let dt = at - t["t"].as_f64()?;
                    Some(xyz("position")? + xyz("velocity")? * dt)
                })
                .min_by(|a, b| (a - est).norm().total_cmp(&(b - est).norm()))
                .expect("a target");
            let angle = gimbal.angle(&(car - p)).to_degrees();
            worst = worst.max(angle);
            checked += 1;
        }
        eprintln!("hand-off: camera within {worst:.3}° of its car over {checked} samples");
        assert!(checked >= 30, "{checked} samples");
        assert!(worst <= 1.0, "the camera points {worst}° off the car");
        server.shutdown().await;
        tokio::task::spawn_blocking(move || world.stop())
            .await
            .expect("stop");
    }));
}
