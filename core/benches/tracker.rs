//! Cost of one multi-target tracker step: 20 confirmed tracks, a scan of 50 detections (20 from
//! the targets, 30 clutter), EKF (the KF on this linear sensor) with the planar CV model and a
//! position sensor.
//!
//! Run with `cargo bench -p harrier-core --bench tracker`. Target: ≤ 100 µs per step.
//!
//! The tracker is first brought to 20 confirmed tracks by running it on clutter-free scans; every
//! timed iteration then starts again from a clone of that tracker (the clone is not timed) and
//! processes the same next scan, so every iteration does the same work.

use std::hint::black_box;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use harrier_core::filter::Extended;
use harrier_core::measurement::{Geometry, Position};
use harrier_core::motion::ConstantVelocity;
use harrier_core::tracker::{
    Association, Deleter, Gater, GaussianFilter, MOfN, SinglePointInitiator, Tracker, TrackerConfig,
};
use nalgebra::Vector2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const TARGETS: usize = 20;
const CLUTTER: usize = 30;
const WARM_UP_SCANS: u32 = 10;

/// Target `i` at scan `k`: a 5 × 4 grid 400 m apart, each flying at its own velocity.
fn target(i: usize, k: u32) -> Vector2<f64> {
    let (gx, gy) = ((i % 5) as f64, (i / 5) as f64);
    let v = Vector2::new(10.0 + gx, -8.0 + 2.0 * gy);
    Vector2::new(400.0 * gx, 400.0 * gy) + v * f64::from(k)
}

fn tracker_step(c: &mut Criterion) {
    let filter = GaussianFilter {
        filter: Extended,
        motion: ConstantVelocity::<4>::new(0.25),
    };
    let sensor = Position::new(Geometry::planar(0.0), [10.0, 10.0]);
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).unwrap(),
        tentative_gater: Gater::chi2(0.99, 2).unwrap(),
        confirm: MOfN::new(2, 3).unwrap(),
        deleter: Deleter::new(3, 1e5, 2).unwrap(),
        association: Association::Gnn,
    };
    let init = SinglePointInitiator::new(10.0, 10.0).unwrap();
    let mut tracker = Tracker::new(filter, init, config);
    for k in 0..WARM_UP_SCANS {
        let scan: Vec<_> = (0..TARGETS).map(|i| target(i, k)).collect();
        tracker.step(f64::from(k), &sensor, &scan).unwrap();
    }
    assert_eq!(tracker.confirmed().len(), TARGETS);
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let mut scan: Vec<_> = (0..TARGETS)
        .map(|i| target(i, WARM_UP_SCANS) + Vector2::new(rng.random_range(-5.0..5.0), 3.0))
        .collect();
    scan.extend((0..CLUTTER).map(|_| {
        Vector2::new(
            rng.random_range(-1000.0..3000.0),
            rng.random_range(-1000.0..2500.0),
        )
    }));
    let t = f64::from(WARM_UP_SCANS);
    c.benchmark_group("tracker")
        .bench_function("step_20_tracks_50_detections", |b| {
            b.iter_batched(
                || tracker.clone(),
                |mut tr| {
                    tr.step(black_box(t), &sensor, black_box(&scan)).unwrap();
                    tr
                },
                BatchSize::SmallInput,
            )
        });
}

criterion_group!(benches, tracker_step);
criterion_main!(benches);
