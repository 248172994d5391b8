use nalgebra::{Matrix3, Matrix4, Vector2, Vector3, Vector4};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::generate::{Case, GenConfig, Variant, generate};
use super::*;
use crate::measurement::{Geometry, MeasKind, MeasurementModel, RangeBearing, SensorModel};
use crate::scenario::ScenarioData;
use crate::state::Gaussian;

fn radar_only(bias: &SensorBias, tuning: Tuning) -> Registration<4, 8> {
    Registration::new(0.01, 0.0, &[(2, Some(bias))], tuning).unwrap()
}

fn start(reg: &Registration<4, 8>, x: Vector4<f64>) -> RegistrationState<8> {
    let g = Gaussian::new(
        x,
        Matrix4::from_diagonal(&Vector4::new(2500.0, 2500.0, 4.0, 4.0)),
    )
    .unwrap();
    reg.initial(&g).unwrap()
}

#[test]
fn prediction_follows_each_terms_dynamics() {
    let bias = SensorBias {
        offset: vec![
            Some(BiasPrior {
                mean: 10.0,
                ..BiasPrior::gauss_markov(30.0, 100.0)
            }),
            Some(BiasPrior::constant(0.01)),
        ],
        scale: vec![Some(BiasPrior::random_walk(0.01, 0.001))],
        time_offset: None,
    };
    let reg = radar_only(&bias, Tuning::default());
    let mut s = start(&reg, Vector4::new(0.0, 0.0, 10.0, 0.0));
    s.estimate.mean[4] = 70.0;
    let p = reg.predict(&s, 50.0).unwrap();
    let phi = (-0.5f64).exp();
    // Gauss–Markov: back towards its mean, variance stationary.
    assert!((p.estimate.mean[4] - (10.0 + phi * 60.0)).abs() < 1e-9);
    assert!((p.estimate.cov[(4, 4)] - 900.0).abs() < 1e-6);
    // Constant: unchanged. Random walk: variance grows by d² Δt.
    assert_eq!(p.estimate.cov[(5, 5)], 1e-4);
    assert!((p.estimate.cov[(6, 6)] - (1e-4 + 1e-6 * 50.0)).abs() < 1e-12);
    assert_eq!(p.estimate.mean[0], 500.0);
    // Padding stays as it was.
    assert_eq!(p.estimate.cov[(7, 7)], 1.0);
    assert!(reg.predict(&s, -1.0).is_err());
    assert_eq!(reg.predict(&s, 0.0).unwrap(), s);
}

/// A radar that sees only the target cannot tell a rotated or scaled track from the true one:
/// held, its azimuth offset and range scale stay at the prior and are reported unobservable;
/// estimated anyway (`hold: false`), they wander.
#[test]
fn a_radar_alone_holds_what_it_cannot_observe() {
    let bias = SensorBias {
        offset: vec![None, Some(BiasPrior::constant(0.01))],
        scale: vec![Some(BiasPrior::constant(0.005))],
        time_offset: None,
    };
    let truth_az = 0.006;
    let run = |hold: bool| {
        let reg = radar_only(&bias, Tuning { kappa: 0.3, hold });
        let mut s = start(&reg, Vector4::new(1000.0, 3000.0, 8.0, -3.0));
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let radar = RangeBearing::new(Geometry::spatial(), Vector3::zeros(), [5.0, 0.002]);
        let model = SensorModel::RangeBearing(radar);
        for k in 1..=300 {
            let t = k as f64;
            let turn = if k > 150 { (k - 150) as f64 } else { 0.0 };
            let truth = nalgebra::Vector6::new(
                1000.0 + 8.0 * t,
                3000.0 - 3.0 * t + 0.02 * turn * turn,
                0.0,
                0.0,
                0.0,
                0.0,
            );
            let h: Vector2<f64> = radar.function(&truth);
            let n: [f64; 2] = [
                StandardNormal.sample(&mut rng),
                StandardNormal.sample(&mut rng),
            ];
            let z = [h[0] + 5.0 * n[0], h[1] + truth_az + 0.002 * n[1]];
            s = reg.predict(&s, 1.0).unwrap();
            let obs = Observation {
                sensor: 0,
                model: &model,
                platform_vel: Vector3::zeros(),
                z: &z,
            };
            s = reg.update(&s, &obs, &Seen::Target).unwrap().state;
        }
        (reg.estimates(&s).remove(0), s)
    };
    let (held, s) = run(true);
    let az = held.term(Term::Offset(1)).unwrap();
    assert!(!az.observable && !held.observable, "{held:?}");
    assert_eq!((az.value, az.std), (0.0, 0.01));
    assert_eq!(held.term(Term::Scale(0)).unwrap().value, 0.0);
    // The target carries the bias's uncertainty honestly: cross-range std ≥ 3 km × 10 mrad.
    assert!(s.estimate.cov[(0, 0)] + s.estimate.cov[(1, 1)] > 25.0 * 25.0);
    let (free, _) = run(false);
    assert_ne!(free.term(Term::Offset(1)).unwrap().value, 0.0);
}

/// A UAV reporting its GPS position, painted by the radar every second, makes the range and
/// azimuth offsets observable and estimates them to within 3σ.
#[test]
fn references_make_a_radars_offsets_observable() {
    let bias = SensorBias {
        offset: vec![
            Some(BiasPrior::constant(50.0)),
            Some(BiasPrior::constant(0.01)),
        ],
        scale: Vec::new(),
        time_offset: Some(BiasPrior::constant(0.3)),
    };
    let reg = radar_only(&bias, Tuning::default());
    let mut s = start(&reg, Vector4::new(2000.0, 1000.0, 5.0, 5.0));
    let truth = [30.0, 0.005];
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    let radar_at = Vector3::new(0.0, 0.0, 10.0);
    let radar = RangeBearing::new(Geometry::spatial(), radar_at, [5.0, 0.002]);
    let model = SensorModel::RangeBearing(radar);
    for k in 1..=120 {
        let a = 0.06 * k as f64;
        let pos = Vector3::new(2000.0 + 300.0 * a.sin(), 1000.0 + 300.0 * a.cos(), 120.0);
        let vel = Vector3::new(18.0 * a.cos(), -18.0 * a.sin(), 0.0);
        let x6 = nalgebra::Vector6::new(pos.x, pos.y, pos.z, 0.0, 0.0, 0.0);
        let h: Vector2<f64> = radar.function(&x6);
        let n: [f64; 4] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
        let z = [h[0] + truth[0] + 5.0 * n[0], h[1] + truth[1] + 0.002 * n[1]];
        let reported = pos + Vector3::new(n[2], n[3], 0.0);
        s = reg.predict(&s, 1.0).unwrap();
        let obs = Observation {
            sensor: 0,
            model: &model,
            platform_vel: Vector3::zeros(),
            z: &z,
        };
        let known = Seen::Known(KnownObject {
            pos: reported,
            vel,
            cov: Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, 4.0)),
        });
        s = reg.update(&s, &obs, &known).unwrap().state;
    }
    let e = reg.estimates(&s).remove(0);
    for (term, t) in [(Term::Offset(0), truth[0]), (Term::Offset(1), truth[1])] {
        let est = e.term(term).unwrap();
        assert!(est.observable, "{est:?}");
        assert!((est.value - t).abs() < 3.0 * est.std, "{est:?} vs {t}");
    }
    let json = e.to_json();
    assert_eq!(
        json["observable"]["offset"],
        serde_json::json!([true, true])
    );
    assert_eq!(
        json["terms"],
        serde_json::json!(["offset0", "offset1", "time_offset"])
    );
    assert_eq!(json["cov"].as_array().unwrap().len(), 3);
    assert!(json.get("scale").is_none());
}

#[test]
fn updates_refuse_bad_input_and_leave_the_state() {
    let reg = radar_only(
        &SensorBias::typical(MeasKind::RangeBearing),
        Tuning::default(),
    );
    let s = start(&reg, Vector4::new(2000.0, 1000.0, 5.0, 5.0));
    let model = SensorModel::new(
        MeasKind::RangeBearing,
        Geometry::spatial(),
        Vector3::zeros(),
        &[5.0, 0.002],
        None,
    )
    .unwrap();
    let obs = |z: &'static [f64], sensor| Observation {
        sensor,
        model: &model,
        platform_vel: Vector3::zeros(),
        z,
    };
    assert!(reg.update(&s, &obs(&[2200.0], 0), &Seen::Target).is_err());
    assert!(
        reg.update(&s, &obs(&[2200.0, 1.1], 3), &Seen::Target)
            .is_err()
    );
    assert!(
        reg.update(&s, &obs(&[f64::NAN, 1.1], 0), &Seen::Target)
            .is_err()
    );
    let bad = Seen::Known(KnownObject {
        pos: Vector3::new(f64::INFINITY, 0.0, 0.0),
        vel: Vector3::zeros(),
        cov: Matrix3::identity(),
    });
    assert!(reg.update(&s, &obs(&[2200.0, 1.1], 0), &bad).is_err());
    // Too many terms for the state.
    let many = SensorBias::typical(MeasKind::RangeBearing);
    let e = Registration::<4, 8>::new(
        0.1,
        0.0,
        &[(2, Some(&many)), (2, Some(&many))],
        Tuning::default(),
    );
    assert!(e.is_err());
}

#[test]
fn generator_is_seeded_and_its_cases_and_variants_share_the_noise() {
    let cfg = |case, variant| GenConfig {
        case,
        variant,
        duration: 400.0,
    };
    let a = generate(5, &cfg(Case::Constant, Variant::Deployment)).unwrap();
    assert_eq!(
        a,
        generate(5, &cfg(Case::Constant, Variant::Deployment)).unwrap()
    );
    assert_ne!(
        a.measurements_jsonl,
        generate(6, &cfg(Case::Constant, Variant::Deployment))
            .unwrap()
            .measurements_jsonl
    );
    let data =
        ScenarioData::parse(&a.scenario_json, &a.measurements_jsonl, Some(&a.truth_csv)).unwrap();
    assert_eq!(data.scenario.sensors.len(), 3);
    assert!(a.outages.len() >= 2, "{:?}", a.outages);
    // No camera line during an outage; the radar every second.
    for m in &data.measurements {
        let blind = a.outages.iter().any(|&(s, e)| m.t >= s && m.t < e);
        assert!(!(blind && m.sensor.starts_with("cam")), "{m:?}");
    }
    let radar = |d: &ScenarioData| -> Vec<Vec<f64>> {
        d.measurements
            .iter()
            .filter(|m| m.sensor == "radar1")
            .map(|m| m.z.clone())
            .collect()
    };
    assert_eq!(radar(&data).len(), 401);
    // The told-bias variant: the same noise, the bias taken out.
    let told = generate(5, &cfg(Case::Constant, Variant::ToldBias)).unwrap();
    let told = ScenarioData::parse(&told.scenario_json, &told.measurements_jsonl, None).unwrap();
    assert!(told.scenario.sensors.iter().all(|s| s.bias.is_none()));
    let truth = BiasTruth::parse(&a.bias_truth_csv).unwrap();
    let (o, oa, s) = (
        truth.at("radar1", Term::Offset(0), 0.0),
        truth.at("radar1", Term::Offset(1), 0.0),
        truth.at("radar1", Term::Scale(0), 0.0),
    );
    assert!((20.0..60.0).contains(&o.abs()) && (0.003..0.008).contains(&oa.abs()));
    for (b, u) in radar(&data).iter().zip(radar(&told)) {
        assert!((b[0] - ((1.0 + s) * u[0] + o)).abs() < 0.05, "{b:?} {u:?}");
        assert!((crate::linalg::wrap_angle(b[1] - u[1] - oa)).abs() < 1e-8);
    }
    // The none case of the seed is the unbiased data of every case.
    let none = generate(5, &cfg(Case::None, Variant::Deployment)).unwrap();
    assert_eq!(
        none.measurements_jsonl,
        generate(5, &cfg(Case::Mounting, Variant::ToldBias))
            .unwrap()
            .measurements_jsonl
    );
    assert_eq!(none.bias_truth_csv, "t,sensor,term,value\n");
}

#[test]
fn generator_writes_references_and_told_models() {
    let cfg = GenConfig {
        case: Case::RadarReference,
        variant: Variant::Deployment,
        duration: 120.0,
    };
    let g = generate(2, &cfg).unwrap();
    let data = ScenarioData::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv))
        .unwrap()
        .with_references(&g.references_jsonl)
        .unwrap();
    assert_eq!(data.scenario.sensors.len(), 1);
    let n = data.references.len();
    assert!((90..=121).contains(&n), "{n}");
    assert_eq!(data.references[0].object.id, "uav1");
    let alone = generate(
        2,
        &GenConfig {
            case: Case::RadarAlone,
            ..cfg
        },
    )
    .unwrap();
    assert!(alone.references_jsonl.is_empty());

    let gm = generate(
        2,
        &GenConfig {
            case: Case::GaussMarkov,
            variant: Variant::ToldModel,
            duration: 120.0,
        },
    )
    .unwrap();
    let sc = crate::scenario::Scenario::parse(&gm.scenario_json).unwrap();
    let cams: Vec<_> = sc
        .sensors
        .iter()
        .filter(|s| s.id.starts_with("cam"))
        .collect();
    assert!(cams.iter().all(|s| s.bias.is_none()));
    let radar = sc.sensor("radar1").unwrap();
    let b = SensorBias::from_block(radar.bias.as_ref().unwrap(), 2)
        .unwrap()
        .unwrap();
    assert!(
        matches!(b.offset[0].unwrap().dynamics, Dynamics::GaussMarkov { tau } if (60.0..200.0).contains(&tau))
    );
    assert!(b.scale.is_empty() && b.time_offset.is_none());
    // A Gauss–Markov truth moves.
    let truth = BiasTruth::parse(&gm.bias_truth_csv).unwrap();
    assert_ne!(
        truth.at("radar1", Term::Offset(0), 0.0),
        truth.at("radar1", Term::Offset(0), 100.0)
    );
    for case in Case::ALL {
        assert_eq!(Case::parse(case.name()), Some(case));
    }
    assert!(
        generate(
            1,
            &GenConfig {
                duration: 10.0,
                ..cfg
            }
        )
        .is_err()
    );
}

/// The bias modes: a radar range offset that ramps at 1 m/s, seen against GPS references, makes
/// the drifting mode win; a constant one leaves the steady mode in front; without an offset the
/// "no bias" mode wins.
#[test]
fn the_bias_modes_follow_what_the_references_show() {
    let bias = SensorBias {
        offset: vec![
            Some(BiasPrior::random_walk(50.0, 0.05)),
            Some(BiasPrior::random_walk(0.01, 1e-6)),
        ],
        scale: Vec::new(),
        time_offset: None,
    };
    let run = |offset: f64, ramp: f64| {
        let imm = RegistrationImm::new(radar_only(&bias, Tuning::default()), DriftModes::default())
            .unwrap();
        let g = Gaussian::new(
            Vector4::new(2000.0, 1000.0, 0.0, 0.0),
            Matrix4::from_diagonal(&Vector4::new(2500.0, 2500.0, 4.0, 4.0)),
        )
        .unwrap();
        let mut s = imm.initial(&g).unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(11);
        let radar = RangeBearing::new(Geometry::spatial(), Vector3::zeros(), [5.0, 0.002]);
        let model = SensorModel::RangeBearing(radar);
        for k in 1..=300 {
            let a = 0.05 * k as f64;
            let pos = Vector3::new(2000.0 + 300.0 * a.sin(), 1000.0 + 300.0 * a.cos(), 100.0);
            let x6 = nalgebra::Vector6::new(pos.x, pos.y, pos.z, 0.0, 0.0, 0.0);
            let h: Vector2<f64> = radar.function(&x6);
            let n: [f64; 2] = std::array::from_fn(|_| StandardNormal.sample(&mut rng));
            let z = [
                h[0] + offset + ramp * k as f64 + 5.0 * n[0],
                h[1] + 0.002 * n[1],
            ];
            s = imm.predict(&s, 1.0).unwrap();
            let obs = Observation {
                sensor: 0,
                model: &model,
                platform_vel: Vector3::zeros(),
                z: &z,
            };
            let known = Seen::Known(KnownObject {
                pos,
                vel: Vector3::new(15.0 * a.cos(), -15.0 * a.sin(), 0.0),
                cov: Matrix3::identity(),
            });
            s = imm.update(&s, &obs, &known).unwrap();
        }
        let c = imm.combined(&s);
        (s.probs, c.estimate.mean[4])
    };
    // Modes: [none, steady, drifting].
    let (steady, b) = run(20.0, 0.0);
    assert!(
        steady[0] < 1e-3 && steady[1] > 0.9 && (b - 20.0).abs() < 3.0,
        "{steady:?} {b}"
    );
    let (drifting, b) = run(20.0, 1.0);
    assert!(
        drifting[0] < 1e-3 && drifting[2] > 0.9 && (b - 320.0).abs() < 10.0,
        "{drifting:?} {b}"
    );
    // No bias: the unbiased mode takes the weight, the estimate is exactly at the prior mean.
    let (none, b) = run(0.0, 0.0);
    assert!(none[0] > 0.9 && b.abs() < 1.0, "{none:?} {b}");
    assert!(
        RegistrationImm::new(
            radar_only(&bias, Tuning::default()),
            DriftModes {
                factor: 0.5,
                ..DriftModes::default()
            }
        )
        .is_err()
    );
}

/// Taking a sensor as unbiased is the joint Gaussian conditioned on its block at the prior
/// mean (the same as a perfect measurement of the block), and the Savage–Dickey ratio is the
/// posterior density of the block there over the prior's.
#[test]
fn a_block_taken_at_its_prior_is_the_gaussian_conditional() {
    let bias = SensorBias {
        offset: vec![
            Some(BiasPrior::constant(50.0)),
            Some(BiasPrior::constant(0.01)),
        ],
        scale: Vec::new(),
        time_offset: None,
    };
    let reg = radar_only(&bias, Tuning::default());
    let mut s = start(&reg, Vector4::new(1000.0, 3000.0, 8.0, -3.0));
    // A correlated posterior: the target and both offsets moved and tied together.
    let a = nalgebra::SMatrix::<f64, 8, 8>::from_fn(|i, j| {
        if i < 6 && j < 6 {
            ((i * 7 + j * 3) % 5) as f64 * 0.3 - 0.5
        } else {
            0.0
        }
    });
    let scale = nalgebra::SVector::<f64, 8>::from_column_slice(&[
        4.0, 4.0, 1.0, 1.0, 12.0, 0.003, 1.0, 1.0,
    ]);
    let d = nalgebra::SMatrix::<f64, 8, 8>::from_diagonal(&scale);
    let cov = d * (a * a.transpose() + nalgebra::SMatrix::<f64, 8, 8>::identity()) * d;
    s.estimate.cov = cov;
    s.estimate.mean[4] = 20.0;
    s.estimate.mean[5] = 0.004;
    let (c, log_bf) = reg.given_prior(&s, &[4, 5]).unwrap();
    // The conditional as a Kalman update with a near-perfect measurement of the block.
    let h = nalgebra::SMatrix::<f64, 2, 8>::from_fn(|i, j| f64::from(j == i + 4));
    let innov = nalgebra::Vector2::new(0.0, 0.0) - h * s.estimate.mean;
    let sm = h * cov * h.transpose() + nalgebra::Matrix2::identity() * 1e-14;
    let gain = cov * h.transpose() * sm.try_inverse().unwrap();
    let mean = s.estimate.mean + gain * innov;
    let p = cov - gain * h * cov;
    for i in 0..4 {
        assert!((c.estimate.mean[i] - mean[i]).abs() < 1e-6, "{i}");
        for j in 0..4 {
            assert!((c.estimate.cov[(i, j)] - p[(i, j)]).abs() < 1e-6, "{i} {j}");
        }
    }
    assert_eq!((c.estimate.mean[4], c.estimate.mean[5]), (0.0, 0.0));
    assert_eq!((c.estimate.cov[(4, 4)], c.estimate.cov[(4, 0)]), (0.0, 0.0));
    let log_n = |r: nalgebra::Vector2<f64>, m: nalgebra::Matrix2<f64>| {
        -0.5 * (r.dot(&(m.try_inverse().unwrap() * r)) + m.determinant().ln())
    };
    let pcc = h * cov * h.transpose();
    let prior = nalgebra::Matrix2::new(2500.0, 0.0, 0.0, 1e-4);
    let expected = log_n(innov, pcc) - log_n(nalgebra::Vector2::zeros(), prior);
    assert!((log_bf - expected).abs() < 1e-9, "{log_bf} {expected}");
    // Nothing pinned: the state itself; an index that is not a bias term: refused.
    assert_eq!(reg.given_prior(&s, &[]).unwrap(), (s, 0.0));
    assert!(reg.given_prior(&s, &[0]).is_none());
}

/// The output's hypotheses: every non-empty set of biased sensors, and within it a biased sensor
/// whose terms are all constant, a time offset among them, biased three ways (every term free,
/// its time offset alone at the prior, its time offset alone free); a sensor with a drifting
/// term one way; each set's prior uniform over the sensor sets, then over the ways; too many
/// sets: the sensors alone.
#[test]
fn the_hypotheses_split_a_constant_sensors_latency_from_its_offsets() {
    use super::imm::biased_sets;
    let camera = SensorBias {
        offset: vec![
            Some(BiasPrior::constant(0.017)),
            Some(BiasPrior::constant(0.017)),
        ],
        scale: Vec::new(),
        time_offset: Some(BiasPrior::constant(0.3)),
    };
    let radar = SensorBias {
        offset: vec![Some(BiasPrior::random_walk(50.0, 0.1)), None],
        scale: Vec::new(),
        time_offset: Some(BiasPrior::constant(0.3)),
    };
    // State: 4 kinematic, cam1 4..7 (az, el, δ), cam2 7..10, radar 10..12 (range, δ).
    let reg = Registration::<4, 12>::new(
        0.01,
        0.0,
        &[(2, Some(&camera)), (2, Some(&camera)), (2, Some(&radar))],
        Tuning::default(),
    )
    .unwrap();
    let sets = biased_sets(&reg, true);
    // {cam1}, {cam2}: 3 ways; {radar}: 1; {cam1, cam2}: 9; with the radar 3, 3, 9.
    assert_eq!(sets.len(), 31);
    let total: f64 = sets.iter().map(|s| s.prior).sum();
    assert!((total - 1.0).abs() < 1e-12, "{total}");
    let last = sets.last().unwrap();
    assert_eq!(last.biased, [true; 3]);
    assert!(last.pinned.is_empty());
    assert!((last.prior - 1.0 / 63.0).abs() < 1e-12);
    // Every sensor biased, cam1's latency alone at the prior; cam2 with its latency alone free.
    assert!(
        sets.iter()
            .any(|s| s.biased == [true; 3] && s.pinned == [6])
    );
    assert!(
        sets.iter()
            .any(|s| s.biased == [true; 3] && s.pinned == [7, 8])
    );
    // The radar, with a random-walk offset, is never split: its two terms go together.
    for s in &sets {
        let radar: Vec<_> = s.pinned.iter().filter(|&&i| i >= 10).collect();
        assert!(radar.is_empty() || radar == [&10, &11], "{:?}", s.pinned);
        assert_eq!(s.biased[2], radar.is_empty(), "{s:?}");
    }
    // The sensors alone without `per_sensor`, and above MAX_SETS: four cameras make 255.
    assert_eq!(biased_sets(&reg, false).len(), 1);
    let four =
        Registration::<4, 16>::new(0.01, 0.0, &[(2, Some(&camera)); 4], Tuning::default()).unwrap();
    let sets = biased_sets(&four, true);
    assert_eq!(sets.len(), 15);
    assert!(sets.iter().all(|s| (s.prior - 1.0 / 15.0).abs() < 1e-12));
}
