use super::*;
use crate::measurement::{Geometry, MeasKind};
use approx::assert_relative_eq;

/// The analytic Jacobian of the biased model (target, offsets, scale, time offset) against
/// central differences of its innovation, for a radar and a camera, target and reference.
#[test]
fn jacobian_matches_central_differences() {
    let mut radar = SensorBias::typical(MeasKind::RangeBearing);
    radar.scale.push(Some(BiasPrior::constant(0.01)));
    let camera = SensorBias::typical(MeasKind::AzEl);
    let reg = Registration::<4, 16>::new(
        0.25,
        2.0,
        &[(2, Some(&radar)), (2, Some(&camera))],
        Tuning::default(),
    )
    .unwrap();
    let mut x = SVector::<f64, 16>::zeros();
    x.fixed_rows_mut::<4>(0)
        .copy_from(&nalgebra::Vector4::new(420.0, -130.0, 9.0, -4.0));
    for (i, v) in [30.0, 0.004, 0.002, -0.001, 0.15, 0.008, -0.006, 0.12]
        .into_iter()
        .enumerate()
    {
        x[4 + i] = v;
    }
    let known = Seen::Known(KnownObject {
        pos: Vector3::new(300.0, 200.0, 120.0),
        vel: Vector3::new(-12.0, 9.0, 0.5),
        cov: Matrix3::identity(),
    });
    for (sensor, kind, at, vel) in [
        (
            0,
            MeasKind::RangeBearing,
            Vector3::new(-2000.0, -1500.0, 10.0),
            Vector3::zeros(),
        ),
        (
            1,
            MeasKind::AzEl,
            Vector3::new(150.0, 80.0, 120.0),
            Vector3::new(15.0, -8.0, 0.0),
        ),
    ] {
        let model = SensorModel::new(kind, Geometry::spatial(), at, &[1.0, 0.01], None).unwrap();
        let z = [1000.0, 0.3];
        let obs = Observation {
            sensor,
            model: &model,
            platform_vel: vel,
            z: &z,
        };
        for seen in [Seen::Target, known] {
            struct J<'a> {
                reg: &'a Registration<4, 16>,
                x: SVector<f64, 16>,
                obs: &'a Observation<'a>,
                seen: &'a Seen,
            }
            impl WithSensor<6> for J<'_> {
                type Output = ();
                fn with<H, const M: usize>(self, model: &H)
                where
                    H: MeasurementModel<6, M> + Locate<M>,
                {
                    let slots = &self.reg.sensors[self.obs.sensor];
                    let nu = |x: &SVector<f64, 16>| {
                        self.reg
                            .linearise(model, x, slots, self.obs, self.seen)
                            .unwrap()
                            .0
                    };
                    let (_, H, _) = self
                        .reg
                        .linearise(model, &self.x, slots, self.obs, self.seen)
                        .unwrap();
                    let mut numeric = SMatrix::<f64, M, 16>::zeros();
                    for c in 0..16 {
                        let e = 1e-6 * (1.0 + self.x[c].abs());
                        let (mut a, mut b) = (self.x, self.x);
                        a[c] += e;
                        b[c] -= e;
                        // ν = z − ẑ, so ∂ẑ/∂x = −∂ν/∂x.
                        numeric.set_column(c, &((nu(&b) - nu(&a)) / (2.0 * e)));
                    }
                    assert_relative_eq!(H, numeric, epsilon = 1e-6, max_relative = 1e-5);
                }
            }
            model.apply(J {
                reg: &reg,
                x,
                obs: &obs,
                seen: &seen,
            });
        }
    }
}
