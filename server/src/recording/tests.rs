//! Tests of the recording: the writer on a real SQLite file ([`writer`]), and the reader, the
//! export and the command line on sessions the writer recorded ([`sessions`]); the records they
//! write are made by [`fixtures`].

/// Records for the tests.
mod fixtures {
    use harrier_core::detection::{DETECTIONS_SCHEMA, Detection, PlatformPose, TargetTruth};
    use harrier_core::detection::{DetectionScan, GeoPoint, TRUTH_SCHEMA, TruthSample};
    use harrier_core::measurement::MeasKind;

    use crate::engine::TrackView;
    use crate::recording::writer::{Record, SessionMeta};

    /// PX4 SITL's home (`live::config::DEFAULT_ORIGIN`), the session's origin.
    pub(super) const HOME: GeoPoint = GeoPoint {
        lat_deg: 47.397_742,
        lon_deg: 8.545_594,
        alt_m: 488.0,
    };
    /// UNIX time of the tests' scan time 0.
    pub(super) const T0_UNIX: f64 = 1_795_430_400.25;

    /// The session of a server at [`HOME`] on the ground plane z = 0.
    pub(super) fn meta(estimator: &str) -> SessionMeta {
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
    pub(super) fn scan(vehicle: u8, seq: u64, t: f64, pos: [f64; 3], z: &[[f64; 2]]) -> Record {
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
    pub(super) fn truth(t: f64, targets: &[(&str, [f64; 6])]) -> Record {
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
    pub(super) fn track(id: u64, t: f64, state: [f64; 6]) -> TrackView {
        TrackView {
            id,
            status: crate::engine::TrackStatus::Confirmed,
            t,
            state,
            cov: vec![vec![4.0, 0.0, 0.0, 0.0]; 4],
            cov_dims: vec![0, 1, 3, 4],
            updated: true,
            age: 3,
            last_update: t,
            mode_probabilities: vec![0.9, 0.1],
        }
    }
}

/// The writer.
mod writer {
    use std::path::Path;
    use std::time::{Duration, Instant};

    use rusqlite::Connection;

    use super::fixtures::*;
    use crate::recording::writer::{Record, Recorder, RecorderStats};

    fn count(conn: &Connection, sql: &str) -> i64 {
        conn.query_row(sql, [], |r| r.get(0)).expect(sql)
    }

    fn reader(path: &Path) -> Connection {
        Connection::open_with_flags(path, rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY)
            .expect("open read-only")
    }

    #[test]
    fn records_land_in_their_tables_and_a_second_open_is_a_new_session() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("sub/rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(50), 64).expect("open");
        assert_eq!(r.session_id(), 1);
        let clone = r.clone();
        clone.record(scan(
            1,
            0,
            0.0,
            [0.0, 0.0, 100.0],
            &[[10.0, 20.0], [30.0, -40.0]],
        ));
        r.record(truth(0.0, &[("T0", [10.0, 20.0, 0.0, 1.0, 0.0, 0.0])]));
        r.record(Record::Tracks {
            t: T0_UNIX,
            tracks: vec![
                track(1, T0_UNIX, [10.0, 20.0, 0.0, 1.0, 0.0, 0.0]),
                track(2, T0_UNIX, [30.0, -40.0, 0.0, 0.0, 0.0, 0.0]),
            ],
        });
        r.record(Record::Action {
            time_unix: T0_UNIX + 1.0,
            method: "POST".into(),
            path: "/api/v1/estimator".into(),
            body: r#"{"name":"imm"}"#.into(),
            status: 200,
        });
        let stats = clone.close().expect("close");
        assert_eq!(r.close().expect("idempotent"), stats);
        assert_eq!(
            (
                stats.scans,
                stats.detections,
                stats.track_rows,
                stats.truth_rows,
                stats.actions
            ),
            (1, 2, 2, 1, 1),
            "{stats:?}"
        );
        assert_eq!((stats.dropped, stats.errors), (0, 0));
        assert!(stats.commits >= 1 && stats.last_commit_unix.is_some());
        r.record(scan(1, 1, 1.0, [0.0; 3], &[]));
        assert_eq!(
            r.stats().dropped,
            1,
            "a record after close is dropped and counted"
        );

        let c = reader(&path);
        assert_eq!(count(&c, "SELECT count(*) FROM detections"), 2);
        assert_eq!(
            count(
                &c,
                "SELECT count(*) FROM tracks WHERE mode_probabilities = '[0.9,0.1]'"
            ),
            2
        );
        let (scans, ended, kind): (i64, Option<f64>, String) = c
            .query_row(
                "SELECT s.scans, s.ended_unix, k.kind FROM sessions s JOIN scans k \
                 ON k.session = s.id WHERE s.id = 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?, r.get(2)?)),
            )
            .expect("session row");
        assert_eq!(
            (scans, ended.is_some(), kind.as_str()),
            (1, true, "position")
        );
        let z1: f64 = c
            .query_row("SELECT z1 FROM detections WHERE idx = 1", [], |r| r.get(0))
            .expect("z1");
        assert_eq!(z1, -40.0);
        drop(c);

        let again =
            Recorder::open(&path, &meta("imm"), Duration::from_millis(50), 64).expect("reopen");
        assert_eq!(again.session_id(), 2);
        again.close().expect("close");
    }

    #[test]
    fn a_record_is_committed_within_the_flush_interval_without_close() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(50), 64).expect("open");
        let sent = Instant::now();
        r.record(scan(1, 0, 0.0, [0.0; 3], &[[1.0, 2.0]]));
        let c = reader(&path);
        while count(&c, "SELECT count(*) FROM scans") == 0 {
            assert!(
                sent.elapsed() < Duration::from_secs(5),
                "no commit within 5 s"
            );
            std::thread::sleep(Duration::from_millis(5));
        }
        let lag = sent.elapsed();
        assert!(lag < Duration::from_secs(1), "committed after {lag:?}");
        let (scans, last): (i64, Option<f64>) = c
            .query_row(
                "SELECT scans, last_received_unix FROM sessions WHERE id = 1",
                [],
                |r| Ok((r.get(0)?, r.get(1)?)),
            )
            .expect("summary");
        assert_eq!((scans, last), (1, Some(T0_UNIX + 0.01)));
        assert_eq!(r.stats().scans, 1);
        r.close().expect("close");
    }

    #[test]
    fn a_full_queue_drops_and_counts_and_never_blocks() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 4).expect("open");
        // Another connection holds the write lock: the writer waits on its first insert.
        let blocker = Connection::open(&path).expect("open");
        blocker.execute_batch("BEGIN IMMEDIATE").expect("lock");
        let n = 100;
        let start = Instant::now();
        for i in 0..n {
            r.record(scan(1, i, i as f64, [0.0; 3], &[]));
        }
        let took = start.elapsed();
        blocker.execute_batch("COMMIT").expect("unlock");
        let s = r.close().expect("close");
        assert!(
            took < Duration::from_millis(500),
            "record blocked: {took:?}"
        );
        assert_eq!(s.scans + s.dropped, n, "{s:?}");
        assert!(s.dropped >= n - 5, "queue of 4 (+1 in hand) but {s:?}");
        let dropped: i64 = reader(&path)
            .query_row("SELECT dropped FROM sessions WHERE id = 1", [], |r| {
                r.get(0)
            })
            .expect("dropped");
        assert_eq!(dropped as u64, s.dropped);
    }

    #[test]
    fn a_record_that_fails_half_way_leaves_no_row_and_is_counted() {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let r = Recorder::open(&path, &meta("ekf"), Duration::from_millis(20), 64).expect("open");
        // A real SQLite trigger refuses one detection: its scan fails after its scan row.
        Connection::open(&path)
            .and_then(|c| {
                c.execute_batch(
                    "CREATE TRIGGER refuse BEFORE INSERT ON detections WHEN NEW.z0 = 666 \
                     BEGIN SELECT RAISE(ABORT, 'refused by the test'); END;",
                )
            })
            .expect("trigger");
        r.record(scan(1, 0, 0.0, [0.0; 3], &[[1.0, 2.0]]));
        r.record(scan(2, 0, 0.0, [0.0; 3], &[[1.0, 2.0], [666.0, 0.0]]));
        r.record(scan(1, 1, 1.0, [0.0; 3], &[[3.0, 4.0]]));
        let s = r.close().expect("close");
        assert_eq!((s.scans, s.detections, s.errors), (2, 2, 1), "{s:?}");
        let c = reader(&path);
        assert_eq!(count(&c, "SELECT count(*) FROM scans"), 2);
        assert_eq!(count(&c, "SELECT count(*) FROM detections"), 2);
        assert_eq!(count(&c, "SELECT count(*) FROM scans WHERE vehicle = 2"), 0);
        assert_eq!(
            count(&c, "SELECT count(*) FROM sensors"),
            1,
            "vehicle 2's sensor row went with its scan"
        );
        assert_eq!(count(&c, "SELECT scans FROM sessions"), 2);
    }

    #[test]
    fn other_files_are_refused_with_their_path() {
        let dir = tempfile::tempdir().expect("tempdir");
        let other = dir.path().join("other.sqlite");
        Connection::open(&other)
            .and_then(|c| c.execute_batch("CREATE TABLE t (x)"))
            .expect("other db");
        let e = Recorder::open(&other, &meta("ekf"), Duration::from_millis(50), 4)
            .expect_err("not ours");
        assert!(
            e.to_string().contains("other.sqlite") && e.to_string().contains("not a Harrier"),
            "{e}"
        );
        let text = dir.path().join("notes.txt");
        std::fs::write(
            &text,
            "not a database, just some text that is long enough ".repeat(20),
        )
        .expect("write");
        let e = Recorder::open(&text, &meta("ekf"), Duration::from_millis(50), 4)
            .expect_err("not sqlite");
        assert!(e.to_string().contains("notes.txt"), "{e}");
    }

    /// Writes `n` scans (one detection each) and `n` track rows as fast as they can be queued;
    /// returns the seconds from the first record to the end of `close`.
    fn burst(n: u64) -> (f64, RecorderStats) {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("rec.sqlite");
        let queue = usize::try_from(2 * n).expect("queue");
        let r =
            Recorder::open(&path, &meta("ekf"), Duration::from_millis(200), queue).expect("open");
        let start = Instant::now();
        for i in 0..n {
            let t = i as f64 * 0.002;
            let v = (i % 10) as u8 + 1;
            r.record(scan(v, i / 10, t, [0.0, 0.0, 100.0], &[[t, 2.0 * t]]));
            r.record(Record::Tracks {
                t: T0_UNIX + t,
                tracks: vec![track(1, T0_UNIX + t, [t, 2.0 * t, 0.0, 1.0, 2.0, 0.0])],
            });
        }
        let s = r.close().expect("close");
        (start.elapsed().as_secs_f64(), s)
    }

    #[test]
    fn the_writer_keeps_up_with_ten_vehicles_at_50_hz() {
        // 5000 scans = 10 s of 10 vehicles × 50 Hz, with a detection and a track row each.
        let (secs, s) = burst(5000);
        let rows = s.scans + s.detections + s.track_rows;
        eprintln!(
            "recorder: {} scans + {} detections + {} track rows in {secs:.3} s: {:.0} scans/s, \
             {:.0} rows/s, {} commits",
            s.scans,
            s.detections,
            s.track_rows,
            s.scans as f64 / secs,
            rows as f64 / secs,
            s.commits
        );
        assert_eq!((s.scans, s.dropped, s.errors), (5000, 0, 0), "{s:?}");
        assert!(
            s.scans as f64 / secs > 500.0,
            "only {:.0} scans/s",
            s.scans as f64 / secs
        );
    }

    /// `cargo test -p harrier-server --lib bench_recorder -- --ignored --nocapture`
    #[test]
    #[ignore = "benchmark"]
    fn bench_recorder_burst() {
        let (secs, s) = burst(50_000);
        let rows = s.scans + s.detections + s.track_rows;
        eprintln!(
            "recorder burst: {rows} rows in {secs:.2} s = {:.0} rows/s ({:.0} scans/s with a \
             detection and a track row each), {} commits",
            rows as f64 / secs,
            s.scans as f64 / secs,
            s.commits
        );
    }
}

/// The reader, the export and the command line.
mod sessions {
    use std::path::{Path, PathBuf};
    use std::time::Duration;

    use harrier_core::detection::GeoPoint;
    use harrier_core::scenario as fmt;
    use harrier_core::tracker::format::MultiScenario;
    use harrier_link::geo::LocalFrame;
    use nalgebra::Vector3;
    use rusqlite::Connection;

    use super::fixtures::{HOME, T0_UNIX, meta, scan, track, truth};
    use crate::recording::cli::{SessionsArgs, SessionsCommand, run};
    use crate::recording::export::export;
    use crate::recording::reader::{SessionError, info, list};
    use crate::recording::writer::{Record, Recorder};

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

        let report = crate::replay::run(&data, "kf", &crate::engine::Params::default())
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
        let r = crate::replay::run(&data, "tracker", &crate::engine::Params::default())
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

        let empty = Recorder::open(&db, &meta("imm"), Duration::from_millis(20), 16)
            .expect("second session");
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
                out_dir: out.clone(),
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
            out_dir: out.clone(),
        };
        let e = run(&SessionsArgs { command: again }).expect_err("not empty");
        assert!(e.to_string().contains("session1"), "{e}");
    }
}
