//! The filters' hot path never touches the heap: 100 predict + update steps at N = 6, M = 2 (KF,
//! EKF, CDKF, STF, OBE, ICDKF, bias-aware CDKF) must make zero allocations.
//!
//! How: the test binary (`it`, shared with the other end-to-end tests) links `allocation-counter`,
//! which installs a global allocator wrapping `std::alloc::System` and counting allocations per
//! thread, in thread-locals (the `unsafe impl GlobalAlloc` lives in that crate; this workspace
//! forbids unsafe code). [`allocation_counter::measure`] returns what the closure allocated on the
//! current thread only, so the other tests running in parallel threads of the same process (live
//! servers, Zenoh, tokio runtimes), or the test harness, cannot add noise.
//!
//! To cover another filter, add a `#[test]` calling [`assert_steps_do_not_allocate`] with the
//! filter, a motion model and a measurement model (or, for non-Gaussian filters, a loop of the same
//! shape inside [`assert_no_allocations`]).

use std::hint::black_box;

use harrier_core::filter::{
    BiasAwareCdkf, BiasedMeasurement, BoundedLinearMeasurement, BoundedLinearTransition,
    CentralDifference, Extended, IncrementalCdkf, Kalman, Obe, ObeCriterion, Predictor, StfState,
    StrongTracking, Updater, WithBias, current,
};
use harrier_core::measurement::{AzEl, Geometry, MeasurementModel, Position, RangeBearing};
use harrier_core::motion::{ConstantVelocity, LinearTransition, TransitionModel};
use harrier_core::state::{Ellipsoid, Gaussian};
use nalgebra::{Matrix2x6, Matrix6, Matrix6x3, SMatrix, SVector, Vector2, Vector3, Vector6};

const STEPS: u32 = 100;
const DT: f64 = 0.1;

/// Truth `[x, y, z, vx, vy, vz]` at step `k`: straight and level at 120 m, 18 m/s.
fn truth(k: u32) -> Vector6<f64> {
    let t = f64::from(k) * DT;
    Vector6::new(1500.0 + 12.0 * t, 800.0 + 13.5 * t, 120.0, 12.0, 13.5, 0.0)
}

fn initial() -> Gaussian<6> {
    let mean = truth(0) + Vector6::new(20.0, -15.0, 5.0, 2.0, -1.5, 0.5);
    let cov = Matrix6::from_diagonal(&Vector6::new(400.0, 400.0, 100.0, 25.0, 25.0, 4.0));
    Gaussian::new(mean, cov).expect("valid initial state")
}

/// Runs `body` under the counting allocator and fails if it allocated anything.
fn assert_no_allocations(name: &str, body: impl FnOnce()) {
    let info = allocation_counter::measure(body);
    assert_eq!(
        (info.count_total, info.bytes_total),
        (0, 0),
        "{name}: the filter allocated on the heap ({info:?})"
    );
}

/// [`STEPS`] predict + update steps of `filter` on noise-free measurements of [`truth`] make no
/// heap allocation. One step runs first, outside the measurement, so that nothing lazily
/// initialised on first use is counted.
fn assert_steps_do_not_allocate<F, T, H, const M: usize>(
    name: &str,
    filter: &F,
    motion: &T,
    sensor: &H,
) where
    F: Predictor<T, 6, State = Gaussian<6>> + Updater<H, 6, M, State = Gaussian<6>>,
    T: TransitionModel<6>,
    H: MeasurementModel<6, M>,
{
    let step = |state: &Gaussian<6>, k: u32| -> Gaussian<6> {
        let predicted = filter.predict(motion, state, DT).expect("predict");
        let z: SVector<f64, M> = sensor.function(&truth(k));
        filter.update(sensor, &predicted, &z).expect("update").state
    };
    let mut state = step(&initial(), 1);
    assert_no_allocations(name, || {
        for k in 2..=STEPS + 1 {
            state = black_box(step(black_box(&state), k));
        }
    });
    // The run tracked the target: the check above measured real work, not a diverged filter.
    let err = (state.mean.fixed_rows::<2>(0) - truth(STEPS + 1).fixed_rows::<2>(0)).norm();
    assert!(
        err < 20.0,
        "{name}: position error {err} m after {STEPS} steps"
    );
}

fn cv6() -> ConstantVelocity<6> {
    ConstantVelocity::<6>::new(1.0)
}

fn sensor() -> Vector3<f64> {
    Vector3::new(-200.0, -300.0, 2.0)
}

fn radar() -> RangeBearing {
    RangeBearing::new(Geometry::spatial(), sensor(), [5.0, 0.005])
}

fn camera() -> AzEl {
    AzEl::new(Geometry::spatial(), sensor(), [0.002, 0.002])
}

#[test]
fn counter_sees_allocations() {
    // Positive control: the counting allocator is installed and counts this thread.
    let info = allocation_counter::measure(|| {
        black_box(vec![0_u8; 64]);
    });
    assert_eq!(info.count_total, 1);
}

#[test]
fn kf_does_not_allocate() {
    let position = Position::<2>::new(Geometry::spatial(), [5.0, 5.0]);
    assert_steps_do_not_allocate("KF cv6/position2", &Kalman, &cv6(), &position);
}

#[test]
fn ekf_does_not_allocate() {
    assert_steps_do_not_allocate("EKF cv6/range_bearing", &Extended, &cv6(), &radar());
    assert_steps_do_not_allocate("EKF cv6/az_el", &Extended, &cv6(), &camera());
}

#[test]
fn cdkf_does_not_allocate() {
    let cd = CentralDifference::default();
    assert_steps_do_not_allocate("CDKF cv6/range_bearing", &cd, &cv6(), &radar());
    assert_steps_do_not_allocate("CDKF cv6/az_el", &cd, &cv6(), &camera());
}

#[test]
fn stf_does_not_allocate() {
    let stf = StrongTracking::new(1.0, 0.95).expect("valid STF");
    let sensor = Position::<2>::new(Geometry::spatial(), [5.0, 5.0]);
    let mut state = StfState::new(initial());
    let mut step = |k: u32| {
        let z = sensor.function(&truth(k));
        state = stf
            .step(&cv6(), &sensor, &state, &z, DT)
            .expect("stf step")
            .state;
    };
    step(1);
    assert_no_allocations("STF cv6/position2", || (2..=STEPS).for_each(&mut step));
}

#[test]
fn obe_does_not_allocate() {
    let f = cv6().matrix(DT);
    let b = Matrix6x3::from_fn(|i, j| {
        if i == j + 3 {
            2.0 * DT
        } else if i == j {
            DT * DT
        } else {
            0.0
        }
    });
    let motion = BoundedLinearTransition::new(f, b, 1.0).expect("valid system");
    let h = Matrix2x6::new(1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0);
    let sensor = BoundedLinearMeasurement::new(h, Vector2::new(2.0, 2.0)).expect("valid sensor");
    for criterion in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
        let obe = Obe::new(criterion);
        let mut set = Ellipsoid::new(truth(0), initial().cov).expect("valid set");
        let mut step = |k: u32| {
            let p = obe.predict(&motion, &set, DT).expect("predict");
            set = obe
                .update(&sensor, &p, &Vector2::new(truth(k)[0], truth(k)[1]))
                .expect("update")
                .state;
        };
        step(1);
        assert_no_allocations("OBE cv6/position2", || (2..=STEPS).for_each(&mut step));
    }
}

#[test]
fn icdkf_and_bias_aware_cdkf_do_not_allocate() {
    let f = IncrementalCdkf::default();
    let mut g = initial();
    let at = |k: u32| {
        RangeBearing::new(
            Geometry::spatial(),
            sensor() + Vector3::new(f64::from(k), 0.0, 0.0),
            [5.0, 0.005],
        )
    };
    let z = |k: u32| -> Vector2<f64> { at(k).function(&truth(k)) };
    let mut step = |k: u32| {
        let pred: Gaussian<12> = f.predict(&cv6(), &g, DT).expect("predict");
        g = current(
            &f.update::<_, 6, 12, 2>(&at(k), &at(k - 1), &pred, &(z(k) - z(k - 1)))
                .expect("update")
                .state,
        );
    };
    step(1);
    assert_no_allocations("ICDKF cv6/range_bearing", || {
        (2..=STEPS).for_each(&mut step)
    });

    let motion = WithBias::<_, 6, 2>::new(cv6(), [0.05, 5e-5], f64::INFINITY).expect("bias model");
    let filter = BiasAwareCdkf {
        cd: CentralDifference::default(),
        jump_std: [200.0, 0.2],
        jump_prob: 1e-5,
    };
    let sensor = BiasedMeasurement::<_, 6> { inner: radar() };
    let mut mean = SVector::<f64, 8>::zeros();
    mean.fixed_rows_mut::<6>(0).copy_from(&initial().mean);
    let mut cov = SMatrix::<f64, 8, 8>::identity() * 1e-6;
    cov.fixed_view_mut::<6, 6>(0, 0).copy_from(&initial().cov);
    let mut state = Gaussian::new(mean, cov).expect("valid prior");
    let mut step = |k: u32| {
        let pred = filter.predict(&motion, &state, DT).expect("predict");
        state = filter
            .update(&sensor, &pred, &radar().function(&truth(k)))
            .expect("update")
            .posterior
            .state;
    };
    step(1);
    assert_no_allocations("bias-aware CDKF cv6/range_bearing", || {
        (2..=STEPS).for_each(&mut step)
    });
}
