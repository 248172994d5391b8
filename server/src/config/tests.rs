//! Tests of the configuration: the example file, defaults, refusals that name their key, the
//! deployment, named tokens and signing keys.

use harrier_link::signing::SigningMode;

use super::*;

#[test]
fn the_example_parses_and_builds_its_engine() {
    let text = include_str!("../../../harrier.example.toml");
    let c = Config::parse(text, "harrier.example.toml").expect("example config");
    harrier_engine::registry::build_track_filter(
        &c.tracker.estimator,
        &c.deployment(),
        &c.params(),
    )
    .expect("engine");
}

#[test]
fn defaults_build_and_bad_values_are_named() {
    let c = Config::parse("", "empty").expect("defaults");
    assert_eq!(c, Config::default());
    harrier_engine::registry::build_track_filter("ekf", &c.deployment(), &c.params())
        .expect("engine");
    let e = Config::parse("[tracker]\nreorder_window_s = -1\n", "f").unwrap_err();
    assert!(e.to_string().contains("reorder_window_s"), "{e}");
    let e = Config::parse("[zenoh]\nmode = \"router\"\n", "f").unwrap_err();
    assert!(e.to_string().contains("router"), "{e}");
    let e = Config::parse(
        "[zenoh]\nconnect = [\"tls/10.0.0.1:7447\"]\nenable_mtls = true\n",
        "f",
    )
    .unwrap_err();
    assert!(e.to_string().contains("connect_certificate"), "{e}");
    let e = Config::parse("[api]\nlisten = 3\n", "f").unwrap_err();
    assert!(e.to_string().starts_with("f: "), "{e}");
    let e = Config::parse("[nonsense]\n", "f").unwrap_err();
    assert!(e.to_string().contains("nonsense"), "{e}");
    let e = Config::parse("[guidance.safety]\nfloor_m = 600.0\n", "f").unwrap_err();
    assert!(e.to_string().contains("guidance.safety: floor_m"), "{e}");
    let e = Config::parse("[guidance.safety]\nbattery_floor_pct = 120.0\n", "f").unwrap_err();
    assert!(e.to_string().contains("battery_floor_pct"), "{e}");
    let g = crate::guidance::GuidanceSettings::from(&c);
    assert_eq!(
        (
            g.envelope.max_distance_m,
            g.envelope.ceiling_m,
            g.envelope.battery_floor_pct
        ),
        (Some(5000.0), Some(500.0), Some(25.0))
    );
}

#[test]
fn the_deployment_is_the_tracker_section_and_its_numbers_are_checked() {
    let c = Config::parse(
        "[frame]\nplane_z = 12.5\n[tracker]\nscan_period_s = 0.5\n\
         [[tracker.roads]]\nid = \"r\"\nsigma_m = 2.0\n\
         segments = [{type = \"line\", start = [0.0, 0.0], end = [100.0, 0.0]}]\n",
        "f",
    )
    .expect("config");
    let d = c.deployment();
    assert_eq!(
        (d.dims, d.plane_z, d.scan_period_s, d.sensors),
        (2, 12.5, 0.5, 1)
    );
    assert_eq!(d.motion.as_ref(), Some(&c.tracker.motion));
    assert_eq!(d.roads, c.tracker.roads);
    harrier_engine::registry::build_track_filter("cimm", &d, &c.params()).expect("cimm engine");
    let e = Config::parse("[tracker.motion]\naccel_std = -1.0\n", "f").unwrap_err();
    assert!(e.to_string().contains("tracker.motion.accel_std"), "{e}");
    let e = Config::parse("[tracker.motion]\ntransition_matrix = [[nan]]\n", "f").unwrap_err();
    assert!(e.to_string().contains("tracker.motion: NaN"), "{e}");
    let e = Config::parse(
        "[[tracker.roads]]\nid = \"r\"\nsigma_m = 2.0\n\
         segments = [{type = \"line\", start = [0.0, inf], end = [1.0, 0.0]}]\n",
        "f",
    )
    .unwrap_err();
    assert!(e.to_string().contains("tracker.roads \"r\": inf"), "{e}");
}

#[test]
fn named_tokens_need_a_long_secret_and_a_real_expiry() {
    let tokens = |entry: &str| format!("[[api.tokens]]\n{entry}\n");
    let c = Config::parse(
        &tokens("name = \"ci\"\ntoken = \"0123456789abcdef\"\nexpires = \"2026-12-31T23:59:59Z\""),
        "f",
    )
    .expect("valid token");
    let at = c.api.tokens[0].expiry().expect("expiry").expect("some");
    let unix = at
        .duration_since(std::time::UNIX_EPOCH)
        .expect("after 1970");
    assert_eq!(unix.as_secs(), 1_798_761_599);
    let e = Config::parse(&tokens("name = \"ci\"\ntoken = \"short\""), "f").unwrap_err();
    assert!(e.to_string().contains("16 characters"), "{e}");
    let e = Config::parse(
        &tokens("name = \"ci\"\ntoken = \"0123456789abcdef\"\nexpires = \"next week\""),
        "f",
    )
    .unwrap_err();
    assert!(e.to_string().contains("RFC 3339"), "{e}");
    let twice = tokens("name = \"a\"\ntoken = \"0123456789abcdef\"").repeat(2);
    let e = Config::parse(&twice, "f").unwrap_err();
    assert!(e.to_string().contains("distinct"), "{e}");
}

#[test]
fn signing_keys_from_hex_or_file_and_never_written_out() {
    let hex = "ab".repeat(32);
    let c = Config::parse(
        &format!("[mavlink.signing]\nmode = \"signed_only\"\nkey = \"{hex}\"\nlink_id = 4\n"),
        "f",
    )
    .expect("hex key");
    let s = c.mavlink.signing.resolve().expect("valid").expect("on");
    assert_eq!(
        (s.mode, s.link_id, *s.key.bytes()),
        (SigningMode::SignedOnly, 4, [0xAB; 32])
    );
    assert!(
        crate::gcs::GcsConfig::from_config(&c, None)
            .expect("gcs")
            .expect("on")
            .signing
            .is_some()
    );
    // The configuration recorded with a session does not hold the key.
    let json = serde_json::to_string(&c).expect("json");
    assert!(!json.contains(&hex), "{json}");
    let dir = tempfile::tempdir().expect("temporary directory");
    let file = dir.path().join("key");
    std::fs::write(&file, [7u8; 32]).expect("write");
    let text = format!(
        "[mavlink.signing]\nmode = \"sign\"\nkey_file = {:?}\n",
        file.display().to_string()
    );
    let s = Config::parse(&text, "f")
        .expect("key file")
        .mavlink
        .signing
        .resolve()
        .expect("valid")
        .expect("on");
    assert_eq!((s.mode, *s.key.bytes()), (SigningMode::Sign, [7; 32]));
    assert_eq!(
        Config::default().mavlink.signing.resolve().expect("off"),
        None
    );
    for (bad, says) in [
        ("mode = \"on\"", "off, sign or signed_only"),
        ("mode = \"signed_only\"", "exactly one of key_file and key"),
        ("mode = \"sign\"\nkey = \"abcd\"", "64 hex characters"),
        (
            "mode = \"sign\"\nkey_file = \"/nonexistent/key\"",
            "/nonexistent/key",
        ),
    ] {
        let e = Config::parse(&format!("[mavlink.signing]\n{bad}\n"), "f").unwrap_err();
        assert!(e.to_string().contains(says), "{bad}: {e}");
    }
}

#[test]
fn the_adsb_format_is_sbs_or_beast() {
    assert_eq!(Config::default().adsb.format, AdsbFormat::Sbs);
    let c = Config::parse("[adsb]\nformat = \"beast\"\n", "f").expect("beast");
    assert_eq!(c.adsb.format, AdsbFormat::Beast);
    let e = Config::parse("[adsb]\nformat = \"avr\"\n", "f").unwrap_err();
    let e = e.to_string();
    assert!(
        e.contains("format") && e.contains("avr") && e.contains("beast"),
        "{e}"
    );
    assert_eq!("beast".parse(), Ok(AdsbFormat::Beast));
    let e = "Beast".parse::<AdsbFormat>().unwrap_err();
    assert!(e.contains("adsb.format") && e.contains("\"sbs\""), "{e}");
}
