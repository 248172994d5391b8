//! Helpers for Harrier's end-to-end tests: where the reference scenarios are, how to replay one
//! in-process and how to run the independent scorer (`shared/scenarios/score.py`).

use std::path::{Path, PathBuf};
use std::process::Command;

/// `shared/scenarios`, which CI places beside the repository (`../shared`). `HARRIER_SHARED`
/// overrides the location of `shared/`.
pub fn scenarios_dir() -> PathBuf {
    let shared = std::env::var_os("HARRIER_SHARED").map_or_else(
        || Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"),
        PathBuf::from,
    );
    shared.join("scenarios")
}

/// Path of one reference scenario.
pub fn scenario(name: &str) -> PathBuf {
    scenarios_dir().join(name)
}

/// Runs `python3 score.py <dir> <estimates> --json -` and returns its JSON.
pub fn score_py(dir: &Path, estimates: &Path) -> anyhow::Result<serde_json::Value> {
    let out = Command::new("python3")
        .arg(scenarios_dir().join("score.py"))
        .arg(dir)
        .arg(estimates)
        .args(["--json", "-"])
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "score.py failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    Ok(serde_json::from_slice(&out.stdout)?)
}

/// Replays the reference scenario `name` with `estimator` and default parameters.
pub fn replay(name: &str, estimator: &str) -> harrier_server::replay::ReplayReport {
    let data = harrier_server::replay::load(&scenario(name)).expect("reference scenario loads");
    harrier_server::replay::run(&data, estimator, &harrier_server::engine::Params::default())
        .expect("replay runs")
}

/// Replays `name` with `estimator`, checks that no step was rejected, prints and returns the score.
pub fn replay_score(name: &str, estimator: &str) -> harrier_core::metrics::Score {
    let r = replay(name, estimator);
    assert!(
        r.rejected.is_empty(),
        "{estimator} on {name} rejected steps: {:?}",
        r.rejected
    );
    let s = r.score.expect("reference scenarios have truth");
    println!(
        "{name:<22} {estimator:<14} pos RMSE {:8.3} m  NEES-95% ok {:.3}",
        s.pos_rmse.unwrap_or(f64::NAN),
        s.nees.as_ref().map_or(f64::NAN, |n| n.frac_within_95)
    );
    s
}

/// Writes the estimates of `report` (a replay of the reference scenario `name`) to a temporary file,
/// scores it with `score.py` and asserts that the state metrics harrier-core computed agree to 1e-9.
pub fn assert_score_py_agrees(name: &str, report: &harrier_server::replay::ReplayReport) {
    let s = report
        .score
        .clone()
        .expect("reference scenarios have truth");
    let dir = tempfile::tempdir().expect("tempdir");
    let out = dir.path().join("estimates.jsonl");
    harrier_server::replay::write_estimates(&out, &report.estimates).expect("write estimates");
    let py = score_py(&scenario(name), &out).expect("score.py runs");
    let close = |what: &str, a: f64, b: &serde_json::Value| {
        let b = b.as_f64().unwrap_or(f64::NAN);
        assert!(
            (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
            "{name} {what}: rust {a} vs score.py {b}"
        );
    };
    close("pos_rmse", s.pos_rmse.unwrap_or(f64::NAN), &py["pos_rmse"]);
    close("vel_rmse", s.vel_rmse.unwrap_or(f64::NAN), &py["vel_rmse"]);
    close("pos_max", s.pos_max.unwrap_or(f64::NAN), &py["pos_max"]);
    for (mode, v) in &s.pos_rmse_by_mode {
        close("pos_rmse_by_mode", *v, &py["pos_rmse_by_mode"][mode]);
    }
    if let Some(n) = &s.nees {
        close("nees.mean", n.mean, &py["nees"]["mean"]);
        close(
            "nees.frac_within_95",
            n.frac_within_95,
            &py["nees"]["frac_within_95"],
        );
        close(
            "nees.chi2_95_bound",
            n.chi2_95_bound,
            &py["nees"]["chi2_95_bound"],
        );
    }
    if let Some(n) = &s.nees_pos {
        close("nees_pos.mean", n.mean, &py["nees_pos"]["mean"]);
    }
}
