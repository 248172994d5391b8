//! Set-membership acceptance on `bounded_linear` (\[ELL\], FORMAT.md §2.1): the OBE filters must
//! contain the truth at every step, the minimum-volume one with a mean volume close to the
//! reference implementation's (5.42), and the independent scorer must agree with Harrier's.

use harrier_engine::Params;
use harrier_tests::{scenario, score_py};
use harrier_tools::replay;

/// Containment and mean volume of one estimator, checked against `score.py`.
fn run(estimator: &str) -> (f64, f64) {
    let dir = scenario("bounded_linear");
    let data = replay::load(&dir).expect("load bounded_linear");
    let report = replay::run(&data, estimator, &Params::default()).expect("replay");
    assert!(
        report.rejected.is_empty(),
        "{estimator}: rejected steps {:?}",
        report.rejected
    );
    let n_times = data.groups().len();
    assert_eq!(report.estimates.len(), n_times, "one estimate per time");
    let score = report.score.expect("truth present");
    let ell = score.ellipsoid.expect("ellipsoid summary");
    assert_eq!(ell.dims, vec![0, 1, 3, 4]);
    assert_eq!(ell.n, n_times);

    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("estimates.jsonl");
    replay::write_estimates(&out, &report.estimates).expect("write estimates");
    let py = score_py(&dir, &out).expect("score.py");
    let py_contain = py["ellipsoid"]["containment"]
        .as_f64()
        .expect("containment");
    let py_volume = py["ellipsoid"]["mean_volume"]
        .as_f64()
        .expect("mean_volume");
    println!(
        "{estimator}: containment {:.4} ({} violations of {}), mean volume {:.6}, median {:.6}; \
         score.py: containment {py_contain:.4}, mean volume {py_volume:.6} (rel. diff {:.2e})",
        ell.containment,
        ell.violations,
        ell.n,
        ell.mean_volume,
        ell.median_volume,
        (py_volume - ell.mean_volume).abs() / ell.mean_volume
    );
    assert_eq!(py_contain, ell.containment, "{estimator}: containment");
    assert!(
        (py_volume - ell.mean_volume).abs() <= 1e-6 * ell.mean_volume,
        "{estimator}: mean volume {} (Rust) vs {py_volume} (score.py)",
        ell.mean_volume
    );
    (ell.containment, ell.mean_volume)
}

#[test]
fn obe_min_volume_contains_the_truth_with_a_small_set() {
    let (containment, volume) = run("obe");
    assert_eq!(containment, 1.0);
    assert!(volume <= 5.5, "mean volume {volume} > 5.5 (reference 5.42)");
}

#[test]
fn obe_min_trace_contains_the_truth() {
    let (containment, _) = run("obe-trace");
    assert_eq!(containment, 1.0);
}
