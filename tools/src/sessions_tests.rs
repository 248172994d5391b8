//! Tests of `harrier sessions` and what it runs: the reader, the export and the command line
//! on sessions harrier-recording's writer recorded, exported and replayed.

use std::path::{Path, PathBuf};
use std::time::Duration;

use harrier_core::detection::GeoPoint;
use harrier_core::scenario as fmt;
use harrier_core::tracker::format::MultiScenario;
use harrier_link::geo::LocalFrame;
use nalgebra::Vector3;
use rusqlite::Connection;

use super::{ExportFormat, SessionsArgs, SessionsCommand, run};
use harrier_recording::export::{export, mcap};
use harrier_recording::fixtures::{HOME, T0_UNIX, meta, scan, track, truth};
use harrier_recording::reader::{SessionError, info, list};
use harrier_recording::writer::{Record, Recorder};

/// Target `j` at time `t`: straight lines at 5–8 m/s on the ground plane.
fn state(t: f64, j: usize) -> [f64; 6] {
    let (p, v) = (
        [100.0 + 300.0 * j as f64, 200.0],
        [5.0, 3.0 + 5.0 * j as f64],
    );
    [p[0] + v[0] * t, p[1] + v[1] * t, 0.0, v[0], v[1], 0.0]
}

/// `r`, a scan, re-published in the ENU frame of `origin` (as a vehicle with another home
/// would): platform and 2-D fixes through ECEF.
fn moved(r: Record, origin: GeoPoint) -> Record {
    let Record::Scan {
        received_unix,
        mut scan,
    } = r
    else {
        return r;
    };
    let (from, to) = (LocalFrame::new(scan.origin), LocalFrame::new(origin));
    let p = from.enu_to_frame(&to, &Vector3::from(scan.platform.pos));
    scan.platform.pos = p.into();
    for d in &mut scan.detections {
        let q = from.enu_to_frame(&to, &Vector3::new(d.z[0], d.z[1], 0.0));
        d.z = vec![q.x, q.y];
    }
    scan.origin = origin;
    Record::Scan {
        received_unix,
        scan,
    }
}

/// A 40 s session of `targets` targets seen by the `position` cameras of vehicles 1 and 2 at
/// 1 Hz (detections within 3 m; vehicle 2 scans `late` s after vehicle 1 and publishes in a
/// frame some 300 m away), truth at 10 Hz, a track row per scan.
fn session(dir: &Path, targets: usize, late: f64) -> PathBuf {
    let path = dir.join("rec.sqlite");
    let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 4096).expect("open");
    let away = GeoPoint::new(HOME.lat_deg + 0.002, HOME.lon_deg + 0.003, HOME.alt_m + 5.0);
    for k in -5..=405 {
        let t = f64::from(k) * 0.1;
        let ids = ["T0", "T1", "T2"];
        let tr: Vec<(&str, [f64; 6])> = (0..targets).map(|j| (ids[j], state(t, j))).collect();
        r.record(truth(t, &tr));
    }
    for k in 0..=40_u64 {
        let t = k as f64;
        for v in [1_u8, 2] {
            let t = if v == 2 { t + late } else { t };
            let z: Vec<[f64; 2]> = (0..targets)
                .map(|j| {
                    let s = state(t, j);
                    let e = |i: u64| 3.0 * ((7 * k + 3 * j as u64 + 5 * i) as f64).sin();
                    [s[0] + e(u64::from(v)), s[1] + e(u64::from(v) + 1)]
                })
                .collect();
            let rec = scan(v, k, t, [f64::from(v) * 50.0, 0.0, 300.0], &z);
            r.record(if v == 2 { moved(rec, away) } else { rec });
        }
        r.record(Record::Tracks {
            t: T0_UNIX + t,
            tracks: vec![track(1, T0_UNIX + t, state(t, 0))],
        });
    }
    let s = r.close().expect("close");
    assert_eq!(s.dropped + s.errors, 0, "{s:?}");
    path
}

#[test]
fn a_single_target_session_lists_exports_replays_and_scores() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = session(dir.path(), 1, 0.0);
    let all = list(&db).expect("list");
    assert_eq!(all.len(), 1);
    let s = &all[0];
    assert_eq!(
        (s.id, s.scans, s.detections, s.track_rows, s.truth_rows),
        (1, 82, 82, 41, 411)
    );
    assert_eq!(s.vehicles, ["1", "2"]);
    assert_eq!(s.sensors, ["1/cam", "2/cam"]);
    assert!(s.ended_unix.is_some() && s.estimator == "ekf");
    assert_eq!(info(&db, 1).expect("info"), *s);

    let e = export(&db, 1).expect("export");
    assert!(!e.multi);
    assert_eq!((e.epoch, e.time_line.as_str()), (T0_UNIX, "time_unix"));
    assert_eq!((e.scans, e.lines, e.truth_rows), (82, 82, 41));
    assert_eq!(e.sensors, ["cam1", "cam2"]);
    let out = dir.path().join("export");
    e.write_to(&out).expect("write");
    let data = crate::replay::load(&out).expect("the export loads");
    let sc = &data.scenario;
    assert_eq!((sc.sensors.len(), sc.platforms.len()), (2, 2));
    assert_eq!(sc.sensors[1].rate_hz, Some(1.0));
    assert_eq!(sc.time.t_end, 40.0);
    assert_eq!(sc.target.id, "T0");
    assert_eq!(sc.motion.as_ref().and_then(|m| m.accel_std), Some(0.5));
    // Both vehicles' detections, in the session's frame, are within the 3 m of their noise.
    let truth = data.truth.as_ref().expect("truth");
    for m in &data.measurements {
        let (x, ..) = fmt::truth_at(truth, m.t).expect("truth at every scan");
        let err = (m.z[0] - x[0]).hypot(m.z[1] - x[1]);
        assert!(
            err < 3.0 * 2f64.sqrt() + 0.01,
            "{} at t {}: {err} m",
            m.sensor,
            m.t
        );
    }
    let prior = sc.prior.as_ref().expect("prior");
    assert_eq!((prior.t, prior.state[3]), (0.0, 0.0));
    assert!((prior.cov[0][0] - 400.0).abs() < 1e-9, "{:?}", prior.cov);

    let report = crate::replay::run(&data, "kf", &harrier_engine::Params::default())
        .expect("kf replays the export");
    assert!(report.rejected.is_empty(), "{:?}", report.rejected);
    assert_eq!(report.estimates.len(), 41);
    let rmse = report.score.and_then(|s| s.pos_rmse).expect("scored");
    assert!(rmse < 3.0, "kf position RMSE {rmse} m");
}

#[test]
fn several_targets_export_as_format_multi_and_replay_with_the_tracker() {
    let dir = tempfile::tempdir().expect("tempdir");
    // Vehicle 2 scans 15 ms after vehicle 1: its scans are snapped to the 1 s grid.
    let db = session(dir.path(), 2, 0.015);
    let e = export(&db, 1).expect("export");
    assert!(e.multi && e.lines == 164 && e.truth_rows == 82, "{e:?}");
    assert!(
        e.max_time_shift_s > 0.005 && e.max_time_shift_s < 0.015,
        "{e:?}"
    );
    assert!(
        (e.epoch - T0_UNIX - 0.0075).abs() < 1e-6,
        "{}",
        e.epoch - T0_UNIX
    );
    let m = MultiScenario::parse(
        &e.scenario_json,
        &e.measurements_jsonl,
        e.truth_csv.as_deref(),
    )
    .expect("a valid FORMAT-MULTI scenario");
    assert_eq!(m.targets.len(), 2);
    assert_eq!((m.scans.len(), m.scenario.time.dt), (41, 1.0));
    assert!(m.scans.iter().all(|s| s.detections.len() == 4));
    assert!(m.scenario.prior.is_none());
    let out = dir.path().join("multi");
    e.write_to(&out).expect("write");
    let data = crate::replay::load(&out).expect("loads");
    let r = crate::replay::run(&data, "tracker", &harrier_engine::Params::default())
        .expect("the tracker replays it");
    let last = r.estimates.last().expect("estimates");
    let tracks = serde_json::to_value(last).expect("json")["tracks"].clone();
    assert_eq!(tracks.as_array().map(Vec::len), Some(2), "{tracks}");
}

#[test]
fn errors_name_the_file_the_session_and_the_row() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = session(dir.path(), 1, 0.0);
    let e = info(&db, 99).expect_err("no such session");
    assert!(matches!(e, SessionError::NotFound { id: 99, .. }), "{e}");
    assert!(e.to_string().ends_with("rec.sqlite: no session 99"), "{e}");
    assert!(matches!(
        export(&db, 99),
        Err(SessionError::NotFound { .. })
    ));

    let missing = dir.path().join("missing.sqlite");
    let e = list(&missing).expect_err("missing");
    assert!(e.to_string().contains("missing.sqlite: cannot open"), "{e}");
    assert!(e.to_string().contains("no such file"), "{e}");
    assert!(!e.to_string().contains("Invalid path"), "{e}");
    let other = dir.path().join("other.sqlite");
    Connection::open(&other)
        .and_then(|c| c.execute_batch("CREATE TABLE t (x)"))
        .expect("other db");
    let e = list(&other).expect_err("not ours");
    assert!(matches!(e, SessionError::NotSessionFile { .. }), "{e}");
    assert!(
        e.to_string()
            .contains("other.sqlite: not a Harrier session file"),
        "{e}"
    );

    let rw = Connection::open(&db).expect("open");
    rw.execute("UPDATE scans SET json = '{\"schema\": 1' WHERE id = 3", [])
        .expect("corrupt");
    let e = export(&db, 1).expect_err("malformed");
    assert!(matches!(e, SessionError::Malformed { id: 1, .. }), "{e}");
    assert!(
        e.to_string()
            .contains("session 1: scans row 3: malformed detections"),
        "{e}"
    );
    rw.execute(
        "UPDATE scans SET json = (SELECT json FROM scans WHERE id = 4) WHERE id = 3",
        [],
    )
    .expect("repair");
    rw.execute(
        "UPDATE scans SET json = replace(json, '[10.0,10.0]', '[10.0,-1.0]') WHERE id = 5",
        [],
    )
    .expect("invalid noise");
    let e = export(&db, 1).expect_err("invalid");
    assert!(
        e.to_string().contains("scans row 5") && e.to_string().contains("noise_std"),
        "{e}"
    );
    rw.execute("UPDATE sessions SET config_json = 'nope' WHERE id = 1", [])
        .expect("update");
    let e = export(&db, 1).expect_err("config");
    assert!(
        e.to_string()
            .contains("session 1: sessions row: config_json"),
        "{e}"
    );
    drop(rw);

    let empty =
        Recorder::open(&db, &meta("imm"), Duration::from_millis(20), 16).expect("second session");
    empty.close().expect("close");
    let e = export(&db, 2).expect_err("no scans");
    assert!(
        e.to_string()
            .contains("session 2: cannot export: it has no scans"),
        "{e}"
    );
}

#[test]
fn the_command_line_lists_and_exports() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = session(dir.path(), 1, 0.0);
    let out = dir.path().join("out/session1");
    for command in [
        SessionsCommand::List {
            db: db.clone(),
            json: false,
        },
        SessionsCommand::List {
            db: db.clone(),
            json: true,
        },
        SessionsCommand::Info {
            db: db.clone(),
            id: 1,
            json: false,
        },
        SessionsCommand::Export {
            db: db.clone(),
            id: 1,
            out: out.clone(),
            format: ExportFormat::Scenario,
        },
    ] {
        run(&SessionsArgs { command }).expect("runs");
    }
    for f in ["scenario.json", "measurements.jsonl", "truth.csv"] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let again = SessionsCommand::Export {
        db,
        id: 1,
        out: out.clone(),
        format: ExportFormat::Scenario,
    };
    let e = run(&SessionsArgs { command: again }).expect_err("not empty");
    assert!(e.to_string().contains("session1"), "{e}");
}

#[test]
fn an_mcap_export_holds_a_message_per_scan_and_track_row_as_the_mcap_crate_reads_it() {
    let dir = tempfile::tempdir().expect("tempdir");
    let db = session(dir.path(), 2, 0.0);
    let out = dir.path().join("session1.mcap");
    let e = mcap(&db, 1, &out).expect("exports");
    let c = Connection::open(&db).expect("open");
    let count = |sql: &str| -> u64 {
        let n: i64 = c.query_row(sql, [], |r| r.get(0)).expect(sql);
        u64::try_from(n).expect("a count")
    };
    let scans = count("SELECT count(*) FROM scans");
    let groups = count("SELECT count(DISTINCT t) FROM tracks");
    let confirmed = count("SELECT count(*) FROM tracks WHERE status = 'confirmed'");
    assert!(scans > 0 && groups > 0 && confirmed > 0);
    let bytes = std::fs::read(&out).expect("read");
    let mut read: std::collections::BTreeMap<String, u64> = Default::default();
    let mut last = 0;
    let mut encodings = std::collections::BTreeSet::new();
    for m in mcap::MessageStream::new(&bytes).expect("an MCAP file") {
        let m = m.expect("a whole message");
        *read.entry(m.channel.topic.clone()).or_default() += 1;
        assert!(m.log_time >= last, "in time order");
        last = m.log_time;
        let schema = m.channel.schema.as_ref().expect("a schema");
        encodings.insert((schema.encoding.clone(), m.channel.message_encoding.clone()));
    }
    let want = [
        ("/harrier/detections", scans),
        ("/harrier/vehicles/location", scans),
        ("/tf", scans),
        ("/harrier/tracks", groups),
        ("/harrier/tracks/location", confirmed),
    ];
    for (topic, n) in want {
        assert_eq!(read.get(topic).copied(), Some(n), "{topic}: {read:?}");
        assert_eq!(e.messages[topic], n, "{topic}");
    }
    assert_eq!(
        encodings.into_iter().collect::<Vec<_>>(),
        [("protobuf".to_owned(), "protobuf".to_owned())]
    );
    // The log times are the tracker's UNIX times.
    assert!((last as f64 / 1e9 - (T0_UNIX + 40.0)).abs() < 1.0, "{last}");
    assert!(!dir.path().join("session1.mcap.partial").exists());
    // An existing file is refused, and left alone.
    let again = SessionsCommand::Export {
        db,
        id: 1,
        out: out.clone(),
        format: ExportFormat::Mcap,
    };
    let err = run(&SessionsArgs { command: again }).expect_err("exists");
    assert!(err.to_string().contains("session1.mcap"), "{err}");
    assert_eq!(std::fs::read(&out).expect("read"), bytes);
}
