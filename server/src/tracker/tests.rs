use super::*;
use crate::config::{Config, DEFAULT_ORIGIN};
use harrier_core::measurement::{Geometry, MeasKind, SensorModel};
use harrier_engine::SensorScan;
use nalgebra::Vector3;

fn scan(t: f64, vehicle: &str) -> ReadyScan {
    let sensor = SensorModel::new(
        MeasKind::Position,
        Geometry::planar(0.0),
        Vector3::zeros(),
        &[10.0, 10.0],
        None,
    )
    .expect("model");
    ReadyScan {
        vehicle: vehicle.into(),
        sensor: "cam".into(),
        scan: SensorScan {
            t,
            sensor,
            detections: vec![vec![100.0 + t, 50.0]],
        },
        platform: [0.0; 3],
        platform_vel: [0.0; 3],
        geodetic: DEFAULT_ORIGIN,
        received: std::time::Instant::now(),
        noise_std: vec![10.0, 10.0],
    }
}

type Parts = (
    TrackerActor,
    Arc<Metrics>,
    watch::Receiver<Arc<Snapshot>>,
    broadcast::Receiver<Arc<ScanEvents>>,
);

fn actor(window: f64) -> Parts {
    actor_of(&Config::default(), window)
}

fn actor_of(c: &Config, window: f64) -> Parts {
    let deployment = c.deployment();
    let engine = harrier_engine::registry::build_track_filter("ekf", &deployment, &c.params())
        .expect("engine");
    let metrics = Arc::new(Metrics::default());
    let (snap_tx, snap_rx) = watch::channel(Arc::new(Snapshot::default()));
    let (ev_tx, ev_rx) = broadcast::channel(16);
    let a = TrackerActor::new(
        engine,
        deployment,
        TrackFilterState {
            name: "ekf".into(),
            associator: "gnn".into(),
            params: BTreeMap::new(),
        },
        window,
        Arc::clone(&metrics),
        Arc::new(Recent::default()),
        snap_tx,
        ev_tx,
    );
    (a, metrics, snap_rx, ev_rx)
}

/// The published tracks, kept from the scans' outcomes, are the engine's snapshot.
fn in_step(a: &TrackerActor, snap_rx: &watch::Receiver<Arc<Snapshot>>) {
    assert_eq!(*snap_rx.borrow().tracks, a.engine.snapshot());
}

#[test]
fn scans_are_reordered_within_the_window_and_late_ones_dropped() {
    let (mut a, metrics, snap_rx, mut ev_rx) = actor(2.0);
    a.push(scan(0.0, "1")); // a lone source: processed at once
    assert_eq!(snap_rx.borrow().t, Some(0.0));
    a.push(scan(0.0, "2")); // a second source, same time: in order
    assert_eq!(snap_rx.borrow().seq, 2);
    a.push(scan(1.0, "1")); // waits for source 2 …
    assert_eq!(snap_rx.borrow().t, Some(0.0));
    a.push(scan(0.8, "2")); // … which is behind: 0.8 first, 1.0 still waits
    assert_eq!(snap_rx.borrow().t, Some(0.8));
    a.push(scan(1.1, "2")); // source 2 caught up: 1.0 goes
    assert_eq!(snap_rx.borrow().t, Some(1.0));
    in_step(&a, &snap_rx);
    let seqs: Vec<_> = std::iter::from_fn(|| ev_rx.try_recv().ok())
        .map(|e| (e.seq, e.t))
        .collect();
    assert_eq!(seqs, [(1, 0.0), (2, 0.0), (3, 0.8), (4, 1.0)]);
    a.push(scan(2.0, "1")); // 1.1 goes, 2.0 waits for source 2
    assert_eq!(snap_rx.borrow().t, Some(1.1));
    a.push(scan(3.5, "1")); // source 2 silent for > 2 s: forgotten, nothing waits for it
    assert_eq!(snap_rx.borrow().t, Some(3.5));
    a.push(scan(3.0, "2")); // older than the last processed: late
    assert_eq!(
        metrics.vehicle_counters("2").dropped.get(&DropReason::Late),
        Some(&1)
    );
    a.release(f64::INFINITY);
    in_step(&a, &snap_rx);
    assert_eq!(snap_rx.borrow().seq, 7);
    assert_eq!(metrics.scans_ingested(), 7);
    assert!(!snap_rx.borrow().tracks.is_empty());
    let vehicles: Vec<_> = snap_rx
        .borrow()
        .vehicles
        .iter()
        .map(|v| (v.vehicle.clone(), v.scans))
        .collect();
    assert_eq!(vehicles, [("1".to_string(), 4), ("2".to_string(), 3)]);
    assert_eq!(a.recent.scans_after(4).len(), 3);
    let first = crate::wire::scan_json(&a.recent.scans_after(0)[0]).to_owned();
    assert!(first.contains(r#""type":"scan""#), "{first}");
}

/// Within the lag, a scan older than the last processed one updates its track by
/// retrodiction (the tracks' time stays); beyond it, it is dropped as late.
#[test]
fn late_scans_within_the_lag_are_retrodicted() {
    let (a, metrics, snap_rx, mut ev_rx) = actor(0.1);
    let mut a = a.with_late_lag(2.0);
    for k in 0..=5 {
        a.push(scan(f64::from(k), "1"));
    }
    assert_eq!(snap_rx.borrow().t, Some(5.0));
    let before = snap_rx.borrow().tracks[0].clone();
    while ev_rx.try_recv().is_ok() {}
    a.push(scan(4.5, "2"));
    let late = ev_rx.try_recv().expect("the late scan's events");
    assert!(
        matches!(late.events[..], [TrackEvent::Updated { id, .. }] if id == before.id),
        "{:?}",
        late.events
    );
    assert_eq!(late.t, 4.5);
    assert_eq!(snap_rx.borrow().t, Some(5.0));
    let after = snap_rx.borrow().tracks[0].clone();
    assert_eq!(after.t, 5.0);
    assert_ne!(after.state, before.state);
    assert_eq!(metrics.vehicle_counters("2").retrodicted, 1);
    a.push(scan(2.5, "2"));
    assert_eq!(
        metrics.vehicle_counters("2").dropped.get(&DropReason::Late),
        Some(&1)
    );
    assert_eq!(metrics.scans_ingested(), 7);
    in_step(&a, &snap_rx);
}

#[test]
fn a_change_of_estimator_keeps_the_tracks() {
    let (mut a, _, snap_rx, _) = actor(0.0);
    for k in 0..4 {
        a.push(scan(f64::from(k), "1"));
    }
    a.release(f64::INFINITY);
    let before = snap_rx.borrow().tracks.clone();
    assert_eq!(before.len(), 1);
    let bad = a.set_estimator(TrackFilterState {
        name: "nonesuch".into(),
        associator: "gnn".into(),
        params: BTreeMap::new(),
    });
    assert!(
        matches!(bad, Err(SetError::Invalid(ref m)) if m.contains("nonesuch")),
        "{bad:?}"
    );
    let bad = a.set_estimator(TrackFilterState {
        name: "cdkf".into(),
        associator: "gnn".into(),
        params: BTreeMap::from([("m".to_string(), 0.5)]),
    });
    assert!(matches!(bad, Err(SetError::Invalid(_))), "{bad:?}");
    assert_eq!(snap_rx.borrow().estimator.name, "ekf");
    let now = a
        .set_estimator(TrackFilterState {
            name: "cdkf".into(),
            associator: "gnn".into(),
            params: BTreeMap::new(),
        })
        .expect("cdkf");
    assert_eq!(now.name, "cdkf");
    let after = snap_rx.borrow().tracks.clone();
    in_step(&a, &snap_rx);
    assert_eq!(snap_rx.borrow().estimator.name, "cdkf");
    assert_eq!(after.len(), 1);
    assert_eq!(
        (after[0].id, after[0].status),
        (before[0].id, before[0].status)
    );
    assert_eq!(after[0].state, before[0].state);
    a.push(scan(4.0, "1"));
    a.release(f64::INFINITY);
    in_step(&a, &snap_rx);
    let k = snap_rx.borrow().tracks[0].clone();
    assert_eq!((k.id, k.updated), (before[0].id, true));
    assert_eq!(k.existence, None);
    // The associator too: the track keeps its id and gets an existence.
    let now = a
        .set_estimator(TrackFilterState {
            name: "cdkf".into(),
            associator: "jipda".into(),
            params: BTreeMap::new(),
        })
        .expect("cdkf + jipda");
    assert_eq!(now.associator, "jipda");
    a.push(scan(5.0, "1"));
    a.release(f64::INFINITY);
    in_step(&a, &snap_rx);
    let k = snap_rx.borrow().tracks[0].clone();
    assert_eq!((k.id, k.updated), (before[0].id, true));
    assert!(k.existence.is_some_and(|p| p > 0.5), "{k:?}");
    let bad = a.set_estimator(TrackFilterState {
        name: "cdkf".into(),
        associator: "nonesuch".into(),
        params: BTreeMap::new(),
    });
    assert!(matches!(bad, Err(SetError::Invalid(_))), "{bad:?}");
}

/// With registration on, a scan's cooperative references are the link's other vehicles, each
/// GPS position moved along its velocity from its arrival to the scan's time (a UAV at 15 m/s
/// moves 1.5 m in a tenth of a second); the scan's own vehicle, a position more than 2 s from the
/// scan and a lost vehicle are none.
#[test]
fn references_are_the_other_vehicles_at_the_scans_time() {
    use crate::config::RegistrationSensor;
    use crate::gcs::transport::Peer;
    use crate::gcs::vehicle::VehicleLink;
    use harrier_link::geo::LocalFrame;
    use harrier_link::mavlink::MavHeader;
    use harrier_link::mavlink::dialects::common::{GLOBAL_POSITION_INT_DATA, MavMessage};

    let mut c = Config::default();
    c.registration.sensors = vec![RegistrationSensor {
        vehicle: "1".into(),
        sensor: "radar".into(),
        kind: MeasKind::RangeBearing,
        bias: None,
    }];
    let (mut a, ..) = actor_of(&c, 0.1);
    assert!(a.references("1", 1000.0).is_empty(), "no link yet");
    let frame = LocalFrame::new(c.frame.origin);
    let t0 = std::time::Instant::now();
    let peer = Peer::Udp(std::net::SocketAddr::from(([127, 0, 0, 1], 9)));
    // At the origin, 100 m up, flying North-East: NED (10, 10, 0) m/s.
    let position = MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        lat: (c.frame.origin.lat_deg * 1e7).round() as i32,
        lon: (c.frame.origin.lon_deg * 1e7).round() as i32,
        alt: ((c.frame.origin.alt_m + 100.0) * 1e3).round() as i32,
        relative_alt: 100_000,
        vx: 1000,
        vy: 1000,
        ..GLOBAL_POSITION_INT_DATA::DEFAULT
    });
    let sample = |id: u8, state: LinkState| {
        let mut v = VehicleLink::new(id, 0, peer, t0);
        let header = MavHeader {
            system_id: u32::from(id),
            component_id: 1,
            sequence: 0,
        };
        v.on_frame(&header, &position, t0, 0.0);
        let mut view = v.view(&frame, t0);
        view.state = state;
        VehicleSample {
            view,
            status: None,
            home_amsl: None,
            gimbal_manager: None,
            position_unix: Some(1000.0),
            confirmed: true,
            client_command: None,
        }
    };
    let vehicles = vec![
        sample(1, LinkState::Connected),
        sample(2, LinkState::Connected),
        sample(3, LinkState::Lost),
    ];
    let (_tx, rx) = watch::channel(Arc::new(vehicles));
    a.command(Command::References(rx));
    let r = a.references("1", 1000.5);
    assert_eq!(r.len(), 1, "{r:?}");
    let moved = Vector3::new(5.0, 5.0, 100.0);
    assert!((r[0].pos - moved).norm() < 0.01, "{:?}", r[0].pos);
    assert!((r[0].vel - Vector3::new(10.0, 10.0, 0.0)).norm() < 1e-9);
    // GPS_STD_M² plus the motion over the timing's uncertainty.
    let var = GPS_STD_M.powi(2) + (200f64.sqrt() * REFERENCE_TIMING_STD_S).powi(2);
    assert!((r[0].cov[(0, 0)] - var).abs() < 1e-9, "{:?}", r[0].cov);
    // Before its arrival too (a scan processed after the next frame).
    let r = a.references("2", 999.8);
    assert!((r[0].pos - Vector3::new(-2.0, -2.0, 100.0)).norm() < 0.01);
    assert!(a.references("1", 1002.5).is_empty(), "2.5 s from the scan");
}
