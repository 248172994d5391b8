//! `cdkf-bias`: Harrier's bias-robust radar estimator ([`BiasAwareCdkf`]): CDKF on the CV state
//! augmented with additive range/azimuth bias states, with a bias-jump hypothesis test.

use harrier_core::filter::{BiasAwareCdkf, BiasedMeasurement, CentralDifference, WithBias};
use harrier_core::measurement::SensorModel;
use harrier_core::motion::ConstantVelocity;
use harrier_core::scenario::{Estimate, Scenario};
use harrier_core::state::Gaussian;
use nalgebra::{Matrix6, Vector2, Vector6};

use super::{cv_estimate, geometry, model_for, prior};
use crate::{EngineError, EstimatorInfo, Params, Q_PARAM, ReplayEstimator, Step, setup};

/// `cdkf-bias`.
pub const CDKF_BIAS: EstimatorInfo = EstimatorInfo {
    name: "cdkf-bias",
    summary: "bias-robust radar CDKF: bias states + bias-jump hypothesis test (Harrier's design)",
    params: &[
        Q_PARAM,
        (
            "sigma0",
            "initial bias std in units of the noise std (default 0)",
        ),
        (
            "drift",
            "bias drift intensity, noise std per √s (default 0.01)",
        ),
        ("tau", "bias correlation time, s (default ∞: random walk)"),
        (
            "jump",
            "bias jump std in units of the noise std (default 40)",
        ),
        (
            "p_jump",
            "prior probability of a bias jump per update (default 1e-5)",
        ),
    ],
    build,
};

fn build(sc: &Scenario, p: &Params) -> Result<Box<dyn ReplayEstimator>, EngineError> {
    if sc.dims != 2 || sc.sensors.len() != 1 {
        return Err(setup(
            "cdkf-bias needs a planar scenario with one range_bearing or az_el sensor",
        ));
    }
    let s = &sc.sensors[0];
    let std = s.noise.std();
    if std.len() != 2 {
        return Err(setup(
            "cdkf-bias needs a two-component sensor (range_bearing or az_el)",
        ));
    }
    let q = p.q(sc)?;
    let (t, kin) = prior::<4>(sc, super::cv_dims(4))?;
    let unit = |k: f64| [k * std[0], k * std[1]];
    let motion = WithBias::new(
        ConstantVelocity::<4>::new(q),
        unit(p.get("drift", 0.01)),
        p.get("tau", f64::INFINITY),
    )?;
    let mut mean = Vector6::zeros();
    mean.fixed_rows_mut::<4>(0).copy_from(&kin.mean);
    let mut cov = Matrix6::zeros();
    cov.fixed_view_mut::<4, 4>(0, 0).copy_from(&kin.cov);
    let s0 = unit(p.get("sigma0", 0.0));
    // A zero initial bias variance is represented by a tiny one (Cholesky needs SPD).
    cov[(4, 4)] = (s0[0] * s0[0]).max(1e-12 * std[0] * std[0]);
    cov[(5, 5)] = (s0[1] * s0[1]).max(1e-12 * std[1] * std[1]);
    let filter = BiasAwareCdkf {
        cd: CentralDifference::default(),
        jump_std: unit(p.get("jump", 40.0)),
        jump_prob: p.get("p_jump", 1e-5),
    };
    Ok(Box::new(CdkfBias {
        filter,
        motion,
        sc: sc.clone(),
        t,
        state: Gaussian::new(mean, cov)?,
        jumps: Vec::new(),
    }))
}

#[derive(Debug)]
struct CdkfBias {
    filter: BiasAwareCdkf<2>,
    motion: WithBias<ConstantVelocity<4>, 4, 2>,
    sc: Scenario,
    t: f64,
    state: Gaussian<6>,
    jumps: Vec<f64>,
}

impl ReplayEstimator for CdkfBias {
    fn step(&mut self, step: &Step<'_>) -> Result<Option<Estimate>, EngineError> {
        let geo = geometry(&self.sc);
        let mut g = self.state;
        let mut t = self.t;
        let mut jumped = false;
        for m in step.measurements {
            if m.t > t {
                g = self.filter.predict(&self.motion, &g, m.t - t)?;
                t = m.t;
            }
            let z = Vector2::new(m.z[0], m.z[1]);
            let up = match model_for(&self.sc, geo, m, None)? {
                SensorModel::RangeBearing(h) => {
                    self.filter
                        .update(&BiasedMeasurement::<_, 4> { inner: h }, &g, &z)?
                }
                SensorModel::AzEl(h) => {
                    self.filter
                        .update(&BiasedMeasurement::<_, 4> { inner: h }, &g, &z)?
                }
                _ => return Err(setup("cdkf-bias supports range_bearing and az_el sensors")),
            };
            g = up.posterior.state;
            jumped |= up.jump;
        }
        self.state = g;
        self.t = t;
        if jumped {
            self.jumps.push(t);
        }
        let kin = Gaussian {
            mean: g.mean.fixed_rows::<4>(0).into_owned(),
            cov: g.cov.fixed_view::<4, 4>(0, 0).into_owned(),
        };
        let mut e = cv_estimate(self.sc.plane_z(), t, &kin);
        e.extra
            .insert("bias_est".into(), serde_json::json!([g.mean[4], g.mean[5]]));
        if jumped {
            e.extra
                .insert("bias_jump".into(), serde_json::Value::Bool(true));
        }
        Ok(Some(e))
    }
}
