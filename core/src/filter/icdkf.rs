//! Incremental central-difference Kalman filter (ICDKF), faithfully after \[ICDKF\] §3.
//!
//! A radar whose measurements carry an unknown, slowly varying bias,
//! `z_k = h(x_k) + Γ_k b_k + v_k` (\[ICDKF\] eqs. (9)–(10)), is differenced between consecutive
//! samples so that the bias cancels (\[ICDKF\] eq. (11)):
//!
//! ```text
//! Δz_k = z_k ⊖ z_{k−1} = h_k(x_k) ⊖ h_{k−1}(x_{k−1}) + v*_k,      v*_k = v_k − v_{k−1}   (eqs. (11)–(12))
//! ```
//!
//! and the bias-difference is ignored (the paper: "can be defined as zero-mean Gaussian white noise
//! or ignored directly"), so `v*` is taken white with covariance `2R`.
//!
//! Since Δz depends on two consecutive states, the filter carries the augmented state
//! `[x_k; x_{k−1}]` (stochastic cloning). Each cycle clones the posterior of `x_{k−1}` and predicts
//! the pair, `[x_k; x_{k−1}] = [f(x_{k−1}) + w; x_{k−1}]`, with central differences, then updates
//! the pair with Δz_k by the CDKF equations (\[ICDKF\] eqs. (13)–(14); \[NPR00\]).
//!
//! Two forms, as in the paper:
//! * [`IcdkfForm::General`]: process and measurement noise are augmented into the sigma points
//!   (eq. (13): `χ^a = (x̂^{ax}, x̂^{aw}, u)`), which handles non-additive noise;
//! * [`IcdkfForm::Additive`]: noise enters additively (`+ Q`, `+ 2R`), cheaper. With the additive
//!   models of harrier-core both forms agree to rounding (tested).
//!
//! **What the method can and cannot do.** Increments carry no absolute position: the only absolute
//! information is the prior, so the position error random-walks with the process noise. On the
//! reference radar scenarios the faithful ICDKF does *not* beat the plain CDKF; see
//! `BENCHMARKS.md` and the bias-robust estimator in `BiasAwareCdkf` for what does.
//!
//! # References
//! * \[ICDKF\] Q. Wang, "Research on target tracking technology of multi-rotor aircraft based on
//!   ICDKF" (`shared/papers/001`).
//! * \[NPR00\] M. Nørgaard, N. K. Poulsen, O. Ravn, *Automatica* 36(11), 2000.
#![allow(non_snake_case)]

use nalgebra::SVector;

use super::cdkf::{CentralDifference, sigma_point_update};
use crate::Result;
use crate::linalg::{ensure_covariance, symmetrize};
use crate::measurement::MeasurementModel;
use crate::motion::TransitionModel;
use crate::state::{Gaussian, Posterior};

/// Which ICDKF form of \[ICDKF\] §3 to run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IcdkfForm {
    /// Noise augmented into the sigma points (general, non-additive noise).
    General,
    /// Additive noise.
    #[default]
    Additive,
}

/// The incremental CDKF. `N` is the kinematic state size, `N2 = 2N` the augmented one.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct IncrementalCdkf {
    /// Central-difference interval.
    pub cd: CentralDifference,
    /// General or additive form.
    pub form: IcdkfForm,
}

/// The marginal of `x_k` (the first N components) of an augmented `[x_k; x_{k−1}]` state.
pub fn current<const N: usize, const N2: usize>(aug: &Gaussian<N2>) -> Gaussian<N> {
    const { assert!(N2 == 2 * N) };
    Gaussian {
        mean: aug.mean.fixed_rows::<N>(0).into_owned(),
        cov: aug.cov.fixed_view::<N, N>(0, 0).into_owned(),
    }
}

impl IncrementalCdkf {
    /// Clone-and-predict: from the posterior of `x_{k−1}` to the augmented prediction
    /// `[x_k; x_{k−1}] = [f(x_{k−1}) + w; x_{k−1}]` (\[ICDKF\] eqs. (13)–(14)).
    pub fn predict<T: TransitionModel<N>, const N: usize, const N2: usize>(
        &self,
        model: &T,
        prior: &Gaussian<N>,
        dt: f64,
    ) -> Result<Gaussian<N2>> {
        const { assert!(N2 == 2 * N) };
        let stack = |a: SVector<f64, N>, b: &SVector<f64, N>| {
            let mut y = SVector::<f64, N2>::zeros();
            y.fixed_rows_mut::<N>(0).copy_from(&a);
            y.fixed_rows_mut::<N>(N).copy_from(b);
            y
        };
        let Q = model.covar(dt);
        let (mean, Pyy, _) = match self.form {
            IcdkfForm::General => self.cd.moments_with_noise(
                &prior.mean,
                &prior.cov,
                &Q,
                |x, w| stack(model.function(x, dt) + w, x),
                |a, b| a - b,
            )?,
            IcdkfForm::Additive => {
                let (m, mut P, c) = self.cd.moments(
                    &prior.mean,
                    &prior.cov,
                    |x| stack(model.function(x, dt), x),
                    |a, b| a - b,
                )?;
                let mut top = P.fixed_view_mut::<N, N>(0, 0);
                top += Q;
                (m, P, c)
            }
        };
        let cov = symmetrize(&Pyy);
        ensure_covariance(&cov, "predicted covariance")?;
        Ok(Gaussian { mean, cov })
    }

    /// Update of the augmented prediction with the increment `dz = z_k ⊖ z_{k−1}`; `now` and `prev`
    /// are the measurement models at t_k and t_{k−1} (the platform moves). Eqs. (11)–(12), with
    /// `Cov(v*) = 2R`; the covariance update is the Joseph form of [`CentralDifference`].
    pub fn update<H: MeasurementModel<N, M>, const N: usize, const N2: usize, const M: usize>(
        &self,
        now: &H,
        prev: &H,
        predicted: &Gaussian<N2>,
        dz: &SVector<f64, M>,
    ) -> Result<Posterior<Gaussian<N2>, M>> {
        const { assert!(N2 == 2 * N) };
        let inc = |xa: &SVector<f64, N2>| {
            let xk: SVector<f64, N> = xa.fixed_rows::<N>(0).into_owned();
            let xp: SVector<f64, N> = xa.fixed_rows::<N>(N).into_owned();
            now.residual(&now.function(&xk), &prev.function(&xp))
        };
        let diff = |a: &SVector<f64, M>, b: &SVector<f64, M>| now.residual(a, b);
        let R2 = now.covar() + prev.covar();
        let P = &predicted.cov;
        let (zhat, Pzz, Pxz) = match self.form {
            IcdkfForm::General => {
                self.cd
                    .moments_with_noise(&predicted.mean, P, &R2, |xa, v| inc(xa) + v, diff)?
            }
            IcdkfForm::Additive => {
                let (m, Pzz, Pxz) = self.cd.moments(&predicted.mean, P, inc, diff)?;
                (m, Pzz + R2, Pxz)
            }
        };
        let nu = now.residual(dz, &zhat);
        sigma_point_update(predicted, symmetrize(&Pzz), &Pxz, nu)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::measurement::{Geometry, RangeBearing};
    use crate::motion::ConstantVelocity;
    use approx::assert_relative_eq;
    use nalgebra::{Matrix4, Vector2, Vector3, Vector4};

    #[test]
    fn general_and_additive_forms_agree() {
        let cv = ConstantVelocity::<4>::new(1.0);
        let prior = Gaussian::new(
            Vector4::new(1000.0, 5000.0, 15.0, -10.0),
            Matrix4::from_diagonal(&Vector4::new(1e4, 1e4, 25.0, 25.0)),
        )
        .unwrap();
        let prev = RangeBearing::new(Geometry::planar(0.0), Vector3::zeros(), [5.0, 0.005]);
        let now = RangeBearing::new(
            Geometry::planar(0.0),
            Vector3::new(5.0, 0.0, 0.0),
            [5.0, 0.005],
        );
        let dz = Vector2::new(-12.0, 0.004);
        let mut out = Vec::new();
        for form in [IcdkfForm::General, IcdkfForm::Additive] {
            let f = IncrementalCdkf {
                form,
                ..Default::default()
            };
            let pred: Gaussian<8> = f.predict(&cv, &prior, 1.0).unwrap();
            out.push(
                f.update::<_, 4, 8, 2>(&now, &prev, &pred, &dz)
                    .unwrap()
                    .state,
            );
        }
        assert_relative_eq!(out[0].mean, out[1].mean, max_relative = 1e-9);
        assert_relative_eq!(out[0].cov, out[1].cov, max_relative = 1e-8);
    }

    #[test]
    fn constant_offset_is_invisible_to_the_increments() {
        // Two measurement sequences that differ by a constant bias give the same estimate.
        let cv = ConstantVelocity::<4>::new(0.5);
        let sensor = |k: f64| {
            RangeBearing::new(
                Geometry::planar(0.0),
                Vector3::new(5.0 * k, 0.0, 0.0),
                [5.0, 0.005],
            )
        };
        let truth = |k: f64| Vector4::new(1000.0 + 15.0 * k, 5000.0 - 10.0 * k, 15.0, -10.0);
        let f = IncrementalCdkf::default();
        let run = |bias: Vector2<f64>| {
            let mut g = Gaussian::new(
                truth(0.0),
                Matrix4::from_diagonal(&Vector4::new(1e4, 1e4, 25.0, 25.0)),
            )
            .unwrap();
            let mut zprev: Vector2<f64> =
                MeasurementModel::<4, 2>::function(&sensor(0.0), &truth(0.0)) + bias;
            for k in 1..20 {
                let k = f64::from(k);
                let z: Vector2<f64> =
                    MeasurementModel::<4, 2>::function(&sensor(k), &truth(k)) + bias;
                let pred: Gaussian<8> = f.predict(&cv, &g, 1.0).unwrap();
                let post = f
                    .update::<_, 4, 8, 2>(&sensor(k), &sensor(k - 1.0), &pred, &(z - zprev))
                    .unwrap();
                g = current(&post.state);
                zprev = z;
            }
            g.mean
        };
        assert_relative_eq!(
            run(Vector2::zeros()),
            run(Vector2::new(120.0, 0.01)),
            epsilon = 1e-6
        );
    }
}
