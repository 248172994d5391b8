//! Late scans over a real Zenoh session: three vehicles see one standing target at 5 Hz and
//! each scan reaches the live server after a random delay of up to 1.9 s (a radio link and a
//! mesh). With the default `tracker.late_lag_s` (2 s) every scan is tracked — those older than
//! the last processed one by retrodiction — none is dropped as late, and the one target has one
//! confirmed track where it stands.

use std::time::{Duration, Instant};

use harrier_core::detection::{
    DETECTIONS_SCHEMA, Detection, DetectionScan, PlatformPose, detections_key,
};
use harrier_server::config::{Config, DEFAULT_ORIGIN};
use harrier_server::metrics::DropReason;
use harrier_tests::{http_get, loopback_server, within, zenoh_client};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const VEHICLES: u8 = 3;
const HZ: f64 = 5.0;
const SCANS: u64 = 60;
const MAX_DELAY_S: f64 = 1.9;
const TARGET: [f64; 2] = [120.0, -60.0];

#[test]
fn scans_up_to_two_seconds_late_are_all_tracked() {
    let config = Config::default();
    assert_eq!(config.tracker.late_lag_s, 2.0, "the default lag");
    let (rt, server, endpoint) = loopback_server(config);

    rt.block_on(async {
        let session = zenoh_client(&endpoint).await;
        let mut publishers = Vec::new();
        for v in 1..=VEHICLES {
            let p = within(
                10,
                "declare a publisher",
                session.declare_publisher(detections_key(v)),
            )
            .await
            .expect("publisher");
            // Until the server's subscription has reached the publisher: no put is lost.
            within(10, "the server's subscription", async {
                while !p.matching_status().await.is_ok_and(|m| m.matching()) {
                    tokio::time::sleep(Duration::from_millis(10)).await;
                }
            })
            .await;
            publishers.push(std::sync::Arc::new(p));
        }
        // Scan k of every vehicle is made at k / HZ s and put after its own random delay.
        let start = tokio::time::Instant::now();
        let frame = harrier_link::geo::LocalFrame::new(DEFAULT_ORIGIN);
        let mut rng = ChaCha8Rng::seed_from_u64(20);
        let mut puts = Vec::new();
        for k in 0..SCANS {
            let t = k as f64 / HZ;
            for (i, p) in publishers.iter().enumerate() {
                let v = i as u8 + 1;
                let platform = [-200.0 + 150.0 * i as f64, 0.0, 50.0];
                let pos = nalgebra::Vector3::from(platform);
                let scan = DetectionScan {
                    schema: DETECTIONS_SCHEMA.into(),
                    t,
                    time_unix: None,
                    vehicle: v,
                    seq: k,
                    sensor: "cam".into(),
                    kind: harrier_core::measurement::MeasKind::Position,
                    origin: DEFAULT_ORIGIN,
                    platform: PlatformPose {
                        pos: platform,
                        vel: [0.0; 3],
                        attitude: [0.0; 3],
                        geodetic: Some(frame.from_enu(&pos)),
                    },
                    noise_std: vec![3.0, 3.0],
                    detections: vec![Detection {
                        z: vec![
                            TARGET[0] + rng.random_range(-3.0..3.0),
                            TARGET[1] + rng.random_range(-3.0..3.0),
                        ],
                    }],
                };
                let at = start + Duration::from_secs_f64(t + rng.random_range(0.0..MAX_DELAY_S));
                let p = std::sync::Arc::clone(p);
                puts.push(tokio::spawn(async move {
                    tokio::time::sleep_until(at).await;
                    p.put(scan.to_json()).await.expect("put");
                }));
            }
        }
        for put in puts {
            within(30, "the delayed puts", put).await.expect("put task");
        }
        let _ = session.close().await;
    });

    // Every scan is either ingested or dropped, then counted.
    let metrics = server.metrics();
    let count = |f: &dyn Fn(&harrier_server::metrics::VehicleCounters) -> u64| {
        (1..=VEHICLES)
            .map(|v| f(&metrics.vehicle_counters(&v.to_string())))
            .sum::<u64>()
    };
    let all = u64::from(VEHICLES) * SCANS;
    let deadline = Instant::now() + Duration::from_secs(15);
    while count(&|c| c.ingested + c.dropped.values().sum::<u64>()) < all {
        assert!(
            Instant::now() < deadline,
            "only {} of {all} scans ingested or dropped",
            count(&|c| c.ingested + c.dropped.values().sum::<u64>())
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let late = count(&|c| c.dropped.get(&DropReason::Late).copied().unwrap_or(0));
    let dropped = count(&|c| c.dropped.values().sum());
    let retrodicted = count(&|c| c.retrodicted);
    let ingested = count(&|c| c.ingested);
    eprintln!(
        "late_scans: {all} scans delayed by up to {MAX_DELAY_S} s: {ingested} ingested \
         ({retrodicted} retrodicted), {late} dropped as late, {dropped} dropped in all"
    );
    assert_eq!(late, 0);
    assert_eq!(dropped, 0);
    assert_eq!(ingested, all);
    // The delays reorder the vehicles' scans: many come after newer ones.
    assert!(
        retrodicted * 4 >= all,
        "only {retrodicted} of {all} came late"
    );

    // One target, one confirmed track where it stands, at the newest scan's time.
    let snap = server.snapshot().borrow().clone();
    let confirmed: Vec<_> = snap
        .tracks
        .iter()
        .filter(|k| k.status == harrier_engine::TrackStatus::Confirmed)
        .collect();
    assert_eq!(confirmed.len(), 1, "{:?}", snap.tracks);
    let k = confirmed[0];
    let err = (k.state[0] - TARGET[0]).hypot(k.state[1] - TARGET[1]);
    assert!(err < 3.0, "the track is {err:.2} m from the target");
    assert_eq!(snap.t, Some((SCANS - 1) as f64 / HZ));

    // The counters are on the Prometheus endpoint.
    let (status, text) = http_get(server.local_addr(), "/api/v1/metrics");
    assert_eq!(status, 200);
    for v in 1..=VEHICLES {
        let c = metrics.vehicle_counters(&v.to_string());
        let line = format!(
            "harrier_scans_retrodicted_total{{vehicle=\"{v}\"}} {}",
            c.retrodicted
        );
        assert!(text.contains(&line), "{line} not in /api/v1/metrics");
        assert!(
            text.contains(&format!("harrier_scans_late_total{{vehicle=\"{v}\"}} 0")),
            "{text}"
        );
    }
    rt.block_on(server.shutdown());
}
