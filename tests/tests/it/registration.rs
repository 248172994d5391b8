//! Sensor registration (issue 21) in replay: `harrier replay -e registration` on
//! `harrier gen-registration` scenarios (FORMAT-REGISTRATION.md), one estimator with one tuning
//! (every sensor with Harrier's default bias model), against its baselines, over two seeds — the
//! short version of `scripts/eval_registration.py` (BENCHMARKS.md, "Sensor registration").
//!
//! Every scenario is written to a temporary directory and read back with `harrier replay`'s
//! loader (with its `references.jsonl`); the bias bound comes from the independent
//! `scripts/registration_crlb.py` (numpy). Starts nothing else.

use std::path::Path;
use std::process::Command;

use harrier_core::metrics::chi2_quantile;
use harrier_core::registration::generate::{Case, GenConfig, Variant};
use harrier_core::registration::{BiasTruth, Term};
use harrier_core::scenario::Estimate;
use harrier_engine::Params;
use harrier_tools::replay::{self, ReplayReport};

const SEEDS: [u64; 2] = [1, 2];

/// One generated scenario, written to disk and replayed with `registration`.
struct Run {
    _dir: tempfile::TempDir,
    path: std::path::PathBuf,
    report: ReplayReport,
}

impl Run {
    fn new(seed: u64, case: Case, variant: Variant, duration: f64) -> Self {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("scenario");
        let cfg = GenConfig {
            case,
            variant,
            duration,
        };
        harrier_tools::gen_registration::write(&path, seed, &cfg).expect("generate");
        let data = replay::load(&path).expect("scenario loads");
        assert_eq!(data.references.is_empty(), case != Case::RadarReference);
        let report = replay::run(&data, "registration", &Params::default()).expect("replay");
        assert!(report.rejected.is_empty(), "{:?}", report.rejected);
        Self {
            _dir: dir,
            path,
            report,
        }
    }

    fn rmse(&self) -> f64 {
        harrier_tests::pos_rmse(self.report.score.as_ref().expect("truth"))
    }

    fn truth(&self) -> BiasTruth {
        let text = std::fs::read_to_string(self.path.join("bias_truth.csv")).expect("bias truth");
        BiasTruth::parse(&text).expect("bias truth parses")
    }

    fn last(&self) -> &Estimate {
        self.report.estimates.last().expect("estimates")
    }
}

/// A sensor's `bias_est` entry of an estimate line.
fn bias<'a>(e: &'a Estimate, sensor: &str) -> &'a serde_json::Value {
    &e.extra["bias_est"][sensor]
}

/// The value of `term` in a `bias_est` entry (`suffix` ""), or its standard deviation
/// (`suffix` "_std").
fn field(b: &serde_json::Value, term: Term, suffix: &str) -> f64 {
    let v = match term {
        Term::Offset(i) => &b[format!("offset{suffix}")][i],
        Term::Scale(i) => &b[format!("scale{suffix}")][i],
        Term::TimeOffset => &b[format!("time_offset{suffix}")],
    };
    v.as_f64()
        .unwrap_or_else(|| panic!("{term:?}{suffix} in {b}"))
}

/// The value of `term` in a `bias_est` entry.
fn value(b: &serde_json::Value, term: Term) -> f64 {
    field(b, term, "")
}

/// The standard deviation of `term` in a `bias_est` entry.
fn std_of(b: &serde_json::Value, term: Term) -> f64 {
    field(b, term, "_std")
}

fn observable(b: &serde_json::Value, term: Term) -> bool {
    let v = match term {
        Term::Offset(i) => &b["observable"]["offset"][i],
        Term::Scale(i) => &b["observable"]["scale"][i],
        Term::TimeOffset => &b["observable"]["time_offset"],
    };
    v.as_bool().expect("flag")
}

/// For each of `sensor`'s `terms`: the sum of its squared errors from 60 s on, and the sum of
/// the CRLB variances of the same scans (`scripts/registration_crlb.py`'s RMS from 60 s, squared,
/// times the number of scans).
fn bias_error_and_bound(run: &Run, sensor: &str, terms: &[Term]) -> Vec<(f64, f64)> {
    let truth = run.truth();
    let crlb = crlb(&run.path);
    terms
        .iter()
        .map(|&term| {
            let errors: Vec<f64> = run
                .report
                .estimates
                .iter()
                .filter(|e| e.t >= 60.0)
                .map(|e| value(bias(e, sensor), term) - truth.at(sensor, term, e.t))
                .collect();
            let bound = crlb["terms"]
                .as_array()
                .expect("terms")
                .iter()
                .find(|t| t["sensor"] == sensor && t["term"] == term.name().as_str())
                .and_then(|t| t["rms_after"].as_f64())
                .expect("bound of the term");
            let n = errors.len() as f64;
            (errors.iter().map(|e| e * e).sum(), bound * bound * n)
        })
        .collect()
}

/// `python3 scripts/registration_crlb.py DIR --json`.
fn crlb(dir: &Path) -> serde_json::Value {
    harrier_tests::require_python_module("numpy", "numpy");
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scripts/registration_crlb.py");
    let out = Command::new("python3")
        .arg(script)
        .arg(dir)
        .arg("--json")
        .output()
        .expect("python3");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON")
}

/// The fraction of scans from 60 s on whose radar bias NEES (over its terms, with the covariance
/// the line reports) is within the χ² 95 % bound.
fn radar_nees_ok(run: &Run) -> f64 {
    let truth = run.truth();
    let mut ok = 0;
    let mut n = 0;
    for e in run.report.estimates.iter().filter(|e| e.t >= 60.0) {
        let b = bias(e, "radar1");
        let terms: Vec<Term> = b["terms"]
            .as_array()
            .expect("terms")
            .iter()
            .map(|t| Term::parse(t.as_str().expect("name")).expect("term"))
            .collect();
        let k = terms.len();
        let err = nalgebra::DVector::from_iterator(
            k,
            terms
                .iter()
                .map(|t| value(b, *t) - truth.at("radar1", *t, e.t)),
        );
        let cov =
            nalgebra::DMatrix::from_fn(k, k, |i, j| b["cov"][i][j].as_f64().expect("covariance"));
        let nees = err.dot(&cov.cholesky().expect("SPD").solve(&err));
        ok += usize::from(nees <= chi2_quantile(0.95, k));
        n += 1;
    }
    ok as f64 / n as f64
}

/// At the end of `run` the sensors `biased` are biased with probability above 0.99 and the
/// sensors `unbiased` with probability below 0.1 (`bias_est.*.biased_prob`).
fn assert_biased(run: &Run, biased: &[&str], unbiased: &[&str]) {
    let last = run.last();
    let prob = |s: &str| bias(last, s)["biased_prob"].as_f64().expect("biased_prob");
    for s in biased {
        assert!(prob(s) > 0.99, "{s}: {}", prob(s));
    }
    for s in unbiased {
        assert!(prob(s) < 0.1, "{s}: {}", prob(s));
    }
}

/// No bias and constant radar offsets: the cost of registering against a filter told the true
/// bias (without bias the "no bias" mode takes the weight), the radar's offsets after 60 s
/// against the Cramér–Rao bound, and the bias NEES.
#[test]
fn constant_radar_offsets_are_learnt_to_the_bound() {
    let (mut none, mut constant) = (Vec::new(), Vec::new());
    let (mut err, mut bound) = ([0.0; 2], [0.0; 2]);
    for seed in SEEDS {
        let told = Run::new(seed, Case::Constant, Variant::ToldBias, 600.0).rmse();
        let unbiased = Run::new(seed, Case::None, Variant::Deployment, 600.0);
        let run = Run::new(seed, Case::Constant, Variant::Deployment, 600.0);
        none.push(unbiased.rmse() / told);
        constant.push(run.rmse() / told);
        let offsets = [Term::Offset(0), Term::Offset(1)];
        for (i, (e, b)) in bias_error_and_bound(&run, "radar1", &offsets)
            .into_iter()
            .enumerate()
        {
            err[i] += e;
            bound[i] += b;
        }
        let nees = radar_nees_ok(&run);
        println!(
            "seed {seed}: RMSE told-bias {told:.2} m, none {:.2}, constant {:.2}; radar bias NEES ok {nees:.3}",
            unbiased.rmse(),
            run.rmse()
        );
        assert!(nees >= 0.9, "seed {seed}: bias NEES within 95 % in {nees}");
        let none_prob = |r: &Run| r.last().extra["bias_none_prob"].as_f64().unwrap();
        assert!(none_prob(&unbiased) > 0.99 && none_prob(&run) < 1e-3);
        assert_biased(&run, &["radar1"], &["cam1", "cam2"]);
        let last = bias(run.last(), "radar1");
        assert!(observable(last, Term::Offset(0)) && observable(last, Term::Offset(1)));
    }
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let ratio = [(err[0] / bound[0]).sqrt(), (err[1] / bound[1]).sqrt()];
    println!(
        "RMSE / told-bias: none {none:.3?}, constant {constant:.3?}; bias error / √CRLB: range {:.3}, azimuth {:.3}",
        ratio[0], ratio[1]
    );
    assert!(mean(&constant) <= 1.2, "constant: {constant:?}");
    assert!(none.iter().all(|r| *r <= 1.05), "none: {none:?}");
    assert!(ratio.iter().all(|r| *r <= 1.5), "{ratio:?}");
}

/// Gauss–Markov radar offsets: within 1.2 of the filter told the bias model (σ, τ) but not its
/// values.
#[test]
fn gauss_markov_offsets_are_followed_as_well_as_with_the_model() {
    let mut ratios = Vec::new();
    for seed in SEEDS {
        let run = Run::new(seed, Case::GaussMarkov, Variant::Deployment, 600.0);
        let model = Run::new(seed, Case::GaussMarkov, Variant::ToldModel, 600.0);
        ratios.push(run.rmse() / model.rmse());
        println!(
            "seed {seed}: RMSE {:.2} m, told the model {:.2} m, drifting mode at the end {:.3}",
            run.rmse(),
            model.rmse(),
            run.last().extra["bias_drift_prob"]
        );
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!(mean <= 1.2, "{ratios:?}");
}

/// Cameras mounted 0.5° off in azimuth and elevation, and one camera 200 ms late: estimated to
/// 0.05° and 20 ms, the track back within 10 % of the unbiased run.
#[test]
fn camera_mounting_and_latency_are_estimated() {
    for seed in SEEDS {
        let mounted = Run::new(seed, Case::Mounting, Variant::Deployment, 600.0);
        let unbiased = Run::new(seed, Case::None, Variant::Deployment, 600.0);
        let truth = mounted.truth();
        let t = mounted.last().t;
        for cam in ["cam1", "cam2"] {
            for term in [Term::Offset(0), Term::Offset(1)] {
                let b = bias(mounted.last(), cam);
                let err = (value(b, term) - truth.at(cam, term, t)).abs().to_degrees();
                assert!(observable(b, term), "{cam} {term:?}");
                assert!(err <= 0.05, "seed {seed} {cam} {term:?}: {err}°");
            }
        }
        // The issue asks 1.1: 1.08 mean, 1.18 worst over 8 seeds with the sets of biased
        // sensors weighed (1.17 and 1.32 without; BENCHMARKS.md); this guards the worst.
        let ratio = mounted.rmse() / unbiased.rmse();
        assert!(ratio <= 1.2, "seed {seed}: {ratio}");
        assert_biased(&mounted, &["cam1", "cam2"], &["radar1"]);
        let late = Run::new(seed, Case::TimeOffset, Variant::Deployment, 600.0);
        assert_biased(&late, &["cam1"], &["cam2", "radar1"]);
        let delta = value(bias(late.last(), "cam1"), Term::TimeOffset);
        println!(
            "seed {seed}: mounted / unbiased RMSE {ratio:.3}, latency 0.2 s estimated {delta:.4} s"
        );
        assert!((delta - 0.2).abs() <= 0.02, "seed {seed}: {delta}");
    }
}

/// One radar alone: with a UAV it paints, its range and azimuth offsets are observable from the
/// UAV's GPS and estimated to the bound; without it, reported unobservable, held at the prior
/// and reported as uncertain as the prior.
#[test]
fn a_painted_uav_makes_a_lone_radars_bias_observable() {
    let (mut err, mut bound) = ([0.0; 2], [0.0; 2]);
    for seed in SEEDS {
        let painted = Run::new(seed, Case::RadarReference, Variant::Deployment, 300.0);
        let b = bias(painted.last(), "radar1");
        let offsets = [Term::Offset(0), Term::Offset(1)];
        for term in offsets {
            assert!(observable(b, term), "seed {seed} {term:?}");
        }
        let bounds = bias_error_and_bound(&painted, "radar1", &offsets);
        for (i, (e, c)) in bounds.into_iter().enumerate() {
            err[i] += e;
            bound[i] += c;
        }
        let alone = Run::new(seed, Case::RadarAlone, Variant::Deployment, 300.0);
        let b = bias(alone.last(), "radar1");
        assert_eq!(b["observable"]["all"], false);
        let prior = [50.0, 0.01, 0.005, 0.3];
        for (term, sigma) in [
            Term::Offset(0),
            Term::Offset(1),
            Term::Scale(0),
            Term::TimeOffset,
        ]
        .into_iter()
        .zip(prior)
        {
            assert!(!observable(b, term), "seed {seed} {term:?}");
            assert!(
                value(b, term).abs() <= 0.05 * sigma,
                "seed {seed} {term:?}: {b}"
            );
            // Held at the prior, and as uncertain as the prior: the "no bias" hypothesis, which
            // the data cannot reject here, does not shrink it.
            assert!(
                std_of(b, term) >= 0.9 * sigma,
                "seed {seed} {term:?}: std {} of prior {sigma}",
                std_of(b, term)
            );
        }
        println!(
            "seed {seed}: RMSE with the UAV {:.2} m, without {:.2} m",
            painted.rmse(),
            alone.rmse()
        );
        assert!(painted.rmse() * 2.0 < alone.rmse());
    }
    let ratio = [(err[0] / bound[0]).sqrt(), (err[1] / bound[1]).sqrt()];
    println!(
        "bias error / √CRLB with the UAV: range {:.3}, azimuth {:.3}",
        ratio[0], ratio[1]
    );
    assert!(ratio.iter().all(|r| *r <= 1.5), "{ratio:?}");
}

/// The live service's registrar (the track engine's `BiasBank`) on the same scenarios, through
/// `harrier replay -e tracker --register`: constant radar offsets learnt and observable, the
/// track within 1.2 × the same engine on the data with the biases taken out; without a bias
/// within 1.05 × of it; Gauss–Markov offsets within 1.2 × the engine told their model; a lone
/// radar's offsets reported unobservable; a camera's latency learnt without duplicate tracks;
/// mounted cameras' offsets learnt to 0.05°;
/// without `--register` no `bias_est` and a track over 3 × worse.
/// (Its figures over 8 seeds and every case: BENCHMARKS.md, "The live registrar on the replay scenarios".)
#[test]
fn the_live_registrar_learns_the_replay_scenarios() {
    /// A number of `sensor`'s entry in the last line's `bias_est`.
    fn value_of(run: &ReplayReport, sensor: &str, key: &str) -> f64 {
        let last = run.estimates.last().expect("estimates");
        bias(last, sensor)[key]
            .as_f64()
            .unwrap_or_else(|| panic!("{key} of {sensor}"))
    }
    /// The live engine (`ekf` tracks, `gnn`) over one scenario, and its position RMSE from
    /// 10 s on: the confirmed track nearest the truth at each line (a line without one fails).
    fn live(
        seed: u64,
        case: Case,
        variant: Variant,
        register: bool,
    ) -> (ReplayReport, f64, BiasTruth) {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("scenario");
        let cfg = GenConfig {
            case,
            variant,
            duration: 600.0,
        };
        harrier_tools::gen_registration::write(&path, seed, &cfg).expect("generate");
        let data = replay::load(&path).expect("scenario loads");
        let choice = replay::TrackerChoice {
            filter: "ekf".into(),
            associator: "gnn".into(),
            register,
        };
        let report = replay::run_tracker(&data, &choice, &Params::default()).expect("replay");
        assert!(report.rejected.is_empty(), "{:?}", report.rejected);
        let truth = data.truth.as_deref().expect("truth");
        let mut sq = Vec::new();
        for e in report.estimates.iter().filter(|e| e.t >= 10.0) {
            let (x, _, _) = harrier_core::scenario::truth_at(truth, e.t).expect("truth at t");
            let nearest = e.extra["tracks"]
                .as_array()
                .expect("tracks")
                .iter()
                .map(|k| {
                    let s = &k["state"];
                    let d = |i: usize| s[i].as_f64().expect("state") - x[i];
                    d(0).hypot(d(1))
                })
                .min_by(f64::total_cmp);
            sq.push(nearest.unwrap_or_else(|| panic!("seed {seed} {case:?}: no track at {}", e.t)));
        }
        let rmse = (sq.iter().map(|d| d * d).sum::<f64>() / sq.len() as f64).sqrt();
        let text = std::fs::read_to_string(path.join("bias_truth.csv")).expect("bias truth");
        (
            report,
            rmse,
            BiasTruth::parse(&text).expect("bias truth parses"),
        )
    }
    for seed in SEEDS {
        let (run, rmse, truth) = live(seed, Case::Constant, Variant::Deployment, true);
        let (_, told, _) = live(seed, Case::Constant, Variant::ToldBias, false);
        let (plain, unregistered, _) = live(seed, Case::Constant, Variant::Deployment, false);
        assert!(
            !plain
                .estimates
                .iter()
                .any(|e| e.extra.contains_key("bias_est"))
        );
        let last = run.estimates.last().expect("estimates");
        let b = bias(last, "radar1");
        println!(
            "seed {seed}: RMSE registered {rmse:.2} m, told the bias {told:.2} m, unregistered \
             {unregistered:.2} m; radar offsets {:.2} ± {:.2} m (truth {:.2}), {:.5} ± {:.5} rad \
             (truth {:.5})",
            value(b, Term::Offset(0)),
            std_of(b, Term::Offset(0)),
            truth.at("radar1", Term::Offset(0), last.t),
            value(b, Term::Offset(1)),
            std_of(b, Term::Offset(1)),
            truth.at("radar1", Term::Offset(1), last.t),
        );
        for term in [Term::Offset(0), Term::Offset(1)] {
            let err = value(b, term) - truth.at("radar1", term, last.t);
            assert!(observable(b, term), "seed {seed} {term:?}");
            assert!(
                err.abs() <= 3.0 * std_of(b, term),
                "seed {seed} {term:?}: {b}"
            );
        }
        assert!(rmse <= 1.2 * told, "seed {seed}: {rmse} vs {told}");
        assert!(
            3.0 * rmse < unregistered,
            "seed {seed}: {rmse} vs {unregistered}"
        );
        // No bias: within 5 % of the engine told the bias (the output weighs "no sensor
        // biased"); Gauss–Markov offsets (σ 20–40 m, τ 60–200 s): within 1.2 × the engine told
        // their model but not their values (the drifting mode follows them).
        let (clean, unbiased, _) = live(seed, Case::None, Variant::Deployment, true);
        let p = value_of(&clean, "radar1", "biased_prob");
        println!(
            "seed {seed}: no bias {unbiased:.2} m against {told:.2} m, radar biased with p {p:.3}"
        );
        assert!(unbiased <= 1.05 * told, "seed {seed}: {unbiased} vs {told}");
        assert!(p < 0.5, "seed {seed}: {p}");
        let (drifting, wandering, _) = live(seed, Case::GaussMarkov, Variant::Deployment, true);
        let (_, modelled, _) = live(seed, Case::GaussMarkov, Variant::ToldModel, true);
        let p = value_of(&drifting, "radar1", "bias_drift_prob");
        println!(
            "seed {seed}: Gauss-Markov {wandering:.2} m against {modelled:.2} m told the model, \
             drifting mode at the end {p:.3}"
        );
        assert!(
            wandering <= 1.2 * modelled,
            "seed {seed}: {wandering} vs {modelled}"
        );
        let (alone, _, _) = live(seed, Case::RadarAlone, Variant::Deployment, true);
        let b = bias(alone.estimates.last().expect("estimates"), "radar1");
        assert_eq!(b["observable"]["all"], false, "seed {seed}: {b}");
        // A camera 200 ms late: learnt within 20 ms, and its detections of the 10 m/s target
        // stay on the target's track (before the target's motion in δ̂ was in the tracker's
        // noise, they fell outside its gate and started duplicates that took the latency to
        // 160 ms: 19 tracks on seed 2).
        let (late, _, _) = live(seed, Case::TimeOffset, Variant::Deployment, true);
        let delta = value(
            bias(late.estimates.last().expect("estimates"), "cam1"),
            Term::TimeOffset,
        );
        let ids: std::collections::BTreeSet<u64> = late
            .estimates
            .iter()
            .flat_map(|e| e.extra["tracks"].as_array().expect("tracks"))
            .map(|k| k["id"].as_u64().expect("id"))
            .collect();
        println!("seed {seed}: latency 0.2 s learnt {delta:.4} s, confirmed tracks {ids:?}");
        assert!((delta - 0.2).abs() <= 0.02, "seed {seed}: {delta}");
        assert!(ids.len() <= 2, "seed {seed}: {ids:?}");
    }
    // Cameras mounted 0.5° off: each azimuth and elevation within 0.05°, the track within
    // 1.2 × the unbiased run's. Seed 4 read both azimuths 0.08° off before a camera's latency
    // was weighed apart from its offsets (it read ~15 ms of latency there is none of).
    for seed in [1, 2, 4] {
        let (mounted, rmse, truth) = live(seed, Case::Mounting, Variant::Deployment, true);
        let (_, unbiased, _) = live(seed, Case::None, Variant::Deployment, true);
        let last = mounted.estimates.last().expect("estimates");
        for cam in ["cam1", "cam2"] {
            let b = bias(last, cam);
            for term in [Term::Offset(0), Term::Offset(1)] {
                let err = (value(b, term) - truth.at(cam, term, last.t))
                    .abs()
                    .to_degrees();
                println!("seed {seed}: {cam} {term:?} mounting off by {err:.4}°");
                assert!(observable(b, term), "seed {seed} {cam} {term:?}");
                assert!(err <= 0.05, "seed {seed} {cam} {term:?}: {err}°");
            }
        }
        println!("seed {seed}: mounted {rmse:.2} m against {unbiased:.2} m unbiased");
        assert!(rmse <= 1.2 * unbiased, "seed {seed}: {rmse} vs {unbiased}");
    }
}
