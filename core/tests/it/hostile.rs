//! Hostile numbers (issue 11): NaN, ±∞, zero and negative noise, `dt ≤ 0` and huge values
//! (1e300) fed to every filter, the multi-target tracker and every guidance law.
//!
//! What must hold (ARCHITECTURE.md, "never panics on numeric failure"): each call returns an
//! error or a defined safe output — a finite state, or for guidance the documented
//! [`hold`] command — and a stateful object (tracker, error-space predictor, adaptive network) is
//! unchanged after an error. Immutable inputs (`&prior`) cannot change by construction; what is
//! checked for them is that an `Ok` is finite.
//!
//! Case counts: [`cases`] per property (BENCHMARKS.md § Fuzzing).

use harrier_core::filter::mpekf::{ModifiedPolarEkf, MpAzEl, PlatformStep};
use harrier_core::filter::nn::AdaptiveNn;
use harrier_core::filter::{
    BiasAwareCdkf, BiasedMeasurement, BoundedLinearMeasurement, BoundedLinearTransition,
    CentralDifference, ErrorSpace, ErrorSpacePredictor, Extended, IcdkfForm, Imm, ImmState,
    IncrementalCdkf, Kalman, MeasurementPredictor, ModeModel, Obe, ObeCriterion, Predictor,
    StfState, StrongTracking, Updater, WithBias,
};
use harrier_core::fusion::{CiCriterion, covariance_intersection, state_vector_fusion};
use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::observability::ObservabilityManeuver;
use harrier_core::guidance::obstacle::{Avoidance, Obstacle, avoid};
use harrier_core::guidance::phase::{PhaseGains, PhaseNeighbours, gap, phase_of, speed_correction};
use harrier_core::guidance::togvf::{Togvf, optimal_entry_length, tangents};
use harrier_core::guidance::{Command, Limits, StandoffLaw, TargetEstimate, UavState, hold};
use harrier_core::measurement::{
    AzEl, BearingSize, DirectPosition, Geometry, Position, RangeBearing, TargetSize,
};
use harrier_core::motion::{
    ConstantAcceleration, ConstantTurn, ConstantVelocity, WienerAcceleration,
};
use harrier_core::road::{Road, RoadNetwork, RoadSegment, road_from_turn_legs};
use harrier_core::state::{Ellipsoid, Gaussian, Posterior};
use harrier_core::tracker::{
    Association, CimmFilter, Deleter, Gater, GaussianFilter, ImmFilter, MOfN, SinglePointInitiator,
    Tracker, TrackerConfig,
};
use nalgebra::{SMatrix, SVector, Vector2, Vector3, Vector4};
use proptest::prelude::*;

/// Cases per property: 1024, or `HARRIER_HOSTILE_CASES` (BENCHMARKS.md records a long run).
fn cases() -> u32 {
    std::env::var("HARRIER_HOSTILE_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1024)
}

/// A number from the hostile set, or an ordinary one.
fn num() -> impl Strategy<Value = f64> {
    prop_oneof![
        4 => -1e3..1e3f64,
        1 => Just(f64::NAN),
        1 => Just(f64::INFINITY),
        1 => Just(f64::NEG_INFINITY),
        1 => Just(0.0),
        1 => Just(-1.0),
        1 => Just(1e300),
        1 => Just(-1e300),
        1 => Just(1e-300),
        1 => Just(f64::MAX),
        1 => Just(f64::MIN_POSITIVE),
    ]
}

/// A noise level / std / rate: hostile or positive.
fn noise() -> impl Strategy<Value = f64> {
    prop_oneof![3 => 1e-3..1e2f64, 2 => num()]
}

/// A time step: hostile or ordinary.
fn dt() -> impl Strategy<Value = f64> {
    prop_oneof![3 => 1e-3..5.0f64, 2 => num()]
}

fn vec<const N: usize>() -> impl Strategy<Value = SVector<f64, N>> {
    prop::collection::vec(num(), N).prop_map(|v| SVector::<f64, N>::from_column_slice(&v))
}

fn ordinary<const N: usize>() -> impl Strategy<Value = SVector<f64, N>> {
    prop::collection::vec(-1e3..1e3f64, N).prop_map(|v| SVector::<f64, N>::from_column_slice(&v))
}

/// A Gaussian as a caller could hold it: either valid (from `Gaussian::new`) or with hostile
/// numbers written straight into its public fields.
fn gaussian<const N: usize>() -> impl Strategy<Value = Gaussian<N>> {
    (
        ordinary::<N>(),
        vec::<N>(),
        prop::collection::vec(noise(), N),
        any::<u8>(),
    )
        .prop_map(|(good, bad, var, pick)| {
            let diag = SVector::<f64, N>::from_iterator(var.iter().map(|v| v * v.abs()));
            match pick % 4 {
                0 | 1 => Gaussian::new(good, SMatrix::from_diagonal(&good.map(|x| 1.0 + x.abs())))
                    .unwrap_or(Gaussian {
                        mean: good,
                        cov: SMatrix::identity(),
                    }),
                2 => Gaussian {
                    mean: bad,
                    cov: SMatrix::identity() * 10.0,
                },
                _ => Gaussian {
                    mean: good,
                    cov: SMatrix::from_diagonal(&diag),
                },
            }
        })
}

fn finite<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> bool {
    m.iter().all(|x| x.is_finite())
}

/// An `Ok` state is finite, symmetric, with a non-negative diagonal (up to rounding).
fn check_gaussian<const N: usize>(g: &Gaussian<N>, what: &str) {
    assert!(finite(&g.mean), "{what}: non-finite mean {g:?}");
    assert!(finite(&g.cov), "{what}: non-finite covariance {g:?}");
    assert!(
        (g.cov - g.cov.transpose()).abs().max() <= 1e-9 * (1.0 + g.cov.abs().max()),
        "{what}: asymmetric covariance {g:?}"
    );
    // As `linalg::ensure_covariance`: rounding may leave −1e-12 of the largest variance.
    let tol = 1e-12 * g.cov.diagonal().abs().max();
    assert!(
        g.cov.diagonal().iter().all(|&v| v >= -tol),
        "{what}: negative variance {g:?}"
    );
}

fn check_predict<const N: usize>(r: &harrier_core::Result<Gaussian<N>>, what: &str) {
    if let Ok(g) = r {
        check_gaussian(g, what);
    }
}

fn check_update<const N: usize, const M: usize>(
    r: &harrier_core::Result<Posterior<Gaussian<N>, M>>,
    what: &str,
) {
    if let Ok(p) = r {
        check_gaussian(&p.state, what);
        assert!(
            finite(&p.innovation) && finite(&p.innovation_cov),
            "{what}: {p:?}"
        );
    }
}

fn sensor() -> impl Strategy<Value = Vector3<f64>> {
    prop_oneof![3 => ordinary::<3>(), 1 => vec::<3>()]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// KF, EKF and CDKF: predict / update / measurement prediction with hostile priors, process
    /// noise, time steps, measurement noise and measurements.
    #[test]
    fn gaussian_filters(
        prior in gaussian::<6>(),
        q in noise(), omega in num(), dt in dt(),
        std in noise(), z3 in vec::<3>(), z2 in vec::<2>(),
        at in sensor(), h in noise(),
    ) {
        let cv = ConstantVelocity::<6>::new(q);
        let ct = ConstantTurn::<6>::new(omega, q);
        let pos = Position::<3>::new(Geometry::spatial(), [std; 3]);
        let rb = RangeBearing::new(Geometry::spatial(), at, [std, std * 1e-3]);
        let ae = AzEl::new(Geometry::spatial(), at, [std, std]);
        check_predict(&Kalman.predict(&cv, &prior, dt), "kf predict");
        check_update(&Kalman.update(&pos, &prior, &z3), "kf update");
        check_predict(&Extended.predict(&ct, &prior, dt), "ekf predict ct");
        check_update(&Extended.update(&rb, &prior, &z2), "ekf update rb");
        check_update(&Extended.update(&ae, &prior, &z2), "ekf update az_el");
        let _ = Extended.predict_measurement(&rb, &prior);
        let cd = CentralDifference::new(h).unwrap_or_default();
        check_predict(&cd.predict(&ct, &prior, dt), "cdkf predict");
        check_update(&cd.update(&rb, &prior, &z2), "cdkf update");
        if let Ok(p) = cd.predict_measurement(&ae, &prior) {
            prop_assert!(finite(&p.zhat) && finite(&p.cov));
        }
    }

    /// CA prediction and the bearing-size model (target size from the state or known).
    #[test]
    fn ca_and_bearing_size(
        prior in gaussian::<9>(), q in noise(), dt in dt(),
        std in noise(), size in num(), z in vec::<3>(), at in sensor(),
    ) {
        let ca = ConstantAcceleration::<9>::new(q);
        check_predict(&Kalman.predict(&ca, &prior, dt), "ca predict");
        let bs = BearingSize::new(Geometry::spatial(), at, TargetSize::Known(size), [std; 3]);
        check_update(&Extended.update(&bs, &prior, &z), "bearing-size update");
        check_update(&CentralDifference::default().update(&bs, &prior, &z), "bearing-size cdkf");
    }

    /// Incremental CDKF (both forms) and the bias-aware CDKF.
    #[test]
    fn icdkf_and_bias(
        prior in gaussian::<4>(), q in noise(), dt in dt(), std in noise(),
        dz in vec::<2>(), at in sensor(), drift in noise(), tau in num(),
        aug in gaussian::<6>(), jump_std in noise(), jump_prob in num(),
    ) {
        let cv = ConstantVelocity::<4>::new(q);
        let rb = RangeBearing::new(Geometry::planar(0.0), at, [std, std * 1e-3]);
        let rb0 = RangeBearing::new(Geometry::planar(0.0), Vector3::zeros(), [std, std * 1e-3]);
        let general = IncrementalCdkf { form: IcdkfForm::General, ..IncrementalCdkf::default() };
        for ic in [IncrementalCdkf::default(), general] {
            let p: harrier_core::Result<Gaussian<8>> = ic.predict(&cv, &prior, dt);
            check_predict(&p, "icdkf predict");
            if let Ok(p) = ic.predict::<_, 4, 8>(&cv, &Gaussian::new(Vector4::new(100.0, 50.0, 1.0, 1.0), SMatrix::identity()).unwrap(), 1.0) {
                check_update(&ic.update::<_, 4, 8, 2>(&rb, &rb0, &p, &dz), "icdkf update");
            }
        }
        if let Ok(model) = WithBias::<_, 4, 2>::new(cv, [drift, drift], tau) {
            let bf = BiasAwareCdkf::<2> {
                cd: CentralDifference::default(),
                jump_std: [jump_std; 2],
                jump_prob,
            };
            check_predict(&bf.predict(&model, &aug, dt), "bias predict");
            let h = BiasedMeasurement::<_, 4> { inner: rb };
            if let Ok(u) = bf.update(&h, &aug, &dz) {
                check_gaussian(&u.posterior.state, "bias update");
            }
        }
    }

    /// Strong tracking filter: one step with hostile inputs; an `Ok` is finite and λ ≥ 1.
    #[test]
    fn strong_tracking(
        prior in gaussian::<6>(), q in noise(), dt in dt(), std in noise(), z in vec::<3>(),
        beta in num(), rho in num(),
    ) {
        let stf = StrongTracking::new(beta, rho).unwrap_or_default();
        let cv = ConstantVelocity::<6>::new(q);
        let pos = Position::<3>::new(Geometry::spatial(), [std; 3]);
        let state = StfState::<6, 3>::new(prior);
        if let Ok(s) = stf.step(&cv, &pos, &state, &z, dt) {
            check_gaussian(&s.state.estimate, "stf");
            prop_assert!(s.fading_factor.is_finite() && s.fading_factor >= 1.0);
            // A second step from the first's state (with its innovation covariance).
            if let Ok(s2) = stf.step(&cv, &pos, &s.state, &z, dt) {
                check_gaussian(&s2.state.estimate, "stf 2");
            }
        }
    }

    /// Error-space estimator: a stateful predictor; after an error its state is unchanged.
    #[test]
    fn error_space(
        zs in prop::collection::vec((vec::<2>(), dt()), 1..10), q in noise(), std in noise(),
    ) {
        let models = ErrorSpace::symmetric(WienerAcceleration::<6>::new(q), DirectPosition::new([std; 2]));
        let mut ese = ErrorSpacePredictor::<_, _, 6, 2>::new(models);
        let mut t = 0.0;
        for (z, dt) in zs {
            t += dt;
            let before = format!("{ese:?}");
            if ese.step(&z, t).is_err() {
                prop_assert_eq!(format!("{ese:?}"), before, "changed on error");
            }
            if let Ok(Some(p)) = ese.predict(t + 1.0) {
                prop_assert!(finite(&p), "ese prediction {p:?}");
            }
        }
    }

    /// Set-membership (OBE): hostile ellipsoids, noise radii and half-widths.
    #[test]
    fn obe(
        centre in vec::<2>(), shape in prop::collection::vec(noise(), 2), w in noise(),
        half in noise(), y in num(), a in num(),
    ) {
        let e = Ellipsoid {
            center: centre,
            shape: SMatrix::<f64, 2, 2>::from_diagonal(&Vector2::new(shape[0], shape[1])),
        };
        let good = Ellipsoid::new(Vector2::new(1.0, 2.0), SMatrix::identity() * 4.0).unwrap();
        for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
            let obe = Obe::new(crit);
            if let Ok(tr) = BoundedLinearTransition::new(
                SMatrix::<f64, 2, 2>::new(1.0, a, 0.0, 1.0),
                SMatrix::<f64, 2, 1>::new(0.5, 1.0),
                w,
            ) {
                for s in [&e, &good] {
                    if let Ok(p) = obe.predict(&tr, s, 1.0) {
                        prop_assert!(finite(&p.center) && finite(&p.shape), "{p:?}");
                    }
                }
            }
            if let Ok(me) = BoundedLinearMeasurement::new(
                SMatrix::<f64, 1, 2>::new(1.0, 0.0),
                SVector::<f64, 1>::new(half),
            ) {
                for s in [&e, &good] {
                    if let Ok(p) = obe.update(&me, s, &SVector::<f64, 1>::new(y)) {
                        prop_assert!(finite(&p.state.center) && finite(&p.state.shape), "{p:?}");
                    }
                }
            }
        }
    }

    /// Modified-polar EKF: prediction with hostile platform motion and the angles update.
    #[test]
    fn mpekf(
        prior in gaussian::<6>(), qh in noise(), qv in noise(), dt in dt(),
        from in vec::<3>(), to in vec::<3>(), accel in vec::<3>(), z in vec::<2>(), std in noise(),
    ) {
        if let Ok(f) = ModifiedPolarEkf::new(qh, qv) {
            let step = PlatformStep { from_pos: from, from_vel: Vector3::zeros(), to_pos: to, to_vel: Vector3::zeros() };
            check_predict(&f.predict(&prior, &step, &accel, dt), "mpekf predict");
        }
        check_update(&Extended.update(&MpAzEl::new([std, std]), &prior, &z), "mp az_el");
    }

    /// The adaptive network: training with a hostile input or error leaves it unchanged and its
    /// output stays finite.
    #[test]
    fn adaptive_nn(x in vec::<4>(), e in vec::<2>()) {
        let mut nn = AdaptiveNn::<4, 6, 2>::new(0.5, 0.01, 10.0).unwrap();
        let before = nn;
        match nn.train(&x, &e) {
            Ok(()) => prop_assert!(finite(&nn.output(&Vector4::new(1.0, 0.1, 0.2, 0.3)))),
            Err(_) => prop_assert_eq!(format!("{nn:?}"), format!("{before:?}")),
        }
    }

    /// IMM: predict and update with hostile mode models, transition matrices and probabilities.
    #[test]
    fn imm(
        prior in gaussian::<4>(), q in noise(), omega in num(), p in num(), mu in num(),
        dt in dt(), z in vec::<2>(), std in noise(),
    ) {
        let Ok(imm) = Imm::new(
            Extended,
            [ModeModel::Cv { q }, ModeModel::Ct { omega, q }],
            [[1.0 - p, p], [p, 1.0 - p]],
        ) else { return Ok(()) };
        let Ok(state) = ImmState::new(prior, [mu, 1.0 - mu]) else { return Ok(()) };
        if let Ok(s) = imm.predict(&state, dt) {
            for m in &s.modes {
                check_gaussian(m, "imm predict");
            }
            prop_assert!(s.probs.iter().all(|p| p.is_finite() && *p >= 0.0));
            let pos = Position::<2>::new(Geometry::planar(0.0), [std; 2]);
            if let Ok(u) = imm.update(&pos, &s, &z) {
                for m in &u.modes {
                    check_gaussian(m, "imm update");
                }
                prop_assert!((u.probs.iter().sum::<f64>() - 1.0).abs() < 1e-9);
            }
        }
    }

    /// The multi-target tracker (EKF and IMM per track): hostile scan times, detections and
    /// sensor noise; an error leaves the tracker unchanged, every track stays finite.
    #[test]
    fn tracker(
        scans in prop::collection::vec((dt(), prop::collection::vec(prop_oneof![3 => ordinary::<2>(), 1 => vec::<2>()], 0..4), noise()), 1..12),
    ) {
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).unwrap(),
            tentative_gater: Gater::chi2(0.99, 2).unwrap(),
            confirm: MOfN::new(2, 3).unwrap(),
            deleter: Deleter::new(3, 1e4, 2).unwrap(),
            association: Association::Gnn,
        };
        let mut ekf: Tracker<_, _, 4> = Tracker::new(
            GaussianFilter { filter: Extended, motion: ConstantVelocity::<4>::new(0.5) },
            SinglePointInitiator::new(10.0, 10.0).unwrap(),
            config,
        );
        let imm = Imm::new(
            Extended,
            [ModeModel::Cv { q: 0.05 }, ModeModel::Ct { omega: 0.1, q: 0.05 }],
            [[0.95, 0.05], [0.05, 0.95]],
        ).unwrap();
        let mut immt: Tracker<_, _, 4> = Tracker::new(
            ImmFilter { imm, initial_probs: [0.9, 0.1] },
            SinglePointInitiator::new(10.0, 10.0).unwrap(),
            config,
        );
        let mut t = 0.0;
        for (dt, dets, std) in scans {
            t += dt;
            let cam = Position::<2>::new(Geometry::planar(0.0), [std, std]);
            let before = (format!("{:?}", ekf.tracks()), ekf.time(), ekf.next_id());
            if ekf.step(t, &cam, &dets).is_err() {
                prop_assert_eq!((format!("{:?}", ekf.tracks()), ekf.time(), ekf.next_id()), before);
            }
            for tr in ekf.tracks() {
                check_gaussian(&tr.state, "ekf track");
            }
            let before = (format!("{:?}", immt.tracks()), immt.time(), immt.next_id());
            if immt.step(t, &cam, &dets).is_err() {
                prop_assert_eq!((format!("{:?}", immt.tracks()), immt.time(), immt.next_id()), before);
            }
            for tr in immt.tracks() {
                for m in &tr.state.modes {
                    check_gaussian::<4>(m, "imm track");
                }
            }
            for s in ekf.snapshot() {
                prop_assert!(s.estimate.mean.iter().all(|x| x.is_finite()));
            }
        }
    }

    /// Roads (lines and arcs with hostile geometry), projection of hostile points, the road
    /// builder of the guidance simulation, and state-vector / covariance-intersection fusion.
    #[test]
    fn roads_and_fusion(
        a in vec::<2>(), b in vec::<2>(), c in vec::<2>(), radius in num(), start in num(),
        sweep in num(), sigma in noise(), p in vec::<2>(), legs in prop::collection::vec((num(), num()), 0..4),
        end_t in num(), tracks in prop::collection::vec(gaussian::<4>(), 1..4),
    ) {
        let segments = vec![
            RoadSegment::Line { start: a, end: b },
            RoadSegment::Arc { center: c, radius, start_angle: start, sweep },
        ];
        for segs in [segments[..1].to_vec(), segments[1..].to_vec(), segments] {
            if let Ok(road) = Road::new(segs, sigma) {
                let q = road.project(&p);
                if finite(&p) && p.amax() <= 1e150 {
                    prop_assert!(finite(&q.point) && finite(&q.tangent) && q.offset.is_finite(), "{q:?}");
                }
            }
        }
        if let Ok(spec) = road_from_turn_legs(a, b, &legs, end_t, "r", None, Some(sigma)) {
            if let Ok(net) = RoadNetwork::from_scenario(&[spec]) {
                if let Some(road) = net.nearest(&p) {
                    let q = road.project(&p);
                    if finite(&p) && p.amax() <= 1e150 {
                        prop_assert!(finite(&q.point) && q.offset.is_finite(), "{q:?}");
                    }
                }
            }
        }
        check_predict(&state_vector_fusion(&tracks), "state-vector fusion");
        for crit in [CiCriterion::Trace, CiCriterion::Det] {
            check_predict(&covariance_intersection(&tracks, crit), "covariance intersection");
        }
    }

    /// The road-constrained IMM tracker (CIMM): hostile scans on a road network.
    #[test]
    fn cimm_tracker(
        scans in prop::collection::vec((dt(), prop::collection::vec(prop_oneof![3 => ordinary::<2>(), 1 => vec::<2>()], 0..4), noise()), 1..10),
    ) {
        let spec = road_from_turn_legs(
            Vector2::new(-500.0, 0.0), Vector2::new(10.0, 0.0), &[(0.0, 0.0), (30.0, 0.05)], 100.0,
            "r", Some(8.0), Some(3.0),
        ).unwrap();
        let roads = RoadNetwork::from_scenario(&[spec]).unwrap();
        let imm = Imm::new(
            Extended,
            [ModeModel::Cv { q: 0.05 }, ModeModel::Ct { omega: 0.05, q: 0.05 }],
            [[0.95, 0.05], [0.05, 0.95]],
        ).unwrap();
        let filter = CimmFilter {
            imm: ImmFilter { imm, initial_probs: [0.9, 0.1] },
            roads,
            sigma_v: 3.0,
            max_offset_m: 19.0,
        };
        let config = TrackerConfig {
            gater: Gater::chi2(0.999, 2).unwrap(),
            tentative_gater: Gater::chi2(0.99, 2).unwrap(),
            confirm: MOfN::new(2, 3).unwrap(),
            deleter: Deleter::new(3, 1e4, 2).unwrap(),
            association: Association::Gnn,
        };
        let mut tr: Tracker<_, _, 4> = Tracker::new(filter, SinglePointInitiator::new(10.0, 10.0).unwrap(), config);
        let mut t = 0.0;
        for (dt, dets, std) in scans {
            t += dt;
            let cam = Position::<2>::new(Geometry::planar(0.0), [std, std]);
            let before = (format!("{:?}", tr.tracks()), tr.time(), tr.next_id());
            if tr.step(t, &cam, &dets).is_err() {
                prop_assert_eq!((format!("{:?}", tr.tracks()), tr.time(), tr.next_id()), before);
            }
            for s in tr.snapshot() {
                check_gaussian(&s.estimate, "cimm track");
            }
        }
    }

    /// Kinematics: a step is finite, or the state unchanged for a non-finite state or `dt`.
    #[test]
    fn kinematics_step(
        p in vec::<3>(), v in vec::<3>(), c in vec::<3>(), dt in dt(), fixed_wing in any::<bool>(),
    ) {
        let limits = if fixed_wing { Limits::fixed_wing() } else { Limits::multirotor() };
        let s = UavState::new(p, v);
        let next = step(&s, &Command { velocity: c }, &limits, dt);
        if s.is_finite() && dt.is_finite() && dt > 0.0 {
            prop_assert!(next.is_finite() || format!("{next:?}") == format!("{s:?}"), "{s:?} dt={dt} → {next:?}");
        } else {
            prop_assert_eq!(format!("{next:?}"), format!("{s:?}"));
        }
        prop_assert!(hold(&s, &limits).is_finite());
    }

    /// TOGVF and LGVF: hostile UAV state, target estimate, law parameters and phase neighbours
    /// give a finite command (the hold command when the inputs are not finite).
    #[test]
    fn standoff_laws(
        p in vec::<3>(), v in vec::<3>(), tp in vec::<3>(), tv in vec::<3>(),
        radius in num(), height in num(), speed in num(),
        ahead in num(), behind in num(), spacing in num(), fixed_wing in any::<bool>(),
    ) {
        let limits = if fixed_wing { Limits::fixed_wing() } else { Limits::multirotor() };
        let uav = UavState::new(p, v);
        let tgt = TargetEstimate { position: tp, velocity: tv };
        let nb = PhaseNeighbours { ahead: Some(ahead), behind: Some(behind), spacing };
        let laws: [&dyn StandoffLaw; 2] = [&Togvf::new(radius, height, speed), &Lgvf::new(radius, height, speed)];
        for law in laws {
            for target in [Some(&tgt), None] {
                for phase in [Some(&nb), None] {
                    let c = law.command(&uav, target, &limits, phase);
                    prop_assert!(c.is_finite(), "{c:?}");
                    if !(uav.is_finite() && target.is_some_and(|t| t.is_finite())) {
                        prop_assert_eq!(c, hold(&uav, &limits));
                    }
                }
            }
        }
        let d = Vector2::new(p.x, p.y);
        let _ = tangents(d, radius);
        let _ = optimal_entry_length(d, Vector2::new(v.x, v.y), radius, speed, 1.0);
        let _ = Togvf::vertical_speed(height, &limits);
    }

    /// Phase coordination, formation regulator, obstacle avoidance, observability manoeuvre.
    #[test]
    fn other_laws(
        a in vec::<2>(), b in vec::<2>(), c in vec::<2>(), x in num(), y in num(), r in num(),
        dt in dt(), radius in num(), k1 in num(), k2 in num(),
    ) {
        let th = phase_of(a, b);
        prop_assert!(th.is_nan() || th.abs() <= std::f64::consts::PI + 1e-12);
        let _ = gap(x, y, 1.0);
        let nb = PhaseNeighbours { ahead: Some(x), behind: Some(y), spacing: r };
        prop_assert!(speed_correction(th, 1.0, &nb, &PhaseGains::default(), radius).is_finite());
        let _ = PhaseNeighbours::ring(&[x, y, r], 1);

        let reg = RangeRegulator::default();
        let pair = PairState::start(r);
        let next = reg.advance(&pair, x, y, dt);
        if pair.r_c.is_finite() && x.is_finite() && y.is_finite() && dt.is_finite() && dt > 0.0 {
            prop_assert!(next.r_c.is_finite() && next.v_ad.is_finite(), "{pair:?} → {next:?}");
        }
        let _ = reg.hedge(&pair, x);
        let _ = reg.pseudo_control(&pair, x, y);
        let _ = vector_sum([(a, x), (b, y)]);

        let obstacles = [Obstacle { center: c, radius }, Obstacle { center: Vector2::new(50.0, 0.0), radius: 10.0 }];
        let params = Avoidance { lookahead: r, margin: x };
        let (cmd, _) = avoid(a, b, Vector2::new(20.0, 1.0), &obstacles, &params);
        if a.iter().chain(b.iter()).all(|v| v.is_finite()) {
            prop_assert!(cmd.iter().all(|v| v.is_finite()), "avoid gave {cmd:?}");
        }

        if let Some(m) = ObservabilityManeuver::from_weights(k1, k2, r) {
            prop_assert!(m.omega.is_finite());
            let lv = m.lateral_velocity(a, x, y);
            prop_assert!(lv.iter().all(|v| v.is_finite()) || !r.is_finite() || !y.is_finite(), "{lv:?}");
        }
    }
}
