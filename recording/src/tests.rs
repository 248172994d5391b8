//! Tests of the recording's writer on a real SQLite file ([`writer`]), with the records of
//! [`crate::fixtures`]. The reader and the export are tested with harrier-tools' `sessions`.

/// The writer.
mod writer {
    use std::path::Path;
    use std::time::{Duration, Instant};

    use rusqlite::Connection;

    use crate::fixtures::*;
    use crate::writer::{Record, Recorder, RecorderStats};

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

    /// `cargo test -p harrier-recording --lib bench_recorder -- --ignored --nocapture`
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
