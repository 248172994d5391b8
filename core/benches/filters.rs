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
use harrier_core::filter::{CentralDifference, Extended, Kalman, Predictor, Updater};
use harrier_core::measurement::{AzEl, Geometry, MeasurementModel, Position, RangeBearing};
use harrier_core::motion::{ConstantVelocity, TransitionModel};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix6, SVector, Vector2, Vector3, Vector6};

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

fn config() -> Criterion {
    Criterion::default()
        .warm_up_time(Duration::from_secs(1))
        .measurement_time(Duration::from_millis(2500))
}

criterion_group! {
    name = filters;
    config = config();
    targets = kf, ekf, cdkf
}
criterion_main!(filters);
