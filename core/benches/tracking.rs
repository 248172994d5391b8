//! Per-step cost of the multiple-model trackers at 6 states: one IMM-3 step (mixing, three
//! mode-matched EKF predictions, three updates with a position measurement, mode-probability
//! update) and one CIMM-3 step (the same plus the road pseudo-measurement update in every mode
//! filter, as `harrier replay --estimator cimm` does).
//!
//! Run with `cargo bench -p harrier-core --bench tracking`. Targets: IMM-3 ≤ 2 µs, CIMM-3 ≤ 3 µs
//! per step.
//!
//! Scene: the road of the `cimm_road_*` scenarios (a line, then a right and a left arc), a
//! ground vehicle at 10 m/s on its centre line in the 3-D CV layout `[x, y, z, vx, vy, vz]`
//! (z = 0), a camera reporting `[x, y]` with 10 m noise at 1 Hz, and the three modes of those
//! scenarios (CV, CT −0.008 rad/s, CT +0.01 rad/s). The filter is first run for
//! [`WARM_UP_STEPS`] steps on noise-free measurements; every timed iteration then starts again
//! from that state with the next measurement, so every iteration does the same work.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use harrier_core::filter::{Extended, Imm, ImmState, ModeModel};
use harrier_core::measurement::{Geometry, Position};
use harrier_core::road::{Road, RoadConstraint, RoadSegment};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix6, Vector2, Vector6};

/// Sensor period (s).
const DT: f64 = 1.0;
/// Acceleration spectral density (m²/s³): `accel_std = 0.05`.
const Q: f64 = 0.0025;
/// Steps run before timing.
const WARM_UP_STEPS: u32 = 50;

fn road() -> Road {
    Road::new(
        vec![
            RoadSegment::Line {
                start: Vector2::new(140.0, 220.0),
                end: Vector2::new(1040.0, 1420.0),
            },
            RoadSegment::Arc {
                center: Vector2::new(2040.0, 670.0),
                radius: 1250.0,
                start_angle: (1420.0_f64 - 670.0).atan2(1040.0 - 2040.0),
                sweep: -1.76,
            },
        ],
        2.0,
    )
    .expect("valid road")
}

/// Truth at step k: 10 m/s along the first (straight) segment.
fn truth(k: u32) -> Vector6<f64> {
    let t = f64::from(k) * DT;
    Vector6::new(200.0 + 6.0 * t, 300.0 + 8.0 * t, 0.0, 6.0, 8.0, 0.0)
}

fn imm() -> Imm<Extended, ModeModel, 3> {
    let models = [
        ModeModel::Cv { q: Q },
        ModeModel::Ct {
            omega: -0.008,
            q: Q,
        },
        ModeModel::Ct { omega: 0.01, q: Q },
    ];
    let tpm = [[0.98, 0.01, 0.01], [0.01, 0.98, 0.01], [0.01, 0.01, 0.98]];
    Imm::new(Extended, models, tpm).expect("valid IMM")
}

fn initial() -> ImmState<6, 3> {
    let prior = Gaussian::new(
        truth(0) + Vector6::new(5.0, -4.0, 0.0, 0.5, -0.5, 0.0),
        Matrix6::from_diagonal(&Vector6::new(400.0, 400.0, 1.0, 4.0, 4.0, 0.01)),
    )
    .expect("valid prior");
    ImmState::new(prior, [0.98, 0.01, 0.01]).expect("valid probabilities")
}

fn tracking(c: &mut Criterion) {
    let imm = imm();
    let cam = Position::<2>::new(Geometry::spatial(), [10.0, 10.0]);
    let road = road();
    let constraint = RoadConstraint::new(&road, 2.0);
    let z_of = |k: u32| Vector2::new(truth(k)[0], truth(k)[1]);

    let mut s = initial();
    for k in 1..=WARM_UP_STEPS {
        s = imm.predict(&s, DT).expect("warm-up predict");
        s = imm.update(&cam, &s, &z_of(k)).expect("warm-up update");
    }
    let z = z_of(WARM_UP_STEPS + 1);
    let mut g = c.benchmark_group("imm");
    g.bench_function("imm3_cv6_position2", |b| {
        b.iter(|| {
            let f = black_box(&imm);
            let p = f.predict(black_box(&s), black_box(DT)).expect("predict");
            f.update(black_box(&cam), &p, black_box(&z))
                .expect("update")
        });
    });
    g.finish();

    let mut s = initial();
    for k in 1..=WARM_UP_STEPS {
        s = imm.predict(&s, DT).expect("warm-up predict");
        s = imm.update(&cam, &s, &z_of(k)).expect("warm-up update");
        s = imm
            .update(&constraint, &s, &RoadConstraint::z())
            .expect("warm-up road update");
    }
    let z = z_of(WARM_UP_STEPS + 1);
    let mut g = c.benchmark_group("cimm");
    g.bench_function("cimm3_cv6_position2", |b| {
        b.iter(|| {
            let f = black_box(&imm);
            let p = f.predict(black_box(&s), black_box(DT)).expect("predict");
            let u = f
                .update(black_box(&cam), &p, black_box(&z))
                .expect("update");
            f.update(black_box(&constraint), &u, &RoadConstraint::z())
                .expect("road update")
        });
    });
    g.finish();
}

criterion_group!(benches, tracking);
criterion_main!(benches);
