//! The Foxglove feed (`[foxglove]`, docs/foxglove.md): the live server, fed a standing target's
//! scans over Zenoh, serves the Foxglove WebSocket protocol (the official `foxglove` SDK's
//! server). `tests/python/foxglove_client.py` — the `websockets` package speaking
//! `foxglove.sdk.v1`, decoding with the schema each channel advertises and again with
//! Foxglove's published `foxglove-schemas-protobuf` classes — subscribes to every channel: the
//! four channels are advertised with their protobuf schemas, every message of each decodes, the
//! two decodings agree, and each confirmed track's `LocationFix` is where `GET /api/v1/tracks`
//! says the track is (the scans stopped first, so both read the same estimate). The same
//! channels go to an MCAP file (`foxglove.mcap`), which the `mcap` package's reader
//! (`tests/python/mcap_check.py`) reads after the server stopped: every message decodes against
//! the schema in the file, and there are as many as the feed logged. The scans are recorded
//! (`[recorder]`), and `harrier sessions export --format mcap` writes the session as an MCAP file
//! of the same topics, which the same reader decodes whole, with a message per `scans` row (its
//! detections, the vehicle's pose and transform), per scan's group of `tracks` rows and per
//! confirmed `tracks` row, as SQLite counts them.

use std::time::Duration;

use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_tests::{
    http_get_json, open_session, publish_standing_target, python_json, require_python_module,
    runtime, server_config, target_bin, within,
};
use nalgebra::Vector3;
use serde_json::Value;

#[test]
fn a_foxglove_client_decodes_every_channel_and_finds_the_tracks_where_the_api_has_them() {
    require_python_module("websockets", "websockets==17.4");
    require_python_module(
        "foxglove_schemas_protobuf",
        "foxglove-schemas-protobuf==0.4.0",
    );
    let (mut config, zenoh) = server_config();
    config.foxglove.enabled = true;
    config.foxglove.listen = "127.0.0.1:0".parse().expect("addr");
    let dir = tempfile::tempdir().expect("tempdir");
    let mcap = dir.path().join("live.mcap");
    config.foxglove.mcap = mcap.display().to_string();
    let db = dir.path().join("rec.sqlite");
    config.recorder.path = db.display().to_string();
    config.recorder.flush_ms = 100;
    let frame = LocalFrame::new(config.frame.origin);
    let rt = runtime();
    let (server, publisher) = rt.block_on(async {
        let server = within(10, "start the server", harrier_server::start(&config))
            .await
            .expect("start the live server");
        let session = open_session(vec![zenoh]).await;
        let publisher =
            publish_standing_target(&session, 1, [60.0, 80.0], [0.0, 0.0, 100.0], 10.0).await;
        (server, (publisher, session))
    });
    let addr = server.local_addr();
    let fox = server
        .foxglove_addr()
        .expect("the Foxglove server's address");

    // A confirmed track, then no more scans: the estimate stays as it is.
    rt.block_on(within(30, "a confirmed track", async {
        loop {
            let (_, body) = http_get_json(addr, "/api/v1/tracks");
            let confirmed = body["tracks"]
                .as_array()
                .is_some_and(|t| t.iter().any(|t| t["status"] == "confirmed"));
            if confirmed {
                break;
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    }));
    publisher.0.abort();
    rt.block_on(within(10, "the tracker idle", async {
        let mut seq = http_get_json(addr, "/api/v1/tracks").1["seq"].clone();
        loop {
            tokio::time::sleep(Duration::from_millis(500)).await;
            let now = http_get_json(addr, "/api/v1/tracks").1["seq"].clone();
            if now == seq {
                break;
            }
            seq = now;
        }
    }));

    // The scans have stopped: every channel but the detections' gets messages.
    let url = format!("ws://{fox}");
    let report = python_json(
        "foxglove_client.py",
        &[
            &url,
            "--seconds",
            "20",
            "--min",
            "3",
            "--quiet-topic",
            "/harrier/detections",
        ],
        Duration::from_secs(40),
    );
    eprintln!("foxglove client: {report}");
    assert_eq!(
        report["errors"],
        Value::Array(Vec::new()),
        "decoding errors"
    );
    let mut channels: Vec<(String, String)> = report["channels"]
        .as_array()
        .expect("channels")
        .iter()
        .map(|c| {
            assert_eq!(c["encoding"], "protobuf");
            (
                c["topic"].as_str().expect("topic").to_owned(),
                c["schema"].as_str().expect("schema").to_owned(),
            )
        })
        .collect();
    channels.sort();
    let expected = [
        ("/harrier/detections", "foxglove.SceneUpdate"),
        ("/harrier/tracks", "foxglove.SceneUpdate"),
        ("/harrier/tracks/location", "foxglove.LocationFix"),
        ("/harrier/vehicles/location", "foxglove.LocationFix"),
        ("/tf", "foxglove.FrameTransforms"),
    ];
    assert_eq!(
        channels,
        expected.map(|(t, s)| (t.to_owned(), s.to_owned())).to_vec()
    );
    for (topic, _) in &expected[1..] {
        assert!(
            report["counts"][topic].as_u64().unwrap_or(0) >= 3,
            "{topic}: fewer than 3 messages decoded: {report}"
        );
    }

    let (_, body) = http_get_json(addr, "/api/v1/tracks");
    let mut compared = 0;
    for t in body["tracks"].as_array().expect("tracks") {
        if t["status"] != "confirmed" {
            continue;
        }
        let id = t["id"].as_u64().expect("id");
        let fix = &report["fixes"][format!("track/{id}")];
        let at = frame.to_enu(&Geodetic {
            lat_deg: fix["lat"].as_f64().expect("fix lat"),
            lon_deg: fix["lon"].as_f64().expect("fix lon"),
            alt_m: fix["alt"].as_f64().expect("fix alt"),
        });
        let s = t["state"].as_array().expect("state");
        let rest = Vector3::from_fn(|i, _| s[i].as_f64().expect("state value"));
        let d = (at - rest).norm();
        assert!(
            d < 0.01,
            "track {id}: its fix is {d} m from the API's estimate"
        );
        compared += 1;
    }
    assert!(compared >= 1, "no confirmed track compared");
    assert!(server.feed_counters().get("foxglove", "scenes") >= 3);
    let counters = server.feed_counters();
    rt.block_on(server.shutdown());
    let logged = counters.get("foxglove", "messages");

    // The MCAP file, closed at shutdown.
    let path = mcap.display().to_string();
    let file = python_json("mcap_check.py", &[&path], Duration::from_secs(60));
    eprintln!("MCAP: {file}");
    assert_eq!(file["errors"], Value::Array(Vec::new()), "decoding errors");
    for (topic, schema) in expected {
        assert_eq!(file["schemas"][topic]["schema"], schema, "{topic}");
        assert_eq!(file["schemas"][topic]["encoding"], "protobuf", "{topic}");
        assert!(
            file["counts"][topic].as_u64().unwrap_or(0) >= 3,
            "{topic}: {file}"
        );
    }
    assert_eq!(
        file["total"].as_u64(),
        Some(logged),
        "every logged message is in the file"
    );

    // The recorded session, exported.
    let out = dir.path().join("session1.mcap");
    let run = std::process::Command::new(target_bin("harrier"))
        .args(["sessions", "export"])
        .arg(&db)
        .arg("1")
        .arg(&out)
        .args(["--format", "mcap"])
        .output()
        .expect("run harrier sessions export");
    let said = String::from_utf8_lossy(&run.stdout);
    eprintln!("harrier sessions export: {said}");
    assert!(
        run.status.success(),
        "{said}{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let path = out.display().to_string();
    let file = python_json("mcap_check.py", &[&path], Duration::from_secs(60));
    eprintln!("exported MCAP: {file}");
    assert_eq!(file["errors"], Value::Array(Vec::new()), "decoding errors");
    let c = rusqlite::Connection::open(&db).expect("open the session file");
    let count = |sql: &str| -> u64 {
        c.query_row(sql, [], |r| r.get::<_, i64>(0))
            .map(|n| n as u64)
            .expect(sql)
    };
    let scans = count("SELECT count(*) FROM scans WHERE session = 1");
    let want = [
        ("/harrier/detections", scans),
        ("/harrier/vehicles/location", scans),
        ("/tf", scans),
        (
            "/harrier/tracks",
            count("SELECT count(DISTINCT t) FROM tracks WHERE session = 1"),
        ),
        (
            "/harrier/tracks/location",
            count("SELECT count(*) FROM tracks WHERE session = 1 AND status = 'confirmed'"),
        ),
    ];
    assert!(scans >= 3, "{scans} scans recorded");
    for (topic, n) in want {
        assert_eq!(file["counts"][topic].as_u64(), Some(n), "{topic}: {file}");
    }
    for (topic, schema) in expected {
        assert_eq!(file["schemas"][topic]["schema"], schema, "{topic}");
    }
}
