//! Acceptance of the multi-target tracker on the crossing-target generator
//! (`harrier_core::tracker::generate`, default configuration): six targets crossing in pairs at the
//! same point and the same scan (crossing angles 30°–150°, 12–25 m/s), Pd 0.9, Poisson clutter
//! (one detection per scan on average over 10 km × 10 km), 10 m position noise, 200 scans at 1 Hz,
//! over 30 seeds.
//!
//! Per seed the tracker (EKF = KF on position detections, CV, GNN, 2-of-4 confirmation, deletion
//! after 5 misses) runs over the three files as a reader of FORMAT-MULTI.md sees them. Every scan
//! is scored with GOSPA (c = 50 m, p = 2, α = 2) and the continuity counts of
//! `tracker::metrics::Continuity` (50 m association threshold).
//!
//! Two more acceptance runs use data generated here, in the test: targets on parallel roads
//! 30–45 m apart that appear next to an already tracked target (initiation must compete for
//! detections in the same assignment, not be barred from a confirmed track's gate), and three
//! crossing targets seen by two moving `az_el` cameras and a ground `range_bearing` radar, tracked
//! by IMM tracks that fuse all three sensors.

use harrier_core::filter::{
    CentralDifference, Extended, Imm, ModeModel, NonlinearFilter, Predictor,
};
use harrier_core::measurement::{AzEl, Geometry, Locate, MeasurementModel, Position, RangeBearing};
use harrier_core::motion::ConstantVelocity;
use harrier_core::state::Gaussian;
use harrier_core::tracker::format::MultiScenario;
use harrier_core::tracker::generate::{GenConfig, generate};
use harrier_core::tracker::metrics::{Continuity, ContinuityReport, GospaParts, gospa};
use harrier_core::tracker::{
    Association, Deleter, Gater, GaussianFilter, ImmFilter, MOfN, SinglePointInitiator,
    TrackFilter, Tracker, TrackerConfig,
};
use nalgebra::{Vector2, Vector3, Vector4};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal, Poisson};

/// GOSPA cut-off (m) and order; also the continuity association threshold.
const C: f64 = 50.0;
const P: f64 = 2.0;
/// Seeds of the acceptance run.
const SEEDS: std::ops::RangeInclusive<u64> = 1..=30;

/// What one seed gave: continuity counts and GOSPA parts averaged over the scans.
#[derive(Debug)]
struct Outcome {
    continuity: ContinuityReport,
    mean: GospaParts,
    scans: usize,
}

/// Runs the tracker with the Gaussian filter `f` over the scenario of `seed`.
fn run<F>(seed: u64, cfg: &GenConfig, f: F) -> Outcome
where
    F: Predictor<ConstantVelocity<4>, 4, State = Gaussian<4>> + NonlinearFilter<4>,
{
    let g = generate(seed, cfg).unwrap();
    let m =
        MultiScenario::parse(&g.scenario_json, &g.measurements_jsonl, Some(&g.truth_csv)).unwrap();
    let std = m.scenario.sensors[0].noise.std();
    let filter = GaussianFilter {
        filter: f,
        motion: ConstantVelocity::<4>::new(m.scenario.accel_q().unwrap()),
    };
    let sensor = Position::new(Geometry::planar(0.0), [std[0], std[1]]);
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).unwrap(),
        tentative_gater: Gater::chi2(0.95, 2).unwrap(),
        confirm: MOfN::new(2, 4).unwrap(),
        deleter: Deleter::new(5, 1e5, 2).unwrap(),
        association: Association::Gnn,
    };
    let init = SinglePointInitiator::new(12.0, 50.0).unwrap();
    let mut tracker = Tracker::new(filter, init, config);
    let mut continuity = Continuity::new(C).unwrap();
    let mut sum = GospaParts::default();
    for scan in &m.scans {
        let dets: Vec<Vector2<f64>> = scan
            .detections
            .iter()
            .map(|d| Vector2::new(d.z[0], d.z[1]))
            .collect();
        tracker.step(scan.t, &sensor, &dets).unwrap();
        let tracks: Vec<(u64, Vector2<f64>)> = tracker
            .confirmed()
            .iter()
            .map(|k| (k.id, Vector2::new(k.estimate.mean[0], k.estimate.mean[1])))
            .collect();
        let truths: Vec<(usize, Vector2<f64>)> = m
            .truth_at(scan.t)
            .into_iter()
            .map(|(i, s)| (i, Vector2::new(s[0], s[1])))
            .collect();
        continuity.add_scan(&truths, &tracks).unwrap();
        let x: Vec<_> = tracks.iter().map(|(_, p)| *p).collect();
        let y: Vec<_> = truths.iter().map(|(_, p)| *p).collect();
        let g = gospa(&x, &y, C, P).unwrap();
        sum.gospa += g.gospa;
        sum.localisation += g.localisation;
        sum.missed += g.missed;
        sum.false_tracks += g.false_tracks;
        sum.n_assigned += g.n_assigned;
        sum.n_missed += g.n_missed;
        sum.n_false += g.n_false;
    }
    let n = m.scans.len() as f64;
    Outcome {
        continuity: continuity.report(),
        mean: GospaParts {
            gospa: sum.gospa / n,
            localisation: sum.localisation / n,
            missed: sum.missed / n,
            false_tracks: sum.false_tracks / n,
            ..sum
        },
        scans: m.scans.len(),
    }
}

#[test]
fn crossing_targets_in_clutter() {
    let cfg = GenConfig::default();
    let (mut scans, mut false_tracks, mut swaps, mut targets, mut gospa_sum) = (0, 0, 0, 0, 0.0);
    let mut delays = Vec::new();
    for seed in SEEDS {
        let o = run(seed, &cfg, Extended);
        let c = &o.continuity;
        println!(
            "seed {seed:2}: GOSPA {:5.2} m (per scan: localisation {:5.1}, missed {:4.1}, false \
             {:4.1} m²; {} missed / {} false truth-scans), swaps {}, id switches {}, breaks {}, \
             false tracks {} of {}, confirmation delays {:?}",
            o.mean.gospa,
            o.mean.localisation,
            o.mean.missed,
            o.mean.false_tracks,
            o.mean.n_missed,
            o.mean.n_false,
            c.swaps,
            c.id_switches,
            c.breaks,
            c.false_tracks,
            c.tracks,
            c.confirmation_delays.values().collect::<Vec<_>>(),
        );
        scans += o.scans;
        false_tracks += c.false_tracks;
        swaps += c.swaps;
        targets += c.confirmation_delays.len();
        gospa_sum += o.mean.gospa;
        // Every target is confirmed at some point.
        delays.extend(c.confirmation_delays.values().map(|d| d.unwrap()));
    }
    let per_1000 = 1000.0 * false_tracks as f64 / scans as f64;
    let late = delays.iter().filter(|&&d| d > 4).count();
    println!(
        "{} seeds, {scans} scans, {targets} targets: swaps {swaps}, false tracks {false_tracks} \
         ({per_1000:.2} per 1000 scans), confirmed later than the 5th scan: {late}, worst delay {} \
         scans, mean GOSPA {:.2} m",
        SEEDS.count(),
        delays.iter().max().unwrap(),
        gospa_sum / SEEDS.count() as f64
    );
    assert_eq!(targets, 6 * SEEDS.count());
    // No track follows one target into a crossing and leaves with the other.
    assert_eq!(swaps, 0);
    // False tracks: at most one per 1000 scans.
    assert!(per_1000 <= 1.0, "{per_1000} false tracks per 1000 scans");
    // Confirmation within 5 scans (delay ≤ 4 after the target's first scan). A 2-hit rule cannot
    // confirm a target with fewer than 2 detections in its first scans, nor (with N = 4) one
    // detected only at its 1st and 5th scans: P ≈ 0.0013 per target at Pd 0.9, so a few of the
    // 180 targets may need one more scan. Honest bound achieved on these seeds:
    assert!(late <= 1, "{late} targets confirmed after their 5th scan");
    assert!(delays.iter().all(|&d| d <= 5));
}

/// Any Gaussian filter plugs in: the same scenarios with the central-difference filter.
#[test]
fn central_difference_filter_plugs_in() {
    let cfg = GenConfig::default();
    for seed in 1..=5 {
        let o = run(seed, &cfg, CentralDifference::new(3f64.sqrt()).unwrap());
        let c = &o.continuity;
        assert_eq!(c.swaps, 0, "seed {seed}");
        assert!(
            c.confirmation_delays
                .values()
                .all(|d| d.is_some_and(|d| d <= 5))
        );
        assert!(o.mean.gospa < 25.0, "seed {seed}: {}", o.mean.gospa);
    }
}

/// The tracker configuration of the generated runs below, over any track filter.
fn live_tracker<F: TrackFilter<4>>(filter: F, misses: u32) -> Tracker<F, SinglePointInitiator, 4> {
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).unwrap(),
        tentative_gater: Gater::chi2(0.95, 2).unwrap(),
        confirm: MOfN::new(2, 4).unwrap(),
        deleter: Deleter::new(misses, 1e5, 2).unwrap(),
        association: Association::Gnn,
    };
    Tracker::new(
        filter,
        SinglePointInitiator::new(12.0, 50.0).unwrap(),
        config,
    )
}

/// Positions of the confirmed tracks.
fn confirmed_positions<F: TrackFilter<4>>(
    tracker: &Tracker<F, SinglePointInitiator, 4>,
) -> Vec<(u64, Vector2<f64>)> {
    tracker
        .confirmed()
        .iter()
        .map(|k| (k.id, Vector2::new(k.estimate.mean[0], k.estimate.mean[1])))
        .collect()
}

/// One scan of generated position detections with the truth alive at its time.
struct GroundScan {
    t: f64,
    dets: Vec<Vector2<f64>>,
    truths: Vec<(usize, Vector2<f64>)>,
}

/// Targets on parallel roads along East, 30–45 m apart: the first is tracked from scan 0, the
/// others appear 10–25 scans later level with it (±20 m), so that their first detections fall in
/// the confirmed track's gate (γ = χ²₂(0.999) = 13.8 on S ≥ R = (10 m)² I: a radius of 37 m and
/// more). Same speed ± 1.5 m/s, 10 m noise, Pd 0.9, 5 clutter detections
/// per scan over 4 km × 4 km, 60 scans at 1 Hz.
fn parallel_roads(seed: u64) -> Vec<GroundScan> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let noise = Normal::new(0.0, 10.0).unwrap();
    let clutter = Poisson::new(5.0).unwrap();
    let v0: f64 = rng.random_range(12.0..18.0);
    // (lane offset North, first scan, speed, East at first scan)
    let mut targets = vec![(0.0, 0usize, v0, -600.0)];
    for side in [1.0, -1.0] {
        let start = rng.random_range(10..=25);
        let lead = -600.0 + v0 * start as f64 + rng.random_range(-20.0..20.0);
        targets.push((
            side * rng.random_range(30.0..45.0),
            start,
            v0 + rng.random_range(-1.5..1.5),
            lead,
        ));
    }
    (0..60)
        .map(|k| {
            let t = k as f64;
            let mut truths = Vec::new();
            let mut dets = Vec::new();
            for (i, &(north, start, v, east0)) in targets.iter().enumerate() {
                if k < start {
                    continue;
                }
                let p = Vector2::new(east0 + v * (k - start) as f64, north);
                truths.push((i, p));
                if rng.random::<f64>() < 0.9 {
                    dets.push(p + Vector2::new(noise.sample(&mut rng), noise.sample(&mut rng)));
                }
            }
            for _ in 0..clutter.sample(&mut rng) as usize {
                dets.push(Vector2::new(
                    rng.random_range(-2000.0..2000.0),
                    rng.random_range(-2000.0..2000.0),
                ));
            }
            GroundScan { t, dets, truths }
        })
        .collect()
}

/// A target next to a tracked one is confirmed within 3 scans: initiation competes for detections
/// in the same assignment as the confirmed tracks instead of being barred from their gates.
#[test]
fn newcomer_next_to_a_confirmed_track_is_confirmed_at_once() {
    let seeds = 1..=20u64;
    let (mut newcomers, mut within_3, mut worst, mut false_tracks, mut swaps, mut switches) =
        (0, 0, 0, 0, 0, 0);
    for seed in seeds.clone() {
        let filter = GaussianFilter {
            filter: Extended,
            motion: ConstantVelocity::<4>::new(0.3 * 0.3),
        };
        let mut tracker = live_tracker(filter, 5);
        let camera = Position::new(Geometry::planar(0.0), [10.0, 10.0]);
        let mut continuity = Continuity::new(C).unwrap();
        for GroundScan { t, dets, truths } in parallel_roads(seed) {
            tracker.step(t, &camera, &dets).unwrap();
            continuity
                .add_scan(&truths, &confirmed_positions(&tracker))
                .unwrap();
        }
        let c = continuity.report();
        for (&i, d) in &c.confirmation_delays {
            let d = d.expect("every target is confirmed");
            if i > 0 {
                newcomers += 1;
                within_3 += usize::from(d <= 2);
                worst = worst.max(d);
            }
        }
        false_tracks += c.false_tracks;
        swaps += c.swaps;
        switches += c.id_switches;
    }
    println!(
        "parallel roads, {} seeds: {newcomers} newcomers, {within_3} confirmed within 3 scans, \
         worst delay {worst} scans; swaps {swaps}, id switches {switches}, false tracks {false_tracks}",
        seeds.count()
    );
    // Pd 0.9 and 2-of-4: P(2 hits in the first 3 scans) = 0.972, so one or two of 40 may need a
    // 4th scan. The tracker before this change (tentative tracks barred from detections in a
    // confirmed track's gate, confirmed tracks associated first) gave on the same data: 15 of 40
    // within 3 scans, some never confirmed, 6 swaps, 83 false tracks (all clutter-born: 5 clutter
    // detections per scan and a 2-of-4 rule).
    assert!(
        within_3 as f64 >= 0.9 * newcomers as f64,
        "{within_3} of {newcomers}"
    );
    assert!(worst <= 4, "worst delay {worst}");
    assert_eq!(swaps, 0);
    assert!(false_tracks <= 83, "{false_tracks} false tracks");
}

/// Ground truth of the fusion run: three targets crossing at the origin at t = 30 s, 10 m/s, at
/// 0°, 60° and 120° from East; state `[x, y, vx, vy]`.
fn crossing(i: usize, t: f64) -> Vector4<f64> {
    let a = std::f64::consts::FRAC_PI_3 * i as f64;
    let v = Vector2::new(a.cos(), a.sin()) * 10.0;
    let p = v * (t - 30.0);
    Vector4::new(p.x, p.y, v.x, v.y)
}

/// The three sensors of the fusion run at time `t`: two cameras 150 m up flying circles of 600 m
/// radius about the crossing (one clockwise, one counter-clockwise) and a radar on a 20 m mast
/// 1.5 km South-West.
#[derive(Debug, Clone, Copy)]
enum Sensor {
    Camera(usize),
    Radar,
}

impl Sensor {
    fn position(self, t: f64) -> Vector3<f64> {
        match self {
            Self::Camera(k) => {
                let w = if k == 0 { 0.04 } else { -0.04 };
                let a = w * t + k as f64 * 2.0;
                Vector3::new(600.0 * a.cos(), 600.0 * a.sin(), 150.0)
            }
            Self::Radar => Vector3::new(-1060.0, -1060.0, 20.0),
        }
    }
}

/// One scan of `sensor` at `t`: the targets (Pd 0.9) and Poisson clutter (one per scan on average,
/// uniform over the ground square ±800 m, seen through the sensor's own model).
fn scan<H: MeasurementModel<4, 2>>(
    h: &H,
    t: f64,
    std: [f64; 2],
    rng: &mut ChaCha8Rng,
) -> Vec<Vector2<f64>> {
    let mut out = Vec::new();
    let n = [
        Normal::new(0.0, std[0]).unwrap(),
        Normal::new(0.0, std[1]).unwrap(),
    ];
    let noisy = |x: &Vector4<f64>, rng: &mut ChaCha8Rng| {
        h.function(x) + Vector2::new(n[0].sample(rng), n[1].sample(rng))
    };
    for i in 0..3 {
        if rng.random::<f64>() < 0.9 {
            out.push(noisy(&crossing(i, t), rng));
        }
    }
    for _ in 0..Poisson::new(1.0).unwrap().sample(rng) as usize {
        let x = Vector4::new(
            rng.random_range(-800.0..800.0),
            rng.random_range(-800.0..800.0),
            0.0,
            0.0,
        );
        out.push(h.function(&x));
    }
    out
}

/// What one fusion run gave: continuity and the position RMSE of the confirmed tracks assigned to
/// a target over the second half (after the crossing).
struct FusionOutcome {
    continuity: ContinuityReport,
    rmse: f64,
}

/// IMM tracks (CV + two CT modes over the EKF) over the scans of `sensors`, each at 2 Hz with its
/// own phase, for 60 s.
fn fusion_run(seed: u64, sensors: &[Sensor]) -> FusionOutcome {
    let q = 0.05;
    let imm = Imm::new(
        Extended,
        [
            ModeModel::Cv { q },
            ModeModel::Ct { omega: 0.1, q },
            ModeModel::Ct { omega: -0.1, q },
        ],
        [[0.95, 0.025, 0.025], [0.05, 0.95, 0.0], [0.05, 0.0, 0.95]],
    )
    .unwrap();
    let filter = ImmFilter {
        imm,
        initial_probs: [0.8, 0.1, 0.1],
    };
    let misses = 5 * u32::try_from(sensors.len()).unwrap();
    let mut tracker = live_tracker(filter, misses);
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut continuity = Continuity::new(C).unwrap();
    let (mut se, mut n) = (0.0, 0usize);
    let ground = Geometry::planar(0.0);
    for k in 0..120 {
        for (j, &s) in sensors.iter().enumerate() {
            let t = 0.5 * k as f64 + 0.1 * j as f64;
            let at = s.position(t);
            match s {
                Sensor::Camera(_) => {
                    let std = [0.004, 0.004];
                    let h = AzEl::new(ground, at, std);
                    let dets = scan(&h, t, std, &mut rng);
                    assert!(dets.iter().all(|z| h.locate(z).is_some()));
                    tracker.step(t, &h, &dets).unwrap();
                }
                Sensor::Radar => {
                    let std = [5.0, 0.003];
                    let h = RangeBearing::new(ground, at, std);
                    let dets = scan(&h, t, std, &mut rng);
                    tracker.step(t, &h, &dets).unwrap();
                }
            }
            let truths: Vec<(usize, Vector2<f64>)> =
                (0..3).map(|i| (i, crossing(i, t).xy())).collect();
            let tracks = confirmed_positions(&tracker);
            continuity.add_scan(&truths, &tracks).unwrap();
            if t >= 30.0 {
                for (_, y) in &truths {
                    if let Some(d) = tracks.iter().map(|(_, x)| (x - y).norm()).reduce(f64::min) {
                        if d < C {
                            se += d * d;
                            n += 1;
                        }
                    }
                }
            }
        }
    }
    FusionOutcome {
        continuity: continuity.report(),
        rmse: (se / n as f64).sqrt(),
    }
}

/// Two moving `az_el` cameras and a ground `range_bearing` radar update the same IMM tracks: every
/// target confirmed, no swaps at the crossing, and the fused error lower than any one sensor's.
/// (Clutter-born false tracks are printed, not bounded: three sensors bring 6 clutter detections a
/// second over 2.6 km², and a 2-of-4 rule confirms a few of them.)
#[test]
fn cameras_and_radar_fuse_into_one_track_per_target() {
    let single = [
        ("camera 1", vec![Sensor::Camera(0)]),
        ("camera 2", vec![Sensor::Camera(1)]),
        ("radar", vec![Sensor::Radar]),
    ];
    let all = vec![Sensor::Camera(0), Sensor::Camera(1), Sensor::Radar];
    for seed in 1..=4 {
        let fused = fusion_run(seed, &all);
        let c = &fused.continuity;
        let alone: Vec<(&str, f64)> = single
            .iter()
            .map(|(name, s)| (*name, fusion_run(seed, s).rmse))
            .collect();
        println!(
            "seed {seed}: fused RMSE {:.2} m (alone: {}), swaps {}, false tracks {}, delays {:?}",
            fused.rmse,
            alone
                .iter()
                .map(|(n, r)| format!("{n} {r:.2} m"))
                .collect::<Vec<_>>()
                .join(", "),
            c.swaps,
            c.false_tracks,
            c.confirmation_delays.values().collect::<Vec<_>>()
        );
        assert!(
            c.confirmation_delays
                .values()
                .all(|d| d.is_some_and(|d| d <= 6))
        );
        assert_eq!(c.swaps, 0, "seed {seed}");
        for (name, r) in &alone {
            assert!(
                fused.rmse < *r,
                "seed {seed}: fused {} ≥ {name} {r}",
                fused.rmse
            );
        }
    }
}

/// The live service's track engines, built by name from the registry, on the \[CIMM\] reference
/// scenario with three UAV cameras: one confirmed track on the target, and the road constraint
/// pays off as it does for the single-target estimators (`cimm.rs`). The track list kept from
/// each scan's outcome (as the tracker actor keeps it) is the engine's snapshot after every scan,
/// the three cameras' scans of one time included.
#[test]
fn track_engines_by_name_on_the_cimm_reference() {
    use harrier_core::measurement::SensorModel;
    use harrier_engine::registry::build_track_filter;
    use harrier_engine::{Params, SensorScan};
    let data = harrier_tools::replay::load(&harrier_tests::scenario("cimm_road_3uav")).unwrap();
    let sc = &data.scenario;
    let deployment = &harrier_engine::Deployment::from(sc);
    let truth = data.truth.as_ref().unwrap();
    let mut rmse = Vec::new();
    for name in ["ekf", "cdkf", "imm", "cimm"] {
        let mut engine = build_track_filter(name, deployment, &Params::default()).unwrap();
        let mut tracks = engine.snapshot();
        let (mut se, mut n, mut ids) = (0.0, 0usize, std::collections::BTreeSet::new());
        for m in &data.measurements {
            let sensor = SensorModel::new(
                m.kind,
                Geometry::planar(sc.plane_z()),
                Vector3::from(m.platform.pos),
                &sc.sensor(&m.sensor).unwrap().noise.std(),
                None,
            )
            .unwrap();
            let scan = SensorScan {
                t: m.t,
                sensor,
                detections: vec![m.z.clone()],
            };
            (tracks, _) = engine.ingest(&scan).unwrap().apply(&tracks);
            assert_eq!(tracks, engine.snapshot(), "{name} at t = {}", m.t);
            let confirmed: Vec<_> = tracks
                .iter()
                .filter(|k| k.status == harrier_engine::TrackStatus::Confirmed)
                .collect();
            let row = truth.iter().find(|r| (r.t - m.t).abs() < 1e-6).unwrap();
            if m.t >= 100.0 {
                // The CV filters (q = motion.accel_std²) lose the target in the turns and start
                // again; the IMM tracks follow it with one id.
                let Some(k) = confirmed.iter().min_by(|a, b| {
                    let d = |k: &harrier_engine::TrackView| {
                        (k.state[0] - row.state[0]).hypot(k.state[1] - row.state[1])
                    };
                    d(a).total_cmp(&d(b))
                }) else {
                    continue;
                };
                ids.insert(k.id);
                se += (k.state[0] - row.state[0]).powi(2) + (k.state[1] - row.state[1]).powi(2);
                n += 1;
                if name.contains("imm") {
                    assert_eq!(confirmed.len(), 1, "{name} at t = {}", m.t);
                    assert_eq!(k.mode_probabilities.len(), 3);
                } else {
                    assert!(k.mode_probabilities.is_empty());
                }
            }
        }
        if name.contains("imm") {
            assert_eq!(ids.len(), 1, "{name}: one stable id");
        }
        println!("{name}: {} track ids after 100 s", ids.len());
        rmse.push((name, (se / n as f64).sqrt()));
    }
    println!("cimm_road_3uav, track engines, position RMSE after 100 s: {rmse:?}");
    let of = |n: &str| rmse.iter().find(|(m, _)| *m == n).unwrap().1;
    assert!(of("cimm") < of("imm") && of("imm") < of("ekf"), "{rmse:?}");
    assert!(of("cimm") < 2.5, "{rmse:?}");
    // Unknown names and parameters are refused with the list of what exists.
    let e = build_track_filter("kalman", deployment, &Params::default()).unwrap_err();
    assert!(e.to_string().contains("ekf, cdkf, imm, cimm"), "{e}");
    let e =
        build_track_filter("imm", deployment, &Params::parse(&["nope=1"]).unwrap()).unwrap_err();
    assert!(e.to_string().contains("nope"), "{e}");
}

/// `harrier gen-multi`'s writer and `harrier replay -e tracker` on what it wrote.
#[test]
fn replays_a_generated_scenario() {
    let dir = tempfile::tempdir().unwrap();
    harrier_tools::gen_multi::write(dir.path(), 5).unwrap();
    let data = harrier_tools::replay::load(dir.path()).unwrap();
    let report =
        harrier_tools::replay::run(&data, "tracker", &harrier_engine::Params::default()).unwrap();
    assert!(report.rejected.is_empty());
    let last = report.estimates.last().unwrap();
    assert!(last.state.is_none());
    let tracks = last.extra["tracks"].as_array().unwrap();
    assert_eq!(tracks.len(), 6);
    for k in tracks {
        assert!(k["id"].as_u64().is_some());
        assert_eq!(k["state"].as_array().unwrap().len(), 6);
        assert_eq!(k["cov_dims"], serde_json::json!([0, 1, 3, 4]));
    }
    // A parameter out of range is a setup error.
    let bad = harrier_engine::Params::parse(&["n=1.5"]).unwrap();
    assert!(harrier_tools::replay::run(&data, "tracker", &bad).is_err());
}
