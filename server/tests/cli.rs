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
    let with_params = String::from_utf8(harrier(&["estimators", "--params"]).stdout).unwrap();
    assert!(with_params.contains("--param p_jump="));
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
