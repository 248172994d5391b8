//! The `harrier` binary end to end: listing estimators, replaying a scenario, and the behaviour on
//! bad input (exit code 2, an error naming file and line, no partial output file).

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const SCENARIO: &str = r#"{"format": "gcs-scenario/1", "name": "cli", "dims": 2, "plane_z": 0.0,
 "time": {"t0": 0.0, "dt": 1.0, "t_end": 3.0},
 "target": {"id": "tgt"},
 "sensors": [{"id": "cam", "platform": "uav", "kind": "position", "ncomp": 2,
              "noise": {"type": "gaussian", "std": [1.0, 1.0]}}],
 "motion": {"models": [{"name": "CV", "type": "CV"}], "accel_std": 0.1},
 "prior": {"t": 0.0, "state": [0, 0, 0, 1, 0, 0], "cov": [[100,0,0,0],[0,100,0,0],[0,0,4,0],[0,0,0,4]]}}"#;

fn line(t: f64, z: &str) -> String {
    format!(
        r#"{{"t": {t}, "sensor": "cam", "kind": "position", "platform": {{"pos": [0, 0, 30]}}, "z": {z}}}"#
    )
}

fn write_scenario(dir: &Path, scenario: &str, lines: &[String], truth: Option<&str>) -> PathBuf {
    std::fs::write(dir.join("scenario.json"), scenario).unwrap();
    std::fs::write(dir.join("measurements.jsonl"), lines.join("\n") + "\n").unwrap();
    if let Some(t) = truth {
        std::fs::write(dir.join("truth.csv"), t).unwrap();
    }
    dir.to_path_buf()
}

fn harrier(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_harrier"))
        .args(args)
        .output()
        .unwrap()
}

/// Asserts that the run exited 0, showing its stderr if not.
fn assert_ok(out: &Output) {
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn replay(dir: &Path, out: &Path, est: &str) -> Output {
    harrier(&[
        "replay",
        dir.to_str().unwrap(),
        "-e",
        est,
        "-o",
        out.to_str().unwrap(),
    ])
}

fn good_lines() -> Vec<String> {
    vec![
        line(0.0, "[0.1, -0.2]"),
        line(1.0, "[1.2, 0.1]"),
        line(2.0, "[1.9, 0.0]"),
        line(3.0, "[3.1, -0.1]"),
    ]
}

const TRUTH: &str = "t,x,y,z,vx,vy,vz,mode\n0,0,0,0,1,0,0,CV\n1,1,0,0,1,0,0,CV\n2,2,0,0,1,0,0,CV\n3,3,0,0,1,0,0,CV\n";

#[test]
fn lists_estimators_with_one_line_each() {
    let out = harrier(&["estimators"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for name in ["kf", "ekf", "cdkf", "icdkf", "cdkf-bias"] {
        assert!(
            text.lines().any(|l| l.starts_with(&format!("{name} "))),
            "{name} missing in\n{text}"
        );
    }
    assert!(
        text.lines().all(|l| !l.starts_with(' ')),
        "one line per estimator:\n{text}"
    );
    // Two tables: the replay estimators, then the track filters of the live tracker, so that
    // `ekf` in each is visibly a different program.
    let (replay, track) = text
        .split_once("\n\nTrack filters")
        .expect("a track filter table");
    assert!(replay.starts_with("Replay estimators"), "{text}");
    for name in ["ekf", "cdkf", "imm", "cimm"] {
        let row = |table: &str| table.lines().any(|l| l.starts_with(&format!("{name} ")));
        assert!(row(replay) && row(track), "{name} in both tables:\n{text}");
    }
    assert!(!track.lines().any(|l| l.starts_with("kf ")), "{text}");
    let with_params = String::from_utf8(harrier(&["estimators", "--params"]).stdout).unwrap();
    assert!(with_params.contains("--param p_jump="));
    assert!(with_params.contains("   misses = …"), "{with_params}");
}

#[test]
fn replays_and_scores_a_good_scenario() {
    let dir = tempfile::tempdir().unwrap();
    let sc = write_scenario(dir.path(), SCENARIO, &good_lines(), Some(TRUTH));
    let out_file = dir.path().join("est.jsonl");
    let out = replay(&sc, &out_file, "kf");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let est = std::fs::read_to_string(&out_file).unwrap();
    assert_eq!(est.lines().count(), 4);
    let first: serde_json::Value = serde_json::from_str(est.lines().next().unwrap()).unwrap();
    assert_eq!(first["cov_dims"], serde_json::json!([0, 1, 3, 4]));
    assert!(String::from_utf8(out.stdout).unwrap().contains("pos RMSE"));
}

#[test]
fn malformed_measurement_line_names_file_and_line_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines = good_lines();
    lines[2] = r#"{"t": 2.0, "sensor": "cam", "kind": "position", "z": [1.0, 2.0]"#.into();
    let sc = write_scenario(dir.path(), SCENARIO, &lines, None);
    let out_file = dir.path().join("est.jsonl");
    let out = replay(&sc, &out_file, "kf");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.contains("measurements.jsonl:3:"), "{err}");
    assert!(!out_file.exists());
}

#[test]
fn inconsistent_scenarios_are_rejected_with_exit_code_2() {
    let cases: Vec<(String, Vec<String>, &str)> = vec![
        (
            SCENARIO.replace("\"cam\"", "\"cam2\""),
            good_lines(),
            "unknown sensor \"cam\"",
        ),
        (
            SCENARIO.to_string(),
            vec![line(1.0, "[0, 0]"), line(0.5, "[0, 0]")],
            "earlier than",
        ),
        (
            SCENARIO.to_string(),
            vec![line(0.0, "[0, 0, 0]")],
            "3 components",
        ),
        (
            SCENARIO.replace("\"dims\": 2", "\"dims\": 5"),
            good_lines(),
            "dims must be 2 or 3",
        ),
        (
            SCENARIO.replace("[1.0, 1.0]", "[1.0, -1.0]"),
            good_lines(),
            "not > 0",
        ),
        (
            SCENARIO.replace("\"name\": \"cli\",", "\"name\": \"cli\""),
            good_lines(),
            "scenario.json:1:",
        ),
    ];
    for (sc_text, lines, expect) in cases {
        let dir = tempfile::tempdir().unwrap();
        let sc = write_scenario(dir.path(), &sc_text, &lines, None);
        let out_file = dir.path().join("est.jsonl");
        let out = replay(&sc, &out_file, "kf");
        let err = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{expect}: {err}");
        assert!(err.contains(expect), "expected {expect:?} in {err}");
        assert!(!out_file.exists());
    }
}

#[test]
fn nan_measurements_are_skipped_and_counted() {
    let dir = tempfile::tempdir().unwrap();
    let mut lines = good_lines();
    lines[1] = line(1.0, "[null, 0.1]");
    let sc = write_scenario(dir.path(), SCENARIO, &lines, None);
    let out_file = dir.path().join("est.jsonl");
    let out = replay(&sc, &out_file, "ekf");
    assert!(out.status.success());
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("skipped 1 measurements with non-finite values")
    );
    assert_eq!(
        std::fs::read_to_string(&out_file).unwrap().lines().count(),
        3
    );
}

#[test]
fn unknown_estimator_and_parameter_are_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let sc = write_scenario(dir.path(), SCENARIO, &good_lines(), None);
    let out_file = dir.path().join("est.jsonl");
    let out = replay(&sc, &out_file, "nope");
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("unknown estimator \"nope\"")
    );
    let out = harrier(&[
        "replay",
        sc.to_str().unwrap(),
        "-e",
        "kf",
        "-p",
        "bogus=1",
        "-o",
        out_file.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("no parameter \"bogus\"")
    );
    let out = harrier(&["replay", "/nonexistent/dir", "-e", "kf"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("/nonexistent/dir/scenario.json")
    );
    // The linear KF on a nonlinear sensor is refused before anything runs.
    let radar = SCENARIO
        .replace(
            "\"kind\": \"position\", \"ncomp\": 2",
            "\"kind\": \"range_bearing\"",
        )
        .replace("[1.0, 1.0]", "[1.0, 0.01]");
    let lines: Vec<String> = (0..3)
        .map(|k| format!(r#"{{"t": {k}, "sensor": "cam", "kind": "range_bearing", "platform": {{"pos": [0, 0, 30]}}, "z": [30.0, 0.1]}}"#))
        .collect();
    let sc = write_scenario(dir.path(), &radar, &lines, None);
    let out = replay(&sc, &out_file, "kf");
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("linear KF takes only position")
    );
    assert!(!out_file.exists());
}

#[test]
fn guidance_sim_writes_trajectories_plot_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("three.csv");
    let svg = dir.path().join("three.svg");
    let out = harrier(&[
        "guidance-sim",
        "--case",
        "three-moving",
        "--duration",
        "60",
        "-o",
        csv.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // Summary: header with the default (CIMM) estimator, one line per UAV, the phase figures.
    assert!(
        stdout.starts_with("three-moving: law togvf, 3 UAV(s), 60 s at 10 Hz, estimator cimm"),
        "{stdout}"
    );
    for id in ["uav1", "uav2", "uav3"] {
        assert!(
            stdout.contains(&format!("  {id}: path to circle")),
            "{stdout}"
        );
    }
    assert!(stdout.contains("phase spacing error"), "{stdout}");
    let text = std::fs::read_to_string(&csv).unwrap();
    assert!(text.starts_with("t,id,kind,x,y,z,vx,vy,vz\n"));
    // 3 UAVs + target + estimate, 601 samples each.
    assert_eq!(text.lines().count(), 1 + 5 * 601);
    let picture = std::fs::read_to_string(&svg).unwrap();
    assert!(picture.contains("<svg"), "not an SVG");
    // --json: the summary as one JSON document, here with the KF for comparison.
    let out = harrier(&[
        "guidance-sim",
        "--case",
        "cimm-moving",
        "--duration",
        "60",
        "--estimator",
        "kf",
        "--json",
    ]);
    assert!(out.status.success());
    let s: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(s["case"], "cimm-moving");
    assert!(s["estimator"].as_str().unwrap().starts_with("kf"));
    assert!(s["estimate_rms_m"].as_f64().unwrap() > 0.0);
}

#[test]
fn guidance_sim_rejects_bad_arguments_with_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let cases: [(&[&str], &str); 5] = [
        (
            &["--case", "nope"],
            "unknown case \"nope\"; one of cimm-static",
        ),
        (&["--law", "pid"], "unknown law \"pid\""),
        (&["--estimator", "oracle"], "unknown estimator \"oracle\""),
        (&["--dt", "0"], "--dt 0 must be in (0, 1] s"),
        (&["--duration", "0"], "--duration 0 must be in (0, 36000] s"),
    ];
    for (args, message) in cases {
        let mut all = vec!["guidance-sim", "-o", csv.to_str().unwrap()];
        all.extend_from_slice(args);
        let out = harrier(&all);
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(message), "{args:?}: {stderr}");
        assert!(out.stdout.is_empty(), "{args:?}");
        assert!(!csv.exists(), "{args:?} wrote {}", csv.display());
    }
    // A positional argument (the case must be given with --case) is refused by the parser.
    let out = harrier(&["guidance-sim", "cimm-moving"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8(out.stderr)
            .unwrap()
            .contains("unexpected argument 'cimm-moving'")
    );
}

#[test]
fn generated_multi_target_scenario_replays_with_the_tracker() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("multi");
    let out = harrier(&["gen-multi", sc.to_str().unwrap(), "--seed", "3"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in ["scenario.json", "measurements.jsonl", "truth.csv"] {
        assert!(
            std::fs::metadata(sc.join(f)).is_ok_and(|m| m.len() > 0),
            "{f} missing or empty"
        );
    }
    let scenario: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sc.join("scenario.json")).unwrap()).unwrap();
    assert_eq!(scenario["format"], "gcs-scenario/1");
    // Scans = distinct measurement times.
    let mut scans: Vec<f64> = std::fs::read_to_string(sc.join("measurements.jsonl"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["t"]
                .as_f64()
                .unwrap()
        })
        .collect();
    scans.dedup();
    assert!(scans.len() > 1);
    let est = dir.path().join("tracks.jsonl");
    let out = replay(&sc, &est, "tracker");
    assert_ok(&out);
    let text = std::fs::read_to_string(&est).unwrap();
    assert_eq!(text.lines().count(), scans.len(), "one line per scan");
    for (l, t) in text.lines().zip(&scans) {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        assert_eq!(v["t"].as_f64(), Some(*t));
        assert!(v["tracks"].is_array());
    }
    // Nothing to register: no sensor has a bias block.
    let out = harrier(&[
        "replay",
        sc.to_str().unwrap(),
        "-e",
        "tracker",
        "--register",
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("no sensor of the scenario has a bias block"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// A configuration with a road and a no-fly disc, its API on a free port and no MAVLink link.
const WORLD_TOML: &str = r#"
[api]
listen = "127.0.0.1:0"
[mavlink]
gcs = []
router = []
[[tracker.roads]]
id = "r1"
width_m = 7.0
segments = [{ type = "line", start = [0.0, 0.0], end = [500.0, 300.0] }]
[[guidance.obstacles]]
x_m = 200.0
y_m = -100.0
radius_m = 40.0
"#;

#[test]
fn tiles_render_a_configurations_world_refuse_to_overwrite_and_info_lists_them() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("area.toml");
    std::fs::write(&config, WORLD_TOML).unwrap();
    let out = dir.path().join("area.mbtiles");
    let render = |extra: &[&str]| {
        let mut args = vec!["tiles", "render", "--config", config.to_str().unwrap()];
        args.extend_from_slice(&["--min-zoom", "12", "--max-zoom", "14", "--margin", "300"]);
        args.extend_from_slice(extra);
        args.push(out.to_str().unwrap());
        harrier(&args)
    };
    let r = render(&[]);
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(stdout.contains("tiles (zoom 12–14)"), "{stdout}");
    // Progress on stderr (not a terminal: a line per tenth, the last at the total).
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(
        stderr
            .lines()
            .last()
            .is_some_and(|l| l.starts_with("rendering: ")),
        "{stderr}"
    );
    let again = render(&[]);
    assert_eq!(again.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&again.stderr)
            .contains("already exists (overwrite it with --force)")
    );
    assert!(render(&["--force"]).status.success());
    let info = harrier(&["tiles", "info", out.to_str().unwrap()]);
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        info.status.success(),
        "{}",
        String::from_utf8_lossy(&info.stderr)
    );
    for want in [
        "format      png",
        "zoom        12–14",
        "name        AREA",
        "zoom 12",
        "zoom 14",
        "total",
    ] {
        assert!(text.contains(want), "{want}: {text}");
    }
    let bad = harrier(&[
        "tiles",
        "render",
        "--demo",
        "--max-zoom",
        "23",
        out.to_str().unwrap(),
    ]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&bad.stderr).contains("expected min ≤ max ≤ 22"));
}

#[test]
fn serve_refuses_a_bad_mbtiles_file_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("not-tiles.mbtiles");
    std::fs::write(&bad, "this is not an SQLite file, whatever its name says").unwrap();
    let config = dir.path().join("serve.toml");
    std::fs::write(
        &config,
        format!(
            "{WORLD_TOML}\n[map]\nmbtiles = {:?}\n",
            bad.display().to_string()
        ),
    )
    .unwrap();
    let r = harrier(&["serve", "--config", config.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "map: MBTiles file {}: not an MBTiles file",
            bad.display()
        )),
        "{stderr}"
    );
}

#[test]
fn a_generated_registration_scenario_replays_with_its_references() {
    let dir = tempfile::tempdir().unwrap();
    let sc = dir.path().join("reg");
    let generate = |case: &str| {
        harrier(&[
            "gen-registration",
            sc.to_str().unwrap(),
            "--case",
            case,
            "--seed",
            "4",
            "--duration",
            "120",
        ])
    };
    let out = generate("radar-reference");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for f in [
        "scenario.json",
        "measurements.jsonl",
        "truth.csv",
        "bias_truth.csv",
        "references.jsonl",
    ] {
        assert!(
            std::fs::metadata(sc.join(f)).is_ok_and(|m| m.len() > 0),
            "{f} missing or empty"
        );
    }
    let est = dir.path().join("est.jsonl");
    let out = replay(&sc, &est, "registration");
    assert_ok(&out);
    let last: serde_json::Value = serde_json::from_str(
        std::fs::read_to_string(&est)
            .unwrap()
            .lines()
            .last()
            .unwrap(),
    )
    .unwrap();
    // The UAV's GPS made the radar's offsets observable.
    let radar = &last["bias_est"]["radar1"];
    assert_eq!(
        radar["observable"]["offset"],
        serde_json::json!([true, true])
    );
    assert_eq!(radar["terms"].as_array().unwrap().len(), 4);

    // The live registrar on the same scenario: the painted UAV's detections are references,
    // they make the offsets observable and start no track.
    let live = dir.path().join("live.jsonl");
    let out = harrier(&[
        "replay",
        sc.to_str().unwrap(),
        "-e",
        "tracker",
        "--register",
        "-o",
        live.to_str().unwrap(),
    ]);
    assert_ok(&out);
    let text = std::fs::read_to_string(&live).unwrap();
    let last: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    let radar = &last["bias_est"]["radar1"];
    assert_eq!(
        radar["observable"]["offset"],
        serde_json::json!([true, true]),
        "{radar}"
    );
    assert!(radar["references"].as_u64().unwrap() > 100, "{radar}");
    assert_eq!(last["tracks"].as_array().unwrap().len(), 1, "{last}");
    let out = harrier(&["replay", sc.to_str().unwrap(), "-e", "ekf", "--register"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("go with -e tracker"));

    // The same directory as another case: its references go; a bad reference line is refused.
    let out = generate("radar-alone");
    assert!(out.status.success());
    assert!(!sc.join("references.jsonl").exists());
    std::fs::write(
        sc.join("references.jsonl"),
        r#"{"t":0,"sensor":"radar1","kind":"range_bearing","platform":{"pos":[0,0,0]},"z":[1,2],"object":{"id":"u","pos":[0,0,0],"std":[0,1,1]}}"#,
    )
    .unwrap();
    let out = replay(&sc, &est, "registration");
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("references.jsonl:1") && err.contains("std > 0"),
        "{err}"
    );

    let out = generate("spline");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown case \"spline\""));
}

/// The errors a new user meets first say what to do, once: a taken port (named, with the hint
/// that another `harrier demo` may hold it), a missing session file, `--port`.
#[test]
fn first_errors_say_what_to_do_once() {
    let held = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let port = held.local_addr().unwrap().port();
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("serve.toml");
    std::fs::write(
        &config,
        "[zenoh]\nlisten = [\"tcp/127.0.0.1:0\"]\n[mavlink]\ngcs = []\nrouter = []\n",
    )
    .unwrap();
    let listen = format!("127.0.0.1:{port}");
    let r = harrier(&[
        "serve",
        "--config",
        config.to_str().unwrap(),
        "--listen",
        &listen,
    ]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains(&listen), "{stderr}");
    assert_eq!(
        stderr.matches("Address already in use").count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("another `harrier demo`"), "{stderr}");
    drop(held);

    let missing = dir.path().join("nope.sqlite");
    let r = harrier(&["sessions", "list", missing.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("nope.sqlite: cannot open: no such file"),
        "{stderr}"
    );
    assert!(!stderr.contains("Invalid path"), "{stderr}");

    let r = harrier(&["demo", "--port", "8081"]);
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert_eq!(r.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("--listen 127.0.0.1:8081"), "{stderr}");
    assert!(!stderr.contains("--cot"), "{stderr}");
}
