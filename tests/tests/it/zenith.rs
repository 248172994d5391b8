//! Acceptance test for paper 004 (\[ESE\]) on `zenith_pass`: one-step-ahead azimuth prediction of the
//! error-space estimate method against the CA Kalman filter and the strong tracking filter, scored
//! in-process and cross-checked with `score.py`.

use harrier_engine::Params;
use harrier_tests::{scenario, score_py};
use harrier_tools::replay::{self, ReplayReport};

fn run(name: &str) -> ReplayReport {
    let data = replay::load(&scenario("zenith_pass")).expect("zenith_pass loads");
    let report = replay::run(&data, name, &Params::default()).expect("replay runs");
    assert!(
        report.rejected.is_empty(),
        "{name}: rejected steps {:?}",
        &report.rejected[..report.rejected.len().min(5)]
    );
    report
}

/// `(max, rms)` of the one-step prediction error vs truth, per component `[az, el]`.
fn errors(name: &str, r: &ReplayReport) -> ([f64; 2], [f64; 2]) {
    let score = r.score.as_ref().expect("zenith_pass has truth");
    let p = &score.prediction["az_el"];
    assert!(p.n > 7000, "{name}: only {} scored predictions", p.n);
    (
        [p.max_abs_vs_truth[0], p.max_abs_vs_truth[1]],
        [p.rms_vs_truth[0], p.rms_vs_truth[1]],
    )
}

#[test]
fn ese_beats_kf_and_stf_on_the_zenith_pass() {
    let kf = run("ca-kf");
    let stf = run("stf");
    let ese = run("ese");
    let mut max_az = Vec::new();
    for (name, r) in [("ca-kf", &kf), ("stf", &stf), ("ese", &ese)] {
        let (max, rms) = errors(name, r);
        println!(
            "{name:>6}: one-step error vs truth  az max {:8.3} µrad rms {:7.3} µrad | el max {:7.3} µrad rms {:6.3} µrad",
            max[0] * 1e6,
            rms[0] * 1e6,
            max[1] * 1e6,
            rms[1] * 1e6
        );
        max_az.push(max[0]);
    }
    let [kf_az, stf_az, ese_az] = max_az[..] else {
        unreachable!()
    };
    assert!(ese_az <= stf_az, "ESE {ese_az} vs STF {stf_az}");
    assert!(ese_az <= kf_az / 10.0, "ESE {ese_az} vs KF {kf_az}");

    // score.py agrees with the in-process score.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ese.jsonl");
    replay::write_estimates(&path, &ese.estimates).unwrap();
    let py = score_py(&scenario("zenith_pass"), &path).unwrap();
    let py_az = py["prediction"]["az_el"]["max_abs_vs_truth"][0]
        .as_f64()
        .expect("score.py reports the azimuth prediction error");
    let rel = (py_az - ese_az).abs() / ese_az;
    println!(
        "score.py ESE az max {:.6} µrad (relative difference {rel:.1e})",
        py_az * 1e6
    );
    assert!(rel <= 1e-9, "score.py {py_az} vs Rust {ese_az}");
}
