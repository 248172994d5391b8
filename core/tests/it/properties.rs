//! Property and equivalence tests of the Gaussian filters (STYLE.md §B5 kinds 2 and 4).
//!
//! * EKF = KF and CDKF = KF on linear models;
//! * covariances stay symmetric positive definite under random predict/update sequences;
//! * the Joseph form equals the optimal form when the gain is optimal.

use approx::assert_relative_eq;
use harrier_core::filter::{CentralDifference, Extended, Kalman, Predictor, Updater};
use harrier_core::linalg::cholesky;
use harrier_core::measurement::{Geometry, Position, RangeBearing};
use harrier_core::motion::{ConstantAcceleration, ConstantTurn, ConstantVelocity};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix6, SMatrix, Vector2, Vector3, Vector6};
use proptest::prelude::*;

/// SPD matrix `A Aᵀ + εI` with physical scales.
fn spd6(a: [f64; 36], scale: f64) -> Matrix6<f64> {
    let a = Matrix6::from_column_slice(&a) * scale;
    a * a.transpose() + Matrix6::identity() * (0.01 * scale * scale)
}

fn assert_spd<const N: usize>(p: &SMatrix<f64, N, N>) {
    assert_relative_eq!(*p, p.transpose(), max_relative = 1e-12);
    assert!(cholesky(p, "P").is_ok(), "not positive definite: {p}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn ekf_and_cdkf_equal_kf_on_linear_models(
        a in prop::array::uniform32(-1.0f64..1.0),
        b in prop::array::uniform4(-1.0f64..1.0),
        x in prop::array::uniform6(-100.0f64..100.0),
        z in prop::array::uniform2(-100.0f64..100.0),
        dt in 0.05f64..2.0,
        q in 0.01f64..5.0,
    ) {
        let mut m = [0.0; 36];
        m[..32].copy_from_slice(&a);
        m[32..].copy_from_slice(&b);
        let prior = Gaussian::new(Vector6::from_column_slice(&x), spd6(m, 3.0)).unwrap();
        let cv = ConstantVelocity::<6>::new(q);
        let h = Position::<2>::new(Geometry::spatial(), [2.0, 3.0]);
        let z = Vector2::from_column_slice(&z);
        let kf = Kalman.update(&h, &Kalman.predict(&cv, &prior, dt).unwrap(), &z).unwrap();
        let ekf = Extended.update(&h, &Extended.predict(&cv, &prior, dt).unwrap(), &z).unwrap();
        let cd = CentralDifference::default();
        let cdkf = cd.update(&h, &cd.predict(&cv, &prior, dt).unwrap(), &z).unwrap();
        // EKF on a linear model is the KF, bit for bit.
        prop_assert_eq!(ekf.state, kf.state);
        prop_assert_eq!(ekf.innovation, kf.innovation);
        // CDKF on a linear model is the KF up to rounding.
        let tol = 1e-8 * (1.0 + kf.state.cov.abs().max());
        prop_assert!((cdkf.state.mean - kf.state.mean).abs().max() <= 1e-8 * (1.0 + kf.state.mean.abs().max()));
        prop_assert!((cdkf.state.cov - kf.state.cov).abs().max() <= tol);
        prop_assert!((cdkf.innovation_cov - kf.innovation_cov).abs().max() <= 1e-8 * (1.0 + kf.innovation_cov.abs().max()));
    }

    #[test]
    fn covariance_stays_spd_under_random_sequences(
        steps in prop::collection::vec((0u8..4, 0.01f64..3.0, prop::array::uniform3(-1.0f64..1.0)), 1..60),
        q in 1e-6f64..10.0,
        sigma in 1e-4f64..50.0,
    ) {
        // A target near (1000, 2000, 100) seen by a radar at the origin; every filter runs the
        // same random mix of CV / CT / CA-free predictions and position / range-bearing updates.
        let truth = Vector6::new(1000.0, 2000.0, 100.0, 10.0, -5.0, 0.0);
        let prior = Gaussian::new(truth, Matrix6::from_diagonal(&Vector6::new(1e4, 1e4, 1e4, 100.0, 100.0, 100.0))).unwrap();
        let (mut kf, mut ekf, mut cdkf) = (prior, prior, prior);
        let cd = CentralDifference::default();
        let cv = ConstantVelocity::<6>::new(q);
        let ct = ConstantTurn::<6>::new(0.05, q);
        let pos = Position::<3>::new(Geometry::spatial(), [sigma; 3]);
        let rb = RangeBearing::new(Geometry::spatial(), Vector3::zeros(), [sigma, sigma * 1e-3]);
        for (kind, dt, noise) in steps {
            match kind {
                0 => {
                    kf = Kalman.predict(&cv, &kf, dt).unwrap();
                    ekf = Extended.predict(&cv, &ekf, dt).unwrap();
                    cdkf = cd.predict(&cv, &cdkf, dt).unwrap();
                }
                1 => {
                    kf = Kalman.predict(&ct, &kf, dt).unwrap();
                    ekf = Extended.predict(&ct, &ekf, dt).unwrap();
                    cdkf = cd.predict(&ct, &cdkf, dt).unwrap();
                }
                2 => {
                    let z = Vector3::new(truth[0], truth[1], truth[2]) + Vector3::from_column_slice(&noise) * sigma;
                    kf = Kalman.update(&pos, &kf, &z).unwrap().state;
                    ekf = Extended.update(&pos, &ekf, &z).unwrap().state;
                    cdkf = cd.update(&pos, &cdkf, &z).unwrap().state;
                }
                _ => {
                    let z = Vector2::new(2236.07 + noise[0] * sigma, 0.4636 + noise[1] * sigma * 1e-3);
                    ekf = Extended.update(&rb, &ekf, &z).unwrap().state;
                    cdkf = cd.update(&rb, &cdkf, &z).unwrap().state;
                }
            }
            assert_spd(&kf.cov);
            assert_spd(&ekf.cov);
            assert_spd(&cdkf.cov);
        }
    }
}

#[test]
fn joseph_equals_optimal_form_when_gain_optimal() {
    let prior = Gaussian::new(
        Vector6::new(1.0, 2.0, 3.0, 0.1, 0.2, 0.3),
        spd6(
            core::array::from_fn(|i| ((i * 7 % 11) as f64 - 5.0) / 5.0),
            2.0,
        ),
    )
    .unwrap();
    let h = Position::<3>::new(Geometry::spatial(), [0.5, 0.7, 0.9]);
    let post = Kalman
        .update(&h, &prior, &Vector3::new(1.5, 1.0, 2.0))
        .unwrap();
    // Optimal form: P = P⁻ − K S Kᵀ with K = P⁻Hᵀ S⁻¹.
    let hm: SMatrix<f64, 3, 6> = harrier_core::measurement::LinearMeasurement::<6, 3>::matrix(&h);
    let s = hm * prior.cov * hm.transpose()
        + harrier_core::measurement::MeasurementModel::<6, 3>::covar(&h);
    let k = prior.cov * hm.transpose() * s.try_inverse().unwrap();
    assert_relative_eq!(
        post.state.cov,
        prior.cov - k * s * k.transpose(),
        max_relative = 1e-10
    );
}

#[test]
fn ca_kf_tracks_a_constant_acceleration_exactly() {
    // Planar CA state [px, py, vx, vy, ax, ay]; no process noise, tiny measurement noise: the KF
    // locks onto a parabola and recovers its acceleration.
    let ca = ConstantAcceleration::<6>::new(0.0);
    let h = Position::<2>::new(Geometry::planar(0.0), [1e-3, 1e-3]);
    let mut g = Gaussian::new(Vector6::zeros(), Matrix6::identity() * 1e6).unwrap();
    for k in 1..40 {
        let t = f64::from(k) * 0.1;
        g = Kalman.predict(&ca, &g, 0.1).unwrap();
        let z = Vector2::new(1.0 + 2.0 * t + 1.5 * t * t, -0.5 * t * t);
        g = Kalman.update(&h, &g, &z).unwrap().state;
    }
    assert_relative_eq!(g.mean[4], 3.0, epsilon = 1e-2);
    assert_relative_eq!(g.mean[5], -1.0, epsilon = 1e-2);
}
