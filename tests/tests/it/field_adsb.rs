//! ADS-B in (`[adsb]`, docs/adsb.md): the live server as a client of an ADS-B receiver's SBS-1
//! output. `tests/python/sbs_replay.py` plays the receiver: 300 aircraft in straight flight up
//! to 100 km around the frame origin, 500 lines/s over TCP at real time for 15 s, one line in 97
//! broken. Afterwards every line is counted (none lost), the broken ones as `malformed`; every
//! aircraft is a track of its own on `GET /api/v1/aircraft` with its callsign, within 50 m of its
//! last position report carried on with its velocity to the track's time; and the ground tracks
//! stay empty (aircraft are never ground targets).

use std::process::Stdio;
use std::time::Duration;

use harrier_link::geo::{Geodetic, LocalFrame};
use harrier_tests::{
    http_get, http_get_json, json_lines, kill_group, python_script, runtime, server_config,
};
use nalgebra::Vector3;

const AIRCRAFT: usize = 300;
const RATE: f64 = 500.0;
const DURATION_S: f64 = 15.0;

#[test]
fn an_sbs1_feed_of_300_aircraft_becomes_300_aircraft_tracks() {
    let mut replay = python_script("sbs_replay.py")
        .args(["--aircraft", &AIRCRAFT.to_string()])
        .args(["--rate", &RATE.to_string()])
        .args(["--duration", &DURATION_S.to_string()])
        .args(["--origin", "47.397742,8.545594"])
        .stdout(Stdio::piped())
        .spawn()
        .expect("start sbs_replay.py");
    let rx = json_lines(&mut replay);
    let ready = rx
        .recv_timeout(Duration::from_secs(20))
        .expect("sbs_replay.py did not say it listens");
    let port = ready["ready"].as_u64().expect("ready port");

    let (mut config, _) = server_config();
    config.adsb.enabled = true;
    config.adsb.address = format!("127.0.0.1:{port}");
    let frame = LocalFrame::new(config.frame.origin);
    let rt = runtime();
    let server = rt
        .block_on(harrier_tests::within(
            10,
            "start the server",
            harrier_server::start(&config),
        ))
        .expect("start the live server");
    let addr = server.local_addr();

    let report = rx
        .recv_timeout(Duration::from_secs_f64(DURATION_S + 40.0))
        .unwrap_or_else(|_| {
            kill_group(&mut replay);
            panic!("sbs_replay.py did not finish its replay")
        });
    let _ = replay.wait();
    let sent = report["sent"].as_u64().expect("sent");
    let malformed = report["malformed"].as_u64().expect("malformed");
    assert_eq!(sent, (RATE * DURATION_S) as u64);
    eprintln!(
        "replayed {sent} lines ({malformed} broken) in {:.2} s",
        report["elapsed_s"].as_f64().unwrap_or(0.0)
    );

    // Every line read before the connection closed: poll the counters (no timing assumption).
    let counters = server.feed_counters();
    rt.block_on(harrier_tests::within(10, "every line counted", async {
        while counters.get("adsb", "lines") < sent {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    }));
    assert_eq!(
        counters.get("adsb", "lines"),
        sent,
        "lines lost or invented"
    );
    assert_eq!(counters.get("adsb", "malformed"), malformed);
    assert_eq!(counters.get("adsb", "gated"), 0);
    assert_eq!(counters.get("adsb", "reset"), 0);

    let (status, list) = http_get_json(addr, "/api/v1/aircraft");
    assert_eq!(status, 200);
    let aircraft = list["aircraft"].as_array().expect("aircraft");
    let truth = report["aircraft"].as_object().expect("report aircraft");
    assert_eq!(truth.len(), AIRCRAFT);
    assert_eq!(aircraft.len(), AIRCRAFT, "one track per aircraft");
    let mut worst = 0.0_f64;
    for a in aircraft {
        let icao = a["icao"].as_str().expect("icao");
        let t = &truth[icao];
        assert_eq!(a["callsign"], t["callsign"], "{icao}");
        let last = Geodetic {
            lat_deg: t["lat"].as_f64().expect("lat"),
            lon_deg: t["lon"].as_f64().expect("lon"),
            alt_m: t["alt_m"].as_f64().expect("alt"),
        };
        // The last position report, carried on with the aircraft's velocity to the track's time.
        let dt = a["time_unix"].as_f64().expect("time") - t["t"].as_f64().expect("t");
        let v = Vector3::new(
            t["ve"].as_f64().expect("ve"),
            t["vn"].as_f64().expect("vn"),
            t["vu"].as_f64().expect("vu"),
        );
        let expected = frame.to_enu(&LocalFrame::new(last).from_enu(&(v * dt)));
        let s = a["state"].as_array().expect("state");
        let got = Vector3::from_fn(|i, _| s[i].as_f64().expect("state value"));
        let err = (got - expected).norm();
        worst = worst.max(err);
        assert!(err < 50.0, "{icao}: {err:.1} m from its reports");
    }
    eprintln!("{AIRCRAFT} aircraft, worst distance from the reports {worst:.1} m");

    let (_, tracks) = http_get_json(addr, "/api/v1/tracks");
    assert_eq!(tracks["tracks"].as_array().map(Vec::len), Some(0));
    let (_, metrics) = http_get(addr, "/api/v1/metrics");
    assert!(
        metrics.contains(&format!(
            "harrier_feed_events_total{{feed=\"adsb\",event=\"malformed\"}} {malformed}"
        )),
        "{metrics}"
    );
    rt.block_on(server.shutdown());
}
