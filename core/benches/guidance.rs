//! Cost of one guidance evaluation per UAV (target: ≤ 1 µs).
//!
//! Run with `cargo bench -p harrier-core --bench guidance`; GUIDANCE.md records the figures.
//! Every law is evaluated on a fixed set of UAV states around the target of the \[CIMM\] §5.2 case
//! (outside, inside and on the circle), so that every branch is timed.

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use harrier_core::guidance::formation::{PairState, RangeRegulator, vector_sum};
use harrier_core::guidance::kinematics::step;
use harrier_core::guidance::lgvf::Lgvf;
use harrier_core::guidance::obstacle::{Avoidance, Obstacle, avoid};
use harrier_core::guidance::phase::PhaseNeighbours;
use harrier_core::guidance::togvf::Togvf;
use harrier_core::guidance::{Command, Limits, StandoffLaw, TargetEstimate, UavState};
use nalgebra::{Vector2, Vector3};

fn states() -> Vec<UavState> {
    (0..16)
        .map(|k| {
            let a = k as f64 * 0.4;
            let r = [900.0, 150.0, 300.0, 600.0][k % 4];
            UavState::new(
                Vector3::new(1500.0 + r * a.cos(), 1800.0 + r * a.sin(), 350.0),
                Vector3::new(-25.0 * a.sin(), 25.0 * a.cos(), -1.0),
            )
        })
        .collect()
}

fn standoff(c: &mut Criterion) {
    let target = TargetEstimate {
        position: Vector3::new(1500.0, 1800.0, 0.0),
        velocity: Vector3::new(6.0, 8.0, 0.0),
    };
    let limits = Limits::fixed_wing();
    let uavs = states();
    let nb = PhaseNeighbours {
        ahead: Some(2.0),
        behind: Some(-2.0),
        spacing: std::f64::consts::TAU / 3.0,
    };
    let togvf = Togvf::new(300.0, 300.0, 25.0);
    let lgvf = Lgvf::new(300.0, 300.0, 25.0);
    let mut g = c.benchmark_group("guidance");
    let mut i = 0;
    g.bench_function("togvf", |b| {
        b.iter(|| {
            i = (i + 1) % uavs.len();
            black_box(togvf.command(black_box(&uavs[i]), Some(&target), &limits, Some(&nb)))
        })
    });
    g.bench_function("lgvf", |b| {
        b.iter(|| {
            i = (i + 1) % uavs.len();
            black_box(lgvf.command(black_box(&uavs[i]), Some(&target), &limits, Some(&nb)))
        })
    });
    let cmd = Command::new(Vector2::new(10.0, 20.0), -3.0);
    g.bench_function("kinematics_step", |b| {
        b.iter(|| {
            i = (i + 1) % uavs.len();
            black_box(step(black_box(&uavs[i]), &cmd, &limits, 0.1))
        })
    });
    // A follower with three neighbours and four obstacles: eqs. (5)–(6) + avoidance.
    let reg = RangeRegulator::default();
    let pairs = [PairState::start(120.0); 3];
    let obstacles = [
        Obstacle {
            center: Vector2::new(1600.0, 2000.0),
            radius: 80.0,
        },
        Obstacle {
            center: Vector2::new(1300.0, 2300.0),
            radius: 90.0,
        },
        Obstacle {
            center: Vector2::new(1900.0, 1500.0),
            radius: 70.0,
        },
        Obstacle {
            center: Vector2::new(1000.0, 1200.0),
            radius: 100.0,
        },
    ];
    let av = Avoidance {
        lookahead: 220.0,
        margin: 35.0,
    };
    g.bench_function("formation_avoid", |b| {
        b.iter(|| {
            i = (i + 1) % uavs.len();
            let u = black_box(&uavs[i]);
            let p = u.horizontal_position();
            let terms = [(0usize, 128.0), (5, 200.0), (9, 141.0)].map(|(j, rc)| {
                let rel = uavs[j].horizontal_position() - p;
                let r = rel.norm().max(1e-9);
                (rel / r, reg.pseudo_control(&pairs[j % 3], r, rc))
            });
            let v = vector_sum(terms);
            black_box(avoid(p, u.horizontal_velocity(), v, &obstacles, &av))
        })
    });
    g.finish();
}

criterion_group!(benches, standoff);
criterion_main!(benches);
