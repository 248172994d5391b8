//! Cost of one multi-target tracker scan by associator, at scale: N confirmed tracks on N targets
//! and a scan of about 5 N detections (the targets at Pd 0.9, 4.1 N clutter detections uniform
//! over the area), EKF (the KF on this planar position sensor) with the CV model.
//!
//! Run with `cargo bench -p harrier-core --bench association`. Targets: 1 000 tracks and 5 000
//! detections, GNN ≤ 10 ms, JIPDA ≤ 20 ms per scan (2-core machine); the growth from 10 to
//! 10 000 targets is in BENCHMARKS.md ("Association under ambiguity").
//!
//! The targets fly straight at 5–15 m/s in random directions from random places of a square of
//! side √N · 300 m (one target per 9 ha, so that some gates overlap and clusters form). The
//! tracker is first brought to N confirmed tracks by clutter-free scans with every target
//! detected; every timed iteration then starts again from a clone of it (the clone is not timed)
//! and processes the same next scan, so every iteration does the same work: gating through the
//! spatial index, clustering, the association of every cluster, the updates, and the tentative
//! tracks started from the 4.1 N clutter detections.

use std::hint::black_box;

use criterion::{BatchSize, BenchmarkId, Criterion, criterion_group, criterion_main};
use harrier_core::filter::Extended;
use harrier_core::measurement::{Geometry, Position};
use harrier_core::motion::ConstantVelocity;
use harrier_core::tracker::existence::Existence;
use harrier_core::tracker::{
    Association, Deleter, DetectionModel, Gater, GaussianFilter, Jipda, MOfN, Mht,
    SinglePointInitiator, Tracker, TrackerConfig,
};
use nalgebra::Vector2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

const WARM_UP_SCANS: u32 = 4;
/// Clutter detections per target and scan.
const CLUTTER_PER_TARGET: f64 = 4.1;

type Kf = GaussianFilter<Extended, ConstantVelocity<4>>;

/// The associators measured, with the clutter density of the scans.
fn associations(density: f64) -> [(&'static str, Association); 3] {
    let detection = DetectionModel::new(0.9, Some(density)).expect("detection model");
    let existence = Existence::new(0.995, 0.1, 0.9, 0.01).expect("existence");
    [
        ("gnn", Association::Gnn),
        (
            "jipda",
            Association::Jipda(Jipda {
                detection,
                existence,
                birth: 0.5,
                max_net_nodes: 10_000,
                star_nodes: 20_000,
                star_gate: 0.9,
            }),
        ),
        (
            "mht",
            Association::Mht(
                Mht::new(detection, existence, 3, 16, 1_000_000, 100_000, 0.0).expect("mht"),
            ),
        ),
    ]
}

/// A tracker with `n` confirmed tracks and the scan to time.
fn setup(
    n: usize,
    association: Association,
) -> (Tracker<Kf, SinglePointInitiator, 4>, Vec<Vector2<f64>>) {
    let mut rng = ChaCha8Rng::seed_from_u64(n as u64);
    let side = (n as f64).sqrt() * 300.0;
    let targets: Vec<(Vector2<f64>, Vector2<f64>)> = (0..n)
        .map(|_| {
            let p = Vector2::new(rng.random_range(0.0..side), rng.random_range(0.0..side));
            let (h, s) = (
                rng.random_range(0.0..std::f64::consts::TAU),
                rng.random_range(5.0..15.0),
            );
            (p, Vector2::new(h.sin(), h.cos()) * s)
        })
        .collect();
    let at = |k: u32, rng: &mut ChaCha8Rng| -> Vec<Vector2<f64>> {
        targets
            .iter()
            .map(|(p, v)| {
                p + v * f64::from(k)
                    + Vector2::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0))
            })
            .collect()
    };
    let config = TrackerConfig {
        gater: Gater::chi2(0.999, 2).expect("gate"),
        tentative_gater: Gater::chi2(0.95, 2).expect("gate"),
        confirm: MOfN::new(2, 3).expect("m of n"),
        deleter: Deleter::new(5, 1e5, 2).expect("deleter"),
        association,
    };
    let filter = GaussianFilter {
        filter: Extended,
        motion: ConstantVelocity::<4>::new(0.25),
    };
    let mut tracker = Tracker::new(
        filter,
        SinglePointInitiator::new(12.0, 50.0).expect("init"),
        config,
    );
    let sensor = Position::new(Geometry::planar(0.0), [5.0, 5.0]);
    for k in 0..WARM_UP_SCANS {
        tracker
            .step(f64::from(k), &sensor, &at(k, &mut rng))
            .expect("a scan");
    }
    let confirmed = tracker.confirmed().len();
    assert!(confirmed >= n * 95 / 100, "{confirmed} of {n} confirmed");
    let mut scan: Vec<Vector2<f64>> = at(WARM_UP_SCANS, &mut rng)
        .into_iter()
        .filter(|_| rng.random_bool(0.9))
        .collect();
    let clutter = (CLUTTER_PER_TARGET * n as f64) as usize;
    scan.extend((0..clutter).map(|_| {
        Vector2::new(
            rng.random_range(-500.0..side + 500.0),
            rng.random_range(-500.0..side + 500.0),
        )
    }));
    (tracker, scan)
}

fn scale(c: &mut Criterion) {
    let sensor = Position::new(Geometry::planar(0.0), [5.0, 5.0]);
    let mut group = c.benchmark_group("association");
    for n in [10usize, 100, 1_000, 10_000] {
        let side = (n as f64).sqrt() * 300.0;
        let density = CLUTTER_PER_TARGET * n as f64 / ((side + 1000.0) * (side + 1000.0));
        if n >= 1_000 {
            group.sample_size(10);
        }
        for (name, association) in associations(density) {
            let (tracker, scan) = setup(n, association);
            let t = f64::from(WARM_UP_SCANS);
            group.bench_with_input(BenchmarkId::new(name, n), &n, |b, _| {
                b.iter_batched(
                    || tracker.clone(),
                    |mut tr| {
                        tr.step(black_box(t), &sensor, black_box(&scan))
                            .expect("a scan");
                        tr
                    },
                    BatchSize::LargeInput,
                )
            });
        }
    }
    group.finish();
}

criterion_group!(benches, scale);
criterion_main!(benches);
