//! Unit tests of the OBE filter: containment of the strip update and the prediction, their
//! optimality within the family, the Jacobi eigenvalues, and random bounded systems.

use super::solve::sym_eigenvalues;
use super::*;
use crate::linalg::ln_det;
use nalgebra::{Matrix2, Matrix4, SMatrix, Vector2, Vector4};
use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

const TOL: f64 = 1e-9;

/// Uniform point in the unit ball of R^N, or on its sphere when `surface`.
fn ball<const N: usize>(rng: &mut ChaCha8Rng, surface: bool) -> SVector<f64, N> {
    let g = SVector::<f64, N>::from_fn(|_, _| rng.sample(StandardNormal));
    let r: f64 = if surface {
        1.0
    } else {
        rng.random::<f64>().powf(1.0 / N as f64)
    };
    g.normalize() * r
}

/// A point of `E` (a quarter of them on its boundary).
fn point_in<const N: usize>(rng: &mut ChaCha8Rng, e: &Ellipsoid<N>) -> SVector<f64, N> {
    let surface = rng.random::<f64>() < 0.25;
    let l = cholesky(&e.shape, "test").unwrap().l();
    e.center + l * ball::<N>(rng, surface)
}

fn random_ellipsoid<const N: usize>(rng: &mut ChaCha8Rng) -> Ellipsoid<N> {
    let m = SMatrix::<f64, N, N>::from_fn(|_, _| rng.random_range(-1.0..1.0));
    let shape = m * m.transpose() + SMatrix::<f64, N, N>::identity() * 0.1;
    let center = SVector::<f64, N>::from_fn(|_, _| rng.random_range(-3.0..3.0));
    Ellipsoid::new(center, shape).unwrap()
}

fn det<const N: usize>(e: &Ellipsoid<N>) -> f64 {
    ln_det(&cholesky(&e.shape, "test").unwrap()).exp()
}

/// Random strip that cuts `e`: normal `a`, centre somewhere in the support, half-width a
/// fraction of it.
fn cutting_strip<const N: usize>(
    rng: &mut ChaCha8Rng,
    e: &Ellipsoid<N>,
) -> (SVector<f64, N>, f64, f64) {
    let a = ball::<N>(rng, true) * rng.random_range(0.5..2.0);
    let sg = a.dot(&(e.shape * a)).sqrt();
    let y = a.dot(&e.center) + rng.random_range(-0.9..0.9) * sg;
    let sigma = rng.random_range(0.02..0.6) * sg;
    (a, y, sigma)
}

#[test]
fn strip_update_contains_the_intersection() {
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    for _ in 0..200 {
        let e = random_ellipsoid::<4>(&mut rng);
        let (a, y, sigma) = cutting_strip(&mut rng, &e);
        for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
            let post = intersect_strip(&e, &a, y, sigma, crit).unwrap();
            // ρ = 0 (the prior) is in the family, so neither criterion can get worse.
            match crit {
                ObeCriterion::MinVolume => assert!(det(&post) <= det(&e) * (1.0 + 1e-12)),
                ObeCriterion::MinTrace => {
                    assert!(post.shape.trace() <= e.shape.trace() * (1.0 + 1e-12));
                }
            }
            let mut inside = 0;
            for _ in 0..400 {
                let x = point_in(&mut rng, &e);
                if (y - a.dot(&x)).abs() <= sigma {
                    inside += 1;
                    assert!(post.contains(&x, TOL).unwrap(), "{crit:?}");
                }
            }
            assert!(inside > 0);
        }
    }
}

#[test]
fn strip_update_in_one_dimension_is_exact() {
    let e = Ellipsoid::new(SVector::<f64, 1>::new(1.0), SMatrix::<f64, 1, 1>::new(4.0)).unwrap();
    // E = [-1, 3]; strip |5 − 2x| ≤ 1 ⇔ x ∈ [2, 3].
    let a = SVector::<f64, 1>::new(2.0);
    let post = intersect_strip(&e, &a, 5.0, 1.0, ObeCriterion::MinVolume).unwrap();
    assert!((post.center[0] - 2.5).abs() < 1e-12);
    assert!((post.shape[(0, 0)] - 0.25).abs() < 1e-12);
}

#[test]
fn covering_strip_is_a_no_op_and_missing_strip_is_empty() {
    let e = Ellipsoid::new(Vector2::new(1.0, -1.0), Matrix2::new(4.0, 1.0, 1.0, 2.0)).unwrap();
    let a = Vector2::new(1.0, 0.5);
    let sg = a.dot(&(e.shape * a)).sqrt();
    let ac = a.dot(&e.center);
    for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
        assert_eq!(
            intersect_strip(&e, &a, ac + 0.1, sg + 0.2, crit).unwrap(),
            e
        );
        assert_eq!(
            intersect_strip(&e, &a, ac + sg + 1.0, 0.5, crit).unwrap_err(),
            EstimationError::EmptyIntersection
        );
        // Just touching: a thin but valid ellipsoid around the touching point.
        let touch = intersect_strip(&e, &a, ac + sg + 0.5, 0.5, crit).unwrap();
        assert!(det(&touch) < 1e-6 * det(&e));
        let model = BoundedLinearMeasurement::new(
            SMatrix::<f64, 1, 2>::new(1.0, 0.5),
            SVector::<f64, 1>::new(0.5),
        )
        .unwrap();
        let err = Obe::new(crit)
            .update(&model, &e, &SVector::<f64, 1>::new(ac - sg - 2.0))
            .unwrap_err();
        assert_eq!(err, EstimationError::EmptyIntersection);
    }
}

/// Shape for a given ρ, straight from the family's formula (untightened strip).
fn family<const N: usize>(
    e: &Ellipsoid<N>,
    a: &SVector<f64, N>,
    y: f64,
    sigma: f64,
    rho: f64,
) -> SMatrix<f64, N, N> {
    let pa = e.shape * a;
    let g = a.dot(&pa);
    let innov = y - a.dot(&e.center);
    let s = sigma * sigma + rho * g;
    let delta = 1.0 + rho - rho * innov * innov / s;
    (e.shape - pa * pa.transpose() * (rho / s)) * delta
}

#[test]
fn fogel_huang_root_minimises_volume_and_search_minimises_trace() {
    let mut rng = ChaCha8Rng::seed_from_u64(2);
    for _ in 0..100 {
        let e = random_ellipsoid::<4>(&mut rng);
        let (a, y, sigma) = cutting_strip(&mut rng, &e);
        // Tighten first so that the family below is the one the filter optimises over.
        let sg = a.dot(&(e.shape * a)).sqrt();
        let ac = a.dot(&e.center);
        let (lo, hi) = ((y - sigma).max(ac - sg), (y + sigma).min(ac + sg));
        let (y, sigma) = (0.5 * (lo + hi), 0.5 * (hi - lo));
        let vol = intersect_strip(&e, &a, y, sigma, ObeCriterion::MinVolume).unwrap();
        let tr = intersect_strip(&e, &a, y, sigma, ObeCriterion::MinTrace).unwrap();
        assert!(det(&vol) <= det(&tr) * (1.0 + 1e-9));
        assert!(vol.shape.trace() >= tr.shape.trace() * (1.0 - 1e-9));
        for i in 0..=400 {
            let rho = if i == 0 {
                0.0
            } else {
                10f64.powf(-4.0 + i as f64 / 50.0)
            };
            let p = family(&e, &a, y, sigma, rho);
            assert!(det(&vol) <= p.determinant() * (1.0 + 1e-9), "ρ = {rho}");
            assert!(tr.shape.trace() <= p.trace() * (1.0 + 1e-9), "ρ = {rho}");
        }
    }
}

#[test]
fn prediction_contains_the_minkowski_sum_and_optimises_its_criterion() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for _ in 0..100 {
        let e = random_ellipsoid::<4>(&mut rng);
        let A = Matrix4::from_fn(|_, _| rng.random_range(-1.0..1.0)) + Matrix4::identity();
        let B = SMatrix::<f64, 4, 2>::from_fn(|_, _| rng.random_range(-1.0..1.0));
        let r = rng.random_range(0.1..2.0);
        let model = BoundedLinearTransition::new(A, B, r).unwrap();
        let vol = Obe::new(ObeCriterion::MinVolume).predict(&model, &e, 1.0);
        let tr = Obe::new(ObeCriterion::MinTrace).predict(&model, &e, 1.0);
        let (Ok(vol), Ok(tr)) = (vol, tr) else {
            continue; // A P Aᵀ singular: nothing to check
        };
        assert!(det(&vol) <= det(&tr) * (1.0 + 1e-9));
        assert!(vol.shape.trace() >= tr.shape.trace() * (1.0 - 1e-9));
        for _ in 0..300 {
            let surface = rng.random::<f64>() < 0.5;
            let w = ball::<2>(&mut rng, surface) * r;
            let x = A * point_in(&mut rng, &e) + B * w;
            assert!(vol.contains(&x, TOL).unwrap());
            assert!(tr.contains(&x, TOL).unwrap());
        }
        let q1 = A * e.shape * A.transpose();
        let q2 = B * B.transpose() * (r * r);
        for i in 1..400 {
            let lambda = i as f64 / 400.0;
            let p = q1 / lambda + q2 / (1.0 - lambda);
            assert!(det(&vol) <= p.determinant() * (1.0 + 1e-9));
            assert!(tr.shape.trace() <= p.trace() * (1.0 + 1e-9));
        }
    }
}

#[test]
fn jacobi_eigenvalues_match_nalgebra() {
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..100 {
        let m = SMatrix::<f64, 3, 3>::from_fn(|_, _| rng.random_range(-2.0..2.0));
        let s = m + m.transpose();
        let mut ours: Vec<f64> = sym_eigenvalues(s).iter().copied().collect();
        let mut theirs: Vec<f64> = s.symmetric_eigen().eigenvalues.iter().copied().collect();
        ours.sort_by(f64::total_cmp);
        theirs.sort_by(f64::total_cmp);
        for (a, b) in ours.iter().zip(&theirs) {
            assert!(
                (a - b).abs() < 1e-12 * (1.0 + b.abs()),
                "{ours:?} vs {theirs:?}"
            );
        }
    }
    let one = sym_eigenvalues(SMatrix::<f64, 1, 1>::new(2.5));
    assert_eq!(one[0], 2.5);
}

#[test]
fn prediction_without_noise_is_the_exact_image() {
    let e = Ellipsoid::new(Vector2::new(1.0, 2.0), Matrix2::new(2.0, 0.5, 0.5, 1.0)).unwrap();
    let A = Matrix2::new(1.0, 0.1, 0.0, 1.0);
    let model = BoundedLinearTransition::new(A, SMatrix::<f64, 2, 1>::zeros(), 1.0).unwrap();
    let p = Obe::default().predict(&model, &e, 0.1).unwrap();
    assert_eq!(p.center, A * e.center);
    assert!((p.shape - A * e.shape * A.transpose()).norm() < 1e-12);
}

#[test]
fn vector_update_gates_consistent_measurements() {
    let mut rng = ChaCha8Rng::seed_from_u64(4);
    let model =
        BoundedLinearMeasurement::new(SMatrix::<f64, 2, 4>::identity(), Vector2::new(0.3, 0.5))
            .unwrap();
    for _ in 0..200 {
        let e = random_ellipsoid::<4>(&mut rng);
        let x = point_in(&mut rng, &e);
        let v = Vector2::new(rng.random_range(-0.3..0.3), rng.random_range(-0.5..0.5));
        let z = model.matrix() * x + v;
        let post = Obe::default().update(&model, &e, &z).unwrap();
        assert!(post.nis().unwrap() <= 1.0 + TOL);
        assert!(post.state.contains(&x, TOL).unwrap());
    }
}

/// CV model with bounded acceleration: `x = [px, py, vx, vy]`, `w ∈ R²`, `‖w‖ ≤ 1` scaled by
/// `a_max`, position measured with box noise.
fn cv_system(
    dt: f64,
    a_max: f64,
    sigma: Vector2<f64>,
) -> (
    BoundedLinearTransition<4, 2>,
    BoundedLinearMeasurement<4, 2>,
) {
    let mut A = Matrix4::identity();
    A[(0, 2)] = dt;
    A[(1, 3)] = dt;
    let mut B = SMatrix::<f64, 4, 2>::zeros();
    B[(0, 0)] = 0.5 * dt * dt * a_max;
    B[(1, 1)] = 0.5 * dt * dt * a_max;
    B[(2, 0)] = dt * a_max;
    B[(3, 1)] = dt * a_max;
    let C = SMatrix::<f64, 2, 4>::identity();
    (
        BoundedLinearTransition::new(A, B, 1.0).unwrap(),
        BoundedLinearMeasurement::new(C, sigma).unwrap(),
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(48))]
    #[test]
    fn truth_stays_inside_on_random_bounded_systems(
        seed in any::<u64>(),
        dt in 0.02f64..1.0,
        a_max in 0.05f64..5.0,
        sx in 0.01f64..2.0,
        sy in 0.01f64..2.0,
        semi in proptest::array::uniform4(0.1f64..5.0),
        worst in 0.0f64..1.0,
    ) {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let sigma = Vector2::new(sx, sy);
        let (f, h) = cv_system(dt, a_max, sigma);
        let x0 = Ellipsoid::new(
            Vector4::new(10.0, -5.0, 1.0, 0.5),
            Matrix4::from_diagonal(&Vector4::from(semi).component_mul(&Vector4::from(semi))),
        ).unwrap();
        for crit in [ObeCriterion::MinVolume, ObeCriterion::MinTrace] {
            let obe = Obe::new(crit);
            let mut truth = point_in(&mut ChaCha8Rng::seed_from_u64(seed ^ 1), &x0);
            let mut set = x0;
            for k in 0..50 {
                if k > 0 {
                    // With probability `worst` the noise sits on its bound.
                    let surface = rng.random::<f64>() < worst;
                    let w = ball::<2>(&mut rng, surface);
                    truth = f.matrix() * truth + f.input() * w;
                    set = obe.predict(&f, &set, dt).unwrap();
                    prop_assert!(set.contains(&truth, TOL).unwrap(), "{crit:?} predict {k}");
                }
                let v = Vector2::from_fn(|i, _| {
                    if rng.random::<f64>() < worst {
                        if rng.random::<bool>() { sigma[i] } else { -sigma[i] }
                    } else {
                        rng.random_range(-sigma[i]..=sigma[i])
                    }
                });
                let z = h.matrix() * truth + v;
                set = obe.update(&h, &set, &z).unwrap().state;
                prop_assert!(set.contains(&truth, TOL).unwrap(), "{crit:?} update {k}");
            }
        }
    }
}
