//! Per-step cost of the filters: one predict + update at 6 states / 2 measurements.
//!
//! Run with `scripts/bench` (or `cargo bench -p harrier-core --bench filters`); BENCHMARKS.md
//! records the figures and the targets.
//!
//! Every benchmark works on the same scene: a target flying straight and level at 120 m altitude,
//! tracked with the 3-D constant-velocity model `ConstantVelocity::<6>` at 10 Hz, seen by a sensor
//! on the ground. The prior is first brought to its steady state by running the filter itself for
//! [`WARM_UP_STEPS`] steps on noise-free measurements, and every timed iteration then starts again
//! from that prior with the next measurement, so the state cannot drift or diverge however many
//! iterations criterion runs, and every iteration does the same work.
//!
//! One function per filter, each with its own benchmark group named after the filter (`kf`, `ekf`,
//! `cdkf`, …; `scripts/bench` reads the group name to find the target). To add a filter, write one
//! more `fn name(c: &mut Criterion)` calling [`bench_step`] and list it in `criterion_group!`.

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use harrier_core::filter::{
    BiasAwareCdkf, BiasedMeasurement, BoundedLinearMeasurement, BoundedLinearTransition,
    CentralDifference, Extended, IncrementalCdkf, Kalman, Obe, ObeCriterion, Predictor, StfState,
    StrongTracking, Updater, WithBias, current,
};
use harrier_core::measurement::{AzEl, Geometry, MeasurementModel, Position, RangeBearing};
use harrier_core::motion::{ConstantVelocity, LinearTransition, TransitionModel};
use harrier_core::state::{Ellipsoid, Gaussian};
use nalgebra::{Matrix2x6, Matrix6, Matrix6x3, SMatrix, SVector, Vector2, Vector3, Vector6};

/// Filter period (s): 10 Hz.
const DT: f64 = 0.1;
/// Acceleration spectral density of the CV model (m²/s³).
const Q: f64 = 1.0;
/// Steps run before timing, to bring the covariance to its steady state.
const WARM_UP_STEPS: u32 = 50;

/// Ground sensor (ENU, m).
fn sensor() -> Vector3<f64> {
    Vector3::new(-200.0, -300.0, 2.0)
}

/// Truth `[x, y, z, vx, vy, vz]` at step `k`: 120 m up, 18 m/s towards the north-east.
fn truth(k: u32) -> Vector6<f64> {
    let t = f64::from(k) * DT;
    Vector6::new(1500.0 + 12.0 * t, 800.0 + 13.5 * t, 120.0, 12.0, 13.5, 0.0)
}

/// Initial estimate: a little off the truth, loose covariance.
fn initial() -> Gaussian<6> {
    let mean = truth(0) + Vector6::new(20.0, -15.0, 5.0, 2.0, -1.5, 0.5);
    let cov = Matrix6::from_diagonal(&Vector6::new(400.0, 400.0, 100.0, 25.0, 25.0, 4.0));
    Gaussian::new(mean, cov).expect("valid initial state")
}

/// Runs the filter [`WARM_UP_STEPS`] steps on noise-free measurements and returns the state it
/// reached together with the measurement of the following step.
fn steady_state<F, T, H>(filter: &F, motion: &T, sensor: &H) -> (Gaussian<6>, Vector2<f64>)
where
    F: Predictor<T, 6, State = Gaussian<6>> + Updater<H, 6, 2, State = Gaussian<6>>,
    T: TransitionModel<6>,
    H: MeasurementModel<6, 2>,
{
    let mut state = initial();
    for k in 1..=WARM_UP_STEPS {
        let predicted = filter.predict(motion, &state, DT).expect("warm-up predict");
        let z: SVector<f64, 2> = sensor.function(&truth(k));
        state = filter
            .update(sensor, &predicted, &z)
            .expect("warm-up update")
            .state;
    }
    (state, sensor.function(&truth(WARM_UP_STEPS + 1)))
}

/// Times one `predict` + `update` of `filter`, in group `group` under the name `id`.
fn bench_step<F, T, H>(c: &mut Criterion, group: &str, id: &str, filter: &F, motion: &T, sensor: &H)
where
    F: Predictor<T, 6, State = Gaussian<6>> + Updater<H, 6, 2, State = Gaussian<6>>,
    T: TransitionModel<6>,
    H: MeasurementModel<6, 2>,
{
    let (prior, z) = steady_state(filter, motion, sensor);
    let mut g = c.benchmark_group(group);
    g.bench_function(id, |b| {
        b.iter(|| {
            let f = black_box(filter);
            let predicted = f
                .predict(black_box(motion), black_box(&prior), black_box(DT))
                .expect("predict");
            f.update(black_box(sensor), &predicted, black_box(&z))
                .expect("update")
        });
    });
    g.finish();
}

fn cv6() -> ConstantVelocity<6> {
    ConstantVelocity::<6>::new(Q)
}

/// Position `[x, y]` (M = 2) of a 3-D state: `Geometry::spatial()` reads z from the state, and the
/// measurement takes x and y only.
fn position2() -> Position<2> {
    Position::<2>::new(Geometry::spatial(), [5.0, 5.0])
}

/// Ground radar: range (m) and azimuth (rad).
fn radar() -> RangeBearing {
    RangeBearing::new(Geometry::spatial(), sensor(), [5.0, 0.005])
}

/// Camera/gimbal: azimuth and elevation (rad).
fn camera() -> AzEl {
    AzEl::new(Geometry::spatial(), sensor(), [0.002, 0.002])
}

fn kf(c: &mut Criterion) {
    bench_step(c, "kf", "cv6_position2", &Kalman, &cv6(), &position2());
}

fn ekf(c: &mut Criterion) {
    bench_step(c, "ekf", "cv6_range_bearing", &Extended, &cv6(), &radar());
    bench_step(c, "ekf", "cv6_az_el", &Extended, &cv6(), &camera());
}

fn cdkf(c: &mut Criterion) {
    let cd = CentralDifference::default();
    bench_step(c, "cdkf", "cv6_range_bearing", &cd, &cv6(), &radar());
    bench_step(c, "cdkf", "cv6_az_el", &cd, &cv6(), &camera());
}

fn stf(c: &mut Criterion) {
    let stf = StrongTracking::new(1.0, 0.95).expect("valid STF");
    let (motion, sensor) = (cv6(), position2());
    // Steady state from the KF, then one STF step so that V_{k−1} exists.
    let (prior, z) = steady_state(&Kalman, &motion, &sensor);
    let state = StfState::new(prior);
    let state = stf
        .step(&motion, &sensor, &state, &z, DT)
        .expect("stf")
        .state;
    let z = sensor.function(&truth(WARM_UP_STEPS + 2));
    let mut g = c.benchmark_group("stf");
    g.bench_function("cv6_position2", |b| {
        b.iter(|| {
            black_box(&stf)
                .step(
                    black_box(&motion),
                    black_box(&sensor),
                    black_box(&state),
                    black_box(&z),
                    DT,
                )
                .expect("stf step")
        });
    });
    g.finish();
}

fn obe(c: &mut Criterion) {
    // x⁺ = F x + B w, ‖w‖ ≤ 1 (B = acceleration over one step), y = [x, y] + v, |vᵢ| ≤ 2 m.
    let f = cv6().matrix(DT);
    let b = Matrix6x3::from_fn(|i, j| match (i, j) {
        (i, j) if i == j => 0.5 * DT * DT,
        (i, j) if i == j + 3 => DT,
        _ => 0.0,
    }) * 2.0;
    let motion = BoundedLinearTransition::new(f, b, 1.0).expect("valid system");
    let h = Matrix2x6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
    let sensor = BoundedLinearMeasurement::new(h, Vector2::new(2.0, 2.0)).expect("valid sensor");
    for criterion in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
        let obe = Obe::new(criterion);
        let mut set = Ellipsoid::new(
            truth(0),
            Matrix6::from_diagonal(&Vector6::new(400.0, 400.0, 100.0, 25.0, 25.0, 4.0)),
        )
        .expect("valid set");
        for k in 1..=WARM_UP_STEPS {
            set = obe.predict(&motion, &set, DT).expect("warm-up predict");
            let z = Vector2::new(truth(k)[0], truth(k)[1]);
            set = obe.update(&sensor, &set, &z).expect("warm-up update").state;
        }
        let t = truth(WARM_UP_STEPS + 1);
        let z = Vector2::new(t[0], t[1]);
        let mut g = c.benchmark_group("obe");
        g.bench_function(format!("cv6_position2_{criterion:?}"), |bch| {
            bch.iter(|| {
                let o = black_box(&obe);
                let predicted = o
                    .predict(black_box(&motion), black_box(&set), DT)
                    .expect("predict");
                o.update(black_box(&sensor), &predicted, black_box(&z))
                    .expect("update")
            });
        });
        g.finish();
    }
}

fn icdkf(c: &mut Criterion) {
    // Planar CV (N = 4, augmented 8) with a radar, as in the [ICDKF] scenarios.
    let motion = ConstantVelocity::<4>::new(Q);
    let geo = Geometry::planar(120.0);
    let at = |k: u32| {
        RangeBearing::new(
            geo,
            sensor() + Vector3::new(0.5 * f64::from(k), 0.0, 0.0),
            [5.0, 0.005],
        )
    };
    let x = |k: u32| {
        let t = truth(k);
        nalgebra::Vector4::new(t[0], t[1], t[3], t[4])
    };
    let f = IncrementalCdkf::default();
    let mut g4 = Gaussian::new(
        x(0),
        nalgebra::Matrix4::from_diagonal(&nalgebra::Vector4::new(400.0, 400.0, 25.0, 25.0)),
    )
    .expect("valid prior");
    let z = |k: u32| -> Vector2<f64> { at(k).function(&x(k)) };
    for k in 1..=WARM_UP_STEPS {
        let pred: Gaussian<8> = f.predict(&motion, &g4, DT).expect("predict");
        let post = f
            .update::<_, 4, 8, 2>(&at(k), &at(k - 1), &pred, &(z(k) - z(k - 1)))
            .expect("update");
        g4 = current(&post.state);
    }
    let k = WARM_UP_STEPS + 1;
    let (now, prev, dz) = (at(k), at(k - 1), z(k) - z(k - 1));
    let mut g = c.benchmark_group("icdkf");
    g.bench_function("cv4_range_bearing", |b| {
        b.iter(|| {
            let pred: Gaussian<8> = f
                .predict(black_box(&motion), black_box(&g4), DT)
                .expect("predict");
            f.update::<_, 4, 8, 2>(black_box(&now), black_box(&prev), &pred, black_box(&dz))
                .expect("update")
        });
    });
    g.finish();
}

fn cdkf_bias(c: &mut Criterion) {
    // CV6 + range/azimuth bias states (N = 8) with the jump test.
    let motion =
        WithBias::<_, 6, 2>::new(cv6(), [0.05, 5e-5], f64::INFINITY).expect("valid bias model");
    let filter = BiasAwareCdkf {
        cd: CentralDifference::default(),
        jump_std: [200.0, 0.2],
        jump_prob: 1e-5,
    };
    let sensor = BiasedMeasurement::<_, 6> { inner: radar() };
    let init = initial();
    let mut mean = SVector::<f64, 8>::zeros();
    mean.fixed_rows_mut::<6>(0).copy_from(&init.mean);
    let mut cov = SMatrix::<f64, 8, 8>::identity() * 1e-6;
    cov.fixed_view_mut::<6, 6>(0, 0).copy_from(&init.cov);
    let mut state = Gaussian::new(mean, cov).expect("valid prior");
    for k in 1..=WARM_UP_STEPS {
        let pred = filter.predict(&motion, &state, DT).expect("predict");
        state = filter
            .update(&sensor, &pred, &radar().function(&truth(k)))
            .expect("update")
            .posterior
            .state;
    }
    let z = radar().function(&truth(WARM_UP_STEPS + 1));
    let mut g = c.benchmark_group("cdkf-bias");
    g.bench_function("cv6_range_bearing", |b| {
        b.iter(|| {
            let f = black_box(&filter);
            let pred = f
                .predict(black_box(&motion), black_box(&state), DT)
                .expect("predict");
            f.update(black_box(&sensor), &pred, black_box(&z))
                .expect("update")
        });
    });
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_millis(2500))
}

criterion_group! {
    name = filters;
    config = config();
    targets = kf, ekf, cdkf, stf, obe, icdkf, cdkf_bias
}
criterion_main!(filters);
