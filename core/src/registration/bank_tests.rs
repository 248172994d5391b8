//! The bank against the single-target augmented filter on generated data: a radar with range
//! and azimuth offsets, a camera on a UAV circling two ground targets with mounting offsets.

use nalgebra::{Matrix3, Matrix4, Vector2, Vector3, Vector4, Vector6};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};

use super::*;
use crate::filter::{Extended, Predictor};
use crate::measurement::{AzEl, Geometry, MeasurementModel, RangeBearing, SensorModel};
use crate::motion::ConstantVelocity;
use crate::registration::{BiasPrior, DriftModes, SensorBias, Tuning};

const Q: f64 = 0.05;
const RADAR_AT: Vector3<f64> = Vector3::new(0.0, 0.0, 10.0);
const RADAR_STD: [f64; 2] = [5.0, 0.002];
const CAM_STD: [f64; 2] = [0.002, 0.002];
/// True biases: radar range, azimuth; camera azimuth, elevation.
const TRUTH: [f64; 4] = [30.0, 0.005, 0.0087, -0.0052];
const PRIOR_STD: [f64; 4] = [50.0, 0.01, 0.0175, 0.0175];

fn biases() -> [SensorBias; 2] {
    let c = |s| Some(BiasPrior::constant(s));
    [
        SensorBias {
            offset: vec![c(PRIOR_STD[0]), c(PRIOR_STD[1])],
            ..SensorBias::default()
        },
        SensorBias {
            offset: vec![c(PRIOR_STD[2]), c(PRIOR_STD[3])],
            ..SensorBias::default()
        },
    ]
}

fn registration() -> Registration<4, 8> {
    let [radar, camera] = biases();
    let tuning = Tuning {
        kappa: 0.3,
        hold: false,
    };
    Registration::new(Q, 0.0, &[(2, Some(&radar)), (2, Some(&camera))], tuning).unwrap()
}

/// The truth of target `i` at `t`: straight legs with a turn at 150 s.
fn target(i: usize, t: f64) -> (Vector2<f64>, Vector2<f64>) {
    let (p0, v0, v1) = if i == 0 {
        (
            Vector2::new(800.0, 600.0),
            Vector2::new(6.0, -3.0),
            Vector2::new(2.0, 6.0),
        )
    } else {
        (
            Vector2::new(1200.0, 900.0),
            Vector2::new(-4.0, 5.0),
            Vector2::new(-6.0, -2.0),
        )
    };
    if t < 150.0 {
        (p0 + v0 * t, v0)
    } else {
        (p0 + v0 * 150.0 + v1 * (t - 150.0), v1)
    }
}

/// The UAV carrying the camera: a 300 m orbit at 150 m above the targets' area.
fn uav(t: f64) -> (Vector3<f64>, Vector3<f64>) {
    let w = 18.0 / 300.0;
    let a = w * t;
    (
        Vector3::new(1000.0 + 300.0 * a.cos(), 750.0 + 300.0 * a.sin(), 150.0),
        Vector3::new(-18.0 * a.sin(), 18.0 * a.cos(), 0.0),
    )
}

/// One detection: sensor 0 (radar) or 1 (camera), of target `of` or of the UAV (a reference).
struct Detection {
    t: f64,
    sensor: usize,
    of: Option<usize>,
    z: [f64; 2],
}

/// Every detection over `duration` s: the camera sees every target at 2 Hz, the radar every
/// target each second, and paints the UAV every 5 s when `references`.
fn detections(seed: u64, targets: usize, duration: f64, references: bool) -> Vec<Detection> {
    detections_with(|_| TRUTH, seed, targets, duration, references)
}

/// [`detections`] with the true biases `truth(t)` (as [`TRUTH`]).
fn detections_with(
    truth: impl Fn(f64) -> [f64; 4],
    seed: u64,
    targets: usize,
    duration: f64,
    references: bool,
) -> Vec<Detection> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut n = || -> f64 { StandardNormal.sample(&mut rng) };
    let mut out = Vec::new();
    for k in 1..=(duration * 2.0) as usize {
        let t = k as f64 * 0.5;
        let truth = truth(t);
        let (at, _) = uav(t);
        let cam = AzEl::new(Geometry::spatial(), at, CAM_STD);
        let radar = RangeBearing::new(Geometry::spatial(), RADAR_AT, RADAR_STD);
        for i in 0..targets {
            let (p, _) = target(i, t);
            let x6 = Vector6::new(p.x, p.y, 0.0, 0.0, 0.0, 0.0);
            let h: Vector2<f64> = cam.function(&x6);
            out.push(Detection {
                t,
                sensor: 1,
                of: Some(i),
                z: [
                    h[0] + truth[2] + CAM_STD[0] * n(),
                    h[1] + truth[3] + CAM_STD[1] * n(),
                ],
            });
            if k % 2 == 0 {
                let h: Vector2<f64> = radar.function(&x6);
                out.push(Detection {
                    t,
                    sensor: 0,
                    of: Some(i),
                    z: [
                        h[0] + truth[0] + RADAR_STD[0] * n(),
                        h[1] + truth[1] + RADAR_STD[1] * n(),
                    ],
                });
            }
        }
        if references && k % 10 == 0 {
            let x6 = Vector6::new(at.x, at.y, at.z, 0.0, 0.0, 0.0);
            let h: Vector2<f64> = radar.function(&x6);
            out.push(Detection {
                t,
                sensor: 0,
                of: None,
                z: [
                    h[0] + truth[0] + RADAR_STD[0] * n(),
                    h[1] + truth[1] + RADAR_STD[1] * n(),
                ],
            });
        }
    }
    out
}

fn model_of(d: &Detection) -> (SensorModel, Vector3<f64>) {
    if d.sensor == 0 {
        let m = RangeBearing::new(Geometry::spatial(), RADAR_AT, RADAR_STD);
        (SensorModel::RangeBearing(m), Vector3::zeros())
    } else {
        let (at, vel) = uav(d.t);
        (
            SensorModel::AzEl(AzEl::new(Geometry::spatial(), at, CAM_STD)),
            vel,
        )
    }
}

/// The GPS report of the UAV at `t` (exact here; its 1 m noise is in the covariance).
fn reference(t: f64) -> KnownObject {
    let (pos, vel) = uav(t);
    KnownObject {
        pos,
        vel,
        cov: Matrix3::identity(),
    }
}

fn prior_of(i: usize) -> Gaussian<4> {
    let (p, v) = target(i, 0.0);
    Gaussian::new(
        Vector4::new(p.x + 20.0, p.y - 20.0, v.x, v.y),
        Matrix4::from_diagonal(&Vector4::new(900.0, 900.0, 9.0, 9.0)),
    )
    .unwrap()
}

/// The single-target augmented filter on target `i`'s detections (and the references).
fn augmented(dets: &[Detection], i: usize) -> Vec<(f64, RegistrationState<8>)> {
    let reg = registration();
    let mut s = reg.initial(&prior_of(i)).unwrap();
    let mut t = 0.0;
    let mut out = Vec::new();
    for d in dets.iter().filter(|d| d.of.is_none_or(|o| o == i)) {
        s = reg.predict(&s, d.t - t).unwrap();
        t = d.t;
        let (model, platform_vel) = model_of(d);
        let obs = Observation {
            sensor: d.sensor,
            model: &model,
            platform_vel,
            z: &d.z,
        };
        let seen = d.of.map_or(Seen::Known(reference(d.t)), |_| Seen::Target);
        s = reg.update(&s, &obs, &seen).unwrap().state;
        out.push((t, s));
    }
    out
}

/// The bank with one track per target: after each detection, the tracks and the bank's state.
fn banked(dets: &[Detection], targets: usize) -> Vec<(f64, Vec<Gaussian<4>>, BiasBank<4, 8>)> {
    banked_with(dets, targets, |_, _, _| {})
}

/// [`banked`] with the tracker's own update `own(track, t, state)` of each track after every
/// prediction, outside the bank.
fn banked_with(
    dets: &[Detection],
    targets: usize,
    own: impl FnMut(usize, f64, &mut Gaussian<4>),
) -> Vec<(f64, Vec<Gaussian<4>>, BiasBank<4, 8>)> {
    run_bank(BiasBank::new(registration()).unwrap(), dets, targets, own)
}

/// [`banked_with`] from `bank`.
fn run_bank(
    mut bank: BiasBank<4, 8>,
    dets: &[Detection],
    targets: usize,
    mut own: impl FnMut(usize, f64, &mut Gaussian<4>),
) -> Vec<(f64, Vec<Gaussian<4>>, BiasBank<4, 8>)> {
    let motion = ConstantVelocity::<4>::new(Q);
    let mut tracks: Vec<Gaussian<4>> = (0..targets).map(prior_of).collect();
    for (id, g) in tracks.iter().enumerate() {
        bank.add_track(id as TrackId, g).unwrap();
    }
    let mut t = 0.0;
    let mut out = Vec::new();
    for d in dets {
        if d.t > t {
            bank.predict(d.t - t).unwrap();
            for (i, g) in tracks.iter_mut().enumerate() {
                *g = Extended.predict(&motion, g, d.t - t).unwrap();
                own(i, d.t, g);
            }
            t = d.t;
        }
        let (model, platform_vel) = model_of(d);
        let obs = Observation {
            sensor: d.sensor,
            model: &model,
            platform_vel,
            z: &d.z,
        };
        let mut all: Vec<(TrackId, &mut Gaussian<4>)> = tracks
            .iter_mut()
            .enumerate()
            .map(|(i, g)| (i as TrackId, g))
            .collect();
        match d.of {
            Some(i) => bank.update(&mut all, i as TrackId, &obs).unwrap(),
            None => bank
                .update_reference(&mut all, &obs, &reference(d.t))
                .unwrap(),
        };
        out.push((t, tracks.clone(), bank.clone()));
    }
    out
}

/// With one track the bank is the augmented filter: the same means and covariances after
/// 300 s of radar, camera and reference detections (the bias rows, the target's, and their
/// cross-covariance).
#[test]
fn with_one_track_the_bank_is_the_augmented_filter() {
    let dets = detections(5, 1, 300.0, true);
    let aug = augmented(&dets, 0);
    let bank = banked(&dets, 1);
    assert_eq!(aug.len(), bank.len());
    let (_, s) = aug.last().unwrap();
    let (_, tracks, b) = bank.last().unwrap();
    let scale = |a: f64, b: f64| (a - b).abs() / (1e-9 + a.abs().max(b.abs()));
    for i in 0..4 {
        assert!(scale(s.estimate.mean[i], tracks[0].mean[i]) < 1e-6);
        for j in 0..4 {
            assert!(scale(s.estimate.cov[(i, j)], tracks[0].cov[(i, j)]) < 1e-6);
        }
    }
    let bs = b.state();
    let cross = b.cross(0).unwrap();
    for i in 4..8 {
        assert!(scale(s.estimate.mean[i], bs.estimate.mean[i]) < 1e-6);
        for j in 4..8 {
            assert!(scale(s.estimate.cov[(i, j)], bs.estimate.cov[(i, j)]) < 1e-6);
        }
        for r in 0..4 {
            assert!(scale(s.estimate.cov[(r, i)], cross[(r, i)]) < 1e-6);
        }
    }
    // The data do fix the biases (the comparison is not of two priors).
    for (i, (t, p)) in TRUTH.iter().zip(PRIOR_STD).enumerate() {
        let sd = bs.estimate.cov[(4 + i, 4 + i)].sqrt();
        assert!(sd < 0.2 * p && (bs.estimate.mean[4 + i] - t).abs() < 4.0 * sd);
    }
    assert!(b.estimates().iter().all(|e| e.observable));
}

/// Two targets seen by both sensors share the biases: the bank against the single-target
/// augmented filter on each target alone. Stated factors (4 seeds × 300 s; measured 0.53, 0.95
/// and 4.15): the bank's bias error at most 0.8 times the single-target filter's (it sees
/// twice the data), its tracks no worse, its bias NEES (4 terms) within 2–6.
#[test]
fn two_tracks_share_the_biases_as_well_as_one_augmented_filter() {
    let (mut bias_bank, mut bias_single) = (0.0, 0.0);
    let (mut track_bank, mut track_single) = (0.0, 0.0);
    let (mut nees, mut count) = (0.0, 0.0);
    for seed in 1..=4 {
        let dets = detections(seed, 2, 300.0, false);
        let bank = banked(&dets, 2);
        let singles = [augmented(&dets, 0), augmented(&dets, 1)];
        // Normalised bias error² and position error² from 100 s on.
        let bias_err = |m: &SVector<f64, 8>| -> f64 {
            (0..4)
                .map(|i| ((m[4 + i] - TRUTH[i]) / PRIOR_STD[i]).powi(2))
                .sum()
        };
        let pos_err = |t: f64, i: usize, m: &SVector<f64, 4>| -> f64 {
            let (p, _) = target(i, t);
            (m[0] - p.x).powi(2) + (m[1] - p.y).powi(2)
        };
        for (t, tracks, b) in bank.iter().filter(|(t, ..)| *t >= 100.0) {
            let s = b.state().estimate;
            bias_bank += bias_err(&s.mean);
            let e = s.mean.fixed_rows::<4>(4) - SVector::<f64, 4>::from(TRUTH);
            let c = s.cov.fixed_view::<4, 4>(4, 4).into_owned();
            nees += (e.transpose() * c.try_inverse().unwrap() * e)[0];
            count += 1.0;
            track_bank += (0..2).map(|i| pos_err(*t, i, &tracks[i].mean)).sum::<f64>() / 2.0;
        }
        let n_bank = bank.iter().filter(|(t, ..)| *t >= 100.0).count() as f64;
        for (i, single) in singles.iter().enumerate() {
            let late: Vec<_> = single.iter().filter(|(t, _)| *t >= 100.0).collect();
            let n = late.len() as f64;
            // Weighted to the bank's number of samples.
            let w = n_bank / n / 2.0;
            bias_single += w * late
                .iter()
                .map(|(_, s)| bias_err(&s.estimate.mean))
                .sum::<f64>();
            track_single += w * late
                .iter()
                .map(|(t, s)| pos_err(*t, i, &s.estimate.mean.fixed_rows::<4>(0).into_owned()))
                .sum::<f64>();
        }
    }
    let bias_ratio = (bias_bank / bias_single).sqrt();
    let track_ratio = (track_bank / track_single).sqrt();
    let nees = nees / count;
    println!(
        "bank / single: bias error {bias_ratio:.3}, track error {track_ratio:.3}; bias NEES {nees:.2} (4 dof)"
    );
    assert!(bias_ratio <= 0.8, "{bias_ratio}");
    assert!(track_ratio <= 1.0, "{track_ratio}");
    assert!((2.0..=6.0).contains(&nees), "{nees}");
}

/// `correct` takes the estimated offsets and scales out and maps their covariance into the
/// noise; bad input is refused.
#[test]
fn corrected_detections_carry_the_bias_uncertainty() {
    let radar = SensorBias {
        offset: vec![
            Some(BiasPrior {
                mean: 30.0,
                ..BiasPrior::constant(10.0)
            }),
            None,
        ],
        scale: vec![Some(BiasPrior {
            mean: 0.01,
            ..BiasPrior::constant(0.002)
        })],
        time_offset: Some(BiasPrior {
            mean: 0.2,
            ..BiasPrior::constant(0.05)
        }),
    };
    let reg = Registration::<4, 8>::new(Q, 0.0, &[(2, Some(&radar))], Tuning::default()).unwrap();
    let bank = BiasBank::new(reg).unwrap();
    let c = bank.correct(0, &[1040.0, 0.3]).unwrap();
    assert!((c.z[0] - 1000.0).abs() < 1e-9 && c.z[1] == 0.3);
    let var = (100.0 + (c.z[0] * 0.002).powi(2)) / 1.01f64.powi(2);
    assert!((c.extra_cov[(0, 0)] - var).abs() < 1e-9 * var);
    assert_eq!(c.extra_cov[(1, 1)], 0.0);
    assert_eq!((c.time_offset, c.time_offset_var), (0.2, 0.05 * 0.05));
    assert!(bank.correct(1, &[1.0, 2.0]).is_err());
    assert!(bank.correct(0, &[f64::NAN, 2.0]).is_err());
}

/// An unknown track, a reference update without every track, are refused and change nothing.
#[test]
fn the_bank_refuses_unknown_tracks() {
    let dets = detections(2, 1, 5.0, true);
    let mut bank = BiasBank::new(registration()).unwrap();
    let mut g = prior_of(0);
    bank.add_track(7, &g).unwrap();
    assert!(bank.add_track(7, &g).is_err());
    let before = bank.clone();
    let d = dets.iter().find(|d| d.sensor == 0).unwrap();
    let (model, platform_vel) = model_of(d);
    let obs = Observation {
        sensor: 0,
        model: &model,
        platform_vel,
        z: &d.z,
    };
    assert!(bank.update(&mut [(7, &mut g)], 3, &obs).is_err());
    assert!(bank.update(&mut [], 7, &obs).is_err());
    assert!(bank.update(&mut [(8, &mut g)], 7, &obs).is_err());
    assert!(
        bank.update_reference(&mut [], &obs, &reference(d.t))
            .is_err()
    );
    let bad = Observation { sensor: 5, ..obs };
    assert!(bank.update(&mut [(7, &mut g)], 7, &bad).is_err());
    assert_eq!(g, prior_of(0));
    assert!(bank.predict(-1.0).is_err());
    assert_eq!(bank, before);
    bank.remove_track(7);
    assert!(bank.cross(7).is_none() && bank.tracks().is_empty());
    assert_eq!(bank, BiasBank::new(registration()).unwrap());
}

/// A tracker whose own update shrinks a track's covariance between the bank's updates (a road
/// update: here the target's true north coordinate seen with 2 m noise, as a road along the east
/// would give) leaves the bank positive definite and its biases consistent: each track's
/// cross-covariances are carried through the tracker's change (`A = L_c L_b⁻¹`). Every update
/// succeeds, the joint covariance keeps a Cholesky factor, and each offset ends within 4 sd of
/// the truth.
#[test]
fn a_tracker_that_shrinks_its_tracks_keeps_the_bank_positive_definite() {
    let dets = detections(3, 2, 300.0, false);
    // The tracker's own update, outside the bank: north seen with 2 m noise (Joseph form).
    let north = |i: usize, t: f64, g: &mut Gaussian<4>| {
        let h = nalgebra::RowVector4::new(0.0, 1.0, 0.0, 0.0);
        let s = (h * g.cov * h.transpose())[0] + 4.0;
        let k = g.cov * h.transpose() / s;
        g.mean += k * (target(i, t).0.y - g.mean[1]);
        let a = Matrix4::identity() - k * h;
        g.cov = a * g.cov * a.transpose() + k * k.transpose() * 4.0;
    };
    let (_, _, bank) = banked_with(&dets, 2, north).pop().expect("updates");
    assert!(
        bank.modes[0].cov.clone().cholesky().is_some(),
        "{}",
        bank.modes[0].cov
    );
    let terms: Vec<_> = bank.estimates().into_iter().flat_map(|e| e.terms).collect();
    assert_eq!(terms.len(), 4);
    for (term, truth) in terms.iter().zip(TRUTH) {
        assert!(
            (term.value - truth).abs() <= 4.0 * term.std,
            "{term:?} against {truth}"
        );
    }
}

/// With the hold (`Tuning::hold`, the live registrar's), a radar alone leaves its offsets
/// where their prior puts them, reported unobservable, and the track carries their
/// uncertainty; with the UAV it paints they are learnt.
#[test]
fn with_the_hold_a_lone_radars_offsets_stay_at_their_prior() {
    let [radar, camera] = biases();
    let reg = Registration::<4, 8>::new(
        Q,
        0.0,
        &[(2, Some(&radar)), (2, Some(&camera))],
        Tuning::default(),
    )
    .unwrap();
    for references in [false, true] {
        let dets: Vec<Detection> = detections(3, 1, 300.0, references)
            .into_iter()
            .filter(|d| d.sensor == 0)
            .collect();
        let out = run_bank(BiasBank::new(reg.clone()).unwrap(), &dets, 1, |_, _, _| {});
        let (_, tracks, bank) = out.last().unwrap();
        let radar = &bank.estimates()[0];
        let offsets: Vec<(f64, f64)> = radar.terms.iter().map(|t| (t.value, t.std)).collect();
        println!(
            "references {references}: offsets {offsets:?}, observable {}",
            radar.observable
        );
        if references {
            assert!(radar.observable);
            for (t, truth) in radar.terms.iter().zip(TRUTH) {
                assert!((t.value - truth).abs() <= 3.0 * t.std, "{t:?}");
            }
        } else {
            assert!(!radar.observable);
            for (t, sd) in radar.terms.iter().zip(PRIOR_STD) {
                assert_eq!(t.value, 0.0, "{t:?}");
                assert!(t.std > 0.9 * sd, "{t:?}");
            }
            // The track's covariance carries the offsets' uncertainty: it covers the 30 m of
            // range offset the track is off by.
            let (p, _) = target(0, 300.0);
            let err = (tracks[0].mean.fixed_rows::<2>(0) - p).norm();
            let sd = tracks[0].cov.fixed_view::<2, 2>(0, 0).trace().sqrt();
            assert!(err <= 3.0 * sd, "track {err} m off with sd {sd} m");
        }
    }
}

/// The tracks of [`run_bank`] with their ids (their indices).
fn numbered(tracks: &[Gaussian<4>]) -> Vec<(TrackId, Gaussian<4>)> {
    tracks
        .iter()
        .enumerate()
        .map(|(i, g)| (i as TrackId, *g))
        .collect()
}

/// The output weighs which sensors are biased: on unbiased data "no bias" takes the weight and
/// the reported tracks come back to those of a bank told there is no bias (the same joint
/// filter without terms), closer than the bank's own; on biased data both sensors are biased
/// with probability 1 and the output is the bank's tracks. Stated factors (3 seeds, two
/// targets, position RMSE from 40 to 100 s, while the bank's own estimates of the four terms
/// still cost; measured: output / told 1.000, bank / told 1.075): the output within 2 % of
/// told, and better than the bank's own.
#[test]
fn the_output_weighs_which_sensors_are_biased() {
    const FROM: f64 = 40.0;
    const UNTIL: f64 = 100.0;
    let [radar, camera] = biases();
    let slots = [(2, Some(&radar)), (2, Some(&camera))];
    let reg = Registration::<4, 8>::new(Q, 0.0, &slots, Tuning::default()).unwrap();
    let told = Registration::<4, 8>::new(Q, 0.0, &[(2, None), (2, None)], Tuning::default());
    let sq = |t: f64, i: usize, g: &Gaussian<4>| {
        (g.mean.fixed_rows::<2>(0) - target(i, t).0).norm_squared()
    };
    let (mut out_err, mut bank_err, mut told_err, mut n) = (0.0, 0.0, 0.0, 0.0);
    for seed in 1..=3 {
        let dets = detections_with(|_| [0.0; 4], seed, 2, UNTIL, false);
        let ran = run_bank(BiasBank::new(reg.clone()).unwrap(), &dets, 2, |_, _, _| {});
        let told = run_bank(
            BiasBank::new(told.clone().unwrap()).unwrap(),
            &dets,
            2,
            |_, _, _| {},
        );
        for ((t, tracks, bank), (_, told, _)) in ran.iter().zip(&told).step_by(7) {
            if *t < FROM || *t >= UNTIL {
                continue;
            }
            let out = bank.output(&numbered(tracks)).unwrap();
            assert!(out.biased.iter().all(|p| *p < 0.05), "{:?}", out.biased);
            for i in 0..2 {
                assert_eq!(out.tracks[i].0, i as TrackId);
                out_err += sq(*t, i, &out.tracks[i].1);
                bank_err += sq(*t, i, &tracks[i]);
                told_err += sq(*t, i, &told[i]);
                n += 1.0;
            }
        }
    }
    let (out_ratio, bank_ratio) = ((out_err / told_err).sqrt(), (bank_err / told_err).sqrt());
    println!("unbiased, {n} samples: output / told {out_ratio:.3}, bank / told {bank_ratio:.3}");
    assert!(
        out_ratio <= 1.02 && out_ratio < bank_ratio,
        "{out_ratio} {bank_ratio}"
    );
    // Biased: both sensors biased, the output the bank's own tracks.
    let dets = detections(4, 2, 300.0, false);
    let (_, tracks, bank) = run_bank(BiasBank::new(reg).unwrap(), &dets, 2, |_, _, _| {})
        .pop()
        .unwrap();
    let given = numbered(&tracks);
    let out = bank.output(&given).unwrap();
    assert!(out.biased.iter().all(|p| *p > 0.999), "{:?}", out.biased);
    for ((_, g), own) in out.tracks.iter().zip(&tracks) {
        assert!((g.mean - own.mean).norm() < 1e-3 && (g.cov - own.cov).norm() < 1e-3);
    }
    // Every track of the bank, and only those.
    assert!(bank.output(&given[..1]).is_err());
}

/// The drift modes (with "no bias": [`BiasBank::with_drift`]) follow a radar range offset that
/// wanders (30 m ± 25 m over 200 s) where the bias model as configured (a slow random walk,
/// 0.1 m/√s) lags it, and cost little when it is constant. Stated factors (3 seeds × 400 s, two targets, from 100 s on; measured: wandering,
/// range offset error 0.21 ×, tracks 0.52 × the one-mode bank's, drifting mode 0.86 on average;
/// constant, tracks 1.10 ×, drifting mode 0.08): with a wandering offset the modes' error
/// at most half the one mode's, their tracks better and the drifting mode the more probable;
/// with a constant one their tracks within 15 % and the steady mode the more probable.
#[test]
fn the_drift_modes_follow_a_wandering_offset() {
    let [_, camera] = biases();
    let radar = SensorBias {
        offset: vec![
            Some(BiasPrior::random_walk(PRIOR_STD[0], 0.1)),
            Some(BiasPrior::random_walk(PRIOR_STD[1], 1e-5)),
        ],
        ..SensorBias::default()
    };
    let reg = Registration::<4, 8>::new(
        Q,
        0.0,
        &[(2, Some(&radar)), (2, Some(&camera))],
        Tuning::default(),
    )
    .unwrap();
    let wandering = |t: f64| {
        let mut b = TRUTH;
        b[0] = 30.0 + 25.0 * (std::f64::consts::TAU * t / 200.0).sin();
        b
    };
    for wanders in [true, false] {
        let truth = |t: f64| if wanders { wandering(t) } else { TRUTH };
        let (mut bias_err, mut track_err) = ([0.0; 2], [0.0; 2]);
        let (mut drifting, mut samples) = (0.0, 0.0);
        for seed in 1..=3 {
            let dets = detections_with(truth, seed, 2, 400.0, false);
            let banks = [
                BiasBank::new(reg.clone()).unwrap(),
                BiasBank::with_drift(reg.clone(), DriftModes::default()).unwrap(),
            ];
            for (m, bank) in banks.into_iter().enumerate() {
                let run = run_bank(bank, &dets, 2, |_, _, _| {});
                for (t, tracks, b) in run.iter().filter(|(t, ..)| *t >= 100.0).step_by(5) {
                    bias_err[m] += (b.state().estimate.mean[4] - truth(*t)[0]).powi(2);
                    track_err[m] += (0..2)
                        .map(|i| {
                            (tracks[i].mean.fixed_rows::<2>(0) - target(i, *t).0).norm_squared()
                        })
                        .sum::<f64>();
                    if let Some(p) = b.drifting_prob() {
                        drifting += p;
                        samples += 1.0;
                    }
                }
            }
        }
        let bias = (bias_err[1] / bias_err[0]).sqrt();
        let track = (track_err[1] / track_err[0]).sqrt();
        let drifting = drifting / samples;
        println!(
            "wandering {wanders}: with_drift / one mode: range offset error {bias:.3}, tracks \
             {track:.3}; drifting mode {drifting:.2} on average"
        );
        if wanders {
            assert!(
                bias <= 0.5 && track < 1.0 && drifting > 0.5,
                "{bias} {track} {drifting}"
            );
        } else {
            assert!(track <= 1.15 && drifting < 0.5, "{track} {drifting}");
        }
    }
}
