//! Replays the fuzz corpora on stable: every file under `fuzz/regressions/<target>/` (inputs that
//! once crashed a fuzz target, kept after the fix) and `fuzz/seeds/<target>/` runs through the
//! same per-target function as the fuzz target (`fuzz/harness/mod.rs`, included below), so a
//! regression fails `cargo test` without nightly or cargo-fuzz. BENCHMARKS.md § Fuzzing.

#[path = "../../../fuzz/harness/mod.rs"]
mod harness;

use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../fuzz")
}

/// Runs every file of `fuzz/<kind>/<target>/` through the target; returns how many ran.
fn replay(kind: &str) -> usize {
    let mut n = 0;
    for (name, run) in harness::TARGETS {
        let dir = fuzz_dir().join(kind).join(name);
        let Ok(entries) = std::fs::read_dir(&dir) else {
            continue;
        };
        let mut files: Vec<PathBuf> = entries.filter_map(|e| Some(e.ok()?.path())).collect();
        files.sort();
        for file in files.iter().filter(|f| f.is_file()) {
            let data = std::fs::read(file).expect("readable input");
            let result = std::panic::catch_unwind(|| run(&data));
            assert!(result.is_ok(), "{name}: {} panics", file.display());
            n += 1;
        }
    }
    n
}

#[test]
fn regression_inputs_pass() {
    // The directory may hold no input for a target that never crashed.
    replay("regressions");
}

#[test]
fn seed_inputs_pass() {
    assert!(replay("seeds") > 0, "no seeds under fuzz/seeds");
}

/// Every built-in harrier-sim preset goes through the `sim_scenario` target (its world, sensors
/// and published scans); `HARRIER_WRITE_SEEDS=1` also writes them as seeds.
#[test]
fn sim_presets_pass_the_sim_scenario_target() {
    let write = std::env::var_os("HARRIER_WRITE_SEEDS").is_some();
    for name in harrier_sim::setup::PRESETS {
        let sc = harrier_sim::setup::SimScenario::preset(name).expect("preset");
        let json = sc.to_json();
        harness::sim_scenario(json.as_bytes());
        if write {
            let dir = fuzz_dir().join("seeds/sim_scenario");
            std::fs::create_dir_all(&dir).expect("seed dir");
            std::fs::write(dir.join(format!("{name}.json")), &json).expect("seed");
        }
    }
}

/// The reference scenarios of `shared/` (when present) through the `scenario` target.
#[test]
fn shared_scenarios_pass_the_scenario_target() {
    let shared = std::env::var_os("HARRIER_SHARED")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared"));
    let Ok(dirs) = std::fs::read_dir(shared.join("scenarios")) else {
        return;
    };
    for dir in dirs
        .filter_map(|e| Some(e.ok()?.path()))
        .filter(|p| p.is_dir())
    {
        let read = |f: &str| std::fs::read_to_string(dir.join(f)).unwrap_or_default();
        let input = [
            read("scenario.json"),
            read("measurements.jsonl"),
            read("truth.csv"),
        ]
        .join(&harness::FILE_SEPARATOR.to_string());
        harness::scenario(input.as_bytes());
    }
}
