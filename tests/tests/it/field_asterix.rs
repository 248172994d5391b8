//! ASTERIX out (`[asterix]`, docs/asterix.md): the live server sends its tracks as CAT062 over
//! UDP to `tests/python/asterix_listen.py`, which decodes every datagram with two independent
//! decoders (aviconv-asterix and asterix4py's ed. 1.18 definition) and prints each record.
//! Detections of two standing targets are published on Zenoh (10 scans/s each); the feed runs at
//! 5 Hz. Every datagram must be one CAT062 block both decoders read, agreeing; each record's
//! WGS-84 (I062/105) and Cartesian (I062/100) positions must be within 1 m of the track the
//! snapshot held at the record's time of track (I062/070), and its velocity (I062/185) within
//! 0.25 m/s.

use std::collections::HashMap;
use std::io::{BufRead as _, BufReader};
use std::process::Stdio;
use std::sync::{Arc, Mutex, mpsc};
use std::time::Duration;

use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_tests::{
    http_get, kill_group, open_session, publish_standing_target, python_script, runtime,
    server_config, within,
};
use serde_json::Value;

/// Datagrams the listener waits for.
const DATAGRAMS: usize = 20;

/// A track as the snapshot held it: x, y, vx, vy.
type Held = [f64; 4];
/// Every estimate of every snapshot, by (track id, time of day in 1/128 s).
type History = Arc<Mutex<HashMap<(u64, i64), Vec<Held>>>>;

#[test]
fn cat062_tracks_decode_where_the_tracker_has_them() {
    let mut listener = python_script("asterix_listen.py")
        .args(["--datagrams", &DATAGRAMS.to_string(), "--timeout", "60"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start asterix_listen.py");
    let out = listener.stdout.take().expect("stdout");
    let (tx, rx) = mpsc::channel::<Value>();
    std::thread::spawn(move || {
        for line in BufReader::new(out).lines().map_while(Result::ok) {
            if let Ok(v) = serde_json::from_str::<Value>(&line)
                && tx.send(v).is_err()
            {
                return;
            }
        }
    });
    let Ok(ready) = rx.recv_timeout(Duration::from_secs(20)) else {
        kill_group(&mut listener);
        panic!("asterix_listen.py did not say it listens");
    };
    let port = ready["ready"].as_u64().expect("ready port");

    let (mut config, zenoh) = server_config();
    config.zenoh.tracks_key = String::new();
    config.asterix.enabled = true;
    config.asterix.hz = 5.0;
    config.asterix.destination = format!("127.0.0.1:{port}");
    config.asterix.sac = 25;
    config.asterix.sic = 201;
    config.asterix.service_id = 3;
    let frame = LocalFrame::new(config.frame.origin);

    let rt = runtime();
    let (server, session, publishers, history) = rt.block_on(async {
        let server = within(20, "start the server", harrier_server::start(&config))
            .await
            .expect("start the live server");
        // Every snapshot the tracker publishes, by (track id, time of day in 1/128 s).
        // Scans of both vehicles can fall into the same 1/128 s: every estimate is kept.
        let history: History = Arc::default();
        let mut snapshot = server.snapshot();
        let h = Arc::clone(&history);
        tokio::spawn(async move {
            loop {
                {
                    let s = snapshot.borrow_and_update();
                    let mut h = h.lock().expect("history");
                    for t in s.tracks.iter() {
                        let key = (t.id, (t.t.rem_euclid(86_400.0) * 128.0).round() as i64);
                        let held = [t.state[0], t.state[1], t.state[3], t.state[4]];
                        let v = h.entry(key).or_default();
                        if !v.contains(&held) {
                            v.push(held);
                        }
                    }
                }
                if snapshot.changed().await.is_err() {
                    return;
                }
            }
        });
        let session = open_session(vec![zenoh]).await;
        let publishers = vec![
            publish_standing_target(&session, 1, [80.0, 30.0], [0.0, 0.0, 30.0], 10.0).await,
            publish_standing_target(&session, 2, [-150.0, 220.0], [0.0, 100.0, 30.0], 10.0).await,
        ];
        (server, session, publishers, history)
    });

    let mut records = Vec::new();
    let done = loop {
        let Ok(v) = rx.recv_timeout(Duration::from_secs(70)) else {
            kill_group(&mut listener);
            panic!("asterix_listen.py did not finish");
        };
        if let Some(r) = v.get("record") {
            records.push(r.clone());
        } else if let Some(d) = v.get("done") {
            break d.clone();
        }
    };
    let _ = listener.wait();
    let datagrams_sent = server.feed_counters().get("asterix", "datagrams");
    let (_, metrics) = http_get(server.local_addr(), "/api/v1/metrics");
    assert!(
        metrics.contains("harrier_feed_events_total{feed=\"asterix\",event=\"datagrams\"}"),
        "{metrics}"
    );
    for p in publishers {
        p.abort();
    }
    rt.block_on(async {
        let _ = session.close().await;
        server.shutdown().await;
    });

    eprintln!("asterix_listen.py: {done}");
    assert_eq!(done["datagrams"], DATAGRAMS, "{done}");
    assert_eq!(done["decode_errors"], 0, "{done}");
    assert_eq!(done["disagreements"], 0, "{done}");
    assert_eq!(done["blocks"], DATAGRAMS, "every datagram one block");
    assert!(datagrams_sent >= DATAGRAMS as u64, "{datagrams_sent} sent");
    assert!(records.len() >= DATAGRAMS, "{} records", records.len());

    let history = history.lock().expect("history");
    let (mut matched, mut worst_wgs, mut worst_xy, mut worst_v) = (0, 0.0_f64, 0.0_f64, 0.0_f64);
    let mut tracks = std::collections::BTreeSet::new();
    for r in &records {
        let f = |k: &str| r[k].as_f64().unwrap_or_else(|| panic!("{k} in {r}"));
        assert_eq!(
            (r["sac"].as_u64(), r["sic"].as_u64()),
            (Some(25), Some(201))
        );
        assert_eq!(r["service_id"].as_u64(), Some(3));
        assert_eq!(r["tentative"], false, "only confirmed tracks: {r}");
        // I062/500 from the covariance: position and velocity standard deviations.
        for k in ["APC_X", "APC_Y", "ATV_X", "ATV_Y"] {
            assert!(r["accuracy"][k].as_f64().is_some(), "{k} in {r}");
        }
        let number = r["track_number"].as_u64().expect("track number");
        tracks.insert(number);
        let key = (number, (f("time_of_track_s") * 128.0).round() as i64);
        // Track ids stay far below 2¹⁶ here, so the track number is the id.
        let Some(candidates) = history.get(&key) else {
            continue;
        };
        matched += 1;
        let enu = frame.to_enu(&Geodetic {
            lat_deg: f("lat"),
            lon_deg: f("lon"),
            alt_m: frame.origin().alt_m,
        });
        // The estimate of that time the record is closest to, each error against its own bound
        // (several scans may share a time, and the 0.5 m and 0.25 m/s steps blur which one).
        let errors = |held: &Held| {
            [
                (enu.x - held[0]).hypot(enu.y - held[1]),
                (f("x") - held[0]).hypot(f("y") - held[1]),
                (f("vx") - held[2]).hypot(f("vy") - held[3]),
            ]
        };
        let [wgs, xy, v] = candidates
            .iter()
            .map(errors)
            .min_by(|a, b| worst_ratio(a).total_cmp(&worst_ratio(b)))
            .expect("a candidate");
        assert!(
            wgs < 1.0,
            "I062/105 {wgs:.2} m from the track: {r} vs {candidates:?}"
        );
        assert!(
            xy < 1.0,
            "I062/100 {xy:.2} m from the track: {r} vs {candidates:?}"
        );
        // 0.25 m/s steps: at most 0.18 m/s off.
        assert!(
            v < 0.2,
            "I062/185 {v:.2} m/s from the track: {r} vs {candidates:?}"
        );
        worst_wgs = worst_wgs.max(wgs);
        worst_xy = worst_xy.max(xy);
        worst_v = worst_v.max(v);
    }
    eprintln!(
        "{} records of {} tracks, {matched} matched to a snapshot; worst I062/105 {worst_wgs:.3} m, \
         I062/100 {worst_xy:.3} m, I062/185 {worst_v:.3} m/s",
        records.len(),
        tracks.len()
    );
    // Each track number is one of the tracker's tracks: one per standing target, and (seen
    // once, on a machine running the whole suite: three tracks, every record matched) maybe a
    // third the tracker started meanwhile. How many tracks the tracker keeps is not the feed's
    // to assert; that each record is one of them is.
    let known: std::collections::BTreeSet<u64> = history.keys().map(|k| k.0).collect();
    assert!(
        tracks.len() >= 2 && tracks.is_subset(&known),
        "two standing targets: tracks {tracks:?} in ASTERIX, {known:?} in the tracker"
    );
    // The history sees every snapshot unless two scans land between two of its wake-ups.
    assert!(
        matched * 10 >= records.len() * 9,
        "{matched} of {} records matched a snapshot",
        records.len()
    );
}

/// The largest of a record's errors, each over its bound (1 m, 1 m, 0.2 m/s): ≤ 1 passes.
fn worst_ratio(e: &[f64; 3]) -> f64 {
    (e[0] / 1.0).max(e[1] / 1.0).max(e[2] / 0.2)
}
