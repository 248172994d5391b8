//! Unit tests of the sensors: field of view and range, measurement conventions and noise, Pd
//! and clutter, radar bias, per-vehicle streams, the gimbal pointed at a region of interest.

use super::*;
use crate::setup::{
    AirframeSpec, Behaviour, CameraOutput, Jitter, MotionSegment, TargetMotion, TargetSpec,
    VehicleSpec,
};
use harrier_core::detection::TargetTruth;

const ORIGIN: GeoPoint = GeoPoint {
    lat_deg: 47.0,
    lon_deg: 8.0,
    alt_m: 400.0,
};

fn pose(pos: [f64; 3], yaw: f64) -> PlatformPose {
    PlatformPose {
        pos,
        vel: [0.0; 3],
        attitude: [0.0, 0.0, yaw],
        geodetic: Some(ORIGIN),
    }
}

fn still(id: &str, x: f64, y: f64) -> TargetSpec {
    TargetSpec {
        id: id.into(),
        size_m: 10.0,
        size_known: true,
        motion: TargetMotion::Segments {
            position: [x, y],
            velocity: [0.0, 0.0],
            z_m: 0.0,
            segments: Vec::<MotionSegment>::new(),
        },
        jitter: Jitter::default(),
    }
}

/// A scenario with static targets and one sensor.
fn scenario(targets: Vec<TargetSpec>, sensor: SensorSpec) -> SimScenario {
    let mut s = SimScenario::preset("crossing").expect("preset");
    s.targets = targets;
    s.sensors = vec![sensor];
    s.vehicles = VehicleSpec {
        airframe: AirframeSpec::Multirotor,
        preroll_s: 0.0,
        behaviour: Behaviour::Hold {
            position: [0.0, 0.0, 100.0],
            spacing_m: 0.0,
        },
    };
    s
}

fn camera(output: CameraOutput, fov_deg: f64, pointing: Pointing, noise: Vec<f64>) -> SensorSpec {
    SensorSpec {
        id: "cam".into(),
        rate_hz: 10.0,
        pd: 1.0,
        clutter_rate: 0.0,
        time_offset_s: 0.0,
        max_range_m: 1000.0,
        noise_std: noise,
        model: SensorType::Camera {
            output,
            fov_deg,
            pointing,
            mounting_deg: [0.0, 0.0],
        },
    }
}

fn run(s: &SimScenario, p: &PlatformPose, scans: usize, seed: u64) -> Vec<LabelledScan> {
    let world = World::new(s, seed).expect("world");
    let mut suite = SensorSuite::new(s, seed, 1).expect("suite");
    let mut out = Vec::new();
    for k in 0..scans {
        let t = k as f64 / s.sensors[0].rate_hz;
        for l in suite.scan_labelled(t, 1, p, ORIGIN, &world) {
            l.scan.validate().expect("valid scan");
            assert_eq!(l.scan.seq, k as u64);
            assert_eq!(l.scan.t, t);
            out.push(l);
        }
    }
    assert_eq!(out.len(), scans);
    out
}

#[test]
fn field_of_view_and_range_limit_detections() {
    // Nadir camera 100 m up, 60° FOV: ground footprint radius 100·tan 30° = 57.7 m.
    let targets = vec![
        still("in", 40.0, 0.0),
        still("edge_out", 0.0, -60.0),
        still("far", 2000.0, 0.0),
    ];
    let s = scenario(
        targets,
        camera(
            CameraOutput::AzEl,
            60.0,
            Pointing::Nadir,
            vec![0.001, 0.001],
        ),
    );
    let scans = run(&s, &pose([0.0, 0.0, 100.0], 0.0), 50, 1);
    for l in &scans {
        assert_eq!(l.sources, vec![Some(0)]);
    }
    // A fixed gimbal looking East (yaw 90°, pan 0, depression 45°) from 100 m sees (100, 0).
    let s = scenario(
        vec![still("east", 100.0, 0.0), still("west", -100.0, 0.0)],
        camera(
            CameraOutput::AzEl,
            20.0,
            Pointing::Fixed {
                pan_deg: 0.0,
                depression_deg: 45.0,
            },
            vec![0.001, 0.001],
        ),
    );
    let scans = run(&s, &pose([0.0, 0.0, 100.0], FRAC_PI_2), 20, 2);
    assert!(scans.iter().all(|l| l.sources == vec![Some(0)]));
    // Radar range limit.
    let mut radar = SensorSpec {
        id: "radar".into(),
        rate_hz: 1.0,
        pd: 1.0,
        clutter_rate: 0.0,
        time_offset_s: 0.0,
        max_range_m: 1500.0,
        noise_std: vec![5.0, 0.005],
        model: SensorType::Radar {
            bias: BiasModel::None,
            paints_vehicles: false,
        },
    };
    let s = scenario(
        vec![still("near", 1000.0, 0.0), still("far", 0.0, -1600.0)],
        radar.clone(),
    );
    let scans = run(&s, &pose([0.0, 0.0, 0.0], 0.0), 20, 3);
    assert!(scans.iter().all(|l| l.sources == vec![Some(0)]));
    radar.max_range_m = 2000.0;
    let s = scenario(
        vec![still("near", 1000.0, 0.0), still("far", 0.0, -1600.0)],
        radar,
    );
    let scans = run(&s, &pose([0.0, 0.0, 0.0], 0.0), 20, 3);
    assert!(scans.iter().all(|l| l.sources.len() == 2));
}

#[test]
fn measurements_follow_the_conventions_and_the_noise() {
    // Target due East and 100 m below: azimuth +π/2, elevation −45°.
    let p = pose([-100.0, 0.0, 100.0], 0.0);
    let n = 4000;
    let check = |output, noise: Vec<f64>, expected: Vec<f64>| {
        let s = scenario(
            vec![still("t", 0.0, 0.0)],
            camera(output, 90.0, Pointing::Track { target: 0 }, noise.clone()),
        );
        let scans = run(&s, &p, n, 4);
        for (c, (e, sd)) in expected.iter().zip(&noise).enumerate() {
            let r: Vec<f64> = scans
                .iter()
                .map(|l| {
                    let r = l.scan.detections[0].z[c] - e;
                    if output == CameraOutput::Position {
                        r
                    } else {
                        wrap_angle(r)
                    }
                })
                .collect();
            let mean = r.iter().sum::<f64>() / n as f64;
            let var = r.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / n as f64;
            // Mean within 4 standard errors, std within 5 %.
            assert!(
                mean.abs() < 4.0 * sd / (n as f64).sqrt(),
                "{output:?}[{c}] mean {mean}"
            );
            assert!(
                (var.sqrt() / sd - 1.0).abs() < 0.05,
                "{output:?}[{c}] std {}",
                var.sqrt()
            );
        }
    };
    let sub = 2.0 * (10.0 / (2.0 * 100.0 * 2f64.sqrt())).atan();
    check(
        CameraOutput::AzEl,
        vec![0.01, 0.02],
        vec![FRAC_PI_2, -PI / 4.0],
    );
    check(
        CameraOutput::BearingSize,
        vec![0.01, 0.01, 0.001],
        vec![FRAC_PI_2, -PI / 4.0, sub],
    );
    check(CameraOutput::Position, vec![10.0, 5.0], vec![0.0, 0.0]);
    // harrier-core's models give the same h (FORMAT.md §1: North = 0, East = +π/2).
    let x = SVector::<f64, 6>::zeros();
    let h = AzEl::new(Geometry::spatial(), Vector3::from(p.pos), [1.0, 1.0]).function(&x);
    assert!((h[0] - FRAC_PI_2).abs() < 1e-12 && (h[1] + PI / 4.0).abs() < 1e-12);
    // Azimuth wraps to [−π, π): a target due South straddles the cut.
    let s = scenario(
        vec![still("t", 0.0, -100.0)],
        camera(
            CameraOutput::AzEl,
            90.0,
            Pointing::Track { target: 0 },
            vec![0.05, 0.05],
        ),
    );
    let scans = run(&s, &pose([0.0, 0.0, 10.0], 0.0), 500, 5);
    let az: Vec<f64> = scans.iter().map(|l| l.scan.detections[0].z[0]).collect();
    assert!(az.iter().all(|a| (-PI..PI).contains(a)));
    assert!(az.iter().any(|a| *a > 3.0) && az.iter().any(|a| *a < -3.0));
}

#[test]
fn pd_and_clutter_rates_are_right() {
    let mut cam = camera(
        CameraOutput::Position,
        90.0,
        Pointing::Nadir,
        vec![5.0, 5.0],
    );
    cam.pd = 0.7;
    cam.clutter_rate = 2.5;
    let s = scenario(vec![still("a", 10.0, 0.0), still("b", -10.0, 20.0)], cam);
    let p = pose([0.0, 0.0, 100.0], 0.0);
    let n = 4000;
    let scans = run(&s, &p, n, 6);
    let det = scans
        .iter()
        .flat_map(|l| &l.sources)
        .filter(|s| s.is_some())
        .count();
    let clutter: Vec<usize> = scans
        .iter()
        .map(|l| l.sources.iter().filter(|s| s.is_none()).count())
        .collect();
    let pd = det as f64 / (2 * n) as f64;
    // Binomial: std sqrt(0.21 / 8000) = 0.005.
    assert!((pd - 0.7).abs() < 0.02, "pd {pd}");
    let mean = clutter.iter().sum::<usize>() as f64 / n as f64;
    let var = clutter
        .iter()
        .map(|&c| (c as f64 - mean).powi(2))
        .sum::<f64>()
        / n as f64;
    // Poisson: mean = variance = 2.5; std error of the mean 0.025.
    assert!((mean - 2.5).abs() < 0.1, "clutter mean {mean}");
    assert!((var / mean - 1.0).abs() < 0.1, "dispersion {}", var / mean);
    // Clutter falls in the footprint (radius 100 m for a 90° cone from 100 m).
    for l in &scans {
        for (d, src) in l.scan.detections.iter().zip(&l.sources) {
            if src.is_none() {
                assert!(d.z[0].hypot(d.z[1]) <= 100.0 + 1e-6);
            }
        }
    }
    // Clutter directions are uniform over the cone: the fraction inside half the cone's
    // solid angle is 1/2.
    let mut cam = camera(CameraOutput::AzEl, 60.0, Pointing::Nadir, vec![0.01, 0.01]);
    cam.clutter_rate = 3.0;
    let s = scenario(vec![still("far", 5000.0, 0.0)], cam);
    let scans = run(&s, &p, 2000, 7);
    let half_cos = 1.0 - 0.5 * (1.0 - (PI / 6.0).cos());
    let (mut inner, mut all) = (0.0_f64, 0.0_f64);
    for d in scans.iter().flat_map(|l| &l.scan.detections) {
        let off_nadir = FRAC_PI_2 + d.z[1];
        assert!(off_nadir <= PI / 6.0 + 1e-9);
        all += 1.0;
        if off_nadir.cos() >= half_cos {
            inner += 1.0;
        }
    }
    assert!((inner / all - 0.5).abs() < 0.03, "{}", inner / all);
}

fn radar_run(bias: BiasModel, scans: usize) -> Vec<[f64; 2]> {
    let radar = SensorSpec {
        id: "radar".into(),
        rate_hz: 1.0,
        pd: 1.0,
        clutter_rate: 0.0,
        time_offset_s: 0.0,
        max_range_m: 20_000.0,
        noise_std: vec![1e-6, 1e-9],
        model: SensorType::Radar {
            bias,
            paints_vehicles: false,
        },
    };
    let s = scenario(vec![still("t", 3000.0, 4000.0)], radar);
    run(&s, &pose([0.0, 0.0, 0.0], 0.0), scans, 8)
        .iter()
        .map(|l| {
            [
                l.scan.detections[0].z[0] - 5000.0,
                l.scan.detections[0].z[1] - 0.6435011087932844,
            ]
        })
        .collect()
}

#[test]
fn radar_bias_models() {
    for r in radar_run(BiasModel::None, 10) {
        assert!(r[0].abs() < 1e-4 && r[1].abs() < 1e-7);
    }
    // Abrupt: z = (1 + s) h + o while t_on ≤ t < t_off ([ICDKF] eq. (9)).
    let abrupt = BiasModel::Abrupt {
        t_on: 3.0,
        t_off: 6.0,
        scale: [0.01, 0.0],
        offset: [100.0, 0.01],
    };
    for (t, r) in radar_run(abrupt, 10).iter().enumerate() {
        let on = (3..6).contains(&t);
        let expected = if on { [150.0, 0.01] } else { [0.0, 0.0] };
        assert!(
            (r[0] - expected[0]).abs() < 1e-4 && (r[1] - expected[1]).abs() < 1e-7,
            "{t}"
        );
    }
    // Markov: stationary mean and std, correlation exp(−Δ/τ) at lag 1 s.
    let markov = BiasModel::Markov {
        mean: [60.0, 0.006],
        std: [30.0, 0.004],
        tau_s: 10.0,
        scale: [0.0, 0.0],
    };
    let r = radar_run(markov, 20_000);
    let o: Vec<f64> = r.iter().map(|x| x[0]).collect();
    let n = o.len() as f64;
    let mean = o.iter().sum::<f64>() / n;
    let var = o.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n;
    let cov1 = o
        .windows(2)
        .map(|w| (w[0] - mean) * (w[1] - mean))
        .sum::<f64>()
        / (n - 1.0);
    // Effective sample size ≈ n (1 − a)/(1 + a) ≈ 1000: mean std error ≈ 1 m.
    assert!((mean - 60.0).abs() < 5.0, "mean {mean}");
    assert!((var.sqrt() / 30.0 - 1.0).abs() < 0.1, "std {}", var.sqrt());
    assert!(
        (cov1 / var - (-0.1f64).exp()).abs() < 0.03,
        "rho {}",
        cov1 / var
    );
}

#[test]
fn streams_are_independent_per_vehicle_and_scans_are_due_on_time() {
    let s = SimScenario::preset("crossing").expect("preset");
    let mut world = World::new(&s, 1).expect("world");
    world.advance(1.0);
    let p = pose([0.0, 0.0, 400.0], 0.0);
    let mut a1 = SensorSuite::new(&s, 1, 1).expect("suite");
    let mut a2 = SensorSuite::new(&s, 1, 2).expect("suite");
    let mut b1 = SensorSuite::new(&s, 1, 1).expect("suite");
    let x = a1.scan(1.0, 1, &p, ORIGIN, &world);
    let y = a2.scan(1.0, 2, &p, ORIGIN, &world);
    let z = b1.scan(1.0, 1, &p, ORIGIN, &world);
    assert_eq!(x, z);
    assert_ne!(x[0].detections, y[0].detections);
    // 2 Hz: due at 1.0 (done), not at 1.2, due at 1.5, and once only after a gap.
    assert!(a1.scan(1.2, 1, &p, ORIGIN, &world).is_empty());
    assert_eq!(a1.scan(1.5, 1, &p, ORIGIN, &world).len(), 1);
    let late = a1.scan(3.7, 1, &p, ORIGIN, &world);
    assert_eq!(late.len(), 1);
    assert_eq!(late[0].seq, 2);
    assert!(a1.scan(3.9, 1, &p, ORIGIN, &world).is_empty());
    assert!(a1.scan(f64::NAN, 1, &p, ORIGIN, &world).is_empty());
    let _: Vec<TargetTruth> = world.truth();
}

#[test]
fn degenerate_geometry_never_gives_nan() {
    // Target exactly at the sensor, straight below, straight above: no NaN, valid scans.
    let s = scenario(
        vec![still("t", 0.0, 0.0)],
        camera(
            CameraOutput::BearingSize,
            170.0,
            Pointing::Track { target: 0 },
            vec![0.01; 3],
        ),
    );
    for z in [0.0, 50.0, -50.0] {
        let scans = run(&s, &pose([0.0, 0.0, z], 0.0), 20, 9);
        for l in scans {
            assert!(
                l.scan
                    .detections
                    .iter()
                    .all(|d| d.z.iter().all(|v| v.is_finite()))
            );
        }
    }
}

/// A camera on the vehicle's gimbal (`pointing: roi`) looks where the gimbal points: at a target
/// 300 m east of a vehicle 100 m up (outside a nadir view), and straight down without an ROI.
#[test]
fn a_roi_camera_looks_along_the_gimbal() {
    let s = scenario(
        vec![still("east", 300.0, 0.0), still("below", 0.0, 5.0)],
        camera(CameraOutput::AzEl, 10.0, Pointing::Roi, vec![0.001, 0.001]),
    );
    let world = World::new(&s, 5).expect("world");
    let mut suite = SensorSuite::new(&s, 5, 1).expect("suite");
    let p = pose([0.0, 0.0, 100.0], 0.0);
    let sources = |suite: &mut SensorSuite, k: usize| {
        let scans = suite.scan_labelled(k as f64 / 10.0, 1, &p, ORIGIN, &world);
        scans
            .into_iter()
            .flat_map(|l| l.sources)
            .collect::<Vec<_>>()
    };
    assert_eq!(sources(&mut suite, 0), vec![Some(1)], "no ROI: nadir");
    suite.set_gimbal(Vector3::new(300.0, 0.0, -100.0).try_normalize(1e-9));
    assert_eq!(sources(&mut suite, 1), vec![Some(0)], "pointed east");
    suite.set_gimbal(Some(Vector3::new(f64::NAN, 0.0, -1.0)));
    assert_eq!(
        sources(&mut suite, 2),
        vec![Some(1)],
        "a bad direction: nadir"
    );
}

#[test]
fn a_mounting_error_shifts_the_camera_angles() {
    // A camera 100 m up looking East at (100, 0): azimuth 90°, elevation −45°.
    let mut cam = camera(
        CameraOutput::AzEl,
        20.0,
        Pointing::Track { target: 0 },
        vec![1e-4, 1e-4],
    );
    let mean = |cam: SensorSpec| {
        let s = scenario(vec![still("east", 100.0, 0.0)], cam);
        let scans = run(&s, &pose([0.0, 0.0, 100.0], 0.0), 100, 3);
        let n = scans.len() as f64;
        let sum = scans.iter().fold([0.0, 0.0], |a, l| {
            let z = &l.scan.detections[0].z;
            [a[0] + z[0], a[1] + z[1]]
        });
        [sum[0] / n, sum[1] / n]
    };
    let clean = mean(cam.clone());
    if let SensorType::Camera { mounting_deg, .. } = &mut cam.model {
        *mounting_deg = [0.5, -0.3];
    }
    let mounted = mean(cam);
    assert!((clean[0] - FRAC_PI_2).abs() < 1e-4, "{clean:?}");
    assert!(
        (clean[1] + std::f64::consts::FRAC_PI_4).abs() < 1e-4,
        "{clean:?}"
    );
    assert!(
        ((mounted[0] - clean[0]).to_degrees() - 0.5).abs() < 1e-3,
        "{mounted:?}"
    );
    assert!(
        ((mounted[1] - clean[1]).to_degrees() + 0.3).abs() < 1e-3,
        "{mounted:?}"
    );
}

#[test]
fn a_time_offset_stamps_the_same_scans_later() {
    let mut cam = camera(
        CameraOutput::AzEl,
        20.0,
        Pointing::Track { target: 0 },
        vec![1e-3, 1e-3],
    );
    let scans = |cam: SensorSpec| {
        let s = scenario(vec![still("east", 100.0, 0.0)], cam);
        let world = World::new(&s, 3).expect("world");
        let mut suite = SensorSuite::new(&s, 3, 1).expect("suite");
        (0..20)
            .flat_map(|k| {
                let t = k as f64 / s.sensors[0].rate_hz;
                suite.scan(t, 1, &pose([0.0, 0.0, 100.0], 0.0), ORIGIN, &world)
            })
            .collect::<Vec<_>>()
    };
    let clean = scans(cam.clone());
    cam.time_offset_s = 0.2;
    let late = scans(cam);
    assert_eq!(clean.len(), 20);
    assert_eq!(late.len(), clean.len());
    for (c, l) in clean.iter().zip(&late) {
        assert!((l.t - c.t - 0.2).abs() < 1e-12, "{} vs {}", l.t, c.t);
        assert_eq!(
            l.detections, c.detections,
            "the same world, seen at the same time"
        );
        assert_eq!(l.platform, c.platform);
    }
}

/// A radar that paints vehicles detects the other vehicles as it does the targets (with its
/// bias, labelled past the targets), within its range; one that does not, and the cameras, see
/// the targets only, with the same draws as before.
#[test]
fn a_radar_that_paints_vehicles_sees_the_others_with_its_bias() {
    let radar = |paints_vehicles| SensorSpec {
        id: "radar".into(),
        rate_hz: 1.0,
        pd: 1.0,
        clutter_rate: 0.0,
        time_offset_s: 0.0,
        max_range_m: 6000.0,
        noise_std: vec![1e-6, 1e-9],
        model: SensorType::Radar {
            bias: BiasModel::Abrupt {
                t_on: 0.0,
                t_off: 1e9,
                scale: [0.0, 0.0],
                offset: [25.0, 0.004],
            },
            paints_vehicles,
        },
    };
    let scan = |paints: bool| {
        let s = scenario(vec![still("t", 3000.0, 4000.0)], radar(paints));
        let world = World::new(&s, 3).expect("world");
        let mut suite = SensorSuite::new(&s, 3, 1).expect("suite");
        // A UAV 300 m East, 400 m North and 120 m up of the radar; another out of range.
        assert_eq!(suite.paints_vehicles(), paints);
        suite.set_vehicles([
            Vector3::new(300.0, 400.0, 120.0),
            Vector3::new(9000.0, 0.0, 100.0),
        ]);
        let mut l = suite.scan_labelled(0.0, 1, &pose([0.0, 0.0, 0.0], 0.0), ORIGIN, &world);
        assert_eq!(l.len(), 1);
        l.remove(0)
    };
    let plain = scan(false);
    assert_eq!(plain.sources, vec![Some(0)]);
    let painting = scan(true);
    let mut sources = painting.sources.clone();
    sources.sort();
    assert_eq!(sources, vec![Some(0), Some(1)]);
    let uav = painting
        .sources
        .iter()
        .position(|s| *s == Some(1))
        .expect("the UAV");
    let z = &painting.scan.detections[uav].z;
    let slant = (300.0f64 * 300.0 + 400.0 * 400.0 + 120.0 * 120.0).sqrt();
    assert!((z[0] - (slant + 25.0)).abs() < 1e-3, "{z:?}");
    assert!((z[1] - (0.6435011087932844 + 0.004)).abs() < 1e-6, "{z:?}");
    // The target's detection is the one of the radar that does not paint vehicles.
    let target = painting
        .sources
        .iter()
        .position(|s| *s == Some(0))
        .expect("the target");
    assert_eq!(painting.scan.detections[target], plain.scan.detections[0]);
}
