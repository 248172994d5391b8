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
